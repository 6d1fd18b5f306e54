//! `rig build`: the firmware and host binaries built reproducibly, and the build record
//! (`build.json`) that names each artifact by SHA-256.
//!
//! Reproducible means same source + same toolchain → same bytes, wherever the tree is checked
//! out and whenever it is built:
//! - `--remap-path-prefix` turns the checkout's and cargo home's absolute paths (panic
//!   locations, debug info) into `/src` and `/cargo`;
//! - `SOURCE_DATE_EPOCH` is the commit's time, for any build script that stamps one;
//! - `--locked` builds exactly Cargo.lock; `CARGO_INCREMENTAL=0`;
//! - the firmware's release profile already has `codegen-units = 1` and `lto`; the host
//!   binaries keep the workspace profile (rustc's codegen-unit partitioning is deterministic).
//!
//! The flags go in `CARGO_ENCODED_RUSTFLAGS`: the firmware's linker arguments come from its
//! `build.rs`, so an environment RUSTFLAGS cannot drop them. Because they differ from a plain
//! build's, host binaries go to their own target folder (default `target/rig-build`), and a
//! plain `cargo build --release` keeps its cache.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};

use crate::record::{now_rfc3339, sha256_file, write_atomically};

/// File name of the build record in an output folder.
pub const BUILD_FILE: &str = "build.json";

/// A device's firmware crate: built once per config compiled in.
#[derive(Debug, Clone, Copy)]
pub struct FirmwareCrate {
    /// Where it lives in the repository (its own workspace and lock file).
    pub dir: &'static str,
    /// Its binary's name.
    pub bin: &'static str,
    /// The target it is built for.
    pub target: &'static str,
    /// The config it is built with when the rig file names none, in `dir`.
    pub default_config: &'static str,
    /// The environment variable the build reads the config's path from.
    pub config_env: &'static str,
    /// Checks a built image (repository root, ELF) as the device's CI does; an image it
    /// refuses is not an artifact.
    pub check: fn(&Path, &Path) -> Result<()>,
}

/// The host programs a rig run needs, with the package each is in: the rig and the device
/// programs it starts.
fn host_bins() -> Vec<(&'static str, &'static str)> {
    let mut bins = vec![("harness", "rig")];
    bins.extend(crate::devices::PROGRAMS);
    bins
}

/// What to build.
#[derive(Debug, Clone)]
pub struct BuildOptions {
    /// Repository root (a git checkout).
    pub repo: PathBuf,
    /// Cargo target folder for every build (firmware in `<target_dir>/firmware`).
    pub target_dir: PathBuf,
    /// Where `build.json` and the firmware images are written (`<out>/artifacts/`).
    pub out_dir: PathBuf,
    /// One firmware image per (label, MultiRX config); empty: the crate's default config.
    pub firmware_configs: Vec<(String, PathBuf)>,
    /// Build the host programs too (`rig`, bridge, router, emulator).
    pub host: bool,
}

/// The record of a build: what was built from what, with which tools.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BuildRecord {
    /// Format of this file.
    pub schema: String,
    /// `git rev-parse HEAD`.
    pub git_commit: String,
    /// Whether the work tree had uncommitted changes (`git status --porcelain` not empty):
    /// a dirty build is not reproducible from the commit alone.
    pub git_dirty: bool,
    /// The commit's time (seconds since 1970), passed as `SOURCE_DATE_EPOCH`.
    pub source_date_epoch: u64,
    /// `rustc -vV`, verbatim.
    pub rustc: String,
    /// `cargo -V`, verbatim.
    pub cargo: String,
    /// The rustflags every build got (paths in them are the builder's own).
    pub rustflags: Vec<String>,
    /// Start and end, RFC 3339 UTC.
    pub started: String,
    pub finished: String,
    /// What was built.
    pub artifacts: Vec<Artifact>,
}

/// One built file.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Artifact {
    /// The firmware's binary and config label (`<bin>-<mode>.elf`), or a program's name.
    pub name: String,
    /// `firmware` or `host`.
    pub kind: String,
    /// Where it is: relative to the output folder for firmware images (copied there),
    /// absolute for host programs (left in the target folder: tens of MB each).
    pub path: PathBuf,
    /// SHA-256 of the file, lower-case hex.
    pub sha256: String,
    /// Size in bytes.
    pub size: u64,
    /// The device config compiled into a firmware image, with its digest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub config: Option<ConfigInput>,
}

/// A config file that went into an artifact.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConfigInput {
    /// Path relative to the repository root.
    pub path: PathBuf,
    pub sha256: String,
}

impl BuildRecord {
    /// Saves the record as `build.json` in `dir`.
    pub fn save(&self, dir: &Path) -> Result<PathBuf> {
        std::fs::create_dir_all(dir)?;
        let path = dir.join(BUILD_FILE);
        let mut json = serde_json::to_vec_pretty(self)?;
        json.push(b'\n');
        write_atomically(&path, &json)
            .with_context(|| format!("cannot write {}", path.display()))?;
        Ok(path)
    }

    /// Loads a saved `build.json`.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        serde_json::from_str(&text)
            .with_context(|| format!("{}: not a build record", path.display()))
    }

    /// The host program `name` (e.g. `rig`), if it was built.
    pub fn host(&self, name: &str) -> Option<&Artifact> {
        self.artifacts
            .iter()
            .find(|a| a.kind == "host" && a.name == name)
    }
}

/// Builds what `options` asks for, showing cargo's progress on the terminal, and saves
/// `build.json`.
pub fn build(options: &BuildOptions) -> Result<BuildRecord> {
    let repo = &options.repo;
    let started = now_rfc3339();
    let git_commit = git(repo, &["rev-parse", "HEAD"])?;
    let git_dirty = !git(repo, &["status", "--porcelain"])?.is_empty();
    let source_date_epoch: u64 = git(repo, &["log", "-1", "--format=%ct"])?
        .parse()
        .context("git log gave no commit time")?;
    let rustc = tool_version(repo, "rustc", "-vV")?;
    let cargo = tool_version(repo, "cargo", "-V")?;
    let rustflags = rustflags(repo);
    let artifacts_dir = options.out_dir.join("artifacts");
    std::fs::create_dir_all(&artifacts_dir)
        .with_context(|| format!("cannot create {}", artifacts_dir.display()))?;
    let env = BuildEnv {
        rustflags: rustflags.clone(),
        source_date_epoch,
    };

    let mut artifacts = Vec::new();
    let firmware = crate::devices::FIRMWARE;
    let configs = if options.firmware_configs.is_empty() {
        vec![(
            "default".to_owned(),
            repo.join(firmware.dir).join(firmware.default_config),
        )]
    } else {
        options.firmware_configs.clone()
    };
    let firmware_target = options.target_dir.join("firmware");
    for (label, config) in &configs {
        eprintln!(
            "rig build: firmware with {} ({label})",
            config.strip_prefix(repo).unwrap_or(config).display()
        );
        let elf = build_firmware(repo, &firmware, &firmware_target, config, &env)?;
        let name = format!("{}-{label}.elf", firmware.bin);
        let copy = artifacts_dir.join(&name);
        std::fs::copy(&elf, &copy)
            .with_context(|| format!("cannot copy {} to {}", elf.display(), copy.display()))?;
        let config_rel = config.strip_prefix(repo).unwrap_or(config).to_path_buf();
        artifacts.push(Artifact {
            kind: "firmware".into(),
            path: PathBuf::from("artifacts").join(&name),
            sha256: sha256_file(&copy)?,
            size: std::fs::metadata(&copy)?.len(),
            config: Some(ConfigInput {
                path: config_rel,
                sha256: sha256_file(config)
                    .with_context(|| format!("cannot read {}", config.display()))?,
            }),
            name,
        });
    }
    if options.host {
        eprintln!(
            "rig build: host programs into {}",
            options.target_dir.display()
        );
        let mut cmd = cargo_command(repo, &env);
        cmd.args(["build", "--release", "--locked", "--bins"])
            .arg("--target-dir")
            .arg(&options.target_dir);
        let bins = host_bins();
        let mut packages: Vec<&str> = bins.iter().map(|(p, _)| *p).collect();
        packages.dedup();
        for p in packages {
            cmd.args(["-p", p]);
        }
        run(cmd, "the host programs")?;
        for (_, bin) in bins {
            let path = options.target_dir.join("release").join(bin);
            artifacts.push(Artifact {
                name: bin.into(),
                kind: "host".into(),
                sha256: sha256_file(&path)
                    .with_context(|| format!("cannot read {}", path.display()))?,
                size: std::fs::metadata(&path)?.len(),
                config: None,
                path,
            });
        }
    }
    let record = BuildRecord {
        schema: "rig-build/1".into(),
        git_commit,
        git_dirty,
        source_date_epoch,
        rustc,
        cargo,
        rustflags,
        started,
        finished: now_rfc3339(),
        artifacts,
    };
    record.save(&options.out_dir)?;
    Ok(record)
}

/// What every build gets from the environment.
struct BuildEnv {
    rustflags: Vec<String>,
    source_date_epoch: u64,
}

/// The flags that make paths in the binaries independent of where the tree and cargo's
/// registry are.
fn rustflags(repo: &Path) -> Vec<String> {
    let mut flags = vec![format!("--remap-path-prefix={}=/src", repo.display())];
    let cargo_home = std::env::var_os("CARGO_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cargo")));
    if let Some(home) = cargo_home {
        flags.push(format!("--remap-path-prefix={}=/cargo", home.display()));
    }
    flags
}

fn cargo_command(dir: &Path, env: &BuildEnv) -> Command {
    let mut cmd = Command::new("cargo");
    cmd.current_dir(dir)
        .env("CARGO_ENCODED_RUSTFLAGS", env.rustflags.join("\x1f"))
        .env_remove("RUSTFLAGS")
        .env("SOURCE_DATE_EPOCH", env.source_date_epoch.to_string())
        .env("CARGO_INCREMENTAL", "0")
        // Cargo's own progress bar, even when stderr is not a terminal (CI logs).
        .env("CARGO_TERM_PROGRESS_WHEN", "auto");
    cmd
}

/// Builds the firmware with `config` compiled in; returns the ELF's path.
fn build_firmware(
    repo: &Path,
    firmware: &FirmwareCrate,
    target_dir: &Path,
    config: &Path,
    env: &BuildEnv,
) -> Result<PathBuf> {
    let crate_dir = repo.join(firmware.dir);
    let mut cmd = cargo_command(&crate_dir, env);
    cmd.args(["build", "--release", "--locked"])
        .arg("--target-dir")
        .arg(target_dir)
        .env(firmware.config_env, config);
    run(cmd, &format!("the firmware with {}", config.display()))?;
    let elf = target_dir
        .join(firmware.target)
        .join("release")
        .join(firmware.bin);
    (firmware.check)(repo, &elf)?;
    Ok(elf)
}

fn run(mut cmd: Command, what: &str) -> Result<()> {
    let status = cmd
        .status()
        .with_context(|| format!("cannot run cargo to build {what}"))?;
    if !status.success() {
        bail!("building {what} failed ({status})");
    }
    Ok(())
}

fn git(repo: &Path, args: &[&str]) -> Result<String> {
    let out = Command::new("git")
        .arg("-C")
        .arg(repo)
        .args(args)
        .output()
        .context("cannot run git")?;
    if !out.status.success() {
        bail!(
            "git {} in {}: {}",
            args.join(" "),
            repo.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(String::from_utf8_lossy(&out.stdout).trim().to_owned())
}

/// A tool's version output, run in `dir` so rust-toolchain.toml picks the toolchain.
fn tool_version(dir: &Path, tool: &str, flag: &str) -> Result<String> {
    let out = Command::new(tool)
        .arg(flag)
        .current_dir(dir)
        .output()
        .with_context(|| format!("cannot run {tool} {flag}"))?;
    if !out.status.success() {
        bail!("{tool} {flag} failed ({})", out.status);
    }
    Ok(String::from_utf8_lossy(&out.stdout).trim().to_owned())
}

/// The repository root containing `start` (`git rev-parse --show-toplevel`).
pub fn repo_root(start: &Path) -> Result<PathBuf> {
    Ok(PathBuf::from(git(
        start,
        &["rev-parse", "--show-toplevel"],
    )?))
}

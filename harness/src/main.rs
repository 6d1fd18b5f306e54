//! `rig`: runs C2-link scenarios on a bench or emulated, and writes evidence.
//!
//! Exit codes: see [`EXIT_CODES`] (also in `rig --help`).

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use harness::devices;
use harness::evidence::{build, certify, manifest};
use harness::multirx::firmware;
use harness::multirx::rigfile::{DeviceSetup, Mode};
use harness::record::RunOutcome;
use harness::report;
use harness::rigfile::RigFile;
use harness::runner::{self, RunOptions};

/// Every allocation counted, so the soak can show its memory stays flat.
#[global_allocator]
static HEAP: harness::heap::HeapMeter = harness::heap::HeapMeter;

/// The exit codes, as `rig --help` lists them.
const EXIT_CODES: &str = "\
Exit codes:
  0    every phase passed
  1    a phase failed or errored (results.json says which)
  2    the rig file, a device config or the command line is wrong, or --filter
       selects no phase: nothing ran, nothing was written
  130  interrupted by SIGINT, 143 by SIGTERM: results.json says `interrupted`,
       the programs the rig started were stopped";

/// Test rig for SORA-grade drone C2 links (MultiRX, MavLora).
#[derive(Debug, Parser)]
#[command(version, about, after_help = EXIT_CODES)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the scenarios a rig file describes and write results.json, junit.xml and summary.txt.
    Run {
        /// Rig file (TOML).
        #[arg(default_value = "rigs/emulated.toml")]
        rig: PathBuf,
        /// Output folder (default: the rig file's `output`, else ./rig-report).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Only run phases whose name contains this (e.g. `parallel::b_handover`).
        #[arg(long)]
        filter: Option<String>,
        /// Match --filter exactly.
        #[arg(long, requires = "filter")]
        exact: bool,
        /// List the phases instead of running them.
        #[arg(long)]
        list: bool,
    },
    /// Check a rig file and the device configs it names, without running anything.
    Check {
        #[arg(default_value = "rigs/emulated.toml")]
        rig: PathBuf,
    },
    /// Build the firmware with a mode's config from a board rig file, and flash it.
    Flash {
        #[arg(default_value = "rigs/bench.example.toml")]
        rig: PathBuf,
        /// Which mode's MultiRX config to compile in.
        #[arg(long, value_parser = mode_parser(), default_value = "parallel")]
        mode: Mode,
        /// Build and print sizes only.
        #[arg(long)]
        no_flash: bool,
    },
    /// Render junit.xml and summary.txt again from a saved results.json.
    Report { results: PathBuf },
    /// Build the firmware (and the host programs) reproducibly and write build.json:
    /// per artifact SHA-256 and size, git commit and dirty flag, toolchain versions.
    Build {
        /// Rig file whose MultiRX configs are compiled into firmware images (one per mode);
        /// without one, the firmware crate's default config.
        rig: Option<PathBuf>,
        /// Output folder for build.json and the firmware images.
        #[arg(long, default_value = "rig-build")]
        out: PathBuf,
        /// Cargo target folder (kept apart from target/release: other rustflags).
        #[arg(long, default_value = "target/rig-build")]
        target_dir: PathBuf,
        /// Firmware only (no rig, bridge, router, emulator).
        #[arg(long)]
        firmware_only: bool,
    },
    /// Build, run the suite with the programs just built, and write a sealed evidence folder:
    /// report.html, trace matrix, results.json, junit.xml, traces, SBOM, in-toto statements,
    /// MANIFEST.sha256 (signed with --key).
    #[command(after_help = CERTIFY_EXIT_CODES)]
    Certify {
        rig: PathBuf,
        /// Evidence folder (must not exist or be empty).
        #[arg(long, default_value = "evidence")]
        out: PathBuf,
        /// ed25519 private key, PKCS#8 PEM (`openssl genpkey -algorithm ed25519 -out key.pem`).
        #[arg(long)]
        key: Option<PathBuf>,
        /// Only run phases whose name contains this: the verdict is then at best PARTIAL.
        #[arg(long)]
        filter: Option<String>,
        /// Match --filter exactly.
        #[arg(long, requires = "filter")]
        exact: bool,
        /// Cargo target folder for the build.
        #[arg(long, default_value = "target/rig-build")]
        target_dir: PathBuf,
    },
    /// Re-check every digest and the signature of an evidence folder; names the file that changed.
    #[command(after_help = VERIFY_EXIT_CODES)]
    Verify {
        dir: PathBuf,
        /// The team's published public key (SPKI PEM); default: the folder's own, whose
        /// fingerprint is printed for comparison.
        #[arg(long)]
        pubkey: Option<PathBuf>,
    },
}

/// `rig certify --help`'s exit codes.
const CERTIFY_EXIT_CODES: &str = "\
Exit codes:
  0  PASS: every phase ran and passed, every requirement covered and met
  1  FAIL: a phase or a requirement's measurement failed (evidence written)
  2  nothing certified: bad rig file, requirements file, key or command line,
     a build that failed, or a suite that did not run
  3  PARTIAL: nothing failed, but the run does not show every requirement
     (--filter, an uncovered requirement, a skipped phase); evidence written";

/// `rig verify --help`'s exit codes.
const VERIFY_EXIT_CODES: &str = "\
Exit codes:
  0  every file matches MANIFEST.sha256 and the ed25519 signature is valid
  1  a file changed, was added or removed, or the signature is not valid
     (the message names the file)
  2  not an evidence folder (no manifest or seal) or a file cannot be read
  3  every digest matches but the folder is not signed";

/// `--mode`: the core's mode names, listed in `--help` as before.
fn mode_parser() -> impl clap::builder::TypedValueParser<Value = Mode> {
    use clap::builder::TypedValueParser as _;
    clap::builder::PossibleValuesParser::new(Mode::ALL.map(Mode::as_str)).map(|name| {
        name.parse::<Mode>()
            .expect("only the modes' names are possible")
    })
}

fn main() -> ExitCode {
    hostio::logging::init("warn");
    let cli = Cli::parse();
    match execute(cli.command) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("rig: error: {e:#}");
            ExitCode::from(2)
        }
    }
}

fn execute(command: Command) -> Result<ExitCode> {
    match command {
        Command::Run {
            rig,
            out,
            filter,
            exact,
            list,
        } => {
            let rig = Arc::new(RigFile::load(&rig)?);
            let out_dir = out.unwrap_or_else(|| rig.output_dir());
            let result = runner::run(
                rig.clone(),
                devices::of_rig(&rig),
                RunOptions {
                    out_dir: out_dir.clone(),
                    filter,
                    exact,
                    list,
                },
            )?;
            let (Some(record), Some(paths)) = (result.record, result.paths) else {
                return Ok(ExitCode::SUCCESS);
            };
            let summary = std::fs::read_to_string(&paths.summary)
                .with_context(|| format!("cannot read {}", paths.summary.display()))?;
            println!("\n{summary}");
            Ok(match record.outcome {
                RunOutcome::Pass => ExitCode::SUCCESS,
                _ => ExitCode::from(1),
            })
        }
        Command::Check { rig } => {
            let rig = RigFile::load(&rig)?;
            if let Some(section) = &rig.devices.multirx {
                // Read and checked by RigFile::load.
                for (&mode, loaded) in &section.device.configs {
                    println!(
                        "{}: mode {mode}: {} receivers, ok",
                        loaded.path.display(),
                        loaded.config.receivers
                    );
                }
            }
            for (name, setup) in &rig.radios {
                let preset = setup.preset.resolve()?;
                println!(
                    "radio {name}: {} ({:.0} B/s max), ok",
                    preset.name,
                    preset.max_data_rate()
                );
            }
            for (name, spec) in &rig.autopilots {
                // A missing build is not an error: its phases are reported as not run.
                match spec.available() {
                    Ok(()) => println!("autopilot {name}: {}, ok", spec.kind()),
                    Err(e) => println!(
                        "autopilot {name}: {}, its phases will not run: {e}",
                        spec.kind()
                    ),
                }
            }
            if let Some(m) = &rig.devices.mavlora {
                for suite in &m.suites {
                    println!("mavlora: suite {}", suite.as_str());
                }
                for profile in [
                    "px4-normal.toml",
                    "px4-compact.toml",
                    "ardupilot-compact.toml",
                    "ardupilot-mavlink1.toml",
                ] {
                    let path = m.profiles.join(profile);
                    mavlora::filter::Profile::load(&path)?;
                    println!("{}: ok", path.display());
                }
            }
            println!("{}: ok", rig.path.display());
            Ok(ExitCode::SUCCESS)
        }
        Command::Flash {
            rig,
            mode,
            no_flash,
        } => {
            let rig = RigFile::load(&rig)?;
            let section = rig
                .devices
                .multirx
                .as_ref()
                .context("the rig file has no [multirx] section")?;
            let DeviceSetup::Board(board) = &section.device.setup else {
                anyhow::bail!(
                    "{}: [multirx.device] is not kind = \"board\"",
                    rig.path.display()
                );
            };
            let config = &section
                .config(mode)
                .context("no config for this mode")?
                .path;
            eprintln!(
                "rig: building {} with {}...",
                board.firmware.display(),
                config.display()
            );
            let image = firmware::build(&board.firmware, config)?;
            println!(
                "{}: flash {} B, RAM {} B, sha256 {}",
                image.elf.display(),
                image.flash_bytes,
                image.ram_bytes,
                image.sha256
            );
            if !no_flash {
                let flashed = firmware::flash(board, &image)?;
                println!(
                    "flashed through {} in {:.1} s",
                    flashed.probe,
                    flashed.duration.as_secs_f64()
                );
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Build {
            rig,
            out,
            target_dir,
            firmware_only,
        } => {
            let rig = rig.map(|r| RigFile::load(&r)).transpose()?;
            let options = certify::build_options(rig.as_ref(), out, target_dir, !firmware_only)?;
            let record = build::build(&options)?;
            for a in &record.artifacts {
                println!("{}  {:>10} B  {}", a.sha256, a.size, a.path.display());
            }
            println!(
                "{}: commit {}{}",
                options.out_dir.join(build::BUILD_FILE).display(),
                record.git_commit,
                if record.git_dirty { " (dirty)" } else { "" }
            );
            Ok(ExitCode::SUCCESS)
        }
        Command::Certify {
            rig,
            out,
            key,
            filter,
            exact,
            target_dir,
        } => {
            let record = certify::certify(&certify::CertifyOptions {
                rig,
                out_dir: out.clone(),
                key,
                filter,
                exact,
                target_dir,
            })?;
            println!(
                "rig certify: {}: {}\nevidence: {}",
                record.verdict.as_str(),
                record.why,
                out.display()
            );
            Ok(ExitCode::from(record.verdict.exit_code()))
        }
        Command::Verify { dir, pubkey } => match manifest::verify(&dir, pubkey.as_deref()) {
            Ok(v) => match v.signed_by {
                Some(key) => {
                    println!(
                        "{}: {} files match MANIFEST.sha256; signed by {key}",
                        dir.display(),
                        v.files
                    );
                    Ok(ExitCode::SUCCESS)
                }
                None => {
                    println!(
                        "{}: {} files match MANIFEST.sha256; NOT signed",
                        dir.display(),
                        v.files
                    );
                    Ok(ExitCode::from(3))
                }
            },
            Err(e) => {
                eprintln!("rig verify: {}: {e}", dir.display());
                Ok(ExitCode::from(e.exit_code()))
            }
        },
        Command::Report { results } => {
            let paths = report::rerender(&results)?;
            println!("{}\n{}", paths.junit.display(), paths.summary.display());
            let outcome = harness::record::RunRecord::load(&results)?.outcome;
            if matches!(outcome, RunOutcome::Running | RunOutcome::Interrupted) {
                eprintln!(
                    "rig: {}: the run is {} (not finished): no verdict",
                    results.display(),
                    outcome.as_str()
                );
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}

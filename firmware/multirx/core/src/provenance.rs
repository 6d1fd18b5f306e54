//! Where an image was built from, as a number for its build id
//! ([`crate::boot::build_id`]): the git commit of the tree (or
//! [`UNKNOWN_COMMIT`] outside one; the emulated device leaves it out,
//! [`Source::emulator`]) and an FNV-1a 64 hash of the image's input files'
//! relative paths and contents.
//!
//! The firmware's and the emulated device's build scripts compute it when they
//! build; the rig computes it again from the tree it runs with, so a board
//! that runs an image built from other source, with the same core version and
//! config, fails the identity check instead of passing it. One function
//! serves all three, so they cannot list different inputs.
//!
//! Paths are hashed relative to the crate folder, never absolute: two
//! checkouts of one commit at different places give the same id.

use std::io;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::boot::{Fnv1a64, source_id};

/// The commit of an image built outside a git tree (a tarball, a copy).
pub const UNKNOWN_COMMIT: &str = "unknown";

/// The commit of an image named by its input files alone ([`Source::emulator`]).
pub const UNRECORDED_COMMIT: &str = "not recorded";

/// What the SAMD21 firmware is built from, relative to its crate folder
/// (`firmware/multirx/samd21`): its own sources, layouts and lock file, and
/// the sources of the two path crates it links. The config file is added
/// apart, by content, since `MULTIRX_CONFIG` may name any path.
pub const SAMD21_INPUTS: &[&str] = &[
    "Cargo.toml",
    "Cargo.lock",
    "build.rs",
    ".cargo/config.toml",
    "src",
    "memory",
    "../core/Cargo.toml",
    "../core/src",
    "../../timebase/Cargo.toml",
    "../../timebase/src",
];

/// What the emulated device is built from, relative to its crate folder
/// (`firmware/multirx/emulator`); the config is read at start, so not an input.
pub const EMULATOR_INPUTS: &[&str] = &[
    "Cargo.toml",
    "src",
    "../core/Cargo.toml",
    "../core/src",
    "../../timebase/Cargo.toml",
    "../../timebase/src",
    "../../hostio/Cargo.toml",
    "../../hostio/src",
    "../../../Cargo.lock",
];

/// An image's source: the commit and the hash of its inputs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Source {
    /// `git rev-parse HEAD` of the tree, or [`UNKNOWN_COMMIT`].
    pub commit: String,
    /// [`inputs_hash`] of the image's inputs.
    pub inputs: u64,
}

impl Source {
    /// The source of the crate at `dir` built from `inputs` (one of
    /// [`SAMD21_INPUTS`], [`EMULATOR_INPUTS`]) and, if given, the config file.
    pub fn of(dir: &Path, inputs: &[&str], config: Option<&Path>) -> io::Result<Source> {
        Ok(Source {
            commit: git_commit(dir),
            inputs: inputs_hash(dir, inputs, config)?,
        })
    }

    /// The emulated device's source: its input files ([`EMULATOR_INPUTS`]) only.
    /// The rig compiles in the id of the `multirx-emu` built beside it; with
    /// the commit in it, every commit would rebuild the rig for nothing the
    /// files do not already tell (a stale `multirx-emu` differs in its files).
    pub fn emulator(dir: &Path) -> io::Result<Source> {
        Ok(Source {
            commit: UNRECORDED_COMMIT.to_owned(),
            inputs: inputs_hash(dir, EMULATOR_INPUTS, None)?,
        })
    }

    /// The number the build id takes ([`crate::boot::source_id`]).
    pub fn id(&self) -> u64 {
        source_id(self.commit.as_bytes(), self.inputs)
    }
}

/// The commit checked out at `dir`, or [`UNKNOWN_COMMIT`] when `dir` is not in
/// a git tree or git cannot be run: a build never fails for want of git.
pub fn git_commit(dir: &Path) -> String {
    git(dir, &["rev-parse", "--verify", "-q", "HEAD"])
        .filter(|c| !c.is_empty())
        .unwrap_or_else(|| UNKNOWN_COMMIT.to_owned())
}

/// The files whose change moves HEAD (HEAD itself, the branch it names and
/// the packed refs), for a build script's `rerun-if-changed`: without them a
/// new commit that touches no input would keep the old commit in the image.
/// Empty outside a git tree.
pub fn git_head_files(dir: &Path) -> Vec<PathBuf> {
    let mut names = vec!["HEAD".to_owned(), "packed-refs".to_owned()];
    if let Some(branch) = git(dir, &["symbolic-ref", "-q", "HEAD"]) {
        names.push(branch);
    }
    names
        .iter()
        .filter_map(|name| git(dir, &["rev-parse", "--git-path", name]))
        .map(|p| dir.join(p))
        // A path that does not exist would make cargo rerun the script every build.
        .filter(|p| p.exists())
        .collect()
}

/// The `inputs` (relative to `dir`) that exist, for a build script's
/// `rerun-if-changed`: cargo reruns a script every build for a path that does
/// not exist (an optional file such as `.cargo/config.toml`).
pub fn existing_inputs(dir: &Path, inputs: &[&str]) -> Vec<PathBuf> {
    inputs
        .iter()
        .map(|i| dir.join(i))
        .filter(|p| p.exists())
        .collect()
}

fn git(dir: &Path, args: &[&str]) -> Option<String> {
    let out = Command::new("git")
        .arg("-C")
        .arg(dir)
        .args(args)
        .output()
        .ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_owned())
}

/// FNV-1a 64 over every file under `inputs` (files or folders, relative to
/// `dir`, walked in sorted order): each file's relative path, length and
/// contents, then the config file's contents if given. A missing input is
/// hashed as missing rather than failing, so an optional file (a crate
/// without `.cargo/config.toml`) does not stop a build; an unreadable one is
/// an error.
pub fn inputs_hash(dir: &Path, inputs: &[&str], config: Option<&Path>) -> io::Result<u64> {
    let mut hasher = Fnv1a64::new();
    for input in inputs {
        let mut files = Vec::new();
        collect(dir, Path::new(input), &mut files)?;
        if files.is_empty() {
            hasher = hasher
                .bytes(b"missing\0")
                .bytes(input.as_bytes())
                .bytes(b"\0");
        }
        for rel in files {
            let bytes = std::fs::read(dir.join(&rel))?;
            // Separators as `/` so a Windows checkout names files as Linux does.
            let name = rel.to_string_lossy().replace('\\', "/");
            hasher = hasher
                .bytes(b"file\0")
                .bytes(name.as_bytes())
                .bytes(b"\0")
                .bytes(&(bytes.len() as u64).to_le_bytes())
                .bytes(&bytes);
        }
    }
    if let Some(config) = config {
        let bytes = std::fs::read(config)?;
        hasher = hasher
            .bytes(b"config\0")
            .bytes(&(bytes.len() as u64).to_le_bytes())
            .bytes(&bytes);
    }
    Ok(hasher.finish())
}

/// Every file at or under `dir/rel`, relative to `dir`, sorted.
fn collect(dir: &Path, rel: &Path, out: &mut Vec<PathBuf>) -> io::Result<()> {
    let path = dir.join(rel);
    let meta = match std::fs::metadata(&path) {
        Ok(m) => m,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e),
    };
    if meta.is_file() {
        out.push(rel.to_path_buf());
        return Ok(());
    }
    let mut entries = std::fs::read_dir(&path)?
        .map(|e| e.map(|e| e.file_name()))
        .collect::<io::Result<Vec<_>>>()?;
    entries.sort();
    for name in entries {
        collect(dir, &rel.join(name), out)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boot::{ImageKind, build_id};

    fn tree() -> PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "multirx-provenance-{}-{:?}",
            std::process::id(),
            std::thread::current().id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("crate/src/sub")).unwrap();
        std::fs::write(dir.join("crate/Cargo.toml"), "[package]\n").unwrap();
        std::fs::write(dir.join("crate/src/main.rs"), "fn main() {}\n").unwrap();
        std::fs::write(dir.join("crate/src/sub/a.rs"), "// a\n").unwrap();
        std::fs::write(dir.join("config.toml"), "mode = \"scan\"\n").unwrap();
        dir
    }

    const INPUTS: &[&str] = &["Cargo.toml", "src", ".cargo/config.toml"];

    #[test]
    fn a_changed_input_changes_the_build_id() {
        let dir = tree();
        let krate = dir.join("crate");
        let config = dir.join("config.toml");
        let id = |s: &Source| build_id(ImageKind::Samd21, 7, s.id());
        let before = Source::of(&krate, INPUTS, Some(&config)).unwrap();
        assert_eq!(
            before,
            Source::of(&krate, INPUTS, Some(&config)).unwrap(),
            "same tree, same source"
        );

        // A source file deep in a folder.
        std::fs::write(krate.join("src/sub/a.rs"), "// b\n").unwrap();
        let edited = Source::of(&krate, INPUTS, Some(&config)).unwrap();
        assert_ne!(id(&before), id(&edited));

        // A new file, and a renamed one with the same contents.
        std::fs::write(krate.join("src/sub/b.rs"), "").unwrap();
        let added = Source::of(&krate, INPUTS, Some(&config)).unwrap();
        assert_ne!(edited.inputs, added.inputs);
        std::fs::rename(krate.join("src/sub/b.rs"), krate.join("src/sub/c.rs")).unwrap();
        assert_ne!(
            added.inputs,
            inputs_hash(&krate, INPUTS, Some(&config)).unwrap()
        );

        // The config file, even a comment in it.
        let before_config = inputs_hash(&krate, INPUTS, Some(&config)).unwrap();
        std::fs::write(&config, "mode = \"scan\" # x\n").unwrap();
        assert_ne!(
            before_config,
            inputs_hash(&krate, INPUTS, Some(&config)).unwrap()
        );

        // An optional input appearing.
        let before_cargo = inputs_hash(&krate, INPUTS, None).unwrap();
        std::fs::create_dir_all(krate.join(".cargo")).unwrap();
        std::fs::write(krate.join(".cargo/config.toml"), "").unwrap();
        assert_ne!(before_cargo, inputs_hash(&krate, INPUTS, None).unwrap());

        // The commit alone.
        let other_commit = Source {
            commit: "0123abcd".into(),
            ..before.clone()
        };
        assert_ne!(id(&before), id(&other_commit));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_same_tree_elsewhere_has_the_same_inputs() {
        let a = tree();
        let b = a.with_extension("copy");
        let _ = std::fs::remove_dir_all(&b);
        std::fs::create_dir_all(b.join("crate/src/sub")).unwrap();
        for f in [
            "crate/Cargo.toml",
            "crate/src/main.rs",
            "crate/src/sub/a.rs",
        ] {
            std::fs::copy(a.join(f), b.join(f)).unwrap();
        }
        assert_eq!(
            inputs_hash(&a.join("crate"), INPUTS, None).unwrap(),
            inputs_hash(&b.join("crate"), INPUTS, None).unwrap()
        );
        std::fs::remove_dir_all(&a).unwrap();
        std::fs::remove_dir_all(&b).unwrap();
    }

    #[test]
    fn outside_git_the_commit_is_unknown_not_an_error() {
        // The root folder is in no git tree on any machine this runs on.
        assert_eq!(git_commit(Path::new("/")), UNKNOWN_COMMIT);
        assert!(git_head_files(Path::new("/")).is_empty());
    }
}

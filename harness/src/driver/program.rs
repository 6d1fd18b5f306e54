//! The device programs the rig starts when the rig file names none (each device module names
//! its own): built by the same `cargo build` as `rig`, so they are found next to it (or one folder up: a test binary
//! runs from `target/<profile>/deps/`).

use std::path::PathBuf;

/// A program of this workspace the rig starts, and how to build it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Program {
    /// The executable's file name.
    pub name: &'static str,
    /// The command that builds it.
    pub build: &'static str,
}

/// A program is not where it should be.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{} not found: build it with `{build}` (same profile as rig)", path.display())]
pub struct ProgramMissing {
    /// Where it was looked for.
    pub path: PathBuf,
    /// The command that builds it.
    pub build: &'static str,
}

impl Program {
    /// Where it is: next to the running executable, else one folder up; next to the
    /// executable if in neither (where an error should point); the bare name, to be found on
    /// `PATH`, if the running executable cannot be located.
    pub fn path(self) -> PathBuf {
        let Ok(exe) = std::env::current_exe() else {
            return PathBuf::from(self.name);
        };
        let here = exe.with_file_name(self.name);
        match exe
            .parent()
            .and_then(|p| p.parent())
            .map(|p| p.join(self.name))
        {
            Some(up) if !here.exists() && up.exists() => up,
            _ => here,
        }
    }

    /// [`Program::path`] if it exists.
    pub fn find(self) -> Result<PathBuf, ProgramMissing> {
        let path = self.path();
        if path.exists() {
            Ok(path)
        } else {
            Err(self.missing(path))
        }
    }

    /// The error for this program not being at `path`.
    pub fn missing(self, path: PathBuf) -> ProgramMissing {
        ProgramMissing {
            path,
            build: self.build,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_program_says_how_to_build_it() {
        let p = Program {
            name: "no-such-program",
            build: "cargo build -p nothing",
        };
        let e = p.find().unwrap_err();
        assert!(e.path.ends_with("no-such-program"), "{e}");
        assert!(
            e.to_string().ends_with(
                "not found: build it with `cargo build -p nothing` (same profile as rig)"
            ),
            "{e}"
        );
    }
}

//! The bench lock: a run of a rig file with `[rig] lock = "..."` holds an exclusive `flock` on
//! that file for as long as it runs, so two CI jobs (or a person and a job) never drive the same
//! hardware at once. The kernel drops the lock when the process ends, however it ends: no stale
//! lock files to clean up.

use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};

use rustix::fs::{FlockOperation, flock};

/// Errors taking the lock.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// The lock file cannot be created or opened.
    #[error("bench lock {path}: cannot open: {source}")]
    Open {
        path: PathBuf,
        source: std::io::Error,
    },
    /// `flock` failed for another reason than "held by someone else".
    #[error("bench lock {path}: {source}")]
    Flock {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// A held bench lock; released when dropped (or when the process ends).
#[derive(Debug)]
pub struct BenchLock {
    _file: File,
    pub path: PathBuf,
}

/// Whether the lock was free or had to be waited for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Taken {
    AtOnce,
    AfterWaiting,
}

impl BenchLock {
    /// Takes the lock at `path`, waiting (and saying so on stderr) while another run holds it.
    pub fn acquire(path: &Path) -> Result<(Self, Taken), LockError> {
        let file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(path)
            .map_err(|source| LockError::Open {
                path: path.to_owned(),
                source,
            })?;
        let flock_err = |e: rustix::io::Errno| LockError::Flock {
            path: path.to_owned(),
            source: e.into(),
        };
        let taken = match flock(&file, FlockOperation::NonBlockingLockExclusive) {
            Ok(()) => Taken::AtOnce,
            Err(rustix::io::Errno::WOULDBLOCK) => {
                eprintln!(
                    "rig: bench lock {} is held by another run: waiting for it",
                    path.display()
                );
                flock(&file, FlockOperation::LockExclusive).map_err(flock_err)?;
                Taken::AfterWaiting
            }
            Err(e) => return Err(flock_err(e)),
        };
        Ok((
            BenchLock {
                _file: file,
                path: path.to_owned(),
            },
            taken,
        ))
    }

    /// Takes the lock only if it is free now; `None` if another run holds it.
    pub fn try_acquire(path: &Path) -> Result<Option<Self>, LockError> {
        let file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(path)
            .map_err(|source| LockError::Open {
                path: path.to_owned(),
                source,
            })?;
        match flock(&file, FlockOperation::NonBlockingLockExclusive) {
            Ok(()) => Ok(Some(BenchLock {
                _file: file,
                path: path.to_owned(),
            })),
            Err(rustix::io::Errno::WOULDBLOCK) => Ok(None),
            Err(e) => Err(LockError::Flock {
                path: path.to_owned(),
                source: e.into(),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_holder_is_refused_until_the_first_lets_go() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bench-7.lock");
        let (first, taken) = BenchLock::acquire(&path).unwrap();
        assert_eq!(taken, Taken::AtOnce);
        // flock locks belong to the open file description: a second open is a second holder,
        // as another process would be.
        assert!(BenchLock::try_acquire(&path).unwrap().is_none());
        drop(first);
        assert!(BenchLock::try_acquire(&path).unwrap().is_some());
    }

    #[test]
    fn a_waiting_run_gets_the_lock_when_the_holder_ends() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bench.lock");
        let (first, _) = BenchLock::acquire(&path).unwrap();
        let p = path.clone();
        let waiter = std::thread::spawn(move || BenchLock::acquire(&p).unwrap().1);
        std::thread::sleep(std::time::Duration::from_millis(100));
        assert!(!waiter.is_finished(), "the second run must wait");
        drop(first);
        assert_eq!(waiter.join().unwrap(), Taken::AfterWaiting);
    }

    #[test]
    fn an_unwritable_lock_path_names_the_file() {
        let err = BenchLock::acquire(Path::new("/nonexistent-dir/bench.lock"))
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("bench lock /nonexistent-dir/bench.lock"),
            "{err}"
        );
    }
}

//! The signing state file (MAVLink signing spec: store the timestamp at least once a minute;
//! see [`SigningState`]): read at start, written atomically (temporary file, fsync, rename)
//! at start, every [`SAVE_EVERY`] and at exit. A lock file next to it keeps two processes
//! from sharing one state (the bridge and router on one host must not, and each needs its
//! own: the default path carries the binary's role). The router's ground key has one too, so
//! a restart refuses what the ground stations sent before it as the radio link does.

use std::fs::{File, OpenOptions};
use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context as _;

use super::signing_epoch_now;
use crate::Duration;
use crate::signing::{SigningConfig, SigningKey, SigningState};
use crate::time::Instant;

/// How often the state is written while running (the spec asks for at least once a minute;
/// a crash loses what was accepted since, which a replay could then reuse within a minute).
pub const SAVE_EVERY: Duration = Duration::from_secs(10);

/// One process's signing state file, locked for the process's lifetime.
#[derive(Debug)]
pub struct SigningStateFile {
    path: PathBuf,
    _lock: File,
    next_save: Option<Instant>,
}

impl SigningStateFile {
    /// The default state file of a key: `<key>.<role>-state` beside it.
    pub fn default_path(key: &Path, role: &str) -> PathBuf {
        let mut name = key.as_os_str().to_owned();
        name.push(format!(".{role}-state"));
        PathBuf::from(name)
    }

    /// Locks `path` for this process and reads what a previous run stored (nothing yet: a
    /// fresh state). Fails naming the file if it is in use, unreadable or malformed.
    pub fn open(path: PathBuf) -> anyhow::Result<(Self, SigningState)> {
        let lock_path = sibling(&path, ".lock");
        let lock = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&lock_path)
            .with_context(|| format!("signing state lock {}", lock_path.display()))?;
        match lock.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => anyhow::bail!(
                "signing state {} is in use by another process (each bridge and router needs \
                 its own: --signing-state)",
                path.display()
            ),
            Err(std::fs::TryLockError::Error(e)) => {
                return Err(e).with_context(|| format!("locking {}", lock_path.display()));
            }
        }
        // Bounded by what a state can hold: a timestamp and one line per stream, at most
        // 256 links × 65,536 senders; well under 64 MiB.
        let state = match crate::input_file::read_to_string(&path, 64 << 20) {
            Ok(text) => SigningState::parse(&text)
                .with_context(|| format!("signing state {}", path.display()))?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                // A first start, or a lost file: nothing of the peer is taken until it answers
                // our challenge (the radio leg's handshake), but our own timestamps come from
                // the clock, and only the operator knows whether it is right.
                tracing::warn!(
                    path = %path.display(),
                    "no signing state: starting a new one from this clock, which must be right \
                     within a minute (check `date -u` if this is not a first start); the peer \
                     must prove it is live before its frames are taken"
                );
                SigningState::default()
            }
            Err(e) => {
                return Err(e).with_context(|| format!("signing state {}", path.display()));
            }
        };
        Ok((
            Self {
                path,
                _lock: lock,
                next_save: None,
            },
            state,
        ))
    }

    /// Signing with `key` as link `link_id` from the clock now, resuming from the state file
    /// at `path` ([`open`](Self::open): locked and read), which is written back at once so
    /// that a path that cannot be written fails at start, not at the first save. A state
    /// stamped more than a minute ahead of the clock is an error naming the file
    /// ([`SigningState::check_ahead`]). For the radio key and the router's ground key alike.
    pub fn resume(
        path: PathBuf,
        key: SigningKey,
        link_id: u8,
    ) -> anyhow::Result<(Self, SigningConfig)> {
        let (file, state) = Self::open(path)?;
        let config = SigningConfig {
            key,
            link_id,
            epoch: signing_epoch_now(),
            state,
        };
        // Refused, not clamped: lowering a stored stream timestamp would accept again what
        // was accepted before, and the file names what to check (the clock, then the file).
        config
            .state
            .check_ahead(config.epoch)
            .with_context(|| format!("signing state {}", file.path().display()))?;
        file.save(&config.signer().state(Instant::ZERO))?;
        tracing::info!(state = %file.path().display(), "signing state");
        Ok((file, config))
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes `state` atomically: a reader (or a crash) sees the old or the new file whole.
    pub fn save(&self, state: &SigningState) -> anyhow::Result<()> {
        let tmp = sibling(&self.path, ".tmp");
        let write = || -> std::io::Result<()> {
            let mut options = OpenOptions::new();
            options.create(true).truncate(true).write(true);
            #[cfg(unix)]
            std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
            let mut f = options.open(&tmp)?;
            f.write_all(state.to_text().as_bytes())?;
            f.sync_all()?;
            std::fs::rename(&tmp, &self.path)?;
            if let Some(dir) = self.path.parent().filter(|d| !d.as_os_str().is_empty()) {
                // the rename itself survives a power loss once the directory is synced
                File::open(dir)?.sync_all()?;
            }
            Ok(())
        };
        write().with_context(|| format!("writing signing state {}", self.path.display()))
    }

    /// Saves `state()` if [`SAVE_EVERY`] passed since the last save (the first call saves);
    /// a failed save is logged, not fatal (the next one may succeed; the exit save reports).
    pub fn tick(&mut self, now: Instant, state: impl FnOnce() -> Option<SigningState>) {
        if self.next_save.is_some_and(|due| now < due) {
            return;
        }
        self.next_save = Some(now + SAVE_EVERY);
        if let Some(state) = state()
            && let Err(e) = self.save(&state)
        {
            tracing::warn!("{e:#}");
        }
    }
}

fn sibling(path: &Path, suffix: &str) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(suffix);
    PathBuf::from(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn saves_atomically_reads_back_and_refuses_a_second_user() {
        let dir = std::env::temp_dir().join(format!("mavlora-state-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("radio.key.bridge-state");
        let _ = std::fs::remove_file(&path);
        let (file, fresh) = SigningStateFile::open(path.clone()).unwrap();
        assert_eq!(fresh, SigningState::default());
        let mut state = SigningState {
            timestamp: 42,
            ..Default::default()
        };
        state.streams.insert((2, 255, 190), 41);
        file.save(&state).unwrap();
        let second = SigningStateFile::open(path.clone())
            .unwrap_err()
            .to_string();
        assert!(second.contains("in use by another process"), "{second}");
        drop(file);
        let (_file, read) = SigningStateFile::open(path.clone()).unwrap();
        assert_eq!(read, state);
        std::fs::write(&path, "garbage\n").unwrap();
        drop(_file);
        let bad = format!("{:#}", SigningStateFile::open(path.clone()).unwrap_err());
        assert!(
            bad.contains("radio.key.bridge-state") && bad.contains("line 1"),
            "{bad}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

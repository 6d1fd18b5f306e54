//! Programs the rig starts (the emulated device, fixtures): stderr goes to a
//! log file kept as evidence; they are stopped when dropped.
//!
//! Nothing outlives the rig: each program runs in its own process group (so a
//! terminal's Ctrl-C reaches the rig, which decides), is listed while it runs so
//! [`kill_all`] can end every group when the rig is interrupted, and on Linux
//! gets `SIGKILL` from the kernel if the rig dies without cleaning up
//! (`PR_SET_PDEATHSIG`).

use std::fs::File;
use std::os::unix::process::CommandExt as _;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, ExitStatus, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use rustix::process::{Pid, Signal};

/// Process groups (= the leaders' pids) of the programs running now.
static RUNNING: Mutex<Vec<i32>> = Mutex::new(Vec::new());

fn running() -> std::sync::MutexGuard<'static, Vec<i32>> {
    RUNNING
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Ends every program the rig started and has not stopped yet, with whatever
/// they started: `SIGTERM` to each process group, then `SIGKILL` after `grace`.
/// For an interrupted rig, which exits right after.
pub fn kill_all(grace: Duration) {
    let groups = std::mem::take(&mut *running());
    let signal_all = |signal| {
        for &pgid in &groups {
            if let Some(pid) = Pid::from_raw(pgid) {
                let _ = rustix::process::kill_process_group(pid, signal);
            }
        }
    };
    signal_all(Signal::TERM);
    if !groups.is_empty() {
        std::thread::sleep(grace);
    }
    signal_all(Signal::KILL);
}

/// Puts the program in a process group of its own and, on Linux, has the
/// kernel kill it when the rig dies.
fn detach_and_tie(command: &mut Command) {
    command.process_group(0);
    #[cfg(target_os = "linux")]
    {
        let rig = rustix::process::getpid();
        // SAFETY: the closure runs between fork and exec and only makes system
        // calls (prctl, getppid, _exit), which are async-signal-safe.
        #[allow(unsafe_code)]
        unsafe {
            command.pre_exec(move || {
                rustix::process::set_parent_process_death_signal(Some(Signal::KILL))?;
                // The rig may have died before the prctl: then nobody will send it.
                if rustix::process::getppid() != Some(rig) {
                    libc::_exit(1);
                }
                Ok(())
            });
        }
    }
}

/// A started program.
pub struct Process {
    name: String,
    child: Child,
    log: PathBuf,
}

impl Process {
    /// Starts `command` with stdin and stdout piped and stderr to `log`.
    pub fn spawn(name: &str, mut command: Command, log: &Path) -> Result<Process> {
        let stderr =
            File::create(log).with_context(|| format!("cannot create {}", log.display()))?;
        command
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(stderr);
        Self::start(name, command, log)
    }

    /// Starts `command` with stdout and stderr both to `log` and stdin closed: a program that
    /// talks only through its ports and prints as it goes (a SITL), which a pipe nobody reads
    /// would stall.
    pub fn spawn_logged(name: &str, mut command: Command, log: &Path) -> Result<Process> {
        let out = File::create(log).with_context(|| format!("cannot create {}", log.display()))?;
        let err = out
            .try_clone()
            .with_context(|| format!("cannot reopen {}", log.display()))?;
        command.stdin(Stdio::null()).stdout(out).stderr(err);
        Self::start(name, command, log)
    }

    /// Spawns `command`, its standard streams already set, in a process group of its own
    /// tied to the rig, and registers it for [`kill_all`].
    fn start(name: &str, mut command: Command, log: &Path) -> Result<Process> {
        let program = command.get_program().to_string_lossy().into_owned();
        detach_and_tie(&mut command);
        let child = command
            .spawn()
            .with_context(|| format!("cannot start {name} ({program})"))?;
        tracing::debug!(name, pid = child.id(), "started");
        running().push(child.id() as i32);
        Ok(Process {
            name: name.to_string(),
            child,
            log: log.to_path_buf(),
        })
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// The process id (for reading its `/proc` entry).
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    pub fn log_path(&self) -> &Path {
        &self.log
    }

    pub fn take_stdin(&mut self) -> Option<ChildStdin> {
        self.child.stdin.take()
    }

    pub fn take_stdout(&mut self) -> Option<ChildStdout> {
        self.child.stdout.take()
    }

    /// Fails if the program has already exited (e.g. a bad argument).
    pub fn check_running(&mut self) -> Result<()> {
        if let Some(status) = self.child.try_wait()? {
            let log = std::fs::read_to_string(&self.log).unwrap_or_default();
            let tail: Vec<&str> = log.lines().rev().take(5).collect();
            anyhow::bail!(
                "{} exited early ({status}); last lines of {}:\n{}",
                self.name,
                self.log.display(),
                tail.into_iter().rev().collect::<Vec<_>>().join("\n")
            );
        }
        Ok(())
    }

    /// Waits up to `timeout` for the program to exit by itself; `None` if it still runs.
    pub fn wait_timeout(&mut self, timeout: Duration) -> Result<Option<ExitStatus>> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(status) = self.child.try_wait()? {
                return Ok(Some(status));
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Like [`Process::stop`], but says how it ended: the exit status after
    /// SIGTERM, or `None` if it had to be killed (a clean stop is evidence too).
    pub fn terminate(&mut self, grace: Duration) -> Result<Option<ExitStatus>> {
        if let Some(status) = self.child.try_wait()? {
            return Ok(Some(status));
        }
        if let Some(pid) = rustix::process::Pid::from_raw(self.child.id() as i32) {
            let _ = rustix::process::kill_process(pid, rustix::process::Signal::TERM);
        }
        if let Some(status) = self.wait_timeout(grace)? {
            return Ok(Some(status));
        }
        tracing::warn!(name = %self.name, "did not stop on SIGTERM; killing");
        let _ = self.child.kill();
        let _ = self.child.wait();
        Ok(None)
    }

    /// Kills the program at once (SIGKILL: a crash) and reaps it.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// Asks the program to stop (SIGTERM), then kills it after `grace`.
    pub fn stop(&mut self, grace: Duration) {
        if let Ok(Some(_)) = self.child.try_wait() {
            return;
        }
        if let Some(pid) = rustix::process::Pid::from_raw(self.child.id() as i32) {
            let _ = rustix::process::kill_process(pid, rustix::process::Signal::TERM);
        }
        let deadline = Instant::now() + grace;
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        tracing::warn!(name = %self.name, "did not stop on SIGTERM; killing");
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        self.stop(Duration::from_secs(2));
        let pid = self.child.id() as i32;
        running().retain(|&p| p != pid);
    }
}

//! What the end-to-end tests share: the repository root, a child-process guard, pty pairs,
//! temp folders and free ports, a binary run to its end, the checks of a status JSON file
//! ([`status_json`]).
// Each test program uses its own part of this.
#![allow(dead_code)]

pub mod status_json;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::thread;
use std::time::{Duration, Instant};

/// The repository root, where `fixtures/` and `firmware/` are.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Kills a child on drop so a failing test leaves no processes behind.
pub struct Guard(pub Option<Child>, pub &'static str);

impl Guard {
    /// SIGTERM, then wait up to 5 s; returns whether it exited with status 0.
    pub fn terminate(&mut self) -> bool {
        let Some(mut child) = self.0.take() else {
            return false;
        };
        let _ = Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status();
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if let Ok(Some(status)) = child.try_wait() {
                return status.success();
            }
            thread::sleep(Duration::from_millis(50));
        }
        let _ = child.kill();
        let _ = child.wait();
        eprintln!("{} did not stop on SIGTERM", self.1);
        false
    }
}

impl Drop for Guard {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// A pty pair whose descriptors are not inherited: serialport opens them without
/// close-on-exec, so a router spawned by a test running alongside would hold this pair's
/// master open and closing it here would never hang the line up.
pub fn pty_pair() -> (serialport::TTYPort, serialport::TTYPort) {
    let (master, slave) = serialport::TTYPort::pair().unwrap();
    for port in [&master, &slave] {
        use std::os::fd::{AsRawFd, BorrowedFd};
        // SAFETY: the descriptor belongs to `port`, alive for this call.
        let fd = unsafe { BorrowedFd::borrow_raw(port.as_raw_fd()) };
        rustix::io::fcntl_setfd(fd, rustix::io::FdFlags::CLOEXEC).unwrap();
    }
    (master, slave)
}

/// A folder of the test's own, `mavlora-<name>-<pid>` in the temp folder.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mavlora-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A local TCP (and, in practice, UDP) port nobody uses now.
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Runs `bin` with `args` in `dir` until it exits (killed after 10 s): its exit code and
/// stderr (logging at `info`, no colours).
pub fn run(bin: &str, dir: &Path, args: &[&str]) -> (Option<i32>, String) {
    let mut child = Command::new(bin)
        .args(args)
        .current_dir(dir)
        .env("RUST_LOG", "info")
        .env("NO_COLOR", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    while child.try_wait().unwrap().is_none() && Instant::now() < deadline {
        thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

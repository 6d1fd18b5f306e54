//! What the tests and benchmarks that run the host programs (`mavlora-bridge`,
//! `mavlora-router`) on real ptys share:
//!
//! - [`pty_pair`]: a pty pair whose descriptors a spawned child does not inherit;
//! - [`Guard`]: a child process killed on drop, or stopped with SIGTERM by
//!   [`Guard::terminate`].
//!
//! Test support only: no device program links it. It lives beside the firmware so that
//! MavLora's tests and the rig's benchmarks can both use it without either linking the
//! other's test code.

use std::os::fd::{AsRawFd, BorrowedFd};
use std::process::{Child, Command};
use std::thread;
use std::time::{Duration, Instant};

use serialport::TTYPort;

/// Kills a child on drop so a failing test leaves no processes behind. The name is for
/// messages.
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

/// A pty pair (master, slave) whose descriptors are not inherited: serialport opens them
/// without close-on-exec, so a program spawned by a test running alongside would hold this
/// pair's master open, and closing it here would never hang the line up.
pub fn pty_pair() -> (TTYPort, TTYPort) {
    let (master, slave) = TTYPort::pair().expect("pty pair");
    for port in [&master, &slave] {
        // SAFETY: the descriptor belongs to `port`, alive for this call.
        let fd = unsafe { BorrowedFd::borrow_raw(port.as_raw_fd()) };
        rustix::io::fcntl_setfd(fd, rustix::io::FdFlags::CLOEXEC).expect("close-on-exec");
    }
    (master, slave)
}

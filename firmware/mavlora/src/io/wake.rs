//! Waiting on a port with no timeout, yet stoppable: a thread blocked in `poll` on its port
//! also watches a pipe that another thread writes a byte into (a writer that failed, a stop).
//! A reader that woke every 50–100 ms to look at flags would cost CPU on an idle link.

use std::os::fd::{BorrowedFd, OwnedFd};
use std::time::Duration;

use rustix::event::{PollFd, PollFlags, Timespec, poll};
use rustix::io::Errno;
use rustix::pipe::{PipeFlags, pipe_with};

/// The read and write ends of a wake-up pipe.
#[derive(Debug)]
pub struct Wake {
    read: OwnedFd,
    write: OwnedFd,
}

/// What [`Wake::wait_readable`] saw first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ready {
    /// The port has bytes, or an error or hang-up to report (its read says which).
    Port,
    /// Someone called [`Wake::wake`].
    Woken,
    /// The timeout passed.
    Timeout,
}

impl Wake {
    /// A new pipe (close-on-exec, non-blocking).
    pub fn new() -> std::io::Result<Self> {
        let (read, write) = pipe_with(PipeFlags::CLOEXEC | PipeFlags::NONBLOCK)?;
        Ok(Self { read, write })
    }

    /// Interrupts a [`wait_readable`](Self::wait_readable) in progress or the next one.
    pub fn wake(&self) {
        // A full pipe already holds a wake-up: nothing is lost by EAGAIN.
        let _ = rustix::io::write(&self.write, &[1]);
    }

    /// Waits until `port` is readable, [`wake`](Self::wake) is called, or `timeout` passes
    /// (`None`: no timeout). A wake-up is consumed.
    pub fn wait_readable(
        &self,
        port: BorrowedFd<'_>,
        timeout: Option<Duration>,
    ) -> std::io::Result<Ready> {
        let timeout = timeout.map(|t| Timespec {
            tv_sec: t.as_secs() as _,
            tv_nsec: t.subsec_nanos() as _,
        });
        let mut fds = [
            PollFd::new(&port, PollFlags::IN),
            PollFd::new(&self.read, PollFlags::IN),
        ];
        match poll(&mut fds, timeout.as_ref()) {
            Ok(0) => Ok(Ready::Timeout),
            Ok(_) if !fds[1].revents().is_empty() => {
                let mut buf = [0u8; 64];
                while matches!(rustix::io::read(&self.read, &mut buf), Ok(n) if n > 0) {}
                Ok(Ready::Woken)
            }
            Ok(_) => Ok(Ready::Port),
            Err(Errno::INTR) => Ok(Ready::Woken),
            Err(e) => Err(e.into()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::fd::AsFd;

    #[test]
    fn a_wake_interrupts_a_wait_without_timeout_and_is_consumed() {
        let (port_read, _port_write) = pipe_with(PipeFlags::CLOEXEC).unwrap();
        let wake = std::sync::Arc::new(Wake::new().unwrap());
        let w = wake.clone();
        let waker = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(50));
            w.wake();
        });
        assert_eq!(
            wake.wait_readable(port_read.as_fd(), None).unwrap(),
            Ready::Woken
        );
        waker.join().unwrap();
        // Consumed: the next wait times out.
        let t = Some(Duration::from_millis(10));
        assert_eq!(
            wake.wait_readable(port_read.as_fd(), t).unwrap(),
            Ready::Timeout
        );
    }

    #[test]
    fn bytes_on_the_port_make_it_ready() {
        let (port_read, port_write) = pipe_with(PipeFlags::CLOEXEC).unwrap();
        rustix::io::write(&port_write, b"x").unwrap();
        let wake = Wake::new().unwrap();
        assert_eq!(
            wake.wait_readable(port_read.as_fd(), None).unwrap(),
            Ready::Port
        );
    }
}

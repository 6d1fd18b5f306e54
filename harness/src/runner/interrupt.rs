//! SIGINT and SIGTERM during a run: the handler only writes the signal's number
//! to a pipe (async-signal-safe); a thread reads it and does the real work
//! (finalise the record, kill the children, exit) outside signal context.
//!
//! Handlers are reset by `exec`, so the programs the rig starts get the default
//! dispositions.

use std::io;
use std::sync::atomic::{AtomicI32, Ordering};

/// Write end of the pipe the handler writes to; -1 before [`on_interrupt`].
static PIPE: AtomicI32 = AtomicI32::new(-1);

extern "C" fn handler(signal: libc::c_int) {
    let fd = PIPE.load(Ordering::Relaxed);
    if fd >= 0 {
        let byte = signal as u8;
        // SAFETY: write(2) is async-signal-safe; the buffer is one live byte.
        #[allow(unsafe_code)]
        unsafe {
            libc::write(fd, (&raw const byte).cast(), 1);
        }
    }
}

/// The signals that stop a run, with the exit code the rig then uses (128 +
/// the signal's number, as a shell reports a process killed by it).
pub const SIGNALS: [(libc::c_int, &str); 2] =
    [(libc::SIGINT, "SIGINT"), (libc::SIGTERM, "SIGTERM")];

/// Calls `then(signal number, name)` on a thread of its own at the first
/// SIGINT or SIGTERM. `then` is expected to exit the process.
pub fn on_interrupt(then: impl FnOnce(i32, &'static str) + Send + 'static) -> io::Result<()> {
    let mut fds = [0; 2];
    // SAFETY: pipe2 and sigaction with a zeroed, then filled, sigaction; the
    // handler is an `extern "C" fn(c_int)`.
    #[allow(unsafe_code)]
    unsafe {
        if libc::pipe2(fds.as_mut_ptr(), libc::O_CLOEXEC) != 0 {
            return Err(io::Error::last_os_error());
        }
        PIPE.store(fds[1], Ordering::Relaxed);
        for (signal, _) in SIGNALS {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = handler as extern "C" fn(libc::c_int) as libc::sighandler_t;
            action.sa_flags = libc::SA_RESTART;
            libc::sigemptyset(&mut action.sa_mask);
            if libc::sigaction(signal, &action, std::ptr::null_mut()) != 0 {
                return Err(io::Error::last_os_error());
            }
        }
    }
    let read_fd = fds[0];
    std::thread::Builder::new()
        .name("rig-interrupt".into())
        .spawn(move || {
            loop {
                let mut byte = 0u8;
                // SAFETY: reads one byte into a live buffer from our own pipe.
                #[allow(unsafe_code)]
                let n = unsafe { libc::read(read_fd, (&raw mut byte).cast(), 1) };
                if n == 1 {
                    let signal = i32::from(byte);
                    let name = SIGNALS
                        .iter()
                        .find(|(s, _)| *s == signal)
                        .map_or("signal", |(_, name)| name);
                    then(signal, name);
                    return;
                }
                if n < 0 && io::Error::last_os_error().kind() == io::ErrorKind::Interrupted {
                    continue;
                }
                return;
            }
        })?;
    Ok(())
}

/// Waits for the interrupt handler to end the process: called by a thread that found the run
/// interrupted, so that it does not end the process first with another exit code.
pub fn wait_for_exit() -> ! {
    loop {
        std::thread::park();
    }
}

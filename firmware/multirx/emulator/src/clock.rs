//! The emulated board's clock.
//!
//! A board's timer interrupt is never late; a host thread is, whenever the
//! host does not run it: a loaded machine, or a virtual machine whose vCPU is
//! descheduled (a busy loop at SCHED_FIFO on an idle 2-vCPU CI VM sees holes
//! of 10-40 ms, several a second, whatever the program). So the engine runs on
//! a device clock that stands still while the host holds the device:
//!
//! - while the loop runs, the time it was runnable but not run: host time
//!   minus the thread's CPU time, which on Linux excludes preemption and a
//!   hypervisor's steal (mostly: now and then a hole is counted as CPU time);
//!   and in any case everything past a pass's budget: [`IDLE_PASS`] for a
//!   poll that found nothing to do, [`WORK_PASS`] for handling an input or
//!   a deadline. The emulated rig judges the engine's schedule (a skipped
//!   frame, a loop that blocks), not its speed on the board's 48 MHz core,
//!   which only the bench can measure;
//! - a stretch of the loop's own work in which the thread blocked of its own
//!   accord (a voluntary context switch) is the device's own delay and is
//!   never held;
//! - handing bytes to a port is held whole: the board's UART shifts them out
//!   in the background, the host's write (syscalls, tty layer, VM exits,
//!   where a vCPU is often descheduled, and whose holes the CPU clock
//!   sometimes counts as CPU time) is the emulation's cost, not the device's;
//! - while it sleeps, how long it took to run once it could have: past the
//!   wake-up it asked for, or past the input that woke it.
//!
//! Every accounting returns its instant, and the engine is given that one as
//! "now" (and the TX probe stamps a frame with it): a hold after it belongs to
//! the next accounting, so the engine never sees time a hold has not yet been
//! taken out of (it would reset its frame grid to a late time).
//!
//! Nothing the device decides is excused: an engine that skips a frame or a
//! loop that blocks still shows as a gap in device time. The TX probe writes
//! the total held with each frame, so the rig judges the cadence in device
//! time and reports the host's holes apart.

use std::time::{Duration, Instant as HostInstant};

use multirx_core::Instant;

/// Longest an idle pass of the loop (a poll that finds nothing to do: no
/// syscall, no allocation, about a microsecond) may take on its own; beyond
/// it the host took the time.
pub const IDLE_PASS: Duration = Duration::from_micros(50);

/// Longest a pass that handles an input or a deadline (and builds a frame)
/// may take on its own: about 10 µs on a CI host, a hundred times that here.
pub const WORK_PASS: Duration = Duration::from_millis(1);

/// A pass that blocked for longer is logged: it is the device's own delay.
const BLOCKED_NOTE: Duration = Duration::from_millis(2);

/// Host time to device time and back, with the host's holds taken out.
#[derive(Debug)]
pub struct DeviceClock {
    epoch: HostInstant,
    /// CLOCK_MONOTONIC at `epoch` (std's `Instant` reads the same clock on
    /// Linux but does not show it).
    monotonic_epoch: Duration,
    held: Duration,
    mark: Mark,
}

/// Where the last accounting left off.
#[derive(Debug, Clone, Copy)]
struct Mark {
    host: HostInstant,
    cpu: Duration,
    voluntary_switches: i64,
}

impl Mark {
    fn now() -> Mark {
        let cpu = rustix::time::clock_gettime(rustix::time::ClockId::ThreadCPUTime);
        Mark {
            host: HostInstant::now(),
            cpu: Duration::new(cpu.tv_sec as u64, cpu.tv_nsec as u32),
            voluntary_switches: voluntary_switches(),
        }
    }
}

/// Context switches the calling thread made of its own accord (it blocked).
fn voluntary_switches() -> i64 {
    let mut usage = std::mem::MaybeUninit::<libc::rusage>::zeroed();
    // SAFETY: getrusage writes a whole `rusage` into the buffer it is given;
    // RUSAGE_THREAD is valid on Linux, the only host the emulator runs on.
    let rc = unsafe { libc::getrusage(libc::RUSAGE_THREAD, usage.as_mut_ptr()) };
    if rc != 0 {
        // Cannot tell: count it as blocking, so nothing is held.
        return i64::MAX;
    }
    // SAFETY: initialised by the successful call above.
    unsafe { usage.assume_init() }.ru_nvcsw
}

impl DeviceClock {
    /// Device time zero is now; call from the thread that runs the device.
    pub fn new() -> DeviceClock {
        let mark = Mark::now();
        let mono = rustix::time::clock_gettime(rustix::time::ClockId::Monotonic);
        DeviceClock {
            epoch: mark.host,
            monotonic_epoch: Duration::new(mono.tv_sec as u64, mono.tv_nsec as u32),
            held: Duration::ZERO,
            mark,
        }
    }

    /// The loop worked since the last accounting: holds what the host took,
    /// at least all past [`WORK_PASS`].
    pub fn ran(&mut self) -> HostInstant {
        self.account(WORK_PASS)
    }

    /// The loop only polled since the last accounting, and found nothing to
    /// do: holds what the host took, at least all past [`IDLE_PASS`].
    pub fn idled(&mut self) -> HostInstant {
        self.account(IDLE_PASS)
    }

    fn account(&mut self, pass: Duration) -> HostInstant {
        let now = Mark::now();
        let blocked = now.voluntary_switches != self.mark.voluntary_switches
            || now.voluntary_switches == i64::MAX;
        let host = now.host.saturating_duration_since(self.mark.host);
        if !blocked {
            let not_run = host.saturating_sub(now.cpu.saturating_sub(self.mark.cpu));
            self.held += not_run.max(host.saturating_sub(pass));
        } else if host > BLOCKED_NOTE {
            // The device's own delay, and it will show as an output gap: say where.
            tracing::info!(
                blocked_ms = host.as_secs_f64() * 1000.0,
                cpu_ms = now.cpu.saturating_sub(self.mark.cpu).as_secs_f64() * 1000.0,
                "the loop blocked of its own accord"
            );
        }
        self.mark = now;
        now.host
    }

    /// The loop slept since the last accounting and could have run again
    /// from `ready` (the wake-up it asked for, or the input that woke it):
    /// holds how long it took.
    pub fn woke(&mut self, ready: HostInstant) -> HostInstant {
        let now = Mark::now();
        self.held += now.host.saturating_duration_since(ready);
        self.mark = now;
        now.host
    }

    /// The loop handed bytes to a port since the last accounting: all of
    /// it is held (on the board, DMA and the UART do it in the background).
    pub fn handed_off(&mut self) -> HostInstant {
        let now = Mark::now();
        self.held += now.host.saturating_duration_since(self.mark.host);
        self.mark = now;
        now.host
    }

    /// `t` on CLOCK_MONOTONIC (what the rig and the fixtures read), for the
    /// TX probe.
    pub fn monotonic(&self, t: HostInstant) -> Duration {
        self.monotonic_epoch + t.saturating_duration_since(self.epoch)
    }

    /// Total time held so far.
    pub fn held(&self) -> Duration {
        self.held
    }

    /// Device time at host time `t`.
    pub fn device(&self, t: HostInstant) -> Instant {
        let since = t
            .saturating_duration_since(self.epoch)
            .saturating_sub(self.held);
        Instant::from_micros(since.as_micros() as u64)
    }

    /// Host time at which device time `t` comes, as things stand.
    pub fn host(&self, t: Instant) -> HostInstant {
        self.epoch + self.held + Duration::from(t.since_epoch())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_thread_that_blocks_of_its_own_accord_is_not_held() {
        let mut clock = DeviceClock::new();
        // A blocking read: a voluntary switch, the device's own delay.
        let (_tx, rx) = std::sync::mpsc::channel::<()>();
        let _ = rx.recv_timeout(Duration::from_millis(30));
        clock.ran();
        assert_eq!(clock.held(), Duration::ZERO);
    }

    #[test]
    fn a_late_wake_up_is_held_and_moves_device_time() {
        let mut clock = DeviceClock::new();
        let asked = HostInstant::now();
        std::thread::sleep(Duration::from_millis(20));
        clock.woke(asked);
        assert!(
            clock.held() >= Duration::from_millis(20),
            "{:?}",
            clock.held()
        );
        let now = HostInstant::now();
        let device = Duration::from(clock.device(now).since_epoch());
        assert!(device < Duration::from_millis(5), "{device:?}");
        // And back: host time of a device time comes later by what was held.
        assert!(clock.host(Instant::from_micros(0)) >= clock.epoch + clock.held());
    }

    #[test]
    fn a_pass_longer_than_its_budget_is_held() {
        // Pretend each pass started 5 ms ago (a hole the CPU clock missed).
        let mut clock = DeviceClock::new();
        clock.mark.host -= Duration::from_millis(5);
        clock.idled();
        assert!(clock.held() >= Duration::from_millis(5) - IDLE_PASS);
        let mut clock = DeviceClock::new();
        clock.mark.host -= Duration::from_millis(5);
        clock.ran();
        assert!(clock.held() >= Duration::from_millis(5) - WORK_PASS);
    }

    #[test]
    fn handing_bytes_to_a_port_is_held_whole() {
        let mut clock = DeviceClock::new();
        std::thread::sleep(Duration::from_millis(5));
        clock.handed_off();
        assert!(clock.held() >= Duration::from_millis(5));
    }

    #[test]
    fn busy_work_is_device_time() {
        let mut clock = DeviceClock::new();
        let start = HostInstant::now();
        while start.elapsed() < Duration::from_millis(20) {
            std::hint::spin_loop();
        }
        clock.ran();
        let device = Duration::from(clock.device(HostInstant::now()).since_epoch());
        // On a quiet host nearly all of it; a loaded one may hold some, but
        // device time never runs ahead of host time.
        assert!(
            device <= start.elapsed() + Duration::from_millis(1),
            "{device:?}"
        );
        assert!(clock.held() <= start.elapsed());
    }
}

//! On the board MultiRX owns its MCU; on a shared host the output cadence, and
//! the rig's timestamps of it, are only as steady as the scheduler lets them be.
//! Asking for real-time priority approximates the board; without it (no
//! CAP_SYS_NICE) we run as we can.

use thread_priority::unix::{
    RealtimeThreadSchedulePolicy, ThreadSchedulePolicy, set_thread_priority_and_policy,
    thread_native_id,
};
use thread_priority::{ThreadPriority, ThreadPriorityValue};

/// Puts the calling thread in SCHED_FIFO; logs and carries on if refused.
pub fn request(what: &str) {
    let priority = ThreadPriorityValue::try_from(50u8).expect("50 is a valid priority");
    let result = set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(priority),
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    );
    match result {
        Ok(()) => tracing::debug!(thread = what, "real-time priority"),
        Err(e) => {
            tracing::info!(thread = what, error = ?e, "real-time priority refused; timing follows host load")
        }
    }
}

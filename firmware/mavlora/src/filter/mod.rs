//! The paper's two bandwidth mechanisms, driven by one [`Profile`]: stream-rate requests to
//! the flight controller ([`set_message_interval_requests`]) and per-message filtering and
//! rate limiting on the way to the radio ([`RadioFilter`]).

mod limiter;
mod profile;
mod stream_rate;

pub use limiter::{FilterStats, RadioFilter, Verdict};
pub use profile::{
    COMPACT_BATCH_PERIOD_MS, COMPACT_COALESCE_MS, COMPACT_SAMPLE_HZ, COMPACT_STATUS_PERIOD_MS,
    DATA_STREAMS, MAX_RATE_HZ, MIN_RATE_HZ, MessageRule, Profile, ProfileError, RadioRule,
    Unlisted,
};
pub use stream_rate::{
    request_data_stream_requests, set_message_interval_requests, state_interval_requests,
};

//! The link budget scheduler: never offers the radio more than its byte rate, sends commands,
//! acks and mission traffic before periodic telemetry, and keeps only the newest sample of
//! each periodic message.

mod bucket;
mod class;
mod scheduler;

pub use bucket::TokenBucket;
pub use class::Class;
pub use scheduler::{LinkScheduler, ScheduleError, SchedulerConfig, SchedulerStats};

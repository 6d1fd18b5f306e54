//! The link budget scheduler: never offers the radio more than its byte rate, sends commands
//! and acks first, shares the rest between transfers, status text, parameters and telemetry
//! by weight (fair between origins), and keeps only the newest sample of each periodic
//! message.

mod bucket;
mod class;
mod fair;
mod scheduler;

pub use bucket::TokenBucket;
pub use class::Class;
pub use fair::Origin;
pub use scheduler::{LinkScheduler, ScheduleError, SchedulerConfig, SchedulerStats};

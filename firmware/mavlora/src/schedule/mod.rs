//! The link budget scheduler: never offers the radio more than its byte rate, sends commands
//! and acks first, shares the rest between transfers, status text, parameters and telemetry
//! by weight (fair between origins), and keeps only the newest sample of each periodic
//! message. [`TxbufPacer`] moves the byte rate by the radio's report of its free buffer;
//! [`RadioBacklog`] keeps what the radio holds unsent short, so a backlog waits here instead.

mod backlog;
mod bucket;
mod class;
mod fair;
mod pacer;
mod scheduler;

pub use backlog::{DEFAULT_RADIO_BACKLOG, RadioBacklog};
pub use bucket::TokenBucket;
pub use class::Class;
pub use fair::Origin;
pub use pacer::TxbufPacer;
pub use scheduler::{LinkScheduler, ScheduleError, SchedulerConfig, SchedulerStats};

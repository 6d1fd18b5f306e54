//! Evidence a reviewer can check offline: a reproducible [`build`] with its record, and
//! (by `rig certify`) an evidence folder of the run, its report and digests.
pub mod build;
pub mod certify;
pub mod trace;
pub mod manifest;

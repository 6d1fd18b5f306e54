//! Strategies bring a rig from files on disk to devices running and wired
//! (labgrid's vocabulary): build → (flash) → running → torn down.

pub mod boot_check;
pub mod firmware;
pub mod mavlora;
pub mod multirx;

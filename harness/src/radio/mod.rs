//! Line-of-sight radio models for the link emulator (issue 4): placeholder
//! module, filled in by the radio work.

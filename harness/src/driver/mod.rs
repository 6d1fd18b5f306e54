//! Drivers bind resources that every device's rig uses (labgrid's vocabulary): pty pairs and
//! serial ports, child processes, fixture programs (one driver, [`fixture`]), the device
//! programs of this workspace, the radio emulator, SiK radios' AT command set ([`sik`]),
//! programmable step attenuators ([`attenuator`]). Device-specific drivers live in the
//! device's folder.

pub mod attenuator;
pub mod autopilot;
pub mod fixture;
pub mod process;
pub mod program;
pub mod pty;
pub mod radio_emulator;
pub mod sik;

//! Wire formats: a zero-copy view over bytes plus an owned representation
//! (after smoltcp `wire/`).

pub mod sbus;

pub use sbus::{Channels, Flags, Footer, SbusFrame, SbusRepr};

/// Why bytes are not a well-formed frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum WireError {
    /// The buffer is shorter than a frame.
    #[error("truncated: {len} bytes, a frame needs {need}")]
    Truncated { len: usize, need: usize },
    /// The first byte is not the SBUS header 0x0F.
    #[error("bad header byte {0:#04x}, expected 0x0f")]
    BadHeader(u8),
    /// The last byte is not an SBUS or SBUS2 footer.
    #[error("bad footer byte {0:#04x}, expected 0x00 or an SBUS2 footer")]
    BadFooter(u8),
    /// The flags byte has bits set that no receiver sets.
    #[error("flags byte {0:#04x} has reserved bits set")]
    BadFlags(u8),
}

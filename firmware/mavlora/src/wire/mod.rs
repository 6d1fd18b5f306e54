//! MAVLink on the wire: frame views, the stream reader and its counters.
//!
//! Everything here works on raw frames. Routing needs only header fields, so payloads are
//! never decoded unless a caller asks ([`Frame::decode`]).

mod frame;
pub mod ids;
pub mod known;
mod reader;
mod resequence;
mod sender;
mod stats;
mod version;

pub use frame::{
    Frame, FrameError, IFLAG_SIGNED, MAX_FRAME_LEN, OwnedFrame, SIGNATURE_LEN, STX_V1, STX_V2,
    encode,
};
pub use reader::{Authenticator, CrcExtraFn, FrameReader, Integrity, Received};
pub use resequence::Resequencer;
pub use sender::Sender;
pub use stats::{ReaderStats, StreamCounters, StreamId};
pub use version::{crc_extra_of, to_v1, to_v2};

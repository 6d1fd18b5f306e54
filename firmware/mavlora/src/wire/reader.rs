//! Sans-IO stream reader: bytes in, raw frames out, resynchronising after garbage.
//!
//! Why not the `mavlink` crate's reader: it pulls from a `std::io::Read` (not sans-IO), drops
//! bad-checksum frames without counting them, and rejects message ids outside its dialect,
//! which a router must forward. Its frame decoder is crate-private, so the framing rules are
//! reimplemented here on top of its CRC and constants.
//!
//! Rules, chosen so that the output depends only on the bytes, never on how they were split
//! into chunks:
//! - a candidate starts at a start byte (0xFE v1, 0xFD v2) and is decided only once all of
//!   its announced bytes are buffered;
//! - a known message id is accepted iff its checksum matches; otherwise the reader counts a
//!   bad CRC and retries from the next byte, so a frame hidden inside a corrupted one is kept;
//! - an unknown message id cannot be checked: it is accepted unless a checksum-valid frame of
//!   a known id starts inside it (garbage must not swallow a good frame); deciding that may
//!   wait for the inner candidate's bytes;
//! - at end of input ([`FrameReader::finish`]) incomplete candidates are dropped as garbage;
//!   so are they when the caller knows no more bytes of them will come
//!   ([`FrameReader::flush_partial`]: the end of a datagram, or a serial line idle for longer
//!   than the frame would take), and frames buffered behind them come out.
//!
//! One exception, for a signed link ([`FrameReader::with_authenticator`]): while a candidate
//! waits for its bytes, a complete frame inside it that carries a valid signature of the link's
//! key makes the candidate garbage at once. Ten bytes announcing a 280-byte frame, sent by
//! anyone every 0.4 s, otherwise held every frame behind them until 280 more bytes came
//! (1.8 s for a command's ack on LoRa). A genuine frame never carries a whole frame signed
//! with the link's key in its payload (nothing tunnels the link's own frames), so this
//! departs from "the bytes alone decide" only where someone forged the candidate.

use tracing::debug;

use super::frame::{Frame, OwnedFrame, STX_V1, STX_V2, announced_len};
use super::known;
use super::stats::{ReaderStats, StreamId};

/// Whether an accepted frame's checksum was verified.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Integrity {
    /// Known message id and the checksum matched.
    Checked,
    /// Unknown message id: no CRC_EXTRA, so the checksum could not be verified.
    Unchecked,
}

/// One frame accepted by the reader.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Received {
    /// The frame, exactly as on the wire.
    pub frame: OwnedFrame,
    /// Whether its checksum was verified.
    pub integrity: Integrity,
}

/// Looks up the CRC_EXTRA of a message id; `None` for ids the reader should forward unchecked.
pub type CrcExtraFn = fn(u32) -> Option<u8>;

/// Tells whether a whole signed frame carries a valid signature of the link's key (the
/// signature only: timestamps and replays are the verifier's business).
pub trait Authenticator: std::fmt::Debug + Send + Sync {
    /// `frame` is a whole, signed MAVLink 2 frame.
    fn authentic(&self, frame: &[u8]) -> bool;
}

/// When a frame counts as received (frames, per-stream sequence numbers, loss).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Counting {
    /// As the reader takes it off the byte stream.
    OnRead,
    /// Only once the caller accepts it ([`FrameReader::accept`]): a signed radio link, where a
    /// frame nobody signed must move neither the frame count nor the loss (injected frames
    /// with the peer's ids and made-up sequence numbers read as a "88 % lost" link, or fill a
    /// real gap and hide it).
    OnAccept,
}

/// What the bytes at one position are.
enum Candidate {
    /// Not all bytes needed to decide have arrived.
    NeedMore,
    /// Not a frame start (or unsupported flags): skip one byte.
    Invalid,
    /// Known id, checksum failed.
    BadCrc(StreamId),
    /// Unknown id whose span contains a valid known frame: skip one byte.
    HidesValid,
    /// A frame of this many bytes.
    Frame(usize, Integrity),
}

/// Sans-IO MAVLink frame reader: [`push`](Self::push) bytes as they arrive, then take frames
/// with [`next_frame`](Self::next_frame) until it returns `None`.
#[derive(Debug)]
pub struct FrameReader {
    buf: Vec<u8>,
    /// Bytes before `start` are consumed; compacted on the next push.
    start: usize,
    /// The input has ended: incomplete candidates are garbage, not "wait for more".
    finished: bool,
    crc_extra: CrcExtraFn,
    counting: Counting,
    authenticator: Option<std::sync::Arc<dyn Authenticator>>,
    stats: ReaderStats,
}

impl Default for FrameReader {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameReader {
    /// A reader that checks every message of the MavLora dialect (common + ours) and of
    /// ArduPilot's (`ardupilotmega.xml`), so an autopilot's own messages are checked and never
    /// wait on the unknown-id rule below.
    pub fn new() -> Self {
        Self::with_crc_extra(known::checkable_crc_extra)
    }

    /// A reader with another dialect's CRC_EXTRA table.
    pub fn with_crc_extra(crc_extra: CrcExtraFn) -> Self {
        Self {
            buf: Vec::new(),
            start: 0,
            finished: false,
            crc_extra,
            counting: Counting::OnRead,
            authenticator: None,
            stats: ReaderStats::default(),
        }
    }

    /// This reader on a signed link: a waiting candidate with a complete frame inside it
    /// that `authenticator` vouches for is dropped at once (counted in `partials_dropped`);
    /// see the module doc.
    pub fn with_authenticator(mut self, authenticator: std::sync::Arc<dyn Authenticator>) -> Self {
        self.authenticator = Some(authenticator);
        self
    }

    /// As [`new`](Self::new), but a frame counts as received (in [`ReaderStats::frames`],
    /// its stream's sequence and loss) only when the caller [`accept`](Self::accept)s it,
    /// after checking its signature. Garbage, bad checksums and partial frames count as read.
    pub fn counting_accepted() -> Self {
        Self {
            counting: Counting::OnAccept,
            ..Self::new()
        }
    }

    /// Counts `frame`, which [`next_frame`](Self::next_frame) returned with `integrity`, as
    /// received (a [`counting_accepted`](Self::counting_accepted) reader; the others counted
    /// it already, and this does nothing).
    pub fn accept<T: AsRef<[u8]>>(&mut self, frame: &Frame<T>, integrity: Integrity) {
        if self.counting == Counting::OnAccept {
            self.record(frame, integrity);
        }
    }

    fn record<T: AsRef<[u8]>>(&mut self, frame: &Frame<T>, integrity: Integrity) {
        let stream = StreamId {
            system: frame.system_id(),
            component: frame.component_id(),
        };
        self.stats
            .record_frame(stream, frame.sequence(), integrity == Integrity::Checked);
    }

    /// Appends received bytes. Pushing bytes after [`finish`](Self::finish) starts a new
    /// input (a reopened port), keeping the counters; pushing nothing changes nothing.
    pub fn push(&mut self, bytes: &[u8]) {
        if self.start > 0 {
            self.buf.drain(..self.start);
            self.start = 0;
        }
        if !bytes.is_empty() {
            self.finished = false;
        }
        self.buf.extend_from_slice(bytes);
    }

    /// Gives up on the partial frame the reader is waiting on, if any (call once
    /// [`next_frame`](Self::next_frame) returned `None`): its bytes become garbage, frames
    /// buffered behind it come out of the next [`next_frame`](Self::next_frame) calls, and
    /// `partials_dropped` counts it. Returns whether there was one. The next bytes pushed
    /// start a new input, as after [`finish`](Self::finish).
    ///
    /// Without it a reader waits for a partial frame's announced length however long that
    /// takes: 10 bytes starting `FD FF` held the next command for 11 s.
    pub fn flush_partial(&mut self) -> bool {
        if self.buffered() == 0 {
            return false;
        }
        self.stats.partials_dropped += 1;
        self.finished = true;
        true
    }

    /// Declares the end of input: buffered incomplete candidates become garbage, so frames
    /// queued behind them come out of [`next_frame`](Self::next_frame).
    pub fn finish(&mut self) {
        self.finished = true;
    }

    /// Bytes buffered and not yet decided.
    pub fn buffered(&self) -> usize {
        self.buf.len() - self.start
    }

    /// Counters so far.
    pub fn stats(&self) -> &ReaderStats {
        &self.stats
    }

    /// See [`ReaderStats::expect_restart`].
    pub fn expect_restart(&mut self, said_by: StreamId) {
        self.stats.expect_restart(said_by);
    }

    /// The next complete frame, or `None` until more bytes arrive.
    pub fn next_frame(&mut self) -> Option<Received> {
        loop {
            let data = &self.buf[self.start..];
            let Some(skip) = data.iter().position(|&b| b == STX_V1 || b == STX_V2) else {
                self.stats.garbage_bytes += data.len() as u64;
                self.start = self.buf.len();
                return None;
            };
            self.stats.garbage_bytes += skip as u64;
            self.start += skip;

            match self.classify(self.start) {
                Candidate::NeedMore => {
                    let inner = self.authentic_frame_inside(self.start)?;
                    debug!(
                        skipped = inner - self.start,
                        "a signed frame inside a waiting candidate: the candidate is garbage"
                    );
                    self.stats.partials_dropped += 1;
                    self.stats.garbage_bytes += (inner - self.start) as u64;
                    self.start = inner;
                }
                Candidate::Invalid | Candidate::HidesValid => {
                    self.stats.garbage_bytes += 1;
                    self.start += 1;
                }
                Candidate::BadCrc(stream) => {
                    debug!(
                        system = stream.system,
                        component = stream.component,
                        "bad checksum, resynchronising"
                    );
                    self.stats.record_bad_crc(stream);
                    self.stats.garbage_bytes += 1;
                    self.start += 1;
                }
                Candidate::Frame(len, integrity) => {
                    let bytes = self.buf[self.start..self.start + len].to_vec();
                    self.start += len;
                    let frame = Frame::new_unchecked(bytes);
                    if self.counting == Counting::OnRead {
                        self.record(&frame, integrity);
                    }
                    return Some(Received { frame, integrity });
                }
            }
        }
    }

    /// Decides what the bytes at `pos` are.
    fn classify(&self, pos: usize) -> Candidate {
        match self.classify_known(pos) {
            Candidate::Frame(len, Integrity::Unchecked) => {
                // Unknown id: accept only if no valid known frame starts inside it.
                for inner in pos + 1..pos + len {
                    let b = self.buf[inner];
                    if b != STX_V1 && b != STX_V2 {
                        continue;
                    }
                    match self.classify_known(inner) {
                        Candidate::NeedMore => return Candidate::NeedMore,
                        Candidate::Frame(_, Integrity::Checked) => return Candidate::HidesValid,
                        _ => {}
                    }
                }
                Candidate::Frame(len, Integrity::Unchecked)
            }
            other => other,
        }
    }

    /// The first position after `pos` where a complete frame signed with the link's key
    /// starts, if the reader has an authenticator.
    fn authentic_frame_inside(&self, pos: usize) -> Option<usize> {
        let auth = self.authenticator.as_ref()?;
        (pos + 1..self.buf.len()).find(|&inner| {
            if self.buf[inner] != STX_V2 {
                return false;
            }
            let Candidate::Frame(len, _) = self.classify_known(inner) else {
                return false;
            };
            let bytes = &self.buf[inner..inner + len];
            Frame::new_unchecked(bytes).is_signed() && auth.authentic(bytes)
        })
    }

    /// Decides the candidate at `pos` on its own bytes only.
    fn classify_known(&self, pos: usize) -> Candidate {
        let data = &self.buf[pos..];
        let len = match announced_len(data) {
            Err(_) => return Candidate::Invalid,
            Ok(None) => return self.incomplete(),
            Ok(Some(len)) if len > data.len() => return self.incomplete(),
            Ok(Some(len)) => len,
        };
        let frame = Frame::new_unchecked(&data[..len]);
        match (self.crc_extra)(frame.message_id()) {
            None => Candidate::Frame(len, Integrity::Unchecked),
            Some(extra) if frame.crc_matches(extra) => Candidate::Frame(len, Integrity::Checked),
            Some(_) => Candidate::BadCrc(StreamId {
                system: frame.system_id(),
                component: frame.component_id(),
            }),
        }
    }

    fn incomplete(&self) -> Candidate {
        if self.finished {
            Candidate::Invalid
        } else {
            Candidate::NeedMore
        }
    }
}

#[cfg(test)]
mod tests;

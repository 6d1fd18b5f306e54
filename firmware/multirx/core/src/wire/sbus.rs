//! The SBUS frame: 25 bytes, 16 channels of 11 bits packed LSB-first.
//!
//! ```text
//!  byte 0     1 ..= 22                 23                          24
//!  0x0F       ch1..ch16, 11 bits each  flags: b0 ch17, b1 ch18,    footer: 0x00, or
//!             LSB first                b2 frame lost, b3 failsafe  SBUS2 0x04/0x14/0x24/0x34
//! ```
//!
//! There is no checksum: UART parity is the only integrity check, so the
//! header, footer and reserved flag bits are all we can validate here.

use super::WireError;

/// Raw channel values, 0..=2047 (receivers send about 172..=1811).
pub type Channels = [u16; SbusFrame::<&[u8]>::CHANNELS];

mod field {
    use core::ops::Range;
    pub const HEADER: usize = 0;
    pub const CHANNELS: Range<usize> = 1..23;
    pub const FLAGS: usize = 23;
    pub const FOOTER: usize = 24;
}

/// First byte of every frame.
pub const HEADER: u8 = 0x0F;

/// The UART SBUS runs on, a protocol fact (every receiver, board and adapter uses it):
/// 100000 baud, 8 data bits, even parity, 2 stop bits ("8E2"), on an inverted line.
pub const BAUD: u32 = 100_000;
/// Data bits of a UART character: see [`BAUD`].
pub const DATA_BITS: u8 = 8;
/// Parity of a UART character: see [`BAUD`].
pub const PARITY: Parity = Parity::Even;
/// Stop bits of a UART character: see [`BAUD`].
pub const STOP_BITS: u8 = 2;

/// UART parity.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Parity {
    /// No parity bit.
    None,
    /// Odd parity.
    Odd,
    /// Even parity.
    Even,
}

const FLAG_CH17: u8 = 0x01;
const FLAG_CH18: u8 = 0x02;
const FLAG_FRAME_LOST: u8 = 0x04;
const FLAG_FAILSAFE: u8 = 0x08;
const FLAG_RESERVED: u8 = 0xF0;

/// A read/write view of an SBUS frame in a byte buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SbusFrame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> SbusFrame<T> {
    /// Bytes in a frame.
    pub const LEN: usize = 25;
    /// Proportional channels in a frame.
    pub const CHANNELS: usize = 16;
    /// Largest raw channel value (11 bits).
    pub const MAX_VALUE: u16 = 0x7FF;

    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        SbusFrame { buffer }
    }

    /// Wraps a buffer and checks that it holds a well-formed frame.
    pub fn new_checked(buffer: T) -> Result<Self, WireError> {
        let frame = Self::new_unchecked(buffer);
        frame.check_len()?;
        frame.check_framing()?;
        Ok(frame)
    }

    /// Ensures that accessors will not panic.
    pub fn check_len(&self) -> Result<(), WireError> {
        let len = self.buffer.as_ref().len();
        if len < Self::LEN {
            Err(WireError::Truncated {
                len,
                need: Self::LEN,
            })
        } else {
            Ok(())
        }
    }

    /// Checks header, footer and reserved flag bits.
    pub fn check_framing(&self) -> Result<(), WireError> {
        if self.header() != HEADER {
            return Err(WireError::BadHeader(self.header()));
        }
        if Footer::from_byte(self.footer_byte()).is_none() {
            return Err(WireError::BadFooter(self.footer_byte()));
        }
        if self.flags_byte() & FLAG_RESERVED != 0 {
            return Err(WireError::BadFlags(self.flags_byte()));
        }
        Ok(())
    }

    pub fn into_inner(self) -> T {
        self.buffer
    }

    pub fn header(&self) -> u8 {
        self.buffer.as_ref()[field::HEADER]
    }

    pub fn flags_byte(&self) -> u8 {
        self.buffer.as_ref()[field::FLAGS]
    }

    pub fn footer_byte(&self) -> u8 {
        self.buffer.as_ref()[field::FOOTER]
    }

    /// Channel `index` (0-based, < 16).
    ///
    /// # Panics
    /// If `index` >= 16.
    pub fn channel(&self, index: usize) -> u16 {
        assert!(index < Self::CHANNELS, "SBUS has 16 proportional channels");
        let data = &self.buffer.as_ref()[field::CHANNELS];
        let bit = index * 11;
        let byte = bit / 8;
        let shift = bit % 8;
        // 11 bits starting at `shift` span at most three bytes.
        let mut word = u32::from(data[byte]) | (u32::from(data[byte + 1]) << 8);
        if byte + 2 < data.len() {
            word |= u32::from(data[byte + 2]) << 16;
        }
        ((word >> shift) & u32::from(Self::MAX_VALUE)) as u16
    }

    /// All 16 channels, unpacked in one pass (what the engine does per frame sent out;
    /// per [`SbusFrame::channel`] it costs the Cortex-M0+ several times as much).
    pub fn channels(&self) -> Channels {
        let data = &self.buffer.as_ref()[field::CHANNELS];
        let mut channels = [0u16; 16];
        let mut bytes = data.iter();
        let (mut acc, mut bits) = (0u32, 0u32);
        for channel in &mut channels {
            while bits < 11 {
                acc |= u32::from(bytes.next().copied().unwrap_or(0)) << bits;
                bits += 8;
            }
            *channel = (acc & u32::from(Self::MAX_VALUE)) as u16;
            acc >>= 11;
            bits -= 11;
        }
        channels
    }

    pub fn flags(&self) -> Flags {
        Flags::from_byte(self.flags_byte())
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> SbusFrame<T> {
    pub fn set_header(&mut self) {
        self.buffer.as_mut()[field::HEADER] = HEADER;
    }

    pub fn set_flags_byte(&mut self, value: u8) {
        self.buffer.as_mut()[field::FLAGS] = value;
    }

    pub fn set_footer_byte(&mut self, value: u8) {
        self.buffer.as_mut()[field::FOOTER] = value;
    }

    /// Sets all 16 channels to the low 11 bits of `channels`, packed in one pass.
    pub fn set_channels(&mut self, channels: &Channels) {
        let data = &mut self.buffer.as_mut()[field::CHANNELS];
        let mut bytes = data.iter_mut();
        let (mut acc, mut bits) = (0u32, 0u32);
        for &value in channels {
            acc |= u32::from(value & Self::MAX_VALUE) << bits;
            bits += 11;
            while bits >= 8 {
                if let Some(byte) = bytes.next() {
                    *byte = acc as u8;
                }
                acc >>= 8;
                bits -= 8;
            }
        }
    }

    /// Sets channel `index` (0-based) to the low 11 bits of `value`.
    ///
    /// # Panics
    /// If `index` >= 16.
    pub fn set_channel(&mut self, index: usize, value: u16) {
        assert!(index < Self::CHANNELS, "SBUS has 16 proportional channels");
        let data = &mut self.buffer.as_mut()[field::CHANNELS];
        let value = u32::from(value & Self::MAX_VALUE);
        let bit = index * 11;
        let byte = bit / 8;
        let shift = bit % 8;
        let mask = u32::from(Self::MAX_VALUE) << shift;
        let span = if byte + 2 < data.len() { 3 } else { 2 };
        let mut word = 0u32;
        for k in 0..span {
            word |= u32::from(data[byte + k]) << (8 * k);
        }
        word = (word & !mask) | (value << shift);
        for k in 0..span {
            data[byte + k] = (word >> (8 * k)) as u8;
        }
    }
}

/// The flags byte, decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct Flags {
    /// Digital channel 17.
    pub ch17: bool,
    /// Digital channel 18.
    pub ch18: bool,
    /// The receiver missed a frame from the transmitter. Not a link loss by itself.
    pub frame_lost: bool,
    /// The receiver declares its link lost.
    pub failsafe: bool,
}

impl Flags {
    pub const fn from_byte(byte: u8) -> Self {
        Flags {
            ch17: byte & FLAG_CH17 != 0,
            ch18: byte & FLAG_CH18 != 0,
            frame_lost: byte & FLAG_FRAME_LOST != 0,
            failsafe: byte & FLAG_FAILSAFE != 0,
        }
    }

    pub const fn to_byte(self) -> u8 {
        let mut byte = 0;
        if self.ch17 {
            byte |= FLAG_CH17;
        }
        if self.ch18 {
            byte |= FLAG_CH18;
        }
        if self.frame_lost {
            byte |= FLAG_FRAME_LOST;
        }
        if self.failsafe {
            byte |= FLAG_FAILSAFE;
        }
        byte
    }
}

/// The last byte: plain SBUS, or one of the four SBUS2 telemetry slots.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum Footer {
    #[default]
    Sbus,
    /// SBUS2 footer; the slot group 0..=3 (bytes 0x04, 0x14, 0x24, 0x34).
    Sbus2(u8),
}

impl Footer {
    pub const fn from_byte(byte: u8) -> Option<Self> {
        match byte {
            0x00 => Some(Footer::Sbus),
            0x04 | 0x14 | 0x24 | 0x34 => Some(Footer::Sbus2(byte >> 4)),
            _ => None,
        }
    }

    pub const fn to_byte(self) -> u8 {
        match self {
            Footer::Sbus => 0x00,
            Footer::Sbus2(slot) => ((slot & 0x03) << 4) | 0x04,
        }
    }
}

/// An SBUS frame's content, owned.
///
/// Word-aligned: the engine moves one a few times per frame it sends out, and the
/// Cortex-M0+'s `memcpy` copies a 2-aligned one byte by byte (about 280 instructions
/// each), a 4-aligned one word by word.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(align(4))]
pub struct SbusRepr {
    pub channels: Channels,
    pub flags: Flags,
    pub footer: Footer,
}

impl Default for SbusRepr {
    /// Centred sticks, no flags.
    fn default() -> Self {
        SbusRepr {
            channels: [992; 16],
            flags: Flags::default(),
            footer: Footer::Sbus,
        }
    }
}

impl SbusRepr {
    /// Parses a checked or unchecked view, validating it.
    pub fn parse<T: AsRef<[u8]>>(frame: &SbusFrame<T>) -> Result<Self, WireError> {
        frame.check_len()?;
        frame.check_framing()?;
        Ok(SbusRepr {
            channels: frame.channels(),
            flags: frame.flags(),
            footer: Footer::from_byte(frame.footer_byte()).unwrap_or_default(),
        })
    }

    /// Writes this frame into a view of at least 25 bytes.
    ///
    /// Channel values above 2047 are truncated to 11 bits.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, frame: &mut SbusFrame<T>) {
        frame.set_header();
        frame.set_channels(&self.channels);
        frame.set_flags_byte(self.flags.to_byte());
        frame.set_footer_byte(self.footer.to_byte());
    }

    /// The frame as a fresh byte array.
    pub fn to_bytes(&self) -> [u8; SbusFrame::<&[u8]>::LEN] {
        let mut bytes = [0u8; SbusFrame::<&[u8]>::LEN];
        self.emit(&mut SbusFrame::new_unchecked(&mut bytes[..]));
        bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Channels 1..=16 = 172, 992, 1811, 0, 2047, 1000, 1500, 1, 2, 4, 8, 16, 32, 64, 128, 1024,
    /// flags: ch17 and failsafe, footer 0x00. Packed independently of this module, as one
    /// big integer `sum(ch[i] << 11*i)` written out little-endian.
    static FRAME: [u8; 25] = [
        0x0F, 0xAC, 0x00, 0xDF, 0xC4, 0x01, 0xF0, 0x7F, 0xF4, 0x71, 0x37, 0x00, 0x02, 0x20, 0x00,
        0x02, 0x20, 0x00, 0x02, 0x20, 0x00, 0x02, 0x80, 0x09, 0x00,
    ];
    static CHANNELS: Channels = [
        172, 992, 1811, 0, 2047, 1000, 1500, 1, 2, 4, 8, 16, 32, 64, 128, 1024,
    ];

    #[test]
    fn one_pass_packing_agrees_with_channel_by_channel() {
        let mut seed = 0x1234_5678u32;
        for _ in 0..200 {
            let channels: Channels = core::array::from_fn(|_| {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (seed >> 16) as u16 // above 11 bits too: both keep the low 11
            });
            let mut one_pass = [0xA5u8; 25];
            let mut by_channel = [0xA5u8; 25];
            SbusFrame::new_unchecked(&mut one_pass[..]).set_channels(&channels);
            let mut view = SbusFrame::new_unchecked(&mut by_channel[..]);
            for (i, &v) in channels.iter().enumerate() {
                view.set_channel(i, v);
            }
            assert_eq!(one_pass, by_channel);
            let frame = SbusFrame::new_unchecked(&one_pass[..]);
            let read: Channels = core::array::from_fn(|i| frame.channel(i));
            assert_eq!(frame.channels(), read);
            assert_eq!(read, channels.map(|v| v & SbusFrame::<&[u8]>::MAX_VALUE));
        }
    }

    #[test]
    fn deconstruct() {
        let frame = SbusFrame::new_checked(&FRAME[..]).unwrap();
        assert_eq!(frame.channels(), CHANNELS);
        let flags = frame.flags();
        assert!(flags.ch17 && flags.failsafe && !flags.ch18 && !flags.frame_lost);
    }

    #[test]
    fn construct() {
        let mut bytes = [0xA5u8; 25];
        let mut frame = SbusFrame::new_unchecked(&mut bytes[..]);
        frame.set_header();
        for (i, v) in CHANNELS.iter().enumerate() {
            frame.set_channel(i, *v);
        }
        frame.set_flags_byte(0x09);
        frame.set_footer_byte(0x00);
        assert_eq!(bytes, FRAME);
    }

    #[test]
    fn parse_and_emit_round_trip() {
        let repr = SbusRepr::parse(&SbusFrame::new_unchecked(&FRAME[..])).unwrap();
        assert_eq!(repr.channels, CHANNELS);
        assert_eq!(repr.footer, Footer::Sbus);
        assert_eq!(repr.to_bytes(), FRAME);
    }

    #[test]
    fn sbus2_footers_are_accepted() {
        for (byte, slot) in [(0x04, 0), (0x14, 1), (0x24, 2), (0x34, 3)] {
            let mut bytes = FRAME;
            bytes[24] = byte;
            let repr = SbusRepr::parse(&SbusFrame::new_unchecked(&bytes[..])).unwrap();
            assert_eq!(repr.footer, Footer::Sbus2(slot));
            assert_eq!(repr.to_bytes()[24], byte);
        }
    }

    #[test]
    fn impossible_lengths_and_framing_are_rejected() {
        assert_eq!(
            SbusFrame::new_checked(&FRAME[..24]),
            Err(WireError::Truncated { len: 24, need: 25 })
        );
        let mut bytes = FRAME;
        bytes[0] = 0x0E;
        assert_eq!(
            SbusFrame::new_checked(&bytes[..]),
            Err(WireError::BadHeader(0x0E))
        );
        let mut bytes = FRAME;
        bytes[24] = 0x08;
        assert_eq!(
            SbusFrame::new_checked(&bytes[..]),
            Err(WireError::BadFooter(0x08))
        );
        let mut bytes = FRAME;
        bytes[23] = 0x10;
        assert_eq!(
            SbusFrame::new_checked(&bytes[..]),
            Err(WireError::BadFlags(0x10))
        );
    }

    #[test]
    fn set_channel_leaves_neighbours_alone() {
        let mut bytes = FRAME;
        let mut frame = SbusFrame::new_unchecked(&mut bytes[..]);
        frame.set_channel(7, 0x7FF);
        let mut expected = CHANNELS;
        expected[7] = 0x7FF;
        assert_eq!(frame.channels(), expected);
    }
}

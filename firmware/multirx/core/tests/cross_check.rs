//! Our SBUS codec against an independent one, the `sbus-rs` crate (AeroRust).
//!
//! We keep our own codec because the core needs a smoltcp-style view with
//! setters for the output path, the exact SBUS2 footer set and the reserved
//! flag bits for resynchronisation (sbus-rs accepts any footer ending in 0x4
//! and ignores reserved bits), and per-link resync hooks; this test makes sure
//! the two agree on every frame both accept.

use multirx_core::wire::{Flags, Footer, SbusFrame, SbusRepr};
use proptest::prelude::*;

proptest! {
    #[test]
    fn sbus_rs_reads_what_we_write(channels in prop::array::uniform16(0u16..=2047), flags in 0u8..16) {
        let repr = SbusRepr { channels, flags: Flags::from_byte(flags), footer: Footer::Sbus };
        let theirs = sbus_rs::SbusPacket::from_array(&repr.to_bytes()).unwrap();
        prop_assert_eq!(theirs.channels, channels);
        prop_assert_eq!(theirs.flags.d1, repr.flags.ch17);
        prop_assert_eq!(theirs.flags.d2, repr.flags.ch18);
        prop_assert_eq!(theirs.flags.frame_lost, repr.flags.frame_lost);
        prop_assert_eq!(theirs.flags.failsafe, repr.flags.failsafe);
    }

    #[test]
    fn we_read_what_sbus_rs_writes(channels in prop::array::uniform16(0u16..=2047)) {
        let mut bytes = [0u8; 25];
        bytes[0] = 0x0F;
        sbus_rs::pack_channels(&mut bytes, &channels);
        let ours = SbusRepr::parse(&SbusFrame::new_checked(&bytes[..]).unwrap()).unwrap();
        prop_assert_eq!(ours.channels, channels);
    }
}

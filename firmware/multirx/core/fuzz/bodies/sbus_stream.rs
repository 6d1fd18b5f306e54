//! Arbitrary bytes and arrival times into the decoder and the whole engine:
//! no panic, only well-formed frames out, the output cadence never broken.

use multirx_core::decoder::SbusDecoder;
use multirx_core::wire::{SbusFrame, SbusRepr};
use multirx_core::{Config, Duration, Instant, Mode, Multiplexer};

pub fn run(data: &[u8]) {
    let mut decoder = SbusDecoder::new();
    decoder.push_slice(data, |frame: SbusRepr| {
        let bytes = frame.to_bytes();
        assert!(SbusFrame::new_checked(&bytes[..]).is_ok());
    });

    // Each chunk: a header byte (receiver, time step), then up to 31 bytes.
    let mode = if data.first().is_some_and(|b| b & 1 == 1) {
        Mode::Scan
    } else {
        Mode::Parallel
    };
    let mut mux = Multiplexer::new(Config::new(mode, 3), Instant::ZERO);
    let mut now = Instant::ZERO;
    let mut rest = data;
    while let Some((&head, tail)) = rest.split_first() {
        let len = usize::from(head & 31).min(tail.len());
        let (chunk, next) = tail.split_at(len);
        rest = next;
        now += Duration::from_micros(u64::from(head >> 2) * 250);
        while let Some(due) = mux.poll_timeout().filter(|&due| due <= now) {
            mux.handle_timeout(due);
        }
        mux.handle_receiver_bytes(now, head % 4, chunk);
        while mux.poll_transmit().is_some() {}
        while mux.poll_event().is_some() {}
    }
}

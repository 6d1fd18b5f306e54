//! Stream reader on arbitrary bytes: no panic, checked frames really are valid, and the output
//! does not depend on how the input is split into chunks.

use mavlora::wire::{Frame, FrameReader, Integrity, known};

fn read(input: &[u8], chunk: usize) -> Vec<Vec<u8>> {
    let mut reader = FrameReader::new();
    let mut out = Vec::new();
    for piece in input.chunks(chunk.max(1)) {
        reader.push(piece);
        while let Some(received) = reader.next_frame() {
            if received.integrity == Integrity::Checked {
                let frame = Frame::new_checked(received.frame.as_bytes()).expect("well-formed");
                let extra = known::crc_extra(frame.message_id()).expect("checked means known");
                assert!(frame.crc_matches(extra));
            }
            out.push(received.frame.into_inner());
        }
    }
    reader.finish();
    while let Some(received) = reader.next_frame() {
        out.push(received.frame.into_inner());
    }
    out
}

pub fn run(data: &[u8]) {
    let Some((&chunk, input)) = data.split_first() else {
        return;
    };
    let whole = read(input, input.len());
    assert_eq!(read(input, usize::from(chunk)), whole);
}

//! Arbitrary bytes as what a Mini-Circuits attenuator sends over Telnet: the decoder splits
//! them into lines (in two chunks, cut where the first byte says, as TCP may deliver them)
//! and owes the device only option refusals; every line goes through each reply parser.
//! Never a panic, and what the parsers accept is usable.

use harness::driver::attenuator::minicircuits::{
    parse_db, parse_firmware, parse_status, parse_tagged,
};
use harness::driver::attenuator::telnet::Decoder;

pub fn run(data: &[u8]) {
    let cut = data
        .first()
        .map_or(0, |&b| usize::from(b) % (data.len() + 1));
    let mut decoder = Decoder::default();
    decoder.push(&data[..cut]);
    decoder.push(&data[cut..]);
    let replies = decoder.take_replies();
    assert!(
        replies
            .chunks(3)
            .all(|c| c.len() == 3 && c[0] == 255 && (c[1] == 252 || c[1] == 254)),
        "owes the device more than refusals: {replies:?}"
    );
    while let Some(line) = decoder.next_line() {
        assert!(!line.is_empty(), "an empty line");
        assert!(
            !line.contains(&b'\r') && !line.contains(&b'\n'),
            "a line end in {line:?}"
        );
        if let Some(db) = parse_db(&line) {
            assert!(db.is_finite(), "{db} from {line:?}");
        }
        let _ = parse_status(&line);
        for tag in ["MN", "SN"] {
            if let Some(v) = parse_tagged(&line, tag) {
                assert!(!v.is_empty() && !v.contains(' '), "{tag}: {v:?}");
            }
        }
        if let Some(v) = parse_firmware(&line) {
            assert!(!v.is_empty(), "an empty firmware version from {line:?}");
        }
    }
}

//! The emulated device's TX probe (`multirx-emu --tx-log`): one line per frame
//! handed to the flight-controller port, `HOST_SECS HELD_SECS`, both
//! CLOCK_MONOTONIC-based: when it left, and how long the host had held the
//! device clock so far (the emulator's module docs). From it the rig judges
//! the device's own cadence in device time, and reports the host's holes
//! apart: the figure a board's logic analyser would give, without the
//! shared host's stalls, which no program on it can prevent.

use std::path::Path;
use std::time::Duration;

use anyhow::{Context, Result, bail};

use crate::clock::Mono;

/// One frame as the probe saw it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeLine {
    /// When the frame was handed to the port (host clock).
    pub sent: Mono,
    /// Total time the host had held the device clock, up to this frame.
    pub held: Duration,
}

/// What the probe shows over a window.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Cadence {
    /// Longest interval between frames in device time (host holds taken out).
    pub max_gap: Duration,
    /// Longest host hold between two frames (the host's share of a wall gap).
    pub max_hold: Duration,
    /// Frames in the window.
    pub frames: usize,
}

/// Parses the probe file at `path` (named in errors, with the line).
pub fn read(path: &Path) -> Result<Vec<ProbeLine>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    parse(&text).with_context(|| format!("{}", path.display()))
}

/// Reads the probe log once it holds a frame sent after `until`, or after `patience`.
///
/// That frame closes the last interval with its hold accounted; read before the device
/// wrote it (a frame period, more while the host holds the device), the tail would count
/// as a gap with the hold left in (15 ms seen on CI). A device that writes nothing for
/// `patience` has stopped: then the tail is a gap, as it should be.
pub fn read_past(
    path: &Path,
    until: Mono,
    patience: std::time::Duration,
) -> Result<Vec<ProbeLine>> {
    let give_up = std::time::Instant::now() + patience;
    loop {
        let lines = read(path)?;
        if lines.last().is_some_and(|l| l.sent > until) || std::time::Instant::now() >= give_up {
            return Ok(lines);
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

/// Parses probe lines; a last line without its newline is a frame being
/// written while we read, and is left out.
pub fn parse(text: &str) -> Result<Vec<ProbeLine>> {
    let complete = match text.rfind('\n') {
        Some(end) => &text[..end],
        None => "",
    };
    complete
        .lines()
        .enumerate()
        .map(|(i, line)| parse_line(line).with_context(|| format!("line {}: {line:?}", i + 1)))
        .collect()
}

fn parse_line(line: &str) -> Result<ProbeLine> {
    let mut fields = line.split_ascii_whitespace();
    let secs = |f: Option<&str>, what: &str| -> Result<f64> {
        let f = f.with_context(|| format!("no {what}"))?;
        let v: f64 = f
            .parse()
            .with_context(|| format!("{what} {f:?} is not a number"))?;
        if !v.is_finite() || v < 0.0 {
            bail!("{what} {f:?} is not a time");
        }
        Ok(v)
    };
    let sent = secs(fields.next(), "send time")?;
    let held = secs(fields.next(), "held time")?;
    if let Some(extra) = fields.next() {
        bail!("unexpected field {extra:?}");
    }
    Ok(ProbeLine {
        sent: Mono::from_secs_f64(sent),
        held: Duration::from_secs_f64(held),
    })
}

/// The cadence over `[from, until]`: gaps between consecutive frames in
/// device time, the first measured from `from` and the last up to the first
/// frame after `until` (or to `until` itself if none came yet, in host
/// time: nothing to take out).
pub fn cadence(lines: &[ProbeLine], from: Mono, until: Mono) -> Cadence {
    let mut out = Cadence::default();
    // Device time of the previous frame: `from`, less what was held before it.
    let mut held_before = lines
        .iter()
        .take_while(|l| l.sent < from)
        .last()
        .map_or(Duration::ZERO, |l| l.held);
    let mut last = from;
    let mut closed = false;
    for line in lines.iter().filter(|l| l.sent >= from) {
        let hold = line.held.saturating_sub(held_before);
        out.max_gap = out.max_gap.max(line.sent.since(last).saturating_sub(hold));
        out.max_hold = out.max_hold.max(hold);
        last = line.sent;
        held_before = line.held;
        if line.sent > until {
            closed = true;
            break;
        }
        out.frames += 1;
    }
    if !closed {
        out.max_gap = out.max_gap.max(until.since(last));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reading_waits_for_the_frame_that_closes_the_window() {
        let dir = std::env::temp_dir().join(format!("tx-probe-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("tx.log");
        let now = Mono::now();
        let stamp = |m: Mono| format!("{:.9} 0.000000000\n", m.as_secs_f64());
        std::fs::write(&path, stamp(now)).unwrap();
        let until = Mono::now();
        let writer = {
            let path = path.clone();
            std::thread::spawn(move || {
                std::thread::sleep(std::time::Duration::from_millis(30));
                let mut f = std::fs::OpenOptions::new()
                    .append(true)
                    .open(&path)
                    .unwrap();
                std::io::Write::write_all(&mut f, stamp(Mono::now()).as_bytes()).unwrap();
            })
        };
        let lines = read_past(&path, until, std::time::Duration::from_secs(5)).unwrap();
        writer.join().unwrap();
        assert_eq!(lines.len(), 2, "read before the closing frame was written");
        // a device that stopped: the reader gives up and the tail is a gap
        let later = Mono::now();
        let lines = read_past(&path, later, std::time::Duration::from_millis(20)).unwrap();
        assert_eq!(lines.len(), 2);
        let _ = std::fs::remove_dir_all(&dir);
    }

    fn line(sent_ms: f64, held_ms: f64) -> ProbeLine {
        ProbeLine {
            sent: Mono::from_secs_f64(100.0 + sent_ms / 1000.0),
            held: Duration::from_secs_f64(held_ms / 1000.0),
        }
    }

    fn at(ms: f64) -> Mono {
        Mono::from_secs_f64(100.0 + ms / 1000.0)
    }

    fn ms(d: Duration) -> f64 {
        (d.as_secs_f64() * 1000.0 * 1000.0).round() / 1000.0
    }

    #[test]
    fn a_steady_device_shows_its_period() {
        let lines: Vec<_> = (0..10).map(|i| line(7.0 * f64::from(i), 0.0)).collect();
        let c = cadence(&lines, at(0.0), at(63.0));
        assert_eq!(ms(c.max_gap), 7.0);
        assert_eq!(c.max_hold, Duration::ZERO);
        assert_eq!(c.frames, 10);
    }

    #[test]
    fn a_host_hold_is_taken_out_and_reported_apart() {
        // 20 ms held before frame 3: in host time a 27 ms gap.
        let lines = [
            line(0.0, 0.0),
            line(7.0, 0.0),
            line(34.0, 20.0),
            line(41.0, 20.0),
        ];
        let c = cadence(&lines, at(0.0), at(41.0));
        assert_eq!(ms(c.max_gap), 7.0);
        assert_eq!(ms(c.max_hold), 20.0);
    }

    #[test]
    fn a_skipped_frame_stays_a_gap() {
        // The device itself skipped a frame: nothing held, 14 ms apart.
        let lines = [line(0.0, 5.0), line(7.0, 5.0), line(21.0, 5.0)];
        assert_eq!(ms(cadence(&lines, at(0.0), at(21.0)).max_gap), 14.0);
    }

    #[test]
    fn a_device_that_stopped_shows_the_gap_to_the_end_of_the_window() {
        let lines = [line(0.0, 0.0), line(7.0, 0.0)];
        assert_eq!(ms(cadence(&lines, at(0.0), at(500.0)).max_gap), 493.0);
    }

    #[test]
    fn the_window_ends_at_the_first_frame_after_it() {
        // A hold across the window's end is taken out through the next frame.
        let lines = [line(0.0, 0.0), line(7.0, 0.0), line(30.0, 16.0)];
        let c = cadence(&lines, at(0.0), at(20.0));
        assert_eq!(ms(c.max_gap), 7.0);
        assert_eq!(c.frames, 2);
    }

    #[test]
    fn frames_before_the_window_set_only_what_was_held() {
        let lines = [line(-7.0, 3.0), line(1.0, 3.0), line(8.0, 3.0)];
        let c = cadence(&lines, at(0.0), at(8.0));
        assert_eq!(ms(c.max_gap), 7.0);
        assert_eq!(ms(c.max_hold), 0.0);
    }

    #[test]
    fn garbage_is_named_with_its_line() {
        let err = parse("1.0 0.0\n1.007 x\n").unwrap_err();
        assert_eq!(
            format!("{err:#}"),
            "line 2: \"1.007 x\": held time \"x\" is not a number: invalid float literal"
        );
        assert!(parse("1.0\n").is_err(), "the held field is required");
        assert!(parse("1.0 0.0 9\n").is_err());
    }

    #[test]
    fn a_half_written_last_line_is_left_out() {
        assert_eq!(parse("1.0 0.0\n1.00").unwrap().len(), 1);
    }
}

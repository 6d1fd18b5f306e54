//! A program's `--status-json` file read as any reader would: each line with `serde_json`
//! alone (not the writer's own types), checked against `firmware/hostio/STATUS-JSON.md`.

use std::path::Path;
use std::time::{Duration, Instant};

use serde_json::Value;

/// The complete lines of the file now, each parsed (a line still being written, without its
/// newline yet, is left out); panics naming a complete line that is not JSON.
pub fn read(path: &Path) -> Vec<Value> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let complete = &text[..text.rfind('\n').map_or(0, |i| i + 1)];
    complete
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON ({e}): {l}")))
        .collect()
}

/// A number from a line's `counters`.
pub fn counter(line: &Value, name: &str) -> u64 {
    line["counters"][name]
        .as_u64()
        .unwrap_or_else(|| panic!("no counter {name} in {line}"))
}

/// Waits (at most 10 s) until the file's latest status line satisfies `ready`.
pub fn wait_for(path: &Path, mut ready: impl FnMut(&Value) -> bool) -> Option<Value> {
    let deadline = Instant::now() + Duration::from_secs(10);
    while Instant::now() < deadline {
        if let Some(last) = read(path).into_iter().rev().find(|l| l["kind"] == "status")
            && ready(&last)
        {
            return Some(last);
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    None
}

/// Checks a whole file of `program`'s lines: every line names the schema and the program; the
/// first is `start`, then `status` lines, the last `stop` (if `stopped`) or `status` (killed);
/// every status and stop line has `counters` (each of `counters`, non-negative integers, none
/// ever smaller than on an earlier line) and `gauges` (each of `gauges`); `t_s` never goes
/// back. Returns the lines.
pub fn check(
    path: &Path,
    program: &str,
    counters: &[&str],
    gauges: &[&str],
    stopped: bool,
) -> Vec<Value> {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(text.ends_with('\n'), "a torn last line:\n{text}");
    let lines = read(path);
    assert!(
        lines.len() >= 3,
        "start, a status and stop at least:\n{text}"
    );
    let kinds: Vec<&str> = lines.iter().map(|l| l["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds[0], "start", "{text}");
    let last = if stopped { "stop" } else { "status" };
    assert_eq!(kinds[kinds.len() - 1], last, "{text}");
    assert!(
        kinds[1..kinds.len() - 1].iter().all(|&k| k == "status"),
        "{kinds:?}"
    );
    let mut previous: Option<&Value> = None;
    let mut t_s = 0.0;
    for line in &lines {
        assert_eq!(line["schema"], "c2-status/1", "{line}");
        assert_eq!(line["program"], program, "{line}");
        assert!(line["mono_s"].as_f64().is_some(), "{line}");
        let t = line["t_s"].as_f64().unwrap();
        assert!(t >= t_s, "t_s went back: {line}");
        t_s = t;
        if line["kind"] == "start" {
            continue;
        }
        let have: Vec<&String> = line["counters"].as_object().unwrap().keys().collect();
        for name in counters {
            assert!(
                line["counters"][name].is_u64(),
                "counter {name} missing: {line}"
            );
        }
        assert_eq!(
            have.len(),
            counters.len(),
            "counters beyond the documented: {have:?}"
        );
        for name in gauges {
            assert!(
                line["gauges"][name].is_u64(),
                "gauge {name} missing: {line}"
            );
        }
        if let Some(p) = previous {
            for name in counters {
                assert!(
                    counter(line, name) >= counter(p, name),
                    "{name} went down:\n{p}\n{line}"
                );
            }
        }
        previous = Some(line);
    }
    lines
}

//! The paper's Table II next to this run's reproduction, for the summary: bytes and messages
//! per second UAV→GCS per bandwidth mechanism, from the run's own measurements
//! (`mavlora.<variant>.*` from the simulated full-length flight, `mavlora.pty.<variant>.*`
//! from the real binaries over ptys).

use std::fmt::Write as _;

use crate::record::RunRecord;
use crate::scenario::mavlora::simulated::table_ii::paper_table;

/// The table, or `None` when the run measured none of its rows.
pub fn render(record: &RunRecord) -> Option<String> {
    let value = |name: String| {
        record
            .phases
            .iter()
            .flat_map(|p| &p.measurements)
            .find(|m| m.name == name)
            .and_then(|m| m.value)
    };
    let fmt = |v: Option<f64>| v.map_or("-".to_owned(), |v| format!("{v:.1}"));
    let mut any = false;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Table II (UAV→GCS)  {:>11} {:>11}   {:>11} {:>11}   {:>11} {:>11}",
        "paper B/s", "paper msg/s", "sim B/s", "sim msg/s", "pty B/s", "pty msg/s"
    );
    for row in paper_table() {
        let v = row.variant;
        let sim = (
            value(format!("mavlora.{v}.bytes_per_s")),
            value(format!("mavlora.{v}.msgs_per_s")),
        );
        let pty = (
            value(format!("mavlora.pty.{v}.bytes_per_s")),
            value(format!("mavlora.pty.{v}.msgs_per_s")),
        );
        any |= sim.0.is_some() || pty.0.is_some();
        let paper_bytes = if row.bound {
            format!("< {:.0}", row.bytes_per_s)
        } else {
            format!("{:.0}", row.bytes_per_s)
        };
        let _ = writeln!(
            out,
            "  {v:<17} {paper_bytes:>11} {:>11}   {:>11} {:>11}   {:>11} {:>11}",
            row.msgs_per_s.map_or("-".to_owned(), |m| format!("{m:.2}")),
            fmt(sim.0),
            fmt(sim.1),
            fmt(pty.0),
            fmt(pty.1),
        );
    }
    out.push_str(
        "  sim: the paper's 513 s flight under a virtual clock, frames on the radio; pty: the \
         real binaries, msg/s as the ground station decoded them (compact frames expanded)\n",
    );
    any.then_some(out)
}

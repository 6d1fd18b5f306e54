//! The paper's Table II next to this run's reproduction, for the summary: bytes and messages
//! per second UAV→GCS per bandwidth mechanism, from the run's own measurements, selected by
//! their `autopilot`, `variant` and `transport` dimensions (the simulated full-length flight,
//! and the real binaries over ptys), then the same rows for the ArduPilot-like autopilot.

use std::fmt::Write as _;

use crate::mavlora::simulated::table_ii::{ARDUPILOT, paper_table};
use crate::measurement::{Dimension, PTY, PX4, SIMULATED, Selector};

/// The autopilot dimension of a real PX4 (`px4-sitl` in the rig file).
const PX4_SITL: &str = "px4_sitl";
use crate::record::RunRecord;

/// The table, or `None` when the run measured none of its rows.
pub fn render(record: &RunRecord) -> Option<String> {
    let ardupilot = ARDUPILOT;
    // PX4 rows: `autopilot = px4`, or no autopilot at all (recorded before the dimension).
    let value_of = |autopilot: &str, base: &str, transport: &str, variant: &str| {
        let selector = Selector::base(base)
            .dim(Dimension::Device, "mavlora")
            .dim(Dimension::Transport, transport)
            .dim(Dimension::Variant, variant);
        record
            .select(&selector)
            .map(|(_, m)| m)
            .find(|m| m.dimensions.get(Dimension::Autopilot).unwrap_or(PX4) == autopilot)
            .and_then(|m| m.value)
    };
    let value =
        |base: &str, transport: &str, variant: &str| value_of(PX4, base, transport, variant);
    // Real PX4 (the `sitl` suite) on SiK 64k: its Table II phase for limiting + filtering, its
    // telemetry phase (downlink bytes) for compact.
    let sitl = |base: &str, variant: &str| {
        let selector = Selector::base(base)
            .dim(Dimension::Device, "mavlora")
            .dim(Dimension::Transport, PTY)
            .dim(Dimension::Autopilot, PX4_SITL)
            .dim(Dimension::Radio, "sik_64k")
            .dim(Dimension::Variant, variant);
        record.select(&selector).find_map(|(_, m)| m.value)
    };
    let fmt = |v: Option<f64>| v.map_or("-".to_owned(), |v| format!("{v:.1}"));
    let mut any = false;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Table II (UAV→GCS)  {:>11} {:>11}   {:>11} {:>11}   {:>11} {:>11}   {:>11} {:>11}",
        "paper B/s",
        "paper msg/s",
        "sim B/s",
        "sim msg/s",
        "pty B/s",
        "pty msg/s",
        "PX4 B/s",
        "PX4 msg/s"
    );
    for row in paper_table() {
        let v = row.variant;
        let sim = (
            value("bytes_per_s", SIMULATED, v),
            value("msgs_per_s", SIMULATED, v),
        );
        let pty = (value("bytes_per_s", PTY, v), value("msgs_per_s", PTY, v));
        let px4 = (
            sitl("bytes_per_s", v).or_else(|| sitl("down_bytes_per_s", v)),
            sitl("msgs_per_s", v),
        );
        any |= sim.0.is_some() || pty.0.is_some() || px4.0.is_some();
        let paper_bytes = if row.bound {
            format!("< {:.0}", row.bytes_per_s)
        } else {
            format!("{:.0}", row.bytes_per_s)
        };
        let _ = writeln!(
            out,
            "  {v:<17} {paper_bytes:>11} {:>11}   {:>11} {:>11}   {:>11} {:>11}   {:>11} {:>11}",
            row.msgs_per_s.map_or("-".to_owned(), |m| format!("{m:.2}")),
            fmt(sim.0),
            fmt(sim.1),
            fmt(pty.0),
            fmt(pty.1),
            fmt(px4.0),
            fmt(px4.1),
        );
    }
    let mut ap_any = false;
    let mut ap = String::new();
    for row in paper_table() {
        let v = row.variant;
        let cell = |base: &str| value_of(ardupilot, base, SIMULATED, v);
        let (b, m, hz, lag) = (
            cell("bytes_per_s"),
            cell("msgs_per_s"),
            cell("position_hz"),
            cell("position_lag_p99_s"),
        );
        ap_any |= b.is_some();
        let _ = writeln!(
            ap,
            "  {v:<17} {:>11} {:>11}   {:>11} {:>11}",
            fmt(b),
            fmt(m),
            hz.map_or("-".to_owned(), |v| format!("{v:.2}")),
            lag.map_or("-".to_owned(), |v| format!("{v:.2}")),
        );
    }
    out.push_str(
        "  sim: the paper's 513 s flight under a virtual clock, frames on the radio; pty: the \
         real binaries, msg/s as the ground station decoded them (compact frames expanded); \
         PX4: the real binaries behind PX4 SITL (the `sitl` suite) on SiK 64k\n",
    );
    if ap_any {
        let _ = writeln!(
            out,
            "ArduPilot-like FC  {:>11} {:>11}   {:>11} {:>11}",
            "sim B/s", "sim msg/s", "pos Hz", "lag p99 s"
        );
        out.push_str(&ap);
        out.push_str(
            "  MAVLink 1, ~3.7 kB/s over 31 types, stream requests ignored; position at the \
             ground from 10 s on\n",
        );
    }
    (any || ap_any).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::{Declarations, Spec};
    use crate::record::PhaseRecord;
    use crate::record::tests::sample_record;

    /// Rows come from the measurements' dimensions: which transport, which variant.
    #[test]
    fn rows_are_selected_by_variant_and_transport() {
        let mut record = sample_record();
        assert_eq!(
            render(&record),
            None,
            "no Table II measurement in the sample"
        );
        let mut d = Declarations::new();
        let table = |base: &str, transport: &str, variant: &str| {
            Spec::new(base, "B/s")
                .dim(Dimension::Device, "mavlora")
                .dim(Dimension::Transport, transport)
                .dim(Dimension::Variant, variant)
        };
        let sim = d.declare(table("bytes_per_s", SIMULATED, "compact"));
        d.record(sim, 48.4);
        let pty = d.declare(table("bytes_per_s", PTY, "compact"));
        d.record(pty, 44.9);
        let pty_msgs = d.declare(table("msgs_per_s", PTY, "limit_filter"));
        d.record(pty_msgs, 9.7);
        // an ArduPilot row of the same variant must not land in the PX4 table
        let ap = d.declare(
            table("bytes_per_s", SIMULATED, "compact").dim(Dimension::Autopilot, ARDUPILOT),
        );
        d.record(ap, 31.5);
        // Real PX4 on SiK 64k: its own column, never the fixture's; LoRa not shown.
        let sitl = |base: &str, variant: &str, radio: &str| {
            table(base, PTY, variant)
                .dim(Dimension::Autopilot, PX4_SITL)
                .dim(Dimension::Radio, radio)
        };
        let px4_lf = d.declare(sitl("bytes_per_s", "limit_filter", "sik_64k"));
        d.record(px4_lf, 612.0);
        let px4_compact_lora = d.declare(sitl("down_bytes_per_s", "compact", "lora_sf7"));
        d.record(px4_compact_lora, 54.5);
        let px4_compact = d.declare(sitl("down_bytes_per_s", "compact", "sik_64k"));
        d.record(px4_compact, 58.2);
        record.phases.push(PhaseRecord::ran(
            "mavlora::simulated::table_ii",
            "2026-01-31T09:12:37.000Z",
            0.5,
            d.into_measurements(),
            None,
        ));
        let text = render(&record).unwrap();
        let row = |v: &str| {
            text.lines()
                .find(|l| l.split_whitespace().next() == Some(v))
                .unwrap()
                .split_whitespace()
                .collect::<Vec<_>>()
        };
        assert_eq!(
            row("compact"),
            [
                "compact", "<", "100", "-", "48.4", "-", "44.9", "-", "58.2", "-"
            ]
        );
        assert_eq!(
            row("limit_filter"),
            [
                "limit_filter",
                "951",
                "35.23",
                "-",
                "-",
                "-",
                "9.7",
                "612.0",
                "-"
            ]
        );
        let ap_table = text.split("ArduPilot-like FC").nth(1).unwrap();
        let ap_compact = ap_table
            .lines()
            .find(|l| l.split_whitespace().next() == Some("compact"))
            .unwrap();
        assert_eq!(
            ap_compact.split_whitespace().collect::<Vec<_>>(),
            ["compact", "31.5", "-", "-", "-"]
        );
    }
}

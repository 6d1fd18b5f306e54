//! Command-to-ack latency through bridge and router over SiK with 10 %
//! bursty loss each way, as a ground station sees it: first send to first
//! `COMMAND_ACK`, a retry after 1.5 s without one. SORA's TMPR asks < 3 s
//! for medium robustness, < 5 s for low.

use anyhow::{Context, Result};

use super::{Scenario, Script, Unsigned, ensure_clean, run_session, spec};
use crate::mavlora::session::{GcsPlan, SessionDefaults};
use crate::measurement::{Declarations, Handle};
use crate::runner::PhaseContext;

const SCENARIO_NAME: &str = "c2_latency";

pub const SCENARIO: Scenario = Scenario {
    name: SCENARIO_NAME,
    summary: "30 commands (DO_SET_MODE, REQUEST_MESSAGE) through bridge and router over SiK with 10 % bursty loss: ack latency",
    plan,
};

const COMMANDS: u32 = 30;
const HOW: &str = "pymavlink GCS: COMMAND_LONG first send to the first matching COMMAND_ACK, \
     resent after 1.5 s without one (5 sends at most), one command at a time every 0.5 s; \
     nearest-rank percentile over the acked commands";

/// The measurements [`run`] records.
struct Measured {
    unsigned: Unsigned,
    p50_ms: Handle,
    p99_ms: Handle,
    max_ms: Handle,
    lost: Handle,
}

fn plan(d: &mut Declarations) -> Script {
    let m = Measured {
        unsigned: Unsigned::declare(d, SCENARIO_NAME),
        p50_ms: d.declare(
            spec("c2_latency_p50_ms", "ms")
                .describe(format!("median, {COMMANDS} commands; {HOW}"))
                .at_most(3000.0),
        ),
        p99_ms: d.declare(
            spec("c2_latency_p99_ms", "ms")
                .describe(format!(
                    "99th percentile, {COMMANDS} commands (= the slowest); {HOW}"
                ))
                .at_most(3000.0),
        ),
        max_ms: d.declare(
            spec("c2_latency_max_ms", "ms")
                .describe(format!(
                    "slowest of {COMMANDS} commands, against SORA's low-robustness bound (< 5 s); {HOW}"
                ))
                .at_most(5000.0),
        ),
        lost: d.declare(
            spec("c2_commands_lost", "")
                .describe(format!("commands of {COMMANDS} never acked after 5 sends"))
                .equal_to(0.0),
        ),
    };
    Box::new(move |ctx, defaults| run(ctx, defaults, &m))
}

fn run(ctx: &mut PhaseContext, d: &SessionDefaults, m: &Measured) -> Result<()> {
    let mut o = d.options("c2_latency", &d.c2_radio, &ctx.dir.join("c2_latency"));
    o.gcs = GcsPlan {
        listen_s: 2.0,
        commands: COMMANDS,
        ..GcsPlan::default()
    };
    let report = run_session(ctx, o)?;
    let c = report
        .gcs
        .commands
        .as_ref()
        .context("the GCS fixture ran no command phase")?;
    let latency = c.latency();
    let each: Vec<String> = c.latency_ms.iter().map(|ms| format!("{ms:.1}")).collect();
    ctx.log(format!(
        "{} acked, {} lost, {} sends, max {:.0} ms; latencies [{}]; FC received {:?}",
        c.acked,
        c.lost,
        c.sends,
        latency.max,
        each.join(", "),
        report.fc.commands
    ));
    // Where the retries came from: sends the FC never got were lost on the
    // uplink; the rest of the extra sends answered an ack lost on the downlink.
    let fc_got = i64::from(report.fc.commands_received(176) + report.fc.commands_received(512));
    ctx.log(format!(
        "command sends lost on the uplink: {}; acks lost on the downlink (or late): {}",
        i64::from(c.sends) - fc_got,
        fc_got - i64::from(c.acked)
    ));
    ctx.record(m.p50_ms, latency.p50);
    ctx.record(m.p99_ms, latency.p99);
    ctx.record(m.max_ms, latency.max);
    ctx.record(m.lost, f64::from(c.lost));
    m.unsigned.record(ctx, &[&report])?;
    ensure_clean(ctx, &report)
}

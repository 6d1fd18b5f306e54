//! The opt-in real-time soak: `soak_minutes` (default 10) of flight through the real bridge
//! and router over SiK with 10 % bursty loss each way and 5 s of silence both ways every 2
//! minutes, the pilot commanding every 2 s throughout and uploading a 100-item mission at
//! the end; both programs' memory sampled every 5 s. It takes its length in wall time, so
//! it is not in the default suite: name it in a rig file's `suites` (`rigs/soak.toml`
//! does). The virtual-clock hour (`simulated::soak`) is the one in the default suite.
//!
//! What it holds the programs to: peak RSS under 8 MB each (the project's target for a
//! companion computer) and no growth of the high-water mark over the second half of the run
//! (at most 5 %: the project's bound, so a leak shows within a soak), no command lost, the
//! mission accepted exactly as sent, every radio byte accounted for (offered = written +
//! dropped + queued at exit), nothing unsigned on the air.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};

use super::mission::compare;
use super::{Scenario, Script, Unsigned, ensure_clean, keep_evidence, spec};
use crate::mavlora::session::{GcsPlan, MavloraSession, SessionDefaults, SessionReport};
use crate::measurement::{Declarations, Handle};
use crate::runner::PhaseContext;
use harness_radio::Silence;

const SCENARIO_NAME: &str = "soak";

pub const SCENARIO: Scenario = Scenario {
    name: SCENARIO_NAME,
    summary: "opt-in: minutes of flight over lossy SiK with silences, commands every 2 s and a mission: memory flat, nothing lost",
    plan,
};

/// Peak RSS of either program, whatever the input rate: the project's target for a
/// companion computer.
const RSS_LIMIT_KB: f64 = 8192.0;
/// Growth of the memory high-water mark after the start-up part of a soak: the project's
/// bound, so that a program that leaks shows it within a soak rather than in a long flight.
const GROWTH_LIMIT_PCT: f64 = 5.0;
/// How often both programs' memory is read.
const SAMPLE_EVERY: Duration = Duration::from_secs(5);
const COMMAND_INTERVAL_S: f64 = 2.0;
const ITEMS: u32 = 100;
/// Silence both ways: this long, every `SILENCE_EVERY_S`, the first one minute in.
const SILENCE_S: f64 = 5.0;
const SILENCE_EVERY_S: f64 = 120.0;

struct Measured {
    rss_peak: [Handle; 2],
    rss_growth: [Handle; 2],
    commands_lost: Handle,
    c2_p50: Handle,
    c2_max: Handle,
    mission_intact: Handle,
    unbalanced: Handle,
    unsigned: Unsigned,
}

const PROGRAMS: [&str; 2] = ["bridge", "router"];

fn plan(d: &mut Declarations) -> Script {
    let rss_peak = PROGRAMS.map(|p| {
        d.declare(
            spec(&format!("soak_{p}_rss_peak_kb"), "kB")
                .at_most(RSS_LIMIT_KB)
                .describe(format!(
                    "peak resident memory (VmHWM) over the soak; limit 8 MB, the project's \
                     target for a companion computer (mavlora-{p})"
                )),
        )
    });
    let rss_growth = PROGRAMS.map(|p| {
        d.declare(
            spec(&format!("soak_{p}_rss_growth_pct"), "%")
                .at_most(GROWTH_LIMIT_PCT)
                .describe(format!(
                    "growth of the memory high-water mark (VmHWM) from half-time to the end; \
                     limit 5 %, the project's bound for a program that does not leak \
                     (mavlora-{p})"
                )),
        )
    });
    let m = Measured {
        rss_peak,
        rss_growth,
        commands_lost: d.declare(
            spec("soak_commands_lost", "")
                .describe("commands of the soak never acked after 5 sends 1.5 s apart")
                .equal_to(0.0),
        ),
        c2_p50: d.declare(
            spec("soak_c2_latency_p50_ms", "ms")
                .describe("median command-to-ack time over the soak; limit SORA TMPR medium (3 s)")
                .at_most(super::TMPR_S * 1000.0),
        ),
        c2_max: d.declare(spec("soak_c2_latency_max_ms", "ms").describe(
            "slowest command over the soak (one sent into a 5 s silence waits it out): recorded",
        )),
        mission_intact: d.declare(
            spec("soak_mission_items_intact", "")
                .describe(format!(
                    "1 when the {ITEMS}-item mission uploaded at the end was accepted and the FC \
                     holds exactly what the GCS sent, else 0"
                ))
                .equal_to(1.0),
        ),
        unbalanced: d.declare(
            spec("soak_radio_unbalanced_bytes", "")
                .describe(
                    "radio bytes of both programs not accounted for at exit: offered minus \
                     written, dropped and still queued (their last status lines)",
                )
                .equal_to(0.0),
        ),
        unsigned: Unsigned::declare(d, SCENARIO_NAME),
    };
    Box::new(move |ctx, defaults| run(ctx, defaults, &m))
}

fn run(ctx: &mut PhaseContext, d: &SessionDefaults, m: &Measured) -> Result<()> {
    let soak_s = d.soak_s;
    let mut radio = d.lossy_radio.clone();
    for link in [&mut radio.downlink, &mut radio.uplink] {
        link.silences.push(Silence {
            at_s: 60.0,
            for_s: SILENCE_S,
            every_s: Some(SILENCE_EVERY_S),
        });
    }
    let mut o = d.options(SCENARIO_NAME, &radio, &ctx.dir.join(SCENARIO_NAME));
    let listen_s = 10.0;
    o.gcs = GcsPlan {
        listen_s,
        commands: ((soak_s - listen_s) / COMMAND_INTERVAL_S).max(1.0) as u32,
        command_interval_s: COMMAND_INTERVAL_S,
        items: ITEMS,
        upload_timeout_s: 120.0,
        ..GcsPlan::default()
    };
    ctx.log(format!(
        "{soak_s:.0} s: {} commands every {COMMAND_INTERVAL_S} s, then {ITEMS} items; \
         {SILENCE_S} s of silence every {SILENCE_EVERY_S} s from 60 s",
        o.gcs.commands
    ));
    let session = MavloraSession::start(o)?;
    let sampler = Sampler::start(session.pids(), SAMPLE_EVERY);
    let report = session.finish()?;
    let samples = sampler.stop();
    keep_evidence(ctx, SCENARIO_NAME, &report);
    record_memory(ctx, m, &samples)?;
    record_traffic(ctx, m, &report)?;
    m.unsigned.record(ctx, &[&report])?;
    ensure_clean(ctx, &report)
}

/// Peak and growth of each program's high-water mark.
fn record_memory(ctx: &mut PhaseContext, m: &Measured, samples: &[Sample]) -> Result<()> {
    for (i, program) in PROGRAMS.iter().enumerate() {
        let mine: Vec<&Sample> = samples.iter().filter(|s| s.program == i).collect();
        let (Some(first), Some(last)) = (mine.first(), mine.last()) else {
            anyhow::bail!("no memory sample of mavlora-{program}");
        };
        let span = last.at - first.at;
        let half = mine
            .iter()
            .find(|s| s.at - first.at >= span / 2)
            .context("no sample at half-time")?;
        let growth = 100.0 * (last.hwm_kb as f64 - half.hwm_kb as f64) / half.hwm_kb as f64;
        ctx.log(format!(
            "mavlora-{program}: {} samples over {:.0} s; VmHWM {} kB at half-time, {} kB at the end; VmRSS {:?} kB",
            mine.len(),
            span.as_secs_f64(),
            half.hwm_kb,
            last.hwm_kb,
            mine.iter().map(|s| s.rss_kb).collect::<Vec<_>>()
        ));
        ctx.record(m.rss_peak[i], last.hwm_kb as f64);
        ctx.record(m.rss_growth[i], growth);
    }
    Ok(())
}

fn record_traffic(ctx: &mut PhaseContext, m: &Measured, report: &SessionReport) -> Result<()> {
    let c = report
        .gcs
        .commands
        .as_ref()
        .context("the GCS fixture ran no command phase")?;
    let latency = c.latency();
    ctx.log(format!(
        "commands: {} sent, {} acked, {} lost, {} sends, p50 {:.0} ms, max {:.0} ms",
        c.sent, c.acked, c.lost, c.sends, latency.p50, latency.max
    ));
    ctx.record(m.commands_lost, f64::from(c.lost));
    ctx.record(m.c2_p50, latency.p50);
    ctx.record(m.c2_max, latency.max);
    let accepted = report.gcs.result == Some(0);
    let (intact, why) = compare(&report.gcs.mission, &report.fc.mission);
    ctx.log(format!(
        "mission: result {:?} after {:?} s{}",
        report.gcs.result,
        report.gcs.upload_s,
        why.map(|w| format!("; differs: {w}")).unwrap_or_default()
    ));
    ctx.record(m.mission_intact, if accepted && intact { 1.0 } else { 0.0 });
    let mut unbalanced = 0.0;
    for (who, line) in [
        ("bridge", &report.bridge_status),
        ("router", &report.router_status),
    ] {
        let status = line
            .as_ref()
            .with_context(|| format!("the {who} wrote no status"))?;
        let balance = status.counter("radio_offered_bytes")?
            - status.counter("radio_written_bytes")?
            - status.counter("radio_dropped_bytes")?
            - status.gauge("radio_queued_bytes")?;
        ctx.log(format!(
            "{who}: radio bytes offered - written - dropped - queued = {balance}"
        ));
        unbalanced += balance.abs();
    }
    ctx.record(m.unbalanced, unbalanced);
    Ok(())
}

/// One reading of one program's memory.
#[derive(Debug, Clone, Copy)]
struct Sample {
    /// Index into [`PROGRAMS`].
    program: usize,
    at: Instant,
    rss_kb: u64,
    hwm_kb: u64,
}

/// Reads the programs' `VmRSS` and `VmHWM` every period until stopped (or they are gone).
struct Sampler {
    stop: Arc<AtomicBool>,
    thread: thread::JoinHandle<Vec<Sample>>,
}

impl Sampler {
    fn start(pids: [Option<u32>; 2], every: Duration) -> Sampler {
        let stop = Arc::new(AtomicBool::new(false));
        let stopped = stop.clone();
        let thread = thread::spawn(move || {
            let mut samples = Vec::new();
            let mut next = Instant::now();
            while !stopped.load(Ordering::Relaxed) {
                if Instant::now() >= next {
                    next += every;
                    for (program, pid) in pids.iter().enumerate() {
                        let Some(pid) = pid else { continue };
                        if let Some((rss_kb, hwm_kb)) = memory(*pid) {
                            samples.push(Sample {
                                program,
                                at: Instant::now(),
                                rss_kb,
                                hwm_kb,
                            });
                        }
                    }
                }
                thread::sleep(Duration::from_millis(100));
            }
            samples
        });
        Sampler { stop, thread }
    }

    fn stop(self) -> Vec<Sample> {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.join().unwrap_or_default()
    }
}

/// `VmRSS` and `VmHWM` of a live process, kB.
fn memory(pid: u32) -> Option<(u64, u64)> {
    let status =
        std::fs::read_to_string(Path::new("/proc").join(pid.to_string()).join("status")).ok()?;
    let field = |key: &str| {
        status
            .lines()
            .find_map(|l| l.strip_prefix(key))
            .and_then(|v| v.split_whitespace().next())
            .and_then(|v| v.parse().ok())
    };
    Some((field("VmRSS:")?, field("VmHWM:")?))
}

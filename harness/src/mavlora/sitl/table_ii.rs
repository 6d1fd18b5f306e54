//! Paper Table II's limiting + filtering row with the paper's real autopilot: what the
//! radio carries UAV → GCS when the bridge configures the autopilot's streams and filters
//! them by the non-compact profile (`px4-normal.toml` for PX4), over a steady window, next
//! to the paper's 951 B/s. The compact row with a real autopilot is the telemetry
//! scenario's `down_bytes_per_s` (the summary's Table II shows both).

use super::telemetry::{STEADY_BUDGET, SteadyWindow, steady_args};
use super::{Flavour, Scenario, Script, Target, options, run};
use crate::mavlora::session::SessionDefaults;
use crate::measurement::{Declarations, Dimension};
use crate::runner::PhaseContext;

pub const SCENARIO: Scenario = Scenario {
    name: "table_ii",
    summary: "Table II, limiting + filtering with a real autopilot's own streams: radio B/s \
              UAV→GCS (PX4: <= 951, the paper's) and messages per second at the ground",
    plan,
    radios: |p| &p.table_ii,
};

const VARIANT: &str = "limit_filter";

/// The paper's limiting + filtering row (Table II), measured with PX4.
const PAPER_LIMIT_FILTER: f64 = 951.0;

/// Far above the profile's share of any radio here, so the figure is what the profile lets
/// through rather than the scheduler's budget (as the fixture-driven Table II phase).
const RATE: u32 = 3000;

fn plan(d: &mut Declarations, t: &Target) -> Script {
    let spec = |base: &str, unit: &str| t.spec(base, unit).dim(Dimension::Variant, VARIANT);
    let bytes = spec("bytes_per_s", "B/s").describe(
        "UAV→GCS bytes the emulated radio put on air over the steady window (as the telemetry \
         scenario's: 20 s after the ground station's connection, 30 s), non-compact profile, \
         bridge --rate 3000",
    );
    let bytes = match t.flavour() {
        Flavour::Px4 => bytes.at_most(PAPER_LIMIT_FILTER),
        // The paper measured PX4 only.
        Flavour::ArduPilot => bytes,
    };
    let bytes = d.declare(bytes);
    let msgs = d.declare(spec("msgs_per_s", "msg/s").describe(
        "messages from the vehicle the ground station decoded per second of the same window \
         (paper, PX4: 35.23)",
    ));
    Box::new(
        move |ctx: &mut PhaseContext, defaults: &SessionDefaults, t: &Target| {
            let dir = ctx.dir.clone();
            let mut o = options(defaults, t, &dir, steady_args(), STEADY_BUDGET);
            o.link.bridge_profile = defaults.profile_dir.join(match t.flavour() {
                Flavour::Px4 => "px4-normal.toml",
                Flavour::ArduPilot => "ardupilot-mavlink1.toml",
            });
            o.link.compact = false;
            o.link.rate = RATE;
            let report = run(ctx, o)?;
            let w = SteadyWindow::of(&report)?;
            let (seconds, down) = (w.seconds, w.down_bytes_per_s);
            let s = &report.ground_summary;
            let per_s = s.messages as f64 / seconds;
            ctx.log(format!(
                "{VARIANT}: window {seconds:.2} s; radio {down:.1} B/s down; ground {per_s:.2} \
                 msg/s ({} B); by type {:?}",
                s.bytes, s.by_type
            ));
            ctx.record(bytes, down);
            ctx.record(msgs, per_s);
            Ok(())
        },
    )
}

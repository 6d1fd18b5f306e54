//! MavLora's figures in the certification page (`report.html`): Table II bytes/s next to the
//! paper, attenuation sweeps per radio, mission upload per radio, command latency against the
//! TMPR limits; each drawn from the saved run only, or said to be missing.

use std::path::Path;

use crate::evidence::html::{figure, missing};
use crate::evidence::svg::{HLine, Series, bar_chart, line_chart};
use crate::measurement::{Dimension, SIMULATED, Selector};
use crate::record::RunRecord;

/// The paper's Table II (bytes/s) for each variant the rig reproduces.
const PAPER_TABLE_II: [(&str, f64); 4] = [
    ("wired", 11440.0),
    ("limit", 1536.0),
    ("limit_filter", 951.0),
    ("compact", 100.0),
];

/// Adds MavLora's figures to the page `h`; `dir` holds the run's attachments.
pub fn html_figures(h: &mut String, dir: &Path, run: &RunRecord) {
    // Table II: bytes/s per variant next to the paper (simulated flight).
    let sel = Selector::base("bytes_per_s").dim(Dimension::Transport, "simulated");
    let measured: Vec<(String, f64)> = run
        .select(&sel)
        .filter_map(|(_, m)| Some((m.dimensions.get(Dimension::Variant)?.to_owned(), m.value?)))
        .collect();
    if measured.is_empty() {
        missing(
            h,
            "plot-table-ii",
            "Table II bytes/s",
            "No simulated Table II phase ran.",
        );
    } else {
        let cats: Vec<String> = PAPER_TABLE_II.iter().map(|(v, _)| v.to_string()).collect();
        let rig: Vec<Option<f64>> = cats
            .iter()
            .map(|c| measured.iter().find(|(v, _)| v == c).map(|(_, x)| *x))
            .collect();
        let paper: Vec<Option<f64>> = PAPER_TABLE_II.iter().map(|(_, x)| Some(*x)).collect();
        figure(
            h,
            "Radio bytes/s over the flight per Table II variant, this rig (simulated flight) next to \
             the paper (compact: the paper's < 100 B/s goal). Log scale.",
            &bar_chart(
                "plot-table-ii",
                "Table II bytes/s",
                "bytes/s",
                &cats,
                &[("this run".into(), rig), ("paper".into(), paper)],
                &[],
                true,
            ),
        );
    }
    missing(
        h,
        "plot-message-mix",
        "Message mix by category (paper Fig. 6)",
        "results.json holds bytes/s and msgs/s per variant only, not counts per message category.",
    );

    // Attenuation sweeps per radio.
    let sweep = run
        .phases
        .iter()
        .flat_map(|p| &p.attachments)
        .find(|a| a.path.ends_with("attenuation_sweep.csv"));
    match sweep.and_then(|a| std::fs::read_to_string(dir.join(&a.path)).ok()) {
        Some(csv) => {
            let mut series: Vec<Series> = Vec::new();
            for line in csv.lines().skip(1) {
                let f: Vec<&str> = line.split(',').collect();
                let (Some(name), Some(db), Some(loss)) = (
                    f.first(),
                    f.get(1).and_then(|s| s.parse::<f64>().ok()),
                    f.get(5).and_then(|s| s.parse::<f64>().ok()),
                ) else {
                    continue;
                };
                match series.iter_mut().find(|s| s.name == *name) {
                    Some(s) => s.points.push((db, loss)),
                    None => series.push(Series {
                        name: name.to_string(),
                        points: vec![(db, loss)],
                        step: false,
                    }),
                }
            }
            figure(
                h,
                "Packet loss against path attenuation, per radio (simulated sweep)",
                &line_chart(
                    "plot-attenuation",
                    "Attenuation sweep",
                    "attenuation (dB)",
                    "loss (%)",
                    &series,
                    &[],
                    false,
                ),
            );
        }
        None => missing(
            h,
            "plot-attenuation",
            "Attenuation sweeps",
            "No attenuation sweep ran.",
        ),
    }

    sitl_position_age(h, dir, run);

    // Mission upload: totals per radio (relay against a naive relay).
    let uploads: Vec<(String, String, f64)> = run
        .select(&Selector::base("mission_upload_s"))
        .filter_map(|(_, m)| {
            Some((
                m.dimensions.get(Dimension::Radio)?.to_owned(),
                m.dimensions
                    .get(Dimension::Variant)
                    .unwrap_or("relay")
                    .to_owned(),
                m.value?,
            ))
        })
        .collect();
    if uploads.is_empty() {
        missing(
            h,
            "plot-mission",
            "Mission upload",
            "No mission upload phase ran.",
        );
    } else {
        let mut radios: Vec<String> = uploads.iter().map(|u| u.0.clone()).collect();
        radios.dedup();
        let col = |variant: &str| -> Vec<Option<f64>> {
            radios
                .iter()
                .map(|r| {
                    uploads
                        .iter()
                        .find(|u| &u.0 == r && u.1 == variant)
                        .map(|u| u.2)
                })
                .collect()
        };
        figure(
            h,
            "Mission upload time per radio, MavLora relay against a naive relay (limit 300 s). \
             Progress over time (items acknowledged against time) is not recorded: totals only.",
            &bar_chart(
                "plot-mission",
                "Mission upload",
                "s",
                &radios,
                &[
                    ("relay".into(), col("relay")),
                    ("naive".into(), col("naive")),
                ],
                &[HLine {
                    y: 300.0,
                    label: "limit 300 s".into(),
                }],
                false,
            ),
        );
    }

    // Command latency: the percentiles recorded, against the TMPR limits.
    // The simulated 10 % loss flight's percentiles (the per-radio runs carry a radio).
    let lat: Vec<(String, f64)> = [("p50", "c2_latency_p50_ms"), ("p99", "c2_latency_p99_ms")]
        .into_iter()
        .filter_map(|(label, base)| {
            let selector = Selector::base(base)
                .dim(Dimension::Device, "mavlora")
                .dim(Dimension::Transport, SIMULATED)
                .lacks(Dimension::Radio);
            let (_, m) = run.select(&selector).next()?;
            Some((format!("{label}_ms"), m.value?))
        })
        .collect();
    if lat.is_empty() {
        missing(
            h,
            "plot-latency",
            "Command latency",
            "No command latency phase ran.",
        );
    } else {
        let cats: Vec<String> = lat.iter().map(|l| l.0.clone()).collect();
        figure(
            h,
            "Command round-trip latency under 10 % loss: the percentiles results.json records, \
             against the TMPR limits (3 s medium, 5 s low). The full distribution (each command's \
             latency) is not recorded.",
            &bar_chart(
                "plot-latency",
                "Command latency",
                "ms",
                &cats,
                &[("latency".into(), lat.iter().map(|l| Some(l.1)).collect())],
                &[
                    HLine {
                        y: 3000.0,
                        label: "3 s (medium TMPR)".into(),
                    },
                    HLine {
                        y: 5000.0,
                        label: "5 s (low TMPR)".into(),
                    },
                ],
                false,
            ),
        );
    }
}

/// Position age at the ground over each real-autopilot flight (the `sitl` suite's `flight`
/// phases), from their `position_age.csv`, against the 1 s freshness target.
fn sitl_position_age(h: &mut String, dir: &Path, run: &RunRecord) {
    let mut series = Vec::new();
    for phase in run
        .phases
        .iter()
        .filter(|p| p.name.starts_with("mavlora::sitl::flight::"))
    {
        let Some(a) = phase.attachments.iter().find(|a| {
            a.path
                .ends_with(crate::mavlora::sitl::freshness::SERIES_FILE)
        }) else {
            continue;
        };
        let Ok(csv) = std::fs::read_to_string(dir.join(&a.path)) else {
            continue;
        };
        let points: Vec<(f64, f64)> = csv
            .lines()
            .skip(1)
            .filter_map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                Some((f.first()?.parse().ok()?, f.get(2)?.parse().ok()?))
            })
            .collect();
        series.push(Series {
            name: phase
                .name
                .trim_start_matches("mavlora::sitl::flight::")
                .to_string(),
            points,
            step: false,
        });
    }
    if series.is_empty() {
        missing(
            h,
            "plot-sitl-position-age",
            "Position age over a flight",
            "No sitl flight phase ran (no SITL build given, or the sitl suite was not run).",
        );
        return;
    }
    figure(
        h,
        "Age of each position at the ground station over a whole flight with a real autopilot \
         (compact MavLora), judged on the vehicle's clock: arrival minus the sample's \
         time_boot_ms. Target: p95 <= 1 s.",
        &line_chart(
            "plot-sitl-position-age",
            "Position age over a flight",
            "time since the first position (s)",
            "age (s)",
            &series,
            &[HLine {
                y: 1.0,
                label: "1 s".into(),
            }],
            false,
        ),
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::{Declarations, Spec};
    use crate::record::PhaseRecord;
    use crate::record::tests::sample_record;

    #[test]
    fn the_latency_figure_takes_the_flight_without_a_radio_dimension() {
        let mut d = Declarations::new();
        let latency = |base: &str| {
            Spec::new(base, "ms")
                .dim(Dimension::Device, "mavlora")
                .dim(Dimension::Transport, SIMULATED)
        };
        let p50 = d.declare(latency("c2_latency_p50_ms"));
        let per_radio = d.declare(latency("c2_latency_p50_ms").dim(Dimension::Radio, "sik_64k"));
        d.record(p50, 179.0);
        d.record(per_radio, 131.0);
        let mut run = sample_record();
        run.phases.push(PhaseRecord::ran(
            "mavlora::simulated::c2_latency",
            String::new(),
            0.0,
            d.into_measurements(),
            None,
        ));
        let mut h = String::new();
        html_figures(&mut h, Path::new("."), &run);
        let start = h.find("plot-latency").expect("the latency plot is drawn");
        let plot = &h[start..];
        assert!(plot.contains("p50_ms"), "{plot}");
        assert!(!plot.contains("p99_ms"), "no p99 was recorded: {plot}");
        assert!(plot.contains("179"), "{plot}");
        assert!(
            !plot.contains("131"),
            "the per-radio p50 is another figure: {plot}"
        );
    }

    #[test]
    fn table_ii_and_the_sweep_are_drawn_from_the_run_and_its_csv() {
        let dir = tempfile::tempdir().unwrap();
        let mut d = Declarations::new();
        let bytes = d.declare(
            Spec::new("bytes_per_s", "B/s")
                .dim(Dimension::Device, "mavlora")
                .dim(Dimension::Transport, SIMULATED)
                .dim(Dimension::Variant, "limit_filter")
                .at_most(951.0),
        );
        d.record(bytes, 426.0);
        let mut p = PhaseRecord::ran(
            "mavlora::simulated::table_ii",
            String::new(),
            1.0,
            d.into_measurements(),
            None,
        );
        std::fs::create_dir(dir.path().join("sweep")).unwrap();
        let csv = dir.path().join("sweep/attenuation_sweep.csv");
        std::fs::write(
            &csv,
            "preset,attenuation_db,free_space_range_m,sent,received,loss_pct,mean_period_ms,\
             max_period_ms,nominal\n\
             sik-64k,80,1,10,10,0.00,1,1,true\nsik-64k,90,1,10,2,80.0,1,1,false\n",
        )
        .unwrap();
        p.attachments.push(
            crate::record::Attachment::from_file(dir.path(), &csv, "sweep", "text/csv").unwrap(),
        );
        let mut run = sample_record();
        run.phases.push(p);
        let mut h = String::new();
        html_figures(&mut h, dir.path(), &run);
        let drawn = |id: &str| h.contains(&format!("<svg class=\"plot\" id=\"{id}\""));
        assert!(drawn("plot-table-ii"), "{h}");
        assert!(h.contains("426"), "this run's bytes/s: {h}");
        assert!(drawn("plot-attenuation"), "{h}");
        assert!(
            !drawn("plot-mission") && h.contains("plot-mission"),
            "said missing: {h}"
        );
    }
}

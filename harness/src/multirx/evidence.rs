//! MultiRX's figures in the certification page (`report.html`): per handover phase, the output
//! gaps at the flight controller and the pilot channel over time, from the `fc-frames.csv` the
//! phase attached.

use std::path::Path;

use crate::evidence::html::{figure, missing};
use crate::evidence::svg::{HLine, Series, line_chart};
use crate::record::RunRecord;

/// Adds MultiRX's figures to the page `h`; `dir` holds the run's attachments.
pub fn html_figures(h: &mut String, dir: &Path, run: &RunRecord) {
    // Handover timelines: which pilot is in control and the output gaps at the FC, per phase.
    let mut drawn = 0;
    for p in &run.phases {
        let Some(a) = p.attachments.iter().find(|a| a.name == "fc-frames") else {
            continue;
        };
        if !(p.name.contains("b_handover")
            || p.name.contains("c_loiter")
            || p.name.contains("d_mission"))
        {
            continue;
        }
        let Ok(csv) = std::fs::read_to_string(dir.join(&a.path)) else {
            missing(
                h,
                &format!("plot-timeline-{}", p.name),
                &p.name,
                "The attached fc-frames.csv is not in the folder.",
            );
            continue;
        };
        let (mut pilot, mut gap) = (Vec::new(), Vec::new());
        for line in csv.lines().skip(1) {
            let f: Vec<&str> = line.split(',').collect();
            let num = |i: usize| f.get(i).and_then(|s| s.parse::<f64>().ok());
            if let (Some(t), Some(g), Some(pl)) = (num(0), num(1), num(2)) {
                pilot.push((t / 1000.0, pl));
                gap.push((t / 1000.0, g));
            }
        }
        let id = format!("plot-timeline-{}", p.name.replace("::", "-"));
        figure(
            h,
            &format!(
                "{}: output gaps at the flight controller (ms; RC is lost after 500 ms) and the \
                 pilot channel (raw SBUS value: which transmitter is in control)",
                p.name
            ),
            &line_chart(
                &id,
                &format!("Handover timeline {}", p.name),
                "time (s)",
                "ms / raw",
                &[
                    Series {
                        name: "gap (ms)".into(),
                        points: gap,
                        step: false,
                    },
                    Series {
                        name: "pilot channel".into(),
                        points: pilot,
                        step: true,
                    },
                ],
                &[HLine {
                    y: 21.0,
                    label: "21 ms gap limit".into(),
                }],
                false,
            ),
        );
        drawn += 1;
    }
    if drawn == 0 {
        missing(
            h,
            "plot-handover",
            "Handover timelines",
            "No MultiRX handover phase ran.",
        );
    }
}

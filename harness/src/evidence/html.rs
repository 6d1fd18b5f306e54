//! `report.html`: one self-contained page rendered only from the saved records in an evidence
//! folder (`certify.json`, `results.json`, `build.json`, `trace.json` and the CSV traces the
//! phases attached), never from live state. Verdict first, then the trace matrix, the plots
//! (inline SVG from [`super::svg`]), every measurement against its limits, and the build.
//!
//! Where a plot's data is not recorded by the run, the page says so in place of the plot. A
//! small inline script marks each drawn plot with its rendered size (`data-rendered`), which the
//! headless-browser test reads back.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};

use super::build::{BUILD_FILE, BuildRecord};
use super::certify::{CERTIFY_FILE, CertifyRecord, TRACE_FILE};
use super::svg::{HLine, Series, bar_chart, esc, line_chart};
use super::trace::TraceRow;
use crate::measurement::{Dimension, Selector};
use crate::record::{RESULTS_FILE, RunRecord};

/// File name of the page.
pub const REPORT_FILE: &str = "report.html";

/// The paper's Table II (bytes/s) for each variant the rig reproduces.
const PAPER_TABLE_II: [(&str, f64); 4] = [
    ("wired", 11440.0),
    ("limit", 1536.0),
    ("limit_filter", 951.0),
    ("compact", 100.0),
];

/// Renders the page from the records saved in `dir`.
pub fn render(dir: &Path) -> Result<String> {
    let read = |name: &str| {
        std::fs::read_to_string(dir.join(name))
            .with_context(|| format!("cannot read {}", dir.join(name).display()))
    };
    let certify: CertifyRecord = serde_json::from_str(&read(CERTIFY_FILE)?)
        .with_context(|| format!("{CERTIFY_FILE}: not a certify record"))?;
    let run = RunRecord::load(&dir.join(RESULTS_FILE))?;
    let build = BuildRecord::load(&dir.join(BUILD_FILE))?;
    let trace: Vec<TraceRow> = serde_json::from_str(&read(TRACE_FILE)?)
        .with_context(|| format!("{TRACE_FILE}: not a trace matrix"))?;

    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>Certification evidence: {rig}</title><style>{CSS}</style></head><body>",
        rig = esc(&run.rig.name)
    );
    let verdict = certify.verdict.as_str();
    let _ = write!(
        h,
        "<h1>Certification evidence</h1><div id=\"verdict\" class=\"verdict {cls}\">\
         Verdict: <b>{verdict}</b></div><p>{why}</p>",
        cls = verdict.to_lowercase(),
        why = esc(&certify.why)
    );
    let _ = write!(
        h,
        "<table class=\"facts\"><tr><th>rig</th><td>{} ({}, sha256 {})</td></tr>\
         <tr><th>phases</th><td>{}</td></tr><tr><th>run</th><td>{} → {}, outcome {}</td></tr>\
         <tr><th>source</th><td>commit {}{}</td></tr></table>",
        esc(&run.rig.name),
        esc(&certify.rig_file),
        esc(&run.rig.sha256),
        match &certify.filter {
            Some(f) => format!(
                "only those matching --filter {}{}: a partial run",
                esc(f),
                if certify.exact { " --exact" } else { "" }
            ),
            None => "all the rig file describes".into(),
        },
        esc(&run.started),
        esc(&run.ended),
        run.outcome.as_str(),
        esc(&build.git_commit),
        if build.git_dirty {
            " <b>with uncommitted changes (dirty): not reproducible from the commit</b>"
        } else {
            ""
        }
    );

    h.push_str("<h2>Requirements (trace matrix)</h2><table class=\"trace\"><tr><th>id</th><th>requirement</th><th>source</th><th>covering measurements</th><th>outcome</th></tr>");
    for row in &trace {
        let r = &row.requirement;
        let covering = if row.covering.is_empty() {
            "<i>no measurement covers this requirement</i>".to_owned()
        } else {
            row.covering
                .iter()
                .map(|c| {
                    format!(
                        "<span class=\"{}\">{} ({}{})</span>",
                        c.outcome.replace(' ', "-"),
                        esc(&c.measurement),
                        esc(&c.outcome),
                        c.phase
                            .as_ref()
                            .map(|p| format!(", phase {}", esc(p)))
                            .unwrap_or_default()
                    )
                })
                .collect::<Vec<_>>()
                .join("<br>")
        };
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}{}</td><td>{}</td><td>{}</td><td class=\"{}\">{}</td></tr>",
            esc(&r.id),
            esc(&r.text),
            r.covers
                .as_ref()
                .map(|c| format!("<br><small>covered: {}</small>", esc(c)))
                .unwrap_or_default(),
            esc(&r.source),
            covering,
            row.outcome.as_str().to_lowercase(),
            row.outcome.as_str()
        );
    }
    h.push_str("</table>");

    h.push_str("<h2>Plots</h2>");
    plots(&mut h, dir, &run);

    h.push_str("<h2>Measurements against limits</h2><table class=\"meas\"><tr><th>phase</th><th>measurement</th><th>value</th><th>limits</th><th>outcome</th></tr>");
    for p in &run.phases {
        if p.measurements.is_empty() {
            let _ = write!(
                h,
                "<tr><td>{}</td><td colspan=\"3\">{}</td><td class=\"{o}\">{o}</td></tr>",
                esc(&p.name),
                esc(p.error.as_deref().unwrap_or("no measurements")),
                o = p.outcome.as_str()
            );
        }
        for m in &p.measurements {
            let _ = write!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"{o}\">{o}</td></tr>",
                esc(&p.name),
                esc(&m.name),
                esc(&m.render_value()),
                esc(&m.limits.render(&m.unit)),
                o = m.outcome.as_str()
            );
        }
    }
    h.push_str("</table><h2>Build</h2><table class=\"facts\">");
    let _ = write!(
        h,
        "<tr><th>rustc</th><td><pre>{}</pre></td></tr><tr><th>cargo</th><td>{}</td></tr>\
         <tr><th>rustflags</th><td>{}</td></tr><tr><th>SOURCE_DATE_EPOCH</th><td>{}</td></tr>",
        esc(&build.rustc),
        esc(&build.cargo),
        esc(&build.rustflags.join(" ")),
        build.source_date_epoch
    );
    h.push_str(
        "</table><table class=\"meas\"><tr><th>artifact</th><th>sha256</th><th>bytes</th></tr>",
    );
    for a in &build.artifacts {
        let _ = write!(
            h,
            "<tr><td>{}</td><td><code>{}</code></td><td>{}</td></tr>",
            esc(&a.name),
            esc(&a.sha256),
            a.size
        );
    }
    h.push_str("</table>");
    h.push_str(SCRIPT);
    h.push_str("</body></html>\n");
    Ok(h)
}

fn figure(h: &mut String, caption: &str, body: &str) {
    let _ = write!(
        h,
        "<figure>{body}<figcaption>{}</figcaption></figure>",
        esc(caption)
    );
}

/// A plot whose data the run did not record: said plainly, not drawn.
fn missing(h: &mut String, id: &str, title: &str, why: &str) {
    let _ = write!(
        h,
        "<figure><div class=\"missing\" id=\"{}\"><b>{}</b>: not recorded. {}</div></figure>",
        esc(id),
        esc(title),
        esc(why)
    );
}

fn plots(h: &mut String, dir: &Path, run: &RunRecord) {
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
    let lat: Vec<(String, f64)> = run
        .phases
        .iter()
        .flat_map(|p| &p.measurements)
        .filter(|m| m.name.starts_with("mavlora.c2_latency_p"))
        .filter_map(|m| {
            Some((
                m.name.trim_start_matches("mavlora.c2_latency_").to_owned(),
                m.value?,
            ))
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

const CSS: &str = "body{font-family:sans-serif;max-width:72em;margin:1em auto;padding:0 1em}\
.verdict{font-size:2em;padding:.4em;border:3px solid}.pass{color:#060}.fail,.error,.uncovered{color:#a00}\
.partial,.marginal,.skipped,.not-run{color:#a60}.verdict.pass{background:#e6ffe6}.verdict.fail{background:#ffe6e6}\
.verdict.partial{background:#fff3d6}table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;\
padding:.2em .4em;vertical-align:top;text-align:left}.missing{border:2px dashed #a60;padding:1em;width:40em}\
figure{margin:1em 0}pre{margin:0}";

/// Marks each drawn plot with its rendered size, and the verdict with its box: the browser test
/// reads these back from the DOM (a plot that failed to render has no size).
const SCRIPT: &str = "<script>(function(){\
document.querySelectorAll('svg.plot').forEach(function(s){var b=s.getBBox();\
s.setAttribute('data-rendered',Math.round(b.width)+'x'+Math.round(b.height)+'/'+s.querySelectorAll('path,rect').length);});\
var v=document.getElementById('verdict');var r=v.getBoundingClientRect();\
v.setAttribute('data-rendered',Math.round(r.width)+'x'+Math.round(r.height));\
document.body.setAttribute('data-rendered','done');})();</script>";

#[cfg(test)]
mod tests {
    use super::*;
    use crate::evidence::build::Artifact;
    use crate::evidence::certify::Verdict;
    use crate::evidence::trace::{Requirements, matrix};
    use crate::record::tests::sample_record;

    /// An evidence folder with the sample run, a build record, a trace matrix and an
    /// attenuation sweep CSV, as `rig certify` saves them.
    fn folder() -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        let mut run = sample_record();
        // A Table II measurement and a sweep, so those plots have data.
        let mut d = crate::measurement::Declarations::new();
        let h = d.declare(
            crate::measurement::Spec::new("bytes_per_s", "B/s")
                .dim(Dimension::Device, "mavlora")
                .dim(Dimension::Transport, "simulated")
                .dim(Dimension::Variant, "limit_filter")
                .at_most(951.0),
        );
        d.record(h, 426.0);
        let mut p = crate::record::PhaseRecord::ran(
            "mavlora::simulated::table_ii",
            "2026-01-31T09:12:03.123Z",
            1.0,
            d.into_measurements(),
            None,
        );
        std::fs::create_dir(dir.path().join("sweep")).unwrap();
        let csv = dir.path().join("sweep/attenuation_sweep.csv");
        std::fs::write(
            &csv,
            "preset,attenuation_db,free_space_range_m,sent,received,loss_pct,mean_period_ms,max_period_ms,nominal\n\
             sik-64k,80,1,10,10,0.00,1,1,true\nsik-64k,90,1,10,2,80.0,1,1,false\n",
        )
        .unwrap();
        p.attachments.push(
            crate::record::Attachment::from_file(dir.path(), &csv, "sweep", "text/csv").unwrap(),
        );
        run.phases.push(p);
        run.save(dir.path()).unwrap();
        let build = BuildRecord {
            schema: "rig-build/1".into(),
            git_commit: "0123".into(),
            git_dirty: true,
            source_date_epoch: 1,
            rustc: "rustc 1.95.0".into(),
            cargo: "cargo 1.95.0".into(),
            rustflags: vec!["--remap-path-prefix=/x=/src".into()],
            started: "a".into(),
            finished: "b".into(),
            artifacts: vec![Artifact {
                name: "multirx-samd21-default.elf".into(),
                kind: "firmware".into(),
                path: "artifacts/multirx-samd21-default.elf".into(),
                sha256: "ab".repeat(32),
                size: 1,
                config: None,
            }],
        };
        build.save(dir.path()).unwrap();
        let reqs = Requirements::parse(
            Path::new("r.toml"),
            "[[requirement]]\nid = \"D\"\ntext = \"Link <security>\"\nsource = \"s\"\ncovered_by = []\n\
             [[requirement]]\nid = \"B\"\ntext = \"t\"\nsource = \"s\"\ncovered_by = [\"multirx.*.handover_ms\"]\n",
        )
        .unwrap();
        let declared = vec!["multirx.parallel.handover_ms".to_owned()];
        let trace = matrix(&reqs, &declared, &run);
        let (verdict, why) = Verdict::judge(&run, &trace, None);
        let certify = CertifyRecord {
            verdict,
            why,
            rig_file: "rigs/emulated.toml".into(),
            filter: None,
            exact: false,
            requirements_file: "harness/requirements.toml".into(),
            requirements_sha256: "00".repeat(32),
            run_exit_code: 1,
        };
        std::fs::write(
            dir.path().join(CERTIFY_FILE),
            serde_json::to_string(&certify).unwrap(),
        )
        .unwrap();
        std::fs::write(
            dir.path().join(TRACE_FILE),
            serde_json::to_string(&trace).unwrap(),
        )
        .unwrap();
        dir
    }

    #[test]
    fn the_page_says_the_verdict_first_and_uncovered_plainly() {
        let dir = folder();
        let page = render(dir.path()).unwrap();
        let verdict = page.find("id=\"verdict\"").unwrap();
        assert!(
            verdict < page.find("<h2>").unwrap(),
            "verdict before everything else"
        );
        assert!(
            page.contains("Verdict: <b>FAIL</b>"),
            "the sample run has a failed phase"
        );
        assert!(page.contains("UNCOVERED") && page.contains("Link &lt;security&gt;"));
        assert!(
            page.contains("not recorded"),
            "message mix is not recorded: said so"
        );
        assert!(page.contains("dirty"), "a dirty build is called out");
        assert!(
            !page.contains("http://")
                || page.matches("http://").count()
                    == page.matches("xmlns=\"http://www.w3.org/2000/svg\"").count(),
            "self-contained: nothing fetched"
        );
    }

    /// Real headless Chromium (Debian package `chromium`, installed by ci/setup.sh) loads the
    /// page: the verdict has a box and every plot drew its marks. Fails if Chromium is missing.
    #[test]
    fn headless_chromium_renders_the_verdict_and_every_plot() {
        let dir = folder();
        let page = render(dir.path()).unwrap();
        let path = dir.path().join(REPORT_FILE);
        std::fs::write(&path, &page).unwrap();
        let plots = page.matches("<svg class=\"plot\"").count();
        assert!(plots >= 2, "table II and attenuation at least: {plots}");
        let profile = dir.path().join("chromium-profile");
        let out = std::process::Command::new("chromium")
            .args(["--headless", "--no-sandbox", "--disable-gpu", "--dump-dom"])
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg(format!("file://{}", path.display()))
            .output()
            .expect("chromium must be installed (apt-get install chromium; ci/setup.sh does)");
        let dom = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            dom.contains("data-rendered=\"done\""),
            "the page's script ran:\n{dom}"
        );
        let verdict = dom
            .split("id=\"verdict\"")
            .nth(1)
            .unwrap()
            .split('>')
            .next()
            .unwrap();
        let size = verdict
            .split("data-rendered=\"")
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap();
        let (w, h) = size.split_once('x').unwrap();
        assert!(
            w.parse::<u32>().unwrap() > 100 && h.parse::<u32>().unwrap() > 10,
            "{size}"
        );
        let rendered: Vec<&str> = dom
            .split("<svg class=\"plot\"")
            .skip(1)
            .map(|s| {
                s.split("data-rendered=\"")
                    .nth(1)
                    .unwrap()
                    .split('"')
                    .next()
                    .unwrap()
            })
            .collect();
        assert_eq!(
            rendered.len(),
            plots,
            "every plot was marked by the browser"
        );
        for r in rendered {
            let (wh, marks) = r.split_once('/').unwrap();
            let (w, h) = wh.split_once('x').unwrap();
            assert!(
                w.parse::<u32>().unwrap() > 300 && h.parse::<u32>().unwrap() > 100,
                "{r}"
            );
            assert!(
                marks.parse::<u32>().unwrap() >= 2,
                "background plus marks: {r}"
            );
        }
    }
}

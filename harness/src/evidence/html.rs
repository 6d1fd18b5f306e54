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
use super::svg::esc;
use super::trace::TraceRow;
use crate::record::{RESULTS_FILE, RunRecord};

/// File name of the page.
pub const REPORT_FILE: &str = "report.html";

/// What draws the devices' figures into the page: `(page, folder, run)` (the device registry's
/// [`crate::devices::html_figures`]).
pub type Figures = fn(&mut String, &Path, &RunRecord);

/// Renders the page from the records saved in `dir`, with the figures `figures` draws.
pub fn render(dir: &Path, figures: Figures) -> Result<String> {
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
    figures(&mut h, dir, &run);

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

/// A drawn plot with its caption.
pub(crate) fn figure(h: &mut String, caption: &str, body: &str) {
    let _ = write!(
        h,
        "<figure>{body}<figcaption>{}</figcaption></figure>",
        esc(caption)
    );
}

/// A plot whose data the run did not record: said plainly, not drawn.
pub(crate) fn missing(h: &mut String, id: &str, title: &str, why: &str) {
    let _ = write!(
        h,
        "<figure><div class=\"missing\" id=\"{}\"><b>{}</b>: not recorded. {}</div></figure>",
        esc(id),
        esc(title),
        esc(why)
    );
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

    /// A device's figures for the tests: two bar charts of the run's measurements and a
    /// figure whose data is not recorded.
    fn figures(h: &mut String, _dir: &Path, run: &RunRecord) {
        use super::super::svg::bar_chart;
        let values: Vec<Option<f64>> = run
            .phases
            .iter()
            .flat_map(|p| &p.measurements)
            .map(|m| m.value)
            .collect();
        let cats: Vec<String> = (0..values.len()).map(|i| i.to_string()).collect();
        for id in ["plot-a", "plot-b"] {
            figure(
                h,
                "every value",
                &bar_chart(
                    id,
                    id,
                    "x",
                    &cats,
                    &[("run".into(), values.clone())],
                    &[],
                    false,
                ),
            );
        }
        missing(h, "plot-mix", "Message mix", "No phase records it.");
    }

    /// An evidence folder with the sample run, a build record and a trace matrix, as
    /// `rig certify` saves them.
    fn folder() -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        let run = sample_record();
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
                name: "dut-default.elf".into(),
                kind: "firmware".into(),
                path: "artifacts/dut-default.elf".into(),
                sha256: "ab".repeat(32),
                size: 1,
                config: None,
            }],
        };
        build.save(dir.path()).unwrap();
        let reqs = Requirements::parse(
            Path::new("r.toml"),
            "[[requirement]]\nid = \"D\"\ntext = \"Link <security>\"\nsource = \"s\"\ncovered_by = []\n\
             [[requirement]]\nid = \"B\"\ntext = \"t\"\nsource = \"s\"\ncovered_by = [\"dut.*.handover_ms\"]\n",
        )
        .unwrap();
        let declared = vec!["dut.parallel.handover_ms".to_owned()];
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
        let page = render(dir.path(), figures).unwrap();
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
            "a figure whose data is not recorded: said so"
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
        let page = render(dir.path(), figures).unwrap();
        let path = dir.path().join(REPORT_FILE);
        std::fs::write(&path, &page).unwrap();
        let plots = page.matches("<svg class=\"plot\"").count();
        assert_eq!(plots, 2, "both figures drawn: {page}");
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

//! Small SVG charts for the report (line and bar charts with axes, limits and a legend),
//! written as text: no JavaScript charting library, nothing fetched when the page opens.

use std::fmt::Write as _;

/// Escapes text for HTML and SVG.
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

const W: f64 = 640.0;
const H: f64 = 300.0;
const LEFT: f64 = 64.0;
const RIGHT: f64 = 16.0;
const TOP: f64 = 16.0;
const BOTTOM: f64 = 64.0;
const COLOURS: [&str; 6] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b",
];

/// A horizontal reference line (a limit, a paper figure).
pub struct HLine {
    pub y: f64,
    pub label: String,
}

/// One named series of (x, y) points.
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// Draw as steps (a state that holds until the next point), not straight segments.
    pub step: bool,
}

struct Axis {
    lo: f64,
    hi: f64,
    log: bool,
}

impl Axis {
    fn new(values: impl Iterator<Item = f64>, log: bool) -> Self {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in values.filter(|v| v.is_finite() && (!log || *v > 0.0)) {
            lo = lo.min(v);
            hi = hi.max(v);
        }
        if !lo.is_finite() {
            (lo, hi) = (0.0, 1.0);
        }
        if log {
            lo = 10f64.powf(lo.log10().floor());
            hi = 10f64.powf(hi.log10().ceil());
            if hi <= lo {
                hi = lo * 10.0;
            }
        } else {
            lo = lo.min(0.0);
            if hi <= lo {
                hi = lo + 1.0;
            }
            hi += (hi - lo) * 0.05;
        }
        Axis { lo, hi, log }
    }

    /// 0..1 along the axis.
    fn frac(&self, v: f64) -> f64 {
        if self.log {
            (v.max(self.lo).log10() - self.lo.log10()) / (self.hi.log10() - self.lo.log10())
        } else {
            (v - self.lo) / (self.hi - self.lo)
        }
    }

    fn ticks(&self) -> Vec<f64> {
        if self.log {
            let mut t = Vec::new();
            let mut v = self.lo;
            while v <= self.hi * 1.0001 {
                t.push(v);
                v *= 10.0;
            }
            t
        } else {
            let raw = (self.hi - self.lo) / 5.0;
            let mag = 10f64.powf(raw.log10().floor());
            let step = [1.0, 2.0, 5.0, 10.0]
                .iter()
                .map(|m| m * mag)
                .find(|s| *s >= raw)
                .unwrap_or(raw);
            let mut t = Vec::new();
            let mut v = (self.lo / step).ceil() * step;
            while v <= self.hi {
                t.push(v);
                v += step;
            }
            t
        }
    }
}

fn fmt_num(v: f64) -> String {
    if v.abs() >= 10.0 || v == v.trunc() {
        format!("{v:.0}")
    } else {
        format!("{v:.2}")
    }
}

fn open(id: &str, title: &str) -> String {
    format!(
        "<svg class=\"plot\" id=\"{}\" viewBox=\"0 0 {W} {H}\" width=\"{W}\" height=\"{H}\" \
         role=\"img\" xmlns=\"http://www.w3.org/2000/svg\"><title>{}</title>\
         <rect x=\"0\" y=\"0\" width=\"{W}\" height=\"{H}\" fill=\"#fff\"/>",
        esc(id),
        esc(title)
    )
}

fn y_axis(svg: &mut String, y: &Axis, label: &str, hlines: &[HLine]) {
    let py = |v: f64| TOP + (1.0 - y.frac(v)) * (H - TOP - BOTTOM);
    for t in y.ticks() {
        let _ = write!(
            svg,
            "<line x1=\"{LEFT}\" x2=\"{}\" y1=\"{y0:.1}\" y2=\"{y0:.1}\" stroke=\"#ddd\"/>\
             <text x=\"{}\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"end\">{}</text>",
            W - RIGHT,
            LEFT - 4.0,
            py(t) + 4.0,
            fmt_num(t),
            y0 = py(t)
        );
    }
    for h in hlines {
        let _ = write!(
            svg,
            "<line x1=\"{LEFT}\" x2=\"{}\" y1=\"{y0:.1}\" y2=\"{y0:.1}\" stroke=\"#000\" \
             stroke-dasharray=\"6 3\"/><text x=\"{}\" y=\"{:.1}\" font-size=\"11\" \
             text-anchor=\"end\">{}</text>",
            W - RIGHT,
            W - RIGHT - 2.0,
            py(h.y) - 3.0,
            esc(&h.label),
            y0 = py(h.y)
        );
    }
    let _ = write!(
        svg,
        "<line x1=\"{LEFT}\" x2=\"{LEFT}\" y1=\"{TOP}\" y2=\"{}\" stroke=\"#000\"/>\
         <text x=\"14\" y=\"{}\" font-size=\"12\" transform=\"rotate(-90 14 {})\" \
         text-anchor=\"middle\">{}</text>",
        H - BOTTOM,
        (H - BOTTOM + TOP) / 2.0,
        (H - BOTTOM + TOP) / 2.0,
        esc(label)
    );
}

fn legend(svg: &mut String, names: &[&str]) {
    for (i, n) in names.iter().enumerate() {
        let x = LEFT + i as f64 * 150.0;
        let _ = write!(
            svg,
            "<rect x=\"{x}\" y=\"{}\" width=\"10\" height=\"10\" fill=\"{}\"/>\
             <text x=\"{}\" y=\"{}\" font-size=\"11\">{}</text>",
            H - 18.0,
            COLOURS[i % COLOURS.len()],
            x + 14.0,
            H - 9.0,
            esc(n)
        );
    }
}

/// A line (or step) chart of `series` against a linear x axis.
pub fn line_chart(
    id: &str,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    hlines: &[HLine],
    log_y: bool,
) -> String {
    let x = Axis::new(
        series.iter().flat_map(|s| s.points.iter().map(|p| p.0)),
        false,
    );
    let y = Axis::new(
        series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.1))
            .chain(hlines.iter().map(|h| h.y)),
        log_y,
    );
    let px = |v: f64| LEFT + x.frac(v) * (W - LEFT - RIGHT);
    let py = |v: f64| TOP + (1.0 - y.frac(v)) * (H - TOP - BOTTOM);
    let mut svg = open(id, title);
    y_axis(&mut svg, &y, y_label, hlines);
    for t in x.ticks() {
        let _ = write!(
            svg,
            "<text x=\"{:.1}\" y=\"{}\" font-size=\"11\" text-anchor=\"middle\">{}</text>",
            px(t),
            H - BOTTOM + 14.0,
            fmt_num(t)
        );
    }
    let _ = write!(
        svg,
        "<line x1=\"{LEFT}\" x2=\"{}\" y1=\"{y0}\" y2=\"{y0}\" stroke=\"#000\"/>\
         <text x=\"{}\" y=\"{}\" font-size=\"12\" text-anchor=\"middle\">{}</text>",
        W - RIGHT,
        (LEFT + W - RIGHT) / 2.0,
        H - BOTTOM + 30.0,
        esc(x_label),
        y0 = H - BOTTOM
    );
    for (i, s) in series.iter().enumerate() {
        let mut d = String::new();
        let mut last: Option<(f64, f64)> = None;
        for &(a, b) in &s.points {
            if !a.is_finite() || !b.is_finite() {
                continue;
            }
            let (xa, yb) = (px(a), py(b));
            match last {
                None => {
                    let _ = write!(d, "M{xa:.1} {yb:.1}");
                }
                Some((_, ly)) if s.step => {
                    let _ = write!(d, "H{xa:.1}V{yb:.1}");
                    let _ = ly;
                }
                Some(_) => {
                    let _ = write!(d, "L{xa:.1} {yb:.1}");
                }
            }
            last = Some((xa, yb));
        }
        let _ = write!(
            svg,
            "<path d=\"{d}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\"/>",
            COLOURS[i % COLOURS.len()]
        );
    }
    legend(
        &mut svg,
        &series.iter().map(|s| s.name.as_str()).collect::<Vec<_>>(),
    );
    svg.push_str("</svg>");
    svg
}

/// Grouped bars: one group per category, one bar per series (`None`: no value, no bar).
pub fn bar_chart(
    id: &str,
    title: &str,
    y_label: &str,
    categories: &[String],
    series: &[(String, Vec<Option<f64>>)],
    hlines: &[HLine],
    log_y: bool,
) -> String {
    let y = Axis::new(
        series
            .iter()
            .flat_map(|s| s.1.iter().flatten().copied())
            .chain(hlines.iter().map(|h| h.y)),
        log_y,
    );
    let py = |v: f64| TOP + (1.0 - y.frac(v)) * (H - TOP - BOTTOM);
    let mut svg = open(id, title);
    y_axis(&mut svg, &y, y_label, hlines);
    let group = (W - LEFT - RIGHT) / categories.len().max(1) as f64;
    let bar = group * 0.8 / series.len().max(1) as f64;
    for (c, cat) in categories.iter().enumerate() {
        let gx = LEFT + c as f64 * group;
        for (s, (_, values)) in series.iter().enumerate() {
            if let Some(Some(v)) = values.get(c) {
                let top = py(*v);
                let _ = write!(
                    svg,
                    "<rect x=\"{:.1}\" y=\"{top:.1}\" width=\"{:.1}\" height=\"{:.1}\" \
                     fill=\"{}\"><title>{}: {}</title></rect>",
                    gx + group * 0.1 + s as f64 * bar,
                    bar - 2.0,
                    (H - BOTTOM - top).max(0.5),
                    COLOURS[s % COLOURS.len()],
                    esc(cat),
                    fmt_num(*v)
                );
            }
        }
        let _ = write!(
            svg,
            "<text x=\"{:.1}\" y=\"{}\" font-size=\"11\" text-anchor=\"middle\">{}</text>",
            gx + group / 2.0,
            H - BOTTOM + 14.0,
            esc(cat)
        );
    }
    let _ = write!(
        svg,
        "<line x1=\"{LEFT}\" x2=\"{}\" y1=\"{y0}\" y2=\"{y0}\" stroke=\"#000\"/>",
        W - RIGHT,
        y0 = H - BOTTOM
    );
    legend(
        &mut svg,
        &series.iter().map(|s| s.0.as_str()).collect::<Vec<_>>(),
    );
    svg.push_str("</svg>");
    svg
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn charts_are_well_formed_and_escape_text() {
        let s = line_chart(
            "p",
            "a<b",
            "t",
            "y",
            &[Series {
                name: "x&y".into(),
                points: vec![(0.0, 1.0), (1.0, 2.0), (2.0, f64::NAN)],
                step: true,
            }],
            &[HLine {
                y: 1.5,
                label: "limit".into(),
            }],
            false,
        );
        assert!(s.starts_with("<svg") && s.ends_with("</svg>"));
        assert!(s.contains("a&lt;b") && s.contains("x&amp;y") && !s.contains("NaN"));
        let b = bar_chart(
            "b",
            "t",
            "B/s",
            &["wired".into()],
            &[
                ("rig".into(), vec![Some(10.0)]),
                ("paper".into(), vec![None]),
            ],
            &[],
            true,
        );
        assert_eq!(
            b.matches("<rect x=").count() - 1 - 2,
            1,
            "one bar (plus background, legend)"
        );
    }
}

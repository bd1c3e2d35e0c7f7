//! Small SVG line plots (no plotting dependency): time series with their bounds drawn as
//! dashed lines, and an x–y path with markers. Enough for the `wip` result files.

use std::fmt::Write as _;

/// One curve.
pub struct Series<'a> {
    pub label: &'a str,
    pub x: &'a [f64],
    pub y: &'a [f64],
    pub color: &'a str,
}

/// A plot: curves, horizontal bound lines, optional markers (x, y).
pub struct Plot<'a> {
    pub title: &'a str,
    pub xlabel: &'a str,
    pub ylabel: &'a str,
    pub series: Vec<Series<'a>>,
    pub bounds: Vec<f64>,
    pub markers: Vec<(f64, f64)>,
    /// Equal scales on both axes (for paths).
    pub equal_axes: bool,
}

const W: f64 = 800.0;
const H: f64 = 420.0;
const ML: f64 = 70.0;
const MR: f64 = 20.0;
const MT: f64 = 40.0;
const MB: f64 = 50.0;

fn nice_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let span = (hi - lo).max(1e-12);
    let raw = span / 6.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| span / s <= 7.0)
        .unwrap_or(10.0 * mag);
    let mut t = (lo / step).ceil() * step;
    let mut out = Vec::new();
    while t <= hi + 1e-9 * span {
        out.push(if t.abs() < 1e-12 * span { 0.0 } else { t });
        t += step;
    }
    out
}

impl Plot<'_> {
    pub fn to_svg(&self) -> String {
        let finite = |v: &f64| v.is_finite();
        let xs = self.series.iter().flat_map(|s| s.x.iter()).copied();
        let ys = self
            .series
            .iter()
            .flat_map(|s| s.y.iter())
            .copied()
            .chain(self.bounds.iter().copied())
            .chain(self.markers.iter().map(|m| m.1));
        let xs = xs.chain(self.markers.iter().map(|m| m.0));
        let (mut x0, mut x1) = xs
            .filter(finite)
            .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
        let (mut y0, mut y1) = ys
            .filter(finite)
            .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
        if x0 > x1 {
            (x0, x1) = (0.0, 1.0);
        }
        if y0 > y1 {
            (y0, y1) = (0.0, 1.0);
        }
        let pad = 0.05 * (y1 - y0).max(1e-9);
        y0 -= pad;
        y1 += pad;
        if x1 - x0 < 1e-12 {
            x1 = x0 + 1.0;
        }
        let (pw, ph) = (W - ML - MR, H - MT - MB);
        if self.equal_axes {
            let sx = (x1 - x0) / pw;
            let sy = (y1 - y0) / ph;
            let s = sx.max(sy);
            let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
            x0 = cx - s * pw / 2.0;
            x1 = cx + s * pw / 2.0;
            y0 = cy - s * ph / 2.0;
            y1 = cy + s * ph / 2.0;
        }
        let px = |x: f64| ML + (x - x0) / (x1 - x0) * pw;
        let py = |y: f64| MT + (1.0 - (y - y0) / (y1 - y0)) * ph;
        let mut s = String::new();
        let _ = writeln!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="12">"#
        );
        let _ = writeln!(s, r#"<rect width="{W}" height="{H}" fill="white"/>"#);
        let _ = writeln!(
            s,
            r#"<text x="{}" y="22" text-anchor="middle" font-size="15">{}</text>"#,
            W / 2.0,
            self.title
        );
        for t in nice_ticks(x0, x1) {
            let x = px(t);
            let _ = writeln!(
                s,
                r##"<line x1="{x:.1}" y1="{MT}" x2="{x:.1}" y2="{:.1}" stroke="#eee"/>"##,
                H - MB
            );
            let _ = writeln!(
                s,
                r#"<text x="{x:.1}" y="{:.1}" text-anchor="middle">{t}</text>"#,
                H - MB + 16.0
            );
        }
        for t in nice_ticks(y0, y1) {
            let y = py(t);
            let _ = writeln!(
                s,
                r##"<line x1="{ML}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#eee"/>"##,
                W - MR
            );
            let _ = writeln!(
                s,
                r#"<text x="{:.1}" y="{:.1}" text-anchor="end">{t}</text>"#,
                ML - 6.0,
                y + 4.0
            );
        }
        let _ = writeln!(
            s,
            r#"<rect x="{ML}" y="{MT}" width="{pw}" height="{ph}" fill="none" stroke="black"/>"#
        );
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
            ML + pw / 2.0,
            H - 12.0,
            self.xlabel
        );
        let _ = writeln!(
            s,
            r#"<text x="16" y="{}" text-anchor="middle" transform="rotate(-90 16 {})">{}</text>"#,
            MT + ph / 2.0,
            MT + ph / 2.0,
            self.ylabel
        );
        for &b in &self.bounds {
            let y = py(b);
            let _ = writeln!(
                s,
                r##"<line x1="{ML}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#c00" stroke-dasharray="6,4"/>"##,
                W - MR
            );
        }
        for (i, ser) in self.series.iter().enumerate() {
            // Thin the polyline to at most ~2000 points: the file stays small.
            let stride = (ser.x.len() / 2000).max(1);
            let mut pts = String::new();
            for j in (0..ser.x.len())
                .step_by(stride)
                .chain(std::iter::once(ser.x.len().saturating_sub(1)))
            {
                if ser.x[j].is_finite() && ser.y[j].is_finite() {
                    let _ = write!(pts, "{:.2},{:.2} ", px(ser.x[j]), py(ser.y[j]));
                }
            }
            let _ = writeln!(
                s,
                r#"<polyline fill="none" stroke="{}" stroke-width="1.5" points="{pts}"/>"#,
                ser.color
            );
            let ly = MT + 16.0 + 16.0 * i as f64;
            let _ = writeln!(
                s,
                r#"<line x1="{:.1}" y1="{ly:.1}" x2="{:.1}" y2="{ly:.1}" stroke="{}" stroke-width="2"/><text x="{:.1}" y="{:.1}">{}</text>"#,
                W - MR - 150.0,
                W - MR - 125.0,
                ser.color,
                W - MR - 120.0,
                ly + 4.0,
                ser.label
            );
        }
        for &(mx, my) in &self.markers {
            let _ = writeln!(
                s,
                r##"<circle cx="{:.1}" cy="{:.1}" r="4" fill="none" stroke="#c00" stroke-width="1.5"/>"##,
                px(mx),
                py(my)
            );
        }
        s.push_str("</svg>\n");
        s
    }
}

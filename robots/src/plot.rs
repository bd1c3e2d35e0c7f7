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
/// The top margin holds the title and, under it, the legend (outside the data).
const MT: f64 = 52.0;
const MB: f64 = 50.0;

/// A tick's label with as many decimals as the tick step needs, so that a tick computed as
/// `k · 0.02` reads `-0.02`, not `-0.019999999999999997`.
fn tick_label(t: f64, step: f64) -> String {
    if t == 0.0 {
        return "0".into();
    }
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    if t.abs() >= 1e5 || decimals > 5 {
        let mantissa_decimals =
            ((t.abs().log10().floor() - step.log10().floor()).max(0.0)) as usize;
        format!("{t:.mantissa_decimals$e}")
    } else {
        format!("{t:.decimals$}")
    }
}

/// Indices of a polyline thinned to at most `2 · buckets` points: the first and last
/// index of each bucket of consecutive points and, in their order, the smallest and the
/// largest `y` in it, so that a one-sample spike survives the thinning.
fn thin_min_max(y: &[f64], buckets: usize) -> Vec<usize> {
    let n = y.len();
    if n <= 4 * buckets {
        return (0..n).collect();
    }
    let size = n.div_ceil(buckets);
    let mut out = Vec::with_capacity(4 * buckets);
    for start in (0..n).step_by(size) {
        let end = (start + size).min(n);
        let (mut lo, mut hi) = (start, start);
        for j in start..end {
            if y[j] < y[lo] {
                lo = j;
            }
            if y[j] > y[hi] {
                hi = j;
            }
        }
        let mut pick = [start, lo.min(hi), lo.max(hi), end - 1];
        pick.sort_unstable();
        for j in pick {
            if out.last() != Some(&j) {
                out.push(j);
            }
        }
    }
    out
}

fn tick_step(lo: f64, hi: f64) -> f64 {
    let span = (hi - lo).max(1e-12);
    let mag = 10f64.powf((span / 6.0).log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| span / s <= 7.0)
        .unwrap_or(10.0 * mag)
}

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
            r#"<text x="{}" y="20" text-anchor="middle" font-size="15">{}</text>"#,
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
                r#"<text x="{x:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
                H - MB + 16.0,
                tick_label(t, tick_step(x0, x1))
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
                r#"<text x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"#,
                ML - 6.0,
                y + 4.0,
                tick_label(t, tick_step(y0, y1))
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
        // The legend sits in the top margin, right-aligned, one entry after another.
        let mut lx = W - MR;
        for ser in self.series.iter().rev() {
            let width = 30.0 + 7.0 * ser.label.chars().count() as f64;
            lx -= width;
            let ly = MT - 10.0;
            let _ = writeln!(
                s,
                r#"<line x1="{lx:.1}" y1="{ly:.1}" x2="{:.1}" y2="{ly:.1}" stroke="{}" stroke-width="2"/><text x="{:.1}" y="{:.1}">{}</text>"#,
                lx + 20.0,
                ser.color,
                lx + 24.0,
                ly + 4.0,
                ser.label
            );
        }
        for ser in &self.series {
            // At most ~4000 points per curve (two per pixel column and extremes kept).
            let mut pts = String::new();
            for j in thin_min_max(ser.y, 1000) {
                if ser.x[j].is_finite() && ser.y[j].is_finite() {
                    let _ = write!(pts, "{:.2},{:.2} ", px(ser.x[j]), py(ser.y[j]));
                }
            }
            let _ = writeln!(
                s,
                r#"<polyline fill="none" stroke="{}" stroke-width="1.5" points="{pts}"/>"#,
                ser.color
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_carry_no_rounding_noise() {
        let (lo, hi) = (-0.061, 0.061);
        let step = tick_step(lo, hi);
        let labels: Vec<String> = nice_ticks(lo, hi)
            .iter()
            .map(|&t| tick_label(t, step))
            .collect();
        assert!(labels.contains(&"-0.02".to_string()), "{labels:?}");
        // A label is the tick to the step's precision, no more digits than that.
        for l in &labels {
            assert!(l.len() <= 5, "{labels:?}");
        }
        assert_eq!(tick_label(2.0e6, 5.0e5), "2.0e6");
    }

    #[test]
    fn a_one_sample_spike_survives_thinning() {
        let mut y: Vec<f64> = (0..100_000).map(|k| (k as f64 * 1e-3).sin()).collect();
        y[54_321] = 50.0;
        y[77_777] = -50.0;
        let kept = thin_min_max(&y, 1000);
        assert!(kept.len() <= 4000);
        assert!(kept.contains(&54_321) && kept.contains(&77_777));
        assert!(kept.windows(2).all(|w| w[0] < w[1]), "in order");
        assert_eq!((kept[0], *kept.last().unwrap()), (0, y.len() - 1));
    }

    #[test]
    fn the_legend_sits_outside_the_plotting_area() {
        let (x, y) = ([0.0, 1.0], [0.0, 1.0]);
        let plot = Plot {
            title: "t",
            xlabel: "x",
            ylabel: "y",
            series: vec![
                Series {
                    label: "first",
                    x: &x,
                    y: &y,
                    color: "red",
                },
                Series {
                    label: "second",
                    x: &x,
                    y: &y,
                    color: "blue",
                },
            ],
            bounds: vec![],
            markers: vec![],
            equal_axes: false,
        };
        let svg = plot.to_svg();
        for line in svg.lines().filter(|l| l.contains("stroke-width=\"2\"")) {
            let y1: f64 = line
                .split("y1=\"")
                .nth(1)
                .unwrap()
                .split('"')
                .next()
                .unwrap()
                .parse()
                .unwrap();
            assert!(y1 < MT, "legend at y = {y1} inside the plot (top at {MT})");
        }
    }
}

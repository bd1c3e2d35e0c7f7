//! Geometric pose paths for the kinematic starts of planar robots: quintic Hermite
//! segments between poses `(x, y, θ)`, timed rest to rest.

use dmech_lie::Se2;

/// A pose `(x, y, θ)` (m, m, rad).
pub type Pose = [f64; 3];

/// Cumulative chord length of the poses' positions, as fractions of the total.
pub fn path_fractions(poses: &[Pose]) -> Vec<f64> {
    let mut acc = vec![0.0];
    for w in poses.windows(2) {
        let d = ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt();
        acc.push(acc.last().unwrap() + d);
    }
    let total = acc.last().copied().unwrap_or(0.0).max(f64::MIN_POSITIVE);
    acc.iter().map(|a| a / total).collect()
}

/// Rest to rest along the path: the path fraction `3τ² − 2τ³` at time fraction `τ`.
pub fn path_fraction_at(tau: f64) -> f64 {
    tau * tau * (3.0 - 2.0 * tau)
}

/// The time fraction at which the path fraction `f` is reached (bisection on the monotone
/// `3τ² − 2τ³`).
pub fn time_of_path_fraction(f: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if path_fraction_at(mid) < f {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The geometric start path through `poses` (at least two): quintic Hermite segments with
/// tangents along the headings (reversed when `reverse`, driving backwards), scaled by the
/// chord, and zero second derivatives at the poses (zero curvature: a car stands there with
/// its steering straight, a snakeboard with its axles straight); the heading along the path
/// is the tangent's direction, so the path is one a robot that cannot slip sideways can
/// follow (its curvature permitting). Timed rest to rest by `3τ² − 2τ³`. Returns `n + 1`
/// poses.
pub fn start_path(poses: &[Pose], reverse: bool, n: usize) -> Vec<Se2<f64>> {
    let fractions = path_fractions(poses);
    let dir = if reverse { -1.0 } else { 1.0 };
    let mut heading_prev = poses[0][2];
    (0..=n)
        .map(|k| {
            let f = path_fraction_at(k as f64 / n as f64);
            let seg = fractions
                .windows(2)
                .position(|w| f <= w[1])
                .unwrap_or(poses.len() - 2);
            let (a, b) = (poses[seg], poses[seg + 1]);
            let span = (fractions[seg + 1] - fractions[seg]).max(f64::MIN_POSITIVE);
            let t = ((f - fractions[seg]) / span).clamp(0.0, 1.0);
            let chord = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
            let (ta, tb) = (
                [dir * a[2].cos() * chord, dir * a[2].sin() * chord],
                [dir * b[2].cos() * chord, dir * b[2].sin() * chord],
            );
            let (t2, t3, t4, t5) = (t * t, t * t * t, t.powi(4), t.powi(5));
            let (h00, h10, h01, h11) = (
                1.0 - 10.0 * t3 + 15.0 * t4 - 6.0 * t5,
                t - 6.0 * t3 + 8.0 * t4 - 3.0 * t5,
                10.0 * t3 - 15.0 * t4 + 6.0 * t5,
                -4.0 * t3 + 7.0 * t4 - 3.0 * t5,
            );
            let (d00, d10, d01, d11) = (
                -30.0 * t2 + 60.0 * t3 - 30.0 * t4,
                1.0 - 18.0 * t2 + 32.0 * t3 - 15.0 * t4,
                30.0 * t2 - 60.0 * t3 + 30.0 * t4,
                -12.0 * t2 + 28.0 * t3 - 15.0 * t4,
            );
            let p = |i: usize| h00 * a[i] + h10 * ta[i] + h01 * b[i] + h11 * tb[i];
            let dp = |i: usize| d00 * a[i] + d10 * ta[i] + d01 * b[i] + d11 * tb[i];
            // The heading is the direction of motion (turned by π when reversing), kept
            // continuous; where the tangent vanishes (never inside a segment with unit
            // tangents) the previous heading stays.
            let (dx, dy) = (dir * dp(0), dir * dp(1));
            let heading = if dx.hypot(dy) > 1e-12 {
                let raw = dy.atan2(dx);
                heading_prev + wrap(raw - heading_prev)
            } else {
                heading_prev
            };
            heading_prev = heading;
            Se2::new(p(0), p(1), heading)
        })
        .collect()
}

/// An angle in `(−π, π]`.
fn wrap(a: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    a - two_pi * ((a + std::f64::consts::PI) / two_pi).floor()
}

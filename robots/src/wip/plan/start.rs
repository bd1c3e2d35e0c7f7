//! The WIP planner's starts: a kinematically consistent path along the waypoint polyline,
//! laid out for the variational and the Runge–Kutta transcriptions.

use crate::wip::plan::problem::{varint_layout, PlanModel};
use crate::wip::plan::problems::{arc_lengths, PlanProblem};
use crate::wip::Wip;
use dmech_ocp::transcription::layout::Layout;
use nalgebra::SVector;

/// A start along the waypoint polyline: the arc length is a monotone cubic in time through
/// the waypoints' (stage, arc length), with zero speed at both ends; the positions are
/// smoothed by a moving average (window `±0.25 s`) so that corners are cut and the speed is
/// continuous, the heading is the direction of motion, the wheel angles follow by rolling,
/// tilt, charges, currents and voltages are zero. States are kinematically consistent:
/// `(x, y, θ)` and `(φR, φL)` agree along the path.
///
/// Why a cubic: with the arc length linear between waypoints the start leaves rest at the
/// first segment's mean speed within the smoothing window (1.2 m/s² on the eight, where the
/// 2 V/s rate limit allows about 0.2); the first Newton steps then try to build that
/// acceleration from `u = 0` and the rate limits at both ends cut them to 2–10 % for 40
/// iterations (phase one took 83 iterations from that start, 17 from this one).
pub fn polyline_start(wip: &Wip, p: &PlanProblem) -> Vec<(SVector<f64, 3>, SVector<f64, 5>)> {
    let n = p.n;
    let s_at = arc_lengths(&p.points);
    // Arc length against time: a monotone cubic (Fritsch–Carlson) through the waypoints'
    // (stage, arc length), at rest at both ends, so that the start accelerates smoothly.
    let m = p.stages.len();
    let secant: Vec<f64> = (1..m)
        .map(|j| (s_at[j] - s_at[j - 1]) / (p.stages[j] - p.stages[j - 1]) as f64)
        .collect();
    let slope: Vec<f64> = (0..m)
        .map(|j| {
            if j == 0 || j == m - 1 {
                0.0
            } else {
                let (a, b) = (secant[j - 1], secant[j]);
                if a * b <= 0.0 {
                    0.0
                } else {
                    2.0 * a * b / (a + b)
                }
            }
        })
        .collect();
    let arc_of_stage = |k: usize| -> f64 {
        let j = p.stages.partition_point(|&sk| sk <= k).clamp(1, m - 1);
        let (k0, k1) = (p.stages[j - 1], p.stages[j]);
        let dk = (k1 - k0) as f64;
        let f = ((k as f64 - k0 as f64) / dk).clamp(0.0, 1.0);
        let (h00, h10, h01, h11) = (
            (1.0 + 2.0 * f) * (1.0 - f) * (1.0 - f),
            f * (1.0 - f) * (1.0 - f),
            f * f * (3.0 - 2.0 * f),
            f * f * (f - 1.0),
        );
        h00 * s_at[j - 1] + h10 * dk * slope[j - 1] + h01 * s_at[j] + h11 * dk * slope[j]
    };
    let point_at = |s: f64| -> [f64; 2] {
        let j = s_at.partition_point(|&sj| sj <= s).clamp(1, s_at.len() - 1);
        let len = s_at[j] - s_at[j - 1];
        let f = ((s - s_at[j - 1]) / len).clamp(0.0, 1.0);
        let (a, b) = (p.points[j - 1], p.points[j]);
        [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])]
    };
    let raw: Vec<[f64; 2]> = (0..=n).map(|k| point_at(arc_of_stage(k))).collect();
    let half = ((0.25 / p.h).round() as usize).max(1);
    let smooth: Vec<[f64; 2]> = (0..=n)
        .map(|k| {
            let (lo, hi) = (k.saturating_sub(half), (k + half).min(n));
            let m = (hi - lo + 1) as f64;
            let (sx, sy) = raw[lo..=hi]
                .iter()
                .fold((0.0, 0.0), |(a, b), q| (a + q[0], b + q[1]));
            [sx / m, sy / m]
        })
        .collect();
    // Heading: direction of motion, unwrapped, held where the robot stands still.
    let mut raw_theta = vec![p.start_heading; n + 1];
    let mut prev = p.start_heading;
    for k in 0..n {
        let (dx, dy) = (
            smooth[k + 1][0] - smooth[k][0],
            smooth[k + 1][1] - smooth[k][1],
        );
        if (dx * dx + dy * dy).sqrt() > 1e-9 {
            let a = dy.atan2(dx);
            let mut d = a - prev;
            d -= (d / std::f64::consts::TAU).round() * std::f64::consts::TAU;
            prev += d;
        }
        raw_theta[k + 1] = prev;
    }
    // The end heading, unwrapped next to the path's last direction.
    let mut end = p.end_heading;
    end += ((prev - end) / std::f64::consts::TAU).round() * std::f64::consts::TAU;
    // Blend from the start heading onto the path (and off it onto the end heading) over
    // one window: the interior keeps the direction of motion.
    let ramp = (2 * half) as f64;
    let theta: Vec<f64> = (0..=n)
        .map(|k| {
            let a = (k as f64 / ramp).min(1.0);
            let b = ((n - k) as f64 / ramp).min(1.0);
            let th = a * raw_theta[k] + (1.0 - a) * p.start_heading;
            b * th + (1.0 - b) * end
        })
        .collect();
    let (r, d) = (wip.params.r, wip.params.d);
    let mut dist = 0.0;
    let mut out = Vec::with_capacity(n + 1);
    for k in 0..=n {
        if k > 0 {
            let (dx, dy) = (
                smooth[k][0] - smooth[k - 1][0],
                smooth[k][1] - smooth[k - 1][1],
            );
            dist += (dx * dx + dy * dy).sqrt();
        }
        let th = theta[k] - p.start_heading;
        let g = SVector::<f64, 3>::new(smooth[k][0], smooth[k][1], theta[k]);
        let s = SVector::<f64, 5>::new(0.0, (dist + d * th) / r, (dist - d * th) / r, 0.0, 0.0);
        out.push((g, s));
    }
    out
}

/// Stage states from [`polyline_start`] and the shape velocities
/// `vel_j = (s_{j+1} − s_j)/h`; stage `k` (`0 < k < N`) carries `vel_{k − lag}` (`lag = 1`:
/// the VI's `v_{k−1}`; `lag = 0`: RK's `v_k`). Both ends are at rest. The model takes the
/// first `NS` components of the full shape `(α, φR, φL, qR, qL)`.
fn start_states<M: PlanModel<NS>, const NS: usize, const NX: usize>(
    model: &M,
    p: &PlanProblem,
    lag: usize,
    layout: Layout,
) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, NS>>) {
    let path = polyline_start(model.wip(), p);
    let n = p.n;
    let shape = |k: usize| path[k].1.fixed_rows::<NS>(0).into_owned();
    let vel: Vec<SVector<f64, NS>> = (0..n).map(|k| (shape(k + 1) - shape(k)) / p.h).collect();
    let xs = (0..=n)
        .map(|k| {
            let mut x = SVector::<f64, NX>::zeros();
            x.fixed_rows_mut::<3>(0).copy_from(&path[k].0);
            layout.set_shape(&mut x, &shape(k));
            if k > 0 && k < n {
                x.fixed_rows_mut::<NS>(layout.v_at())
                    .copy_from(&vel[k - lag]);
            }
            x
        })
        .collect();
    (xs, vel)
}

/// The VI start: `start_states` with `w_k = (v_k, u_k = 0)`.
pub fn varint_start<M: PlanModel<NS>, const NS: usize, const NX: usize, const NW: usize>(
    model: &M,
    p: &PlanProblem,
) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, NW>>) {
    let (xs, vel) = start_states::<M, NS, NX>(model, p, 1, varint_layout::<M, NS, NX>(model));
    let ws = vel
        .iter()
        .map(|v| {
            let mut w = SVector::<f64, NW>::zeros();
            w.fixed_rows_mut::<NS>(0).copy_from(v);
            w
        })
        .collect();
    (xs, ws)
}

/// The RK start: `start_states` with `v_k` in the state, `u = 0`.
pub fn rk_start<M: PlanModel<NS>, const NS: usize, const NX: usize>(
    model: &M,
    p: &PlanProblem,
) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, 2>>) {
    let (mut xs, _) = start_states::<M, NS, NX>(model, p, 0, Layout::new(3, NS, 2));
    // The currents on their slow manifold for u = 0 (steady state). The current is stiff
    // (h R_m/L_m = 18.75 at h = 5 ms): an explicit step from i = 0 amplifies the mismatch by
    // |R(−hR/L)| (4,200 for RK4), which left RK4 a start violation of 1e4.
    for x in xs.iter_mut() {
        let mut v = x.fixed_rows::<NS>(3 + NS).into_owned();
        model.settle_currents(&mut v);
        x.fixed_rows_mut::<NS>(3 + NS).copy_from(&v);
    }
    let n = p.n;
    (xs, vec![SVector::zeros(); n])
}

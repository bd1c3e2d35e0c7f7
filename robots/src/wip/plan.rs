//! The WIP's energy-optimal planning problem (paper eq. (opt), `benchmarks.md`) declared
//! for the generic solver of `dmech-ocp`: cost, bounds, waypoints, boundary states, and a
//! start along the waypoint polyline.
//!
//! Stage layout (both transcriptions, `NX = 15`): `x = (x, y, θ, α, φR, φL, qR, qL,
//! v(5), u_prev(2))`, where `v` is `v_{k−1}` for the variational integrator and `v_k`
//! for Runge–Kutta. The VI decides `w = (v_k, u_k)`, RK decides `w = u_k`.

use super::benchmarks::{arc_lengths, PlanProblem};
use super::simulate::Integrator;
use super::Wip;
use dmech::{ForcingQuadrature, RungeKutta};
use dmech_lie::Real;
use dmech_ocp::ipm::{IpOptions, Iterate, SolveResult, Solver};
use dmech_ocp::problem::{StageProblem, StateEquality};
use dmech_ocp::runge_kutta::RkStages;
use dmech_ocp::varint::VarIntStages;
use nalgebra::{SMatrix, SVector};

pub const NX: usize = 15;
/// Inequalities per stage: uR, uL, ΔuR, ΔuL, iR, iL, α, v_θ.
pub const NC: usize = 8;
const V_AT: usize = 8;
const U_PREV_AT: usize = 13;

/// `d_0` of the first (smoothed-friction) phase, s/rad.
pub const SMOOTH_FRICTION_SLOPE: f64 = 1.0;

/// The bounds of benchmarks.md.
#[derive(Clone, Copy, Debug)]
pub struct PlanBounds {
    pub u_max: f64,
    /// Voltage rate limit in V/s (the bound on `|u_k − u_{k−1}|` is `h` times it).
    pub du_max_per_s: f64,
    pub i_max: f64,
    pub alpha_max: f64,
    pub v_theta_max: f64,
}

impl Default for PlanBounds {
    fn default() -> Self {
        PlanBounds {
            u_max: 5.0,
            du_max_per_s: 2.0,
            i_max: 3.0,
            alpha_max: 15f64.to_radians(),
            v_theta_max: 120f64.to_radians(),
        }
    }
}

/// What is common to both transcriptions.
pub struct WipPlan<'a> {
    pub wip: &'a Wip,
    pub problem: &'a PlanProblem,
    pub bounds: PlanBounds,
}

impl WipPlan<'_> {
    fn x0(&self) -> SVector<f64, NX> {
        let mut x = SVector::zeros();
        x[0] = self.problem.points[0][0];
        x[1] = self.problem.points[0][1];
        x[2] = self.problem.start_heading;
        x
    }

    fn bounds_vec(&self) -> (SVector<f64, NC>, SVector<f64, NC>) {
        let b = &self.bounds;
        let du = b.du_max_per_s * self.problem.h;
        let hi = SVector::<f64, NC>::from_column_slice(&[
            b.u_max,
            b.u_max,
            du,
            du,
            b.i_max,
            b.i_max,
            b.alpha_max,
            b.v_theta_max,
        ]);
        (-hi, hi)
    }

    /// Waypoint positions at their stages; at the end the full pose, `α = 0` and all
    /// velocities and currents zero.
    fn equalities(&self) -> Vec<StateEquality> {
        let p = self.problem;
        let mut eqs = Vec::new();
        for (pt, &k) in p.points.iter().zip(&p.stages) {
            if k == 0 || k == p.n {
                continue;
            }
            for (i, &value) in pt.iter().enumerate() {
                eqs.push(StateEquality {
                    stage: k,
                    index: i,
                    value,
                });
            }
        }
        let end = p.points.last().expect("at least two points");
        let mut fix = |index, value| {
            eqs.push(StateEquality {
                stage: p.n,
                index,
                value,
            })
        };
        fix(0, end[0]);
        fix(1, end[1]);
        fix(2, p.end_heading);
        fix(3, 0.0);
        for i in 0..5 {
            fix(V_AT + i, 0.0);
        }
        eqs
    }

    /// `v_θ` from the wheel rates.
    fn heading_rate<T: Real>(&self, vr: T, vl: T) -> T {
        (vr - vl) * (self.wip.params.r / (2.0 * self.wip.params.d))
    }
}

/// The VI transcription: `NW = 7` (`v_k`, `u_k`), `NE = 5` (momentum matching).
pub struct VarIntPlan<'a> {
    pub plan: WipPlan<'a>,
    pub stages: VarIntStages<'a, Wip>,
}

impl<'a> VarIntPlan<'a> {
    pub fn new(wip: &'a Wip, problem: &'a PlanProblem, bounds: PlanBounds) -> Self {
        VarIntPlan {
            plan: WipPlan {
                wip,
                problem,
                bounds,
            },
            stages: VarIntStages::new::<3, 2, 5, 2>(wip, problem.h, ForcingQuadrature::Right),
        }
    }
}

impl StageProblem<NX, 7, 5, NC> for VarIntPlan<'_> {
    fn horizon(&self) -> usize {
        self.plan.problem.n
    }
    fn initial_state(&self) -> SVector<f64, NX> {
        self.plan.x0()
    }
    fn dynamics<T: Real>(
        &self,
        _k: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, 7>,
    ) -> SVector<T, NX> {
        self.stages.dynamics::<T, 3, 2, 5, 2, NX, 7>(x, w)
    }
    fn equality<T: Real>(&self, _k: usize, x: &SVector<T, NX>, w: &SVector<T, 7>) -> SVector<T, 5> {
        self.stages.equality::<T, 3, 2, 5, 2, NX, 7>(x, w)
    }
    fn affine_in_state(&self) -> bool {
        // The cost reads w only; the inequalities read α and u_{k−1} linearly.
        true
    }
    fn equality_jacobian(
        &self,
        _k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, 7>,
    ) -> (SVector<f64, 5>, SMatrix<f64, 5, NX>, SMatrix<f64, 5, 7>) {
        self.stages.equality_jacobian::<3, 2, 5, 2, NX, 7>(x, w)
    }
    fn cost<T: Real>(&self, _k: usize, _x: &SVector<T, NX>, w: &SVector<T, 7>) -> T {
        (w[5] * w[3] + w[6] * w[4]) * 0.5
    }
    fn constraints<T: Real>(
        &self,
        _k: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, 7>,
    ) -> SVector<T, NC> {
        SVector::<T, NC>::from_column_slice(&[
            w[5],
            w[6],
            w[5] - x[U_PREV_AT],
            w[6] - x[U_PREV_AT + 1],
            w[3],
            w[4],
            x[3],
            self.plan.heading_rate(w[1], w[2]),
        ])
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, NC>, SVector<f64, NC>) {
        self.plan.bounds_vec()
    }
    fn state_equalities(&self) -> Vec<StateEquality> {
        self.plan.equalities()
    }
}

/// The Runge–Kutta transcriptions: `NW = 2` (`u_k`), no stage equality.
pub struct RkPlan<'a> {
    pub plan: WipPlan<'a>,
    pub stages: RkStages<'a, Wip>,
}

impl<'a> RkPlan<'a> {
    pub fn new(wip: &'a Wip, problem: &'a PlanProblem, bounds: PlanBounds, rk: RungeKutta) -> Self {
        RkPlan {
            plan: WipPlan {
                wip,
                problem,
                bounds,
            },
            stages: RkStages::new::<3, 2, 5, 2>(wip, problem.h, rk),
        }
    }
}

impl StageProblem<NX, 2, 0, NC> for RkPlan<'_> {
    fn horizon(&self) -> usize {
        self.plan.problem.n
    }
    fn initial_state(&self) -> SVector<f64, NX> {
        self.plan.x0()
    }
    fn dynamics<T: Real>(
        &self,
        _k: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, 2>,
    ) -> SVector<T, NX> {
        self.stages.dynamics::<T, 3, 2, 5, 2, NX, 2>(x, w)
    }
    fn equality<T: Real>(
        &self,
        _k: usize,
        _x: &SVector<T, NX>,
        _w: &SVector<T, 2>,
    ) -> SVector<T, 0> {
        SVector::<T, 0>::zeros()
    }
    fn cost<T: Real>(&self, _k: usize, x: &SVector<T, NX>, w: &SVector<T, 2>) -> T {
        (w[0] * x[V_AT + 3] + w[1] * x[V_AT + 4]) * 0.5
    }
    fn constraints<T: Real>(
        &self,
        _k: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, 2>,
    ) -> SVector<T, NC> {
        SVector::<T, NC>::from_column_slice(&[
            w[0],
            w[1],
            w[0] - x[U_PREV_AT],
            w[1] - x[U_PREV_AT + 1],
            x[V_AT + 3],
            x[V_AT + 4],
            x[3],
            self.plan.heading_rate(x[V_AT + 1], x[V_AT + 2]),
        ])
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, NC>, SVector<f64, NC>) {
        self.plan.bounds_vec()
    }
    fn state_equalities(&self) -> Vec<StateEquality> {
        self.plan.equalities()
    }
}

/// A start along the waypoint polyline: the arc length is interpolated linearly in time
/// between waypoint stages, the positions are smoothed by a moving average (window
/// `±0.25 s`) so that corners are cut and the speed is continuous, the heading is the
/// direction of motion, the wheel angles follow by rolling, tilt, charges, currents and
/// voltages are zero. States are kinematically consistent: `(x, y, θ)` and `(φR, φL)`
/// agree along the path.
pub fn polyline_start(wip: &Wip, p: &PlanProblem) -> Vec<(SVector<f64, 3>, SVector<f64, 5>)> {
    let n = p.n;
    let s_at = arc_lengths(&p.points);
    let arc_of_stage = |k: usize| -> f64 {
        let j = p
            .stages
            .partition_point(|&sk| sk <= k)
            .clamp(1, p.stages.len() - 1);
        let (k0, k1) = (p.stages[j - 1], p.stages[j]);
        let f = ((k as f64 - k0 as f64) / (k1 - k0) as f64).clamp(0.0, 1.0);
        s_at[j - 1] + f * (s_at[j] - s_at[j - 1])
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
/// the VI's `v_{k−1}`; `lag = 0`: RK's `v_k`). Both ends are at rest.
fn start_states(
    wip: &Wip,
    p: &PlanProblem,
    lag: usize,
) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, 5>>) {
    let path = polyline_start(wip, p);
    let n = p.n;
    let vel: Vec<SVector<f64, 5>> = (0..n).map(|k| (path[k + 1].1 - path[k].1) / p.h).collect();
    let xs = (0..=n)
        .map(|k| {
            let mut x = SVector::<f64, NX>::zeros();
            x.fixed_rows_mut::<3>(0).copy_from(&path[k].0);
            x.fixed_rows_mut::<5>(3).copy_from(&path[k].1);
            if k > 0 && k < n {
                x.fixed_rows_mut::<5>(V_AT).copy_from(&vel[k - lag]);
            }
            x
        })
        .collect();
    (xs, vel)
}

/// The VI start: [`start_states`] with `w_k = (v_k, u_k = 0)`.
pub fn varint_start(wip: &Wip, p: &PlanProblem) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, 7>>) {
    let (xs, vel) = start_states(wip, p, 1);
    let ws = vel
        .iter()
        .map(|v| {
            let mut w = SVector::<f64, 7>::zeros();
            w.fixed_rows_mut::<5>(0).copy_from(v);
            w
        })
        .collect();
    (xs, ws)
}

/// The RK start: [`start_states`] with `v_k` in the state, `u = 0`.
pub fn rk_start(wip: &Wip, p: &PlanProblem) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, 2>>) {
    let (mut xs, _) = start_states(wip, p, 0);
    // The currents on their slow manifold for u = 0 (steady state). The current is stiff
    // (h R_m/L_m = 18.75 at h = 5 ms): an explicit step from i = 0 amplifies the mismatch by
    // |R(−hR/L)| (4,200 for RK4), which left RK4 a start violation of 1e4.
    let q = &wip.params;
    for x in xs.iter_mut() {
        let va = x[V_AT];
        x[V_AT + 3] = q.steady_current(0.0, x[V_AT + 1] - va);
        x[V_AT + 4] = q.steady_current(0.0, x[V_AT + 2] - va);
    }
    let n = p.n;
    (xs, vec![SVector::zeros(); n])
}

/// The planned trajectory in a transcription-independent form, per stage `k = 0..=N`:
/// `(g, s, v_k, u_k)` with `v_N = 0` and `u_N = u_{N−1}`.
#[derive(Clone, Debug)]
pub struct PlannedTrajectory {
    pub h: f64,
    pub g: Vec<SVector<f64, 3>>,
    pub s: Vec<SVector<f64, 5>>,
    pub v: Vec<SVector<f64, 5>>,
    pub u: Vec<SVector<f64, 2>>,
}

/// Which transcription a plan uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transcription {
    VarInt,
    Rk(RungeKutta),
}

/// The same names as the simulator's integrators (`varint`, `rk1`, `rk2`, `rk4`).
impl std::str::FromStr for Transcription {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Ok(match s.parse::<Integrator>()? {
            Integrator::VarInt { .. } => Transcription::VarInt,
            Integrator::Rk(rk) => Transcription::Rk(rk),
        })
    }
}

/// A finished solve, transcription-independent.
pub struct PlanOutcome {
    pub status: dmech_ocp::ipm::Status,
    pub iterations: usize,
    pub objective: f64,
    pub max_violation: f64,
    pub timings: dmech_ocp::ipm::Timings,
    pub trajectory: PlannedTrajectory,
}

fn outcome<const NW: usize>(
    r: SolveResult<NX, NW, NC>,
    h: f64,
    velocity_in_w: bool,
) -> PlanOutcome {
    let it: &Iterate<NX, NW, NC> = &r.iterate;
    let n = it.w.len();
    let mut t = PlannedTrajectory {
        h,
        g: Vec::with_capacity(n + 1),
        s: Vec::with_capacity(n + 1),
        v: Vec::with_capacity(n + 1),
        u: Vec::with_capacity(n + 1),
    };
    for k in 0..=n {
        let x = &it.x[k];
        t.g.push(x.fixed_rows::<3>(0).into_owned());
        t.s.push(x.fixed_rows::<5>(3).into_owned());
        let v = if velocity_in_w {
            if k < n {
                it.w[k].fixed_rows::<5>(0).into_owned()
            } else {
                SVector::zeros()
            }
        } else {
            x.fixed_rows::<5>(V_AT).into_owned()
        };
        t.v.push(v);
        let u = it.w[k.min(n - 1)].fixed_rows::<2>(NW - 2).into_owned();
        t.u.push(u);
    }
    PlanOutcome {
        status: r.status,
        iterations: r.iterations,
        objective: r.objective,
        max_violation: r.max_violation,
        timings: r.timings,
        trajectory: t,
    }
}

/// Plan with the given transcription from the polyline start.
///
/// Two phases: the problem with a gentler Coulomb friction (`d_0 = 1 s/rad` instead of 8:
/// same saturated torque, 8× smaller slope at zero relative wheel speed) from the
/// polyline start; then the true problem, warm-started from that solution with a small
/// barrier parameter. The `tanh` of the Coulomb friction has slope `d_c d_0` at zero wheel
/// speed and saturates within ~0.3 rad/s: Newton steps from a start at rest or with wrong
/// wheel speeds overshoot it by orders of magnitude and the line search stalls. Switching
/// the Coulomb friction off entirely in phase one (tried) leaves phase two too far to go:
/// it is 60 % of the optimal energy.
pub fn plan(
    wip: &Wip,
    problem: &PlanProblem,
    transcription: Transcription,
    opts: IpOptions,
) -> PlanOutcome {
    let bounds = PlanBounds::default();
    let mut smooth = *wip;
    smooth.params.d_0 = SMOOTH_FRICTION_SLOPE.min(wip.params.d_0);
    let phases = (smooth != *wip).then_some(opts.clone());
    match transcription {
        Transcription::VarInt => {
            let (xs, ws) = varint_start(wip, problem);
            let (p0, p1) = (
                VarIntPlan::new(&smooth, problem, bounds),
                VarIntPlan::new(wip, problem, bounds),
            );
            two_phase::<_, 7, 5, 2>(&p0, &p1, phases, xs, ws, opts, problem.h, true)
        }
        Transcription::Rk(rk) => {
            let (xs, ws) = rk_start(wip, problem);
            let (p0, p1) = (
                RkPlan::new(&smooth, problem, bounds, rk),
                RkPlan::new(wip, problem, bounds, rk),
            );
            two_phase::<_, 2, 0, 2>(&p0, &p1, phases, xs, ws, opts, problem.h, false)
        }
    }
}

/// Phase one (`smoothed`) from `(xs, ws)`; phase two (`exact`) from its solution, unless
/// `second` is `None` (the model has no friction to smooth). See [`plan`].
#[allow(clippy::too_many_arguments)]
fn two_phase<P, const NW: usize, const NE: usize, const NU: usize>(
    smoothed: &P,
    exact: &P,
    second: Option<IpOptions>,
    xs: Vec<SVector<f64, NX>>,
    ws: Vec<SVector<f64, NW>>,
    opts: IpOptions,
    h: f64,
    velocity_in_w: bool,
) -> PlanOutcome
where
    P: StageProblem<NX, NW, NE, NC>,
{
    let first = if second.is_some() { smoothed } else { exact };
    // Phase one only has to bring phase two a start: phase two begins at μ = μ₀/100, so
    // solving phase one far below that barrier is work thrown away (measured on the eight:
    // 60 of its 137 iterations). It stops at tolerance 10 μ₀/100.
    let phase_one = match &second {
        Some(o) => IpOptions {
            tol: (10.0 * o.warm_mu_init()).max(o.tol),
            ..opts.clone()
        },
        None => opts.clone(),
    };
    let s0: Solver<_, NX, NW, NE, NU, NC> = Solver::new(first, phase_one);
    let r0 = s0.solve(s0.initial_iterate(xs, ws));
    let Some(o) = second.filter(|_| r0.status == dmech_ocp::ipm::Status::Solved) else {
        return outcome(r0, h, velocity_in_w);
    };
    let warm = IpOptions {
        mu_init: o.warm_mu_init(),
        ..o
    };
    let s1: Solver<_, NX, NW, NE, NU, NC> = Solver::new(exact, warm);
    let r = s1.solve(s1.warm_iterate(r0.iterate.clone()));
    outcome(merge(r, &r0), h, velocity_in_w)
}

/// The second phase's result with the first phase's iterations and time added.
fn merge<const NW: usize>(
    mut r: SolveResult<NX, NW, NC>,
    r0: &SolveResult<NX, NW, NC>,
) -> SolveResult<NX, NW, NC> {
    r.iterations += r0.iterations;
    r.timings.derivatives += r0.timings.derivatives;
    r.timings.kkt += r0.timings.kkt;
    r.timings.line_search += r0.timings.line_search;
    r.timings.riccati += r0.timings.riccati;
    r.timings.factorizations += r0.timings.factorizations;
    r.timings.second_order_corrections += r0.timings.second_order_corrections;
    r.timings.total += r0.timings.total;
    r
}

//! Open-loop simulation of the WIP from a reduced state with zero-order-hold voltages.

use super::state::{from_reduced, to_reduced, ReducedState};
use super::Wip;
pub use crate::io::InputSchedule;
use dmech::continuous::{ContinuousModel, RungeKutta};
use dmech::{
    Discretisation, ForcingQuadrature, JacobianPolicy, NewtonCache, StepError,
    VariationalIntegrator, ViState,
};
use nalgebra::{Complex, SVector};
use std::fmt::Write as _;

/// The time-stepping schemes `wip` offers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integrator {
    /// The variational integrator: its discretisation (the paper's first-order one, or the
    /// symmetric midpoint one), forcing quadrature (first order only) and Newton Jacobian
    /// policy.
    VarInt {
        discretisation: Discretisation,
        quadrature: ForcingQuadrature,
        jacobian: JacobianPolicy,
    },
    Rk(RungeKutta),
}

impl std::str::FromStr for Integrator {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "varint" => Ok(Integrator::varint()),
            "midpoint" => Ok(Integrator::midpoint()),
            "rk1" => Ok(Integrator::Rk(RungeKutta::Rk1)),
            "rk2" => Ok(Integrator::Rk(RungeKutta::Rk2)),
            "rk4" => Ok(Integrator::Rk(RungeKutta::Rk4)),
            _ => Err(format!(
                "unknown integrator '{s}' (expected varint, midpoint, rk1, rk2 or rk4)"
            )),
        }
    }
}

impl Integrator {
    /// The default variational integrator: right-point forcing, and the exact Newton
    /// Jacobian carried across steps (refreshed whenever a chord step stalls).
    pub fn varint() -> Self {
        Integrator::VarInt {
            discretisation: Discretisation::FirstOrder,
            quadrature: ForcingQuadrature::Right,
            jacobian: JacobianPolicy::ReuseAcrossSteps,
        }
    }
    /// The symmetric (midpoint) variational integrator: second order, reversible.
    pub fn midpoint() -> Self {
        Integrator::VarInt {
            discretisation: Discretisation::Midpoint,
            quadrature: ForcingQuadrature::Right,
            jacobian: JacobianPolicy::ReuseAcrossSteps,
        }
    }
    pub fn name(&self) -> &'static str {
        match self {
            Integrator::VarInt {
                discretisation: Discretisation::FirstOrder,
                ..
            } => "varint",
            Integrator::VarInt {
                discretisation: Discretisation::Midpoint,
                ..
            } => "midpoint",
            Integrator::Rk(RungeKutta::Rk1) => "rk1",
            Integrator::Rk(RungeKutta::Rk2) => "rk2",
            Integrator::Rk(RungeKutta::Rk4) => "rk4",
        }
    }
}

/// `trajectory.csv`: `t,x,y,theta,alpha,v_alpha,v_d,v_theta,iR,iL,uR,uL`. A non-finite
/// value is an error naming its row and column: a file of NaNs is never a result.
pub fn trajectory_csv(traj: &Trajectory) -> Result<String, String> {
    const COLUMNS: [&str; 12] = [
        "t", "x", "y", "theta", "alpha", "v_alpha", "v_d", "v_theta", "iR", "iL", "uR", "uL",
    ];
    let mut s = COLUMNS.join(",") + "\n";
    for k in 0..traj.t.len() {
        let u = traj.u[k];
        let row = std::iter::once(traj.t[k])
            .chain(traj.x[k].iter().copied())
            .chain(u);
        for (j, v) in row.enumerate() {
            if !v.is_finite() {
                return Err(format!(
                    "the trajectory holds a non-finite value ({v}) at t = {} in column '{}': \
                     nothing written",
                    traj.t[k], COLUMNS[j]
                ));
            }
            if j == 0 {
                let _ = write!(s, "{v}");
            } else {
                let _ = write!(s, ",{v:.17e}");
            }
        }
        s.push('\n');
    }
    Ok(s)
}

/// A simulated trajectory: reduced states and the inputs applied from each node on.
#[derive(Clone, Debug, Default)]
pub struct Trajectory {
    pub t: Vec<f64>,
    pub x: Vec<ReducedState>,
    pub u: Vec<[f64; 2]>,
}

/// Simulate from `x0` for `n_steps` steps of size `h`. Fails (with the time) if a step fails.
///
/// The midpoint scheme's interval velocities `v_k` approximate `v(t_k + h/2)`: it starts
/// from the discrete Legendre transform of `x0` and reports at node `k` the average
/// `(v_{k−1} + v_k)/2`, second-order accurate at `t_k` (the first-order scheme reports `v_k`).
pub fn simulate(
    w: &Wip,
    integrator: Integrator,
    h: f64,
    x0: &ReducedState,
    inputs: &InputSchedule,
    n_steps: usize,
) -> Result<Trajectory, String> {
    let p = w.params;
    let (g0, s0, v0) = from_reduced(&p, x0, [0.0; 4]);
    let uvec = |k: usize| {
        let u = inputs.at(k as f64 * h);
        (u, SVector::<f64, 2>::new(u[0], u[1]))
    };
    // One step k → k+1 of the chosen scheme; the VI also carries its Newton cache and the
    // previous velocity, for the start 2 v_k − v_{k−1}.
    let mut cache = NewtonCache::default();
    let mut v_prev = v0;
    let mut advance = |k: usize, x: &ViState<_, 5>| -> Result<ViState<_, 5>, StepError> {
        let (_, uk) = uvec(k);
        match integrator {
            Integrator::VarInt {
                discretisation,
                quadrature,
                jacobian,
            } => {
                let vi = VariationalIntegrator::new(h)
                    .with_discretisation(discretisation)
                    .with_quadrature(quadrature)
                    .with_jacobian(jacobian);
                let guess = x.v * 2.0 - v_prev;
                v_prev = x.v;
                let (_, unext) = uvec(k + 1);
                Ok(vi.step_cached(w, x, &uk, &unext, &guess, &mut cache)?.0)
            }
            Integrator::Rk(m) => ContinuousModel::step(w, m, h, x, &uk),
        }
    };

    let midpoint = matches!(
        integrator,
        Integrator::VarInt {
            discretisation: Discretisation::Midpoint,
            ..
        }
    );
    let mut x = ViState {
        g: g0,
        s: s0,
        v: v0,
    };
    if midpoint {
        let vi = VariationalIntegrator::new(h).with_discretisation(Discretisation::Midpoint);
        x.v = vi
            .start(w, &s0, &v0, &uvec(0).1)
            .map_err(|e| format!("the midpoint scheme's start failed: {e}"))?;
    }
    let mut traj = Trajectory::default();
    let mut v_before = v0;
    for k in 0..=n_steps {
        traj.t.push(k as f64 * h);
        let v_node = if midpoint && k > 0 {
            (v_before + x.v) * 0.5
        } else if midpoint {
            v0
        } else {
            x.v
        };
        v_before = x.v;
        traj.x.push(to_reduced(&p, &x.g, &x.s, &v_node));
        traj.u.push(uvec(k).0);
        if k == n_steps {
            break;
        }
        x = advance(k, &x).map_err(|e| {
            format!(
                "step {k} (t = {:.4} s) failed: {e}; the motion left the range the step {h} s \
                 resolves (a smaller --step, or smaller voltages)",
                k as f64 * h
            )
        })?;
    }
    Ok(traj)
}

/// Refuse an explicit Runge–Kutta step that the linearised model at the start shows to be
/// beyond the method's stability bound: a damped mode `λ` (Re λ < 0) resolved by less than
/// a step (`|hλ| > 1`) whose stability function `R(hλ) = Σ_{j≤p} (hλ)^j / j!` amplifies
/// it (`|R| > 1`), which is the blow-up explicit methods show on the motor circuit's fast
/// electrical mode. Slow or growing modes are the physics and are left alone. The Jacobian
/// of `(s, v) ↦ (v, v̇)` is taken by central differences (a diagnostic, not a derivative
/// the results depend on).
pub fn check_stability(
    w: &Wip,
    integrator: Integrator,
    h: f64,
    x0: &ReducedState,
    inputs: &InputSchedule,
) -> Result<(), String> {
    let Integrator::Rk(method) = integrator else {
        return Ok(());
    };
    let order = match method {
        RungeKutta::Rk1 => 1,
        RungeKutta::Rk2 => 2,
        RungeKutta::Rk4 => 4,
    };
    let lambdas = shape_modes(w, x0, inputs.at(0.0));
    let amplification = |z: Complex<f64>| {
        let (mut term, mut sum) = (Complex::new(1.0, 0.0), Complex::new(1.0, 0.0));
        for j in 1..=order {
            term = term * z / j as f64;
            sum += term;
        }
        sum.norm()
    };
    let beyond =
        |h: f64, l: &Complex<f64>| l.re < 0.0 && (l * h).norm() > 1.0 && amplification(l * h) > 1.0;
    let Some(worst) = lambdas
        .iter()
        .filter(|l| beyond(h, l))
        .max_by(|a, b| a.norm().total_cmp(&b.norm()))
    else {
        return Ok(());
    };
    // The largest stable step: bisection on h for the modes flagged at this one.
    let (mut lo, mut hi) = (0.0, h);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if lambdas.iter().any(|l| beyond(mid, l)) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Err(format!(
        "{} at a step of {h} s is beyond its stability bound for this model: the mode \
         λ = {:.3e}{:+.3e}i 1/s (time constant {:.2e} s) grows ×{:.3} per step; use --step ≤ {:.3e} \
         or --integrator varint",
        integrator.name(),
        worst.re,
        worst.im,
        -1.0 / worst.re,
        amplification(worst * h),
        lo
    ))
}

/// Eigenvalues of the linearised shape dynamics `(s, v) ↦ (v, v̇)` at a reduced state.
fn shape_modes(w: &Wip, x0: &ReducedState, u: [f64; 2]) -> Vec<Complex<f64>> {
    const NS: usize = super::NS;
    let p = w.params;
    let (g, s, v) = from_reduced(&p, x0, [0.0; 4]);
    let u = SVector::<f64, 2>::new(u[0], u[1]);
    let rhs = |z: &SVector<f64, { 2 * NS }>| -> Option<SVector<f64, { 2 * NS }>> {
        let x = ViState {
            g,
            s: z.fixed_rows::<NS>(0).into_owned(),
            v: z.fixed_rows::<NS>(NS).into_owned(),
        };
        let (_, sdot, a) = ContinuousModel::derivative(w, &x, &u).ok()?;
        let mut out = SVector::<f64, { 2 * NS }>::zeros();
        out.fixed_rows_mut::<NS>(0).copy_from(&sdot);
        out.fixed_rows_mut::<NS>(NS).copy_from(&a);
        Some(out)
    };
    let mut z0 = SVector::<f64, { 2 * NS }>::zeros();
    z0.fixed_rows_mut::<NS>(0).copy_from(&s);
    z0.fixed_rows_mut::<NS>(NS).copy_from(&v);
    let mut jac = nalgebra::SMatrix::<f64, { 2 * NS }, { 2 * NS }>::zeros();
    for j in 0..2 * NS {
        let d = 1e-6 * (1.0 + z0[j].abs());
        let (mut zp, mut zm) = (z0, z0);
        zp[j] += d;
        zm[j] -= d;
        match (rhs(&zp), rhs(&zm)) {
            (Some(fp), Some(fm)) => jac.set_column(j, &((fp - fm) / (2.0 * d))),
            _ => return Vec::new(),
        }
    }
    jac.complex_eigenvalues().iter().copied().collect()
}

//! Tracking a plan in closed loop, for any transcribed robot: the plan's time-varying
//! linearisation by the transcription's exact Jacobians, the finite-horizon LQ gains by the
//! Riccati recursion ([`lq`]), the constrained model predictive control on the same
//! linearisation and weights ([`mpc`]), and a closed-loop run on a plant (the same robot
//! with other parameters, transcribed the same way).
//!
//! A variational transcription's stage decides `w_k = (v_k, u_k)` with the momentum matching
//! `e(x_k, w_k) = 0` fixing `v_k` for given `u_k`. Eliminating it,
//! ```text
//! δx_{k+1} = A_k δx_k + B_k δu_k,   A_k = F_x − F_v E_v⁻¹ E_x,   B_k = F_u − F_v E_v⁻¹ E_u
//! ```
//! at the plan's `(x̄_k, w̄_k)` (`F`, `E` the dynamics' and the equality's Jacobians). The
//! decision's first `NE` components are the eliminated ones, its last `NF` the inputs (the
//! layout of both transcriptions; a Runge–Kutta stage has `NE = 0`). The LQ law is
//! `u_k = ū_k − K_k (x_k − x̄_k)` with
//! `K_k = (R + B_kᵀ P_{k+1} B_k)⁻¹ B_kᵀ P_{k+1} A_k`,
//! `P_k = Q + A_kᵀ P_{k+1} (A_k − B_k K_k)`, `P_N = Q_N`.

pub mod lq;
pub mod mpc;
pub mod nmpc;
pub mod observer;

pub use lq::{lq_design, lq_gains, LqDesign, TrackingWeights};
pub use mpc::{Mpc, MpcError, MpcMove, MpcSettings};
pub use nmpc::{Nmpc, NmpcError, NmpcMemory, NmpcMove, NmpcSettings, SoftRow};
pub use observer::{DelayLaw, Observer, ObserverError, ObserverNoise, PlanView, Readings};

use crate::nlp::StageProblem;
use dmech_lie::linalg::Lu;
use nalgebra::{SMatrix, SVector};

/// The plan's linearisation: `A_k`, `B_k` for `k < N`.
#[derive(Clone, Debug)]
pub struct LinearisedPlan<const NX: usize, const NF: usize> {
    /// `∂x_{k+1}/∂x_k` with the stage equality eliminated.
    pub a: Vec<SMatrix<f64, NX, NX>>,
    /// `∂x_{k+1}/∂u_k` with the stage equality eliminated.
    pub b: Vec<SMatrix<f64, NX, NF>>,
}

/// Why a plan cannot be linearised or tracked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrackingError {
    /// The stage equality's Jacobian in the eliminated decisions is singular at a stage.
    #[error("the stage equality does not determine the eliminated decisions at stage {stage}")]
    SingularEquality {
        /// The stage.
        stage: usize,
    },
    /// The Riccati recursion met a singular `R + BᵀPB`.
    #[error("the LQ recursion is singular at stage {stage}: R + BᵀPB is not invertible")]
    SingularRiccati {
        /// The stage.
        stage: usize,
    },
    /// The plant's step gave a value that is not finite (a state or input not finite, or
    /// a step beyond the model's reach).
    #[error("the plant's step {stage} is not finite")]
    NotFinite {
        /// The stage.
        stage: usize,
    },
    /// The plant's stage equality was not solved (Newton on the eliminated decisions).
    #[error("the plant's step {stage} did not converge (residual {residual:.2e})")]
    PlantStep {
        /// The stage.
        stage: usize,
        /// The residual left.
        residual: f64,
    },
}

/// `A_k`, `B_k` along the plan `(x, w)` of `p` (module documentation).
pub fn linearise_along<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    p: &P,
    x: &[SVector<f64, NX>],
    w: &[SVector<f64, NW>],
) -> Result<LinearisedPlan<NX, NF>, TrackingError>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    let mut a = Vec::with_capacity(w.len());
    let mut b = Vec::with_capacity(w.len());
    for k in 0..w.len() {
        let (_, fx, fw) = p.dynamics_jacobian(k, &x[k], &w[k]);
        let (ex, ew) = p.equality_partials(k, &x[k], &w[k]);
        let fu = fw.fixed_columns::<NF>(NE).into_owned();
        if NE == 0 {
            a.push(fx);
            b.push(fu);
            continue;
        }
        let fv = fw.fixed_columns::<NE>(0).into_owned();
        let ev = ew.fixed_columns::<NE>(0).into_owned();
        let eu = ew.fixed_columns::<NF>(NE).into_owned();
        let lu = Lu::new(&ev).ok_or(TrackingError::SingularEquality { stage: k })?;
        a.push(fx - fv * lu.solve_columns(&ex));
        b.push(fu - fv * lu.solve_columns(&eu));
    }
    Ok(LinearisedPlan { a, b })
}

/// One step of `plant` from `x` with input `u`: the eliminated decisions by Newton on the
/// stage equality from `guess` (to `1e-12` relative), then the dynamics. Returns `x_{k+1}`
/// and the decision, or an error if either is not finite.
pub fn plant_step<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    plant: &P,
    k: usize,
    x: &SVector<f64, NX>,
    u: &SVector<f64, NF>,
    guess: &SVector<f64, NE>,
) -> Result<(SVector<f64, NX>, SVector<f64, NW>), TrackingError>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    let decision = |v: &SVector<f64, NE>| {
        SVector::<f64, NW>::from_fn(|i, _| if i < NE { v[i] } else { u[i - NE] })
    };
    let mut v = *guess;
    let mut residual = 0.0;
    for _ in 0..50 {
        if NE == 0 {
            break;
        }
        let (e, _, ew) = plant.equality_jacobian(k, x, &decision(&v));
        residual = e.amax();
        if residual <= 1e-12 * (1.0 + v.amax()) {
            break;
        }
        let ev = ew.fixed_columns::<NE>(0).into_owned();
        let lu = Lu::new(&ev).ok_or(TrackingError::SingularEquality { stage: k })?;
        v -= lu.solve(&e);
    }
    if NE > 0 && residual > 1e-9 * (1.0 + v.amax()) {
        return Err(TrackingError::PlantStep { stage: k, residual });
    }
    let w = decision(&v);
    let next = plant.dynamics(k, x, &w);
    if !next.iter().chain(w.iter()).all(|z| z.is_finite()) {
        return Err(TrackingError::NotFinite { stage: k });
    }
    Ok((next, w))
}

/// A closed-loop run of `plant` from `x0` along the plan `(x̄, w̄)` with the gains `K_k`
/// (`u_k = ū_k − K_k (x_k − x̄_k)`; no gains: the plan's inputs open loop). Returns the
/// states `x_0 … x_N`.
pub fn track<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    plant: &P,
    x0: &SVector<f64, NX>,
    plan_x: &[SVector<f64, NX>],
    plan_w: &[SVector<f64, NW>],
    gains: Option<&[SMatrix<f64, NF, NX>]>,
) -> Result<Vec<SVector<f64, NX>>, TrackingError>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    track_by(plant, x0, plan_w, |k, x| {
        let u_plan = plan_w[k].fixed_rows::<NF>(NE).into_owned();
        match gains {
            Some(g) => u_plan - g[k] * (x - plan_x[k]),
            None => u_plan,
        }
    })
}

/// A closed-loop run of `plant` from `x0` over the plan's stages, the input at stage `k`
/// `control(k, x_k)` (e.g. [`Mpc::input`]); the plan's decisions `w̄` start the plant's
/// Newton on its eliminated decisions. Returns the states `x_0 … x_N`.
pub fn track_by<
    P,
    F,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    plant: &P,
    x0: &SVector<f64, NX>,
    plan_w: &[SVector<f64, NW>],
    mut control: F,
) -> Result<Vec<SVector<f64, NX>>, TrackingError>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
    F: FnMut(usize, &SVector<f64, NX>) -> SVector<f64, NF>,
{
    let mut xs = vec![*x0];
    for k in 0..plan_w.len() {
        let x = xs[k];
        let u = control(k, &x);
        let guess = plan_w[k].fixed_rows::<NE>(0).into_owned();
        let (next, _) = plant_step::<P, NX, NW, NE, NF, NC>(plant, k, &x, &u, &guess)?;
        xs.push(next);
    }
    Ok(xs)
}

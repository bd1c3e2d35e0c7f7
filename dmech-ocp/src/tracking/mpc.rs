//! Constrained model predictive control along a linearised plan: at every sample a QP over
//! the next `H` stages of the plan's linearisation with the LQ tracker's weights and hard
//! input bounds, solved by [`crate::qp`].
//!
//! At sample `k`, with `H_k = min(H, N − k)` stages and `δx_0 = x_k − x̄_k` the measured
//! deviation from the plan,
//! ```text
//! min  Σ_{j<H_k} (δx_jᵀ Q δx_j + δu_jᵀ R δu_j) + δx_{H_k}ᵀ P_{k+H_k} δx_{H_k}
//! s.t. δx_{j+1} = A_{k+j} δx_j + B_{k+j} δu_j,
//!      lo − ū_{k+j} ≤ δu_j ≤ hi − ū_{k+j}        (hard)
//! ```
//! and the input applied is `ū_k + δu_0`. `P` is the LQ design's cost-to-go
//! ([`super::lq_design`], `P_N = Q_N`), so that where no bound is active the recursion over
//! the horizon from `P_{k+H_k}` is the LQ tracker's own and the first move is its
//! `−K_k δx_0`: the MPC differs from the LQ tracker exactly where the LQ move would leave
//! the bounds. Near the plan's end the horizon shrinks to the stages left.
//!
//! The QP (`StageQp<NX, NF, NF>`: one box row per input) has the objective above
//! (its Hessian blocks `2Q`, `2R`, `2P`); it starts cold at each sample. When it is not
//! solved (any [`QpStatus`] but `Solved`, or data the QP refuses) the move is the LQ
//! tracker's, clamped to the bounds, and [`MpcMove::status`] says so.

use super::lq::{lq_design, LqDesign, TrackingWeights};
use super::{LinearisedPlan, TrackingError};
use crate::qp::{QpError, QpSettings, QpSolver, QpStatus, Stage, StageQp, Terminal};
use nalgebra::SVector;

/// The MPC's QP at one sample: `NX` deviation states, `NF` input deviations, one box row
/// per input.
pub type MpcQp<const NX: usize, const NF: usize> = StageQp<NX, NF, NF>;

/// The MPC's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct MpcSettings<const NF: usize> {
    /// Stages in the horizon, `H ≥ 1`.
    pub horizon: usize,
    /// The inputs' lower bounds `lo` (absolute, `−∞` for none).
    pub lower: SVector<f64, NF>,
    /// The inputs' upper bounds `hi` (absolute, `+∞` for none).
    pub upper: SVector<f64, NF>,
    /// The QP solver's settings.
    pub qp: QpSettings,
}

/// Why an MPC could not be built or asked for a move.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MpcError {
    /// The LQ design beneath it failed.
    #[error("the LQ design failed: {0}")]
    Lq(#[from] TrackingError),
    /// The plan's inputs do not match its stages.
    #[error("{inputs} plan inputs for {stages} linearised stages")]
    InputCount {
        /// Inputs given.
        inputs: usize,
        /// Stages of the linearisation.
        stages: usize,
    },
    /// A horizon of no stage.
    #[error("the horizon must have at least one stage")]
    EmptyHorizon,
    /// A bound is NaN, or `lo > hi`.
    #[error("input {input}: the bounds [{lower}, {upper}] are empty")]
    EmptyBounds {
        /// The input.
        input: usize,
        /// Its lower bound.
        lower: f64,
        /// Its upper bound.
        upper: f64,
    },
    /// A move was asked for at or past the plan's last stage.
    #[error("sample {sample} is past the plan's {stages} stages")]
    PastThePlan {
        /// The sample asked for.
        sample: usize,
        /// The plan's stages.
        stages: usize,
    },
}

/// One sample's move.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MpcMove<const NF: usize> {
    /// The input to apply, `ū_k + δu_0` (or the clamped LQ move).
    pub input: SVector<f64, NF>,
    /// The QP's status; `None` where the QP refused its data ([`QpError`]). Anything but
    /// `Some(QpStatus::Solved)` means the input is the LQ fallback.
    pub status: Option<QpStatus>,
    /// The QP's interior-point iterations (0 if refused).
    pub iterations: usize,
    /// The calling thread's CPU time for building and solving the QP, s: the compute the
    /// sample needs, without what a shared machine gives to other work.
    pub cpu_s: f64,
}

impl<const NF: usize> MpcMove<NF> {
    /// Whether the QP was solved (else the move is the LQ fallback).
    pub fn solved(&self) -> bool {
        self.status == Some(QpStatus::Solved)
    }
}

/// The MPC along one plan (module documentation), with its QP solver's buffers.
#[derive(Clone, Debug)]
pub struct Mpc<const NX: usize, const NF: usize> {
    plan: LinearisedPlan<NX, NF>,
    inputs: Vec<SVector<f64, NF>>,
    weights: TrackingWeights<NX, NF>,
    lq: LqDesign<NX, NF>,
    horizon: usize,
    lower: SVector<f64, NF>,
    upper: SVector<f64, NF>,
    solver: QpSolver<NX, NF, NF>,
}

impl<const NX: usize, const NF: usize> Mpc<NX, NF> {
    /// The MPC along the linearised `plan` whose inputs are `inputs` (`ū_k`, `k < N`), with
    /// the tracking `weights` (the LQ design's) and `settings`.
    pub fn new(
        plan: LinearisedPlan<NX, NF>,
        inputs: Vec<SVector<f64, NF>>,
        weights: &TrackingWeights<NX, NF>,
        settings: MpcSettings<NF>,
    ) -> Result<Self, MpcError> {
        let stages = plan.a.len();
        if inputs.len() != stages || plan.b.len() != stages {
            return Err(MpcError::InputCount {
                inputs: inputs.len(),
                stages,
            });
        }
        if settings.horizon == 0 {
            return Err(MpcError::EmptyHorizon);
        }
        for i in 0..NF {
            let (lower, upper) = (settings.lower[i], settings.upper[i]);
            if lower.is_nan()
                || upper.is_nan()
                || lower > upper
                || lower == f64::INFINITY
                || upper == f64::NEG_INFINITY
            {
                return Err(MpcError::EmptyBounds {
                    input: i,
                    lower,
                    upper,
                });
            }
        }
        let lq = lq_design(&plan, weights)?;
        Ok(Mpc {
            plan,
            inputs,
            weights: weights.clone(),
            lq,
            horizon: settings.horizon,
            lower: settings.lower,
            upper: settings.upper,
            solver: QpSolver::new(settings.qp),
        })
    }

    /// The LQ design beneath (gains and cost-to-go).
    pub fn lq(&self) -> &LqDesign<NX, NF> {
        &self.lq
    }

    /// The plan's stages `N`.
    pub fn stages(&self) -> usize {
        self.inputs.len()
    }

    /// The move at sample `k < N` for the state deviation `dx = x_k − x̄_k`.
    pub fn input(&mut self, k: usize, dx: &SVector<f64, NX>) -> Result<MpcMove<NF>, MpcError> {
        self.check_sample(k)?;
        let cpu = thread_cpu_seconds();
        let (status, iterations, du) = match self.stage_qp(k, dx) {
            Ok(qp) => {
                let sol = self.solver.solve(&qp);
                (Some(sol.status), sol.info.iterations, sol.u[0])
            }
            Err(_) => (None, 0, SVector::zeros()),
        };
        let input = match status {
            Some(QpStatus::Solved) => self.inputs[k] + du,
            _ => self.lq_input(k, dx)?,
        };
        Ok(MpcMove {
            input,
            status,
            iterations,
            cpu_s: thread_cpu_seconds() - cpu,
        })
    }

    /// The LQ tracker's move at sample `k`, `ū_k − K_k dx`, clamped to the bounds: the
    /// fallback.
    pub fn lq_input(&self, k: usize, dx: &SVector<f64, NX>) -> Result<SVector<f64, NF>, MpcError> {
        self.check_sample(k)?;
        let u = self.inputs[k] - self.lq.gains[k] * dx;
        // A comparison, not `max`/`min`: a NaN stays NaN (and the plant's step refuses it).
        let clamp = |v: f64, lo: f64, hi: f64| match v {
            v if v < lo => lo,
            v if v > hi => hi,
            v => v,
        };
        Ok(SVector::from_fn(|i, _| {
            clamp(u[i], self.lower[i], self.upper[i])
        }))
    }

    /// The QP at sample `k < N` for the deviation `dx` (module documentation).
    pub fn stage_qp(&self, k: usize, dx: &SVector<f64, NX>) -> Result<MpcQp<NX, NF>, QpError> {
        let n = self.stages();
        let h = self.horizon.min(n.saturating_sub(k));
        let stages = (0..h)
            .map(|j| {
                let mut st = Stage::<NX, NF, NF>::zeros();
                st.a = self.plan.a[k + j];
                st.b = self.plan.b[k + j];
                if j > 0 {
                    st.q = self.weights.state * 2.0;
                }
                st.r = self.weights.input * 2.0;
                let u = &self.inputs[k + j];
                for i in 0..NF {
                    st.rows
                        .input_bound(i, i, self.lower[i] - u[i], self.upper[i] - u[i]);
                }
                st
            })
            .collect();
        let mut terminal = Terminal::<NX, NF, NF>::zeros();
        terminal.q = self.lq.cost_to_go[k + h] * 2.0;
        StageQp::new(*dx, stages, terminal)
    }

    fn check_sample(&self, k: usize) -> Result<(), MpcError> {
        match k < self.stages() {
            true => Ok(()),
            false => Err(MpcError::PastThePlan {
                sample: k,
                stages: self.stages(),
            }),
        }
    }
}

/// The calling thread's CPU time in seconds (`CLOCK_THREAD_CPUTIME_ID`); NaN if the clock
/// is not available.
pub fn thread_cpu_seconds() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; the call only writes it.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    if rc != 0 {
        return f64::NAN;
    }
    ts.tv_sec as f64 + 1e-9 * ts.tv_nsec as f64
}

//! The nonlinear MPC of the WIP (`--controller nmpc`): [`dmech_ocp::tracking::nmpc`] on the
//! plan's own transcription, the first-order variational integrator of the full model
//! (currents as states, the nonlinear friction) at the 5-ms sample, with the plan's
//! inequalities (voltage ±5 V, current ±3 A, tilt ±15° hard; the voltage rate soft; the
//! heading rate free), its first state the observer's estimate.
//!
//! The state is the transcription's, `x = (x, y, θ, α, v_α, φ̇R, φ̇L, iR, iL, u_prev)` (the
//! velocities those of the interval before the sample). The weights are the LQ design's
//! `Q_Y` and `R = I` carried over to it: 1500 on each of `x` and `y` (the distance
//! weight, which the nonlinear model can also spend on the lateral offset the linear
//! design hands to the guidance), 350 on `θ`, 0.1 on `α`, 1 on `v_θ = r (φ̇R − φ̇L)/(2d)`;
//! the terminal weight is the cost-to-go of the LQ tracker along the plan's own
//! linearisation with those weights. The voltage rate's rows are held by a quadratic
//! penalty on their excess weighed like the input (`R = 1` per V² of excess per sample):
//! a closed loop under the sensor noise changes its voltage by far more than the plan's
//! 0.01 V per sample (docs/tracking.md, "Why the rate bound is soft"). The heading rate's
//! 120°/s is the plan's choice, not a limit of the robot: held in the loop, it made the
//! NMPC hold one wheel back at the voltage bound on a mismatched plant, and the robot fall
//! (docs/tracking.md, "NMPC").
//!
//! When a sample's solve fails or runs out of its budget, the move is the LQ controller's
//! (counted as the MPC's `qp_fallbacks` are).

use super::closed_loop::Reference;
use super::dare::DareError;
use super::lq::{LqController, Q_Y, SAMPLE};
use super::observer::Estimate;
use crate::wip::plan::problems::PlanProblem;
use crate::wip::plan::{varint_plan, PlanBounds, VarIntPlan, NC, NX_VI};
use crate::wip::simulate::Trajectory;
use crate::wip::state::wheel_rates;
use crate::wip::{Wip, WipParams, NS, NU};
use dmech::Discretisation;
use dmech_ocp::solver::Curvature;
use dmech_ocp::tracking::nmpc::{
    stationary_cost_to_go, Nmpc, NmpcError, NmpcMemory, NmpcSettings, SoftRow,
};
use dmech_ocp::tracking::TrackingWeights;
use nalgebra::{SMatrix, SVector};
use std::sync::Mutex;
use std::thread::ThreadId;

/// The transcription's decision size, `(v_k, u_k)`.
pub const NW: usize = NS + NU;
/// The inequality rows of the voltage rate (`docs/problems.md`), held softly.
pub const RATE_ROWS: [usize; 2] = [2, 3];
/// The inequality row of the heading rate, left free (a soft row of no weight).
pub const HEADING_RATE_ROW: usize = 7;
/// Riccati steps at most for the cost-to-go at the plan's end (a minute of samples).
const END_STEPS: usize = 12_000;
/// Where the state's velocities start (after the pose and the tilt).
const V_AT: usize = 4;
/// Samples in the horizon by default (`--horizon`).
pub const HORIZON: usize = 10;
/// Newton steps per sample by default (`--newton-steps`).
pub const NEWTON_STEPS: usize = 2;
/// The barrier parameter of the real-time iteration, held: the solver's tolerance is ten
/// times it, so that its barrier rule never lowers it (IPOPT's floor `tol/10`) and each
/// sample's steps follow the one barrier problem's solution along the plan. Measured on
/// the eight, seed 1, two steps per sample: position error max 3.57 mm at 1e-3, 4.39 mm
/// at 1e-4 (its tolerance 1e-8, the barrier lowered within a sample), 4.70 mm at 1e-6.
pub const BARRIER: f64 = 1e-3;
/// The wall-clock budget of a sample's solve by default: none, so that a run's moves do
/// not depend on the machine's load (the Newton steps bound the compute; `--budget` sets
/// one for a controller on its own core).
pub const BUDGET_S: f64 = f64::INFINITY;

/// `wip track --controller nmpc`'s options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NmpcOptions {
    /// Samples in the horizon.
    pub horizon: usize,
    /// Newton steps per sample.
    pub newton_steps: usize,
    /// The wall-clock budget of a sample's solve (s).
    pub budget_s: f64,
}

impl Default for NmpcOptions {
    fn default() -> Self {
        NmpcOptions {
            horizon: HORIZON,
            newton_steps: NEWTON_STEPS,
            budget_s: BUDGET_S,
        }
    }
}

/// What one NMPC sample did.
#[derive(Clone, Copy, Debug)]
pub struct NmpcStep {
    /// The feedback voltages (the NMPC's input less the feedforward, or the LQ's).
    pub u_fb: [f64; 2],
    /// The sample's compute as the thread's CPU time (s).
    pub solve_s: f64,
    /// The same as wall-clock time (s).
    pub solve_wall_s: f64,
    /// `false` when the LQ move was applied instead.
    pub solved: bool,
}

/// Why the NMPC could not be designed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NmpcDesignError {
    /// The LQ fallback's design failed.
    #[error("the LQ design failed: {0}")]
    Lq(DareError),
    /// The NMPC along the plan could not be set up.
    #[error("the NMPC along the plan: {0}")]
    Nmpc(#[from] NmpcError),
    /// The LQ recursion at the plan's held end does not settle.
    #[error("the LQ tracker's cost-to-go at the plan's end does not settle")]
    End,
    /// A plan of fewer than two samples.
    #[error("the plan is shorter than two samples")]
    ShortPlan,
}

/// One thread's real-time iteration memory.
#[derive(Debug)]
struct Workspace {
    thread: ThreadId,
    memory: NmpcMemory<NX_VI, NW, NC>,
}

/// The NMPC along one plan (module documentation). Each thread that calls
/// [`NmpcController::feedback`] keeps its own last iterate; a run starts cold at its
/// first sample.
#[derive(Debug)]
pub struct NmpcController {
    pub lq: LqController,
    model: Wip,
    problem: PlanProblem,
    nmpc: Nmpc<NX_VI, NW, NU>,
    workspaces: Mutex<Vec<Workspace>>,
}

impl Clone for NmpcController {
    /// The same controller with no iterate kept.
    fn clone(&self) -> Self {
        NmpcController {
            lq: self.lq.clone(),
            model: self.model,
            problem: self.problem.clone(),
            nmpc: self.nmpc.clone(),
            workspaces: Mutex::new(Vec::new()),
        }
    }
}

/// The state weight on the transcription's state (module documentation).
pub fn state_weight(p: &WipParams) -> SMatrix<f64, NX_VI, NX_VI> {
    let mut q = SMatrix::<f64, NX_VI, NX_VI>::zeros();
    q[(0, 0)] = Q_Y[0];
    q[(1, 1)] = Q_Y[0];
    q[(2, 2)] = Q_Y[1];
    q[(3, 3)] = Q_Y[2];
    q[(4, 4)] = Q_Y[3];
    // v_θ = g·(φ̇R, φ̇L), g = r/(2d) (1, −1): weight Q_Y[5] g gᵀ on the wheel rates.
    let g = p.r / (2.0 * p.d);
    for (r, sr) in [(5, 1.0), (6, -1.0)] {
        for (c, sc) in [(5, 1.0), (6, -1.0)] {
            q[(r, c)] = Q_Y[5] * g * g * sr * sc;
        }
    }
    q
}

/// The transcription's state of a reduced state's pose and tilt, the interval velocity
/// `v` (reduced: `v_α, v_d, v_θ, iR, iL` at indices 4…8 of `before`) and the previous
/// voltages.
fn state_of(
    p: &WipParams,
    at: &crate::wip::ReducedState,
    before: &crate::wip::ReducedState,
    u_prev: [f64; 2],
) -> SVector<f64, NX_VI> {
    let (vr, vl) = wheel_rates(p, before[5], before[6]);
    SVector::from_column_slice(&[
        at[0], at[1], at[2], at[3], before[4], vr, vl, before[7], before[8], u_prev[0], u_prev[1],
    ])
}

impl NmpcController {
    /// The NMPC along `plan` for the nominal robot `p`: the plan sampled every 5 ms as the
    /// transcription's states and decisions, the LQ tracker along its linearisation.
    pub fn design(
        p: &WipParams,
        plan: &Trajectory,
        options: NmpcOptions,
    ) -> Result<Self, NmpcDesignError> {
        let lq = LqController::design(p).map_err(NmpcDesignError::Lq)?;
        let model = Wip::new(*p);
        let reference = Reference { plan };
        let n = (reference.end() / SAMPLE).round() as usize;
        if n < 2 {
            return Err(NmpcDesignError::ShortPlan);
        }
        let samples: Vec<_> = (0..=n).map(|k| reference.at(k as f64 * SAMPLE)).collect();
        let x: Vec<SVector<f64, NX_VI>> = (0..=n)
            .map(|k| match k {
                0 => state_of(p, &samples[0].0, &samples[0].0, [0.0; 2]),
                _ => state_of(p, &samples[k].0, &samples[k - 1].0, samples[k - 1].1),
            })
            .collect();
        let w: Vec<SVector<f64, NW>> = samples[..n]
            .iter()
            .map(|(xr, u)| {
                let (vr, vl) = wheel_rates(p, xr[5], xr[6]);
                SVector::from_column_slice(&[xr[4], vr, vl, xr[7], xr[8], u[0], u[1]])
            })
            .collect();
        let end = plan.x.last().expect("a plan has rows");
        let problem = PlanProblem {
            name: "track".into(),
            h: SAMPLE,
            n,
            points: vec![[plan.x[0][0], plan.x[0][1]], [end[0], end[1]]],
            stages: vec![0, n],
            start_heading: plan.x[0][2],
            end_heading: end[2],
        };
        let q = state_weight(p);
        let mut weights = TrackingWeights {
            state: q,
            terminal: q,
            input: SMatrix::identity(),
        };
        let settings = NmpcSettings {
            horizon: options.horizon,
            newton_steps: options.newton_steps,
            barrier: BARRIER,
            tol: 10.0 * BARRIER,
            budget_s: options.budget_s,
            curvature: Curvature::GaussNewton,
            soft: RATE_ROWS
                .iter()
                .map(|&row| SoftRow {
                    row,
                    // The rows are rates (V/s): an excess of δ V per sample is δ/h of it.
                    weight: SAMPLE * SAMPLE,
                })
                .chain([SoftRow {
                    row: HEADING_RATE_ROW,
                    weight: 0.0,
                }])
                .collect(),
        };
        let nmpc = {
            let tr = transcription(&model, &problem);
            // The plan ends at rest and the horizons past its end hold it there: the LQ
            // design's terminal weight is the cost-to-go of holding it for ever.
            // At rest the lateral offset cannot be steered: that cost-to-go weighs the
            // distance along the end heading alone.
            let (c, s) = (end[2].cos(), end[2].sin());
            let mut at_rest = weights.clone();
            at_rest.state[(0, 0)] = Q_Y[0] * c * c;
            at_rest.state[(0, 1)] = Q_Y[0] * c * s;
            at_rest.state[(1, 0)] = Q_Y[0] * c * s;
            at_rest.state[(1, 1)] = Q_Y[0] * s * s;
            at_rest.terminal = at_rest.state;
            weights.terminal = stationary_cost_to_go(&tr, &x[n], &w[n - 1], &at_rest, END_STEPS)
                .ok_or(NmpcDesignError::End)?;
            Nmpc::new(&tr, x, w, &weights, settings)?
        };
        Ok(NmpcController {
            lq,
            model,
            problem,
            nmpc,
            workspaces: Mutex::new(Vec::new()),
        })
    }

    /// The NMPC beneath.
    pub fn nmpc(&self) -> &Nmpc<NX_VI, NW, NU> {
        &self.nmpc
    }

    /// The feedback at sample `k` from the estimate `est` (`e` its LQ error state, for the
    /// fallback), `u_ff` the plan's voltage there and `u_prev` the voltage applied last.
    pub fn feedback(
        &self,
        k: usize,
        est: &Estimate,
        e: &SVector<f64, 8>,
        u_ff: [f64; 2],
        u_prev: [f64; 2],
    ) -> NmpcStep {
        let p = &self.model.params;
        let (vr, vl) = wheel_rates(p, est.v_d, est.v_theta);
        let x0 = SVector::<f64, NX_VI>::from_column_slice(&[
            est.pose[0],
            est.pose[1],
            est.pose[2],
            est.alpha,
            est.v_alpha,
            vr,
            vl,
            est.i[0],
            est.i[1],
            u_prev[0],
            u_prev[1],
        ]);
        let k = k.min(self.nmpc.stages() - 1);
        // The estimate's velocities are the robot's at the sample; the state's are those of
        // the interval before it, which the plan's differ from by half the plan's change
        // over the sample (the first-order scheme's velocity at a node is the mean of the
        // intervals' on either side, to first order in h).
        let (before, after) = (
            self.nmpc.reference_state(k),
            self.nmpc.reference_decision(k),
        );
        let mut x0 = x0;
        for i in 0..NS {
            x0[V_AT + i] -= 0.5 * (after[i] - before[V_AT + i]);
        }
        let mut ws = self.workspace();
        let tr = transcription(&self.model, &self.problem);
        let step = self.nmpc.step(&tr, k, &x0, &mut ws.memory);
        self.workspaces
            .lock()
            .expect("no panics while held")
            .push(ws);
        match step {
            Ok(m) => {
                let solved = m.input.is_some();
                let u_fb = m
                    .input
                    .map_or_else(|| self.lq.feedback(e), |u| [u[0] - u_ff[0], u[1] - u_ff[1]]);
                NmpcStep {
                    u_fb,
                    solve_s: m.cpu_s,
                    solve_wall_s: m.wall_s,
                    solved,
                }
            }
            Err(_) => NmpcStep {
                u_fb: self.lq.feedback(e),
                solve_s: 0.0,
                solve_wall_s: 0.0,
                solved: false,
            },
        }
    }

    /// The calling thread's workspace, taken out of the pool (a new one for a new thread).
    fn workspace(&self) -> Workspace {
        let thread = std::thread::current().id();
        let mut pool = self.workspaces.lock().expect("no panics while held");
        match pool.iter().position(|w| w.thread == thread) {
            Some(i) => pool.swap_remove(i),
            None => Workspace {
                thread,
                memory: NmpcMemory::default(),
            },
        }
    }
}

/// The plan's transcription: the first-order VI of the full model at the sample, the
/// plan's bounds at the 5-V supply.
fn transcription<'a>(
    model: &'a Wip,
    problem: &'a PlanProblem,
) -> VarIntPlan<'a, Wip, NS, NX_VI, NW> {
    varint_plan::<Wip, NS, NX_VI, NW>(
        model,
        problem,
        PlanBounds::default(),
        Discretisation::FirstOrder,
    )
}

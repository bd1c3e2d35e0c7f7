//! The constrained alternative to the LQ controller: a QP per 5-ms sample over a horizon of
//! `N_p` samples along the plan, on the linear time-varying error model, solved by the
//! stage-structured interior point `dmech_ocp::qp`, from a cold start each sample (the
//! warm start from the previous sample's solution took more iterations on these QPs:
//! docs/tracking.md, "MPC").
//!
//! Stage `j` of the QP has the state `x_j = (e_j, p_j)`: the error state and the feedback
//! voltage of the stage before (`p_0` the voltage applied last), so that the rate rows
//! are stage-local; its input is `δu_j`; its soft rows' violations are eliminated inside
//! the stage by the solver. Cost `Σ_{j<Np} (e_jᵀ Q_Y e_j + δu_jᵀ δu_j) + e_Npᵀ P e_Np + ρ Σ σ` with `P` the
//! DARE's solution at upright rest, so that with no constraint active at upright rest the
//! first move is the LQ controller's `−K e_0`. Constraints: `e_{j+1} = Φ_j e_j + Γ_j δu_j`
//! (the model linearised at the plan's sample `k + j` and discretised exactly); the voltage
//! `|u_ff + δu| ≤ 5 V` hard; the rate `|u_j − u_{j−1}| ≤ 2 V/s · h` (`u_{−1}` the voltage
//! applied last) and the tilt `|α_ref + e[α]| ≤ 15°` softened by slacks `σ` with weights
//! `ρ`: under the paper's sensor noise the LQ loop changes its voltage by 0.56 V per sample
//! (median over the eight; 99 % of the samples above the bound's 0.01 V), so a hard rate
//! bound would leave the robot without balance authority. The rate slack's weight is therefore a trade-off
//! (`RATE_WEIGHT`), the tilt slack's an exact penalty (`TILT_WEIGHT`).

use super::closed_loop::{Reference, U_MAX};
use super::dare::DareError;
use super::linear::{linear_model_params, linearise_at, zoh, NIN, NZ};
use super::lq::{LqController, Q_Y, SAMPLE};
use crate::wip::simulate::Trajectory;
use crate::wip::{Wip, WipParams};
use dmech_ocp::qp::{QpError, QpSettings, QpSolver, QpStatus, SoftPrice, Stage, StageQp, Terminal};
use dmech_ocp::tracking::mpc::thread_cpu_seconds;
use nalgebra::{SMatrix, SVector};
use std::sync::Mutex;
use std::thread::ThreadId;

/// Samples in the horizon (50 ms; the terminal cost carries the rest). Measured on the
/// eight (one run, 4237 QPs): 10 samples 1.18 ms median / 1.89 ms worst per QP, position
/// error max 1.25 mm; 20: 2.52 / 6.57 ms, 1.22 mm; 40: 5.77 / 11.0 ms, 1.35 mm.
pub const HORIZON: usize = 10;
/// The voltage rate bound per sample: 2 V/s times the 5-ms sample.
pub const DU_MAX: f64 = 2.0 * SAMPLE;
/// The tilt bound of the plan (rad).
pub const TILT_MAX: f64 = 15.0 * std::f64::consts::PI / 180.0;
/// Exact-penalty weight on the tilt slack (per rad): above the multipliers the bound takes
/// when it can be met, so that the slack stays zero whenever that is possible.
pub const TILT_WEIGHT: f64 = 1e4;
/// L1 weight on the rate slack (per V of excess per sample): a trade-off, not an exact
/// penalty (docs/tracking.md: at 1e4 the rate bound holds and the robot falls within 1 s).
pub const RATE_WEIGHT: f64 = 1.0;
/// The QP's stage state: the error state and the previous feedback voltage.
pub const QP_NX: usize = NZ + NIN;
/// The QP's rows per stage: voltage (right, left), rate (right, left), tilt.
pub const QP_NC: usize = 5;
/// The MPC's QP at one sample.
pub type MpcQp = StageQp<QP_NX, NIN, QP_NC>;
/// The interior point's tolerance: the gap within 1e-6 of the objective. What the loop
/// uses of a solution is its first move, and that needs no more accuracy than a motor
/// driver can apply: on the QPs of the eight (4236 of them, seed 1) the move is within
/// 0.9 mV of the solution at 1e-12 (1.3e-4 V at 1e-8, 1.9e-3 V at 1e-5), below a 12-bit
/// PWM's step over ±5 V (2.4 mV) and 0.2 % of the 0.56 V by which the sensor noise moves
/// the voltage per sample; the iterations fall from 7.46 to 6.52 on average (docs/qp.md).
const QP_TOL: f64 = 1e-6;
/// The complementarity the interior point's cold start is centred at
/// ([`QpSettings::start_mu`]): these QPs' bounds are small (a rate bound of 0.01 V per
/// sample); on 530 QPs of the 4.4-V eight for each of seeds 1–3, 7.4–7.5 iterations on
/// average (at most 10) against 8.7–8.8 (at most 11) at the default 10 (docs/qp.md).
pub const QP_START_MU: f64 = 0.1;

/// The interior point's settings for the MPC's QPs.
pub fn qp_settings() -> QpSettings {
    QpSettings::builder()
        .tol(QP_TOL)
        .start_mu(QP_START_MU)
        .build()
        .expect("valid settings")
}

/// The linear error model at one sample and the plan's values there.
#[derive(Clone, Debug)]
struct PlanSample {
    phi: SMatrix<f64, NZ, NZ>,
    gamma: SMatrix<f64, NZ, NIN>,
    alpha_ref: f64,
    u_ff: [f64; 2],
}

/// What one MPC step did.
#[derive(Clone, Copy, Debug)]
pub struct MpcMove {
    /// The feedback voltages `δu_0`.
    pub u_fb: [f64; 2],
    /// The QP's solve time (s, set-up included) as the calling thread's CPU time: the
    /// compute the sample needs, without the time a shared machine gives to other work.
    pub solve_s: f64,
    /// The same as wall-clock time.
    pub solve_wall_s: f64,
    /// `false` when the QP was not solved (the LQ move was used).
    pub solved: bool,
}

/// The arguments of one [`MpcController::feedback`] call, from which
/// [`MpcController::stage_qp`] builds its QP again.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MpcSample {
    /// The sample.
    pub k: usize,
    /// The error state.
    pub e0: SVector<f64, NZ>,
    /// The voltage applied at the sample before.
    pub u_prev: [f64; 2],
}

/// One thread's solver (its buffers reused from sample to sample).
#[derive(Debug)]
struct Workspace {
    thread: ThreadId,
    solver: QpSolver<QP_NX, NIN, QP_NC>,
}

/// The MPC along one plan: the linear time-varying model at every sample, precomputed.
///
/// Each thread that calls [`MpcController::feedback`] gets its own solver, whose buffers
/// it reuses; every QP starts cold, so a run's results depend on its own samples alone.
#[derive(Debug)]
pub struct MpcController {
    pub lq: LqController,
    samples: Vec<PlanSample>,
    settings: QpSettings,
    workspaces: Mutex<Vec<Workspace>>,
    /// The calls' arguments, when recording ([`MpcController::recording`]).
    record: Option<Mutex<Vec<MpcSample>>>,
}

impl Clone for MpcController {
    /// The same controller with no solver state and no record.
    fn clone(&self) -> Self {
        MpcController {
            lq: self.lq.clone(),
            samples: self.samples.clone(),
            settings: self.settings.clone(),
            workspaces: Mutex::new(Vec::new()),
            record: None,
        }
    }
}

/// Why an MPC could not be designed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MpcDesignError {
    /// The LQ design beneath it failed.
    #[error("the LQ design failed: {0}")]
    Lq(DareError),
    /// The linearisation at a sample of the plan is singular.
    #[error("the model is singular at t = {t:.3} s")]
    Singular {
        /// The sample's time.
        t: f64,
    },
}

impl MpcController {
    /// Linearise the model with the parameters `p` (the linear model's friction, as for
    /// the LQ design) at each 5-ms sample of `plan` and discretise it.
    pub fn design(p: &WipParams, plan: &Trajectory) -> Result<Self, MpcDesignError> {
        let lq = LqController::design(p).map_err(MpcDesignError::Lq)?;
        let wip = Wip::new(linear_model_params(p));
        let reference = Reference { plan };
        let n = (reference.end() / SAMPLE).round() as usize;
        let samples = (0..=n)
            .map(|k| {
                let (x, u_ff) = reference.at(k as f64 * SAMPLE);
                let z = SVector::<f64, NZ>::from_column_slice(&[
                    0.0, 0.0, x[3], x[4], x[5], x[6], x[7], x[8],
                ]);
                let u = SVector::<f64, NIN>::new(u_ff[0], u_ff[1]);
                let (a, b) = linearise_at(&wip, &z, &u).ok_or(MpcDesignError::Singular {
                    t: k as f64 * SAMPLE,
                })?;
                let (phi, gamma) = zoh(&a, &b, SAMPLE);
                Ok(PlanSample {
                    phi,
                    gamma,
                    alpha_ref: x[3],
                    u_ff,
                })
            })
            .collect::<Result<Vec<_>, MpcDesignError>>()?;
        let settings = qp_settings();
        Ok(MpcController {
            lq,
            samples,
            settings,
            workspaces: Mutex::new(Vec::new()),
            record: None,
        })
    }

    /// The controller recording every [`MpcController::feedback`] call's arguments
    /// ([`MpcController::recorded`]): the QPs of a run, to compare solvers on.
    pub fn recording(mut self) -> Self {
        self.record = Some(Mutex::new(Vec::new()));
        self
    }

    /// The recorded calls, in the order they came (empty unless recording).
    pub fn recorded(&self) -> Vec<MpcSample> {
        self.record.as_ref().map_or_else(Vec::new, |r| {
            r.lock().expect("no panics while held").clone()
        })
    }

    /// The MPC at upright rest (no plan): every sample's model is the LQ design's, no
    /// feedforward, and the tilt reference zero. For tests.
    pub fn at_rest(p: &WipParams, samples: usize) -> Result<Self, MpcDesignError> {
        let plan = Trajectory {
            t: vec![0.0, samples as f64 * SAMPLE],
            x: vec![Default::default(); 2],
            u: vec![[0.0; 2]; 2],
        };
        Self::design(p, &plan)
    }

    /// The feedback at sample `k` for the error state `e0`, `u_prev` the voltage applied
    /// at the sample before.
    pub fn feedback(&self, k: usize, e0: &SVector<f64, NZ>, u_prev: [f64; 2]) -> MpcMove {
        let (t0, c0) = (std::time::Instant::now(), thread_cpu_seconds());
        if let Some(r) = &self.record {
            let call = MpcSample { k, e0: *e0, u_prev };
            r.lock().expect("no panics while held").push(call);
        }
        let mut ws = self.workspace();
        let solution = self
            .stage_qp(k, e0, u_prev)
            .ok()
            .map(|qp| ws.solver.solve(&qp));
        let solution = solution.filter(|sol| sol.status == QpStatus::Solved);
        let u_fb = solution
            .as_ref()
            .map_or_else(|| self.lq.feedback(e0), |sol| [sol.u[0][0], sol.u[0][1]]);
        let solved = solution.is_some();
        self.workspaces
            .lock()
            .expect("no panics while held")
            .push(ws);
        MpcMove {
            u_fb,
            solve_s: thread_cpu_seconds() - c0,
            solve_wall_s: t0.elapsed().as_secs_f64(),
            solved,
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
                solver: QpSolver::new(self.settings.clone()),
            },
        }
    }

    /// The QP at sample `k` (module doc): stage `j < N_p` has the model `Φ_{k+j}`,
    /// `Γ_{k+j}` and carries `δu_j` on as `p_{j+1}`; the cost `e_jᵀ Q_Y e_j` (`j ≥ 1`;
    /// `e_0` is given) `+ δu_jᵀ δu_j`, the terminal `e_Nᵀ P e_N`; rows: the voltage box,
    /// the soft rate `(u_ff,j + δu_j) − (u_ff,j−1 + p_j)` (`u_prev = p_0` at `j = 0`) and
    /// the soft tilt `α_ref,k+j + e_j[α]` (`j ≥ 1`, and at the terminal stage).
    pub fn stage_qp(
        &self,
        k: usize,
        e0: &SVector<f64, NZ>,
        u_prev: [f64; 2],
    ) -> Result<MpcQp, QpError> {
        let mut x0 = SVector::<f64, QP_NX>::zeros();
        x0.fixed_rows_mut::<NZ>(0).copy_from(e0);
        x0.fixed_rows_mut::<NIN>(NZ).copy_from_slice(&u_prev);
        let q_y = SMatrix::<f64, NZ, NZ>::from_diagonal(&SVector::from_column_slice(&Q_Y));
        let tilt = |rows: &mut dmech_ocp::qp::Rows<QP_NX, NIN, QP_NC>, alpha_ref: f64| {
            rows.state_bound(4, 2, -TILT_MAX - alpha_ref, TILT_MAX - alpha_ref)
                .soften(4, SoftPrice::l1(TILT_WEIGHT));
        };
        let stages = (0..HORIZON)
            .map(|j| {
                let s = self.sample(k + j);
                let mut st = Stage::<QP_NX, NIN, QP_NC>::zeros();
                st.a.fixed_view_mut::<NZ, NZ>(0, 0).copy_from(&s.phi);
                st.b.fixed_view_mut::<NZ, NIN>(0, 0).copy_from(&s.gamma);
                st.b.fixed_view_mut::<NIN, NIN>(NZ, 0).fill_with_identity();
                if j > 0 {
                    st.q.fixed_view_mut::<NZ, NZ>(0, 0).copy_from(&(q_y * 2.0));
                }
                st.r = SMatrix::identity() * 2.0;
                let before = if j == 0 {
                    [0.0; 2]
                } else {
                    self.sample(k + j - 1).u_ff
                };
                for w in 0..NIN {
                    st.rows
                        .input_bound(w, w, -U_MAX - s.u_ff[w], U_MAX - s.u_ff[w]);
                    // Rate: δu_j − p_j within ±DU_MAX − (u_ff,j − before).
                    let offset = before[w] - s.u_ff[w];
                    let mut d = SVector::<f64, QP_NX>::zeros();
                    d[NZ + w] = -1.0;
                    let mut e = SVector::<f64, NIN>::zeros();
                    e[w] = 1.0;
                    st.rows
                        .set_row(2 + w, d, e, offset - DU_MAX, offset + DU_MAX)
                        .soften(2 + w, SoftPrice::l1(RATE_WEIGHT));
                }
                if j > 0 {
                    tilt(&mut st.rows, s.alpha_ref);
                }
                st
            })
            .collect();
        let mut terminal = Terminal::<QP_NX, NIN, QP_NC>::zeros();
        terminal
            .q
            .fixed_view_mut::<NZ, NZ>(0, 0)
            .copy_from(&(self.lq.design.p * 2.0));
        tilt(&mut terminal.rows, self.sample(k + HORIZON).alpha_ref);
        StageQp::new(x0, stages, terminal)
    }

    /// The plan's sample `k + j`, or its last one beyond the end.
    fn sample(&self, i: usize) -> &PlanSample {
        &self.samples[i.min(self.samples.len() - 1)]
    }
}

/// The same QP in clarabel's form, the oracle of the tests: variables `(e_1 … e_Np,
/// δu_0 … δu_{Np−1}, σ)` (error states, feedback voltages, one slack per soft row).
#[cfg(test)]
mod oracle {
    use super::*;
    use clarabel::algebra::CscMatrix;
    use clarabel::solver::{
        DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus, ZeroConeT,
    };

    /// One QP in clarabel's form: `min ½ xᵀPx + qᵀx` s.t. `Ax + s = b`, `s ∈ cones`.
    struct Qp {
        p: CscMatrix<f64>,
        q: Vec<f64>,
        a: CscMatrix<f64>,
        b: Vec<f64>,
        cones: Vec<clarabel::solver::SupportedConeT<f64>>,
        /// Index of `δu_0` in `x`.
        u0: usize,
    }

    /// Triplets of a sparse matrix under construction.
    #[derive(Default)]
    struct Triplets {
        rows: Vec<usize>,
        cols: Vec<usize>,
        vals: Vec<f64>,
    }

    impl Triplets {
        fn put(&mut self, r: usize, c: usize, v: f64) {
            if v != 0.0 {
                self.rows.push(r);
                self.cols.push(c);
                self.vals.push(v);
            }
        }
        fn csc(self, m: usize, n: usize) -> CscMatrix<f64> {
            CscMatrix::new_from_triplets(m, n, self.rows, self.cols, self.vals)
        }
    }

    /// Where each variable sits in the QP's `x`: `e_j` at `8(j−1)`, `δu_j` at `8Np + 2j`, rate
    /// slacks at `10Np + 2j`, tilt slacks at `12Np + j`.
    mod layout {
        use super::{HORIZON as NP, NZ};
        pub const NX: usize = (NZ + 5) * NP;
        /// `e_j[i]`, `j ≥ 1` (`e_0` is given).
        pub fn e(j: usize, i: usize) -> usize {
            NZ * (j - 1) + i
        }
        pub fn du(j: usize, wheel: usize) -> usize {
            NZ * NP + 2 * j + wheel
        }
        pub fn rate_slack(j: usize, wheel: usize) -> usize {
            (NZ + 2) * NP + 2 * j + wheel
        }
        pub fn tilt_slack(j: usize) -> usize {
            (NZ + 4) * NP + j
        }
    }

    impl MpcController {
        /// clarabel's `δu_0` and objective for the QP of sample `k`; `None` unless solved.
        pub(super) fn clarabel_solve(
            &self,
            k: usize,
            e0: &SVector<f64, NZ>,
            u_prev: [f64; 2],
        ) -> Option<([f64; 2], f64)> {
            let qp = self.qp(k, e0, u_prev);
            let settings = DefaultSettingsBuilder::default()
                .verbose(false)
                .presolve_enable(false)
                .build()
                .expect("valid settings");
            let mut solver =
                DefaultSolver::new(&qp.p, &qp.q, &qp.a, &qp.b, &qp.cones, settings).ok()?;
            solver.solve();
            let x = &solver.solution.x;
            (solver.solution.status == SolverStatus::Solved)
                .then(|| ([x[qp.u0], x[qp.u0 + 1]], solver.solution.obj_val))
        }

        /// The QP at sample `k` (module doc).
        fn qp(&self, k: usize, e0: &SVector<f64, NZ>, u_prev: [f64; 2]) -> Qp {
            let (p, q) = self.cost();
            let (a, b, n_eq) = self.constraints(k, e0, u_prev);
            let m = b.len();
            Qp {
                p,
                q,
                a,
                b,
                cones: vec![ZeroConeT(n_eq), NonnegativeConeT(m - n_eq)],
                u0: layout::du(0, 0),
            }
        }

        /// `½ xᵀPx + qᵀx` with `P = 2 blockdiag(Q_Y, …, Q_Y, P_T, I, …, I)` (upper triangle)
        /// and `q` the slack weights.
        fn cost(&self) -> (CscMatrix<f64>, Vec<f64>) {
            use layout::{du, e, rate_slack, tilt_slack, NX};
            let mut pm = Triplets::default();
            let terminal = &self.lq.design.p;
            for j in 1..=HORIZON {
                for r in 0..NZ {
                    for c in r..NZ {
                        let v = match (j < HORIZON, r == c) {
                            (true, true) => Q_Y[r],
                            (true, false) => 0.0,
                            (false, _) => terminal[(r, c)],
                        };
                        pm.put(e(j, r), e(j, c), 2.0 * v);
                    }
                }
            }
            let mut q = vec![0.0; NX];
            for j in 0..HORIZON {
                for w in 0..2 {
                    pm.put(du(j, w), du(j, w), 2.0);
                    q[rate_slack(j, w)] = RATE_WEIGHT;
                }
                q[tilt_slack(j)] = TILT_WEIGHT;
            }
            (pm.csc(NX, NX), q)
        }

        /// `A x + s = b`: the dynamics rows first (`s = 0`, their count returned), then the
        /// voltage, rate, tilt and slack-sign rows (`s ≥ 0`).
        fn constraints(
            &self,
            k: usize,
            e0: &SVector<f64, NZ>,
            u_prev: [f64; 2],
        ) -> (CscMatrix<f64>, Vec<f64>, usize) {
            use layout::{du, e, rate_slack, tilt_slack, NX};
            let (mut am, mut b) = (Triplets::default(), Vec::new());
            // Dynamics: e_{j+1} − Φ e_j − Γ δu_j = 0 (e_0 given, on the right).
            for j in 0..HORIZON {
                let s = self.sample(k + j);
                let rhs = if j == 0 { s.phi * e0 } else { SVector::zeros() };
                for r in 0..NZ {
                    let row = b.len();
                    am.put(row, e(j + 1, r), 1.0);
                    if j > 0 {
                        for c in 0..NZ {
                            am.put(row, e(j, c), -s.phi[(r, c)]);
                        }
                    }
                    for w in 0..2 {
                        am.put(row, du(j, w), -s.gamma[(r, w)]);
                    }
                    b.push(rhs[r]);
                }
            }
            let n_eq = b.len();
            for j in 0..HORIZON {
                let s = self.sample(k + j);
                let before = if j == 0 {
                    u_prev
                } else {
                    self.sample(k + j - 1).u_ff
                };
                for (w, (&u_ff, &u_before)) in s.u_ff.iter().zip(&before).enumerate() {
                    for sgn in [1.0, -1.0] {
                        // Voltage: ±(u_ff + δu) ≤ U_MAX.
                        let row = b.len();
                        am.put(row, du(j, w), sgn);
                        b.push(U_MAX - sgn * u_ff);
                        // Rate: ±((u_ff,j + δu_j) − u_{j−1}) − σ ≤ DU_MAX.
                        let row = b.len();
                        am.put(row, du(j, w), sgn);
                        if j > 0 {
                            am.put(row, du(j - 1, w), -sgn);
                        }
                        am.put(row, rate_slack(j, w), -1.0);
                        b.push(DU_MAX - sgn * (u_ff - u_before));
                    }
                    let row = b.len();
                    am.put(row, rate_slack(j, w), -1.0);
                    b.push(0.0);
                }
                // Tilt at the sample after: ±(α_ref + e[α]) − σ ≤ TILT_MAX.
                let alpha_ref = self.sample(k + j + 1).alpha_ref;
                for sgn in [1.0, -1.0] {
                    let row = b.len();
                    am.put(row, e(j + 1, 2), sgn);
                    am.put(row, tilt_slack(j), -1.0);
                    b.push(TILT_MAX - sgn * alpha_ref);
                }
                let row = b.len();
                am.put(row, tilt_slack(j), -1.0);
                b.push(0.0);
            }
            let m = b.len();
            (am.csc(m, NX), b, n_eq)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Unconstrained at upright rest, the QP's first move is the LQ feedback: the terminal
    /// cost is the DARE's `P`, so the finite horizon reproduces the infinite one. The
    /// solver at a gap of 1e-10 (the structure, not the loop's tolerance, is tested): the
    /// move within 1e-5 of its size, voltages of order 0.1 V.
    #[test]
    fn unconstrained_at_rest_the_first_move_is_the_lq_feedback() {
        let mut mpc = MpcController::at_rest(&WipParams::default(), 100).unwrap();
        mpc.settings = QpSettings::builder()
            .tol(1e-10)
            .start_mu(QP_START_MU)
            .build()
            .unwrap();
        // Small enough that the LQ sequence changes by less than the rate bound per sample.
        let e0 = SVector::<f64, NZ>::from_column_slice(&[
            2e-5, -1e-4, 4e-5, 1e-4, 5e-5, -2e-4, 0.0, 0.0,
        ]);
        let lq = mpc.lq.feedback(&e0);
        // Start from the LQ voltage itself, so that the first step's rate is zero.
        let m = mpc.feedback(0, &e0, lq);
        assert!(m.solved);
        let scale = lq[0].abs().max(lq[1].abs());
        for w in 0..2 {
            assert!(
                (m.u_fb[w] - lq[w]).abs() < 1e-5 * scale,
                "{:?} against {lq:?}",
                m.u_fb
            );
        }
    }

    /// An error that asks for more than 5 V: the MPC's move stays inside the bound.
    #[test]
    fn the_voltage_bound_holds_where_lq_would_exceed_it() {
        let mpc = MpcController::at_rest(&WipParams::default(), 100).unwrap();
        let e0 = SVector::<f64, NZ>::from_column_slice(&[0.0, 0.0, 0.2, 2.0, 0.0, 0.0, 0.0, 0.0]);
        let lq = mpc.lq.feedback(&e0);
        assert!(
            lq[0].abs() > U_MAX,
            "the LQ move {lq:?} is inside the bound"
        );
        let m = mpc.feedback(0, &e0, [0.0; 2]);
        assert!(m.solved);
        for w in 0..2 {
            assert!(m.u_fb[w].abs() <= U_MAX * (1.0 + 1e-7), "{:?}", m.u_fb);
        }
    }

    /// The QPs of a real run, solved by clarabel too: the hook plan
    /// (`tests/data/track_hook_h20.csv`, 7 s), the paper's sensors, seed 1, every QP the
    /// loop solved (its move, and a warm start from the previous QP's shifted solution)
    /// against clarabel's solve of the
    /// same QP written out (`oracle`). Ours stops at a gap within `ε = QP_TOL` of
    /// `max(1, |f|)`, clarabel at 1e-8 (tighter); each solution within
    /// `δ = 4 ε max(1, |f*|)` of the optimum (gap and
    /// residual terms); the QP is strongly convex in `δu` with modulus `m = 2` (`R = 2I`,
    /// `[Q S; Sᵀ R] ⪰ blockdiag(0, 2I)`, the soft prices convex), so
    /// `‖δu − δu*‖ ≤ √(2δ/m)` for each and the two agree to twice that.
    #[test]
    fn equals_clarabel_on_the_qps_of_a_real_run() {
        use crate::wip::track::closed_loop::{track, TrackConfig};
        use crate::wip::track::observer::SensorModel;
        let p = WipParams::default();
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/track_hook_h20.csv");
        let plan = crate::wip::track::report::read_plan(&path, usize::MAX, "").unwrap();
        let mpc = MpcController::design(&p, &plan).unwrap().recording();
        let cfg = TrackConfig {
            plant: p,
            nominal: p,
            sensors: SensorModel::paper(),
            seed: 1,
            push: None,
        };
        let run = track(&plan, &mpc, &cfg, |_| {}).unwrap();
        assert_eq!(run.qp_fallbacks, 0);
        let calls = mpc.recorded();
        assert_eq!(calls.len(), run.samples.len());
        let (mut worst, mut active) = (0.0f64, 0);
        let mut solver = QpSolver::new(mpc.settings.clone());
        let mut previous: Option<dmech_ocp::qp::QpSolution<QP_NX, NIN, QP_NC>> = None;
        for (call, sample) in calls.iter().zip(&run.samples) {
            let (u, f) = mpc.clarabel_solve(call.k, &call.e0, call.u_prev).unwrap();
            let qp = mpc.stage_qp(call.k, &call.e0, call.u_prev).unwrap();
            let ours = match &previous {
                Some(p) => solver.solve_warm(&qp, &p.shifted()),
                None => solver.solve(&qp),
            };
            assert_eq!(ours.status, QpStatus::Solved);
            let delta = 4.0 * QP_TOL * f.abs().max(1.0);
            assert!((ours.info.objective - f).abs() <= 2.0 * delta);
            let tol = 2.0 * (2.0 * delta / 2.0).sqrt();
            for w in 0..2 {
                // The loop's (cold) move and the warm-started solve, both against clarabel.
                let d = (sample.u_fb[w] - u[w])
                    .abs()
                    .max((ours.u[0][w] - u[w]).abs());
                assert!(
                    d <= tol,
                    "sample {}: {:?} against {u:?}",
                    call.k,
                    sample.u_fb
                );
                worst = worst.max(d / tol);
            }
            active += usize::from(ours.violations.iter().any(|v| v.amax() > 1e-6));
            previous = Some(ours);
        }
        println!(
            "{} QPs, {active} with a soft row violated: worst δu_0 difference {worst:.1e} of \
             its tolerance",
            calls.len()
        );
        assert!(active > 0, "no QP of the run had a soft row violated");
    }
}

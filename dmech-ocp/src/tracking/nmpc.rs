//! Nonlinear model predictive control along a plan by real-time iteration: at every sample
//! an optimal control problem over the next `H` stages of the plan's own transcription
//! (the nonlinear stage dynamics and equalities, the plan's inequalities), its first state
//! fixed to the measured one, solved by [`crate::solver`]'s interior point for a fixed,
//! small number of Newton steps from the previous sample's solution shifted by one stage.
//!
//! At sample `k`, with `x̄_i`, `w̄_i = (v̄_i, ū_i)` the plan (held at its last values beyond
//! its end) and `x` the measured state,
//! ```text
//! min  Σ_{j<H} (δx_jᵀ Q δx_j + δu_jᵀ R δu_j + Σ_soft ρ_i dist(c_i, [lo_i, hi_i])²) + δx_Hᵀ P_{k+H} δx_H
//! s.t. x_{j+1} = f(x_j, w_j),  e(x_j, w_j) = 0,  lo ≤ c(x_j, w_j) ≤ hi (the hard rows),  x_0 = x
//! ```
//! with `δx_j = x_j − x̄_{k+j}`, `δu_j = u_j − ū_{k+j}`, and `P` the cost-to-go of the LQ
//! tracker along the plan's linearisation with the same `Q`, `R` ([`super::lq_design`]):
//! where no inequality is active, the problem's first move agrees with the LQ tracker's
//! `ū_k − K_k δx_0` to first order in `δx_0` (its dynamics' linearisation is the LQ's).
//! The rows named soft ([`SoftRow`]) leave the hard inequalities and enter the cost as a
//! quadratic penalty on their excess: a bound that a closed loop under noise cannot hold
//! (the plan's voltage rate, say) shapes the moves without making the problem infeasible.
//!
//! Real-time iteration ([`Nmpc::step`]): the solver runs at most
//! [`NmpcSettings::newton_steps`] iterations at the fixed barrier [`NmpcSettings::barrier`]
//! (the objective unscaled, [`IpOptions::objective_scale`]) from the previous sample's
//! iterate shifted by one stage ([`NmpcMemory`]: states, decisions, multipliers, slacks; the
//! new last stage from the LQ tracker's move by the transcription's own step,
//! [`super::plant_step`]), or, without one, from the LQ tracker's rollout. The move is the
//! iterate's first input when the solve ends solved or at its step limit with a finite
//! input; otherwise ([`NmpcMove::input`] `None`: a solver failure, or the wall-clock
//! budget [`NmpcSettings::budget_s`] spent) the caller applies its fallback, and the next
//! sample starts cold.

use super::lq::{lq_design, LqDesign, TrackingWeights};
use super::mpc::thread_cpu_seconds;
use super::{linearise_along, plant_step, TrackingError};
use crate::nlp::{HessianBlocks, StageProblem, StateEquality};
use crate::solver::{Curvature, IpOptions, Iterate, Solver, Status};
use dmech_lie::Real;
use nalgebra::{SMatrix, SVector};

/// An inequality row held softly: no bound in the problem, `weight · dist(c, [lo, hi])²`
/// in each stage's cost instead.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoftRow {
    /// The row of the transcription's inequalities.
    pub row: usize,
    /// `ρ`, per squared unit of the row's excess.
    pub weight: f64,
}

/// The real-time iteration's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct NmpcSettings {
    /// Stages in the horizon, `H ≥ 1`.
    pub horizon: usize,
    /// Interior-point iterations per sample, at most (`≥ 1`).
    pub newton_steps: usize,
    /// The barrier parameter `μ` each sample's iterations start at (positive).
    pub barrier: f64,
    /// The solver's tolerance ([`IpOptions::tol`]): a sample whose iterate meets it stops
    /// before its steps are spent.
    pub tol: f64,
    /// Wall-clock seconds a sample's solve may take; past them it stops and the move is
    /// the caller's fallback (`f64::INFINITY`: no budget).
    pub budget_s: f64,
    /// The curvature of the dynamics in the Newton systems.
    pub curvature: Curvature,
    /// The inequality rows held softly.
    pub soft: Vec<SoftRow>,
}

/// Why an NMPC could not be built or asked for a move.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NmpcError {
    /// The LQ design along the plan failed.
    #[error("the LQ design along the plan failed: {0}")]
    Lq(#[from] TrackingError),
    /// The plan's states and decisions do not match (`N + 1` states for `N` decisions).
    #[error("{states} plan states for {decisions} decisions (expected one more state)")]
    PlanLength {
        /// States given.
        states: usize,
        /// Decisions given.
        decisions: usize,
    },
    /// A horizon of no stage, or no Newton step per sample.
    #[error(
        "the horizon ({horizon}) and the Newton steps per sample ({steps}) must be at least 1"
    )]
    Empty {
        /// The horizon asked for.
        horizon: usize,
        /// The steps asked for.
        steps: usize,
    },
    /// The barrier, the tolerance or the budget is not positive.
    #[error("the barrier ({barrier}), the tolerance ({tol}) and the budget ({budget_s} s) must be positive")]
    NotPositive {
        /// The barrier asked for.
        barrier: f64,
        /// The tolerance asked for.
        tol: f64,
        /// The budget asked for.
        budget_s: f64,
    },
    /// A soft row beyond the inequalities, or a weight that is negative or not finite.
    #[error("soft row {row} (of {rows}) with weight {weight}")]
    SoftRow {
        /// The row.
        row: usize,
        /// The inequalities per stage.
        rows: usize,
        /// Its weight.
        weight: f64,
    },
    /// A move was asked for past the plan's last stage.
    #[error("sample {sample} is past the plan's {stages} stages")]
    PastThePlan {
        /// The sample asked for.
        sample: usize,
        /// The plan's stages.
        stages: usize,
    },
}

/// One sample's move.
#[derive(Clone, Debug, PartialEq)]
pub struct NmpcMove<const NF: usize> {
    /// The input to apply, the iterate's first; `None`: apply the fallback.
    pub input: Option<SVector<f64, NF>>,
    /// How the sample's solve ended (`MaxIterations`: the real-time iteration's steps
    /// spent, the normal outcome).
    pub status: Status,
    /// Interior-point iterations taken.
    pub iterations: usize,
    /// Whether the solve started from the previous sample's shifted iterate.
    pub warm: bool,
    /// The calling thread's CPU time for the sample (set-up, solve, shift), s.
    pub cpu_s: f64,
    /// The same as wall-clock time, s.
    pub wall_s: f64,
}

/// What the real-time iteration carries from one sample to the next: the last iterate and
/// its sample. One per closed loop; [`NmpcMemory::default`] starts cold.
#[derive(Clone, Debug, Default)]
pub struct NmpcMemory<const NX: usize, const NW: usize, const NC: usize> {
    last: Option<(usize, Iterate<NX, NW, NC>)>,
}

impl<const NX: usize, const NW: usize, const NC: usize> NmpcMemory<NX, NW, NC> {
    /// Forget the last iterate: the next sample starts cold.
    pub fn clear(&mut self) {
        self.last = None;
    }
}

/// The stationary cost-to-go of the LQ tracker at the stage `(x, w)` held for ever (the
/// Riccati recursion iterated from `weights.terminal` on that stage's linearisation until
/// `P` changes by at most `1e-10 ‖P‖`, at most `max_steps` times): the terminal weight for
/// a plan that ends at rest and is held there, as the horizons past its end hold it.
/// `None` if it does not settle within `max_steps` (the held stage not stabilisable) or
/// the recursion is singular.
pub fn stationary_cost_to_go<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    problem: &P,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
    weights: &TrackingWeights<NX, NF>,
    max_steps: usize,
) -> Option<SMatrix<f64, NX, NX>>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    let lin = linearise_along(problem, &[*x, *x], &[*w]).ok()?;
    let (a, b) = (&lin.a[0], &lin.b[0]);
    let (q, r) = (&weights.state, &weights.input);
    let mut p = weights.terminal;
    for _ in 0..max_steps {
        let bp = b.transpose() * p;
        let k = dmech_lie::linalg::Lu::new(&(r + bp * b))?.solve_columns(&(bp * a));
        let mut next = q + a.transpose() * p * (a - b * k);
        next = (next + next.transpose()) * 0.5;
        let change = (next - p).amax();
        p = next;
        if change <= 1e-10 * p.amax() {
            return Some(p);
        }
    }
    None
}

/// The NMPC along one plan: the plan, the weights, and the LQ tracker along it (its gains
/// start the new last stage of a shifted iterate; its cost-to-go is the terminal weight).
#[derive(Clone, Debug)]
pub struct Nmpc<const NX: usize, const NW: usize, const NF: usize> {
    x: Vec<SVector<f64, NX>>,
    w: Vec<SVector<f64, NW>>,
    weights: TrackingWeights<NX, NF>,
    lq: LqDesign<NX, NF>,
    settings: NmpcSettings,
}

impl<const NX: usize, const NW: usize, const NF: usize> Nmpc<NX, NW, NF> {
    /// The NMPC along the plan `(x̄, w̄)` of `problem` (its transcription: `N + 1` states,
    /// `N` decisions), with the tracking `weights` and `settings`.
    pub fn new<P, const NE: usize, const NC: usize>(
        problem: &P,
        x: Vec<SVector<f64, NX>>,
        w: Vec<SVector<f64, NW>>,
        weights: &TrackingWeights<NX, NF>,
        settings: NmpcSettings,
    ) -> Result<Self, NmpcError>
    where
        P: StageProblem<NX, NW, NE, NF, NC>,
    {
        if x.len() != w.len() + 1 || w.is_empty() {
            return Err(NmpcError::PlanLength {
                states: x.len(),
                decisions: w.len(),
            });
        }
        if settings.horizon == 0 || settings.newton_steps == 0 {
            return Err(NmpcError::Empty {
                horizon: settings.horizon,
                steps: settings.newton_steps,
            });
        }
        if !(settings.barrier > 0.0 && settings.budget_s > 0.0 && settings.tol > 0.0) {
            return Err(NmpcError::NotPositive {
                barrier: settings.barrier,
                tol: settings.tol,
                budget_s: settings.budget_s,
            });
        }
        if let Some(s) = settings
            .soft
            .iter()
            .find(|s| s.row >= NC || !(s.weight >= 0.0 && s.weight.is_finite()))
        {
            return Err(NmpcError::SoftRow {
                row: s.row,
                rows: NC,
                weight: s.weight,
            });
        }
        let plan = linearise_along(problem, &x, &w)?;
        let lq = lq_design(&plan, weights)?;
        Ok(Nmpc {
            x,
            w,
            weights: weights.clone(),
            lq,
            settings,
        })
    }

    /// The plan's stages `N`.
    pub fn stages(&self) -> usize {
        self.w.len()
    }

    /// The settings.
    pub fn settings(&self) -> &NmpcSettings {
        &self.settings
    }

    /// The LQ tracker along the plan.
    pub fn lq(&self) -> &LqDesign<NX, NF> {
        &self.lq
    }

    /// The plan's state at stage `i`, its last beyond the end.
    pub fn reference_state(&self, i: usize) -> &SVector<f64, NX> {
        &self.x[i.min(self.x.len() - 1)]
    }

    /// The plan's decision at stage `i`, its last beyond the end.
    pub fn reference_decision(&self, i: usize) -> &SVector<f64, NW> {
        &self.w[i.min(self.w.len() - 1)]
    }

    /// The LQ tracker's input at stage `i` (its last gain beyond the end) for the state `x`.
    pub fn lq_input<const NE: usize>(&self, i: usize, x: &SVector<f64, NX>) -> SVector<f64, NF> {
        let g = &self.lq.gains[i.min(self.lq.gains.len() - 1)];
        let u: SVector<f64, NF> = self.reference_decision(i).fixed_rows::<NF>(NE).into_owned();
        u - g * (x - self.reference_state(i))
    }

    /// The horizon's problem at sample `k` from the state `x0` (module documentation).
    pub fn horizon_problem<'p, P, const NE: usize, const NC: usize>(
        &'p self,
        problem: &'p P,
        k: usize,
        x0: SVector<f64, NX>,
    ) -> HorizonProblem<'p, P, NX, NW, NF>
    where
        P: StageProblem<NX, NW, NE, NF, NC>,
    {
        HorizonProblem {
            inner: problem,
            nmpc: self,
            start: k,
            x0,
        }
    }

    /// The move at sample `k < N` from the measured state `x0`, by the real-time iteration
    /// from `memory` (module documentation), which it updates.
    pub fn step<P, const NE: usize, const NC: usize>(
        &self,
        problem: &P,
        k: usize,
        x0: &SVector<f64, NX>,
        memory: &mut NmpcMemory<NX, NW, NC>,
    ) -> Result<NmpcMove<NF>, NmpcError>
    where
        P: StageProblem<NX, NW, NE, NF, NC>,
    {
        if k >= self.stages() {
            return Err(NmpcError::PastThePlan {
                sample: k,
                stages: self.stages(),
            });
        }
        let (t0, c0) = (std::time::Instant::now(), thread_cpu_seconds());
        let hp = self.horizon_problem::<P, NE, NC>(problem, k, *x0);
        let opts = IpOptions {
            max_iter: self.settings.newton_steps,
            mu_init: self.settings.barrier,
            tol: self.settings.tol,
            time_limit: self.settings.budget_s,
            curvature: self.settings.curvature,
            objective_scale: Some(1.0),
            threads: 1,
            verbose: false,
            ..IpOptions::default()
        };
        let solver = Solver::new(&hp, opts);
        let shifted = match memory.last.take() {
            Some((last, it)) if last + 1 == k => Some(self.shifted::<P, NE, NC>(problem, k, it)),
            _ => None,
        };
        let warm = shifted.is_some();
        let start = match shifted {
            Some(it) => solver.warm_iterate(it),
            None => {
                let (xs, ws) = self.rollout::<P, NE, NC>(problem, k, x0);
                solver.initial_iterate(xs, ws)
            }
        };
        let r = solver.solve(start);
        let u: SVector<f64, NF> = r.iterate.w[0].fixed_rows::<NF>(NE).into_owned();
        let usable = matches!(r.status, Status::Solved | Status::MaxIterations)
            && u.iter().all(|v| v.is_finite());
        if usable {
            memory.last = Some((k, r.iterate));
        }
        Ok(NmpcMove {
            input: usable.then_some(u),
            status: r.status,
            iterations: r.iterations,
            warm,
            cpu_s: thread_cpu_seconds() - c0,
            wall_s: t0.elapsed().as_secs_f64(),
        })
    }

    /// The LQ tracker's rollout over the horizon from `x0` at sample `k` by the
    /// transcription's own step (the plan's values where a step fails).
    #[allow(clippy::type_complexity)]
    fn rollout<P, const NE: usize, const NC: usize>(
        &self,
        problem: &P,
        k: usize,
        x0: &SVector<f64, NX>,
    ) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, NW>>)
    where
        P: StageProblem<NX, NW, NE, NF, NC>,
    {
        let h = self.settings.horizon;
        let mut xs = vec![*x0];
        let mut ws = Vec::with_capacity(h);
        for j in 0..h {
            let (x, w) = self.lq_stage::<P, NE, NC>(problem, k + j, &xs[j]);
            xs.push(x);
            ws.push(w);
        }
        (xs, ws)
    }

    /// Stage `i` from `x` under the LQ tracker's move: `(x_{i+1}, w_i)`, or the plan's
    /// values if the transcription's step fails there.
    fn lq_stage<P, const NE: usize, const NC: usize>(
        &self,
        problem: &P,
        i: usize,
        x: &SVector<f64, NX>,
    ) -> (SVector<f64, NX>, SVector<f64, NW>)
    where
        P: StageProblem<NX, NW, NE, NF, NC>,
    {
        let u = self.lq_input::<NE>(i, x);
        let guess: SVector<f64, NE> = self.reference_decision(i).fixed_rows::<NE>(0).into_owned();
        let stage = i.min(self.stages() - 1);
        plant_step::<P, NX, NW, NE, NF, NC>(problem, stage, x, &u, &guess)
            .unwrap_or((*self.reference_state(i + 1), *self.reference_decision(i)))
    }

    /// The iterate of sample `k − 1` shifted to sample `k`: its stages `1 … H` become
    /// `0 … H − 1` (states, decisions, multipliers, slacks), the new last stage is the LQ
    /// tracker's move from the old last state, with the old last stage's multipliers.
    fn shifted<P, const NE: usize, const NC: usize>(
        &self,
        problem: &P,
        k: usize,
        mut it: Iterate<NX, NW, NC>,
    ) -> Iterate<NX, NW, NC>
    where
        P: StageProblem<NX, NW, NE, NF, NC>,
    {
        let h = it.w.len();
        let last = *it.x.last().expect("a horizon has states");
        let (x_new, w_new) = self.lq_stage::<P, NE, NC>(problem, k + h - 1, &last);
        fn shift<T: Clone>(v: &mut Vec<T>, new: T) {
            v.remove(0);
            v.push(new);
        }
        shift(&mut it.x, x_new);
        shift(&mut it.w, w_new);
        let l = it.lambda[h - 1];
        shift(&mut it.lambda, l);
        let (tl, th, zl, zh) = (
            it.t_lo[h - 1],
            it.t_hi[h - 1],
            it.z_lo[h - 1],
            it.z_hi[h - 1],
        );
        shift(&mut it.t_lo, tl);
        shift(&mut it.t_hi, th);
        shift(&mut it.z_lo, zl);
        shift(&mut it.z_hi, zh);
        it
    }
}

/// The problem of one sample ([`Nmpc::horizon_problem`]): the transcription's stages
/// `k … k + H − 1` (its last beyond the plan's end), the tracking cost, the hard rows'
/// bounds, no state equalities, `x_0` the measured state.
pub struct HorizonProblem<'p, P, const NX: usize, const NW: usize, const NF: usize> {
    inner: &'p P,
    nmpc: &'p Nmpc<NX, NW, NF>,
    start: usize,
    x0: SVector<f64, NX>,
}

impl<P, const NX: usize, const NW: usize, const NF: usize> HorizonProblem<'_, P, NX, NW, NF> {
    /// The transcription's stage of the horizon's stage `j`.
    fn stage(&self, j: usize) -> usize {
        (self.start + j).min(self.nmpc.stages() - 1)
    }

    /// `δxᵀ M δx` with `δx = x − x̄_i`.
    fn deviation_cost<T: Real>(
        x: &SVector<T, NX>,
        reference: &SVector<f64, NX>,
        m: &SMatrix<f64, NX, NX>,
    ) -> T {
        let d = SVector::<T, NX>::from_fn(|r, _| x[r] - reference[r]);
        let mut sum = T::zero();
        for r in 0..NX {
            let mut row = T::zero();
            for c in 0..NX {
                if m[(r, c)] != 0.0 {
                    row += d[c] * m[(r, c)];
                }
            }
            sum += d[r] * row;
        }
        sum
    }
}

impl<P, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    StageProblem<NX, NW, NE, NF, NC> for HorizonProblem<'_, P, NX, NW, NF>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    fn horizon(&self) -> usize {
        self.nmpc.settings.horizon
    }
    fn initial_state(&self) -> SVector<f64, NX> {
        self.x0
    }
    fn dynamics<T: Real>(
        &self,
        j: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> SVector<T, NX> {
        self.inner.dynamics(self.stage(j), x, w)
    }
    fn equality<T: Real>(
        &self,
        j: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> SVector<T, NE> {
        self.inner.equality(self.stage(j), x, w)
    }
    fn cost<T: Real>(&self, j: usize, x: &SVector<T, NX>, w: &SVector<T, NW>) -> T {
        let i = self.start + j;
        let n = self.nmpc;
        let mut cost = Self::deviation_cost(x, n.reference_state(i), &n.weights.state);
        let w_ref = n.reference_decision(i);
        let du = SVector::<T, NF>::from_fn(|r, _| w[NE + r] - w_ref[NE + r]);
        for r in 0..NF {
            for c in 0..NF {
                let rc = n.weights.input[(r, c)];
                if rc != 0.0 {
                    cost += du[r] * du[c] * rc;
                }
            }
        }
        if n.settings.soft.is_empty() {
            return cost;
        }
        let c = self.inner.constraints(self.stage(j), x, w);
        let (lo, hi) = self.inner.bounds(self.stage(j));
        for s in &n.settings.soft {
            let v = c[s.row];
            let excess = if v.re() > hi[s.row] {
                v - hi[s.row]
            } else if v.re() < lo[s.row] {
                v - lo[s.row]
            } else {
                continue;
            };
            cost += excess * excess * s.weight;
        }
        cost
    }
    fn terminal_cost<T: Real>(&self, x: &SVector<T, NX>) -> T {
        let n = self.nmpc;
        let i = (self.start + n.settings.horizon).min(n.stages());
        Self::deviation_cost(x, n.reference_state(i), &n.lq.cost_to_go[i])
    }
    fn constraints<T: Real>(
        &self,
        j: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> SVector<T, NC> {
        self.inner.constraints(self.stage(j), x, w)
    }
    fn bounds(&self, j: usize) -> (SVector<f64, NC>, SVector<f64, NC>) {
        let (mut lo, mut hi) = self.inner.bounds(self.stage(j));
        for s in &self.nmpc.settings.soft {
            lo[s.row] = f64::NEG_INFINITY;
            hi[s.row] = f64::INFINITY;
        }
        (lo, hi)
    }
    fn state_equalities(&self) -> Vec<StateEquality> {
        Vec::new()
    }
    fn dynamics_jacobian(
        &self,
        j: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NX>, SMatrix<f64, NX, NX>, SMatrix<f64, NX, NW>) {
        self.inner.dynamics_jacobian(self.stage(j), x, w)
    }
    fn equality_jacobian(
        &self,
        j: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NE>, SMatrix<f64, NE, NX>, SMatrix<f64, NE, NW>) {
        self.inner.equality_jacobian(self.stage(j), x, w)
    }
    fn equality_partials(
        &self,
        j: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SMatrix<f64, NE, NX>, SMatrix<f64, NE, NW>) {
        self.inner.equality_partials(self.stage(j), x, w)
    }
    fn constraint_curvature(
        &self,
        j: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        lambda: &SVector<f64, NX>,
        nu: &SVector<f64, NE>,
    ) -> HessianBlocks<NX, NW> {
        self.inner
            .constraint_curvature(self.stage(j), x, w, lambda, nu)
    }
}

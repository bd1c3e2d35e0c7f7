//! Feasibility restoration: what the solver does when its line search finds no acceptable
//! step far from feasibility, or the violation stalls there, and how it tells a problem
//! that has no feasible point near from one it only failed to make progress on.
//!
//! IPOPT's restoration phase (Wächter & Biegler 2006, §3.3) minimises the `ℓ₁` norm of
//! every constraint's violation plus a proximity term. Here the dynamics, the stage
//! equalities and the inequalities stay hard: a stage-structured problem can always meet
//! its explicit dynamics and (by the assumption of [`StageProblem`]) its stage equalities
//! by simulating forward from `x̄`, so what makes a plan infeasible is that the state
//! equalities (waypoints, the end state) cannot be reached within the inequalities. The
//! restoration problem keeps the original's stages and replaces its objective by
//!
//! ```text
//! ρ/2 Σ_j (x_{k_j}[i_j] − v_j)² + ρ/2 ‖r(x_N)‖²  +  ζ/2 Σ_k (‖D_x (x_k − x̂_k)‖² + ‖D_w (w_k − ŵ_k)‖²)
//! ```
//!
//! (the state and terminal equalities' residuals, squared, and a proximity to the point `(x̂, ŵ)` where
//! restoration began, `D = diag(min(1, 1/|x̂_i|))`, `ζ = √μ` following the restoration's
//! barrier parameter down, so that the proximity vanishes at its solution), solved by the
//! same interior point. `ρ = ρ₁/θ̂`, with `θ̂` the largest violation at entry, makes the penalty's
//! gradient `ρ₁ = 1000` there, as IPOPT's `ℓ₁` penalty weight. The restoration stops as
//! soon as the original problem's violation has fallen to `κ_R = 0.9` of its value at entry
//! and the state equalities' own violation, which is what the restoration problem
//! minimises, has fallen to `κ_R` of its value at entry too (the first restoration steps
//! remove the dynamics' residuals at once; measured on an unreachable plan, stopping on the
//! total alone handed back points that stalled again). The original filter then holds the
//! point restoration began at. If the restoration problem is
//! instead solved to its tolerance with the violation still above that, the iterate is a
//! stationary point of the squared violation within the hard constraints, a point of local
//! infeasibility, and the problem is reported [`Status::Infeasible`].

use super::oracle::{RestorationOracle, RestorationSetup};
use super::*;
use dmech_lie::Real;
use std::sync::atomic::{AtomicU64, Ordering};

/// `ρ₁`: the penalty's gradient at entry (IPOPT's `ρ`).
const RHO_AT_ENTRY: f64 = 1e3;
/// `κ_R`: the restoration has succeeded when the violation is at most this fraction of
/// its value at entry.
pub(super) const KAPPA_RESTORATION: f64 = 0.9;
/// Bound multipliers above this after restoration are reset to 1 (IPOPT's
/// `bound_mult_reset_threshold`).
const BOUND_MULT_RESET: f64 = 1e3;
/// A completed restoration counts as feasible when the largest violation is at most this
/// fraction of its value at entry. On a feasible problem the converged restoration leaves
/// `r ≈ ζ|x − x̂|/ρ ≈ 3·10⁻⁷ θ̂` (`ζ = √(tol/10)`, `ρ = 10³/θ̂`); on an infeasible one the
/// least violation, of the order of `θ̂`.
const FEASIBLE_FRACTION: f64 = 1e-4;

/// The restoration problem of `p` around `(x̂, ŵ)`: `p`'s stages with the objective above.
pub(super) struct Restoration<'a, P, const NX: usize, const NW: usize> {
    p: &'a P,
    /// The point, the penalty weight and the state equalities.
    at: RestorationSetup<'a, NX, NW>,
    /// `ζ`, as the bits of an `f64` (set between iterations, read by the stage functions on
    /// every thread).
    zeta: AtomicU64,
}

/// `D (v − v̂)` with `D = diag(min(1, 1/|v̂_i|))`, squared and summed.
fn proximity<T: Real, const N: usize>(v: &SVector<T, N>, v_ref: &SVector<f64, N>) -> T {
    let mut s = T::zero();
    for i in 0..N {
        let d = (v[i] - v_ref[i]) * (1.0 / v_ref[i].abs().max(1.0));
        s += d * d;
    }
    s
}

impl<'a, P, const NX: usize, const NW: usize> Restoration<'a, P, NX, NW> {
    /// The restoration problem of `p` around `at`'s point, with `ζ` first `zeta`.
    pub(super) fn new(p: &'a P, at: RestorationSetup<'a, NX, NW>, zeta: f64) -> Self {
        Restoration {
            p,
            at,
            zeta: AtomicU64::new(zeta.to_bits()),
        }
    }

    fn zeta(&self) -> f64 {
        f64::from_bits(self.zeta.load(Ordering::Relaxed))
    }

    /// `ρ/2 Σ (x[i_j] − v_j)²` over the state equalities at stage `k`.
    fn penalty<T: Real>(&self, k: usize, x: &SVector<T, NX>) -> T {
        let mut s = T::zero();
        for &j in &self.at.eqs_at[k] {
            let e = &self.at.eqs[j];
            let r = x[e.index] - e.value;
            s += r * r;
        }
        s * (0.5 * self.at.rho)
    }
}

impl<P, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    StageProblem<NX, NW, NE, NF, NC> for Restoration<'_, P, NX, NW>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    crate::nlp::forward_stage_problem!(p: horizon, initial_state, dynamics, equality,
        constraints, bounds, dynamics_jacobian, equality_jacobian, equality_partials,
        constraint_curvature);
    fn cost<T: Real>(&self, k: usize, x: &SVector<T, NX>, w: &SVector<T, NW>) -> T {
        let prox = proximity(x, &self.at.x_ref[k]) + proximity(w, &self.at.w_ref[k]);
        self.penalty(k, x) + prox * (0.5 * self.zeta())
    }
    fn terminal_cost<T: Real>(&self, x: &SVector<T, NX>) -> T {
        let n = self.at.x_ref.len() - 1;
        let mut terminal = T::zero();
        for r in self.p.terminal_equalities(x) {
            terminal += r * r;
        }
        self.penalty(n, x)
            + terminal * (0.5 * self.at.rho)
            + proximity(x, &self.at.x_ref[n]) * (0.5 * self.zeta())
    }
    fn state_equalities(&self) -> Vec<StateEquality> {
        Vec::new()
    }
    /// The globals stay, with their equalities and bounds hard (they can always be met)
    /// and without their cost.
    fn globals(&self) -> Option<crate::nlp::Globals> {
        self.p.globals().map(|mut g| {
            g.cost.iter_mut().for_each(|v| *v = 0.0);
            g
        })
    }
}

impl<P, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    RestorationOracle<NX, NW, NE, NF, NC> for Restoration<'_, P, NX, NW>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    fn follow(&self, mu: f64) -> bool {
        let new = mu.sqrt().to_bits();
        self.zeta.swap(new, Ordering::Relaxed) != new
    }
}

/// How a restoration ended.
pub(super) enum Restored<const NX: usize, const NW: usize, const NC: usize> {
    /// The violation fell to `κ_R` of its value at entry: go on from this iterate.
    Progress(Iterate<NX, NW, NC>),
    /// The solve could not go on: `Infeasible` (a point of local infeasibility, or the hard
    /// constraints themselves infeasible), an iteration or time limit, or a failure; with
    /// the restoration's last iterate.
    Stop(Status, Iterate<NX, NW, NC>),
}

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NF, NC>
{
    /// `Σ_j |x_{k_j}[i_j] − v_j| + Σ_j |r_j(x_N)|`, the state and terminal equalities'
    /// part of `θ`.
    pub(super) fn state_equality_violation(&self, it: &Iterate<NX, NW, NC>) -> f64 {
        let state: f64 = self
            .eqs
            .iter()
            .map(|e| (it.x[e.stage][e.index] - e.value).abs())
            .sum();
        let terminal: f64 = self
            .p
            .terminal_equalities(&it.x[self.n])
            .iter()
            .map(|r| r.abs())
            .sum();
        state + terminal
    }

    /// Restoration from `it` (measures `m`, barrier `mu`), within `max_iter` iterations and
    /// `time_limit` seconds; returns how it ended and the iterations it took. A `complete`
    /// restoration (the solve has been restored before, and came back to a stall) does not
    /// stop at `κ_R`: it solves the restoration problem, and the result is feasible or a
    /// point of local infeasibility.
    pub(super) fn restore(
        &self,
        it: &Iterate<NX, NW, NC>,
        m: &Measures,
        mu: f64,
        limits: (usize, f64),
        complete: bool,
    ) -> (Restored<NX, NW, NC>, usize) {
        let (max_iter, time_limit) = limits;
        let mu_r = mu.max(m.theta_max.min(self.opts.mu_init));
        let problem = self
            .derived
            .expect("a restoration problem's solver does not restore")
            .restoration(
                RestorationSetup {
                    eqs: &self.eqs,
                    eqs_at: &self.eqs_at,
                    x_ref: it.x.clone(),
                    w_ref: it.w.clone(),
                    rho: RHO_AT_ENTRY / m.theta_max.max(f64::MIN_POSITIVE),
                },
                mu_r.sqrt(),
            );
        let solver: Solver<NX, NW, NE, NF, NC> = Solver::of_oracle(
            &*problem,
            None,
            IpOptions {
                mu_init: mu_r,
                max_iter,
                time_limit,
                // The restoration problem ends by its own test; an end at the caller's
                // final barrier would read as a converged restoration, i.e. infeasible.
                final_barrier: None,
                ..self.opts.clone()
            },
        );
        if self.opts.verbose {
            let _ = writeln!(
                std::io::stderr(),
                "restoration: violation {:.2e}, barrier {mu_r:.1e}",
                m.theta_max
            );
        }
        // Same primal point, slacks and bound multipliers; no equality multipliers (the
        // objective is another one).
        let start = Iterate {
            lambda: vec![SVector::zeros(); self.n],
            y: Vec::new(),
            ..it.clone()
        };
        let target = KAPPA_RESTORATION * m.theta;
        // The state equalities' part may be zero at entry: within their tolerance then.
        let eq_target = KAPPA_RESTORATION * self.state_equality_violation(it)
            + self.equality_multipliers() as f64 * self.opts.constr_viol_tol;
        let done = |r: &Iterate<NX, NW, NC>, rm: &Measures| {
            let eq = self.state_equality_violation(r);
            !complete && eq <= eq_target && rm.theta + eq <= target
        };
        let follow = |mu: f64| problem.follow(mu);
        let (r, progressed) = solver.run_with(
            start,
            Mode::Restoration {
                done: &done,
                follow: &follow,
            },
        );
        let mut back = r.iterate;
        back.y = vec![0.0; self.equality_multipliers()];
        let violation = self.measures(&back, &self.values(&back), mu).theta_max;
        let feasible =
            complete && r.status == Status::Solved && violation <= FEASIBLE_FRACTION * m.theta_max;
        let status = match r.status {
            _ if progressed || feasible => {
                for z in back.z_lo.iter_mut().chain(back.z_hi.iter_mut()) {
                    z.apply(|v| {
                        if *v > BOUND_MULT_RESET {
                            *v = 1.0
                        }
                    });
                }
                back.lambda.iter_mut().for_each(|l| l.fill(0.0));
                return (Restored::Progress(back), r.iterations);
            }
            // Converged to a stationary point of the squared violation that is not feasible.
            Status::Solved => Status::Infeasible { violation },
            s @ (Status::Infeasible { .. } | Status::MaxIterations | Status::TimeLimit) => s,
            Status::Diverged => Status::Failed(Failure::RestorationDiverged),
            Status::Failed(why) => Status::Failed(Failure::Restoration(Box::new(why))),
        };
        (Restored::Stop(status, back), r.iterations)
    }
}

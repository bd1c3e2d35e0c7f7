//! Free waypoint timing on the first-order variational integrator: the plan's stages are
//! split into segments (between the stages of its conditions), each segment's step is a
//! global variable `h_j = h̄ σ_j`, and the planner chooses the ratios `σ_j` (bounded), with
//! the total time fixed (`Σ_j N_j σ_j = N`) or priced ([`TotalTime`]).
//!
//! The variable-step discrete Lagrangian: interval `k` has its own step `h_k`, so node
//! `k`'s momentum matching reads `h_{k−1}` (incoming momentum and `s_{k−1} = s_k − h_{k−1}
//! v_{k−1}`) and `h_k` (outgoing momentum):
//! ```text
//! (out(s_k, v_k; h_k) − inc(s_{k−1}, v_{k−1}; h_{k−1}))/h_k − F(s_k, v_k, u_k) = 0
//! out = ∂ℓ/∂v − h_k ∂ℓ/∂s − A(s_k)ᵀ dexp⁻¹(h_k ξ_k)ᵀ μ_k,
//! inc = ∂ℓ_{k−1}/∂v − A(s_k)ᵀ dexp⁻¹(−h_{k−1} ξ_{k−1})ᵀ μ_{k−1}
//! ```
//! (right-point forcing, weight `h_k`, divided by `h_k` as the fixed-step rows). With
//! `h_{k−1} = h_k` it is the fixed-step residual. The decision is `w_k = (v_k, u_k, σ_{k−1},
//! σ_k)`, the last two the solver's copies of the globals of intervals `k − 1` and `k`
//! ([`crate::nlp::Globals`]). The robot's cost and constraints see the step ratio
//! through [`PlanningProblem::cost_at_step`] and [`PlanningProblem::constraints_at_step`].

use crate::nlp::derivatives::{
    cost_and_inequalities, generic_cost_curvature, generic_equality_jacobian, hess2, seed2,
    seed_hyper,
};
use crate::nlp::HessianBlocks;
use crate::nlp::{GlobalEquality, Globals, StageProblem, StateEquality};
use crate::solver::Iterate;
use crate::transcription::layout::segment;
use crate::transcription::variational::stages::VarIntStages;
use crate::transcription::{PlannedTrajectory, PlanningProblem, VarIntTranscription};
use dmech::partials::{dl_ds, dl_dv, dl_dxi};
use dmech::{Discretisation, ForcingQuadrature, PrincipalKinematicSystem};
use dmech_lie::dual::{jacobian_part, lift_vec};
use dmech_lie::{LieGroup, Real};
use nalgebra::{SMatrix, SVector};
use num_dual::{Derivative, Dual2SVec64, DualSVec64, DualVec, HyperDualSVec64};

/// How the plan's total time enters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TotalTime {
    /// `Σ_j N_j h_j = N h̄`.
    Fixed,
    /// Free, at this cost per second added to the objective.
    Priced(f64),
}

/// The timing freedom of a plan.
#[derive(Clone, Debug, PartialEq)]
pub struct FreeTiming {
    /// The first stage of each segment, increasing, starting at 0 (e.g. the waypoints'
    /// stages; the last segment ends at `N`).
    pub segment_starts: Vec<usize>,
    /// Bounds on each segment's step ratio `σ_j = h_j / h̄`.
    pub ratio_bounds: (f64, f64),
    /// The plan's total time: fixed, or free at a price.
    pub total: TotalTime,
}

/// Why a free timing does not fit its plan.
#[derive(Clone, Debug, PartialEq)]
pub enum FreeTimingError {
    /// The segments do not start at 0 and increase within `0..N`.
    Segments(String),
    /// The ratio bounds do not hold 1 strictly inside positive values.
    Bounds(f64, f64),
    /// Only the first-order scheme with right-point forcing has a variable-step form here.
    Discretisation,
    /// The variable-step stages read every shape position from the state: a layout that
    /// leaves ignorable ones out is not supported here.
    IgnoredShape,
}

impl std::fmt::Display for FreeTimingError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FreeTimingError::Segments(why) => write!(f, "free timing: {why}"),
            FreeTimingError::Bounds(lo, hi) => write!(
                f,
                "free timing: step ratio bounds [{lo}, {hi}] must satisfy 0 < lo < 1 < hi"
            ),
            FreeTimingError::Discretisation => write!(
                f,
                "free timing needs the first-order variational integrator with right-point forcing"
            ),
            FreeTimingError::IgnoredShape => write!(
                f,
                "free timing needs a state that carries every shape position"
            ),
        }
    }
}

impl std::error::Error for FreeTimingError {}

/// A robot's VI plan with free segment timing. `NW` of the solver is `NS + NU + 2`.
pub struct FreeTimingTranscription<
    'a,
    S,
    P,
    const DOF: usize,
    const NP: usize,
    const NS: usize,
    const NU: usize,
    const NX: usize,
    const NW: usize,
> {
    /// The fixed-timing plan it frees (its decision `w_k` of `NW` entries; the free-timing
    /// problem's decision is `NW + 2`).
    pub plan: VarIntTranscription<'a, S, P, DOF, NP, NS, NU, NX, NW>,
    /// The timing freedom.
    pub timing: FreeTiming,
    /// The segment of each interval `k < N`.
    segment_of: Vec<usize>,
}

impl<
        'a,
        S,
        P,
        const DOF: usize,
        const NP: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    > FreeTimingTranscription<'a, S, P, DOF, NP, NS, NU, NX, NW>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    /// `plan` with the timing freedom `timing`.
    pub fn new<const NC: usize>(
        plan: VarIntTranscription<'a, S, P, DOF, NP, NS, NU, NX, NW>,
        timing: FreeTiming,
    ) -> Result<Self, FreeTimingError>
    where
        P: PlanningProblem<NP, NS, NU, NC>,
    {
        let st = &plan.stages;
        if st.discretisation != Discretisation::FirstOrder
            || st.quadrature != ForcingQuadrature::Right
        {
            return Err(FreeTimingError::Discretisation);
        }
        if st.layout.ignored != 0 {
            return Err(FreeTimingError::IgnoredShape);
        }
        let (lo, hi) = timing.ratio_bounds;
        if !(0.0 < lo && lo < 1.0 && 1.0 < hi && hi.is_finite()) {
            return Err(FreeTimingError::Bounds(lo, hi));
        }
        let n = plan.problem.horizon();
        let starts = &timing.segment_starts;
        if starts.first() != Some(&0)
            || starts.windows(2).any(|w| w[0] >= w[1])
            || starts.last().is_some_and(|&s| s >= n)
        {
            return Err(FreeTimingError::Segments(format!(
                "segment starts {starts:?} must increase from 0 below N = {n}"
            )));
        }
        let segment_of = (0..n)
            .map(|k| starts.partition_point(|&s| s <= k) - 1)
            .collect();
        Ok(FreeTimingTranscription {
            plan,
            timing,
            segment_of,
        })
    }

    /// The number of segments (globals).
    pub fn segments(&self) -> usize {
        self.timing.segment_starts.len()
    }

    /// Steps of each segment.
    fn segment_steps(&self) -> Vec<usize> {
        let mut counts = vec![0usize; self.segments()];
        for &j in &self.segment_of {
            counts[j] += 1;
        }
        counts
    }

    /// The ratios of a solution, and its stage times `t_0 … t_N`.
    pub fn times<const NWT: usize, const NC: usize>(
        &self,
        it: &Iterate<NX, NWT, NC>,
    ) -> (Vec<f64>, Vec<f64>) {
        let sigma = it.globals.p.clone();
        let h = self.plan.stages.h;
        let mut t = vec![0.0];
        for &j in &self.segment_of {
            t.push(t.last().unwrap() + h * sigma[j]);
        }
        (sigma, t)
    }

    /// The fixed-timing iterate as a start of this problem: `w_k` extended by the ratios
    /// (1), the multipliers kept.
    pub fn start_from_fixed<const NWT: usize, const NC: usize>(
        &self,
        it: Iterate<NX, NW, NC>,
    ) -> Iterate<NX, NWT, NC> {
        assert_eq!(NWT, NW + 2, "the free-timing decision adds two ratios");
        let w =
            it.w.iter()
                .map(|w0| SVector::<f64, NWT>::from_fn(|i, _| if i < NW { w0[i] } else { 1.0 }))
                .collect();
        Iterate {
            x: it.x,
            w,
            lambda: it.lambda,
            t_lo: it.t_lo,
            t_hi: it.t_hi,
            z_lo: it.z_lo,
            z_hi: it.z_hi,
            y: it.y,
            globals: Default::default(),
        }
    }

    /// The solution as a [`PlannedTrajectory`] at the nominal step (the fixed
    /// transcription's reading of the stages: the ratios trail `w`), with its stage times.
    pub fn trajectory<const NWT: usize, const NC: usize>(
        &self,
        it: &Iterate<NX, NWT, NC>,
    ) -> (PlannedTrajectory<NP, NS, NU>, Vec<f64>)
    where
        P: PlanningProblem<NP, NS, NU, NC>,
    {
        (self.plan.trajectory_of(&it.x, &it.w), self.times(it).1)
    }
}

impl<
        S,
        P,
        const DOF: usize,
        const NP: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
        const NWT: usize,
        const NC: usize,
    > StageProblem<NX, NWT, NS, NU, NC>
    for FreeTimingTranscription<'_, S, P, DOF, NP, NS, NU, NX, NW>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64> + Sync,
    P: PlanningProblem<NP, NS, NU, NC>,
{
    fn horizon(&self) -> usize {
        self.plan.stages.layout.check(NX, NWT, NS + NU + 2);
        self.plan.problem.horizon()
    }
    fn initial_state(&self) -> SVector<f64, NX> {
        crate::transcription::initial_state(self.plan.stages.layout, &self.plan.problem.start())
    }
    fn dynamics<T: Real>(
        &self,
        _k: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, NWT>,
    ) -> SVector<T, NX> {
        let l = self.plan.stages.layout;
        let sys = self.plan.stages.sys;
        let coords: Vec<T> = (0..l.np).map(|i| x[i]).collect();
        let g = <S::Group<T> as LieGroup<DOF>>::from_coordinates(&coords).expect("layout checked");
        let s: SVector<T, NS> = segment(x, l.s_at());
        let v: SVector<T, NS> = segment(w, 0);
        let h = w[NWT - 1] * self.plan.stages.h;
        let xi = -(sys.connection(&s) * v);
        let g_next = g.compose(&<S::Group<T> as LieGroup<DOF>>::exp(&(xi * h)));
        let mut out = SVector::<T, NX>::zeros();
        for (i, c) in g_next.coordinates().into_iter().enumerate() {
            out[i] = c;
        }
        for i in 0..NS {
            out[l.s_at() + i] = s[i] + v[i] * h;
            out[l.v_at() + i] = v[i];
        }
        for i in 0..NU {
            out[l.u_at() + i] = w[NS + i];
        }
        out
    }
    fn equality<T: Real>(
        &self,
        _k: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, NWT>,
    ) -> SVector<T, NS> {
        let l = self.plan.stages.layout;
        let sys = self.plan.stages.sys;
        let s: SVector<T, NS> = segment(x, l.s_at());
        let v_prev: SVector<T, NS> = segment(x, l.v_at());
        let v: SVector<T, NS> = segment(w, 0);
        let u: SVector<T, NU> = segment(w, NS);
        let hb = self.plan.stages.h;
        let (h_prev, h) = (w[NWT - 2] * hb, w[NWT - 1] * hb);
        let s_prev = s - v_prev * h_prev;
        let a_k = sys.connection(&s);
        let dexp_inv = |xi: &SVector<T, DOF>| <S::Group<T> as LieGroup<DOF>>::dexp_inv(xi);
        // Outgoing: ∂ℓ/∂v − h ∂ℓ/∂s − Aᵀ dexp⁻¹(hξ)ᵀ μ at (s_k, v_k, ξ_k).
        let xi = -(a_k * v);
        let out = dl_dv::<S, T, DOF, NS, NU>(sys, &s, &v, &xi)
            - dl_ds::<S, T, DOF, NS, NU>(sys, &s, &v, &xi) * h
            - a_k.transpose()
                * (dexp_inv(&(xi * h)).transpose() * dl_dxi::<S, T, DOF, NS, NU>(sys, &s, &v, &xi));
        // Incoming: ∂ℓ_{k−1}/∂v − A(s_k)ᵀ dexp⁻¹(−h_{k−1}ξ_{k−1})ᵀ μ_{k−1}.
        let xi_prev = -(sys.connection(&s_prev) * v_prev);
        let inc = dl_dv::<S, T, DOF, NS, NU>(sys, &s_prev, &v_prev, &xi_prev)
            - a_k.transpose()
                * (dexp_inv(&(xi_prev * (-h_prev))).transpose()
                    * dl_dxi::<S, T, DOF, NS, NU>(sys, &s_prev, &v_prev, &xi_prev));
        (out - inc) / h - sys.forcing(&s, &v, &u)
    }
    /// Inside a segment (both ratios of the stage equal, as the solver keeps the copies of
    /// one global) the residual is the fixed-step one at `h = σ h̄` ([`Self::equality`]'s
    /// docs), so its partials in `x` and `(v_k, u_k)` are the fixed transcription's
    /// structured ones at that step ([`VarIntStages::first_order_equality_partials`]), and
    /// one vector-dual pass of two lanes gives the ratios' columns. At a segment's first
    /// stage the two steps differ: both passes of the generic path. Why: the generic path
    /// seeds all of `x` and `w` in nested duals (three evaluations of `ℓ` per momentum),
    /// most of a free iteration's derivative pass.
    fn equality_jacobian(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NWT>,
    ) -> (
        SVector<f64, NS>,
        SMatrix<f64, NS, NX>,
        SMatrix<f64, NS, NWT>,
    ) {
        // The value as the line search measures it (see `VarIntStages::equality_jacobian`).
        let e = self.equality(k, x, w);
        let (ex, ew) = self.equality_partials(k, x, w);
        (e, ex, ew)
    }
    fn equality_partials(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NWT>,
    ) -> (SMatrix<f64, NS, NX>, SMatrix<f64, NS, NWT>) {
        let (sigma_prev, sigma) = (w[NWT - 2], w[NWT - 1]);
        if sigma_prev != sigma {
            let (_, ex, ew) = generic_equality_jacobian(self, k, x, w);
            return (ex, ew);
        }
        let st = &self.plan.stages;
        let at_step = VarIntStages {
            h: sigma * st.h,
            ..*st
        };
        let (ex, mut ew) = at_step.first_order_equality_partials::<DOF, NS, NU, NX, NWT>(x, w);
        // w's last two entries (the ratios) seeded, the rest constant.
        let ratios_seeded =
            SVector::<DualSVec64<2>, NWT>::from_fn(|i, _| match i.checked_sub(NWT - 2) {
                Some(lane) => {
                    let mut eps = SVector::<f64, 2>::zeros();
                    eps[lane] = 1.0;
                    DualVec::new(w[i], Derivative::some(eps))
                }
                None => DualSVec64::<2>::from_re(w[i]),
            });
        let r = self.equality(k, &lift_vec::<f64, 2, NX>(x), &ratios_seeded);
        let dr = jacobian_part(&r);
        ew.fixed_columns_mut::<2>(NWT - 2).copy_from(&dr);
        (ex, ew)
    }
    /// When the robot's problem is affine in its configuration and previous input, and
    /// those multiply neither velocity nor input ([`PlanningProblem::affine_in_configuration`];
    /// the step ratio enters through `cost_at_step` and `constraints_at_step`, which keep
    /// that form for a fixed ratio), `s ℓ_k + ζᵀc_k` is affine in `x` for a fixed `w`, and
    /// `x` meets `w` only through the ratios (a cost per stage times `σ_k`, a rate limit
    /// divided by it). So `∇²_xx = 0`, `∇²_xw` has only the ratios' two columns (one
    /// hyper-dual pass, `x` against the ratios), and `∇²_ww` takes one second-order pass
    /// over `w`. Why: the generic route's `xx` pass over all of `x` and its `xw` pass
    /// against all of `w` were most of the curvature's cost. Otherwise the generic route.
    fn cost_curvature(
        &self,
        k: usize,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NWT>,
        cost_scale: f64,
        zeta: &SVector<f64, NC>,
    ) -> HessianBlocks<NX, NWT> {
        if !self.plan.problem.affine_in_configuration() {
            return generic_cost_curvature(self, k, x, w, cost_scale, zeta);
        }
        let hww = hess2(&cost_and_inequalities(
            self,
            k,
            cost_scale,
            zeta,
            &x.map(Dual2SVec64::<NWT>::from_re),
            &seed2(w),
        ));
        let ratios: SVector<f64, 2> = w.fixed_rows::<2>(NWT - 2).into_owned();
        let (xh, rh) = seed_hyper(x, &ratios);
        let wh =
            SVector::<HyperDualSVec64<NX, 2>, NWT>::from_fn(|i, _| match i.checked_sub(NWT - 2) {
                Some(j) => rh[j],
                None => HyperDualSVec64::<NX, 2>::from_re(w[i]),
            });
        let mut hxw = SMatrix::<f64, NX, NWT>::zeros();
        let xr = cost_and_inequalities(self, k, cost_scale, zeta, &xh, &wh);
        if let Some(hxr) = xr.eps1eps2.0 {
            hxw.fixed_columns_mut::<2>(NWT - 2).copy_from(&hxr);
        }
        (SMatrix::zeros(), hxw, hww)
    }
    fn cost<T: Real>(&self, k: usize, x: &SVector<T, NX>, w: &SVector<T, NWT>) -> T {
        let stage = self.plan.stage(x, w);
        self.plan.problem.cost_at_step(k, &stage, w[NWT - 1])
    }
    fn constraints<T: Real>(
        &self,
        k: usize,
        x: &SVector<T, NX>,
        w: &SVector<T, NWT>,
    ) -> SVector<T, NC> {
        let stage = self.plan.stage(x, w);
        self.plan.problem.constraints_at_step(k, &stage, w[NWT - 1])
    }
    fn bounds(&self, k: usize) -> (SVector<f64, NC>, SVector<f64, NC>) {
        self.plan.problem.bounds(k)
    }
    fn state_equalities(&self) -> Vec<StateEquality> {
        // The first-order scheme only (checked in `new`): the conditions as they are.
        crate::transcription::state_equalities(
            self.plan.stages.layout,
            &self.plan.scheme_conditions().state,
        )
    }
    fn globals(&self) -> Option<Globals> {
        let m = self.segments();
        let counts = self.segment_steps();
        let n = self.segment_of.len();
        let (lo, hi) = self.timing.ratio_bounds;
        let (equalities, cost) = match self.timing.total {
            TotalTime::Fixed => (
                vec![GlobalEquality {
                    a: counts.iter().map(|&c| c as f64).collect(),
                    b: n as f64,
                }],
                vec![0.0; m],
            ),
            TotalTime::Priced(per_second) => (
                Vec::new(),
                counts
                    .iter()
                    .map(|&c| per_second * c as f64 * self.plan.stages.h)
                    .collect(),
            ),
        };
        let support = (0..n)
            .flat_map(|k| [self.segment_of[k.saturating_sub(1)], self.segment_of[k]])
            .collect();
        Some(Globals {
            start: vec![1.0; m],
            lo: vec![lo; m],
            hi: vec![hi; m],
            equalities,
            cost,
            per_stage: 2,
            support,
        })
    }
}

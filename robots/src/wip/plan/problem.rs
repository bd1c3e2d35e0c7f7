//! The WIP's energy-optimal planning problem (paper eq. (opt), `docs/problems.md`) declared
//! for the generic solver of `dmech-ocp`: cost, bounds, waypoints, boundary states.
//!
//! Two models ([`PlanModel`]): the full WIP (`NS = 5`, shape `(α, φR, φL, qR, qL)`, the
//! currents are shape velocities) and the algebraic-current WIP (`NS = 3`, the currents
//! follow from `v` and `u`). Stage layout of both transcriptions, `NX = 2 NS + 5`:
//! `x = (x, y, θ, s(NS), v(NS), u_prev(2))`, where `v` is `v_{k−1}` for the variational
//! integrator and `v_k` for Runge–Kutta. The VI decides `w = (v_k, u_k)`, RK decides
//! `w = u_k`. The VI plans leave the positions of the ignorable shape coordinates out of
//! `s` (the wheel angles, and the charges of the full model): `NX_VI = 11`,
//! `NX_VI_ALGEBRAIC = 9` ([`varint_layout`]).

use crate::wip::algebraic_current::WipAlgebraicCurrent;
use crate::wip::plan::problems::PlanProblem;
use crate::wip::Wip;
use dmech::{Discretisation, PrincipalKinematicSystem, RungeKutta};
use dmech_lie::Real;
use dmech_ocp::transcription::layout::Layout;
use dmech_ocp::transcription::{
    Condition, PlanningProblem, Quantity, RkTranscription, Stage, StartState, VarIntTranscription,
};
use nalgebra::SVector;

/// Stage state size of the full model (`NS = 5`).
pub const NX: usize = 15;
/// Stage state size of the algebraic-current model (`NS = 3`).
pub const NX_ALGEBRAIC: usize = 11;
/// The VI plans' state size of the full model: without the positions of the wheel
/// angles and the charges, which its equations of motion do not read
/// ([`PrincipalKinematicSystem::ignorable_shape`]; `docs/ocp.md`).
pub const NX_VI: usize = 11;
/// The same for the algebraic-current model: without the wheel angles.
pub const NX_VI_ALGEBRAIC: usize = 9;
/// Inequalities per stage: uR, uL, the rates (uR_k − uR_{k−1})/h and (uL_k − uL_{k−1})/h, iR, iL, α, v_θ.
pub const NC: usize = 8;

/// `d_0` of the first (smoothed-friction) phase, s/rad.
pub const SMOOTH_FRICTION_SLOPE: f64 = 1.0;

/// A WIP model the planner transcribes: what differs between the current models.
pub trait PlanModel<const NS: usize>:
    PrincipalKinematicSystem<3, NS, 2, Param = f64> + Clone + PartialEq + Sync
{
    /// Whether the currents are states with their (stiff) dynamics; if not, the outcome
    /// reconstructs currents and charges from `currents`.
    const CURRENT_DYNAMICS: bool;
    /// The mechanics and parameters shared by all models.
    fn wip(&self) -> &Wip;
    fn wip_mut(&mut self) -> &mut Wip;
    /// The currents `(iR, iL)` at shape velocity `v_k` and voltages `u_k`.
    fn currents<T: Real>(&self, v: &SVector<T, NS>, u: &SVector<T, 2>) -> [T; 2];
    /// A shape velocity with whatever the model holds of the currents set to their steady
    /// state for `u = 0` (the starts' velocities come from kinematics alone).
    fn settle_currents(&self, v: &mut SVector<f64, NS>);
}

impl PlanModel<5> for Wip {
    const CURRENT_DYNAMICS: bool = true;
    fn wip(&self) -> &Wip {
        self
    }
    fn wip_mut(&mut self) -> &mut Wip {
        self
    }
    fn currents<T: Real>(&self, v: &SVector<T, 5>, _u: &SVector<T, 2>) -> [T; 2] {
        [v[3], v[4]]
    }
    fn settle_currents(&self, v: &mut SVector<f64, 5>) {
        let q = &self.params;
        v[3] = q.steady_current(0.0, v[1] - v[0]);
        v[4] = q.steady_current(0.0, v[2] - v[0]);
    }
}

impl PlanModel<3> for WipAlgebraicCurrent {
    const CURRENT_DYNAMICS: bool = false;
    fn wip(&self) -> &Wip {
        &self.wip
    }
    fn wip_mut(&mut self) -> &mut Wip {
        &mut self.wip
    }
    fn currents<T: Real>(&self, v: &SVector<T, 3>, u: &SVector<T, 2>) -> [T; 2] {
        WipAlgebraicCurrent::currents(self, v, u)
    }
    fn settle_currents(&self, _v: &mut SVector<f64, 3>) {}
}

/// The bounds of docs/problems.md.
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
pub struct WipPlan<'a, M> {
    pub model: &'a M,
    pub problem: &'a PlanProblem,
    pub bounds: PlanBounds,
}

impl<M> WipPlan<'_, M> {
    fn bounds_vec(&self) -> (SVector<f64, NC>, SVector<f64, NC>) {
        let b = &self.bounds;
        let hi = SVector::<f64, NC>::from_column_slice(&[
            b.u_max,
            b.u_max,
            b.du_max_per_s,
            b.du_max_per_s,
            b.i_max,
            b.i_max,
            b.alpha_max,
            b.v_theta_max,
        ]);
        (-hi, hi)
    }

    /// Waypoint positions at their stages; at the end the full pose, `α = 0` and the
    /// arriving shape velocity zero (velocities and, in the full model, currents).
    fn conditions<const NS: usize>(&self) -> Vec<Condition> {
        let p = self.problem;
        let mut conds = Vec::new();
        for (pt, &k) in p.points.iter().zip(&p.stages) {
            if k == 0 || k == p.n {
                continue;
            }
            for (i, &value) in pt.iter().enumerate() {
                conds.push(Condition {
                    stage: k,
                    quantity: Quantity::Pose(i),
                    value,
                });
            }
        }
        let end = p.points.last().expect("at least two points");
        let mut fix = |quantity, value| {
            conds.push(Condition {
                stage: p.n,
                quantity,
                value,
            })
        };
        fix(Quantity::Pose(0), end[0]);
        fix(Quantity::Pose(1), end[1]);
        fix(Quantity::Pose(2), p.end_heading);
        fix(Quantity::Shape(0), 0.0);
        for i in 0..NS {
            fix(Quantity::Velocity(i), 0.0);
        }
        conds
    }
}

impl<M> WipPlan<'_, M> {
    /// `v_θ` from the wheel rates.
    fn heading_rate<T: Real, const NS: usize>(&self, vr: T, vl: T) -> T
    where
        M: PlanModel<NS>,
    {
        let p = &self.model.wip().params;
        (vr - vl) * (p.r / (2.0 * p.d))
    }

    /// The inequalities at shape velocity `v`, tilt `alpha`, voltages `u` after `u_prev`.
    fn constraints<T: Real, const NS: usize>(
        &self,
        v: &SVector<T, NS>,
        alpha: T,
        u: &SVector<T, 2>,
        u_prev: [T; 2],
    ) -> SVector<T, NC>
    where
        M: PlanModel<NS>,
    {
        let [ir, il] = self.model.currents(v, u);
        // The rate limit as a rate, `(u_k − u_{k−1})/h ≤ 2 V/s`: the bound as a difference,
        // `2h`, shrinks with the step (0.0025 V at 1.25 ms) and the barrier, on the scale
        // of the other bounds, then holds these constraints far inside it.
        let rate = 1.0 / self.problem.h;
        SVector::<T, NC>::from_column_slice(&[
            u[0],
            u[1],
            (u[0] - u_prev[0]) * rate,
            (u[1] - u_prev[1]) * rate,
            ir,
            il,
            alpha,
            self.heading_rate::<T, NS>(v[1], v[2]),
        ])
    }

    /// The running cost `½ (uR iR + uL iL)`.
    fn cost<T: Real, const NS: usize>(&self, v: &SVector<T, NS>, u: &SVector<T, 2>) -> T
    where
        M: PlanModel<NS>,
    {
        let [ir, il] = self.model.currents(v, u);
        (u[0] * ir + u[1] * il) * 0.5
    }
}

/// The WIP's problem in the toolkit's terms: cost and inequalities read the stage's
/// velocity, tilt, inputs and previous inputs; waypoints and the end state are conditions.
impl<M: PlanModel<NS>, const NS: usize> PlanningProblem<3, NS, 2, NC> for WipPlan<'_, M> {
    fn horizon(&self) -> usize {
        self.problem.n
    }
    fn start(&self) -> StartState<3, NS, 2> {
        let p = self.problem;
        StartState::at_rest(
            SVector::<f64, 3>::new(p.points[0][0], p.points[0][1], p.start_heading),
            SVector::zeros(),
        )
    }
    fn cost<T: Real>(&self, _k: usize, stage: &Stage<T, 3, NS, 2>) -> T {
        self.cost(&stage.velocity, &stage.input)
    }
    fn constraints<T: Real>(&self, _k: usize, stage: &Stage<T, 3, NS, 2>) -> SVector<T, NC> {
        let u_prev = [stage.previous_input[0], stage.previous_input[1]];
        self.constraints(&stage.velocity, stage.shape[0], &stage.input, u_prev)
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, NC>, SVector<f64, NC>) {
        self.bounds_vec()
    }
    fn conditions(&self) -> Vec<Condition> {
        self.conditions::<NS>()
    }
    fn affine_in_configuration(&self) -> bool {
        // The cost reads velocity and input only; the inequalities read α and u_{k−1}
        // linearly.
        true
    }
    fn quadratic_cost_affine_constraints(&self) -> bool {
        // The cost `½ u·i` with currents linear in (v, u) (the charges' rates, or the
        // steady currents `(u − k_e n ω)/R`); voltages, rates, currents, tilt and heading
        // rate are linear.
        true
    }
    /// The rate limit divides by the stage's actual step; the cost is the default's
    /// `ratio · cost` (the energy of the stage at its step, in units of the nominal one).
    fn constraints_at_step<T: Real>(
        &self,
        k: usize,
        stage: &Stage<T, 3, NS, 2>,
        ratio: T,
    ) -> SVector<T, NC> {
        let mut c = PlanningProblem::constraints(self, k, stage);
        c[2] /= ratio;
        c[3] /= ratio;
        c
    }
}

/// The WIP on a variational integrator (first order or midpoint), state size `NX`
/// ([`varint_layout`]), decision size `NW = NS + 2`.
pub type VarIntPlan<'a, M, const NS: usize, const NX: usize, const NW: usize> =
    VarIntTranscription<'a, M, WipPlan<'a, M>, 3, 3, NS, 2, NX, NW>;

/// The WIP on a Runge–Kutta step, state size `NX = 2 NS + 5`.
pub type RkPlan<'a, M, const NS: usize, const NX: usize> =
    RkTranscription<'a, M, WipPlan<'a, M>, 3, 3, NS, 2, NX>;

/// The VI stage layout for state size `NX`: every shape position (`NX = 2 NS + 5`), or
/// without the model's ignorable ones.
pub fn varint_layout<M: PlanModel<NS>, const NS: usize, const NX: usize>(model: &M) -> Layout {
    let full = Layout::new(3, NS, 2);
    if NX == full.nx() {
        return full;
    }
    let reduced = full.ignoring(model.ignorable_shape());
    assert_eq!(
        NX,
        reduced.nx(),
        "a VI state of the model has {} or {} entries",
        full.nx(),
        reduced.nx()
    );
    reduced
}

/// The VI plan of `problem` for `model` with the state of size `NX` ([`varint_layout`]):
/// the paper's transcription with [`Discretisation::FirstOrder`].
pub fn varint_plan<'a, M: PlanModel<NS>, const NS: usize, const NX: usize, const NW: usize>(
    model: &'a M,
    problem: &'a PlanProblem,
    bounds: PlanBounds,
    discretisation: Discretisation,
) -> VarIntPlan<'a, M, NS, NX, NW> {
    let plan = WipPlan {
        model,
        problem,
        bounds,
    };
    let layout = varint_layout::<M, NS, NX>(model);
    VarIntTranscription::with_layout(model, plan, problem.h, discretisation, layout)
        .unwrap_or_else(|e| panic!("the WIP's VI sizes: {e}"))
}

/// The RK plan of `problem` for `model`.
pub fn rk_plan<'a, M: PlanModel<NS>, const NS: usize, const NX: usize>(
    model: &'a M,
    problem: &'a PlanProblem,
    bounds: PlanBounds,
    rk: RungeKutta,
) -> RkPlan<'a, M, NS, NX> {
    let plan = WipPlan {
        model,
        problem,
        bounds,
    };
    RkTranscription::with_sizes(model, plan, problem.h, rk)
        .unwrap_or_else(|e| panic!("the WIP's RK sizes: {e}"))
}

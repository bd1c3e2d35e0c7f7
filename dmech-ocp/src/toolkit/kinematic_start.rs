//! A start for planning from a geometric pose path: the shape motion that realises the
//! path through the connection, found by the solver itself, and the variational
//! transcription's start built from it.
//!
//! A nonholonomic robot cannot follow an arbitrary pose path: its body velocity is
//! `ξ = −A(s) v`. Given the path's poses `g_k` (e.g. a smooth curve with the heading along
//! its tangent), the path's body velocities are `ξ̄_k = log(g_k⁻¹ g_{k+1})/h`, and the shape
//! path is the least-squares solution of
//! ```text
//! min Σ_k |ξ̄_k + A(s_k + ½h v_k) v_k|² + Σ_i ρ_i v_{k,i}²,    s_{k+1} = s_k + h v_k,  s_0 given,
//! ```
//! a stage-structured problem with no constraints, solved by the same interior point
//! (Riccati recursion, exact derivatives). Shape variables that do not enter `A` (a
//! steering angle, say) are still determined where they change `A` along the path: the
//! residual at stage `k` depends on `s_k` through `A`. The weights `ρ_i` (the robot's:
//! they carry its units) keep the rest smooth and at rest where the path says nothing (a
//! charge, or the steering while standing), and a variable that `A` reads through a
//! periodic function (a steering angle through `tan`) on the branch it starts on.
//!
//! The start then rolls the poses forward from `g_0` with the solved shape motion, so it
//! satisfies the transcription's dynamics exactly and the path only approximately; the
//! inputs are zero.
//!
//! # Example
//!
//! A differential drive on a straight path at 0.5 m/s: both wheels turn at `0.5 / r` = 10 rad/s (r = 0.05 m).
//! ```
//! # use dmech::{Lift, PrincipalKinematicSystem};
//! # use dmech_lie::{Real, Se2};
//! # use nalgebra::{SMatrix, SVector};
//! # struct DiffDrive;
//! # impl PrincipalKinematicSystem<3, 2, 2> for DiffDrive {
//! #     type Param = f64;
//! #     type Group<T: Real> = Se2<T>;
//! #     fn reduced_lagrangian<T: Lift<f64>>(&self, _s: &SVector<T, 2>, v: &SVector<T, 2>, xi: &SVector<T, 3>) -> T {
//! #         (xi.dot(xi) + v.dot(v) * 1e-3) * 0.5
//! #     }
//! #     fn connection<T: Lift<f64>>(&self, _s: &SVector<T, 2>) -> SMatrix<T, 3, 2> {
//! #         let (half_r, yaw, z) = (T::from(0.025), T::from(0.25), T::zero());
//! #         SMatrix::<T, 3, 2>::new(-half_r, -half_r, z, z, -yaw, yaw)
//! #     }
//! #     fn forcing<T: Lift<f64>>(&self, _s: &SVector<T, 2>, _v: &SVector<T, 2>, u: &SVector<T, 2>) -> SVector<T, 2> { *u }
//! # }
//! use dmech_ocp::toolkit::kinematic_start::shape_motion;
//! let h = 0.02;
//! let path: Vec<Se2<f64>> = (0..=50).map(|k| Se2::new(0.5 * h * k as f64, 0.0, 0.0)).collect();
//! let weights = SVector::<f64, 2>::repeat(1e-9);
//! let motion = shape_motion(&DiffDrive, h, &path, &SVector::zeros(), &weights)?;
//! let v = &motion.velocities;
//! assert!(v.iter().all(|vk| (vk[0] - 10.0).abs() < 1e-3 && (vk[1] - 10.0).abs() < 1e-3));
//! assert!((motion.shapes[50][0] - 10.0).abs() < 1e-3); // 1 s at 10 rad/s
//! # Ok::<(), dmech_ocp::toolkit::kinematic_start::KinematicStartError>(())
//! ```

use crate::nlp::{StageProblem, StateEquality};
use crate::solver::{IpOptions, SolveResult, Solver, Status};
use crate::transcription::layout::Layout;
use dmech::PrincipalKinematicSystem;
use dmech_lie::{LieGroup, Real};
use nalgebra::SVector;
use std::marker::PhantomData;

/// The least-squares problem of the module's documentation: `x_k = s_k`, `w_k = v_k`.
pub struct KinematicPath<'a, S, const DOF: usize, const NU: usize> {
    /// The system.
    pub sys: &'a S,
    /// The step.
    pub h: f64,
    /// `ξ̄_k`, one per step.
    pub body_velocities: Vec<SVector<f64, DOF>>,
    /// `ρ_i`, one per shape velocity.
    pub regularisation: Vec<f64>,
    s0: Vec<f64>,
    _nu: PhantomData<[(); NU]>,
}

impl<'a, S, const DOF: usize, const NU: usize> KinematicPath<'a, S, DOF, NU> {
    /// The problem for the pose path `poses` (`N + 1` poses at step `h`) from shape `s0`.
    pub fn new<const NS: usize>(
        sys: &'a S,
        h: f64,
        poses: &[S::Group<f64>],
        s0: &SVector<f64, NS>,
        regularisation: &SVector<f64, NS>,
    ) -> Self
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let body_velocities = poses
            .windows(2)
            .map(|p| p[0].inverse().compose(&p[1]).log() / h)
            .collect();
        KinematicPath {
            sys,
            h,
            body_velocities,
            regularisation: regularisation.iter().copied().collect(),
            s0: s0.iter().copied().collect(),
            _nu: PhantomData,
        }
    }
}

impl<S, const DOF: usize, const NS: usize, const NU: usize> StageProblem<NS, NS, 0, NS, 0>
    for KinematicPath<'_, S, DOF, NU>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64> + Sync,
{
    fn horizon(&self) -> usize {
        self.body_velocities.len()
    }
    fn initial_state(&self) -> SVector<f64, NS> {
        SVector::from_fn(|i, _| self.s0[i])
    }
    fn dynamics<T: Real>(
        &self,
        _k: usize,
        s: &SVector<T, NS>,
        v: &SVector<T, NS>,
    ) -> SVector<T, NS> {
        s + v * T::from(self.h)
    }
    fn equality<T: Real>(
        &self,
        _k: usize,
        _s: &SVector<T, NS>,
        _v: &SVector<T, NS>,
    ) -> SVector<T, 0> {
        SVector::zeros()
    }
    fn cost<T: Real>(&self, k: usize, s: &SVector<T, NS>, v: &SVector<T, NS>) -> T {
        let mid = s + v * T::from(0.5 * self.h);
        let r = self.body_velocities[k].map(T::from) + self.sys.connection(&mid) * v;
        let mut c = r.dot(&r);
        for i in 0..NS {
            c += v[i] * v[i] * self.regularisation[i];
        }
        c
    }
    fn constraints<T: Real>(
        &self,
        _k: usize,
        _s: &SVector<T, NS>,
        _v: &SVector<T, NS>,
    ) -> SVector<T, 0> {
        SVector::zeros()
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, 0>, SVector<f64, 0>) {
        (SVector::zeros(), SVector::zeros())
    }
    fn state_equalities(&self) -> Vec<StateEquality> {
        Vec::new()
    }
}

/// Why a kinematic start could not be built: the least-squares solve for the shape motion
/// ended with `status`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("the shape motion along the start path was not found ({})", .status.code())]
pub struct KinematicStartError {
    /// How the shape-motion solve ended.
    pub status: Status,
}

/// The shape motion that realises a pose path: `s_0 … s_N` and `v_0 … v_{N−1}`.
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeMotion<const NS: usize> {
    /// The shape at each stage, `N + 1` of them.
    pub shapes: Vec<SVector<f64, NS>>,
    /// The shape velocity over each step, `N` of them.
    pub velocities: Vec<SVector<f64, NS>>,
}

impl<const NS: usize> ShapeMotion<NS> {
    /// The motion with a rest-to-rest oscillation added to each shape coordinate:
    /// `a_i sin²(π t/T) sin(2π c t/T + iπ/2)` over the horizon `T = N h` (`c = cycles`),
    /// velocities the differences of the shapes. Zero at both ends with its velocity, so
    /// a start at rest stays at rest and so does the end.
    ///
    /// What it is for: a system whose free directions gain momentum only from two shape
    /// velocities together (the snakeboard's rotor and axles) has, along a motion in which
    /// one of them rests, a momentum equation whose linearisation does not see the other,
    /// and Newton's method cannot leave such a start. Shifted by a quarter period from one
    /// coordinate to the next, the oscillations drive no net motion of their own; they
    /// only make the linearisation see every coordinate.
    pub fn excited(&self, h: f64, amplitudes: &SVector<f64, NS>, cycles: f64) -> Self {
        use std::f64::consts::{FRAC_PI_2, PI, TAU};
        let n = self.velocities.len();
        let offset = |k: usize| {
            let tau = k as f64 / n as f64;
            let window = (PI * tau).sin().powi(2);
            SVector::<f64, NS>::from_fn(|i, _| {
                amplitudes[i] * window * (TAU * cycles * tau + FRAC_PI_2 * i as f64).sin()
            })
        };
        ShapeMotion {
            shapes: (0..=n).map(|k| self.shapes[k] + offset(k)).collect(),
            velocities: (0..n)
                .map(|k| self.velocities[k] + (offset(k + 1) - offset(k)) / h)
                .collect(),
        }
    }
}

/// Solves [`KinematicPath`] for `poses`: the shape motion that realises them.
pub fn shape_motion<S, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    h: f64,
    poses: &[S::Group<f64>],
    s0: &SVector<f64, NS>,
    regularisation: &SVector<f64, NS>,
) -> Result<ShapeMotion<NS>, KinematicStartError>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64> + Sync,
{
    let problem = KinematicPath::<S, DOF, NU>::new(sys, h, poses, s0, regularisation);
    let n = problem.body_velocities.len();
    let opts = IpOptions {
        verbose: false,
        ..IpOptions::default()
    };
    let solver: Solver<NS, NS, 0, NS, 0> = Solver::new(&problem, opts);
    // The solver starts from the stage-wise answer: `v_k` the regularised least-squares
    // solution at `s_k` alone, `s_{k+1} = s_k + h v_k`. From `v = 0` the residual does not
    // see the shape variables that act through `A` (their derivative multiplies `v`), and
    // the first Newton step moves them almost freely (a steering angle jumped a branch).
    let mut xs = vec![*s0; n + 1];
    let mut ws = vec![SVector::<f64, NS>::zeros(); n];
    for k in 0..n {
        let a = sys.connection(&xs[k]);
        let normal = a.transpose() * a
            + nalgebra::SMatrix::<f64, NS, NS>::from_diagonal(&SVector::from_fn(|i, _| {
                regularisation[i]
            }));
        let rhs = -(a.transpose() * problem.body_velocities[k]);
        ws[k] =
            dmech_lie::linalg::Lu::new(&normal).map_or_else(SVector::zeros, |lu| lu.solve(&rhs));
        xs[k + 1] = xs[k] + ws[k] * h;
    }
    let r: SolveResult<NS, NS, 0> = solver.solve(solver.initial_iterate(xs, ws));
    if r.status != Status::Solved {
        return Err(KinematicStartError { status: r.status });
    }
    Ok(ShapeMotion {
        shapes: r.iterate.x,
        velocities: r.iterate.w,
    })
}

/// The variational transcription's start in `layout` (`x_k = (coords(g_k), s_k, v_{k−1},
/// u_{k−1})` with the layout's carried shape positions, `w_k = (v_k, u_k)`, inputs zero)
/// from the pose path `poses`: the shape motion of [`shape_motion`], rolled forward from
/// `poses[0]` by [`varint_start_from_motion`]. The transcriptions call it as
/// [`VarIntTranscription::start_from_path`](crate::transcription::VarIntTranscription::start_from_path).
#[allow(clippy::type_complexity)]
pub(crate) fn varint_start_in_layout<
    S,
    const DOF: usize,
    const NS: usize,
    const NU: usize,
    const NX: usize,
    const NW: usize,
>(
    sys: &S,
    h: f64,
    poses: &[S::Group<f64>],
    s0: &SVector<f64, NS>,
    regularisation: &SVector<f64, NS>,
    discretisation: dmech::Discretisation,
    layout: Layout,
) -> Result<(Vec<SVector<f64, NX>>, Vec<SVector<f64, NW>>), KinematicStartError>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64> + Sync,
{
    let motion = shape_motion(sys, h, poses, s0, regularisation)?;
    Ok(varint_start_from_motion::<S, DOF, NS, NU, NX, NW>(
        sys,
        h,
        &poses[0],
        &motion,
        discretisation,
        layout,
    ))
}

/// The variational transcription's start in `layout` from a shape motion: poses rolled
/// forward from `g0` by the scheme's group update (`ξ_k = −A(s_k + c h v_k) v_k`, `c = 0`
/// first order, `½` midpoint), so that the start satisfies the transcription's pose and
/// shape dynamics exactly; inputs zero. The transcriptions call it as
/// [`VarIntTranscription::start_from_motion`](crate::transcription::VarIntTranscription::start_from_motion).
#[allow(clippy::type_complexity)]
pub(crate) fn varint_start_from_motion<
    S,
    const DOF: usize,
    const NS: usize,
    const NU: usize,
    const NX: usize,
    const NW: usize,
>(
    sys: &S,
    h: f64,
    g0: &S::Group<f64>,
    motion: &ShapeMotion<NS>,
    discretisation: dmech::Discretisation,
    layout: Layout,
) -> (Vec<SVector<f64, NX>>, Vec<SVector<f64, NW>>)
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    let (s, v) = (&motion.shapes, &motion.velocities);
    let shift = match discretisation {
        dmech::Discretisation::FirstOrder => 0.0,
        dmech::Discretisation::Midpoint => 0.5 * h,
    };
    let mut g = *g0;
    let mut xs = Vec::with_capacity(s.len());
    for k in 0..s.len() {
        let mut x = SVector::<f64, NX>::zeros();
        for (i, c) in g.coordinates().iter().enumerate() {
            x[i] = *c;
        }
        layout.set_shape(&mut x, &s[k]);
        if k > 0 {
            x.fixed_rows_mut::<NS>(layout.v_at()).copy_from(&v[k - 1]);
        }
        xs.push(x);
        if k < v.len() {
            let xi = -(sys.connection(&(s[k] + v[k] * shift)) * v[k]);
            g = g.compose(&<S::Group<f64> as LieGroup<DOF>>::exp(&(xi * h)));
        }
    }
    let ws = v
        .iter()
        .map(|vk| SVector::<f64, NW>::from_fn(|i, _| if i < NS { vk[i] } else { 0.0 }))
        .collect();
    (xs, ws)
}

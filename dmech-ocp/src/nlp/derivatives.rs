//! Exact stage derivatives of a [`StageProblem`] by dual numbers.
//!
//! Jacobians of the cost and the inequalities come from two vector-dual passes (seeded in
//! `x`, then in `w`); those of the dynamics and the stage equality from the problem's
//! [`StageProblem::dynamics_jacobian`] and [`StageProblem::equality_jacobian`]. The Hessian of
//! `Φ = ℓ_k + ζᵀ c_k` (cost plus inequality curvature, `ζ` the inequality multipliers)
//! comes from three second-order passes (`xx`, `ww` by `Dual2`, `xw` by hyper-duals).
//! The curvature of the dynamics and of the stage equality, `∇²(λᵀf + νᵀe)`, is formed only
//! when the exact Hessian is asked for ([`StageProblem::constraint_curvature`]); by default
//! the solver approximates it by SR1 from the Jacobians (`docs/solver.md`).

use crate::nlp::{HessianBlocks, StageProblem};
use dmech_lie::dual::{grad_part as grad, jacobian_part, seeded as seed, split_passes};
use dmech_lie::linalg::Lu;
use nalgebra::{SMatrix, SVector};
use num_dual::{Derivative, Dual2SVec64, DualSVec64, HyperDualSVec64};

/// What a solver computes once per stage for a problem whose derivatives are partly
/// constant: the cost's curvature ([`StageProblem::constant_cost_curvature`]) and, when the
/// cost and inequalities are also affine in the state ([`StageProblem::affine_in_state`]),
/// their state gradients `(∇_x ℓ_k, C_x)`, constant then too.
#[derive(Clone, Debug, PartialEq)]
pub struct StageConstants<const NX: usize, const NW: usize, const NC: usize> {
    /// The cost's and inequalities' curvature.
    pub curvature: HessianBlocks<NX, NW>,
    /// `(∇_x ℓ_k, C_x)`, when they are constant too.
    pub state_gradients: Option<(SVector<f64, NX>, SMatrix<f64, NC, NX>)>,
}

/// Every stage's [`StageConstants`], each distinct value stored once: stages with the same
/// cost and inequalities have the same constants, and one copy stays in cache where one
/// per stage (3 kB each, 13 MB on the eight) was read from memory at every derivative
/// pass.
#[derive(Clone, Debug, Default)]
pub struct ConstantsTable<const NX: usize, const NW: usize, const NC: usize> {
    distinct: Vec<StageConstants<NX, NW, NC>>,
    of_stage: Vec<usize>,
}

impl<const NX: usize, const NW: usize, const NC: usize> ConstantsTable<NX, NW, NC> {
    /// The table of `per_stage` (stage order), runs of equal values (as `==` on floats)
    /// stored once (cloned: only the distinct values are copied).
    pub fn new<'a>(per_stage: impl IntoIterator<Item = &'a StageConstants<NX, NW, NC>>) -> Self {
        let mut table = ConstantsTable {
            distinct: Vec::new(),
            of_stage: Vec::new(),
        };
        // The same item as the previous stage's is in the last run without a comparison
        // (a solver's stages mostly share one value: comparing each, 3 kB of floats, on
        // one thread was 0.5 % of the eight).
        let mut previous: Option<&StageConstants<NX, NW, NC>> = None;
        for c in per_stage {
            let same_item = previous.is_some_and(|p| std::ptr::eq(p, c));
            if !same_item && table.distinct.last() != Some(c) {
                table.distinct.push(c.clone());
            }
            table.of_stage.push(table.distinct.len() - 1);
            previous = Some(c);
        }
        table
    }

    /// Stage `k`'s constants (`None` past the last stage, and for an empty table).
    pub fn get(&self, k: usize) -> Option<&StageConstants<NX, NW, NC>> {
        self.of_stage.get(k).map(|&i| &self.distinct[i])
    }

    /// The number of distinct values stored.
    pub fn distinct(&self) -> usize {
        self.distinct.len()
    }
}

/// `ℓ_k` and `c_k` in vector duals seeded in `x`: their values and state gradients.
pub(crate) fn state_pass<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    p: &P,
    k: usize,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
) -> (DualSVec64<NX>, SVector<DualSVec64<NX>, NC>)
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    let xd = seed(x);
    let wc = w.map(DualSVec64::<NX>::from_re);
    (p.cost(k, &xd, &wc), p.constraints(k, &xd, &wc))
}

/// Values and first derivatives at one stage, and the Hessian of `ℓ + ζᵀc`.
#[derive(Clone, Debug)]
pub struct StageDerivatives<const NX: usize, const NW: usize, const NE: usize, const NC: usize> {
    /// The dynamics `f_k(x, w)`.
    pub f: SVector<f64, NX>,
    /// `∂f/∂x`.
    pub fx: SMatrix<f64, NX, NX>,
    /// `∂f/∂w`.
    pub fw: SMatrix<f64, NX, NW>,
    /// The stage equality `e_k(x, w)`.
    pub e: SVector<f64, NE>,
    /// `∂e/∂x`.
    pub ex: SMatrix<f64, NE, NX>,
    /// `∂e/∂w`.
    pub ew: SMatrix<f64, NE, NW>,
    /// The cost `ℓ_k(x, w)`.
    pub cost: f64,
    /// `∇_x ℓ_k`.
    pub gx: SVector<f64, NX>,
    /// `∇_w ℓ_k`.
    pub gw: SVector<f64, NW>,
    /// The inequalities `c_k(x, w)`.
    pub c: SVector<f64, NC>,
    /// `∂c/∂x`.
    pub cx: SMatrix<f64, NC, NX>,
    /// `∂c/∂w`.
    pub cw: SMatrix<f64, NC, NW>,
    /// `∇²_xx` of `ℓ + ζᵀc` (with the exact Hessian, `+ λᵀf + νᵀe`).
    pub hxx: SMatrix<f64, NX, NX>,
    /// `∇²_xw` of the same.
    pub hxw: SMatrix<f64, NX, NW>,
    /// `∇²_ww` of the same.
    pub hww: SMatrix<f64, NW, NW>,
    /// The stage equality's multiplier estimate at the iterate's `(λ, ζ)`
    /// ([`StageDerivatives::equality_multiplier`]), computed once per iteration by the
    /// solver for its SR1 update and its KKT error; `None` before that or if `E_v` is
    /// singular.
    pub nu: Option<SVector<f64, NE>>,
}

impl<const NX: usize, const NW: usize, const NE: usize, const NC: usize>
    StageDerivatives<NX, NW, NE, NC>
{
    /// All values and derivatives zero, no multiplier estimate.
    pub fn zeros() -> Self {
        StageDerivatives {
            f: SVector::zeros(),
            fx: SMatrix::zeros(),
            fw: SMatrix::zeros(),
            e: SVector::zeros(),
            ex: SMatrix::zeros(),
            ew: SMatrix::zeros(),
            cost: 0.0,
            gx: SVector::zeros(),
            gw: SVector::zeros(),
            c: SVector::zeros(),
            cx: SMatrix::zeros(),
            cw: SMatrix::zeros(),
            hxx: SMatrix::zeros(),
            hxw: SMatrix::zeros(),
            hww: SMatrix::zeros(),
            nu: None,
        }
    }

    /// The multiplier estimate `ν` of the stage equality that zeroes the Lagrangian's
    /// gradient in the dependent decisions: `E_vᵀ ν = −(∇_v ℓ + f_vᵀ λ + C_vᵀ ζ)`.
    /// `None` if `E_v` is singular; zero when there is no stage equality.
    pub fn equality_multiplier(
        &self,
        lambda: &SVector<f64, NX>,
        zeta: &SVector<f64, NC>,
    ) -> Option<SVector<f64, NE>> {
        if NE == 0 {
            return Some(SVector::zeros());
        }
        let gw = self.gw + self.fw.tr_mul(lambda) + self.cw.tr_mul(zeta);
        let ev: SMatrix<f64, NE, NE> = self.ew.fixed_columns::<NE>(0).into_owned();
        Lu::new(&ev.transpose()).map(|lu| lu.solve(&(-gw.fixed_rows::<NE>(0).into_owned())))
    }
}

pub(crate) fn seed2<const N: usize>(x: &SVector<f64, N>) -> SVector<Dual2SVec64<N>, N> {
    SVector::from_fn(|i, _| {
        let mut e = SMatrix::<f64, 1, N>::zeros();
        e[i] = 1.0;
        Dual2SVec64::new(x[i], Derivative::some(e), Derivative::none())
    })
}

pub(crate) fn hess2<const N: usize>(d: &Dual2SVec64<N>) -> SMatrix<f64, N, N> {
    d.v2.0.unwrap_or_else(SMatrix::zeros)
}

/// `s ℓ + ζᵀ c` of stage `k` in any scalar (`s` the cost's scale; not multiplied when 1).
pub fn cost_and_inequalities<
    P,
    T,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    p: &P,
    k: usize,
    cost_scale: f64,
    zeta: &SVector<f64, NC>,
    x: &SVector<T, NX>,
    w: &SVector<T, NW>,
) -> T
where
    P: StageProblem<NX, NW, NE, NF, NC>,
    T: dmech_lie::Real,
{
    let c = p.constraints(k, x, w);
    let mut v = p.cost(k, x, w);
    if cost_scale != 1.0 {
        v *= cost_scale;
    }
    for i in 0..NC {
        if zeta[i] != 0.0 {
            v += c[i] * zeta[i];
        }
    }
    v
}

/// A scalar function of a stage `(x, w)` in any scalar: what [`block_hessian`] takes
/// second derivatives of (closures cannot be generic over the scalar).
pub trait StageScalar<const NX: usize, const NW: usize> {
    /// The function's value at `(x, w)`.
    fn eval<T: dmech_lie::Real>(&self, x: &SVector<T, NX>, w: &SVector<T, NW>) -> T;
}

/// `(∇²_xx, ∇²_xw, ∇²_ww)` of `f` at `(x, w)`: `xx` and `ww` by `Dual2` passes, `xw` by a
/// hyper-dual pass. `with_state = false` skips the two state blocks (left zero).
pub fn block_hessian<F, const NX: usize, const NW: usize>(
    f: &F,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
    with_state: bool,
) -> HessianBlocks<NX, NW>
where
    F: StageScalar<NX, NW>,
{
    let hww = hess2(&f.eval(&x.map(Dual2SVec64::<NW>::from_re), &seed2(w)));
    if !with_state {
        return (SMatrix::zeros(), SMatrix::zeros(), hww);
    }
    let hxx = hess2(&f.eval(&seed2(x), &w.map(Dual2SVec64::<NX>::from_re)));
    let (xh, wh) = seed_hyper(x, w);
    let hxw = f.eval(&xh, &wh).eps1eps2.0.unwrap_or_else(SMatrix::zeros);
    (hxx, hxw, hww)
}

/// `a` seeded in the first direction and `b` in the second of a hyper-dual.
pub fn seed_hyper<const NA: usize, const NB: usize>(
    a: &SVector<f64, NA>,
    b: &SVector<f64, NB>,
) -> (
    SVector<HyperDualSVec64<NA, NB>, NA>,
    SVector<HyperDualSVec64<NA, NB>, NB>,
) {
    let ah = SVector::from_fn(|i, _| {
        let mut e = SVector::<f64, NA>::zeros();
        e[i] = 1.0;
        let mut h = HyperDualSVec64::<NA, NB>::from_re(a[i]);
        h.eps1 = Derivative::some(e);
        h
    });
    let bh = SVector::from_fn(|i, _| {
        let mut e = SMatrix::<f64, 1, NB>::zeros();
        e[i] = 1.0;
        let mut h = HyperDualSVec64::<NA, NB>::from_re(b[i]);
        h.eps2 = Derivative::some(e);
        h
    });
    (ah, bh)
}

/// The cost and inequality part `s ℓ + ζᵀc` of stage `k` as a [`StageScalar`].
struct CostPart<'a, P, const NC: usize> {
    p: &'a P,
    k: usize,
    cost_scale: f64,
    zeta: &'a SVector<f64, NC>,
}

/// The Hessian blocks of `s ℓ_k + ζᵀc_k` at `(x, w)` over the whole stage (`with_state =
/// false`: the `ww` block only).
#[allow(clippy::too_many_arguments)]
fn cost_part_hessian<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    p: &P,
    k: usize,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
    cost_scale: f64,
    zeta: &SVector<f64, NC>,
    with_state: bool,
) -> HessianBlocks<NX, NW>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    let part = (
        CostPart {
            p,
            k,
            cost_scale,
            zeta,
        },
        std::marker::PhantomData::<([(); NE], [(); NF])>,
    );
    block_hessian(&part, x, w, with_state)
}

impl<P, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    StageScalar<NX, NW>
    for (
        CostPart<'_, P, NC>,
        std::marker::PhantomData<([(); NE], [(); NF])>,
    )
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    fn eval<T: dmech_lie::Real>(&self, x: &SVector<T, NX>, w: &SVector<T, NW>) -> T {
        let c = &self.0;
        cost_and_inequalities(c.p, c.k, c.cost_scale, c.zeta, x, w)
    }
}

/// The constraint part `λᵀf + νᵀe` of stage `k` as a [`StageScalar`] (through the
/// problem's generic dynamics and equality).
pub struct ConstraintPart<'a, P, const NX: usize, const NE: usize> {
    /// The problem.
    pub p: &'a P,
    /// The stage.
    pub k: usize,
    /// The dynamics' multipliers `λ`.
    pub lambda: &'a SVector<f64, NX>,
    /// The stage equality's multipliers `ν`.
    pub nu: &'a SVector<f64, NE>,
}

impl<P, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    StageScalar<NX, NW>
    for (
        ConstraintPart<'_, P, NX, NE>,
        std::marker::PhantomData<([(); NF], [(); NC])>,
    )
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    fn eval<T: dmech_lie::Real>(&self, x: &SVector<T, NX>, w: &SVector<T, NW>) -> T {
        let c = &self.0;
        let f = c.p.dynamics(c.k, x, w);
        let e = c.p.equality(c.k, x, w);
        let mut v = T::zero();
        for i in 0..NX {
            if c.lambda[i] != 0.0 {
                v += f[i] * c.lambda[i];
            }
        }
        for i in 0..NE {
            v += e[i] * c.nu[i];
        }
        v
    }
}

/// The curvature `∇²(λᵀf + νᵀe)` of stage `k` through the problem's generic dynamics and
/// equality: the default of [`StageProblem::constraint_curvature`]. For a variational
/// integrator's momentum equation these are third derivatives of `ℓ` in nested duals.
pub fn generic_constraint_curvature<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    p: &P,
    k: usize,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
    lambda: &SVector<f64, NX>,
    nu: &SVector<f64, NE>,
) -> HessianBlocks<NX, NW>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    let part = (
        ConstraintPart { p, k, lambda, nu },
        std::marker::PhantomData::<([(); NF], [(); NC])>,
    );
    block_hessian(&part, x, w, true)
}

/// What a caller of [`stage_derivatives_into`] has computed already for stage `k`.
#[derive(Clone, Copy, Default)]
pub struct Precomputed<'a, const NX: usize, const NW: usize, const NE: usize, const NC: usize> {
    /// What the solver computed once for a problem that declares its cost curvature
    /// constant ([`StageConstants`]).
    pub constants: Option<&'a StageConstants<NX, NW, NC>>,
    /// The stage equality's value `e(x, w)`, as [`StageProblem::equality`] gives it to the
    /// bit (the solver's line search measured it at the point it accepted): only its
    /// partials are then computed ([`StageProblem::equality_partials`]).
    pub equality: Option<&'a SVector<f64, NE>>,
}

/// All derivatives of stage `k` at `(x, w)`, with inequality multipliers `ζ = z_hi − z_lo`.
pub fn stage_derivatives<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    p: &P,
    k: usize,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
    zeta: &SVector<f64, NC>,
    lambda: Option<&SVector<f64, NX>>,
) -> StageDerivatives<NX, NW, NE, NC>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    let mut d = StageDerivatives::zeros();
    stage_derivatives_into(&mut d, p, k, x, w, zeta, lambda, Precomputed::default());
    d
}

/// [`stage_derivatives`] written into `d` field by field (every field is overwritten,
/// `nu` set to `None`). The solver keeps one `d` per stage across iterations: building
/// the 8 kB struct and moving it into place cost several copies per stage.
/// `known` is what the caller has computed already ([`Precomputed`]); the default computes
/// everything here.
#[allow(clippy::too_many_arguments)] // the stage, its point and multipliers, and the known
pub fn stage_derivatives_into<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    d: &mut StageDerivatives<NX, NW, NE, NC>,
    p: &P,
    k: usize,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
    zeta: &SVector<f64, NC>,
    lambda: Option<&SVector<f64, NX>>,
    known: Precomputed<'_, NX, NW, NE, NC>,
) where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    stage_first_derivatives_into(d, p, k, x, w, known);
    // Second order of `ℓ + ζᵀc` (only its `ww` block when the problem declares itself affine
    // in the state; the solver's copy when it declares it constant), plus the constraints'
    // curvature when the exact Hessian is asked for.
    (d.hxx, d.hxw, d.hww) = match known.constants {
        Some(c) => c.curvature,
        None => p.cost_curvature(k, x, w, 1.0, zeta),
    };
    if let Some(lam) = lambda {
        let nu = d
            .equality_multiplier(lam, zeta)
            .unwrap_or_else(SVector::zeros);
        let (cxx, cxw, cww) = p.constraint_curvature(k, x, w, lam, &nu);
        d.hxx += cxx;
        d.hxw += cxw;
        d.hww += cww;
    }
}

/// Everything [`stage_derivatives_into`] writes but the curvature blocks `hxx`, `hxw`,
/// `hww`, which are left as they were: for a solver that reads a constant curvature from
/// its [`ConstantsTable`] instead of copying 3 kB into every stage (that copy was the
/// largest caller of `memcpy` in a plan).
pub fn stage_first_derivatives_into<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    d: &mut StageDerivatives<NX, NW, NE, NC>,
    p: &P,
    k: usize,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
    known: Precomputed<'_, NX, NW, NE, NC>,
) where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    (d.f, d.fx, d.fw) = p.dynamics_jacobian(k, x, w);
    match known.equality {
        Some(e) => {
            d.e = *e;
            (d.ex, d.ew) = p.equality_partials(k, x, w);
        }
        None => (d.e, d.ex, d.ew) = p.equality_jacobian(k, x, w),
    }
    // Cost and inequalities: a pass seeded in w, and one in x unless its gradients are
    // the solver's constants (the values are the same real arithmetic in either pass).
    let xc = x.map(DualSVec64::<NW>::from_re);
    let wd = seed(w);
    let l_w = p.cost(k, &xc, &wd);
    let c_w = p.constraints(k, &xc, &wd);
    match known.constants.and_then(|c| c.state_gradients.as_ref()) {
        Some((gx, cx)) => {
            d.c = c_w.map(|v| v.re);
            d.cx = *cx;
            d.cw = jacobian_part(&c_w);
            d.cost = l_w.re;
            d.gx = *gx;
        }
        None => {
            let (l_d, c_d) = state_pass(p, k, x, w);
            (d.c, d.cx, d.cw) = split_passes(&c_d, &c_w);
            d.cost = l_d.re;
            d.gx = grad(&l_d);
        }
    }
    d.gw = grad(&l_w);
    d.nu = None;
}

/// `(e, E_x, E_w)` of `p`'s stage equality by two vector-dual passes through
/// [`StageProblem::equality`] (seeded in `x`, then in `w`): the default of
/// [`StageProblem::equality_jacobian`], for an override that takes it where its own
/// route does not apply.
#[allow(clippy::type_complexity)]
pub fn generic_equality_jacobian<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    p: &P,
    k: usize,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
) -> (SVector<f64, NE>, SMatrix<f64, NE, NX>, SMatrix<f64, NE, NW>)
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    let ex = p.equality(k, &seed(x), &w.map(DualSVec64::<NX>::from_re));
    let ew = p.equality(k, &x.map(DualSVec64::<NW>::from_re), &seed(w));
    split_passes(&ex, &ew)
}

/// `(∇²_xx, ∇²_xw, ∇²_ww)` of `s ℓ_k + ζᵀc_k` at `(x, w)` by second-order passes over the
/// whole stage (only the `ww` block when the problem declares itself affine in the state):
/// the default of [`StageProblem::cost_curvature`].
pub fn generic_cost_curvature<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    p: &P,
    k: usize,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
    cost_scale: f64,
    zeta: &SVector<f64, NC>,
) -> HessianBlocks<NX, NW>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    cost_part_hessian(p, k, x, w, cost_scale, zeta, !p.affine_in_state())
}

/// The `xx` and `xw` blocks of the Hessian of `ℓ_k + ζᵀc_k` at `(x, w)`: what
/// [`StageProblem::affine_in_state`] declares to be zero.
pub fn state_curvature<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    p: &P,
    k: usize,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
    zeta: &SVector<f64, NC>,
) -> (SMatrix<f64, NX, NX>, SMatrix<f64, NX, NW>)
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    let (hxx, hxw, _) = cost_part_hessian(p, k, x, w, 1.0, zeta, true);
    (hxx, hxw)
}

/// Stage values only (for the line search).
#[derive(Clone, Copy, Debug)]
pub struct StageValues<const NX: usize, const NE: usize, const NC: usize> {
    /// The dynamics.
    pub f: SVector<f64, NX>,
    /// The stage equality.
    pub e: SVector<f64, NE>,
    /// The cost.
    pub cost: f64,
    /// The inequalities.
    pub c: SVector<f64, NC>,
}

/// The values of stage `k` at `(x, w)` (no derivatives).
pub fn stage_values<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    p: &P,
    k: usize,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
) -> StageValues<NX, NE, NC>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    StageValues {
        f: p.dynamics(k, x, w),
        e: p.equality(k, x, w),
        cost: p.cost(k, x, w),
        c: p.constraints(k, x, w),
    }
}

/// The last stage's own functions at `x_N`: the terminal cost `ℓ_N` (value, gradient) and
/// the terminal equalities `r(x_N)` (values, gradients), with the curvature of
/// `ℓ_N + yᵀr` for the terminal equalities' multipliers `y`, by one `Dual2` pass.
#[derive(Clone, Debug)]
pub struct TerminalDerivatives<const NX: usize> {
    /// `ℓ_N(x_N)`.
    pub cost: f64,
    /// Its gradient.
    pub gx: SVector<f64, NX>,
    /// The Hessian of `ℓ_N + yᵀr`.
    pub hxx: SMatrix<f64, NX, NX>,
    /// `r(x_N)` ([`StageProblem::terminal_equalities`]).
    pub equalities: Vec<f64>,
    /// `∇r_j(x_N)`, one per terminal equality.
    pub equality_gradients: Vec<SVector<f64, NX>>,
}

impl<const NX: usize> TerminalDerivatives<NX> {
    /// No terminal cost and no terminal equalities.
    pub fn zeros() -> Self {
        TerminalDerivatives {
            cost: 0.0,
            gx: SVector::zeros(),
            hxx: SMatrix::zeros(),
            equalities: Vec::new(),
            equality_gradients: Vec::new(),
        }
    }
}

/// The [`TerminalDerivatives`] of `p` at `x` with the terminal equalities' multipliers `y`
/// (one per terminal equality; missing ones are taken as zero).
pub fn terminal_derivatives<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>(
    p: &P,
    x: &SVector<f64, NX>,
    y: &[f64],
) -> TerminalDerivatives<NX>
where
    P: StageProblem<NX, NW, NE, NF, NC>,
{
    let xd = seed2(x);
    let v = p.terminal_cost(&xd);
    let gradient = |d: &Dual2SVec64<NX>| d.v1.0.map_or_else(SVector::zeros, |g| g.transpose());
    let mut hxx = hess2(&v);
    let rows = p.terminal_equalities(&xd);
    for (r, &yj) in rows.iter().zip(y) {
        if yj != 0.0 {
            hxx += hess2(r) * yj;
        }
    }
    TerminalDerivatives {
        cost: v.re,
        gx: gradient(&v),
        hxx,
        equalities: rows.iter().map(|r| r.re).collect(),
        equality_gradients: rows.iter().map(gradient).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn constants(v: f64) -> StageConstants<2, 1, 1> {
        StageConstants {
            curvature: (
                SMatrix::repeat(v),
                SMatrix::repeat(2.0 * v),
                SMatrix::repeat(3.0),
            ),
            state_gradients: Some((SVector::repeat(v), SMatrix::zeros())),
        }
    }

    /// Runs of equal constants are stored once; every stage reads its own value.
    #[test]
    fn the_table_keeps_each_run_once_and_every_stage_its_value() {
        let values = [1.0, 1.0, 1.0, 2.0, 2.0, 1.0, -0.0, 0.0];
        let per_stage: Vec<_> = values.iter().map(|&v| constants(v)).collect();
        let table = ConstantsTable::new(&per_stage);
        // 1, 2, 1, then ±0 (equal as numbers) once.
        assert_eq!(table.distinct(), 4);
        for (k, &v) in values.iter().enumerate() {
            assert_eq!(table.get(k), Some(&constants(v)), "stage {k}");
        }
        assert_eq!(table.get(values.len()), None);
        assert_eq!(ConstantsTable::<2, 1, 1>::default().get(0), None);
    }
}

//! Exact stage derivatives of a [`StageProblem`] by dual numbers.
//!
//! Jacobians of the cost and the inequalities come from two vector-dual passes (seeded in
//! `x`, then in `w`); those of the dynamics and the stage equality from the problem's
//! [`StageProblem::dynamics_jacobian`] and [`StageProblem::equality_jacobian`]. The Hessian of
//! `Φ = ℓ_k + ζᵀ c_k` (cost plus inequality curvature, `ζ` the inequality multipliers)
//! comes from three second-order passes (`xx`, `ww` by `Dual2`, `xw` by hyper-duals).
//! The curvature of the dynamics and of the stage equality is not formed: for the first
//! robot of the project (five shape variables, variational integrator) it costs 2.5 ms
//! per stage by nested duals (50× the Jacobian), see `docs/ocp.md`.

use crate::problem::StageProblem;
use dmech::linalg::Lu;
use dmech::partials::{grad_part as grad, seeded as seed, split_passes};
use nalgebra::{SMatrix, SVector};
use num_dual::{Derivative, Dual2SVec64, DualSVec64, HyperDualSVec64};

/// Values and first derivatives at one stage, and the Hessian of `ℓ + ζᵀc`.
#[derive(Clone, Debug)]
pub struct StageDerivatives<const NX: usize, const NW: usize, const NE: usize, const NC: usize> {
    pub f: SVector<f64, NX>,
    pub fx: SMatrix<f64, NX, NX>,
    pub fw: SMatrix<f64, NX, NW>,
    pub e: SVector<f64, NE>,
    pub ex: SMatrix<f64, NE, NX>,
    pub ew: SMatrix<f64, NE, NW>,
    pub cost: f64,
    pub gx: SVector<f64, NX>,
    pub gw: SVector<f64, NW>,
    pub c: SVector<f64, NC>,
    pub cx: SMatrix<f64, NC, NX>,
    pub cw: SMatrix<f64, NC, NW>,
    pub hxx: SMatrix<f64, NX, NX>,
    pub hxw: SMatrix<f64, NX, NW>,
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
        let gw = self.gw + self.fw.transpose() * lambda + self.cw.transpose() * zeta;
        let ev: SMatrix<f64, NE, NE> = self.ew.fixed_columns::<NE>(0).into_owned();
        Lu::new(&ev.transpose()).map(|lu| lu.solve(&(-gw.fixed_rows::<NE>(0).into_owned())))
    }
}

fn seed2<const N: usize>(x: &SVector<f64, N>) -> SVector<Dual2SVec64<N>, N> {
    SVector::from_fn(|i, _| {
        let mut e = SMatrix::<f64, 1, N>::zeros();
        e[i] = 1.0;
        Dual2SVec64::new(x[i], Derivative::some(e), Derivative::none())
    })
}

fn hess2<const N: usize>(d: &Dual2SVec64<N>) -> SMatrix<f64, N, N> {
    d.v2.0.unwrap_or_else(SMatrix::zeros)
}

/// Multipliers of the dynamics and the stage equality, for the exact Hessian.
pub type Multipliers<'a, const NX: usize, const NE: usize> =
    Option<(&'a SVector<f64, NX>, SVector<f64, NE>)>;

/// `ℓ + ζᵀ c (+ λᵀ f + νᵀ e)` in any scalar.
fn phi<P, T, const NX: usize, const NW: usize, const NE: usize, const NC: usize>(
    p: &P,
    k: usize,
    zeta: &SVector<f64, NC>,
    mult: &Multipliers<NX, NE>,
    x: &SVector<T, NX>,
    w: &SVector<T, NW>,
) -> T
where
    P: StageProblem<NX, NW, NE, NC>,
    T: dmech_lie::Real,
{
    let c = p.constraints(k, x, w);
    let mut v = p.cost(k, x, w);
    for i in 0..NC {
        if zeta[i] != 0.0 {
            v += c[i] * zeta[i];
        }
    }
    if let Some((lam, nu)) = mult {
        let f = p.dynamics(k, x, w);
        for i in 0..NX {
            v += f[i] * lam[i];
        }
        let e = p.equality(k, x, w);
        for i in 0..NE {
            v += e[i] * nu[i];
        }
    }
    v
}

/// All derivatives of stage `k` at `(x, w)`, with inequality multipliers `ζ = z_hi − z_lo`.
pub fn stage_derivatives<P, const NX: usize, const NW: usize, const NE: usize, const NC: usize>(
    p: &P,
    k: usize,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
    zeta: &SVector<f64, NC>,
    lambda: Option<&SVector<f64, NX>>,
) -> StageDerivatives<NX, NW, NE, NC>
where
    P: StageProblem<NX, NW, NE, NC>,
{
    let mut d = StageDerivatives::zeros();
    stage_derivatives_into(&mut d, p, k, x, w, zeta, lambda);
    d
}

/// [`stage_derivatives`] written into `d` field by field (every field is overwritten,
/// `nu` set to `None`). The solver keeps one `d` per stage across iterations: building
/// the 8 kB struct and moving it into place cost several copies per stage.
pub fn stage_derivatives_into<
    P,
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NC: usize,
>(
    d: &mut StageDerivatives<NX, NW, NE, NC>,
    p: &P,
    k: usize,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
    zeta: &SVector<f64, NC>,
    lambda: Option<&SVector<f64, NX>>,
) where
    P: StageProblem<NX, NW, NE, NC>,
{
    (d.f, d.fx, d.fw) = p.dynamics_jacobian(k, x, w);
    (d.e, d.ex, d.ew) = p.equality_jacobian(k, x, w);
    // Cost and inequalities: a pass seeded in x, then one in w.
    let xd = seed(x);
    let wc = w.map(DualSVec64::<NX>::from_re);
    let l_d = p.cost(k, &xd, &wc);
    let c_d = p.constraints(k, &xd, &wc);
    let xc = x.map(DualSVec64::<NW>::from_re);
    let wd = seed(w);
    let l_w = p.cost(k, &xc, &wd);
    let c_w = p.constraints(k, &xc, &wd);
    (d.c, d.cx, d.cw) = split_passes(&c_d, &c_w);
    d.cost = l_d.re;
    d.gx = grad(&l_d);
    d.gw = grad(&l_w);
    d.nu = None;
    let mult: Multipliers<NX, NE> = lambda.map(|lam| {
        (
            lam,
            d.equality_multiplier(lam, zeta)
                .unwrap_or_else(SVector::zeros),
        )
    });
    // Second order of the Lagrangian (or of ℓ + ζᵀc only, whose `xx` and `xw` blocks vanish
    // when the problem declares it affine in the state).
    d.hww = hess2(&phi::<P, _, NX, NW, NE, NC>(
        p,
        k,
        zeta,
        &mult,
        &x.map(Dual2SVec64::<NW>::from_re),
        &seed2(w),
    ));
    if mult.is_none() && p.affine_in_state() {
        d.hxx.fill(0.0);
        d.hxw.fill(0.0);
        return;
    }
    (d.hxx, d.hxw) = state_blocks(p, k, zeta, &mult, x, w);
}

/// The `xx` and `xw` blocks of the Hessian of `ℓ_k + ζᵀc_k` at `(x, w)`: what
/// [`StageProblem::affine_in_state`] declares to be zero.
pub fn state_curvature<P, const NX: usize, const NW: usize, const NE: usize, const NC: usize>(
    p: &P,
    k: usize,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
    zeta: &SVector<f64, NC>,
) -> (SMatrix<f64, NX, NX>, SMatrix<f64, NX, NW>)
where
    P: StageProblem<NX, NW, NE, NC>,
{
    state_blocks(p, k, zeta, &None, x, w)
}

/// The `xx` (by `Dual2`) and `xw` (by hyper-duals) blocks of the Hessian of [`phi`].
fn state_blocks<P, const NX: usize, const NW: usize, const NE: usize, const NC: usize>(
    p: &P,
    k: usize,
    zeta: &SVector<f64, NC>,
    mult: &Multipliers<NX, NE>,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
) -> (SMatrix<f64, NX, NX>, SMatrix<f64, NX, NW>)
where
    P: StageProblem<NX, NW, NE, NC>,
{
    let hxx = hess2(&phi::<P, _, NX, NW, NE, NC>(
        p,
        k,
        zeta,
        mult,
        &seed2(x),
        &w.map(Dual2SVec64::<NX>::from_re),
    ));
    let xh: SVector<HyperDualSVec64<NX, NW>, NX> = SVector::from_fn(|i, _| {
        let mut e = SVector::<f64, NX>::zeros();
        e[i] = 1.0;
        let mut h = HyperDualSVec64::<NX, NW>::from_re(x[i]);
        h.eps1 = Derivative::some(e);
        h
    });
    let wh: SVector<HyperDualSVec64<NX, NW>, NW> = SVector::from_fn(|i, _| {
        let mut e = SMatrix::<f64, 1, NW>::zeros();
        e[i] = 1.0;
        let mut h = HyperDualSVec64::<NX, NW>::from_re(w[i]);
        h.eps2 = Derivative::some(e);
        h
    });
    let hxw = phi::<P, _, NX, NW, NE, NC>(p, k, zeta, mult, &xh, &wh)
        .eps1eps2
        .0
        .unwrap_or_else(SMatrix::zeros);
    (hxx, hxw)
}

/// Stage values only (for the line search).
#[derive(Clone, Copy, Debug)]
pub struct StageValues<const NX: usize, const NE: usize, const NC: usize> {
    pub f: SVector<f64, NX>,
    pub e: SVector<f64, NE>,
    pub cost: f64,
    pub c: SVector<f64, NC>,
}

pub fn stage_values<P, const NX: usize, const NW: usize, const NE: usize, const NC: usize>(
    p: &P,
    k: usize,
    x: &SVector<f64, NX>,
    w: &SVector<f64, NW>,
) -> StageValues<NX, NE, NC>
where
    P: StageProblem<NX, NW, NE, NC>,
{
    StageValues {
        f: p.dynamics(k, x, w),
        e: p.equality(k, x, w),
        cost: p.cost(k, x, w),
        c: p.constraints(k, x, w),
    }
}

/// The terminal cost `ℓ_N(x_N)`: value, gradient and Hessian, by one `Dual2` pass.
#[derive(Clone, Copy, Debug)]
pub struct TerminalDerivatives<const NX: usize> {
    pub cost: f64,
    pub gx: SVector<f64, NX>,
    pub hxx: SMatrix<f64, NX, NX>,
}

pub fn terminal_derivatives<P, const NX: usize, const NW: usize, const NE: usize, const NC: usize>(
    p: &P,
    x: &SVector<f64, NX>,
) -> TerminalDerivatives<NX>
where
    P: StageProblem<NX, NW, NE, NC>,
{
    let v = p.terminal_cost(&seed2(x));
    TerminalDerivatives {
        cost: v.re,
        gx: v.v1.0.map_or_else(SVector::zeros, |g| g.transpose()),
        hxx: hess2(&v),
    }
}

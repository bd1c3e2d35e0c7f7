//! The exact curvature of the variational transcription's constraints,
//! `∇²(λᵀf + νᵀe)`, by blocks (the first-order scheme).
//!
//! `νᵀe` is a third derivative of `ℓ`: the momenta are first derivatives, and the stage
//! Hessian differentiates them twice more. Through the generic path
//! ([`crate::nlp::derivatives::generic_constraint_curvature`]) that is `ℓ` in `Dual2` numbers
//! over the whole stage vector, nested inside the vector dual of each momentum's gradient
//! (over a millisecond a stage on the robots in `robots/`). Here:
//! - each momentum is contracted with `ν` by a *scalar* dual along `ν`
//!   ([`dmech::partials::pulled_back_directional`]), not a gradient of `NS` lanes;
//! - the equality reads three blocks, `s = s_k`, `p = (v_{k−1}, u_{k−1})` and
//!   `q = (v_k, u_k)`, and each term only some of them (outgoing momentum: `s, q`;
//!   incoming: `s, p`; the force: its quadrature's interval). One second-order pass per
//!   pair of blocks (`Dual2` on the diagonal, hyper-duals off it), each evaluating only
//!   the terms that read both blocks; the group coordinates are never seeded;
//! - `λᵀf` is cheap (the group's `exp` and the connection) and goes through
//!   [`block_hessian`] on the dynamics alone.

use crate::nlp::derivatives::{block_hessian, hess2, seed2, seed_hyper, StageScalar};
use crate::nlp::HessianBlocks;
use crate::transcription::layout::segment;
use crate::transcription::variational::stages::{Terms, VarIntStages};
use dmech::partials::pulled_back_directional;
use dmech::variational::{discrete_force, incoming_variation, outgoing_variation};
use dmech::PrincipalKinematicSystem;
use dmech_lie::Real;
use nalgebra::{SMatrix, SVector};
use num_dual::{Dual2SVec64, HyperDualSVec64};

/// `λᵀ f(x, w)` of the variational transcription, for [`block_hessian`].
struct DynamicsPart<'s, 'a, S, const NX: usize> {
    stages: &'s VarIntStages<'a, S>,
    lambda: &'s SVector<f64, NX>,
}

/// The sizes a [`DynamicsPart`] is evaluated at (a marker: the impl needs them named).
struct Sizes<const DOF: usize, const NS: usize, const NU: usize>;

impl<S, const DOF: usize, const NS: usize, const NU: usize, const NX: usize, const NW: usize>
    StageScalar<NX, NW> for (DynamicsPart<'_, '_, S, NX>, Sizes<DOF, NS, NU>)
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    fn eval<T: Real>(&self, x: &SVector<T, NX>, w: &SVector<T, NW>) -> T {
        let part = &self.0;
        let f = part.stages.dynamics::<T, DOF, NS, NU, NX, NW>(x, w);
        let mut v = T::zero();
        for i in 0..NX {
            if part.lambda[i] != 0.0 {
                v += f[i] * part.lambda[i];
            }
        }
        v
    }
}

impl<S> VarIntStages<'_, S> {
    /// `νᵀ e` over the blocks `s = s_k`, `p = (v_{k−1}, u_{k−1})`, `q = (v_k, u_k)`, the
    /// selected terms only, each momentum contracted with `ν` by one scalar dual.
    fn contracted_equality<
        T: Real,
        const DOF: usize,
        const NS: usize,
        const NU: usize,
        const NW: usize,
    >(
        &self,
        terms: Terms,
        s: &SVector<T, NS>,
        p: &SVector<T, NW>,
        q: &SVector<T, NW>,
        nu: &SVector<f64, NS>,
    ) -> T
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let ht = T::from(self.h);
        let (v_prev, u_prev): (SVector<T, NS>, SVector<T, NU>) = (segment(p, 0), segment(p, NS));
        let (v, u): (SVector<T, NS>, SVector<T, NU>) = (segment(q, 0), segment(q, NS));
        let a_k = self.sys.connection(s);
        let mut r = T::zero();
        if terms.outgoing {
            let (xi, d) = outgoing_variation::<S, T, DOF, NS, NU>(self.h, &v, &a_k);
            r +=
                pulled_back_directional::<S, T, DOF, NS, NU>(self.sys, s, -self.h, &v, &xi, &d, nu)
                    / ht;
        }
        let s_prev = s - v_prev * ht;
        if terms.incoming {
            let (xi, d) =
                incoming_variation::<S, T, DOF, NS, NU>(self.sys, self.h, &s_prev, &v_prev, &a_k);
            r -= pulled_back_directional::<S, T, DOF, NS, NU>(
                self.sys, &s_prev, 0.0, &v_prev, &xi, &d, nu,
            ) / ht;
        }
        if terms.force {
            let f = discrete_force::<S, T, DOF, NS, NU>(
                self.sys,
                self.quadrature,
                &s_prev,
                &v_prev,
                &u_prev,
                s,
                &v,
                &u,
            );
            for i in 0..NS {
                r -= f[i] * nu[i];
            }
        }
        r
    }

    /// `(∇²_xx, ∇²_xw, ∇²_ww)` of `νᵀe(x, w)` for the first-order scheme, by one
    /// second-order pass per pair of the blocks `(s, p, q)` that some term reads together
    /// (module documentation). Checked against the generic path in a test.
    pub fn equality_curvature<
        const DOF: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        nu: &SVector<f64, NS>,
    ) -> HessianBlocks<NX, NW>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let l = self.layout;
        l.check(NX, NW, NS + NU);
        let s: SVector<f64, NS> = l.shape(x);
        // (v_{k−1}, u_{k−1}) are adjacent in the state, in w's order.
        let p: SVector<f64, NW> = segment(x, l.v_at());
        let q = *w;
        let (left, right) = self.quadrature.ends();
        let every = Terms::ALL;
        let prev = Terms::previous_interval(left);
        let cur = Terms::current_interval(right);
        type D2<const N: usize> = Dual2SVec64<N>;
        let hss = hess2(&self.contracted_equality::<_, DOF, NS, NU, NW>(
            every,
            &seed2(&s),
            &p.map(D2::<NS>::from_re),
            &q.map(D2::<NS>::from_re),
            nu,
        ));
        let hpp = hess2(&self.contracted_equality::<_, DOF, NS, NU, NW>(
            prev,
            &s.map(D2::<NW>::from_re),
            &seed2(&p),
            &q.map(D2::<NW>::from_re),
            nu,
        ));
        let hqq = hess2(&self.contracted_equality::<_, DOF, NS, NU, NW>(
            cur,
            &s.map(D2::<NW>::from_re),
            &p.map(D2::<NW>::from_re),
            &seed2(&q),
            nu,
        ));
        type Hd<const A: usize, const B: usize> = HyperDualSVec64<A, B>;
        let mixed = |h: Hd<NS, NW>| h.eps1eps2.0.unwrap_or_else(SMatrix::zeros);
        let (sh, ph) = seed_hyper(&s, &p);
        let hsp = mixed(self.contracted_equality::<_, DOF, NS, NU, NW>(
            prev,
            &sh,
            &ph,
            &q.map(Hd::<NS, NW>::from_re),
            nu,
        ));
        let (sh, qh) = seed_hyper(&s, &q);
        let hsq = mixed(self.contracted_equality::<_, DOF, NS, NU, NW>(
            cur,
            &sh,
            &p.map(Hd::<NS, NW>::from_re),
            &qh,
            nu,
        ));
        // p and q meet only in a force that reads both intervals.
        let hpq = if left && right {
            let force = Terms::FORCE;
            let (ph, qh) = seed_hyper(&p, &q);
            self.contracted_equality::<_, DOF, NS, NU, NW>(
                force,
                &s.map(Hd::<NW, NW>::from_re),
                &ph,
                &qh,
                nu,
            )
            .eps1eps2
            .0
            .unwrap_or_else(SMatrix::zeros)
        } else {
            SMatrix::zeros()
        };
        let pa = l.v_at();
        let mut hxx = SMatrix::<f64, NX, NX>::zeros();
        let mut hxw = SMatrix::<f64, NX, NW>::zeros();
        hxx.fixed_view_mut::<NW, NW>(pa, pa).copy_from(&hpp);
        // The shape's rows and columns where the state carries them (an ignored
        // coordinate's, zero for an ignorable one, have no place).
        for i in 0..NS {
            let Some(a) = l.shape_slot(i) else { continue };
            for j in 0..NS {
                if let Some(b) = l.shape_slot(j) {
                    hxx[(a, b)] = hss[(i, j)];
                }
            }
            for j in 0..NW {
                hxx[(a, pa + j)] = hsp[(i, j)];
                hxx[(pa + j, a)] = hsp[(i, j)];
                hxw[(a, j)] = hsq[(i, j)];
            }
        }
        hxw.fixed_view_mut::<NW, NW>(pa, 0).copy_from(&hpq);
        (hxx, hxw, hqq)
    }

    /// `(∇²_xx, ∇²_xw, ∇²_ww)` of `λᵀf + νᵀe`: the dynamics by [`block_hessian`], the
    /// equality by [`VarIntStages::equality_curvature`] for the first-order scheme. `None`
    /// for the midpoint scheme (its caller takes the generic path).
    #[allow(clippy::type_complexity)]
    pub fn constraint_curvature<
        const DOF: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        lambda: &SVector<f64, NX>,
        nu: &SVector<f64, NS>,
    ) -> Option<(
        SMatrix<f64, NX, NX>,
        SMatrix<f64, NX, NW>,
        SMatrix<f64, NW, NW>,
    )>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        if self.discretisation != dmech::Discretisation::FirstOrder {
            return None;
        }
        let part = (
            DynamicsPart {
                stages: self,
                lambda,
            },
            Sizes::<DOF, NS, NU>,
        );
        let (fxx, fxw, fww) = block_hessian(&part, x, w, true);
        let (exx, exw, eww) = self.equality_curvature::<DOF, NS, NU, NX, NW>(x, w, nu);
        Some((fxx + exx, fxw + exw, fww + eww))
    }
}

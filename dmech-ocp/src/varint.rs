//! The variational-integrator transcription: `x_k = (coords(g_k), s_k, v_{k−1}, u_{k−1})`,
//! `w_k = (v_k, u_k)`.
//!
//! ```text
//! dynamics  x_{k+1} = (coords(g_k exp(−h A(s_k) v_k)), s_k + h v_k, v_k, u_k)
//! equality  e(x_k, w_k) = momentum-matching residual of node k
//!           with (s_{k−1}, v_{k−1}, u_{k−1}) = (s_k − h v_{k−1}, v_{k−1}, u_{k−1})
//! ```
//! At `k = 0`, `v_{−1} = 0`, `u_{−1} = 0` says the robot was at rest before the start.
//!
//! With [`Discretisation::Midpoint`] the same layout carries the symmetric scheme
//! ([`dmech::midpoint`]): `ξ_k = −A(s_k + ½h v_k) v_k` in the dynamics and the midpoint
//! momentum-matching residual as the equality.

use crate::layout::{segment, Layout};
use dmech::midpoint::{
    interval_body_velocity, interval_force, midpoint_incoming_momentum,
    midpoint_momentum_matching_residual, midpoint_outgoing_momentum,
};
use dmech::partials::{grad_part, lift_vec, seeded, seeded_from};
use dmech::variational::{
    discrete_force, incoming_momentum_dual, momentum_matching_residual, outgoing_momentum_dual,
};
use dmech::{Discretisation, ForcingQuadrature, PrincipalKinematicSystem};
use dmech_lie::{LieGroup, Real};
use nalgebra::{SMatrix, SVector};
use num_dual::DualSVec64;

type D<const N: usize> = DualSVec64<N>;

/// Which terms of the momentum-matching residual a derivative pass evaluates.
#[derive(Clone, Copy)]
pub(crate) struct Terms {
    pub(crate) outgoing: bool,
    pub(crate) incoming: bool,
    pub(crate) force: bool,
}

/// The stage functions of the VI transcription of `sys` at step `h`.
#[derive(Clone, Copy)]
pub struct VarIntStages<'a, S> {
    pub sys: &'a S,
    pub h: f64,
    pub quadrature: ForcingQuadrature,
    pub discretisation: Discretisation,
    pub layout: Layout,
}

impl<'a, S> VarIntStages<'a, S> {
    pub fn new<const DOF: usize, const DIM: usize, const NS: usize, const NU: usize>(
        sys: &'a S,
        h: f64,
        quadrature: ForcingQuadrature,
    ) -> Self
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let nc = <S::Group<f64> as LieGroup<DOF, DIM>>::identity()
            .coordinates()
            .len();
        VarIntStages {
            sys,
            h,
            quadrature,
            discretisation: Discretisation::FirstOrder,
            layout: Layout::new(nc, NS, NU),
        }
    }

    /// The same transcription with another discretisation of the LDAP principle.
    pub fn with_discretisation(mut self, discretisation: Discretisation) -> Self {
        self.discretisation = discretisation;
        self
    }

    /// `x_{k+1} = f(x_k, w_k)`.
    pub fn dynamics<
        T: Real,
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> SVector<T, NX>
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let l = self.layout;
        l.check(NX, NW, NS + NU);
        let g_next = self.group_step::<T, DOF, DIM, NS, NU, NX, NW>(x, w);
        let s: SVector<T, NS> = l.shape(x);
        let v: SVector<T, NS> = segment(w, 0);
        let u: SVector<T, NU> = segment(w, NS);
        let s_next = s + v * T::from(self.h);
        let mut out = SVector::<T, NX>::zeros();
        for (i, c) in g_next.coordinates().into_iter().enumerate() {
            out[i] = c;
        }
        l.set_shape(&mut out, &s_next);
        for i in 0..NS {
            out[l.v_at() + i] = v[i];
        }
        for i in 0..NU {
            out[l.u_at() + i] = u[i];
        }
        out
    }

    /// `g_{k+1} = g_k exp(h ξ_k)`, the one part of [`VarIntStages::dynamics`] that is not
    /// linear in `(x_k, w_k)`.
    fn group_step<
        T: Real,
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> S::Group<T>
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let l = self.layout;
        let g = <S::Group<T> as LieGroup<DOF, DIM>>::from_coordinates(&x.as_slice()[..l.nc])
            .expect("layout checked");
        let s: SVector<T, NS> = l.shape(x);
        let v: SVector<T, NS> = segment(w, 0);
        let xi = match self.discretisation {
            Discretisation::FirstOrder => -(self.sys.connection(&s) * v),
            Discretisation::Midpoint => {
                interval_body_velocity::<S, T, DOF, DIM, NS, NU>(self.sys, self.h, &s, &v)
            }
        };
        g.compose(&<S::Group<T> as LieGroup<DOF, DIM>>::exp(
            &(xi * T::from(self.h)),
        ))
    }

    /// `(f, F_x, F_w)` of [`VarIntStages::dynamics`]: the group rows by one vector-dual pass
    /// of width `NX` through [`VarIntStages::group_step`], the other rows written out (they
    /// are linear: `s_{k+1} = s_k + h v_k`, `(v_k, u_k)` copied). The group step reads only
    /// `(coords(g_k), s_k)` of `x` and all of `w`; `w` is seeded in the directions of the
    /// entries of `x` it does not read, `(v_{k−1}, u_{k−1})`, which `w = (v_k, u_k)` fills
    /// exactly. Each direction of a vector dual is propagated on its own, so the columns
    /// are the two-pass default's to the bit (checked against it in a test); the linear
    /// rows' entries `1`, `h` are what a dual pass gives for them, exactly.
    #[allow(clippy::type_complexity)]
    pub fn dynamics_jacobian<
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NX>, SMatrix<f64, NX, NX>, SMatrix<f64, NX, NW>)
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let l = self.layout;
        l.check(NX, NW, NS + NU);
        let at = l.v_at();
        let xd = SVector::<D<NX>, NX>::from_fn(|i, _| {
            if i < at {
                let mut e = SVector::<f64, NX>::zeros();
                e[i] = 1.0;
                D::<NX>::new(x[i], num_dual::Derivative::some(e))
            } else {
                D::<NX>::from_re(x[i])
            }
        });
        let wd = seeded_from::<f64, NX, NW>(w, at);
        let g_next = self.group_step::<D<NX>, DOF, DIM, NS, NU, NX, NW>(&xd, &wd);
        let mut f = SVector::<f64, NX>::zeros();
        let mut fx = SMatrix::<f64, NX, NX>::zeros();
        let mut fw = SMatrix::<f64, NX, NW>::zeros();
        for (i, c) in g_next.coordinates().iter().enumerate() {
            f[i] = c.re;
            let g = grad_part(c);
            for j in 0..at {
                fx[(i, j)] = g[j];
            }
            for j in 0..NW {
                fw[(i, j)] = g[at + j];
            }
        }
        for i in 0..NS {
            if let Some(slot) = l.shape_slot(i) {
                f[slot] = x[slot] + w[i] * self.h;
                fx[(slot, slot)] = 1.0;
                fw[(slot, i)] = self.h;
            }
            f[at + i] = w[i];
            fw[(at + i, i)] = 1.0;
        }
        for i in 0..NU {
            f[l.u_at() + i] = w[NS + i];
            fw[(l.u_at() + i, NS + i)] = 1.0;
        }
        (f, fx, fw)
    }

    /// `e(x_k, w_k)`: the momentum-matching residual of node `k` (divided by `h`).
    pub fn equality<
        T: Real,
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> SVector<T, NS>
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let l = self.layout;
        l.check(NX, NW, NS + NU);
        let s: SVector<T, NS> = l.shape(x);
        let v_prev: SVector<T, NS> = segment(x, l.v_at());
        let u_prev: SVector<T, NU> = segment(x, l.u_at());
        let v: SVector<T, NS> = segment(w, 0);
        let u: SVector<T, NU> = segment(w, NS);
        let s_prev = s - v_prev * T::from(self.h);
        if self.discretisation == Discretisation::Midpoint {
            return midpoint_momentum_matching_residual::<S, T, DOF, DIM, NS, NU>(
                self.sys, self.h, &s_prev, &v_prev, &u_prev, &s, &v, &u,
            );
        }
        momentum_matching_residual::<S, T, DOF, DIM, NS, NU>(
            self.sys,
            self.h,
            self.quadrature,
            &s_prev,
            &v_prev,
            &u_prev,
            &s,
            &v,
            &u,
        )
    }

    /// The selected terms of [`VarIntStages::equality`] in blocks
    /// `(s_k, v_{k−1}, u_{k−1}, v_k, u_k)`.
    #[allow(clippy::too_many_arguments)]
    fn equality_terms<
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
        const N: usize,
    >(
        &self,
        terms: Terms,
        s: &SVector<D<N>, NS>,
        v_prev: &SVector<D<N>, NS>,
        u_prev: &SVector<D<N>, NU>,
        v: &SVector<D<N>, NS>,
        u: &SVector<D<N>, NU>,
    ) -> SVector<D<N>, NS>
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let ht = D::<N>::from(self.h);
        let a_k = self.sys.connection(s);
        let mut r = SVector::<D<N>, NS>::zeros();
        if terms.outgoing {
            r +=
                outgoing_momentum_dual::<S, DOF, DIM, NS, NU, N>(self.sys, self.h, s, v, &a_k) / ht;
        }
        let s_prev = s - v_prev * ht;
        if terms.incoming {
            r -= incoming_momentum_dual::<S, DOF, DIM, NS, NU, N>(
                self.sys, self.h, &s_prev, v_prev, &a_k,
            ) / ht;
        }
        if terms.force {
            r -= discrete_force::<S, D<N>, DOF, DIM, NS, NU>(
                self.sys,
                self.quadrature,
                &s_prev,
                v_prev,
                u_prev,
                s,
                v,
                u,
            );
        }
        r
    }

    /// `(e, E_x, E_w)`, exact, seeding each block of `(s_k, v_{k−1}, u_{k−1}, v_k, u_k)` in
    /// turn and evaluating only the terms that depend on it: the outgoing momentum depends
    /// on `(s_k, v_k)`, the incoming one on `(s_k, v_{k−1})`, the force on the blocks of its
    /// quadrature. The group coordinates do not enter. The momenta's second derivatives come
    /// from one hyper-dual evaluation of `ℓ` per term ([`outgoing_momentum_dual`]) instead
    /// of duals nested inside duals. 12–15 µs against 44 µs for seeding all of `x` and `w`
    /// (`plan_stage` bench, `docs/ocp.md`); checked against that generic path in a test.
    #[allow(clippy::type_complexity)]
    pub fn equality_jacobian<
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NS>, SMatrix<f64, NS, NX>, SMatrix<f64, NS, NW>)
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        if self.discretisation == Discretisation::Midpoint {
            return self.midpoint_equality_jacobian::<DOF, DIM, NS, NU, NX, NW>(x, w);
        }
        // The value as the line search measures it (`equality` in f64): the residual the
        // Newton step removes must be the one the filter sees, to the last bit (the s-pass's
        // real parts differ by round-off, and the iteration count is sensitive to it).
        let e = self.equality::<f64, DOF, DIM, NS, NU, NX, NW>(x, w);
        let (ex, ew) = self.equality_partials::<DOF, DIM, NS, NU, NX, NW>(x, w);
        (e, ex, ew)
    }

    /// [`VarIntStages::equality_jacobian`] without the value, for a caller that has it (the
    /// solver's derivative pass takes the line search's).
    #[allow(clippy::type_complexity)]
    pub fn equality_partials<
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SMatrix<f64, NS, NX>, SMatrix<f64, NS, NW>)
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        if self.discretisation == Discretisation::Midpoint {
            let (_, ex, ew) = self.midpoint_equality_jacobian::<DOF, DIM, NS, NU, NX, NW>(x, w);
            return (ex, ew);
        }
        self.layout.check(NX, NW, NS + NU);
        self.first_order_equality_partials::<DOF, DIM, NS, NU, NX, NW>(x, w)
    }

    /// `(E_x, E_w)` of the first-order scheme's residual at this step, each block of
    /// `(s_k, v_{k−1}, u_{k−1}, v_k, u_k)` seeded alone. `w` starts with `(v_k, u_k)` and may
    /// carry more entries (a free-timing stage's step ratios), whose columns stay zero: the
    /// residual at a fixed step does not read them.
    #[allow(clippy::type_complexity)]
    pub fn first_order_equality_partials<
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SMatrix<f64, NS, NX>, SMatrix<f64, NS, NW>)
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        assert!(
            self.discretisation == Discretisation::FirstOrder && NW >= NS + NU,
            "the first-order scheme's partials, with (v_k, u_k) leading the decision"
        );
        let l = self.layout;
        let s: SVector<f64, NS> = l.shape(x);
        let v_prev: SVector<f64, NS> = segment(x, l.v_at());
        let u_prev: SVector<f64, NU> = segment(x, l.u_at());
        let v: SVector<f64, NS> = segment(w, 0);
        let u: SVector<f64, NU> = segment(w, NS);
        let mut ex = SMatrix::<f64, NS, NX>::zeros();
        let mut ew = SMatrix::<f64, NS, NW>::zeros();
        let (left, right) = match self.quadrature {
            ForcingQuadrature::Left => (true, false),
            ForcingQuadrature::Right => (false, true),
            ForcingQuadrature::Midpoint => (true, true),
        };
        let terms = |outgoing, incoming, force| Terms {
            outgoing,
            incoming,
            force,
        };
        // With the force at one end of the step, each term of the residual reads one
        // interval: the incoming momentum (and a left-point force) the previous one, the
        // outgoing momentum (and a right-point force) the current one. One pass per
        // interval, seeded in its velocity and the carried shape coordinates, gives both
        // velocity blocks and the shape columns as the sum of the two passes' shape lanes
        // (each term is evaluated in exactly one of them). Against a separate shape pass
        // through every term this saves one evaluation of both momenta (on the WIP a
        // sixth of the partials' instructions). A midpoint force reads both intervals and
        // would count its shape derivative twice: it keeps the separate passes, as does a
        // system too wide for the lane counts below.
        let shape_args = (&s, &v_prev, &u_prev, &v, &u);
        let lanes = NS + l.ns_kept();
        let merged = match (left && right, lanes) {
            (true, _) => false,
            (false, 0..=4) => self.interval_passes::<DOF, DIM, NS, NU, NX, NW, 4>(
                left,
                shape_args,
                (&mut ex, &mut ew),
            ),
            (false, 5..=6) => self.interval_passes::<DOF, DIM, NS, NU, NX, NW, 6>(
                left,
                shape_args,
                (&mut ex, &mut ew),
            ),
            (false, 7..=8) => self.interval_passes::<DOF, DIM, NS, NU, NX, NW, 8>(
                left,
                shape_args,
                (&mut ex, &mut ew),
            ),
            (false, _) => false,
        };
        if !merged {
            self.separate_passes::<DOF, DIM, NS, NU, NX, NW>(
                (left, right),
                shape_args,
                (&mut ex, &mut ew),
            );
        }
        // The inputs enter through the force only.
        if left {
            let r = self.equality_terms::<DOF, DIM, NS, NU, _>(
                terms(false, false, true),
                &lift_vec(&s),
                &lift_vec(&v_prev),
                &seeded(&u_prev),
                &lift_vec(&v),
                &lift_vec(&u),
            );
            put_columns(&mut ex, l.u_at(), &r);
        }
        if right {
            let r = self.equality_terms::<DOF, DIM, NS, NU, _>(
                terms(false, false, true),
                &lift_vec(&s),
                &lift_vec(&v_prev),
                &lift_vec(&u_prev),
                &lift_vec(&v),
                &seeded(&u),
            );
            put_columns(&mut ew, NS, &r);
        }
        (ex, ew)
    }

    /// The velocity blocks and the shape columns of `E_x`, `E_w` by one pass per interval
    /// of `N ≥ NS + kept` dual lanes: the interval's velocity in lanes `0..NS`, the carried
    /// shape coordinates in lanes `NS..NS + kept` (in state order). The force is read at
    /// the left point if `left`, otherwise at the right one. `false` (nothing written) if
    /// the lanes do not fit.
    #[allow(clippy::type_complexity)]
    fn interval_passes<
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
        const N: usize,
    >(
        &self,
        left: bool,
        (s, v_prev, u_prev, v, u): (
            &SVector<f64, NS>,
            &SVector<f64, NS>,
            &SVector<f64, NU>,
            &SVector<f64, NS>,
            &SVector<f64, NU>,
        ),
        (ex, ew): (&mut SMatrix<f64, NS, NX>, &mut SMatrix<f64, NS, NW>),
    ) -> bool
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let l = self.layout;
        let kept = l.ns_kept();
        if NS + kept > N {
            return false;
        }
        let s_at = l.s_at();
        let sd = SVector::<D<N>, NS>::from_fn(|i, _| match l.shape_slot(i) {
            Some(at) => {
                let mut e = SVector::<f64, N>::zeros();
                e[NS + at - s_at] = 1.0;
                D::<N>::new(s[i], num_dual::Derivative::some(e))
            }
            None => D::<N>::from_re(s[i]),
        });
        let terms = |outgoing, incoming, force| Terms {
            outgoing,
            incoming,
            force,
        };
        // The previous interval: the incoming momentum, and a left-point force.
        let previous = self.equality_terms::<DOF, DIM, NS, NU, N>(
            terms(false, true, left),
            &sd,
            &seeded_from(v_prev, 0),
            &lift_vec(u_prev),
            &lift_vec(v),
            &lift_vec(u),
        );
        // The current interval: the outgoing momentum, and a right-point force.
        let current = self.equality_terms::<DOF, DIM, NS, NU, N>(
            terms(true, false, !left),
            &sd,
            &lift_vec(v_prev),
            &lift_vec(u_prev),
            &seeded_from(v, 0),
            &lift_vec(u),
        );
        let (v_at, shape_lane) = (l.v_at(), |j: usize| (NS..NS + kept).contains(&j));
        put_columns_by(ex, &previous, |j| (j < NS).then_some(v_at + j));
        put_columns_by(ew, &current, |j| (j < NS).then_some(j));
        for i in 0..NS {
            let (gp, gc) = (grad_part(&previous[i]), grad_part(&current[i]));
            for j in (0..N).filter(|&j| shape_lane(j)) {
                ex[(i, s_at + j - NS)] = gp[j] + gc[j];
            }
        }
        true
    }

    /// The shape and velocity columns of `E_x`, `E_w` by a pass per block: the carried
    /// shape coordinates through every term ([`VarIntStages::carried_shape_pass`]), then
    /// each velocity through the terms that read it.
    #[allow(clippy::type_complexity)]
    fn separate_passes<
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        (left, right): (bool, bool),
        shape_args: (
            &SVector<f64, NS>,
            &SVector<f64, NS>,
            &SVector<f64, NU>,
            &SVector<f64, NS>,
            &SVector<f64, NU>,
        ),
        (ex, ew): (&mut SMatrix<f64, NS, NX>, &mut SMatrix<f64, NS, NW>),
    ) where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let l = self.layout;
        let (s, v_prev, u_prev, v, u) = shape_args;
        let terms = |outgoing, incoming, force| Terms {
            outgoing,
            incoming,
            force,
        };
        // s_k: every term, seeded in the carried coordinates only (an ignored one's column
        // has no place in the state). The lanes are independent, so a pass as wide as the
        // shape changes no bit of the kept columns against a narrower one.
        if l.ns_kept() > 0 {
            self.carried_shape_pass::<DOF, DIM, NS, NU, NX, NS>(shape_args, ex);
        }
        // v_{k−1}: the incoming momentum, and the force if it reads the previous interval.
        let r = self.equality_terms::<DOF, DIM, NS, NU, _>(
            terms(false, true, left),
            &lift_vec(s),
            &seeded(v_prev),
            &lift_vec(u_prev),
            &lift_vec(v),
            &lift_vec(u),
        );
        put_columns(ex, l.v_at(), &r);
        // v_k: the outgoing momentum, and the force if it reads the current interval.
        let r = self.equality_terms::<DOF, DIM, NS, NU, _>(
            terms(true, false, right),
            &lift_vec(s),
            &lift_vec(v_prev),
            &lift_vec(u_prev),
            &seeded(v),
            &lift_vec(u),
        );
        put_columns(ew, 0, &r);
    }

    /// The shape columns of `E_x`: every term of the residual in one pass of `K` dual lanes,
    /// the carried shape coordinates seeded in the first [`Layout::ns_kept`] `≤ K` of them
    /// (in state order), the ignored ones constant.
    #[allow(clippy::type_complexity)]
    fn carried_shape_pass<
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const K: usize,
    >(
        &self,
        (s, v_prev, u_prev, v, u): (
            &SVector<f64, NS>,
            &SVector<f64, NS>,
            &SVector<f64, NU>,
            &SVector<f64, NS>,
            &SVector<f64, NU>,
        ),
        ex: &mut SMatrix<f64, NS, NX>,
    ) where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let l = self.layout;
        let kept = l.ns_kept();
        assert!(kept <= K, "a dual lane for each carried shape coordinate");
        let s_at = l.s_at();
        let sd = SVector::<D<K>, NS>::from_fn(|i, _| match l.shape_slot(i) {
            Some(at) => {
                let mut e = SVector::<f64, K>::zeros();
                e[at - s_at] = 1.0;
                D::<K>::new(s[i], num_dual::Derivative::some(e))
            }
            None => D::<K>::from_re(s[i]),
        });
        let all = Terms {
            outgoing: true,
            incoming: true,
            force: true,
        };
        let r = self.equality_terms::<DOF, DIM, NS, NU, K>(
            all,
            &sd,
            &lift_vec(v_prev),
            &lift_vec(u_prev),
            &lift_vec(v),
            &lift_vec(u),
        );
        put_columns_by(ex, &r, |j| (j < kept).then_some(s_at + j));
    }

    /// [`VarIntStages::equality_jacobian`] of the midpoint scheme: each block of
    /// `(s_k, v_{k−1}, v_k)` seeded in turn through the generic momenta (ℓ's gradient in
    /// nested duals, or the system's closed-form partials in duals), a velocity's pass evaluating only its interval's half of the
    /// residual; the inputs by one pass through the forces.
    #[allow(clippy::type_complexity)]
    fn midpoint_equality_jacobian<
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NS>, SMatrix<f64, NS, NX>, SMatrix<f64, NS, NW>)
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let l = self.layout;
        l.check(NX, NW, NS + NU);
        let s: SVector<f64, NS> = l.shape(x);
        let v_prev: SVector<f64, NS> = segment(x, l.v_at());
        let u_prev: SVector<f64, NU> = segment(x, l.u_at());
        let v: SVector<f64, NS> = segment(w, 0);
        let u: SVector<f64, NU> = segment(w, NS);
        let e = self.equality::<f64, DOF, DIM, NS, NU, NX, NW>(x, w);
        let mut ex = SMatrix::<f64, NS, NX>::zeros();
        let mut ew = SMatrix::<f64, NS, NW>::zeros();
        let h = self.h;
        // The residual's two halves: the interval before node k (incoming momentum and
        // its force, moved by s_k and v_{k−1}) and the interval after it (outgoing, moved
        // by s_k and v_k). A pass seeded in one velocity evaluates only its half.
        let terms = |incoming: bool,
                     outgoing: bool,
                     s: &SVector<D<NS>, NS>,
                     vp: &SVector<D<NS>, NS>,
                     up: &SVector<D<NS>, NU>,
                     v: &SVector<D<NS>, NS>,
                     u: &SVector<D<NS>, NU>| {
            let (ht, half) = (D::<NS>::from(h), D::<NS>::from(0.5));
            let a_k = self.sys.connection(s);
            let mut r = SVector::<D<NS>, NS>::zeros();
            if outgoing {
                let out = midpoint_outgoing_momentum::<S, D<NS>, DOF, DIM, NS, NU>(
                    self.sys, h, s, v, &a_k,
                );
                let f = interval_force::<S, D<NS>, DOF, DIM, NS, NU>(self.sys, h, s, v, u);
                r += out / ht - f * half;
            }
            if incoming {
                let s_prev = s - vp * ht;
                let inc = midpoint_incoming_momentum::<S, D<NS>, DOF, DIM, NS, NU>(
                    self.sys, h, &s_prev, vp, &a_k,
                );
                let f = interval_force::<S, D<NS>, DOF, DIM, NS, NU>(self.sys, h, &s_prev, vp, up);
                r -= inc / ht + f * half;
            }
            r
        };
        let (ls, lvp, lup, lv, lu) = (
            lift_vec(&s),
            lift_vec(&v_prev),
            lift_vec(&u_prev),
            lift_vec(&v),
            lift_vec(&u),
        );
        put_shape_columns(
            &mut ex,
            l,
            &terms(true, true, &seeded(&s), &lvp, &lup, &lv, &lu),
        );
        put_columns(
            &mut ex,
            l.v_at(),
            &terms(true, false, &ls, &seeded(&v_prev), &lup, &lv, &lu),
        );
        put_columns(
            &mut ew,
            0,
            &terms(false, true, &ls, &lvp, &lup, &seeded(&v), &lu),
        );
        // The inputs enter through the interval forces only: one pass with both seeded.
        let r = self.midpoint_input_columns::<DOF, DIM, NS, NU>(&s, &v_prev, &u_prev, &v, &u);
        for i in 0..NS {
            for j in 0..NU {
                ex[(i, l.u_at() + j)] = r.0[(i, j)];
                ew[(i, NS + j)] = r.1[(i, j)];
            }
        }
        (e, ex, ew)
    }

    /// `∂e/∂u_{k−1}` and `∂e/∂u_k` of the midpoint residual: `−½ ∂F/∂u` at each interval's
    /// midpoint, by one dual pass per interval.
    fn midpoint_input_columns<
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
    >(
        &self,
        s: &SVector<f64, NS>,
        v_prev: &SVector<f64, NS>,
        u_prev: &SVector<f64, NU>,
        v: &SVector<f64, NS>,
        u: &SVector<f64, NU>,
    ) -> (SMatrix<f64, NS, NU>, SMatrix<f64, NS, NU>)
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let h = self.h;
        let column =
            |s_start: &SVector<f64, NS>, vel: &SVector<f64, NS>, inp: &SVector<f64, NU>| {
                let f = dmech::midpoint::interval_force::<S, D<NU>, DOF, DIM, NS, NU>(
                    self.sys,
                    h,
                    &lift_vec(s_start),
                    &lift_vec(vel),
                    &seeded(inp),
                );
                SMatrix::<f64, NS, NU>::from_fn(|i, j| -0.5 * grad_part(&f[i])[j])
            };
        let s_prev = s - v_prev * h;
        (column(&s_prev, v_prev, u_prev), column(s, v, u))
    }
}

/// Writes the gradients of `r` (a pass seeded in `N` variables) into the columns
/// `slot(j)` of `m` (`None`: variable `j` has no column).
fn put_columns_by<const R: usize, const C: usize, const N: usize>(
    m: &mut SMatrix<f64, R, C>,
    r: &SVector<DualSVec64<N>, R>,
    slot: impl Fn(usize) -> Option<usize>,
) {
    for i in 0..R {
        let g = grad_part(&r[i]);
        for j in 0..N {
            if let Some(at) = slot(j) {
                m[(i, at)] = g[j];
            }
        }
    }
}

/// Columns `col .. col + N` of `m` from a pass seeded in `N` variables.
fn put_columns<const R: usize, const C: usize, const N: usize>(
    m: &mut SMatrix<f64, R, C>,
    col: usize,
    r: &SVector<DualSVec64<N>, R>,
) {
    put_columns_by(m, r, |j| Some(col + j));
}

/// The columns of a pass seeded in `s` into the state's carried shape columns (an ignored
/// coordinate's column, zero for an ignorable one, has no place in the state).
fn put_shape_columns<const R: usize, const C: usize, const NS: usize>(
    m: &mut SMatrix<f64, R, C>,
    l: Layout,
    r: &SVector<DualSVec64<NS>, R>,
) {
    put_columns_by(m, r, |j| l.shape_slot(j));
}

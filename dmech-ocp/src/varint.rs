//! The variational-integrator transcription: `x_k = (coords(g_k), s_k, v_{k−1}, u_{k−1})`,
//! `w_k = (v_k, u_k)`.
//!
//! ```text
//! dynamics  x_{k+1} = (coords(g_k exp(−h A(s_k) v_k)), s_k + h v_k, v_k, u_k)
//! equality  e(x_k, w_k) = momentum-matching residual of node k
//!           with (s_{k−1}, v_{k−1}, u_{k−1}) = (s_k − h v_{k−1}, v_{k−1}, u_{k−1})
//! ```
//! At `k = 0`, `v_{−1} = 0`, `u_{−1} = 0` says the robot was at rest before the start.

use crate::layout::{segment, Layout};
use dmech::partials::{grad_part, seeded};
use dmech::variational::{
    discrete_force, incoming_momentum, momentum_matching_residual, outgoing_momentum,
};
use dmech::{ForcingQuadrature, PrincipalKinematicSystem};
use dmech_lie::{LieGroup, Real};
use nalgebra::{SMatrix, SVector};
use num_dual::DualSVec64;

/// Which terms of the momentum-matching residual a derivative pass evaluates.
#[derive(Clone, Copy)]
struct Terms {
    outgoing: bool,
    incoming: bool,
    force: bool,
}

/// The stage functions of the VI transcription of `sys` at step `h`.
pub struct VarIntStages<'a, S> {
    pub sys: &'a S,
    pub h: f64,
    pub quadrature: ForcingQuadrature,
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
            layout: Layout { nc, ns: NS, nu: NU },
        }
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
        let coords: Vec<T> = (0..l.nc).map(|i| x[i]).collect();
        let g =
            <S::Group<T> as LieGroup<DOF, DIM>>::from_coordinates(&coords).expect("layout checked");
        let s: SVector<T, NS> = segment(x, l.s_at());
        let v: SVector<T, NS> = segment(w, 0);
        let u: SVector<T, NU> = segment(w, NS);
        let ht = T::from(self.h);
        let xi = -(self.sys.connection(&s) * v);
        let g_next = g.compose(&<S::Group<T> as LieGroup<DOF, DIM>>::exp(&(xi * ht)));
        let s_next = s + v * ht;
        let mut out = SVector::<T, NX>::zeros();
        for (i, c) in g_next.coordinates().into_iter().enumerate() {
            out[i] = c;
        }
        for i in 0..NS {
            out[l.s_at() + i] = s_next[i];
            out[l.v_at() + i] = v[i];
        }
        for i in 0..NU {
            out[l.u_at() + i] = u[i];
        }
        out
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
        let s: SVector<T, NS> = segment(x, l.s_at());
        let v_prev: SVector<T, NS> = segment(x, l.v_at());
        let u_prev: SVector<T, NU> = segment(x, l.u_at());
        let v: SVector<T, NS> = segment(w, 0);
        let u: SVector<T, NU> = segment(w, NS);
        let s_prev = s - v_prev * T::from(self.h);
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
        T: Real,
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
    >(
        &self,
        terms: Terms,
        s: &SVector<T, NS>,
        v_prev: &SVector<T, NS>,
        u_prev: &SVector<T, NU>,
        v: &SVector<T, NS>,
        u: &SVector<T, NU>,
    ) -> SVector<T, NS>
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let ht = T::from(self.h);
        let a_k = self.sys.connection(s);
        let mut r = SVector::<T, NS>::zeros();
        if terms.outgoing {
            r += outgoing_momentum::<S, T, DOF, DIM, NS, NU>(self.sys, self.h, s, v, &a_k) / ht;
        }
        let s_prev = s - v_prev * ht;
        if terms.incoming {
            r -= incoming_momentum::<S, T, DOF, DIM, NS, NU>(
                self.sys, self.h, &s_prev, v_prev, &a_k,
            ) / ht;
        }
        if terms.force {
            r -= discrete_force::<S, T, DOF, DIM, NS, NU>(
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
    /// quadrature. The group coordinates do not enter. About 3× cheaper than seeding all of
    /// `x` and `w` (`docs/ocp.md`); checked against that generic path in a test.
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
        let l = self.layout;
        l.check(NX, NW, NS + NU);
        let s: SVector<f64, NS> = segment(x, l.s_at());
        let v_prev: SVector<f64, NS> = segment(x, l.v_at());
        let u_prev: SVector<f64, NU> = segment(x, l.u_at());
        let v: SVector<f64, NS> = segment(w, 0);
        let u: SVector<f64, NU> = segment(w, NS);
        let e = self.equality::<f64, DOF, DIM, NS, NU, NX, NW>(x, w);
        let mut ex = SMatrix::<f64, NS, NX>::zeros();
        let mut ew = SMatrix::<f64, NS, NW>::zeros();
        let (left, right) = match self.quadrature {
            ForcingQuadrature::Left => (true, false),
            ForcingQuadrature::Right => (false, true),
            ForcingQuadrature::Midpoint => (true, true),
        };
        type Ds<const N: usize> = DualSVec64<N>;
        let c_ns = |z: &SVector<f64, NS>| z.map(Ds::<NS>::from_re);
        let c_nu = |z: &SVector<f64, NU>| z.map(Ds::<NU>::from_re);
        let c_ns_u = |z: &SVector<f64, NS>| z.map(Ds::<NU>::from_re);
        let mut put = |col: usize, in_x: bool, r: &SVector<Ds<NS>, NS>| {
            for i in 0..NS {
                let g = grad_part(&r[i]);
                for j in 0..NS {
                    if in_x {
                        ex[(i, col + j)] = g[j];
                    } else {
                        ew[(i, col + j)] = g[j];
                    }
                }
            }
        };
        // s_k: every term.
        let all = Terms {
            outgoing: true,
            incoming: true,
            force: true,
        };
        let r = self.equality_terms::<_, DOF, DIM, NS, NU>(
            all,
            &seeded(&s),
            &c_ns(&v_prev),
            &u_prev.map(Ds::<NS>::from_re),
            &c_ns(&v),
            &u.map(Ds::<NS>::from_re),
        );
        put(l.s_at(), true, &r);
        // v_{k−1}: the incoming momentum, and the force if it reads the previous interval.
        let terms = Terms {
            outgoing: false,
            incoming: true,
            force: left,
        };
        let r = self.equality_terms::<_, DOF, DIM, NS, NU>(
            terms,
            &c_ns(&s),
            &seeded(&v_prev),
            &u_prev.map(Ds::<NS>::from_re),
            &c_ns(&v),
            &u.map(Ds::<NS>::from_re),
        );
        put(l.v_at(), true, &r);
        // v_k: the outgoing momentum, and the force if it reads the current interval.
        let terms = Terms {
            outgoing: true,
            incoming: false,
            force: right,
        };
        let r = self.equality_terms::<_, DOF, DIM, NS, NU>(
            terms,
            &c_ns(&s),
            &c_ns(&v_prev),
            &u_prev.map(Ds::<NS>::from_re),
            &seeded(&v),
            &u.map(Ds::<NS>::from_re),
        );
        put(0, false, &r);
        // The inputs enter through the force only.
        let force = Terms {
            outgoing: false,
            incoming: false,
            force: true,
        };
        for (seed_prev, at, in_x) in [(true, l.u_at(), true), (false, NS, false)] {
            if (seed_prev && !left) || (!seed_prev && !right) {
                continue;
            }
            let (up, uk) = if seed_prev {
                (seeded(&u_prev), c_nu(&u))
            } else {
                (c_nu(&u_prev), seeded(&u))
            };
            let r = self.equality_terms::<_, DOF, DIM, NS, NU>(
                force,
                &c_ns_u(&s),
                &c_ns_u(&v_prev),
                &up,
                &c_ns_u(&v),
                &uk,
            );
            for i in 0..NS {
                let g = grad_part(&r[i]);
                for j in 0..NU {
                    if in_x {
                        ex[(i, at + j)] = g[j];
                    } else {
                        ew[(i, at + j)] = g[j];
                    }
                }
            }
        }
        (e, ex, ew)
    }
}

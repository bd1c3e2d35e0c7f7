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

use crate::transcription::layout::{segment, Layout};
use dmech::midpoint::interval_body_velocity;
use dmech::variational::{
    discrete_force, incoming_momentum_dual, momentum_matching_residual, outgoing_momentum_dual,
};
use dmech::{Discretisation, ForcingQuadrature, PrincipalKinematicSystem};
use dmech_lie::dual::{grad_part, seeded_from};
use dmech_lie::{LieGroup, Real};
use nalgebra::{SMatrix, SVector};
use num_dual::DualSVec64;

pub(crate) type D<const N: usize> = DualSVec64<N>;

/// Which terms of the momentum-matching residual a derivative pass evaluates.
#[derive(Clone, Copy)]
pub(crate) struct Terms {
    pub(crate) outgoing: bool,
    pub(crate) incoming: bool,
    pub(crate) force: bool,
}

impl Terms {
    /// The whole residual.
    pub(crate) const ALL: Terms = Terms {
        outgoing: true,
        incoming: true,
        force: true,
    };
    /// The force alone (the only term that reads the inputs).
    pub(crate) const FORCE: Terms = Terms {
        outgoing: false,
        incoming: false,
        force: true,
    };

    /// The terms of the interval before the node: the incoming momentum, and the force if
    /// it reads that interval.
    pub(crate) fn previous_interval(force: bool) -> Terms {
        Terms {
            outgoing: false,
            incoming: true,
            force,
        }
    }

    /// The terms of the interval after the node: the outgoing momentum, and the force if
    /// it reads that interval.
    pub(crate) fn current_interval(force: bool) -> Terms {
        Terms {
            outgoing: true,
            incoming: false,
            force,
        }
    }
}

/// The blocks of `(x_k, w_k)` the stage equality reads: `s_k`, `v_{k−1}`, `u_{k−1}` from the
/// state, `v_k`, `u_k` from the decision (the group coordinates it never reads).
pub(crate) struct NodePoint<T: nalgebra::Scalar, const NS: usize, const NU: usize> {
    pub(crate) s: SVector<T, NS>,
    pub(crate) v_prev: SVector<T, NS>,
    pub(crate) u_prev: SVector<T, NU>,
    pub(crate) v: SVector<T, NS>,
    pub(crate) u: SVector<T, NU>,
}

impl<T: Real, const NS: usize, const NU: usize> NodePoint<T, NS, NU> {
    /// The blocks of `(x, w)` in `layout` (`w` starts with `(v_k, u_k)`).
    pub(crate) fn of<const NX: usize, const NW: usize>(
        layout: Layout,
        x: &SVector<T, NX>,
        w: &SVector<T, NW>,
    ) -> Self {
        NodePoint {
            s: layout.shape(x),
            v_prev: segment(x, layout.v_at()),
            u_prev: segment(x, layout.u_at()),
            v: segment(w, 0),
            u: segment(w, NS),
        }
    }
}

/// The stage functions of the VI transcription of `sys` at step `h`.
#[derive(Clone, Copy)]
pub struct VarIntStages<'a, S> {
    /// The system.
    pub sys: &'a S,
    /// The step.
    pub h: f64,
    /// Where the first-order scheme reads the force.
    pub quadrature: ForcingQuadrature,
    /// The discretisation of the principle.
    pub discretisation: Discretisation,
    /// Where each quantity sits in the stage vectors.
    pub layout: Layout,
}

impl<'a, S> VarIntStages<'a, S> {
    /// `sys`'s first-order stage functions at step `h` with the forcing `quadrature`, every
    /// shape position in the state.
    pub fn new<const DOF: usize, const NS: usize, const NU: usize>(
        sys: &'a S,
        h: f64,
        quadrature: ForcingQuadrature,
    ) -> Self
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let np = <S::Group<f64> as LieGroup<DOF>>::identity()
            .coordinates()
            .len();
        VarIntStages {
            sys,
            h,
            quadrature,
            discretisation: Discretisation::FirstOrder,
            layout: Layout::new(np, NS, NU),
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
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let l = self.layout;
        l.check(NX, NW, NS + NU);
        let g_next = self.group_step::<T, DOF, NS, NU, NX, NW>(x, w);
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
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let l = self.layout;
        let g = <S::Group<T> as LieGroup<DOF>>::from_coordinates(&x.as_slice()[..l.np])
            .expect("layout checked");
        let s: SVector<T, NS> = l.shape(x);
        let v: SVector<T, NS> = segment(w, 0);
        let xi = match self.discretisation {
            Discretisation::FirstOrder => -(self.sys.connection(&s) * v),
            Discretisation::Midpoint => {
                interval_body_velocity::<S, T, DOF, NS, NU>(self.sys, self.h, &s, &v)
            }
        };
        g.compose(&<S::Group<T> as LieGroup<DOF>>::exp(
            &(xi * T::from(self.h)),
        ))
    }

    /// `(f, F_x, F_w)` of [`VarIntStages::dynamics`]: the group rows by one vector-dual pass
    /// of width `NX` through `VarIntStages::group_step`, the other rows written out (they
    /// are linear: `s_{k+1} = s_k + h v_k`, `(v_k, u_k)` copied). The group step reads only
    /// `(coords(g_k), s_k)` of `x` and all of `w`; `w` is seeded in the directions of the
    /// entries of `x` it does not read, `(v_{k−1}, u_{k−1})`, which `w = (v_k, u_k)` fills
    /// exactly. Each direction of a vector dual is propagated on its own, so the columns
    /// are the two-pass default's to the bit (checked against it in a test); the linear
    /// rows' entries `1`, `h` are what a dual pass gives for them, exactly.
    #[allow(clippy::type_complexity)]
    pub fn dynamics_jacobian<
        const DOF: usize,
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
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
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
        let g_next = self.group_step::<D<NX>, DOF, NS, NU, NX, NW>(&xd, &wd);
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
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        self.layout.check(NX, NW, NS + NU);
        let NodePoint {
            s,
            v_prev,
            u_prev,
            v,
            u,
        } = NodePoint::<T, NS, NU>::of(self.layout, x, w);
        let s_prev = s - v_prev * T::from(self.h);
        momentum_matching_residual(
            self.sys,
            self.h,
            self.discretisation,
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
    pub(crate) fn equality_terms<
        const DOF: usize,
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
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let ht = D::<N>::from(self.h);
        let a_k = self.sys.connection(s);
        let mut r = SVector::<D<N>, NS>::zeros();
        if terms.outgoing {
            r += outgoing_momentum_dual::<S, DOF, NS, NU, N>(self.sys, self.h, s, v, &a_k) / ht;
        }
        let s_prev = s - v_prev * ht;
        if terms.incoming {
            r -= incoming_momentum_dual::<S, DOF, NS, NU, N>(
                self.sys, self.h, &s_prev, v_prev, &a_k,
            ) / ht;
        }
        if terms.force {
            r -= discrete_force::<S, D<N>, DOF, NS, NU>(
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
}

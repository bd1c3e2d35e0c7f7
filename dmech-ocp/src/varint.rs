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
use dmech::variational::momentum_matching_residual;
use dmech::{ForcingQuadrature, PrincipalKinematicSystem};
use dmech_lie::{LieGroup, Real};
use nalgebra::SVector;

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
}

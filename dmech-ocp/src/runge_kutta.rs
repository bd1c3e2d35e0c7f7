//! The Runge–Kutta transcriptions of the continuous model:
//! `x_k = (coords(g_k), s_k, v_k, u_{k−1})`, `w_k = u_k`, `x_{k+1} = (RK step with u_k held, u_k)`.

use crate::layout::{segment, Layout};
use dmech::continuous::{acceleration, acceleration_dual, coordinate_rate};
use dmech::partials::{lift_vec, seeded, split_passes};
use dmech::{PrincipalKinematicSystem, RungeKutta};
use dmech_lie::{LieGroup, Real};
use nalgebra::{SMatrix, SVector};
use num_dual::DualSVec64;

/// The shape acceleration `(s, v, u) ↦ v̇` a Runge–Kutta step evaluates (`None`: singular
/// mass matrix).
type Accel<'f, T, const NS: usize, const NU: usize> =
    dyn Fn(&SVector<T, NS>, &SVector<T, NS>, &SVector<T, NU>) -> Option<SVector<T, NS>> + 'f;

/// The stage functions of an RK transcription of `sys` at step `h`.
pub struct RkStages<'a, S> {
    pub sys: &'a S,
    pub h: f64,
    pub method: RungeKutta,
    pub layout: Layout,
}

impl<'a, S> RkStages<'a, S> {
    pub fn new<const DOF: usize, const DIM: usize, const NS: usize, const NU: usize>(
        sys: &'a S,
        h: f64,
        method: RungeKutta,
    ) -> Self
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let nc = <S::Group<f64> as LieGroup<DOF, DIM>>::identity()
            .coordinates()
            .len();
        RkStages {
            sys,
            h,
            method,
            layout: Layout { nc, ns: NS, nu: NU },
        }
    }

    /// The time derivative of the state at constant input (zero in the `u_{k−1}` slots).
    /// A singular mass matrix gives NaN, which a solver reports as a failed evaluation.
    fn rate<
        T: Real,
        const DOF: usize,
        const DIM: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
    >(
        &self,
        x: &SVector<T, NX>,
        u: &SVector<T, NU>,
        acceleration: &Accel<T, NS, NU>,
    ) -> SVector<T, NX>
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let l = self.layout;
        let coords: Vec<T> = (0..l.nc).map(|i| x[i]).collect();
        let g =
            <S::Group<T> as LieGroup<DOF, DIM>>::from_coordinates(&coords).expect("layout checked");
        let s: SVector<T, NS> = segment(x, l.s_at());
        let v: SVector<T, NS> = segment(x, l.v_at());
        let xi = -(self.sys.connection(&s) * v);
        let gdot = coordinate_rate::<_, T, DOF, DIM>(&g, &xi);
        let a = acceleration(&s, &v, u).unwrap_or_else(|| SVector::from_element(T::from(f64::NAN)));
        let mut out = SVector::<T, NX>::zeros();
        for (i, c) in gdot.into_iter().enumerate() {
            out[i] = c;
        }
        for i in 0..NS {
            out[l.s_at() + i] = v[i];
            out[l.v_at() + i] = a[i];
        }
        out
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
        self.dynamics_with::<T, DOF, DIM, NS, NU, NX, NW>(x, w, &|s, v, u| {
            acceleration::<S, T, DOF, DIM, NS, NU>(self.sys, s, v, u)
        })
    }

    /// `(f, F_x, F_w)`, exact: two vector-dual passes (seeded in `x`, then in `w`) whose
    /// accelerations take their derivatives by the implicit function theorem
    /// ([`acceleration_dual`]) instead of duals nested three deep in `ℓ`; checked against
    /// the generic path in a test.
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
        let fx = self.dynamics_with::<DualSVec64<NX>, DOF, DIM, NS, NU, NX, NW>(
            &seeded(x),
            &lift_vec(w),
            &|s, v, u| acceleration_dual::<S, DOF, DIM, NS, NU, NX>(self.sys, s, v, u),
        );
        let fw = self.dynamics_with::<DualSVec64<NW>, DOF, DIM, NS, NU, NX, NW>(
            &lift_vec(x),
            &seeded(w),
            &|s, v, u| acceleration_dual::<S, DOF, DIM, NS, NU, NW>(self.sys, s, v, u),
        );
        split_passes(&fx, &fw)
    }

    /// The RK step with a given acceleration function.
    fn dynamics_with<
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
        acceleration: &Accel<T, NS, NU>,
    ) -> SVector<T, NX>
    where
        S: PrincipalKinematicSystem<DOF, DIM, NS, NU, Param = f64>,
    {
        let l = self.layout;
        l.check(NX, NW, NU);
        let u: SVector<T, NU> = segment(w, 0);
        let h = T::from(self.h);
        let half = T::from(0.5);
        let f = |y: &SVector<T, NX>| self.rate::<T, DOF, DIM, NS, NU, NX>(y, &u, acceleration);
        let mut next = match self.method {
            RungeKutta::Rk1 => x + f(x) * h,
            RungeKutta::Rk2 => {
                let k1 = f(x);
                x + f(&(x + k1 * (h * half))) * h
            }
            RungeKutta::Rk4 => {
                let k1 = f(x);
                let k2 = f(&(x + k1 * (h * half)));
                let k3 = f(&(x + k2 * (h * half)));
                let k4 = f(&(x + k3 * h));
                x + (k1 + k2 * T::from(2.0) + k3 * T::from(2.0) + k4) * (h / T::from(6.0))
            }
        };
        for i in 0..NU {
            next[l.u_at() + i] = u[i];
        }
        next
    }
}

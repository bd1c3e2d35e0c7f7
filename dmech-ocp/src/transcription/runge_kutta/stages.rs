//! The Runge–Kutta transcriptions of the continuous model:
//! `x_k = (coords(g_k), s_k, v_k, u_{k−1})`, `w_k = u_k`, `x_{k+1} = (RK step with u_k held, u_k)`.

use crate::transcription::layout::{segment, Layout};
use dmech::continuous::{acceleration, acceleration_jacobian, coordinate_rate};
use dmech::{PrincipalKinematicSystem, RungeKutta};
use dmech_lie::dual::{grad_part, jacobian_part, seeded};
use dmech_lie::{LieGroup, Real};
use nalgebra::{SMatrix, SVector};
use num_dual::DualSVec64;

/// The shape acceleration `(s, v, u) ↦ v̇` a Runge–Kutta step evaluates (`None`: singular
/// mass matrix).
type Accel<'f, T, const NS: usize, const NU: usize> =
    dyn Fn(&SVector<T, NS>, &SVector<T, NS>, &SVector<T, NU>) -> Option<SVector<T, NS>> + 'f;

/// The stage functions of an RK transcription of `sys` at step `h`.
pub struct RkStages<'a, S> {
    /// The system.
    pub sys: &'a S,
    /// The step.
    pub h: f64,
    /// The Runge–Kutta method.
    pub method: RungeKutta,
    /// Where each quantity sits in the stage vectors.
    pub layout: Layout,
}

impl<'a, S> RkStages<'a, S> {
    /// `sys`'s stage functions at step `h` with `method`, every shape position in the state.
    pub fn new<const DOF: usize, const NS: usize, const NU: usize>(
        sys: &'a S,
        h: f64,
        method: RungeKutta,
    ) -> Self
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let np = <S::Group<f64> as LieGroup<DOF>>::identity()
            .coordinates()
            .len();
        RkStages {
            sys,
            h,
            method,
            layout: Layout::new(np, NS, NU),
        }
    }

    /// The time derivative of the state at constant input (zero in the `u_{k−1}` slots).
    /// A singular mass matrix gives NaN, which a solver reports as a failed evaluation.
    fn rate<T: Real, const DOF: usize, const NS: usize, const NU: usize, const NX: usize>(
        &self,
        x: &SVector<T, NX>,
        u: &SVector<T, NU>,
        acceleration: &Accel<T, NS, NU>,
    ) -> SVector<T, NX>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let l = self.layout;
        let coords: Vec<T> = (0..l.np).map(|i| x[i]).collect();
        let g = <S::Group<T> as LieGroup<DOF>>::from_coordinates(&coords).expect("layout checked");
        let s: SVector<T, NS> = segment(x, l.s_at());
        let v: SVector<T, NS> = segment(x, l.v_at());
        let xi = -(self.sys.connection(&s) * v);
        let gdot = coordinate_rate::<_, T, DOF>(&g, &xi);
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
        self.dynamics_with::<T, DOF, NS, NU, NX, NW>(x, w, &|s, v, u| {
            self.sys
                .closed_form_acceleration(s, v, u)
                .or_else(|| acceleration::<S, T, DOF, NS, NU>(self.sys, s, v, u))
        })
    }

    /// `(f, F_x, F_w)`, exact, by the chain rule through the method's stages: each stage
    /// evaluation's rate Jacobian (`RkStages::rate_jacobian`) takes the acceleration's
    /// derivatives from the system's closed form where it supplies one, else by the implicit
    /// function theorem with only the blocks the equations of motion read seeded
    /// ([`acceleration_jacobian`]), and the stages are composed in `f64`
    /// (`dK_i = F(Y_i) dY_i`, `dY_i = I + h Σ_j a_ij dK_j`). Checked against the generic
    /// path in a test. A singular mass matrix gives NaN, as in [`RkStages::dynamics`].
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
        l.check(NX, NW, NU);
        let u: SVector<f64, NU> = segment(w, 0);
        let h = self.h;
        let rate = |y: &SVector<f64, NX>| self.rate_jacobian::<DOF, NS, NU, NX>(y, &u);
        let eye = SMatrix::<f64, NX, NX>::identity();
        // (K, dK/dx, dK/du) of one stage at Y = x + c·Σ, from the stage point's derivatives.
        let stage =
            |y: &SVector<f64, NX>, dy: &SMatrix<f64, NX, NX>, dyu: &SMatrix<f64, NX, NU>| {
                rate(y).map(|(k, fx, fu)| (k, fx * dy, fx * dyu + fu))
            };
        let zu = SMatrix::<f64, NX, NU>::zeros();
        let combined = match self.method {
            RungeKutta::Rk1 => stage(x, &eye, &zu),
            RungeKutta::Rk2 => stage(x, &eye, &zu).and_then(|(k1, d1, d1u)| {
                let c = 0.5 * h;
                stage(&(x + k1 * c), &(eye + d1 * c), &(d1u * c))
            }),
            RungeKutta::Rk4 => stage(x, &eye, &zu).and_then(|(k1, d1, d1u)| {
                let c = 0.5 * h;
                let (k2, d2, d2u) = stage(&(x + k1 * c), &(eye + d1 * c), &(d1u * c))?;
                let (k3, d3, d3u) = stage(&(x + k2 * c), &(eye + d2 * c), &(d2u * c))?;
                let (k4, d4, d4u) = stage(&(x + k3 * h), &(eye + d3 * h), &(d3u * h))?;
                Some((
                    (k1 + (k2 + k3) * 2.0 + k4) / 6.0,
                    (d1 + (d2 + d3) * 2.0 + d4) / 6.0,
                    (d1u + (d2u + d3u) * 2.0 + d4u) / 6.0,
                ))
            }),
        };
        let Some((k, dk, dku)) = combined else {
            let nan = f64::NAN;
            return (
                SVector::from_element(nan),
                SMatrix::from_element(nan),
                SMatrix::from_element(nan),
            );
        };
        let mut next = x + k * h;
        let mut fx = eye + dk * h;
        let mut fw = SMatrix::<f64, NX, NW>::from_fn(|r, c| h * dku[(r, c)]);
        for i in 0..NU {
            let row = l.u_at() + i;
            next[row] = u[i];
            fx.row_mut(row).fill(0.0);
            fw.row_mut(row).fill(0.0);
            fw[(row, i)] = 1.0;
        }
        (next, fx, fw)
    }

    /// The rate at `x` with input `u` and its Jacobians `(F_x, F_u)`: the group coordinates'
    /// rate by one vector-dual pass seeded in `x` (it reads `coords(g)`, `s` and `v`), the
    /// acceleration's rows from the system's closed form
    /// ([`PrincipalKinematicSystem::closed_form_acceleration`], one pass seeded in `x` and one
    /// in `u`) or else from [`acceleration_jacobian`]. `None` if the generic mass matrix is
    /// singular (a closed form reports it as NaN).
    #[allow(clippy::type_complexity)]
    fn rate_jacobian<const DOF: usize, const NS: usize, const NU: usize, const NX: usize>(
        &self,
        x: &SVector<f64, NX>,
        u: &SVector<f64, NU>,
    ) -> Option<(SVector<f64, NX>, SMatrix<f64, NX, NX>, SMatrix<f64, NX, NU>)>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let l = self.layout;
        let s: SVector<f64, NS> = segment(x, l.s_at());
        let v: SVector<f64, NS> = segment(x, l.v_at());
        let xd = seeded(x);
        let coords: Vec<DualSVec64<NX>> = (0..l.np).map(|i| xd[i]).collect();
        let g = <S::Group<DualSVec64<NX>> as LieGroup<DOF>>::from_coordinates(&coords)
            .expect("layout checked");
        let sd: SVector<DualSVec64<NX>, NS> = segment(&xd, l.s_at());
        let vd: SVector<DualSVec64<NX>, NS> = segment(&xd, l.v_at());
        // The system's closed form: one pass seeded in the stage (it reads `s` and `v`), one
        // in the input.
        let closed = self
            .sys
            .closed_form_acceleration(&sd, &vd, &u.map(DualSVec64::from_re))
            .zip(self.sys.closed_form_acceleration(
                &s.map(DualSVec64::<NU>::from_re),
                &v.map(DualSVec64::<NU>::from_re),
                &seeded(u),
            ));
        let (a, a_x, a_u) = match closed {
            Some((ax, au)) => (ax.map(|d| d.re), jacobian_part(&ax), jacobian_part(&au)),
            None => {
                let acc = acceleration_jacobian::<S, DOF, NS, NU>(self.sys, &s, &v, u)?;
                let mut a_x = SMatrix::<f64, NS, NX>::zeros();
                a_x.fixed_columns_mut::<NS>(l.s_at()).copy_from(&acc.a_s);
                a_x.fixed_columns_mut::<NS>(l.v_at()).copy_from(&acc.a_v);
                (acc.a, a_x, acc.a_u)
            }
        };
        let gdot = coordinate_rate::<_, _, DOF>(&g, &(-(self.sys.connection(&sd) * vd)));
        let mut f = SVector::<f64, NX>::zeros();
        let mut fx = SMatrix::<f64, NX, NX>::zeros();
        let mut fu = SMatrix::<f64, NX, NU>::zeros();
        for (i, c) in gdot.iter().enumerate() {
            f[i] = c.re;
            fx.set_row(i, &grad_part(c).transpose());
        }
        for i in 0..NS {
            let (rs, rv) = (l.s_at() + i, l.v_at() + i);
            f[rs] = v[i];
            fx[(rs, rv)] = 1.0;
            f[rv] = a[i];
            fx.row_mut(rv).copy_from(&a_x.row(i));
            fu.row_mut(rv).copy_from(&a_u.row(i));
        }
        Some((f, fx, fu))
    }

    /// The RK step with a given acceleration function.
    fn dynamics_with<
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
        acceleration: &Accel<T, NS, NU>,
    ) -> SVector<T, NX>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let l = self.layout;
        l.check(NX, NW, NU);
        let u: SVector<T, NU> = segment(w, 0);
        let h = T::from(self.h);
        let half = T::from(0.5);
        let f = |y: &SVector<T, NX>| self.rate::<T, DOF, NS, NU, NX>(y, &u, acceleration);
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

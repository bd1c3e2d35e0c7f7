//! The WIP with its current dynamics replaced by their steady state: the paper's
//! "algebraic current" (`docs/wip.md`: "constant current") variant,
//! `0 = u − R_m i − k_e n_wm (φ̇ − α̇)`.
//!
//! A principal-kinematic system of its own on SE(2) × R³, shape `s = (α, φR, φL)`: with
//! `L_m = 0` the charge coordinates carry no kinetic energy and the charges' Euler–Lagrange
//! equations are the algebraic relation above; what the currents do to the mechanics (the
//! back-EMF term `−k_e n_wm (φ̇ − α̇) q` of ℓ, differentiated in time) is the motor torque
//! `k_m n_wm i` on the wheel and its reaction on the body. So
//! `ℓ_a(s, v, ξ) = ℓ((s, 0, 0), (v, 0, 0), ξ)` and
//! `F_a = (fR + fL − k n (iR + iL), −fR + k n iR, −fL + k n iL)`, `i = (u − k n w)/R_m`.
//! The integrators and the transcriptions of `dmech` apply unchanged.

use super::closed_form;
use super::Wip;
use dmech::{Lift, Param, PrincipalKinematicSystem};
use dmech_lie::{Real, Se2};
use nalgebra::{SMatrix, SVector};

/// The WIP with algebraic currents; `P` is the parameter scalar.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WipAlgebraicCurrent<P = f64> {
    /// The full model whose mechanics this one shares (`L_m` is not read).
    pub wip: Wip<P>,
}

impl<P: Real> WipAlgebraicCurrent<P> {
    pub fn new(wip: Wip<P>) -> Self {
        WipAlgebraicCurrent { wip }
    }

    /// The steady-state currents `(iR, iL)` at shape velocity `v = (v_α, v_φR, v_φL)` and
    /// voltages `u` ([`super::WipParams::steady_current`]).
    pub fn currents<T: Lift<P>>(&self, v: &SVector<T, 3>, u: &SVector<T, 2>) -> [T; 2] {
        let p = &self.wip.params;
        [
            p.steady_current(u[0], v[1] - v[0]),
            p.steady_current(u[1], v[2] - v[0]),
        ]
    }
}

/// `(s, 0, 0)`: the full model's shape with the charges (or currents) zero.
fn with_zero_charges<T: Real>(s: &SVector<T, 3>) -> SVector<T, 5> {
    SVector::<T, 5>::new(s[0], s[1], s[2], T::zero(), T::zero())
}

impl<P: Real> PrincipalKinematicSystem<3, 3, 2> for WipAlgebraicCurrent<P> {
    type Param = P;
    type Group<T: Real> = Se2<T>;

    fn reduced_lagrangian<T: Lift<P>>(
        &self,
        s: &SVector<T, 3>,
        v: &SVector<T, 3>,
        xi: &SVector<T, 3>,
    ) -> T {
        self.wip
            .reduced_lagrangian(&with_zero_charges(s), &with_zero_charges(v), xi)
    }

    /// The wheel angles, as in the full model.
    fn ignorable_shape(&self) -> &'static [usize] {
        &[1, 2]
    }

    fn connection<T: Lift<P>>(&self, s: &SVector<T, 3>) -> SMatrix<T, 3, 3> {
        self.wip
            .connection(&with_zero_charges(s))
            .fixed_columns::<3>(0)
            .into_owned()
    }

    fn forcing<T: Lift<P>>(
        &self,
        s: &SVector<T, 3>,
        v: &SVector<T, 3>,
        u: &SVector<T, 2>,
    ) -> SVector<T, 3> {
        // The full model's friction on the mechanical coordinates, plus the motor torques.
        let f = self
            .wip
            .forcing(&with_zero_charges(s), &with_zero_charges(v), u);
        let kn = Param(self.wip.params.k_e) * Param(self.wip.params.n_wm);
        let [ir, il] = self.currents(v, u);
        let (tr, tl) = (kn * ir, kn * il);
        SVector::<T, 3>::new(f[0] - tr - tl, f[1] + tr, f[2] + tl)
    }

    /// The full model's closed-form partials at zero charges and currents, restricted to
    /// the mechanical coordinates (`ℓ_a` is `ℓ` there).
    fn closed_form_lagrangian_gradient<T: Lift<P>>(
        &self,
        s: &SVector<T, 3>,
        v: &SVector<T, 3>,
        xi: &SVector<T, 3>,
    ) -> Option<(SVector<T, 3>, SVector<T, 3>, SVector<T, 3>)> {
        let (ls, lv, lxi) = self.wip.closed_form_lagrangian_gradient(
            &with_zero_charges(s),
            &with_zero_charges(v),
            xi,
        )?;
        Some((
            ls.fixed_rows::<3>(0).into_owned(),
            lv.fixed_rows::<3>(0).into_owned(),
            lxi,
        ))
    }

    /// [`closed_form::shape_acceleration`] at the steady-state currents. Checked against the
    /// generic path in `tests/model/wip_continuous.rs`.
    fn closed_form_acceleration<T: Lift<P>>(
        &self,
        s: &SVector<T, 3>,
        v: &SVector<T, 3>,
        u: &SVector<T, 2>,
    ) -> Option<SVector<T, 3>> {
        let sys = self.wip.lifted::<T>();
        let a = closed_form::shape_acceleration(
            &sys,
            s[0],
            [v[0], v[1], v[2]],
            self.currents(v, u),
            [T::zero(); 3],
        )
        .unwrap_or([T::from(f64::NAN); 3]);
        Some(SVector::from(a))
    }
}

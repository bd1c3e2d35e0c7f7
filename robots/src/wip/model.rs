//! The WIP as a [`PrincipalKinematicSystem`] on SE(2) × R⁵: reduced Lagrangian, connection,
//! forcing. This is all the integrators and the continuous model need.

use super::closed_form;
use super::params::WipParams;
use dmech::{Lift, Param, PrincipalKinematicSystem};
use dmech_lie::{Real, Se2};
use nalgebra::{SMatrix, SVector};

/// The wheeled inverted pendulum with DC motors; `P` is the parameter scalar.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wip<P = f64> {
    pub params: WipParams<P>,
    /// Offsets `(δ_R, δ_L)` of the two wheels' radii from `r` (zero in the paper's model;
    /// the `wheel_radius_asymmetry` effect of `wip diagnose`). They enter the connection
    /// only: the wheels' inertias stay those of the table.
    pub wheel_radius_offsets: [P; 2],
    /// `J_e`, a kinetic term `−½ J_e ((φ̇R − α̇)² + (φ̇L − α̇)²)`: zero in the full model.
    /// When the current is eliminated (`i` algebraic), `J_e = (k_e n_wm)² L_m / R_m²` is
    /// the first-order singular-perturbation correction of the current's lag: the lag
    /// adds a torque `(k_e n_wm)² (L_m/R_m²) ẇ` on each wheel (`docs/diagnose.md`).
    pub quasi_static_inertia: P,
}

impl<P: Real> Wip<P> {
    pub fn new(params: WipParams<P>) -> Self {
        Wip {
            params,
            wheel_radius_offsets: [P::zero(); 2],
            quasi_static_inertia: P::zero(),
        }
    }

    /// The same robot with its parameters lifted into the scalar `T`.
    pub fn lifted<T: Lift<P>>(&self) -> Wip<T> {
        Wip {
            params: self.params.map(T::lift),
            wheel_radius_offsets: self.wheel_radius_offsets.map(T::lift),
            quasi_static_inertia: T::lift(self.quasi_static_inertia),
        }
    }
}

impl Default for Wip<f64> {
    fn default() -> Self {
        Wip::new(WipParams::default())
    }
}

/// Gear/bearing friction torque at relative wheel speed `w = φ̇ − α̇`. The parameters are
/// anything that multiplies `T`: `Param`s of the model's scalar (a scalar product in dual
/// arithmetic), or values of `T` itself (the closed form, whose parameters are `T`).
pub fn friction<M, T>(d_v: M, d_c: M, d_0: M, w: T) -> T
where
    M: std::ops::Mul<T, Output = T> + Copy,
    T: Real,
{
    d_v * w + d_c * tanh_saturating(d_0 * w)
}

pub use dmech_lie::scalar::tanh_saturating;

/// The body's motion at `g = e` with body velocity `ξ`: its centre of mass at height `l`
/// moves at `vb`, it turns at `ωb` (body frame), and `(sin α, cos α)`. What `ℓ` and its
/// partials share.
struct BodyMotion<T> {
    vb: [T; 3],
    wb: [T; 3],
    sa: T,
    ca: T,
}

fn body_motion<P: Real, T: Lift<P>>(
    l: Param<P>,
    al: T,
    va: T,
    xi: &SVector<T, 3>,
) -> BodyMotion<T> {
    let (x1, x2, w) = (xi[0], xi[1], xi[2]);
    let (sa, ca) = al.sin_cos();
    BodyMotion {
        vb: [x1 + l * (va * ca), x2 + l * (w * sa), -(l * (va * sa))],
        wb: [-(w * sa), va, w * ca],
        sa,
        ca,
    }
}

impl<P: Real> PrincipalKinematicSystem<3, 5, 2> for Wip<P> {
    type Param = P;
    type Group<T: Real> = Se2<T>;

    fn reduced_lagrangian<T: Lift<P>>(
        &self,
        s: &SVector<T, 5>,
        v: &SVector<T, 5>,
        xi: &SVector<T, 3>,
    ) -> T {
        // Parameters multiply as `Param`s: a scalar product in dual arithmetic.
        let p = self.params.map(Param);
        let (al, qr, ql) = (s[0], s[3], s[4]);
        let (va, vr, vl, ir, il) = (v[0], v[1], v[2], v[3], v[4]);
        let (x1, x2, w) = (xi[0], xi[1], xi[2]);

        // Body: centre of mass at height l, at g = e (θ = 0) with body velocity ξ.
        let BodyMotion { vb, wb, ca, .. } = body_motion(p.l, al, va, xi);
        let ([vb0, vb1, vb2], [wb0, wb1, wb2]) = (vb, wb);
        let t_body = (0.5 * p.m_b) * (vb0 * vb0 + vb1 * vb1 + vb2 * vb2)
            + (0.5 * p.I_bxx) * (wb0 * wb0)
            + (0.5 * p.I_byy) * (wb1 * wb1)
            + (0.5 * p.I_bzz) * (wb2 * wb2);

        // Wheels at (0, ∓d): translation, spin about the axle, yaw.
        let (wr, wl) = (x1 + p.d * w, x1 - p.d * w);
        let t_wheels = (0.5 * p.m_w) * (wr * wr + wl * wl + x2 * x2 * 2.0)
            + (0.5 * p.I_wyy) * (vr * vr + vl * vl)
            + p.I_wzz * (w * w);

        // Rotor and gear stage, relative to the body.
        let stage = |vphi: T| {
            let rel = vphi - va;
            let m = va + p.n_wm * rel;
            let g = va - p.n_wg * rel;
            (0.5 * p.I_m) * (m * m) + (0.5 * p.I_g) * (g * g)
        };
        let t_gear = stage(vr) + stage(vl);
        let t_motor = (0.5 * p.L_m) * (ir * ir + il * il);

        let v_grav = (p.m_b * p.g * p.l) * ca;
        let v_emf = (p.k_e * p.n_wm) * ((vr - va) * qr + (vl - va) * ql);
        let l = t_body + t_wheels + t_gear + t_motor - v_grav - v_emf;
        // `J_e` is a constant of the reduced model, zero in the full one: the planner's
        // and the integrators' ℓ (evaluated in nested duals at every step) skip the term.
        if self.quasi_static_inertia.re() == 0.0 {
            return l;
        }
        let (wr_rel, wl_rel) = (vr - va, vl - va);
        l - (0.5 * Param(self.quasi_static_inertia)) * (wr_rel * wr_rel + wl_rel * wl_rel)
    }

    /// The wheel angles (nothing reads them) and the charges (`ℓ` reads them only in the
    /// back-EMF term `k_e n_wm (φ̇ − α̇) q`, which a constant added to `q` changes by a
    /// total time derivative). Checked in `tests/model/plan_derivatives.rs`.
    fn ignorable_shape(&self) -> &'static [usize] {
        &[1, 2, 3, 4]
    }

    fn connection<T: Lift<P>>(&self, _s: &SVector<T, 5>) -> SMatrix<T, 3, 5> {
        let p = self.params.map(Param);
        let z = T::zero();
        // Wheel radii r_R, r_L: ξ₁ = (r_R φ̇R + r_L φ̇L)/2, ω = (r_R φ̇R − r_L φ̇L)/(2d).
        let r_r = p.r + Param(self.wheel_radius_offsets[0]);
        let r_l = p.r + Param(self.wheel_radius_offsets[1]);
        let (hr_r, hr_l): (T, T) = ((0.5 * r_r).lift(), (0.5 * r_l).lift());
        let (hrd_r, hrd_l): (T, T) = ((0.5 * r_r / p.d).lift(), (0.5 * r_l / p.d).lift());
        SMatrix::<T, 3, 5>::new(z, -hr_r, -hr_l, z, z, z, z, z, z, z, z, -hrd_r, hrd_l, z, z)
    }

    fn forcing<T: Lift<P>>(
        &self,
        _s: &SVector<T, 5>,
        v: &SVector<T, 5>,
        u: &SVector<T, 2>,
    ) -> SVector<T, 5> {
        let p = self.params.map(Param);
        let fr = friction(p.d_v, p.d_c, p.d_0, v[1] - v[0]);
        let fl = friction(p.d_v, p.d_c, p.d_0, v[2] - v[0]);
        SVector::<T, 5>::new(fr + fl, -fr, -fl, u[0] - p.R_m * v[3], u[1] - p.R_m * v[4])
    }

    /// The partials of [`Wip::reduced_lagrangian`] term by term (the same symbols; with
    /// `c = k_e n_wm` and the gear stage's motor and gear rates `m = v_α + n_wm (φ̇ − v_α)`,
    /// `g = v_α − n_wg (φ̇ − v_α)`). Checked against the dual-number partials in
    /// `tests/model/wip_continuous.rs`.
    fn closed_form_lagrangian_gradient<T: Lift<P>>(
        &self,
        s: &SVector<T, 5>,
        v: &SVector<T, 5>,
        xi: &SVector<T, 3>,
    ) -> Option<(SVector<T, 5>, SVector<T, 5>, SVector<T, 3>)> {
        let p = self.params.map(Param);
        let (al, qr, ql) = (s[0], s[3], s[4]);
        let (va, vr, vl, ir, il) = (v[0], v[1], v[2], v[3], v[4]);
        let (x1, x2, w) = (xi[0], xi[1], xi[2]);

        // Body: vb = (x1 + l v_α cos α, x2 + l w sin α, −l v_α sin α), ωb = (−w sin α, v_α, w cos α).
        let BodyMotion { vb, wb, sa, ca } = body_motion(p.l, al, va, xi);
        let ([vb0, vb1, vb2], [wb0, _, wb2]) = (vb, wb);
        let (mvb0, mvb1, mvb2) = (p.m_b * vb0, p.m_b * vb1, p.m_b * vb2);
        let (iwb0, iwb2) = (p.I_bxx * wb0, p.I_bzz * wb2);
        let body_al = p.l * (-(mvb0 * (va * sa)) + mvb1 * (w * ca) - mvb2 * (va * ca))
            - iwb0 * (w * ca)
            - iwb2 * (w * sa);
        let body_va = p.l * (mvb0 * ca - mvb2 * sa) + p.I_byy * va;
        let body_w = p.l * (mvb1 * sa) - iwb0 * sa + iwb2 * ca;

        // Wheels at (0, ∓d).
        let (wr, wl) = (x1 + p.d * w, x1 - p.d * w);
        let wheel_x1 = p.m_w * (wr + wl);
        let wheel_x2 = (p.m_w * x2) * 2.0;
        let wheel_w = p.m_w * (p.d * (wr - wl)) + (p.I_wzz * w) * 2.0;

        // Rotor and gear stage of each wheel: (∂/∂φ̇, ∂/∂v_α).
        let stage = |vphi: T| {
            let rel = vphi - va;
            let m = va + p.n_wm * rel;
            let g = va - p.n_wg * rel;
            let (im, ig) = (p.I_m * m, p.I_g * g);
            (
                p.n_wm * im - p.n_wg * ig,
                im - p.n_wm * im + ig + p.n_wg * ig,
            )
        };
        let (gear_r, gear_ar) = stage(vr);
        let (gear_l, gear_al) = stage(vl);
        let kn = p.k_e * p.n_wm;
        let je = Param(self.quasi_static_inertia);
        let (wr_rel, wl_rel) = (vr - va, vl - va);

        let ls = SVector::<T, 5>::new(
            body_al + (p.m_b * p.g * p.l) * sa,
            T::zero(),
            T::zero(),
            -(kn * wr_rel),
            -(kn * wl_rel),
        );
        let lv = SVector::<T, 5>::new(
            body_va + gear_ar + gear_al + kn * (qr + ql) + je * (wr_rel + wl_rel),
            p.I_wyy * vr + gear_r - kn * qr - je * wr_rel,
            p.I_wyy * vl + gear_l - kn * ql - je * wl_rel,
            p.L_m * ir,
            p.L_m * il,
        );
        let lxi = SVector::<T, 3>::new(mvb0 + wheel_x1, mvb1 + wheel_x2, body_w + wheel_w);
        Some((ls, lv, lxi))
    }

    /// The mechanical accelerations of [`closed_form::shape_acceleration`] at the currents
    /// `(v₃, v₄)`, and the motor circuits `L_m i̇ = u − R_m i − k_e n_wm (φ̇ − α̇)`. Checked
    /// against the generic path in `tests/model/wip_continuous.rs`.
    fn closed_form_acceleration<T: Lift<P>>(
        &self,
        s: &SVector<T, 5>,
        v: &SVector<T, 5>,
        u: &SVector<T, 2>,
    ) -> Option<SVector<T, 5>> {
        let sys = self.lifted::<T>();
        let p = &sys.params;
        let no_force = [T::zero(); 3];
        let a =
            closed_form::shape_acceleration(&sys, s[0], [v[0], v[1], v[2]], [v[3], v[4]], no_force)
                .unwrap_or([T::from(f64::NAN); 3]);
        Some(SVector::<T, 5>::new(
            a[0],
            a[1],
            a[2],
            closed_form::current_rate(p, u[0], v[3], v[1] - v[0]),
            closed_form::current_rate(p, u[1], v[4], v[2] - v[0]),
        ))
    }
}

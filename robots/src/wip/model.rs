//! The WIP as a [`PrincipalKinematicSystem`] on SE(2) × R⁵: reduced Lagrangian, connection,
//! forcing. This is all the integrators and the continuous model need.

use super::params::WipParams;
use dmech::{Lift, Param, PrincipalKinematicSystem};
use dmech_lie::{Real, Se2};
use nalgebra::{SMatrix, SVector};

/// The wheeled inverted pendulum with DC motors; `P` is the parameter scalar.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wip<P = f64> {
    pub params: WipParams<P>,
}

impl Wip<f64> {
    pub fn new(params: WipParams<f64>) -> Self {
        Wip { params }
    }
}

impl Default for Wip<f64> {
    fn default() -> Self {
        Wip::new(WipParams::default())
    }
}

/// Gear/bearing friction torque at relative wheel speed `w = φ̇ − α̇`.
pub fn friction<P: Real, T: Lift<P>>(d_v: Param<P>, d_c: Param<P>, d_0: Param<P>, w: T) -> T {
    d_v * w + d_c * (d_0 * w).tanh()
}

impl<P: Real> PrincipalKinematicSystem<3, 2, 5, 2> for Wip<P> {
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
        let (sa, ca) = al.sin_cos();

        // Body: centre of mass at height l, at g = e (θ = 0) with body velocity ξ.
        let vb0 = x1 + p.l * (va * ca);
        let vb1 = x2 + p.l * (w * sa);
        let vb2 = -(p.l * (va * sa));
        let (wb0, wb1, wb2) = (-(w * sa), va, w * ca);
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
        t_body + t_wheels + t_gear + t_motor - v_grav - v_emf
    }

    fn connection<T: Lift<P>>(&self, _s: &SVector<T, 5>) -> SMatrix<T, 3, 5> {
        let p = self.params.map(Param);
        let z = T::zero();
        let hr: T = (0.5 * p.r).lift();
        let hrd: T = (0.5 * p.r / p.d).lift();
        SMatrix::<T, 3, 5>::new(z, -hr, -hr, z, z, z, z, z, z, z, z, -hrd, hrd, z, z)
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
}

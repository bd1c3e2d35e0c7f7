//! Systems other than the WIP, with known answers, for testing the generic machinery.

use dmech::{Lift, PrincipalKinematicSystem};
use dmech_lie::{Real, Se2};
use nalgebra::{SMatrix, SVector};

/// A differential-drive robot with its centre of mass on the axle: shape `(φR, φL)`,
/// `ℓ = ½ m (ξ₁² + ξ₂²) + ½ J ω² + ½ I (v_R² + v_L²)`, the WIP's rolling constraints.
/// Unforced, its wheels turn at constant rates and it drives on a circle: `g(t) = g₀ exp(tξ)`.
pub struct DifferentialDrive {
    pub m: f64,
    pub j: f64,
    pub i: f64,
    pub r: f64,
    pub d: f64,
}

impl PrincipalKinematicSystem<3, 2, 2, 0> for DifferentialDrive {
    type Param = f64;
    type Group<T: Real> = Se2<T>;
    fn reduced_lagrangian<T: Lift<f64>>(
        &self,
        _s: &SVector<T, 2>,
        v: &SVector<T, 2>,
        xi: &SVector<T, 3>,
    ) -> T {
        let h = T::from(0.5);
        h * T::from(self.m) * (xi[0] * xi[0] + xi[1] * xi[1])
            + h * T::from(self.j) * xi[2] * xi[2]
            + h * T::from(self.i) * (v[0] * v[0] + v[1] * v[1])
    }
    fn connection<T: Lift<f64>>(&self, _s: &SVector<T, 2>) -> SMatrix<T, 3, 2> {
        let (hr, z) = (T::from(0.5 * self.r), T::zero());
        let hrd = T::from(0.5 * self.r / self.d);
        SMatrix::<T, 3, 2>::new(-hr, -hr, z, z, -hrd, hrd)
    }
    fn forcing<T: Lift<f64>>(
        &self,
        _s: &SVector<T, 2>,
        _v: &SVector<T, 2>,
        _u: &SVector<T, 0>,
    ) -> SVector<T, 2> {
        SVector::zeros()
    }
}

/// A robot whose wheel radius depends on the shape: shape `(φR, φL, ψ)`, radius
/// `r(ψ) = r₀ (1 + ε sin ψ)` (a shape-dependent connection), a torsion spring on `ψ`, and
/// a body whose centre of mass sits ahead of the axle by `c` (so that ξ's lateral component
/// couples). Conservative: its energy is an exact invariant of the continuous model, which
/// tests the `Ȧ` terms of the generic equations of motion.
pub struct VariableRadiusRobot {
    pub m: f64,
    pub c: f64,
    pub j: f64,
    pub i: f64,
    pub i_psi: f64,
    pub k_psi: f64,
    pub r0: f64,
    pub eps: f64,
    pub d: f64,
}

impl PrincipalKinematicSystem<3, 2, 3, 0> for VariableRadiusRobot {
    type Param = f64;
    type Group<T: Real> = Se2<T>;
    fn reduced_lagrangian<T: Lift<f64>>(
        &self,
        s: &SVector<T, 3>,
        v: &SVector<T, 3>,
        xi: &SVector<T, 3>,
    ) -> T {
        let h = T::from(0.5);
        let c = T::from(self.c);
        // Velocity of the centre of mass at (c, 0) in the body frame: (ξ₁, ξ₂ + c ω).
        let vx = xi[0];
        let vy = xi[1] + c * xi[2];
        h * T::from(self.m) * (vx * vx + vy * vy)
            + h * T::from(self.j) * xi[2] * xi[2]
            + h * T::from(self.i) * (v[0] * v[0] + v[1] * v[1])
            + h * T::from(self.i_psi) * v[2] * v[2]
            - h * T::from(self.k_psi) * s[2] * s[2]
    }
    fn connection<T: Lift<f64>>(&self, s: &SVector<T, 3>) -> SMatrix<T, 3, 3> {
        let r = T::from(self.r0) * (T::one() + T::from(self.eps) * s[2].sin());
        let (hr, z) = (r * 0.5, T::zero());
        let hrd = hr / self.d;
        SMatrix::<T, 3, 3>::new(-hr, -hr, z, z, z, z, -hrd, hrd, z)
    }
    fn forcing<T: Lift<f64>>(
        &self,
        _s: &SVector<T, 3>,
        _v: &SVector<T, 3>,
        _u: &SVector<T, 0>,
    ) -> SVector<T, 3> {
        SVector::zeros()
    }
}

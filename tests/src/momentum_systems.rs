//! Nonholonomic systems whose constraints leave group directions free
//! ([`dmech::NonholonomicSystem`]), with known answers: the Chaplygin sleigh, the vertical
//! rolling disk written with a free yaw direction (beside [`RollingDiskOnPlane`], the same
//! disk as a principal-kinematic system on `R²`), and random systems of the class.

use crate::random_system::{GroupFamily, Lcg, RandomSystem, RandomSystemSpec};
use dmech::{Lift, NonholonomicSystem, PrincipalKinematicSystem};
use dmech_lie::{Real, Rn, Se2};
use nalgebra::{SMatrix, SVector};

/// The Chaplygin sleigh: a rigid body on a knife edge at the origin of its body frame, its
/// centre of mass a distance `a` ahead on the body's x axis. One constraint (no sideways
/// slip at the edge, `ξ₂ = 0`), no shape, two free directions (forward speed and yaw rate):
/// `ℓ = ½ m (ξ₁² + (ξ₂ + a ξ₃)²) + ½ J ξ₃²` with `J` about the centre of mass.
/// Its closed form ([`ChaplyginSleigh::closed_form_rates`]): `m v̇ = m a ω²`,
/// `(J + m a²) ω̇ = −m a v ω`; the energy `½ m v² + ½ (J + m a²) ω²` is conserved and, for
/// `a > 0`, `ω → 0` and `v → √(2E/m)`.
#[derive(Clone, Copy, Debug)]
pub struct ChaplyginSleigh {
    pub m: f64,
    pub a: f64,
    pub j: f64,
}

impl ChaplyginSleigh {
    /// `(v̇, ω̇)` at `(v, ω)` from the sleigh's classical equations.
    pub fn closed_form_rates(&self, v: f64, omega: f64) -> (f64, f64) {
        (
            self.a * omega * omega,
            -self.m * self.a * v * omega / (self.j + self.m * self.a * self.a),
        )
    }

    /// The energy at forward speed `v` and yaw rate `ω`.
    pub fn closed_form_energy(&self, v: f64, omega: f64) -> f64 {
        0.5 * self.m * v * v + 0.5 * (self.j + self.m * self.a * self.a) * omega * omega
    }
}

impl NonholonomicSystem<3, 0, 2, 0> for ChaplyginSleigh {
    type Param = f64;
    type Group<T: Real> = Se2<T>;
    fn reduced_lagrangian<T: Lift<f64>>(
        &self,
        _s: &SVector<T, 0>,
        _v: &SVector<T, 0>,
        xi: &SVector<T, 3>,
    ) -> T {
        let h = T::from(0.5);
        let lateral = xi[1] + T::from(self.a) * xi[2];
        h * T::from(self.m) * (xi[0] * xi[0] + lateral * lateral)
            + h * T::from(self.j) * xi[2] * xi[2]
    }
    fn connection<T: Lift<f64>>(&self, _s: &SVector<T, 0>) -> SMatrix<T, 3, 0> {
        SMatrix::zeros()
    }
    fn free_directions<T: Lift<f64>>(&self, _s: &SVector<T, 0>) -> SMatrix<T, 3, 2> {
        let (o, z) = (T::one(), T::zero());
        SMatrix::<T, 3, 2>::new(o, z, z, z, z, o)
    }
    fn forcing<T: Lift<f64>>(
        &self,
        _s: &SVector<T, 0>,
        _v: &SVector<T, 0>,
        _u: &SVector<T, 0>,
    ) -> SVector<T, 0> {
        SVector::zeros()
    }
}

/// The vertical rolling disk (radius `R`, mass `m`, inertia `I` about the vertical, `J`
/// about its axle), torques on the heading and the rolling angle. Two ways:
/// [`RollingDiskOnPlane`] is principal-kinematic on `G = R²` (the contact point) with
/// shape `(θ, φ)`; [`RollingDiskWithYaw`] lives on `G = SE(2)` with shape `φ`, the yaw rate
/// free. Both have `ℓ = ½ m |ẋ|² + ½ I θ̇² + ½ J φ̇²` and `|ẋ| = R φ̇` along the heading.
#[derive(Clone, Copy, Debug)]
pub struct RollingDisk {
    pub m: f64,
    pub r: f64,
    pub i: f64,
    pub j: f64,
}

/// [`RollingDisk`] on `R²`, shape `(θ, φ)`: `ẋ = R φ̇ (cos θ, sin θ)`.
pub struct RollingDiskOnPlane(pub RollingDisk);

impl PrincipalKinematicSystem<2, 2, 2> for RollingDiskOnPlane {
    type Param = f64;
    type Group<T: Real> = Rn<T, 2>;
    fn reduced_lagrangian<T: Lift<f64>>(
        &self,
        _s: &SVector<T, 2>,
        v: &SVector<T, 2>,
        xi: &SVector<T, 2>,
    ) -> T {
        let (d, h) = (self.0, T::from(0.5));
        h * T::from(d.m) * (xi[0] * xi[0] + xi[1] * xi[1])
            + h * T::from(d.i) * v[0] * v[0]
            + h * T::from(d.j) * v[1] * v[1]
    }
    fn connection<T: Lift<f64>>(&self, s: &SVector<T, 2>) -> SMatrix<T, 2, 2> {
        let (r, z) = (T::from(self.0.r), T::zero());
        SMatrix::<T, 2, 2>::new(z, -r * s[0].cos(), z, -r * s[0].sin())
    }
    fn forcing<T: Lift<f64>>(
        &self,
        _s: &SVector<T, 2>,
        _v: &SVector<T, 2>,
        u: &SVector<T, 2>,
    ) -> SVector<T, 2> {
        *u
    }
}

/// [`RollingDisk`] on `SE(2)` (the contact point and the heading), shape `φ`: `ξ₁ = R φ̇`,
/// `ξ₂ = 0`, the yaw rate `ξ₃` free; the heading torque acts along the free direction.
pub struct RollingDiskWithYaw(pub RollingDisk);

impl NonholonomicSystem<3, 1, 1, 2> for RollingDiskWithYaw {
    type Param = f64;
    type Group<T: Real> = Se2<T>;
    fn reduced_lagrangian<T: Lift<f64>>(
        &self,
        _s: &SVector<T, 1>,
        v: &SVector<T, 1>,
        xi: &SVector<T, 3>,
    ) -> T {
        let (d, h) = (self.0, T::from(0.5));
        h * T::from(d.m) * (xi[0] * xi[0] + xi[1] * xi[1])
            + h * T::from(d.i) * xi[2] * xi[2]
            + h * T::from(d.j) * v[0] * v[0]
    }
    fn connection<T: Lift<f64>>(&self, _s: &SVector<T, 1>) -> SMatrix<T, 3, 1> {
        let z = T::zero();
        SMatrix::<T, 3, 1>::new(-T::from(self.0.r), z, z)
    }
    fn free_directions<T: Lift<f64>>(&self, _s: &SVector<T, 1>) -> SMatrix<T, 3, 1> {
        let z = T::zero();
        SMatrix::<T, 3, 1>::new(z, z, T::one())
    }
    fn forcing<T: Lift<f64>>(
        &self,
        _s: &SVector<T, 1>,
        _v: &SVector<T, 1>,
        u: &SVector<T, 2>,
    ) -> SVector<T, 1> {
        SVector::<T, 1>::new(u[1])
    }
    fn free_forcing<T: Lift<f64>>(
        &self,
        _s: &SVector<T, 1>,
        _v: &SVector<T, 1>,
        _p: &SVector<T, 1>,
        u: &SVector<T, 2>,
    ) -> SVector<T, 1> {
        SVector::<T, 1>::new(u[0])
    }
}

/// A random system of the general class on the group family `F`: the Lagrangian, the
/// kinematic connection and the forcing of a [`RandomSystem`], and `NM` free directions
/// `E(s) = E₀ + Σᵢ sin(sᵢ + χᵢ) Eᵢ` with `E₀` of orthonormal columns and `|Eᵢ|` scaled by
/// the spec's shape dependence (small enough that `E(s)` keeps full rank).
pub struct RandomMomentumSystem<F, const DOF: usize, const NS: usize, const NM: usize> {
    base: RandomSystem<F, DOF, NS>,
    e0: SMatrix<f64, DOF, NM>,
    ei: Vec<SMatrix<f64, DOF, NM>>,
    chi: Vec<f64>,
}

impl<F, const DOF: usize, const NS: usize, const NM: usize> RandomMomentumSystem<F, DOF, NS, NM>
where
    F: GroupFamily<DOF>,
{
    /// Draws a system from `seed`.
    pub fn draw(seed: u64, spec: RandomSystemSpec) -> Self {
        let base = RandomSystem::draw(seed, spec);
        let mut rng = Lcg(seed ^ 0x51A7_E00D_F00D_CAFE);
        // Gram–Schmidt on random columns.
        let mut e0 = SMatrix::<f64, DOF, NM>::from_fn(|_, _| rng.uniform());
        for j in 0..NM {
            for k in 0..j {
                let proj = e0.column(k).dot(&e0.column(j));
                let ek = e0.column(k).into_owned();
                e0.column_mut(j).axpy(-proj, &ek, 1.0);
            }
            let norm = e0.column(j).norm();
            e0.column_mut(j).unscale_mut(norm);
        }
        let ei = (0..NS)
            .map(|_| SMatrix::from_fn(|_, _| 0.5 * spec.shape_dependence * rng.uniform()))
            .collect();
        let chi = (0..NS).map(|_| 3.0 * rng.uniform()).collect();
        RandomMomentumSystem { base, e0, ei, chi }
    }
}

impl<F, const DOF: usize, const NS: usize, const NM: usize> NonholonomicSystem<DOF, NS, NM, NS>
    for RandomMomentumSystem<F, DOF, NS, NM>
where
    F: GroupFamily<DOF>,
{
    type Param = f64;
    type Group<T: Real> = F::G<T>;
    fn reduced_lagrangian<T: Lift<f64>>(
        &self,
        s: &SVector<T, NS>,
        v: &SVector<T, NS>,
        xi: &SVector<T, DOF>,
    ) -> T {
        self.base.reduced_lagrangian(s, v, xi)
    }
    fn connection<T: Lift<f64>>(&self, s: &SVector<T, NS>) -> SMatrix<T, DOF, NS> {
        self.base.connection(s)
    }
    fn free_directions<T: Lift<f64>>(&self, s: &SVector<T, NS>) -> SMatrix<T, DOF, NM> {
        let mut e = self.e0.map(T::from);
        for (i, ei) in self.ei.iter().enumerate() {
            e += ei.map(T::from) * (s[i] + T::from(self.chi[i])).sin();
        }
        e
    }
    fn forcing<T: Lift<f64>>(
        &self,
        s: &SVector<T, NS>,
        v: &SVector<T, NS>,
        u: &SVector<T, NS>,
    ) -> SVector<T, NS> {
        self.base.forcing(s, v, u)
    }
}

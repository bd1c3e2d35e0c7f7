//! The snakeboard (Lewis, Ostrowski, Murray & Burdick 1994; Bloch, Krishnaprasad, Marsden &
//! Murray 1996) as a [`NonholonomicSystem`] on SE(2) with shape `(ψ, φ)` and one free
//! direction (`docs/snakeboard.md`).
//!
//! Pose `g = (x, y, θ)` of the board's centre; shape `s = (ψ, φ)`: the rotor angle (the
//! rider's torso, a momentum wheel on the board's centre) and the axle angle, the front axle
//! turned by `φ` and the back one by `−φ`; inputs `u = (τ_ψ, τ_φ)`: the torques on the rotor
//! and on the axles. The wheels roll without slipping sideways, which leaves one direction
//! of the body velocity free, `ξ = p (1, 0, tan φ / l)`: the board moves along its axis and
//! turns about the point where the axles' normals meet. No shape velocity drives the group
//! kinematically (`A = 0`): the board gains its forward speed only through the momentum
//! equation, from the rotor and the axles moving together.
//!
//! ```text
//! ℓ = ½ m (ξ₁² + ξ₂²) + ½ J ξ₃² + ½ J_r (ξ₃ + ψ̇)² + ½ J_w [(ξ₃ + φ̇)² + (ξ₃ − φ̇)²]
//! ```

use dmech::{Lift, NonholonomicSystem, WithMomentum};
use dmech_lie::{Real, Se2};
use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

/// Shape dimension: rotor angle, axle angle.
pub const NS: usize = 2;
/// Free group directions: the forward speed.
pub const NM: usize = 1;
/// Inputs: rotor torque, axle torque.
pub const NU: usize = 2;
/// The extended shape `(ψ, φ, σ)` of [`WithMomentum`], `σ̇ = p`.
pub const NA: usize = NS + NM;

/// The snakeboard's parameters (SI units).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SnakeboardParams {
    /// Mass of board, rider and wheels, kg.
    pub m: f64,
    /// Distance from the board's centre to each axle, m.
    pub l: f64,
    /// Yaw inertia of the board about its centre, kg m².
    pub j: f64,
    /// Rotor inertia, kg m².
    pub j_r: f64,
    /// Inertia of each wheel pair about its axle's pivot, kg m².
    pub j_w: f64,
    /// Damping on the rotor and on the axles, N m s/rad.
    pub c_r: f64,
    pub c_w: f64,
}

impl Default for SnakeboardParams {
    /// A small robotic snakeboard: a 2 kg board 0.4 m between the axles, a rotor of a tenth
    /// of the board's yaw inertia, light wheels, a little damping.
    fn default() -> Self {
        SnakeboardParams {
            m: 2.0,
            l: 0.2,
            j: 0.03,
            j_r: 0.01,
            j_w: 5e-4,
            c_r: 1e-3,
            c_w: 1e-3,
        }
    }
}

/// The snakeboard.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Snakeboard {
    pub params: SnakeboardParams,
}

/// The snakeboard as the principal-kinematic system the integrators and the planner run.
pub type ExtendedSnakeboard = WithMomentum<Snakeboard, NS, NM>;

impl Snakeboard {
    /// The snakeboard on its extended shape `(ψ, φ, σ)`.
    pub fn extended(self) -> ExtendedSnakeboard {
        WithMomentum::new(self)
    }

    /// The rate of the nonholonomic momentum `J = Eᵀ ∂ℓ/∂ξ` from the published momentum
    /// equation (Bloch et al. 1996, §8): along `ξ = p (1, 0, tan φ / l)` the coadjoint term
    /// vanishes, and what is left is the axles' turning of the free direction,
    /// `J̇ = ⟨∂ℓ/∂ξ, ∂E/∂φ⟩ φ̇ = (φ̇ / (l cos²φ)) ((J + J_r + 2 J_w) ξ₃ + J_r ψ̇)`.
    pub fn published_momentum_rate(&self, phi: f64, v_psi: f64, v_phi: f64, p: f64) -> f64 {
        let q = &self.params;
        let yaw_rate = p * phi.tan() / q.l;
        let yaw_momentum = (q.j + q.j_r + 2.0 * q.j_w) * yaw_rate + q.j_r * v_psi;
        v_phi / (q.l * phi.cos().powi(2)) * yaw_momentum
    }

    /// The nonholonomic momentum `J = m p + (J + J_r + 2 J_w) p tan²φ / l² + J_r ψ̇ tan φ / l`
    /// (in any scalar: with dual numbers, its rate along a motion).
    pub fn momentum<T: Real>(&self, phi: T, v_psi: T, p: T) -> T {
        let q = &self.params;
        let t = phi.tan() * (1.0 / q.l);
        p * q.m + p * t * t * (q.j + q.j_r + 2.0 * q.j_w) + v_psi * t * q.j_r
    }
}

impl NonholonomicSystem<3, NS, NM, NU> for Snakeboard {
    type Param = f64;
    type Group<T: Real> = Se2<T>;

    fn reduced_lagrangian<T: Lift<f64>>(
        &self,
        _s: &SVector<T, NS>,
        v: &SVector<T, NS>,
        xi: &SVector<T, 3>,
    ) -> T {
        let q = &self.params;
        let (v_psi, v_phi, yaw) = (v[0], v[1], xi[2]);
        let (rotor, front, back) = (yaw + v_psi, yaw + v_phi, yaw - v_phi);
        (xi[0] * xi[0] + xi[1] * xi[1]) * (0.5 * q.m)
            + yaw * yaw * (0.5 * q.j)
            + rotor * rotor * (0.5 * q.j_r)
            + (front * front + back * back) * (0.5 * q.j_w)
    }

    fn connection<T: Lift<f64>>(&self, _s: &SVector<T, NS>) -> SMatrix<T, 3, NS> {
        SMatrix::zeros()
    }

    fn free_directions<T: Lift<f64>>(&self, s: &SVector<T, NS>) -> SMatrix<T, 3, NM> {
        SMatrix::<T, 3, NM>::new(T::one(), T::zero(), s[1].tan() * (1.0 / self.params.l))
    }

    fn forcing<T: Lift<f64>>(
        &self,
        _s: &SVector<T, NS>,
        v: &SVector<T, NS>,
        u: &SVector<T, NU>,
    ) -> SVector<T, NS> {
        let q = &self.params;
        SVector::<T, NS>::new(u[0] - v[0] * q.c_r, u[1] - v[1] * q.c_w)
    }

    fn ignorable_shape(&self) -> &[usize] {
        // ℓ, E and the forcing read neither angle's position except φ through E.
        &[0]
    }
}

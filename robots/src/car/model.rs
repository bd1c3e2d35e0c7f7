//! The car as a [`PrincipalKinematicSystem`] on SE(2) × R³: front-wheel steering, rear-wheel
//! drive by a DC motor in charge coordinates (as the WIP's motors, `docs/car.md`).
//!
//! Pose `g = (x, y, θ)` of the rear-axle midpoint; shape `s = (φ, ψ, q)`: steering angle,
//! rear-wheel rolling angle, drive-motor charge; shape velocity `v = (φ̇, ψ̇, i)`; inputs
//! `u = (τ_s, u_d)`: steering torque and drive voltage. The rear wheels roll without
//! slipping and the front wheel does not slip sideways:
//! `ξ = (r ψ̇, 0, r ψ̇ tan φ / L)` — a connection that depends on the steering angle.

use dmech::{Lift, PrincipalKinematicSystem};
use dmech_lie::{Real, Se2};
use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

/// Shape dimension: steering angle, rear-wheel angle, drive charge.
pub const NS: usize = 3;
/// Inputs: steering torque, drive voltage.
pub const NU: usize = 2;

/// The car's parameters (SI units).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(non_snake_case)]
pub struct CarParams {
    /// Mass, kg.
    pub m: f64,
    /// Centre of mass ahead of the rear axle, m.
    pub b: f64,
    /// Yaw inertia about the centre of mass, kg m².
    pub j: f64,
    /// Wheelbase, m.
    pub L: f64,
    /// Rear-wheel radius, m.
    pub r: f64,
    /// Rear wheels' spin inertia (both), kg m².
    pub i_w: f64,
    /// Steering assembly's inertia about its vertical axis, kg m².
    pub i_s: f64,
    /// Steering damping, N m s/rad.
    pub c_s: f64,
    /// Rear-axle damping, N m s/rad.
    pub c_w: f64,
    /// Drive motor: rotor inertia, kg m²; gear ratio; back-EMF constant, V s/rad;
    /// resistance, Ω; inductance, H.
    pub I_m: f64,
    pub n: f64,
    pub k_e: f64,
    pub R_m: f64,
    pub L_m: f64,
}

impl Default for CarParams {
    /// A small rear-driven car (about 1:10 scale): the body and steering
    /// parameters, a 6 V drive motor with a 10:1 gear.
    fn default() -> Self {
        CarParams {
            m: 2.0,
            b: 0.1,
            j: 0.02,
            L: 0.25,
            r: 0.05,
            i_w: 5e-4,
            i_s: 1e-3,
            c_s: 0.02,
            c_w: 1e-3,
            I_m: 1e-6,
            n: 10.0,
            k_e: 0.01,
            R_m: 1.0,
            L_m: 1e-3,
        }
    }
}

/// The car.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Car {
    pub params: CarParams,
}

impl Car {
    /// The drive torque on the rear axle per ampere, `k_e n` (N m/A).
    pub fn torque_constant(&self) -> f64 {
        self.params.k_e * self.params.n
    }
    /// The steady current at drive voltage `u` and wheel rate `ψ̇`.
    pub fn steady_current(&self, u: f64, wheel_rate: f64) -> f64 {
        (u - self.torque_constant() * wheel_rate) / self.params.R_m
    }
}

impl PrincipalKinematicSystem<3, NS, NU> for Car {
    type Param = f64;
    type Group<T: Real> = Se2<T>;

    fn reduced_lagrangian<T: Lift<f64>>(
        &self,
        s: &SVector<T, NS>,
        v: &SVector<T, NS>,
        xi: &SVector<T, 3>,
    ) -> T {
        let p = &self.params;
        let (vphi, vpsi, i) = (v[0], v[1], v[2]);
        let lateral = xi[1] + xi[2] * p.b;
        let steer = xi[2] + vphi;
        let rotor = vpsi * p.n;
        (xi[0] * xi[0] + lateral * lateral) * (0.5 * p.m)
            + xi[2] * xi[2] * (0.5 * p.j)
            + steer * steer * (0.5 * p.i_s)
            + vpsi * vpsi * (0.5 * p.i_w)
            + rotor * rotor * (0.5 * p.I_m)
            + i * i * (0.5 * p.L_m)
            // The motor's electromechanical coupling (charge coordinates, as the WIP's).
            - vpsi * s[2] * (p.k_e * p.n)
    }

    /// The rear-wheel angle `ψ` (the connection and the forcing do not read it) and the
    /// motor's charge `q` (`ℓ` reads it only in `−ψ̇ q k_e n`, whose change under
    /// `q → q + c` is the total derivative of `−c k_e n ψ`).
    fn ignorable_shape(&self) -> &[usize] {
        &[1, 2]
    }

    fn connection<T: Lift<f64>>(&self, s: &SVector<T, NS>) -> SMatrix<T, 3, NS> {
        let p = &self.params;
        let z = T::zero();
        let yaw_per_wheel_angle = s[0].tan() * (p.r / p.L);
        SMatrix::<T, 3, NS>::new(z, T::from(-p.r), z, z, z, z, z, -yaw_per_wheel_angle, z)
    }

    fn forcing<T: Lift<f64>>(
        &self,
        _s: &SVector<T, NS>,
        v: &SVector<T, NS>,
        u: &SVector<T, NU>,
    ) -> SVector<T, NS> {
        let p = &self.params;
        SVector::<T, NS>::new(u[0] - v[0] * p.c_s, -(v[1] * p.c_w), u[1] - v[2] * p.R_m)
    }
}

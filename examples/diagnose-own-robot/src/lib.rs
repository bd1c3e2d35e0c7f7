//! A differential-drive robot diagnosed by `dmech-diagnose` through the system traits alone:
//! the model is `ℓ`, the connection and the forcing ([`DiffDrive`]), the readings are a
//! measurement map ([`Rover::measure`]), and `dmech_diagnose::SystemPlant` derives the
//! prediction and its derivatives from them. Nothing here integrates or differentiates by
//! hand.
//!
//! The robot: a body of mass `m` and yaw inertia `I` on two wheels of radius `r`, inertia
//! `J`, a half track `b` apart, each driven by a motor of torque `k u` with viscous loss
//! `c φ̇`. Readings: a motion-capture pose `(x, y, heading)`, the two wheel encoders and a
//! yaw-rate gyro. Catalogue: a Coulomb friction of the wheels (`wheel_friction`, torque
//! `f_c tanh(φ̇/ω_c)`, by `tanh_saturating`, which stays finite in dual numbers at any
//! speed), the mass (calibration), the generic offset and scale hypotheses
//! of every reading and the generic offset and gain hypotheses of every input.

use dmech::{Lift, PrincipalKinematicSystem};
use dmech_diagnose::model::{Catalogue, ParamSpec};
use dmech_diagnose::{
    ActuatorHypotheses, ChannelSpec, FitScalar, MeasuredLog, ObservedPoint, ObservedSystem,
    ReadingHypotheses,
};
use dmech_lie::scalar::tanh_saturating;
use dmech_lie::{Real, Se2};
use nalgebra::{SMatrix, SVector};

/// Wheel radius, m.
pub const RADIUS: f64 = 0.04;
/// Half the distance between the wheels, m.
pub const HALF_TRACK: f64 = 0.1;
/// Yaw inertia of the body, kg m².
pub const YAW_INERTIA: f64 = 0.02;
/// Inertia of a wheel with its motor, kg m².
pub const WHEEL_INERTIA: f64 = 1e-4;
/// Motor torque per unit command, N m.
pub const TORQUE_GAIN: f64 = 0.1;
/// Viscous loss of a wheel, N m s/rad.
pub const VISCOUS: f64 = 0.005;
/// The nominal mass, kg.
pub const MASS: f64 = 2.0;
/// Wheel speed below which the Coulomb friction is smoothed (`tanh(φ̇/ω_c)`), rad/s.
pub const FRICTION_SMOOTHING: f64 = 0.05;

/// The robot's model with its uncertain parameters in scalar `T`.
#[derive(Clone, Copy, Debug)]
pub struct DiffDrive<T> {
    /// Body mass, kg.
    pub mass: T,
    /// Coulomb friction torque of each wheel, N m.
    pub coulomb: T,
}

impl<T: FitScalar> PrincipalKinematicSystem<3, 2, 2> for DiffDrive<T> {
    type Param = T;
    type Group<U: Real> = Se2<U>;

    /// `ℓ = ½ m (ξ_x² + ξ_y²) + ½ I ω² + ½ J (φ̇_R² + φ̇_L²)`.
    fn reduced_lagrangian<U: Lift<T>>(
        &self,
        _s: &SVector<U, 2>,
        v: &SVector<U, 2>,
        xi: &SVector<U, 3>,
    ) -> U {
        let m = U::lift(self.mass);
        (m * (xi[0] * xi[0] + xi[1] * xi[1])
            + xi[2] * xi[2] * YAW_INERTIA
            + (v[0] * v[0] + v[1] * v[1]) * WHEEL_INERTIA)
            * 0.5
    }

    /// Rolling without slipping: `ξ = (r (φ̇_R + φ̇_L)/2, 0, r (φ̇_R − φ̇_L)/(2b))`.
    fn connection<U: Lift<T>>(&self, _s: &SVector<U, 2>) -> SMatrix<U, 3, 2> {
        let (a, w) = (RADIUS / 2.0, RADIUS / (2.0 * HALF_TRACK));
        SMatrix::<f64, 3, 2>::new(-a, -a, 0.0, 0.0, -w, w).map(U::from)
    }

    /// Motor torque less the viscous and Coulomb losses of each wheel.
    fn forcing<U: Lift<T>>(
        &self,
        _s: &SVector<U, 2>,
        v: &SVector<U, 2>,
        u: &SVector<U, 2>,
    ) -> SVector<U, 2> {
        let fc = U::lift(self.coulomb);
        v.zip_map(u, |w, u| {
            u * TORQUE_GAIN - w * VISCOUS - fc * tanh_saturating(w / FRICTION_SMOOTHING)
        })
    }
}

/// The robot as `diagnose` sees it: the model, its readings and its catalogue.
pub struct Rover {
    catalogue: Catalogue,
    channels: Vec<ChannelSpec>,
    inputs: Vec<String>,
    readings: ReadingHypotheses,
    actuators: ActuatorHypotheses,
    additive: Vec<(usize, usize)>,
}

/// Where the parameters sit in [`Rover`]'s catalogue.
pub mod param {
    /// The wheels' Coulomb friction, N m.
    pub const COULOMB: usize = 0;
    /// The body mass, kg.
    pub const MASS: usize = 1;
}

impl Rover {
    /// The robot with its catalogue: `wheel_friction`, the mass as calibration, and the
    /// reading hypotheses (an offset where a sensor can have one: the gyro).
    pub fn new() -> Self {
        let mut cat = Catalogue::default();
        let coulomb = cat.param(ParamSpec::linear("f_c", 0.0, 1e-3, (0.0, 0.05)));
        let mass = cat.param(ParamSpec::positive("mass", MASS, 0.1, (0.5, 8.0)));
        assert_eq!((coulomb, mass), (param::COULOMB, param::MASS));
        cat.effect("wheel_friction", vec![coulomb]);
        cat.calibration = vec![mass];
        let mut gyro = ChannelSpec::new("gyro", "rad/s", 50.0);
        gyro.offset_limit = 0.1;
        let mut heading = ChannelSpec::new("heading", "rad", 1e3);
        heading.wraps = true;
        let channels = vec![
            ChannelSpec::new("x", "m", 100.0),
            ChannelSpec::new("y", "m", 100.0),
            heading,
            ChannelSpec::new("phi_r", "rad", 1e5),
            ChannelSpec::new("phi_l", "rad", 1e5),
            gyro,
        ];
        // The wheel angles enter their encoders alone.
        let additive = vec![(3, 3), (4, 4)];
        let readings = ReadingHypotheses::declare(&mut cat, &channels, &additive, &[]);
        let inputs = vec!["u_r".into(), "u_l".into()];
        // A motor driver's zero point can be off by up to 5 % of the commands' range (±1).
        let actuators = ActuatorHypotheses::declare(&mut cat, &inputs, &[0.05, 0.05]);
        Rover {
            catalogue: cat,
            channels,
            inputs,
            readings,
            actuators,
            additive,
        }
    }
}

impl Default for Rover {
    fn default() -> Self {
        Self::new()
    }
}

impl ObservedSystem<3, 2, 2> for Rover {
    type System<T: FitScalar> = DiffDrive<T>;

    fn channels(&self) -> &[ChannelSpec] {
        &self.channels
    }
    fn inputs(&self) -> &[String] {
        &self.inputs
    }
    fn catalogue(&self) -> &Catalogue {
        &self.catalogue
    }
    fn system<T: FitScalar>(&self, theta: &[T]) -> DiffDrive<T> {
        DiffDrive {
            mass: theta[param::MASS],
            coulomb: theta[param::COULOMB],
        }
    }
    /// Pose, wheel angles and the body's yaw rate.
    fn measure<T: FitScalar>(&self, at: &ObservedPoint<'_, T, 2, 2>, _theta: &[T]) -> Vec<T> {
        vec![
            at.coords[0],
            at.coords[1],
            at.coords[2],
            at.s[0],
            at.s[1],
            at.xi[2],
        ]
    }
    /// Pose and wheel angles read at `start`; wheel speeds from the encoders' first
    /// difference.
    fn initial_state(&self, log: &MeasuredLog, start: usize, _len: usize) -> Vec<f64> {
        let at = |k: usize, c: usize| log.value(k, c).unwrap_or(0.0);
        let next = (start + 1).min(log.len() - 1);
        let rate = |c: usize| (at(next, c) - at(start, c)) / (log.h * (next - start).max(1) as f64);
        vec![
            at(start, 0),
            at(start, 1),
            at(start, 2),
            at(start, 3),
            at(start, 4),
            rate(3),
            rate(4),
        ]
    }
    fn additive(&self) -> &[(usize, usize)] {
        &self.additive
    }
    fn reading_hypotheses(&self) -> Option<&ReadingHypotheses> {
        Some(&self.readings)
    }
    fn actuator_hypotheses(&self) -> Option<&ActuatorHypotheses> {
        Some(&self.actuators)
    }
}

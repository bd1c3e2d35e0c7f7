//! The car's sensors and its observer's design (`docs/car.md`, "Sensors"): a rear-wheel
//! (drive) encoder, a steering-angle encoder and a yaw-rate gyro read every sample, and an
//! external pose at 50 Hz that arrives late or never, fused by the framework's observer
//! (`dmech_ocp::tracking::observer`) on the plan's linearisation.
//!
//! The readings are functions of the transcription's state
//! `x_k = (x, y, θ, φ, ψ, q, φ̇_{k−1}, ψ̇_{k−1}, i_{k−1}, τ_s,k−1, u_d,k−1)` ([`CarReadings`]).

use super::model::{CarParams, NS};
use super::plan::{LAYOUT, NX};
use crate::wip::track::observer::PAPER_POSE_DELAY;
use dmech_lie::rng::Rng;
use dmech_lie::Real;
use dmech_ocp::tracking::{DelayLaw, ObserverNoise, Readings};
use dmech_ocp::transcription::layout::segment;
use nalgebra::{SMatrix, SVector};
use std::f64::consts::PI;

/// On-board readings: steering angle, rear-wheel angle, yaw rate.
pub const NY: usize = 3;
/// A pose reading: `(x, y, θ)`.
pub const NP: usize = 3;

/// The sensors' accuracies, rates and delays. [`CarSensorModel::paper`] is the default.
#[derive(Clone, Debug, PartialEq)]
pub struct CarSensorModel {
    /// Rear-wheel encoder counts per revolution (900 cpr × 4 quadrature edges); 0: exact.
    pub wheel_counts: u32,
    /// Steering encoder counts per revolution (a 12-bit absolute encoder); 0: exact.
    pub steer_counts: u32,
    /// Standard deviation of the yaw-rate gyro, rad/s.
    pub sigma_gyro: f64,
    /// Period of the external pose, s (50 Hz).
    pub pose_period: f64,
    /// Standard deviations of a pose's position (m) and heading (rad).
    pub sigma_position: f64,
    pub sigma_heading: f64,
    /// Delay of a pose.
    pub delay: DelayLaw,
    /// Probability that a pose is lost.
    pub loss: f64,
}

impl CarSensorModel {
    /// The WIP's paper model for the pose channel (50 Hz, 13–148 ms late, mean 63 ms,
    /// 2 % lost, σ 0.5 mm and 5 mrad) and its encoders' resolution; a 12-bit steering
    /// encoder and a gyro of σ 0.01 rad/s (the WIP's tilt-rate gyro).
    pub fn paper() -> Self {
        CarSensorModel {
            wheel_counts: 3600,
            steer_counts: 4096,
            sigma_gyro: 1e-2,
            pose_period: 0.02,
            sigma_position: 5e-4,
            sigma_heading: 5e-3,
            delay: PAPER_POSE_DELAY,
            loss: 0.02,
        }
    }

    /// The same rates with no noise, no quantisation, no delay and no loss.
    pub fn ideal() -> Self {
        CarSensorModel {
            wheel_counts: 0,
            steer_counts: 0,
            sigma_gyro: 0.0,
            sigma_position: 0.0,
            sigma_heading: 0.0,
            delay: DelayLaw::NONE,
            loss: 0.0,
            ..Self::paper()
        }
    }

    /// The paper's model with every delay (minimum, scale, maximum) scaled so that the
    /// mean delay is `mean` s (the paper's 63 ms at factor 1), as `wip track`'s sweep.
    pub fn with_mean_delay(mean: f64) -> Self {
        let s = Self::paper();
        CarSensorModel {
            delay: s.delay.scaled(mean / 0.063),
            ..s
        }
    }

    /// The samples between poses at sample length `h` (at least 1).
    pub fn pose_every(&self, h: f64) -> usize {
        ((self.pose_period / h).round() as usize).max(1)
    }

    /// The on-board readings of the true state `x`: the encoders' angles counted down to
    /// whole counts, the gyro's rate with its noise.
    pub fn on_board(
        &self,
        readings: &CarReadings,
        x: &SVector<f64, NX>,
        rng: &mut Rng,
    ) -> SVector<f64, NY> {
        let exact = readings.on_board(x);
        SVector::<f64, NY>::new(
            quantise(exact[0], self.steer_counts),
            quantise(exact[1], self.wheel_counts),
            exact[2] + self.sigma_gyro * rng.normal(),
        )
    }

    /// A pose reading of the true state `x`.
    pub fn pose(&self, x: &SVector<f64, NX>, rng: &mut Rng) -> SVector<f64, NP> {
        SVector::<f64, NP>::new(
            x[0] + self.sigma_position * rng.normal(),
            x[1] + self.sigma_position * rng.normal(),
            x[2] + self.sigma_heading * rng.normal(),
        )
    }

    /// The covariances the observer assumes (for the paper's sensors, also when the
    /// readings are ideal): an encoder's quantisation as uniform over one count
    /// (`q²/12`), the gyro's and the pose's variances; the process noise
    /// [`process_noise`] over samples of `h` s.
    pub fn observer_noise(&self, h: f64) -> ObserverNoise<NX, NY, NP> {
        let p = Self::paper();
        let count = |n: u32| (2.0 * PI / n as f64).powi(2) / 12.0;
        ObserverNoise {
            process: process_noise(h),
            on_board: SMatrix::<f64, NY, NY>::from_diagonal(&SVector::<f64, NY>::new(
                count(p.steer_counts),
                count(p.wheel_counts),
                p.sigma_gyro.powi(2),
            )),
            pose: SMatrix::<f64, NP, NP>::from_diagonal(&SVector::<f64, NP>::new(
                p.sigma_position.powi(2),
                p.sigma_position.powi(2),
                p.sigma_heading.powi(2),
            )),
        }
    }
}

/// `a` counted down to whole counts of `counts` per revolution (0: exact).
fn quantise(a: f64, counts: u32) -> f64 {
    if counts == 0 {
        return a;
    }
    let q = 2.0 * PI / counts as f64;
    (a / q).floor() * q
}

/// A tenth of the built-in plans' largest accelerations (`car plan`, 20 ms: the wheel
/// 28.5 rad/s², lane-change; the steering 2.35 rad/s², parallel-park) and current (1.59 A,
/// lane-change): what ±10 % on the parameters may change them by.
const WHEEL_ACCELERATION_ERROR: f64 = 2.85;
/// See [`WHEEL_ACCELERATION_ERROR`].
const STEER_ACCELERATION_ERROR: f64 = 0.235;
/// See [`WHEEL_ACCELERATION_ERROR`].
const CURRENT_ERROR: f64 = 0.16;

/// What the model may be wrong by over a sample of `h` s, as standard deviations: the rates
/// by the acceleration errors over the sample, the current by its error, the angles by
/// those rates over the sample, the position by the wheel rate's (`r`) and the heading by
/// the yaw rate's at the steering bound (`r tan 0.6 / L`); the previous inputs are known.
pub fn process_noise(h: f64) -> SMatrix<f64, NX, NX> {
    let p = CarParams::default();
    let (wheel_rate, steer_rate) = (WHEEL_ACCELERATION_ERROR * h, STEER_ACCELERATION_ERROR * h);
    let yaw_rate = wheel_rate * p.r * 0.6_f64.tan() / p.L;
    let sigma = [
        wheel_rate * p.r * h,
        wheel_rate * p.r * h,
        yaw_rate * h,
        steer_rate * h,
        wheel_rate * h,
        CURRENT_ERROR * h,
        steer_rate,
        wheel_rate,
        CURRENT_ERROR,
        0.0,
        0.0,
    ];
    SMatrix::<f64, NX, NX>::from_diagonal(&SVector::<f64, NX>::from_fn(|i, _| sigma[i] * sigma[i]))
}

/// The observer's start: the plan's start, uncertain by the start's offset (2 cm, 0.05 rad)
/// in the pose and a little in the shape; the car at rest; the inputs known.
pub fn start_covariance() -> SMatrix<f64, NX, NX> {
    let sigma = [
        2e-2, 2e-2, 5e-2, // pose
        1e-3, 1e-3, 1e-3, // shape
        1e-3, 1e-3, 1e-3, // velocities
        0.0, 0.0,
    ];
    SMatrix::<f64, NX, NX>::from_diagonal(&SVector::<f64, NX>::from_fn(|i, _| sigma[i] * sigma[i]))
}

/// The car's readings as functions of the transcription's state, for its geometry (the
/// nominal's: wheel radius and wheelbase are not among the mismatched parameters):
/// steering angle `φ`, rear-wheel angle `ψ`, and the yaw rate of the no-slip connection,
/// `r ψ̇ tan φ / L` with the last interval's wheel rate; the pose `(x, y, θ)`.
#[derive(Clone, Copy, Debug)]
pub struct CarReadings {
    pub r: f64,
    pub wheelbase: f64,
}

impl CarReadings {
    pub fn new(p: &CarParams) -> Self {
        CarReadings {
            r: p.r,
            wheelbase: p.L,
        }
    }
}

impl Readings<NX, NY, NP> for CarReadings {
    fn on_board<T: Real>(&self, x: &SVector<T, NX>) -> SVector<T, NY> {
        let s: SVector<T, NS> = LAYOUT.shape(x);
        let v: SVector<T, NS> = segment(x, LAYOUT.v_at());
        let (steer, wheel, wheel_rate) = (s[0], s[1], v[1]);
        let yaw_rate = wheel_rate * steer.tan() * (self.r / self.wheelbase);
        SVector::<T, NY>::new(steer, wheel, yaw_rate)
    }
    fn pose<T: Real>(&self, x: &SVector<T, NX>) -> SVector<T, NP> {
        segment(x, 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Quantisation counts down to whole counts: within one count below, exact at a count.
    #[test]
    fn encoders_count_down() {
        let q = 2.0 * PI / 3600.0;
        for a in [-1.234, -q, 0.0, 0.5 * q, 3.0 * q, 7.89] {
            let c = quantise(a, 3600);
            assert!(c <= a && a - c < q * (1.0 + 1e-12), "{a} → {c}");
        }
        assert_eq!(quantise(0.3, 0), 0.3);
    }
}

//! The car's shape-dependent connection against an independent known answer: at a
//! constant steering angle φ the rear axle drives the kinematic bicycle's circle of radius
//! `L / tan φ`, here at steady speed (drive torque balancing the axle damping, no steering
//! torque), through the generic continuous model and the midpoint integrator.

use dmech::continuous::{ContinuousModel, ContinuousState, RungeKutta};
use dmech::{Discretisation, VariationalIntegrator, ViState};
use dmech_lie::Se2;
use nalgebra::{SVector, Vector3};
use robots::car::Car;

/// The steady circle: steering `phi`, wheel rate `wheel_rate`; the current whose torque
/// balances the axle damping and the voltage that holds it.
fn steady(car: &Car, wheel_rate: f64) -> (Vector3<f64>, SVector<f64, 2>) {
    let p = &car.params;
    let current = p.c_w * wheel_rate / car.torque_constant();
    let voltage = p.R_m * current + car.torque_constant() * wheel_rate;
    (
        Vector3::new(0.0, wheel_rate, current),
        SVector::<f64, 2>::new(0.0, voltage),
    )
}

/// Largest `|distance from the centre − R|` and `|φ − φ₀|` over one lap, and the number of
/// steps.
fn lap_deviation(
    car: &Car,
    phi: f64,
    wheel_rate: f64,
    h: f64,
    scheme: Option<Discretisation>,
) -> (f64, f64, usize) {
    let p = &car.params;
    let radius = p.L / phi.tan();
    let speed = p.r * wheel_rate;
    let n = (2.0 * std::f64::consts::PI * radius / speed.abs() / h).round() as usize;
    let (v0, u) = steady(car, wheel_rate);
    let s0 = Vector3::new(phi, 0.0, 0.0);
    let g0 = Se2::new(0.0, 0.0, 0.0);
    let (mut worst_r, mut worst_phi) = (0.0f64, 0.0f64);
    let mut record = |g: &Se2<f64>, s: &Vector3<f64>| {
        let d = (g.x * g.x + (g.y - radius) * (g.y - radius)).sqrt();
        worst_r = worst_r.max((d - radius).abs());
        worst_phi = worst_phi.max((s[0] - phi).abs());
    };
    match scheme {
        None => {
            let mut y = ContinuousState {
                g: g0,
                s: s0,
                v: v0,
            };
            for _ in 0..n {
                y = ContinuousModel::step(car, RungeKutta::Rk4, h, &y, &u).unwrap();
                record(&y.g, &y.s);
            }
        }
        Some(d) => {
            let vi = VariationalIntegrator::new(h).with_discretisation(d);
            let mut x = ViState {
                g: g0,
                s: s0,
                v: vi.start(car, &s0, &v0, &u).unwrap(),
            };
            for _ in 0..n {
                x = vi.step(car, &x, &u, &u).unwrap().0;
                record(&x.g, &x.s);
            }
        }
    }
    (worst_r, worst_phi, n)
}

/// φ = 0.3 rad (R = 0.808 m), 1 m/s forward and 0.5 m/s in reverse, one lap at h = 2 ms.
/// Both variational schemes keep a constant body velocity exactly (a relative equilibrium:
/// `dexp⁻¹_x − dexp⁻¹_{−x} = −ad_x`, and `A_ψᵀ ad*_ξ μ = 0` because `A_ψ ∝ ξ`), so their
/// laps are the circle to round-off: a few ulps of `R` per step, `8 ε R n`. RK4 on the
/// pose coordinates adds its truncation error, `(hω)⁴ R` per lap at most (ω the yaw rate).
#[test]
fn constant_steering_drives_the_bicycle_circle() {
    let car = Car::default();
    let phi: f64 = 0.3;
    let radius = car.params.L / phi.tan();
    let h = 2e-3;
    for wheel_rate in [20.0, -10.0] {
        let omega = (car.params.r * wheel_rate / radius).abs();
        for scheme in [
            None,
            Some(Discretisation::FirstOrder),
            Some(Discretisation::Midpoint),
        ] {
            let (dev_r, dev_phi, n) = lap_deviation(&car, phi, wheel_rate, h, scheme);
            println!(
                "ψ̇ = {wheel_rate}, {scheme:?}: {n} steps, off the circle by {dev_r:.2e} m, \
                 steering off by {dev_phi:.2e} rad (R = {radius:.4} m)"
            );
            let round_off = 8.0 * f64::EPSILON * radius * n as f64;
            let truncation = if scheme.is_none() {
                (h * omega).powi(4) * radius
            } else {
                0.0
            };
            assert!(dev_r <= round_off + truncation, "{scheme:?}: {dev_r:e} m");
            assert!(
                dev_phi <= 8.0 * f64::EPSILON * phi * n as f64,
                "{scheme:?}: {dev_phi:e} rad"
            );
        }
    }
}

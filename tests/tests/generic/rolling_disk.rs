//! The vertical rolling disk (principal-kinematic on R², heading and rolling angle as
//! shape), unforced, against the closed forms of both schemes' steps: the evidence for the
//! library's default scheme (docs/integrator.md, "Which scheme").
//!
//! With `θ̇` constant (the heading's equation has no coupling), the rolling rate's momentum
//! matching reads, for the first-order scheme (`A` at the node; on R² `dexp = I`),
//! `(J + mR²) φ̇_k = (J + mR² cos(h θ̇)) φ̇_{k−1}`: every step multiplies the rolling rate,
//! hence the rolling energy, by a factor below one. The midpoint scheme reads `A` at the
//! interval midpoints, half a step of heading from either node, and both sides carry
//! `cos(h θ̇ / 2)`: `φ̇_k = φ̇_{k−1}` exactly.

use dmech::{energy, Discretisation, VariationalIntegrator, ViState};
use dmech_lie::Rn;
use dmech_tests::momentum_systems::{RollingDisk, RollingDiskOnPlane};
use nalgebra::Vector2;

const DISK: RollingDisk = RollingDisk {
    m: 1.2,
    r: 0.15,
    i: 0.01,
    j: 0.02,
};

/// 10⁵ steps of 10 ms from θ̇ = 1, φ̇ = 10 rad/s: the first-order scheme's rolling rate is
/// `φ̇₀ fⁿ` at every step to round-off (a relative error of a few ulps per step, so the
/// bound grows with the step count), the midpoint scheme's is `φ̇₀`, and the energy follows.
#[test]
fn the_rolling_rate_follows_each_schemes_closed_form() {
    let disk = RollingDiskOnPlane(DISK);
    let (h, n, theta_dot, phi_dot): (f64, usize, f64, f64) = (0.01, 100_000, 1.0, 10.0);
    let rolling = DISK.j + DISK.m * DISK.r * DISK.r;
    let factor = (DISK.j + DISK.m * DISK.r * DISK.r * (h * theta_dot).cos()) / rolling;
    let u = Vector2::zeros();
    let x0 = ViState {
        g: Rn(Vector2::zeros()),
        s: Vector2::new(0.0, 0.0),
        v: Vector2::new(theta_dot, phi_dot),
    };
    let e0 = energy::<_, f64, 2, 2, 2>(&disk, &x0.s, &x0.v);
    for disc in [Discretisation::FirstOrder, Discretisation::Midpoint] {
        let vi = VariationalIntegrator::new(h).with_discretisation(disc);
        let mut x = ViState {
            v: vi.start(&disk, &x0.s, &x0.v, &u).unwrap(),
            ..x0
        };
        let v_start = x.v[1];
        let mut expected = v_start;
        let mut tenths = Vec::new();
        for k in 1..=n {
            x = vi.step(&disk, &x, &u, &u).unwrap().0;
            if disc == Discretisation::FirstOrder {
                expected *= factor;
            }
            let bound = 16.0 * f64::EPSILON * k as f64 * expected.abs() + 1e-300;
            assert!(
                (x.v[1] - expected).abs() <= bound,
                "{disc:?} step {k}: rolling rate {} against the closed form {expected}",
                x.v[1]
            );
            assert!((x.v[0] - theta_dot).abs() <= 8.0 * f64::EPSILON * k as f64);
            if k % (n / 10) == 0 {
                let s = disc.evaluation_point(h, &x.s, &x.v);
                tenths.push(energy::<_, f64, 2, 2, 2>(&disk, &s, &x.v) / e0);
            }
        }
        let shown: Vec<String> = tenths.iter().map(|e| format!("{e:.4}")).collect();
        println!("{disc:?}: E/E₀ at each tenth of 10⁵ steps {shown:?}");
    }
}

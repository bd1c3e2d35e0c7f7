//! The scalar abstraction and the removable-singularity functions that the closed forms
//! of `exp`, `log`, `dexp` and `dexp⁻¹` are built from.
//!
//! Every coefficient function here is even in the rotation angle `θ`, so it is written as
//! a function of `t = θ²`. That matters for dual numbers: `θ = √(ω·ω)` has an infinite
//! derivative at `ω = 0`, whereas `t = ω·ω` is smooth, so a function of `t` differentiated
//! through dual numbers at `ω = 0` gives the exact derivative. The branch between the
//! series and the closed form is taken on the real part only, and the series is evaluated
//! in the dual variable, so that no derivative information is lost on either branch.

use num_dual::DualNum;

/// A scalar the Lie groups (and everything built on them) can be evaluated in: `f64`, or
/// any `num-dual` number over `f64` (first/second derivatives, vector duals, nested duals).
pub trait Real: DualNum<Primitive = f64> + Copy + Send + Sync {}
impl<T: DualNum<Primitive = f64> + Copy + Send + Sync> Real for T {}

/// `t = θ²` below which the series branch is used: `θ < 0.25`. Each series below is
/// truncated where the next term is below 1e-20 at this bound, and above it the closed
/// forms lose at most `ε/θ² ≈ 4e-15` to cancellation (and `ε/θ⁴ ≈ 6e-14` in second
/// derivatives), so values and derivatives are accurate to ~1e-13 on both sides.
pub const SERIES_THRESHOLD: f64 = 0.0625;

/// Lift a constant into the scalar type.
#[inline(always)]
pub fn c<T: Real>(x: f64) -> T {
    T::from(x)
}

/// Horner evaluation of `Σ coeffs[k] t^k` in the scalar type.
#[inline]
fn series<T: Real>(t: T, coeffs: &[f64]) -> T {
    let mut acc = T::from(*coeffs.last().unwrap());
    for &ck in coeffs.iter().rev().skip(1) {
        acc = acc * t + ck;
    }
    acc
}

#[inline]
fn small<T: Real>(t: T) -> bool {
    t.re().abs() < SERIES_THRESHOLD
}

// Series coefficients (in t = θ²), Σ_k (−1)^k t^k / (2k+n)! for n = 1, 2, 3, 4.
const SINC: [f64; 8] = [
    1.0,
    -1.0 / 6.0,
    1.0 / 120.0,
    -1.0 / 5040.0,
    1.0 / 362880.0,
    -1.0 / 39916800.0,
    1.0 / 6227020800.0,
    -1.0 / 1307674368000.0,
];
const COSC: [f64; 8] = [
    1.0 / 2.0,
    -1.0 / 24.0,
    1.0 / 720.0,
    -1.0 / 40320.0,
    1.0 / 3628800.0,
    -1.0 / 479001600.0,
    1.0 / 87178291200.0,
    -1.0 / 20922789888000.0,
];
const SINC3: [f64; 8] = [
    1.0 / 6.0,
    -1.0 / 120.0,
    1.0 / 5040.0,
    -1.0 / 362880.0,
    1.0 / 39916800.0,
    -1.0 / 6227020800.0,
    1.0 / 1307674368000.0,
    -1.0 / 355687428096000.0,
];
const COSC4: [f64; 8] = [
    1.0 / 24.0,
    -1.0 / 720.0,
    1.0 / 40320.0,
    -1.0 / 3628800.0,
    1.0 / 479001600.0,
    -1.0 / 87178291200.0,
    1.0 / 20922789888000.0,
    -1.0 / 6402373705728000.0,
];
// Σ_{k≥2} (−1)^k (k−1)/(2k+1)! t^{k−2}
const SE3_C: [f64; 7] = [
    1.0 / 120.0,
    -2.0 / 5040.0,
    3.0 / 362880.0,
    -4.0 / 39916800.0,
    5.0 / 6227020800.0,
    -6.0 / 1307674368000.0,
    7.0 / 355687428096000.0,
];
// (1 − (θ/2)cot(θ/2))/θ² = Σ_{n≥1} (−1)^{n+1} B_{2n} θ^{2n−2}/(2n)!; radius of convergence
// (2π)², so terms fall by ≈ (θ/2π)² ≤ 1.6e-3 each at the threshold.
const DEXPINV: [f64; 7] = [
    1.0 / 12.0,
    1.0 / 720.0,
    1.0 / 30240.0,
    1.0 / 1209600.0,
    1.0 / 47900160.0,
    691.0 / 1307674368000.0,
    1.0 / 74724249600.0,
];

/// `sin θ / θ` as a function of `t = θ²`.
pub fn sinc<T: Real>(t: T) -> T {
    if small(t) {
        series(t, &SINC)
    } else {
        let th = t.sqrt();
        th.sin() / th
    }
}

/// `(1 − cos θ) / θ²` as a function of `t = θ²`.
pub fn cosc<T: Real>(t: T) -> T {
    if small(t) {
        series(t, &COSC)
    } else {
        (T::one() - t.sqrt().cos()) / t
    }
}

/// `(θ − sin θ) / θ³` as a function of `t = θ²`.
pub fn sinc3<T: Real>(t: T) -> T {
    if small(t) {
        series(t, &SINC3)
    } else {
        let th = t.sqrt();
        (th - th.sin()) / (t * th)
    }
}

/// `(θ² + 2 cos θ − 2) / (2 θ⁴)` as a function of `t = θ²`.
pub fn cosc4<T: Real>(t: T) -> T {
    if small(t) {
        series(t, &COSC4)
    } else {
        (t + t.sqrt().cos() * 2.0 - 2.0) / (t * t * 2.0)
    }
}

/// `(2θ − 3 sin θ + θ cos θ) / (2 θ⁵)` as a function of `t = θ²` (SE(3)'s `Q` matrix).
pub fn se3_q_coeff<T: Real>(t: T) -> T {
    if small(t) {
        series(t, &SE3_C)
    } else {
        let th = t.sqrt();
        let (s, co) = th.sin_cos();
        (th * 2.0 - s * 3.0 + th * co) / (t * t * th * 2.0)
    }
}

/// `(1 − (θ/2) cot(θ/2)) / θ²` as a function of `t = θ²`: the coefficient of `ad²` in
/// `dexp⁻¹` of SO(3) and SE(2)/SE(3) (singular at θ = 2π, the end of the injectivity domain).
pub fn dexp_inv_coeff<T: Real>(t: T) -> T {
    if small(t) {
        series(t, &DEXPINV)
    } else {
        let half = t.sqrt() * 0.5;
        let (s, co) = half.sin_cos();
        (T::one() - half * co / s) / t
    }
}

const SE3_ALPHA3: [f64; 8] = [
    1.0 / 24.0,
    -1.0 / 360.0,
    1.0 / 13440.0,
    -1.0 / 907200.0,
    1.0 / 95800320.0,
    -1.0 / 14529715200.0,
    1.0 / 2988969984000.0,
    -1.0 / 800296713216000.0,
];

/// `(2 − 2 cos θ − θ sin θ) / (2 θ⁴)` as a function of `t = θ²` (coefficient of `ad³` in
/// the SE(3) `dexp`).
pub fn se3_alpha3<T: Real>(t: T) -> T {
    if small(t) {
        series(t, &SE3_ALPHA3)
    } else {
        let th = t.sqrt();
        let (s, co) = th.sin_cos();
        (T::from(2.0) - co * 2.0 - th * s) / (t * t * 2.0)
    }
}

/// `cos(θ/2)` as a function of `t = θ²`.
pub fn cos_half<T: Real>(t: T) -> T {
    // cos(√t/2) = Σ (−1)^k t^k / (4^k (2k)!)
    if small(t) {
        series(
            t,
            &[
                1.0,
                -1.0 / 8.0,
                1.0 / 384.0,
                -1.0 / 46080.0,
                1.0 / 10321920.0,
                -1.0 / 3715891200.0,
            ],
        )
    } else {
        (t.sqrt() * 0.5).cos()
    }
}

/// `sin(θ/2) / θ` as a function of `t = θ²`.
pub fn sin_half_over<T: Real>(t: T) -> T {
    sinc(t * 0.25) * 0.5
}

/// `atan(√t)/√t` for `t ≥ 0`, a smooth function of `t` (used by the SO(3) log).
pub fn atan_over<T: Real>(t: T) -> T {
    if small(t) {
        // Σ (−1)^k t^k / (2k+1); at t < 0.0625 the 12th term is below 1e-16.
        series(
            t,
            &[
                1.0,
                -1.0 / 3.0,
                1.0 / 5.0,
                -1.0 / 7.0,
                1.0 / 9.0,
                -1.0 / 11.0,
                1.0 / 13.0,
                -1.0 / 15.0,
                1.0 / 17.0,
                -1.0 / 19.0,
                1.0 / 21.0,
                -1.0 / 23.0,
                1.0 / 25.0,
                -1.0 / 27.0,
            ],
        )
    } else {
        let s = t.sqrt();
        s.atan() / s
    }
}

/// `tanh` that stays finite in dual numbers at any argument. num-dual evaluates
/// `sinh/cosh`, which overflow to `inf/inf = NaN` beyond `|x| ≈ 710` (a smoothed Coulomb
/// friction `tanh(ω/ω_c)` at a fast wheel, reachable while a fit explores); beyond
/// `|x| = 20` the value is `±1` and the derivative `4e-17`, both exact in double precision.
pub fn tanh_saturating<T: Real>(x: T) -> T {
    if x.re().abs() > 20.0 {
        T::from(x.re().signum())
    } else {
        x.tanh()
    }
}

/// Wrap an angle into (−π, π] by subtracting a multiple of 2π chosen on the real part, so
/// that the derivative passes through unchanged.
pub fn wrap_angle<T: Real>(theta: T) -> T {
    let tau = std::f64::consts::TAU;
    let k = ((theta.re() + std::f64::consts::PI) / tau).floor();
    let mut w = theta - k * tau;
    // floor(·) maps exactly π to −π; keep π.
    if w.re() <= -std::f64::consts::PI {
        w += tau;
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::{Dual2_64, Dual64};

    /// Value and derivative equal `tanh` and `1 − tanh²` in double precision at every
    /// argument, and stay finite where num-dual's own `tanh` (`sinh/cosh`) gives NaN.
    #[test]
    fn tanh_saturating_is_tanh_and_finite_everywhere() {
        for x in [
            -1e4, -800.0, -20.5, -19.5, -1.0, 0.0, 0.3, 19.5, 20.5, 800.0, 1e4,
        ] {
            let y = tanh_saturating(Dual64::from(x).derivative());
            let exact = x.tanh();
            assert!(
                (y.re - exact).abs() <= f64::EPSILON,
                "{x}: {} vs {exact}",
                y.re
            );
            assert!(
                (y.eps - (1.0 - exact * exact)).abs() <= 4.0 * f64::EPSILON,
                "{x}: {}",
                y.eps
            );
        }
        assert!(Dual64::from(800.0).derivative().tanh().re.is_nan());
    }

    /// Both branches agree at the threshold (values and first/second derivatives), so the
    /// switch introduces no jump: checked with second-order duals just below and above.
    #[test]
    fn branches_agree_at_threshold() {
        type F = fn(Dual2_64) -> Dual2_64;
        let fns: [(&str, F); 8] = [
            ("sinc", sinc),
            ("cosc", cosc),
            ("sinc3", sinc3),
            ("cosc4", cosc4),
            ("se3_q", se3_q_coeff),
            ("dexp_inv", dexp_inv_coeff),
            ("cos_half", cos_half),
            ("atan_over", atan_over),
        ];
        for (name, f) in fns {
            let lo = f(Dual2_64::from_re(SERIES_THRESHOLD * (1.0 - 1e-12)).derivative());
            let hi = f(Dual2_64::from_re(SERIES_THRESHOLD * (1.0 + 1e-12)).derivative());
            // Value and derivatives change by O(1e-12 · t) across the 2e-12 relative gap,
            // the closed form carries ≲ ε/t² ≈ 6e-14 of cancellation in v2.
            assert!((lo.re - hi.re).abs() < 1e-13, "{name} value");
            assert!(
                (lo.v1 - hi.v1).abs() < 1e-12,
                "{name} d1 {} {}",
                lo.v1,
                hi.v1
            );
            assert!((lo.v2 - hi.v2).abs() < 1e-10, "{name} d2");
        }
    }

    #[test]
    fn derivatives_at_zero_are_exact() {
        // d/dt sinc(t) at 0 = −1/6, cosc' = −1/24, dexp_inv' = 1/720.
        let d = |f: fn(Dual64) -> Dual64| f(Dual64::from_re(0.0).derivative()).eps;
        assert_eq!(d(sinc), -1.0 / 6.0);
        assert_eq!(d(cosc), -1.0 / 24.0);
        assert_eq!(d(dexp_inv_coeff), 1.0 / 720.0);
    }

    #[test]
    fn wrap_keeps_derivative() {
        let x = Dual64::from_re(7.0).derivative();
        let w = wrap_angle(x);
        assert!((w.re - (7.0 - std::f64::consts::TAU)).abs() < 1e-15);
        assert_eq!(w.eps, 1.0);
        assert_eq!(wrap_angle(std::f64::consts::PI), std::f64::consts::PI);
        assert_eq!(wrap_angle(-std::f64::consts::PI), std::f64::consts::PI);
    }
}

//! The paper's 9-state reduced state `X = (x, y, θ, α, v_α, v_d, v_θ, iR, iL)` and its
//! relation to the framework's `(g, s, v_s)`.

use super::params::WipParams;
use dmech_lie::Se2;
use nalgebra::SVector;

/// Shape dimension and number of inputs of the WIP.
pub const NS: usize = 5;
pub const NU: usize = 2;

/// `X = (x, y, θ, α, v_α, v_d, v_θ, iR, iL)`.
pub type ReducedState = SVector<f64, 9>;

/// Names of the reduced state's components, in order (CSV headers, messages).
pub const STATE_NAMES: [&str; 9] = [
    "x", "y", "theta", "alpha", "v_alpha", "v_d", "v_theta", "iR", "iL",
];

/// `(v_d, v_θ) → (φ̇R, φ̇L)`: `φ̇R = (v_d + d v_θ)/r`, `φ̇L = (v_d − d v_θ)/r`.
pub fn wheel_rates(p: &WipParams, v_d: f64, v_theta: f64) -> (f64, f64) {
    ((v_d + p.d * v_theta) / p.r, (v_d - p.d * v_theta) / p.r)
}

/// `(φ̇R, φ̇L) → (v_d, v_θ)`.
pub fn body_rates(p: &WipParams, vr: f64, vl: f64) -> (f64, f64) {
    (p.r * (vr + vl) / 2.0, p.r * (vr - vl) / (2.0 * p.d))
}

/// `X → (g, s, v_s)`. The wheel angles and charges, which `X` does not carry (the
/// dynamics do not depend on them), are given separately.
pub fn from_reduced(
    p: &WipParams,
    x: &ReducedState,
    phi_and_charge: [f64; 4],
) -> (Se2<f64>, SVector<f64, 5>, SVector<f64, 5>) {
    let g = Se2::new(x[0], x[1], x[2]);
    let [phr, phl, qr, ql] = phi_and_charge;
    let s = SVector::<f64, 5>::new(x[3], phr, phl, qr, ql);
    let (vr, vl) = wheel_rates(p, x[5], x[6]);
    let v = SVector::<f64, 5>::new(x[4], vr, vl, x[7], x[8]);
    (g, s, v)
}

/// `(g, s, v_s) → X`.
pub fn to_reduced(
    p: &WipParams,
    g: &Se2<f64>,
    s: &SVector<f64, 5>,
    v: &SVector<f64, 5>,
) -> ReducedState {
    let (vd, vt) = body_rates(p, v[1], v[2]);
    ReducedState::from_column_slice(&[g.x, g.y, g.theta, s[0], v[0], vd, vt, v[3], v[4]])
}

/// `v̇_s → (v̇_α, v̇_d, v̇_θ, i̇R, i̇L)`.
pub fn reduced_acceleration(p: &WipParams, a: &SVector<f64, 5>) -> SVector<f64, 5> {
    let (ad, at) = body_rates(p, a[1], a[2]);
    SVector::<f64, 5>::new(a[0], ad, at, a[3], a[4])
}

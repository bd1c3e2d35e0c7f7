//! The paper's linear discrete-time model: the continuous model linearised at upright rest
//! by autodiff, then discretised exactly under zero-order hold (docs/tracking.md).

use crate::wip::Wip;
use crate::wip::WipParams;
use dmech::continuous::acceleration;
use dmech_lie::dual::value_and_jacobian;
use dmech_lie::Real;
use nalgebra::{SMatrix, SVector};

/// Number of linear states `z = (d, θ, α, v_α, v_d, v_θ, iR, iL)` and inputs `(uR, uL)`.
pub const NZ: usize = 8;
pub const NIN: usize = 2;

/// The continuous vector field `ż = f(z, u)` of the planar WIP with `y` dropped and `x`
/// replaced by the travelled distance `d` (so `ḋ = v_d`, valid at any heading), generic
/// over the scalar so that autodiff gives its Jacobian. `w = (z, u)`.
pub fn vector_field<T: Real>(wip: &Wip, w: &SVector<T, { NZ + NIN }>) -> Option<SVector<T, NZ>> {
    let p = wip.params;
    let (r, dd) = (T::from(p.r), T::from(p.d));
    let (alpha, va, vd, vt, ir, il) = (w[2], w[3], w[4], w[5], w[6], w[7]);
    let s = SVector::<T, 5>::new(alpha, T::zero(), T::zero(), T::zero(), T::zero());
    let v = SVector::<T, 5>::new(va, (vd + dd * vt) / r, (vd - dd * vt) / r, ir, il);
    let u = SVector::<T, 2>::new(w[8], w[9]);
    let a = acceleration(wip, &s, &v, &u)?;
    let two = T::from(2.0);
    Some(SVector::<T, NZ>::from_column_slice(&[
        vd,
        vt,
        va,
        a[0],
        r * (a[1] + a[2]) / two,
        r * (a[1] - a[2]) / (two * dd),
        a[3],
        a[4],
    ]))
}

/// The linearisation `(A, B)` of [`vector_field`] at `z = 0, u = 0`, by vector duals.
pub fn linearise(wip: &Wip) -> (SMatrix<f64, NZ, NZ>, SMatrix<f64, NZ, NIN>) {
    linearise_at(wip, &SVector::zeros(), &SVector::zeros())
        .expect("the mass matrix is regular at upright rest")
}

/// The linearisation `(A, B)` of [`vector_field`] at the state `z` and input `u`, by
/// vector duals; `None` where the mass matrix is singular.
pub fn linearise_at(
    wip: &Wip,
    z: &SVector<f64, NZ>,
    u: &SVector<f64, NIN>,
) -> Option<(SMatrix<f64, NZ, NZ>, SMatrix<f64, NZ, NIN>)> {
    let mut w = SVector::<f64, { NZ + NIN }>::zeros();
    w.fixed_rows_mut::<NZ>(0).copy_from(z);
    w.fixed_rows_mut::<NIN>(NZ).copy_from(u);
    vector_field(wip, &w)?;
    let (_, j) = value_and_jacobian(
        |w| vector_field(wip, w).expect("regular at the point, checked above"),
        &w,
    );
    Some((
        j.fixed_view::<NZ, NZ>(0, 0).into_owned(),
        j.fixed_view::<NZ, NIN>(0, NZ).into_owned(),
    ))
}

/// The paper's linear-model parameters: the nominal ones with the friction replaced by a
/// viscous `d_v = 4.25e-3 N m s/rad`, `d_c = 0` (the secant of the nonlinear friction
/// curve at the nominal 0.4 m/s).
pub fn linear_model_params(p: &WipParams) -> WipParams {
    WipParams {
        d_v: 4.25e-3,
        d_c: 0.0,
        ..*p
    }
}

/// Exact zero-order-hold discretisation at step `h`: `exp(h [A B; 0 0]) = [Φ Γ; 0 I]`.
pub fn zoh<const N: usize, const M: usize>(
    a: &SMatrix<f64, N, N>,
    b: &SMatrix<f64, N, M>,
    h: f64,
) -> (SMatrix<f64, N, N>, SMatrix<f64, N, M>) {
    let n = N + M;
    let mut big = nalgebra::DMatrix::<f64>::zeros(n, n);
    big.view_mut((0, 0), (N, N)).copy_from(&(a * h));
    big.view_mut((0, N), (N, M)).copy_from(&(b * h));
    let e = big.exp();
    (
        SMatrix::<f64, N, N>::from_fn(|i, j| e[(i, j)]),
        SMatrix::<f64, N, M>::from_fn(|i, j| e[(i, N + j)]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ZOH pair satisfies `Φ = I + A ∫₀ʰ e^{As} ds`, `Γ = ∫₀ʰ e^{As} ds B`: so
    /// `A Γ = (Φ − I) B` exactly; the tolerance is the matrix exponential's rounding
    /// (norms of order 1e3 times machine epsilon).
    #[test]
    fn zoh_pair_is_consistent() {
        let wip = Wip::new(linear_model_params(&WipParams::default()));
        let (a, b) = linearise(&wip);
        let (phi, gam) = zoh(&a, &b, 0.005);
        let lhs = a * gam;
        let rhs = (phi - SMatrix::<f64, NZ, NZ>::identity()) * b;
        let scale = lhs.norm().max(1.0);
        assert!((lhs - rhs).norm() < 1e-9 * scale, "{}", (lhs - rhs).norm());
    }

    /// The upright WIP is unstable: one eigenvalue with positive real part (the falling
    /// pendulum), and the inputs reach it.
    #[test]
    fn upright_rest_is_unstable() {
        let wip = Wip::new(linear_model_params(&WipParams::default()));
        let (a, _) = linearise(&wip);
        let ev = a.complex_eigenvalues();
        assert_eq!(ev.iter().filter(|l| l.re > 1e-6).count(), 1, "{ev}");
    }
}

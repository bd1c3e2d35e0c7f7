//! The prediction model of `wip diagnose`: the WIP with a [`ModelExtension`] (the same
//! `Wip<T>` as everywhere else), the current reduced to its steady state, and the sensors.
//! The accelerations come from the WIP's closed form (`closed_form::shape_acceleration`,
//! checked against `dmech`'s generic equations of motion with every extension), because
//! the fit differentiates them in up to 17 dual directions.
//!
//! The electrical time constant `τ_e = L_m/R_m` (0.27 ms) is far below the sample step, so
//! the current is algebraic, `i = (u − k_e n_wm (φ̇ − α̇))/R_m`, and what the current's lag
//! does to the motion is, to first order, an input delay of `τ_e`: the prediction applies
//! over each step the mean of the zero-order-hold voltage delayed by `τ_e + delay`
//! (`docs/diagnose.md`).

use super::effects::ModelExtension;
use crate::wip::closed_form::shape_acceleration;
use crate::wip::Wip;
use dmech::{Lift, PrincipalKinematicSystem};
use dmech_lie::Real;
use nalgebra::SVector;
use num_dual::DualSVec64;

/// `z = (x, y, θ, α, φR, φL, v_α, v_φR, v_φL)`.
pub const NZ: usize = 9;
/// Dual directions of the LQR design (four states, two inputs; `generate`).
pub const ND: usize = 9;
/// A dual scalar with `ND` directions.
pub type D = DualSVec64<ND>;

/// Indices of `z` seeded with dual directions 0..5.
pub const DUAL_STATE: [usize; 5] = [2, 3, 6, 7, 8];

/// Scalars in which the prediction model runs: `f64` (values) and dual vectors (values
/// and derivatives with respect to the initial state and the effect parameters).
pub trait FitScalar: Real + Lift<Self> {}
impl<T: Real + Lift<T>> FitScalar for T {}

/// The prediction model: a system with its extension.
pub struct Predictor<T> {
    pub ext: ModelExtension<T>,
    pub sys: Wip<T>,
    /// `τ_e = L_m / R_m`.
    pub electrical_lag: f64,
}

impl<T: FitScalar> Predictor<T> {
    pub fn new(ext: ModelExtension<T>, base: &crate::wip::WipParams) -> Self {
        let mut sys = ext.system(base);
        sys.quasi_static_inertia = T::from(lag_inertia(base));
        Predictor {
            sys,
            ext,
            electrical_lag: base.L_m / base.R_m,
        }
    }

    /// The steady-state currents for applied voltages `u` at wheel rates relative to the
    /// body `w = φ̇ − α̇`.
    pub fn current(&self, u: [T; 2], w: [T; 2]) -> [T; 2] {
        let p = &self.sys.params;
        [p.steady_current(u[0], w[0]), p.steady_current(u[1], w[1])]
    }

    /// `ż` for applied voltages `u` (after the driver).
    pub fn rate(&self, z: &SVector<T, NZ>, u: [T; 2]) -> Option<SVector<T, NZ>> {
        let (va, vr, vl) = (z[6], z[7], z[8]);
        let i = self.current(u, [vr - va, vl - va]);
        let s = SVector::<T, 5>::new(z[3], z[4], z[5], T::zero(), T::zero());
        let v = SVector::<T, 5>::new(va, vr, vl, i[0], i[1]);
        let a_conn = self.sys.connection(&s);
        let xi = -(a_conn * v);
        let f_ext = self.ext.floor_force(&self.sys, &s, z[2]);
        let a = shape_acceleration(
            &self.sys,
            z[3],
            [va, vr, vl],
            i,
            [f_ext[0], f_ext[1], f_ext[2]],
        )?;
        let (st, ct) = z[2].sin_cos();
        Some(SVector::<T, NZ>::from_column_slice(&[
            xi[0] * ct - xi[1] * st,
            xi[0] * st + xi[1] * ct,
            xi[2],
            va,
            vr,
            vl,
            a[0],
            a[1],
            a[2],
        ]))
    }

    /// One classical Runge–Kutta step of length `dt` with the applied voltage `u` held;
    /// also the relative wheel accelerations `ẇ` of the last stage (at the step's end,
    /// to `O(dt³)`), which the current reading needs.
    pub fn step(&self, z: &SVector<T, NZ>, u: [T; 2], dt: T) -> Option<(SVector<T, NZ>, [T; 2])> {
        let half = dt * 0.5;
        let k1 = self.rate(z, u)?;
        let k2 = self.rate(&(z + k1 * half), u)?;
        let k3 = self.rate(&(z + k2 * half), u)?;
        let k4 = self.rate(&(z + k3 * dt), u)?;
        let out = z + (k1 + k2 * T::from(2.0) + k3 * T::from(2.0) + k4) * (dt / 6.0);
        let wdot = [k4[7] - k4[6], k4[8] - k4[6]];
        out.iter()
            .all(|x| x.re().is_finite())
            .then_some((out, wdot))
    }

    /// Advance from `t_k` to `t_{k+1}`. The commands reach the motors `τ = τ_e + delay`
    /// late; with `τ = m h + f`, the applied voltage is `κ·dz(u_{k−m−1})` on
    /// `[t_k, t_k + f)` and `κ·dz(u_{k−m})` on `[t_k + f, t_{k+1})`. Each piece is
    /// integrated on its own (a Runge–Kutta step across the switch would be first order)
    /// in steps of at most `MAX_SUBSTEP · h`; `f` carries the derivative with respect to
    /// the delay.
    pub fn advance(
        &self,
        z: &SVector<T, NZ>,
        cmd: &[[f64; 2]],
        k: usize,
        h: f64,
    ) -> Option<(SVector<T, NZ>, [T; 2])> {
        let tau = self.ext.delay + T::from(self.electrical_lag);
        let (f, old, new) = self.delayed(cmd, k as isize, h, tau);
        let mut state = (*z, [T::zero(); 2]);
        let rest = T::from(h) - f;
        for (len, u) in [(f, old), (rest, new)] {
            if len.re() <= 1e-12 * h {
                continue;
            }
            let n = (len.re() / (MAX_SUBSTEP * h)).ceil().max(1.0) as usize;
            let dt = len / n as f64;
            for _ in 0..n {
                state = self.step(&state.0, u, dt)?;
            }
        }
        Some(state)
    }

    /// `ẇ` at a state for applied voltages `u` (for the first reading of a window).
    pub fn wheel_acceleration(&self, z: &SVector<T, NZ>, u: [T; 2]) -> Option<[T; 2]> {
        let r = self.rate(z, u)?;
        Some([r[7] - r[6], r[8] - r[6]])
    }

    /// The driver's output over `[t_k, t_{k+1})` when the commands `cmd` (zero-order
    /// hold, `cmd[j]` from `t_j`; before the log the first command) arrive `τ` late: with
    /// `τ = m h + f`, `(f, κ·dz(u_{k−m−1}), κ·dz(u_{k−m}))`, the first voltage applied
    /// until `t_k + f`, the second after. `f` carries the derivative with respect to `τ`.
    fn delayed(&self, cmd: &[[f64; 2]], k: isize, h: f64, tau: T) -> (T, [T; 2], [T; 2]) {
        let (m, f) = split_delay(tau, h);
        let at = |j: isize| {
            let c = cmd[j.max(0) as usize];
            [
                self.ext.driver(T::from(c[0])),
                self.ext.driver(T::from(c[1])),
            ]
        };
        (f, at(k - m - 1), at(k - m))
    }

    /// The mean of the applied voltage over `[t_k, t_{k+1})` (delay `τ_e + delay`):
    /// `(f/h) old + (1 − f/h) new`.
    pub fn mean_applied(&self, cmd: &[[f64; 2]], k: usize, h: f64) -> [T; 2] {
        let tau = self.ext.delay + T::from(self.electrical_lag);
        let (f, old, new) = self.delayed(cmd, k as isize, h, tau);
        let w = f / h;
        [0, 1].map(|c| old[c] * w + new[c] * (T::one() - w))
    }

    /// The voltage behind the current read at `t_k`: the driver's last switch before
    /// `t_k` (the step before, delayed by `delay` alone) happened `h − f` earlier, and the
    /// current has relaxed from the previous level with `exp(−(h − f)/τ_e)` since.
    pub fn current_voltage(&self, cmd: &[[f64; 2]], k: usize, h: f64) -> [T; 2] {
        let (f, old, new) = self.delayed(cmd, k as isize - 1, h, self.ext.delay);
        let decay = (-(T::from(h) - f) / self.electrical_lag).exp();
        [0, 1].map(|c| new[c] + (old[c] - new[c]) * decay)
    }

    /// The sensor readings at state `z` with `u_i` the voltage behind the current and
    /// `ẇ` the relative wheel accelerations:
    /// `[x, y, θ, alpha, v_alpha, phiR_rel, phiL_rel, iR, iL]`. The current is the steady
    /// state plus its first-order lag correction `(L_m k_e n_wm / R_m²) ẇ`.
    pub fn readings(&self, z: &SVector<T, NZ>, u_i: [T; 2], wdot: [T; 2]) -> [T; 9] {
        let (va, vr, vl) = (z[6], z[7], z[8]);
        let i0 = self.current(u_i, [vr - va, vl - va]);
        let p = &self.sys.params;
        let c = p.L_m * p.k_e * p.n_wm / (p.R_m * p.R_m);
        let i = [i0[0] + c * wdot[0], i0[1] + c * wdot[1]];
        [
            z[0],
            z[1],
            z[2],
            self.ext.tilt_reading(z[3]),
            va,
            z[4] - z[3],
            z[5] - z[3],
            i[0],
            i[1],
        ]
    }
}

/// The longest Runge–Kutta step of the prediction, as a fraction of the sample step. The
/// gear friction `d_c tanh(d_0 w)` has slope `d_c d_0 ≈ 0.26 N m s` at `w = 0`, ten times
/// the back-EMF damping: near a wheel reversal the wheel's relative motion relaxes in
/// `≈ 3 ms`, and one 5 ms step (`λh ≈ 1.7`) misses it by several noise levels where the
/// robot reverses often (measured in docs/diagnose.md); at `h/4` (`λh ≈ 0.4`) the
/// integration error is below a tenth of the noise.
pub const MAX_SUBSTEP: f64 = 0.25;

/// `J_e = (k_e n_wm)² L_m / R_m²`, see [`Wip::quasi_static_inertia`].
pub fn lag_inertia(p: &crate::wip::WipParams) -> f64 {
    (p.k_e * p.n_wm).powi(2) * p.L_m / (p.R_m * p.R_m)
}

/// `τ = m h + f` with `0 ≤ f < h` (on the real part; `f` keeps the derivative).
fn split_delay<T: Real>(tau: T, h: f64) -> (isize, T) {
    let m = (tau.re() / h).floor().max(0.0);
    (m as isize, tau - T::from(m * h))
}

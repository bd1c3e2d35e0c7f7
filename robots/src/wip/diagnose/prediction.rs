//! The prediction model of `wip diagnose`: the WIP with a [`ModelExtension`] (the same
//! `Wip<T>` as everywhere else), the current reduced to its steady state, and the sensors.
//! The accelerations come from the WIP's closed form (`closed_form::shape_acceleration`,
//! checked against `dmech`'s generic equations of motion with every extension), because
//! the fit differentiates them in many dual directions.
//!
//! The electrical time constant `τ_e = L_m/R_m` (0.27 ms) is far below the sample step, so
//! the current is algebraic, `i = (v − k_e n_wm (φ̇ − α̇))/R_m`, with `v` the driver's
//! zero-order-hold output through the first-order electrical lag (exact, since it depends
//! on the commands alone), and the lag behind the back-EMF kept to first order as an
//! inertia `J_e` (`docs/diagnose.md` §2).
//!
//! With the stick-slip effect the friction law is set-valued: a wheel at rest relative to
//! the body stays there while the torque that holds it is below the static limit, and
//! slips with Coulomb (and Stribeck) friction otherwise. The prediction is then hybrid:
//! per wheel a mode (stuck, or slipping in a direction), smooth dynamics within a mode
//! (Runge–Kutta), and the switching times located within a step by interpolation, in the
//! dual scalar, so that they carry their derivatives.

use super::effects::ModelExtension;
use crate::diagnose::FitScalar;
use crate::wip::closed_form::{shape_acceleration, shape_acceleration_with_response};
use crate::wip::Wip;
use dmech::PrincipalKinematicSystem;
use nalgebra::SVector;

/// `z = (x, y, θ, α, φR, φL, v_α, v_φR, v_φL)`.
pub const NZ: usize = 9;

/// A wheel's mode under the stick-slip law.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wheel {
    /// At rest relative to the body.
    Stuck,
    /// Slipping with relative speed of this sign (±1).
    Slipping(i8),
}

/// A row's command as the drivers receive it: the command `u` and the fraction of the
/// step for which the firmware passes it on (1 but where a reversal lockout holds it).
#[derive(Clone, Copy, Debug)]
pub struct Command<T> {
    pub u: [f64; 2],
    pub passed: [T; 2],
}

/// The prediction model: a system with its extension.
pub struct Predictor<T> {
    pub ext: ModelExtension<T>,
    pub sys: Wip<T>,
    /// The system without its friction (the stick-slip law supplies it).
    frictionless: Wip<T>,
    /// `τ_e = L_m / R_m`.
    pub electrical_lag: T,
    /// The floor is level and its slope not free: no floor force (half the trigonometry of
    /// a prediction step otherwise, for a force that is exactly zero).
    level_floor: bool,
}

/// The generalised force of a unit friction torque on wheel `j` (opposing `w_j > 0`):
/// `+1` on `α`, `−1` on `φ_j`.
fn friction_direction<T: FitScalar>(j: usize) -> [T; 3] {
    let (z, o) = (T::zero(), T::one());
    if j == 0 {
        [o, -o, z]
    } else {
        [o, z, -o]
    }
}

impl<T: FitScalar> Predictor<T> {
    pub fn new(ext: ModelExtension<T>) -> Self {
        let mut sys = ext.system();
        let p = &ext.params;
        sys.quasi_static_inertia = (p.k_e * p.n_wm).powi(2) * p.L_m / (p.R_m * p.R_m);
        let mut frictionless = sys;
        frictionless.params.d_v = T::zero();
        frictionless.params.d_c = T::zero();
        Predictor {
            electrical_lag: p.L_m / p.R_m,
            level_floor: ext.slope.iter().all(|s| s.vanishes()),
            sys,
            frictionless,
            ext,
        }
    }

    /// The floor slope's generalised force (exactly zero on a level floor whose slope is
    /// not free, so not computed there).
    fn floor_force(&self, s: &SVector<T, 5>, theta: T) -> SVector<T, 5> {
        if self.level_floor {
            SVector::zeros()
        } else {
            self.ext.floor_force(&self.sys, s, theta)
        }
    }

    /// The steady-state currents for applied voltages `u` at wheel rates relative to the
    /// body `w = φ̇ − α̇`.
    pub fn current(&self, u: [T; 2], w: [T; 2]) -> [T; 2] {
        let p = &self.sys.params;
        [p.steady_current(u[0], w[0]), p.steady_current(u[1], w[1])]
    }

    /// Pose rates from the shape velocities.
    fn pose_rates(&self, z: &SVector<T, NZ>, s: &SVector<T, 5>, v: &SVector<T, 5>) -> [T; 3] {
        let xi = -(self.sys.connection(s) * v);
        let (st, ct) = z[2].sin_cos();
        [xi[0] * ct - xi[1] * st, xi[0] * st + xi[1] * ct, xi[2]]
    }

    fn shape_of(z: &SVector<T, NZ>) -> SVector<T, 5> {
        SVector::<T, 5>::new(z[3], z[4], z[5], T::zero(), T::zero())
    }

    /// `ż` for applied voltages `u` (after the driver), with the model's friction law.
    pub fn rate(&self, z: &SVector<T, NZ>, u: [T; 2]) -> Option<SVector<T, NZ>> {
        let (va, vr, vl) = (z[6], z[7], z[8]);
        let i = self.current(u, [vr - va, vl - va]);
        let s = Self::shape_of(z);
        let v = SVector::<T, 5>::new(va, vr, vl, i[0], i[1]);
        let f_ext = self.floor_force(&s, z[2]);
        let a = shape_acceleration(
            &self.sys,
            z[3],
            [va, vr, vl],
            i,
            [f_ext[0], f_ext[1], f_ext[2]],
        )?;
        let pose = self.pose_rates(z, &s, &v);
        Some(SVector::<T, NZ>::from_column_slice(&[
            pose[0], pose[1], pose[2], va, vr, vl, a[0], a[1], a[2],
        ]))
    }

    /// `ż` under the stick-slip law with the wheels in `modes`, and the torque holding each
    /// stuck wheel (zero for a slipping one).
    pub fn rate_hybrid(
        &self,
        z: &SVector<T, NZ>,
        u: [T; 2],
        modes: [Wheel; 2],
    ) -> Option<(SVector<T, NZ>, [T; 2])> {
        let (va, vr, vl) = (z[6], z[7], z[8]);
        let w = [vr - va, vl - va];
        let i = self.current(u, w);
        let s = Self::shape_of(z);
        let v = SVector::<T, 5>::new(va, vr, vl, i[0], i[1]);
        let mut f = self.floor_force(&s, z[2]);
        for j in 0..2 {
            if let Wheel::Slipping(sign) = modes[j] {
                let fr = self.ext.slip_friction(w[j], sign as f64);
                let d = friction_direction::<T>(j);
                for q in 0..3 {
                    f[q] += d[q] * fr;
                }
            }
        }
        let (a0, g) = shape_acceleration_with_response(
            &self.frictionless,
            z[3],
            [va, vr, vl],
            i,
            [f[0], f[1], f[2]],
            [friction_direction(0), friction_direction(1)],
        )?;
        // Relative accelerations ẇ_j = φ̈_j − α̈; a stuck wheel's holding torques make them
        // zero: Σ_k (g_k[1+j] − g_k[0]) F_k = −(a0[1+j] − a0[0]) over the stuck wheels.
        let wdot0 = [a0[1] - a0[0], a0[2] - a0[0]];
        let c = |j: usize, k: usize| g[k][1 + j] - g[k][0];
        let stuck = [modes[0] == Wheel::Stuck, modes[1] == Wheel::Stuck];
        let hold = match stuck {
            [true, true] => {
                let det = c(0, 0) * c(1, 1) - c(0, 1) * c(1, 0);
                if det.re() == 0.0 {
                    return None;
                }
                [
                    (-wdot0[0] * c(1, 1) + wdot0[1] * c(0, 1)) / det,
                    (-wdot0[1] * c(0, 0) + wdot0[0] * c(1, 0)) / det,
                ]
            }
            [true, false] => [-wdot0[0] / c(0, 0), T::zero()],
            [false, true] => [T::zero(), -wdot0[1] / c(1, 1)],
            [false, false] => [T::zero(); 2],
        };
        let mut a = a0;
        for k in 0..2 {
            for q in 0..3 {
                a[q] += g[k][q] * hold[k];
            }
        }
        let pose = self.pose_rates(z, &s, &v);
        Some((
            SVector::<T, NZ>::from_column_slice(&[
                pose[0], pose[1], pose[2], va, vr, vl, a[0], a[1], a[2],
            ]),
            hold,
        ))
    }

    /// One classical Runge–Kutta step of length `dt` with the applied voltage `u` held;
    /// also the relative wheel accelerations `ẇ` of the last stage (at the step's end,
    /// to `O(dt³)`), which the current reading needs.
    pub fn step(&self, z: &SVector<T, NZ>, u: [T; 2], dt: T) -> Option<(SVector<T, NZ>, [T; 2])> {
        self.rk4(z, dt, &|y, _| self.rate(y, u))
    }

    /// A Runge–Kutta step where the rate depends on the stage's time offset `s` in the step
    /// (the lagging voltage).
    #[allow(clippy::type_complexity)]
    fn rk4(
        &self,
        z: &SVector<T, NZ>,
        dt: T,
        f: &dyn Fn(&SVector<T, NZ>, T) -> Option<SVector<T, NZ>>,
    ) -> Option<(SVector<T, NZ>, [T; 2])> {
        let half = dt * 0.5;
        let k1 = f(z, T::zero())?;
        let k2 = f(&(z + k1 * half), half)?;
        let k3 = f(&(z + k2 * half), half)?;
        let k4 = f(&(z + k3 * dt), dt)?;
        let out = z + (k1 + k2 * T::from(2.0) + k3 * T::from(2.0) + k4) * (dt / 6.0);
        let wdot = [k4[7] - k4[6], k4[8] - k4[6]];
        out.iter()
            .all(|x| x.re().is_finite())
            .then_some((out, wdot))
    }

    /// Advance from `t_k` to `t_{k+1}`. The drivers apply the command `delay` late
    /// (zero-order hold): with `delay = m h + f`, the command `κ·dz(u_{k−m−1})` from
    /// `t_k − h + f` and `κ·dz(u_{k−m})` from `t_k + f`. The motor's voltage across its
    /// resistance follows the driver with the electrical lag `τ_e = L_m/R_m`, exactly
    /// (a first-order response to a step: `v(t) = a + (v₀ − a) e^{−t/τ_e}`); what the lag
    /// behind the back-EMF does is the inertia `J_e` (docs/diagnose.md §2). The step is
    /// split at the switch (the voltage has a kink there) and each piece integrated in steps
    /// of at most `MAX_SUBSTEP · h`; `f` carries the derivative with respect to the delay.
    /// `modes` is the wheels' stick-slip state, carried from step to step.
    pub fn advance(
        &self,
        z: &SVector<T, NZ>,
        cmd: &dyn Fn(usize) -> Command<T>,
        k: usize,
        h: f64,
        modes: &mut [Wheel; 2],
    ) -> Option<(SVector<T, NZ>, [T; 2])> {
        let pieces = self.pieces(cmd, k, h);
        let mut state = (*z, [T::zero(); 2]);
        for lag in pieces {
            if lag.len.re() <= 1e-12 * h {
                // A piece of no real length (the delay a whole number of samples, or 0)
                // still moves with the delay: its length's derivative is the switch's, and
                // the state's derivative gains the rate there times it. One Runge–Kutta
                // step of the derivative part alone carries that and leaves the values as
                // they are; in `f64` (no derivative) the piece is skipped.
                let d = lag.len - T::from(lag.len.re());
                if !d.vanishes() {
                    let m = *modes;
                    state = if self.ext.sticks() {
                        self.rk4(&state.0, d, &|y, s| {
                            self.rate_hybrid(y, lag.at(s), m).map(|r| r.0)
                        })?
                    } else {
                        self.rk4(&state.0, d, &|y, s| self.rate(y, lag.at(s)))?
                    };
                }
                continue;
            }
            let n = (lag.len.re() / (MAX_SUBSTEP * h)).ceil().max(1.0) as usize;
            let dt = lag.len / n as f64;
            for i in 0..n {
                let s0 = dt * i as f64;
                state = if self.ext.sticks() {
                    self.hybrid_step(&state.0, &lag, s0, dt, modes)?
                } else {
                    self.rk4(&state.0, dt, &|y, s| self.rate(y, lag.at(s0 + s)))?
                };
            }
        }
        Some(state)
    }

    /// One step of length `dt` (from offset `s0` in the voltage piece `lag`) under the
    /// stick-slip law: a Runge–Kutta step in the current modes; if a slipping wheel's
    /// relative speed changes sign, or a stuck wheel's holding torque passes the static
    /// limit, the step is cut at the switching time, the wheel's mode changes there (a
    /// wheel reaching rest sticks if the torque that would hold it is within the limit,
    /// else reverses), and the rest of the step follows.
    fn hybrid_step(
        &self,
        z: &SVector<T, NZ>,
        lag: &Lagged<T>,
        s0: T,
        dt: T,
        modes: &mut [Wheel; 2],
    ) -> Option<(SVector<T, NZ>, [T; 2])> {
        let limit = self.ext.static_limit();
        let rel = |y: &SVector<T, NZ>| [y[7] - y[6], y[8] - y[6]];
        let mut z = *z;
        let mut done = T::zero();
        let mut wdot = [T::zero(); 2];
        for _ in 0..MAX_SWITCHES {
            let m = *modes;
            let remaining = dt - done;
            let at = s0 + done;
            let rate =
                |y: &SVector<T, NZ>, s: T| self.rate_hybrid(y, lag.at(at + s), m).map(|r| r.0);
            let hold_at =
                |y: &SVector<T, NZ>, s: T| self.rate_hybrid(y, lag.at(at + s), m).map(|r| r.1);
            let hold0 = hold_at(&z, T::zero())?;
            let (z1, wd) = self.rk4(&z, remaining, &rate)?;
            let hold1 = hold_at(&z1, remaining)?;
            let (w0, w1) = (rel(&z), rel(&z1));
            // The earliest switch in this step, as a fraction of it (interpolated).
            let mut first: Option<(T, usize)> = None;
            for j in 0..2 {
                let frac = match m[j] {
                    Wheel::Slipping(s) => {
                        let s = s as f64;
                        (w1[j].re() * s < 0.0).then(|| w0[j] / (w0[j] - w1[j]))
                    }
                    Wheel::Stuck => (hold1[j].re().abs() > limit.re()).then(|| {
                        let (a, b) = (hold0[j].abs(), hold1[j].abs());
                        (limit - a) / (b - a)
                    }),
                };
                if let Some(fr) = frac {
                    let fr = if fr.re().is_finite() { fr } else { T::zero() };
                    let fr = clamp01(fr);
                    if first.as_ref().is_none_or(|(g, _)| fr.re() < g.re()) {
                        first = Some((fr, j));
                    }
                }
            }
            let Some((fr, j)) = first else {
                return Some((z1, wd));
            };
            // The switching function of wheel j, positive before the switch.
            let event = |y: &SVector<T, NZ>, s: T| -> Option<T> {
                Some(match m[j] {
                    Wheel::Slipping(sg) => rel(y)[j] * sg as f64,
                    Wheel::Stuck => limit - hold_at(y, s)?[j].abs(),
                })
            };
            let g = (event(&z, T::zero())?, event(&z1, remaining)?);
            let fr =
                self.refine_switch(&z, remaining, fr, g, &event, &|y, t| self.rk4(y, t, &rate))?;
            let piece = remaining * fr;
            if piece.re() > 0.0 {
                let (zp, wdp) = self.rk4(&z, piece, &rate)?;
                z = zp;
                wdot = wdp;
            }
            done += piece;
            let u_now = lag.at(s0 + done);
            match m[j] {
                Wheel::Slipping(s) => {
                    // At rest: stick if the holding torque is within the limit.
                    let mut trial = m;
                    trial[j] = Wheel::Stuck;
                    z[7 + j] = z[6];
                    let (_, hold) = self.rate_hybrid(&z, u_now, trial)?;
                    modes[j] = if hold[j].re().abs() <= limit.re() {
                        Wheel::Stuck
                    } else {
                        Wheel::Slipping(-s)
                    };
                }
                Wheel::Stuck => {
                    modes[j] = Wheel::Slipping(if hold1[j].re() > 0.0 { 1 } else { -1 });
                }
            }
            if (dt - done).re() <= 1e-12 * dt.re() {
                return Some((z, wdot));
            }
        }
        // More switches than a step can resolve (chatter): finish the step in the last
        // modes.
        let m = *modes;
        let at = s0 + done;
        self.rk4(&z, dt - done, &|y, s| {
            self.rate_hybrid(y, lag.at(at + s), m).map(|r| r.0)
        })
    }

    /// The fraction of a step of length `dt` from `z` at which the switching function `g`
    /// (positive before the switch, `g = (g(0), g(1))` at the step's ends) crosses zero:
    /// from the linear interpolation `fr`, a few Illinois (regula falsi) steps, each a
    /// Runge–Kutta step to the trial time. Near a wheel's stop the Stribeck friction bends
    /// its speed, and the interpolation alone misplaces the stop by a good part of the step
    /// (the wheel then sticks with a wrong angle); the last secant's slope carries the
    /// derivative of the switching time (`−∂g/∂p / ġ`) into the dual scalar.
    #[allow(clippy::type_complexity)]
    fn refine_switch(
        &self,
        z: &SVector<T, NZ>,
        dt: T,
        fr: T,
        g: (T, T),
        event: &dyn Fn(&SVector<T, NZ>, T) -> Option<T>,
        advance: &dyn Fn(&SVector<T, NZ>, T) -> Option<(SVector<T, NZ>, [T; 2])>,
    ) -> Option<T> {
        let (mut a, mut ga, mut b, mut gb) = (T::zero(), g.0, T::one(), g.1);
        if ga.re() <= 0.0 {
            return Some(T::zero());
        }
        let mut fr = fr;
        for _ in 0..SWITCH_ITERATIONS {
            let gf = event(&advance(z, dt * fr)?.0, dt * fr)?;
            if gf.re().abs() <= 1e-12 * (ga.re().abs() + gb.re().abs()) {
                return Some(fr);
            }
            if gf.re() > 0.0 {
                a = fr;
                ga = gf;
                gb *= T::from(0.5);
            } else {
                b = fr;
                gb = gf;
                ga *= T::from(0.5);
            }
            let next = a - ga * (b - a) / (gb - ga);
            fr = if next.re().is_finite() && next.re() > a.re() && next.re() < b.re() {
                next
            } else {
                (a + b) * 0.5
            };
        }
        Some(fr)
    }

    /// `ẇ` at a state for applied voltages `u` (for the first reading of a window).
    pub fn wheel_acceleration(
        &self,
        z: &SVector<T, NZ>,
        u: [T; 2],
        modes: [Wheel; 2],
    ) -> Option<[T; 2]> {
        let r = if self.ext.sticks() {
            self.rate_hybrid(z, u, modes)?.0
        } else {
            self.rate(z, u)?
        };
        Some([r[7] - r[6], r[8] - r[6]])
    }

    /// The driver's outputs around `t_k` when the commands `cmd` (zero-order hold, `cmd(j)`
    /// from `t_j`; before the log the first command) arrive `delay` late: with
    /// `delay = m h + f`, `(f, [κ·dz(u_{k−m−2}), κ·dz(u_{k−m−1}), κ·dz(u_{k−m})])`, the
    /// second switched on at `t_k − h + f`, the third at `t_k + f`. `f` carries the
    /// derivative with respect to the delay.
    fn delayed(&self, cmd: &dyn Fn(usize) -> Command<T>, k: isize, h: f64) -> (T, [[T; 2]; 3]) {
        let (m, f) = split_delay(self.ext.delay, h);
        let at = |j: isize| {
            let c = cmd(j.max(0) as usize);
            [
                self.ext.driver(T::from(c.u[0])) * c.passed[0],
                self.ext.driver(T::from(c.u[1])) * c.passed[1],
            ]
        };
        (f, [at(k - m - 2), at(k - m - 1), at(k - m)])
    }

    /// The voltage behind the current (the driver's output through the electrical lag) on
    /// `[t_k, t_{k+1})`, as two pieces split at the driver's switch `t_k + f`.
    fn pieces(&self, cmd: &dyn Fn(usize) -> Command<T>, k: usize, h: f64) -> [Lagged<T>; 2] {
        let (f, [a2, a1, a0]) = self.delayed(cmd, k as isize, h);
        let tau = self.electrical_lag;
        let relax = |from: [T; 2], to: [T; 2], t: T| {
            let e = (-t / tau).exp();
            [0, 1].map(|c| to[c] + (from[c] - to[c]) * e)
        };
        // At t_k the output has relaxed from a2 towards a1 for h − f.
        let v_k = relax(a2, a1, T::from(h) - f);
        let v_f = relax(v_k, a1, f);
        [
            Lagged {
                len: f,
                start: v_k,
                target: a1,
                tau,
            },
            Lagged {
                len: T::from(h) - f,
                start: v_f,
                target: a0,
                tau,
            },
        ]
    }

    /// The mean of the voltage behind the current over `[t_k, t_{k+1})` (approximate: the
    /// pieces' targets weighted by their lengths).
    pub fn mean_applied(&self, cmd: &dyn Fn(usize) -> Command<T>, k: usize, h: f64) -> [T; 2] {
        let [p1, p2] = self.pieces(cmd, k, h);
        let w = p1.len / h;
        [0, 1].map(|c| p1.target[c] * w + p2.target[c] * (T::one() - w))
    }

    /// The voltage behind the current read at `t_k`.
    pub fn current_voltage(&self, cmd: &dyn Fn(usize) -> Command<T>, k: usize, h: f64) -> [T; 2] {
        self.pieces(cmd, k, h)[0].start
    }

    /// The sensor readings at state `z` with `u_i` the voltage behind the current and
    /// `ẇ` the relative wheel accelerations:
    /// `[x, y, θ, alpha, v_alpha, phiR_rel, phiL_rel, iR, iL]`. The current is the steady
    /// state plus its first-order lag correction `(L_m k_e n_wm / R_m²) ẇ`; the encoders
    /// read the motors, which lead the wheels through the gear's lost motion.
    pub fn readings(&self, z: &SVector<T, NZ>, u_i: [T; 2], wdot: [T; 2]) -> [T; 9] {
        let (va, vr, vl) = (z[6], z[7], z[8]);
        let i0 = self.current(u_i, [vr - va, vl - va]);
        let p = &self.sys.params;
        let c = p.L_m * p.k_e * p.n_wm / (p.R_m * p.R_m);
        let i = [i0[0] + c * wdot[0], i0[1] + c * wdot[1]];
        let lost = if self.ext.backlash.vanishes() {
            [T::zero(); 2]
        } else {
            [
                self.ext.backlash_offset(i[0]),
                self.ext.backlash_offset(i[1]),
            ]
        };
        [
            z[0],
            z[1],
            z[2],
            self.ext.tilt_reading(z[3]),
            va,
            z[4] - z[3] + lost[0],
            z[5] - z[3] + lost[1],
            i[0],
            i[1],
        ]
    }
}

/// The voltage behind the current over a piece of a step: from `start` towards the
/// driver's output `target` with the electrical lag `tau`.
pub struct Lagged<T> {
    pub len: T,
    pub start: [T; 2],
    pub target: [T; 2],
    pub tau: T,
}

impl<T: FitScalar> Lagged<T> {
    /// The voltage at offset `s` into the piece.
    pub fn at(&self, s: T) -> [T; 2] {
        let e = (-s / self.tau).exp();
        [0, 1].map(|c| self.target[c] + (self.start[c] - self.target[c]) * e)
    }
}

/// `x` clamped to `[0, 1]` on its real part (keeping its derivative inside).
fn clamp01<T: FitScalar>(x: T) -> T {
    if x.re() < 0.0 {
        T::zero()
    } else if x.re() > 1.0 {
        T::one()
    } else {
        x
    }
}

/// Illinois steps locating a mode switch within a step (each one Runge–Kutta step; four
/// bring the switch within `~10⁻⁴` of the step, measured against the truth's fine steps in
/// `tests/diagnose/prediction.rs`).
const SWITCH_ITERATIONS: usize = 4;

/// The most mode switches resolved within one step; beyond, the step finishes in the last
/// modes (a wheel chattering at rest).
const MAX_SWITCHES: usize = 6;

/// The longest Runge–Kutta step of the prediction, as a fraction of the sample step. The
/// gear friction `d_c tanh(d_0 w)` has slope `d_c d_0 ≈ 0.26 N m s` at `w = 0`, ten times
/// the back-EMF damping: near a wheel reversal the wheel's relative motion relaxes in
/// `≈ 3 ms`, and one 5 ms step (`λh ≈ 1.7`) misses it by several noise levels where the
/// robot reverses often. At `h/4` (`λh ≈ 0.4`) the prediction from the true states of a
/// closed-loop run with a 20–30 % payload still misses the encoders by 1.4 noise levels
/// (and a run without effect by 0.16); at `h/8` by 0.16 and 0.012
/// (`tests/diagnose/prediction.rs`, which requires below 0.5).
pub const MAX_SUBSTEP: f64 = 0.125;

/// `τ = m h + f` with `0 ≤ f < h` (on the real part; `f` keeps the derivative). A delay
/// within rounding (`10⁻⁹` of a sample) of a whole number of samples is that number, with
/// `f = 0` in value: `3 × 0.005` is `2.9999999999999996` samples in `f64`, and the step
/// would otherwise be split as `2 h + (h − 10⁻¹⁸)`, the side of the switch below it.
fn split_delay<T: FitScalar>(tau: T, h: f64) -> (isize, T) {
    let m = (tau.re() / h + 1e-9).floor().max(0.0);
    let f = tau - T::from(m * h);
    let f = if f.re() < 0.0 { f - T::from(f.re()) } else { f };
    (m as isize, f)
}

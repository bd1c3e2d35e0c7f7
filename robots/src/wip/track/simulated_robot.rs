//! The simulated robot of the closed loop: the full nonlinear model (tanh friction, current
//! dynamics) in the reduced state `X` plus the two wheel angles the encoders read,
//! integrated by RK4 with [`SUBSTEPS`] substeps per 5-ms sample (more where the plant's
//! parameters need them: [`substeps`]), the voltages held.
//!
//! The rates are the WIP's closed form ([`closed_form::state_derivative`]), not the generic
//! path of `dmech::continuous`: the two are the same equations (tests
//! `generic_equals_closed_form_at_random_states` and `reference_vectors`: 1e-10 relative at
//! 1,000 random states), and the closed form costs a few hundred flops where the generic
//! acceleration differentiates `ℓ` twice by nested duals. The loop evaluates the rates 40
//! times per sample, so this is what sets its speed (docs/tracking.md, "Speed").

use crate::check::{stable_substeps, CheckError, Scheme};
use crate::wip::closed_form;
use crate::wip::simulate::modes_at;
use crate::wip::state::wheel_rates;
use crate::wip::{ReducedState, Wip, WipParams};
use nalgebra::SVector;

/// RK4 substeps per sample: 0.5 ms, within RK4's stability bound for the motor circuit's
/// electrical mode (time constant `L_m/R_m` ≈ 0.27 ms, `|hλ|` ≈ 1.9 < 2.78). A plant whose
/// modes need shorter steps gets more ([`substeps`]).
pub const SUBSTEPS: usize = 10;

/// The most RK4 substeps per sample a plant may need (5 µs steps).
pub const MAX_SUBSTEPS: usize = 1000;

/// The RK4 substeps per sample of length `sample` that keep the plant with `params` within
/// RK4's stability bound ([`crate::check::stable_substeps`] on its modes at `x0`):
/// [`SUBSTEPS`] for the paper's robot and any plant that it suffices for, more for a
/// faster motor circuit (a smaller `L_m` or a larger `R_m`, as a Monte Carlo draw may
/// give), an error beyond [`MAX_SUBSTEPS`] or where the model's rates are not finite.
pub fn substeps(params: &WipParams, x0: &ReducedState, sample: f64) -> Result<usize, CheckError> {
    let what = "track: the plant";
    let modes = modes_at(&Wip::new(*params), x0, [0.0; 2], what)?;
    stable_substeps(
        what,
        &modes,
        Scheme::from(dmech::Integrator::Rk4),
        sample,
        SUBSTEPS,
        MAX_SUBSTEPS,
    )
}

/// `(X, φR, φL)`: the reduced state and the absolute wheel angles.
type PlantVector = SVector<f64, 11>;

/// Why the simulated plant cannot go on: a numerical failure, never a fall.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Divergence {
    /// The state stopped being finite.
    #[error("the plant's state is no longer finite")]
    NotFinite,
    /// The rates could not be evaluated (the projected mass matrix is not invertible).
    #[error("the plant's rates cannot be evaluated")]
    Singular,
    /// A rate or current no motion of the robot reaches ([`PHYSICAL_BOUNDS`]).
    #[error("the plant's {quantity} reached {value:.3e} {unit}, beyond any motion of the robot")]
    Unphysical {
        quantity: &'static str,
        value: f64,
        unit: &'static str,
    },
}

/// Bounds no motion of the robot reaches (index in the reduced state, name, unit, bound):
/// a state beyond one is a numerical blow-up, not a fall (the drivers saturate at ±5 V).
pub const PHYSICAL_BOUNDS: [(usize, &str, &str, f64); 5] = [
    (4, "tilt rate v_alpha", "rad/s", 1e3),
    (5, "speed v_d", "m/s", 1e2),
    (6, "heading rate v_theta", "rad/s", 1e3),
    (7, "current iR", "A", 1e3),
    (8, "current iL", "A", 1e3),
];

/// Whether `x` is a state the robot can be in: finite and within [`PHYSICAL_BOUNDS`].
pub fn check_physical(x: &ReducedState) -> Result<(), Divergence> {
    if !x.iter().all(|v| v.is_finite()) {
        return Err(Divergence::NotFinite);
    }
    for (i, quantity, unit, bound) in PHYSICAL_BOUNDS {
        if x[i].abs() > bound {
            return Err(Divergence::Unphysical {
                quantity,
                value: x[i],
                unit,
            });
        }
    }
    Ok(())
}

/// The plant's state and parameters.
#[derive(Clone, Debug)]
pub struct Plant {
    params: WipParams,
    z: PlantVector,
    substeps: usize,
}

impl Plant {
    /// The plant at reduced state `x`, wheel angles zero, [`SUBSTEPS`] per sample.
    pub fn new(params: WipParams, x: &ReducedState) -> Self {
        Self::with_substeps(params, x, SUBSTEPS)
    }

    /// The plant with `substeps` RK4 substeps per sample (from [`substeps`]).
    pub fn with_substeps(params: WipParams, x: &ReducedState, substeps: usize) -> Self {
        let mut z = PlantVector::zeros();
        z.fixed_rows_mut::<9>(0).copy_from(x);
        Plant {
            params,
            z,
            substeps: substeps.max(1),
        }
    }

    /// RK4 substeps per sample.
    pub fn substeps(&self) -> usize {
        self.substeps
    }

    /// The reduced state `X = (x, y, θ, α, v_α, v_d, v_θ, iR, iL)`.
    pub fn reduced(&self) -> ReducedState {
        self.z.fixed_rows::<9>(0).into_owned()
    }

    /// The wheel angles relative to the body, `(φR − α, φL − α)`: what the encoders count.
    pub fn wheels_relative_to_body(&self) -> [f64; 2] {
        [self.z[9] - self.z[3], self.z[10] - self.z[3]]
    }

    /// A push: the tilt rate `v_α` changed at once by `dv` (rad/s), every other state
    /// (the wheels' rates, the currents) as it was.
    pub fn push_tilt_rate(&mut self, dv: f64) {
        self.z[4] += dv;
    }

    fn rate(&self, z: &PlantVector, u: &SVector<f64, 2>) -> Result<PlantVector, Divergence> {
        let x = z.fixed_rows::<9>(0).into_owned();
        let xd = closed_form::state_derivative(&self.params, &x, u).ok_or(Divergence::Singular)?;
        let (phr, phl) = wheel_rates(&self.params, x[5], x[6]);
        let mut zd = PlantVector::zeros();
        zd.fixed_rows_mut::<9>(0).copy_from(&xd);
        zd[9] = phr;
        zd[10] = phl;
        Ok(zd)
    }

    /// Advances one sample of length `sample` with the voltages `u` held; `Err` if the state
    /// stops being finite or the rates cannot be evaluated.
    pub fn advance(&mut self, sample: f64, u: [f64; 2]) -> Result<(), Divergence> {
        let u = SVector::<f64, 2>::new(u[0], u[1]);
        let h = sample / self.substeps as f64;
        for _ in 0..self.substeps {
            let z = &self.z;
            let k1 = self.rate(z, &u)?;
            let k2 = self.rate(&(z + k1 * (0.5 * h)), &u)?;
            let k3 = self.rate(&(z + k2 * (0.5 * h)), &u)?;
            let k4 = self.rate(&(z + k3 * h), &u)?;
            self.z += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
        }
        if self.z.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(Divergence::NotFinite)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wip::simulate::{simulate, InputSchedule};

    /// Over 0.5 s of varying voltages from a tilted start, the plant equals `wip simulate`'s
    /// generic RK4 (the continuous model of `dmech`) at the same 0.5-ms step. Both are the
    /// same method on the same equations, so they differ only by the rates' rounding
    /// (1e-10 relative at worst, amplified by 100 samples of a stable closed-form flow):
    /// a bound of 1e-8 on every state entry leaves two orders of margin above that and is
    /// far below any method error (RK4 at 0.5 ms against 0.25 ms: ~1e-6 here).
    #[test]
    fn equals_the_generic_continuous_model() {
        let p = WipParams::default();
        let n = 100;
        let sample = 0.005;
        let mut sched = InputSchedule {
            t: vec![],
            u: vec![],
        };
        for k in 0..=n {
            let t = k as f64 * sample;
            sched.t.push(t);
            sched.u.push([1.5 * (9.0 * t).sin(), -(6.0 * t).cos()]);
        }
        let mut x0 = ReducedState::zeros();
        x0[2] = 0.3;
        x0[3] = 0.05;
        let generic = simulate(
            &Wip::new(p),
            dmech::Integrator::Rk4,
            sample / SUBSTEPS as f64,
            &x0,
            &sched,
            n * SUBSTEPS,
        )
        .unwrap();
        let mut plant = Plant::new(p, &x0);
        let mut worst: f64 = 0.0;
        for k in 0..n {
            plant.advance(sample, sched.u[k]).unwrap();
            let g = generic.x[(k + 1) * SUBSTEPS];
            worst = worst.max((plant.reduced() - g).amax());
        }
        println!("largest difference from the generic path: {worst:.3e}");
        assert!(worst < 1e-8, "largest difference {worst:e}");
    }
}

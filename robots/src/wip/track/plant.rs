//! The simulated robot of the closed loop: the full nonlinear model (tanh friction, current
//! dynamics) in the reduced state `X` plus the two wheel angles the encoders read,
//! integrated by RK4 with [`SUBSTEPS`] substeps per 5-ms sample, the voltages held.
//!
//! The rates are the WIP's closed form ([`closed_form::state_derivative`]), not the generic
//! path of `dmech::continuous`: the two are the same equations (tests
//! `generic_equals_closed_form_at_random_states` and `reference_vectors`: 1e-10 relative at
//! 1,000 random states), and the closed form costs a few hundred flops where the generic
//! acceleration differentiates `ℓ` twice by nested duals. The loop evaluates the rates 40
//! times per sample, so this is what sets its speed (docs/tracking.md, "Speed").

use crate::wip::closed_form;
use crate::wip::state::wheel_rates;
use crate::wip::{ReducedState, WipParams};
use nalgebra::SVector;

/// RK4 substeps per sample: 0.5 ms, within RK4's stability bound for the motor circuit's
/// electrical mode (time constant `L_m/R_m` ≈ 0.27 ms, `|hλ|` ≈ 1.9 < 2.78).
pub const SUBSTEPS: usize = 10;

/// `(X, φR, φL)`: the reduced state and the absolute wheel angles.
type PlantVector = SVector<f64, 11>;

/// The plant's state and parameters.
#[derive(Clone, Debug)]
pub struct Plant {
    params: WipParams,
    z: PlantVector,
}

impl Plant {
    /// The plant at reduced state `x`, wheel angles zero.
    pub fn new(params: WipParams, x: &ReducedState) -> Self {
        let mut z = PlantVector::zeros();
        z.fixed_rows_mut::<9>(0).copy_from(x);
        Plant { params, z }
    }

    /// The reduced state `X = (x, y, θ, α, v_α, v_d, v_θ, iR, iL)`.
    pub fn reduced(&self) -> ReducedState {
        self.z.fixed_rows::<9>(0).into_owned()
    }

    /// The wheel angles relative to the body, `(φR − α, φL − α)`: what the encoders count.
    pub fn wheels_relative_to_body(&self) -> [f64; 2] {
        [self.z[9] - self.z[3], self.z[10] - self.z[3]]
    }

    fn rate(&self, z: &PlantVector, u: &SVector<f64, 2>) -> PlantVector {
        let x = z.fixed_rows::<9>(0).into_owned();
        let xd = closed_form::state_derivative(&self.params, &x, u);
        let (phr, phl) = wheel_rates(&self.params, x[5], x[6]);
        let mut zd = PlantVector::zeros();
        zd.fixed_rows_mut::<9>(0).copy_from(&xd);
        zd[9] = phr;
        zd[10] = phl;
        zd
    }

    /// Advances one sample of length `sample` with the voltages `u` held; `Err` if the state
    /// stops being finite.
    pub fn advance(&mut self, sample: f64, u: [f64; 2]) -> Result<(), String> {
        let u = SVector::<f64, 2>::new(u[0], u[1]);
        let h = sample / SUBSTEPS as f64;
        for _ in 0..SUBSTEPS {
            let z = &self.z;
            let k1 = self.rate(z, &u);
            let k2 = self.rate(&(z + k1 * (0.5 * h)), &u);
            let k3 = self.rate(&(z + k2 * (0.5 * h)), &u);
            let k4 = self.rate(&(z + k3 * h), &u);
            self.z += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
        }
        if self.z.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err("the plant's state is no longer finite".to_string())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wip::simulate::{simulate, InputSchedule};
    use crate::wip::Wip;

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
            "rk4".parse().unwrap(),
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

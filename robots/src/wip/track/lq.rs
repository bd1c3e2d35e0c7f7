//! The paper's LQ tracking controller for the WIP: `Q_Y`, `R = I` on the ZOH model at
//! 5 ms; the gain acts on the error state `z − z_ref` whose pose part comes from the
//! guidance (docs/tracking.md, including why `Q_Y` is read in this state order).

use super::dare::{solve_dare, DareError, LqDesign};
use super::linear::{linear_model_params, linearise, zoh, NIN, NZ};
use crate::wip::{Wip, WipParams};
use nalgebra::{SMatrix, SVector};

/// The controller's sample time (s).
pub const SAMPLE: f64 = 0.005;

/// The paper's `Q_Y = diag(1500, 350, 0.1, 0, 0, 1, 0, 0)`, read in the order of the
/// linear state `z = (d, θ, α, v_α, v_d, v_θ, iR, iL)`: the paper's `X` without `y`, with
/// `x` replaced by `d`.
pub const Q_Y: [f64; NZ] = [1500.0, 350.0, 0.1, 0.0, 0.0, 1.0, 0.0, 0.0];

/// The discrete linear model and the LQ design on it.
#[derive(Debug, Clone)]
pub struct LqController {
    pub phi: SMatrix<f64, NZ, NZ>,
    pub gamma: SMatrix<f64, NZ, NIN>,
    pub design: LqDesign<NZ, NIN>,
}

impl LqController {
    /// Linearise the model with parameters `p` (friction replaced by the linear model's),
    /// discretise at [`SAMPLE`], solve the DARE.
    pub fn design(p: &WipParams) -> Result<Self, DareError> {
        let wip = Wip::new(linear_model_params(p));
        let (a, b) = linearise(&wip);
        let (phi, gamma) = zoh(&a, &b, SAMPLE);
        let q = SMatrix::<f64, NZ, NZ>::from_diagonal(&SVector::from_column_slice(&Q_Y));
        let design = solve_dare(&phi, &gamma, &q, &SMatrix::<f64, NIN, NIN>::identity())?;
        Ok(LqController { phi, gamma, design })
    }

    /// The feedback voltages `−K e` for an error state `e`.
    pub fn feedback(&self, e: &SVector<f64, NZ>) -> [f64; 2] {
        let u = -(self.design.k * e);
        [u[0], u[1]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The DARE's residual is at rounding level and the closed loop `Φ − ΓK` is stable,
    /// while the open loop `Φ` is not (one eigenvalue outside the unit circle).
    #[test]
    fn lq_design_stabilises_the_linear_wip() {
        let c = LqController::design(&WipParams::default()).unwrap();
        assert!(c.design.residual < 1e-9, "{}", c.design.residual);
        let open = c.phi.complex_eigenvalues();
        assert!(open.iter().any(|l| l.norm() > 1.0 + 1e-6), "{open}");
        let closed = (c.phi - c.gamma * c.design.k).complex_eigenvalues();
        let rho = closed.iter().map(|l| l.norm()).fold(0.0, f64::max);
        assert!(rho < 1.0, "spectral radius {rho}");
    }
}

//! Hypotheses on the inputs, for any system of the traits (docs/diagnose.md §2b): for each
//! input `j` the system declares, two small families of what goes wrong between a command
//! and the actuator it drives, an **offset** (`u_j = û_j + b`, null `b = 0`: a driver's
//! zero point, a bias in the PWM) and a **gain** (`u_j = k û_j`, null `k = 1`: a supply
//! voltage other than the nominal one, a motor constant off), where `û_j` is the input the
//! system receives from the log's command (`ObservedSystem::input`). They are built from
//! the system's inputs ([`ActuatorHypotheses::declare`]) and applied by
//! [`crate::SystemPlant`] before the equations of motion see the input, in the same dual
//! pass.
//!
//! Effect names say what and where: `input_offset:<input>`, `input_gain:<input>`; their
//! parameters are `<input>_offset` (the input's unit) and `<input>_gain` (dimensionless).
//!
//! Physical ranges (the `plausible` check): an offset within the system's declared
//! `±offset_limit` for that input (none is declared where the limit is zero); a gain within
//! [`GAIN_PLAUSIBLE`] `0.7–1.3`: a battery between full and empty charge moves a driver's
//! output by up to ±20 %, a motor constant within its tolerance by a few per cent; a
//! factor beyond 30 % is a wrong configuration (a PWM range, a unit), not the actuator.

use crate::model::{Catalogue, ParamSpec};
use crate::FitScalar;

/// The plausible range of an input gain (see the module's documentation).
pub const GAIN_PLAUSIBLE: (f64, f64) = (0.7, 1.3);

/// A family of input hypotheses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ActuatorFamily {
    /// `u = û + b`.
    Offset,
    /// `u = k û`.
    Gain,
}

impl ActuatorFamily {
    /// Both families, in the order they are declared per input (offset, then gain).
    pub const ALL: [ActuatorFamily; 2] = [ActuatorFamily::Offset, ActuatorFamily::Gain];

    /// The family's part of an effect name (before `:`).
    pub fn name(self) -> &'static str {
        match self {
            ActuatorFamily::Offset => "input_offset",
            ActuatorFamily::Gain => "input_gain",
        }
    }

    /// The effect's name at the input `input`: `input_gain:u_r`.
    pub fn effect_name(self, input: &str) -> String {
        format!("{}:{input}", self.name())
    }

    /// The parameter's name at the input `input`: `u_r_offset`, `u_r_gain`.
    pub fn param_name(self, input: &str) -> String {
        match self {
            ActuatorFamily::Offset => format!("{input}_offset"),
            ActuatorFamily::Gain => format!("{input}_gain"),
        }
    }
}

/// Where the input hypotheses' parameters sit in the catalogue: per input, the index of
/// its offset and of its gain parameter (none where the family is not declared).
#[derive(Clone, Debug, Default)]
pub struct ActuatorHypotheses {
    per_input: Vec<[Option<usize>; 2]>,
}

impl ActuatorHypotheses {
    /// Append the input hypotheses of `inputs` to `cat` (parameters and effects, in the
    /// inputs' order, offset before gain): a gain on every input, an offset on those whose
    /// `offset_limits` entry (the largest zero-point error of a working driver, in the
    /// input's unit) is positive.
    ///
    /// # Panics
    /// If `offset_limits` and `inputs` differ in length (a programming error of the
    /// system's declaration).
    pub fn declare(cat: &mut Catalogue, inputs: &[String], offset_limits: &[f64]) -> Self {
        assert_eq!(
            inputs.len(),
            offset_limits.len(),
            "one offset limit per input"
        );
        let mut per_input = vec![[None, None]; inputs.len()];
        for (j, (name, &lim)) in inputs.iter().zip(offset_limits).enumerate() {
            if lim > 0.0 {
                let family = ActuatorFamily::Offset;
                let mut p =
                    ParamSpec::linear(&family.param_name(name), 0.0, 0.01 * lim, (-lim, lim));
                p.bounds = (-2.0 * lim, 2.0 * lim);
                let idx = cat.param(p);
                cat.effect(&family.effect_name(name), vec![idx]);
                per_input[j][0] = Some(idx);
            }
            let family = ActuatorFamily::Gain;
            let mut p = ParamSpec::linear(&family.param_name(name), 1.0, 0.01, GAIN_PLAUSIBLE);
            p.bounds = (0.25, 4.0);
            let idx = cat.param(p);
            cat.effect(&family.effect_name(name), vec![idx]);
            per_input[j][1] = Some(idx);
        }
        ActuatorHypotheses { per_input }
    }

    /// The inputs `u` with every declared offset and gain of `theta` applied: `k û + b`.
    /// Inputs whose parameters sit at their null values and carry no derivative are left
    /// untouched.
    pub fn apply<T: FitScalar>(&self, u: &mut [T], theta: &[T]) {
        for (uj, [off, gain]) in u.iter_mut().zip(&self.per_input) {
            let b = off.map(|p| theta[p]).filter(|b| !b.vanishes());
            let k = gain
                .map(|p| theta[p])
                .filter(|k| !(*k - T::one()).vanishes());
            if let Some(k) = k {
                *uj *= k;
            }
            if let Some(b) = b {
                *uj += b;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::DualSVec64;

    /// Declared where asked (an offset only with a positive limit), applied as `k û + b`
    /// with the derivatives of `k` and `b` in the dual part: `∂u/∂k = û`, `∂u/∂b = 1`.
    #[test]
    fn declare_and_apply_offset_and_gain() {
        let mut cat = Catalogue::default();
        let inputs = vec!["a".to_string(), "b".to_string()];
        let h = ActuatorHypotheses::declare(&mut cat, &inputs, &[0.5, 0.0]);
        let names: Vec<&str> = cat.effects.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["input_offset:a", "input_gain:a", "input_gain:b"]);
        type D = DualSVec64<2>;
        let theta = [
            D::from(0.1).derivative(0),
            D::from(1.2).derivative(1),
            D::from(1.0),
        ];
        let mut u = [D::from(2.0), D::from(3.0)];
        h.apply(&mut u, &theta);
        assert!((u[0].re - (1.2 * 2.0 + 0.1)).abs() < 1e-15);
        let e = u[0]
            .eps
            .unwrap_generic(nalgebra::Const::<2>, nalgebra::Const::<1>);
        assert_eq!((e[0], e[1]), (1.0, 2.0));
        assert_eq!(u[1].re, 3.0);
    }
}

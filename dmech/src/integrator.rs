//! The one choice of time-stepping scheme, by what the schemes are: the two variational
//! integrators of the discrete reduced Lagrange–d'Alembert–Pontryagin principle and three
//! explicit Runge–Kutta methods on the continuous equations of motion.

use crate::continuous::RungeKutta;
use crate::variational::Discretisation;

/// A time-stepping scheme for a system: what a simulation or a plan is discretised with.
///
/// The variational schemes ([`VariationalIntegrator`](crate::VariationalIntegrator)) keep
/// the nonholonomic constraint exactly and have the structure of a discrete mechanical
/// system; the Runge–Kutta ones step the continuous model
/// ([`ContinuousModel`](crate::ContinuousModel)). Names on the command lines:
/// `first-order` (also `varint`, the paper's name), `midpoint`, `rk1`, `rk2`, `rk4`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Integrator {
    /// The first-order variational integrator (the paper's VarInt): rectangle-rule
    /// Lagrangian, connection at the node, right-point forcing.
    FirstOrder,
    /// The midpoint variational integrator: second order and time-reversible.
    Midpoint,
    /// Explicit Euler on the continuous model.
    Rk1,
    /// Explicit midpoint on the continuous model.
    Rk2,
    /// The classical fourth-order Runge–Kutta method on the continuous model.
    Rk4,
}

/// A name that is not an [`Integrator`]'s.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown integrator '{0}' (expected first-order, midpoint, rk1, rk2 or rk4)")]
pub struct UnknownIntegrator(pub String);

impl Integrator {
    /// Every scheme, in the order of [`Integrator::name`]'s documentation.
    pub const ALL: [Integrator; 5] = [
        Integrator::FirstOrder,
        Integrator::Midpoint,
        Integrator::Rk1,
        Integrator::Rk2,
        Integrator::Rk4,
    ];

    /// The name the tools read and write: `first-order`, `midpoint`, `rk1`, `rk2`, `rk4`.
    pub fn name(self) -> &'static str {
        match self {
            Integrator::FirstOrder => "first-order",
            Integrator::Midpoint => "midpoint",
            Integrator::Rk1 => "rk1",
            Integrator::Rk2 => "rk2",
            Integrator::Rk4 => "rk4",
        }
    }

    /// The variational discretisation, if this is a variational scheme.
    pub fn variational(self) -> Option<Discretisation> {
        match self {
            Integrator::FirstOrder => Some(Discretisation::FirstOrder),
            Integrator::Midpoint => Some(Discretisation::Midpoint),
            _ => None,
        }
    }

    /// The Runge–Kutta method, if this is one.
    pub fn runge_kutta(self) -> Option<RungeKutta> {
        match self {
            Integrator::Rk1 => Some(RungeKutta::Rk1),
            Integrator::Rk2 => Some(RungeKutta::Rk2),
            Integrator::Rk4 => Some(RungeKutta::Rk4),
            _ => None,
        }
    }

    /// The order of accuracy of a step.
    pub fn order(self) -> u32 {
        match self {
            Integrator::FirstOrder | Integrator::Rk1 => 1,
            Integrator::Midpoint | Integrator::Rk2 => 2,
            Integrator::Rk4 => 4,
        }
    }
}

impl From<Discretisation> for Integrator {
    fn from(d: Discretisation) -> Self {
        match d {
            Discretisation::FirstOrder => Integrator::FirstOrder,
            Discretisation::Midpoint => Integrator::Midpoint,
        }
    }
}

impl From<RungeKutta> for Integrator {
    fn from(rk: RungeKutta) -> Self {
        match rk {
            RungeKutta::Rk1 => Integrator::Rk1,
            RungeKutta::Rk2 => Integrator::Rk2,
            RungeKutta::Rk4 => Integrator::Rk4,
        }
    }
}

impl std::fmt::Display for Integrator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// [`Integrator::name`]'s names, and `varint` for [`Integrator::FirstOrder`].
impl std::str::FromStr for Integrator {
    type Err = UnknownIntegrator;
    fn from_str(s: &str) -> Result<Self, UnknownIntegrator> {
        if s == "varint" {
            return Ok(Integrator::FirstOrder);
        }
        Integrator::ALL
            .into_iter()
            .find(|i| i.name() == s)
            .ok_or_else(|| UnknownIntegrator(s.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_families_partition_the_schemes() {
        for i in Integrator::ALL {
            assert_eq!(i.name().parse::<Integrator>(), Ok(i));
            assert!(
                i.variational().is_some() != i.runge_kutta().is_some(),
                "{i}"
            );
            let back = match (i.variational(), i.runge_kutta()) {
                (Some(d), None) => Integrator::from(d),
                (None, Some(rk)) => Integrator::from(rk),
                _ => unreachable!(),
            };
            assert_eq!(back, i);
        }
        assert_eq!("varint".parse::<Integrator>(), Ok(Integrator::FirstOrder));
        assert!("rk3".parse::<Integrator>().is_err());
    }
}

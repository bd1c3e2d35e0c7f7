//! Model validation by short-horizon prediction error, for any system that can predict its
//! own readings (docs/diagnose.md): given a measured log, show where the model disagrees
//! with the data, which unmodelled effect of a catalogue explains the difference, calibrate
//! the system's own parameters, and measure the gain.
//!
//! Nothing here knows a particular robot. A system supplies a [`Plant`]: its channels and
//! inputs, a catalogue of effects with their parameters ([`Catalogue`]), a prediction of
//! the readings over a window from an initial state (generic in the scalar, so that one
//! pass in dual numbers gives the derivatives), and the operating conditions worth
//! testing the residual against. The WIP's plant is `robots::wip::diagnose::plant`; a toy
//! system in `robots/tests/diagnose/toy.rs` shows the machinery on a second system.
//!
//! The crate depends on the framework crates, `nalgebra`, `num-dual` and `thiserror` alone:
//! reading a log from CSV and writing the report files are the tools' (`robots::diagnose`).
//!
//! One concept per module: [`diagnosis`] (what `diagnose` takes and gives), [`error`]
//! (why a log cannot be diagnosed), [`log`] (the measured log), [`model`] (parameters, effects,
//! candidates), [`fit`] (the windows' Levenberg–Marquardt fit), [`normal_equations`] (its
//! Gauss–Newton blocks, step and covariance),
//! [`restart`] (restarts of a fit's outlying windows), [`noise`] (noise levels and the
//! error measure), [`adequacy`] (is anything left), [`conditions`] (where the model
//! fails), [`identify`] (which parameter combinations a log determines), [`readings`] (the
//! generic offset and scale hypotheses of every reading), [`actuators`] (those of every
//! input, for systems of the traits), [`session`] (a
//! candidate fitted and scored, re-weighting, calibration), [`selection`] (the order of the
//! diagnosis), [`verdict`] (its conclusion), [`system_plant`] (the plant of a system
//! described by `dmech`'s traits, its prediction derived from them), [`fixed_params`] (a
//! system whose own parameters are not fitted, for it).

#![warn(missing_docs)]

pub mod actuators;
pub mod adequacy;
pub mod conditions;
pub mod diagnosis;
pub mod error;
pub mod fit;
pub mod fixed_params;
mod grid_scan;
pub mod identify;
pub mod log;
pub mod model;
pub mod noise;
pub mod normal_equations;
pub mod readings;
pub mod restart;
pub mod selection;
pub mod session;
pub mod system_plant;
pub mod verdict;
mod window_memo;

pub use actuators::{ActuatorFamily, ActuatorHypotheses};
pub use diagnosis::{DiagnoseOptions, Diagnosis};
pub use error::DiagnoseError;
pub use fixed_params::FixedParams;
pub use log::{ChannelSpec, MeasuredLog};
pub use model::{Candidate, Catalogue, EffectSpec, ParamSpec};
pub use readings::{ReadingFamily, ReadingHypotheses};
pub use selection::diagnose;
pub use system_plant::{ObservedPoint, ObservedSystem, SystemPlant};

use dmech::continuous::acceleration_with_force;
use dmech::{Lift, PrincipalKinematicSystem};
use dmech_lie::Real;
use nalgebra::SVector;
use num_dual::DualSVec64;

/// Scalars a prediction runs in: `f64` (values) and dual vectors (values and derivatives
/// with respect to a window's initial state and the free parameters).
pub trait FitScalar: Real + Lift<Self> {
    /// Zero in value and in every derivative: an effect at this value, and not free, can
    /// be skipped.
    fn vanishes(&self) -> bool;

    /// The shape acceleration `v̇ = a(s, v, u)` of a system whose parameters are in this
    /// scalar, with the generalised force `f_ext` on the shape added to its forcing
    /// (`dmech::continuous::acceleration_with_force`, which takes its mass matrix by
    /// nested duals over this scalar: the two implementations name those scalars, which a
    /// caller generic over `FitScalar` cannot). A system's closed form is taken where it has
    /// one and `f_ext` vanishes. `None` if the mass matrix is singular.
    fn shape_acceleration<S, const DOF: usize, const NS: usize, const NU: usize>(
        sys: &S,
        s: &SVector<Self, NS>,
        v: &SVector<Self, NS>,
        u: &SVector<Self, NU>,
        f_ext: &SVector<Self, NS>,
    ) -> Option<SVector<Self, NS>>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = Self>;
}

type Dv<T, const N: usize> = num_dual::DualVec<T, nalgebra::Const<N>>;

/// [`FitScalar::shape_acceleration`] for a scalar `T` that names the nested duals
/// `acceleration_with_force` needs: the system's closed form where it has one and `f_ext`
/// vanishes, the generic equations of motion otherwise.
fn shape_acceleration_in<S, T, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    s: &SVector<T, NS>,
    v: &SVector<T, NS>,
    u: &SVector<T, NU>,
    f_ext: &SVector<T, NS>,
) -> Option<SVector<T, NS>>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = T>,
    T: FitScalar,
    Dv<T, NS>: Lift<T>,
    Dv<T, DOF>: Lift<T>,
    Dv<Dv<T, NS>, NS>: Lift<T>,
    num_dual::Dual<T>: Lift<T>,
    Dv<num_dual::Dual<T>, NS>: Lift<T>,
{
    let closed = if f_ext.iter().all(FitScalar::vanishes) {
        sys.closed_form_acceleration(s, v, u)
    } else {
        None
    };
    closed.or_else(|| acceleration_with_force::<S, T, DOF, NS, NU>(sys, s, v, u, f_ext))
}

impl FitScalar for f64 {
    fn vanishes(&self) -> bool {
        *self == 0.0
    }

    fn shape_acceleration<S, const DOF: usize, const NS: usize, const NU: usize>(
        sys: &S,
        s: &SVector<f64, NS>,
        v: &SVector<f64, NS>,
        u: &SVector<f64, NU>,
        f_ext: &SVector<f64, NS>,
    ) -> Option<SVector<f64, NS>>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        shape_acceleration_in::<S, f64, DOF, NS, NU>(sys, s, v, u, f_ext)
    }
}

impl<const N: usize> FitScalar for DualSVec64<N> {
    fn vanishes(&self) -> bool {
        self.re == 0.0
            && self
                .eps
                .unwrap_generic(nalgebra::Const::<N>, nalgebra::Const::<1>)
                .iter()
                .all(|&e| e == 0.0)
    }

    fn shape_acceleration<S, const DOF: usize, const NS: usize, const NU: usize>(
        sys: &S,
        s: &SVector<Self, NS>,
        v: &SVector<Self, NS>,
        u: &SVector<Self, NU>,
        f_ext: &SVector<Self, NS>,
    ) -> Option<SVector<Self, NS>>
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = Self>,
    {
        shape_acceleration_in::<S, Self, DOF, NS, NU>(sys, s, v, u, f_ext)
    }
}

/// One operating condition: per row of the log, whether the condition holds (`None` where
/// it is undefined). The residual of a failing channel is compared inside and outside.
#[derive(Clone, Debug)]
pub struct Indicator {
    /// What the condition says, as the report names it (e.g. `input positive`).
    pub name: String,
    /// Per row of the log: the condition holds, does not, or is undefined there.
    pub flags: Vec<Option<bool>>,
}

/// A system that `diagnose` can compare with a log.
///
/// The prediction of a window starts from a state `z₀` of [`Plant::state_dim`] components,
/// fitted per window; the parameters `θ` are the whole catalogue's ([`Catalogue::params`]),
/// every one at its nominal value except those a candidate frees. At nominal values the
/// prediction is the system's own model.
pub trait Plant: Sync {
    /// The measured channels, in the order of the predicted readings.
    fn channels(&self) -> &[ChannelSpec];
    /// The names of the input columns (the commands), in the order of
    /// [`MeasuredLog::input`].
    fn inputs(&self) -> &[String];
    /// The effects and parameters the diagnosis may free.
    fn catalogue(&self) -> &Catalogue;
    /// Components of a window's initial state.
    fn state_dim(&self) -> usize;
    /// `(state, channel)` pairs: the state component adds to that channel's reading with
    /// coefficient one and enters nothing else (a position along a symmetry). Its Jacobian
    /// column is then a constant and needs no dual direction.
    fn additive(&self) -> &[(usize, usize)];
    /// Rows of the log needed before the first window (commands that a delay reaches back to).
    fn history(&self, h: f64) -> usize;
    /// A first guess of the state at row `start` from the readings of the window
    /// `start..start + len`.
    fn initial_state(&self, log: &MeasuredLog, start: usize, len: usize) -> Vec<f64>;
    /// The predicted readings of rows `start..start + len`, row after row
    /// (`len × channels().len()` values), from the state `z0` at `start` with parameters
    /// `theta`; `None` if the model cannot be simulated there.
    fn predict<T: FitScalar>(
        &self,
        log: &MeasuredLog,
        start: usize,
        len: usize,
        z0: &[T],
        theta: &[T],
    ) -> Option<Vec<T>>;
    /// What [`Plant::predict`] over the window `(start, len)` reads of the parameters
    /// `theta`: parameters with equal keys (bit for bit) predict the window alike, from
    /// any state and with any dual seeding of the state. The default is `theta` itself; a
    /// plant whose parameter acts on a window only through a few discrete decisions (a
    /// sampled time threshold) may return those decisions instead, so that a scan over
    /// that parameter shares the windows it cannot tell apart (`fit::WindowMemo`).
    fn window_key(
        &self,
        _log: &MeasuredLog,
        _start: usize,
        _len: usize,
        theta: &[f64],
    ) -> Vec<f64> {
        theta.to_vec()
    }
    /// Operating conditions the residual may follow (the diagnosis adds a trend in time).
    fn conditions(&self, log: &MeasuredLog) -> Vec<Indicator>;
    /// Channels of `log` that the log's writer computed from other channels through the
    /// plant's own kinematics (a firmware's dead reckoning of its encoders logged as a
    /// pose), each with the reason in words: not a second measurement, so the diagnosis
    /// sets them aside as it does a copied column (fitting them would count the same
    /// readings twice, and the writer's formula is not the model's). The default: none.
    fn derived_channels(&self, _log: &MeasuredLog) -> Vec<(usize, String)> {
        Vec::new()
    }
    /// The generic hypotheses on the readings (offset and scale per channel) that the
    /// plant declared into its catalogue with [`ReadingHypotheses::declare`]; the fit
    /// applies them on top of [`Plant::predict`]. `None`: the plant declares none.
    fn readings(&self) -> Option<&ReadingHypotheses> {
        None
    }
}

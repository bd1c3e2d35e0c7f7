//! A closed loop along a plan as a library call: what `wip track` and the Python package's
//! `dmech.wip.track` share (the plant of a seed, the sensors, the controller's design), so
//! that both give the same run.

use super::closed_loop::{
    track_with_substeps, Controller, Push, TrackConfig, TrackError, TrackRun,
};
use super::dare::DareError;
use super::lq::{LqController, SAMPLE};
use super::monte_carlo::{monte_carlo, perturbed, with_mean_delay, McRun};
use super::mpc::{MpcController, MpcDesignError};
use super::nmpc::{NmpcController, NmpcDesignError, NmpcOptions};
use super::observer::SensorModel;
use super::simulated_robot::substeps;
use crate::wip::simulate::Trajectory;
use crate::wip::WipParams;

/// The tracking controllers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ControllerKind {
    /// The paper's LQ controller on the ZOH-discretised linear model.
    #[default]
    Lq,
    /// A QP per sample along the plan (`dmech_ocp::qp`).
    Mpc,
    /// The nonlinear MPC on the plan's transcription (`dmech_ocp::tracking::nmpc`).
    Nmpc,
}

impl std::str::FromStr for ControllerKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "lq" => Ok(ControllerKind::Lq),
            "mpc" => Ok(ControllerKind::Mpc),
            "nmpc" => Ok(ControllerKind::Nmpc),
            _ => Err(format!(
                "unknown controller '{s}' (expected lq, mpc or nmpc)"
            )),
        }
    }
}

/// A closed-loop run's settings (`wip track`'s options).
#[derive(Clone, Debug)]
pub struct TrackRequest {
    pub controller: ControllerKind,
    /// The nominal robot: the controller's and the observer's design.
    pub params: WipParams,
    /// Seed of the sensor noise, delays and losses.
    pub seed: u64,
    /// No noise, no delay, no loss: the observer sees the true state.
    pub ideal: bool,
    /// Mean delay of the external pose (s); `None`: the paper's law.
    pub mean_delay: Option<f64>,
    /// The plant of Monte Carlo seed N (its parameter error `param_error`); `None`: the
    /// nominal robot.
    pub plant_seed: Option<u64>,
    /// Relative error of every mass, inertia and motor parameter of a perturbed plant.
    pub param_error: f64,
    /// The NMPC's horizon, Newton steps and budget.
    pub nmpc: NmpcOptions,
    /// A push on the robot during the run (a single run; a Monte Carlo run has none).
    pub push: Option<Push>,
}

impl Default for TrackRequest {
    fn default() -> Self {
        TrackRequest {
            controller: ControllerKind::Lq,
            params: WipParams::default(),
            seed: 1,
            ideal: false,
            mean_delay: None,
            plant_seed: None,
            param_error: 0.1,
            nmpc: NmpcOptions::default(),
            push: None,
        }
    }
}

/// Why a closed loop cannot start.
#[derive(Debug, thiserror::Error)]
pub enum TrackSetupError {
    #[error(transparent)]
    Plant(#[from] TrackError),
    #[error("the LQ design failed: {0}")]
    Lq(DareError),
    #[error(transparent)]
    Mpc(#[from] MpcDesignError),
    #[error(transparent)]
    Nmpc(#[from] NmpcDesignError),
    /// A push outside the plan's time, or of a tilt rate that is not finite.
    #[error("a push of {tilt_rate} rad/s at t = {at_s} s: it must be finite and within the plan's 0–{end_s} s")]
    Push {
        at_s: f64,
        tilt_rate: f64,
        end_s: f64,
    },
}

/// A closed loop ready to run along its plan: the plant checked, the controllers designed.
pub struct PreparedTrack<'p> {
    plan: &'p Trajectory,
    lq: LqController,
    mpc: Option<MpcController>,
    nmpc: Option<NmpcController>,
    /// The plant, the nominal model, the sensors and the seed.
    pub config: TrackConfig,
    /// RK4 substeps per sample of the plant.
    pub substeps: usize,
}

impl TrackRequest {
    /// The sensors of the run.
    pub fn sensors(&self) -> SensorModel {
        match (self.ideal, self.mean_delay) {
            (true, _) => SensorModel::ideal(),
            (false, Some(m)) => with_mean_delay(m),
            (false, None) => SensorModel::paper(),
        }
    }

    /// Check the plant (a plant that cannot be simulated is refused at once) and design the
    /// controllers along `plan`.
    pub fn prepare<'p>(&self, plan: &'p Trajectory) -> Result<PreparedTrack<'p>, TrackSetupError> {
        if let Some(p) = self.push {
            let end_s = plan.t.last().copied().unwrap_or(0.0);
            if !(p.tilt_rate.is_finite() && p.at_s >= 0.0 && p.at_s <= end_s) {
                return Err(TrackSetupError::Push {
                    at_s: p.at_s,
                    tilt_rate: p.tilt_rate,
                    end_s,
                });
            }
        }
        let plant = self.plant_seed.map_or(self.params, |n| {
            perturbed(&self.params, self.param_error, n)
        });
        let substeps = substeps(&plant, &plan.x[0], SAMPLE).map_err(|e| match self.plant_seed {
            Some(seed) => TrackError::Seed {
                seed,
                source: Box::new(e),
            },
            None => TrackError::Plant(e),
        })?;
        let lq = LqController::design(&self.params).map_err(TrackSetupError::Lq)?;
        let mpc = match self.controller {
            ControllerKind::Mpc => Some(MpcController::design(&self.params, plan)?),
            _ => None,
        };
        let nmpc = match self.controller {
            ControllerKind::Nmpc => Some(NmpcController::design(&self.params, plan, self.nmpc)?),
            _ => None,
        };
        Ok(PreparedTrack {
            plan,
            lq,
            mpc,
            nmpc,
            config: TrackConfig {
                plant,
                nominal: self.params,
                sensors: self.sensors(),
                seed: self.seed,
                push: self.push,
            },
            substeps,
        })
    }
}

impl PreparedTrack<'_> {
    /// The feedback law.
    pub fn controller(&self) -> Controller<'_> {
        match (&self.mpc, &self.nmpc) {
            (Some(mpc), _) => Controller::Mpc(mpc),
            (None, Some(nmpc)) => Controller::Nmpc(nmpc),
            (None, None) => Controller::Lq(&self.lq),
        }
    }

    /// The plan being tracked.
    pub fn plan(&self) -> &Trajectory {
        self.plan
    }

    /// One closed-loop run; `progress` gets the fraction done every 5 %.
    pub fn run(&self, progress: impl FnMut(f64)) -> TrackRun {
        track_with_substeps(
            self.plan,
            self.controller(),
            &self.config,
            self.substeps,
            progress,
        )
    }

    /// Seeds `1..=n` on `threads` threads, each with its own plant error (`param_error`
    /// around the nominal robot) and the run's sensors.
    pub fn monte_carlo(
        &self,
        param_error: f64,
        n: u64,
        threads: usize,
    ) -> Result<Vec<McRun>, TrackError> {
        monte_carlo(
            self.plan,
            self.controller(),
            &self.config.plant,
            &self.config.sensors,
            param_error,
            n,
            threads,
        )
    }
}

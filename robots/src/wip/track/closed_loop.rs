//! The closed loop: the plan's feedforward plus LQ feedback on the guidance and observer
//! errors, saturated at ±5 V, applied to the plant (`plant.rs`: the full nonlinear model,
//! RK4 with substeps between the 5-ms samples); its record and figures.

use super::guidance;
use super::lq::{LqController, SAMPLE};
use super::mpc::MpcController;
use super::nmpc::NmpcController;
use super::observer::{Estimate, Observer, OnBoard, PoseMeasurement, SensorModel};
use super::simulated_robot::{check_physical, substeps, Divergence, Plant};
use crate::check::CheckError;
use crate::wip::simulate::Trajectory;
use crate::wip::{ReducedState, WipParams};
use dmech_lie::rng::Rng;
use dmech_ocp::tracking::DelayLaw;
use nalgebra::SVector;

/// Motor voltage limit (V).
pub const U_MAX: f64 = 5.0;
/// A tilt beyond which the WIP counts as fallen (rad, 45°): no 5-V input recovers it.
pub const FALL_TILT: f64 = std::f64::consts::FRAC_PI_4;

/// What runs: the plant's parameters, the sensors, the seed.
#[derive(Clone, Debug)]
pub struct TrackConfig {
    pub plant: WipParams,
    /// The parameters the controller and the observer are designed with.
    pub nominal: WipParams,
    pub sensors: SensorModel,
    pub seed: u64,
    /// A push on the robot during the run, if any.
    pub push: Option<Push>,
}

/// A push: the body's tilt rate `v_α` changed at once by `tilt_rate` (rad/s) at the first
/// sample at or after `at_s` (s), before that sample's sensors read the plant (`wip track
/// --push-at T --push W`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Push {
    pub at_s: f64,
    pub tilt_rate: f64,
}

impl Push {
    /// The sample the push acts at: the first at or after `at_s` (a time within 1e-6 of a
    /// sample's is that sample's).
    pub fn sample(&self) -> usize {
        let k = self.at_s / SAMPLE;
        let k = if (k - k.round()).abs() < 1e-6 {
            k.round()
        } else {
            k.ceil()
        };
        k.max(0.0) as usize
    }
}

/// One controller sample of the closed loop.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    pub t: f64,
    pub x: ReducedState,
    pub reference: ReducedState,
    pub estimate: [f64; 3],
    pub u_ff: [f64; 2],
    pub u_fb: [f64; 2],
    pub u: [f64; 2],
}

/// The closed loop's record and whether (and when) the WIP fell, or the simulation of the
/// plant diverged (a numerical failure, never counted as a fall).
#[derive(Clone, Debug, Default)]
pub struct TrackRun {
    pub samples: Vec<Sample>,
    pub fell_at: Option<f64>,
    /// When and why the plant's simulation diverged; the samples end before it.
    pub diverged: Option<(f64, Divergence)>,
    /// RK4 substeps per sample of the plant ([`super::simulated_robot::substeps`]).
    pub substeps: usize,
    /// The MPC's QP (or the NMPC's) solve time per sample (s, the thread's CPU time); empty
    /// for LQ.
    pub qp_solve_s: Vec<f64>,
    /// The same as wall-clock time (s).
    pub qp_wall_s: Vec<f64>,
    /// Samples where the QP (or the NMPC's solve) gave no move and the LQ move was applied
    /// instead.
    pub qp_fallbacks: usize,
    /// The push the run had, if any.
    pub push: Option<Push>,
}

/// The feedback law of the loop.
#[derive(Clone, Copy, Debug)]
pub enum Controller<'a> {
    /// The paper's LQ controller, `u_fb = −K e`.
    Lq(&'a LqController),
    /// The constrained MPC along the plan (`mpc.rs`).
    Mpc(&'a MpcController),
    /// The nonlinear MPC on the plan's transcription (`nmpc.rs`).
    Nmpc(&'a NmpcController),
}

impl<'a> From<&'a LqController> for Controller<'a> {
    fn from(lq: &'a LqController) -> Self {
        Controller::Lq(lq)
    }
}

impl<'a> From<&'a MpcController> for Controller<'a> {
    fn from(mpc: &'a MpcController) -> Self {
        Controller::Mpc(mpc)
    }
}

impl<'a> From<&'a NmpcController> for Controller<'a> {
    fn from(nmpc: &'a NmpcController) -> Self {
        Controller::Nmpc(nmpc)
    }
}

impl Controller<'_> {
    /// The name used in outputs.
    pub fn name(&self) -> &'static str {
        match self {
            Controller::Lq(_) => "lq",
            Controller::Mpc(_) => "mpc",
            Controller::Nmpc(_) => "nmpc",
        }
    }
}

/// The plan as a reference: states linearly interpolated between its nodes, voltages held.
pub struct Reference<'a> {
    pub plan: &'a Trajectory,
}

impl Reference<'_> {
    pub fn end(&self) -> f64 {
        *self.plan.t.last().unwrap_or(&0.0)
    }
    pub fn at(&self, t: f64) -> (ReducedState, [f64; 2]) {
        let tt = &self.plan.t;
        let j = tt.partition_point(|&tj| tj <= t + 1e-9).saturating_sub(1);
        if j + 1 >= tt.len() {
            return (self.plan.x[tt.len() - 1], self.plan.u[tt.len() - 1]);
        }
        let w = ((t - tt[j]) / (tt[j + 1] - tt[j])).clamp(0.0, 1.0);
        (
            self.plan.x[j] * (1.0 - w) + self.plan.x[j + 1] * w,
            self.plan.u[j],
        )
    }
}

/// Summary figures of a run (tracking.json).
#[derive(Clone, Debug, serde::Serialize)]
pub struct TrackFigures {
    pub position_error_max_m: f64,
    pub position_error_rms_m: f64,
    pub heading_error_max_rad: f64,
    pub heading_error_rms_rad: f64,
    pub tilt_max_rad: f64,
    pub feedback_voltage_max: f64,
    pub feedback_voltage_rms: f64,
    pub fell: bool,
    /// `"completed"`, `"fell"` (|α| > 45°) or `"diverged"` (the plant's simulation, not the
    /// robot, failed: its figures are not a result).
    pub outcome: &'static str,
    /// The MPC's QP (or the NMPC's solve) time per sample as CPU time, median, 99th
    /// percentile and largest (ms), and the same as wall-clock time; `null` for LQ.
    pub qp_solve_ms_median: Option<f64>,
    pub qp_solve_ms_p99: Option<f64>,
    pub qp_solve_ms_max: Option<f64>,
    pub qp_wall_ms_median: Option<f64>,
    pub qp_wall_ms_p99: Option<f64>,
    pub qp_wall_ms_max: Option<f64>,
    pub qp_fallbacks: usize,
    /// The push the run had, if any.
    pub push: Option<Push>,
}

impl TrackRun {
    /// `"completed"`, `"fell"` or `"diverged"`.
    pub fn outcome(&self) -> &'static str {
        match (self.diverged.is_some(), self.fell_at.is_some()) {
            (true, _) => "diverged",
            (false, true) => "fell",
            (false, false) => "completed",
        }
    }

    pub fn figures(&self) -> TrackFigures {
        let n = self.samples.len().max(1) as f64;
        let mut f = TrackFigures {
            position_error_max_m: 0.0,
            position_error_rms_m: 0.0,
            heading_error_max_rad: 0.0,
            heading_error_rms_rad: 0.0,
            tilt_max_rad: 0.0,
            feedback_voltage_max: 0.0,
            feedback_voltage_rms: 0.0,
            fell: self.fell_at.is_some(),
            outcome: self.outcome(),
            qp_solve_ms_median: ms_quantile(&self.qp_solve_s, 0.5),
            qp_solve_ms_p99: ms_quantile(&self.qp_solve_s, 0.99),
            qp_solve_ms_max: ms_quantile(&self.qp_solve_s, 1.0),
            qp_wall_ms_median: ms_quantile(&self.qp_wall_s, 0.5),
            qp_wall_ms_p99: ms_quantile(&self.qp_wall_s, 0.99),
            qp_wall_ms_max: ms_quantile(&self.qp_wall_s, 1.0),
            qp_fallbacks: self.qp_fallbacks,
            push: self.push,
        };
        let (mut sp, mut sh, mut su) = (0.0, 0.0, 0.0);
        for s in &self.samples {
            let (ep, eh) = s.errors();
            f.position_error_max_m = f.position_error_max_m.max(ep);
            f.heading_error_max_rad = f.heading_error_max_rad.max(eh.abs());
            f.tilt_max_rad = f.tilt_max_rad.max(s.x[3].abs());
            let ufb = s.u_fb[0].abs().max(s.u_fb[1].abs());
            f.feedback_voltage_max = f.feedback_voltage_max.max(ufb);
            sp += ep * ep;
            sh += eh * eh;
            su += 0.5 * (s.u_fb[0].powi(2) + s.u_fb[1].powi(2));
        }
        f.position_error_rms_m = (sp / n).sqrt();
        f.heading_error_rms_rad = (sh / n).sqrt();
        f.feedback_voltage_rms = (su / n).sqrt();
        f
    }
}

impl Sample {
    /// True position error (m) and heading error (rad) against the plan.
    pub fn errors(&self) -> (f64, f64) {
        let ep = (self.x[0] - self.reference[0]).hypot(self.x[1] - self.reference[1]);
        (ep, guidance::wrap(self.x[2] - self.reference[2]))
    }
}

/// The LQ error state `(e_d, e_θ, α − α_r, v_α − v_α,r, v_d − v_d,r, v_θ − v_θ,r,
/// iR − iR_r, iL − iL_r)` of an estimate against the reference.
fn error_state(e: &Estimate, r: &ReducedState) -> SVector<f64, 8> {
    let (ed, eth) = guidance::errors(e.pose, [r[0], r[1], r[2]], r[5]);
    SVector::<f64, 8>::from_column_slice(&[
        ed,
        eth,
        e.alpha - r[3],
        e.v_alpha - r[4],
        e.v_d - r[5],
        e.v_theta - r[6],
        e.i[0] - r[7],
        e.i[1] - r[8],
    ])
}

/// Why a closed loop was not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrackError {
    /// The plant cannot be simulated within RK4's stability bound, or its rates are not
    /// finite at the start.
    #[error(transparent)]
    Plant(#[from] CheckError),
    /// The same for the plant of one Monte Carlo seed.
    #[error("Monte Carlo seed {seed}: {source}")]
    Seed {
        seed: u64,
        #[source]
        source: Box<CheckError>,
    },
}

/// Run the closed loop along `plan` with `controller` (LQ or MPC). `progress` is called with
/// the fraction done every 5 % of the run. The plant's RK4 substeps are chosen from its
/// modes first ([`super::simulated_robot::substeps`]); a refusal there is the error. A fall (|α| >
/// 45°) ends the run, and so does a divergence of the plant's simulation (a state not
/// finite or beyond [`super::simulated_robot::PHYSICAL_BOUNDS`]): that is not a fall.
pub fn track<'a>(
    plan: &Trajectory,
    controller: impl Into<Controller<'a>>,
    cfg: &TrackConfig,
    progress: impl FnMut(f64),
) -> Result<TrackRun, TrackError> {
    let n = substeps(&cfg.plant, &plan.x[0], SAMPLE)?;
    Ok(track_with_substeps(plan, controller, cfg, n, progress))
}

/// [`track`] with the plant's substeps given (checked by the caller).
pub fn track_with_substeps<'a>(
    plan: &Trajectory,
    controller: impl Into<Controller<'a>>,
    cfg: &TrackConfig,
    substeps: usize,
    mut progress: impl FnMut(f64),
) -> TrackRun {
    let controller = controller.into();
    let reference = Reference { plan };
    let n = (reference.end() / SAMPLE).round() as usize;
    let sens = &cfg.sensors;
    let mut rng = Rng::new(cfg.seed);
    let x0 = plan.x[0];
    let mut plant = Plant::with_substeps(cfg.plant, &x0, substeps);
    let start = Estimate {
        pose: [x0[0], x0[1], x0[2]],
        alpha: x0[3],
        v_alpha: x0[4],
        v_d: x0[5],
        v_theta: x0[6],
        i: [x0[7], x0[8]],
    };
    let mut obs = Observer::new(cfg.nominal, SAMPLE, sens.pose_gain, start);
    let quantum = if sens.encoder_counts == 0 {
        0.0
    } else {
        2.0 * std::f64::consts::PI / sens.encoder_counts as f64
    };
    let ideal = *sens == SensorModel::ideal();
    // Poses in flight: (arrival sample, measurement).
    let mut in_flight: Vec<(usize, PoseMeasurement)> = Vec::new();
    let mut run = TrackRun {
        substeps,
        push: cfg.push,
        ..TrackRun::default()
    };
    let mut u_prev = plan.u[0];
    let every = (n / 20).max(1);
    let push_at = cfg.push.map(|p| (p.sample(), p.tilt_rate));
    for k in 0..=n {
        let t = k as f64 * SAMPLE;
        if let Some((at, dv)) = push_at {
            if at == k {
                plant.push_tilt_rate(dv);
            }
        }
        let x = plant.reduced();
        if let Err(d) = check_physical(&x) {
            run.diverged = Some((t, d));
            break;
        }
        if x[3].abs() > FALL_TILT {
            run.fell_at = Some(t);
            break;
        }
        // Sensors.
        let est = if ideal {
            Estimate {
                pose: [x[0], x[1], x[2]],
                alpha: x[3],
                v_alpha: x[4],
                v_d: x[5],
                v_theta: x[6],
                i: [x[7], x[8]],
            }
        } else {
            let q = |a: f64| {
                if quantum > 0.0 {
                    (a / quantum).floor() * quantum
                } else {
                    a
                }
            };
            let wheels = plant.wheels_relative_to_body();
            let onb = OnBoard {
                alpha: x[3] + sens.sigma_alpha * rng.normal(),
                v_alpha: x[4] + sens.sigma_v_alpha * rng.normal(),
                encoders: [q(wheels[0]), q(wheels[1])],
            };
            obs.on_board(&onb, u_prev);
            if k % sens.pose_every == 0 && rng.uniform() >= sens.loss {
                let delay = sens.delay.draw(&mut rng);
                let arrive = k + DelayLaw::samples_late(delay, SAMPLE);
                let pose = [
                    x[0] + sens.sigma_position * rng.normal(),
                    x[1] + sens.sigma_position * rng.normal(),
                    x[2] + sens.sigma_heading * rng.normal(),
                ];
                in_flight.push((arrive, PoseMeasurement { k, pose }));
            }
            in_flight.retain(|(arrive, m)| {
                if *arrive <= k {
                    obs.pose(m);
                    false
                } else {
                    true
                }
            });
            obs.estimate()
        };
        let (xr, u_ff) = reference.at(t);
        let e = error_state(&est, &xr);
        let u_fb = match controller {
            Controller::Lq(lq) => lq.feedback(&e),
            Controller::Mpc(mpc) => {
                let m = mpc.feedback(k, &e, u_prev);
                run.qp_solve_s.push(m.solve_s);
                run.qp_wall_s.push(m.solve_wall_s);
                run.qp_fallbacks += usize::from(!m.solved);
                m.u_fb
            }
            Controller::Nmpc(nmpc) => {
                let m = nmpc.feedback(k, &est, &e, u_ff, u_prev);
                run.qp_solve_s.push(m.solve_s);
                run.qp_wall_s.push(m.solve_wall_s);
                run.qp_fallbacks += usize::from(!m.solved);
                m.u_fb
            }
        };
        let u = [
            (u_ff[0] + u_fb[0]).clamp(-U_MAX, U_MAX),
            (u_ff[1] + u_fb[1]).clamp(-U_MAX, U_MAX),
        ];
        run.samples.push(Sample {
            t,
            x,
            reference: xr,
            estimate: est.pose,
            u_ff,
            u_fb,
            u,
        });
        u_prev = u;
        if k == n {
            break;
        }
        if let Err(d) = plant.advance(SAMPLE, u) {
            run.diverged = Some((t, d));
            break;
        }
        if k % every == 0 {
            progress(k as f64 / n as f64);
        }
    }
    run
}

/// A quantile of times in seconds, in ms; `None` for no samples (LQ has no QP).
fn ms_quantile(seconds: &[f64], q: f64) -> Option<f64> {
    (!seconds.is_empty()).then(|| 1e3 * super::monte_carlo::quantile(seconds, q))
}

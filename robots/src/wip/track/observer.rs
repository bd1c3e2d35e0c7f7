//! The sensors and the observer: on-board tilt, tilt rate and wheel encoders every 5 ms,
//! an external pose at 50 Hz arriving late or never, fused by re-predicting the pose from
//! the measurement's time with the odometry stored since (docs/tracking.md).

use crate::wip::WipParams;
use dmech_ocp::tracking::DelayLaw;
use std::collections::VecDeque;

/// The paper's delay of an external pose: 13–148 ms with a mean of 63 ms (`scale` chosen
/// so that the truncated exponential has that mean; a test measures it).
pub const PAPER_POSE_DELAY: DelayLaw = DelayLaw {
    min: 0.013,
    scale: 0.084,
    max: 0.148,
};

/// The sensor model. `ideal()` is exact and immediate.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorModel {
    /// Standard deviation of the tilt `α` (rad) and of the tilt rate `v_α` (rad/s).
    pub sigma_alpha: f64,
    pub sigma_v_alpha: f64,
    /// Encoder counts per wheel revolution (900 cpr × 4 quadrature edges); 0: exact.
    pub encoder_counts: u32,
    /// External pose: every `pose_every` controller samples (4 × 5 ms = 50 Hz), standard
    /// deviations of position (m) and heading (rad).
    pub pose_every: usize,
    pub sigma_position: f64,
    pub sigma_heading: f64,
    /// Delay of a pose: `min + Exp(mean scale)`, redrawn beyond `max` (s).
    pub delay: DelayLaw,
    /// Probability that a pose is lost.
    pub loss: f64,
    /// Weight of an arriving pose against the predicted one (1: replace).
    pub pose_gain: f64,
}

impl SensorModel {
    /// The paper's rates and delays ([`PAPER_POSE_DELAY`]) and our noise
    /// assumptions (the paper gives no noise figures).
    pub fn paper() -> Self {
        SensorModel {
            sigma_alpha: 2e-3,
            sigma_v_alpha: 1e-2,
            encoder_counts: 3600,
            pose_every: 4,
            sigma_position: 5e-4,
            sigma_heading: 5e-3,
            delay: PAPER_POSE_DELAY,
            loss: 0.02,
            pose_gain: 0.5,
        }
    }
    /// No noise, no quantisation, no delay, no loss.
    pub fn ideal() -> Self {
        SensorModel {
            sigma_alpha: 0.0,
            sigma_v_alpha: 0.0,
            encoder_counts: 0,
            pose_every: 1,
            sigma_position: 0.0,
            sigma_heading: 0.0,
            delay: DelayLaw::NONE,
            loss: 0.0,
            pose_gain: 1.0,
        }
    }
}

/// What the on-board sensors deliver at one sample.
#[derive(Clone, Copy, Debug)]
pub struct OnBoard {
    pub alpha: f64,
    pub v_alpha: f64,
    /// Wheel angles relative to the body, `φ − α` (rad), quantised.
    pub encoders: [f64; 2],
}

/// A pose measured at controller sample `k`.
#[derive(Clone, Copy, Debug)]
pub struct PoseMeasurement {
    pub k: usize,
    pub pose: [f64; 3],
}

/// The estimate the controller uses: the reduced state `X` without the wheel angles.
#[derive(Clone, Copy, Debug, Default)]
pub struct Estimate {
    pub pose: [f64; 3],
    pub alpha: f64,
    pub v_alpha: f64,
    pub v_d: f64,
    pub v_theta: f64,
    pub i: [f64; 2],
}

/// One stored sample: the pose estimate at its time and the odometry increment after it.
#[derive(Clone, Copy, Debug)]
struct Past {
    k: usize,
    pose: [f64; 3],
    /// `(Δd, Δθ)` from sample `k` to `k + 1`.
    step: (f64, f64),
}

/// The observer: odometry from encoders and tilt, current from the motor circuit's exact
/// discretisation, pose corrected by late measurements.
pub struct Observer {
    p: WipParams,
    h: f64,
    gain: f64,
    est: Estimate,
    wheels: Option<[f64; 2]>,
    history: VecDeque<Past>,
    k: usize,
}

/// How far back (samples) a late pose can be fused: 1 s, beyond any delay the channel has.
const HISTORY: usize = 200;

impl Observer {
    pub fn new(p: WipParams, h: f64, pose_gain: f64, start: Estimate) -> Self {
        Observer {
            p,
            h,
            gain: pose_gain,
            est: start,
            wheels: None,
            history: VecDeque::with_capacity(HISTORY + 1),
            k: 0,
        }
    }

    pub fn estimate(&self) -> Estimate {
        self.est
    }

    /// Fuse the on-board sample of sample `k` (the wheel rates by differencing the wheel
    /// angles `φ = enc + α`), after the voltages `u_prev` held over the last interval.
    pub fn on_board(&mut self, m: &OnBoard, u_prev: [f64; 2]) {
        let p = self.p;
        let phi = [m.encoders[0] + m.alpha, m.encoders[1] + m.alpha];
        let (mut dd, mut dth) = (0.0, 0.0);
        if let Some(prev) = self.wheels {
            let (dr, dl) = (phi[0] - prev[0], phi[1] - prev[1]);
            dd = p.r * (dr + dl) / 2.0;
            dth = p.r * (dr - dl) / (2.0 * p.d);
            self.est.v_d = dd / self.h;
            self.est.v_theta = dth / self.h;
            // Odometry with the heading at the interval's middle.
            self.advance_pose(dd, dth);
            // Motor current: exact ZOH solution of L i̇ = u − R i − k_e n_wm (φ̇ − α̇).
            let decay = (-self.h * p.R_m / p.L_m).exp();
            for s in 0..2 {
                let w = (phi[s] - prev[s]) / self.h - m.v_alpha;
                let i_ss = (u_prev[s] - p.k_e * p.n_wm * w) / p.R_m;
                self.est.i[s] = i_ss + (self.est.i[s] - i_ss) * decay;
            }
        }
        if let Some(last) = self.history.back_mut() {
            last.step = (dd, dth);
        }
        self.wheels = Some(phi);
        self.est.alpha = m.alpha;
        self.est.v_alpha = m.v_alpha;
        self.history.push_back(Past {
            k: self.k,
            pose: self.est.pose,
            step: (0.0, 0.0),
        });
        if self.history.len() > HISTORY {
            self.history.pop_front();
        }
        self.k += 1;
    }

    fn advance_pose(&mut self, dd: f64, dth: f64) {
        let pose = &mut self.est.pose;
        let mid = pose[2] + 0.5 * dth;
        pose[0] += dd * mid.cos();
        pose[1] += dd * mid.sin();
        pose[2] += dth;
    }

    /// Fuse a pose measured at sample `m.k`: correct the stored estimate of that time
    /// and re-predict to now with the odometry increments stored since. A pose older than
    /// the history is dropped (returns false).
    pub fn pose(&mut self, m: &PoseMeasurement) -> bool {
        let Some(front) = self.history.front() else {
            return false;
        };
        if m.k < front.k || m.k >= front.k + self.history.len() {
            return false;
        }
        let j = m.k - front.k;
        let old = self.history[j].pose;
        let g = self.gain;
        let dth = super::guidance::wrap(m.pose[2] - old[2]);
        let mut pose = [
            old[0] + g * (m.pose[0] - old[0]),
            old[1] + g * (m.pose[1] - old[1]),
            old[2] + g * dth,
        ];
        for past in self.history.iter_mut().skip(j) {
            past.pose = pose;
            let (dd, dt) = past.step;
            let mid = pose[2] + 0.5 * dt;
            pose = [
                pose[0] + dd * mid.cos(),
                pose[1] + dd * mid.sin(),
                pose[2] + dt,
            ];
        }
        // The last stored entry is the current sample: its pose is the estimate's, and the
        // loop above carried the correction to it without its (not yet known) increment.
        self.est.pose = self.history.back().map(|p| p.pose).unwrap_or(pose);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dmech_lie::rng::Rng;

    /// The default delay law has the paper's mean of 63 ms and range 13–148 ms; the
    /// tolerance is 4 standard errors of the mean of 20 000 draws (σ ≈ 35 ms).
    #[test]
    fn delay_law_has_the_papers_mean_and_range() {
        let s = SensorModel::paper();
        let mut rng = Rng::new(7);
        let n = 20_000;
        let draws: Vec<f64> = (0..n).map(|_| s.delay.draw(&mut rng)).collect();
        let mean = draws.iter().sum::<f64>() / n as f64;
        assert!(draws.iter().all(|&d| (0.013..=0.148).contains(&d)));
        assert!(
            (mean - 0.063).abs() < 4.0 * 0.035 / (n as f64).sqrt(),
            "{mean}"
        );
    }

    /// Straight driving at constant heading: odometry is exact, so a late exact pose with
    /// gain 1, fused by re-prediction from its own time, removes an initial pose error
    /// entirely (rounding only: 1e-12 m on metre-sized sums).
    #[test]
    fn late_pose_is_fused_at_its_own_time() {
        let p = WipParams::default();
        let h = 0.005;
        let wrong = Estimate {
            pose: [0.01, -0.02, 0.0],
            ..Default::default()
        };
        let mut obs = Observer::new(p, h, 1.0, wrong);
        // Both wheels advance 0.3 m/s; the true pose starts at the origin, heading +x.
        let rate = 0.3 / p.r;
        for k in 0..40 {
            let phi = rate * h * k as f64;
            obs.on_board(
                &OnBoard {
                    alpha: 0.0,
                    v_alpha: 0.0,
                    encoders: [phi, phi],
                },
                [0.0; 2],
            );
        }
        // The pose measured at sample 10 (true x = 0.3 · 0.05 m) arrives at sample 39.
        assert!(obs.pose(&PoseMeasurement {
            k: 10,
            pose: [0.3 * 10.0 * h, 0.0, 0.0],
        }));
        let e = obs.estimate().pose;
        let truth = 0.3 * 39.0 * h;
        assert!(
            (e[0] - truth).abs() < 1e-12 && e[1].abs() < 1e-12,
            "{e:?} vs {truth}"
        );
    }
}

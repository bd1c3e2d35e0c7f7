//! A state observer along a plan: a Kalman filter on the plan's linearisation that fuses
//! the on-board readings of every sample with external pose readings that arrive late or
//! never, by going back to the time a pose was measured and re-predicting from there with
//! the inputs and readings stored since.
//!
//! The robot declares what its sensors read as functions of the transcription's state
//! ([`Readings`]: the on-board readings `y = h(x)` every sample, e.g. encoders and a gyro,
//! and the pose reading `p = g(x)`), generic over the scalar so that their Jacobians are
//! taken by vector duals. Noise and quantisation belong to the robot's sensor model; the
//! filter knows only their covariances ([`ObserverNoise`]).
//!
//! At sample `k` the estimate `x̂_k` is corrected by the readings of `k` and by every pose
//! measured at `k` that has arrived, in that order (the extended Kalman update at the
//! estimate: `H = ∂h/∂x(x̂)`, `K = P Hᵀ (H P Hᵀ + R)⁻¹`, `x̂ += K (y − h(x̂))`, the covariance
//! in Joseph's form), then predicted along the plan's linearisation ([`super::LinearisedPlan`]):
//! ```text
//! x̂_{k+1} = x̄_{k+1} + A_k (x̂_k − x̄_k) + B_k (u_k − ū_k),   P_{k+1} = A_k P_k A_kᵀ + Q
//! ```
//! A pose measured at sample `m < k` is stored with sample `m`'s entry and the filter is run
//! again from `m`: its estimate at `k` is then the one it would have had if the pose had
//! arrived at `m` (the same operations in the same order). The filter keeps the last
//! `memory` samples; an older pose is dropped.
//!
//! Why a Kalman filter on the plan's linearisation and not fixed gains: the plan's
//! linearisation is time-varying (a car's steering changes what its yaw rate says about
//! the wheel rate), the poses arrive irregularly and some never, and the sensors differ
//! in accuracy by orders of magnitude; the covariance weighs each reading by its accuracy
//! at each sample without a gain schedule to design. Its prediction is linear in the
//! deviation from the plan, as the LQ and the MPC are: a plant far from its plan is
//! predicted as badly as it is controlled.

use super::LinearisedPlan;
use dmech_lie::dual::value_and_jacobian;
use dmech_lie::linalg::Lu;
use dmech_lie::rng::Rng;
use dmech_lie::Real;
use nalgebra::{SMatrix, SVector};
use std::collections::VecDeque;

/// What the robot's sensors read, noise-free, as functions of the transcription's state:
/// `NY` on-board readings every sample and an `NP`-dimensional pose when one arrives.
/// Angles are read continuous (unwrapped) as the state holds them.
pub trait Readings<const NX: usize, const NY: usize, const NP: usize> {
    /// The on-board readings at state `x`.
    fn on_board<T: Real>(&self, x: &SVector<T, NX>) -> SVector<T, NY>;
    /// The external pose reading at state `x`.
    fn pose<T: Real>(&self, x: &SVector<T, NX>) -> SVector<T, NP>;
}

/// The covariances the filter assumes.
#[derive(Clone, Debug, PartialEq)]
pub struct ObserverNoise<const NX: usize, const NY: usize, const NP: usize> {
    /// `Q`: what the model may be wrong by per sample (parameter error, unmodelled forces).
    pub process: SMatrix<f64, NX, NX>,
    /// `R` of the on-board readings.
    pub on_board: SMatrix<f64, NY, NY>,
    /// `R` of a pose reading.
    pub pose: SMatrix<f64, NP, NP>,
}

/// How late a pose arrives: `min + Exp(mean scale)`, redrawn beyond `max` (s), one draw per
/// pose. A pose measured at sample `m` arrives at sample `m + ⌈delay/h⌉`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DelayLaw {
    /// The shortest delay, s.
    pub min: f64,
    /// The exponential part's mean, s (0: always `min`).
    pub scale: f64,
    /// The longest delay, s (at most `min`: always `min`).
    pub max: f64,
}

impl DelayLaw {
    /// No delay.
    pub const NONE: DelayLaw = DelayLaw {
        min: 0.0,
        scale: 0.0,
        max: 0.0,
    };

    /// A delay, s.
    pub fn draw(&self, rng: &mut Rng) -> f64 {
        if self.scale <= 0.0 || self.max <= self.min {
            return self.min;
        }
        loop {
            let d = self.min - self.scale * (1.0 - rng.uniform()).ln();
            if d <= self.max {
                return d;
            }
        }
    }

    /// Every delay (minimum, scale, maximum) times `factor`: the mean scales with it.
    pub fn scaled(&self, factor: f64) -> Self {
        DelayLaw {
            min: self.min * factor,
            scale: self.scale * factor,
            max: self.max * factor,
        }
    }

    /// The samples of length `h` a pose delayed by `delay` s arrives after its own.
    pub fn samples_late(delay: f64, h: f64) -> usize {
        (delay / h).ceil() as usize
    }
}

/// The plan an observer predicts along: its linearisation, its states `x̄_0 … x̄_N` and its
/// inputs `ū_0 … ū_{N−1}`.
#[derive(Clone, Copy, Debug)]
pub struct PlanView<'a, const NX: usize, const NU: usize> {
    /// `A_k`, `B_k`.
    pub linearised: &'a LinearisedPlan<NX, NU>,
    /// `x̄_k`.
    pub states: &'a [SVector<f64, NX>],
    /// `ū_k`.
    pub inputs: &'a [SVector<f64, NU>],
}

/// Why the observer refuses a call.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ObserverError {
    /// The plan's states, inputs and linearisation do not match.
    #[error("{states} plan states and {inputs} inputs for {stages} linearised stages (need N + 1, N, N)")]
    PlanSizes {
        /// States given.
        states: usize,
        /// Inputs given.
        inputs: usize,
        /// Stages of the linearisation.
        stages: usize,
    },
    /// A history of no sample.
    #[error("the observer's memory must hold at least one sample")]
    NoMemory,
    /// An input at or past the plan's last stage.
    #[error("sample {sample} is past the plan's {stages} stages")]
    PastThePlan {
        /// The sample.
        sample: usize,
        /// The plan's stages.
        stages: usize,
    },
    /// A second set of on-board readings at one sample.
    #[error("sample {sample} already has its on-board readings")]
    ReadTwice {
        /// The sample.
        sample: usize,
    },
    /// A pose measured after the current sample.
    #[error("a pose measured at sample {measured} cannot arrive at sample {now}")]
    FromTheFuture {
        /// When it was measured.
        measured: usize,
        /// The current sample.
        now: usize,
    },
    /// A reading, input or the estimate is not finite.
    #[error("a value at sample {sample} is not finite")]
    NotFinite {
        /// The sample.
        sample: usize,
    },
    /// `H P Hᵀ + R` is singular at a sample (a reading the filter gives no variance).
    #[error("the innovation's covariance is singular at sample {sample}")]
    SingularInnovation {
        /// The sample.
        sample: usize,
    },
}

/// One sample's entry: the prediction into it, what was read at it, and the input after.
#[derive(Clone, Debug)]
struct Entry<const NX: usize, const NU: usize, const NY: usize, const NP: usize> {
    k: usize,
    prior: SVector<f64, NX>,
    prior_cov: SMatrix<f64, NX, NX>,
    reading: Option<SVector<f64, NY>>,
    poses: Vec<SVector<f64, NP>>,
    input: Option<SVector<f64, NU>>,
    estimate: SVector<f64, NX>,
    cov: SMatrix<f64, NX, NX>,
}

/// The observer along one plan (module documentation).
#[derive(Clone, Debug)]
pub struct Observer<'a, R, const NX: usize, const NU: usize, const NY: usize, const NP: usize> {
    readings: R,
    plan: &'a LinearisedPlan<NX, NU>,
    states: &'a [SVector<f64, NX>],
    inputs: &'a [SVector<f64, NU>],
    noise: ObserverNoise<NX, NY, NP>,
    memory: usize,
    history: VecDeque<Entry<NX, NU, NY, NP>>,
}

impl<'a, R, const NX: usize, const NU: usize, const NY: usize, const NP: usize>
    Observer<'a, R, NX, NU, NY, NP>
where
    R: Readings<NX, NY, NP>,
{
    /// The observer along `plan`, starting at sample 0 from the estimate `start` with
    /// covariance `start_cov`, keeping `memory` samples for late poses.
    pub fn new(
        readings: R,
        plan: PlanView<'a, NX, NU>,
        noise: ObserverNoise<NX, NY, NP>,
        start: SVector<f64, NX>,
        start_cov: SMatrix<f64, NX, NX>,
        memory: usize,
    ) -> Result<Self, ObserverError> {
        let PlanView {
            linearised: plan,
            states,
            inputs,
        } = plan;
        let stages = plan.a.len();
        if plan.b.len() != stages || states.len() != stages + 1 || inputs.len() != stages {
            return Err(ObserverError::PlanSizes {
                states: states.len(),
                inputs: inputs.len(),
                stages,
            });
        }
        if memory == 0 {
            return Err(ObserverError::NoMemory);
        }
        if !finite(start.iter().chain(start_cov.iter())) {
            return Err(ObserverError::NotFinite { sample: 0 });
        }
        let mut history = VecDeque::with_capacity(memory + 1);
        history.push_back(Entry {
            k: 0,
            prior: start,
            prior_cov: start_cov,
            reading: None,
            poses: Vec::new(),
            input: None,
            estimate: start,
            cov: start_cov,
        });
        Ok(Observer {
            readings,
            plan,
            states,
            inputs,
            noise,
            memory,
            history,
        })
    }

    /// The current sample `k`.
    pub fn sample(&self) -> usize {
        self.current().k
    }

    /// The estimate `x̂_k` at the current sample, with what has been read so far.
    pub fn estimate(&self) -> SVector<f64, NX> {
        self.current().estimate
    }

    /// Its covariance.
    pub fn covariance(&self) -> SMatrix<f64, NX, NX> {
        self.current().cov
    }

    /// The on-board readings of the current sample (at most once per sample).
    pub fn read(&mut self, y: &SVector<f64, NY>) -> Result<(), ObserverError> {
        let sample = self.sample();
        if !finite(y.iter()) {
            return Err(ObserverError::NotFinite { sample });
        }
        let last = self.history.len() - 1;
        if self.history[last].reading.is_some() {
            return Err(ObserverError::ReadTwice { sample });
        }
        self.history[last].reading = Some(*y);
        self.settle(last)
    }

    /// A pose measured at sample `measured` (at most the current one), fused at its own
    /// time. Returns whether it was fused: `false` if it is older than the memory.
    pub fn pose(&mut self, measured: usize, p: &SVector<f64, NP>) -> Result<bool, ObserverError> {
        let now = self.sample();
        if measured > now {
            return Err(ObserverError::FromTheFuture { measured, now });
        }
        if !finite(p.iter()) {
            return Err(ObserverError::NotFinite { sample: now });
        }
        let first = self.history[0].k;
        if measured < first {
            return Ok(false);
        }
        let j = measured - first;
        self.history[j].poses.push(*p);
        self.settle(j)?;
        Ok(true)
    }

    /// The input applied at the current sample `k < N`: the estimate is predicted to
    /// `k + 1`, which becomes the current sample.
    pub fn advance(&mut self, u: &SVector<f64, NU>) -> Result<(), ObserverError> {
        let k = self.sample();
        let stages = self.inputs.len();
        if k >= stages {
            return Err(ObserverError::PastThePlan { sample: k, stages });
        }
        if !finite(u.iter()) {
            return Err(ObserverError::NotFinite { sample: k });
        }
        let last = self.history.len() - 1;
        self.history[last].input = Some(*u);
        let (prior, prior_cov) = self.predict(&self.history[last]);
        self.history.push_back(Entry {
            k: k + 1,
            prior,
            prior_cov,
            reading: None,
            poses: Vec::new(),
            input: None,
            estimate: prior,
            cov: prior_cov,
        });
        if self.history.len() > self.memory {
            self.history.pop_front();
        }
        Ok(())
    }

    fn current(&self) -> &Entry<NX, NU, NY, NP> {
        self.history.back().expect("never empty")
    }

    /// The entries from index `from` on corrected again and re-predicted.
    fn settle(&mut self, from: usize) -> Result<(), ObserverError> {
        for j in from..self.history.len() {
            if j > from {
                let (prior, prior_cov) = self.predict(&self.history[j - 1]);
                self.history[j].prior = prior;
                self.history[j].prior_cov = prior_cov;
            }
            let e = &self.history[j];
            let (mut x, mut p) = (e.prior, e.prior_cov);
            if let Some(y) = e.reading {
                (x, p) = update(e.k, &x, &p, &y, &self.noise.on_board, |z| {
                    self.readings.on_board(z)
                })?;
            }
            for pose in &e.poses {
                (x, p) = update(e.k, &x, &p, pose, &self.noise.pose, |z| {
                    self.readings.pose(z)
                })?;
            }
            let e = &mut self.history[j];
            e.estimate = x;
            e.cov = p;
        }
        Ok(())
    }

    /// The prediction from an entry with its input to the next sample.
    fn predict(&self, e: &Entry<NX, NU, NY, NP>) -> (SVector<f64, NX>, SMatrix<f64, NX, NX>) {
        let k = e.k;
        let u = e
            .input
            .expect("an entry before the current one has its input");
        let (a, b) = (&self.plan.a[k], &self.plan.b[k]);
        let x = self.states[k + 1] + a * (e.estimate - self.states[k]) + b * (u - self.inputs[k]);
        let p = a * e.cov * a.transpose() + self.noise.process;
        (x, (p + p.transpose()) * 0.5)
    }
}

/// The extended Kalman update of `(x, p)` by the reading `y = h(x) + noise` of covariance
/// `r`, in Joseph's form.
fn update<const NX: usize, const M: usize>(
    sample: usize,
    x: &SVector<f64, NX>,
    p: &SMatrix<f64, NX, NX>,
    y: &SVector<f64, M>,
    r: &SMatrix<f64, M, M>,
    h: impl Fn(
        &SVector<num_dual::DualVec<f64, nalgebra::Const<NX>>, NX>,
    ) -> SVector<num_dual::DualVec<f64, nalgebra::Const<NX>>, M>,
) -> Result<(SVector<f64, NX>, SMatrix<f64, NX, NX>), ObserverError> {
    let (hx, jac) = value_and_jacobian(h, x);
    let s = jac * p * jac.transpose() + r;
    let lu = Lu::new(&s).ok_or(ObserverError::SingularInnovation { sample })?;
    // K = P Hᵀ S⁻¹, with S symmetric: Kᵀ = S⁻¹ H P.
    let gain = lu.solve_columns(&(jac * p)).transpose();
    let x = x + gain * (y - hx);
    let i_kh = SMatrix::<f64, NX, NX>::identity() - gain * jac;
    let p = i_kh * p * i_kh.transpose() + gain * r * gain.transpose();
    let p = (p + p.transpose()) * 0.5;
    if !finite(x.iter().chain(p.iter())) {
        return Err(ObserverError::NotFinite { sample });
    }
    Ok((x, p))
}

fn finite<'b>(mut values: impl Iterator<Item = &'b f64>) -> bool {
    values.all(|v| v.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 13 ms + Exp(84 ms) redrawn beyond 148 ms has a mean of 63 ms (the WIP's paper's
    /// figure) and stays in its range; the tolerance is 4 standard errors of the mean of
    /// 20,000 draws (σ ≈ 35 ms).
    #[test]
    fn truncated_delay_has_its_mean_and_range() {
        let law = DelayLaw {
            min: 0.013,
            scale: 0.084,
            max: 0.148,
        };
        let mut rng = Rng::new(7);
        let n = 20_000;
        let draws: Vec<f64> = (0..n).map(|_| law.draw(&mut rng)).collect();
        let mean = draws.iter().sum::<f64>() / n as f64;
        assert!(draws.iter().all(|&d| (0.013..=0.148).contains(&d)));
        assert!(
            (mean - 0.063).abs() < 4.0 * 0.035 / (n as f64).sqrt(),
            "{mean}"
        );
        // Scaled, the mean scales; an empty range gives the minimum.
        let twice: f64 = (0..n).map(|_| law.scaled(2.0).draw(&mut rng)).sum::<f64>() / n as f64;
        assert!(
            (twice - 0.126).abs() < 8.0 * 0.035 / (n as f64).sqrt(),
            "{twice}"
        );
        let stuck = DelayLaw { max: 0.01, ..law };
        assert_eq!(stuck.draw(&mut rng), 0.013);
        assert_eq!(DelayLaw::samples_late(0.013, 0.02), 1);
        assert_eq!(DelayLaw::samples_late(0.0, 0.02), 0);
    }
}

//! The WIP as a [`Plant`] of the generic diagnosis: its channels and inputs, its catalogue
//! of effects, its prediction of a window (the [`Predictor`] and the sensors), and the
//! operating conditions worth testing its residual against.

use super::effects::{wip_catalogue, Layout};
use super::prediction::{Command, Predictor, Wheel, NZ};
use super::reversal_lockout::passed_fractions;
use crate::diagnose::conditions::{above_median, near_zero, positive};
use crate::diagnose::model::Catalogue;
use crate::diagnose::read_log::{parse_log, parse_log_limited, LogError};
use crate::diagnose::{
    ChannelSpec, FitScalar, Indicator, MeasuredLog, Plant, ReadingFamily, ReadingHypotheses,
};
use crate::wip::WipParams;
use nalgebra::SVector;

/// A measured channel of the WIP. The order is that of [`Predictor::readings`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Channel {
    X,
    Y,
    Theta,
    Alpha,
    VAlpha,
    PhiRRel,
    PhiLRel,
    IR,
    IL,
}

impl Channel {
    pub const ALL: [Channel; 9] = [
        Channel::X,
        Channel::Y,
        Channel::Theta,
        Channel::Alpha,
        Channel::VAlpha,
        Channel::PhiRRel,
        Channel::PhiLRel,
        Channel::IR,
        Channel::IL,
    ];
    /// The CSV column name.
    pub fn name(self) -> &'static str {
        [
            "x", "y", "theta", "alpha", "v_alpha", "phiR_rel", "phiL_rel", "iR", "iL",
        ][self.index()]
    }
    pub fn unit(self) -> &'static str {
        ["m", "m", "rad", "rad", "rad/s", "rad", "rad", "A", "A"][self.index()]
    }
    pub fn index(self) -> usize {
        self as usize
    }
    /// The largest magnitude a reading of this channel can physically have; a reading
    /// beyond it is a logging fault, not a measurement. Generous on purpose: a position of
    /// 10 km, a heading or wheel angle of 10⁶ rad (40 km of a 4 cm wheel), a tilt of 2π,
    /// a tilt rate of 10³ rad/s (gyros saturate near 35 rad/s), a current of 10³ A.
    pub fn range(self) -> f64 {
        [
            1e4,
            1e4,
            1e6,
            std::f64::consts::TAU,
            1e3,
            1e6,
            1e6,
            1e3,
            1e3,
        ][self.index()]
    }
    /// The largest zero-point offset a working sensor of this channel has (the plausible
    /// range of the generic `reading_offset` hypothesis; 0: none declared):
    /// - heading 0.3 rad, as the tilt's offset (`tilt_offset`): a pose system's frame
    ///   turned by more than 17° is a set-up error, not an offset;
    /// - tilt rate 0.5 rad/s: three times the zero-rate level a MEMS gyro of the Balboa's
    ///   class guarantees (±10 °/s, 0.17 rad/s);
    /// - currents 0.5 A: a current-sense amplifier's zero error, a sixteenth of the
    ///   paper motor's 8 A stall current at 12 V;
    /// - none on the pose's position and the wheel angles (a window's fitted state absorbs
    ///   a constant there) nor on the tilt (the catalogue's `tilt_offset` is that offset).
    pub fn offset_limit(self) -> f64 {
        match self {
            Channel::Theta => 0.3,
            Channel::VAlpha => 0.5,
            Channel::IR | Channel::IL => 0.5,
            _ => 0.0,
        }
    }
    pub fn spec(self) -> ChannelSpec {
        let mut s = ChannelSpec::new(self.name(), self.unit(), self.range());
        s.wraps = self == Channel::Theta;
        s.offset_limit = self.offset_limit();
        s
    }
}

/// The state components that enter a reading additively (state, channel): x, y and the
/// wheel angles enter only their own readings (translation and wheel rotation are
/// symmetries of the dynamics).
const ADDITIVE: [(usize, usize); 4] = [(0, 0), (1, 1), (4, 5), (5, 6)];

/// The generic reading hypotheses of the WIP's channels appended to its catalogue (after
/// the twelve effects of [`super::effects::Effect::ALL`]); the tilt's offset is the
/// catalogue's own `tilt_offset`.
pub fn declare_readings(cat: &mut Catalogue, channels: &[ChannelSpec]) -> ReadingHypotheses {
    ReadingHypotheses::declare(
        cat,
        channels,
        &ADDITIVE,
        &[(ReadingFamily::Offset, Channel::Alpha.name())],
    )
}

/// The WIP with parameters `params` and its catalogue.
pub struct WipPlant {
    pub params: WipParams,
    catalogue: Catalogue,
    layout: Layout,
    channels: Vec<ChannelSpec>,
    inputs: Vec<String>,
    readings: ReadingHypotheses,
}

/// The longest input delay the fit may reach (the catalogue's bound), for the rows kept
/// before the first window.
const MAX_DELAY: f64 = 0.1;

/// The bytes a row of a measured log is allowed (the twelve columns `wip generate` writes
/// take about 180), for the size limit of [`WipPlant::read_log`]: a log of a million rows
/// may have 256 MB, and one of ten million rows (400 MB) is refused from its size.
pub const LOG_ROW_BYTES: u64 = 256;

impl WipPlant {
    pub fn new(params: WipParams) -> Self {
        let mut catalogue = wip_catalogue(&params);
        let layout = Layout::new(&catalogue, &params);
        let channels: Vec<ChannelSpec> = Channel::ALL.iter().map(|c| c.spec()).collect();
        let readings = declare_readings(&mut catalogue, &channels);
        WipPlant {
            params,
            catalogue,
            layout,
            channels,
            inputs: vec!["uR".into(), "uL".into()],
            readings,
        }
    }

    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// Parse a measured log with the WIP's columns.
    pub fn parse_log(&self, text: &str, what: &str) -> Result<MeasuredLog, LogError> {
        parse_log(text, what, &self.channels, &self.inputs)
    }

    /// Refuse a log whose step the prediction model cannot follow: the model's predictions
    /// (the current algebraic) take RK4 substeps of at most
    /// [`super::prediction::MAX_SUBSTEP`] of the log's step `h`, which must stay within
    /// RK4's stability bound on the model's modes at rest, whose rates must be finite
    /// ([`crate::check::check_step`]).
    pub fn check_model(&self, h: f64) -> Result<(), crate::check::CheckError> {
        use crate::wip::algebraic_current::WipAlgebraicCurrent;
        let what = "diagnose: the model";
        let mut sys = crate::wip::Wip::new(self.params);
        let p = &self.params;
        sys.quasi_static_inertia = (p.k_e * p.n_wm).powi(2) * p.L_m / (p.R_m * p.R_m);
        let model = WipAlgebraicCurrent::new(sys);
        let x = dmech::continuous::ContinuousState {
            g: dmech_lie::Se2::new(0.0, 0.0, 0.0),
            s: SVector::<f64, 3>::zeros(),
            v: SVector::<f64, 3>::zeros(),
        };
        let modes = crate::check::linear_modes(&model, &x, &SVector::zeros(), what)?;
        let substep = super::prediction::MAX_SUBSTEP;
        let scheme = crate::check::Scheme {
            name: "rk4 in 8 substeps",
            ..crate::check::Scheme::from(dmech::Integrator::Rk4)
        };
        // Said of the log's step: its 8 substeps, the growth over all of them.
        crate::check::check_step(what, &modes, scheme, h * substep, "a log step", "").map_err(|e| {
            match e {
                crate::check::CheckError::Step {
                    h_max,
                    mode,
                    failure,
                    ..
                } => crate::check::CheckError::Step {
                    what,
                    scheme: scheme.name,
                    h,
                    mode,
                    h_max: h_max / substep,
                    option: "a log step",
                    alternative: "",
                    failure: match failure {
                        crate::check::StepFailure::Amplified { growth } => {
                            crate::check::StepFailure::Amplified {
                                growth: growth.powf(1.0 / substep),
                            }
                        }
                        f => f,
                    },
                },
                other => other,
            }
        })
    }

    /// Read a measured log of at most `max_rows` data rows: a file too large for that is
    /// refused from its size before it is read (`hint` says how to raise the limit).
    pub fn read_log(
        &self,
        path: &std::path::Path,
        max_rows: usize,
        hint: &str,
    ) -> Result<MeasuredLog, crate::io::ReadError> {
        let what = format!("{}", path.display());
        let limit = crate::io::csv_byte_limit(max_rows, LOG_ROW_BYTES);
        let text = crate::io::read_text_limited(path, &what, limit, hint)?;
        Ok(parse_log_limited(
            &text,
            &what,
            &self.channels,
            &self.inputs,
            max_rows,
            hint,
        )?)
    }

    /// The reversal lockout's passed fractions of both motors for the window, and the row
    /// of the first: from `history` rows before the window's start to its end
    /// (`passed_fractions` resynchronises its state before them); none without a lockout.
    fn passed<T: FitScalar>(
        &self,
        log: &MeasuredLog,
        start: usize,
        len: usize,
        lockout: T,
    ) -> (usize, Vec<[T; 2]>) {
        let h = log.h;
        let from = start.saturating_sub(self.history(h));
        if lockout.re() <= 0.0 {
            return (from, Vec::new());
        }
        let end = (start + len + 1).min(log.len());
        let per_motor = |m: usize| passed_fractions(|k| log.input(k)[m], from, end, lockout, h);
        let (r, l) = (per_motor(0), per_motor(1));
        (from, r.into_iter().zip(l).map(|(r, l)| [r, l]).collect())
    }

    /// An empty log with the WIP's inputs and channels.
    pub fn empty_log(h: f64) -> MeasuredLog {
        MeasuredLog::empty(h, 2, Channel::ALL.len())
    }
}

impl Plant for WipPlant {
    fn channels(&self) -> &[ChannelSpec] {
        &self.channels
    }
    fn inputs(&self) -> &[String] {
        &self.inputs
    }
    fn catalogue(&self) -> &Catalogue {
        &self.catalogue
    }
    fn state_dim(&self) -> usize {
        NZ
    }
    fn additive(&self) -> &[(usize, usize)] {
        &ADDITIVE
    }
    fn readings(&self) -> Option<&ReadingHypotheses> {
        Some(&self.readings)
    }
    fn history(&self, h: f64) -> usize {
        (MAX_DELAY / h).ceil() as usize + 2
    }

    /// Pose from the nearest pose sample, tilt and rate from the first readings, wheel
    /// rates from encoder differences.
    fn initial_state(&self, log: &MeasuredLog, s: usize, len: usize) -> Vec<f64> {
        let h = log.h;
        let near = |c: Channel| -> f64 {
            (s..(s + len).min(log.len()))
                .find_map(|k| log.value(k, c.index()))
                .unwrap_or(0.0)
        };
        let alpha = near(Channel::Alpha);
        let va = near(Channel::VAlpha);
        let rate = |c: Channel| -> f64 {
            let (a, b) = (s.saturating_sub(2), (s + 2).min(log.len() - 1));
            match (log.value(a, c.index()), log.value(b, c.index())) {
                (Some(x), Some(y)) if b > a => (y - x) / ((b - a) as f64 * h) + va,
                _ => 0.0,
            }
        };
        vec![
            near(Channel::X),
            near(Channel::Y),
            near(Channel::Theta),
            alpha,
            near(Channel::PhiRRel) + alpha,
            near(Channel::PhiLRel) + alpha,
            va,
            rate(Channel::PhiRRel),
            rate(Channel::PhiLRel),
        ]
    }

    fn predict<T: FitScalar>(
        &self,
        log: &MeasuredLog,
        start: usize,
        len: usize,
        z0: &[T],
        theta: &[T],
    ) -> Option<Vec<T>> {
        let ext = self.layout.extension(&self.params, theta);
        let pred = Predictor::new(ext);
        let h = log.h;
        let last = log.len() - 1;
        let (from, passed) = self.passed(log, start, len, pred.ext.lockout);
        let cmd = |k: usize| {
            let k = k.min(last);
            let u = log.input(k);
            let passed = match k.checked_sub(from).and_then(|i| passed.get(i)) {
                Some(&p) => p,
                None => [T::one(); 2],
            };
            Command {
                u: [u[0], u[1]],
                passed,
            }
        };
        let mut z = SVector::<T, NZ>::from_column_slice(z0);
        let slip = |w: T| Wheel::Slipping(if w.re() >= 0.0 { 1 } else { -1 });
        let mut modes = [slip(z[7] - z[6]), slip(z[8] - z[6])];
        let mut out = Vec::with_capacity(len * 9);
        let mut wdot = pred.wheel_acceleration(
            &z,
            pred.mean_applied(&cmd, start.saturating_sub(1), h),
            modes,
        )?;
        // The tilt reading through the firmware's complementary filter: the previous
        // reading plus the rate reading's increment, corrected towards the tilt with weight
        // `a` per sample (`a = 1`: the tilt itself). In this innovation form the residual is
        // `a` times the tilt's error and the accelerometer's noise, white; simulated from
        // the window's start instead, it would be that noise low-passed, which no white
        // noise test passes. Where the previous reading is missing, the predicted one
        // stands in.
        let a = pred.ext.accel_weight;
        let filtered = !(a - T::one()).vanishes();
        let (ai, vi) = (Channel::Alpha.index(), Channel::VAlpha.index());
        let mut filter = T::zero();
        for k in start..start + len {
            let mut y = pred.readings(&z, pred.current_voltage(&cmd, k, h), wdot);
            if filtered {
                let tilt = y[ai];
                filter = if k == start {
                    match log.value(k, ai) {
                        Some(r) => tilt * a + (T::one() - a) * r,
                        None => tilt,
                    }
                } else {
                    let g = log.value(k, vi).map_or(y[vi], T::from);
                    let prev = log.value(k - 1, ai).map_or(filter, T::from);
                    (prev + g * h) * (T::one() - a) + tilt * a
                };
                y[ai] = filter;
            }
            out.extend_from_slice(&y);
            if k + 1 < start + len {
                (z, wdot) = pred.advance(&z, &cmd, k, h, &mut modes)?;
            }
        }
        Some(out)
    }

    /// The lockout acts on a window only through its passed fractions: they stand for
    /// `lockout_s` in the key.
    fn window_key(&self, log: &MeasuredLog, start: usize, len: usize, theta: &[f64]) -> Vec<f64> {
        let mut key = theta.to_vec();
        let t = &mut key[self.layout.lockout()];
        let lockout = *t;
        *t = if lockout > 0.0 { 1.0 } else { 0.0 };
        key.extend(
            self.passed(log, start, len, lockout)
                .1
                .into_iter()
                .flatten(),
        );
        key
    }

    /// The pose, when its heading is the encoders' dead reckoning: in every row,
    /// `θₖ − θ₀ = r((φR,ₖ − φR,₀) − (φL,ₖ − φL,₀))/(2d)` to the rounding of the three
    /// columns as written (a firmware's odometry logged as the pose, as the REGBOT's).
    /// Its position is then that odometry's too (the same encoders, and without the
    /// axle's roll with the tilt that the model's position has).
    fn derived_channels(&self, log: &MeasuredLog) -> Vec<(usize, String)> {
        dead_reckoned_pose(log, &self.channels, self.params.r, self.params.d)
    }

    fn conditions(&self, log: &MeasuredLog) -> Vec<Indicator> {
        let n = log.len();
        // Mean wheel speed relative to the body, from the wheel-angle readings (central
        // differences over two rows).
        let wheel: Vec<Option<f64>> = (0..n)
            .map(|k| {
                let (mut s, mut m) = (0.0, 0);
                for c in [Channel::PhiRRel, Channel::PhiLRel] {
                    if k >= 1 && k + 1 < n {
                        if let (Some(y1), Some(y0)) =
                            (log.value(k + 1, c.index()), log.value(k - 1, c.index()))
                        {
                            s += (y1 - y0) / (2.0 * log.h);
                            m += 1;
                        }
                    }
                }
                (m > 0).then(|| s / m as f64)
            })
            .collect();
        let mut out = Vec::new();
        if wheel.iter().any(|w| w.is_some()) {
            out.extend(near_zero("wheel speed near zero (slowest quarter)", &wheel));
            out.push(positive("wheel speed positive", &wheel));
        }
        let u: Vec<Option<f64>> = (0..n)
            .map(|k| Some(0.5 * (log.input(k)[0] + log.input(k)[1]).abs()))
            .collect();
        out.extend(above_median("commanded voltage above its median", &u));
        // A reversal of the command within the last three rows (where lost motion in the
        // gears shows).
        let reversal: Vec<Option<f64>> = (0..n)
            .map(|k| {
                let s = |j: usize| (log.input(j)[0] + log.input(j)[1]).signum();
                Some(if k >= 3 && (k - 3..k).any(|j| s(j) != s(j + 1)) {
                    1.0
                } else {
                    -1.0
                })
            })
            .collect();
        out.push(positive(
            "commanded voltage reversed within three rows",
            &reversal,
        ));
        let tilt: Vec<Option<f64>> = (0..n)
            .map(|k| log.value(k, Channel::Alpha.index()))
            .collect();
        out.extend(above_median("tilt above its median", &tilt));
        out
    }
}

/// [`Plant::derived_channels`] of the WIP: the pose channels present, if the heading
/// reading equals the dead reckoning of the wheel angles (radius `r`, half track `d`) to
/// within the rounding of the columns as written and the heading turns by more than ten
/// times that bound somewhere (else the log cannot tell).
pub fn dead_reckoned_pose(
    log: &MeasuredLog,
    channels: &[ChannelSpec],
    r: f64,
    d: f64,
) -> Vec<(usize, String)> {
    let (th, pr, pl) = (
        Channel::Theta.index(),
        Channel::PhiRRel.index(),
        Channel::PhiLRel.index(),
    );
    let rows: Vec<usize> = (0..log.len())
        .filter(|&k| [th, pr, pl].iter().all(|&c| log.value(k, c).is_some()))
        .collect();
    let (Some(&first), Some(qt), Some(qr), Some(ql)) = (
        rows.first(),
        log.decimal_resolution(th),
        log.decimal_resolution(pr),
        log.decimal_resolution(pl),
    ) else {
        return Vec::new();
    };
    let k_turn = r / (2.0 * d);
    // A difference of two rounded readings is off by at most one resolution.
    let bound = qt + k_turn * (qr + ql);
    let reading = |k: usize, c: usize| log.row(k)[c] - log.row(first)[c];
    let mut turned: f64 = 0.0;
    for &k in &rows {
        let reckoned = k_turn * (reading(k, pr) - reading(k, pl));
        turned = turned.max(reckoned.abs());
        if channels[th].residual(reckoned, reading(k, th)).abs() > bound {
            return Vec::new();
        }
    }
    if turned <= 10.0 * bound {
        return Vec::new();
    }
    let why = format!(
        "is the dead reckoning of the wheel angles (the heading equals r(phiR_rel - phiL_rel)/(2d) \
         within {bound:.1e} rad, the columns' rounding, in all {} rows)",
        rows.len()
    );
    [Channel::X, Channel::Y, Channel::Theta]
        .iter()
        .filter(|c| log.present[c.index()])
        .map(|c| (c.index(), why.clone()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A log of `n` rows turning on the spot and rolling: wheel angles written to four
    /// decimals, the heading either their dead reckoning written to four decimals (a
    /// firmware's odometry) or that plus a measurement's noise.
    fn turning_log(heading_noise: f64) -> (MeasuredLog, Vec<ChannelSpec>) {
        let channels: Vec<ChannelSpec> = Channel::ALL.iter().map(|c| c.spec()).collect();
        let (r, d) = (0.04, 0.1);
        let round4 = |v: f64| (v * 1e4).round() / 1e4;
        let mut log = MeasuredLog::empty(0.01, 2, channels.len());
        for k in 0..300 {
            let t = 0.01 * k as f64;
            let (pr, pl) = (round4(3.0 * t + 0.2), round4(0.7 - t));
            // A deterministic, sign-changing disturbance of amplitude `heading_noise`.
            let noise = heading_noise * (7.3 * k as f64).sin();
            let theta = round4(r * ((pr - 0.2) - (pl - 0.7)) / (2.0 * d) + 0.05 + noise);
            let mut row = vec![f64::NAN; channels.len()];
            row[Channel::X.index()] = round4(0.01 * t);
            row[Channel::Y.index()] = round4(0.02 * t);
            row[Channel::Theta.index()] = theta;
            row[Channel::PhiRRel.index()] = pr;
            row[Channel::PhiLRel.index()] = pl;
            log.push_row(t, &[0.0, 0.0], &row);
        }
        log.channels_present_from_data();
        (log, channels)
    }

    #[test]
    fn a_heading_that_is_the_encoders_odometry_sets_the_pose_aside() {
        let (log, channels) = turning_log(0.0);
        let derived = dead_reckoned_pose(&log, &channels, 0.04, 0.1);
        let set_aside: Vec<usize> = derived.iter().map(|(c, _)| *c).collect();
        assert_eq!(
            set_aside,
            vec![
                Channel::X.index(),
                Channel::Y.index(),
                Channel::Theta.index()
            ]
        );
        // The wheel geometry decides: with another track the same log is a measurement.
        assert!(dead_reckoned_pose(&log, &channels, 0.04, 0.12).is_empty());
    }

    #[test]
    fn a_measured_heading_is_kept() {
        // Noise of 5 mrad (the generated logs' pose noise) is far above the columns'
        // rounding bound of 1e-4 (1 + 2 * 0.04 / 0.2) = 1.4e-4 rad.
        let (log, channels) = turning_log(5e-3);
        assert!(dead_reckoned_pose(&log, &channels, 0.04, 0.1).is_empty());
    }
}

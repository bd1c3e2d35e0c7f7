//! Hypotheses on the readings themselves, for any plant (docs/diagnose.md §2a): for each
//! channel `c` the plant declares, two small families of what goes wrong with a sensor,
//! an **offset** (`y_c = ŷ_c + b`, null `b = 0`) and a **scale** (`y_c = s ŷ_c`, null
//! `s = 1`), where `ŷ_c` is the plant's own prediction of the reading. They are built here
//! from the plant's channels ([`ReadingHypotheses::declare`]) and applied by the fit on top
//! of [`super::Plant::predict`] ([`ReadingHypotheses::apply`]), so a plant gets them by
//! declaring its readings; its own catalogue stays about its physics.
//!
//! Effect names say what and where: `reading_offset:<channel>`, `reading_scale:<channel>`
//! (docs/formats.md, "Effect names"); their parameters are `<channel>_offset` (in the
//! channel's unit) and `<channel>_scale` (dimensionless).
//!
//! Which channels get which family:
//! - no offset where a window state enters the reading additively
//!   ([`super::Plant::additive`]: a position along a symmetry, an integrated wheel angle):
//!   each window's fitted state absorbs any constant there, so the log cannot tell an
//!   offset; and none where the plant declares no offset limit
//!   ([`ChannelSpec::offset_limit`] zero) or lists the offset already in its own catalogue;
//! - a scale on every channel: `s ŷ` changes the reading's increments, which no window
//!   state absorbs.
//!
//! Physical ranges (the `plausible` check, §4b): an offset within the plant's declared
//! `±offset_limit` (the largest zero-point error a working sensor of that kind has); a
//! scale within [`SCALE_PLAUSIBLE`] `0.8–1.2`: a sensitivity off by more than 20 % is a
//! wrong configuration (a full-scale setting, counts per revolution, degrees for radians:
//! factors of 2, 8, 57), not a calibration error of a working sensor, whose sensitivity
//! tolerances are a few per cent.

use super::log::ChannelSpec;
use super::model::{Catalogue, ParamSpec};
use super::FitScalar;

/// The plausible range of a reading scale (see the module's documentation).
pub const SCALE_PLAUSIBLE: (f64, f64) = (0.8, 1.2);

/// A family of reading hypotheses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ReadingFamily {
    /// `y = ŷ + b`.
    Offset,
    /// `y = s ŷ`.
    Scale,
}

impl ReadingFamily {
    /// Both families, in the order they are declared per channel (offset, then scale).
    pub const ALL: [ReadingFamily; 2] = [ReadingFamily::Offset, ReadingFamily::Scale];

    /// The family's part of an effect name (before `:`).
    pub fn name(self) -> &'static str {
        match self {
            ReadingFamily::Offset => "reading_offset",
            ReadingFamily::Scale => "reading_scale",
        }
    }

    /// The parameter's value where the hypothesis is absent.
    pub fn null(self) -> f64 {
        match self {
            ReadingFamily::Offset => 0.0,
            ReadingFamily::Scale => 1.0,
        }
    }

    /// The effect's name at the channel `channel`: `reading_offset:v_alpha`.
    pub fn effect_name(self, channel: &str) -> String {
        format!("{}:{channel}", self.name())
    }

    /// The parameter's name at the channel `channel`: `v_alpha_offset`, `phiR_rel_scale`.
    pub fn param_name(self, channel: &str) -> String {
        match self {
            ReadingFamily::Offset => format!("{channel}_offset"),
            ReadingFamily::Scale => format!("{channel}_scale"),
        }
    }

    /// The family and channel of an effect name `family:channel` (`None` if it is not a
    /// reading hypothesis).
    pub fn parse(name: &str) -> Option<(ReadingFamily, &str)> {
        let (family, channel) = name.split_once(':')?;
        let f = ReadingFamily::ALL
            .into_iter()
            .find(|f| f.name() == family)?;
        (!channel.is_empty()).then_some((f, channel))
    }
}

/// Where the reading hypotheses' parameters sit in the catalogue: per channel, the index
/// of its offset and of its scale parameter (none where the family is not declared).
#[derive(Clone, Debug, Default)]
pub struct ReadingHypotheses {
    per_channel: Vec<[Option<usize>; 2]>,
}

impl ReadingHypotheses {
    /// Append the reading hypotheses of `channels` to `cat` (parameters and effects, in
    /// the channels' order, offset before scale): no offset on a channel that a state of
    /// `additive` enters, none where the channel declares no offset limit, and none of the
    /// `(family, channel)` pairs the plant's own catalogue already holds (`skip`).
    pub fn declare(
        cat: &mut Catalogue,
        channels: &[ChannelSpec],
        additive: &[(usize, usize)],
        skip: &[(ReadingFamily, &str)],
    ) -> Self {
        let mut per_channel = vec![[None, None]; channels.len()];
        for (c, spec) in channels.iter().enumerate() {
            for (i, family) in ReadingFamily::ALL.into_iter().enumerate() {
                if skip.contains(&(family, spec.name.as_str())) {
                    continue;
                }
                let param = match family {
                    ReadingFamily::Offset => {
                        let absorbed = additive.iter().any(|&(_, ch)| ch == c);
                        if absorbed || spec.offset_limit <= 0.0 {
                            continue;
                        }
                        let lim = spec.offset_limit;
                        let mut p = ParamSpec::linear(
                            &family.param_name(&spec.name),
                            0.0,
                            0.01 * lim,
                            (-lim, lim),
                        );
                        p.bounds = (-2.0 * lim, 2.0 * lim);
                        p
                    }
                    ReadingFamily::Scale => {
                        let mut p = ParamSpec::linear(
                            &family.param_name(&spec.name),
                            1.0,
                            0.01,
                            SCALE_PLAUSIBLE,
                        );
                        p.bounds = (0.5, 2.0);
                        p
                    }
                };
                let idx = cat.param(param);
                cat.effect_at_reading(&family.effect_name(&spec.name), vec![idx], c);
                per_channel[c][i] = Some(idx);
            }
        }
        ReadingHypotheses { per_channel }
    }

    /// The readings `y` (rows of `n_channels` values, the plant's prediction) with every
    /// declared offset and scale of `theta` applied: `s ŷ + b`. Channels whose parameters
    /// sit at their null values and carry no derivative are left untouched.
    pub fn apply<T: FitScalar>(&self, y: &mut [T], n_channels: usize, theta: &[T]) {
        for (c, [off, sc]) in self.per_channel.iter().enumerate() {
            let b = off.map(|p| theta[p]).filter(|b| !b.vanishes());
            let s = sc.map(|p| theta[p]).filter(|s| !(*s - T::one()).vanishes());
            if b.is_none() && s.is_none() {
                continue;
            }
            for row in y.chunks_mut(n_channels) {
                let scaled = s.map_or(row[c], |s| row[c] * s);
                row[c] = b.map_or(scaled, |b| scaled + b);
            }
        }
    }

    /// The coefficient with which a state that enters channel `c` additively enters the
    /// reading under `theta` (its scale; 1 without one).
    pub fn additive_coefficient(&self, c: usize, theta: &[f64]) -> f64 {
        self.per_channel
            .get(c)
            .and_then(|[_, s]| s.map(|p| theta[p]))
            .unwrap_or(1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::DualSVec64;

    fn channels() -> Vec<ChannelSpec> {
        let mut a = ChannelSpec::new("a", "m", 10.0);
        a.offset_limit = 0.5;
        let b = ChannelSpec::new("b", "m", 10.0);
        let mut c = ChannelSpec::new("c", "m", 10.0);
        c.offset_limit = 1.0;
        vec![a, b, c]
    }

    /// Offsets only where declared and not absorbed, scales everywhere; names say what
    /// and where and parse back.
    #[test]
    fn declared_families_and_names() {
        let mut cat = Catalogue::default();
        let r = ReadingHypotheses::declare(&mut cat, &channels(), &[(0, 2)], &[]);
        let names: Vec<&str> = cat.effects.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "reading_offset:a",
                "reading_scale:a",
                "reading_scale:b",
                "reading_scale:c"
            ]
        );
        assert_eq!(cat.effects[0].reading, Some(0));
        assert_eq!(cat.params[0].name, "a_offset");
        assert_eq!(
            ReadingFamily::parse("reading_scale:phiR_rel"),
            Some((ReadingFamily::Scale, "phiR_rel"))
        );
        assert_eq!(ReadingFamily::parse("tilt_offset"), None);
        assert_eq!(r.additive_coefficient(2, &[0.0, 1.0, 1.0, 1.03]), 1.03);
    }

    /// `s ŷ + b` in value and derivatives; null parameters leave the readings untouched.
    #[test]
    fn apply_offset_and_scale() {
        let mut cat = Catalogue::default();
        let r = ReadingHypotheses::declare(&mut cat, &channels(), &[], &[]);
        // a_offset, a_scale, b_scale, c_offset, c_scale
        type D = DualSVec64<2>;
        let theta: Vec<D> = vec![
            D::from(0.1).derivative(0),
            D::from(1.1).derivative(1),
            D::from(1.0),
            D::from(0.0),
            D::from(1.0),
        ];
        let mut y: Vec<D> = [2.0, 3.0, 4.0, 5.0, 6.0, 7.0].map(D::from).to_vec();
        r.apply(&mut y, 3, &theta);
        assert!((y[0].re - (1.1 * 2.0 + 0.1)).abs() < 1e-15);
        assert!((y[3].re - (1.1 * 5.0 + 0.1)).abs() < 1e-15);
        let g = y[3]
            .eps
            .unwrap_generic(nalgebra::Const::<2>, nalgebra::Const::<1>);
        assert_eq!((g[0], g[1]), (1.0, 5.0));
        assert_eq!(y[1].re, 3.0);
        assert_eq!(y[5].re, 7.0);
    }
}

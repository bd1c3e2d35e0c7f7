//! Parameters, effects and candidates. A plant's [`Catalogue`] lists every parameter the
//! diagnosis may free, each with its nominal value (where the effect is absent), a typical
//! change, the bounds a fit projects onto and the range that physics admits; an effect is a
//! group of parameters. A [`Candidate`] frees some effects and, after a calibration, some
//! directions of the system's own parameters.
//!
//! The fit works in internal coordinates `x`: `x_j = θ_j`, or `x_j = ln θ_j` for a
//! parameter marked `log` (a positive physical parameter, whose uncertainty is relative).
//! A candidate's free coordinates `β` move `x` along fixed directions, `x = x_ref + B β`.

/// One parameter of the catalogue.
#[derive(Clone, Debug)]
pub struct ParamSpec {
    /// The key in `diagnosis.json`.
    pub name: String,
    /// The value at which the effect is absent (for the system's own parameters: the
    /// parameter file's value).
    pub nominal: f64,
    /// Where a fit of the effect starts (the nominal value, unless the effect's
    /// derivative vanishes there, as for a threshold that switches a law on).
    pub start: f64,
    /// A typical change, for the fit's scaling (in `x`: relative for a `log` parameter).
    pub scale: f64,
    /// The fit projects onto `[lo, hi]`.
    pub bounds: (f64, f64),
    /// The physically admissible range: a candidate whose parameter ends outside is never
    /// named.
    pub plausible: (f64, f64),
    /// A floor under the standard deviation from the prediction model's own
    /// approximation, added in quadrature.
    pub systematic: f64,
    /// Fitted in `ln θ` (positive).
    pub log: bool,
    /// A time threshold that the plant decides at its sample instants: where it ends
    /// between two samples the log cannot tell, so the standard deviation has the floor
    /// `h/√12` of a value uniform over one step (added in quadrature).
    pub sampled_time: bool,
    /// Where the cost is multimodal in this parameter (a time threshold that switches
    /// events on and off), the values a fit first tries from `start`: it starts from the
    /// one with the lowest cost (empty: from `start`).
    pub start_grid: Vec<f64>,
}

impl ParamSpec {
    /// A parameter fitted as it is, with the same bounds and plausible range.
    pub fn linear(name: &str, nominal: f64, scale: f64, range: (f64, f64)) -> Self {
        ParamSpec {
            name: name.into(),
            nominal,
            start: nominal,
            scale,
            bounds: range,
            plausible: range,
            systematic: 0.0,
            log: false,
            sampled_time: false,
            start_grid: Vec::new(),
        }
    }
    /// A positive physical parameter fitted in `ln θ`; `rel_scale` is a typical relative
    /// change.
    pub fn positive(name: &str, nominal: f64, rel_scale: f64, plausible: (f64, f64)) -> Self {
        ParamSpec {
            name: name.into(),
            nominal,
            start: nominal,
            scale: rel_scale,
            bounds: (plausible.0.max(1e-300) * 0.5, plausible.1 * 2.0),
            plausible,
            systematic: 0.0,
            log: true,
            sampled_time: false,
            start_grid: Vec::new(),
        }
    }
    /// The internal coordinate `x` of `θ`: `ln θ` for a `log` parameter (`θ` floored at
    /// 1e-300), else `θ`.
    pub fn to_internal(&self, theta: f64) -> f64 {
        if self.log {
            theta.max(1e-300).ln()
        } else {
            theta
        }
    }
    /// `θ` of the internal coordinate `x` (in any scalar: the linearisation maps dual
    /// coordinates the same way).
    pub fn from_internal<T: dmech_lie::Real>(&self, x: T) -> T {
        if self.log {
            x.exp()
        } else {
            x
        }
    }
    /// `θ` clamped to the bounds.
    pub fn project(&self, theta: f64) -> f64 {
        theta.clamp(self.bounds.0, self.bounds.1)
    }
    /// Whether `θ` lies in the physically admissible range (false for NaN).
    pub fn is_plausible(&self, theta: f64) -> bool {
        !theta.is_nan() && theta >= self.plausible.0 && theta <= self.plausible.1
    }
}

/// An effect: a named group of parameters.
#[derive(Clone, Debug)]
pub struct EffectSpec {
    /// The effect's name in the verdict and `diagnosis.json` (e.g. `floor_slope`,
    /// `reading_offset:v_alpha`).
    pub name: String,
    /// Indices into [`Catalogue::params`].
    pub params: Vec<usize>,
    /// The channel a reading hypothesis acts on (`super::readings`); `None` for the
    /// plant's own effects. A reading hypothesis on a channel the log does not carry is
    /// left out of the candidates.
    pub reading: Option<usize>,
}

/// Everything a diagnosis may free.
#[derive(Clone, Debug, Default)]
pub struct Catalogue {
    /// Every parameter: the effects' and the system's own; a parameter vector `θ` is
    /// indexed alike.
    pub params: Vec<ParamSpec>,
    /// Every effect, the plant's and the declared reading hypotheses.
    pub effects: Vec<EffectSpec>,
    /// The system's own parameters a calibration may move (indices into `params`, all
    /// `log`). An effect whose parameters are all among them is a calibration of those
    /// parameters, and is left out of the candidates when they are calibrated.
    pub calibration: Vec<usize>,
}

impl Catalogue {
    /// Add a parameter; returns its index.
    pub fn param(&mut self, p: ParamSpec) -> usize {
        self.params.push(p);
        self.params.len() - 1
    }
    /// Add an effect over existing parameters; returns its index.
    pub fn effect(&mut self, name: &str, params: Vec<usize>) -> usize {
        self.effects.push(EffectSpec {
            name: name.into(),
            params,
            reading: None,
        });
        self.effects.len() - 1
    }
    /// Add a reading hypothesis on channel `channel`; returns its index.
    pub fn effect_at_reading(&mut self, name: &str, params: Vec<usize>, channel: usize) -> usize {
        let e = self.effect(name, params);
        self.effects[e].reading = Some(channel);
        e
    }
    /// The index of the effect named `name`; `None` if the catalogue has none.
    pub fn effect_index(&self, name: &str) -> Option<usize> {
        self.effects.iter().position(|e| e.name == name)
    }
    /// The index of the parameter named `name`; `None` if the catalogue has none.
    pub fn param_index(&self, name: &str) -> Option<usize> {
        self.params.iter().position(|p| p.name == name)
    }
    /// Every parameter at its nominal value: the system's own model with no effect.
    pub fn nominal(&self) -> Vec<f64> {
        self.params.iter().map(|p| p.nominal).collect()
    }
    /// Whether an effect only re-fits parameters that the calibration set holds.
    pub fn is_calibration_effect(&self, e: usize, calibrated: &[usize]) -> bool {
        !calibrated.is_empty()
            && self.effects[e]
                .params
                .iter()
                .all(|p| calibrated.contains(p))
    }
}

/// A direction in the internal coordinates of the parameters, sparse.
pub type Direction = Vec<(usize, f64)>;

/// A candidate model: the effects it frees and, after a calibration, the directions of the
/// system's own parameters that the log determines (in `ln θ`).
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    /// Indices of the effects freed, into [`Catalogue::effects`].
    pub effects: Vec<usize>,
    /// Directions of the calibrated combinations freed (empty without a calibration).
    pub calibration: Vec<Direction>,
}

impl Candidate {
    /// The nominal model: nothing free but the window states.
    pub fn none() -> Self {
        Candidate {
            effects: vec![],
            calibration: vec![],
        }
    }
    /// The effects `effects` freed, without calibration.
    pub fn of(effects: Vec<usize>) -> Self {
        Candidate {
            effects,
            calibration: vec![],
        }
    }
    /// The free directions: one per effect parameter, then the calibration's.
    pub fn directions(&self, cat: &Catalogue) -> Vec<Direction> {
        self.effects
            .iter()
            .flat_map(|&e| cat.effects[e].params.iter().map(|&p| vec![(p, 1.0)]))
            .chain(self.calibration.iter().cloned())
            .collect()
    }
    /// The number of free coordinates `β`: the effects' parameters and the calibrated
    /// directions (the `k` of the information criterion).
    pub fn n_free(&self, cat: &Catalogue) -> usize {
        self.effects
            .iter()
            .map(|&e| cat.effects[e].params.len())
            .sum::<usize>()
            + self.calibration.len()
    }
    /// A starting point for this candidate from a fitted model `theta`: the parameters of
    /// effects that `theta` leaves at their nominal value move to their start values.
    pub fn start_from(&self, cat: &Catalogue, theta: &[f64]) -> Vec<f64> {
        let mut t = theta.to_vec();
        for p in self.effect_params(cat) {
            let s = &cat.params[p];
            if t[p] == s.nominal {
                t[p] = s.start;
            }
        }
        t
    }
    /// The effects' parameter indices, in order.
    pub fn effect_params(&self, cat: &Catalogue) -> Vec<usize> {
        self.effects
            .iter()
            .flat_map(|&e| cat.effects[e].params.iter().copied())
            .collect()
    }
    /// `"none"`, or the effects joined by `+` (and `+calibration` when calibrated).
    pub fn name(&self, cat: &Catalogue) -> String {
        let mut parts: Vec<String> = self
            .effects
            .iter()
            .map(|&e| cat.effects[e].name.clone())
            .collect();
        if !self.calibration.is_empty() {
            parts.insert(0, "calibration".into());
        }
        if parts.is_empty() {
            "none".into()
        } else {
            parts.join("+")
        }
    }
    /// The effects' parameters of `theta` (full vector) outside their plausible range, in
    /// words; the calibrated parameters too.
    pub fn implausible(&self, cat: &Catalogue, theta: &[f64]) -> Vec<String> {
        let mut idx = self.effect_params(cat);
        for d in &self.calibration {
            for &(p, _) in d {
                if !idx.contains(&p) {
                    idx.push(p);
                }
            }
        }
        idx.iter()
            .filter(|&&p| !cat.params[p].is_plausible(theta[p]))
            .map(|&p| {
                let s = &cat.params[p];
                format!(
                    "{} = {:.4e} outside [{:.3e}, {:.3e}]",
                    s.name, theta[p], s.plausible.0, s.plausible.1
                )
            })
            .collect()
    }
}

/// Internal coordinates of a full parameter vector.
pub fn to_internal(cat: &Catalogue, theta: &[f64]) -> Vec<f64> {
    cat.params
        .iter()
        .zip(theta)
        .map(|(s, &t)| s.to_internal(t))
        .collect()
}

/// The full parameter vector of internal coordinates, projected onto the bounds.
pub fn from_internal(cat: &Catalogue, x: &[f64]) -> Vec<f64> {
    cat.params
        .iter()
        .zip(x)
        .map(|(s, &v)| s.project(s.from_internal(v)))
        .collect()
}

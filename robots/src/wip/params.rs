//! The WIP's parameters (docs/wip.md, table of parameters; the file format in
//! docs/formats.md): defaults, validation, and the JSON parameter file.

use crate::io::{JsonError, JsonObject};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Physical parameters, SI units. Generic over the scalar so that parameters can be dual
/// numbers (derivatives with respect to them). Field names are the keys of parameter files,
/// written in this order; a file may give any subset (`WipParams<Option<f64>>` reads it).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(
    deny_unknown_fields,
    bound(deserialize = "P: Deserialize<'de> + Default")
)]
#[allow(non_snake_case)]
pub struct WipParams<P = f64> {
    #[serde(default)]
    pub g: P,
    #[serde(default)]
    pub m_b: P,
    #[serde(default)]
    pub I_bxx: P,
    #[serde(default)]
    pub I_byy: P,
    #[serde(default)]
    pub I_bzz: P,
    #[serde(default)]
    pub m_w: P,
    #[serde(default)]
    pub I_wxx: P,
    #[serde(default)]
    pub I_wyy: P,
    #[serde(default)]
    pub I_wzz: P,
    #[serde(default)]
    pub l: P,
    #[serde(default)]
    pub r: P,
    #[serde(default)]
    pub d: P,
    #[serde(default)]
    pub d_v: P,
    #[serde(default)]
    pub d_c: P,
    #[serde(default)]
    pub d_0: P,
    #[serde(default)]
    pub I_m: P,
    #[serde(default)]
    pub I_g: P,
    #[serde(default)]
    pub n_wm: P,
    #[serde(default)]
    pub n_wg: P,
    #[serde(default)]
    pub k_e: P,
    #[serde(default)]
    pub L_m: P,
    #[serde(default)]
    pub R_m: P,
}

impl Default for WipParams<f64> {
    fn default() -> Self {
        WipParams {
            g: 9.81,
            m_b: 277e-3,
            I_bxx: 543.108e-6,
            I_byy: 481.457e-6,
            I_bzz: 153.951e-6,
            m_w: 28e-3,
            I_wxx: 4.957e-6,
            I_wyy: 7.411e-6,
            I_wzz: 4.957e-6,
            l: 48.67e-3,
            r: 33e-3,
            d: 49e-3,
            d_v: 1.532e-3,
            d_c: 32.6e-3,
            d_0: 8.0,
            I_m: 268.528e-9,
            I_g: 1.807e-6,
            n_wm: (78.0 / 11.0) * (78.0 / 11.0),
            n_wg: 78.0 / 11.0,
            k_e: 3.76e-3,
            L_m: 4e-4,
            R_m: 1.5,
        }
    }
}

impl<P: Copy> WipParams<P> {
    /// Apply `f` to every parameter (e.g. to lift them into another scalar).
    pub fn map<Q>(&self, f: impl Fn(P) -> Q) -> WipParams<Q> {
        self.zip(self, |a, _| f(a))
    }

    /// Combine two parameter sets key by key.
    pub fn zip<Q: Copy, R>(&self, other: &WipParams<Q>, f: impl Fn(P, Q) -> R) -> WipParams<R> {
        WipParams {
            g: f(self.g, other.g),
            m_b: f(self.m_b, other.m_b),
            I_bxx: f(self.I_bxx, other.I_bxx),
            I_byy: f(self.I_byy, other.I_byy),
            I_bzz: f(self.I_bzz, other.I_bzz),
            m_w: f(self.m_w, other.m_w),
            I_wxx: f(self.I_wxx, other.I_wxx),
            I_wyy: f(self.I_wyy, other.I_wyy),
            I_wzz: f(self.I_wzz, other.I_wzz),
            l: f(self.l, other.l),
            r: f(self.r, other.r),
            d: f(self.d, other.d),
            d_v: f(self.d_v, other.d_v),
            d_c: f(self.d_c, other.d_c),
            d_0: f(self.d_0, other.d_0),
            I_m: f(self.I_m, other.I_m),
            I_g: f(self.I_g, other.I_g),
            n_wm: f(self.n_wm, other.n_wm),
            n_wg: f(self.n_wg, other.n_wg),
            k_e: f(self.k_e, other.k_e),
            L_m: f(self.L_m, other.L_m),
            R_m: f(self.R_m, other.R_m),
        }
    }
}

impl<P: dmech_lie::Real> WipParams<P> {
    /// The motor current at steady state, `L_m i̇ = u − R_m i − k_e n_wm w` with `i̇ = 0`, for
    /// the voltage `u` at the wheel's rate relative to the body `w = φ̇ − α̇`, in any scalar
    /// the parameters lift to.
    pub fn steady_current<T: dmech::Lift<P>>(&self, u: T, w: T) -> T {
        (u - w.mul_param(self.k_e * self.n_wm)) / T::lift(self.R_m)
    }
}

impl WipParams<f64> {
    /// The parameters with their file keys.
    pub fn named_mut(&mut self) -> [(&'static str, &mut f64); 22] {
        [
            ("g", &mut self.g),
            ("m_b", &mut self.m_b),
            ("I_bxx", &mut self.I_bxx),
            ("I_byy", &mut self.I_byy),
            ("I_bzz", &mut self.I_bzz),
            ("m_w", &mut self.m_w),
            ("I_wxx", &mut self.I_wxx),
            ("I_wyy", &mut self.I_wyy),
            ("I_wzz", &mut self.I_wzz),
            ("l", &mut self.l),
            ("r", &mut self.r),
            ("d", &mut self.d),
            ("d_v", &mut self.d_v),
            ("d_c", &mut self.d_c),
            ("d_0", &mut self.d_0),
            ("I_m", &mut self.I_m),
            ("I_g", &mut self.I_g),
            ("n_wm", &mut self.n_wm),
            ("n_wg", &mut self.n_wg),
            ("k_e", &mut self.k_e),
            ("L_m", &mut self.L_m),
            ("R_m", &mut self.R_m),
        ]
    }

    /// Check that the parameters describe a physical robot: everything finite; masses,
    /// inertias of the body and wheels, wheel radius, half-track, gear ratios, motor
    /// constant, resistance, inductance and the friction slope `d_0` positive; rotor and
    /// gear inertias, friction coefficients and gravity non-negative (`l` may have either
    /// sign: the body's centre of mass may sit below the axle). Called where parameters
    /// come from a file; limiting cases (`R_m = 0`) stay constructible in code.
    pub fn validate(&self) -> Result<(), ParamError> {
        let mut p = *self;
        for (key, v) in p.named_mut() {
            let v = *v;
            let need = match key {
                "l" => Sign::Any,
                "I_m" | "I_g" | "d_v" | "d_c" | "g" => Sign::NonNegative,
                _ => Sign::Positive,
            };
            let ok = v.is_finite()
                && match need {
                    Sign::Any => true,
                    Sign::NonNegative => v >= 0.0,
                    Sign::Positive => v > 0.0,
                };
            if !ok {
                return Err(ParamError::OutOfRange {
                    key,
                    value: v,
                    need: need.text(),
                });
            }
        }
        Ok(())
    }

    /// Parse a JSON parameter file's text: an object with any subset of the keys; a key not
    /// given keeps its default. Malformed JSON (with its line and column), anything but an
    /// object, an unknown key, and a value that is not a number (`null` included: it is
    /// never read as "the default") are errors that name the key; then
    /// [`WipParams::validate`].
    pub fn from_json_str(text: &str) -> Result<Self, ParamError> {
        let mut p = WipParams::default();
        let keys: Vec<&str> = p.named_mut().iter().map(|(k, _)| *k).collect();
        let given = JsonObject::parse(text, &keys).map_err(|e| match e {
            JsonError::UnknownKey { key, .. } => ParamError::UnknownKey { key },
            other => ParamError::Json(other),
        })?;
        for (key, v) in p.named_mut() {
            if let Some(x) = given.number(key).map_err(|e| match e {
                JsonError::WrongType { found, .. } => ParamError::NotANumber { key, found },
                other => ParamError::Json(other),
            })? {
                *v = x;
            }
        }
        p.validate()?;
        Ok(p)
    }

    /// The parameter file of these parameters (every key, in the documented order).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a struct of numbers") + "\n"
    }

    /// Read a parameter file (JSON).
    pub fn from_file(path: &Path) -> Result<Self, crate::io::ReadError> {
        let what = format!("parameter file {}", path.display());
        let text = crate::io::read_text_limited(path, &what, crate::io::MAX_JSON_BYTES, "")?;
        Self::from_json_str(&text)
            .map_err(|e| crate::io::ReadError::Content(format!("{what}: {e}")))
    }
}

#[derive(Clone, Copy)]
enum Sign {
    Any,
    NonNegative,
    Positive,
}

impl Sign {
    fn text(self) -> &'static str {
        match self {
            Sign::Any => "finite",
            Sign::NonNegative => "finite and ≥ 0",
            Sign::Positive => "finite and > 0",
        }
    }
}

/// Why a parameter set was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParamError {
    /// Not JSON (serde's message, with line and column), or not an object.
    #[error("{0}")]
    Json(JsonError),
    /// A key that is not a parameter.
    #[error("unknown parameter '{key}' (`wip params` lists the keys)")]
    UnknownKey { key: String },
    /// A value that is not a finite number.
    #[error("parameter '{key}' must be a number, got {found}")]
    NotANumber { key: &'static str, found: String },
    /// A value outside its physical range.
    #[error("parameter '{key}' must be {need}, got {value}")]
    OutOfRange {
        key: &'static str,
        value: f64,
        need: &'static str,
    },
}

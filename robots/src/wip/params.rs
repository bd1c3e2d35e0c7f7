//! The WIP's parameters (model.md, table "WIP model parameters"), loadable from JSON.

use dmech::Lift;
use dmech_lie::Real;
use serde::Deserialize;
use std::path::Path;

/// Physical parameters, SI units. Generic over the scalar so that parameters can be dual
/// numbers (derivatives with respect to them). Field names are the keys of parameter files.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
#[allow(non_snake_case)]
pub struct WipParams<P = f64> {
    pub g: P,
    pub m_b: P,
    pub I_bxx: P,
    pub I_byy: P,
    pub I_bzz: P,
    pub m_w: P,
    pub I_wxx: P,
    pub I_wyy: P,
    pub I_wzz: P,
    pub l: P,
    pub r: P,
    pub d: P,
    pub d_v: P,
    pub d_c: P,
    pub d_0: P,
    pub I_m: P,
    pub I_g: P,
    pub n_wm: P,
    pub n_wg: P,
    pub k_e: P,
    pub L_m: P,
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
        WipParams {
            g: f(self.g),
            m_b: f(self.m_b),
            I_bxx: f(self.I_bxx),
            I_byy: f(self.I_byy),
            I_bzz: f(self.I_bzz),
            m_w: f(self.m_w),
            I_wxx: f(self.I_wxx),
            I_wyy: f(self.I_wyy),
            I_wzz: f(self.I_wzz),
            l: f(self.l),
            r: f(self.r),
            d: f(self.d),
            d_v: f(self.d_v),
            d_c: f(self.d_c),
            d_0: f(self.d_0),
            I_m: f(self.I_m),
            I_g: f(self.I_g),
            n_wm: f(self.n_wm),
            n_wg: f(self.n_wg),
            k_e: f(self.k_e),
            L_m: f(self.L_m),
            R_m: f(self.R_m),
        }
    }
    /// The parameters in scalar `T`.
    pub fn lift<T: Lift<P>>(&self) -> WipParams<T>
    where
        P: Real,
    {
        self.map(T::lift)
    }
}

impl WipParams<f64> {
    /// Parse a JSON parameter file's text: any subset of the keys; an unknown key, a
    /// non-number, or a non-finite value is an error naming it.
    pub fn from_json_str(text: &str) -> Result<Self, String> {
        let p: WipParams<f64> = serde_json::from_str(text).map_err(|e| e.to_string())?;
        p.validate()?;
        Ok(p)
    }

    /// Read a parameter file (JSON).
    pub fn from_file(path: &Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("cannot read parameter file {}: {e}", path.display()))?;
        Self::from_json_str(&text).map_err(|e| format!("parameter file {}: {e}", path.display()))
    }

    fn validate(&self) -> Result<(), String> {
        let named = [
            ("g", self.g),
            ("m_b", self.m_b),
            ("I_bxx", self.I_bxx),
            ("I_byy", self.I_byy),
            ("I_bzz", self.I_bzz),
            ("m_w", self.m_w),
            ("I_wxx", self.I_wxx),
            ("I_wyy", self.I_wyy),
            ("I_wzz", self.I_wzz),
            ("l", self.l),
            ("r", self.r),
            ("d", self.d),
            ("d_v", self.d_v),
            ("d_c", self.d_c),
            ("d_0", self.d_0),
            ("I_m", self.I_m),
            ("I_g", self.I_g),
            ("n_wm", self.n_wm),
            ("n_wg", self.n_wg),
            ("k_e", self.k_e),
            ("L_m", self.L_m),
            ("R_m", self.R_m),
        ];
        for (k, v) in named {
            if !v.is_finite() {
                return Err(format!("parameter '{k}' is not finite"));
            }
        }
        for (k, v) in [
            ("m_b", self.m_b),
            ("m_w", self.m_w),
            ("r", self.r),
            ("d", self.d),
            ("L_m", self.L_m),
        ] {
            if v <= 0.0 {
                return Err(format!("parameter '{k}' must be positive, got {v}"));
            }
        }
        Ok(())
    }
}

//! The WIP's parameters (model.md, table "WIP model parameters"), loadable from JSON.

use std::path::Path;

/// Physical parameters, SI units. Generic over the scalar so that parameters can be dual
/// numbers (derivatives with respect to them). Field names are the keys of parameter files.
#[derive(Clone, Copy, Debug, PartialEq)]
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

    /// Parse a JSON parameter file's text: an object with any subset of the keys; a key not
    /// given keeps its default. An unknown key, a value that is not a finite number, or a
    /// non-positive mass, radius, half-track or inductance is an error naming the key.
    pub fn from_json_str(text: &str) -> Result<Self, String> {
        let value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| format!("not valid JSON: {e}"))?;
        let obj = value
            .as_object()
            .ok_or("expected a JSON object of parameter names and numbers")?;
        let mut p = WipParams::default();
        for (key, v) in obj {
            let mut named = p.named_mut();
            let slot = named
                .iter_mut()
                .find(|(k, _)| k == key)
                .ok_or_else(|| format!("unknown parameter '{key}'"))?;
            let x = v
                .as_f64()
                .filter(|x| x.is_finite())
                .ok_or_else(|| format!("parameter '{key}' must be a finite number, got {v}"))?;
            *slot.1 = x;
        }
        for (k, v) in [
            ("m_b", p.m_b),
            ("m_w", p.m_w),
            ("r", p.r),
            ("d", p.d),
            ("L_m", p.L_m),
        ] {
            if v <= 0.0 {
                return Err(format!("parameter '{k}' must be positive, got {v}"));
            }
        }
        Ok(p)
    }

    /// Read a parameter file (JSON).
    pub fn from_file(path: &Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("cannot read parameter file {}: {e}", path.display()))?;
        Self::from_json_str(&text).map_err(|e| format!("parameter file {}: {e}", path.display()))
    }
}

//! The WIP's energy and momentum-like quantities, for tests and tools.

use super::{Wip, WipParams};
use nalgebra::SVector;

/// Energy `E = T + m_b g l cos α` (with `½ L_m i²` in `T`; the back-EMF term of `V` is
/// velocity-linear and stores no energy), at shape `s` and shape velocity `v`.
pub fn energy(w: &Wip, s: &SVector<f64, 5>, v: &SVector<f64, 5>) -> f64 {
    dmech::energy(w, s, v)
}

/// The electromechanical momentum (flux linkage) of each side, `L_m i + k_e n_wm (φ − α)`:
/// conserved by the continuous model when `u = 0` and `R_m = 0`.
pub fn flux_linkage(p: &WipParams, s: &SVector<f64, 5>, v: &SVector<f64, 5>) -> [f64; 2] {
    let ken = p.k_e * p.n_wm;
    [
        p.L_m * v[3] + ken * (s[1] - s[0]),
        p.L_m * v[4] + ken * (s[2] - s[0]),
    ]
}

/// Its discrete counterpart for the variational integrator, which pairs the current of
/// interval `k` with the angles at node `k + 1`: `L_m i_k + k_e n_wm (φ − α)_{k+1}` with
/// `s_{k+1} = s_k + h v_k`. Conserved exactly (to Newton's tolerance) when `u = 0`, `R_m = 0`.
pub fn discrete_flux_linkage(
    p: &WipParams,
    h: f64,
    s: &SVector<f64, 5>,
    v: &SVector<f64, 5>,
) -> [f64; 2] {
    flux_linkage(p, &(s + v * h), v)
}

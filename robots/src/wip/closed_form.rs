//! A hand-derived closed form of the WIP's continuous model (the paper's Appendix
//! "Nonlinear state space model"): `M(q) q̈ + K(q, q̇) + P(q, q̇) = 𝓕 + A_cᵀλ`, projected
//! with `q̇ = S(q) ν`. Used only to check the generic path (`dmech::continuous`).
//! The derivation is in `docs/wip-model.md`.

use super::model::friction;
use super::params::WipParams;
use dmech::Param;
use nalgebra::{SMatrix, SVector};

type M8 = SMatrix<f64, 8, 8>;
type V8 = SVector<f64, 8>;

/// `Ẋ = f(X, u)`, `X = (x, y, θ, α, v_α, v_d, v_θ, iR, iL)`, `u = (uR, uL)`.
pub fn state_derivative(
    p: &WipParams,
    x: &SVector<f64, 9>,
    u: &SVector<f64, 2>,
) -> SVector<f64, 9> {
    let th = x[2];
    let al = x[3];
    let nu = SVector::<f64, 5>::new(x[4], x[5], x[6], x[7], x[8]);
    let (st, ct) = th.sin_cos();
    let (sa, ca) = al.sin_cos();
    let (r, d, l) = (p.r, p.d, p.l);

    // q̇ = S ν.
    let mut s = SMatrix::<f64, 8, 5>::zeros();
    s[(0, 1)] = ct;
    s[(1, 1)] = st;
    s[(2, 2)] = 1.0;
    s[(3, 0)] = 1.0;
    s[(4, 1)] = 1.0 / r;
    s[(4, 2)] = d / r;
    s[(5, 1)] = 1.0 / r;
    s[(5, 2)] = -d / r;
    s[(6, 3)] = 1.0;
    s[(7, 4)] = 1.0;
    let qd: V8 = s * nu;
    let (xd, yd, thd, ald) = (qd[0], qd[1], qd[2], qd[3]);
    let (phrd, phld, ir, il) = (qd[4], qd[5], qd[6], qd[7]);
    // Ṡ: only the (x, y) rows of the v_d column depend on θ.
    let mut sdot = SMatrix::<f64, 8, 5>::zeros();
    sdot[(0, 1)] = -st * thd;
    sdot[(1, 1)] = ct * thd;

    // Mass matrix (T = ½ q̇ᵀ M q̇).
    let mt = p.m_b + 2.0 * p.m_w;
    let mbl = p.m_b * l;
    let j_theta = (p.m_b * l * l + p.I_bxx) * sa * sa
        + p.I_bzz * ca * ca
        + 2.0 * p.m_w * d * d
        + 2.0 * p.I_wzz;
    let dj_theta = 2.0 * (p.m_b * l * l + p.I_bxx - p.I_bzz) * sa * ca;
    let (nm, ng) = (p.n_wm, p.n_wg);
    let m_aphi = p.I_m * (1.0 - nm) * nm - p.I_g * (1.0 + ng) * ng;
    let m_phiphi = p.I_wyy + p.I_m * nm * nm + p.I_g * ng * ng;
    let m_aa = p.m_b * l * l
        + p.I_byy
        + 2.0 * (p.I_m * (1.0 - nm) * (1.0 - nm) + p.I_g * (1.0 + ng) * (1.0 + ng));
    let mut m = M8::zeros();
    m[(0, 0)] = mt;
    m[(1, 1)] = mt;
    m[(0, 2)] = -mbl * sa * st;
    m[(1, 2)] = mbl * sa * ct;
    m[(0, 3)] = mbl * ca * ct;
    m[(1, 3)] = mbl * ca * st;
    m[(2, 2)] = j_theta;
    m[(3, 3)] = m_aa;
    m[(3, 4)] = m_aphi;
    m[(3, 5)] = m_aphi;
    m[(4, 4)] = m_phiphi;
    m[(5, 5)] = m_phiphi;
    m[(6, 6)] = p.L_m;
    m[(7, 7)] = p.L_m;
    for i in 0..8 {
        for j in 0..i {
            m[(i, j)] = m[(j, i)];
        }
    }

    // K = Ṁ q̇ − ∂T/∂q (velocity-quadratic terms).
    let mut k = V8::zeros();
    k[0] = -mbl * (sa * ct * (ald * ald + thd * thd) + 2.0 * ca * st * ald * thd);
    k[1] = mbl * (-sa * st * (ald * ald + thd * thd) + 2.0 * ca * ct * ald * thd);
    k[2] = dj_theta * ald * thd;
    k[3] = -0.5 * dj_theta * thd * thd;

    // P = −d/dt ∂V/∂q̇ + ∂V/∂q (gravity and back-EMF).
    let ken = p.k_e * nm;
    let mut pv = V8::zeros();
    pv[3] = ken * (ir + il) - p.m_b * p.g * l * sa;
    pv[4] = -ken * ir;
    pv[5] = -ken * il;
    pv[6] = ken * (phrd - ald);
    pv[7] = ken * (phld - ald);

    // 𝓕: friction and the motor circuits.
    let q = p.map(Param);
    let fr = friction(q.d_v, q.d_c, q.d_0, phrd - ald);
    let fl = friction(q.d_v, q.d_c, q.d_0, phld - ald);
    let mut f = V8::zeros();
    f[3] = fr + fl;
    f[4] = -fr;
    f[5] = -fl;
    f[6] = u[0] - p.R_m * ir;
    f[7] = u[1] - p.R_m * il;

    // ν̇ = −(SᵀMS)⁻¹ Sᵀ (M Ṡ ν + K + P − 𝓕).
    let sms = s.transpose() * m * s;
    let rhs = s.transpose() * (m * sdot * nu + k + pv - f);
    let nud = -(sms.lu().solve(&rhs).expect("SᵀMS is positive definite"));
    SVector::<f64, 9>::from_column_slice(&[
        xd, yd, thd, ald, nud[0], nud[1], nud[2], nud[3], nud[4],
    ])
}

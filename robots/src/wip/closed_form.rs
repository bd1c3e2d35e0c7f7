//! A hand-derived closed form of the WIP's continuous model (the paper's Appendix
//! "Nonlinear state space model"): `M(q) q̈ + K(q, q̇) + P(q, q̇) = 𝓕 + A_cᵀλ`, projected
//! with `q̇ = S(q) ν`. `state_derivative` checks the generic path (`dmech::continuous`);
//! `shape_acceleration` is the fast evaluation `wip diagnose` differentiates. The
//! derivation is in `docs/wip-model.md`.

use super::model::{friction, tanh_saturating, Wip};
use super::params::WipParams;
use dmech::Param;
use dmech_lie::Real;
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

/// The shape accelerations `(α̈, φ̈R, φ̈L)` of the mechanical part of the closed form, for
/// any scalar and with everything a [`Wip`] can carry besides the table (wheel radius
/// offsets, the quasi-static inertia `J_e`) and an external force `f_shape` on
/// `(α, φR, φL)`, given the currents `i`. The equations do not depend on the pose (SE(2)
/// symmetry), so they are evaluated at `θ = 0`, where `Ṡ ν` has only the `y` entry
/// `v_θ v_d`. `wip diagnose` differentiates its predictions with respect to the initial
/// state and the effect parameters through this function (dual numbers with up to 17
/// directions); the generic path differentiates `ℓ` by nested duals and costs ~40 times
/// more there. The test `closed_form_with_extensions_equals_generic_path` checks it against
/// `dmech::continuous::acceleration_with_force`.
pub fn shape_acceleration<T: Real>(
    sys: &Wip<T>,
    alpha: T,
    w: [T; 3],
    i: [T; 2],
    f_shape: [T; 3],
) -> Option<[T; 3]> {
    let p = &sys.params;
    let (va, vr, vl) = (w[0], w[1], w[2]);
    let r_r = p.r + sys.wheel_radius_offsets[0];
    let r_l = p.r + sys.wheel_radius_offsets[1];
    // ν = (v_α, v_d, v_θ) from the wheel rates.
    let vd = (r_r * vr + r_l * vl) * 0.5;
    let vt = (r_r * vr - r_l * vl) / (p.d * 2.0);
    let (sa, ca) = alpha.sin_cos();
    let mbl = p.m_b * p.l;
    let mt = p.m_b + p.m_w * 2.0;
    let j_theta = (p.m_b * p.l * p.l + p.I_bxx) * sa * sa
        + p.I_bzz * ca * ca
        + p.m_w * p.d * p.d * 2.0
        + p.I_wzz * 2.0;
    let dj_theta = (p.m_b * p.l * p.l + p.I_bxx - p.I_bzz) * sa * ca * 2.0;
    let (nm, ng) = (p.n_wm, p.n_wg);
    let one = T::one();
    let je = sys.quasi_static_inertia;
    let m_aphi = p.I_m * (one - nm) * nm - p.I_g * (one + ng) * ng + je;
    let m_phiphi = p.I_wyy + p.I_m * nm * nm + p.I_g * ng * ng - je;
    let m_aa = p.m_b * p.l * p.l
        + p.I_byy
        + (p.I_m * (one - nm) * (one - nm) + p.I_g * (one + ng) * (one + ng)) * 2.0
        - je * 2.0;

    // q = (x, y, θ, α, φR, φL) at θ = 0: M (symmetric), S (q̇ = S ν).
    let z = T::zero();
    let mut m = SMatrix::<T, 6, 6>::from_element(z);
    m[(0, 0)] = mt;
    m[(1, 1)] = mt;
    m[(1, 2)] = mbl * sa;
    m[(0, 3)] = mbl * ca;
    m[(2, 2)] = j_theta;
    m[(3, 3)] = m_aa;
    m[(3, 4)] = m_aphi;
    m[(3, 5)] = m_aphi;
    m[(4, 4)] = m_phiphi;
    m[(5, 5)] = m_phiphi;
    for a in 0..6 {
        for b in 0..a {
            m[(a, b)] = m[(b, a)];
        }
    }
    let mut s = SMatrix::<T, 6, 3>::from_element(z);
    s[(0, 1)] = one;
    s[(2, 2)] = one;
    s[(3, 0)] = one;
    s[(4, 1)] = one / r_r;
    s[(4, 2)] = p.d / r_r;
    s[(5, 1)] = one / r_l;
    s[(5, 2)] = -p.d / r_l;

    // K (velocity-quadratic), P (gravity, back-EMF torque), 𝓕 (friction, f_shape).
    let mut rhs = SVector::<T, 6>::from_element(z);
    for a in 0..6 {
        rhs[a] = m[(a, 1)] * (vt * vd);
    }
    rhs[0] -= mbl * sa * (va * va + vt * vt);
    rhs[1] += mbl * ca * va * vt * 2.0;
    rhs[2] += dj_theta * va * vt;
    rhs[3] -= dj_theta * vt * vt * 0.5;
    let ken = p.k_e * nm;
    rhs[3] += ken * (i[0] + i[1]) - p.m_b * p.g * p.l * sa;
    rhs[4] -= ken * i[0];
    rhs[5] -= ken * i[1];
    let fric = |wrel: T| p.d_v * wrel + p.d_c * tanh_saturating(p.d_0 * wrel);
    let (fr, fl) = (fric(vr - va), fric(vl - va));
    rhs[3] -= fr + fl + f_shape[0];
    rhs[4] -= -fr + f_shape[1];
    rhs[5] -= -fl + f_shape[2];

    // ν̇ = −(SᵀMS)⁻¹ Sᵀ (M Ṡ ν + K + P − 𝓕).
    let st = s.transpose();
    let sms = st * m * s;
    let nud = -dmech::linalg::solve(&sms, &(st * rhs))?;
    Some([
        nud[0],
        (nud[1] + p.d * nud[2]) / r_r,
        (nud[1] - p.d * nud[2]) / r_l,
    ])
}

//! A hand-derived closed form of the WIP's continuous model (the paper's Appendix
//! "Nonlinear state space model"): `M(q) q̈ + K(q, q̇) + P(q, q̇) = 𝓕 + A_cᵀλ`, projected
//! with `q̇ = S(q) ν` (at `θ = 0`: the equations are SE(2)-invariant). It checks the generic
//! path (`dmech::continuous`), and `shape_acceleration` is the fast evaluation that
//! `wip diagnose` and the planner's Runge–Kutta transcriptions differentiate
//! (`PrincipalKinematicSystem::closed_form_acceleration`). The derivation is in
//! `docs/wip.md`.

use super::model::{friction, Wip};
use super::params::WipParams;
use dmech_lie::Real;
use nalgebra::{SMatrix, SVector};

/// `Ẋ = f(X, u)`, `X = (x, y, θ, α, v_α, v_d, v_θ, iR, iL)`, `u = (uR, uL)`: the pose
/// rates, the mechanical accelerations of [`shape_acceleration`] in `(v̇_d, v̇_θ)`, and the
/// motor circuits `L_m i̇ = u − R_m i − k_e n_wm (φ̇ − α̇)`. `None` where the projected
/// mass matrix `SᵀMS` cannot be factorised: at a state that is not finite (a diverged
/// simulation), never at a finite state of a physical robot, where it is positive definite.
pub fn state_derivative(
    p: &WipParams,
    x: &SVector<f64, 9>,
    u: &SVector<f64, 2>,
) -> Option<SVector<f64, 9>> {
    let (th, al) = (x[2], x[3]);
    let (va, vd, vt, ir, il) = (x[4], x[5], x[6], x[7], x[8]);
    let (phrd, phld) = ((vd + p.d * vt) / p.r, (vd - p.d * vt) / p.r);
    let a = shape_acceleration(&Wip::new(*p), al, [va, phrd, phld], [ir, il], [0.0; 3])?;
    let di = |u: f64, i: f64, phid: f64| current_rate(p, u, i, phid - va);
    Some(SVector::<f64, 9>::from_column_slice(&[
        vd * th.cos(),
        vd * th.sin(),
        vt,
        va,
        a[0],
        p.r * (a[1] + a[2]) / 2.0,
        p.r * (a[1] - a[2]) / (2.0 * p.d),
        di(u[0], ir, phrd),
        di(u[1], il, phld),
    ]))
}

/// `i̇` of a motor circuit, `L_m i̇ = u − R_m i − k_e n_wm w`, at voltage `u`, current `i` and
/// the wheel's rate relative to the body `w = φ̇ − α̇`.
pub fn current_rate<T: Real>(p: &WipParams<T>, u: T, i: T, w: T) -> T {
    (u - p.R_m * i - (p.k_e * p.n_wm) * w) / p.L_m
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
    shape_acceleration_with_response::<T, 0>(sys, alpha, w, i, f_shape, []).map(|(a, _)| a)
}

/// [`shape_acceleration`] and, with the same factorisation, the response of the shape
/// accelerations to each unit generalised force `dirs[j]` on `(α, φR, φL)` (the
/// accelerations are affine in the force): `wip diagnose`'s stick-slip law needs the
/// torque that holds a wheel at rest relative to the body.
pub fn shape_acceleration_with_response<T: Real, const K: usize>(
    sys: &Wip<T>,
    alpha: T,
    w: [T; 3],
    i: [T; 2],
    f_shape: [T; 3],
    dirs: [[T; 3]; K],
) -> Option<([T; 3], [[T; 3]; K])> {
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

    // q = (x, y, θ, α, φR, φL) at θ = 0, q̇ = S ν with the columns of S
    //   S₀ = e_α,   S₁ = e_x + e_φR / r_R + e_φL / r_L,   S₂ = e_θ + (d/r_R) e_φR − (d/r_L) e_φL,
    // and M's entries: M_xx = M_yy = m_t, M_yθ = m_b l sin α, M_xα = m_b l cos α, M_θθ = J_θ,
    // M_αα, M_αφ (both wheels), M_φφ (both wheels); every other entry is zero. SᵀMS and Sᵀ(·)
    // are written out on these nonzeros: as dense products of dual-number matrices they
    // were most of `wip diagnose`'s time.
    let z = T::zero();
    let (inv_r, inv_l) = (one / r_r, one / r_l);
    let (d_r, d_l) = (p.d * inv_r, p.d * inv_l);
    let s_transpose = |v: [T; 6]| {
        [
            v[3],
            v[0] + v[4] * inv_r + v[5] * inv_l,
            v[2] + v[4] * d_r - v[5] * d_l,
        ]
    };
    let sms01 = mbl * ca + m_aphi * (inv_r + inv_l);
    let sms02 = m_aphi * (d_r - d_l);
    let sms12 = m_phiphi * (d_r * inv_r - d_l * inv_l);
    let sms = SMatrix::<T, 3, 3>::new(
        m_aa,
        sms01,
        sms02,
        sms01,
        mt + m_phiphi * (inv_r * inv_r + inv_l * inv_l),
        sms12,
        sms02,
        sms12,
        j_theta + m_phiphi * (d_r * d_r + d_l * d_l),
    );

    // K (velocity-quadratic), P (gravity, back-EMF torque), 𝓕 (friction, f_shape). The
    // M Ṡ ν term: Ṡ ν at θ = 0 is v_θ v_d along y, so it is M's y column times v_θ v_d.
    let vtvd = vt * vd;
    let mut rhs = [z; 6];
    rhs[1] = mt * vtvd;
    rhs[2] = mbl * sa * vtvd;
    rhs[0] -= mbl * sa * (va * va + vt * vt);
    rhs[1] += mbl * ca * va * vt * 2.0;
    rhs[2] += dj_theta * va * vt;
    rhs[3] -= dj_theta * vt * vt * 0.5;
    let ken = p.k_e * nm;
    rhs[3] += ken * (i[0] + i[1]) - p.m_b * p.g * p.l * sa;
    rhs[4] -= ken * i[0];
    rhs[5] -= ken * i[1];
    let fric = |wrel: T| friction(p.d_v, p.d_c, p.d_0, wrel);
    let (fr, fl) = (fric(vr - va), fric(vl - va));
    rhs[3] -= fr + fl + f_shape[0];
    rhs[4] -= -fr + f_shape[1];
    rhs[5] -= -fl + f_shape[2];

    // ν̇ = −(SᵀMS)⁻¹ Sᵀ (M Ṡ ν + K + P − 𝓕).
    let lu = dmech_lie::linalg::Lu::new(&sms)?;
    let shape = |nud: SVector<T, 3>| {
        [
            nud[0],
            (nud[1] + p.d * nud[2]) * inv_r,
            (nud[1] - p.d * nud[2]) * inv_l,
        ]
    };
    let nud = -lu.solve(&SVector::from(s_transpose(rhs)));
    let response = dirs.map(|f| {
        let sf = s_transpose([z, z, z, f[0], f[1], f[2]]);
        shape(lu.solve(&SVector::from(sf)))
    });
    Some((shape(nud), response))
}

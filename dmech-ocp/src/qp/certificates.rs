//! Certificates that a QP has no solution: a Farkas certificate of primal infeasibility
//! from the multipliers, a recession direction of unbounded descent from a step.

use super::iterate::{Side, StageIterate, StageSides, SIGN};
use super::problem::StageQp;
use nalgebra::SVector;

/// Whether the iterate's multipliers `(π, λ)` (hard sides only), scaled to `‖·‖∞ = 1`,
/// prove the hard rows infeasible: for every `y` that satisfies the dynamics,
/// `Σ λ_j (σ_j z_j(y) − b_j) = v + ρᵀy` with `v` the constant and `ρ` the coefficients
/// below; a feasible `y` makes the left side `≤ 0`. So `v > 0` with `‖ρ‖∞ ≤ tol · v`
/// excludes every feasible `y` with `‖y‖₁ < 1/tol`.
pub(crate) fn primal_infeasible<const NX: usize, const NU: usize, const NC: usize>(
    qp: &StageQp<NX, NU, NC>,
    sides: &[StageSides<NC>],
    it: &[StageIterate<NX, NU, NC>],
    tol: f64,
) -> bool {
    let n = qp.horizon();
    let hard = |k: usize| -> SVector<f64, NC> {
        SVector::from_fn(|i, _| {
            (0..2)
                .filter(|&j| sides[k].side[j][i] == Side::Hard)
                .map(|j| SIGN[j] * it[k].lam[j][i])
                .sum()
        })
    };
    let mut scale: f64 = 0.0;
    for k in 0..=n {
        for j in 0..2 {
            for i in 0..NC {
                if sides[k].side[j][i] == Side::Hard {
                    scale = scale.max(it[k].lam[j][i]);
                }
            }
        }
        if k < n {
            scale = scale.max(it[k].pi.amax());
        }
    }
    if !(scale > 0.0 && scale.is_finite()) {
        return false;
    }
    let (mut value, mut coefficient): (f64, f64) = (0.0, 0.0);
    for k in 0..=n {
        let net = hard(k) / scale;
        let rows = qp.rows(k);
        for j in 0..2 {
            for i in 0..NC {
                if sides[k].side[j][i] == Side::Hard {
                    value -= it[k].lam[j][i] / scale * sides[k].b[j][i];
                }
            }
        }
        let mut r_x = rows.d.tr_mul(&net);
        if k > 0 {
            r_x -= it[k - 1].pi / scale;
        }
        if k < n {
            let (st, pi) = (&qp.stages()[k], it[k].pi / scale);
            let r_u = st.b.tr_mul(&pi) + rows.e.tr_mul(&net);
            r_x += st.a.tr_mul(&pi);
            coefficient = coefficient.max(r_u.amax());
            value += pi.dot(&st.c);
        }
        if k == 0 {
            // x_0 is given: its terms are constants.
            value += r_x.dot(qp.x0());
        } else {
            coefficient = coefficient.max(r_x.amax());
        }
    }
    value > 0.0 && coefficient <= tol * value
}

/// Whether the primal part of the direction `d`, scaled to `‖·‖∞ = 1`, is a direction of
/// unbounded descent: it satisfies the homogeneous dynamics and every hard row's
/// present sides (`σ C d ≤ tol`), has no curvature (`‖H d‖∞ ≤ tol`, Hessian's entries
/// scaled to 1), and the objective's slope along it, soft rows' prices included, is
/// below `−tol`.
pub(crate) fn dual_infeasible<const NX: usize, const NU: usize, const NC: usize>(
    qp: &StageQp<NX, NU, NC>,
    sides: &[StageSides<NC>],
    d: &[StageIterate<NX, NU, NC>],
    tol: f64,
) -> bool {
    let n = qp.horizon();
    let mut norm: f64 = 0.0;
    let mut h_scale = qp.terminal().q.amax();
    for (k, dk) in d.iter().enumerate().take(n + 1) {
        norm = norm.max(dk.x.amax());
        if k < n {
            norm = norm.max(dk.u.amax());
            let st = &qp.stages()[k];
            h_scale = h_scale.max(st.q.amax()).max(st.s.amax()).max(st.r.amax());
        }
    }
    if !(norm > 0.0 && norm.is_finite()) {
        return false;
    }
    let h_scale = h_scale.max(1.0);
    let mut slope = 0.0;
    for k in 0..=n {
        let (x, rows) = (d[k].x / norm, qp.rows(k));
        let (hx, hu, z) = if k < n {
            let (st, u) = (&qp.stages()[k], d[k].u / norm);
            if (st.a * x + st.b * u - d[k + 1].x / norm).amax() > tol {
                return false;
            }
            slope += st.q_vec.dot(&x) + st.r_vec.dot(&u);
            (
                st.q * x + st.s * u,
                st.s.tr_mul(&x) + st.r * u,
                rows.d * x + rows.e * u,
            )
        } else {
            let t = qp.terminal();
            slope += t.q_vec.dot(&x);
            (t.q * x, SVector::zeros(), rows.d * x)
        };
        if hx.amax().max(hu.amax()) > tol * h_scale {
            return false;
        }
        for j in 0..2 {
            for i in 0..NC {
                let rise = SIGN[j] * z[i];
                match sides[k].side[j][i] {
                    Side::Absent => {}
                    Side::Hard => {
                        if rise > tol {
                            return false;
                        }
                    }
                    Side::Soft { l1, l2 } => {
                        if l2 > 0.0 && rise > tol {
                            return false;
                        }
                        slope += l1 * rise.max(0.0);
                    }
                }
            }
        }
    }
    slope < -tol
}

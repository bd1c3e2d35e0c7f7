//! The interior point's Newton step: each stage's slacks, soft violations and row
//! multipliers eliminated into its Hessian and gradient (the stage's condensing), then a
//! Riccati recursion over the stages, factored once per iteration and solved for the
//! predictor and the corrector (`docs/qp.md`, "The Newton step").

use super::dense;
use super::iterate::{Side, StageIterate, StageResidual, StageSides, SIGN};
use super::problem::StageQp;
use nalgebra::{SMatrix, SVector};

/// What the factorisation keeps of stage `k`: per side the barrier weight `w = λ/t` and,
/// for soft sides, the violation's own curvature `e = l2 + ν/s` and `d = e + w`; the condensed weight per row `W`; the
/// cost-to-go Hessian `P_k` (`k ≥ 1`), the gain `K_k` and the Cholesky factor `L` of
/// `R̂_k = R̃ + BᵀP_{k+1}B`; and the vector pass's `p_k`, `κ_k` and the sides' `ã`.
#[derive(Clone, Debug)]
pub(crate) struct StageFactor<const NX: usize, const NU: usize, const NC: usize> {
    w: [SVector<f64, NC>; 2],
    e: [SVector<f64, NC>; 2],
    d: [SVector<f64, NC>; 2],
    p: SMatrix<f64, NX, NX>,
    gain: SMatrix<f64, NU, NX>,
    chol: SMatrix<f64, NU, NU>,
    p_vec: SVector<f64, NX>,
    kappa: SVector<f64, NU>,
    a_side: [SVector<f64, NC>; 2],
    a_tilde: [SVector<f64, NC>; 2],
}

impl<const NX: usize, const NU: usize, const NC: usize> StageFactor<NX, NU, NC> {
    pub fn zeros() -> Self {
        StageFactor {
            w: [SVector::zeros(); 2],
            e: [SVector::zeros(); 2],
            d: [SVector::zeros(); 2],
            p: SMatrix::zeros(),
            gain: SMatrix::zeros(),
            chol: SMatrix::zeros(),
            p_vec: SVector::zeros(),
            kappa: SVector::zeros(),
            a_side: [SVector::zeros(); 2],
            a_tilde: [SVector::zeros(); 2],
        }
    }

    /// `W = Σ_j w̃_j` per row, `w̃ = w` on a hard side and `w e / d` on a soft one (the
    /// soft violation eliminated; `w (1 − w/d)` would cancel where `w ≫ e`).
    fn row_weight(&self, sides: &StageSides<NC>) -> SVector<f64, NC> {
        SVector::from_fn(|i, _| {
            (0..2)
                .map(|j| match sides.side[j][i] {
                    Side::Absent => 0.0,
                    Side::Hard => self.w[j][i],
                    Side::Soft { .. } => self.w[j][i] * self.e[j][i] / self.d[j][i],
                })
                .sum()
        })
    }
}

/// The Newton step's linear algebra failed at this stage: `R̂` not positive definite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct NotPositiveDefinite(pub usize);

/// Factor the Newton system at the iterate `it`: the sides' weights, the condensed stage
/// Hessians and the backward Riccati recursion's matrices.
pub(crate) fn factor<const NX: usize, const NU: usize, const NC: usize>(
    qp: &StageQp<NX, NU, NC>,
    sides: &[StageSides<NC>],
    it: &[StageIterate<NX, NU, NC>],
    regularisation: f64,
    fac: &mut [StageFactor<NX, NU, NC>],
) -> Result<(), NotPositiveDefinite> {
    let n = qp.horizon();
    for k in 0..=n {
        let (f, ik) = (&mut fac[k], &it[k]);
        for j in 0..2 {
            for i in 0..NC {
                let w = match sides[k].side[j][i] {
                    Side::Absent => 0.0,
                    _ => ik.lam[j][i] / ik.t[j][i],
                };
                f.w[j][i] = w;
                f.e[j][i] = match sides[k].side[j][i] {
                    Side::Soft { l2, .. } => l2 + ik.nu[j][i] / ik.s[j][i],
                    _ => 0.0,
                };
                f.d[j][i] = f.e[j][i] + w;
            }
        }
    }
    let rows = qp.rows(n);
    let weight = fac[n].row_weight(&sides[n]);
    let mut p_n = qp.terminal().q;
    let mut unused = (
        SMatrix::<f64, NU, NX>::zeros(),
        SMatrix::<f64, NU, NU>::zeros(),
    );
    condense(rows, &weight, &mut p_n, &mut unused.0, &mut unused.1);
    fac[n].p = p_n;
    let eye_u = SMatrix::<f64, NU, NU>::identity() * regularisation;
    for k in (0..n).rev() {
        let (st, rows) = (&qp.stages()[k], qp.rows(k));
        let (head, tail) = fac.split_at_mut(k + 1);
        let (f, next) = (&mut head[k], &tail[0]);
        let weight = f.row_weight(&sides[k]);
        let pb = dense::mul(&next.p, &st.b);
        // Q̂ = Q + AᵀPA, its upper triangle (all that P_k reads), none at k = 0, where x_0
        // is held and P_0 not formed. Each entry summed in mul's order: the closed loop's
        // quantised sensors turn a change of 1e-13 in a QP's result into another
        // trajectory.
        let mut q_hat = st.q;
        if k > 0 {
            q_hat += dense::mul_upper(qp.a_t(k), &dense::mul(&next.p, &st.a));
        }
        // Ŝ = Sᵀ + BᵀPA = (S + AᵀPB)ᵀ: axpys over Aᵀ's columns.
        let mut s_hat = (st.s + dense::mul(qp.a_t(k), &pb)).transpose();
        let mut r_hat = st.r + dense::tr_mul(&st.b, &pb) + eye_u;
        condense(rows, &weight, &mut q_hat, &mut s_hat, &mut r_hat);
        f.chol = dense::cholesky(&r_hat).ok_or(NotPositiveDefinite(k))?;
        f.gain = -dense::cholesky_solve(&f.chol, &s_hat);
        if k > 0 {
            // P_k = Q̂ + Ŝᵀ K, its upper triangle formed and mirrored (the sum is
            // symmetric but for rounding; Q̂'s lower triangle is not formed).
            for c in 0..NX {
                for r in 0..=c {
                    let mut sk = 0.0;
                    for i in 0..NU {
                        sk += s_hat[(i, r)] * f.gain[(i, c)];
                    }
                    let p = q_hat[(r, c)] + sk;
                    f.p[(r, c)] = p;
                    f.p[(c, r)] = p;
                }
            }
        }
    }
    Ok(())
}

/// The rows' barrier terms added to a stage's blocks: `Q += Dᵀ W D`, `Ŝ += Eᵀ W D`,
/// `R += Eᵀ W E`, row by row as rank-one updates that skip the rows' zero entries
/// (a box bound has one).
fn condense<const NX: usize, const NU: usize, const NC: usize>(
    rows: &super::problem::Rows<NX, NU, NC>,
    weight: &SVector<f64, NC>,
    q: &mut SMatrix<f64, NX, NX>,
    s_hat: &mut SMatrix<f64, NU, NX>,
    r: &mut SMatrix<f64, NU, NU>,
) {
    for i in 0..NC {
        let w = weight[i];
        if w == 0.0 {
            continue;
        }
        let d: [f64; NX] = std::array::from_fn(|c| rows.d[(i, c)]);
        let e: [f64; NU] = std::array::from_fn(|c| rows.e[(i, c)]);
        for c in 0..NX {
            let wd = w * d[c];
            if wd == 0.0 {
                continue;
            }
            for r_ in 0..NX {
                q[(r_, c)] += d[r_] * wd;
            }
            for r_ in 0..NU {
                s_hat[(r_, c)] += e[r_] * wd;
            }
        }
        for c in 0..NU {
            let we = w * e[c];
            if we == 0.0 {
                continue;
            }
            for r_ in 0..NU {
                r[(r_, c)] += e[r_] * we;
            }
        }
    }
}

/// The complementarity targets of a solve: `r_c = tλ − target` per side (and `sν` for the
/// soft violations). The predictor aims at zero; Mehrotra's corrector at `σμ` less the
/// predictor's second-order term `Δt Δλ`; an iterative refinement solves for the residual
/// of the Newton system alone (`r_c = 0`).
pub(crate) enum Target<'a, const NX: usize, const NU: usize, const NC: usize> {
    Affine,
    Corrector {
        affine: &'a [StageIterate<NX, NU, NC>],
        sigma_mu: f64,
    },
    Refinement,
}

impl<const NX: usize, const NU: usize, const NC: usize> Target<'_, NX, NU, NC> {
    /// `(r_c, r_cs)` of side `j` of row `i` at stage `k`.
    fn complementarity(
        &self,
        it: &StageIterate<NX, NU, NC>,
        k: usize,
        j: usize,
        i: usize,
    ) -> (f64, f64) {
        let (r_c, r_cs) = (it.t[j][i] * it.lam[j][i], it.s[j][i] * it.nu[j][i]);
        match self {
            Target::Affine => (r_c, r_cs),
            Target::Corrector { affine, sigma_mu } => {
                let da = &affine[k];
                (
                    r_c + da.t[j][i] * da.lam[j][i] - sigma_mu,
                    r_cs + da.s[j][i] * da.nu[j][i] - sigma_mu,
                )
            }
            Target::Refinement => (0.0, 0.0),
        }
    }
}

/// The residual of the Newton system's stationarity rows at the direction `d` for the
/// right-hand side `res` (`H Δy + [A B]ᵀΔπ_k − Δπ_{k−1} + Cᵀ(Δλ_hi − Δλ_lo) + r_y`), into
/// `out` with every other residual zero: the right-hand side of an iterative refinement
/// (the other rows, eliminations and dynamics, hold by construction). Returns its
/// `‖·‖∞`.
pub(crate) fn newton_residual<const NX: usize, const NU: usize, const NC: usize>(
    qp: &StageQp<NX, NU, NC>,
    d: &[StageIterate<NX, NU, NC>],
    res: &[StageResidual<NX, NU, NC>],
    out: &mut [StageResidual<NX, NU, NC>],
) -> f64 {
    let n = qp.horizon();
    let mut norm: f64 = 0.0;
    for k in 0..=n {
        let (dk, rows, o) = (&d[k], qp.rows(k), &mut out[k]);
        let net = dk.lam[0] - dk.lam[1];
        if k < n {
            let st = &qp.stages()[k];
            o.r_u = st.r * dk.u
                + st.s.tr_mul(&dk.x)
                + st.b.tr_mul(&dk.pi)
                + rows.e.tr_mul(&net)
                + res[k].r_u;
            o.r_x = st.q * dk.x
                + st.s * dk.u
                + dense::mul_vec(qp.a_t(k), &dk.pi)
                + dense::mul_vec(qp.d_t(k), &net)
                + res[k].r_x;
        } else {
            o.r_u = SVector::zeros();
            o.r_x = qp.terminal().q * dk.x + dense::mul_vec(qp.d_t(k), &net) + res[k].r_x;
        }
        if k > 0 {
            o.r_x -= d[k - 1].pi;
            norm = norm.max(o.r_x.amax());
        } else {
            // x_0 is held: its row is not part of the system.
            o.r_x = SVector::zeros();
        }
        norm = norm.max(o.r_u.amax());
        o.r_dyn = SVector::zeros();
        o.r_p = [SVector::zeros(); 2];
        o.r_s = [SVector::zeros(); 2];
    }
    norm
}

/// Solve the factored Newton system for the direction `dir`.
pub(crate) fn solve<const NX: usize, const NU: usize, const NC: usize>(
    qp: &StageQp<NX, NU, NC>,
    sides: &[StageSides<NC>],
    it: &[StageIterate<NX, NU, NC>],
    res: &[StageResidual<NX, NU, NC>],
    fac: &mut [StageFactor<NX, NU, NC>],
    target: &Target<'_, NX, NU, NC>,
    dir: &mut [StageIterate<NX, NU, NC>],
) {
    let n = qp.horizon();
    // The sides' eliminated right-hand sides `ã` and the condensed gradients.
    for k in (0..=n).rev() {
        let (ik, rk, sd) = (&it[k], &res[k], &sides[k]);
        let f = &mut fac[k];
        let mut a_net = SVector::<f64, NC>::zeros();
        for j in 0..2 {
            for i in 0..NC {
                if sd.side[j][i] == Side::Absent {
                    continue;
                }
                let (t, lam) = (ik.t[j][i], ik.lam[j][i]);
                let (r_c, r_cs) = target.complementarity(ik, k, j, i);
                let a = (-r_c + lam * rk.r_p[j][i]) / t;
                let a_tilde = match sd.side[j][i] {
                    Side::Soft { .. } => {
                        let (w, e, d, s) = (f.w[j][i], f.e[j][i], f.d[j][i], ik.s[j][i]);
                        (a * e + w * (rk.r_s[j][i] + r_cs / s)) / d
                    }
                    _ => a,
                };
                f.a_side[j][i] = a;
                f.a_tilde[j][i] = a_tilde;
                a_net[i] += SIGN[j] * a_tilde;
            }
        }
        let rows = qp.rows(k);
        let q_tilde = rk.r_x + dense::mul_vec(qp.d_t(k), &a_net);
        if k == n {
            f.p_vec = q_tilde;
            continue;
        }
        let st = &qp.stages()[k];
        let r_tilde = rk.r_u + rows.e.tr_mul(&a_net);
        let (head, tail) = fac.split_at_mut(k + 1);
        let (f, next) = (&mut head[k], &tail[0]);
        let pc = dense::mul_vec(&next.p, &rk.r_dyn) + next.p_vec;
        let h_u = r_tilde + dense::tr_mul_vec(&st.b, &pc);
        f.kappa = -dense::cholesky_solve(&f.chol, &h_u);
        if k > 0 {
            f.p_vec = q_tilde + dense::mul_vec(qp.a_t(k), &pc) + dense::tr_mul_vec(&f.gain, &h_u);
        }
    }
    // Forward: dx_0 = 0 (x_0 is given and held).
    dir[0].x = SVector::zeros();
    for k in 0..n {
        let st = &qp.stages()[k];
        let f = &fac[k];
        let du = dense::mul_vec(&f.gain, &dir[k].x) + f.kappa;
        let dx_next = dense::mul_vec(&st.a, &dir[k].x) + dense::mul_vec(&st.b, &du) + res[k].r_dyn;
        dir[k].u = du;
        // The predictor's Δπ is never used (its sides' directions are).
        if !matches!(target, Target::Affine) {
            dir[k].pi = dense::mul_vec(&fac[k + 1].p, &dx_next) + fac[k + 1].p_vec;
        }
        dir[k + 1].x = dx_next;
    }
    dir[n].u = SVector::zeros();
    dir[n].pi = SVector::zeros();
    // The sides' directions from the rows' `C Δy`.
    for k in 0..=n {
        let rows = qp.rows(k);
        let mut cdy = rows.d * dir[k].x;
        if k < n {
            cdy += rows.e * dir[k].u;
        }
        let (ik, rk, sd, f) = (&it[k], &res[k], &sides[k], &fac[k]);
        let dk = &mut dir[k];
        for j in 0..2 {
            for i in 0..NC {
                let side = sd.side[j][i];
                if side == Side::Absent {
                    (dk.t[j][i], dk.lam[j][i], dk.s[j][i], dk.nu[j][i]) = (0.0, 0.0, 0.0, 0.0);
                    continue;
                }
                let sc = SIGN[j] * cdy[i];
                let w = f.w[j][i];
                let ds = match side {
                    Side::Soft { .. } => {
                        let (s, nu) = (ik.s[j][i], ik.nu[j][i]);
                        let (_, r_cs) = target.complementarity(ik, k, j, i);
                        let ds = (-rk.r_s[j][i] + f.a_side[j][i] - r_cs / s + w * sc) / f.d[j][i];
                        dk.nu[j][i] = (-r_cs - nu * ds) / s;
                        ds
                    }
                    _ => {
                        dk.nu[j][i] = 0.0;
                        0.0
                    }
                };
                dk.s[j][i] = ds;
                dk.lam[j][i] = f.a_side[j][i] + w * sc - w * ds;
                dk.t[j][i] = -rk.r_p[j][i] - sc + ds;
            }
        }
    }
}

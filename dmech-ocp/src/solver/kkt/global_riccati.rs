//! The Riccati recursion augmented by global variables: an LQ problem over stages whose
//! stages also read a few of `n_g` global variables `p`, solved by a Schur complement.
//!
//! ```text
//! min  Σ_k ½ [x;u;θ]ᵀ [Q S S_xθ; Sᵀ R S_uθ; · · R_θθ] [x;u;θ] + qᵀx + rᵀu + q_θᵀθ  + ½ x_Nᵀ Q_N x_N + q_Nᵀ x_N
//! s.t. x_{k+1} = A x_k + B u_k + B_θ θ_k + c_k,   θ_k = S_k p,   x_0 = x̄
//! ```
//! `S_k` selects the globals stage `k` reads (its `support`). For a fixed `p` this is the
//! plain LQ problem with right-hand sides affine in `p`: the factorisation
//! ([`BackwardSweep`]: `P_k`, `K_k`) does not depend on `p`, and the cost-to-go is
//! `V_k(x, p) = ½ xᵀP_k x + xᵀ(p_k + Π_k p) + ½ pᵀΨ_k p + ψ_kᵀ p + const`. With
//! `G = B_θ S_k` and the next stage's `P, p, Π, Ψ, ψ` (`Π_N = 0`, `Ψ_N = 0`, `ψ_N = 0`):
//! ```text
//! M   = P G + Π                                  (∂∇ₓV_{k+1}/∂p along the dynamics)
//! H_up = S_uθ S_k + Bᵀ M,   H_xp = S_xθ S_k + Aᵀ M,   K_p = −H_uu⁻¹ H_up
//! Π_k = H_xp + H_uxᵀ K_p
//! Ψ_k = Ψ + S_kᵀ R_θθ S_k + Gᵀ P G + Gᵀ Π + Πᵀ G + H_upᵀ K_p
//! ψ_k = ψ + S_kᵀ q_θ + Gᵀ (P c + p) + Πᵀ c + H_upᵀ κ
//! ```
//! (`H_uu`, `H_ux`, `κ` as in the plain sweep). From `x_0 = x̄`, `V_0(x̄, p)` is a quadratic
//! in `p` alone, `½ pᵀ(Ψ_0) p + (ψ_0 + Π_0ᵀ x̄)ᵀ p`: the caller adds the globals' own terms
//! and solves that small dense system for `p` (with its equalities and inertia check);
//! the forward pass then feeds `p` into every stage: `u_k = K_k x_k + κ_k + K_{p,k} p`,
//! `λ_k = P_{k+1} x_{k+1} + p_{k+1} + Π_{k+1} p`. Per stage the extra work is
//! `O(n_x² n_g)`, against `O(n_x³)` for the sweep itself.

use crate::solver::kkt::riccati::{BackwardSweep, LqSolution, LqStage, RiccatiError};
use nalgebra::{Const, DMatrix, DVector, Dyn, OMatrix, SMatrix, SVector};

/// `R` rows, one column per global.
type Cols<const R: usize> = OMatrix<f64, Const<R>, Dyn>;

/// Stage `k`'s coupling to its `NT` global entries `θ_k = S_k p` (unused columns zero).
#[derive(Clone, Debug)]
pub struct LqCoupling<const NX: usize, const NF: usize, const NT: usize> {
    pub s_xt: SMatrix<f64, NX, NT>,
    pub s_ut: SMatrix<f64, NF, NT>,
    pub r_tt: SMatrix<f64, NT, NT>,
    pub q_t: SVector<f64, NT>,
    pub b_t: SMatrix<f64, NX, NT>,
}

impl<const NX: usize, const NF: usize, const NT: usize> LqCoupling<NX, NF, NT> {
    pub fn zeros() -> Self {
        LqCoupling {
            s_xt: SMatrix::zeros(),
            s_ut: SMatrix::zeros(),
            r_tt: SMatrix::zeros(),
            q_t: SVector::zeros(),
            b_t: SMatrix::zeros(),
        }
    }
}

/// The globals' columns of the factorisation: `Π_k` (`k = 0..=N`), `K_{p,k}`, and the
/// reduced quadratic `½ pᵀ Ψ p + ψᵀ p` of the globals at `x_0 = x̄`.
pub struct GlobalSchur<const NXG: usize, const NUG: usize> {
    pi: Vec<Cols<NXG>>,
    kp: Vec<Cols<NUG>>,
    pub psi: DMatrix<f64>,
    pub psi_vec: DVector<f64>,
}

/// The distinct globals of `support` (at most `NT`), in order of first appearance, and for
/// each the sum of `b`'s columns that read it: the nonzero columns of `b S_kᵀ`. Fixed-size,
/// so that the serial sweep allocates nothing per stage for it.
struct DistinctColumns<const R: usize, const NT: usize> {
    globals: [usize; NT],
    cols: [SVector<f64, R>; NT],
    len: usize,
}

impl<const R: usize, const NT: usize> DistinctColumns<R, NT> {
    fn new(b: &SMatrix<f64, R, NT>, support: &[usize]) -> Self {
        let mut d = DistinctColumns {
            globals: [0; NT],
            cols: [SVector::zeros(); NT],
            len: 0,
        };
        for (a, &j) in support.iter().enumerate() {
            let i = d.globals[..d.len]
                .iter()
                .position(|&g| g == j)
                .unwrap_or_else(|| {
                    d.globals[d.len] = j;
                    d.len += 1;
                    d.len - 1
                });
            d.cols[i] += b.column(a);
        }
        d
    }

    /// `(global, column)` pairs.
    fn iter(&self) -> impl Iterator<Item = (usize, &SVector<f64, R>)> {
        self.globals[..self.len]
            .iter()
            .copied()
            .zip(&self.cols[..self.len])
    }
}

/// `m S_kᵀ`: the `NT` columns of `m` added into the columns `support` of an `r × n_g`
/// matrix.
fn scatter_columns<const R: usize, const NT: usize>(
    m: &SMatrix<f64, R, NT>,
    support: &[usize],
    ng: usize,
) -> Cols<R> {
    let mut out = Cols::<R>::zeros(ng);
    for (i, &j) in support.iter().enumerate() {
        for r in 0..R {
            out[(r, j)] += m[(r, i)];
        }
    }
    out
}

/// The backward pass of the globals' columns over a complete plain `sweep` of `stages`
/// (with its shift), from `x_0 = x0`. `support(k)` lists the globals of stage `k`'s first
/// `support(k).len()` coupling columns.
pub fn global_sweep<'s, const NX: usize, const NF: usize, const NT: usize>(
    sweep: &BackwardSweep<NX, NF>,
    stages: &[LqStage<NX, NF>],
    couplings: &[LqCoupling<NX, NF, NT>],
    support: &dyn Fn(usize) -> &'s [usize],
    ng: usize,
    x0: &SVector<f64, NX>,
) -> Result<GlobalSchur<NX, NF>, RiccatiError> {
    let n = stages.len();
    let eye_u = SMatrix::<f64, NF, NF>::identity() * sweep.shift();
    let mut pi = vec![Cols::<NX>::zeros(ng); n + 1];
    let mut kp = vec![Cols::<NF>::zeros(ng); n];
    let mut psi = DMatrix::zeros(ng, ng);
    let mut psi_vec = DVector::zeros(ng);
    for k in (0..n).rev() {
        let (st, cp, sup) = (&stages[k], &couplings[k], support(k));
        let (p_mat, p_vec) = sweep.cost_to_go(k + 1);
        let (_, kappa) = sweep.gain(k);
        let huu = st.r_mat + eye_u + st.b.transpose() * p_mat * st.b;
        let hux = st.s_mat.transpose() + st.b.transpose() * p_mat * st.a;
        let chol = huu
            .cholesky()
            .ok_or(RiccatiError::NotPositiveDefinite { stage: k })?;
        // G = B_θ S_kᵀ has a column only at the stage's distinct globals (a global read
        // twice, as a free-timing stage reads its segment's ratio, adds its columns): the
        // products with G are taken over those columns alone.
        let g = DistinctColumns::new(&cp.b_t, sup);
        // P G's columns, each used twice below.
        let pg: [SVector<f64, NX>; NT] = std::array::from_fn(|i| {
            if i < g.len {
                p_mat * g.cols[i]
            } else {
                SVector::zeros()
            }
        });
        let pi_next = &pi[k + 1];
        let mut m = pi_next.clone();
        for (a, (j, _)) in g.iter().enumerate() {
            let mut col = m.column_mut(j);
            col += pg[a];
        }
        let h_up = scatter_columns(&cp.s_ut, sup, ng) + st.b.transpose() * &m;
        let h_xp = scatter_columns(&cp.s_xt, sup, ng) + st.a.transpose() * &m;
        let mut k_p = h_up.clone();
        chol.solve_mut(&mut k_p);
        k_p.neg_mut();
        // Ψ += S R_θθ Sᵀ + Gᵀ P G + Gᵀ Π + Πᵀ G + H_upᵀ K_p, kept symmetric; with
        // M = P G + Π, Gᵀ M + Mᵀ G − Gᵀ P G is the same sum.
        let mut add = h_up.transpose() * &k_p;
        for (a, (ja, ga)) in g.iter().enumerate() {
            let gtm = ga.transpose() * &m;
            for j in 0..ng {
                add[(ja, j)] += gtm[j];
                add[(j, ja)] += gtm[j];
            }
            for (jb, gb) in g.iter().take(a + 1) {
                let gpg = gb.dot(&pg[a]);
                add[(ja, jb)] -= gpg;
                if ja != jb {
                    add[(jb, ja)] -= gpg;
                }
            }
        }
        for (a, &ja) in sup.iter().enumerate() {
            for (b, &jb) in sup.iter().enumerate() {
                add[(ja, jb)] += cp.r_tt[(a, b)];
            }
        }
        psi += (&add + add.transpose()) * 0.5;
        let pc = p_mat * st.c + p_vec;
        psi_vec += pi_next.transpose() * st.c + h_up.transpose() * kappa;
        for (j, gj) in g.iter() {
            psi_vec[j] += gj.dot(&pc);
        }
        for (a, &ja) in sup.iter().enumerate() {
            psi_vec[ja] += cp.q_t[a];
        }
        pi[k] = h_xp + hux.transpose() * &k_p;
        kp[k] = k_p;
    }
    psi_vec += pi[0].transpose() * x0;
    Ok(GlobalSchur {
        pi,
        kp,
        psi,
        psi_vec,
    })
}

/// The forward pass with the globals' step `p` fed into every stage.
pub fn global_forward<'s, const NX: usize, const NF: usize, const NT: usize>(
    sweep: &BackwardSweep<NX, NF>,
    schur: &GlobalSchur<NX, NF>,
    stages: &[LqStage<NX, NF>],
    couplings: &[LqCoupling<NX, NF, NT>],
    support: &dyn Fn(usize) -> &'s [usize],
    x0: &SVector<f64, NX>,
    p: &DVector<f64>,
) -> LqSolution<NX, NF> {
    let n = stages.len();
    let mut x = Vec::with_capacity(n + 1);
    x.push(*x0);
    let mut u = Vec::with_capacity(n);
    let mut lambda = Vec::with_capacity(n);
    for (k, st) in stages.iter().enumerate() {
        let (gain, ff) = sweep.gain(k);
        let uk: SVector<f64, NF> = gain * x[k] + ff + &schur.kp[k] * p;
        let mut theta = SVector::<f64, NT>::zeros();
        for (a, &j) in support(k).iter().enumerate() {
            theta[a] = p[j];
        }
        let next = st.a * x[k] + st.b * uk + couplings[k].b_t * theta + st.c;
        let (pm, pv) = sweep.cost_to_go(k + 1);
        let lam: SVector<f64, NX> = pm * next + pv + &schur.pi[k + 1] * p;
        lambda.push(lam);
        u.push(uk);
        x.push(next);
    }
    LqSolution { x, u, lambda }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::kkt::riccati::{solve_lq, sweep_lq};
    use dmech_lie::lcg::Lcg;

    fn mat<const R: usize, const C: usize>(seed: &mut Lcg) -> SMatrix<f64, R, C> {
        SMatrix::from_fn(|_, _| seed.uniform())
    }

    /// With the globals' step fixed at the Schur solution, the augmented recursion gives the
    /// plain recursion's solution of the problem with those globals substituted (the
    /// right-hand sides moved), and the globals' gradient of the total cost vanishes there:
    /// checked against the plain solver on the substituted problem, for random stages.
    #[test]
    fn schur_complement_solves_the_coupled_lq() {
        const NX: usize = 3;
        const NF: usize = 2;
        const NT: usize = 2;
        let (n, ng) = (7usize, 3usize);
        let mut seed = Lcg(11);
        let spd = |m: SMatrix<f64, NX, NX>| m * m.transpose() + SMatrix::identity() * 0.2;
        let stages: Vec<LqStage<NX, NF>> = (0..n)
            .map(|_| {
                let r: SMatrix<f64, NF, NF> = mat(&mut seed);
                LqStage {
                    q_mat: spd(mat(&mut seed)),
                    s_mat: mat::<NX, NF>(&mut seed) * 0.1,
                    r_mat: r * r.transpose() + SMatrix::identity() * 0.5,
                    q: mat(&mut seed),
                    r: mat(&mut seed),
                    a: SMatrix::identity() + mat::<NX, NX>(&mut seed) * 0.3,
                    b: mat(&mut seed),
                    c: mat(&mut seed),
                }
            })
            .collect();
        let couplings: Vec<LqCoupling<NX, NF, NT>> = (0..n)
            .map(|_| {
                let r: SMatrix<f64, NT, NT> = mat(&mut seed);
                LqCoupling {
                    s_xt: mat::<NX, NT>(&mut seed) * 0.1,
                    s_ut: mat::<NF, NT>(&mut seed) * 0.1,
                    r_tt: r * r.transpose() + SMatrix::identity(),
                    q_t: mat(&mut seed),
                    b_t: mat(&mut seed),
                }
            })
            .collect();
        // Stage k reads globals (k mod 3, (k + 1) mod 3); stage 2 reads global 0 twice.
        let supports: Vec<[usize; 2]> = (0..n)
            .map(|k| if k == 2 { [0, 0] } else { [k % 3, (k + 1) % 3] })
            .collect();
        let support = |k: usize| &supports[k][..];
        let q_n = spd(mat(&mut seed));
        let q_vec_n: SVector<f64, NX> = mat(&mut seed);
        let x0: SVector<f64, NX> = mat(&mut seed);
        let sweep = sweep_lq(&stages, &q_n, &q_vec_n, 0.0).unwrap();
        let schur = global_sweep(&sweep, &stages, &couplings, &support, ng, &x0).unwrap();
        let p = schur
            .psi
            .clone()
            .cholesky()
            .expect("a convex problem")
            .solve(&(-&schur.psi_vec));
        let sol = global_forward(&sweep, &schur, &stages, &couplings, &support, &x0, &p);
        // The substituted problem: θ fixed, its terms moved into q, r, c.
        let total = |p: &DVector<f64>| {
            let sub: Vec<LqStage<NX, NF>> = stages
                .iter()
                .zip(&couplings)
                .enumerate()
                .map(|(k, (st, cp))| {
                    let mut th = SVector::<f64, NT>::zeros();
                    for (a, &j) in support(k).iter().enumerate() {
                        th[a] = p[j];
                    }
                    LqStage {
                        q: st.q + cp.s_xt * th,
                        r: st.r + cp.s_ut * th,
                        c: st.c + cp.b_t * th,
                        ..st.clone()
                    }
                })
                .collect();
            let s = solve_lq(&sub, &q_n, &q_vec_n, &x0, 0.0).unwrap();
            let mut j = 0.5 * s.x[n].dot(&(q_n * s.x[n])) + q_vec_n.dot(&s.x[n]);
            for k in 0..n {
                let (st, cp) = (&stages[k], &couplings[k]);
                let mut th = SVector::<f64, NT>::zeros();
                for (a, &g) in support(k).iter().enumerate() {
                    th[a] = p[g];
                }
                let (x, u) = (s.x[k], s.u[k]);
                j += 0.5 * x.dot(&(st.q_mat * x))
                    + x.dot(&(st.s_mat * u))
                    + 0.5 * u.dot(&(st.r_mat * u))
                    + st.q.dot(&x)
                    + st.r.dot(&u)
                    + x.dot(&(cp.s_xt * th))
                    + u.dot(&(cp.s_ut * th))
                    + 0.5 * th.dot(&(cp.r_tt * th))
                    + cp.q_t.dot(&th);
            }
            (j, s)
        };
        let (j0, plain) = total(&p);
        let mut worst = 0.0f64;
        for k in 0..n {
            worst = worst.max((plain.u[k] - sol.u[k]).amax());
            worst = worst.max((plain.x[k + 1] - sol.x[k + 1]).amax());
        }
        // The optimum in p: the reduced cost is a convex quadratic, so its central
        // differences are exact up to round-off: (J(p+he) − J(p−he))/2h = 0.
        let h = 1e-3;
        let mut grad = 0.0f64;
        for j in 0..ng {
            let mut e = DVector::zeros(ng);
            e[j] = h;
            grad = grad.max(((total(&(&p + &e)).0 - total(&(&p - &e)).0) / (2.0 * h)).abs());
        }
        println!("states/inputs vs substituted: {worst:.2e}; reduced gradient {grad:.2e}; J {j0}");
        // Entries of order one, κ of the stage systems ~1e2: agreement to ~1e-13; the
        // difference quotient's round-off is ε|J|/h ≈ 1e-12.
        assert!(worst < 1e-11, "{worst:e}");
        assert!(grad < 1e-9 * j0.abs().max(1.0), "{grad:e}");
    }
}

//! The Riccati recursion for stage-structured linear–quadratic problems: the linear
//! algebra of the interior-point solver's Newton step (as in FATROP and HPIPM), in
//! `O(N (n_x + n_u)³)` instead of a general sparse factorisation.
//!
//! ```text
//! min  Σ_{k<N} ½ [x_k; u_k]ᵀ [Q_k S_k; S_kᵀ R_k] [x_k; u_k] + q_kᵀ x_k + r_kᵀ u_k  + ½ x_Nᵀ Q_N x_N + q_Nᵀ x_N
//! s.t. x_{k+1} = A_k x_k + B_k u_k + b_k,   x_0 = x̄
//! ```
//! Backward: `P_N = Q_N`, `p_N = q_N`, and for `k = N−1 … 0`
//! `H_uu = R + BᵀPB`, `H_ux = Sᵀ + BᵀPA`, `H_xx = Q + AᵀPA`, `h_u = r + Bᵀ(Pb + p)`,
//! `h_x = q + Aᵀ(Pb + p)`, `K = −H_uu⁻¹ H_ux`, `κ = −H_uu⁻¹ h_u`,
//! `P ← H_xx + H_uxᵀ K`, `p ← h_x + H_uxᵀ κ`. Forward: `u_k = K_k x_k + κ_k`, and the
//! multipliers of the dynamics are `λ_{k+1} = P_{k+1} x_{k+1} + p_{k+1}`.
//! `H_uu` must be positive definite at every stage (the reduced Hessian's inertia is
//! right); otherwise the stage is reported so that the caller can regularise.

use nalgebra::{DMatrix, DVector};

/// One stage of the LQ problem (the last stage uses only `q_mat`, `q`).
#[derive(Clone, Debug)]
pub struct LqStage {
    pub q_mat: DMatrix<f64>,
    pub s_mat: DMatrix<f64>,
    pub r_mat: DMatrix<f64>,
    pub q: DVector<f64>,
    pub r: DVector<f64>,
    pub a: DMatrix<f64>,
    pub b: DMatrix<f64>,
    pub c: DVector<f64>,
}

/// The solution: states, inputs, and the multipliers of the dynamics (`lambda[k]` for the
/// constraint that defines `x_{k+1}`).
#[derive(Clone, Debug)]
pub struct LqSolution {
    pub x: Vec<DVector<f64>>,
    pub u: Vec<DVector<f64>>,
    pub lambda: Vec<DVector<f64>>,
}

/// Why the recursion stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum RiccatiError {
    /// `H_uu` not positive definite at this stage.
    NotPositiveDefinite { stage: usize },
}

/// Solve the LQ problem over `stages[0..N]` (with dynamics) and the terminal cost
/// `(q_n, q_vec_n)`, from `x0`.
pub fn solve_lq(
    stages: &[LqStage],
    q_n: &DMatrix<f64>,
    q_vec_n: &DVector<f64>,
    x0: &DVector<f64>,
) -> Result<LqSolution, RiccatiError> {
    let n = stages.len();
    let mut p_mat = q_n.clone();
    let mut p_vec = q_vec_n.clone();
    let mut gains = Vec::with_capacity(n);
    let mut costate = vec![(p_mat.clone(), p_vec.clone())];
    for (k, st) in stages.iter().enumerate().rev() {
        let pa = &p_mat * &st.a;
        let pb = &p_mat * &st.b;
        let pc_p = &p_mat * &st.c + &p_vec;
        let huu = &st.r_mat + st.b.transpose() * &pb;
        let hux = st.s_mat.transpose() + st.b.transpose() * &pa;
        let hxx = &st.q_mat + st.a.transpose() * &pa;
        let hu = &st.r + st.b.transpose() * &pc_p;
        let hx = &st.q + st.a.transpose() * &pc_p;
        let chol = huu
            .cholesky()
            .ok_or(RiccatiError::NotPositiveDefinite { stage: k })?;
        let gain = -chol.solve(&hux);
        let ff = -chol.solve(&hu);
        p_mat = &hxx + hux.transpose() * &gain;
        p_mat = (&p_mat + p_mat.transpose()) * 0.5;
        p_vec = &hx + hux.transpose() * &ff;
        gains.push((gain, ff));
        costate.push((p_mat.clone(), p_vec.clone()));
    }
    gains.reverse();
    costate.reverse(); // costate[k] = (P_k, p_k), k = 0..=N
    let mut x = vec![x0.clone()];
    let mut u = Vec::with_capacity(n);
    let mut lambda = Vec::with_capacity(n);
    for (k, st) in stages.iter().enumerate() {
        let uk = &gains[k].0 * &x[k] + &gains[k].1;
        let next = &st.a * &x[k] + &st.b * &uk + &st.c;
        let (pk, pv) = &costate[k + 1];
        lambda.push(pk * &next + pv);
        u.push(uk);
        x.push(next);
    }
    Ok(LqSolution { x, u, lambda })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random matrix.
    fn mat(r: usize, c: usize, seed: &mut u64) -> DMatrix<f64> {
        DMatrix::from_fn(r, c, |_, _| {
            *seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((*seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        })
    }

    /// The Riccati solution equals the solution of the whole KKT system, assembled densely
    /// and solved by LU (κ(KKT) ≈ 1e3 here, so agreement to ~1e-12).
    #[test]
    fn riccati_equals_dense_kkt() {
        let (nx, nu, n) = (4usize, 2usize, 6usize);
        let mut seed = 3u64;
        let spd = |m: DMatrix<f64>, shift: f64| {
            &m * m.transpose() + DMatrix::identity(m.nrows(), m.nrows()) * shift
        };
        let stages: Vec<LqStage> = (0..n)
            .map(|_| LqStage {
                q_mat: spd(mat(nx, nx, &mut seed), 0.1),
                s_mat: mat(nx, nu, &mut seed) * 0.1,
                r_mat: spd(mat(nu, nu, &mut seed), 0.5),
                q: DVector::from_column_slice(mat(nx, 1, &mut seed).as_slice()),
                r: DVector::from_column_slice(mat(nu, 1, &mut seed).as_slice()),
                a: DMatrix::identity(nx, nx) + mat(nx, nx, &mut seed) * 0.3,
                b: mat(nx, nu, &mut seed),
                c: DVector::from_column_slice(mat(nx, 1, &mut seed).as_slice()),
            })
            .collect();
        let q_n = spd(mat(nx, nx, &mut seed), 0.1);
        let q_vec_n = DVector::from_column_slice(mat(nx, 1, &mut seed).as_slice());
        let x0 = DVector::from_column_slice(mat(nx, 1, &mut seed).as_slice());
        let sol = solve_lq(&stages, &q_n, &q_vec_n, &x0).unwrap();

        // Dense KKT in z = (u_0, x_1, u_1, …, x_N), constraints x_{k+1} − A x_k − B u_k = c.
        let nz = n * nu + n * nx;
        let ncon = n * nx;
        let (ui, xi) = (|k: usize| k * (nu + nx), |k: usize| k * (nu + nx) - nx); // x_k for k ≥ 1
        let mut h = DMatrix::<f64>::zeros(nz, nz);
        let mut g = DVector::<f64>::zeros(nz);
        let mut jac = DMatrix::<f64>::zeros(ncon, nz);
        let mut rhs = DVector::<f64>::zeros(ncon);
        for (k, st) in stages.iter().enumerate() {
            h.view_mut((ui(k), ui(k)), (nu, nu)).copy_from(&st.r_mat);
            g.rows_mut(ui(k), nu).copy_from(&st.r);
            if k == 0 {
                g.rows_mut(ui(0), nu)
                    .axpy(1.0, &(st.s_mat.transpose() * &x0), 1.0);
            } else {
                h.view_mut((xi(k), xi(k)), (nx, nx)).copy_from(&st.q_mat);
                h.view_mut((xi(k), ui(k)), (nx, nu)).copy_from(&st.s_mat);
                h.view_mut((ui(k), xi(k)), (nu, nx))
                    .copy_from(&st.s_mat.transpose());
                g.rows_mut(xi(k), nx).copy_from(&st.q);
            }
            // x_{k+1} − A x_k − B u_k = c
            jac.view_mut((k * nx, xi(k + 1)), (nx, nx))
                .copy_from(&DMatrix::identity(nx, nx));
            jac.view_mut((k * nx, ui(k)), (nx, nu)).copy_from(&(-&st.b));
            let mut r = st.c.clone();
            if k == 0 {
                r += &st.a * &x0;
            } else {
                jac.view_mut((k * nx, xi(k)), (nx, nx)).copy_from(&(-&st.a));
            }
            rhs.rows_mut(k * nx, nx).copy_from(&r);
        }
        h.view_mut((xi(n), xi(n)), (nx, nx)).copy_from(&q_n);
        g.rows_mut(xi(n), nx).copy_from(&q_vec_n);
        let mut kkt = DMatrix::<f64>::zeros(nz + ncon, nz + ncon);
        kkt.view_mut((0, 0), (nz, nz)).copy_from(&h);
        kkt.view_mut((nz, 0), (ncon, nz)).copy_from(&jac);
        kkt.view_mut((0, nz), (nz, ncon))
            .copy_from(&jac.transpose());
        let mut b = DVector::<f64>::zeros(nz + ncon);
        b.rows_mut(0, nz).copy_from(&(-&g));
        b.rows_mut(nz, ncon).copy_from(&rhs);
        let z = kkt.lu().solve(&b).unwrap();
        let mut worst: f64 = 0.0;
        for k in 0..n {
            worst = worst.max((z.rows(ui(k), nu) - &sol.u[k]).amax());
            worst = worst.max((z.rows(xi(k + 1), nx) - &sol.x[k + 1]).amax());
            // KKT multipliers ν of the rows (x_{k+1} − …): H z + Jᵀν = −g, so λ = −ν.
            worst = worst.max((z.rows(nz + k * nx, nx) + &sol.lambda[k]).amax());
        }
        println!("Riccati vs dense KKT: {worst:.2e}");
        assert!(worst < 1e-10);
    }

    #[test]
    fn indefinite_stage_is_reported() {
        let st = LqStage {
            q_mat: DMatrix::identity(1, 1),
            s_mat: DMatrix::zeros(1, 1),
            r_mat: DMatrix::from_element(1, 1, -1.0),
            q: DVector::zeros(1),
            r: DVector::zeros(1),
            a: DMatrix::identity(1, 1),
            b: DMatrix::zeros(1, 1),
            c: DVector::zeros(1),
        };
        let e = solve_lq(
            &[st],
            &DMatrix::identity(1, 1),
            &DVector::zeros(1),
            &DVector::zeros(1),
        );
        assert_eq!(
            e.unwrap_err(),
            RiccatiError::NotPositiveDefinite { stage: 0 }
        );
    }
}

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
//! right); otherwise the stage is reported so that the caller can regularise. A primal
//! shift `δ` (added to every `Q`, `R` and `Q_N`) is the caller's inertia correction.

use nalgebra::{SMatrix, SVector};

/// One stage of the LQ problem, fixed sizes (`NX` states, `NF` inputs).
#[derive(Clone, Debug)]
pub struct LqStage<const NX: usize, const NF: usize> {
    /// `Q`, the cost's state block.
    pub q_mat: SMatrix<f64, NX, NX>,
    /// `S`, its state–input block.
    pub s_mat: SMatrix<f64, NX, NF>,
    /// `R`, its input block.
    pub r_mat: SMatrix<f64, NF, NF>,
    /// `q`, the cost's state gradient.
    pub q: SVector<f64, NX>,
    /// `r`, its input gradient.
    pub r: SVector<f64, NF>,
    /// `A` of `x_{k+1} = A x_k + B u_k + c`.
    pub a: SMatrix<f64, NX, NX>,
    /// `B`.
    pub b: SMatrix<f64, NX, NF>,
    /// `c`.
    pub c: SVector<f64, NX>,
}

impl<const NX: usize, const NF: usize> LqStage<NX, NF> {
    /// Every block zero.
    pub fn zeros() -> Self {
        LqStage {
            q_mat: SMatrix::zeros(),
            s_mat: SMatrix::zeros(),
            r_mat: SMatrix::zeros(),
            q: SVector::zeros(),
            r: SVector::zeros(),
            a: SMatrix::zeros(),
            b: SMatrix::zeros(),
            c: SVector::zeros(),
        }
    }
}

/// The solution: states `x[0..=N]`, inputs `u[0..N]`, and the multipliers of the dynamics
/// (`lambda[k]` for the constraint that defines `x_{k+1}`).
#[derive(Clone, Debug)]
pub struct LqSolution<const NX: usize, const NF: usize> {
    /// The states.
    pub x: Vec<SVector<f64, NX>>,
    /// The inputs.
    pub u: Vec<SVector<f64, NF>>,
    /// The dynamics' multipliers.
    pub lambda: Vec<SVector<f64, NX>>,
}

/// Why the recursion stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum RiccatiError {
    /// `H_uu` not positive definite at this stage.
    NotPositiveDefinite {
        /// The stage.
        stage: usize,
    },
}

/// The backward sweep of the recursion, one stage at a time from `k = N−1` down, so that a
/// caller can run it while the stages are still being formed (the solver condenses stage
/// `k` on one thread while another sweeps through `k + 1 … N−1`).
pub struct BackwardSweep<const NX: usize, const NF: usize> {
    shift: f64,
    /// The terminal cost `(Q_N, q_N)` without the shift, for [`BackwardSweep::reshift`].
    terminal: (SMatrix<f64, NX, NX>, SVector<f64, NX>),
    eye_x: SMatrix<f64, NX, NX>,
    eye_u: SMatrix<f64, NF, NF>,
    /// `(P_k, p_k)` for `k = next … N` (a step reads `P_{k+1}` here, in place).
    cost_to_go: Vec<(SMatrix<f64, NX, NX>, SVector<f64, NX>)>,
    /// `(K_k, κ_k)` for `k = next … N−1`.
    gains: Vec<(SMatrix<f64, NF, NX>, SVector<f64, NF>)>,
    /// The stage the next [`BackwardSweep::step`] takes is `next − 1`.
    next: usize,
}

impl<const NX: usize, const NF: usize> BackwardSweep<NX, NF> {
    /// A sweep over `n` stages from the terminal cost `(q_n, q_vec_n)`, with the primal
    /// shift `shift`.
    pub fn new(
        n: usize,
        q_n: &SMatrix<f64, NX, NX>,
        q_vec_n: &SVector<f64, NX>,
        shift: f64,
    ) -> Self {
        let mut sweep = BackwardSweep {
            shift,
            terminal: (SMatrix::zeros(), SVector::zeros()),
            eye_x: SMatrix::zeros(),
            eye_u: SMatrix::zeros(),
            cost_to_go: Vec::new(),
            gains: Vec::new(),
            next: 0,
        };
        sweep.restart(n, q_n, q_vec_n, shift);
        sweep
    }

    /// The sweep begun again, as [`BackwardSweep::new`] would, in the buffers it has. A
    /// stage's `(P_k, p_k)` and gains are written by its step before anything may read them,
    /// so they are not cleared: filling 8 MB per factorisation, in fresh pages, was 3 % of
    /// a plan.
    pub fn restart(
        &mut self,
        n: usize,
        q_n: &SMatrix<f64, NX, NX>,
        q_vec_n: &SVector<f64, NX>,
        shift: f64,
    ) {
        self.shift = shift;
        self.terminal = (*q_n, *q_vec_n);
        self.eye_x = SMatrix::<f64, NX, NX>::identity() * shift;
        self.eye_u = SMatrix::<f64, NF, NF>::identity() * shift;
        let terminal = (q_n + self.eye_x, *q_vec_n);
        crate::solver::huge_pages::resize(&mut self.cost_to_go, n + 1, terminal);
        self.cost_to_go[n] = terminal;
        crate::solver::huge_pages::resize(&mut self.gains, n, (SMatrix::zeros(), SVector::zeros()));
        self.next = n;
    }

    /// The sweep begun again over the same stages and terminal cost with another primal
    /// shift (an inertia correction's next trial).
    pub fn reshift(&mut self, shift: f64) {
        let (n, (q_n, q_vec_n)) = (self.gains.len(), self.terminal);
        self.restart(n, &q_n, &q_vec_n, shift);
    }

    /// Every remaining stage of `stages`, last first.
    pub fn sweep_all(&mut self, stages: &[LqStage<NX, NF>]) -> Result<(), RiccatiError> {
        while let Some(k) = self.expects() {
            self.step(k, &stages[k])?;
        }
        Ok(())
    }

    /// The stage the next [`BackwardSweep::step`] expects, `None` when the sweep is done.
    pub fn expects(&self) -> Option<usize> {
        self.next.checked_sub(1)
    }

    /// Stage `k = next − 1` ([`BackwardSweep::expects`]) of the backward recursion.
    pub fn step(&mut self, k: usize, st: &LqStage<NX, NF>) -> Result<(), RiccatiError> {
        assert_eq!(
            Some(k),
            self.expects(),
            "the backward sweep takes the stages in order"
        );
        let (p_mat, p_vec) = &self.cost_to_go[k + 1];
        let pa = p_mat * st.a;
        let pb = p_mat * st.b;
        let pc = p_mat * st.c + p_vec;
        // Products with a transposed factor as `tr_mul` (column dot products, no transposed
        // copy), and `AᵀPA`, symmetric, formed on and above the diagonal only: the sweep is
        // the serial part of the Newton step.
        let huu = st.r_mat + self.eye_u + st.b.tr_mul(&pb);
        let hux = st.s_mat.transpose() + st.b.tr_mul(&pa);
        let hu = st.r + st.b.tr_mul(&pc);
        let hx = st.q + st.a.tr_mul(&pc);
        let chol = huu
            .cholesky()
            .ok_or(RiccatiError::NotPositiveDefinite { stage: k })?;
        let gain = -chol.solve(&hux);
        let ff = -chol.solve(&hu);
        // P_k = Q + I δ + AᵀPA + Hᵤₓᵀ K, symmetrised.
        let (q_mat, correction) = (&st.q_mat, hux.tr_mul(&gain));
        let mut p_new = SMatrix::<f64, NX, NX>::zeros();
        for j in 0..NX {
            for i in 0..=j {
                let atpa = st.a.column(i).dot(&pa.column(j));
                let sym = 0.5 * (q_mat[(i, j)] + q_mat[(j, i)])
                    + 0.5 * (correction[(i, j)] + correction[(j, i)]);
                p_new[(i, j)] = sym + self.eye_x[(i, j)] + atpa;
                p_new[(j, i)] = p_new[(i, j)];
            }
        }
        self.gains[k] = (gain, ff);
        self.cost_to_go[k] = (p_new, hx + hux.tr_mul(&ff));
        self.next = k;
        Ok(())
    }

    /// The primal shift of the sweep.
    pub fn shift(&self) -> f64 {
        self.shift
    }

    /// `(P_k, p_k)` of a swept stage (`k = N`: the terminal cost with the shift).
    pub fn cost_to_go(&self, k: usize) -> &(SMatrix<f64, NX, NX>, SVector<f64, NX>) {
        assert!(k >= self.next, "stage {k} is not swept yet");
        &self.cost_to_go[k]
    }

    /// `(K_k, κ_k)` of a swept stage.
    pub fn gain(&self, k: usize) -> &(SMatrix<f64, NF, NX>, SVector<f64, NF>) {
        assert!(k >= self.next, "stage {k} is not swept yet");
        &self.gains[k]
    }

    /// The forward pass from `x0` once every stage has been swept.
    pub fn forward(&self, stages: &[LqStage<NX, NF>], x0: &SVector<f64, NX>) -> LqSolution<NX, NF> {
        assert_eq!(self.next, 0, "the backward sweep is not complete");
        let n = stages.len();
        let mut x = Vec::with_capacity(n + 1);
        x.push(*x0);
        let mut u = Vec::with_capacity(n);
        let mut lambda = Vec::with_capacity(n);
        for (k, st) in stages.iter().enumerate() {
            let uk = self.gains[k].0 * x[k] + self.gains[k].1;
            let next = st.a * x[k] + st.b * uk + st.c;
            let (pm, pv) = &self.cost_to_go[k + 1];
            lambda.push(pm * next + pv);
            u.push(uk);
            x.push(next);
        }
        LqSolution { x, u, lambda }
    }
}

/// Solve the LQ problem over `stages[0..N]` and the terminal cost `(q_n, q_vec_n)` from
/// `x0`, with the primal shift `shift` (the tests' reference path).
#[cfg(test)]
pub fn solve_lq<const NX: usize, const NF: usize>(
    stages: &[LqStage<NX, NF>],
    q_n: &SMatrix<f64, NX, NX>,
    q_vec_n: &SVector<f64, NX>,
    x0: &SVector<f64, NX>,
    shift: f64,
) -> Result<LqSolution<NX, NF>, RiccatiError> {
    Ok(sweep_lq(stages, q_n, q_vec_n, shift)?.forward(stages, x0))
}

/// The backward sweep over `stages[0..N]` and the terminal cost `(q_n, q_vec_n)` with the
/// primal shift `shift`, complete (the tests' reference path).
#[cfg(test)]
pub fn sweep_lq<const NX: usize, const NF: usize>(
    stages: &[LqStage<NX, NF>],
    q_n: &SMatrix<f64, NX, NX>,
    q_vec_n: &SVector<f64, NX>,
    shift: f64,
) -> Result<BackwardSweep<NX, NF>, RiccatiError> {
    let mut sweep = BackwardSweep::new(stages.len(), q_n, q_vec_n, shift);
    sweep.sweep_all(stages)?;
    Ok(sweep)
}

#[cfg(test)]
mod tests {
    use super::*;
    use dmech_lie::lcg::Lcg;
    use nalgebra::{DMatrix, DVector};

    /// A deterministic pseudo-random matrix.
    fn mat(r: usize, c: usize, seed: &mut Lcg) -> DMatrix<f64> {
        DMatrix::from_fn(r, c, |_, _| seed.uniform())
    }

    /// A stage with dynamic sizes, for the dense assembly.
    struct DenseStage {
        q_mat: DMatrix<f64>,
        s_mat: DMatrix<f64>,
        r_mat: DMatrix<f64>,
        q: DVector<f64>,
        r: DVector<f64>,
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DVector<f64>,
    }

    fn fixed<const R: usize, const C: usize>(m: &DMatrix<f64>) -> SMatrix<f64, R, C> {
        SMatrix::from_column_slice(m.as_slice())
    }

    fn fixed_v<const R: usize>(v: &DVector<f64>) -> SVector<f64, R> {
        SVector::from_column_slice(v.as_slice())
    }

    /// The Riccati solution equals the solution of the whole KKT system, assembled densely
    /// and solved by LU (κ(KKT) ≈ 1e3 here, so agreement to ~1e-12).
    #[test]
    fn riccati_equals_dense_kkt() {
        const NX: usize = 4;
        const NF: usize = 2;
        let (nx, nu, n) = (NX, NF, 6usize);
        let mut seed = Lcg(3);
        let spd = |m: DMatrix<f64>, shift: f64| {
            &m * m.transpose() + DMatrix::identity(m.nrows(), m.nrows()) * shift
        };
        let vec = |m: DMatrix<f64>| DVector::from_column_slice(m.as_slice());
        let stages: Vec<DenseStage> = (0..n)
            .map(|_| DenseStage {
                q_mat: spd(mat(nx, nx, &mut seed), 0.1),
                s_mat: mat(nx, nu, &mut seed) * 0.1,
                r_mat: spd(mat(nu, nu, &mut seed), 0.5),
                q: vec(mat(nx, 1, &mut seed)),
                r: vec(mat(nu, 1, &mut seed)),
                a: DMatrix::identity(nx, nx) + mat(nx, nx, &mut seed) * 0.3,
                b: mat(nx, nu, &mut seed),
                c: vec(mat(nx, 1, &mut seed)),
            })
            .collect();
        let q_n = spd(mat(nx, nx, &mut seed), 0.1);
        let q_vec_n = vec(mat(nx, 1, &mut seed));
        let x0 = vec(mat(nx, 1, &mut seed));
        let lq: Vec<LqStage<NX, NF>> = stages
            .iter()
            .map(|st| LqStage {
                q_mat: fixed(&st.q_mat),
                s_mat: fixed(&st.s_mat),
                r_mat: fixed(&st.r_mat),
                q: fixed_v(&st.q),
                r: fixed_v(&st.r),
                a: fixed(&st.a),
                b: fixed(&st.b),
                c: fixed_v(&st.c),
            })
            .collect();
        let sol = solve_lq(&lq, &fixed(&q_n), &fixed_v(&q_vec_n), &fixed_v(&x0), 0.0).unwrap();
        // A sweep re-shifted (an inertia correction's retry) is the sweep begun with that
        // shift, to the bit; and back at shift 0 it is the unshifted one.
        let mut sweep = sweep_lq(&lq, &fixed(&q_n), &fixed_v(&q_vec_n), 0.0).unwrap();
        let shifted = sweep_lq(&lq, &fixed(&q_n), &fixed_v(&q_vec_n), 0.7).unwrap();
        sweep.reshift(0.7);
        sweep.sweep_all(&lq).unwrap();
        let (a, b) = (
            sweep.forward(&lq, &fixed_v(&x0)),
            shifted.forward(&lq, &fixed_v(&x0)),
        );
        assert_eq!((a.x, a.u, a.lambda), (b.x, b.u, b.lambda));
        sweep.reshift(0.0);
        sweep.sweep_all(&lq).unwrap();
        let back = sweep.forward(&lq, &fixed_v(&x0));
        assert_eq!((back.x, back.u), (sol.x.clone(), sol.u.clone()));

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
            worst = worst.max((z.fixed_rows::<NF>(ui(k)) - sol.u[k]).amax());
            worst = worst.max((z.fixed_rows::<NX>(xi(k + 1)) - sol.x[k + 1]).amax());
            // KKT multipliers ν of the rows (x_{k+1} − …): H z + Jᵀν = −g, so λ = −ν.
            worst = worst.max((z.fixed_rows::<NX>(nz + k * nx) + sol.lambda[k]).amax());
        }
        println!("Riccati vs dense KKT: {worst:.2e}");
        assert!(worst < 1e-10);
    }

    #[test]
    fn indefinite_stage_is_reported() {
        let st = LqStage::<1, 1> {
            q_mat: SMatrix::identity(),
            s_mat: SMatrix::zeros(),
            r_mat: SMatrix::from_element(-1.0),
            q: SVector::zeros(),
            r: SVector::zeros(),
            a: SMatrix::identity(),
            b: SMatrix::zeros(),
            c: SVector::zeros(),
        };
        let e = solve_lq(
            &[st],
            &SMatrix::identity(),
            &SVector::zeros(),
            &SVector::zeros(),
            0.0,
        );
        assert_eq!(
            e.unwrap_err(),
            RiccatiError::NotPositiveDefinite { stage: 0 }
        );
    }
}

//! The KKT system of the (globally coupled) LQ problem of [`crate::solver::kkt::global_riccati`] as one
//! sparse symmetric matrix, factorised by faer's sparse `LDLᵀ`: the alternative to the
//! augmented Riccati recursion, for problems whose coupling is not a stage chain.
//!
//! Unknowns in this order: `u_0, x_1, u_1, x_2, …, u_{N−1}, x_N` (primal), `p` (globals),
//! then the multipliers `ν_k` of the dynamics rows `x_{k+1} − A x_k − B u_k − B_θ θ_k = c_k`
//! and `ν_e` of the globals' equalities `A_g p = r_g`:
//! ```text
//! [H + δ_w I   Jᵀ     ] [z]   [−g]
//! [J           −δ_d I ] [ν] = [ r]
//! ```
//! The fill-reducing ordering (AMD) and the symbolic factorisation are computed once per
//! sparsity pattern ([`SparseKkt::new`]); each solve assembles the values, factorises
//! without pivoting (simplicial, so that `D` can be read), checks the inertia (`D` has as
//! many positive entries as primal unknowns: the reduced Hessian is positive definite) and
//! refines the solution twice against the matrix without the dual regularisation `δ_d`
//! (which only makes the pivots of the multipliers' block nonzero). The multipliers of the
//! dynamics in the Riccati convention are `λ_k = −ν_k`.

use crate::solver::kkt::global_riccati::LqCoupling;
use crate::solver::kkt::globals::GlobalTerms;
use crate::solver::kkt::riccati::{LqSolution, LqStage};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::ldlt::factor::{LdltParams, LdltRegularization};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LdltRef, SymbolicCholesky,
    SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::{Argsort, Pair, SparseColMat, SymbolicSparseColMat, Triplet};
use faer::{Conj, Mat, Par, Side};
use nalgebra::{DVector, SMatrix, SVector};

/// `δ_d`: the dual regularisation of the factorised matrix (refined away).
const DUAL_REGULARISATION: f64 = 1e-10;
/// Refinement steps against the unregularised matrix.
const REFINEMENT_STEPS: usize = 2;

/// Why a sparse solve failed.
#[derive(Clone, Debug, PartialEq)]
pub enum SparseKktError {
    /// The factorisation met a zero pivot.
    Singular,
    /// `D` has this many positive entries where the primal unknowns are `expected`.
    Inertia { positive: usize, expected: usize },
    /// faer could not build the matrix or its symbolic factorisation.
    Faer(String),
}

/// Sizes of the system: `n` stages, `n_g` globals, `n_e` equalities of the globals, the
/// stages' supports.
#[derive(Clone, Debug, PartialEq)]
struct Shape {
    n: usize,
    nx: usize,
    nu: usize,
    ng: usize,
    ne: usize,
    supports: Vec<Vec<usize>>,
}

impl Shape {
    fn u_at(&self, k: usize) -> usize {
        k * (self.nu + self.nx)
    }
    /// `x_k`, `k ≥ 1`.
    fn x_at(&self, k: usize) -> usize {
        (k - 1) * (self.nu + self.nx) + self.nu
    }
    fn p_at(&self) -> usize {
        self.n * (self.nu + self.nx)
    }
    fn nu_at(&self, k: usize) -> usize {
        self.p_at() + self.ng + k * self.nx
    }
    fn eq_at(&self) -> usize {
        self.nu_at(self.n)
    }
    fn primal(&self) -> usize {
        self.p_at() + self.ng
    }
    fn size(&self) -> usize {
        self.eq_at() + self.ne
    }
}

/// The symbolic factorisation of one sparsity pattern, reused by every solve of it.
pub struct SparseKkt {
    shape: Shape,
    /// The matrix's pattern and the order that sums an assembly's entries into it.
    pattern: SymbolicSparseColMat<usize>,
    argsort: Argsort<usize>,
    symbolic: SymbolicCholesky<usize>,
}

/// The upper triangle of the KKT matrix and its right-hand side.
struct Assembled {
    entries: Vec<Triplet<usize, usize, f64>>,
    rhs: Vec<f64>,
}

impl Assembled {
    fn add(&mut self, r: usize, c: usize, v: f64) {
        let (r, c) = if r <= c { (r, c) } else { (c, r) };
        self.entries.push(Triplet::new(r, c, v));
    }
    /// A dense block at `(r0, c0)`; on the diagonal (`r0 == c0`) its upper triangle.
    fn block<const R: usize, const C: usize>(
        &mut self,
        r0: usize,
        c0: usize,
        m: &SMatrix<f64, R, C>,
    ) {
        for i in 0..R {
            for j in 0..C {
                if r0 != c0 || i <= j {
                    self.add(r0 + i, c0 + j, m[(i, j)]);
                }
            }
        }
    }
}

impl SparseKkt {
    /// The pattern of `n` stages of `NX` states and `NF` inputs, the globals read through
    /// `supports`, `ne` equalities of `ng` globals; its AMD ordering and symbolic
    /// factorisation.
    pub fn new<const NX: usize, const NF: usize>(
        n: usize,
        ng: usize,
        ne: usize,
        supports: Vec<Vec<usize>>,
    ) -> Result<Self, SparseKktError> {
        let shape = Shape {
            n,
            nx: NX,
            nu: NF,
            ng,
            ne,
            supports,
        };
        // The pattern from an assembly of ones (every entry the solves will write).
        let one_stage = LqStage::<NX, NF> {
            q_mat: SMatrix::repeat(1.0),
            s_mat: SMatrix::repeat(1.0),
            r_mat: SMatrix::repeat(1.0),
            q: SVector::repeat(1.0),
            r: SVector::repeat(1.0),
            a: SMatrix::repeat(1.0),
            b: SMatrix::repeat(1.0),
            c: SVector::repeat(1.0),
        };
        let nt = shape.supports.first().map_or(0, |s| s.len());
        let one_coupling = LqCoupling::<NX, NF, 8> {
            s_xt: SMatrix::repeat(1.0),
            s_ut: SMatrix::repeat(1.0),
            r_tt: SMatrix::repeat(1.0),
            q_t: SVector::repeat(1.0),
            b_t: SMatrix::repeat(1.0),
        };
        assert!(nt <= 8, "at most 8 globals per stage");
        let terms = GlobalTerms {
            diag: vec![1.0; ng],
            grad: vec![1.0; ng],
            eq_a: vec![vec![1.0; ng]; ne],
            eq_rhs: vec![1.0; ne],
        };
        let stages = vec![one_stage; n];
        let couplings = vec![one_coupling; n];
        let a = assemble(
            &shape,
            &stages,
            &couplings,
            &SMatrix::repeat(1.0),
            &SVector::repeat(1.0),
            &SVector::repeat(1.0),
            1.0,
            &terms,
        );
        let size = shape.size();
        let pairs: Vec<Pair<usize, usize>> =
            a.entries.iter().map(|t| Pair::new(t.row, t.col)).collect();
        let (pattern, argsort) = SymbolicSparseColMat::try_new_from_indices(size, size, &pairs)
            .map_err(|e| SparseKktError::Faer(format!("{e:?}")))?;
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold:
                faer::sparse::linalg::SupernodalThreshold::FORCE_SIMPLICIAL,
            ..Default::default()
        };
        let symbolic = factorize_symbolic_cholesky(
            pattern.as_ref(),
            Side::Upper,
            SymmetricOrdering::Amd,
            params,
        )
        .map_err(|e| SparseKktError::Faer(format!("{e:?}")))?;
        Ok(SparseKkt {
            shape,
            pattern,
            argsort,
            symbolic,
        })
    }

    /// Solve the LQ problem with the globals' `couplings` (their `NT ≤ 8` columns), from
    /// `x0`, with primal shift `shift` and the globals' own `terms`: the states, inputs and
    /// dynamics multipliers, the globals' step and the equalities' multipliers.
    #[allow(clippy::too_many_arguments, clippy::type_complexity)]
    pub fn solve<const NX: usize, const NF: usize, const NT: usize>(
        &self,
        stages: &[LqStage<NX, NF>],
        couplings: &[LqCoupling<NX, NF, NT>],
        q_n: &SMatrix<f64, NX, NX>,
        q_vec_n: &SVector<f64, NX>,
        x0: &SVector<f64, NX>,
        shift: f64,
        terms: &GlobalTerms,
    ) -> Result<(LqSolution<NX, NF>, DVector<f64>, Vec<f64>), SparseKktError> {
        let sh = &self.shape;
        let a = assemble(sh, stages, couplings, q_n, q_vec_n, x0, shift, terms);
        let size = sh.size();
        let vals: Vec<f64> = a.entries.iter().map(|t| t.val).collect();
        let m = SparseColMat::<usize, f64>::new_from_argsort(
            self.pattern.clone(),
            &self.argsort,
            &vals,
        )
        .map_err(|e| SparseKktError::Faer(format!("{e:?}")))?;
        let mut values = vec![0.0f64; self.symbolic.len_val()];
        let params: faer::Spec<LdltParams, f64> = Default::default();
        let mut mem = MemBuffer::new(
            self.symbolic
                .factorize_numeric_ldlt_scratch::<f64>(Par::Seq, params)
                .or(self.symbolic.solve_in_place_scratch::<f64>(1, Par::Seq)),
        );
        let stack = MemStack::new(&mut mem);
        self.symbolic
            .factorize_numeric_ldlt(
                &mut values,
                m.as_ref(),
                Side::Upper,
                LdltRegularization::default(),
                Par::Seq,
                stack,
                params,
            )
            .map_err(|_| SparseKktError::Singular)?;
        let ldlt = LdltRef::new(&self.symbolic, &values);
        // Inertia from D, the diagonal of the simplicial factor.
        let SymbolicCholeskyRaw::Simplicial(simp) = self.symbolic.raw() else {
            unreachable!("the factorisation is forced simplicial")
        };
        let factor = simp.factor();
        let (col_ptr, row_idx) = (factor.col_ptr(), factor.row_idx());
        let mut positive = 0;
        for j in 0..size {
            let d = (col_ptr[j]..col_ptr[j + 1])
                .find(|&i| row_idx[i] == j)
                .map_or(0.0, |i| values[i]);
            if !d.is_finite() || d == 0.0 {
                return Err(SparseKktError::Singular);
            }
            positive += usize::from(d > 0.0);
        }
        if positive != sh.primal() {
            return Err(SparseKktError::Inertia {
                positive,
                expected: sh.primal(),
            });
        }
        // Solve, then refine against the matrix without δ_d.
        let mut z = Mat::<f64>::zeros(size, 1);
        for (i, v) in a.rhs.iter().enumerate() {
            z[(i, 0)] = *v;
        }
        ldlt.solve_in_place_with_conj(Conj::No, z.as_mut(), Par::Seq, stack);
        for _ in 0..REFINEMENT_STEPS {
            let mut r = Mat::<f64>::zeros(size, 1);
            let kz = sym_mul(&a.entries, size, sh.primal(), &z);
            for i in 0..size {
                r[(i, 0)] = a.rhs[i] - kz[i];
            }
            ldlt.solve_in_place_with_conj(Conj::No, r.as_mut(), Par::Seq, stack);
            for i in 0..size {
                z[(i, 0)] += r[(i, 0)];
            }
        }
        Ok(read(sh, &z, x0))
    }
}

/// `K z` of the symmetric matrix given by its upper triangle, without the dual
/// regularisation on the diagonal of the rows from `primal` on.
fn sym_mul(
    entries: &[Triplet<usize, usize, f64>],
    size: usize,
    primal: usize,
    z: &Mat<f64>,
) -> Vec<f64> {
    let mut out = vec![0.0; size];
    for t in entries {
        let (r, c, v) = (t.row, t.col, t.val);
        if r == c {
            if r < primal {
                out[r] += v * z[(c, 0)];
            }
        } else {
            out[r] += v * z[(c, 0)];
            out[c] += v * z[(r, 0)];
        }
    }
    // The dual diagonal holds only −δ_d (no other entry there): skipped above.
    out
}

/// The matrix's upper triangle and the right-hand side.
#[allow(clippy::too_many_arguments)]
fn assemble<const NX: usize, const NF: usize, const NT: usize>(
    sh: &Shape,
    stages: &[LqStage<NX, NF>],
    couplings: &[LqCoupling<NX, NF, NT>],
    q_n: &SMatrix<f64, NX, NX>,
    q_vec_n: &SVector<f64, NX>,
    x0: &SVector<f64, NX>,
    shift: f64,
    terms: &GlobalTerms,
) -> Assembled {
    let mut a = Assembled {
        entries: Vec::new(),
        rhs: vec![0.0; sh.size()],
    };
    let eye_x = SMatrix::<f64, NX, NX>::identity() * shift;
    let eye_u = SMatrix::<f64, NF, NF>::identity() * shift;
    let p0 = sh.p_at();
    for (k, (st, cp)) in stages.iter().zip(couplings).enumerate() {
        let sup = &sh.supports[k];
        let (u, lam) = (sh.u_at(k), sh.nu_at(k));
        a.block(u, u, &(st.r_mat + eye_u));
        let mut gu = st.r;
        let mut c = st.c;
        let mut gt: SVector<f64, NT> = cp.q_t;
        if k == 0 {
            // x_0 is given: its terms move to the right-hand side.
            gu += st.s_mat.transpose() * x0;
            c += st.a * x0;
            gt += cp.s_xt.transpose() * x0;
        } else {
            let x = sh.x_at(k);
            a.block(x, x, &(st.q_mat + eye_x));
            a.block(x, u, &st.s_mat);
            for (i, v) in st.q.iter().enumerate() {
                a.rhs[x + i] = -v;
            }
            for (t, &j) in sup.iter().enumerate() {
                for i in 0..NX {
                    a.add(x + i, p0 + j, cp.s_xt[(i, t)]);
                }
            }
            for i in 0..NX {
                for j in 0..NX {
                    a.add(x + j, lam + i, -st.a[(i, j)]);
                }
            }
        }
        for (i, v) in gu.iter().enumerate() {
            a.rhs[u + i] = -v;
        }
        for (t, &j) in sup.iter().enumerate() {
            for i in 0..NF {
                a.add(u + i, p0 + j, cp.s_ut[(i, t)]);
            }
            a.rhs[p0 + j] -= gt[t];
            for (t2, &j2) in sup.iter().enumerate() {
                if j <= j2 {
                    a.add(p0 + j, p0 + j2, cp.r_tt[(t, t2)]);
                }
            }
        }
        // The dynamics row: x_{k+1} − A x_k − B u_k − B_θ θ_k = c_k.
        let xn = sh.x_at(k + 1);
        for i in 0..NX {
            a.add(xn + i, lam + i, 1.0);
            for j in 0..NF {
                a.add(u + j, lam + i, -st.b[(i, j)]);
            }
            for (t, &j) in sup.iter().enumerate() {
                a.add(p0 + j, lam + i, -cp.b_t[(i, t)]);
            }
            a.add(lam + i, lam + i, -DUAL_REGULARISATION);
            a.rhs[lam + i] = c[i];
        }
    }
    let xn = sh.x_at(sh.n);
    a.block(xn, xn, &(q_n + eye_x));
    for (i, v) in q_vec_n.iter().enumerate() {
        a.rhs[xn + i] = -v;
    }
    for j in 0..sh.ng {
        a.add(p0 + j, p0 + j, terms.diag[j]);
        a.rhs[p0 + j] -= terms.grad[j];
    }
    for (e, (row, r)) in terms.eq_a.iter().zip(&terms.eq_rhs).enumerate() {
        let at = sh.eq_at() + e;
        for (j, v) in row.iter().enumerate() {
            a.add(p0 + j, at, *v);
        }
        a.add(at, at, -DUAL_REGULARISATION);
        a.rhs[at] = *r;
    }
    a
}

/// The solution in the Riccati's terms.
#[allow(clippy::type_complexity)]
fn read<const NX: usize, const NF: usize>(
    sh: &Shape,
    z: &Mat<f64>,
    x0: &SVector<f64, NX>,
) -> (LqSolution<NX, NF>, DVector<f64>, Vec<f64>) {
    let x = std::iter::once(*x0)
        .chain((1..=sh.n).map(|k| SVector::from_fn(|i, _| z[(sh.x_at(k) + i, 0)])))
        .collect();
    let u = (0..sh.n)
        .map(|k| SVector::from_fn(|i, _| z[(sh.u_at(k) + i, 0)]))
        .collect();
    let lambda = (0..sh.n)
        .map(|k| SVector::from_fn(|i, _| -z[(sh.nu_at(k) + i, 0)]))
        .collect();
    let p = DVector::from_fn(sh.ng, |j, _| z[(sh.p_at() + j, 0)]);
    let y = (0..sh.ne).map(|e| z[(sh.eq_at() + e, 0)]).collect();
    (LqSolution { x, u, lambda }, p, y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::kkt::global_riccati::{global_forward, global_sweep};
    use crate::solver::kkt::riccati::{solve_lq, sweep_lq};
    use dmech_lie::lcg::Lcg;
    use nalgebra::DMatrix;

    const NX: usize = 4;
    const NF: usize = 2;
    const NT: usize = 2;

    fn mat<const R: usize, const C: usize>(seed: &mut Lcg) -> SMatrix<f64, R, C> {
        SMatrix::from_fn(|_, _| seed.uniform())
    }

    /// Random stages: convex costs, dynamics near the identity.
    fn stages(n: usize, seed: &mut Lcg) -> Vec<LqStage<NX, NF>> {
        (0..n)
            .map(|_| {
                let (q, r): (SMatrix<f64, NX, NX>, SMatrix<f64, NF, NF>) = (mat(seed), mat(seed));
                LqStage {
                    q_mat: q * q.transpose() + SMatrix::identity() * 0.1,
                    s_mat: mat::<NX, NF>(seed) * 0.1,
                    r_mat: r * r.transpose() + SMatrix::identity() * 0.5,
                    q: mat(seed),
                    r: mat(seed),
                    a: SMatrix::identity() + mat::<NX, NX>(seed) * 0.3,
                    b: mat(seed),
                    c: mat(seed),
                }
            })
            .collect()
    }

    /// The KKT matrix of the sparse path densely (its upper triangle mirrored, without
    /// `δ_d`), for its condition number.
    fn dense(kkt: &SparseKkt, a: &Assembled) -> DMatrix<f64> {
        let size = kkt.shape.size();
        let mut m = DMatrix::zeros(size, size);
        for t in &a.entries {
            if t.row == t.col && t.row >= kkt.shape.primal() {
                continue;
            }
            m[(t.row, t.col)] += t.val;
            if t.row != t.col {
                m[(t.col, t.row)] += t.val;
            }
        }
        m
    }

    /// The largest difference allowed between two backward-stable solutions of one system:
    /// `2 n κ₂ ε ‖z‖` (each solver's backward error `≲ n ε ‖K‖‖z‖`, amplified by `κ₂`).
    /// The largest entry of `a − b` over every stage's `u`, `x_{k+1}`, `λ`, and the largest
    /// entry of `a` there.
    fn difference_and_size<const NX: usize, const NF: usize>(
        a: &LqSolution<NX, NF>,
        b: &LqSolution<NX, NF>,
    ) -> (f64, f64) {
        let (mut worst, mut size) = (0.0f64, 0.0f64);
        for k in 0..a.u.len() {
            worst = worst
                .max((a.u[k] - b.u[k]).amax())
                .max((a.x[k + 1] - b.x[k + 1]).amax())
                .max((a.lambda[k] - b.lambda[k]).amax());
            size = size
                .max(a.u[k].amax())
                .max(a.x[k + 1].amax())
                .max(a.lambda[k].amax());
        }
        (worst, size)
    }

    fn allowed(m: &DMatrix<f64>, z_norm: f64) -> f64 {
        let sv = m.clone().singular_values();
        let kappa = sv.max() / sv.min();
        2.0 * m.nrows() as f64 * kappa * f64::EPSILON * z_norm
    }

    /// Without globals (a fixed-time problem): the sparse LDLᵀ against the Riccati
    /// recursion, states, inputs and multipliers, within the round-off the conditioning
    /// allows.
    #[test]
    fn sparse_ldlt_equals_riccati_on_a_fixed_time_problem() {
        let n = 30;
        let mut seed = Lcg(5);
        let st = stages(n, &mut seed);
        let q_n: SMatrix<f64, NX, NX> = SMatrix::identity();
        let q_vec_n: SVector<f64, NX> = mat(&mut seed);
        let x0: SVector<f64, NX> = mat(&mut seed);
        let riccati = solve_lq(&st, &q_n, &q_vec_n, &x0, 0.0).unwrap();
        let kkt = SparseKkt::new::<NX, NF>(n, 0, 0, vec![Vec::new(); n]).unwrap();
        let none = vec![LqCoupling::<NX, NF, NT>::zeros(); n];
        let terms = GlobalTerms::default();
        let (sparse, _, _) = kkt
            .solve(&st, &none, &q_n, &q_vec_n, &x0, 0.0, &terms)
            .unwrap();
        let (worst, z_norm) = difference_and_size(&riccati, &sparse);
        let a = assemble(&kkt.shape, &st, &none, &q_n, &q_vec_n, &x0, 0.0, &terms);
        let bound = allowed(&dense(&kkt, &a), z_norm);
        println!("fixed time: sparse vs Riccati {worst:.2e}, allowed {bound:.2e}");
        assert!(worst <= bound, "{worst:e} > {bound:e}");
        // An indefinite stage: the inertia is reported, not a wrong step.
        let mut bad = st.clone();
        bad[7].r_mat = -bad[7].r_mat * 10.0;
        assert!(matches!(
            kkt.solve(&bad, &none, &q_n, &q_vec_n, &x0, 0.0, &terms),
            Err(SparseKktError::Inertia { .. })
        ));
    }

    /// With globals and an equality on them: the sparse path against the augmented
    /// Riccati recursion with its reduced system solved densely.
    #[test]
    fn sparse_ldlt_equals_augmented_riccati_with_globals() {
        let (n, ng) = (30, 3);
        let mut seed = Lcg(9);
        let st = stages(n, &mut seed);
        let cps: Vec<LqCoupling<NX, NF, NT>> = (0..n)
            .map(|_| {
                let r: SMatrix<f64, NT, NT> = mat(&mut seed);
                LqCoupling {
                    s_xt: mat::<NX, NT>(&mut seed) * 0.1,
                    s_ut: mat::<NF, NT>(&mut seed) * 0.1,
                    r_tt: r * r.transpose() + SMatrix::identity(),
                    q_t: mat(&mut seed),
                    b_t: mat::<NX, NT>(&mut seed) * 0.3,
                }
            })
            .collect();
        let supports: Vec<Vec<usize>> = (0..n)
            .map(|k| vec![k * ng / n, (k + 1) * ng / n % ng])
            .collect();
        let q_n: SMatrix<f64, NX, NX> = SMatrix::identity();
        let q_vec_n: SVector<f64, NX> = mat(&mut seed);
        let x0: SVector<f64, NX> = mat(&mut seed);
        let terms = GlobalTerms {
            diag: vec![0.5, 1.0, 2.0],
            grad: vec![0.3, -0.2, 0.1],
            eq_a: vec![vec![1.0, 2.0, 3.0]],
            eq_rhs: vec![0.25],
        };
        // Riccati: the sweep, the globals' columns, the reduced system densely.
        let sweep = sweep_lq(&st, &q_n, &q_vec_n, 0.0).unwrap();
        let support = |k: usize| &supports[k][..];
        let schur = global_sweep(&sweep, &st, &cps, &support, ng, &x0).unwrap();
        let mut m = DMatrix::<f64>::zeros(ng + 1, ng + 1);
        m.view_mut((0, 0), (ng, ng)).copy_from(&schur.psi);
        let mut rhs = DVector::<f64>::zeros(ng + 1);
        for j in 0..ng {
            m[(j, j)] += terms.diag[j];
            m[(j, ng)] = terms.eq_a[0][j];
            m[(ng, j)] = terms.eq_a[0][j];
            rhs[j] = -(schur.psi_vec[j] + terms.grad[j]);
        }
        rhs[ng] = terms.eq_rhs[0];
        let sol = m.lu().solve(&rhs).unwrap();
        let dp = sol.rows(0, ng).into_owned();
        let riccati = global_forward(&sweep, &schur, &st, &cps, &support, &x0, &dp);
        let kkt = SparseKkt::new::<NX, NF>(n, ng, 1, supports.clone()).unwrap();
        let (sparse, p, y) = kkt
            .solve(&st, &cps, &q_n, &q_vec_n, &x0, 0.0, &terms)
            .unwrap();
        let (stages, stage_norm) = difference_and_size(&riccati, &sparse);
        let worst = stages.max((p - &dp).amax()).max((y[0] - sol[ng]).abs());
        let z_norm = stage_norm.max(dp.amax()).max(sol[ng].abs());
        let a = assemble(&kkt.shape, &st, &cps, &q_n, &q_vec_n, &x0, 0.0, &terms);
        let bound = allowed(&dense(&kkt, &a), z_norm);
        println!("globals: sparse vs Riccati {worst:.2e}, allowed {bound:.2e}");
        assert!(worst <= bound, "{worst:e} > {bound:e}");
    }
}

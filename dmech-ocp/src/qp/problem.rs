//! The stage-structured convex QP: its stages, terminal stage and constraint rows, validated.

use nalgebra::{SMatrix, SVector};

/// The price of violating a soft row: `l1 · v + ½ l2 · v²` for a violation `v ≥ 0` of
/// either side. `l1` above the row's multiplier makes the penalty exact (the row holds
/// whenever it can).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoftPrice {
    /// Price per unit of violation.
    pub l1: f64,
    /// Price of the squared violation (halved).
    pub l2: f64,
}

impl SoftPrice {
    /// An L1 price alone.
    pub fn l1(l1: f64) -> Self {
        SoftPrice { l1, l2: 0.0 }
    }
}

/// `NC` constraint rows `lo ≤ D x + E u ≤ hi` of a stage (the terminal stage has no `u`:
/// its `E` is ignored). A side at `±∞` is absent; a row with both sides infinite is free.
#[derive(Clone, Debug, PartialEq)]
pub struct Rows<const NX: usize, const NU: usize, const NC: usize> {
    /// `D`.
    pub d: SMatrix<f64, NC, NX>,
    /// `E`.
    pub e: SMatrix<f64, NC, NU>,
    /// Lower bounds (`−∞` allowed).
    pub lo: SVector<f64, NC>,
    /// Upper bounds (`+∞` allowed).
    pub hi: SVector<f64, NC>,
    /// `Some(price)` for a soft row, `None` for a hard one.
    pub soft: [Option<SoftPrice>; NC],
}

impl<const NX: usize, const NU: usize, const NC: usize> Rows<NX, NU, NC> {
    /// Every row free: zero coefficients, bounds `±∞`, hard.
    pub fn free() -> Self {
        Rows {
            d: SMatrix::zeros(),
            e: SMatrix::zeros(),
            lo: SVector::repeat(f64::NEG_INFINITY),
            hi: SVector::repeat(f64::INFINITY),
            soft: [None; NC],
        }
    }

    /// Row `row` as the box `lo ≤ u[input] ≤ hi` on one input.
    pub fn input_bound(&mut self, row: usize, input: usize, lo: f64, hi: f64) -> &mut Self {
        self.set_row(row, SVector::zeros(), unit(input), lo, hi)
    }

    /// Row `row` as the box `lo ≤ x[state] ≤ hi` on one state.
    pub fn state_bound(&mut self, row: usize, state: usize, lo: f64, hi: f64) -> &mut Self {
        self.set_row(row, unit(state), SVector::zeros(), lo, hi)
    }

    /// Row `row` as `lo ≤ dᵀx + eᵀu ≤ hi` (hard until [`Rows::soften`]).
    pub fn set_row(
        &mut self,
        row: usize,
        d: SVector<f64, NX>,
        e: SVector<f64, NU>,
        lo: f64,
        hi: f64,
    ) -> &mut Self {
        self.d.set_row(row, &d.transpose());
        self.e.set_row(row, &e.transpose());
        self.lo[row] = lo;
        self.hi[row] = hi;
        self
    }

    /// Make row `row` soft with `price`.
    pub fn soften(&mut self, row: usize, price: SoftPrice) -> &mut Self {
        self.soft[row] = Some(price);
        self
    }
}

/// The `i`-th unit vector.
fn unit<const N: usize>(i: usize) -> SVector<f64, N> {
    SVector::from_fn(|r, _| if r == i { 1.0 } else { 0.0 })
}

/// Stage `k < N`: cost `½ [x;u]ᵀ [Q S; Sᵀ R] [x;u] + qᵀx + rᵀu`, dynamics
/// `x_{k+1} = A x + B u + c`, and its rows.
#[derive(Clone, Debug, PartialEq)]
pub struct Stage<const NX: usize, const NU: usize, const NC: usize> {
    /// `A`.
    pub a: SMatrix<f64, NX, NX>,
    /// `B`.
    pub b: SMatrix<f64, NX, NU>,
    /// `c`.
    pub c: SVector<f64, NX>,
    /// `Q` (symmetric).
    pub q: SMatrix<f64, NX, NX>,
    /// `S`, the state–input block.
    pub s: SMatrix<f64, NX, NU>,
    /// `R` (symmetric).
    pub r: SMatrix<f64, NU, NU>,
    /// The state gradient `q`.
    pub q_vec: SVector<f64, NX>,
    /// The input gradient `r`.
    pub r_vec: SVector<f64, NU>,
    /// The constraint rows.
    pub rows: Rows<NX, NU, NC>,
}

impl<const NX: usize, const NU: usize, const NC: usize> Stage<NX, NU, NC> {
    /// A stage with every block zero and every row free.
    pub fn zeros() -> Self {
        Stage {
            a: SMatrix::zeros(),
            b: SMatrix::zeros(),
            c: SVector::zeros(),
            q: SMatrix::zeros(),
            s: SMatrix::zeros(),
            r: SMatrix::zeros(),
            q_vec: SVector::zeros(),
            r_vec: SVector::zeros(),
            rows: Rows::free(),
        }
    }
}

/// The terminal stage `N`: cost `½ x_Nᵀ Q_N x_N + q_Nᵀ x_N` and rows on `x_N` alone.
#[derive(Clone, Debug, PartialEq)]
pub struct Terminal<const NX: usize, const NU: usize, const NC: usize> {
    /// `Q_N` (symmetric).
    pub q: SMatrix<f64, NX, NX>,
    /// `q_N`.
    pub q_vec: SVector<f64, NX>,
    /// The rows (`E` ignored).
    pub rows: Rows<NX, NU, NC>,
}

impl<const NX: usize, const NU: usize, const NC: usize> Terminal<NX, NU, NC> {
    /// Zero cost, every row free.
    pub fn zeros() -> Self {
        Terminal {
            q: SMatrix::zeros(),
            q_vec: SVector::zeros(),
            rows: Rows::free(),
        }
    }
}

/// Why a QP was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum QpError {
    /// No stage.
    #[error("the horizon is empty")]
    EmptyHorizon,
    /// A NaN or an infinity in the data (bounds may be infinite, not NaN).
    #[error("stage {stage}: {what} is not finite")]
    NotFinite {
        /// The stage (`N` for the terminal stage).
        stage: usize,
        /// Which block.
        what: &'static str,
    },
    /// `lo > hi`, or a bound `lo = +∞` / `hi = −∞`.
    #[error("stage {stage}, row {row}: the bounds [{lo}, {hi}] are empty")]
    EmptyBounds {
        /// The stage.
        stage: usize,
        /// The row.
        row: usize,
        /// Its lower bound.
        lo: f64,
        /// Its upper bound.
        hi: f64,
    },
    /// A soft row's prices are negative, not finite, or both zero.
    #[error("stage {stage}, row {row}: a soft price must be finite, ≥ 0 and not both zero")]
    BadPrice {
        /// The stage.
        stage: usize,
        /// The row.
        row: usize,
    },
    /// A stage's Hessian `[Q S; Sᵀ R]` (or `Q_N`) is not symmetric positive semidefinite.
    #[error("stage {stage}: the Hessian is not symmetric positive semidefinite")]
    NotConvex {
        /// The stage.
        stage: usize,
    },
}

/// A stage-structured convex QP (module doc of [`crate::qp`]), validated on construction.
#[derive(Clone, Debug)]
pub struct StageQp<const NX: usize, const NU: usize, const NC: usize> {
    x0: SVector<f64, NX>,
    stages: Vec<Stage<NX, NU, NC>>,
    terminal: Terminal<NX, NU, NC>,
    /// Each stage's `Aᵀ` and each stage's rows' `Dᵀ` (`0 … N`): the interior point's
    /// products with them (`Aᵀπ`, `AᵀPA`, `AᵀPB`, `Dᵀλ`) become `axpy`s over their
    /// columns rather than dot products.
    a_t: Vec<SMatrix<f64, NX, NX>>,
    d_t: Vec<SMatrix<f64, NX, NC>>,
}

impl<const NX: usize, const NU: usize, const NC: usize> StageQp<NX, NU, NC> {
    /// The QP from the initial state `x0`, stages `0 … N−1` and the terminal stage `N`.
    pub fn new(
        x0: SVector<f64, NX>,
        stages: Vec<Stage<NX, NU, NC>>,
        terminal: Terminal<NX, NU, NC>,
    ) -> Result<Self, QpError> {
        if stages.is_empty() {
            return Err(QpError::EmptyHorizon);
        }
        finite(stages.len(), "x0", x0.as_slice())?;
        for (k, st) in stages.iter().enumerate() {
            validate_stage(k, st)?;
        }
        let n = stages.len();
        finite(n, "Q_N", terminal.q.as_slice())?;
        finite(n, "q_N", terminal.q_vec.as_slice())?;
        validate_rows(n, &terminal.rows)?;
        if !positive_semidefinite(&terminal.q) {
            return Err(QpError::NotConvex { stage: n });
        }
        let a_t = stages.iter().map(|st| st.a.transpose()).collect();
        let rows = stages.iter().map(|st| &st.rows).chain([&terminal.rows]);
        let d_t = rows.map(|rows| rows.d.transpose()).collect();
        Ok(StageQp {
            x0,
            stages,
            terminal,
            a_t,
            d_t,
        })
    }

    /// The horizon `N`.
    pub fn horizon(&self) -> usize {
        self.stages.len()
    }

    /// The initial state.
    pub fn x0(&self) -> &SVector<f64, NX> {
        &self.x0
    }

    /// The stages `0 … N−1`.
    pub fn stages(&self) -> &[Stage<NX, NU, NC>] {
        &self.stages
    }

    /// The terminal stage.
    pub fn terminal(&self) -> &Terminal<NX, NU, NC> {
        &self.terminal
    }

    /// `A_kᵀ`.
    pub(crate) fn a_t(&self, k: usize) -> &SMatrix<f64, NX, NX> {
        &self.a_t[k]
    }

    /// `D_kᵀ` of the rows of stage `k ≤ N`.
    pub(crate) fn d_t(&self, k: usize) -> &SMatrix<f64, NX, NC> {
        &self.d_t[k]
    }

    /// The rows of stage `k ≤ N`.
    pub fn rows(&self, k: usize) -> &Rows<NX, NU, NC> {
        match self.stages.get(k) {
            Some(st) => &st.rows,
            None => &self.terminal.rows,
        }
    }

    /// The objective at the states `x[0..=N]` and inputs `u[0..N]`, soft rows' violations
    /// priced.
    pub fn objective(&self, x: &[SVector<f64, NX>], u: &[SVector<f64, NU>]) -> f64 {
        let mut f = 0.0;
        for (k, st) in self.stages.iter().enumerate() {
            let (xk, uk) = (&x[k], &u[k]);
            f += 0.5 * xk.dot(&(st.q * xk)) + xk.dot(&(st.s * uk)) + 0.5 * uk.dot(&(st.r * uk));
            f += st.q_vec.dot(xk) + st.r_vec.dot(uk);
            f += soft_cost(&st.rows, &(st.rows.d * xk + st.rows.e * uk));
        }
        let (t, xn) = (&self.terminal, &x[self.stages.len()]);
        f += 0.5 * xn.dot(&(t.q * xn)) + t.q_vec.dot(xn);
        f + soft_cost(&t.rows, &(t.rows.d * xn))
    }
}

/// The soft rows' price at the row values `z`.
fn soft_cost<const NX: usize, const NU: usize, const NC: usize>(
    rows: &Rows<NX, NU, NC>,
    z: &SVector<f64, NC>,
) -> f64 {
    (0..NC)
        .filter_map(|i| {
            let price = rows.soft[i]?;
            let v = (z[i] - rows.hi[i]).max(rows.lo[i] - z[i]).max(0.0);
            Some(price.l1 * v + 0.5 * price.l2 * v * v)
        })
        .sum()
}

/// Every entry of `v` finite: no entry with the exponent bits all set (an infinity or a
/// NaN), tested by an or over the entries (no early exit: the loop vectorises).
fn finite(stage: usize, what: &'static str, v: &[f64]) -> Result<(), QpError> {
    const EXPONENT: u64 = 0x7ff0_0000_0000_0000;
    let not_finite = v
        .iter()
        .fold(false, |acc, x| acc | (x.to_bits() & EXPONENT == EXPONENT));
    match !not_finite {
        true => Ok(()),
        false => Err(QpError::NotFinite { stage, what }),
    }
}

fn validate_stage<const NX: usize, const NU: usize, const NC: usize>(
    k: usize,
    st: &Stage<NX, NU, NC>,
) -> Result<(), QpError> {
    finite(k, "A", st.a.as_slice())?;
    finite(k, "B", st.b.as_slice())?;
    finite(k, "c", st.c.as_slice())?;
    finite(k, "Q", st.q.as_slice())?;
    finite(k, "S", st.s.as_slice())?;
    finite(k, "R", st.r.as_slice())?;
    finite(k, "q", st.q_vec.as_slice())?;
    finite(k, "r", st.r_vec.as_slice())?;
    validate_rows(k, &st.rows)?;
    if diagonal_hessian(st) {
        return Ok(());
    }
    // [Q S; Sᵀ R] by its entries.
    let h = |i: usize, j: usize| match (i < NX, j < NX) {
        (true, true) => st.q[(i, j)],
        (true, false) => st.s[(i, j - NX)],
        (false, true) => st.s[(j, i - NX)],
        (false, false) => st.r[(i - NX, j - NX)],
    };
    match positive_semidefinite_by(NX + NU, h) {
        true => Ok(()),
        false => Err(QpError::NotConvex { stage: k }),
    }
}

/// Whether the stage's Hessian `[Q S; Sᵀ R]` is diagonal and semidefinite: `S = 0`, `Q`
/// and `R` without off-diagonal entries and every diagonal entry at least `−ε` (the
/// MPC's stages). [`positive_semidefinite_by`] gives the same answer by its entries, at
/// several times the cost; `false` says only that the fast test does not apply or fails.
fn diagonal_hessian<const NX: usize, const NU: usize, const NC: usize>(
    st: &Stage<NX, NU, NC>,
) -> bool {
    fn off_diagonal_zero<const N: usize>(m: &SMatrix<f64, N, N>) -> bool {
        (0..N).all(|c| (0..N).all(|r| r == c || m[(r, c)] == 0.0))
    }
    if st.s.iter().any(|&v| v != 0.0) || !off_diagonal_zero(&st.q) || !off_diagonal_zero(&st.r) {
        return false;
    }
    let eps = 1e-12 * (NX + NU) as f64 * st.q.amax().max(st.r.amax());
    (0..NX).all(|i| st.q[(i, i)] >= -eps) && (0..NU).all(|i| st.r[(i, i)] >= -eps)
}

fn validate_rows<const NX: usize, const NU: usize, const NC: usize>(
    k: usize,
    rows: &Rows<NX, NU, NC>,
) -> Result<(), QpError> {
    finite(k, "D", rows.d.as_slice())?;
    finite(k, "E", rows.e.as_slice())?;
    for i in 0..NC {
        let (lo, hi) = (rows.lo[i], rows.hi[i]);
        if lo.is_nan() || hi.is_nan() || lo > hi || lo == f64::INFINITY || hi == f64::NEG_INFINITY {
            return Err(QpError::EmptyBounds {
                stage: k,
                row: i,
                lo,
                hi,
            });
        }
        if let Some(p) = rows.soft[i] {
            let ok = |v: f64| v.is_finite() && v >= 0.0;
            if !ok(p.l1) || !ok(p.l2) || p.l1 + p.l2 == 0.0 {
                return Err(QpError::BadPrice { stage: k, row: i });
            }
        }
    }
    Ok(())
}

/// Whether the symmetric matrix `h` is positive semidefinite ([`positive_semidefinite_by`]).
fn positive_semidefinite<R, C, S>(h: &nalgebra::Matrix<f64, R, C, S>) -> bool
where
    R: nalgebra::Dim,
    C: nalgebra::Dim,
    S: nalgebra::RawStorage<f64, R, C>,
{
    positive_semidefinite_by(h.nrows(), |i, j| h[(i, j)])
}

/// Whether the symmetric `n × n` matrix with the entries `h(i, j)` is positive
/// semidefinite, by a Cholesky factorisation with diagonal pivoting (the largest
/// remaining diagonal first, which keeps the rounding at `O(n u max|h_ij|)`): once every
/// remaining diagonal is below `ε = 1e-12 n max|h_ij|`, the remainder of a semidefinite
/// matrix is zero to rounding, so a remaining entry above `√(ε max|h_ij|)` (or a diagonal
/// below `−ε`) refutes it. Asymmetry beyond `ε` refutes it too. An index without an
/// off-diagonal entry (a diagonal cost term, a zero row) takes no part in the
/// factorisation (a pivot on it changes no other entry): it is checked on its own,
/// `h_ii ≥ −ε`, and the factorisation runs on the coupled indices alone (none for a
/// diagonal Hessian, and then nothing is allocated).
fn positive_semidefinite_by(n: usize, h: impl Fn(usize, usize) -> f64) -> bool {
    let mut scale: f64 = 0.0;
    for i in 0..n {
        for j in 0..n {
            scale = scale.max(h(i, j).abs());
        }
    }
    let eps = 1e-12 * n as f64 * scale;
    let mut coupled = Vec::new();
    for i in 0..n {
        let mut alone = true;
        for j in 0..n {
            if j < i && (h(i, j) - h(j, i)).abs() > eps {
                return false;
            }
            alone &= j == i || h(i, j) == 0.0;
        }
        match alone {
            true if h(i, i) < -eps => return false,
            true => {}
            false => coupled.push(i),
        }
    }
    if coupled.is_empty() {
        return true;
    }
    let c = coupled.len();
    let mut m = nalgebra::DMatrix::<f64>::from_fn(c, c, |i, j| h(coupled[i], coupled[j]));
    let mut left: Vec<usize> = (0..c).collect();
    while let Some((at, &k)) = left
        .iter()
        .enumerate()
        .max_by(|a, b| m[(*a.1, *a.1)].total_cmp(&m[(*b.1, *b.1)]))
    {
        let p = m[(k, k)];
        if p <= eps {
            let tol = (eps * scale).sqrt();
            return left
                .iter()
                .all(|&i| m[(i, i)] >= -eps && left.iter().all(|&j| m[(i, j)].abs() <= tol));
        }
        left.swap_remove(at);
        for &j in &left {
            let f = m[(j, k)] / p;
            for &i in &left {
                m[(i, j)] -= f * m[(i, k)];
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn semidefinite_test_separates_the_cases() {
        let psd = SMatrix::<f64, 3, 3>::new(2.0, 1.0, 0.0, 1.0, 0.5, 0.0, 0.0, 0.0, 0.0);
        assert!(positive_semidefinite(&psd));
        let indefinite = SMatrix::<f64, 2, 2>::new(1.0, 2.0, 2.0, 1.0);
        assert!(!positive_semidefinite(&indefinite));
        // A zero pivot with a coupling below it: [[0, 1], [1, 1]] has eigenvalues ±.
        let coupled = SMatrix::<f64, 2, 2>::new(0.0, 1.0, 1.0, 1.0);
        assert!(!positive_semidefinite(&coupled));
    }

    #[test]
    fn indices_without_coupling_are_checked_alone() {
        // Index 0 decoupled; {1, 2} coupled and semidefinite (determinant zero).
        let psd = SMatrix::<f64, 3, 3>::new(1.0, 0.0, 0.0, 0.0, 2.0, 1.0, 0.0, 1.0, 0.5);
        assert!(positive_semidefinite(&psd));
        let negative_alone =
            SMatrix::<f64, 3, 3>::new(-1e-3, 0.0, 0.0, 0.0, 2.0, 1.0, 0.0, 1.0, 0.5);
        assert!(!positive_semidefinite(&negative_alone));
        let indefinite_block =
            SMatrix::<f64, 3, 3>::new(1.0, 0.0, 0.0, 0.0, 1.0, 2.0, 0.0, 2.0, 1.0);
        assert!(!positive_semidefinite(&indefinite_block));
        let diagonal = SMatrix::<f64, 2, 2>::new(3.0, 0.0, 0.0, 0.0);
        assert!(positive_semidefinite(&diagonal));
    }

    #[test]
    fn diagonal_hessians_take_the_fast_test_with_the_same_answer() {
        let mut st = Stage::<3, 2, 1>::zeros();
        st.q = SMatrix::from_diagonal(&SVector::from([3000.0, 0.0, 1e-9]));
        st.r = SMatrix::from_diagonal(&SVector::from([2.0, 2.0]));
        assert!(diagonal_hessian(&st));
        assert!(validate_stage(0, &st).is_ok());
        st.q[(1, 1)] = -1e-3;
        assert!(!diagonal_hessian(&st));
        assert_eq!(validate_stage(0, &st), Err(QpError::NotConvex { stage: 0 }));
        // x_1 (no cost of its own) coupled to u_0: indefinite.
        st.q[(1, 1)] = 0.0;
        st.s[(1, 0)] = 1.0;
        assert!(!diagonal_hessian(&st));
        assert_eq!(validate_stage(0, &st), Err(QpError::NotConvex { stage: 0 }));
    }

    #[test]
    fn empty_bounds_and_bad_prices_are_refused() {
        let mut st = Stage::<1, 1, 1>::zeros();
        st.rows.input_bound(0, 0, 1.0, 0.0);
        let e = StageQp::new(SVector::zeros(), vec![st.clone()], Terminal::zeros());
        assert!(matches!(
            e,
            Err(QpError::EmptyBounds {
                stage: 0,
                row: 0,
                ..
            })
        ));
        st.rows
            .input_bound(0, 0, 0.0, 1.0)
            .soften(0, SoftPrice::l1(0.0));
        let e = StageQp::new(SVector::zeros(), vec![st], Terminal::zeros());
        assert_eq!(e.unwrap_err(), QpError::BadPrice { stage: 0, row: 0 });
    }
}

//! The discrete algebraic Riccati equation `P = AᵀPA − AᵀPB (R + BᵀPB)⁻¹ BᵀPA + Q` by the
//! structured doubling algorithm, with a residual check, and the LQ gain from it.

use nalgebra::{DMatrix, SMatrix};

fn dyn_of<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> DMatrix<f64> {
    DMatrix::from_column_slice(R, C, m.as_slice())
}

/// `X` solving `S X = Y` (LU with partial pivoting), `None` if `S` is singular.
fn solve_dyn(s: DMatrix<f64>, y: DMatrix<f64>) -> Option<DMatrix<f64>> {
    s.lu().solve(&y)
}

fn static_of<const R: usize, const C: usize>(m: &DMatrix<f64>) -> SMatrix<f64, R, C> {
    SMatrix::<f64, R, C>::from_column_slice(m.as_slice())
}

/// Why a DARE has no accepted solution.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DareError {
    #[error("a matrix in the doubling iteration is singular")]
    Singular,
    #[error("the doubling iteration did not converge in {0} iterations")]
    NoConvergence(usize),
    #[error("the Riccati residual {0:.3e} (relative to ‖P‖) is above the accepted 1e-9")]
    Residual(f64),
}

/// The stabilising solution `P` and the gain `K = (R + BᵀPB)⁻¹ BᵀPA` (`u = −K z`).
#[derive(Debug, Clone)]
pub struct LqDesign<const N: usize, const M: usize> {
    pub p: SMatrix<f64, N, N>,
    pub k: SMatrix<f64, M, N>,
    /// `‖AᵀPA − P − AᵀPB(R + BᵀPB)⁻¹BᵀPA + Q‖_F / ‖P‖_F`.
    pub residual: f64,
}

/// The residual of the DARE at `P`, relative to `‖P‖`.
pub fn dare_residual<const N: usize, const M: usize>(
    a: &SMatrix<f64, N, N>,
    b: &SMatrix<f64, N, M>,
    q: &SMatrix<f64, N, N>,
    r: &SMatrix<f64, M, M>,
    p: &SMatrix<f64, N, N>,
) -> Option<f64> {
    let s = r + b.transpose() * p * b;
    let kk: SMatrix<f64, M, N> =
        static_of(&solve_dyn(dyn_of(&s), dyn_of(&(b.transpose() * p * a)))?);
    let res = a.transpose() * p * a - p - a.transpose() * p * b * kk + q;
    Some(res.norm() / p.norm().max(f64::MIN_POSITIVE))
}

/// Solve the DARE by structured doubling (Chu, Fan, Lin 2005): with `G = B R⁻¹ Bᵀ`,
/// `A ← A (I + G H)⁻¹ A`, `G ← G + A (I + G H)⁻¹ G Aᵀ`, `H ← H + Aᵀ H (I + G H)⁻¹ A`, and
/// `H → P` quadratically when `(A, B)` is stabilisable and `(A, Q)` detectable.
pub fn solve_dare<const N: usize, const M: usize>(
    a: &SMatrix<f64, N, N>,
    b: &SMatrix<f64, N, M>,
    q: &SMatrix<f64, N, N>,
    r: &SMatrix<f64, M, M>,
) -> Result<LqDesign<N, M>, DareError> {
    const MAX_IT: usize = 100;
    let r_inv: SMatrix<f64, M, M> = static_of(&dyn_of(r).try_inverse().ok_or(DareError::Singular)?);
    let (mut ak, mut g, mut h) = (*a, b * r_inv * b.transpose(), *q);
    let id = SMatrix::<f64, N, N>::identity();
    let mut converged = false;
    for _ in 0..MAX_IT {
        let w = dyn_of(&(id + g * h)).lu();
        let w_a: SMatrix<f64, N, N> = static_of(&w.solve(&dyn_of(&ak)).ok_or(DareError::Singular)?);
        let w_g: SMatrix<f64, N, N> = static_of(&w.solve(&dyn_of(&g)).ok_or(DareError::Singular)?);
        let h_next = h + ak.transpose() * h * w_a;
        let g_next = g + ak * w_g * ak.transpose();
        ak *= w_a;
        let change = (h_next - h).norm();
        h = 0.5 * (h_next + h_next.transpose());
        g = 0.5 * (g_next + g_next.transpose());
        if change <= 1e-13 * h.norm() {
            converged = true;
            break;
        }
    }
    if !converged {
        return Err(DareError::NoConvergence(MAX_IT));
    }
    let p = h;
    let residual = dare_residual(a, b, q, r, &p).ok_or(DareError::Singular)?;
    // Doubling reaches the fixed point to rounding: a residual of 1e-9 relative leaves
    // ample room for the conditioning of the WIP's (stiff) model.
    if residual > 1e-9 {
        return Err(DareError::Residual(residual));
    }
    let k = static_of(
        &solve_dyn(
            dyn_of(&(r + b.transpose() * p * b)),
            dyn_of(&(b.transpose() * p * a)),
        )
        .ok_or(DareError::Singular)?,
    );
    Ok(LqDesign { p, k, residual })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix1, Matrix2, Vector2};

    /// A scalar DARE has a closed form: `p = a²p − a²b²p²/(r + b²p) + q`, i.e.
    /// `b²p² + (r − a²r − qb²) p − qr = 0`, whose positive root is the solution.
    #[test]
    fn scalar_dare_matches_its_closed_form() {
        let (a, b, q, r) = (1.2, 0.5, 2.0, 0.3);
        let d = solve_dare(
            &Matrix1::new(a),
            &Matrix1::new(b),
            &Matrix1::new(q),
            &Matrix1::new(r),
        )
        .unwrap();
        let (qa, qb, qc) = (b * b, r - a * a * r - q * b * b, -q * r);
        let root = (-qb + (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa);
        assert!((d.p[0] - root).abs() < 1e-12 * root, "{} vs {root}", d.p[0]);
        assert!((a - b * d.k[0]).abs() < 1.0);
    }

    /// A discrete double integrator: the solution has a small residual and `A − BK` is
    /// stable.
    #[test]
    fn double_integrator_is_stabilised() {
        let h = 0.1;
        let a = Matrix2::new(1.0, h, 0.0, 1.0);
        let b = Vector2::new(0.5 * h * h, h);
        let d = solve_dare(&a, &b, &Matrix2::identity(), &Matrix1::new(1.0)).unwrap();
        assert!(d.residual < 1e-12);
        let cl = a - b * d.k;
        assert!(cl.complex_eigenvalues().iter().all(|l| l.norm() < 1.0));
    }
}

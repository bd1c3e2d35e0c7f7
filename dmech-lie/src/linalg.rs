//! A small dense solve generic over the scalar (so that solutions carry dual derivatives).

use crate::Real;
use nalgebra::{SMatrix, SVector};

/// Solve `M x = b` (one use of [`Lu`]). Returns `None` if a pivot is zero or not finite.
pub fn solve<T: Real, const N: usize>(
    m: &SMatrix<T, N, N>,
    b: &SVector<T, N>,
) -> Option<SVector<T, N>> {
    Lu::new(m).map(|lu| lu.solve(b))
}

/// An LU factorisation with row pivoting (chosen on the real parts), for repeated solves
/// with the same matrix (chord steps of Newton's method).
#[derive(Clone, Copy, Debug)]
pub struct Lu<T: Real, const N: usize> {
    lu: SMatrix<T, N, N>,
    perm: [usize; N],
}

impl<T: Real, const N: usize> Lu<T, N> {
    /// Factor `m`; `None` if a pivot is zero or not finite.
    pub fn new(m: &SMatrix<T, N, N>) -> Option<Self> {
        let mut a = *m;
        let mut perm = [0usize; N];
        for (i, p) in perm.iter_mut().enumerate() {
            *p = i;
        }
        for col in 0..N {
            // Pivots chosen on the real parts; no elimination is skipped on a zero real
            // part, since the dual parts may still be nonzero.
            let piv = (col..N)
                .max_by(|&i, &j| a[(i, col)].re().abs().total_cmp(&a[(j, col)].re().abs()))?;
            let p = a[(piv, col)].re();
            if p == 0.0 || !p.is_finite() {
                return None;
            }
            if piv != col {
                a.swap_rows(piv, col);
                perm.swap(piv, col);
            }
            let inv = a[(col, col)].recip();
            for r in col + 1..N {
                let f = a[(r, col)] * inv;
                a[(r, col)] = f;
                for c in col + 1..N {
                    let v = a[(col, c)];
                    a[(r, c)] -= f * v;
                }
            }
        }
        Some(Lu { lu: a, perm })
    }

    /// Solve `M x = b`.
    pub fn solve(&self, b: &SVector<T, N>) -> SVector<T, N> {
        self.solve_columns(b)
    }

    /// Solve `M X = B` for a matrix of right-hand sides: forward and back substitution
    /// row by row over all columns at once (a column at a time was a tenth of the KKT
    /// condensing). The columns do not mix, so each is what [`Lu::solve`] gives for it.
    pub fn solve_columns<const C: usize>(&self, b: &SMatrix<T, N, C>) -> SMatrix<T, N, C> {
        let mut x = SMatrix::<T, N, C>::from_fn(|i, j| b[(self.perm[i], j)]);
        for r in 0..N {
            for c in 0..r {
                let l = self.lu[(r, c)];
                for j in 0..C {
                    let v = l * x[(c, j)];
                    x[(r, j)] -= v;
                }
            }
        }
        for r in (0..N).rev() {
            for c in r + 1..N {
                let u = self.lu[(r, c)];
                for j in 0..C {
                    let v = u * x[(c, j)];
                    x[(r, j)] -= v;
                }
            }
            let d = self.lu[(r, r)];
            for j in 0..C {
                x[(r, j)] /= d;
            }
        }
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix4, Vector4};

    #[test]
    fn lu_and_solve_agree_with_nalgebra() {
        let m = Matrix4::new(
            0.1, 2.0, -1.0, 0.5, 3.0, 0.2, 0.0, 1.0, -1.0, 0.3, 4.0, 0.0, 0.5, 1.0, 0.0, 2.0,
        );
        let b = Vector4::new(1.0, -2.0, 0.5, 3.0);
        let want = m.lu().solve(&b).unwrap();
        let x1 = solve(&m, &b).unwrap();
        let x2 = Lu::new(&m).unwrap().solve(&b);
        // κ(m) ≈ 10: agreement to a few ε·κ.
        assert!((x1 - want).amax() < 1e-14 && (x2 - want).amax() < 1e-14);
        assert!(Lu::new(&Matrix4::<f64>::zeros()).is_none());
        let cols = Lu::new(&m).unwrap().solve_columns(&Matrix4::identity());
        assert!((cols - m.try_inverse().unwrap()).amax() < 1e-14);
        // All columns at once: each one bitwise the single-column solve.
        let b = nalgebra::Matrix4x3::from_fn(|i, j| (i as f64 + 1.0).sin() * (j as f64 - 0.7));
        let lu = Lu::new(&m).unwrap();
        let x = lu.solve_columns(&b);
        for j in 0..3 {
            assert_eq!(
                x.column(j),
                lu.solve(&b.column(j).into_owned()),
                "column {j}"
            );
        }
    }
}

//! A small dense solve generic over the scalar (so that solutions carry dual derivatives).

use dmech_lie::Real;
use nalgebra::{SMatrix, SVector};

/// Solve `M x = b` by Gaussian elimination with partial pivoting chosen on the real parts.
/// Returns `None` if a pivot is zero or not finite.
pub fn solve<T: Real, const N: usize>(
    m: &SMatrix<T, N, N>,
    b: &SVector<T, N>,
) -> Option<SVector<T, N>> {
    let mut a = *m;
    let mut x = *b;
    for col in 0..N {
        let piv =
            (col..N).max_by(|&i, &j| a[(i, col)].re().abs().total_cmp(&a[(j, col)].re().abs()))?;
        let p = a[(piv, col)].re();
        if p == 0.0 || !p.is_finite() {
            return None;
        }
        if piv != col {
            a.swap_rows(piv, col);
            x.swap_rows(piv, col);
        }
        let inv = a[(col, col)].recip();
        for r in col + 1..N {
            // No skipping on a zero real part: the dual parts may still be nonzero.
            let f = a[(r, col)] * inv;
            for c in col..N {
                let v = a[(col, c)];
                a[(r, c)] -= f * v;
            }
            let xc = x[col];
            x[r] -= f * xc;
        }
    }
    for col in (0..N).rev() {
        let mut acc = x[col];
        for c in col + 1..N {
            acc -= a[(col, c)] * x[c];
        }
        x[col] = acc / a[(col, col)];
    }
    Some(x)
}

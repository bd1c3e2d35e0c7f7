//! Products of the small fixed-size matrices of the Newton step, written as column
//! `axpy`s and column dot products that the compiler unrolls and vectorises, skipping the
//! structural zeros of the right factor (an entry of `B` in `A B`, a column of `A` in
//! `Aᵀ B`): a stage's `A` and `B` often carry zero blocks (an input memory in the state,
//! rows without a term), and a skipped entry saves a whole column operation.

use nalgebra::{SMatrix, SVector};

/// `A B`.
#[inline]
pub(crate) fn mul<const R: usize, const K: usize, const C: usize>(
    a: &SMatrix<f64, R, K>,
    b: &SMatrix<f64, K, C>,
) -> SMatrix<f64, R, C> {
    let mut out = SMatrix::<f64, R, C>::zeros();
    for c in 0..C {
        let col = &mut out.as_mut_slice()[c * R..(c + 1) * R];
        for k in 0..K {
            let s = b[(k, c)];
            if s != 0.0 {
                let a_col = &a.as_slice()[k * R..(k + 1) * R];
                for r in 0..R {
                    col[r] += a_col[r] * s;
                }
            }
        }
    }
    out
}

/// `A v`.
#[inline]
pub(crate) fn mul_vec<const R: usize, const K: usize>(
    a: &SMatrix<f64, R, K>,
    v: &SVector<f64, K>,
) -> SVector<f64, R> {
    let mut out = SVector::<f64, R>::zeros();
    for k in 0..K {
        let s = v[k];
        if s != 0.0 {
            let a_col = &a.as_slice()[k * R..(k + 1) * R];
            for r in 0..R {
                out[r] += a_col[r] * s;
            }
        }
    }
    out
}

/// `Aᵀ B`, a zero column of `A` giving a zero row without a product.
#[inline]
pub(crate) fn tr_mul<const K: usize, const R: usize, const C: usize>(
    a: &SMatrix<f64, K, R>,
    b: &SMatrix<f64, K, C>,
) -> SMatrix<f64, R, C> {
    let mut out = SMatrix::<f64, R, C>::zeros();
    for r in 0..R {
        let a_col = &a.as_slice()[r * K..(r + 1) * K];
        if a_col.iter().all(|&x| x == 0.0) {
            continue;
        }
        for c in 0..C {
            out[(r, c)] = dot(a_col, &b.as_slice()[c * K..(c + 1) * K]);
        }
    }
    out
}

/// `A B` for a product known to be symmetric (`Aᵀ P A` as `Aᵀ (P A)`), formed on and
/// above the diagonal alone, by blocks of four rows (the entries below the diagonal
/// within a block formed too, the rest zero): each entry summed as [`mul`] sums it, to the
/// bit, but in a register rather than through memory, and half the blocks.
#[inline]
pub(crate) fn mul_upper<const N: usize, const K: usize>(
    a: &SMatrix<f64, N, K>,
    b: &SMatrix<f64, K, N>,
) -> SMatrix<f64, N, N> {
    const W: usize = 4;
    let mut out = SMatrix::<f64, N, N>::zeros();
    for c in 0..N {
        let b_col = &b.as_slice()[c * K..(c + 1) * K];
        for r0 in (0..=c).step_by(W) {
            let mut acc = [0.0; W];
            if r0 + W <= N {
                for k in 0..K {
                    let s = b_col[k];
                    if s != 0.0 {
                        let a_block = &a.as_slice()[k * N + r0..k * N + r0 + W];
                        for r in 0..W {
                            acc[r] += a_block[r] * s;
                        }
                    }
                }
            } else {
                for k in 0..K {
                    let s = b_col[k];
                    if s != 0.0 {
                        for r in r0..N {
                            acc[r - r0] += a[(r, k)] * s;
                        }
                    }
                }
            }
            let len = W.min(N - r0);
            out.as_mut_slice()[c * N + r0..c * N + r0 + len].copy_from_slice(&acc[..len]);
        }
    }
    out
}

/// `Aᵀ v`.
#[inline]
pub(crate) fn tr_mul_vec<const K: usize, const R: usize>(
    a: &SMatrix<f64, K, R>,
    v: &SVector<f64, K>,
) -> SVector<f64, R> {
    SVector::from_fn(|r, _| dot(&a.as_slice()[r * K..(r + 1) * K], v.as_slice()))
}

/// `aᵀb` in four interleaved partial sums (`i mod 4`), added pairwise at the end: the
/// compiler keeps a float sum in order, so one accumulator would be a chain of dependent
/// additions; four are one vector register.
#[inline]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..4 {
            acc[i] += x[i] * y[i];
        }
    }
    for (i, (x, y)) in ra.iter().zip(rb).enumerate() {
        acc[i] += x * y;
    }
    (acc[0] + acc[2]) + (acc[1] + acc[3])
}

/// The lower-triangular Cholesky factor `L` of `M = L Lᵀ`, `None` where a pivot is not
/// positive: nalgebra's `Cholesky::new(M).unpack()` operation for operation (left-looking,
/// a column at a time), without its generic set-up, which cost as much as the 2 × 2
/// factorisation of `R̂` itself.
#[inline]
pub(crate) fn cholesky<const N: usize>(m: &SMatrix<f64, N, N>) -> Option<SMatrix<f64, N, N>> {
    let mut l = *m;
    for j in 0..N {
        for k in 0..j {
            let f = l[(j, k)];
            for i in j..N {
                l[(i, j)] -= f * l[(i, k)];
            }
        }
        // A zero, negative or NaN pivot fails.
        let pivot = l[(j, j)];
        if pivot.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let d = pivot.sqrt();
        l[(j, j)] = d;
        for i in j + 1..N {
            l[(i, j)] /= d;
        }
        for i in 0..j {
            l[(i, j)] = 0.0;
        }
    }
    Some(l)
}

/// `X = (L Lᵀ)⁻¹ B` for a lower-triangular `L` with a positive diagonal: forward and back
/// substitution, column by column.
#[inline]
pub(crate) fn cholesky_solve<const N: usize, const C: usize>(
    l: &SMatrix<f64, N, N>,
    b: &SMatrix<f64, N, C>,
) -> SMatrix<f64, N, C> {
    let mut x = *b;
    for c in 0..C {
        for i in 0..N {
            let mut v = x[(i, c)];
            for k in 0..i {
                v -= l[(i, k)] * x[(k, c)];
            }
            x[(i, c)] = v / l[(i, i)];
        }
        for i in (0..N).rev() {
            let mut v = x[(i, c)];
            for k in i + 1..N {
                v -= l[(k, i)] * x[(k, c)];
            }
            x[(i, c)] = v / l[(i, i)];
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_is_nalgebras_to_the_bit() {
        let b = SMatrix::<f64, 3, 3>::new(2.0, 0.3, -1.1, 0.7, 1.9, 0.2, -0.4, 0.05, 3.3);
        let m = b * b.transpose() + SMatrix::identity() * 1e-3;
        let ours = cholesky(&m).expect("positive definite");
        assert_eq!(ours, m.cholesky().expect("positive definite").unpack());
        let indefinite = SMatrix::<f64, 2, 2>::new(1.0, 2.0, 2.0, 1.0);
        assert!(cholesky(&indefinite).is_none());
        assert!(cholesky(&SMatrix::<f64, 2, 2>::zeros()).is_none());
    }

    #[test]
    fn mul_upper_is_muls_upper_triangle_to_the_bit() {
        let a = SMatrix::<f64, 10, 10>::from_fn(|r, c| ((r * 7 + c * 3) % 11) as f64 / 7.0 - 0.6);
        let mut p = a * a.transpose();
        p.column_mut(8).fill(0.0);
        p[(2, 5)] = 0.0;
        let (full, upper) = (mul(&a.transpose(), &p), mul_upper(&a.transpose(), &p));
        for c in 0..10 {
            for r in 0..=c {
                assert_eq!(
                    full[(r, c)].to_bits(),
                    upper[(r, c)].to_bits(),
                    "({r}, {c})"
                );
            }
        }
    }
}

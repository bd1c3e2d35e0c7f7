//! Random feasible stage QPs: stable-ish dynamics, a convex stage Hessian with `R ⪰ I`,
//! rows around a random trajectory (some tight, some loose, some infinite), some soft.

use dmech_lie::rng::Rng;
use dmech_ocp::qp::{Rows, SoftPrice, Stage, StageQp, Terminal};
use nalgebra::{SMatrix, SVector};

fn matrix<const R: usize, const C: usize>(rng: &mut Rng, scale: f64) -> SMatrix<f64, R, C> {
    SMatrix::from_fn(|_, _| scale * rng.normal())
}

/// `[Q S; Sᵀ R] = L Lᵀ + blockdiag(0, I)`, `L` of rank at most `(NX + NU)/2`: convex,
/// often singular in `Q`, and strongly convex in the inputs with modulus at least 1.
fn hessian<const NX: usize, const NU: usize>(
    rng: &mut Rng,
) -> (
    SMatrix<f64, NX, NX>,
    SMatrix<f64, NX, NU>,
    SMatrix<f64, NU, NU>,
) {
    let n = NX + NU;
    let rank = n.div_ceil(2);
    let l = nalgebra::DMatrix::<f64>::from_fn(n, rank, |_, _| rng.normal());
    let h = &l * l.transpose();
    let q = SMatrix::<f64, NX, NX>::from_fn(|i, j| h[(i, j)]);
    let s = SMatrix::<f64, NX, NU>::from_fn(|i, j| h[(i, NX + j)]);
    let r = SMatrix::<f64, NU, NU>::from_fn(|i, j| h[(NX + i, NX + j)]) + SMatrix::identity();
    (q, s, r)
}

/// Rows of `(d, e)` around the row values `z` of a reference trajectory: each side finite
/// with probability 0.8, at a distance uniform in `[0, 2 |z| + 1)·slack` from `z`, so
/// that the reference satisfies the hard rows and the optimum presses on some; each row
/// soft with probability `soft` at an L1 price in `[0.1, 10)` (often below its
/// multiplier: violated at the optimum) and an L2 price half the time.
fn rows<const NX: usize, const NU: usize, const NC: usize>(
    rng: &mut Rng,
    d: SMatrix<f64, NC, NX>,
    e: SMatrix<f64, NC, NU>,
    z: SVector<f64, NC>,
    soft: f64,
) -> Rows<NX, NU, NC> {
    let mut rows = Rows::free();
    rows.d = d;
    rows.e = e;
    for i in 0..NC {
        let reach = 0.3 * (2.0 * z[i].abs() + 1.0);
        if rng.uniform() < 0.8 {
            rows.hi[i] = z[i] + reach * rng.uniform();
        }
        if rng.uniform() < 0.8 {
            rows.lo[i] = z[i] - reach * rng.uniform();
        }
        if rng.uniform() < soft {
            let l2 = if rng.uniform() < 0.5 {
                rng.range(0.1, 2.0)
            } else {
                0.0
            };
            rows.soften(
                i,
                SoftPrice {
                    l1: rng.range(0.1, 10.0),
                    l2,
                },
            );
        }
    }
    rows
}

/// A random QP of horizon `n` with every `NC`-th row … (module doc); `soft` the
/// probability of a soft row.
pub fn stage_qp<const NX: usize, const NU: usize, const NC: usize>(
    seed: u64,
    n: usize,
    soft: f64,
) -> StageQp<NX, NU, NC> {
    let mut rng = Rng::new(seed);
    let x0: SVector<f64, NX> = matrix(&mut rng, 1.0);
    let mut x = x0;
    let mut stages = Vec::with_capacity(n);
    for _ in 0..n {
        let mut st = Stage::<NX, NU, NC>::zeros();
        st.a = SMatrix::identity() + matrix(&mut rng, 0.3 / (NX as f64).sqrt());
        st.b = matrix(&mut rng, 0.5);
        st.c = matrix(&mut rng, 0.1);
        (st.q, st.s, st.r) = hessian(&mut rng);
        st.q_vec = matrix(&mut rng, 1.0);
        st.r_vec = matrix(&mut rng, 1.0);
        let u: SVector<f64, NU> = matrix(&mut rng, 0.5);
        let (d, e) = (matrix(&mut rng, 1.0), matrix(&mut rng, 1.0));
        st.rows = rows(&mut rng, d, e, d * x + e * u, soft);
        x = st.a * x + st.b * u + st.c;
        stages.push(st);
    }
    let mut terminal = Terminal::<NX, NU, NC>::zeros();
    let (q, _, _) = hessian::<NX, NU>(&mut rng);
    terminal.q = q;
    terminal.q_vec = matrix(&mut rng, 1.0);
    let d = matrix(&mut rng, 1.0);
    terminal.rows = rows(&mut rng, d, SMatrix::zeros(), d * x, soft);
    StageQp::new(x0, stages, terminal).expect("a valid QP")
}

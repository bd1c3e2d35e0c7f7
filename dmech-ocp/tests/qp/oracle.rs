//! A stage QP written out for clarabel as one sparse program:
//! `min ½ vᵀPv + qᵀv` s.t. `Av + s = b`, `s ∈ {0}ⁿ × ℝ₊ᵐ`, `v = (x_1 … x_N, u_0 … u_{N−1}, σ)`
//! with one violation `σ ≥ 0` per soft row (both sides share it; at most one is violated).

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus, ZeroConeT,
};
use dmech_ocp::qp::StageQp;
use nalgebra::SVector;

/// clarabel's solution of a stage QP.
pub struct OracleSolution<const NU: usize> {
    pub u: Vec<SVector<f64, NU>>,
    pub objective: f64,
}

#[derive(Default)]
struct Triplets {
    rows: Vec<usize>,
    cols: Vec<usize>,
    vals: Vec<f64>,
}

impl Triplets {
    fn put(&mut self, r: usize, c: usize, v: f64) {
        if v != 0.0 {
            self.rows.push(r);
            self.cols.push(c);
            self.vals.push(v);
        }
    }
}

/// Solve `qp` with clarabel at gap and feasibility tolerances `tol`; `None` unless solved.
pub fn solve<const NX: usize, const NU: usize, const NC: usize>(
    qp: &StageQp<NX, NU, NC>,
    tol: f64,
) -> Option<OracleSolution<NU>> {
    let n = qp.horizon();
    let xi = |k: usize, i: usize| NX * (k - 1) + i; // k ≥ 1
    let ui = |k: usize, i: usize| NX * n + NU * k + i;
    let mut n_var = (NX + NU) * n;
    // One violation variable per soft row with a finite side.
    let mut soft_var = vec![[None; NC]; n + 1];
    for (k, sv) in soft_var.iter_mut().enumerate() {
        let rows = qp.rows(k);
        for i in 0..NC {
            if rows.soft[i].is_some() && (rows.lo[i].is_finite() || rows.hi[i].is_finite()) {
                sv[i] = Some(n_var);
                n_var += 1;
            }
        }
    }
    let (mut p, mut q) = (Triplets::default(), vec![0.0; n_var]);
    let x0 = qp.x0();
    let mut constant = 0.0;
    for (k, st) in qp.stages().iter().enumerate() {
        for c in 0..NU {
            for r in 0..=c {
                p.put(ui(k, r), ui(k, c), st.r[(r, c)]);
            }
            q[ui(k, c)] += st.r_vec[c];
        }
        if k == 0 {
            let sx = st.s.transpose() * x0;
            for c in 0..NU {
                q[ui(0, c)] += sx[c];
            }
            constant += 0.5 * x0.dot(&(st.q * x0)) + st.q_vec.dot(x0);
            continue;
        }
        for c in 0..NX {
            for r in 0..=c {
                p.put(xi(k, r), xi(k, c), st.q[(r, c)]);
            }
            for w in 0..NU {
                p.put(xi(k, c), ui(k, w), st.s[(c, w)]);
            }
            q[xi(k, c)] += st.q_vec[c];
        }
    }
    let t = qp.terminal();
    for c in 0..NX {
        for r in 0..=c {
            p.put(xi(n, r), xi(n, c), t.q[(r, c)]);
        }
        q[xi(n, c)] += t.q_vec[c];
    }
    for k in 0..=n {
        let rows = qp.rows(k);
        for i in 0..NC {
            if let (Some(v), Some(price)) = (soft_var[k][i], rows.soft[i]) {
                p.put(v, v, price.l2);
                q[v] += price.l1;
            }
        }
    }
    // Dynamics: x_{k+1} − A x_k − B u_k = c_k (+ A_0 x_0 for k = 0).
    let (mut a, mut b) = (Triplets::default(), Vec::new());
    for (k, st) in qp.stages().iter().enumerate() {
        let rhs = if k == 0 { st.c + st.a * x0 } else { st.c };
        for r in 0..NX {
            let row = b.len();
            a.put(row, xi(k + 1, r), 1.0);
            for c in 0..NX {
                if k > 0 {
                    a.put(row, xi(k, c), -st.a[(r, c)]);
                }
            }
            for w in 0..NU {
                a.put(row, ui(k, w), -st.b[(r, w)]);
            }
            b.push(rhs[r]);
        }
    }
    let n_eq = b.len();
    // Rows: ±(D x + E u) − σ ≤ ±bound, D_0 x_0 on the right; then −σ ≤ 0.
    for k in 0..=n {
        let rows = qp.rows(k);
        for i in 0..NC {
            for (sign, bound) in [(1.0, rows.hi[i]), (-1.0, -rows.lo[i])] {
                if !bound.is_finite() {
                    continue;
                }
                let row = b.len();
                let mut rhs = bound;
                for c in 0..NX {
                    let v = sign * rows.d[(i, c)];
                    if k == 0 {
                        rhs -= v * x0[c];
                    } else {
                        a.put(row, xi(k, c), v);
                    }
                }
                if k < n {
                    for w in 0..NU {
                        a.put(row, ui(k, w), sign * rows.e[(i, w)]);
                    }
                }
                if let Some(v) = soft_var[k][i] {
                    a.put(row, v, -1.0);
                }
                b.push(rhs);
            }
            if let Some(v) = soft_var[k][i] {
                let row = b.len();
                a.put(row, v, -1.0);
                b.push(0.0);
            }
        }
    }
    let m = b.len();
    let p = CscMatrix::new_from_triplets(n_var, n_var, p.rows, p.cols, p.vals);
    let a = CscMatrix::new_from_triplets(m, n_var, a.rows, a.cols, a.vals);
    let cones = [ZeroConeT(n_eq), NonnegativeConeT(m - n_eq)];
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(tol)
        .tol_gap_rel(tol)
        .tol_feas(tol)
        .build()
        .expect("valid settings");
    let mut solver = DefaultSolver::new(&p, &q, &a, &b, &cones, settings).ok()?;
    solver.solve();
    if solver.solution.status != SolverStatus::Solved {
        return None;
    }
    let v = &solver.solution.x;
    let u = (0..n)
        .map(|k| SVector::from_fn(|i, _| v[ui(k, i)]))
        .collect();
    Some(OracleSolution {
        u,
        objective: solver.solution.obj_val + constant,
    })
}

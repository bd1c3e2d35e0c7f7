//! `clarabel` as an independent oracle: on a convex linear–quadratic OCP with bounds on
//! the input and on a state component and a terminal state, the interior point's solution
//! equals the one `clarabel` finds for the same QP written out as one sparse program
//! (a different algorithm and a different linear algebra: a homogeneous embedding with a
//! sparse LDLᵀ of the whole KKT matrix, against our Riccati recursion over the stages).

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus, ZeroConeT,
};
use dmech_lie::Real;
use dmech_ocp::nlp::{StageProblem, StateEquality};
use dmech_ocp::solver::{IpOptions, Solver, Status};
use nalgebra::SVector;

/// A double integrator `x = (p, v)`, `w = u`, cost `½(u² + q_v v² + q_p p²)` per stage,
/// `|u| ≤ u_max`, `|v| ≤ v_max`, from rest at 0 to rest at `target`.
struct LinearQuadratic {
    n: usize,
    h: f64,
    q_p: f64,
    q_v: f64,
    u_max: f64,
    v_max: f64,
    target: f64,
}

impl StageProblem<2, 1, 0, 1, 2> for LinearQuadratic {
    fn horizon(&self) -> usize {
        self.n
    }
    fn initial_state(&self) -> SVector<f64, 2> {
        SVector::zeros()
    }
    fn dynamics<T: Real>(&self, _k: usize, x: &SVector<T, 2>, w: &SVector<T, 1>) -> SVector<T, 2> {
        SVector::<T, 2>::new(x[0] + x[1] * self.h, x[1] + w[0] * self.h)
    }
    fn equality<T: Real>(
        &self,
        _k: usize,
        _x: &SVector<T, 2>,
        _w: &SVector<T, 1>,
    ) -> SVector<T, 0> {
        SVector::zeros()
    }
    fn cost<T: Real>(&self, _k: usize, x: &SVector<T, 2>, w: &SVector<T, 1>) -> T {
        (w[0] * w[0] + x[1] * x[1] * self.q_v + x[0] * x[0] * self.q_p) * 0.5
    }
    fn constraints<T: Real>(
        &self,
        _k: usize,
        x: &SVector<T, 2>,
        w: &SVector<T, 1>,
    ) -> SVector<T, 2> {
        SVector::<T, 2>::new(w[0], x[1])
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, 2>, SVector<f64, 2>) {
        let hi = SVector::<f64, 2>::new(self.u_max, self.v_max);
        (-hi, hi)
    }
    fn state_equalities(&self) -> Vec<StateEquality> {
        vec![
            StateEquality {
                stage: self.n,
                index: 0,
                value: self.target,
            },
            StateEquality {
                stage: self.n,
                index: 1,
                value: 0.0,
            },
        ]
    }
}

/// The same problem as one QP for clarabel: `z = (x_1 … x_N, u_0 … u_{N−1})` (`x_0 = 0`),
/// `min ½ zᵀPz` s.t. dynamics and terminal state (zero cone), bounds (non-negative cone).
/// Returns `(u, objective)`.
fn clarabel_solution(p: &LinearQuadratic, tol: f64) -> (Vec<f64>, f64) {
    let n = p.n;
    let nz = 3 * n;
    let xi = |k: usize, i: usize| 2 * (k - 1) + i; // x_k, k ≥ 1
    let ui = |k: usize| 2 * n + k;
    let mut pdiag = vec![0.0; nz];
    for k in 1..n {
        pdiag[xi(k, 0)] = p.q_p;
        pdiag[xi(k, 1)] = p.q_v;
    }
    for k in 0..n {
        pdiag[ui(k)] = 1.0;
    }
    let pm = CscMatrix::new_from_triplets(nz, nz, (0..nz).collect(), (0..nz).collect(), pdiag);
    let (mut rows, mut cols, mut vals, mut b) = (vec![], vec![], vec![], vec![]);
    let mut row = 0;
    let mut put = |r: usize, c: usize, v: f64| {
        rows.push(r);
        cols.push(c);
        vals.push(v);
    };
    // x_{k+1} − x_k − h(v_k, u_k) = 0.
    for k in 0..n {
        put(row, xi(k + 1, 0), 1.0);
        put(row + 1, xi(k + 1, 1), 1.0);
        if k > 0 {
            put(row, xi(k, 0), -1.0);
            put(row, xi(k, 1), -p.h);
            put(row + 1, xi(k, 1), -1.0);
        }
        put(row + 1, ui(k), -p.h);
        b.extend([0.0, 0.0]);
        row += 2;
    }
    put(row, xi(n, 0), 1.0);
    put(row + 1, xi(n, 1), 1.0);
    b.extend([p.target, 0.0]);
    row += 2;
    let n_eq = row;
    // ±u_k ≤ u_max (k < N), ±v_k ≤ v_max (1 ≤ k < N; v_0 = 0 is given).
    for k in 0..n {
        for sgn in [1.0, -1.0] {
            put(row, ui(k), sgn);
            b.push(p.u_max);
            row += 1;
        }
    }
    for k in 1..n {
        for sgn in [1.0, -1.0] {
            put(row, xi(k, 1), sgn);
            b.push(p.v_max);
            row += 1;
        }
    }
    let a = CscMatrix::new_from_triplets(row, nz, rows, cols, vals);
    let cones = [ZeroConeT(n_eq), NonnegativeConeT(row - n_eq)];
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(tol)
        .tol_gap_rel(tol)
        .tol_feas(tol)
        .build()
        .expect("valid settings");
    let mut solver = DefaultSolver::new(&pm, &vec![0.0; nz], &a, &b, &cones, settings)
        .expect("a well-formed QP");
    solver.solve();
    assert_eq!(solver.solution.status, SolverStatus::Solved);
    let u = (0..n).map(|k| solver.solution.x[ui(k)]).collect();
    (u, solver.solution.obj_val)
}

#[test]
fn interior_point_equals_clarabel_on_a_constrained_lq_problem() {
    // Two cases: the velocity bound active over the cruise (and the input bound at the
    // ends), and both bounds far (an equality-constrained QP in effect).
    for (u_max, v_max) in [(0.6, 0.3), (10.0, 10.0)] {
        let p = LinearQuadratic {
            n: 40,
            h: 0.1,
            q_p: 0.01,
            q_v: 0.1,
            u_max,
            v_max,
            target: 1.0,
        };
        let tol = 1e-10;
        let s = Solver::new(
            &p,
            IpOptions {
                tol,
                constr_viol_tol: tol,
                ..Default::default()
            },
        );
        let r = s
            .solve(s.initial_iterate(vec![SVector::zeros(); p.n + 1], vec![SVector::zeros(); p.n]));
        assert_eq!(r.status, Status::Solved, "bounds ({u_max}, {v_max})");
        let (u_ref, j_ref) = clarabel_solution(&p, tol);
        // Both solvers stop with every complementarity product t·z and every KKT residual
        // below `tol`. There are m = 4N bound rows; a perturbation of size tol in each
        // moves the solution by at most √m·tol through the KKT matrix, whose inverse is
        // bounded by the inverse curvature in u (1) times the horizon's lever N·h (a
        // velocity bound acts on u through the dynamics). Two solvers: twice that. The
        // objective moves by at most the duality gap Σ t·z ≤ m·tol.
        let m = 4.0 * p.n as f64;
        let du_bound = 2.0 * m.sqrt() * (p.n as f64 * p.h) * tol;
        let dj_bound = 2.0 * m * tol;
        let du = r
            .iterate
            .w
            .iter()
            .zip(&u_ref)
            .map(|(w, u)| (w[0] - u).abs())
            .fold(0.0f64, f64::max);
        let dj = (r.objective - j_ref).abs();
        println!("bounds ({u_max}, {v_max}): {} iterations, J = {} (clarabel {j_ref}), max |Δu| = {du:.2e} (bound {du_bound:.1e}), |ΔJ| = {dj:.2e} (bound {dj_bound:.1e})", r.iterations, r.objective);
        assert!(du <= du_bound, "max |Δu| = {du:.3e} > {du_bound:.3e}");
        assert!(dj <= dj_bound, "|ΔJ| = {dj:.3e} > {dj_bound:.3e}");
    }
}

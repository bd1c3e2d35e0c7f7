//! Nonlinear terminal equalities (`StageProblem::terminal_equalities`): a plan that must end
//! on a curve gives the optimum of the plan that ends at the right point of it, with the
//! multipliers the two conditions' gradients say, on every KKT back-end and curvature.

use dmech_lie::Real;
use dmech_ocp::nlp::{StageProblem, StateEquality};
use dmech_ocp::solver::{Curvature, IpOptions, KktMethod, Solver, Status};
use nalgebra::{SVector, Vector2};

/// A point mass in the plane, `x = (p, v)`, `w = a`, from rest at `start` to rest on the
/// unit circle (`|p_N|² − 1 = 0`, a terminal equality) or at the point `target` (state
/// equalities), least `½ Σ |a_k|²`.
struct PlanarMass {
    n: usize,
    h: f64,
    start: Vector2<f64>,
    /// `None`: end on the unit circle; `Some(p)`: end at `p`.
    target: Option<Vector2<f64>>,
}

impl StageProblem<4, 2, 0, 2, 0> for PlanarMass {
    fn horizon(&self) -> usize {
        self.n
    }
    fn initial_state(&self) -> SVector<f64, 4> {
        SVector::<f64, 4>::new(self.start[0], self.start[1], 0.0, 0.0)
    }
    fn dynamics<T: Real>(&self, _k: usize, x: &SVector<T, 4>, w: &SVector<T, 2>) -> SVector<T, 4> {
        let h = self.h;
        SVector::<T, 4>::new(
            x[0] + x[2] * h,
            x[1] + x[3] * h,
            x[2] + w[0] * h,
            x[3] + w[1] * h,
        )
    }
    fn equality<T: Real>(
        &self,
        _k: usize,
        _x: &SVector<T, 4>,
        _w: &SVector<T, 2>,
    ) -> SVector<T, 0> {
        SVector::zeros()
    }
    fn cost<T: Real>(&self, _k: usize, _x: &SVector<T, 4>, w: &SVector<T, 2>) -> T {
        (w[0] * w[0] + w[1] * w[1]) * 0.5
    }
    fn constraints<T: Real>(
        &self,
        _k: usize,
        _x: &SVector<T, 4>,
        _w: &SVector<T, 2>,
    ) -> SVector<T, 0> {
        SVector::zeros()
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, 0>, SVector<f64, 0>) {
        (SVector::zeros(), SVector::zeros())
    }
    fn state_equalities(&self) -> Vec<StateEquality> {
        let at = |index, value| StateEquality {
            stage: self.n,
            index,
            value,
        };
        let mut eqs = vec![at(2, 0.0), at(3, 0.0)];
        if let Some(p) = self.target {
            eqs.extend([at(0, p[0]), at(1, p[1])]);
        }
        eqs
    }
    fn terminal_equalities<T: Real>(&self, x: &SVector<T, 4>) -> Vec<T> {
        match self.target {
            None => vec![x[0] * x[0] + x[1] * x[1] - 1.0],
            Some(_) => Vec::new(),
        }
    }
}

/// The problem is invariant under rotations about the origin and its cost grows with the
/// distance travelled, so the nearest point of the circle, `start/|start|`, is where the
/// circle plan ends; there it is the point plan. Both solves stop at the solver's
/// tolerance `τ = 1e-8` on the (scaled) KKT error and `1e-8` on the violation:
/// - end on the circle to the violation tolerance over `|∇r| = 2`;
/// - the objectives agree to `|y| · 2·1e-8` (the objective's sensitivity to the end
///   condition is its multiplier) plus `τ` times the objective: `1e-7 (1 + |y| + J)` leaves
///   a factor 5 over both;
/// - the point plan's multipliers of `p_N` are the circle plan's `y` times `∇r = 2 p_N`, to
///   the regularised update's error, `1e-6` relative;
/// - the end point's tangential offset costs only at second order, so it is pinned to
///   `√(τ)`-size by the objective: `1e-4`.
#[test]
fn a_plan_that_ends_on_a_curve_ends_at_its_nearest_point() {
    let (n, h) = (40, 0.05);
    let start = Vector2::new(0.5, 0.2);
    let nearest = start / start.norm();
    for kkt in [KktMethod::Riccati, KktMethod::SparseLdlt] {
        for curvature in [Curvature::Sr1, Curvature::Exact] {
            let solve = |target| {
                let p = PlanarMass {
                    n,
                    h,
                    start,
                    target,
                };
                let opts = IpOptions {
                    verbose: false,
                    kkt,
                    curvature,
                    ..IpOptions::default()
                };
                let s = Solver::new(&p, opts);
                // At rest at the start throughout: the circle's gradient `2 p` is not zero
                // there (at `p = 0` the row would say nothing).
                let xs = vec![p.initial_state(); n + 1];
                let r = s.solve(s.initial_iterate(xs, vec![SVector::zeros(); n]));
                assert_eq!(
                    r.status,
                    Status::Solved,
                    "{kkt:?}, {curvature:?}, {target:?}"
                );
                r
            };
            let circle = solve(None);
            let point = solve(Some(nearest));
            let end = circle.iterate.x[n];
            let p_end = Vector2::new(end[0], end[1]);
            println!(
                "{kkt:?} {curvature:?}: {} / {} iterations, J {:.12} / {:.12}, end {p_end:?}, y {:?} / {:?}",
                circle.iterations, point.iterations, circle.objective, point.objective,
                circle.iterate.y, point.iterate.y
            );
            assert!(
                (p_end.norm_squared() - 1.0).abs() <= 1e-8,
                "off the circle: {p_end:?}"
            );
            assert!(
                (p_end - nearest).norm() <= 1e-4,
                "{p_end:?} against {nearest:?}"
            );
            // y: (v_x, v_y) first, then the circle's row.
            let y = circle.iterate.y[2];
            let scale = 1e-7 * (1.0 + y.abs() + circle.objective.abs());
            assert!(
                (circle.objective - point.objective).abs() <= scale,
                "objectives {} and {}",
                circle.objective,
                point.objective
            );
            for i in 0..2 {
                let expected = y * 2.0 * p_end[i];
                let got = point.iterate.y[2 + i];
                assert!(
                    (got - expected).abs() <= 1e-6 * expected.abs().max(1.0),
                    "multiplier of p_{i}: {got} against {expected}"
                );
            }
        }
    }
}

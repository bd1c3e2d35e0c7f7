//! The interior point on small problems with known structure.

use dmech_lie::Real;
use dmech_ocp::ipm::{IpOptions, Solver, Status};
use dmech_ocp::problem::{StageProblem, StateEquality};
use nalgebra::SVector;

/// A double integrator (position, velocity) driven by a bounded force, with a rate limit
/// carried in the state: x = (p, v, u_prev), w = u.
struct DoubleIntegrator {
    n: usize,
    h: f64,
    u_max: f64,
    du_max: f64,
    target: f64,
    nonlinear: bool,
    cost_scale: f64,
    /// Whether the problem declares its (quadratic) cost's curvature constant.
    declares_constant_curvature: bool,
}

impl StageProblem<3, 1, 0, 2> for DoubleIntegrator {
    fn horizon(&self) -> usize {
        self.n
    }
    fn initial_state(&self) -> SVector<f64, 3> {
        SVector::zeros()
    }
    fn dynamics<T: Real>(&self, _k: usize, x: &SVector<T, 3>, w: &SVector<T, 1>) -> SVector<T, 3> {
        let h = self.h;
        // Optionally a pendulum-like nonlinearity in the force.
        let f = if self.nonlinear {
            w[0] - x[0].sin() * 0.5
        } else {
            w[0]
        };
        SVector::<T, 3>::new(x[0] + x[1] * h, x[1] + f * h, w[0])
    }
    fn equality<T: Real>(
        &self,
        _k: usize,
        _x: &SVector<T, 3>,
        _w: &SVector<T, 1>,
    ) -> SVector<T, 0> {
        SVector::zeros()
    }
    fn cost<T: Real>(&self, _k: usize, x: &SVector<T, 3>, w: &SVector<T, 1>) -> T {
        (w[0] * w[0] + x[1] * x[1] * 0.1) * (0.5 * self.cost_scale)
    }
    fn constraints<T: Real>(
        &self,
        _k: usize,
        x: &SVector<T, 3>,
        w: &SVector<T, 1>,
    ) -> SVector<T, 2> {
        SVector::<T, 2>::new(w[0], w[0] - x[2])
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, 2>, SVector<f64, 2>) {
        let hi = SVector::<f64, 2>::new(self.u_max, self.du_max);
        (-hi, hi)
    }
    fn constant_cost_curvature(&self) -> bool {
        self.declares_constant_curvature
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

#[test]
fn double_integrator_converges() {
    for nonlinear in [false, true] {
        let p = DoubleIntegrator {
            n: 100,
            h: 0.05,
            u_max: 1.0,
            du_max: 0.05,
            target: 1.0,
            nonlinear,
            cost_scale: 1.0,
            declares_constant_curvature: false,
        };
        let s: Solver<3, 1, 0, 1, 2> = Solver::new(
            &p,
            IpOptions {
                verbose: true,
                ..Default::default()
            },
        );
        let start = s.initial_iterate(vec![SVector::zeros(); 101], vec![SVector::zeros(); 100]);
        let r = s.solve(start);
        println!("{:?} {} {}", r.status, r.iterations, r.objective);
        assert_eq!(r.status, Status::Solved);
    }
}

/// The parallel loops and the Riccati sweep that runs behind the condensing give bitwise
/// the iterates of the serial solver: every stage sees the same operations in the same
/// order whatever the thread that takes it. A horizon that is not a multiple of the work
/// chunk (32 stages) and a nonlinear problem, so that chunks finish out of order.
#[test]
fn threads_do_not_change_the_iterates() {
    let p = DoubleIntegrator {
        n: 1001,
        h: 0.01,
        u_max: 1.0,
        du_max: 0.01,
        target: 1.0,
        nonlinear: true,
        cost_scale: 1.0,
        declares_constant_curvature: false,
    };
    let solve = |threads| {
        let s: Solver<3, 1, 0, 1, 2> = Solver::new(
            &p,
            IpOptions {
                threads,
                ..Default::default()
            },
        );
        let start = s.initial_iterate(vec![SVector::zeros(); 1002], vec![SVector::zeros(); 1001]);
        s.solve(start)
    };
    let serial = solve(1);
    assert_eq!(serial.status, Status::Solved);
    for threads in [2, 3] {
        let r = solve(threads);
        assert_eq!(r.status, serial.status);
        assert_eq!(r.iterations, serial.iterations);
        assert_eq!(r.objective.to_bits(), serial.objective.to_bits());
        assert_eq!(r.iterate.x, serial.iterate.x);
        assert_eq!(r.iterate.w, serial.iterate.w);
        assert_eq!(r.iterate.lambda, serial.iterate.lambda);
    }
}

/// The solver works on the cost scaled to a mean stage cost of one (`ipm/scaling.rs`), so a
/// small cost times `a` is the same internal problem up to rounding: the same iterations,
/// the same primal solution (to rounding amplified by the solve, 1e-9), the objective and
/// the equality multipliers times `a` (reported in the problem's units). The start has a
/// nonzero input so that the scale is read at the start itself.
#[test]
fn small_objectives_are_solved_scale_invariantly() {
    let solve = |cost_scale: f64| {
        let p = DoubleIntegrator {
            n: 200,
            h: 0.05,
            u_max: 1.0,
            du_max: 0.05,
            target: 1.0,
            nonlinear: true,
            cost_scale,
            declares_constant_curvature: false,
        };
        let s: Solver<3, 1, 0, 1, 2> = Solver::new(&p, IpOptions::default());
        let start = s.initial_iterate(
            vec![SVector::zeros(); 201],
            vec![SVector::repeat(0.01); 200],
        );
        s.solve(start)
    };
    let base = solve(1e-2);
    assert_eq!(base.status, Status::Solved);
    for a in [1e-4, 1e-7] {
        let r = solve(a);
        let ratio = a / 1e-2;
        assert_eq!(r.status, Status::Solved);
        assert_eq!(r.iterations, base.iterations, "scale {a}");
        assert!(
            (r.objective / (base.objective * ratio) - 1.0).abs() < 1e-9,
            "scale {a}"
        );
        for (x, xb) in r.iterate.x.iter().zip(&base.iterate.x) {
            assert!((x - xb).amax() < 1e-9, "scale {a}: {x} against {xb}");
        }
        let lam_max = base
            .iterate
            .lambda
            .iter()
            .map(|l| l.amax())
            .fold(0.0, f64::max);
        for (l, lb) in r.iterate.lambda.iter().zip(&base.iterate.lambda) {
            assert!((l / ratio - lb).amax() <= 1e-9 * lam_max, "scale {a}");
        }
    }
}

/// A cost declared of constant curvature is solved as the same cost undeclared, to the
/// last bit: the solver then reads the curvature from the table it builds at the start
/// (not copied into the stages' derivatives without the exact Hessian, added to the
/// constraints' curvature with it), and for a quadratic cost the table holds the very
/// numbers the derivative pass would compute at every iteration.
#[test]
fn a_declared_constant_curvature_gives_the_same_iterates() {
    for exact_hessian in [false, true] {
        let solve = |declares_constant_curvature| {
            let p = DoubleIntegrator {
                n: 150,
                h: 0.05,
                u_max: 1.0,
                du_max: 0.05,
                target: 1.0,
                nonlinear: true,
                cost_scale: 1.0,
                declares_constant_curvature,
            };
            let opts = IpOptions {
                exact_hessian,
                ..Default::default()
            };
            let s: Solver<3, 1, 0, 1, 2> = Solver::new(&p, opts);
            let start = s.initial_iterate(vec![SVector::zeros(); 151], vec![SVector::zeros(); 150]);
            s.solve(start)
        };
        let (declared, undeclared) = (solve(true), solve(false));
        assert_eq!(undeclared.status, Status::Solved, "exact {exact_hessian}");
        assert_eq!(declared.status, undeclared.status);
        assert_eq!(declared.iterations, undeclared.iterations);
        assert_eq!(
            declared.objective.to_bits(),
            undeclared.objective.to_bits(),
            "exact {exact_hessian}"
        );
        assert_eq!(declared.iterate.x, undeclared.iterate.x);
        assert_eq!(declared.iterate.w, undeclared.iterate.w);
    }
}

//! The interior point on small problems with known structure.

use dmech_lie::Real;
use dmech_ocp::nlp::{StageProblem, StateEquality};
use dmech_ocp::solver::{Curvature, IpOptions, Solver, Status};
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

impl DoubleIntegrator {
    /// `n` steps of `h` from rest to position 1: unit force bound, a rate limit of one
    /// unit per step (`du_max = h`), the nonlinear variant, cost at scale one, no
    /// declared constant curvature. The tests vary one field of it.
    fn to_unit_position(n: usize, h: f64) -> Self {
        DoubleIntegrator {
            n,
            h,
            u_max: 1.0,
            du_max: h,
            target: 1.0,
            nonlinear: true,
            cost_scale: 1.0,
            declares_constant_curvature: false,
        }
    }
}

impl StageProblem<3, 1, 0, 1, 2> for DoubleIntegrator {
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
            nonlinear,
            ..DoubleIntegrator::to_unit_position(100, 0.05)
        };
        let s = Solver::new(
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
    let p = DoubleIntegrator::to_unit_position(1001, 0.01);
    let solve = |threads| {
        let s = Solver::new(
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

/// A final barrier ends the solve where the full solve leaves that barrier problem: the
/// same iterate, bitwise, as the full solve stopped after as many iterations, and fewer
/// iterations than the full solve. The barrier is one the monotone rule visits from
/// `μ₀ = 0.1` (`κ_μ μ₀`), so that both solves meet it. A barrier between two of the
/// rule's values is landed on, not skipped: the solve then ends on it too.
#[test]
fn a_final_barrier_stops_where_the_full_solve_leaves_it() {
    let p = DoubleIntegrator::to_unit_position(200, 0.05);
    let solve = |final_barrier: Option<f64>, max_iter: usize| {
        let o = IpOptions {
            final_barrier,
            max_iter,
            ..Default::default()
        };
        let visited = 0.2 * o.mu_init;
        let s = Solver::new(&p, o);
        let start = s.initial_iterate(vec![SVector::zeros(); 201], vec![SVector::zeros(); 200]);
        (s.solve(start), visited)
    };
    let (full, visited) = solve(None, 500);
    assert_eq!(full.status, Status::Solved);
    let (stopped, _) = solve(Some(visited), 500);
    assert_eq!(stopped.status, Status::Solved);
    assert!(
        stopped.iterations < full.iterations,
        "{} against {}",
        stopped.iterations,
        full.iterations
    );
    let (cut, _) = solve(None, stopped.iterations);
    assert_eq!(cut.status, Status::MaxIterations);
    assert_eq!(cut.iterate.x, stopped.iterate.x);
    assert_eq!(cut.iterate.w, stopped.iterate.w);
    assert_eq!(cut.iterate.z_lo, stopped.iterate.z_lo);
    // Between the rule's values (0.02 → 0.0028): still an early end, on that barrier's
    // central path. The bound multipliers are reported unscaled (times the solver's cost
    // scale), so the barrier is read off against the full solve's, which ends at
    // `μ = tol/10`: the mean `t z` of the two stand as the barriers, within a factor 2
    // (the rule's values on either side of 1e-2 are 3.5 and 2 times away).
    let between = 1e-2;
    let (landed, _) = solve(Some(between), 500);
    assert_eq!(landed.status, Status::Solved);
    assert!(landed.iterations < full.iterations);
    let mean_tz = |it: &dmech_ocp::solver::Iterate<3, 1, 2>| {
        let pairs = it
            .t_lo
            .iter()
            .zip(&it.z_lo)
            .chain(it.t_hi.iter().zip(&it.z_hi));
        let (sum, count) = pairs.fold((0.0, 0.0), |(s, c), (t, z)| (s + t.dot(z), c + 2.0));
        sum / count
    };
    let ratio = mean_tz(&landed.iterate) / mean_tz(&full.iterate);
    let want = between / (IpOptions::default().tol / 10.0);
    println!("mean t z against the full solve's: {ratio:.3e} (barriers: {want:.1e})");
    assert!(
        ratio > want / 2.0 && ratio < want * 2.0,
        "mean t z ratio {ratio:.3e}, barriers {want:.1e}"
    );
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
            cost_scale,
            ..DoubleIntegrator::to_unit_position(200, 0.05)
        };
        let s = Solver::new(&p, IpOptions::default());
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
    for curvature in [Curvature::Sr1, Curvature::Exact] {
        let solve = |declares_constant_curvature| {
            let p = DoubleIntegrator {
                declares_constant_curvature,
                ..DoubleIntegrator::to_unit_position(150, 0.05)
            };
            let opts = IpOptions {
                curvature,
                ..Default::default()
            };
            let s = Solver::new(&p, opts);
            let start = s.initial_iterate(vec![SVector::zeros(); 151], vec![SVector::zeros(); 150]);
            s.solve(start)
        };
        let (declared, undeclared) = (solve(true), solve(false));
        assert_eq!(undeclared.status, Status::Solved, "{curvature:?}");
        assert_eq!(declared.status, undeclared.status);
        assert_eq!(declared.iterations, undeclared.iterations);
        assert_eq!(
            declared.objective.to_bits(),
            undeclared.objective.to_bits(),
            "{curvature:?}"
        );
        assert_eq!(declared.iterate.x, undeclared.iterate.x);
        assert_eq!(declared.iterate.w, undeclared.iterate.w);
    }
}

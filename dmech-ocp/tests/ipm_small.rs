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
        (w[0] * w[0] + x[1] * x[1] * 0.1) * 0.5
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
        };
        let s: Solver<_, 3, 1, 0, 1, 2> = Solver::new(
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

//! Global variables on a problem with a known answer: a double integrator that must pass a
//! waypoint, with the waypoint's time free (the step of each of the two phases a global,
//! their total fixed). The answer is found independently by a golden-section search over
//! the first phase's step of the fixed-timing optimum, which is an equality-constrained
//! least-squares problem solved in closed form.

use dmech_lie::Real;
use dmech_ocp::nlp::{GlobalEquality, Globals, StageProblem, StateEquality};
use dmech_ocp::solver::{IpOptions, KktMethod, Solver, Status};
use nalgebra::{DMatrix, DVector, SVector};

/// `x = (position, velocity)`, `w = (u, h)`: `h` is the step of the stage's phase.
/// Exact zero-order hold: `x⁺ = (p + h v + ½h²u, v + h u)`, cost `h u²` (the integral of
/// `u²`). Phase 0 has `n1` steps and ends at the waypoint `p = a`; phase 1 has `n2` and
/// ends at rest at `p = b`.
struct TwoPhase {
    n1: usize,
    n2: usize,
    a: f64,
    b: f64,
    total: f64,
}

impl TwoPhase {
    fn nominal(&self) -> f64 {
        self.total / (self.n1 + self.n2) as f64
    }
}

impl StageProblem<2, 2, 0, 1, 0> for TwoPhase {
    fn horizon(&self) -> usize {
        self.n1 + self.n2
    }
    fn initial_state(&self) -> SVector<f64, 2> {
        SVector::zeros()
    }
    fn dynamics<T: Real>(&self, _k: usize, x: &SVector<T, 2>, w: &SVector<T, 2>) -> SVector<T, 2> {
        let (u, h) = (w[0], w[1]);
        SVector::from([x[0] + h * x[1] + h * h * u * 0.5, x[1] + h * u])
    }
    fn equality<T: Real>(
        &self,
        _k: usize,
        _x: &SVector<T, 2>,
        _w: &SVector<T, 2>,
    ) -> SVector<T, 0> {
        SVector::zeros()
    }
    fn cost<T: Real>(&self, _k: usize, _x: &SVector<T, 2>, w: &SVector<T, 2>) -> T {
        w[1] * w[0] * w[0]
    }
    fn constraints<T: Real>(
        &self,
        _k: usize,
        _x: &SVector<T, 2>,
        _w: &SVector<T, 2>,
    ) -> SVector<T, 0> {
        SVector::zeros()
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, 0>, SVector<f64, 0>) {
        (SVector::zeros(), SVector::zeros())
    }
    fn state_equalities(&self) -> Vec<StateEquality> {
        let n = self.horizon();
        let eq = |stage, index, value| StateEquality {
            stage,
            index,
            value,
        };
        vec![eq(self.n1, 0, self.a), eq(n, 0, self.b), eq(n, 1, 0.0)]
    }
    fn globals(&self) -> Option<Globals> {
        let h = self.nominal();
        Some(Globals {
            start: vec![h, h],
            lo: vec![0.2 * h; 2],
            hi: vec![5.0 * h; 2],
            equalities: vec![GlobalEquality {
                a: vec![self.n1 as f64, self.n2 as f64],
                b: self.total,
            }],
            cost: vec![0.0, 0.0],
            per_stage: 1,
            support: (0..self.horizon())
                .map(|k| usize::from(k >= self.n1))
                .collect(),
        })
    }
}

/// The fixed-timing optimum with steps `h1`, `h2`: `min Σ h_k u_k²` subject to three linear
/// conditions `C u = d` (position at the waypoint, position and velocity at the end),
/// `u = W⁻¹Cᵀ(CW⁻¹Cᵀ)⁻¹d`, `W = diag(h_k)`; its cost `dᵀ(CW⁻¹Cᵀ)⁻¹d`.
fn fixed_timing(pr: &TwoPhase, h1: f64) -> f64 {
    let h2 = (pr.total - pr.n1 as f64 * h1) / pr.n2 as f64;
    let n = pr.horizon();
    let steps: Vec<f64> = (0..n).map(|k| if k < pr.n1 { h1 } else { h2 }).collect();
    let t: Vec<f64> = std::iter::once(0.0)
        .chain(steps.iter().scan(0.0, |s, h| {
            *s += h;
            Some(*s)
        }))
        .collect();
    // Position at time τ from u_k held on [t_k, t_{k+1}): h_k (τ − t_k − h_k/2) for t_{k+1} ≤ τ.
    let pos_row = |tau: f64, upto: usize| {
        DVector::from_fn(n, |k, _| {
            if k < upto {
                steps[k] * (tau - t[k] - steps[k] / 2.0)
            } else {
                0.0
            }
        })
    };
    let c = DMatrix::from_rows(&[
        pos_row(t[pr.n1], pr.n1).transpose(),
        pos_row(t[n], n).transpose(),
        DVector::from_column_slice(&steps).transpose(),
    ]);
    let d = DVector::from_column_slice(&[pr.a, pr.b, 0.0]);
    let winv = DMatrix::from_diagonal(&DVector::from_iterator(n, steps.iter().map(|h| 1.0 / h)));
    let m = &c * winv * c.transpose();
    d.dot(&m.lu().solve(&d).expect("independent conditions"))
}

/// Golden-section search for the minimiser of a unimodal `f` on `[lo, hi]`, to the width
/// at which its values stop being distinguishable.
fn golden(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let (mut x1, mut x2) = (hi - r * (hi - lo), lo + r * (hi - lo));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..200 {
        if f1 < f2 {
            hi = x2;
            (x2, f2) = (x1, f1);
            x1 = hi - r * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            (x1, f1) = (x2, f2);
            x2 = lo + r * (hi - lo);
            f2 = f(x2);
        }
    }
    0.5 * (lo + hi)
}

fn solve(pr: &TwoPhase, tol: f64) -> (f64, f64, usize) {
    solve_with(pr, tol, KktMethod::Riccati)
}

fn solve_with(pr: &TwoPhase, tol: f64, kkt: KktMethod) -> (f64, f64, usize) {
    let opts = IpOptions {
        tol,
        verbose: false,
        kkt,
        ..Default::default()
    };
    let s = Solver::new(pr, opts);
    let n = pr.horizon();
    let h = pr.nominal();
    let start = s.initial_iterate(
        vec![SVector::zeros(); n + 1],
        vec![SVector::from([0.0, h]); n],
    );
    let r = s.solve(start);
    assert_eq!(r.status, Status::Solved, "{:?}", r.status);
    (r.iterate.globals.p[0], r.objective, r.iterations)
}

/// The waypoint a quarter of the way: the rest-to-rest optimum (a cubic) passes it at
/// `τ ≈ 0.326 T`, so the free timing moves it there from the fixed `T/2` and lowers the
/// cost. The free-timing solve agrees with the golden-section minimiser to within what
/// the two methods resolve, and its objective with the fixed-timing optimum there.
#[test]
fn free_switching_time_of_a_double_integrator() {
    let pr = TwoPhase {
        n1: 20,
        n2: 20,
        a: 0.25,
        b: 1.0,
        total: 2.0,
    };
    let tol = 1e-10;
    let (h1, objective, iterations) = solve(&pr, tol);
    let h = pr.nominal();
    let j = |h1: f64| fixed_timing(&pr, h1);
    let h1_ref = golden(j, 0.3 * h, 1.7 * h);
    // What each method resolves: golden section, steps whose costs differ by less than
    // the round-off of J, |Δh| ≈ √(2ε|J|/J''); the interior point, a gradient of the
    // reduced cost of `tol` (in its scaled KKT error, at most `tol · s_d` with `s_d` ≤ the
    // mean multiplier, bounded here by 10 |J|/h), |Δh| ≈ tol · s_d / J''.
    let dh = 1e-3 * h;
    let j2 = (j(h1_ref + dh) - 2.0 * j(h1_ref) + j(h1_ref - dh)) / (dh * dh);
    let resolved = (2.0 * f64::EPSILON * j(h1_ref) / j2).sqrt() + tol * 10.0 * j(h1_ref) / h / j2;
    println!(
        "h1 = {h1:.12} (golden section {h1_ref:.12}, resolved ±{resolved:.1e}), J = {objective:.12} \
         against {:.12} there and {:.12} at the fixed timing, {iterations} iterations",
        j(h1_ref),
        j(h)
    );
    assert!((h1 - h1_ref).abs() <= resolved, "{h1} vs {h1_ref}");
    // The objective: J is flat at its minimiser, so the two agree to second order in the
    // steps' difference, and to the interior point's tolerance.
    assert!((objective - j(h1_ref)).abs() <= 10.0 * tol * j(h1_ref).max(1.0));
    assert!(
        objective < j(h),
        "free timing must not cost more than the fixed one"
    );
    // For orientation (the discrete optimum approaches it as the step shrinks, at a rate
    // this test does not measure): the continuous answer, where the cubic passes 1/4 at
    // 3τ² − 2τ³ = 1/4, 20 h1 / T = 0.3264.
    println!(
        "20 h1 / T = {:.4} (continuous 0.3264)",
        20.0 * h1 / pr.total
    );
}

/// The fixed timing is optimal when the waypoint sits half-way (by symmetry): the free
/// solve keeps the steps equal, and its objective is the fixed-timing one.
#[test]
fn symmetric_waypoint_keeps_the_timing() {
    let pr = TwoPhase {
        n1: 10,
        n2: 10,
        a: 0.5,
        b: 1.0,
        total: 2.0,
    };
    let tol = 1e-10;
    let (h1, objective, _) = solve(&pr, tol);
    let h = pr.nominal();
    let fixed = fixed_timing(&pr, h);
    println!("h1 = {h1:.14} (nominal {h}), J = {objective:.14} against {fixed:.14}");
    assert!((h1 - h).abs() < 1e-8 * h);
    assert!((objective - fixed).abs() < 10.0 * tol * fixed);
}

/// The speed limit of [`Fixed`]: active on the fixed-timing plan (the test checks it).
const SPEED_LIMIT: f64 = 1.0;

/// The same double integrator with the timing fixed (no globals): `w = u`.
struct Fixed(TwoPhase);

impl StageProblem<2, 1, 0, 1, 1> for Fixed {
    fn horizon(&self) -> usize {
        self.0.horizon()
    }
    fn initial_state(&self) -> SVector<f64, 2> {
        SVector::zeros()
    }
    fn dynamics<T: Real>(&self, k: usize, x: &SVector<T, 2>, w: &SVector<T, 1>) -> SVector<T, 2> {
        let h = T::from(self.0.nominal());
        self.0.dynamics(k, x, &SVector::from([w[0], h]))
    }
    fn equality<T: Real>(
        &self,
        _k: usize,
        _x: &SVector<T, 2>,
        _w: &SVector<T, 1>,
    ) -> SVector<T, 0> {
        SVector::zeros()
    }
    fn cost<T: Real>(&self, _k: usize, _x: &SVector<T, 2>, w: &SVector<T, 1>) -> T {
        w[0] * w[0] * self.0.nominal()
    }
    /// A speed limit, active in the middle of the motion (a bound the barrier must handle).
    fn constraints<T: Real>(
        &self,
        _k: usize,
        x: &SVector<T, 2>,
        _w: &SVector<T, 1>,
    ) -> SVector<T, 1> {
        SVector::from([x[1]])
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, 1>, SVector<f64, 1>) {
        (SVector::from([-SPEED_LIMIT]), SVector::from([SPEED_LIMIT]))
    }
    fn state_equalities(&self) -> Vec<StateEquality> {
        self.0.state_equalities()
    }
}

/// The two KKT paths along whole solves: the sparse LDLᵀ and the Riccati recursion take
/// the same iterations to the same point, on a fixed-time problem with an active bound
/// and on the free-timing one. Their steps differ by round-off (`sparse_kkt` tests), which
/// the iteration does not amplify beyond the tolerance it solves to.
#[test]
fn sparse_ldlt_and_riccati_solve_alike() {
    let pr = TwoPhase {
        n1: 20,
        n2: 20,
        a: 0.25,
        b: 1.0,
        total: 2.0,
    };
    let tol = 1e-10;
    let (h_r, j_r, it_r) = solve_with(&pr, tol, KktMethod::Riccati);
    let (h_s, j_s, it_s) = solve_with(&pr, tol, KktMethod::SparseLdlt);
    println!("free timing: Riccati h1 {h_r:.14} J {j_r:.14} ({it_r} its), sparse h1 {h_s:.14} J {j_s:.14} ({it_s} its)");
    assert_eq!(it_r, it_s);
    assert!((h_r - h_s).abs() <= tol * pr.nominal());
    assert!((j_r - j_s).abs() <= tol * j_r);
    let fixed = Fixed(pr);
    let n = fixed.horizon();
    let run = |kkt| {
        let opts = IpOptions {
            tol,
            verbose: false,
            kkt,
            ..Default::default()
        };
        let s = Solver::new(&fixed, opts);
        let r =
            s.solve(s.initial_iterate(vec![SVector::zeros(); n + 1], vec![SVector::zeros(); n]));
        assert_eq!(r.status, Status::Solved);
        r
    };
    let (r, s) = (run(KktMethod::Riccati), run(KktMethod::SparseLdlt));
    let du = r
        .iterate
        .w
        .iter()
        .zip(&s.iterate.w)
        .map(|(a, b)| (a - b).amax())
        .fold(0.0, f64::max);
    println!(
        "fixed timing: Riccati J {:.14} ({} its), sparse J {:.14} ({} its), inputs differ by {du:.1e}",
        r.objective, r.iterations, s.objective, s.iterations
    );
    let peak = r.iterate.x.iter().map(|x| x[1].abs()).fold(0.0, f64::max);
    println!("peak speed {peak:.6} (limit {SPEED_LIMIT})");
    assert!(peak > SPEED_LIMIT - 1e-6, "the bound must be active");
    assert_eq!(r.iterations, s.iterations);
    assert!((r.objective - s.objective).abs() <= tol * r.objective);
    // Inputs of order 1: both points are within the tolerance of the same optimum.
    assert!(du <= 10.0 * tol.sqrt(), "{du:e}");
}

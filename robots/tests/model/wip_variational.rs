//! The variational integrator on the WIP: the structure it preserves, and how it converges.

use dmech::continuous::{ContinuousModel, ContinuousState, RungeKutta};
use dmech::{
    Discretisation, ForcingQuadrature, PrincipalKinematicSystem, VariationalIntegrator, ViState,
};
use dmech_lie::{LieGroup, Se2};
use nalgebra::SVector;
use robots::wip::invariants::energy;
use robots::wip::state::from_reduced;
use robots::wip::{ReducedState, Wip, WipParams};

type V5 = SVector<f64, 5>;
type U2 = SVector<f64, 2>;

/// Print a list of numbers in scientific notation.
struct Sci<'a>(&'a [f64]);
impl std::fmt::Display for Sci<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v: Vec<String> = self.0.iter().map(|x| format!("{x:.3e}")).collect();
        write!(f, "[{}]", v.join(", "))
    }
}

fn start(p: &WipParams, x: [f64; 9]) -> (Se2<f64>, V5, V5) {
    from_reduced(p, &ReducedState::from_column_slice(&x), [0.0; 4])
}

/// A conservative WIP: no inputs, no resistance, no friction.
fn conservative() -> Wip {
    Wip::new(WipParams {
        R_m: 0.0,
        d_v: 0.0,
        d_c: 0.0,
        ..Default::default()
    })
}

/// A tilted, moving, turning start with currents flowing.
const MOVING: [f64; 9] = [0.0, 0.0, 0.3, 0.3, 0.5, 0.4, 1.0, 0.1, -0.05];

#[test]
fn nonholonomic_constraints_hold_to_machine_precision() {
    let w = Wip::default();
    let h = 0.005;
    let vi = VariationalIntegrator::new(h).with_discretisation(Discretisation::FirstOrder);
    let (g, s, v) = start(&w.params, MOVING);
    let mut x = ViState { g, s, v };
    let mut worst: f64 = 0.0;
    for k in 0..2000 {
        let u = U2::new((k as f64 * 0.01).sin() * 2.0, 1.0);
        let (next, _) = vi.step(&w, &x, &u, &u).unwrap();
        // log(g_k⁻¹ g_{k+1})/h + A(s_k) (s_{k+1} − s_k)/h = 0.
        let xi = x.g.between(&next.g).log() / h;
        let res = xi + w.connection(&x.s) * ((next.s - x.s) / h);
        // The check itself rounds: g_k⁻¹ g_{k+1} cancels translations of size ‖p_k‖ (and
        // s_{k+1} − s_k cancels ‖s_k‖), so its absolute error is ≈ a few ε (1 + ‖p_k‖ + ‖s_k‖)/h.
        let scale = 1.0 + x.g.x.abs().max(x.g.y.abs()) + x.s.amax() + x.g.theta.abs();
        worst = worst.max(res.amax() * h / (f64::EPSILON * scale));
        x = next;
    }
    println!("worst constraint residual over 2000 steps: {worst:.2} ε(1 + ‖p‖ + ‖s‖)/h");
    assert!(worst < 16.0, "{worst}");
}

/// Energy over 10⁵ steps at h = 5 ms: bounded for the VI, drifting for RK4.
#[test]
fn energy_bounded_for_vi_drifts_for_rk4() {
    let w = conservative();
    let h = 0.005;
    let n = 100_000;
    let chunks = 10;
    let (g, s, v) = start(&w.params, MOVING);
    let e0 = energy(&w, &s, &v);
    let zero = U2::zeros();

    // Least-squares slope of E − E0 against t over the last nine tenths (after the
    // initial transient): the drift rate.
    struct Trend {
        n: f64,
        st: f64,
        se: f64,
        stt: f64,
        ste: f64,
    }
    impl Trend {
        fn add(&mut self, t: f64, e: f64) {
            self.n += 1.0;
            self.st += t;
            self.se += e;
            self.stt += t * t;
            self.ste += t * e;
        }
        fn slope(&self) -> f64 {
            (self.n * self.ste - self.st * self.se) / (self.n * self.stt - self.st * self.st)
        }
    }
    let vi = VariationalIntegrator::new(h).with_discretisation(Discretisation::FirstOrder);
    let mut x = ViState { g, s, v };
    let mut vi_max = vec![0.0f64; chunks];
    let mut vi_trend = Trend {
        n: 0.0,
        st: 0.0,
        se: 0.0,
        stt: 0.0,
        ste: 0.0,
    };
    for k in 0..n {
        x = vi.step(&w, &x, &zero, &zero).unwrap().0;
        let err = energy(&w, &x.s, &x.v) - e0;
        let c = k * chunks / n;
        vi_max[c] = vi_max[c].max(err.abs());
        if c > 0 {
            vi_trend.add(k as f64 * h, err);
        }
    }

    let mut y = ContinuousState { g, s, v };
    let mut rk_err = vec![0.0f64; chunks];
    let mut rk_trend = Trend {
        n: 0.0,
        st: 0.0,
        se: 0.0,
        stt: 0.0,
        ste: 0.0,
    };
    for k in 0..n {
        y = ContinuousModel::step(&w, RungeKutta::Rk4, h, &y, &zero).unwrap();
        let err = energy(&w, &y.s, &y.v) - e0;
        let c = k * chunks / n;
        rk_err[c] = err;
        if c > 0 {
            rk_trend.add(k as f64 * h, err);
        }
    }
    let (vs, rs) = (vi_trend.slope(), rk_trend.slope());
    println!("E0 = {e0:.6e} J, {n} steps of {h} s");
    println!("VI  max |E − E0| per tenth of the run: {}", Sci(&vi_max));
    println!("RK4 E − E0 at the end of each tenth:   {}", Sci(&rk_err));
    println!("drift rate d(E − E0)/dt: VI {vs:.3e} J/s, RK4 {rs:.3e} J/s");
    // Bounded: the largest error in the second half is no larger than in the first half
    // (the O(h) oscillation of a symplectic method, here large because h·ω ≈ 1.8 for the
    // undamped electromechanical mode, ω ≈ 363 rad/s; see docs/integrator.md).
    let first = vi_max[..chunks / 2].iter().cloned().fold(0.0, f64::max);
    let second = vi_max[chunks / 2..].iter().cloned().fold(0.0, f64::max);
    assert!(
        second <= first * (1.0 + 1e-3),
        "VI energy error grows: {first:e} → {second:e}"
    );
    // RK4 drifts: its error grows in magnitude through every tenth of the run (a bounded
    // oscillation, like the VI's, does not; the VI's trend is printed for comparison).
    assert!(
        rk_err.windows(2).all(|p| p[1].abs() > p[0].abs()),
        "RK4 error grows monotonically"
    );
    assert!(rs < 0.0, "RK4 loses energy steadily: {rs:e}");
}

/// With u = 0 and R_m = 0 the VI conserves L_m i_k + k_e n_wm (φ − α)_{k+1} on each side
/// exactly (a discrete Noether law: the node equation of q is its difference).
#[test]
fn electromechanical_momentum_conserved_exactly() {
    let w = conservative();
    let p = w.params;
    let h = 0.005;
    let vi = VariationalIntegrator::new(h).with_discretisation(Discretisation::FirstOrder);
    let (g, s, v) = start(&p, MOVING);
    let mut x = ViState { g, s, v };
    let zero = U2::zeros();
    let ken = p.k_e * p.n_wm;
    let flux = |s: &V5, v: &V5| robots::wip::invariants::discrete_flux_linkage(&p, h, s, v);
    let n = 10_000;
    let first = flux(&x.s, &x.v);
    let mut worst: f64 = 0.0;
    let mut bound: f64 = 0.0;
    for _ in 0..n {
        x = vi.step(&w, &x, &zero, &zero).unwrap().0;
        let f = flux(&x.s, &x.v);
        worst = worst
            .max((f[0] - first[0]).abs())
            .max((f[1] - first[1]).abs());
        // Per step: Newton's stopping tolerance on v (tol·(1+‖v‖)) times the row's
        // coefficients (L_m + h k_e n_wm), plus round-off ε·|k_e n_wm (φ − α)| in the sum.
        let newton = vi.newton_tol * (1.0 + x.v.amax()) * (p.L_m + h * ken);
        let roundoff = 4.0
            * f64::EPSILON
            * (ken * (x.s[1].abs() + x.s[2].abs() + x.s[0].abs()) + p.L_m * x.v.amax());
        bound += newton + roundoff;
    }
    println!("flux linkage drift over {n} steps: {worst:.3e} (bound {bound:.3e})");
    assert!(worst <= bound, "{worst:e} > {bound:e}");
}

/// Power balance with everything on: per step, E_{k+1} − E_k = h (u·i − R i² − Σ f ω) at the
/// right node, up to the method's local error, which must be O(h²): measured at three
/// step sizes, the fitted order of the per-step mismatch is 2 ± 0.3. The work uses the
/// forcing of the model (`forcing · v`), so inputs, resistance and friction are all in it.
#[test]
fn power_balance_per_step() {
    let w = Wip::default();
    let t_end = 0.4;
    let mut mismatch = Vec::new();
    let hs = [0.004, 0.002, 0.001];
    for &h in &hs {
        let vi = VariationalIntegrator::new(h).with_discretisation(Discretisation::FirstOrder);
        let (g, s, v) = start(&w.params, MOVING);
        let mut x = ViState { g, s, v };
        let n = (t_end / h).round() as usize;
        let mut worst: f64 = 0.0;
        let u_at = |k: usize| U2::new(2.0 + (k as f64 * h * 7.0).sin(), -1.0);
        for k in 0..n {
            let (next, _) = vi.step(&w, &x, &u_at(k), &u_at(k + 1)).unwrap();
            let de = energy(&w, &next.s, &next.v) - energy(&w, &x.s, &x.v);
            let work = h * w.forcing(&next.s, &next.v, &u_at(k + 1)).dot(&next.v);
            // The first steps relax the stiff current (time constant L/R = 0.27 ms < h) to
            // its quasi-steady value: an O(1) jump per step, outside the asymptotic regime.
            if k as f64 * h >= 0.05 {
                worst = worst.max((de - work).abs());
            }
            x = next;
        }
        mismatch.push(worst);
    }
    let order = (mismatch[0] / mismatch[2]).ln() / (hs[0] / hs[2]).ln();
    println!(
        "per-step power-balance mismatch {}, order {order:.3}",
        Sci(&mismatch)
    );
    assert!((order - 2.0).abs() < 0.3, "order {order}");
}

/// Convergence to the continuous model: the VI's configuration at t = 0.5 s against RK4 with
/// h = 25 µs, at h = 10, 5, 2.5, 1.25, 0.625 ms. Derived order: 1 (the discrete Lagrangian
/// is the rectangle rule ℓ(s_k, v_k, ξ_k), and the forcing is one-sided).
#[test]
fn vi_converges_with_order_one() {
    let w = Wip::default();
    let t_end: f64 = 0.5;
    let u = U2::new(1.0, 0.5);
    let (g0, s0, v0) = start(&w.params, MOVING);
    let h_ref = 2.5e-5;
    let mut y = ContinuousState {
        g: g0,
        s: s0,
        v: v0,
    };
    for _ in 0..(t_end / h_ref).round() as usize {
        y = ContinuousModel::step(&w, RungeKutta::Rk4, h_ref, &y, &u).unwrap();
    }
    let hs = [0.01, 0.005, 0.0025, 0.00125, 0.000625];
    let mut errs = Vec::new();
    for &h in &hs {
        let vi = VariationalIntegrator::new(h).with_discretisation(Discretisation::FirstOrder);
        let mut x = ViState {
            g: g0,
            s: s0,
            v: v0,
        };
        for _ in 0..(t_end / h).round() as usize {
            x = vi.step(&w, &x, &u, &u).unwrap().0;
        }
        let dg = (y.g.x - x.g.x)
            .abs()
            .max((y.g.y - x.g.y).abs())
            .max((y.g.theta - x.g.theta).abs());
        errs.push(dg.max((y.s - x.s).amax()));
    }
    let (lx, ly): (Vec<f64>, Vec<f64>) =
        hs.iter().zip(&errs).map(|(h, e)| (h.ln(), e.ln())).unzip();
    let mx = lx.iter().sum::<f64>() / lx.len() as f64;
    let my = ly.iter().sum::<f64>() / ly.len() as f64;
    let slope = lx
        .iter()
        .zip(&ly)
        .map(|(x, y)| (x - mx) * (y - my))
        .sum::<f64>()
        / lx.iter().map(|x| (x - mx) * (x - mx)).sum::<f64>();
    println!(
        "configuration errors {}; fitted order {slope:.3}",
        Sci(&errs)
    );
    assert!((slope - 1.0).abs() <= 0.2, "order {slope}");
}

/// Stiffness: h R_m / L_m = 18.75 at h = 5 ms. The explicit (left-point) forcing makes the
/// current diverge (factor ≈ −17.75 per step); the default (right-point) stays bounded.
#[test]
fn left_point_forcing_diverges_default_does_not() {
    let w = Wip::default();
    let h = 0.005;
    let (g, s, v) = start(&w.params, [0.0, 0.0, 0.0, 0.02, 0.0, 0.0, 0.0, 0.05, 0.0]);
    let u = U2::new(0.5, 0.5);
    // The currents iR of each step, until a step fails.
    let run = |q: ForcingQuadrature| -> (Vec<f64>, Option<String>) {
        let vi = VariationalIntegrator::new(h)
            .with_discretisation(Discretisation::FirstOrder)
            .with_quadrature(q);
        let mut x = ViState { g, s, v };
        let mut currents = vec![x.v[3]];
        for _ in 0..100 {
            match vi.step(&w, &x, &u, &u) {
                Ok((next, _)) => x = next,
                Err(e) => return (currents, Some(e.to_string())),
            }
            currents.push(x.v[3]);
        }
        (currents, None)
    };
    let (left, err) = run(ForcingQuadrature::Left);
    let ratios: Vec<f64> = left
        .windows(2)
        .skip(1)
        .take(4)
        .map(|p| p[1] / p[0])
        .collect();
    println!(
        "left-point forcing: first currents {:?}, ratios {ratios:?}, ended by {err:?}",
        &left[..6.min(left.len())]
    );
    // Geometric divergence. Per step the current is multiplied by
    //   1 − h R_m/L_m − h² (k_e n_wm)²/(L_m J)
    // (the second term: the lagged motor torque k_e n_wm i_{k−1} spins the rotor, whose
    // back-EMF enters the same step), J the inertia the relative wheel motion drives. J is at
    // least the rotor and gear stage, I_m n_wm² + I_g n_wg², which bounds the factor:
    // −17.75 − 2.9 ≤ factor < −17.75.
    let p = w.params;
    let electrical = 1.0 - h * p.R_m / p.L_m;
    let j_min = p.I_m * p.n_wm * p.n_wm + p.I_g * p.n_wg * p.n_wg;
    let coupling = h * h * (p.k_e * p.n_wm).powi(2) / (p.L_m * j_min);
    println!(
        "predicted factor in [{:.2}, {electrical:.2})",
        electrical - coupling
    );
    assert!(
        ratios
            .iter()
            .all(|&r| r < electrical && r >= electrical - coupling),
        "{ratios:?}"
    );
    assert!(
        ratios
            .windows(2)
            .skip(1)
            .all(|q| (q[1] / q[0] - 1.0).abs() < 0.01),
        "geometric: {ratios:?}"
    );
    assert!(
        err.is_some() || left.last().unwrap().abs() > 1e6,
        "explicit forcing must diverge"
    );
    let (right, err) = run(ForcingQuadrature::Right);
    assert!(err.is_none(), "default quadrature steps: {err:?}");
    let imax = right.iter().fold(0.0f64, |m, i| m.max(i.abs()));
    println!("right-point forcing: 100 steps, max |iR| = {imax:.4} A");
    assert!(imax < 1.0, "default stays bounded");
}

/// The two Newton Jacobian policies solve the same equations to the same tolerance: over
/// 1 s of a falling robot their trajectories agree to 1e-9 (per-step differences ~1e-13
/// relative, amplified at most e^{7.4 t} ≈ 1.7e3 by the unstable mode, eigenvalue 7.42/s).
#[test]
fn jacobian_policies_agree() {
    use dmech::{JacobianPolicy, NewtonCache};
    let w = Wip::default();
    let h = 0.005;
    let (g, s, v) = start(&w.params, MOVING);
    let exact = VariationalIntegrator::new(h).with_discretisation(Discretisation::FirstOrder);
    let reuse = VariationalIntegrator::new(h)
        .with_discretisation(Discretisation::FirstOrder)
        .with_jacobian(JacobianPolicy::ReuseAcrossSteps);
    let (mut a, mut b) = (ViState { g, s, v }, ViState { g, s, v });
    let mut cache = NewtonCache::default();
    let (mut it_a, mut it_b) = (0, 0);
    for k in 0..200 {
        let u = U2::new(1.5 * (k as f64 * 0.05).sin(), 0.8);
        let (na, ia) = exact.step(&w, &a, &u, &u).unwrap();
        let (nb, ib) = reuse.step_cached(&w, &b, &u, &u, &b.v, &mut cache).unwrap();
        it_a += ia;
        it_b += ib;
        a = na;
        b = nb;
    }
    let d = (a.v - b.v).amax() / (1.0 + a.v.amax());
    println!("relative difference after 1 s: {d:.2e}; iterations {it_a} (exact) vs {it_b} (reuse)");
    assert!(d < 1e-9, "{d:e}");
}

/// `wip simulate --integrator midpoint` (the `simulate` function the command runs) against
/// the continuous model by RK4 at h = 25 µs, at h = 5, 2.5, 1.25, 0.625 ms over 1 s: the
/// whole reduced state (pose, tilt, velocities, currents) at the end. Derived order: 2
/// (symmetric discrete Lagrangian, connection and forcing). The default WIP's current is
/// stiff (h R_m/L_m = 18.75 at 5 ms), so this also checks that the midpoint forcing keeps
/// order 2 on a smooth solution: its factor on the current mode, (1 − hR/2L)/(1 + hR/2L) =
/// −0.81 at 5 ms, damps the start's transient within the run.
#[test]
fn wip_simulate_midpoint_converges_with_order_two() {
    use dmech::Integrator;
    use robots::wip::simulate::{simulate, InputSchedule};
    let w = Wip::default();
    let t_end: f64 = 1.0;
    let schedule = InputSchedule {
        t: vec![0.0, t_end],
        u: vec![[1.0, 0.5], [1.0, 0.5]],
    };
    let x0 = ReducedState::from_column_slice(&MOVING);
    let h_ref = 2.5e-5;
    let n_ref = (t_end / h_ref).round() as usize;
    let reference = *simulate(&w, Integrator::Rk4, h_ref, &x0, &schedule, n_ref)
        .unwrap()
        .x
        .last()
        .unwrap();
    let hs = [0.005, 0.0025, 0.00125, 0.000625];
    let errs: Vec<f64> = hs
        .iter()
        .map(|&h| {
            let n = (t_end / h).round() as usize;
            let traj = simulate(&w, Integrator::Midpoint, h, &x0, &schedule, n).unwrap();
            (traj.x.last().unwrap() - reference).amax()
        })
        .collect();
    let orders: Vec<f64> = errs.windows(2).map(|e| (e[0] / e[1]).log2()).collect();
    println!(
        "midpoint: state errors {}; observed orders {orders:.3?}",
        Sci(&errs)
    );
    for (i, o) in orders.iter().enumerate() {
        assert!(
            *o >= 1.9,
            "observed order {o:.3} between h = {} and {}",
            hs[i],
            hs[i + 1]
        );
    }
}

/// The stiff electromechanical mode undamped (R_m = 0, ω ≈ 363 rad/s, hω ≈ 1.8 at 5 ms),
/// 10⁵ steps: the midpoint scheme is stable on it and its energy error is bounded (the
/// last tenth's envelope under twice the first's: a drift over the run larger than 1.25×
/// the bounded error would exceed that; see `tests/tests/generic/midpoint_integrator.rs`), with
/// the Newton iterations per step the simulator's policy needs. The first-order scheme's
/// envelope is printed beside it (docs/integrator.md).
#[test]
fn midpoint_on_the_undamped_electromechanical_mode() {
    use dmech::{Discretisation, JacobianPolicy, NewtonCache};
    let w = conservative();
    let (h, n) = (0.005, 100_000);
    let (g, s, v) = start(&w.params, MOVING);
    let e0 = energy(&w, &s, &v);
    let zero = U2::zeros();
    for disc in [Discretisation::FirstOrder, Discretisation::Midpoint] {
        let vi = VariationalIntegrator::new(h)
            .with_discretisation(disc)
            .with_jacobian(JacobianPolicy::ReuseAcrossSteps);
        let mut x = ViState {
            g,
            s,
            v: vi.start(&w, &s, &v, &zero).unwrap(),
        };
        let mut cache = NewtonCache::default();
        let (mut envelope, mut iterations) = ([0.0f64; 10], 0);
        for k in 0..n {
            let (next, it) = vi
                .step_cached(&w, &x, &zero, &zero, &x.v, &mut cache)
                .unwrap();
            x = next;
            iterations += it;
            let s_e = disc.evaluation_point(h, &x.s, &x.v);
            let tenth = &mut envelope[k * 10 / n];
            *tenth = tenth.max((energy(&w, &s_e, &x.v) - e0).abs());
        }
        println!(
            "{disc:?}: E0 = {e0:.4} J, max |E − E0| per tenth {} J, {:.2} Newton iterations per step",
            Sci(&envelope),
            iterations as f64 / n as f64
        );
        assert!(x.v.iter().all(|z| z.is_finite()));
        if disc == Discretisation::Midpoint {
            assert!(
                envelope[9] < 2.0 * envelope[0],
                "midpoint energy drifts: {envelope:?}"
            );
        }
    }
}

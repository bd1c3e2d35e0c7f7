//! The OCP transcriptions of dmech-ocp agree with the integrators of dmech on the WIP,
//! and their stage Jacobians by dual numbers agree with central differences.

use dmech::continuous::{ContinuousModel, ContinuousState};
use dmech::{Discretisation, ForcingQuadrature, RungeKutta, VariationalIntegrator, ViState};
use dmech_lie::LieGroup;
use dmech_ocp::transcription::runge_kutta::RkStages;
use dmech_ocp::transcription::variational::VarIntStages;
use nalgebra::SVector;
use num_dual::DualSVec64;
use robots::wip::state::from_reduced;
use robots::wip::{ReducedState, Wip};

type X = SVector<f64, 15>; // coords(3) + s(5) + v(5) + u(2)
type W = SVector<f64, 7>; // v(5) + u(2)

fn stage_x(g: &[f64], s: &SVector<f64, 5>, v: &SVector<f64, 5>, u: &SVector<f64, 2>) -> X {
    X::from_iterator(
        g.iter()
            .copied()
            .chain(s.iter().copied())
            .chain(v.iter().copied())
            .chain(u.iter().copied()),
    )
}

fn u_at(k: usize) -> SVector<f64, 2> {
    SVector::<f64, 2>::new(1.5 * (k as f64 * 0.02).sin(), 0.7)
}

/// A VI trajectory satisfies the VI transcription: dynamics exactly (same operations) and
/// the stage equality to Newton's tolerance times the Jacobian's scale
/// (‖J‖ ≈ I_m n_wm²/h² ≈ 30, tol·(1 + ‖v‖) ≈ 1e-11 → 3e-10; 1e-8 leaves room for the
/// round-off of recomputing s_{k−1} = s_k − h v_{k−1}).
/// Both discretisations.
#[test]
fn vi_trajectory_satisfies_the_vi_transcription() {
    for d in [Discretisation::FirstOrder, Discretisation::Midpoint] {
        vi_trajectory_satisfies_its_transcription(d);
    }
}

fn vi_trajectory_satisfies_its_transcription(d: Discretisation) {
    let w = Wip::default();
    let h = 0.005;
    let st = VarIntStages::new::<3, 5, 2>(&w, h, ForcingQuadrature::Right).with_discretisation(d);
    let x0 = ReducedState::from_column_slice(&[0.5, 0.2, 0.3, 0.05, 0.1, 0.2, 0.3, 0.1, 0.0]);
    let (g, s, v) = from_reduced(&w.params, &x0, [0.0; 4]);
    let vi = VariationalIntegrator::new(h).with_discretisation(d);
    let mut traj = vec![ViState { g, s, v }];
    for k in 0..400 {
        let next = vi
            .step(&w, traj.last().unwrap(), &u_at(k), &u_at(k + 1))
            .unwrap()
            .0;
        traj.push(next);
    }
    let (mut worst_dyn, mut worst_eq): (f64, f64) = (0.0, 0.0);
    for k in 1..400 {
        let (a, b) = (&traj[k], &traj[k + 1]);
        let xk = stage_x(&a.g.coordinates(), &a.s, &traj[k - 1].v, &u_at(k - 1));
        let wk = W::from_iterator(a.v.iter().copied().chain(u_at(k).iter().copied()));
        let want = stage_x(&b.g.coordinates(), &b.s, &a.v, &u_at(k));
        let got = st.dynamics::<f64, 3, 5, 2, 15, 7>(&xk, &wk);
        worst_dyn = worst_dyn.max((got - want).amax() / (1.0 + want.amax()));
        worst_eq = worst_eq.max(st.equality::<f64, 3, 5, 2, 15, 7>(&xk, &wk).amax());
    }
    println!("{d:?} transcription: dynamics {worst_dyn:.2e} (relative), equality {worst_eq:.2e}");
    assert!(worst_dyn < 4.0 * f64::EPSILON);
    assert!(worst_eq < 1e-8);
}

/// An RK4 trajectory of the continuous model satisfies the RK4 transcription (same
/// formulas, different code path: agreement to a few ε relative).
#[test]
fn rk4_trajectory_satisfies_the_rk4_transcription() {
    let w = Wip::default();
    let h = 0.0005;
    let st = RkStages::new::<3, 5, 2>(&w, h, RungeKutta::Rk4);
    let x0 = ReducedState::from_column_slice(&[0.5, 0.2, 0.3, 0.05, 0.1, 0.2, 0.3, 0.1, 0.0]);
    let (g, s, v) = from_reduced(&w.params, &x0, [0.0; 4]);
    let mut y = ContinuousState { g, s, v };
    let mut worst: f64 = 0.0;
    for k in 0..400 {
        let u = u_at(k);
        let xk = stage_x(&y.g.coordinates(), &y.s, &y.v, &u_at(k.saturating_sub(1)));
        let next = ContinuousModel::step(&w, RungeKutta::Rk4, h, &y, &u).unwrap();
        let want = stage_x(&next.g.coordinates(), &next.s, &next.v, &u);
        let got = st.dynamics::<f64, 3, 5, 2, 15, 2>(
            &xk,
            &SVector::<f64, 2>::from_column_slice(u.as_slice()),
        );
        worst = worst.max((got - want).amax() / (1.0 + want.amax()));
        y = next;
    }
    println!("RK4 transcription vs simulator: {worst:.2e} relative");
    assert!(worst < 1e-13);
}

/// Stage Jacobians by dual numbers (22 directions at once) against central differences
/// (step 1e-6: truncation ≈ 1e-12·|f'''|, round-off ≈ 1e-10·|f|).
#[test]
fn stage_jacobians_match_central_differences() {
    let w = Wip::default();
    let h = 0.005;
    let vi = VarIntStages::new::<3, 5, 2>(&w, h, ForcingQuadrature::Right);
    let z0 = SVector::<f64, 22>::from_fn(|i, _| 0.3 * ((i as f64) * 1.7).sin() + 0.05 * i as f64);
    type D = DualSVec64<22>;
    let split = |z: &SVector<D, 22>| {
        (
            SVector::<D, 15>::from_fn(|i, _| z[i]),
            SVector::<D, 7>::from_fn(|i, _| z[15 + i]),
        )
    };
    let (_, jd) = dmech_lie::dual::value_and_jacobian(
        |z: &SVector<D, 22>| {
            let (x, wv) = split(z);
            let f = vi.dynamics::<D, 3, 5, 2, 15, 7>(&x, &wv);
            let e = vi.equality::<D, 3, 5, 2, 15, 7>(&x, &wv);
            SVector::<D, 20>::from_fn(|i, _| if i < 15 { f[i] } else { e[i - 15] })
        },
        &z0,
    );
    let eval = |z: &SVector<f64, 22>| {
        let x = SVector::<f64, 15>::from_fn(|i, _| z[i]);
        let wv = SVector::<f64, 7>::from_fn(|i, _| z[15 + i]);
        let f = vi.dynamics::<f64, 3, 5, 2, 15, 7>(&x, &wv);
        let e = vi.equality::<f64, 3, 5, 2, 15, 7>(&x, &wv);
        SVector::<f64, 20>::from_fn(|i, _| if i < 15 { f[i] } else { e[i - 15] })
    };
    let mut worst: f64 = 0.0;
    for j in 0..22 {
        let step = 1e-6 * (1.0 + z0[j].abs());
        let mut zp = z0;
        let mut zm = z0;
        zp[j] += step;
        zm[j] -= step;
        let col = (eval(&zp) - eval(&zm)) / (2.0 * step);
        for i in 0..20 {
            let scale = 1.0 + jd[(i, j)].abs();
            worst = worst.max((col[i] - jd[(i, j)]).abs() / scale);
        }
    }
    println!("worst relative Jacobian difference: {worst:.2e}");
    assert!(worst < 1e-5);
}

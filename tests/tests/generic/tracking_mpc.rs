//! The constrained MPC of `dmech_ocp::tracking::mpc` on random systems' references (those
//! of `tracking.rs`): with its bounds inactive its first move is the LQ tracker's over the
//! same horizon; with them active its moves stay inside them, and its closed loop on a
//! mismatched plant is compared with the LQ tracker's saturated at the same bounds.

use crate::tracking::{reference_of, spec, Reference};
use dmech::Discretisation;
use dmech_ocp::qp::QpSettings;
use dmech_ocp::tracking::{
    linearise_along, lq_design, track_by, LinearisedPlan, Mpc, MpcError, MpcSettings,
    TrackingError, TrackingWeights,
};
use dmech_ocp::transcription::VarIntTranscription;
use dmech_tests::random_system::{RandomSystem, Se2Family};
use nalgebra::{SMatrix, SVector};

const N: usize = 200;
const H: f64 = 0.02;
/// The QP's tolerance (the solver's default).
const QP_TOL: f64 = 1e-8;

/// Pose errors weigh 1e4, everything else and the inputs 1 (as `tracking.rs`'s LQ).
fn weights() -> TrackingWeights<9, 2> {
    let mut q = SMatrix::<f64, 9, 9>::from_diagonal_element(1.0);
    for i in 0..3 {
        q[(i, i)] = 1e4;
    }
    TrackingWeights {
        state: q,
        terminal: q * 10.0,
        input: SMatrix::identity(),
    }
}

/// Seed `seed`'s nominal random system, its reference and the reference's linearisation.
type Linearised = (
    Vec<SVector<f64, 9>>,
    Vec<SVector<f64, 4>>,
    LinearisedPlan<9, 2>,
);

fn linearised(system: &RandomSystem<Se2Family, 3, 2>) -> Linearised {
    let tr = VarIntTranscription::new(system, Reference(N), H, Discretisation::Midpoint);
    let (px, pw) = reference_of(&tr, N, H);
    let lin = linearise_along(&tr, &px, &pw).unwrap();
    (px, pw, lin)
}

fn inputs(pw: &[SVector<f64, 4>]) -> Vec<SVector<f64, 2>> {
    pw.iter()
        .map(|w| w.fixed_rows::<2>(2).into_owned())
        .collect()
}

fn settings(horizon: usize, bound: f64) -> MpcSettings<2> {
    MpcSettings {
        horizon,
        lower: SVector::repeat(-bound),
        upper: SVector::repeat(bound),
        qp: QpSettings::builder().tol(QP_TOL).build().unwrap(),
    }
}

/// With bounds that no move of the horizon reaches, the QP's first move is the Riccati
/// recursion's over the same horizon, from the LQ design's cost-to-go at its end (and so
/// the LQ tracker's own `−K_k δx`). Tolerance from the QP's: it stops with its objective
/// within `δ = 4 ε max(1, |f*|)` of the optimum `f*` (gap and residual terms, `ε` the
/// tolerance; `docs/qp.md`, "Termination"), and the objective is strongly convex in the
/// stacked inputs with modulus `m = 2 λ_min(R) = 2` (Hessian `2R + …`), so
/// `|δu_0 − δu_0*| ≤ √(2δ/m)`.
#[test]
fn with_inactive_bounds_the_first_move_is_the_finite_horizon_lq_move() {
    let horizon = 10;
    let bound = 1.0;
    for seed in 0..4 {
        let system = RandomSystem::<Se2Family, 3, 2>::draw(seed, spec(0.5, 0.2));
        let (_, pw, lin) = linearised(&system);
        let u_plan = inputs(&pw);
        let w = weights();
        let full = lq_design(&lin, &w).unwrap();
        let mut mpc = Mpc::new(lin.clone(), u_plan.clone(), &w, settings(horizon, bound)).unwrap();
        let mut worst = 0.0f64;
        for (i, k) in [0, 37, 120, N - 4].into_iter().enumerate() {
            let h = horizon.min(N - k);
            // The Riccati recursion over the QP's horizon alone.
            let window = LinearisedPlan {
                a: lin.a[k..k + h].to_vec(),
                b: lin.b[k..k + h].to_vec(),
            };
            let w_window = TrackingWeights {
                terminal: full.cost_to_go[k + h],
                ..w.clone()
            };
            let lq = lq_design(&window, &w_window).unwrap();
            // A deviation in every state, of a size the moves stay well inside the bounds.
            let dx = SVector::<f64, 9>::from_fn(|r, _| {
                let phase = (seed as usize * 9 + r + i) as f64;
                2e-3 * (1.7 * phase).sin()
            });
            // The premise: the LQ moves of the whole horizon inside the bounds.
            let mut x = dx;
            for j in 0..h {
                let du = -lq.gains[j] * x;
                let u = u_plan[k + j] + du;
                assert!(
                    u.amax() < 0.9 * bound,
                    "seed {seed}, sample {k}: the LQ reaches the bound at stage {j}"
                );
                x = window.a[j] * x + window.b[j] * du;
            }
            let expected = u_plan[k] - lq.gains[0] * dx;
            // The tracker's own move is the same (the recursion from the same cost-to-go).
            let tracker = u_plan[k] - full.gains[k] * dx;
            assert!((expected - tracker).amax() <= 1e-9 * (1.0 + expected.amax()));
            let m = mpc.input(k, &dx).unwrap();
            assert!(m.solved(), "seed {seed}, sample {k}: {:?}", m.status);
            // The optimum of the QP: the cost-to-go less stage 0's state term (x_0 is given).
            let f_star = dx.dot(&((full.cost_to_go[k] - w.state) * dx));
            let delta = 4.0 * QP_TOL * f_star.abs().max(1.0);
            let tol = (2.0 * delta / 2.0).sqrt();
            let d = (m.input - expected).norm();
            assert!(
                d <= tol,
                "seed {seed}, sample {k}: {:?} against {expected:?}",
                m.input
            );
            worst = worst.max(d / tol);
        }
        println!("seed {seed}: worst first-move difference {worst:.1e} of its tolerance");
    }
}

/// Bounds the LQ tracker runs into: a plant with more shape dependence and damping than
/// the design, started off the reference (pose 5 cm and 0.1 rad off, shape 0.1 off). The
/// MPC's inputs stay within the bounds (to the QP's primal tolerance, `ε` times the
/// bounds' scale) at every sample, every QP is solved, and the closed loops of the MPC and
/// of the LQ tracker clamped to the same bounds are reported side by side, not compared by
/// an assertion: neither is optimal for the mismatched plant. Measured (seeds 0–3): the
/// bounds hold the inputs at 145–189 of the 200 stages for both, and the state cost
/// `Σ δxᵀQδx` of the MPC is 0.1 %, 0.1 % and 6.9 % below the saturated LQ's for seeds 0–2
/// and 2.2 % above it for seed 3.
#[test]
fn with_active_bounds_the_moves_stay_inside() {
    let horizon = 10;
    let bound = 0.6;
    for seed in 0..4 {
        let system = RandomSystem::<Se2Family, 3, 2>::draw(seed, spec(0.5, 0.2));
        let plant_system = RandomSystem::<Se2Family, 3, 2>::draw(seed, spec(0.55, 0.3));
        let plant =
            VarIntTranscription::new(&plant_system, Reference(N), H, Discretisation::Midpoint);
        let (px, pw, lin) = linearised(&system);
        let u_plan = inputs(&pw);
        let w = weights();
        let mut mpc = Mpc::new(lin, u_plan.clone(), &w, settings(horizon, bound)).unwrap();
        let mut x0 = px[0];
        x0[0] += 0.05;
        x0[1] -= 0.05;
        x0[2] += 0.1;
        x0[3] += 0.1;
        let (mut moves, mut lq_clamped) = (Vec::new(), 0);
        let mpc_run = track_by(&plant, &x0, &pw, |k, x| {
            let m = mpc.input(k, &(x - px[k])).unwrap();
            moves.push(m);
            m.input
        })
        .unwrap();
        let lq_run = track_by(&plant, &x0, &pw, |k, x| {
            let unclamped = u_plan[k] - mpc.lq().gains[k] * (x - px[k]);
            let u = mpc.lq_input(k, &(x - px[k])).unwrap();
            lq_clamped += usize::from(u != unclamped);
            u
        })
        .unwrap();
        assert!(lq_clamped > 0, "seed {seed}: the LQ never met the bounds");
        let slack = QP_TOL * bound.max(1.0);
        for (k, m) in moves.iter().enumerate() {
            assert!(m.solved(), "seed {seed}, sample {k}: {:?}", m.status);
            assert!(
                m.input.amax() <= bound + slack,
                "seed {seed}, sample {k}: {:?} outside ±{bound}",
                m.input
            );
        }
        let at_bound = moves
            .iter()
            .filter(|m| m.input.amax() > bound - 1e-6)
            .count();
        assert!(at_bound > 0, "seed {seed}: the MPC never used its bounds");
        let cost = |xs: &[SVector<f64, 9>]| {
            (0..=N)
                .map(|k| {
                    let e = xs[k] - px[k];
                    e.dot(&(w.state * e))
                })
                .sum::<f64>()
        };
        let pose_error = |xs: &[SVector<f64, 9>]| {
            (0..=N)
                .map(|k| (xs[k].fixed_rows::<3>(0) - px[k].fixed_rows::<3>(0)).norm())
                .fold(0.0, f64::max)
        };
        let end =
            |xs: &[SVector<f64, 9>]| (xs[N].fixed_rows::<3>(0) - px[N].fixed_rows::<3>(0)).norm();
        println!(
            "seed {seed}: {at_bound} MPC moves and {lq_clamped} LQ moves at a bound; state \
             cost MPC {:.4e}, saturated LQ {:.4e}; largest pose error {:.3e} / {:.3e}; end \
             {:.3e} / {:.3e}",
            cost(&mpc_run),
            cost(&lq_run),
            pose_error(&mpc_run),
            pose_error(&lq_run),
            end(&mpc_run),
            end(&lq_run)
        );
    }
}

/// The refusals a caller can match on.
#[test]
fn bad_mpc_data_is_refused() {
    let system = RandomSystem::<Se2Family, 3, 2>::draw(0, spec(0.5, 0.2));
    let (_, pw, lin) = linearised(&system);
    let u_plan = inputs(&pw);
    let w = weights();
    let e = Mpc::new(lin.clone(), u_plan[1..].to_vec(), &w, settings(5, 1.0));
    assert_eq!(
        e.unwrap_err(),
        MpcError::InputCount {
            inputs: N - 1,
            stages: N
        }
    );
    assert_eq!(
        Mpc::new(lin.clone(), u_plan.clone(), &w, settings(0, 1.0)).unwrap_err(),
        MpcError::EmptyHorizon
    );
    let mut empty = settings(5, 1.0);
    empty.lower[1] = 2.0;
    assert!(matches!(
        Mpc::new(lin.clone(), u_plan.clone(), &w, empty),
        Err(MpcError::EmptyBounds { input: 1, .. })
    ));
    let mut mpc = Mpc::new(lin, u_plan, &w, settings(5, 1.0)).unwrap();
    assert_eq!(
        mpc.input(N, &SVector::zeros()).unwrap_err(),
        MpcError::PastThePlan {
            sample: N,
            stages: N
        }
    );
    // A deviation the QP refuses (not finite): the LQ fallback, said so.
    let m = mpc.input(3, &SVector::repeat(f64::NAN)).unwrap();
    assert_eq!(m.status, None);
    assert!(!m.solved());
    // The fallback keeps the NaN, and the plant's step refuses it (here its Newton, whose
    // Jacobian at a NaN input does not factor).
    assert!(m.input.iter().all(|u| u.is_nan()));
    let plant = VarIntTranscription::new(&system, Reference(N), H, Discretisation::Midpoint);
    let run = track_by(&plant, &SVector::zeros(), &pw, |_, _| m.input);
    assert!(
        matches!(
            run,
            Err(TrackingError::SingularEquality { stage: 0 }
                | TrackingError::NotFinite { stage: 0 })
        ),
        "{run:?}"
    );
}

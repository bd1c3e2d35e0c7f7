//! The nonlinear MPC of `dmech_ocp::tracking::nmpc` on random systems' references (those
//! of `tracking.rs`, on their own midpoint transcription): with no inequality active its
//! first move is the LQ tracker's to first order in the deviation; with an input bound
//! that the LQ tracker runs into, its moves stay inside it.

use crate::tracking::{reference_of, spec};
use dmech::Discretisation;
use dmech_lie::Real;
use dmech_ocp::solver::{Curvature, Status};
use dmech_ocp::tracking::{
    track_by, Nmpc, NmpcError, NmpcMemory, NmpcSettings, SoftRow, TrackingWeights,
};
use dmech_ocp::transcription::{
    Condition, PlanningProblem, Stage, StartState, VarIntTranscription,
};
use dmech_tests::random_system::{RandomSystem, Se2Family};
use nalgebra::{SMatrix, SVector};

const N: usize = 200;
const H: f64 = 0.02;

/// The random system's stages with the first input bounded by `±self.1` (infinite: no
/// bound), nothing to optimise.
struct Bounded(usize, f64);

impl PlanningProblem<3, 2, 2, 1> for Bounded {
    fn horizon(&self) -> usize {
        self.0
    }
    fn start(&self) -> StartState<3, 2, 2> {
        StartState::at_rest(SVector::zeros(), SVector::zeros())
    }
    fn cost<T: Real>(&self, _k: usize, st: &Stage<T, 3, 2, 2>) -> T {
        st.input.dot(&st.input)
    }
    fn constraints<T: Real>(&self, _k: usize, st: &Stage<T, 3, 2, 2>) -> SVector<T, 1> {
        SVector::<T, 1>::new(st.input[0])
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, 1>, SVector<f64, 1>) {
        (SVector::repeat(-self.1), SVector::repeat(self.1))
    }
    fn conditions(&self) -> Vec<Condition> {
        Vec::new()
    }
}

/// Pose errors weigh 1e4, everything else and the inputs 1 (as `tracking_mpc.rs`).
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

fn settings(newton_steps: usize, tol: f64) -> NmpcSettings {
    NmpcSettings {
        horizon: 10,
        newton_steps,
        barrier: 1e-8,
        tol,
        budget_s: f64::INFINITY,
        curvature: Curvature::Exact,
        soft: Vec::new(),
    }
}

/// No bound: the horizon's problem is smooth and unconstrained, and its first move
/// `u(δx)` has `u(0) = ū_k` (the plan is a solution of the transcription) and
/// `∂u/∂δx = −K_k` (the problem's second-order expansion at the plan is the LQ problem over
/// the horizon from the cost-to-go `P_{k+H}`, whose first gain is the LQ tracker's). So
/// `d(ε) = |u(ε δ) − (ū_k − K_k ε δ)| = c ε² + O(ε³)`: halving `ε` divides it by 4. Solved
/// to a dual tolerance of 1e-11 (Newton from the LQ rollout converges quadratically), the
/// solver's error is at most ~1e-11 / λ_min(2R) = 5e-12 per input, far below `d` at the
/// sizes compared (`ε δ` of 1e-3 … 2.5e-4 in every state: `d ≳ 1e-8`). Asserted: the ratio
/// `d(ε)/d(ε/2)` within [3, 5] (4 + the O(ε) term) at each of three halvings, and `d` at the
/// smallest a thousand times the solver's error. Measured: ratios 4.00 throughout, `d` at
/// `ε = 1e-3` between 4e-6 and 3.5e-4 (0.9 % of the feedback `|K_k ε δ|` at most).
#[test]
fn unconstrained_the_first_move_is_the_lq_move_to_first_order() {
    for seed in 0..3 {
        let system = RandomSystem::<Se2Family, 3, 2>::draw(seed, spec(0.5, 0.2));
        let tr = VarIntTranscription::new(
            &system,
            Bounded(N, f64::INFINITY),
            H,
            Discretisation::Midpoint,
        );
        let (px, pw) = reference_of(&tr, N, H);
        let nmpc = Nmpc::new(&tr, px.clone(), pw.clone(), &weights(), settings(50, 1e-11)).unwrap();
        for (i, k) in [0usize, 57, 140].into_iter().enumerate() {
            let direction = SVector::<f64, 9>::from_fn(|r, _| {
                let phase = (seed as usize * 9 + r + i) as f64;
                (1.7 * phase).sin()
            });
            let u_plan: SVector<f64, 2> = pw[k].fixed_rows::<2>(2).into_owned();
            let gain = nmpc.lq().gains[k];
            let mut d = Vec::new();
            for eps in [1e-3, 5e-4, 2.5e-4, 1.25e-4] {
                let dx = direction * eps;
                let mut memory = NmpcMemory::default();
                let m = nmpc.step(&tr, k, &(px[k] + dx), &mut memory).unwrap();
                assert_eq!(m.status, Status::Solved, "seed {seed}, sample {k}, ε {eps}");
                let lq = u_plan - gain * dx;
                d.push(((m.input.unwrap() - lq).norm(), (gain * dx).norm()));
            }
            println!(
                "seed {seed}, sample {k}: d(ε) {:?}",
                d.iter().map(|p| p.0).collect::<Vec<_>>()
            );
            for pair in d.windows(2) {
                let ratio = pair[0].0 / pair[1].0;
                assert!(
                    (3.0..=5.0).contains(&ratio),
                    "seed {seed}, sample {k}: d halves by {ratio:.2} ({d:?})"
                );
            }
            // The smallest `d` far above the solver's error: the ratios measure the expansion.
            let last = d[d.len() - 1].0;
            assert!(last > 1e3 * 5e-12, "seed {seed}, sample {k}: {d:?}");
        }
    }
}

/// The bound the LQ tracker runs into (`|u_0| ≤ 0.6`, as `tracking_mpc.rs`'s active case):
/// a plant with more shape dependence and damping, started off the reference (pose 5 cm
/// and 0.1 rad, shape 0.1). Real-time iteration, 3 Newton steps per sample from the shifted
/// iterate: every sample's move exists (no fallback), stays inside the bound (the interior
/// point's iterates are strictly feasible), the bound is used, and the pose ends closer
/// to the reference than it started.
#[test]
fn with_an_active_bound_the_moves_stay_inside() {
    let bound = 0.6;
    for seed in 0..3 {
        let system = RandomSystem::<Se2Family, 3, 2>::draw(seed, spec(0.5, 0.2));
        let plant_system = RandomSystem::<Se2Family, 3, 2>::draw(seed, spec(0.55, 0.3));
        let tr = VarIntTranscription::new(&system, Bounded(N, bound), H, Discretisation::Midpoint);
        let plant = VarIntTranscription::new(
            &plant_system,
            Bounded(N, bound),
            H,
            Discretisation::Midpoint,
        );
        let (px, pw) = reference_of(&tr, N, H);
        let nmpc = Nmpc::new(&tr, px.clone(), pw.clone(), &weights(), settings(3, 1e-8)).unwrap();
        let mut x0 = px[0];
        x0[0] += 0.05;
        x0[1] -= 0.05;
        x0[2] += 0.1;
        x0[3] += 0.1;
        let mut memory = NmpcMemory::default();
        let mut moves = Vec::new();
        let run = track_by(&plant, &x0, &pw, |k, x| {
            let m = nmpc.step(&tr, k, x, &mut memory).unwrap();
            let u = m
                .input
                .unwrap_or_else(|| panic!("seed {seed}, sample {k}: {:?}", m.status));
            moves.push(m);
            u
        })
        .unwrap();
        let inside = moves.iter().all(|m| m.input.unwrap()[0].abs() < bound);
        let at_bound = moves
            .iter()
            .filter(|m| m.input.unwrap()[0].abs() > bound - 1e-3)
            .count();
        let warm = moves.iter().filter(|m| m.warm).count();
        let pose = |k: usize| (run[k].fixed_rows::<3>(0) - px[k].fixed_rows::<3>(0)).norm();
        println!(
            "seed {seed}: {at_bound} moves within 1e-3 of the bound, {warm} warm; pose error \
             {:.3e} at the start, {:.3e} at the end",
            pose(0),
            pose(N)
        );
        assert!(inside, "seed {seed}: a move left the bound");
        assert!(at_bound > 0, "seed {seed}: the bound was never used");
        assert_eq!(
            warm,
            N - 1,
            "seed {seed}: every sample after the first is warm"
        );
        assert!(pose(N) < pose(0), "seed {seed}");
    }
}

/// The refusals a caller can match on.
#[test]
fn bad_nmpc_data_is_refused() {
    let system = RandomSystem::<Se2Family, 3, 2>::draw(0, spec(0.5, 0.2));
    let tr = VarIntTranscription::new(&system, Bounded(N, 1.0), H, Discretisation::Midpoint);
    let (px, pw) = reference_of(&tr, N, H);
    let w = weights();
    let e = Nmpc::new(&tr, px[1..].to_vec(), pw.clone(), &w, settings(3, 1e-8));
    assert!(matches!(e, Err(NmpcError::PlanLength { .. })));
    let mut s = settings(0, 1e-8);
    assert!(matches!(
        Nmpc::new(&tr, px.clone(), pw.clone(), &w, s.clone()),
        Err(NmpcError::Empty { steps: 0, .. })
    ));
    s = settings(3, 1e-8);
    s.barrier = 0.0;
    assert!(matches!(
        Nmpc::new(&tr, px.clone(), pw.clone(), &w, s),
        Err(NmpcError::NotPositive { .. })
    ));
    s = settings(3, 1e-8);
    s.soft = vec![SoftRow {
        row: 1,
        weight: 1.0,
    }];
    assert!(matches!(
        Nmpc::new(&tr, px.clone(), pw.clone(), &w, s),
        Err(NmpcError::SoftRow {
            row: 1,
            rows: 1,
            ..
        })
    ));
    let nmpc = Nmpc::new(&tr, px.clone(), pw, &w, settings(3, 1e-8)).unwrap();
    let mut memory = NmpcMemory::default();
    assert_eq!(
        nmpc.step(&tr, N, &px[0], &mut memory).unwrap_err(),
        NmpcError::PastThePlan {
            sample: N,
            stages: N
        }
    );
    // A state that is not finite: no move, the caller's fallback.
    let m = nmpc
        .step(&tr, 3, &SVector::repeat(f64::NAN), &mut memory)
        .unwrap();
    assert!(m.input.is_none(), "{:?}", m.status);
}

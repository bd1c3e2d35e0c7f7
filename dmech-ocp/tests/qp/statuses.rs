//! Warm starts, and what the solver reports on QPs without a solution or with bad data.

use super::{clarabel_oracle::check_kkt, random};
use dmech_ocp::qp::{QpError, QpSettings, QpSolver, QpStatus, Rows, Stage, StageQp, Terminal};
use nalgebra::{SMatrix, SVector};

fn solver<const NX: usize, const NU: usize, const NC: usize>() -> QpSolver<NX, NU, NC> {
    QpSolver::new(QpSettings::default())
}

/// A receding horizon on a random QP (every row soft, so that each shifted QP has a
/// solution): the QP of sample `t + 1` is the one of sample `t` shifted by a stage (its
/// last stage repeated) from the state its first input reaches. The warm start from the
/// shifted solution finds the cold start's solution (the KKT conditions hold; inputs
/// equal to `2√(2δ)` of `clarabel_oracle`'s derivation) in fewer iterations over all.
#[test]
fn shifted_warm_start_reaches_the_same_solution_in_fewer_iterations() {
    let mut qp = random::stage_qp::<6, 2, 4>(77, 15, 1.0);
    let (mut cold_solver, mut warm_solver) = (solver(), solver());
    let mut previous = cold_solver.solve(&qp);
    let (mut cold_total, mut warm_total) = (0, 0);
    for _ in 0..20 {
        let mut stages = qp.stages().to_vec();
        stages.remove(0);
        stages.push(stages.last().unwrap().clone());
        qp = StageQp::new(previous.x[1], stages, qp.terminal().clone()).unwrap();
        let cold = cold_solver.solve(&qp);
        let warm = warm_solver.solve_warm(&qp, &previous.shifted());
        assert_eq!(
            (cold.status, warm.status),
            (QpStatus::Solved, QpStatus::Solved),
            "{:?} {:?}",
            cold.info,
            warm.info
        );
        assert!(warm.info.warm && !cold.info.warm);
        check_kkt(&qp, &warm);
        let du_tol = 2.0 * (8e-8 * cold.info.objective.abs().max(1.0)).sqrt();
        for (a, b) in warm.u.iter().zip(&cold.u) {
            assert!((a - b).amax() <= du_tol);
        }
        cold_total += cold.info.iterations;
        warm_total += warm.info.iterations;
        previous = warm;
    }
    println!("20 shifted QPs: {cold_total} iterations cold, {warm_total} warm");
    assert!(warm_total < cold_total);
}

/// The same QP with its gradients moved by 1 %: warm from the first solution, fewer
/// iterations than cold, the same solution.
#[test]
fn warm_start_of_a_nearby_qp_takes_fewer_iterations() {
    let qp = random::stage_qp::<4, 2, 3>(5, 12, 0.3);
    let first = solver().solve(&qp);
    let mut stages = qp.stages().to_vec();
    for st in &mut stages {
        st.q_vec *= 1.01;
        st.r_vec *= 1.01;
    }
    let nearby = StageQp::new(*qp.x0(), stages, qp.terminal().clone()).unwrap();
    let cold = solver().solve(&nearby);
    let warm = solver().solve_warm(&nearby, &first.warm_start());
    assert_eq!(
        (cold.status, warm.status),
        (QpStatus::Solved, QpStatus::Solved)
    );
    check_kkt(&nearby, &warm);
    println!(
        "iterations cold {}, warm {}",
        cold.info.iterations, warm.info.iterations
    );
    assert!(warm.info.iterations < cold.info.iterations);
}

/// A double integrator (`h = 0.1`, 10 stages, `|u| ≤ 1`) from rest cannot travel 10 (at
/// most `½ (Nh)² = 0.5`): the hard terminal row makes the QP infeasible.
#[test]
fn an_unreachable_hard_bound_is_reported_infeasible() {
    let h = 0.1;
    let mut st = Stage::<2, 1, 1>::zeros();
    st.a = SMatrix::<f64, 2, 2>::new(1.0, h, 0.0, 1.0);
    st.b = SMatrix::<f64, 2, 1>::new(0.5 * h * h, h);
    st.q = SMatrix::identity();
    st.r = SMatrix::identity();
    st.rows.input_bound(0, 0, -1.0, 1.0);
    let mut terminal = Terminal::<2, 1, 1>::zeros();
    terminal.rows.state_bound(0, 0, 10.0, f64::INFINITY);
    let qp = StageQp::new(SVector::zeros(), vec![st.clone(); 10], terminal.clone()).unwrap();
    let sol = solver().solve(&qp);
    assert_eq!(sol.status, QpStatus::PrimalInfeasible, "{:?}", sol.info);
    // Reachable (0.3 ≤ 0.5): solved.
    terminal.rows.state_bound(0, 0, 0.3, f64::INFINITY);
    let qp = StageQp::new(SVector::zeros(), vec![st; 10], terminal).unwrap();
    assert_eq!(solver().solve(&qp).status, QpStatus::Solved);
}

/// A bound that the given initial state violates is infeasible at once.
#[test]
fn a_violated_row_on_the_initial_state_is_infeasible() {
    let mut st = Stage::<1, 1, 1>::zeros();
    st.a = SMatrix::identity();
    st.b = SMatrix::identity();
    st.r = SMatrix::identity();
    st.rows.state_bound(0, 0, -1.0, 1.0);
    let qp = StageQp::new(SVector::repeat(2.0), vec![st; 3], Terminal::zeros()).unwrap();
    assert_eq!(solver().solve(&qp).status, QpStatus::PrimalInfeasible);
}

/// No curvature in `u`, a gradient `r = −1`, `u ≥ 0` only: the objective falls without
/// bound along `u → ∞`.
#[test]
fn a_direction_of_unbounded_descent_is_reported() {
    let mut st = Stage::<1, 1, 1>::zeros();
    st.a = SMatrix::identity();
    st.b = SMatrix::identity();
    st.q = SMatrix::identity();
    st.r_vec = SVector::repeat(-1.0);
    st.rows.input_bound(0, 0, 0.0, f64::INFINITY);
    let mut terminal = Terminal::<1, 1, 1>::zeros();
    terminal.q = SMatrix::zeros();
    let mut last = st.clone();
    last.q = SMatrix::zeros();
    // x_k grows with the inputs but only x_0 … x_{N−1} are priced: u_{N−1} is free of cost.
    let qp = StageQp::new(SVector::zeros(), vec![st, last], terminal).unwrap();
    let sol = solver().solve(&qp);
    assert_eq!(sol.status, QpStatus::DualInfeasible, "{:?}", sol.info);
}

#[test]
fn bad_data_is_refused_with_its_reason() {
    let mut st = Stage::<1, 1, 1>::zeros();
    st.r = SMatrix::repeat(-1.0);
    let e = StageQp::new(SVector::zeros(), vec![st.clone()], Terminal::zeros());
    assert_eq!(e.unwrap_err(), QpError::NotConvex { stage: 0 });
    st.r = SMatrix::repeat(f64::NAN);
    let e = StageQp::new(SVector::zeros(), vec![st], Terminal::zeros());
    assert_eq!(
        e.unwrap_err(),
        QpError::NotFinite {
            stage: 0,
            what: "R"
        }
    );
    let e = StageQp::<1, 1, 1>::new(SVector::zeros(), vec![], Terminal::zeros());
    assert_eq!(e.unwrap_err(), QpError::EmptyHorizon);
    let _ = Rows::<1, 1, 1>::free();
}

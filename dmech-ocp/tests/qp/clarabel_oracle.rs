//! Our interior point against clarabel on random feasible stage QPs of several sizes
//! (hard and soft rows, active and inactive, some sides infinite), and the KKT conditions
//! checked directly on our solution.
//!
//! Tolerances. Both solvers stop with a duality gap within `ε = 1e-8` of
//! `max(1, |f|)` (ours: `pairs · μ`; clarabel: `tol_gap_abs`, `tol_gap_rel`) and
//! residuals within `ε` of their scales. A point that is feasible to `ε` and whose gap
//! is `g` is within `g` plus the residuals' first-order effect of the optimum; we allow
//! `δ = 4 ε max(1, |f*|)` per solver (gap and residual terms, twice each), so the
//! objectives agree to `2δ`. The QPs are strongly convex in the inputs with modulus
//! `m ≥ 1` (`random.rs`: `[Q S; Sᵀ R] ⪰ blockdiag(0, I)`, the soft prices convex), so
//! `½ m ‖u − u*‖² ≤ f(u) − f* ≤ δ` and the inputs agree to `2 √(2δ/m)`.

use super::{oracle, random};
use dmech_ocp::qp::{QpSettings, QpSolution, QpSolver, QpStatus, StageQp};

const EPS: f64 = 1e-8;

/// Our solution and clarabel's agree (module doc); returns `(iterations, objective
/// difference / its tolerance, input difference / its tolerance)`.
fn compare<const NX: usize, const NU: usize, const NC: usize>(
    qp: &StageQp<NX, NU, NC>,
) -> (usize, f64, f64) {
    let mut solver = QpSolver::new(QpSettings::builder().tol(EPS).build().unwrap());
    let ours = solver.solve(qp);
    assert_eq!(ours.status, QpStatus::Solved, "{:?}", ours.info);
    check_kkt(qp, &ours);
    let theirs = oracle::solve(qp, EPS).expect("clarabel solves it");
    let f = theirs.objective;
    let delta = 4.0 * EPS * f.abs().max(1.0);
    let df = (ours.info.objective - f).abs();
    assert!(
        df <= 2.0 * delta,
        "objective {} against {f}",
        ours.info.objective
    );
    let du_tol = 2.0 * (2.0 * delta).sqrt();
    let du = ours
        .u
        .iter()
        .zip(&theirs.u)
        .map(|(a, b)| (a - b).amax())
        .fold(0.0, f64::max);
    assert!(
        du <= du_tol,
        "inputs differ by {du:.2e} (tolerance {du_tol:.2e})"
    );
    (ours.info.iterations, df / (2.0 * delta), du / du_tol)
}

/// The KKT conditions on `sol` with its own multipliers: stationarity and the dynamics
/// to the termination's tolerance, each hard row within its bounds and each soft row's
/// violation the one reported, multipliers of the right sign and size, and
/// complementarity to the gap (each pair's product is at most `pairs · μ ≤ ε max(1,|f|)`,
/// plus a multiplier times the primal residual).
pub fn check_kkt<const NX: usize, const NU: usize, const NC: usize>(
    qp: &StageQp<NX, NU, NC>,
    sol: &QpSolution<NX, NU, NC>,
) {
    let n = qp.horizon();
    let (mut dual, mut primal) = (qp.terminal().q_vec.amax(), qp.x0().amax());
    for st in qp.stages() {
        dual = dual.max(st.q_vec.amax()).max(st.r_vec.amax());
        primal = primal.max(st.c.amax());
    }
    for k in 0..=n {
        let rows = qp.rows(k);
        for i in 0..NC {
            for b in [rows.hi[i], rows.lo[i]] {
                if b.is_finite() {
                    primal = primal.max(b.abs());
                }
            }
            if let Some(p) = rows.soft[i] {
                dual = dual.max(p.l1);
            }
        }
    }
    let (dual, primal) = (dual.max(1.0), primal.max(1.0));
    // Rounding of the residuals' sums: a few ulps of the largest term.
    let (stat_tol, feas_tol) = (EPS * dual * 1.01, EPS * primal * 1.01);
    let gap = EPS * sol.info.objective.abs().max(1.0);
    for k in 0..=n {
        let (x, lam, rows) = (&sol.x[k], &sol.row_multipliers[k], qp.rows(k));
        let (z, r_x) = if k < n {
            let (st, u, pi) = (&qp.stages()[k], &sol.u[k], &sol.pi[k]);
            let r_u = st.r * u
                + st.s.transpose() * x
                + st.r_vec
                + st.b.transpose() * pi
                + rows.e.transpose() * lam;
            assert!(r_u.amax() <= stat_tol, "stage {k}: ∂L/∂u = {r_u}");
            let dyn_res = st.a * x + st.b * u + st.c - sol.x[k + 1];
            assert!(dyn_res.amax() <= feas_tol, "stage {k}: dynamics {dyn_res}");
            let r_x = st.q * x + st.s * u + st.q_vec + st.a.transpose() * pi;
            (rows.d * x + rows.e * u, r_x + rows.d.transpose() * lam)
        } else {
            let t = qp.terminal();
            (rows.d * x, t.q * x + t.q_vec + rows.d.transpose() * lam)
        };
        if k > 0 {
            let r_x = r_x - sol.pi[k - 1];
            assert!(r_x.amax() <= stat_tol, "stage {k}: ∂L/∂x = {r_x}");
        }
        for i in 0..NC {
            let (lo, hi, l) = (rows.lo[i], rows.hi[i], lam[i]);
            let v = sol.violations[k][i];
            let (price, allowed) = match rows.soft[i] {
                Some(p) => (Some(p), v),
                None => (None, 0.0),
            };
            assert!(v >= 0.0 && (price.is_some() || v == 0.0));
            // Within the bounds widened by the violation.
            assert!(
                z[i] <= hi + allowed + feas_tol,
                "stage {k} row {i}: {} > {hi}",
                z[i]
            );
            assert!(
                z[i] >= lo - allowed - feas_tol,
                "stage {k} row {i}: {} < {lo}",
                z[i]
            );
            // A multiplier only on a finite side; complementarity with that side's slack.
            let slack_hi = hi + allowed - z[i];
            let slack_lo = z[i] - lo + allowed;
            let pair_tol = gap + l.abs() * feas_tol;
            if l > 0.0 {
                assert!(hi.is_finite() || l <= stat_tol);
                assert!(
                    !hi.is_finite() || l * slack_hi <= pair_tol,
                    "stage {k} row {i}"
                );
            } else {
                assert!(lo.is_finite() || -l <= stat_tol);
                assert!(
                    !lo.is_finite() || -l * slack_lo <= pair_tol,
                    "stage {k} row {i}: λ {l:e}, slack {slack_lo:e}, v {v:e}, tolerance {pair_tol:e}, {:?}",
                    sol.info
                );
            }
            if let Some(p) = price {
                // ν = l1 + l2 v − |λ| ≥ 0, and ν v ≈ 0.
                let nu = p.l1 + p.l2 * v - l.abs();
                assert!(
                    nu >= -stat_tol,
                    "stage {k} row {i}: |λ| = {} above the price",
                    l.abs()
                );
                assert!(
                    nu * v <= gap + stat_tol * v,
                    "stage {k} row {i}: ν v = {}",
                    nu * v
                );
            }
        }
    }
}

fn sweep<const NX: usize, const NU: usize, const NC: usize>(n: usize, seeds: u64, soft: f64) {
    let (mut iters, mut worst_f, mut worst_u) = (Vec::new(), 0.0f64, 0.0f64);
    for seed in 0..seeds {
        let qp = random::stage_qp::<NX, NU, NC>(1000 * n as u64 + seed, n, soft);
        let (it, f, u) = compare(&qp);
        iters.push(it);
        worst_f = worst_f.max(f);
        worst_u = worst_u.max(u);
    }
    iters.sort();
    println!(
        "NX {NX} NU {NU} NC {NC} N {n}: iterations median {} max {}; worst objective and \
         input differences {worst_f:.1e}, {worst_u:.1e} of their tolerances",
        iters[iters.len() / 2],
        iters[iters.len() - 1]
    );
}

#[test]
fn tiny_stages_equal_clarabel() {
    sweep::<2, 1, 2>(5, 30, 0.3);
}

#[test]
fn medium_stages_equal_clarabel() {
    sweep::<4, 2, 3>(12, 30, 0.3);
}

#[test]
fn mpc_sized_stages_equal_clarabel() {
    sweep::<10, 2, 5>(10, 20, 0.5);
}

#[test]
fn long_horizons_equal_clarabel() {
    sweep::<6, 3, 6>(40, 8, 0.3);
}

#[test]
fn hard_rows_only_equal_clarabel() {
    sweep::<4, 2, 4>(15, 20, 0.0);
}

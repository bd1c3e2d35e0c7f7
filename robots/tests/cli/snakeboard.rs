//! `snakeboard plan` and `snakeboard simulate`: the built-in problems solve from the
//! default start with every constraint held on the written trajectory.csv (re-measured
//! from the file), and the simulator's coasting circle and refusals.

use crate::common::{read_json, rows, scratch, snakeboard};

#[test]
fn snakeboard_plans_the_built_in_problems() {
    for (problem, end) in [
        ("forward", [1.0, 0.0, 0.0]),
        ("sideways", [0.0, 0.3, 0.0]),
        ("turn", [0.6, 0.6, std::f64::consts::FRAC_PI_2]),
    ] {
        let dir = scratch(&format!("snakeboard-{problem}"));
        let out = snakeboard()
            .args(["plan", problem, "--quiet", "--out"])
            .arg(&dir)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "snakeboard plan {problem}: {stderr}");
        let summary = read_json(dir.join("summary.json"));
        assert_eq!(summary["status"], "solved");
        assert_eq!(summary["integrator"], "midpoint");
        assert_eq!(summary["start"], "excited");
        assert!(
            summary["max_violation"].as_f64().unwrap() <= 1e-9,
            "{summary}"
        );
        // Columns t,x,y,theta,psi,phi,v_psi,v_phi,p,J,tau_psi,tau_phi; the bounds of
        // docs/snakeboard.md to the solver's constraint tolerance.
        let r = rows(&std::fs::read_to_string(dir.join("trajectory.csv")).unwrap());
        let tol = 1e-9;
        for row in &r[..r.len() - 1] {
            assert!(row[5].abs() <= 1.0 + tol, "axle angle {row:?}");
            assert!(row[6].abs() <= 10.0 + tol, "rotor rate {row:?}");
            assert!(row[10].abs() <= 0.1 + tol, "rotor torque {row:?}");
            assert!(row[11].abs() <= 0.05 + tol, "axle torque {row:?}");
        }
        let last = r.last().unwrap();
        for i in 0..3 {
            assert!((last[1 + i] - end[i]).abs() < 1e-9, "end pose {last:?}");
        }
        assert!(
            last[6..10].iter().all(|v| v.abs() < 1e-9),
            "at rest: {last:?}"
        );
        // It got there by the momentum equation alone: the board moved while J changed.
        let j_max = r.iter().map(|row| row[9].abs()).fold(0.0, f64::max);
        assert!(
            j_max > 0.01,
            "{problem}: the momentum never built up ({j_max:.2e})"
        );
        for svg in ["path.svg", "shape.svg", "torques.svg"] {
            assert!(std::fs::read_to_string(dir.join(svg))
                .unwrap()
                .starts_with("<svg"));
        }
    }
}

/// From the all-zero start the solver stops infeasible: along a motion with the rotor and
/// the axles at rest the momentum equation's linearisation sees neither (docs/snakeboard.md).
#[test]
fn the_zero_start_cannot_leave_rest() {
    let dir = scratch("snakeboard-zero");
    let out = snakeboard()
        .args(["plan", "forward", "--start", "zero", "--quiet", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let summary = read_json(dir.join("summary.json"));
    assert_eq!(summary["status"], "infeasible", "{summary}");
}

/// Axles at 0.4 rad, no torque: the board coasts on the circle of radius l / tan φ about
/// (0, l / tan φ) (l = 0.2 m), every row of trajectory.csv on it.
#[test]
fn snakeboard_simulate_coasts_on_a_circle() {
    let dir = scratch("snakeboard-simulate");
    std::fs::write(dir.join("in.csv"), "t,tau_psi,tau_phi\n0,0,0\n5,0,0\n").unwrap();
    let out = snakeboard()
        .args(["simulate", "--x0", "0,0,0,0,0.4,0,0,0.3", "--inputs"])
        .arg(dir.join("in.csv"))
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r = rows(&std::fs::read_to_string(dir.join("trajectory.csv")).unwrap());
    assert_eq!(r.len(), 501);
    let radius = 0.2 / 0.4f64.tan();
    for row in &r {
        let off = (row[1].hypot(row[2] - radius) - radius).abs();
        assert!(off < 1e-12, "off the circle by {off:.2e}: {row:?}");
    }
    // The board went round (5 s at 0.3 m/s is 1.5 m of a 2.97 m circle).
    assert!(
        r.last().unwrap()[3] > 2.5,
        "heading {}",
        r.last().unwrap()[3]
    );
}

#[test]
fn snakeboard_refuses_what_it_cannot_run() {
    let dir = scratch("snakeboard-refuse");
    std::fs::write(dir.join("in.csv"), "t,tau_psi,tau_phi\n0,0,0\n1,0,0\n").unwrap();
    let out = snakeboard()
        .args(["simulate", "--x0", "0,0,0,0,1.6,0,0,0.3", "--inputs"])
        .arg(dir.join("in.csv"))
        .arg("--out")
        .arg(dir.join("o"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("axle angle 1.6 rad"), "{stderr}");
    let out = snakeboard()
        .args(["plan", "backflip", "--quiet"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("built-in problems: forward, sideways, turn"),
        "{stderr}"
    );
    let out = snakeboard()
        .args(["plan", "forward", "--step", "0.03", "--quiet"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("whole number of steps"));
}

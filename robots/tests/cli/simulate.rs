//! `wip simulate` through the real binary: a closed-form steady state, and clear failures.

use crate::common::{fails_with_one_line, scratch, wip};

fn last_row(csv: &str) -> Vec<f64> {
    csv.lines()
        .last()
        .unwrap()
        .split(',')
        .map(|f| f.parse().unwrap())
        .collect()
}

/// With g = 0 the body cannot fall, but it is not held either: the pitch angular momentum
/// about the contact line, H = p_α + r p_d, has no external torque and stays 0 from rest,
/// so the body counter-rotates while the wheels drive. With l ≠ 0 that rotation modulates
/// the speed through cos α and there is no steady state; with l = 0 as well (centre of mass
/// on the axle) there is one, in closed form:
///   u = R i + k n ω,   k n i = d_v ω + d_c tanh(d_0 ω)   (ω = φ̇ − α̇: motor/friction balance)
///   H = 0:  α̇ (M_αα + 2 M_αφ) + φ̇ (2 M_αφ + r² m_t + 2 M_φφ) = 0,   v_d = r φ̇.
#[test]
fn steady_state_matches_closed_form() {
    let dir = scratch("steady");
    std::fs::write(dir.join("in.csv"), "t,uR,uL\n0,3,3\n20,3,3\n").unwrap();
    std::fs::write(dir.join("p.json"), r#"{"g": 0.0, "l": 0.0}"#).unwrap();
    for integ in ["varint", "rk4"] {
        let h = if integ == "rk4" { "0.0002" } else { "0.005" };
        let out = wip()
            .args(["simulate", "--x0", "0,0,0,0,0,0,0,0,0", "--inputs"])
            .arg(dir.join("in.csv"))
            .args(["--params"])
            .arg(dir.join("p.json"))
            .args(["--integrator", integ, "--h", h, "--out"])
            .arg(dir.join(integ))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let csv = std::fs::read_to_string(dir.join(integ).join("trajectory.csv")).unwrap();
        let row = last_row(&csv);

        let p = robots::wip::WipParams {
            g: 0.0,
            l: 0.0,
            ..Default::default()
        };
        let ken = p.k_e * p.n_wm;
        let u = 3.0;
        // Newton on  k n (u − k n ω)/R − d_v ω − d_c tanh(d_0 ω) = 0.
        let mut w = 1.0;
        for _ in 0..50 {
            let th = (p.d_0 * w).tanh();
            let f = ken * (u - ken * w) / p.R_m - p.d_v * w - p.d_c * th;
            let df = -ken * ken / p.R_m - p.d_v - p.d_c * p.d_0 * (1.0 - th * th);
            w -= f / df;
        }
        let i = (u - ken * w) / p.R_m;
        let (nm, ng) = (p.n_wm, p.n_wg);
        let m_aphi = p.I_m * (1.0 - nm) * nm - p.I_g * (1.0 + ng) * ng;
        let m_phiphi = p.I_wyy + p.I_m * nm * nm + p.I_g * ng * ng;
        let m_aa = p.I_byy + 2.0 * (p.I_m * (1.0 - nm).powi(2) + p.I_g * (1.0 + ng).powi(2));
        let mt = p.m_b + 2.0 * p.m_w;
        let c = (2.0 * m_aphi + p.r * p.r * mt + 2.0 * m_phiphi) / (m_aa + 2.0 * m_aphi);
        let phid = w / (1.0 + c);
        let (v_d, v_alpha) = (p.r * phid, -c * phid);
        println!(
            "{integ}: v_d {:.9} vs {v_d:.9}, v_alpha {:.9} vs {v_alpha:.9}, iR {:.9} vs {i:.9}",
            row[6], row[5], row[8]
        );
        for (got, want) in [(row[6], v_d), (row[5], v_alpha), (row[8], i), (row[9], i)] {
            approx::assert_relative_eq!(got, want, max_relative = 1e-6);
        }
    }
}

#[test]
fn bad_inputs_exit_1_with_one_line() {
    let dir = scratch("bad");
    std::fs::write(dir.join("ok.csv"), "t,uR,uL\n0,1,1\n1,1,1\n").unwrap();
    std::fs::write(dir.join("text.csv"), "t,uR,uL\n0,1,1\n0.5,abc,1\n").unwrap();
    std::fs::write(dir.join("nocol.csv"), "t,uR\n0,1\n").unwrap();
    std::fs::write(dir.join("order.csv"), "t,uR,uL\n0,1,1\n0.5,1,1\n0.4,1,1\n").unwrap();
    std::fs::write(dir.join("empty.csv"), "").unwrap();
    std::fs::write(dir.join("unknown.json"), r#"{"m_b": 0.3, "mass": 1}"#).unwrap();
    std::fs::write(dir.join("broken.json"), r#"{"m_b": "heavy"}"#).unwrap();
    let x0 = "0,0,0,0,0,0,0,0,0";
    fails_with_one_line(
        &["simulate", "--x0", "0,0,0", "--inputs", "ok.csv"],
        &dir,
        "9 comma-separated",
    );
    fails_with_one_line(
        &[
            "simulate",
            "--x0",
            "0,0,0,0,0,x,0,0,0",
            "--inputs",
            "ok.csv",
        ],
        &dir,
        "--x0 component 6",
    );
    fails_with_one_line(
        &["simulate", "--x0", x0, "--inputs", "text.csv"],
        &dir,
        "line 3, column 2 ('uR')",
    );
    fails_with_one_line(
        &["simulate", "--x0", x0, "--inputs", "nocol.csv"],
        &dir,
        "missing column 'uL'",
    );
    fails_with_one_line(
        &["simulate", "--x0", x0, "--inputs", "order.csv"],
        &dir,
        "line 4, column 't'",
    );
    fails_with_one_line(
        &["simulate", "--x0", x0, "--inputs", "empty.csv"],
        &dir,
        "empty file",
    );
    fails_with_one_line(
        &["simulate", "--x0", x0, "--inputs", "missing.csv"],
        &dir,
        "cannot read",
    );
    fails_with_one_line(
        &[
            "simulate",
            "--x0",
            x0,
            "--inputs",
            "ok.csv",
            "--params",
            "unknown.json",
        ],
        &dir,
        "unknown parameter 'mass'",
    );
    fails_with_one_line(
        &[
            "simulate",
            "--x0",
            x0,
            "--inputs",
            "ok.csv",
            "--params",
            "broken.json",
        ],
        &dir,
        "m_b",
    );
    // Bad usage is exit 2.
    let out = wip()
        .args(["simulate", "--frobnicate"])
        .current_dir(&dir)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let out = wip().args(["simulate", "--help"]).output().unwrap();
    assert!(out.status.success() && String::from_utf8_lossy(&out.stdout).contains("--x0"));
}

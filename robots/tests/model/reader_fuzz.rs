//! Fuzz-style property tests of every reader of the `wip` and `car` tools and of the
//! closed loop's: random bytes, random CSV rows built from plausible and hostile tokens, and
//! random JSON. A reader may accept or refuse its input; it must never panic, and what it
//! accepts must be finite (and, for the checks after it, what they pass must hold).

use proptest::prelude::*;
use robots::car::plan::{CarBounds, CarPlan};
use robots::car::problems::CarProblem;
use robots::diagnose::Plant;
use robots::io::{parse_csv, parse_input_columns, parse_inputs};
use robots::wip::diagnose::{Channel, WipPlant};
use robots::wip::plan::problems;
use robots::wip::track::monte_carlo::perturbed;
use robots::wip::track::report::{parse_plan, HOLE_RATIO};
use robots::wip::track::simulated_robot::substeps;
use robots::wip::{ReducedState, WipParams};

/// Cases per property: enough to hit every token pool many times, small enough for CI.
const CASES: u32 = 1024;

fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        (-1e3f64..1e3).prop_map(|v| v.to_string()),
        (0u32..2000).prop_map(|k| format!("{}", k as f64 * 0.01)),
        Just(String::new()),
        Just("nan".to_string()),
        Just("NaN".to_string()),
        Just("inf".to_string()),
        Just("1e300".to_string()),
        Just("-1e308".to_string()),
        Just("1e999".to_string()),
        Just("\"1.5\"".to_string()),
        Just("\"".to_string()),
        Just("abc".to_string()),
        Just("#".to_string()),
        Just(" ".to_string()),
        Just("\u{feff}".to_string()),
    ]
}

fn column() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("t"),
        Just("uR"),
        Just("uL"),
        Just("x"),
        Just("y"),
        Just("theta"),
        Just("alpha"),
        Just("v_alpha"),
        Just("phiR_rel"),
        Just("phiL_rel"),
        Just("iR"),
        Just("iL"),
        Just("tau_s"),
        Just("u_d"),
        Just("extra"),
        Just(""),
    ]
    .prop_map(String::from)
}

/// CSV text: a header of 0–8 column names, then 0–40 rows of 0–9 tokens, with `#`
/// comments, blank lines and CRLF ends sprinkled in.
fn csv_text() -> impl Strategy<Value = String> {
    (
        proptest::collection::vec(column(), 0..8),
        proptest::collection::vec(proptest::collection::vec(token(), 0..9), 0..40),
        any::<bool>(),
        any::<bool>(),
    )
        .prop_map(|(header, rows, crlf, comment)| {
            let end = if crlf { "\r\n" } else { "\n" };
            let mut s = String::new();
            if comment {
                s += "# key: value";
                s += end;
            }
            s += &header.join(",");
            s += end;
            for r in rows {
                s += &r.join(",");
                s += end;
            }
            s
        })
}

/// A well-formed measured log with hostile values in it: a uniform grid, then random
/// channel values (some huge, missing or constant).
fn log_text() -> impl Strategy<Value = String> {
    (
        proptest::collection::vec(token(), 20..80),
        proptest::collection::vec(-2.0f64..2.0, 20..80),
    )
        .prop_map(|(tokens, values)| {
            let mut s = String::from("t,uR,uL,alpha,v_alpha\n");
            for (k, (tok, v)) in tokens.iter().zip(&values).enumerate() {
                s += &format!("{},{v},{v},{tok},{}\n", k as f64 * 0.01, v * 0.5);
            }
            s
        })
}

fn json_value() -> impl Strategy<Value = serde_json::Value> {
    let leaf = prop_oneof![
        Just(serde_json::Value::Null),
        any::<bool>().prop_map(serde_json::Value::from),
        (-1e6f64..1e6).prop_map(serde_json::Value::from),
        Just(serde_json::Value::from(0.0)),
        Just(serde_json::Value::from(-1.0)),
        Just(serde_json::Value::from(1e308)),
        "[a-z_]{0,6}".prop_map(serde_json::Value::from),
    ];
    leaf.prop_recursive(3, 24, 6, |inner| {
        prop_oneof![
            proptest::collection::vec(inner.clone(), 0..5).prop_map(serde_json::Value::from),
            proptest::collection::vec((key(), inner), 0..6)
                .prop_map(|kv| serde_json::Value::Object(kv.into_iter().collect())),
        ]
    })
}

/// Keys of the parameter and waypoint files, and strangers.
fn key() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("R_m"),
        Just("m_b"),
        Just("L_m"),
        Just("l"),
        Just("d_c"),
        Just("points"),
        Just("duration"),
        Just("accel"),
        Just("start_heading"),
        Just("end_heading"),
        Just("name"),
        Just("mass"),
        Just("start"),
        Just("end"),
        Just("waypoints"),
        Just("reverse"),
    ]
    .prop_map(String::from)
}

/// A `trajectory.csv` with the twelve columns and hostile rows: times from a grid with
/// gaps and repeats, values from the token pool.
fn plan_text() -> impl Strategy<Value = String> {
    (
        proptest::collection::vec(
            (
                0u32..60,
                proptest::collection::vec(
                    prop_oneof![
                        30 => (-1e3f64..1e3).prop_map(|v| v.to_string()),
                        1 => token(),
                    ],
                    11,
                ),
            ),
            0..40,
        ),
        any::<bool>(),
    )
        .prop_map(|(rows, from_zero)| {
            let mut s = String::from("t,x,y,theta,alpha,v_alpha,v_d,v_theta,iR,iL,uR,uL\n");
            let mut k = if from_zero { 0 } else { 1 };
            for (gap, vals) in rows {
                // Mostly one step of 20 ms, sometimes a hole or a repeat.
                k += match gap {
                    0 => 0,
                    1..=3 => 30,
                    _ => 1,
                };
                s += &format!("{}", k as f64 * 0.02);
                for v in vals {
                    s += ",";
                    s += &v;
                }
                s.push('\n');
            }
            s
        })
}

/// A car's inputs file: `t` on and off a 5-ms grid, hostile values.
fn car_inputs_text() -> impl Strategy<Value = String> {
    proptest::collection::vec((0u32..400, token(), token()), 1..30).prop_map(|rows| {
        let mut s = String::from("t,tau_s,u_d\n0,0,0\n");
        let mut t = 0u32;
        for (dt, a, b) in rows {
            t += dt + 1;
            s += &format!("{},{a},{b}\n", t as f64 * 0.001);
        }
        s
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: CASES, ..ProptestConfig::default() })]

    #[test]
    fn csv_readers_never_panic_on_random_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let text = String::from_utf8_lossy(&bytes);
        let _ = parse_csv(&text, "fuzz", true);
        let _ = parse_inputs(&text, "fuzz");
        let _ = WipPlant::new(WipParams::default()).parse_log(&text, "fuzz");
    }

    #[test]
    fn csv_readers_never_panic_on_random_rows(text in csv_text()) {
        if let Ok(csv) = parse_csv(&text, "fuzz", false) {
            prop_assert!(csv.rows.iter().flatten().all(|v| v.is_finite()));
        }
        if let Ok(s) = parse_inputs(&text, "fuzz") {
            prop_assert!(s.t.windows(2).all(|w| w[1] > w[0]));
            prop_assert!(s.u.iter().flatten().all(|v| v.is_finite()));
        }
        if let Ok(log) = WipPlant::new(WipParams::default()).parse_log(&text, "fuzz") {
            prop_assert!(log.h.is_finite() && log.h > 0.0);
        }
    }

    #[test]
    fn the_log_reader_sets_aside_what_it_cannot_fit(text in log_text()) {
        let plant = WipPlant::new(WipParams::default());
        if let Ok(mut log) = plant.parse_log(&text, "fuzz") {
            // What diagnose keeps lies within each channel's physical range.
            if log.drop_out_of_range(plant.channels(), plant.inputs()).is_ok() {
                for k in 0..log.len() {
                    let row = log.row(k);
                    for c in Channel::ALL {
                        let v = row[c.index()];
                        prop_assert!(v.is_nan() || v.abs() <= c.range(), "{row:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn json_readers_never_panic(v in json_value(), bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        let text = v.to_string();
        for t in [text.as_str(), &String::from_utf8_lossy(&bytes)] {
            if let Ok(p) = WipParams::from_json_str(t) {
                prop_assert!(p.validate().is_ok());
            }
            if let Ok(problem) = problems::from_json_str(t, 0.02) {
                prop_assert!(problem.n > 0 && problem.h == 0.02);
                // Every waypoint at a stage of the horizon (a huge `accel` put one past it).
                prop_assert!(problem.stages.iter().all(|&k| k <= problem.n));
            }
        }
    }

    #[test]
    fn the_car_readers_never_panic(v in json_value(), text in car_inputs_text(), bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        for t in [v.to_string(), String::from_utf8_lossy(&bytes).into_owned()] {
            if let Ok(problem) = CarProblem::from_json_str(&t) {
                prop_assert!(problem.duration > 0.0 && problem.duration.is_finite());
                prop_assert!(problem.poses().iter().flatten().all(|x| x.is_finite()));
                // The plan's checks refuse or accept; they never panic.
                let _ = CarPlan::new(&problem, CarBounds::default(), 0.02);
            }
        }
        for t in [text.as_str(), &String::from_utf8_lossy(&bytes)] {
            if let Ok(s) = parse_input_columns(t, "fuzz", ["tau_s", "u_d"]) {
                prop_assert!(s.u.iter().flatten().all(|x| x.is_finite()));
                let _ = s.check_limits("fuzz", [("tau_s", 1.0, "N m", "--max-torque"), ("u_d", 24.0, "V", "--max-voltage")]);
                if let Ok(n) = s.steps_on_grid(0.005, "fuzz", "--step") {
                    prop_assert!(n >= 1 && (n as f64 * 0.005 - s.end()).abs() < 1e-9);
                    for &tj in &s.t {
                        let m = tj / 0.005;
                        prop_assert!((m - m.round()).abs() <= 1e-6 * m.max(1.0), "row at {tj}");
                    }
                }
            }
        }
    }

    #[test]
    fn the_closed_loops_plan_reader_never_panics(text in plan_text(), bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
        for t in [text.as_str(), &String::from_utf8_lossy(&bytes)] {
            if let Ok(plan) = parse_plan(t, "fuzz", 30, "") {
                prop_assert!(plan.t.len() >= 2 && plan.t.len() <= 30 && plan.t[0] == 0.0);
                prop_assert!(plan.t.windows(2).all(|w| w[1] > w[0]));
                let mut steps: Vec<f64> = plan.t.windows(2).map(|w| w[1] - w[0]).collect();
                steps.sort_by(f64::total_cmp);
                let median = steps[steps.len() / 2];
                prop_assert!(steps.iter().all(|&s| s <= HOLE_RATIO * median));
                prop_assert!(plan.x.iter().flatten().chain(plan.u.iter().flatten()).all(|v| v.is_finite()));
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// The closed loop's plants: every Monte Carlo draw below a relative error of 1 is a
    /// valid parameter set, and its substeps are chosen or refused, never a panic; the
    /// substeps chosen keep at least the default 10.
    #[test]
    fn monte_carlo_plants_are_valid_and_checked(rel in 0.0f64..0.99, seed in 1u64..10_000, tilt in -0.5f64..0.5) {
        let p = perturbed(&WipParams::default(), rel, seed);
        prop_assert!(p.validate().is_ok(), "{p:?}");
        let mut x = ReducedState::zeros();
        x[3] = tilt;
        if let Ok(n) = substeps(&p, &x, 0.005) {
            prop_assert!(n >= 10);
        }
    }
}

//! Fuzz-style property tests of every reader of the `wip` tool: random bytes, random CSV
//! rows built from plausible and hostile tokens, and random JSON. A reader may accept or
//! refuse its input; it must never panic, and what it accepts must be finite.

use proptest::prelude::*;
use robots::diagnose::Plant;
use robots::io::{parse_csv, parse_inputs};
use robots::wip::benchmarks;
use robots::wip::diagnose::{Channel, WipPlant};
use robots::wip::WipParams;

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
    ]
    .prop_map(String::from)
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
            if let Ok(problem) = benchmarks::from_json_str(t, 0.02) {
                prop_assert!(problem.n > 0 && problem.h == 0.02);
            }
        }
    }
}

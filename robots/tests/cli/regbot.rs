//! `wip diagnose` on the two real REGBOT logs of `data/regbot` (docs/diagnose.md, §8b), as
//! a user runs them (`--calibrate --max-effects 3`): the firmware's dead-reckoned pose is
//! set aside, and each log comes within 2.5 × its noise floor with the same causes, each
//! parameter in its physical range and the two logs' estimates within 3 combined σ.

use crate::common::{read_json, scratch, wip};
use serde_json::Value;

/// The named effects' parameters of a diagnosis, with their standard deviations: from the
/// candidate that is the chosen model (its `effect` is the effects joined by `+`).
fn chosen_parameters(d: &Value) -> Vec<(String, f64, f64)> {
    let name = d["effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e.as_str().unwrap())
        .collect::<Vec<_>>()
        .join("+");
    let c = d["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["effect"] == name.as_str())
        .unwrap_or_else(|| panic!("no candidate {name}"));
    assert_eq!(c["plausible"], true, "{c}");
    c["parameters"]
        .as_object()
        .unwrap()
        .iter()
        .map(|(k, v)| {
            let std = c["uncertainty"][k].as_f64().unwrap();
            (k.clone(), v.as_f64().unwrap(), std)
        })
        .collect()
}

#[test]
fn both_regbot_logs_name_the_same_physical_causes() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/regbot");
    let dir = scratch("regbot");
    // The two logs side by side, one thread each.
    let runs: Vec<_> = ["regbot_01", "regbot_02"]
        .iter()
        .map(|log| {
            wip()
                .args(["diagnose", "--quiet", "--calibrate", "--max-effects", "3"])
                .args(["--threads", "1", "--params"])
                .arg(data.join("regbot_params.json"))
                .arg(data.join(format!("{log}.csv")))
                .arg("--out")
                .arg(dir.join(log))
                .spawn()
                .unwrap()
        })
        .collect();
    let mut found = Vec::new();
    for (mut run, log) in runs.into_iter().zip(["regbot_01", "regbot_02"]) {
        assert!(run.wait().unwrap().success(), "{log}");
        let d = read_json(dir.join(log).join("diagnosis.json"));
        // x, y and theta are the firmware's odometry of the two encoders.
        let flagged = d["flagged_readings"].to_string();
        for c in ["x", "y", "theta"] {
            assert!(
                flagged.contains(&format!("column '{c}' is the dead reckoning")),
                "{log}: {flagged}"
            );
        }
        let after = d["error_after"].as_f64().unwrap();
        assert!(after <= 2.5, "{log}: E after {after}");
        assert!(
            !d["effects"].as_array().unwrap().is_empty(),
            "{log}: {}",
            d["effects"]
        );
        found.push((d["effects"].clone(), chosen_parameters(&d)));
    }
    let ((e1, p1), (e2, p2)) = (&found[0], &found[1]);
    assert_eq!(e1, e2, "the two logs name different causes");
    for ((name, a, sa), (_, b, sb)) in p1.iter().zip(p2) {
        let combined = (sa * sa + sb * sb).sqrt();
        assert!(
            (a - b).abs() <= 3.0 * combined,
            "{name}: {a} ± {sa} against {b} ± {sb}"
        );
    }
}

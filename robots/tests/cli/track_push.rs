//! `wip track --push-at T --push W`: the push changes the plant's tilt rate by exactly `W`
//! at the sample of `T` and nothing before it, the LQ loop recovers from a small one, and
//! a push outside the plan fails with one line.

use crate::common::{fails_with_one_line, read_json, scratch, succeeds, wip};
use robots::wip::simulate::Trajectory;
use robots::wip::track::closed_loop::{track, Push, TrackConfig, TrackRun};
use robots::wip::track::lq::{LqController, SAMPLE};
use robots::wip::track::observer::SensorModel;
use robots::wip::track::report::read_plan;
use robots::wip::WipParams;
use std::path::PathBuf;

fn hook_plan() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/track_hook_h20.csv")
}

fn run(plan: &Trajectory, lq: &LqController, push: Option<Push>) -> TrackRun {
    let p = WipParams::default();
    let cfg = TrackConfig {
        plant: p,
        nominal: p,
        sensors: SensorModel::ideal(),
        seed: 1,
        push,
    };
    track(plan, lq, &cfg, |_| {}).unwrap()
}

/// With ideal sensors the run is deterministic: the samples before the push equal the
/// unpushed run's to the bit, the push's sample has the tilt rate larger by `W` (the same
/// state plus `W`: one rounding of the sum), every other state entry equal; the LQ loop
/// brings the tilt back, so that at the plan's end the two runs' tilts differ by less than
/// a hundredth of the push's first effect.
#[test]
fn a_push_changes_the_tilt_rate_at_its_sample_alone() {
    let plan = read_plan(&hook_plan(), 1_000_000, "").unwrap();
    let lq = LqController::design(&WipParams::default()).unwrap();
    let (at_s, w) = (2.0, 0.5);
    let calm = run(&plan, &lq, None);
    let pushed = run(&plan, &lq, Some(Push { at_s, tilt_rate: w }));
    assert_eq!(pushed.outcome(), "completed");
    let k = (at_s / SAMPLE).round() as usize;
    for (a, b) in calm.samples[..k].iter().zip(&pushed.samples[..k]) {
        assert_eq!(a.x, b.x, "before the push, t = {}", a.t);
        assert_eq!(a.u, b.u, "before the push, t = {}", a.t);
    }
    let (a, b) = (&calm.samples[k].x, &pushed.samples[k].x);
    let rounding = 4.0 * f64::EPSILON * (a[4].abs() + w);
    assert!(
        ((b[4] - a[4]) - w).abs() <= rounding,
        "{} vs {}",
        b[4],
        a[4]
    );
    for i in (0..9).filter(|&i| i != 4) {
        assert_eq!(a[i], b[i], "state {i} at the push");
    }
    // The push's first effect on the tilt: its largest deviation over the next 0.2 s.
    let deviation = |s: usize| (pushed.samples[s].x[3] - calm.samples[s].x[3]).abs();
    let first = (k..k + 40).map(deviation).fold(0.0, f64::max);
    let last = deviation(pushed.samples.len() - 1);
    assert!(
        first > 0.0 && last < 0.01 * first,
        "first {first}, last {last}"
    );
    assert_eq!(pushed.figures().push, Some(Push { at_s, tilt_rate: w }));
    assert_eq!(calm.figures().push, None);
}

#[test]
fn the_push_is_in_tracking_json_and_a_bad_one_fails_with_one_line() {
    let dir = scratch("track-push");
    let out_dir = dir.join("pushed");
    succeeds(
        wip()
            .arg("track")
            .arg(hook_plan())
            .args(["--push-at", "1.5", "--push", "-0.4", "--out"])
            .arg(&out_dir),
    );
    let j = read_json(out_dir.join("tracking.json"));
    assert_eq!(j["push"]["at_s"], 1.5, "{j}");
    assert_eq!(j["push"]["tilt_rate"], -0.4, "{j}");
    assert_eq!(j["outcome"], "completed", "{j}");
    let plan = hook_plan();
    let plan = plan.to_str().unwrap();
    fails_with_one_line(
        &["track", plan, "--push-at", "9", "--push", "0.5"],
        &dir,
        "within the plan's 0–7 s",
    );
    // A push without its time is a usage error (clap's, exit 2).
    let out = wip()
        .args(["track", plan, "--push", "0.5"])
        .current_dir(&dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("--push-at"), "{err}");
}

//! The generic reading hypotheses (`robots::diagnose::readings`, docs/diagnose.md §2a) name
//! what no catalogue entry of the WIP lists, by what and where: generated closed-loop logs
//! (the controller sees the corrupted readings) with
//!
//! - a constant gyro offset of 0.03 rad/s, 1.5 × the rate noise (issue 60: such a log was
//!   diagnosed `tilt_filter` with `accel_weight` 0.58 at E 1.01 → 1.01, an effect that
//!   explains nothing), and
//! - a right-encoder scale of 1.03 (counts per revolution 3 % off),
//!
//! must be named `reading_offset:v_alpha` and `reading_scale:phiR_rel`, each parameter
//! within 3 reported standard deviations of the truth, the error within 1.2 × the noise
//! floor (the checks of the recovery matrix, `recovery::failures_of`). The null log's
//! `none` is the recovery matrix's.

use super::recovery::{failures_of, label, master_seed, run_all, Case};
use robots::diagnose::ReadingFamily;
use robots::wip::diagnose::effects::Effect;
use robots::wip::diagnose::generate::Rng;
use robots::wip::diagnose::Channel;
use robots::wip::WipParams;

#[test]
fn a_gyro_offset_and_an_encoder_scale_are_named_at_their_readings() {
    let p = WipParams::default();
    let mut rng = Rng::new(master_seed() ^ 0x7ead);
    let cases: Vec<Case> = vec![
        (
            vec![(
                Effect::Reading(ReadingFamily::Offset, Channel::VAlpha),
                vec![0.03],
            )],
            rng.next_u64(),
        ),
        (
            vec![(
                Effect::Reading(ReadingFamily::Scale, Channel::PhiRRel),
                vec![1.03],
            )],
            rng.next_u64(),
        ),
    ];
    let outcomes = run_all(&p, cases);
    let mut failures = Vec::new();
    for o in &outcomes {
        println!("{:<24} {}  ({:.1} s)", label(o.truth), o.line, o.elapsed);
        failures.extend(failures_of(o));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

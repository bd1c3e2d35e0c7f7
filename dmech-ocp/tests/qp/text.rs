//! The text form reads back to the same QP, bit for bit.

use super::random;
use dmech_ocp::qp::{QpTextError, StageQp};

#[test]
fn text_reads_back_bit_for_bit() {
    let (a, b) = (
        random::stage_qp::<4, 2, 3>(3, 6, 0.5),
        random::stage_qp::<4, 2, 3>(4, 9, 0.5),
    );
    let text = a.to_text() + &b.to_text();
    let read = StageQp::<4, 2, 3>::all_from_text(&text).unwrap();
    assert_eq!(read.len(), 2);
    for (r, o) in read.iter().zip([&a, &b]) {
        assert_eq!(r.x0(), o.x0());
        assert_eq!(r.stages(), o.stages());
        assert_eq!(r.terminal(), o.terminal());
    }
    let e = StageQp::<4, 2, 2>::all_from_text(&text).unwrap_err();
    assert_eq!(
        e,
        QpTextError::Sizes {
            expected: (4, 2, 2),
            found: (4, 2, 3)
        }
    );
}

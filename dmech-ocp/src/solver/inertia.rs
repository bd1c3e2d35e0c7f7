//! Inertia correction: when some stage's reduced Hessian `H_uu` is not positive definite,
//! the KKT matrix has the wrong inertia, and the step is computed again with a primal
//! shift `δ_w I` on every stage. The schedule is IPOPT's (Wächter & Biegler 2006, §3.1,
//! Algorithm IC), with its constants under their names there.

/// `δ̄_w⁰`: the first shift tried when no earlier iteration needed one.
const DELTA_W_0: f64 = 1e-4;
/// `δ̄_w^min`, `δ̄_w^max`: the smallest shift kept; above the largest the correction fails.
const DELTA_W_MIN: f64 = 1e-20;
const DELTA_W_MAX: f64 = 1e40;
/// `κ_w⁻`: the first trial is the last successful shift divided by this.
const KAPPA_W_MINUS_INV: f64 = 3.0;
/// `κ̄_w⁺`, `κ_w⁺`: the growth of the shift between trials, without and with a shift
/// remembered from an earlier iteration.
const KAPPA_W_PLUS_BAR: f64 = 100.0;
const KAPPA_W_PLUS: f64 = 8.0;

/// The shift schedule, remembering the last shift that worked.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct InertiaCorrection {
    /// The last successful nonzero shift (0: none yet).
    pub(super) last: f64,
}

impl InertiaCorrection {
    /// The shift to try after a factorisation with shift `delta` failed, `None` when the
    /// schedule is exhausted.
    pub(super) fn next(&self, delta: f64) -> Option<f64> {
        let next = if delta == 0.0 {
            if self.last == 0.0 {
                DELTA_W_0
            } else {
                (self.last / KAPPA_W_MINUS_INV).max(DELTA_W_MIN)
            }
        } else if self.last == 0.0 {
            delta * KAPPA_W_PLUS_BAR
        } else {
            delta * KAPPA_W_PLUS
        };
        (next <= DELTA_W_MAX).then_some(next)
    }

    /// Remember the shift a factorisation succeeded with.
    pub(super) fn succeeded(&mut self, delta: f64) {
        if delta > 0.0 {
            self.last = delta;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// From no history: 1e-4, then ×100 per trial up to the cap; with a history δ: δ/3,
    /// then ×8.
    #[test]
    fn the_schedule_is_ipopts() {
        let fresh = InertiaCorrection::default();
        assert_eq!(fresh.next(0.0), Some(1e-4));
        assert_eq!(fresh.next(1e-4), Some(1e-2));
        assert_eq!(fresh.next(1e39), None);
        let mut warm = InertiaCorrection::default();
        warm.succeeded(3.0);
        assert_eq!(warm.next(0.0), Some(1.0));
        assert_eq!(warm.next(1.0), Some(8.0));
        warm.succeeded(0.0);
        assert_eq!(
            warm.last, 3.0,
            "a factorisation without shift keeps the memory"
        );
    }
}

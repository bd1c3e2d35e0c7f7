//! The scan of a parameter whose cost jumps ([`ParamSpec::start_grid`]), coarse to fine.
//!
//! Each grid value is ranked by a fit of every window's state (the dearest step of a
//! diagnosis with a reversal lockout in its catalogue), so a long grid is not ranked in
//! full: every other value first, then the two unranked neighbours of the best of those.
//! The value returned is then a local minimum of the full grid's ranking (both its
//! neighbours are ranked and no lower), and the global minimum wherever the ranking falls
//! and then rises over the grid. What a grid holds is the start of a fit that then refines
//! it (for a sampled time threshold, also across the neighbouring sample intervals): the
//! scan has to land in the right basin, not on its floor.
//!
//! [`ParamSpec::start_grid`]: crate::model::ParamSpec

/// A grid of at most this many values is ranked in full.
const RANKED_IN_FULL: usize = 8;

/// The index of the lowest-ranked value of a grid of `n` values, its rank and what the
/// ranking returned with it, `rank(i)` called on the even indices and then on the odd
/// neighbours of the best of those (every index for a grid of at most
/// [`RANKED_IN_FULL`] values). Non-finite ranks lose. `None` for an empty grid.
pub(crate) fn lowest_on_grid<Z>(
    n: usize,
    mut rank: impl FnMut(usize) -> (f64, Z),
) -> Option<(usize, f64, Z)> {
    let key = |r: f64| if r.is_nan() { f64::INFINITY } else { r };
    let mut best: Option<(usize, f64, Z)> = None;
    let mut consider = |i: usize, best: &mut Option<(usize, f64, Z)>| {
        let (r, z) = rank(i);
        if best.as_ref().is_none_or(|b| key(r) < key(b.1)) {
            *best = Some((i, r, z));
        }
    };
    if n <= RANKED_IN_FULL {
        for i in 0..n {
            consider(i, &mut best);
        }
        return best;
    }
    for i in (0..n).step_by(2) {
        consider(i, &mut best);
    }
    let coarse = best.as_ref().map(|b| b.0)?;
    for i in [coarse.checked_sub(1), Some(coarse + 1)]
        .into_iter()
        .flatten()
    {
        if i < n {
            consider(i, &mut best);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Ranks `values` through [`lowest_on_grid`], counting the calls.
    fn scan(values: &[f64]) -> (usize, usize) {
        let mut calls = 0;
        let (i, r, ()) = lowest_on_grid(values.len(), |i| {
            calls += 1;
            (values[i], ())
        })
        .expect("non-empty grid");
        assert_eq!(r, values[i]);
        (i, calls)
    }

    proptest! {
        /// Wherever the ranking falls and then rises, the scan finds its minimum, at
        /// about half the cost for a long grid.
        #[test]
        fn a_valley_is_found_at_its_floor(
            n in 1usize..40,
            at in 0.0f64..1.0,
            left in 0.01f64..10.0,
            right in 0.01f64..10.0,
        ) {
            let floor = ((n - 1) as f64 * at).round() as usize;
            let values: Vec<f64> = (0..n)
                .map(|i| {
                    let d = i as f64 - floor as f64;
                    if d < 0.0 { -d * left } else { d * right }
                })
                .collect();
            let (i, calls) = scan(&values);
            prop_assert_eq!(i, floor);
            if n > RANKED_IN_FULL {
                prop_assert!(calls <= n.div_ceil(2) + 2);
            }
        }

        /// On any ranking, the value returned is a local minimum of the whole grid.
        #[test]
        fn any_ranking_gives_a_local_minimum(
            values in proptest::collection::vec(-1e3f64..1e3, 1..40),
        ) {
            let (i, _) = scan(&values);
            if i > 0 {
                prop_assert!(values[i] <= values[i - 1]);
            }
            if i + 1 < values.len() {
                prop_assert!(values[i] <= values[i + 1]);
            }
        }
    }

    #[test]
    fn a_failed_ranking_loses_to_a_finite_one() {
        let values = [
            f64::NAN,
            3.0,
            f64::NAN,
            2.0,
            5.0,
            f64::NAN,
            7.0,
            8.0,
            9.0,
            1.5,
        ];
        // The even values: NaN, NaN, 5, NaN, 9 → index 4; its neighbours 2.0 (3) and NaN.
        let (i, _) = scan(&values);
        assert_eq!(i, 3);
        assert_eq!(lowest_on_grid(0, |_| (0.0, ())).map(|b| b.0), None);
    }
}

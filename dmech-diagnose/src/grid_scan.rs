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
//! The scan runs once per parameter and diagnosis, when the effect is screened (its
//! linearisation at the start sees nothing, [`Screened::unseen`]): the lowest rank against
//! the base model's cost on the same windows is the effect's predicted reduction, so an
//! effect the scan finds strong is fitted first and bounds the others. The first fit of
//! the effect starts from the scan's choice and states; later candidates from its choice.
//!
//! [`ParamSpec::start_grid`]: crate::model::ParamSpec
//! [`Screened::unseen`]: crate::fit::Screened::unseen

use super::fit::{Fit, Fitter};
use super::model::Candidate;
use super::session::{Scored, Session, RESTARTS};
use super::Plant;

/// Iterations of the window states alone behind each grid value's cost
/// ([`Session::grid_start`]). One ranks too roughly: with one, and the four lowest
/// decided by two more, the generated lockout of 78 ms was missed (E 17 → 3.3, named
/// voltage_gain + input_delay).
const GRID_STATE_ITERATIONS: usize = 3;
/// At most this many windows, evenly spread, in a scan: it only ranks (the fit from its
/// choice sees every window), and its cost stays that of this many windows however long
/// the log is.
const GRID_MAX_WINDOWS: usize = 30;

/// Intervals a fit may step across per sampled time threshold.
const EDGE_STEPS: usize = 3;

/// The fit that ranks values of a jumping parameter: [`GRID_STATE_ITERATIONS`]
/// iterations of the window states `z` alone at `theta`.
fn ranking_fit<P: Plant>(fitter: &Fitter<'_, P>, theta: &[f64], z: &[Vec<f64>]) -> Fit {
    fitter.fit_capped(
        &Candidate::none(),
        theta,
        z,
        None,
        &|_| {},
        GRID_STATE_ITERATIONS,
    )
}

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

/// What the scan of one parameter chose, for the rest of the diagnosis.
#[derive(Clone, Debug)]
pub(super) struct GridChoice {
    /// The parameter's index in the catalogue.
    pub param: usize,
    /// The grid value of lowest rank (moved by a fit across sample intervals,
    /// [`Session::cross_sampled_edges`]).
    pub value: f64,
    /// The scanned windows' states at `value` (window, states), for the first fit from it.
    states: Vec<(usize, Vec<f64>)>,
    /// No fit has started from this choice yet: the first one takes `states` and tries
    /// the neighbouring sample intervals.
    first_fit_pending: bool,
}

impl<P: Plant> Session<'_, P> {
    /// The predicted reduction of the base model's cost by the single effect `cand`, from
    /// the scan of its parameters that have a grid (`None` when it has none): the base's
    /// cost on the scanned windows less the lowest rank, scaled from the scanned windows to
    /// all. Scans the parameters not yet scanned, from where `cand` would start on `base`.
    pub(super) fn scan_screen(&self, cand: &Candidate, base: &Scored) -> Option<f64> {
        let cat = self.fitter.catalogue();
        let mut theta = cand.start_from(cat, &base.fit.theta);
        let mut lowest = None;
        for p in cand.effect_params(cat) {
            let spec = &cat.params[p];
            if spec.start_grid.is_empty() || theta[p] != spec.start || self.is_scanned(p) {
                continue;
            }
            let (value, rss) = self.scan(p, &theta, &base.fit.z0)?;
            theta[p] = value;
            lowest = Some(rss);
        }
        let lowest = lowest?;
        let pick = self.scan_windows();
        let z_pick: Vec<Vec<f64>> = pick.iter().map(|&w| base.fit.z0[w].clone()).collect();
        let (base_rss, _) = self
            .fitter
            .on_windows(&pick)
            .cost(&base.fit.theta, &z_pick)?;
        let scale = self.fitter.windows.len() as f64 / pick.len().max(1) as f64;
        Some(((base_rss - lowest) * scale).max(0.0))
    }

    /// Whether parameter `p` has been scanned in this diagnosis.
    fn is_scanned(&self, p: usize) -> bool {
        let chosen = self.grid_chosen.lock().expect("not poisoned");
        chosen.iter().any(|c| c.param == p)
    }

    /// Scan parameter `p` from `theta` and the window states `z`, and keep the grid value
    /// of lowest rank ([`lowest_on_grid`]) with its states as the parameter's choice;
    /// returns that value and its rank.
    fn scan(&self, p: usize, theta: &[f64], z: &[Vec<f64>]) -> Option<(f64, f64)> {
        let spec = &self.fitter.catalogue().params[p];
        // A long log is scanned on evenly spread windows: the scan only ranks.
        let pick = self.scan_windows();
        let fitter = self.fitter.on_windows(&pick).with_window_memo();
        let z_pick: Vec<Vec<f64>> = pick.iter().map(|&w| z[w].clone()).collect();
        let mut theta = theta.to_vec();
        let grid = &spec.start_grid;
        let mut ranked = 0;
        let (i, rss, zb) = lowest_on_grid(grid.len(), |i| {
            ranked += 1;
            theta[p] = grid[i];
            let f = ranking_fit(&fitter, &theta, &z_pick);
            (f.rss, f.z0)
        })?;
        let value = grid[i];
        (self.progress)(&format!(
            "  scan {:<24} starts at {value:.4e} ({ranked} of {} values ranked, on {} windows)  ({:.1} s)",
            spec.name,
            grid.len(),
            pick.len(),
            self.t0.elapsed().as_secs_f64()
        ));
        self.grid_chosen
            .lock()
            .expect("not poisoned")
            .push(GridChoice {
                param: p,
                value,
                states: pick.into_iter().zip(zb).collect(),
                first_fit_pending: true,
            });
        Some((value, rss))
    }

    /// `theta0` with each of the candidate's parameters that sits at its start and has a
    /// [`ParamSpec::start_grid`](super::model::ParamSpec) moved to the scan's choice
    /// (scanned now if it was not yet): a Gauss–Newton fit cannot cross the jumps of such
    /// a parameter's cost. The first fit from a choice also takes the scanned windows'
    /// states. Also returns the parameters whose choice this fit is the first from.
    pub(super) fn grid_start(
        &self,
        cand: &Candidate,
        theta0: &[f64],
        z0: &[Vec<f64>],
    ) -> (Vec<f64>, Vec<Vec<f64>>, Vec<usize>) {
        let cat = self.fitter.catalogue();
        let mut theta = theta0.to_vec();
        let mut z = z0.to_vec();
        let mut first = Vec::new();
        for p in cand.effect_params(cat) {
            let spec = &cat.params[p];
            if spec.start_grid.is_empty() || theta[p] != spec.start {
                continue;
            }
            if !self.is_scanned(p) && self.scan(p, &theta, &z).is_none() {
                continue;
            }
            let mut chosen = self.grid_chosen.lock().expect("not poisoned");
            let c = chosen
                .iter_mut()
                .find(|c| c.param == p)
                .expect("scanned above");
            theta[p] = c.value;
            if c.first_fit_pending {
                c.first_fit_pending = false;
                for (w, zw) in c.states.drain(..) {
                    z[w] = zw;
                }
                first.push(p);
            }
        }
        (theta, z, first)
    }

    /// `fit` moved across the jumps of its sampled time thresholds. Such a threshold `T`
    /// anywhere in `((n − 1) h, n h]` makes the same sample-instant decisions: the cost is
    /// continuous inside the interval and jumps at its ends, so a Gauss–Newton fit ends in
    /// whichever interval its steps happen to land in, and a scan coarser than `h` (10 ms
    /// on a 5-ms log) does not start in every interval. The fit whose start was scanned
    /// (`scanned`: once per parameter and diagnosis) therefore tries the two neighbouring
    /// intervals, at their right ends `(n ± 1) h` (where the model reproduces the sampled rule exactly): each is ranked
    /// against the fit's own point by [`GRID_STATE_ITERATIONS`] iterations of the window
    /// states alone from the fit's states (a neighbouring interval's decisions differ at a
    /// few rows only); the lower-ranked one, if it ranks below the fit's point, is fitted in
    /// full and kept if its cost is lower, and later candidates start from it. Up to
    /// [`EDGE_STEPS`] steps per parameter.
    pub(super) fn cross_sampled_edges(
        &self,
        cand: &Candidate,
        mut f: Fit,
        scanned: &[usize],
        bound: Option<f64>,
        best: Option<f64>,
    ) -> Fit {
        let cat = self.fitter.catalogue();
        let h = self.fitter.log.h;
        let pick = self.scan_windows();
        // The neighbouring intervals' decisions differ at a few rows: most windows are
        // ranked once for the three values.
        let fitter = self.fitter.on_windows(&pick).with_window_memo();
        let states_rss = |theta: &[f64], z: &[Vec<f64>]| {
            let z_pick: Vec<Vec<f64>> = pick.iter().map(|&w| z[w].clone()).collect();
            ranking_fit(&fitter, theta, &z_pick).rss
        };
        for &p in scanned {
            let spec = &cat.params[p];
            if !spec.sampled_time || h <= 0.0 {
                continue;
            }
            // Also after an abandoned fit: one stuck in the wrong interval is abandoned.
            for _ in 0..EDGE_STEPS {
                // `T` in `((n − 1) h, n h]`.
                let n = (f.theta[p] / h - 1e-9).ceil();
                let here = states_rss(&f.theta, &f.z0);
                let ranked = [n - 1.0, n + 1.0]
                    .into_iter()
                    .map(|m| m * h)
                    .filter(|&t| t > 0.0 && t >= spec.bounds.0 && t <= spec.bounds.1)
                    .map(|t| {
                        let mut theta = f.theta.clone();
                        theta[p] = t;
                        (states_rss(&theta, &f.z0), theta)
                    })
                    .min_by(|a, b| a.0.total_cmp(&b.0));
                let Some((rss, theta)) = ranked else { break };
                if rss >= here {
                    break;
                }
                let g = self.fit_leading(cand, &theta, &f.z0, bound, best, RESTARTS);
                if g.rss >= f.rss {
                    break;
                }
                let iterations = f.iterations + g.iterations;
                f = Fit { iterations, ..g };
                // Later candidates start in the interval found here, not the scan's.
                let mut chosen = self.grid_chosen.lock().expect("not poisoned");
                if let Some(c) = chosen.iter_mut().find(|c| c.param == p) {
                    c.value = theta[p];
                }
            }
        }
        f
    }

    /// The windows a scan ranks on: all, or [`GRID_MAX_WINDOWS`] evenly spread ones.
    fn scan_windows(&self) -> Vec<usize> {
        let n = self.fitter.windows.len();
        if n > GRID_MAX_WINDOWS {
            (0..GRID_MAX_WINDOWS)
                .map(|i| i * n / GRID_MAX_WINDOWS)
                .collect()
        } else {
            (0..n).collect()
        }
    }
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

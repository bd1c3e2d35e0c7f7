//! Restarts of a fit's outlying windows. With a hybrid law (a wheel that sticks or slips)
//! a window's cost is multimodal in its initial state: a slightly different state puts a
//! wheel in another mode for part of the window, and the joint Levenberg–Marquardt descent,
//! which moves every window's state a little at a time, can settle with a few windows in
//! the wrong mode while the rest sit at the noise. Such a window stands out against the
//! others: its cost per residual is many times the median (of a model at the noise in the
//! median window). It is re-fitted alone, the
//! parameters held, from the state the readings give at its start
//! ([`super::Plant::initial_state`]), and the lower of the two minima is kept.

use super::fit::Fitter;
use super::model::to_internal;
use super::normal_equations::step;
use super::Plant;
use nalgebra::DVector;

/// A window is an outlier when its cost per residual exceeds this multiple of the median
/// window's (a window at the noise has a cost per residual near 1, with a spread of
/// `sqrt(2/m)` over its `m` residuals: a few per cent for hundreds of residuals).
const OUTLIER_RATIO: f64 = 4.0;

/// Restarts are for a model that fits the median window at the noise (cost per residual
/// near 1, at most this): where the median window is itself far above the noise the model
/// lacks something, and its worst windows are where the data excite what it lacks, not
/// windows in a wrong basin.
const MEDIAN_AT_NOISE: f64 = 2.0;

/// Iterations of a restarted window's own state fit.
const WINDOW_ITERATIONS: usize = 30;

impl<P: Plant> Fitter<'_, P> {
    /// Re-fit the initial states of the outlying windows of `(theta, z)` from the readings'
    /// start, keeping each where it ends lower. Returns how many windows moved.
    pub fn restart_outliers(&self, theta: &[f64], z: &mut [Vec<f64>]) -> usize {
        let costs: Vec<Option<(f64, usize)>> =
            self.map_windows(|wi| self.window_cost(theta, self.windows[wi], &z[wi]));
        let mut per: Vec<f64> = costs
            .iter()
            .flatten()
            .filter(|(_, m)| *m > 0)
            .map(|(r, m)| r / *m as f64)
            .collect();
        if per.len() < 3 {
            return 0;
        }
        per.sort_by(f64::total_cmp);
        let median = per[per.len() / 2];
        if median > MEDIAN_AT_NOISE {
            return 0;
        }
        let outliers: Vec<usize> = costs
            .iter()
            .enumerate()
            .filter_map(|(wi, c)| {
                let (r, m) = (*c)?;
                (m > 0 && r / m as f64 > OUTLIER_RATIO * median).then_some(wi)
            })
            .collect();
        if outliers.is_empty() {
            return 0;
        }
        let fresh = self.initial_states();
        // Every thread walks all windows but refits only the outliers (a few).
        let refitted: Vec<Option<Vec<f64>>> = self.map_windows(|wi| {
            if !outliers.contains(&wi) {
                return None;
            }
            let current = costs[wi]?.0;
            let (z_new, cost) = self.fit_window_state(theta, wi, fresh[wi].clone())?;
            (cost < current).then_some(z_new)
        });
        let mut n = 0;
        for (wi, r) in refitted.into_iter().enumerate() {
            if let Some(z_new) = r {
                z[wi] = z_new;
                n += 1;
            }
        }
        n
    }

    /// Levenberg–Marquardt on one window's initial state alone, parameters held at
    /// `theta`, from `z`: the state reached and its cost.
    fn fit_window_state(
        &self,
        theta: &[f64],
        wi: usize,
        mut z: Vec<f64>,
    ) -> Option<(Vec<f64>, f64)> {
        let x = to_internal(self.catalogue(), theta);
        let win = self.windows[wi];
        let mut cost = self.window_cost(theta, win, &z)?.0;
        let mut lambda = 1e-3;
        for _ in 0..WINDOW_ITERATIONS {
            let lin = self.window_lin(&x, &[], win, &z)?;
            let mut improved = false;
            while lambda <= 1e8 {
                // The fit's own step with no free coordinates: the damped window block.
                let (dz, _) = step(std::slice::from_ref(&lin), 0, lambda, &DVector::zeros(0));
                let trial: Vec<f64> = z.iter().zip(dz[0].iter()).map(|(a, b)| a + b).collect();
                match self.window_cost(theta, win, &trial) {
                    Some((c, _)) if c < cost => {
                        let rel = (cost - c) / cost.max(1e-300);
                        z = trial;
                        cost = c;
                        lambda = (lambda / 3.0).max(1e-9);
                        improved = rel > 1e-9;
                        break;
                    }
                    _ => lambda *= 4.0,
                }
            }
            if !improved {
                break;
            }
        }
        Some((z, cost))
    }
}

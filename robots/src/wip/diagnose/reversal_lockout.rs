//! The reversal lockout of a motor's firmware: a command whose sign differs from the last
//! accepted one is replaced by zero volts unless the last accepted reversal lies at least
//! the lockout `T` back; then it is accepted and the clock restarts. Firmware writes this
//! to keep a balancing loop from chattering the motors; the log records the command before
//! it, so the wheel is seen held (or coasting) against a command that says drive.
//!
//! The firmware decides at the sample instants `t_k`, so only `T` rounded up to a whole
//! number of steps matters to it. The model makes the lockout continuous in `T`: the last
//! locked step of a window passes its command for the part of the step after `t + T`
//! (the step's mean voltage, [`ReversalLockout::pass`]), which gives the fit a derivative
//! with respect to `T` and reproduces the firmware wherever `T` is a whole number of steps.

use dmech_lie::Real;

/// The lockout's state along one motor's command sequence.
#[derive(Clone, Copy, Debug, Default)]
pub struct ReversalLockout {
    /// The sign of the last accepted command (`true`: `u ≥ 0`), `None` before the first.
    direction: Option<bool>,
    /// When the last reversal was accepted; `None` before the first (nothing pending: a
    /// log starts at a state the firmware reached long before).
    since: Option<f64>,
}

impl ReversalLockout {
    /// The fraction of the step `[t, t + h)` for which the driver passes the command `u`
    /// issued at `t` (1: passed, 0: held at zero volts), under the lockout `lockout`; the
    /// state moves on to `t`. Commands must come in time order.
    pub fn pass<T: Real>(&mut self, t: f64, u: f64, lockout: T, h: f64) -> T {
        let direction = u >= 0.0;
        let Some(last) = self.direction else {
            self.direction = Some(direction);
            return T::one();
        };
        if last == direction {
            return T::one();
        }
        let left = match self.since {
            Some(s) => lockout - (t - s),
            None => T::zero(),
        };
        // Exact multiples of the step must not flip on round-off in `t − since`.
        let tol = 1e-9 * h;
        if left.re() > tol {
            if left.re() >= h - tol {
                T::zero()
            } else {
                T::one() - left / h
            }
        } else {
            self.direction = Some(direction);
            self.since = Some(t);
            if left.re() > -tol {
                // `T` ends exactly at this step: the value is 1, the derivative the
                // right-hand one (a longer lockout would hold the step's start).
                T::one() - left / h
            } else {
                T::one()
            }
        }
    }
}

/// The passed fractions of the commands `u(k)` at `t_k = k h` for `k = from..n` (one
/// motor), with the lockout's state as if run from the log's first row. The rows before
/// `from` decide on the values alone (the state's decisions do not depend on derivatives),
/// and only from [`resync_row`] on: a window late in a long log costs its own rows, not
/// the log's.
pub fn passed_fractions<T: Real>(
    u: impl Fn(usize) -> f64,
    from: usize,
    n: usize,
    lockout: T,
    h: f64,
) -> Vec<T> {
    if from >= n {
        return Vec::new();
    }
    let mut state = ReversalLockout::default();
    for k in resync_row(&u, from, lockout.re(), h)..from {
        state.pass(k as f64 * h, u(k), lockout.re(), h);
    }
    (from..n)
        .map(|k| state.pass(k as f64 * h, u(k), lockout, h))
        .collect()
}

/// The latest row `s ≤ from` from which the lockout's state, started afresh (nothing
/// pending), decides every row from `s` on as the state run from row 0 does: the last row
/// of a same-sign run of more than `2T/h + 1` steps, or 0. Reads rows up to `from`.
///
/// Why: within a run of one sign that starts at row `a`, a pending reversal is accepted
/// by `t_a + T` (the last acceptance lies before `t_a`), so the last acceptance is at most
/// `t_a + T + h`. Once the run is longer than `2T + h`, the next reversal finds the clock
/// past `T` and is accepted with the value 1 and no derivative in `T`, which is what a
/// fresh state gives it; and within the run the commands agree with the direction.
fn resync_row(u: impl Fn(usize) -> f64, from: usize, lockout: f64, h: f64) -> usize {
    if from == 0 || lockout <= 0.0 {
        return from;
    }
    // Rows in the run before its last one; a margin of two steps over the bound.
    let needed = (2.0 * lockout / h).ceil() as usize + 2;
    let mut top = from;
    let mut run = 0;
    for k in (0..from).rev() {
        if (u(k) >= 0.0) == (u(k + 1) >= 0.0) {
            run += 1;
            if run >= needed {
                return top;
            }
        } else {
            top = k;
            run = 0;
        }
    }
    0
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::Dual64;

    /// The firmware's rule at sample instants: with `T` a whole number of steps the model
    /// passes exactly the commands the firmware passes.
    #[test]
    fn whole_steps_reproduce_the_sampled_rule() {
        let h = 0.01;
        // Reversals at k = 3 (accepted: none before), 5 (locked until 3 + 15 = 18, then
        // accepted), 20 (locked until 33, but reversed back at 22), 40 (accepted).
        let signs: Vec<f64> = (0..45)
            .map(|k| match k {
                0..=2 => 1.0,
                3..=4 => -1.0,
                5..=19 => 1.0,
                20..=21 => -1.0,
                22..=39 => 1.0,
                _ => -1.0,
            })
            .collect();
        let pass = passed_fractions(|k| signs[k], 0, signs.len(), 15.0 * h, h);
        // The firmware: zero while `t_k − t_accepted < T`.
        let mut expect = vec![1.0; signs.len()];
        for (k, e) in expect.iter_mut().enumerate() {
            if (5..18).contains(&k) || (20..22).contains(&k) {
                *e = 0.0;
            }
        }
        for (k, (a, b)) in pass.iter().zip(&expect).enumerate() {
            assert!((a - b).abs() < 1e-9, "step {k}: {a} against {b}");
        }
    }

    /// Between whole steps the last locked step passes the part after `t_accepted + T`,
    /// and the derivative with respect to `T` is `−1/h` there and zero elsewhere.
    #[test]
    fn a_fractional_lockout_passes_the_rest_of_its_last_step() {
        let h = 0.01;
        let signs = [1.0, -1.0, 1.0, 1.0, 1.0, 1.0, 1.0];
        let t = Dual64::from_re(0.0325).derivative();
        let pass = passed_fractions(|k| signs[k], 0, signs.len(), t, h);
        // Accepted at k = 1 (t = 0.01); reversed at k = 2, locked while t_k < 0.0425:
        // k = 2, 3 fully, k = 4 (t = 0.04) for a quarter of its step.
        let re: Vec<f64> = pass.iter().map(|p| p.re).collect();
        let expect = [1.0, 1.0, 0.0, 0.0, 0.75, 1.0, 1.0];
        for (a, b) in re.iter().zip(expect) {
            assert!((a - b).abs() < 1e-12, "{re:?}");
        }
        let d: Vec<f64> = pass.iter().map(|p| p.eps).collect();
        assert!((d[4] + 1.0 / h).abs() < 1e-9, "{d:?}");
        assert!(d.iter().enumerate().all(|(k, &x)| k == 4 || x == 0.0));
    }

    /// Starting the derivatives late changes no value.
    #[test]
    fn a_late_start_gives_the_same_fractions() {
        let u: Vec<f64> = (0..60).map(|k| (k * 7 % 11) as f64 - 5.0).collect();
        let all = passed_fractions(|k| u[k], 0, u.len(), 0.047, 0.01);
        let late = passed_fractions(|k| u[k], 25, u.len(), 0.047, 0.01);
        assert_eq!(all[25..], late[..]);
    }

    /// The resynchronised start gives what the state run from row 0 gives, values and
    /// derivatives, for random command sequences (runs of a few steps, so that some
    /// windows resynchronise and some run from row 0), lockouts and window starts.
    #[test]
    fn the_resynchronised_start_agrees_with_the_whole_log() {
        let mut rng = dmech_lie::rng::Rng::new(23);
        let mut resynced_cases = 0;
        let h = 0.01;
        for case in 0..300 {
            let n = 200;
            let mut u = Vec::with_capacity(n);
            let mut sign = 1.0;
            while u.len() < n {
                let run = 1 + (rng.uniform() * 30.0 * rng.uniform()) as usize;
                u.extend(std::iter::repeat_n(sign * (0.4 + rng.uniform()), run));
                sign = -sign;
            }
            u.truncate(n);
            let lockout = 0.005 + 0.1 * rng.uniform();
            let t = Dual64::from_re(lockout).derivative();
            let from = (rng.uniform() * n as f64) as usize;
            let mut state = ReversalLockout::default();
            let whole: Vec<Dual64> = (0..n)
                .map(|k| state.pass(k as f64 * h, u[k], t, h))
                .collect();
            if resync_row(|k| u[k], from, lockout, h) > 0 {
                resynced_cases += 1;
            }
            let resynced = passed_fractions(|k| u[k], from, n, t, h);
            for (k, (a, b)) in whole[from..].iter().zip(&resynced).enumerate() {
                assert!(
                    a.re == b.re && a.eps == b.eps,
                    "case {case}, row {}: {a:?} against {b:?}",
                    from + k
                );
            }
        }
        // Both paths exercised: resynchronised windows and windows run from row 0.
        assert!(
            (50..250).contains(&resynced_cases),
            "{resynced_cases} of 300"
        );
    }

    /// No lockout passes every command.
    #[test]
    fn zero_lockout_passes_everything() {
        let u = [1.0, -1.0, 1.0, -1.0, 1.0];
        let pass = passed_fractions(|k| u[k], 0, u.len(), 0.0, 0.01);
        assert!(pass.iter().all(|&p| p == 1.0));
    }
}

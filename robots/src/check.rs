//! The checks a command runs on the model it is about to run, before any long work, for
//! every robot (docs/formats.md, "Checks before a run"): the model's rates finite at the
//! start, the time-stepping scheme's stability bound at the chosen step (a damped mode an
//! explicit scheme amplifies, a growing mode no scheme follows within a step), and the
//! size of the run against its limit. A command calls [`linear_modes`] on its model (any
//! [`PrincipalKinematicSystem`]) and [`check_step`] with its scheme and step, or
//! [`stable_substeps`] where it chooses the step itself, and [`check_size`] on what it
//! would allocate; each refusal is one [`CheckError`] whose message is the line the tool
//! prints.

use dmech::continuous::{ContinuousModel, ContinuousState};
use dmech::Integrator;
use dmech::PrincipalKinematicSystem;
use nalgebra::{Complex, DMatrix, SVector};

/// How a scheme steps, for its stability bound.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepKind {
    /// An explicit Runge–Kutta method of this order (1, 2, 4): its stability function is
    /// `R(z) = Σ_{j≤p} z^j / j!`.
    Explicit(u32),
    /// An implicit (variational) scheme: stable on damped modes at any step.
    Implicit,
}

/// A time-stepping scheme as the checks see it: its name (for messages) and kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Scheme {
    pub name: &'static str,
    pub kind: StepKind,
}

impl From<Integrator> for Scheme {
    /// The scheme's name, and explicit of its order for a Runge–Kutta method.
    fn from(integrator: Integrator) -> Self {
        Scheme {
            name: integrator.name(),
            kind: match integrator.runge_kutta() {
                Some(_) => StepKind::Explicit(integrator.order()),
                None => StepKind::Implicit,
            },
        }
    }
}

/// Why a run was refused before it started.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CheckError {
    /// The model's rates or their linearisation are not finite at the start, or too large
    /// for any step (parameters such as `g = 1e308`).
    #[error(
        "{what}: the model's linearisation at the start is not finite ({detail}): check the \
         parameters"
    )]
    NotFinite { what: &'static str, detail: String },
    /// A mode the scheme does not follow at this step: a damped one an explicit scheme
    /// amplifies, or a growing one faster than the step.
    #[error("{}", step_message(self))]
    Step {
        what: &'static str,
        scheme: &'static str,
        h: f64,
        /// The fastest mode that fails, `λ` in 1/s.
        mode: Complex<f64>,
        /// The largest step that passes.
        h_max: f64,
        /// What sets the step (`--step`), and another remedy (` or --integrator first-order`).
        option: &'static str,
        alternative: &'static str,
        failure: StepFailure,
    },
    /// Where the command chooses the step itself: more substeps than it allows.
    #[error(
        "{what}: {scheme} would need {needed} substeps per {interval} s to stay within its \
         stability bound (fastest mode's time constant {tau:.2e} s), more than {limit}: check \
         the parameters"
    )]
    TooStiff {
        what: &'static str,
        scheme: &'static str,
        interval: f64,
        needed: f64,
        limit: usize,
        tau: f64,
    },
    /// More items (stages, steps, samples, rows) than the limit, before any allocation.
    #[error(
        "{what}: {count:.0} would need about {:.1} GB, above the limit of {limit} ({:.1} GB); \
         check the units (seconds) or raise the limit with {option}",
        .count * .bytes_each / 1e9,
        *.limit as f64 * .bytes_each / 1e9
    )]
    TooLarge {
        what: String,
        count: f64,
        limit: usize,
        bytes_each: f64,
        option: String,
    },
}

/// How a mode fails a step's check.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepFailure {
    /// A damped mode (Re λ < 0) that the explicit scheme amplifies ×`growth` per step.
    Amplified { growth: f64 },
    /// A growing mode (Re λ > 0) faster than the step: no scheme follows it (an implicit
    /// one damps it or turns it over, an explicit one misses its growth).
    Unresolved,
}

/// The message of [`CheckError::Step`].
fn step_message(e: &CheckError) -> String {
    let CheckError::Step {
        what,
        scheme,
        h,
        mode,
        h_max,
        option,
        alternative,
        failure,
    } = e
    else {
        return String::new();
    };
    let lambda = format!("λ = {:.3e}{:+.3e}i 1/s", mode.re, mode.im);
    let tau = 1.0 / mode.re.abs();
    match failure {
        StepFailure::Amplified { growth } => format!(
            "{what}: {scheme} at a step of {h} s is beyond its stability bound for this model: \
             the mode {lambda} (time constant {tau:.2e} s) grows ×{growth:.3} per step; use \
             {option} ≤ {h_max:.3e}{alternative}"
        ),
        StepFailure::Unresolved => format!(
            "{what}: the model has a mode {lambda} that grows e-fold in {tau:.2e} s, faster \
             than a step of {h} s resolves ({scheme} would not follow it): use {option} ≤ \
             {h_max:.3e}, or check the parameters"
        ),
    }
}

/// Refuse a run of `count` items (stages, steps, samples) above `limit`, before it
/// allocates: the message gives the memory it would take and the option that raises the
/// limit.
pub fn check_size(
    what: &str,
    count: f64,
    limit: usize,
    bytes_each: f64,
    option: &str,
) -> Result<(), CheckError> {
    if count.is_finite() && count <= limit as f64 {
        return Ok(());
    }
    Err(CheckError::TooLarge {
        what: what.to_string(),
        count,
        limit,
        bytes_each,
        option: option.to_string(),
    })
}

/// The largest entry of a linearisation that a check accepts: beyond it the modes are
/// faster than any step the tools take (1e100 1/s), and the eigenvalue iteration would
/// overflow.
const LARGEST_RATE: f64 = 1e100;

/// Eigenvalues of the linearised shape dynamics `(s, v) ↦ (v, v̇)` of `sys` at state `x`
/// and input `u` (the equations do not depend on the pose). The Jacobian is taken by
/// central differences (a diagnostic, not a derivative the results depend on). An error if
/// the rates are not finite there, the linearisation has entries beyond 1e100, or its
/// eigenvalues do not converge (a model no step resolves).
pub fn linear_modes<S, const DOF: usize, const NS: usize, const NU: usize>(
    sys: &S,
    x: &ContinuousState<S::Group<f64>, NS>,
    u: &SVector<f64, NU>,
    what: &'static str,
) -> Result<Vec<Complex<f64>>, CheckError>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
{
    let not_finite = |detail: String| CheckError::NotFinite { what, detail };
    let n = 2 * NS;
    let rhs = |z: &[f64]| -> Result<Vec<f64>, CheckError> {
        let y = ContinuousState {
            g: x.g,
            s: SVector::<f64, NS>::from_fn(|i, _| z[i]),
            v: SVector::<f64, NS>::from_fn(|i, _| z[NS + i]),
        };
        let (_, sdot, a) = ContinuousModel::derivative(sys, &y, u)
            .map_err(|e| not_finite(format!("its equations of motion: {e}")))?;
        Ok(sdot.iter().chain(a.iter()).copied().collect())
    };
    let z0: Vec<f64> = x.s.iter().chain(x.v.iter()).copied().collect();
    rhs(&z0)?;
    let mut jac = DMatrix::<f64>::zeros(n, n);
    for j in 0..n {
        let d = 1e-6 * (1.0 + z0[j].abs());
        let (mut zp, mut zm) = (z0.clone(), z0.clone());
        zp[j] += d;
        zm[j] -= d;
        let (fp, fm) = (rhs(&zp)?, rhs(&zm)?);
        for i in 0..n {
            jac[(i, j)] = (fp[i] - fm[i]) / (2.0 * d);
        }
    }
    if jac.iter().any(|v| v.is_nan()) {
        return Err(not_finite("its entries are not numbers".into()));
    }
    let largest = jac.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if !largest.is_finite() || largest > LARGEST_RATE {
        return Err(not_finite(format!("its entries reach {largest:.3e}")));
    }
    let schur = nalgebra::linalg::Schur::try_new(jac, f64::EPSILON, 1000 * n)
        .ok_or_else(|| not_finite("its eigenvalues do not converge".into()))?;
    Ok(schur.complex_eigenvalues().iter().copied().collect())
}

/// `|R(z)|` of an explicit Runge–Kutta method of order `p` (`R(z) = Σ_{j≤p} z^j / j!`).
fn amplification(order: u32, z: Complex<f64>) -> f64 {
    let (mut term, mut sum) = (Complex::new(1.0, 0.0), Complex::new(1.0, 0.0));
    for j in 1..=order {
        term = term * z / j as f64;
        sum += term;
    }
    sum.norm()
}

/// A damped mode `λ` (Re λ < 0) resolved by less than a step (`|hλ| > 1`) that the
/// explicit scheme of order `order` amplifies (`|R(hλ)| > 1`): the blow-up explicit methods
/// show on a fast mode such as a motor circuit's electrical one. Slow or growing modes are
/// the physics and are left to [`unresolved`].
fn amplified(order: u32, h: f64, l: &Complex<f64>) -> bool {
    l.re < 0.0 && (l * h).norm() > 1.0 && amplification(order, l * h) > 1.0
}

/// A growing mode (Re λ > 0) faster than the step (`|hλ| > 1`).
fn unresolved(h: f64, l: &Complex<f64>) -> bool {
    l.re > 0.0 && (l * h).norm() > 1.0
}

/// The fastest mode of `modes` that fails `fails` at step `h`.
fn worst(
    modes: &[Complex<f64>],
    fails: impl Fn(f64, &Complex<f64>) -> bool,
    h: f64,
) -> Option<Complex<f64>> {
    modes
        .iter()
        .filter(|l| fails(h, l))
        .max_by(|a, b| a.norm().total_cmp(&b.norm()))
        .copied()
}

/// The largest step at which no mode of `modes` fails the scheme's checks (bisection from
/// `h`, the step at which one does).
fn largest_step(modes: &[Complex<f64>], fails: impl Fn(f64, &Complex<f64>) -> bool, h: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, h);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if modes.iter().any(|l| fails(mid, l)) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    lo
}

/// Refuse a step `h` of `scheme` on a model with linearised modes `modes` (from
/// [`linear_modes`]): for an explicit scheme, a damped mode it amplifies; for any scheme,
/// a growing mode faster than the step. `option` is what sets the step (the message
/// suggests the largest step that passes), `alternative` another remedy for an explicit
/// scheme's bound (e.g. ` or --integrator first-order`, or empty).
pub fn check_step(
    what: &'static str,
    modes: &[Complex<f64>],
    scheme: Scheme,
    h: f64,
    option: &'static str,
    alternative: &'static str,
) -> Result<(), CheckError> {
    let refuse = |mode: Complex<f64>, h_max: f64, failure: StepFailure| CheckError::Step {
        what,
        scheme: scheme.name,
        h,
        mode,
        h_max,
        option,
        alternative: match failure {
            StepFailure::Amplified { .. } => alternative,
            StepFailure::Unresolved => "",
        },
        failure,
    };
    if let StepKind::Explicit(order) = scheme.kind {
        let fails = |h: f64, l: &Complex<f64>| amplified(order, h, l);
        if let Some(mode) = worst(modes, fails, h) {
            let growth = amplification(order, mode * h);
            return Err(refuse(
                mode,
                largest_step(modes, fails, h),
                StepFailure::Amplified { growth },
            ));
        }
    }
    if let Some(mode) = worst(modes, unresolved, h) {
        return Err(refuse(
            mode,
            largest_step(modes, unresolved, h),
            StepFailure::Unresolved,
        ));
    }
    Ok(())
}

/// [`check_step`] of a simulation whose step is `--step`, where the variational
/// integrator is the remedy for an explicit scheme's bound.
pub fn check_simulation_step(
    what: &'static str,
    modes: &[Complex<f64>],
    scheme: Scheme,
    h: f64,
) -> Result<(), CheckError> {
    check_step(
        what,
        modes,
        scheme,
        h,
        "--step",
        " or --integrator first-order",
    )
}

/// The number of substeps of an interval of `interval` seconds that keeps `scheme` within
/// the checks of [`check_step`] on `modes`: `min` where that suffices (the figures a
/// command has always produced), more where the model needs them, and an error beyond
/// `max`.
pub fn stable_substeps(
    what: &'static str,
    modes: &[Complex<f64>],
    scheme: Scheme,
    interval: f64,
    min: usize,
    max: usize,
) -> Result<usize, CheckError> {
    let passes = |n: usize| check_step(what, modes, scheme, interval / n as f64, "", "").is_ok();
    if passes(min) {
        return Ok(min);
    }
    let fails = |h: f64, l: &Complex<f64>| {
        unresolved(h, l) || matches!(scheme.kind, StepKind::Explicit(p) if amplified(p, h, l))
    };
    let h_max = largest_step(modes, fails, interval / min as f64);
    let needed = (interval / h_max).ceil();
    let fastest = modes
        .iter()
        .filter(|l| fails(interval / min as f64, l))
        .map(|l| 1.0 / l.re.abs())
        .fold(f64::INFINITY, f64::min);
    if needed.is_finite() && needed <= max as f64 {
        // The bisection's step passes; the next whole count at or above it does too, but
        // a few more make sure of it where the bound is not monotone in the step.
        let n = (needed as usize).max(min);
        if let Some(ok) = (n..=(n + 8).min(max)).find(|&k| passes(k)) {
            return Ok(ok);
        }
    }
    Err(CheckError::TooStiff {
        what,
        scheme: scheme.name,
        interval,
        needed,
        limit: max,
        tau: fastest,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The motor circuit's mode of the WIP (τ ≈ 0.27 ms): RK4 is stable at 0.5 ms and not
    /// at 1 ms (|hλ| ≈ 3.8 > 2.78); an implicit scheme is stable at any step; a growing
    /// mode of 10 1/s is resolved by 0.05 s and not by 0.2 s.
    #[test]
    fn the_bounds_of_explicit_and_implicit_schemes() {
        let fast = [Complex::new(-3750.0, 0.0)];
        let rk4 = Scheme::from(Integrator::Rk4);
        assert!(check_step("t", &fast, rk4, 5e-4, "--step", "").is_ok());
        let e = check_step("t", &fast, rk4, 1e-3, "--step", "").unwrap_err();
        assert!(
            matches!(e, CheckError::Step { h_max, failure: StepFailure::Amplified { .. }, .. } if (h_max * 3750.0 - 2.785).abs() < 0.01),
            "{e}"
        );
        assert!(check_step(
            "t",
            &fast,
            Scheme::from(Integrator::FirstOrder),
            1.0,
            "--step",
            ""
        )
        .is_ok());
        let growing = [Complex::new(10.0, 0.0)];
        assert!(check_step(
            "t",
            &growing,
            Scheme::from(Integrator::Midpoint),
            0.05,
            "--step",
            ""
        )
        .is_ok());
        let e = check_step(
            "t",
            &growing,
            Scheme::from(Integrator::Midpoint),
            0.2,
            "--step",
            "",
        )
        .unwrap_err();
        assert!(
            matches!(e, CheckError::Step { h_max, failure: StepFailure::Unresolved, .. } if (h_max - 0.1).abs() < 1e-9),
            "{e}"
        );
        // Substeps: 10 of 5 ms suffice for τ = 0.27 ms; a 4× faster mode needs more; one
        // far faster is refused.
        assert_eq!(
            stable_substeps("t", &fast, rk4, 5e-3, 10, 1000).unwrap(),
            10
        );
        let faster = [Complex::new(-15000.0, 0.0)];
        let n = stable_substeps("t", &faster, rk4, 5e-3, 10, 1000).unwrap();
        assert!((27..=30).contains(&n), "{n}");
        assert!(check_step("t", &faster, rk4, 5e-3 / n as f64, "", "").is_ok());
        let e = stable_substeps("t", &[Complex::new(-1e9, 0.0)], rk4, 5e-3, 10, 1000);
        assert!(matches!(e, Err(CheckError::TooStiff { .. })), "{e:?}");
    }
}

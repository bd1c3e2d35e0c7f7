//! The QP solver's settings and their builder.

/// Settings of [`crate::qp::QpSolver`] (defaults in [`QpSettings::default`]).
#[derive(Clone, Debug, PartialEq)]
pub struct QpSettings {
    /// Convergence tolerance: the stationarity, primal residual and mean complementarity
    /// each at most `tol` times their scale (`docs/qp.md`, "Termination").
    pub tol: f64,
    /// Iterations, at most.
    pub max_iter: usize,
    /// The least fraction of the step to the boundary taken at most: `τ = max(step_fraction,
    /// 1 − μ)` of the fraction-to-the-boundary rule (IPOPT's), so that `τ → 1` as `μ → 0`.
    pub step_fraction: f64,
    /// The diagonal added to every stage's `R̃` in the Newton systems: a convex QP's
    /// `R + Bᵀ P B` may be singular in a direction without curvature; the shift keeps the
    /// Riccati recursion defined and leaves the residuals (and so the solution) exact.
    pub regularisation: f64,
    /// A warm start's slacks and multipliers are raised to at least this (their
    /// products, the complementarity, to its square): a point on the boundary would stall
    /// the interior point.
    pub warm_floor: f64,
    /// Tolerance of the infeasibility and unboundedness certificates.
    pub certificate_tol: f64,
    /// The complementarity `tλ` a cold start is centred at (`docs/qp.md`, "Starts").
    pub start_mu: f64,
}

impl Default for QpSettings {
    /// `tol = 1e-8`, `max_iter = 50`, `step_fraction = 0.995`, `regularisation = 1e-10`,
    /// `warm_floor = 1e-3`, `certificate_tol = 1e-7`, `start_mu = 10`.
    fn default() -> Self {
        QpSettings {
            tol: 1e-8,
            max_iter: 50,
            step_fraction: 0.995,
            regularisation: 1e-10,
            warm_floor: 1e-3,
            certificate_tol: 1e-7,
            start_mu: 10.0,
        }
    }
}

impl QpSettings {
    /// A builder from the defaults.
    pub fn builder() -> QpSettingsBuilder {
        QpSettingsBuilder(QpSettings::default())
    }
}

/// Builds [`QpSettings`] from the defaults; [`QpSettingsBuilder::build`] checks them.
#[derive(Clone, Debug)]
pub struct QpSettingsBuilder(QpSettings);

/// A setting out of its range.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("the setting {name} = {value} is out of its range {range}")]
pub struct SettingsError {
    /// The setting.
    pub name: &'static str,
    /// Its value.
    pub value: f64,
    /// Its range.
    pub range: &'static str,
}

impl QpSettingsBuilder {
    /// [`QpSettings::tol`].
    pub fn tol(mut self, v: f64) -> Self {
        self.0.tol = v;
        self
    }
    /// [`QpSettings::max_iter`].
    pub fn max_iter(mut self, v: usize) -> Self {
        self.0.max_iter = v;
        self
    }
    /// [`QpSettings::step_fraction`].
    pub fn step_fraction(mut self, v: f64) -> Self {
        self.0.step_fraction = v;
        self
    }
    /// [`QpSettings::regularisation`].
    pub fn regularisation(mut self, v: f64) -> Self {
        self.0.regularisation = v;
        self
    }
    /// [`QpSettings::warm_floor`].
    pub fn warm_floor(mut self, v: f64) -> Self {
        self.0.warm_floor = v;
        self
    }
    /// [`QpSettings::certificate_tol`].
    pub fn certificate_tol(mut self, v: f64) -> Self {
        self.0.certificate_tol = v;
        self
    }

    /// [`QpSettings::start_mu`].
    pub fn start_mu(mut self, v: f64) -> Self {
        self.0.start_mu = v;
        self
    }

    /// The settings, each checked against its range.
    pub fn build(self) -> Result<QpSettings, SettingsError> {
        let s = self.0;
        let check = |name, value: f64, ok: bool, range| match ok {
            true => Ok(()),
            false => Err(SettingsError { name, value, range }),
        };
        check("tol", s.tol, s.tol > 0.0 && s.tol < 1.0, "(0, 1)")?;
        check("max_iter", s.max_iter as f64, s.max_iter >= 1, "1 or more")?;
        let tau = s.step_fraction;
        check("step_fraction", tau, tau > 0.0 && tau < 1.0, "(0, 1)")?;
        let reg = s.regularisation;
        check("regularisation", reg, (0.0..1.0).contains(&reg), "[0, 1)")?;
        let floor = s.warm_floor;
        check(
            "warm_floor",
            floor,
            floor > 0.0 && floor.is_finite(),
            "(0, ∞)",
        )?;
        let ct = s.certificate_tol;
        check("certificate_tol", ct, ct > 0.0 && ct < 1.0, "(0, 1)")?;
        let mu0 = s.start_mu;
        check("start_mu", mu0, mu0 > 0.0 && mu0.is_finite(), "(0, ∞)")?;
        Ok(s)
    }
}

//! The catalogue of unmodelled effects (docs/formats.md, "Effect names") as extensions of the
//! one WIP model: each effect changes a parameter of [`Wip`], the voltage the drivers apply,
//! an external force, or a sensor reading. Nothing here copies the model; the equations of
//! motion stay those derived by `dmech` from `ℓ`, `A` and the forcing.

use super::super::params::WipParams;
use super::super::Wip;
use dmech_lie::Real;
use nalgebra::SVector;

/// An effect of the catalogue.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Effect {
    TiltOffset,
    FloorSlope,
    InputDelay,
    VoltageGain,
    Friction,
    WheelRadiusAsymmetry,
    Payload,
    DeadZone,
}

impl Effect {
    pub const ALL: [Effect; 8] = [
        Effect::TiltOffset,
        Effect::FloorSlope,
        Effect::InputDelay,
        Effect::VoltageGain,
        Effect::Friction,
        Effect::WheelRadiusAsymmetry,
        Effect::Payload,
        Effect::DeadZone,
    ];

    /// The name used in `diagnosis.json`.
    pub fn name(self) -> &'static str {
        match self {
            Effect::TiltOffset => "tilt_offset",
            Effect::FloorSlope => "floor_slope",
            Effect::InputDelay => "input_delay",
            Effect::VoltageGain => "voltage_gain",
            Effect::Friction => "friction",
            Effect::WheelRadiusAsymmetry => "wheel_radius_asymmetry",
            Effect::Payload => "payload",
            Effect::DeadZone => "dead_zone",
        }
    }

    pub fn from_name(name: &str) -> Option<Effect> {
        Effect::ALL.into_iter().find(|e| e.name() == name)
    }

    /// Parameter names (the keys of `diagnosis.json`).
    pub fn parameter_names(self) -> &'static [&'static str] {
        match self {
            Effect::TiltOffset => &["b_rad"],
            Effect::FloorSlope => &["slope_x_rad", "slope_y_rad"],
            Effect::InputDelay => &["delay_s"],
            Effect::VoltageGain => &["gain"],
            Effect::Friction => &["d_v", "d_c"],
            Effect::WheelRadiusAsymmetry => &["r_R_m", "r_L_m"],
            Effect::Payload => &["m_b_kg", "l_m"],
            Effect::DeadZone => &["u0_V"],
        }
    }

    pub fn n_params(self) -> usize {
        self.parameter_names().len()
    }

    /// The parameter values for which the effect is absent (the nominal model).
    pub fn nominal(self, p: &WipParams) -> Vec<f64> {
        match self {
            Effect::TiltOffset | Effect::InputDelay | Effect::DeadZone => vec![0.0],
            Effect::FloorSlope => vec![0.0, 0.0],
            Effect::VoltageGain => vec![1.0],
            Effect::Friction => vec![p.d_v, p.d_c],
            Effect::WheelRadiusAsymmetry => vec![p.r, p.r],
            Effect::Payload => vec![p.m_b, p.l],
        }
    }

    /// A typical size of a change of each parameter, for scaling the fit and for the
    /// generator's magnitudes (see `docs/diagnose.md`).
    pub fn scale(self, p: &WipParams) -> Vec<f64> {
        match self {
            Effect::TiltOffset => vec![0.01],
            Effect::FloorSlope => vec![0.02, 0.02],
            Effect::InputDelay => vec![0.01],
            Effect::VoltageGain => vec![0.1],
            Effect::Friction => vec![p.d_v, p.d_c],
            Effect::WheelRadiusAsymmetry => vec![0.03 * p.r, 0.03 * p.r],
            Effect::Payload => vec![0.2 * p.m_b, 0.2 * p.l],
            Effect::DeadZone => vec![0.2],
        }
    }

    /// A floor under each parameter's uncertainty from the prediction model's own
    /// approximation, added in quadrature to the statistical one. Only the delay has one:
    /// the prediction replaces the current's exponential lag `τ_e = L_m/R_m` by a pure
    /// delay of `τ_e`, exact in the impulse it gives the wheels but not in its shape. On
    /// generated runs (true model with the current dynamics) this biases the fitted delay
    /// by 0.6–0.8 % of `τ_e` (1.6–2.1 µs at 12 ms; unchanged when the true model's
    /// step is halved or the prediction's, so it is the reduction, not the integration);
    /// the floor is 1 % of `τ_e` (docs/diagnose.md).
    pub fn systematic(self, p: &WipParams) -> Vec<f64> {
        match self {
            Effect::InputDelay => vec![0.01 * p.L_m / p.R_m],
            _ => vec![0.0; self.n_params()],
        }
    }

    /// The physically plausible range `[lo, hi]` of each parameter: a fit may wander
    /// outside while it converges, but a candidate whose parameters end outside is not
    /// named. The bounds come from what the effect is, for a robot of parameters `p`:
    /// - tilt offset and floor slope: at most 0.3 rad (17°; a robot mounted or driven
    ///   further off is not "balancing with an offset");
    /// - input delay: at most 0.1 s (ten 100 Hz control steps; the robot would not balance);
    /// - voltage gain: 0.3–3 (a driver or battery off by more is a wiring error);
    /// - friction: `d_c` up to the motor's stall torque at 12 V, `n_wm k_e 12/R_m` (the
    ///   wheels could not turn); `d_v` up to ten times the back-EMF damping `n_wm² k_e²/R_m`;
    /// - wheel radii: within ±25 % of `r` (a different wheel, not an asymmetry);
    /// - payload: body mass 0.5–2 × `m_b` (a payload cannot weigh more than the robot),
    ///   height of the centre of mass 0.2–5 × `l` and at most 0.5 m;
    /// - dead zone: at most 3 V.
    pub fn plausible(self, p: &WipParams) -> Vec<(f64, f64)> {
        match self {
            Effect::TiltOffset => vec![(-0.3, 0.3)],
            Effect::FloorSlope => vec![(-0.3, 0.3), (-0.3, 0.3)],
            Effect::InputDelay => vec![(0.0, 0.1)],
            Effect::VoltageGain => vec![(0.3, 3.0)],
            Effect::Friction => vec![
                (0.0, 10.0 * p.n_wm * p.n_wm * p.k_e * p.k_e / p.R_m),
                (0.0, p.n_wm * p.k_e * 12.0 / p.R_m),
            ],
            Effect::WheelRadiusAsymmetry => vec![(0.75 * p.r, 1.25 * p.r); 2],
            Effect::Payload => vec![
                (0.5 * p.m_b, 2.0 * p.m_b),
                (0.2 * p.l, (5.0 * p.l).min(0.5)),
            ],
            Effect::DeadZone => vec![(0.0, 3.0)],
        }
    }

    /// The parameters of `theta` outside [`Effect::plausible`], in words (empty: plausible).
    pub fn implausible(self, theta: &[f64], p: &WipParams) -> Vec<String> {
        self.parameter_names()
            .iter()
            .zip(theta)
            .zip(self.plausible(p))
            .filter(|((_, v), (lo, hi))| v.is_nan() || **v < *lo || **v > *hi)
            .map(|((n, v), (lo, hi))| format!("{n} = {v:.4e} outside [{lo:.3e}, {hi:.3e}]"))
            .collect()
    }

    /// Whether a parameter vector is physically admissible (the fit projects onto this set).
    pub fn project(self, theta: &mut [f64], p: &WipParams) {
        match self {
            Effect::InputDelay | Effect::DeadZone => theta[0] = theta[0].max(0.0),
            Effect::VoltageGain => theta[0] = theta[0].max(0.05),
            Effect::Friction => {
                theta[0] = theta[0].max(0.0);
                theta[1] = theta[1].max(0.0);
            }
            Effect::WheelRadiusAsymmetry => {
                for r in theta.iter_mut() {
                    *r = r.clamp(0.5 * p.r, 2.0 * p.r);
                }
            }
            Effect::Payload => {
                theta[0] = theta[0].max(0.1 * p.m_b);
                theta[1] = theta[1].max(0.1 * p.l);
            }
            Effect::TiltOffset | Effect::FloorSlope => {
                for a in theta.iter_mut() {
                    *a = a.clamp(-0.5, 0.5);
                }
            }
        }
    }
}

/// The model with every effect's parameters; at [`ModelExtension::nominal`] it is the
/// paper's model. Several effects can be active at once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelExtension<T> {
    /// The tilt sensor reads `α + b`.
    pub tilt_offset: T,
    /// Floor inclination `(σx, σy)`: the floor rises along +x by `σx` and along +y by `σy`.
    pub slope: [T; 2],
    /// The drivers apply the voltage this much later (on top of the electrical lag).
    pub delay: T,
    /// The drivers apply `κ u`.
    pub gain: T,
    /// `(d_v, d_c)` of the gear/bearing friction.
    pub friction: [T; 2],
    /// `(r_R, r_L)`.
    pub radii: [T; 2],
    /// `(m_b, l)`.
    pub payload: [T; 2],
    /// Dead zone half-width `u0`.
    pub dead_zone: T,
}

impl<T: Real> ModelExtension<T> {
    /// No effect: the paper's model with parameters `p`.
    pub fn nominal(p: &WipParams) -> Self {
        let c = |x: f64| T::from(x);
        ModelExtension {
            tilt_offset: T::zero(),
            slope: [T::zero(); 2],
            delay: T::zero(),
            gain: T::one(),
            friction: [c(p.d_v), c(p.d_c)],
            radii: [c(p.r), c(p.r)],
            payload: [c(p.m_b), c(p.l)],
            dead_zone: T::zero(),
        }
    }

    /// Set one effect's parameters (in the order of [`Effect::parameter_names`]).
    pub fn set(&mut self, effect: Effect, theta: &[T]) {
        match effect {
            Effect::TiltOffset => self.tilt_offset = theta[0],
            Effect::FloorSlope => self.slope = [theta[0], theta[1]],
            Effect::InputDelay => self.delay = theta[0],
            Effect::VoltageGain => self.gain = theta[0],
            Effect::Friction => self.friction = [theta[0], theta[1]],
            Effect::WheelRadiusAsymmetry => self.radii = [theta[0], theta[1]],
            Effect::Payload => self.payload = [theta[0], theta[1]],
            Effect::DeadZone => self.dead_zone = theta[0],
        }
    }

    /// The WIP whose parameters carry the effects (`P = T`: dual parameters give
    /// derivatives with respect to them).
    pub fn system(&self, base: &WipParams) -> Wip<T> {
        let mut params = base.map(T::from);
        params.d_v = self.friction[0];
        params.d_c = self.friction[1];
        params.m_b = self.payload[0];
        params.l = self.payload[1];
        let mut w = Wip::new(params);
        let r = T::from(base.r);
        w.wheel_radius_offsets = [self.radii[0] - r, self.radii[1] - r];
        w
    }

    /// The voltage the driver applies for the command `u`: dead zone, then gain.
    pub fn driver(&self, u: T) -> T {
        let u0 = self.dead_zone;
        let dz = if u.re() > u0.re() {
            u - u0
        } else if u.re() < -u0.re() {
            u + u0
        } else {
            T::zero()
        };
        self.gain * dz
    }

    /// The tilt sensor's reading of the tilt `α` (from the floor's normal).
    pub fn tilt_reading(&self, alpha: T) -> T {
        alpha + self.tilt_offset
    }

    /// The generalised shape force of gravity's component along an inclined floor, minus
    /// the nominal gravity term already in `ℓ`, at heading `θ` and tilt `α` (`s[0]`).
    ///
    /// Gravity in the floor frame is `−g (sin σx, cos σx sin σy, cos σx cos σy)`, so
    /// `ΔV = g m_tot (sx x + sy y) + g m_b l [(sx cos θ + sy sin θ) sin α + (cz − 1) cos α]`.
    /// Its part on the group, `∇_b V = (Rᵀ∇_xy V, ∂V/∂θ)`, enters the shape equations as
    /// `Aᵀ ∇_b V` (virtual work along `g⁻¹δg = −A δs`), its part on `α` as `−∂ΔV/∂α`.
    pub fn floor_force(&self, sys: &Wip<T>, s: &SVector<T, 5>, theta: T) -> SVector<T, 5>
    where
        T: dmech::Lift<T>,
    {
        let [sigx, sigy] = self.slope;
        let p = &sys.params;
        let sx = sigx.sin();
        let sy = sigx.cos() * sigy.sin();
        let cz = sigx.cos() * sigy.cos();
        let g = p.g;
        let m_tot = p.m_b + p.m_w * 2.0;
        let mbl = p.m_b * p.l;
        let (sa, ca) = s[0].sin_cos();
        let (st, ct) = theta.sin_cos();
        let lever = sx * ct + sy * st;
        let grad_xy = [g * m_tot * sx, g * m_tot * sy];
        let grad_body = SVector::<T, 3>::new(
            grad_xy[0] * ct + grad_xy[1] * st,
            -grad_xy[0] * st + grad_xy[1] * ct,
            g * mbl * sa * (-sx * st + sy * ct),
        );
        use dmech::PrincipalKinematicSystem;
        let a = sys.connection(s);
        let mut f = a.transpose() * grad_body;
        f[0] -= g * mbl * (lever * ca - (cz - T::one()) * sa);
        f
    }
}

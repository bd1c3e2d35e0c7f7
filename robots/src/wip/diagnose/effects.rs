//! The WIP's catalogue of unmodelled effects (docs/formats.md, "Effect names") as
//! extensions of the one WIP model: each effect changes a parameter of [`Wip`], the voltage
//! the drivers apply, an external force, the friction law, or a sensor reading. Nothing here
//! copies the model; the equations of motion stay those derived by `dmech` from `ℓ`, `A` and
//! the forcing (the closed form, checked against them).
//!
//! The robot's own parameters that a calibration may move ([`CALIBRATED`]) are parameters
//! of the catalogue too; the `friction` and `payload` effects free two of them each.

use super::super::params::WipParams;
use super::super::Wip;
use super::plant::Channel;
use crate::diagnose::model::{Catalogue, ParamSpec};
use crate::diagnose::ReadingFamily;
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
    StickSlip,
    TiltFilter,
    GearBacklash,
    ReversalLockout,
    /// A generic hypothesis on a reading (`crate::diagnose::readings`): an offset or a
    /// scale of the channel's reading.
    Reading(ReadingFamily, Channel),
}

/// `[concat!(pre, channel, post); 9]` over the WIP's channels in [`Channel::ALL`]'s order.
macro_rules! per_channel {
    ($pre:literal, $post:literal) => {
        [
            concat!($pre, "x", $post),
            concat!($pre, "y", $post),
            concat!($pre, "theta", $post),
            concat!($pre, "alpha", $post),
            concat!($pre, "v_alpha", $post),
            concat!($pre, "phiR_rel", $post),
            concat!($pre, "phiL_rel", $post),
            concat!($pre, "iR", $post),
            concat!($pre, "iL", $post),
        ]
    };
}

/// `reading_offset:<channel>` and `reading_scale:<channel>`, by channel, as
/// [`ReadingFamily::effect_name`] builds them (a unit test checks the two agree; the
/// names must be `'static` for [`Effect::name`]).
static READING_NAMES: [[&str; 9]; 2] = [
    per_channel!("reading_offset:", ""),
    per_channel!("reading_scale:", ""),
];

/// Their parameters' names, as [`ReadingFamily::param_name`] builds them.
static READING_PARAMS: [[&str; 9]; 2] = [per_channel!("", "_offset"), per_channel!("", "_scale")];

fn family_row(f: ReadingFamily) -> usize {
    match f {
        ReadingFamily::Offset => 0,
        ReadingFamily::Scale => 1,
    }
}

impl Effect {
    pub const ALL: [Effect; 12] = [
        Effect::TiltOffset,
        Effect::FloorSlope,
        Effect::InputDelay,
        Effect::VoltageGain,
        Effect::Friction,
        Effect::WheelRadiusAsymmetry,
        Effect::Payload,
        Effect::DeadZone,
        Effect::StickSlip,
        Effect::TiltFilter,
        Effect::GearBacklash,
        Effect::ReversalLockout,
    ];

    /// The generic reading hypotheses the WIP's plant declares
    /// ([`super::plant::declare_readings`]), in the catalogue's order after [`Effect::ALL`]:
    /// a scale on every channel, an offset on the heading, the tilt rate and the currents
    /// (none on the positions and wheel angles, which a window's state absorbs, nor on the
    /// tilt, whose offset is `tilt_offset`).
    pub const READINGS: [Effect; 13] = {
        use Channel::*;
        use ReadingFamily::{Offset, Scale};
        [
            Effect::Reading(Scale, X),
            Effect::Reading(Scale, Y),
            Effect::Reading(Offset, Theta),
            Effect::Reading(Scale, Theta),
            Effect::Reading(Scale, Alpha),
            Effect::Reading(Offset, VAlpha),
            Effect::Reading(Scale, VAlpha),
            Effect::Reading(Scale, PhiRRel),
            Effect::Reading(Scale, PhiLRel),
            Effect::Reading(Offset, IR),
            Effect::Reading(Scale, IR),
            Effect::Reading(Offset, IL),
            Effect::Reading(Scale, IL),
        ]
    };

    /// Every effect of the WIP's plant: the catalogue's, then the reading hypotheses.
    pub fn all() -> impl Iterator<Item = Effect> {
        Effect::ALL.into_iter().chain(Effect::READINGS)
    }

    /// The effect at index `e` of the WIP plant's catalogue.
    pub fn at(e: usize) -> Option<Effect> {
        Effect::all().nth(e)
    }

    /// The name used in `diagnosis.json` and by `wip generate --effect`.
    pub fn name(self) -> &'static str {
        match self {
            Effect::Reading(f, c) => READING_NAMES[family_row(f)][c.index()],
            Effect::TiltOffset => "tilt_offset",
            Effect::FloorSlope => "floor_slope",
            Effect::InputDelay => "input_delay",
            Effect::VoltageGain => "voltage_gain",
            Effect::Friction => "friction",
            Effect::WheelRadiusAsymmetry => "wheel_radius_asymmetry",
            Effect::Payload => "payload",
            Effect::DeadZone => "dead_zone",
            Effect::StickSlip => "stick_slip",
            Effect::TiltFilter => "tilt_filter",
            Effect::GearBacklash => "gear_backlash",
            Effect::ReversalLockout => "reversal_lockout",
        }
    }

    pub fn from_name(name: &str) -> Option<Effect> {
        Effect::all().find(|e| e.name() == name)
    }

    /// Parameter names (the keys of `diagnosis.json`), in the catalogue's order.
    pub fn parameter_names(self) -> &'static [&'static str] {
        match self {
            Effect::Reading(f, c) => {
                std::slice::from_ref(&READING_PARAMS[family_row(f)][c.index()])
            }
            Effect::TiltOffset => &["b_rad"],
            Effect::FloorSlope => &["slope_x_rad", "slope_y_rad"],
            Effect::InputDelay => &["delay_s"],
            Effect::VoltageGain => &["gain"],
            Effect::Friction => &["d_v", "d_c"],
            Effect::WheelRadiusAsymmetry => &["r_R_m", "r_L_m"],
            Effect::Payload => &["m_b", "l"],
            Effect::DeadZone => &["u0_V"],
            Effect::StickSlip => &["f_static_Nm", "w_stribeck"],
            Effect::TiltFilter => &["accel_weight"],
            Effect::GearBacklash => &["backlash_rad"],
            Effect::ReversalLockout => &["lockout_s"],
        }
    }

    pub fn n_params(self) -> usize {
        self.parameter_names().len()
    }

    /// The effect's index in the catalogue of the WIP's plant ([`wip_catalogue`], then
    /// [`Effect::READINGS`]).
    pub fn index(self) -> usize {
        Effect::all()
            .position(|e| e == self)
            .expect("in ALL or READINGS")
    }
}

/// The reversal lockout's cost jumps wherever `T` crosses the gap between two reversals
/// of the command, so its fit first scans `LOCKOUT_START · (1..=LOCKOUT_GRID)`: 10 ms steps
/// up to 0.25 s, beyond which a balancing robot hardly stays up (a lockout of zero locks
/// no step, and its derivative vanishes there).
const LOCKOUT_START: f64 = 0.01;
const LOCKOUT_GRID: usize = 25;

/// The robot's own parameters a calibration may move (keys of the parameter file), and a
/// typical relative change of each.
pub const CALIBRATED: [&str; 10] = [
    "m_b", "l", "I_byy", "I_wyy", "r", "I_m", "k_e", "R_m", "d_v", "d_c",
];

/// The parameter value of a [`WipParams`] key.
pub fn param_value(p: &WipParams, key: &str) -> f64 {
    let mut q = *p;
    let v = q
        .named_mut()
        .into_iter()
        .find(|(k, _)| *k == key)
        .map(|(_, v)| *v);
    v.unwrap_or_else(|| panic!("no parameter {key}"))
}

/// A robot parameter as a catalogue parameter: fitted in `ln θ`; admissible within a
/// factor of 4 of the file's value unless the effect that frees it says otherwise.
fn own(key: &str, p: &WipParams, plausible: Option<(f64, f64)>) -> ParamSpec {
    let v = param_value(p, key);
    let range = plausible.unwrap_or((v / 4.0, v * 4.0));
    let mut s = ParamSpec::positive(key, v, 0.2, range);
    if v <= 0.0 {
        // A parameter the file sets to zero cannot be fitted in its logarithm.
        s = ParamSpec::linear(key, v, 1e-3, (0.0, range.1.max(1e-3)));
    }
    s
}

/// The catalogue of the WIP with parameters `p`: every effect's parameters with their
/// nominal values (the effect absent), scales, bounds and physically plausible ranges:
/// - tilt offset and floor slope: at most 0.3 rad (17°; a robot mounted or driven further
///   off is not "balancing with an offset");
/// - input delay: at most 0.1 s (ten 100 Hz control steps; the robot would not balance);
/// - voltage gain: 0.3–3 (a driver or battery off by more is a wiring error);
/// - friction: `d_c` up to the motor's stall torque at 12 V, `n_wm k_e 12/R_m` (the wheels
///   could not turn); `d_v` up to ten times the back-EMF damping `n_wm² k_e²/R_m`;
/// - wheel radii: within ±25 % of `r` (a different wheel, not an asymmetry);
/// - payload: body mass 0.5–2 × `m_b` (a payload cannot weigh more than the robot), height
///   of the centre of mass 0.2–5 × `l` and at most 0.5 m;
/// - dead zone: at most 3 V;
/// - stick-slip: breakaway torque up to the stall torque at 12 V, Stribeck speed
///   0.005–20 rad/s;
/// - tilt filter: the accelerometer's weight per sample in `[0, 1]` (1: no filter);
/// - gear backlash: at most 0.2 rad (11°) at the wheel;
/// - reversal lockout: at most 0.5 s (a balancing robot whose motors may not reverse for
///   longer falls);
/// - the other calibrated parameters: within a factor 4 of the file's value (a robot off by
///   more is another robot).
pub fn wip_catalogue(p: &WipParams) -> Catalogue {
    let mut cat = Catalogue::default();
    let stall = p.n_wm * p.k_e * 12.0 / p.R_m;
    let emf = p.n_wm * p.n_wm * p.k_e * p.k_e / p.R_m;
    let lin = |n: &str, nominal: f64, scale: f64, range: (f64, f64)| {
        ParamSpec::linear(n, nominal, scale, range)
    };
    let add = |cat: &mut Catalogue, e: Effect, specs: Vec<ParamSpec>| {
        let idx: Vec<usize> = specs
            .into_iter()
            .map(|s| cat.param_index(&s.name).unwrap_or_else(|| cat.param(s)))
            .collect();
        cat.effect(e.name(), idx);
    };
    // Own parameters first, so that effects freeing them share the entries.
    let d_v = own("d_v", p, Some((0.0, 10.0 * emf)));
    let d_c = own("d_c", p, Some((0.0, stall)));
    let m_b = own("m_b", p, Some((0.5 * p.m_b, 2.0 * p.m_b)));
    let l = own("l", p, Some((0.2 * p.l, (5.0 * p.l).min(0.5))));
    for s in [m_b, l, d_v, d_c] {
        cat.param(s);
    }
    for key in CALIBRATED {
        if cat.param_index(key).is_none() {
            cat.param(own(key, p, None));
        }
    }
    cat.calibration = CALIBRATED
        .iter()
        .filter_map(|k| cat.param_index(k))
        .filter(|&i| cat.params[i].log)
        .collect();
    for e in Effect::ALL {
        let names = e.parameter_names();
        let specs = match e {
            Effect::TiltOffset => vec![lin(names[0], 0.0, 0.01, (-0.3, 0.3))],
            Effect::FloorSlope => vec![
                lin(names[0], 0.0, 0.02, (-0.3, 0.3)),
                lin(names[1], 0.0, 0.02, (-0.3, 0.3)),
            ],
            Effect::InputDelay => vec![lin(names[0], 0.0, 0.01, (0.0, 0.1))],
            Effect::VoltageGain => {
                let mut s = lin(names[0], 1.0, 0.1, (0.3, 3.0));
                s.bounds = (0.05, 20.0);
                vec![s]
            }
            Effect::Friction | Effect::Payload => names
                .iter()
                .map(|n| cat.params[cat.param_index(n).expect("own parameter")].clone())
                .collect(),
            Effect::WheelRadiusAsymmetry => (0..2)
                .map(|j| {
                    let mut s = lin(names[j], p.r, 0.03 * p.r, (0.75 * p.r, 1.25 * p.r));
                    s.bounds = (0.5 * p.r, 2.0 * p.r);
                    s
                })
                .collect(),
            Effect::DeadZone => {
                let mut s = lin(names[0], 0.0, 0.2, (0.0, 3.0));
                s.bounds = (0.0, 10.0);
                vec![s]
            }
            Effect::StickSlip => {
                let mut f = lin(names[0], 0.0, 0.5 * p.d_c.max(1e-3), (0.0, stall));
                f.start = 1.5 * p.d_c.max(1e-3);
                f.bounds = (0.0, 2.0 * stall);
                let mut w = lin(names[1], 0.3, 0.1, (0.005, 20.0));
                w.bounds = (0.002, 50.0);
                vec![f, w]
            }
            Effect::TiltFilter => vec![lin(names[0], 1.0, 0.05, (0.0, 1.0))],
            Effect::GearBacklash => {
                let mut s = lin(names[0], 0.0, 0.01, (0.0, 0.2));
                s.bounds = (0.0, 0.5);
                vec![s]
            }
            Effect::ReversalLockout => {
                let mut s = lin(names[0], 0.0, 0.02, (0.0, 0.5));
                s.start = LOCKOUT_START;
                s.sampled_time = true;
                s.start_grid = (0..LOCKOUT_GRID)
                    .map(|i| LOCKOUT_START * (1 + i) as f64)
                    .collect();
                s.bounds = (0.0, 1.0);
                vec![s]
            }
            Effect::Reading(..) => unreachable!("not in Effect::ALL"),
        };
        add(&mut cat, e, specs);
    }
    cat
}

/// Where each parameter of [`wip_catalogue`] sits in the full parameter vector.
#[derive(Clone, Debug)]
pub struct Layout {
    own: Vec<(usize, usize)>,
    b: usize,
    slope: [usize; 2],
    delay: usize,
    gain: usize,
    radii: [usize; 2],
    dead_zone: usize,
    stick: [usize; 2],
    accel_weight: usize,
    backlash: usize,
    lockout: usize,
    /// The file's wheel radius (the radius effect's values are relative to it).
    r_file: f64,
}

impl Layout {
    pub fn new(cat: &Catalogue, p: &WipParams) -> Self {
        let at = |n: &str| {
            cat.param_index(n)
                .unwrap_or_else(|| panic!("catalogue has {n}"))
        };
        let mut q = *p;
        let own = q
            .named_mut()
            .into_iter()
            .enumerate()
            .filter_map(|(i, (k, _))| cat.param_index(k).map(|j| (i, j)))
            .collect();
        Layout {
            own,
            b: at("b_rad"),
            slope: [at("slope_x_rad"), at("slope_y_rad")],
            delay: at("delay_s"),
            gain: at("gain"),
            radii: [at("r_R_m"), at("r_L_m")],
            dead_zone: at("u0_V"),
            stick: [at("f_static_Nm"), at("w_stribeck")],
            accel_weight: at("accel_weight"),
            backlash: at("backlash_rad"),
            lockout: at("lockout_s"),
            r_file: p.r,
        }
    }

    /// Where the reversal lockout's `lockout_s` sits in the parameter vector.
    pub fn lockout(&self) -> usize {
        self.lockout
    }

    /// The extension with the parameter vector `theta` on the robot `base`.
    pub fn extension<T: Real>(&self, base: &WipParams, theta: &[T]) -> ModelExtension<T> {
        let mut params = base.map(T::from);
        {
            let slots = params_slots(&mut params);
            for &(i, j) in &self.own {
                *slots[i] = theta[j];
            }
        }
        let rf = T::from(self.r_file);
        ModelExtension {
            params,
            tilt_offset: theta[self.b],
            slope: [theta[self.slope[0]], theta[self.slope[1]]],
            delay: theta[self.delay],
            gain: theta[self.gain],
            radius_offsets: [theta[self.radii[0]] - rf, theta[self.radii[1]] - rf],
            dead_zone: theta[self.dead_zone],
            stick: [theta[self.stick[0]], theta[self.stick[1]]],
            accel_weight: theta[self.accel_weight],
            backlash: theta[self.backlash],
            lockout: theta[self.lockout],
        }
    }

    /// A full parameter vector with the effects `set` (values in the order of
    /// [`Effect::parameter_names`]) on top of the nominal values.
    pub fn theta_with(&self, cat: &Catalogue, set: &[(Effect, Vec<f64>)]) -> Vec<f64> {
        let mut theta = cat.nominal();
        for (e, v) in set {
            for (&p, &x) in cat.effects[e.index()].params.iter().zip(v) {
                theta[p] = x;
            }
        }
        theta
    }
}

/// Mutable references to every field of a generic [`WipParams`], in the order of
/// [`WipParams::named_mut`].
fn params_slots<T>(p: &mut WipParams<T>) -> [&mut T; 22] {
    [
        &mut p.g,
        &mut p.m_b,
        &mut p.I_bxx,
        &mut p.I_byy,
        &mut p.I_bzz,
        &mut p.m_w,
        &mut p.I_wxx,
        &mut p.I_wyy,
        &mut p.I_wzz,
        &mut p.l,
        &mut p.r,
        &mut p.d,
        &mut p.d_v,
        &mut p.d_c,
        &mut p.d_0,
        &mut p.I_m,
        &mut p.I_g,
        &mut p.n_wm,
        &mut p.n_wg,
        &mut p.k_e,
        &mut p.L_m,
        &mut p.R_m,
    ]
}

/// The model with every effect's parameters; at the catalogue's nominal values it is the
/// paper's model with the parameter file's values. Several effects can be active at once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelExtension<T> {
    /// The robot's own parameters (calibrated, or with a payload or friction effect).
    pub params: WipParams<T>,
    /// The tilt sensor reads `α + b`.
    pub tilt_offset: T,
    /// Floor inclination `(σx, σy)`: the floor rises along +x by `σx` and along +y by `σy`.
    pub slope: [T; 2],
    /// The drivers apply the voltage this much later (on top of the electrical lag).
    pub delay: T,
    /// The drivers apply `κ u`.
    pub gain: T,
    /// `(δ_R, δ_L)`: the wheels' radii minus `r`.
    pub radius_offsets: [T; 2],
    /// Dead zone half-width `u0`.
    pub dead_zone: T,
    /// Stick-slip: breakaway torque `f_s` (0: the model's regularised Coulomb law) and
    /// Stribeck speed `w_s`.
    pub stick: [T; 2],
    /// The tilt reading is a complementary filter with this accelerometer weight per
    /// sample (1: the tilt itself).
    pub accel_weight: T,
    /// Lost motion between the motor (encoder) and the wheel, rad at the wheel.
    pub backlash: T,
    /// The firmware holds a reversed command at zero volts until this long after the last
    /// accepted reversal (`super::reversal_lockout`; 0: no lockout).
    pub lockout: T,
}

impl<T: Real> ModelExtension<T> {
    /// No effect: the paper's model with parameters `p`.
    pub fn nominal(p: &WipParams) -> Self {
        let z = T::zero();
        ModelExtension {
            params: p.map(T::from),
            tilt_offset: z,
            slope: [z; 2],
            delay: z,
            gain: T::one(),
            radius_offsets: [z; 2],
            dead_zone: z,
            stick: [z, T::from(0.3)],
            accel_weight: T::one(),
            backlash: z,
            lockout: z,
        }
    }

    /// The WIP whose parameters carry the effects (`P = T`: dual parameters give
    /// derivatives with respect to them).
    pub fn system(&self) -> Wip<T> {
        let mut w = Wip::new(self.params);
        w.wheel_radius_offsets = self.radius_offsets;
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

    /// The tilt sensor's reading of the tilt `α` (from the floor's normal), before any
    /// filter.
    pub fn tilt_reading(&self, alpha: T) -> T {
        alpha + self.tilt_offset
    }

    /// Whether the stick-slip law replaces the model's regularised Coulomb friction.
    pub fn sticks(&self) -> bool {
        self.stick[0].re() > 0.0
    }

    /// The static limit of the stick-slip law: the holding torque a wheel at rest relative
    /// to the body can take, at least the Coulomb level.
    pub fn static_limit(&self) -> T {
        let (fs, dc) = (self.stick[0], self.params.d_c);
        if fs.re() > dc.re() {
            fs
        } else {
            dc
        }
    }

    /// The slip friction of the stick-slip law at relative speed `w` moving in direction
    /// `sign` (±1): `d_v w + sign (d_c + (f_s − d_c)⁺ exp(−(w/w_s)²))`.
    pub fn slip_friction(&self, w: T, sign: f64) -> T {
        let p = &self.params;
        let excess = self.static_limit() - p.d_c;
        let ws = self.stick[1];
        let x = w / ws;
        p.d_v * w + (p.d_c + excess * (-(x * x)).exp()) * sign
    }

    /// The encoder's offset from the wheel through the gear's lost motion: the motor leads
    /// the wheel by half the backlash in the direction of the torque it transmits (the
    /// motor torque `k_e n_wm i`), smoothed over a tenth of the Coulomb level.
    pub fn backlash_offset(&self, i: T) -> T {
        let p = &self.params;
        let scale = p.d_c * 0.1 + T::from(1e-4);
        let x = p.k_e * p.n_wm * i / scale;
        self.backlash * 0.5 * crate::wip::model::tanh_saturating(x)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::Plant;

    /// The WIP plant's catalogue lists [`Effect::all`] in order, with their parameter
    /// names, and the reading hypotheses' static names are those the generic machinery
    /// builds.
    #[test]
    fn effect_names_and_indices_match_the_catalogue() {
        let plant = super::super::WipPlant::new(WipParams::default());
        let cat = plant.catalogue();
        let all: Vec<Effect> = Effect::all().collect();
        assert_eq!(cat.effects.len(), all.len());
        for (i, e) in all.iter().enumerate() {
            assert_eq!(cat.effects[i].name, e.name());
            assert_eq!(e.index(), i);
            assert_eq!(Effect::from_name(e.name()), Some(*e));
            let names: Vec<&str> = cat.effects[i]
                .params
                .iter()
                .map(|&p| cat.params[p].name.as_str())
                .collect();
            assert_eq!(names, e.parameter_names());
            if let Effect::Reading(f, c) = e {
                assert_eq!(e.name(), f.effect_name(c.name()));
                assert_eq!(cat.effects[i].reading, Some(c.index()));
            }
        }
    }
}

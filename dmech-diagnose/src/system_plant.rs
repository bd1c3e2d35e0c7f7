//! The [`Plant`] of a system described by `dmech`'s traits: the user declares the readings
//! (a measurement map), the inputs and the catalogue, and the prediction comes from the
//! system's own continuous equations of motion (`dmech::continuous`, derived from `ℓ`, the
//! connection and the forcing), integrated by the classical Runge–Kutta method in the
//! fit's scalar, so that one pass in dual numbers gives the derivatives with respect to the
//! window's initial state and the free parameters. No predictor is written by hand.
//!
//! The state of a window is `z = (coords(g), s, v)`: the group's coordinates
//! (`LieGroup::coordinates`), the shape and the shape velocity, less the shape positions
//! that nothing reads ([`ObservedSystem::unread_shape`]). Between two rows of the log
//! the command of the earlier row is held (zero-order hold) and the step is divided into
//! [`SystemPlant::substeps`] Runge–Kutta steps.

use crate::{
    ActuatorHypotheses, Catalogue, ChannelSpec, FitScalar, Indicator, MeasuredLog, Plant,
    ReadingHypotheses,
};
use dmech::continuous::coordinate_rate;
use dmech::PrincipalKinematicSystem;
use dmech_lie::LieGroup;
use nalgebra::SVector;

/// Where a reading is taken: the group's coordinates, the shape, the shape velocity, its
/// acceleration and the input, in the prediction's scalar.
pub struct ObservedPoint<'a, T, const NS: usize, const NU: usize> {
    /// The coordinates of the group element (`LieGroup::coordinates`).
    pub coords: &'a [T],
    /// The body velocity `ξ = −A(s) v`.
    pub xi: &'a [T],
    /// The shape `s`.
    pub s: &'a SVector<T, NS>,
    /// The shape velocity `v = ṡ`.
    pub v: &'a SVector<T, NS>,
    /// The shape acceleration `v̇` under the input held from this row.
    pub a: &'a SVector<T, NS>,
    /// The input of this row, as the system receives it ([`ObservedSystem::input`]).
    pub u: &'a SVector<T, NU>,
}

/// A robot described by the system traits, with what `diagnose` needs besides: its
/// readings, its inputs and the effects it may free.
///
/// `theta` is always the whole catalogue's parameter vector ([`Catalogue::params`]), every
/// parameter at its nominal value except those a candidate frees; at nominal values the
/// model is the robot's own.
pub trait ObservedSystem<const DOF: usize, const NS: usize, const NU: usize>: Sync {
    /// The system with its parameters in the prediction's scalar.
    type System<T: FitScalar>: PrincipalKinematicSystem<DOF, NS, NU, Param = T>;
    /// The measured channels, in the order [`ObservedSystem::measure`] returns them.
    fn channels(&self) -> &[ChannelSpec];
    /// The names of the log's input columns.
    fn inputs(&self) -> &[String];
    /// The parameters and effects the diagnosis may free (the robot's own, and the generic
    /// reading hypotheses if it declares them with [`ReadingHypotheses::declare`]).
    fn catalogue(&self) -> &Catalogue;
    /// The system under the parameters `theta`.
    fn system<T: FitScalar>(&self, theta: &[T]) -> Self::System<T>;
    /// The measurement map: one reading per channel at a point of the motion.
    fn measure<T: FitScalar>(&self, at: &ObservedPoint<'_, T, NS, NU>, theta: &[T]) -> Vec<T>;
    /// A first guess of the state `z = (coords(g), s, v)` at row `start` from the readings
    /// of the window `start..start + len`.
    fn initial_state(&self, log: &MeasuredLog, start: usize, len: usize) -> Vec<f64>;
    /// The input the system receives from a row's commands (an actuator's gain or offset
    /// goes here). Default: the commands themselves.
    fn input<T: FitScalar>(&self, command: &[f64], _theta: &[T]) -> SVector<T, NU> {
        SVector::from_fn(|i, _| T::from(command[i]))
    }
    /// A generalised force on the shape that the system's forcing leaves out (an effect
    /// such as a friction the catalogue frees). Default: none.
    fn shape_force<T: FitScalar>(
        &self,
        _s: &SVector<T, NS>,
        _v: &SVector<T, NS>,
        _u: &SVector<T, NU>,
        _theta: &[T],
    ) -> SVector<T, NS> {
        SVector::zeros()
    }
    /// `(state, channel)` pairs of [`Plant::additive`], state indices into the whole
    /// `z = (coords(g), s, v)`.
    fn additive(&self) -> &[(usize, usize)] {
        &[]
    }
    /// Shape positions that neither the equations of motion (they must be among the
    /// system's `ignorable_shape`) nor any reading reads, such as a motor's charge: a
    /// window cannot determine them, so they are held at zero and not fitted. Default:
    /// none.
    fn unread_shape(&self) -> &[usize] {
        &[]
    }
    /// Operating conditions the residual may follow. Default: none (the diagnosis adds a
    /// trend in time).
    fn conditions(&self, _log: &MeasuredLog) -> Vec<Indicator> {
        Vec::new()
    }
    /// The generic reading hypotheses declared into [`ObservedSystem::catalogue`].
    fn reading_hypotheses(&self) -> Option<&ReadingHypotheses> {
        None
    }
    /// The generic input hypotheses declared into [`ObservedSystem::catalogue`], applied
    /// to [`ObservedSystem::input`]'s result.
    fn actuator_hypotheses(&self) -> Option<&ActuatorHypotheses> {
        None
    }
}

/// The [`Plant`] of an [`ObservedSystem`].
pub struct SystemPlant<O, const DOF: usize, const NS: usize, const NU: usize> {
    observed: O,
    substeps: usize,
    n_coords: usize,
    /// The components of `z = (coords(g), s, v)` a window fits (all but the unread shape
    /// positions), in order.
    fitted: Vec<usize>,
    /// [`ObservedSystem::additive`] in the fitted state's indices.
    additive: Vec<(usize, usize)>,
}

type Group<O, T, const DOF: usize, const NS: usize, const NU: usize> = <<O as ObservedSystem<
    DOF,
    NS,
    NU,
>>::System<T> as PrincipalKinematicSystem<
    DOF,
    NS,
    NU,
>>::Group<T>;

impl<O, const DOF: usize, const NS: usize, const NU: usize> SystemPlant<O, DOF, NS, NU>
where
    O: ObservedSystem<DOF, NS, NU>,
{
    /// The plant of `observed`, each step of the log divided into `substeps` Runge–Kutta
    /// steps (at least one).
    ///
    /// # Panics
    /// If [`ObservedSystem::unread_shape`] names a shape position that the system's
    /// `ignorable_shape` does not (a wrong declaration: holding it at zero would change
    /// the motion).
    pub fn new(observed: O, substeps: usize) -> Self {
        let n_coords = Group::<O, f64, DOF, NS, NU>::identity().coordinates().len();
        let nominal = observed.catalogue().nominal();
        let ignorable = observed.system::<f64>(&nominal).ignorable_shape().to_vec();
        let unread = observed.unread_shape();
        for i in unread {
            assert!(
                ignorable.contains(i),
                "unread shape position {i} is not among the system's ignorable_shape"
            );
        }
        let fitted: Vec<usize> = (0..n_coords + 2 * NS)
            .filter(|&i| !(i >= n_coords && i < n_coords + NS && unread.contains(&(i - n_coords))))
            .collect();
        let additive = observed
            .additive()
            .iter()
            .filter_map(|&(i, c)| fitted.iter().position(|&f| f == i).map(|j| (j, c)))
            .collect();
        SystemPlant {
            observed,
            substeps: substeps.max(1),
            n_coords,
            fitted,
            additive,
        }
    }

    /// The system it observes.
    pub fn observed(&self) -> &O {
        &self.observed
    }

    /// Runge–Kutta steps per step of the log.
    pub fn substeps(&self) -> usize {
        self.substeps
    }

    /// The number of group coordinates at the head of `z = (coords(g), s, v)`.
    pub fn n_coords(&self) -> usize {
        self.n_coords
    }

    /// The whole state from a window's fitted one: the unread shape positions at zero.
    fn expand<T: FitScalar>(&self, z: &[T]) -> Vec<T> {
        let mut full = vec![T::zero(); self.n_coords + 2 * NS];
        for (&i, &x) in self.fitted.iter().zip(z) {
            full[i] = x;
        }
        full
    }

    /// The readings the model predicts over the whole of `log` from the state
    /// `z0 = (coords(g), s, v)` at its first row, with the commands of the log and the
    /// parameters `theta` (reading hypotheses applied): a simulation, e.g. to generate a
    /// log with a hidden effect. `None` if the model cannot be simulated there.
    pub fn simulate(&self, log: &MeasuredLog, z0: &[f64], theta: &[f64]) -> Option<Vec<f64>> {
        let fitted: Vec<f64> = self.fitted.iter().map(|&i| z0[i]).collect();
        let mut y = self.predict(log, 0, log.len(), &fitted, theta)?;
        if let Some(r) = self.observed.reading_hypotheses() {
            r.apply(&mut y, self.observed.channels().len(), theta);
        }
        Some(y)
    }

    fn split<T: FitScalar>(&self, z: &[T]) -> (SVector<T, NS>, SVector<T, NS>) {
        let m = self.n_coords;
        (
            SVector::from_fn(|i, _| z[m + i]),
            SVector::from_fn(|i, _| z[m + NS + i]),
        )
    }

    /// `ż = (d coords(g)/dt, v, v̇)` and `ξ`.
    fn rate<T: FitScalar>(
        &self,
        sys: &O::System<T>,
        z: &[T],
        u: &SVector<T, NU>,
        theta: &[T],
    ) -> Option<(Vec<T>, SVector<T, DOF>, SVector<T, NS>)> {
        let (s, v) = self.split(z);
        let g = Group::<O, T, DOF, NS, NU>::from_coordinates(&z[..self.n_coords])?;
        let xi = -(sys.connection(&s) * v);
        let f = self.observed.shape_force(&s, &v, u, theta);
        let a = T::shape_acceleration::<O::System<T>, DOF, NS, NU>(sys, &s, &v, u, &f)?;
        let mut dz = coordinate_rate::<_, T, DOF>(&g, &xi);
        dz.extend(v.iter().copied());
        dz.extend(a.iter().copied());
        Some((dz, xi, a))
    }

    /// One classical Runge–Kutta step of length `dt` with the input held.
    fn rk4<T: FitScalar>(
        &self,
        sys: &O::System<T>,
        z: &[T],
        k1: &[T],
        u: &SVector<T, NU>,
        theta: &[T],
        dt: f64,
    ) -> Option<Vec<T>> {
        let at =
            |k: &[T], c: f64| -> Vec<T> { z.iter().zip(k).map(|(&x, &d)| x + d * c).collect() };
        let k2 = self.rate(sys, &at(k1, 0.5 * dt), u, theta)?.0;
        let k3 = self.rate(sys, &at(&k2, 0.5 * dt), u, theta)?.0;
        let k4 = self.rate(sys, &at(&k3, dt), u, theta)?.0;
        Some(
            (0..z.len())
                .map(|i| z[i] + (k1[i] + (k2[i] + k3[i]) * 2.0 + k4[i]) * (dt / 6.0))
                .collect(),
        )
    }
}

impl<O, const DOF: usize, const NS: usize, const NU: usize> Plant for SystemPlant<O, DOF, NS, NU>
where
    O: ObservedSystem<DOF, NS, NU>,
{
    fn channels(&self) -> &[ChannelSpec] {
        self.observed.channels()
    }
    fn inputs(&self) -> &[String] {
        self.observed.inputs()
    }
    fn catalogue(&self) -> &Catalogue {
        self.observed.catalogue()
    }
    fn state_dim(&self) -> usize {
        self.fitted.len()
    }
    fn additive(&self) -> &[(usize, usize)] {
        &self.additive
    }
    fn history(&self, _h: f64) -> usize {
        0
    }
    fn initial_state(&self, log: &MeasuredLog, start: usize, len: usize) -> Vec<f64> {
        let full = self.observed.initial_state(log, start, len);
        self.fitted.iter().map(|&i| full[i]).collect()
    }
    fn predict<T: FitScalar>(
        &self,
        log: &MeasuredLog,
        start: usize,
        len: usize,
        z0: &[T],
        theta: &[T],
    ) -> Option<Vec<T>> {
        let sys = self.observed.system(theta);
        let n_channels = self.observed.channels().len();
        let dt = log.h / self.substeps as f64;
        let mut z = self.expand(z0);
        let mut out = Vec::with_capacity(len * n_channels);
        for k in start..start + len {
            let mut u = self.observed.input(log.input(k), theta);
            if let Some(a) = self.observed.actuator_hypotheses() {
                a.apply(u.as_mut_slice(), theta);
            }
            let (mut dz, xi, a) = self.rate(&sys, &z, &u, theta)?;
            let (s, v) = self.split(&z);
            let at = ObservedPoint {
                coords: &z[..self.n_coords],
                xi: xi.as_slice(),
                s: &s,
                v: &v,
                a: &a,
                u: &u,
            };
            let row = self.observed.measure(&at, theta);
            if row.len() != n_channels {
                return None;
            }
            out.extend(row);
            if k + 1 == start + len {
                break;
            }
            for sub in 0..self.substeps {
                if sub > 0 {
                    dz = self.rate(&sys, &z, &u, theta)?.0;
                }
                z = self.rk4(&sys, &z, &dz, &u, theta, dt)?;
            }
        }
        out.iter().all(|y| y.re().is_finite()).then_some(out)
    }
    fn conditions(&self, log: &MeasuredLog) -> Vec<Indicator> {
        self.observed.conditions(log)
    }
    fn readings(&self) -> Option<&ReadingHypotheses> {
        self.observed.reading_hypotheses()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ParamSpec;
    use dmech::Lift;
    use dmech_lie::rn::Rn;
    use dmech_lie::Real;
    use nalgebra::SMatrix;
    use num_dual::DualSVec64;

    const RADIUS: f64 = 0.05;
    const WHEEL_INERTIA: f64 = 2e-4;
    const GAIN: f64 = 0.2;
    const VISCOUS: f64 = 0.01;

    /// A wheel of radius `r` rolling a cart of mass `m` along a line: `G = ℝ`, the wheel
    /// angle the shape, `ξ = r φ̇`, `ℓ = ½ m ξ² + ½ J φ̇²`, forcing `k u − c φ̇`. Its motion
    /// under a held input has the closed form `φ̇(t) = φ̇∞ + (φ̇₀ − φ̇∞) e^{−t/τ}` with
    /// `τ = (m r² + J)/c`, `φ̇∞ = k u / c`.
    struct Cart<T> {
        mass: T,
    }

    impl<T: FitScalar> PrincipalKinematicSystem<1, 1, 1> for Cart<T> {
        type Param = T;
        type Group<U: Real> = Rn<U, 1>;
        fn reduced_lagrangian<U: Lift<T>>(
            &self,
            _s: &SVector<U, 1>,
            v: &SVector<U, 1>,
            xi: &SVector<U, 1>,
        ) -> U {
            (U::lift(self.mass) * xi[0] * xi[0] + v[0] * v[0] * WHEEL_INERTIA) * 0.5
        }
        fn connection<U: Lift<T>>(&self, _s: &SVector<U, 1>) -> SMatrix<U, 1, 1> {
            SMatrix::from_element(U::from(-RADIUS))
        }
        fn forcing<U: Lift<T>>(
            &self,
            _s: &SVector<U, 1>,
            v: &SVector<U, 1>,
            u: &SVector<U, 1>,
        ) -> SVector<U, 1> {
            SVector::from_element(u[0] * GAIN - v[0] * VISCOUS)
        }
    }

    /// The cart observed by its position and its wheel's speed; the mass is the catalogue's
    /// one parameter.
    struct ObservedCart {
        catalogue: Catalogue,
        channels: Vec<ChannelSpec>,
        inputs: Vec<String>,
    }

    impl ObservedCart {
        fn new() -> Self {
            let mut catalogue = Catalogue::default();
            let m = catalogue.param(ParamSpec::positive("mass", 1.5, 0.1, (0.5, 5.0)));
            catalogue.calibration = vec![m];
            ObservedCart {
                catalogue,
                channels: vec![
                    ChannelSpec::new("x", "m", 10.0),
                    ChannelSpec::new("phi_dot", "rad/s", 1e3),
                ],
                inputs: vec!["u".into()],
            }
        }
    }

    impl ObservedSystem<1, 1, 1> for ObservedCart {
        type System<T: FitScalar> = Cart<T>;
        fn channels(&self) -> &[ChannelSpec] {
            &self.channels
        }
        fn inputs(&self) -> &[String] {
            &self.inputs
        }
        fn catalogue(&self) -> &Catalogue {
            &self.catalogue
        }
        fn system<T: FitScalar>(&self, theta: &[T]) -> Cart<T> {
            Cart { mass: theta[0] }
        }
        fn measure<T: FitScalar>(&self, at: &ObservedPoint<'_, T, 1, 1>, _: &[T]) -> Vec<T> {
            vec![at.coords[0], at.v[0]]
        }
        fn initial_state(&self, _: &MeasuredLog, _: usize, _: usize) -> Vec<f64> {
            vec![0.0; 3]
        }
    }

    /// A log of `n` rows at step `h` with the commands `u(k)` and no readings.
    fn commands(h: f64, n: usize, u: impl Fn(usize) -> f64) -> MeasuredLog {
        let mut log = MeasuredLog::empty(h, 1, 2);
        for k in 0..n {
            log.push_row(k as f64 * h, &[u(k)], &[0.0, 0.0]);
        }
        log
    }

    /// Under a held input the prediction follows the closed form, to the classical
    /// Runge–Kutta method's error: its global error after `t` is below
    /// `t/τ · (dt/τ)⁴/120 · |φ̇₀ − φ̇∞|` (the local error `(dt/τ)⁵/120` of one step on
    /// `ẏ = −y/τ`, summed over `t/dt` steps), with `τ = 0.1 s`, `dt = 5 ms`.
    #[test]
    fn prediction_follows_the_closed_form_of_a_rolling_cart() {
        let plant = SystemPlant::new(ObservedCart::new(), 2);
        let (mass, u, h, n) = (1.5, 0.7, 0.01, 200);
        let log = commands(h, n, |_| u);
        let (v0, x0) = (3.0, 0.2);
        let y = plant.predict(&log, 0, n, &[x0, 0.0, v0], &[mass]).unwrap();
        let tau = (mass * RADIUS * RADIUS + WHEEL_INERTIA) / VISCOUS;
        let v_inf = GAIN * u / VISCOUS;
        let dt = h / 2.0;
        for k in 0..n {
            let t = k as f64 * h;
            let decay = (-t / tau).exp();
            let v = v_inf + (v0 - v_inf) * decay;
            let x = x0 + RADIUS * (v_inf * t + (v0 - v_inf) * tau * (1.0 - decay));
            let bound = (t / tau) * (dt / tau).powi(4) / 120.0 * (v0 - v_inf).abs() + 1e-12;
            assert!(
                (y[2 * k + 1] - v).abs() <= bound,
                "row {k}: φ̇ {} vs {v}",
                y[2 * k + 1]
            );
            assert!(
                (y[2 * k] - x).abs() <= RADIUS * tau * bound + 1e-12,
                "row {k}: x {} vs {x}",
                y[2 * k]
            );
        }
    }

    /// The derivatives of the prediction in dual numbers (with respect to the initial state
    /// and the mass) equal central differences, within the differences' own truncation
    /// error, estimated as `|D(2δ) − D(δ)|`, plus their rounding error `ε_y/δ`, where
    /// `ε_y = 320 ε |y|` bounds the rounding of a reading computed through 320 right-hand
    /// sides (40 rows × 2 steps × 4 stages), each adding at most one rounding.
    #[test]
    fn prediction_derivatives_equal_central_differences() {
        let plant = SystemPlant::new(ObservedCart::new(), 2);
        let log = commands(0.01, 40, |k| (0.3 * k as f64).sin());
        let (z, mass) = ([0.1, 0.4, 2.0], 1.5);
        type D = DualSVec64<4>;
        let zd: Vec<D> = (0..3).map(|i| D::from(z[i]).derivative(i)).collect();
        let yd = plant
            .predict(&log, 0, 40, &zd, &[D::from(mass).derivative(3)])
            .unwrap();
        let f = |dz: [f64; 3], dm: f64| {
            let z: Vec<f64> = (0..3).map(|i| z[i] + dz[i]).collect();
            plant.predict(&log, 0, 40, &z, &[mass + dm]).unwrap()
        };
        let central = |j: usize, d: f64| -> Vec<f64> {
            let step = |s: f64| {
                let mut dz = [0.0; 3];
                if j < 3 {
                    dz[j] = s;
                }
                f(dz, if j == 3 { s } else { 0.0 })
            };
            let (p, m) = (step(d), step(-d));
            p.iter().zip(&m).map(|(a, b)| (a - b) / (2.0 * d)).collect()
        };
        for j in 0..4 {
            let delta = 1e-5;
            let (d1, d2) = (central(j, delta), central(j, 2.0 * delta));
            for (r, y) in yd.iter().enumerate() {
                let dual = y
                    .eps
                    .unwrap_generic(nalgebra::Const::<4>, nalgebra::Const::<1>)[j];
                let rounding = 320.0 * f64::EPSILON * y.re.abs().max(1.0) / delta;
                let tol = (d2[r] - d1[r]).abs() + rounding;
                assert!(
                    (dual - d1[r]).abs() <= tol,
                    "direction {j}, reading {r}: dual {dual} vs differences {}",
                    d1[r]
                );
            }
        }
    }
}

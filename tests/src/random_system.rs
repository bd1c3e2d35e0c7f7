//! Random principal-kinematic systems: random positive definite, shape-dependent inertias,
//! random smooth shape-dependent connections, random confining potentials, on any group of
//! `dmech-lie` and any shape dimension. The integrators' properties are tested over them,
//! so that nothing is checked on the WIP's special structure (constant connection) alone.
//!
//! With `z = (v, ξ) ∈ R^{NS+DOF}`:
//! ```text
//! ℓ(s, v, ξ) = ½ |C(s) z|² + ½ δ |z|² − V(s),   C(s) = C₀ + Σᵢ sin(sᵢ + ψᵢ) Cᵢ
//! V(s)       = Σᵢ ½ kᵢ sᵢ² + cᵢ (1 − cos sᵢ)
//! A(s)       = A₀ + Σᵢ sin(sᵢ + ψᵢ) Aᵢ
//! F(s, v, u) = u − d ⊙ v
//! ```
//! `ℓ` is even in the velocities, so the continuous flow is reversible; the inertia
//! `CᵀC + δI` is positive definite for every `s`; `kᵢ > 0` keeps the motion bounded. A
//! *cyclic* shape variable `j` (optional) enters neither `ℓ` nor `A`, and `A`'s column `j`
//! is zero: then `P_j = ∂ℓ/∂v_j` is conserved, exactly by both discretisations.

use dmech::{Lift, PrincipalKinematicSystem};
use dmech_lie::{LieGroup, Real, Se2, Se3, So3};
use nalgebra::{SMatrix, SVector};
use std::marker::PhantomData;

/// A family of Lie groups over every scalar (the systems' `Group<T>`).
pub trait GroupFamily<const DOF: usize> {
    type G<T: Real>: LieGroup<DOF, Scalar = T>;
    const NAME: &'static str;
}

/// SE(2): planar rigid motions.
pub struct Se2Family;
impl GroupFamily<3> for Se2Family {
    type G<T: Real> = Se2<T>;
    const NAME: &'static str = "SE(2)";
}

/// SO(3): rotations.
pub struct So3Family;
impl GroupFamily<3> for So3Family {
    type G<T: Real> = So3<T>;
    const NAME: &'static str = "SO(3)";
}

/// SE(3): rigid motions in space.
pub struct Se3Family;
impl GroupFamily<6> for Se3Family {
    type G<T: Real> = Se3<T>;
    const NAME: &'static str = "SE(3)";
}

/// What a drawn system contains.
#[derive(Clone, Copy, Debug)]
pub struct RandomSystemSpec {
    /// Damping `d ≥ 0` on every shape velocity (0: conservative).
    pub damping: f64,
    /// Make shape variable 0 cyclic (needs `NS ≥ 2`, so that something else moves the group).
    pub cyclic_first: bool,
    /// Scale of the shape-dependent parts of `C` and `A` relative to their constant parts.
    pub shape_dependence: f64,
}

/// A random system on the group family `F` with `NS` shape variables and `NS` inputs.
pub struct RandomSystem<F, const DOF: usize, const NS: usize> {
    n: usize,
    c0: Vec<f64>,
    ci: Vec<Vec<f64>>,
    phase: Vec<f64>,
    delta: f64,
    k: Vec<f64>,
    c_cos: Vec<f64>,
    a0: SMatrix<f64, DOF, NS>,
    ai: Vec<SMatrix<f64, DOF, NS>>,
    d: f64,
    _family: PhantomData<F>,
}

/// A random stage state `x = (coords(g), rest)` for the transcriptions' derivative tests:
/// `g = exp(ξ)` and `rest` with entries uniform in `[−0.5, 0.5)`, drawn in that order.
/// Returns `x` and the number of group coordinates.
pub fn random_stage_state<F, const DOF: usize, const NX: usize>(
    rng: &mut Lcg,
) -> (SVector<f64, NX>, usize)
where
    F: GroupFamily<DOF>,
{
    let pose = F::G::<f64>::exp(&SVector::<f64, DOF>::from_fn(|_, _| rng.uniform()));
    let coords = pose.coordinates();
    let nc = coords.len();
    let x = SVector::<f64, NX>::from_fn(|i, _| if i < nc { coords[i] } else { rng.uniform() });
    (x, nc)
}

pub use dmech_lie::lcg::Lcg;

impl<F, const DOF: usize, const NS: usize> RandomSystem<F, DOF, NS> {
    /// Draws a system from `seed`.
    pub fn draw(seed: u64, spec: RandomSystemSpec) -> Self {
        let mut rng = Lcg(seed ^ 0x9E37_79B9_7F4A_7C15);
        let n = NS + DOF;
        let cyclic = |i: usize| spec.cyclic_first && i == 0;
        let c0: Vec<f64> = (0..n * n)
            .map(|_| rng.uniform() * 2.0)
            .collect::<Vec<_>>()
            .into_iter()
            .enumerate()
            // A dominant diagonal keeps C₀ well conditioned.
            .map(|(idx, x)| if idx % (n + 1) == 0 { x + 1.5 } else { x })
            .collect();
        let ci = (0..NS)
            .map(|i| {
                (0..n * n)
                    .map(|_| {
                        let x = rng.uniform() * 2.0 * spec.shape_dependence;
                        if cyclic(i) {
                            0.0
                        } else {
                            x
                        }
                    })
                    .collect()
            })
            .collect();
        let phase = (0..NS)
            .map(|_| rng.range(0.0, std::f64::consts::TAU))
            .collect();
        let k = (0..NS)
            .map(|i| if cyclic(i) { 0.0 } else { rng.range(0.5, 2.0) })
            .collect();
        let c_cos = (0..NS)
            .map(|i| if cyclic(i) { 0.0 } else { rng.range(0.0, 0.5) })
            .collect();
        let col_zero = |m: &mut SMatrix<f64, DOF, NS>| {
            if spec.cyclic_first {
                m.column_mut(0).fill(0.0);
            }
        };
        let mut a0 = SMatrix::<f64, DOF, NS>::from_fn(|_, _| rng.uniform() * 1.5);
        col_zero(&mut a0);
        let ai = (0..NS)
            .map(|i| {
                let mut m = SMatrix::<f64, DOF, NS>::from_fn(|_, _| {
                    rng.uniform() * 1.5 * spec.shape_dependence
                });
                col_zero(&mut m);
                if cyclic(i) {
                    m.fill(0.0);
                }
                m
            })
            .collect();
        RandomSystem {
            n,
            c0,
            ci,
            phase,
            delta: rng.range(0.1, 0.3),
            k,
            c_cos,
            a0,
            ai,
            d: spec.damping,
            _family: PhantomData,
        }
    }
}

impl<F, const DOF: usize, const NS: usize> PrincipalKinematicSystem<DOF, NS, NS>
    for RandomSystem<F, DOF, NS>
where
    F: GroupFamily<DOF>,
{
    type Param = f64;
    type Group<T: Real> = F::G<T>;

    fn reduced_lagrangian<T: Lift<f64>>(
        &self,
        s: &SVector<T, NS>,
        v: &SVector<T, NS>,
        xi: &SVector<T, DOF>,
    ) -> T {
        let n = self.n;
        let z: Vec<T> = v.iter().chain(xi.iter()).copied().collect();
        let sines: Vec<T> = (0..NS).map(|i| (s[i] + self.phase[i]).sin()).collect();
        let mut l = T::zero();
        for r in 0..n {
            let mut cz = T::zero();
            for (c, zc) in z.iter().enumerate() {
                let mut coef = T::from(self.c0[r * n + c]);
                for (i, sin) in sines.iter().enumerate() {
                    let ci = self.ci[i][r * n + c];
                    if ci != 0.0 {
                        coef += *sin * ci;
                    }
                }
                cz += coef * *zc;
            }
            l += cz * cz * 0.5;
        }
        for zc in &z {
            l += *zc * *zc * (0.5 * self.delta);
        }
        for i in 0..NS {
            l -= s[i] * s[i] * (0.5 * self.k[i]) + (T::one() - s[i].cos()) * self.c_cos[i];
        }
        l
    }

    fn connection<T: Lift<f64>>(&self, s: &SVector<T, NS>) -> SMatrix<T, DOF, NS> {
        let mut a = self.a0.map(T::from);
        for i in 0..NS {
            let sin = (s[i] + self.phase[i]).sin();
            a += self.ai[i].map(|x| sin * x);
        }
        a
    }

    fn forcing<T: Lift<f64>>(
        &self,
        _s: &SVector<T, NS>,
        v: &SVector<T, NS>,
        u: &SVector<T, NS>,
    ) -> SVector<T, NS> {
        u - v * T::from(self.d)
    }
}

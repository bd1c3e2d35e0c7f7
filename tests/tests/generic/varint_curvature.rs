//! The variational transcription's exact constraint curvature `∇²(λᵀf + νᵀe)` by blocks
//! (momenta contracted with `ν` by a scalar dual, one second-order pass per pair of the
//! blocks the terms read) against the generic path (`Dual2` and hyper-dual numbers over
//! the whole stage vector through the transcription's dynamics and equality), on random
//! systems with shape-dependent inertia and connection, for every forcing quadrature.

use dmech::variational::ForcingQuadrature;
use dmech_lie::Real;
use dmech_ocp::nlp::derivatives::{block_hessian, StageScalar};
use dmech_ocp::transcription::variational::VarIntStages;
use dmech_tests::random_system::{
    random_stage_state, GroupFamily, Lcg, RandomSystem, RandomSystemSpec, Se2Family, Se3Family,
    So3Family,
};
use nalgebra::SVector;

/// `λᵀf + νᵀe` through the transcription's generic functions.
struct Lagrangian<'s, 'a, S, const DOF: usize, const NS: usize, const NX: usize> {
    stages: &'s VarIntStages<'a, S>,
    lambda: SVector<f64, NX>,
    nu: SVector<f64, NS>,
}

impl<F, const DOF: usize, const NS: usize, const NX: usize, const NW: usize> StageScalar<NX, NW>
    for Lagrangian<'_, '_, RandomSystem<F, DOF, NS>, DOF, NS, NX>
where
    F: GroupFamily<DOF>,
{
    fn eval<T: Real>(&self, x: &SVector<T, NX>, w: &SVector<T, NW>) -> T {
        let f = self.stages.dynamics::<T, DOF, NS, NS, NX, NW>(x, w);
        let e = self.stages.equality::<T, DOF, NS, NS, NX, NW>(x, w);
        let mut v = T::zero();
        for i in 0..NX {
            v += f[i] * self.lambda[i];
        }
        for i in 0..NS {
            v += e[i] * self.nu[i];
        }
        v
    }
}

/// The worst difference between the two, relative to `512 ε` times the largest entry:
/// both are exact second derivatives rounded along different operation orders.
fn worst_ratio<F, const DOF: usize, const NS: usize, const NX: usize, const NW: usize>(
    seed: u64,
) -> f64
where
    F: GroupFamily<DOF>,
{
    let spec = RandomSystemSpec {
        damping: 0.3,
        cyclic_first: false,
        shape_dependence: 0.5,
    };
    let sys = RandomSystem::<F, DOF, NS>::draw(seed, spec);
    let mut rng = Lcg(seed.wrapping_mul(0x5851_F42D) ^ 0x1234);
    let (x, nc) = random_stage_state::<F, DOF, NX>(&mut rng);
    assert_eq!(
        (NX, NW),
        (nc + 3 * NS, 2 * NS),
        "layout (coords, s, v_prev, u_prev), (v, u)"
    );
    let w = SVector::<f64, NW>::from_fn(|_, _| rng.uniform());
    let lambda = SVector::<f64, NX>::from_fn(|_, _| rng.uniform());
    let nu = SVector::<f64, NS>::from_fn(|_, _| rng.uniform());
    let mut worst = 0.0f64;
    for quadrature in [
        ForcingQuadrature::Left,
        ForcingQuadrature::Right,
        ForcingQuadrature::Midpoint,
    ] {
        let stages = VarIntStages::new::<DOF, NS, NS>(&sys, 0.05, quadrature);
        let (hxx, hxw, hww) = stages
            .constraint_curvature::<DOF, NS, NS, NX, NW>(&x, &w, &lambda, &nu)
            .expect("first-order scheme");
        let reference = Lagrangian::<_, DOF, NS, NX> {
            stages: &stages,
            lambda,
            nu,
        };
        let (rxx, rxw, rww) = block_hessian(&reference, &x, &w, true);
        let scale = rxx.amax().max(rxw.amax()).max(rww.amax());
        let err = (hxx - rxx)
            .amax()
            .max((hxw - rxw).amax())
            .max((hww - rww).amax());
        eprintln!(
            "{} NS={NS} seed {seed} {quadrature:?}: |ΔH| = {err:.2e} of |H| = {scale:.2e}",
            F::NAME
        );
        worst = worst.max(err / (512.0 * f64::EPSILON * scale));
    }
    worst
}

#[test]
fn block_curvature_equals_generic_on_random_systems() {
    for seed in 0..3 {
        let worst = [
            worst_ratio::<Se2Family, 3, 1, 6, 2>(seed),
            worst_ratio::<Se2Family, 3, 2, 9, 4>(seed),
            worst_ratio::<So3Family, 3, 2, 10, 4>(seed),
            worst_ratio::<Se3Family, 6, 3, 16, 6>(seed),
        ];
        for r in worst {
            assert!(r <= 1.0, "seed {seed}: error {r:.2} × its round-off bound");
        }
    }
}

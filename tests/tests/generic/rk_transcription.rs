//! The Runge–Kutta transcription's structured dynamics Jacobian (accelerations by the
//! implicit function theorem with only the blocks the equations of motion read seeded, the
//! method's stages composed by the chain rule in `f64`) against the generic path (vector
//! duals seeded in the whole stage vector, through the solve of the equations of motion),
//! on random systems with shape-dependent inertia and connection, on SE(2), SO(3) and SE(3).

use dmech::continuous::motion_residual;
use dmech::RungeKutta;
use dmech_lie::dual::{grad_part, jacobian_part, seeded};
use dmech_ocp::transcription::runge_kutta::RkStages;
use dmech_tests::random_system::{
    random_stage_state, GroupFamily, Lcg, RandomSystem, RandomSystemSpec, Se2Family, Se3Family,
    So3Family,
};
use nalgebra::{DMatrix, SMatrix, SVector};
use num_dual::DualSVec64;

const METHODS: [RungeKutta; 3] = [RungeKutta::Rk1, RungeKutta::Rk2, RungeKutta::Rk4];

/// The worst difference between the two Jacobians relative to the bound
/// `512 ε κ(𝕄) |J − I|`: both are exact derivatives rounded along different operation
/// orders (a few hundred ulps of the largest entry, as for the WIP), and the structured one
/// solves `𝕄 ∂a = −∂r` where the generic one differentiates through the solve, so their
/// round-off differs by up to the mass matrix's condition number `κ(𝕄)`.
fn worst_ratio<F, const DOF: usize, const NS: usize, const NX: usize>(seed: u64) -> f64
where
    F: GroupFamily<DOF>,
{
    let spec = RandomSystemSpec {
        damping: 0.3,
        cyclic_first: false,
        shape_dependence: 0.5,
    };
    let sys = RandomSystem::<F, DOF, NS>::draw(seed, spec);
    let mut rng = Lcg(seed.wrapping_mul(0x9E37_79B9) ^ 0xA5A5);
    let (x, nc) = random_stage_state::<F, DOF, NX>(&mut rng);
    assert_eq!(NX, nc + 3 * NS, "state layout (coords(g), s, v, u_prev)");
    let w = SVector::<f64, NS>::from_fn(|_, _| rng.uniform());
    let s: SVector<f64, NS> = x.fixed_rows::<NS>(nc).into_owned();
    let v: SVector<f64, NS> = x.fixed_rows::<NS>(nc + NS).into_owned();
    // 𝕄 = ∂r/∂a (the equations of motion are affine in the acceleration).
    let r_a = motion_residual::<_, DualSVec64<NS>, DOF, NS, NS>(
        &sys,
        &s.map(DualSVec64::from_re),
        &v.map(DualSVec64::from_re),
        &seeded(&SVector::zeros()),
        &w.map(DualSVec64::from_re),
    );
    let m = jacobian_part(&r_a);
    let sv = DMatrix::from_column_slice(NS, NS, m.as_slice()).singular_values();
    let kappa = sv.max() / sv.min();
    let mut worst = 0.0f64;
    for method in METHODS {
        let st = RkStages::new::<DOF, NS, NS>(&sys, 0.1, method);
        let (f, fx, fw) = st.dynamics_jacobian::<DOF, NS, NS, NX, NS>(&x, &w);
        let gx = st.dynamics::<DualSVec64<NX>, DOF, NS, NS, NX, NS>(
            &seeded(&x),
            &w.map(DualSVec64::<NX>::from_re),
        );
        let gw = st.dynamics::<DualSVec64<NS>, DOF, NS, NS, NX, NS>(
            &x.map(DualSVec64::<NS>::from_re),
            &seeded(&w),
        );
        let fx_ref = SMatrix::<f64, NX, NX>::from_fn(|i, j| grad_part(&gx[i])[j]);
        let fw_ref = SMatrix::<f64, NX, NS>::from_fn(|i, j| grad_part(&gw[i])[j]);
        let f_ref = gx.map(|d| d.re);
        // The derivative part: `F_x − I` and `F_w` (the identity is exact in both).
        let eye = SMatrix::<f64, NX, NX>::identity();
        let scale = (fx_ref - eye).amax().max(fw_ref.amax());
        let err = (fx - fx_ref)
            .amax()
            .max((fw - fw_ref).amax())
            .max((f - f_ref).amax());
        let ratio = err / (512.0 * f64::EPSILON * kappa * scale);
        eprintln!(
            "{} NS={NS} seed {seed} {method:?}: |ΔJ| = {err:.2e} (|J − I| {scale:.1}, κ(𝕄) {kappa:.1})",
            F::NAME
        );
        worst = worst.max(ratio);
    }
    worst
}

#[test]
fn structured_rk_jacobian_equals_generic_on_random_systems() {
    for seed in 0..3 {
        let worst = [
            worst_ratio::<Se2Family, 3, 1, 6>(seed),
            worst_ratio::<Se2Family, 3, 2, 9>(seed),
            worst_ratio::<So3Family, 3, 2, 10>(seed),
            worst_ratio::<Se3Family, 6, 3, 16>(seed),
        ];
        for r in worst {
            assert!(r <= 1.0, "seed {seed}: error {r:.2} × its round-off bound");
        }
    }
}

//! The VI transcription's Jacobians on a state that leaves shape coordinates out
//! (`Layout::ignoring`): the carried columns are the full state's, to the bit, with the
//! ignored positions at zero (as the reduced state reads them). The passes then seed one
//! dual lane per carried coordinate instead of one per shape coordinate, in passes of
//! another width; lanes are computed independently, so neither may change a bit. Random
//! systems read every shape coordinate, so the checks cover every carried count the
//! passes dispatch on; and the structured partials against the generic path.

use dmech::variational::ForcingQuadrature;
use dmech_lie::dual::{grad_part, seeded};
use dmech_ocp::transcription::variational::VarIntStages;
use dmech_tests::random_system::{
    random_stage_state, Lcg, RandomSystem, RandomSystemSpec, Se2Family,
};
use nalgebra::{SMatrix, SVector};
use num_dual::DualSVec64;

const NS: usize = 4;
const NX: usize = 15;
const NW: usize = 8;

/// A random system with `NS = 4` on SE(2) and a stage point: the full state (`NX = 3 + 3·4
/// = 15`, the ignored positions at zero, as the reduced state reads them), the reduced one
/// (`NXR = 15 − ignored.len()`), the decision, and where the full state's kept entries and
/// shape block sit.
struct Case<const NXR: usize> {
    sys: RandomSystem<Se2Family, 3, NS>,
    x: SVector<f64, NX>,
    xr: SVector<f64, NXR>,
    w: SVector<f64, NW>,
    nc: usize,
    kept: Vec<usize>,
}

fn case<const NXR: usize>(seed: u64, ignored: &[usize]) -> Case<NXR> {
    let spec = RandomSystemSpec {
        damping: 0.3,
        cyclic_first: false,
        shape_dependence: 0.5,
    };
    let sys = RandomSystem::<Se2Family, 3, NS>::draw(seed, spec);
    let mut rng = Lcg(seed ^ 0xC0FFEE);
    let (mut x, nc) = random_stage_state::<Se2Family, 3, NX>(&mut rng);
    for &i in ignored {
        x[nc + i] = 0.0;
    }
    let w = SVector::<f64, NW>::from_fn(|_, _| rng.uniform());
    let kept: Vec<usize> = (0..NX)
        .filter(|&j| !ignored.iter().any(|&i| j == nc + i))
        .collect();
    assert_eq!(kept.len(), NXR);
    let xr = SVector::<f64, NXR>::from_fn(|j, _| x[kept[j]]);
    Case {
        sys,
        x,
        xr,
        w,
        nc,
        kept,
    }
}

fn carried_columns_match<const NXR: usize>(seed: u64, ignored: &[usize]) {
    let Case {
        sys,
        x,
        xr,
        w,
        nc,
        kept,
    } = case::<NXR>(seed, ignored);
    for quadrature in [
        ForcingQuadrature::Left,
        ForcingQuadrature::Right,
        ForcingQuadrature::Midpoint,
    ] {
        let full = VarIntStages::new::<3, NS, NS>(&sys, 0.05, quadrature);
        let reduced = VarIntStages {
            layout: full.layout.ignoring(ignored),
            ..full
        };
        let (e, ex, ew) = full.equality_jacobian::<3, NS, NS, NX, NW>(&x, &w);
        let (er, exr, ewr) = reduced.equality_jacobian::<3, NS, NS, NXR, NW>(&xr, &w);
        let (exp, ewp) = reduced.equality_partials::<3, NS, NS, NXR, NW>(&xr, &w);
        assert_eq!(e, er, "{ignored:?} {quadrature:?}: the residual");
        assert_eq!(ew, ewr, "{ignored:?} {quadrature:?}: E_w");
        assert_eq!((exr, ewr), (exp, ewp), "{ignored:?}: the partials alone");
        for (jr, &j) in kept.iter().enumerate() {
            assert_eq!(
                ex.column(j),
                exr.column(jr),
                "{ignored:?} {quadrature:?}: column {j} of E_x"
            );
        }
        // The ignored columns are the system's own dependence on those positions: not zero
        // for a random system, so the reduced state really leaves something out.
        for &i in ignored {
            assert!(ex.column(nc + i).amax() > 0.0, "{ignored:?}: s_{i} is read");
        }
    }
}

#[test]
fn a_reduced_state_has_the_full_states_carried_columns_to_the_bit() {
    for seed in 0..3 {
        carried_columns_match::<15>(seed, &[]);
        carried_columns_match::<14>(seed, &[2]);
        carried_columns_match::<13>(seed, &[0, 3]);
        carried_columns_match::<12>(seed, &[0, 1, 3]);
        carried_columns_match::<11>(seed, &[0, 1, 2, 3]);
    }
}

/// The structured partials (one pass per interval, seeded in its velocity and the carried
/// shape coordinates, for a force at one end; separate passes for a midpoint force) against
/// the generic path, all of `x` then all of `w` seeded, on reduced layouts of random systems.
/// Both are exact derivatives in double precision along different operation orders: they
/// may differ by round-off, a few hundred ulps of the largest entry.
fn structured_partials_match<const NXR: usize>(seed: u64, ignored: &[usize]) {
    const ROUND_OFF: f64 = 512.0 * f64::EPSILON;
    let Case { sys, xr, w, nc, .. } = case::<NXR>(seed, ignored);
    for quadrature in [
        ForcingQuadrature::Left,
        ForcingQuadrature::Right,
        ForcingQuadrature::Midpoint,
    ] {
        let full = VarIntStages::new::<3, NS, NS>(&sys, 0.05, quadrature);
        let st = VarIntStages {
            layout: full.layout.ignoring(ignored),
            ..full
        };
        let (_, ex, ew) = st.equality_jacobian::<3, NS, NS, NXR, NW>(&xr, &w);
        let gx = st.equality::<DualSVec64<NXR>, 3, NS, NS, NXR, NW>(
            &seeded(&xr),
            &w.map(DualSVec64::<NXR>::from_re),
        );
        let gw = st.equality::<DualSVec64<NW>, 3, NS, NS, NXR, NW>(
            &xr.map(DualSVec64::<NW>::from_re),
            &seeded(&w),
        );
        let want_x = SMatrix::<f64, NS, NXR>::from_fn(|i, j| grad_part(&gx[i])[j]);
        let want_w = SMatrix::<f64, NS, NW>::from_fn(|i, j| grad_part(&gw[i])[j]);
        let scale = want_x.amax().max(want_w.amax()).max(1.0);
        let err = (ex - want_x).amax().max((ew - want_w).amax());
        assert!(
            err <= ROUND_OFF * scale,
            "{ignored:?} {quadrature:?}: error {err:.3e} (scale {scale:.3e})"
        );
        // The random system reads every shape coordinate: the carried columns are not zero.
        for j in nc..nc + NS - ignored.len() {
            assert!(
                want_x.column(j).amax() > 0.0,
                "{ignored:?}: column {j} is read"
            );
        }
    }
}

#[test]
fn structured_partials_equal_the_generic_path_on_reduced_states() {
    for seed in 0..3 {
        structured_partials_match::<15>(seed, &[]);
        structured_partials_match::<14>(seed, &[2]);
        structured_partials_match::<13>(seed, &[0, 3]);
        structured_partials_match::<12>(seed, &[0, 1, 3]);
        structured_partials_match::<11>(seed, &[0, 1, 2, 3]);
    }
}

//! Mesh refinement of a variational-integrator iterate: the start of a plan at step `h`
//! from the solution of the same problem at a coarser step (mesh sequencing).
//!
//! Why: an interior point moves the switch of a bang-bang input (a rate-limited voltage
//! where the robot leaves and reaches rest) by one or two stages per iteration, so a plan whose
//! start has the switch a fixed *time* away needs iterations in proportion to `1/h`
//! (`docs/ocp.md`, "Why the iteration count grows with N"). From the coarse solution the
//! switch is within one coarse step of its place.
//!
//! Layout of [`crate::transcription::variational`]: `x_k = (coords(g_k), s_k, v_{k−1}, u_{k−1})`,
//! `w_k = (v_k, u_k)`. Coarse stage `k` (step `H`, `N_c` steps) and fine stage `j` (step
//! `h`, `N_f` steps) are matched by stage fraction, `κ = j N_c/N_f`, so that both ends
//! match when the duration is not a whole number of steps:
//! - positions (`coords(g)` and `s`): Catmull–Rom cubic in `κ` through the coarse nodes
//!   (exact for quadratics). A linear `s` would make the fine velocities piecewise constant,
//!   and their jumps at the coarse nodes leave momentum-matching residuals of the size of
//!   the forces;
//! - velocities: the fine differences `v_j = (s_{j+1} − s_j)/h`, as the integrator defines
//!   them (`s_{k+1} = s_k + h v_k` holds exactly);
//! - inputs: linear, with `u_k` at time `t_{k+1}`: with `u_{−1} = 0` and the rate
//!   `(u_k − u_{k−1})/h` a ramp at the limit is `u_k = r (k + 1) h`, so the fine rates equal
//!   the coarse ones (a constraint active on the coarse mesh stays satisfied);
//! - multipliers: `λ` (piecewise constant: it belongs to a step, and jumps at a waypoint)
//!   and the state equalities' `y` times `dual_scale`, each fine equality taking the
//!   multiplier of the coarse equality on the same state component at the nearest time
//!   (matched by what they constrain, not by their position in the list), the terminal
//!   equalities' each its own, times `h/H` too (rows in force units: the momentum matching
//!   divided by the step) (`dual_scale` is the caller's: how the cost-to-go scales
//!   from the coarse to the fine problem, `N_f/N_c` for a cost summed over stages without
//!   a factor `h`); bound multipliers and slacks interpolated as they
//!   are (a pointwise bound's multiplier balances one stage's cost gradient, whose size does
//!   not depend on `h`), linearly between the coarse stages' middles `t_{k+½}`, where
//!   each stage's constraints on `(x_k, w_k)` sit. The caller's warm start recomputes the
//!   slacks.
//!
//! Group coordinates are interpolated componentwise: right for coordinates without
//! constraints among them (SE(2)'s `(x, y, θ)`, `Rⁿ`); a group with constrained
//! coordinates (unit quaternions) would need its own interpolation.

use crate::nlp::StateEquality;
use crate::solver::Iterate;
use crate::transcription::layout::Layout;
use nalgebra::SVector;

/// The state equalities of the coarse and the fine problem (each in its own problem's
/// order: the solver's `y` follows it).
pub struct EqualityLists<'a> {
    /// The coarse problem's.
    pub coarse: &'a [StateEquality],
    /// The fine problem's.
    pub fine: &'a [StateEquality],
}

/// The fine problem's equality multipliers from the coarse ones: for each fine equality,
/// the coarse equality on the same state component whose stage is nearest in time
/// (stage fraction `k/N`), times `dual_scale`; zero where the coarse problem had none.
pub fn match_equality_multipliers(
    lists: &EqualityLists,
    coarse_y: &[f64],
    n_coarse: usize,
    n_fine: usize,
    dual_scale: f64,
) -> Vec<f64> {
    lists
        .fine
        .iter()
        .map(|f| {
            let t = f.stage as f64 / n_fine as f64;
            lists
                .coarse
                .iter()
                .zip(coarse_y)
                .filter(|(c, _)| c.index == f.index)
                .min_by(|(a, _), (b, _)| {
                    let da = (a.stage as f64 / n_coarse as f64 - t).abs();
                    let db = (b.stage as f64 / n_coarse as f64 - t).abs();
                    da.total_cmp(&db)
                })
                .map_or(0.0, |(_, y)| y * dual_scale)
        })
        .collect()
}

/// The fine problem's `y`: the state equalities' multipliers matched
/// ([`match_equality_multipliers`]), then the terminal equalities' (the entries of the coarse
/// `y` after its state equalities'; the same rows on every mesh), times `dual_scale` and
/// `h_fine/h_coarse`: a variational transcription's terminal rows are the last node's
/// momentum matching divided by `h` (force units), so a multiplier, the objective's
/// sensitivity to the row, is the sensitivity to the node's momentum times `h`.
fn equality_multipliers(
    lists: &EqualityLists,
    coarse_y: &[f64],
    (n_coarse, n_fine): (usize, usize),
    dual_scale: f64,
    step_ratio: f64,
) -> Vec<f64> {
    let mut y = match_equality_multipliers(lists, coarse_y, n_coarse, n_fine, dual_scale);
    let terminal = coarse_y.iter().skip(lists.coarse.len());
    y.extend(terminal.map(|v| v * dual_scale * step_ratio));
    y
}

/// The fine iterate on `n_fine` steps of length `h_fine` from the coarse one (of
/// `coarse.w.len()` steps), for the layout `layout` (see the module's documentation).
///
/// A shape coordinate the layout ignores has no positions in the states; its coarse
/// positions are rebuilt from its velocities by the dynamics it has, `s_{k+1} = s_k + H v_k`
/// from zero (`H = h_coarse`; nothing reads their level), and refined as the others.
#[allow(clippy::too_many_arguments)]
pub fn refine_varint_iterate<const NX: usize, const NW: usize, const NC: usize>(
    layout: Layout,
    coarse: &Iterate<NX, NW, NC>,
    equalities: &EqualityLists,
    n_fine: usize,
    h_fine: f64,
    h_coarse: f64,
    dual_scale: f64,
) -> Iterate<NX, NW, NC> {
    let nc = coarse.w.len();
    assert!(
        nc >= 1 && n_fine >= 1,
        "refinement needs at least one step on each mesh"
    );
    layout.check(NX, NW, layout.ns + layout.nu);
    // v_{k−1} and u_{k−1} are adjacent in the state, in w's order (v, u).
    debug_assert_eq!(layout.u_at(), layout.v_at() + layout.ns);
    let (ncoord, ns, v_at) = (layout.np, layout.ns, layout.v_at());
    // Positions of every node: the group coordinates, then every shape coordinate.
    let n_pos = ncoord + ns;
    let mut coarse_pos: Vec<Vec<f64>> = coarse
        .x
        .iter()
        .map(|x| {
            (0..n_pos)
                .map(|i| match i.checked_sub(ncoord) {
                    None => x[i],
                    Some(si) => layout.shape_slot(si).map_or(0.0, |at| x[at]),
                })
                .collect()
        })
        .collect();
    for si in (0..ns).filter(|&si| layout.is_ignored(si)) {
        for k in 0..nc {
            coarse_pos[k + 1][ncoord + si] =
                coarse_pos[k][ncoord + si] + h_coarse * coarse.w[k][si];
        }
    }
    // Coarse index of fine stage j.
    let ratio = n_fine as f64 / nc as f64;
    let kappa = |j: f64| j / ratio;
    // The interval [k, k + 1] holding κ and the fraction within it.
    let interval = |kap: f64| {
        let k = (kap.floor().max(0.0) as usize).min(nc - 1);
        (k, kap - k as f64)
    };
    let node = |k: isize| &coarse_pos[k.clamp(0, nc as isize) as usize];
    let positions = |kap: f64| -> Vec<f64> {
        let (k, t) = interval(kap);
        let k = k as isize;
        let (p0, p1, pm, pp) = (node(k), node(k + 1), node(k - 1), node(k + 2));
        // Cubic Hermite basis with Catmull–Rom tangents (p_{k+1} − p_{k−1})/2.
        let (t2, t3) = (t * t, t * t * t);
        let (h00, h10, h01, h11) = (
            2.0 * t3 - 3.0 * t2 + 1.0,
            t3 - 2.0 * t2 + t,
            -2.0 * t3 + 3.0 * t2,
            t3 - t2,
        );
        (0..n_pos)
            .map(|i| {
                h00 * p0[i]
                    + h10 * 0.5 * (p1[i] - pm[i])
                    + h01 * p1[i]
                    + h11 * 0.5 * (pp[i] - p0[i])
            })
            .collect()
    };
    // u_k at time t_{k+1}: fine u_j at coarse index (j + 1)/ratio − 1, from u_{−1} = 0.
    let input = |kap: f64, i: usize| -> f64 {
        let u = |k: usize| coarse.w[k.min(nc - 1)][ns + i];
        if kap < 0.0 {
            return u(0) * (1.0 + kap.max(-1.0));
        }
        let (k, t) = interval(kap);
        u(k) * (1.0 - t) + u(k + 1) * t
    };
    // A stage quantity sampled at the middle of its step, `t_{k+½}`, on both meshes: the
    // coarse stage fraction of fine stage j's middle, less the coarse stage's own ½.
    let at_stage_middle = |v: &[SVector<f64, NC>], j: usize| {
        let (k, t) = interval((kappa(j as f64 + 0.5) - 0.5).max(0.0));
        v[k] * (1.0 - t) + v[(k + 1).min(nc - 1)] * t
    };

    let pos: Vec<Vec<f64>> = (0..=n_fine).map(|j| positions(kappa(j as f64))).collect();
    let w: Vec<SVector<f64, NW>> = (0..n_fine)
        .map(|j| {
            SVector::<f64, NW>::from_fn(|i, _| {
                if i < ns {
                    (pos[j + 1][ncoord + i] - pos[j][ncoord + i]) / h_fine
                } else {
                    input(kappa(j as f64 + 1.0) - 1.0, i - ns)
                }
            })
        })
        .collect();
    // The state carries the previous decision: (v_{j−1}, u_{j−1}) of x_j is w_{j−1}.
    let x = (0..=n_fine)
        .map(|j| {
            let mut x = SVector::<f64, NX>::zeros();
            for i in 0..n_pos {
                match i.checked_sub(ncoord) {
                    None => x[i] = pos[j][i],
                    Some(si) => {
                        if let Some(at) = layout.shape_slot(si) {
                            x[at] = pos[j][i];
                        }
                    }
                }
            }
            if j > 0 {
                x.fixed_rows_mut::<NW>(v_at).copy_from(&w[j - 1]);
            }
            x
        })
        .collect();
    // λ_k multiplies x_{k+1} = f(x_k, w_k): it belongs to the interval [t_k, t_{k+1}] and
    // jumps at a waypoint by the waypoint's multiplier. Each fine interval takes the coarse
    // interval's value at its midpoint: interpolating across the jump put half of it on
    // the stage before the waypoint, a dual residual of ±220 there (eight, 20 → 10 ms).
    let lambda = (0..n_fine)
        .map(|j| coarse.lambda[interval(kappa(j as f64 + 0.5)).0] * dual_scale)
        .collect();
    // Bound multipliers (and slacks) belong to the stage's constraints on `(x_k, w_k)`,
    // which span the step: linear between the coarse stages' middles. Matching the steps'
    // starts instead read each fine stage's multiplier `(H − h)/2` late (a quarter of a
    // coarse step when halving), which cuts the fine mesh's first steps where an active
    // bound's multiplier rises from zero (docs/ocp.md, mesh sequencing).
    let bound = |v: &[SVector<f64, NC>]| (0..n_fine).map(|j| at_stage_middle(v, j)).collect();
    Iterate {
        x,
        w,
        lambda,
        t_lo: bound(&coarse.t_lo),
        t_hi: bound(&coarse.t_hi),
        z_lo: bound(&coarse.z_lo),
        z_hi: bound(&coarse.z_hi),
        y: equality_multipliers(
            equalities,
            &coarse.y,
            (nc, n_fine),
            dual_scale,
            h_fine / h_coarse,
        ),
        globals: Default::default(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // One group coordinate, one shape, one input: NX = 1 + 2 + 1, NW = 2, one bound.
    const L: Layout = Layout::new(1, 1, 1);

    /// A coarse iterate sampling `p(t)` (both the group coordinate and the shape), the shape
    /// velocity as the VI's difference, an input ramp `u_k = r (k + 1) H`, constant
    /// multipliers.
    fn coarse(nc: usize, big_h: f64, p: impl Fn(f64) -> f64, r: f64) -> Iterate<4, 2, 1> {
        let s = |k: usize| p(k as f64 * big_h);
        let u = |k: usize| r * (k as f64 + 1.0) * big_h;
        let v = |k: usize| (s(k + 1) - s(k)) / big_h;
        Iterate {
            x: (0..=nc)
                .map(|k| {
                    let (vp, up) = if k > 0 {
                        (v(k - 1), u(k - 1))
                    } else {
                        (0.0, 0.0)
                    };
                    SVector::from([s(k), s(k), vp, up])
                })
                .collect(),
            w: (0..nc).map(|k| SVector::from([v(k), u(k)])).collect(),
            lambda: vec![SVector::repeat(0.5); nc],
            t_lo: vec![SVector::repeat(0.25); nc],
            t_hi: vec![SVector::repeat(0.75); nc],
            z_lo: vec![SVector::repeat(2.0); nc],
            z_hi: vec![SVector::repeat(3.0); nc],
            y: vec![1.5, -2.0],
            globals: Default::default(),
        }
    }

    /// A waypoint on component 0 half-way and the end on component 1 (coarse order), and
    /// the same on the fine mesh listed end first, plus one the coarse problem did not have.
    fn equalities(nc: usize, nf: usize) -> (Vec<StateEquality>, Vec<StateEquality>) {
        let eq = |stage, index| StateEquality {
            stage,
            index,
            value: 0.0,
        };
        (
            vec![eq(nc / 2, 0), eq(nc, 1)],
            vec![eq(nf, 1), eq(nf / 2, 0), eq(nf, 2)],
        )
    }

    /// Catmull–Rom reproduces a quadratic: away from the ends (where the clamped
    /// neighbours break it) the fine positions are the quadratic's values and the fine
    /// velocities its exact differences; the input ramp keeps its rate (a doubled rate at
    /// the first fine stage was the bug the `t_{k+1}` rule fixes); multipliers scaled.
    #[test]
    fn refinement_is_exact_for_quadratic_positions_and_input_ramps() {
        let (nc, big_h) = (10, 0.04);
        let p = |t: f64| 0.3 + 1.7 * t - 2.5 * t * t;
        let r = 1.25;
        let c = coarse(nc, big_h, p, r);
        let (nf, h) = (40, big_h / 4.0);
        // The fine problem lists its equalities in another order: multipliers follow what
        // each equality constrains, not its position.
        let (coarse_eqs, fine_eqs) = equalities(nc, nf);
        let lists = EqualityLists {
            coarse: &coarse_eqs,
            fine: &fine_eqs,
        };
        let f = refine_varint_iterate::<4, 2, 1>(L, &c, &lists, nf, h, big_h, 4.0);
        // Positions: exact on the interior intervals [1, nc − 1] of the coarse mesh.
        let tol = 64.0 * f64::EPSILON;
        let mut worst: f64 = 0.0;
        for j in 4..=(nf - 4) {
            let t = j as f64 * h;
            worst = worst
                .max((f.x[j][0] - p(t)).abs())
                .max((f.x[j][1] - p(t)).abs());
        }
        assert!(worst < tol, "positions off by {worst:e}");
        // Velocities: the fine differences, in x (v_{j−1}) and in w (v_j).
        for j in 0..nf {
            let d = (f.x[j + 1][1] - f.x[j][1]) / h;
            assert!((f.w[j][0] - d).abs() <= 1e-12 * d.abs().max(1.0));
            assert!((f.x[j + 1][2] - d).abs() <= 1e-12 * d.abs().max(1.0));
        }
        // Inputs: the ramp u_j = r (j + 1) h on the fine mesh, so every fine rate is r.
        for j in 0..nf - 4 {
            let u_prev = if j == 0 { 0.0 } else { f.w[j - 1][1] };
            let rate = (f.w[j][1] - u_prev) / h;
            assert!((rate - r).abs() < 1e-9, "rate {rate} at fine stage {j}");
            assert_eq!(f.x[j + 1][3], f.w[j][1]);
        }
        // Multipliers: λ and y scaled, bound multipliers and slacks kept.
        assert!(f.lambda.iter().all(|l| (l[0] - 2.0).abs() < 1e-15));
        assert_eq!(f.y, vec![-8.0, 6.0, 0.0]);
        assert!(f.z_lo.iter().all(|z| z[0] == 2.0) && f.t_hi.iter().all(|t| t[0] == 0.75));
        // A jump of λ at coarse node 5 (a waypoint) lands at fine node 20, whole: with λ
        // interpolated, half of it sat on fine stage 19.
        let mut c_jump = c.clone();
        for k in 5..nc {
            c_jump.lambda[k] = SVector::repeat(1.5);
        }
        let f_jump = refine_varint_iterate::<4, 2, 1>(L, &c_jump, &lists, nf, h, big_h, 4.0);
        for (j, l) in f_jump.lambda.iter().enumerate() {
            let want = if j < 20 { 2.0 } else { 6.0 };
            assert_eq!(l[0], want, "λ at fine interval {j}");
        }
        // Both ends are the coarse ends.
        assert_eq!(f.x[0][0], c.x[0][0]);
        assert!((f.x[nf][1] - c.x[nc][1]).abs() < tol);
    }

    /// A bound multiplier that is linear in time on the coarse mesh, `z_k = a + b t_{k+½}`,
    /// is carried exactly: the fine stage `j` gets `a + b t_{j+½}` (away from the first
    /// half coarse step, where it is held at the first stage's value).
    #[test]
    fn bound_multipliers_are_matched_at_the_stages_middles() {
        let (nc, big_h) = (10, 0.04);
        let (a, b) = (2.0, 5.0);
        let mut c = coarse(nc, big_h, |t| t, 0.0);
        for k in 0..nc {
            let t_mid = (k as f64 + 0.5) * big_h;
            c.z_lo[k] = SVector::repeat(a + b * t_mid);
        }
        let (ce, fe) = equalities(nc, 4 * nc);
        let lists = EqualityLists {
            coarse: &ce,
            fine: &fe,
        };
        for nf in [2 * nc, 4 * nc] {
            let h = big_h * nc as f64 / nf as f64;
            let f = refine_varint_iterate::<4, 2, 1>(L, &c, &lists, nf, h, big_h, 1.0);
            for j in 0..nf {
                let t_mid = (j as f64 + 0.5) * h;
                let want = if t_mid < 0.5 * big_h {
                    c.z_lo[0][0]
                } else {
                    a + b * t_mid.min((nc as f64 - 0.5) * big_h)
                };
                let got = f.z_lo[j][0];
                assert!(
                    (got - want).abs() <= 1e-14 * want,
                    "z at fine stage {j}: {got} ≠ {want}"
                );
            }
        }
    }

    /// For a smooth non-polynomial path the interpolation error is O(H³) per unit of κ
    /// (Catmull–Rom is third-order accurate): halving the coarse step divides the worst
    /// fine position error by about 8 (measured order between 2.5 and 3.5).
    #[test]
    fn refinement_error_is_third_order_in_the_coarse_step() {
        let p = |t: f64| (3.0 * t).sin() + 0.2 * (7.0 * t).cos();
        let err = |nc: usize| {
            let big_h = 2.0 / nc as f64;
            let c = coarse(nc, big_h, p, 0.0);
            let nf = 4 * nc;
            let (ce, fe) = equalities(nc, nf);
            let lists = EqualityLists {
                coarse: &ce,
                fine: &fe,
            };
            let f = refine_varint_iterate::<4, 2, 1>(L, &c, &lists, nf, big_h / 4.0, big_h, 1.0);
            (4..=nf - 4)
                .map(|j| (f.x[j][1] - p(j as f64 * big_h / 4.0)).abs())
                .fold(0.0f64, f64::max)
        };
        let (e1, e2) = (err(40), err(80));
        let order = (e1 / e2).log2();
        println!("position error {e1:.2e} → {e2:.2e}: order {order:.2}");
        assert!(
            (2.5..3.5).contains(&order),
            "order {order} ({e1:e} → {e2:e})"
        );
    }

    /// An ignored shape coordinate is refined from the positions its velocities integrate
    /// to: the fine velocities and every carried entry are the full layout's (the
    /// positions differ by the constant `p(0)`, which the cubic and the differences carry
    /// through to round-off).
    #[test]
    fn an_ignored_shape_coordinate_refines_as_a_carried_one() {
        let (nc, big_h) = (10, 0.04);
        let p = |t: f64| (3.0 * t).sin() + 0.5;
        let c = coarse(nc, big_h, p, 1.25);
        // The same iterate without the shape position: x = (g, v_{k−1}, u_{k−1}).
        let ignoring = L.ignoring(&[0]);
        let drop_s = |x: &SVector<f64, 4>| SVector::<f64, 3>::from([x[0], x[2], x[3]]);
        let c_ign = Iterate::<3, 2, 1> {
            x: c.x.iter().map(drop_s).collect(),
            w: c.w.clone(),
            lambda: c.lambda.iter().map(drop_s).collect(),
            t_lo: c.t_lo.clone(),
            t_hi: c.t_hi.clone(),
            z_lo: c.z_lo.clone(),
            z_hi: c.z_hi.clone(),
            y: c.y.clone(),
            globals: Default::default(),
        };
        let eqs: Vec<StateEquality> = Vec::new();
        let lists = EqualityLists {
            coarse: &eqs,
            fine: &eqs,
        };
        let nf = 4 * nc;
        let h = big_h / 4.0;
        let full = refine_varint_iterate::<4, 2, 1>(L, &c, &lists, nf, h, big_h, 1.0);
        let ign = refine_varint_iterate::<3, 2, 1>(ignoring, &c_ign, &lists, nf, h, big_h, 1.0);
        // Differences of positions of size 1 divided by h: round-off of a few ε/h.
        let tol = 64.0 * f64::EPSILON / h;
        let mut worst: f64 = 0.0;
        for j in 0..nf {
            worst = worst.max((full.w[j] - ign.w[j]).amax());
        }
        for j in 0..=nf {
            worst = worst.max((drop_s(&full.x[j]) - ign.x[j]).amax());
        }
        assert!(worst <= tol, "{worst:e} > {tol:e}");
        // The velocity is not trivially the same: the shape moves.
        assert!(full.w[nf / 2][0].abs() > 0.1);
    }
}

//! The Jacobian of the variational transcription's stage equality, `(E_x, E_w)`, by
//! structured vector-dual passes: each block of `(s_k, v_{k−1}, u_{k−1}, v_k, u_k)` is
//! seeded only in the passes whose terms read it (the interval passes of a force at one end
//! of the step, or separate passes), the group coordinates never
//! (`docs/solver.md`, "The algorithm").

use crate::transcription::layout::Layout;
use crate::transcription::variational::stages::{NodePoint, Terms, VarIntStages, D};
use dmech::midpoint::interval_force;
use dmech::variational::{interval_momentum, Node};
use dmech::{Discretisation, PrincipalKinematicSystem};
use dmech_lie::dual::{grad_part, lift_vec, seeded, seeded_from};
use nalgebra::{SMatrix, SVector};
use num_dual::DualSVec64;

impl<S> VarIntStages<'_, S> {
    /// `(e, E_x, E_w)`, exact, each block of `(s_k, v_{k−1}, u_{k−1}, v_k, u_k)` seeded only
    /// in the passes of the terms that read it: the outgoing momentum reads `(s_k, v_k)`,
    /// the incoming one `(s_k, v_{k−1})`, the force the blocks of its quadrature; the group
    /// coordinates never. A momentum's Jacobian comes from the system's closed-form partials
    /// in first-order duals ([`dmech::partials::pulled_back_partials_factored`]) or from
    /// one hyper-dual evaluation of `ℓ` ([`dmech::partials::pulled_back_gradient_dual`]),
    /// not from duals nested inside duals. Checked against the generic path (all of `x`,
    /// then all of `w` seeded) in tests.
    #[allow(clippy::type_complexity)]
    pub fn equality_jacobian<
        const DOF: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NS>, SMatrix<f64, NS, NX>, SMatrix<f64, NS, NW>)
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        if self.discretisation == Discretisation::Midpoint {
            return self.midpoint_equality_jacobian::<DOF, NS, NU, NX, NW>(x, w);
        }
        // The value as the line search measures it (`equality` in f64): the residual the
        // Newton step removes must be the one the filter sees, to the last bit (the s-pass's
        // real parts differ by round-off, and the iteration count is sensitive to it).
        let e = self.equality::<f64, DOF, NS, NU, NX, NW>(x, w);
        let (ex, ew) = self.equality_partials::<DOF, NS, NU, NX, NW>(x, w);
        (e, ex, ew)
    }

    /// [`VarIntStages::equality_jacobian`] without the value, for a caller that has it (the
    /// solver's derivative pass takes the line search's).
    #[allow(clippy::type_complexity)]
    pub fn equality_partials<
        const DOF: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SMatrix<f64, NS, NX>, SMatrix<f64, NS, NW>)
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        if self.discretisation == Discretisation::Midpoint {
            let (_, ex, ew) = self.midpoint_equality_jacobian::<DOF, NS, NU, NX, NW>(x, w);
            return (ex, ew);
        }
        self.layout.check(NX, NW, NS + NU);
        self.first_order_equality_partials::<DOF, NS, NU, NX, NW>(x, w)
    }

    /// `(E_x, E_w)` of the first-order scheme's residual at this step, each block of
    /// `(s_k, v_{k−1}, u_{k−1}, v_k, u_k)` seeded alone. `w` starts with `(v_k, u_k)` and may
    /// carry more entries (a free-timing stage's step ratios), whose columns stay zero: the
    /// residual at a fixed step does not read them.
    #[allow(clippy::type_complexity)]
    pub fn first_order_equality_partials<
        const DOF: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SMatrix<f64, NS, NX>, SMatrix<f64, NS, NW>)
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        assert!(
            self.discretisation == Discretisation::FirstOrder && NW >= NS + NU,
            "the first-order scheme's partials, with (v_k, u_k) leading the decision"
        );
        let l = self.layout;
        let p = NodePoint::<f64, NS, NU>::of(l, x, w);
        let mut ex = SMatrix::<f64, NS, NX>::zeros();
        let mut ew = SMatrix::<f64, NS, NW>::zeros();
        let (left, right) = self.quadrature.ends();
        // With the force at one end of the step, each term of the residual reads one
        // interval: the incoming momentum (and a left-point force) the previous one, the
        // outgoing momentum (and a right-point force) the current one. One pass per
        // interval, seeded in its velocity and the carried shape coordinates, gives both
        // velocity blocks and the shape columns as the sum of the two passes' shape lanes
        // (each term is evaluated in exactly one of them). Against a separate shape pass
        // through every term this saves one evaluation of both momenta (with `NS = 5`, a
        // sixth of the partials' instructions). A midpoint force reads both intervals and
        // would count its shape derivative twice: it keeps the separate passes, as does a
        // system too wide for the lane counts below.
        let lanes = NS + l.ns_kept();
        let blocks = (&mut ex, &mut ew);
        match (left && right, lanes) {
            (false, 0..=4) => self.interval_passes::<DOF, NS, NU, NX, NW, 4>(left, &p, blocks),
            (false, 5..=6) => self.interval_passes::<DOF, NS, NU, NX, NW, 6>(left, &p, blocks),
            (false, 7..=8) => self.interval_passes::<DOF, NS, NU, NX, NW, 8>(left, &p, blocks),
            _ => self.separate_passes::<DOF, NS, NU, NX, NW>((left, right), &p, blocks),
        }
        // The inputs enter through the force only.
        let (ls, lvp, lup, lv, lu) = (
            lift_vec(&p.s),
            lift_vec(&p.v_prev),
            lift_vec(&p.u_prev),
            lift_vec(&p.v),
            lift_vec(&p.u),
        );
        if left {
            let r = self.equality_terms::<DOF, NS, NU, _>(
                Terms::FORCE,
                &ls,
                &lvp,
                &seeded(&p.u_prev),
                &lv,
                &lu,
            );
            put_columns(&mut ex, l.u_at(), &r);
        }
        if right {
            let r = self.equality_terms::<DOF, NS, NU, _>(
                Terms::FORCE,
                &ls,
                &lvp,
                &lup,
                &lv,
                &seeded(&p.u),
            );
            put_columns(&mut ew, NS, &r);
        }
        (ex, ew)
    }

    /// The velocity blocks and the shape columns of `E_x`, `E_w` by one pass per interval
    /// of `N ≥ NS + kept` dual lanes: the interval's velocity in lanes `0..NS`, the carried
    /// shape coordinates in lanes `NS..NS + kept` (in state order). The force is read at
    /// the left point if `left`, otherwise at the right one.
    #[allow(clippy::type_complexity)]
    fn interval_passes<
        const DOF: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
        const N: usize,
    >(
        &self,
        left: bool,
        p: &NodePoint<f64, NS, NU>,
        (ex, ew): (&mut SMatrix<f64, NS, NX>, &mut SMatrix<f64, NS, NW>),
    ) where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let l = self.layout;
        let kept = l.ns_kept();
        assert!(
            NS + kept <= N,
            "a dual lane for each velocity and carried shape coordinate"
        );
        let sd = carried_shape_seeded::<NS, N>(l, &p.s, NS);
        let (lvp, lup, lv, lu) = (
            lift_vec(&p.v_prev),
            lift_vec(&p.u_prev),
            lift_vec(&p.v),
            lift_vec(&p.u),
        );
        let previous = self.equality_terms::<DOF, NS, NU, N>(
            Terms::previous_interval(left),
            &sd,
            &seeded_from(&p.v_prev, 0),
            &lup,
            &lv,
            &lu,
        );
        let current = self.equality_terms::<DOF, NS, NU, N>(
            Terms::current_interval(!left),
            &sd,
            &lvp,
            &lup,
            &seeded_from(&p.v, 0),
            &lu,
        );
        let (s_at, v_at) = (l.s_at(), l.v_at());
        put_columns_by(ex, &previous, |j| (j < NS).then_some(v_at + j));
        put_columns_by(ew, &current, |j| (j < NS).then_some(j));
        for i in 0..NS {
            let (gp, gc) = (grad_part(&previous[i]), grad_part(&current[i]));
            for j in NS..NS + kept {
                ex[(i, s_at + j - NS)] = gp[j] + gc[j];
            }
        }
    }

    /// The shape and velocity columns of `E_x`, `E_w` by a pass per block: the carried
    /// shape coordinates through every term (lanes `0..kept` of an `NS`-lane pass; the
    /// lanes are independent, so its width changes no bit of the kept columns), then each
    /// velocity through the terms that read it.
    #[allow(clippy::type_complexity)]
    fn separate_passes<
        const DOF: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        (left, right): (bool, bool),
        p: &NodePoint<f64, NS, NU>,
        (ex, ew): (&mut SMatrix<f64, NS, NX>, &mut SMatrix<f64, NS, NW>),
    ) where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let l = self.layout;
        let kept = l.ns_kept();
        let (ls, lvp, lup, lv, lu) = (
            lift_vec(&p.s),
            lift_vec(&p.v_prev),
            lift_vec(&p.u_prev),
            lift_vec(&p.v),
            lift_vec(&p.u),
        );
        // s_k: every term, seeded in the carried coordinates only (an ignored one's column
        // has no place in the state).
        if kept > 0 {
            let r = self.equality_terms::<DOF, NS, NU, NS>(
                Terms::ALL,
                &carried_shape_seeded::<NS, NS>(l, &p.s, 0),
                &lvp,
                &lup,
                &lv,
                &lu,
            );
            put_columns_by(ex, &r, |j| (j < kept).then_some(l.s_at() + j));
        }
        // v_{k−1}: the incoming momentum, and the force if it reads the previous interval.
        let r = self.equality_terms::<DOF, NS, NU, NS>(
            Terms::previous_interval(left),
            &ls,
            &seeded(&p.v_prev),
            &lup,
            &lv,
            &lu,
        );
        put_columns(ex, l.v_at(), &r);
        // v_k: the outgoing momentum, and the force if it reads the current interval.
        let r = self.equality_terms::<DOF, NS, NU, NS>(
            Terms::current_interval(right),
            &ls,
            &lvp,
            &lup,
            &seeded(&p.v),
            &lu,
        );
        put_columns(ew, 0, &r);
    }

    /// [`VarIntStages::equality_jacobian`] of the midpoint scheme: each block of
    /// `(s_k, v_{k−1}, v_k)` seeded in turn through the generic momenta (ℓ's gradient in
    /// nested duals, or the system's closed-form partials in duals), a velocity's pass
    /// evaluating only its interval's half of the residual; the inputs by one pass through
    /// the forces.
    #[allow(clippy::type_complexity)]
    fn midpoint_equality_jacobian<
        const DOF: usize,
        const NS: usize,
        const NU: usize,
        const NX: usize,
        const NW: usize,
    >(
        &self,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
    ) -> (SVector<f64, NS>, SMatrix<f64, NS, NX>, SMatrix<f64, NS, NW>)
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let l = self.layout;
        l.check(NX, NW, NS + NU);
        let NodePoint {
            s,
            v_prev,
            u_prev,
            v,
            u,
        } = NodePoint::<f64, NS, NU>::of(l, x, w);
        let e = self.equality::<f64, DOF, NS, NU, NX, NW>(x, w);
        let mut ex = SMatrix::<f64, NS, NX>::zeros();
        let mut ew = SMatrix::<f64, NS, NW>::zeros();
        let h = self.h;
        // The residual's two halves: the interval before node k (incoming momentum and
        // its force, moved by s_k and v_{k−1}) and the interval after it (outgoing, moved
        // by s_k and v_k). A pass seeded in one velocity evaluates only its half.
        let terms = |incoming: bool,
                     outgoing: bool,
                     s: &SVector<D<NS>, NS>,
                     vp: &SVector<D<NS>, NS>,
                     up: &SVector<D<NS>, NU>,
                     v: &SVector<D<NS>, NS>,
                     u: &SVector<D<NS>, NU>| {
            let (ht, half) = (D::<NS>::from(h), D::<NS>::from(0.5));
            let a_k = self.sys.connection(s);
            let mut r = SVector::<D<NS>, NS>::zeros();
            if outgoing {
                let out = interval_momentum(
                    self.sys,
                    h,
                    Discretisation::Midpoint,
                    s,
                    v,
                    &a_k,
                    Node::Start,
                );
                let f = interval_force::<S, D<NS>, DOF, NS, NU>(self.sys, h, s, v, u);
                r += out / ht - f * half;
            }
            if incoming {
                let s_prev = s - vp * ht;
                let inc = interval_momentum(
                    self.sys,
                    h,
                    Discretisation::Midpoint,
                    &s_prev,
                    vp,
                    &a_k,
                    Node::End,
                );
                let f = interval_force::<S, D<NS>, DOF, NS, NU>(self.sys, h, &s_prev, vp, up);
                r -= inc / ht + f * half;
            }
            r
        };
        let (ls, lvp, lup, lv, lu) = (
            lift_vec(&s),
            lift_vec(&v_prev),
            lift_vec(&u_prev),
            lift_vec(&v),
            lift_vec(&u),
        );
        put_shape_columns(
            &mut ex,
            l,
            &terms(true, true, &seeded(&s), &lvp, &lup, &lv, &lu),
        );
        put_columns(
            &mut ex,
            l.v_at(),
            &terms(true, false, &ls, &seeded(&v_prev), &lup, &lv, &lu),
        );
        put_columns(
            &mut ew,
            0,
            &terms(false, true, &ls, &lvp, &lup, &seeded(&v), &lu),
        );
        // The inputs enter through the interval forces only: one pass with both seeded.
        let r = self.midpoint_input_columns::<DOF, NS, NU>(&s, &v_prev, &u_prev, &v, &u);
        for i in 0..NS {
            for j in 0..NU {
                ex[(i, l.u_at() + j)] = r.0[(i, j)];
                ew[(i, NS + j)] = r.1[(i, j)];
            }
        }
        (e, ex, ew)
    }

    /// `∂e/∂u_{k−1}` and `∂e/∂u_k` of the midpoint residual: `−½ ∂F/∂u` at each interval's
    /// midpoint, by one dual pass per interval.
    fn midpoint_input_columns<const DOF: usize, const NS: usize, const NU: usize>(
        &self,
        s: &SVector<f64, NS>,
        v_prev: &SVector<f64, NS>,
        u_prev: &SVector<f64, NU>,
        v: &SVector<f64, NS>,
        u: &SVector<f64, NU>,
    ) -> (SMatrix<f64, NS, NU>, SMatrix<f64, NS, NU>)
    where
        S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    {
        let h = self.h;
        let column =
            |s_start: &SVector<f64, NS>, vel: &SVector<f64, NS>, inp: &SVector<f64, NU>| {
                let f = dmech::midpoint::interval_force::<S, D<NU>, DOF, NS, NU>(
                    self.sys,
                    h,
                    &lift_vec(s_start),
                    &lift_vec(vel),
                    &seeded(inp),
                );
                SMatrix::<f64, NS, NU>::from_fn(|i, j| -0.5 * grad_part(&f[i])[j])
            };
        let s_prev = s - v_prev * h;
        (column(&s_prev, v_prev, u_prev), column(s, v, u))
    }
}

/// Writes the gradients of `r` (a pass seeded in `N` variables) into the columns
/// `slot(j)` of `m` (`None`: variable `j` has no column).
fn put_columns_by<const R: usize, const C: usize, const N: usize>(
    m: &mut SMatrix<f64, R, C>,
    r: &SVector<DualSVec64<N>, R>,
    slot: impl Fn(usize) -> Option<usize>,
) {
    for i in 0..R {
        let g = grad_part(&r[i]);
        for j in 0..N {
            if let Some(at) = slot(j) {
                m[(i, at)] = g[j];
            }
        }
    }
}

/// Columns `col .. col + N` of `m` from a pass seeded in `N` variables.
fn put_columns<const R: usize, const C: usize, const N: usize>(
    m: &mut SMatrix<f64, R, C>,
    col: usize,
    r: &SVector<DualSVec64<N>, R>,
) {
    put_columns_by(m, r, |j| Some(col + j));
}

/// The columns of a pass seeded in `s` into the state's carried shape columns (an ignored
/// coordinate's column, zero for an ignorable one, has no place in the state).
fn put_shape_columns<const R: usize, const C: usize, const NS: usize>(
    m: &mut SMatrix<f64, R, C>,
    l: Layout,
    r: &SVector<DualSVec64<NS>, R>,
) {
    put_columns_by(m, r, |j| l.shape_slot(j));
}

/// `s` in `N`-lane duals with the carried coordinates seeded in lanes
/// `first_lane..first_lane + kept` (in state order) and the ignored ones constant.
fn carried_shape_seeded<const NS: usize, const N: usize>(
    l: Layout,
    s: &SVector<f64, NS>,
    first_lane: usize,
) -> SVector<D<N>, NS> {
    SVector::from_fn(|i, _| match l.shape_slot(i) {
        Some(at) => {
            let mut e = SVector::<f64, N>::zeros();
            e[first_lane + at - l.s_at()] = 1.0;
            D::<N>::new(s[i], num_dual::Derivative::some(e))
        }
        None => D::<N>::from_re(s[i]),
    })
}

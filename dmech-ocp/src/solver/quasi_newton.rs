//! The partitioned SR1 approximation of each stage's constraint curvature.

use super::*;

/// Partitioned SR1 approximation of one stage's constraint curvature
/// `∇²(λᵀf + νᵀe)`, updated from the exact Jacobians at consecutive iterates.
///
/// The previous point's Jacobians are not kept here: the stage's derivatives still hold
/// them when the next pass reaches the stage, and it reads them
/// ([`QuasiNewton::previous_jacobians`]) before it overwrites them, so this array, written
/// and read at every iteration, holds only the blocks and the point.
#[derive(Clone, Debug)]
pub(super) struct QuasiNewton<const NX: usize, const NW: usize, const NE: usize> {
    pub(super) bxx: SMatrix<f64, NX, NX>,
    pub(super) bxw: SMatrix<f64, NX, NW>,
    pub(super) bww: SMatrix<f64, NW, NW>,
    pub(super) x: SVector<f64, NX>,
    pub(super) w: SVector<f64, NW>,
    pub(super) valid: bool,
}

/// A stage's constraint Jacobians at the previous SR1 point.
#[derive(Clone, Debug)]
pub(super) struct StageJacobians<const NX: usize, const NW: usize, const NE: usize> {
    fx: SMatrix<f64, NX, NX>,
    fw: SMatrix<f64, NX, NW>,
    ex: SMatrix<f64, NE, NX>,
    ew: SMatrix<f64, NE, NW>,
}

impl<const NX: usize, const NW: usize, const NE: usize> QuasiNewton<NX, NW, NE> {
    pub(super) fn new() -> Self {
        QuasiNewton {
            bxx: SMatrix::zeros(),
            bxw: SMatrix::zeros(),
            bww: SMatrix::zeros(),
            x: SVector::zeros(),
            w: SVector::zeros(),
            valid: false,
        }
    }

    pub(super) fn reset(&mut self) {
        self.bxx.fill(0.0);
        self.bxw.fill(0.0);
        self.bww.fill(0.0);
    }

    /// As [`QuasiNewton::new`]: no curvature and no previous point (a new solve).
    pub(super) fn start_over(&mut self) {
        self.reset();
        self.valid = false;
    }

    /// The Jacobians at the previous point, read from `d`, the stage's derivatives as the
    /// last pass left them (the pass that also set this point); `None` before the first
    /// update.
    pub(super) fn previous_jacobians<const NC: usize>(
        &self,
        d: &StageDerivatives<NX, NW, NE, NC>,
    ) -> Option<StageJacobians<NX, NW, NE>> {
        self.valid.then_some(StageJacobians {
            fx: d.fx,
            fw: d.fw,
            ex: d.ex,
            ew: d.ew,
        })
    }

    /// SR1 update with the multipliers of the new iterate, then remember the new point.
    /// `previous` are the Jacobians at the point remembered last
    /// ([`QuasiNewton::previous_jacobians`]), `d` the new derivatives. Skipped when
    /// `|sᵀr| ≤ skip ‖s‖‖r‖` ([`IpOptions::sr1_skip`]).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn update<const NC: usize>(
        &mut self,
        skip: f64,
        x: &SVector<f64, NX>,
        w: &SVector<f64, NW>,
        previous: Option<StageJacobians<NX, NW, NE>>,
        d: &StageDerivatives<NX, NW, NE, NC>,
        lam: &SVector<f64, NX>,
        nu: &SVector<f64, NE>,
    ) {
        if let Some(mut dj) = previous {
            let (sx, sw) = (x - self.x, w - self.w);
            // r = y − B s with y = (J − J_old)ᵀ(λ, ν): the new Jacobians are subtracted from
            // the old ones in place, so no further matrix and no transposed copy is built;
            // the rank-one terms go into B in place.
            dj.fx -= d.fx;
            dj.fw -= d.fw;
            dj.ex -= d.ex;
            dj.ew -= d.ew;
            let mut rx = self.bxx * sx;
            rx.gemv(1.0, &self.bxw, &sw, 1.0);
            rx.gemv_tr(1.0, &dj.fx, lam, 1.0);
            rx.gemv_tr(1.0, &dj.ex, nu, 1.0);
            let mut rw = self.bww * sw;
            rw.gemv_tr(1.0, &self.bxw, &sx, 1.0);
            rw.gemv_tr(1.0, &dj.fw, lam, 1.0);
            rw.gemv_tr(1.0, &dj.ew, nu, 1.0);
            // (The old minus the new Jacobians were multiplied: r is negated here.)
            rx.neg_mut();
            rw.neg_mut();
            let den = sx.dot(&rx) + sw.dot(&rw);
            let ns = (sx.norm_squared() + sw.norm_squared()).sqrt();
            let nr = (rx.norm_squared() + rw.norm_squared()).sqrt();
            if den.abs() > skip * ns * nr && ns > 0.0 {
                let inv = 1.0 / den;
                self.bxx.ger(inv, &rx, &rx, 1.0);
                self.bxw.ger(inv, &rx, &rw, 1.0);
                self.bww.ger(inv, &rw, &rw, 1.0);
            }
        }
        self.x = *x;
        self.w = *w;
        self.valid = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dmech_lie::lcg::Lcg;

    type Der = StageDerivatives<3, 2, 1, 1>;

    /// A deterministic pseudo-random matrix with entries in [−0.5, 0.5).
    fn mat<const R: usize, const C: usize>(seed: &mut Lcg) -> SMatrix<f64, R, C> {
        SMatrix::from_fn(|_, _| seed.uniform())
    }

    /// Two stage Jacobians, points and multipliers with `cos∠(s, y) = cos` (y the
    /// multiplier-weighted change of the Jacobians, `B = 0` before, so `r = y`).
    fn secant_pair(
        cos: f64,
    ) -> (
        QuasiNewton<3, 2, 1>,
        Der,
        Der,
        SVector<f64, 3>,
        SVector<f64, 3>,
    ) {
        let mut seed = Lcg(7);
        let (mut d0, mut d1) = (Der::zeros(), Der::zeros());
        (d0.fx, d0.fw, d0.ex, d0.ew) = (
            mat(&mut seed),
            mat(&mut seed),
            mat(&mut seed),
            mat(&mut seed),
        );
        (d1.fx, d1.fw, d1.ex, d1.ew) = (d0.fx, d0.fw, d0.ex, d0.ew);
        // Only f_x changes, by M: y = (Mᵀλ, 0) and sᵀy = (M s_x)ᵀλ. λ is built from the
        // unit vector along M s_x and one orthogonal to it, at the requested angle.
        let m: SMatrix<f64, 3, 3> = mat(&mut seed);
        d1.fx += m;
        let (x0, w0) = (mat::<3, 1>(&mut seed), mat::<2, 1>(&mut seed));
        let x1 = x0 + mat::<3, 1>(&mut seed);
        let sx = x1 - x0;
        let a = (m * sx).normalize();
        let o = {
            let t = mat::<3, 1>(&mut seed);
            (t - a * a.dot(&t)).normalize()
        };
        // sᵀy = (M s_x)ᵀλ and ‖y‖ = ‖Mᵀλ‖: pick λ's angle to M s_x by bisection on cos.
        let cos_of = |phi: f64| {
            let lam = a * phi.cos() + o * phi.sin();
            sx.dot(&(m.transpose() * lam)) / (sx.norm() * (m.transpose() * lam).norm())
        };
        assert!(cos_of(0.0) > cos && cos_of(std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let (mut lo, mut hi) = (0.0, std::f64::consts::FRAC_PI_2);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if cos_of(mid) > cos {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let lam = a * lo.cos() + o * lo.sin();
        let mut q = QuasiNewton::<3, 2, 1>::new();
        q.update(1e-8, &x0, &w0, None, &d0, &lam, &SVector::zeros());
        (q, d0, d1, x1, lam)
    }

    /// An applied SR1 update satisfies the secant equation `B⁺ s = y`.
    #[test]
    fn sr1_update_satisfies_the_secant_equation() {
        let (mut q, d0, d1, x1, lam) = secant_pair(0.05);
        let w1 = q.w;
        let (sx, y) = (x1 - q.x, (d1.fx - d0.fx).transpose() * lam);
        let previous = q.previous_jacobians(&d0);
        q.update(1e-2, &x1, &w1, previous, &d1, &lam, &SVector::zeros());
        let bs = q.bxx * sx; // s_w = 0
        let err = (bs - y).amax().max((q.bxw.transpose() * sx).amax());
        // One rank-one product and one division: round-off of a few ε; bound ≈ 500 ε.
        assert!(err < 1e-13 * y.amax().max(1.0), "B s − y = {err:e}");
    }

    /// Below the skip threshold the update is skipped; above it, it is applied.
    #[test]
    fn sr1_update_skipped_below_threshold() {
        for (cos, skip, applied) in [(5e-3, 1e-2, false), (5e-3, 1e-8, true), (2e-2, 1e-2, true)] {
            let (mut q, d0, d1, x1, lam) = secant_pair(cos);
            let w1 = q.w;
            let previous = q.previous_jacobians(&d0);
            q.update(skip, &x1, &w1, previous, &d1, &lam, &SVector::zeros());
            assert_eq!(q.bxx.amax() > 0.0, applied, "cos {cos}, threshold {skip}");
        }
    }
}

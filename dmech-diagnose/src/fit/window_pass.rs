//! One window's prediction turned into its cost (an `f64` pass) or its Gauss–Newton blocks
//! (one dual pass through the window's simulation, the state and the free directions
//! seeded).

use super::{Fitter, MAX_DIRECTIONS};
use crate::model::Direction;
use crate::normal_equations::WindowLin;
use crate::Plant;
use nalgebra::{DMatrix, DVector};
use num_dual::DualSVec64;

impl<P: Plant> Fitter<'_, P> {
    /// The plant's prediction of a window with the reading hypotheses of `theta` applied
    /// on top ([`Plant::readings`]).
    pub(crate) fn predict<T: crate::FitScalar>(
        &self,
        start: usize,
        len: usize,
        z0: &[T],
        theta: &[T],
    ) -> Option<Vec<T>> {
        let mut y = self.plant.predict(self.log, start, len, z0, theta)?;
        if let Some(r) = self.plant.readings() {
            r.apply(&mut y, self.plant.channels().len(), theta);
        }
        Some(y)
    }

    /// Weighted residual sum of squares and count of one window (f64 pass).
    pub(crate) fn window_cost(
        &self,
        theta: &[f64],
        (start, len): (usize, usize),
        z0: &[f64],
    ) -> Option<(f64, usize)> {
        let y = self.predict(start, len, z0, theta)?;
        let chans = self.plant.channels();
        let (mut rss, mut m) = (0.0, 0);
        for (i, c, wgt, meas) in self.weighted_readings(start, len) {
            let r = chans[c].residual(y[i], meas) * wgt;
            rss += r * r;
            m += 1;
        }
        (rss.is_finite()).then_some((rss, m))
    }

    /// The readings a window's residual counts, rows then channels: the index of the
    /// prediction, the channel, its weight and the measured value (channels of weight zero
    /// and missing readings left out).
    fn weighted_readings(
        &self,
        start: usize,
        len: usize,
    ) -> impl Iterator<Item = (usize, usize, f64, f64)> + '_ {
        let nc = self.log.n_channels;
        (0..len).flat_map(move |j| {
            (0..self.plant.channels().len()).filter_map(move |c| {
                let wgt = self.weight(c);
                if wgt == 0.0 {
                    return None;
                }
                let meas = self.log.value(start + j, c)?;
                Some((j * nc + c, c, wgt, meas))
            })
        })
    }

    /// The window's Gauss–Newton blocks for the free directions `dirs` at internal
    /// coordinates `x` (one dual pass with `N ≥ dual states + directions`).
    fn window_lin_n<const N: usize>(
        &self,
        x: &[f64],
        dirs: &[Direction],
        (start, len): (usize, usize),
        z0: &[f64],
    ) -> Option<WindowLin> {
        type Dn<const N: usize> = DualSVec64<N>;
        let cat = self.catalogue();
        let nd = self.dual_states.len();
        let k = dirs.len();
        let nz = z0.len();
        debug_assert!(nd + k <= N);
        // x_j = x_ref_j + Σ_q B_jq β_q with β_q dual in direction nd + q.
        let mut xd: Vec<Dn<N>> = x.iter().map(|&v| Dn::<N>::from(v)).collect();
        for (q, d) in dirs.iter().enumerate() {
            for &(j, b) in d {
                xd[j] += Dn::<N>::from(0.0).derivative(nd + q) * b;
            }
        }
        let theta: Vec<Dn<N>> = cat
            .params
            .iter()
            .zip(xd)
            .map(|(s, v)| s.from_internal(v))
            .collect();
        let mut zd: Vec<Dn<N>> = z0.iter().map(|&v| Dn::<N>::from(v)).collect();
        for (d, &i) in self.dual_states.iter().enumerate() {
            zd[i] = Dn::<N>::from(z0[i]).derivative(d);
        }
        let y = self.predict(start, len, &zd, &theta)?;
        let chans = self.plant.channels();
        let additive = self.plant.additive();
        // An additive state enters its reading with the reading's scale (1 without one).
        let theta_re: Vec<f64> = theta.iter().map(|t| t.re).collect();
        let coefficient = |c: usize| {
            self.plant
                .readings()
                .map_or(1.0, |r| r.additive_coefficient(c, &theta_re))
        };
        let mut a = vec![0.0; nz * nz];
        let mut w = vec![0.0; nz * k];
        let mut v = vec![0.0; k * k];
        let mut gz = vec![0.0; nz];
        let mut gp = vec![0.0; k];
        let mut jz = vec![0.0; nz];
        let mut jp = vec![0.0; k];
        let (mut rss, mut m) = (0.0, 0);
        for (at, c, wgt, meas) in self.weighted_readings(start, len) {
            let yc = &y[at];
            let r = chans[c].residual(yc.re, meas) * wgt;
            let g = yc
                .eps
                .unwrap_generic(nalgebra::Const::<N>, nalgebra::Const::<1>);
            jz.fill(0.0);
            for (d, &i) in self.dual_states.iter().enumerate() {
                jz[i] = g[d] * wgt;
            }
            for &(s, ch) in additive {
                if ch == c {
                    jz[s] += wgt * coefficient(c);
                }
            }
            for q in 0..k {
                jp[q] = g[nd + q] * wgt;
            }
            for p in 0..nz {
                if jz[p] == 0.0 {
                    continue;
                }
                for q in 0..nz {
                    a[p * nz + q] += jz[p] * jz[q];
                }
                for q in 0..k {
                    w[p * k + q] += jz[p] * jp[q];
                }
                gz[p] += jz[p] * r;
            }
            for p in 0..k {
                for q in 0..k {
                    v[p * k + q] += jp[p] * jp[q];
                }
                gp[p] += jp[p] * r;
            }
            rss += r * r;
            m += 1;
        }
        let lin = WindowLin {
            a: DMatrix::from_row_slice(nz, nz, &a),
            w: DMatrix::from_row_slice(nz, k, &w),
            v: DMatrix::from_row_slice(k, k, &v),
            gz: DVector::from_vec(gz),
            gp: DVector::from_vec(gp),
            rss,
            m,
        };
        let finite = lin
            .a
            .iter()
            .chain(lin.w.iter())
            .chain(lin.v.iter())
            .all(|x| x.is_finite())
            && rss.is_finite();
        finite.then_some(lin)
    }

    pub(crate) fn window_lin(
        &self,
        x: &[f64],
        dirs: &[Direction],
        win: (usize, usize),
        z0: &[f64],
    ) -> Option<WindowLin> {
        let n = self.dual_states.len() + dirs.len();
        macro_rules! dispatch {
            ($($b:literal),*) => {
                match n {
                    $(_ if n <= $b => self.window_lin_n::<$b>(x, dirs, win, z0),)*
                    _ => panic!("{n} dual directions: more than {MAX_DIRECTIONS}"),
                }
            };
        }
        dispatch!(4, 6, 8, 10, 12, 16, 20, 24, 32, 40)
    }
}

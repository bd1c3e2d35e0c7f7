//! The interior point's iterate per stage, the rows' sides it works with, and the KKT
//! residuals at an iterate.

use super::problem::{Rows, StageQp};
use nalgebra::SVector;

/// Side `0` of a row is its upper bound (`z ≤ hi`, sign `+1`), side `1` its lower bound
/// (`−z ≤ −lo`, sign `−1`).
pub(crate) const SIGN: [f64; 2] = [1.0, -1.0];

/// What one side of a row is to the interior point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Side {
    /// Its bound is infinite: no slack, no multiplier.
    Absent,
    /// `σ z − b + t = 0`, `t ≥ 0`.
    Hard,
    /// `σ z − b − s + t = 0`, `t, s ≥ 0`, `s` priced `l1 s + ½ l2 s²`.
    Soft { l1: f64, l2: f64 },
}

/// The sides of a stage's rows and their bounds `b` (`hi` and `−lo`).
#[derive(Clone, Debug)]
pub(crate) struct StageSides<const NC: usize> {
    pub side: [[Side; NC]; 2],
    pub b: [SVector<f64, NC>; 2],
}

impl<const NC: usize> StageSides<NC> {
    pub fn of<const NX: usize, const NU: usize>(rows: &Rows<NX, NU, NC>) -> Self {
        let mut side = [[Side::Absent; NC]; 2];
        let mut b = [SVector::zeros(); 2];
        for i in 0..NC {
            let bound = [rows.hi[i], -rows.lo[i]];
            for j in 0..2 {
                if bound[j].is_finite() {
                    b[j][i] = bound[j];
                    side[j][i] = match rows.soft[i] {
                        Some(p) => Side::Soft { l1: p.l1, l2: p.l2 },
                        None => Side::Hard,
                    };
                }
            }
        }
        StageSides { side, b }
    }

    /// The number of complementarity pairs: one per present side, two per soft one.
    pub fn pairs(&self) -> usize {
        self.side
            .iter()
            .flatten()
            .map(|s| match s {
                Side::Absent => 0,
                Side::Hard => 1,
                Side::Soft { .. } => 2,
            })
            .sum()
    }
}

/// The primal–dual iterate of stage `k ≤ N` (at the terminal stage `u` and `pi` are zero).
/// Per side `j` of each row: the slack `t`, its multiplier `lam`, and for soft rows the
/// violation `s` and its multiplier `nu`; absent sides hold `t = 1`, the rest zero.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct StageIterate<const NX: usize, const NU: usize, const NC: usize> {
    pub x: SVector<f64, NX>,
    pub u: SVector<f64, NU>,
    /// The multiplier of `x_{k+1} = A x_k + B u_k + c_k`.
    pub pi: SVector<f64, NX>,
    pub t: [SVector<f64, NC>; 2],
    pub lam: [SVector<f64, NC>; 2],
    pub s: [SVector<f64, NC>; 2],
    pub nu: [SVector<f64, NC>; 2],
}

impl<const NX: usize, const NU: usize, const NC: usize> StageIterate<NX, NU, NC> {
    pub fn zeros() -> Self {
        StageIterate {
            x: SVector::zeros(),
            u: SVector::zeros(),
            pi: SVector::zeros(),
            t: [SVector::zeros(); 2],
            lam: [SVector::zeros(); 2],
            s: [SVector::zeros(); 2],
            nu: [SVector::zeros(); 2],
        }
    }

    /// `self += α d`.
    pub fn step(&mut self, alpha: f64, d: &Self) {
        self.x.axpy(alpha, &d.x, 1.0);
        self.u.axpy(alpha, &d.u, 1.0);
        self.pi.axpy(alpha, &d.pi, 1.0);
        for j in 0..2 {
            self.t[j].axpy(alpha, &d.t[j], 1.0);
            self.lam[j].axpy(alpha, &d.lam[j], 1.0);
            self.s[j].axpy(alpha, &d.s[j], 1.0);
            self.nu[j].axpy(alpha, &d.nu[j], 1.0);
        }
    }
}

/// The KKT residuals of stage `k` at an iterate: `r_x = ∂L/∂x_k`, `r_u = ∂L/∂u_k`,
/// `r_dyn = A x + B u + c − x_{k+1}`, the row values `z`, and per side
/// `r_p = σ z − b − s + t` and (soft) `r_s = l1 + l2 s − λ − ν`.
#[derive(Clone, Debug)]
pub(crate) struct StageResidual<const NX: usize, const NU: usize, const NC: usize> {
    pub r_x: SVector<f64, NX>,
    pub r_u: SVector<f64, NU>,
    pub r_dyn: SVector<f64, NX>,
    pub z: SVector<f64, NC>,
    pub r_p: [SVector<f64, NC>; 2],
    pub r_s: [SVector<f64, NC>; 2],
}

impl<const NX: usize, const NU: usize, const NC: usize> StageResidual<NX, NU, NC> {
    pub fn zeros() -> Self {
        StageResidual {
            r_x: SVector::zeros(),
            r_u: SVector::zeros(),
            r_dyn: SVector::zeros(),
            z: SVector::zeros(),
            r_p: [SVector::zeros(); 2],
            r_s: [SVector::zeros(); 2],
        }
    }
}

/// The residuals' norms and the objective at an iterate.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Measures {
    /// `max ‖r_x, r_u, r_s‖∞`.
    pub stationarity: f64,
    /// `max ‖r_dyn, r_p‖∞`.
    pub primal: f64,
    /// `(Σ tλ + Σ sν) / pairs`, 0 without pairs.
    pub mu: f64,
    pub objective: f64,
}

/// The residuals of every stage into `res`; the norms, `μ` and the objective returned.
pub(crate) fn residuals<const NX: usize, const NU: usize, const NC: usize>(
    qp: &StageQp<NX, NU, NC>,
    sides: &[StageSides<NC>],
    it: &[StageIterate<NX, NU, NC>],
    res: &mut [StageResidual<NX, NU, NC>],
) -> Measures {
    let n = qp.horizon();
    let mut m = Measures::default();
    let (mut comp, mut pairs) = (0.0, 0usize);
    for k in 0..=n {
        let (ik, rk, sd) = (&it[k], &mut res[k], &sides[k]);
        let rows = qp.rows(k);
        let net = ik.lam[0] - ik.lam[1];
        if k < n {
            let st = &qp.stages()[k];
            let (qx, su) = (st.q * ik.x, st.s * ik.u);
            let ru = st.r * ik.u;
            m.objective += 0.5 * ik.x.dot(&qx) + ik.x.dot(&su) + 0.5 * ik.u.dot(&ru);
            m.objective += st.q_vec.dot(&ik.x) + st.r_vec.dot(&ik.u);
            rk.r_u = ru + st.s.tr_mul(&ik.x) + st.r_vec + st.b.tr_mul(&ik.pi) + rows.e.tr_mul(&net);
            let a_pi = super::dense::mul_vec(qp.a_t(k), &ik.pi);
            rk.r_x = qx + su + st.q_vec + a_pi + super::dense::mul_vec(qp.d_t(k), &net);
            rk.r_dyn = st.a * ik.x + st.b * ik.u + st.c - it[k + 1].x;
            rk.z = rows.d * ik.x + rows.e * ik.u;
        } else {
            let t = qp.terminal();
            let qx = t.q * ik.x;
            m.objective += 0.5 * ik.x.dot(&qx) + t.q_vec.dot(&ik.x);
            rk.r_x = qx + t.q_vec + super::dense::mul_vec(qp.d_t(k), &net);
            rk.r_u = SVector::zeros();
            rk.r_dyn = SVector::zeros();
            rk.z = rows.d * ik.x;
        }
        if k > 0 {
            rk.r_x -= it[k - 1].pi;
            m.stationarity = m.stationarity.max(rk.r_x.amax());
        }
        m.stationarity = m.stationarity.max(rk.r_u.amax());
        m.primal = m.primal.max(rk.r_dyn.amax());
        for j in 0..2 {
            for i in 0..NC {
                let (t, lam, s, nu) = (ik.t[j][i], ik.lam[j][i], ik.s[j][i], ik.nu[j][i]);
                let (r_p, r_s) = match sd.side[j][i] {
                    Side::Absent => (0.0, 0.0),
                    Side::Hard => {
                        comp += t * lam;
                        pairs += 1;
                        (SIGN[j] * rk.z[i] - sd.b[j][i] + t, 0.0)
                    }
                    Side::Soft { l1, l2 } => {
                        comp += t * lam + s * nu;
                        pairs += 2;
                        m.objective += l1 * s + 0.5 * l2 * s * s;
                        (
                            SIGN[j] * rk.z[i] - sd.b[j][i] - s + t,
                            l1 + l2 * s - lam - nu,
                        )
                    }
                };
                rk.r_p[j][i] = r_p;
                rk.r_s[j][i] = r_s;
                m.primal = m.primal.max(r_p.abs());
                m.stationarity = m.stationarity.max(r_s.abs());
            }
        }
    }
    m.mu = if pairs > 0 { comp / pairs as f64 } else { 0.0 };
    m
}

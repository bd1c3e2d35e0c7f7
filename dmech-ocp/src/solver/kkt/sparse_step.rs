//! The Newton step by faer's sparse `LDLᵀ` of the whole condensed KKT matrix
//! ([`crate::solver::kkt::sparse_ldlt`], `IpOptions::kkt = KktMethod::SparseLdlt`): the same condensed
//! stages and couplings as the Riccati path, the inertia read from `D`, the same inertia
//! correction. With or without globals.

use super::kkt::{corrected_derivatives, Correction, KktBackend};
use super::*;
use crate::solver::kkt::global_riccati::LqCoupling;
use crate::solver::kkt::sparse_ldlt::{SparseKkt, SparseKktError};

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NF, NC>
{
    /// The pattern's symbolic factorisation, built at the first sparse step of a solve.
    fn sparse_kkt(&self) -> Result<&SparseKkt, Failure> {
        self.sparse
            .get_or_init(|| {
                let (ng, ne, supports) = match &self.globals {
                    Some(gs) => (
                        gs.g.len(),
                        gs.g.equalities.len(),
                        (0..self.n).map(|k| gs.g.support_of(k).to_vec()).collect(),
                    ),
                    None => (0, 0, vec![Vec::new(); self.n]),
                };
                SparseKkt::new::<NX, NF>(self.n, ng, ne, supports)
                    .map_err(|e| Failure::SparseKkt(format!("{e:?}")))
            })
            .as_ref()
            .map_err(Clone::clone)
    }

    /// One sparse solve at shift `delta`: `None` if its inertia is wrong or it is
    /// singular.
    fn sparse_solve(
        &self,
        it: &Iterate<NX, NW, NC>,
        ws: &Workspace<NX, NW, NE, NF, NC>,
        mu: f64,
        dc: f64,
        delta: f64,
    ) -> Result<Option<Step<NX, NW, NC>>, Failure> {
        let kkt = self.sparse_kkt()?;
        let (q_n, q_vec_n) = self.terminal_lq(it, &ws.terminal, dc);
        let cps: Vec<LqCoupling<NX, NF, NW>> = ws.couplings.iter().map(|c| c.0.clone()).collect();
        let terms = self.global_terms(&it.globals, mu, delta);
        match kkt.solve(
            &ws.lq,
            &cps,
            &q_n,
            &q_vec_n,
            &SVector::zeros(),
            delta,
            &terms,
        ) {
            Ok((sol, dp, y)) => Ok(Some(self.recover_with_globals(
                it,
                &ws.ders,
                &ws.terminal,
                &ws.elim,
                &ws.couplings,
                sol,
                &dp,
                y,
                mu,
                dc,
            ))),
            Err(SparseKktError::Inertia { .. } | SparseKktError::Singular) => Ok(None),
            Err(e) => Err(Failure::SparseKkt(format!("{e:?}"))),
        }
    }

    /// Every stage condensed into the workspace (from the iteration's derivatives, or a
    /// second-order correction's), in parallel, with no sweep behind it.
    fn condense_stages(
        &self,
        it: &Iterate<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        mu: f64,
        dc: f64,
        correction: Option<Correction<'_, NX, NW, NE, NC>>,
    ) -> Result<(), Failure> {
        let (ders, qn, constants) = (&ws.ders, &ws.qn, &ws.constants);
        // The closure borrows `ws` immutably; condense into its buffers taken out, then
        // put them back.
        let mut lq = std::mem::take(&mut ws.lq);
        let mut elim = std::mem::take(&mut ws.elim);
        let failed = std::sync::Mutex::new(None::<(usize, Failure)>);
        par_zip(&mut lq, &mut elim, self.opts.threads, |k, l, e| {
            let curvature = self.stage_curvature(k, constants, qn);
            let condensed = match correction {
                None => self.condense(k, it, &ders[k], curvature, mu, dc, l, e),
                Some((trial_vals, trial, alpha)) => {
                    let d = corrected_derivatives(k, it, &ders[k], &trial_vals[k], trial, alpha);
                    self.condense(k, it, &d, curvature, mu, dc, l, e)
                }
            };
            if let Err(failure) = condensed {
                let mut f = failed.lock().unwrap_or_else(|p| p.into_inner());
                if f.as_ref().is_none_or(|(j, _)| k < *j) {
                    *f = Some((k, failure));
                }
            }
        });
        ws.lq = lq;
        ws.elim = elim;
        match failed.into_inner().unwrap_or_else(|p| p.into_inner()) {
            Some((_, failure)) => Err(failure),
            None => Ok(()),
        }
    }

    /// The couplings of the condensed stages (zero without globals).
    fn fill_couplings(
        &self,
        it: &Iterate<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        mu: f64,
    ) -> Result<(), Failure> {
        if self.globals.is_some() {
            let Workspace {
                ders,
                elim,
                qn,
                constants,
                couplings,
                ..
            } = ws;
            self.couplings(it, ders, (constants, qn), elim, mu, couplings)
        } else {
            ws.couplings
                .resize_with(self.n, || (LqCoupling::zeros(), SMatrix::zeros()));
            Ok(())
        }
    }
}

/// faer's sparse `LDLᵀ` of the whole condensed KKT matrix, its inertia read from `D`.
pub(in crate::solver) struct SparseLdlt;

impl<const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    KktBackend<NX, NW, NE, NF, NC> for SparseLdlt
{
    fn condense_and_solve(
        &self,
        s: &Solver<'_, NX, NW, NE, NF, NC>,
        it: &Iterate<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        mu: f64,
        dc: f64,
        delta: f64,
        correction: Option<Correction<'_, NX, NW, NE, NC>>,
        tm: &mut Timings,
    ) -> Result<Option<Step<NX, NW, NC>>, Failure> {
        s.condense_stages(it, ws, mu, dc, correction)?;
        s.fill_couplings(it, ws, mu)?;
        self.solve_again(s, it, ws, mu, dc, delta, tm)
    }

    fn solve_again(
        &self,
        s: &Solver<'_, NX, NW, NE, NF, NC>,
        it: &Iterate<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        mu: f64,
        dc: f64,
        delta: f64,
        tm: &mut Timings,
    ) -> Result<Option<Step<NX, NW, NC>>, Failure> {
        let t = Instant::now();
        let step = s.sparse_solve(it, ws, mu, dc, delta);
        tm.riccati += t.elapsed().as_secs_f64();
        step
    }
}

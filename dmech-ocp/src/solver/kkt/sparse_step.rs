//! The Newton step by faer's sparse `LDLᵀ` of the whole condensed KKT matrix
//! ([`crate::solver::kkt::sparse_ldlt`], `IpOptions::kkt = KktMethod::SparseLdlt`): the same condensed
//! stages and couplings as the Riccati path, the inertia read from `D`, the same inertia
//! correction. With or without globals.

use super::kkt::corrected_derivatives;
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

    /// The Newton step by the sparse path (see [`Solver::newton_step`]).
    pub(in crate::solver) fn newton_step_sparse(
        &self,
        it: &Iterate<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        inertia: &mut InertiaCorrection,
        mu: f64,
        dc: f64,
        tm: &mut Timings,
    ) -> Result<(Step<NX, NW, NC>, f64), Failure> {
        let t1 = Instant::now();
        {
            let (ders, qn, constants) = (&ws.ders, &ws.qn, &ws.constants);
            let condense = |k: usize, l: &mut LqStage<NX, NF>, e: &mut Elimination<NX, NW, NF>| {
                let curvature = self.stage_curvature(k, constants, qn);
                self.condense(k, it, &ders[k], curvature, mu, dc, l, e)
            };
            // The closure borrows `ws` immutably; condense into fresh buffers, then move.
            let mut lq = std::mem::take(&mut ws.lq);
            let mut elim = std::mem::take(&mut ws.elim);
            let failed = std::sync::Mutex::new(None::<(usize, Failure)>);
            par_zip(&mut lq, &mut elim, self.opts.threads, |k, l, e| {
                if let Err(msg) = condense(k, l, e) {
                    let mut f = failed.lock().unwrap_or_else(|p| p.into_inner());
                    if f.as_ref().is_none_or(|(j, _)| k < *j) {
                        *f = Some((k, msg));
                    }
                }
            });
            ws.lq = lq;
            ws.elim = elim;
            if let Some((_, msg)) = failed.into_inner().unwrap_or_else(|p| p.into_inner()) {
                return Err(msg);
            }
        }
        self.fill_couplings(it, ws, mu)?;
        let mut delta = 0.0;
        let step = loop {
            tm.factorizations += 1;
            let t_r = Instant::now();
            let r = self.sparse_solve(it, ws, mu, dc, delta)?;
            tm.riccati += t_r.elapsed().as_secs_f64();
            match r {
                Some(s) => break s,
                None => match inertia.next(delta) {
                    Some(next) => delta = next,
                    None => return Err(Failure::InertiaCorrection),
                },
            }
        };
        inertia.succeeded(delta);
        tm.kkt += t1.elapsed().as_secs_f64();
        Ok((step, delta))
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

    /// The second-order correction by the sparse path (see
    /// [`Solver::second_order_correction`]).
    #[allow(clippy::too_many_arguments)]
    pub(in crate::solver) fn sparse_correction(
        &self,
        it: &Iterate<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        trial_vals: &[StageValues<NX, NE, NC>],
        trial: &Iterate<NX, NW, NC>,
        alpha: f64,
        mu: f64,
        dc: f64,
        delta: f64,
    ) -> Option<Step<NX, NW, NC>> {
        let mut lq = std::mem::take(&mut ws.lq);
        let mut elim = std::mem::take(&mut ws.elim);
        let failed = std::sync::atomic::AtomicBool::new(false);
        {
            let (ders, qn, constants) = (&ws.ders, &ws.qn, &ws.constants);
            par_zip(&mut lq, &mut elim, self.opts.threads, |k, l, e| {
                let d = corrected_derivatives(k, it, &ders[k], &trial_vals[k], trial, alpha);
                let curvature = self.stage_curvature(k, constants, qn);
                if self.condense(k, it, &d, curvature, mu, dc, l, e).is_err() {
                    failed.store(true, std::sync::atomic::Ordering::Relaxed);
                }
            });
        }
        ws.lq = lq;
        ws.elim = elim;
        if failed.into_inner() {
            return None;
        }
        self.fill_couplings(it, ws, mu).ok()?;
        self.sparse_solve(it, ws, mu, dc, delta).ok().flatten()
    }
}

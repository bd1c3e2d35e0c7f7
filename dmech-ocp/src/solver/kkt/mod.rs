//! The KKT system: the Newton step with its inertia correction, a stage condensed
//! (dependent decisions and slacks eliminated), the state equalities' dual-regularised
//! rows, and the condense-and-sweep pass with its second-order correction. The KKT error
//! is in `kkt_error.rs`.

use super::*;

pub(crate) mod global_riccati;
pub(super) mod globals;
pub mod riccati;
pub(crate) mod sparse_ldlt;
mod sparse_step;

/// What stage `k`'s Hessian takes besides its derivatives: the cost's constant curvature
/// when the derivative pass left it in the constants table (its blocks in the derivatives
/// are then not written), and the stage's SR1 blocks.
#[derive(Clone, Copy)]
pub(super) struct StageCurvature<'c, const NX: usize, const NW: usize, const NE: usize> {
    pub(super) constant: Option<&'c HessianBlocks<NX, NW>>,
    pub(super) qn: Option<&'c QuasiNewton<NX, NW, NE>>,
}

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NF, NC>
{
    /// The Newton step at `it` and the primal shift it took: every stage condensed, the
    /// Riccati recursion run behind the condensing with no shift, and, while some stage's
    /// `H_uu` is not positive definite, again over the condensed stages with the next shift
    /// of the inertia correction. `Err` when a stage cannot be condensed or the shifts are
    /// exhausted.
    pub(super) fn newton_step(
        &self,
        it: &Iterate<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        inertia: &mut InertiaCorrection,
        mu: f64,
        dc: f64,
        tm: &mut Timings,
    ) -> Result<(Step<NX, NW, NC>, f64), Failure> {
        if self.opts.kkt == KktMethod::SparseLdlt {
            return self.newton_step_sparse(it, ws, inertia, mu, dc, tm);
        }
        if self.globals.is_some() {
            return self.newton_step_global(it, ws, inertia, mu, dc, tm);
        }
        let t1 = Instant::now();
        let (first, t_sweep) = self.condense_workspace(it, ws, mu, dc, 0.0, None)?;
        tm.riccati += t_sweep;
        let Workspace {
            ders,
            lq,
            elim,
            sweep,
            ..
        } = ws;
        let mut attempt = Some(first);
        let mut delta = 0.0;
        loop {
            tm.factorizations += 1;
            let swept = match attempt.take() {
                Some(r) => r,
                None => {
                    let t_r = Instant::now();
                    sweep.reshift(delta);
                    let r = sweep.sweep_all(lq);
                    tm.riccati += t_r.elapsed().as_secs_f64();
                    r
                }
            };
            match swept {
                Ok(()) => break,
                Err(_) => match inertia.next(delta) {
                    Some(next) => delta = next,
                    None => return Err(Failure::InertiaCorrection),
                },
            }
        }
        inertia.succeeded(delta);
        let sol = sweep.forward(lq, &SVector::zeros());
        let step = self.recover(it, ders, elim, sol, mu, dc, None);
        tm.kkt += t1.elapsed().as_secs_f64();
        Ok((step, delta))
    }

    /// Condense stage `k`: eliminate the dependent decisions and the inequality slacks,
    /// into the solver's buffers `lq`, `el` (written in place: returning the 5 kB pair and
    /// moving it there was part of the memmove share, see `condense_and_sweep`).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn condense(
        &self,
        k: usize,
        it: &Iterate<NX, NW, NC>,
        d: &StageDerivatives<NX, NW, NE, NC>,
        curvature: StageCurvature<'_, NX, NW, NE>,
        mu: f64,
        dc: f64,
        lq: &mut LqStage<NX, NF>,
        el: &mut Elimination<NX, NW, NF>,
    ) -> Result<(), Failure> {
        // `H_xx` and `g_x` go straight into the stage's `Q` and `q`, which the terms below
        // are added to in place (each entry sees the same additions in the same order as
        // the sums written out, so the same bits).
        let (hxw, hww, gw) =
            self.stage_hessian_into(k, it, d, curvature, mu, (&mut lq.q_mat, &mut lq.q));

        // δw = w0 + wx δx + wu δu, with δv from the linearised stage equality: `wx`, `w0`
        // are `(D_x, 0)`, `(d_0, 0)` and `wu = (D_u, I)`.
        let (dx, du, d0) = if NE > 0 {
            let ev: SMatrix<f64, NE, NE> = d.ew.fixed_columns::<NE>(0).into_owned();
            let eu: SMatrix<f64, NE, NF> = d.ew.fixed_columns::<NF>(NE).into_owned();
            let lu = Lu::new(&ev).ok_or(Failure::SingularStageEquality { stage: k })?;
            (
                lu.solve_columns(&(-d.ex)),
                lu.solve_columns(&(-eu)),
                lu.solve(&(-d.e)),
            )
        } else {
            (SMatrix::zeros(), SMatrix::zeros(), SVector::zeros())
        };
        let Elimination { w0, wx, wu } = el;
        wx.fixed_rows_mut::<NE>(0).copy_from(&dx);
        wx.rows_mut(NE, NW - NE).fill(0.0);
        w0.fixed_rows_mut::<NE>(0).copy_from(&d0);
        w0.rows_mut(NE, NW - NE).fill(0.0);
        wu.fixed_rows_mut::<NE>(0).copy_from(&du);
        wu.rows_mut(NE, NW - NE).fill(0.0);
        for i in 0..NF {
            wu[(NE + i, i)] = 1.0;
        }
        let wu = &*wu;
        // The products with `wx` and `w0` take only their first `NE` rows (the others are
        // zero; the skipped terms were exact zeros and the kept ones are summed in order).
        let hww_v = hww.fixed_columns::<NE>(0);
        let hww_wx = hww_v * dx;
        let hww_wu = hww * wu;
        let hww_w0 = hww_v * d0;
        let hxw_v = hxw.fixed_columns::<NE>(0);
        let hxw_wx = hxw_v * dx;
        // Products with a transposed factor by `tr_mul` (column dot products), without
        // forming the transpose.
        lq.q_mat += hxw_wx;
        lq.q_mat += hxw_wx.transpose();
        lq.q_mat += dx.tr_mul(&hww_wx.fixed_rows::<NE>(0));
        lq.s_mat = hxw * wu + dx.tr_mul(&hww_wu.fixed_rows::<NE>(0));
        lq.r_mat = wu.tr_mul(&hww_wu);
        lq.q += dx.tr_mul(&gw.fixed_rows::<NE>(0));
        lq.q += hxw_v * d0;
        lq.q += dx.tr_mul(&hww_w0.fixed_rows::<NE>(0));
        lq.r = wu.tr_mul(&(gw + hww_w0));
        self.add_state_equalities(k, it, dc, &mut lq.q_mat, &mut lq.q);
        let fw_v = d.fw.fixed_columns::<NE>(0);
        lq.a = d.fx + fw_v * dx;
        lq.b = d.fw * wu;
        lq.c = d.f + fw_v * d0 - it.x[k + 1];
        Ok(())
    }

    /// Stage `k`'s Hessian and gradient with its inequalities eliminated: the cost's and the
    /// inequalities' curvature (and the SR1 blocks), `Cᵀ Σ C`, and the barrier terms.
    /// `(H_xw, H_ww, g_w)` are returned; `H_xx` and `g_x` are written into `hxx`, `gx`.
    #[allow(clippy::type_complexity)]
    pub(super) fn stage_hessian_into(
        &self,
        k: usize,
        it: &Iterate<NX, NW, NC>,
        d: &StageDerivatives<NX, NW, NE, NC>,
        curvature: StageCurvature<'_, NX, NW, NE>,
        mu: f64,
        (hxx, gx): (&mut SMatrix<f64, NX, NX>, &mut SVector<f64, NX>),
    ) -> (SMatrix<f64, NX, NW>, SMatrix<f64, NW, NW>, SVector<f64, NW>) {
        let b = &self.bounds[k];
        // Inequalities: Σ and the barrier gradient term.
        let mut sigma = SVector::<f64, NC>::zeros();
        let mut bc = SVector::<f64, NC>::zeros();
        for i in 0..NC {
            if b.has_lo[i] > 0.0 {
                let s = it.z_lo[k][i] / it.t_lo[k][i];
                let r = d.c[i] - b.lo[i] - it.t_lo[k][i];
                sigma[i] += s;
                bc[i] -= mu / it.t_lo[k][i] - s * r;
            }
            if b.has_hi[i] > 0.0 {
                let s = it.z_hi[k][i] / it.t_hi[k][i];
                let r = b.hi[i] - d.c[i] - it.t_hi[k][i];
                sigma[i] += s;
                bc[i] += mu / it.t_hi[k][i] - s * r;
            }
        }
        let cw_s = SMatrix::<f64, NW, NC>::from_fn(|i, j| d.cw[(j, i)] * sigma[j]);
        // The curvature and the SR1 blocks summed in one pass (not copied, then added to).
        let (c_xx, c_xw, c_ww) = match curvature.constant {
            Some(c) => (&c.0, &c.1, &c.2),
            None => (&d.hxx, &d.hxw, &d.hww),
        };
        let (mut hxw, mut hww) = match curvature.qn {
            Some(q) => {
                *hxx = c_xx + q.bxx;
                (c_xw + q.bxw, c_ww + q.bww)
            }
            None => {
                *hxx = *c_xx;
                (*c_xw, *c_ww)
            }
        };
        add_state_rows_weighted(&d.cx, &d.cw, &sigma, hxx, &mut hxw);
        hww.gemm(1.0, &cw_s, &d.cw, 1.0);
        *gx = d.gx + d.cx.tr_mul(&bc);
        let gw = d.gw + d.cw.tr_mul(&bc);
        (hxw, hww, gw)
    }

    /// The cost's constant curvature of stage `k`, if the derivative pass reads it from the
    /// constants table rather than copying it into the stage's derivatives: a problem that
    /// declares it constant, without the exact Hessian (which adds the constraints'
    /// curvature to the derivatives' blocks).
    pub(super) fn table_curvature<'c>(
        &self,
        k: usize,
        constants: &'c ConstantsTable<NX, NW, NC>,
    ) -> Option<&'c HessianBlocks<NX, NW>> {
        if self.opts.curvature == Curvature::Exact {
            return None;
        }
        constants.get(k).map(|c| &c.curvature)
    }

    /// What stage `k`'s Hessian takes besides its derivatives ([`StageCurvature`]).
    pub(super) fn stage_curvature<'c>(
        &self,
        k: usize,
        constants: &'c ConstantsTable<NX, NW, NC>,
        qn: &'c [QuasiNewton<NX, NW, NE>],
    ) -> StageCurvature<'c, NX, NW, NE> {
        StageCurvature {
            constant: self.table_curvature(k, constants),
            qn: qn.get(k),
        }
    }

    /// The terminal stage of the LQ problem: the terminal cost's curvature and gradient and
    /// the state equalities at `x_N`.
    pub(super) fn terminal_lq(
        &self,
        it: &Iterate<NX, NW, NC>,
        terminal: &TerminalDerivatives<NX>,
        dc: f64,
    ) -> (SMatrix<f64, NX, NX>, SVector<f64, NX>) {
        let (mut q_n, mut q_vec_n) = (terminal.hxx, terminal.gx);
        self.add_state_equalities(self.n, it, dc, &mut q_n, &mut q_vec_n);
        (q_n, q_vec_n)
    }

    /// The quadratic terms of the state equalities at stage `k`.
    pub(super) fn add_state_equalities(
        &self,
        k: usize,
        it: &Iterate<NX, NW, NC>,
        dc: f64,
        q_mat: &mut SMatrix<f64, NX, NX>,
        q: &mut SVector<f64, NX>,
    ) {
        for &j in &self.eqs_at[k] {
            let e = &self.eqs[j];
            q_mat[(e.index, e.index)] += 1.0 / dc;
            q[e.index] += it.y[j] + (it.x[k][e.index] - e.value) / dc;
        }
    }

    /// Every stage condensed by `stage(k)` into `lq[k]`, `elim[k]`, with the Riccati
    /// backward sweep (primal shift 0) run behind the condensing: chunks of stages are
    /// condensed from the last one down, in parallel, and one thread sweeps each chunk as
    /// soon as it and every later one are done (condensing a chunk itself when the next one
    /// is not). The serial sweep so overlaps the parallel condensing instead of following
    /// it; every stage sees the same operations in the same order as
    /// condense-then-[`solve_lq`], so the result is bitwise the same.
    ///
    /// `Err` is the condensing error of the first stage that fails; `Ok` carries the sweep's
    /// outcome (a stage whose `H_uu` is not positive definite stops it; the condensing
    /// still completes, for the caller's inertia correction) and the seconds spent in it.
    #[allow(clippy::type_complexity)]
    pub(super) fn condense_and_sweep<F>(
        &self,
        lq: &mut [LqStage<NX, NF>],
        elim: &mut [Elimination<NX, NW, NF>],
        sweep: &mut BackwardSweep<NX, NF>,
        stage: F,
    ) -> Result<(Result<(), RiccatiError>, f64), Failure>
    where
        F: Fn(usize, &mut LqStage<NX, NF>, &mut Elimination<NX, NW, NF>) -> Result<(), Failure>
            + Sync,
    {
        let failed = std::sync::Mutex::new(None::<(usize, Failure)>);
        let condense_chunk =
            |ci: usize, pl: &mut [LqStage<NX, NF>], pe: &mut [Elimination<NX, NW, NF>]| {
                let mut ok = true;
                for (j, (l, e)) in pl.iter_mut().zip(pe.iter_mut()).enumerate() {
                    let k = ci * PAR_CHUNK + j;
                    if let Err(msg) = stage(k, l, e) {
                        ok = false;
                        let mut f = failed.lock().unwrap_or_else(|p| p.into_inner());
                        if f.as_ref().is_none_or(|(j, _)| k < *j) {
                            *f = Some((k, msg));
                        }
                    }
                }
                ok
            };
        let mut sweep_result = Ok(());
        let mut sweep_time = 0.0;
        // Sweep one condensed chunk (all of its stages, last first).
        let mut sweep_chunk =
            |ci: usize, stages: &[LqStage<NX, NF>], result: &mut Result<(), RiccatiError>| {
                if result.is_err() {
                    return;
                }
                let t = Instant::now();
                for (j, st) in stages.iter().enumerate().rev() {
                    if let Err(e) = sweep.step(ci * PAR_CHUNK + j, st) {
                        *result = Err(e);
                        break;
                    }
                }
                sweep_time += t.elapsed().as_secs_f64();
            };
        let n_chunks = lq.len().div_ceil(PAR_CHUNK);
        let chunks = lq
            .chunks_mut(PAR_CHUNK)
            .zip(elim.chunks_mut(PAR_CHUNK))
            .enumerate()
            .rev();
        if self.opts.threads <= 1 {
            // Each chunk swept right after it is condensed (still in cache), until one fails.
            let mut sweeping = true;
            for (ci, (pl, pe)) in chunks {
                sweeping &= condense_chunk(ci, pl, pe);
                if sweeping {
                    sweep_chunk(ci, pl, &mut sweep_result);
                }
            }
        } else {
            let queue = std::sync::Mutex::new(chunks);
            let take = || queue.lock().unwrap_or_else(|p| p.into_inner()).next();
            // Condensed chunks travel to the sweeping thread by channel; `None` marks a
            // chunk whose condensing failed. One sender per helper: the channel closes
            // when every helper is done (or has panicked), and the senders no helper took
            // are dropped once the queue is empty.
            let (tx, rx) = std::sync::mpsc::channel::<(usize, Option<&[LqStage<NX, NF>]>)>();
            let helpers = self.opts.threads - 1;
            let senders = std::sync::Mutex::new(vec![tx; helpers]);
            let condense_chunks = || {
                let Some(tx) = senders.lock().unwrap_or_else(|p| p.into_inner()).pop() else {
                    return;
                };
                while let Some((ci, (pl, pe))) = take() {
                    let ok = condense_chunk(ci, pl, pe);
                    let pl: &[LqStage<NX, NF>] = pl;
                    if tx.send((ci, ok.then_some(pl))).is_err() {
                        break;
                    }
                }
            };
            // This thread: sweep the next chunk when it is ready, otherwise condense one
            // (the queue hands them out last first, so usually the next one).
            let mut sweep_chunks = || {
                let mut ready: Vec<Option<Option<&[LqStage<NX, NF>]>>> = vec![None; n_chunks];
                let mut next = n_chunks;
                // A chunk that failed to condense stops the sweep (its error is reported).
                let mut sweeping = true;
                while next > 0 {
                    if let Some(chunk) = ready[next - 1].take() {
                        match chunk {
                            Some(stages) if sweeping => {
                                sweep_chunk(next - 1, stages, &mut sweep_result)
                            }
                            _ => sweeping = false,
                        }
                        next -= 1;
                    } else if let Ok((ci, chunk)) = rx.try_recv() {
                        ready[ci] = Some(chunk);
                    } else if let Some((ci, (pl, pe))) = take() {
                        let ok = condense_chunk(ci, pl, pe);
                        let pl: &[LqStage<NX, NF>] = pl;
                        ready[ci] = Some(ok.then_some(pl));
                    } else {
                        senders.lock().unwrap_or_else(|p| p.into_inner()).clear();
                        match rx.recv() {
                            Ok((ci, chunk)) => ready[ci] = Some(chunk),
                            Err(_) => break,
                        }
                    }
                }
            };
            if !worker_pool::run_split(helpers, &condense_chunks, &mut sweep_chunks) {
                std::thread::scope(|sc| {
                    for _ in 0..helpers {
                        sc.spawn(condense_chunks);
                    }
                    sweep_chunks();
                });
            }
        }
        match failed.into_inner().unwrap_or_else(|p| p.into_inner()) {
            Some((_, msg)) => Err(msg),
            None => Ok((sweep_result, sweep_time)),
        }
    }

    /// The second-order correction step: the KKT system of the iterate (same curvature,
    /// same inertia shift `delta`) with the residuals of the dynamics and the stage
    /// equalities replaced by `α r(x) + r(x_trial)`, condensed into the iteration's buffers
    /// `lq`, `elim` (its own step is already recovered from them). `None` if it cannot be
    /// solved.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn second_order_correction(
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
        // The iteration's step is recovered already: its sweep's buffers are free.
        let correction = Some((trial_vals, trial, alpha));
        let (swept, _) = self
            .condense_workspace(it, ws, mu, dc, delta, correction)
            .ok()?;
        swept.ok()?;
        let sol = ws.sweep.forward(&ws.lq, &SVector::zeros());
        Some(self.recover(it, &ws.ders, &ws.elim, sol, mu, dc, None))
    }

    /// Every stage condensed into the workspace's buffers (`lq`, `elim`) with the Riccati
    /// sweep restarted at the primal shift `shift` and run behind the condensing
    /// ([`Solver::condense_and_sweep`]): from the iteration's derivatives, or, with
    /// `correction = Some((trial_vals, trial, α))`, from a second-order correction's
    /// ([`corrected_derivatives`]).
    #[allow(clippy::type_complexity)]
    pub(super) fn condense_workspace(
        &self,
        it: &Iterate<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        mu: f64,
        dc: f64,
        shift: f64,
        correction: Option<(&[StageValues<NX, NE, NC>], &Iterate<NX, NW, NC>, f64)>,
    ) -> Result<(Result<(), RiccatiError>, f64), Failure> {
        let (q_n, q_vec_n) = self.terminal_lq(it, &ws.terminal, dc);
        let Workspace {
            ders,
            lq,
            elim,
            qn,
            constants,
            sweep,
            ..
        } = ws;
        sweep.restart(self.n, &q_n, &q_vec_n, shift);
        self.condense_and_sweep(lq, elim, sweep, |k, l, e| {
            let curvature = self.stage_curvature(k, constants, qn);
            match correction {
                None => self.condense(k, it, &ders[k], curvature, mu, dc, l, e),
                Some((trial_vals, trial, alpha)) => {
                    let d = corrected_derivatives(k, it, &ders[k], &trial_vals[k], trial, alpha);
                    self.condense(k, it, &d, curvature, mu, dc, l, e)
                }
            }
        })
    }
}

/// Stage `k`'s derivatives for the second-order correction: the residuals of the dynamics
/// and the stage equality replaced by `α r(x) + r(x_trial)` (the derivatives themselves
/// stay those of the iteration).
pub(super) fn corrected_derivatives<
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NC: usize,
>(
    k: usize,
    it: &Iterate<NX, NW, NC>,
    d: &StageDerivatives<NX, NW, NE, NC>,
    trial_val: &StageValues<NX, NE, NC>,
    trial: &Iterate<NX, NW, NC>,
    alpha: f64,
) -> StageDerivatives<NX, NW, NE, NC> {
    let mut d = d.clone();
    let r = (d.f - it.x[k + 1]) * alpha + (trial_val.f - trial.x[k + 1]);
    d.f = it.x[k + 1] + r;
    d.e = d.e * alpha + trial_val.e;
    d
}

/// `C_xᵀ Σ C_x` and `C_xᵀ Σ C_w` added into `hxx`, `hxw`, over the nonzeros of `C_x`'s
/// rows: an inequality reads one or two state entries (a bound on the tilt, a rate limit
/// on `u_{k−1}`), so the dense `NX·NC·NX` products were mostly multiplications by zero.
fn add_state_rows_weighted<const NX: usize, const NW: usize, const NC: usize>(
    cx: &SMatrix<f64, NC, NX>,
    cw: &SMatrix<f64, NC, NW>,
    sigma: &SVector<f64, NC>,
    hxx: &mut SMatrix<f64, NX, NX>,
    hxw: &mut SMatrix<f64, NX, NW>,
) {
    let mut nz = [0usize; NX];
    for i in 0..NC {
        let mut m = 0;
        for a in 0..NX {
            if cx[(i, a)] != 0.0 {
                nz[m] = a;
                m += 1;
            }
        }
        for &a in &nz[..m] {
            let ca = cx[(i, a)] * sigma[i];
            for &b in &nz[..m] {
                hxx[(a, b)] += ca * cx[(i, b)];
            }
            for b in 0..NW {
                hxw[(a, b)] += ca * cw[(i, b)];
            }
        }
    }
}

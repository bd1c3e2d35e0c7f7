//! The KKT system: the Newton step with its inertia correction over one [`KktBackend`]
//! (the Riccati recursion, the recursion with global variables, or a sparse `LDLᵀ`), a
//! stage condensed (dependent decisions and slacks eliminated), the state equalities'
//! dual-regularised rows, the condense-and-sweep pass, and the second-order correction.
//! The KKT error is in `kkt_error.rs`.

use super::*;

pub(crate) mod global_riccati;
pub(super) mod globals;
pub mod riccati;
#[cfg(feature = "sparse-ldlt")]
pub(crate) mod sparse_ldlt;
#[cfg(feature = "sparse-ldlt")]
mod sparse_step;

/// What stage `k`'s Hessian takes besides its derivatives: the cost's constant curvature
/// when the derivative pass left it in the constants table (its blocks in the derivatives
/// are then not written), and the stage's SR1 blocks.
#[derive(Clone, Copy)]
pub(super) struct StageCurvature<'c, const NX: usize, const NW: usize, const NE: usize> {
    pub(super) constant: Option<&'c HessianBlocks<NX, NW>>,
    pub(super) qn: Option<&'c QuasiNewton<NX, NW, NE>>,
}

/// A second-order correction's data: the trial point's values, the trial point and the
/// step length `α` that reached it (the residuals become `α r(x) + r(x_trial)`).
pub(super) type Correction<'c, const NX: usize, const NW: usize, const NE: usize, const NC: usize> =
    (&'c [StageValues<NX, NE, NC>], &'c Iterate<NX, NW, NC>, f64);

/// A linear solver of the condensed KKT system. The solver condenses every stage the same
/// way ([`Solver::condense`]); a back-end solves what the condensing leaves, and reports a
/// wrong inertia so that the one inertia-correction loop ([`Solver::newton_step`]) can
/// shift it. Three back-ends: the Riccati recursion ([`Riccati`]), the recursion augmented
/// by the global variables' columns ([`RiccatiWithGlobals`], `globals.rs`), and faer's
/// sparse `LDLᵀ` of the whole condensed matrix ([`SparseLdlt`], `sparse_step.rs`).
pub(super) trait KktBackend<
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
>
{
    /// Every stage condensed into the workspace (from the iteration's derivatives, or a
    /// second-order correction's) and the system solved at the primal shift `delta`: the
    /// step, or `None` if the inertia is wrong at that shift. `Err` if a stage cannot be
    /// condensed or the back-end fails otherwise.
    #[allow(clippy::too_many_arguments)]
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
    ) -> Result<Option<Step<NX, NW, NC>>, Failure>;

    /// The condensed stages solved again at another shift `delta`.
    #[allow(clippy::too_many_arguments)]
    fn solve_again(
        &self,
        s: &Solver<'_, NX, NW, NE, NF, NC>,
        it: &Iterate<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        mu: f64,
        dc: f64,
        delta: f64,
        tm: &mut Timings,
    ) -> Result<Option<Step<NX, NW, NC>>, Failure>;
}

/// The Riccati recursion over the condensed stages, its backward sweep run behind the
/// condensing ([`Solver::condense_and_sweep`]).
pub(super) struct Riccati;

impl<const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    KktBackend<NX, NW, NE, NF, NC> for Riccati
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
        let (swept, t_sweep) = s.condense_workspace(it, ws, mu, dc, delta, correction)?;
        tm.riccati += t_sweep;
        Ok(swept.ok().map(|()| self.step(s, it, ws, mu, dc)))
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
        ws.sweep.reshift(delta);
        let swept = ws.sweep.sweep_all(&ws.lq);
        tm.riccati += t.elapsed().as_secs_f64();
        Ok(swept.ok().map(|()| self.step(s, it, ws, mu, dc)))
    }
}

impl Riccati {
    /// The step from a completed backward sweep: the forward pass and the stages' recovery.
    fn step<const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>(
        &self,
        s: &Solver<'_, NX, NW, NE, NF, NC>,
        it: &Iterate<NX, NW, NC>,
        ws: &Workspace<NX, NW, NE, NF, NC>,
        mu: f64,
        dc: f64,
    ) -> Step<NX, NW, NC> {
        let sol = ws.sweep.forward(&ws.lq, &SVector::zeros());
        s.recover(it, &ws.ders, &ws.terminal, &ws.elim, sol, mu, dc, None)
    }
}

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NF, NC>
{
    /// The back-end of this solve's Newton systems ([`KktBackend`]). `Err` for the sparse
    /// one in a build without it (feature `sparse-ldlt`).
    fn kkt_backend(&self) -> Result<&'static dyn KktBackend<NX, NW, NE, NF, NC>, Failure> {
        if self.opts.kkt == KktMethod::SparseLdlt {
            #[cfg(feature = "sparse-ldlt")]
            return Ok(&sparse_step::SparseLdlt);
            #[cfg(not(feature = "sparse-ldlt"))]
            return Err(Failure::SparseKkt(
                "this build has no sparse LDLᵀ back-end (dmech-ocp's feature sparse-ldlt)".into(),
            ));
        }
        if self.globals.is_some() {
            Ok(&globals::RiccatiWithGlobals)
        } else {
            Ok(&Riccati)
        }
    }

    /// The Newton step at `it` and the primal shift it took: every stage condensed and the
    /// system solved with no shift, and, while its inertia is wrong (some stage's `H_uu`
    /// not positive definite, or the globals' reduced system of the wrong inertia), again
    /// over the condensed stages with the next shift of the inertia correction. `Err` when
    /// a stage cannot be condensed, the back-end fails, or the shifts are exhausted.
    pub(super) fn newton_step(
        &self,
        it: &Iterate<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        inertia: &mut InertiaCorrection,
        mu: f64,
        dc: f64,
        tm: &mut Timings,
    ) -> Result<(Step<NX, NW, NC>, f64), Failure> {
        let t1 = Instant::now();
        let backend = self.kkt_backend()?;
        let mut delta = 0.0;
        let mut solved = backend.condense_and_solve(self, it, ws, mu, dc, delta, None, tm)?;
        let step = loop {
            tm.factorizations += 1;
            if let Some(step) = solved {
                break step;
            }
            delta = inertia.next(delta).ok_or(Failure::InertiaCorrection)?;
            solved = backend.solve_again(self, it, ws, mu, dc, delta, tm)?;
        };
        inertia.succeeded(delta);
        tm.kkt += t1.elapsed().as_secs_f64();
        Ok((step, delta))
    }

    /// The second-order correction step: the KKT system of the iterate (same curvature,
    /// same inertia shift `delta`) with the residuals of the dynamics and the stage
    /// equalities replaced by `α r(x) + r(x_trial)` (`correction`), condensed into the
    /// iteration's buffers (its own step is already recovered from them). `None` if it
    /// cannot be solved.
    pub(super) fn second_order_correction(
        &self,
        it: &Iterate<NX, NW, NC>,
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
        correction: Correction<'_, NX, NW, NE, NC>,
        mu: f64,
        dc: f64,
        delta: f64,
    ) -> Option<Step<NX, NW, NC>> {
        let mut untimed = Timings::default();
        self.kkt_backend()
            .ok()?
            .condense_and_solve(self, it, ws, mu, dc, delta, Some(correction), &mut untimed)
            .ok()
            .flatten()
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

    /// The terminal stage of the LQ problem: the terminal cost's curvature and gradient (the
    /// curvature of `yᵀr` of the terminal equalities with it, `terminal.hxx`), the state
    /// equalities at `x_N`, and the terminal equalities' dual-regularised rows.
    pub(super) fn terminal_lq(
        &self,
        it: &Iterate<NX, NW, NC>,
        terminal: &TerminalDerivatives<NX>,
        dc: f64,
    ) -> (SMatrix<f64, NX, NX>, SVector<f64, NX>) {
        let (mut q_n, mut q_vec_n) = (terminal.hxx, terminal.gx);
        self.add_state_equalities(self.n, it, dc, &mut q_n, &mut q_vec_n);
        self.add_terminal_equalities(it, terminal, dc, &mut q_n, &mut q_vec_n);
        (q_n, q_vec_n)
    }

    /// The quadratic terms of the terminal equalities `r(x_N) = 0`: the rows `∇r_j` with
    /// the regularisation `δ_c`, as a state equality's unit row, `‖∇r δx + r‖²/(2δ_c)`
    /// and the multiplier `y_j`.
    fn add_terminal_equalities(
        &self,
        it: &Iterate<NX, NW, NC>,
        terminal: &TerminalDerivatives<NX>,
        dc: f64,
        q_mat: &mut SMatrix<f64, NX, NX>,
        q: &mut SVector<f64, NX>,
    ) {
        let y = self.terminal_multipliers(&it.y);
        for (j, (r, a)) in terminal
            .equalities
            .iter()
            .zip(&terminal.equality_gradients)
            .enumerate()
        {
            q_mat.ger(1.0 / dc, a, a, 1.0);
            *q += a * (y.get(j).copied().unwrap_or(0.0) + r / dc);
        }
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
        correction: Option<Correction<'_, NX, NW, NE, NC>>,
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

//! Ending a solve: the returned point, its recomputed violation, and the recovery of
//! multipliers; the checks of the problem's declarations (affine in the state, constant
//! cost curvature).

use super::*;

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NF, NC>
{
    /// If the problem declares its cost and inequalities affine in the state, check it at
    /// the first, middle and last stage of the start (with unit inequality multipliers).
    pub(super) fn check_affine_declaration(&self, it: &Iterate<NX, NW, NC>) -> Option<Failure> {
        if !self.p.affine_in_state() || self.n == 0 {
            return None;
        }
        let ones = SVector::<f64, NC>::repeat(1.0);
        for k in [0, self.n / 2, self.n - 1] {
            let (hxx, hxw) = self.p.state_curvature(k, &it.x[k], &it.w[k], &ones);
            let worst = hxx.amax().max(hxw.amax());
            if worst != 0.0 {
                return Some(Failure::NotAffineInState {
                    stage: k,
                    entry: worst,
                });
            }
        }
        None
    }

    /// If the problem declares its cost curvature constant, each stage's constants at the
    /// start (the solver's copy for every iteration, [`StageConstants`]); empty if it does
    /// not. With the state gradients when the problem also declares itself affine in the
    /// state: `∇_x ℓ_k` and `C_x` are then constant. What is kept is checked at the first,
    /// middle and last stage against its value at a second point with other inequality
    /// multipliers: for a quadratic cost and affine inequalities the second-order parts of
    /// the dual arithmetic never read the point, nor do the state gradients of a function
    /// affine in the state, so the two agree to round-off (`64 ε` of the largest entry is
    /// allowed).
    pub(super) fn stage_constants(
        &self,
        it: &Iterate<NX, NW, NC>,
    ) -> Result<ConstantsTable<NX, NW, NC>, Failure> {
        if !self.p.constant_cost_curvature() || self.n == 0 {
            return Ok(ConstantsTable::default());
        }
        let affine = self.p.affine_in_state();
        let at = |k: usize, x: &SVector<f64, NX>, w: &SVector<f64, NW>, zeta: &SVector<f64, NC>| {
            let state_gradients = affine.then(|| self.p.state_gradients(k, x, w));
            StageConstants {
                curvature: self.p.cost_curvature(k, x, w, zeta),
                state_gradients,
            }
        };
        let at_stage = |k: usize| at(k, &it.x[k], &it.w[k], &(it.z_hi[k] - it.z_lo[k]));
        // Kept only where a stage's constants differ from the first stage's: most problems'
        // stages share one value, and a whole per-stage array (13 MB on the eight) was the
        // start's largest allocation.
        let first = at_stage(0);
        let mut differing: Vec<Option<Box<StageConstants<NX, NW, NC>>>> = vec![None; self.n];
        par_fill(&mut differing, self.opts.threads, |k| {
            let c = at_stage(k);
            (c != first).then(|| Box::new(c))
        });
        let constants =
            ConstantsTable::new(differing.iter().map(|d| d.as_deref().unwrap_or(&first)));
        let shift = |i: usize| 0.25 + 0.125 * (i % 3) as f64;
        for k in [0, self.n / 2, self.n - 1] {
            let x = SVector::<f64, NX>::from_fn(|i, _| it.x[k][i] + shift(i));
            let w = SVector::<f64, NW>::from_fn(|i, _| it.w[k][i] - shift(i + 1));
            let zeta = SVector::<f64, NC>::from_fn(|i, _| 1.0 + shift(i));
            let kept = constants.get(k).expect("a value per stage");
            let there = at(k, &x, &w, &zeta);
            let (rxx, rxw, rww) = &kept.curvature;
            let (hxx, hxw, hww) = &there.curvature;
            let mut scale = rxx.amax().max(rxw.amax()).max(rww.amax());
            let mut diff = (hxx - rxx)
                .amax()
                .max((hxw - rxw).amax())
                .max((hww - rww).amax());
            if let (Some((gx, cx)), Some((hx, dx))) =
                (&kept.state_gradients, &there.state_gradients)
            {
                scale = scale.max(gx.amax()).max(cx.amax());
                diff = diff.max((hx - gx).amax()).max((dx - cx).amax());
            }
            if diff > 64.0 * f64::EPSILON * scale {
                return Err(Failure::CurvatureNotConstant {
                    stage: k,
                    change: diff,
                    scale,
                });
            }
        }
        Ok(constants)
    }

    pub(super) fn finish(
        &self,
        status: Status,
        it: Iterate<NX, NW, NC>,
        iterations: usize,
        mut tm: Timings,
        t_start: Instant,
    ) -> SolveResult<NX, NW, NC> {
        tm.total = t_start.elapsed().as_secs_f64();
        let mut objective = (0..self.n)
            .map(|k| self.p.cost(k, &it.x[k], &it.w[k]))
            .sum::<f64>()
            + self.p.terminal_cost(&it.x[self.n]);
        let mut max_violation = self.max_violation(&it.x, &it.w);
        if let Some(gs) = &self.globals {
            objective += gs.cost(&it.globals.p);
            max_violation = max_violation.max(gs.violation(&it.globals.p).1);
        }
        let duality_gap = self.duality_gap(&it);
        SolveResult {
            status,
            iterate: it,
            iterations,
            objective,
            max_violation,
            duality_gap,
            timings: tm,
        }
    }

    /// The step from the LQ solution: each stage's decision (with `dw_globals[k]` added,
    /// the globals' part of a problem that has them), slacks and bound multipliers, and the
    /// state and terminal equalities' multipliers (`terminal`: the last stage's derivatives).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn recover(
        &self,
        it: &Iterate<NX, NW, NC>,
        ders: &[StageDerivatives<NX, NW, NE, NC>],
        terminal: &TerminalDerivatives<NX>,
        elim: &[Elimination<NX, NW, NF>],
        sol: LqSolution<NX, NF>,
        mu: f64,
        dc: f64,
        dw_globals: Option<&[SVector<f64, NW>]>,
    ) -> Step<NX, NW, NC> {
        let LqSolution {
            x: dx,
            u: du,
            lambda,
        } = sol;
        let n = self.n;
        // Per stage (δw, δt_lo, δt_hi, δz_lo, δz_hi), in parallel.
        type StageStep<const NW: usize, const NC: usize> =
            (SVector<f64, NW>, [SVector<f64, NC>; 4]);
        let per_stage: Vec<StageStep<NW, NC>> = par_collect(n, self.opts.threads, |k| {
            let c = &elim[k];
            let mut dwk = c.w0 + c.wx * dx[k] + c.wu * du[k];
            if let Some(g) = dw_globals {
                dwk += g[k];
            }
            let d = &ders[k];
            let cd = d.cx * dx[k] + d.cw * dwk;
            let b = &self.bounds[k];
            let [mut dt_lo, mut dt_hi, mut dz_lo, mut dz_hi] = [SVector::zeros(); 4];
            for i in 0..NC {
                if b.has_lo[i] > 0.0 {
                    let r = d.c[i] - b.lo[i] - it.t_lo[k][i];
                    dt_lo[i] = cd[i] + r;
                    dz_lo[i] = mu / it.t_lo[k][i]
                        - it.z_lo[k][i]
                        - it.z_lo[k][i] / it.t_lo[k][i] * dt_lo[i];
                }
                if b.has_hi[i] > 0.0 {
                    let r = b.hi[i] - d.c[i] - it.t_hi[k][i];
                    dt_hi[i] = r - cd[i];
                    dz_hi[i] = mu / it.t_hi[k][i]
                        - it.z_hi[k][i]
                        - it.z_hi[k][i] / it.t_hi[k][i] * dt_hi[i];
                }
            }
            (dwk, [dt_lo, dt_hi, dz_lo, dz_hi])
        });
        let dw = per_stage.iter().map(|s| s.0).collect();
        let dt_lo = per_stage.iter().map(|s| s.1[0]).collect();
        let dt_hi = per_stage.iter().map(|s| s.1[1]).collect();
        let dz_lo = per_stage.iter().map(|s| s.1[2]).collect();
        let dz_hi = per_stage.iter().map(|s| s.1[3]).collect();
        let mut y: Vec<f64> = self
            .eqs
            .iter()
            .enumerate()
            .map(|(j, e)| it.y[j] + (dx[e.stage][e.index] + it.x[e.stage][e.index] - e.value) / dc)
            .collect();
        let y_terminal = self.terminal_multipliers(&it.y);
        for (j, (r, a)) in terminal
            .equalities
            .iter()
            .zip(&terminal.equality_gradients)
            .enumerate()
        {
            y.push(y_terminal.get(j).copied().unwrap_or(0.0) + (a.dot(&dx[n]) + r) / dc);
        }
        Step {
            dx,
            dw,
            lambda,
            dt_lo,
            dt_hi,
            dz_lo,
            dz_hi,
            y,
            globals: Default::default(),
        }
    }
}

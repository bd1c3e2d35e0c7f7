//! The per-iteration pass over the stages: exact derivatives, the SR1 update, each stage's
//! part of the KKT error and its values, in parallel, and the terminal cost's derivatives;
//! and the buffers it and the Newton step keep from one iteration to the next.

use super::*;

/// The per-stage buffers of a solve, overwritten every iteration: derivatives, the
/// condensed stages and their eliminations, what the derivative pass leaves besides the
/// derivatives, and the SR1 curvature (empty without quasi-Newton).
pub(super) struct Workspace<
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NU: usize,
    const NC: usize,
> {
    pub(super) ders: Vec<StageDerivatives<NX, NW, NE, NC>>,
    pub(super) lq: Vec<LqStage<NX, NU>>,
    pub(super) elim: Vec<Elimination<NX, NW, NU>>,
    pub(super) aux: Vec<StageAux<NX, NE, NC>>,
    pub(super) qn: Vec<QuasiNewton<NX, NW, NE>>,
    /// What is computed once per stage when the problem declares its cost curvature
    /// constant (empty otherwise; [`ConstantsTable`]).
    pub(super) constants: ConstantsTable<NX, NW, NC>,
    pub(super) terminal: TerminalDerivatives<NX>,
    /// The Riccati sweep of the Newton step, its buffers kept from one iteration to the next
    /// (empty until the first restart: the sparse KKT path never sweeps).
    pub(super) sweep: BackwardSweep<NX, NU>,
    /// Each stage's coupling to the globals (empty without them; `globals.rs`).
    pub(super) couplings: Vec<globals::StageCoupling<NX, NW, NU>>,
}

impl<const NX: usize, const NW: usize, const NE: usize, const NU: usize, const NC: usize>
    Workspace<NX, NW, NE, NU, NC>
{
    /// Every per-stage array for `n` stages, built on `threads` threads ([`par_vec`]).
    pub(super) fn new(n: usize, quasi_newton: bool, threads: usize) -> Self {
        Workspace {
            ders: par_vec(n, threads, |_| StageDerivatives::zeros()),
            lq: par_vec(n, threads, |_| LqStage::zeros()),
            elim: par_vec(n, threads, |_| Elimination::zeros()),
            aux: par_vec(n, threads, |_| StageAux::zeros()),
            qn: par_vec(if quasi_newton { n } else { 0 }, threads, |_| {
                QuasiNewton::new()
            }),
            constants: ConstantsTable::default(),
            terminal: TerminalDerivatives {
                cost: 0.0,
                gx: SVector::zeros(),
                hxx: SMatrix::zeros(),
            },
            couplings: Vec::new(),
            sweep: BackwardSweep::new(0, &SMatrix::zeros(), &SVector::zeros(), 0.0),
        }
    }

    /// Forget the SR1 curvature (back to the exact cost curvature alone).
    pub(super) fn reset_quasi_newton(&mut self) {
        for q in self.qn.iter_mut() {
            q.reset();
        }
    }
}

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NU: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NU, NC>
{
    /// Every stage's derivatives at `it`, with, while they are in cache, its SR1 update, its
    /// part of the KKT error and its values (reading the 36 MB of derivatives again for
    /// these was 5–7 % of a plan). `vals` are the stage values at `it` (the line search's
    /// at the point it accepted): the stage equality's value is taken from them, not
    /// evaluated again (that evaluation was a fifth of the pass).
    pub(super) fn derivative_pass(
        &self,
        it: &Iterate<NX, NW, NC>,
        vals: &[StageValues<NX, NE, NC>],
        ws: &mut Workspace<NX, NW, NE, NU, NC>,
        tm: &mut Timings,
    ) {
        let o = &self.opts;
        let t0 = Instant::now();
        let ws_constants = &ws.constants;
        let derivatives = |k: usize, d: &mut StageDerivatives<NX, NW, NE, NC>| {
            let zeta = it.z_hi[k] - it.z_lo[k];
            let lam = &it.lambda[k];
            let (x, w) = (&it.x[k], &it.w[k]);
            let known = Precomputed {
                constants: ws_constants.get(k),
                equality: Some(&vals[k].e),
            };
            if self.table_curvature(k, ws_constants).is_some() {
                // The condensing reads the curvature from the table.
                self.p.first_derivatives_into(d, k, x, w, known);
            } else {
                let lam_exact = o.exact_hessian.then_some(lam);
                self.p.derivatives_into(d, k, x, w, &zeta, lam_exact, known);
            }
            d.nu = d.equality_multiplier(lam, &zeta);
        };
        let finish =
            |k: usize, d: &StageDerivatives<NX, NW, NE, NC>, a: &mut StageAux<NX, NE, NC>| {
                a.kkt = self.kkt_stage(k, it, d);
                a.vals = StageValues {
                    f: d.f,
                    e: d.e,
                    cost: d.cost,
                    c: d.c,
                };
            };
        if o.quasi_newton {
            par_zip3(
                &mut ws.ders,
                &mut ws.qn,
                &mut ws.aux,
                o.threads,
                |k, d, q, a| {
                    derivatives(k, d);
                    let nu = d.nu.unwrap_or_else(SVector::zeros);
                    q.update(o.sr1_skip, &it.x[k], &it.w[k], d, &it.lambda[k], &nu);
                    finish(k, d, a);
                },
            );
        } else {
            par_zip(&mut ws.ders, &mut ws.aux, o.threads, |k, d, a| {
                derivatives(k, d);
                finish(k, d, a);
            });
        }
        ws.terminal = self.p.terminal_derivatives(&it.x[self.n]);
        tm.derivatives += t0.elapsed().as_secs_f64();
    }
}

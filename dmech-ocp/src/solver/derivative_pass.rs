//! The per-iteration pass over the stages: exact derivatives, the SR1 update, each stage's
//! part of the KKT error and its values, in parallel, and the terminal cost's derivatives;
//! and the buffers it and the Newton step keep from one iteration to the next.

use super::parallel::{par_resize, with_room};
use super::*;
use std::any::Any;
use std::cell::RefCell;

/// The per-stage buffers of a solve, overwritten every iteration: derivatives, the
/// condensed stages and their eliminations, what the derivative pass leaves besides the
/// derivatives, and the SR1 curvature (empty without quasi-Newton).
pub(super) struct Workspace<
    const NX: usize,
    const NW: usize,
    const NE: usize,
    const NF: usize,
    const NC: usize,
> {
    pub(super) ders: Vec<StageDerivatives<NX, NW, NE, NC>>,
    pub(super) lq: Vec<LqStage<NX, NF>>,
    pub(super) elim: Vec<Elimination<NX, NW, NF>>,
    pub(super) aux: Vec<StageAux<NX, NE, NC>>,
    pub(super) qn: Vec<QuasiNewton<NX, NW, NE>>,
    /// What is computed once per stage when the problem declares its cost curvature
    /// constant (empty otherwise; [`ConstantsTable`]).
    pub(super) constants: ConstantsTable<NX, NW, NC>,
    pub(super) terminal: TerminalDerivatives<NX>,
    /// The Riccati sweep of the Newton step, its buffers kept from one iteration to the next
    /// (empty until the first restart: the sparse KKT path never sweeps).
    pub(super) sweep: BackwardSweep<NX, NF>,
    /// Each stage's coupling to the globals (empty without them; `globals.rs`).
    pub(super) couplings: Vec<kkt::globals::StageCoupling<NX, NW, NF>>,
}

/// Inside [`reuse_workspaces`] on this thread: the stage capacity of new workspaces, and
/// the one the last finished solve left.
struct WorkspacePool {
    capacity: usize,
    spare: Option<Box<dyn Any>>,
}

thread_local! {
    static POOL: RefCell<Option<WorkspacePool>> = const { RefCell::new(None) };
}

/// `f` with the solves it runs on this thread handing their per-stage buffers on: a solve
/// builds its workspace in the one the previous solve of the same sizes left, and new
/// ones are allocated with room for `stages` stages (untouched room costs no memory).
/// Why: a mesh sequence runs up to five solves of 1059 … 4235 stages in a row, and each
/// built its 20–80 MB of buffers in fresh pages: the kernel zeroing them was 5 % of the
/// eight's samples. The buffers are freed when `f` returns.
pub fn reuse_workspaces<R>(stages: usize, f: impl FnOnce() -> R) -> R {
    struct Restore(Option<WorkspacePool>);
    impl Drop for Restore {
        fn drop(&mut self) {
            let outer = self.0.take();
            POOL.with(|p| *p.borrow_mut() = outer);
        }
    }
    let outer = POOL.with(|p| {
        p.borrow_mut().replace(WorkspacePool {
            capacity: stages,
            spare: None,
        })
    });
    let _restore = Restore(outer);
    f()
}

impl<const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Workspace<NX, NW, NE, NF, NC>
{
    /// Every per-stage array for `n` stages, built on `threads` threads, in the buffers a
    /// finished solve left if there are some ([`reuse_workspaces`]).
    pub(super) fn new(n: usize, quasi_newton: bool, threads: usize) -> Self {
        let (capacity, spare) = POOL.with(|p| match p.borrow_mut().as_mut() {
            Some(pool) => (pool.capacity.max(n), pool.spare.take()),
            None => (n, None),
        });
        let ws = match spare.and_then(|s| s.downcast::<Self>().ok()) {
            Some(ws) => *ws,
            None => Self::empty(capacity),
        };
        ws.rebuilt(n, quasi_newton, threads)
    }

    /// Leave the buffers to the next solve ([`reuse_workspaces`]); dropped outside it.
    pub(super) fn retire(self) {
        POOL.with(|p| {
            if let Some(pool) = p.borrow_mut().as_mut() {
                pool.spare = Some(Box::new(self));
            }
        });
    }

    /// This workspace for a new solve of `n` stages: the stages it keeps are overwritten
    /// before they are read, except the SR1 curvature, which starts over.
    fn rebuilt(mut self, n: usize, quasi_newton: bool, threads: usize) -> Self {
        par_resize(&mut self.ders, n, threads, |_| StageDerivatives::zeros());
        par_resize(&mut self.lq, n, threads, |_| LqStage::zeros());
        par_resize(&mut self.elim, n, threads, |_| Elimination::zeros());
        par_resize(&mut self.aux, n, threads, |_| StageAux::zeros());
        let n_qn = if quasi_newton { n } else { 0 };
        self.qn.truncate(n_qn);
        par_update(&mut self.qn, threads, |_, q| q.start_over());
        par_resize(&mut self.qn, n_qn, threads, |_| QuasiNewton::new());
        self.constants = ConstantsTable::default();
        self.couplings.clear();
        self
    }

    /// No stages, room for `capacity` of them.
    fn empty(capacity: usize) -> Self {
        Workspace {
            ders: with_room(capacity),
            lq: with_room(capacity),
            elim: with_room(capacity),
            aux: with_room(capacity),
            qn: with_room(capacity),
            constants: ConstantsTable::default(),
            terminal: TerminalDerivatives::zeros(),
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

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NF, NC>
{
    /// Every stage's derivatives at `it`, with, while they are in cache, its SR1 update, its
    /// part of the KKT error and its values (reading the 36 MB of derivatives again for
    /// these was 5–7 % of a plan). `vals` are the stage values at `it` (the line search's
    /// at the point it accepted): the stage equality's value is taken from them, not
    /// evaluated again (the eight 3.5 % faster).
    pub(super) fn derivative_pass(
        &self,
        it: &Iterate<NX, NW, NC>,
        vals: &[StageValues<NX, NE, NC>],
        ws: &mut Workspace<NX, NW, NE, NF, NC>,
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
                let lam_exact = (o.curvature == Curvature::Exact).then_some(lam);
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
        if o.curvature == Curvature::Sr1 {
            par_zip3(
                &mut ws.ders,
                &mut ws.qn,
                &mut ws.aux,
                o.threads,
                |k, d, q, a| {
                    // Read before `derivatives` overwrites them.
                    let previous = q.previous_jacobians(d);
                    derivatives(k, d);
                    let nu = d.nu.unwrap_or_else(SVector::zeros);
                    q.update(
                        o.sr1_skip,
                        &it.x[k],
                        &it.w[k],
                        previous,
                        d,
                        &it.lambda[k],
                        &nu,
                    );
                    finish(k, d, a);
                },
            );
        } else {
            par_zip(&mut ws.ders, &mut ws.aux, o.threads, |k, d, a| {
                derivatives(k, d);
                finish(k, d, a);
            });
        }
        ws.terminal = self
            .p
            .terminal_derivatives(&it.x[self.n], self.terminal_multipliers(&it.y));
        tm.derivatives += t0.elapsed().as_secs_f64();
    }
}

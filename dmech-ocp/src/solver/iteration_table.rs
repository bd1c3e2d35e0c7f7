//! The iteration table (`IpOptions::verbose`, on stderr): IPOPT's columns, one row per
//! iterate (`docs/solver.md`, "The algorithm").

use super::*;

impl<'a, const NX: usize, const NW: usize, const NE: usize, const NF: usize, const NC: usize>
    Solver<'a, NX, NW, NE, NF, NC>
{
    pub(super) fn print_header(&self) {
        if self.opts.verbose {
            // Best-effort: a closed or full stderr must not abort the solve (eprintln! panics).
            let _ = writeln!(
                std::io::stderr(),
                "{:>4} {:>14} {:>9} {:>9} {:>6} {:>9} {:>9} {:>9} {:>3} {:>7}",
                "iter",
                "objective",
                "inf_pr",
                "inf_du",
                "lg(mu)",
                "lg(rg)",
                "alpha_du",
                "alpha_pr",
                "ls",
                "time"
            );
        }
    }

    /// One row of the iteration table: the iterate's measures and the step that led to it.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn print_row(
        &self,
        iter: usize,
        m: &Measures,
        kkt: &KktError,
        mu: f64,
        shift: f64,
        last: &LineSearch<NX, NW, NE, NC>,
        t_start: Instant,
    ) {
        if let Some(observer) = &self.opts.observer {
            (observer.0)(&IterationReport {
                iteration: iter,
                stages: self.n,
                objective: m.objective,
                primal_infeasibility: kkt.primal,
                dual_infeasibility: kkt.dual,
                barrier: mu,
                elapsed_s: t_start.elapsed().as_secs_f64(),
            });
        }
        if self.opts.verbose {
            let _ =
                writeln!(
                std::io::stderr(),
                "{:>4} {:>14.7e} {:>9.2e} {:>9.2e} {:>6.1} {:>9} {:>9.2e} {:>9.2e} {:>3} {:>6.2}s",
                iter,
                m.objective,
                kkt.primal,
                kkt.dual,
                mu.log10(),
                if shift > 0.0 { format!("{:.1}", shift.log10()) } else { "-".into() },
                last.alpha_dual,
                last.alpha,
                last.trials,
                t_start.elapsed().as_secs_f64()
            );
        }
    }
}

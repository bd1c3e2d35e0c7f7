//! Command-line arguments shared by the robots' tools.

use dmech_ocp::ipm::IpOptions;

/// `--hessian`: the curvature of the constraints in the solver's Newton systems.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum HessianArg {
    /// A partitioned SR1 approximation per stage, updated from the exact Jacobians
    Sr1,
    /// The exact second derivatives (by blocks for the first-order VI; several times the
    /// cost of an SR1 iteration, docs/ocp.md)
    Exact,
}

impl HessianArg {
    /// `opts` with this curvature.
    pub fn apply(self, opts: IpOptions) -> IpOptions {
        let exact = self == HessianArg::Exact;
        IpOptions {
            exact_hessian: exact,
            quasi_newton: !exact,
            ..opts
        }
    }
}

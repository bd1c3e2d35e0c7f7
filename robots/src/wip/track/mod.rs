//! `wip track`: the paper's closed loop (feedforward plan + LQ controller + guidance +
//! observer) with sensor rates, delays and noise (docs/tracking.md).

pub mod closed_loop;
pub mod dare;
pub mod guidance;
pub mod linear;
pub mod lq;
pub mod monte_carlo;
pub mod mpc;
pub mod nmpc;
pub mod observer;
pub mod report;
pub mod request;
pub mod simulated_robot;

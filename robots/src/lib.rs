//! Robots built on `dmech`: the wheeled inverted pendulum (WIP) with DC motors, and the
//! file formats of the `wip` tool.

pub mod io;
pub mod plot;
pub mod wip;

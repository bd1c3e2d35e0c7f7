//! Robots built on `dmech`: the wheeled inverted pendulum (WIP) with DC motors, a
//! front-wheel-steered car, and the file formats of their tools (`wip`, `car`).

pub mod car;
pub mod check;
pub mod cli;
pub mod diagnose;
pub mod io;
pub mod plot;
pub mod pose_path;
pub mod simulation;
pub mod snakeboard;
pub mod wip;

/// The tutorial `docs/add-a-robot.md`: its code blocks are compiled and run as doc tests.
#[cfg(doctest)]
#[doc = include_str!("../../docs/add-a-robot.md")]
pub struct AddARobotTutorial;

//! The `wip`, `car` and `snakeboard` tools through their binaries, in one binary: every test file of
//! `tests/` is compiled and linked as its own binary, so together these compile the shared
//! helpers (`common`) and the generic library code they call directly (the closed loop of
//! `track`) once, and link once.
//!
//! - `car`: `car plan`, `car simulate` and `car track`;
//! - `car_nmpc`: `car track --controller nmpc` on the built-in problems;
//! - `car_sensors`: `car track` on the car's sensors through the observer, the delay sweep;
//! - `diagnose`: `wip generate` and `wip diagnose`;
//! - `hostile`: both tools under hostile use, second round (issue 57);
//! - `plan`: `wip plan`;
//! - `regbot`: `wip diagnose` on the real REGBOT logs of `data/regbot`;
//! - `reliability`: every subcommand under careless or hostile use (issue 24);
//! - `simulate`: `wip simulate`;
//! - `snakeboard`: `snakeboard plan` and `snakeboard simulate`;
//! - `track`: `wip track` and the closed loop;
//! - `track_nmpc`: `wip track --controller nmpc` on the eight and the zigzag;
//! - `track_push`: `wip track --push-at T --push W`.
//!
//! One module's tests: `cargo test -p robots --test cli -- plan::`.

#[path = "../common/mod.rs"]
mod common;

mod car;
mod car_diagnose;
mod car_nmpc;
mod car_sensors;
mod diagnose;
mod hostile;
mod plan;
mod regbot;
mod reliability;
mod simulate;
mod snakeboard;
mod track;
mod track_nmpc;
mod track_push;

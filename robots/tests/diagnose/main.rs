//! The diagnosis tests, in one binary: every test file of `tests/` is compiled and linked
//! as its own binary, and these all instantiate the same generic code (the diagnose
//! pipeline over `WipPlant`), so together they pay for it once.
//!
//! - `hidden`: an effect outside the catalogue is reported `unexplained`, with where it acts;
//! - `prediction`: the model's prediction from the true state follows the truth;
//! - `recovery`: hidden effects named and their parameters recovered (`WIP_DIAGNOSE_SEED`,
//!   `WIP_DIAGNOSE_EFFECTS`; the full matrix is ignored by default);
//! - `readings`: a gyro offset and an encoder scale named by the generic reading
//!   hypotheses, with their parameters;
//! - `restart`: a fit's window in the wrong basin is restarted to the truth;
//! - `toy`: the machinery on a driven pendulum that knows nothing of the WIP.
//!
//! One module's tests: `cargo test -p robots --test diagnose -- recovery::`.

mod car;
mod hidden;
mod prediction;
mod readings;
mod recovery;
mod restart;
mod toy;

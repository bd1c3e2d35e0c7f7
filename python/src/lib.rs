//! `dmech._native`: the Rust side of the Python package `dmech`. Each function takes plain
//! Python values (numbers, strings, JSON text, CSV text) and returns dictionaries of
//! numbers and tables; the package's Python modules (`python/dmech/`) turn them into result
//! objects with numpy arrays and map [`errors::NativeError`] onto the documented exception
//! hierarchy. Every solve, simulation, closed loop and diagnosis runs with the GIL
//! released.

use pyo3::prelude::*;

mod car;
mod errors;
mod options;
mod snakeboard;
mod table;
mod wip;
mod wip_diagnose;
mod wip_track;

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("NativeError", m.py().get_type::<errors::NativeError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    wip::register(m)?;
    wip_track::register(m)?;
    wip_diagnose::register(m)?;
    car::register(m)?;
    snakeboard::register(m)?;
    Ok(())
}

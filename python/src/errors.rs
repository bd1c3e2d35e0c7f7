//! The one exception the extension raises, `NativeError(kind, message)`: `kind` says which
//! documented exception the Python side raises (`dmech.errors`), `message` is the command
//! line's one-line message.

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::PyErr;

create_exception!(
    _native,
    NativeError,
    PyException,
    "A failure of the native code: args (kind, message)."
);

/// Which exception of `dmech.errors` a failure becomes.
#[derive(Clone, Copy, Debug)]
pub enum Kind {
    /// A malformed request or an input that was refused before the run (`BadInputError`).
    BadInput,
    /// A run that started and failed: a simulation step, a closed loop (`RunError`).
    Run,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::BadInput => "bad_input",
            Kind::Run => "run",
        }
    }
}

/// The exception for `message` of `kind`.
pub fn native(kind: Kind, message: impl std::fmt::Display) -> PyErr {
    NativeError::new_err((kind.name(), message.to_string()))
}

/// A refused input.
pub fn bad_input(message: impl std::fmt::Display) -> PyErr {
    native(Kind::BadInput, message)
}

/// A failed run.
pub fn run_failed(message: impl std::fmt::Display) -> PyErr {
    native(Kind::Run, message)
}

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

/// A Python callback called from native code that runs without the GIL: each call
/// attaches to the interpreter; the first exception it raises is kept (the run goes on)
/// and raised when the run returns ([`Callback::finish`]).
pub struct Callback {
    f: pyo3::Py<pyo3::PyAny>,
    raised: std::sync::Mutex<Option<PyErr>>,
}

impl Callback {
    /// Wrap `f`.
    pub fn new(f: pyo3::Py<pyo3::PyAny>) -> Self {
        Callback {
            f,
            raised: std::sync::Mutex::new(None),
        }
    }

    /// Call it with the arguments `make` builds, unless it raised before.
    pub fn call<A>(&self, make: impl FnOnce(pyo3::Python<'_>) -> A)
    where
        A: for<'py> pyo3::call::PyCallArgs<'py>,
    {
        let mut raised = self.raised.lock().unwrap_or_else(|e| e.into_inner());
        if raised.is_some() {
            return;
        }
        pyo3::Python::attach(|py| {
            if let Err(e) = self.f.call1(py, make(py)) {
                *raised = Some(e);
            }
        });
    }

    /// `Err` with the callback's first exception, if it raised.
    pub fn finish(&self) -> pyo3::PyResult<()> {
        match self.raised.lock().unwrap_or_else(|e| e.into_inner()).take() {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }
}

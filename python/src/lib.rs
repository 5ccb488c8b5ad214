//! `furfit` for Python (issue 63): the library's synthesis, loaders, fitter and renderer
//! with numpy arrays in and out. Every number comes from the same library calls the CLI
//! makes (`src/cli/synth.rs`, `src/cli/fit.rs`, `src/cli/render.rs`), so `furfit.synth`
//! returns the values `furfit synth` writes and `furfit.fit` the fit `furfit fit` writes.
//!
//! Long calls (fit, render, loading) run on a worker thread with the GIL released
//! ([`run_interruptible`]); the calling thread polls Python's signal handlers, and Ctrl-C
//! sets the call's [`Cancel`](furfit::cancel::Cancel) token and raises
//! `KeyboardInterrupt` once the work has stopped, so the interpreter stays usable. A
//! synthesis, which has no cancellation point, runs on the calling thread without the
//! GIL.

mod convert;
mod fit;
mod profile;
mod render;
mod synth;

use furfit::cancel::Cancel;
use pyo3::exceptions::{
    PyKeyboardInterrupt, PyOSError, PyRuntimeError, PyUserWarning, PyValueError,
};
use pyo3::prelude::*;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

/// How often a waiting call looks at Python's signal handlers: Ctrl-C is answered within
/// this (plus the work's own step to the next cancellation check).
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// A library error as the Python exception of its kind, with the library's message:
/// `OSError` (with its errno, so `FileNotFoundError` and kin) for files, `ValueError` for
/// parameters, angles and options, `KeyboardInterrupt` for a cancelled call.
pub(crate) fn py_err(e: furfit::Error) -> PyErr {
    use furfit::Error as E;
    let msg = e.to_string();
    match e {
        E::Io { err, .. } => match err.raw_os_error() {
            Some(errno) => PyOSError::new_err((errno, msg)),
            None => PyOSError::new_err(msg),
        },
        E::Parse { .. } | E::Array { .. } | E::File { .. } => PyOSError::new_err(msg),
        E::Param { .. } | E::Invalid(_) => PyValueError::new_err(msg),
        E::Interrupted => PyKeyboardInterrupt::new_err(msg),
    }
}

/// An error of the CLI's option parsers (`anyhow`): the library error inside it if there
/// is one, else a `ValueError` with the whole chain.
pub(crate) fn py_err_any(e: anyhow::Error) -> PyErr {
    match e.downcast::<furfit::Error>() {
        Ok(e) => py_err(e),
        Err(e) => PyValueError::new_err(format!("{e:#}")),
    }
}

/// Say `msg` as a Python `UserWarning` (where the CLI prints a `note:` or `warning:`).
pub(crate) fn warn(py: Python<'_>, msg: &str) -> PyResult<()> {
    let text = std::ffi::CString::new(msg.replace('\0', " ")).expect("no NUL left");
    PyErr::warn(py, &py.get_type::<PyUserWarning>(), &text, 1)
}

/// Run `work` on a worker thread with the GIL released, answering Ctrl-C: while it runs,
/// the calling thread checks Python's signal handlers every [`SIGNAL_POLL`]; when one
/// raises (`KeyboardInterrupt`), `cancel` is set, the worker is waited for (the fit and the
/// renderer stop within a model evaluation or an image row; a synthesis, which has no
/// cancellation point, runs to its end) and the handler's exception is raised.
pub(crate) fn run_interruptible<T: Send>(
    py: Python<'_>,
    cancel: &Cancel,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    let (tx, rx) = mpsc::channel();
    std::thread::scope(|s| {
        s.spawn(move || {
            // The receiver may be gone only if the caller is; nothing to tell then.
            let _ = tx.send(work());
        });
        let mut rx = rx;
        loop {
            // Receiver is Send but not Sync: moved in and out of the GIL-free closure.
            let (back, got) = py.detach(move || {
                let got = rx.recv_timeout(SIGNAL_POLL);
                (rx, got)
            });
            rx = back;
            match got {
                Ok(v) => return Ok(v),
                Err(RecvTimeoutError::Timeout) => {
                    if let Err(e) = py.check_signals() {
                        cancel.cancel();
                        py.detach(move || {
                            let _ = rx.recv();
                        });
                        return Err(e);
                    }
                }
                // The worker panicked; the scope re-raises it when it ends, as a
                // PanicException through PyO3.
                Err(RecvTimeoutError::Disconnected) => return Err(PyRuntimeError::new_err(
                    "furfit: the worker thread ended without a result (a bug: please report it)",
                )),
            }
        }
    })
}

/// Fit fiber reflectance models to goniometric profiles: numpy arrays in and out, the
/// numbers of the `furfit` command line (same library, same calls).
#[pymodule]
fn _furfit(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("TOOL_VERSION", furfit::TOOL_VERSION)?;
    m.add("MAX_GRID_SAMPLES", furfit::grid::MAX_GRID_SAMPLES)?;
    m.add_function(wrap_pyfunction!(synth::synth, m)?)?;
    m.add_function(wrap_pyfunction!(synth::library_synth_seconds, m)?)?;
    m.add_function(wrap_pyfunction!(profile::load_profile, m)?)?;
    m.add_function(wrap_pyfunction!(fit::fit, m)?)?;
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(convert::presets, m)?)?;
    m.add_function(wrap_pyfunction!(convert::bounds, m)?)?;
    m.add_function(wrap_pyfunction!(convert::models, m)?)?;
    m.add_class::<profile::Profile>()?;
    m.add_class::<fit::FitResult>()?;
    Ok(())
}

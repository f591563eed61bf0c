//! quadtex errors as Python exceptions: the operating system's refusals as
//! `OSError` (the subclass its errno selects, e.g. `FileNotFoundError`, with
//! `filename` set), everything else (bad files, bad data, limits) as
//! `ValueError`; messages are quadtex's, naming the file and the field.

use std::path::Path;

use pyo3::PyErr;
use pyo3::exceptions::{PyOSError, PyValueError};

/// A `quadtex-io` error as an exception.
pub(crate) fn io_error(e: quadtex_io::Error) -> PyErr {
    match &e {
        quadtex_io::Error::Io { path, source } => match source.raw_os_error() {
            // OSError(errno, strerror, filename) picks the subclass by errno.
            Some(errno) => {
                let text = source.to_string();
                let suffix = format!(" (os error {errno})");
                let strerror = text.strip_suffix(&suffix).unwrap_or(&text).to_string();
                PyOSError::new_err((errno, strerror, path.display().to_string()))
            }
            None => PyOSError::new_err(e.to_string()),
        },
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// A `quadtex-core` error (the data was refused) as a `ValueError`, prefixed
/// with the file it came from, if any.
pub(crate) fn core_error(e: &quadtex_core::Error, path: Option<&Path>) -> PyErr {
    match path {
        Some(path) => PyValueError::new_err(format!("{}: {e}", path.display())),
        None => PyValueError::new_err(e.to_string()),
    }
}

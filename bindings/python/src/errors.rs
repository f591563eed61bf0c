//! quadtex errors as Python exceptions: the operating system's refusals as
//! `OSError` (the subclass its errno selects, e.g. `FileNotFoundError`, with
//! `errno`, `strerror` and `filename` set), everything else (bad files, bad
//! data, limits) as `ValueError`; messages are quadtex's, naming the file
//! and the field.

use std::io::ErrorKind;
use std::path::Path;

use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;

/// A `quadtex-io` error as an exception.
pub(crate) fn io_error(e: quadtex_io::Error) -> PyErr {
    match &e {
        quadtex_io::Error::Io { path, source } => {
            let filename = path.display().to_string();
            let text = source.to_string();
            let errno = source.raw_os_error().or_else(|| kind_errno(source.kind()));
            // OSError(errno, strerror, filename) picks the subclass by errno.
            match errno {
                Some(errno) => {
                    let suffix = format!(" (os error {errno})");
                    let strerror = text.strip_suffix(&suffix).unwrap_or(&text).to_string();
                    PyOSError::new_err((errno, strerror, filename))
                }
                None => PyOSError::new_err((None::<i32>, text, filename)),
            }
        }
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// The errno of an `io::Error` quadtex made itself (no OS error code), from
/// its kind: e.g. saving over a directory is `EISDIR`. Read from Python's
/// `errno` module, so the numbers are the platform's.
fn kind_errno(kind: ErrorKind) -> Option<i32> {
    let name = match kind {
        ErrorKind::NotFound => "ENOENT",
        ErrorKind::PermissionDenied => "EACCES",
        ErrorKind::AlreadyExists => "EEXIST",
        ErrorKind::IsADirectory => "EISDIR",
        ErrorKind::NotADirectory => "ENOTDIR",
        ErrorKind::DirectoryNotEmpty => "ENOTEMPTY",
        ErrorKind::ReadOnlyFilesystem => "EROFS",
        ErrorKind::StorageFull => "ENOSPC",
        ErrorKind::FileTooLarge => "EFBIG",
        ErrorKind::CrossesDevices => "EXDEV",
        ErrorKind::Interrupted => "EINTR",
        ErrorKind::OutOfMemory => "ENOMEM",
        _ => return None,
    };
    Python::attach(|py| py.import("errno")?.getattr(name)?.extract::<i32>()).ok()
}

/// A `quadtex-core` error (the data was refused) as a `ValueError`, prefixed
/// with the file it came from, if any.
pub(crate) fn core_error(e: &quadtex_core::Error, path: Option<&Path>) -> PyErr {
    match path {
        Some(path) => PyValueError::new_err(format!("{}: {e}", path.display())),
        None => PyValueError::new_err(e.to_string()),
    }
}

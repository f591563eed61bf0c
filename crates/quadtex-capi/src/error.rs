//! Status codes, the thread-local last-error message, and the guard every
//! exported function runs its body in (errors to statuses, panics caught).

use std::cell::RefCell;
use std::ffi::{CStr, CString};
use std::panic::{AssertUnwindSafe, catch_unwind};

/// What a `qtx_*` function returned. `QTX_STATUS_OK` is zero; on any other
/// status `qtx_last_error()` describes what went wrong.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum QtxStatus {
    /// Success.
    Ok = 0,
    /// A NULL pointer where one is required, a misaligned or overlapping
    /// buffer, an option out of its range, a non-finite footprint corner.
    InvalidArgument = 1,
    /// The operating system refused to read a file (missing, permissions).
    Io = 2,
    /// A file's contents are malformed: a corrupt `.qtx`, an image that does
    /// not decode, SVG that does not parse.
    Format = 3,
    /// A well-formed file using something quadtex does not support (SVG
    /// filters, GIF/WebP/svgz images, patterns over too many tiles).
    Unsupported = 4,
    /// A resource limit would be exceeded (image dimensions, file size, node
    /// count, tree depth, sweep work, the memory budget), an SVG refers to
    /// an image outside what `QtxSvgOptions.resources` allows (by default,
    /// outside its own folder), or the system refused the memory the input
    /// asked for; nothing was built.
    Limit = 5,
    /// A bug in quadtex (an internal panic, caught at the boundary). The
    /// library remains usable; please report the message.
    Internal = 6,
}

/// A failed call: the status to return and the message `qtx_last_error`
/// will show.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Failure {
    pub(crate) status: QtxStatus,
    pub(crate) message: String,
}

impl Failure {
    /// A [`QtxStatus::InvalidArgument`] failure.
    pub(crate) fn invalid(message: impl Into<String>) -> Failure {
        Failure {
            status: QtxStatus::InvalidArgument,
            message: message.into(),
        }
    }

    /// A failure whose message is prefixed with `context: `.
    pub(crate) fn context(self, context: &str) -> Failure {
        Failure {
            message: format!("{context}: {}", self.message),
            ..self
        }
    }
}

/// The status for a core error (the core's messages name the field at fault).
pub(crate) fn core_status(e: &quadtex_core::Error) -> QtxStatus {
    use quadtex_core::Error as E;
    match e {
        E::DepthTooLarge { .. }
        | E::TooManyNodes { .. }
        | E::SweepWork { .. }
        | E::MemoryBudget { .. }
        | E::AllocationFailed { .. } => QtxStatus::Limit,
        E::NonFiniteCoordinate { .. }
        | E::ReversedBounds { .. }
        | E::BadTolerance(_)
        | E::BadPolygon(_)
        | E::BadOption { .. } => QtxStatus::InvalidArgument,
        _ => QtxStatus::Format,
    }
}

impl From<quadtex_core::Error> for Failure {
    fn from(e: quadtex_core::Error) -> Failure {
        Failure {
            status: core_status(&e),
            message: e.to_string(),
        }
    }
}

impl From<quadtex_io::Error> for Failure {
    fn from(e: quadtex_io::Error) -> Failure {
        use quadtex_io::Error as E;
        let status = match &e {
            E::Io { .. } => QtxStatus::Io,
            E::Limit { .. } | E::MemoryBudget { .. } | E::ExternalResource { .. } => {
                QtxStatus::Limit
            }
            E::UnsupportedSvg { .. } | E::UnsupportedExtension(_) => QtxStatus::Unsupported,
            E::Core { source, .. } => core_status(source),
            _ => QtxStatus::Format,
        };
        Failure {
            status,
            message: e.to_string(),
        }
    }
}

thread_local! {
    /// The message of the last failed call on this thread.
    static LAST_ERROR: RefCell<Option<CString>> = const { RefCell::new(None) };
}

/// Records `message` as this thread's last error (NUL bytes, which a C
/// string cannot hold, become `?`).
fn set_last_error(message: String) {
    let c = CString::new(message).unwrap_or_else(|e| {
        let bytes = e.into_vec();
        let cleaned: Vec<u8> = bytes
            .into_iter()
            .map(|b| if b == 0 { b'?' } else { b })
            .collect();
        CString::new(cleaned).unwrap_or_default()
    });
    LAST_ERROR.with(|slot| *slot.borrow_mut() = Some(c));
}

/// Forgets this thread's last error.
fn clear_last_error() {
    LAST_ERROR.with(|slot| *slot.borrow_mut() = None);
}

/// This thread's last error message, as a pointer into thread-local storage
/// (valid until the next fallible call on this thread), or NULL.
pub(crate) fn last_error_ptr() -> *const std::ffi::c_char {
    LAST_ERROR.with(|slot| {
        slot.borrow()
            .as_deref()
            .map_or(std::ptr::null(), CStr::as_ptr)
    })
}

/// Runs the body of an exported function: clears the last error, returns
/// `QTX_STATUS_OK` on success, records the message and returns its status on
/// failure, and turns a panic into [`QtxStatus::Internal`] instead of
/// letting it unwind into C.
pub(crate) fn guard(body: impl FnOnce() -> Result<(), Failure>) -> QtxStatus {
    clear_last_error();
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => QtxStatus::Ok,
        Ok(Err(failure)) => {
            set_last_error(failure.message);
            failure.status
        }
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| (*s).to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_string());
            set_last_error(format!(
                "internal error (a bug in quadtex, please report it): {what}"
            ));
            QtxStatus::Internal
        }
    }
}

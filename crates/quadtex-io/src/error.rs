use std::fmt;
use std::path::PathBuf;

/// Everything that can go wrong in `quadtex-io`. Each variant names the file
/// and, for format errors, the field at fault.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// The operating system refused a read or write.
    Io {
        /// The file.
        path: PathBuf,
        /// What failed.
        source: std::io::Error,
    },
    /// An image could not be decoded or encoded.
    Image {
        /// The file.
        path: PathBuf,
        /// The decoder's message.
        message: String,
    },
    /// A `.qtx` file is malformed; `field` names the first thing found wrong.
    Format {
        /// The file.
        path: PathBuf,
        /// The header field or section (`magic`, `version`, `node_count`, `colours`…).
        field: &'static str,
        /// Why it is wrong.
        message: String,
    },
    /// A configured resource limit would be exceeded; nothing was allocated.
    Limit {
        /// The file.
        path: PathBuf,
        /// Which limit (`max_dimension`, `max_file_bytes`, `max_nodes`, `max_depth`).
        limit: &'static str,
        /// The value found.
        value: u64,
        /// The limit's value.
        max: u64,
    },
    /// An output file name whose extension selects no supported format.
    UnsupportedExtension(PathBuf),
    /// An SVG document could not be parsed (the message gives the position).
    Svg {
        /// The file.
        path: PathBuf,
        /// The parser's message.
        message: String,
    },
    /// An SVG feature the exact packer does not support (filters, GIF,
    /// WebP and svgz images, patterns over too many tiles).
    UnsupportedSvg {
        /// The file.
        path: PathBuf,
        /// The element or property, with its `id` when it has one.
        element: String,
    },
    /// A folder of tiles, or a tiled TIFF, is not a complete square grid of
    /// equal square tiles (see [`crate::pack_tiles`]); the message names
    /// the tile, or says what the TIFF's tiles are.
    Tiles {
        /// The folder, the tile at fault, or the TIFF.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Reading, decoding or packing the file would need more memory than
    /// [`crate::Limits::max_memory`]; nothing large was allocated. Shown as
    /// `FILE: WHAT needs an estimated 9.3 GiB, above the memory budget of
    /// 4.0 GiB (KNOBS)`. (The core's own [`quadtex_core::Error::MemoryBudget`]
    /// is turned into this variant.)
    MemoryBudget {
        /// The file.
        path: PathBuf,
        /// What was attempted (`packing at level 20`, `decoding 1x20000 texels`).
        what: String,
        /// The estimated peak, in bytes.
        estimate: u64,
        /// The budget, in bytes.
        budget: u64,
        /// The settings that lower the estimate or raise the budget.
        knobs: &'static str,
    },
    /// An SVG or glTF file refers to a file its
    /// [`crate::ExternalResources`] policy does not let it read (by default,
    /// one outside its own folder).
    ExternalResource {
        /// The referring file.
        path: PathBuf,
        /// The reference as written (an `href` or `uri`).
        reference: String,
        /// Why it was refused.
        reason: String,
    },
    /// The core library refused the data.
    Core {
        /// The file.
        path: PathBuf,
        /// The core error.
        source: quadtex_core::Error,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Io { path, source } => write!(f, "{}: {source}", path.display()),
            Error::Image { path, message } => write!(f, "{}: {message}", path.display()),
            Error::Format {
                path,
                field,
                message,
            } => {
                write!(
                    f,
                    "{}: invalid .qtx file: {field}: {message}",
                    path.display()
                )
            }
            Error::Limit {
                path,
                limit,
                value,
                max,
            } => {
                write!(f, "{}: {limit} exceeded: {value} > {max}", path.display())
            }
            Error::UnsupportedExtension(path) => write!(
                f,
                "{}: unsupported output format (use .png or .exr)",
                path.display()
            ),
            Error::Svg { path, message } => {
                write!(f, "{}: invalid SVG: {message}", path.display())
            }
            Error::UnsupportedSvg { path, element } => {
                write!(f, "{}: unsupported: {element}", path.display())
            }
            Error::Tiles { path, message } => write!(f, "{}: {message}", path.display()),
            Error::MemoryBudget {
                path,
                what,
                estimate,
                budget,
                knobs,
            } => write!(
                f,
                "{}: {what} needs an estimated {}, above the memory budget of {} ({knobs})",
                path.display(),
                quadtex_core::memory::format_bytes(*estimate),
                quadtex_core::memory::format_bytes(*budget)
            ),
            Error::ExternalResource {
                path,
                reference,
                reason,
            } => write!(
                f,
                "{}: external resource \"{reference}\" refused: {reason}; \
                 `--resources anywhere` (Python `resources=\"anywhere\"`, Rust \
                 `Limits::external_resources`) reads it if the file is trusted",
                path.display()
            ),
            Error::Core { path, source } => write!(f, "{}: {source}", path.display()),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } => Some(source),
            Error::Core { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// Wraps a core error for `path`; a core memory-budget refusal becomes
/// [`Error::MemoryBudget`].
pub(crate) fn core(path: &std::path::Path) -> impl FnOnce(quadtex_core::Error) -> Error + '_ {
    move |source| match source {
        quadtex_core::Error::MemoryBudget {
            what,
            estimate,
            budget,
            knobs,
        } => Error::MemoryBudget {
            path: path.to_path_buf(),
            what,
            estimate,
            budget,
            knobs,
        },
        source => Error::Core {
            path: path.to_path_buf(),
            source,
        },
    }
}

pub(crate) fn io(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |source| Error::Io {
        path: path.to_path_buf(),
        source,
    }
}

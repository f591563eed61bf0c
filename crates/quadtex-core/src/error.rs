use std::fmt;

/// Everything that can go wrong in `quadtex-core`.
///
/// Every variant names the offending value, so a message can be shown to a
/// user as it is.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// A coordinate is NaN or infinite; `field` names it (`x0`, `z0`, `x1`, `z1`).
    NonFiniteCoordinate {
        /// Which coordinate.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// A rectangle's upper bound lies below its lower bound on `axis`.
    ReversedBounds {
        /// `"x"` or `"z"`.
        axis: &'static str,
        /// Lower bound as given.
        lo: f64,
        /// Upper bound as given.
        hi: f64,
    },
    /// Image dimensions that are zero or larger than the builder accepts.
    BadDimensions {
        /// Width in texels.
        width: u64,
        /// Height in texels.
        height: u64,
        /// Why they were refused.
        reason: &'static str,
    },
    /// The texel buffer does not hold `width × height` texels.
    TexelCount {
        /// Texels expected.
        expected: u64,
        /// Texels given.
        actual: u64,
    },
    /// A requested tree depth above [`crate::MAX_DEPTH`] or above a caller's limit.
    DepthTooLarge {
        /// The depth asked for.
        depth: u32,
        /// The largest accepted.
        max: u32,
    },
    /// A node count above [`crate::MAX_NODES`] or above a caller's limit.
    TooManyNodes {
        /// Nodes the tree would have.
        nodes: u64,
        /// The largest accepted.
        max: u64,
    },
    /// A tolerance that is negative or not finite.
    BadTolerance(f64),
    /// Vector art whose exact trapezoid sweep needs more steps than
    /// [`crate::VectorOptions::max_sweep_work`] allows (edges crossing
    /// each other at thousands of heights in one square).
    SweepWork {
        /// Steps up to and including the square whose sweep would have
        /// passed the budget (the art needs at least this many).
        needed: u64,
        /// The budget.
        max: u64,
    },
    /// The node arrays given to [`crate::QuadTree::from_parts`] do not describe a
    /// quadtree; the message says which invariant fails.
    MalformedTree(String),
    /// Vector art that cannot be packed (non-finite point, colour not
    /// premultiplied, bad group); the message says what.
    BadVector(String),
    /// A polygon or projection the exact pixel integral cannot take (not
    /// convex, too many vertices, a non-finite vertex, a singular map); the
    /// message says what.
    BadPolygon(String),
    /// A filter option out of its range: `name` is the option, `expected`
    /// what it must be.
    BadOption {
        /// The option (`quality`, `error bound`).
        name: &'static str,
        /// The value given.
        value: f64,
        /// What is accepted.
        expected: &'static str,
    },
    /// A build or read would need more memory than the caller's budget
    /// (see [`crate::memory`]); nothing large was allocated. Shown as
    /// `WHAT needs an estimated 9.3 GiB, above the memory budget of
    /// 4.0 GiB (KNOBS)`.
    MemoryBudget {
        /// What was attempted (`packing at level 20`).
        what: String,
        /// The estimated peak, in bytes.
        estimate: u64,
        /// The budget, in bytes.
        budget: u64,
        /// The settings that lower the estimate or raise the budget
        /// (`lower --max-level, or set --memory-limit`).
        knobs: &'static str,
    },
    /// The allocator refused memory the input asked for (the budget was
    /// not set or the estimate was low); nothing was built.
    AllocationFailed {
        /// What was being allocated.
        what: String,
        /// The size of the refused allocation, in bytes.
        bytes: u64,
    },
    /// An HDR texel with a NaN or infinite channel: refused, never clamped.
    NonFiniteTexel {
        /// Its column.
        col: u32,
        /// Its row (0 at the top).
        row: u32,
        /// The channel (`r`, `g`, `b`, `a`).
        channel: char,
        /// The value.
        value: f32,
    },
    /// An HDR (float) tile in a tiled texture: tiled packing takes 8- and
    /// 16-bit tiles only, and would otherwise clamp it.
    HdrTile {
        /// The tile's row (0 at the top).
        row: u32,
        /// The tile's column.
        col: u32,
    },
    /// A tile of a tiled texture in another precision than the first one
    /// (8-bit sRGB against 16-bit or float): one tree keeps its texel
    /// blocks in one format.
    TileFormat {
        /// The tile's row (0 at the top).
        row: u32,
        /// The tile's column.
        col: u32,
        /// What the tile is.
        found: &'static str,
        /// What the first tile was.
        expected: &'static str,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::NonFiniteCoordinate { field, value } => {
                write!(f, "coordinate {field} is not finite ({value})")
            }
            Error::ReversedBounds { axis, lo, hi } => {
                write!(f, "reversed bounds on {axis}: upper {hi} < lower {lo}")
            }
            Error::BadDimensions {
                width,
                height,
                reason,
            } => {
                write!(f, "bad image dimensions {width}x{height}: {reason}")
            }
            Error::TexelCount { expected, actual } => {
                write!(f, "texel buffer holds {actual} texels, expected {expected}")
            }
            Error::DepthTooLarge { depth, max } => {
                write!(f, "tree depth {depth} exceeds the limit {max}")
            }
            Error::TooManyNodes { nodes, max } => {
                write!(f, "tree would have {nodes} nodes, above the limit {max}")
            }
            Error::BadTolerance(t) => {
                write!(f, "tolerance must be finite and >= 0, got {t}")
            }
            Error::SweepWork { needed, max } => write!(
                f,
                "vector art too complex to pack exactly: its edges cross at so many heights that the \
                 trapezoid sweep needs more than {needed} steps, above the limit of {max} \
                 (max sweep work); simplify the art (dashes or strokes piled on one point) or raise the limit"
            ),
            Error::MalformedTree(why) => write!(f, "malformed quadtree: {why}"),
            Error::BadVector(why) => write!(f, "bad vector art: {why}"),
            Error::BadPolygon(why) => write!(f, "bad polygon: {why}"),
            Error::BadOption {
                name,
                value,
                expected,
            } => write!(f, "{name} must be {expected}, got {value}"),
            Error::MemoryBudget {
                what,
                estimate,
                budget,
                knobs,
            } => write!(
                f,
                "{what} needs an estimated {}, above the memory budget of {} ({knobs})",
                crate::memory::format_bytes(*estimate),
                crate::memory::format_bytes(*budget)
            ),
            Error::AllocationFailed { what, bytes } => write!(
                f,
                "out of memory: {what} needed {} more and the system refused it (lower --max-level, or set --memory-limit to refuse such work up front)",
                crate::memory::format_bytes(*bytes)
            ),
            Error::NonFiniteTexel {
                col,
                row,
                channel,
                value,
            } => write!(
                f,
                "texel ({col}, {row}) has {channel} = {value}: HDR texels must be finite"
            ),
            Error::HdrTile { row, col } => write!(
                f,
                "tile ({row}, {col}) is HDR (float): tiled packing takes 8- and 16-bit tiles only"
            ),
            Error::TileFormat {
                row,
                col,
                found,
                expected,
            } => write!(
                f,
                "tile ({row}, {col}) is {found}, the first tile was {expected}: all tiles must share one format"
            ),
        }
    }
}

impl std::error::Error for Error {}

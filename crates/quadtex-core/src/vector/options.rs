//! What a vector packing is asked ([`VectorOptions`]) and what it did
//! ([`VectorReport`]).

use crate::tree::MAX_NODES;

/// Options of [`QuadTree::from_vector`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VectorOptions {
    /// Deepest level (leaf squares of side `2^-max_level`), at most
    /// [`MAX_VECTOR_LEVEL`].
    pub max_level: u8,
    /// Refuse to build trees with more nodes than this.
    pub max_nodes: u64,
    /// Memory budget in bytes (`None`: no budget). Before building, the
    /// packer refuses with [`Error::MemoryBudget`] when
    /// [`crate::VectorArt::estimate_bytes`] exceeds it (in a time about
    /// proportional to the points times the levels;
    /// [`crate::QuadTree::from_vector_within`] lowers the settings left to it
    /// instead); while building, when the nodes so far at
    /// [`crate::memory::BUILD_BYTES_PER_NODE`] and the contour leaves so
    /// far at [`crate::CONTOUR_BYTES_PER_POINT`] a point and
    /// [`crate::CONTOUR_BYTES_PER_LEAF`] a leaf do.
    pub max_bytes: Option<u64>,
    /// Largest per-channel deviation between any point of a square painted
    /// by gradients and the square's one colour (its exact mean) for the
    /// square to be terminal; squares beyond it are split, down to
    /// `max_level`. Measured on the **sRGB-encoded** premultiplied colour
    /// channels (alpha as is), full scale 1, so that the default
    /// [`DEFAULT_SMOOTH_TOLERANCE`], a quarter of an 8-bit step, is a quarter
    /// of a step of 8-bit output at every brightness (a linear measure would
    /// be 13× too loose near black and 9× too strict near white). The
    /// deviation is bounded by the colour's range over the square (interval
    /// arithmetic through the compositing). Flat colour and edges are exact
    /// regardless.
    pub tolerance: f64,
    /// Keep squares painted by one linear gradient (and flat colour) whole,
    /// with their paint, instead of splitting them to the tolerance
    /// ([`crate::vector::gradient_leaf`]). On by default.
    pub gradient_leaves: bool,
    /// Keep a square of flat art crossed by at most this many edges whole,
    /// with its contours, instead of splitting it further
    /// ([`crate::vector::contour_leaf`]): the art is then exact at any
    /// magnification, and the tree answers down to level 30. Only squares
    /// whose shapes are solid fills outside clip paths and masks, in groups
    /// of plain opacity (at most [`crate::vector::contour_leaf::MAX_LEAF_GROUP_DEPTH`]
    /// deep) or none, qualify. Squares at `max_level` that qualify keep
    /// their contours up to 256 edges (or the budget, if larger), so flat
    /// art is exact at any magnification everywhere but where more edges
    /// crowd one square of `max_level` (a query would sweep them all).
    /// Off (`None`) by default.
    pub contour_leaves: Option<usize>,
    /// How close to the true curves a reader of SVG (`quadtex_io`)
    /// flattens them, in texture-space units (the texture's longer side is
    /// 1); the packer itself takes art already flattened. `None`: see
    /// [`VectorOptions::curve_tolerance_or_default`].
    pub curve_tolerance: Option<f64>,
    /// Budget of the exact trapezoid sweep over the whole packing, in its
    /// steps (pairs of edges tested for a crossing, plus each edge handed
    /// to each slab: see the module's *Limits*). Art that needs more is
    /// refused with [`Error::SweepWork`] before the square that would pass
    /// it is swept, instead of packing for minutes. The default,
    /// [`DEFAULT_MAX_SWEEP_WORK`], is about a minute on one core.
    pub max_sweep_work: u64,
}

/// The default [`VectorOptions::max_sweep_work`]: 2³¹ steps, about 70 s
/// of one core where steps are dearest (measured: a fuzzed dashed star,
/// 3.9 × 10⁸ steps in 13 s). The resvg test suite needs at most
/// 6.6 × 10⁷ in one file (a pattern of strokes), 1/32 of it (its test
/// checks the margin).
pub const DEFAULT_MAX_SWEEP_WORK: u64 = 1 << 31;

/// Max level of trees with contour leaves when none is given (callers
/// that pick a level for SVG art use it): squares split only while they
/// hold more edges than the budget, so a deeper limit costs only where
/// edges crowd (curves flattened finely, small text, stroke joins).
pub const CONTOUR_MAX_LEVEL: u8 = 20;

/// Curve flattening of trees with contour leaves, unless stated:
/// 2⁻²² of the texture's side (2.4e-7; 0.24 mm on a 1 km texture): a
/// quarter of a pixel when the texture spans 10⁶ pixels, and four times
/// the `f32` resolution of the coordinates SVG readers hand over, so the
/// bound is not lost in their rounding. A circle of radius 0.1 takes
/// about 1 400 segments.
pub const CONTOUR_CURVE_TOLERANCE: f64 = 1.0 / (1u64 << 22) as f64;

impl VectorOptions {
    /// [`VectorOptions::curve_tolerance`], or by default
    /// [`CONTOUR_CURVE_TOLERANCE`] with contour leaves (exact at any
    /// magnification, so the curves must not show their segments) and
    /// `2^-(max_level + 4)`, a sixteenth of a square at `max_level`,
    /// without them.
    pub fn curve_tolerance_or_default(&self) -> f64 {
        self.curve_tolerance
            .unwrap_or(if self.contour_leaves.is_some() {
                CONTOUR_CURVE_TOLERANCE
            } else {
                (-(f64::from(self.max_level) + 4.0)).exp2()
            })
    }
}

/// A quarter of an 8-bit step: the default [`VectorOptions::tolerance`].
pub const DEFAULT_SMOOTH_TOLERANCE: f64 = 0.25 / 255.0;

impl Default for VectorOptions {
    fn default() -> Self {
        VectorOptions {
            max_level: 12,
            max_nodes: MAX_NODES,
            max_bytes: None,
            tolerance: DEFAULT_SMOOTH_TOLERANCE,
            gradient_leaves: true,
            contour_leaves: None,
            curve_tolerance: None,
            max_sweep_work: DEFAULT_MAX_SWEEP_WORK,
        }
    }
}

/// What vector packing did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VectorReport {
    /// Leaves at the maximum level whose colour came from the trapezoid sweep.
    pub swept_leaves: u64,
    /// Most edges inside one swept leaf.
    pub max_leaf_edges: usize,
    /// Steps of the trapezoid sweep, counted against
    /// [`VectorOptions::max_sweep_work`].
    pub sweep_work: u64,
    /// Largest deviation (per channel, sRGB-encoded, bounded as for
    /// [`VectorOptions::tolerance`]) between a point of a terminal square
    /// painted by gradients and the square's one colour. At most the
    /// tolerance, except in squares at the maximum level.
    pub max_smooth_deviation: f64,
    /// Bound on the error of any stored mean, linear (0 when every mean is
    /// exact: flat colour, and linear gradients not overlapping other
    /// gradients).
    pub max_mean_error: f64,
    /// Terminal squares kept as gradient leaves ([`crate::vector::gradient_leaf`]).
    pub gradient_leaves: u64,
    /// Distinct paints of those leaves.
    pub gradient_leaf_paints: u64,
    /// Terminal squares kept as contour leaves ([`crate::vector::contour_leaf`]).
    pub contour_leaves: u64,
    /// Points their contours hold.
    pub contour_leaf_points: u64,
    /// With contour leaves: squares of flat art at the max level holding
    /// more edges than a contour leaf may there (the budget or 256,
    /// whichever is larger), kept as their exact mean instead. The art is
    /// exact at any magnification except inside these squares, where it
    /// is exact down to the max level only.
    pub crowded_leaves: u64,
}

//! Vector art packed straight into a quadtree, with exact coverage and no
//! raster in between.
//!
//! [`VectorArt`] is a list of filled polygonal shapes in paint order (back to
//! front), each with a fill rule, a [`Paint`] (a linear premultiplied colour,
//! a [`Gradient`] or an [`ImagePaint`]), the translucent groups it belongs
//! to (each possibly blended and masked) and the clip region it is painted
//! within. Coordinates are texture space (`x` right,
//! `z` up, see the crate conventions); art outside `[0,1)²` is clipped off and
//! uncovered parts are transparent. Curves are the caller's to flatten (the
//! SVG packer states its tolerance).
//!
//! ## How the tree is built
//!
//! Recursive subdivision from the root. Each square carries, per shape that
//! may cover it, the shape's contours **clipped to the square**
//! (Sutherland–Hodgman against its four sides). Clipping to a convex window
//! keeps the winding number of every interior point (the parts outside are
//! replaced by runs along the window's border), so the clipped contours
//! describe the shape exactly inside the square. A contour that no longer
//! enters the interior (all its edges lie on the border) is replaced by the
//! constant winding it contributes (its signed area over the square's).
//!
//! * If no shape has an edge inside the square, every shape either covers it
//!   entirely or not at all: the square is **terminal**, with the composite of
//!   the covering shapes. An opaque shape covering the square hides all the
//!   shapes below it, whose edges then do not split the square.
//! * At the maximum level a square is a **leaf**: its colour is the exact
//!   area-weighted composite of the regions inside it, found by a trapezoid
//!   sweep (slabs between all vertex and crossing heights; within a slab the
//!   edges do not cross, each gap between neighbouring edges is a trapezoid
//!   covered by a known set of shapes).
//! * Otherwise the square splits and its colour is the exact mean of its
//!   children, rounded once to 16 bits.
//!
//! **Gradients.** A square no edge enters but a gradient paints is terminal
//! when every point of it lies within [`VectorOptions::tolerance`] of its
//! one colour, the exact mean (see [`crate::vector::gradient`]); otherwise it splits
//! like an edge square, down to the maximum level. So smooth colour costs
//! squares in proportion to its area times (slope / tolerance)², not `4^L`. At a
//! leaf the trapezoid sweep takes each trapezoid's mean the same way.
//! Means are exact where at most one varying layer shows and it is a linear
//! gradient (compositing is affine in each layer); otherwise they carry a
//! bound, reported in [`VectorReport::max_mean_error`].
//!
//! **Clip regions** ([`VectorArt::clip_region`]) are carried the same way:
//! their member shapes are clipped to every square like painted shapes (so
//! their edges split squares too) but never painted. Wherever the square's
//! or the trapezoid's set of covering shapes is known, a painted shape counts
//! only if its region covers too, evaluated from that same set; clipping is
//! as exact as coverage.
//!
//! **Masks** ([`VectorArt::begin_mask`]) are carried the same way: their
//! content shapes travel through the subdivision as members, and wherever
//! the covering set is known, a masked group's composite is multiplied by
//! the composite of its mask's content there, turned into a coverage
//! ([`MaskKind`]). On flat content that is exact; where a gradient or an
//! image varies inside a mask, the mean carries the bound of the coverage's
//! range (interval arithmetic, as for gradients).
//!
//! Memory and time grow with the length of the edges times `2^L` (the squares
//! an edge crosses), never with `4^L`. Compositing is the premultiplied
//! *over* operator in **linear light**; browsers composite in sRGB, so
//! translucent overlaps differ from a browser's rendering (opaque art does
//! not). A translucent group is composited in isolation and then faded by
//! its opacity, as SVG specifies.
//!
//! ## Limits
//!
//! Besides nodes ([`VectorOptions::max_nodes`]) and memory
//! ([`VectorOptions::max_bytes`]), the trapezoid sweep's **work** is
//! budgeted ([`VectorOptions::max_sweep_work`]): per swept square, the
//! pairs of edges tested for a crossing plus, over its slabs, the edges
//! spanning each. It grows with the edges alive at once times the heights
//! where they end or cross, so a few kilobytes of SVG whose dashes pile
//! on one point can need billions of steps (minutes). The packer counts a
//! square's steps before sweeping it and refuses with [`Error::SweepWork`]
//! when the total would pass the budget; [`VectorReport::sweep_work`] is
//! what a packing used.

pub(crate) mod blend;
pub(crate) mod contour_leaf;
pub(crate) mod gradient;
pub(crate) mod gradient_leaf;
pub(crate) mod image_paint;

mod art;
mod composite;
mod estimate;
mod options;
mod pack;

pub use crate::memory::{CONTOUR_BYTES_PER_LEAF, CONTOUR_BYTES_PER_POINT};
pub use art::{
    ClipId, GroupId, MAX_CLIP_DEPTH, MAX_MASK_DEPTH, MAX_VECTOR_COORDINATE, MAX_VECTOR_LEVEL,
    MAX_VECTOR_POINTS, MaskId, MaskKind, Paint, VectorArt,
};
pub use estimate::{Adjustable, BudgetFit, MIN_FITTED_LEVEL};
pub use options::{
    CONTOUR_CURVE_TOLERANCE, CONTOUR_MAX_LEVEL, DEFAULT_MAX_SWEEP_WORK, DEFAULT_SMOOTH_TOLERANCE,
    VectorOptions, VectorReport,
};

/// The settings that shrink a vector build, for [`Error::MemoryBudget`].
const VECTOR_KNOBS: &str = "lower --max-level, or raise --memory-limit";

#[cfg(test)]
mod tests;

//! # quadtex-core
//!
//! Textures packed as *incomplete quadtrees* (uniform regions stop
//! splitting early; every node carries its mean colour), and their exact
//! filtering: the integral of a texture over a pixel's footprint, or over a
//! screen region under a projective map weighted by a pixel filter, with a
//! stated error bound. The method is restated in `docs/algorithm.md`; the
//! crate map and glossary are in `docs/architecture.md`. This crate does no
//! I/O.
//!
//! ## The front door
//!
//! * Pack: [`QuadTree::from_texels`] (a raster, [`TexelGrid`]) or
//!   [`QuadTree::from_vector`] (vector art, [`VectorArt`]).
//! * Filter: a [`Texture`] (a tree and its [`Wrap`]) answers
//!   [`Texture::filter`] for a [`Footprint`] under [`FilterOptions`], and
//!   [`Texture::integrate_region`] for a renderer's screen regions under a
//!   [`Projection`] and a [`PixelFilter`]; [`QuadTree::weighted_colour`] gives the
//!   weighted colour over one [`Fragment`].
//! * Compare: the filters users run today live in [`baseline`].
//!
//! ## Vocabulary
//!
//! *Square*: a node's extent; *terminal square*: one that is not split;
//! *fragment*: an axis-aligned rectangle of texture space; *footprint*: the
//! texture-space image of a pixel's corners; *region*: a convex screen
//! polygon seen through one projective map; *weighted colour*: an integral
//! of colour over an area, not yet divided by it.
//!
//! ## Conventions (written once, here)
//!
//! * **Texture space** is the unit square `[0,1)²`: axis `x` to the right,
//!   axis `z` *up*. A raster image's row 0 is the *top* of the texture:
//!   texel `(col, row)` of a `W×H` image covers
//!   `x ∈ [col/W, (col+1)/W)`, `z ∈ [1-(row+1)/H, 1-row/H)`.
//! * **Rectangles are half-open**: a [`Fragment`] `[x0,x1) × [z0,z1)` and every
//!   quadtree square include their left and bottom edges only.
//! * **Levels**: the root square is level 0; a square at level `i` has side
//!   `2^-i` and area `2^-2i`.
//! * **Colour** is linear light, premultiplied alpha, nominal range `[0,1]`
//!   ([`Rgba`]). sRGB is decoded before packing and encoded after filtering, by
//!   the I/O crate.
//! * **Float types by purpose**: texture-space coordinates, areas and weighted
//!   colours are `f64` (a level-30 square has side `2^-30`; repeating
//!   textures put coordinates far from zero); colours handed to a renderer are
//!   `f32`; colours stored in the tree are unsigned 16-bit normalised integers
//!   (`unorm16`, step `1/65535`, far finer than the 12 linear bits asked of us).
#![forbid(unsafe_code)]

// One folder a job; every public type is re-exported once, here, and
// reached by that one path (the folders are private).
mod colour;
mod error;
mod filter;
mod geometry;
mod raster;
mod tree;
mod vector;

pub mod baseline;
pub mod memory;
pub mod reference;
pub mod synth;
#[cfg(test)]
mod test_rng;

pub use colour::{
    ColourEncoding, Rgba, Unorm16Rgba, WeightedColour, srgb_decode, srgb_decode_f32, srgb_encode,
    srgb_encode_f32,
};
pub use error::Error;
pub use filter::batch::{Threads, fill_runs_on_threads, map_runs_on_threads};
pub use filter::footprint::{Footprint, MAX_TEXTURE_COORDINATE};
pub use filter::options::{FilterOptions, FilterStats, LevelOfDetail, SQUARE_BUDGET, Weighting};
pub use filter::pixel_filter::PixelFilter;
pub use filter::projection::Projection;
pub use filter::query::RegionIntegral;
pub use filter::region::MAX_SCREEN_COORDINATE;
pub use filter::screen_cell::CellIntegral;
pub use filter::texture::Texture;
pub use filter::walk::FIXED_LEVEL_CAP;
pub use filter::wrap::{BoxIntegral, Wrap, WrapMode, integrate_wrapped};
pub use geometry::FillRule;
pub use geometry::fragment::Fragment;
pub use geometry::polygon::{ConvexPolygon, MAX_VERTICES};
pub use raster::{
    BuildOptions, BuildReport, MAX_BUILD_DEPTH, MAX_DIMENSION, Mosaic, PackedTile, TexelGrid,
    raster_cells, raster_grid_bytes,
};
pub use tree::shared::SharedBytes;
pub use tree::texel_block::{BLOCK_LOG2_SIDE, BlockFormat, TexelBlocks, srgb8_texel};
pub use tree::variant;
pub use tree::{
    Aspect, FLAT_GRID_MAX_DEPTH, LevelStats, MAX_DEPTH, MAX_NODES, QuadTree, TraversalStats,
    UNIFORM_SEARCH_NODES,
};
pub use vector::blend::{BlendMode, blend, blend_range};
pub use vector::contour_leaf::{
    ContourLeaves, ContourParts, LeafGroup, LeafPiece, MAX_LEAF_GROUP_DEPTH,
};
pub use vector::gradient::{Circle, Gradient, Interpolation, MAX_PERIODS, MAX_STOPS, Spread, Stop};
pub use vector::gradient_leaf::{GradientLeaves, LeafPaint, MAX_CELL_LEVELS, MAX_GRADIENT_LEAVES};
pub use vector::image_paint::ImagePaint;
pub use vector::{
    Adjustable, BudgetFit, CONTOUR_BYTES_PER_LEAF, CONTOUR_BYTES_PER_POINT,
    CONTOUR_CURVE_TOLERANCE, CONTOUR_MAX_LEVEL, ClipId, DEFAULT_MAX_SWEEP_WORK,
    DEFAULT_SMOOTH_TOLERANCE, GroupId, MAX_CLIP_DEPTH, MAX_MASK_DEPTH, MAX_VECTOR_COORDINATE,
    MAX_VECTOR_LEVEL, MAX_VECTOR_POINTS, MIN_FITTED_LEVEL, MaskId, MaskKind, Paint, VectorArt,
    VectorOptions, VectorReport,
};

/// The README's Rust examples, run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
struct ReadmeDoctests;

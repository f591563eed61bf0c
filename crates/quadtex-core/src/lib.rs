//! # quadtex-core
//!
//! Textures packed as *incomplete quadtrees* and the exact area integral of a
//! texture over an axis-aligned rectangle (a *fragment*), after
//! the method restated in `ALGORITHM.md`. This crate does no I/O.
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

pub mod blend;
mod colour;
pub mod contour_leaf;
mod error;
pub mod exact;
pub mod footprint;
mod fragment;
mod geometry;
pub mod gradient;
pub mod gradient_leaf;
pub mod image_paint;
mod leaf_nodes;

pub mod build;
pub mod memory;
pub mod mipmap;
pub mod options;
pub mod polygon;
pub mod reference;
pub mod sat;
mod shared;
pub mod synth;
#[cfg(test)]
mod test_rng;
pub mod texel_block;
pub mod texture;
mod tree;
pub mod variant;
pub mod vector;
pub mod wrap;

pub use build::{BuildOptions, BuildReport, TexelGrid};
pub use colour::{ColourEncoding, Rgba, Unorm16Rgba, WeightedColour};
pub use contour_leaf::{ContourLeaves, ContourParts, LeafGroup, LeafPiece};
pub use error::Error;
pub use exact::{PixelFilter, Projection, RegionIntegral};
pub use footprint::Footprint;
pub use fragment::Fragment;
pub use gradient_leaf::{GradientLeaves, LeafPaint};
pub use polygon::ConvexPolygon;
pub use shared::SharedBytes;
pub use texel_block::{BlockFormat, TexelBlocks};
pub use texture::{FilterOptions, FilterStats, LevelOfDetail, Texture, Weighting};
pub use tree::{
    Aspect, LevelStats, MAX_DEPTH, MAX_NODES, QuadTree, TraversalStats, UNIFORM_SEARCH_NODES,
};
pub use vector::{ClipId, FillRule, Paint, VectorArt, VectorOptions, VectorReport};
pub use wrap::{Wrap, WrapMode};

/// The README's Rust examples, run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
struct ReadmeDoctests;

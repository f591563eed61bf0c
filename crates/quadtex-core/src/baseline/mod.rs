//! Baselines: the filters users run today (mip pyramid with trilinear and
//! EWA lookups, summed-area table) and the strip pipeline that came before
//! the exact filter, kept to be measured against on the same footprints
//! the quadtree integrates exactly.

mod mipmap;
mod sat;
mod strips;

pub use mipmap::MipPyramid;
pub use sat::SummedAreaTable;
pub use strips::{MAX_DENSITY_PIECES, MAX_STRIPS, StripCover, StripOptions, filter_by_strips};

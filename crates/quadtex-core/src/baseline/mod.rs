//! Baselines: the filters users run today (mip pyramid with trilinear and
//! EWA lookups, summed-area table), kept to be measured against on the
//! same footprints the quadtree integrates exactly.

mod mipmap;
mod sat;

pub use mipmap::MipPyramid;
pub use sat::SummedAreaTable;

//! The exact filter: footprints and projective maps, the region integral
//! under a pixel filter, wrap modes, and the [`crate::Texture`] front door.
//!
//! One file a job: [`region`] states what is computed and its bound and
//! holds the entry point; [`projection`] the screen → texture map;
//! [`pixel_filter`] the reconstruction filters; [`walk`] the refinement
//! over tiles ([`tiles`]) and squares; [`few_cells`] and [`scan`] the
//! direct scans that answer small regions before any walk is set up.

pub(crate) mod batch;
pub(crate) mod few_cells;
pub(crate) mod footprint;
pub(crate) mod options;
pub(crate) mod pixel_filter;
pub(crate) mod projection;
pub(crate) mod query;
pub(crate) mod region;
pub(crate) mod scan;
pub(crate) mod screen_cell;
pub(crate) mod texture;
pub(crate) mod tiles;
pub(crate) mod walk;
pub(crate) mod wrap;

#[cfg(test)]
mod exact_tests;

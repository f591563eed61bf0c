//! The exact filter: footprints and projective maps, the region integral
//! under a pixel filter, wrap modes, and the [`crate::Texture`] front door.

pub(crate) mod exact;
pub(crate) mod footprint;
pub(crate) mod options;
pub(crate) mod texture;
pub(crate) mod wrap;

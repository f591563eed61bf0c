//! # quadtex-io
//!
//! Everything of quadtex that touches files: decoding PNG, JPEG, TIFF (and
//! BigTIFF, stripped or tiled, with GeoTIFF tags kept as [`GeoReference`])
//! and OpenEXR into the core's linear, premultiplied
//! [`quadtex_core::TexelGrid`]; packing mosaics of tiles ([`pack_tiles`]:
//! a folder of tiles or a tiled TIFF); writing rendered images
//! (PNG in sRGB 8-bit, OpenEXR in linear float); SVG art as vector art for
//! the exact vector packer ([`svg`]); and the `.qtx` tree file
//! (see `docs/format.md`). Every file is written atomically: to a temporary
//! file in the same directory, then renamed over the target, so a reader never
//! sees a half-written file and an interrupted run leaves none behind. A
//! symbolic link is followed (the file it names is replaced; the link stays);
//! a device, FIFO or socket is written in place ([`write_atomically`]);
//! [`write_image`] and [`write_qtx_to`] write to any stream, such as
//! standard output. `.qtx` files can also be memory-mapped ([`map_qtx`]):
//! that one call is the crate's only `unsafe` (`unsafe_code` is denied
//! everywhere else, see `Cargo.toml`).
#![deny(unsafe_code)]

mod atomic;
mod error;
mod footprints;
mod image_io;
mod limits;
mod png_on_threads;
mod qtx;
mod query;
mod svg;
mod tiff_io;
mod tiles;
mod tiles_on_threads;

pub use atomic::write_atomically;
pub use error::Error;
pub use footprints::{
    DumpTexture, DumpWrap, FOOTPRINT_MAGIC, FootprintDump, FootprintRecord, RECORD_BYTES,
    read_footprints, write_footprints,
};
pub use image_io::{
    ImageFormat, LinearImage, linear_to_srgb8, load_linear_image, load_texels,
    load_texels_from_bytes, load_texels_with_georeference, save_image, save_image_as,
    srgb8_from_linear, write_image,
};
pub use limits::{
    ExternalResources, FALLBACK_MEMORY_BUDGET, Limits, QTX_READ_BYTES_PER_NODE,
    default_memory_budget,
};
pub use png_on_threads::{PackedPng, pack_png_on_threads};
pub use qtx::{
    FORMAT_VERSION, MAGIC, QtxInfo, map_qtx, map_qtx_unverified, parse_qtx, parse_qtx_structure,
    read_qtx, write_qtx, write_qtx_to,
};
pub use query::parse_query_line;
pub use svg::{
    MAX_PATTERN_TILES, MIN_CURVE_TOLERANCE, SvgOptions, load_svg, pack_svg, pack_svg_fitted,
    parse_svg,
};
pub use tiff_io::GeoReference;
pub use tiles::{TileFolder, TileSource, pack_tile, pack_tiles, splice_tiles};
pub use tiles_on_threads::pack_tiles_on_threads;

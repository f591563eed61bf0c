//! # quadtex-render
//!
//! quadtex's showcase: a backward ray tracer whose textures are filtered
//! exactly over each pixel's filter support, split among the planar
//! primitives that show in it, by [`quadtex_core::Texture::integrate_region`]
//! (spheres: over the tangent plane's footprint). Scenes
//! come from TOML files ([`load_scene`], format in `docs/scenes.md`) or from
//! code ([`demo_scene`]); [`render`](fn@render) turns one into a linear image.
//!
//! Modules: [`scene`] (the validated scene model), `parse` (TOML → scene),
//! `view` (a planar primitive's projective map from screen to texture),
//! `tangent_plane` (tangent-plane footprints for spheres and baselines),
//! `exact` (exact pixels: visibility by clipping, regions integrated), `shade` (one
//! ray's colour), `pixel` (pixel strategies: exact, supersampling, spheres),
//! `render` (the parallel loop), [`path`] (camera paths for sequences),
//! `stats` (what a render cost), `measure`
//! (lookups and footprints for the comparison and peer benchmarks), `rays`
//! (the renderer's rays dumped and timed for a peer ray caster).
#![forbid(unsafe_code)]

mod bvh;
mod caster;
mod demo;
mod exact;
mod frame;
mod gltf_scene;
mod math;
mod measure;
mod options;
mod parse;
mod path;
mod pixel;
mod rays;
mod reach;
mod render;
mod scene;
mod screen_bins;
mod shade;
mod span;
mod stats;
mod sun_grid;
mod tangent_plane;
mod terrain;
mod view;
mod visibility;

use std::fmt;
use std::path::PathBuf;

pub use demo::{demo_scene, sign_art};
pub use gltf_scene::write_glb;
pub use math::{Ray, Vec3};
pub use measure::{
    LookupTiming, PixelFootprint, centre_distance, pixel_footprints, texture_only, time_lookups,
};
pub use options::{PixelFilter, REFERENCE_SEED, RenderOptions, TextureFilter};
pub use parse::{load_camera_path, load_scene, parse_camera_path, parse_obj, parse_scene};
pub use path::{CameraPath, Key, MAX_PATH_FRAMES, MAX_PATH_KEYS};
pub use rays::{
    DumpKind, DumpRay, DumpSurface, MISS, PrimaryHit, RayDump, RayResults, RayTiming, ShadowRay,
    ray_dump, read_ray_dump, read_ray_results, time_rays, write_ray_dump, write_ray_results,
};
pub use render::{render, render_into};
pub use scene::{
    Camera, Geometry, Lighting, MESH_BYTES_PER_TRIANGLE, Mesh, Scene, SceneTexture, Sky, Surface,
    Triangle, UvTransform, baseline_bytes, baseline_level, mipmapped_raster_bytes,
    same_memory_level,
};
pub use stats::RenderSummary;
pub use terrain::{TERRAIN_CELLS, write_terrain};

/// Most pixels one render may have (64 megapixels).
pub const MAX_PIXELS: u64 = 1 << 26;

/// Everything that can go wrong while loading or rendering a scene.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// The scene file could not be read.
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The scene is malformed: `key` is the dotted path of the offending
    /// entry (`shape[2].texture`), `line` its line in the file when known.
    Scene {
        /// The file.
        path: PathBuf,
        /// 1-based line, when known.
        line: Option<usize>,
        /// Dotted key path.
        key: String,
        /// What is wrong.
        message: String,
    },
    /// A texture could not be packed.
    Pack {
        /// The scene key or built-in name.
        key: String,
        /// The core error.
        source: quadtex_core::Error,
    },
    /// A zero or too large output size.
    Resolution {
        /// Width asked for.
        width: u32,
        /// Height asked for.
        height: u32,
    },
    /// An invalid render option.
    Option(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Io { path, source } => write!(f, "{}: {source}", path.display()),
            Error::Scene {
                path,
                line: Some(line),
                key,
                message,
            } => {
                write!(f, "{}:{line}: {key}: {message}", path.display())
            }
            Error::Scene {
                path,
                line: None,
                key,
                message,
            } => write!(f, "{}: {key}: {message}", path.display()),
            Error::Pack { key, source } => write!(f, "{key}: {source}"),
            Error::Resolution { width, height } => {
                write!(
                    f,
                    "resolution {width}x{height} is zero or above {MAX_PIXELS} pixels"
                )
            }
            Error::Option(m) => write!(f, "{m}"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } => Some(source),
            Error::Pack { source, .. } => Some(source),
            _ => None,
        }
    }
}

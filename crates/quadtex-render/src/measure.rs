//! What measurements need from the renderer: the textured pixels' centre
//! hits and footprints, texture lookups timed without ray casting, and the
//! scene reduced to its textures.

use std::time::Instant;

use quadtex_core::{Footprint, Rgba};
use quadtex_io::LinearImage;

use crate::caster::Caster;
use crate::frame::Frame;
use crate::options::{PixelFilter, TextureFilter};
use crate::render::{prepare_baselines, sized_scene};
use crate::scene::{Hit, Lighting, Scene, Sky};
use crate::shade::{TexturedHit, texture_colour};
use crate::stats::PixelStats;
use crate::tangent_plane::{self, ScreenSquare};

/// Distance from the camera to the first surface along the view's central
/// ray, if it hits one.
pub fn centre_distance(scene: &Scene) -> Option<f64> {
    let c = &scene.camera;
    let ray = c.ray(f64::from(c.width()) / 2.0, f64::from(c.height()) / 2.0);
    Caster::new(scene).nearest_hit(&ray).map(|(_, h)| h.t)
}

/// The centre hits of the textured pixels of `scene` at its camera's size:
/// `(pixel index, surface index, hit)`, in raster order.
fn textured_hits(scene: &Scene) -> Vec<(usize, usize, Hit)> {
    let (w, h) = (scene.camera.width(), scene.camera.height());
    let mut out = Vec::new();
    let rays = Caster::new(scene);
    for y in 0..h {
        for x in 0..w {
            let ray = scene.camera.ray(f64::from(x) + 0.5, f64::from(y) + 0.5);
            if let Some((index, hit)) = rays.nearest_index(&ray)
                && scene.surfaces[index].texture.is_some()
            {
                out.push(((y * w + x) as usize, index, hit));
            }
        }
    }
    out
}

/// Texture lookups alone, timed: each textured pixel's centre hit and
/// footprint are found first, then the texture filter runs over all of
/// them on one thread, `passes` times (ray casting, footprints and shading
/// excluded, as a peer library's lookups are timed given derivatives).
#[derive(Debug, Clone)]
pub struct LookupTiming {
    /// The filtered texture colour per pixel (transparent where no textured
    /// surface is seen), unshaded.
    pub image: LinearImage,
    /// Median nanoseconds per lookup over the passes.
    pub ns_per_lookup: f64,
    /// Lookups per pass (textured pixels).
    pub lookups: u64,
}

/// Times `filter` on the textured pixels of `scene` (see [`LookupTiming`]).
pub fn time_lookups(
    scene: &Scene,
    width: u32,
    height: u32,
    filter: TextureFilter,
    passes: u32,
) -> Result<LookupTiming, crate::Error> {
    let scene = sized_scene(scene, width, height)?;
    prepare_baselines(&scene, filter)?;
    let frame = Frame::new(&scene);
    let hits = textured_hits(&scene);
    // The footprints (ray casting) before the clock starts, as a peer's
    // lookups get their derivatives from the renderer.
    let footprints: Vec<_> = hits
        .iter()
        .map(|&(pixel, surface, hit)| {
            let (x, y) = (pixel as u32 % width, pixel as u32 / width);
            let square = ScreenSquare::pixel(f64::from(x) + 0.5, f64::from(y) + 0.5);
            tangent_plane::footprint(&scene, &scene.surfaces[surface], &hit, square)
        })
        .collect();
    let mut pixels = vec![Rgba::TRANSPARENT; (width * height) as usize];
    let mut times = Vec::new();
    let mut stats = PixelStats::default();
    for _ in 0..passes.max(1) {
        let start = Instant::now();
        for (&(pixel, surface, hit), &footprint) in hits.iter().zip(&footprints) {
            let (x, y) = (pixel as u32 % width, pixel as u32 / width);
            let square = ScreenSquare::pixel(f64::from(x) + 0.5, f64::from(y) + 0.5);
            if let Some(texture) = frame.texture(surface) {
                let at = TexturedHit {
                    surface,
                    texture,
                    hit: &hit,
                };
                pixels[pixel] = texture_colour(
                    &frame,
                    at,
                    filter,
                    PixelFilter::Box,
                    square,
                    || footprint,
                    &mut stats,
                );
            }
        }
        times.push(start.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    Ok(LookupTiming {
        image: LinearImage {
            width,
            height,
            pixels,
        },
        ns_per_lookup: 1e9 * median / hits.len().max(1) as f64,
        lookups: hits.len() as u64,
    })
}

/// The scene reduced to its textures: unlit, black transparent sky, white
/// multipliers, untextured surfaces transparent. Rendered with
/// supersampling it is the reference for [`time_lookups`] images.
pub fn texture_only(scene: &Scene) -> Scene {
    let mut s = scene.clone();
    s.lighting = Lighting::Unlit;
    s.sky = Sky::Solid(Rgba::TRANSPARENT);
    for surface in &mut s.surfaces {
        surface.colour = if surface.texture.is_some() {
            Rgba::opaque(1.0, 1.0, 1.0)
        } else {
            Rgba::TRANSPARENT
        };
    }
    s
}

/// One textured pixel's lookup, as the renderer would make it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelFootprint {
    /// Index of the pixel in raster order.
    pub pixel: usize,
    /// Index of the surface its centre sees.
    pub surface: usize,
    /// The texture point at the pixel centre.
    pub centre: [f64; 2],
    /// The pixel's footprint (corners in pixel order).
    pub footprint: Footprint,
}

/// The footprints of the textured pixels of `scene` at `width × height`, in
/// raster order (pixels whose footprint is not finite are left out).
pub fn pixel_footprints(
    scene: &Scene,
    width: u32,
    height: u32,
) -> Result<Vec<PixelFootprint>, crate::Error> {
    let scene = sized_scene(scene, width, height)?;
    Ok(textured_hits(&scene)
        .into_iter()
        .filter_map(|(pixel, surface, hit)| {
            let (x, y) = (pixel as u32 % width, pixel as u32 / width);
            let square = ScreenSquare::pixel(f64::from(x) + 0.5, f64::from(y) + 0.5);
            let s = &scene.surfaces[surface];
            Some(PixelFootprint {
                pixel,
                surface,
                centre: tangent_plane::centre_point(s, &hit),
                footprint: tangent_plane::footprint(&scene, s, &hit, square)?,
            })
        })
        .collect())
}

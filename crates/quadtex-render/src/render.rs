//! The render loop: one primary ray per pixel (more where a pixel strategy
//! asks), parallel over rows with rayon and deterministic (each pixel is
//! computed independently, and statistics are integer sums combined in row
//! order).
//!
//! **Pixel filter.** A box over the pixel in *screen* space is not a uniform
//! box over its footprint in texture space: under perspective the far end of
//! a footprint gets less screen area per unit of texture. The texture filter
//! ([`quadtex_core::Texture::filter`], [`quadtex_core::Weighting::Screen`])
//! weighs each strip of the footprint by the screen-space density of the
//! projective map its four corners fix.

use std::time::Instant;

use quadtex_core::Rgba;
use quadtex_io::LinearImage;
use rayon::prelude::*;

use crate::options::{Filter, RenderOptions};
use crate::pixel::shade_pixel;
use crate::scene::Scene;
use crate::shade::Frame;
use crate::stats::{PixelStats, RenderSummary};

/// Renders `scene`; `progress(done_rows, total_rows)` is called as rows finish
/// (from worker threads, in no particular order).
pub fn render(
    scene: &Scene,
    options: &RenderOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(LinearImage, RenderSummary), crate::Error> {
    let (w, h) = match (options.width, options.height) {
        (None, None) => (scene.camera.width(), scene.camera.height()),
        (Some(w), None) => (w, scene.camera.height_for_width(w)),
        (None, Some(h)) => {
            let w = (f64::from(h) * f64::from(scene.camera.width())
                / f64::from(scene.camera.height()))
            .round();
            ((w as u32).max(1), h)
        }
        (Some(w), Some(h)) => (w, h),
    };
    let scene = sized_scene(scene, w, h)?;
    if let Filter::Supersample(n) = options.filter
        && (n == 0 || n > 64)
    {
        return Err(crate::Error::Option(format!(
            "supersample:{n}: the sample grid must be 1..=64 per side"
        )));
    }
    prepare_baselines(&scene, options.filter)?;
    let frame = Frame::new(&scene);
    let start = Instant::now();
    // Which surface each pixel centre sees (0: none), to find the pixels a
    // silhouette may cross: those whose 4-neighbours see something else.
    let seen: Vec<usize> = if !matches!(options.filter, Filter::Supersample(_)) {
        (0..h)
            .into_par_iter()
            .flat_map_iter(|y| {
                let scene = &scene;
                (0..w).map(move |x| {
                    let ray = scene.camera.ray(f64::from(x) + 0.5, f64::from(y) + 0.5);
                    scene.nearest_index(&ray).map_or(0, |(i, _)| i + 1)
                })
            })
            .collect()
    } else {
        Vec::new()
    };
    let straddles = |x: u32, y: u32| -> bool {
        if seen.is_empty() {
            return false;
        }
        let at = |x: u32, y: u32| seen[(y * w + x) as usize];
        let me = at(x, y);
        (x > 0 && at(x - 1, y) != me)
            || (x + 1 < w && at(x + 1, y) != me)
            || (y > 0 && at(x, y - 1) != me)
            || (y + 1 < h && at(x, y + 1) != me)
    };
    let done = std::sync::atomic::AtomicU64::new(0);
    let rows: Vec<(Vec<Rgba>, PixelStats)> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut stats = PixelStats::default();
            let row = (0..w)
                .map(|x| {
                    let mut pixel = PixelStats::default();
                    let c = shade_pixel(
                        &frame,
                        options.filter,
                        options.pixel_filter,
                        (x, y),
                        straddles(x, y),
                        options.seed,
                        &mut pixel,
                    );
                    stats.merge_parts(&pixel);
                    c
                })
                .collect();
            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(n, u64::from(h));
            (row, stats)
        })
        .collect();
    let mut total = PixelStats::default();
    let mut pixels = Vec::with_capacity(w as usize * h as usize);
    for (row, stats) in rows {
        pixels.extend(row);
        total.merge(&stats);
    }
    let summary = RenderSummary {
        width: w,
        height: h,
        seconds: start.elapsed().as_secs_f64(),
        textured_pixels: total.textured,
        filter: total.filter,
    };
    Ok((
        LinearImage {
            width: w,
            height: h,
            pixels,
        },
        summary,
    ))
}

/// Builds the raster baselines a baseline filter needs, before any pixel
/// asks for them (so a failure is one error, not one per pixel).
pub(crate) fn prepare_baselines(scene: &Scene, filter: Filter) -> Result<(), crate::Error> {
    if matches!(
        filter,
        Filter::Trilinear | Filter::Ewa { .. } | Filter::Sat(_)
    ) {
        for s in &scene.surfaces {
            if let Some(t) = &s.texture {
                t.baselines()
                    .map_err(|e| crate::Error::Option(format!("raster baseline: {e}")))?;
            }
        }
    }
    Ok(())
}

/// The scene with its camera at `width × height`, within [`crate::MAX_PIXELS`].
pub(crate) fn sized_scene(scene: &Scene, width: u32, height: u32) -> Result<Scene, crate::Error> {
    if width == 0 || height == 0 || u64::from(width) * u64::from(height) > crate::MAX_PIXELS {
        return Err(crate::Error::Resolution { width, height });
    }
    Ok(Scene {
        camera: scene.camera.with_size(width, height),
        ..scene.clone()
    })
}

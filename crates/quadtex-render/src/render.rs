//! The render loop: one primary ray per pixel (more where a pixel strategy
//! asks), parallel over rows with rayon and deterministic (each pixel is
//! computed independently, and statistics are integer sums combined in row
//! order).
//!
//! **Pixel filter.** A box (tent, Mitchell) over the pixel in *screen*
//! space is not a uniform box over its footprint in texture space: under
//! perspective the far end of a footprint gets less screen area per unit of
//! texture. The quadtree filter integrates the pixel filter exactly over
//! each planar primitive's visible part of the support
//! ([`quadtex_core::Texture::integrate_region`], `crate::exact`).

use std::time::Instant;

use quadtex_core::Rgba;
use quadtex_io::LinearImage;
use rayon::prelude::*;

use crate::caster::Seen;
use crate::exact::{Scratch, SurfaceViews};
use crate::frame::Frame;
use crate::options::{Filter, RenderOptions};
use crate::pixel::{Neighbourhood, shade_pixel};
use crate::scene::Scene;
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
    // The frame's own set-up (views, shadow grids) counts in its time.
    let start = Instant::now();
    let frame = Frame::new(&scene);
    let mut views = SurfaceViews::new(&scene);
    // Which primitive each pixel centre sees (0: the sky), on a grid padded
    // by the widest filter's reach so pixels at the image's edge see what
    // lies beyond it.
    let pad = PAD as i64;
    let (gw, gh) = (i64::from(w) + 2 * pad, i64::from(h) + 2 * pad);
    let seen: Vec<Seen> = if !matches!(options.filter, Filter::Supersample(_)) {
        let (seen, reach) = crate::visibility::visibility_grid(
            &scene,
            &frame.rays,
            &views,
            (gw as usize, gh as usize),
            pad as f64,
        );
        views.set_mesh_reach(reach);
        seen
    } else {
        Vec::new()
    };
    let views = views;
    // Centres within reach of the support: a change there may cross it.
    let reach = (options.pixel_filter.radius() + 0.5).ceil() as i64;
    let neighbourhood = |x: u32, y: u32, ids: &mut Vec<Seen>| -> bool {
        ids.clear();
        let mut sky = false;
        if seen.is_empty() {
            return false;
        }
        let row_of = |dy: i64| {
            let centre = (i64::from(y) + pad + dy) * gw + i64::from(x) + pad;
            &seen[(centre - reach) as usize..=(centre + reach) as usize]
        };
        // Most neighbourhoods see one thing only: one comparison a centre.
        let first = row_of(0)[reach as usize];
        if (-reach..=reach).all(|dy| row_of(dy).iter().all(|&id| id == first)) {
            if first == 0 {
                return true;
            }
            ids.push(first);
            return false;
        }
        for dy in -reach..=reach {
            for &id in row_of(dy) {
                if id == 0 {
                    sky = true;
                } else if ids.last() != Some(&id) && !ids.contains(&id) {
                    ids.push(id);
                }
            }
        }
        sky
    };
    let done = std::sync::atomic::AtomicU64::new(0);
    // Each row is shaded into its place in the image: no per-row buffers
    // gathered afterwards on one thread (about 30 ms of a 1080p frame).
    let mut pixels = vec![Rgba::TRANSPARENT; w as usize * h as usize];
    let row_stats: Vec<PixelStats> = pixels
        .par_chunks_mut(w as usize)
        .enumerate()
        .map(|(y, row)| {
            let y = y as u32;
            let mut stats = PixelStats::default();
            let mut ids = Vec::new();
            let mut scratch = Scratch::default();
            for (x, out) in (0..w).zip(row.iter_mut()) {
                let mut pixel = PixelStats::default();
                let sky = neighbourhood(x, y, &mut ids);
                let centre = (!seen.is_empty())
                    .then(|| seen[((i64::from(y) + pad) * gw + i64::from(x) + pad) as usize]);
                let near = Neighbourhood {
                    primitives: &ids,
                    sky,
                    centre,
                    views: &views,
                };
                *out = shade_pixel(
                    &frame,
                    options.filter,
                    options.pixel_filter,
                    (x, y),
                    &near,
                    options.seed,
                    &mut scratch,
                    &mut pixel,
                );
                stats.merge_parts(&pixel);
            }
            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(n, u64::from(h));
            stats
        })
        .collect();
    // Merged in row order, so the summary's sums do not depend on the
    // threads' schedule.
    let mut total = PixelStats::default();
    for stats in &row_stats {
        total.merge(stats);
    }
    let summary = RenderSummary {
        width: w,
        height: h,
        seconds: start.elapsed().as_secs_f64(),
        textured_pixels: total.textured,
        filter: total.filter,
        max_weight_error: total.weight_error,
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

/// Pixels of padding around the image in the visibility pass: the reach of
/// the widest pixel filter (Mitchell, radius 2, plus half a pixel).
const PAD: u32 = 3;

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
    if matches!(filter, Filter::EwaSameMemory { .. }) {
        for s in &scene.surfaces {
            if let Some(t) = &s.texture {
                t.same_memory_pyramid()
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

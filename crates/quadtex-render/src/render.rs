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
use crate::exact::{SHARED_CUT_PIXELS, SHARED_CUT_PRIMITIVES, Scratch, SurfaceViews};
use crate::frame::Frame;
use crate::options::{PixelFilter, RenderOptions, TextureFilter};
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
    let mut image = LinearImage::default();
    let summary = render_with(scene, options, progress, Spans::Shared, &mut image, None)?;
    Ok((image, summary))
}

/// As [`render`], into `image`: its buffer is resized to the frame (and
/// its size set) and every pixel overwritten, so a loop of frames at one
/// size (a camera path, a real-time preview) allocates and clears its
/// 1080p buffer (33 MB of `f32` RGBA, about 15 ms of page faults and
/// clearing on a 2-core machine) once instead of every frame. On an error
/// the image is left as it was.
pub fn render_into(
    scene: &Scene,
    options: &RenderOptions,
    image: &mut LinearImage,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<RenderSummary, crate::Error> {
    render_with(scene, options, progress, Spans::Shared, image, None)
}

/// Whether runs of pixels inside one primitive may share their answer
/// ([`crate::span`]) and runs of box pixels whose centres see more than
/// one thing be cut as one support ([`SHARED_CUT_PIXELS`]); the tests render
/// each way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Spans {
    Shared,
    /// Spans shared, cuts not.
    #[cfg(test)]
    NoSharedCuts,
    #[cfg(test)]
    EachPixel,
}

/// Renders `scene` into `image`; with `bounds`, also each pixel's
/// relative error bound (the largest its counters recorded), row by row.
fn render_with(
    scene: &Scene,
    options: &RenderOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
    spans: Spans,
    image: &mut LinearImage,
    bounds: Option<&mut Vec<f64>>,
) -> Result<RenderSummary, crate::Error> {
    let (w, h) = output_size(scene, options);
    let scene = sized_scene(scene, w, h)?;
    if let TextureFilter::Supersample(n) = options.filter
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
    let centres = CentreGrid::cast(&scene, &frame, &mut views, options, (w, h));
    let rows = Rows {
        scene: &scene,
        frame: &frame,
        views: &views,
        centres: &centres,
        options,
        spans,
        width: w,
    };
    let done = std::sync::atomic::AtomicU64::new(0);
    // Each row is shaded into its place in the image: no per-row buffers
    // gathered afterwards on one thread (about 30 ms of a 1080p frame).
    // Every pixel is written below, so a buffer of the right size is
    // reused as it is.
    let mut pixels = std::mem::take(&mut image.pixels);
    let len = w as usize * h as usize;
    if pixels.len() != len {
        // A new buffer's pages are first touched by every thread at once:
        // filled on one, a 1080p frame's 33 MB took 14–25 ms of the first
        // frame on the 2-core VM (its pages' faults, then the writes).
        pixels.clear();
        pixels.par_extend(rayon::iter::repeat_n(Rgba::TRANSPARENT, len));
    }
    let shade = |y: usize, row: &mut [Rgba], bounds: &mut [f64]| {
        let stats = rows.shade(y as u32, row, bounds);
        let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress(n, u64::from(h));
        stats
    };
    // One task a row. Rows cost very different amounts (a row at a
    // horizon costs a hundred sky rows or more), and rayon's adaptive
    // split, left to itself, hands each thread long runs of rows: the
    // demo at 1080p kept 1.6 of 2 cores busy; split to single rows, 1.9
    // (docs/performance.md, "One task a row").
    let row_stats: Vec<PixelStats> = match bounds {
        None => (pixels.par_chunks_mut(w as usize).enumerate())
            .with_max_len(1)
            .map(|(y, row)| shade(y, row, &mut []))
            .collect(),
        Some(bounds) => {
            bounds.clear();
            bounds.resize(pixels.len(), 0.0);
            (pixels
                .par_chunks_mut(w as usize)
                .zip(bounds.par_chunks_mut(w as usize)))
            .enumerate()
            .with_max_len(1)
            .map(|(y, (row, bounds))| shade(y, row, bounds))
            .collect()
        }
    };
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
    *image = LinearImage {
        width: w,
        height: h,
        pixels,
    };
    Ok(summary)
}

/// The image's size: the options' width and height, the camera's where
/// neither is given, the camera's aspect where one is.
fn output_size(scene: &Scene, options: &RenderOptions) -> (u32, u32) {
    match (options.width, options.height) {
        (None, None) => (scene.camera.width(), scene.camera.height()),
        (Some(w), None) => (w, scene.camera.height_for_width(w)),
        (None, Some(h)) => {
            let w = (f64::from(h) * f64::from(scene.camera.width())
                / f64::from(scene.camera.height()))
            .round();
            ((w as u32).max(1), h)
        }
        (Some(w), Some(h)) => (w, h),
    }
}

/// Which primitive each pixel centre sees (0: the sky), on a grid padded
/// by the widest filter's reach so pixels at the image's edge see what
/// lies beyond it; empty when supersampling, which asks no neighbourhood.
struct CentreGrid {
    seen: Vec<Seen>,
    /// The grid's width: the image's plus twice the padding.
    width: i64,
    /// [`PAD`].
    pad: i64,
    /// Centres within reach of the pixel filter's support: a change there
    /// may cross it.
    reach: i64,
}

impl CentreGrid {
    /// Casts the grid for an image of `(w, h)` pixels; the visibility pass
    /// also gives `views` where the mesh triangles reach and their screen
    /// bins.
    fn cast(
        scene: &Scene,
        frame: &Frame<'_>,
        views: &mut SurfaceViews,
        options: &RenderOptions,
        (w, h): (u32, u32),
    ) -> CentreGrid {
        let pad = PAD as i64;
        let (gw, gh) = (i64::from(w) + 2 * pad, i64::from(h) + 2 * pad);
        let seen: Vec<Seen> = if !matches!(options.filter, TextureFilter::Supersample(_)) {
            let (seen, reach, bins) = crate::visibility::visibility_grid(
                scene,
                &frame.rays,
                views,
                (gw as usize, gh as usize),
                pad as f64,
                matches!(options.filter, TextureFilter::Quadtree(_)),
            );
            views.set_mesh_reach(reach);
            views.set_screen_bins(bins);
            seen
        } else {
            Vec::new()
        };
        CentreGrid {
            seen,
            width: gw,
            pad,
            reach: (options.pixel_filter.radius() + 0.5).ceil() as i64,
        }
    }

    /// Lists in `ids` the primitives the centres in reach of pixel `(x, y)`
    /// see, each once, and returns whether one sees the sky. `uniform`:
    /// what every centre in reach sees, when they all see one thing
    /// ([`uniform_in_reach`]).
    fn neighbourhood(&self, x: u32, y: u32, uniform: Option<Seen>, ids: &mut Vec<Seen>) -> bool {
        let (seen, gw, pad, reach) = (&self.seen, self.width, self.pad, self.reach);
        ids.clear();
        let mut sky = false;
        if seen.is_empty() {
            return false;
        }
        // Most neighbourhoods see one thing only.
        if let Some(id) = uniform {
            if id == 0 {
                return true;
            }
            ids.push(id);
            return false;
        }
        let row_of = |dy: i64| {
            let centre = (i64::from(y) + pad + dy) * gw + i64::from(x) + pad;
            &seen[(centre - reach) as usize..=(centre + reach) as usize]
        };
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
    }

    /// How many of pixels `x..end` of row `y`, from `x`, one shared cut
    /// takes: pixels join while the primitives their centres in reach see
    /// number at most [`SHARED_CUT_PRIMITIVES`] (two pixels at least).
    /// Returns the cut's end, and those primitives in `shared` (`ids`:
    /// scratch).
    fn shared_run(
        &self,
        (x, end, y): (u32, u32, u32),
        ids: &mut Vec<Seen>,
        shared: &mut Vec<Seen>,
    ) -> u32 {
        shared.clear();
        for p in x..end {
            self.neighbourhood(p, y, None, ids);
            let before = shared.len();
            for &id in ids.iter() {
                if !shared[..before].contains(&id) && !shared[before..].contains(&id) {
                    shared.push(id);
                }
            }
            if p >= x + 2 && shared.len() > SHARED_CUT_PRIMITIVES {
                shared.truncate(before);
                return p;
            }
        }
        end
    }

    /// What pixel `(x, y)`'s own centre sees, when the grid was cast.
    fn centre(&self, x: u32, y: u32) -> Option<Seen> {
        let (gw, pad) = (self.width, self.pad);
        (!self.seen.is_empty())
            .then(|| self.seen[((i64::from(y) + pad) * gw + i64::from(x) + pad) as usize])
    }
}

/// What shading a row of the frame takes.
struct Rows<'r> {
    scene: &'r Scene,
    frame: &'r Frame<'r>,
    views: &'r SurfaceViews,
    centres: &'r CentreGrid,
    options: &'r RenderOptions,
    spans: Spans,
    /// The image's width.
    width: u32,
}

impl Rows<'_> {
    /// Shades row `y` into `row`, and each pixel's relative error bound
    /// into `bounds` unless it is empty; returns what it cost.
    fn shade(&self, y: u32, row: &mut [Rgba], bounds: &mut [f64]) -> PixelStats {
        let (options, spans, views, centres) = (self.options, self.spans, self.views, self.centres);
        let mut stats = PixelStats::default();
        let mut ids = Vec::new();
        let mut scratch = Scratch::for_row(views);
        let uniform = uniform_in_reach(
            &centres.seen,
            centres.width as usize,
            (y + PAD) as usize,
            PAD as usize,
            centres.reach as usize,
            self.width as usize,
        );
        let shared = match spans {
            Spans::Shared => true,
            #[cfg(test)]
            Spans::NoSharedCuts => true,
            #[cfg(test)]
            Spans::EachPixel => false,
        };
        let runs = match (shared, options.filter) {
            (true, TextureFilter::Quadtree(_)) => runs_of_primitives(&uniform),
            _ => Vec::new(),
        };
        let shared_cuts = match (spans, options.filter, options.pixel_filter) {
            (Spans::Shared, TextureFilter::Quadtree(filter_options), PixelFilter::Box) => {
                Some(filter_options)
            }
            _ => None,
        };
        let mut shared_ids = Vec::new();
        // Where a shared cut failed (a sphere listed, or a primitive with
        // no view), its run's pixels go one by one: no other is tried before
        // this pixel.
        let mut no_shared_cut_until = 0;
        for (x, out) in (0..self.width).zip(row.iter_mut()) {
            // A pixel a span or the row's last shared cut answered.
            let mut fill = |scratch: &Scratch<'_>, out: &mut Rgba, stats: &mut PixelStats| {
                let filled =
                    (scratch.span_fill((x, y))).or_else(|| scratch.shared_cut_fill((x, y)));
                if let Some((colour, parts)) = filled {
                    *out = *colour;
                    stats.merge_parts(parts);
                    record(bounds, x, parts);
                }
                filled.is_some()
            };
            if fill(&scratch, out, &mut stats) {
                continue;
            }
            // A run of pixels whose centres in reach see more than one thing
            // (`uniform` holds `None` for each), not yet answered: one cut,
            // whose pixels the fill then answers.
            if let Some(filter_options) = &shared_cuts
                && x >= no_shared_cut_until
            {
                let mixed = |x: u32| uniform.get(x as usize) == Some(&None);
                let run_end = (x..self.width.min(x + SHARED_CUT_PIXELS))
                    .take_while(|&x| mixed(x))
                    .last()
                    .map_or(x, |last| last + 1);
                if run_end >= x + 2 {
                    let end = centres.shared_run((x, run_end, y), &mut ids, &mut shared_ids);
                    let cut = (x, end, y);
                    if !scratch.shared_cut(self.frame, filter_options, cut, &shared_ids, views) {
                        no_shared_cut_until = run_end;
                    } else if fill(&scratch, out, &mut stats) {
                        continue;
                    }
                }
            }
            if let (true, TextureFilter::Quadtree(filter_options), Some(Some(0))) =
                (shared, options.filter, uniform.get(x as usize))
                && let Some(colour) = scratch.sky_pixel(
                    self.scene,
                    views,
                    &filter_options,
                    options.pixel_filter,
                    (x, y),
                )
            {
                *out = colour;
                continue;
            }
            let mut pixel = PixelStats::default();
            let sky =
                centres.neighbourhood(x, y, uniform.get(x as usize).copied().flatten(), &mut ids);
            let near = Neighbourhood {
                primitives: &ids,
                sky,
                centre: centres.centre(x, y),
                run: runs.get(x as usize).copied().unwrap_or(0),
                views,
            };
            *out = shade_pixel(self.frame, options, (x, y), &near, &mut scratch, &mut pixel);
            stats.merge_parts(&pixel);
            record(bounds, x, &pixel);
        }
        scratch.end_row();
        stats
    }
}

/// Writes pixel `x`'s relative error bound, the largest its counters
/// `parts` recorded, into `bounds` (when they are kept).
fn record(bounds: &mut [f64], x: u32, parts: &PixelStats) {
    if let Some(b) = bounds.get_mut(x as usize) {
        *b = parts.filter.max_error_bound;
    }
}

/// Pixels of padding around the image in the visibility pass: the reach of
/// the widest pixel filter (Mitchell, radius 2, plus half a pixel).
const PAD: u32 = 3;

/// Builds the raster baselines a baseline filter needs, before any pixel
/// asks for them (so a failure is one error, not one per pixel).
pub(crate) fn prepare_baselines(scene: &Scene, filter: TextureFilter) -> Result<(), crate::Error> {
    if matches!(
        filter,
        TextureFilter::Trilinear | TextureFilter::Ewa { .. } | TextureFilter::Sat(_)
    ) {
        for s in &scene.surfaces {
            if let Some(t) = &s.texture {
                t.baselines()
                    .map_err(|e| crate::Error::Option(format!("raster baseline: {e}")))?;
            }
        }
    }
    if matches!(filter, TextureFilter::EwaSameMemory { .. }) {
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

/// For each pixel of a row, what every centre within `reach` of its own
/// sees when they all see one thing (`None` where they differ, or where
/// `seen` is empty): `seen` is the padded grid, `gw` wide, the row's
/// centres on grid row `grid_row` from column `pad`. One pass over the
/// columns (those whose `2·reach + 1` centres agree) and their runs, where
/// comparing each pixel's square of centres costs `(2·reach + 1)²`.
fn uniform_in_reach(
    seen: &[Seen],
    gw: usize,
    grid_row: usize,
    pad: usize,
    reach: usize,
    width: usize,
) -> Vec<Option<Seen>> {
    if seen.is_empty() || reach > pad || reach > grid_row {
        return Vec::new();
    }
    let rows: Vec<&[Seen]> = (grid_row - reach..=grid_row + reach)
        .filter_map(|r| seen.get(r * gw..(r + 1) * gw))
        .collect();
    if rows.len() != 2 * reach + 1 || pad + width + reach > gw {
        return Vec::new();
    }
    let mut out = Vec::with_capacity(width);
    let (mut run, mut last) = (0, None);
    for c in pad - reach..pad + width + reach {
        let id = rows[0][c];
        let column = rows.iter().all(|r| r[c] == id).then_some(id);
        run = match column {
            Some(_) if column == last => run + 1,
            Some(_) => 1,
            None => 0,
        };
        last = column;
        // Column `c` closes the window of pixel `c − pad − reach`.
        if c >= pad + reach {
            out.push(column.filter(|_| run > 2 * reach));
        }
    }
    out
}

/// For each pixel of a row, given what every centre in its reach sees
/// when they agree ([`uniform_in_reach`]), how many pixels from it on
/// (itself included) agree on the same primitive: 0 where the centres
/// differ or see the sky.
fn runs_of_primitives(uniform: &[Option<Seen>]) -> Vec<u32> {
    let mut runs = vec![0u32; uniform.len()];
    for x in (0..uniform.len()).rev() {
        runs[x] = match uniform[x] {
            Some(id) if id != 0 => {
                let next = if uniform.get(x + 1) == Some(&Some(id)) {
                    runs[x + 1]
                } else {
                    0
                };
                next.saturating_add(1)
            }
            _ => 0,
        };
    }
    runs
}

#[cfg(test)]
mod tests;

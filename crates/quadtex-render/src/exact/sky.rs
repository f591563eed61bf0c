//! The sky over a pixel or part of one: at the centre where a bound
//! allows ([`sky_at_centre`]), else by quadrature ([`sky_integral`]), and
//! the spans of sky pixels clear of every primitive ([`SkySpan`]).

use quadtex_core::{ConvexPolygon, FilterOptions, PixelFilter, Rgba};

use crate::frame::sky;
use crate::math::Ray;
use crate::scene::Scene;
use crate::span::span_rect;
use crate::view::Placement;

use super::views::SurfaceViews;

/// Pixels of one row, from the one that set the span up to `until`
/// (exclusive), whose filter supports every plane and quad of the scene
/// misses when `clear` ([`views_miss`]).
#[derive(Default)]
pub(super) struct SkySpan {
    row: Option<u32>,
    until: u32,
    pub(super) clear: bool,
    /// The rectangle the span's supports cover.
    pub(super) wide: Option<ConvexPolygon>,
    /// Whether no mesh triangle may reach into `wide`, once asked.
    pub(super) meshes_clear: Option<bool>,
}

impl SkySpan {
    /// Whether every plane and quad misses the rectangle the supports of
    /// the span of pixel `(x, y)` cover, a span of [`SKY_SPAN`] pixels set
    /// up from `x` when none of this row holds it ([`views_miss`]).
    pub(super) fn views_clear(
        &mut self,
        cache: &SurfaceViews,
        filter: PixelFilter,
        (x, y): (u32, u32),
    ) -> bool {
        if self.row != Some(y) || x >= self.until {
            let wide = span_rect(filter, (x, y), SKY_SPAN);
            *self = SkySpan {
                row: Some(y),
                until: x.saturating_add(SKY_SPAN),
                clear: (cache.views.iter().flatten())
                    .all(|v| matches!(v.placement(&wide), Placement::Outside))
                    && cache.spheres_miss(wide.bounds()),
                wide: Some(wide),
                meshes_clear: None,
            };
        }
        self.clear
    }
}

/// Pixels a row's [`SkySpan`] covers.
pub(super) const SKY_SPAN: u32 = 32;

/// Whether every plane and quad of the scene misses the support of pixel
/// `(x, y)` (a pixel whose neighbourhood's centres all see the sky), as
/// [`View::misses`](crate::view::View::misses) decides it, with the test
/// made once for a span of [`SKY_SPAN`] pixels of the row: the rectangle
/// their supports cover is wholly beyond one line of each view. That implies the same of each
/// pixel's support, computed: its corners lie in the rectangle (the same
/// float expressions, monotone in the pixel), and each line's side test,
/// `a·x + b·y + c` in floats, is monotone in `x` and in `y`, so it is
/// largest at one of the rectangle's corners. A span that fails (a view
/// reaches into it somewhere) leaves its pixels to the test one by one.
pub(super) fn views_miss(
    cache: &SurfaceViews,
    span: &mut SkySpan,
    filter: PixelFilter,
    (x, y): (u32, u32),
    support: &ConvexPolygon,
) -> bool {
    span.views_clear(cache, filter, (x, y))
        || cache.views.iter().flatten().all(|v| v.misses(support))
}

/// The largest difference between the sky's colours in any channel: how
/// far its colour anywhere is from its colour at one point.
pub(super) fn sky_range(scene: &Scene) -> f64 {
    match scene.sky {
        crate::scene::Sky::Solid(_) => 0.0,
        crate::scene::Sky::Gradient { horizon, zenith } => (horizon - zenith)
            .to_array()
            .iter()
            .fold(0.0, |m, v| m.max(f64::from(v.abs()))),
    }
}

/// The screen row where the camera's ray through column `px` is level
/// (`direction.y = 0`), if the camera is not rolled onto its side.
pub(super) fn level_line(scene: &Scene, px: f64) -> Option<f64> {
    let cam = &scene.camera;
    let (width, height) = (f64::from(cam.width), f64::from(cam.height));
    let aspect = width / height;
    let sx = (2.0 * px / width - 1.0) * cam.tan_half_fov * aspect;
    // forward.y + right.y·sx + up.y·sy = 0.
    if cam.up.y.abs() < 1e-12 {
        return None;
    }
    let sy = -(cam.forward.y + cam.right.y * sx) / cam.up.y;
    Some((1.0 - sy / cam.tan_half_fov) * height / 2.0)
}

/// Cells per pixel side for the sky's midpoint rule.
pub(super) const SKY_CELLS: f64 = 4.0;

/// How far the sky's integral over a pixel may be from exact when it is
/// taken at the pixel's centre alone ([`sky_at_centre`]): a quarter of the
/// error bound the texture filter aims at (the default under a fixed level).
pub(super) fn sky_tolerance(options: &FilterOptions) -> f64 {
    use quadtex_core::LevelOfDetail;
    match (options.level_of_detail(), LevelOfDetail::default()) {
        (LevelOfDetail::ErrorBound(e), _) | (_, LevelOfDetail::ErrorBound(e)) => 0.25 * e,
        _ => 0.0,
    }
}

/// The gradient sky at the centre of the pixel centred at `centre`, and
/// a bound (per channel) on how far that is from the sky's mean over the
/// support of `filter` (its weight integrating to 1 there); `None` for a
/// solid sky or where the support may reach the level line (where the
/// gradient's square root has an unbounded derivative).
///
/// The bound: with `g = 2·tan(fov/2)/height` the change of the unnormalised
/// ray direction per pixel (the same along both axes), the unit direction's
/// height `y` changes by at most `g` and bends by at most `3g²` per pixel
/// (differentiating `D/|D|` twice with `|D| ≥ 1`), so `t = √y` has second
/// derivatives at most `T = 3g²/(2√y) + g²/(4y^{3/2})` along any screen
/// direction, `y` its least over the support (the centre's less `√2·r·g`,
/// `r` the filter's radius). The midpoint rule over the box's unit square
/// is then off by at most `T·∫|δ|²/2 = T/12` in `t`, times the sky's
/// contrast in colour; a symmetric `k` makes the rule exact for linear
/// functions, and the rest is at most `T·M₂/2` ([`second_moment`]).
/// Where the whole support looks below level the sky is the horizon
/// colour: exact.
pub(super) fn sky_at_centre(
    scene: &Scene,
    centre: [f64; 2],
    filter: PixelFilter,
) -> Option<([f64; 4], f64)> {
    let crate::scene::Sky::Gradient { horizon, zenith } = scene.sky else {
        return None;
    };
    let ray = scene.camera.ray(centre[0], centre[1]);
    let g = sky_step(scene);
    let reach = std::f64::consts::SQRT_2 * filter.radius() * g;
    let y_min = ray.direction.y - reach;
    let bound = if y_min + 2.0 * reach < 0.0 {
        0.0
    } else if y_min > 0.0 {
        let contrast = sky_contrast(horizon, zenith);
        sky_bound_under(g, contrast, y_min, filter)
    } else {
        return None;
    };
    Some((sky(scene, &ray).to_array().map(f64::from), bound))
}

/// `M₂ = ∫∫ |δ|²·|k(δ)| dδ` over the filter's support, rounded up: the
/// box's `1/6`, the tent's `1/3` (`2·∫x²·(1 − |x|)`), Mitchell's
/// `2·∫x²|k₁|·∫|k₁|` (0.57268…, its negative lobes counted as positive;
/// checked against a dense sum in the tests).
pub(super) fn second_moment(filter: PixelFilter) -> f64 {
    match filter {
        PixelFilter::Box => 1.0 / 6.0,
        PixelFilter::Tent => 1.0 / 3.0,
        PixelFilter::Mitchell => 0.5727,
    }
}

/// The gradient sky's largest change in a channel, horizon to zenith.
#[inline]
pub(super) fn sky_contrast(horizon: Rgba, zenith: Rgba) -> f64 {
    (horizon.to_array().iter().zip(zenith.to_array()))
        .map(|(h, z)| f64::from((z - h).abs()))
        .fold(0.0, f64::max)
}

/// `g` of [`sky_at_centre`]: the change of the unnormalised ray direction
/// per pixel.
#[inline]
pub(super) fn sky_step(scene: &Scene) -> f64 {
    2.0 * scene.camera.tan_half_fov / f64::from(scene.camera.height)
}

/// [`sky_at_centre`]'s bound where the least height over the pixel is
/// `y_min > 0`: `T/12` times the contrast.
#[inline]
pub(super) fn sky_bound(g: f64, contrast: f64, y_min: f64) -> f64 {
    sky_curvature(g, y_min) / 12.0 * contrast
}

/// [`sky_at_centre`]'s `T`: a bound on `t = √y`'s second derivatives
/// along any screen direction where `y ≥ y_min > 0`.
#[inline]
fn sky_curvature(g: f64, y_min: f64) -> f64 {
    // 1.5/√y + 0.25/y^{3/2} over one division (one a sky pixel).
    g * g * (1.5 * y_min + 0.25) / (y_min * y_min.sqrt())
}

/// [`sky_bound`] for the support of `filter`: `T·M₂/2` times the
/// contrast ([`second_moment`]; the box's `M₂ = 1/6` gives `T/12`, by
/// [`sky_bound`] itself, whose bisection in [`sky_clear_above`] the box's
/// shortcut relies on).
#[inline]
pub(super) fn sky_bound_under(g: f64, contrast: f64, y_min: f64, filter: PixelFilter) -> f64 {
    match filter {
        PixelFilter::Box => sky_bound(g, contrast, y_min),
        _ => 0.5 * sky_curvature(g, y_min) * second_moment(filter) * contrast,
    }
}

/// A height above which [`sky_at_centre`]'s bound for `filter` is
/// within `tolerance` (`∞` where none is, or the sky is solid): the
/// bound falls as `y_min`
/// grows, and this is where it is half the tolerance (bisected), so that
/// the bound computed in floats above it is within the tolerance too. A
/// sky pixel whose `y_min` is past it takes the centre's value without
/// the bound's square root and divisions, the same answer.
pub(super) fn sky_clear_above(scene: &Scene, tolerance: f64, filter: PixelFilter) -> f64 {
    let crate::scene::Sky::Gradient { horizon, zenith } = scene.sky else {
        return f64::INFINITY;
    };
    let contrast = sky_contrast(horizon, zenith);
    let g = sky_step(scene);
    let within = |y: f64| sky_bound_under(g, contrast, y, filter) <= 0.5 * tolerance;
    if !within(1.0) {
        return f64::INFINITY;
    }
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..64 {
        let mid = 0.5 * (lo + hi);
        if within(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// Whether a region is the filter's whole support, when the caller knows.
#[derive(Debug, Clone, Copy)]
pub(super) enum Whole {
    Yes,
    Unknown,
}

/// `(Σ sky·k, Σ k)` over screen region `region`, where the sky shows. A
/// whole support is taken at its centre where
/// [`sky_at_centre`]'s bound is within `tolerance`.
pub(super) fn sky_integral(
    scene: &Scene,
    region: &ConvexPolygon,
    whole: Whole,
    filter: PixelFilter,
    centre: [f64; 2],
    tolerance: f64,
) -> ([f64; 4], f64) {
    let colour_at = |s: [f64; 2]| -> [f64; 4] {
        let ray: Ray = scene.camera.ray(s[0], s[1]);
        sky(scene, &ray).to_array().map(f64::from)
    };
    if let crate::scene::Sky::Solid(c) = scene.sky {
        let w = filter.integral(region, centre);
        return (c.to_array().map(|v| f64::from(v) * w), w);
    }
    let whole = match whole {
        Whole::Yes => true,
        Whole::Unknown => region.area() >= filter.support(centre).area() * (1.0 - 1e-12),
    };
    if whole
        && let Some((c, bound)) = sky_at_centre(scene, centre, filter)
        && bound <= tolerance
    {
        let w = filter.integral(region, centre);
        return (c.map(|v| v * w), w);
    }
    let (lo, hi) = region.bounds();
    let step = 1.0 / SKY_CELLS;
    let level = level_line(scene, 0.5 * (lo[0] + hi[0]));
    if whole && level.is_none_or(|yh| yh < lo[1] - 1.0 || yh > hi[1] + 1.0) {
        // The whole support, away from the level line: the sky is smooth
        // there; 2×2 Gauss–Legendre points per unit cell of the filter.
        const G: [f64; 2] = [0.211_324_865_405_187_1, 0.788_675_134_594_812_9];
        let (mut acc, mut weight) = ([0.0; 4], 0.0);
        let r = filter.radius();
        let cells = (2.0 * r).ceil() as i32;
        for j in 0..cells {
            for i in 0..cells {
                let (x0, y0) = (centre[0] - r + f64::from(i), centre[1] - r + f64::from(j));
                let (sx, sy) = ((2.0 * r).min(1.0), (2.0 * r).min(1.0));
                for gy in G {
                    for gx in G {
                        let s = [x0 + gx * sx, y0 + gy * sy];
                        let w = filter.weight(s[0] - centre[0], s[1] - centre[1]) * sx * sy / 4.0;
                        for (a, v) in acc.iter_mut().zip(colour_at(s)) {
                            *a += v * w;
                        }
                        weight += w;
                    }
                }
            }
        }
        // The weights' exact total (the points integrate k only approximately).
        let exact = filter.integral(region, centre);
        return (acc.map(|v| v * exact / weight), exact);
    }
    // Row boundaries: quarter pixels, graded geometrically towards the line
    // where the view turns level (the gradient's square root has an
    // unbounded derivative there) when it lies at the region's bottom.
    // Eight halvings: the last row, within 2^-8 of the line's distance,
    // errs by about 0.04·√g·h^{3/2} times the contrast (the midpoint rule
    // on √s over [0, h]; g as in [`sky_at_centre`]), under 1e-6 at the
    // demo's sizes; twenty halvings changed the level line's rows by under
    // 1e-6 and cost 2.3 times the instructions (the demo at 1920 wide:
    // 0.19 → 0.08 G). The coarse rows dominate the error (test
    // `the_sky_at_the_level_line_matches_a_dense_sum`).
    let mut rows = Vec::with_capacity(12);
    match level {
        Some(yh) if yh >= lo[1] && yh <= hi[1] + step => {
            let top = lo[1];
            let d = yh - top;
            rows.push(top);
            for k in 1..=8 {
                let y = yh - d * 0.5f64.powi(k);
                if y > top && y < hi[1] {
                    rows.push(y);
                }
            }
            rows.push(hi[1]);
        }
        _ => {
            let mut y = (lo[1] * SKY_CELLS).floor() * step;
            while y < hi[1] {
                rows.push(y);
                y += step;
            }
            rows.push(y);
        }
    }
    let (mut acc, mut weight) = ([0.0; 4], 0.0);
    // A whole box-filtered pixel is its bounding box: each cell is a
    // rectangle whose weight is its area, no clipping needed.
    let rectangle = whole && filter == PixelFilter::Box;
    // The cells' sides across, as the sweep below steps them.
    let mut columns = Vec::with_capacity(24);
    let mut x = (lo[0] * SKY_CELLS).floor() * step;
    while x < hi[0] {
        columns.push(x);
        x += step;
    }
    columns.push(x);
    // A cell whose corners lie inside the (convex) region is whole, and
    // the filter's integral over a rectangle is the product of its
    // running integral's differences: only the cells the region's edges
    // cross are clipped. Along one row line the corners inside are a run
    // (the region is convex), found from each end; the line between two
    // rows is shared by both.
    let vertices = region.vertices();
    let orientation = region.signed_area().signum();
    let inside = |p: [f64; 2]| {
        (0..vertices.len()).all(|i| {
            let (a, b) = (vertices[i], vertices[(i + 1) % vertices.len()]);
            orientation * ((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])) >= 0.0
        })
    };
    let run_inside = |y: f64| -> Option<(usize, usize)> {
        let first = columns.iter().position(|&x| inside([x, y]))?;
        let last = columns.iter().rposition(|&x| inside([x, y]))?;
        Some((first, last))
    };
    // (The box's weight is the area, as its `integral` takes it: the
    // region is inside its support.)
    let across = |a: f64, b: f64, c: f64| match filter {
        PixelFilter::Box => b - a,
        _ => filter.cumulative(b - c) - filter.cumulative(a - c),
    };
    let widths: Vec<f64> = columns
        .windows(2)
        .map(|pair| across(pair[0], pair[0] + step, centre[0]))
        .collect();
    let mut below = if rectangle {
        None
    } else {
        rows.first().and_then(|&y| run_inside(y))
    };
    for pair in rows.windows(2) {
        let (y0, y1) = (pair[0], pair[1]);
        let down = across(y0, y1, centre[1]);
        let above = if rectangle { None } else { run_inside(y1) };
        // Cells `j` with both corners on both lines inside.
        let whole_cells = match (below, above) {
            (Some((a0, b0)), Some((a1, b1))) if y1 > y0 => a0.max(a1)..b0.min(b1),
            _ => 0..0,
        };
        below = above;
        for (j, &x0) in columns[..columns.len() - 1].iter().enumerate() {
            let x1 = x0 + step;
            // The cell's sample point and weight.
            let sample = if rectangle {
                let (a, b) = (x0.max(lo[0]), x1.min(hi[0]));
                let w = (b - a) * (y1 - y0);
                (w > 0.0).then_some(([0.5 * (a + b), 0.5 * (y0 + y1)], w))
            } else if whole_cells.contains(&j) {
                let w = widths[j] * down;
                Some(([0.5 * (x0 + x1), 0.5 * (y0 + y1)], w))
            } else {
                let cell = region.clip_rect(x0, y0, x1, y1);
                (cell.area() > 0.0).then(|| (cell.centroid(), filter.integral(&cell, centre)))
            };
            if let Some((s, w)) = sample {
                for (a, v) in acc.iter_mut().zip(colour_at(s)) {
                    *a += v * w;
                }
                weight += w;
            }
        }
    }
    (acc, weight)
}

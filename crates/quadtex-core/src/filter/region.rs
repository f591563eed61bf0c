//! Exact pixels: the integral of a texture over a screen region under a
//! projective map, weighted by a pixel filter, with a stated error bound.
//!
//! **What is computed.** A region `V` of the screen (a convex polygon, in
//! pixel units) sees a planar surface whose texture point is
//! `t = P(s)`, a projective map ([`Projection`]). For a pixel filter `k`
//! centred at `c` ([`PixelFilter`]) the result is
//!
//! ```text
//!   ∫∫_V colour(P(s)) · k(s − c) ds     and     ∫∫_V k(s − c) ds,
//! ```
//!
//! whose ratio is the filtered colour. The texture is piecewise constant on
//! the tree's terminal squares, so the first integral is
//! `Σ_S colour(S) · ∫∫_{P⁻¹(S ∩ Q)} k`, `Q = P(V)`: clip the square against
//! `Q`, map the clipped polygon back to the screen (a projective map sends
//! segments to segments on its visible side), integrate `k` over it: the
//! box's area by the shoelace formula, the tent's and Mitchell's cubic
//! pieces by Green's theorem ([`crate::geometry::polygon`]). Squares inside `Q` need
//! only their four mapped corners; squares outside cost nothing.
//!
//! **Where it stops early, and the bound.** Descending to every terminal
//! square would be exact and slow. Two kinds of square are taken at their
//! stored mean instead, each adding a bound on its error (colour channels
//! in `[0,1]`, so a square's colour range `Δc ≤ 1`; `ρ = |det J(P⁻¹)|` is
//! the screen area per texture area, `|k| ≤ k_S` over the box of the
//! square's screen image (`PixelFilter::largest_weight_in`), `|∇k| ≤ L_k`):
//! * a square inside `Q`: the error is a covariance of colour and weight,
//!   at most `½·Δc·a_S·(k_S·(ρ_max − ρ_min) + ρ_max·L_k·diam(S))`, with
//!   `ρ`'s extremes at the square's corners (`ρ ∝ w⁻³`, `w` affine);
//! * a square on `Q`'s boundary, taken whole over its clipped part `P`: at
//!   most `Δc · k_P · area(P⁻¹(P))`.
//!
//! The walk aims the sum at `ε` times the region's weight
//! (`PixelFilter::weight_scale`: the box's area, a tent's or Mitchell's
//! `|∫k|`), so that a pixel's regions keep its colour within `ε`.
//!
//! The bound `ε` of [`LevelOfDetail::ErrorBound`] is shared half and half:
//! inner squares are taken whole when their bound is `≤ ε/2` of their own
//! weight, boundary squares when their screen area is below
//! `(ε/2)·area(V)·diam(S)/perimeter(V)` (a band along the boundary). The
//! bound actually incurred, summed over the squares taken whole, is
//! returned with every result ([`RegionIntegral::error_bound`]): that sum
//! is rigorous; the rule that aims it at `ε` is a heuristic.
//! [`LevelOfDetail::Fixed`] instead descends every square to that level
//! (or to a terminal square): with the tree's depth, the result is exact up
//! to float rounding and half a 16-bit step on nothing (only terminal
//! colours are used) — the slow, obvious reference the tests use.
//!
//! **Shallow repeated textures.** A tree of depth ≤ 4 repeated or mirrored
//! on both axes is integrated cell by cell over the grid at its depth, band
//! by band, exactly, up to 512 cells a region (`scan_flat_grid`); the
//! walk below does the rest.
//!
//! **Budget.** Refinement also stops after a budget of squares
//! ([`crate::FilterOptions::budget`]: 64 in the renderer, none by default,
//! where it stops only at [`crate::FIXED_LEVEL_CAP`]). Over more than 16 repeated tiles a
//! refinement the budget cuts short with its bound above 5% of full
//! contrast is replaced by the coarse sum (every tile at the tile mean):
//! the partial one is biased by moiré, the coarse one keeps the
//! cancellation over many periods (`docs/algorithm.md` §8, measured there).
//!
//! **Wrap.** Repeat and mirror tiles are grouped in blocks of tiles; a block
//! inside `Q` has the tree's root mean, with the covariance bound above
//! summed over its tiles (`Δc·(k_S·(ρ_max−ρ_min)·(n_x+n_z) + …)`: it shrinks
//! as the block grows, so far, many-tile regions cost `O(log)` blocks). Clamp
//! stretches the outermost cells outwards, border shows the border colour.
//!
//! **Visibility.** The projection's denominator `w` must be positive over
//! the region (the surface in front of the camera). A region reaching the
//! horizon `w = 0` is clipped at a sliver of width `10⁻⁹` pixel beyond which
//! the texture's mean colour is taken (bounded, and reported).

use crate::colour::{Rgba, WeightedColour};
use crate::filter::few_cells::{RasterBox, raster_box};
use crate::filter::options::{FilterOptions, FilterStats, LevelOfDetail};
use crate::filter::pixel_filter::PixelFilter;
use crate::filter::projection::{Projection, apply};
use crate::filter::query::{RegionIntegral, RegionQuery};
use crate::filter::scan::scan_flat_grid;
use crate::filter::walk::{WalkPlan, walk_region};
use crate::filter::wrap::Wrap;
use crate::filter::wrap::uniform_colour_in;
use crate::geometry::polygon::ConvexPolygon;
use crate::tree::QuadTree;

/// Largest screen coordinate a region may have (`2^50` pixels); beyond it
/// the integral is empty (the caller falls back to a point lookup).
pub const MAX_SCREEN_COORDINATE: f64 = (1u64 << 50) as f64;

/// The least `w` a vertex of `region` may have for [`integrate_region`]
/// to take the region as it is: nearer the horizon it cuts off the sliver
/// of `w` below this, whose width is an eighth of the error budget over the
/// region's diameter (`1e-9` pixel under a fixed level). `region`'s
/// coordinates are within [`MAX_SCREEN_COORDINATE`] (the squares cannot
/// overflow).
pub(super) fn horizon_floor(
    projection: &Projection,
    region: &ConvexPolygon,
    options: &FilterOptions,
) -> f64 {
    horizon_floor_of(projection, region.bounds(), region.area(), options)
}

/// [`horizon_floor`] of a region whose bounds and area are known.
#[inline]
fn horizon_floor_of(
    projection: &Projection,
    (rlo, rhi): ([f64; 2], [f64; 2]),
    area: f64,
    options: &FilterOptions,
) -> f64 {
    let sliver_width = match options.level_of_detail() {
        LevelOfDetail::ErrorBound(e) => {
            let (dx, dy) = (rhi[0] - rlo[0], rhi[1] - rlo[1]);
            let diam = (dx * dx + dy * dy).sqrt().max(f64::MIN_POSITIVE);
            (e * area / (8.0 * diam)).max(1e-9)
        }
        LevelOfDetail::Fixed(_) => 1e-9,
    };
    sliver_width * projection.w_gradient
}

/// The colour of the one terminal square of `tree` (folded into a tile by
/// `wrap`) that holds the image of the whole screen region `span` under
/// `projection`, when one does and `span` lies far enough in front of the
/// horizon that [`integrate_region`] takes every region of `pixel`'s size
/// and shape inside it as it is (its vertices at `w` at least twice
/// [`horizon_floor`] of `pixel`; `w` is affine, so its least over such a
/// region is at least its least over `span`'s vertices). Every such
/// region's integral is then this colour times its weight, exactly: its
/// image lies in `span`'s, which lies in the square (a projective map in
/// front of the camera sends a convex polygon to the convex hull of its
/// vertices' images).
pub(crate) fn uniform_colour_over(
    tree: &QuadTree,
    wrap: Wrap,
    projection: &Projection,
    span: &ConvexPolygon,
    pixel: &ConvexPolygon,
    options: &FilterOptions,
) -> Option<Rgba> {
    let within = |p: &ConvexPolygon| {
        let (lo, hi) = p.bounds();
        !p.is_empty()
            && lo
                .iter()
                .chain(&hi)
                .all(|v| v.abs() <= MAX_SCREEN_COORDINATE)
    };
    if !(within(span) && within(pixel)) {
        return None;
    }
    let floor = (2.0 * horizon_floor(projection, pixel, options)).max(f64::MIN_POSITIVE);
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for &s in span.vertices() {
        let w = projection.w(s);
        if w.is_nan() || w < floor {
            return None;
        }
        let t = apply(&projection.texture_from_screen, s);
        if !(t[0].is_finite() && t[1].is_finite()) {
            return None;
        }
        for a in 0..2 {
            lo[a] = lo[a].min(t[a]);
            hi[a] = hi[a].max(t[a]);
        }
    }
    uniform_colour_in(tree, lo, hi, wrap)
}

/// A screen region in front of the horizon, with its bounds and area
/// computed once.
struct VisibleRegion<'r> {
    screen: &'r ConvexPolygon,
    bounds: ([f64; 2], [f64; 2]),
    area: f64,
}

/// The integral (module documentation) over screen region `region` under
/// `query`. The region is first clipped to the filter's support.
pub(crate) fn integrate_region(
    query: &RegionQuery<'_>,
    region: &ConvexPolygon,
    stats: &mut FilterStats,
) -> RegionIntegral {
    stats.footprints += 1;
    stats.fragments += 1;
    stats.traversal.queries += 1;
    let mut out = RegionIntegral::default();
    let projection = query.projection;
    // Borrowed when the box filter takes it as it is; `clipped` and `kept`
    // own what clipping makes of it (a polygon is a few hundred bytes, and
    // this runs once per pixel).
    let (clipped, kept);
    let mut region = match query.filter {
        PixelFilter::Box => region,
        _ => {
            clipped = region.intersect(&query.filter.support(query.centre));
            &clipped
        }
    };
    let (mut rlo, mut rhi) = region.bounds();
    if region.is_empty()
        || rlo
            .iter()
            .chain(&rhi)
            .any(|v| v.is_nan() || v.abs() > MAX_SCREEN_COORDINATE)
    {
        return out;
    }
    // The region's bounds and area, computed once (and again only if the
    // horizon clips it).
    let mut area = region.area();
    // Keep to where the surface is in front, w ≥ w_min. The sliver between
    // the horizon (w = 0) and w_min, where the texture is minified without
    // bound, is taken at the texture's mean with its whole weight as the
    // bound: its width is an eighth of the error budget over the region's
    // diameter (1e-9 pixel under a fixed level).
    let w_min = horizon_floor_of(projection, (rlo, rhi), area, query.options);
    if region
        .vertices()
        .iter()
        .any(|&s| projection.w(s) < w_min.max(f64::MIN_POSITIVE))
    {
        kept = take_horizon_sliver(query, region, w_min.max(f64::MIN_POSITIVE), &mut out);
        region = &kept;
        (rlo, rhi) = region.bounds();
        area = region.area();
        if region.is_empty() {
            return out;
        }
    }
    if !(area > 0.0 && area.is_finite()) {
        return out;
    }
    let visible = VisibleRegion {
        screen: region,
        bounds: (rlo, rhi),
        area,
    };
    integrate_in_front(query, &visible, out, stats)
}

/// `region` cut at `w = floor`: the part in front is returned, the sliver
/// between the horizon (`w = 0`) and `floor` is added to `out` at the
/// tree's mean with its whole weight as the bound; beyond the horizon the
/// surface is not seen at all.
fn take_horizon_sliver(
    query: &RegionQuery<'_>,
    region: &ConvexPolygon,
    floor: f64,
    out: &mut RegionIntegral,
) -> ConvexPolygon {
    let (tree, filter, centre) = (query.tree, query.filter, query.centre);
    let r = query.projection.texture_from_screen[2];
    let sliver = region
        .clip(r[0], r[1], r[2])
        .clip(-r[0], -r[1], floor - r[2]);
    let kept = region.clip(r[0], r[1], r[2] - floor);
    if !sliver.is_empty() {
        let c = tree.average();
        let wgt = filter.integral(&sliver, centre);
        out.colour += WeightedColour::from_colour(c, wgt);
        out.weight += wgt;
        // Unit-contrast bounds scale with an HDR tree's colour range.
        out.error_bound +=
            filter.largest_weight_in(sliver.bounds(), centre) * sliver.area() * query.bound_scale;
    }
    kept
}

/// A screen region's vertices mapped to texture space, and their box.
struct MappedVertices {
    lo: [f64; 2],
    hi: [f64; 2],
    /// The first `region.vertices().len()` are the region's, in order.
    points: [[f64; 2]; crate::geometry::polygon::MAX_VERTICES],
}

/// The region's texture-space box, with no polygon built; `None` when a
/// mapped vertex is not finite.
fn map_vertices(projection: &Projection, region: &ConvexPolygon) -> Option<MappedVertices> {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let mut finite = true;
    // Kept for the texture polygon, so no vertex is mapped twice.
    let mut mapped = [[0.0; 2]; crate::geometry::polygon::MAX_VERTICES];
    for (&s, m) in region.vertices().iter().zip(mapped.iter_mut()) {
        let t = apply(&projection.texture_from_screen, s);
        *m = t;
        finite &= t[0].is_finite() && t[1].is_finite();
        for a in 0..2 {
            crate::geometry::polygon::widen(&mut lo[a], &mut hi[a], t[a]);
        }
    }
    finite.then_some(MappedVertices {
        lo,
        hi,
        points: mapped,
    })
}

/// The integral over a region in front of the horizon (`out` holds what
/// its sliver gave): one uniform colour, a direct scan, or the walk.
fn integrate_in_front(
    query: &RegionQuery<'_>,
    visible: &VisibleRegion<'_>,
    mut out: RegionIntegral,
    stats: &mut FilterStats,
) -> RegionIntegral {
    let (tree, wrap, projection) = (query.tree, query.wrap, query.projection);
    let (filter, centre, options) = (query.filter, query.centre, query.options);
    let (region, (rlo, rhi), area) = (visible.screen, visible.bounds, visible.area);
    // The region's texture-space box first: most regions (a magnified
    // pixel) lie in one uniform square and need no more.
    let Some(MappedVertices { lo, hi, points }) = map_vertices(projection, region) else {
        return out;
    };
    let fixed = match options.level_of_detail() {
        LevelOfDetail::Fixed(k) => Some(k.min(tree.depth())),
        LevelOfDetail::ErrorBound(_) => None,
    };
    // A plain raster's cells are read directly (a shallow one's flat grid
    // comes first, below).
    let plain_raster = fixed.is_none() && tree.is_plain_raster();
    let raster = if plain_raster && tree.flat_grid().is_none() {
        raster_box(tree, wrap, lo, hi)
    } else {
        RasterBox::Other
    };
    let uniform = match raster {
        RasterBox::Uniform(c) => Some(c),
        RasterBox::Small(_) | RasterBox::Few(_) => None,
        RasterBox::Other => uniform_colour_in(tree, lo, hi, wrap),
    };
    // One colour under the whole region: that colour, exactly.
    if let Some(c) = uniform {
        let wgt = match filter {
            PixelFilter::Box => area,
            _ => filter.integral(region, centre),
        };
        out.colour += WeightedColour::from_colour(c, wgt);
        out.weight += wgt;
        return out;
    }
    if let RasterBox::Few(few) = &raster {
        let total = match filter {
            PixelFilter::Box => area,
            _ => filter.integral(region, centre),
        };
        if let Some(scanned) = few.integrate(
            region,
            &projection.texture_from_screen,
            filter,
            centre,
            total,
        ) {
            return with_scan(out, scanned, stats);
        }
    }
    // Vertices closer than a millionth of the region's extent on the
    // screen (left where a clip passes through a vertex, or two nearly
    // parallel lines cross) bound an edge whose direction rounding sets:
    // taken as a half-plane, its line cuts a sliver off the region, or all
    // of it (once, the whole region lost). Merged, the region and the
    // weight the walk finds change by at most the tolerance times its
    // perimeter ([`ConvexPolygon::without_close_vertices`]): a pixel's
    // region loses or gains under 1e-5 of the pixel (the terrain scene at
    // 960×540: no pixel's weight off by 1e-6).
    let tolerance = 1e-6 * ((rhi[0] - rlo[0]) + (rhi[1] - rlo[1]));
    let texture_region = if region.has_close_vertices(tolerance) {
        region
            .clone()
            .without_close_vertices(tolerance)
            .map_counter_clockwise(|s| apply(&projection.texture_from_screen, s))
    } else {
        // The same polygon (nothing merges): the vertices mapped above.
        ConvexPolygon::from_trusted(&points[..region.vertices().len()])
    };
    let epsilon = match options.level_of_detail() {
        LevelOfDetail::ErrorBound(e) => e,
        LevelOfDetail::Fixed(_) => 0.0,
    };
    if fixed.is_none()
        && let Some(scanned) = scan_flat_grid(query, (lo, hi), &texture_region)
    {
        return with_scan(out, scanned, stats);
    }
    let mut walk_scans = plain_raster;
    if let RasterBox::Small(small) = raster {
        match small.scan(
            tree,
            &texture_region,
            &projection.screen_from_texture,
            filter,
            centre,
        ) {
            Some(scanned) => return with_scan(out, scanned, stats),
            // The walk's own scan of the one tile would fail the same way.
            None => walk_scans = false,
        }
    }
    let plan = WalkPlan {
        texture_region,
        texture_box: (lo, hi),
        area,
        perimeter: region.perimeter(),
        fixed,
        epsilon,
        weight_scale: filter.weight_scale(region, area, centre),
        texel_scan: walk_scans,
    };
    finite_or_nothing(walk_region(query, plan, out, stats))
}

/// `out` (what the horizon's sliver gave) plus a scan's `(Σ colour·k, Σ
/// k, cells)`, the cells counted as nodes visited; nothing if a figure is
/// not finite ([`finite_or_nothing`]).
fn with_scan(
    mut out: RegionIntegral,
    (colour, weight, cells): ([f64; 4], f64, f64),
    stats: &mut FilterStats,
) -> RegionIntegral {
    for (a, c) in out.colour.0.iter_mut().zip(colour) {
        *a += c;
    }
    out.weight += weight;
    stats.traversal.nodes_visited += cells as u64;
    finite_or_nothing(out)
}

/// The integral if every figure is finite; nothing otherwise (a map that
/// overflows `f64` somewhere on the region: the caller falls back).
pub(super) fn finite_or_nothing(r: RegionIntegral) -> RegionIntegral {
    let finite = r.weight.is_finite()
        && r.error_bound.is_finite()
        && r.colour.0.iter().all(|v| v.is_finite());
    if finite { r } else { RegionIntegral::default() }
}

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
//! the screen area per texture area, `|k| ≤ k_max`, `|∇k| ≤ L_k`):
//! * a square inside `Q`: the error is a covariance of colour and weight,
//!   at most `½·Δc·a_S·(k_max·(ρ_max − ρ_min) + ρ_max·L_k·diam(S))`, with
//!   `ρ`'s extremes at the square's corners (`ρ ∝ w⁻³`, `w` affine);
//! * a square on `Q`'s boundary, taken whole over its clipped part `P`: at
//!   most `Δc · k_max · area(P⁻¹(P))`.
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
//! ([`crate::FilterOptions::budget`]). Over more than 16 repeated tiles a
//! refinement the budget cuts short with its bound above 5% of full
//! contrast is replaced by the coarse sum (every tile at the tile mean):
//! the partial one is biased by moiré, the coarse one keeps the
//! cancellation over many periods (`docs/algorithm.md` §8, measured there).
//!
//! **Wrap.** Repeat and mirror tiles are grouped in blocks of tiles; a block
//! inside `Q` has the tree's root mean, with the covariance bound above
//! summed over its tiles (`Δc·(k_max·(ρ_max−ρ_min)·(n_x+n_z) + …)`: it shrinks
//! as the block grows, so far, many-tile regions cost `O(log)` blocks). Clamp
//! stretches the outermost cells outwards, border shows the border colour.
//!
//! **Visibility.** The projection's denominator `w` must be positive over
//! the region (the surface in front of the camera). A region reaching the
//! horizon `w = 0` is clipped at a sliver of width `10⁻⁹` pixel beyond which
//! the texture's mean colour is taken (bounded, and reported).

use arrayvec::ArrayVec;

use crate::Error;
use crate::colour::{Rgba, WeightedColour};
use crate::filter::footprint::Footprint;
use crate::filter::options::{FilterOptions, FilterStats, LevelOfDetail, SQUARE_BUDGET};
use crate::filter::wrap::{Wrap, WrapMode};
use crate::filter::wrap::{fold_cell, uniform_colour_in};
use crate::geometry::polygon::{ConvexPolygon, Cubic, separable_integral};
use crate::tree::{FinestCell, NodeRef, QuadTree, StoredSquare, unit_side};

type Mat3 = [[f64; 3]; 3];

/// Largest screen coordinate a region may have (`2^50` pixels); beyond it
/// the integral is empty (the caller falls back to a point lookup).
pub const MAX_SCREEN_COORDINATE: f64 = (1u64 << 50) as f64;

/// Whole-tile blocks of more tiles than this are taken at the tile mean
/// whatever their bound (reported): descending into that many trees costs
/// more than it is worth.
const MAX_TILES_DESCENDED: f64 = 16.0;

/// Most grid cells [`scan_flat_grid`] clips for one region: about the
/// time the walk spends on its default budget of squares.
const SCAN_CELLS: f64 = 512.0;

/// Most cells of the grid at the tree's depth [`Walk::scan_texels`] takes
/// a region's part of a tile over, texel by texel, instead of walking it.
const TEXEL_SCAN_CELLS: f64 = 256.0;

/// [`Walk::scan_texels`] scans below a node at most this many levels above
/// the texel blocks: a region within 4 × 4 blocks (16 × 16 texels of
/// 4-texel blocks). Measured with 256 cells, `quadtex render` of the
/// terrain at 480×270: its texture integrals 6.02 → 3.68 G instructions.
/// Scanning below any node was faster still there, but the demo at
/// 960×540 took 4.46 G instructions against 4.31 G with this limit (its
/// runway's uniform squares taken cell by cell instead of whole).
const TEXEL_SCAN_LEVELS_ABOVE_BLOCKS: u8 = 2;

/// Most cells of the grid at the tree's depth [`raster_box`] and
/// [`SmallBox::scan`] take a region over, before any walk is set up
/// (measured for the scan that came before them, reading cells by the
/// traversals' node descent). Measured (callgrind, whole
/// `quadtex render` runs at 960×540, against no such scan): the terrain
/// 24.14 → 22.25, 22.06 and 22.05 G instructions with 4, 16 and 64 cells,
/// the demo 3.258 → 3.244, 3.244 and 3.225 G.
const SMALL_SCAN_CELLS: f64 = 64.0;

/// The walk starts below the root ([`Walk::start_node`]) only for error
/// bounds below this fraction of full contrast: above it, a square holding
/// the whole region might be taken whole.
const MAX_SKIPPED_EPSILON: f64 = 0.5;

/// How far (tree units) a region's bounds must keep from a square's middle
/// lines for [`Walk::start_node`] to place it in one half: many times the
/// rounding of a tile frame's edges (a few ulps of the tile index).
const START_MARGIN: f64 = 1e-9;

/// A refinement over more than [`MAX_TILES_DESCENDED`] tiles that the
/// budget stops with its bound above this fraction of full contrast is
/// replaced by the coarse sum (see `Walk::run`).
const UNCONTROLLED: f64 = 0.05;

/// A region over more than [`MAX_TILES_DESCENDED`] tiles whose perimeter
/// (in tiles) is more than this many times the budget of squares, and
/// whose coarse bound is its whole weight, takes the coarse sum without
/// refining (see `Walk::run`): a boundary that long crosses more tiles
/// than the budget can evaluate.
const BOUNDARY_TILES_PER_SQUARE: f64 = 2.0;

/// A projective map from the screen to texture space,
/// `texture_from_screen`: `t = (M·(s, 1))` divided by its third
/// coordinate `w`. The surface is in front of the camera where `w > 0`.
///
/// Invariant: finite, invertible (both directions are kept).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    texture_from_screen: Mat3,
    screen_from_texture: Mat3,
    /// `|∇w|` over the screen, for the horizon sliver's width (kept: a
    /// view's projection serves every pixel it covers).
    w_gradient: f64,
}

impl Projection {
    /// The map with matrix `texture_from_screen` (row-major, acting on
    /// `(x, y, 1)`); scaled by a positive factor for range, which changes
    /// nothing. [`Error::BadPolygon`] when it is not finite or singular.
    pub fn new(texture_from_screen: [[f64; 3]; 3]) -> Result<Projection, Error> {
        let scale = texture_from_screen
            .iter()
            .flatten()
            .fold(0f64, |m, v| m.max(v.abs()));
        if !(scale.is_finite() && scale > 0.0) {
            return Err(Error::BadPolygon(
                "projection matrix is not finite or is zero".into(),
            ));
        }
        let m = texture_from_screen.map(|row| row.map(|v| v / scale));
        let (adj, det) = adjugate(&m);
        if !(det.is_finite() && det.abs() > 1e-300) {
            return Err(Error::BadPolygon("projection matrix is singular".into()));
        }
        let inv_scale = adj.iter().flatten().fold(0f64, |a, v| a.max(v.abs()));
        // adj(M) = det·M⁻¹: any positive multiple represents the inverse map;
        // the sign is chosen so that w > 0 on the visible side both ways.
        let sign = det.signum();
        let inv = adj.map(|row| row.map(|v| sign * v / inv_scale));
        Ok(Projection {
            texture_from_screen: m,
            screen_from_texture: inv,
            w_gradient: m[2][0].hypot(m[2][1]),
        })
    }

    /// The identity (screen and texture coordinates coincide): filtering a
    /// texture-space region uniformly in texture space.
    pub fn identity() -> Projection {
        let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        Projection {
            texture_from_screen: id,
            screen_from_texture: id,
            w_gradient: 0.0,
        }
    }

    /// The map sending the screen square `[x, x+1] × [y, y+1]` (pixel
    /// `(x, y)` when `origin = [x, y]`) onto `footprint`, corner to corner in
    /// pixel order; `None` unless the footprint is a convex quad the square
    /// maps onto one-to-one ([`Footprint::homography`]).
    pub fn for_pixel(footprint: &Footprint, origin: [f64; 2]) -> Option<Projection> {
        let m = footprint.homography()?.matrix();
        // M·T with T translating (x, y) to (u, v) = (x − origin.x, y − origin.y).
        let t = [
            [1.0, 0.0, -origin[0]],
            [0.0, 1.0, -origin[1]],
            [0.0, 0.0, 1.0],
        ];
        Projection::new(mul(&m, &t)).ok()
    }

    /// The matrix taking screen points to texture points.
    pub fn texture_from_screen(&self) -> [[f64; 3]; 3] {
        self.texture_from_screen
    }

    /// The denominator `w` at screen point `s` (positive where the surface
    /// is in front of the camera).
    pub fn w(&self, s: [f64; 2]) -> f64 {
        let r = &self.texture_from_screen[2];
        r[0] * s[0] + r[1] * s[1] + r[2]
    }

    /// The texture point seen at screen point `s`, if `w > 0` there.
    pub fn texture_point(&self, s: [f64; 2]) -> Option<[f64; 2]> {
        (self.w(s) > 0.0).then(|| apply(&self.texture_from_screen, s))
    }

    /// The screen point where texture point `t` is seen.
    pub fn screen_point(&self, t: [f64; 2]) -> [f64; 2] {
        apply(&self.screen_from_texture, t)
    }
}

/// A pixel reconstruction filter, separable, `k(dx, dy) = k₁(dx)·k₁(dy)`
/// with `(dx, dy)` in pixels from the pixel's centre; each integrates to 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum PixelFilter {
    /// 1 on the pixel square `[−½, ½]²`.
    #[default]
    Box,
    /// `k₁(x) = 1 − |x|` on `[−1, 1]`: bilinear on each of 4 unit cells.
    Tent,
    /// Mitchell–Netravali with `B = C = ⅓` on `[−2, 2]`: bicubic on each of
    /// 16 unit cells, negative lobes (results may leave `[0, 1]`).
    Mitchell,
}

impl PixelFilter {
    /// Half the side of the support, in pixels.
    #[inline]
    pub fn radius(self) -> f64 {
        match self {
            PixelFilter::Box => 0.5,
            PixelFilter::Tent => 1.0,
            PixelFilter::Mitchell => 2.0,
        }
    }

    /// The name as the CLI spells it.
    pub fn name(self) -> &'static str {
        match self {
            PixelFilter::Box => "box",
            PixelFilter::Tent => "tent",
            PixelFilter::Mitchell => "mitchell",
        }
    }

    /// `k(dx, dy)`.
    pub fn weight(self, dx: f64, dy: f64) -> f64 {
        self.k1(dx) * self.k1(dy)
    }

    /// `k₁(x)`.
    pub fn k1(self, x: f64) -> f64 {
        if x.abs() >= self.radius() {
            return if self == PixelFilter::Box && x.abs() == 0.5 {
                1.0
            } else {
                0.0
            };
        }
        let c = self.cubic(x.floor() as i32);
        c[0] + x * (c[1] + x * (c[2] + x * c[3]))
    }

    /// The filter's support around `centre`.
    #[inline]
    pub fn support(self, centre: [f64; 2]) -> ConvexPolygon {
        let r = self.radius();
        ConvexPolygon::rect(centre[0] - r, centre[1] - r, centre[0] + r, centre[1] + r)
    }

    /// Largest `|k|`.
    fn k_max(self) -> f64 {
        match self {
            PixelFilter::Box | PixelFilter::Tent => 1.0,
            PixelFilter::Mitchell => (8.0 / 9.0) * (8.0 / 9.0),
        }
    }

    /// A bound on `|∇k|` (0 for the box, constant on its support).
    fn lipschitz(self) -> f64 {
        match self {
            PixelFilter::Box => 0.0,
            PixelFilter::Tent => std::f64::consts::SQRT_2,
            // max|k₁'| = 8/7 (at x = 4/7) times max|k₁| = 8/9, per axis.
            PixelFilter::Mitchell => std::f64::consts::SQRT_2 * (8.0 / 7.0) * (8.0 / 9.0),
        }
    }

    /// `k₁` on the unit cell `[i, i+1)` as a cubic in `x`.
    fn cubic(self, i: i32) -> Cubic {
        const S: f64 = 1.0 / 6.0;
        match (self, i) {
            (PixelFilter::Box, _) => [1.0, 0.0, 0.0, 0.0],
            (PixelFilter::Tent, -1) => [1.0, 1.0, 0.0, 0.0],
            (PixelFilter::Tent, 0) => [1.0, -1.0, 0.0, 0.0],
            // (7|x|³ − 12x² + 16/3)/6 and (−7/3|x|³ + 12x² − 20|x| + 32/3)/6.
            (PixelFilter::Mitchell, 0) => [16.0 / 3.0 * S, 0.0, -12.0 * S, 7.0 * S],
            (PixelFilter::Mitchell, -1) => [16.0 / 3.0 * S, 0.0, -12.0 * S, -7.0 * S],
            (PixelFilter::Mitchell, 1) => [32.0 / 3.0 * S, -20.0 * S, 12.0 * S, -7.0 / 3.0 * S],
            (PixelFilter::Mitchell, -2) => [32.0 / 3.0 * S, 20.0 * S, 12.0 * S, 7.0 / 3.0 * S],
            _ => [0.0; 4],
        }
    }

    /// `∫∫ k(s − centre) ds` over screen polygon `p` (either orientation),
    /// exactly (Green's theorem on each unit cell of the filter).
    pub fn integral(self, p: &ConvexPolygon, centre: [f64; 2]) -> f64 {
        if self == PixelFilter::Box {
            return p.area();
        }
        let sign = p.signed_area().signum();
        let rel = p.map(|s| [s[0] - centre[0], s[1] - centre[1]]);
        let r = self.radius();
        let (lo, hi) = rel.bounds();
        let (i0, i1) = (lo[0].max(-r).floor() as i32, hi[0].min(r).ceil() as i32);
        let (j0, j1) = (lo[1].max(-r).floor() as i32, hi[1].min(r).ceil() as i32);
        let mut total = 0.0;
        for j in j0..j1 {
            for i in i0..i1 {
                let (x, y) = (f64::from(i), f64::from(j));
                let cell = rel.clip_rect(x, y, x + 1.0, y + 1.0);
                if !cell.is_empty() {
                    total += separable_integral(cell.vertices(), &self.cubic(i), &self.cubic(j));
                }
            }
        }
        sign * total
    }
}

/// What [`crate::Texture::integrate_region`] returns.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RegionIntegral {
    /// `∫ colour · k` over the region (linear, premultiplied; units of
    /// colour × screen area).
    pub colour: WeightedColour,
    /// `∫ k` over the region.
    pub weight: f64,
    /// A bound on `|colour − exact|` per channel, in the same units: what
    /// taking squares at their mean cost (module documentation).
    pub error_bound: f64,
}

impl RegionIntegral {
    /// Adds another region's integral.
    pub fn add(&mut self, other: &RegionIntegral) {
        self.colour += other.colour;
        self.weight += other.weight;
        self.error_bound += other.error_bound;
    }

    /// `colour / weight`, `None` when the weight is zero.
    pub fn mean(&self) -> Option<Rgba> {
        // Not `mean_over`: a Mitchell lobe's weight may be negative.
        (self.weight != 0.0 && self.weight.is_finite()).then(|| {
            let s = 1.0 / self.weight;
            let c = self.colour.0;
            Rgba::new(
                (c[0] * s) as f32,
                (c[1] * s) as f32,
                (c[2] * s) as f32,
                (c[3] * s) as f32,
            )
        })
    }
}

/// The least `w` a vertex of `region` may have for [`integrate_region`]
/// to take the region as it is: nearer the horizon it cuts off the sliver
/// of `w` below this, whose width is an eighth of the error budget over the
/// region's diameter (`1e-9` pixel under a fixed level). `region`'s
/// coordinates are within [`MAX_SCREEN_COORDINATE`] (the squares cannot
/// overflow).
fn horizon_floor(projection: &Projection, region: &ConvexPolygon, options: &FilterOptions) -> f64 {
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

/// The integral (module documentation) over screen region `region` under
/// `projection`, with `filter` centred at `centre`. The region is first
/// clipped to the filter's support.
#[allow(clippy::too_many_arguments)]
pub(crate) fn integrate_region(
    tree: &QuadTree,
    wrap: Wrap,
    projection: &Projection,
    region: &ConvexPolygon,
    filter: PixelFilter,
    centre: [f64; 2],
    options: &FilterOptions,
    stats: &mut FilterStats,
) -> RegionIntegral {
    stats.footprints += 1;
    stats.fragments += 1;
    stats.traversal.queries += 1;
    let mut out = RegionIntegral::default();
    // Borrowed when the box filter takes it as it is; `clipped` and `kept`
    // own what clipping makes of it (a polygon is a few hundred bytes, and
    // this runs once per pixel).
    let (clipped, kept);
    let mut region = match filter {
        PixelFilter::Box => region,
        _ => {
            clipped = region.intersect(&filter.support(centre));
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
    let r = projection.texture_from_screen[2];
    let w_min = horizon_floor_of(projection, (rlo, rhi), area, options);
    if region
        .vertices()
        .iter()
        .any(|&s| projection.w(s) < w_min.max(f64::MIN_POSITIVE))
    {
        let floor = w_min.max(f64::MIN_POSITIVE);
        // Between the horizon (w = 0) and w = floor; beyond the horizon the
        // surface is not seen at all.
        let sliver = region
            .clip(r[0], r[1], r[2])
            .clip(-r[0], -r[1], floor - r[2]);
        kept = region.clip(r[0], r[1], r[2] - floor);
        region = &kept;
        (rlo, rhi) = region.bounds();
        area = region.area();
        if !sliver.is_empty() {
            let c = tree.average();
            let wgt = filter.integral(&sliver, centre);
            out.colour += WeightedColour::from_colour(c, wgt);
            out.weight += wgt;
            // Unit-contrast bounds scale with an HDR tree's colour range.
            out.error_bound += filter.k_max() * sliver.area() * tree.bound_scale();
        }
        if region.is_empty() {
            return out;
        }
    }
    if !(area > 0.0 && area.is_finite()) {
        return out;
    }
    // The region's texture-space box first, with no polygon built: most
    // regions (a magnified pixel) lie in one uniform square and need no
    // more.
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let mut finite = true;
    // Kept for the texture polygon below, so no vertex is mapped twice.
    let mut mapped = [[0.0; 2]; crate::geometry::polygon::MAX_VERTICES];
    for (&s, m) in region.vertices().iter().zip(mapped.iter_mut()) {
        let t = apply(&projection.texture_from_screen, s);
        *m = t;
        finite &= t[0].is_finite() && t[1].is_finite();
        for a in 0..2 {
            crate::geometry::polygon::widen(&mut lo[a], &mut hi[a], t[a]);
        }
    }
    if !finite {
        return out;
    }
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
        ConvexPolygon::from_trusted(&mapped[..region.vertices().len()])
    };
    let epsilon = match options.level_of_detail() {
        LevelOfDetail::ErrorBound(e) => e,
        LevelOfDetail::Fixed(_) => 0.0,
    };
    if fixed.is_none()
        && let Some(scanned) = scan_flat_grid(
            tree,
            wrap,
            (lo, hi),
            &texture_region,
            &projection.screen_from_texture,
            filter,
            centre,
        )
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
    let buffers = WalkBuffers::lend();
    let mut walk = Walk {
        frames: buffers.frames,
        pending: buffers.pending,
        queue: buffers.queue,
        queued_bound: 0.0,
        target: epsilon * filter.k_max() * area,
        area,
        budget: options.budget(),
        tree,
        wrap,
        filter,
        centre,
        screen_from_texture: projection.screen_from_texture,
        screen_det: adjugate(&projection.screen_from_texture).1.abs(),
        edges: edges_of(&texture_region),
        region: texture_region,
        fixed,
        boundary_coef: 0.5 * epsilon * area / region.perimeter().max(f64::MIN_POSITIVE),
        k_max: filter.k_max(),
        lipschitz: filter.lipschitz(),
        out,
        visited: 0,
        texel_scan: walk_scans,
        edge_means: [None; 4],
    };
    let before = walk.out.error_bound;
    walk.run(lo, hi);
    stats.traversal.nodes_visited += walk.visited;
    // The walk's bounds assume colour channels in [0, 1]; HDR colours span more.
    walk.out.error_bound = before + (walk.out.error_bound - before) * tree.bound_scale();
    let out = walk.out;
    WalkBuffers {
        frames: walk.frames,
        pending: walk.pending,
        queue: walk.queue,
    }
    .give_back();
    finite_or_nothing(out)
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

/// The growable parts of a [`Walk`], kept per thread between regions so
/// that a walk allocates nothing once they have grown (a pixel's regions
/// are many and small).
#[derive(Default)]
struct WalkBuffers {
    frames: Vec<TileFrame>,
    pending: Vec<Pending>,
    queue: std::collections::BinaryHeap<(u64, u32)>,
}

thread_local! {
    static WALK_BUFFERS: std::cell::RefCell<WalkBuffers> =
        std::cell::RefCell::new(WalkBuffers::default());
}

impl WalkBuffers {
    /// Parts longer than this are dropped rather than kept (a walk under a
    /// fixed level may hold [`FIXED_LEVEL_CAP`] of them).
    const KEEP: usize = 1 << 12;

    /// This thread's buffers, empty (new ones if they are lent already).
    fn lend() -> WalkBuffers {
        WALK_BUFFERS
            .try_with(|b| b.try_borrow_mut().map(|mut b| std::mem::take(&mut *b)))
            .ok()
            .and_then(Result::ok)
            .unwrap_or_default()
    }

    /// Returns the buffers, emptied, for the thread's next walk.
    fn give_back(mut self) {
        if self.frames.capacity() > Self::KEEP
            || self.pending.capacity() > Self::KEEP
            || self.queue.capacity() > Self::KEEP
        {
            return;
        }
        self.frames.clear();
        self.pending.clear();
        self.queue.clear();
        let _ = WALK_BUFFERS.try_with(|b| {
            if let Ok(mut b) = b.try_borrow_mut() {
                *b = self;
            }
        });
    }
}

/// The integral if every figure is finite; nothing otherwise (a map that
/// overflows `f64` somewhere on the region: the caller falls back).
fn finite_or_nothing(r: RegionIntegral) -> RegionIntegral {
    let finite = r.weight.is_finite()
        && r.error_bound.is_finite()
        && r.colour.0.iter().all(|v| v.is_finite());
    if finite { r } else { RegionIntegral::default() }
}

/// An edge line `n·p + c ≥ 0` (inside).
type Line = [f64; 3];

/// The region's edges, plus one that keeps a non-square texture's tile off
/// the tree's pad ([`crate::Aspect`]).
const MAX_EDGES: usize = crate::geometry::polygon::MAX_VERTICES + 1;

fn edges_of(p: &ConvexPolygon) -> ([Line; MAX_EDGES], usize) {
    let mut lines = [[0.0; 3]; MAX_EDGES];
    let mut n = 0;
    for (slot, line) in lines.iter_mut().zip(p.edge_lines()) {
        *slot = line;
        n += 1;
    }
    (lines, n)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Class {
    Outside,
    Inside,
    /// Crossed by the edges in the bit mask.
    Boundary(u32),
}

/// Where the rectangle `[x0, x1] × [z0, z1]` lies against the polygon with
/// `edges`.
#[inline]
fn classify(edges: &([Line; MAX_EDGES], usize), x0: f64, z0: f64, x1: f64, z1: f64) -> Class {
    let mut crossing = 0u32;
    for (i, e) in edges.0[..edges.1].iter().enumerate() {
        let base = e[2];
        let (ax0, ax1) = (e[0] * x0, e[0] * x1);
        let (bz0, bz1) = (e[1] * z0, e[1] * z1);
        let min = ax0.min(ax1) + bz0.min(bz1) + base;
        if min >= 0.0 {
            continue;
        }
        let max = ax0.max(ax1) + bz0.max(bz1) + base;
        if max <= 0.0 {
            return Class::Outside;
        }
        crossing |= 1 << i;
    }
    if crossing == 0 {
        Class::Inside
    } else {
        Class::Boundary(crossing)
    }
}

/// One axis of texture space, cut where the wrap changes what it shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Segment {
    /// Tiles `i0..=i1` (the unit tile alone, `0..=0`, for clamp and border).
    Tiles(i64, i64),
    /// Beyond the low edge (clamp, border).
    Low,
    /// Beyond the high edge.
    High,
}

fn segments(mode: WrapMode, lo: f64, hi: f64) -> [Option<Segment>; 3] {
    match mode {
        WrapMode::Repeat | WrapMode::Mirror => {
            let (a, b) = (lo.floor(), hi.floor());
            // Far beyond i64: the region is absurdly far out; treat as none.
            if !(a.abs() < 9.0e15 && b.abs() < 9.0e15) {
                return [None; 3];
            }
            let b = if b > a && b == hi { b - 1.0 } else { b };
            [Some(Segment::Tiles(a as i64, b as i64)), None, None]
        }
        WrapMode::Clamp | WrapMode::Border => [
            (lo < 0.0).then_some(Segment::Low),
            (lo < 1.0 && hi > 0.0).then_some(Segment::Tiles(0, 0)),
            (hi > 1.0).then_some(Segment::High),
        ],
    }
}

/// How many tiles an axis's [`segments`] cross when they are one run of
/// tiles (no part outside a clamped or bordered edge); `None` otherwise.
fn one_run_of_tiles(s: &[Option<Segment>; 3]) -> Option<f64> {
    match s {
        [Some(Segment::Tiles(a, b)), None, _] => Some((b - a + 1) as f64),
        _ => None,
    }
}

/// How tile `i` of an axis maps to the tree: texture = `sign·local + offset`.
#[inline]
fn tile_map(mode: WrapMode, i: i64) -> (f64, f64) {
    match mode {
        WrapMode::Mirror if i.rem_euclid(2) == 1 => (-1.0, (i + 1) as f64),
        _ => (1.0, i as f64),
    }
}

/// A tile's view of the region: the region and its edges in the tile's
/// local coordinates, and the map from local coordinates to the screen.
struct TileFrame {
    edges: ([Line; MAX_EDGES], usize),
    to_screen: Mat3,
    det: f64,
}

/// Most squares a region evaluates under a fixed level
/// ([`LevelOfDetail::Fixed`]) before it stops refining and reports its
/// bound: about 80 MiB of pending parts at most.
pub const FIXED_LEVEL_CAP: u64 = 1 << 20;

/// The default budget of squares ([`crate::FilterOptions::budget`]).
pub const DEFAULT_SQUARE_BUDGET: u64 = SQUARE_BUDGET;

/// What taking a square or block whole adds: `Σ colour·k`, `Σ k`, bound.
#[derive(Debug, Clone, Copy)]
struct Contribution {
    colour: [f64; 4],
    weight: f64,
    bound: f64,
}

/// A part of the texture plane the walk may refine.
#[derive(Debug, Clone, Copy)]
enum Item {
    /// Whole tiles `[i0, i1] × [j0, j1]`.
    Block { i0: i64, i1: i64, j0: i64, j1: i64 },
    /// Tree node `node` at `(level, ix, iz)` of tile frame `frame`.
    Node {
        frame: u32,
        node: NodeRef,
        level: u8,
        ix: u32,
        iz: u32,
    },
}

#[derive(Debug, Clone, Copy)]
struct Pending {
    item: Item,
    taken: Contribution,
}

enum Outcome {
    Outside,
    Final(Contribution),
    /// What taking it whole adds, and the item to refine it from.
    Refinable(Contribution, Item),
}

struct Walk<'a> {
    frames: Vec<TileFrame>,
    pending: Vec<Pending>,
    /// `(bound bits, index into pending)`: positive floats order as their bits.
    queue: std::collections::BinaryHeap<(u64, u32)>,
    queued_bound: f64,
    target: f64,
    /// The region's screen area.
    area: f64,
    budget: u64,
    tree: &'a QuadTree,
    wrap: Wrap,
    filter: PixelFilter,
    centre: [f64; 2],
    screen_from_texture: Mat3,
    /// `|det|` of `screen_from_texture`, for the density `|det| / w³`.
    screen_det: f64,
    region: ConvexPolygon,
    edges: ([Line; MAX_EDGES], usize),
    fixed: Option<u8>,
    boundary_coef: f64,
    k_max: f64,
    lipschitz: f64,
    out: RegionIntegral,
    visited: u64,
    /// Whether [`Walk::scan_texels`] may take tiles texel by texel: a
    /// square tree with texel blocks and no gradient or contour leaves
    /// (every terminal square uniform), walked to an error bound (a fixed
    /// level asks for that level's approximation).
    texel_scan: bool,
    /// Mean colour along each edge (x low, x high, z low, z high), for
    /// clamp stripes over many tiles, computed when first needed.
    edge_means: [Option<[f64; 4]>; 4],
}

impl Walk<'_> {
    fn run(&mut self, lo: [f64; 2], hi: [f64; 2]) {
        let xs = segments(self.wrap.x, lo[0], hi[0]);
        let zs = segments(self.wrap.z, lo[1], hi[1]);
        for zs in zs.into_iter().flatten() {
            for xs in xs.into_iter().flatten() {
                match (xs, zs) {
                    (Segment::Tiles(i0, i1), Segment::Tiles(j0, j1)) => {
                        self.offer(Item::Block { i0, i1, j0, j1 })
                    }
                    _ => self.outside(xs, zs),
                }
            }
        }
        // Over many periods of a repeated texture, a refinement the budget
        // cuts short far from its bound is biased: the parts refined first
        // (the largest, the nearest) follow the slow drift of a moiré
        // between the region's edges and the tiles, and the rest, at the
        // tile mean, does not cancel it. The coarse sum (every tile at the
        // tile mean) keeps that cancellation, so it is returned instead,
        // with its own (larger, still rigorous) bound. Measured on the
        // checker scene at 960×540, RMSE against the closed form:
        // 2.2e-3 → 6.1e-4 at the default budget.
        // The coarse sum is what was offered before refining: `out` then,
        // plus the first `offered` pending parts (pending only grows).
        // A region whose coarse sum controls none of its weight (the bound
        // of what was offered is the whole weight) and whose boundary
        // crosses more tiles than the budget has squares is not refined:
        // its boundary blocks keep their bounds until each tile along it
        // is evaluated, which the budget cannot pay for, so the refinement
        // would end cut short and the coarse sum be taken anyway. Measured
        // at 960 wide: every region of more than 16 tiles the demo (2880),
        // the runway scene (2924) and the checker scene (1922) refined went
        // to the coarse sum, each with its whole weight as the coarse bound
        // and a perimeter of 243 tiles or more; images byte-identical (those
        // and the sign and close-up scenes, 960 and 1920 wide, box, tent
        // and Mitchell), the demo's frame at 960 wide 2.82 → 2.34 G
        // instructions.
        let n_tiles = one_run_of_tiles(&xs).unwrap_or(1.0) * one_run_of_tiles(&zs).unwrap_or(1.0);
        let (before, offered) = (self.out, self.pending.len());
        let unresolvable = self.fixed.is_none()
            && n_tiles > MAX_TILES_DESCENDED
            && self.region.perimeter() > BOUNDARY_TILES_PER_SQUARE * self.budget as f64
            && before.error_bound + self.queued_bound >= self.k_max * self.area;
        let cut_short = !unresolvable && self.refine();
        if unresolvable
            || n_tiles > MAX_TILES_DESCENDED
                && cut_short
                && self.fixed.is_none()
                && self.out.error_bound > UNCONTROLLED * self.k_max * self.area
        {
            let mut coarse = before;
            for p in &self.pending[..offered] {
                coarse.add(&RegionIntegral {
                    colour: WeightedColour(p.taken.colour),
                    weight: p.taken.weight,
                    error_bound: p.taken.bound,
                });
            }
            self.out = coarse;
        }
    }

    /// Tile `(i, j)`'s part of the region, exactly, texel by texel: when
    /// `start`, the node the walk would start from ([`Walk::start_node`]),
    /// lies at most [`TEXEL_SCAN_LEVELS_ABOVE_BLOCKS`] levels above the
    /// texel blocks, and the region's part of it spans at most
    /// [`TEXEL_SCAN_CELLS`] cells of the grid at the tree's depth, all
    /// under uniform squares (texels or stored terminal squares). `None`
    /// (nothing added) otherwise.
    ///
    /// A region of a pixel or less over a raster (a mesh's triangle, a
    /// magnified or mildly minified photograph) spans a few texels; the
    /// walk refines it square by square down to them, each square clipped,
    /// bounded and queued, where here each texel costs one cut of its band.
    fn scan_texels(
        &mut self,
        frame: usize,
        (i, j): (i64, i64),
        (node, level, ix, iz): (NodeRef, u8, u32, u32),
    ) -> Option<Contribution> {
        if !self.texel_scan {
            return None;
        }
        // Only among texel blocks: above them the tree keeps uniform
        // squares the walk takes whole, where a scan would take each cell.
        let blocks = self.tree.texel_blocks()?;
        if level + TEXEL_SCAN_LEVELS_ABOVE_BLOCKS < blocks.level() {
            return None;
        }
        // Local (tree) coordinates of a square tree: texture = sign·local
        // + offset ([`Walk::tile_frame`]), sign ±1.
        let (sx, ox) = tile_map(self.wrap.x, i);
        let (sz, oz) = tile_map(self.wrap.z, j);
        let side = unit_side(level);
        let (x0, z0) = (f64::from(ix) * side, f64::from(iz) * side);
        let mut local = self
            .region
            .map_counter_clockwise(|[x, z]| [(x - ox) * sx, (z - oz) * sz]);
        let (lo, hi) = local.bounds();
        if lo[0] < x0 || lo[1] < z0 || hi[0] > x0 + side || hi[1] > z0 + side {
            local = local.clip_rect(x0, z0, x0 + side, z0 + side);
        }
        let (lo, hi) = local.bounds();
        let h = unit_side(self.tree.depth());
        let span = |a: f64, b: f64| (b / h).ceil() - (a / h).floor();
        if local.is_empty() || span(lo[0], hi[0]) * span(lo[1], hi[1]) > TEXEL_SCAN_CELLS {
            return None;
        }
        let colour = finest_colour_below(self.tree, (node, level, ix, iz));
        let (colour, weight, cells) = scan_grid(
            &local,
            &self.frames[frame].to_screen,
            h,
            self.filter,
            self.centre,
            TEXEL_SCAN_CELLS,
            colour,
        )?;
        self.visited += cells as u64;
        Some(Contribution {
            colour,
            weight,
            bound: 0.0,
        })
    }

    /// Adds `colour` over the screen polygon `piece`; `approximate` pieces
    /// (a non-terminal square taken whole over part of it) add their bound.
    #[inline]
    fn add(&mut self, colour: [f64; 4], piece: &ConvexPolygon, approximate: bool) {
        let w = self.filter.integral(piece, self.centre);
        for (a, c) in self.out.colour.0.iter_mut().zip(colour) {
            *a += c * w;
        }
        self.out.weight += w;
        if approximate {
            self.out.error_bound += self.k_max * piece.area();
        }
    }

    fn to_screen_poly(&self, p: &ConvexPolygon, m: &Mat3) -> ConvexPolygon {
        p.map(|t| apply(m, t))
    }

    /// Offers `item`: a part taken exactly is added now, one that could be
    /// refined waits in the queue with what taking it whole contributes.
    fn offer(&mut self, item: Item) {
        match self.evaluate(item) {
            Outcome::Outside => {}
            Outcome::Final(c) => self.add_contribution(&c),
            Outcome::Refinable(c, item) => {
                self.queued_bound += c.bound;
                let index = self.pending.len() as u32;
                self.pending.push(Pending { item, taken: c });
                self.queue.push((c.bound.to_bits(), index));
            }
        }
    }

    /// True once the region has evaluated its budget of squares (under a
    /// fixed level: the hard cap).
    fn over_budget(&self) -> bool {
        self.visited
            >= match self.fixed {
                None => self.budget,
                Some(_) => FIXED_LEVEL_CAP,
            }
    }

    fn add_contribution(&mut self, c: &Contribution) {
        for (a, v) in self.out.colour.0.iter_mut().zip(c.colour) {
            *a += v;
        }
        self.out.weight += c.weight;
        self.out.error_bound += c.bound;
    }

    /// Refines the queued part with the largest bound first, until the
    /// bound is met or the budget spent (under a fixed level: until nothing
    /// above that level is left), then takes what is left whole.
    /// True when the budget (or the cap) stopped it short of the bound.
    fn refine(&mut self) -> bool {
        let mut cut_short = false;
        while let Some(&(_, index)) = self.queue.peek() {
            let done = match self.fixed {
                None => {
                    let met = self.queued_bound + self.out.error_bound <= self.target;
                    cut_short = !met && self.visited >= self.budget;
                    met || cut_short
                }
                // A fixed level over a region reaching the horizon (or a
                // million tiles) would never finish: stop at a hard cap and
                // report the bound reached.
                Some(_) => self.visited >= FIXED_LEVEL_CAP,
            };
            if done {
                break;
            }
            self.queue.pop();
            let Pending { item, taken } = self.pending[index as usize];
            self.queued_bound -= taken.bound;
            match item {
                Item::Block { i0, i1, j0, j1 } => {
                    let (mi, mj) = (i0 + (i1 - i0) / 2, j0 + (j1 - j0) / 2);
                    let xs: &[(i64, i64)] = if i1 > i0 {
                        &[(i0, mi), (mi + 1, i1)]
                    } else {
                        &[(i0, i1)]
                    };
                    let zs: &[(i64, i64)] = if j1 > j0 {
                        &[(j0, mj), (mj + 1, j1)]
                    } else {
                        &[(j0, j1)]
                    };
                    for &(a, b) in zs {
                        for &(c, d) in xs {
                            self.offer(Item::Block {
                                i0: c,
                                i1: d,
                                j0: a,
                                j1: b,
                            });
                        }
                    }
                }
                Item::Node {
                    frame,
                    node,
                    level,
                    ix,
                    iz,
                } => {
                    for c in 0..4u32 {
                        self.offer(Item::Node {
                            frame,
                            node: self.tree.child_ref(node, c as usize),
                            level: level + 1,
                            ix: 2 * ix + (c & 1),
                            iz: 2 * iz + (c >> 1),
                        });
                    }
                }
            }
        }
        while let Some((_, index)) = self.queue.pop() {
            let taken = self.pending[index as usize].taken;
            self.add_contribution(&taken);
        }
        cut_short
    }

    fn contribution(&self, colour: [f64; 4], piece: &ConvexPolygon, bound: f64) -> Contribution {
        let weight = self.filter.integral(piece, self.centre);
        Contribution {
            colour: colour.map(|c| c * weight),
            weight,
            bound,
        }
    }

    fn evaluate(&mut self, item: Item) -> Outcome {
        match item {
            Item::Block { i0, i1, j0, j1 } => self.evaluate_block(i0, i1, j0, j1),
            Item::Node {
                frame,
                node,
                level,
                ix,
                iz,
            } => self.evaluate_node(frame as usize, node, level, ix, iz),
        }
    }

    /// Tiles `[i0, i1] × [j0, j1]` (both axes tiled).
    fn evaluate_block(&mut self, i0: i64, i1: i64, j0: i64, j1: i64) -> Outcome {
        let (x0, x1) = (i0 as f64, (i1 + 1) as f64);
        let (z0, z1) = (j0 as f64, (j1 + 1) as f64);
        let class = classify(&self.edges, x0, z0, x1, z1);
        if class == Class::Outside {
            return Outcome::Outside;
        }
        if i0 == i1 && j0 == j1 {
            let frame = self.tile_frame(i0, j0);
            let start = self.start_node(i0, j0);
            if let Some(c) = self.scan_texels(frame, (i0, j0), start) {
                return Outcome::Final(c);
            }
            let (node, level, ix, iz) = start;
            return self.evaluate_node(frame, node, level, ix, iz);
        }
        self.visited += 1;
        let m = self.screen_from_texture;
        let corners = [[x0, z0], [x1, z0], [x1, z1], [x0, z1]];
        let quad = ConvexPolygon::from_trusted(&corners.map(|t| apply(&m, t)));
        let root = self.tree.mean_colour();
        let root_terminal = !self.tree.node_info(QuadTree::ROOT).0;
        let (nx, nz) = ((i1 - i0 + 1) as f64, (j1 - j0 + 1) as f64);
        match class {
            Class::Inside => {
                if root_terminal {
                    return Outcome::Final(self.contribution(root, &quad, 0.0));
                }
                let (linear, curved) = self.block_bound(&corners, nx, nz);
                let (rmin, rmax) = density_range_det(&m, self.screen_det, &corners);
                let tile = tile_diameter(&corners.map(|t| apply(&m, t)), nx, nz, rmin, rmax);
                let bound = (self.k_max * (linear + curved)
                    + 0.5 * self.lipschitz * tile * quad.area())
                .min(self.k_max * quad.area());
                let c = self.contribution(root, &quad, bound);
                // In the linear regime, splitting a block does not shrink its
                // bound (module documentation); only descending into tiles
                // does, worth it for a few tiles, not for many.
                if self.fixed.is_none() && nx * nz > MAX_TILES_DESCENDED && curved <= linear {
                    Outcome::Final(c)
                } else {
                    Outcome::Refinable(c, Item::Block { i0, i1, j0, j1 })
                }
            }
            _ => {
                // Cut by the region's boundary: whole tiles keep the tile
                // mean (up to the covariance above); only the tiles the cut
                // crosses differ, a band one tile wide along it.
                let piece_tex = self.region.clip_rect(x0, z0, x1, z1);
                let piece = self.to_screen_poly(&piece_tex, &m);
                if root_terminal {
                    return Outcome::Final(self.contribution(root, &piece, 0.0));
                }
                let (rmin, rmax) = density_range_det(&m, self.screen_det, &corners);
                let tile = tile_diameter(&corners.map(|t| apply(&m, t)), nx, nz, rmin, rmax);
                // The tiles' screen sizes come from the block's corners: only
                // when all of them are in front of the camera. A block
                // reaching past the horizon (the region's part of it can
                // still be small) gets the whole weight as its bound.
                let in_front = corners
                    .iter()
                    .all(|t| m[2][0] * t[0] + m[2][1] * t[1] + m[2][2] > 0.0);
                let band = if in_front {
                    cut_length(&piece_tex, [x0, z0, x1, z1], &m) * tile
                } else {
                    f64::INFINITY
                };
                let (linear, curved) = self.block_bound(&corners, nx, nz);
                let bound = self.k_max * (band + linear + curved).min(piece.area());
                Outcome::Refinable(
                    self.contribution(root, &piece, bound),
                    Item::Block { i0, i1, j0, j1 },
                )
            }
        }
    }

    /// A bound on `|Σ_tiles Σ_leaves (c − c̄)(∫ρ − a·ρ̄)|` over a block of
    /// `nx × nz` whole tiles with texture-space `corners`: expanding `ρ` to
    /// first order about each tile's centre, the first-order terms are the
    /// tile's first moments `m` dotted with `Σ ∇ρ(centres)`, which telescopes
    /// along rows and columns to the density's range `D` across the block;
    /// the remainder is bounded by the Hessian `|∂²ρ| ≤ 12ρ|∇w|²/w²`.
    /// Returned as the first-order part and the remainder.
    fn block_bound(&self, corners: &[[f64; 2]; 4], nx: f64, nz: f64) -> (f64, f64) {
        let (m, det) = (&self.screen_from_texture, self.screen_det);
        let w_min = corners
            .iter()
            .map(|t| (m[2][0] * t[0] + m[2][1] * t[1] + m[2][2]).abs())
            .fold(f64::INFINITY, f64::min);
        let (rmin, rmax) = density_range_det(m, det, corners);
        let d = rmax - rmin;
        let g2 = m[2][0] * m[2][0] + m[2][1] * m[2][1];
        let hessian = 12.0 * rmax * g2 / (w_min * w_min);
        let [mx, mz] = self.tree.first_moments();
        // Per tile: the colour's spread times the remainder over a unit
        // tile (|δ|² ≤ ½), plus the moments times the Hessian for the error
        // of the telescoped sum of gradients.
        (
            (mx * nz + mz * nx) * d,
            (mx * nz + mz * nx) * hessian + nx * nz * hessian * (0.25 + mx + mz),
        )
    }

    /// The frame of tile `(i, j)`: the region in the tile's local
    /// coordinates and the map from them to the screen.
    fn tile_frame(&mut self, i: i64, j: i64) -> usize {
        let (sx, ox) = tile_map(self.wrap.x, i);
        let (sz, oz) = tile_map(self.wrap.z, j);
        // Local coordinates are tree space: a texture of another aspect
        // spans [0, ex) × [0, ez) of it, exact powers of two.
        let aspect = self.tree.aspect();
        let [ex, ez] = aspect.scale();
        let (sx, sz) = (sx / ex, sz / ez);
        // texture = (sx·x + ox, sz·z + oz): a half-plane's line in local
        // coordinates, and the screen map composed with it.
        let mut edges = self.edges;
        for l in &mut edges.0[..edges.1] {
            *l = [l[0] * sx, l[1] * sz, l[0] * ox + l[1] * oz + l[2]];
        }
        // The pad is not texture: keep the tile to x < ex, z < ez.
        if !aspect.is_square() {
            edges.0[edges.1] = if ex < 1.0 {
                [-1.0, 0.0, ex]
            } else {
                [0.0, -1.0, ez]
            };
            edges.1 += 1;
        }
        let m = &self.screen_from_texture;
        let to_screen = [0, 1, 2].map(|r| {
            [
                m[r][0] * sx,
                m[r][1] * sz,
                m[r][0] * ox + m[r][1] * oz + m[r][2],
            ]
        });
        self.frames.push(TileFrame {
            edges,
            to_screen,
            det: self.screen_det * aspect.area_ratio(),
        });
        self.frames.len() - 1
    }

    /// Where the walk over tile `(i, j)` starts: the deepest node whose
    /// square holds the region's part of the tile strictly inside one
    /// child, down from the root through nodes of full contrast
    /// ([`QuadTree::splits_fully`]). The walk would refine each node above
    /// it first thing: its bound there is the region's whole weight (unit
    /// contrast over all of it), above any target of an error bound below
    /// [`MAX_SKIPPED_EPSILON`], and of its four children the other three
    /// miss the region. Starting below them skips evaluating four squares
    /// a level for nothing (a region of a pixel or two over a deep raster:
    /// most of the walk's squares before).
    fn start_node(&self, i: i64, j: i64) -> (NodeRef, u8, u32, u32) {
        let mut at = (QuadTree::ROOT, 0u8, 0u32, 0u32);
        if self.target >= MAX_SKIPPED_EPSILON * self.k_max * self.area {
            return at;
        }
        // The region's bounds in the tile's local (tree) coordinates:
        // texture = sign·local/extent + offset (`tile_frame`).
        let (lo, hi) = self.region.bounds();
        let extent = self.tree.aspect().scale();
        let local = |axis: usize, mode: WrapMode, tile: i64| {
            let (sign, offset) = tile_map(mode, tile);
            let a = (lo[axis] - offset) * sign * extent[axis];
            let b = (hi[axis] - offset) * sign * extent[axis];
            (a.min(b), a.max(b))
        };
        let (x, z) = (local(0, self.wrap.x, i), local(1, self.wrap.z, j));
        loop {
            let (node, level, ix, iz) = at;
            if self.fixed.is_some_and(|k| level >= k) || !self.tree.splits_fully(node) {
                return at;
            }
            let side = unit_side(level + 1);
            let (mx, mz) = (f64::from(2 * ix + 1) * side, f64::from(2 * iz + 1) * side);
            let (Some(hx), Some(hz)) = (half(x, mx), half(z, mz)) else {
                return at;
            };
            at = (
                self.tree.child_ref(node, (hx + 2 * hz) as usize),
                level + 1,
                2 * ix + hx,
                2 * iz + hz,
            );
        }
    }

    fn evaluate_node(&mut self, frame: usize, p: NodeRef, level: u8, ix: u32, iz: u32) -> Outcome {
        let f = &self.frames[frame];
        let side = unit_side(level);
        let (x0, z0) = (f64::from(ix) * side, f64::from(iz) * side);
        let (x1, z1) = (x0 + side, z0 + side);
        let class = classify(&f.edges, x0, z0, x1, z1);
        if class == Class::Outside {
            return Outcome::Outside;
        }
        self.visited += 1;
        // `contrast` bounds the colour's deviation from the square's mean: 1
        // (full contrast) but in gradient leaves, whose range is known.
        let (inner, colour, contrast) = self.tree.node_detail(p);
        let corners = [[x0, z0], [x1, z0], [x1, z1], [x0, z1]];
        let m = f.to_screen;
        let refinable = inner && self.fixed.is_none_or(|k| level < k);
        let here = Item::Node {
            frame: frame as u32,
            node: p,
            level,
            ix,
            iz,
        };
        let piece = match class {
            Class::Inside => {
                let mapped = corners.map(|t| apply(&m, t));
                let bound = if contrast > 0.0 {
                    let (rmin, rmax) = density_range_det(&m, f.det, &corners);
                    let diam = if self.lipschitz > 0.0 {
                        bbox_diagonal(&mapped)
                    } else {
                        0.0
                    };
                    0.5 * contrast
                        * side
                        * side
                        * (self.k_max * (rmax - rmin) + rmax * self.lipschitz * diam)
                } else {
                    0.0
                };
                // The box's weight is the quad's area: no polygon needed.
                let c = if self.filter == PixelFilter::Box {
                    let weight = crate::geometry::polygon::signed_area(&mapped).abs();
                    Contribution {
                        colour: colour.map(|v| v * weight),
                        weight,
                        bound,
                    }
                } else {
                    self.contribution(colour, &ConvexPolygon::from_trusted(&mapped), bound)
                };
                return if refinable && bound > 0.0 {
                    Outcome::Refinable(c, here)
                } else {
                    Outcome::Final(c)
                };
            }
            Class::Boundary(crossing) => ConvexPolygon::rect(x0, z0, x1, z1)
                .clip_lines(
                    f.edges.0[..f.edges.1]
                        .iter()
                        .enumerate()
                        .filter(|(e, _)| crossing >> e & 1 == 1)
                        .map(|(_, l)| *l),
                )
                .map(|t| apply(&m, t)),
            Class::Outside => return Outcome::Outside,
        };
        let bound = contrast * self.k_max * piece.area();
        let c = self.contribution(colour, &piece, bound);
        if refinable {
            Outcome::Refinable(c, here)
        } else {
            Outcome::Final(c)
        }
    }

    /// A part of the plane beyond a clamp or border edge.
    fn outside(&mut self, xs: Segment, zs: Segment) {
        let range = |s: Segment| match s {
            Segment::Tiles(a, b) => (a as f64, (b + 1) as f64),
            Segment::Low => (f64::NEG_INFINITY, 0.0),
            Segment::High => (1.0, f64::INFINITY),
        };
        let (x0, x1) = range(xs);
        let (z0, z1) = range(zs);
        let piece = self.region.clip_rect(x0, z0, x1, z1);
        if piece.is_empty() {
            return;
        }
        self.visited += 1;
        let m = self.screen_from_texture;
        let x_out = !matches!(xs, Segment::Tiles(..));
        let z_out = !matches!(zs, Segment::Tiles(..));
        if (x_out && self.wrap.x == WrapMode::Border) || (z_out && self.wrap.z == WrapMode::Border)
        {
            let b = self.wrap.border.to_array().map(f64::from);
            self.add(b, &self.to_screen_poly(&piece, &m), false);
            return;
        }
        if x_out && z_out {
            let c = self.corner_colour(xs == Segment::High, zs == Segment::High);
            self.add(c, &self.to_screen_poly(&piece, &m), false);
            return;
        }
        // A clamp stripe: the colour varies along the other axis only.
        let (axis, high, other) = if x_out {
            (0, xs == Segment::High, zs)
        } else {
            (1, zs == Segment::High, xs)
        };
        if let Segment::Tiles(j0, j1) = other {
            self.stripe(axis, high, j0, j1, &piece);
        }
    }

    /// Tiles `j0..=j1` along the stripe beyond edge (`axis`, `high`).
    fn stripe(&mut self, axis: usize, high: bool, j0: i64, j1: i64, piece: &ConvexPolygon) {
        let (b0, b1) = (j0 as f64, (j1 + 1) as f64);
        let part = clip_axis(piece, 1 - axis, b0, b1);
        if part.is_empty() {
            return;
        }
        self.visited += 1;
        let m = self.screen_from_texture;
        let screen = self.to_screen_poly(&part, &m);
        if j0 == j1 {
            let mode = if axis == 0 { self.wrap.z } else { self.wrap.x };
            let (sign, offset) = tile_map(mode, j0);
            self.edge_node(axis, high, QuadTree::ROOT, 0, 0, sign, offset, &part);
            return;
        }
        if self.over_budget() {
            // Out of budget: the texture's mean, the whole weight as bound.
            let c = self.tree.mean_colour();
            self.add(c, &screen, true);
            return;
        }
        if self.fixed.is_none() && screen.area() <= self.boundary_coef * diameter(&screen) {
            let c = self.edge_mean(axis, high);
            self.add(c, &screen, true);
            return;
        }
        let mid = j0 + (j1 - j0) / 2;
        self.stripe(axis, high, j0, mid, &part);
        self.stripe(axis, high, mid + 1, j1, &part);
    }

    /// The edge cells of node `p` (index `k` along the edge at `level`) over
    /// the stripe part `part`, the edge's tile mapped by `sign`, `offset`.
    #[allow(clippy::too_many_arguments)]
    fn edge_node(
        &mut self,
        axis: usize,
        high: bool,
        p: NodeRef,
        level: u8,
        k: u32,
        sign: f64,
        offset: f64,
        part: &ConvexPolygon,
    ) {
        // Along the edge, in texture units of that axis (tree units over the extent).
        let aspect = self.tree.aspect();
        let along = aspect.scale()[1 - axis];
        let side = unit_side(level);
        let (l0, l1) = (f64::from(k) * side / along, f64::from(k + 1) * side / along);
        if l0 >= 1.0 {
            return;
        }
        let (t0, t1) = if sign > 0.0 {
            (offset + l0, offset + l1)
        } else {
            (offset - l1, offset - l0)
        };
        let piece = clip_axis(part, 1 - axis, t0, t1);
        if piece.is_empty() {
            return;
        }
        self.visited += 1;
        let (inner, stored) = self.tree.node_info(p);
        let m = self.screen_from_texture;
        let screen = self.to_screen_poly(&piece, &m);
        let take = !inner
            || self.over_budget()
            || match self.fixed {
                Some(f) => level >= f,
                None => screen.area() <= self.boundary_coef * diameter(&screen),
            };
        if take {
            self.add(stored, &screen, inner);
            return;
        }
        let h = u32::from(across_high(aspect, axis, high, level));
        for c in 0..2u32 {
            // Children on the edge: the outer half across the edge, both along it.
            let child = if axis == 0 { h + 2 * c } else { c + 2 * h };
            self.edge_node(
                axis,
                high,
                self.tree.child_ref(p, child as usize),
                level + 1,
                2 * k + c,
                sign,
                offset,
                &piece,
            );
        }
    }

    /// The mean colour along edge (`axis`, `high`): the stretched cells of a
    /// clamp stripe, averaged over one tile.
    fn edge_mean(&mut self, axis: usize, high: bool) -> [f64; 4] {
        let slot = 2 * axis + usize::from(high);
        if let Some(c) = self.edge_means[slot] {
            return c;
        }
        let mut acc = [0.0; 4];
        let aspect = self.tree.aspect();
        let along = aspect.scale()[1 - axis];
        let mut stack = vec![(QuadTree::ROOT, 0u8, 0u32)];
        while let Some((p, level, k)) = stack.pop() {
            let side = unit_side(level);
            let start = f64::from(k) * side;
            if start >= along {
                continue;
            }
            let (inner, c) = self.tree.node_info(p);
            if !inner {
                // Its length along the edge that is texture, in texture units.
                let length = ((start + side).min(along) - start) / along;
                for (a, v) in acc.iter_mut().zip(c) {
                    *a += v * length;
                }
                continue;
            }
            let h = usize::from(across_high(aspect, axis, high, level));
            for c in 0..2usize {
                let child = if axis == 0 { h + 2 * c } else { c + 2 * h };
                stack.push((self.tree.child_ref(p, child), level + 1, 2 * k + c as u32));
            }
        }
        self.edge_means[slot] = Some(acc);
        acc
    }

    /// The colour of the tree's corner cell (`x` high?, `z` high?).
    fn corner_colour(&self, x_high: bool, z_high: bool) -> [f64; 4] {
        let aspect = self.tree.aspect();
        let (mut p, mut level) = (QuadTree::ROOT, 0u8);
        loop {
            let (inner, colour) = self.tree.node_info(p);
            if !inner {
                return colour;
            }
            let hx = across_high(aspect, 0, x_high, level);
            let hz = across_high(aspect, 1, z_high, level);
            p = self
                .tree
                .child_ref(p, usize::from(hx) + 2 * usize::from(hz));
            level += 1;
        }
    }
}

/// Which half of a level-`level` square on the texture's edge (`axis`,
/// `high`) holds that edge: the high one for the high edge, except above a
/// shrunk axis's level, where the texture's high edge lies in the low half
/// ([`crate::Aspect`]).
#[inline]
fn across_high(aspect: crate::Aspect, axis: usize, high: bool, level: u8) -> bool {
    high && level >= aspect.shrink()[axis]
}

/// Screen length of the edges of `piece` (a region clipped to the box
/// `[x0, z0, x1, z1]`) that are not on the box's sides: where the region's
/// boundary cuts the box.
fn cut_length(piece: &ConvexPolygon, [x0, z0, x1, z1]: [f64; 4], m: &Mat3) -> f64 {
    let v = piece.vertices();
    let n = v.len();
    let tol = 1e-9 * (x1 - x0).max(z1 - z0);
    let on = |a: f64, b: f64, c: f64| (a - c).abs() <= tol && (b - c).abs() <= tol;
    let mut total = 0.0;
    for i in 0..n {
        let (a, b) = (v[i], v[(i + 1) % n]);
        if on(a[0], b[0], x0) || on(a[0], b[0], x1) || on(a[1], b[1], z0) || on(a[1], b[1], z1) {
            continue;
        }
        let (p, q) = (apply(m, a), apply(m, b));
        let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
        total += (dx * dx + dy * dy).sqrt();
    }
    total
}

/// The part of `p` with coordinate `axis` in `[lo, hi]`.
fn clip_axis(p: &ConvexPolygon, axis: usize, lo: f64, hi: f64) -> ConvexPolygon {
    if axis == 0 {
        p.clip_rect(lo, f64::NEG_INFINITY, hi, f64::INFINITY)
    } else {
        p.clip_rect(f64::NEG_INFINITY, lo, f64::INFINITY, hi)
    }
}

/// A bound on the screen diameter of one tile of a block of `nx × nz`
/// tiles whose corners map to `q` on the screen (low-x low-z, high-x low-z,
/// high-x high-z, low-x high-z): the block's sides over the tile
/// counts, each axis on its own (a block one tile wide and many tall has
/// tiles as wide as itself, not a `1/max(nx, nz)` share of its diameter),
/// scaled by how much the density varies across the block.
fn tile_diameter(q: &[[f64; 2]; 4], nx: f64, nz: f64, rmin: f64, rmax: f64) -> f64 {
    let len = |a: [f64; 2], b: [f64; 2]| length(a[0] - b[0], a[1] - b[1]);
    let along_x = len(q[1], q[0]).max(len(q[2], q[3])) / nx;
    let along_z = len(q[3], q[0]).max(len(q[2], q[1])) / nz;
    (along_x + along_z) * (rmax / rmin).max(1.0).sqrt()
}

/// `√(dx² + dy²)`, by `hypot` only where the squares overflow or
/// underflow (`hypot` costs several times more, and this runs per block).
#[inline]
fn length(dx: f64, dy: f64) -> f64 {
    let s = (dx * dx + dy * dy).sqrt();
    if s.is_finite() && s > 1e-150 {
        s
    } else {
        dx.hypot(dy)
    }
}

/// The diagonal of the bounding box of `points`.
#[inline]
fn bbox_diagonal(points: &[[f64; 2]]) -> f64 {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in points {
        for a in 0..2 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let (dx, dy) = (hi[0] - lo[0], hi[1] - lo[1]);
    (dx * dx + dy * dy).sqrt()
}

/// The bounding box's diagonal of a polygon.
#[inline]
fn diameter(p: &ConvexPolygon) -> f64 {
    bbox_diagonal(p.vertices())
}

/// Extremes of the screen density `|det m| / w³` over `corners`.
#[inline]
fn density_range_det(m: &Mat3, det: f64, corners: &[[f64; 2]; 4]) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, 0f64);
    for t in corners {
        let w = (m[2][0] * t[0] + m[2][1] * t[1] + m[2][2]).abs();
        let rho = det / (w * w * w);
        lo = lo.min(rho);
        hi = hi.max(rho);
    }
    (lo, hi)
}

/// Which half of a square split at `mid` holds `(a, b)` (0 low, 1 high),
/// with room to spare for the rounding of a tile frame's edges; `None`
/// when it reaches within [`START_MARGIN`] of the middle.
#[inline]
fn half(a_b: (f64, f64), mid: f64) -> Option<u32> {
    let (a, b) = a_b;
    if b < mid - START_MARGIN {
        Some(0)
    } else if a > mid + START_MARGIN {
        Some(1)
    } else {
        None
    }
}

/// The colour of finest cell `(x, z)` (tree space) under node `node` at
/// `(level, ix, iz)` where a uniform square holds it
/// ([`QuadTree::finest_colour`]), for [`scan_grid`].
fn finest_colour_below(
    tree: &QuadTree,
    (node, level, ix, iz): (NodeRef, u8, u32, u32),
) -> impl Fn(i64, i64) -> Option<[f64; 4]> + '_ {
    move |x, z| {
        tree.finest_colour(
            node,
            level,
            ix,
            iz,
            u32::try_from(x).ok()?,
            u32::try_from(z).ok()?,
        )
    }
}

/// A region's texture box over a plain raster
/// ([`QuadTree::is_plain_raster`]), from [`raster_box`].
enum RasterBox {
    /// One colour covers the whole box: a terminal square holds it, or
    /// every cell of the grid at the depth it reaches has that colour.
    Uniform(Rgba),
    /// In one tile, at most [`SMALL_SCAN_CELLS`] cells, not one colour:
    /// for [`SmallBox::scan`].
    Small(SmallBox),
    /// Two cells of one tile or four (two a side), not one colour: for
    /// [`FewCells::integrate`].
    Few(FewCells),
    /// Neither: across tiles, or more cells.
    Other,
}

/// A box in one tile of a plain raster, over a few cells of the grid at
/// the tree's depth.
struct SmallBox {
    /// The tile's frame per axis, `(sign, offset)`: texture = sign·local +
    /// offset ([`tile_map`]), as the walk's tile frame takes it.
    frame: [(f64, f64); 2],
    /// The deepest stored square holding the box: each cell's colour is a
    /// short descent from it.
    start: StoredSquare,
}

/// A texture box over two cells or four (two a side) of one tile: the
/// region's part in each cell is where it lies on that cell's side of the
/// grid lines between them, and a grid line `x = t` (or `z = t`) of the
/// texture is the screen line `(m₀ − t·m₂)·(x, y, 1) = 0` of the map
/// `m = texture_from_screen` (a projective map sends lines to lines; the
/// region lies in front of the camera, `m₂·(x, y, 1) > 0`, so the sign
/// tells the side). Each part is one clip of the screen region, no texture
/// polygon built and no band swept: most of a photograph's pieces in the
/// terrain's pixels are of this kind (1×2, 2×1 or 2×2 texels: 91 % of
/// those [`SmallBox::scan`] took before).
struct FewCells {
    /// Per axis, where the box reaches two cells: the texture coordinate
    /// of the grid line between them and the tile's sign on that axis
    /// (the cell of the lower local coordinate comes first).
    lines: [Option<(f64, f64)>; 2],
    /// `colours[z][x]`: the cells' colours (premultiplied, linear), by
    /// local position, low first; the second of an axis the box does not
    /// span is unused.
    colours: [[[f64; 4]; 2]; 2],
    /// How many cells the box reaches (2 or 4).
    cells: f64,
}

impl FewCells {
    /// The cells `x0..x1` by `z0..z1` (at most two a side) of the grid of
    /// side `h` in the tile of `frame` ([`SmallBox::frame`]), and their
    /// `colours` (`[z][x]`, low local position first).
    fn new(
        frame: [(f64, f64); 2],
        h: f64,
        (x0, x1): (i64, i64),
        (z0, z1): (i64, i64),
        colours: [[[f64; 4]; 2]; 2],
    ) -> FewCells {
        // The grid line between two cells, in texture coordinates: local
        // `(c0 + 1)·h` (a multiple of a power of two, exact).
        let line = |(c0, c1): (i64, i64), (sign, offset): (f64, f64)| {
            (c1 - c0 == 2).then(|| (sign * ((c0 + 1) as f64 * h) + offset, sign))
        };
        FewCells {
            lines: [line((x0, x1), frame[0]), line((z0, z1), frame[1])],
            colours,
            cells: ((x1 - x0) * (z1 - z0)) as f64,
        }
    }

    /// The integral under `filter` centred at `centre` over screen region
    /// `region` (whose weight there is `total`): `(Σ colour·k, Σ k,
    /// cells)`, or `None` where a grid line's screen image is not finite
    /// (the caller then walks the region). The parts' weights sum to `total`: each
    /// second part's is what its axis leaves of the first's.
    fn integrate(
        &self,
        region: &ConvexPolygon,
        texture_from_screen: &Mat3,
        filter: PixelFilter,
        centre: [f64; 2],
        total: f64,
    ) -> Option<([f64; 4], f64, f64)> {
        let m = texture_from_screen;
        // `l·(x, y, 1) ≥ 0` on the cell of the higher local coordinate.
        let line = |axis: usize| -> Option<Option<[f64; 3]>> {
            let Some((t, sign)) = self.lines[axis] else {
                return Some(None);
            };
            let l = [0, 1, 2].map(|j| sign * (m[axis][j] - t * m[2][j]));
            l.iter().all(|v| v.is_finite()).then_some(Some(l))
        };
        let (lx, lz) = (line(0)?, line(1)?);
        let low_side = |p: &ConvexPolygon, l: [f64; 3]| p.clip(-l[0], -l[1], -l[2]);
        // The weights of the low and high cells of z within `part`.
        let split_z = |part: &ConvexPolygon, weight: f64| match lz {
            None => [weight, 0.0],
            Some(l) => {
                let low = filter.integral(&low_side(part, l), centre);
                [low, weight - low]
            }
        };
        let weights: [[f64; 2]; 2] = match lx {
            None => {
                let [a, b] = split_z(region, total);
                [[a, 0.0], [b, 0.0]]
            }
            Some(l) => {
                let low = low_side(region, l);
                let w_low = filter.integral(&low, centre);
                let [a, b] = split_z(&low, w_low);
                let [c, d] = match lz {
                    None => [total - w_low, 0.0],
                    Some(_) => split_z(&region.clip(l[0], l[1], l[2]), total - w_low),
                };
                [[a, c], [b, d]]
            }
        };
        let mut colour = [0.0; 4];
        for (cz, row) in weights.iter().enumerate() {
            for (cx, &w) in row.iter().enumerate() {
                for (a, c) in colour.iter_mut().zip(self.colours[cz][cx]) {
                    *a += c * w;
                }
            }
        }
        Some((colour, total, self.cells))
    }
}

/// What the texture box `lo..hi` of a region over a plain raster
/// ([`QuadTree::is_plain_raster`]) is: one colour, a few cells of one
/// tile, or neither. One descent of stored nodes, and a look at each
/// cell the box reaches (at most [`SMALL_SCAN_CELLS`]).
///
/// A mesh triangle's piece of a pixel over a photograph spans one to four
/// texels: here it costs a descent and a texel read or four, where the
/// uniform search ([`uniform_colour_in`]) and the walk's set-up (buffers,
/// tile frame, start node, first square) each cost several times that.
fn raster_box(tree: &QuadTree, wrap: Wrap, lo: [f64; 2], hi: [f64; 2]) -> RasterBox {
    let one_tile = |mode: WrapMode, lo: f64, hi: f64| match segments(mode, lo, hi) {
        [Some(Segment::Tiles(a, b)), None, None] | [None, Some(Segment::Tiles(a, b)), None]
            if a == b =>
        {
            Some(a)
        }
        _ => None,
    };
    let (Some(i), Some(j)) = (
        one_tile(wrap.x, lo[0], hi[0]),
        one_tile(wrap.z, lo[1], hi[1]),
    ) else {
        return RasterBox::Other;
    };
    let frame = [tile_map(wrap.x, i), tile_map(wrap.z, j)];
    let local = |a: f64, b: f64, (sign, offset): (f64, f64)| {
        let (p, q) = ((a - offset) * sign, (b - offset) * sign);
        (p.min(q), p.max(q))
    };
    let (x, z) = (local(lo[0], hi[0], frame[0]), local(lo[1], hi[1], frame[1]));
    let start = tree.stored_square_holding(x, z);
    // A plain raster's terminal squares are of one colour each.
    if let Some(cell) = tree.terminal_cell(start) {
        return RasterBox::Uniform(cell.rgba());
    }
    // The cells the box reaches, half-open (a box ending on a cell's side
    // does not reach the next), at least one a side.
    let n = 1i64 << tree.depth();
    let h = unit_side(tree.depth());
    let cells = |(a, b): (f64, f64)| {
        let first = ((a / h).floor() as i64).clamp(0, n - 1);
        let end = ((b / h).ceil() as i64).clamp(first + 1, n);
        (first, end)
    };
    let ((x0, x1), (z0, z1)) = (cells(x), cells(z));
    if ((x1 - x0) * (z1 - z0)) as f64 > SMALL_SCAN_CELLS {
        return RasterBox::Other;
    }
    let cells = tree.cells_below(start);
    if x1 - x0 <= 2 && z1 - z0 <= 2 {
        return few_cells(&cells, frame, h, (x0, x1), (z0, z1));
    }
    let Some(first) = cells.cell(x0 as u32, z0 as u32) else {
        return RasterBox::Other;
    };
    let colour = first.rgba();
    for cz in z0..z1 {
        // The first cell is read above.
        let from = if cz == z0 { x0 + 1 } else { x0 };
        for cx in from..x1 {
            match cells.cell(cx as u32, cz as u32) {
                Some(c) if c.rgba() == colour => {}
                Some(_) => return RasterBox::Small(SmallBox { frame, start }),
                None => return RasterBox::Other,
            }
        }
    }
    RasterBox::Uniform(colour)
}

/// [`raster_box`]'s answer for a box over at most two cells a side,
/// `x0..x1` by `z0..z1` of the grid (side `h`) in the tile of `frame`:
/// one colour, or the cells for [`FewCells`] (neither when a cell has no
/// colour, as [`raster_box`] answers then).
fn few_cells(
    cells: &crate::tree::CellReader<'_>,
    frame: [(f64, f64); 2],
    h: f64,
    (x0, x1): (i64, i64),
    (z0, z1): (i64, i64),
) -> RasterBox {
    let mut colours = [[[0.0; 4]; 2]; 2];
    let mut first = None;
    let mut uniform = true;
    for (cz, z) in (z0..z1).enumerate() {
        for (cx, x) in (x0..x1).enumerate() {
            let Some(c) = cells.cell(x as u32, z as u32) else {
                return RasterBox::Other;
            };
            let rgba = c.rgba();
            uniform &= *first.get_or_insert(rgba) == rgba;
            colours[cz][cx] = c.colour();
        }
    }
    match first {
        Some(c) if uniform => RasterBox::Uniform(c),
        _ => RasterBox::Few(FewCells::new(frame, h, (x0, x1), (z0, z1), colours)),
    }
}

impl SmallBox {
    /// The region (texture space, counter-clockwise), whose box this is,
    /// exactly: each cell of the grid at the tree's depth it crosses
    /// clipped and weighted ([`scan_grid`]), as the walk's texel scan does
    /// ([`Walk::scan_texels`]), but with no walk set up. `(Σ colour·k, Σ
    /// k, cells)`, or `None` (nothing computed) past [`SMALL_SCAN_CELLS`]
    /// cells: the walk's own scan of the tile would fail the same way.
    fn scan(
        &self,
        tree: &QuadTree,
        region: &ConvexPolygon,
        screen_from_texture: &Mat3,
        filter: PixelFilter,
        centre: [f64; 2],
    ) -> Option<([f64; 4], f64, f64)> {
        let [(sx, ox), (sz, oz)] = self.frame;
        // The first tile's frame maps each coordinate to itself (`(x − 0)·1
        // = x`, signed zeros and all): a counter-clockwise region is then
        // its own local polygon, not copied.
        let (moved, clipped);
        let mut local = if self.frame == [(1.0, 0.0), (1.0, 0.0)] && region.signed_area() >= 0.0 {
            region
        } else {
            moved = region.map_counter_clockwise(|[x, z]| [(x - ox) * sx, (z - oz) * sz]);
            &moved
        };
        let (llo, lhi) = local.bounds();
        if llo[0] < 0.0 || llo[1] < 0.0 || lhi[0] > 1.0 || lhi[1] > 1.0 {
            clipped = local.clip_rect(0.0, 0.0, 1.0, 1.0);
            local = &clipped;
        }
        if local.is_empty() {
            return None;
        }
        let m = screen_from_texture;
        // Row by row, not by an array `map` (not inlined: this runs per region).
        let row = |r: &[f64; 3]| [r[0] * sx, r[1] * sz, r[0] * ox + r[1] * oz + r[2]];
        let to_screen = [row(&m[0]), row(&m[1]), row(&m[2])];
        let cells = tree.cells_below(self.start);
        scan_grid(
            local,
            &to_screen,
            unit_side(tree.depth()),
            filter,
            centre,
            SMALL_SCAN_CELLS,
            |x, z| {
                let (x, z) = (u32::try_from(x).ok()?, u32::try_from(z).ok()?);
                cells.cell(x, z).map(FinestCell::colour)
            },
        )
    }
}

/// The region over a shallow tree (depth ≤
/// [`crate::tree::FLAT_GRID_MAX_DEPTH`], both axes repeated or mirrored)
/// whose texture-space box `lo..hi` lies in one run of tiles a side,
/// exactly: band by band of the grid at the tree's depth, each cell the
/// region crosses clipped and weighted, at most [`SCAN_CELLS`] cells.
/// `(Σ colour·k, Σ k, cells)`, or `None` (nothing computed) when it does
/// not apply; the walk then takes the region.
///
/// It matters for the thin needles below a horizon: the walk's blocks
/// do not fit inside them and refining tile by tile costs more squares
/// than the budget, while a cell here costs a clip and an area. It runs
/// before a walk is set up (its lines, buffers and queue), which a
/// region it takes does not need.
#[allow(clippy::too_many_arguments)]
fn scan_flat_grid(
    tree: &QuadTree,
    wrap: Wrap,
    (lo, hi): ([f64; 2], [f64; 2]),
    region: &ConvexPolygon,
    screen_from_texture: &Mat3,
    filter: PixelFilter,
    centre: [f64; 2],
) -> Option<([f64; 4], f64, f64)> {
    let grid = tree.flat_grid()?;
    let depth = tree.depth();
    if depth == 0
        || one_run_of_tiles(&segments(wrap.x, lo[0], hi[0])).is_none()
        || one_run_of_tiles(&segments(wrap.z, lo[1], hi[1])).is_none()
    {
        return None;
    }
    let n = 1usize << depth;
    let (wrap_x, wrap_z) = (wrap.x, wrap.z);
    let colour = |x: i64, z: i64| {
        Some(grid[fold_cell(wrap_z, z, depth)? * n + fold_cell(wrap_x, x, depth)?])
    };
    scan_grid(
        region,
        screen_from_texture,
        1.0 / n as f64,
        filter,
        centre,
        SCAN_CELLS,
        colour,
    )
}

/// The integral under `filter` centred at `centre` over `region` (grid
/// coordinates: cell `(x, z)` is `[x·h, (x+1)·h) × [z·h, (z+1)·h)`, mapped to
/// the screen by `m`) of the colour `colour(x, z)` of each cell it crosses,
/// exactly: band by band of cells, each cell's piece clipped and weighted.
/// `(Σ colour·k, Σ k, cells)`, or `None` (nothing computed) past
/// `max_cells` cells or where `colour` gives none.
fn scan_grid(
    region: &ConvexPolygon,
    m: &Mat3,
    h: f64,
    filter: PixelFilter,
    centre: [f64; 2],
    max_cells: f64,
    mut colour: impl FnMut(i64, i64) -> Option<[f64; 4]>,
) -> Option<([f64; 4], f64, f64)> {
    let (lo, hi) = region.bounds();
    let (k0, k1) = ((lo[1] / h).floor(), (hi[1] / h).ceil());
    let (c0, c1) = ((lo[0] / h).floor(), (hi[0] / h).ceil());
    // Bands run across the axis the region spans fewer cells of: a
    // needle along z is cut into a few long columns, not many short
    // rows (a band costs a split and the projection of its vertices,
    // a box-filtered cell within it one cut). The region is transposed
    // for it, `(x, z) → (z, x)`, with the screen map's columns swapped;
    // the orientation this reverses does not matter to the box's
    // areas, taken as absolute values. Other filters clip each cell by
    // rows.
    let transpose = filter == PixelFilter::Box && c1 - c0 < k1 - k0;
    // The bands' cells number at least the bands, the columns the region
    // spans, and its area in cells (less rounding): past `max_cells` by
    // any of these, the scan would stop there, its work thrown away (the
    // regions at a horizon, millions of cells, spent 24 µs each so).
    let least = (k1 - k0).max(c1 - c0).max(region.area() / (h * h) - 1.0);
    if least.is_nan() || least > max_cells {
        return None;
    }
    let (k0, k1) = if transpose { (c0, c1) } else { (k0, k1) };
    let (k0, k1) = (k0 as i64, k1 as i64);
    let columns = |p: &ConvexPolygon| {
        let (a, b) = p.bounds();
        ((a[0] / h).floor() as i64, (b[0] / h).ceil() as i64)
    };
    let mut m = *m;
    if transpose {
        for row in &mut m {
            row.swap(0, 1);
        }
    }
    // Band `k`, cell `col` within it: the cell's grid position.
    let mut colour = |k: i64, col: i64| {
        if transpose {
            colour(k, col)
        } else {
            colour(col, k)
        }
    };
    let (mut colour_sum, mut weight_sum, mut cells) = ([0.0; 4], 0.0, 0.0);
    let mut add = |colour: [f64; 4], w: f64| {
        for (a, c) in colour_sum.iter_mut().zip(colour) {
            *a += c * w;
        }
        weight_sum += w;
    };
    let transposed;
    let region = if transpose {
        transposed = region.map(|[x, z]| [z, x]);
        &transposed
    } else {
        region
    };
    let texture = region.vertices();
    let screen = band_to_screen(texture, &m, centre);
    let mut bands = Bands::new(texture, &screen);
    let mut band = BandBuffer::default();
    for k in k0..k1 {
        let top = if k + 1 < k1 {
            (k + 1) as f64 * h
        } else {
            f64::INFINITY
        };
        bands.next_band(top, &m, centre, &mut band);
        let (texture, screen) = (band.texture(), band.screen());
        if texture.len() < 3 {
            continue;
        }
        if filter == PixelFilter::Box {
            // The box weight of a cell's piece is its screen area: the
            // screen area of the band left of the cell's right side,
            // less that left of its left side. One sweep along the band's
            // two chains, no polygon built.
            let total = shoelace(screen);
            let mut sweep = LeftOf::new(texture, screen, total);
            let (m0, m1) = (
                (sweep.x_min / h).floor() as i64,
                (sweep.x_max / h).ceil() as i64,
            );
            cells += (m1 - m0) as f64;
            if cells > max_cells {
                return None;
            }
            let mut left = 0.0;
            for col in m0..m1 {
                let upto = if col + 1 == m1 {
                    total
                } else {
                    sweep.area((col + 1) as f64 * h, &m, centre)
                };
                let w = 0.5 * (upto - left).abs();
                left = upto;
                add(colour(k, col)?, w);
            }
            continue;
        }
        let p = ConvexPolygon::from_trusted(texture);
        let (m0, m1) = columns(&p);
        cells += (m1 - m0) as f64;
        if cells > max_cells {
            return None;
        }
        for col in m0..m1 {
            let x = col as f64 * h;
            let piece = p.clip_rect(x, f64::NEG_INFINITY, x + h, f64::INFINITY);
            if piece.is_empty() {
                continue;
            }
            let w = filter.integral(&piece.map(|t| apply(&m, t)), centre);
            add(colour(k, col)?, w);
        }
    }
    Some((colour_sum, weight_sum, cells))
}

/// The texture-space `texture` vertices (at most
/// [`MAX_VERTICES`](crate::geometry::polygon::MAX_VERTICES)) mapped by `m` to screen
/// coordinates relative to `centre` (so that shoelace sums stay at the
/// polygon's own scale), in a buffer that is not zeroed first.
#[inline(always)]
fn band_to_screen(
    texture: &[[f64; 2]],
    m: &Mat3,
    centre: [f64; 2],
) -> ArrayVec<[f64; 2], { crate::geometry::polygon::MAX_VERTICES }> {
    (texture.iter().take(crate::geometry::polygon::MAX_VERTICES))
        .map(|&t| {
            let q = apply(m, t);
            [q[0] - centre[0], q[1] - centre[1]]
        })
        .collect()
}

/// The doubled signed area of the polygon with vertices `p`.
#[inline(always)]
fn shoelace(p: &[[f64; 2]]) -> f64 {
    let (Some(&first), Some(&last)) = (p.first(), p.last()) else {
        return 0.0;
    };
    let cross = |a: [f64; 2], b: [f64; 2]| a[0] * b[1] - a[1] * b[0];
    let mut sum = 0.0;
    let mut a = first;
    for &b in &p[1..] {
        sum += cross(a, b);
        a = b;
    }
    sum + cross(last, first)
}

/// One band of a region, in its order: texture coordinates and the
/// screen coordinates [`band_to_screen`] gives them (one band has at most
/// the region's vertices and four crossings).
struct BandBuffer {
    // Not zeroed arrays: a band is written from its first vertex, and
    // clearing 640 bytes per region cost more than most bands' cuts.
    texture: ArrayVec<[f64; 2], BAND_VERTICES>,
    screen: ArrayVec<[f64; 2], BAND_VERTICES>,
}

/// Most vertices of a band: the region's and four crossings.
const BAND_VERTICES: usize = crate::geometry::polygon::MAX_VERTICES + 4;

impl Default for BandBuffer {
    fn default() -> Self {
        BandBuffer {
            texture: ArrayVec::new(),
            screen: ArrayVec::new(),
        }
    }
}

impl BandBuffer {
    fn texture(&self) -> &[[f64; 2]] {
        &self.texture
    }

    fn screen(&self) -> &[[f64; 2]] {
        &self.screen
    }

    #[cfg(test)]
    fn len(&self) -> usize {
        self.texture.len()
    }

    fn clear(&mut self) {
        self.texture.clear();
        self.screen.clear();
    }

    /// Drops the last vertex.
    fn pop(&mut self) {
        self.texture.pop();
        self.screen.pop();
    }

    #[inline(always)]
    fn push(&mut self, (texture, screen): ([f64; 2], [f64; 2])) {
        if self.texture.len() < BAND_VERTICES {
            self.texture.push(texture);
            self.screen.push(screen);
        }
    }
}

/// A convex texture-space polygon (either orientation) cut into bands
/// `z ∈ [z_k, z_(k+1)]` from the bottom up, for cuts taken in increasing
/// order: a walk up its two chains from its lowest vertex, as [`LeftOf`]
/// walks in `x`. Each crossing of a cut is computed and mapped to the
/// screen once, for the band below it and the band above; the region's
/// own vertices are mapped once, beforehand. A band is the polygon's part
/// between two cuts, in the polygon's order: the first chain's (forward
/// from the lowest vertex) crossing of the lower cut, its vertices between
/// the cuts, its crossing of the upper cut, the second chain's (backward)
/// crossing of it, the second chain's vertices between, and its crossing
/// of the lower cut. A chain's last vertex at or below a cut is that
/// cut's crossing when it lies on the cut (a run of vertices on a cut,
/// which rounding leaves at a convex polygon's top, keeps all but that
/// one as the band's).
///
/// Where rounding leaves a chain not quite monotone in `z`, the walk
/// stops at the first vertex past the cut, as [`LeftOf`] does.
struct Bands<'a> {
    texture: &'a [[f64; 2]],
    screen: &'a [[f64; 2]],
    /// Per chain: its last vertex at or below the previous cut.
    at: [usize; 2],
    /// Per chain: its crossing of the previous cut (texture, screen);
    /// `None` before the first band (the lowest vertex starts both).
    low: Option<[([f64; 2], [f64; 2]); 2]>,
}

impl<'a> Bands<'a> {
    fn new(texture: &'a [[f64; 2]], screen: &'a [[f64; 2]]) -> Bands<'a> {
        let mut lowest = 0;
        for (i, t) in texture.iter().enumerate() {
            if t[1] < texture[lowest][1] {
                lowest = i;
            }
        }
        Bands {
            texture,
            screen,
            at: [lowest; 2],
            low: None,
        }
    }

    /// The band from the previous cut (the polygon's bottom at first) up
    /// to `top`, into `band`; `top` no less than the previous cut, and
    /// infinite for the last band (the rest of the polygon).
    #[inline(always)]
    fn next_band(&mut self, top: f64, m: &Mat3, centre: [f64; 2], band: &mut BandBuffer) {
        band.clear();
        let n = self.texture.len();
        if n < 3 {
            return;
        }
        let forward = |i: usize| if i + 1 == n { 0 } else { i + 1 };
        let backward = |i: usize| if i == 0 { n - 1 } else { i - 1 };
        let vertex = |i: usize| (self.texture[i], self.screen[i]);
        match self.low {
            Some([first, _]) => band.push(first),
            None => band.push(vertex(self.at[0])),
        }
        if top == f64::INFINITY {
            // The rest: the vertices after the first chain's last one
            // below, up to the second chain's (not included), then the
            // second chain's crossing. With no cut before, the two chains
            // start at the lowest vertex: the whole polygon.
            let mut i = forward(self.at[0]);
            while i != self.at[1] {
                band.push(vertex(i));
                i = forward(i);
            }
            if let Some([_, second]) = self.low {
                band.push(second);
            }
            return;
        }
        // The lowest vertex is not above any cut and the highest is above
        // this one, so neither walk passes the top (bounded below anyway).
        let crossing = |a: usize, b: usize| {
            let (a, b) = (self.texture[a], self.texture[b]);
            let u = (top - a[1]) / (b[1] - a[1]);
            let t = [a[0] + u * (b[0] - a[0]), top];
            let q = apply(m, t);
            (t, [q[0] - centre[0], q[1] - centre[1]])
        };
        // Each vertex the walk reaches is the band's, but the last one when
        // it lies on the cut: the crossing is that vertex then (`u = 0`
        // gives it exactly), pushed below.
        // At most `n` steps a walk: a top at or above every vertex (which
        // callers' cuts below the region's top never are) cannot cycle.
        let (mut i, mut next) = (self.at[0], forward(self.at[0]));
        let mut steps = 0;
        while steps < n && self.texture[next][1] <= top {
            (i, next) = (next, forward(next));
            band.push(vertex(i));
            steps += 1;
        }
        if i != self.at[0] && self.texture[i][1] == top {
            band.pop();
        }
        self.at[0] = i;
        let first = crossing(i, next);
        band.push(first);
        let (mut i, mut next) = (self.at[1], backward(self.at[1]));
        // The second chain's vertices between the cuts, in the order it
        // meets them (against the polygon's): pushed reversed below.
        let mut between = [0usize; crate::geometry::polygon::MAX_VERTICES];
        let mut count = 0;
        let mut steps = 0;
        while steps < n && self.texture[next][1] <= top {
            steps += 1;
            (i, next) = (next, backward(next));
            if count < between.len() {
                between[count] = i;
                count += 1;
            }
        }
        if i != self.at[1] && self.texture[i][1] == top {
            count = count.saturating_sub(1);
        }
        self.at[1] = i;
        let second = crossing(i, next);
        band.push(second);
        for &i in between[..count].iter().rev() {
            band.push(vertex(i));
        }
        if let Some([_, low]) = self.low {
            band.push(low);
        }
        self.low = Some([first, second]);
    }
}

/// The doubled signed screen area of the part of a texture-space convex
/// polygon left of a cut `x = c`, for cuts taken in increasing order: a
/// sweep along the polygon's two chains from its leftmost vertex to its
/// rightmost, each vertex's shoelace term added once as the cuts pass it,
/// so that a cut costs its two crossing points (`O(n + cuts)` a band,
/// against `O(n)` a cut for clipping the band at each).
///
/// The left part's boundary, in the polygon's own order: the first chain
/// (forward from the leftmost vertex) up to its last vertex left of the
/// cut, its crossing, the cut, the second chain's crossing, and the second
/// chain (backward from the leftmost vertex) back to the start. Where
/// rounding leaves a chain not quite monotone in `x` (a vertex a few ulps
/// behind its predecessor), the sweep stops at the first vertex past the
/// cut: the left part then differs from a clip by a sliver of that wiggle's
/// width.
struct LeftOf<'a> {
    texture: &'a [[f64; 2]],
    screen: &'a [[f64; 2]],
    /// The doubled signed area of the whole polygon, for cuts past it.
    total: f64,
    /// The leftmost and rightmost `x`.
    x_min: f64,
    x_max: f64,
    /// Per chain (0 forward, 1 backward from the leftmost vertex): the
    /// index of its last vertex left of the cut and the shoelace sum up to
    /// it.
    at: [usize; 2],
    sum: [f64; 2],
}

impl<'a> LeftOf<'a> {
    fn new(texture: &'a [[f64; 2]], screen: &'a [[f64; 2]], total: f64) -> LeftOf<'a> {
        let (mut first, mut x_min, mut x_max) = (0, f64::INFINITY, f64::NEG_INFINITY);
        for (i, t) in texture.iter().enumerate() {
            if t[0] < x_min {
                (first, x_min) = (i, t[0]);
            }
            x_max = x_max.max(t[0]);
        }
        LeftOf {
            texture,
            screen,
            total,
            x_min,
            x_max,
            at: [first; 2],
            sum: [0.0; 2],
        }
    }

    /// The doubled signed screen area left of `x = cut` (see the type);
    /// `cut` no less than at the previous call.
    #[inline(always)]
    fn area(&mut self, cut: f64, m: &Mat3, centre: [f64; 2]) -> f64 {
        if cut.is_nan() || cut <= self.x_min {
            return 0.0;
        }
        if cut >= self.x_max {
            return self.total;
        }
        let n = self.texture.len();
        let cross = |a: [f64; 2], b: [f64; 2]| a[0] * b[1] - a[1] * b[0];
        let mut crossing = [[0.0; 2]; 2];
        for (chain, point) in crossing.iter_mut().enumerate() {
            // The neighbour by a compare, not `% n`: `n` is not known
            // when compiled, so `%` is an integer division each step.
            let step = |i: usize| {
                if chain == 0 {
                    if i + 1 == n { 0 } else { i + 1 }
                } else if i == 0 {
                    n - 1
                } else {
                    i - 1
                }
            };
            let (mut i, mut next) = (self.at[chain], step(self.at[chain]));
            // The rightmost vertex lies past the cut: the loop stops there
            // at the latest.
            while self.texture[next][0] <= cut {
                let (a, b) = (self.screen[i], self.screen[next]);
                // The backward chain runs against the polygon's order.
                self.sum[chain] += if chain == 0 { cross(a, b) } else { cross(b, a) };
                (i, next) = (next, step(next));
            }
            self.at[chain] = i;
            let (a, b) = (self.texture[i], self.texture[next]);
            let u = (cut - a[0]) / (b[0] - a[0]);
            let q = apply(m, [cut, a[1] + u * (b[1] - a[1])]);
            *point = [q[0] - centre[0], q[1] - centre[1]];
        }
        let [forward, backward] = crossing;
        self.sum[0]
            + cross(self.screen[self.at[0]], forward)
            + cross(forward, backward)
            + cross(backward, self.screen[self.at[1]])
            + self.sum[1]
    }
}

/// The doubled signed screen area of the part of a texture-space convex
/// polygon with `x <= x_cut`: Sutherland–Hodgman against one half-plane,
/// the clipped vertices fed straight into the shoelace sum. `screen` holds
/// the vertices as [`band_to_screen`] mapped them. The slow reference
/// [`LeftOf`] is tested against.
#[cfg(test)]
fn band_left_of(
    texture: &[[f64; 2]],
    screen: &[[f64; 2]],
    x_cut: f64,
    m: &Mat3,
    centre: [f64; 2],
) -> f64 {
    let n = texture.len();
    let mut sum = 0.0;
    let mut first: Option<[f64; 2]> = None;
    let mut last = [0.0; 2];
    let mut emit = |q: [f64; 2]| {
        match first {
            None => first = Some(q),
            Some(_) => sum += last[0] * q[1] - last[1] * q[0],
        }
        last = q;
    };
    let crossing = |a: [f64; 2], b: [f64; 2]| {
        let u = (x_cut - a[0]) / (b[0] - a[0]);
        let q = apply(m, [x_cut, a[1] + u * (b[1] - a[1])]);
        [q[0] - centre[0], q[1] - centre[1]]
    };
    let mut prev = n.wrapping_sub(1);
    for i in 0..n {
        let (prev_in, cur_in) = (texture[prev][0] <= x_cut, texture[i][0] <= x_cut);
        if cur_in {
            if !prev_in {
                emit(crossing(texture[prev], texture[i]));
            }
            emit(screen[i]);
        } else if prev_in {
            emit(crossing(texture[prev], texture[i]));
        }
        prev = i;
    }
    if let Some(f) = first {
        sum += last[0] * f[1] - last[1] * f[0];
    }
    sum
}

#[inline]
fn apply(m: &Mat3, p: [f64; 2]) -> [f64; 2] {
    let w = m[2][0] * p[0] + m[2][1] * p[1] + m[2][2];
    [
        (m[0][0] * p[0] + m[0][1] * p[1] + m[0][2]) / w,
        (m[1][0] * p[0] + m[1][1] * p[1] + m[1][2]) / w,
    ]
}

fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

/// The adjugate (transposed cofactors) and the determinant.
fn adjugate(m: &Mat3) -> (Mat3, f64) {
    let [[a, b, c], [d, e, f], [g, h, i]] = *m;
    let adj = [
        [e * i - f * h, c * h - b * i, b * f - c * e],
        [f * g - d * i, a * i - c * g, c * d - a * f],
        [d * h - e * g, b * g - a * h, a * e - b * d],
    ];
    let det = a * adj[0][0] + b * adj[1][0] + c * adj[2][0];
    (adj, det)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A convex polygon of `n` vertices on an ellipse, counter-clockwise
    /// or (`reversed`) clockwise, vertices at random angles.
    fn ellipse_polygon(next: &mut impl FnMut() -> f64, n: usize, reversed: bool) -> Vec<[f64; 2]> {
        let (cx, cz) = (next() * 4.0 - 2.0, next() * 4.0 - 2.0);
        let (rx, rz) = (0.1 + next() * 3.0, 0.1 + next() * 3.0);
        let mut angles: Vec<f64> = (0..n).map(|_| next() * std::f64::consts::TAU).collect();
        angles.sort_by(f64::total_cmp);
        let mut p: Vec<[f64; 2]> = angles
            .iter()
            .map(|a| [cx + rx * a.cos(), cz + rz * a.sin()])
            .collect();
        if reversed {
            p.reverse();
        }
        p
    }

    /// The sweep's area left of each cut is the clip's (the slow
    /// reference), for increasing cuts before, across (on vertices too)
    /// and past random convex polygons in either orientation, under mild
    /// random perspective: polygons with vertical sides at the cuts, the
    /// bands `scan_grid` cuts (an ellipse between two lines), and a vertex
    /// rounding left a few ulps behind its predecessor.
    #[test]
    fn the_sweep_gives_each_cut_what_clipping_gives() {
        let mut next = crate::test_rng::uniform(29);
        let mut checked = 0;
        for case in 0..3000 {
            let n = 3 + case % 10;
            let mut texture = ellipse_polygon(&mut next, n, case % 2 == 1);
            match case % 5 {
                // An axis-aligned box: vertical sides, cut exactly on them.
                0 => {
                    let (x0, z0) = (next() * 2.0, next() * 2.0);
                    let (x1, z1) = (x0 + 0.25 * (1 + case % 7) as f64, z0 + next() + 0.1);
                    texture = vec![[x0, z0], [x1, z0], [x1, z1], [x0, z1]];
                }
                // A band of the ellipse between two lines z = const.
                1 => {
                    let p = ConvexPolygon::new(&texture);
                    if let Ok(p) = p {
                        let (lo, hi) = p.bounds();
                        let z = lo[1] + (hi[1] - lo[1]) * next();
                        let band = p.clip(0.0, 1.0, -z).clip(0.0, -1.0, z + 0.3);
                        if band.vertices().len() >= 3 {
                            texture = band.vertices().to_vec();
                        }
                    }
                }
                // A vertex a few ulps behind its predecessor in x.
                2 => {
                    let i = case % texture.len();
                    let behind = texture[i][0] - 4.0 * f64::EPSILON * texture[i][0].abs();
                    texture.insert(i + 1, [behind, texture[i][1]]);
                }
                _ => {}
            }
            // Mild perspective: w stays within [0.5, 1.5] over the polygon.
            let m: Mat3 = [
                [1.0 + next(), next() - 0.5, next() * 10.0],
                [next() - 0.5, 1.0 + next(), next() * 10.0],
                [0.1 * (next() - 0.5), 0.1 * (next() - 0.5), 1.0],
            ];
            let centre = [next() * 10.0, next() * 10.0];
            let screen = band_to_screen(&texture, &m, centre);
            let total = shoelace(&screen);
            let mut sweep = LeftOf::new(&texture, &screen, total);
            let xs: Vec<f64> = texture.iter().map(|t| t[0]).collect();
            let (lo, hi) = (
                xs.iter().copied().fold(f64::INFINITY, f64::min),
                xs.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            );
            // Cuts: before, on every vertex, between, past.
            let mut cuts: Vec<f64> = xs.clone();
            cuts.extend((0..8).map(|_| lo - 0.5 + (hi - lo + 1.0) * next()));
            cuts.extend([lo - 1.0, lo, hi, hi + 1.0]);
            cuts.sort_by(f64::total_cmp);
            for cut in cuts {
                let swept = sweep.area(cut, &m, centre);
                let clipped = band_left_of(&texture, &screen, cut, &m, centre);
                let tolerance = 1e-11 * total.abs().max(1.0);
                assert!(
                    (swept - clipped).abs() <= tolerance,
                    "case {case}: cut {cut} of {texture:?}: swept {swept}, clipped {clipped}"
                );
                checked += 1;
            }
        }
        assert!(checked > 30_000);
    }

    /// `(Σ colour·area, Σ area, cells)` over the cells of size `h` that
    /// `region` crosses: each cell's piece clipped, mapped by `m` and
    /// weighted by its screen area (relative to `centre`).
    fn clip_every_cell(
        region: &ConvexPolygon,
        m: &Mat3,
        h: f64,
        centre: [f64; 2],
        colour: impl Fn(i64, i64) -> Option<[f64; 4]>,
    ) -> ([f64; 4], f64, f64) {
        let (lo, hi) = region.bounds();
        let (mut sum, mut weight, mut cells) = ([0.0; 4], 0.0, 0.0);
        for z in (lo[1] / h).floor() as i64..(hi[1] / h).ceil() as i64 {
            for x in (lo[0] / h).floor() as i64..(hi[0] / h).ceil() as i64 {
                let (x0, z0) = (x as f64 * h, z as f64 * h);
                let piece = region.clip_rect(x0, z0, x0 + h, z0 + h);
                if piece.is_empty() {
                    continue;
                }
                let w = PixelFilter::Box.integral(&piece.map(|t| apply(m, t)), centre);
                for (s, c) in sum.iter_mut().zip(colour(x, z).unwrap()) {
                    *s += c * w;
                }
                weight += w;
                cells += 1.0;
            }
        }
        (sum, weight, cells)
    }

    /// The box scan (a band at a time, a sweep a band) gives what clipping
    /// every cell gives (the slow reference, `clip_every_cell`): random
    /// convex polygons in either orientation under random perspective, on
    /// grids of random colours;
    /// boxes with their sides on grid lines, bands of an ellipse between
    /// two grid lines, triangles with their vertices on grid points;
    /// negative coordinates; cells from 1/16 to 2; needles across and
    /// along the grid (both of the scan's orientations).
    /// A run of vertices on a cut, one chain's, with the polygon's top a
    /// rounding above it (a mapped region's top edge, from the terrain
    /// scene): each stays the band's, and the bands keep the region's
    /// weight, in either orientation and with the axes swapped.
    #[test]
    fn a_cut_above_the_whole_region_ends_its_walk() {
        // Callers cut strictly below the region's top; a cut at or above
        // every vertex (a cell side whose multiples round up) must still
        // end, with no more than the buffer's vertices.
        let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let m: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        for top in [1.0, 2.0] {
            let mut bands = Bands::new(&square, &square);
            let mut band = BandBuffer::default();
            bands.next_band(0.5, &m, [0.0, 0.0], &mut band);
            assert_eq!(band.len(), 4);
            bands.next_band(top, &m, [0.0, 0.0], &mut band);
            assert!(band.len() <= BAND_VERTICES);
        }
    }

    #[test]
    fn a_run_of_vertices_on_a_cut_stays_in_its_band() {
        let cases: [(&[[f64; 2]], f64); 2] = [
            (
                &[
                    [0.5968829885663551, 0.7498363903052521],
                    [0.5968368329422433, 0.7500000000000001],
                    [0.5967517636501981, 0.75],
                    [0.5966666936874391, 0.75],
                ],
                1.0 / 1024.0,
            ),
            (
                &[
                    [0.1, 0.3],
                    [0.9, 0.5000000000000001],
                    [0.6, 0.5],
                    [0.2, 0.5],
                ],
                0.25,
            ),
        ];
        let m: Mat3 = [[1.2, 0.1, 3.0], [-0.2, 0.9, 1.0], [0.01, 0.02, 1.0]];
        let colour =
            |x: i64, z: i64| Some([x.rem_euclid(3) as f64, z.rem_euclid(2) as f64, 1.0, 1.0]);
        let mut checked = 0;
        for (vertices, h) in cases {
            for (reversed, swapped) in [(false, false), (true, false), (false, true), (true, true)]
            {
                let mut v: Vec<[f64; 2]> = vertices.to_vec();
                if swapped {
                    v.iter_mut().for_each(|p| p.swap(0, 1));
                }
                if reversed {
                    v.reverse();
                }
                let region = ConvexPolygon::from_trusted(&v);
                // Shoelace sums relative to a point near the region, as a
                // pixel's centre is.
                let centre = apply(&m, v[0]);
                let clipped = clip_every_cell(&region, &m, h, centre, colour);
                let swept =
                    scan_grid(&region, &m, h, PixelFilter::Box, centre, 4096.0, colour).unwrap();
                // The reference's clips round too: at the first case's
                // thin corner it is off by 3e-6 of that cell's weight
                // (against exact rational arithmetic, which the scan meets
                // to 2e-11). A vertex lost loses a third of the region.
                let tolerance = 1e-5 * clipped.1;
                assert!(
                    (swept.1 - clipped.1).abs() <= tolerance
                        && (0..4).all(|c| (swept.0[c] - clipped.0[c]).abs() <= tolerance),
                    "{v:?}: {swept:?} against {clipped:?}"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 8);
    }

    /// Two or four cells (two a side) of a tile, repeated or mirrored, at
    /// grid sides from 1/2 to 1/64: the region's integral from
    /// [`FewCells::integrate`] (one clip a grid line, on the screen) is
    /// what clipping the region to each cell in texture space and
    /// integrating the piece's image gives (the slow reference), under
    /// each pixel filter, for random convex regions inside the cells under
    /// random perspective, regions on one side of the line (the box
    /// reaches the other cell by rounding) and regions with an edge on
    /// it.
    #[test]
    fn few_cells_give_what_clipping_every_cell_gives() {
        let mut next = crate::test_rng::uniform(37);
        let mut checked = [0; 3];
        for case in 0..3000 {
            let depth = 1 + case % 6;
            let h = unit_side(depth as u8);
            let n = 1i64 << depth;
            let (wide, tall) = match case % 3 {
                0 => (2, 1),
                1 => (1, 2),
                _ => (2, 2),
            };
            let x0 = ((next() * (n - wide + 1) as f64) as i64).min(n - wide);
            let z0 = ((next() * (n - tall + 1) as f64) as i64).min(n - tall);
            let (x1, z1) = (x0 + wide, z0 + tall);
            let tile = |i: i64| match (case / 3) % 2 {
                0 => tile_map(WrapMode::Repeat, i),
                _ => tile_map(WrapMode::Mirror, i),
            };
            let frame = [
                tile((next() * 5.0) as i64 - 2),
                tile((next() * 5.0) as i64 - 2),
            ];
            // A random convex region in local coordinates, inside the
            // cells' rectangle; or one side of it; or a rectangle with a
            // side on the grid line.
            let (rx0, rz0, rx1, rz1) = (x0 as f64 * h, z0 as f64 * h, x1 as f64 * h, z1 as f64 * h);
            let ellipse = ellipse_polygon(&mut next, 3 + case % 8, case % 2 == 1);
            let Ok(e) = ConvexPolygon::new(&ellipse) else {
                continue;
            };
            let (elo, ehi) = e.bounds();
            let fit = |[x, z]: [f64; 2]| {
                [
                    rx0 + (x - elo[0]) / (ehi[0] - elo[0]) * (rx1 - rx0),
                    rz0 + (z - elo[1]) / (ehi[1] - elo[1]) * (rz1 - rz0),
                ]
            };
            let local = match (case / 6) % 4 {
                0 | 1 => e.map(fit),
                2 => e.map(fit).clip_rect(rx0, rz0, rx0 + h, rz1),
                _ => ConvexPolygon::new(&[
                    [rx0 + h * 0.3, rz0 + h * 0.2],
                    [rx0 + h, rz0 + h * 0.2],
                    [rx0 + h, rz1 - h * 0.1],
                    [rx0 + h * 0.3, rz1 - h * 0.1],
                ])
                .unwrap(),
            };
            if local.is_empty() {
                continue;
            }
            let to_texture =
                |[x, z]: [f64; 2]| [frame[0].0 * x + frame[0].1, frame[1].0 * z + frame[1].1];
            let texture_region = local.map_counter_clockwise(to_texture);
            // Perspective over the region's texture box, w within [0.7, 1.3].
            let (tlo, thi) = texture_region.bounds();
            let extent = tlo.iter().chain(&thi).fold(1.0f64, |a, v| a.max(v.abs()));
            let g = 0.3 / (2.0 * extent);
            let scale = 1.0 / h * (0.5 + 2.0 * next());
            let screen_from_texture: Mat3 = [
                [
                    scale * (1.0 + next()),
                    scale * (next() - 0.5),
                    next() * 10.0,
                ],
                [
                    scale * (next() - 0.5),
                    scale * (1.0 + next()),
                    next() * 10.0,
                ],
                [g * (next() - 0.5), g * (next() - 0.5), 1.0],
            ];
            let texture_from_screen = adjugate(&screen_from_texture).0;
            let screen = texture_region.map_counter_clockwise(|t| apply(&screen_from_texture, t));
            let mut colours = [[[0.0; 4]; 2]; 2];
            for c in colours.iter_mut().flatten() {
                *c = [next(), next(), next(), 0.5 + 0.5 * next()];
            }
            let few = FewCells::new(frame, h, (x0, x1), (z0, z1), colours);
            let centre = {
                let c = screen.centroid();
                [c[0] + next() - 0.5, c[1] + next() - 0.5]
            };
            let filter = [PixelFilter::Box, PixelFilter::Tent, PixelFilter::Mitchell][case % 7 % 3];
            // The reference: each cell's piece in local coordinates, mapped
            // to the screen and integrated.
            let (mut want, mut want_weight) = ([0.0; 4], 0.0);
            for (cz, z) in (z0..z1).enumerate() {
                for (cx, x) in (x0..x1).enumerate() {
                    let (px, pz) = (x as f64 * h, z as f64 * h);
                    let piece = local.clip_rect(px, pz, px + h, pz + h);
                    if piece.is_empty() {
                        continue;
                    }
                    let on_screen =
                        piece.map_counter_clockwise(|l| apply(&screen_from_texture, to_texture(l)));
                    let w = filter.integral(&on_screen, centre);
                    for (a, c) in want.iter_mut().zip(colours[cz][cx]) {
                        *a += c * w;
                    }
                    want_weight += w;
                }
            }
            let total = filter.integral(&screen, centre);
            let (got, weight, cells) = few
                .integrate(&screen, &texture_from_screen, filter, centre, total)
                .unwrap_or_else(|| panic!("case {case}: no lines"));
            assert_eq!(cells, (wide * tall) as f64);
            let tolerance = 1e-11 * (1.0 + screen.area());
            assert!(
                (weight - want_weight).abs() <= tolerance,
                "case {case}: weight {weight} against {want_weight}"
            );
            for c in 0..4 {
                assert!(
                    (got[c] - want[c]).abs() <= tolerance,
                    "case {case}: channel {c}: {} against {} ({filter:?}, {wide}×{tall}, frame {frame:?})",
                    got[c],
                    want[c]
                );
            }
            checked[case % 3] += 1;
        }
        assert!(checked.iter().all(|&c| c > 500), "{checked:?}");
    }

    #[test]
    fn the_box_scan_gives_what_clipping_every_cell_gives() {
        let mut next = crate::test_rng::uniform(31);
        let (mut checked, mut transposed, mut cells) = (0, 0, 0.0);
        for case in 0..4000 {
            let n = 3 + case % 10;
            let mut texture = ellipse_polygon(&mut next, n, case % 2 == 1);
            let h = [0.0625, 0.25, 0.5, 1.0, 2.0][case % 5];
            match case % 7 {
                0 => {
                    let (x0, z0) = (
                        (next() * 8.0 - 4.0).floor() * h,
                        (next() * 8.0).floor() * -h,
                    );
                    let (x1, z1) = (
                        // `case % 7` is 0 here: widths from the case's other digits.
                        x0 + h * (1 + (case / 7) % 6) as f64,
                        z0 + h * (1 + (case / 42) % 3) as f64,
                    );
                    texture = vec![[x0, z0], [x1, z0], [x1, z1], [x0, z1]];
                }
                1 => {
                    if let Ok(p) = ConvexPolygon::new(&texture) {
                        let (lo, hi) = p.bounds();
                        let z = ((lo[1] + (hi[1] - lo[1]) * next()) / h).floor() * h;
                        let band = p.clip(0.0, 1.0, -z).clip(0.0, -1.0, z + h);
                        if band.vertices().len() >= 3 {
                            texture = band.vertices().to_vec();
                        }
                    }
                }
                2 => {
                    let mut grid_point = || {
                        [
                            (next() * 12.0 - 6.0).floor() * h,
                            (next() * 12.0 - 6.0).floor() * h,
                        ]
                    };
                    texture = vec![grid_point(), grid_point(), grid_point()];
                }
                // A needle: long along one axis, thin across it.
                3 => {
                    let (x, z, long, thin) = (
                        next() * 4.0 - 2.0,
                        next() * 4.0 - 2.0,
                        2.0 + 6.0 * next(),
                        0.05 + 0.3 * next(),
                    );
                    texture = if next() < 0.5 {
                        vec![
                            [x, z],
                            [x + thin, z + 0.1],
                            [x + thin * 1.5, z + long],
                            [x - 0.1 * thin, z + long * 0.9],
                        ]
                    } else {
                        vec![
                            [x, z],
                            [x + long, z - 0.1],
                            [x + long * 0.9, z + thin],
                            [x + 0.05, z + thin * 1.2],
                        ]
                    };
                }
                _ => {}
            }
            let Ok(region) = ConvexPolygon::new(&texture) else {
                continue;
            };
            if region.is_empty() {
                continue;
            }
            let (lo, hi) = region.bounds();
            // Perspective: w stays within [0.8, 1.2] over the polygon.
            let g = 0.2 / (1.0 + lo[0].abs().max(hi[0].abs()) + lo[1].abs().max(hi[1].abs()));
            let m: Mat3 = [
                [1.0 + next(), next() - 0.5, next() * 10.0],
                [next() - 0.5, 1.0 + next(), next() * 10.0],
                [g * (next() - 0.5), g * (next() - 0.5), 1.0],
            ];
            let centre = [next() * 10.0, next() * 10.0];
            let salt = (next() * 1e6) as i64;
            let colour = |x: i64, z: i64| {
                let k = (x * 7 + z * 13 + salt).rem_euclid(5) as f64;
                Some([k / 4.0, x.rem_euclid(2) as f64, 0.5, 1.0 - k / 8.0])
            };
            let max_cells = 4096.0;
            let clipped = clip_every_cell(&region, &m, h, centre, colour);
            if clipped.2 > max_cells {
                continue;
            }
            let swept = scan_grid(&region, &m, h, PixelFilter::Box, centre, max_cells, colour)
                .unwrap_or_else(|| panic!("case {case}: no box scan of {texture:?}"));
            let screen = region.map(|t| apply(&m, t));
            let scale = diameter(&screen) * (diameter(&screen) + 1.0);
            let tolerance = 1e-12 * scale * (1.0 + clipped.2);
            assert!(
                (swept.1 - clipped.1).abs() <= tolerance,
                "case {case}: weight {} against {} over {texture:?}",
                swept.1,
                clipped.1
            );
            for c in 0..4 {
                assert!(
                    (swept.0[c] - clipped.0[c]).abs() <= tolerance,
                    "case {case}: channel {c}: {} against {} over {texture:?}, h {h}",
                    swept.0[c],
                    clipped.0[c]
                );
            }
            if (hi[0] - lo[0]) < (hi[1] - lo[1]) {
                transposed += 1;
            }
            checked += 1;
            cells += clipped.2;
        }
        assert!(
            checked > 3000 && transposed > 500 && cells > 50_000.0,
            "{checked} cases, {transposed} transposed, {cells} cells"
        );
    }
}

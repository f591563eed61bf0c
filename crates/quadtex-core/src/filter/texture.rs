//! The filtering API: a [`Texture`] (a packed tree and its [`Wrap`]) answers
//! "what is the mean colour over this footprint?" for a [`Footprint`] under
//! [`FilterOptions`], and, for renderers that know more than four corners,
//! "what is the filtered integral over this screen region?"
//! ([`Texture::integrate_region`]).
//!
//! [`Texture::filter`], for one footprint:
//! 1. **Uniform shortcut.** If the footprint's bounding box (folded into one
//!    tile by the wrap) lies inside one terminal square of the tree, every
//!    point of the footprint has that square's colour: one descent, exact.
//! 2. **Exact polygon integral.** Otherwise the tree's squares are clipped
//!    against the footprint quad and each piece is weighted by the screen
//!    area that sees it, through the projective map the four corners fix
//!    ([`Weighting::Screen`], a box over the *pixel*), or by its texture
//!    area ([`Weighting::Texture`], a box over the footprint, as the seed
//!    paper does). See [`crate::filter::region`]: the result is exact up to the
//!    squares the [`crate::LevelOfDetail`] takes at their mean, whose error is
//!    bounded and reported in [`FilterStats`].
//! 3. A footprint of zero area filters to the texel at its centre.
//!
//! The older rectangle pipeline (axis-aligned strips over-covering the
//! footprint) is a baseline now: [`crate::baseline::filter_by_strips`].

use std::sync::Arc;

use crate::colour::{ColourEncoding, Rgba, WeightedColour};
use crate::filter::batch::{Threads, map_runs_on_threads};
use crate::filter::footprint::Footprint;
use crate::filter::options::{FilterOptions, FilterStats, Weighting};
use crate::filter::pixel_filter::PixelFilter;
use crate::filter::projection::Projection;
use crate::filter::query::{RegionIntegral, RegionQuery};
use crate::filter::region;
use crate::filter::screen_cell::CellIntegral;
use crate::filter::wrap::{Wrap, integrate_wrapped};
use crate::geometry::fragment::Fragment;
use crate::geometry::polygon::ConvexPolygon;
use crate::tree::{QuadTree, TraversalStats};

/// A packed texture ready to filter: the tree (shared) and how texture space
/// continues beyond the unit square.
///
/// ```
/// use quadtex_core::{BuildOptions, FilterOptions, Footprint, QuadTree, Rgba, TexelGrid, Texture, Wrap};
///
/// // A 2×2 checkerboard, packed.
/// let grid = TexelGrid::from_fn(2, 2, |c, r| {
///     if (c + r) % 2 == 0 { Rgba::opaque(1.0, 1.0, 1.0) } else { Rgba::opaque(0.0, 0.0, 0.0) }
/// })?;
/// let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default())?;
/// let texture = Texture::new(tree, Wrap::REPEAT);
///
/// // A pixel whose footprint covers ten tiles and a half: the mean is grey
/// // (to within half a 16-bit step: whole tiles count the root's stored mean).
/// let footprint = Footprint::from_corners([[0.0, 0.0], [10.5, 0.0], [10.5, 1.0], [0.0, 1.0]])?;
/// let colour = texture.filter(&footprint, &FilterOptions::default());
/// assert!((colour.r - 0.5).abs() <= 0.5 / 65535.0);
/// # Ok::<(), quadtex_core::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct Texture {
    tree: Arc<QuadTree>,
    wrap: Wrap,
    /// [`Texture::bound_scale`], fixed by the tree and wrap: found once,
    /// not on every region a renderer integrates.
    bound_scale: f64,
}

impl Texture {
    /// A texture from its tree and wrap.
    pub fn new(tree: impl Into<Arc<QuadTree>>, wrap: Wrap) -> Texture {
        let tree = tree.into();
        let border = [wrap.x(), wrap.z()].contains(&crate::WrapMode::Border);
        let bound_scale =
            (tree.channel_ranges()).widest_with(border.then_some(wrap.border_colour()));
        Texture {
            tree,
            wrap,
            bound_scale,
        }
    }

    /// The packed tree.
    pub fn tree(&self) -> &Arc<QuadTree> {
        &self.tree
    }

    /// The wrap.
    pub fn wrap(&self) -> Wrap {
        self.wrap
    }

    /// What the error bounds, derived for colour channels in `[0, 1]`, are
    /// multiplied by for this texture: the widest channel range (at least 1)
    /// of the colours it can show, the tree's ([`QuadTree::bound_scale`])
    /// and, where an axis wraps to [`crate::WrapMode::Border`], the border
    /// colour's. A bound "relative to the texture's contrast" is relative to
    /// this.
    pub fn bound_scale(&self) -> f64 {
        self.bound_scale
    }

    /// The same tree with another wrap.
    pub fn with_wrap(&self, wrap: Wrap) -> Texture {
        Texture::new(Arc::clone(&self.tree), wrap)
    }

    /// The mean colour (linear, premultiplied) over `footprint` under
    /// `options` (module documentation). Under the default options it is
    /// within the error bound (1/512 of the texture's contrast) of the exact
    /// mean, whatever the footprint; [`Texture::filter_with_bound`] also
    /// returns the bound reached.
    pub fn filter(&self, footprint: &Footprint, options: &FilterOptions) -> Rgba {
        self.filter_counted(footprint, options, &mut FilterStats::default())
    }

    /// As [`Texture::filter`], adding the cost to `stats`.
    pub fn filter_counted(
        &self,
        footprint: &Footprint,
        options: &FilterOptions,
        stats: &mut FilterStats,
    ) -> Rgba {
        self.filter_with_bound(footprint, options, stats).0
    }

    /// As [`Texture::filter_counted`], with the error bound the colour
    /// reached, relative to the texture's contrast (each channel is within
    /// `bound × `[`Texture::bound_scale`] of the exact mean: the bound
    /// itself for LDR textures; 0 when exact).
    /// It is at most the error bound asked for unless a square budget
    /// ([`FilterOptions::with_budget`]) or the hard cap
    /// ([`crate::FIXED_LEVEL_CAP`]) stopped the refinement; such footprints
    /// are counted in [`FilterStats::over_target`].
    ///
    /// Channels that cannot be negative (every channel of an LDR texture,
    /// alpha of an HDR one) are clamped at 0: rounding in the sums can
    /// otherwise leave tiny negatives (`-2e-20`) where the mean is 0.
    pub fn filter_with_bound(
        &self,
        footprint: &Footprint,
        options: &FilterOptions,
        stats: &mut FilterStats,
    ) -> (Rgba, f64) {
        let (colour, absolute) = self.filter_unclamped(footprint, options, stats);
        // The pipeline's bound is in colour units; the target is relative to
        // the texture's contrast (the widest channel range for HDR).
        let bound = absolute / self.bound_scale();
        let mut c = [colour.r, colour.g, colour.b, colour.a];
        let clamped = match self.tree.encoding() {
            ColourEncoding::Unorm16 => &mut c[..],
            ColourEncoding::Half => &mut c[3..],
        };
        for v in clamped {
            *v = v.max(0.0);
        }
        if let Some(target) = options.target_bound()
            && bound > target
        {
            stats.over_target += 1;
        }
        let [r, g, b, a] = c;
        (Rgba { r, g, b, a }, bound)
    }

    /// The filtered colour and its bound (colour units), as the pipeline
    /// gives them (no clamping).
    fn filter_unclamped(
        &self,
        footprint: &Footprint,
        options: &FilterOptions,
        stats: &mut FilterStats,
    ) -> (Rgba, f64) {
        let unit = ConvexPolygon::rect(0.0, 0.0, 1.0, 1.0);
        let screen = match options.weighting() {
            Weighting::Screen => Projection::for_pixel(footprint, [0.0, 0.0]),
            Weighting::Texture => None,
        };
        let result = match screen {
            Some(projection) => self.integrate_region(
                &projection,
                &unit,
                PixelFilter::Box,
                [0.5, 0.5],
                options,
                stats,
            ),
            // Texture weighting, or corners no projective map of the square
            // reaches (a concave or degenerate quad): uniform over the hull.
            None => {
                let hull = ConvexPolygon::hull(&footprint.corners());
                if is_segment(&hull) {
                    stats.record_bound(0.0);
                    let centre = self.nearest_counted(footprint.centre(), &mut stats.traversal);
                    return (centre, 0.0);
                }
                self.integrate_region(
                    &Projection::identity(),
                    &hull,
                    PixelFilter::Box,
                    [0.0, 0.0],
                    options,
                    stats,
                )
            }
        };
        match result.mean() {
            Some(c) if result.weight > 0.0 => {
                let bound = result.error_bound / result.weight;
                // The statistics' bounds are relative to the contrast.
                stats.record_bound(bound / self.bound_scale());
                (c, bound)
            }
            _ => {
                stats.record_bound(0.0);
                (
                    self.nearest_counted(footprint.centre(), &mut stats.traversal),
                    0.0,
                )
            }
        }
    }

    /// The integral of the texture over screen region `region` seen through
    /// `projection` (screen → texture), weighted by `filter` centred at
    /// `centre` (pixel units), with its error bound: see [`crate::filter::region`].
    /// A renderer sums these over the visible parts of a pixel's filter
    /// support (one per surface) and divides by the total weight.
    pub fn integrate_region(
        &self,
        projection: &Projection,
        region: &ConvexPolygon,
        filter: PixelFilter,
        centre: [f64; 2],
        options: &FilterOptions,
        stats: &mut FilterStats,
    ) -> RegionIntegral {
        let query = RegionQuery {
            tree: &self.tree,
            wrap: self.wrap,
            bound_scale: self.bound_scale(),
            projection,
            filter,
            centre,
            options,
        };
        region::integrate_region(&query, region, stats)
    }

    /// Whether [`Texture::integrate_screen_cell`] takes every cell under
    /// `filter` in front of the horizon (within the scan's cell limit):
    /// the tent or Mitchell filter over a shallow repeated texture, whose
    /// cells are scanned exactly. Over other textures it takes only the
    /// cells whose image is one colour, and a renderer is better served
    /// by each pixel's whole support.
    pub fn scans_screen_cells(&self, filter: PixelFilter) -> bool {
        filter != PixelFilter::Box && self.tree.flat_grid().is_some()
    }

    /// The integrals over screen cell `cell` (the unit square between
    /// four pixel centres: [`CellIntegral`] documents the convention) of
    /// the texture seen through `projection` under
    /// `filter`, for each pixel whose support covers the cell, exactly:
    /// summed over the cells of a pixel's support, each pixel's part is
    /// what [`Texture::integrate_region`] gives over that whole support,
    /// up to rounding, with a zero bound. `None` (nothing to add) under
    /// the box filter (no pixels share a cell), under a fixed level of
    /// detail, where a corner of the cell is nearer the horizon than
    /// [`Texture::integrate_region`] takes a support as it is, and where
    /// the cell's image is neither one colour nor within a shallow
    /// repeated texture's scan ([`Texture::scans_screen_cells`]): the
    /// caller then integrates each pixel's support.
    pub fn integrate_screen_cell(
        &self,
        projection: &Projection,
        cell: [i64; 2],
        filter: PixelFilter,
        options: &FilterOptions,
        stats: &mut FilterStats,
    ) -> Option<CellIntegral> {
        let query = super::screen_cell::CellQuery {
            tree: &self.tree,
            wrap: self.wrap,
            projection,
            filter,
            options,
        };
        super::screen_cell::integrate_screen_cell(&query, cell, stats)
    }

    /// The colour of the texture over the whole of screen region `span`
    /// seen through `projection`, when one terminal square of the tree
    /// (under the wrap) holds all of its image; `None` when none does, or
    /// when `span` reaches so near the horizon (`w → 0`) that
    /// [`Texture::integrate_region`] would cut a sliver off a region of
    /// `pixel`'s size and shape inside it. When `Some(c)`, the integral
    /// over any region inside `span` no larger than `pixel` (a pixel's
    /// support, in a run of pixels whose supports `span` covers) is `c`
    /// times its weight, exactly, with a zero bound: a renderer answers a
    /// run of magnified pixels with one lookup.
    pub fn uniform_colour_over(
        &self,
        projection: &Projection,
        span: &ConvexPolygon,
        pixel: &ConvexPolygon,
        options: &FilterOptions,
    ) -> Option<Rgba> {
        region::uniform_colour_over(&self.tree, self.wrap, projection, span, pixel, options)
    }

    /// The colour of the texture over the whole texture-space box
    /// `[lo, hi]` (closed), when one terminal square of the tree (under the
    /// wrap) holds all of it; `None` when none does. When `Some(c)`, the
    /// integral over any region whose image lies in the box is `c` times
    /// its weight, exactly: a renderer whose map to texture space is only
    /// known to within a margin can still answer exactly where the box of
    /// every candidate image is uniform.
    pub fn uniform_colour_in_box(&self, lo: [f64; 2], hi: [f64; 2]) -> Option<Rgba> {
        let finite = lo.iter().chain(&hi).all(|v| v.is_finite());
        if !(finite && lo[0] <= hi[0] && lo[1] <= hi[1]) {
            return None;
        }
        super::wrap::uniform_colour_in(&self.tree, lo, hi, self.wrap)
    }

    /// [`Texture::filter`] over a slice, on every core; `out[i]` is the
    /// colour of `footprints[i]`, bit for bit what [`Texture::filter`]
    /// gives it. [`Texture::filter_batch_with_bounds`] chooses the threads.
    pub fn filter_batch(&self, footprints: &[Footprint], options: &FilterOptions) -> Vec<Rgba> {
        map_runs_on_threads(footprints, Threads::EveryCore, |part, out| {
            let mut stats = FilterStats::default();
            out.extend(
                part.iter()
                    .map(|f| self.filter_counted(f, options, &mut stats)),
            );
        })
    }

    /// [`Texture::filter_with_bound`] over a slice, on `threads` threads:
    /// `out[i]` is the colour of `footprints[i]` and its error bound, bit
    /// for bit the same whatever the thread count.
    pub fn filter_batch_with_bounds(
        &self,
        footprints: &[Footprint],
        options: &FilterOptions,
        threads: Threads,
    ) -> Vec<(Rgba, f64)> {
        map_runs_on_threads(footprints, threads, |part, out| {
            let mut stats = FilterStats::default();
            out.extend(
                part.iter()
                    .map(|f| self.filter_with_bound(f, options, &mut stats)),
            );
        })
    }

    /// The integral (linear, premultiplied colour × area) over the fragment,
    /// which may span tiles, under the wrap, traversing to `level` (the
    /// tree's depth when `None`). Divide by the fragment's area for the mean.
    pub fn integral(&self, fragment: &Fragment, level: Option<u8>) -> WeightedColour {
        let k = level.unwrap_or(self.tree.depth());
        integrate_wrapped(
            &*self.tree,
            fragment,
            k,
            self.wrap,
            &mut TraversalStats::default(),
        )
    }

    /// The finest cell under point `p` (no filtering), under the wrap.
    pub fn nearest(&self, p: [f64; 2]) -> Rgba {
        self.nearest_counted(p, &mut TraversalStats::default())
    }

    /// As [`Texture::nearest`], adding the cost to `stats`.
    pub fn nearest_counted(&self, p: [f64; 2], stats: &mut TraversalStats) -> Rgba {
        let depth = self.tree.depth();
        let [cx, cz] = self.tree.finest_cell_size();
        let (fx, fz) = ((p[0] / cx).floor() * cx, (p[1] / cz).floor() * cz);
        match Fragment::new(fx, fz, fx + cx, fz + cz) {
            Ok(f) => integrate_wrapped(&*self.tree, &f, depth, self.wrap, stats).mean_over(cx * cz),
            Err(_) => Rgba::TRANSPARENT,
        }
    }

    /// Bilinear interpolation between the four finest cells whose centres
    /// surround `p` (no filtering), under the wrap.
    pub fn bilinear(&self, p: [f64; 2]) -> Rgba {
        self.bilinear_counted(p, &mut TraversalStats::default())
    }

    /// As [`Texture::bilinear`], adding the cost to `stats`.
    pub fn bilinear_counted(&self, p: [f64; 2], stats: &mut TraversalStats) -> Rgba {
        let [cx, cz] = self.tree.finest_cell_size();
        let (u, v) = (p[0] / cx - 0.5, p[1] / cz - 0.5);
        let (u0, v0) = (u.floor(), v.floor());
        let (fu, fv) = ((u - u0) as f32, (v - v0) as f32);
        let mut at = |i: f64, j: f64| self.nearest_counted([(i + 0.5) * cx, (j + 0.5) * cz], stats);
        let (a, b) = (at(u0, v0), at(u0 + 1.0, v0));
        let (c, d) = (at(u0, v0 + 1.0), at(u0 + 1.0, v0 + 1.0));
        a.lerp(b, fu).lerp(c.lerp(d, fu), fv)
    }
}

/// Whether a footprint's hull is a segment (or a point) up to rounding:
/// its area at most `10⁻¹²` of its bounding box's squared diagonal. Equal
/// differentials leave such a hull a sliver whose area is rounding alone
/// (its sign and size depend on how the shoelace is summed); its mean is
/// then the point lookup at the centre, under either weighting.
fn is_segment(hull: &ConvexPolygon) -> bool {
    let (lo, hi) = hull.bounds();
    let diagonal = (hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2);
    let area = hull.area();
    area.is_nan() || area <= 1e-12 * diagonal
}

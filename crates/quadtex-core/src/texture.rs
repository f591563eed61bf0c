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
//!    paper does). See [`crate::exact`]: the result is exact up to the
//!    squares the [`LevelOfDetail`] takes at their mean, whose error is
//!    bounded and reported in [`FilterStats`].
//! 3. A footprint of zero area filters to the texel at its centre.
//!
//! [`filter_footprint`] is the older rectangle pipeline (axis-aligned strips
//! over-covering the footprint, each weighted by the screen density at its
//! centre), kept for baselines that can only integrate rectangles (the
//! summed-area table).

use std::sync::Arc;

use crate::Error;
use crate::colour::{Rgba, WeightedColour};
use crate::exact::{self, PixelFilter, Projection, RegionIntegral};
use crate::footprint::Footprint;
use crate::fragment::Fragment;
use crate::polygon::ConvexPolygon;
use crate::tree::{QuadTree, TraversalStats};
use crate::wrap::{BoxIntegral, Wrap, WrapMode, integrate_wrapped};

/// How a footprint's points are weighted in its mean colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Weighting {
    /// Uniform over the pixel square (a screen-space box filter): texture
    /// area is weighed by the screen area that sees it, from the projective
    /// map the footprint's corners fix. The right choice for a renderer.
    #[default]
    Screen,
    /// Uniform over the footprint in texture space, as the seed paper does.
    Texture,
}

/// Where the traversal may take a non-terminal square at its mean.
///
/// For [`Texture::filter`] and [`Texture::integrate_region`]
/// ([`crate::exact`]): `ErrorBound(ε)` aims the bound on each pixel's error
/// (relative to full contrast) at `ε`; `Fixed(k)` descends every square to
/// level `k` or to a terminal square (the tree's depth: exact).
///
/// For the strip pipeline ([`filter_footprint`]): a fragment of sides
/// `w × h` may stop at level `k` only where the squares it treats as whole
/// are partially covered; their area is at most `2(w+h)·2^-k`, so the mean
/// colour is off by at most `2(w+h)·2^-k/(w·h)` of the texture's contrast.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LevelOfDetail {
    /// The smallest level whose truncation bound is `≤ epsilon` (relative to
    /// the texture's contrast), capped by the tree's depth.
    ErrorBound(f64),
    /// Always this level (clamped to the tree's depth).
    Fixed(u8),
}

impl Default for LevelOfDetail {
    /// `ErrorBound(1/512)`: half an 8-bit step at full contrast.
    fn default() -> Self {
        LevelOfDetail::ErrorBound(1.0 / 512.0)
    }
}

impl LevelOfDetail {
    /// The level for a fragment of `w × h` texture units in a tree of `depth`.
    pub fn level(&self, w: f64, h: f64, depth: u8) -> u8 {
        match *self {
            LevelOfDetail::Fixed(k) => k.min(depth),
            LevelOfDetail::ErrorBound(eps) => {
                if !(w > 0.0 && h > 0.0) {
                    return depth;
                }
                let needed = (2.0 * (w + h) / (w * h * eps)).log2().ceil();
                if needed.is_finite() {
                    needed.clamp(0.0, f64::from(depth)) as u8
                } else {
                    depth
                }
            }
        }
    }
}

/// Options of [`Texture::filter`]: weighting, strip quality, level of detail.
///
/// Invariants (checked by the `with_*` constructors): quality is finite and
/// `≥ 1`; an error bound is finite and `> 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilterOptions {
    weighting: Weighting,
    quality: f64,
    lod: LevelOfDetail,
    budget: u64,
}

impl Default for FilterOptions {
    /// [`FilterOptions::DEFAULT`].
    fn default() -> Self {
        FilterOptions::DEFAULT
    }
}

impl FilterOptions {
    /// Screen weighting, quality 1 (strips over-cover by at most 25 %),
    /// error bound 1/512.
    pub const DEFAULT: FilterOptions = FilterOptions {
        weighting: Weighting::Screen,
        quality: 1.0,
        lod: LevelOfDetail::ErrorBound(1.0 / 512.0),
        budget: crate::exact::SQUARE_BUDGET,
    };

    /// The defaults ([`FilterOptions::default`]).
    pub fn new() -> FilterOptions {
        FilterOptions::default()
    }

    /// With this weighting.
    pub fn with_weighting(self, weighting: Weighting) -> FilterOptions {
        FilterOptions { weighting, ..self }
    }

    /// With strip quality `quality` (≥ 1; the strips' area-excess target is
    /// `1/(4·quality)`).
    pub fn with_quality(self, quality: f64) -> Result<FilterOptions, Error> {
        if !(quality.is_finite() && quality >= 1.0) {
            return Err(Error::BadOption {
                name: "quality",
                value: quality,
                expected: "a finite number >= 1",
            });
        }
        Ok(FilterOptions { quality, ..self })
    }

    /// With the level of detail chosen by the error bound `epsilon`
    /// (finite, `> 0`; relative to the texture's contrast).
    pub fn with_error_bound(self, epsilon: f64) -> Result<FilterOptions, Error> {
        if !(epsilon.is_finite() && epsilon > 0.0) {
            return Err(Error::BadOption {
                name: "error bound",
                value: epsilon,
                expected: "a finite number > 0",
            });
        }
        Ok(FilterOptions {
            lod: LevelOfDetail::ErrorBound(epsilon),
            ..self
        })
    }

    /// With every fragment traversed down to level `level` (clamped to the
    /// tree's depth), whatever its size.
    pub fn with_level(self, level: u8) -> FilterOptions {
        FilterOptions {
            lod: LevelOfDetail::Fixed(level),
            ..self
        }
    }

    /// With at most `budget` squares and tile blocks evaluated per region
    /// under an error bound (`≥ 1`; see [`crate::exact`]): past it the
    /// largest remaining errors stay and the bound reached is reported.
    pub fn with_budget(self, budget: u64) -> Result<FilterOptions, Error> {
        if budget == 0 {
            return Err(Error::BadOption {
                name: "budget",
                value: 0.0,
                expected: "at least 1",
            });
        }
        Ok(FilterOptions { budget, ..self })
    }

    /// The square budget per region.
    pub fn budget(&self) -> u64 {
        self.budget
    }

    /// The weighting.
    pub fn weighting(&self) -> Weighting {
        self.weighting
    }

    /// The strip quality.
    pub fn quality(&self) -> f64 {
        self.quality
    }

    /// The level-of-detail rule.
    pub fn level_of_detail(&self) -> LevelOfDetail {
        self.lod
    }
}

/// What filtering cost, summed over calls (for reports).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FilterStats {
    /// Footprints filtered.
    pub footprints: u64,
    /// Fragments integrated (1 for a footprint the uniform shortcut answers).
    pub fragments: u64,
    /// Tree queries (after wrap splitting) and nodes they visited.
    pub traversal: TraversalStats,
    /// Largest relative area excess of a footprint's strips (strip
    /// pipeline only).
    pub max_mismatch: f64,
    /// Sum of the footprints' relative area excess (mean = sum / footprints).
    pub sum_mismatch: f64,
    /// Largest error bound of a filtered colour, relative to full contrast
    /// (exact pipeline: [`crate::exact`]).
    pub max_error_bound: f64,
    /// Sum of the filtered colours' error bounds (mean = sum / footprints).
    pub sum_error_bound: f64,
}

impl FilterStats {
    /// Adds `other`'s counts to these.
    pub fn merge(&mut self, other: &FilterStats) {
        self.footprints += other.footprints;
        self.fragments += other.fragments;
        self.traversal.queries += other.traversal.queries;
        self.traversal.nodes_visited += other.traversal.nodes_visited;
        self.max_mismatch = self.max_mismatch.max(other.max_mismatch);
        self.sum_mismatch += other.sum_mismatch;
        self.max_error_bound = self.max_error_bound.max(other.max_error_bound);
        self.sum_error_bound += other.sum_error_bound;
    }

    /// Records one filtered colour's relative error bound.
    pub fn record_bound(&mut self, relative: f64) {
        self.max_error_bound = self.max_error_bound.max(relative);
        self.sum_error_bound += relative;
    }
}

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
}

impl Texture {
    /// A texture from its tree and wrap.
    pub fn new(tree: impl Into<Arc<QuadTree>>, wrap: Wrap) -> Texture {
        Texture {
            tree: tree.into(),
            wrap,
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

    /// The same tree with another wrap.
    pub fn with_wrap(&self, wrap: Wrap) -> Texture {
        Texture {
            tree: Arc::clone(&self.tree),
            wrap,
        }
    }

    /// The mean colour (linear, premultiplied) over `footprint` under
    /// `options` (module documentation).
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
        let unit = ConvexPolygon::rect(0.0, 0.0, 1.0, 1.0);
        let screen = match options.weighting {
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
            // reaches (a bow tie, a degenerate quad): uniform over the hull.
            None => self.integrate_region(
                &Projection::identity(),
                &ConvexPolygon::hull(&footprint.corners()),
                PixelFilter::Box,
                [0.0, 0.0],
                options,
                stats,
            ),
        };
        match result.mean() {
            Some(c) if result.weight > 0.0 => {
                stats.record_bound(result.error_bound / result.weight);
                c
            }
            _ => self.nearest_counted(footprint.centre(), &mut stats.traversal),
        }
    }

    /// The integral of the texture over screen region `region` seen through
    /// `projection` (screen → texture), weighted by `filter` centred at
    /// `centre` (pixel units), with its error bound: see [`crate::exact`].
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
        exact::integrate_region(
            &self.tree, self.wrap, projection, region, filter, centre, options, stats,
        )
    }

    /// [`Texture::filter`] over a slice, on the calling thread; `out[i]` is
    /// the colour of `footprints[i]`.
    pub fn filter_batch(&self, footprints: &[Footprint], options: &FilterOptions) -> Vec<Rgba> {
        let mut stats = FilterStats::default();
        footprints
            .iter()
            .map(|f| self.filter_counted(f, options, &mut stats))
            .collect()
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
        let cell = self.tree.finest_cell();
        let (fx, fz) = ((p[0] / cell).floor() * cell, (p[1] / cell).floor() * cell);
        match Fragment::new(fx, fz, fx + cell, fz + cell) {
            Ok(f) => {
                integrate_wrapped(&*self.tree, &f, depth, self.wrap, stats).mean_over(cell * cell)
            }
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
        let cell = self.tree.finest_cell();
        let (u, v) = (p[0] / cell - 0.5, p[1] / cell - 0.5);
        let (u0, v0) = (u.floor(), v.floor());
        let (fu, fv) = ((u - u0) as f32, (v - v0) as f32);
        let mut at =
            |i: f64, j: f64| self.nearest_counted([(i + 0.5) * cell, (j + 0.5) * cell], stats);
        let (a, b) = (at(u0, v0), at(u0 + 1.0, v0));
        let (c, d) = (at(u0, v0 + 1.0), at(u0 + 1.0, v0 + 1.0));
        a.lerp(b, fu).lerp(c.lerp(d, fu), fv)
    }
}

/// The footprint pipeline (module documentation) over any exact box
/// integral `source` (the tree, or a baseline such as a summed-area table),
/// continued by `wrap`. `uniform` is the tree the one-lookup shortcut may
/// consult (`None` to always cut strips). `None` when the footprint has no
/// area to average over (the caller picks a point lookup).
pub fn filter_footprint<T: BoxIntegral + ?Sized>(
    source: &T,
    uniform: Option<&QuadTree>,
    wrap: Wrap,
    footprint: &Footprint,
    options: &FilterOptions,
    stats: &mut FilterStats,
) -> Option<Rgba> {
    stats.footprints += 1;
    if let Some(c) = uniform.and_then(|tree| uniform_over(tree, footprint, wrap)) {
        stats.fragments += 1;
        stats.traversal.queries += 1;
        return Some(c);
    }
    let strips = footprint.strips(options.quality);
    stats.fragments += strips.rects.len() as u64;
    stats.max_mismatch = stats.max_mismatch.max(strips.mismatch);
    stats.sum_mismatch += strips.mismatch;
    let density = match options.weighting {
        Weighting::Screen => footprint.homography().filter(|h| !h.is_affine()),
        Weighting::Texture => None,
    };
    let depth = source.finest_level();
    let (mut acc, mut area) = (WeightedColour::ZERO, 0.0);
    let mut add = |f: &Fragment, w: f64, traversal: &mut TraversalStats| {
        let k = options.lod.level(f.width(), f.height(), depth);
        acc += integrate_wrapped(source, f, k, wrap, traversal) * w;
        area += f.area() * w;
    };
    // The density may vary a lot along a strip (a footprint wider than deep
    // at a grazing angle): cut it until it is nearly constant on each piece.
    let tolerance = 0.25 / options.quality;
    for f in &strips.rects {
        let Some(h) = density else {
            add(f, 1.0, &mut stats.traversal);
            continue;
        };
        let (nx, nz) = h.density_pieces(f, tolerance);
        if nx * nz > 1 {
            stats.fragments += (nx * nz - 1) as u64;
        }
        // Cut k of n along [lo, hi): exact at both ends.
        let cut = |lo: f64, hi: f64, k: usize, n: usize| {
            if k == n {
                hi
            } else {
                lo + (hi - lo) * k as f64 / n as f64
            }
        };
        for j in 0..nz {
            let (z0, z1) = (cut(f.z0(), f.z1(), j, nz), cut(f.z0(), f.z1(), j + 1, nz));
            for i in 0..nx {
                let (x0, x1) = (cut(f.x0(), f.x1(), i, nx), cut(f.x0(), f.x1(), i + 1, nx));
                let Ok(piece) = Fragment::new(x0, z0, x1, z1) else {
                    continue;
                };
                let w = h.screen_density([0.5 * (x0 + x1), 0.5 * (z0 + z1)]);
                add(&piece, w, &mut stats.traversal);
            }
        }
    }
    (area > 0.0 && area.is_finite()).then(|| acc.mean_over(area))
}

/// The colour over the whole footprint when one terminal square of the tree
/// holds the footprint's bounding box (folded into one tile by the wrap).
fn uniform_over(tree: &QuadTree, footprint: &Footprint, wrap: Wrap) -> Option<Rgba> {
    let (lo, hi) = footprint.bounds();
    uniform_colour_in(tree, lo, hi, wrap)
}

/// The colour over the box `[lo, hi]` when one terminal square of the tree
/// holds it (folded into one tile by the wrap).
pub(crate) fn uniform_colour_in(
    tree: &QuadTree,
    lo: [f64; 2],
    hi: [f64; 2],
    wrap: Wrap,
) -> Option<Rgba> {
    let (x0, x1) = fold_interval(wrap.x, lo[0], hi[0])?;
    let (z0, z1) = fold_interval(wrap.z, lo[1], hi[1])?;
    let f = Fragment::new(x0, z0, x1, z1).ok()?;
    if f.area() <= 0.0 {
        return None;
    }
    tree.uniform_colour(&f).map(|c| c.to_rgba())
}

/// `[lo, hi]` moved into `[0,1]` when it lies in one tile the wrap folds
/// there without a seam; `None` otherwise.
fn fold_interval(mode: WrapMode, lo: f64, hi: f64) -> Option<(f64, f64)> {
    let (a, b) = match mode {
        WrapMode::Repeat => {
            let t = lo.floor();
            (lo - t, hi - t)
        }
        WrapMode::Mirror => {
            let t = lo.floor();
            if t.rem_euclid(2.0) == 1.0 {
                (1.0 - (hi - t), 1.0 - (lo - t))
            } else {
                (lo - t, hi - t)
            }
        }
        WrapMode::Clamp | WrapMode::Border => (lo, hi),
    };
    (a >= 0.0 && b <= 1.0).then_some((a, b))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn level_of_detail_rule() {
        let lod = LevelOfDetail::ErrorBound(1.0 / 512.0);
        // A fragment of 1/64 on a side needs k with 4·2^-k/(1/64) ≤ 1/512 → k ≥ 6 + 11.
        assert_eq!(lod.level(1.0 / 64.0, 1.0 / 64.0, 30), 17);
        assert_eq!(lod.level(1.0 / 64.0, 1.0 / 64.0, 12), 12);
        assert_eq!(LevelOfDetail::Fixed(5).level(0.1, 0.1, 3), 3);
    }

    #[test]
    fn options_refuse_bad_values() {
        let o = FilterOptions::new();
        assert!(o.with_quality(0.5).is_err());
        assert!(o.with_quality(f64::NAN).is_err());
        assert!(o.with_error_bound(0.0).is_err());
        assert!(o.with_error_bound(f64::INFINITY).is_err());
        let e = o.with_quality(-1.0).unwrap_err().to_string();
        assert!(e.contains("quality"), "{e}");
        assert_eq!(o.with_quality(4.0).unwrap().quality(), 4.0);
    }

    #[test]
    fn mirror_intervals_fold() {
        assert_eq!(
            fold_interval(WrapMode::Mirror, 1.25, 1.5),
            Some((0.5, 0.75))
        );
        assert_eq!(
            fold_interval(WrapMode::Repeat, 1.25, 1.5),
            Some((0.25, 0.5))
        );
        assert_eq!(fold_interval(WrapMode::Repeat, 0.75, 1.25), None);
        assert_eq!(fold_interval(WrapMode::Clamp, 0.75, 1.25), None);
    }
}

//! The strip baseline: a footprint covered by axis-aligned strips
//! (fragments), each integrated by any exact box integral (the tree, or a
//! summed-area table) and weighted by the screen density at its centre.
//! The exact filter ([`crate::Texture::filter`]) replaced it; it stays for
//! baselines that can only integrate rectangles.
//!
//! **Strips.** The quadrilateral is cut into `n` strips of equal height
//! across its longer bounding-box axis; each strip becomes the rectangle
//! spanning the quadrilateral's extent inside that strip. The rectangles
//! cover the quadrilateral, so the *area mismatch* (union of rectangles minus
//! the quad, over the quad) is never negative; it is computed exactly for
//! every footprint and reported. `n` starts from the estimate
//! `(bbox − quad)/(quad·target)` and doubles until the measured mismatch
//! meets the target `1/(4·quality)`, at most [`MAX_STRIPS`]: an axis-aligned
//! footprint is one exact fragment, an anisotropic diagonal one gets more.

use crate::Error;
use crate::colour::{Rgba, WeightedColour};
use crate::filter::footprint::{Footprint, polygon_area};
use crate::filter::options::{FilterOptions, FilterStats, Weighting};
use crate::filter::wrap::{BoxIntegral, Wrap, integrate_wrapped, uniform_colour_in};
use crate::geometry::fragment::Fragment;
use crate::tree::{QuadTree, TraversalStats};

/// Most strips a footprint is cut into.
pub const MAX_STRIPS: usize = 32;

/// Most pieces a strip is cut into so the screen density is nearly
/// constant on each (the map from the pixel square onto the footprint).
pub const MAX_DENSITY_PIECES: usize = 16;

/// Options of [`filter_by_strips`]: the strip quality, and the weighting
/// and level of detail it shares with the exact filter.
///
/// Invariant (checked by [`StripOptions::with_quality`]): quality is finite
/// and `≥ 1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StripOptions {
    quality: f64,
    filter: FilterOptions,
}

impl Default for StripOptions {
    /// [`StripOptions::DEFAULT`].
    fn default() -> Self {
        StripOptions::DEFAULT
    }
}

impl StripOptions {
    /// Quality 1 (strips over-cover by at most 25 %) and
    /// [`FilterOptions::DEFAULT`].
    pub const DEFAULT: StripOptions = StripOptions {
        quality: 1.0,
        filter: FilterOptions::DEFAULT,
    };

    /// With strip quality `quality` (≥ 1; the strips' area-excess target is
    /// `1/(4·quality)`).
    pub fn with_quality(self, quality: f64) -> Result<StripOptions, Error> {
        if !(quality.is_finite() && quality >= 1.0) {
            return Err(Error::BadOption {
                name: "quality",
                value: quality,
                expected: "a finite number >= 1",
            });
        }
        Ok(StripOptions { quality, ..self })
    }

    /// With the weighting and level of detail of `filter` (its budget
    /// does not apply to strips).
    pub fn with_filter_options(self, filter: FilterOptions) -> StripOptions {
        StripOptions { filter, ..self }
    }

    /// With every strip traversed down to level `level`
    /// ([`FilterOptions::with_level`]).
    pub fn with_level(self, level: u8) -> StripOptions {
        StripOptions {
            filter: self.filter.with_level(level),
            ..self
        }
    }

    /// The strip quality.
    pub fn quality(&self) -> f64 {
        self.quality
    }

    /// The weighting and level of detail.
    pub fn filter_options(&self) -> &FilterOptions {
        &self.filter
    }
}

/// A footprint's cover by axis-aligned rectangles.
#[derive(Debug, Clone, Default)]
pub struct StripCover {
    /// The rectangles (texture space, may span tiles).
    pub rects: Vec<Fragment>,
    /// Σ rectangle areas / quad area − 1 (≥ 0; 0 for a degenerate footprint).
    pub mismatch: f64,
}

impl StripCover {
    /// The strips covering `footprint` (module documentation);
    /// `quality ≥ 1` tightens the area-mismatch target `1/(4·quality)`.
    pub fn new(footprint: &Footprint, quality: f64) -> StripCover {
        let (lo, hi) = footprint.bounds();
        strips_of_quad(&footprint.corners(), lo, hi, quality)
    }
}

/// Extent along `axis` (0 = x, 1 = z) of the convex polygon within the slab
/// `lo ≤ other-axis ≤ hi`.
fn extent_in_slab(p: &[[f64; 2]], axis: usize, lo: f64, hi: f64) -> Option<(f64, f64)> {
    let other = 1 - axis;
    let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut take = |v: f64| {
        min = min.min(v);
        max = max.max(v);
    };
    for i in 0..p.len() {
        let a = p[i];
        let b = p[(i + 1) % p.len()];
        if a[other] >= lo && a[other] <= hi {
            take(a[axis]);
        }
        for cut in [lo, hi] {
            if (a[other] - cut) * (b[other] - cut) < 0.0 {
                let t = (cut - a[other]) / (b[other] - a[other]);
                take(a[axis] + t * (b[axis] - a[axis]));
            }
        }
    }
    (min <= max).then_some((min, max))
}

fn strips_of_quad(quad: &[[f64; 2]; 4], lo: [f64; 2], hi: [f64; 2], quality: f64) -> StripCover {
    let size = [hi[0] - lo[0], hi[1] - lo[1]];
    let bbox = size[0] * size[1];
    let area = polygon_area(quad);
    // NaN-safe: anything but a finite positive area is degenerate.
    if bbox.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
        || area.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
        || !bbox.is_finite()
    {
        // Degenerate (a line or a point): its bounding box is the best we have.
        return StripCover {
            rects: Fragment::new(lo[0], lo[1], hi[0], hi[1])
                .into_iter()
                .collect(),
            mismatch: 0.0,
        };
    }
    let excess = (bbox - area) / area;
    let target = 0.25 / quality.max(1.0);
    // Strips are stacked along the longer axis, each spanning the other.
    let along = if size[1] >= size[0] { 1 } else { 0 };
    // The excess falls roughly as 1/n; start from that estimate and double
    // until the measured mismatch meets the target.
    let mut n = if excess <= target {
        1
    } else {
        ((excess / target).ceil() as usize).clamp(1, MAX_STRIPS)
    };
    loop {
        let (rects, total) = cut_strips(quad, lo, hi, size, along, n);
        let mismatch = (total / area - 1.0).max(0.0);
        if mismatch <= target || n >= MAX_STRIPS {
            return StripCover { rects, mismatch };
        }
        n = (2 * n).min(MAX_STRIPS);
    }
}

fn cut_strips(
    quad: &[[f64; 2]; 4],
    lo: [f64; 2],
    hi: [f64; 2],
    size: [f64; 2],
    along: usize,
    n: usize,
) -> (Vec<Fragment>, f64) {
    let across = 1 - along;
    let mut rects = Vec::with_capacity(n);
    let mut total = 0.0;
    for i in 0..n {
        let a = lo[along] + size[along] * i as f64 / n as f64;
        let b = if i + 1 == n {
            hi[along]
        } else {
            lo[along] + size[along] * (i + 1) as f64 / n as f64
        };
        if let Some((c0, c1)) = extent_in_slab(quad, across, a, b) {
            let r = if along == 1 {
                Fragment::new(c0, a, c1, b)
            } else {
                Fragment::new(a, c0, b, c1)
            };
            if let Ok(r) = r {
                total += r.area();
                rects.push(r);
            }
        }
    }
    (rects, total)
}

/// The strip pipeline (module documentation) over any exact box
/// integral `source` (the tree, or a baseline such as a summed-area table),
/// continued by `wrap`. `uniform` is the tree the one-lookup shortcut may
/// consult (`None` to always cut strips). `None` when the footprint has no
/// area to average over (the caller picks a point lookup).
pub fn filter_by_strips<T: BoxIntegral + ?Sized>(
    source: &T,
    uniform: Option<&QuadTree>,
    wrap: Wrap,
    footprint: &Footprint,
    options: &StripOptions,
    stats: &mut FilterStats,
) -> Option<Rgba> {
    stats.footprints += 1;
    if let Some(c) = uniform.and_then(|tree| uniform_over(tree, footprint, wrap)) {
        stats.fragments += 1;
        stats.traversal.queries += 1;
        return Some(c);
    }
    let strips = StripCover::new(footprint, options.quality());
    stats.fragments += strips.rects.len() as u64;
    stats.max_mismatch = stats.max_mismatch.max(strips.mismatch);
    stats.sum_mismatch += strips.mismatch;
    let density = match options.filter_options().weighting() {
        Weighting::Screen => footprint.square_to_quad().filter(|h| !h.is_affine()),
        Weighting::Texture => None,
    };
    let depth = source.finest_level();
    // Level units: a level-k cell is 2^-k of them (a non-square texture's
    // cells are not square in texture units).
    let [cx, cz] = source.finest_cell();
    let unit = f64::from_bits((1023 - u64::from(depth.min(60))) << 52);
    let (ux, uz) = (unit / cx, unit / cz);
    let (mut acc, mut area) = (WeightedColour::ZERO, 0.0);
    let mut add = |f: &Fragment, w: f64, traversal: &mut TraversalStats| {
        let k = options.filter_options().level_of_detail().level(
            f.width() * ux,
            f.height() * uz,
            depth,
        );
        acc += integrate_wrapped(source, f, k, wrap, traversal) * w;
        area += f.area() * w;
    };
    // The density may vary a lot along a strip (a footprint wider than deep
    // at a grazing angle): cut it until it is nearly constant on each piece.
    let tolerance = 0.25 / options.quality();
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn quad(c: [[f64; 2]; 4]) -> Footprint {
        Footprint::from_corners(c).unwrap()
    }

    #[test]
    fn axis_aligned_quad_is_one_exact_fragment() {
        let f = StripCover::new(&quad([[0.1, 0.2], [0.4, 0.2], [0.4, 0.3], [0.1, 0.3]]), 1.0);
        assert_eq!(f.rects.len(), 1);
        assert!(f.mismatch < 1e-12);
        assert_eq!(f.rects[0], Fragment::new(0.1, 0.2, 0.4, 0.3).unwrap());
    }

    #[test]
    fn diagonal_quad_mismatch_is_reported_and_bounded() {
        let q = [[0.0, 0.0], [0.02, 0.0], [1.0, 0.98], [0.98, 0.98]];
        let f = StripCover::new(&quad(q), 1.0);
        assert!(f.rects.len() > 4, "{}", f.rects.len());
        let total: f64 = f.rects.iter().map(Fragment::area).sum();
        let area = polygon_area(&q);
        assert!((f.mismatch - (total / area - 1.0)).abs() < 1e-12);
        let square = quad([[0.5, 0.0], [1.0, 0.5], [0.5, 1.0], [0.0, 0.5]]);
        let s = StripCover::new(&square, 1.0);
        assert!(s.mismatch <= 0.25 + 1e-9, "{}", s.mismatch);
        let s4 = StripCover::new(&square, 4.0);
        assert!(s4.mismatch < s.mismatch && s4.rects.len() > s.rects.len());
    }

    #[test]
    fn options_refuse_bad_quality() {
        let o = StripOptions::default();
        assert!(o.with_quality(0.5).is_err());
        assert!(o.with_quality(f64::NAN).is_err());
        let e = o.with_quality(-1.0).unwrap_err().to_string();
        assert!(e.contains("quality"), "{e}");
        assert_eq!(o.with_quality(4.0).unwrap().quality(), 4.0);
    }
}

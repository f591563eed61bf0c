//! From a pixel's footprint (a convex quadrilateral in texture space) to
//! axis-aligned fragments, and from fragments to a filtered colour with wrap
//! modes and a level-of-detail rule.
//!
//! **Strips.** The quadrilateral is cut into `n` strips of equal height across
//! its longer bounding-box axis; each strip becomes the rectangle spanning the
//! quadrilateral's extent inside that strip. The rectangles cover the
//! quadrilateral, so the *area mismatch* (union of rectangles minus the quad,
//! over the quad) is never negative; it is computed exactly for every pixel
//! and reported. `n` starts from the estimate `(bbox − quad)/(quad·target)`
//! and doubles until the measured mismatch meets the target `1/(4·quality)`,
//! at most [`MAX_STRIPS`]: an axis-aligned footprint is one exact fragment,
//! an anisotropic diagonal one gets more.
//!
//! **Level of detail.** For a fragment of sides `w × h` (texture units) the
//! traversal may stop at level `k` only where the squares it treats as whole
//! are partially covered; their area is at most `2(w+h)·2^-k`, so the mean
//! colour is off by at most `2(w+h)·2^-k/(w·h)` of the texture's contrast. The
//! rule picks the smallest `k` that makes this bound `≤ ε` (default `1/512`,
//! half an 8-bit step at full contrast), capped by the tree's depth; a fixed
//! `k` can be forced instead.

use quadtex_core::{Fragment, QuadTree, TraversalStats, WeightedColour};

use crate::scene::WrapMode;

/// Most strips a footprint is cut into.
pub const MAX_STRIPS: usize = 32;

/// A fragment list for one pixel.
#[derive(Debug, Clone, Default)]
pub struct Fragments {
    /// The rectangles (texture space, may span tiles).
    pub rects: Vec<Fragment>,
    /// Σ rectangle areas / quad area − 1 (≥ 0).
    pub mismatch: f64,
}

/// Area of a polygon by the shoelace formula (absolute value).
fn polygon_area(p: &[[f64; 2]]) -> f64 {
    let mut a = 0.0;
    for i in 0..p.len() {
        let (x0, z0) = (p[i][0], p[i][1]);
        let (x1, z1) = (p[(i + 1) % p.len()][0], p[(i + 1) % p.len()][1]);
        a += x0 * z1 - x1 * z0;
    }
    (a * 0.5).abs()
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

/// Cuts a convex quadrilateral (texture space, any vertex order around it)
/// into strips; `quality ≥ 1` tightens the mismatch target.
pub fn fragments_of_quad(quad: &[[f64; 2]; 4], quality: f64) -> Fragments {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in quad {
        for a in 0..2 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let size = [hi[0] - lo[0], hi[1] - lo[1]];
    let bbox = size[0] * size[1];
    let area = polygon_area(quad);
    // NaN-safe: anything but a finite positive area is degenerate.
    if bbox.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
        || area.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
        || !bbox.is_finite()
    {
        // Degenerate (a line or a point): its bounding box is the best we have.
        return Fragments {
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
        let (rects, total) = strips(quad, lo, hi, size, along, n);
        let mismatch = (total / area - 1.0).max(0.0);
        if mismatch <= target || n >= MAX_STRIPS {
            return Fragments { rects, mismatch };
        }
        n = (2 * n).min(MAX_STRIPS);
    }
}

fn strips(
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

/// The level-of-detail rule (module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LevelOfDetail {
    /// Smallest level whose truncation error bound is `≤ epsilon` (relative to contrast).
    ErrorBound(f64),
    /// Always this level (clamped to the tree's depth).
    Fixed(u8),
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

/// Integral of the texture over a fragment in (tiled) texture space, honouring
/// the wrap mode. `Repeat` splits the fragment at tile borders into at most
/// 3×3 pieces; whole tiles count in O(1) from the root's average, so the cost
/// does not depend on how many tiles the fragment covers.
pub fn integrate<T: BoxIntegral + ?Sized>(
    tree: &T,
    f: &Fragment,
    k: u8,
    wrap: WrapMode,
    stats: &mut TraversalStats,
) -> WeightedColour {
    match wrap {
        WrapMode::Repeat => {
            let xs = split_axis(f.x0(), f.x1());
            let zs = split_axis(f.z0(), f.z1());
            let mut acc = WeightedColour::ZERO;
            for &(xa, xb, nx) in xs.iter().flatten() {
                for &(za, zb, nz) in zs.iter().flatten() {
                    let count = nx * nz;
                    if count == 0.0 {
                        continue;
                    }
                    let piece = if xa == 0.0 && xb == 1.0 && za == 0.0 && zb == 1.0 {
                        stats.queries += 1;
                        tree.whole_tile()
                    } else {
                        match Fragment::new(xa, za, xb, zb) {
                            Ok(p) => tree.box_integral(&p, k, stats),
                            Err(_) => WeightedColour::ZERO,
                        }
                    };
                    acc += piece * count;
                }
            }
            acc
        }
        WrapMode::Border(colour) => {
            let inside = tree.box_integral(f, k, stats);
            let inside_area = f.clip_to_unit().map_or(0.0, |c| c.area());
            inside + WeightedColour::from_colour(colour, f.area() - inside_area)
        }
        WrapMode::Clamp => {
            // Each axis: the part below 0, inside, above 1. Outside parts read
            // a thin edge strip of the texture, stretched to their length.
            let edge = quadtex_core_edge(tree);
            let xs = clamp_axis(f.x0(), f.x1(), edge);
            let zs = clamp_axis(f.z0(), f.z1(), edge);
            let mut acc = WeightedColour::ZERO;
            for &(xa, xb, wx) in xs.iter().flatten() {
                for &(za, zb, wz) in zs.iter().flatten() {
                    if let Ok(p) = Fragment::new(xa, za, xb, zb) {
                        acc += tree.box_integral(&p, k, stats) * (wx * wz);
                    }
                }
            }
            acc
        }
    }
}

/// Width of the edge strip clamp mode reads: one finest square.
fn quadtex_core_edge<T: BoxIntegral + ?Sized>(tree: &T) -> f64 {
    tree.finest_cell()
}

/// An exact box filter over one tile of texture space: the quadtree, or a
/// baseline over the same fragments (the summed-area table).
pub trait BoxIntegral {
    /// Integral over the fragment's overlap with the unit square, with the
    /// traversal limited to level `k` where that means something.
    fn box_integral(&self, f: &Fragment, k: u8, stats: &mut TraversalStats) -> WeightedColour;
    /// Integral over the whole unit square.
    fn whole_tile(&self) -> WeightedColour;
    /// Side of the finest cell (the edge strip clamp mode reads).
    fn finest_cell(&self) -> f64;
}

impl BoxIntegral for QuadTree {
    fn box_integral(&self, f: &Fragment, k: u8, stats: &mut TraversalStats) -> WeightedColour {
        self.weighted_colour_counted(f, k, stats)
    }
    fn whole_tile(&self) -> WeightedColour {
        WeightedColour::from_unorm16(self.average(), 1.0)
    }
    fn finest_cell(&self) -> f64 {
        f64::from_bits((1023 - u64::from(self.depth())) << 52)
    }
}

impl BoxIntegral for quadtex_core::sat::SummedAreaTable {
    fn box_integral(&self, f: &Fragment, _k: u8, stats: &mut TraversalStats) -> WeightedColour {
        stats.queries += 1;
        self.weighted_colour(f)
    }
    fn whole_tile(&self) -> WeightedColour {
        Fragment::new(0.0, 0.0, 1.0, 1.0).map_or(WeightedColour::ZERO, |f| self.weighted_colour(&f))
    }
    fn finest_cell(&self) -> f64 {
        1.0 / self.width() as f64
    }
}

/// `[a, b)` cut at integers: up to three pieces `(lo, hi, count)` in local
/// tile coordinates: the left partial tile, the whole tiles (`[0,1)` × count),
/// the right partial tile.
fn split_axis(a: f64, b: f64) -> [Option<(f64, f64, f64)>; 3] {
    let (ta, tb) = (a.floor(), b.floor());
    if ta == tb || b == tb && tb - ta == 1.0 {
        // Within one tile (b may sit exactly on the next tile's border).
        let hi = if b == tb && tb != ta { 1.0 } else { b - ta };
        return [Some((a - ta, hi, 1.0)), None, None];
    }
    let left = Some((a - ta, 1.0, 1.0));
    let whole = tb - ta - 1.0;
    let middle = (whole > 0.0).then_some((0.0, 1.0, whole));
    let right = (b > tb).then_some((0.0, b - tb, 1.0));
    [left, middle, right]
}

/// `[a, b)` against `[0,1)` for clamp mode: `(lo, hi, weight)` pieces, where
/// outside parts map to an edge strip of width `edge` and weigh their length
/// over `edge`.
fn clamp_axis(a: f64, b: f64, edge: f64) -> [Option<(f64, f64, f64)>; 3] {
    let below = (a < 0.0).then(|| (0.0, edge, (b.min(0.0) - a) / edge));
    let inside = (b > 0.0 && a < 1.0).then(|| (a.max(0.0), b.min(1.0), 1.0));
    let above = (b > 1.0).then(|| (1.0 - edge, 1.0, (b - a.max(1.0)) / edge));
    [below, inside, above]
}

#[cfg(test)]
mod tests {
    use super::*;
    use quadtex_core::{BuildOptions, Rgba, TexelGrid};

    fn checker_tree() -> QuadTree {
        let g = TexelGrid::from_fn(8, 8, |c, r| {
            if (c + r) % 2 == 0 {
                Rgba::opaque(1.0, 1.0, 1.0)
            } else {
                Rgba::opaque(0.0, 0.0, 0.0)
            }
        })
        .unwrap();
        QuadTree::from_texels(&g, &BuildOptions::default())
            .unwrap()
            .0
    }

    #[test]
    fn axis_aligned_quad_is_one_exact_fragment() {
        let f = fragments_of_quad(&[[0.1, 0.2], [0.4, 0.2], [0.4, 0.3], [0.1, 0.3]], 1.0);
        assert_eq!(f.rects.len(), 1);
        assert!(f.mismatch < 1e-12);
        assert_eq!(f.rects[0], Fragment::new(0.1, 0.2, 0.4, 0.3).unwrap());
    }

    #[test]
    fn diagonal_quad_mismatch_is_reported_and_bounded() {
        // A thin sliver along the diagonal: anisotropic, needs many strips.
        let q = [[0.0, 0.0], [0.02, 0.0], [1.0, 0.98], [0.98, 0.98]];
        let f = fragments_of_quad(&q, 1.0);
        assert!(f.rects.len() > 4, "{}", f.rects.len());
        let total: f64 = f.rects.iter().map(Fragment::area).sum();
        let area = polygon_area(&q);
        assert!((f.mismatch - (total / area - 1.0)).abs() < 1e-12);
        // A 45° square is filled to 1/2 by its box; strips must do far better.
        let square = [[0.5, 0.0], [1.0, 0.5], [0.5, 1.0], [0.0, 0.5]];
        let s = fragments_of_quad(&square, 1.0);
        assert!(s.mismatch <= 0.25 + 1e-9, "{}", s.mismatch);
        let s4 = fragments_of_quad(&square, 4.0);
        assert!(s4.mismatch < s.mismatch && s4.rects.len() > s.rects.len());
    }

    #[test]
    fn repeat_costs_the_same_for_ten_or_a_million_tiles() {
        let tree = checker_tree();
        let mut few = TraversalStats::default();
        let mut many = TraversalStats::default();
        let small = integrate(
            &tree,
            &Fragment::new(0.3, 0.3, 3.7, 3.2).unwrap(),
            30,
            WrapMode::Repeat,
            &mut few,
        );
        let huge = integrate(
            &tree,
            &Fragment::new(0.3, 0.3, 1000.7, 1000.2).unwrap(),
            30,
            WrapMode::Repeat,
            &mut many,
        );
        assert_eq!(
            few.queries, many.queries,
            "queries must not grow with the tile count"
        );
        // Both are half white: the mean of a checkerboard.
        let mean = |w: WeightedColour, a: f64| w.0[0] / a;
        assert!((mean(small, 3.4 * 2.9) - 0.5).abs() < 0.02);
        assert!((mean(huge, 1000.4 * 999.9) - 0.5).abs() < 1e-4);
    }

    #[test]
    fn repeat_matches_summing_tile_by_tile() {
        let tree = checker_tree();
        let f = Fragment::new(-1.25, 0.6, 1.4, 2.1).unwrap();
        let mut s = TraversalStats::default();
        let fast = integrate(&tree, &f, 30, WrapMode::Repeat, &mut s);
        let mut slow = WeightedColour::ZERO;
        for tx in -2..=2 {
            for tz in -1..=3 {
                let shifted = Fragment::new(
                    f.x0() - f64::from(tx),
                    f.z0() - f64::from(tz),
                    f.x1() - f64::from(tx),
                    f.z1() - f64::from(tz),
                )
                .unwrap();
                slow += tree.weighted_colour(&shifted, 30);
            }
        }
        for ch in 0..4 {
            assert!(
                (fast.0[ch] - slow.0[ch]).abs() < 1e-9,
                "{fast:?} vs {slow:?}"
            );
        }
    }

    #[test]
    fn border_and_clamp_fill_the_outside() {
        let tree = checker_tree();
        let mut s = TraversalStats::default();
        let f = Fragment::new(1.0, 0.0, 2.0, 1.0).unwrap();
        let b = integrate(
            &tree,
            &f,
            30,
            WrapMode::Border(Rgba::opaque(0.0, 1.0, 0.0)),
            &mut s,
        );
        assert!((b.0[1] - 1.0).abs() < 1e-9 && b.0[0].abs() < 1e-9);
        // Clamp: the right edge column alternates black/white: mean 1/2.
        let c = integrate(&tree, &f, 30, WrapMode::Clamp, &mut s);
        assert!((c.0[0] - 0.5).abs() < 1e-3, "{c:?}");
    }

    #[test]
    fn level_of_detail_rule() {
        let lod = LevelOfDetail::ErrorBound(1.0 / 512.0);
        // A fragment of 1/64 on a side needs k with 4·2^-k/(1/64) ≤ 1/512 → k ≥ 6 + 11.
        assert_eq!(lod.level(1.0 / 64.0, 1.0 / 64.0, 30), 17);
        assert_eq!(lod.level(1.0 / 64.0, 1.0 / 64.0, 12), 12);
        assert_eq!(LevelOfDetail::Fixed(5).level(0.1, 0.1, 3), 3);
    }
}

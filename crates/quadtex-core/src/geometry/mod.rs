//! Small geometry shared by the packer, the tree and its leaves: square
//! sides, fill rules, winding numbers, polygon clipping and areas, in tree
//! space (`x` right, `z` up; points are `[x, z]`).

pub(crate) mod fragment;
pub(crate) mod polygon;

type Point = [f64; 2];

/// Side of a square at `level`: `2^-level`, exact.
#[inline]
pub(crate) fn unit_side(level: u8) -> f64 {
    f64::from_bits((1023 - u64::from(level)) << 52)
}

/// Which points a set of contours covers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FillRule {
    /// Points with a non-zero winding number.
    NonZero,
    /// Points with an odd winding number.
    EvenOdd,
}

impl FillRule {
    /// True when a point of winding number `winding` is inside.
    pub fn covers(self, winding: i32) -> bool {
        match self {
            FillRule::NonZero => winding != 0,
            FillRule::EvenOdd => winding & 1 != 0,
        }
    }
}

/// Winding number of closed polygon `poly` around `p` (crossings of the ray
/// to the right; half-open in `z`).
pub(crate) fn winding(poly: &[Point], p: Point) -> i32 {
    let mut w = 0;
    for i in 0..poly.len() {
        let a = poly[i];
        let b = poly[(i + 1) % poly.len()];
        if (a[1] <= p[1]) != (b[1] <= p[1]) {
            let x = a[0] + (p[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
            if x > p[0] {
                // Downward edges wind positively (counter-clockwise contours are +1).
                w += if b[1] < a[1] { 1 } else { -1 };
            }
        }
    }
    -w
}

/// Height at which segments `a–b` and `c–d` cross, if they cross properly.
pub(crate) fn crossing_height(a: Point, b: Point, c: Point, d: Point) -> Option<f64> {
    let r = [b[0] - a[0], b[1] - a[1]];
    let s = [d[0] - c[0], d[1] - c[1]];
    let denom = r[0] * s[1] - r[1] * s[0];
    if denom == 0.0 {
        return None;
    }
    let q = [c[0] - a[0], c[1] - a[1]];
    let t = (q[0] * s[1] - q[1] * s[0]) / denom;
    let u = (q[0] * r[1] - q[1] * r[0]) / denom;
    (t > 0.0 && t < 1.0 && u > 0.0 && u < 1.0).then(|| a[1] + t * r[1])
}

/// Twice-halved shoelace: positive for counter-clockwise contours.
pub(crate) fn signed_area(points: &[Point]) -> f64 {
    let n = points.len();
    let Some(&o) = points.first() else {
        return 0.0;
    };
    // Relative to a vertex: a small polygon far from the origin keeps its digits.
    let mut a = 0.0;
    for i in 0..n {
        let (p, q) = (points[i], points[(i + 1) % n]);
        a += (p[0] - o[0]) * (q[1] - o[1]) - (q[0] - o[0]) * (p[1] - o[1]);
    }
    0.5 * a
}

/// True when every edge of the closed polygon lies on the border of
/// `[x0, z0, x1, z1]`.
pub(crate) fn on_rect_border(points: &[Point], [x0, z0, x1, z1]: [f64; 4]) -> bool {
    let n = points.len();
    (0..n).all(|i| {
        let (p, q) = (points[i], points[(i + 1) % n]);
        (p[0] == x0 && q[0] == x0)
            || (p[0] == x1 && q[0] == x1)
            || (p[1] == z0 && q[1] == z0)
            || (p[1] == z1 && q[1] == z1)
    })
}

/// [`clip_to_square`] for the rectangle `[x0, z0, x1, z1]`.
pub(crate) fn clip_to_rect(
    points: &[Point],
    [x0, z0, x1, z1]: [f64; 4],
    scratch: &mut [Vec<Point>; 2],
    out: &mut Vec<Point>,
) {
    let [a, b] = scratch;
    a.clear();
    a.extend_from_slice(points);
    let planes = [
        (0usize, x0, true),
        (0, x1, false),
        (1, z0, true),
        (1, z1, false),
    ];
    for (axis, bound, keep_above) in planes {
        b.clear();
        let inside = |p: &Point| {
            if keep_above {
                p[axis] >= bound
            } else {
                p[axis] <= bound
            }
        };
        let n = a.len();
        if n == 0 {
            break;
        }
        for i in 0..n {
            let prev = a[(i + n - 1) % n];
            let cur = a[i];
            let (pin, cin) = (inside(&prev), inside(&cur));
            if pin != cin {
                let t = (bound - prev[axis]) / (cur[axis] - prev[axis]);
                let mut x = prev;
                x[axis] = bound;
                x[1 - axis] = prev[1 - axis] + t * (cur[1 - axis] - prev[1 - axis]);
                b.push(x);
            }
            if cin {
                b.push(cur);
            }
        }
        std::mem::swap(a, b);
    }
    let start = out.len();
    for p in a.iter() {
        let p = [p[0].clamp(x0, x1), p[1].clamp(z0, z1)];
        if out.len() == start || out.last() != Some(&p) {
            out.push(p);
        }
    }
    while out.len() > start + 1 && out[start] == out[out.len() - 1] {
        out.pop();
    }
}

/// A non-horizontal edge of the trapezoid sweep: `lo[1] < hi[1]`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SweepEdge {
    pub(crate) lo: Point,
    pub(crate) hi: Point,
    /// The piece (shape) whose contour it belongs to.
    pub(crate) piece: usize,
    /// Winding change when crossing the edge from left to right.
    pub(crate) step: i32,
}

impl SweepEdge {
    /// The edge `a → b` of a contour of `piece`, or `None` when horizontal.
    #[inline]
    pub(crate) fn new(a: Point, b: Point, piece: usize) -> Option<SweepEdge> {
        match a[1].total_cmp(&b[1]) {
            std::cmp::Ordering::Less => Some(SweepEdge {
                lo: a,
                hi: b,
                piece,
                step: -1,
            }),
            std::cmp::Ordering::Greater => Some(SweepEdge {
                lo: b,
                hi: a,
                piece,
                step: 1,
            }),
            std::cmp::Ordering::Equal => None,
        }
    }

    /// `x` where the edge meets height `z`.
    #[inline]
    pub(crate) fn x_at(&self, z: f64) -> f64 {
        let t = (z - self.lo[1]) / (self.hi[1] - self.lo[1]);
        self.lo[0] + t * (self.hi[0] - self.lo[0])
    }
}

/// What [`for_each_slab`] reuses between calls.
#[derive(Debug, Default)]
pub(crate) struct SlabScratch {
    heights: Vec<f64>,
    active: Vec<usize>,
    tops: Vec<f64>,
}

/// The trapezoid sweep's slabs: sorts `edges` by their lower end, finds
/// every height where an edge ends or two edges cross, and calls
/// `slab(z0, z1, edges, active)` for each slab of positive height between
/// consecutive such heights within `[z_lo, z_hi]`, `active` indexing the
/// (sorted) `edges` that span the slab (no edge ends or crosses another
/// inside it).
///
/// Only edges whose heights overlap are tested for crossings and only the
/// edges spanning a slab are handed to it (an active list, as in
/// Bentley–Ottmann without its ordering): the cost follows the edges alive
/// at once, not the square of all edges, so a square crossed by a long run
/// of short edges (a dashed stroke) sweeps in near-linear time.
///
/// The sweep's **work** is the pairs of edges tested for a crossing plus,
/// over the slabs, the edges spanning each (what `slab` is handed). It is
/// counted before any slab is swept: above `max_work`, no slab is and
/// `Err(work)` is returned; otherwise `Ok(work)`. Edges crossing at
/// thousands of heights (dashes piled on a point) make it grow as the
/// square of the edges times their count.
pub(crate) fn for_each_slab(
    edges: &mut [SweepEdge],
    z_lo: f64,
    z_hi: f64,
    scratch: &mut SlabScratch,
    max_work: u64,
    slab: impl FnMut(f64, f64, &[SweepEdge], &[usize]),
) -> Result<u64, u64> {
    let pairs = slab_heights(edges, z_lo, z_hi, scratch);
    let work = pairs.saturating_add(slab_work(edges, scratch));
    if work > max_work {
        return Err(work);
    }
    for_each_prepared_slab(edges, scratch, slab);
    Ok(work)
}

/// The first half of [`for_each_slab`]: sorts `edges` and finds the
/// heights; returns the pairs of edges tested for a crossing.
fn slab_heights(edges: &mut [SweepEdge], z_lo: f64, z_hi: f64, scratch: &mut SlabScratch) -> u64 {
    let SlabScratch {
        heights, active, ..
    } = scratch;
    edges.sort_unstable_by(|a, b| a.lo[1].total_cmp(&b.lo[1]));
    heights.clear();
    heights.extend([z_lo, z_hi]);
    active.clear();
    let mut pairs = 0u64;
    for (i, e) in edges.iter().enumerate() {
        heights.push(e.lo[1]);
        heights.push(e.hi[1]);
        // Edges that ended at or below this one's start cannot cross it.
        active.retain(|&k| edges[k].hi[1] > e.lo[1]);
        pairs += active.len() as u64;
        for &k in active.iter() {
            let f = &edges[k];
            if let Some(z) = crossing_height(f.lo, f.hi, e.lo, e.hi) {
                heights.push(z);
            }
        }
        active.push(i);
    }
    heights.retain(|z| *z >= z_lo && *z <= z_hi);
    heights.sort_by(f64::total_cmp);
    heights.dedup();
    pairs
}

/// Over the slabs [`slab_heights`] left, the edges spanning each: those
/// starting below the slab's middle less those ending there or below
/// (edges are sorted by their lower ends, their tops are sorted here).
fn slab_work(edges: &[SweepEdge], scratch: &mut SlabScratch) -> u64 {
    let SlabScratch { heights, tops, .. } = scratch;
    tops.clear();
    tops.extend(edges.iter().map(|e| e.hi[1]));
    tops.sort_unstable_by(f64::total_cmp);
    let (mut started, mut ended, mut work) = (0usize, 0usize, 0u64);
    for w in heights.windows(2) {
        if w[1] - w[0] <= 0.0 {
            continue;
        }
        let zm = 0.5 * (w[0] + w[1]);
        while started < edges.len() && edges[started].lo[1] < zm {
            started += 1;
        }
        while ended < tops.len() && tops[ended] <= zm {
            ended += 1;
        }
        work += started.saturating_sub(ended) as u64;
    }
    work
}

/// The second half of [`for_each_slab`], on what [`slab_heights`] left.
fn for_each_prepared_slab(
    edges: &[SweepEdge],
    scratch: &mut SlabScratch,
    mut slab: impl FnMut(f64, f64, &[SweepEdge], &[usize]),
) {
    let SlabScratch {
        heights, active, ..
    } = scratch;
    active.clear();
    let mut next = 0;
    for w in heights.windows(2) {
        let (z0, z1) = (w[0], w[1]);
        if z1 - z0 <= 0.0 {
            continue;
        }
        let zm = 0.5 * (z0 + z1);
        while next < edges.len() && edges[next].lo[1] < zm {
            active.push(next);
            next += 1;
        }
        active.retain(|&k| edges[k].hi[1] > zm);
        slab(z0, z1, edges, active);
    }
}

#[cfg(test)]
mod tests {
    use super::{SlabScratch, SweepEdge, for_each_slab};

    #[test]
    fn the_counted_work_is_the_pairs_tested_plus_the_edges_each_slab_is_handed() {
        // A deterministic scatter of edges, some crossing, some stacked.
        let mut next = crate::test_rng::uniform(12345);
        for n in [0, 1, 2, 7, 40, 200] {
            let mut edges: Vec<SweepEdge> = (0..n)
                .filter_map(|i| SweepEdge::new([next(), next()], [next(), next()], i))
                .collect();
            let mut handed = 0u64;
            let mut scratch = SlabScratch::default();
            let work = for_each_slab(
                &mut edges,
                0.0,
                1.0,
                &mut scratch,
                u64::MAX,
                |_, _, _, a| {
                    handed += a.len() as u64;
                },
            )
            .unwrap();
            // Pairs whose heights overlap, counted the obvious way.
            let mut pairs = 0u64;
            for (i, e) in edges.iter().enumerate() {
                pairs += edges[..i].iter().filter(|f| f.hi[1] > e.lo[1]).count() as u64;
            }
            assert_eq!(work, pairs + handed, "{n} edges");
            // A budget one short refuses without sweeping.
            if work > 0 {
                let mut called = false;
                let refused = for_each_slab(
                    &mut edges,
                    0.0,
                    1.0,
                    &mut scratch,
                    work - 1,
                    |_, _, _, _| {
                        called = true;
                    },
                );
                assert_eq!(refused, Err(work));
                assert!(!called);
            }
        }
    }
}

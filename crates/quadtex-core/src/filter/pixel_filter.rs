//! Pixel reconstruction filters ([`PixelFilter`]): weights, supports and
//! their exact integrals over convex polygons.

use crate::geometry::polygon::{ConvexPolygon, Cubic, GAUSS4};

/// How near the side of a tent's or Mitchell's support an edge is taken
/// as on it, in pixels: a region's vertices on the support's sides come
/// back from texture space a rounding off them, and an edge along a side
/// then adds (by [`PixelFilter::edge_integral`]'s terms) at most
/// `ON_SIDE²` times its length (`k₁` vanishes at `±r`, the tent's
/// linearly, Mitchell's quadratically; `K₁` is within `ON_SIDE²` of 0 and
/// 1 there): 10⁻¹⁸, below the rounding of the weight, against a search
/// of the filter's cells for such an edge.
const ON_SIDE: f64 = 1e-9;

/// 2-point Gauss–Legendre nodes and weights on `[0, 1]`: exact for
/// polynomials of degree ≤ 3 (the tent's `K₁·k₁` along a line).
pub(super) const GAUSS2: [(f64, f64); 2] = [
    (0.211_324_865_405_187_1, 0.5),
    (0.788_675_134_594_812_9, 0.5),
];

/// The tent's or Mitchell's pieces, cell by cell of its support (index
/// `i + r` for the cell `[i, i + 1)`): `k₁`'s cubic, its antiderivative
/// ([`integrated`]) and the constant that makes that `K₁` there, `K₁(x) =
/// base + at(anti, x)`. Computed when compiled, by the same float steps
/// as at run time.
struct FilterCells {
    piece: [Cubic; 4],
    anti: [Cubic; 4],
    base: [f64; 4],
}

impl FilterCells {
    const fn of(filter: PixelFilter) -> FilterCells {
        let r = match filter {
            PixelFilter::Mitchell => 2,
            _ => 1,
        };
        let running = filter.running_integrals();
        let mut cells = FilterCells {
            piece: [[0.0; 4]; 4],
            anti: [[0.0; 4]; 4],
            base: [0.0; 4],
        };
        let mut k = 0;
        while k < 2 * r {
            let i = k as i32 - r as i32;
            let piece = filter.cubic(i);
            let anti = integrated(piece);
            cells.piece[k] = piece;
            cells.anti[k] = anti;
            cells.base[k] = running[k] - at(&anti, i as f64);
            k += 1;
        }
        cells
    }
}

const TENT_CELLS: FilterCells = FilterCells::of(PixelFilter::Tent);
const MITCHELL_CELLS: FilterCells = FilterCells::of(PixelFilter::Mitchell);

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

    /// `K₁(x) = ∫ k₁` from the support's left side to `x` (pixels from
    /// the centre): 0 left of the support, 1 right of it. The filter's
    /// integral over an axis-aligned rectangle is the product of two
    /// differences of it.
    #[inline]
    pub fn cumulative(self, x: f64) -> f64 {
        let r = self.radius();
        if x <= -r {
            return 0.0;
        }
        if x >= r {
            return 1.0;
        }
        if self == PixelFilter::Box {
            return x + 0.5;
        }
        let i = x.floor();
        let a = integrated(self.cubic(i as i32));
        self.running_integrals()[(i + r) as usize] + at(&a, x) - at(&a, i)
    }

    /// The largest `|k(s − centre)|` over the screen box `(lo, hi)`: the
    /// largest `|k₁|` over each axis's interval, multiplied (0 where the
    /// box misses the support). `|k₁|` is monotone between `0`, the
    /// Mitchell lobes' extremes at `±10/7` and the support's edges, so
    /// those points and the interval's ends are where it peaks.
    pub fn largest_weight_in(self, (lo, hi): ([f64; 2], [f64; 2]), centre: [f64; 2]) -> f64 {
        let r = self.radius();
        // Mitchell's negative lobes peak at ±10/7.
        const LOBE: f64 = 10.0 / 7.0;
        let largest = |a: f64, b: f64| {
            let (a, b) = (a.max(-r), b.min(r));
            if a.is_nan() || b.is_nan() || a > b {
                return 0.0;
            }
            if a <= 0.0 && 0.0 <= b {
                return self.k1(0.0).abs();
            }
            // `k₁` is even: the interval's side, from its end nearer the
            // centre to the farther. At the support's edge the box's own
            // k₁ is 0 but a point just inside takes the limit.
            let (near, far) = if b < 0.0 { (-b, -a) } else { (a, b) };
            let at = |x: f64| self.k1(x.min(r * (1.0 - 1e-12))).abs();
            let ends = at(near).max(at(far));
            if self == PixelFilter::Mitchell && near <= LOBE && LOBE <= far {
                ends.max(at(LOBE))
            } else {
                ends
            }
        };
        largest(lo[0] - centre[0], hi[0] - centre[0])
            * largest(lo[1] - centre[1], hi[1] - centre[1])
    }

    /// The filter's support around `centre`.
    #[inline]
    pub fn support(self, centre: [f64; 2]) -> ConvexPolygon {
        let r = self.radius();
        ConvexPolygon::rect(centre[0] - r, centre[1] - r, centre[0] + r, centre[1] + r)
    }

    /// Largest `|k|`.
    pub(super) fn k_max(self) -> f64 {
        match self {
            PixelFilter::Box | PixelFilter::Tent => 1.0,
            PixelFilter::Mitchell => (8.0 / 9.0) * (8.0 / 9.0),
        }
    }

    /// What a region's error bound is relative to, so that a pixel's
    /// regions together keep its colour within the bound asked for: the
    /// box's is the region's area (its weight); a tent's or Mitchell's is
    /// `|∫k|` over the region, far less than its area times the peak (a
    /// whole Mitchell support weighs 1 where 16 pixels at the peak make
    /// 12.6). Mitchell's is divided by its `∫|k|` over the support,
    /// `(1 + 1/18)²` (each negative lobe adds `1/36` to `∫|k₁|`), so that
    /// the regions' shares add up to at most the support's weight however
    /// its lobes are split among them. `area` is the region's.
    pub(super) fn weight_scale(self, region: &ConvexPolygon, area: f64, centre: [f64; 2]) -> f64 {
        match self {
            PixelFilter::Box => area,
            PixelFilter::Tent => self.integral(region, centre).abs(),
            PixelFilter::Mitchell => {
                const LOBES: f64 = (1.0 + 1.0 / 18.0) * (1.0 + 1.0 / 18.0);
                self.integral(region, centre).abs() / LOBES
            }
        }
    }

    /// A bound on `|∇k|` (0 for the box, constant on its support).
    pub(super) fn lipschitz(self) -> f64 {
        match self {
            PixelFilter::Box => 0.0,
            PixelFilter::Tent => std::f64::consts::SQRT_2,
            // max|k₁'| = 8/7 (at x = 4/7) times max|k₁| = 8/9, per axis.
            PixelFilter::Mitchell => std::f64::consts::SQRT_2 * (8.0 / 7.0) * (8.0 / 9.0),
        }
    }

    /// `k₁` on the unit cell `[i, i+1)` as a cubic in `x`.
    pub(super) const fn cubic(self, i: i32) -> Cubic {
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
    /// exactly: Green's theorem, `∮ K₁(x)·k₁(y) dy` with `K₁` the running
    /// integral of `k₁` from the support's left edge (continuous, so the
    /// theorem holds across the filter's cells), each edge split where it
    /// crosses a cell's side and each part integrated by 4-point
    /// Gauss–Legendre (degree at most 4 + 3: exact up to rounding). No
    /// clipping: [`PixelFilter::integral_by_cells`], which clips `p` to each
    /// cell, is the slower reference the tests hold it to.
    pub fn integral(self, p: &ConvexPolygon, centre: [f64; 2]) -> f64 {
        if self == PixelFilter::Box {
            return p.area();
        }
        let v = p.vertices();
        let n = v.len();
        if n < 3 {
            return 0.0;
        }
        let mut total = 0.0;
        let mut a = [v[n - 1][0] - centre[0], v[n - 1][1] - centre[1]];
        for &b in v {
            let b = [b[0] - centre[0], b[1] - centre[1]];
            total += self.edge_integral(a, b);
            a = b;
        }
        p.signed_area().signum() * total
    }

    /// One edge's term of [`PixelFilter::integral`]'s Green's theorem,
    /// `∫ K₁(x)·k₁(y) dy` from `a` to `b` (screen points relative to the
    /// filter's centre): over a closed polygon the terms sum to its weight
    /// times its orientation's sign. The box's is `x dy` (the shoelace's
    /// half), so that every filter shares it.
    pub(crate) fn edge_integral(self, a: [f64; 2], b: [f64; 2]) -> f64 {
        match self {
            // K₁(x) = x + ½ and k₁(y) = 1 inside the support: the
            // polygon's area, clipped by no support (as `integral`'s box).
            PixelFilter::Box => 0.5 * (a[0] + b[0]) * (b[1] - a[1]),
            PixelFilter::Tent => Self::edge_integral_of::<false>(a, b),
            PixelFilter::Mitchell => Self::edge_integral_of::<true>(a, b),
        }
    }

    /// [`PixelFilter::edge_integral`] of the tent (`MITCHELL` false) or
    /// Mitchell's filter, compiled for each so that its cubics, radius
    /// and Gauss points are constants.
    #[inline(always)]
    fn edge_integral_of<const MITCHELL: bool>(a: [f64; 2], b: [f64; 2]) -> f64 {
        let this = if MITCHELL {
            PixelFilter::Mitchell
        } else {
            PixelFilter::Tent
        };
        let r = this.radius();
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        // Gauss–Legendre points enough for `K₁·k₁` along a line: the
        // tent's is a cubic (2 points), Mitchell's of degree 7 (4 points).
        let points: &[(f64, f64)] = if !MITCHELL { &GAUSS2 } else { &GAUSS4 };
        // K₁(x)·k₁(y) on the cells holding (x, y) (relative to the centre).
        // K₁ at `x`, 0 left of the support and 1 right of it.
        let running_at = |x: f64| this.cumulative(x);
        let part_integral = |a: [f64; 2], d: [f64; 2], t0: f64, span: f64| {
            this.part_integral(points, (a, d), t0, span)
        };
        let mut total = 0.0;
        // Horizontal edges add nothing; so do edges wholly above or
        // below the support, or left of it (`K₁ = 0`). Right of it
        // `K₁ = 1`: the edge adds `K₁(y_b) − K₁(y_a)`, in closed form.
        let (inner, outer) = (r - ON_SIDE, -r + ON_SIDE);
        let outside = dy == 0.0
            || a[1].max(b[1]) <= outer
            || a[1].min(b[1]) >= inner
            || a[0].max(b[0]) <= outer;
        if !outside && a[0].min(b[0]) >= inner {
            total += running_at(b[1]) - running_at(a[1]);
        } else if !outside && a[0].floor() == b[0].floor() && a[1].floor() == b[1].floor() {
            // Within one cell: no side to cut at (what the search below
            // would find), one part.
            total += part_integral(a, [dx, dy], 0.0, 1.0) * dy;
        } else if !outside {
            // Where the edge crosses the cells' sides, as parameters in (0, 1).
            let mut cuts = [0.0f64; 12];
            let mut count = 0;
            let mut cross = |from: f64, d: f64| {
                if d == 0.0 {
                    return;
                }
                let (lo, hi) = (from.min(from + d), from.max(from + d));
                let mut k = (lo.max(-r)).floor();
                while k <= hi.min(r) && count < cuts.len() {
                    let t = (k - from) / d;
                    if t > 0.0 && t < 1.0 {
                        cuts[count] = t;
                        count += 1;
                    }
                    k += 1.0;
                }
            };
            cross(a[0], dx);
            cross(a[1], dy);
            let cuts = &mut cuts[..count];
            cuts.sort_unstable_by(f64::total_cmp);
            let mut t0 = 0.0;
            for t1 in cuts.iter().copied().chain([1.0]) {
                let span = t1 - t0;
                if span > 0.0 {
                    total += part_integral(a, [dx, dy], t0, span) * dy;
                }
                t0 = t1;
            }
        }
        total
    }

    /// `∫ K₁(x)·k₁(y) dt` over one part of an edge, `x` and `y` affine in
    /// `t` (`a + t·d`, relative to the centre), the part inside one cell
    /// (its cubics fetched once, from the part's middle), by the
    /// Gauss–Legendre `points`, the cell's pieces from [`FilterCells`].
    #[inline(always)]
    fn part_integral(
        self,
        points: &[(f64, f64)],
        (a, d): ([f64; 2], [f64; 2]),
        t0: f64,
        span: f64,
    ) -> f64 {
        let r = self.radius();
        let middle = t0 + 0.5 * span;
        let (xm, ym) = (a[0] + middle * d[0], a[1] + middle * d[1]);
        if ym <= -r || ym >= r {
            return 0.0;
        }
        let cells = if self == PixelFilter::Mitchell {
            &MITCHELL_CELLS
        } else {
            &TENT_CELLS
        };
        // K₁(x) = base + (anti(x) when inside the support).
        let (inside, base, cx) = if xm <= -r {
            (false, 0.0, [0.0; 4])
        } else if xm >= r {
            (false, 1.0, [0.0; 4])
        } else {
            let k = (xm.floor() + r) as usize;
            (true, cells.base[k], cells.anti[k])
        };
        let cy = cells.piece[(ym.floor() + r) as usize];
        let mut sum = 0.0;
        for &(g, w) in points {
            let t = t0 + g * span;
            let (x, y) = (a[0] + t * d[0], a[1] + t * d[1]);
            let big = if inside { base + at(&cx, x) } else { base };
            sum += w * big * (cy[0] + y * (cy[1] + y * (cy[2] + y * cy[3])));
        }
        sum * span
    }

    /// `K₁` at the left side of each of the filter's cells, from the
    /// support's left edge (`[k]` at `x = k − r`): the tent's halves;
    /// Mitchell's outer cells each integrate to `−1/72`, so its inner ones
    /// to `1/2 + 1/72` (checked against the cubics in the tests).
    const fn running_integrals(self) -> [f64; 4] {
        match self {
            PixelFilter::Mitchell => [0.0, -1.0 / 72.0, 0.5, 1.0 + 1.0 / 72.0],
            _ => [0.0, 0.5, 1.0, 1.0],
        }
    }

    /// `∫∫ k(s − centre) ds` over `p` as [`PixelFilter::integral`] gives
    /// it, computed by clipping `p` to each unit cell of the filter and
    /// integrating the cell's bicubic there: the reference for the tests.
    #[cfg(test)]
    pub(crate) fn integral_by_cells(self, p: &ConvexPolygon, centre: [f64; 2]) -> f64 {
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
                    total += crate::geometry::polygon::separable_integral(
                        cell.vertices(),
                        &self.cubic(i),
                        &self.cubic(j),
                    );
                }
            }
        }
        sign * total
    }
}

/// The coefficients of cubic `c`'s antiderivative vanishing at 0, as
/// [`at`] reads them: `x·(a₀ + a₁x + a₂x² + a₃x³)`.
#[inline]
pub(super) const fn integrated(c: Cubic) -> Cubic {
    [c[0], c[1] / 2.0, c[2] / 3.0, c[3] / 4.0]
}

/// `x·(a₀ + a₁x + a₂x² + a₃x³)`: an [`integrated`] cubic at `x`.
#[inline]
pub(super) const fn at(a: &Cubic, x: f64) -> f64 {
    x * (a[0] + x * (a[1] + x * (a[2] + x * a[3])))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The clip-free integral agrees with the by-cells reference on random
    /// convex polygons: inside the support, across its cells and sides,
    /// wholly outside it, tiny and huge, either orientation, and the
    /// support itself (where it is 1).
    #[test]
    fn the_integral_matches_the_by_cells_reference() {
        let mut next = crate::test_rng::uniform(64);
        let mut across = 0;
        for filter in [PixelFilter::Tent, PixelFilter::Mitchell] {
            let support = filter.support([3.5, -2.5]);
            let whole = filter.integral(&support, [3.5, -2.5]);
            assert!((whole - 1.0).abs() < 1e-12, "{filter:?}: {whole}");
            for case in 0..20_000 {
                let centre = [next() * 10.0 - 5.0, next() * 10.0 - 5.0];
                let scale = [0.01, 0.3, 1.0, 3.0, 10.0][case % 5];
                let middle = [
                    centre[0] + (next() - 0.5) * 3.0 * filter.radius(),
                    centre[1] + (next() - 0.5) * 3.0 * filter.radius(),
                ];
                let mut points = Vec::new();
                for _ in 0..3 + case % 6 {
                    points.push([
                        middle[0] + (next() - 0.5) * scale,
                        middle[1] + (next() - 0.5) * scale,
                    ]);
                }
                let mut polygon = ConvexPolygon::hull(&points);
                if case % 2 == 1 && !polygon.is_empty() {
                    // The other orientation.
                    let mut v = polygon.vertices().to_vec();
                    v.reverse();
                    polygon = ConvexPolygon::new(&v).unwrap_or(polygon);
                }
                let (fast, slow) = (
                    filter.integral(&polygon, centre),
                    filter.integral_by_cells(&polygon, centre),
                );
                assert!(
                    (fast - slow).abs() <= 1e-12 * (1.0 + polygon.area()),
                    "{filter:?}, case {case}: {fast} against {slow}"
                );
                // Polygons with weight on more than one cell of the filter.
                if slow.abs() > 1e-3 && polygon.area() > 1.0 {
                    across += 1;
                }
            }
        }
        assert!(across > 1000, "only {across} polygons across cells");
    }

    /// The running integrals at the cells' left sides are the cubics'.
    #[test]
    fn the_largest_weight_in_a_box_bounds_every_point_in_it() {
        let mut seed = 0x1234_5678_9abc_def1_u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for filter in [PixelFilter::Box, PixelFilter::Tent, PixelFilter::Mitchell] {
            assert_eq!(
                filter.largest_weight_in(([-0.1, -0.1], [0.1, 0.1]), [0.0; 2]),
                filter.k_max()
            );
            for _ in 0..2000 {
                let (x, y) = (5.0 * next() - 2.5, 5.0 * next() - 2.5);
                let (w, h) = (next(), next());
                let bound = filter.largest_weight_in(([x, y], [x + w, y + h]), [0.0; 2]);
                let mut seen = 0f64;
                for i in 0..=20 {
                    for j in 0..=20 {
                        let (px, py) = (x + w * f64::from(i) / 20.0, y + h * f64::from(j) / 20.0);
                        seen = seen.max(filter.weight(px, py).abs());
                    }
                }
                assert!(
                    seen <= bound + 1e-12,
                    "{filter:?} at {x} {y} {w} {h}: {seen} > {bound}"
                );
                // Tight: within what the 21 × 21 grid may miss.
                assert!(
                    bound <= seen + 0.15 * filter.k_max() * (w + h),
                    "{filter:?}: {bound} vs {seen}"
                );
            }
        }
    }

    /// The filter's integral over a rectangle is the product of the
    /// differences of `K₁` across it, for rectangles in, across and
    /// outside the support (the box's inside it).
    #[test]
    fn rectangles_weigh_the_product_of_cumulatives() {
        let mut next = crate::test_rng::uniform(59);
        for filter in [PixelFilter::Box, PixelFilter::Tent, PixelFilter::Mitchell] {
            // The box's `integral` is the area (its callers clip to the
            // support first): its rectangles inside the support.
            let (reach, size) = if filter == PixelFilter::Box {
                (0.5, 0.5)
            } else {
                (3.0, 3.0)
            };
            for _ in 0..2000 {
                let (x0, y0) = (next() * 2.0 * reach - reach, next() * 2.0 * reach - reach);
                let (x1, y1) = (
                    (x0 + next() * size).min(reach),
                    (y0 + next() * size).min(reach),
                );
                let rect = ConvexPolygon::new(&[[x0, y0], [x1, y0], [x1, y1], [x0, y1]]).unwrap();
                let by_green = filter.integral(&rect, [0.0; 2]);
                let product = (filter.cumulative(x1) - filter.cumulative(x0))
                    * (filter.cumulative(y1) - filter.cumulative(y0));
                assert!(
                    (by_green - product).abs() < 1e-12,
                    "{filter:?} [{x0}, {x1}] × [{y0}, {y1}]: {by_green} against {product}"
                );
            }
        }
    }

    #[test]
    fn running_integrals_are_the_cubics() {
        for filter in [PixelFilter::Tent, PixelFilter::Mitchell] {
            let r = filter.radius();
            let mut sum = 0.0;
            for (k, &stated) in filter.running_integrals().iter().enumerate() {
                assert!(
                    (stated - sum).abs() < 1e-15,
                    "{filter:?} cell {k}: {stated} against {sum}"
                );
                let i = k as f64 - r;
                if i < r {
                    let a = integrated(filter.cubic(i as i32));
                    sum += at(&a, i + 1.0) - at(&a, i);
                }
            }
        }
    }
}

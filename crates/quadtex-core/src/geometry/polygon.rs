//! Small convex polygons in the plane: clipping by half-planes
//! (Sutherland–Hodgman), area, and the exact integral of a separable
//! piecewise-polynomial weight over them (Green's theorem).
//!
//! Polygons live on the stack (at most [`MAX_VERTICES`] vertices): the exact
//! pixel integral clips one per visited square. Coordinates are `f64` in
//! whatever plane the caller works in (screen pixels, texture units).

use arrayvec::ArrayVec;

use crate::Error;

/// Most vertices a [`ConvexPolygon`] holds. A convex polygon clipped by a
/// half-plane gains at most one vertex; a pixel region clipped by a tree
/// square, then by a filter's cell, stays far below this.
pub const MAX_VERTICES: usize = 16;

/// A convex polygon, vertices in counter-clockwise order (positive
/// shoelace area in its own coordinates: with `y` down on the screen this
/// is clockwise as seen on the screen, which does not matter here).
///
/// Invariants (checked by [`ConvexPolygon::new`]): finite coordinates, at
/// most [`MAX_VERTICES`] vertices, convex. Fewer than three vertices, or
/// collinear ones, make an empty polygon of zero area.
#[derive(Debug, PartialEq)]
pub struct ConvexPolygon {
    v: ArrayVec<[f64; 2], MAX_VERTICES>,
}

impl Clone for ConvexPolygon {
    fn clone(&self) -> Self {
        ConvexPolygon { v: self.v.clone() }
    }

    /// Copies the vertices alone, not the whole capacity.
    fn clone_from(&mut self, source: &Self) {
        self.v.clone_from(&source.v);
    }
}

/// Whether `a` and `b` are within `tolerance` of each other on both axes.
#[inline]
fn within(a: [f64; 2], b: [f64; 2], tolerance: f64) -> bool {
    (a[0] - b[0]).abs() <= tolerance && (a[1] - b[1]).abs() <= tolerance
}

impl Default for ConvexPolygon {
    fn default() -> Self {
        ConvexPolygon::empty()
    }
}

impl ConvexPolygon {
    /// No vertices.
    pub const EMPTY: ConvexPolygon = ConvexPolygon {
        v: ArrayVec::new_const(),
    };

    /// No vertices, as [`ConvexPolygon::EMPTY`], built where it is needed:
    /// the constant is its whole capacity written (a memset per use), this
    /// only its length.
    #[inline(always)]
    pub fn empty() -> ConvexPolygon {
        ConvexPolygon { v: ArrayVec::new() }
    }

    /// A convex polygon from its vertices in either orientation.
    /// [`Error::NonFiniteCoordinate`] names a NaN or infinite coordinate
    /// (`vertex[i].x`); [`Error::BadPolygon`] a polygon with too many
    /// vertices or one that is not convex.
    pub fn new(vertices: &[[f64; 2]]) -> Result<ConvexPolygon, Error> {
        if vertices.len() > MAX_VERTICES {
            return Err(Error::BadPolygon(format!(
                "{} vertices, at most {MAX_VERTICES}",
                vertices.len()
            )));
        }
        for (i, p) in vertices.iter().enumerate() {
            for (a, &value) in p.iter().enumerate() {
                if !value.is_finite() {
                    let axis = if a == 0 { 'x' } else { 'y' };
                    return Err(Error::BadPolygon(format!(
                        "vertex[{i}].{axis} is {value}, not a finite number"
                    )));
                }
            }
        }
        let mut p = ConvexPolygon::empty();
        p.v.extend(vertices.iter().copied());
        if p.signed_area() < 0.0 {
            p.v.reverse();
        }
        if !p.is_convex() {
            return Err(Error::BadPolygon("the polygon is not convex".into()));
        }
        Ok(p)
    }

    /// The axis-aligned rectangle `[x0, x1] × [y0, y1]` (empty if reversed).
    #[inline]
    pub fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> ConvexPolygon {
        if !(x0 < x1 && y0 < y1) {
            return ConvexPolygon::empty();
        }
        let mut p = ConvexPolygon::empty();
        p.v.extend([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]);
        p
    }

    /// Vertices from a trusted source (already convex, finite), made
    /// counter-clockwise.
    pub(crate) fn from_trusted(vertices: &[[f64; 2]]) -> ConvexPolygon {
        let mut p = ConvexPolygon::empty();
        p.v.extend(vertices.iter().take(MAX_VERTICES).copied());
        if p.signed_area() < 0.0 {
            p.v.reverse();
        }
        p
    }

    /// The vertices.
    #[inline]
    pub fn vertices(&self) -> &[[f64; 2]] {
        &self.v
    }

    /// True with fewer than three vertices.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.v.len() < 3
    }

    /// Shoelace area, signed (positive for counter-clockwise).
    #[inline]
    pub fn signed_area(&self) -> f64 {
        signed_area(self.vertices())
    }

    /// Area (`≥ 0`).
    #[inline]
    pub fn area(&self) -> f64 {
        self.signed_area().abs()
    }

    /// The centroid (the vertices' mean for a degenerate polygon).
    #[inline]
    pub fn centroid(&self) -> [f64; 2] {
        let v = self.vertices();
        let n = v.len();
        if n == 0 {
            return [0.0, 0.0];
        }
        let o = v[0];
        let (mut cx, mut cy, mut a2) = (0.0, 0.0, 0.0);
        for i in 1..n.saturating_sub(1) {
            let (p, q) = (
                [v[i][0] - o[0], v[i][1] - o[1]],
                [v[i + 1][0] - o[0], v[i + 1][1] - o[1]],
            );
            let cross = p[0] * q[1] - q[0] * p[1];
            a2 += cross;
            cx += cross * (p[0] + q[0]);
            cy += cross * (p[1] + q[1]);
        }
        if a2 == 0.0 {
            let m = v.iter().fold([0.0, 0.0], |m, p| [m[0] + p[0], m[1] + p[1]]);
            return [m[0] / n as f64, m[1] / n as f64];
        }
        [o[0] + cx / (3.0 * a2), o[1] + cy / (3.0 * a2)]
    }

    /// The parts of this polygon outside convex polygon `other`, as convex
    /// pieces (at most one per edge of `other`).
    pub fn subtract(&self, other: &ConvexPolygon, out: impl FnMut(ConvexPolygon)) {
        self.split_by(other, out);
    }

    /// The part inside convex polygon `other` (what
    /// [`ConvexPolygon::intersect`] returns, vertex for vertex), having
    /// given the parts outside it to `out` (what
    /// [`ConvexPolygon::subtract`] gives, in the same order): one pass over
    /// `other`'s edges for both. `other` empty: all of this polygon is
    /// outside, nothing inside.
    pub fn split_by(
        &self,
        other: &ConvexPolygon,
        mut out: impl FnMut(ConvexPolygon),
    ) -> ConvexPolygon {
        if other.is_empty() {
            out(self.clone());
            return ConvexPolygon::empty();
        }
        // What is left inside every edge so far, ping-ponged between two
        // buffers (none before the first line: this polygon, not copied);
        // each edge splits it in one pass.
        let mut rest = [ConvexPolygon::empty(), ConvexPolygon::empty()];
        let mut current: Option<usize> = None;
        let mut outside = ConvexPolygon::empty();
        for [a, b, c] in other.edge_lines() {
            // No line (a repeated vertex): keeps everything, as a clip by
            // `0 ≥ 0` would; cutting by it would give the inside out too.
            if a == 0.0 && b == 0.0 {
                continue;
            }
            // Every vertex strictly inside: the split would copy them all to
            // the inside and leave nothing outside (no vertex on the line,
            // no crossing), so the line is passed over.
            let kept = match current {
                None => self,
                Some(i) => &rest[i],
            };
            if (kept.vertices().iter()).all(|&[x, y]| a * x + b * y + c > 0.0) {
                continue;
            }
            let [first, second] = &mut rest;
            let (from, to) = match current {
                None => (self, first),
                Some(0) => (&*first, second),
                Some(_) => (&*second, first),
            };
            from.split_into(a, b, c, to, &mut outside);
            let now = current.map_or(0, |c| c ^ 1);
            current = Some(now);
            if outside.area() > 0.0 {
                out(outside.clone());
            }
            if rest[now].is_empty() {
                return ConvexPolygon::empty();
            }
        }
        let [first, second] = rest;
        match current {
            None => self.clone(),
            Some(0) => first,
            Some(_) => second,
        }
    }

    /// Sum of the edge lengths.
    pub fn perimeter(&self) -> f64 {
        let v = self.vertices();
        (0..v.len())
            .map(|i| {
                let (a, b) = (v[i], v[(i + 1) % v.len()]);
                let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
                (dx * dx + dy * dy).sqrt()
            })
            .sum()
    }

    /// Lower-left and upper-right corners of the bounding box (NaN
    /// coordinates skipped; empty: `([∞, ∞], [−∞, −∞])`).
    #[inline]
    pub fn bounds(&self) -> ([f64; 2], [f64; 2]) {
        bounds_of(self.vertices())
    }

    /// The part where `a·x + b·y + c ≥ 0`.
    #[inline]
    pub fn clip(&self, a: f64, b: f64, c: f64) -> ConvexPolygon {
        let mut out = ConvexPolygon::empty();
        self.clip_into(a, b, c, &mut out);
        out
    }

    /// The part inside the axis-aligned box `[x0, x1] × [y0, y1]`.
    #[inline]
    pub fn clip_rect(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> ConvexPolygon {
        let (lo, hi) = self.bounds();
        let planes = [
            (lo[0] < x0, [1.0, 0.0, -x0]),
            (hi[0] > x1, [-1.0, 0.0, x1]),
            (lo[1] < y0, [0.0, 1.0, -y0]),
            (hi[1] > y1, [0.0, -1.0, y1]),
        ];
        self.clip_lines(planes.iter().filter(|p| p.0).map(|p| p.1))
    }

    /// The part inside every half-plane `a·x + b·y + c ≥ 0` of `lines`.
    #[inline]
    pub fn clip_lines(&self, lines: impl IntoIterator<Item = [f64; 3]>) -> ConvexPolygon {
        // Ping-pong between two buffers by index: a polygon moved or swapped
        // is its whole capacity copied, a clip only its vertices.
        let mut lines = lines.into_iter();
        let Some([a, b, c]) = lines.next() else {
            return self.clone();
        };
        let mut buffers = [ConvexPolygon::empty(), ConvexPolygon::empty()];
        self.clip_into(a, b, c, &mut buffers[0]);
        let mut current = 0;
        if buffers[0].is_empty() {
            return ConvexPolygon::empty();
        }
        for [a, b, c] in lines {
            // Every vertex inside: the clip would copy them all, in order
            // (no crossing), so the line is passed over.
            if (buffers[current].vertices().iter()).all(|&[x, y]| a * x + b * y + c >= 0.0) {
                continue;
            }
            let [first, second] = &mut buffers;
            let (from, to) = if current == 0 {
                (&*first, second)
            } else {
                (&*second, first)
            };
            from.clip_into(a, b, c, to);
            current ^= 1;
            if buffers[current].is_empty() {
                return ConvexPolygon::empty();
            }
        }
        let [first, second] = buffers;
        if current == 0 { first } else { second }
    }

    /// [`ConvexPolygon::clip_lines`] written into `out` (its vertices
    /// replaced), for a caller that keeps polygons in place: the clips
    /// alternate between `out` and one buffer, so only vertices are copied,
    /// never a polygon's whole capacity. The same polygon, to the bit.
    pub fn clip_lines_into(&self, lines: &[[f64; 3]], out: &mut ConvexPolygon) {
        let Some((&[a, b, c], rest)) = lines.split_first() else {
            out.v.clone_from(&self.v);
            return;
        };
        // Each clip goes to the other of the two, so that the last lands in
        // `out`.
        let mut buffer = ConvexPolygon::empty();
        let (mut from, mut to) = if rest.len() % 2 == 0 {
            (&mut buffer, &mut *out)
        } else {
            (&mut *out, &mut buffer)
        };
        self.clip_into(a, b, c, to);
        for &[a, b, c] in rest {
            std::mem::swap(&mut from, &mut to);
            if from.is_empty() {
                out.v.clear();
                return;
            }
            from.clip_into(a, b, c, to);
        }
    }

    /// [`ConvexPolygon::clip`] into `out` (cleared first).
    #[inline]
    pub(crate) fn clip_into(&self, a: f64, b: f64, c: f64, out: &mut ConvexPolygon) {
        out.v.clear();
        let v = self.vertices();
        let n = v.len();
        if n == 0 {
            return;
        }
        let side = |p: [f64; 2]| a * p[0] + b * p[1] + c;
        let mut prev = v[n - 1];
        let mut s_prev = side(prev);
        for &p in v {
            let s = side(p);
            if (s >= 0.0) != (s_prev >= 0.0) {
                let _ = out.v.try_push(crossing(prev, p, s_prev, s));
            }
            if s >= 0.0 {
                let _ = out.v.try_push(p);
            }
            prev = p;
            s_prev = s;
        }
    }

    /// The parts on either side of the line `a·x + b·y + c = 0` into
    /// `inside` (`≥ 0`) and `outside` (`≤ 0`), both cleared first, in one
    /// pass: the same polygons as [`ConvexPolygon::clip_into`] with
    /// `(a, b, c)` and with `(−a, −b, −c)` (negation is exact, so each
    /// side value and crossing point is too).
    pub fn split_into(
        &self,
        a: f64,
        b: f64,
        c: f64,
        inside: &mut ConvexPolygon,
        outside: &mut ConvexPolygon,
    ) {
        inside.v.clear();
        outside.v.clear();
        let v = self.vertices();
        let n = v.len();
        if n == 0 {
            return;
        }
        let side = |p: [f64; 2]| a * p[0] + b * p[1] + c;
        let mut prev = v[n - 1];
        let mut s_prev = side(prev);
        for &p in v {
            let s = side(p);
            let crosses_in = (s >= 0.0) != (s_prev >= 0.0);
            let crosses_out = (s <= 0.0) != (s_prev <= 0.0);
            if crosses_in || crosses_out {
                let q = crossing(prev, p, s_prev, s);
                if crosses_in {
                    let _ = inside.v.try_push(q);
                }
                if crosses_out {
                    let _ = outside.v.try_push(q);
                }
            }
            if s >= 0.0 {
                let _ = inside.v.try_push(p);
            }
            if s <= 0.0 {
                let _ = outside.v.try_push(p);
            }
            prev = p;
            s_prev = s;
        }
    }

    /// Each edge as the line `(a, b, c)` with `a·x + b·y + c ≥ 0` on the
    /// inside (left of the edge, the polygon being counter-clockwise).
    pub fn edge_lines(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        let v = self.vertices();
        // The next vertex without a division (`% len`) per edge.
        let next = v.iter().skip(1).chain(v.first());
        v.iter().zip(next).map(|(&a, &b)| {
            let (nx, ny) = (-(b[1] - a[1]), b[0] - a[0]);
            [nx, ny, -(nx * a[0] + ny * a[1])]
        })
    }

    /// The part inside convex polygon `other`.
    pub fn intersect(&self, other: &ConvexPolygon) -> ConvexPolygon {
        self.clip_lines(other.edge_lines())
    }

    /// Whether [`ConvexPolygon::without_close_vertices`] would merge any
    /// vertex: two neighbours (the last and the first included) within
    /// `tolerance` on both axes.
    pub(crate) fn has_close_vertices(&self, tolerance: f64) -> bool {
        let v = self.vertices();
        (0..v.len()).any(|i| within(v[i], v[(i + 1) % v.len()], tolerance))
    }

    /// This polygon less each vertex within `tolerance` (in both
    /// coordinates) of the one kept before it. An edge that short, left by
    /// rounding where a clip passes through a vertex, points where the
    /// rounding points it: as one of the polygon's half-planes its line
    /// may cut through the polygon (and everything may lie outside it).
    /// Removing the vertex changes the area by at most `tolerance` times
    /// the polygon's perimeter.
    pub(crate) fn without_close_vertices(mut self, tolerance: f64) -> ConvexPolygon {
        let close = |a: [f64; 2], b: [f64; 2]| within(a, b, tolerance);
        let mut kept = 0;
        for i in 0..self.v.len() {
            if kept == 0 || !close(self.v[kept - 1], self.v[i]) {
                self.v[kept] = self.v[i];
                kept += 1;
            }
        }
        self.v.truncate(kept);
        while self.v.len() > 1 && close(self.v[0], self.v[self.v.len() - 1]) {
            self.v.pop();
        }
        self
    }

    /// [`ConvexPolygon::map`], made counter-clockwise (a map that mirrors
    /// reverses the order), as [`ConvexPolygon::from_trusted`] would.
    pub(crate) fn map_counter_clockwise(&self, f: impl Fn([f64; 2]) -> [f64; 2]) -> ConvexPolygon {
        let mut p = self.map(f);
        if p.signed_area() < 0.0 {
            p.v.reverse();
        }
        p
    }

    /// The polygon with every vertex mapped by `f` (which must keep it
    /// convex, as an affine or a projective map on its visible side does).
    pub fn map(&self, f: impl Fn([f64; 2]) -> [f64; 2]) -> ConvexPolygon {
        ConvexPolygon {
            v: self.v.iter().map(|&p| f(p)).collect(),
        }
    }

    /// The convex hull of `points` (finite), counter-clockwise (Andrew's
    /// monotone chain); at most [`MAX_VERTICES`] points are read.
    pub fn hull(points: &[[f64; 2]]) -> ConvexPolygon {
        // On the stack: shadow tests take millions of triangles' hulls a
        // frame, and two heap buffers each cost more than the chain itself.
        let mut pts: ArrayVec<[f64; 2], MAX_VERTICES> =
            points.iter().take(MAX_VERTICES).copied().collect();
        // `total_cmp` on both coordinates leaves no two unequal points tied,
        // so an unstable sort gives the stable one's order.
        pts.sort_unstable_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
        let mut unique: ArrayVec<[f64; 2], MAX_VERTICES> = ArrayVec::new();
        for p in pts {
            if unique.last() != Some(&p) {
                unique.push(p);
            }
        }
        if unique.len() < 3 {
            return ConvexPolygon::empty();
        }
        let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
            (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
        };
        if let [a, b, c] = unique[..] {
            // A triangle (the shadow tests' case): the chain below decides
            // on two turns only, `cross(a, b, c)` on the way out and
            // `cross(c, b, a)` on the way back; its four outcomes, taken
            // directly (to the bit, rounding included).
            let (out, back) = (cross(a, b, c) > 0.0, cross(c, b, a) > 0.0);
            return match (out, back) {
                (true, false) => ConvexPolygon::from_trusted(&[a, b, c]),
                (true, true) => ConvexPolygon::from_trusted(&[a, b, c, b]),
                (false, false) => ConvexPolygon::from_trusted(&[a, c]),
                (false, true) => ConvexPolygon::from_trusted(&[a, c, b]),
            };
        }
        // Each pass pushes at most every point and pops its last one.
        let mut hull: ArrayVec<[f64; 2], { 2 * MAX_VERTICES }> = ArrayVec::new();
        let chain = |hull: &mut ArrayVec<[f64; 2], { 2 * MAX_VERTICES }>, p: [f64; 2], start| {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        };
        for &p in &unique {
            chain(&mut hull, p, 0);
        }
        hull.pop();
        let start = hull.len();
        for &p in unique.iter().rev() {
            chain(&mut hull, p, start);
        }
        hull.pop();
        ConvexPolygon::from_trusted(&hull)
    }

    fn is_convex(&self) -> bool {
        let v = self.vertices();
        let n = v.len();
        if n < 4 {
            return true;
        }
        let scale = v
            .iter()
            .flatten()
            .fold(0f64, |m, c| m.max(c.abs()))
            .max(f64::MIN_POSITIVE);
        let tolerance = -1e-12 * scale * scale;
        (0..n).all(|i| {
            let (a, b, c) = (v[i], v[(i + 1) % n], v[(i + 2) % n]);
            (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]) >= tolerance
        })
    }
}

/// Shoelace area of a polygon, signed.
pub(crate) fn signed_area(v: &[[f64; 2]]) -> f64 {
    let n = v.len();
    if n < 3 {
        return 0.0;
    }
    // Relative to the first vertex: the products stay at the polygon's
    // own scale, not its distance from the origin (a one-pixel square
    // near x = 900 summed over absolute coordinates is off by about 1e-11).
    let o = v[0];
    let mut a = 0.0;
    let mut prev = [v[1][0] - o[0], v[1][1] - o[1]];
    for p in &v[2..] {
        let p = [p[0] - o[0], p[1] - o[1]];
        a += prev[0] * p[1] - p[0] * prev[1];
        prev = p;
    }
    0.5 * a
}

/// A cubic `c[0] + c[1]·x + c[2]·x² + c[3]·x³`.
pub(crate) type Cubic = [f64; 4];

/// 4-point Gauss–Legendre nodes and weights on `[0, 1]`: exact for
/// polynomials of degree ≤ 7.
pub(crate) const GAUSS4: [(f64, f64); 4] = [
    (0.069_431_844_202_973_71, 0.173_927_422_568_726_93),
    (0.330_009_478_207_571_87, 0.326_072_577_431_273_07),
    (0.669_990_521_792_428_1, 0.326_072_577_431_273_07),
    (0.930_568_155_797_026_3, 0.173_927_422_568_726_93),
];

/// `∫∫_P f(x)·g(y) dx dy` over polygon `P`, for cubics `f` and `g`, by
/// Green's theorem: `∮ F(x)·g(y) dy` with `F' = f`, each edge integrated by
/// 4-point Gauss–Legendre (degree 4 + 3 = 7: exact up to rounding). Positive
/// for a counter-clockwise polygon. The tests' reference for
/// [`crate::PixelFilter::integral`], cell by cell.
#[cfg(test)]
pub(crate) fn separable_integral(p: &[[f64; 2]], f: &Cubic, g: &Cubic) -> f64 {
    let n = p.len();
    if n < 3 {
        return 0.0;
    }
    let big_f = |x: f64| x * (f[0] + x * (f[1] / 2.0 + x * (f[2] / 3.0 + x * f[3] / 4.0)));
    let small_g = |y: f64| g[0] + y * (g[1] + y * (g[2] + y * g[3]));
    let mut total = 0.0;
    let mut a = p[n - 1];
    for &b in p {
        let dy = b[1] - a[1];
        if dy != 0.0 {
            let mut edge = 0.0;
            for (t, w) in GAUSS4 {
                let (x, y) = (a[0] + t * (b[0] - a[0]), a[1] + t * dy);
                edge += w * big_f(x) * small_g(y);
            }
            total += edge * dy;
        }
        a = b;
    }
    total
}

/// Where the edge from `prev` (side value `s_prev`) to `p` (side value
/// `s`, of the other sign) crosses the line: one formula for
/// [`ConvexPolygon::clip_into`] and [`ConvexPolygon::split_into`], so the
/// two agree bit for bit.
#[inline]
fn crossing(prev: [f64; 2], p: [f64; 2], s_prev: f64, s: f64) -> [f64; 2] {
    let t = s_prev / (s_prev - s);
    [
        prev[0] + t * (p[0] - prev[0]),
        prev[1] + t * (p[1] - prev[1]),
    ]
}

/// Widens the interval `lo..=hi` to hold `v`; a NaN `v` leaves it as it
/// is. What `*lo = lo.min(v); *hi = hi.max(v)` gives (but perhaps for
/// the sign of a zero), by one comparison each: `f64::min` and `max`
/// handle a NaN on either side, which costs x86 several instructions
/// each, and boxes of polygons are taken millions of times a frame (a
/// twentieth of the terrain's instructions went to them).
/// The bounding box of `points`, as [`ConvexPolygon::bounds`] takes it.
#[inline]
pub(crate) fn bounds_of(points: &[[f64; 2]]) -> ([f64; 2], [f64; 2]) {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in points {
        for a in 0..2 {
            widen(&mut lo[a], &mut hi[a], p[a]);
        }
    }
    (lo, hi)
}

#[inline]
pub(crate) fn widen(lo: &mut f64, hi: &mut f64, v: f64) {
    if v < *lo {
        *lo = v;
    }
    if v > *hi {
        *hi = v;
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// The next state of a xorshift64 generator (the tests' random input).
    fn xorshift(state: &mut u64) -> u64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        *state
    }

    /// `widen` is `f64::min`/`max` as a box takes them: equal on random
    /// values of every sign and size (zeros, infinities), with NaN
    /// skipped on the value's side; a box of a polygon with a NaN vertex
    /// is the box of the others.
    #[test]
    fn widen_is_min_and_max_with_nan_skipped() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let specials = [0.0, 1.0, -1.0, f64::INFINITY, f64::NEG_INFINITY, f64::NAN];
        for i in 0..20_000 {
            let r = xorshift(&mut state);
            let v = match i % 4 {
                0 => specials[(r % specials.len() as u64) as usize],
                1 => f64::from_bits(r),
                _ => (r as f64 / u64::MAX as f64 - 0.5) * 1e3,
            };
            let (mut lo, mut hi) = ((i as f64).sin(), (i as f64).sin() + 0.25);
            let (want_lo, want_hi) = (lo.min(v), hi.max(v));
            widen(&mut lo, &mut hi, v);
            assert!(lo == want_lo && hi == want_hi, "{v} gave {lo}..{hi}");
        }
        let p = ConvexPolygon::from_trusted(&[[0.0, 0.0], [2.0, f64::NAN], [1.0, 3.0]]);
        assert_eq!(p.bounds(), ([0.0, 0.0], [2.0, 3.0]));
    }

    /// Andrew's monotone chain as first written (heap buffers, stable
    /// sort, `Vec::dedup`): the reference `hull` must match to the bit.
    fn hull_reference(points: &[[f64; 2]]) -> ConvexPolygon {
        let mut pts: Vec<[f64; 2]> = points.iter().take(MAX_VERTICES).copied().collect();
        pts.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
        pts.dedup();
        if pts.len() < 3 {
            return ConvexPolygon::empty();
        }
        let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
            (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
        };
        let mut hull: Vec<[f64; 2]> = Vec::new();
        for pass in 0..2 {
            let start = hull.len();
            let order: Vec<[f64; 2]> = if pass == 0 {
                pts.clone()
            } else {
                pts.iter().rev().copied().collect()
            };
            for p in order {
                while hull.len() >= start + 2
                    && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
                {
                    hull.pop();
                }
                hull.push(p);
            }
            hull.pop();
        }
        ConvexPolygon::from_trusted(&hull)
    }

    /// `hull` against [`hull_reference`] on random point sets of 0 to 20
    /// points (beyond `MAX_VERTICES`), half of them triangles, some snapped
    /// to a coarse lattice (duplicates, collinear runs, signed zeros), some
    /// within rounding of one line.
    #[test]
    fn hull_matches_the_heap_reference_to_the_bit() {
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut random = || xorshift(&mut state);
        for case in 0..20_000 {
            // Half the sets are triangles (their own path in `hull`).
            let n = if case % 4 < 2 {
                3
            } else {
                (random() % 21) as usize
            };
            let points: Vec<[f64; 2]> = (0..n)
                .map(|_| {
                    let mut coordinate = || {
                        let r = random();
                        let v = if case % 2 == 0 {
                            (r % 5) as f64 - 2.0
                        } else {
                            (r >> 11) as f64 / (1u64 << 53) as f64 * 4.0 - 2.0
                        };
                        if v == 0.0 && r & 1 == 1 { -0.0 } else { v }
                    };
                    let p = [coordinate(), coordinate()];
                    if case % 8 == 5 {
                        // Nearly on one line: turns of either sign, and
                        // zero, at the rounding's scale.
                        let noise = (random() % 5) as f64 - 2.0;
                        [p[0], 0.3 * p[0] + 1.1 + noise * 1e-16]
                    } else {
                        p
                    }
                })
                .collect();
            let (fast, slow) = (ConvexPolygon::hull(&points), hull_reference(&points));
            let bits = |p: &ConvexPolygon| -> Vec<[u64; 2]> {
                p.vertices().iter().map(|v| v.map(f64::to_bits)).collect()
            };
            assert_eq!(bits(&fast), bits(&slow), "points {points:?}");
        }
    }

    /// `clip_lines` (two buffers, early exit) against clipping one line at
    /// a time, on random convex polygons and lines, empty results included.
    #[test]
    fn clipping_by_many_lines_equals_clipping_one_at_a_time() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut random = || (xorshift(&mut state) >> 11) as f64 / (1u64 << 53) as f64 * 4.0 - 2.0;
        for _ in 0..2000 {
            let points: Vec<[f64; 2]> = (0..8).map(|_| [random(), random()]).collect();
            let polygon = ConvexPolygon::hull(&points);
            let lines: Vec<[f64; 3]> = (0..(random().abs() * 2.5) as usize + 1)
                .map(|_| [random(), random(), random() * 0.5])
                .collect();
            let by_one = lines
                .iter()
                .fold(polygon.clone(), |p, l| p.clip(l[0], l[1], l[2]));
            let at_once = polygon.clip_lines(lines.iter().copied());
            // In place, over a polygon left from before.
            let mut into = ConvexPolygon::rect(-9.0, -9.0, 9.0, 9.0);
            polygon.clip_lines_into(&lines, &mut into);
            if by_one.is_empty() {
                assert!(at_once.is_empty(), "{polygon:?} {lines:?}");
                assert!(into.is_empty(), "{polygon:?} {lines:?}");
            } else {
                assert_eq!(at_once, by_one, "{polygon:?} {lines:?}");
                assert_eq!(into, by_one, "{polygon:?} {lines:?}");
            }
        }
        let square = ConvexPolygon::rect(0.0, 0.0, 1.0, 1.0);
        assert_eq!(square.clip_lines(std::iter::empty()), square);
        let mut into = ConvexPolygon::empty();
        square.clip_lines_into(&[], &mut into);
        assert_eq!(into, square);
    }

    /// `split_into` against two clips, bit for bit (PartialEq on `f64`
    /// coordinates; signed zeros compared by bits too), on random polygons,
    /// random lines, lines through vertices and the horizontal lines the
    /// cell scan cuts bands with.
    #[test]
    fn splitting_equals_clipping_both_sides() {
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut random = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 4.0 - 2.0
        };
        let bits = |p: &ConvexPolygon| -> Vec<[u64; 2]> {
            p.vertices().iter().map(|v| v.map(f64::to_bits)).collect()
        };
        for i in 0..4000 {
            let points: Vec<[f64; 2]> = (0..8).map(|_| [random(), random()]).collect();
            let polygon = ConvexPolygon::hull(&points);
            let line = match i % 3 {
                0 => [random(), random(), random() * 0.5],
                // Through a vertex: a side value of exactly zero.
                1 => {
                    let v = polygon.vertices()[0];
                    let (a, b) = (random(), 0.0);
                    [a, b, -a * v[0]]
                }
                _ => {
                    let z = (random() * 8.0).round() / 8.0;
                    [0.0, -1.0, z]
                }
            };
            let (mut inside, mut outside) = (ConvexPolygon::empty(), ConvexPolygon::empty());
            polygon.split_into(line[0], line[1], line[2], &mut inside, &mut outside);
            let want_in = polygon.clip(line[0], line[1], line[2]);
            let want_out = polygon.clip(-line[0], -line[1], -line[2]);
            assert_eq!(bits(&inside), bits(&want_in), "{polygon:?} {line:?}");
            assert_eq!(bits(&outside), bits(&want_out), "{polygon:?} {line:?}");
        }
    }

    #[test]
    fn clipping_a_square_by_a_diagonal_halves_it() {
        let sq = ConvexPolygon::rect(0.0, 0.0, 1.0, 1.0);
        let half = sq.clip(-1.0, -1.0, 1.0); // x + y ≤ 1
        assert!((half.area() - 0.5).abs() < 1e-15);
        assert!(sq.clip(1.0, 0.0, -2.0).is_empty());
        assert_eq!(sq.clip_rect(-1.0, -1.0, 2.0, 2.0), sq);
        let q = sq.clip_rect(0.25, 0.5, 0.75, 3.0);
        assert!((q.area() - 0.25).abs() < 1e-15);
    }

    #[test]
    fn new_checks_convexity_and_orientation() {
        let cw = ConvexPolygon::new(&[[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]]).unwrap();
        assert!(cw.signed_area() > 0.0);
        assert!(ConvexPolygon::new(&[[0.0, 0.0], [2.0, 0.0], [0.5, 0.5], [0.0, 2.0]]).is_err());
        let e = ConvexPolygon::new(&[[0.0, f64::NAN], [1.0, 0.0], [0.0, 1.0]]).unwrap_err();
        assert!(e.to_string().contains("vertex[0]"), "{e}");
    }

    #[test]
    fn subtraction_leaves_the_difference() {
        let a = ConvexPolygon::rect(0.0, 0.0, 2.0, 2.0);
        let b = ConvexPolygon::rect(1.0, 1.0, 3.0, 3.0);
        let mut area = 0.0;
        a.subtract(&b, |p| area += p.area());
        assert!((area - 3.0).abs() < 1e-14);
        assert_eq!(a.centroid(), [1.0, 1.0]);
    }

    /// [`ConvexPolygon::split_by`] (and so [`ConvexPolygon::subtract`]) is
    /// the intersection and, outside, the clips inside each edge before and
    /// outside this one, vertex for vertex: random convex polygons,
    /// rectangles sharing edges, repeated vertices.
    #[test]
    fn a_split_is_the_intersection_and_the_difference() {
        let mut next = crate::test_rng::uniform(29);
        let mut random = |n: usize, scale: f64| {
            let points: Vec<[f64; 2]> = (0..n).map(|_| [next() * scale, next() * scale]).collect();
            ConvexPolygon::hull(&points)
        };
        let mut cases = vec![
            (
                ConvexPolygon::rect(0.0, 0.0, 2.0, 2.0),
                ConvexPolygon::rect(1.0, 0.0, 3.0, 2.0),
            ),
            (
                ConvexPolygon::rect(0.0, 0.0, 1.0, 1.0),
                ConvexPolygon::rect(0.0, 0.0, 1.0, 1.0),
            ),
            (
                ConvexPolygon::rect(1.5, 0.5, 2.5, 1.5),
                ConvexPolygon::new(&[[0.0, 0.0], [2.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
                    .unwrap(),
            ),
        ];
        for _ in 0..500 {
            cases.push((random(6, 2.0), random(5, 2.0)));
        }
        let mut straddling = 0;
        // The outside as clips: inside the edges before, outside this one.
        let apart = |a: &ConvexPolygon, b: &ConvexPolygon| {
            let lines: Vec<[f64; 3]> = b
                .edge_lines()
                .filter(|l| l[0] != 0.0 || l[1] != 0.0)
                .collect();
            let mut pieces = Vec::new();
            for (k, &[x, y, z]) in lines.iter().enumerate() {
                let flipped = [-x, -y, -z];
                let piece = a.clip_lines(lines[..k].iter().copied().chain([flipped]));
                if piece.area() > 0.0 {
                    pieces.push(piece);
                }
                if a.clip_lines(lines[..=k].iter().copied()).is_empty() {
                    break;
                }
            }
            pieces
        };
        for (a, b) in &cases {
            let mut split = Vec::new();
            let inside = a.split_by(b, |p| split.push(p));
            assert_eq!(inside, a.intersect(b), "{a:?} by {b:?}");
            assert_eq!(split, apart(a, b), "{a:?} by {b:?}");
            straddling += usize::from(!inside.is_empty() && !split.is_empty());
        }
        assert!(straddling > 100, "{straddling}");
    }

    /// A repeated vertex (clipping leaves them where a vertex lies on the
    /// line) has no edge line: what lies inside is not given out as well.
    #[test]
    fn a_repeated_vertex_does_not_leak_the_inside() {
        let region =
            ConvexPolygon::new(&[[0.0, 0.0], [2.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
                .unwrap();
        let inside = ConvexPolygon::rect(0.5, 0.5, 1.5, 1.5);
        let mut outside = 0.0;
        inside.subtract(&region, |p| outside += p.area());
        assert_eq!(outside, 0.0);
        assert_eq!(inside.intersect(&region).area(), 1.0);
        // Half out: the parts still add up to the whole.
        let straddling = ConvexPolygon::rect(1.5, 0.5, 2.5, 1.5);
        let mut outside = 0.0;
        straddling.subtract(&region, |p| outside += p.area());
        assert_eq!(outside + straddling.intersect(&region).area(), 1.0);
    }

    #[test]
    fn close_vertices_go_and_the_rest_stay() {
        let d = 4.0 * f64::EPSILON;
        let p = ConvexPolygon::from_trusted(&[
            [0.0, 0.0],
            [1.0, 0.0],
            [1.0 + d, d],
            [1.0, 1.0],
            [0.5, 1.0],
            [0.5 + d, 1.0],
            [0.0, 1.0],
            [d, 0.0],
        ]);
        let kept = p.clone().without_close_vertices(1e-9);
        assert_eq!(
            kept.vertices(),
            &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.5, 1.0], [0.0, 1.0]]
        );
        assert!((kept.area() - p.area()).abs() < 1e-12);
        // Nothing within the tolerance: unchanged; everything: one vertex.
        assert_eq!(p.clone().without_close_vertices(0.0), p);
        assert!(p.has_close_vertices(1e-9) && !p.has_close_vertices(0.0));
        assert_eq!(p.clone().without_close_vertices(2.0).vertices().len(), 1);
        // Only the last and the first close: the wrap is seen too.
        let q = ConvexPolygon::from_trusted(&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [d, d]]);
        assert!(q.has_close_vertices(1e-9));
        assert_eq!(q.clone().without_close_vertices(1e-9).vertices().len(), 3);
        // `has_close_vertices` is exactly "something would merge".
        for tolerance in [0.0, 1e-12, 1e-9, 0.3, 0.5, 0.6, 2.0] {
            for poly in [&p, &q] {
                let merged = poly.clone().without_close_vertices(tolerance);
                assert_eq!(poly.has_close_vertices(tolerance), merged != *poly);
            }
        }
    }

    #[test]
    fn hull_of_a_bow_tie_is_its_square() {
        let h = ConvexPolygon::hull(&[[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]);
        assert_eq!(h.vertices().len(), 4);
        assert!((h.area() - 1.0).abs() < 1e-15);
        assert!(ConvexPolygon::hull(&[[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]).is_empty());
    }

    #[test]
    fn intersection_of_two_squares() {
        let a = ConvexPolygon::rect(0.0, 0.0, 2.0, 2.0);
        let b = ConvexPolygon::new(&[[1.0, -1.0], [3.0, 1.0], [1.0, 3.0], [-1.0, 1.0]]).unwrap();
        // |x−1| + |y−1| ≤ 2 holds all of the square [0,2]².
        assert!((a.intersect(&b).area() - 4.0).abs() < 1e-14);
        // The diamond |x−1| + |y−1| ≤ 1 inside it: area 2.
        let c = ConvexPolygon::new(&[[1.0, 0.0], [2.0, 1.0], [1.0, 2.0], [0.0, 1.0]]).unwrap();
        assert!((a.intersect(&c).area() - 2.0).abs() < 1e-14);
        assert!((c.intersect(&a).area() - 2.0).abs() < 1e-14);
    }

    #[test]
    fn green_matches_a_product_of_one_dimensional_integrals_on_rectangles() {
        // ∫₀²∫₋₁¹ (1 + 2x − x³)(3 − y + y²) = [x + x² − x⁴/4]₋₁¹ · [3y − y²/2 + y³/3]₀²
        let f = [1.0, 2.0, 0.0, -1.0];
        let g = [3.0, -1.0, 1.0, 0.0];
        let r = ConvexPolygon::rect(-1.0, 0.0, 1.0, 2.0);
        let fx = |x: f64| x + x * x - x.powi(4) / 4.0;
        let gy = |y: f64| 3.0 * y - y * y / 2.0 + y.powi(3) / 3.0;
        let expected = (fx(1.0) - fx(-1.0)) * (gy(2.0) - gy(0.0));
        let got = separable_integral(r.vertices(), &f, &g);
        assert!((got - expected).abs() < 1e-12, "{got} vs {expected}");
    }

    #[test]
    fn green_matches_dense_sampling_on_a_triangle() {
        let f = [0.5, -1.0, 2.0, 0.7];
        let g = [1.0, 0.3, -0.2, 0.9];
        let tri = ConvexPolygon::new(&[[0.0, 0.0], [1.0, 0.2], [0.3, 0.9]]).unwrap();
        let n = 2000;
        let mut sum = 0.0;
        for j in 0..n {
            for i in 0..n {
                let (x, y) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                // Point-in-triangle by edge signs.
                let v = tri.vertices();
                let ok = (0..3).all(|k| {
                    let (a, b) = (v[k], v[(k + 1) % 3]);
                    (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]) >= 0.0
                });
                if ok {
                    let fx = f[0] + x * (f[1] + x * (f[2] + x * f[3]));
                    let gy = g[0] + y * (g[1] + y * (g[2] + y * g[3]));
                    sum += fx * gy;
                }
            }
        }
        let sampled = sum / (n * n) as f64;
        let exact = separable_integral(tri.vertices(), &f, &g);
        assert!((sampled - exact).abs() < 2e-3, "{sampled} vs {exact}");
    }
}

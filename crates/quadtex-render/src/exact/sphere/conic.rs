//! Ellipses on the screen ([`Ellipse`]): a sphere's outline, and the
//! images of the circles on the sphere that its texture's edges run
//! along ([`super::edges`]). Each is clipped into a support by chords
//! ([`Ellipse::chords`]) that leave out segments whose areas are known in
//! closed form, `a·b·(δ − sin δ)/2` for a chord of angle `δ` (`a`, `b` the
//! semi-axes), and whose weight under a pixel filter is bounded by the
//! filter's largest `|k|` over each segment's box
//! ([`Ellipse::sliver_bound`]).

use quadtex_core::ConvexPolygon;

/// Chords a region is clipped by at most: with the support's four
/// corners, one vertex each keeps the region within
/// [`quadtex_core::ConvexPolygon`]'s vertex capacity.
pub(super) const MAX_CHORDS: usize = 10;

/// Chords the ellipse is cut into when the support holds its centre (a
/// small sphere): again within the polygon's capacity.
const MAX_CHORDS_AROUND: usize = 12;

/// Area the chords may leave out of one support (pixels², at full
/// contrast: a sixteenth of the default error bound): as few chords as
/// keep the segments they leave out within it, up to [`MAX_CHORDS`].
pub(super) const SLIVER_BUDGET: f64 = 1.0 / 512.0 / 16.0;

/// An ellipse on the screen, `e0 + ea·cos θ + eb·sin θ`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Ellipse {
    pub(super) e0: [f64; 2],
    pub(super) ea: [f64; 2],
    pub(super) eb: [f64; 2],
    /// Rows of the map from `s − e0` to the unit circle's coordinates `q`.
    to_circle: [[f64; 2]; 2],
    /// The ellipse's screen box.
    pub(super) lo: [f64; 2],
    pub(super) hi: [f64; 2],
}

/// The chords that clip a support ([`Ellipse::chords`]): half-planes
/// `a·x + b·y + c ≥ 0`, the first `count` of `lines`.
#[derive(Default)]
pub(super) struct Chords {
    pub(super) lines: [[f64; 3]; MAX_CHORDS_AROUND],
    pub(super) count: usize,
    /// Chord `j` joins the ellipse's points at angles `from + j·delta` and
    /// `from + (j + 1)·delta`.
    pub(super) from: f64,
    pub(super) delta: f64,
}

impl Chords {
    /// The angle where chord (or sector) `j` starts.
    pub(super) fn angle(&self, j: usize) -> f64 {
        self.from + self.delta * j as f64
    }
}

impl Ellipse {
    /// The ellipse where the quadratic form `sᵀ·A·s + 2·b·s + c` (`A =
    /// [[a00, a01], [a01, a11]]`) is zero, its inside where the form is
    /// positive; `None` unless that is a bounded, non-empty ellipse with
    /// finite parameters.
    pub(super) fn from_form(
        [a00, a01, a11]: [f64; 3],
        [b0, b1]: [f64; 2],
        c: f64,
    ) -> Option<Ellipse> {
        let det = a00 * a11 - a01 * a01;
        if !(a00 < 0.0 && det > 0.0) {
            return None;
        }
        // Centre: A·s0 = −b.
        let e0 = [(-a11 * b0 + a01 * b1) / det, (a01 * b0 - a00 * b1) / det];
        let level = c + b0 * e0[0] + b1 * e0[1];
        if level.is_nan() || level <= 0.0 {
            return None;
        }
        // (s − e0)ᵀ N (s − e0) ≤ 1 with N = −A / level.
        let (p, o, r) = (-a00 / level, -a01 / level, -a11 / level);
        let half = 0.5 * (p + r);
        let spread = (0.25 * (p - r) * (p - r) + o * o).sqrt();
        let (l1, l2) = (half - spread, half + spread);
        if !(l1 > 0.0 && l2.is_finite()) {
            return None;
        }
        let e1 = if o.abs() > 1e-300 {
            let (x, y) = (l1 - r, o);
            let n = x.hypot(y);
            [x / n, y / n]
        } else if p <= r {
            [1.0, 0.0]
        } else {
            [0.0, 1.0]
        };
        let e2 = [-e1[1], e1[0]];
        let (sa, sb) = (l1.sqrt(), l2.sqrt());
        let ea = [e1[0] / sa, e1[1] / sa];
        let eb = [e2[0] / sb, e2[1] / sb];
        let extent = [ea[0].hypot(eb[0]), ea[1].hypot(eb[1])];
        let ellipse = Ellipse {
            e0,
            ea,
            eb,
            to_circle: [[e1[0] * sa, e1[1] * sa], [e2[0] * sb, e2[1] * sb]],
            lo: [e0[0] - extent[0], e0[1] - extent[1]],
            hi: [e0[0] + extent[0], e0[1] + extent[1]],
        };
        [e0, ea, eb, ellipse.lo, ellipse.hi]
            .iter()
            .flatten()
            .all(|v| v.is_finite())
            .then_some(ellipse)
    }

    /// `s` in the coordinates that make the ellipse the unit circle.
    pub(super) fn circle(&self, s: [f64; 2]) -> [f64; 2] {
        let (x, y) = (s[0] - self.e0[0], s[1] - self.e0[1]);
        let [r0, r1] = self.to_circle;
        [r0[0] * x + r0[1] * y, r1[0] * x + r1[1] * y]
    }

    /// The screen point at angle `theta` on the ellipse.
    pub(super) fn point(&self, theta: f64) -> [f64; 2] {
        let (s, c) = theta.sin_cos();
        [
            self.e0[0] + self.ea[0] * c + self.eb[0] * s,
            self.e0[1] + self.ea[1] * c + self.eb[1] * s,
        ]
    }

    /// The product of the semi-axes, `a·b`.
    pub(super) fn axes_product(&self) -> f64 {
        (self.ea[0] * self.eb[1] - self.ea[1] * self.eb[0]).abs()
    }

    /// The chords that clip `support` (half-planes holding the ellipse's
    /// centre, into `lines`) and the area they leave out of the ellipse's
    /// part near the support (screen pixels², the region's bound at full
    /// contrast). `None`: the support lies wholly outside the ellipse. No
    /// chords: it lies inside every one.
    pub(super) fn chords(&self, support: &ConvexPolygon, lines: &mut Chords) -> Option<f64> {
        lines.count = 0;
        let mut corners = [[0.0; 2]; quadtex_core::MAX_VERTICES];
        let n = support.vertices().len();
        for (q, &s) in corners.iter_mut().zip(support.vertices()) {
            *q = self.circle(s);
        }
        let q = &corners[..n];
        if q.is_empty() {
            return None;
        }
        // Every corner inside the ellipse: so is the (convex) support.
        let farthest = q.iter().fold(0f64, |m, p| m.max(p[0] * p[0] + p[1] * p[1]));
        if farthest <= 1.0 {
            return Some(0.0);
        }
        // Is the circle's centre inside the (convex) polygon, and how near
        // does the polygon come to it (squared)?
        let orientation = support.signed_area().signum();
        let mut inside = true;
        let mut nearest = f64::INFINITY;
        for i in 0..n {
            let (a, b) = (q[i], q[(i + 1) % n]);
            let e = [b[0] - a[0], b[1] - a[1]];
            let cross = e[0] * (-a[1]) - e[1] * (-a[0]);
            if cross * orientation < 0.0 {
                inside = false;
            }
            let len2 = e[0] * e[0] + e[1] * e[1];
            let t = if len2 > 0.0 {
                (-(a[0] * e[0] + a[1] * e[1]) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let p = [a[0] + e[0] * t, a[1] + e[1] * t];
            nearest = nearest.min(p[0] * p[0] + p[1] * p[1]);
        }
        if !inside && nearest >= 1.0 {
            return None;
        }
        let (from, span, most) = if inside {
            (0.0, std::f64::consts::TAU, MAX_CHORDS_AROUND)
        } else {
            let (from, span) = angles_seen(q);
            (from, span, MAX_CHORDS)
        };
        let ab = self.axes_product();
        let left_out = |count: usize| {
            let delta = span / count as f64;
            ab * count as f64 * 0.5 * (delta - delta.sin())
        };
        let fewest = if inside { 3 } else { 1 };
        let count = (fewest..=most)
            .find(|&c| left_out(c) <= SLIVER_BUDGET)
            .unwrap_or(most);
        let delta = span / count as f64;
        lines.from = from;
        lines.delta = delta;
        let mut a = self.point(from);
        for j in 1..=count {
            let b = self.point(from + delta * j as f64);
            // The line through a and b, the ellipse's centre on its ≥ 0 side.
            let (la, lb) = (a[1] - b[1], b[0] - a[0]);
            let lc = -(la * a[0] + lb * a[1]);
            let sign = if la * self.e0[0] + lb * self.e0[1] + lc >= 0.0 {
                1.0
            } else {
                -1.0
            };
            lines.lines[lines.count] = [sign * la, sign * lb, sign * lc];
            lines.count += 1;
            a = b;
        }
        Some(left_out(count))
    }

    /// A bound on the weight, under `filter` about `centre`, of what the
    /// chords of `support` ([`Ellipse::chords`]) leave out of the ellipse:
    /// each chord's segment, `a·b·(δ − sin δ)/2`, times the filter's
    /// largest `|k|` over the box of its arc (its ends and the ellipse's
    /// points of extreme `x` or `y` between them), which holds the
    /// segment.
    pub(super) fn sliver_bound(
        &self,
        support: &ConvexPolygon,
        filter: quadtex_core::PixelFilter,
        centre: [f64; 2],
    ) -> f64 {
        let mut lines = Chords::default();
        if self.chords(support, &mut lines).is_none() {
            return 0.0;
        }
        self.slivers(&lines, filter, centre)
    }

    /// [`Ellipse::sliver_bound`] of the chords `lines` (none: `0`).
    pub(super) fn slivers(
        &self,
        lines: &Chords,
        filter: quadtex_core::PixelFilter,
        centre: [f64; 2],
    ) -> f64 {
        if lines.count == 0 {
            return 0.0;
        }
        let delta = lines.delta;
        let segment = self.axes_product() * 0.5 * (delta - delta.sin());
        let pi = std::f64::consts::PI;
        let x_extreme = self.eb[0].atan2(self.ea[0]);
        let y_extreme = self.eb[1].atan2(self.ea[1]);
        let extremes = [x_extreme, x_extreme + pi, y_extreme, y_extreme + pi];
        (0..lines.count)
            .map(|j| {
                let (t0, t1) = (lines.angle(j), lines.angle(j + 1));
                let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
                let inside = extremes
                    .iter()
                    .filter(|&&t| (t - t0).rem_euclid(2.0 * pi) < delta);
                for t in [t0, t1].iter().chain(inside) {
                    let p = self.point(*t);
                    for a in 0..2 {
                        lo[a] = lo[a].min(p[a]);
                        hi[a] = hi[a].max(p[a]);
                    }
                }
                segment * filter.largest_weight_in((lo, hi), centre)
            })
            .sum()
    }
}

/// The angles `points` (in an ellipse's unit-circle coordinates, not
/// around the centre) are seen at from the centre: `(from, span)`, the
/// smallest arc holding them all, measured from the first point's angle.
pub(super) fn angles_seen(points: &[[f64; 2]]) -> (f64, f64) {
    let reference = points[0][1].atan2(points[0][0]);
    let (mut lo, mut hi) = (0f64, 0f64);
    for p in &points[1..] {
        let mut a = p[1].atan2(p[0]) - reference;
        if a > std::f64::consts::PI {
            a -= std::f64::consts::TAU;
        } else if a <= -std::f64::consts::PI {
            a += std::f64::consts::TAU;
        }
        lo = lo.min(a);
        hi = hi.max(a);
    }
    (reference + lo, hi - lo)
}

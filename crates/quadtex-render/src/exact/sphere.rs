//! A sphere seen from the camera ([`SphereView`]): its outline on the
//! screen (a conic), clipped into a pixel's support by chords with the
//! area they leave out in closed form, and its texture integrated exactly
//! over pieces of the support on each of which a projective map stays
//! within the error bound of the sphere's own map.
//!
//! **Outline.** The camera's unnormalised ray through screen point `s` is
//! `d(s) = d0 + dx·px + dy·py`; with `m` the sphere's centre seen from the
//! camera and `K = |m|² − r²`, it meets the sphere where
//! `(m·d)² − K·|d|² ≥ 0`: a quadratic form in `(px, py, 1)`, an ellipse
//! when the sphere lies wholly in front of the camera's plane (else the
//! sphere is left to the tangent-plane path). In the coordinates that
//! make the ellipse the unit circle (`q`), the support's part inside it is
//! approximated from inside by chords between points of the circle at
//! angles `θⱼ` spanning the support's angles; each chord leaves out a
//! segment of area `a·b·(δ − sin δ)/2` (`δ` its angle, `a`, `b` the
//! semi-axes), and as few chords are taken as keep their sum within
//! [`SLIVER_BUDGET`] (up to [`MAX_CHORDS`]): the sum is the region's area
//! bound, in screen pixels, times full contrast
//! ([`SphereView::region_into`]). A support whose corners all lie inside
//! the outline is its own region.
//!
//! **Texture map.** The sphere's map from the screen to its UV square
//! (`u`: longitude, `v`: latitude) is smooth inside the outline but not
//! projective. A piece of the region is integrated on a projective map
//! `H` through the sphere's UV at four points (where `H` is exact) when,
//! at its check points (the centre and sides' midpoints of the square or
//! trapezoid whose corners those are, when the piece lies within it and
//! inside the outline; else the piece's centroid, vertices and edges'
//! midpoints), the screen point the exact map sends to the same texture
//! point lies within `ε` pixels (`ε` the filter's error bound; `|J⁻¹·(H(s) − uv(s))|` with `J`
//! the fit's Jacobian, [`SphereView::map_error`]): a texture edge then
//! moves by at most `ε` pixels, and a pixel it crosses is off by at most
//! `ε` times its length times the contrast. A piece whose every candidate
//! image (the fit's, widened by twice its largest UV error at the check
//! points) lies in one texture square is that square's colour times its
//! weight, exactly, whatever the map's error. A pixel's region is first
//! tried whole against the sphere's own UV box over it, in closed form
//! ([`arcs`]): where one texture square holds it (and the light varies
//! over it by little), that is the region's colour, with no fit and no
//! pieces. The pieces:
//!
//! - **Squares** (most of the disc): the region's bounding square, split
//!   in four while its map is off, at most [`MAX_SPLITS`](pieces::MAX_SPLITS) times; `H` goes
//!   through the sphere's UV at the square's corners (Heckbert's
//!   square-to-quad; beyond the outline, a corner takes the point of the
//!   sphere nearest its ray). A whole square's checks are its children's
//!   corners ([`Square`](pieces::Square)), and points on the half-pixel grid are kept by
//!   the thread for the pixels beside and below.
//! - **Rings** along the outline, where the map has a square root
//!   (`√disc` in the ray's parameter) and a square of side `h` touching
//!   the outline is off by about `0.2·h`: the support's sectors (its
//!   chords' angles, or pieces of about half a pixel when it lies inside
//!   within a pixel and a half) are cut by the chords scaled about the
//!   centre at q-radii whose `k`-th lies `k²/512` pixels in, to a pixel (a
//!   fit across a ring of width `w` at `δ` from the outline is off by
//!   about `w²/(8·δ)`, measured; the first by about `w/5`): trapezoids, each on the map through the sphere's UV at
//!   its four corners, tried whole across several rings first and halved
//!   while no texture square holds them ([`SphereView::shade_ring`]);
//!   within the innermost ring, squares.
//!
//! Around a pole, where longitude turns around a point and no piece fits
//! the UV, squares and ring pieces are fitted in the pole's tangent-plane
//! coordinates instead and integrated exactly on its **fan**, the texture
//! squares touching the pole as wedges with straight sides, or beyond it
//! on a **band** of squares between two latitudes ([`fan`]).
//!
//! A piece still off whose weight is at most an eighth of what is left of
//! a budget of `ε/2` a call, or one at the deepest split, is integrated on
//! its fitted map with its whole weight in the bound. Each kept piece is integrated exactly
//! over the tree ([`quadtex_core::Texture::integrate_region`]), cut at the
//! longitude seam (`u` a whole number) so that each side is read in
//! `[0, 1)`, whatever the texture's wrap. Lambert light is taken at each
//! piece's centroid (its own normal and shadow ray).

use quadtex_core::ConvexPolygon;

use crate::math::Vec3;
use crate::scene::{Geometry, Scene};

/// Chords a region is clipped by at most: with the support's four
/// corners, one vertex each keeps the region within
/// [`quadtex_core::ConvexPolygon`]'s vertex capacity.
const MAX_CHORDS: usize = 10;

/// Chords the outline is cut into when the support holds its centre (a
/// small sphere): again within the polygon's capacity.
const MAX_CHORDS_AROUND: usize = 12;

/// Area the chords may leave out of one support (pixels², at full
/// contrast: a sixteenth of the default error bound): as few chords as
/// keep the segments they leave out within it, up to [`MAX_CHORDS`].
const SLIVER_BUDGET: f64 = 1.0 / 512.0 / 16.0;

/// A sphere seen from the camera: its outline on the screen and what
/// mapping a screen point to the sphere's UV takes. Built once per frame.
#[derive(Debug, Clone)]
pub(crate) struct SphereView {
    /// Unique in the process: what tells this view's points in a thread's
    /// half-pixel grid of UV (`pieces::HALF_PIXEL_UV`) from another's (0 is none's).
    stamp: u64,
    surface: usize,
    centre: Vec3,
    radius: f64,
    camera: Vec3,
    /// `[d0, dx, dy]`: the camera's unnormalised ray through `(px, py)` is
    /// `d0 + dx·px + dy·py`.
    basis: [Vec3; 3],
    /// `|centre − camera|² − radius²` (positive: the camera is outside).
    k: f64,
    /// The outline: `e0 + ea·cos θ + eb·sin θ`.
    e0: [f64; 2],
    ea: [f64; 2],
    eb: [f64; 2],
    /// Rows of the map from `s − e0` to the unit circle's coordinates `q`.
    to_circle: [[f64; 2]; 2],
    /// Texture point from the sphere's `(u, v, 1)`: the surface's UV
    /// transform, two affine rows.
    texture_from_uv: [[f64; 3]; 2],
    /// The outline's screen box.
    lo: [f64; 2],
    hi: [f64; 2],
    /// The texture redrawn around the poles ([`PolarFans`]).
    fans: std::sync::Arc<PolarFans>,
}

/// The chords that clip a support ([`SphereView::chords`]): half-planes
/// `a·x + b·y + c ≥ 0`, the first `count` of `lines`.
#[derive(Default)]
struct Chords {
    lines: [[f64; 3]; MAX_CHORDS_AROUND],
    count: usize,
    /// Chord `j` joins the outline's points at angles `from + j·delta` and
    /// `from + (j + 1)·delta`.
    from: f64,
    delta: f64,
}

impl Chords {
    /// The angle where chord (or sector) `j` starts.
    fn angle(&self, j: usize) -> f64 {
        self.from + self.delta * j as f64
    }
}

impl SphereView {
    /// The view of surface `surface` when it is a sphere wholly in front of
    /// the camera's plane (its outline is then an ellipse); `None`
    /// otherwise.
    pub(crate) fn new(scene: &Scene, surface: usize) -> Option<SphereView> {
        let s = scene.surfaces.get(surface)?;
        let Geometry::Sphere { centre, radius } = s.geometry else {
            return None;
        };
        let cam = &scene.camera;
        let m = centre - cam.position;
        let k = m.dot(m) - radius * radius;
        let forward = cam.forward();
        let ahead = m.dot(forward) / forward.length();
        if !(k > 0.0 && radius > 0.0 && ahead > radius * (1.0 + 1e-9)) {
            return None;
        }
        let [d0, dx, dy] = cam.basis();
        let cols = [dx, dy, d0];
        let q = |i: usize, j: usize| m.dot(cols[i]) * m.dot(cols[j]) - k * cols[i].dot(cols[j]);
        let (a00, a01, a11) = (q(0, 0), q(0, 1), q(1, 1));
        let (b0, b1, c) = (q(0, 2), q(1, 2), q(2, 2));
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
        let transform = s.uv_transform;
        let o = transform.apply([0.0, 0.0]);
        let ex = transform.apply([1.0, 0.0]);
        let ez = transform.apply([0.0, 1.0]);
        static STAMPS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        let view = SphereView {
            stamp: STAMPS.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            surface,
            centre,
            radius,
            camera: cam.position,
            basis: [d0, dx, dy],
            k,
            e0,
            ea,
            eb,
            to_circle: [[e1[0] * sa, e1[1] * sa], [e2[0] * sb, e2[1] * sb]],
            texture_from_uv: [
                [ex[0] - o[0], ez[0] - o[0], o[0]],
                [ex[1] - o[1], ez[1] - o[1], o[1]],
            ],
            lo: [e0[0] - extent[0], e0[1] - extent[1]],
            hi: [e0[0] + extent[0], e0[1] + extent[1]],
            fans: (s.texture.as_ref())
                .map(|t| t.polar_fans(&s.uv_transform, s.wrap))
                .unwrap_or_default(),
        };
        [e0, ea, eb, view.lo, view.hi]
            .iter()
            .flatten()
            .all(|v| v.is_finite())
            .then_some(view)
    }

    /// The surface this is the view of.
    pub(crate) fn surface(&self) -> usize {
        self.surface
    }

    /// Whether the outline's screen box misses the box `(lo, hi)`.
    pub(crate) fn misses_box(&self, lo: [f64; 2], hi: [f64; 2]) -> bool {
        self.hi[0] < lo[0] || self.lo[0] > hi[0] || self.hi[1] < lo[1] || self.lo[1] > hi[1]
    }

    /// The camera's unnormalised ray direction through screen point `s`.
    fn direction(&self, s: [f64; 2]) -> Vec3 {
        let [d0, dx, dy] = self.basis;
        d0 + dx * s[0] + dy * s[1]
    }

    /// Ray parameter (for the camera's unnormalised ray through `s`) of
    /// the sphere's near side; beyond the outline, of the ray's point
    /// nearest the centre (for ordering only).
    pub(crate) fn depth_at(&self, s: [f64; 2]) -> f64 {
        let d = self.direction(s);
        let (md, dd) = ((self.centre - self.camera).dot(d), d.dot(d));
        let disc = md * md - dd * self.k;
        let t = (md - disc.max(0.0).sqrt()) / dd;
        if t.is_finite() && t > 0.0 {
            t
        } else {
            f64::INFINITY
        }
    }

    /// The sphere's outward unit normal where the ray through `s` meets
    /// it (beyond the outline: at the point of the sphere nearest the ray).
    fn normal(&self, s: [f64; 2]) -> Vec3 {
        let d = self.direction(s);
        let m = self.centre - self.camera;
        let (md, dd) = (m.dot(d), d.dot(d));
        let disc = md * md - dd * self.k;
        let t = (md - disc.max(0.0).sqrt()) / dd;
        let p = self.camera + d * t;
        (p - self.centre)
            .normalized()
            .unwrap_or(Vec3::new(0.0, 1.0, 0.0))
    }

    /// The sphere's UV (longitude, latitude) where the ray through `s`
    /// meets it (beyond the outline: at the point nearest the ray).
    fn sphere_uv(&self, s: [f64; 2]) -> [f64; 2] {
        let n = self.normal(s);
        let phi = n.z.atan2(n.x);
        let theta = n.y.clamp(-1.0, 1.0).acos();
        [
            (phi + std::f64::consts::PI) / std::f64::consts::TAU,
            1.0 - theta / std::f64::consts::PI,
        ]
    }

    /// `s` in the coordinates that make the outline the unit circle.
    fn circle(&self, s: [f64; 2]) -> [f64; 2] {
        let (x, y) = (s[0] - self.e0[0], s[1] - self.e0[1]);
        let [r0, r1] = self.to_circle;
        [r0[0] * x + r0[1] * y, r1[0] * x + r1[1] * y]
    }

    /// The screen point at angle `theta` on the outline.
    fn outline(&self, theta: f64) -> [f64; 2] {
        let (s, c) = theta.sin_cos();
        [
            self.e0[0] + self.ea[0] * c + self.eb[0] * s,
            self.e0[1] + self.ea[1] * c + self.eb[1] * s,
        ]
    }

    /// The chords that clip `support` (half-planes holding the outline's
    /// centre, into `lines`) and the area they leave
    /// out of the outline's part near the support (screen pixels², the
    /// region's bound at full contrast). `None`: the support lies wholly
    /// outside the outline. No chords: it lies inside every one.
    fn chords(&self, support: &ConvexPolygon, lines: &mut Chords) -> Option<f64> {
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
        // Every corner inside the outline: so is the (convex) support.
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
        let ab = (self.ea[0] * self.eb[1] - self.ea[1] * self.eb[0]).abs();
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
        let mut a = self.outline(from);
        for j in 1..=count {
            let b = self.outline(from + delta * j as f64);
            // The line through a and b, the outline's centre on its ≥ 0 side.
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

    /// The sphere's part of `support` (occlusion ignored): the support
    /// clipped by the chords of its outline ([`SphereView::chords`]).
    pub(crate) fn region_into(&self, support: &ConvexPolygon, out: &mut ConvexPolygon) {
        let mut lines = Chords::default();
        match self.chords(support, &mut lines) {
            None => *out = ConvexPolygon::empty(),
            Some(_) if lines.count == 0 => out.clone_from(support),
            Some(_) => support.clip_lines_into(&lines.lines[..lines.count], out),
        }
    }

    /// Whether `support` lies inside every chord of the outline (its
    /// region is the whole support; no sliver is left out).
    pub(crate) fn holds(&self, support: &ConvexPolygon) -> bool {
        let mut lines = Chords::default();
        self.chords(support, &mut lines) == Some(0.0) && lines.count == 0
    }

    /// The area the chords leave out of the outline near `support`
    /// ([`SphereView::chords`]).
    #[cfg(test)]
    pub(crate) fn sliver_area(&self, support: &ConvexPolygon) -> f64 {
        self.chords(support, &mut Chords::default()).unwrap_or(0.0)
    }

    /// A bound on the weight, under `filter` about `centre`, of what the
    /// chords leave out of the outline near `support` (the sphere's, but
    /// taken as what lies behind it): each chord's segment of the outline,
    /// `a·b·(δ − sin δ)/2`, times the filter's largest `|k|` over the box
    /// of its arc (its ends and the outline's points of extreme `x` or `y`
    /// between them), which holds the segment.
    pub(crate) fn sliver_bound(
        &self,
        support: &ConvexPolygon,
        filter: quadtex_core::PixelFilter,
        centre: [f64; 2],
    ) -> f64 {
        let mut lines = Chords::default();
        if self.chords(support, &mut lines).is_none() || lines.count == 0 {
            return 0.0;
        }
        let ab = (self.ea[0] * self.eb[1] - self.ea[1] * self.eb[0]).abs();
        let delta = lines.delta;
        let segment = ab * 0.5 * (delta - delta.sin());
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
                    let p = self.outline(*t);
                    for a in 0..2 {
                        lo[a] = lo[a].min(p[a]);
                        hi[a] = hi[a].max(p[a]);
                    }
                }
                segment * filter.largest_weight_in((lo, hi), centre)
            })
            .sum()
    }

    /// The line through the points at angles `t0` and `t1` on the
    /// outline scaled by `r` about its centre, as `a·x + b·y + c ≥ 0` on
    /// the centre's side.
    fn chord_line(&self, t0: f64, t1: f64, r: f64) -> [f64; 3] {
        let point = |t: f64| {
            let (sn, cs) = t.sin_cos();
            [
                self.e0[0] + r * (self.ea[0] * cs + self.eb[0] * sn),
                self.e0[1] + r * (self.ea[1] * cs + self.eb[1] * sn),
            ]
        };
        let (a, b) = (point(t0), point(t1));
        let (la, lb) = (a[1] - b[1], b[0] - a[0]);
        let lc = -(la * a[0] + lb * a[1]);
        let sign = if la * self.e0[0] + lb * self.e0[1] + lc >= 0.0 {
            1.0
        } else {
            -1.0
        };
        [sign * la, sign * lb, sign * lc]
    }

    /// The half-plane left of the ray from the outline's centre at angle
    /// `t` (counter-clockwise of it, as angles grow).
    fn left_of_ray(&self, t: f64) -> [f64; 3] {
        let (sn, cs) = t.sin_cos();
        let d = [
            self.ea[0] * cs + self.eb[0] * sn,
            self.ea[1] * cs + self.eb[1] * sn,
        ];
        [-d[1], d[0], d[1] * self.e0[0] - d[0] * self.e0[1]]
    }

    /// Sectors for a support wholly inside the outline but within about
    /// a pixel and a half of it (the rings reach it): its angles seen from
    /// the centre cut into pieces of about half a pixel along the outline,
    /// into `sectors` (no chord lines: the support needs no clip). False
    /// when the support lies further in, or holds the centre.
    fn sectors_near_outline(&self, support: &ConvexPolygon, sectors: &mut Chords) -> bool {
        sectors.count = 0;
        let minor = self.eb[0]
            .hypot(self.eb[1])
            .min(self.ea[0].hypot(self.ea[1]));
        let major = self.eb[0]
            .hypot(self.eb[1])
            .max(self.ea[0].hypot(self.ea[1]));
        let near = 1.0 - 1.5 / minor;
        let q: Vec<[f64; 2]> = support.vertices().iter().map(|&s| self.circle(s)).collect();
        let farthest = q.iter().fold(0f64, |m, p| m.max(p[0] * p[0] + p[1] * p[1]));
        if q.is_empty() || near <= 0.0 || farthest < near * near {
            return false;
        }
        let (from, span) = angles_seen(&q);
        if !(span > 0.0 && span < 3.0) {
            return false;
        }
        sectors.from = from;
        sectors.count = ((span * major / 0.5).ceil() as usize).clamp(1, MAX_CHORDS);
        sectors.delta = span / sectors.count as f64;
        true
    }
}

/// The angles `points` (in the outline's unit-circle coordinates, not
/// around the centre) are seen at from the centre: `(from, span)`, the
/// smallest arc holding them all, measured from the first point's angle.
fn angles_seen(points: &[[f64; 2]]) -> (f64, f64) {
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

mod arcs;
mod fan;
mod pieces;

pub(crate) use fan::PolarFans;

#[cfg(test)]
mod tests;

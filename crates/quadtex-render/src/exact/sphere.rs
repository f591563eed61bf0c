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
//! [`SLIVER_BUDGET`](conic::SLIVER_BUDGET) (up to [`MAX_CHORDS`]): the sum is the region's area
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
//! over it by little, [`light`]), that is the region's colour, with no
//! fit and no pieces; where one texture edge parts it into two colours,
//! it is split along the edge's own image, an ellipse clipped by chords
//! ([`edges`], [`conic`]). Inside the outline, a textured sphere first
//! tries the box of a run of pixels along the row ([`runs`]). The
//! pieces:
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
//! piece's centroid (its own normal and shadow ray); a region taken in
//! closed form carries the light's error in its bound ([`light`]).

use quadtex_core::ConvexPolygon;

use crate::math::Vec3;

use crate::scene::{Geometry, Scene};
use conic::{Chords, Ellipse, MAX_CHORDS, angles_seen};

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
    /// The outline.
    outline: Ellipse,
    /// Texture point from the sphere's `(u, v, 1)`: the surface's UV
    /// transform, two affine rows.
    texture_from_uv: [[f64; 3]; 2],
    /// The texture redrawn around the poles ([`PolarFans`]).
    fans: std::sync::Arc<PolarFans>,
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
        let outline = Ellipse::from_form([a00, a01, a11], [b0, b1], c)?;
        let transform = s.uv_transform;
        let o = transform.apply([0.0, 0.0]);
        let ex = transform.apply([1.0, 0.0]);
        let ez = transform.apply([0.0, 1.0]);
        static STAMPS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        Some(SphereView {
            stamp: STAMPS.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            surface,
            centre,
            radius,
            camera: cam.position,
            basis: [d0, dx, dy],
            k,
            outline,
            texture_from_uv: [
                [ex[0] - o[0], ez[0] - o[0], o[0]],
                [ex[1] - o[1], ez[1] - o[1], o[1]],
            ],
            fans: (s.texture.as_ref())
                .map(|t| t.polar_fans(&s.uv_transform, s.wrap))
                .unwrap_or_default(),
        })
    }

    /// The surface this is the view of.
    pub(crate) fn surface(&self) -> usize {
        self.surface
    }

    /// Whether the outline's screen box misses the box `(lo, hi)`.
    pub(crate) fn misses_box(&self, lo: [f64; 2], hi: [f64; 2]) -> bool {
        let o = &self.outline;
        o.hi[0] < lo[0] || o.lo[0] > hi[0] || o.hi[1] < lo[1] || o.lo[1] > hi[1]
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
        self.outline.circle(s)
    }

    /// The chords of the outline that clip `support` ([`Ellipse::chords`]).
    fn chords(&self, support: &ConvexPolygon, lines: &mut Chords) -> Option<f64> {
        self.outline.chords(support, lines)
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
    /// taken as what lies behind it; [`Ellipse::sliver_bound`]).
    pub(crate) fn sliver_bound(
        &self,
        support: &ConvexPolygon,
        filter: quadtex_core::PixelFilter,
        centre: [f64; 2],
    ) -> f64 {
        self.outline.sliver_bound(support, filter, centre)
    }

    /// The line through the points at angles `t0` and `t1` on the
    /// outline scaled by `r` about its centre, as `a·x + b·y + c ≥ 0` on
    /// the centre's side.
    fn chord_line(&self, t0: f64, t1: f64, r: f64) -> [f64; 3] {
        let point = |t: f64| {
            let (sn, cs) = t.sin_cos();
            [
                self.outline.e0[0] + r * (self.outline.ea[0] * cs + self.outline.eb[0] * sn),
                self.outline.e0[1] + r * (self.outline.ea[1] * cs + self.outline.eb[1] * sn),
            ]
        };
        let (a, b) = (point(t0), point(t1));
        let (la, lb) = (a[1] - b[1], b[0] - a[0]);
        let lc = -(la * a[0] + lb * a[1]);
        let sign = if la * self.outline.e0[0] + lb * self.outline.e0[1] + lc >= 0.0 {
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
            self.outline.ea[0] * cs + self.outline.eb[0] * sn,
            self.outline.ea[1] * cs + self.outline.eb[1] * sn,
        ];
        [
            -d[1],
            d[0],
            d[1] * self.outline.e0[0] - d[0] * self.outline.e0[1],
        ]
    }

    /// Sectors for a support wholly inside the outline but within about
    /// a pixel and a half of it (the rings reach it): its angles seen from
    /// the centre cut into pieces of about half a pixel along the outline,
    /// into `sectors` (no chord lines: the support needs no clip). False
    /// when the support lies further in, or holds the centre.
    fn sectors_near_outline(&self, support: &ConvexPolygon, sectors: &mut Chords) -> bool {
        sectors.count = 0;
        let minor = self.outline.eb[0]
            .hypot(self.outline.eb[1])
            .min(self.outline.ea[0].hypot(self.outline.ea[1]));
        let major = self.outline.eb[0]
            .hypot(self.outline.eb[1])
            .max(self.outline.ea[0].hypot(self.outline.ea[1]));
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

mod arcs;
mod conic;
mod edges;
mod fan;
mod light;
mod pieces;
mod runs;

pub(crate) use fan::PolarFans;

#[cfg(test)]
mod tests;

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
//! at the piece's centroid, vertices and edges' midpoints, the screen
//! point the exact map sends to the same texture point lies within `ε`
//! pixels (`ε` the filter's error bound; `|J⁻¹·(H(s) − uv(s))|` with `J`
//! the fit's Jacobian, [`SphereView::map_error`]): a texture edge then
//! moves by at most `ε` pixels, and a pixel it crosses is off by at most
//! `ε` times its length times the contrast. A piece whose every candidate
//! image (the fit's, widened by twice its largest UV error at the check
//! points) lies in one texture square is that square's colour times its
//! weight, exactly, whatever the map's error. The pieces:
//!
//! - **Squares** (most of the disc): the region's bounding square, split
//!   in four while its map is off, at most [`MAX_SPLITS`] times; `H` goes
//!   through the sphere's UV at the square's corners (Heckbert's
//!   square-to-quad; beyond the outline, a corner takes the point of the
//!   sphere nearest its ray). A whole square's checks are its children's
//!   corners ([`Square`]), and points on the half-pixel grid are kept by
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
//! A piece still off whose weight is at most an eighth of what is left of
//! a budget of `ε/2` a call, or one at the deepest split (the poles, where
//! longitude turns around a point), is integrated on its fitted map with
//! its whole weight in the bound. Each kept piece is integrated exactly
//! over the tree ([`quadtex_core::Texture::integrate_region`]), cut at the
//! longitude seam (`u` a whole number) so that each side is read in
//! `[0, 1)`, whatever the texture's wrap. Lambert light is taken at each
//! piece's centroid (its own normal and shadow ray).

use quadtex_core::{ConvexPolygon, Projection};

use crate::frame::lambert;
use crate::math::Vec3;
use crate::scene::{Geometry, Lighting, Scene};
use crate::stats::PixelStats;

use super::lighting::{Shading, apply_light};

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

/// The rings along the outline are spaced for a quarter of the default
/// error bound (pixels), the model's error being an estimate: with another
/// bound the rings are the same and the pieces are checked against it
/// (none of the checkered ball's failed at 1/512).
const RING_TOLERANCE: f64 = 1.0 / 512.0 / 4.0;

/// Deepest split of a sphere's region below its bounding square.
pub(super) const MAX_SPLITS: u32 = 10;

/// One row of [`HALF_PIXEL_UV`]: its tag `(view stamp, 2y)` and the UV
/// by column `2x`, where computed.
type GridRow = ((u64, u32), Vec<Option<[f64; 2]>>);

thread_local! {
    /// The sphere's UV at half-pixel grid points a thread computed lately:
    /// four rows of the grid (row `2y` in slot `2y mod 4`), each tagged with
    /// the view's stamp and its row, by column `2x`.
    static HALF_PIXEL_UV: std::cell::RefCell<[GridRow; 4]> = std::cell::RefCell::default();
}

/// A sphere seen from the camera: its outline on the screen and what
/// mapping a screen point to the sphere's UV takes. Built once per frame.
#[derive(Debug, Clone)]
pub(crate) struct SphereView {
    /// Unique in the process: what tells this view's points in a thread's
    /// [`HALF_PIXEL_UV`] from another's (0 is none's).
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

/// Pieces a sphere's pixel may look at per square of the filter options'
/// budget (the renderer's 64: 1024 pieces). The checkered ball needs at
/// most that many at every pixel; the runway's beacon, a ball of a few
/// pixels whose pole is in view (where longitude turns around a point and
/// squares shrink towards it as they do towards the outline), spends it
/// in a few.
const PIECES_PER_SQUARE: u64 = 16;

/// What a sphere's pixel may still spend ([`SphereView::shade`]): weight
/// that pieces still off the map's tolerance may take whole into the
/// bound (each at most an eighth of what is left), and pieces to look at
/// ([`PIECES_PER_SQUARE`] times the filter options' square budget per
/// pixel of the support; none without one): once they are spent, each piece left is integrated on its
/// fit as it stands, its weight in the bound where the fit is off (the
/// pixel then counts as above the target, as where squares run out).
struct Budget {
    weight: f64,
    pieces: u64,
}

/// One chord's sector of the rings along the outline
/// ([`SphereView::shade_ring`]).
struct Ring<'a> {
    chords: &'a Chords,
    radii: &'a [f64],
    chord: usize,
    /// The screen point and the sphere's UV at ring `k`'s chord end `e`,
    /// at `k·(chords + 1) + e`, where computed.
    corners: &'a mut Vec<Option<([f64; 2], [f64; 2])>>,
}

impl Chords {
    /// The angle where chord (or sector) `j` starts.
    fn angle(&self, j: usize) -> f64 {
        self.from + self.delta * j as f64
    }
}

impl Ring<'_> {
    /// The screen point and UV at ring `k` on the chords' end `e`.
    fn corner(&mut self, view: &SphereView, k: usize, e: usize) -> ([f64; 2], [f64; 2]) {
        let index = k * (self.chords.count + 1) + e;
        if let Some(found) = self.corners[index] {
            return found;
        }
        let theta = self.chords.from + self.chords.delta * e as f64;
        let (sn, cs) = theta.sin_cos();
        let r = self.radii[k];
        let s = [
            view.e0[0] + r * (view.ea[0] * cs + view.eb[0] * sn),
            view.e0[1] + r * (view.ea[1] * cs + view.eb[1] * sn),
        ];
        let found = (s, view.on_sphere(s).uv);
        self.corners[index] = Some(found);
        found
    }
}

/// A point's place on the sphere: its UV (longitude, latitude), the point
/// and its outward normal.
struct OnSphere {
    uv: [f64; 2],
    point: Vec3,
    normal: Vec3,
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

    /// Where the ray through `s` meets the sphere (beyond the outline:
    /// the point of the sphere nearest the ray), and its UV there.
    fn on_sphere(&self, s: [f64; 2]) -> OnSphere {
        let d = self.direction(s);
        let m = self.centre - self.camera;
        let (md, dd) = (m.dot(d), d.dot(d));
        let disc = md * md - dd * self.k;
        let t = (md - disc.max(0.0).sqrt()) / dd;
        let p = self.camera + d * t;
        let n = (p - self.centre)
            .normalized()
            .unwrap_or(Vec3::new(0.0, 1.0, 0.0));
        let phi = n.z.atan2(n.x);
        let theta = n.y.clamp(-1.0, 1.0).acos();
        OnSphere {
            uv: [
                (phi + std::f64::consts::PI) / std::f64::consts::TAU,
                1.0 - theta / std::f64::consts::PI,
            ],
            point: self.centre + n * self.radius,
            normal: n,
        }
    }

    /// The sphere's UV at `s` ([`SphereView::on_sphere`]), kept in the
    /// thread's [`HALF_PIXEL_UV`] when `s` lies on the half-pixel grid
    /// (a pixel's corners, edges' midpoints and centre, shared with the
    /// pixels beside, above and below it): the same bits either way.
    fn uv_at_grid_point(&self, s: [f64; 2]) -> [f64; 2] {
        let (x2, y2) = (2.0 * s[0], 2.0 * s[1]);
        let on_grid = x2 == x2.floor() && y2 == y2.floor() && x2 >= 0.0 && y2 >= 0.0;
        if !(on_grid && x2 < 65536.0 && y2 < 65536.0) {
            return self.on_sphere(s).uv;
        }
        let (column, row) = (x2 as usize, y2 as u32);
        let tag = (self.stamp, row);
        HALF_PIXEL_UV
            .try_with(|rows| {
                let mut rows = rows.borrow_mut();
                let slot = &mut rows[(row % 4) as usize];
                if slot.0 != tag {
                    slot.0 = tag;
                    slot.1.clear();
                }
                if slot.1.len() <= column {
                    slot.1.resize(column + 1, None);
                }
                *slot.1[column].get_or_insert_with(|| self.on_sphere(s).uv)
            })
            .unwrap_or_else(|_| self.on_sphere(s).uv)
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
            let reference = q[0][1].atan2(q[0][0]);
            let (mut lo, mut hi) = (0f64, 0f64);
            for p in &q[1..] {
                let mut a = p[1].atan2(p[0]) - reference;
                if a > std::f64::consts::PI {
                    a -= std::f64::consts::TAU;
                } else if a <= -std::f64::consts::PI {
                    a += std::f64::consts::TAU;
                }
                lo = lo.min(a);
                hi = hi.max(a);
            }
            (reference + lo, hi - lo, MAX_CHORDS)
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
    /// ([`SphereView::chords`]): at most this much of the support's weight
    /// is the sphere's but taken as what lies behind it.
    pub(crate) fn sliver_area(&self, support: &ConvexPolygon) -> f64 {
        self.chords(support, &mut Chords::default()).unwrap_or(0.0)
    }

    /// `(Σ colour·k, Σ k, bound)` of the sphere over screen `region` (a
    /// part of its [`SphereView::region_into`]), split into pieces each
    /// integrated on a projective map within the error bound of the
    /// sphere's (module doc).
    pub(super) fn shade(
        &self,
        shading: &Shading<'_>,
        region: &ConvexPolygon,
        stats: &mut PixelStats,
    ) -> ([f64; 4], f64, f64) {
        let mut sums = ([0.0; 4], 0.0, 0.0);
        if region.is_empty() {
            return sums;
        }
        let tolerance = shading.options.target_bound().unwrap_or(1.0 / 512.0);
        let support = shading.filter.support(shading.centre);
        let mut spare = Budget {
            weight: 0.5 * tolerance,
            pieces: (shading.options.budget()).map_or(u64::MAX, |b| {
                // Per pixel of the support: a tent's is 4, a Mitchell's 16.
                let pixels = support.area().round().max(1.0) as u64;
                b.saturating_mul(PIECES_PER_SQUARE).saturating_mul(pixels)
            }),
        };
        let mut chords = Chords::default();
        let crossing = self.chords(&support, &mut chords).is_some() && chords.count > 0;
        if !crossing && !self.sectors_near_outline(&support, &mut chords) {
            self.shade_squares(shading, region, &mut spare, &mut sums, stats);
            return sums;
        }
        // Along the outline: rings of trapezoids between the chords'
        // polygon and ones like it further in, each thin where the map's
        // square root bends most; inside them, squares.
        let radii = self.ring_radii(&chords);
        if radii.len() < 2 {
            self.shade_squares(shading, region, &mut spare, &mut sums, stats);
            return sums;
        }
        // One texture square may hold all of it.
        let (lo, hi) = region.bounds();
        let mut whole = Square::new(lo, (hi[0] - lo[0]).max(hi[1] - lo[1]));
        if let Some(fit) = self.fit(&mut whole)
            && let uv_error = self.map_error(&fit, region, &mut whole, &[]).1
            && let Some(colour) = self.uniform(shading, &fit, region, uv_error)
        {
            self.add_uniform(shading, region, colour, &mut sums, stats);
            return sums;
        }
        let mut corners = vec![None; radii.len() * (chords.count + 1)];
        for j in 0..chords.count {
            let mut ring = Ring {
                chords: &chords,
                radii: &radii,
                chord: j,
                corners: &mut corners,
            };
            self.shade_ring(
                shading,
                region,
                &mut ring,
                (0, radii.len() - 1),
                &mut spare,
                &mut sums,
                stats,
            );
        }
        let inner = radii[radii.len() - 1];
        let lines: Vec<[f64; 3]> = (0..chords.count)
            .map(|j| self.chord_line(chords.angle(j), chords.angle(j + 1), inner))
            .collect();
        let inside = region.clip_lines(lines);
        if !inside.is_empty() {
            self.shade_squares(shading, &inside, &mut spare, &mut sums, stats);
        }
        sums
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
        let reference = q[0][1].atan2(q[0][0]);
        let (mut lo, mut hi) = (0f64, 0f64);
        for p in &q[1..] {
            let mut a = p[1].atan2(p[0]) - reference;
            if a > std::f64::consts::PI {
                a -= std::f64::consts::TAU;
            } else if a <= -std::f64::consts::PI {
                a += std::f64::consts::TAU;
            }
            lo = lo.min(a);
            hi = hi.max(a);
        }
        let span = hi - lo;
        if !(span > 0.0 && span < 3.0) {
            return false;
        }
        sectors.from = reference + lo;
        sectors.count = ((span * major / 0.5).ceil() as usize).clamp(1, MAX_CHORDS);
        sectors.delta = span / sectors.count as f64;
        true
    }

    /// The q-radii of the rings along the outline, from 1 inward: the
    /// `k`-th `4·RING_TOLERANCE·k²` pixels in (along the middle of the
    /// chords' span), to a pixel: so that a fit across each, off by about
    /// `w²/(8·δ)` for width `w` at `δ` from the outline (the first by about
    /// `w/5`), stays within the default bound.
    fn ring_radii(&self, chords: &Chords) -> Vec<f64> {
        let theta = chords.from + 0.5 * chords.delta * chords.count as f64;
        let (sn, cs) = theta.sin_cos();
        let scale = (self.ea[0] * cs + self.eb[0] * sn).hypot(self.ea[1] * cs + self.eb[1] * sn);
        let tolerance = RING_TOLERANCE;
        let mut radii = vec![1.0];
        for k in 1.. {
            let depth = 4.0 * tolerance * f64::from(k) * f64::from(k);
            let r = 1.0 - depth / scale;
            if r.is_nan() || r <= 0.5 || depth > 1.0 {
                break;
            }
            radii.push(r);
        }
        radii
    }

    /// The colour of the texture over all of `piece` when one texture
    /// square holds every image it may have under `fit` or, off by at most
    /// twice `uv_error` (the fit's at the check points), under the
    /// sphere's map;
    /// `Some(None)` when the surface has no texture.
    fn uniform(
        &self,
        shading: &Shading<'_>,
        fit: &[[f64; 3]; 3],
        piece: &ConvexPolygon,
        uv_error: f64,
    ) -> Option<Option<quadtex_core::Rgba>> {
        let Some(texture) = shading.frame.texture(self.surface) else {
            return Some(None);
        };
        let (lo, hi) = self.texture_box(fit, piece, uv_error)?;
        texture.uniform_colour_in_box(lo, hi).map(Some)
    }

    /// Adds `piece` in one colour (`None`: the surface's own) to `sums`.
    fn add_uniform(
        &self,
        shading: &Shading<'_>,
        piece: &ConvexPolygon,
        colour: Option<quadtex_core::Rgba>,
        sums: &mut ([f64; 4], f64, f64),
        stats: &mut PixelStats,
    ) {
        let w = shading.filter.integral(piece, shading.centre);
        let c = colour.map_or([w; 4], |c| c.to_array().map(|v| f64::from(v) * w));
        if colour.is_some() {
            stats.textured = 1;
            stats.filter.footprints += 1;
            stats.filter.fragments += 1;
        }
        add(sums, self.finish(shading, piece, c), w, 0.0);
    }

    /// [`SphereView::shade`] of `region`'s part between rings `a` and `b`
    /// of one chord's sector: one colour where one texture square holds
    /// it; else, across several rings, each half in turn; across one, on
    /// the projective map through the sphere's UV at its corners where
    /// that is within the tolerance, else by squares.
    #[allow(clippy::too_many_arguments)]
    fn shade_ring(
        &self,
        shading: &Shading<'_>,
        region: &ConvexPolygon,
        ring: &mut Ring<'_>,
        (a, b): (usize, usize),
        spare: &mut Budget,
        sums: &mut ([f64; 4], f64, f64),
        stats: &mut PixelStats,
    ) {
        let j = ring.chord;
        let ends = [(a, j), (a, j + 1), (b, j + 1), (b, j)].map(|(k, e)| ring.corner(self, k, e));
        let corners = ends.map(|(s, _)| s);
        // The sector's wedge, beyond ring b's chord and (past the first
        // ring) within ring a's; the first ring reaches the outline, so
        // that a support inside it but beyond its chord loses nothing.
        let (t0, t1) = (ring.chords.angle(j), ring.chords.angle(j + 1));
        let beyond = self.chord_line(t0, t1, ring.radii[b]).map(|v| -v);
        let mut lines = vec![
            self.left_of_ray(t0),
            self.left_of_ray(t1).map(|v| -v),
            beyond,
        ];
        if a > 0 {
            lines.push(self.chord_line(t0, t1, ring.radii[a]));
        }
        let piece = region.clip_lines(lines);
        if piece.is_empty() {
            return;
        }
        let first = ends[0].1;
        let uv = ends.map(|(_, [u, v])| [u + (first[0] - u).round(), v]);
        let fit = quad_to_quad(corners, uv);
        let mut nowhere = Square::new([f64::NAN, f64::NAN], f64::NAN);
        let (error, uv_error) = fit.map_or((f64::INFINITY, f64::INFINITY), |f| {
            self.map_error(&f, &piece, &mut nowhere, &corners)
        });
        if let Some(fit) = &fit
            && let Some(colour) = self.uniform(shading, fit, &piece, uv_error)
        {
            self.add_uniform(shading, &piece, colour, sums, stats);
            return;
        }
        let tolerance = shading.options.target_bound().unwrap_or(1.0 / 512.0);
        spare.pieces = spare.pieces.saturating_sub(1);
        if spare.pieces == 0
            && let Some(fit) = fit
        {
            // The budget is spent: this piece on its fit, its weight in
            // the bound unless the fit is within the tolerance.
            let (c, w, b) = self.shade_piece(shading, &piece, &fit, stats);
            let off = if error > tolerance { w.abs() } else { 0.0 };
            add(sums, self.finish(shading, &piece, c), w, b + off);
            return;
        }
        if b - a > 1 {
            let middle = (a + b) / 2;
            for half in [(a, middle), (middle, b)] {
                self.shade_ring(shading, region, ring, half, spare, sums, stats);
            }
            return;
        }
        match fit {
            Some(fit) if error <= tolerance => {
                let (c, w, b) = self.shade_piece(shading, &piece, &fit, stats);
                add(sums, self.finish(shading, &piece, c), w, b);
            }
            _ => self.shade_squares(shading, &piece, spare, sums, stats),
        }
    }

    /// [`SphereView::shade`] of `region` by squares, from its bounding
    /// square down, into `sums`.
    fn shade_squares(
        &self,
        shading: &Shading<'_>,
        region: &ConvexPolygon,
        spare: &mut Budget,
        sums: &mut ([f64; 4], f64, f64),
        stats: &mut PixelStats,
    ) {
        let (lo, hi) = region.bounds();
        let side = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        if region.is_empty() || !(side > 0.0 && side.is_finite()) {
            return;
        }
        let tolerance = shading.options.target_bound().unwrap_or(1.0 / 512.0);
        let texture = shading.frame.texture(self.surface);
        let mut squares = vec![Square::new(lo, side)];
        while let Some(mut square) = squares.pop() {
            let Square { x0, y0, h, .. } = square;
            let piece = region.clip_rect(x0, y0, x0 + h, y0 + h);
            if piece.is_empty() {
                continue;
            }
            let fit = self.fit(&mut square);
            let (error, uv_error) = fit.map_or((f64::INFINITY, f64::INFINITY), |f| {
                self.map_error(&f, &piece, &mut square, &[])
            });
            // Exact whatever the map's error: one texture square holds
            // every image the piece may have (or there is no texture).
            let uniform = match (texture, &fit) {
                (None, _) => Some(None),
                (Some(texture), Some(f)) => self
                    .texture_box(f, &piece, uv_error)
                    .and_then(|(lo, hi)| texture.uniform_colour_in_box(lo, hi))
                    .map(Some),
                _ => None,
            };
            let w = shading.filter.integral(&piece, shading.centre);
            if let Some(colour) = uniform {
                let c = colour.map_or([w; 4], |c| c.to_array().map(|v| f64::from(v) * w));
                if texture.is_some() {
                    stats.textured = 1;
                    stats.filter.footprints += 1;
                    stats.filter.fragments += 1;
                }
                add(sums, self.finish(shading, &piece, c), w, 0.0);
                continue;
            }
            let off = error > tolerance;
            let spent = off && w.abs() <= 0.125 * spare.weight;
            spare.pieces = spare.pieces.saturating_sub(1);
            if off && !spent && square.depth < MAX_SPLITS && spare.pieces > 0 {
                for child in square.children(self) {
                    squares.push(child);
                }
                continue;
            }
            if spent {
                spare.weight -= w.abs();
            }
            let fit = match fit {
                Some(f) => f,
                None => match self.tangent_fit(piece.centroid(), h) {
                    Some(f) => f,
                    None => continue,
                },
            };
            let (c, w, b) = self.shade_piece(shading, &piece, &fit, stats);
            let off = if off { w.abs() } else { 0.0 };
            add(sums, self.finish(shading, &piece, c), w, b + off);
        }
    }

    /// The projective map from the screen to the sphere's `(u, v)` through
    /// its UV at the corners of the square `[x0, x0 + h]²` (longitude
    /// unwrapped around the first corner's), rows acting on
    /// `(px, py, 1)` with `w > 0` over the square; `None` when the corners'
    /// quadrilateral has no such map (it folds).
    fn fit(&self, square: &mut Square) -> Option<[[f64; 3]; 3]> {
        let Square { x0, y0, h, .. } = *square;
        let first = square.uv(self, 0, 0);
        let mut corner = |i: usize, j: usize| {
            let [u, v] = square.uv(self, i, j);
            [u + (first[0] - u).round(), v]
        };
        let p = [first, corner(2, 0), corner(2, 2), corner(0, 2)];
        let quad = square_to_quad(p)?;
        // Screen to the unit square: (s − (x0, y0)) / h.
        let unit = [
            [1.0 / h, 0.0, -x0 / h],
            [0.0, 1.0 / h, -y0 / h],
            [0.0, 0.0, 1.0],
        ];
        let m = mul(&quad, &unit);
        let w = |s: [f64; 2]| m[2][0] * s[0] + m[2][1] * s[1] + m[2][2];
        let corners = [[x0, y0], [x0 + h, y0], [x0 + h, y0 + h], [x0, y0 + h]];
        let signs: Vec<f64> = corners.iter().map(|&s| w(s)).collect();
        if signs.iter().all(|&v| v > 0.0) {
            Some(m)
        } else if signs.iter().all(|&v| v < 0.0) {
            Some(m.map(|row| row.map(|v| -v)))
        } else {
            None
        }
    }

    /// The affine map through the sphere's UV at `c` with its derivatives
    /// there (central differences over `h / 64`): the fallback where the
    /// corners' map folds.
    fn tangent_fit(&self, c: [f64; 2], h: f64) -> Option<[[f64; 3]; 3]> {
        let e = (h / 64.0).max(1e-9);
        let at = self.on_sphere(c).uv;
        let near = |s: [f64; 2]| {
            let [u, v] = self.on_sphere(s).uv;
            [u + (at[0] - u).round(), v]
        };
        let (xp, xm) = (near([c[0] + e, c[1]]), near([c[0] - e, c[1]]));
        let (yp, ym) = (near([c[0], c[1] + e]), near([c[0], c[1] - e]));
        let du = [(xp[0] - xm[0]) / (2.0 * e), (yp[0] - ym[0]) / (2.0 * e)];
        let dv = [(xp[1] - xm[1]) / (2.0 * e), (yp[1] - ym[1]) / (2.0 * e)];
        let m = [
            [du[0], du[1], at[0] - du[0] * c[0] - du[1] * c[1]],
            [dv[0], dv[1], at[1] - dv[0] * c[0] - dv[1] * c[1]],
            [0.0, 0.0, 1.0],
        ];
        let det = du[0] * dv[1] - du[1] * dv[0];
        (det.is_finite() && det.abs() > 1e-300).then_some(m)
    }

    /// The largest screen distance, at `piece`'s check points, between a
    /// point and the one the sphere's map sends where `fit` sends it
    /// (first order: `|J⁻¹·(H(s) − uv(s))|`, `J` the fit's Jacobian), and
    /// the largest UV difference there. The check points: a whole
    /// `square`'s centre and edges' midpoints; else the piece's centroid,
    /// edges' midpoints and vertices but the square's corners and `exact`
    /// (where the fit passes through the sphere's UV).
    fn map_error(
        &self,
        fit: &[[f64; 3]; 3],
        piece: &ConvexPolygon,
        square: &mut Square,
        exact: &[[f64; 2]],
    ) -> (f64, f64) {
        let Square { x0, y0, h, .. } = *square;
        let v = piece.vertices();
        let c = piece.centroid();
        let n = v.len();
        let mut worst = 0f64;
        let mut worst_uv = 0f64;
        let mut check = |s: [f64; 2], square: &mut Square| {
            let w = fit[2][0] * s[0] + fit[2][1] * s[1] + fit[2][2];
            let hu = (fit[0][0] * s[0] + fit[0][1] * s[1] + fit[0][2]) / w;
            let hv = (fit[1][0] * s[0] + fit[1][1] * s[1] + fit[1][2]) / w;
            let [u, uv_v] = square.uv_at(self, s);
            let e = [u + (hu - u).round() - hu, uv_v - hv];
            worst_uv = worst_uv.max(e[0].abs().max(e[1].abs()));
            // Jacobian of (a·s̃ / w·s̃): (a_xy − value·w_xy) / w.
            let j = [
                [
                    (fit[0][0] - hu * fit[2][0]) / w,
                    (fit[0][1] - hu * fit[2][1]) / w,
                ],
                [
                    (fit[1][0] - hv * fit[2][0]) / w,
                    (fit[1][1] - hv * fit[2][1]) / w,
                ],
            ];
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            let d = if w > 0.0 && det.abs() > 1e-300 {
                let dx = (j[1][1] * e[0] - j[0][1] * e[1]) / det;
                let dy = (-j[1][0] * e[0] + j[0][0] * e[1]) / det;
                (dx * dx + dy * dy).sqrt()
            } else {
                f64::INFINITY
            };
            worst = worst.max(if d.is_nan() { f64::INFINITY } else { d });
        };
        // The fit is exact at the square's corners.
        let corner = |p: [f64; 2]| (p[0] == x0 || p[0] == x0 + h) && (p[1] == y0 || p[1] == y0 + h);
        if n == 4 && v.iter().all(|&p| corner(p)) {
            // The whole square: its centre and edges' midpoints, which
            // are its children's corners.
            for (i, j) in [(1, 1), (1, 0), (2, 1), (1, 2), (0, 1)] {
                let s = square.point(i, j);
                check(s, square);
            }
        } else {
            check(c, square);
            for i in 0..n {
                let (a, b) = (v[i], v[(i + 1) % n]);
                if !corner(a) && !exact.contains(&a) {
                    check(a, square);
                }
                check([0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])], square);
            }
        }
        if worst_uv.is_nan() {
            worst_uv = f64::INFINITY;
        }
        (worst, worst_uv)
    }

    /// A texture-space box holding the image of `piece` under the fitted
    /// map `fit` and, by its error at the check points (`uv_error`, doubled
    /// for margin), under the sphere's own; `None` where the piece reaches
    /// across the longitude seam or the box is not finite.
    fn texture_box(
        &self,
        fit: &[[f64; 3]; 3],
        piece: &ConvexPolygon,
        uv_error: f64,
    ) -> Option<([f64; 2], [f64; 2])> {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for &s in piece.vertices() {
            let w = fit[2][0] * s[0] + fit[2][1] * s[1] + fit[2][2];
            if w.is_nan() || w <= 0.0 {
                return None;
            }
            for a in 0..2 {
                let t = (fit[a][0] * s[0] + fit[a][1] * s[1] + fit[a][2]) / w;
                lo[a] = lo[a].min(t);
                hi[a] = hi[a].max(t);
            }
        }
        let margin = 2.0 * uv_error + 1e-12;
        let (lo, hi) = (lo.map(|v| v - margin), hi.map(|v| v + margin));
        let turn = lo[0].floor();
        if !(turn.is_finite() && hi[0].floor() == turn) {
            return None;
        }
        let t = &self.texture_from_uv;
        let (mut tlo, mut thi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for (u, v) in [
            (lo[0], lo[1]),
            (hi[0], lo[1]),
            (hi[0], hi[1]),
            (lo[0], hi[1]),
        ] {
            let u = u - turn;
            for a in 0..2 {
                let x = t[a][0] * u + t[a][1] * v + t[a][2];
                tlo[a] = tlo[a].min(x);
                thi[a] = thi[a].max(x);
            }
        }
        Some((tlo, thi))
    }

    /// `(Σ colour·k, Σ k, bound)` of one piece on map `fit` (to the
    /// sphere's UV), cut at the seams `u ∈ ℤ` and each side read in
    /// `[0, 1)`; tinted and lit at the piece's centroid.
    fn shade_piece(
        &self,
        shading: &Shading<'_>,
        piece: &ConvexPolygon,
        fit: &[[f64; 3]; 3],
        stats: &mut PixelStats,
    ) -> ([f64; 4], f64, f64) {
        let Shading {
            frame,
            filter,
            centre,
            options,
        } = *shading;
        let value = |row: &[f64; 3], s: [f64; 2]| row[0] * s[0] + row[1] * s[1] + row[2];
        let u_at = |s: [f64; 2]| value(&fit[0], s) / value(&fit[2], s);
        let (mut u_lo, mut u_hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for &s in piece.vertices() {
            let u = u_at(s);
            u_lo = u_lo.min(u);
            u_hi = u_hi.max(u);
        }
        let mut colour = [0.0; 4];
        let (mut weight, mut bound) = (0.0, 0.0);
        let texture = frame.texture(self.surface);
        if !(u_lo.is_finite() && u_hi.is_finite()) {
            return (colour, 0.0, 0.0);
        }
        let first = u_lo.floor() as i64;
        let last = (u_hi.floor() as i64).max(first);
        for turn in first..=last {
            let k = turn as f64;
            // The piece's part with u in [k, k + 1), its u moved by −k.
            let shifted = [
                [
                    fit[0][0] - k * fit[2][0],
                    fit[0][1] - k * fit[2][1],
                    fit[0][2] - k * fit[2][2],
                ],
                fit[1],
                fit[2],
            ];
            let part = if first == last {
                piece.clone()
            } else {
                let upper = [
                    fit[2][0] - shifted[0][0],
                    fit[2][1] - shifted[0][1],
                    fit[2][2] - shifted[0][2],
                ];
                let mut lines = Vec::with_capacity(2);
                if turn > first {
                    lines.push(shifted[0]);
                }
                if turn < last {
                    lines.push(upper);
                }
                piece.clip_lines(lines)
            };
            if part.is_empty() {
                continue;
            }
            let (c, w, b) = match texture {
                Some(texture) => {
                    stats.textured = 1;
                    let t = &self.texture_from_uv;
                    let rows = [0, 1].map(|r| {
                        [0, 1, 2].map(|col| {
                            t[r][0] * shifted[0][col]
                                + t[r][1] * shifted[1][col]
                                + t[r][2] * shifted[2][col]
                        })
                    });
                    let Ok(projection) = Projection::new([rows[0], rows[1], shifted[2]]) else {
                        let w = filter.integral(&part, centre);
                        weight += w;
                        bound += w.abs();
                        continue;
                    };
                    let r = texture.integrate_region(
                        &projection,
                        &part,
                        filter,
                        centre,
                        options,
                        &mut stats.filter,
                    );
                    (r.colour.0, r.weight, r.error_bound)
                }
                None => {
                    let w = filter.integral(&part, centre);
                    ([w; 4], w, 0.0)
                }
            };
            for (a, v) in colour.iter_mut().zip(c) {
                *a += v;
            }
            weight += w;
            bound += b;
        }
        (colour, weight, bound)
    }

    /// A piece's texture integral `c` tinted by the surface's colour and
    /// lit at the piece's centroid (its normal and shadow ray there).
    fn finish(&self, shading: &Shading<'_>, piece: &ConvexPolygon, mut c: [f64; 4]) -> [f64; 4] {
        let scene = shading.frame.scene;
        let tint = scene.surfaces[self.surface]
            .colour
            .to_array()
            .map(f64::from);
        for (v, t) in c.iter_mut().zip(tint) {
            *v *= t;
        }
        if let Lighting::Lambert { .. } = scene.lighting {
            let s = piece.centroid();
            let at = self.on_sphere(s);
            let ray = scene.camera.ray(s[0], s[1]);
            let k = lambert(
                &shading.frame.rays,
                (self.surface, 0),
                at.normal,
                at.point,
                &ray,
            );
            apply_light(&mut c, k);
        }
        c
    }
}

/// A square of a region's split, `[x0, x0 + h]²`, with the sphere's UV
/// at the points of its 3 × 3 grid (corners, edges' midpoints, centre)
/// as far as they have been computed: a whole square's checks are its
/// children's corners, and its corners its parent's grid points.
#[derive(Clone, Copy)]
struct Square {
    x0: f64,
    y0: f64,
    h: f64,
    depth: u32,
    /// `uv[j][i]` at [`Square::point`]`(i, j)`.
    uv: [[Option<[f64; 2]>; 3]; 3],
}

impl Square {
    fn new(lo: [f64; 2], h: f64) -> Square {
        Square {
            x0: lo[0],
            y0: lo[1],
            h,
            depth: 0,
            uv: [[None; 3]; 3],
        }
    }

    /// Grid point `(i, j)`, `i, j ∈ 0..3` (the midpoints by the same
    /// expression as an edge's midpoint).
    fn point(&self, i: usize, j: usize) -> [f64; 2] {
        let at = |lo: f64, k: usize| match k {
            0 => lo,
            1 => 0.5 * (lo + (lo + self.h)),
            _ => lo + self.h,
        };
        [at(self.x0, i), at(self.y0, j)]
    }

    /// The sphere's UV at grid point `(i, j)`.
    fn uv(&mut self, view: &SphereView, i: usize, j: usize) -> [f64; 2] {
        if let Some(uv) = self.uv[j][i] {
            return uv;
        }
        let uv = view.uv_at_grid_point(self.point(i, j));
        self.uv[j][i] = Some(uv);
        uv
    }

    /// The sphere's UV at `s`, kept when `s` is a grid point.
    fn uv_at(&mut self, view: &SphereView, s: [f64; 2]) -> [f64; 2] {
        let (xs, ys) = (
            [0, 1, 2].map(|k| self.point(k, k)[0]),
            [0, 1, 2].map(|k| self.point(k, k)[1]),
        );
        match (
            xs.iter().position(|&x| x == s[0]),
            ys.iter().position(|&y| y == s[1]),
        ) {
            (Some(i), Some(j)) => self.uv(view, i, j),
            _ => view.on_sphere(s).uv,
        }
    }

    /// The four quarters, their corners' UV taken from this grid.
    fn children(&mut self, view: &SphereView) -> [Square; 4] {
        for j in 0..3 {
            for i in 0..3 {
                self.uv(view, i, j);
            }
        }
        let g = 0.5 * self.h;
        [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(a, b)| {
            let lo = self.point(a, b);
            let mut uv = [[None; 3]; 3];
            for (cj, pj) in [(0, b), (2, b + 1)] {
                for (ci, pi) in [(0, a), (2, a + 1)] {
                    uv[cj][ci] = self.uv[pj][pi];
                }
            }
            Square {
                x0: lo[0],
                y0: lo[1],
                h: g,
                depth: self.depth + 1,
                uv,
            }
        })
    }
}

/// Adds a piece's `(Σ colour·k, Σ k, bound)` to `sums`.
fn add(sums: &mut ([f64; 4], f64, f64), c: [f64; 4], w: f64, b: f64) {
    for (a, v) in sums.0.iter_mut().zip(c) {
        *a += v;
    }
    sums.1 += w;
    sums.2 += b;
}

/// The projective map sending quadrilateral `from` to `to` corner by
/// corner (rows acting on `(x, y, 1)`, `w > 0` at `from`'s corners);
/// `None` when either is degenerate or the map folds.
fn quad_to_quad(from: [[f64; 2]; 4], to: [[f64; 2]; 4]) -> Option<[[f64; 3]; 3]> {
    let a = square_to_quad(from)?;
    let b = square_to_quad(to)?;
    // a⁻¹ up to a factor: its adjugate.
    let adj = [
        [
            a[1][1] * a[2][2] - a[1][2] * a[2][1],
            a[0][2] * a[2][1] - a[0][1] * a[2][2],
            a[0][1] * a[1][2] - a[0][2] * a[1][1],
        ],
        [
            a[1][2] * a[2][0] - a[1][0] * a[2][2],
            a[0][0] * a[2][2] - a[0][2] * a[2][0],
            a[0][2] * a[1][0] - a[0][0] * a[1][2],
        ],
        [
            a[1][0] * a[2][1] - a[1][1] * a[2][0],
            a[0][1] * a[2][0] - a[0][0] * a[2][1],
            a[0][0] * a[1][1] - a[0][1] * a[1][0],
        ],
    ];
    let m = mul(&b, &adj);
    let w = |s: [f64; 2]| m[2][0] * s[0] + m[2][1] * s[1] + m[2][2];
    let signs = from.map(w);
    if signs.iter().all(|&v| v > 0.0) {
        Some(m)
    } else if signs.iter().all(|&v| v < 0.0) {
        Some(m.map(|row| row.map(|v| -v)))
    } else {
        None
    }
}

/// Heckbert's square-to-quad map: rows acting on `(x, y, 1)` of the unit
/// square that send its corners `(0,0), (1,0), (1,1), (0,1)` to `p`;
/// `None` when `p` is degenerate.
fn square_to_quad(p: [[f64; 2]; 4]) -> Option<[[f64; 3]; 3]> {
    let [[x0, y0], [x1, y1], [x2, y2], [x3, y3]] = p;
    let (sx, sy) = (x0 - x1 + x2 - x3, y0 - y1 + y2 - y3);
    let (g, h) = if sx == 0.0 && sy == 0.0 {
        (0.0, 0.0)
    } else {
        let (dx1, dx2, dy1, dy2) = (x1 - x2, x3 - x2, y1 - y2, y3 - y2);
        let det = dx1 * dy2 - dx2 * dy1;
        if det.is_nan() || det.abs() <= 1e-300 {
            return None;
        }
        ((sx * dy2 - dx2 * sy) / det, (dx1 * sy - sx * dy1) / det)
    };
    let m = [
        [x1 - x0 + g * x1, x3 - x0 + h * x3, x0],
        [y1 - y0 + g * y1, y3 - y0 + h * y3, y0],
        [g, h, 1.0],
    ];
    m.iter().flatten().all(|v| v.is_finite()).then_some(m)
}

/// The product `a·b` of two 3×3 matrices.
fn mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_to_quad_sends_the_corners_where_asked() {
        let p = [[0.2, 0.1], [1.3, 0.0], [1.1, 0.9], [0.0, 1.2]];
        let m = square_to_quad(p).unwrap();
        for (corner, want) in [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
            .iter()
            .zip(p)
        {
            let w = m[2][0] * corner[0] + m[2][1] * corner[1] + m[2][2];
            let x = (m[0][0] * corner[0] + m[0][1] * corner[1] + m[0][2]) / w;
            let y = (m[1][0] * corner[0] + m[1][1] * corner[1] + m[1][2]) / w;
            assert!((x - want[0]).abs() < 1e-12 && (y - want[1]).abs() < 1e-12);
        }
    }
}

#[cfg(test)]
mod outline_and_pixels {
    use super::*;
    use crate::options::{PixelFilter, RenderOptions, TextureFilter};

    fn checkered_ball() -> Scene {
        let text = include_str!("../../../../scenes/sphere.toml");
        crate::parse::parse_scene(
            text,
            std::path::Path::new("scenes/sphere.toml"),
            &Default::default(),
        )
        .unwrap()
    }

    /// The support's part inside the outline, in closed form: in the
    /// coordinates that make the outline the unit circle, the signed areas
    /// of each edge's triangle with the centre clipped to the circle
    /// (straight where inside, a sector where outside), scaled back.
    fn inside_area(view: &SphereView, support: &ConvexPolygon) -> f64 {
        let cross = |p: [f64; 2], q: [f64; 2]| p[0] * q[1] - p[1] * q[0];
        let dot = |p: [f64; 2], q: [f64; 2]| p[0] * q[0] + p[1] * q[1];
        let v: Vec<[f64; 2]> = support.vertices().iter().map(|&s| view.circle(s)).collect();
        let mut area = 0.0;
        for i in 0..v.len() {
            let (a, b) = (v[i], v[(i + 1) % v.len()]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let (qa, qb, qc) = (dot(d, d), 2.0 * dot(a, d), dot(a, a) - 1.0);
            let disc = qb * qb - 4.0 * qa * qc;
            let mut points = vec![a];
            if disc > 0.0 {
                for t in [
                    (-qb - disc.sqrt()) / (2.0 * qa),
                    (-qb + disc.sqrt()) / (2.0 * qa),
                ] {
                    if t > 0.0 && t < 1.0 {
                        points.push([a[0] + d[0] * t, a[1] + d[1] * t]);
                    }
                }
            }
            points.push(b);
            for w in points.windows(2) {
                let (p, q) = (w[0], w[1]);
                let m = [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])];
                area += if dot(m, m) < 1.0 {
                    0.5 * cross(p, q)
                } else {
                    0.5 * cross(p, q).atan2(dot(p, q))
                };
            }
        }
        let ab = (view.ea[0] * view.eb[1] - view.ea[1] * view.eb[0]).abs();
        area.abs() * ab
    }

    /// The outline is the sphere's: the screen points the chords' region
    /// holds are ones whose rays meet the sphere, and the region misses
    /// at most its stated sliver of the support's true part, for supports
    /// of the three filters' sizes across the outline (and inside it,
    /// outside it, around a small ball's whole outline).
    #[test]
    fn chords_hold_the_outline_within_their_stated_area() {
        let scene = checkered_ball();
        let view = SphereView::new(&scene, 0).unwrap();
        let mut state = 65;
        let mut rnd = |lo: f64, hi: f64| crate::math::test_uniform(&mut state, lo, hi);
        let mut straddling = 0;
        for i in 0..400 {
            let r = [0.5, 1.0, 2.0][i % 3];
            let angle = rnd(0.0, std::f64::consts::TAU);
            // Most across the outline, some well inside or outside.
            let along = if i % 10 == 0 {
                rnd(0.5, 1.5)
            } else {
                rnd(0.97, 1.03)
            };
            let p = view.outline(angle);
            let c = [
                view.e0[0] + (p[0] - view.e0[0]) * along,
                view.e0[1] + (p[1] - view.e0[1]) * along,
            ];
            let support = ConvexPolygon::rect(c[0] - r, c[1] - r, c[0] + r, c[1] + r);
            let mut region = ConvexPolygon::empty();
            view.region_into(&support, &mut region);
            let sliver = view.sliver_area(&support);
            let truth = inside_area(&view, &support);
            assert!(region.area() <= truth + 1e-9, "{c:?} r {r}");
            let missed = truth - region.area();
            assert!(missed <= sliver + 1e-9, "{c:?} r {r}: {missed} > {sliver}");
            for &s in region.vertices() {
                assert!(view.circle(s)[0].hypot(view.circle(s)[1]) <= 1.0 + 1e-12);
            }
            if region.area() > 0.0 && region.area() < support.area() {
                straddling += 1;
                // Where the cap of chords sets it (a Mitchell support across
                // a 73-pixel ball), about 10⁻⁴ of the support.
                assert!(sliver < 2e-4 * support.area(), "{sliver}");
            }
        }
        assert!(straddling > 200, "{straddling}");
    }

    /// The fitted map's error falls as the square's side squared (a
    /// second-order fit) where the sphere's map is smooth.
    #[test]
    fn fitted_maps_are_second_order_inside_the_outline() {
        let view = SphereView::new(&checkered_ball(), 0).unwrap();
        for c in [[128.0, 96.0], [150.0, 96.0], [128.0, 140.0], [170.0, 60.0]] {
            let error = |h: f64| {
                let (x0, y0) = (c[0] - 0.5 * h, c[1] - 0.5 * h);
                let mut square = Square::new([x0, y0], h);
                let fit = view.fit(&mut square).unwrap();
                let piece = ConvexPolygon::rect(x0, y0, x0 + h, y0 + h);
                view.map_error(&fit, &piece, &mut square, &[]).0
            };
            let (coarse, fine) = (error(1.0), error(0.25));
            assert!(
                fine < coarse / 10.0 && coarse < 1e-2,
                "{c:?}: {coarse} {fine}"
            );
        }
    }

    /// The checkered ball at 64 × 48 against 64 × 64 stratified samples
    /// a pixel (an independent reference: it never calls the sphere's
    /// exact path): the exact pixels come within the reference's own
    /// noise and below 8 × 8 supersampling, where the tangent plane they
    /// replace was above it.
    #[test]
    fn the_checkered_ball_matches_a_converged_reference() {
        let scene = checkered_ball();
        let render = |filter, seed| {
            let options = RenderOptions {
                width: Some(64),
                height: Some(48),
                filter,
                pixel_filter: PixelFilter::Box,
                seed,
            };
            crate::render(&scene, &options, &|_, _| ())
                .unwrap()
                .0
                .pixels
        };
        let rmse = |a: &[quadtex_core::Rgba], b: &[quadtex_core::Rgba]| {
            let sum: f64 = a
                .iter()
                .zip(b)
                .map(|(p, q)| {
                    let d = f64::from(p.r - q.r);
                    d * d
                })
                .sum();
            (sum / a.len() as f64).sqrt()
        };
        let reference = render(TextureFilter::Supersample(64), 11);
        let again = render(TextureFilter::Supersample(64), 12);
        let exact = render(
            TextureFilter::Quadtree(quadtex_core::FilterOptions::RENDER),
            0,
        );
        let sampled = render(TextureFilter::Supersample(8), 13);
        let noise = rmse(&reference, &again) / std::f64::consts::SQRT_2;
        let (e, s) = (rmse(&exact, &reference), rmse(&sampled, &reference));
        assert!(
            e < 2.0 * noise && e < s / 3.0,
            "exact {e}, 64 samples {s}, noise {noise}"
        );
    }

    /// The ball between a checkered wall behind it and a quad in front
    /// of part of it, under each pixel filter: its outline against both,
    /// and the quad's edges across it, against 64 × 64 stratified samples
    /// weighted by the same filter.
    #[test]
    fn the_ball_among_planar_primitives_matches_a_converged_reference() {
        use crate::math::Vec3;
        use crate::scene::{Geometry, Surface, UvTransform};
        let mut scene = checkered_ball();
        let checker = scene.surfaces[0].texture.clone();
        let surface = |geometry, scale: f64| Surface {
            geometry,
            texture: checker.clone(),
            colour: quadtex_core::Rgba::opaque(0.8, 0.9, 1.0),
            uv_transform: UvTransform {
                scale: [scale, scale],
                ..UvTransform::default()
            },
            wrap: quadtex_core::Wrap::REPEAT,
        };
        scene.surfaces.push(surface(
            Geometry::Plane {
                point: Vec3::new(0.0, 0.0, 2.0),
                normal: Vec3::new(0.0, 0.0, -1.0),
                u_axis: Vec3::new(1.0, 0.0, 0.0),
                v_axis: Vec3::new(0.0, 1.0, 0.0),
            },
            0.7,
        ));
        scene.surfaces.push(surface(
            Geometry::Quad {
                origin: Vec3::new(0.3, -1.4, -1.5),
                edge_u: Vec3::new(1.2, 0.3, 0.0),
                edge_v: Vec3::new(0.0, 1.5, 0.4),
            },
            2.0,
        ));
        for pixel_filter in [PixelFilter::Box, PixelFilter::Tent, PixelFilter::Mitchell] {
            let render = |filter, seed| {
                let options = RenderOptions {
                    width: Some(48),
                    height: Some(36),
                    filter,
                    pixel_filter,
                    seed,
                };
                crate::render(&scene, &options, &|_, _| ())
                    .unwrap()
                    .0
                    .pixels
            };
            let reference = render(TextureFilter::Supersample(64), 21);
            let again = render(TextureFilter::Supersample(64), 22);
            let exact = render(
                TextureFilter::Quadtree(quadtex_core::FilterOptions::RENDER),
                0,
            );
            let sampled = render(TextureFilter::Supersample(8), 23);
            let rmse = |a: &[quadtex_core::Rgba], b: &[quadtex_core::Rgba]| {
                let sum: f64 = (a.iter().zip(b))
                    .map(|(p, q)| {
                        let d = f64::from(p.g - q.g);
                        d * d
                    })
                    .sum();
                (sum / a.len() as f64).sqrt()
            };
            let noise = rmse(&reference, &again) / std::f64::consts::SQRT_2;
            let (e, s) = (rmse(&exact, &reference), rmse(&sampled, &reference));
            assert!(
                e < 2.0 * noise && e < s / 3.0,
                "{pixel_filter:?}: exact {e}, 64 samples {s}, noise {noise}"
            );
        }
    }

    /// The ball seen from above, its north pole in view (where longitude
    /// turns around a point and the squares shrink towards it): the image
    /// within the reference's noise, and only the pixels at the pole above
    /// the target (they spend their budget of pieces; a known limit).
    #[test]
    fn a_pole_in_view_keeps_the_bound() {
        let mut scene = checkered_ball();
        scene.camera = crate::scene::Camera::new(
            crate::math::Vec3::new(0.0, 3.0, -4.0),
            crate::math::Vec3::new(0.0, 0.0, 0.0),
            crate::math::Vec3::new(0.0, 1.0, 0.0),
            30.0,
            64,
            48,
        )
        .unwrap();
        let render = |filter, seed| {
            let options = RenderOptions {
                width: Some(64),
                height: Some(48),
                filter,
                pixel_filter: PixelFilter::Box,
                seed,
            };
            crate::render(&scene, &options, &|_, _| ()).unwrap()
        };
        let (exact, summary) = render(
            TextureFilter::Quadtree(quadtex_core::FilterOptions::RENDER),
            0,
        );
        let pole = scene
            .camera
            .project(crate::math::Vec3::new(0.0, 1.0, 0.0))
            .unwrap();
        assert!(
            pole[0] > 1.0 && pole[1] > 1.0,
            "the pole is in the frame: {pole:?}"
        );
        assert!(
            summary.filter.over_target <= 4,
            "{}",
            summary.filter.over_target
        );
        let reference = render(TextureFilter::Supersample(64), 31).0.pixels;
        let again = render(TextureFilter::Supersample(64), 32).0.pixels;
        let sampled = render(TextureFilter::Supersample(8), 33).0.pixels;
        let rmse = |a: &[quadtex_core::Rgba], b: &[quadtex_core::Rgba]| {
            let sum: f64 = (a.iter().zip(b))
                .map(|(p, q)| {
                    let d = f64::from(p.r - q.r);
                    d * d
                })
                .sum();
            (sum / a.len() as f64).sqrt()
        };
        let noise = rmse(&reference, &again) / std::f64::consts::SQRT_2;
        let (e, s) = (rmse(&exact.pixels, &reference), rmse(&sampled, &reference));
        assert!(
            e < 2.0 * noise && e < s / 3.0,
            "exact {e}, 64 samples {s}, noise {noise}"
        );
    }
}

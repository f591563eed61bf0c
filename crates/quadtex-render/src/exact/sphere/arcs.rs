//! The sphere's UV over a screen polygon inside its outline, bounded in
//! closed form rather than through a fitted map: where one texture square
//! holds that box, the polygon is the square's colour times its weight,
//! exactly, with no fit, no check points and no pieces.
//!
//! As `s` runs along a straight screen segment, the camera's rays sweep a
//! plane `Π` through the camera, and the sphere's near side along them is
//! an arc of the circle `Π ∩ sphere`: on the unit sphere of normals,
//! `n(α) = c·m + ρ·(e₁ cos α + e₂ sin α)` with `m` the plane's unit normal,
//! `c = m·(camera − centre)/r`, `ρ = √(1 − c²)`, from the segment's first
//! end (`α = 0`) to its second (`α = β`). The camera sees less than half
//! of that circle, so `β < π`. A linear function of the normal, `g·n`, is
//! `g·c·m + ρ·(g₁ cos α + g₂ sin α)` along the arc (`gᵢ = g·eᵢ`): its
//! extremes are the arc's ends, or `g·c·m ± ρ·|(g₁, g₂)|` where the
//! direction `±(g₁, g₂)` lies between the ends' directions `(1, 0)` and
//! `(cos β, sin β)`. Over the polygon's inside, `g·n` has no other extreme
//! than `n = ±g/|g|`, where it is `±|g|`.
//!
//! So the boundary's arcs give the exact range of `n.y`, and so of the
//! latitude `v = 1 − acos(n.y)/π`, once the poles are known to lie outside
//! (a box of the boundary's `(n.x, n.z)` that misses the origin shows it).
//! The longitude `φ = atan2(n.z, n.x)` has no extreme inside the polygon
//! away from the poles: its range is the boundary's, from the vertices and
//! the points where an arc's longitude turns
//! ([`Arc::longitude_turns`]), all within less than half a turn around
//! the pole's axis, so the furthest clockwise and anticlockwise of them
//! bound it. A range across the seam (`φ = ±π`) runs past `u = 1`; the
//! texture is read only for boxes within one turn. The angles are taken
//! within `1.3·10⁻⁷` ([`atan2_near`]) and the box widened by
//! [`UV_MARGIN`], which covers that and rounding. Tested: every point of random
//! polygons inside the outline, from a tenth of a pixel to five pixels
//! across, lies in its box, which is within 1.25× the range dense
//! sampling finds.

use quadtex_core::ConvexPolygon;

use crate::math::Vec3;
use crate::scene::Lighting;

use super::super::lighting::Shading;
use super::SphereView;

/// What the UV box is widened by on each side: the angles come from
/// [`atan2_near`], within [`ANGLE_ERROR`] of `atan2` (0.42 of this
/// margin in `v`, 0.21 in `u`), and the rest of the rounding (of the
/// normals, relative `10⁻¹⁵` or so) is far less.
const UV_MARGIN: f64 = 1e-7;

/// How far [`atan2_near`] may be from `atan2`, radians.
const ANGLE_ERROR: f64 = 1.3e-7;

// The margin holds the angles' error in `v = 1 − θ/π` (and in `u = (φ + π)/2π`).
const _: () = assert!(ANGLE_ERROR / std::f64::consts::PI < 0.5 * UV_MARGIN);

/// `atan2(y, x)` within [`ANGLE_ERROR`], at about a tenth of the libm
/// call's cost (the box's four angles were two thirds of its time): the
/// ratio of the smaller to the larger magnitude, taken below `tan(π/8)`
/// by `atan t = π/4 + atan((t − 1)/(t + 1))`, in the alternating series
/// `t − t³/3 + … + t¹³/13`, whose error is below its next term,
/// `tan(π/8)¹⁵/15 ≈ 1.21·10⁻⁷` (1.03·10⁻⁷ measured). Signs as `atan2`'s,
/// `−0` included.
pub(super) fn atan2_near(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    let (ax, ay) = (x.abs(), y.abs());
    let (small, large) = if ay > ax { (ax, ay) } else { (ay, ax) };
    if large == 0.0 {
        return f64::atan2(y, x);
    }
    let t = small / large;
    let (t, base) = if t > std::f64::consts::SQRT_2 - 1.0 {
        ((t - 1.0) / (t + 1.0), FRAC_PI_4)
    } else {
        (t, 0.0)
    };
    let t2 = t * t;
    let series = t
        * (1.0
            + t2 * (-1.0 / 3.0
                + t2 * (1.0 / 5.0
                    + t2 * (-1.0 / 7.0
                        + t2 * (1.0 / 9.0 + t2 * (-1.0 / 11.0 + t2 * (1.0 / 13.0)))))));
    let mut a = base + series;
    if ay > ax {
        a = FRAC_PI_2 - a;
    }
    if x.is_sign_negative() {
        a = PI - a;
    }
    if y.is_sign_negative() { -a } else { a }
}

/// Share of the error bound the light may move a polygon's colour by (its
/// cosine's spread times the light's brightest channel times the tinted
/// colour's) for it to be taken in one colour: it is then lit at its
/// centroid, as each of the pieces it would otherwise be cut into is at
/// theirs, and that spread joins the bound.
const LIGHT_SHARE: f64 = 0.25;

/// The lowest and highest value of a function over a set.
#[derive(Debug, Clone, Copy)]
pub(super) struct Range {
    pub(super) lo: f64,
    pub(super) hi: f64,
}

impl Range {
    const EMPTY: Range = Range {
        lo: f64::INFINITY,
        hi: f64::NEG_INFINITY,
    };

    fn take(&mut self, v: f64) {
        self.lo = self.lo.min(v);
        self.hi = self.hi.max(v);
    }
}

/// The arc of normals along one screen segment (module documentation).
struct Arc {
    /// `c·m`, the circle's centre.
    centre: Vec3,
    rho: f64,
    e1: Vec3,
    e2: Vec3,
    /// `(cos β, sin β)` times `ρ` (only their ratio matters), `sin β ≥ 0`.
    end: [f64; 2],
}

impl Arc {
    /// The arc from normal `na` (ray direction `da`) to `nb` (`db`);
    /// `None` when it is a point (the ends then hold it) or not finite.
    fn new(view: &SphereView, (da, na): (Vec3, Vec3), (db, nb): (Vec3, Vec3)) -> Option<Arc> {
        let m = da.cross(db).normalized()?;
        let c = m.dot(view.camera - view.centre) / view.radius;
        let rho2 = 1.0 - c * c;
        if rho2.is_nan() || rho2 <= 1e-24 {
            return None;
        }
        let centre = m * c;
        let e1 = (na - centre).normalized()?;
        let mut e2 = m.cross(e1);
        let b = nb - centre;
        let mut end = [e1.dot(b), e2.dot(b)];
        // The arc is less than half the circle: its second end lies on
        // the side of `e₂` that makes `sin β ≥ 0`.
        if end[1] < 0.0 {
            e2 = -e2;
            end[1] = -end[1];
        }
        end.iter().all(|v| v.is_finite()).then_some(Arc {
            centre,
            rho: rho2.sqrt(),
            e1,
            e2,
            end,
        })
    }

    /// Calls `take` with `(n.x, n.z)` at each point inside the arc where
    /// the longitude `atan2(n.z, n.x)` turns: with `n = A + B cos α +
    /// C sin α` (`A = c·m`, `B = ρe₁`, `C = ρe₂`), its derivative has the
    /// sign of `n.x·n.z′ − n.z·n.x′ = P sin α + Q cos α + K`, `P = A_z B_x −
    /// A_x B_z`, `Q = A_x C_z − A_z C_x`, `K = B_x C_z − B_z C_x`.
    fn longitude_turns(&self, mut take: impl FnMut([f64; 2])) {
        let (a, b, c) = (self.centre, self.e1 * self.rho, self.e2 * self.rho);
        let p = a.z * b.x - a.x * b.z;
        let q = a.x * c.z - a.z * c.x;
        let k = b.x * c.z - b.z * c.x;
        let r2 = p * p + q * q;
        let root2 = r2 - k * k;
        if !(r2 > 0.0 && root2 >= 0.0) {
            return;
        }
        let root = root2.sqrt();
        let [cb, sb] = self.end;
        for sign in [1.0, -1.0] {
            let (cos, sin) = (
                (-k * q + sign * p * root) / r2,
                (-k * p - sign * q * root) / r2,
            );
            if sin >= 0.0 && cos * sb - sin * cb >= 0.0 {
                let n = a + b * cos + c * sin;
                take([n.x, n.z]);
            }
        }
    }

    /// Takes into `range` the extremes of `g·n` inside the arc.
    fn extend(&self, g: Vec3, range: &mut Range) {
        let (g1, g2) = (g.dot(self.e1), g.dot(self.e2));
        let amplitude = self.rho * (g1 * g1 + g2 * g2).sqrt();
        let base = g.dot(self.centre);
        // Direction (a, b) between (1, 0) and (cos β, sin β), β < π.
        let [cb, sb] = self.end;
        let within = |a: f64, b: f64| b >= 0.0 && a * sb - b * cb >= 0.0;
        if within(g1, g2) {
            range.take(base + amplitude);
        }
        if within(-g1, -g2) {
            range.take(base - amplitude);
        }
    }
}

/// What [`SphereView::uv_box`] bounds over a polygon: the sphere's UV
/// box (widened by [`UV_MARGIN`], `u` possibly past 1 where the polygon
/// reaches across the seam from below) and the range of `n·L` for the
/// light direction asked for.
#[derive(Debug, Clone, Copy)]
pub(super) struct UvBox {
    pub(super) lo: [f64; 2],
    pub(super) hi: [f64; 2],
    pub(super) cosine: Range,
}

impl SphereView {
    /// The closed-form box of the sphere's UV over `piece` (inside the
    /// outline) and the range of `n·light` there (module documentation);
    /// `None` where a pole may lie inside or a number is not finite.
    pub(super) fn uv_box(
        &self,
        piece: &ConvexPolygon,
        light: Option<Vec3>,
        camera: &crate::scene::Camera,
    ) -> Option<UvBox> {
        let vertices = piece.vertices();
        if vertices.len() < 3 {
            return None;
        }
        let axes = [
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        let mut ranges = [Range::EMPTY; 4];
        // Where the longitude is furthest clockwise and anticlockwise
        // (as `(n.x, n.z)`): at a vertex or where an arc turns.
        let cross = |p: [f64; 2], q: [f64; 2]| p[0] * q[1] - p[1] * q[0];
        let mut turns: Option<([f64; 2], [f64; 2])> = None;
        let mut turn = |p: [f64; 2]| {
            let (from, to) = turns.get_or_insert((p, p));
            if cross(*from, p) < 0.0 {
                *from = p;
            }
            if cross(*to, p) > 0.0 {
                *to = p;
            }
        };
        let end = |s: [f64; 2]| (self.direction(s), self.normal(s));
        let first = end(vertices[0]);
        let mut this = first;
        for (i, _) in vertices.iter().enumerate() {
            let (d, n) = this;
            ranges[0].take(n.x);
            ranges[1].take(n.y);
            ranges[2].take(n.z);
            turn([n.x, n.z]);
            if let Some(l) = light {
                ranges[3].take(n.dot(l));
            }
            let next = vertices.get(i + 1).map_or(first, |&s| end(s));
            if let Some(arc) = Arc::new(self, (d, n), next) {
                for (k, axis) in axes.iter().enumerate() {
                    arc.extend(*axis, &mut ranges[k]);
                }
                arc.longitude_turns(&mut turn);
                if let Some(l) = light {
                    arc.extend(l, &mut ranges[3]);
                }
            }
            this = next;
        }
        let [x, y, z, mut cosine] = ranges;
        // A box of (n.x, n.z) holding the origin: a pole may lie inside.
        let origin = x.lo <= 0.0 && x.hi >= 0.0 && z.lo <= 0.0 && z.hi >= 0.0;
        if origin
            || [x, y, z]
                .iter()
                .any(|r| !(r.lo.is_finite() && r.hi.is_finite()))
        {
            return None;
        }
        if let Some(l) = light {
            // The light's own point (and its opposite) inside the piece.
            for sign in [1.0, -1.0] {
                let point = self.centre + l * (sign * self.radius);
                if (self.camera - point).dot(l * sign) > 0.0
                    && let Some(s) = camera.project(point)
                    && piece
                        .edge_lines()
                        .all(|[a, b, c]| a * s[0] + b * s[1] + c >= 0.0)
                {
                    cosine.take(sign);
                }
            }
        }
        // The boundary's (n.x, n.z) lie in a box that misses the origin,
        // less than half a turn around it: the furthest clockwise and
        // anticlockwise of them bound the longitude.
        let (from, to) = turns?;
        let pi = std::f64::consts::PI;
        let u = |p: [f64; 2]| (atan2_near(p[1], p[0]) + pi) / std::f64::consts::TAU;
        let (u_lo, mut u_hi) = (u(from), u(to));
        // Across the seam: the anticlockwise end a turn on.
        if u_hi < u_lo {
            u_hi += 1.0;
        }
        // acos(y), as `sphere_uv` takes it, within the same error.
        let v = |y: f64| {
            let y = y.clamp(-1.0, 1.0);
            1.0 - atan2_near(((1.0 - y) * (1.0 + y)).max(0.0).sqrt(), y) / pi
        };
        Some(UvBox {
            lo: [u_lo - UV_MARGIN, v(y.lo) - UV_MARGIN],
            hi: [u_hi + UV_MARGIN, v(y.hi) + UV_MARGIN],
            cosine,
        })
    }

    /// [`SphereView::uv_box`] of `piece` (inside the outline), with the
    /// range of the cosine for the scene's light, if any.
    pub(super) fn region_uv_box(
        &self,
        shading: &Shading<'_>,
        piece: &ConvexPolygon,
    ) -> Option<UvBox> {
        let scene = shading.frame.scene;
        let light = match scene.lighting {
            Lighting::Lambert { direction, .. } => Some(direction),
            Lighting::Unlit => None,
        };
        self.uv_box(piece, light, &scene.camera)
    }

    /// A bound on `∫|k|` over `piece`, whose filter integral is `w`: the
    /// light's per-unit-weight bound ([`SphereView::light_bound`]) is
    /// multiplied by it. `|w|` where `k ≥ 0` (box, tent); under Mitchell,
    /// whose negative lobes can cancel part of `∫k`, the filter's largest
    /// `|k|` over the piece's box times its area where that is more.
    pub(super) fn absolute_weight(
        &self,
        shading: &Shading<'_>,
        piece: &ConvexPolygon,
        w: f64,
    ) -> f64 {
        match shading.filter {
            quadtex_core::PixelFilter::Mitchell => w.abs().max(
                shading
                    .filter
                    .largest_weight_in(piece.bounds(), shading.centre)
                    * piece.area(),
            ),
            _ => w.abs(),
        }
    }

    /// A bound on how far the light anywhere in a piece whose UV box is
    /// `uv` takes its colour (in `texels`, `None` for the surface's own)
    /// from the light at its centroid, per unit weight: the cosine's spread
    /// times the light's brightest channel times the brightest tinted
    /// colour's, `0` unlit. `None` when that is above [`LIGHT_SHARE`] of
    /// the bound: the piece is then cut into pieces each lit at its own
    /// centroid.
    pub(super) fn light_bound(
        &self,
        shading: &Shading<'_>,
        piece: &ConvexPolygon,
        uv: &UvBox,
        texels: &[Option<quadtex_core::Rgba>],
    ) -> Option<f64> {
        let scene = shading.frame.scene;
        let Lighting::Lambert {
            direction, colour, ..
        } = scene.lighting
        else {
            return Some(0.0);
        };
        let brightest = colour.iter().fold(0f32, |m, &c| m.max(c.abs()));
        let tint = scene.surfaces[self.surface].colour.to_array();
        let strongest = texels.iter().fold(0f64, |m, texel| {
            let texel = texel.map_or([1.0; 4], |c| c.to_array());
            (0..3).fold(m, |m, k| m.max(f64::from((tint[k] * texel[k]).abs())))
        });
        let mut varies = uv.cosine.hi.max(0.0) - uv.cosine.lo.max(0.0);
        // Lit wholly (the cosine smooth over it) under the box: the
        // midpoint's second-order bound, where it is the smaller.
        if varies > 0.0
            && uv.cosine.lo > 0.0
            && shading.filter == quadtex_core::PixelFilter::Box
            && let Some(midpoint) = self.midpoint_cosine_error(piece, direction)
        {
            varies = varies.min(midpoint);
        }
        let bound = varies * f64::from(brightest) * strongest;
        let tolerance = shading.options.target_bound().unwrap_or(1.0 / 512.0);
        if bound.is_nan() || bound > LIGHT_SHARE * tolerance {
            return None;
        }
        Some(bound)
    }
}

#[cfg(test)]
mod tests {
    use super::{ANGLE_ERROR, atan2_near};

    /// Within the stated error of `atan2` all around the circle, at every
    /// scale, on the axes, at the reduction's switch and with signed
    /// zeros.
    #[test]
    fn atan2_near_is_within_its_stated_error() {
        let mut worst = 0.0f64;
        let mut check = |y: f64, x: f64| {
            let (near, exact) = (atan2_near(y, x), f64::atan2(y, x));
            worst = worst.max((near - exact).abs());
            assert!(
                (near - exact).abs() <= ANGLE_ERROR,
                "atan2({y}, {x}): {near} vs {exact}"
            );
        };
        for i in 0..200_000 {
            let a =
                std::f64::consts::TAU * (f64::from(i) + 0.37) / 200_000.0 - std::f64::consts::PI;
            for r in [1e-300, 1e-8, 1.0, 3.7e5, 1e300] {
                check(r * a.sin(), r * a.cos());
            }
        }
        let switch = std::f64::consts::SQRT_2 - 1.0;
        for (y, x) in [
            (0.0, 1.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (-0.0, 1.0),
            (1.0, 0.0),
            (-1.0, 0.0),
            (1.0, -0.0),
            (switch, 1.0),
            (-switch, -1.0),
            (1.0, switch),
            (1.0, 1.0),
            (0.0, 0.0),
            (-0.0, -0.0),
        ] {
            check(y, x);
        }
        assert!(worst > 1e-9, "the series' error should show: {worst}");
    }
}

//! A region where one edge of the texture parts two colours, split along
//! the edge's own image on the screen ([`SphereView::two_colours`]).
//!
//! Where the surface's UV transform is axis-aligned, a line of texture
//! space (`x = X` or `z = Z`) is a meridian (`u = u₀`) or a parallel
//! (`v = v₀`) of the sphere: part of a circle on it (centre `c`, radius
//! `ρ`) in the plane through `c` with normal `n`. The camera's ray
//! through screen point `s`, `camera + λ·d(s)`, meets that plane at
//! `λ = e/β` (`e = (c − camera)·n`, `β = n·d(s)`), inside the circle
//! where `|β·(camera − c) + e·d(s)|² < ρ²·β²`: a quadratic form in
//! `(s, 1)`, whose zero set `Γ` is the image of the whole circle, an
//! ellipse, since the sphere lies in front of the camera's plane.
//!
//! `Γ`'s arc over the sphere's visible side is where the region's colour
//! changes; its arc over the hidden side (which also crosses the disc)
//! changes nothing. For a circle partly hidden both arcs end on the
//! outline, so inside a region that lies within the outline each one that
//! reaches the region crosses its boundary. (A circle wholly in view
//! surrounds a pole, and a region holding its image holds the pole, which
//! the UV box refuses; one wholly hidden has no colour change in view, and
//! its image could only reach a region whose UV box holds the line by the
//! box's 10⁻⁷ margin.) So when
//!
//! - the region's closed-form UV box ([`super::arcs`]) maps into two
//!   texture squares, each of one colour, on either side of one line,
//! - and every point where `Γ` crosses the region's boundary is on the
//!   visible arc (the ray through it meets the circle's plane at the
//!   sphere's near side, not its far one),
//!
//! each side of `Γ` within the region is one colour, the side checked at
//! the region's vertices against the sphere's own normals. The region is
//! then the outer colour over all of it plus the difference of the two
//! over its part inside `Γ`, that part clipped by `Γ`'s chords
//! ([`super::conic::Ellipse::chords`]): exact but for the segments the
//! chords leave out, whose weight times the colours' contrast is the
//! bound. Each of the two terms is lit at its polygon's centroid, as
//! pieces are, where the light varies over the region by little
//! ([`SphereView::light_bound`]).

use quadtex_core::{ConvexPolygon, Rgba};

use crate::math::Vec3;
use crate::stats::PixelStats;

use super::super::lighting::Shading;
use super::SphereView;
use super::arcs::UvBox;
use super::conic::{Chords, Ellipse};

/// What the texture is over a UV box ([`SphereView::box_texture`]).
// Kept by value in a thread's `Cell` for a run of pixels (copied out,
// never moved in bulk): boxing the large variant would allocate a run.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy)]
pub(super) enum BoxTexture {
    /// One colour holds the box (`None`: the surface's own, untextured).
    One(Option<quadtex_core::Rgba>),
    /// One texture edge parts the box into two colours.
    Two(EdgeImage),
    /// Neither.
    Other,
}

/// A circle on the sphere along which a texture edge runs, and which side
/// of it has which colour.
#[derive(Debug, Clone, Copy)]
struct EdgeCircle {
    centre: Vec3,
    radius: f64,
    /// The normal of the circle's plane, pointing to the side of
    /// `colour_ahead`.
    normal: Vec3,
    colour_ahead: Rgba,
    colour_behind: Rgba,
}

/// The one texture edge across a UV box, as a circle on the sphere, with
/// its image on the screen: the quadratic form negative inside it, and
/// the ellipse where that is zero. What splitting any region whose UV
/// lies in the box takes ([`SphereView::split_along`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct EdgeImage {
    edge: EdgeCircle,
    form: [[f64; 3]; 3],
    ellipse: Ellipse,
}

impl SphereView {
    /// What the texture is over the UV box `uv`: one colour, where one
    /// texture square holds the box (any colour at all for an untextured
    /// sphere), two parted by one texture edge ([`SphereView::edge_image`]),
    /// or neither.
    pub(super) fn box_texture(&self, shading: &Shading<'_>, uv: &UvBox) -> BoxTexture {
        let Some(texture) = shading.frame.texture(self.surface) else {
            return BoxTexture::One(None);
        };
        let one = (self.texture_box_of_uv(uv.lo, uv.hi))
            .and_then(|(tlo, thi)| texture.uniform_colour_in_box(tlo, thi));
        match one {
            Some(colour) => BoxTexture::One(Some(colour)),
            None => (self.edge_image(shading, uv)).map_or(BoxTexture::Other, BoxTexture::Two),
        }
    }

    /// `(Σ colour·k, Σ k, bound)` of `region` (inside the outline, its
    /// closed-form UV box `uv`) when one texture edge parts it into two
    /// colours, the edge's image is shown to part it (module doc) and the
    /// bound is at most `allowance`; `None` otherwise.
    pub(super) fn two_colours(
        &self,
        shading: &Shading<'_>,
        region: &ConvexPolygon,
        uv: &UvBox,
        allowance: f64,
        stats: &mut PixelStats,
    ) -> Option<([f64; 4], f64, f64)> {
        let image = self.edge_image(shading, uv)?;
        self.split_along(shading, region, uv, &image, allowance, stats)
    }

    /// The one texture edge across the UV box `uv` and its image, when
    /// there is one ([`SphereView::edge_circle`]) and its image is an
    /// ellipse.
    pub(super) fn edge_image(&self, shading: &Shading<'_>, uv: &UvBox) -> Option<EdgeImage> {
        let edge = self.edge_circle(shading, uv)?;
        let form = self.circle_form(&edge)?;
        let ellipse = Ellipse::from_form(
            [-form[0][0], -form[0][1], -form[1][1]],
            [-form[0][2], -form[1][2]],
            -form[2][2],
        )?;
        Some(EdgeImage {
            edge,
            form,
            ellipse,
        })
    }

    /// [`SphereView::two_colours`] of `region`, whose UV lies in the box
    /// `uv` across which `image`'s edge is the one texture edge.
    pub(super) fn split_along(
        &self,
        shading: &Shading<'_>,
        region: &ConvexPolygon,
        uv: &UvBox,
        image: &EdgeImage,
        allowance: f64,
        stats: &mut PixelStats,
    ) -> Option<([f64; 4], f64, f64)> {
        let EdgeImage {
            edge,
            form,
            ref ellipse,
        } = *image;
        // The light over the whole region first: at the limb, where the
        // cosine varies too fast for it, nothing below is needed.
        let texels = [Some(edge.colour_ahead), Some(edge.colour_behind)];
        let region_light = self.light_bound(shading, region, uv, &texels)?;
        let value = |s: [f64; 2]| {
            let p = [s[0], s[1], 1.0];
            (0..3)
                .map(|i| (0..3).map(|j| form[i][j] * p[i] * p[j]).sum::<f64>())
                .sum::<f64>()
        };
        let vertices = region.vertices();
        // Where Γ crosses the boundary: on the visible arc only.
        for (i, &a) in vertices.iter().enumerate() {
            let b = vertices[(i + 1) % vertices.len()];
            for t in segment_roots(&form, a, b) {
                let s = [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
                if !self.on_visible_side(&edge, s) {
                    return None;
                }
            }
        }
        // Which side of Γ holds which colour, from the normals at the
        // vertices clear of it (every one of them must agree).
        let mut inside_ahead = None;
        for &s in vertices {
            let f = value(s);
            let gradient =
                [0, 1].map(|i| 2.0 * (form[i][0] * s[0] + form[i][1] * s[1] + form[i][2]));
            let ahead = (self.normal(s) - (edge.centre - self.centre) * (1.0 / self.radius))
                .dot(edge.normal);
            // Too near Γ (within a millionth of a pixel) or the circle's
            // plane to tell.
            if !(f.abs() > 1e-6 * gradient[0].hypot(gradient[1]) && ahead.abs() > 1e-9) {
                continue;
            }
            let this = (f < 0.0) == (ahead > 0.0);
            if *inside_ahead.get_or_insert(this) != this {
                return None;
            }
        }
        let inside_ahead = inside_ahead?;
        let (inner_texel, outer_texel) = if inside_ahead {
            (edge.colour_ahead, edge.colour_behind)
        } else {
            (edge.colour_behind, edge.colour_ahead)
        };

        // The region's part inside Γ, within its chords.
        let mut chords = Chords::default();
        let mut part = match ellipse.chords(region, &mut chords) {
            None => ConvexPolygon::empty(),
            Some(_) => region.clone(),
        };
        for &line in &chords.lines[..chords.count] {
            // A clip adds at most one vertex: none is dropped.
            if part.vertices().len() >= quadtex_core::MAX_VERTICES {
                return None;
            }
            part = part.clip_lines([line]);
        }
        let (filter, centre) = (shading.filter, shading.centre);
        let whole = filter.integral(region, centre);
        let within = filter.integral(&part, centre);
        let (inner, outer) = (
            inner_texel.to_array().map(f64::from),
            outer_texel.to_array().map(f64::from),
        );
        let contrast = (0..4).fold(0f64, |m, k| m.max((inner[k] - outer[k]).abs()));
        let mut colour = self.finish(shading, region, outer.map(|c| c * whole));
        if !part.is_empty() {
            let difference: [f64; 4] = std::array::from_fn(|k| (inner[k] - outer[k]) * within);
            for (a, v) in colour
                .iter_mut()
                .zip(self.finish(shading, &part, difference))
            {
                *a += v;
            }
        }
        // Each term lit at its own polygon's centroid.
        let mut light = region_light * self.absolute_weight(shading, region, whole);
        if !part.is_empty() {
            light += self.light_bound(shading, &part, uv, &texels)?
                * self.absolute_weight(shading, &part, within);
        }
        let bound = ellipse.slivers(&chords, filter, centre) * contrast + light;
        if bound.is_nan() || bound > allowance {
            return None;
        }
        stats.textured = 1;
        stats.filter.footprints += 1;
        stats.filter.fragments += 1;
        Some((colour, whole, bound))
    }

    /// The circle on the sphere along which the one texture edge inside
    /// the UV box `uv` runs, with the colours on its two sides, when the
    /// surface is textured (a power-of-two square or strip, whose cells'
    /// sides are dyadic lines of texture space), its UV transform
    /// axis-aligned, `uv` narrow (less than a quarter turn, within one
    /// turn) and the texture over it two colours parted by one line of
    /// texture space: the coarsest dyadic line inside the box, each side's
    /// box one colour.
    fn edge_circle(&self, shading: &Shading<'_>, uv: &UvBox) -> Option<EdgeCircle> {
        let texture = shading.frame.texture(self.surface)?;
        let t = &self.texture_from_uv;
        if t[0][1] != 0.0 || t[1][0] != 0.0 || t[0][0] == 0.0 || t[1][1] == 0.0 {
            return None;
        }
        let width = uv.hi[0] - uv.lo[0];
        if width.is_nan() || width >= 0.25 {
            return None;
        }
        // The tree's cells lie on dyadic lines of texture space only where
        // the texture is a power-of-two square or strip (a 640-texel-wide
        // photograph's texel edges lie at k/640): elsewhere no split.
        texture.tree().aspect().shrink()?;
        let turn = uv.lo[0].floor();
        let (lo, hi) = self.texture_box_of_uv(uv.lo, uv.hi)?;
        let depth = i32::from(texture.tree().depth());
        for axis in 0..2 {
            let Some(line) = coarsest_line(lo[axis], hi[axis], depth) else {
                continue;
            };
            // Each side's box ends short of the line by less than the
            // finest cell: a terminal square holding it reaches the line.
            let finest = f64::from(depth).exp2().recip();
            let (below, above) = (
                (0.25 * finest).min(0.5 * (line - lo[axis])),
                (0.25 * finest).min(0.5 * (hi[axis] - line)),
            );
            let (mut low_hi, mut high_lo) = (hi, lo);
            low_hi[axis] = line - below;
            high_lo[axis] = line + above;
            let (Some(low), Some(high)) = (
                texture.uniform_colour_in_box(lo, low_hi),
                texture.uniform_colour_in_box(high_lo, hi),
            ) else {
                continue;
            };
            // The line in the sphere's UV, and which colour lies where it
            // grows.
            let (scale, offset) = (t[axis][axis], t[axis][2]);
            let at = (line - offset) / scale;
            let (ahead, behind) = if scale > 0.0 {
                (high, low)
            } else {
                (low, high)
            };
            let pi = std::f64::consts::PI;
            let circle = if axis == 0 {
                // A meridian, longitude φ₀: its plane holds the poles' axis;
                // its normal points to growing longitude.
                let phi = std::f64::consts::TAU * (at + turn) - pi;
                let (sin, cos) = phi.sin_cos();
                EdgeCircle {
                    centre: self.centre,
                    radius: self.radius,
                    normal: Vec3::new(-sin, 0.0, cos),
                    colour_ahead: ahead,
                    colour_behind: behind,
                }
            } else {
                // A parallel, latitude v₀ (θ₀ = π(1 − v₀) from the north
                // pole): v grows northward.
                let (sin, cos) = (pi * (1.0 - at)).sin_cos();
                if sin.is_nan() || sin <= 1e-9 {
                    return None;
                }
                EdgeCircle {
                    centre: self.centre + Vec3::new(0.0, self.radius * cos, 0.0),
                    radius: self.radius * sin,
                    normal: Vec3::new(0.0, 1.0, 0.0),
                    colour_ahead: ahead,
                    colour_behind: behind,
                }
            };
            return Some(circle);
        }
        None
    }

    /// The quadratic form, on `(sx, sy, 1)`, negative where the camera's
    /// ray through the screen point meets the plane of `edge` inside it
    /// (module doc), as a symmetric 3 × 3 matrix.
    fn circle_form(&self, edge: &EdgeCircle) -> Option<[[f64; 3]; 3]> {
        let [d0, dx, dy] = self.basis;
        let columns = [dx, dy, d0];
        let w = self.camera - edge.centre;
        let e = (edge.centre - self.camera).dot(edge.normal);
        let beta = columns.map(|d| edge.normal.dot(d));
        let big = columns.map(|d| d * e);
        let dirs: [Vec3; 3] = std::array::from_fn(|k| w * beta[k] + big[k]);
        let r2 = edge.radius * edge.radius;
        let form: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| dirs[i].dot(dirs[j]) - r2 * beta[i] * beta[j])
        });
        form.iter().flatten().all(|v| v.is_finite()).then_some(form)
    }

    /// Whether the camera's ray through `s` meets the plane of `edge` at
    /// the sphere's near side rather than its far one (clearly: `false`
    /// where the two sides are too near to tell, at the outline).
    fn on_visible_side(&self, edge: &EdgeCircle, s: [f64; 2]) -> bool {
        let d = self.direction(s);
        let m = self.centre - self.camera;
        let (a, g) = (m.dot(d), d.dot(d));
        let q = a * a - self.k * g;
        let beta = edge.normal.dot(d);
        if !(q > 0.0 && beta != 0.0) {
            return false;
        }
        let root = q.sqrt();
        let (near, far) = ((a - root) / g, (a + root) / g);
        let lambda = (edge.centre - self.camera).dot(edge.normal) / beta;
        far - near > 1e-9 * far && (lambda - near).abs() < (lambda - far).abs()
    }
}

/// The parameters `t ∈ [0, 1]` where the quadratic form `form` is zero
/// along the segment from `a` to `b`.
fn segment_roots(form: &[[f64; 3]; 3], a: [f64; 2], b: [f64; 2]) -> impl Iterator<Item = f64> {
    let p = [a[0], a[1], 1.0];
    let e = [b[0] - a[0], b[1] - a[1], 0.0];
    let bilinear = |x: &[f64; 3], y: &[f64; 3]| {
        (0..3)
            .map(|i| (0..3).map(|j| form[i][j] * x[i] * y[j]).sum::<f64>())
            .sum::<f64>()
    };
    let (qa, qb, qc) = (bilinear(&e, &e), bilinear(&e, &p), bilinear(&p, &p));
    let disc = qb * qb - qa * qc;
    let mut roots = [f64::NAN; 2];
    if disc >= 0.0 && qa != 0.0 {
        // The stabler of the two forms for each root.
        let root = disc.sqrt();
        let big = -qb - root.copysign(qb);
        roots = [big / qa, if big != 0.0 { qc / big } else { f64::NAN }];
    } else if qa == 0.0 && qb != 0.0 {
        roots[0] = -qc / (2.0 * qb);
    }
    roots.into_iter().filter(|t| (0.0..=1.0).contains(t))
}

/// The coarsest dyadic line `k·2⁻ˡ` (`l` from 0 to `depth`) strictly
/// between `lo` and `hi`, if any.
fn coarsest_line(lo: f64, hi: f64, depth: i32) -> Option<f64> {
    (0..=depth).find_map(|level| {
        let step = f64::from(-level).exp2();
        let line = ((lo / step).floor() + 1.0) * step;
        (line < hi).then_some(line)
    })
}

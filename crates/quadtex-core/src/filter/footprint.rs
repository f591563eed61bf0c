//! A pixel's footprint in texture space and the map from the pixel square
//! onto it. (Its cover by axis-aligned strips is a baseline:
//! [`crate::baseline::StripCover`].)

use crate::Error;
use crate::baseline::MAX_DENSITY_PIECES;
use crate::geometry::fragment::Fragment;

/// The texture-space image of one pixel square (or of any screen square):
/// its four corners, in pixel order: the images of pixel corners
/// `(0,0), (1,0), (1,1), (0,1)`, where pixel `x` runs right and `y` runs
/// down the screen. Texture space follows the crate conventions (`x` right,
/// `z` up, the texture's tile is `[0,1)²`); corners may lie anywhere in the
/// plane, wrap modes decide what lies outside the tile.
///
/// On a planar surface seen through a pinhole camera, the map from the pixel
/// square to texture space is a projective map (a homography), and four
/// point pairs fix it: the corners alone determine how screen area is
/// distributed over the footprint ([`crate::Projection::for_pixel`]).
///
/// Invariants: every coordinate is finite and at most
/// [`MAX_TEXTURE_COORDINATE`] in magnitude, and the quad does not cross
/// itself (no bow tie: its corners go around it in order). Degenerate
/// footprints (zero area: a point, a segment) are allowed and filter to the
/// texture at their centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    corners: [[f64; 2]; 4],
}

/// Largest magnitude of a footprint's coordinate (texture units),
/// `10^15`: beyond it an `f64` no longer resolves a texel of the tile, so
/// the filter could not tell where within a tile a corner lies (at `10^20`
/// it returned zero under repeat). [`Footprint::from_corners`] refuses
/// coordinates beyond it with [`Error::BadPolygon`] naming the corner.
pub const MAX_TEXTURE_COORDINATE: f64 = 1e15;

/// Field names for errors, `corner[i].x` / `corner[i].z`.
const CORNER_FIELDS: [[&str; 2]; 4] = [
    ["corner[0].x", "corner[0].z"],
    ["corner[1].x", "corner[1].z"],
    ["corner[2].x", "corner[2].z"],
    ["corner[3].x", "corner[3].z"],
];

impl Footprint {
    /// A footprint from the texture-space images of the pixel's corners
    /// `(0,0), (1,0), (1,1), (0,1)`; [`Error::NonFiniteCoordinate`] names a
    /// NaN or infinite coordinate (`corner[2].z`), [`Error::BadPolygon`] a
    /// coordinate beyond [`MAX_TEXTURE_COORDINATE`] or a quad that crosses
    /// itself (a bow tie: two opposite edges intersect, which no pixel
    /// square seen in perspective gives; its corners are out of order).
    pub fn from_corners(corners: [[f64; 2]; 4]) -> Result<Footprint, Error> {
        for (corner, names) in corners.iter().zip(CORNER_FIELDS) {
            for (&value, field) in corner.iter().zip(names) {
                if !value.is_finite() {
                    return Err(Error::NonFiniteCoordinate { field, value });
                }
                if value.abs() > MAX_TEXTURE_COORDINATE {
                    return Err(Error::BadPolygon(format!(
                        "footprint coordinate {field} = {value:e} is beyond the largest texture coordinate {MAX_TEXTURE_COORDINATE:e} (MAX_TEXTURE_COORDINATE)"
                    )));
                }
            }
        }
        for (a, b, c, d) in [(0, 1, 2, 3), (1, 2, 3, 0)] {
            if segments_cross(corners[a], corners[b], corners[c], corners[d]) {
                return Err(Error::BadPolygon(format!(
                    "footprint crosses itself (a bow tie): edge corner[{a}]–corner[{b}] crosses edge corner[{c}]–corner[{d}]; give the corners in order around the quad"
                )));
            }
        }
        Ok(Footprint { corners })
    }

    /// The parallelogram a renderer's ray differentials give: the texture
    /// point `st` at the pixel centre and its change per pixel step along the
    /// screen's `x` (`d_dx`) and `y` (`d_dy`). Corner `(i, j)` is
    /// `st + (i − ½)·d_dx + (j − ½)·d_dy`.
    pub fn from_differentials(
        st: [f64; 2],
        d_dx: [f64; 2],
        d_dy: [f64; 2],
    ) -> Result<Footprint, Error> {
        let at = |i: f64, j: f64| {
            [
                st[0] + (i - 0.5) * d_dx[0] + (j - 0.5) * d_dy[0],
                st[1] + (i - 0.5) * d_dx[1] + (j - 0.5) * d_dy[1],
            ]
        };
        Footprint::from_corners([at(0.0, 0.0), at(1.0, 0.0), at(1.0, 1.0), at(0.0, 1.0)])
    }

    /// The corners, in pixel order.
    pub fn corners(&self) -> [[f64; 2]; 4] {
        self.corners
    }

    /// Area enclosed (shoelace formula, absolute value).
    pub fn area(&self) -> f64 {
        polygon_area(&self.corners)
    }

    /// Lower-left and upper-right corners of the bounding box.
    pub fn bounds(&self) -> ([f64; 2], [f64; 2]) {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in &self.corners {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        (lo, hi)
    }

    /// The image of the pixel centre: the crossing of the diagonals (where a
    /// projective map sends the square's centre), or the corners' mean when
    /// the diagonals are parallel or the quad is degenerate.
    pub fn centre(&self) -> [f64; 2] {
        let [p0, p1, p2, p3] = self.corners;
        let d1 = [p2[0] - p0[0], p2[1] - p0[1]];
        let d2 = [p3[0] - p1[0], p3[1] - p1[1]];
        let den = d1[0] * d2[1] - d1[1] * d2[0];
        let mean = [
            0.25 * (p0[0] + p1[0] + p2[0] + p3[0]),
            0.25 * (p0[1] + p1[1] + p2[1] + p3[1]),
        ];
        if den == 0.0 || !den.is_finite() {
            return mean;
        }
        // p0 + s·d1 = p1 + t·d2.
        let r = [p1[0] - p0[0], p1[1] - p0[1]];
        let s = (r[0] * d2[1] - r[1] * d2[0]) / den;
        if !(0.0..=1.0).contains(&s) {
            return mean;
        }
        [p0[0] + s * d1[0], p0[1] + s * d1[1]]
    }

    /// Central differences of the corners: the change of the texture point
    /// per pixel step along screen `x` and `y` (what a mip-map lookup takes).
    pub fn differentials(&self) -> ([f64; 2], [f64; 2]) {
        let q = &self.corners;
        (
            [
                0.5 * (q[1][0] - q[0][0] + q[2][0] - q[3][0]),
                0.5 * (q[1][1] - q[0][1] + q[2][1] - q[3][1]),
            ],
            [
                0.5 * (q[3][0] - q[0][0] + q[2][0] - q[1][0]),
                0.5 * (q[3][1] - q[0][1] + q[2][1] - q[1][1]),
            ],
        )
    }

    /// The projective map from the pixel square `[0,1]²` onto this
    /// footprint, if the corners define one that is one-to-one on the square
    /// (a convex quad, corners in order; parallelograms give an affine map).
    /// Public as [`crate::Projection::for_pixel`].
    pub(crate) fn square_to_quad(&self) -> Option<SquareToQuad> {
        SquareToQuad::new(&self.corners)
    }
}

/// The projective map from the pixel square to a footprint:
/// `t(u, v) = (a·u + b·v + c, d·u + e·v + f) / (g·u + h·v + 1)` for
/// `(u, v) ∈ [0,1]²` (Heckbert's square-to-quad construction).
///
/// Crate-private: the one public projective map is [`crate::Projection`]
/// (built from this one by [`crate::Projection::for_pixel`]); the strip
/// baseline also weighs its strips by this map's screen density.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SquareToQuad {
    /// Row-major `[[a, b, c], [d, e, f], [g, h, 1]]`.
    m: [[f64; 3]; 3],
    /// The third row of the inverse's adjugate: `q(t) = r·(x, z, 1)` is
    /// proportional to `1/w`, where `w = g·u + h·v + 1`.
    inverse_w: [f64; 3],
    /// `q` at the image of the square's centre, so densities are relative
    /// to the centre's (near 1, whatever the footprint's scale).
    q_centre: f64,
}

impl SquareToQuad {
    /// The map sending `(0,0), (1,0), (1,1), (0,1)` to `p[0..4]`, if the
    /// denominator `w` keeps one sign over the square (the map is then
    /// continuous and one-to-one there).
    pub(crate) fn new(p: &[[f64; 2]; 4]) -> Option<SquareToQuad> {
        let [p0, p1, p2, p3] = *p;
        // A quad's area is half the cross product of its diagonals: below
        // 1e-12 of the longer one's square it is a segment or a point to
        // rounding (which would otherwise make a near-singular map).
        let (d1, d2) = (
            [p2[0] - p0[0], p2[1] - p0[1]],
            [p3[0] - p1[0], p3[1] - p1[1]],
        );
        let cross = d1[0] * d2[1] - d1[1] * d2[0];
        // Squared lengths (no square roots: this runs per piece of a
        // sphere); where they overflow, the lengths themselves.
        let longer_squared = (d1[0] * d1[0] + d1[1] * d1[1]).max(d2[0] * d2[0] + d2[1] * d2[1]);
        let longer_squared = if longer_squared.is_finite() {
            longer_squared
        } else {
            let longer = d1[0].hypot(d1[1]).max(d2[0].hypot(d2[1]));
            longer * longer
        };
        if cross.abs() <= 1e-12 * longer_squared {
            return None;
        }
        let sx = p0[0] - p1[0] + p2[0] - p3[0];
        let sz = p0[1] - p1[1] + p2[1] - p3[1];
        let (g, h) = if sx == 0.0 && sz == 0.0 {
            (0.0, 0.0)
        } else {
            let (dx1, dx2) = (p1[0] - p2[0], p3[0] - p2[0]);
            let (dz1, dz2) = (p1[1] - p2[1], p3[1] - p2[1]);
            let den = dx1 * dz2 - dx2 * dz1;
            if den == 0.0 {
                return None;
            }
            ((sx * dz2 - dx2 * sz) / den, (dx1 * sz - sx * dz1) / den)
        };
        let m = [
            [p1[0] - p0[0] + g * p1[0], p3[0] - p0[0] + h * p3[0], p0[0]],
            [p1[1] - p0[1] + g * p1[1], p3[1] - p0[1] + h * p3[1], p0[1]],
            [g, h, 1.0],
        ];
        // w at the square's corners: one sign, never zero.
        let ws = [1.0, 1.0 + g, 1.0 + g + h, 1.0 + h];
        if !ws.iter().all(|&w| w > 0.0) {
            return None;
        }
        // Third row of adj(m): (d·h − e·g, b·g − a·h, a·e − b·d); then
        // q(t(u, v)) = det(m)/w(u, v), which is nonzero iff det(m) is.
        let [[a, b, c], [d, e, f], _] = m;
        let inverse_w = [d * h - e * g, b * g - a * h, a * e - b * d];
        let det = a * (e - f * h) - b * (d - f * g) + c * (d * h - e * g);
        let finite = m.iter().flatten().chain(&inverse_w).all(|v| v.is_finite());
        let q_centre = det / (1.0 + 0.5 * g + 0.5 * h);
        (finite && det != 0.0 && det.is_finite() && q_centre.is_finite()).then_some(SquareToQuad {
            m,
            inverse_w,
            q_centre,
        })
    }

    /// The texture point of pixel-square point `(u, v)`.
    #[cfg(test)]
    pub(crate) fn apply(&self, u: f64, v: f64) -> [f64; 2] {
        let m = &self.m;
        let w = m[2][0] * u + m[2][1] * v + 1.0;
        [
            (m[0][0] * u + m[0][1] * v + m[0][2]) / w,
            (m[1][0] * u + m[1][1] * v + m[1][2]) / w,
        ]
    }

    /// The screen-space density at texture point `t` relative to its value
    /// at the footprint's centre: the Jacobian determinant of the inverse
    /// map, which for a projective map is `∝ 1/q(t)³` with `q` affine in `t`.
    /// A box filter over the pixel weighs texture area by it. Constant for
    /// an affine map.
    pub(crate) fn screen_density(&self, t: [f64; 2]) -> f64 {
        let r = &self.inverse_w;
        let q = (r[0] * t[0] + r[1] * t[1] + r[2]) / self.q_centre;
        (q * q * q).abs().recip()
    }

    /// How many pieces to cut `rect` into along `x` and `z` so that the
    /// screen density varies by at most a factor `1 + tolerance` (to first
    /// order) within each piece; at most [`MAX_DENSITY_PIECES`] in all.
    #[inline]
    pub(crate) fn density_pieces(&self, rect: &Fragment, tolerance: f64) -> (usize, usize) {
        let r = &self.inverse_w;
        // q is affine: over the rectangle it ranges ±(|r₀|·w + |r₁|·h)/2
        // around its value at the centre (which keeps one sign over Q).
        let (dq_x, dq_z) = (r[0].abs() * rect.width(), r[1].abs() * rect.height());
        let centre =
            r[0] * 0.5 * (rect.x0() + rect.x1()) + r[1] * 0.5 * (rect.z0() + rect.z1()) + r[2];
        let q_min = centre.abs() - 0.5 * (dq_x + dq_z);
        if q_min.is_nan() || q_min <= 0.0 {
            return (1, 1);
        }
        // ρ ∝ q⁻³: a relative change Δq/q changes ρ by about 3·Δq/q.
        let limit = q_min * tolerance / 3.0;
        if dq_x <= limit && dq_z <= limit {
            return (1, 1);
        }
        let count = |dq: f64| {
            let k = (dq / limit).ceil();
            if k.is_finite() {
                k.clamp(1.0, MAX_DENSITY_PIECES as f64) as usize
            } else {
                MAX_DENSITY_PIECES
            }
        };
        let (mut nx, mut nz) = (count(dq_x), count(dq_z));
        while nx * nz > MAX_DENSITY_PIECES {
            if nx >= nz {
                nx = nx.div_ceil(2)
            } else {
                nz = nz.div_ceil(2)
            }
        }
        (nx, nz)
    }

    /// The matrix `[[a, b, c], [d, e, f], [g, h, 1]]` acting on `(u, v, 1)`.
    pub(crate) fn matrix(&self) -> [[f64; 3]; 3] {
        self.m
    }

    /// True when the map is affine (the footprint is a parallelogram): the
    /// screen density is then the same everywhere.
    pub(crate) fn is_affine(&self) -> bool {
        self.m[2][0] == 0.0 && self.m[2][1] == 0.0
    }
}

/// Area of a polygon by the shoelace formula (absolute value).
pub(crate) fn polygon_area(p: &[[f64; 2]]) -> f64 {
    crate::geometry::polygon::signed_area(p).abs()
}

/// True when segments `p0p1` and `q0q1` cross at a point inside both
/// (touching at an end or overlapping along a line does not count).
fn segments_cross(p0: [f64; 2], p1: [f64; 2], q0: [f64; 2], q1: [f64; 2]) -> bool {
    let orient = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        let d = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        i8::from(d > 0.0) - i8::from(d < 0.0)
    };
    orient(p0, p1, q0) * orient(p0, p1, q1) < 0 && orient(q0, q1, p0) * orient(q0, q1, p1) < 0
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn quad(c: [[f64; 2]; 4]) -> Footprint {
        Footprint::from_corners(c).unwrap()
    }

    #[test]
    fn bow_ties_and_huge_coordinates_are_refused() {
        // Corners 2 and 3 swapped: edges 1–2 and 3–0 cross.
        let e =
            Footprint::from_corners([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]).unwrap_err();
        assert!(matches!(e, Error::BadPolygon(_)), "{e:?}");
        assert!(e.to_string().contains("bow tie"), "{e}");
        // Convex, concave, degenerate and touching quads are accepted.
        for c in [
            [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            [[0.0, 0.0], [1.0, 0.0], [0.2, 0.2], [0.0, 1.0]],
            [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]],
            [[0.5, 0.5]; 4],
        ] {
            assert!(Footprint::from_corners(c).is_ok(), "{c:?}");
        }
        let m = MAX_TEXTURE_COORDINATE;
        assert!(Footprint::from_corners([[-m, -m], [m, -m], [m, m], [-m, m]]).is_ok());
        let e = Footprint::from_corners([[0.0, 0.0], [1e20, 0.0], [1e20, 1.0], [0.0, 1.0]])
            .unwrap_err();
        assert!(e.to_string().contains("corner[1].x"), "{e}");
        assert!(e.to_string().contains("MAX_TEXTURE_COORDINATE"), "{e}");
    }

    #[test]
    fn non_finite_corners_are_named() {
        let e = Footprint::from_corners([[0.0, 0.0], [1.0, 0.0], [1.0, f64::NAN], [0.0, 1.0]])
            .unwrap_err();
        assert!(e.to_string().contains("corner[2].z"), "{e}");
        assert!(
            Footprint::from_differentials([0.5, 0.5], [f64::INFINITY, 0.0], [0.0, 0.1]).is_err()
        );
    }

    #[test]
    fn square_to_quad_maps_corners_and_centre() {
        let c = [[0.1, 0.1], [0.9, 0.2], [0.6, 0.7], [0.2, 0.5]];
        let fp = quad(c);
        let h = fp.square_to_quad().unwrap();
        for (p, (u, v)) in c
            .iter()
            .zip([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)])
        {
            let t = h.apply(u, v);
            assert!((t[0] - p[0]).abs() < 1e-12 && (t[1] - p[1]).abs() < 1e-12);
        }
        let m = h.apply(0.5, 0.5);
        let centre = fp.centre();
        assert!((m[0] - centre[0]).abs() < 1e-12 && (m[1] - centre[1]).abs() < 1e-12);
    }

    #[test]
    fn screen_density_is_the_inverse_jacobian() {
        let fp = quad([[0.1, 0.1], [0.9, 0.2], [0.6, 0.7], [0.2, 0.5]]);
        let h = fp.square_to_quad().unwrap();
        // Numerical Jacobian of the forward map at a few points: the density
        // ratio between two points must be the inverse ratio of |J|.
        let jac = |u: f64, v: f64| {
            let e = 1e-6;
            let (a, b) = (h.apply(u + e, v), h.apply(u - e, v));
            let (c, d) = (h.apply(u, v + e), h.apply(u, v - e));
            let du = [(a[0] - b[0]) / (2.0 * e), (a[1] - b[1]) / (2.0 * e)];
            let dv = [(c[0] - d[0]) / (2.0 * e), (c[1] - d[1]) / (2.0 * e)];
            (du[0] * dv[1] - du[1] * dv[0]).abs()
        };
        let (p, q) = ((0.2, 0.3), (0.8, 0.9));
        let ratio_density =
            h.screen_density(h.apply(p.0, p.1)) / h.screen_density(h.apply(q.0, q.1));
        let ratio_jac = jac(q.0, q.1) / jac(p.0, p.1);
        assert!(
            (ratio_density / ratio_jac - 1.0).abs() < 1e-6,
            "{ratio_density} vs {ratio_jac}"
        );
    }

    #[test]
    fn parallelograms_are_affine_and_folded_quads_are_refused() {
        let p = Footprint::from_differentials([0.5, 0.5], [0.25, 0.0], [0.0, 0.125]).unwrap();
        let h = p.square_to_quad().unwrap();
        assert!(h.is_affine());
        assert_eq!(p.centre(), [0.5, 0.5]);
        // Corners out of order (a bow tie) do not bound a projective image:
        // refused.
        assert!(Footprint::from_corners([[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]).is_err());
    }
}

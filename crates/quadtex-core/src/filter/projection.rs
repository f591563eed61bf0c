//! The projective map from the screen to texture space ([`Projection`])
//! and the 3×3 matrix helpers it is built from.

use crate::Error;
use crate::filter::footprint::{Footprint, SquareToQuad};

pub(super) type Mat3 = [[f64; 3]; 3];

/// A projective map from the screen to texture space,
/// `texture_from_screen`: `t = (M·(s, 1))` divided by its third
/// coordinate `w`. The surface is in front of the camera where `w > 0`.
///
/// Invariant: finite, invertible (both directions are kept).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    pub(super) texture_from_screen: Mat3,
    pub(super) screen_from_texture: Mat3,
    /// `|∇w|` over the screen, for the horizon sliver's width (kept: a
    /// view's projection serves every pixel it covers).
    pub(super) w_gradient: f64,
}

impl Projection {
    /// The map with matrix `texture_from_screen` (row-major, acting on
    /// `(x, y, 1)`); scaled by a positive factor for range, which changes
    /// nothing. [`Error::BadPolygon`] when it is not finite or singular.
    pub fn new(texture_from_screen: [[f64; 3]; 3]) -> Result<Projection, Error> {
        let scale = texture_from_screen
            .iter()
            .flatten()
            .fold(0f64, |m, v| m.max(v.abs()));
        if !(scale.is_finite() && scale > 0.0) {
            return Err(Error::BadPolygon(
                "projection matrix is not finite or is zero".into(),
            ));
        }
        let m = texture_from_screen.map(|row| row.map(|v| v / scale));
        let (adj, det) = adjugate(&m);
        if !(det.is_finite() && det.abs() > 1e-300) {
            return Err(Error::BadPolygon("projection matrix is singular".into()));
        }
        let inv_scale = adj.iter().flatten().fold(0f64, |a, v| a.max(v.abs()));
        // adj(M) = det·M⁻¹: any positive multiple represents the inverse map;
        // the sign is chosen so that w > 0 on the visible side both ways.
        let sign = det.signum();
        let inv = adj.map(|row| row.map(|v| sign * v / inv_scale));
        Ok(Projection {
            texture_from_screen: m,
            screen_from_texture: inv,
            // m's entries are at most 1 in size: no overflow without hypot.
            w_gradient: (m[2][0] * m[2][0] + m[2][1] * m[2][1]).sqrt(),
        })
    }

    /// The identity (screen and texture coordinates coincide): filtering a
    /// texture-space region uniformly in texture space.
    pub fn identity() -> Projection {
        let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        Projection {
            texture_from_screen: id,
            screen_from_texture: id,
            w_gradient: 0.0,
        }
    }

    /// The map sending the screen square `[x, x+1] × [y, y+1]` (pixel
    /// `(x, y)` when `origin = [x, y]`) onto `footprint`, corner to corner in
    /// pixel order; `None` unless the footprint is a convex quad the square
    /// maps onto one-to-one.
    pub fn for_pixel(footprint: &Footprint, origin: [f64; 2]) -> Option<Projection> {
        let m = footprint.square_to_quad()?.matrix();
        // M·T with T translating (x, y) to (u, v) = (x − origin.x, y − origin.y).
        let t = [
            [1.0, 0.0, -origin[0]],
            [0.0, 1.0, -origin[1]],
            [0.0, 0.0, 1.0],
        ];
        Projection::new(mul(&m, &t)).ok()
    }

    /// The map sending screen quadrilateral `screen` onto texture
    /// quadrilateral `texture`, corner `i` to corner `i` (corners in order
    /// around each, as [`Footprint`]'s), with `w > 0` inside `screen`;
    /// `None` unless each quad is convex and not degenerate (Heckbert's
    /// square-to-quad map of each, the screen's inverted). For a renderer
    /// whose own map is not projective: a projective map through four of
    /// its points.
    pub fn between_quads(screen: &[[f64; 2]; 4], texture: &[[f64; 2]; 4]) -> Option<Projection> {
        let to_screen = SquareToQuad::new(screen)?.matrix();
        let to_texture = SquareToQuad::new(texture)?.matrix();
        // adj(M) = det·M⁻¹; the square's w is positive, so sign(det)·adj
        // keeps it positive inside the screen quad.
        let (adj, det) = adjugate(&to_screen);
        let sign = det.signum();
        let square_from_screen = adj.map(|row| row.map(|v| sign * v));
        Projection::new(mul(&to_texture, &square_from_screen)).ok()
    }

    /// The matrix of [`Projection::between_quads`] up to a positive
    /// factor, unchecked beyond the quads' own checks and the product's
    /// being finite with a nonzero determinant (not scaled first, as
    /// [`Projection::new`] scales it: at entries far from 1, below 10⁻¹⁰⁰
    /// or above 10¹⁰⁰, the two may refuse differently): for a caller that
    /// only evaluates the map (a fit it checks against its own), without
    /// the scaling and inverse a [`Projection`] keeps.
    pub fn matrix_between_quads(
        screen: &[[f64; 2]; 4],
        texture: &[[f64; 2]; 4],
    ) -> Option<[[f64; 3]; 3]> {
        let to_screen = SquareToQuad::new(screen)?.matrix();
        let to_texture = SquareToQuad::new(texture)?.matrix();
        let (adj, det) = adjugate(&to_screen);
        let sign = det.signum();
        let square_from_screen = adj.map(|row| row.map(|v| sign * v));
        let m = mul(&to_texture, &square_from_screen);
        let det = adjugate(&m).1;
        (det.is_finite() && det != 0.0).then_some(m)
    }

    /// The matrix taking screen points to texture points.
    pub fn texture_from_screen(&self) -> [[f64; 3]; 3] {
        self.texture_from_screen
    }

    /// The denominator `w` at screen point `s` (positive where the surface
    /// is in front of the camera).
    pub fn w(&self, s: [f64; 2]) -> f64 {
        let r = &self.texture_from_screen[2];
        r[0] * s[0] + r[1] * s[1] + r[2]
    }

    /// The texture point seen at screen point `s`, if `w > 0` there.
    pub fn texture_point(&self, s: [f64; 2]) -> Option<[f64; 2]> {
        (self.w(s) > 0.0).then(|| apply(&self.texture_from_screen, s))
    }

    /// The screen point where texture point `t` is seen.
    pub fn screen_point(&self, t: [f64; 2]) -> [f64; 2] {
        apply(&self.screen_from_texture, t)
    }
}

#[inline]
pub(super) fn apply(m: &Mat3, p: [f64; 2]) -> [f64; 2] {
    let w = m[2][0] * p[0] + m[2][1] * p[1] + m[2][2];
    [
        (m[0][0] * p[0] + m[0][1] * p[1] + m[0][2]) / w,
        (m[1][0] * p[0] + m[1][1] * p[1] + m[1][2]) / w,
    ]
}

pub(super) fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

/// The adjugate (transposed cofactors) and the determinant.
pub(super) fn adjugate(m: &Mat3) -> (Mat3, f64) {
    let [[a, b, c], [d, e, f], [g, h, i]] = *m;
    let adj = [
        [e * i - f * h, c * h - b * i, b * f - c * e],
        [f * g - d * i, a * i - c * g, c * d - a * f],
        [d * h - e * g, b * g - a * h, a * e - b * d],
    ];
    let det = a * adj[0][0] + b * adj[1][0] + c * adj[2][0];
    (adj, det)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each corner of the screen quad lands on the texture quad's, `w` is
    /// positive inside, and folded or degenerate quads are refused.
    #[test]
    fn between_quads_sends_corners_to_corners() {
        let screen = [[10.0, 5.0], [12.5, 5.2], [12.0, 7.9], [9.8, 7.0]];
        let texture = [[0.2, 0.1], [1.3, 0.0], [1.1, 0.9], [0.0, 1.2]];
        for (screen, texture) in [(screen, texture), (texture, screen)] {
            let p = Projection::between_quads(&screen, &texture).unwrap();
            for (s, t) in screen.iter().zip(texture) {
                let got = p.texture_point(*s).unwrap();
                assert!((got[0] - t[0]).abs() < 1e-12 && (got[1] - t[1]).abs() < 1e-12);
            }
            let centre = [0, 1].map(|a| screen.iter().map(|c| c[a]).sum::<f64>() / 4.0);
            assert!(p.w(centre) > 0.0);
        }
        let folded = [[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]];
        assert!(Projection::between_quads(&folded, &texture).is_none());
        let flat = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]];
        assert!(Projection::between_quads(&screen, &flat).is_none());
    }

    /// The bare matrix is the projection's up to a positive factor: the
    /// same texture point and the same sign of `w` everywhere, and folded
    /// or flat quads refused.
    #[test]
    fn matrix_between_quads_is_the_projections_up_to_scale() {
        let screen = [[10.0, 5.0], [12.5, 5.2], [12.0, 7.9], [9.8, 7.0]];
        let texture = [[0.2, 0.1], [1.3, 0.0], [1.1, 0.9], [0.0, 1.2]];
        let p = Projection::between_quads(&screen, &texture).unwrap();
        let m = Projection::matrix_between_quads(&screen, &texture).unwrap();
        let w = |s: [f64; 2]| m[2][0] * s[0] + m[2][1] * s[1] + m[2][2];
        for s in [
            [10.0, 5.0],
            [11.0, 6.0],
            [12.4, 7.5],
            [30.0, -4.0],
            [0.0, 0.0],
        ] {
            let (a, b) = (apply(&m, s), apply(&p.texture_from_screen(), s));
            assert!(
                (a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9,
                "{s:?}"
            );
            assert_eq!(w(s) > 0.0, p.w(s) > 0.0, "{s:?}");
        }
        let folded = [[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]];
        assert!(Projection::matrix_between_quads(&folded, &texture).is_none());
        let flat = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]];
        assert!(Projection::matrix_between_quads(&screen, &flat).is_none());
    }
}

//! Pixel reconstruction filters ([`PixelFilter`]): weights, supports and
//! their exact integrals over convex polygons.

use crate::geometry::polygon::{ConvexPolygon, Cubic, separable_integral};

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
    fn cubic(self, i: i32) -> Cubic {
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
    /// exactly (Green's theorem on each unit cell of the filter).
    pub fn integral(self, p: &ConvexPolygon, centre: [f64; 2]) -> f64 {
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
                    total += separable_integral(cell.vertices(), &self.cubic(i), &self.cubic(j));
                }
            }
        }
        sign * total
    }
}

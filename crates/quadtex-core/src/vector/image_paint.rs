//! A raster image as a paint of vector art: the image's texels, each a
//! flat square of colour, placed in texture space by an affine map.
//!
//! **Convention.** `image_from_texture` maps a texture point `(x, z)` to
//! image coordinates `(u, v)`: `u` to the right, `v` down, in texels, so
//! texel `(col, row)` is the half-open square `[col, col+1) × [row, row+1)`
//! (row 0 at the top, as [`TexelGrid`] stores it). Points beyond the image
//! take the nearest edge texel (clamp), which only matters for rounding at
//! the image's border: the shape an image paints is normally its own
//! rectangle.
//!
//! The mean over a convex polygon is **exact**: the sum over the texels it
//! overlaps of each texel's colour times the area of the overlap (the
//! polygon clipped to the texel's square), over the polygon's area. An
//! affine map scales every area by the same factor, so the ratio is the
//! same in image and texture space. Image smoothing (`image-rendering` in
//! SVG, bilinear or bicubic in browsers) is not modelled: the texels are
//! the colour, as when quadtex packs a raster.

use std::sync::Arc;

use crate::Error;
use crate::raster::TexelGrid;

type Point = [f64; 2];

/// A raster placed in texture space (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct ImagePaint {
    texels: Arc<TexelGrid>,
    /// `[a, b, c, d, e, f]`: `u = a·x + c·z + e`, `v = b·x + d·z + f`.
    image_from_texture: [f64; 6],
    opaque: bool,
}

impl ImagePaint {
    /// The image `texels` (linear, premultiplied) placed by
    /// `image_from_texture` (`[a, b, c, d, e, f]`: `u = a·x + c·z + e`,
    /// `v = b·x + d·z + f`). Errors when the map is not finite or not
    /// invertible.
    pub fn new(texels: Arc<TexelGrid>, image_from_texture: [f64; 6]) -> Result<ImagePaint, Error> {
        let m = image_from_texture;
        let det = m[0] * m[3] - m[1] * m[2];
        if m.iter().any(|v| !v.is_finite()) || !(det.abs() > 0.0 && det.is_finite()) {
            return Err(Error::BadVector(format!(
                "image placement {m:?} is not a finite invertible map"
            )));
        }
        let opaque = texels.texels().iter().all(|t| t.0[3] == u16::MAX);
        Ok(ImagePaint {
            texels,
            image_from_texture,
            opaque,
        })
    }

    /// True when every texel is opaque.
    pub fn is_opaque(&self) -> bool {
        self.opaque
    }

    fn to_image(&self, p: Point) -> Point {
        let m = &self.image_from_texture;
        [
            m[0] * p[0] + m[2] * p[1] + m[4],
            m[1] * p[0] + m[3] * p[1] + m[5],
        ]
    }

    fn texel(&self, col: i64, row: i64) -> [f64; 4] {
        let g = &*self.texels;
        let c = col.clamp(0, i64::from(g.width()) - 1) as u32;
        let r = row.clamp(0, i64::from(g.height()) - 1) as u32;
        g.texel(c, r).0.map(|v| f64::from(v) / 65535.0)
    }

    /// The texel index range `[lo, hi]` (clamped to the image) that
    /// coordinates `lo..hi` along an axis of `n` texels reach.
    fn span(lo: f64, hi: f64, n: u32) -> (i64, i64) {
        let last = i64::from(n) - 1;
        let f = |v: f64| {
            if v.is_nan() {
                0
            } else {
                (v.floor().clamp(-1.0, n as f64) as i64).clamp(0, last)
            }
        };
        (f(lo), f(hi))
    }

    fn bounds(&self, poly: &[Point]) -> (Point, Point) {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for &p in poly {
            let q = self.to_image(p);
            for a in 0..2 {
                lo[a] = lo[a].min(q[a]);
                hi[a] = hi[a].max(q[a]);
            }
        }
        (lo, hi)
    }

    /// Linear premultiplied colour at texture point `p`.
    pub fn colour_at(&self, p: Point) -> [f64; 4] {
        let q = self.to_image(p);
        self.texel(q[0].floor() as i64, q[1].floor() as i64)
    }

    /// Per channel `[lo, hi]` of the colour over the convex polygon `poly`:
    /// the extremes of the texels its bounding box reaches.
    pub fn range_over(&self, poly: &[Point]) -> [[f64; 2]; 4] {
        let g = &*self.texels;
        let (lo, hi) = self.bounds(poly);
        let (c0, c1) = Self::span(lo[0], hi[0], g.width());
        let (r0, r1) = Self::span(lo[1], hi[1], g.height());
        let mut out = [[f64::INFINITY, f64::NEG_INFINITY]; 4];
        for row in r0..=r1 {
            for col in c0..=c1 {
                let t = g.texel(col as u32, row as u32).0;
                for (o, v) in out.iter_mut().zip(t) {
                    let v = f64::from(v) / 65535.0;
                    *o = [o[0].min(v), o[1].max(v)];
                }
            }
        }
        out
    }

    /// The exact mean colour over the convex polygon `poly` (either
    /// orientation), and its error bound (0: see the module docs).
    pub fn mean_over(&self, poly: &[Point]) -> ([f64; 4], f64) {
        let g = &*self.texels;
        let image: Vec<Point> = poly.iter().map(|&p| self.to_image(p)).collect();
        let total = signed_area(&image);
        if poly.len() < 3 || total == 0.0 || !total.is_finite() {
            return (poly.first().map_or([0.0; 4], |&p| self.colour_at(p)), 0.0);
        }
        let (lo, hi) = self.bounds(poly);
        let (c0, c1) = Self::span(lo[0], hi[0], g.width());
        let (r0, r1) = Self::span(lo[1], hi[1], g.height());
        let (last_col, last_row) = (i64::from(g.width()) - 1, i64::from(g.height()) - 1);
        let mut sum = [0.0; 4];
        let (mut strip, mut cell, mut scratch) = (Vec::new(), Vec::new(), Vec::new());
        for row in r0..=r1 {
            // The edge rows and columns reach to infinity (clamping).
            strip.clear();
            strip.extend_from_slice(&image);
            if row > 0 {
                clip_half_plane(&mut strip, &mut scratch, 1, row as f64, true);
            }
            if row < last_row {
                clip_half_plane(&mut strip, &mut scratch, 1, (row + 1) as f64, false);
            }
            if strip.len() < 3 {
                continue;
            }
            for col in c0..=c1 {
                cell.clear();
                cell.extend_from_slice(&strip);
                if col > 0 {
                    clip_half_plane(&mut cell, &mut scratch, 0, col as f64, true);
                }
                if col < last_col {
                    clip_half_plane(&mut cell, &mut scratch, 0, (col + 1) as f64, false);
                }
                if cell.len() < 3 {
                    continue;
                }
                let a = signed_area(&cell);
                let t = self.texel(col, row);
                for (s, v) in sum.iter_mut().zip(t) {
                    *s += a * v;
                }
            }
        }
        (sum.map(|s| s / total), 0.0)
    }
}

/// Clips `poly` in place to `p[axis] ≥ at` (`keep_above`) or `p[axis] ≤ at`.
fn clip_half_plane(
    poly: &mut Vec<Point>,
    scratch: &mut Vec<Point>,
    axis: usize,
    at: f64,
    keep_above: bool,
) {
    let inside = |p: &Point| {
        if keep_above {
            p[axis] >= at
        } else {
            p[axis] <= at
        }
    };
    scratch.clear();
    let n = poly.len();
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        let (ia, ib) = (inside(&a), inside(&b));
        if ia {
            scratch.push(a);
        }
        if ia != ib {
            let t = (at - a[axis]) / (b[axis] - a[axis]);
            let mut q = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
            q[axis] = at;
            scratch.push(q);
        }
    }
    std::mem::swap(poly, scratch);
}

fn signed_area(poly: &[Point]) -> f64 {
    let n = poly.len();
    let Some(&o) = poly.first() else {
        return 0.0;
    };
    // Relative to a vertex, so a small polygon far from the origin keeps its digits.
    (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            (a[0] - o[0]) * (b[1] - o[1]) - (b[0] - o[0]) * (a[1] - o[1])
        })
        .sum::<f64>()
        / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Unorm16Rgba;

    fn grid(w: u32, h: u32, f: impl Fn(u32, u32) -> [u16; 4]) -> Arc<TexelGrid> {
        let mut t = Vec::new();
        for r in 0..h {
            for c in 0..w {
                t.push(Unorm16Rgba(f(c, r)));
            }
        }
        Arc::new(TexelGrid::new(w, h, t).unwrap())
    }

    /// A 3×2 image stretched over texture `[0.1, 0.7] × [0.2, 0.6]`: texel
    /// width 0.2, height 0.2, row 0 at the top (`z` from 0.6 down).
    fn placed() -> ImagePaint {
        let g = grid(3, 2, |c, r| {
            let v = (c + 3 * r) as u16 * 10000;
            [v / 2, v / 3, v / 4, v]
        });
        // u = (x − 0.1)/0.2, v = (0.6 − z)/0.2
        ImagePaint::new(g, [5.0, 0.0, 0.0, -5.0, -0.5, 3.0]).unwrap()
    }

    /// The same mean by sampling on a fine grid (midpoint rule).
    fn sampled_mean(p: &ImagePaint, lo: Point, hi: Point, n: usize) -> [f64; 4] {
        let mut s = [0.0; 4];
        for i in 0..n {
            for j in 0..n {
                let x = lo[0] + (hi[0] - lo[0]) * (i as f64 + 0.5) / n as f64;
                let z = lo[1] + (hi[1] - lo[1]) * (j as f64 + 0.5) / n as f64;
                let c = p.colour_at([x, z]);
                for k in 0..4 {
                    s[k] += c[k] / (n * n) as f64;
                }
            }
        }
        s
    }

    #[test]
    fn mean_over_a_rectangle_is_the_area_weighted_sum_of_texels() {
        let p = placed();
        // Covers texels (0,0) half, (1,0) full, (0,1) half, (1,1) full, in u ∈ [0.5, 2], v ∈ [0, 2].
        let rect = [[0.2, 0.2], [0.5, 0.2], [0.5, 0.6], [0.2, 0.6]];
        let (mean, err) = p.mean_over(&rect);
        assert_eq!(err, 0.0);
        let t = |c, r| p.texel(c, r);
        for k in 0..4 {
            let expected = (0.5 * t(0, 0)[k] + t(1, 0)[k] + 0.5 * t(0, 1)[k] + t(1, 1)[k]) / 3.0;
            assert!((mean[k] - expected).abs() < 1e-12, "{k}: {mean:?}");
        }
        // Reversed orientation gives the same mean.
        let mut rev = rect;
        rev.reverse();
        assert_eq!(p.mean_over(&rev).0, mean);
    }

    #[test]
    fn mean_over_a_triangle_matches_dense_sampling() {
        let p = placed();
        let tri = [[0.13, 0.25], [0.66, 0.31], [0.29, 0.58]];
        let (mean, _) = p.mean_over(&tri);
        // Sample the triangle by rejection on a fine grid.
        let n = 2000;
        let (mut s, mut count) = ([0.0; 4], 0usize);
        let inside = |q: Point| {
            let cross =
                |a: Point, b: Point| (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0]);
            cross(tri[0], tri[1]) >= 0.0
                && cross(tri[1], tri[2]) >= 0.0
                && cross(tri[2], tri[0]) >= 0.0
        };
        for i in 0..n {
            for j in 0..n {
                let q = [
                    0.1 + 0.6 * (i as f64 + 0.5) / n as f64,
                    0.2 + 0.4 * (j as f64 + 0.5) / n as f64,
                ];
                if inside(q) {
                    let c = p.colour_at(q);
                    for k in 0..4 {
                        s[k] += c[k];
                    }
                    count += 1;
                }
            }
        }
        for k in 0..4 {
            let sampled = s[k] / count as f64;
            assert!(
                (mean[k] - sampled).abs() < 2e-3,
                "{k}: {} vs {sampled}",
                mean[k]
            );
        }
        // And a rectangle against the midpoint rule, to its own resolution.
        let (lo, hi) = ([0.17, 0.23], [0.61, 0.52]);
        let rect = [lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]];
        let exact = p.mean_over(&rect).0;
        let dense = sampled_mean(&p, lo, hi, 1000);
        for k in 0..4 {
            assert!((exact[k] - dense[k]).abs() < 2e-3, "{k}");
        }
    }

    #[test]
    fn polygons_beyond_the_image_take_the_edge_texels() {
        let p = placed();
        // Entirely left of the image, level with row 1: texel (0, 1).
        let (mean, _) = p.mean_over(&[[-3.0, 0.25], [-2.0, 0.25], [-2.0, 0.3]]);
        assert_eq!(mean, p.texel(0, 1));
        assert_eq!(p.colour_at([-3.0, 0.25]), p.texel(0, 1));
    }

    #[test]
    fn the_range_holds_every_texel_reached_and_no_other() {
        let p = placed();
        // Inside texel (2, 0) only: a point range.
        let r = p.range_over(&[[0.55, 0.45], [0.65, 0.45], [0.6, 0.55]]);
        let t = p.texel(2, 0);
        for k in 0..4 {
            assert_eq!(r[k], [t[k], t[k]]);
        }
        let all = p.range_over(&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
        assert_eq!(all[3], [0.0, p.texel(2, 1)[3]]);
    }

    #[test]
    fn degenerate_placements_are_refused() {
        let g = grid(1, 1, |_, _| [0; 4]);
        assert!(ImagePaint::new(g.clone(), [1.0, 2.0, 2.0, 4.0, 0.0, 0.0]).is_err());
        assert!(ImagePaint::new(g, [f64::NAN, 0.0, 0.0, 1.0, 0.0, 0.0]).is_err());
    }
}

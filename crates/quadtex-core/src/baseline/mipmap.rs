//! Raster baseline filters: what users run today, on the same footprints the
//! quadtree integrates exactly. Each follows a named reference:
//!
//! * [`MipPyramid::nearest`], [`MipPyramid::bilinear`]: point and bilinear
//!   lookups of the finest level, no mip-mapping;
//! * [`MipPyramid::trilinear`]: pbrt-v4 `MIPMap::Filter` with
//!   `FilterFunction::Trilinear` (level from the footprint's longest
//!   component, `level = levels − 1 + log2(2·max|∂|)`, bilinear lookups in the
//!   two nearest levels, lerped; pbrt's quirk of not lerping below level 1 is
//!   kept);
//! * [`MipPyramid::ewa`]: pbrt-v4 `MIPMap::EWA` (elliptical Gaussian,
//!   `exp(−2r²) − exp(−2)`, evaluated exactly instead of pbrt's 128-entry
//!   table; minor axis stretched to at most `max_anisotropy` (default 8) times
//!   shorter than the major; level from the minor axis; two levels lerped).
//!
//! The pyramid is built from the tree's texel grid: a non-power-of-two
//! raster is first resampled (exact area weights) to the next power of two,
//! as pbrt does; each coarser level is the 2×2 box average of the one below.
//! Texels are stored as `f32` RGBA (16 bytes a texel); [`MipPyramid::memory_bytes`]
//! reports that, and [`MipPyramid::rgba8_bytes`] what the same pyramid takes
//! in the RGBA8 format a GPU would use.
//!
//! Coordinates follow the crate conventions (`x` right, `z` up, row 0 at the
//! top); texel centres sit at half-integers of `x·W` and `(1−z)·H`.

use crate::colour::Rgba;
use crate::filter::footprint::Footprint;
use crate::filter::wrap::Wrap;
use crate::raster::{TexelGrid, resample};

struct Level {
    side: usize,
    texels: Vec<[f32; 4]>,
}

/// A mip pyramid of `f32` RGBA levels, finest first.
pub struct MipPyramid {
    levels: Vec<Level>,
}

impl MipPyramid {
    /// Builds the pyramid of a raster (see the module documentation).
    pub fn new(grid: &TexelGrid) -> MipPyramid {
        let side = grid.width().max(grid.height()).next_power_of_two() as usize;
        let base: Vec<[f32; 4]> = if grid.width() as usize == side && grid.height() as usize == side
        {
            grid.texels()
                .iter()
                .map(|t| t.to_rgba().to_array())
                .collect()
        } else {
            resample(grid, side)
                .iter()
                .map(|t| t.to_rgba().to_array())
                .collect()
        };
        let mut levels = vec![Level { side, texels: base }];
        while let Some(prev) = levels.last().filter(|l| l.side > 1) {
            let s = prev.side / 2;
            let mut texels = vec![[0f32; 4]; s * s];
            for r in 0..s {
                for c in 0..s {
                    let at = |rr: usize, cc: usize| prev.texels[rr * prev.side + cc];
                    let (a, b, d, e) = (
                        at(2 * r, 2 * c),
                        at(2 * r, 2 * c + 1),
                        at(2 * r + 1, 2 * c),
                        at(2 * r + 1, 2 * c + 1),
                    );
                    texels[r * s + c] =
                        std::array::from_fn(|ch| 0.25 * (a[ch] + b[ch] + d[ch] + e[ch]));
                }
            }
            levels.push(Level { side: s, texels });
        }
        MipPyramid { levels }
    }

    /// Number of levels (finest = 0).
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// Bytes held (`f32` RGBA).
    pub fn memory_bytes(&self) -> u64 {
        self.levels
            .iter()
            .map(|l| (l.texels.len() * 16) as u64)
            .sum()
    }

    /// Bytes the same pyramid would take as RGBA8.
    pub fn rgba8_bytes(&self) -> u64 {
        self.memory_bytes() / 4
    }

    fn texel(&self, level: usize, col: i64, row: i64, wrap: Wrap) -> [f32; 4] {
        let l = &self.levels[level.min(self.levels.len() - 1)];
        let n = l.side as i64;
        // Rows run down from z = 1, so a row index folds like a column index.
        match (wrap.x().fold_index(col, n), wrap.z().fold_index(row, n)) {
            (Some(c), Some(r)) => l.texels[(r * n + c) as usize],
            _ => wrap.border_colour().to_array(),
        }
    }

    /// Texel containing the point, finest level.
    pub fn nearest(&self, x: f64, z: f64, wrap: Wrap) -> Rgba {
        let n = self.levels[0].side as f64;
        let t = self.texel(
            0,
            (x * n).floor() as i64,
            ((1.0 - z) * n).floor() as i64,
            wrap,
        );
        Rgba::new(t[0], t[1], t[2], t[3])
    }

    /// Bilinear interpolation between the four nearest texel centres of `level`.
    pub fn bilinear(&self, level: usize, x: f64, z: f64, wrap: Wrap) -> Rgba {
        let level = level.min(self.levels.len() - 1);
        let n = self.levels[level].side as f64;
        let (u, v) = (x * n - 0.5, (1.0 - z) * n - 0.5);
        let (c0, r0) = (u.floor(), v.floor());
        let (fu, fv) = ((u - c0) as f32, (v - r0) as f32);
        let (c0, r0) = (c0 as i64, r0 as i64);
        let a = self.texel(level, c0, r0, wrap);
        let b = self.texel(level, c0 + 1, r0, wrap);
        let c = self.texel(level, c0, r0 + 1, wrap);
        let d = self.texel(level, c0 + 1, r0 + 1, wrap);
        let mix = |ch: usize| {
            let top = a[ch] + fu * (b[ch] - a[ch]);
            let bottom = c[ch] + fu * (d[ch] - c[ch]);
            top + fv * (bottom - top)
        };
        Rgba::new(mix(0), mix(1), mix(2), mix(3))
    }

    /// pbrt-v4 trilinear mip-mapping.
    pub fn trilinear(&self, fp: &Footprint, wrap: Wrap) -> Rgba {
        let (d_dx, d_dy) = fp.differentials();
        let width = 2.0
            * [d_dx[0], d_dx[1], d_dy[0], d_dy[1]]
                .iter()
                .fold(0f64, |m, v| m.max(v.abs()));
        let n_levels = self.levels.len();
        let level = (n_levels - 1) as f64 + width.max(1e-8).log2();
        let [x, z] = fp.centre();
        if level >= (n_levels - 1) as f64 {
            return self.bilinear(n_levels - 1, x, z, wrap);
        }
        let i = level.floor().max(0.0) as usize;
        if i == 0 {
            return self.bilinear(0, x, z, wrap);
        }
        let t = (level - i as f64) as f32;
        self.bilinear(i, x, z, wrap)
            .lerp(self.bilinear(i + 1, x, z, wrap), t)
    }

    /// pbrt-v4 elliptically weighted average.
    pub fn ewa(&self, fp: &Footprint, max_anisotropy: f64, wrap: Wrap) -> Rgba {
        let (mut major, mut minor) = fp.differentials();
        let len = |v: [f64; 2]| v[0].hypot(v[1]);
        if len(major) < len(minor) {
            std::mem::swap(&mut major, &mut minor);
        }
        let (major_len, mut minor_len) = (len(major), len(minor));
        if minor_len * max_anisotropy < major_len && minor_len > 0.0 {
            let scale = major_len / (minor_len * max_anisotropy);
            minor = [minor[0] * scale, minor[1] * scale];
            minor_len *= scale;
        }
        let centre = fp.centre();
        let [x, z] = centre;
        if minor_len == 0.0 {
            return self.bilinear(0, x, z, wrap);
        }
        let lod = ((self.levels.len() - 1) as f64 + minor_len.log2()).max(0.0);
        let i = lod.floor() as usize;
        let t = (lod - i as f64) as f32;
        self.ewa_level(i, centre, major, minor, wrap)
            .lerp(self.ewa_level(i + 1, centre, major, minor, wrap), t)
    }

    fn ewa_level(
        &self,
        level: usize,
        centre: [f64; 2],
        d0: [f64; 2],
        d1: [f64; 2],
        wrap: Wrap,
    ) -> Rgba {
        if level >= self.levels.len() {
            let t = self.texel(self.levels.len() - 1, 0, 0, wrap);
            return Rgba::new(t[0], t[1], t[2], t[3]);
        }
        let n = self.levels[level].side as f64;
        // Texel-centre coordinates of this level; z flips because rows run downwards.
        let (s, t) = (centre[0] * n - 0.5, (1.0 - centre[1]) * n - 0.5);
        let (d0, d1) = ([d0[0] * n, -d0[1] * n], [d1[0] * n, -d1[1] * n]);
        let mut a = d0[1] * d0[1] + d1[1] * d1[1] + 1.0;
        let mut b = -2.0 * (d0[0] * d0[1] + d1[0] * d1[1]);
        let mut c = d0[0] * d0[0] + d1[0] * d1[0] + 1.0;
        let inv_f = 1.0 / (a * c - b * b * 0.25);
        a *= inv_f;
        b *= inv_f;
        c *= inv_f;
        let det = -b * b + 4.0 * a * c;
        let inv_det = 1.0 / det;
        let (u_sqrt, v_sqrt) = ((det * c).max(0.0).sqrt(), (a * det).max(0.0).sqrt());
        let s0 = (s - 2.0 * inv_det * u_sqrt).ceil() as i64;
        let s1 = (s + 2.0 * inv_det * u_sqrt).floor() as i64;
        let t0 = (t - 2.0 * inv_det * v_sqrt).ceil() as i64;
        let t1 = (t + 2.0 * inv_det * v_sqrt).floor() as i64;
        let (mut sum, mut weights) = ([0f64; 4], 0f64);
        for it in t0..=t1 {
            let tt = it as f64 - t;
            for is in s0..=s1 {
                let ss = is as f64 - s;
                let r2 = a * ss * ss + b * ss * tt + c * tt * tt;
                if r2 < 1.0 {
                    let w = (-2.0 * r2).exp() - (-2.0f64).exp();
                    let texel = self.texel(level, is, it, wrap);
                    for (acc, &v) in sum.iter_mut().zip(&texel) {
                        *acc += w * f64::from(v);
                    }
                    weights += w;
                }
            }
        }
        if weights <= 0.0 {
            return self.bilinear(level, centre[0], centre[1], wrap);
        }
        let m = |ch: usize| (sum[ch] / weights) as f32;
        Rgba::new(m(0), m(1), m(2), m(3))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::synth::checkerboard;

    fn fp(x: f64, z: f64, dx: [f64; 2], dy: [f64; 2]) -> Footprint {
        Footprint::from_differentials([x, z], dx, dy).unwrap()
    }

    #[test]
    fn lookups_at_texel_centres_return_texels() {
        let g = checkerboard(4, 4).unwrap();
        let p = MipPyramid::new(&g);
        assert_eq!(p.levels(), 3);
        for (col, row) in [(0u32, 0u32), (1, 2), (3, 3)] {
            let (x, z) = (
                (f64::from(col) + 0.5) / 4.0,
                1.0 - (f64::from(row) + 0.5) / 4.0,
            );
            let want = g.texel(col, row).to_rgba();
            assert_eq!(p.nearest(x, z, Wrap::CLAMP), want);
            let b = p.bilinear(0, x, z, Wrap::CLAMP);
            assert!((b.r - want.r).abs() < 1e-6, "{b:?} vs {want:?}");
        }
    }

    #[test]
    fn wide_footprints_converge_to_the_mean() {
        let g = checkerboard(8, 64).unwrap();
        let p = MipPyramid::new(&g);
        let mean = (0.6 + 0.05) / 2.0;
        let wide = fp(0.3, 0.6, [0.5, 0.0], [0.0, 0.5]);
        assert!((p.trilinear(&wide, Wrap::REPEAT).r - mean).abs() < 1e-3);
        assert!((p.ewa(&wide, 8.0, Wrap::REPEAT).r - mean).abs() < 1e-3);
    }

    #[test]
    fn ewa_blurs_less_than_trilinear_across_a_thin_anisotropic_footprint() {
        // Vertical stripes, one texel wide; a footprint long in z and thin in x
        // sits on one stripe: EWA keeps it, trilinear (level from the long axis) greys it out.
        let g = TexelGrid::from_fn(64, 64, |c, _| {
            if c % 8 < 4 {
                Rgba::opaque(1.0, 1.0, 1.0)
            } else {
                Rgba::opaque(0.0, 0.0, 0.0)
            }
        })
        .unwrap();
        let p = MipPyramid::new(&g);
        let f = fp(
            (1.5 + 0.5) / 64.0,
            0.5,
            [0.5 / 64.0, 0.0],
            [0.0, 8.0 / 64.0],
        );
        let ewa = p.ewa(&f, 8.0, Wrap::REPEAT).r;
        let tri = p.trilinear(&f, Wrap::REPEAT).r;
        assert!(ewa > 0.9, "ewa {ewa}");
        assert!(tri < 0.8, "trilinear {tri}");
    }

    #[test]
    fn non_power_of_two_is_resampled() {
        let g = TexelGrid::from_fn(3, 5, |_, _| Rgba::opaque(0.5, 0.25, 0.125)).unwrap();
        let p = MipPyramid::new(&g);
        assert_eq!(p.levels(), 4);
        let c = p.nearest(0.9, 0.1, Wrap::CLAMP);
        assert!((c.g - 0.25).abs() < 1e-4);
    }
}

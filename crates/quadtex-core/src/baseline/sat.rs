//! Summed-area table: the exact box-filter baseline for rasters.
//!
//! The table holds, at corner `(i, j)`, the sum of all texels left of column
//! `i` and below row `j` (rows counted from the *bottom*, `z` up), in
//! **`f64` accumulators** of unorm16 texel values: integer sums stay exact below
//! 2^53, i.e. for any image up to 2^37 texels. Because the integral of a
//! piecewise-constant texture is bilinear inside each texel, bilinear
//! interpolation of the table at a fragment's four corners gives the exact
//! integral over any rectangle, texel-aligned or not: O(1) per fragment.

use crate::colour::WeightedColour;
use crate::geometry::fragment::Fragment;
use crate::raster::TexelGrid;

/// An exact box filter over a raster by summed-area table.
#[derive(Debug, Clone)]
pub struct SummedAreaTable {
    width: usize,
    height: usize,
    /// `(width + 1) × (height + 1)` corners, row-major from the bottom.
    table: Vec<[f64; 4]>,
}

impl SummedAreaTable {
    /// Builds the table of a raster.
    pub fn new(grid: &TexelGrid) -> SummedAreaTable {
        let (w, h) = (grid.width() as usize, grid.height() as usize);
        let stride = w + 1;
        let mut table = vec![[0f64; 4]; stride * (h + 1)];
        for j in 0..h {
            let row = (h - 1 - j) as u32;
            let mut run = [0f64; 4];
            for i in 0..w {
                let t = grid.texel(i as u32, row);
                for ch in 0..4 {
                    run[ch] += f64::from(t.0[ch]);
                    table[(j + 1) * stride + i + 1][ch] = table[j * stride + i + 1][ch] + run[ch];
                }
            }
        }
        SummedAreaTable {
            width: w,
            height: h,
            table,
        }
    }

    /// Width of the raster in texels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height of the raster in texels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Bytes of memory the table occupies.
    pub fn memory_bytes(&self) -> u64 {
        (self.table.len() * std::mem::size_of::<[f64; 4]>()) as u64
    }

    /// Integral of the texture over `[0,x) × [0,z)`, `x, z ∈ [0,1]`, in texel-sum units.
    #[inline]
    fn integral_to(&self, x: f64, z: f64) -> [f64; 4] {
        let u = x * self.width as f64;
        let v = z * self.height as f64;
        let i = (u as usize).min(self.width - 1);
        let j = (v as usize).min(self.height - 1);
        let (fu, fv) = (u - i as f64, v - j as f64);
        let stride = self.width + 1;
        let (a, b) = (self.table[j * stride + i], self.table[j * stride + i + 1]);
        let (c, d) = (
            self.table[(j + 1) * stride + i],
            self.table[(j + 1) * stride + i + 1],
        );
        let mut out = [0f64; 4];
        for ch in 0..4 {
            let lo = a[ch] + fu * (b[ch] - a[ch]);
            let hi = c[ch] + fu * (d[ch] - c[ch]);
            out[ch] = lo + fv * (hi - lo);
        }
        out
    }

    /// The weighted colour of the fragment's overlap with the unit square (exact).
    pub fn weighted_colour(&self, fragment: &Fragment) -> WeightedColour {
        let Some(f) = fragment.clip_to_unit() else {
            return WeightedColour::ZERO;
        };
        let p11 = self.integral_to(f.x1(), f.z1());
        let p01 = self.integral_to(f.x0(), f.z1());
        let p10 = self.integral_to(f.x1(), f.z0());
        let p00 = self.integral_to(f.x0(), f.z0());
        let scale = 1.0 / (65535.0 * self.width as f64 * self.height as f64);
        WeightedColour(std::array::from_fn(|ch| {
            (p11[ch] - p01[ch] - p10[ch] + p00[ch]) * scale
        }))
    }
}

//! Random incomplete trees shared by the property tests.
#![allow(dead_code, clippy::unwrap_used)]

use arbtest::arbitrary::{Result as ArbResult, Unstructured};
use quadtex_core::{Rgba, TexelGrid};

pub const PALETTE: [Rgba; 5] = [
    Rgba::opaque(1.0, 0.0, 0.0),
    Rgba::opaque(0.0, 0.5, 1.0),
    Rgba::new(0.1, 0.2, 0.3, 0.5),
    Rgba::TRANSPARENT,
    Rgba::opaque(0.25, 0.25, 0.25),
];

/// A blocky random power-of-two grid: each square is uniform or split, so the
/// tree is incomplete with terminals at every level.
pub fn blocky_grid(u: &mut Unstructured<'_>, max_depth: u32) -> ArbResult<TexelGrid> {
    let depth = u.int_in_range(0..=max_depth)?;
    let side = 1usize << depth;
    let mut texels = vec![PALETTE[0]; side * side];
    fill(u, &mut texels, side, 0, 0, side)?;
    Ok(TexelGrid::from_fn(side as u32, side as u32, |c, r| {
        texels[r as usize * side + c as usize]
    })
    .unwrap())
}

/// [`blocky_grid`], or one time in two a strip of it: its first `2^-k` of
/// rows or of columns, a texture that takes part of the tree's square.
pub fn blocky_grid_any_aspect(u: &mut Unstructured<'_>, max_depth: u32) -> ArbResult<TexelGrid> {
    let grid = if u.ratio(1, 3)? {
        noisy_srgb8_grid(u, max_depth)?
    } else {
        blocky_grid(u, max_depth)?
    };
    let side = grid.width();
    if side == 1 || u.ratio(1, 3)? {
        return Ok(grid);
    }
    if u.ratio(1, 2)? {
        // Any size: a crop, which keeps its texels on part of the tree.
        let (w, h) = (u.int_in_range(1..=side)?, u.int_in_range(1..=side)?);
        return Ok(TexelGrid::from_fn(w, h, |c, r| grid.texel(c, r).to_rgba()).unwrap());
    }
    let short = side >> u.int_in_range(1..=side.trailing_zeros())?;
    let (w, h) = if u.ratio(1, 2)? {
        (side, short)
    } else {
        (short, side)
    };
    Ok(TexelGrid::from_fn(w, h, |c, r| grid.texel(c, r).to_rgba()).unwrap())
}

/// A square 8-bit sRGB grid (as a PNG decodes) of noise over a few bytes
/// per channel, with translucent texels: its subtrees split to the texels,
/// so the packer keeps most of its bottom in 8-bit texel blocks.
pub fn noisy_srgb8_grid(u: &mut Unstructured<'_>, max_depth: u32) -> ArbResult<TexelGrid> {
    let side = 1u32 << u.int_in_range(0..=max_depth)?;
    let mut bytes = Vec::with_capacity((side * side) as usize);
    for _ in 0..side * side {
        let v = *u.choose(&[0u8, 40, 128, 200, 255])?;
        let a = *u.choose(&[255u8, 255, 255, 128, 0])?;
        bytes.push([v, 255 - v, v / 2, a]);
    }
    Ok(TexelGrid::from_srgb8(side, side, bytes).unwrap())
}

pub fn fill(
    u: &mut Unstructured<'_>,
    t: &mut [Rgba],
    side: usize,
    x: usize,
    y: usize,
    n: usize,
) -> ArbResult<()> {
    if n == 1 || u.ratio(1, 3)? {
        let c = if u.ratio(1, 8)? {
            Rgba::opaque(u.int_in_range(0..=255u8)? as f32 / 255.0, 0.3, 0.7)
        } else {
            PALETTE[u.choose_index(PALETTE.len())?]
        };
        for row in y..y + n {
            for col in x..x + n {
                t[row * side + col] = c;
            }
        }
        return Ok(());
    }
    let h = n / 2;
    for (dx, dy) in [(0, 0), (h, 0), (0, h), (h, h)] {
        fill(u, t, side, x + dx, y + dy, h)?;
    }
    Ok(())
}

/// Heckbert's square-to-quad coefficients `[a, b, c, d, e, f, g, h]`:
/// texture `(x, z) = ((a u + b v + c), (d u + e v + f)) / (g u + h v + 1)`
/// for `(u, v)` in the pixel square, corners in the footprint's order.
#[allow(dead_code)]
pub fn coefficients(p: [[f64; 2]; 4]) -> [f64; 8] {
    let [p0, p1, p2, p3] = p;
    let sx = p0[0] - p1[0] + p2[0] - p3[0];
    let sz = p0[1] - p1[1] + p2[1] - p3[1];
    let (dx1, dx2, dz1, dz2) = (p1[0] - p2[0], p3[0] - p2[0], p1[1] - p2[1], p3[1] - p2[1]);
    let den = dx1 * dz2 - dx2 * dz1;
    let g = (sx * dz2 - dx2 * sz) / den;
    let h = (dx1 * sz - sx * dz1) / den;
    [
        p1[0] - p0[0] + g * p1[0],
        p3[0] - p0[0] + h * p3[0],
        p0[0],
        p1[1] - p0[1] + g * p1[1],
        p3[1] - p0[1] + h * p3[1],
        p0[1],
        g,
        h,
    ]
}

//! Differential: the fast fragment integral against the slow truncated-tree
//! sum, on small random trees and arbitrary floats (NaN, infinities, huge,
//! subnormal, reversed bounds included). Trees are square or strips (part
//! of the tree's square), LDR (unorm16, with 8-bit texel blocks when the
//! texels come as sRGB bytes) or HDR (half floats).
#![no_main]
use libfuzzer_sys::fuzz_target;
use quadtex_core::reference::truncated_tree_sum;
use quadtex_core::{BuildOptions, Fragment, QuadTree, Rgba, TexelGrid};

fuzz_target!(|data: &[u8]| {
    if data.len() < 35 {
        return;
    }
    let side = 1u32 << (data[0] % 5);
    // Strips: one side shortened by a power of two.
    let shrink = (data[34] >> 2) % 4;
    let (w, h) = match data[34] % 3 {
        0 => (side, side),
        1 => (side, (side >> shrink).max(1)),
        _ => ((side >> shrink).max(1), side),
    };
    let pick = &data[35..];
    let palette = [Rgba::opaque(1.0, 0.0, 0.0), Rgba::opaque(0.0, 0.3, 1.0), Rgba::new(0.1, 0.2, 0.3, 0.5), Rgba::TRANSPARENT];
    let bytes = [[255u8, 0, 0, 255], [0, 149, 255, 255], [89, 124, 149, 128], [0, 0, 0, 0]];
    // Blocky: neighbours often share a byte, so the tree is incomplete.
    let at = |c: u32, r: u32| usize::from(pick.get(((r * w + c) / 4) as usize).copied().unwrap_or(0) % 4);
    let grid = match data[34] / 16 % 3 {
        0 => TexelGrid::from_fn(w, h, |c, r| palette[at(c, r)]),
        1 => TexelGrid::from_srgb8(w, h, (0..h).flat_map(|r| (0..w).map(move |c| bytes[at(c, r)])).collect()),
        _ => {
            let texels: Vec<[f32; 4]> = (0..h)
                .flat_map(|r| (0..w).map(move |c| (c, r)))
                .map(|(c, r)| {
                    let [r_, g, b, a] = palette[at(c, r)].to_array();
                    [r_ * 900.0, g - 0.5, b, a]
                })
                .collect();
            TexelGrid::from_linear_f32(w, h, &texels)
        }
    }
    .unwrap();
    let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
    let f64_at = |o: usize| f64::from_le_bytes(data[o..o + 8].try_into().unwrap());
    let k = data[1] % 8;
    let Ok(f) = Fragment::new(f64_at(2), f64_at(10), f64_at(18), f64_at(26)) else { return };
    let fast = tree.weighted_colour(&f, k);
    let slow = truncated_tree_sum(&tree, &f, k);
    let area = f.clip_to_unit().map_or(0.0, |c| c.area());
    // Storage rounding: half a unorm16 step, or for half floats 2^-11 of
    // the largest value (900), per unit area.
    let step = if grid.is_hdr() { 900.0 / 1024.0 } else { 1.0 / 65535.0 };
    let tol = 1e-12 + area * step + area * 1e-12;
    for (a, b) in fast.0.iter().zip(&slow.0) {
        assert!((a - b).abs() <= tol, "{f:?} k={k}: {fast:?} vs {slow:?}");
    }
});

//! Differential: the fast fragment integral against the slow truncated-tree
//! sum, on small random trees and arbitrary floats (NaN, infinities, huge,
//! subnormal, reversed bounds included).
#![no_main]
use libfuzzer_sys::fuzz_target;
use quadtex_core::reference::truncated_tree_sum;
use quadtex_core::{BuildOptions, Fragment, QuadTree, Rgba, TexelGrid};

fuzz_target!(|data: &[u8]| {
    if data.len() < 34 {
        return;
    }
    let side = 1u32 << (data[0] % 5);
    let pick = &data[34..];
    let palette = [Rgba::opaque(1.0, 0.0, 0.0), Rgba::opaque(0.0, 0.3, 1.0), Rgba::new(0.1, 0.2, 0.3, 0.5), Rgba::TRANSPARENT];
    let grid = TexelGrid::from_fn(side, side, |c, r| {
        let i = (r * side + c) as usize;
        // Blocky: neighbours often share a byte, so the tree is incomplete.
        let b = pick.get(i / 4).copied().unwrap_or(0);
        palette[usize::from(b % 4)]
    })
    .unwrap();
    let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
    let f64_at = |o: usize| f64::from_le_bytes(data[o..o + 8].try_into().unwrap());
    let k = data[1] % 8;
    let Ok(f) = Fragment::new(f64_at(2), f64_at(10), f64_at(18), f64_at(26)) else { return };
    let fast = tree.weighted_colour(&f, k);
    let slow = truncated_tree_sum(&tree, &f, k);
    let area = f.clip_to_unit().map_or(0.0, |c| c.area());
    let tol = 1e-12 + area / 65535.0 + area * 1e-12;
    for (a, b) in fast.0.iter().zip(&slow.0) {
        assert!((a - b).abs() <= tol, "{f:?} k={k}: {fast:?} vs {slow:?}");
    }
});

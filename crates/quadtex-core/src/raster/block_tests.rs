use super::tests::sq;
use super::*;
use crate::Fragment;
use crate::tree::texel_block::srgb8_texel;

fn noise(c: u32, r: u32) -> [u8; 4] {
    let h = c.wrapping_mul(2_654_435_761) ^ r.wrapping_mul(40_503);
    [
        (h % 251) as u8,
        (h / 7 % 253) as u8,
        (h / 13 % 241) as u8,
        255,
    ]
}

/// An 8-bit photograph-like grid keeps its bytes in blocks; every texel
/// integrates back exactly, and the tree is smaller than its nodes were.
#[test]
fn photographs_keep_8_bit_texels_in_blocks() {
    let (w, h) = (16u32, 16u32);
    let bytes: Vec<[u8; 4]> = (0..h)
        .flat_map(|r| (0..w).map(move |c| noise(c, r)))
        .collect();
    let g = TexelGrid::from_srgb8(w, h, bytes.clone()).unwrap();
    let (t, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
    let tb = t.texel_blocks().expect("blocks");
    // Opaque colour: three bytes a texel.
    assert_eq!(tb.format(), BlockFormat::Srgb8Rgb);
    assert_eq!((tb.level(), tb.count()), (2, 16));
    assert_eq!(t.depth(), 4);
    // Level 2 is the deepest stored level: 1 + 4 + 16 nodes.
    assert_eq!(t.node_count(), 21);
    for r in 0..h {
        for c in 0..w {
            let f = Fragment::new(
                f64::from(c) / 16.0,
                f64::from(15 - r) / 16.0,
                f64::from(c + 1) / 16.0,
                f64::from(16 - r) / 16.0,
            )
            .unwrap();
            let got = t.weighted_colour(&f, 30).0.map(|v| v * 256.0);
            let want = srgb8_texel(bytes[(r * w + c) as usize])
                .to_rgba()
                .to_array();
            for (a, b) in got.iter().zip(want) {
                assert!(
                    (a - f64::from(b)).abs() < 1e-6,
                    "({c}, {r}): {got:?} vs {want:?}"
                );
            }
            assert_eq!(t.uniform_colour(&f), Some(g.texel(c, r).to_rgba()));
        }
    }
    // Translucent texels keep four bytes, opaque grey one.
    let format = |f: fn([u8; 4]) -> [u8; 4]| {
        let bytes = bytes.iter().map(|&p| f(p)).collect();
        let g = TexelGrid::from_srgb8(w, h, bytes).unwrap();
        let (t, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
        t.texel_blocks().map(|b| b.format())
    };
    assert_eq!(
        format(|[r, g, b, _]| [r, g, b, r]),
        Some(BlockFormat::Srgb8Rgba)
    );
    assert_eq!(
        format(|[r, ..]| [r, r, r, 255]),
        Some(BlockFormat::Srgb8Grey)
    );
    let unorm = TexelGrid::new(w, h, g.texels().to_vec()).unwrap();
    let (t16, _) = QuadTree::from_texels(&unorm, &BuildOptions::default()).unwrap();
    assert_eq!(
        t16.texel_blocks().map(|b| b.format()),
        Some(BlockFormat::Unorm16Rgba)
    );
    assert!(t.memory_bytes() < t16.memory_bytes());
}

/// 8-bit tiles of different kinds (grey first, then colour, then
/// translucent) widen the blocks as they come: the tree is the whole
/// mosaic's. A 16-bit tile among 8-bit ones is refused by name.
#[test]
fn tiles_widen_their_blocks_to_the_mosaic_format() {
    let texel = |x: u32, y: u32| {
        let v = noise(x, y);
        match (x / 8, y / 8) {
            (0, 0) => [v[0], v[0], v[0], 255],
            (1, 0) => v,
            _ => [v[0], v[1], v[2], v[0] | 1],
        }
    };
    let bytes = (0..16u32)
        .flat_map(|y| (0..16).map(move |x| texel(x, y)))
        .collect();
    let whole = TexelGrid::from_srgb8(16, 16, bytes).unwrap();
    let options = BuildOptions::default();
    let (expected, _) = QuadTree::from_texels(&whole, &options).unwrap();
    assert_eq!(
        expected.texel_blocks().map(|b| b.format()),
        Some(BlockFormat::Srgb8Rgba)
    );
    let tile = |row: u32, col: u32| {
        let bytes = (0..8u32)
            .flat_map(|y| (0..8).map(move |x| texel(8 * col + x, 8 * row + y)))
            .collect();
        TexelGrid::from_srgb8(8, 8, bytes)
    };
    let (tree, _) =
        QuadTree::from_tiles(&sq(2, 8), &options, &mut |row, col| tile(row, col)).unwrap();
    assert_eq!(tree, expected);
    let e = QuadTree::from_tiles(&sq(2, 8), &options, &mut |row, col| {
        let t = tile(row, col)?;
        if (row, col) == (1, 1) {
            TexelGrid::new(8, 8, t.texels().to_vec())
        } else {
            Ok(t)
        }
    })
    .unwrap_err();
    assert!(
        e.to_string()
            .starts_with("tile (1, 1) is 16-bit or float, the first tile was 8-bit"),
        "{e}"
    );
    let e = QuadTree::from_tiles(&sq(2, 8), &options, &mut |_, _| {
        TexelGrid::from_linear_f32(8, 8, &[[2.0, 0.5, 0.5, 1.0]; 64])
    })
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "tile (1, 0) is HDR (float): tiled packing takes 8- and 16-bit tiles only"
    );
}

/// HDR texels (up to 1000, below 0, translucent) pack into half floats
/// and integrate back within half-float precision; strips and odd sizes
/// too; a NaN texel is refused by position.
#[test]
fn hdr_texels_keep_their_range_to_half_precision() {
    let value = |c: u32, r: u32| {
        let h = (c.wrapping_mul(2_654_435_761) ^ r.wrapping_mul(40_503)) % 1000;
        let v = match h % 4 {
            0 => 1000.0 - h as f32 / 7.0,
            1 => -(h as f32) / 300.0,
            2 => h as f32 / 1000.0,
            _ => 3.0,
        };
        [
            v,
            0.5 * v,
            -0.25,
            if h.is_multiple_of(5) { 0.5 } else { 1.0 },
        ]
    };
    for (w, h) in [(16u32, 16u32), (32, 4), (5, 3)] {
        let texels: Vec<[f32; 4]> = (0..h)
            .flat_map(|r| (0..w).map(move |c| value(c, r)))
            .collect();
        let g = TexelGrid::from_linear_f32(w, h, &texels).unwrap();
        assert!(g.is_hdr());
        let (t, report) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
        assert_eq!(t.encoding(), ColourEncoding::Half);
        assert!(t.texel_blocks().is_none());
        let exact = |f: &Fragment| {
            // Σ texel × overlap, texels as rectangles of the unit square.
            let mut acc = [0f64; 4];
            for r in 0..h {
                for c in 0..w {
                    let (x0, x1) = (f64::from(c) / f64::from(w), f64::from(c + 1) / f64::from(w));
                    let (z0, z1) = (
                        1.0 - f64::from(r + 1) / f64::from(h),
                        1.0 - f64::from(r) / f64::from(h),
                    );
                    let a = (f.x1().min(x1) - f.x0().max(x0)).max(0.0)
                        * (f.z1().min(z1) - f.z0().max(z0)).max(0.0);
                    for (s, v) in acc.iter_mut().zip(value(c, r)) {
                        *s += a * f64::from(v);
                    }
                }
            }
            acc
        };
        // Every size keeps its texels as its cells: each texel's rectangle
        // integrates back to that texel.
        assert!(!report.resampled, "{w}x{h}");
        let fragments: Vec<Fragment> = (0..h)
            .flat_map(|r| (0..w).map(move |c| (c, r)))
            .map(|(c, r)| {
                Fragment::new(
                    f64::from(c) / f64::from(w),
                    1.0 - f64::from(r + 1) / f64::from(h),
                    f64::from(c + 1) / f64::from(w),
                    1.0 - f64::from(r) / f64::from(h),
                )
                .unwrap()
            })
            .chain([
                Fragment::new(0.1, 0.2, 0.7, 0.9).unwrap(),
                Fragment::new(0.0, 0.0, 1.0, 1.0).unwrap(),
            ])
            .collect();
        for f in fragments {
            let got = t.weighted_colour(&f, 30).0;
            let want = exact(&f);
            for (a, b) in got.iter().zip(want) {
                // Half floats: 11 significant bits, rounded once per
                // texel and once per inner mean.
                let tol = f.area() * 1e-3 + b.abs() * 2.0 / 1024.0;
                assert!((a - b).abs() <= tol, "{w}x{h} {f:?}: {got:?} vs {want:?}");
            }
        }
    }
    let mut texels = vec![[0.5f32; 4]; 12];
    texels[7][1] = f32::NAN;
    let e = TexelGrid::from_linear_f32(4, 3, &texels).unwrap_err();
    assert_eq!(
        e.to_string(),
        "texel (3, 1) has g = NaN: HDR texels must be finite"
    );
    texels[7][1] = f32::INFINITY;
    assert!(TexelGrid::from_linear_f32(4, 3, &texels).is_err());
}

/// Edges of vector-like art stay nodes where nodes are cheaper than a
/// block; uniform squares never become blocks.
#[test]
fn sparse_subtrees_stay_nodes() {
    let g = TexelGrid::from_fn(16, 16, |c, r| {
        if c + r < 9 {
            Rgba::opaque(1.0, 0.0, 0.0)
        } else {
            Rgba::opaque(0.0, 0.0, 1.0)
        }
    })
    .unwrap();
    let (t, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
    let blocks = t.texel_blocks().map_or(0, |b| b.count());
    // A 4×4 square the diagonal crosses splits into 4 + 8 nodes (96 B)
    // against 128 B of unorm16 texels: it stays nodes.
    assert_eq!(blocks, 0, "{blocks} blocks");
}

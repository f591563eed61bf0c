use super::resample::weights_1d;
use super::*;
use crate::tree::texel_block::BlockFormat;

/// A mosaic with uniform regions, edges and noise: `(col, row)` texel.
/// A complete square mosaic (test shorthand).
pub(super) fn sq(tiles: u32, side: u32) -> Mosaic {
    Mosaic::square(tiles, side).unwrap()
}

fn mosaic_texel(col: u32, row: u32) -> Rgba {
    let h = (col.wrapping_mul(2_654_435_761) ^ row.wrapping_mul(40_503)) % 7;
    if col < 20 && row < 12 {
        Rgba::opaque(0.2, 0.4, 0.6)
    } else if (col / 3 + row / 5).is_multiple_of(2) {
        Rgba::new(0.5, 0.25, 0.0, 0.5)
    } else {
        Rgba::opaque(h as f32 / 7.0, 0.1, 0.9)
    }
}

/// The root's quarters built on threads give the sequential build's
/// tree and report: rasters square and not (pad quarters), with and
/// without texel blocks, a tolerance, HDR; a node limit the whole tree
/// could reach keeps the build sequential and its error.
#[test]
fn quarters_built_apart_make_the_sequential_tree() {
    let hdr = |w: u32, h: u32| {
        let mut g = TexelGrid::from_fn(w, h, mosaic_texel).unwrap();
        let half = (0..w * h)
            .map(|i| {
                let v = f64::from(i % 97) * 0.37;
                let c = ColourEncoding::Half.encode(v);
                HalfRgba([c, c, c, ColourEncoding::Half.encode(1.0)])
            })
            .collect();
        g.half = Some(half);
        g
    };
    let cases = [
        (TexelGrid::from_fn(64, 64, mosaic_texel).unwrap(), true, 0.0),
        (
            TexelGrid::from_fn(64, 64, mosaic_texel).unwrap(),
            false,
            0.0,
        ),
        (
            TexelGrid::from_fn(128, 32, mosaic_texel).unwrap(),
            true,
            0.0,
        ),
        (
            TexelGrid::from_fn(24, 96, mosaic_texel).unwrap(),
            true,
            0.05,
        ),
        (hdr(32, 32), false, 0.0),
        (hdr(21, 30), false, 0.0),
        (TexelGrid::from_fn(75, 49, mosaic_texel).unwrap(), true, 0.0),
    ];
    for (grid, texel_blocks, tolerance) in &cases {
        let options = BuildOptions {
            tolerance: *tolerance,
            texel_blocks: *texel_blocks,
            ..BuildOptions::default()
        };
        let sequential = QuadTree::from_texels_split(grid, &options, usize::MAX).unwrap();
        let apart = QuadTree::from_texels_split(grid, &options, 1).unwrap();
        let what = format!("{}x{}, blocks {texel_blocks}", grid.width, grid.height);
        assert_eq!(apart.0, sequential.0, "{what}");
        assert_eq!(apart.1.max_error, sequential.1.max_error, "{what}");
        assert!(apart.0.node_count() > 100, "{what}: too simple to tell");
    }
    // A limit the whole tree could reach: built in order, same error.
    let grid = TexelGrid::from_fn(64, 64, mosaic_texel).unwrap();
    let options = BuildOptions {
        max_nodes: 200,
        ..BuildOptions::default()
    };
    let sequential = QuadTree::from_texels_split(&grid, &options, usize::MAX);
    let apart = QuadTree::from_texels_split(&grid, &options, 1);
    assert_eq!(
        format!("{:?}", apart.map(|_| ())),
        format!("{:?}", sequential.map(|_| ()))
    );
}

#[test]
fn tiles_pack_to_the_tree_of_the_whole_mosaic() {
    for (tiles, side, tolerance) in [
        (4u32, 8u32, 0.0),
        (2, 16, 0.0),
        (4, 8, 0.05),
        (1, 32, 0.0),
        (8, 4, 0.0),
    ] {
        let total = tiles * side;
        let whole = TexelGrid::from_fn(total, total, mosaic_texel).unwrap();
        let options = BuildOptions {
            tolerance,
            ..BuildOptions::default()
        };
        let (expected, expected_report) = QuadTree::from_texels(&whole, &options).unwrap();
        let mut loaded = Vec::new();
        let (tree, report) = QuadTree::from_tiles(&sq(tiles, side), &options, &mut |row, col| {
            loaded.push((row, col));
            TexelGrid::from_fn(side, side, |c, r| {
                mosaic_texel(col * side + c, row * side + r)
            })
        })
        .unwrap();
        assert_eq!(
            tree, expected,
            "{tiles}x{tiles} tiles of {side}, tolerance {tolerance}"
        );
        assert_eq!(report.max_error, expected_report.max_error);
        // Every tile loaded once.
        loaded.sort_unstable();
        loaded.dedup();
        assert_eq!(loaded.len(), (tiles * tiles) as usize);
    }
}

/// A texture of any size packed tile by tile, partial tiles on its top and
/// right edges and tiles wholly in the pad included, is the tree of the
/// whole texture: 16-bit and 8-bit texels, lossless and with a tolerance,
/// tiles packed in order and packed apart (through bytes) then spliced.
#[test]
fn any_size_texture_packs_tile_by_tile_to_the_tree_of_the_whole() {
    let mut uniform = crate::test_rng::uniform(0x7113);
    let mut below = |n: u32| ((uniform() * f64::from(n)) as u32).min(n - 1);
    for case in 0..60 {
        let side = [4u32, 8, 16][below(3) as usize];
        let width = 1 + below(5 * side);
        let height = 1 + below(5 * side);
        let Ok(mosaic) = Mosaic::of_texture(width, height, side) else {
            assert!(2 * width.max(height) <= side, "{width}x{height}/{side}");
            continue;
        };
        let eight = case % 2 == 0;
        let tolerance = if case % 3 == 0 { 0.03 } else { 0.0 };
        let texel8 = |c: u32, r: u32| -> [u8; 4] {
            // Flat patches and noise, so trees have uniform squares and blocks.
            let h = (c.wrapping_mul(2_654_435_761) ^ r.wrapping_mul(40_503)) as u8;
            if (c / 8 + r / 8).is_multiple_of(3) {
                [90, 40, 200, 255]
            } else {
                [h, h / 2, 30, 255]
            }
        };
        let grid_of = |(x0, y0, w, h): (u32, u32, u32, u32)| {
            if eight {
                let bytes = (0..h)
                    .flat_map(|y| (0..w).map(move |x| (x, y)))
                    .map(|(x, y)| texel8(x0 + x, y0 + y))
                    .collect();
                TexelGrid::from_srgb8(w, h, bytes).unwrap()
            } else {
                TexelGrid::from_fn(w, h, |x, y| mosaic_texel(x0 + x, y0 + y)).unwrap()
            }
        };
        let options = BuildOptions {
            tolerance,
            ..BuildOptions::default()
        };
        let what =
            format!("{width}x{height} in tiles of {side}, 8-bit {eight}, tolerance {tolerance}");
        let (expected, expected_report) =
            QuadTree::from_texels(&grid_of((0, 0, width, height)), &options).unwrap();
        let mut asked = Vec::new();
        let (tree, report) = QuadTree::from_tiles(&mosaic, &options, &mut |row, col| {
            asked.push((row, col));
            Ok(grid_of(mosaic.tile_rect(row, col).unwrap()))
        })
        .unwrap();
        assert!(tree == expected, "{what}");
        assert_eq!(report.max_error, expected_report.max_error, "{what}");
        assert_eq!(asked, mosaic.tiles_in_order(), "{what}");
        let packed: Vec<((u32, u32), Vec<u8>)> = mosaic
            .tiles_in_order()
            .into_iter()
            .map(|at| {
                let grid = grid_of(mosaic.tile_rect(at.0, at.1).unwrap());
                let tile = QuadTree::pack_tile(&mosaic, at, &grid, &options, None).unwrap();
                (at, tile.to_bytes())
            })
            .collect();
        let (spliced, _) =
            QuadTree::from_packed_tiles(&mosaic, &options, &mut |row, col, format| match format {
                None => {
                    let (_, bytes) = packed.iter().find(|(at, _)| *at == (row, col)).unwrap();
                    PackedTile::from_bytes(bytes)
                }
                Some(f) => {
                    let grid = grid_of(mosaic.tile_rect(row, col).unwrap());
                    QuadTree::pack_tile(&mosaic, (row, col), &grid, &options, Some(f))
                }
            })
            .unwrap();
        assert!(spliced == expected, "{what}");
        // A pad tile, or one of another size, is refused by name.
        let n = mosaic.tiles();
        let full = grid_of((0, 0, side, side));
        if let Some(pad) = (0..n * n)
            .map(|i| (i / n, i % n))
            .find(|&(r, c)| mosaic.tile_rect(r, c).is_none())
        {
            let e = QuadTree::pack_tile(&mosaic, pad, &full, &options, None).unwrap_err();
            assert!(
                e.to_string().contains("outside the mosaic's texture"),
                "{e}"
            );
        }
        let (row, col) = mosaic.tiles_in_order()[0];
        if mosaic.tile_extent(row, col) != Some((side, side)) {
            let e = QuadTree::pack_tile(&mosaic, (row, col), &full, &options, None).unwrap_err();
            assert!(e.to_string().contains("not the size"), "{e}");
        }
    }
}

/// An 8-bit tile of a mosaic whose format depends on where it is: grey,
/// RGB or translucent by quadrant, so the mosaic's block format widens
/// as the build goes.
fn mixed_tile(tiles: u32, side: u32, row: u32, col: u32) -> TexelGrid {
    let bytes = (0..side * side)
        .map(|i| {
            let (c, r) = (col * side + i % side, row * side + i / side);
            let h = (c.wrapping_mul(2_654_435_761) ^ r.wrapping_mul(40_503)) as u8;
            match (row >= tiles / 2, col >= tiles / 2) {
                (false, false) => [h, h, h, 255],
                (false, true) => [h, h / 2, 7, 255],
                (true, false) => [h, h, h, 255],
                (true, true) => [h, 3, h / 3, 200],
            }
        })
        .collect();
    TexelGrid::from_srgb8(side, side, bytes).unwrap()
}

/// Tiles packed on their own (on threads, through bytes) splice into the
/// tree the sequential build makes, byte for byte: plain and 8-bit tiles
/// whose formats widen along the way (grey, then RGB, then RGBA: the
/// splicer asks for tiles again in the wider format), with a tolerance.
#[test]
fn tiles_packed_apart_splice_into_the_sequential_tree() {
    type Load = fn(u32, u32, u32, u32) -> TexelGrid;
    let plain: Load = |_, side, row, col| {
        TexelGrid::from_fn(side, side, |c, r| {
            mosaic_texel(col * side + c, row * side + r)
        })
        .unwrap()
    };
    let mixed: Load = mixed_tile;
    for (load, widens, tiles, side, tolerance) in [
        (plain, false, 4u32, 8u32, 0.0),
        (plain, false, 4, 8, 0.05),
        (plain, false, 1, 16, 0.0),
        (mixed, true, 4, 8, 0.0),
        (mixed, true, 2, 16, 0.0),
    ] {
        let options = BuildOptions {
            tolerance,
            ..BuildOptions::default()
        };
        let sequential = QuadTree::from_tiles(&sq(tiles, side), &options, &mut |row, col| {
            Ok(load(tiles, side, row, col))
        })
        .unwrap();
        // Every tile packed on a thread of its own, in its own format.
        let packed: Vec<Vec<u8>> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..tiles * tiles)
                .map(|i| {
                    let options = &options;
                    scope.spawn(move || {
                        let (row, col) = (i / tiles, i % tiles);
                        let grid = load(tiles, side, row, col);
                        QuadTree::pack_tile(&sq(tiles, side), (row, col), &grid, options, None)
                            .unwrap()
                            .to_bytes()
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        let mut again = 0;
        let spliced =
            QuadTree::from_packed_tiles(&sq(tiles, side), &options, &mut |row, col, format| {
                match format {
                    None => PackedTile::from_bytes(&packed[(row * tiles + col) as usize]),
                    Some(f) => {
                        again += 1;
                        let grid = load(tiles, side, row, col);
                        QuadTree::pack_tile(&sq(tiles, side), (row, col), &grid, &options, Some(f))
                    }
                }
            })
            .unwrap();
        let what = format!("{tiles}x{tiles} tiles of {side}, tolerance {tolerance}");
        assert_eq!(spliced.0, sequential.0, "{what}");
        assert_eq!(spliced.1, sequential.1, "{what}");
        if widens {
            // The RGB quadrant's tiles come first in Morton order after the
            // grey ones; the grey tiles after them are packed again as RGB.
            assert!(again > 0, "{what}: no tile packed again");
            assert_eq!(
                spliced.0.texel_blocks().map(|b| b.format()),
                Some(BlockFormat::Srgb8Rgba)
            );
        }
    }
}

/// Packed tiles read back only what was written: a flipped bit, a cut, a
/// foreign file are refused by name; a tile of the wrong size or format
/// stops the splice.
#[test]
fn packed_tiles_refuse_damage_and_mismatches() {
    let options = BuildOptions::default();
    let grid = mixed_tile(2, 8, 0, 0);
    let tile = QuadTree::pack_tile(&sq(2, 8), (0, 0), &grid, &options, None).unwrap();
    let bytes = tile.to_bytes();
    assert_eq!(PackedTile::from_bytes(&bytes).unwrap(), tile);
    let mut flipped = bytes.clone();
    flipped[40] ^= 0x10;
    assert!(
        PackedTile::from_bytes(&flipped)
            .unwrap_err()
            .to_string()
            .contains("checksum")
    );
    assert!(PackedTile::from_bytes(&bytes[..bytes.len() - 9]).is_err());
    assert!(
        PackedTile::from_bytes(b"PNG, not a tile")
            .unwrap_err()
            .to_string()
            .contains("magic")
    );
    let e = QuadTree::pack_tile(&sq(2, 16), (0, 0), &grid, &options, None).unwrap_err();
    assert!(e.to_string().contains("not the size"), "{e}");
    assert!(QuadTree::pack_tile(&sq(2, 8), (2, 0), &grid, &options, None).is_err());
    let e = QuadTree::pack_tile(
        &sq(2, 8),
        (0, 0),
        &grid,
        &options,
        Some(BlockFormat::Unorm16Rgba),
    )
    .unwrap_err();
    assert!(e.to_string().contains("8-bit"), "{e}");
    // A 16-bit tile among 8-bit ones.
    let sixteen = TexelGrid::from_fn(8, 8, mosaic_texel).unwrap();
    let e = QuadTree::from_packed_tiles(&sq(2, 8), &options, &mut |row, col, format| {
        let g = if (row, col) == (1, 1) {
            sixteen.clone()
        } else {
            mixed_tile(2, 8, row, col)
        };
        QuadTree::pack_tile(&sq(2, 8), (row, col), &g, &options, format)
    })
    .unwrap_err();
    assert!(e.to_string().contains("16-bit"), "{e}");
}

#[test]
fn tiles_of_the_wrong_size_or_failing_to_load_stop_the_build() {
    let options = BuildOptions::default();
    let e = QuadTree::from_tiles(&sq(2, 8), &options, &mut |row, col| {
        let side = if (row, col) == (1, 1) { 4 } else { 8 };
        TexelGrid::from_fn(side, side, |_, _| Rgba::opaque(1.0, 0.0, 0.0))
    })
    .unwrap_err();
    assert!(
        e.to_string().contains("not the size of the mosaic's tile"),
        "{e}"
    );
    let e = QuadTree::from_tiles(&sq(2, 8), &options, &mut |_, _| {
        Err(Error::BadDimensions {
            width: 0,
            height: 0,
            reason: "a test failure",
        })
    })
    .unwrap_err();
    assert!(e.to_string().contains("a test failure"), "{e}");
    assert!(Mosaic::square(3, 8).is_err());
    assert!(Mosaic::square(2, 6).is_err());
    let levelled = BuildOptions {
        max_level: Some(3),
        ..BuildOptions::default()
    };
    assert!(QuadTree::from_tiles(&sq(2, 8), &levelled, &mut |_, _| unreachable!()).is_err());
}

/// Photo-like 8-bit texels of any size pack losslessly as their own
/// bytes: no resampling, blocks across the texture's edge included, the
/// tree passes `verify`, and it costs no more than the RGBA8 raster and its
/// mip pyramid (`4/3 · 4` bytes a texel).
#[test]
fn any_size_packs_its_own_bytes_within_raster_and_mips() {
    for (w, h) in [(600u32, 400u32), (601, 403), (300, 7), (5, 130), (512, 512)] {
        let srgb8: Vec<[u8; 4]> = (0..w * h)
            .map(|i| {
                let (c, r) = (i % w, i / w);
                // 4×4 blocks of random colours with a little noise.
                let block = (c / 4).wrapping_mul(2_654_435_761) ^ (r / 4).wrapping_mul(40_503);
                let noise = (c.wrapping_mul(97) ^ r.wrapping_mul(31)) % 9;
                let v = |k: u32| ((block >> (8 * k)) as u8).wrapping_add(noise as u8);
                [v(0), v(1), v(2), 255]
            })
            .collect();
        let grid = TexelGrid::from_srgb8(w, h, srgb8).unwrap();
        let (tree, report) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
        let what = format!("{w}x{h}");
        assert!(!report.resampled && report.max_error == 0.0, "{what}");
        tree.verify().unwrap_or_else(|e| panic!("{what}: {e}"));
        assert!(
            tree.texel_blocks().is_some_and(|b| b.format().is_srgb8()),
            "{what}: blocks keep the source bytes"
        );
        let raster_and_mips = 4.0 * f64::from(w) * f64::from(h) * 4.0 / 3.0;
        let bytes = tree.memory_bytes() as f64;
        assert!(
            bytes <= raster_and_mips || w * h < 4096,
            "{what}: {bytes} B against {raster_and_mips} B of raster and mips"
        );
    }
}

#[test]
fn weights_cover_each_cell_once() {
    for (t, c) in [(3, 4), (5, 8), (8, 8), (16, 4), (7, 2), (1, 1)] {
        for taps in weights_1d(t, c) {
            let s: f32 = taps.iter().map(|&(_, w)| w).sum();
            assert!((s - 1.0).abs() < 1e-6, "{t} texels -> {c} cells: {taps:?}");
        }
    }
}

#[test]
fn uniform_image_is_a_single_terminal_root() {
    let g = TexelGrid::from_fn(64, 64, |_, _| Rgba::opaque(0.25, 0.5, 0.75)).unwrap();
    let (t, r) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
    assert_eq!(t.node_count(), 1);
    assert_eq!(t.depth(), 0);
    assert_eq!(r.max_error, 0.0);
}

#[test]
fn one_odd_texel_splits_only_its_path() {
    let g = TexelGrid::from_fn(16, 16, |c, r| {
        if (c, r) == (3, 5) {
            Rgba::opaque(1.0, 0.0, 0.0)
        } else {
            Rgba::opaque(0.0, 0.0, 1.0)
        }
    })
    .unwrap();
    let (t, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
    assert_eq!(t.depth(), 4);
    assert_eq!(t.node_count(), 1 + 4 * 4, "one inner node per level");
    let stats = t.level_stats();
    assert_eq!(
        stats.iter().map(|s| s.nodes).collect::<Vec<_>>(),
        vec![1, 4, 4, 4, 4]
    );
}

#[test]
fn tolerance_merges_small_noise_and_reports_error() {
    let g = TexelGrid::from_fn(8, 8, |c, r| {
        Rgba::opaque(0.5 + 0.001 * ((c + r) % 2) as f32, 0.5, 0.5)
    })
    .unwrap();
    let (lossless, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
    assert!(lossless.node_count() > 1);
    let opts = BuildOptions {
        tolerance: 0.002,
        ..BuildOptions::default()
    };
    let (lossy, report) = QuadTree::from_texels(&g, &opts).unwrap();
    assert_eq!(lossy.node_count(), 1);
    assert!(
        report.max_error > 0.0 && report.max_error <= 0.002,
        "{report:?}"
    );
}

#[test]
fn grid_estimate_counts_texels_cells_and_resampling_rows() {
    assert_eq!(raster_grid_bytes(64, 64, 6), 8 * 64 * 64);
    assert_eq!(
        raster_grid_bytes(64, 16, 6),
        8 * 64 * 16,
        "a strip packs its own texels"
    );
    // Other sizes keep their texels as cells: no cell grid, no resampling.
    assert_eq!(raster_grid_bytes(1, 20000, 15), 8 * 20000);
    assert_eq!(raster_grid_bytes(3000, 3000, 12), 8 * 9_000_000);
    // Deeper than the image, each texel repeated 2×2: texels + cells + rows.
    assert_eq!(
        raster_grid_bytes(3000, 3000, 13),
        8 * 9_000_000 + 8 * 6000 * 6000 + 16 * 3000 * 6000
    );
    // Coarser than the image: the square around it, resampled.
    assert_eq!(
        raster_grid_bytes(3000, 3000, 11),
        8 * 9_000_000 + 8 * 2048 * 2048 + 16 * 3000 * 2048
    );
    let g = TexelGrid::from_fn(1, 20000, |_, r| {
        Rgba::opaque((r % 7) as f32 / 7.0, 0.0, 0.0)
    })
    .unwrap();
    let opts = BuildOptions {
        max_bytes: Some(128 << 10),
        ..BuildOptions::default()
    };
    let e = QuadTree::from_texels(&g, &opts).unwrap_err();
    assert!(
        e.to_string().starts_with(
            "packing 1x20000 texels at level 15 (1x20000 cells) needs an estimated 156.3 KiB, above the memory budget of 128.0 KiB"
        ),
        "{e}"
    );
}

/// A noisy 256² image: the up-front part is the texels; the build stops
/// once the nodes so far exceed the rest of the budget, and a budget of
/// the texels plus `BUILD_BYTES_PER_NODE` a node of the finished tree
/// (within 4× of its `memory_bytes`) fits.
#[test]
fn budget_bounds_the_tree_while_building() {
    let g = TexelGrid::from_fn(256, 256, |c, r| {
        let h = (c.wrapping_mul(2_654_435_761) ^ r.wrapping_mul(40503)) % 1000;
        Rgba::opaque(h as f32 / 1000.0, 0.5, 0.5)
    })
    .unwrap();
    let (tree, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
    let fixed = raster_grid_bytes(256, 256, 8);
    let needed = fixed + BUILD_BYTES_PER_NODE * tree.node_count();
    assert!(needed - fixed <= 4 * tree.memory_bytes());
    let fits = BuildOptions {
        max_bytes: Some(needed),
        ..BuildOptions::default()
    };
    assert!(QuadTree::from_texels(&g, &fits).is_ok());
    let half = BuildOptions {
        max_bytes: Some(fixed + (needed - fixed) / 2),
        ..BuildOptions::default()
    };
    let e = QuadTree::from_texels(&g, &half).unwrap_err();
    assert!(matches!(e, Error::MemoryBudget { .. }), "{e}");
    assert!(e.to_string().contains("stopped after"), "{e}");
}

#[test]
fn refuses_bad_input() {
    assert!(matches!(
        TexelGrid::new(0, 4, vec![]),
        Err(Error::BadDimensions { .. })
    ));
    assert!(matches!(
        TexelGrid::new(2, 2, vec![Unorm16Rgba::default(); 3]),
        Err(Error::TexelCount { .. })
    ));
    let g = TexelGrid::from_fn(2, 2, |_, _| Rgba::TRANSPARENT).unwrap();
    let bad = BuildOptions {
        tolerance: f64::NAN,
        ..BuildOptions::default()
    };
    assert!(matches!(
        QuadTree::from_texels(&g, &bad),
        Err(Error::BadTolerance(_))
    ));
    let deep = BuildOptions {
        max_level: Some(40),
        ..BuildOptions::default()
    };
    assert!(matches!(
        QuadTree::from_texels(&g, &deep),
        Err(Error::DepthTooLarge { .. })
    ));
    let few = BuildOptions {
        max_nodes: 3,
        ..BuildOptions::default()
    };
    let g = TexelGrid::from_fn(4, 4, |c, _| Rgba::opaque(c as f32 / 4.0, 0.0, 0.0)).unwrap();
    assert!(matches!(
        QuadTree::from_texels(&g, &few),
        Err(Error::TooManyNodes { .. })
    ));
}

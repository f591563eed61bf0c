#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The fast fragment integral against slow, obvious references, on random
//! incomplete trees and random fragments (arbtest).

mod common;

use arbtest::arbitrary::{Result as ArbResult, Unstructured};
use common::{PALETTE, blocky_grid, blocky_grid_any_aspect};
use quadtex_core::baseline::SummedAreaTable;
use quadtex_core::reference::{paper_traversal, texel_sum, truncated_tree_sum};
use quadtex_core::variant::f_init;
use quadtex_core::{Aspect, BuildOptions, Fragment, QuadTree, Rgba, TexelGrid, WeightedColour};

/// A random grid of any size (non-power-of-two included).
fn any_grid(u: &mut Unstructured<'_>) -> ArbResult<TexelGrid> {
    let w = u.int_in_range(1..=19u32)?;
    let h = u.int_in_range(1..=19u32)?;
    let mut colours = Vec::new();
    for _ in 0..w * h {
        colours.push(PALETTE[u.choose_index(PALETTE.len())?]);
    }
    Ok(TexelGrid::from_fn(w, h, |c, r| colours[(r * w + c) as usize]).unwrap())
}

fn coord(u: &mut Unstructured<'_>) -> ArbResult<f64> {
    Ok(match u.int_in_range(0..=3u8)? {
        // Dyadic: multiples of 1/64, across and beyond the unit square.
        0 => f64::from(u.int_in_range(-32..=96i32)?) / 64.0,
        1 => f64::from(u.int_in_range(0..=1_000_000u32)?) / 1_000_000.0,
        2 => f64::from(u.int_in_range(-2_000_000..=3_000_000i32)?) / 1_000_000.0,
        _ => *u.choose(&[0.0, 1.0, -0.0, 0.5, 0.999_999_999, 1.0 + 1e-12])?,
    })
}

fn fragment(u: &mut Unstructured<'_>) -> ArbResult<Fragment> {
    let (a, b) = (coord(u)?, coord(u)?);
    let (c, d) = (coord(u)?, coord(u)?);
    let (x0, x1) = (a.min(b), a.max(b));
    let (z0, z1) = (c.min(d), c.max(d));
    Ok(match u.int_in_range(0..=5u8)? {
        0 => Fragment::new(x0, z0, x0, z1).unwrap(), // zero width
        1 => Fragment::new(x0, z0, x0 + 1e-9, z0 + 3e-9).unwrap(), // tiny
        _ => Fragment::new(x0, z0, x1, z1).unwrap(),
    })
}

/// Tolerance between two ways of summing the tree: float rounding plus one
/// 16-bit step over the fragment's area. Each inner colour is its region's
/// exact mean rounded once (half a step, see `QuadTree::weighted_colour`), and
/// two different truncations can round in opposite directions.
fn storage_tol(f: &Fragment) -> f64 {
    1e-12 + f.clip_to_unit().map_or(0.0, |c| c.area()) / 65535.0
}

fn close(a: WeightedColour, b: WeightedColour, tol: f64) -> bool {
    a.0.iter().zip(&b.0).all(|(x, y)| (x - y).abs() <= tol)
}

#[test]
fn fast_traversal_equals_truncated_tree_sum_and_paper_recursion() {
    arbtest::arbtest(|u| {
        let grid = blocky_grid_any_aspect(u, 5)?;
        let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
        for _ in 0..20 {
            let f = fragment(u)?;
            let k = u.int_in_range(0..=tree.depth() + 2)?;
            let fast = tree.weighted_colour(&f, k);
            let slow = truncated_tree_sum(&tree, &f, k);
            let paper = paper_traversal(&tree, &f, k, f_init);
            assert!(
                close(fast, slow, storage_tol(&f)),
                "{f:?} k={k}: fast {fast:?} vs truncated sum {slow:?}"
            );
            // At ties (A == lo) the paper keeps variant 4 where the fast path
            // sees 3 and takes the square whole: equal up to storage rounding.
            assert!(
                close(fast, paper, storage_tol(&f)),
                "{f:?} k={k}: fast {fast:?} vs paper {paper:?}"
            );
        }
        Ok(())
    })
    .budget_ms(3000);
}

#[test]
fn full_depth_equals_sum_over_texels_for_power_of_two_grids() {
    arbtest::arbtest(|u| {
        let grid = blocky_grid_any_aspect(u, 5)?;
        let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
        let sat = SummedAreaTable::new(&grid);
        for _ in 0..20 {
            let f = fragment(u)?;
            let texels = texel_sum(&grid, &f);
            let fast = tree.weighted_colour(&f, u8::MAX);
            assert!(
                close(fast, texels, storage_tol(&f)),
                "{f:?}: tree {fast:?} vs texels {texels:?}"
            );
            let s = sat.weighted_colour(&f);
            assert!(
                close(s, texels, 1e-9),
                "{f:?}: SAT {s:?} vs texels {texels:?}"
            );
        }
        Ok(())
    })
    .budget_ms(2000);
}

#[test]
fn any_size_image_keeps_its_texels_and_integrates_to_them() {
    // Any size packs its own texels as the finest cells (the texture spans
    // `w × h` cells of its natural depth, the rest of the square is pad), so
    // the full-depth integral over any fragment is the texel sum, and a
    // truncated one agrees with the slow references.
    arbtest::arbtest(|u| {
        let grid = any_grid(u)?;
        let (tree, report) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
        assert!(!report.resampled);
        let (w, h) = (grid.width(), grid.height());
        assert_eq!(
            tree.aspect(),
            Aspect::from_extent(w, h, grid.natural_depth()).unwrap()
        );
        // A tree that stops above its texels (a uniform image) is shallower.
        if tree.depth() == grid.natural_depth() {
            assert_eq!(tree.finest_grid(), [u64::from(w), u64::from(h)]);
            assert_eq!(tree.raster_size(tree.depth()), [w, h]);
        }
        let whole = Fragment::new(0.0, 0.0, 1.0, 1.0).unwrap();
        assert!(close(
            tree.weighted_colour(&whole, 0),
            texel_sum(&grid, &whole),
            0.5 / 65535.0 + 1e-12
        ));
        for _ in 0..10 {
            let f = fragment(u)?;
            let texels = texel_sum(&grid, &f);
            let fast = tree.weighted_colour(&f, u8::MAX);
            assert!(
                close(fast, texels, storage_tol(&f)),
                "{w}x{h} {f:?}: tree {fast:?} vs texels {texels:?}"
            );
            let k = u.int_in_range(0..=tree.depth() + 1)?;
            let fast = tree.weighted_colour(&f, k);
            let slow = truncated_tree_sum(&tree, &f, k);
            let paper = paper_traversal(&tree, &f, k, f_init);
            assert!(
                close(fast, slow, storage_tol(&f)),
                "{w}x{h} {f:?} k={k}: fast {fast:?} vs truncated sum {slow:?}"
            );
            assert!(
                close(fast, paper, storage_tol(&f)),
                "{w}x{h} {f:?} k={k}: fast {fast:?} vs paper {paper:?}"
            );
        }
        // A texel's rectangle integrates to that texel.
        let (c, r) = (u.int_in_range(0..=w - 1)?, u.int_in_range(0..=h - 1)?);
        let (fw, fh) = (f64::from(w), f64::from(h));
        let texel = Fragment::new(
            f64::from(c) / fw,
            1.0 - f64::from(r + 1) / fh,
            f64::from(c + 1) / fw,
            1.0 - f64::from(r) / fh,
        )
        .unwrap();
        let want = grid.texel(c, r).0.map(|v| f64::from(v) / 65535.0);
        let got = tree.weighted_colour(&texel, u8::MAX).0.map(|v| v * fw * fh);
        for (g, t) in got.iter().zip(want) {
            assert!(
                (g - t).abs() <= 1e-9,
                "{w}x{h} texel ({c}, {r}): {got:?} vs {want:?}"
            );
        }
        Ok(())
    })
    .budget_ms(2000);
}

#[test]
fn additive_when_split_in_two() {
    arbtest::arbtest(|u| {
        let grid = blocky_grid(u, 5)?;
        let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
        let f = fragment(u)?;
        let k = u.int_in_range(0..=tree.depth())?;
        let t = f64::from(u.int_in_range(0..=1000u32)?) / 1000.0;
        let whole = tree.weighted_colour(&f, k);
        let (a, b) = if u.arbitrary()? {
            let m = (f.x0() + t * f.width()).min(f.x1());
            (
                Fragment::new(f.x0(), f.z0(), m, f.z1()).unwrap(),
                Fragment::new(m, f.z0(), f.x1(), f.z1()).unwrap(),
            )
        } else {
            let m = (f.z0() + t * f.height()).min(f.z1());
            (
                Fragment::new(f.x0(), f.z0(), f.x1(), m).unwrap(),
                Fragment::new(f.x0(), m, f.x1(), f.z1()).unwrap(),
            )
        };
        let parts = tree.weighted_colour(&a, k) + tree.weighted_colour(&b, k);
        assert!(
            close(whole, parts, storage_tol(&f)),
            "{f:?} split at {t}: {whole:?} vs {parts:?}"
        );
        Ok(())
    })
    .budget_ms(1000);
}

#[test]
fn constant_texture_gives_colour_times_clipped_area() {
    let c = Rgba::new(0.2, 0.3, 0.1, 0.5);
    let grid = TexelGrid::from_fn(32, 32, |_, _| c).unwrap();
    let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
    let stored = tree.mean_colour();
    arbtest::arbtest(|u| {
        let f = fragment(u)?;
        let area = f.clip_to_unit().map_or(0.0, |g| g.area());
        let got = tree.weighted_colour(&f, 5);
        assert!(
            close(got, WeightedColour(stored.map(|c| c * area)), 1e-15),
            "{f:?}"
        );
        Ok(())
    })
    .budget_ms(300);
}

#[test]
fn bounded_by_extreme_texels_times_area() {
    arbtest::arbtest(|u| {
        let grid = blocky_grid(u, 5)?;
        let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
        let (mut lo, mut hi) = ([f64::MAX; 4], [f64::MIN; 4]);
        for t in grid.texels() {
            for ch in 0..4 {
                lo[ch] = lo[ch].min(f64::from(t.0[ch]) / 65535.0);
                hi[ch] = hi[ch].max(f64::from(t.0[ch]) / 65535.0);
            }
        }
        let f = fragment(u)?;
        let area = f.clip_to_unit().map_or(0.0, |g| g.area());
        let k = u.int_in_range(0..=tree.depth())?;
        let got = tree.weighted_colour(&f, k);
        for ch in 0..4 {
            assert!(
                got.0[ch] >= lo[ch] * area - storage_tol(&f)
                    && got.0[ch] <= hi[ch] * area + storage_tol(&f),
                "{f:?} ch {ch}: {got:?}"
            );
        }
        Ok(())
    })
    .budget_ms(1000);
}

#[test]
fn uniform_colour_is_exact_where_it_answers() {
    arbtest::arbtest(|u| {
        // Square and non-square grids (the tree's pad must never answer),
        // uniform over blocks so the search across squares is exercised.
        let grid = if u.arbitrary()? {
            blocky_grid(u, 5)?
        } else {
            blocky_grid_any_aspect(u, 5)?
        };
        let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
        let f = fragment(u)?;
        if let Some(c) = tree.uniform_colour(&f) {
            let area = f.clip_to_unit().map_or(0.0, |c| c.area());
            let exact = texel_sum(&grid, &f);
            assert!(
                close(
                    WeightedColour::from_colour(c, area),
                    exact,
                    1e-7 * area.max(1e-300)
                ),
                "{f:?}"
            );
        }
        Ok(())
    })
    .budget_ms(500);
    // A constant texture always answers; a checkerboard answers inside one square only.
    let grid = TexelGrid::from_fn(4, 4, |c, r| {
        if (c + r) % 2 == 0 {
            PALETTE[0]
        } else {
            PALETTE[1]
        }
    })
    .unwrap();
    let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
    assert!(
        tree.uniform_colour(&Fragment::new(0.3, 0.3, 0.45, 0.45).unwrap())
            .is_some()
    );
    assert!(
        tree.uniform_colour(&Fragment::new(0.2, 0.3, 0.3, 0.45).unwrap())
            .is_none()
    );
    assert!(
        tree.uniform_colour(&Fragment::new(2.0, 2.0, 3.0, 3.0).unwrap())
            .is_none()
    );
    // One odd texel at the origin (column 0, the last row: rows run down,
    // z up): squares of one colour around it answer
    // across their borders, unless the fragment reaches the odd texel or
    // needs more squares than the search looks at.
    let one_odd = |n: u32| {
        let grid =
            TexelGrid::from_fn(n, n, |c, r| PALETTE[usize::from(c == 0 && r == n - 1)]).unwrap();
        QuadTree::from_texels(&grid, &BuildOptions::default())
            .unwrap()
            .0
    };
    let tree = one_odd(4);
    let a = Some(PALETTE[0]);
    let answer = |tree: &QuadTree, f: [f64; 4]| {
        tree.uniform_colour(&Fragment::new(f[0], f[1], f[2], f[3]).unwrap())
    };
    // Across the two uniform quadrants of the far half.
    assert_eq!(answer(&tree, [0.3, 0.6, 0.7, 0.9]), a);
    // Across all four quadrants, the split one only on its odd-free texels.
    assert_eq!(answer(&tree, [0.3, 0.3, 0.7, 0.7]), a);
    // Onto the odd texel.
    assert_eq!(answer(&tree, [0.1, 0.1, 0.6, 0.3]), None);
    // Ending exactly where the odd texel begins (half-open): uniform.
    assert_eq!(answer(&tree, [0.25, 0.0, 0.6, 0.2]), a);
    // Off the odd texel of an 8x8 grid, down three levels beside it.
    assert_eq!(answer(&one_odd(8), [0.13, 0.13, 0.99, 0.99]), a);
    assert_eq!(answer(&one_odd(8), [0.12, 0.12, 0.99, 0.99]), None);
}

#[test]
fn rasterising_a_tree_gives_back_its_texels() {
    arbtest::arbtest(|u| {
        let grid = blocky_grid(u, 5)?;
        let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
        // At the grid's own resolution (the tree may stop above it) and finer.
        let level = grid.natural_depth() + u.int_in_range(0..=2)?;
        let back = tree.rasterise(level).unwrap();
        let scale = back.width() / grid.width();
        for row in 0..back.height() {
            for col in 0..back.width() {
                assert_eq!(back.texel(col, row), grid.texel(col / scale, row / scale));
            }
        }
        Ok(())
    })
    .budget_ms(300);
    let (tree, _) = QuadTree::from_texels(
        &TexelGrid::from_fn(2, 2, |_, _| PALETTE[0]).unwrap(),
        &BuildOptions::default(),
    )
    .unwrap();
    assert!(tree.rasterise(15).is_err());
}

/// The erratum: eq. (2) as printed swaps variants 2 and 3.
#[test]
fn printed_f_init_is_wrong_and_the_corrected_one_is_right() {
    fn printed(a: f64, b: f64) -> u8 {
        match f_init(a, b) {
            2 => 3,
            3 => 2,
            v => v,
        }
    }
    // A 4×4 checkerboard of red and blue and the fragment [0.25,0.5)×[0.25,0.5):
    // one texel, lying *inside* the root square (variant 2 on both axes).
    let red = Rgba::opaque(1.0, 0.0, 0.0);
    let blue = Rgba::opaque(0.0, 0.0, 1.0);
    let grid = TexelGrid::from_fn(4, 4, |c, r| if (c + r) % 2 == 0 { red } else { blue }).unwrap();
    let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
    let f = Fragment::new(0.25, 0.25, 0.5, 0.5).unwrap();
    let truth = texel_sum(&grid, &f);
    // Texel (col 1, row 2) is red: (1+2) % 2 == 1 → blue. Check the truth itself.
    assert!(close(
        truth,
        WeightedColour::from_unorm16(blue.to_unorm16(), 1.0 / 16.0),
        1e-12
    ));
    let corrected = paper_traversal(&tree, &f, 2, f_init);
    let as_printed = paper_traversal(&tree, &f, 2, printed);
    assert!(
        close(corrected, truth, 1e-12),
        "corrected {corrected:?} vs {truth:?}"
    );
    assert!(
        !close(as_printed, truth, 1e-3),
        "printed F_init should be wrong here, got {as_printed:?}"
    );
    // As printed, "square inside fragment" makes every child count whole: the whole texture.
    let whole = texel_sum(&grid, &Fragment::new(0.0, 0.0, 1.0, 1.0).unwrap());
    assert!(close(as_printed, whole, 1.0 / 65535.0));
}

#[test]
fn level_of_detail_below_depth_uses_prefiltered_colours() {
    let red = Rgba::opaque(1.0, 0.0, 0.0);
    let blue = Rgba::opaque(0.0, 0.0, 1.0);
    let grid = TexelGrid::from_fn(8, 8, |c, r| if (c + r) % 2 == 0 { red } else { blue }).unwrap();
    let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
    // One texel, but at level 0 the root's average (purple) is all we see.
    let f = Fragment::new(0.0, 0.0, 0.125, 0.125).unwrap();
    let got = tree.weighted_colour(&f, 0).mean_over(f.area());
    assert!(
        (got.r - 0.5).abs() < 1e-4 && (got.b - 0.5).abs() < 1e-4,
        "{got:?}"
    );
    let exact = tree.weighted_colour(&f, 3).mean_over(f.area());
    assert!(exact.r == 0.0 || exact.r == 1.0, "{exact:?}");
}

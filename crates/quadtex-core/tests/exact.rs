#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The exact pixel integral against slow, obvious references: the pixel
//! square cut by the preimages of every finest cell's edges (lines, under
//! a projective map) for the box; dense weighted sampling for the tent and
//! Mitchell filters; the reported error bound against the exact value.

mod common;

use arbtest::arbitrary::{Result as ArbResult, Unstructured};
use common::{PALETTE, blocky_grid_any_aspect, coefficients};
use quadtex_core::{
    BuildOptions, ConvexPolygon, FilterOptions, FilterStats, Footprint, PixelFilter, Projection,
    QuadTree, Rgba, Texture, Wrap, WrapMode,
};

/// A blocky tree, square or a strip (part of the tree's square); one time
/// in four an HDR one (half floats: colours up to 1000 and below 0).
fn blocky_tree(u: &mut Unstructured<'_>) -> ArbResult<QuadTree> {
    let grid = blocky_grid_any_aspect(u, 4)?;
    let grid = if u.ratio(1, 4)? {
        let gain = *u.choose(&[1000.0f32, -3.0, 7.5])?;
        let texels: Vec<[f32; 4]> = grid
            .texels()
            .iter()
            .map(|t| {
                let [r, g, b, a] = t.to_rgba().to_array();
                [r * gain, g, b * gain * 0.5, a]
            })
            .collect();
        quadtex_core::TexelGrid::from_linear_f32(grid.width(), grid.height(), &texels).unwrap()
    } else {
        grid
    };
    Ok(QuadTree::from_texels(&grid, &BuildOptions::default())
        .unwrap()
        .0)
}

fn wrap(u: &mut Unstructured<'_>) -> ArbResult<Wrap> {
    let modes = [
        WrapMode::Repeat,
        WrapMode::Clamp,
        WrapMode::Mirror,
        WrapMode::Border,
    ];
    Ok(Wrap::new(
        *u.choose(&modes)?,
        *u.choose(&modes)?,
        PALETTE[u.choose_index(PALETTE.len())?],
    )
    .unwrap())
}

fn unit(u: &mut Unstructured<'_>, lo: f64, hi: f64) -> ArbResult<f64> {
    Ok(lo + (hi - lo) * f64::from(u.int_in_range(0..=10_000u32)?) / 10_000.0)
}

/// A convex footprint: a grazing trapezoid (strong perspective), rotated,
/// anywhere in `[-2, 3]²`.
fn footprint(u: &mut Unstructured<'_>) -> ArbResult<Footprint> {
    let (cx, cz) = (unit(u, -2.0, 3.0)?, unit(u, -2.0, 3.0)?);
    let near = unit(u, 0.02, 0.6)?;
    let far = near * unit(u, 0.5, 8.0)?;
    let depth = unit(u, 0.02, 1.5)?;
    let angle = unit(u, 0.0, std::f64::consts::TAU)?;
    let (s, c) = angle.sin_cos();
    let rot = |p: [f64; 2]| [cx + c * p[0] - s * p[1], cz + s * p[0] + c * p[1]];
    Ok(Footprint::from_corners([
        rot([-near / 2.0, 0.0]),
        rot([near / 2.0, 0.0]),
        rot([far / 2.0, depth]),
        rot([-far / 2.0, depth]),
    ])
    .unwrap())
}

/// The box-filtered pixel, slowly: every finest cell under the footprint's
/// bounding box, its preimage in the pixel square cut out by four
/// half-planes (`x ≥ c ⇔ (a−c·g)u + (b−c·h)v + (x₀−c) ≥ 0` where `w > 0`),
/// times the colour `Texture::nearest` gives at the cell's centre.
fn brute_force_box(texture: &Texture, fp: &Footprint) -> Rgba {
    let [a, b, c, d, e, f, g, h] = coefficients(fp.corners());
    let [cx, cz] = texture.tree().finest_cell_size();
    let (lo, hi) = fp.bounds();
    let (i0, i1) = ((lo[0] / cx).floor() as i64, (hi[0] / cx).ceil() as i64);
    let (j0, j1) = ((lo[1] / cz).floor() as i64, (hi[1] / cz).ceil() as i64);
    let square = ConvexPolygon::rect(0.0, 0.0, 1.0, 1.0);
    let mut acc = [0f64; 4];
    for j in j0..j1 {
        for i in i0..i1 {
            let (x0, x1) = (i as f64 * cx, (i + 1) as f64 * cx);
            let (z0, z1) = (j as f64 * cz, (j + 1) as f64 * cz);
            let piece = square
                .clip(a - x0 * g, b - x0 * h, c - x0)
                .clip(x1 * g - a, x1 * h - b, x1 - c)
                .clip(d - z0 * g, e - z0 * h, f - z0)
                .clip(z1 * g - d, z1 * h - e, z1 - f);
            let area = piece.area();
            if area > 0.0 {
                let colour = texture.nearest([(x0 + x1) / 2.0, (z0 + z1) / 2.0]);
                for (s, v) in acc.iter_mut().zip(colour.to_array()) {
                    *s += area * f64::from(v);
                }
            }
        }
    }
    Rgba::new(acc[0] as f32, acc[1] as f32, acc[2] as f32, acc[3] as f32)
}

fn max_diff(a: Rgba, b: Rgba) -> f64 {
    (a - b)
        .to_array()
        .iter()
        .fold(0f64, |m, v| m.max(f64::from(v.abs())))
}

/// At full depth the box-filtered pixel is the brute-force sum over cells
/// to float precision, for every wrap; the default level of detail stays
/// within the bound it reports.
#[test]
fn box_pixels_match_the_cell_by_cell_sum_and_the_bound_holds() {
    arbtest::arbtest(|u| {
        let texture = Texture::new(blocky_tree(u)?, wrap(u)?);
        let fp = footprint(u)?;
        if Projection::for_pixel(&fp, [0.0, 0.0]).is_none() {
            return Ok(());
        }
        let truth = brute_force_box(&texture, &fp);
        let exact = texture.filter(&fp, &FilterOptions::default().with_level(30));
        // f32 results: the rounding tolerance grows with an HDR tree's range.
        let tol = 2e-6 * texture.bound_scale();
        assert!(
            max_diff(exact, truth) < tol,
            "{exact:?} vs {truth:?} for {fp:?} under {:?}",
            texture.wrap()
        );
        let mut stats = FilterStats::default();
        let fast = texture.filter_counted(&fp, &FilterOptions::default(), &mut stats);
        let err = max_diff(fast, truth);
        // The statistics' bound is relative to the texture's contrast.
        let bound = stats.max_error_bound * texture.bound_scale();
        assert!(err <= bound + tol, "{err} above the reported bound {bound}");
        Ok(())
    })
    .budget_ms(4_000);
}

/// A trapezoid `near` wide at one end and `far` at the other, `depth`
/// deep, turned by `angle` about `centre`: a perspective pixel's footprint.
fn perspective_quad(centre: [f64; 2], near: f64, far: f64, depth: f64, angle: f64) -> Footprint {
    let (s, c) = angle.sin_cos();
    let rot = |p: [f64; 2]| {
        [
            centre[0] + c * p[0] - s * p[1],
            centre[1] + s * p[0] + c * p[1],
        ]
    };
    Footprint::from_corners([
        rot([-near / 2.0, -depth / 2.0]),
        rot([near / 2.0, -depth / 2.0]),
        rot([far / 2.0, depth / 2.0]),
        rot([-far / 2.0, depth / 2.0]),
    ])
    .unwrap()
}

/// A photograph-like raster of `2^k` texels a side (`k` drawn from
/// `log2_sides`): noisy 4×4 texel blocks, about a third of them uniform
/// (kept as stored terminal squares), under a random wrap; and its side.
fn noisy_raster(
    u: &mut Unstructured<'_>,
    log2_sides: std::ops::RangeInclusive<u32>,
) -> ArbResult<(Texture, u32)> {
    let side = 1u32 << u.int_in_range(log2_sides)?;
    let blocks = side / 4;
    let mut uniform = Vec::with_capacity((blocks * blocks) as usize);
    for _ in 0..blocks * blocks {
        uniform.push(u.ratio(1, 3)?.then_some(*u.choose(&[0u8, 128, 255])?));
    }
    let mut bytes = Vec::with_capacity((side * side) as usize);
    for k in 0..side * side {
        let (c, r) = (k % side, k / side);
        let v = match uniform[((r / 4) * blocks + c / 4) as usize] {
            Some(v) => v,
            None => *u.choose(&[0u8, 40, 128, 200, 255])?,
        };
        bytes.push([v, 255 - v, v / 2, 255]);
    }
    let grid = quadtex_core::TexelGrid::from_srgb8(side, side, bytes).unwrap();
    let tree = QuadTree::from_texels(&grid, &BuildOptions::default())
        .unwrap()
        .0;
    Ok((Texture::new(tree, wrap(u)?), side))
}

/// A footprint of a few texels over a photograph-like raster (noisy 4×4
/// texel blocks, some uniform ones kept as stored terminal squares), inside
/// one aligned square of 16×16 texels (four blocks a side), is integrated
/// texel by texel, exactly, at the default level of detail too: the result
/// is the cell-by-cell sum and the reported bound is zero. (Walked square
/// by square instead, it stops once its bound is below the default target,
/// off the sum.)
#[test]
fn small_footprints_over_rasters_are_exact_at_the_default_level() {
    arbtest::arbtest(|u| {
        let (texture, side) = noisy_raster(u, 4..=6)?;
        let blocks = side / 4;
        let wrap = texture.wrap();
        // Which aligned 16×16 square, in which tile (any, on a repeated or
        // mirrored axis; the texture's own beyond a clamp or border edge).
        let texel = 1.0 / f64::from(side);
        let mut origin = [0.0; 2];
        for (axis, mode) in [wrap.x(), wrap.z()].into_iter().enumerate() {
            let tile = if matches!(mode, WrapMode::Repeat | WrapMode::Mirror) {
                f64::from(u.int_in_range(-2..=2i32)?)
            } else {
                0.0
            };
            let window = f64::from(u.int_in_range(0..=blocks / 4 - 1)?);
            origin[axis] = tile + window * 16.0 * texel;
        }
        // A perspective quad at most 6 texels across, centred in the
        // middle 4×4 texels of the square.
        let cx = origin[0] + texel * unit(u, 6.0, 10.0)?;
        let cz = origin[1] + texel * unit(u, 6.0, 10.0)?;
        let near = texel * unit(u, 0.2, 3.0)?;
        let far = near * unit(u, 0.3, 2.0)?;
        let depth = texel * unit(u, 0.2, 3.0)?;
        let angle = unit(u, 0.0, std::f64::consts::TAU)?;
        let fp = perspective_quad([cx, cz], near, far, depth, angle);
        if Projection::for_pixel(&fp, [0.0, 0.0]).is_none() {
            return Ok(());
        }
        let truth = brute_force_box(&texture, &fp);
        let mut stats = FilterStats::default();
        let fast = texture.filter_counted(&fp, &FilterOptions::default(), &mut stats);
        assert!(
            max_diff(fast, truth) < 2e-6,
            "{fast:?} vs {truth:?} for {fp:?} under {wrap:?}"
        );
        assert_eq!(stats.max_error_bound, 0.0, "{fp:?} under {wrap:?}");
        Ok(())
    })
    .budget_ms(3_000);
}

/// A footprint whose box spans at most 16 cells of the finest grid and lies
/// in one tile is integrated cell by cell before any walk, exactly, wherever
/// it lies: across the tree's middle lines (where no square below the root
/// holds it), beside a tile's edge, under every wrap, over noisy and
/// uniform blocks. The result is the cell-by-cell sum and the bound zero;
/// a box that crosses a seam is walked and stays within its bound.
#[test]
fn small_footprints_anywhere_over_rasters_are_exact() {
    arbtest::arbtest(|u| {
        let (texture, side) = noisy_raster(u, 3..=6)?;
        let wrap = texture.wrap();
        let texel = 1.0 / f64::from(side);
        // The centre: on the tree's middle line, beside a tile's edge, or
        // anywhere, in any of five tiles on a repeated or mirrored axis.
        let mut centre = [0.0; 2];
        for (axis, mode) in [wrap.x(), wrap.z()].into_iter().enumerate() {
            let tile = if matches!(mode, WrapMode::Repeat | WrapMode::Mirror) {
                f64::from(u.int_in_range(-2..=2i32)?)
            } else {
                0.0
            };
            let at = match u.int_in_range(0..=2u8)? {
                0 => 0.5 + texel * unit(u, -1.5, 1.5)?,
                1 => {
                    let inside = 2.0 * texel * unit(u, 0.8, 1.2)?;
                    *u.choose(&[inside, 1.0 - inside])?
                }
                _ => unit(u, 0.05, 0.95)?,
            };
            centre[axis] = tile + at;
        }
        // A perspective quad at most 3 texels across.
        let near = texel * unit(u, 0.2, 2.0)?;
        let far = near * unit(u, 0.3, 1.5)?;
        let depth = texel * unit(u, 0.2, 2.0)?;
        let angle = unit(u, 0.0, std::f64::consts::TAU)?;
        let fp = perspective_quad(centre, near, far, depth, angle);
        if Projection::for_pixel(&fp, [0.0, 0.0]).is_none() {
            return Ok(());
        }
        let truth = brute_force_box(&texture, &fp);
        let mut stats = FilterStats::default();
        let fast = texture.filter_counted(&fp, &FilterOptions::default(), &mut stats);
        let (lo, hi) = fp.bounds();
        let one_tile = (0..2).all(|a| {
            let mode = [wrap.x(), wrap.z()][a];
            let tiled = matches!(mode, WrapMode::Repeat | WrapMode::Mirror);
            let (t0, t1) = (lo[a].floor(), hi[a].floor());
            (tiled || (lo[a] >= 0.0 && hi[a] <= 1.0)) && (t0 == t1 || hi[a] == t1)
        });
        if one_tile {
            assert!(
                max_diff(fast, truth) < 2e-6,
                "{fast:?} vs {truth:?} for {fp:?} under {wrap:?}"
            );
            assert_eq!(stats.max_error_bound, 0.0, "{fp:?} under {wrap:?}");
        } else {
            assert!(
                max_diff(fast, truth) <= stats.max_error_bound + 2e-6,
                "{fast:?} vs {truth:?} beyond the bound {} for {fp:?} under {wrap:?}",
                stats.max_error_bound
            );
        }
        Ok(())
    })
    .budget_ms(3_000);
}

/// `filter`'s support around `centre`, unless it reaches the horizon
/// (a vertex's `w` under a millionth of the centre's).
fn support_in_front(
    filter: PixelFilter,
    projection: &Projection,
    centre: [f64; 2],
) -> Option<ConvexPolygon> {
    let support = filter.support(centre);
    let in_front =
        (support.vertices().iter()).all(|&s| projection.w(s) > 1e-6 * projection.w(centre));
    in_front.then_some(support)
}

/// The tent and Mitchell integrals over a projected support match dense
/// sampling of the support weighted by the filter; a fully visible support
/// weighs exactly 1.
#[test]
fn tent_and_mitchell_match_weighted_sampling() {
    arbtest::arbtest(|u| {
        let texture = Texture::new(blocky_tree(u)?, wrap(u)?);
        let fp = footprint(u)?;
        if Projection::for_pixel(&fp, [0.0, 0.0]).is_none() {
            return Ok(());
        }
        // The footprint is pixel (10, 20); the filters reach its neighbours.
        let Some(projection) = Projection::for_pixel(&fp, [10.0, 20.0]) else {
            return Ok(());
        };
        let centre = [10.5, 20.5];
        for filter in [PixelFilter::Tent, PixelFilter::Mitchell] {
            let Some(support) = support_in_front(filter, &projection, centre) else {
                continue; // the support reaches the horizon: not this test
            };
            let options = FilterOptions::default().with_level(30);
            let r = texture.integrate_region(
                &projection,
                &support,
                filter,
                centre,
                &options,
                &mut FilterStats::default(),
            );
            assert!(
                (r.weight - 1.0).abs() < 1e-9,
                "{filter:?} weight {}",
                r.weight
            );
            let side = 2.0 * filter.radius();
            let sample = |n: u32| {
                let (mut acc, mut wsum) = ([0f64; 4], 0.0);
                for j in 0..n {
                    for i in 0..n {
                        let dx = -filter.radius() + side * (f64::from(i) + 0.5) / f64::from(n);
                        let dy = -filter.radius() + side * (f64::from(j) + 0.5) / f64::from(n);
                        let w = filter.weight(dx, dy);
                        let t = projection
                            .texture_point([centre[0] + dx, centre[1] + dy])
                            .unwrap();
                        for (a, v) in acc.iter_mut().zip(texture.nearest(t).to_array()) {
                            *a += w * f64::from(v);
                        }
                        wsum += w;
                    }
                }
                Rgba::new(
                    (acc[0] / wsum) as f32,
                    (acc[1] / wsum) as f32,
                    (acc[2] / wsum) as f32,
                    (acc[3] / wsum) as f32,
                )
            };
            let exact = r.mean().unwrap();
            // Relative to the contrast in view: an HDR texture against a
            // border colour spans more than [0, 1].
            let contrast = |sampled: Rgba| {
                exact
                    .to_array()
                    .iter()
                    .chain(&sampled.to_array())
                    .fold(texture.bound_scale(), |m, v| m.max(f64::from(v.abs())))
            };
            // Midpoint sampling on a 300² grid: edges cut ~300 samples each,
            // within 2 % of the contrast but for rare arrangements of thin,
            // bright HDR squares under Mitchell's lobes (seed
            // 0x0944216800010000: 4.6 %, converging to the exact value,
            // 1e-6 apart, at 3000²). Those get a second, 5× finer sampling
            // held to 1 %; a wrong integral fails both.
            let coarse = sample(300);
            if max_diff(exact, coarse) >= 0.02 * contrast(coarse) {
                let fine = sample(1500);
                assert!(
                    max_diff(exact, fine) < 0.01 * contrast(fine),
                    "{filter:?}: {exact:?} vs sampled {coarse:?} (300²), {fine:?} (1500²)"
                );
            }
        }
        Ok(())
    })
    .budget_ms(4_000);
}

/// A tent's or Mitchell's whole support under the default level of
/// detail keeps the pixel's colour within the bound asked for, relative
/// to the support's weight (1), as the box's pixel does: the walk aims at
/// `ε` times the region's weight, not at `ε` times its area at the
/// filter's peak (4 and 12.6 for a whole support, which left pixels up to
/// that many times the target); the reported bound holds against the
/// full-depth integral.
#[test]
fn tent_and_mitchell_supports_keep_the_bound_asked_for() {
    arbtest::arbtest(|u| {
        let texture = Texture::new(blocky_tree(u)?, wrap(u)?);
        let fp = footprint(u)?;
        let Some(projection) = Projection::for_pixel(&fp, [10.0, 20.0]) else {
            return Ok(());
        };
        let centre = [10.5, 20.5];
        let epsilon = 1.0 / 512.0;
        for filter in [PixelFilter::Tent, PixelFilter::Mitchell] {
            let Some(support) = support_in_front(filter, &projection, centre) else {
                continue; // the support reaches the horizon: not this test
            };
            let integral = |options: &FilterOptions, stats: &mut FilterStats| {
                texture.integrate_region(&projection, &support, filter, centre, options, stats)
            };
            let mut stats = FilterStats::default();
            let fast = integral(&FilterOptions::default(), &mut stats);
            let relative = fast.error_bound / fast.weight.abs() / texture.bound_scale();
            // No budget by default: only the hard cap stops short.
            assert!(
                relative <= epsilon * (1.0 + 1e-9) || stats.over_target > 0,
                "{filter:?}: bound {relative:e} above the target {epsilon:e}"
            );
            let exact = integral(
                &FilterOptions::default().with_level(30),
                &mut FilterStats::default(),
            );
            let (fast, exact) = (fast.mean().unwrap(), exact.mean().unwrap());
            let tol = 2e-6 * texture.bound_scale();
            assert!(
                max_diff(fast, exact) <= relative * texture.bound_scale() + tol,
                "{filter:?}: {fast:?} vs {exact:?}, bound {relative:e}"
            );
        }
        Ok(())
    })
    .budget_ms(3_000);
}

/// The bound is relative to the contrast the texture can show, the border
/// colour included: a uniform HDR tree (red 1000) beside a grey border has
/// a contrast of ~1000, not the tree's own range (0, so 1). This tent
/// support reaches near the horizon, whose sliver is taken at the tree's
/// mean (red 1000) while it shows the border: scaled by the tree's range
/// alone, its bound was 1.6e-7 for an error of 4e-5 (found by the random
/// test above, seed 0xda57abaf00010000).
#[test]
fn a_border_colour_counts_in_the_contrast() {
    let grid = quadtex_core::TexelGrid::from_linear_f32(1, 1, &[[1000.0, 0.0, 0.0, 1.0]]).unwrap();
    let tree = QuadTree::from_texels(&grid, &BuildOptions::default())
        .unwrap()
        .0;
    assert_eq!(tree.bound_scale(), 1.0);
    let grey = Rgba::new(0.25, 0.25, 0.25, 1.0);
    let texture = Texture::new(
        tree,
        Wrap::new(WrapMode::Border, WrapMode::Border, grey).unwrap(),
    );
    assert_eq!(texture.bound_scale(), 999.75);
    assert_eq!(texture.with_wrap(Wrap::REPEAT).bound_scale(), 1.0);
    let fp = Footprint::from_corners([
        [1.2350712330937685, 2.453913973109616],
        [0.9759287669062316, 2.8560860268903845],
        [0.210455403119012, 2.9319289674856783],
        [0.9878180160650759, 1.7255133491568186],
    ])
    .unwrap();
    let projection = Projection::for_pixel(&fp, [10.0, 20.0]).unwrap();
    let centre = [10.5, 20.5];
    // Mitchell's support reaches this footprint's horizon.
    for filter in [PixelFilter::Box, PixelFilter::Tent] {
        let support = support_in_front(filter, &projection, centre).unwrap();
        let integral = |options: &FilterOptions| {
            let mut stats = FilterStats::default();
            texture.integrate_region(&projection, &support, filter, centre, options, &mut stats)
        };
        let fast = integral(&FilterOptions::default());
        let exact = integral(&FilterOptions::default().with_level(30));
        assert_eq!(exact.error_bound, 0.0);
        let bound = fast.error_bound / fast.weight.abs();
        assert!(
            bound <= texture.bound_scale() / 512.0,
            "{filter:?}: bound {bound:e}"
        );
        // f32 rounding of means near 5.
        let rounding = 1e-6;
        let (fast, exact) = (fast.mean().unwrap(), exact.mean().unwrap());
        assert!(
            max_diff(fast, exact) <= bound + rounding,
            "{filter:?}: {fast:?} vs {exact:?}, bound {bound:e}"
        );
    }
}

/// The filters' one-dimensional kernels integrate to 1 and have the stated
/// values: the tent peaks at 1, Mitchell at 8/9 and is negative near ±1.5.
#[test]
fn kernels_are_normalised() {
    for filter in [PixelFilter::Box, PixelFilter::Tent, PixelFilter::Mitchell] {
        let r = filter.radius();
        let n = 200_000;
        let sum: f64 = (0..n)
            .map(|i| filter.k1(-r + 2.0 * r * (f64::from(i) + 0.5) / f64::from(n)))
            .sum::<f64>()
            * 2.0
            * r
            / f64::from(n);
        assert!((sum - 1.0).abs() < 1e-6, "{filter:?}: {sum}");
    }
    assert_eq!(PixelFilter::Tent.k1(0.0), 1.0);
    assert!((PixelFilter::Mitchell.k1(0.0) - 8.0 / 9.0).abs() < 1e-15);
    assert!(PixelFilter::Mitchell.k1(1.5) < 0.0);
    // Continuity at the cell boundaries.
    for x in [-1.0f64, 1.0] {
        let m = PixelFilter::Mitchell;
        assert!((m.k1(x - 1e-12) - m.k1(x + 1e-12)).abs() < 1e-9);
    }
}

/// A 4 × 4 tile of the palette's colours in diagonal stripes.
fn palette_tile() -> QuadTree {
    let grid =
        quadtex_core::TexelGrid::from_fn(4, 4, |c, r| PALETTE[((c + 2 * r) % 5) as usize]).unwrap();
    QuadTree::from_texels(&grid, &BuildOptions::default())
        .unwrap()
        .0
}

/// A footprint over a million repeating tiles costs a bounded number of
/// nodes (whole tiles are taken in blocks) and gives the tile mean within
/// the reported bound.
#[test]
fn a_million_tiles_cost_little() {
    let tree = palette_tile();
    let mean = tree.average();
    let texture = Texture::new(tree, Wrap::REPEAT);
    let corners = [
        [0.3, 0.1],
        [1000.3, 0.2],
        [1400.0, 2000.0],
        [-600.0, 1900.0],
    ];
    let mut nodes = Vec::new();
    for scale in [1.0, 10.0, 100.0] {
        let fp = Footprint::from_corners(corners.map(|p| p.map(|v| v * scale))).unwrap();
        let mut stats = FilterStats::default();
        let c = texture.filter_counted(&fp, &FilterOptions::default(), &mut stats);
        eprintln!(
            "×{scale}: {} nodes, bound {}, colour {c:?} vs mean {mean:?}",
            stats.traversal.nodes_visited, stats.max_error_bound
        );
        assert!(max_diff(c, mean) <= stats.max_error_bound + 1e-4);
        assert!(stats.max_error_bound < 0.01, "{stats:?}");
        nodes.push(stats.traversal.nodes_visited);
    }
    // 10⁴ times the tiles, not 10⁴ times the cost.
    assert!(nodes[2] < 2 * nodes[0], "{nodes:?}");
}

/// A needle a fraction of a tile wide over thousands of repeating tiles
/// (a pixel below the horizon): its boundary crosses more tiles than the
/// budget has squares and its coarse bound is its whole weight, so it takes
/// the coarse sum without refining. The answer stays within its bound of
/// one refined under a budget large enough to refine it.
#[test]
fn needles_over_many_tiles_take_the_coarse_sum_at_once() {
    let texture = Texture::new(palette_tile(), Wrap::REPEAT);
    for length in [300.0, 3000.0] {
        let corners = [[0.1, 0.2], [length, 0.5], [length, 0.9], [0.1, 0.45]];
        let fp = Footprint::from_corners(corners).unwrap();
        let run = |options: &FilterOptions| {
            let mut stats = FilterStats::default();
            let c = texture.filter_counted(&fp, options, &mut stats);
            (c, stats)
        };
        // The renderer's budget (the library default has none).
        let (coarse, quick) = run(&FilterOptions::RENDER);
        let (refined, slow) = run(&FilterOptions::default().with_budget(1 << 16).unwrap());
        let started = std::time::Instant::now();
        let (unlimited, full) = run(&FilterOptions::default());
        eprintln!(
            "length {length}: no budget, {} squares, {:?}, bound {}",
            full.traversal.nodes_visited,
            started.elapsed(),
            full.max_error_bound
        );
        assert!(full.traversal.nodes_visited <= 2 * quadtex_core::FIXED_LEVEL_CAP);
        assert!(
            max_diff(unlimited, refined) <= full.max_error_bound + slow.max_error_bound + 1e-9,
            "length {length}: {unlimited:?} vs {refined:?}"
        );
        assert!(
            quick.traversal.nodes_visited < 16,
            "length {length}: {} squares",
            quick.traversal.nodes_visited
        );
        assert!(
            slow.traversal.nodes_visited > 64,
            "the large budget refines"
        );
        let bound = quick.max_error_bound + slow.max_error_bound;
        assert!(
            max_diff(coarse, refined) <= bound + 1e-9,
            "length {length}: {coarse:?} vs {refined:?}, bounds {} + {}",
            quick.max_error_bound,
            slow.max_error_bound
        );
    }
}

/// A repeating 2×2 checker of opaque white and transparent cells.
fn white_and_clear_checker() -> Texture {
    let grid = quadtex_core::TexelGrid::from_fn(2, 2, |c, r| {
        if (c + r) % 2 == 0 {
            Rgba::opaque(1.0, 1.0, 1.0)
        } else {
            Rgba::TRANSPARENT
        }
    })
    .unwrap();
    let tree = QuadTree::from_texels(&grid, &BuildOptions::default())
        .unwrap()
        .0;
    Texture::new(tree, Wrap::REPEAT)
}

/// The box pixel `[0, 1] × [−½, ½]` over a ground plane whose horizon
/// is screen `y = 0` (texture x = 3·s_x/s_y, z = 3/s_y: `w = s_y`), under
/// `options`: its integral and what it cost.
fn pixel_at_the_horizon(
    texture: &Texture,
    options: &FilterOptions,
) -> (quadtex_core::RegionIntegral, FilterStats) {
    let projection = Projection::new([[3.0, 0.0, 0.0], [0.0, 0.0, 3.0], [0.0, 1.0, 0.0]]).unwrap();
    let mut stats = FilterStats::default();
    let r = texture.integrate_region(
        &projection,
        &ConvexPolygon::rect(0.0, -0.5, 1.0, 0.5),
        PixelFilter::Box,
        [0.5, 0.0],
        options,
        &mut stats,
    );
    (r, stats)
}

/// A region reaching past the horizon (`w ≤ 0`) is clipped there; what lies
/// a hair before it takes the texture's mean, within the bound.
#[test]
fn regions_reaching_the_horizon_stay_finite() {
    let texture = white_and_clear_checker();
    let (r, stats) = pixel_at_the_horizon(&texture, &FilterOptions::default());
    // Only the lower half sees the plane.
    assert!((r.weight - 0.5).abs() < 1e-6, "{r:?}");
    let mean = r.mean().unwrap();
    assert!(
        f64::from((mean.a - 0.5).abs()) < 2e-3 + r.error_bound / r.weight,
        "{mean:?} {r:?}"
    );
    eprintln!("horizon: {r:?} {stats:?}");
    assert!(stats.traversal.nodes_visited < 200_000, "{stats:?}");
}

/// The same over an HDR checker (red 1000 and 0: a contrast of 1000):
/// the horizon's sliver, bounded in colour units, is weighed against the
/// target in the walk's units (unit contrast), so the walk still meets
/// the bound asked for, relative to the contrast, at the same cost.
#[test]
fn regions_reaching_the_horizon_keep_the_bound_over_hdr() {
    let texels: Vec<[f32; 4]> = (0..4)
        .map(|i| {
            if (i % 2 + i / 2) % 2 == 0 {
                [1000.0, 0.0, 0.0, 1.0]
            } else {
                [0.0, 0.0, 0.0, 1.0]
            }
        })
        .collect();
    let grid = quadtex_core::TexelGrid::from_linear_f32(2, 2, &texels).unwrap();
    let tree = QuadTree::from_texels(&grid, &BuildOptions::default())
        .unwrap()
        .0;
    let texture = Texture::new(tree, Wrap::REPEAT);
    assert_eq!(texture.bound_scale(), 1000.0);
    let (r, stats) = pixel_at_the_horizon(&texture, &FilterOptions::default());
    let relative = r.error_bound / r.weight / texture.bound_scale();
    assert!(relative <= 1.0 / 512.0, "{relative:e} {r:?} {stats:?}");
    assert!(stats.traversal.nodes_visited < 200_000, "{stats:?}");
}

/// Over many tiles of a repeated HDR texture (red up to 1000, a lean to
/// one side so that whole tiles' bounds count the colour's moments), the
/// reported bound holds against the full-depth integral and meets the
/// target: the tiles' moments, in colour units, are weighed against
/// unit-contrast bounds (counted in colour units and then scaled by the
/// contrast again, one footprint's bound was 0.18, 90× the target), and
/// with no budget, whole-tile blocks above their share descend.
#[test]
fn many_hdr_tiles_keep_the_reported_bound() {
    let side = 8u32;
    let texels: Vec<[f32; 4]> = (0..side * side)
        .map(|k| {
            let (c, r) = (k % side, k / side);
            let lean = f32::from(u8::try_from(c).unwrap()) / 7.0;
            let v = if (c * 7 + r * 3) % 5 < 2 {
                1000.0 * lean
            } else {
                3.0
            };
            [v, 0.5, 0.25 * v, 1.0]
        })
        .collect();
    let grid = quadtex_core::TexelGrid::from_linear_f32(side, side, &texels).unwrap();
    let tree = QuadTree::from_texels(&grid, &BuildOptions::default())
        .unwrap()
        .0;
    let texture = Texture::new(tree, Wrap::REPEAT);
    let scale = texture.bound_scale();
    assert!(scale > 900.0, "{scale}");
    let mut worst = 0.0f64;
    for (k, depth) in [0.3, 0.8, 1.5].into_iter().enumerate() {
        for angle in [0.1, 0.7, 2.0] {
            let fp = perspective_quad([0.3 + k as f64, 0.6], 6.0, 40.0, depth * 20.0, angle);
            let mut stats = FilterStats::default();
            let (fast, bound) =
                texture.filter_with_bound(&fp, &FilterOptions::default(), &mut stats);
            eprintln!("{} squares, bound {bound:e}", stats.traversal.nodes_visited);
            assert!(stats.traversal.nodes_visited < 200_000, "{stats:?}");
            let exact = texture.filter(&fp, &FilterOptions::default().with_level(12));
            let err = max_diff(fast, exact);
            assert!(
                err <= bound * scale + 1e-3,
                "{fp:?}: {err} above {}",
                bound * scale
            );
            // Met, with no budget: whole-tile blocks above their share of
            // the target descend under the box too (one of these footprints
            // ended at 1.17× the target before, and at 90× with the
            // moments counted in colour units and scaled again).
            assert!(bound <= 1.0 / 512.0, "{fp:?}: bound {bound:e} {stats:?}");
            worst = worst.max(err / scale);
        }
    }
    assert!(worst > 0.0, "every footprint exact: the test shows nothing");
}

/// A fixed level over a region reaching the horizon cannot refine
/// everything: it stops at the cap with a finite colour and its bound.
#[test]
fn a_fixed_level_at_the_horizon_stops_at_the_cap() {
    let texture = white_and_clear_checker();
    let (r, stats) = pixel_at_the_horizon(&texture, &FilterOptions::default().with_level(30));
    assert!(stats.traversal.nodes_visited <= quadtex_core::FIXED_LEVEL_CAP + 8);
    let mean = r.mean().unwrap();
    assert!(mean.a.is_finite() && r.error_bound.is_finite(), "{r:?}");
}

/// Any projection and region, however extreme (huge or tiny scales, the
/// horizon inside the region, far-away tiles), gives a finite answer or
/// nothing, within the budget (the renderer's), and never panics.
#[test]
fn extreme_projections_never_panic() {
    arbtest::arbtest(|u| {
        let texture = Texture::new(blocky_tree(u)?, wrap(u)?);
        let scale = |u: &mut Unstructured<'_>| -> ArbResult<f64> {
            let e = u.int_in_range(-40..=40i32)?;
            let m = unit(u, -1.0, 1.0)?;
            Ok(m * 10f64.powi(e))
        };
        let mut m = [[0.0; 3]; 3];
        for row in &mut m {
            for v in row.iter_mut() {
                *v = scale(u)?;
            }
        }
        let Ok(projection) = Projection::new(m) else {
            return Ok(());
        };
        let (x, y) = (scale(u)?, scale(u)?);
        let (w, h) = (scale(u)?.abs(), scale(u)?.abs());
        let region = ConvexPolygon::rect(x, y, x + w, y + h);
        for filter in [PixelFilter::Box, PixelFilter::Tent] {
            let mut stats = FilterStats::default();
            let r = texture.integrate_region(
                &projection,
                &region,
                filter,
                [x + w / 2.0, y + h / 2.0],
                &FilterOptions::RENDER,
                &mut stats,
            );
            assert!(r.weight.is_finite() && r.error_bound.is_finite(), "{r:?}");
            if let Some(c) = r.mean() {
                assert!(c.to_array().iter().all(|v| v.is_finite()), "{c:?}");
            }
            assert!(stats.traversal.nodes_visited < 100_000, "{stats:?}");
        }
        Ok(())
    })
    .budget_ms(3_000);
}

/// Needles over many tiles of a shallow tree (the pixels below a horizon)
/// are integrated cell by cell: the default options give the same integral
/// as refining every square (`--level 30`), with a zero bound, for every
/// pixel filter and for repeat and mirror on either axis; where the cells
/// are too many (the tent's and Mitchell's larger supports, deep trees) the
/// walk's answer is within its bound.
#[test]
fn needles_over_many_tiles_are_exact() {
    let (mut scanned, mut boxes) = (0, 0);
    arbtest::arbtest(|u| {
        let modes = [WrapMode::Repeat, WrapMode::Mirror];
        let wrap = Wrap::new(*u.choose(&modes)?, *u.choose(&modes)?, PALETTE[0]).unwrap();
        // Square trees: only those of depth ≤ 4 are scanned cell by cell.
        let grid = common::blocky_grid(u, 4)?;
        let tree = QuadTree::from_texels(&grid, &BuildOptions::default())
            .unwrap()
            .0;
        let texture = Texture::new(tree, wrap);
        // A thin trapezoid 20–60 tiles long, 0.05–0.5 tiles wide, widening
        // with distance, leaning, anywhere within ±1000 tiles.
        let (x0, z0) = (unit(u, -1000.0, 1000.0)?, unit(u, -1000.0, 1000.0)?);
        let (near, length) = (unit(u, 0.05, 0.3)?, unit(u, 20.0, 60.0)?);
        let (far, lean) = (near * unit(u, 1.0, 1.7)?, unit(u, -0.7, 0.7)? * length);
        let fp = Footprint::from_corners([
            [x0, z0],
            [x0 + near, z0],
            [x0 + lean + far, z0 + length],
            [x0 + lean, z0 + length],
        ])
        .unwrap();
        let Some(projection) = Projection::for_pixel(&fp, [0.0, 0.0]) else {
            return Ok(());
        };
        for filter in [PixelFilter::Box, PixelFilter::Tent, PixelFilter::Mitchell] {
            let centre = [0.5, 0.5];
            let region = match filter {
                PixelFilter::Box => ConvexPolygon::rect(0.0, 0.0, 1.0, 1.0),
                _ => filter.support(centre),
            };
            if region
                .vertices()
                .iter()
                .any(|&s| projection.w(s) <= 1e-3 * projection.w(centre))
            {
                continue; // the support reaches the horizon: not this test
            }
            let get = |options: &FilterOptions| {
                texture.integrate_region(
                    &projection,
                    &region,
                    filter,
                    centre,
                    options,
                    &mut FilterStats::default(),
                )
            };
            let quick = get(&FilterOptions::default());
            let exact = get(&FilterOptions::default().with_level(30));
            // Within the reported bound: zero when the cells were scanned.
            let scale = 1.0 + exact.weight.abs();
            let tolerance = quick.error_bound + 1e-9 * scale;
            assert!((quick.weight - exact.weight).abs() < 1e-9 * scale);
            for (a, b) in quick.colour.0.iter().zip(exact.colour.0) {
                assert!(
                    (a - b).abs() <= tolerance,
                    "{filter:?}: {quick:?} vs {exact:?} for {fp:?} under {wrap:?}"
                );
            }
            if filter == PixelFilter::Box {
                boxes += 1;
                if quick.error_bound == 0.0 {
                    scanned += 1;
                }
            }
        }
        Ok(())
    })
    .budget_ms(3_000);
    // The cell scan, not the walk, answered most box pixels.
    eprintln!("{scanned} of {boxes} box pixels scanned");
    assert!(scanned * 2 > boxes, "{scanned} scanned of {boxes}");
}

/// A region whose boundary carries a rounding wiggle (a vertex repeated a
/// few ulps away, backwards along its edge, as a clip through a vertex
/// leaves one) integrates as the same region without it: the wiggle's
/// edge points where the rounding points it, and taken as a half-plane it
/// once put the whole region outside (weight 0, the pixel's part lost;
/// 213 regions of the terrain scene at 960×540), or a sliver of it.
/// Regions of many texels (the walk) and of a few (the texel scan).
#[test]
fn a_rounding_wiggle_in_a_region_loses_nothing() {
    let grid = quadtex_core::TexelGrid::from_fn(256, 256, |c, r| {
        Rgba::opaque(
            (c % 16) as f32 / 15.0,
            (r % 13) as f32 / 12.0,
            ((c * r) % 7) as f32 / 6.0,
        )
    })
    .unwrap();
    let tree = QuadTree::from_texels(&grid, &BuildOptions::default())
        .unwrap()
        .0;
    let texture = Texture::new(tree, Wrap::REPEAT);
    let integral = |vertices: &[[f64; 2]]| {
        let region = ConvexPolygon::new(vertices).unwrap();
        texture.integrate_region(
            &Projection::identity(),
            &region,
            PixelFilter::Box,
            [0.5, 0.5],
            &FilterOptions::default(),
            &mut FilterStats::default(),
        )
    };
    for (lo, hi) in [(0.2, 0.8), (0.4, 0.43)] {
        let mid = 0.5 * (lo + hi);
        let clean = integral(&[[lo, lo], [hi, lo], [hi, hi], [mid, hi], [lo, hi]]);
        let area = (hi - lo) * (hi - lo);
        assert!((clean.weight - area).abs() < 1e-12 * area, "{clean:?}");
        // A few ulps (a clip through a vertex), and a billionth of the
        // region (two nearly parallel lines crossing).
        for d in [1.0, 4.0, 64.0, 1e7 * (hi - lo)].map(|k| k * f64::EPSILON) {
            // Backwards along the top edge (which runs from x = hi to lo),
            // and, by ulps only (more is refused as not convex), across it.
            let across = if d < 1e-12 { 3 } else { 1 };
            for wiggle in [[mid + d, hi], [mid + d, hi + d], [mid - d, hi - d]]
                .into_iter()
                .take(across)
            {
                let r = integral(&[[lo, lo], [hi, lo], [hi, hi], [mid, hi], wiggle, [lo, hi]]);
                assert!(
                    (r.weight - clean.weight).abs() < 1e-12 * area,
                    "{wiggle:?}: {r:?}"
                );
                for (a, b) in r.colour.0.iter().zip(clean.colour.0) {
                    assert!(
                        (a - b).abs() < 1e-9 * area,
                        "{wiggle:?}: {r:?} vs {clean:?}"
                    );
                }
            }
        }
    }
}

/// A span's colour ([`Texture::uniform_colour_over`]) is the exact
/// integral of every pixel inside it: random blocky trees (HDR too) under
/// every wrap, ground planes seen in perspective (spans below, across and
/// above the horizon, on negative and dyadic coordinates), spans of 1 to 64
/// pixels of one row, box and tent. Where it answers, each pixel integrated
/// at the tree's depth (the slow reference) has that colour as its mean;
/// both answers must occur (a test the shortcut never enters passes).
#[test]
fn a_spans_uniform_colour_is_each_pixels_integral() {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static ANSWERED: AtomicUsize = AtomicUsize::new(0);
    static REFUSED: AtomicUsize = AtomicUsize::new(0);
    arbtest::arbtest(|u| {
        let texture = Texture::new(blocky_tree(u)?, wrap(u)?);
        // texture x = (kx·sx + ox) / w, z = kz / w, w = g·sy + h.
        let (kx, kz, ox) = (unit(u, 0.01, 2.0)?, unit(u, 0.01, 2.0)?, unit(u, -3.0, 3.0)?);
        let (g, h) = (unit(u, 0.01, 1.0)?, unit(u, -5.0, 5.0)?);
        let projection = Projection::new([[kx, 0.0, ox], [0.0, 0.0, kz], [0.0, g, h]]).unwrap();
        let filter = *u.choose(&[PixelFilter::Box, PixelFilter::Tent])?;
        let r = filter.radius();
        let x0 = f64::from(u.int_in_range(-64i32..=64)?);
        let y = f64::from(u.int_in_range(-40i32..=400)?) + 0.5;
        let len = u.int_in_range(1u32..=64)?;
        let last = x0 + f64::from(len - 1) + 0.5;
        let span = ConvexPolygon::rect(x0 + 0.5 - r, y - r, last + r, y + r);
        let options = FilterOptions::default();
        let first = filter.support([x0 + 0.5, y]);
        let Some(colour) = texture.uniform_colour_over(&projection, &span, &first, &options) else {
            REFUSED.fetch_add(1, Ordering::Relaxed);
            return Ok(());
        };
        ANSWERED.fetch_add(1, Ordering::Relaxed);
        let tol = 2e-6 * texture.bound_scale();
        for i in 0..len {
            let centre = [x0 + f64::from(i) + 0.5, y];
            let support = filter.support(centre);
            let depth = texture.tree().depth();
            let reference = texture.integrate_region(
                &projection,
                &support,
                filter,
                centre,
                &FilterOptions::default().with_level(depth),
                &mut FilterStats::default(),
            );
            let mean = reference.mean().unwrap();
            assert!(
                max_diff(mean, colour) < tol && reference.error_bound == 0.0,
                "pixel {i} of {len} at ({x0}, {y}): {mean:?} against the span's {colour:?} ({reference:?})"
            );
        }
        Ok(())
    })
    .budget_ms(3_000);
    let (answered, refused) = (
        ANSWERED.load(Ordering::Relaxed),
        REFUSED.load(Ordering::Relaxed),
    );
    assert!(
        answered > 50 && refused > 50,
        "{answered} answered, {refused} refused"
    );
}

#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The filtering API against slow references: rectangles against the
//! fragment integral, parallelograms under both weightings, projective
//! footprints against dense sampling of the pixel square mapped through
//! the projective map ([`quadtex_core::Projection`]).

mod common;

use arbtest::arbitrary::{Result as ArbResult, Unstructured};
use common::{PALETTE, blocky_grid};
use quadtex_core::{
    BuildOptions, FilterOptions, Footprint, Projection, QuadTree, Rgba, TexelGrid, Texture,
    Weighting, Wrap, WrapMode,
};

/// A random blocky texture of up to 16×16 cells (an incomplete tree).
fn blocky_tree(u: &mut Unstructured<'_>) -> ArbResult<QuadTree> {
    let grid = blocky_grid(u, 4)?;
    Ok(QuadTree::from_texels(&grid, &BuildOptions::default())
        .unwrap()
        .0)
}

fn coord(u: &mut Unstructured<'_>) -> ArbResult<f64> {
    Ok(match u.int_in_range(0..=2u8)? {
        // Dyadic, across and beyond the unit square.
        0 => f64::from(u.int_in_range(-64..=192i32)?) / 64.0,
        1 => f64::from(u.int_in_range(0..=1_000_000u32)?) / 1_000_000.0,
        _ => f64::from(u.int_in_range(-3_000_000..=4_000_000i32)?) / 1_000_000.0,
    })
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
    .expect("palette colours are finite"))
}

fn max_diff(a: Rgba, b: Rgba) -> f32 {
    (a - b).to_array().iter().fold(0f32, |m, v| m.max(v.abs()))
}

/// Axis-aligned rectangles under `Weighting::Texture` at full depth are the
/// wrapped fragment integral over the rectangle's area; with a transparent
/// border they are exactly what `quadtex query` prints over the area.
#[test]
fn rectangles_filter_to_integral_over_area() {
    arbtest::arbtest(|u| {
        let tree = blocky_tree(u)?;
        let wrap = wrap(u)?;
        let (a, b, c, d) = (coord(u)?, coord(u)?, coord(u)?, coord(u)?);
        let (x0, x1, z0, z1) = (a.min(b), a.max(b), c.min(d), c.max(d));
        if x1 - x0 < 1e-9 || z1 - z0 < 1e-9 {
            return Ok(());
        }
        let texture = Texture::new(tree.clone(), wrap);
        let fp = Footprint::from_corners([[x0, z0], [x1, z0], [x1, z1], [x0, z1]]).unwrap();
        let options = FilterOptions::default()
            .with_weighting(Weighting::Texture)
            .with_level(30);
        let got = texture.filter(&fp, &options);
        let f = quadtex_core::Fragment::new(x0, z0, x1, z1).unwrap();
        let area = (x1 - x0) * (z1 - z0);
        let want = texture.integral(&f, None).mean_over(area);
        // f32 output; inner colours are rounded once to 16 bits.
        assert!(
            max_diff(got, want) <= 1e-5 + 1.0 / 65535.0,
            "{got:?} vs {want:?}"
        );
        let query = Texture::new(tree, Wrap::border(Rgba::TRANSPARENT).unwrap());
        let got = query.filter(&fp, &options);
        let want = query.tree().weighted_colour(&f, 30).mean_over(area);
        assert!(
            max_diff(got, want) <= 1e-5 + 1.0 / 65535.0,
            "{got:?} vs {want:?}"
        );
        Ok(())
    });
}

/// A parallelogram is an affine image of the pixel: screen-space weighting
/// is uniform over it, so both weightings agree (exactly at full depth;
/// within the reported bounds at the default level of detail).
#[test]
fn parallelograms_weigh_the_same_in_screen_and_texture_space() {
    arbtest::arbtest(|u| {
        let texture = Texture::new(blocky_tree(u)?, wrap(u)?);
        let st = [coord(u)?, coord(u)?];
        let d_dx = [coord(u)? / 4.0, coord(u)? / 4.0];
        let d_dy = [coord(u)? / 4.0, coord(u)? / 4.0];
        let Ok(fp) = Footprint::from_differentials(st, d_dx, d_dy) else {
            return Ok(());
        };
        let exact = FilterOptions::default().with_level(30);
        let screen = texture.filter(&fp, &exact);
        let flat = texture.filter(&fp, &exact.with_weighting(Weighting::Texture));
        assert!(max_diff(screen, flat) <= 1e-5, "{screen:?} vs {flat:?}");
        let (mut s1, mut s2) = (
            quadtex_core::FilterStats::default(),
            quadtex_core::FilterStats::default(),
        );
        let a = texture.filter_counted(&fp, &FilterOptions::default(), &mut s1);
        let b = texture.filter_counted(
            &fp,
            &FilterOptions::default().with_weighting(Weighting::Texture),
            &mut s2,
        );
        let bound = (s1.max_error_bound + s2.max_error_bound) as f32 + 1e-5;
        assert!(max_diff(a, b) <= bound, "{a:?} vs {b:?} beyond {bound}");
        Ok(())
    });
}

/// Equal differentials make a segment, not a parallelogram: rounding left
/// its homography a tiny determinant, so the screen weighting integrated a
/// near-singular map to transparent where the texture weighting took the
/// point lookup at the centre (arbtest seed 0xaac0f6c300000028). Both now
/// take the point lookup.
#[test]
fn a_segment_footprint_filters_to_its_centre_under_both_weightings() {
    let grid = TexelGrid::new(
        4,
        4,
        (0..16)
            .map(|i| {
                Rgba::new(0.05 * (i % 4) as f32, 0.0, 0.0, 0.2 + 0.05 * (i / 4) as f32).to_unorm16()
            })
            .collect(),
    )
    .unwrap();
    let tree = QuadTree::from_texels(&grid, &quadtex_core::BuildOptions::default())
        .unwrap()
        .0;
    let texture = Texture::new(tree, Wrap::REPEAT);
    let fp =
        Footprint::from_differentials([0.434764, 0.0], [-0.25, -0.25], [-0.25, -0.25]).unwrap();
    assert!(Projection::for_pixel(&fp, [0.0, 0.0]).is_none());
    let exact = FilterOptions::default().with_level(30);
    let centre = texture.nearest(fp.centre());
    for weighting in [Weighting::Screen, Weighting::Texture] {
        assert_eq!(
            texture.filter(&fp, &exact.with_weighting(weighting)),
            centre
        );
    }
}

/// The colour of the pixel square mapped through the footprint's
/// projective map, by midpoint sampling on an `n × n` grid (the finest cell
/// under each sample, wrap included).
fn sampled(texture: &Texture, fp: &Footprint, n: u32) -> Rgba {
    let p = Projection::for_pixel(fp, [0.0, 0.0]).expect("a projective footprint");
    let mut acc = Rgba::TRANSPARENT;
    for j in 0..n {
        for i in 0..n {
            let (u, v) = (
                (f64::from(i) + 0.5) / f64::from(n),
                (f64::from(j) + 0.5) / f64::from(n),
            );
            acc += texture.nearest(p.texture_point([u, v]).expect("in front of the camera"));
        }
    }
    acc * (1.0 / (n * n) as f32)
}

/// A footprint of a ground plane seen at a grazing angle: a trapezoid whose
/// far edge (`z` large) is `ratio` times wider than the near one, the image
/// of a pixel under a homography with a strong perspective term.
fn grazing_quad(centre: [f64; 2], near: f64, ratio: f64, depth: f64, skew: f64) -> Footprint {
    let far = near * ratio;
    Footprint::from_corners([
        [centre[0] - near / 2.0, centre[1]],
        [centre[0] + near / 2.0, centre[1]],
        [centre[0] + far / 2.0 + skew, centre[1] + depth],
        [centre[0] - far / 2.0 + skew, centre[1] + depth],
    ])
    .unwrap()
}

/// Projective footprints under `Weighting::Screen` match dense sampling of
/// the pixel square within the sampling error (the exact polygon integral
/// has no strips, so no area excess: `max_mismatch` stays 0). `Weighting::Texture`
/// is measurably farther on a texture split across the direction of
/// foreshortening.
#[test]
fn projective_footprints_match_dense_sampling_of_the_pixel() {
    arbtest::arbtest(|u| {
        let texture = Texture::new(blocky_tree(u)?, wrap(u)?);
        let fp = grazing_quad(
            [coord(u)?, coord(u)?],
            0.05 + f64::from(u.int_in_range(0..=100u32)?) / 200.0,
            1.0 + f64::from(u.int_in_range(0..=40u32)?) / 4.0,
            0.1 + f64::from(u.int_in_range(0..=100u32)?) / 50.0,
            coord(u)? / 4.0,
        );
        if Projection::for_pixel(&fp, [0.0, 0.0]).is_none() {
            return Ok(());
        }
        let options = FilterOptions::default().with_level(30);
        let mut stats = quadtex_core::FilterStats::default();
        let screen = texture.filter_counted(&fp, &options, &mut stats);
        let (coarse, fine) = (sampled(&texture, &fp, 128), sampled(&texture, &fp, 256));
        // The 256² estimate's own error is well below the gap to the 128² one.
        let sampling = max_diff(coarse, fine) as f64;
        // A strip pipeline's excess area (reported) could carry up to twice
        // its share of screen weight; the exact filter reports none.
        let bound = 2.0 * sampling + 2.0 * stats.max_mismatch + 0.01;
        let err = max_diff(screen, fine) as f64;
        assert!(
            err <= bound,
            "screen {screen:?} vs sampled {fine:?}: {err} > {bound} (excess {})",
            stats.max_mismatch
        );
        Ok(())
    })
    .budget_ms(4_000);

    // Left half white, right half black: a pixel sees the near (narrow) end
    // large, so its mean is far from the footprint's area mean.
    let split = TexelGrid::from_fn(2, 2, |c, _| {
        if c == 0 {
            Rgba::opaque(1.0, 1.0, 1.0)
        } else {
            Rgba::opaque(0.0, 0.0, 0.0)
        }
    })
    .unwrap();
    let tree = QuadTree::from_texels(&split, &BuildOptions::default())
        .unwrap()
        .0;
    let texture = Texture::new(tree, Wrap::CLAMP);
    // Near end entirely on the white half, far end spanning both halves.
    let fp = Footprint::from_corners([[0.3, 0.1], [0.45, 0.1], [0.95, 0.9], [0.05, 0.9]]).unwrap();
    let options = FilterOptions::default();
    let screen = texture.filter(&fp, &options).r;
    let flat = texture
        .filter(&fp, &options.with_weighting(Weighting::Texture))
        .r;
    let truth = sampled(&texture, &fp, 512).r;
    eprintln!("split texture: screen {screen}, texture {flat}, sampled {truth}");
    assert!(
        (screen - truth).abs() < 0.01,
        "screen {screen} vs sampled {truth}"
    );
    assert!(
        (flat - truth).abs() > 0.05,
        "texture weighting {flat} should differ from {truth}"
    );
}

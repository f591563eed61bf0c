#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The vector packer against closed-form areas and an independent point
//! sampler (winding numbers over the unclipped polygons, `VectorArt::colour_at`).

use arbtest::arbitrary::{Result as ArbResult, Unstructured};
use quadtex_core::{Circle, Gradient, Interpolation, Spread, Stop, srgb_encode};
use quadtex_core::{
    ClipId, ConvexPolygon, FillRule, FilterOptions, Footprint, Fragment, Paint, QuadTree, Rgba,
    Texture, VectorArt, VectorOptions, Wrap,
};

const UNIT: f64 = 1.0;

fn pack(art: &VectorArt, level: u8) -> QuadTree {
    QuadTree::from_vector(
        art,
        &VectorOptions {
            max_level: level,
            ..VectorOptions::default()
        },
    )
    .unwrap()
    .0
}

/// Packed with no smooth-colour tolerance: gradients split down to the
/// leaf grid, so every leaf holds the exact mean of the art over it.
fn pack_exact(art: &VectorArt, level: u8) -> QuadTree {
    QuadTree::from_vector(
        art,
        &VectorOptions {
            max_level: level,
            tolerance: 0.0,
            ..VectorOptions::default()
        },
    )
    .unwrap()
    .0
}

/// Integral over the whole unit square, per channel.
fn total(t: &QuadTree) -> [f64; 4] {
    let f = Fragment::new(0.0, 0.0, UNIT, UNIT).unwrap();
    t.weighted_colour(&f, u8::MAX).0
}

fn rotated_rect(cx: f64, cz: f64, w: f64, h: f64, angle: f64) -> Vec<[f64; 2]> {
    let (s, c) = angle.sin_cos();
    [(-w, -h), (w, -h), (w, h), (-w, h)]
        .iter()
        .map(|&(x, z)| [cx + 0.5 * (x * c - z * s), cz + 0.5 * (x * s + z * c)])
        .collect()
}

fn regular_polygon(cx: f64, cz: f64, r: f64, n: usize) -> Vec<[f64; 2]> {
    (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            [cx + r * a.cos(), cz + r * a.sin()]
        })
        .collect()
}

/// One quantisation step of a stored colour, times the area it covers.
const STEP: f64 = 1.0 / 65535.0;

#[test]
fn whole_square_integral_is_area_times_colour() {
    let white = Rgba::opaque(1.0, 1.0, 1.0);
    let n = 4096;
    // The regular 4096-gon of radius r: area n/2·r²·sin(2π/n) (a circle
    // flattened with sagitta r(1−cos(π/n)) ≈ 1.2e-7).
    let r = 0.3;
    let polygon_area = 0.5 * n as f64 * r * r * (std::f64::consts::TAU / n as f64).sin();
    let cases: Vec<(&str, Vec<[f64; 2]>, f64)> = vec![
        (
            "axis-aligned rectangle",
            vec![[0.1, 0.2], [0.7, 0.2], [0.7, 0.45], [0.1, 0.45]],
            0.6 * 0.25,
        ),
        (
            "rotated rectangle",
            rotated_rect(0.5, 0.5, 0.4, 0.2, 0.3),
            0.4 * 0.2,
        ),
        (
            "triangle",
            vec![[0.1, 0.1], [0.9, 0.3], [0.4, 0.8]],
            0.5 * ((0.9f64 - 0.1) * (0.8 - 0.1) - (0.4 - 0.1) * (0.3 - 0.1)),
        ),
        (
            "clockwise triangle",
            vec![[0.1, 0.1], [0.4, 0.8], [0.9, 0.3]],
            0.5 * ((0.9f64 - 0.1) * (0.8 - 0.1) - (0.4 - 0.1) * (0.3 - 0.1)),
        ),
        ("4096-gon", regular_polygon(0.5, 0.5, r, n), polygon_area),
    ];
    for level in [4u8, 9, 14] {
        for (name, poly, area) in &cases {
            let mut art = VectorArt::new();
            art.fill(vec![poly.clone()], FillRule::NonZero, white, &[])
                .unwrap();
            let t = pack(&art, level);
            let got = total(&t);
            for (ch, v) in got.iter().enumerate() {
                // The root colour is the exact mean rounded once: half a step.
                assert!(
                    (v - area).abs() <= 0.5 * STEP + 1e-12,
                    "{name} at level {level}, channel {ch}: {v} vs {area}"
                );
            }
        }
    }
}

#[test]
fn art_beyond_the_unit_square_is_clipped_off() {
    let mut art = VectorArt::new();
    // A triangle with half its area outside: [−1,1]×[0,1] cut by x+... keep simple:
    // the rectangle [−0.5, 0.5) × [0.25, 0.75) covers 0.5 × 0.5 inside.
    art.fill(
        vec![vec![[-0.5, 0.25], [0.5, 0.25], [0.5, 0.75], [-0.5, 0.75]]],
        FillRule::NonZero,
        Rgba::opaque(0.0, 1.0, 0.0),
        &[],
    )
    .unwrap();
    let t = pack(&art, 6);
    let got = total(&t);
    assert!((got[1] - 0.25).abs() <= 0.5 * STEP, "{got:?}");
    assert!(got[0].abs() <= 0.5 * STEP);
    // Axis-aligned dyadic rectangles make the tree tiny: no leaf needs a sweep.
    let (_, report) = QuadTree::from_vector(&art, &VectorOptions::default()).unwrap();
    assert_eq!(report.swept_leaves, 0);
}

#[test]
fn fill_rules_differ_on_doubled_and_nested_contours() {
    let outer = vec![[0.1, 0.1], [0.9, 0.1], [0.9, 0.9], [0.1, 0.9]];
    let inner = vec![[0.3, 0.3], [0.7, 0.3], [0.7, 0.7], [0.3, 0.7]];
    let white = Rgba::opaque(1.0, 1.0, 1.0);
    let area = |rule, contours: Vec<Vec<[f64; 2]>>| {
        let mut art = VectorArt::new();
        art.fill(contours, rule, white, &[]).unwrap();
        total(&pack(&art, 8))[3]
    };
    let (big, small) = (0.64, 0.16);
    let close = |a: f64, b: f64| (a - b).abs() <= 0.5 * STEP;
    // Same direction: nonzero fills the inner square (winding 2), even-odd does not.
    assert!(close(
        area(FillRule::NonZero, vec![outer.clone(), inner.clone()]),
        big
    ));
    assert!(close(
        area(FillRule::EvenOdd, vec![outer.clone(), inner.clone()]),
        big - small
    ));
    // Opposite direction: a hole under both rules.
    let mut reversed = inner.clone();
    reversed.reverse();
    assert!(close(
        area(FillRule::NonZero, vec![outer.clone(), reversed.clone()]),
        big - small
    ));
    assert!(close(
        area(FillRule::EvenOdd, vec![outer, reversed]),
        big - small
    ));
}

#[test]
fn translucent_overlaps_composite_over_in_linear_light() {
    // Two half-transparent squares overlapping in [0.25,0.5)²; red below, blue above.
    let red = Rgba::new(0.5, 0.0, 0.0, 0.5);
    let blue = Rgba::new(0.0, 0.0, 0.5, 0.5);
    let mut art = VectorArt::new();
    art.fill(
        vec![vec![[0.0, 0.0], [0.5, 0.0], [0.5, 0.5], [0.0, 0.5]]],
        FillRule::NonZero,
        red,
        &[],
    )
    .unwrap();
    art.fill(
        vec![vec![[0.25, 0.25], [0.75, 0.25], [0.75, 0.75], [0.25, 0.75]]],
        FillRule::NonZero,
        blue,
        &[],
    )
    .unwrap();
    let t = pack(&art, 5);
    let q = |x0, z0, x1, z1| {
        let f = Fragment::new(x0, z0, x1, z1).unwrap();
        t.weighted_colour(&f, u8::MAX)
            .mean_over(f.area())
            .to_array()
    };
    let overlap = q(0.3, 0.3, 0.45, 0.45);
    // blue over red: (0,0,0.5,0.5) + (0.5,0,0,0.5)·(1−0.5).
    let want = [0.25, 0.0, 0.5, 0.75];
    for (g, w) in overlap.iter().zip(want) {
        assert!((f64::from(*g) - w).abs() < 1e-4, "{overlap:?}");
    }
    // A group of the same two shapes, opaque inside, faded to 0.5 as a whole:
    // the overlap shows only the top shape, faded.
    let mut art = VectorArt::new();
    let g = art.group(0.5).unwrap();
    art.fill(
        vec![vec![[0.0, 0.0], [0.5, 0.0], [0.5, 0.5], [0.0, 0.5]]],
        FillRule::NonZero,
        Rgba::opaque(1.0, 0.0, 0.0),
        &[g],
    )
    .unwrap();
    art.fill(
        vec![vec![[0.25, 0.25], [0.75, 0.25], [0.75, 0.75], [0.25, 0.75]]],
        FillRule::NonZero,
        Rgba::opaque(0.0, 0.0, 1.0),
        &[g],
    )
    .unwrap();
    let t = pack(&art, 5);
    let f = Fragment::new(0.3, 0.3, 0.45, 0.45).unwrap();
    let c = t
        .weighted_colour(&f, u8::MAX)
        .mean_over(f.area())
        .to_array();
    for (g, w) in c.iter().zip([0.0, 0.0, 0.5, 0.5]) {
        assert!((f64::from(*g) - w).abs() < 1e-4, "{c:?}");
    }
}

#[test]
fn groups_cannot_be_reopened() {
    let mut art = VectorArt::new();
    let g = art.group(0.5).unwrap();
    let tri = vec![vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]];
    art.fill(
        tri.clone(),
        FillRule::NonZero,
        Rgba::opaque(1.0, 0.0, 0.0),
        &[g],
    )
    .unwrap();
    art.fill(
        tri.clone(),
        FillRule::NonZero,
        Rgba::opaque(1.0, 0.0, 0.0),
        &[],
    )
    .unwrap();
    assert!(
        art.fill(tri, FillRule::NonZero, Rgba::opaque(1.0, 0.0, 0.0), &[g])
            .is_err()
    );
    assert!(art.group(1.5).is_err());
    let mut art = VectorArt::new();
    assert!(
        art.fill(
            vec![vec![[0.0, 0.0], [f64::NAN, 0.0], [0.0, 1.0]]],
            FillRule::NonZero,
            Rgba::opaque(1.0, 0.0, 0.0),
            &[]
        )
        .is_err()
    );
}

#[test]
fn absurd_levels_are_refused() {
    let art = VectorArt::new();
    let r = QuadTree::from_vector(
        &art,
        &VectorOptions {
            max_level: 25,
            ..VectorOptions::default()
        },
    );
    assert!(r.is_err());
}

/// Random overlapping translucent polygons (some self-intersecting), random
/// fragments on the leaf grid (some outside the unit square, some empty): the
/// tree's integral at full depth against stratified point sampling of the
/// exact art, within the sampler's own error. Packed with no smooth-colour
/// tolerance: a gradient's square left whole above the leaf grid holds its
/// exact mean, but a fragment that covers part of it gets that mean over
/// the part, off by up to the tolerance (that bound has tests of its own,
/// `gradient_masks_stay_within_the_stated_bound` and the gradient
/// integrals'). Packed with a tolerance of 0.05, seed 0xeeb79d5300007a44
/// found a fragment one leaf wide across such a square off by 7.3e-6
/// (3.5 % of its area) against 6.6e-6 allowed.
#[test]
fn fragments_match_point_sampling_of_random_art() {
    arbtest::arbtest(|u: &mut Unstructured<'_>| {
        let art = random_art(u)?;
        let level = u.int_in_range(3..=9u8)?;
        let t = pack_exact(&art, level);
        // Exact at every depth: a deeper packing of the same art integrates
        // the leaf grid to the same values (up to quantisation), so sweeps and
        // subdivision agree far more tightly than the sampler can tell.
        let deeper = pack_exact(&art, level + 2);
        for _ in 0..4 {
            // On the leaf grid (level `level`): below it the tree holds each
            // leaf's mean, not the art, by design.
            let cells = 1i32 << level;
            let coord = |u: &mut Unstructured<'_>| -> ArbResult<f64> {
                Ok(f64::from(u.int_in_range(-2..=cells + 2)?) / f64::from(cells))
            };
            let (a, b, c, d) = (coord(u)?, coord(u)?, coord(u)?, coord(u)?);
            let f = Fragment::new(a.min(b), c.min(d), a.max(b), c.max(d)).unwrap();
            let got = t.weighted_colour(&f, u8::MAX).0;
            let finer = deeper.weighted_colour(&f, u8::MAX).0;
            for ch in 0..4 {
                assert!(
                    (got[ch] - finer[ch]).abs() <= f.area() * STEP + 1e-12,
                    "{f:?} channel {ch}: level {level} {} vs level {} {}",
                    got[ch],
                    level + 2,
                    finer[ch]
                );
            }
            // The sampler: n×n cell centres; each cell an edge crosses can be
            // wrong by its whole area, so allow a few cells along the edges.
            let n = 96;
            let (w, h) = (f.x1() - f.x0(), f.z1() - f.z0());
            let mut want = [0.0; 4];
            for i in 0..n {
                for j in 0..n {
                    let p = [
                        f.x0() + w * (i as f64 + 0.5) / n as f64,
                        f.z0() + h * (j as f64 + 0.5) / n as f64,
                    ];
                    let c = art.colour_at(p);
                    for (o, v) in want.iter_mut().zip(c) {
                        *o += v * w * h / (n * n) as f64;
                    }
                }
            }
            // Leaves are exact: only quantisation (half a step per node) and
            // the sampler's edge cells (≤ ~edges·n cells of area wh/n²) differ.
            let sampler = 0.25 * w * h * 12.0 / n as f64;
            for ch in 0..4 {
                assert!(
                    (got[ch] - want[ch]).abs() <= sampler + f.area() * STEP + 1e-12,
                    "{f:?} channel {ch}: tree {} sampled {}",
                    got[ch],
                    want[ch]
                );
            }
        }
        Ok(())
    })
    .budget_ms(3000);
}

fn random_art(u: &mut Unstructured<'_>) -> ArbResult<VectorArt> {
    let mut art = VectorArt::new();
    let shapes = u.int_in_range(1..=3usize)?;
    for _ in 0..shapes {
        let mut contours = Vec::new();
        for _ in 0..u.int_in_range(1..=2usize)? {
            let n = u.int_in_range(3..=6usize)?;
            let mut c = Vec::new();
            for _ in 0..n {
                c.push([
                    f64::from(u.int_in_range(-100..=1100i32)?) / 1000.0,
                    f64::from(u.int_in_range(-100..=1100i32)?) / 1000.0,
                ]);
            }
            contours.push(c);
        }
        let a = f32::from(u.int_in_range(1..=4u8)?) / 4.0;
        let colour = Rgba::new(
            a * f32::from(u.int_in_range(0..=4u8)?) / 4.0,
            a * f32::from(u.int_in_range(0..=4u8)?) / 4.0,
            a * f32::from(u.int_in_range(0..=4u8)?) / 4.0,
            a,
        );
        let rule = if u.arbitrary()? {
            FillRule::EvenOdd
        } else {
            FillRule::NonZero
        };
        // Some shapes are clipped: by a region of one or two random polygons,
        // sometimes itself within a second region.
        let clip = if u.ratio(1u8, 3)? {
            let outer = if u.arbitrary()? {
                let r = art.clip_region(&[]).unwrap();
                art.add_to_clip(r, vec![random_polygon(u)?], FillRule::NonZero, None)
                    .unwrap();
                Some(r)
            } else {
                None
            };
            let r = art.clip_region(outer.as_slice()).unwrap();
            for _ in 0..u.int_in_range(1..=2usize)? {
                art.add_to_clip(r, vec![random_polygon(u)?], rule, None)
                    .unwrap();
            }
            Some(r)
        } else {
            None
        };
        // Some shapes are painted with an opaque linear gradient (opaque, so
        // that at most one varying layer shows: every mean stays exact).
        let paint = match u.int_in_range(0..=3u8)? {
            0 => Paint::Gradient(random_gradient(u, false)?),
            _ => Paint::Solid(colour),
        };
        art.fill_paint(contours, rule, paint, &[], clip).unwrap();
    }
    Ok(art)
}

fn random_gradient(u: &mut Unstructured<'_>, radial: bool) -> ArbResult<Gradient> {
    let mut stops = Vec::new();
    let mut offset = 0.0;
    for _ in 0..u.int_in_range(1..=4usize)? {
        offset += f64::from(u.int_in_range(0..=4u8)?) / 10.0;
        let c = |u: &mut Unstructured<'_>| -> ArbResult<f64> {
            Ok(f64::from(u.int_in_range(0..=10u8)?) / 10.0)
        };
        stops.push(Stop {
            offset: offset.min(1.0),
            colour: [c(u)?, c(u)?, c(u)?],
            opacity: 1.0,
        });
    }
    let spread = *u.choose(&[Spread::Pad, Spread::Repeat, Spread::Reflect])?;
    let map = [1.0, 0.2, -0.3, 1.2, 0.05, -0.1];
    let p = |u: &mut Unstructured<'_>| -> ArbResult<f64> {
        Ok(f64::from(u.int_in_range(0..=10u8)?) / 10.0)
    };
    Ok(if radial {
        let (cx, cz) = (p(u)?, p(u)?);
        Gradient::radial(
            map,
            Circle {
                centre: [cx + 0.05, cz],
                radius: 0.0,
            },
            Circle {
                centre: [cx, cz],
                radius: 0.2 + p(u)?,
            },
            stops,
            spread,
            Interpolation::Srgb,
        )
        .unwrap()
    } else {
        let start = [p(u)?, p(u)?];
        Gradient::linear(
            map,
            start,
            [start[0] + 0.3, start[1] + 0.1],
            stops,
            spread,
            Interpolation::Srgb,
        )
        .unwrap()
    })
}

/// A radial gradient (focal point off centre, reflected, sRGB stops) over
/// the whole square: every fragment on the leaf grid integrates within the
/// packer's stated mean-error bound of dense point sampling.
#[test]
fn radial_gradient_integrals_are_within_the_stated_bound() {
    let stop = |offset: f64, colour: [f64; 3]| Stop {
        offset,
        colour,
        opacity: 1.0,
    };
    let g = Gradient::radial(
        [1.0, 0.2, -0.3, 1.2, 0.05, -0.1],
        Circle {
            centre: [0.45, 0.5],
            radius: 0.02,
        },
        Circle {
            centre: [0.5, 0.5],
            radius: 0.3,
        },
        vec![
            stop(0.0, [1.0, 0.5, 0.0]),
            stop(0.6, [0.0, 0.2, 1.0]),
            stop(1.0, [0.3, 0.9, 0.4]),
        ],
        Spread::Reflect,
        Interpolation::Srgb,
    )
    .unwrap();
    let mut art = VectorArt::new();
    let whole = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    art.fill_paint(
        vec![whole],
        FillRule::NonZero,
        Paint::Gradient(g.clone()),
        &[],
        None,
    )
    .unwrap();
    let options = VectorOptions {
        max_level: 8,
        tolerance: 0.01,
        ..VectorOptions::default()
    };
    let (t, report) = QuadTree::from_vector(&art, &options).unwrap();
    assert!(report.max_mean_error > 0.0, "radial means carry a bound");
    for (x0, z0, side) in [(0.0, 0.0, 1.0), (0.25, 0.5, 0.125), (0.5, 0.125, 0.25)] {
        let f = Fragment::new(x0, z0, x0 + side, z0 + side).unwrap();
        let got = t.weighted_colour(&f, u8::MAX).0;
        let n = 400;
        let mut want = [0.0; 4];
        for i in 0..n {
            for j in 0..n {
                let p = [
                    x0 + side * (i as f64 + 0.5) / n as f64,
                    z0 + side * (j as f64 + 0.5) / n as f64,
                ];
                for (w, c) in want.iter_mut().zip(g.colour_at(p)) {
                    *w += c * f.area() / (n * n) as f64;
                }
            }
        }
        // The sampler's own error: the colour moves by at most its range per cell.
        for ch in 0..4 {
            let bound = f.area() * (report.max_mean_error + STEP) + 2e-4 * f.area();
            assert!(
                (got[ch] - want[ch]).abs() <= bound,
                "{f:?} ch {ch}: tree {} sampled {} bound {bound}",
                got[ch],
                want[ch]
            );
        }
    }
}

/// A gradient interpolated in linear light over a rectangle: the integral
/// over any fragment is the overlap's area times the ramp at its centroid
/// (the ramp is linear in `x` between the stops), in closed form; and every
/// point of the art lies within the tolerance of its leaf's colour.
#[test]
fn linear_gradient_integrals_match_closed_forms() {
    let ramp = Gradient::linear(
        [1.0, 0.0, 0.0, 1.0, 0.0, 0.0],
        [0.125, 0.0],
        [0.875, 0.0],
        vec![
            Stop {
                offset: 0.0,
                colour: [0.3, 0.9, 0.2],
                opacity: 1.0,
            },
            Stop {
                offset: 1.0,
                colour: [0.9, 0.3, 0.2],
                opacity: 1.0,
            },
        ],
        Spread::Pad,
        Interpolation::Linear,
    )
    .unwrap();
    // Dyadic edges: only the ramp decides where squares stop splitting.
    let rect = vec![[0.125, 0.25], [0.875, 0.25], [0.875, 0.75], [0.125, 0.75]];
    let mut art = VectorArt::new();
    art.fill_paint(
        vec![rect],
        FillRule::NonZero,
        Paint::Gradient(ramp.clone()),
        &[],
        None,
    )
    .unwrap();
    let level = 12;
    for gradient_leaves in [false, true] {
        let options = VectorOptions {
            max_level: level,
            gradient_leaves,
            ..VectorOptions::default()
        };
        let (t, report) = QuadTree::from_vector(&art, &options).unwrap();
        assert_eq!(report.max_mean_error, 0.0);
        assert!(report.max_smooth_deviation <= options.tolerance);
        // The ramp stops splitting well above the maximum level; with gradient
        // leaves, at the rectangle's edges (level 3).
        assert!(t.stored_depth() < level, "depth {}", t.stored_depth());
        if gradient_leaves {
            assert_eq!(t.stored_depth(), 3);
            assert!(report.gradient_leaves > 0 && report.gradient_leaf_paints == 1);
        }
        let closed = |x0: f64, z0: f64, x1: f64, z1: f64| {
            let (a, b) = (x0.max(0.125), x1.min(0.875));
            let (c, d) = (z0.max(0.25), z1.min(0.75));
            if a >= b || c >= d {
                return [0.0; 4];
            }
            let area = (b - a) * (d - c);
            let w = (0.5 * (a + b) - 0.125) / 0.75;
            let red = 0.3 + 0.6 * w;
            [red * area, (1.2 - red) * area, 0.2 * area, area]
        };
        // The ramp's terminal squares are at level 9 (a quarter step of an
        // encoded slope ≤ 0.9 needs sides ≤ 2^-9): fragments on the level-6 grid
        // are unions of whole squares, whose stored means are exact.
        // With gradient leaves, any fragment: their integrals are exact.
        arbtest::arbtest(|u| {
            let cells = 1i32 << 6;
            let coord = |u: &mut Unstructured<'_>| -> ArbResult<f64> {
                if gradient_leaves {
                    return Ok(f64::from(u.int_in_range(-100_000..=1_100_000)?) / 1e6);
                }
                Ok(f64::from(u.int_in_range(-2..=cells + 2)?) / f64::from(cells))
            };
            let (a, b, c, d) = (coord(u)?, coord(u)?, coord(u)?, coord(u)?);
            let f = Fragment::new(a.min(b), c.min(d), a.max(b), c.max(d)).unwrap();
            let got = t.weighted_colour(&f, u8::MAX).0;
            let want = closed(f.x0(), f.z0(), f.x1(), f.z1());
            for ch in 0..4 {
                assert!(
                    (got[ch] - want[ch]).abs() <= f.area() * STEP + 1e-12,
                    "{f:?} ch {ch}: {} vs {}",
                    got[ch],
                    want[ch]
                );
            }
            // A point's leaf colour against the art there (sRGB-encoded).
            let p = [
                f64::from(u.int_in_range(126..=874u32)?) / 1000.0,
                f64::from(u.int_in_range(251..=749u32)?) / 1000.0,
            ];
            let h = 1e-9;
            let tiny = Fragment::new(p[0] - h, p[1] - h, p[0] + h, p[1] + h).unwrap();
            let leaf = t.weighted_colour(&tiny, u8::MAX).0.map(|v| v / tiny.area());
            let here = ramp.colour_at(p);
            for ch in 0..3 {
                let (e, w) = (srgb_encode(leaf[ch]), srgb_encode(here[ch]));
                let within = if gradient_leaves {
                    1e-6
                } else {
                    options.tolerance + 2e-4
                };
                assert!((e - w).abs() <= within, "{p:?} ch {ch}: leaf {e} art {w}");
            }
            Ok(())
        })
        .budget_ms(1500);
    }
}

fn random_polygon(u: &mut Unstructured<'_>) -> ArbResult<Vec<[f64; 2]>> {
    let n = u.int_in_range(3..=6usize)?;
    let mut c = Vec::new();
    for _ in 0..n {
        c.push([
            f64::from(u.int_in_range(-100..=1100i32)?) / 1000.0,
            f64::from(u.int_in_range(-100..=1100i32)?) / 1000.0,
        ]);
    }
    Ok(c)
}

/// Clip regions against closed-form areas: convex polygons intersected by
/// `ConvexPolygon` (independent of the packer's sweep): a shape within one
/// region, within a union of two, and within a region nested in another;
/// the rest of the square stays transparent.
#[test]
fn clipped_areas_match_convex_intersections() {
    let white = Rgba::opaque(1.0, 1.0, 1.0);
    let shape = rotated_rect(0.5, 0.5, 0.7, 0.4, 0.4);
    let b = regular_polygon(0.4, 0.45, 0.25, 7);
    let c = vec![[0.55, 0.3], [0.95, 0.5], [0.6, 0.9]];
    let convex = |p: &[[f64; 2]]| ConvexPolygon::hull(p);
    let (ps, pb, pc) = (convex(&shape), convex(&b), convex(&c));
    let both = |x: &ConvexPolygon, y: &ConvexPolygon| x.intersect(y).area();
    type MakeClip<'a> = Box<dyn Fn(&mut VectorArt) -> ClipId + 'a>;
    let cases: Vec<(&str, f64, MakeClip)> = vec![
        (
            "one region",
            both(&ps, &pb),
            Box::new(|art: &mut VectorArt| {
                let r = art.clip_region(&[]).unwrap();
                art.add_to_clip(r, vec![b.clone()], FillRule::NonZero, None)
                    .unwrap();
                r
            }),
        ),
        (
            "union of two",
            both(&ps, &pb) + both(&ps, &pc) - ps.intersect(&pb).intersect(&pc).area(),
            Box::new(|art: &mut VectorArt| {
                let r = art.clip_region(&[]).unwrap();
                art.add_to_clip(r, vec![b.clone()], FillRule::EvenOdd, None)
                    .unwrap();
                art.add_to_clip(r, vec![c.clone()], FillRule::NonZero, None)
                    .unwrap();
                r
            }),
        ),
        (
            "nested",
            ps.intersect(&pb).intersect(&pc).area(),
            Box::new(|art: &mut VectorArt| {
                let outer = art.clip_region(&[]).unwrap();
                art.add_to_clip(outer, vec![c.clone()], FillRule::NonZero, None)
                    .unwrap();
                let r = art.clip_region(&[outer]).unwrap();
                art.add_to_clip(r, vec![b.clone()], FillRule::NonZero, None)
                    .unwrap();
                r
            }),
        ),
        (
            "member clipped by its own region",
            ps.intersect(&pb).intersect(&pc).area(),
            Box::new(|art: &mut VectorArt| {
                let own = art.clip_region(&[]).unwrap();
                art.add_to_clip(own, vec![c.clone()], FillRule::NonZero, None)
                    .unwrap();
                let r = art.clip_region(&[]).unwrap();
                art.add_to_clip(r, vec![b.clone()], FillRule::NonZero, Some(own))
                    .unwrap();
                r
            }),
        ),
    ];
    for (name, area, make) in &cases {
        assert!(*area > 0.01, "{name}: degenerate case");
        for level in [5u8, 11] {
            let mut art = VectorArt::new();
            let clip = make(&mut art);
            art.fill_clipped(
                vec![shape.clone()],
                FillRule::NonZero,
                white,
                &[],
                Some(clip),
            )
            .unwrap();
            let t = pack(&art, level);
            for (ch, got) in total(&t).into_iter().enumerate() {
                assert!(
                    (got - area).abs() < 1e-9 + 4.0 * STEP,
                    "{name} at level {level}: channel {ch} integral {got} vs area {area}"
                );
            }
        }
    }
    // An empty region clips everything away.
    let mut art = VectorArt::new();
    let r = art.clip_region(&[]).unwrap();
    art.fill_clipped(vec![shape], FillRule::NonZero, white, &[], Some(r))
        .unwrap();
    assert_eq!(total(&pack(&art, 6)), [0.0; 4]);
}

#[test]
fn clip_regions_refuse_unknown_ids_and_deep_nesting() {
    let mut other = VectorArt::new();
    let foreign = other.clip_region(&[]).unwrap();
    let _ = other.clip_region(&[foreign]).unwrap();
    let mut art = VectorArt::new();
    assert!(art.clip_region(&[foreign]).is_err(), "unknown region");
    let mut r = art.clip_region(&[]).unwrap();
    let mut refused = false;
    for _ in 0..100 {
        match art.clip_region(&[r]) {
            Ok(next) => r = next,
            Err(e) => {
                assert!(e.to_string().contains("nested deeper"), "{e}");
                refused = true;
                break;
            }
        }
    }
    assert!(refused);
    // A region cannot be clipped, through another, by itself.
    let mut art = VectorArt::new();
    let a = art.clip_region(&[]).unwrap();
    let b = art.clip_region(&[]).unwrap();
    let square = vec![vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]];
    art.add_to_clip(a, square.clone(), FillRule::NonZero, Some(b))
        .unwrap();
    let e = art
        .add_to_clip(b, square.clone(), FillRule::NonZero, Some(a))
        .unwrap_err();
    assert!(e.to_string().contains("clipped by itself"), "{e}");
    assert!(
        art.add_to_clip(a, square, FillRule::NonZero, Some(a))
            .is_err()
    );
}

/// sRGB-encoded grey `g` as linear opaque colour.
fn grey(g: f64) -> Rgba {
    let v = quadtex_core::srgb_decode(g) as f32;
    Rgba::opaque(v, v, v)
}

#[test]
fn flat_masks_weight_areas_exactly() {
    use quadtex_core::BlendMode;
    use quadtex_core::MaskKind;
    let shape = rotated_rect(0.5, 0.5, 0.7, 0.4, 0.4);
    let b = regular_polygon(0.4, 0.45, 0.25, 7);
    let c = vec![[0.55, 0.3], [0.95, 0.5], [0.6, 0.9]];
    let convex = |p: &[[f64; 2]]| ConvexPolygon::hull(p);
    let (ps, pb, pc) = (convex(&shape), convex(&b), convex(&c));
    let red = Rgba::opaque(1.0, 0.0, 0.0);
    // Mask content: a white heptagon, then a mid grey (#808080) triangle on
    // top; luminance is 1 in the heptagon, 128/255 in the triangle.
    let g = 128.0 / 255.0;
    let both = ps.intersect(&pb).intersect(&pc).area();
    let only_b = ps.intersect(&pb).area() - both;
    let in_c = ps.intersect(&pc).area();
    for (kind, want) in [
        (MaskKind::Luminance, only_b + g * in_c),
        // Alpha: both are opaque, so the union counts fully.
        (MaskKind::Alpha, only_b + in_c),
    ] {
        for level in [5u8, 11] {
            let mut art = VectorArt::new();
            let m = art.begin_mask(kind).unwrap();
            art.fill(vec![b.clone()], FillRule::NonZero, grey(1.0), &[])
                .unwrap();
            art.fill(vec![c.clone()], FillRule::NonZero, grey(g), &[])
                .unwrap();
            art.end_mask(m).unwrap();
            let group = art.masked_group(1.0, BlendMode::Normal, &[m]).unwrap();
            art.fill(vec![shape.clone()], FillRule::NonZero, red, &[group])
                .unwrap();
            let (t, report) = QuadTree::from_vector(
                &art,
                &VectorOptions {
                    max_level: level,
                    ..VectorOptions::default()
                },
            )
            .unwrap();
            assert_eq!(report.max_mean_error, 0.0);
            let got = total(&t);
            assert!(
                (got[0] - want).abs() < 1e-9 + 4.0 * STEP,
                "{kind:?} at level {level}: red {} vs {want}",
                got[0]
            );
            assert!(got[1].abs() < 4.0 * STEP && got[2].abs() < 4.0 * STEP);
            assert!((got[3] - want).abs() < 1e-9 + 4.0 * STEP);
            // The point sampler agrees inside each region.
            // The triangle's centroid: inside the shape, outside the heptagon.
            let p = [0.7, 1.7 / 3.0];
            let at = art.colour_at(p);
            let expect = if kind == MaskKind::Luminance { g } else { 1.0 };
            assert!((at[0] - expect).abs() < 1e-9, "{at:?}");
        }
    }
}

#[test]
fn gradient_masks_stay_within_the_stated_bound() {
    use quadtex_core::BlendMode;
    use quadtex_core::MaskKind;
    // A black-to-white ramp across x masks a white square: the mean of the
    // luminance is the integral of the encoded ramp, ∫₀¹ t dt = 1/2, as
    // stops interpolate in sRGB.
    let stops = vec![
        Stop {
            offset: 0.0,
            colour: [0.0; 3],
            opacity: 1.0,
        },
        Stop {
            offset: 1.0,
            colour: [1.0; 3],
            opacity: 1.0,
        },
    ];
    let ramp = Gradient::linear(
        [1.0, 0.0, 0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0],
        [1.0, 0.0],
        stops,
        Spread::Pad,
        Interpolation::Srgb,
    )
    .unwrap();
    let mut art = VectorArt::new();
    let m = art.begin_mask(MaskKind::Luminance).unwrap();
    art.fill_paint(
        vec![rotated_rect(0.5, 0.5, 1.0, 1.0, 0.0)],
        FillRule::NonZero,
        Paint::Gradient(ramp),
        &[],
        None,
    )
    .unwrap();
    art.end_mask(m).unwrap();
    let group = art.masked_group(1.0, BlendMode::Normal, &[m]).unwrap();
    art.fill(
        vec![rotated_rect(0.5, 0.5, 1.0, 1.0, 0.0)],
        FillRule::NonZero,
        grey(1.0),
        &[group],
    )
    .unwrap();
    let (t, report) = QuadTree::from_vector(
        &art,
        &VectorOptions {
            max_level: 8,
            ..VectorOptions::default()
        },
    )
    .unwrap();
    // Each stored mean is within `max_mean_error` of its square's true mean,
    // so the whole is too; the coverage is exact in alpha.
    let got = total(&t)[3];
    assert!(report.max_mean_error > 0.0 && report.max_mean_error < 0.05);
    assert!(
        (got - 0.5).abs() <= report.max_mean_error + 1e-6,
        "{got} vs 0.5 (bound {})",
        report.max_mean_error
    );
    // The point sampler: the encoded ramp's value.
    assert!((art.colour_at([0.3, 0.5])[3] - 0.3).abs() < 1e-9);
}

#[test]
fn masks_refuse_misuse() {
    use quadtex_core::BlendMode;
    use quadtex_core::{MAX_MASK_DEPTH, MaskKind};
    let mut art = VectorArt::new();
    let m = art.begin_mask(MaskKind::Alpha).unwrap();
    let e = art.masked_group(1.0, BlendMode::Normal, &[m]).unwrap_err();
    assert!(e.to_string().contains("before its content ends"), "{e}");
    let inner = art.begin_mask(MaskKind::Alpha).unwrap();
    assert!(art.end_mask(m).is_err(), "not the innermost");
    art.end_mask(inner).unwrap();
    art.end_mask(m).unwrap();
    assert!(art.end_mask(m).is_err(), "ended twice");
    let mut deep = VectorArt::new();
    for _ in 0..MAX_MASK_DEPTH {
        deep.begin_mask(MaskKind::Luminance).unwrap();
    }
    assert!(deep.begin_mask(MaskKind::Luminance).is_err());
}

#[test]
fn leaves_crowded_with_edges_stay_exact() {
    // 900 small squares (3 600 edges) and a rotated frame over them, packed
    // at levels 0–2: each leaf holds far more edges than one sweep takes,
    // so it is swept quadrant by quadrant; coverage stays exact.
    let mut art = VectorArt::new();
    let mut area = 0.0;
    let mut contours = Vec::new();
    for i in 0..30 {
        for j in 0..30 {
            let (x, z) = (
                0.1 + 0.8 * f64::from(i) / 30.0,
                0.1 + 0.8 * f64::from(j) / 30.0,
            );
            let s = 0.8 / 30.0 * 0.6;
            contours.push(vec![[x, z], [x + s, z], [x + s, z + s], [x, z + s]]);
            area += s * s;
        }
    }
    art.fill(
        contours,
        FillRule::NonZero,
        Rgba::opaque(1.0, 0.0, 0.0),
        &[],
    )
    .unwrap();
    // A translucent green frame crossing many squares: overlaps composite.
    let outer = rotated_rect(0.5, 0.5, 0.7, 0.5, 0.3);
    let mut inner = rotated_rect(0.5, 0.5, 0.5, 0.3, 0.3);
    inner.reverse();
    art.fill(
        vec![outer.clone(), inner.clone()],
        FillRule::NonZero,
        Rgba::new(0.0, 0.5, 0.0, 0.5),
        &[],
    )
    .unwrap();
    let frame = ConvexPolygon::hull(&outer).area() - ConvexPolygon::hull(&inner).area();
    for level in [0u8, 1, 2] {
        let (t, report) = QuadTree::from_vector(
            &art,
            &VectorOptions {
                max_level: level,
                ..VectorOptions::default()
            },
        )
        .unwrap();
        assert!(report.max_leaf_edges <= 1024, "{}", report.max_leaf_edges);
        let got = total(&t);
        // Green: the frame's area at half; alpha: squares plus frame minus overlap.
        assert!(
            (got[1] - 0.5 * frame).abs() < 1e-9 + 8.0 * STEP,
            "level {level}: {got:?}"
        );
        // Red is covered by the frame at half: red = area − 0.5·overlap ≤ area.
        assert!(got[0] <= area + 8.0 * STEP && got[0] >= area - 0.5 * frame);
    }
    // Against point sampling at a deeper level: the same red.
    let deep = pack(&art, 9);
    let shallow = pack(&art, 1);
    let (a, b) = (total(&deep), total(&shallow));
    for ch in 0..4 {
        assert!(
            (a[ch] - b[ch]).abs() < 1e-9 + 8.0 * STEP,
            "channel {ch}: {a:?} vs {b:?}"
        );
    }
}

/// A reflected sRGB ramp with a translucent stop, under a translucent
/// triangle and over an opaque grey backdrop: squares inside the ramp's
/// rectangle are gradient leaves, affine in the ramp's colour.
fn layered_ramp_art() -> VectorArt {
    let ramp = Gradient::linear(
        [1.0, 0.0, 0.0, 1.0, 0.0, 0.0],
        [0.1, 0.0],
        [0.35, 0.3],
        vec![
            Stop {
                offset: 0.0,
                colour: [0.1, 0.2, 0.9],
                opacity: 1.0,
            },
            Stop {
                offset: 0.6,
                colour: [0.9, 0.8, 0.1],
                opacity: 0.4,
            },
            Stop {
                offset: 1.0,
                colour: [0.2, 0.9, 0.3],
                opacity: 1.0,
            },
        ],
        Spread::Reflect,
        Interpolation::Srgb,
    )
    .unwrap();
    let mut art = VectorArt::new();
    let square = |x0: f64, z0: f64, x1: f64, z1: f64| vec![[x0, z0], [x1, z0], [x1, z1], [x0, z1]];
    art.fill(
        vec![square(0.0, 0.0, 1.0, 1.0)],
        FillRule::NonZero,
        Rgba::new(0.2, 0.2, 0.2, 1.0),
        &[],
    )
    .unwrap();
    art.fill_paint(
        vec![square(0.05, 0.1, 0.95, 0.9)],
        FillRule::NonZero,
        Paint::Gradient(ramp),
        &[],
        None,
    )
    .unwrap();
    art.fill(
        vec![vec![[0.2, 0.15], [0.9, 0.3], [0.4, 0.85]]],
        FillRule::NonZero,
        Rgba::new(0.3, 0.05, 0.0, 0.5),
        &[],
    )
    .unwrap();
    art
}

/// Gradient leaves against the same art split to the tolerance: far fewer
/// nodes; fragment integrals and exact pixels (descending to terminal
/// squares and cells) within the tolerance of each other (linear colour
/// deviates at most 2.3× the sRGB-encoded tolerance, the encoding's
/// smallest slope being 0.44), and the fragment integrals of the leaves
/// exact against dense sampling of the art inside the rectangle.
#[test]
fn gradient_leaves_answer_like_the_split_tree_with_far_fewer_nodes() {
    let art = layered_ramp_art();
    let level = 10;
    let tree = |gradient_leaves: bool| {
        let options = VectorOptions {
            max_level: level,
            gradient_leaves,
            ..VectorOptions::default()
        };
        QuadTree::from_vector(&art, &options).unwrap()
    };
    let ((leafy, report), (split, _)) = (tree(true), tree(false));
    leafy.verify().unwrap();
    assert!(report.gradient_leaves > 100, "{report:?}");
    assert_eq!(leafy.depth(), level);
    assert!(
        leafy.node_count() * 4 < split.node_count(),
        "{} nodes with leaves, {} without",
        leafy.node_count(),
        split.node_count()
    );
    let tol = VectorOptions::default().tolerance;
    let (a, b) = (
        Texture::new(leafy.clone(), Wrap::default()),
        Texture::new(split.clone(), Wrap::default()),
    );
    let options = FilterOptions::default().with_level(30);
    arbtest::arbtest(|u| {
        let coord = |u: &mut Unstructured<'_>| -> ArbResult<f64> {
            Ok(f64::from(u.int_in_range(-100_000..=1_100_000)?) / 1e6)
        };
        let (x0, x1, z0, z1) = (coord(u)?, coord(u)?, coord(u)?, coord(u)?);
        let f = Fragment::new(x0.min(x1), z0.min(z1), x0.max(x1), z0.max(z1)).unwrap();
        let (p, q) = (
            leafy.weighted_colour(&f, u8::MAX).0,
            split.weighted_colour(&f, u8::MAX).0,
        );
        for ch in 0..4 {
            assert!(
                (p[ch] - q[ch]).abs() <= 2.5 * tol * f.area() + 1e-12,
                "{f:?} ch {ch}: {} vs {}",
                p[ch],
                q[ch]
            );
        }
        // A pixel-sized perspective footprint.
        let (cx, cz) = (coord(u)?, coord(u)?);
        let s = 10f64.powf(-1.0 - 2.0 * f64::from(u.int_in_range(0..=100u32)?) / 100.0);
        let k = 1.0 + f64::from(u.int_in_range(0..=100u32)?) / 100.0;
        let corners = [
            [cx - s, cz - s],
            [cx + s, cz - s],
            [cx + k * s, cz + k * s],
            [cx - k * s, cz + k * s],
        ];
        let Ok(fp) = Footprint::from_corners(corners) else {
            return Ok(());
        };
        let (ca, cb) = (a.filter(&fp, &options), b.filter(&fp, &options));
        for (x, y) in ca.to_array().into_iter().zip(cb.to_array()) {
            assert!(
                f64::from((x - y).abs()) <= 5.0 * tol + 1e-5,
                "{corners:?}: {ca:?} vs {cb:?}"
            );
        }
        Ok(())
    })
    .budget_ms(2000);
    // Exact against the art: a fragment inside the rectangle, off the
    // triangle, by dense midpoint sampling (smooth colour: O(h²)).
    let f = Fragment::new(0.06, 0.11, 0.19, 0.87).unwrap();
    let got = leafy.weighted_colour(&f, u8::MAX).0;
    let n = 1500;
    let mut sum = [0.0; 4];
    for i in 0..n {
        for j in 0..n {
            let x = f.x0() + (f.x1() - f.x0()) * (f64::from(i) + 0.5) / f64::from(n);
            let z = f.z0() + (f.z1() - f.z0()) * (f64::from(j) + 0.5) / f64::from(n);
            let c = art.colour_at([x, z]);
            for ch in 0..4 {
                sum[ch] += c[ch] * f.area() / f64::from(n * n);
            }
        }
    }
    for ch in 0..4 {
        assert!(
            (got[ch] - sum[ch]).abs() <= 1e-5 * f.area(),
            "ch {ch}: {} vs sampled {}",
            got[ch],
            sum[ch]
        );
    }
}

/// With gradient leaves, the nodes of a reflected ramp do not grow with its
/// slope (they follow the rectangle's edges, dyadic here so that they cost
/// a few levels); split to the tolerance, they grow with its square.
#[test]
fn gradient_leaf_cost_does_not_grow_with_slope() {
    let nodes = |periods: f64, gradient_leaves: bool| {
        let ramp = Gradient::linear(
            [1.0, 0.0, 0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0],
            [1.0 / periods, 0.0],
            vec![
                Stop {
                    offset: 0.0,
                    colour: [0.0, 0.0, 0.0],
                    opacity: 1.0,
                },
                Stop {
                    offset: 1.0,
                    colour: [1.0, 1.0, 1.0],
                    opacity: 1.0,
                },
            ],
            Spread::Reflect,
            Interpolation::Srgb,
        )
        .unwrap();
        let mut art = VectorArt::new();
        art.fill_paint(
            vec![vec![
                [0.125, 0.125],
                [0.875, 0.125],
                [0.875, 0.875],
                [0.125, 0.875],
            ]],
            FillRule::NonZero,
            Paint::Gradient(ramp),
            &[],
            None,
        )
        .unwrap();
        let options = VectorOptions {
            max_level: 12,
            gradient_leaves,
            ..VectorOptions::default()
        };
        QuadTree::from_vector(&art, &options)
            .unwrap()
            .0
            .node_count()
    };
    let (gentle, steep) = (nodes(0.125, true), nodes(0.5, true));
    let (split_gentle, split_steep) = (nodes(0.125, false), nodes(0.5, false));
    assert_eq!(gentle, steep);
    assert!(
        split_steep > 8 * split_gentle,
        "{split_gentle} → {split_steep}"
    );
    assert!(
        split_gentle > 10 * gentle,
        "{gentle} with leaves, {split_gentle} split"
    );
}

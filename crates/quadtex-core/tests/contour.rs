#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Contour leaves against closed-form areas at any magnification, against
//! the classic packer at its maximum level, and through the exact-pixel
//! filter.

use arbtest::arbitrary::{Result as ArbResult, Unstructured};
use quadtex_core::{
    FillRule, FilterOptions, Footprint, Fragment, QuadTree, Rgba, Texture, VectorArt,
    VectorOptions, Wrap,
};

type Point = [f64; 2];

/// Half a 16-bit step: what a stored (rounded) mean may be off by.
const STEP: f64 = 0.5 / 65535.0;

fn pack(art: &VectorArt, max_level: u8, contour_leaves: Option<usize>) -> QuadTree {
    let options = VectorOptions {
        max_level,
        contour_leaves,
        ..VectorOptions::default()
    };
    let (tree, _) = QuadTree::from_vector(art, &options).unwrap();
    tree.verify().unwrap();
    tree
}

/// The part of polygon `poly` inside `[x0, x1) × [z0, z1)`: Sutherland–
/// Hodgman, written here independently of the library's clipper.
fn clip(poly: &[Point], [x0, z0, x1, z1]: [f64; 4]) -> Vec<Point> {
    let mut out = poly.to_vec();
    let planes: [(usize, f64, f64); 4] = [(0, x0, 1.0), (0, x1, -1.0), (1, z0, 1.0), (1, z1, -1.0)];
    for (axis, bound, sign) in planes {
        let input = std::mem::take(&mut out);
        let inside = |p: &Point| sign * (p[axis] - bound) >= 0.0;
        for i in 0..input.len() {
            let (a, b) = (input[(i + input.len() - 1) % input.len()], input[i]);
            if inside(&a) != inside(&b) {
                let t = (bound - a[axis]) / (b[axis] - a[axis]);
                let mut p = a;
                p[axis] = bound;
                p[1 - axis] = a[1 - axis] + t * (b[1 - axis] - a[1 - axis]);
                out.push(p);
            }
            if inside(&b) {
                out.push(b);
            }
        }
    }
    out
}

fn area(poly: &[Point]) -> f64 {
    let Some(&o) = poly.first() else {
        return 0.0;
    };
    let n = poly.len();
    0.5 * (0..n)
        .map(|i| {
            let (p, q) = (poly[i], poly[(i + 1) % n]);
            (p[0] - o[0]) * (q[1] - o[1]) - (q[0] - o[0]) * (p[1] - o[1])
        })
        .sum::<f64>()
        .abs()
}

fn regular(n: usize, centre: Point, r: f64) -> Vec<Point> {
    (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / n as f64 + 0.1;
            [centre[0] + r * a.cos(), centre[1] + r * a.sin()]
        })
        .collect()
}

/// A fragment from `u`: a centre anywhere around the shapes, a size from
/// 1e-9 to 0.5 (log-uniform), sometimes zero-area or dyadic.
fn fragment(u: &mut Unstructured<'_>) -> ArbResult<Fragment> {
    let unit = |u: &mut Unstructured<'_>| -> ArbResult<f64> {
        Ok(f64::from(u.int_in_range(0..=1_000_000u32)?) / 1e6)
    };
    let (cx, cz) = (unit(u)? * 1.2 - 0.1, unit(u)? * 1.2 - 0.1);
    let (w, h) = (
        10f64.powf(-9.0 + 8.7 * unit(u)?),
        10f64.powf(-9.0 + 8.7 * unit(u)?),
    );
    Ok(match u.int_in_range(0..=9u8)? {
        0 => Fragment::new(cx, cz, cx, cz + h).unwrap(),
        1 => {
            let k = f64::from(1u32 << u.int_in_range(1..=12u8)?);
            let (x, z) = ((cx * k).floor() / k, (cz * k).floor() / k);
            Fragment::new(x, z, x + 1.0 / k, z + 1.0 / k).unwrap()
        }
        _ => Fragment::new(cx - w / 2.0, cz - h / 2.0, cx + w / 2.0, cz + h / 2.0).unwrap(),
    })
}

/// A rectangle, a triangle and a 4096-gon, each alone in its tree: every
/// fragment, down to 1e-9 of the texture, against the closed-form area of
/// its intersection with the shape.
#[test]
fn contour_leaves_match_closed_form_areas_at_any_magnification() {
    let shapes: [(&str, Vec<Point>); 3] = [
        (
            "rectangle",
            vec![[0.1234, 0.2], [0.7, 0.2], [0.7, 0.8111], [0.1234, 0.8111]],
        ),
        ("triangle", vec![[0.05, 0.1], [0.93, 0.31], [0.4, 0.97]]),
        ("4096-gon", regular(4096, [0.5, 0.47], 0.41)),
    ];
    for (name, shape) in shapes {
        let mut art = VectorArt::new();
        art.fill(
            vec![shape.clone()],
            FillRule::NonZero,
            Rgba::new(0.2, 0.5, 0.7, 1.0),
            &[],
        )
        .unwrap();
        let tree = pack(&art, 10, Some(16));
        let leaves = tree.contour_leaves().expect("contour leaves");
        assert!(leaves.count() > 0 && tree.depth() == 30, "{name}");
        arbtest::arbtest(|u| {
            let f = fragment(u)?;
            let got = tree.weighted_colour(&f, u8::MAX).0;
            let covered = area(&clip(&shape, [f.x0(), f.z0(), f.x1(), f.z1()]));
            let want = [0.2, 0.5, 0.7, 1.0].map(|c| c * covered);
            for ch in 0..4 {
                assert!(
                    (got[ch] - want[ch]).abs() <= 2.0 * STEP * f.area() + 1e-7 * f.area() + 1e-15,
                    "{name} {f:?} ch {ch}: {} vs {} (area {})",
                    got[ch],
                    want[ch],
                    f.area()
                );
            }
            Ok(())
        })
        .budget_ms(700);
    }
}

/// Random overlapping translucent polygons (nonzero and even-odd, some in
/// nested translucent groups): on the
/// grid of the maximum level both trees hold exact means of the same art,
/// so they agree to rounding; with contour leaves there are far fewer
/// nodes than the classic tree at that level.
#[test]
fn contour_leaves_agree_with_the_classic_packer_at_its_level() {
    arbtest::arbtest(|u| {
        let mut art = VectorArt::new();
        // Shapes from `grouped` on sit in a translucent group, the last of
        // them possibly in a second group inside it.
        let shapes = u.int_in_range(1..=4u8)?;
        let grouped = u.int_in_range(0..=shapes)?;
        let outer = art
            .group(f64::from(u.int_in_range(1..=4u8)?) / 4.0)
            .unwrap();
        let inner = art
            .group(f64::from(u.int_in_range(1..=4u8)?) / 4.0)
            .unwrap();
        let nest = u.arbitrary::<bool>()?;
        for shape in 0..shapes {
            let n = u.int_in_range(3..=7usize)?;
            let mut poly = Vec::new();
            for _ in 0..n {
                poly.push([
                    f64::from(u.int_in_range(-100..=1100i32)?) / 1000.0,
                    f64::from(u.int_in_range(-100..=1100i32)?) / 1000.0,
                ]);
            }
            let a = f64::from(u.int_in_range(1..=4u8)?) / 4.0;
            let c = [(); 3].map(|_| u.int_in_range(0..=4u8).map(|v| f64::from(v) / 4.0 * a));
            let [Ok(r), Ok(g), Ok(b)] = c else {
                return Ok(());
            };
            let rule = if u.arbitrary()? {
                FillRule::EvenOdd
            } else {
                FillRule::NonZero
            };
            let groups: &[quadtex_core::GroupId] = match shape {
                s if s + 1 == shapes && s >= grouped && nest => &[outer, inner],
                s if s >= grouped => &[outer],
                _ => &[],
            };
            art.fill(
                vec![poly],
                rule,
                Rgba::new(r as f32, g as f32, b as f32, a as f32),
                groups,
            )
            .unwrap();
        }
        let level = 7;
        let (classic, leafy) = (pack(&art, level, None), pack(&art, level, Some(12)));
        let cells = 1u32 << level;
        for _ in 0..8 {
            let i = [(); 4].map(|_| u.int_in_range(0..=cells).unwrap_or(0));
            let f = Fragment::new(
                f64::from(i[0].min(i[1])) / f64::from(cells),
                f64::from(i[2].min(i[3])) / f64::from(cells),
                f64::from(i[0].max(i[1])) / f64::from(cells),
                f64::from(i[2].max(i[3])) / f64::from(cells),
            )
            .unwrap();
            let (p, q) = (
                classic.weighted_colour(&f, u8::MAX).0,
                leafy.weighted_colour(&f, u8::MAX).0,
            );
            for ch in 0..4 {
                assert!(
                    (p[ch] - q[ch]).abs() <= 2.0 * STEP * f.area() + 1e-12,
                    "{f:?} ch {ch}: classic {} contour {}",
                    p[ch],
                    q[ch]
                );
            }
        }
        Ok(())
    })
    .budget_ms(2500);
}

/// Through the exact-pixel filter (box, descending to the tree's depth or
/// the cells' end): a magnified and an ordinary footprint over a star of
/// thin spikes agree with the classic tree at level 12 within the bounds
/// the two report and the classic tree's pixel size.
#[test]
fn exact_pixels_over_contour_leaves() {
    let star: Vec<Point> = (0..64)
        .map(|i| {
            let a = std::f64::consts::TAU * f64::from(i) / 64.0;
            let r = if i % 2 == 0 { 0.45 } else { 0.05 };
            [0.5 + r * a.cos(), 0.5 + r * a.sin()]
        })
        .collect();
    let mut art = VectorArt::new();
    art.fill(
        vec![star.clone()],
        FillRule::NonZero,
        Rgba::new(1.0, 1.0, 1.0, 1.0),
        &[],
    )
    .unwrap();
    let leafy = Texture::new(pack(&art, 8, Some(16)), Wrap::default());
    let options = FilterOptions::default();
    // A pixel 1e-6 wide straddling a spike's edge: the exact coverage.
    let (a, b) = (star[0], star[1]);
    let mid = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
    let s = 1e-6;
    let corners = [
        [mid[0] - s, mid[1] - s],
        [mid[0] + s, mid[1] - s],
        [mid[0] + s, mid[1] + s],
        [mid[0] - s, mid[1] + s],
    ];
    let fp = Footprint::from_corners(corners).unwrap();
    let got = leafy.filter(&fp, &options).to_array()[3];
    let want = area(&clip(
        &star,
        [mid[0] - s, mid[1] - s, mid[0] + s, mid[1] + s],
    )) / (4.0 * s * s);
    assert!(
        (f64::from(got) - want).abs() < 2e-3,
        "coverage {got} against {want}"
    );
    assert!(
        want > 0.2 && want < 0.8,
        "the pixel straddles the edge: {want}"
    );
}

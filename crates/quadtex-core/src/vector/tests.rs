use super::art::Point;
use super::pack::sweep::SWEEP_FLOOR;
use super::pack::{Square, clip_to_square, on_border};
use super::*;
use crate::geometry::{FillRule, signed_area, winding};
use crate::{Error, QuadTree, Rgba};

fn rect(x0: f64, z0: f64, x1: f64, z1: f64) -> Vec<[f64; 2]> {
    vec![[x0, z0], [x1, z0], [x1, z1], [x0, z1]]
}

fn clipped(points: &[Point], sq: Square) -> Vec<Point> {
    let mut out = vec![[9.0, 9.0]];
    clip_to_square(points, sq, &mut [Vec::new(), Vec::new()], &mut out);
    // Appended after what `out` held.
    assert_eq!(out[0], [9.0, 9.0]);
    out.split_off(1)
}

#[test]
fn winding_of_counter_clockwise_square_is_one() {
    let r = rect(0.0, 0.0, 1.0, 1.0);
    assert_eq!(winding(&r, [0.5, 0.5]), 1);
    assert_eq!(winding(&r, [1.5, 0.5]), 0);
    let mut cw = r.clone();
    cw.reverse();
    assert_eq!(winding(&cw, [0.5, 0.5]), -1);
    assert!(signed_area(&r) > 0.0);
}

#[test]
fn clipping_keeps_the_winding_inside() {
    let sq = Square {
        x0: 0.25,
        z0: 0.25,
        side: 0.25,
    };
    // A big square around `sq` clips to `sq`'s border: winding 1.
    let c = clipped(&rect(0.0, 0.0, 1.0, 1.0), sq);
    assert!(on_border(&c, sq));
    assert_eq!((signed_area(&c) / (0.25 * 0.25)).round(), 1.0);
    // A triangle whose hypotenuse is the square's diagonal keeps inner edges.
    let sq = Square {
        x0: 0.375,
        z0: 0.375,
        side: 0.25,
    };
    let t = vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
    let c = clipped(&t, sq);
    assert!(!on_border(&c, sq));
    assert!((signed_area(&c) - 0.25 * 0.25 / 2.0).abs() < 1e-15);
}

fn disc(cx: f64, cz: f64, r: f64, n: usize) -> Vec<[f64; 2]> {
    (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            [cx + r * a.cos(), cz + r * a.sin()]
        })
        .collect()
}

/// The estimate bounds the nodes built from above, and closely (within
/// 1.6× for these outlines); the byte estimate is within 6× of the
/// finished tree's `memory_bytes` (30 bytes a node for the build's peak
/// against ~8.3 for the tree).
#[test]
fn node_estimate_bounds_the_tree_closely() {
    let mut art = VectorArt::new();
    let white = Rgba::opaque(1.0, 1.0, 1.0);
    // A full-canvas background (its edges lie on grid lines: no splits), a
    // disc, a triangle and a translucent square partly outside the canvas.
    art.fill(
        vec![rect(0.0, 0.0, 1.0, 1.0)],
        FillRule::NonZero,
        Rgba::opaque(0.2, 0.2, 0.2),
        &[],
    )
    .unwrap();
    art.fill(
        vec![disc(0.4, 0.5, 0.3, 400)],
        FillRule::NonZero,
        white,
        &[],
    )
    .unwrap();
    art.fill(
        vec![vec![[0.1, 0.1], [0.9, 0.2], [0.5, 0.95]]],
        FillRule::EvenOdd,
        white,
        &[],
    )
    .unwrap();
    let g = art.group(0.5).unwrap();
    art.fill(
        vec![rect(0.7, -0.2, 1.3, 0.4)],
        FillRule::NonZero,
        white,
        &[g],
    )
    .unwrap();
    for level in [4u8, 8, 10, 12] {
        let (tree, _) = QuadTree::from_vector(
            &art,
            &VectorOptions {
                max_level: level,
                ..VectorOptions::default()
            },
        )
        .unwrap();
        let built: Vec<u64> = tree.level_stats().iter().map(|l| l.nodes).collect();
        let estimate = art.estimate_level_nodes(level);
        for (l, (&b, &e)) in built.iter().zip(&estimate).enumerate() {
            assert!(e >= b, "level {l} of {level}: estimate {e} < built {b}");
        }
        let (b, e) = (
            tree.node_count() as f64,
            estimate.iter().sum::<u64>() as f64,
        );
        assert!(e <= 1.6 * b, "level {level}: estimate {e} vs {b} nodes");
        let bytes = art.estimate_build_bytes(level) as f64;
        let tree_bytes = tree.memory_bytes() as f64;
        assert!(
            bytes >= tree_bytes && bytes <= 6.0 * tree_bytes,
            "level {level}: {bytes} vs {tree_bytes}"
        );
    }
}

#[test]
fn budget_refuses_before_building() {
    let mut art = VectorArt::new();
    art.fill(
        vec![disc(0.5, 0.5, 0.4, 1000)],
        FillRule::NonZero,
        Rgba::opaque(1.0, 0.0, 0.0),
        &[],
    )
    .unwrap();
    let options = VectorOptions {
        max_level: 24,
        max_bytes: Some(1 << 30),
        ..VectorOptions::default()
    };
    let start = std::time::Instant::now();
    let e = QuadTree::from_vector(&art, &options).unwrap_err();
    assert!(start.elapsed() < std::time::Duration::from_secs(5));
    let Error::MemoryBudget {
        estimate, budget, ..
    } = &e
    else {
        panic!("{e}")
    };
    // The disc's outline, 2.5 units long, crosses ~2.5 · 2^24 squares at level 24 alone.
    assert!(*estimate > 4 * 30 * (2 << 24), "{e}");
    assert_eq!(*budget, 1 << 30);
    assert!(
        e.to_string()
            .starts_with("packing at level 24 needs an estimated"),
        "{e}"
    );
    // A budget the estimate fits builds.
    let fits = VectorOptions {
        max_level: 8,
        max_bytes: Some(art.estimate_build_bytes(8)),
        ..VectorOptions::default()
    };
    assert!(QuadTree::from_vector(&art, &fits).is_ok());
}

#[test]
fn half_covered_leaf_is_half_the_colour() {
    let mut art = VectorArt::new();
    art.fill(
        vec![vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]],
        FillRule::NonZero,
        Rgba::opaque(1.0, 1.0, 1.0),
        &[],
    )
    .unwrap();
    let (t, report) = QuadTree::from_vector(
        &art,
        &VectorOptions {
            max_level: 3,
            ..VectorOptions::default()
        },
    )
    .unwrap();
    assert_eq!(report.swept_leaves, 8, "the diagonal crosses 8 leaves");
    let a = t.average().to_array();
    assert!((f64::from(a[3]) - 0.5).abs() < 1e-4, "{a:?}");
}

/// 1600 wedges meeting in the centre of the square: no split separates
/// them there, so the squares at the sweep's floor around that point
/// take their centre's colour and report their share as the bound.
#[test]
fn edges_converging_on_a_point_stop_at_the_sweep_floor_with_a_bound() {
    let (n, r) = (1600, 0.4);
    let period = std::f64::consts::TAU / f64::from(n);
    let wedges = (0..n)
        .map(|i| {
            let a = f64::from(i) * period;
            let b = a + 0.5 * period;
            vec![
                [0.5, 0.5],
                [0.5 + r * a.cos(), 0.5 + r * a.sin()],
                [0.5 + r * b.cos(), 0.5 + r * b.sin()],
            ]
        })
        .collect();
    let mut art = VectorArt::new();
    art.fill(wedges, FillRule::NonZero, Rgba::opaque(1.0, 1.0, 1.0), &[])
        .unwrap();
    let (t, report) = QuadTree::from_vector(
        &art,
        &VectorOptions {
            max_level: 0,
            ..VectorOptions::default()
        },
    )
    .unwrap();
    let exact = f64::from(n) * 0.5 * r * r * (0.5 * period).sin();
    let a = f64::from(t.average().to_array()[3]);
    assert!((a - exact).abs() <= 1.0 / 65535.0, "{a} vs {exact}");
    // Floor squares near the centre only, 4^-20 of the leaf each.
    let floor = 64.0 * 0.25f64.powi(i32::from(SWEEP_FLOOR));
    assert!(
        report.max_mean_error > 0.0 && report.max_mean_error <= floor * (1.0 + 1e-9),
        "{} against {floor}",
        report.max_mean_error
    );
}

#[test]
fn sweep_work_is_counted_and_its_budget_refuses_art_beyond_it() {
    // Thin slanted bars crossing each other in one leaf: a sweep with
    // many crossings.
    let bars = (0..40)
        .map(|i| {
            let x = 0.1 + 0.02 * f64::from(i);
            let lean = if i % 2 == 0 { 0.3 } else { -0.3 };
            vec![
                [x, 0.1],
                [x + 0.01, 0.1],
                [x + 0.01 + lean, 0.9],
                [x + lean, 0.9],
            ]
        })
        .collect();
    let mut art = VectorArt::new();
    art.fill(bars, FillRule::NonZero, Rgba::opaque(0.2, 0.6, 1.0), &[])
        .unwrap();
    let options = |max_sweep_work| VectorOptions {
        max_level: 1,
        max_sweep_work,
        ..VectorOptions::default()
    };
    let (tree, report) = QuadTree::from_vector(&art, &options(u64::MAX)).unwrap();
    let needed = report.sweep_work;
    assert!(needed > 1000, "{needed}");
    let (same, again) = QuadTree::from_vector(&art, &options(needed)).unwrap();
    assert_eq!(again.sweep_work, needed);
    assert_eq!(same.average(), tree.average());
    match QuadTree::from_vector(&art, &options(needed - 1)) {
        Err(
            e @ Error::SweepWork {
                needed: at_least,
                max,
            },
        ) => {
            assert_eq!(max, needed - 1);
            assert!(at_least > max && at_least <= needed, "{at_least}");
            assert!(e.to_string().contains("max sweep work"), "{e}");
        }
        other => panic!("{other:?}"),
    }
}

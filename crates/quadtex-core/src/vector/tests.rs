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

/// Discs side by side, each a 2000-gon: flat art whose squares split only
/// where more than a contour leaf's edges meet.
fn discs() -> VectorArt {
    let mut art = VectorArt::new();
    for i in 0..4 {
        for j in 0..4 {
            let (cx, cz) = (0.125 + 0.25 * f64::from(i), 0.125 + 0.25 * f64::from(j));
            art.fill(
                vec![disc(cx, cz, 0.1, 2000)],
                FillRule::NonZero,
                Rgba::opaque(0.1 * i as f32, 0.2 * j as f32, 0.5),
                &[],
            )
            .unwrap();
        }
    }
    art
}

/// With contour leaves the estimate simulates the subdivision: close to
/// what is built (nodes at 30 bytes, contour points at 40, leaves at 200,
/// the art's points at 32 for clipping), and far below the estimate of a
/// tree without them, which splits every square an edge crosses.
#[test]
fn contour_estimate_follows_what_is_built() {
    let art = discs();
    for (level, edges) in [(12u8, 16usize), (20, 16), (20, 64)] {
        let options = VectorOptions {
            max_level: level,
            contour_leaves: Some(edges),
            ..VectorOptions::default()
        };
        let (tree, report) = QuadTree::from_vector(&art, &options).unwrap();
        let built = tree.node_count() as f64 * 30.0
            + report.contour_leaf_points as f64 * 40.0
            + report.contour_leaves as f64 * 200.0
            + art.point_count() as f64 * 32.0;
        let estimate = art.estimate_bytes(&options) as f64;
        assert!(
            (0.8..1.3).contains(&(estimate / built)),
            "level {level}, {edges} edges: estimate {estimate} vs {built}"
        );
        if level == 20 {
            let classic = art.estimate_build_bytes(level) as f64;
            assert!(classic > 100.0 * estimate, "{classic} vs {estimate}");
        }
        // Per level, as one pass gives them, the same.
        let per_level = art.estimate_bytes_per_level(level, Some(edges), None);
        assert_eq!(per_level[usize::from(level)], estimate as u64);
    }
}

/// Settings the caller left open are changed until the estimate fits:
/// the level lowered (not below `MIN_FITTED_LEVEL`), the contour-leaf
/// edge budget raised; fixed settings are refused as `from_vector` does.
#[test]
fn fitting_the_budget_changes_only_what_was_left_open() {
    let art = discs();
    let asked = VectorOptions {
        max_level: 20,
        contour_leaves: Some(16),
        ..VectorOptions::default()
    };
    let at = |level, edges| {
        art.estimate_bytes(&VectorOptions {
            max_level: level,
            contour_leaves: Some(edges),
            ..asked
        })
    };
    let budget = at(20, 64);
    assert!(at(20, 16) > budget && at(20, 32) > budget);
    let options = VectorOptions {
        max_bytes: Some(budget),
        ..asked
    };
    let strict = QuadTree::from_vector(&art, &options).unwrap_err();
    assert!(
        strict
            .to_string()
            .starts_with("packing at level 20 needs an estimated"),
        "{strict}"
    );
    let fixed = QuadTree::from_vector_within(&art, &options, Adjustable::NONE).unwrap_err();
    assert_eq!(fixed.to_string(), strict.to_string());
    let edges = Adjustable {
        max_level: false,
        contour_edges: true,
    };
    let (tree, report, fit) = QuadTree::from_vector_within(&art, &options, edges).unwrap();
    assert_eq!((fit.max_level, fit.contour_leaves), (20, Some(64)));
    assert_eq!(fit.asked, Some((20, Some(16), at(20, 16))));
    assert_eq!(fit.estimate, Some(budget));
    assert!(fit.changed() && report.contour_leaves > 0);
    let (same, _) = QuadTree::from_vector(
        &art,
        &VectorOptions {
            contour_leaves: Some(64),
            ..asked
        },
    )
    .unwrap();
    assert_eq!(tree.node_count(), same.node_count());
    // The level alone, down to the floor: nothing fits under 1 KiB.
    let level = Adjustable {
        max_level: true,
        contour_edges: false,
    };
    let tiny = VectorOptions {
        max_bytes: Some(1024),
        ..asked
    };
    let e = QuadTree::from_vector_within(&art, &tiny, level).unwrap_err();
    assert!(
        e.to_string().starts_with(&format!(
            "packing at level 20 (and at every level down to {MIN_FITTED_LEVEL}) needs an estimated"
        )),
        "{e}"
    );
    // Without a budget nothing is estimated or changed.
    let (_, _, free) = QuadTree::from_vector_within(&art, &asked, level).unwrap();
    assert_eq!(
        (free.max_level, free.estimate, free.asked),
        (20, None, None)
    );
}

/// Contour leaves report the squares at the max level they could not keep
/// (more edges than a leaf may hold there): 1600 wedges meet at the centre.
#[test]
fn crowded_squares_at_the_max_level_are_reported() {
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
    let options = VectorOptions {
        max_level: 8,
        contour_leaves: Some(16),
        ..VectorOptions::default()
    };
    let (_, report) = QuadTree::from_vector(&art, &options).unwrap();
    // The squares around the centre, within about five squares of it:
    // there more than 256 edges (the wedges' sides, and the runs that
    // clipping adds along the squares' borders) crowd one square.
    assert!((4..=120).contains(&report.crowded_leaves), "{report:?}");
    let (_, plain) = QuadTree::from_vector(&discs(), &options).unwrap();
    assert_eq!(plain.crowded_leaves, 0);
}

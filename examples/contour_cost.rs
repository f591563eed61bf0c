//! What contour leaves cost and save on `samples/threshold.svg` and
//! `samples/star.svg`: memory, file size and pack time of the classic tree
//! at levels 12 and 16 against trees with contour leaves (as `quadtex pack
//! --contour-leaves` makes them: curves within 2^-22 of the texture, max
//! level 20; one row with the level-12 flattening, 2^-16, for
//! comparison), then the median time of a fragment query at the `quadtex
//! bench` widths (1, 4 and 16 level-12 texels) and magnified (10^-6 and
//! 10^-9 of the texture wide), every tree timed in the same run. Last,
//! packing time against edge length: slanted stripes and concentric
//! rings, doubling in number.
//!
//! `cargo run --release --example contour_cost`
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::time::Instant;

use quadtex_core::{CONTOUR_CURVE_TOLERANCE, CONTOUR_MAX_LEVEL};
use quadtex_core::{FillRule, Fragment, QuadTree, Rgba, VectorArt, VectorOptions};
use quadtex_io::Limits;

fn main() {
    let limits = Limits::default();
    for name in ["samples/threshold.svg", "samples/star.svg"] {
        let art = quadtex_io::load_svg(
            Path::new(name),
            &quadtex_io::SvgOptions::at_level(12).with_limits(limits),
        )
        .unwrap();
        println!("\n{name}");
        println!(
            "| tree | nodes | contour leaves | most edges in a leaf | memory | file | pack s |"
        );
        println!("|---|---:|---:|---:|---:|---:|---:|");
        let mut trees = Vec::new();
        let fine = quadtex_io::load_svg(
            Path::new(name),
            &quadtex_io::SvgOptions::default()
                .with_curve_tolerance(CONTOUR_CURVE_TOLERANCE)
                .with_limits(limits),
        )
        .unwrap();
        let art16 = quadtex_io::load_svg(
            Path::new(name),
            &quadtex_io::SvgOptions::at_level(16).with_limits(limits),
        )
        .unwrap();
        for (label, level, budget, art) in [
            ("level 12", 12, None, &art),
            ("level 16", 16, None, &art16),
            ("contour ≤ 16, curves 2^-16, level 12", 12, Some(16), &art),
            ("contour ≤ 8", CONTOUR_MAX_LEVEL, Some(8), &fine),
            ("contour ≤ 16", CONTOUR_MAX_LEVEL, Some(16), &fine),
            ("contour ≤ 32", CONTOUR_MAX_LEVEL, Some(32), &fine),
        ] {
            let options = VectorOptions {
                max_level: level,
                contour_leaves: budget,
                ..VectorOptions::default()
            };
            let start = Instant::now();
            let (tree, report) = QuadTree::from_vector(art, &options).unwrap();
            let secs = start.elapsed().as_secs_f64();
            let file =
                std::env::temp_dir().join(format!("contour-cost-{}.qtx", std::process::id()));
            quadtex_io::write_qtx(&file, &tree, None).unwrap();
            let file_bytes = std::fs::metadata(&file).unwrap().len();
            std::fs::remove_file(&file).ok();
            println!(
                "| {label} | {} | {} | {} | {:.2} MiB | {:.2} MiB | {secs:.2} |",
                tree.node_count(),
                report.contour_leaves,
                tree.contour_leaves().map_or(0, |c| c.max_leaf_edges()),
                tree.memory_bytes() as f64 / (1 << 20) as f64,
                file_bytes as f64 / (1 << 20) as f64,
            );
            trees.push((label, tree));
        }
        for (k, what) in [
            (
                u8::MAX,
                "exact (every tree to its depth: contour leaves to level 30)",
            ),
            (
                12,
                "at matched level 12 (k = 12: squares below it count at their mean)",
            ),
        ] {
            println!(
                "\nmedian ns per fragment query, {what} (same run; 20 000 random fragments, 5 rounds)"
            );
            print!("| width |");
            for (label, _) in &trees {
                print!(" {label} |");
            }
            println!();
            println!("|---|{}", "---:|".repeat(trees.len()));
            for width in [1.0 / 4096.0, 4.0 / 4096.0, 16.0 / 4096.0, 1e-6, 1e-9] {
                let fragments = fragments(width);
                print!("| {width:.3e} |");
                for (_, tree) in &trees {
                    let mut rounds: Vec<f64> = (0..5)
                        .map(|_| {
                            let start = Instant::now();
                            let mut sink = 0.0;
                            for f in &fragments {
                                sink += tree.weighted_colour(f, k).0[3];
                            }
                            std::hint::black_box(sink);
                            start.elapsed().as_secs_f64() * 1e9 / fragments.len() as f64
                        })
                        .collect();
                    rounds.sort_by(f64::total_cmp);
                    print!(" {:.0} |", rounds[2]);
                }
                println!();
            }
        }
    }
    pack_time_against_edge_length();
}

/// 20 000 fragments `width` wide at random places in the texture.
fn fragments(width: f64) -> Vec<Fragment> {
    (0..20_000u64)
        .map(|i| {
            let h = |k: u64| {
                let mut x = i.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ k;
                x ^= x >> 31;
                x = x.wrapping_mul(0xbf58_476d_1ce4_e5b9);
                (x >> 11) as f64 / (1u64 << 53) as f64
            };
            let (x, z) = (h(1) * (1.0 - width), h(2) * (1.0 - width));
            Fragment::new(x, z, x + width, z + width).unwrap()
        })
        .collect()
}

/// Pack time of contour-leaf trees (budget 16, max level 20) on art whose
/// edge length doubles at a fixed density: `k` slanted stripes 1/1024
/// apart, `k` rings (two 256-gons, radii 0.006 and 0.01) on a 32 × 32 grid.
fn pack_time_against_edge_length() {
    println!("\npack time against edge length (contour leaves ≤ 16, max level 20; median of 5)");
    println!(
        "| art | k | edge length (texture sides) | leaves | nodes | pack ms | µs per unit length |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for kind in ["stripes", "rings"] {
        for k in [32u32, 64, 128, 256, 512, 1024]
            .into_iter()
            .filter(|&k| kind == "rings" || k <= 512)
        {
            let mut art = VectorArt::new();
            let mut length = 0.0;
            let perimeter = |c: &[[f64; 2]]| -> f64 {
                (0..c.len())
                    .map(|i| {
                        let (a, b) = (c[i], c[(i + 1) % c.len()]);
                        (b[0] - a[0]).hypot(b[1] - a[1])
                    })
                    .sum()
            };
            for i in 0..k {
                // Fixed spacing, so the edges' density stays the same and
                // only their length grows.
                let contours = if kind == "stripes" {
                    let (x, w) = (0.05 + f64::from(i) / 1024.0, 0.3 / 1024.0);
                    vec![vec![
                        [x, 0.0],
                        [x + w, 0.0],
                        [x + w + 0.1, 1.0],
                        [x + 0.1, 1.0],
                    ]]
                } else {
                    let (cx, cz) = (
                        (f64::from(i % 32) + 0.5) / 32.0,
                        (f64::from(i / 32) + 0.5) / 32.0,
                    );
                    let ring = |r: f64| -> Vec<[f64; 2]> {
                        (0..256)
                            .map(|j| {
                                let a = std::f64::consts::TAU * f64::from(j) / 256.0;
                                [cx + r * a.cos(), cz + r * a.sin()]
                            })
                            .collect()
                    };
                    vec![ring(0.01), ring(0.006)]
                };
                length += contours.iter().map(|c| perimeter(c)).sum::<f64>();
                art.fill(
                    contours,
                    FillRule::EvenOdd,
                    Rgba::opaque(1.0, 1.0, 1.0),
                    &[],
                )
                .unwrap();
            }
            let options = VectorOptions {
                max_level: CONTOUR_MAX_LEVEL,
                contour_leaves: Some(16),
                ..VectorOptions::default()
            };
            let mut times = Vec::new();
            let mut last = None;
            for _ in 0..5 {
                let start = Instant::now();
                let built = QuadTree::from_vector(&art, &options).unwrap();
                times.push(start.elapsed().as_secs_f64());
                last = Some(built);
            }
            times.sort_by(f64::total_cmp);
            let (tree, report) = last.unwrap();
            println!(
                "| {kind} | {k} | {length:.1} | {} | {} | {:.1} | {:.0} |",
                report.contour_leaves,
                tree.node_count(),
                times[2] * 1e3,
                times[2] * 1e6 / length,
            );
        }
    }
}

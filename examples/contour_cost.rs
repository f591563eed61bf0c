//! What contour leaves cost and save on `samples/threshold.svg` and
//! `samples/star.svg`: memory, file size and pack time of the classic tree
//! at levels 12 and 16 against trees with contour leaves (curves flattened
//! for level 12, so within 2^-16 of the texture), then the median time of a
//! fragment query at the `quadtex bench` widths (1, 4 and 16 level-12
//! texels) and magnified (10^-6 and 10^-9 of the texture wide), every tree
//! timed in the same run.
//!
//! `cargo run --release --example contour_cost`
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::time::Instant;

use quadtex_core::{Fragment, QuadTree, VectorOptions};
use quadtex_io::Limits;

fn main() {
    let limits = Limits::default();
    for name in ["samples/threshold.svg", "samples/star.svg"] {
        let art = quadtex_io::load_svg(Path::new(name), 12, &limits).unwrap();
        println!("\n{name}");
        println!("| tree | nodes | contour leaves | memory | file | pack s |");
        println!("|---|---:|---:|---:|---:|---:|");
        let mut trees = Vec::new();
        for (label, level, budget) in [
            ("level 12", 12, None),
            ("level 16", 16, None),
            ("contour leaves ≤ 8 edges", 12, Some(8)),
            ("contour leaves ≤ 16 edges", 12, Some(16)),
            ("contour leaves ≤ 32 edges", 12, Some(32)),
        ] {
            // Level 16 flattens its curves finer: load the art for it.
            let art16;
            let art = if level == 16 {
                art16 = quadtex_io::load_svg(Path::new(name), 16, &limits).unwrap();
                &art16
            } else {
                &art
            };
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
                "| {label} | {} | {} | {:.2} MiB | {:.2} MiB | {secs:.2} |",
                tree.node_count(),
                report.contour_leaves,
                tree.memory_bytes() as f64 / (1 << 20) as f64,
                file_bytes as f64 / (1 << 20) as f64,
            );
            trees.push((label, tree));
        }
        println!("\nmedian ns per fragment query (same run; 20 000 random fragments, 5 rounds)");
        print!("| width |");
        for (label, _) in &trees {
            print!(" {label} |");
        }
        println!();
        println!("|---|{}", "---:|".repeat(trees.len()));
        for width in [1.0 / 4096.0, 4.0 / 4096.0, 16.0 / 4096.0, 1e-6, 1e-9] {
            let fragments: Vec<Fragment> = (0..20_000u64)
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
                .collect();
            print!("| {width:.3e} |");
            for (_, tree) in &trees {
                let mut rounds: Vec<f64> = (0..5)
                    .map(|_| {
                        let start = Instant::now();
                        let mut sink = 0.0;
                        for f in &fragments {
                            sink += tree.weighted_colour(f, u8::MAX).0[3];
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

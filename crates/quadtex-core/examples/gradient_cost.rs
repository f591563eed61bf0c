//! Packing cost of gradient art against its slope, with and without
//! gradient leaves: a reflected black-to-white sRGB ramp over a rectangle
//! (dyadic edges, so the edges cost a few levels and the ramp the rest)
//! and the same over a non-dyadic rectangle, at `--max-level` 12.
//!
//! `cargo run --release -p quadtex-core --example gradient_cost`

use quadtex_core::gradient::{Gradient, Interpolation, Spread, Stop};
use quadtex_core::{FillRule, Paint, QuadTree, VectorArt, VectorOptions};

fn art(periods: f64, lo: f64, hi: f64) -> VectorArt {
    let stop = |offset: f64, v: f64| Stop {
        offset,
        colour: [v; 3],
        opacity: 1.0,
    };
    let ramp = Gradient::linear(
        [1.0, 0.0, 0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0],
        [1.0 / periods, 0.3 / periods],
        vec![stop(0.0, 0.0), stop(1.0, 1.0)],
        Spread::Reflect,
        Interpolation::Srgb,
    )
    .expect("ramp");
    let mut art = VectorArt::new();
    art.fill_paint(
        vec![vec![[lo, lo], [hi, lo], [hi, hi], [lo, hi]]],
        FillRule::NonZero,
        Paint::Gradient(ramp),
        &[],
        None,
    )
    .expect("fill");
    art
}

fn main() {
    println!("| rectangle | periods | nodes, split | ms | nodes, leaves | ms | leaves |");
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for (name, lo, hi) in [("dyadic", 0.125, 0.875), ("0.1–0.9", 0.1, 0.9)] {
        for periods in [0.25, 0.5, 1.0, 2.0, 4.0] {
            let a = art(periods, lo, hi);
            let run = |gradient_leaves: bool| {
                let options = VectorOptions {
                    max_level: 12,
                    gradient_leaves,
                    ..VectorOptions::default()
                };
                let mut best = f64::INFINITY;
                let mut out = None;
                for _ in 0..3 {
                    let start = std::time::Instant::now();
                    let r = QuadTree::from_vector(&a, &options).expect("pack");
                    best = best.min(start.elapsed().as_secs_f64() * 1e3);
                    out = Some(r);
                }
                let (t, report) = out.expect("ran");
                (t.node_count(), best, report.gradient_leaves)
            };
            let (split, split_ms, _) = run(false);
            let (leafy, leafy_ms, leaves) = run(true);
            println!(
                "| {name} | {periods} | {split} | {split_ms:.0} | {leafy} | {leafy_ms:.0} | {leaves} |"
            );
        }
    }
}

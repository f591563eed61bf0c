//! What smooth colour costs the vector packer: a full-contrast linear
//! gradient reflected `k` times across the unit square (slope `k` in
//! sRGB-encoded units per unit length), packed at level 14 with the default
//! tolerance, with gradient leaves (the default) and split to the
//! tolerance; and, for comparison, `k` vertical hard edges (flat stripes).
//!
//! `cargo run --release --example gradient_cost` prints nodes and pack time
//! per `k`. Split to the tolerance, gradient squares stop splitting once
//! their colour range is within twice the tolerance, so the nodes grow with
//! the area times (slope / tolerance)² (4× per doubling of the slope) until
//! the maximum level caps them. A gradient leaf keeps the gradient instead:
//! one node, whatever the slope. Edges grow with their length times `2^L`.
#![allow(clippy::unwrap_used)]

use std::time::Instant;

use quadtex_core::{FillRule, Paint, QuadTree, Rgba, VectorArt, VectorOptions};
use quadtex_core::{Gradient, Interpolation, Spread, Stop};

fn main() {
    let level = 14;
    let options = VectorOptions {
        max_level: level,
        ..VectorOptions::default()
    };
    let split = VectorOptions {
        gradient_leaves: false,
        ..options
    };
    let square = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    println!("k  leaf nodes   pack s   split nodes   pack s   stripe nodes   pack s");
    for k in [1u32, 2, 4, 8, 16] {
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
            [1.0 / f64::from(k), 0.0],
            stops,
            Spread::Reflect,
            Interpolation::Srgb,
        )
        .unwrap();
        let mut art = VectorArt::new();
        art.fill_paint(
            vec![square.clone()],
            FillRule::NonZero,
            Paint::Gradient(ramp),
            &[],
            None,
        )
        .unwrap();
        let start = Instant::now();
        let (tree, _) = QuadTree::from_vector(&art, &options).unwrap();
        let leaves = (tree.node_count(), start.elapsed().as_secs_f64());
        let start = Instant::now();
        let (tree, _) = QuadTree::from_vector(&art, &split).unwrap();
        let gradient = (tree.node_count(), start.elapsed().as_secs_f64());
        // k stripes whose edges sit off the dyadic grid.
        let mut art = VectorArt::new();
        for i in 0..k {
            let x0 = (f64::from(i) + 0.3) / f64::from(k);
            let x1 = x0 + 0.4 / f64::from(k);
            art.fill(
                vec![vec![[x0, 0.0], [x1, 0.0], [x1, 1.0], [x0, 1.0]]],
                FillRule::NonZero,
                Rgba::opaque(1.0, 1.0, 1.0),
                &[],
            )
            .unwrap();
        }
        let start = Instant::now();
        let (tree, _) = QuadTree::from_vector(&art, &options).unwrap();
        let stripes = (tree.node_count(), start.elapsed().as_secs_f64());
        println!(
            "{k:<2} {:>10} {:>8.3} {:>13} {:>8.2} {:>14} {:>8.2}",
            leaves.0, leaves.1, gradient.0, gradient.1, stripes.0, stripes.1
        );
    }
}

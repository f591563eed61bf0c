//! Criterion benchmark of the fragment integral: quadtree (full depth and
//! matched level of detail) against the summed-area table on the same
//! fragments. `cargo bench --bench fragment`; `quadtex bench` prints the
//! same comparison as a table, with memory and the brute-force loop.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use quadtex_core::baseline::SummedAreaTable;
use quadtex_core::synth::{runway_art, scanline_fragments};
use quadtex_core::{BuildOptions, QuadTree};

fn fragments(c: &mut Criterion) {
    let size = 4096;
    let Ok(grid) = runway_art().rasterise(size, size) else {
        return;
    };
    let Ok((tree, _)) = QuadTree::from_texels(&grid, &BuildOptions::default()) else {
        return;
    };
    let sat = SummedAreaTable::new(&grid);
    let depth = tree.depth();
    let mut group = c.benchmark_group("fragment_4096");
    for width in [1.0f64, 4.0, 16.0, 256.0] {
        let frags = scanline_fragments(size, width, 10_000, 7);
        let matched = depth.saturating_sub(width.log2().floor() as u8);
        group.throughput(Throughput::Elements(frags.len() as u64));
        group.bench_with_input(BenchmarkId::new("quadtree_full", width), &frags, |b, fs| {
            b.iter(|| {
                fs.iter()
                    .map(|f| tree.weighted_colour(black_box(f), depth).0[0])
                    .sum::<f64>()
            })
        });
        group.bench_with_input(
            BenchmarkId::new("quadtree_matched", width),
            &frags,
            |b, fs| {
                b.iter(|| {
                    fs.iter()
                        .map(|f| tree.weighted_colour(black_box(f), matched).0[0])
                        .sum::<f64>()
                })
            },
        );
        group.bench_with_input(BenchmarkId::new("sat", width), &frags, |b, fs| {
            b.iter(|| {
                fs.iter()
                    .map(|f| sat.weighted_colour(black_box(f)).0[0])
                    .sum::<f64>()
            })
        });
    }
    group.finish();
}

#[allow(missing_docs)]
mod harness {
    use super::*;
    criterion_group!(benches, fragments);
}
use harness::benches;
criterion_main!(benches);

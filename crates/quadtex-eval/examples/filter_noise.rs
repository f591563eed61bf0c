//! The tent or Mitchell pixel filter against a supersampled reference
//! weighted by the same filter, and that reference's own noise:
//! `cargo run --release -p quadtex-eval --example filter_noise -- SCENE WIDTH tent|mitchell [SAMPLES] [BUDGET] [BOUND]`.
//! Renders the quadtree result and two references of SAMPLES×SAMPLES
//! stratified rays per pixel (default 64, i.e. 4096) with different seeds.
//! Prints RMSE(quadtree, reference 1), RMSE(quadtree, mean of both) and
//! the noise of one reference, RMSE(ref 1, ref 2)/√2; a result within the
//! noise cannot be told from the exact filtered image by this reference.

use quadtex_core::FilterOptions;
use quadtex_render::{PixelFilter, RenderOptions, TextureFilter, load_scene, render};

fn rmse(a: &[quadtex_core::Rgba], b: &[quadtex_core::Rgba]) -> f64 {
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| {
            let d = (*x - *y).to_array();
            d[..3].iter().map(|v| f64::from(*v).powi(2)).sum::<f64>() / 3.0
        })
        .sum();
    (sum / a.len().max(1) as f64).sqrt()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: filter_noise SCENE WIDTH tent|mitchell [SAMPLES] [BUDGET] [BOUND]";
    let scene = load_scene(
        std::path::Path::new(args.get(1).ok_or(usage)?),
        &quadtex_io::Limits::default(),
    )?;
    let width: u32 = args.get(2).ok_or(usage)?.parse()?;
    let pixel_filter = match args.get(3).map(String::as_str) {
        Some("tent") => PixelFilter::Tent,
        Some("mitchell") => PixelFilter::Mitchell,
        _ => return Err(usage.into()),
    };
    let samples: u32 = args.get(4).map_or(Ok(64), |s| s.parse())?;
    let mut options = FilterOptions::default();
    if let Some(b) = args.get(5) {
        options = options.with_budget(b.parse()?)?;
    }
    if let Some(e) = args.get(6) {
        options = options.with_error_bound(e.parse()?)?;
    }
    let height = scene.camera.height_for_width(width);
    let base = RenderOptions {
        width: Some(width),
        height: Some(height),
        pixel_filter,
        ..RenderOptions::default()
    };
    let go = |filter, seed| {
        render(
            &scene,
            &RenderOptions {
                filter,
                seed,
                ..base
            },
            &|_, _| {},
        )
    };
    let t = std::time::Instant::now();
    let (quadtree, _) = go(TextureFilter::Quadtree(options), base.seed)?;
    let quadtree_time = t.elapsed().as_secs_f64();
    let (r1, _) = go(TextureFilter::Supersample(samples), 1)?;
    let (r2, _) = go(TextureFilter::Supersample(samples), 2)?;
    let mean: Vec<_> = r1
        .pixels
        .iter()
        .zip(&r2.pixels)
        .map(|(a, b)| (*a + *b) * 0.5)
        .collect();
    println!(
        "{} {width}x{height} {}: quadtree vs reference {:.5}, vs mean of two {:.5}; reference noise {:.5} ({}² samples); quadtree {quadtree_time:.2} s",
        args[1],
        pixel_filter.name(),
        rmse(&quadtree.pixels, &r1.pixels),
        rmse(&quadtree.pixels, &mean),
        rmse(&r1.pixels, &r2.pixels) / 2f64.sqrt(),
        samples
    );
    Ok(())
}

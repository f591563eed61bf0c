//! The quadtree filter's error against the closed-form reference, per
//! pixel, over every pixel of a plane or quad scene:
//! `cargo run --release -p quadtex-eval --example exact_error -- scenes/checker.toml 960 [bound] [budget]`.
//! Prints the RMSE over all pixels, over the rows within 3 of the horizon,
//! the largest error and the render time.

use quadtex_core::FilterOptions;
use quadtex_render::{PixelFilter, RenderOptions, TextureFilter, load_scene, render};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let path = args
        .get(1)
        .ok_or("usage: exact_error SCENE WIDTH [BOUND] [BUDGET]")?;
    let width: u32 = args.get(2).map_or(Ok(480), |w| w.parse())?;
    let mut options = FilterOptions::default();
    if let Some(b) = args.get(3) {
        options = options.with_error_bound(b.parse()?)?;
    }
    if let Some(n) = args.get(4) {
        options = options.with_budget(n.parse()?)?;
    }
    let scene = load_scene(std::path::Path::new(path), &quadtex_io::Limits::default())?;
    let height = scene.camera.height_for_width(width);
    let render_options = RenderOptions {
        width: Some(width),
        height: Some(height),
        filter: TextureFilter::Quadtree(options),
        pixel_filter: PixelFilter::Box,
        ..RenderOptions::default()
    };
    // IMAGE=path.exr judges an image rendered elsewhere (another build).
    let (image, summary) = match std::env::var("IMAGE") {
        Ok(p) => {
            let (_, s) = render(
                &scene,
                &RenderOptions {
                    width: Some(1),
                    height: Some(1),
                    ..render_options
                },
                &|_, _| {},
            )?;
            (quadtex_io::load_linear_image(std::path::Path::new(&p))?, s)
        }
        Err(_) => render(&scene, &render_options, &|_, _| {})?,
    };
    let exact = quadtex_eval::reference::closed_form(&scene, width, height)
        .ok_or("no closed form for this scene")?;
    let (mut sum, mut n, mut max, mut worst) = (0.0, 0u64, 0f64, (0, 0));
    let mut rows = vec![(0.0, 0u64); height as usize];
    for (i, (got, want)) in image.pixels.iter().zip(&exact.pixels).enumerate() {
        let Some(want) = want else { continue };
        let d = (*got - *want).to_array();
        let e2: f64 = d[..3].iter().map(|v| f64::from(*v).powi(2)).sum::<f64>() / 3.0;
        sum += e2;
        n += 1;
        let y = i / width as usize;
        rows[y].0 += e2;
        rows[y].1 += 1;
        let e = d[..3].iter().fold(0f64, |m, v| m.max(f64::from(v.abs())));
        if e > max {
            max = e;
            worst = (i % width as usize, y);
        }
    }
    if std::env::var_os("ROWS").is_some() {
        for (y, &(s, c)) in rows.iter().enumerate() {
            println!("row {y}: {:.3e}", (s / c.max(1) as f64).sqrt());
        }
    }
    let mut by_row: Vec<(f64, usize)> = rows
        .iter()
        .enumerate()
        .map(|(y, &(s, c))| ((s / c.max(1) as f64).sqrt(), y))
        .collect();
    by_row.sort_by(|a, b| b.0.total_cmp(&a.0));
    println!(
        "{path} {width}x{height}: RMSE {:.3e} over {n} pixels ({:.1}% covered), max {:.3e} at {:?}; worst rows {:?}",
        (sum / n.max(1) as f64).sqrt(),
        100.0 * exact.coverage(),
        max,
        worst,
        &by_row[..4.min(by_row.len())]
    );
    println!("{summary}");
    if let Ok(spec) = std::env::var("PIXEL") {
        let (px, py): (u32, u32) = {
            let mut it = spec.split(',').map(|v| v.parse::<u32>());
            (
                it.next().ok_or("PIXEL=x,y")??,
                it.next().ok_or("PIXEL=x,y")??,
            )
        };
        let cam = scene.camera.with_size(width, height);
        let surface = &scene.surfaces[0];
        let sampler = surface
            .texture
            .as_ref()
            .ok_or("untextured")?
            .texture(surface.wrap);
        if let quadtex_render::Geometry::Plane {
            point,
            normal,
            u_axis,
            v_axis,
        } = surface.geometry
        {
            let n = 1024;
            let mut acc = [0f64; 3];
            for j in 0..n {
                for i in 0..n {
                    let sx = f64::from(px) + (f64::from(i) + 0.5) / f64::from(n);
                    let sy = f64::from(py) + (f64::from(j) + 0.5) / f64::from(n);
                    let ray = cam.ray(sx, sy);
                    let denom = ray.direction.dot(normal);
                    let t = (point - ray.origin).dot(normal) / denom;
                    let c = if t > 0.0 && t.is_finite() {
                        let rel = ray.origin + ray.direction * t - point;
                        sampler.nearest(
                            surface
                                .uv_transform
                                .apply([rel.dot(u_axis), rel.dot(v_axis)]),
                        )
                    } else {
                        quadtex_core::Rgba::TRANSPARENT
                    };
                    for (a, v) in acc.iter_mut().zip(c.to_array()) {
                        *a += f64::from(v);
                    }
                }
            }
            let k = (py * width + px) as usize;
            println!(
                "pixel {px},{py}: sampled {:?} quadtree {:?} closed form {:?}",
                acc.map(|v| v / f64::from(n * n)),
                image.pixels[k],
                exact.pixels[k]
            );
        }
    }
    Ok(())
}

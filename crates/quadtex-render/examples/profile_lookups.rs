//! Times the quadtree filter's lookups alone on a scene, many passes, for a
//! profiler (`perf record`) to see the lookups and little else:
//!
//! ```text
//! cargo build --release -p quadtex-render --example profile_lookups
//! perf record -g target/release/examples/profile_lookups scenes/runway.toml 480 20
//! ```

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let scene = args
        .next()
        .ok_or("usage: profile_lookups SCENE.toml [WIDTH] [PASSES]")?;
    let width: u32 = args.next().map_or(Ok(480), |a| a.parse())?;
    let passes: u32 = args.next().map_or(Ok(20), |a| a.parse())?;
    let scene =
        quadtex_render::load_scene(std::path::Path::new(&scene), &quadtex_io::Limits::default())?;
    let height = scene.camera.height_for_width(width);
    let filter = quadtex_render::TextureFilter::Quadtree(quadtex_core::FilterOptions::RENDER);
    let t = quadtex_render::time_lookups(&scene, width, height, filter, passes)?;
    println!(
        "{:.1} ns per lookup over {} lookups (median of {passes})",
        t.ns_per_lookup, t.lookups
    );
    Ok(())
}

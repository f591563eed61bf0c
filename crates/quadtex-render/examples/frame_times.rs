//! Renders a scene several times in one process with the quadtree filter
//! into one frame buffer (as `quadtex bench --frames` does) and prints each
//! frame's time: the first frame after load, then later ones. The harness
//! behind the README's terrain profile and paired timings:
//!
//! ```text
//! cargo run --release --example terrain            # writes target/terrain/
//! cargo build --release -p quadtex-render --example frame_times
//! target/release/examples/frame_times target/terrain/terrain.toml 1920 6
//! RAYON_NUM_THREADS=1 valgrind --tool=callgrind --dump-after='*render_into*' \
//!     target/release/examples/frame_times target/terrain/terrain.toml 960 2
//! ```
//!
//! (callgrind's second dump is a later frame).

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let scene = args
        .next()
        .ok_or("usage: frame_times SCENE.toml [WIDTH] [FRAMES]")?;
    let width: u32 = args.next().map_or(Ok(960), |a| a.parse())?;
    let frames: u32 = args.next().map_or(Ok(2), |a| a.parse())?;
    let scene =
        quadtex_render::load_scene(std::path::Path::new(&scene), &quadtex_io::Limits::default())?;
    let options = quadtex_render::RenderOptions {
        width: Some(width),
        height: Some(scene.camera.height_for_width(width)),
        ..quadtex_render::RenderOptions::default()
    };
    let mut image = quadtex_io::LinearImage::default();
    for frame in 0..frames {
        let summary = quadtex_render::render_into(&scene, &options, &mut image, &|_, _| {})?;
        println!("frame {frame}: {:.3} s", summary.seconds);
    }
    Ok(())
}

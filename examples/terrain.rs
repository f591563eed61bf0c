//! A generated terrain of a million triangles (binary glTF) with a runway
//! on it: how the renderer scales with mesh size.
//!
//! `cargo run --release --example terrain [-- CELLS [WIDTH HEIGHT]]` writes
//! `target/terrain/terrain.glb` and `terrain.toml` (see
//! `quadtex_render::terrain`; default 708 cells, 1 002 528 triangles), loads
//! the scene (glTF read, hierarchy build and texture packing timed), and
//! renders it at `WIDTH × HEIGHT` (default 1920 × 1080) with `nearest` and
//! the quadtree filter, printing each frame's time and the ratio to
//! `nearest`. `quadtex bench --frames` measures the same scene with the
//! demo and the runway.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::time::Instant;

use quadtex_render::{RenderOptions, TextureFilter};
use quadtex_render::{TERRAIN_CELLS, write_terrain};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let cells: usize = args.first().map_or(Ok(TERRAIN_CELLS), |a| a.parse())?;
    let width: u32 = args.get(1).map_or(Ok(1920), |a| a.parse())?;
    let height: u32 = args.get(2).map_or(Ok(1080), |a| a.parse())?;
    let dir = std::path::Path::new("target/terrain");
    let started = Instant::now();
    let file = write_terrain(dir, cells, width, height)?;
    println!(
        "wrote {} ({} triangles) in {:.2} s",
        file.display(),
        2 * cells * cells,
        started.elapsed().as_secs_f64()
    );
    let started = Instant::now();
    let scene = quadtex_render::load_scene(&file, &quadtex_io::Limits::default())?;
    let load = started.elapsed().as_secs_f64();
    let mesh_bytes = scene
        .surfaces
        .iter()
        .filter_map(|s| match &s.geometry {
            quadtex_render::Geometry::Mesh(m) => Some(m.memory_bytes()),
            _ => None,
        })
        .sum::<usize>();
    println!(
        "loaded the scene (glTF read, hierarchy build, texture packing) in {load:.2} s; mesh with hierarchy {:.0} MiB",
        mesh_bytes as f64 / f64::from(1 << 20)
    );
    let mut nearest = None;
    for (name, filter) in [
        ("nearest", TextureFilter::Nearest),
        ("quadtree", TextureFilter::Quadtree(Default::default())),
    ] {
        let options = RenderOptions {
            width: Some(width),
            height: Some(height),
            filter,
            ..RenderOptions::default()
        };
        let (image, summary) = quadtex_render::render(&scene, &options, &|_, _| {})?;
        let base = *nearest.get_or_insert(summary.seconds);
        println!(
            "{name:>9}: {width}x{height} in {:.3} s ({:.2}x nearest)",
            summary.seconds,
            summary.seconds / base
        );
        quadtex_io::save_image(&dir.join(format!("terrain-{name}.png")), &image)?;
    }
    Ok(())
}

//! `quadtex rays`: dump a frame's primary and sun shadow rays with the
//! scene's triangles for a peer ray caster, with quadtex's own caster timed
//! on the same rays. Used by `bench/peers/embree/run.sh`; the formats are
//! documented in `quadtex_render::rays` (crates/quadtex-render/src/rays.rs).

use std::io::Write;
use std::path::PathBuf;

use super::Result;
use super::common::{MemoryArgs, ResourcesArgs, in_range};
use super::output::Text;

/// Dump a frame's rays for a peer ray caster and time quadtex's own.
///
/// Writes into DIR: rays.bin (the scene's surfaces as f32 triangles, one
/// primary ray per pixel centre and the sun's shadow ray of every primary
/// hit facing the sun, exactly as the renderer casts them, in f64; format
/// in crates/quadtex-render/src/rays.rs), quadtex-hits.bin (quadtex's
/// answer per ray: surface, triangle and t of the closest hit; whether
/// each shadow ray is occluded) and quadtex.tsv (the timings below). The
/// rays are cast on one thread, `--passes` times after a warm-up, median
/// reported: primary rays closest-hit, shadow rays any-hit through the
/// meshes' hierarchies and by the renderer's own path (the sun's grid).
/// Timing lines are `method<TAB>ns_per_ray`, then `build: WHAT<TAB>ms`
/// for each mesh's hierarchy and sun grid built on one thread. Used by
/// bench/peers/embree/run.sh.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene (planes and spheres have no triangles for a peer: not
    /// accepted), or `terrain`: the generated 1 M-triangle terrain of
    /// `quadtex bench --frames`, written into DIR as terrain.toml and
    /// terrain.glb (with --timing-only, DIR's terrain.toml is read).
    #[arg(value_name = "SCENE.toml")]
    scene: PathBuf,
    /// The directory to write into (created if missing).
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    /// Frame width in pixels, in 16..=3840.
    #[arg(long, value_name = "W", default_value_t = 1920, value_parser = in_range("--width", 16, 3840))]
    width: u32,
    /// Frame height in pixels, in 16..=2160 (default: the camera's aspect).
    #[arg(long, value_name = "H", value_parser = in_range("--height", 16, 2160))]
    height: Option<u32>,
    /// Timing passes (the median is reported), in 1..=100.
    #[arg(long, value_name = "P", default_value_t = 5, value_parser = in_range("--passes", 1, 100))]
    passes: u32,
    /// Only time quadtex's casts: print the timing lines to standard
    /// output and write nothing (bench/peers/embree/run.sh alternates such
    /// rounds with the peer's).
    #[arg(long)]
    timing_only: bool,
    #[command(flatten)]
    memory: MemoryArgs,
    #[command(flatten)]
    resources: ResourcesArgs,
}

/// Runs `quadtex rays`.
pub fn run(args: Args) -> Result<()> {
    let Args {
        scene: path,
        output: dir,
        width,
        height,
        passes,
        timing_only,
        memory,
        resources,
    } = args;
    let limits = resources.apply(memory.limits());
    let path = if path.as_os_str() == "terrain" {
        if timing_only {
            dir.join("terrain.toml")
        } else {
            let h = height.unwrap_or(width * 9 / 16);
            quadtex_render::write_terrain(&dir, quadtex_render::TERRAIN_CELLS, width, h)?
        }
    } else {
        path
    };
    let scene = quadtex_render::load_scene(&path, &limits)?;
    let height = height.unwrap_or_else(|| scene.camera.height_for_width(width));
    let dump = quadtex_render::ray_dump(&scene, width, height)?;
    let timing = quadtex_render::time_rays(&scene, &dump, passes)?;
    let mut lines = String::new();
    for (method, ns, _) in &timing.methods {
        lines.push_str(&format!("{method}\t{ns:.1}\n"));
    }
    for (what, seconds) in &timing.builds {
        lines.push_str(&format!("build: {what}\t{:.1}\n", 1e3 * seconds));
    }
    let mut out = Text::stdout();
    if timing_only {
        write!(out, "{lines}")?;
        out.flush()?;
        return Ok(());
    }
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    quadtex_render::write_ray_dump(&dir.join("rays.bin"), &dump)?;
    quadtex_render::write_ray_results(&dir.join("quadtex-hits.bin"), &timing.results)?;
    std::fs::write(dir.join("quadtex.tsv"), &lines)
        .map_err(|e| format!("{}: {e}", dir.join("quadtex.tsv").display()))?;
    let r = &timing.results;
    let hits = r
        .primary
        .iter()
        .filter(|h| h.surface != quadtex_render::MISS);
    let differ = (r.shadow_bvh.iter().zip(&r.shadow_renderer))
        .filter(|(a, b)| a != b)
        .count();
    let mut err = std::io::stderr();
    for (method, ns, rays) in &timing.methods {
        let _ = writeln!(
            err,
            "{method}: {ns:.1} ns per ray over {rays} rays (median of {passes}, one thread)"
        );
    }
    for (what, seconds) in &timing.builds {
        let _ = writeln!(err, "build: {what}: {:.1} ms (one thread)", 1e3 * seconds);
    }
    let _ = writeln!(
        err,
        "shadow rays occluded: {} (hierarchy), {} (renderer's path); the two differ on {differ}",
        r.shadow_bvh.iter().filter(|&&o| o).count(),
        r.shadow_renderer.iter().filter(|&&o| o).count(),
    );
    writeln!(
        out,
        "wrote {}: rays.bin ({width}x{height}: {} primary rays, {} hit; {} shadow rays; {} triangles), quadtex-hits.bin, quadtex.tsv",
        dir.display(),
        dump.primary.len(),
        hits.count(),
        dump.shadow.len(),
        dump.surfaces
            .iter()
            .map(|s| s.triangles.len())
            .sum::<usize>(),
    )?;
    Ok(())
}

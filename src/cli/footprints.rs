//! `quadtex footprints`: dump every pixel's lookup for a peer filter, with
//! quadtex's own lookups timed on the same footprints. Used by
//! `bench/peers/run.sh`; see `docs/footprints.md`.

use std::io::Write;
use std::path::PathBuf;

use quadtex_core::WrapMode;
use quadtex_io::LinearImage;
use quadtex_io::{DumpTexture, DumpWrap, FootprintDump, write_footprints};
use quadtex_render::{PixelFilter, RenderOptions, TextureFilter};

use super::Result;
use super::common::{MemoryArgs, ResourcesArgs, in_range};
use super::comparison::texture_bytes;
use super::output::Text;

/// Dump every pixel's lookup for a peer filter and time quadtex's own.
///
/// Writes into DIR: footprints.bin (every pixel's texture lookup: centre,
/// derivatives and footprint quad; format in docs/footprints.md), the scene's
/// textures as texture-K.exr at the baselines' resolution, a supersampled
/// reference.exr of the textures alone, and quadtex.tsv with quadtex's own
/// quadtree, EWA and trilinear lookups timed on the same footprints (one
/// thread, median of the passes) and their images. Used by
/// bench/peers/run.sh.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene whose footprints to dump.
    #[arg(value_name = "SCENE.toml")]
    scene: PathBuf,
    /// The directory to write into (created if missing).
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    /// Frame width in pixels, in 16..=3840 (the height keeps the camera's aspect).
    #[arg(long, value_name = "W", default_value_t = 480, value_parser = in_range("--width", 16, 3840))]
    width: u32,
    /// Timing passes (the median is reported), in 1..=100.
    #[arg(long, value_name = "P", default_value_t = 5, value_parser = in_range("--passes", 1, 100))]
    passes: u32,
    /// Samples per pixel of the reference, clamped to 1..=4096 and rounded
    /// to a square grid.
    #[arg(long, value_name = "N", default_value_t = 1024)]
    reference_spp: u32,
    /// Only time quadtex's lookups: print `method<TAB>ns_per_lookup` lines
    /// to standard output and write nothing (bench/peers/run.sh alternates
    /// such rounds with the peer's).
    #[arg(long)]
    timing_only: bool,
    #[command(flatten)]
    memory: MemoryArgs,
    #[command(flatten)]
    resources: ResourcesArgs,
}

/// The quadtex lookups timed against the peer: label, file stem, filter.
const TIMED: [(&str, &str, TextureFilter); 3] = [
    (
        "quadtex quadtree",
        "quadtex-quadtree",
        TextureFilter::Quadtree(quadtex_core::FilterOptions::RENDER),
    ),
    (
        "quadtex EWA 8 (pbrt-v4 style)",
        "quadtex-ewa8",
        TextureFilter::Ewa {
            max_anisotropy: 8.0,
        },
    ),
    (
        "quadtex trilinear (pbrt-v4 style)",
        "quadtex-trilinear",
        TextureFilter::Trilinear,
    ),
];

/// Runs `quadtex footprints`.
pub fn run(args: Args) -> Result<()> {
    let Args {
        scene: path,
        output: dir,
        width,
        passes,
        reference_spp,
        timing_only,
        memory,
        resources,
    } = args;
    let grid = (f64::from(reference_spp.clamp(1, 4096)).sqrt().round() as u32).max(1);
    let limits = resources.apply(memory.limits());
    let scene = quadtex_render::load_scene(&path, &limits)?;
    if timing_only {
        let height = scene.camera.height_for_width(width);
        let mut out = Text::stdout();
        for (label, _, filter) in TIMED {
            let t = quadtex_render::time_lookups(&scene, width, height, filter, passes)?;
            writeln!(out, "{label}\t{:.1}", t.ns_per_lookup)?;
            out.flush()?;
        }
        return Ok(());
    }
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let height = scene.camera.height_for_width(width);
    let (records, users) = quadtex_eval::peers::footprint_records(&scene, width, height)?;
    let mut textures = Vec::new();
    for (i, &u) in users.iter().enumerate() {
        let surface = &scene.surfaces[u];
        let Some(texture) = &surface.texture else {
            continue;
        };
        let tree = &texture.tree;
        // The peer gets the same raster the in-project baselines use.
        let level = quadtex_render::baseline_level(tree.depth());
        quadtex_core::memory::check_budget(
            || format!("rasterising texture {i} at level {level}"),
            quadtex_core::QuadTree::rasterise_bytes(level),
            Some(limits.max_memory),
            "raise --memory-limit",
        )?;
        let grid = tree.rasterise(level)?;
        let image = LinearImage {
            width: grid.width(),
            height: grid.height(),
            pixels: grid.texels().iter().map(|t| t.to_rgba()).collect(),
        };
        let file = format!("texture-{i}.exr");
        quadtex_io::save_image(&dir.join(&file), &image)?;
        textures.push(DumpTexture {
            file,
            wrap: match (surface.wrap.x(), surface.wrap.z(), surface.wrap.border_colour().a) {
                (WrapMode::Repeat, WrapMode::Repeat, _) => DumpWrap::Repeat,
                (WrapMode::Clamp, WrapMode::Clamp, _) => DumpWrap::Clamp,
                (WrapMode::Border, WrapMode::Border, 0.0) => DumpWrap::Black,
                (x, z, _) => {
                    return Err(format!(
                        "surface {u}: wrap ({}, {}) has no equivalent in the peer dump (repeat, clamp or transparent border on both axes)",
                        x.name(),
                        z.name()
                    )
                    .into());
                }
            },
        });
    }
    write_footprints(
        &dir.join("footprints.bin"),
        &FootprintDump {
            width,
            height,
            textures,
            records,
        },
    )?;
    // The reference: the scene's textures alone, supersampled.
    let (reference, _) = quadtex_render::render(
        &quadtex_render::texture_only(&scene),
        &RenderOptions {
            width: Some(width),
            height: Some(height),
            filter: TextureFilter::Supersample(grid),
            pixel_filter: PixelFilter::Box,
            seed: quadtex_render::REFERENCE_SEED,
        },
        &|_, _| {},
    )?;
    quadtex_io::save_image(&dir.join("reference.exr"), &reference)?;
    let mut table = String::from("method\tns_per_lookup\ttexture_bytes\tfile\n");
    for (label, stem, filter) in TIMED {
        let t = quadtex_render::time_lookups(&scene, width, height, filter, passes)?;
        let file = format!("{stem}.exr");
        quadtex_io::save_image(&dir.join(&file), &t.image)?;
        let bytes = texture_bytes(&scene, filter);
        table.push_str(&format!(
            "{label}\t{:.1}\t{bytes}\t{file}\n",
            t.ns_per_lookup
        ));
        let _ = writeln!(
            std::io::stderr(),
            "{label}: {:.1} ns per lookup over {} lookups (median of {passes}, one thread)",
            t.ns_per_lookup,
            t.lookups
        );
    }
    quadtex_io::write_atomically(&dir.join("quadtex.tsv"), |w| {
        std::io::Write::write_all(w, table.as_bytes()).map_err(|source| quadtex_io::Error::Io {
            path: dir.join("quadtex.tsv"),
            source,
        })
    })?;
    let mut out = Text::stdout();
    writeln!(
        out,
        "wrote {}: footprints.bin ({width}x{height}), texture-*.exr, reference.exr ({} spp), quadtex.tsv and images",
        dir.display(),
        grid * grid
    )?;
    Ok(())
}

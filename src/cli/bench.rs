//! `quadtex bench`: fragment queries per second on a vector-like texture,
//! the quadtree against a summed-area table and a brute-force texel loop on
//! the same fragments in the same run, plus memory and packing time.

use std::hint::black_box;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

use quadtex_core::baseline::SummedAreaTable;
use quadtex_core::reference::texel_sum;
use quadtex_core::synth::{runway_art, scanline_fragments};
use quadtex_core::{BuildOptions, Fragment, QuadTree, TexelGrid, WeightedColour};

use super::Result;
use super::common::{MemoryArgs, blocks_summary, human_bytes, raster_bytes};
use super::output::Text;

/// Median seconds per call of `f` over `runs` runs, each answering every fragment.
fn time_per_query(
    runs: usize,
    frags: &[Fragment],
    mut f: impl FnMut(&Fragment) -> WeightedColour,
) -> f64 {
    let mut samples: Vec<f64> = (0..runs)
        .map(|_| {
            let start = Instant::now();
            let mut acc = 0.0;
            for fr in frags {
                acc += f(black_box(fr)).0[0];
            }
            black_box(acc);
            start.elapsed().as_secs_f64() / frags.len() as f64
        })
        .collect();
    samples.sort_by(f64::total_cmp);
    samples[samples.len() / 2]
}

/// Fragment queries per second: the quadtree against a summed-area table.
///
/// Packs the built-in runway art (vector-like, lossless) and times fragment
/// queries of several widths on the quadtree (exact and at the matched
/// level), a summed-area table and a brute-force texel loop, on the same
/// fragments in the same run; also prints memory and packing time. Prints a
/// Markdown table (the one under "Measured" in the README).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Texture side in texels: a power of two in 64..=16384.
    #[arg(long, value_name = "N", default_value_t = 4096, value_parser = texture_size)]
    size: u32,
    /// Benchmark this image (PNG, JPEG, EXR) instead of the built-in art,
    /// packed losslessly: a photograph shows the texel blocks' cost.
    #[arg(long, value_name = "FILE", conflicts_with = "size")]
    texture: Option<std::path::PathBuf>,
    /// Fragments per width (at least 1).
    #[arg(long, value_name = "Q", default_value_t = 100_000, value_parser = at_least_one("--queries"))]
    queries: usize,
    /// Timed runs per measurement (the median is reported; at least 1;
    /// default 5, or 3 with `--frames`).
    #[arg(long, value_name = "R", value_parser = at_least_one("--runs"))]
    runs: Option<usize>,
    /// Time whole 1920×1080 frames instead: the demo, the runway scene and
    /// a generated terrain of 1 M triangles (binary glTF, see
    /// `quadtex_render::terrain`), each with `nearest`, the quadtree filter
    /// and EWA, as medians with their range and as ratios to `nearest`
    /// (each run renders the three filters in turn, and a ratio is taken
    /// within a run). The runs of a scene and filter render into one frame
    /// buffer, as a real-time loop does; the first run allocates it. Also
    /// prints the terrain's load time and its first frame after load (the
    /// median and range over as many loads as runs), also as a ratio to the
    /// median of the three frames after it in the same load (the median
    /// and range of the loads' ratios), and the demo's quadtree frame under
    /// the box, tent and Mitchell pixel filters (in turn within each run,
    /// the tent's and Mitchell's as ratios to that run's box).
    #[arg(long, conflicts_with_all = ["size", "queries", "texture"])]
    frames: bool,
    #[command(flatten)]
    memory: MemoryArgs,
}

/// A value parser: a count of at least 1; `flag` names the option in the error.
fn at_least_one(
    flag: &'static str,
) -> impl Fn(&str) -> std::result::Result<usize, String> + Clone + Send + Sync + 'static {
    move |text| {
        let v = text.parse::<usize>().map_err(|e| e.to_string())?;
        if v == 0 {
            return Err(format!("{flag} must be at least 1, got 0"));
        }
        Ok(v)
    }
}

/// A value parser: a power of two in 64..=16384.
fn texture_size(text: &str) -> std::result::Result<u32, String> {
    let size = text.parse::<u32>().map_err(|e| e.to_string())?;
    if !size.is_power_of_two() || !(64..=16384).contains(&size) {
        return Err(format!(
            "--size must be a power of two in 64..=16384, got {size}"
        ));
    }
    Ok(size)
}

/// Runs `quadtex bench`.
pub fn run(args: Args) -> Result<()> {
    let Args {
        size,
        texture,
        queries,
        runs,
        frames,
        memory,
    } = args;
    if frames {
        return run_frames(runs.unwrap_or(3), &memory.limits());
    }
    let runs = runs.unwrap_or(5);
    let budget = memory.bytes();
    let (grid, title) = match &texture {
        Some(path) => texture_from_file(path, &memory.limits())?,
        None => runway_texture(size, budget)?,
    };
    let packed = Packed::new(&grid, budget)?;
    let sat = SummedAreaTable::new(&grid);
    let mut out = Text::stdout();
    write_storage(&mut out, &title, &grid, &packed, &sat)?;
    write_query_times(&mut out, &grid, &packed, &sat, runs, queries)?;
    out.flush()?;
    Ok(())
}

/// The texels of image `path`, with the table's title.
fn texture_from_file(path: &Path, limits: &quadtex_io::Limits) -> Result<(TexelGrid, String)> {
    let grid = quadtex_io::load_texels(path, limits)?;
    let title = format!(
        "{}, {}x{} texels (lossless)",
        path.display(),
        grid.width(),
        grid.height()
    );
    Ok((grid, title))
}

/// The runway art rasterised at `size`², with the table's title, refused
/// first if it and its tree would exceed `budget` bytes.
fn runway_texture(size: u32, budget: u64) -> Result<(TexelGrid, String)> {
    let side = u64::from(size);
    // The raster (8 bytes a texel) and a lossless tree of it (at most 4/3 nodes a texel).
    quadtex_core::memory::check_budget(
        || format!("benchmarking a {size}x{size} texture"),
        8 * side * side + quadtex_core::memory::BUILD_BYTES_PER_NODE * side * side * 4 / 3,
        Some(budget),
        "lower --size, or raise --memory-limit",
    )?;
    let title =
        format!("runway markings and lettering, {size}x{size} texels (vector-like, lossless)");
    Ok((runway_art().rasterise(size, size)?, title))
}

/// The benchmarked texture packed: with texel blocks (the default) and
/// with every square a node, and the default packing's median time.
struct Packed {
    tree: QuadTree,
    /// The same texture with every square a node, for the blocks' cost.
    nodes_only: QuadTree,
    /// Median of three packing times, in seconds.
    median_seconds: f64,
}

impl Packed {
    /// Packs `grid` three times (timed) and once without texel blocks.
    fn new(grid: &TexelGrid, budget: u64) -> Result<Packed> {
        let mut pack_times = Vec::new();
        let mut tree = None;
        for _ in 0..3 {
            let start = Instant::now();
            let options = BuildOptions {
                max_bytes: Some(budget),
                ..BuildOptions::default()
            };
            let (t, _) = QuadTree::from_texels(grid, &options)?;
            pack_times.push(start.elapsed().as_secs_f64());
            tree = Some(t);
        }
        let tree = tree.ok_or("no tree")?;
        let (nodes_only, _) = QuadTree::from_texels(
            grid,
            &BuildOptions {
                max_bytes: Some(budget),
                texel_blocks: false,
                ..BuildOptions::default()
            },
        )?;
        pack_times.sort_by(f64::total_cmp);
        Ok(Packed {
            tree,
            nodes_only,
            median_seconds: pack_times[1],
        })
    }
}

/// The title, the packing time and the storage table: the tree against
/// itself without texel blocks, a raster, a raster with mips and a
/// summed-area table.
fn write_storage(
    out: &mut Text,
    title: &str,
    grid: &TexelGrid,
    packed: &Packed,
    sat: &SummedAreaTable,
) -> Result<()> {
    let Packed {
        tree, nodes_only, ..
    } = packed;
    let (raster, mips) = raster_bytes(grid.width(), grid.height());
    let tree_bytes = tree.memory_bytes();
    let depth = tree.depth();
    writeln!(out, "## quadtex bench: {title}\n")?;
    writeln!(
        out,
        "Pack time (median of 3): {:.3} s; {} nodes{}, depth {depth}\n",
        packed.median_seconds,
        tree.node_count(),
        blocks_summary(tree)
    )?;
    writeln!(out, "| storage | bytes | tree is smaller by |")?;
    writeln!(out, "|---|---:|---:|")?;
    writeln!(
        out,
        "| quadtree ({:.2} B/texel) | {} | 1 |",
        tree_bytes as f64 / (f64::from(grid.width()) * f64::from(grid.height())),
        human_bytes(tree_bytes)
    )?;
    if tree.texel_blocks().is_some() {
        let b = nodes_only.memory_bytes();
        writeln!(
            out,
            "| quadtree without texel blocks | {} | {:.1}x |",
            human_bytes(b),
            b as f64 / tree_bytes as f64
        )?;
    }
    writeln!(
        out,
        "| RGBA8 raster | {} | {:.1}x |",
        human_bytes(raster),
        raster as f64 / tree_bytes as f64
    )?;
    writeln!(
        out,
        "| RGBA8 raster + mips | {} | {:.1}x |",
        human_bytes(mips),
        mips as f64 / tree_bytes as f64
    )?;
    writeln!(
        out,
        "| summed-area table (f64 RGBA) | {} | {:.1}x |",
        human_bytes(sat.memory_bytes()),
        sat.memory_bytes() as f64 / tree_bytes as f64
    )?;
    writeln!(out)?;
    Ok(())
}

/// The query-time table: median nanoseconds per fragment of each method,
/// per fragment width, and the largest difference between the exact tree
/// and the SAT.
fn write_query_times(
    out: &mut Text,
    grid: &TexelGrid,
    packed: &Packed,
    sat: &SummedAreaTable,
    runs: usize,
    queries: usize,
) -> Result<()> {
    let Packed {
        tree, nodes_only, ..
    } = packed;
    let size = grid.width().max(grid.height());
    let depth = tree.depth();
    writeln!(
        out,
        "Median ns per fragment over {runs} runs, {queries} fragments per width in scanline order (same run, same fragments):\n"
    )?;
    writeln!(
        out,
        "| width (texels) | quadtree k={depth} (exact) | without blocks (exact) | quadtree matched k | SAT (exact) | texel loop | matched / SAT | exact / SAT | max abs error vs SAT |"
    )?;
    writeln!(out, "|---:|---:|---:|---:|---:|---:|---:|---:|---:|")?;
    for width in [1.0, 4.0, 16.0, 256.0] {
        let frags = scanline_fragments(size, width, queries, 7);
        let matched = depth.saturating_sub(width.log2().floor() as u8);
        let full = time_per_query(runs, &frags, |f| tree.weighted_colour(f, depth));
        let nodes = time_per_query(runs, &frags, |f| nodes_only.weighted_colour(f, depth));
        let lod = time_per_query(runs, &frags, |f| tree.weighted_colour(f, matched));
        let sat_t = time_per_query(runs, &frags, |f| sat.weighted_colour(f));
        // The texel loop is O(width²): cap its work (but time at least 100
        // fragments, or all of them when there are fewer).
        let brute_n = ((20_000_000.0 / (width * width)) as usize)
            .max(100)
            .min(frags.len());
        let brute = time_per_query(1, &frags[..brute_n], |f| texel_sum(grid, f));
        let max_err = frags
            .iter()
            .map(|f| {
                let (a, b) = (tree.weighted_colour(f, depth), sat.weighted_colour(f));
                let area = f.clip_to_unit().map_or(0.0, |c| c.area()).max(1e-300);
                (0..4)
                    .map(|ch| (a.0[ch] - b.0[ch]).abs() / area)
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        writeln!(
            out,
            "| {width} | {:.0} | {:.0} | {:.0} (k={matched}) | {:.0} | {:.0} | {:.2} | {:.2} | {:.1e} |",
            full * 1e9,
            nodes * 1e9,
            lod * 1e9,
            sat_t * 1e9,
            brute * 1e9,
            lod / sat_t,
            full / sat_t,
            max_err
        )?;
    }
    writeln!(
        out,
        "\n(max abs error: largest per-channel difference of the mean colour over a fragment, exact quadtree vs SAT; both are exact, so it shows rounding only.)"
    )?;
    Ok(())
}

/// The median of `values` (the upper one of an even count), their least
/// and their largest.
fn median_range(mut values: Vec<f64>) -> (f64, f64, f64) {
    values.sort_by(f64::total_cmp);
    match (values.first(), values.last()) {
        (Some(&lo), Some(&hi)) => (values[values.len() / 2], lo, hi),
        _ => (f64::NAN, f64::NAN, f64::NAN),
    }
}

/// Frames rendered after each terrain load's first, in the same buffer:
/// what the first frame is compared with.
const FRAMES_AFTER_FIRST: usize = 3;

/// `quadtex bench --frames`: median frame times at 1920×1080.
fn run_frames(runs: usize, limits: &quadtex_io::Limits) -> Result<()> {
    use quadtex_render::{RenderOptions, TextureFilter};
    let (width, height) = (1920, 1080);
    let dir = std::env::temp_dir().join(format!("quadtex-bench-terrain-{}", std::process::id()));
    let runway = quadtex_render::parse_scene(
        include_str!("../../scenes/runway.toml"),
        std::path::Path::new("scenes/runway.toml"),
        &quadtex_io::Limits::default(),
    )?;
    let quadtree = TextureFilter::Quadtree(quadtex_core::FilterOptions::RENDER);
    let options_for = |filter: TextureFilter| RenderOptions {
        width: Some(width),
        height: Some(height),
        filter,
        ..RenderOptions::default()
    };
    // The terrain written once and loaded `runs` times, each load's first
    // frame timed before any other of it: it decides, once per triangle
    // it lights, whether the rest of the mesh can shade it (kept for
    // later frames: the ones rendered after it in the same load, which it
    // is compared with, and the table's; each load is a new mesh, with its
    // own decisions). The first load's time is reported.
    let started = Instant::now();
    let mut terrain_load = 0.0;
    let mut first_frames = Vec::with_capacity(runs);
    // Each load's first frame over the median of the frames right after
    // it, in the same load and buffer: a ratio within the run, as the
    // table's are (against the table's later frames, rendered a minute on,
    // a drift of the host's speed moved it by ±4 % between invocations).
    let mut first_ratios = Vec::with_capacity(runs);
    let loads = (|| -> Result<quadtex_render::Scene> {
        let file =
            quadtex_render::write_terrain(&dir, quadtex_render::TERRAIN_CELLS, width, height)?;
        let mut last = None;
        for _ in 0..runs {
            // The one before is dropped first: one terrain in memory.
            drop(last.take());
            let scene = quadtex_render::load_scene(&file, limits)?;
            if first_frames.is_empty() {
                terrain_load = started.elapsed().as_secs_f64();
            }
            let options = options_for(quadtree);
            let (mut image, first) = quadtex_render::render(&scene, &options, &|_, _| {})?;
            let mut later = Vec::with_capacity(FRAMES_AFTER_FIRST);
            for _ in 0..FRAMES_AFTER_FIRST {
                later.push(
                    quadtex_render::render_into(&scene, &options, &mut image, &|_, _| {})?.seconds,
                );
            }
            first_frames.push(first.seconds);
            first_ratios.push(first.seconds / median_range(later).0);
            last = Some(scene);
        }
        last.ok_or_else(|| "no terrain loaded".into())
    })();
    let _ = std::fs::remove_dir_all(&dir);
    let terrain = loads?;
    let (first_frame, first_lo, first_hi) = median_range(first_frames);
    let first_range = (first_lo, first_hi);
    // The first load runs on the process's fresh heap (its pages not yet
    // faulted in), as an application's start does; later loads reuse what
    // the one before freed.
    let cold_ratio = first_ratios.first().copied().unwrap_or(f64::NAN);
    let first_ratio = median_range(first_ratios);
    let scenes = [
        ("demo (built-in airfield)", quadtex_render::demo_scene()?),
        ("runway (`scenes/runway.toml`)", runway),
        ("terrain, 1 002 528 triangles (glTF)", terrain),
    ];
    let filters = [
        ("nearest", TextureFilter::Nearest),
        ("quadtree", quadtree),
        (
            "ewa",
            TextureFilter::Ewa {
                max_anisotropy: 8.0,
            },
        ),
    ];
    let mut out = Text::stdout();
    writeln!(
        out,
        "## quadtex bench --frames: {width}x{height}, median of {runs} runs (range), the filters in turn within each run, ratios of each run's frames; {} cores\n",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    )?;
    writeln!(
        out,
        "Terrain written and loaded (glTF read, hierarchy build, sun's shadow grid, texture packing) in {terrain_load:.2} s; its first frame after load (quadtree, which also classifies each triangle it lights for the sun's shadows, once; median of {runs} loads) took {:.0} ms ({:.0}–{:.0}).\n",
        first_frame * 1e3,
        first_range.0 * 1e3,
        first_range.1 * 1e3
    )?;
    writeln!(
        out,
        "| scene | nearest | quadtree | EWA (aniso 8) | quadtree / nearest | EWA / nearest | quadtree's filter share / nearest |"
    )?;
    writeln!(out, "|---|---:|---:|---:|---:|---:|---:|")?;
    for (name, scene) in &scenes {
        let options = filters.map(|(_, filter)| options_for(filter));
        let times = times_in_turn(scene, &options, runs)?;
        let per_run =
            |f: usize| -> Vec<f64> { times[f].iter().zip(&times[0]).map(|(t, n)| t / n).collect() };
        let [n, q, e] = [0, 1, 2].map(|f| median_range(times[f].clone()));
        let [q_ratio, e_ratio] = [1, 2].map(|f| median_range(per_run(f)));
        let ms = |(m, lo, hi): (f64, f64, f64)| {
            format!("{:.0} ms ({:.0}–{:.0})", m * 1e3, lo * 1e3, hi * 1e3)
        };
        let ratio = |(m, lo, hi): (f64, f64, f64)| format!("{m:.2} ({lo:.2}–{hi:.2})");
        writeln!(
            out,
            "| {name} | {} | {} | {} | {} | {} | {:.2} |",
            ms(n),
            ms(q),
            ms(e),
            ratio(q_ratio),
            ratio(e_ratio),
            q_ratio.0 - 1.0
        )?;
    }
    pixel_filter_table(&mut out, &scenes[0].1, runs, &options_for(quadtree))?;
    writeln!(
        out,
        "\nThe terrain's first frame after load took {:.3}× the median of the {FRAMES_AFTER_FIRST} frames after it (the median over the {runs} loads of each load's ratio; range {:.3}–{:.3}×; the process's first load {cold_ratio:.3}×).",
        first_ratio.0, first_ratio.1, first_ratio.2
    )?;
    out.flush()?;
    Ok(())
}

/// The frame times of `scene` under each of `options`, `runs` times: per
/// set of options, its times in run order. Each set renders into a frame
/// buffer of its own, as a real-time loop keeps one (the first run sizes,
/// allocates and clears, it), and the sets take turns within each run: a
/// drift of the host's speed over the runs moves them alike, and the
/// ratios of one run's frames cancel it.
fn times_in_turn(
    scene: &quadtex_render::Scene,
    options: &[quadtex_render::RenderOptions],
    runs: usize,
) -> Result<Vec<Vec<f64>>> {
    let mut images: Vec<_> = options
        .iter()
        .map(|_| quadtex_io::LinearImage::default())
        .collect();
    let mut times = vec![Vec::with_capacity(runs); options.len()];
    for _ in 0..runs {
        for ((options, image), t) in options.iter().zip(&mut images).zip(&mut times) {
            t.push(quadtex_render::render_into(scene, options, image, &|_, _| {})?.seconds);
        }
    }
    Ok(times)
}

/// The demo's quadtree frame under each pixel filter, `runs` times, the
/// filters in turn within each run: the tent's and Mitchell's times over
/// the box's of the same run (issue 64's targets: 3× and 5×).
fn pixel_filter_table(
    out: &mut Text,
    demo: &quadtex_render::Scene,
    runs: usize,
    options: &quadtex_render::RenderOptions,
) -> Result<()> {
    use quadtex_core::PixelFilter;
    let filters = [PixelFilter::Box, PixelFilter::Tent, PixelFilter::Mitchell];
    let times = times_in_turn(
        demo,
        &filters.map(|pixel_filter| quadtex_render::RenderOptions {
            pixel_filter,
            ..*options
        }),
        runs,
    )?;
    writeln!(
        out,
        "\nPixel filters on the demo (quadtree; median of {runs} runs, range; the filters in turn within each run):\n"
    )?;
    writeln!(out, "| pixel filter | frame | / box (each run's) |")?;
    writeln!(out, "|---|---:|---:|")?;
    for (f, filter) in filters.iter().enumerate() {
        let (m, lo, hi) = median_range(times[f].clone());
        let ratios = times[f].iter().zip(&times[0]).map(|(t, b)| t / b).collect();
        let (rm, rlo, rhi) = median_range(ratios);
        writeln!(
            out,
            "| {} | {:.0} ms ({:.0}–{:.0}) | {rm:.2} ({rlo:.2}–{rhi:.2}) |",
            filter.name(),
            m * 1e3,
            lo * 1e3,
            hi * 1e3
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_must_be_positive() {
        assert_eq!(at_least_one("--queries")("10"), Ok(10));
        assert_eq!(
            at_least_one("--queries")("0"),
            Err("--queries must be at least 1, got 0".to_string())
        );
        assert!(at_least_one("--runs")("-1").is_err());
    }

    #[test]
    fn texture_size_is_a_power_of_two_in_range() {
        assert_eq!(texture_size("64"), Ok(64));
        for bad in ["32", "100", "32768"] {
            assert_eq!(
                texture_size(bad),
                Err(format!(
                    "--size must be a power of two in 64..=16384, got {bad}"
                ))
            );
        }
    }
}

//! `quadtex pack`: an image or SVG art into a `.qtx` quadtree texture.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use quadtex_core::{BuildOptions, QuadTree};

use super::Result;
use super::common::{
    MemoryArgs, ResourcesArgs, blocks_summary, georeferenced, human_bytes, is_svg, level,
    raster_bytes, smooth_summary, tolerance,
};
use super::output::Output;

/// Max level of SVG art packed without `--max-level` (4096² effective).
const DEFAULT_SVG_LEVEL: u8 = 12;

/// Edges a contour leaf may hold when `--contour-leaves` is given without
/// a value.
const DEFAULT_CONTOUR_EDGES: u16 = 16;

/// Pack an image or SVG art into a quadtree texture.
///
/// Raster images (PNG, JPEG, TIFF and BigTIFF, OpenEXR, Radiance HDR) are
/// decoded to linear colour and packed, losslessly unless `--tolerance`
/// allows merging; a GeoTIFF's georeferencing is printed in the summary.
/// SVG art (`.svg`) is packed exactly: every cell's colour is the art's
/// coverage integral, at most level 24, by default 12 (4096² effective).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The image (PNG, JPEG, TIFF, OpenEXR, HDR) or SVG art to pack.
    #[arg(value_name = "IMAGE")]
    input: PathBuf,
    /// The .qtx file to write; `-` writes it to standard output (the
    /// summary then goes to standard error).
    #[arg(short, long, value_name = "OUT.qtx")]
    output: Output,
    /// Largest per-channel deviation (linear, premultiplied, full scale 1) of
    /// a cell from its terminal square's colour, in [0, 1]; 0 is lossless.
    /// For SVG art it applies to smooth colour only (edges and flat colour
    /// are exact), measured on sRGB-encoded channels, default a quarter of
    /// an 8-bit step: squares that gradients, images or masks paint stop
    /// splitting within it, and gradient leaves are seen by exact pixels
    /// as cells within it.
    #[arg(long, value_name = "T", allow_negative_numbers = true, value_parser = tolerance)]
    tolerance: Option<f64>,
    /// Depth of the finest cells (default: the image's natural depth; for
    /// SVG art 12, or 20 with --contour-leaves, lowered when the packing's
    /// estimate is above the memory budget; the summary says so). A level
    /// given here is kept: art that does not fit at it is refused.
    #[arg(long, value_name = "L", value_parser = level("--max-level"))]
    max_level: Option<u8>,
    /// SVG art: split squares painted by one linear gradient down to
    /// `--tolerance` instead of keeping the gradient in a leaf. The file
    /// is then version 2, which readers older than gradient leaves read.
    #[arg(long)]
    no_gradient_leaves: bool,
    /// SVG art: keep squares of flat art crossed by at most EDGES edges
    /// (default 16 when the flag is given without a value, raised up to
    /// 256 when the packing's estimate is above the memory budget) as
    /// contour leaves, exact at any magnification, instead of splitting
    /// them towards `--max-level`. The file is then version 3.
    #[arg(long, value_name = "EDGES", num_args = 0..=1,
          value_parser = clap::value_parser!(u16).range(3..=1024))]
    contour_leaves: Option<Option<u16>>,
    /// SVG art: flatten curves to within T of the texture's longer side
    /// (default 2^-22 with --contour-leaves, else a sixteenth of a square
    /// at --max-level), at least 2^-40. `quadtex info` states it for trees
    /// with contour leaves.
    #[arg(long, value_name = "T", value_parser = curve_tolerance)]
    curve_tolerance: Option<f64>,
    /// SVG art: refuse art whose exact trapezoid sweep needs more than
    /// STEPS steps in all (pairs of edges tested for a crossing, plus each
    /// edge in each slab between crossings), instead of packing it for
    /// minutes; the summary states the steps used. Default 2^31, about a
    /// minute.
    #[arg(long, value_name = "STEPS", value_parser = clap::value_parser!(u64).range(1..))]
    max_sweep_work: Option<u64>,
    #[command(flatten)]
    memory: MemoryArgs,
    #[command(flatten)]
    resources: ResourcesArgs,
}

/// A value parser: a curve tolerance in `[2^-40, 1]`.
fn curve_tolerance(text: &str) -> std::result::Result<f64, String> {
    let t = text.parse::<f64>().map_err(|e| e.to_string())?;
    if !(quadtex_io::MIN_CURVE_TOLERANCE..=1.0).contains(&t) {
        return Err(format!("--curve-tolerance must be in [2^-40, 1], got {t}"));
    }
    Ok(t)
}

/// Runs `quadtex pack`.
pub fn run(args: Args) -> Result<()> {
    let Args {
        input,
        output,
        tolerance,
        max_level,
        no_gradient_leaves,
        contour_leaves,
        curve_tolerance,
        max_sweep_work,
        memory,
        resources,
    } = args;
    let limits = resources.apply(memory.limits());
    let mut options = BuildOptions {
        max_level,
        max_nodes: limits.max_nodes,
        max_bytes: Some(limits.max_memory),
        ..BuildOptions::default()
    };
    if let Some(t) = tolerance {
        options.tolerance = t;
    }
    if is_svg(&input) {
        let adjustable = quadtex_core::Adjustable {
            max_level: max_level.is_none(),
            contour_edges: contour_leaves == Some(None),
        };
        let contour_leaves = contour_leaves.map(|edges| edges.unwrap_or(DEFAULT_CONTOUR_EDGES));
        let svg = quadtex_core::VectorOptions {
            max_level: options.max_level.unwrap_or(if contour_leaves.is_some() {
                quadtex_core::CONTOUR_MAX_LEVEL
            } else {
                DEFAULT_SVG_LEVEL
            }),
            tolerance: tolerance.unwrap_or(quadtex_core::DEFAULT_SMOOTH_TOLERANCE),
            gradient_leaves: !no_gradient_leaves,
            contour_leaves: contour_leaves.map(usize::from),
            curve_tolerance,
            max_sweep_work: max_sweep_work.unwrap_or(quadtex_core::DEFAULT_MAX_SWEEP_WORK),
            ..quadtex_core::VectorOptions::default()
        };
        let options = quadtex_io::SvgOptions {
            vector: svg,
            limits,
            adjustable,
        };
        return pack_svg(&input, &output, &options);
    }
    let progress = Progress::new();
    let start = Instant::now();
    // With more than one core, an 8-bit PNG is packed tile by tile while
    // it decodes; anything else (and on one core, where the tiles' splice
    // costs more than it saves) is read whole, then packed. The same tree
    // either way.
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let streamed = if threads > 1 {
        progress.stage(&format!("decoding and packing {}", input.display()));
        quadtex_io::pack_png_on_threads(&input, &options, &limits, threads)?
    } else {
        None
    };
    let (tree, report, (width, height), georeference) = match streamed {
        Some((tree, report, size)) => (tree, report, size, None),
        None => {
            progress.stage(&format!("decoding {}", input.display()));
            let (grid, georeference) = quadtex_io::load_texels_with_georeference(&input, &limits)?;
            progress.stage(&format!(
                "packing {}x{} texels",
                grid.width(),
                grid.height()
            ));
            let (tree, report) = QuadTree::from_texels(&grid, &options)
                .map_err(|e| format!("{}: {e}", input.display()))?;
            (tree, report, (grid.width(), grid.height()), georeference)
        }
    };
    progress.stage(&format!("writing {output}"));
    output.write_qtx(&tree, Some((width, height)))?;
    progress.finish();
    let terminals: u64 = tree.level_stats().iter().map(|l| l.terminals).sum();
    let bytes = tree.memory_bytes();
    let (raster, mips) = raster_bytes(width, height);
    let error = if report.max_error == 0.0 {
        "lossless".to_string()
    } else {
        format!("max error {:.6} (L∞ per channel, linear)", report.max_error)
    };
    let mut text = output.text();
    writeln!(
        text,
        "packed {} -> {}: {} nodes ({} terminal){}, depth {}, {} ({:.2} B/texel); RGBA8 raster / tree = {:.1}, raster+mips / tree = {:.1}; {}{}{}; {:.2} s",
        input.display(),
        output,
        tree.node_count(),
        terminals,
        blocks_summary(&tree),
        tree.depth(),
        human_bytes(bytes),
        bytes as f64 / (f64::from(width) * f64::from(height)),
        raster as f64 / bytes as f64,
        mips as f64 / bytes as f64,
        error,
        if report.resampled {
            ", cells resampled (area-weighted): --max-level is not the image's depth"
        } else {
            ""
        },
        georeferenced(georeference.as_ref()),
        start.elapsed().as_secs_f64()
    )?;
    text.flush()?;
    Ok(())
}

fn pack_svg(input: &Path, output: &Output, options: &quadtex_io::SvgOptions) -> Result<()> {
    let progress = Progress::new();
    let start = Instant::now();
    progress.stage(&format!("packing {}", input.display()));
    let (tree, report, fit) = quadtex_io::pack_svg_fitted(input, options)?;
    let level = fit.max_level;
    progress.stage(&format!("writing {output}"));
    let side = 1u32 << level.min(31);
    output.write_qtx(&tree, Some((side, side)))?;
    progress.finish();
    let bytes = tree.memory_bytes();
    let (raster, mips) = raster_bytes(side, side);
    let mut text = output.text();
    writeln!(
        text,
        "packed {} -> {}: {} nodes, depth {}, {} ({:.2} B/node); {}; effective {side}x{side}: RGBA8 raster / tree = {:.1}, raster+mips / tree = {:.1}; exact coverage, {} leaves swept (at most {} edges in one, {} sweep steps){}; {:.2} s",
        input.display(),
        output,
        tree.node_count(),
        tree.depth(),
        human_bytes(bytes),
        bytes as f64 / tree.node_count() as f64,
        fit_summary(&fit, &options.adjustable),
        raster as f64 / bytes as f64,
        mips as f64 / bytes as f64,
        report.swept_leaves,
        report.max_leaf_edges,
        report.sweep_work,
        smooth_summary(&report),
        start.elapsed().as_secs_f64()
    )?;
    text.flush()?;
    Ok(())
}

/// The summary's words on the level (and contour-leaf budget) packed at:
/// `level 20 (default) with contour leaves of up to 16 edges, estimated
/// peak 156.6 MiB within the memory budget of 17.7 GiB`, or, when what was
/// asked for did not fit, what was chosen instead and why.
fn fit_summary(fit: &quadtex_core::BudgetFit, adjustable: &quadtex_core::Adjustable) -> String {
    use quadtex_core::memory::format_bytes;
    let edges = |e: Option<usize>| {
        e.map_or(String::new(), |e| {
            format!(" with contour leaves of up to {e} edges")
        })
    };
    let (estimate, budget) = (fit.estimate.unwrap_or(0), fit.budget.unwrap_or(0));
    if let Some((level, asked_edges, asked)) = fit.asked {
        let defaults = match (level != fit.max_level, asked_edges != fit.contour_leaves) {
            (true, true) => format!(
                "the defaults, level {level} and {} edges, need",
                asked_edges.unwrap_or(0)
            ),
            (false, true) => format!("the default, {} edges, needs", asked_edges.unwrap_or(0)),
            _ => format!("the default, level {level}, needs"),
        };
        return format!(
            "level {}{} chosen to fit the memory budget of {} (estimated peak {}; {defaults} an estimated {})",
            fit.max_level,
            edges(fit.contour_leaves),
            format_bytes(budget),
            format_bytes(estimate),
            format_bytes(asked)
        );
    }
    let default = if adjustable.max_level {
        " (default)"
    } else {
        ""
    };
    let within = match (fit.estimate, fit.budget) {
        (Some(e), Some(b)) => format!(
            ", estimated peak {} within the memory budget of {}",
            format_bytes(e),
            format_bytes(b)
        ),
        _ => String::new(),
    };
    format!(
        "level {}{default}{}{within}",
        fit.max_level,
        edges(fit.contour_leaves)
    )
}

/// Stage messages on a spinner when stderr is a terminal, nothing otherwise.
struct Progress(Option<indicatif::ProgressBar>);

impl Progress {
    fn new() -> Progress {
        Progress(std::io::stderr().is_terminal().then(|| {
            let bar = indicatif::ProgressBar::new_spinner();
            bar.enable_steady_tick(std::time::Duration::from_millis(120));
            bar
        }))
    }
    fn stage(&self, message: &str) {
        if let Some(bar) = &self.0 {
            bar.set_message(message.to_string());
        }
    }
    fn finish(&self) {
        if let Some(bar) = &self.0 {
            bar.finish_and_clear();
        }
    }
}

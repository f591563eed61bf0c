//! `quadtex pack-tiles`: a folder of raster tiles, or a tiled TIFF, into
//! one `.qtx` tree.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use super::Result;
use super::common::{MemoryArgs, georeferenced, human_bytes, raster_bytes, tolerance};
use super::output::Output;

/// Pack a folder of raster tiles, or a tiled TIFF, into one quadtree texture.
///
/// The folder holds tiles named ROW_COL.png (or .jpg, .tif; row 0 at the
/// top): a complete square grid of 1, 2, 4, 8, … tiles a side, every tile
/// the same square of a power of two texels. A tiled TIFF (BigTIFF and
/// Cloud-Optimized GeoTIFF included) may be any size, partial edge tiles
/// included; its tiles must be squares of a power of two texels. Tiles are
/// packed one at a time,
/// so memory holds one tile's texels and the tree, never the whole mosaic;
/// the tree is the one `pack` would build from the mosaic. A missing,
/// duplicate, odd-sized or undecodable tile is an error naming it; nothing
/// is written.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The folder of ROW_COL.png tiles, or a tiled TIFF.
    #[arg(value_name = "DIR|FILE.tif")]
    dir: PathBuf,
    /// The .qtx file to write; `-` writes it to standard output (the
    /// summary then goes to standard error).
    #[arg(short, long, value_name = "OUT.qtx")]
    output: Output,
    /// Largest per-channel deviation (linear, premultiplied, full scale 1)
    /// of a texel from its terminal square's colour, in [0, 1]; 0 (the
    /// default) is lossless.
    #[arg(long, value_name = "T", default_value_t = 0.0, value_parser = tolerance)]
    tolerance: f64,
    /// Threads packing tiles (each holds one tile's texels); the output is
    /// the same file whatever the count. Default: every core.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    #[command(flatten)]
    memory: MemoryArgs,
}

/// Runs `quadtex pack-tiles`.
pub fn run(args: Args) -> Result<()> {
    let start = Instant::now();
    let limits = args.memory.limits();
    let folder = quadtex_io::TileSource::open(&args.dir, &limits)?;
    let threads = args.threads.map_or_else(
        || std::thread::available_parallelism().map_or(1, |n| n.get()),
        usize::from,
    );
    let (tree, report) =
        quadtex_io::pack_tiles_on_threads(&folder, args.tolerance, &limits, threads)?;
    let packed = start.elapsed().as_secs_f64();
    let (width, height) = folder.extent();
    args.output.write_qtx(&tree, Some((width, height)))?;
    let bytes = tree.memory_bytes();
    let (raster, mips) = raster_bytes(width, height);
    let error = if report.max_error == 0.0 {
        "lossless".to_string()
    } else {
        format!("max error {:.6} (L∞ per channel, linear)", report.max_error)
    };
    let mut text = args.output.text();
    writeln!(
        text,
        "packed {}x{} tiles of {}x{} from {} -> {}: {width}x{height} texels, {} nodes, depth {}, {}; RGBA8 raster / tree = {:.1}, raster+mips / tree = {:.1}; {error}{}; packed in {packed:.2} s on {threads} thread{}, {:.2} s with writing{}",
        width.div_ceil(folder.side()),
        height.div_ceil(folder.side()),
        folder.side(),
        folder.side(),
        args.dir.display(),
        args.output,
        tree.node_count(),
        tree.depth(),
        human_bytes(bytes),
        raster as f64 / bytes as f64,
        mips as f64 / bytes as f64,
        georeferenced(folder.georeference()),
        if threads == 1 { "" } else { "s" },
        start.elapsed().as_secs_f64(),
        peak_memory().map_or(String::new(), |m| format!(
            "; peak memory {}",
            human_bytes(m)
        ))
    )?;
    text.flush()?;
    Ok(())
}

/// The process's peak resident memory (`VmHWM`), where the system reports it.
fn peak_memory() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

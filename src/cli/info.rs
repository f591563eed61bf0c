//! `quadtex info`: a `.qtx` file's size, depth and nodes per level, or SVG
//! art's tree against rasters of the same effective resolution.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use quadtex_core::MAX_VECTOR_LEVEL;

use super::Result;
use super::common::{MemoryArgs, ResourcesArgs, human_bytes, is_svg, raster_bytes, smooth_summary};
use super::output::Text;

/// Describe a .qtx file, or SVG art's tree against rasters per level.
///
/// For a .qtx file: its size, depth, nodes, memory, the raster it replaces
/// and its nodes per level. For SVG art: the art packed at several levels
/// against RGBA8 rasters of the same effective resolution, and the deepest
/// level whose tree fits in 1 MiB.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The .qtx file or SVG art to describe.
    #[arg(value_name = "FILE")]
    path: PathBuf,
    /// SVG art only: the levels to pack, comma-separated [default: 8,10,12,14,16].
    #[arg(long, value_name = "L,L,...", value_delimiter = ',', value_parser = vector_level)]
    levels: Option<Vec<u8>>,
    /// A .qtx file is memory-mapped and its header, structure and payload
    /// checksum are checked (one pass at memory speed); with --verify, read
    /// it whole and check every colour as well.
    #[arg(long, conflicts_with = "no_verify")]
    verify: bool,
    /// For trusted .qtx files: map without checking the payload checksum
    /// (opens in time proportional to the structure, 1/64 of the file),
    /// giving up the promise that a damaged file is refused.
    #[arg(long)]
    no_verify: bool,
    #[command(flatten)]
    memory: MemoryArgs,
    #[command(flatten)]
    resources: ResourcesArgs,
}

/// A value parser: one of `--levels`, at most the vector packer's limit.
fn vector_level(text: &str) -> std::result::Result<u8, String> {
    let l: u8 = text
        .trim()
        .parse()
        .map_err(|e| format!("--levels: `{text}`: {e}"))?;
    if l > MAX_VECTOR_LEVEL {
        return Err(format!(
            "--levels: {l} exceeds the vector packer's limit {MAX_VECTOR_LEVEL}"
        ));
    }
    Ok(l)
}

/// Runs `quadtex info`.
pub fn run(args: Args) -> Result<()> {
    let Args {
        path,
        levels,
        verify,
        no_verify,
        memory,
        resources,
    } = args;
    let limits = resources.apply(memory.limits());
    if is_svg(&path) {
        return info_svg(
            &path,
            levels.as_deref().unwrap_or(&[8, 10, 12, 14, 16]),
            &limits,
        );
    }
    if levels.is_some() {
        return Err("--levels applies to SVG art only".into());
    }
    let start = Instant::now();
    let (tree, meta) = if verify {
        quadtex_io::read_qtx(&path, &limits)?
    } else if no_verify {
        quadtex_io::map_qtx_unverified(&path, &limits)?
    } else {
        quadtex_io::map_qtx(&path, &limits)?
    };
    let opened = start.elapsed();
    let bytes = tree.memory_bytes();
    let mut out = Text::stdout();
    writeln!(
        out,
        "file:        {} ({})",
        path.display(),
        human_bytes(meta.file_bytes)
    )?;
    writeln!(
        out,
        "opened:      in {:.1} ms, {}",
        opened.as_secs_f64() * 1e3,
        if verify {
            "read whole; checksums, structure and every colour verified"
        } else if no_verify {
            "mapped unverified; header and structure checked, colours not read (--verify reads them)"
        } else {
            "mapped; checksums and structure checked (--verify checks every colour too)"
        }
    )?;
    writeln!(out, "depth:       {}", tree.depth())?;
    let [columns, rows] = tree.finest_grid();
    let aspect = tree.aspect();
    writeln!(
        out,
        "cells:       {columns}x{rows} at the deepest level{}",
        match aspect.shrink() {
            Some([0, 0]) => String::new(),
            Some([s, 0]) => format!(
                " (texture is the left 1/{} of the tree's square)",
                1u64 << s
            ),
            Some([_, s]) => format!(
                " (texture is the bottom 1/{} of the tree's square)",
                1u64 << s
            ),
            None => {
                let [cx, cz] = aspect.cells();
                let side = 1u64 << aspect.level();
                format!(
                    " (texture is the bottom-left {cx}/{side} x {cz}/{side} of the tree's square)"
                )
            }
        }
    )?;
    writeln!(out, "nodes:       {}", tree.node_count())?;
    if let Some(b) = tree.texel_blocks() {
        let side = 1u32 << b.log2_side();
        writeln!(
            out,
            "blocks:      {} of {side}x{side} texels at level {}, stored as {} ({})",
            b.count(),
            b.level(),
            b.format().name(),
            human_bytes(b.data().len() as u64)
        )?;
    }
    writeln!(
        out,
        "memory:      {} ({:.3} bytes/node with blocks; colour 8 B/node{})",
        human_bytes(bytes),
        bytes as f64 / tree.node_count() as f64,
        if verify {
            ""
        } else {
            "; colours and texels stay in the mapped file, paged in as read"
        }
    )?;
    writeln!(out, "colours:     {}", tree.encoding().name())?;
    if let Some(c) = tree.contour_leaves() {
        writeln!(
            out,
            "contours:    {} leaves keep {} contour points (at most {} edges in one): flat art exact at any magnification; fragment integrals exact at every level, exact pixels see cells down to level {}",
            c.count(),
            c.point_count(),
            c.max_leaf_edges(),
            c.depth()
        )?;
        match c.curve_tolerance() {
            Some(t) => writeln!(
                out,
                "curves:      flattened to within {t:.3e} of the texture's side (2^{:.1}); edges between their points are exact",
                t.log2()
            )?,
            None => writeln!(
                out,
                "curves:      flattening not stated (written before quadtex recorded it)"
            )?,
        }
    }
    if let Some(g) = tree.gradient_leaves() {
        writeln!(
            out,
            "gradient:    {} leaves, {} paints (linear gradients composited with flat colour): fragment integrals exact at any level; stored nodes reach level {}, exact pixels see cells down to level {} within {:.6} (sRGB-encoded) of their colour",
            g.count(),
            g.paints().len(),
            tree.stored_depth(),
            g.depth(),
            g.tolerance()
        )?;
    }
    let (w, h) = if meta.source_width > 0 {
        (meta.source_width, meta.source_height)
    } else {
        let clamp = |n: u64| u32::try_from(n).unwrap_or(u32::MAX);
        (clamp(columns), clamp(rows))
    };
    let (raster, mips) = raster_bytes(w, h);
    writeln!(
        out,
        "source:      {w}x{h}; RGBA8 raster {} ({:.1}x the tree), raster+mips {} ({:.1}x)",
        human_bytes(raster),
        raster as f64 / bytes as f64,
        human_bytes(mips),
        mips as f64 / bytes as f64
    )?;
    let avg = tree.average();
    writeln!(
        out,
        "average:     {} {} {} {} (linear, premultiplied)",
        avg.r, avg.g, avg.b, avg.a
    )?;
    writeln!(out, "level      nodes  terminals")?;
    for l in tree.level_stats() {
        writeln!(out, "{:>5} {:>10} {:>10}", l.level, l.nodes, l.terminals)?;
    }
    out.flush()?;
    Ok(())
}

/// `info ART.svg`: the art packed at several levels against rasters of the
/// The default SVG packing at `level` under `limits`.
fn svg_options(level: u8, limits: &quadtex_io::Limits) -> quadtex_io::SvgOptions {
    quadtex_io::SvgOptions {
        limits: *limits,
        ..quadtex_io::SvgOptions::at_level(level)
    }
}

/// same effective resolution, and the deepest level that fits in 1 MiB.
fn info_svg(path: &Path, levels: &[u8], limits: &quadtex_io::Limits) -> Result<()> {
    let mut out = Text::stdout();
    writeln!(out, "{}: exact vector packing", path.display())?;
    writeln!(
        out,
        "level  effective        nodes   tree bytes   RGBA8 raster  raster+mips  raster+mips/tree   pack s"
    )?;
    let mut smooth = Vec::new();
    let mut rows = levels.to_vec();
    rows.sort_unstable();
    rows.dedup();
    for level in rows {
        let start = Instant::now();
        let (tree, report) = quadtex_io::pack_svg(path, &svg_options(level, limits))?;
        let seconds = start.elapsed().as_secs_f64();
        smooth.push((level, report));
        let bytes = tree.memory_bytes();
        let side = 1u64 << level;
        let raster = 4 * side * side;
        let mips = raster * 4 / 3;
        writeln!(
            out,
            "{level:>5}  {:>9}  {:>11}  {:>11}  {:>13}  {:>11}  {:>16.1}  {:>7.2}",
            format!("{side}²"),
            tree.node_count(),
            human_bytes(bytes),
            human_bytes(raster),
            human_bytes(mips),
            mips as f64 / bytes as f64,
            seconds
        )?;
    }
    // Gradients are the one approximation: say how far, per level.
    for (level, report) in smooth {
        let summary = smooth_summary(&report);
        if !summary.is_empty() {
            writeln!(
                out,
                "level {level}{summary} (tolerance {:.6}, a quarter of an 8-bit step)",
                quadtex_core::DEFAULT_SMOOTH_TOLERANCE
            )?;
        }
    }
    // Trees only grow with the level, so walk up until one exceeds 1 MiB.
    let mut fits = None;
    for level in 0..=MAX_VECTOR_LEVEL {
        let (tree, _) = quadtex_io::pack_svg(path, &svg_options(level, limits))?;
        if tree.memory_bytes() > 1 << 20 {
            break;
        }
        fits = Some(level);
    }
    match fits {
        Some(l) => writeln!(
            out,
            "deepest level within 1 MiB: {l} ({}² effective)",
            1u64 << l
        ),
        None => writeln!(
            out,
            "deepest level within 1 MiB: none (the root alone is larger)"
        ),
    }?;
    out.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_are_trimmed_and_bounded() {
        assert_eq!(vector_level(" 12"), Ok(12));
        assert_eq!(
            vector_level("25"),
            Err(format!(
                "--levels: 25 exceeds the vector packer's limit {MAX_VECTOR_LEVEL}"
            ))
        );
        assert!(vector_level("x").is_err_and(|e| e.starts_with("--levels: `x`: ")));
    }
}

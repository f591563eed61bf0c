//! `quadtex`: pack textures into incomplete quadtrees, inspect and query them,
//! benchmark the fragment integral, and render scenes.

mod bench;
mod compare;
mod peers;

use std::error::Error;
use std::io::{BufRead, BufWriter, IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use lexopt::prelude::*;
use quadtex_core::{BuildOptions, MAX_DEPTH, QuadTree};

type Result<T> = std::result::Result<T, Box<dyn Error>>;

const USAGE: &str = "\
quadtex: alias-free texture mapping with incomplete-quadtree textures

USAGE:
  quadtex pack IMAGE -o OUT.qtx [--tolerance T] [--max-level L]
  quadtex pack ART.svg -o OUT.qtx [--max-level L]     (exact vector packing, L <= 24, default 12)
  quadtex info FILE.qtx
  quadtex info ART.svg [--levels 8,12,16]    (tree vs raster bytes per level)
  quadtex query FILE.qtx [--level K]      (fragments `x0 z0 x1 z1` on stdin)
  quadtex demo [-o demo.png] [RENDER OPTIONS]          (built-in airfield scene)
  quadtex render SCENE.toml -o OUT.png|OUT.exr [RENDER OPTIONS]
      RENDER OPTIONS: [--width W] [--height H]
                      [--filter quadtree|nearest|bilinear|supersample:N|trilinear|ewa|sat]
                      [--quality Q] [--level K] [--pixel-filter box|tent]
  quadtex compare SCENE.toml -o DIR [COMPARE OPTIONS]   (every filter vs a reference: report.html)
  quadtex demo --compare -o DIR [COMPARE OPTIONS]
      COMPARE OPTIONS: [--width W] [--reference-spp N] [--frames F] [--no-flip]
  quadtex footprints SCENE.toml -o DIR [--width W] [--passes P]   (dump lookups for a peer, time ours)
  quadtex diff REFERENCE.exr TEST.exr                  (RMSE and FLIP)
  quadtex bench [--size N] [--queries Q] [--runs R]
  quadtex sample runway|checker -o OUT.png [--size N]   (built-in art as a PNG)
  quadtex help
";

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("Error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<()> {
    let mut parser = lexopt::Parser::from_env();
    let Some(arg) = parser.next()? else {
        print!("{USAGE}");
        return Ok(());
    };
    let command = match arg {
        Value(v) => v.string()?,
        Long("help") | Short('h') => "help".to_string(),
        other => return Err(other.unexpected().into()),
    };
    match command.as_str() {
        "pack" => pack(&mut parser),
        "info" => info(&mut parser),
        "query" => query(&mut parser),
        "bench" => bench::run(&mut parser),
        "render" => render(&mut parser, false),
        "compare" => compare::run(&mut parser),
        "footprints" => peers::footprints(&mut parser),
        "diff" => peers::diff(&mut parser),
        "demo" => render(&mut parser, true),
        "sample" => sample(&mut parser),
        "help" => {
            print!("{USAGE}");
            Ok(())
        }
        other => Err(format!("unknown command `{other}`\n\n{USAGE}").into()),
    }
}

fn parse_level(parser: &mut lexopt::Parser, flag: &str) -> Result<u8> {
    let v: u32 = parser
        .value()?
        .parse()
        .map_err(|e| format!("{flag}: {e}"))?;
    if v > u32::from(MAX_DEPTH) {
        return Err(format!("{flag} {v} exceeds the maximum depth {MAX_DEPTH}").into());
    }
    Ok(v as u8)
}

fn pack(parser: &mut lexopt::Parser) -> Result<()> {
    let (mut input, mut output) = (None::<PathBuf>, None::<PathBuf>);
    let mut options = BuildOptions::default();
    while let Some(arg) = parser.next()? {
        match arg {
            Short('o') | Long("output") => output = Some(parser.value()?.into()),
            Long("tolerance") => {
                let t: f64 = parser
                    .value()?
                    .parse()
                    .map_err(|e| format!("--tolerance: {e}"))?;
                if !(t.is_finite() && (0.0..=1.0).contains(&t)) {
                    return Err(format!("--tolerance must be in [0, 1], got {t}").into());
                }
                options.tolerance = t;
            }
            Long("max-level") => options.max_level = Some(parse_level(parser, "--max-level")?),
            Value(v) if input.is_none() => input = Some(v.into()),
            other => return Err(other.unexpected().into()),
        }
    }
    let input = input.ok_or("pack: missing IMAGE")?;
    let output = output.ok_or("pack: missing -o OUT.qtx")?;
    if is_svg(&input) {
        if options.tolerance != 0.0 {
            return Err(format!(
                "{}: --tolerance applies to raster images; SVG art packs exactly",
                input.display()
            )
            .into());
        }
        return pack_svg(
            &input,
            &output,
            options.max_level.unwrap_or(DEFAULT_SVG_LEVEL),
        );
    }
    let progress = Progress::new();
    let start = Instant::now();
    progress.stage(&format!("decoding {}", input.display()));
    let grid = quadtex_io::load_texels(&input)?;
    progress.stage(&format!(
        "packing {}x{} texels",
        grid.width(),
        grid.height()
    ));
    let (tree, report) =
        QuadTree::from_texels(&grid, &options).map_err(|e| format!("{}: {e}", input.display()))?;
    progress.stage(&format!("writing {}", output.display()));
    quadtex_io::write_qtx(&output, &tree, Some((grid.width(), grid.height())))?;
    progress.finish();
    let terminals: u64 = tree.level_stats().iter().map(|l| l.terminals).sum();
    let bytes = tree.memory_bytes();
    let (raster, mips) = raster_bytes(grid.width(), grid.height());
    let error = if report.max_error == 0.0 {
        "lossless".to_string()
    } else {
        format!("max error {:.6} (L∞ per channel, linear)", report.max_error)
    };
    println!(
        "packed {} -> {}: {} nodes ({} terminal), depth {}, {} ({:.2} B/node); RGBA8 raster / tree = {:.1}, raster+mips / tree = {:.1}; {}{}; {:.2} s",
        input.display(),
        output.display(),
        tree.node_count(),
        terminals,
        tree.depth(),
        human_bytes(bytes),
        bytes as f64 / tree.node_count() as f64,
        raster as f64 / bytes as f64,
        mips as f64 / bytes as f64,
        error,
        if report.resampled {
            ", cells resampled (area-weighted) from a non-power-of-two raster"
        } else {
            ""
        },
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Max level of SVG art packed without `--max-level` (4096² effective).
const DEFAULT_SVG_LEVEL: u8 = 12;

fn is_svg(path: &std::path::Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
}

fn pack_svg(input: &std::path::Path, output: &std::path::Path, level: u8) -> Result<()> {
    let progress = Progress::new();
    let start = Instant::now();
    progress.stage(&format!("packing {} at level {level}", input.display()));
    let (tree, report) = quadtex_io::pack_svg(input, level, &quadtex_io::Limits::default())?;
    progress.stage(&format!("writing {}", output.display()));
    let side = 1u32 << level.min(31);
    quadtex_io::write_qtx(output, &tree, Some((side, side)))?;
    progress.finish();
    let bytes = tree.memory_bytes();
    let (raster, mips) = raster_bytes(side, side);
    println!(
        "packed {} -> {}: {} nodes, depth {}, {} ({:.2} B/node); effective {side}x{side}: RGBA8 raster / tree = {:.1}, raster+mips / tree = {:.1}; exact coverage, {} leaves swept; {:.2} s",
        input.display(),
        output.display(),
        tree.node_count(),
        tree.depth(),
        human_bytes(bytes),
        bytes as f64 / tree.node_count() as f64,
        raster as f64 / bytes as f64,
        mips as f64 / bytes as f64,
        report.swept_leaves,
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// `info ART.svg`: the art packed at several levels against rasters of the
/// same effective resolution, and the deepest level that fits in 1 MiB.
fn info_svg(path: &std::path::Path, levels: &[u8]) -> Result<()> {
    let limits = quadtex_io::Limits::default();
    println!("{}: exact vector packing", path.display());
    println!(
        "level  effective        nodes   tree bytes   RGBA8 raster  raster+mips  raster+mips/tree   pack s"
    );
    let mut rows = levels.to_vec();
    rows.sort_unstable();
    rows.dedup();
    for level in rows {
        let start = Instant::now();
        let (tree, _) = quadtex_io::pack_svg(path, level, &limits)?;
        let seconds = start.elapsed().as_secs_f64();
        let bytes = tree.memory_bytes();
        let side = 1u64 << level;
        let raster = 4 * side * side;
        let mips = raster * 4 / 3;
        println!(
            "{level:>5}  {:>9}  {:>11}  {:>11}  {:>13}  {:>11}  {:>16.1}  {:>7.2}",
            format!("{side}²"),
            tree.node_count(),
            human_bytes(bytes),
            human_bytes(raster),
            human_bytes(mips),
            mips as f64 / bytes as f64,
            seconds
        );
    }
    // Trees only grow with the level, so walk up until one exceeds 1 MiB.
    let mut fits = None;
    for level in 0..=quadtex_core::vector::MAX_VECTOR_LEVEL {
        let (tree, _) = quadtex_io::pack_svg(path, level, &limits)?;
        if tree.memory_bytes() > 1 << 20 {
            break;
        }
        fits = Some(level);
    }
    match fits {
        Some(l) => println!("deepest level within 1 MiB: {l} ({}² effective)", 1u64 << l),
        None => println!("deepest level within 1 MiB: none (the root alone is larger)"),
    }
    Ok(())
}

/// Bytes of an RGBA8 raster and of the raster with its full mip pyramid.
fn raster_bytes(width: u32, height: u32) -> (u64, u64) {
    let raster = 4 * u64::from(width) * u64::from(height);
    let (mut w, mut h, mut mips) = (u64::from(width), u64::from(height), 0u64);
    loop {
        mips += 4 * w * h;
        if w == 1 && h == 1 {
            break;
        }
        w = (w / 2).max(1);
        h = (h / 2).max(1);
    }
    (raster, mips)
}

fn human_bytes(b: u64) -> String {
    match b {
        b if b >= 1 << 30 => format!("{:.2} GiB", b as f64 / f64::from(1u32 << 30)),
        b if b >= 1 << 20 => format!("{:.2} MiB", b as f64 / f64::from(1u32 << 20)),
        b if b >= 1 << 10 => format!("{:.1} KiB", b as f64 / 1024.0),
        b => format!("{b} B"),
    }
}

/// `render` and `demo`: the same options; `demo` builds its scene in code.
fn render(parser: &mut lexopt::Parser, demo: bool) -> Result<()> {
    use quadtex_render::{Filter, LevelOfDetail, RenderOptions};
    let (mut scene_path, mut output) = (None::<PathBuf>, None::<PathBuf>);
    let mut options = RenderOptions::default();
    let (mut quality, mut level, mut filter_name) = (1.0f64, None::<u8>, "quadtree".to_string());
    let (mut comparing, mut compare_settings) = (false, compare::Settings::default());
    while let Some(arg) = parser.next()? {
        if demo {
            if arg == Long("compare") {
                comparing = true;
                continue;
            }
            if comparing
                && let Some(name) = compare::long_name(&arg)
                && compare::OPTIONS.contains(&name.as_str())
            {
                compare::parse_option(&name, parser, &mut compare_settings)?;
                continue;
            }
        }
        match arg {
            Short('o') | Long("output") => output = Some(parser.value()?.into()),
            Long("width") => {
                options.width = Some(
                    parser
                        .value()?
                        .parse()
                        .map_err(|e| format!("--width: {e}"))?,
                )
            }
            Long("height") => {
                options.height = Some(
                    parser
                        .value()?
                        .parse()
                        .map_err(|e| format!("--height: {e}"))?,
                )
            }
            Long("filter") => filter_name = parser.value()?.string()?,
            Long("quality") => {
                quality = parser
                    .value()?
                    .parse()
                    .map_err(|e| format!("--quality: {e}"))?;
                if !(1.0..=64.0).contains(&quality) {
                    return Err(format!("--quality must be in 1..=64, got {quality}").into());
                }
            }
            Long("level") => level = Some(parse_level(parser, "--level")?),
            Long("pixel-filter") => {
                options.pixel_filter = match parser.value()?.string()?.as_str() {
                    "box" => quadtex_render::PixelFilter::Box,
                    "tent" => quadtex_render::PixelFilter::Tent,
                    other => {
                        return Err(format!("--pixel-filter {other}: expected box or tent").into());
                    }
                }
            }
            Value(v) if !demo && scene_path.is_none() => scene_path = Some(v.into()),
            other => return Err(other.unexpected().into()),
        }
    }
    options.filter = match filter_name.as_str() {
        "quadtree" => Filter::Quadtree {
            quality,
            lod: level.map_or(LevelOfDetail::ErrorBound(1.0 / 512.0), LevelOfDetail::Fixed),
        },
        "nearest" => Filter::Nearest,
        "trilinear" => Filter::Trilinear,
        "ewa" => Filter::Ewa {
            max_anisotropy: 8.0,
        },
        "sat" => Filter::Sat { quality },
        "bilinear" => Filter::Bilinear,
        other => match other.strip_prefix("supersample:").map(str::parse::<u32>) {
            Some(Ok(n)) => Filter::Supersample(n),
            _ => {
                return Err(format!(
                    "--filter {other}: expected quadtree, nearest, bilinear, supersample:N, trilinear, ewa or sat"
                )
                .into());
            }
        },
    };
    if comparing {
        if let Some(w) = options.width {
            compare_settings.width = w;
        }
        let dir = output.ok_or("demo --compare: missing -o DIR")?;
        return compare::compare_scene(
            &quadtex_render::demo_scene()?,
            "demo",
            &dir,
            &compare_settings,
        );
    }
    let (scene, output) = if demo {
        (
            quadtex_render::demo_scene()?,
            output.unwrap_or_else(|| PathBuf::from("demo.png")),
        )
    } else {
        let path = scene_path.ok_or("render: missing SCENE.toml")?;
        let out = output.ok_or("render: missing -o OUT.png")?;
        (quadtex_render::load_scene(&path)?, out)
    };
    let ext = output
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(ext.as_deref(), Some("png" | "exr")) {
        return Err(format!("{}: output must end in .png or .exr", output.display()).into());
    }
    let bar = std::io::stderr().is_terminal().then(|| {
        let bar = indicatif::ProgressBar::new(0);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} rows {elapsed}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    });
    let progress = |done: u64, total: u64| {
        if let Some(bar) = &bar {
            bar.set_length(total);
            bar.set_position(done);
        }
    };
    let (image, summary) = quadtex_render::render(&scene, &options, &progress)?;
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    quadtex_io::save_image(&output, &image)?;
    println!("wrote {}", output.display());
    println!("{summary}");
    Ok(())
}

fn sample(parser: &mut lexopt::Parser) -> Result<()> {
    let (mut which, mut output, mut size) = (None::<String>, None::<PathBuf>, 1024u32);
    while let Some(arg) = parser.next()? {
        match arg {
            Short('o') | Long("output") => output = Some(parser.value()?.into()),
            Long("size") => {
                size = parser
                    .value()?
                    .parse()
                    .map_err(|e| format!("--size: {e}"))?
            }
            Value(v) if which.is_none() => which = Some(v.string()?),
            other => return Err(other.unexpected().into()),
        }
    }
    let output = output.ok_or("sample: missing -o OUT.png")?;
    if !(1..=32768).contains(&size) {
        return Err(format!("--size must be in 1..=32768, got {size}").into());
    }
    let grid = match which.as_deref() {
        Some("runway") => quadtex_core::synth::runway_art().rasterise(size, size)?,
        Some("checker") => quadtex_core::synth::checkerboard(8, size)?,
        other => {
            return Err(format!("sample: expected `runway` or `checker`, got {other:?}").into());
        }
    };
    let pixels = grid.texels().iter().map(|t| t.to_rgba()).collect();
    drop(grid);
    quadtex_io::save_image(
        &output,
        &quadtex_io::LinearImage {
            width: size,
            height: size,
            pixels,
        },
    )?;
    println!("wrote {} ({size}x{size})", output.display());
    Ok(())
}

fn info(parser: &mut lexopt::Parser) -> Result<()> {
    let (mut path, mut levels) = (None::<PathBuf>, None::<Vec<u8>>);
    while let Some(arg) = parser.next()? {
        match arg {
            Long("levels") => {
                let text = parser.value()?.string()?;
                let mut v = Vec::new();
                for part in text.split(',') {
                    let l: u8 = part
                        .trim()
                        .parse()
                        .map_err(|e| format!("--levels: `{part}`: {e}"))?;
                    if l > quadtex_core::vector::MAX_VECTOR_LEVEL {
                        return Err(format!(
                            "--levels: {l} exceeds the vector packer's limit {}",
                            quadtex_core::vector::MAX_VECTOR_LEVEL
                        )
                        .into());
                    }
                    v.push(l);
                }
                levels = Some(v);
            }
            Value(v) if path.is_none() => path = Some(v.into()),
            other => return Err(other.unexpected().into()),
        }
    }
    let path = path.ok_or("info: missing FILE")?;
    if is_svg(&path) {
        return info_svg(&path, levels.as_deref().unwrap_or(&[8, 10, 12, 14, 16]));
    }
    if levels.is_some() {
        return Err("--levels applies to SVG art only".into());
    }
    let (tree, meta) = quadtex_io::read_qtx_with_limits(&path, &quadtex_io::Limits::default())?;
    let bytes = tree.memory_bytes();
    println!(
        "file:        {} ({})",
        path.display(),
        human_bytes(meta.file_bytes)
    );
    println!("depth:       {}", tree.depth());
    println!("nodes:       {}", tree.node_count());
    println!(
        "memory:      {} ({:.3} bytes/node; colour 8 B/node as unorm16 RGBA)",
        human_bytes(bytes),
        bytes as f64 / tree.node_count() as f64
    );
    let (w, h) = if meta.source_width > 0 {
        (meta.source_width, meta.source_height)
    } else {
        let side = 1u32.checked_shl(tree.depth().into()).unwrap_or(u32::MAX);
        (side, side)
    };
    let (raster, mips) = raster_bytes(w, h);
    println!(
        "source:      {w}x{h}; RGBA8 raster {} ({:.1}x the tree), raster+mips {} ({:.1}x)",
        human_bytes(raster),
        raster as f64 / bytes as f64,
        human_bytes(mips),
        mips as f64 / bytes as f64
    );
    let avg = tree.average().to_rgba();
    println!(
        "average:     {} {} {} {} (linear, premultiplied)",
        avg.r, avg.g, avg.b, avg.a
    );
    println!("level      nodes  terminals");
    for l in tree.level_stats() {
        println!("{:>5} {:>10} {:>10}", l.level, l.nodes, l.terminals);
    }
    Ok(())
}

fn query(parser: &mut lexopt::Parser) -> Result<()> {
    let (mut path, mut level) = (None::<PathBuf>, None);
    while let Some(arg) = parser.next()? {
        match arg {
            Long("level") | Short('k') => level = Some(parse_level(parser, "--level")?),
            Value(v) if path.is_none() => path = Some(v.into()),
            other => return Err(other.unexpected().into()),
        }
    }
    let path = path.ok_or("query: missing FILE.qtx")?;
    let tree = quadtex_io::read_qtx(&path)?;
    let k = level.unwrap_or(tree.depth());
    let stdin = std::io::stdin().lock();
    let mut out = BufWriter::new(std::io::stdout().lock());
    for (i, line) in stdin.lines().enumerate() {
        let line = line.map_err(|e| format!("stdin line {}: {e}", i + 1))?;
        let Some(fragment) = quadtex_io::parse_query_line(&line)
            .map_err(|e| format!("stdin line {}: {e}", i + 1))?
        else {
            continue;
        };
        let w = tree.weighted_colour(&fragment, k);
        writeln!(out, "{} {} {} {}", w.0[0], w.0[1], w.0[2], w.0[3])?;
    }
    out.flush()?;
    Ok(())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raster_and_mip_bytes() {
        assert_eq!(raster_bytes(4, 4), (64, 4 * (16 + 4 + 1)));
        assert_eq!(raster_bytes(4, 1), (16, 4 * (4 + 2 + 1)));
    }
}

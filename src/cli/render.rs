//! `quadtex render` and `quadtex demo`: the same render options
//! ([`RenderArgs`]); `demo` builds its scene in code and can run the
//! comparison on it instead (`demo --compare`).

use std::io::{IsTerminal, Write};
use std::path::PathBuf;

use quadtex_core::FilterOptions;
use quadtex_core::baseline::StripOptions;
use quadtex_render::{PixelFilter, RenderOptions, Scene, TextureFilter};

use super::Result;
use super::common::{MemoryArgs, ResourcesArgs, budget_scene, level};
use super::comparison::{CompareArgs, Settings, compare_scene};
use super::output::{FormatFlag, Output, Text};

/// Render a scene file to PNG or EXR.
///
/// The scene format is described in docs/scenes.md. Prints the file written
/// and a summary: time, regions and tree queries per textured pixel, nodes
/// per query and the error bounds reached (on standard error with `-o -`).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene to render.
    #[arg(value_name = "SCENE.toml")]
    scene: PathBuf,
    /// The image to write: .png (sRGB, 8-bit) or .exr (linear, float); `-`
    /// writes it to standard output (PNG unless `--format exr`). With
    /// `--path`, the directory the frames go to.
    #[arg(short, long, value_name = "OUT.png|OUT.exr|-|DIR")]
    output: Output,
    /// Render a sequence along a camera path (TOML keyframes, format in
    /// docs/scenes.md) instead of the scene's camera: `-o` is then a
    /// directory, written as frame_0000.png, frame_0001.png, … (.exr with
    /// `--format exr`); every frame shares the scene's packed textures. The
    /// whole path is checked before the first frame is written.
    #[arg(long, value_name = "PATH.toml", requires = "frames")]
    path: Option<PathBuf>,
    /// Frames along `--path`, spread evenly in time from its first key to
    /// its last (1..=100000).
    #[arg(long, value_name = "N", requires = "path",
          value_parser = clap::value_parser!(u32).range(1..=i64::from(quadtex_render::MAX_PATH_FRAMES)))]
    frames: Option<u32>,
    /// With `--path` and `--frames N`: render only frames A to B, both
    /// included, numbered from 0 (so B ≤ N−1; `--range 7` is frame 7 alone),
    /// under the names the whole run gives them and with the same bytes,
    /// however the frames are split among runs (a render farm's jobs). A
    /// frame whose file already exists is skipped as complete: frames are
    /// written to a temporary file and renamed, so a crash never leaves a
    /// partial one, and running a range again resumes it. To render a frame
    /// again, delete its file (without `--range`, every frame is rendered
    /// and replaced).
    #[arg(long, value_name = "A-B", value_parser = frame_range)]
    range: Option<FrameRange>,
    #[command(flatten)]
    render: RenderArgs,
    #[command(flatten)]
    memory: MemoryArgs,
    #[command(flatten)]
    resources: ResourcesArgs,
    #[command(flatten)]
    format: FormatFlag,
}

/// Render the built-in airfield scene, or compare every filter on it.
///
/// Without `--compare`: renders the scene to `-o` (default demo.png) with the
/// render options. With `--compare`: as `quadtex compare`, on this scene,
/// writing the report into the directory `-o`; `--width` is the comparison's
/// frame width (16..=3840, default 480) and the other render options are not
/// used.
#[derive(Debug, clap::Args)]
#[command(group(
    clap::ArgGroup::new("compare_only")
        .args(["reference_spp", "frames", "no_flip", "path"])
        .multiple(true)
        .requires("compare")
))]
pub struct DemoArgs {
    /// The image to write (.png or .exr; `-` for standard output) [default:
    /// demo.png, or demo.exr with `--format exr`]; with `--compare`, the
    /// report's directory (required).
    #[arg(short, long, value_name = "OUT")]
    output: Option<Output>,
    #[command(flatten)]
    render: RenderArgs,
    #[command(flatten)]
    format: FormatFlag,
    /// Run the comparison (every filter against a converged reference) instead.
    #[arg(long)]
    compare: bool,
    #[command(flatten)]
    compare_options: CompareArgs,
    #[command(flatten)]
    memory: MemoryArgs,
}

/// The render options shared by `render` and `demo`.
#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    /// Image width in pixels (default: the camera's; the height follows the
    /// camera's aspect unless also given).
    #[arg(long, value_name = "W")]
    width: Option<u32>,
    /// Image height in pixels (default: the camera's).
    #[arg(long, value_name = "H")]
    height: Option<u32>,
    /// Texture filter: quadtree (the method: the exact integral over each
    /// pixel's footprint), nearest, bilinear, supersample:N (N×N nearest
    /// rays per pixel), trilinear, ewa (anisotropy 8) or sat (summed-area
    /// table).
    #[arg(long, value_name = "FILTER", default_value = "quadtree", value_parser = filter_name)]
    filter: FilterName,
    /// Strip quality of sat (the summed-area table integrates axis-aligned
    /// strips covering the footprint), in 1..=64 (the area-mismatch target
    /// is 1/(4·Q)). The quadtree filter integrates the footprint exactly
    /// and ignores it.
    #[arg(long, value_name = "Q", default_value_t = 1.0, value_parser = quality)]
    quality: f64,
    /// Quadtree only: the error bound each pixel aims at, relative to full
    /// contrast (default 1/512): squares are refined, largest error first,
    /// until the pixel's bound is below it or the budget is spent. The
    /// render summary reports the bounds reached.
    #[arg(long, value_name = "E", value_parser = positive("--error-bound"))]
    error_bound: Option<f64>,
    /// Quadtree only: most squares evaluated per pixel region under the
    /// error bound (default 64); pixels at the horizon are the ones that
    /// reach it. Shallow repeated textures (at most 16×16 texels a tile)
    /// are scanned cell by cell instead, exactly, up to 512 cells a pixel.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    budget: Option<u64>,
    /// Quadtree only: refine every square to this fixed level (or a
    /// terminal square), whatever the bound (the tree's depth: exact, slow).
    #[arg(long, value_name = "K", value_parser = level("--level"))]
    level: Option<u8>,
    /// Pixel filter, for quadtree and supersample: box (the pixel square),
    /// tent (over 2×2 pixels) or mitchell (Mitchell–Netravali B = C = 1/3,
    /// over 4×4 pixels) [default: box].
    #[arg(long, value_name = "box|tent|mitchell", value_parser = pixel_filter)]
    pixel_filter: Option<PixelFilter>,
}

/// A `--filter` name, before `--quality` and `--level` complete it.
#[derive(Debug, Clone, Copy, PartialEq)]
enum FilterName {
    Quadtree,
    Nearest,
    Bilinear,
    Supersample(u32),
    Trilinear,
    Ewa,
    Sat,
}

/// A value parser: `--filter`'s grammar.
fn filter_name(text: &str) -> std::result::Result<FilterName, String> {
    Ok(match text {
        "quadtree" => FilterName::Quadtree,
        "nearest" => FilterName::Nearest,
        "trilinear" => FilterName::Trilinear,
        "ewa" => FilterName::Ewa,
        "sat" => FilterName::Sat,
        "bilinear" => FilterName::Bilinear,
        other => match other.strip_prefix("supersample:").map(str::parse::<u32>) {
            Some(Ok(n)) => FilterName::Supersample(n),
            _ => {
                return Err(format!(
                    "--filter {other}: expected quadtree, nearest, bilinear, supersample:N, trilinear, ewa or sat"
                ));
            }
        },
    })
}

/// `--range A-B`: frames `first..=last` of a camera path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct FrameRange {
    first: u32,
    last: u32,
}

impl std::fmt::Display for FrameRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.first == self.last {
            write!(f, "{}", self.first)
        } else {
            write!(f, "{}-{}", self.first, self.last)
        }
    }
}

impl FrameRange {
    /// The range, checked against `--frames frames`.
    fn within(self, frames: u32) -> Result<FrameRange> {
        if self.last >= frames {
            return Err(format!(
                "--range {self}: frame {} is past the last of --frames {frames} (frames are numbered 0 to {})",
                self.last,
                frames - 1
            )
            .into());
        }
        Ok(self)
    }
}

/// A value parser: `--range A-B` (decimal frame numbers, `A ≤ B`) or `--range
/// A` (the one frame `A-A`).
fn frame_range(text: &str) -> std::result::Result<FrameRange, String> {
    let number = |part: &str| {
        if part.is_empty() || !part.bytes().all(|b| b.is_ascii_digit()) {
            return Err(format!(
                "--range {text}: expected A-B, two frame numbers (from 0) such as 0-9, or one frame such as 7"
            ));
        }
        part.parse::<u32>()
            .map_err(|e| format!("--range {text}: {part}: {e}"))
    };
    let (first, last) = match text.split_once('-') {
        Some((a, b)) => (number(a)?, number(b)?),
        None => {
            let a = number(text)?;
            (a, a)
        }
    };
    if last < first {
        return Err(format!(
            "--range {text}: the last frame {last} comes before the first {first}"
        ));
    }
    Ok(FrameRange { first, last })
}

/// A value parser: `--quality` in 1..=64.
fn quality(text: &str) -> std::result::Result<f64, String> {
    let quality = text.parse::<f64>().map_err(|e| e.to_string())?;
    if !(1.0..=64.0).contains(&quality) {
        return Err(format!("--quality must be in 1..=64, got {quality}"));
    }
    Ok(quality)
}

/// A value parser: `--pixel-filter box|tent|mitchell`.
fn pixel_filter(text: &str) -> std::result::Result<PixelFilter, String> {
    match text {
        "box" => Ok(PixelFilter::Box),
        "tent" => Ok(PixelFilter::Tent),
        "mitchell" => Ok(PixelFilter::Mitchell),
        other => Err(format!(
            "--pixel-filter {other}: expected box, tent or mitchell"
        )),
    }
}

/// A value parser: a finite number `> 0` for `flag`.
fn positive(flag: &'static str) -> impl Fn(&str) -> std::result::Result<f64, String> + Clone {
    move |text| {
        let v = text
            .parse::<f64>()
            .map_err(|e| format!("{flag} {text}: {e}"))?;
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(format!("{flag} must be a finite number > 0, got {text}"))
        }
    }
}

impl RenderArgs {
    /// The render options these arguments ask for.
    fn options(&self) -> Result<RenderOptions> {
        let quality = StripOptions::default().with_quality(self.quality)?;
        let mut quadtree = FilterOptions::RENDER;
        if let Some(e) = self.error_bound {
            quadtree = quadtree.with_error_bound(e)?;
        }
        if let Some(n) = self.budget {
            quadtree = quadtree.with_budget(n)?;
        }
        if let Some(k) = self.level {
            quadtree = quadtree.with_level(k);
        }
        Ok(RenderOptions {
            width: self.width,
            height: self.height,
            filter: match self.filter {
                FilterName::Quadtree => TextureFilter::Quadtree(quadtree),
                FilterName::Nearest => TextureFilter::Nearest,
                FilterName::Trilinear => TextureFilter::Trilinear,
                FilterName::Ewa => TextureFilter::Ewa {
                    max_anisotropy: 8.0,
                },
                FilterName::Sat => TextureFilter::Sat(quality),
                FilterName::Bilinear => TextureFilter::Bilinear,
                FilterName::Supersample(n) => TextureFilter::Supersample(n),
            },
            pixel_filter: self.pixel_filter.unwrap_or_default(),
            seed: 0,
        })
    }
}

/// Runs `quadtex render`.
pub fn run(args: Args) -> Result<()> {
    let options = args.render.options()?;
    if let (Some(range), None) = (args.range, &args.path) {
        return Err(format!(
            "--range {range} picks frames of a camera path: it needs --path PATH.toml and --frames N"
        )
        .into());
    }
    if let (Some(path), Some(frames)) = (&args.path, args.frames) {
        let Output::File(dir) = &args.output else {
            return Err("render --path writes a directory of frames: -o - is not possible".into());
        };
        let range = args.range.map(|r| r.within(frames)).transpose()?;
        let format = args
            .format
            .format
            .map_or(quadtex_io::ImageFormat::Png, quadtex_io::ImageFormat::from);
        let limits = args.resources.apply(args.memory.limits());
        let camera_path = quadtex_render::load_camera_path(path, &limits)?;
        let scene = quadtex_render::load_scene(&args.scene, &limits)?;
        return render_path(&scene, &camera_path, frames, range, &options, dir, format);
    }
    let format = args.output.image_format(args.format.format)?;
    let scene =
        quadtex_render::load_scene(&args.scene, &args.resources.apply(args.memory.limits()))?;
    render(&scene, &options, &args.output, format)
}

/// Renders `frames` frames of `scene` along `path` into `dir` as `format`
/// (or, with `range`, those frames of the `frames`, skipping any whose file
/// exists), with a progress bar over frames on a terminal, then prints where
/// they went, how many were skipped and the frame times. Every frame's
/// camera is checked first, so a bad path writes nothing.
fn render_path(
    scene: &Scene,
    path: &quadtex_render::CameraPath,
    frames: u32,
    range: Option<FrameRange>,
    options: &RenderOptions,
    dir: &std::path::Path,
    format: quadtex_io::ImageFormat,
) -> Result<()> {
    let (w, h) = (scene.camera.width(), scene.camera.height());
    let cameras = (0..frames)
        .map(|i| path.camera(i, frames, w, h))
        .collect::<std::result::Result<Vec<_>, _>>()
        .map_err(|e| format!("camera path: {e}"))?;
    if dir.exists() && !dir.is_dir() {
        return Err(format!("{}: exists and is not a directory", dir.display()).into());
    }
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let digits = (frames - 1).max(1).ilog10() as usize + 1;
    let digits = digits.max(4);
    let todo = range.map_or(0..=frames - 1, |r| r.first..=r.last);
    let bar = std::io::stderr().is_terminal().then(|| {
        let bar = indicatif::ProgressBar::new(u64::from(todo.end() - todo.start() + 1));
        bar.set_style(
            indicatif::ProgressStyle::with_template("{bar:40} frame {pos}/{len} {elapsed}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    });
    let mut seconds = Vec::new();
    let mut names = Vec::new();
    let mut skipped = 0u32;
    let mut image = quadtex_io::LinearImage::default();
    for i in todo {
        let file = dir.join(format!("frame_{i:0digits$}.{}", format.extension()));
        // Complete when its file exists: frames are renamed into place
        // whole, so a crash leaves no partial one under this name.
        if range.is_some() && std::fs::metadata(&file).is_ok_and(|m| m.is_file()) {
            skipped += 1;
        } else {
            let framed = Scene {
                camera: cameras[i as usize].clone(),
                ..scene.clone()
            };
            let summary = quadtex_render::render_into(&framed, options, &mut image, &|_, _| {})?;
            quadtex_io::save_image_as(&file, &image, format)?;
            seconds.push(summary.seconds);
            names.push(file);
        }
        if let Some(bar) = &bar {
            bar.inc(1);
        }
    }
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let mut text = Text::stdout();
    let file_name = |n: Option<&PathBuf>| {
        n.and_then(|n| n.file_name())
            .map_or(String::new(), |n| n.to_string_lossy().into_owned())
    };
    write!(text, "wrote {} frames to {}", names.len(), dir.display())?;
    if !names.is_empty() {
        write!(
            text,
            " ({} … {})",
            file_name(names.first()),
            file_name(names.last())
        )?;
    }
    if let Some(range) = range {
        write!(
            text,
            "; --range {range} of {frames}: {} rendered, {skipped} skipped as already complete",
            names.len()
        )?;
    }
    writeln!(text)?;
    let mut sorted = seconds;
    sorted.sort_by(f64::total_cmp);
    if let (Some(fastest), Some(slowest)) = (sorted.first(), sorted.last()) {
        writeln!(
            text,
            "frame time: median {:.3} s, fastest {fastest:.3} s, slowest {slowest:.3} s",
            sorted[sorted.len() / 2],
        )?;
    }
    text.flush()?;
    Ok(())
}

/// Runs `quadtex demo`.
pub fn run_demo(args: DemoArgs) -> Result<()> {
    let mut scene = quadtex_render::demo_scene()?;
    budget_scene(&mut scene, args.memory.bytes());
    if args.compare {
        let width = args.render.width.unwrap_or(Settings::default().width);
        if !(16..=3840).contains(&width) {
            return Err(format!("--width must be in 16..=3840, got {width}").into());
        }
        let settings = args
            .compare_options
            .settings(width, &args.memory.limits())?;
        let dir = match args.output {
            Some(Output::File(dir)) => dir,
            Some(Output::Stdout) => {
                return Err("demo --compare writes a directory: -o - is not possible".into());
            }
            None => return Err("demo --compare: missing -o DIR".into()),
        };
        if args.format.format.is_some() {
            return Err("demo --compare: --format applies to the rendered image only".into());
        }
        return compare_scene(&scene, "demo", &dir, &settings);
    }
    let options = args.render.options()?;
    let output = args.output.unwrap_or_else(|| {
        let ext = args
            .format
            .format
            .map_or("png", |f| quadtex_io::ImageFormat::from(f).extension());
        Output::File(PathBuf::from(format!("demo.{ext}")))
    });
    let format = output.image_format(args.format.format)?;
    render(&scene, &options, &output, format)
}

/// Renders `scene` into `output` as `format` with a progress bar on a
/// terminal, then prints the summary (to standard error when the image went
/// to standard output).
fn render(
    scene: &Scene,
    options: &RenderOptions,
    output: &Output,
    format: quadtex_io::ImageFormat,
) -> Result<()> {
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
    let (image, summary) = quadtex_render::render(scene, options, &progress)?;
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    output.save_image(&image, format)?;
    let mut text = output.text();
    writeln!(text, "wrote {output}")?;
    writeln!(text, "{summary}")?;
    text.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filter_grammar() {
        assert_eq!(filter_name("ewa"), Ok(FilterName::Ewa));
        assert_eq!(filter_name("supersample:4"), Ok(FilterName::Supersample(4)));
        for bad in ["supersample:", "supersample:x", "box", ""] {
            assert!(
                filter_name(bad)
                    .is_err_and(|e| e.starts_with(&format!("--filter {bad}: expected"))),
                "{bad}"
            );
        }
    }

    #[test]
    fn range_grammar() {
        assert_eq!(frame_range("0-47"), Ok(FrameRange { first: 0, last: 47 }));
        assert_eq!(frame_range("7"), Ok(FrameRange { first: 7, last: 7 }));
        assert_eq!(frame_range("7-7"), Ok(FrameRange { first: 7, last: 7 }));
        for bad in [
            "",
            "-",
            "3-",
            "-3",
            "a-b",
            "1-2-3",
            "+1-2",
            " 1-2",
            "1..2",
            "99999999999",
        ] {
            assert!(
                frame_range(bad).is_err_and(|e| e.starts_with(&format!("--range {bad}: "))),
                "{bad}"
            );
        }
        assert_eq!(
            frame_range("9-3"),
            Err("--range 9-3: the last frame 3 comes before the first 9".to_string())
        );
        let r = FrameRange { first: 2, last: 4 };
        assert_eq!(r.within(5).unwrap(), r);
        assert_eq!(
            r.within(4).unwrap_err().to_string(),
            "--range 2-4: frame 4 is past the last of --frames 4 (frames are numbered 0 to 3)"
        );
    }

    #[test]
    fn quality_and_pixel_filter() {
        assert_eq!(quality("64"), Ok(64.0));
        assert_eq!(
            quality("0.5"),
            Err("--quality must be in 1..=64, got 0.5".to_string())
        );
        assert!(quality("NaN").is_err());
        assert_eq!(pixel_filter("tent"), Ok(PixelFilter::Tent));
        assert_eq!(pixel_filter("mitchell"), Ok(PixelFilter::Mitchell));
        assert_eq!(
            pixel_filter("gauss"),
            Err("--pixel-filter gauss: expected box, tent or mitchell".to_string())
        );
        assert!(positive("--error-bound")("0").is_err());
        assert!(positive("--error-bound")("inf").is_err());
        assert_eq!(positive("--error-bound")("0.001"), Ok(0.001));
    }
}

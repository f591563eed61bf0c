//! The comparison `quadtex compare` and `quadtex demo --compare` run:
//! every contender filter against a converged reference on the same scene,
//! with error, perceptual error, shimmer, time and memory, written as a
//! static report (see `docs/compare.md`). Also the measures other commands
//! reuse: [`flip`] (`diff`) and [`texture_bytes`] (`footprints`).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use quadtex_eval::contenders::{Contender, default_contenders};
use quadtex_eval::metrics::{error_map, psnr, rmse, rmse_where_defined, shimmer};
use quadtex_eval::montage::{self, busiest_window, crop, grid, magnify, shrink};
use quadtex_eval::reference::closed_form_plane;
use quadtex_eval::report::{
    Figures, Provenance, ReportInfo, csv, file_stem, html_report, markdown_table, plot_svg,
};
use quadtex_io::LinearImage;
use quadtex_render::{
    PixelFilter, RenderOptions, Scene, TextureFilter, baseline_level, mipmapped_raster_bytes,
    same_memory_level,
};

use super::Result;
use super::common::in_range;
use super::output::Text;

/// Settings of one comparison.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Frame width (height keeps the camera's aspect).
    pub width: u32,
    /// Reference samples per pixel side (`n × n` stratified).
    pub reference_grid: u32,
    /// Frames of the camera move for shimmer (0 or 1: no shimmer).
    pub frames: u32,
    /// Reference samples per pixel side for the shimmer frames.
    pub shimmer_reference_grid: u32,
    /// Compute FLIP.
    pub flip: bool,
    /// The shimmer frames' camera path, instead of the move along the view.
    pub path: Option<quadtex_render::CameraPath>,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            width: 480,
            reference_grid: 32,
            frames: 16,
            shimmer_reference_grid: 16,
            flip: true,
            path: None,
        }
    }
}

/// The options `compare` shares with `demo --compare` (whose `--width` is
/// the render option's).
#[derive(Debug, clap::Args)]
pub struct CompareArgs {
    /// Reference samples per pixel, in 1..=4096 (rounded to a square grid).
    #[arg(
        long,
        value_name = "N",
        default_value_t = Settings::default().reference_grid.pow(2),
        value_parser = in_range("--reference-spp", 1, 4096)
    )]
    reference_spp: u32,
    /// Frames of the camera move that measures shimmer, in 0..=240 (0 or 1: none).
    #[arg(
        long,
        value_name = "F",
        default_value_t = Settings::default().frames,
        value_parser = in_range("--frames", 0, 240)
    )]
    frames: u32,
    /// Skip FLIP (the perceptual error).
    #[arg(long)]
    no_flip: bool,
    /// Move the shimmer frames' camera along this camera path (format in
    /// docs/scenes.md) instead of straight ahead along the view.
    #[arg(long, value_name = "PATH.toml")]
    path: Option<PathBuf>,
}

impl CompareArgs {
    /// The settings for frames `width` pixels wide (reads `--path` under `limits`).
    pub fn settings(&self, width: u32, limits: &quadtex_io::Limits) -> Result<Settings> {
        let path = match &self.path {
            Some(p) => Some(quadtex_render::load_camera_path(p, limits)?),
            None => None,
        };
        Ok(Settings {
            width,
            reference_grid: (f64::from(self.reference_spp).sqrt().round() as u32).max(1),
            frames: self.frames,
            flip: !self.no_flip,
            path,
            ..Settings::default()
        })
    }
}

/// Renders a contender (jitter stream 0).
fn render_one(
    scene: &Scene,
    w: u32,
    h: u32,
    filter: TextureFilter,
    pixel_filter: PixelFilter,
) -> Result<(LinearImage, quadtex_render::RenderSummary)> {
    render_seeded(scene, w, h, filter, pixel_filter, 0)
}

/// Renders a reference: supersampled from its own jitter stream, so no
/// contender shares its samples.
fn render_reference(
    scene: &Scene,
    w: u32,
    h: u32,
    grid: u32,
    pixel_filter: PixelFilter,
) -> Result<LinearImage> {
    let filter = TextureFilter::Supersample(grid);
    Ok(render_seeded(
        scene,
        w,
        h,
        filter,
        pixel_filter,
        quadtex_render::REFERENCE_SEED,
    )?
    .0)
}

fn render_seeded(
    scene: &Scene,
    w: u32,
    h: u32,
    filter: TextureFilter,
    pixel_filter: PixelFilter,
    seed: u64,
) -> Result<(LinearImage, quadtex_render::RenderSummary)> {
    let options = RenderOptions {
        width: Some(w),
        height: Some(h),
        filter,
        pixel_filter,
        seed,
    };
    Ok(quadtex_render::render(scene, &options, &|_, _| {})?)
}

/// Bytes of texture data a filter needs, in the form its users store it:
/// the tree; an RGBA8 raster at the tree's full resolution (nearest,
/// bilinear, supersampling); RGBA8 raster + mips at the baselines'
/// resolution (trilinear, EWA); a summed-area table of 4 × u32 per texel.
pub fn texture_bytes(scene: &Scene, filter: TextureFilter) -> u64 {
    scene
        .distinct_textures()
        .iter()
        .map(|(_, texture)| {
            let t = &texture.tree;
            let full = 4u64.saturating_mul(1u64 << (2 * u32::from(t.depth()).min(31)));
            let b = baseline_level(t.depth());
            let base = 1u64 << (2 * u32::from(b));
            match filter {
                TextureFilter::Quadtree { .. } => t.memory_bytes(),
                TextureFilter::Nearest
                | TextureFilter::Bilinear
                | TextureFilter::Supersample(_) => full,
                TextureFilter::Trilinear | TextureFilter::Ewa { .. } => mipmapped_raster_bytes(b),
                TextureFilter::EwaSameMemory { .. } => {
                    mipmapped_raster_bytes(same_memory_level(t.memory_bytes(), t.depth()))
                }
                TextureFilter::Sat { .. } => 16 * base,
            }
        })
        .sum()
}

fn lookups_per_pixel(
    filter: TextureFilter,
    summary: &quadtex_render::RenderSummary,
) -> Option<f64> {
    let textured = summary.textured_pixels.max(1) as f64;
    match filter {
        TextureFilter::Quadtree { .. } | TextureFilter::Sat { .. } => {
            Some(summary.filter.traversal.queries as f64 / textured)
        }
        TextureFilter::Nearest => Some(1.0),
        TextureFilter::Bilinear => Some(4.0),
        TextureFilter::Trilinear => Some(8.0),
        TextureFilter::Supersample(n) => Some(f64::from(n * n)),
        TextureFilter::Ewa { .. } | TextureFilter::EwaSameMemory { .. } => None,
    }
}

fn srgb8(img: &LinearImage) -> Vec<u8> {
    let mut out = Vec::with_capacity(img.pixels.len() * 3);
    for p in &img.pixels {
        for v in [p.r, p.g, p.b] {
            out.push((quadtex_core::srgb_encode_f32(v.clamp(0.0, 1.0)) * 255.0 + 0.5) as u8);
        }
    }
    out
}

/// Mean FLIP (LDR, sRGB 8-bit, 67 pixels per degree) of `test` against `reference`.
pub fn flip(reference: &LinearImage, test: &LinearImage) -> f64 {
    let r = nv_flip::FlipImageRgb8::with_data(reference.width, reference.height, &srgb8(reference));
    let t = nv_flip::FlipImageRgb8::with_data(test.width, test.height, &srgb8(test));
    let map = nv_flip::flip(r, t, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    f64::from(nv_flip::FlipPool::from_image(&map).mean())
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    quadtex_io::write_atomically(path, |w| {
        std::io::Write::write_all(w, text.as_bytes()).map_err(|source| quadtex_io::Error::Io {
            path: path.to_path_buf(),
            source,
        })
    })?;
    Ok(())
}

/// Runs the comparison on `scene` and writes the report into `dir`.
pub fn compare_scene(scene: &Scene, name: &str, dir: &Path, s: &Settings) -> Result<()> {
    let start = Instant::now();
    std::fs::create_dir_all(dir.join("frames"))
        .map_err(|e| format!("{}: {e}", dir.join("frames").display()))?;
    let (w, h) = (s.width, scene.camera.height_for_width(s.width));
    let contenders = default_contenders();
    let needs_tent = contenders
        .iter()
        .any(|c| c.pixel_filter == PixelFilter::Tent);
    let stills = StillReferences::render(scene, name, (w, h), s.reference_grid, needs_tent)?;
    let motion = CameraMove::new(scene, s, w, h)?;
    let shimmer_refs = ShimmerReferences::render(&motion, s, name, needs_tent)?;
    let mut rows = Vec::new();
    let mut frames = Vec::new();
    for c in &contenders {
        let (figures, img) = measure(scene, c, s, &stills, &motion, &shimmer_refs, (w, h))?;
        rows.push(figures);
        frames.push(img);
    }
    let labels = write_images(dir, &contenders, &frames, &stills, (w, h), s.reference_grid)?;
    let info = ReportInfo {
        scene: name.to_string(),
        width: w,
        height: h,
        reference: format!(
            "{} stratified samples per pixel, nearest lookups of the full-depth tree, same pixel filter as the method (box; tent for the tent row){}",
            s.reference_grid * s.reference_grid,
            stills.exact_note.clone().unwrap_or_default()
        ),
        motion: motion.describe(s),
        provenance: provenance(available_threads()),
    };
    let table = markdown_table(&rows);
    write_text(&dir.join("results.md"), &table)?;
    write_text(&dir.join("results.csv"), &csv(&rows, &info.provenance))?;
    write_text(
        &dir.join("plot.svg"),
        &plot_svg(&rows, &format!("{name}: error against time per frame")),
    )?;
    write_text(
        &dir.join("report.html"),
        &html_report(&info, &rows, &labels),
    )?;
    let mut out = Text::stdout();
    writeln!(out, "{table}")?;
    writeln!(
        out,
        "wrote {} (report.html, grid.png, plot.svg, results.csv, results.md, frames/) in {:.1} s",
        dir.display(),
        start.elapsed().as_secs_f64()
    )?;
    Ok(())
}

/// The full-size references: box-filtered, tent-filtered when a contender
/// uses the tent, and the closed form where the scene has one.
struct StillReferences {
    /// Box pixel filter.
    box_filtered: LinearImage,
    /// Tent pixel filter, rendered only when a contender uses it.
    tent_filtered: Option<LinearImage>,
    /// The closed-form integral, where the scene is a single unlit textured
    /// plane (per pixel; `None` where it is not defined).
    exact: Option<Vec<Option<quadtex_core::Rgba>>>,
    /// What the closed form covers and how close the reference is to it,
    /// for the report.
    exact_note: Option<String>,
}

impl StillReferences {
    /// Renders them at `w`×`h` with `grid`² samples per pixel, saying so
    /// on standard error.
    fn render(
        scene: &Scene,
        name: &str,
        (w, h): (u32, u32),
        grid: u32,
        needs_tent: bool,
    ) -> Result<StillReferences> {
        let n = grid;
        let _ = writeln!(
            std::io::stderr(),
            "{name}: {w}x{h}; reference {} samples per pixel (box{})",
            n * n,
            if needs_tent { " and tent" } else { "" }
        );
        let box_filtered = render_reference(scene, w, h, n, PixelFilter::Box)?;
        let tent_filtered = if needs_tent {
            Some(render_reference(scene, w, h, n, PixelFilter::Tent)?)
        } else {
            None
        };
        let exact = closed_form_plane(scene, w, h);
        let exact_note = exact.as_ref().and_then(|e| {
            let (r, defined) = rmse_where_defined(&box_filtered, e)?;
            Some(format!(
                "; the closed-form integral (texture and sky integrated exactly over each pixel square, error ≤ 1e-6 per pixel) covers {:.1}% of the pixels, where the reference is within RMSE {r:.5} of it",
                100.0 * defined
            ))
        });
        if let Some(note) = &exact_note {
            let _ = writeln!(std::io::stderr(), "{name}: closed form{note}");
        }
        Ok(StillReferences {
            box_filtered,
            tent_filtered,
            exact,
            exact_note,
        })
    }

    /// The reference with contender `c`'s pixel filter.
    fn for_contender(&self, c: &Contender) -> &LinearImage {
        match (c.pixel_filter, &self.tent_filtered) {
            (PixelFilter::Tent, Some(t)) => t,
            _ => &self.box_filtered,
        }
    }
}

/// The camera move that measures shimmer: the scene once per frame, at a
/// quarter of the frame's size.
struct CameraMove {
    /// The scene with each frame's camera.
    scenes: Vec<Scene>,
    /// Width and height of the shimmer frames.
    size: (u32, u32),
    /// Scene units per frame along the view (when there is no camera path).
    step: f64,
}

impl CameraMove {
    /// `s.frames` frames along `s.path`, or else steps along the view
    /// direction, each 0.4% of the distance to what the centre of the view
    /// sees.
    fn new(scene: &Scene, s: &Settings, w: u32, h: u32) -> Result<CameraMove> {
        let size = ((w / 2).max(16), (h / 2).max(9));
        let step = quadtex_render::centre_distance(scene).unwrap_or(1.0) * 0.004;
        let scenes: Vec<Scene> = match &s.path {
            Some(path) => (0..s.frames)
                .map(|t| {
                    let camera = path
                        .camera(t, s.frames, scene.camera.width(), scene.camera.height())
                        .map_err(|e| format!("camera path: {e}"))?;
                    Ok(Scene {
                        camera,
                        ..scene.clone()
                    })
                })
                .collect::<Result<_>>()?,
            None => (0..s.frames)
                .map(|t| Scene {
                    camera: scene
                        .camera
                        .translated(scene.camera.forward() * (step * f64::from(t))),
                    ..scene.clone()
                })
                .collect(),
        };
        Ok(CameraMove { scenes, size, step })
    }

    /// The report's line on how shimmer was measured.
    fn describe(&self, s: &Settings) -> String {
        if s.frames >= 2 && s.path.is_some() {
            format!(
                "{} frames at {}x{} along the camera path, against {}-sample references",
                s.frames,
                self.size.0,
                self.size.1,
                s.shimmer_reference_grid * s.shimmer_reference_grid
            )
        } else if s.frames >= 2 {
            format!(
                "{} frames at {}x{} moving {:.3} scene units per frame along the view, against {}-sample references",
                s.frames,
                self.size.0,
                self.size.1,
                self.step,
                s.shimmer_reference_grid * s.shimmer_reference_grid
            )
        } else {
            "not measured".into()
        }
    }
}

/// The references of the camera move's frames, per pixel filter (empty
/// when shimmer is not measured).
struct ShimmerReferences {
    box_filtered: Vec<LinearImage>,
    /// Rendered only when a contender uses the tent.
    tent_filtered: Vec<LinearImage>,
}

impl ShimmerReferences {
    /// Renders them when `s.frames` is at least 2, saying so on standard
    /// error.
    fn render(
        motion: &CameraMove,
        s: &Settings,
        name: &str,
        needs_tent: bool,
    ) -> Result<ShimmerReferences> {
        let shimmer_size = motion.size;
        let shimmer_refs = |pf: PixelFilter| -> Result<Vec<LinearImage>> {
            motion
                .scenes
                .iter()
                .map(|sc| {
                    render_reference(
                        sc,
                        shimmer_size.0,
                        shimmer_size.1,
                        s.shimmer_reference_grid,
                        pf,
                    )
                })
                .collect()
        };
        if s.frames < 2 {
            return Ok(ShimmerReferences {
                box_filtered: Vec::new(),
                tent_filtered: Vec::new(),
            });
        }
        let _ = writeln!(
            std::io::stderr(),
            "{name}: {} shimmer frames at {}x{}, references {} samples per pixel",
            s.frames,
            shimmer_size.0,
            shimmer_size.1,
            s.shimmer_reference_grid * s.shimmer_reference_grid
        );
        Ok(ShimmerReferences {
            box_filtered: shimmer_refs(PixelFilter::Box)?,
            tent_filtered: if needs_tent {
                shimmer_refs(PixelFilter::Tent)?
            } else {
                Vec::new()
            },
        })
    }
}

/// Renders contender `c` and measures it: error against its reference and
/// the closed form, FLIP, shimmer along the camera move, time (median of
/// three for fast frames), lookups and texture memory. Returns the figures
/// and the full-size frame.
fn measure(
    scene: &Scene,
    c: &Contender,
    s: &Settings,
    stills: &StillReferences,
    motion: &CameraMove,
    shimmer_refs: &ShimmerReferences,
    (w, h): (u32, u32),
) -> Result<(Figures, LinearImage)> {
    let needs_tent = stills.tent_filtered.is_some();
    let (img, summary) = render_one(scene, w, h, c.filter, c.pixel_filter)?;
    // Median of three timings for frames under half a second.
    let mut times = vec![summary.seconds];
    if summary.seconds < 0.5 {
        for _ in 0..2 {
            times.push(render_one(scene, w, h, c.filter, c.pixel_filter)?.1.seconds);
        }
    }
    times.sort_by(f64::total_cmp);
    let seconds = times[times.len() / 2];
    let reference = stills.for_contender(c);
    let rmse = rmse(&img, reference).ok_or("frame size mismatch")?;
    let shimmer = if s.frames >= 2 {
        let refs = match c.pixel_filter {
            PixelFilter::Tent if needs_tent => &shimmer_refs.tent_filtered,
            _ => &shimmer_refs.box_filtered,
        };
        let (sw, sh) = motion.size;
        let seq: Vec<LinearImage> = motion
            .scenes
            .iter()
            .map(|sc| Ok(render_one(sc, sw, sh, c.filter, c.pixel_filter)?.0))
            .collect::<Result<_>>()?;
        shimmer(&seq, refs)
    } else {
        None
    };
    let figures = Figures {
        label: c.label.clone(),
        rmse,
        psnr: psnr(rmse),
        rmse_exact: match (&stills.exact, c.pixel_filter) {
            (Some(e), PixelFilter::Box) => rmse_where_defined(&img, e).map(|r| r.0),
            _ => None,
        },
        flip: s.flip.then(|| flip(reference, &img)),
        shimmer,
        seconds,
        lookups_per_pixel: lookups_per_pixel(c.filter, &summary),
        texture_bytes: texture_bytes(scene, c.filter),
    };
    let _ = writeln!(
        std::io::stderr(),
        "  {:<16} RMSE {:.4}  {:>7.0} ms/frame",
        c.label,
        rmse,
        1000.0 * seconds
    );
    Ok((figures, img))
}

/// Writes grid.png (reference first, then one row per contender: the
/// frame, two magnified windows where aliasing and contrast are largest,
/// and the error map) and every frame into `dir/frames`. Returns the
/// grid's row labels.
fn write_images(
    dir: &Path,
    contenders: &[Contender],
    frames: &[LinearImage],
    stills: &StillReferences,
    (w, h): (u32, u32),
    n: u32,
) -> Result<Vec<String>> {
    let reference_box = &stills.box_filtered;
    let window = ((w / 8).max(8), (h / 8).max(8));
    let nearest = contenders
        .iter()
        .position(|c| c.filter == TextureFilter::Nearest)
        .map(|i| &frames[i]);
    let pixel = |img: &LinearImage, x: u32, y: u32| img.pixels[(y * img.width + x) as usize];
    let luma = |img: &LinearImage, x: u32, y: u32| {
        let p = pixel(img, x.min(img.width - 1), y.min(img.height - 1));
        f64::from(0.2126 * p.r + 0.7152 * p.g + 0.0722 * p.b)
    };
    let aliasing_at = busiest_window(w, h, window.0, window.1, |x, y| {
        let r = luma(reference_box, x, y);
        nearest.map_or(0.0, |n| (luma(n, x, y) - r).abs())
    });
    let contrast_at = busiest_window(w, h, window.0, window.1, |x, y| {
        let r = luma(reference_box, x, y);
        (luma(reference_box, x + 1, y) - r).abs() + (luma(reference_box, x, y + 1) - r).abs()
    });
    let shrink_by = w.div_ceil(320).max(1);
    let row_of = |img: &LinearImage, reference: &LinearImage| {
        vec![
            shrink(img, shrink_by),
            magnify(
                &crop(img, aliasing_at.0, aliasing_at.1, window.0, window.1),
                3,
            ),
            magnify(
                &crop(img, contrast_at.0, contrast_at.1, window.0, window.1),
                3,
            ),
            shrink(&error_map(img, reference, 0.1), shrink_by),
        ]
    };
    let mut grid_rows = vec![row_of(reference_box, reference_box)];
    let mut labels = vec![format!("reference ({} spp)", n * n)];
    for (c, img) in contenders.iter().zip(frames) {
        grid_rows.push(row_of(img, stills.for_contender(c)));
        labels.push(c.label.clone());
    }
    // Each row starts with its name.
    for (row, label) in grid_rows.iter_mut().zip(&labels) {
        if let Some(l) = montage::label(label) {
            row.insert(0, l);
        }
    }
    let grid = grid(&grid_rows, 4);
    quadtex_io::save_image(&dir.join("grid.png"), &grid)?;
    quadtex_io::save_image(&dir.join("frames").join("reference.png"), reference_box)?;
    for (c, img) in contenders.iter().zip(frames) {
        let file = dir
            .join("frames")
            .join(format!("{}.png", file_stem(&c.label)));
        quadtex_io::save_image(&file, img)?;
    }
    Ok(labels)
}

/// Threads the renderer's pool uses by default (rayon: one per available core).
fn available_threads() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZero::get)
}

/// Where and how this run measures: the processor, threads, build profile,
/// the commit the binary was built from (embedded by build.rs) and today's
/// UTC date.
fn provenance(threads: usize) -> Provenance {
    let machine = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|text| {
            text.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into());
    let cores = std::thread::available_parallelism().map_or(0, usize::from);
    Provenance {
        machine: format!("{machine} ({cores} cores)"),
        threads,
        profile: if cfg!(debug_assertions) {
            "debug"
        } else {
            "release"
        }
        .into(),
        commit: env!("QUADTEX_COMMIT").into(),
        date: utc_date(std::time::SystemTime::now()),
    }
}

/// `YYYY-MM-DD` of a time, in UTC (civil-from-days, proleptic Gregorian).
fn utc_date(t: std::time::SystemTime) -> String {
    let days = t
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() / 86_400) as i64;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}

#[cfg(test)]
mod provenance_tests {
    use super::utc_date;
    use std::time::{Duration, UNIX_EPOCH};

    #[test]
    fn utc_dates_of_known_days() {
        assert_eq!(utc_date(UNIX_EPOCH), "1970-01-01");
        assert_eq!(
            utc_date(UNIX_EPOCH + Duration::from_secs(951_782_400)),
            "2000-02-29"
        );
        assert_eq!(
            utc_date(UNIX_EPOCH + Duration::from_secs(1_795_564_800)),
            "2026-11-25"
        );
    }
}

//! Pieces of `quadtex compare`: the contenders, error metrics against a
//! reference, image crops and grids, and the report's plot, tables and page.
//! No file I/O here; the CLI writes what these build.
//!
//! Metrics are computed on **linear** RGB (alpha ignored; rendered frames are
//! opaque): RMSE over all pixels and channels, PSNR = `20·log10(1/RMSE)`
//! (peak 1), and *temporal shimmer*: over a sequence of frames of a slow
//! camera move, the RMS over pixels and frame pairs of the change of the
//! error, `(img_t − ref_t) − (img_{t−1} − ref_{t−1})`. A filter whose error
//! is steady (a constant blur) scores low; one whose error crawls and
//! flickers from frame to frame (aliasing) scores high.

use quadtex_core::Rgba;
use quadtex_io::LinearImage;

use crate::footprint::LevelOfDetail;
use crate::render::{Filter, PixelFilter};

/// A filter configuration taking part in a comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct Contender {
    /// Short name for tables and plots.
    pub label: String,
    /// Texture filter.
    pub filter: Filter,
    /// Pixel filter.
    pub pixel_filter: PixelFilter,
}

impl Contender {
    fn new(label: &str, filter: Filter, pixel_filter: PixelFilter) -> Contender {
        Contender {
            label: label.into(),
            filter,
            pixel_filter,
        }
    }
}

/// The filters users would pick, and quadtex's settings, in report order.
pub fn default_contenders() -> Vec<Contender> {
    use PixelFilter::{Box, Tent};
    vec![
        Contender::new("quadtree", Filter::default(), Box),
        Contender::new(
            "quadtree q4",
            Filter::Quadtree {
                quality: 4.0,
                lod: LevelOfDetail::ErrorBound(1.0 / 512.0),
            },
            Box,
        ),
        Contender::new("quadtree tent", Filter::default(), Tent),
        Contender::new("nearest", Filter::Nearest, Box),
        Contender::new("bilinear", Filter::Bilinear, Box),
        Contender::new("trilinear", Filter::Trilinear, Box),
        Contender::new(
            "EWA aniso 8",
            Filter::Ewa {
                max_anisotropy: 8.0,
            },
            Box,
        ),
        Contender::new(
            "EWA aniso 32",
            Filter::Ewa {
                max_anisotropy: 32.0,
            },
            Box,
        ),
        Contender::new("SAT", Filter::Sat { quality: 1.0 }, Box),
        Contender::new("supersample 4", Filter::Supersample(2), Box),
        Contender::new("supersample 16", Filter::Supersample(4), Box),
        Contender::new("supersample 64", Filter::Supersample(8), Box),
    ]
}

/// Root-mean-square difference of linear RGB over all pixels and channels.
/// `None` when the sizes differ.
pub fn rmse(a: &LinearImage, b: &LinearImage) -> Option<f64> {
    if a.width != b.width || a.height != b.height || a.pixels.is_empty() {
        return None;
    }
    let mut sum = 0.0;
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        for (x, y) in [(p.r, q.r), (p.g, q.g), (p.b, q.b)] {
            let d = f64::from(x) - f64::from(y);
            sum += d * d;
        }
    }
    Some((sum / (3 * a.pixels.len()) as f64).sqrt())
}

/// Peak signal-to-noise ratio in dB for peak 1 (infinite for identical images).
pub fn psnr(rmse: f64) -> f64 {
    -20.0 * rmse.log10()
}

/// Temporal shimmer of `frames` against `references` (see the module docs);
/// `None` with fewer than two frames or mismatched sizes.
pub fn shimmer(frames: &[LinearImage], references: &[LinearImage]) -> Option<f64> {
    if frames.len() < 2 || frames.len() != references.len() {
        return None;
    }
    let mut sum = 0.0;
    let mut count = 0usize;
    for t in 1..frames.len() {
        let (a, b, ra, rb) = (
            &frames[t],
            &frames[t - 1],
            &references[t],
            &references[t - 1],
        );
        let n = a.pixels.len();
        if [b.pixels.len(), ra.pixels.len(), rb.pixels.len()] != [n, n, n] {
            return None;
        }
        for i in 0..n {
            let (p, q, r, s) = (a.pixels[i], b.pixels[i], ra.pixels[i], rb.pixels[i]);
            for ch in 0..3 {
                let v = |c: Rgba| f64::from(c.to_array()[ch]);
                let d = (v(p) - v(r)) - (v(q) - v(s));
                sum += d * d;
            }
            count += 3;
        }
    }
    Some((sum / count.max(1) as f64).sqrt())
}

/// A false-colour map of `|a − b|` (mean over RGB): black at 0 through red
/// and yellow to white at `full_scale` and above.
pub fn error_map(a: &LinearImage, b: &LinearImage, full_scale: f32) -> LinearImage {
    let pixels = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| {
            let e = ((p.r - q.r).abs() + (p.g - q.g).abs() + (p.b - q.b).abs()) / 3.0;
            let t = (e / full_scale).clamp(0.0, 1.0);
            // Linear-light ramp, so the sRGB PNG reads black → red → yellow → white.
            let r = (3.0 * t).min(1.0);
            let g = (3.0 * t - 1.0).clamp(0.0, 1.0);
            let bl = (3.0 * t - 2.0).clamp(0.0, 1.0);
            Rgba::opaque(r * r, g * g, bl * bl)
        })
        .collect();
    LinearImage {
        width: a.width,
        height: a.height,
        pixels,
    }
}

/// The `w × h` window at `(x, y)`, clipped to the image.
pub fn crop(img: &LinearImage, x: u32, y: u32, w: u32, h: u32) -> LinearImage {
    let x = x.min(img.width.saturating_sub(1));
    let y = y.min(img.height.saturating_sub(1));
    let w = w.min(img.width - x).max(1);
    let h = h.min(img.height - y).max(1);
    let mut pixels = Vec::with_capacity((w * h) as usize);
    for row in y..y + h {
        let start = (row * img.width + x) as usize;
        pixels.extend_from_slice(&img.pixels[start..start + w as usize]);
    }
    LinearImage {
        width: w,
        height: h,
        pixels,
    }
}

/// Each pixel repeated `k × k` times (to show crops without resampling blur).
pub fn magnify(img: &LinearImage, k: u32) -> LinearImage {
    let k = k.max(1);
    let (w, h) = (img.width * k, img.height * k);
    let mut pixels = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            pixels.push(img.pixels[((y / k) * img.width + x / k) as usize]);
        }
    }
    LinearImage {
        width: w,
        height: h,
        pixels,
    }
}

/// Box-downscaled by the integer factor `k` (in linear light).
pub fn shrink(img: &LinearImage, k: u32) -> LinearImage {
    let k = k.max(1);
    let (w, h) = ((img.width / k).max(1), (img.height / k).max(1));
    let mut pixels = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let mut acc = [0f32; 4];
            let mut n = 0.0;
            for yy in y * k..((y + 1) * k).min(img.height) {
                for xx in x * k..((x + 1) * k).min(img.width) {
                    let p = img.pixels[(yy * img.width + xx) as usize].to_array();
                    for (a, v) in acc.iter_mut().zip(p) {
                        *a += v;
                    }
                    n += 1.0;
                }
            }
            pixels.push(Rgba::new(acc[0] / n, acc[1] / n, acc[2] / n, acc[3] / n));
        }
    }
    LinearImage {
        width: w,
        height: h,
        pixels,
    }
}

/// A 256 × 24 image of `text` in white on transparent, set with the SVG
/// packer's shipped font and packed exactly (the report's grid labels).
/// `None` if the text cannot be set.
pub fn label(text: &str) -> Option<LinearImage> {
    const LEVEL: u8 = 8;
    const W: u32 = 256;
    const H: u32 = 24;
    let svg = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {W} {H}"><text x="4" y="18" font-size="16" fill="white">{}</text></svg>"#,
        escape(text)
    );
    let limits = quadtex_io::Limits::default();
    let art = quadtex_io::parse_svg(
        svg.as_bytes(),
        std::path::Path::new("label.svg"),
        LEVEL,
        &limits,
    )
    .ok()?;
    let options = quadtex_core::VectorOptions {
        max_level: LEVEL,
        ..quadtex_core::VectorOptions::default()
    };
    let (tree, _) = quadtex_core::QuadTree::from_vector(&art, &options).ok()?;
    let grid = tree.rasterise(LEVEL).ok()?;
    // The drawing's longer side spans the square: the label is the top rows.
    let pixels = grid.texels()[..(W * H) as usize]
        .iter()
        .map(|t| t.to_rgba())
        .collect();
    Some(LinearImage {
        width: W,
        height: H,
        pixels,
    })
}

/// Tiles `rows` of images on a dark background with `gap` pixels between
/// them, each row as tall as its tallest image.
pub fn grid(rows: &[Vec<LinearImage>], gap: u32) -> LinearImage {
    let width = rows
        .iter()
        .map(|r| r.iter().map(|i| i.width + gap).sum::<u32>() + gap)
        .max()
        .unwrap_or(1);
    let height = rows
        .iter()
        .map(|r| r.iter().map(|i| i.height).max().unwrap_or(0) + gap)
        .sum::<u32>()
        + gap;
    let bg = Rgba::opaque(0.02, 0.02, 0.02);
    let mut out = vec![bg; (width * height) as usize];
    let mut y0 = gap;
    for row in rows {
        let mut x0 = gap;
        for img in row {
            for y in 0..img.height {
                let dst = ((y0 + y) * width + x0) as usize;
                let src = (y * img.width) as usize;
                // Composite over the background, so transparent labels read.
                for (o, p) in out[dst..dst + img.width as usize]
                    .iter_mut()
                    .zip(&img.pixels[src..src + img.width as usize])
                {
                    let keep = 1.0 - p.a;
                    *o = Rgba::new(
                        p.r + o.r * keep,
                        p.g + o.g * keep,
                        p.b + o.b * keep,
                        p.a + o.a * keep,
                    );
                }
            }
            x0 += img.width + gap;
        }
        y0 += row.iter().map(|i| i.height).max().unwrap_or(0) + gap;
    }
    LinearImage {
        width,
        height,
        pixels: out,
    }
}

/// The top-left corner of the `w × h` window (on a grid of half-window
/// steps) that maximises `score(x, y)` summed over the window.
pub fn busiest_window(
    width: u32,
    height: u32,
    w: u32,
    h: u32,
    score: impl Fn(u32, u32) -> f64,
) -> (u32, u32) {
    let (mut best, mut at) = (f64::NEG_INFINITY, (0, 0));
    let (sx, sy) = ((w / 2).max(1), (h / 2).max(1));
    let mut y = 0;
    while y + h <= height {
        let mut x = 0;
        while x + w <= width {
            let mut s = 0.0;
            for yy in y..y + h {
                for xx in x..x + w {
                    s += score(xx, yy);
                }
            }
            if s > best {
                best = s;
                at = (x, y);
            }
            x += sx;
        }
        y += sy;
    }
    at
}

/// One contender's figures.
#[derive(Debug, Clone, PartialEq)]
pub struct Figures {
    /// The contender's label.
    pub label: String,
    /// RMSE against the reference (linear).
    pub rmse: f64,
    /// PSNR in dB.
    pub psnr: f64,
    /// RMSE against the closed-form image where the scene has one (over the
    /// pixels where it is defined).
    pub rmse_exact: Option<f64>,
    /// Mean FLIP against the reference, when computed.
    pub flip: Option<f64>,
    /// Temporal shimmer over the camera move, when computed.
    pub shimmer: Option<f64>,
    /// Median wall-clock seconds per frame.
    pub seconds: f64,
    /// Texture lookups (tree queries or raster taps) per textured pixel, when known.
    pub lookups_per_pixel: Option<f64>,
    /// Bytes of texture data the filter needs.
    pub texture_bytes: u64,
}

fn fmt_opt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "–".into(), |v| format!("{v:.digits$}"))
}

fn human(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= 1024.0 * 1024.0 * 1024.0 {
        format!("{:.2} GiB", b / (1024.0 * 1024.0 * 1024.0))
    } else if b >= 1024.0 * 1024.0 {
        format!("{:.2} MiB", b / (1024.0 * 1024.0))
    } else {
        format!("{:.1} KiB", b / 1024.0)
    }
}

/// Column headings of the figures table (Markdown and HTML).
const HEADINGS: [&str; 9] = [
    "filter",
    "RMSE",
    "PSNR dB",
    "RMSE vs closed form",
    "FLIP",
    "shimmer",
    "ms/frame",
    "lookups/px",
    "texture memory",
];

/// One contender's cells, formatted for display, in [`HEADINGS`] order.
fn cells(r: &Figures) -> [String; 9] {
    [
        r.label.clone(),
        format!("{:.4}", r.rmse),
        format!("{:.1}", r.psnr),
        fmt_opt(r.rmse_exact, 4),
        fmt_opt(r.flip, 4),
        fmt_opt(r.shimmer, 4),
        format!("{:.0}", 1000.0 * r.seconds),
        fmt_opt(r.lookups_per_pixel, 1),
        human(r.texture_bytes),
    ]
}

/// The figures as a Markdown table.
pub fn markdown_table(rows: &[Figures]) -> String {
    let mut s = format!(
        "| {} |\n|---|{}\n",
        HEADINGS.join(" | "),
        "---:|".repeat(HEADINGS.len() - 1)
    );
    for r in rows {
        s.push_str(&format!("| {} |\n", cells(r).join(" | ")));
    }
    s
}

/// The figures as CSV (one header line).
pub fn csv(rows: &[Figures]) -> String {
    let mut s = String::from(
        "filter,rmse,psnr_db,rmse_closed_form,flip,shimmer,seconds_per_frame,lookups_per_pixel,texture_bytes\n",
    );
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v}"));
    for r in rows {
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{}\n",
            r.label,
            r.rmse,
            r.psnr,
            opt(r.rmse_exact),
            opt(r.flip),
            opt(r.shimmer),
            r.seconds,
            opt(r.lookups_per_pixel),
            r.texture_bytes
        ));
    }
    s
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A log–log scatter plot (SVG) of RMSE against milliseconds per frame, one
/// labelled point per contender; quadtex's points in orange.
pub fn plot_svg(rows: &[Figures], title: &str) -> String {
    let (w, h, m) = (720.0, 480.0, 70.0);
    let finite: Vec<&Figures> = rows
        .iter()
        .filter(|r| r.rmse > 0.0 && r.seconds > 0.0)
        .collect();
    let lx = |r: &Figures| (1000.0 * r.seconds).log10();
    let ly = |r: &Figures| r.rmse.log10();
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for r in &finite {
        x0 = x0.min(lx(r));
        x1 = x1.max(lx(r));
        y0 = y0.min(ly(r));
        y1 = y1.max(ly(r));
    }
    if finite.is_empty() {
        (x0, x1, y0, y1) = (0.0, 1.0, -3.0, 0.0);
    }
    let (x0, x1) = (x0.floor(), x1.ceil().max(x0.floor() + 1.0));
    let (y0, y1) = (y0.floor(), y1.ceil().max(y0.floor() + 1.0));
    let px = |v: f64| m + (v - x0) / (x1 - x0) * (w - 2.0 * m);
    let py = |v: f64| h - m - (v - y0) / (y1 - y0) * (h - 2.0 * m);
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n<text x=\"{}\" y=\"24\" text-anchor=\"middle\" font-size=\"15\">{}</text>\n",
        w / 2.0,
        escape(title)
    );
    // Decade grid and labels.
    let mut d = x0;
    while d <= x1 + 1e-9 {
        s.push_str(&format!(
            "<line x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{2}\" stroke=\"#ddd\"/><text x=\"{0}\" y=\"{3}\" text-anchor=\"middle\">{4}</text>\n",
            px(d),
            m,
            h - m,
            h - m + 18.0,
            10f64.powf(d)
        ));
        d += 1.0;
    }
    let mut d = y0;
    while d <= y1 + 1e-9 {
        s.push_str(&format!(
            "<line x1=\"{1}\" y1=\"{0}\" x2=\"{2}\" y2=\"{0}\" stroke=\"#ddd\"/><text x=\"{3}\" y=\"{4}\" text-anchor=\"end\">{5}</text>\n",
            py(d),
            m,
            w - m,
            m - 6.0,
            py(d) + 4.0,
            10f64.powf(d)
        ));
        d += 1.0;
    }
    s.push_str(&format!(
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">milliseconds per frame (log)</text>\n<text transform=\"translate(18 {}) rotate(-90)\" text-anchor=\"middle\">RMSE against the reference, linear (log)</text>\n",
        w / 2.0,
        h - 20.0,
        h / 2.0
    ));
    for r in &finite {
        let ours = r.label.starts_with("quadtree");
        let colour = if ours { "#e66a00" } else { "#2060c0" };
        s.push_str(&format!(
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"5\" fill=\"{colour}\"/><text x=\"{:.1}\" y=\"{:.1}\" fill=\"{colour}\">{}</text>\n",
            px(lx(r)),
            py(ly(r)),
            px(lx(r)) + 8.0,
            py(ly(r)) - 6.0,
            escape(&r.label)
        ));
    }
    s.push_str("</svg>\n");
    s
}

/// What the report page shows about the run.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportInfo {
    /// Scene name.
    pub scene: String,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// How the reference was made.
    pub reference: String,
    /// How shimmer was measured.
    pub motion: String,
    /// Machine and thread count.
    pub machine: String,
}

/// The static report page (no scripts, no network): the table, the plot and
/// the grid, with the images beside it.
pub fn html_report(info: &ReportInfo, rows: &[Figures], labels_in_grid: &[String]) -> String {
    let mut s = format!(
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>quadtex compare: {scene}</title>\n<style>body{{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:3px 8px;text-align:right}}td:first-child,th:first-child{{text-align:left}}img{{max-width:100%;image-rendering:pixelated}}</style></head><body>\n<h1>quadtex compare: {scene}</h1>\n<p>{w}×{h} pixels. Reference: {reference}. Shimmer: {motion}. {machine}. Metrics in linear light; RMSE and FLIP against the reference; time is the median wall-clock time per frame in this run.</p>\n<h2>Error against time</h2>\n<p><img src=\"plot.svg\" alt=\"RMSE against milliseconds per frame\"></p>\n<h2>Figures</h2>\n<table><tr><th>{headings}</th></tr>\n",
        headings = HEADINGS.join("</th><th>"),
        scene = escape(&info.scene),
        w = info.width,
        h = info.height,
        reference = escape(&info.reference),
        motion = escape(&info.motion),
        machine = escape(&info.machine),
    );
    for r in rows {
        let row = cells(r).map(|c| escape(&c));
        s.push_str(&format!("<tr><td>{}</td></tr>\n", row.join("</td><td>")));
    }
    s.push_str("</table>\n<p>Also as <a href=\"results.csv\">CSV</a> and <a href=\"results.md\">Markdown</a>.</p>\n<h2>Images</h2>\n<p>One row each, top to bottom: ");
    s.push_str(&escape(&labels_in_grid.join(", ")));
    s.push_str(". Columns: the full frame (reduced), the window where point sampling errs most (magnified, no resampling), the window of highest contrast in the reference (magnified), and the error map (|error| from black to white at 0.1).</p>\n<p><img src=\"grid.png\" alt=\"comparison grid\"></p>\n<p>Full-size frames: <a href=\"frames/reference.png\">reference</a> ");
    for r in rows {
        s.push_str(&format!(
            "<a href=\"frames/{}.png\">{}</a> ",
            file_stem(&r.label),
            escape(&r.label)
        ));
    }
    s.push_str("</p>\n</body></html>\n");
    s
}

/// A label as a file name (`EWA aniso 8` → `ewa-aniso-8`).
pub fn file_stem(label: &str) -> String {
    label
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect()
}

/// The closed-form box-filtered image of a scene made of one unlit,
/// textured, repeating **plane**: each pixel is the exact integral of the
/// texture over the part of the pixel square that sees the plane. For every
/// cell of the tree's finest grid (a texel of the checker) under the pixel's
/// footprint, the cell is mapped to the screen (a convex quadrilateral, the
/// projective image of a square) and clipped against the pixel square; the
/// pixel is `Σ colour × area`. Pixels that see the sky, or whose footprint
/// covers more than `max_cells` cells, are `None` (excluded). Returns `None`
/// for scenes of any other kind.
pub fn closed_form_plane(
    scene: &crate::Scene,
    width: u32,
    height: u32,
    max_cells: u64,
) -> Option<Vec<Option<Rgba>>> {
    use crate::scene::{Geometry, Lighting, WrapMode};
    let [surface] = scene.surfaces.as_slice() else {
        return None;
    };
    let (
        Geometry::Plane {
            point,
            normal,
            u_axis,
            v_axis,
        },
        Some(texture),
        Lighting::Unlit,
        WrapMode::Repeat,
    ) = (
        &surface.geometry,
        &surface.texture,
        scene.lighting,
        surface.wrap,
    )
    else {
        return None;
    };
    let tree = &texture.tree;
    if tree.depth() > 12 {
        return None;
    }
    let cells_per_unit = 1u32 << tree.depth();
    let cell = 1.0 / f64::from(cells_per_unit);
    // Colour of every finest cell of one tile.
    let mut colours = Vec::with_capacity((cells_per_unit * cells_per_unit) as usize);
    for j in 0..cells_per_unit {
        for i in 0..cells_per_unit {
            let f = quadtex_core::Fragment::new(
                f64::from(i) * cell,
                f64::from(j) * cell,
                f64::from(i + 1) * cell,
                f64::from(j + 1) * cell,
            )
            .ok()?;
            let c = tree.weighted_colour(&f, u8::MAX).mean_over(f.area());
            colours.push(Rgba::new(
                c.r * surface.colour.r,
                c.g * surface.colour.g,
                c.b * surface.colour.b,
                c.a * surface.colour.a,
            ));
        }
    }
    let camera = scene.camera.with_size(width, height);
    let project = |p: crate::math::Vec3| -> Option<[f64; 2]> {
        let d = p - camera.position;
        let z = d.dot(camera.forward);
        if z <= 1e-9 {
            return None;
        }
        let aspect = f64::from(width) / f64::from(height);
        let sx = (d.dot(camera.right) / z / (camera.tan_half_fov * aspect) + 1.0)
            * f64::from(width)
            / 2.0;
        let sy = (1.0 - d.dot(camera.up) / z / camera.tan_half_fov) * f64::from(height) / 2.0;
        Some([sx, sy])
    };
    let to_texture = |sx: f64, sy: f64| -> Option<[f64; 2]> {
        let ray = camera.ray(sx, sy);
        let denom = ray.direction.dot(*normal);
        if denom.abs() < 1e-12 {
            return None;
        }
        let t = (*point - ray.origin).dot(*normal) / denom;
        if !(t > 0.0 && t.is_finite()) {
            return None;
        }
        let rel = ray.origin + ray.direction * t - *point;
        Some(
            surface
                .uv_transform
                .apply([rel.dot(*u_axis), rel.dot(*v_axis)]),
        )
    };
    let to_world = |t: [f64; 2]| {
        let uv = surface.uv_transform.invert(t);
        *point + *u_axis * uv[0] + *v_axis * uv[1]
    };
    let mut out = Vec::with_capacity((width * height) as usize);
    for y in 0..height {
        for x in 0..width {
            let (x0, y0) = (f64::from(x), f64::from(y));
            let corners = [
                (x0, y0),
                (x0 + 1.0, y0),
                (x0 + 1.0, y0 + 1.0),
                (x0, y0 + 1.0),
            ];
            let tex: Option<Vec<[f64; 2]>> =
                corners.iter().map(|&(sx, sy)| to_texture(sx, sy)).collect();
            let Some(tex) = tex else {
                out.push(None);
                continue;
            };
            let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
            for p in &tex {
                for a in 0..2 {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
            }
            let (i0, i1) = ((lo[0] / cell).floor(), (hi[0] / cell).ceil());
            let (j0, j1) = ((lo[1] / cell).floor(), (hi[1] / cell).ceil());
            if (i1 - i0) * (j1 - j0) > max_cells as f64 {
                out.push(None);
                continue;
            }
            let pixel = vec![
                [x0, y0],
                [x0 + 1.0, y0],
                [x0 + 1.0, y0 + 1.0],
                [x0, y0 + 1.0],
            ];
            let mut acc = [0f64; 4];
            let mut covered = 0.0;
            let mut ok = true;
            let mut j = j0;
            while j < j1 && ok {
                let mut i = i0;
                while i < i1 {
                    let quad: Option<Vec<[f64; 2]>> = [
                        [i * cell, j * cell],
                        [(i + 1.0) * cell, j * cell],
                        [(i + 1.0) * cell, (j + 1.0) * cell],
                        [i * cell, (j + 1.0) * cell],
                    ]
                    .iter()
                    .map(|&t| project(to_world(t)))
                    .collect();
                    let Some(quad) = quad else {
                        ok = false;
                        break;
                    };
                    let area = clip_convex_area(&pixel, &quad);
                    if area > 0.0 {
                        let ci = (i.rem_euclid(f64::from(cells_per_unit))) as usize;
                        let cj = (j.rem_euclid(f64::from(cells_per_unit))) as usize;
                        let c = colours[cj * cells_per_unit as usize + ci].to_array();
                        for (a, v) in acc.iter_mut().zip(c) {
                            *a += area * f64::from(v);
                        }
                        covered += area;
                    }
                    i += 1.0;
                }
                j += 1.0;
            }
            // The cells must tile the pixel (it sees only the plane).
            if !ok || (covered - 1.0).abs() > 1e-6 {
                out.push(None);
                continue;
            }
            out.push(Some(Rgba::new(
                acc[0] as f32,
                acc[1] as f32,
                acc[2] as f32,
                acc[3] as f32,
            )));
        }
    }
    Some(out)
}

/// Area of the intersection of convex polygon `subject` with convex polygon
/// `clip` (either orientation), by Sutherland–Hodgman.
fn clip_convex_area(subject: &[[f64; 2]], clip: &[[f64; 2]]) -> f64 {
    let signed = |p: &[[f64; 2]]| {
        let n = p.len();
        (0..n)
            .map(|i| p[i][0] * p[(i + 1) % n][1] - p[(i + 1) % n][0] * p[i][1])
            .sum::<f64>()
            * 0.5
    };
    let orientation = signed(clip).signum();
    let mut poly = subject.to_vec();
    let n = clip.len();
    for k in 0..n {
        let (a, b) = (clip[k], clip[(k + 1) % n]);
        let side = |p: [f64; 2]| {
            orientation * ((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]))
        };
        let mut next = Vec::with_capacity(poly.len() + 2);
        for i in 0..poly.len() {
            let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
            let (sp, sq) = (side(p), side(q));
            if sp >= 0.0 {
                next.push(p);
            }
            if (sp >= 0.0) != (sq >= 0.0) {
                let t = sp / (sp - sq);
                next.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
            }
        }
        poly = next;
        if poly.len() < 3 {
            return 0.0;
        }
    }
    signed(&poly).abs()
}

/// RMSE of `img` against the closed form over the pixels where it is defined,
/// and the fraction of pixels defined.
pub fn rmse_where_defined(img: &LinearImage, exact: &[Option<Rgba>]) -> Option<(f64, f64)> {
    if exact.len() != img.pixels.len() {
        return None;
    }
    let (mut sum, mut n) = (0.0, 0usize);
    for (p, e) in img.pixels.iter().zip(exact) {
        if let Some(e) = e {
            for (a, b) in [(p.r, e.r), (p.g, e.g), (p.b, e.b)] {
                let d = f64::from(a) - f64::from(b);
                sum += d * d;
            }
            n += 1;
        }
    }
    (n > 0).then(|| ((sum / (3 * n) as f64).sqrt(), n as f64 / exact.len() as f64))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(values: &[f32]) -> LinearImage {
        LinearImage {
            width: values.len() as u32,
            height: 1,
            pixels: values.iter().map(|&v| Rgba::opaque(v, v, v)).collect(),
        }
    }

    #[test]
    fn rmse_and_psnr() {
        let a = image(&[0.0, 0.5]);
        let b = image(&[0.1, 0.5]);
        let r = rmse(&a, &b).unwrap();
        assert!((r - (0.01f64 / 2.0).sqrt()).abs() < 1e-7);
        assert!((psnr(0.1) - 20.0).abs() < 1e-9);
        assert!(rmse(&a, &image(&[0.0])).is_none());
    }

    #[test]
    fn steady_error_does_not_shimmer_but_flicker_does() {
        let refs = vec![image(&[0.5, 0.5]); 4];
        let blurred = vec![image(&[0.4, 0.6]); 4];
        assert_eq!(shimmer(&blurred, &refs), Some(0.0));
        let flicker: Vec<_> = (0..4)
            .map(|t| {
                if t % 2 == 0 {
                    image(&[0.4, 0.6])
                } else {
                    image(&[0.6, 0.4])
                }
            })
            .collect();
        assert!((shimmer(&flicker, &refs).unwrap() - 0.2).abs() < 1e-6);
    }

    #[test]
    fn labels_are_set_in_white_on_transparent() {
        let l = label("quadtree").unwrap();
        assert_eq!((l.width, l.height), (256, 24));
        let inked = l.pixels.iter().filter(|p| p.a > 0.5).count();
        assert!(inked > 100 && inked < 256 * 24 / 3, "{inked} inked pixels");
        assert!(
            l.pixels.iter().all(|p| (p.r - p.a).abs() < 1e-3),
            "white, premultiplied"
        );
        // Nothing past the text's end.
        assert!(
            l.pixels
                .iter()
                .enumerate()
                .all(|(i, p)| i % 256 < 120 || p.a == 0.0)
        );
    }

    #[test]
    fn crops_grids_and_windows() {
        let img = LinearImage {
            width: 4,
            height: 4,
            pixels: (0..16).map(|i| Rgba::opaque(i as f32, 0.0, 0.0)).collect(),
        };
        let c = crop(&img, 1, 2, 2, 2);
        assert_eq!(
            c.pixels.iter().map(|p| p.r).collect::<Vec<_>>(),
            vec![9.0, 10.0, 13.0, 14.0]
        );
        assert_eq!(magnify(&c, 3).width, 6);
        assert_eq!(shrink(&img, 2).pixels[0].r, 2.5);
        let g = grid(&[vec![c.clone(), c.clone()], vec![c]], 1);
        assert_eq!((g.width, g.height), (7, 7));
        assert_eq!(busiest_window(4, 4, 2, 2, |x, y| f64::from(x + y)), (2, 2));
        assert_eq!(file_stem("EWA aniso 8"), "ewa-aniso-8");
    }
}

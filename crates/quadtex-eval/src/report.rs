//! The comparison's figures per contender and the report built from them:
//! Markdown and CSV tables, an SVG plot of error against time, and the HTML
//! page. No file I/O here; the CLI writes what these build.

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
    // Full-resolution rasters of deep trees (contour leaves answer to
    // level 30) run to exbibytes: say so, not 4 294 967 296 GiB.
    for (unit, shift) in [("EiB", 60), ("PiB", 50), ("TiB", 40)] {
        if b >= (1u64 << shift) as f64 {
            return format!("{:.2} {unit}", b / (1u64 << shift) as f64);
        }
    }
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
pub fn csv(rows: &[Figures], provenance: &Provenance) -> String {
    let mut s = String::from(
        "filter,rmse,psnr_db,rmse_closed_form,flip,shimmer,seconds_per_frame,lookups_per_pixel,texture_bytes,machine,threads,profile,commit,date\n",
    );
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v}"));
    let p = provenance;
    let tail = format!(
        "{},{},{},{},{}",
        csv_field(&p.machine),
        p.threads,
        csv_field(&p.profile),
        csv_field(&p.commit),
        csv_field(&p.date)
    );
    for r in rows {
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{tail}\n",
            csv_field(&r.label),
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

pub(crate) fn escape(s: &str) -> String {
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
    /// Where and how the figures were measured.
    pub provenance: Provenance,
}

/// Where and how figures were measured, so each carries its provenance
/// (the report's page and every CSV row).
#[derive(Debug, Clone, PartialEq)]
pub struct Provenance {
    /// The processor (model name), or `unknown`.
    pub machine: String,
    /// Worker threads the renders used.
    pub threads: usize,
    /// Build profile of the binary (`release` or `debug`).
    pub profile: String,
    /// The commit the binary was built from (`+dirty` when the tree had
    /// uncommitted changes), or `unknown`.
    pub commit: String,
    /// UTC date of the run, `YYYY-MM-DD`.
    pub date: String,
}

impl Provenance {
    /// One sentence for the report's page.
    pub fn describe(&self) -> String {
        format!(
            "Measured on {} with {} worker threads, {} build of commit {}, on {}",
            self.machine, self.threads, self.profile, self.commit, self.date
        )
    }
}

/// A CSV field, quoted when it holds a comma, quote or newline.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
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
        machine = escape(&info.provenance.describe()),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_rows_carry_their_provenance() {
        let p = Provenance {
            machine: "AMD EPYC, 2 cores".into(),
            threads: 2,
            profile: "release".into(),
            commit: "abc123".into(),
            date: "2026-11-25".into(),
        };
        let row = Figures {
            label: "quadtree".into(),
            rmse: 0.5,
            psnr: 6.0,
            rmse_exact: None,
            flip: None,
            shimmer: None,
            seconds: 1.0,
            lookups_per_pixel: None,
            texture_bytes: 10,
        };
        let text = csv(&[row], &p);
        let line = text.lines().nth(1).unwrap();
        assert!(
            line.ends_with(",\"AMD EPYC, 2 cores\",2,release,abc123,2026-11-25"),
            "{line}"
        );
        assert_eq!(text.lines().next().unwrap().split(',').count(), 14);
    }

    #[test]
    fn file_stems_are_plain() {
        assert_eq!(file_stem("EWA aniso 8"), "ewa-aniso-8");
    }
}

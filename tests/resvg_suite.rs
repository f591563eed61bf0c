//! resvg's own SVG test suite (`tests/resvg-suite/tests/`, 944 SVGs with the PNGs
//! resvg renders of them): every file is packed; none may panic; a refusal
//! must name a feature quadtex still refuses; everything packed is
//! compared pixel by pixel with resvg's PNG.
//!
//! The comparison: each pixel of the PNG (300 px on the SVG's longer side)
//! is the tree's exact box integral over that pixel's square, at level
//! [`LEVEL`]; both are premultiplied, sRGB-encoded 8-bit values. A pixel
//! differs when a channel is off by more than [`PIXEL_TOLERANCE`]. Edge
//! pixels (resvg's 3×3 neighbourhood not uniform) may differ: there
//! resvg's antialiasing (coverage blended in sRGB, conflation of shared
//! edges) and quadtex's exact area mean in linear light differ by design.
//! A file **matches** when at most [`MATCH_SHARE`] of its pixels differ
//! away from edges. Files that differ more are listed with the reason their
//! source gives away (text set in another font, translucent overlaps
//! composited in linear light, resvg's pattern tiles rounded to whole
//! pixels), or "other".
//!
//! `QUADTEX_SUITE_REPORT=FILE cargo test --release --test resvg_suite`
//! writes the per-category table and the per-file list to `FILE`;
//! `QUADTEX_SUITE_DEBUG=SUFFIX` prints the first differing pixels of the
//! file whose path ends with `SUFFIX`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use quadtex_core::srgb_encode_f32;
use quadtex_core::{Fragment, QuadTree, VectorOptions};
use quadtex_io::{Error, ExternalResources, Limits, load_linear_image, parse_svg};

/// Packing level: leaves of `1/4096`, a fourteenth of a pixel.
const LEVEL: u8 = 12;
/// Gradients' smooth-colour tolerance (sRGB-encoded): two 8-bit steps,
/// eight times the default, to keep the test fast; well within
/// [`PIXEL_TOLERANCE`].
const SMOOTH_TOLERANCE: f64 = 2.0 / 255.0;
/// Largest difference, in 8-bit steps, a pixel may have and still agree.
const PIXEL_TOLERANCE: f64 = 8.0;
/// Share of pixels away from edges allowed to disagree in a matching file.
const MATCH_SHARE: f64 = 0.001;
/// Features quadtex still refuses; a refusal naming anything else fails.
const STILL_REFUSED: &[&str] = &[
    "radialGradient with the focal circle not inside the end circle",
    "filter",
    "image in GIF format",
    "image in WebP format",
    "image in compressed SVG (svgz) format",
    "pattern repeated over more than 4096 tiles",
];

enum Outcome {
    /// usvg rejects the file (resvg's PNG shows its fallback).
    Invalid(String),
    Refused(String),
    Compared {
        /// Share of pixels off by more than the tolerance.
        differing: f64,
        /// Share of pixels off by more than the tolerance away from edges.
        interior: f64,
        /// Mean absolute difference per channel, 8-bit steps.
        mean: f64,
    },
}

fn suite_dir() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/resvg-suite/tests"
    ))
}

fn svgs(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            svgs(&p, out);
        } else if p.extension().is_some_and(|e| e == "svg") {
            out.push(p);
        }
    }
}

/// Premultiplied sRGB 8-bit value of a linear premultiplied colour.
fn encoded(c: [f32; 4]) -> [f64; 4] {
    let a = c[3].clamp(0.0, 1.0);
    if a <= 0.0 {
        return [0.0; 4];
    }
    let e = |v: f32| f64::from(srgb_encode_f32(v / a) * a) * 255.0;
    [e(c[0]), e(c[1]), e(c[2]), f64::from(a) * 255.0]
}

/// The most sweep steps one file's packing took, and the file.
static MOST_SWEEP_WORK: std::sync::Mutex<(u64, Option<PathBuf>)> = std::sync::Mutex::new((0, None));

fn check(svg: &Path) -> Outcome {
    let data = std::fs::read(svg).unwrap();
    // The suite's images live in `tests/resvg-suite/resources/`, beside
    // the tests' folders (`../../../resources/image.png`), outside each
    // SVG's own folder: the policy is widened for this trusted suite.
    let limits = Limits {
        external_resources: ExternalResources::Anywhere,
        ..Limits::default()
    };
    let art = match parse_svg(
        &data,
        svg,
        &quadtex_io::SvgOptions::at_level(LEVEL).with_limits(limits),
    ) {
        Ok(art) => art,
        Err(Error::UnsupportedSvg { element, .. }) => {
            let feature = element.split(" (id ").next().unwrap_or("").to_string();
            return Outcome::Refused(feature);
        }
        Err(Error::Svg { message, .. }) => return Outcome::Invalid(message),
        // An image that is missing or broken: the file is at fault.
        Err(e @ (Error::Io { .. } | Error::Image { .. })) => {
            return Outcome::Invalid(e.to_string());
        }
        Err(e) => panic!("{}: unexpected error {e}", svg.display()),
    };
    let options = VectorOptions {
        max_level: LEVEL,
        tolerance: SMOOTH_TOLERANCE,
        ..VectorOptions::default()
    };
    let (tree, packed) = QuadTree::from_vector(&art, &options)
        .unwrap_or_else(|e| panic!("{}: packing failed: {e}", svg.display()));
    let mut most = MOST_SWEEP_WORK.lock().unwrap();
    if packed.sweep_work > most.0 {
        *most = (packed.sweep_work, Some(svg.to_path_buf()));
    }
    drop(most);
    let reference = load_linear_image(&svg.with_extension("png")).unwrap();
    let (w, h) = (reference.width, reference.height);
    let side = f64::from(w.max(h));
    let want: Vec<[f64; 4]> = reference
        .pixels
        .iter()
        .map(|p| encoded(p.to_array()))
        .collect();
    // A pixel is on an edge when resvg's 3×3 neighbourhood around it is not uniform.
    let on_edge = |col: u32, row: u32| {
        let r = want[(row * w + col) as usize];
        (row.saturating_sub(1)..(row + 2).min(h)).any(|j| {
            (col.saturating_sub(1)..(col + 2).min(w)).any(|i| {
                let q = want[(j * w + i) as usize];
                (0..4).any(|c| (q[c] - r[c]).abs() > PIXEL_TOLERANCE)
            })
        })
    };
    let (mut differing, mut interior, mut total) = (0usize, 0usize, 0.0);
    for row in 0..h {
        for col in 0..w {
            let (x0, x1) = (f64::from(col) / side, f64::from(col + 1) / side);
            let (z0, z1) = (1.0 - f64::from(row + 1) / side, 1.0 - f64::from(row) / side);
            let f = Fragment::new(x0, z0, x1, z1).unwrap();
            let got = tree.weighted_colour(&f, LEVEL).mean_over(f.area());
            let (g, r) = (encoded(got.to_array()), want[(row * w + col) as usize]);
            let diff = (0..4).map(|c| (g[c] - r[c]).abs()).fold(0.0, f64::max);
            total += (0..4).map(|c| (g[c] - r[c]).abs()).sum::<f64>() / 4.0;
            if diff > PIXEL_TOLERANCE {
                if std::env::var("QUADTEX_SUITE_DEBUG").is_ok_and(|d| svg.ends_with(&d))
                    && !on_edge(col, row)
                {
                    eprintln!(
                        "{col},{row}: got {g:?} want {r:?} edge {}",
                        on_edge(col, row)
                    );
                }
                differing += 1;
                interior += usize::from(!on_edge(col, row));
            }
        }
    }
    let n = f64::from(w) * f64::from(h);
    Outcome::Compared {
        differing: differing as f64 / n,
        interior: interior as f64 / n,
        mean: total / n,
    }
}

/// Why a file that differs differs, as far as its source tells.
fn reason(svg: &Path) -> &'static str {
    let text = std::fs::read_to_string(svg).unwrap_or_default();
    if text.contains("<image") {
        "image smoothing (resvg filters texels bicubically when it scales an image; quadtex keeps each texel a flat square)"
    } else if text.contains("<text") {
        "text (another font)"
    } else if text.contains("<pattern") {
        "pattern tiles (resvg rasterises a tile at a whole number of pixels, so its tiles drift)"
    } else if text.contains("opacity") || text.contains("rgba(") || text.contains("transparent") {
        "translucency (linear light)"
    } else {
        "other"
    }
}

#[test]
fn resvg_suite_packs_without_panics_and_matches() {
    let root = suite_dir();
    let mut files = Vec::new();
    svgs(&root, &mut files);
    assert!(files.len() >= 900, "suite has {} SVGs", files.len());
    // category → (files, invalid, refused, matches, differs)
    let mut table: BTreeMap<String, [usize; 5]> = BTreeMap::new();
    let mut refusals: BTreeMap<String, usize> = BTreeMap::new();
    let mut differ: BTreeMap<&'static str, Vec<String>> = BTreeMap::new();
    let mut details = String::new();
    // Files are checked on every core; the table is built in file order.
    let workers = std::thread::available_parallelism().map_or(2, |n| n.get());
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut outcomes: Vec<Option<Outcome>> = (0..files.len()).map(|_| None).collect();
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                scope.spawn(|| {
                    let mut done = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(svg) = files.get(i) else { break };
                        let started = std::time::Instant::now();
                        let outcome = std::panic::catch_unwind(|| check(svg))
                            .unwrap_or_else(|_| panic!("{}: panicked", svg.display()));
                        let seconds = started.elapsed().as_secs_f64();
                        if seconds > 2.0 {
                            eprintln!("{}: {seconds:.1} s", svg.display());
                        }
                        done.push((i, outcome));
                    }
                    done
                })
            })
            .collect();
        for h in handles {
            for (i, outcome) in h.join().unwrap() {
                outcomes[i] = Some(outcome);
            }
        }
    });
    for (svg, outcome) in files.iter().zip(outcomes) {
        let outcome = outcome.unwrap();
        let rel = svg.strip_prefix(&root).unwrap().display().to_string();
        let category = rel.split('/').next().unwrap().to_string();
        let row = table.entry(category).or_default();
        row[0] += 1;
        match &outcome {
            Outcome::Invalid(_) => row[1] += 1,
            Outcome::Refused(feature) => {
                assert!(
                    STILL_REFUSED.contains(&feature.as_str()),
                    "{rel}: refused for {feature}, which is supported"
                );
                row[2] += 1;
                *refusals.entry(feature.clone()).or_default() += 1;
            }
            Outcome::Compared { interior, .. } if *interior <= MATCH_SHARE => row[3] += 1,
            Outcome::Compared { .. } => {
                row[4] += 1;
                differ.entry(reason(svg)).or_default().push(rel.clone());
            }
        }
        let described = match &outcome {
            Outcome::Invalid(message) => format!("invalid: {message}"),
            Outcome::Refused(feature) => format!("refused: {feature}"),
            Outcome::Compared {
                differing,
                interior,
                mean,
            } => format!(
                "{:.2} % of pixels differ, {:.2} % away from edges; mean difference {mean:.2} steps",
                100.0 * differing,
                100.0 * interior
            ),
        };
        details.push_str(&format!("| `{rel}` | {described} |\n"));
    }
    let sum = |i: usize| table.values().map(|r| r[i]).sum::<usize>();
    let (all, refused, matched, differs) = (sum(0), sum(2), sum(3), sum(4));
    let mut report = String::from(
        "| category | SVGs | invalid | refused | match | differ |\n|---|---|---|---|---|---|\n",
    );
    for (c, r) in &table {
        report.push_str(&format!(
            "| {c} | {} | {} | {} | {} | {} |\n",
            r[0], r[1], r[2], r[3], r[4]
        ));
    }
    report.push_str(&format!(
        "| **all** | {all} | {} | {refused} | {matched} | {differs} |\n\nRefused: {refusals:?}\n\n",
        sum(1)
    ));
    for (why, list) in &differ {
        report.push_str(&format!("Differ, {why}: {}\n\n", list.len()));
        if *why == "other" {
            for f in list {
                report.push_str(&format!("- `{f}`\n"));
            }
            report.push('\n');
        }
    }
    // Real art packs far inside the default sweep budget, which is there
    // for pathological art (fuzzed dashes piled on a point).
    let (most, file) = MOST_SWEEP_WORK.lock().unwrap().clone();
    let file = file.unwrap_or_default();
    report.push_str(&format!(
        "Most sweep steps in one file: {most} (`{}`), against the default limit of {}\n\n",
        file.strip_prefix(&root).unwrap_or(&file).display(),
        quadtex_core::DEFAULT_MAX_SWEEP_WORK
    ));
    assert!(
        most <= quadtex_core::DEFAULT_MAX_SWEEP_WORK / 16,
        "{}: {most} sweep steps, near the default limit",
        file.display()
    );
    eprintln!("{report}");
    if let Ok(path) = std::env::var("QUADTEX_SUITE_REPORT") {
        report.push_str("| file | outcome |\n|---|---|\n");
        report.push_str(&details);
        std::fs::write(path, report).unwrap();
    }
    assert!(matched > 0);
}

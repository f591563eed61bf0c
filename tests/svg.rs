//! `quadtex pack ART.svg` then `quadtex query` against an independent
//! rasterisation of the same SVG by resvg (tiny-skia) at 4096², averaged
//! over the same fragments.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::sync::Arc;

use quadtex_core::srgb_decode_f32;
use resvg::{tiny_skia, usvg};

const SIDE: u32 = 4096;
const LEVEL: &str = "12";

/// resvg's rendering: premultiplied RGBA8, sRGB-encoded, row 0 at the top,
/// the SVG's longer side scaled to `SIDE` (quadtex's mapping).
fn rasterise(svg: &std::path::Path) -> tiny_skia::Pixmap {
    let mut fonts = usvg::fontdb::Database::new();
    fonts.load_font_data(
        include_bytes!("../crates/quadtex-io/fonts/DejaVuSans-Bold-ascii.ttf").to_vec(),
    );
    fonts.set_sans_serif_family("DejaVu Sans");
    fonts.set_serif_family("DejaVu Sans");
    let options = usvg::Options {
        font_family: "DejaVu Sans".into(),
        fontdb: Arc::new(fonts),
        ..usvg::Options::default()
    };
    let tree = usvg::Tree::from_str(&std::fs::read_to_string(svg).unwrap(), &options).unwrap();
    let size = tree.size();
    let scale = SIDE as f32 / size.width().max(size.height());
    let mut pixmap = tiny_skia::Pixmap::new(SIDE, SIDE).unwrap();
    resvg::render(
        &tree,
        tiny_skia::Transform::from_scale(scale, scale),
        &mut pixmap.as_mut(),
    );
    pixmap
}

/// Linear premultiplied colour of a resvg pixel.
fn linear(p: tiny_skia::PremultipliedColorU8) -> [f64; 4] {
    let a = f64::from(p.alpha()) / 255.0;
    if a == 0.0 {
        return [0.0; 4];
    }
    let c = |v: u8| f64::from(srgb_decode_f32((f64::from(v) / 255.0 / a).min(1.0) as f32)) * a;
    [c(p.red()), c(p.green()), c(p.blue()), a]
}

fn check_sample(name: &str) {
    let dir = common::temp_dir(&format!("svg-{name}"));
    // resvg composites translucent shapes in sRGB, quadtex in linear light (a
    // documented difference, tested exactly in the core's vector tests), so
    // the comparison uses the sample with its group opacities removed.
    let original = std::fs::read_to_string(
        std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/samples"))
            .join(format!("{name}.svg")),
    )
    .unwrap();
    let mut opaque = String::new();
    let mut rest = original.as_str();
    while let Some(i) = rest.find(" opacity=\"") {
        opaque.push_str(&rest[..i]);
        let after = &rest[i + " opacity=\"".len()..];
        rest = &after[after.find('"').unwrap() + 1..];
    }
    opaque.push_str(rest);
    let svg = dir.join(format!("{name}.svg"));
    std::fs::write(&svg, opaque).unwrap();
    let qtx = dir.join(format!("{name}.qtx"));
    let out = common::run(
        &[
            "pack",
            svg.to_str().unwrap(),
            "-o",
            qtx.to_str().unwrap(),
            "--max-level",
            LEVEL,
        ],
        "",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let pixmap = rasterise(&svg);
    let pixels = pixmap.pixels();
    let at = |x: u32, y: u32| pixels[(y * SIDE + x) as usize];
    // Fragments on the pixel grid (so the raster's average is exact for the
    // raster), from single pixels to an eighth of the texture, deterministic.
    let mut seed = 0x9e3779b97f4a7c15u64;
    let mut next = |n: u32| {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed % u64::from(n)) as u32
    };
    let mut fragments = Vec::new();
    for i in 0..120 {
        let max = [1, 8, 64, 512][i % 4];
        let (w, h) = (1 + next(max), 1 + next(max));
        let (x0, y0) = (next(SIDE - w), next(SIDE - h));
        fragments.push((x0, y0, w, h));
    }
    let lines: String = fragments
        .iter()
        .map(|&(x0, y0, w, h)| {
            let s = f64::from(SIDE);
            // Texture z runs up; raster rows run down.
            format!(
                "{} {} {} {}\n",
                f64::from(x0) / s,
                1.0 - f64::from(y0 + h) / s,
                f64::from(x0 + w) / s,
                1.0 - f64::from(y0) / s
            )
        })
        .collect();
    let out = common::run(&["query", qtx.to_str().unwrap()], &lines);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let answers: Vec<[f64; 4]> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|t| t.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3]]
        })
        .collect();
    assert_eq!(answers.len(), fragments.len());
    let (mut sum_err, mut worst_ratio) = (0.0, 0.0f64);
    for (&(x0, y0, w, h), got) in fragments.iter().zip(&answers) {
        let area = f64::from(w) * f64::from(h) / f64::from(SIDE).powi(2);
        let mut want = [0.0; 4];
        // The rasteriser's own error: it is exact on pixels away from edges;
        // an edge pixel's anti-aliased value (coverage estimated, blended in
        // sRGB) can be off by up to its whole value. So the bound is the
        // fraction of edge pixels, plus 8-bit rounding.
        let mut edge_pixels = 0u64;
        for y in y0..y0 + h {
            for x in x0..x0 + w {
                let p = at(x, y);
                let c = linear(p);
                for (o, v) in want.iter_mut().zip(c) {
                    *o += v;
                }
                let neighbours = [
                    (x.saturating_sub(1), y),
                    ((x + 1).min(SIDE - 1), y),
                    (x, y.saturating_sub(1)),
                    (x, (y + 1).min(SIDE - 1)),
                ];
                if neighbours.iter().any(|&(nx, ny)| at(nx, ny) != p) {
                    edge_pixels += 1;
                }
            }
        }
        let n = f64::from(w) * f64::from(h);
        let bound = edge_pixels as f64 / n + 2.0 / 255.0;
        for ch in 0..4 {
            let mean_got = got[ch] / area;
            let mean_want = want[ch] / n;
            let err = (mean_got - mean_want).abs();
            sum_err += err;
            worst_ratio = worst_ratio.max(err / bound);
            assert!(
                err <= bound,
                "{name}: fragment x {x0}+{w} y {y0}+{h} channel {ch}: quadtex {mean_got:.5} resvg {mean_want:.5} (bound {bound:.5}, {edge_pixels} edge pixels)"
            );
        }
    }
    eprintln!(
        "{name}: mean |quadtex − resvg| {:.5} per channel over {} fragments; worst error / bound {worst_ratio:.3}",
        sum_err / (4.0 * fragments.len() as f64),
        fragments.len()
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn threshold_matches_resvg() {
    check_sample("threshold");
}

#[test]
fn sign_with_text_matches_resvg() {
    check_sample("sign");
}

#[test]
fn siemens_star_matches_resvg() {
    check_sample("star");
}

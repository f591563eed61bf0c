//! The conflation artefact, side by side: resvg (a per-pixel antialiaser)
//! against quadtex's exact coverage, on two cases where shapes share edges.
//!
//! 1. A red disc exactly covered by a green disc of the same geometry:
//!    per-pixel coverage blends the green edge over a red edge pixel, not
//!    over the green-covered area, so a red rim shows.
//! 2. Two white half-squares meeting along a diagonal over black: each edge
//!    pixel is half covered twice, composited as 1 − (1 − ½)² = ¾, so the
//!    black background leaks through the seam.
//!
//! `cargo run --release --example conflation -- docs/conflation.png` writes
//! a picture (resvg above, quadtex below, each pixel enlarged 8×) and prints
//! the largest red left in case 1 and the darkest seam pixel in case 2.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};

use quadtex_core::srgb_decode_f32;
use quadtex_core::{Fragment, QuadTree, Rgba, VectorOptions};
use quadtex_io::{Limits, LinearImage, parse_svg, save_image};
use resvg::{tiny_skia, usvg};

/// Pixels on a side of each rendering.
const SIDE: u32 = 40;
/// Enlargement in the picture.
const ZOOM: u32 = 8;

const CASES: [&str; 2] = [
    r##"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 40 40">
        <circle cx="20" cy="20" r="15.3" fill="red"/>
        <circle cx="20" cy="20" r="15.3" fill="#00c000"/></svg>"##,
    r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 40 40">
        <rect width="40" height="40" fill="black"/>
        <path d="M5 5 L35 5 L5 35 Z" fill="white"/>
        <path d="M35 5 L35 35 L5 35 Z" fill="white"/></svg>"#,
];

/// resvg's pixels as linear premultiplied colours.
fn resvg_pixels(svg: &str) -> Vec<Rgba> {
    let tree = usvg::Tree::from_str(svg, &usvg::Options::default()).unwrap();
    let mut pixmap = tiny_skia::Pixmap::new(SIDE, SIDE).unwrap();
    resvg::render(
        &tree,
        tiny_skia::Transform::identity(),
        &mut pixmap.as_mut(),
    );
    pixmap
        .pixels()
        .iter()
        .map(|p| {
            let a = f32::from(p.alpha()) / 255.0;
            if a == 0.0 {
                return Rgba::TRANSPARENT;
            }
            let c = |v: u8| srgb_decode_f32((f32::from(v) / 255.0 / a).min(1.0)) * a;
            Rgba::new(c(p.red()), c(p.green()), c(p.blue()), a)
        })
        .collect()
}

/// quadtex's pixels: the tree's exact box integral over each pixel.
fn quadtex_pixels(svg: &str) -> Vec<Rgba> {
    let level = 12;
    let art = parse_svg(
        svg.as_bytes(),
        Path::new("case.svg"),
        &quadtex_io::SvgOptions::at_level(level).with_limits(Limits::default()),
    )
    .unwrap();
    let options = VectorOptions {
        max_level: level,
        ..VectorOptions::default()
    };
    let (tree, _) = QuadTree::from_vector(&art, &options).unwrap();
    let side = f64::from(SIDE);
    let mut out = Vec::new();
    for row in 0..SIDE {
        for col in 0..SIDE {
            let f = Fragment::new(
                f64::from(col) / side,
                1.0 - f64::from(row + 1) / side,
                f64::from(col + 1) / side,
                1.0 - f64::from(row) / side,
            )
            .unwrap();
            out.push(tree.weighted_colour(&f, level).mean_over(f.area()));
        }
    }
    out
}

fn main() {
    let output = std::env::args()
        .nth(1)
        .map_or_else(|| PathBuf::from("conflation.png"), PathBuf::from);
    let (w, h) = (SIDE * ZOOM * 2, SIDE * ZOOM * 2);
    let mut picture = vec![Rgba::opaque(1.0, 1.0, 1.0); (w * h) as usize];
    for (case, svg) in CASES.iter().enumerate() {
        for (renderer, pixels) in [resvg_pixels(svg), quadtex_pixels(svg)].iter().enumerate() {
            let (x0, y0) = (case as u32 * SIDE * ZOOM, renderer as u32 * SIDE * ZOOM);
            for (i, p) in pixels.iter().enumerate() {
                let (col, row) = (i as u32 % SIDE, i as u32 / SIDE);
                for dy in 0..ZOOM {
                    for dx in 0..ZOOM {
                        let (x, y) = (x0 + col * ZOOM + dx, y0 + row * ZOOM + dy);
                        // Over white, so transparency reads as white.
                        let over = |c: f32| c + (1.0 - p.a);
                        picture[(y * w + x) as usize] =
                            Rgba::opaque(over(p.r), over(p.g), over(p.b));
                    }
                }
            }
            let name = ["resvg", "quadtex"][renderer];
            if case == 0 {
                let red = pixels.iter().map(|p| p.r).fold(0.0f32, f32::max);
                println!("red disc under a green disc, {name}: largest red left {red:.3} (linear)");
            } else {
                // The seam: pixels on the diagonal x + y = 40 inside the square.
                let seam = (7..33)
                    .map(|col| pixels[((39 - col) * SIDE + col) as usize].r)
                    .fold(1.0f32, f32::min);
                println!(
                    "two white triangles sharing a diagonal, {name}: darkest seam pixel {seam:.3} (linear; 1 = white)"
                );
            }
        }
    }
    save_image(
        &output,
        &LinearImage {
            width: w,
            height: h,
            pixels: picture,
        },
    )
    .unwrap();
    println!("wrote {}", output.display());
}

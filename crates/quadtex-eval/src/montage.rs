//! Image crops, magnified windows, labels and grids for the comparison's
//! pictures.

use quadtex_core::Rgba;
use quadtex_io::LinearImage;

use crate::report::escape;

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
        &quadtex_io::SvgOptions::at_level(LEVEL).with_limits(limits),
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

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
    }
}

//! Writes the 4096² photograph of the packing-on-every-core benchmark
//! (docs/results.md, "Packing on every core"): `samples/photos/astronaut.png`
//! enlarged eight times (bilinear, in linear light) with film grain (a
//! deterministic per-texel noise of up to ±4 of 255 in each channel), so that
//! the lossless tree splits nearly everywhere, as a real photograph's does.
//!
//! `cargo run --release --example photo [-- OUT.png]` (default
//! `target/photo/astronaut_4096.png`), then, alternating:
//! `taskset -c 0 quadtex pack OUT.png -o one.qtx` and `quadtex pack OUT.png
//! -o two.qtx` (the files are byte-identical).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;

use quadtex_core::Rgba;
use quadtex_io::LinearImage;

/// Enlargement factor: 512² → 4096².
const SCALE: u32 = 8;

/// A noise in `[-1, 1]` for texel `(x, y)` and channel `c`.
fn grain(x: u32, y: u32, c: u32) -> f32 {
    let mut h =
        x.wrapping_mul(0x9E37_79B1) ^ y.wrapping_mul(0x85EB_CA77) ^ c.wrapping_mul(0xC2B2_AE3D);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2C1B_3C6D);
    h ^= h >> 12;
    (h % 1025) as f32 / 512.0 - 1.0
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "target/photo/astronaut_4096.png".into()),
    );
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let small =
        quadtex_io::load_linear_image(std::path::Path::new("samples/photos/astronaut.png"))?;
    let (w, h) = (small.width, small.height);
    let at = |x: i64, y: i64| {
        let (x, y) = (x.clamp(0, i64::from(w) - 1), y.clamp(0, i64::from(h) - 1));
        small.pixels[(y as usize) * (w as usize) + x as usize]
    };
    let (big_w, big_h) = (w * SCALE, h * SCALE);
    let texel = |x: u32, y: u32| {
        // The small image's texel centres at (i + ½)·SCALE.
        let fx = (f64::from(x) + 0.5) / f64::from(SCALE) - 0.5;
        let fy = (f64::from(y) + 0.5) / f64::from(SCALE) - 0.5;
        let (x0, y0) = (fx.floor(), fy.floor());
        let (tx, ty) = ((fx - x0) as f32, (fy - y0) as f32);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let [a, b, c, d] = [
            at(x0, y0),
            at(x0 + 1, y0),
            at(x0, y0 + 1),
            at(x0 + 1, y0 + 1),
        ]
        .map(|p| p.to_array());
        let mut v = [0.0f32; 4];
        for k in 0..4 {
            let top = a[k] + (b[k] - a[k]) * tx;
            let bottom = c[k] + (d[k] - c[k]) * tx;
            v[k] = top + (bottom - top) * ty;
        }
        let noise = |k: u32| 4.0 / 255.0 * grain(x, y, k);
        Rgba::opaque(
            (v[0] + noise(0)).clamp(0.0, 1.0),
            (v[1] + noise(1)).clamp(0.0, 1.0),
            (v[2] + noise(2)).clamp(0.0, 1.0),
        )
    };
    let image = LinearImage::from_fn(big_w, big_h, texel);
    quadtex_io::save_image(&out, &image)?;
    println!("{}", out.display());
    Ok(())
}

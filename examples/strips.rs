//! Writes PNGs of any shape for the packing-cost benchmark of non-square
//! textures: a 1×20000 column, a 16384×1024 runway strip and the 4096²
//! square of the same texel count, each a runway-like pattern over
//! texel-level noise (so the lossless tree splits to the texels, the worst
//! case for its size).
//!
//! `cargo run --release --example strips [-- DIR]` (default
//! `target/strips`), then `quadtex pack DIR/W_H.png -o OUT.qtx` under
//! `/usr/bin/time -v` for time and peak memory.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;

use quadtex_core::Rgba;
use quadtex_io::LinearImage;

/// Texel `(x, y)` (`y` down): asphalt noise with dashed white bars.
fn texel(x: u32, y: u32) -> Rgba {
    let mut h = x.wrapping_mul(0x9E37_79B1) ^ y.wrapping_mul(0x85EB_CA77);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2C1B_3C6D);
    h ^= h >> 12;
    let grain = (h % 32) as f32 / 255.0;
    if (x / 64) % 3 == 0 && (y / 16) % 4 == 1 {
        Rgba::opaque(0.85 + grain, 0.85 + grain, 0.8 + grain)
    } else {
        Rgba::opaque(0.08 + grain, 0.08 + grain, 0.09 + grain)
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "target/strips".into()),
    );
    std::fs::create_dir_all(&dir)?;
    for (w, h) in [(1u32, 20000u32), (20000, 1), (16384, 1024), (4096, 4096)] {
        let image = LinearImage::from_fn(w, h, texel);
        let path = dir.join(format!("{w}_{h}.png"));
        quadtex_io::save_image(&path, &image)?;
        println!("{}", path.display());
    }
    Ok(())
}

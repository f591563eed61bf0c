//! Writes a tiled texture for `quadtex pack-tiles`: `TILES × TILES` PNG
//! tiles of `SIDE × SIDE` texels named `ROW_COL.png`, an aerial-map-like
//! mosaic at one texel a metre: fields of flat colour 2 km across, roads
//! between them and a runway crossing tile borders.
//!
//! `cargo run --release --example tiles [-- DIR [TILES [SIDE]]]` (default
//! `target/tiles`, 16 tiles of 4096², a 65536² texture), then
//! `quadtex pack-tiles target/tiles -o tiles.qtx`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;
use std::time::Instant;

use quadtex_core::Rgba;
use quadtex_io::LinearImage;

/// The colour of texel `(x, y)` of the whole mosaic (`y` down).
fn texel(x: u32, y: u32) -> Rgba {
    let hash = |a: u32, b: u32| {
        let mut h = a.wrapping_mul(0x9E37_79B1) ^ b.wrapping_mul(0x85EB_CA77);
        h ^= h >> 15;
        h = h.wrapping_mul(0x2C1B_3C6D);
        h ^ (h >> 12)
    };
    // A runway 3 km by 60 m across the middle, its centre line dashed.
    let (rx, ry) = (x.wrapping_sub(31_000), y.wrapping_sub(32_738));
    if rx < 3000 && ry < 60 {
        let centre = (29..31).contains(&ry) && (rx / 30) % 2 == 0;
        return if centre {
            Rgba::opaque(0.9, 0.9, 0.9)
        } else {
            Rgba::opaque(0.05, 0.05, 0.06)
        };
    }
    // Roads 12 m wide every 2048 m.
    if x % 2048 < 12 || y % 2048 < 12 {
        return Rgba::opaque(0.3, 0.28, 0.25);
    }
    let crops = [
        Rgba::opaque(0.16, 0.26, 0.07),
        Rgba::opaque(0.30, 0.32, 0.12),
        Rgba::opaque(0.45, 0.38, 0.20),
        Rgba::opaque(0.10, 0.18, 0.06),
        Rgba::opaque(0.38, 0.30, 0.22),
    ];
    crops[(hash(x / 2048, y / 2048) % crops.len() as u32) as usize]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = PathBuf::from(args.first().map_or("target/tiles", String::as_str));
    let tiles: u32 = args.get(1).map_or(Ok(16), |a| a.parse())?;
    let side: u32 = args.get(2).map_or(Ok(4096), |a| a.parse())?;
    std::fs::create_dir_all(&dir)?;
    let started = Instant::now();
    let next = std::sync::atomic::AtomicU32::new(0);
    let workers = std::thread::available_parallelism().map_or(2, |n| n.get());
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| {
                loop {
                    let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    if k >= tiles * tiles {
                        break;
                    }
                    let (row, col) = (k / tiles, k % tiles);
                    let pixels = (0..side * side)
                        .map(|i| texel(col * side + i % side, row * side + i / side))
                        .collect();
                    let image = LinearImage {
                        width: side,
                        height: side,
                        pixels,
                    };
                    quadtex_io::save_image(&dir.join(format!("{row}_{col}.png")), &image).unwrap();
                }
            });
        }
    });
    println!(
        "wrote {}x{} tiles of {side}x{side} ({}x{} texels) to {} in {:.1} s",
        tiles,
        tiles,
        u64::from(tiles) * u64::from(side),
        u64::from(tiles) * u64::from(side),
        dir.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

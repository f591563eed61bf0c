//! A tile folder packed on several threads: tiles packed apart
//! ([`pack_tile`]) a few ahead of the splice, which takes them in the
//! builder's order ([`splice_tiles`]); the tree is the one a single thread
//! builds, byte for byte.

use std::collections::HashMap;
use std::sync::{Condvar, Mutex};

use quadtex_core::{BuildReport, PackedTile, QuadTree};

use crate::Error;
use crate::limits::Limits;
use crate::tiles::{TileFolder, pack_tile, splice_tiles};

/// Tiles packed ahead of the splice, at most, per thread: enough to keep
/// every thread busy while the splice waits for the next one in order,
/// few enough that packed tiles waiting stay a small part of memory.
const AHEAD_PER_THREAD: usize = 4;

/// What the packing threads and the splice share.
struct Shared {
    /// Index (in builder order) of the next tile a thread takes.
    next: usize,
    /// Index of the tile the splice waits for; threads stay within
    /// `ahead` tiles of it.
    wanted: usize,
    done: HashMap<(u32, u32), Result<PackedTile, Error>>,
    /// Set when the splice stops (finished or failed): threads quit.
    stop: bool,
}

/// [`crate::pack_tiles`] on `threads` threads (at least one): tiles packed
/// apart a few ahead of the splice, which takes them in order. The tree is
/// the one a single thread builds, byte for byte. Memory: a tile's texels
/// per thread, and up to `AHEAD_PER_THREAD` packed tiles per thread.
pub fn pack_tiles_on_threads(
    folder: &TileFolder,
    tolerance: f64,
    limits: &Limits,
    threads: usize,
) -> Result<(QuadTree, BuildReport), Error> {
    let threads = threads.max(1);
    let order = folder.mosaic().tiles_in_order();
    let ahead = threads * AHEAD_PER_THREAD;
    let shared = Mutex::new(Shared {
        next: 0,
        wanted: 0,
        done: HashMap::new(),
        stop: false,
    });
    let changed = Condvar::new();
    let lock = || {
        shared
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    };
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                loop {
                    let tile = {
                        let mut s = lock();
                        while !s.stop && s.next < order.len() && s.next >= s.wanted + ahead {
                            s = changed
                                .wait(s)
                                .unwrap_or_else(std::sync::PoisonError::into_inner);
                        }
                        if s.stop || s.next >= order.len() {
                            return;
                        }
                        s.next += 1;
                        order[s.next - 1]
                    };
                    let packed = pack_tile(folder, tile, tolerance, limits, None);
                    lock().done.insert(tile, packed);
                    changed.notify_all();
                }
            });
        }
        let mut position: HashMap<(u32, u32), usize> = HashMap::new();
        for (i, &t) in order.iter().enumerate() {
            position.insert(t, i);
        }
        let mut load = |row: u32, col: u32, format: Option<quadtex_core::BlockFormat>| {
            if format.is_some() {
                // Asked again in a wider format: packed here, at once.
                return pack_tile(folder, (row, col), tolerance, limits, format);
            }
            let mut s = lock();
            s.wanted = position.get(&(row, col)).copied().unwrap_or(0);
            changed.notify_all();
            loop {
                if let Some(packed) = s.done.remove(&(row, col)) {
                    return packed;
                }
                s = changed
                    .wait(s)
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
            }
        };
        let result = splice_tiles(folder, tolerance, limits, &mut load);
        lock().stop = true;
        changed.notify_all();
        result
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A folder of 8×8 PNG tiles whose formats widen along the builder's
    /// order (grey, then opaque colour, then translucent), packed on 1, 2
    /// and 3 threads: the tree a single thread builds, byte for byte.
    #[test]
    fn threads_pack_the_tree_one_thread_packs() {
        let dir =
            std::env::temp_dir().join(format!("quadtex-tiles-threads-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let tiles = 4u32;
        for row in 0..tiles {
            for col in 0..tiles {
                let pixels = (0..64u32)
                    .map(|i| {
                        let h = ((row * 8 + i / 8).wrapping_mul(40_503)
                            ^ (col * 8 + i % 8).wrapping_mul(2_654_435_761))
                            % 255;
                        let v = h as f32 / 255.0;
                        match (row < 2, col < 2) {
                            (false, false) => quadtex_core::Rgba::new(v * 0.5, 0.1, v * 0.2, 0.5),
                            (true, false) => quadtex_core::Rgba::opaque(v, v * 0.5, 0.2),
                            _ => quadtex_core::Rgba::opaque(v, v, v),
                        }
                    })
                    .collect();
                let image = crate::LinearImage {
                    width: 8,
                    height: 8,
                    pixels,
                };
                crate::save_image(&dir.join(format!("{row}_{col}.png")), &image).unwrap();
            }
        }
        let limits = Limits::default();
        let (serial, report, folder) = crate::pack_tiles(&dir, 0.0, &limits).unwrap();
        for threads in [1, 2, 3] {
            let (tree, r) = pack_tiles_on_threads(&folder, 0.0, &limits, threads).unwrap();
            assert_eq!(tree, serial, "{threads} threads");
            assert_eq!(r, report);
        }
        assert!(serial.texel_blocks().is_some());
        // A tile that fails stops the build with its own error.
        std::fs::write(dir.join("1_2.png"), b"not a png").unwrap();
        let e = pack_tiles_on_threads(&folder, 0.0, &limits, 2).unwrap_err();
        assert!(e.to_string().contains("1_2.png"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

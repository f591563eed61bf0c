//! An 8-bit PNG packed while it decodes ([`pack_png_on_threads`]): its
//! rows are read one after another (a PNG is one zlib stream, so decoding
//! stays on one thread), and each tile of the texture's [`Mosaic`] is
//! packed on another thread as soon as its last row is in; the packed
//! tiles are then spliced in the builder's order. The tree is the one
//! [`QuadTree::from_texels`] builds from the whole image, byte for byte
//! ([`QuadTree::from_packed_tiles`]).

use std::collections::{HashMap, VecDeque};
use std::io::{BufReader, Read};
use std::path::Path;
use std::sync::{Condvar, Mutex, PoisonError};

use quadtex_core::{BuildOptions, BuildReport, Mosaic, PackedTile, QuadTree, TexelGrid};

use crate::Error;
use crate::limits::Limits;

/// Texels on a tile's side: small enough that the first tiles are ready
/// early in the decode, large enough that the splice stays a small part
/// of the work.
const TILE_SIDE: u32 = 256;

/// A PNG packed while it decodes: the tree, the packer's report and the
/// image's width and height.
pub type PackedPng = (QuadTree, BuildReport, (u32, u32));

/// A tile of the mosaic, `(row, col)`, and its rectangle of texels from
/// the image's top-left corner, `(x0, y0, w, h)`.
type TileRect = ((u32, u32), (u32, u32, u32, u32));

/// What the decoding thread and the packing threads share.
#[derive(Default)]
struct Shared {
    /// Tiles whose rows are all decoded, not yet taken.
    ready: VecDeque<((u32, u32), TexelGrid)>,
    /// Set once every row is decoded (or decoding stopped).
    finished: bool,
    /// Each tile packed, with its texels (to pack it again in a wider
    /// format if the splice asks for one).
    packed: HashMap<(u32, u32), (Result<PackedTile, quadtex_core::Error>, TexelGrid)>,
}

/// Packs the 8-bit PNG at `path` as [`QuadTree::from_texels`] packs what
/// [`crate::load_texels`] reads from it, with `threads` threads (at least
/// one) packing tiles while this one decodes: the tree and report are
/// byte for byte the same. `Ok(None)` when this path does not apply and
/// the caller reads the image whole: not a PNG, an interlaced or 16-bit
/// one, a `max_level`, an image of at most half a tile or mostly the
/// mosaic's pad (long and thin), a memory budget the texels held leave
/// too little of, or any error decoding or packing (the whole read then
/// reports it as it always does).
pub fn pack_png_on_threads(
    path: &Path,
    options: &BuildOptions,
    limits: &Limits,
    threads: usize,
) -> Result<Option<PackedPng>, Error> {
    if options.max_level.is_some() {
        return Ok(None);
    }
    let io = |e: std::io::Error| Error::Io {
        path: path.to_path_buf(),
        source: e,
    };
    limits.check_file_size(path, std::fs::metadata(path).map_err(io)?.len())?;
    let mut file = BufReader::new(std::fs::File::open(path).map_err(io)?);
    let mut signature = [0u8; 8];
    if file.read_exact(&mut signature).is_err() || signature != *b"\x89PNG\r\n\x1a\n" {
        return Ok(None);
    }
    let file = BufReader::new(std::fs::File::open(path).map_err(io)?);
    let bytes = usize::try_from(limits.max_memory).unwrap_or(usize::MAX);
    let mut decoder = png::Decoder::new_with_limits(file, png::Limits { bytes });
    // As `image` decodes PNGs: palettes, low bit depths and tRNS expanded.
    decoder.set_transformations(png::Transformations::EXPAND);
    let Ok(mut reader) = decoder.read_info() else {
        return Ok(None);
    };
    let (width, height) = (reader.info().width, reader.info().height);
    let (colour, depth) = reader.output_color_type();
    let channels = match colour {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => return Ok(None),
    };
    if reader.info().interlaced || depth != png::BitDepth::Eight {
        return Ok(None);
    }
    limits.check_dimensions(path, width, height)?;
    // As the whole read counts it: the decoded rows and 8 bytes a texel.
    let texels = u64::from(width) * u64::from(height);
    limits.check_memory(
        path,
        || format!("decoding {width}x{height} texels"),
        (channels + 8) * texels,
        "use a smaller image, or raise --memory-limit",
    )?;
    let Ok(mosaic) = Mosaic::of_texture(width, height, TILE_SIDE) else {
        return Ok(None);
    };
    // The tiles by the last row they need, from the top.
    let mut tiles: Vec<TileRect> = (0..mosaic.tiles())
        .flat_map(|row| (0..mosaic.tiles()).map(move |col| (row, col)))
        .filter_map(|tile| mosaic.tile_rect(tile.0, tile.1).map(|rect| (tile, rect)))
        .collect();
    tiles.sort_by_key(|&(_, (_, y0, _, h))| y0 + h);
    // A long thin image leaves nearly all of the mosaic's tiles in the
    // pad, which the splice still walks: read it whole.
    let grid_tiles = u64::from(mosaic.tiles()) * u64::from(mosaic.tiles());
    if 16 * (tiles.len() as u64) < grid_tiles {
        return Ok(None);
    }
    // The texels stay held while the tiles pack (the decoded rows and each
    // tile's copy, 8 bytes a texel, as the whole read's decoding counts
    // them): the tiles' own budget is what is left of the caller's.
    let held = 8 * texels;
    let options = &match options.max_bytes.map(|b| b.checked_sub(held)) {
        Some(None) => return Ok(None),
        left => BuildOptions {
            max_bytes: left.flatten(),
            ..*options
        },
    };
    let shared = Mutex::new(Shared::default());
    let changed = Condvar::new();
    let lock = || shared.lock().unwrap_or_else(PoisonError::into_inner);
    let pack = |tile: (u32, u32), grid: TexelGrid| {
        let packed = QuadTree::pack_tile(&mosaic, tile, &grid, options, None);
        lock().packed.insert(tile, (packed, grid));
    };
    // Takes ready tiles until none is left and decoding has finished.
    let work = || {
        loop {
            let job = {
                let mut s = lock();
                loop {
                    if let Some(job) = s.ready.pop_front() {
                        break Some(job);
                    }
                    if s.finished {
                        break None;
                    }
                    s = changed.wait(s).unwrap_or_else(PoisonError::into_inner);
                }
            };
            match job {
                Some((tile, grid)) => pack(tile, grid),
                None => return,
            }
        }
    };
    let helpers = threads.max(1) - 1;
    let decoded = std::thread::scope(|scope| {
        for _ in 0..helpers {
            scope.spawn(work);
        }
        let decoded = decode_rows(
            &mut reader,
            (width, height),
            channels,
            &tiles,
            |tile, grid| {
                if helpers == 0 {
                    pack(tile, grid);
                } else {
                    lock().ready.push_back((tile, grid));
                    changed.notify_one();
                }
            },
        );
        lock().finished = true;
        changed.notify_all();
        work();
        decoded
    });
    if decoded.is_err() {
        return Ok(None);
    }
    let packed = std::mem::take(&mut lock().packed);
    // The splice asks again for a tile packed narrower than the tiles
    // before it make the mosaic's format: packed again from its texels.
    let spliced = QuadTree::from_packed_tiles(&mosaic, options, &mut |row, col, format| {
        let Some((tile, grid)) = packed.get(&(row, col)) else {
            return Err(quadtex_core::Error::BadDimensions {
                width: u64::from(col),
                height: u64::from(row),
                reason: "tile never packed",
            });
        };
        let tile = tile.clone()?;
        match format {
            Some(f) if tile.block_format() != Some(f) => {
                QuadTree::pack_tile(&mosaic, (row, col), grid, options, Some(f))
            }
            _ => Ok(tile),
        }
    });
    // Any refusal (a tile's budget, say) is left to the whole read, which
    // reports it as it always has.
    if let Err(e) = &spliced {
        eprintln!("SPLICE {e}");
    }
    Ok(spliced
        .ok()
        .map(|(tree, report)| (tree, report, (width, height))))
}

/// Decodes the image's rows as RGBA8 (grey spread to RGB, opaque where
/// there is no alpha), handing each of `tiles` (`(row, col)` and its
/// rectangle from the top, in the order of their last rows) to `ready` as
/// soon as its rows are in.
fn decode_rows<R: std::io::BufRead + std::io::Seek>(
    reader: &mut png::Reader<R>,
    (width, height): (u32, u32),
    channels: u64,
    tiles: &[TileRect],
    mut ready: impl FnMut((u32, u32), TexelGrid),
) -> Result<(), png::DecodingError> {
    let w = width as usize;
    let mut rows: Vec<[u8; 4]> = Vec::new();
    rows.try_reserve_exact(w * height as usize)
        .map_err(|_| png::DecodingError::LimitsExceeded)?;
    let mut next = 0;
    for y in 0..height {
        let Some(row) = reader.next_row()? else {
            return Err(png::DecodingError::LimitsExceeded);
        };
        let data = row.data();
        match channels {
            1 => rows.extend(data[..w].iter().map(|&l| [l, l, l, 255])),
            2 => rows.extend(
                data[..2 * w]
                    .chunks_exact(2)
                    .map(|p| [p[0], p[0], p[0], p[1]]),
            ),
            3 => rows.extend(
                data[..3 * w]
                    .chunks_exact(3)
                    .map(|p| [p[0], p[1], p[2], 255]),
            ),
            _ => rows.extend(
                data[..4 * w]
                    .chunks_exact(4)
                    .map(|p| [p[0], p[1], p[2], p[3]]),
            ),
        }
        while let Some(&(tile, (x0, y0, tw, th))) = tiles.get(next) {
            if y0 + th > y + 1 {
                break;
            }
            let mut texels = Vec::with_capacity(tw as usize * th as usize);
            for ty in y0..y0 + th {
                let start = ty as usize * w + x0 as usize;
                texels.extend_from_slice(&rows[start..start + tw as usize]);
            }
            let grid = TexelGrid::from_srgb8(tw, th, texels)
                .map_err(|_| png::DecodingError::LimitsExceeded)?;
            ready(tile, grid);
            next += 1;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `.qtx` file's bytes.
    fn qtx(tree: &QuadTree, size: (u32, u32)) -> Vec<u8> {
        let mut bytes = Vec::new();
        crate::write_qtx_to(&mut bytes, Path::new("memory"), tree, Some(size)).unwrap();
        bytes
    }

    /// Writes a `width × height` PNG of `colour` at 8 bits (a palette at
    /// 2 bits, with a tRNS chunk, when `Indexed`; grey at 1 bit when
    /// `one_bit`): noise in places, flat elsewhere, grey in some tiles and
    /// colour in others, so that tiles pack in different formats.
    fn write_png(path: &Path, (width, height): (u32, u32), colour: png::ColorType, one_bit: bool) {
        let channels = match colour {
            png::ColorType::Grayscale | png::ColorType::Indexed => 1,
            png::ColorType::GrayscaleAlpha => 2,
            png::ColorType::Rgb => 3,
            png::ColorType::Rgba => 4,
        };
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        let mut noise = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 56) as u8
        };
        let mut data = Vec::new();
        for y in 0..height {
            for x in 0..width {
                let flat = (x / 97 + y / 61) % 3 == 0;
                let grey_tile = x < 256 && y > height / 2;
                let v = if flat { 200 } else { noise() };
                let px: Vec<u8> = match (colour, one_bit) {
                    (png::ColorType::Indexed, _) => vec![v >> 6],
                    (png::ColorType::Grayscale, true) => vec![v >> 7],
                    _ => (0..channels)
                        .map(|c| match c {
                            3 if flat => 255,
                            1 if channels == 2 => v | 0x80,
                            1 | 2 if !grey_tile && !flat => noise(),
                            _ => v,
                        })
                        .collect(),
                };
                data.extend(px);
            }
        }
        if one_bit {
            // Rows of bits, each padded to a byte.
            let mut packed = Vec::new();
            for row in data.chunks(width as usize) {
                for bits in row.chunks(8) {
                    packed.push(
                        bits.iter()
                            .enumerate()
                            .fold(0, |a, (i, &b)| a | (b << (7 - i))),
                    );
                }
            }
            data = packed;
        }
        if colour == png::ColorType::Indexed {
            // Two bits a texel, four to a byte.
            let mut packed = Vec::new();
            for row in data.chunks(width as usize) {
                for four in row.chunks(4) {
                    packed.push(
                        four.iter()
                            .enumerate()
                            .fold(0, |a, (i, &b)| a | (b << (6 - 2 * i))),
                    );
                }
            }
            data = packed;
        }
        let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
        let mut encoder = png::Encoder::new(file, width, height);
        encoder.set_color(colour);
        let depth = match (colour, one_bit) {
            (png::ColorType::Indexed, _) => png::BitDepth::Two,
            (_, true) => png::BitDepth::One,
            _ => png::BitDepth::Eight,
        };
        encoder.set_depth(depth);
        if colour == png::ColorType::Indexed {
            encoder.set_palette(vec![10, 20, 30, 200, 100, 50, 0, 255, 0, 255, 255, 255]);
            encoder.set_trns(vec![255, 128, 0, 255]);
        }
        encoder
            .write_header()
            .unwrap()
            .write_image_data(&data)
            .unwrap();
    }

    /// Every 8-bit kind of PNG `image` reads (grey, grey and alpha, RGB,
    /// RGBA, a palette with transparency, 1-bit grey), on 1 and 3
    /// threads: byte for byte the tree the whole read and pack make.
    #[test]
    fn packs_as_the_whole_image_packs() {
        let dir = std::env::temp_dir().join(format!("quadtex-png-threads-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let limits = Limits::default();
        let options = BuildOptions::default();
        let kinds = [
            (png::ColorType::Grayscale, false),
            (png::ColorType::GrayscaleAlpha, false),
            (png::ColorType::Rgb, false),
            (png::ColorType::Rgba, false),
            (png::ColorType::Indexed, false),
            (png::ColorType::Grayscale, true),
        ];
        for (i, &(colour, one_bit)) in kinds.iter().enumerate() {
            for size in [(600, 520), (300, 1100)] {
                let path = dir.join(format!("kind{i}-{}x{}.png", size.0, size.1));
                write_png(&path, size, colour, one_bit);
                let grid = crate::load_texels(&path, &limits).unwrap();
                let (whole, whole_report) = QuadTree::from_texels(&grid, &options).unwrap();
                for threads in [1, 3] {
                    let (tree, report, got) =
                        pack_png_on_threads(&path, &options, &limits, threads)
                            .unwrap()
                            .unwrap_or_else(|| panic!("{colour:?} {one_bit}: not streamed"));
                    assert_eq!(got, size);
                    assert_eq!(report, whole_report, "{colour:?} {one_bit} {size:?}");
                    assert!(
                        qtx(&tree, size) == qtx(&whole, size),
                        "{colour:?} {one_bit} {size:?} on {threads} threads: another tree"
                    );
                }
            }
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    /// Where it does not apply, it says so and the whole read takes over:
    /// 16 bits, a level asked for, small, long and thin, a memory budget
    /// the held texels leave too little of, not a PNG, a truncated PNG
    /// (whose error the whole read reports). (Interlaced PNGs are left to
    /// it too; the `png` crate writes none to test with.)
    #[test]
    fn leaves_what_it_does_not_stream_to_the_whole_read() {
        let dir = std::env::temp_dir().join(format!("quadtex-png-whole-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let limits = Limits::default();
        let options = BuildOptions::default();
        let write = |name: &str, size: (u32, u32), depth: png::BitDepth| {
            let path = dir.join(name);
            let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
            let mut encoder = png::Encoder::new(file, size.0, size.1);
            encoder.set_color(png::ColorType::Rgb);
            encoder.set_depth(depth);
            let bytes = if depth == png::BitDepth::Sixteen {
                6
            } else {
                3
            };
            let data = vec![77u8; (size.0 * size.1) as usize * bytes];
            encoder
                .write_header()
                .unwrap()
                .write_image_data(&data)
                .unwrap();
            path
        };
        let streamed = |path: &Path, options: &BuildOptions| {
            pack_png_on_threads(path, options, &limits, 2)
                .unwrap()
                .is_some()
        };
        let plain = write("plain.png", (600, 400), png::BitDepth::Eight);
        assert!(streamed(&plain, &options));
        let level = BuildOptions {
            max_level: Some(8),
            ..BuildOptions::default()
        };
        assert!(!streamed(&plain, &level));
        assert!(!streamed(
            &write("deep.png", (600, 400), png::BitDepth::Sixteen),
            &options
        ));
        assert!(!streamed(
            &write("small.png", (100, 90), png::BitDepth::Eight),
            &options
        ));
        assert!(!streamed(
            &write("tall.png", (8, 5000), png::BitDepth::Eight),
            &options
        ));
        let tight = BuildOptions {
            max_bytes: Some(1 << 20),
            ..BuildOptions::default()
        };
        assert!(!streamed(&plain, &tight));
        let text = dir.join("text.png");
        std::fs::write(&text, b"not a png at all").unwrap();
        assert!(!streamed(&text, &options));
        let bytes = std::fs::read(&plain).unwrap();
        let cut = dir.join("cut.png");
        std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
        assert!(!streamed(&cut, &options));
        assert!(crate::load_texels(&cut, &limits).is_err());
        std::fs::remove_dir_all(&dir).ok();
    }
}

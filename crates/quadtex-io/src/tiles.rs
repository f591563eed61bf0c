//! Tiled rasters packed into one tree, one tile in memory at a time
//! ([`QuadTree::from_tiles`]): a folder of tiles named `ROW_COL.png` (or
//! `.jpg`, `.jpeg`, `.tif`, `.tiff`; row 0 at the top, both counted from 0
//! in decimal), or a tiled TIFF (BigTIFF and Cloud-Optimized GeoTIFF
//! included), whose own tiles are the mosaic's.
//!
//! A folder's tiles must form a complete square grid whose side is a power
//! of two (1, 2, 4, … tiles), every tile the same square size, a power of
//! two texels. Other files in the folder are ignored. A missing tile, a
//! duplicate (`3_5.png` and `3_5.jpg`), a tile of another size or format
//! that does not decode is an error naming it, before anything is written.
//!
//! A tiled TIFF may be any size and its tile grid any shape (partial tiles
//! on its right and bottom edges, as Cloud-Optimized GeoTIFFs have); its
//! tiles must be squares of a power of two texels (256 and 512 are usual)
//! and the image larger than half a tile. The tree is cut into tiles of
//! that size lined up with the image's bottom edge ([`Mosaic`]); where the
//! image's height is not a whole number of tiles, a tree tile is read from
//! the two TIFF tiles it straddles, one after the other: memory holds a
//! tree tile's texels and one decoded TIFF tile.
//! Other TIFFs are refused, pointing to `quadtex pack`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use quadtex_core::{
    BlockFormat, BuildOptions, BuildReport, Mosaic, PackedTile, QuadTree, TexelGrid,
};

use crate::Error;
use crate::limits::Limits;
use crate::tiff_io::{GeoReference, TiffTiles};

/// The tiles of a mosaic, checked for completeness (see the module docs):
/// a folder of `ROW_COL` tiles or a tiled TIFF.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TileSource {
    /// The folder, or the TIFF file.
    path: PathBuf,
    /// How the texture is cut into tiles.
    mosaic: Mosaic,
    kind: Kind,
}

/// The former name of [`TileSource`], from when tiles came from folders only.
pub type TileFolder = TileSource;

#[derive(Debug, Clone, PartialEq, Eq)]
enum Kind {
    /// Row-major file names.
    Folder(Vec<PathBuf>),
    Tiff(Box<TiffTiles>),
}

impl TileSource {
    /// The tiles at `path`: a folder's `ROW_COL` tiles ([`TileSource::scan`])
    /// or a tiled TIFF's ([`TileSource::tiff`]).
    pub fn open(path: &Path, limits: &Limits) -> Result<TileSource, Error> {
        let meta = std::fs::metadata(path).map_err(crate::error::io(path))?;
        if meta.is_dir() {
            return Self::scan(path, limits);
        }
        if !crate::tiff_io::file_is_tiff(path) {
            return Err(Error::Tiles {
                path: path.to_path_buf(),
                message: "neither a folder of ROW_COL tiles nor a tiled TIFF; `quadtex pack` packs a single image"
                    .into(),
            });
        }
        Self::tiff(path, limits)
    }

    /// The tiles of a tiled TIFF (or BigTIFF) file: its first image, read a
    /// tile or two at a time. Refused (naming the file and why) unless its
    /// tiles are squares of a power of two texels and the image is larger
    /// than half a tile (see the module docs).
    pub fn tiff(path: &Path, limits: &Limits) -> Result<TileSource, Error> {
        let tiles = TiffTiles::open(path, limits)?;
        Ok(TileSource {
            path: path.to_path_buf(),
            mosaic: tiles.mosaic(),
            kind: Kind::Tiff(Box::new(tiles)),
        })
    }

    /// The folder or file the tiles come from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether the tiles are a tiled TIFF's (else a folder's).
    pub fn is_tiff(&self) -> bool {
        matches!(self.kind, Kind::Tiff(_))
    }

    /// A GeoTIFF's georeferencing (see [`GeoReference`]); `None` for a
    /// folder and for a TIFF without it.
    pub fn georeference(&self) -> Option<&GeoReference> {
        match &self.kind {
            Kind::Tiff(t) => t.georeference(),
            Kind::Folder(_) => None,
        }
    }
}

impl TileSource {
    /// Scans `dir` for `ROW_COL` tiles and reads the first one's size.
    pub fn scan(dir: &Path, limits: &Limits) -> Result<TileSource, Error> {
        let io = |source| Error::Io {
            path: dir.to_path_buf(),
            source,
        };
        let bad = |path: &Path, message: String| Error::Tiles {
            path: path.to_path_buf(),
            message,
        };
        let mut found: BTreeMap<(u32, u32), PathBuf> = BTreeMap::new();
        for entry in std::fs::read_dir(dir).map_err(io)? {
            let path = entry.map_err(io)?.path();
            let (Some(stem), Some(ext)) = (
                path.file_stem().and_then(|s| s.to_str()),
                path.extension().and_then(|s| s.to_str()),
            ) else {
                continue;
            };
            if !matches!(
                ext.to_ascii_lowercase().as_str(),
                "png" | "jpg" | "jpeg" | "tif" | "tiff"
            ) {
                continue;
            }
            let Some((row, col)) = stem.split_once('_') else {
                continue;
            };
            let (Ok(row), Ok(col)) = (row.parse::<u32>(), col.parse::<u32>()) else {
                continue;
            };
            if let Some(other) = found.insert((row, col), path.clone()) {
                return Err(bad(
                    &path,
                    format!("tile {row}_{col} is also {}", other.display()),
                ));
            }
        }
        let Some(&(last_row, _)) = found.keys().next_back() else {
            return Err(bad(
                dir,
                "no tiles named ROW_COL.png (or .jpg, .tif) found".into(),
            ));
        };
        let last_col = found.keys().map(|k| k.1).max().unwrap_or(0);
        let tiles = last_row.max(last_col) + 1;
        if !tiles.is_power_of_two() {
            return Err(bad(
                dir,
                format!("{tiles} tiles a side: the grid must be 1, 2, 4, 8, … tiles a side"),
            ));
        }
        let mut files = Vec::with_capacity((tiles * tiles) as usize);
        for row in 0..tiles {
            for col in 0..tiles {
                match found.remove(&(row, col)) {
                    Some(f) => files.push(f),
                    None => {
                        return Err(bad(
                            &dir.join(format!("{row}_{col}.png")),
                            format!("missing: a {tiles}x{tiles} grid needs every tile"),
                        ));
                    }
                }
            }
        }
        let first = &files[0];
        let (w, h) = crate::image_io::image_dimensions(first)?;
        if w != h || !w.is_power_of_two() {
            return Err(bad(
                first,
                format!("{w}x{h} texels: tiles must be squares of a power of two"),
            ));
        }
        limits.check_dimensions(first, w, h)?;
        let mosaic = Mosaic::square(tiles, w).map_err(|e| bad(dir, e.to_string()))?;
        Ok(TileSource {
            path: dir.to_path_buf(),
            mosaic,
            kind: Kind::Folder(files),
        })
    }

    /// How the texture is cut into tiles.
    pub fn mosaic(&self) -> Mosaic {
        self.mosaic
    }

    /// Tiles on the tree square's side.
    pub fn tiles(&self) -> u32 {
        self.mosaic.tiles()
    }

    /// Texels on a tile's side.
    pub fn side(&self) -> u32 {
        self.mosaic.side()
    }

    /// The texture's `(width, height)` in texels.
    pub fn extent(&self) -> (u32, u32) {
        (self.mosaic.width(), self.mosaic.height())
    }
}

/// Packs the tiles at `path`, a folder of tiles or a tiled TIFF (see the
/// module docs and [`TileSource::open`]), into one tree, to `tolerance`
/// (0: lossless), holding one tile's texels at a time.
pub fn pack_tiles(
    path: &Path,
    tolerance: f64,
    limits: &Limits,
) -> Result<(QuadTree, BuildReport, TileSource), Error> {
    let folder = TileSource::open(path, limits)?;
    let options = folder.options(tolerance, limits);
    // The loader's own error (naming the tile) is kept aside: the core sees a placeholder.
    let mut failure: Option<Error> = None;
    let mut load = |row: u32, col: u32| {
        folder
            .load_tile(row, col, limits)
            .map_err(|e| set_aside(e, &mut failure))
    };
    let result = QuadTree::from_tiles(&folder.mosaic, &options, &mut load);
    match (result, failure) {
        (Ok((tree, report)), _) => Ok((tree, report, folder)),
        (Err(_), Some(e)) => Err(e),
        (Err(e), None) => Err(crate::error::core(&folder.path)(e)),
    }
}

/// Keeps a loader's own error (naming the tile) aside and gives the core a
/// placeholder that stops the build.
fn set_aside(e: Error, failure: &mut Option<Error>) -> quadtex_core::Error {
    *failure = Some(e);
    quadtex_core::Error::BadDimensions {
        width: 0,
        height: 0,
        reason: "a tile failed to load",
    }
}

/// Packs tile `(row, col)` of the mosaic ([`Mosaic`]: row 0 at the top,
/// tiles wholly in the pad refused) on its own, as
/// [`pack_tiles`] would, for [`splice_tiles`] to splice (on another
/// process or machine: [`PackedTile::to_bytes`]). `format`, when given, is
/// the texel-block format to write (the splicer asks for it).
pub fn pack_tile(
    folder: &TileSource,
    (row, col): (u32, u32),
    tolerance: f64,
    limits: &Limits,
    format: Option<BlockFormat>,
) -> Result<PackedTile, Error> {
    if folder.mosaic.tile_rect(row, col).is_none() {
        let (w, h) = folder.extent();
        let n = folder.tiles();
        let message = if row >= n || col >= n {
            format!("tile ({row}, {col}) outside the {n}x{n} grid")
        } else {
            format!(
                "tile ({row}, {col}) holds none of the {w}x{h} texture (pad of the {n}x{n} grid, never packed)"
            )
        };
        return Err(Error::Tiles {
            path: folder.path.clone(),
            message,
        });
    }
    let grid = folder.load_tile(row, col, limits)?;
    let file = folder.tile_path(row, col);
    QuadTree::pack_tile(
        &folder.mosaic,
        (row, col),
        &grid,
        &folder.options(tolerance, limits),
        format,
    )
    .map_err(crate::error::core(&file))
}

/// The texture [`pack_tiles`] makes of the mosaic, from its tiles packed
/// by [`pack_tile`] elsewhere: `load(row, col, format)` returns tile
/// `(row, col)`, packed in `format` when that is given
/// ([`QuadTree::from_packed_tiles`]). Byte for byte the same tree.
pub fn splice_tiles(
    folder: &TileSource,
    tolerance: f64,
    limits: &Limits,
    load: &mut dyn FnMut(u32, u32, Option<BlockFormat>) -> Result<PackedTile, Error>,
) -> Result<(QuadTree, BuildReport), Error> {
    let options = folder.options(tolerance, limits);
    let mut failure: Option<Error> = None;
    let mut load = |row: u32, col: u32, format: Option<BlockFormat>| {
        load(row, col, format).map_err(|e| set_aside(e, &mut failure))
    };
    let result = QuadTree::from_packed_tiles(&folder.mosaic, &options, &mut load);
    match (result, failure) {
        (Ok(done), _) => Ok(done),
        (Err(_), Some(e)) => Err(e),
        (Err(e), None) => Err(crate::error::core(&folder.path)(e)),
    }
}

impl TileSource {
    /// The options a mosaic of these tiles packs with.
    fn options(&self, tolerance: f64, limits: &Limits) -> BuildOptions {
        BuildOptions {
            tolerance,
            max_level: None,
            max_nodes: limits.max_nodes,
            max_bytes: Some(limits.max_memory),
            ..BuildOptions::default()
        }
    }

    /// The file tile `(row, col)` is read from (the TIFF itself for a
    /// tiled TIFF).
    fn tile_path(&self, row: u32, col: u32) -> PathBuf {
        match &self.kind {
            Kind::Folder(files) => files[(row * self.tiles() + col) as usize].clone(),
            Kind::Tiff(_) => self.path.clone(),
        }
    }

    /// Tile `(row, col)`'s texels, refused unless the first tile's size.
    fn load_tile(&self, row: u32, col: u32, limits: &Limits) -> Result<TexelGrid, Error> {
        let files = match &self.kind {
            Kind::Folder(files) => files,
            Kind::Tiff(tiff) => {
                let Some(rect) = self.mosaic.tile_rect(row, col) else {
                    return Err(Error::Tiles {
                        path: self.path.clone(),
                        message: format!("tile ({row}, {col}) holds none of the texture"),
                    });
                };
                return tiff.load_rect(rect, limits);
            }
        };
        let file = &files[(row * self.tiles() + col) as usize];
        let grid = crate::image_io::load_texels(file, limits)?;
        let side = self.side();
        if (grid.width(), grid.height()) != (side, side) {
            return Err(Error::Tiles {
                path: file.clone(),
                message: format!(
                    "{}x{} texels, but the first tile is {side}x{side}",
                    grid.width(),
                    grid.height()
                ),
            });
        }
        Ok(grid)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tiff_io::tiff_writer::{Spec, utm33_keys};

    fn temp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("quadtex-tiles-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// A `side × side` 8-bit RGB image with flat quarters and noisy detail.
    fn rgb(side: u32) -> Vec<u16> {
        let mut x = 7u32;
        (0..side * side * 3)
            .map(|i| {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                let (col, row) = ((i / 3) % side, (i / 3) / side);
                if (col < side / 2) == (row < side / 2) {
                    (40 * (i % 3) + 20) as u16
                } else {
                    (x % 256) as u16
                }
            })
            .collect()
    }

    fn qtx_bytes(tree: &QuadTree, (width, height): (u32, u32)) -> Vec<u8> {
        let mut out = Vec::new();
        crate::write_qtx_to(&mut out, Path::new("-"), tree, Some((width, height))).unwrap();
        out
    }

    /// Writes the `tiles × tiles` tiles of `spec`'s image as `ROW_COL.ext`.
    fn folder_of(spec: &Spec, tile: u32, dir: &Path, ext: &str) {
        let tiles = spec.width / tile;
        for row in 0..tiles {
            for col in 0..tiles {
                let mut s = Vec::new();
                for y in row * tile..(row + 1) * tile {
                    let at = ((y * spec.width + col * tile) * 3) as usize;
                    s.extend_from_slice(&spec.samples[at..at + 3 * tile as usize]);
                }
                let path = dir.join(format!("{row}_{col}.{ext}"));
                if ext == "png" {
                    let bytes = s.iter().map(|&v| v as u8).collect();
                    image::RgbImage::from_raw(tile, tile, bytes)
                        .unwrap()
                        .save(&path)
                        .unwrap();
                } else {
                    std::fs::write(&path, Spec::rgb8(tile, tile, s).write()).unwrap();
                }
            }
        }
    }

    #[test]
    fn a_tiled_tiff_packs_as_a_folder_of_its_tiles() {
        let limits = Limits::default();
        let d = temp("tiff-vs-folder");
        for (big, compression) in [(false, 5), (true, 8)] {
            let spec = Spec {
                tile: Some((16, 16)),
                compression,
                big,
                geo: Some((
                    [0.5, 0.5, 0.0],
                    [0.0, 0.0, 0.0, 350_000.0, 5_000_000.0, 0.0],
                    utm33_keys(),
                )),
                ..Spec::rgb8(64, 64, rgb(64))
            };
            let tif = d.join("mosaic.tif");
            std::fs::write(&tif, spec.write()).unwrap();
            let (tree, report, source) = pack_tiles(&tif, 0.0, &limits).unwrap();
            assert!(source.is_tiff() && source.path() == tif);
            assert_eq!(
                (source.tiles(), source.side(), source.extent()),
                (4, 16, (64, 64))
            );
            assert_eq!(report.max_error, 0.0);
            let geo = source.georeference().unwrap();
            assert_eq!(geo.epsg(), Some(32633));
            assert_eq!(geo.pixel_scale, Some([0.5, 0.5, 0.0]));
            for ext in ["png", "tif"] {
                let folder = d.join(format!("tiles-{ext}"));
                std::fs::create_dir_all(&folder).unwrap();
                folder_of(&spec, 16, &folder, ext);
                let (other, _, f) = pack_tiles(&folder, 0.0, &limits).unwrap();
                assert!(!f.is_tiff() && f.georeference().is_none());
                assert!(other == tree, "{ext}");
                assert_eq!(
                    qtx_bytes(&other, (64, 64)),
                    qtx_bytes(&tree, (64, 64)),
                    "{ext}"
                );
            }
            // The whole image packed at once: the same tree.
            let grid = crate::load_texels(&tif, &limits).unwrap();
            let (whole, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
            assert!(whole == tree);
            // Tile by tile on two threads (each with its own decoder), then spliced.
            let packed: Vec<Vec<(u32, u32, PackedTile)>> = std::thread::scope(|s| {
                let workers: Vec<_> = (0..2u32)
                    .map(|half| {
                        let source = &source;
                        let limits = &limits;
                        s.spawn(move || {
                            (half * 2..half * 2 + 2)
                                .flat_map(|row| (0..4).map(move |col| (row, col)))
                                .map(|(row, col)| {
                                    let t = pack_tile(source, (row, col), 0.0, limits, None);
                                    (row, col, t.unwrap())
                                })
                                .collect()
                        })
                    })
                    .collect();
                workers.into_iter().map(|w| w.join().unwrap()).collect()
            });
            let packed: Vec<_> = packed.into_iter().flatten().collect();
            let (spliced, _) = splice_tiles(&source, 0.0, &limits, &mut |row, col, format| {
                let (_, _, tile) = packed
                    .iter()
                    .find(|(r, c, _)| (*r, *c) == (row, col))
                    .unwrap();
                match format {
                    None => Ok(tile.clone()),
                    Some(f) => pack_tile(&source, (row, col), 0.0, &limits, Some(f)),
                }
            })
            .unwrap();
            assert!(spliced == tree);
            // A clone opens its own decoder.
            let again = source.clone();
            assert_eq!(again, source);
            assert!(pack_tile(&again, (3, 3), 0.0, &limits, None).is_ok());
            assert!(pack_tile(&again, (4, 0), 0.0, &limits, None).is_err());
        }
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// A TIFF `pack-tiles` must refuse, with every needle in the message.
    fn refused(spec: &Spec, needles: &[&str]) {
        let d = temp("refused");
        let tif = d.join("refused.tif");
        std::fs::write(&tif, spec.write()).unwrap();
        let e = pack_tiles(&tif, 0.0, &Limits::default())
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(&format!("{}: ", tif.display())), "{e}");
        for n in needles {
            assert!(e.contains(n), "`{n}` not in: {e}");
        }
        // `pack` reads it all the same.
        assert!(crate::load_texels(&tif, &Limits::default()).is_ok());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn tiffs_that_cannot_be_tiled_are_refused() {
        let tiled = |w: u32, h: u32, tile: (u32, u32)| Spec {
            tile: Some(tile),
            ..Spec::rgb8(w, h, vec![9; (w * h * 3) as usize])
        };
        refused(
            &Spec::rgb8(32, 32, vec![9; 32 * 32 * 3]),
            &["a stripped TIFF (32x32, 32 rows a strip)", "`quadtex pack`"],
        );
        refused(
            &tiled(64, 32, (32, 16)),
            &["TIFF tiles of 32x16 texels: pack-tiles needs square tiles of a power of two"],
        );
        refused(&tiled(48, 48, (24, 24)), &["TIFF tiles of 24x24 texels"]);
        refused(
            &tiled(8, 7, (16, 16)),
            &["8x7 texels in tiles of 16x16", "no larger than half a tile"],
        );
    }

    /// Tiled TIFFs of any size (Cloud-Optimized GeoTIFF layouts: partial
    /// tiles on the right and bottom edges, grids of any shape) pack tile by
    /// tile to the tree of the whole image: in order, on threads, and packed
    /// apart then spliced; 8-bit RGB and 16-bit RGBA, chunky and planar.
    #[test]
    fn tiffs_of_any_size_pack_tile_by_tile_to_the_tree_of_the_whole_image() {
        let limits = Limits::default();
        let d = temp("tiff-any-size");
        let cases = [
            (48, 32, 16, false, false),
            (48, 48, 16, false, true),
            (40, 40, 16, true, false),
            (100, 37, 16, false, false),
            (17, 70, 16, true, true),
            (9, 5, 16, false, false),
            (130, 129, 32, false, false),
        ];
        for (i, &(w, h, tile, sixteen, planar)) in cases.iter().enumerate() {
            let (spp, bits) = if sixteen { (4u16, 16u16) } else { (3, 8) };
            let max = if sixteen { 65535u32 } else { 255 };
            // Flat patches and noise, so the tree has uniform squares and blocks.
            let mut x = 0x9e37_79b9u32 ^ i as u32;
            let samples = (0..w * h * u32::from(spp))
                .map(|k| {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    let (c, r) = ((k / u32::from(spp)) % w, (k / u32::from(spp)) / w);
                    if (c / 8 + r / 8) % 3 == 0 {
                        (max / 3) as u16
                    } else {
                        (x % (max + 1)) as u16
                    }
                })
                .collect();
            let spec = Spec {
                tile: Some((tile, tile)),
                bits,
                samples_per_pixel: spp,
                extra_samples: if spp == 4 { vec![2] } else { Vec::new() },
                planar,
                compression: if i % 2 == 0 { 8 } else { 1 },
                ..Spec::rgb8(w, h, samples)
            };
            let tif = d.join(format!("any-{i}.tif"));
            std::fs::write(&tif, spec.write()).unwrap();
            let what = format!("{w}x{h} in tiles of {tile}, 16-bit {sixteen}, planar {planar}");
            let (tree, report, source) = pack_tiles(&tif, 0.0, &limits).expect(&what);
            assert_eq!(source.extent(), (w, h), "{what}");
            assert_eq!(report.max_error, 0.0, "{what}");
            let grid = crate::load_texels(&tif, &limits).unwrap();
            let (whole, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
            assert!(whole == tree, "{what}");
            let on_threads = crate::pack_tiles_on_threads(&source, 0.0, &limits, 3)
                .expect(&what)
                .0;
            assert!(on_threads == tree, "{what}");
            let order = source.mosaic().tiles_in_order();
            let packed: Vec<_> = order
                .iter()
                .map(|&at| {
                    (
                        at,
                        pack_tile(&source, at, 0.0, &limits, None)
                            .unwrap()
                            .to_bytes(),
                    )
                })
                .collect();
            let (spliced, _) =
                splice_tiles(
                    &source,
                    0.0,
                    &limits,
                    &mut |row, col, format| match format {
                        None => {
                            let (_, b) = packed.iter().find(|(at, _)| *at == (row, col)).unwrap();
                            Ok(PackedTile::from_bytes(b).unwrap())
                        }
                        Some(f) => pack_tile(&source, (row, col), 0.0, &limits, Some(f)),
                    },
                )
                .unwrap();
            assert!(spliced == tree, "{what}");
            assert_eq!(
                qtx_bytes(&spliced, (w, h)),
                qtx_bytes(&whole, (w, h)),
                "{what}"
            );
            // A tile in the pad is refused by name.
            let n = source.tiles();
            if let Some(pad) = (0..n * n)
                .map(|k| (k / n, k % n))
                .find(|at| !order.contains(at))
            {
                let e = pack_tile(&source, pad, 0.0, &limits, None)
                    .unwrap_err()
                    .to_string();
                assert!(e.contains("holds none of the"), "{e}");
            }
        }
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_file_that_is_not_a_tiff_is_not_a_mosaic() {
        let d = temp("not-tiff");
        let png = d.join("one.png");
        image::RgbImage::new(4, 4).save(&png).unwrap();
        let e = pack_tiles(&png, 0.0, &Limits::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("one.png: neither a folder of ROW_COL tiles nor a tiled TIFF"),
            "{e}"
        );
        let e = pack_tiles(&d.join("absent"), 0.0, &Limits::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("absent"), "{e}");
        std::fs::remove_dir_all(&d).unwrap();
    }
}

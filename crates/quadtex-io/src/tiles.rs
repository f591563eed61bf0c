//! Tiled rasters: a folder of tiles named `ROW_COL.png` (or `.jpg`,
//! `.jpeg`; row 0 at the top, both counted from 0 in decimal) packed into
//! one tree, one tile in memory at a time ([`QuadTree::from_tiles`]).
//!
//! The tiles must form a complete square grid whose side is a power of two
//! (1, 2, 4, … tiles), every tile the same square size, a power of two
//! texels. Other files in the folder are ignored. A missing tile, a
//! duplicate (`3_5.png` and `3_5.jpg`), a tile of another size or format
//! that does not decode is an error naming it, before anything is written.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use quadtex_core::{BlockFormat, BuildOptions, BuildReport, PackedTile, QuadTree, TexelGrid};

use crate::Error;
use crate::limits::Limits;

/// The tiles of a folder, checked for completeness (see the module docs).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TileFolder {
    dir: PathBuf,
    /// Tiles a side.
    tiles: u32,
    /// Texels on a tile's side (from the first tile's header).
    side: u32,
    /// Row-major file names.
    files: Vec<PathBuf>,
}

impl TileFolder {
    /// Scans `dir` for `ROW_COL` tiles and reads the first one's size.
    pub fn scan(dir: &Path, limits: &Limits) -> Result<TileFolder, Error> {
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
            if !matches!(ext.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg") {
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
                "no tiles named ROW_COL.png (or .jpg) found".into(),
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
        let (w, h) = image::image_dimensions(first).map_err(|e| Error::Image {
            path: first.clone(),
            message: e.to_string(),
        })?;
        if w != h || !w.is_power_of_two() {
            return Err(bad(
                first,
                format!("{w}x{h} texels: tiles must be squares of a power of two"),
            ));
        }
        limits.check_dimensions(first, w, h)?;
        Ok(TileFolder {
            dir: dir.to_path_buf(),
            tiles,
            side: w,
            files,
        })
    }

    /// Tiles a side.
    pub fn tiles(&self) -> u32 {
        self.tiles
    }

    /// Texels on a tile's side.
    pub fn side(&self) -> u32 {
        self.side
    }

    /// Texels on the whole texture's side.
    pub fn texels(&self) -> u64 {
        u64::from(self.tiles) * u64::from(self.side)
    }
}

/// Packs the tiles of `dir` (see the module docs) into one tree, to
/// `tolerance` (0: lossless), holding one tile's texels at a time.
pub fn pack_tiles(
    dir: &Path,
    tolerance: f64,
    limits: &Limits,
) -> Result<(QuadTree, BuildReport, TileFolder), Error> {
    let folder = TileFolder::scan(dir, limits)?;
    let options = folder.options(tolerance, limits);
    // The loader's own error (naming the tile) is kept aside: the core sees a placeholder.
    let mut failure: Option<Error> = None;
    let mut load = |row: u32, col: u32| {
        folder
            .load_tile(row, col, limits)
            .map_err(|e| set_aside(e, &mut failure))
    };
    let result = QuadTree::from_tiles(folder.tiles, folder.side, &options, &mut load);
    match (result, failure) {
        (Ok((tree, report)), _) => Ok((tree, report, folder)),
        (Err(_), Some(e)) => Err(e),
        (Err(e), None) => Err(crate::error::core(&folder.dir)(e)),
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

/// Packs tile `(row, col)` (row 0 at the top) of the folder on its own, as
/// [`pack_tiles`] would, for [`splice_tiles`] to splice (on another
/// process or machine: [`PackedTile::to_bytes`]). `format`, when given, is
/// the texel-block format to write (the splicer asks for it).
pub fn pack_tile(
    folder: &TileFolder,
    (row, col): (u32, u32),
    tolerance: f64,
    limits: &Limits,
    format: Option<BlockFormat>,
) -> Result<PackedTile, Error> {
    if row >= folder.tiles || col >= folder.tiles {
        return Err(Error::Tiles {
            path: folder.dir.clone(),
            message: format!("tile ({row}, {col}) outside the {0}x{0} grid", folder.tiles),
        });
    }
    let grid = folder.load_tile(row, col, limits)?;
    let file = folder.files[(row * folder.tiles + col) as usize].clone();
    QuadTree::pack_tile(
        folder.tiles,
        folder.side,
        (row, col),
        &grid,
        &folder.options(tolerance, limits),
        format,
    )
    .map_err(crate::error::core(&file))
}

/// The texture [`pack_tiles`] makes of the folder, from its tiles packed
/// by [`pack_tile`] elsewhere: `load(row, col, format)` returns tile
/// `(row, col)`, packed in `format` when that is given
/// ([`QuadTree::from_packed_tiles`]). Byte for byte the same tree.
pub fn splice_tiles(
    folder: &TileFolder,
    tolerance: f64,
    limits: &Limits,
    load: &mut dyn FnMut(u32, u32, Option<BlockFormat>) -> Result<PackedTile, Error>,
) -> Result<(QuadTree, BuildReport), Error> {
    let options = folder.options(tolerance, limits);
    let mut failure: Option<Error> = None;
    let mut load = |row: u32, col: u32, format: Option<BlockFormat>| {
        load(row, col, format).map_err(|e| set_aside(e, &mut failure))
    };
    let result = QuadTree::from_packed_tiles(folder.tiles, folder.side, &options, &mut load);
    match (result, failure) {
        (Ok(done), _) => Ok(done),
        (Err(_), Some(e)) => Err(e),
        (Err(e), None) => Err(crate::error::core(&folder.dir)(e)),
    }
}

impl TileFolder {
    /// The options a mosaic of this folder packs with.
    fn options(&self, tolerance: f64, limits: &Limits) -> BuildOptions {
        BuildOptions {
            tolerance,
            max_level: None,
            max_nodes: limits.max_nodes,
            max_bytes: Some(limits.max_memory),
            ..BuildOptions::default()
        }
    }

    /// Tile `(row, col)`'s texels, refused unless the first tile's size.
    fn load_tile(&self, row: u32, col: u32, limits: &Limits) -> Result<TexelGrid, Error> {
        let file = &self.files[(row * self.tiles + col) as usize];
        let grid = crate::image_io::load_texels(file, limits)?;
        let side = self.side;
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

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

use quadtex_core::{BuildOptions, BuildReport, QuadTree};

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
    let options = BuildOptions {
        tolerance,
        max_level: None,
        max_nodes: limits.max_nodes,
        max_bytes: Some(limits.max_memory),
        ..BuildOptions::default()
    };
    // The loader's own error (naming the tile) is kept aside: the core sees a placeholder.
    let mut failure: Option<Error> = None;
    let side = folder.side;
    let mut load = |row: u32, col: u32| {
        let file = &folder.files[(row * folder.tiles + col) as usize];
        let fail = |e: Error, failure: &mut Option<Error>| {
            *failure = Some(e);
            quadtex_core::Error::BadDimensions {
                width: 0,
                height: 0,
                reason: "a tile failed to load",
            }
        };
        let grid = match crate::image_io::load_texels(file, limits) {
            Ok(g) => g,
            Err(e) => return Err(fail(e, &mut failure)),
        };
        if (grid.width(), grid.height()) != (side, side) {
            let e = Error::Tiles {
                path: file.clone(),
                message: format!(
                    "{}x{} texels, but the first tile is {side}x{side}",
                    grid.width(),
                    grid.height()
                ),
            };
            return Err(fail(e, &mut failure));
        }
        Ok(grid)
    };
    let result = QuadTree::from_tiles(folder.tiles, side, &options, &mut load);
    match (result, failure) {
        (Ok((tree, report)), _) => Ok((tree, report, folder)),
        (Err(_), Some(e)) => Err(e),
        (Err(e), None) => Err(crate::error::core(&folder.dir)(e)),
    }
}

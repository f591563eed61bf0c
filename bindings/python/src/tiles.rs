//! A tile folder packed tile by tile elsewhere (other processes, other
//! machines: `quadtex.dask.pack_tiles`) and spliced into the texture
//! `pack_tiles` makes: `tile_grid`, `mosaic_tiles`, `pack_tile`,
//! `splice_tiles`.

use std::path::PathBuf;
use std::sync::Arc;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use quadtex_core::{BlockFormat, PackedTile};

use crate::errors::io_error;
use crate::{Texture, limits};

/// A tolerance in `[0, 1]`.
fn check_tolerance(tolerance: f64) -> PyResult<f64> {
    if tolerance.is_finite() && (0.0..=1.0).contains(&tolerance) {
        Ok(tolerance)
    } else {
        Err(PyValueError::new_err(format!(
            "tolerance must be in [0, 1], got {tolerance}"
        )))
    }
}

/// The grid of a folder of tiles, as `pack_tiles` reads it.
///
/// Parameters:
///   directory: str, bytes or os.PathLike; a folder of `ROW_COL.png`
///     (or `.jpg`, `.tif`) tiles, or a tiled TIFF, as for `pack_tiles`.
///
/// Returns: `(tiles, side)`: tiles on a side of the tree's square (a
/// power of two) and texels on a tile's side. A folder fills the square;
/// a tiled TIFF of another size covers its bottom-left part, and
/// `mosaic_tiles` lists the tiles that hold texture.
///
/// Raises: OSError when the folder cannot be read; ValueError for an
/// incomplete or malformed grid, naming the tile.
#[pyfunction]
pub(crate) fn tile_grid(py: Python<'_>, directory: PathBuf) -> PyResult<(u32, u32)> {
    let folder = open_source(py, &directory)?;
    Ok((folder.tiles(), folder.side()))
}

/// The tiles `splice_tiles` asks for: those holding texture, in its order.
///
/// Parameters:
///   directory: the tile folder or tiled TIFF (as for `pack_tiles`).
///
/// Returns: a list of `(row, col)` (row 0 at the top of the tree's
/// square), in Morton order from the bottom-left: every tile of a folder;
/// of a tiled TIFF whose size is not a square of whole tiles, only the
/// tiles that hold part of the image (the others are pad, never packed).
///
/// Raises: as `tile_grid`.
#[pyfunction]
pub(crate) fn mosaic_tiles(py: Python<'_>, directory: PathBuf) -> PyResult<Vec<(u32, u32)>> {
    let folder = open_source(py, &directory)?;
    Ok(folder.mosaic().tiles_in_order())
}

fn open_source(py: Python<'_>, directory: &std::path::Path) -> PyResult<quadtex_io::TileSource> {
    let limits = limits(None)?;
    py.detach(|| quadtex_io::TileSource::open(directory, &limits))
        .map_err(io_error)
}

/// Packs one tile of a folder on its own, for `splice_tiles`.
///
/// Parameters:
///   directory: the tile folder or tiled TIFF (as for `pack_tiles`).
///   row, col: the tile (row 0 at the top), one of `mosaic_tiles`.
///   tolerance: in [0, 1]; the same as the `splice_tiles` call's.
///   memory_limit: bytes, >= 1, or None (the detected budget).
///   block_format: None (the tile's own), or the code `splice_tiles`
///     passes when it asks for the tile again in a wider format.
///
/// Returns: the packed tile as bytes (checked when read back), to carry to
/// the process that splices.
///
/// Raises: OSError when the tile cannot be read; ValueError for a tile of
/// another size or format, or an option out of range.
#[pyfunction]
#[pyo3(signature = (directory, row, col, tolerance = 0.0, memory_limit = None, block_format = None))]
pub(crate) fn pack_tile<'py>(
    py: Python<'py>,
    directory: PathBuf,
    row: u32,
    col: u32,
    tolerance: f64,
    memory_limit: Option<i64>,
    block_format: Option<u8>,
) -> PyResult<Bound<'py, PyBytes>> {
    let tolerance = check_tolerance(tolerance)?;
    let limits = limits(memory_limit)?;
    let format =
        match block_format {
            None => None,
            Some(code) => Some(BlockFormat::from_code(code).ok_or_else(|| {
                PyValueError::new_err(format!("unknown block_format code {code}"))
            })?),
        };
    let bytes = py
        .detach(|| {
            let folder = quadtex_io::TileSource::open(&directory, &limits)?;
            quadtex_io::pack_tile(&folder, (row, col), tolerance, &limits, format)
                .map(|tile| tile.to_bytes())
        })
        .map_err(io_error)?;
    Ok(PyBytes::new(py, &bytes))
}

/// Splices tiles packed by `pack_tile` into the texture `pack_tiles` makes
/// of the folder, byte for byte.
///
/// Parameters:
///   directory: the tile folder or tiled TIFF (as for `pack_tiles`).
///   load: a callable `load(row, col, block_format)` returning the bytes
///     `pack_tile(directory, row, col, tolerance, block_format=block_format)`
///     returns. Tiles are asked for in Morton order; `block_format` is None
///     the first time, and a code when a tile must be packed again in the
///     wider block format of the tiles before it (rare: a mosaic's tiles
///     mostly share a format).
///   tolerance: in [0, 1]; the one the tiles were packed with.
///   memory_limit: bytes, >= 1, or None (the detected budget).
///
/// Returns: a `Texture`, equal to `pack_tiles(directory, tolerance)`.
///
/// Raises: ValueError for damaged tile bytes, a tile of another size or
/// format, or work above `memory_limit`; whatever `load` raises.
#[pyfunction]
#[pyo3(signature = (directory, load, tolerance = 0.0, memory_limit = None))]
pub(crate) fn splice_tiles(
    py: Python<'_>,
    directory: PathBuf,
    load: &Bound<'_, PyAny>,
    tolerance: f64,
    memory_limit: Option<i64>,
) -> PyResult<Texture> {
    let tolerance = check_tolerance(tolerance)?;
    let limits = limits(memory_limit)?;
    let folder = py
        .detach(|| quadtex_io::TileSource::open(&directory, &limits))
        .map_err(io_error)?;
    // The callable's own exception is kept aside and raised as it is.
    let mut raised: Option<PyErr> = None;
    let mut call = |row: u32, col: u32, format: Option<BlockFormat>| {
        let got = load
            .call1((row, col, format.map(BlockFormat::code)))
            .and_then(|b| b.extract::<Vec<u8>>());
        match got {
            Ok(bytes) => PackedTile::from_bytes(&bytes).map_err(|e| quadtex_io::Error::Tiles {
                path: directory.clone(),
                message: format!("tile ({row}, {col}): {e}"),
            }),
            Err(e) => {
                raised = Some(e);
                Err(quadtex_io::Error::Tiles {
                    path: directory.clone(),
                    message: format!("load({row}, {col}) raised"),
                })
            }
        }
    };
    let result = quadtex_io::splice_tiles(&folder, tolerance, &limits, &mut call);
    if let Some(e) = raised {
        return Err(e);
    }
    let (tree, _) = result.map_err(io_error)?;
    Ok(Texture {
        tree: Arc::new(tree),
        source: Some(folder.extent()),
        file: None,
    })
}

//! Packing a raster into an incomplete quadtree.
//!
//! The raster's texels are the *cells*, the squares of the deepest level
//! `D = ⌈log2 max(W, H)⌉`: a `W × H` image of any size covers the
//! bottom-left `W × H` cells of the tree's square, its extent, and the rest
//! is pad, never read (see [`Aspect`]); so an image costs its own texels,
//! not the square around it, and nothing is resampled. Only a `max_level`
//! above `D` (a coarser tree) brings the raster onto the `2^a × 2^b` cells
//! of its power-of-two shape at that level (`a`, `b` the sides' `⌈log2⌉`,
//! shortened alike), each cell the exact area-weighted mean of the texels
//! it overlaps (texels are rectangles of the unit square, see the crate
//! conventions); a deeper one repeats each texel.
//!
//! Then one bottom-up pass computes, for every square, the integer sum, the
//! minimum and the maximum of its cells per channel. A square is **terminal**
//! iff every cell lies within the tolerance `T` of the square's (rounded)
//! mean in every channel (the L∞ metric on linear, premultiplied
//! channels, in units of full scale); with `T = 0` iff all its cells are equal.
//! An inner square's colour is the rounded exact mean of all its texture
//! cells, so rounding never accumulates up the tree.

mod builder;
mod cells;
mod mosaic;
mod packed_tile;
mod resample;

use crate::Error;
use crate::colour::{ColourEncoding, Rgba, Unorm16Rgba};
use crate::memory::{BUILD_BYTES_PER_NODE, check_budget};
use crate::tree::texel_block::{BLOCK_LOG2_SIDE, BlockFormat, BlockWriter};
use crate::tree::{Aspect, MAX_DEPTH, MAX_NODES, QuadTree};
use builder::{Builder, TileSource, Tiles};
use cells::{Cell, HalfRgba};
pub use mosaic::Mosaic;
pub use packed_tile::PackedTile;
use resample::{resample_with, try_resample};

pub(crate) use resample::resample;

/// The settings that shrink a raster build, for [`Error::MemoryBudget`].
const RASTER_KNOBS: &str = "lower --max-level, raise --tolerance, or raise --memory-limit";

/// Deepest cell grid the raster builder allocates: `2^15 × 2^15` cells, 8 GiB.
/// (Vector art packs deeper without a grid; see the SVG packer.)
pub const MAX_BUILD_DEPTH: u8 = 15;

/// Largest width or height the builder accepts (2^20 texels).
pub const MAX_DIMENSION: u32 = 1 << 20;

/// A raster in the tree's colour format, row 0 at the top of the texture.
#[derive(Debug, Clone, PartialEq)]
pub struct TexelGrid {
    width: u32,
    height: u32,
    texels: Vec<Unorm16Rgba>,
    /// The 8-bit sRGB texels (straight alpha) the texels were decoded from,
    /// kept so texel blocks can store them as they were.
    srgb8: Option<Vec<[u8; 4]>>,
    /// HDR texels as half floats (linear, premultiplied, unclamped): the
    /// packer then stores half floats ([`ColourEncoding::Half`]); `texels`
    /// holds them clamped to `[0, 1]` for raster baselines.
    half: Option<Vec<HalfRgba>>,
}

impl TexelGrid {
    /// A grid from row-major texels (row 0 at the top).
    pub fn new(width: u32, height: u32, texels: Vec<Unorm16Rgba>) -> Result<TexelGrid, Error> {
        check_dimensions(width, height)?;
        let expected = u64::from(width) * u64::from(height);
        if texels.len() as u64 != expected {
            return Err(Error::TexelCount {
                expected,
                actual: texels.len() as u64,
            });
        }
        Ok(TexelGrid {
            width,
            height,
            texels,
            srgb8: None,
            half: None,
        })
    }

    /// A grid whose texel `(col, row)` is `f(col, row)`.
    pub fn from_fn(
        width: u32,
        height: u32,
        mut f: impl FnMut(u32, u32) -> Rgba,
    ) -> Result<TexelGrid, Error> {
        check_dimensions(width, height)?;
        let mut texels = Vec::with_capacity(width as usize * height as usize);
        for row in 0..height {
            for col in 0..width {
                texels.push(f(col, row).to_unorm16());
            }
        }
        Ok(TexelGrid {
            width,
            height,
            texels,
            srgb8: None,
            half: None,
        })
    }

    /// A grid from row-major 8-bit sRGB texels with straight alpha (row 0
    /// at the top), as PNG and JPEG store them: each decodes with
    /// [`crate::tree::texel_block::srgb8_texel`], and the packer keeps the bytes
    /// in texel blocks ([`crate::tree::texel_block`]).
    pub fn from_srgb8(width: u32, height: u32, srgb8: Vec<[u8; 4]>) -> Result<TexelGrid, Error> {
        check_dimensions(width, height)?;
        let expected = u64::from(width) * u64::from(height);
        if srgb8.len() as u64 != expected {
            return Err(Error::TexelCount {
                expected,
                actual: srgb8.len() as u64,
            });
        }
        let mut texels = crate::memory::try_with_capacity(srgb8.len(), "texels")?;
        texels.extend(
            srgb8
                .iter()
                .map(|&p| crate::tree::texel_block::srgb8_texel(p)),
        );
        Ok(TexelGrid {
            width,
            height,
            texels,
            srgb8: Some(srgb8),
            half: None,
        })
    }

    /// An HDR grid from row-major linear, premultiplied `f32` texels (row 0
    /// at the top), as OpenEXR and Radiance files hold them: colour is kept
    /// unclamped (above 1 and below 0) to half-float precision; alpha is
    /// clamped to `[0, 1]`. A NaN or infinite channel is refused
    /// ([`Error::NonFiniteTexel`] names the texel), never clamped. The
    /// packer stores such grids as half floats ([`ColourEncoding::Half`]).
    pub fn from_linear_f32(
        width: u32,
        height: u32,
        texels: &[[f32; 4]],
    ) -> Result<TexelGrid, Error> {
        check_dimensions(width, height)?;
        let expected = u64::from(width) * u64::from(height);
        if texels.len() as u64 != expected {
            return Err(Error::TexelCount {
                expected,
                actual: texels.len() as u64,
            });
        }
        let mut half = crate::memory::try_with_capacity(texels.len(), "HDR texels")?;
        let mut ldr = crate::memory::try_with_capacity(texels.len(), "texels")?;
        for (i, t) in texels.iter().enumerate() {
            if let Some(ch) = (0..4).find(|&ch| !t[ch].is_finite()) {
                return Err(Error::NonFiniteTexel {
                    col: (i % width as usize) as u32,
                    row: (i / width as usize) as u32,
                    channel: ['r', 'g', 'b', 'a'][ch],
                    value: t[ch],
                });
            }
            let a = t[3].clamp(0.0, 1.0);
            let v = [t[0], t[1], t[2], a];
            half.push(HalfRgba(
                v.map(|c| ColourEncoding::Half.encode(f64::from(c))),
            ));
            ldr.push(Rgba::new(v[0], v[1], v[2], a).to_unorm16());
        }
        Ok(TexelGrid {
            width,
            height,
            texels: ldr,
            srgb8: None,
            half: Some(half),
        })
    }

    /// True for an HDR grid ([`TexelGrid::from_linear_f32`]).
    pub fn is_hdr(&self) -> bool {
        self.half.is_some()
    }

    /// The 8-bit sRGB texels the grid was made from, if it was
    /// ([`TexelGrid::from_srgb8`]).
    pub fn srgb8(&self) -> Option<&[[u8; 4]]> {
        self.srgb8.as_deref()
    }

    /// Width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Texel `(col, row)`, row 0 at the top. Panics out of range (caller's bug).
    pub fn texel(&self, col: u32, row: u32) -> Unorm16Rgba {
        self.texels[row as usize * self.width as usize + col as usize]
    }
    /// All texels, row-major from the top.
    pub fn texels(&self) -> &[Unorm16Rgba] {
        &self.texels
    }

    /// The depth at which cells are at least as fine as texels: `ceil(log2(max(w, h)))`.
    pub fn natural_depth(&self) -> u8 {
        ceil_log2(self.width.max(self.height))
    }
}

fn ceil_log2(n: u32) -> u8 {
    (32 - n.max(1).saturating_sub(1).leading_zeros()) as u8
}

/// The aspect of a `width × height` raster packed at `depth`, and its cell
/// grid `(columns, rows)`. At the natural depth `D` or deeper, the cells are
/// the texels (each repeated `2^(depth − D)` times a side when deeper) and
/// the texture spans exactly their extent ([`Aspect`]): no resampling. Above
/// `D` (a coarser tree than the image), the image's own power-of-two shape,
/// as deep as `depth` allows on the long side, its cells area-weighted
/// means of the texels.
pub fn raster_cells(width: u32, height: u32, depth: u8) -> (Aspect, usize, usize) {
    let natural = ceil_log2(width.max(height));
    if depth >= natural && depth <= MAX_DEPTH {
        let finer = depth - natural;
        let (columns, rows) = (u64::from(width) << finer, u64::from(height) << finer);
        if let Ok(aspect) = Aspect::from_extent(columns as u32, rows as u32, depth) {
            return (aspect, columns as usize, rows as usize);
        }
    }
    let aspect = Aspect::of_grid(ceil_log2(width), ceil_log2(height));
    let [sx, sz] = aspect.shrink().unwrap_or([0, 0]).map(|s| s.min(depth));
    let aspect = Aspect::new(sx, sz).unwrap_or(Aspect::SQUARE);
    (aspect, 1usize << (depth - sx), 1usize << (depth - sz))
}

pub(crate) fn check_dimensions(width: u32, height: u32) -> Result<(), Error> {
    let (w, h) = (u64::from(width), u64::from(height));
    if width == 0 || height == 0 {
        return Err(Error::BadDimensions {
            width: w,
            height: h,
            reason: "zero-sized",
        });
    }
    if width > MAX_DIMENSION || height > MAX_DIMENSION {
        return Err(Error::BadDimensions {
            width: w,
            height: h,
            reason: "larger than 1048576 texels on a side",
        });
    }
    Ok(())
}

/// How to pack.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BuildOptions {
    /// Largest per-channel deviation (linear, premultiplied, full scale = 1)
    /// allowed between a cell and its terminal square's colour. `0` is lossless.
    pub tolerance: f64,
    /// Depth of the tree's finest cells; `None` for [`TexelGrid::natural_depth`].
    pub max_level: Option<u8>,
    /// Refuse to build trees with more nodes than this.
    pub max_nodes: u64,
    /// Memory budget in bytes (`None`: no budget). Before allocating, the
    /// builder refuses with [`Error::MemoryBudget`] when the texels plus the
    /// cell grid ([`raster_grid_bytes`]) exceed it; while building, when
    /// those plus [`crate::memory::BUILD_BYTES_PER_NODE`] per node so far do.
    pub max_bytes: Option<u64>,
    /// End squares in texel blocks where their texels cost no more than
    /// their nodes ([`crate::tree::texel_block`]); `true` by default. Off, every
    /// square is a node (for comparisons).
    pub texel_blocks: bool,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            tolerance: 0.0,
            max_level: None,
            max_nodes: MAX_NODES,
            max_bytes: None,
            texel_blocks: true,
        }
    }
}

/// What packing did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BuildReport {
    /// Depth of the cell grid (the tree may stop above it).
    pub cell_depth: u8,
    /// True when cells are not the texels themselves (a `max_level` other
    /// than the image's natural depth): each cell then holds an
    /// area-weighted mean of texels, or repeats one.
    pub resampled: bool,
    /// Largest deviation, per channel in full-scale units, between a cell and
    /// the colour of the terminal square that holds it. `0` when lossless.
    pub max_error: f64,
}

impl QuadTree {
    /// Packs a texture tile by tile without holding more than one tile's
    /// texels: the tiles of `mosaic` ([`Mosaic`]), tile `(row, col)`
    /// returned by `load` when the packer reaches it, in Morton order
    /// ([`Mosaic::tiles_in_order`]; tiles wholly in the pad are never
    /// asked for), each of [`Mosaic::tile_extent`] texels. The result is
    /// the tree [`QuadTree::from_texels`] would build from the whole
    /// texture, losslessly or to `options.tolerance`; `options.max_level`
    /// must be `None` (the depth is the mosaic's). The budget covers one
    /// tile's texels and the nodes so far. A tile of another size, or any
    /// error `load` returns, stops the build.
    pub fn from_tiles(
        mosaic: &Mosaic,
        options: &BuildOptions,
        load: &mut dyn FnMut(u32, u32) -> Result<TexelGrid, Error>,
    ) -> Result<(QuadTree, BuildReport), Error> {
        Self::from_tile_source(mosaic, options, TileSource::Texels(load))
    }

    /// Packs tile `(row, col)` of `mosaic` on its own, as
    /// [`QuadTree::from_tiles`] would, for [`QuadTree::from_packed_tiles`]
    /// to splice: on another thread, process or machine. `grid` holds the
    /// tile's texels ([`Mosaic::tile_extent`] of them). `format`, when
    /// given, is the texel-block format to write (the splicer asks for it
    /// when the tiles before this one need a wider one); `None` packs in
    /// the tile's own. Refused: an HDR grid, a grid of another size, a tile
    /// outside the grid or wholly in the pad, options `from_tiles` refuses.
    pub fn pack_tile(
        mosaic: &Mosaic,
        (row, col): (u32, u32),
        grid: &TexelGrid,
        options: &BuildOptions,
        format: Option<crate::BlockFormat>,
    ) -> Result<PackedTile, Error> {
        check_mosaic(mosaic, options)?;
        let Some(extent) = mosaic.tile_extent(row, col) else {
            return Err(Error::BadDimensions {
                width: u64::from(col),
                height: u64::from(row),
                reason: "tile (row, col) outside the mosaic's texture",
            });
        };
        if (grid.width, grid.height) != extent {
            return Err(Error::BadDimensions {
                width: grid.width.into(),
                height: grid.height.into(),
                reason: "not the size of the mosaic's tile there",
            });
        }
        let fixed = tile_fixed_bytes(mosaic);
        let context = options.tile_context(mosaic, extent, format, 0, fixed);
        packed_tile::PackedTile::pack(grid, (row, col), &context)
    }

    /// The tree [`QuadTree::from_tiles`] builds, from tiles packed by
    /// [`QuadTree::pack_tile`] (with the same `mosaic` and `options`):
    /// `load(row, col, format)` returns tile `(row, col)`, packed in
    /// `format` when that is given. The splicer visits tiles in Morton
    /// order, as the sequential build does, and asks for a tile again, in
    /// the wider format, when its blocks were written narrower than the
    /// tiles before it make the mosaic's. The result is byte for byte the
    /// sequential one; only the squares above the tiles are built here, so
    /// the memory is the tree's, not a tile's texels.
    pub fn from_packed_tiles(
        mosaic: &Mosaic,
        options: &BuildOptions,
        load: &mut dyn FnMut(u32, u32, Option<crate::BlockFormat>) -> Result<PackedTile, Error>,
    ) -> Result<(QuadTree, BuildReport), Error> {
        Self::from_tile_source(mosaic, options, TileSource::Packed(load))
    }

    fn from_tile_source(
        mosaic: &Mosaic,
        options: &BuildOptions,
        source: TileSource<'_>,
    ) -> Result<(QuadTree, BuildReport), Error> {
        let depth = check_mosaic(mosaic, options)?;
        let fixed_bytes = tile_fixed_bytes(mosaic);
        let (tiles, side) = (mosaic.tiles(), mosaic.side());
        check_budget(
            || format!("packing {tiles}x{tiles} tiles of {side}x{side} texels"),
            fixed_bytes + BUILD_BYTES_PER_NODE,
            options.max_bytes,
            RASTER_KNOBS,
        )?;
        let aspect = Aspect::from_extent(mosaic.width(), mosaic.height(), depth)?;
        let b = Builder::<Unorm16Rgba> {
            cells: &[],
            srgb8: None,
            // Made when the first tile shows the format.
            blocks: None,
            texel_blocks_allowed: options.texel_blocks,
            tiles: Some(Tiles {
                mosaic: *mosaic,
                source,
                options: *options,
            }),
            // The texture's cells, for the means of squares above the tiles.
            side: mosaic.width() as usize,
            depth,
            tolerance: Unorm16Rgba::tolerance(options.tolerance),
            levels: vec![Vec::new(); usize::from(depth) + 1],
            nodes: 1,
            max_nodes: options.max_nodes,
            max_error: 0.0,
            fixed_bytes,
            max_bytes: options.max_bytes,
            aspect,
            rows: mosaic.height() as usize,
            parallel_cells: usize::MAX,
        };
        b.build(false)
    }

    /// Packs a raster (see the [module documentation](crate::raster)).
    pub fn from_texels(
        grid: &TexelGrid,
        options: &BuildOptions,
    ) -> Result<(QuadTree, BuildReport), Error> {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let split = if cores > 1 {
            PARALLEL_BUILD_CELLS
        } else {
            usize::MAX
        };
        Self::from_texels_split(grid, options, split)
    }

    /// [`QuadTree::from_texels`], the root's quarters built on threads of
    /// their own from `parallel_cells` cells (`usize::MAX`: never).
    pub(crate) fn from_texels_split(
        grid: &TexelGrid,
        options: &BuildOptions,
        parallel_cells: usize,
    ) -> Result<(QuadTree, BuildReport), Error> {
        if !(options.tolerance.is_finite() && options.tolerance >= 0.0) {
            return Err(Error::BadTolerance(options.tolerance));
        }
        let depth = options.max_level.unwrap_or_else(|| grid.natural_depth());
        // The cell grid is 8 bytes a cell: 2^30 cells (depth 15, 8 GiB) is the most we allocate.
        if depth > MAX_BUILD_DEPTH {
            return Err(Error::DepthTooLarge {
                depth: depth.into(),
                max: MAX_BUILD_DEPTH.into(),
            });
        }
        let (aspect, columns, rows) = raster_cells(grid.width, grid.height, depth);
        let resampled = grid.width as usize != columns || grid.height as usize != rows;
        let fixed_bytes = raster_grid_bytes(grid.width, grid.height, depth);
        check_budget(
            || {
                format!(
                    "packing {}x{} texels at level {depth} ({columns}x{rows} cells)",
                    grid.width, grid.height
                )
            },
            fixed_bytes + BUILD_BYTES_PER_NODE,
            options.max_bytes,
            RASTER_KNOBS,
        )?;
        if let Some(half) = &grid.half {
            return build_hdr(
                grid,
                half,
                options,
                (depth, aspect, columns, rows),
                (fixed_bytes, parallel_cells),
            );
        }
        let owned;
        let cells: &[Unorm16Rgba] = if resampled {
            owned = try_resample(grid, columns, rows)?;
            &owned
        } else {
            &grid.texels
        };
        let tolerance = Unorm16Rgba::tolerance(options.tolerance);
        // Blocks unless a strip is thinner than a block: a block across the
        // texture's edge stores pad texels too.
        let blocks = depth
            .checked_sub(BLOCK_LOG2_SIDE)
            .filter(|_| options.texel_blocks)
            .filter(|&l| aspect.shrink().is_none_or(|s| s.iter().all(|&s| s <= l)))
            .map(|level| BlockWriter {
                level,
                format: block_format(grid, resampled),
                flags: Vec::new(),
                data: Vec::new(),
            });
        let b = Builder {
            cells,
            srgb8: grid.srgb8.as_deref().filter(|_| !resampled),
            blocks,
            texel_blocks_allowed: options.texel_blocks,
            tiles: None,
            side: columns,
            depth,
            tolerance,
            levels: vec![Vec::new(); usize::from(depth) + 1],
            nodes: 1,
            max_nodes: options.max_nodes,
            max_error: 0.0,
            fixed_bytes,
            max_bytes: options.max_bytes,
            aspect,
            rows,
            parallel_cells,
        };
        b.build(resampled)
    }
}

/// Checks a mosaic of `tiles × tiles` tiles of `side × side` texels and the
/// options it is packed with; returns the tiles' level and the depth.
/// The mosaic's depth, once `options` suit a tiled build.
fn check_mosaic(mosaic: &Mosaic, options: &BuildOptions) -> Result<u8, Error> {
    if !(options.tolerance.is_finite() && options.tolerance >= 0.0) {
        return Err(Error::BadTolerance(options.tolerance));
    }
    if options.max_level.is_some() {
        return Err(Error::BadDimensions {
            width: u64::from(mosaic.width()),
            height: u64::from(mosaic.height()),
            reason: "a tiled texture is packed at its own depth (no max level)",
        });
    }
    Ok(mosaic.depth())
}

/// Bytes a tiled build holds besides its tree: one tile's texels.
fn tile_fixed_bytes(mosaic: &Mosaic) -> u64 {
    8 * u64::from(mosaic.side()) * u64::from(mosaic.side())
}

/// Textures of at least this many cells (1024 × 1024) have the root's
/// quarters packed on four threads ([`Builder::quarters_apart`]); below, a
/// thread costs more than it saves.
const PARALLEL_BUILD_CELLS: usize = 1 << 20;

/// Packs the half-float texels of an HDR grid (no texel blocks).
fn build_hdr(
    grid: &TexelGrid,
    half: &[HalfRgba],
    options: &BuildOptions,
    (depth, aspect, columns, rows): (u8, Aspect, usize, usize),
    (fixed_bytes, parallel_cells): (u64, usize),
) -> Result<(QuadTree, BuildReport), Error> {
    let resampled = grid.width as usize != columns || grid.height as usize != rows;
    let owned;
    let cells: &[HalfRgba] = if resampled {
        let decode = |i: usize| {
            ColourEncoding::Half
                .decode_colour(Unorm16Rgba(half[i].0))
                .map(|v| v as f32)
        };
        owned = resample_with(
            (grid.width as usize, grid.height as usize),
            (columns, rows),
            decode,
            |acc| HalfRgba(acc.map(|v| ColourEncoding::Half.encode(f64::from(v)))),
        )?;
        &owned
    } else {
        half
    };
    let b = Builder::<HalfRgba> {
        cells,
        srgb8: None,
        blocks: None,
        texel_blocks_allowed: false,
        tiles: None,
        side: columns,
        depth,
        tolerance: options.tolerance,
        levels: vec![Vec::new(); usize::from(depth) + 1],
        nodes: 1,
        max_nodes: options.max_nodes,
        max_error: 0.0,
        fixed_bytes,
        max_bytes: options.max_bytes,
        aspect,
        rows,
        parallel_cells,
    };
    b.build(resampled)
}

/// The format texel blocks keep `grid` in: its 8-bit source when it has
/// one and its cells are its texels, else the tree's unorm16.
fn block_format(grid: &TexelGrid, resampled: bool) -> BlockFormat {
    match grid.srgb8.as_deref() {
        Some(src) if !resampled => BlockFormat::narrowest_srgb8(src),
        _ => BlockFormat::Unorm16Rgba,
    }
}

/// Bytes a raster build at `depth` holds before its tree grows: the
/// `width × height` texels (8 bytes each), and unless they are the cells
/// themselves the cell grid of [`raster_cells`] (8 bytes a cell) plus the
/// resampler's horizontal pass (`height × columns` cells of 16 bytes). The
/// tree adds [`crate::memory::BUILD_BYTES_PER_NODE`] a node, at most
/// `4/3` a cell plus `4` per level of the aspect (a lossless tree of noise).
pub fn raster_grid_bytes(width: u32, height: u32, depth: u8) -> u64 {
    let texels = 8 * u64::from(width) * u64::from(height);
    let depth = depth.min(MAX_DEPTH);
    let (_, columns, rows) = raster_cells(width, height, depth);
    let (columns, rows) = (columns as u64, rows as u64);
    if u64::from(width) == columns && u64::from(height) == rows {
        return texels;
    }
    texels
        .saturating_add(8u64.saturating_mul(columns).saturating_mul(rows))
        .saturating_add(
            16u64
                .saturating_mul(u64::from(height))
                .saturating_mul(columns),
        )
}

#[cfg(test)]
mod block_tests;
#[cfg(test)]
mod tests;

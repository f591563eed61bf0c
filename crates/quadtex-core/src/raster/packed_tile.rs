//! One tile of a mosaic packed on its own ([`PackedTile`]), to be spliced
//! into the mosaic's tree by [`QuadTree::from_packed_tiles`]: tiles packed
//! on other threads, processes or machines give the tree
//! [`QuadTree::from_tiles`] builds, byte for byte.

use super::builder::{Builder, Kind};
use super::cells::{Cell, Stats};
use super::{BuildOptions, TexelGrid, block_format};
use crate::Error;
use crate::colour::Unorm16Rgba;
use crate::tree::texel_block::{BLOCK_LOG2_SIDE, BlockFormat, BlockWriter};
use crate::tree::{Aspect, MAX_DEPTH};

/// First bytes of [`PackedTile::to_bytes`].
const MAGIC: &[u8; 8] = b"QTXTILE2";

/// A tile of a `tiles × tiles` mosaic packed on its own: its subtree (the
/// levels below the tile's square), texel blocks, and the statistics the
/// squares above it need.
///
/// Made by [`QuadTree::pack_tile`], carried as bytes
/// ([`PackedTile::to_bytes`], [`PackedTile::from_bytes`]) and spliced by
/// [`QuadTree::from_packed_tiles`]. A tile's texel blocks are written in an
/// 8-bit format at least as wide as its own texels need; the mosaic's tree
/// writes every tile in the widest format of the tiles before it in Morton
/// order, so a tile packed in a narrower format than that is packed again
/// in the wider one (the splicer asks for it; it is rare in practice: a
/// mosaic's tiles mostly share a format).
#[derive(Debug, Clone, PartialEq)]
pub struct PackedTile {
    pub(super) stats: Stats,
    pub(super) root: Unorm16Rgba,
    pub(super) kind: Kind,
    /// The subtree's levels below the tile's root.
    pub(super) levels: Vec<Vec<(bool, Unorm16Rgba)>>,
    /// Texel blocks: format, one flag per node of the block level, data.
    pub(super) blocks: Option<(BlockFormat, Vec<bool>, Vec<u8>)>,
    /// Nodes the subtree adds below the tile's square.
    pub(super) nodes: u64,
    pub(super) max_error: f64,
    /// Texels on the tile square's side.
    pub(super) side: u32,
    /// The tile's texels, `(w, h)`: `side × side` or less on the texture's
    /// top and right edges ([`super::Mosaic::tile_extent`]).
    pub(super) extent: (u32, u32),
    /// The tile's own narrowest block format (before widening).
    pub(super) own_format: Option<BlockFormat>,
}

/// What packing one tile needs from the mosaic around it.
pub(super) struct TileContext {
    /// Levels below the tile's square: `log2 side`.
    pub(super) depth: u8,
    /// The tile's texels, `(w, h)` ([`super::Mosaic::tile_extent`]).
    pub(super) extent: (u32, u32),
    /// The block level inside the tile, if blocks are allowed.
    pub(super) block_level: Option<u8>,
    /// The format blocks are written in; `None`: the tile's own.
    pub(super) format: Option<BlockFormat>,
    pub(super) tolerance: f64,
    pub(super) texel_blocks_allowed: bool,
    /// Nodes of the mosaic so far, for the node limit.
    pub(super) nodes_before: u64,
    pub(super) max_nodes: u64,
    pub(super) fixed_bytes: u64,
    pub(super) max_bytes: Option<u64>,
}

impl PackedTile {
    /// Packs `grid` (a `side × side` tile, `row` and `col` for errors) as
    /// `context` says.
    pub(super) fn pack(
        grid: &TexelGrid,
        (row, col): (u32, u32),
        context: &TileContext,
    ) -> Result<PackedTile, Error> {
        if (grid.width, grid.height) != context.extent {
            return Err(Error::BadDimensions {
                width: grid.width.into(),
                height: grid.height.into(),
                reason: "not the size of the mosaic's tile there",
            });
        }
        if grid.is_hdr() {
            // Tiles are packed as unorm16 or 8-bit: an HDR tile would be clamped.
            return Err(Error::HdrTile { row, col });
        }
        let own = block_format(grid, false);
        let format = context.format.unwrap_or(own);
        if format.is_srgb8() != own.is_srgb8() {
            return Err(tile_format_error(row, col, own, format));
        }
        let format = format.widest(own);
        let mut b = Builder {
            cells: &grid.texels,
            srgb8: grid.srgb8.as_deref(),
            blocks: context.block_level.map(|level| BlockWriter {
                level,
                format,
                flags: Vec::new(),
                data: Vec::new(),
            }),
            texel_blocks_allowed: context.texel_blocks_allowed,
            tiles: None,
            side: grid.width as usize,
            depth: context.depth,
            tolerance: context.tolerance,
            levels: vec![Vec::new(); usize::from(context.depth) + 1],
            nodes: context.nodes_before,
            max_nodes: context.max_nodes,
            max_error: 0.0,
            fixed_bytes: context.fixed_bytes,
            max_bytes: context.max_bytes,
            aspect: Aspect::from_extent(grid.width, grid.height, context.depth)?,
            rows: grid.height as usize,
            parallel_cells: usize::MAX,
        };
        let Some((stats, root, kind)) = b.square(0, 0, 0)? else {
            return Err(Error::MalformedTree("a tile lies wholly in the pad".into()));
        };
        let nodes = b.nodes - context.nodes_before;
        let mut levels = b.levels;
        levels.remove(0);
        Ok(PackedTile {
            stats,
            root,
            kind,
            levels,
            blocks: b.blocks.map(|w| (w.format, w.flags, w.data)),
            nodes,
            max_error: b.max_error,
            side: 1 << context.depth,
            extent: (grid.width, grid.height),
            own_format: context.block_level.map(|_| own),
        })
    }

    /// The format the tile's texel blocks are written in (`None` without
    /// blocks).
    pub fn block_format(&self) -> Option<BlockFormat> {
        self.blocks.as_ref().map(|b| b.0)
    }

    /// Texels on the tile square's side.
    pub fn side(&self) -> u32 {
        self.side
    }

    /// The tile's texels, `(w, h)` ([`super::Mosaic::tile_extent`]).
    pub fn extent(&self) -> (u32, u32) {
        self.extent
    }

    /// The tile as bytes, for carrying between processes
    /// ([`PackedTile::from_bytes`] reads them back).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        out.extend(MAGIC);
        out.extend(self.side.to_le_bytes());
        out.extend(self.extent.0.to_le_bytes());
        out.extend(self.extent.1.to_le_bytes());
        out.push(match self.kind {
            Kind::Terminal => 0,
            Kind::Inner => 1,
            Kind::Block => 2,
        });
        out.push(self.own_format.map_or(0, BlockFormat::code));
        for v in self.stats.sum {
            out.extend(v.to_le_bytes());
        }
        for v in self
            .stats
            .min
            .iter()
            .chain(&self.stats.max)
            .chain(&self.root.0)
        {
            out.extend(v.to_le_bytes());
        }
        out.extend(self.nodes.to_le_bytes());
        out.extend(self.max_error.to_le_bytes());
        out.push(self.levels.len() as u8);
        for level in &self.levels {
            out.extend((level.len() as u64).to_le_bytes());
            for (inner, c) in level {
                out.push(u8::from(*inner));
                for v in c.0 {
                    out.extend(v.to_le_bytes());
                }
            }
        }
        match &self.blocks {
            None => out.push(0),
            Some((format, flags, data)) => {
                out.push(format.code());
                out.extend((flags.len() as u64).to_le_bytes());
                out.extend(flags.iter().map(|&f| u8::from(f)));
                out.extend((data.len() as u64).to_le_bytes());
                out.extend(data);
            }
        }
        let crc = crc32(&out);
        out.extend(crc.to_le_bytes());
        out
    }

    /// Reads [`PackedTile::to_bytes`]; damaged, truncated or foreign bytes
    /// are refused ([`Error::MalformedTree`] naming what is wrong), never
    /// misread.
    pub fn from_bytes(bytes: &[u8]) -> Result<PackedTile, Error> {
        let bad = |what: &str| Error::MalformedTree(format!("packed tile: {what}"));
        if bytes.len() < MAGIC.len() + 4 || &bytes[..MAGIC.len()] != MAGIC {
            return Err(bad("not a packed tile (wrong magic bytes)"));
        }
        let (body, crc) = bytes.split_at(bytes.len() - 4);
        if crc32(body).to_le_bytes() != crc {
            return Err(bad("checksum mismatch (damaged or truncated)"));
        }
        let mut r = Reader {
            bytes: &body[MAGIC.len()..],
        };
        let side = r.u32()?;
        if !side.is_power_of_two() || !(1 << BLOCK_LOG2_SIDE..=super::MAX_DIMENSION).contains(&side)
        {
            return Err(bad("side is not a power of two of at least 4"));
        }
        let extent = (r.u32()?, r.u32()?);
        if extent.0 == 0 || extent.1 == 0 || extent.0 > side || extent.1 > side {
            return Err(bad("extent empty or larger than the tile"));
        }
        let kind = match r.u8()? {
            0 => Kind::Terminal,
            1 => Kind::Inner,
            2 => Kind::Block,
            _ => return Err(bad("unknown kind")),
        };
        let own_format = match r.u8()? {
            0 => None,
            code => Some(BlockFormat::from_code(code).ok_or_else(|| bad("unknown block format"))?),
        };
        let mut sum = [0u64; 4];
        for s in &mut sum {
            *s = r.u64()?;
        }
        let mut u16s = [0u16; 12];
        for v in &mut u16s {
            *v = r.u16()?;
        }
        let stats = Stats {
            sum,
            min: [u16s[0], u16s[1], u16s[2], u16s[3]],
            max: [u16s[4], u16s[5], u16s[6], u16s[7]],
        };
        let root = Unorm16Rgba([u16s[8], u16s[9], u16s[10], u16s[11]]);
        let nodes = r.u64()?;
        let max_error = f64::from_bits(r.u64()?);
        let depth = r.u8()?;
        if depth > MAX_DEPTH || u32::from(depth) > side.trailing_zeros() {
            return Err(bad("deeper than the tile"));
        }
        let mut levels = Vec::with_capacity(usize::from(depth));
        for _ in 0..depth {
            let n = r.u64()?;
            if n > (r.bytes.len() / 9) as u64 {
                return Err(bad("a level longer than the bytes left"));
            }
            let mut level = Vec::with_capacity(n as usize);
            for _ in 0..n {
                let inner = r.u8()? == 1;
                let c = [r.u16()?, r.u16()?, r.u16()?, r.u16()?];
                level.push((inner, Unorm16Rgba(c)));
            }
            levels.push(level);
        }
        let blocks = match r.u8()? {
            0 => None,
            code => {
                let format =
                    BlockFormat::from_code(code).ok_or_else(|| bad("unknown block format"))?;
                let n = r.u64()?;
                if n > r.bytes.len() as u64 {
                    return Err(bad("more block flags than bytes left"));
                }
                let flags: Vec<bool> = r.take(n as usize)?.iter().map(|&f| f == 1).collect();
                let n = r.u64()?;
                if n > r.bytes.len() as u64 {
                    return Err(bad("more block data than bytes left"));
                }
                Some((format, flags, r.take(n as usize)?.to_vec()))
            }
        };
        if !r.bytes.is_empty() {
            return Err(bad("trailing bytes"));
        }
        // The shape: four children for every inner node above, one block
        // flag for every node of the block level, the texels of each block.
        let mut inner = u64::from(kind == Kind::Inner);
        for (i, level) in levels.iter().enumerate() {
            if level.len() as u64 != 4 * inner {
                return Err(bad(&format!(
                    "level {} does not hold four children per inner node",
                    i + 1
                )));
            }
            inner = level.iter().filter(|(i, _)| *i).count() as u64;
        }
        if inner != 0 {
            return Err(bad("inner nodes on the deepest level"));
        }
        if let Some((format, flags, data)) = &blocks {
            let block_level = side.trailing_zeros() as usize - usize::from(BLOCK_LOG2_SIDE);
            // A tile whose root is at the block level carries no flag for it
            // (the square above pushes it when splicing): its kind says.
            let (at, count) = if block_level == 0 {
                (0, usize::from(kind == Kind::Block))
            } else {
                let at = levels.get(block_level - 1).map_or(0, Vec::len);
                (at, flags.iter().filter(|&&f| f).count())
            };
            if flags.len() != at
                || data.len() != count * (format.bytes_per_texel() << (2 * BLOCK_LOG2_SIDE))
            {
                return Err(bad("block flags or texels do not match the block level"));
            }
        }
        Ok(PackedTile {
            stats,
            root,
            kind,
            levels,
            blocks,
            nodes,
            max_error,
            side,
            extent,
            own_format,
        })
    }
}

/// The error for a tile whose texels are 8-bit where the mosaic's blocks
/// are not, or the other way round.
pub(super) fn tile_format_error(
    row: u32,
    col: u32,
    found: BlockFormat,
    expected: BlockFormat,
) -> Error {
    let name = |f: BlockFormat| {
        if f.is_srgb8() {
            "8-bit"
        } else {
            "16-bit or float"
        }
    };
    Error::TileFormat {
        row,
        col,
        found: name(found),
        expected: name(expected),
    }
}

struct Reader<'a> {
    bytes: &'a [u8],
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], Error> {
        if self.bytes.len() < n {
            return Err(Error::MalformedTree("packed tile: truncated".into()));
        }
        let (head, rest) = self.bytes.split_at(n);
        self.bytes = rest;
        Ok(head)
    }
    fn u8(&mut self) -> Result<u8, Error> {
        Ok(self.take(1)?[0])
    }
    fn u16(&mut self) -> Result<u16, Error> {
        let b = self.take(2)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }
    fn u32(&mut self) -> Result<u32, Error> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    fn u64(&mut self) -> Result<u64, Error> {
        let b = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
}

/// CRC-32 (IEEE), bitwise: the core crate takes no dependency for it, and
/// a packed tile is checked once.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

impl BuildOptions {
    /// The tile context of a tile of `mosaic` holding `extent` texels;
    /// `nodes_before` and `fixed_bytes` as the builder holds them.
    pub(super) fn tile_context(
        &self,
        mosaic: &super::Mosaic,
        extent: (u32, u32),
        format: Option<BlockFormat>,
        nodes_before: u64,
        fixed_bytes: u64,
    ) -> TileContext {
        let depth = mosaic.side().trailing_zeros() as u8;
        TileContext {
            depth,
            extent,
            block_level: depth
                .checked_sub(BLOCK_LOG2_SIDE)
                .filter(|_| self.texel_blocks),
            format,
            tolerance: <Unorm16Rgba as Cell>::tolerance(self.tolerance),
            texel_blocks_allowed: self.texel_blocks,
            nodes_before,
            max_nodes: self.max_nodes,
            fixed_bytes,
            max_bytes: self.max_bytes,
        }
    }
}

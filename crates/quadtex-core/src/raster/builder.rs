//! The bottom-up pass: squares made terminal, inner or texel blocks,
//! the root's quarters packed apart on large textures, and tiles packed
//! one at a time.

use super::cells::{Cell, Stats};
use super::packed_tile::{PackedTile, tile_format_error};
use super::{BuildOptions, BuildReport, Mosaic, RASTER_KNOBS, TexelGrid};
use crate::Error;
use crate::colour::Unorm16Rgba;
use crate::memory::{BUILD_BYTES_PER_NODE, check_budget, try_push};
use crate::tree::texel_block::{BLOCK_LOG2_SIDE, BlockFormat, BlockWriter};
use crate::tree::{self, Aspect, MAX_DEPTH, QuadTree};

/// Where the squares of one level come from whole: tiles packed one at a
/// time (see [`QuadTree::from_tiles`]), or packed elsewhere
/// ([`QuadTree::from_packed_tiles`]).
pub(super) struct Tiles<'a> {
    /// How the texture is cut into tiles (its tile level's squares).
    pub(super) mosaic: Mosaic,
    pub(super) source: TileSource<'a>,
    /// The options the mosaic is packed with.
    pub(super) options: BuildOptions,
}

/// What a tile-level square is made from.
pub(super) enum TileSource<'a> {
    /// The tile's texels, `(row, col)`.
    Texels(&'a mut dyn FnMut(u32, u32) -> Result<TexelGrid, Error>),
    /// The tile packed elsewhere, `(row, col, format)`: `format`, when
    /// given, is the block format it must be packed in.
    Packed(&'a mut dyn FnMut(u32, u32, Option<BlockFormat>) -> Result<PackedTile, Error>),
}

/// What a square became.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    Terminal,
    Inner,
    /// Terminal, its texels in a block.
    Block,
}

pub(crate) struct Builder<'a, C: Cell = Unorm16Rgba> {
    pub(super) cells: &'a [C],
    /// The 8-bit source of `cells`, when blocks store it.
    pub(super) srgb8: Option<&'a [[u8; 4]]>,
    /// Texel blocks, when the tree is deep enough to have them.
    pub(super) blocks: Option<BlockWriter>,
    /// Whether tiles may make texel blocks ([`BuildOptions::texel_blocks`]).
    pub(super) texel_blocks_allowed: bool,
    pub(super) tiles: Option<Tiles<'a>>,
    pub(super) side: usize,
    pub(super) depth: u8,
    pub(super) tolerance: f64,
    pub(super) levels: Vec<Vec<(bool, Unorm16Rgba)>>,
    pub(super) nodes: u64,
    pub(super) max_nodes: u64,
    pub(super) max_error: f64,
    /// Bytes held before the tree grows (texels, cell grid).
    pub(super) fixed_bytes: u64,
    pub(super) max_bytes: Option<u64>,
    /// Where the texture lies in the tree's square; `side` × `rows` cells.
    pub(super) aspect: Aspect,
    pub(super) rows: usize,
    /// A texture of at least this many cells has its root's four quarters
    /// packed on threads of their own ([`Builder::quarters_apart`]).
    pub(super) parallel_cells: usize,
}

/// What a quarter's builder pushed ([`Builder::quarters_apart`]).
struct Quarter {
    levels: Vec<Vec<(bool, Unorm16Rgba)>>,
    blocks: Option<BlockWriter>,
    nodes: u64,
    max_error: f64,
}

impl Quarter {
    fn of<C: Cell>(b: Builder<'_, C>) -> Quarter {
        Quarter {
            levels: b.levels,
            blocks: b.blocks,
            nodes: b.nodes,
            max_error: b.max_error,
        }
    }
}

impl<C: Cell> Builder<'_, C> {
    /// Cell at `(ix, iz)` of the finest level, `iz` counted from the bottom.
    fn cell(&self, ix: usize, iz: usize) -> C {
        self.cells[(self.rows - 1 - iz) * self.side + ix]
    }

    /// Counts `n` more nodes, refused past the node limit or the memory
    /// budget.
    fn add_nodes(&mut self, n: u64) -> Result<(), Error> {
        self.nodes += n;
        if self.nodes > self.max_nodes {
            return Err(Error::TooManyNodes {
                nodes: self.nodes,
                max: self.max_nodes,
            });
        }
        let (nodes, depth) = (self.nodes, self.depth);
        check_budget(
            || format!("packing at level {depth} (stopped after {nodes} nodes)"),
            self.fixed_bytes + nodes * BUILD_BYTES_PER_NODE,
            self.max_bytes,
            RASTER_KNOBS,
        )
    }

    /// How many cells of the texture square `(level, ix, iz)` holds (cells
    /// of the pad excluded, [`Aspect`]).
    fn texture_cells(&self, level: u8, ix: usize, iz: usize) -> u64 {
        let shift = self.depth - level;
        let count = |i: usize, n: usize| {
            let lo = (i as u64) << shift;
            ((lo + (1u64 << shift)).min(n as u64)).saturating_sub(lo)
        };
        count(ix, self.side) * count(iz, self.rows)
    }

    /// Builds the subtree of square `(level, ix, iz)`: returns its stats and
    /// its colour and kind; pushes its descendants if it is inner.
    /// `None` for a square of the pad (its parent gives it a colour).
    pub(super) fn square(
        &mut self,
        level: u8,
        ix: usize,
        iz: usize,
    ) -> Result<Option<(C::Stats, Unorm16Rgba, Kind)>, Error> {
        if self.aspect.is_pad(level, ix as u32, iz as u32) {
            return Ok(None);
        }
        if self
            .tiles
            .as_ref()
            .is_some_and(|t| t.mosaic.tile_level() == level)
        {
            return C::tile(self, level, ix, iz).map(Some);
        }
        if level == self.depth {
            let c = self.cell(ix, iz);
            return Ok(Some((c.stats(), c.stored(), Kind::Terminal)));
        }
        let mut marks = [0usize; MAX_DEPTH as usize + 1];
        for (m, l) in marks.iter_mut().zip(&self.levels[usize::from(level) + 1..]) {
            *m = l.len();
        }
        let block_marks = self.blocks.as_ref().map(|b| (b.flags.len(), b.data.len()));
        let mut parts = [None; 4];
        let mut children = [None; 4];
        let mut take = |k: usize, child: Option<(C::Stats, Unorm16Rgba, Kind)>| {
            if let Some((s, c, kind)) = child {
                parts[k] = Some(s);
                children[k] = Some((c, kind));
            }
        };
        if level == 0 && self.may_build_quarters_apart() {
            for (k, child) in self.quarters_apart(ix, iz)?.into_iter().enumerate() {
                take(k, child);
            }
        } else {
            for k in 0..4 {
                take(
                    k,
                    self.square(level + 1, 2 * ix + (k & 1), 2 * iz + (k >> 1))?,
                );
            }
        }
        let Some(stats) = C::merge(parts) else {
            return Ok(None);
        };
        let mean = C::mean(&stats, self.texture_cells(level, ix, iz));
        // Pad children carry the mean, so the parent stays their average.
        let children = children.map(|c| c.unwrap_or((mean, Kind::Terminal)));
        let deviation = C::deviation(&stats, mean);
        let discard = |b: &mut Self| {
            for (l, &m) in b.levels[usize::from(level) + 1..].iter_mut().zip(&marks) {
                b.nodes -= (l.len() - m) as u64;
                l.truncate(m);
            }
            if let (Some(w), Some((flags, data))) = (b.blocks.as_mut(), block_marks) {
                w.flags.truncate(flags);
                w.data.truncate(data);
            }
        };
        if deviation <= self.tolerance {
            self.max_error = self.max_error.max(deviation);
            // Discard descendants the children pushed (only possible with a tolerance).
            discard(self);
            return Ok(Some((stats, mean, Kind::Terminal)));
        }
        if let Some(w) = self.blocks.as_ref().filter(|w| w.level == level) {
            // A block where its texels cost no more than the nodes below.
            let below = 4 + self.levels[usize::from(level) + 1..]
                .iter()
                .zip(&marks)
                .map(|(l, &m)| (l.len() - m) as u64)
                .sum::<u64>();
            if below * 8 >= w.block_bytes() as u64 {
                discard(self);
                self.write_block(ix, iz)?;
                return Ok(Some((stats, mean, Kind::Block)));
            }
        }
        self.add_nodes(4)?;
        let next = &mut self.levels[usize::from(level) + 1];
        for (c, kind) in children {
            try_push(next, (kind == Kind::Inner, c), "tree level")?;
        }
        if let Some(w) = self.blocks.as_mut().filter(|w| w.level == level + 1) {
            for (_, kind) in children {
                try_push(&mut w.flags, kind == Kind::Block, "texel block flags")?;
            }
        }
        Ok(Some((stats, mean, Kind::Inner)))
    }

    /// The four children of the root square `(0, ix, iz)` (child `k` at
    /// `(2·ix + k mod 2, 2·iz + k div 2)`), built on four threads, each by
    /// a builder of its own, then spliced in order: a child's subtree
    /// pushes its nodes, block flags and block texels after those of the
    /// children before it, so the levels are the sequential build's, node
    /// for node. Only for a texture of at least `parallel_cells` cells and
    /// when the limits cannot be reached whatever the texture
    /// ([`Builder::may_build_quarters_apart`]): a quarter's own count
    /// cannot tell it the whole tree's.
    #[allow(clippy::type_complexity)]
    fn quarters_apart(
        &mut self,
        ix: usize,
        iz: usize,
    ) -> Result<[Option<(C::Stats, Unorm16Rgba, Kind)>; 4], Error> {
        let mut out = [None; 4];
        // The parts a quarter's builder needs, without the tile loader
        // (which no thread may share).
        let (cells, srgb8, depth, rows, side) =
            (self.cells, self.srgb8, self.depth, self.rows, self.side);
        let (tolerance, max_nodes, fixed_bytes, max_bytes, aspect) = (
            self.tolerance,
            self.max_nodes,
            self.fixed_bytes,
            self.max_bytes,
            self.aspect,
        );
        let (levels, allowed) = (self.levels.len(), self.texel_blocks_allowed);
        let blocks = self.blocks.as_ref().map(|w| (w.level, w.format));
        let built: Vec<Result<_, Error>> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..4)
                .map(|k| {
                    scope.spawn(move || {
                        let mut b = Builder {
                            cells,
                            srgb8,
                            blocks: blocks.map(|(level, format)| BlockWriter {
                                level,
                                format,
                                flags: Vec::new(),
                                data: Vec::new(),
                            }),
                            texel_blocks_allowed: allowed,
                            tiles: None,
                            side,
                            depth,
                            tolerance,
                            levels: vec![Vec::new(); levels],
                            nodes: 0,
                            max_nodes,
                            max_error: 0.0,
                            fixed_bytes,
                            max_bytes,
                            aspect,
                            rows,
                            parallel_cells: usize::MAX,
                        };
                        let child = b.square(1, 2 * ix + (k & 1), 2 * iz + (k >> 1))?;
                        Ok((child, Quarter::of(b)))
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
                .collect()
        });
        for (k, result) in built.into_iter().enumerate() {
            let (child, quarter) = result?;
            out[k] = child;
            self.splice(quarter)?;
        }
        Ok(out)
    }

    /// Whether the root's quarters may be built apart: a texture of
    /// `parallel_cells` or more, no tiles, and no limit reachable.
    fn may_build_quarters_apart(&self) -> bool {
        let cells = self.side.saturating_mul(self.rows);
        if self.tiles.is_some() || cells < self.parallel_cells {
            return false;
        }
        // Every square of the tree's square split down to cells.
        let all_nodes = ((1u128 << (2 * (u32::from(self.depth) + 1))) - 1) / 3;
        let nodes = u128::from(self.nodes) + all_nodes;
        nodes <= u128::from(self.max_nodes)
            && self.max_bytes.is_none_or(|budget| {
                u128::from(self.fixed_bytes) + nodes * u128::from(BUILD_BYTES_PER_NODE)
                    <= u128::from(budget)
            })
    }

    /// Appends what a quarter's builder pushed (levels, block flags and
    /// texels) after what this one holds, and its counts.
    fn splice(&mut self, b: Quarter) -> Result<(), Error> {
        self.nodes += b.nodes;
        self.max_error = self.max_error.max(b.max_error);
        if let (Some(w), Some(sub)) = (self.blocks.as_mut(), b.blocks) {
            w.flags.try_reserve(sub.flags.len()).map_err(|_| {
                crate::memory::refused::<bool>("texel block flags", sub.flags.len())
            })?;
            w.flags.extend(sub.flags);
            w.data
                .try_reserve(sub.data.len())
                .map_err(|_| crate::memory::refused::<u8>("texel blocks", sub.data.len()))?;
            w.data.extend(sub.data);
        }
        for (level, sub) in self.levels.iter_mut().zip(b.levels) {
            level.try_reserve(sub.len()).map_err(|_| {
                crate::memory::refused::<(bool, Unorm16Rgba)>("tree level", sub.len())
            })?;
            level.extend(sub);
        }
        Ok(())
    }

    /// Appends the texels of the square `(level, ix, iz)` at the block
    /// level as a block: rows from the bottom.
    fn write_block(&mut self, ix: usize, iz: usize) -> Result<(), Error> {
        let Some(w) = self.blocks.as_mut() else {
            return Ok(());
        };
        let side = 1usize << BLOCK_LOG2_SIDE;
        let bytes = w.block_bytes();
        w.data
            .try_reserve(bytes)
            .map_err(|_| Error::AllocationFailed {
                what: "texel blocks".into(),
                bytes: (w.data.len() + bytes) as u64,
            })?;
        for tz in iz * side..(iz + 1) * side {
            for tx in ix * side..(ix + 1) * side {
                // A block across the texture's edge repeats the edge's texels
                // in the pad (never read; see `Aspect`).
                let (tx, tz) = (tx.min(self.side - 1), tz.min(self.rows - 1));
                let i = (self.rows - 1 - tz) * self.side + tx;
                match (w.format.is_srgb8(), self.srgb8) {
                    (true, Some(src)) => w.format.put_srgb8(&mut w.data, src[i]),
                    _ => {
                        for v in self.cells[i].stored().0 {
                            w.data.extend(v.to_le_bytes());
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

impl<C: Cell> Builder<'_, C> {
    /// Builds the whole tree from the root; `resampled` goes to the report.
    pub(super) fn build(mut self, resampled: bool) -> Result<(QuadTree, BuildReport), Error> {
        let Some((_, root, kind)) = self.square(0, 0, 0)? else {
            return Err(Error::MalformedTree(
                "the texture lies wholly in the pad".into(),
            ));
        };
        self.levels[0].push((kind == Kind::Inner, root));
        if let Some(w) = self.blocks.as_mut().filter(|w| w.level == 0) {
            w.flags.push(kind == Kind::Block);
        }
        while self.levels.last().is_some_and(Vec::is_empty) {
            self.levels.pop();
        }
        let report = BuildReport {
            cell_depth: self.depth,
            resampled,
            max_error: self.max_error,
        };
        let texel_blocks = match self.blocks {
            Some(w) => w.finish()?,
            None => None,
        };
        Ok((
            tree::from_levels_encoded(self.levels, self.aspect, texel_blocks, C::ENCODING)?,
            report,
        ))
    }
}

impl Builder<'_, Unorm16Rgba> {
    /// Square `(level, ix, iz)` as a whole tile: loads it and packs it on
    /// its own (or takes it packed elsewhere), then splices its levels below
    /// this one (breadth-first order holds: squares are visited in the
    /// order their level lists them).
    pub(super) fn tile(
        &mut self,
        level: u8,
        ix: usize,
        iz: usize,
    ) -> Result<(Stats, Unorm16Rgba, Kind), Error> {
        let Some(tiles) = self.tiles.as_mut() else {
            return Err(Error::MalformedTree("no tiles".into()));
        };
        let mosaic = tiles.mosaic;
        let (n, side) = (1u32 << level, mosaic.side());
        let (row, col) = (n - 1 - iz as u32, ix as u32);
        // Squares wholly in the pad never get here.
        let extent = mosaic
            .tile_extent(row, col)
            .ok_or_else(|| Error::MalformedTree(format!("tile ({row}, {col}) lies in the pad")))?;
        // The first tile fixes the blocks' format; the others must agree,
        // 8-bit tiles sharing the widest of their formats.
        let global = self.blocks.as_ref().map(|w| w.format);
        let wrong_size = |w: u32, h: u32| Error::BadDimensions {
            width: w.into(),
            height: h.into(),
            reason: "not the size of the mosaic's tile there",
        };
        let packed = match &mut tiles.source {
            TileSource::Texels(load) => {
                let grid = load(row, col)?;
                if grid.is_hdr() {
                    return Err(Error::HdrTile { row, col });
                }
                if (grid.width, grid.height) != extent {
                    return Err(wrong_size(grid.width, grid.height));
                }
                let context = tiles.options.tile_context(
                    &mosaic,
                    extent,
                    global,
                    self.nodes,
                    self.fixed_bytes,
                );
                PackedTile::pack(&grid, (row, col), &context)?
            }
            TileSource::Packed(load) => {
                let packed = load(row, col, None)?;
                if packed.side != side || packed.extent != extent {
                    return Err(wrong_size(packed.extent.0, packed.extent.1));
                }
                // Packed in its own format: the sequential build writes it in
                // the widest of those before it too.
                match (global, packed.own_format) {
                    (Some(g), Some(own)) if g.is_srgb8() != own.is_srgb8() => {
                        return Err(tile_format_error(row, col, own, g));
                    }
                    (Some(g), Some(own)) if packed.block_format() != Some(g.widest(own)) => {
                        let again = load(row, col, Some(g.widest(own)))?;
                        if again.block_format() != Some(g.widest(own))
                            || again.side != side
                            || again.extent != extent
                        {
                            return Err(Error::MalformedTree(format!(
                                "tile ({row}, {col}) was packed again in another block format than asked"
                            )));
                        }
                        again
                    }
                    _ => packed,
                }
            }
        };
        self.splice_tile(level, packed)
    }

    /// Appends a packed tile's blocks, levels and counts below square
    /// `level`; returns what the square above it needs.
    fn splice_tile(
        &mut self,
        level: u8,
        packed: PackedTile,
    ) -> Result<(Stats, Unorm16Rgba, Kind), Error> {
        self.add_nodes(packed.nodes)?;
        self.max_error = self.max_error.max(packed.max_error);
        if let Some((format, flags, data)) = packed.blocks {
            let w = match self.blocks.as_mut() {
                Some(w) => {
                    w.widen(w.format.widest(format))?;
                    w
                }
                None => self.blocks.insert(BlockWriter {
                    level: self.depth - BLOCK_LOG2_SIDE,
                    format,
                    flags: Vec::new(),
                    data: Vec::new(),
                }),
            };
            w.flags.extend(flags);
            w.data
                .try_reserve(data.len())
                .map_err(|_| Error::AllocationFailed {
                    what: "texel blocks".into(),
                    bytes: (w.data.len() + data.len()) as u64,
                })?;
            w.data.extend(data);
        }
        for (below, tile_level) in self.levels[usize::from(level) + 1..]
            .iter_mut()
            .zip(packed.levels)
        {
            below
                .try_reserve(tile_level.len())
                .map_err(|_| Error::AllocationFailed {
                    what: "tree level".into(),
                    bytes: (tile_level.len() * std::mem::size_of::<(bool, Unorm16Rgba)>()) as u64,
                })?;
            below.extend(tile_level);
        }
        Ok((packed.stats, packed.root, packed.kind))
    }
}

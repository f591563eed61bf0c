//! Packing a raster into an incomplete quadtree.
//!
//! The raster is first brought onto a grid of *cells*, the squares of the
//! deepest level `D` that cover the texture: `2^a × 2^b` of them for a
//! `W × H` image, `a = ⌈log2 W⌉`, `b = ⌈log2 H⌉`, `D = max(a, b)`; a
//! non-square texture covers part of the tree's square (see
//! [`Aspect`]), so a strip costs its own cells, not the square around it.
//! When the image is already that size, cells are texels. Otherwise every
//! cell stores the exact area-weighted mean of the texels it overlaps
//! (texels are rectangles of the unit square, see the crate conventions), so
//! a square that straddles texel borders is exact on average.
//!
//! Then one bottom-up pass computes, for every square, the integer sum, the
//! minimum and the maximum of its cells per channel. A square is **terminal**
//! iff every cell lies within the tolerance `T` of the square's (rounded)
//! mean in every channel (the L∞ metric on linear, premultiplied
//! channels, in units of full scale); with `T = 0` iff all its cells are equal.
//! An inner square's colour is the rounded exact mean of all its cells, so
//! rounding never accumulates up the tree.

use crate::Error;
use crate::colour::{ColourEncoding, Rgba, Unorm16Rgba};
use crate::memory::{BUILD_BYTES_PER_NODE, check_budget, try_push, try_vec};
use crate::tree::texel_block::{BLOCK_LOG2_SIDE, BlockFormat, BlockWriter};
use crate::tree::{self, Aspect, MAX_DEPTH, MAX_NODES, QuadTree};

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
/// grid `(columns, rows)`: the image's own power-of-two shape, as deep as
/// `depth` allows on the long side.
pub fn raster_cells(width: u32, height: u32, depth: u8) -> (Aspect, usize, usize) {
    let aspect = Aspect::of_grid(ceil_log2(width), ceil_log2(height));
    let [sx, sz] = aspect.shrink().map(|s| s.min(depth));
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
    /// True when cells are not the texels themselves (non-power-of-two or
    /// resized input): each cell then holds an area-weighted mean.
    pub resampled: bool,
    /// Largest deviation, per channel in full-scale units, between a cell and
    /// the colour of the terminal square that holds it. `0` when lossless.
    pub max_error: f64,
}

/// A finest cell as the packer reads it: its stored colour, and how the
/// bottom-up pass sums squares of them.
pub(crate) trait Cell: Copy + Send + Sync {
    /// Per-square statistics of the bottom-up pass.
    type Stats: Copy + Send;
    /// How the tree stores the colours made of these cells.
    const ENCODING: ColourEncoding;
    /// The stored colour of a terminal cell.
    fn stored(self) -> Unorm16Rgba;
    /// The statistics of one cell.
    fn stats(self) -> Self::Stats;
    /// The stats of the parts present (`None` when none is).
    fn merge(parts: [Option<Self::Stats>; 4]) -> Option<Self::Stats>;
    /// The rounded mean over `2^log2_cells` cells, as stored.
    fn mean(s: &Self::Stats, log2_cells: u32) -> Unorm16Rgba;
    /// Largest deviation of any cell from the stored `mean`, per channel,
    /// in full-scale units (`1` = an LDR channel's range).
    fn deviation(s: &Self::Stats, mean: Unorm16Rgba) -> f64;
    /// The tolerance as the pass compares it: unorm16 rounds it down to
    /// whole steps.
    fn tolerance(t: f64) -> f64;
    /// Square `(level, ix, iz)` as a whole tile ([`QuadTree::from_tiles`]).
    fn tile(
        b: &mut Builder<'_, Self>,
        level: u8,
        ix: usize,
        iz: usize,
    ) -> Result<(Self::Stats, Unorm16Rgba, Kind), Error>;
}

/// Sums, minima and maxima of unorm16 cells.
#[derive(Clone, Copy)]
pub(crate) struct Stats {
    sum: [u64; 4],
    min: [u16; 4],
    max: [u16; 4],
}

impl Cell for Unorm16Rgba {
    type Stats = Stats;
    const ENCODING: ColourEncoding = ColourEncoding::Unorm16;
    fn stored(self) -> Unorm16Rgba {
        self
    }
    fn stats(self) -> Stats {
        Stats {
            sum: self.0.map(u64::from),
            min: self.0,
            max: self.0,
        }
    }
    fn merge(parts: [Option<Stats>; 4]) -> Option<Stats> {
        let mut present = parts.into_iter().flatten();
        let mut s = present.next()?;
        for p in present {
            for ch in 0..4 {
                s.sum[ch] += p.sum[ch];
                s.min[ch] = s.min[ch].min(p.min[ch]);
                s.max[ch] = s.max[ch].max(p.max[ch]);
            }
        }
        Some(s)
    }
    fn mean(s: &Stats, log2_cells: u32) -> Unorm16Rgba {
        let shift = log2_cells;
        let half = if shift == 0 { 0 } else { 1u64 << (shift - 1) };
        Unorm16Rgba(s.sum.map(|v| ((v + half) >> shift) as u16))
    }
    fn deviation(s: &Stats, mean: Unorm16Rgba) -> f64 {
        let steps = (0..4)
            .map(|ch| (s.max[ch] - mean.0[ch]).max(mean.0[ch] - s.min[ch]))
            .max()
            .unwrap_or(0);
        f64::from(steps) / 65535.0
    }
    fn tolerance(t: f64) -> f64 {
        (t * 65535.0).floor().min(65535.0) / 65535.0
    }
    fn tile(
        b: &mut Builder<'_, Self>,
        level: u8,
        ix: usize,
        iz: usize,
    ) -> Result<(Stats, Unorm16Rgba, Kind), Error> {
        b.tile(level, ix, iz)
    }
}

/// A cell of an HDR texture: four half floats (linear, premultiplied,
/// unclamped colour, alpha in `[0, 1]`), as the tree stores them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct HalfRgba(pub(crate) [u16; 4]);

/// Sums, minima and maxima of half-float cells, in `f64`.
#[derive(Clone, Copy)]
pub(crate) struct HalfStats {
    sum: [f64; 4],
    min: [f64; 4],
    max: [f64; 4],
}

impl Cell for HalfRgba {
    type Stats = HalfStats;
    const ENCODING: ColourEncoding = ColourEncoding::Half;
    fn stored(self) -> Unorm16Rgba {
        Unorm16Rgba(self.0)
    }
    fn stats(self) -> HalfStats {
        let v = ColourEncoding::Half.decode_colour(Unorm16Rgba(self.0));
        HalfStats {
            sum: v,
            min: v,
            max: v,
        }
    }
    fn merge(parts: [Option<HalfStats>; 4]) -> Option<HalfStats> {
        let mut present = parts.into_iter().flatten();
        let mut s = present.next()?;
        for p in present {
            for ch in 0..4 {
                s.sum[ch] += p.sum[ch];
                s.min[ch] = s.min[ch].min(p.min[ch]);
                s.max[ch] = s.max[ch].max(p.max[ch]);
            }
        }
        Some(s)
    }
    fn mean(s: &HalfStats, log2_cells: u32) -> Unorm16Rgba {
        // Sums of halves over at most 2^60 cells: exact enough in f64,
        // and a power-of-two division is exact.
        let n = f64::from_bits((1023 + u64::from(log2_cells)) << 52);
        Unorm16Rgba(s.sum.map(|v| ColourEncoding::Half.encode(v / n)))
    }
    fn deviation(s: &HalfStats, mean: Unorm16Rgba) -> f64 {
        let m = ColourEncoding::Half.decode_colour(mean);
        (0..4)
            .map(|ch| (s.max[ch] - m[ch]).max(m[ch] - s.min[ch]))
            .fold(0.0, f64::max)
    }
    fn tolerance(t: f64) -> f64 {
        t
    }
    fn tile(
        _: &mut Builder<'_, Self>,
        _: u8,
        _: usize,
        _: usize,
    ) -> Result<(HalfStats, Unorm16Rgba, Kind), Error> {
        Err(Error::MalformedTree(
            "HDR textures are not packed from tiles".into(),
        ))
    }
}

/// Where the squares of one level come from whole: tiles packed one at a
/// time (see [`QuadTree::from_tiles`]).
struct Tiles<'a> {
    /// The level whose squares are tiles (`2^level` tiles a side).
    level: u8,
    /// Texels on a tile's side.
    side: u32,
    load: &'a mut dyn FnMut(u32, u32) -> Result<TexelGrid, Error>,
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
    cells: &'a [C],
    /// The 8-bit source of `cells`, when blocks store it.
    srgb8: Option<&'a [[u8; 4]]>,
    /// Texel blocks, when the tree is deep enough to have them.
    blocks: Option<BlockWriter>,
    /// Whether tiles may make texel blocks ([`BuildOptions::texel_blocks`]).
    texel_blocks_allowed: bool,
    tiles: Option<Tiles<'a>>,
    side: usize,
    depth: u8,
    tolerance: f64,
    levels: Vec<Vec<(bool, Unorm16Rgba)>>,
    nodes: u64,
    max_nodes: u64,
    max_error: f64,
    /// Bytes held before the tree grows (texels, cell grid).
    fixed_bytes: u64,
    max_bytes: Option<u64>,
    /// Where the texture lies in the tree's square; `side` × `rows` cells.
    aspect: Aspect,
    rows: usize,
    /// A texture of at least this many cells has its root's four quarters
    /// packed on threads of their own ([`Builder::quarters_apart`]).
    parallel_cells: usize,
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

    /// Builds the subtree of square `(level, ix, iz)`: returns its stats and
    /// its colour and kind; pushes its descendants if it is inner.
    /// `None` for a square of the pad (its parent gives it a colour).
    fn square(
        &mut self,
        level: u8,
        ix: usize,
        iz: usize,
    ) -> Result<Option<(C::Stats, Unorm16Rgba, Kind)>, Error> {
        if self.aspect.is_pad(level, ix as u32, iz as u32) {
            return Ok(None);
        }
        if self.tiles.as_ref().is_some_and(|t| t.level == level) {
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
        // Cells of the texture under this square: a power of two on each axis.
        let [sx, sz] = self.aspect.shrink();
        let below = u32::from(self.depth - level);
        let log2_cells =
            below.min(u32::from(self.depth - sx)) + below.min(u32::from(self.depth - sz));
        let mean = C::mean(&stats, log2_cells);
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
        self.nodes += 4;
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
        )?;
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
    fn build(mut self, resampled: bool) -> Result<(QuadTree, BuildReport), Error> {
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
    /// Square `(level, ix, iz)` as a whole tile: loads it, packs it on its
    /// own and splices its levels below this one (breadth-first order holds:
    /// squares are visited in the order their level lists them).
    fn tile(
        &mut self,
        level: u8,
        ix: usize,
        iz: usize,
    ) -> Result<(Stats, Unorm16Rgba, Kind), Error> {
        let Some(tiles) = self.tiles.as_mut() else {
            return Err(Error::MalformedTree("no tiles".into()));
        };
        let (n, side) = (1u32 << level, tiles.side);
        let (row, col) = (n - 1 - iz as u32, ix as u32);
        let grid = (tiles.load)(row, col)?;
        if grid.is_hdr() {
            // Tiles are packed as unorm16 or 8-bit: an HDR tile would be clamped.
            return Err(Error::HdrTile { row, col });
        }
        if (grid.width, grid.height) != (side, side) {
            return Err(Error::BadDimensions {
                width: grid.width.into(),
                height: grid.height.into(),
                reason: "not the size of the first tile (tiles must all be the same square)",
            });
        }
        let depth = self.depth - level;
        // The first tile fixes the blocks' format; the others must agree.
        let format = block_format(&grid, false);
        let block_level = self
            .depth
            .checked_sub(BLOCK_LOG2_SIDE)
            .filter(|&l| l >= level && self.texel_blocks_allowed);
        let sub_blocks = match (block_level, self.blocks.as_mut()) {
            (None, _) => None,
            (Some(_), Some(w)) if w.format.is_srgb8() != format.is_srgb8() => {
                let name = |f: BlockFormat| {
                    if f.is_srgb8() {
                        "8-bit"
                    } else {
                        "16-bit or float"
                    }
                };
                return Err(Error::TileFormat {
                    row,
                    col,
                    found: name(format),
                    expected: name(w.format),
                });
            }
            (Some(l), w) => {
                // 8-bit tiles share the widest of their formats.
                let format = match w {
                    Some(w) => {
                        w.widen(w.format.widest(format))?;
                        w.format
                    }
                    None => format,
                };
                if self.blocks.is_none() {
                    self.blocks = Some(BlockWriter {
                        level: l,
                        format,
                        flags: Vec::new(),
                        data: Vec::new(),
                    });
                }
                Some(BlockWriter {
                    level: l - level,
                    format,
                    flags: Vec::new(),
                    data: Vec::new(),
                })
            }
        };
        let mut b = Builder {
            cells: &grid.texels,
            srgb8: grid.srgb8.as_deref(),
            blocks: sub_blocks,
            texel_blocks_allowed: self.texel_blocks_allowed,
            tiles: None,
            side: side as usize,
            depth,
            tolerance: self.tolerance,
            levels: vec![Vec::new(); usize::from(depth) + 1],
            nodes: self.nodes,
            max_nodes: self.max_nodes,
            max_error: self.max_error,
            fixed_bytes: self.fixed_bytes,
            max_bytes: self.max_bytes,
            aspect: Aspect::SQUARE,
            rows: side as usize,
            parallel_cells: usize::MAX,
        };
        let Some((stats, root, kind)) = b.square(0, 0, 0)? else {
            return Err(Error::MalformedTree("a tile lies wholly in the pad".into()));
        };
        self.nodes = b.nodes;
        self.max_error = b.max_error;
        if let (Some(w), Some(sub)) = (self.blocks.as_mut(), b.blocks) {
            w.flags.extend(sub.flags);
            w.data
                .try_reserve(sub.data.len())
                .map_err(|_| Error::AllocationFailed {
                    what: "texel blocks".into(),
                    bytes: (w.data.len() + sub.data.len()) as u64,
                })?;
            w.data.extend(sub.data);
        }
        for (below, tile_level) in self.levels[usize::from(level) + 1..]
            .iter_mut()
            .zip(b.levels.into_iter().skip(1))
        {
            below
                .try_reserve(tile_level.len())
                .map_err(|_| Error::AllocationFailed {
                    what: "tree level".into(),
                    bytes: (tile_level.len() * std::mem::size_of::<(bool, Unorm16Rgba)>()) as u64,
                })?;
            below.extend(tile_level);
        }
        Ok((stats, root, kind))
    }
}

impl QuadTree {
    /// Packs a square grid of square tiles into one tree without holding
    /// more than one tile's texels: `tiles × tiles` tiles (a power of two),
    /// each `side × side` texels (a power of two), tile `(row, col)` (row 0
    /// at the top) returned by `load` when the packer reaches it, in Morton
    /// order. The result is the tree [`QuadTree::from_texels`] would build
    /// from the whole mosaic, losslessly or to `options.tolerance`;
    /// `options.max_level` must be `None` (the depth is the mosaic's). The
    /// budget covers one tile's texels and the nodes so far. A tile of
    /// another size, or any error `load` returns, stops the build.
    pub fn from_tiles(
        tiles: u32,
        side: u32,
        options: &BuildOptions,
        load: &mut dyn FnMut(u32, u32) -> Result<TexelGrid, Error>,
    ) -> Result<(QuadTree, BuildReport), Error> {
        if !(options.tolerance.is_finite() && options.tolerance >= 0.0) {
            return Err(Error::BadTolerance(options.tolerance));
        }
        if !tiles.is_power_of_two() || !side.is_power_of_two() || side > MAX_DIMENSION {
            return Err(Error::BadDimensions {
                width: u64::from(tiles),
                height: u64::from(side),
                reason: "tiles a side and texels a tile side must be powers of two",
            });
        }
        if side < 1 << BLOCK_LOG2_SIDE {
            return Err(Error::BadDimensions {
                width: u64::from(side),
                height: u64::from(side),
                reason: "tiles must be at least 4x4 texels",
            });
        }
        if options.max_level.is_some() {
            return Err(Error::BadDimensions {
                width: u64::from(tiles) * u64::from(side),
                height: u64::from(tiles) * u64::from(side),
                reason: "a tiled texture is packed at its own depth (no max level)",
            });
        }
        let level = tiles.trailing_zeros() as u8;
        let depth = level + side.trailing_zeros() as u8;
        if depth > MAX_DEPTH {
            return Err(Error::DepthTooLarge {
                depth: depth.into(),
                max: MAX_DEPTH.into(),
            });
        }
        let fixed_bytes = 8 * u64::from(side) * u64::from(side);
        check_budget(
            || format!("packing {tiles}x{tiles} tiles of {side}x{side} texels"),
            fixed_bytes + BUILD_BYTES_PER_NODE,
            options.max_bytes,
            RASTER_KNOBS,
        )?;
        let b = Builder::<Unorm16Rgba> {
            cells: &[],
            srgb8: None,
            // Made when the first tile shows the format.
            blocks: None,
            texel_blocks_allowed: options.texel_blocks,
            tiles: Some(Tiles { level, side, load }),
            side: 0,
            depth,
            tolerance: Unorm16Rgba::tolerance(options.tolerance),
            levels: vec![Vec::new(); usize::from(depth) + 1],
            nodes: 1,
            max_nodes: options.max_nodes,
            max_error: 0.0,
            fixed_bytes,
            max_bytes: options.max_bytes,
            aspect: Aspect::SQUARE,
            rows: 0,
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
        // Blocks where the block level lies wholly in the texture.
        let blocks = depth
            .checked_sub(BLOCK_LOG2_SIDE)
            .filter(|_| options.texel_blocks)
            .filter(|&l| aspect.shrink().iter().all(|&s| s <= l))
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

/// [`try_resample`] onto a square, for callers that check sizes first (the
/// mip pyramid): an allocation failure aborts, as `vec!` does.
pub(crate) fn resample(grid: &TexelGrid, side: usize) -> Vec<Unorm16Rgba> {
    match try_resample(grid, side, side) {
        Ok(cells) => cells,
        Err(_) => std::alloc::handle_alloc_error(std::alloc::Layout::new::<[f32; 4]>()),
    }
}

/// Exact area-weighted resampling of the texels onto a `columns × rows`
/// cell grid (row 0 at the top).
fn try_resample(
    grid: &TexelGrid,
    columns: usize,
    rows_out: usize,
) -> Result<Vec<Unorm16Rgba>, Error> {
    resample_with(
        (grid.width as usize, grid.height as usize),
        (columns, rows_out),
        |i| grid.texels[i].0.map(f32::from),
        |acc| {
            let q = acc.map(|v| (v + 0.5).clamp(0.0, 65535.0) as u16);
            let a = q[3];
            Unorm16Rgba([q[0].min(a), q[1].min(a), q[2].min(a), a])
        },
    )
}

/// Exact area-weighted resampling of `width × height` texels (`texel(i)`,
/// row-major from the top) onto `columns × rows` cells, each made by `cell`
/// from its weighted sum: a horizontal pass into `f32` rows, then a
/// vertical one.
fn resample_with<T: Copy + Default>(
    (width, height): (usize, usize),
    (columns, rows_out): (usize, usize),
    texel: impl Fn(usize) -> [f32; 4],
    cell: impl Fn([f32; 4]) -> T,
) -> Result<Vec<T>, Error> {
    let side = columns;
    let xw = weights_1d(width, columns);
    let zw = weights_1d(height, rows_out);
    let mut rows = try_vec(height * side, [0f32; 4], "resampling rows")?;
    for row in 0..height {
        for (cx, taps) in xw.iter().enumerate() {
            let mut acc = [0f32; 4];
            for &(col, wgt) in taps {
                for (a, c) in acc.iter_mut().zip(texel(row * width + col)) {
                    *a += wgt * c;
                }
            }
            rows[row * side + cx] = acc;
        }
    }
    let mut out = try_vec(side * rows_out, T::default(), "cell grid")?;
    for (cz, taps) in zw.iter().enumerate() {
        for cx in 0..side {
            let mut acc = [0f32; 4];
            for &(row, wgt) in taps {
                for (a, &c) in acc.iter_mut().zip(&rows[row * side + cx]) {
                    *a += wgt * c;
                }
            }
            out[cz * side + cx] = cell(acc);
        }
    }
    Ok(out)
}

/// For each of `cells` equal cells of `[0,1)`, the texels (of `texels` equal
/// ones) it overlaps and the fraction of the cell each covers.
fn weights_1d(texels: usize, cells: usize) -> Vec<Vec<(usize, f32)>> {
    (0..cells)
        .map(|c| {
            // In units of 1/(texels·cells): cell c spans [c·texels, (c+1)·texels), texel t [t·cells, (t+1)·cells).
            let (lo, hi) = (c * texels, (c + 1) * texels);
            (lo / cells..hi.div_ceil(cells))
                .filter_map(|t| {
                    let overlap = hi.min((t + 1) * cells) - lo.max(t * cells);
                    (overlap > 0).then_some((t, overlap as f32 / texels as f32))
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A mosaic with uniform regions, edges and noise: `(col, row)` texel.
    fn mosaic_texel(col: u32, row: u32) -> Rgba {
        let h = (col.wrapping_mul(2_654_435_761) ^ row.wrapping_mul(40_503)) % 7;
        if col < 20 && row < 12 {
            Rgba::opaque(0.2, 0.4, 0.6)
        } else if (col / 3 + row / 5).is_multiple_of(2) {
            Rgba::new(0.5, 0.25, 0.0, 0.5)
        } else {
            Rgba::opaque(h as f32 / 7.0, 0.1, 0.9)
        }
    }

    /// The root's quarters built on threads give the sequential build's
    /// tree and report: rasters square and not (pad quarters), with and
    /// without texel blocks, a tolerance, HDR; a node limit the whole tree
    /// could reach keeps the build sequential and its error.
    #[test]
    fn quarters_built_apart_make_the_sequential_tree() {
        let hdr = |w: u32, h: u32| {
            let mut g = TexelGrid::from_fn(w, h, mosaic_texel).unwrap();
            let half = (0..w * h)
                .map(|i| {
                    let v = f64::from(i % 97) * 0.37;
                    let c = ColourEncoding::Half.encode(v);
                    HalfRgba([c, c, c, ColourEncoding::Half.encode(1.0)])
                })
                .collect();
            g.half = Some(half);
            g
        };
        let cases = [
            (TexelGrid::from_fn(64, 64, mosaic_texel).unwrap(), true, 0.0),
            (
                TexelGrid::from_fn(64, 64, mosaic_texel).unwrap(),
                false,
                0.0,
            ),
            (
                TexelGrid::from_fn(128, 32, mosaic_texel).unwrap(),
                true,
                0.0,
            ),
            (
                TexelGrid::from_fn(24, 96, mosaic_texel).unwrap(),
                true,
                0.05,
            ),
            (hdr(32, 32), false, 0.0),
        ];
        for (grid, texel_blocks, tolerance) in &cases {
            let options = BuildOptions {
                tolerance: *tolerance,
                texel_blocks: *texel_blocks,
                ..BuildOptions::default()
            };
            let sequential = QuadTree::from_texels_split(grid, &options, usize::MAX).unwrap();
            let apart = QuadTree::from_texels_split(grid, &options, 1).unwrap();
            let what = format!("{}x{}, blocks {texel_blocks}", grid.width, grid.height);
            assert_eq!(apart.0, sequential.0, "{what}");
            assert_eq!(apart.1.max_error, sequential.1.max_error, "{what}");
            assert!(apart.0.node_count() > 100, "{what}: too simple to tell");
        }
        // A limit the whole tree could reach: built in order, same error.
        let grid = TexelGrid::from_fn(64, 64, mosaic_texel).unwrap();
        let options = BuildOptions {
            max_nodes: 200,
            ..BuildOptions::default()
        };
        let sequential = QuadTree::from_texels_split(&grid, &options, usize::MAX);
        let apart = QuadTree::from_texels_split(&grid, &options, 1);
        assert_eq!(
            format!("{:?}", apart.map(|_| ())),
            format!("{:?}", sequential.map(|_| ()))
        );
    }

    #[test]
    fn tiles_pack_to_the_tree_of_the_whole_mosaic() {
        for (tiles, side, tolerance) in [
            (4u32, 8u32, 0.0),
            (2, 16, 0.0),
            (4, 8, 0.05),
            (1, 32, 0.0),
            (8, 4, 0.0),
        ] {
            let total = tiles * side;
            let whole = TexelGrid::from_fn(total, total, mosaic_texel).unwrap();
            let options = BuildOptions {
                tolerance,
                ..BuildOptions::default()
            };
            let (expected, expected_report) = QuadTree::from_texels(&whole, &options).unwrap();
            let mut loaded = Vec::new();
            let (tree, report) = QuadTree::from_tiles(tiles, side, &options, &mut |row, col| {
                loaded.push((row, col));
                TexelGrid::from_fn(side, side, |c, r| {
                    mosaic_texel(col * side + c, row * side + r)
                })
            })
            .unwrap();
            assert_eq!(
                tree, expected,
                "{tiles}x{tiles} tiles of {side}, tolerance {tolerance}"
            );
            assert_eq!(report.max_error, expected_report.max_error);
            // Every tile loaded once.
            loaded.sort_unstable();
            loaded.dedup();
            assert_eq!(loaded.len(), (tiles * tiles) as usize);
        }
    }

    #[test]
    fn tiles_of_the_wrong_size_or_failing_to_load_stop_the_build() {
        let options = BuildOptions::default();
        let e = QuadTree::from_tiles(2, 8, &options, &mut |row, col| {
            let side = if (row, col) == (1, 1) { 4 } else { 8 };
            TexelGrid::from_fn(side, side, |_, _| Rgba::opaque(1.0, 0.0, 0.0))
        })
        .unwrap_err();
        assert!(
            e.to_string().contains("not the size of the first tile"),
            "{e}"
        );
        let e = QuadTree::from_tiles(2, 8, &options, &mut |_, _| {
            Err(Error::BadDimensions {
                width: 0,
                height: 0,
                reason: "a test failure",
            })
        })
        .unwrap_err();
        assert!(e.to_string().contains("a test failure"), "{e}");
        assert!(QuadTree::from_tiles(3, 8, &options, &mut |_, _| unreachable!()).is_err());
        assert!(QuadTree::from_tiles(2, 6, &options, &mut |_, _| unreachable!()).is_err());
        let levelled = BuildOptions {
            max_level: Some(3),
            ..BuildOptions::default()
        };
        assert!(QuadTree::from_tiles(2, 8, &levelled, &mut |_, _| unreachable!()).is_err());
    }

    #[test]
    fn weights_cover_each_cell_once() {
        for (t, c) in [(3, 4), (5, 8), (8, 8), (16, 4), (7, 2), (1, 1)] {
            for taps in weights_1d(t, c) {
                let s: f32 = taps.iter().map(|&(_, w)| w).sum();
                assert!((s - 1.0).abs() < 1e-6, "{t} texels -> {c} cells: {taps:?}");
            }
        }
    }

    #[test]
    fn uniform_image_is_a_single_terminal_root() {
        let g = TexelGrid::from_fn(64, 64, |_, _| Rgba::opaque(0.25, 0.5, 0.75)).unwrap();
        let (t, r) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
        assert_eq!(t.node_count(), 1);
        assert_eq!(t.depth(), 0);
        assert_eq!(r.max_error, 0.0);
    }

    #[test]
    fn one_odd_texel_splits_only_its_path() {
        let g = TexelGrid::from_fn(16, 16, |c, r| {
            if (c, r) == (3, 5) {
                Rgba::opaque(1.0, 0.0, 0.0)
            } else {
                Rgba::opaque(0.0, 0.0, 1.0)
            }
        })
        .unwrap();
        let (t, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
        assert_eq!(t.depth(), 4);
        assert_eq!(t.node_count(), 1 + 4 * 4, "one inner node per level");
        let stats = t.level_stats();
        assert_eq!(
            stats.iter().map(|s| s.nodes).collect::<Vec<_>>(),
            vec![1, 4, 4, 4, 4]
        );
    }

    #[test]
    fn tolerance_merges_small_noise_and_reports_error() {
        let g = TexelGrid::from_fn(8, 8, |c, r| {
            Rgba::opaque(0.5 + 0.001 * ((c + r) % 2) as f32, 0.5, 0.5)
        })
        .unwrap();
        let (lossless, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
        assert!(lossless.node_count() > 1);
        let opts = BuildOptions {
            tolerance: 0.002,
            ..BuildOptions::default()
        };
        let (lossy, report) = QuadTree::from_texels(&g, &opts).unwrap();
        assert_eq!(lossy.node_count(), 1);
        assert!(
            report.max_error > 0.0 && report.max_error <= 0.002,
            "{report:?}"
        );
    }

    #[test]
    fn grid_estimate_counts_texels_cells_and_resampling_rows() {
        assert_eq!(raster_grid_bytes(64, 64, 6), 8 * 64 * 64);
        assert_eq!(
            raster_grid_bytes(64, 16, 6),
            8 * 64 * 16,
            "a strip packs its own texels"
        );
        // The 1×20000 column on its own 1×32768 cells: texels + cells + rows.
        assert_eq!(
            raster_grid_bytes(1, 20000, 15),
            8 * 20000 + 8 * 32768 + 16 * 20000
        );
        // A square of another size still resamples onto the square around it.
        assert_eq!(
            raster_grid_bytes(3000, 3000, 12),
            8 * 9_000_000 + 8 * 4096 * 4096 + 16 * 3000 * 4096
        );
        let g = TexelGrid::from_fn(1, 20000, |_, r| {
            Rgba::opaque((r % 7) as f32 / 7.0, 0.0, 0.0)
        })
        .unwrap();
        let opts = BuildOptions {
            max_bytes: Some(512 << 10),
            ..BuildOptions::default()
        };
        let e = QuadTree::from_texels(&g, &opts).unwrap_err();
        assert!(
            e.to_string().starts_with(
                "packing 1x20000 texels at level 15 (1x32768 cells) needs an estimated 724.8 KiB, above the memory budget of 512.0 KiB"
            ),
            "{e}"
        );
    }

    /// A noisy 256² image: the up-front part is the texels; the build stops
    /// once the nodes so far exceed the rest of the budget, and a budget of
    /// the texels plus `BUILD_BYTES_PER_NODE` a node of the finished tree
    /// (within 4× of its `memory_bytes`) fits.
    #[test]
    fn budget_bounds_the_tree_while_building() {
        let g = TexelGrid::from_fn(256, 256, |c, r| {
            let h = (c.wrapping_mul(2_654_435_761) ^ r.wrapping_mul(40503)) % 1000;
            Rgba::opaque(h as f32 / 1000.0, 0.5, 0.5)
        })
        .unwrap();
        let (tree, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
        let fixed = raster_grid_bytes(256, 256, 8);
        let needed = fixed + BUILD_BYTES_PER_NODE * tree.node_count();
        assert!(needed - fixed <= 4 * tree.memory_bytes());
        let fits = BuildOptions {
            max_bytes: Some(needed),
            ..BuildOptions::default()
        };
        assert!(QuadTree::from_texels(&g, &fits).is_ok());
        let half = BuildOptions {
            max_bytes: Some(fixed + (needed - fixed) / 2),
            ..BuildOptions::default()
        };
        let e = QuadTree::from_texels(&g, &half).unwrap_err();
        assert!(matches!(e, Error::MemoryBudget { .. }), "{e}");
        assert!(e.to_string().contains("stopped after"), "{e}");
    }

    #[test]
    fn refuses_bad_input() {
        assert!(matches!(
            TexelGrid::new(0, 4, vec![]),
            Err(Error::BadDimensions { .. })
        ));
        assert!(matches!(
            TexelGrid::new(2, 2, vec![Unorm16Rgba::default(); 3]),
            Err(Error::TexelCount { .. })
        ));
        let g = TexelGrid::from_fn(2, 2, |_, _| Rgba::TRANSPARENT).unwrap();
        let bad = BuildOptions {
            tolerance: f64::NAN,
            ..BuildOptions::default()
        };
        assert!(matches!(
            QuadTree::from_texels(&g, &bad),
            Err(Error::BadTolerance(_))
        ));
        let deep = BuildOptions {
            max_level: Some(40),
            ..BuildOptions::default()
        };
        assert!(matches!(
            QuadTree::from_texels(&g, &deep),
            Err(Error::DepthTooLarge { .. })
        ));
        let few = BuildOptions {
            max_nodes: 3,
            ..BuildOptions::default()
        };
        let g = TexelGrid::from_fn(4, 4, |c, _| Rgba::opaque(c as f32 / 4.0, 0.0, 0.0)).unwrap();
        assert!(matches!(
            QuadTree::from_texels(&g, &few),
            Err(Error::TooManyNodes { .. })
        ));
    }
}
#[cfg(test)]
mod block_tests {
    use super::*;
    use crate::Fragment;
    use crate::tree::texel_block::srgb8_texel;

    fn noise(c: u32, r: u32) -> [u8; 4] {
        let h = c.wrapping_mul(2_654_435_761) ^ r.wrapping_mul(40_503);
        [
            (h % 251) as u8,
            (h / 7 % 253) as u8,
            (h / 13 % 241) as u8,
            255,
        ]
    }

    /// An 8-bit photograph-like grid keeps its bytes in blocks; every texel
    /// integrates back exactly, and the tree is smaller than its nodes were.
    #[test]
    fn photographs_keep_8_bit_texels_in_blocks() {
        let (w, h) = (16u32, 16u32);
        let bytes: Vec<[u8; 4]> = (0..h)
            .flat_map(|r| (0..w).map(move |c| noise(c, r)))
            .collect();
        let g = TexelGrid::from_srgb8(w, h, bytes.clone()).unwrap();
        let (t, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
        let tb = t.texel_blocks().expect("blocks");
        // Opaque colour: three bytes a texel.
        assert_eq!(tb.format(), BlockFormat::Srgb8Rgb);
        assert_eq!((tb.level(), tb.count()), (2, 16));
        assert_eq!(t.depth(), 4);
        // Level 2 is the deepest stored level: 1 + 4 + 16 nodes.
        assert_eq!(t.node_count(), 21);
        for r in 0..h {
            for c in 0..w {
                let f = Fragment::new(
                    f64::from(c) / 16.0,
                    f64::from(15 - r) / 16.0,
                    f64::from(c + 1) / 16.0,
                    f64::from(16 - r) / 16.0,
                )
                .unwrap();
                let got = t.weighted_colour(&f, 30).0.map(|v| v * 256.0);
                let want = srgb8_texel(bytes[(r * w + c) as usize])
                    .to_rgba()
                    .to_array();
                for (a, b) in got.iter().zip(want) {
                    assert!(
                        (a - f64::from(b)).abs() < 1e-6,
                        "({c}, {r}): {got:?} vs {want:?}"
                    );
                }
                assert_eq!(t.uniform_colour(&f), Some(g.texel(c, r).to_rgba()));
            }
        }
        // Translucent texels keep four bytes, opaque grey one.
        let format = |f: fn([u8; 4]) -> [u8; 4]| {
            let bytes = bytes.iter().map(|&p| f(p)).collect();
            let g = TexelGrid::from_srgb8(w, h, bytes).unwrap();
            let (t, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
            t.texel_blocks().map(|b| b.format())
        };
        assert_eq!(
            format(|[r, g, b, _]| [r, g, b, r]),
            Some(BlockFormat::Srgb8Rgba)
        );
        assert_eq!(
            format(|[r, ..]| [r, r, r, 255]),
            Some(BlockFormat::Srgb8Grey)
        );
        let unorm = TexelGrid::new(w, h, g.texels().to_vec()).unwrap();
        let (t16, _) = QuadTree::from_texels(&unorm, &BuildOptions::default()).unwrap();
        assert_eq!(
            t16.texel_blocks().map(|b| b.format()),
            Some(BlockFormat::Unorm16Rgba)
        );
        assert!(t.memory_bytes() < t16.memory_bytes());
    }

    /// 8-bit tiles of different kinds (grey first, then colour, then
    /// translucent) widen the blocks as they come: the tree is the whole
    /// mosaic's. A 16-bit tile among 8-bit ones is refused by name.
    #[test]
    fn tiles_widen_their_blocks_to_the_mosaic_format() {
        let texel = |x: u32, y: u32| {
            let v = noise(x, y);
            match (x / 8, y / 8) {
                (0, 0) => [v[0], v[0], v[0], 255],
                (1, 0) => v,
                _ => [v[0], v[1], v[2], v[0] | 1],
            }
        };
        let bytes = (0..16u32)
            .flat_map(|y| (0..16).map(move |x| texel(x, y)))
            .collect();
        let whole = TexelGrid::from_srgb8(16, 16, bytes).unwrap();
        let options = BuildOptions::default();
        let (expected, _) = QuadTree::from_texels(&whole, &options).unwrap();
        assert_eq!(
            expected.texel_blocks().map(|b| b.format()),
            Some(BlockFormat::Srgb8Rgba)
        );
        let tile = |row: u32, col: u32| {
            let bytes = (0..8u32)
                .flat_map(|y| (0..8).map(move |x| texel(8 * col + x, 8 * row + y)))
                .collect();
            TexelGrid::from_srgb8(8, 8, bytes)
        };
        let (tree, _) =
            QuadTree::from_tiles(2, 8, &options, &mut |row, col| tile(row, col)).unwrap();
        assert_eq!(tree, expected);
        let e = QuadTree::from_tiles(2, 8, &options, &mut |row, col| {
            let t = tile(row, col)?;
            if (row, col) == (1, 1) {
                TexelGrid::new(8, 8, t.texels().to_vec())
            } else {
                Ok(t)
            }
        })
        .unwrap_err();
        assert!(
            e.to_string()
                .starts_with("tile (1, 1) is 16-bit or float, the first tile was 8-bit"),
            "{e}"
        );
        let e = QuadTree::from_tiles(2, 8, &options, &mut |_, _| {
            TexelGrid::from_linear_f32(8, 8, &[[2.0, 0.5, 0.5, 1.0]; 64])
        })
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "tile (1, 0) is HDR (float): tiled packing takes 8- and 16-bit tiles only"
        );
    }

    /// HDR texels (up to 1000, below 0, translucent) pack into half floats
    /// and integrate back within half-float precision; strips and odd sizes
    /// too; a NaN texel is refused by position.
    #[test]
    fn hdr_texels_keep_their_range_to_half_precision() {
        let value = |c: u32, r: u32| {
            let h = (c.wrapping_mul(2_654_435_761) ^ r.wrapping_mul(40_503)) % 1000;
            let v = match h % 4 {
                0 => 1000.0 - h as f32 / 7.0,
                1 => -(h as f32) / 300.0,
                2 => h as f32 / 1000.0,
                _ => 3.0,
            };
            [
                v,
                0.5 * v,
                -0.25,
                if h.is_multiple_of(5) { 0.5 } else { 1.0 },
            ]
        };
        for (w, h) in [(16u32, 16u32), (32, 4), (5, 3)] {
            let texels: Vec<[f32; 4]> = (0..h)
                .flat_map(|r| (0..w).map(move |c| value(c, r)))
                .collect();
            let g = TexelGrid::from_linear_f32(w, h, &texels).unwrap();
            assert!(g.is_hdr());
            let (t, report) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
            assert_eq!(t.encoding(), ColourEncoding::Half);
            assert!(t.texel_blocks().is_none());
            let exact = |f: &Fragment| {
                // Σ texel × overlap, texels as rectangles of the unit square.
                let mut acc = [0f64; 4];
                for r in 0..h {
                    for c in 0..w {
                        let (x0, x1) =
                            (f64::from(c) / f64::from(w), f64::from(c + 1) / f64::from(w));
                        let (z0, z1) = (
                            1.0 - f64::from(r + 1) / f64::from(h),
                            1.0 - f64::from(r) / f64::from(h),
                        );
                        let a = (f.x1().min(x1) - f.x0().max(x0)).max(0.0)
                            * (f.z1().min(z1) - f.z0().max(z0)).max(0.0);
                        for (s, v) in acc.iter_mut().zip(value(c, r)) {
                            *s += a * f64::from(v);
                        }
                    }
                }
                acc
            };
            let power_of_two = w.is_power_of_two() && h.is_power_of_two();
            assert_eq!(report.resampled, !power_of_two);
            let fragments: Vec<Fragment> = if power_of_two {
                (0..h)
                    .flat_map(|r| (0..w).map(move |c| (c, r)))
                    .map(|(c, r)| {
                        Fragment::new(
                            f64::from(c) / f64::from(w),
                            1.0 - f64::from(r + 1) / f64::from(h),
                            f64::from(c + 1) / f64::from(w),
                            1.0 - f64::from(r) / f64::from(h),
                        )
                        .unwrap()
                    })
                    .chain([Fragment::new(0.1, 0.2, 0.7, 0.9).unwrap()])
                    .collect()
            } else {
                vec![Fragment::new(0.0, 0.0, 1.0, 1.0).unwrap()]
            };
            for f in fragments {
                let got = t.weighted_colour(&f, 30).0;
                let want = exact(&f);
                for (a, b) in got.iter().zip(want) {
                    // Half floats: 11 significant bits, rounded once per
                    // texel and once per inner mean.
                    let tol = f.area() * 1e-3 + b.abs() * 2.0 / 1024.0;
                    assert!((a - b).abs() <= tol, "{w}x{h} {f:?}: {got:?} vs {want:?}");
                }
            }
        }
        let mut texels = vec![[0.5f32; 4]; 12];
        texels[7][1] = f32::NAN;
        let e = TexelGrid::from_linear_f32(4, 3, &texels).unwrap_err();
        assert_eq!(
            e.to_string(),
            "texel (3, 1) has g = NaN: HDR texels must be finite"
        );
        texels[7][1] = f32::INFINITY;
        assert!(TexelGrid::from_linear_f32(4, 3, &texels).is_err());
    }

    /// Edges of vector-like art stay nodes where nodes are cheaper than a
    /// block; uniform squares never become blocks.
    #[test]
    fn sparse_subtrees_stay_nodes() {
        let g = TexelGrid::from_fn(16, 16, |c, r| {
            if c + r < 9 {
                Rgba::opaque(1.0, 0.0, 0.0)
            } else {
                Rgba::opaque(0.0, 0.0, 1.0)
            }
        })
        .unwrap();
        let (t, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
        let blocks = t.texel_blocks().map_or(0, |b| b.count());
        // A 4×4 square the diagonal crosses splits into 4 + 8 nodes (96 B)
        // against 128 B of unorm16 texels: it stays nodes.
        assert_eq!(blocks, 0, "{blocks} blocks");
    }
}

//! The incomplete quadtree and the fragment integral.
//!
//! ## Layout
//!
//! Nodes are stored without pointers, in breadth-first order (the paper's
//! per-level indexing): level 0 (the root), then level 1, and so on; within a
//! level, the children of one inner node are four consecutive entries in the
//! order *low-x low-z, high-x low-z, low-x high-z, high-x high-z*. Hence the
//! children of the node with the `r`-th inner rank (counting inner nodes before
//! it in that order) start at `4r + 1`.
//!
//! In memory the array is shifted by three padding entries so that every
//! sibling group starts at a multiple of four and its four "inner" bits sit in
//! one machine word. Per node the tree stores:
//!
//! * 8 bytes of colour ([`Unorm16Rgba`]),
//! * 1 bit "inner", plus a 64-bit rank counter per 64 nodes (0.25 byte/node),
//!
//! and per tree a small direct-addressed table of the top levels (at most
//! 1/16 of the colour bytes) that lets a query start at the smallest square
//! that encloses its fragment.

mod aspect;
mod construct;
mod integrate;
pub(crate) mod leaf_nodes;
mod navigate;
mod ranks;
pub(crate) mod shared;
pub(crate) mod texel_block;
mod uniform;
pub mod variant;

use crate::Error;
use crate::SharedBytes;
use crate::colour::{ColourEncoding, Rgba, Unorm16Rgba};
use crate::tree::leaf_nodes::LeafNodes;
use crate::tree::texel_block::TexelBlocks;
use crate::vector::contour_leaf::ContourLeaves;
use crate::vector::gradient_leaf::{GradientLeaves, square_corners};

pub(crate) use crate::geometry::unit_side;
pub use aspect::Aspect;
pub(crate) use construct::{from_levels, from_levels_encoded};
pub(crate) use navigate::{CellReader, FinestCell, NodeRef, StoredSquare};
use ranks::{RankBlock, inner_before};

/// Deepest level a tree may have. A level-30 square has side `2^-30`, still
/// exactly representable with room to spare in the `f64` coordinates.
pub const MAX_DEPTH: u8 = 30;

/// Most nodes a tree may have (2³¹, i.e. 16 GiB of colour).
pub const MAX_NODES: u64 = 1 << 31;

/// Padding entries before the root, so sibling groups are 4-aligned.
const PAD: usize = 3;

/// Most squares [`QuadTree::uniform_colour`] looks at below the first
/// square its fragment straddles (a footprint across a few squares of one
/// colour answers; a longer search is left to the caller's integral).
pub const UNIFORM_SEARCH_NODES: usize = 64;

/// Deepest level of the direct-addressed top table.
const MAX_TOP_LEVEL: u8 = 8;

/// Node and terminal counts of one level, for reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LevelStats {
    /// The level (root = 0).
    pub level: u8,
    /// Nodes at this level.
    pub nodes: u64,
    /// Terminal nodes at this level.
    pub terminals: u64,
}

/// Counters a caller can accumulate over many queries (for cost reports).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TraversalStats {
    /// Queries answered.
    pub queries: u64,
    /// Nodes whose colour was read (whole, partial or descended into).
    pub nodes_visited: u64,
}

/// A texture packed as an incomplete quadtree over the unit square.
///
/// Invariants (established by [`QuadTree::from_parts`] or the builder):
/// every inner node has four children; the tree's deepest level is
/// [`QuadTree::depth`] `<= MAX_DEPTH`; colours are premultiplied
/// (`r,g,b <= a`) and an inner node's colour is the rounded area-average of
/// what lies below it.
#[derive(Debug, Clone)]
pub struct QuadTree {
    depth: u8,
    /// How node colours are stored.
    encoding: ColourEncoding,
    /// Each channel's lowest and highest stored colour: `[0, 1]` for
    /// unorm16 colours (no pass needed), found when first needed for half
    /// floats. Error bounds computed for unit contrast scale with it.
    channel_ranges: std::sync::OnceLock<ChannelRanges>,
    /// Where texture space lies in the tree's square.
    aspect: Aspect,
    /// Node colours, four little-endian `u16` each, unpadded: the node at
    /// padded index `p` is at byte `8·(p − PAD)` ([`QuadTree::colour`]).
    /// Owned, or read in place from a mapped file.
    colours: SharedBytes,
    blocks: Vec<RankBlock>,
    /// Padded index of the first node of each level, plus one past the end.
    level_starts: Vec<usize>,
    /// Deepest level covered by `top`.
    top_level: u8,
    /// For each level `l <= top_level` (concatenated, `4^l` entries, row-major
    /// with `z` rows from the bottom): the padded index of the node covering
    /// that cell at level `l`, or of its terminal ancestor.
    top: Vec<u32>,
    /// The colour's first moments about the centre, computed when first
    /// needed ([`QuadTree::first_moments`]).
    moments: std::sync::OnceLock<[f64; 2]>,
    /// The colour's second moments ([`QuadTree::second_moments`]),
    /// computed when first needed.
    second_moments: std::sync::OnceLock<Option<[f64; 3]>>,
    /// The colours of the grid at the tree's depth, for shallow trees
    /// ([`QuadTree::flat_grid`]), computed when first needed.
    grid: std::sync::OnceLock<Option<Vec<[f64; 4]>>>,
    /// Texel blocks ending squares of one level ([`crate::tree::texel_block`]),
    /// and the padded indices of that level's nodes.
    texel_blocks: Option<TexelBlocks>,
    block_nodes: std::ops::Range<usize>,
    /// Terminal squares that keep their gradient paint
    /// ([`crate::vector::gradient_leaf`]).
    gradient_leaves: Option<GradientLeaves>,
    /// Terminal squares that keep the edges crossing them
    /// ([`crate::vector::contour_leaf`]).
    contour_leaves: Option<ContourLeaves>,
}

/// Trees are equal when they store the same nodes and blocks in the same
/// encoding and aspect; what is derived from them (tables, values computed
/// on first use) does not count.
impl PartialEq for QuadTree {
    fn eq(&self, other: &QuadTree) -> bool {
        self.depth == other.depth
            && self.encoding == other.encoding
            && self.aspect == other.aspect
            && self.colours == other.colours
            && self.blocks == other.blocks
            && self.texel_blocks == other.texel_blocks
            && self.gradient_leaves == other.gradient_leaves
            && self.contour_leaves == other.contour_leaves
    }
}

/// Deepest tree whose full grid [`QuadTree::flat_grid`] gives (16 × 16
/// cells, 8 KiB).
pub const FLAT_GRID_MAX_DEPTH: u8 = 4;

impl QuadTree {
    /// The tree with its colours read as `encoding`.
    pub(crate) fn with_encoding(mut self, encoding: ColourEncoding) -> QuadTree {
        self.encoding = encoding;
        self.channel_ranges = std::sync::OnceLock::new();
        self
    }

    /// What the error bounds of [`crate::filter::region`], derived for colour
    /// channels in `[0, 1]`, are multiplied by for this tree alone: 1 for
    /// unorm16 colours, the widest channel range (at least 1) for HDR
    /// colours (one pass over the colours, the first time). A texture whose
    /// wrap shows a border colour widens it: [`crate::Texture::bound_scale`].
    pub fn bound_scale(&self) -> f64 {
        self.channel_ranges().widest_with(None)
    }

    /// Each channel's range over the stored colours.
    pub(crate) fn channel_ranges(&self) -> ChannelRanges {
        *self.channel_ranges.get_or_init(|| match self.encoding {
            ColourEncoding::Unorm16 => ChannelRanges {
                lo: [0.0; 4],
                hi: [1.0; 4],
            },
            encoding => {
                let (mut lo, mut hi) = ([f64::INFINITY; 4], [f64::NEG_INFINITY; 4]);
                for p in PAD..PAD + self.node_count() as usize {
                    for (ch, v) in encoding
                        .decode_colour(self.colour(p))
                        .into_iter()
                        .enumerate()
                    {
                        lo[ch] = lo[ch].min(v);
                        hi[ch] = hi[ch].max(v);
                    }
                }
                ChannelRanges { lo, hi }
            }
        })
    }

    /// The colour of the stored node at padded index `p`.
    #[inline]
    fn colour(&self, p: usize) -> Unorm16Rgba {
        let o = 8 * (p - PAD);
        let b = &self.colours[o..o + 8];
        Unorm16Rgba([
            u16::from_le_bytes([b[0], b[1]]),
            u16::from_le_bytes([b[2], b[3]]),
            u16::from_le_bytes([b[4], b[5]]),
            u16::from_le_bytes([b[6], b[7]]),
        ])
    }

    /// The texel blocks, if any ([`crate::tree::texel_block`]).
    pub fn texel_blocks(&self) -> Option<&TexelBlocks> {
        self.texel_blocks.as_ref()
    }

    /// Deepest level present, texels of blocks included (0 for a
    /// single-colour texture); with gradient or contour leaves, the deepest
    /// level they answer down to ([`GradientLeaves::depth`],
    /// [`ContourLeaves::depth`]).
    pub fn depth(&self) -> u8 {
        self.depth
    }

    /// Deepest level of the stored nodes and texel blocks: [`QuadTree::depth`]
    /// without gradient or contour leaves.
    pub fn stored_depth(&self) -> u8 {
        let nodes = (self.level_starts.len() - 2) as u8;
        let blocks = self
            .texel_blocks
            .as_ref()
            .map_or(0, |b| b.level() + b.log2_side());
        nodes.max(blocks)
    }

    /// The gradient leaves, if any ([`crate::vector::gradient_leaf`]).
    pub fn gradient_leaves(&self) -> Option<&GradientLeaves> {
        self.gradient_leaves.as_ref()
    }

    /// The tree with some terminal squares kept as gradient leaves; its
    /// depth becomes at least `leaves.depth()`. [`Error::MalformedTree`]
    /// when a leaf is not a terminal node of the tree or lies in the pad,
    /// when a node is already a contour leaf, or when the depth is below
    /// the stored nodes'; half-float trees and trees with texel blocks have
    /// no gradient leaves.
    pub fn with_gradient_leaves(mut self, mut leaves: GradientLeaves) -> Result<QuadTree, Error> {
        let other = self.contour_leaves.as_ref().map(ContourLeaves::at);
        let squares = self.leaf_squares("gradient", leaves.at(), leaves.depth(), other)?;
        leaves.at_mut().set_squares(squares);
        self.depth = self.depth.max(leaves.depth());
        self.gradient_leaves = Some(leaves);
        self.forget_derived();
        Ok(self)
    }

    /// The tree with some terminal squares kept as contour leaves
    /// ([`crate::vector::contour_leaf`]); as [`QuadTree::with_gradient_leaves`],
    /// and every point must lie in its leaf's square.
    pub fn with_contour_leaves(mut self, mut leaves: ContourLeaves) -> Result<QuadTree, Error> {
        let other = self.gradient_leaves.as_ref().map(GradientLeaves::at);
        let squares = self.leaf_squares("contour", leaves.at(), leaves.depth(), other)?;
        leaves.at_mut().set_squares(squares);
        if let Some(i) = (0..leaves.count()).find(|&i| !leaves.inside_square(i)) {
            return Err(Error::MalformedTree(format!(
                "contour leaves: leaf {i} (node {}) has points outside its square",
                leaves.at().node(i)
            )));
        }
        self.depth = self.depth.max(leaves.depth());
        self.contour_leaves = Some(leaves);
        self.forget_derived();
        Ok(self)
    }

    /// Drops what was derived from the tree's colours on first use.
    fn forget_derived(&mut self) {
        self.grid = std::sync::OnceLock::new();
        self.moments = std::sync::OnceLock::new();
    }

    /// The squares of `leaves` (of kind `what`), checked: terminal, not
    /// blocks, not in the pad, not leaves of the `other` kind, in a
    /// unorm16 tree whose stored nodes do not reach below `depth`.
    fn leaf_squares(
        &self,
        what: &str,
        leaves: &LeafNodes,
        depth: u8,
        other: Option<&LeafNodes>,
    ) -> Result<Vec<(u8, u32, u32)>, Error> {
        let nodes = leaves.nodes();
        let bad = |why: String| Err(Error::MalformedTree(format!("{what} leaves: {why}")));
        if self.encoding != ColourEncoding::Unorm16 || self.texel_blocks.is_some() {
            return bad("only in unorm16 trees without texel blocks".into());
        }
        if depth < self.stored_depth() {
            return bad(format!(
                "depth {depth} is above the stored nodes' {}",
                self.stored_depth()
            ));
        }
        let n = self.node_count();
        if let Some(&last) = nodes.last()
            && u64::from(last) >= n
        {
            return bad(format!("node {last} of {n}"));
        }
        // Each leaf's square, from one walk over the stored nodes.
        let mut squares = vec![(0u8, 0u32, 0u32); nodes.len()];
        let mut stack = vec![(PAD, 0u8, 0u32, 0u32)];
        while let Some((p, level, ix, iz)) = stack.pop() {
            if self.is_inner(p) {
                let c = self.first_child(p);
                for k in 0..4 {
                    stack.push((
                        c + k,
                        level + 1,
                        2 * ix + (k & 1) as u32,
                        2 * iz + (k >> 1) as u32,
                    ));
                }
            } else if let Some(i) = leaves.index_of((p - PAD) as u32) {
                squares[i] = (level, ix, iz);
            }
        }
        for (i, (&node, &(level, ix, iz))) in nodes.iter().zip(&squares).enumerate() {
            if self.is_inner(node as usize + PAD) {
                return bad(format!("leaf {i}: node {node} is inner"));
            }
            if self.aspect.is_pad(level, ix, iz) {
                return bad(format!("leaf {i}: node {node} lies in the pad"));
            }
            if other.is_some_and(|o| o.index_of(node).is_some()) {
                return bad(format!(
                    "leaf {i}: node {node} is also a leaf of the other kind"
                ));
            }
        }
        Ok(squares)
    }

    /// The gradient leaf at padded index `p`, if it is one.
    #[inline]
    fn gradient_leaf(&self, p: usize) -> Option<(usize, &GradientLeaves)> {
        let g = self.gradient_leaves.as_ref()?;
        g.at().index_of((p - PAD) as u32).map(|i| (i, g))
    }

    /// The contour leaf at padded index `p`, if it is one.
    #[inline]
    fn contour_leaf(&self, p: usize) -> Option<(usize, &ContourLeaves)> {
        let c = self.contour_leaves.as_ref()?;
        c.at().index_of((p - PAD) as u32).map(|i| (i, c))
    }

    /// The contour leaves, if any ([`crate::vector::contour_leaf`]).
    pub fn contour_leaves(&self) -> Option<&ContourLeaves> {
        self.contour_leaves.as_ref()
    }

    /// Cells of both leaf kinds share one numbering in [`NodeRef`]:
    /// gradient leaves first.
    #[inline]
    fn gradient_leaf_count(&self) -> usize {
        self.gradient_leaves
            .as_ref()
            .map_or(0, GradientLeaves::count)
    }

    /// Where texture space lies in the tree's square.
    pub fn aspect(&self) -> Aspect {
        self.aspect
    }

    /// The finest cell's size in texture units, `[width, height]`: the
    /// side of a square of the finest level ([`QuadTree::finest_grid`]) over
    /// the texture's extent on that axis ([`Aspect`]); a raster's texel.
    pub fn finest_cell_size(&self) -> [f64; 2] {
        let side = unit_side(self.finest_level());
        let [ex, ez] = self.aspect.scale();
        [(side / ex).min(1.0), (side / ez).min(1.0)]
    }

    /// Columns and rows of the finest grid over the texture: the extent in
    /// squares of the finest level ([`Aspect::cells_at`]), at least one each.
    pub fn finest_grid(&self) -> [u64; 2] {
        self.aspect.cells_at(self.finest_level())
    }

    /// The level of the finest grid: the depth, or the extent's level when
    /// deeper (a texture uniform down to its texels still has them as its
    /// cells: a square of a shallower level would cross the extent's edge).
    fn finest_level(&self) -> u8 {
        self.depth.max(self.aspect.level())
    }

    /// Number of nodes.
    pub fn node_count(&self) -> u64 {
        (self.colours.len() / 8) as u64
    }

    /// The texture's average colour (the root's colour).
    pub fn average(&self) -> Rgba {
        let [r, g, b, a] = self.mean_colour().map(|v| v as f32);
        Rgba::new(r, g, b, a)
    }

    /// The texture's average colour in `f64`, as stored.
    pub fn mean_colour(&self) -> [f64; 4] {
        self.encoding.decode_colour(self.colour(PAD))
    }

    /// How node colours are stored: unorm16 (LDR) or half floats (HDR).
    pub fn encoding(&self) -> ColourEncoding {
        self.encoding
    }

    /// Bytes of memory the tree occupies (node colours, rank blocks, top table,
    /// level index), excluding the struct itself.
    pub fn memory_bytes(&self) -> u64 {
        (self.colours.len()
            + self.blocks.len() * std::mem::size_of::<RankBlock>()
            + self.top.len() * 4
            + self.level_starts.len() * std::mem::size_of::<usize>()) as u64
            + self
                .texel_blocks
                .as_ref()
                .map_or(0, TexelBlocks::memory_bytes)
            + self
                .gradient_leaves
                .as_ref()
                .map_or(0, GradientLeaves::memory_bytes)
            + self
                .contour_leaves
                .as_ref()
                .map_or(0, ContourLeaves::memory_bytes)
    }

    /// Nodes and terminals per level.
    pub fn level_stats(&self) -> Vec<LevelStats> {
        self.level_starts
            .windows(2)
            .enumerate()
            .map(|(level, w)| {
                let inner = inner_before(&self.blocks, w[1]) - inner_before(&self.blocks, w[0]);
                let nodes = (w[1] - w[0]) as u64;
                LevelStats {
                    level: level as u8,
                    nodes,
                    terminals: nodes - inner,
                }
            })
            .collect()
    }

    /// The nodes in breadth-first order: `(inner, colour)`.
    pub fn nodes(&self) -> impl ExactSizeIterator<Item = (bool, Unorm16Rgba)> + '_ {
        (PAD..PAD + self.node_count() as usize).map(|i| (self.is_inner(i), self.colour(i)))
    }

    /// The largest, over channels, of `|∫ colour·(x − ½)|` and
    /// `|∫ colour·(z − ½)|` over the unit square: how far the colour leans
    /// to one side (0 for a checkerboard). The error of weighing whole tiles
    /// by a smoothly varying density is proportional to it
    /// ([`crate::filter::region`]). One pass over the leaves, the first time.
    pub fn first_moments(&self) -> [f64; 2] {
        *self.moments.get_or_init(|| {
            let (mut mx, mut mz) = ([0f64; 4], [0f64; 4]);
            let [ex, ez] = self.aspect.scale();
            // A gradient leaf counts at its mean; the rest of its moment,
            // ∫ (c − c̄)(x − x̄), is at most its colour range × area × side/4.
            let slack: f64 = self.gradient_leaves.as_ref().map_or(0.0, |g| {
                (0..g.count())
                    .map(|i| {
                        let (level, ix, iz) = g.square(i);
                        let side = unit_side(level);
                        let poly = square_corners(level, ix.into(), iz.into());
                        g.paint(i).linear_width(&poly) * side * side * side / 4.0
                    })
                    .sum::<f64>()
            }) + self.contour_leaves.as_ref().map_or(0.0, |c| {
                (0..c.count())
                    .map(|i| unit_side(c.square(i).0).powi(3) / 4.0)
                    .sum::<f64>()
            });
            self.visit_leaves(self.depth, false, |level, ix, iz, c| {
                // The leaf's texture part, in texture units (a leaf above
                // the aspect's level straddles the pad).
                let side = unit_side(level);
                let (x0, z0) = (f64::from(ix) * side, f64::from(iz) * side);
                let (x1, z1) = ((x0 + side).min(ex) / ex, (z0 + side).min(ez) / ez);
                let (x0, z0) = (x0 / ex, z0 / ez);
                let a = (x1 - x0) * (z1 - z0);
                let (x, z) = (0.5 * (x0 + x1) - 0.5, 0.5 * (z0 + z1) - 0.5);
                for ch in 0..4 {
                    mx[ch] += c[ch] * a * x;
                    mz[ch] += c[ch] * a * z;
                }
            });
            let max = |m: [f64; 4]| m.iter().fold(0f64, |a, v| a.max(v.abs())) + slack;
            [max(mx), max(mz)]
        })
    }

    /// The largest, over channels, of `|∫ (c − c̄)(x − ½)²|`,
    /// `|∫ (c − c̄)(x − ½)(z − ½)|` and `|∫ (c − c̄)(z − ½)²|` over the unit
    /// square of texture space, `c̄` the stored mean: how the colour
    /// correlates with a density that bends across one tile. Weighing a
    /// whole tile at its mean errs by these times the density's Hessian,
    /// to second order ([`crate::filter`]). `None` for trees with gradient
    /// or contour leaves (they count at their means; the walk then assumes
    /// the colour's whole spread). One pass over the leaves, the first time.
    pub fn second_moments(&self) -> Option<[f64; 3]> {
        *self.second_moments.get_or_init(|| {
            if self.gradient_leaves.is_some() || self.contour_leaves.is_some() {
                return None;
            }
            let mean = self.mean_colour();
            let [ex, ez] = self.aspect.scale();
            let (mut xx, mut xz, mut zz) = ([0f64; 4], [0f64; 4], [0f64; 4]);
            // ∫ from a to b of (t − ½) dt, and of (t − ½)² dt.
            let first = |a: f64, b: f64| 0.5 * ((b - 0.5).powi(2) - (a - 0.5).powi(2));
            let second = |a: f64, b: f64| ((b - 0.5).powi(3) - (a - 0.5).powi(3)) / 3.0;
            self.visit_leaves(self.depth, false, |level, ix, iz, c| {
                // The leaf's texture part, in texture units.
                let side = unit_side(level);
                let (x0, z0) = (f64::from(ix) * side, f64::from(iz) * side);
                let (x1, z1) = ((x0 + side).min(ex) / ex, (z0 + side).min(ez) / ez);
                let (x0, z0) = (x0 / ex, z0 / ez);
                let (fx, fz) = (first(x0, x1), first(z0, z1));
                let (sx, sz) = (second(x0, x1), second(z0, z1));
                for ch in 0..4 {
                    let d = c[ch] - mean[ch];
                    xx[ch] += d * sx * (z1 - z0);
                    xz[ch] += d * fx * fz;
                    zz[ch] += d * sz * (x1 - x0);
                }
            });
            let max = |m: [f64; 4]| m.iter().fold(0f64, |a, v| a.max(v.abs()));
            Some([max(xx), max(xz), max(zz)])
        })
    }

    /// For a tree of depth `d ≤` `FLAT_GRID_MAX_DEPTH` (4), the colour of every
    /// cell of the `2^d × 2^d` grid at its depth (linear, premultiplied,
    /// `[0, 1]`), row-major with `z` rows from the bottom: cell `(i, j)`
    /// covers `[i, i+1) × [j, j+1)` scaled by `2^-d`. Exact: each cell lies
    /// in one terminal square. `None` for deeper trees and non-square ones.
    pub fn flat_grid(&self) -> Option<&[[f64; 4]]> {
        self.grid
            .get_or_init(|| {
                let d = self.depth;
                if d > FLAT_GRID_MAX_DEPTH
                    || !self.aspect.is_square()
                    || self.gradient_leaves.is_some()
                    || self.contour_leaves.is_some()
                {
                    return None;
                }
                let n = 1usize << d;
                let mut grid = vec![[0.0; 4]; n * n];
                self.for_each_leaf(d, |level, ix, iz, colour| {
                    let span = 1usize << (d - level);
                    let (i0, j0) = (ix as usize * span, iz as usize * span);
                    for j in j0..j0 + span {
                        grid[j * n + i0..j * n + i0 + span].fill(colour);
                    }
                });
                Some(grid)
            })
            .as_deref()
    }

    /// Calls `f(level, ix, iz, colour)` for every square a traversal to level
    /// `max_level` treats as uniform: terminal nodes at levels `< max_level`
    /// and all nodes at level `max_level`. Square `(level, ix, iz)` covers
    /// `[ix, ix+1) × [iz, iz+1)` scaled by `2^-level` in *tree space*
    /// ([`Aspect`]); squares of the pad are skipped. Order: depth first.
    /// Colours are decoded ([`ColourEncoding`]); a block's cells give the
    /// exact mean of their texels. A gradient leaf above `max_level` gives
    /// its cells ([`crate::vector::gradient_leaf`]), each the exact mean of its
    /// paint over it.
    pub fn for_each_leaf(&self, max_level: u8, f: impl FnMut(u8, u32, u32, [f64; 4])) {
        self.visit_leaves(max_level, true, f);
    }

    /// [`QuadTree::for_each_leaf`]; gradient leaves whole (at their stored
    /// mean) unless `cells`.
    fn visit_leaves(&self, max_level: u8, cells: bool, mut f: impl FnMut(u8, u32, u32, [f64; 4])) {
        let mut stack = vec![(PAD, 0u8, 0u32, 0u32)];
        while let Some((node, level, ix, iz)) = stack.pop() {
            if self.aspect.is_pad(level, ix, iz) {
                continue;
            }
            if let (Some(b), Some(tb)) = (
                self.block_at(node).filter(|_| level < max_level),
                self.texel_blocks.as_ref(),
            ) {
                let j = (max_level - level).min(tb.log2_side());
                for cz in 0..1u32 << j {
                    for cx in 0..1u32 << j {
                        let mean = tb.cell_mean(b, j, cx, cz);
                        f(level + j, (ix << j) + cx, (iz << j) + cz, mean);
                    }
                }
            } else if let Some((leaf, g)) = self
                .gradient_leaf(node)
                .filter(|_| cells && level < max_level)
            {
                let mut pending = vec![(0u8, 0u32, 0u32)];
                while let Some((j, cx, cz)) = pending.pop() {
                    let (l, poly) = g.cell(leaf, j, cx, cz);
                    if l < max_level && g.splits(leaf, j, l, &poly) {
                        for k in 0..4 {
                            pending.push((j + 1, 2 * cx + (k & 1), 2 * cz + (k >> 1)));
                        }
                    } else {
                        f(
                            l,
                            (ix << j) + cx,
                            (iz << j) + cz,
                            g.paint(leaf).mean_over(&poly),
                        );
                    }
                }
            } else if let Some((leaf, c)) = self
                .contour_leaf(node)
                .filter(|_| cells && level < max_level)
            {
                let mut pending = vec![(0u8, 0u32, 0u32)];
                while let Some((j, cx, cz)) = pending.pop() {
                    let (splits, mean, _) = c.cell_info(leaf, j, cx, cz);
                    let (l, sx, sz) = c.cell_square(leaf, j, cx, cz);
                    if l < max_level && splits {
                        for k in 0..4 {
                            pending.push((j + 1, 2 * cx + (k & 1), 2 * cz + (k >> 1)));
                        }
                    } else {
                        f(l, sx, sz, mean);
                    }
                }
            } else if !self.is_inner(node) || level >= max_level {
                f(
                    level,
                    ix,
                    iz,
                    self.encoding.decode_colour(self.colour(node)),
                );
            } else {
                let c = self.first_child(node);
                for k in 0..4 {
                    stack.push((
                        c + k,
                        level + 1,
                        2 * ix + (k & 1) as u32,
                        2 * iz + (k >> 1) as u32,
                    ));
                }
            }
        }
    }

    /// The texture as a raster (row 0 at the top): the tree's square cut
    /// into `2^level × 2^level` cells, of which the texture's
    /// ([`QuadTree::raster_size`]) are kept, each cell the colour of the
    /// square that holds it in the tree truncated at `level` (deeper than
    /// the tree, cells repeat their square's colour). For baselines that
    /// need a raster; refused above level 14 (a 2 GiB grid);
    /// [`QuadTree::rasterise_bytes`] is its size, to check against a budget
    /// first.
    pub fn rasterise(&self, level: u8) -> Result<crate::TexelGrid, Error> {
        if level > 14 {
            return Err(Error::DepthTooLarge {
                depth: level.into(),
                max: 14,
            });
        }
        let [w, h] = self.raster_size(level).map(|v| v as usize);
        let mut texels = crate::memory::try_vec(w * h, Unorm16Rgba::default(), "raster")?;
        self.for_each_leaf(level, |l, ix, iz, c| {
            // HDR colours are clamped to the raster's [0, 1].
            let colour = Rgba::new(c[0] as f32, c[1] as f32, c[2] as f32, c[3] as f32).to_unorm16();
            let span = 1usize << (level - l);
            let (x0, z0) = (ix as usize * span, iz as usize * span);
            // A leaf above the aspect's level straddles the pad: keep its texture part.
            let x1 = (x0 + span).min(w);
            for z in z0..(z0 + span).min(h) {
                let row = h - 1 - z;
                texels[row * w + x0..row * w + x1].fill(colour);
            }
        });
        crate::TexelGrid::new(w as u32, h as u32, texels)
    }

    /// Columns and rows of [`QuadTree::rasterise`] at `level`: the cells
    /// of `level` that hold texture ([`Aspect::cells_at`]), at least one.
    pub fn raster_size(&self, level: u8) -> [u32; 2] {
        self.aspect
            .cells_at(level)
            .map(|c| c.clamp(1, u64::from(u32::MAX)) as u32)
    }

    /// Bytes [`QuadTree::rasterise`] allocates at `level` (8 a cell) for a
    /// square texture, an upper bound for others.
    pub fn rasterise_bytes(level: u8) -> u64 {
        8u64 << (2 * u32::from(level.min(31)))
    }
}

fn top_table_offset(level: u8) -> usize {
    ((1usize << (2 * level)) - 1) / 3
}

fn top_table_len(top_level: u8) -> usize {
    top_table_offset(top_level + 1)
}

#[cfg(test)]
mod tests;

/// The lowest and highest value of each channel (linear, premultiplied) a
/// tree's colours take: what its error bounds' unit contrast stands for.
/// Unorm16 trees report `[0, 1]` without looking.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ChannelRanges {
    lo: [f64; 4],
    hi: [f64; 4],
}

impl ChannelRanges {
    /// The widest channel range (at least 1), with `extra` (a border
    /// colour a wrap shows beside the tree's) taken in.
    pub(crate) fn widest_with(self, extra: Option<Rgba>) -> f64 {
        let extra = extra.map(Rgba::to_array);
        (0..4)
            .map(|ch| {
                let (mut lo, mut hi) = (self.lo[ch], self.hi[ch]);
                if let Some(e) = extra {
                    lo = lo.min(f64::from(e[ch]));
                    hi = hi.max(f64::from(e[ch]));
                }
                hi - lo
            })
            .fold(1.0, f64::max)
    }
}

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

pub(crate) mod leaf_nodes;
pub(crate) mod shared;
pub(crate) mod texel_block;
pub mod variant;

use crate::Error;
use crate::SharedBytes;
use crate::colour::{ColourEncoding, Rgba, Unorm16Rgba, WeightedColour};
use crate::geometry::fragment::{Fragment, overlap_1d};
use crate::tree::leaf_nodes::LeafNodes;
use crate::tree::texel_block::TexelBlocks;
use crate::tree::variant::Variant;
use crate::vector::contour_leaf::ContourLeaves;
use crate::vector::gradient_leaf::{GradientLeaves, square_corners};

pub(crate) use crate::geometry::unit_side;

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

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct RankBlock {
    /// Bit `i`: the node at padded index `64·block + i` is inner.
    bits: u64,
    /// Inner nodes at padded indices below `64·block`.
    rank: u64,
}

/// Where texture space lies in the tree's square, for textures that are not
/// square.
///
/// **Tree space** is the square the tree subdivides, `[0,1)²`, `x` right
/// and `z` up. **Texture space** is the image: `[0,1)²` spans it whatever its
/// aspect (the usual UV convention), so a texel of a `W × H` image is
/// `1/W × 1/H` texture units. A texture `2^s` times wider than high sits in
/// the bottom `2^-s` of the tree's square (`z` shrunk by `s`), one `2^s`
/// times higher than wide in its left `2^-s` (`x` shrunk):
/// `tree = (x·2^-sx, z·2^-sz)`, with at most one of `sx`, `sz` non-zero.
/// Both scales are powers of two, so the map is exact in floating point.
///
/// The rest of the square, the *pad*, is never read: queries are clipped
/// to the texture first. Its squares are terminal and carry their parent's
/// mean, so every inner colour is the mean of its children and the root's
/// is the texture's mean. A `2^a × 2^b` raster packs into `2^(a+b)` finest
/// cells plus `O(2^|a−b|)` nodes along the pad, not `4^max(a,b)`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct Aspect {
    shrink: [u8; 2],
}

impl Aspect {
    /// A square texture: texture space is tree space.
    pub const SQUARE: Aspect = Aspect { shrink: [0, 0] };

    /// Texture space shrunk by `2^-x_shrink` along `x` and `2^-z_shrink`
    /// along `z`; at most one may be non-zero, each at most [`MAX_DEPTH`].
    pub fn new(x_shrink: u8, z_shrink: u8) -> Result<Aspect, Error> {
        if x_shrink != 0 && z_shrink != 0 {
            return Err(Error::MalformedTree(format!(
                "aspect shrinks both axes ({x_shrink}, {z_shrink}); at most one may be shrunk"
            )));
        }
        if x_shrink.max(z_shrink) > MAX_DEPTH {
            return Err(Error::DepthTooLarge {
                depth: x_shrink.max(z_shrink).into(),
                max: MAX_DEPTH.into(),
            });
        }
        Ok(Aspect {
            shrink: [x_shrink, z_shrink],
        })
    }

    /// The aspect of a `2^a × 2^b` grid of cells (`a = log2 columns`,
    /// `b = log2 rows`).
    pub fn of_grid(log2_columns: u8, log2_rows: u8) -> Aspect {
        let (a, b) = (log2_columns.min(MAX_DEPTH), log2_rows.min(MAX_DEPTH));
        Aspect {
            shrink: [b.saturating_sub(a), a.saturating_sub(b)],
        }
    }

    /// `[sx, sz]`: tree space is texture space times `2^-s` per axis.
    pub fn shrink(self) -> [u8; 2] {
        self.shrink
    }

    /// True for a square texture.
    pub fn is_square(self) -> bool {
        self.shrink == [0, 0]
    }

    /// `[2^-sx, 2^-sz]`: tree units per texture unit along each axis, which
    /// is also the texture's extent in tree space.
    #[inline]
    pub fn scale(self) -> [f64; 2] {
        [unit_side(self.shrink[0]), unit_side(self.shrink[1])]
    }

    /// Texture area per tree area: `2^(sx+sz)`.
    #[inline]
    pub fn area_ratio(self) -> f64 {
        f64::from_bits((1023 + u64::from(self.shrink[0]) + u64::from(self.shrink[1])) << 52)
    }

    /// The fragment (texture space) clipped to the texture and mapped to
    /// tree space; `None` when nothing of it is on the texture.
    #[inline]
    pub(crate) fn tree_fragment(self, f: &Fragment) -> Option<Fragment> {
        let f = f.clip_to_unit()?;
        if self.is_square() {
            return Some(f);
        }
        let [sx, sz] = self.scale();
        Fragment::new(f.x0() * sx, f.z0() * sz, f.x1() * sx, f.z1() * sz).ok()
    }

    /// True when square `(level, ix, iz)` of tree space lies wholly in the pad.
    #[inline]
    pub fn is_pad(self, level: u8, ix: u32, iz: u32) -> bool {
        let beyond = |i: u32, s: u8| (u64::from(i) << s) >= 1u64 << level;
        beyond(ix, self.shrink[0]) || beyond(iz, self.shrink[1])
    }
}

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
    /// What error bounds computed for unit contrast are multiplied by:
    /// 1 for unorm16 colours (channels in `[0, 1]`), the largest channel
    /// range (at least 1) for half floats, found when first needed.
    bound_scale: std::sync::OnceLock<f64>,
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

/// A stored node of the tree and its square: `level`, column `ix` and row
/// `iz` at that level (tree space, `z` up).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct StoredSquare {
    p: usize,
    pub level: u8,
    pub ix: u32,
    pub iz: u32,
}

/// What a stored square is ([`QuadTree::stored_kind`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum StoredKind {
    /// Four stored children.
    Inner,
    /// A texel block (its index).
    Block(usize),
    /// A terminal square: one colour, or a gradient or contour leaf.
    Terminal,
}

/// Cells under one stored square, from [`QuadTree::cells_below`].
pub(crate) struct CellReader<'t> {
    tree: &'t QuadTree,
    from: StoredSquare,
    /// `from`'s texel block, when it is one at the level its texels fill
    /// down to the depth.
    block: Option<(usize, &'t TexelBlocks)>,
}

impl CellReader<'_> {
    /// [`QuadTree::finest_cell`] of cell `(cx, cz)` from the reader's square.
    #[inline]
    pub(crate) fn cell(&self, cx: u32, cz: u32) -> Option<FinestCell> {
        if let Some((b, tb)) = self.block
            && let Some(texel) = block_texel(tb, b, self.from, cx, cz)
        {
            return Some(texel);
        }
        self.tree.finest_cell(self.from, cx, cz)
    }
}

/// Texel `(cx, cz)` (cells of the grid at the depth) of block `b`, whose
/// square `s` its texels fill to the depth; `None` when the cell is not
/// under it.
#[inline]
fn block_texel(
    tb: &TexelBlocks,
    b: usize,
    s: StoredSquare,
    cx: u32,
    cz: u32,
) -> Option<FinestCell> {
    let log2 = tb.log2_side();
    let mask = (1u32 << log2) - 1;
    (cx >> log2 == s.ix && cz >> log2 == s.iz)
        .then(|| FinestCell::Texel(tb.texel(b, cx & mask, cz & mask)))
}

/// What covers one cell of the grid at a plain raster's depth
/// ([`QuadTree::finest_cell`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum FinestCell {
    /// A texel of a block.
    Texel(Unorm16Rgba),
    /// A stored terminal square's colour, decoded (in `[0, 1]`).
    Square([f64; 4]),
}

impl FinestCell {
    /// Its colour in `[0, 1]`, as [`QuadTree::node_detail`] gives the
    /// texel's or square's (the same bits).
    #[inline]
    pub(crate) fn colour(self) -> [f64; 4] {
        match self {
            FinestCell::Texel(t) => t.0.map(|v| f64::from(v) * (1.0 / 65535.0)),
            FinestCell::Square(c) => c,
        }
    }

    /// Its colour as [`QuadTree::uniform_colour`] gives it.
    #[inline]
    pub(crate) fn rgba(self) -> Rgba {
        match self {
            FinestCell::Texel(t) => t.to_rgba(),
            FinestCell::Square([r, g, b, a]) => Rgba::new(r as f32, g as f32, b as f32, a as f32),
        }
    }
}

/// A node as traversals see it: a stored node (its padded index), a cell
/// of a texel block below the block level (block, levels below the block
/// node `j`, position in the block at that level), or a cell of a gradient
/// or contour leaf (leaf, levels below it, position below it).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub(crate) struct NodeRef(u128);

const CELL: u128 = 1 << 127;
/// With [`CELL`]: a cell of a gradient or contour leaf (leaf in bits 0–31,
/// levels below the leaf in 32–36, position in 40–71 and 72–103).
const LEAF_CELL: u128 = 1 << 126;

impl NodeRef {
    #[inline]
    fn stored(p: usize) -> NodeRef {
        NodeRef(p as u128)
    }

    #[inline]
    fn cell(block: usize, j: u8, ix: u32, iz: u32) -> NodeRef {
        NodeRef(
            CELL | block as u128
                | u128::from(j) << 40
                | u128::from(ix & 0xff) << 44
                | u128::from(iz & 0xff) << 52,
        )
    }

    #[inline]
    fn gradient_cell(leaf: usize, j: u8, ix: u32, iz: u32) -> NodeRef {
        NodeRef(
            CELL | LEAF_CELL
                | (leaf as u128 & 0xffff_ffff)
                | u128::from(j & 0x1f) << 32
                | u128::from(ix) << 40
                | u128::from(iz) << 72,
        )
    }

    #[inline]
    fn as_gradient_cell(self) -> Option<(usize, u8, u32, u32)> {
        (self.0 & (CELL | LEAF_CELL) == CELL | LEAF_CELL).then_some((
            (self.0 & 0xffff_ffff) as usize,
            (self.0 >> 32 & 0x1f) as u8,
            (self.0 >> 40 & 0xffff_ffff) as u32,
            (self.0 >> 72 & 0xffff_ffff) as u32,
        ))
    }

    #[inline]
    fn as_cell(self) -> Option<(usize, u8, u32, u32)> {
        (self.0 & (CELL | LEAF_CELL) == CELL).then_some((
            (self.0 & ((1 << 40) - 1)) as usize,
            (self.0 >> 40 & 0xf) as u8,
            (self.0 >> 44 & 0xff) as u32,
            (self.0 >> 52 & 0xff) as u32,
        ))
    }
}

/// Deepest tree whose full grid [`QuadTree::flat_grid`] gives (16 × 16
/// cells, 8 KiB).
pub const FLAT_GRID_MAX_DEPTH: u8 = 4;

impl QuadTree {
    /// A tree from its breadth-first node list.
    ///
    /// `inner` holds one bit per node (bit `i % 64` of word `i / 64`, set for an
    /// inner node); `colours` one colour per node. Returns
    /// [`Error::MalformedTree`] if the two do not describe a quadtree of
    /// depth `depth` with consistent colours.
    pub fn from_parts(
        depth: u8,
        inner: &[u64],
        colours: Vec<Unorm16Rgba>,
    ) -> Result<QuadTree, Error> {
        Self::from_parts_with_aspect(depth, Aspect::SQUARE, inner, colours)
    }

    /// As [`QuadTree::from_parts`], for a texture that covers `aspect` of
    /// the tree's square.
    pub fn from_parts_with_aspect(
        depth: u8,
        aspect: Aspect,
        inner: &[u64],
        colours: Vec<Unorm16Rgba>,
    ) -> Result<QuadTree, Error> {
        Self::from_parts_with_blocks(depth, aspect, ColourEncoding::Unorm16, inner, colours, None)
    }

    /// As [`QuadTree::from_parts_with_aspect`], with terminal squares of the
    /// blocks' level ended by texel blocks. `depth` is then the level of the
    /// finest squares, texels of blocks included. Besides the tree's checks:
    /// block nodes are terminal, the flags cover exactly the block level's
    /// nodes, and each block node's colour is the mean of its texels.
    ///
    /// With [`ColourEncoding::Half`] the colours are half floats (HDR):
    /// every channel must be finite and alpha in `[0, 1]`, and texel blocks
    /// are not allowed.
    pub fn from_parts_with_blocks(
        depth: u8,
        aspect: Aspect,
        encoding: ColourEncoding,
        inner: &[u64],
        colours: Vec<Unorm16Rgba>,
        texel_blocks: Option<TexelBlocks>,
    ) -> Result<QuadTree, Error> {
        let n = colours.len();
        let inner_words = n.div_ceil(64);
        if inner.len() < inner_words {
            return Err(Error::MalformedTree(format!(
                "{} inner-flag words for {n} nodes",
                inner.len()
            )));
        }
        let mut bytes = crate::memory::try_with_capacity(8 * n, "tree colours")?;
        for c in &colours {
            for v in c.0 {
                bytes.extend(v.to_le_bytes());
            }
        }
        drop(colours);
        let tree = Self::assemble(
            depth,
            aspect,
            encoding,
            n as u64,
            |k| inner[k],
            bytes.into(),
            texel_blocks,
        )?;
        tree.verify()?;
        Ok(tree)
    }

    /// A tree that reads its colours (and its blocks' texels) in place from
    /// shared bytes, such as a memory-mapped file, without reading them:
    /// `inner_bits` holds one bit per node (bit `i % 8` of byte `i / 8`, set
    /// for an inner node), `colours` four little-endian `u16` per node.
    ///
    /// Only the structure is checked here (depth, levels, block flags), in
    /// time proportional to the inner flags (1/64 of the colours); a query
    /// then loads only the pages it touches. The colours' invariants
    /// (premultiplied, inner colours the mean of their children, blocks the
    /// mean of their texels) are *not* checked: a tree whose colours break
    /// them gives wrong colours, never a panic. [`QuadTree::verify`] checks
    /// them, reading everything.
    pub fn from_shared_parts(
        depth: u8,
        aspect: Aspect,
        encoding: ColourEncoding,
        inner_bits: &[u8],
        colours: SharedBytes,
        texel_blocks: Option<TexelBlocks>,
    ) -> Result<QuadTree, Error> {
        if !colours.len().is_multiple_of(8) {
            return Err(Error::MalformedTree(format!(
                "{} colour bytes, not a whole number of 8-byte nodes",
                colours.len()
            )));
        }
        let n = colours.len() / 8;
        if inner_bits.len() < n.div_ceil(8) {
            return Err(Error::MalformedTree(format!(
                "{} inner-flag bytes for {n} nodes",
                inner_bits.len()
            )));
        }
        let word = |k: usize| {
            let bytes = inner_bits.get(8 * k..).unwrap_or_default();
            u64::from_le_bytes(std::array::from_fn(|i| bytes.get(i).copied().unwrap_or(0)))
        };
        Self::assemble(
            depth,
            aspect,
            encoding,
            n as u64,
            word,
            colours,
            texel_blocks,
        )
    }

    /// Checks what [`QuadTree::from_shared_parts`] leaves unchecked, reading
    /// every colour and texel: colours are premultiplied (unorm16) or finite
    /// with alpha in `[0, 1]` (half floats); every inner colour is the
    /// average of its children within rounding; 16-bit texels are
    /// premultiplied; every block node's colour is the mean of its texels.
    /// Trees made any other way have passed it already.
    pub fn verify(&self) -> Result<(), Error> {
        for p in PAD..PAD + self.node_count() as usize {
            let c = self.colour(p);
            let [r, g, b, a] = c.0;
            let ok = match self.encoding {
                ColourEncoding::Half => {
                    let v = self.encoding.decode_colour(c);
                    v.iter().all(|x| x.is_finite()) && (0.0..=1.0).contains(&v[3])
                }
                _ => r <= a && g <= a && b <= a,
            };
            if !ok {
                return Err(Error::MalformedTree(match self.encoding {
                    ColourEncoding::Half => format!(
                        "node {}: half-float colour {:?} is not finite or its alpha is outside [0, 1]",
                        p - PAD,
                        self.encoding.decode_colour(c)
                    ),
                    _ => format!(
                        "node {}: colour {:?} is not premultiplied (a channel exceeds alpha)",
                        p - PAD,
                        c.0
                    ),
                }));
            }
        }
        self.check_averages()?;
        self.check_blocks()?;
        self.check_gradient_leaves()?;
        self.check_contour_leaves()
    }

    /// Every contour leaf's colour is the mean of its art over its square,
    /// rounded: within one 16-bit step per channel.
    fn check_contour_leaves(&self) -> Result<(), Error> {
        let Some(c) = &self.contour_leaves else {
            return Ok(());
        };
        (0..c.count()).try_for_each(|i| {
            self.check_leaf_mean("contour leaf", i, c.at().node(i), c.cell_info(i, 0, 0, 0).1)
        })
    }

    /// Every gradient leaf's colour is its paint's mean over its square,
    /// rounded: within one 16-bit step per channel.
    fn check_gradient_leaves(&self) -> Result<(), Error> {
        let Some(g) = &self.gradient_leaves else {
            return Ok(());
        };
        (0..g.count()).try_for_each(|i| {
            let (level, ix, iz) = g.square(i);
            let corners = square_corners(level, ix.into(), iz.into());
            self.check_leaf_mean(
                "gradient leaf",
                i,
                g.at().node(i),
                g.paint(i).mean_over(&corners),
            )
        })
    }

    /// The colour stored for leaf `i` at unpadded `node` is `mean`, rounded.
    fn check_leaf_mean(
        &self,
        what: &str,
        i: usize,
        node: u32,
        mean: [f64; 4],
    ) -> Result<(), Error> {
        let stored = self.colour(node as usize + PAD).0;
        let off = |c: usize| (mean[c].clamp(0.0, 1.0) * 65535.0 - f64::from(stored[c])).abs() > 1.0;
        if (0..4).any(off) {
            return Err(Error::MalformedTree(format!(
                "{what} {i} (node {node}): colour {stored:?} is not the mean {mean:?} of what it keeps"
            )));
        }
        Ok(())
    }

    /// The structural checks shared by [`QuadTree::from_parts_with_blocks`]
    /// and [`QuadTree::from_shared_parts`]: `n` nodes whose inner flags
    /// are `inner_word(k)` (bits `64k..64k+64`, those past `n` ignored).
    fn assemble(
        depth: u8,
        aspect: Aspect,
        encoding: ColourEncoding,
        n: u64,
        inner_word: impl Fn(usize) -> u64,
        colours: SharedBytes,
        texel_blocks: Option<TexelBlocks>,
    ) -> Result<QuadTree, Error> {
        if encoding != ColourEncoding::Unorm16 && texel_blocks.is_some() {
            return Err(Error::MalformedTree(
                "texel blocks in a tree of half-float colours".into(),
            ));
        }
        if depth > MAX_DEPTH {
            return Err(Error::DepthTooLarge {
                depth: depth.into(),
                max: MAX_DEPTH.into(),
            });
        }
        if n > MAX_NODES {
            return Err(Error::TooManyNodes {
                nodes: n,
                max: MAX_NODES,
            });
        }
        if n == 0 {
            return Err(Error::MalformedTree("no nodes".into()));
        }
        let n = n as usize;
        let blocks = rank_blocks(n, inner_word)?;
        let inner_before = |p: usize| inner_before(&blocks, p);
        // Walk the levels (padded indices): each holds four children per
        // inner node of the one above.
        let mut level_starts = vec![PAD];
        let (mut start, mut end) = (PAD, PAD + 1);
        loop {
            let inner_here = (inner_before(end) - inner_before(start)) as usize;
            if inner_here == 0 {
                if end != PAD + n {
                    return Err(Error::MalformedTree(format!(
                        "{n} nodes given but the inner flags account for {}",
                        end - PAD
                    )));
                }
                break;
            }
            if level_starts.len() > usize::from(depth) {
                return Err(Error::MalformedTree(format!(
                    "inner nodes at level {depth}, the declared depth"
                )));
            }
            if end + 4 * inner_here > PAD + n {
                return Err(Error::MalformedTree(format!(
                    "level {} needs {} nodes, only {} remain",
                    level_starts.len(),
                    4 * inner_here,
                    PAD + n - end
                )));
            }
            level_starts.push(end);
            (start, end) = (end, end + 4 * inner_here);
        }
        let stored_depth = level_starts.len() - 1;
        let block_bottom = texel_blocks
            .as_ref()
            .map_or(0, |b| usize::from(b.level()) + usize::from(b.log2_side()));
        if stored_depth.max(block_bottom) != usize::from(depth) {
            return Err(Error::MalformedTree(format!(
                "declared depth {depth}, but the nodes reach level {stored_depth}{}",
                if texel_blocks.is_some() {
                    format!(" and the texel blocks level {block_bottom}")
                } else {
                    String::new()
                }
            )));
        }
        level_starts.push(PAD + n);
        Self::finish(depth, aspect, colours, blocks, level_starts, texel_blocks)
            .map(|t| t.with_encoding(encoding))
    }

    /// Completes a tree from validated padded arrays: rank counters and top table.
    fn finish(
        depth: u8,
        aspect: Aspect,
        colours: SharedBytes,
        blocks: Vec<RankBlock>,
        level_starts: Vec<usize>,
        texel_blocks: Option<TexelBlocks>,
    ) -> Result<QuadTree, Error> {
        let block_nodes = match &texel_blocks {
            Some(b) => {
                let l = usize::from(b.level());
                let range = match (level_starts.get(l), level_starts.get(l + 1)) {
                    (Some(&start), Some(&end)) if l + 1 < level_starts.len() => start..end,
                    _ => {
                        return Err(Error::MalformedTree(format!(
                            "texel blocks at level {l}, where the tree has no nodes"
                        )));
                    }
                };
                if b.flag_word_count() != range.len().div_ceil(64)
                    || b.flag_words()
                        .last()
                        .is_some_and(|w| range.len() % 64 != 0 && w >> (range.len() % 64) != 0)
                {
                    return Err(Error::MalformedTree(format!(
                        "texel block flags do not match the {} nodes of level {l}",
                        range.len()
                    )));
                }
                range
            }
            None => 0..0,
        };
        let node_bytes = colours.len() + PAD * std::mem::size_of::<Unorm16Rgba>();
        // Not below the block level: a query starting at a block must start
        // at the block's own level.
        let top_max = texel_blocks
            .as_ref()
            .map_or(MAX_TOP_LEVEL, |b| b.level().min(MAX_TOP_LEVEL));
        let mut top_level = 0u8;
        while top_level < depth.min(top_max)
            && top_table_len(top_level + 1) * 4 <= (node_bytes / 16).max(4096)
        {
            top_level += 1;
        }
        let mut tree = QuadTree {
            depth,
            encoding: ColourEncoding::Unorm16,
            bound_scale: std::sync::OnceLock::new(),
            aspect,
            colours,
            blocks,
            level_starts,
            top_level,
            top: Vec::new(),
            moments: std::sync::OnceLock::new(),
            grid: std::sync::OnceLock::new(),
            texel_blocks,
            block_nodes,
            gradient_leaves: None,
            contour_leaves: None,
        };
        tree.top = tree.build_top_table()?;
        Ok(tree)
    }

    fn build_top_table(&self) -> Result<Vec<u32>, Error> {
        let mut top = crate::memory::try_vec(top_table_len(self.top_level), 0u32, "top table")?;
        top[0] = PAD as u32;
        for l in 1..=self.top_level {
            let side = 1usize << l;
            let (prev, here) = (top_table_offset(l - 1), top_table_offset(l));
            for cz in 0..side {
                for cx in 0..side {
                    let parent = top[prev + (cz / 2) * (side / 2) + cx / 2] as usize;
                    top[here + cz * side + cx] = if self.is_inner(parent) {
                        (self.first_child(parent) + (cx & 1) + 2 * (cz & 1)) as u32
                    } else {
                        parent as u32
                    };
                }
            }
        }
        Ok(top)
    }

    /// The tree with its colours read as `encoding`.
    pub(crate) fn with_encoding(mut self, encoding: ColourEncoding) -> QuadTree {
        self.encoding = encoding;
        self.bound_scale = std::sync::OnceLock::new();
        self
    }

    /// What the error bounds of [`crate::filter::region`], derived for colour
    /// channels in `[0, 1]`, are multiplied by for this tree: 1 for unorm16
    /// colours, the widest channel range (at least 1) for HDR colours (one
    /// pass over the colours, the first time).
    pub fn bound_scale(&self) -> f64 {
        *self.bound_scale.get_or_init(|| match self.encoding {
            ColourEncoding::Unorm16 => 1.0,
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
                (0..4).map(|ch| hi[ch] - lo[ch]).fold(1.0, f64::max)
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

    /// Checks that every inner colour is the average of its children to
    /// within rounding (|4·parent − Σ children| ≤ 4 per channel; for half
    /// floats, within two steps of the larger magnitude).
    fn check_averages(&self) -> Result<(), Error> {
        for p in PAD..PAD + self.node_count() as usize {
            if !self.is_inner(p) {
                continue;
            }
            let c = self.first_child(p);
            if self.encoding == ColourEncoding::Half {
                let parent = self.encoding.decode_colour(self.colour(p));
                for (ch, &stored) in parent.iter().enumerate() {
                    let mean: f64 = (0..4)
                        .map(|k| self.encoding.decode(self.colour(c + k).0[ch]))
                        .sum::<f64>()
                        / 4.0;
                    let scale = stored.abs().max(mean.abs()).max(6.1e-5);
                    if (stored - mean).abs() > scale * (2.0 / 1024.0) {
                        return Err(Error::MalformedTree(format!(
                            "node {}: channel {ch} is {stored} but its children average {mean}",
                            p - PAD
                        )));
                    }
                }
                continue;
            }
            for ch in 0..4 {
                let sum: i64 = (0..4).map(|k| i64::from(self.colour(c + k).0[ch])).sum();
                let parent = 4 * i64::from(self.colour(p).0[ch]);
                if (parent - sum).abs() > 4 {
                    return Err(Error::MalformedTree(format!(
                        "node {}: channel {ch} is {} but its children average {:.1}",
                        p - PAD,
                        self.colour(p).0[ch],
                        sum as f64 / 4.0
                    )));
                }
            }
        }
        Ok(())
    }

    /// Checks that block nodes are terminal and hold their texels' mean
    /// (within rounding: `|n·node − Σ texels| ≤ n` per channel).
    fn check_blocks(&self) -> Result<(), Error> {
        let Some(tb) = &self.texel_blocks else {
            return Ok(());
        };
        tb.check_texels()?;
        for p in self.block_nodes.clone() {
            let Some(b) = tb.block_of(p - self.block_nodes.start) else {
                continue;
            };
            if self.is_inner(p) {
                return Err(Error::MalformedTree(format!(
                    "node {}: a texel block with children",
                    p - PAD
                )));
            }
            let (sum, n) = tb.cell_sum(b, 0, 0, 0);
            for (ch, (&total, &stored)) in sum.iter().zip(&self.colour(p).0).enumerate() {
                if (u64::from(n) * u64::from(stored)).abs_diff(total) > u64::from(n) {
                    return Err(Error::MalformedTree(format!(
                        "node {}: channel {ch} is {stored} but its texel block averages {:.1}",
                        p - PAD,
                        total as f64 / f64::from(n)
                    )));
                }
            }
        }
        Ok(())
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

    /// The finest cell's size in texture units, `[width, height]`: `2^-depth`
    /// scaled up by the aspect's shrink on that axis.
    pub fn finest_cell_size(&self) -> [f64; 2] {
        let [sx, sz] = self.aspect.shrink;
        let side = |s: u8| unit_side(self.depth - s.min(self.depth));
        [side(sx), side(sz)]
    }

    /// Columns and rows of the finest grid over the texture:
    /// `[2^(depth−sx), 2^(depth−sz)]`, at least one each.
    pub fn finest_grid(&self) -> [u64; 2] {
        let [sx, sz] = self.aspect.shrink;
        [
            1u64 << self.depth.saturating_sub(sx),
            1u64 << self.depth.saturating_sub(sz),
        ]
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

    /// Columns and rows of [`QuadTree::rasterise`] at `level`: `2^level`
    /// shrunk by the aspect, at least one.
    pub fn raster_size(&self, level: u8) -> [u32; 2] {
        let [sx, sz] = self.aspect.shrink;
        let cells = |s: u8| 1u32 << level.saturating_sub(s).min(31);
        [cells(sx), cells(sz)]
    }

    /// Bytes [`QuadTree::rasterise`] allocates at `level` (8 a cell) for a
    /// square texture, an upper bound for others.
    pub fn rasterise_bytes(level: u8) -> u64 {
        8u64 << (2 * u32::from(level.min(31)))
    }

    #[inline]
    fn is_inner(&self, p: usize) -> bool {
        self.blocks[p / 64].bits >> (p % 64) & 1 == 1
    }

    /// Padded index of the first child of the inner node at padded index `p`.
    #[inline]
    fn first_child(&self, p: usize) -> usize {
        let b = self.blocks[p / 64];
        let below = b.bits & ((1u64 << (p % 64)) - 1);
        4 + 4 * (b.rank as usize + below.count_ones() as usize)
    }

    /// The texel block ending the stored node at padded index `p`, if any.
    #[inline]
    fn block_at(&self, p: usize) -> Option<usize> {
        if !self.block_nodes.contains(&p) {
            return None;
        }
        self.texel_blocks
            .as_ref()?
            .block_of(p - self.block_nodes.start)
    }

    /// The root.
    pub(crate) const ROOT: NodeRef = NodeRef(PAD as u128);

    /// Whether node `n` has children (an inner node, a texel block, or a
    /// block's cell larger than a texel and not uniform), and its colour in
    /// `[0, 1]` (a cell's is the exact mean of its texels).
    #[inline]
    pub(crate) fn node_info(&self, n: NodeRef) -> (bool, [f64; 4]) {
        let (inner, colour, _) = self.node_detail(n);
        (inner, colour)
    }

    /// [`QuadTree::node_info`], and a bound on how far the colour at any
    /// point of the node's square may be from its colour, per channel, for
    /// colours in `[0, 1]`: 1, but in gradient leaves and their cells,
    /// whose colour range is known.
    #[inline]
    pub(crate) fn node_detail(&self, n: NodeRef) -> (bool, [f64; 4], f64) {
        if let Some((leaf, j, ix, iz)) = n.as_gradient_cell() {
            let gradients = self.gradient_leaf_count();
            return match (&self.gradient_leaves, &self.contour_leaves) {
                (Some(g), _) if leaf < gradients => g.cell_info(leaf, j, ix, iz),
                (_, Some(c)) => c.cell_info(leaf - gradients, j, ix, iz),
                _ => (false, [0.0; 4], 0.0),
            };
        }
        if n.as_cell().is_none() {
            let p = n.0 as usize;
            if let Some((leaf, g)) = self.gradient_leaf(p) {
                let (level, ix, iz) = g.square(leaf);
                let poly = square_corners(level, ix.into(), iz.into());
                let (splits, contrast) = g.split_and_contrast(leaf, 0, level, &poly);
                let colour = self.encoding.decode_colour(self.colour(p));
                return (splits, colour, contrast);
            }
            if let Some((leaf, c)) = self.contour_leaf(p) {
                let (level, _, _) = c.square(leaf);
                let colour = self.encoding.decode_colour(self.colour(p));
                return (level < self.depth, colour, 1.0);
            }
        }
        let (inner, colour) = match (n.as_cell(), &self.texel_blocks) {
            (Some((b, j, ix, iz)), Some(tb)) => (
                j < tb.log2_side() && !tb.cell_is_uniform(b, j, ix, iz),
                tb.cell_mean(b, j, ix, iz),
            ),
            _ => {
                let p = n.0 as usize;
                let c = self.encoding.decode_colour(self.colour(p));
                (self.is_inner(p) || self.block_at(p).is_some(), c)
            }
        };
        // A stored terminal square is uniform: its colour is exact over it.
        (inner, colour, if inner { 1.0 } else { 0.0 })
    }

    /// The colour of cell `(cx, cz)` of the grid at [`QuadTree::depth`]
    /// when a uniform square holds it (a texel of a block, or a stored
    /// terminal square), as [`QuadTree::node_detail`] gives that square's;
    /// `None` under a gradient or contour leaf (its colour varies within
    /// it) or when the cell is not under node `n` at `(level, ix, iz)`.
    pub(crate) fn finest_colour(
        &self,
        mut n: NodeRef,
        level: u8,
        ix: u32,
        iz: u32,
        cx: u32,
        cz: u32,
    ) -> Option<[f64; 4]> {
        let mut down = self.depth.checked_sub(level)?;
        if down >= 32 || cx >> down != ix || cz >> down != iz {
            return None;
        }
        while self.splits_fully(n) {
            down = down.checked_sub(1)?;
            let c = (cx >> down & 1) | (cz >> down & 1) << 1;
            n = self.child_ref(n, c as usize);
        }
        // A terminal square (a texel, a stored square, a gradient or
        // contour leaf): uniform where it neither splits nor varies.
        let (inner, colour, contrast) = self.node_detail(n);
        (!inner && contrast == 0.0).then_some(colour)
    }

    /// Whether the tree is a plain raster: square, its finest level made of
    /// texel blocks ([`QuadTree::texel_blocks`], their texels at
    /// [`QuadTree::depth`]), with no gradient or contour leaves. Every
    /// cell of the grid at the depth then lies under a texel or a stored
    /// terminal square, found by a descent of stored nodes alone
    /// ([`QuadTree::finest_cell`]).
    pub(crate) fn is_plain_raster(&self) -> bool {
        self.aspect.is_square()
            && self.gradient_leaves.is_none()
            && self.contour_leaves.is_none()
            && self
                .texel_blocks
                .as_ref()
                .is_some_and(|tb| tb.level() + tb.log2_side() == self.depth)
    }

    /// The root's square.
    pub(crate) const ROOT_SQUARE: StoredSquare = StoredSquare {
        p: PAD,
        level: 0,
        ix: 0,
        iz: 0,
    };

    /// What stored square `s` is.
    #[inline]
    pub(crate) fn stored_kind(&self, s: StoredSquare) -> StoredKind {
        if let Some(b) = self.block_at(s.p) {
            StoredKind::Block(b)
        } else if self.is_inner(s.p) {
            StoredKind::Inner
        } else {
            StoredKind::Terminal
        }
    }

    /// The smallest square of the top table ([`QuadTree::top_level`]) at
    /// level `max_level` or above that holds the box `x × z` (tree space,
    /// half-open), and its node: the square's own, or its terminal
    /// ancestor's.
    #[inline]
    fn top_square(&self, x: (f64, f64), z: (f64, f64), max_level: u8) -> StoredSquare {
        let t = self.top_level;
        let scale = f64::from(1u32 << t);
        let last = (1u32 << t) - 1;
        // `as` saturates: NaN and negatives give 0, the far side `last`.
        let cx0 = ((x.0 * scale) as u32).min(last);
        let cz0 = ((z.0 * scale) as u32).min(last);
        let cx1 = (((x.1 * scale).ceil() as u32).max(1) - 1).clamp(cx0, last);
        let cz1 = (((z.1 * scale).ceil() as u32).max(1) - 1).clamp(cz0, last);
        let diverge = (32 - (cx0 ^ cx1).leading_zeros()).max(32 - (cz0 ^ cz1).leading_zeros());
        let level = (t - diverge as u8).min(max_level);
        let shift = t - level;
        let (ix, iz) = (cx0 >> shift, cz0 >> shift);
        StoredSquare {
            p: self.top[top_table_offset(level) + ((iz as usize) << level) + ix as usize] as usize,
            level,
            ix,
            iz,
        }
    }

    /// The deepest stored square holding the box `x × z` (tree space,
    /// half-open: a box ending on a square's middle line lies in its low
    /// half) under no block: a texel block, a terminal square, or the inner
    /// square whose middle lines the box crosses. The top table
    /// ([`QuadTree::top_level`]) takes it down its levels in one step.
    pub(crate) fn stored_square_holding(&self, x: (f64, f64), z: (f64, f64)) -> StoredSquare {
        let mut s = self.top_square(x, z, self.top_level);
        if s.level < self.top_level {
            return s;
        }
        while self.stored_kind(s) == StoredKind::Inner {
            let side = unit_side(s.level + 1);
            let (mx, mz) = (
                f64::from(2 * s.ix + 1) * side,
                f64::from(2 * s.iz + 1) * side,
            );
            let hx = match (x.1 <= mx, x.0 >= mx) {
                (true, _) => 0,
                (_, true) => 1,
                _ => break,
            };
            let hz = match (z.1 <= mz, z.0 >= mz) {
                (true, _) => 0,
                (_, true) => 1,
                _ => break,
            };
            s = self.stored_child(s, hx, hz);
        }
        s
    }

    /// Child `(hx, hz)` (0 low, 1 high) of inner stored square `s`.
    #[inline]
    pub(crate) fn stored_child(&self, s: StoredSquare, hx: u32, hz: u32) -> StoredSquare {
        StoredSquare {
            p: self.first_child(s.p) + (hx + 2 * hz) as usize,
            level: s.level + 1,
            ix: 2 * s.ix + hx,
            iz: 2 * s.iz + hz,
        }
    }

    /// The colour of terminal stored square `s`; `None` when it is not
    /// terminal, or is a gradient or contour leaf (its colour varies).
    #[inline]
    pub(crate) fn terminal_cell(&self, s: StoredSquare) -> Option<FinestCell> {
        (self.stored_kind(s) == StoredKind::Terminal)
            .then(|| self.terminal_colour(s))
            .flatten()
    }

    /// [`QuadTree::terminal_cell`] of a square known to be terminal.
    #[inline]
    fn terminal_colour(&self, s: StoredSquare) -> Option<FinestCell> {
        (self.gradient_leaf(s.p).is_none() && self.contour_leaf(s.p).is_none())
            .then(|| FinestCell::Square(self.encoding.decode_colour(self.colour(s.p))))
    }

    /// A reader of cells under stored square `from`
    /// ([`QuadTree::finest_cell`]), which reads a block's texels directly
    /// when `from` is one (a box of a few texels, most often).
    #[inline]
    pub(crate) fn cells_below(&self, from: StoredSquare) -> CellReader<'_> {
        let block = match (self.stored_kind(from), &self.texel_blocks) {
            (StoredKind::Block(b), Some(tb))
                if u32::from(from.level) + u32::from(tb.log2_side()) == u32::from(self.depth) =>
            {
                Some((b, tb))
            }
            _ => None,
        };
        CellReader {
            tree: self,
            from,
            block,
        }
    }

    /// What covers cell `(cx, cz)` of the grid at [`QuadTree::depth`] in a
    /// plain raster ([`QuadTree::is_plain_raster`]): a texel, or a stored
    /// terminal square; found from stored square `from` when the cell lies
    /// under it, else from the root. `None` past the grid (or in a tree
    /// that is not a plain raster).
    #[inline]
    pub(crate) fn finest_cell(&self, from: StoredSquare, cx: u32, cz: u32) -> Option<FinestCell> {
        let tb = self.texel_blocks.as_ref()?;
        let under = |s: StoredSquare| {
            self.depth
                .checked_sub(s.level)
                .is_some_and(|down| down < 32 && cx >> down == s.ix && cz >> down == s.iz)
        };
        let mut s = if under(from) {
            from
        } else if under(QuadTree::ROOT_SQUARE) {
            QuadTree::ROOT_SQUARE
        } else {
            return None;
        };
        loop {
            match self.stored_kind(s) {
                // Checked once per cell: the block is at the level its
                // texels fill down to the depth.
                StoredKind::Block(b)
                    if u32::from(s.level) + u32::from(tb.log2_side()) == u32::from(self.depth) =>
                {
                    return block_texel(tb, b, s, cx, cz);
                }
                StoredKind::Block(_) => return None,
                StoredKind::Terminal => return self.terminal_colour(s),
                StoredKind::Inner => {
                    let below = u32::from(self.depth.checked_sub(s.level + 1)?);
                    if below >= 32 {
                        return None;
                    }
                    s = self.stored_child(s, cx >> below & 1, cz >> below & 1);
                }
            }
        }
    }

    /// Whether node `n` has four children and the full contrast bound (1)
    /// of [`QuadTree::node_detail`], without its colour: a stored inner
    /// node or texel block, or a block's cell above its texels. A cell
    /// whose texels happen to be one colour counts too (its children are
    /// that colour as well). Gradient and contour leaves do not (their
    /// contrast is their own).
    #[inline]
    pub(crate) fn splits_fully(&self, n: NodeRef) -> bool {
        if n.as_gradient_cell().is_some() {
            return false;
        }
        if let Some((_, j, _, _)) = n.as_cell() {
            return self
                .texel_blocks
                .as_ref()
                .is_some_and(|tb| j < tb.log2_side());
        }
        // Gradient and contour leaves are stored terminal squares.
        let p = n.0 as usize;
        self.is_inner(p) || self.block_at(p).is_some()
    }

    /// Child `c` (`low-x low-z, high-x low-z, low-x high-z, high-x high-z`)
    /// of node `n`, which has children ([`QuadTree::node_info`]).
    #[inline]
    pub(crate) fn child_ref(&self, n: NodeRef, c: usize) -> NodeRef {
        let (hx, hz) = ((c & 1) as u32, (c >> 1) as u32);
        if let Some((leaf, j, ix, iz)) = n.as_gradient_cell() {
            return NodeRef::gradient_cell(leaf, j + 1, 2 * ix + hx, 2 * iz + hz);
        }
        if let Some((b, j, ix, iz)) = n.as_cell() {
            return NodeRef::cell(b, j + 1, 2 * ix + hx, 2 * iz + hz);
        }
        let p = n.0 as usize;
        match self.block_at(p) {
            Some(b) => NodeRef::cell(b, 1, hx, hz),
            None if !self.is_inner(p) => match (self.gradient_leaf(p), self.contour_leaf(p)) {
                (Some((leaf, _)), _) => NodeRef::gradient_cell(leaf, 1, hx, hz),
                (_, Some((leaf, _))) => {
                    NodeRef::gradient_cell(self.gradient_leaf_count() + leaf, 1, hx, hz)
                }
                _ => NodeRef::stored(self.first_child(p) + c),
            },
            None => NodeRef::stored(self.first_child(p) + c),
        }
    }

    /// Adds to `acc` (unorm16 units × area) the integral over the fragment
    /// `[x0,x1) × [z0,z1)` (tree space) of texel block `b`, whose square at
    /// `level` has its low corner at `lo` and side `side`, its texels
    /// grouped into cells at level `k` (`> level`) or finer.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    fn add_block(
        &self,
        acc: &mut [f64; 4],
        b: usize,
        level: u8,
        lo: [f64; 2],
        side: f64,
        k: u8,
        [x0, z0, x1, z1]: [f64; 4],
    ) {
        let Some(tb) = &self.texel_blocks else {
            return;
        };
        let j = (k - level).min(tb.log2_side());
        let n = 1u32 << j;
        let cell = side / f64::from(n);
        let range = |a: f64, b: f64, lo: f64| {
            let first = (((a - lo) / cell).floor().max(0.0) as u32).min(n - 1);
            let last = ((((b - lo) / cell).ceil().max(1.0) as u32) - 1).clamp(first, n - 1);
            first..=last
        };
        if j == tb.log2_side() {
            // Texel by texel: separable weights, the overlap of each column
            // and each row (in cell areas, so each texel counts its value).
            let (xs, zs) = (range(x0, x1, lo[0]), range(z0, z1, lo[1]));
            let weights = |a: f64, b: f64, lo: f64, r: &std::ops::RangeInclusive<u32>| {
                let mut w = [0f64; 16];
                for i in r.clone() {
                    let c0 = lo + f64::from(i) * cell;
                    w[i as usize] = overlap_1d(a, b, c0, c0 + cell);
                }
                w
            };
            let (wx, wz) = (weights(x0, x1, lo[0], &xs), weights(z0, z1, lo[1], &zs));
            tb.add_weighted(acc, b, (&wx, xs), (&wz, zs));
            return;
        }
        for cz in range(z0, z1, lo[1]) {
            let (c0, c1) = (
                lo[1] + f64::from(cz) * cell,
                lo[1] + f64::from(cz + 1) * cell,
            );
            let dz = overlap_1d(z0, z1, c0, c1);
            if dz <= 0.0 {
                continue;
            }
            for cx in range(x0, x1, lo[0]) {
                let (c0, c1) = (
                    lo[0] + f64::from(cx) * cell,
                    lo[0] + f64::from(cx + 1) * cell,
                );
                let area = overlap_1d(x0, x1, c0, c1) * dz;
                if area <= 0.0 {
                    continue;
                }
                let (sum, count) = tb.cell_sum(b, j, cx, cz);
                let w = area / f64::from(count);
                for (a, s) in acc.iter_mut().zip(sum) {
                    *a += w * s as f64;
                }
            }
        }
    }

    /// The exact integral (unorm16 units × area) of the gradient or
    /// contour leaf at padded index `p`, if it is one above level `k`, over
    /// the rectangle `[x0, x1) × [z0, z1)` of tree space inside its square.
    #[inline(never)]
    fn leaf_integral(&self, p: usize, k: u8, [x0, z0, x1, z1]: [f64; 4]) -> Option<[f64; 4]> {
        let area = (x1 - x0).max(0.0) * (z1 - z0).max(0.0);
        if let Some((leaf, g)) = self.gradient_leaf(p) {
            if g.square(leaf).0 >= k {
                return None;
            }
            if area <= 0.0 {
                return Some([0.0; 4]);
            }
            let mean = g
                .paint(leaf)
                .mean_over(&[[x0, z0], [x1, z0], [x1, z1], [x0, z1]]);
            return Some(mean.map(|m| m * 65535.0 * area));
        }
        let (leaf, c) = self.contour_leaf(p)?;
        if c.square(leaf).0 >= k {
            return None;
        }
        if area <= 0.0 {
            return Some([0.0; 4]);
        }
        Some(c.integral(leaf, [x0, z0, x1, z1]).0.map(|v| v * 65535.0))
    }

    /// The colour of the fragment's overlap with the unit square when every
    /// point of it has that colour: one terminal square holds all of it, or
    /// the few terminal squares (texels of a raster block) it overlaps all
    /// hold the same colour. Found by descending through the squares that
    /// enclose the fragment, then through at most
    /// [`UNIFORM_SEARCH_NODES`] squares below the first one it straddles;
    /// `None` when the overlap is empty, crosses a border between squares
    /// whose colours differ, overlaps a gradient or contour leaf, or needs a
    /// longer search. Renderers use it to skip cutting footprints that lie
    /// in a uniform region.
    pub fn uniform_colour(&self, fragment: &Fragment) -> Option<Rgba> {
        let f = self.aspect.tree_fragment(fragment)?;
        let mut node = PAD;
        let (mut level, mut ix, mut iz) = (0u8, 0u64, 0u64);
        loop {
            if let Some(b) = self.block_at(node) {
                return self
                    .uniform_in_block(b, level, ix, iz, &f)
                    .map(Unorm16Rgba::to_rgba);
            }
            if !self.is_inner(node) {
                if self.gradient_leaf(node).is_some() || self.contour_leaf(node).is_some() {
                    return None;
                }
                let [r, g, b, a] = self.encoding.decode_colour(self.colour(node));
                return Some(Rgba::new(r as f32, g as f32, b as f32, a as f32));
            }
            let child_level = level + 1;
            let side = unit_side(child_level);
            let (mx, mz) = ((2 * ix + 1) as f64 * side, (2 * iz + 1) as f64 * side);
            // Half-open: the fragment lies in one half iff it does not cross the middle.
            let hx = if f.x1() <= mx {
                0
            } else if f.x0() >= mx {
                1
            } else {
                return self.uniform_below(node, level, ix, iz, &f);
            };
            let hz = if f.z1() <= mz {
                0
            } else if f.z0() >= mz {
                1
            } else {
                return self.uniform_below(node, level, ix, iz, &f);
            };
            node = self.first_child(node) + hx + 2 * hz;
            (level, ix, iz) = (child_level, 2 * ix + hx as u64, 2 * iz + hz as u64);
        }
    }

    /// [`QuadTree::uniform_colour`] from inner node `node` at
    /// `(level, ix, iz)`, which `f` (tree space) straddles: the one colour
    /// of every terminal square under `node` that `f` overlaps (half-open),
    /// if they share one and at most [`UNIFORM_SEARCH_NODES`] squares tell.
    fn uniform_below(
        &self,
        node: usize,
        level: u8,
        ix: u64,
        iz: u64,
        f: &Fragment,
    ) -> Option<Rgba> {
        let mut stack = [(0usize, 0u8, 0u64, 0u64); UNIFORM_SEARCH_NODES];
        stack[0] = (node, level, ix, iz);
        let (mut len, mut visited) = (1, 1);
        let mut colour: Option<Rgba> = None;
        while len > 0 {
            len -= 1;
            let (node, level, ix, iz) = stack[len];
            let here = if let Some(b) = self.block_at(node) {
                self.uniform_in_block(b, level, ix, iz, f)?.to_rgba()
            } else if !self.is_inner(node) {
                if self.gradient_leaf(node).is_some() || self.contour_leaf(node).is_some() {
                    return None;
                }
                let [r, g, b, a] = self.encoding.decode_colour(self.colour(node));
                Rgba::new(r as f32, g as f32, b as f32, a as f32)
            } else {
                let child_level = level + 1;
                let side = unit_side(child_level);
                let (mx, mz) = ((2 * ix + 1) as f64 * side, (2 * iz + 1) as f64 * side);
                let first = self.first_child(node);
                for hz in 0..2u64 {
                    let overlaps_z = if hz == 0 { f.z0() < mz } else { f.z1() > mz };
                    for hx in 0..2u64 {
                        let overlaps_x = if hx == 0 { f.x0() < mx } else { f.x1() > mx };
                        if !(overlaps_x && overlaps_z) {
                            continue;
                        }
                        if visited == UNIFORM_SEARCH_NODES {
                            return None;
                        }
                        visited += 1;
                        stack[len] = (
                            first + (hx + 2 * hz) as usize,
                            child_level,
                            2 * ix + hx,
                            2 * iz + hz,
                        );
                        len += 1;
                    }
                }
                continue;
            };
            match colour {
                None => colour = Some(here),
                Some(c) if c == here => {}
                Some(_) => return None,
            }
        }
        colour
    }

    /// The texel under all of fragment `f` (tree space) inside block `b` of
    /// square `(level, ix, iz)`, if one colour covers it.
    fn uniform_in_block(
        &self,
        b: usize,
        level: u8,
        ix: u64,
        iz: u64,
        f: &Fragment,
    ) -> Option<Unorm16Rgba> {
        let tb = self.texel_blocks.as_ref()?;
        let n = tb.side();
        let side = unit_side(level);
        let cell = side / f64::from(n);
        let (lo_x, lo_z) = (ix as f64 * side, iz as f64 * side);
        let range = |a: f64, b: f64, lo: f64| {
            let first = (((a - lo) / cell).floor().max(0.0) as u32).min(n - 1);
            let last = ((((b - lo) / cell).ceil().max(1.0) as u32) - 1).clamp(first, n - 1);
            first..=last
        };
        let (xs, zs) = (range(f.x0(), f.x1(), lo_x), range(f.z0(), f.z1(), lo_z));
        let first = tb.texel(b, *xs.start(), *zs.start());
        zs.into_iter()
            .all(|tz| xs.clone().all(|tx| tb.texel(b, tx, tz) == first))
            .then_some(first)
    }

    /// The weighted colour (integral of colour over area) of the fragment's
    /// overlap with the unit square, from a traversal down to level
    /// `max_level` (clamped to [`QuadTree::depth`]). The fragment and the
    /// area are in texture units; levels are the tree's ([`Aspect`]).
    ///
    /// Squares inside the fragment count whole at the highest level they
    /// exist, squares at `max_level` or terminal count by their overlap, as in
    /// the paper. Against the exact integral of the tree truncated at
    /// `max_level` the result is off by float rounding plus at most half a
    /// storage step per channel times the area taken from inner nodes
    /// (`≤ 0.5/65535 × area`): an inner colour is the exact mean of its
    /// region rounded once to 16 bits.
    pub fn weighted_colour(&self, fragment: &Fragment, max_level: u8) -> WeightedColour {
        self.weighted_colour_counted(fragment, max_level, &mut TraversalStats::default())
    }

    /// As [`QuadTree::weighted_colour`], adding the query's cost to `stats`.
    pub fn weighted_colour_counted(
        &self,
        fragment: &Fragment,
        max_level: u8,
        stats: &mut TraversalStats,
    ) -> WeightedColour {
        match self.encoding {
            ColourEncoding::Half => self.integrate::<true>(fragment, max_level, stats),
            _ => self.integrate::<false>(fragment, max_level, stats),
        }
    }

    /// The traversal; colours in unorm16 units (half floats scaled by 65535).
    #[inline]
    fn integrate<const HALF: bool>(
        &self,
        fragment: &Fragment,
        max_level: u8,
        stats: &mut TraversalStats,
    ) -> WeightedColour {
        {
            stats.queries += 1;
        }
        let Some(f) = self.aspect.tree_fragment(fragment) else {
            return WeightedColour::ZERO;
        };
        let ratio = self.aspect.area_ratio();
        let result = |acc: [f64; 4]| scaled(acc.map(|a| a * ratio));
        let k = max_level.min(self.depth);
        let (x0, z0, x1, z1) = (f.x0(), f.z0(), f.x1(), f.z1());

        // Start at the smallest square of level <= min(k, top_level) enclosing the fragment.
        let StoredSquare {
            p: start,
            level,
            ix: sx,
            iz: sz,
        } = self.top_square((x0, x1), (z0, z1), k);

        {
            stats.nodes_visited += 1;
        }
        if level < k
            && let Some(b) = self.block_at(start)
        {
            let side = unit_side(level);
            let lo = [f64::from(sx) * side, f64::from(sz) * side];
            let mut acc = [0f64; 4];
            self.add_block(&mut acc, b, level, lo, side, k, [x0, z0, x1, z1]);
            return result(acc);
        }
        if !self.is_inner(start)
            && let Some(w) = self.leaf_integral(start, k, [x0, z0, x1, z1])
        {
            return result(w);
        }
        if level >= k || !self.is_inner(start) {
            return result(weigh::<HALF>(self.colour(start), f.area()));
        }
        let side = unit_side(level);
        let (lo_x, lo_z) = (f64::from(sx) * side, f64::from(sz) * side);
        let vx = variant::classify(x0, x1, lo_x, lo_x + side);
        let vz = variant::classify(z0, z1, lo_z, lo_z + side);
        if vx == variant::SQUARE_INSIDE && vz == variant::SQUARE_INSIDE {
            return result(weigh::<HALF>(self.colour(start), side * side));
        }

        let mut acc = [0f64; 4];
        let mut visited = 0u64;
        // The pending squares live in a buffer kept per thread: a fresh
        // array would be zeroed on every query (3 KiB), a cost measurable
        // against the whole of a small one.
        PENDING.with_borrow_mut(|stack| {
            stack.clear();
            stack.push(Pending {
                node: start as u32,
                level,
                vx,
                vz,
                lo_x,
                lo_z,
            });
            while let Some(Pending {
                node,
                level,
                vx,
                vz,
                lo_x,
                lo_z,
            }) = stack.pop()
            {
                let child_level = level + 1;
                let half = unit_side(child_level);
                let child_area = half * half;
                let (mx, mz) = (lo_x + half, lo_z + half);
                let vxs = [
                    variant::f_low(x0, x1, mx, vx),
                    variant::f_high(x0, x1, mx, vx),
                ];
                let vzs = [
                    variant::f_low(z0, z1, mz, vz),
                    variant::f_high(z0, z1, mz, vz),
                ];
                let first = self.first_child(node as usize);
                let block = self.blocks[first / 64].bits >> (first % 64);
                let descend_allowed = child_level < k;
                for c in 0..4 {
                    let (cvx, cvz): (Variant, Variant) = (vxs[c & 1], vzs[c >> 1]);
                    if variant::is_disjoint(cvx) || variant::is_disjoint(cvz) {
                        continue;
                    }
                    visited += 1;
                    let colour = self.colour(first + c);
                    let (clo_x, clo_z) =
                        (lo_x + (c & 1) as f64 * half, lo_z + (c >> 1) as f64 * half);
                    if cvx == variant::SQUARE_INSIDE && cvz == variant::SQUARE_INSIDE {
                        add::<HALF>(&mut acc, colour, child_area);
                    } else if block >> c & 1 == 0 || !descend_allowed {
                        match self.block_at(first + c).filter(|_| descend_allowed) {
                            Some(b) => self.add_block(
                                &mut acc,
                                b,
                                child_level,
                                [clo_x, clo_z],
                                half,
                                k,
                                [x0, z0, x1, z1],
                            ),
                            None => {
                                let (ox0, ox1) = (x0.max(clo_x), x1.min(clo_x + half));
                                let (oz0, oz1) = (z0.max(clo_z), z1.min(clo_z + half));
                                let leaves =
                                    self.gradient_leaves.is_some() || self.contour_leaves.is_some();
                                match leaves
                                    .then(|| self.leaf_integral(first + c, k, [ox0, oz0, ox1, oz1]))
                                    .flatten()
                                {
                                    Some(w) => {
                                        for (a, v) in acc.iter_mut().zip(w) {
                                            *a += v;
                                        }
                                    }
                                    None => {
                                        let area = overlap_1d(x0, x1, clo_x, clo_x + half)
                                            * overlap_1d(z0, z1, clo_z, clo_z + half);
                                        add::<HALF>(&mut acc, colour, area);
                                    }
                                }
                            }
                        }
                    } else {
                        stack.push(Pending {
                            node: (first + c) as u32,
                            level: child_level,
                            vx: cvx,
                            vz: cvz,
                            lo_x: clo_x,
                            lo_z: clo_z,
                        });
                    }
                }
            }
        });
        {
            stats.nodes_visited += visited;
        }
        result(acc)
    }
}

thread_local! {
    /// The traversal's pending squares: depth first, each level leaves at
    /// most three siblings pending, so at most `3 · depth + 1`.
    static PENDING: std::cell::RefCell<Vec<Pending>> =
        std::cell::RefCell::new(Vec::with_capacity(4 * MAX_DEPTH as usize + 8));
}

#[derive(Debug, Clone, Copy, Default)]
struct Pending {
    node: u32,
    level: u8,
    vx: Variant,
    vz: Variant,
    lo_x: f64,
    lo_z: f64,
}

/// A stored channel in unorm16 units: the integer, or a half float × 65535.
#[inline(always)]
fn units<const HALF: bool>(c: u16) -> f64 {
    if HALF {
        f64::from(half::f16::from_bits(c).to_f32()) * 65535.0
    } else {
        f64::from(c)
    }
}

#[inline]
fn add<const HALF: bool>(acc: &mut [f64; 4], colour: Unorm16Rgba, area: f64) {
    for (a, &c) in acc.iter_mut().zip(&colour.0) {
        *a += area * units::<HALF>(c);
    }
}

#[inline]
fn weigh<const HALF: bool>(colour: Unorm16Rgba, area: f64) -> [f64; 4] {
    colour.0.map(|c| area * units::<HALF>(c))
}

#[inline]
fn scaled(acc: [f64; 4]) -> WeightedColour {
    WeightedColour(acc.map(|a| a * (1.0 / 65535.0)))
}

fn top_table_offset(level: u8) -> usize {
    ((1usize << (2 * level)) - 1) / 3
}

fn top_table_len(top_level: u8) -> usize {
    top_table_offset(top_level + 1)
}

/// Assembles a tree from per-level node lists produced by the builder
/// (already valid by construction).
pub(crate) fn from_levels(
    levels: Vec<Vec<(bool, Unorm16Rgba)>>,
    aspect: Aspect,
) -> Result<QuadTree, Error> {
    from_levels_with_blocks(levels, aspect, None)
}

/// As [`from_levels`], with texel blocks ending squares of their level.
pub(crate) fn from_levels_with_blocks(
    levels: Vec<Vec<(bool, Unorm16Rgba)>>,
    aspect: Aspect,
    texel_blocks: Option<TexelBlocks>,
) -> Result<QuadTree, Error> {
    from_levels_encoded(levels, aspect, texel_blocks, ColourEncoding::Unorm16)
}

/// As [`from_levels_with_blocks`], colours stored as `encoding`.
pub(crate) fn from_levels_encoded(
    levels: Vec<Vec<(bool, Unorm16Rgba)>>,
    aspect: Aspect,
    texel_blocks: Option<TexelBlocks>,
    encoding: ColourEncoding,
) -> Result<QuadTree, Error> {
    let block_bottom = texel_blocks
        .as_ref()
        .map_or(0, |b| b.level() + b.log2_side());
    let depth = ((levels.len() - 1) as u8).max(block_bottom);
    let n: usize = levels.iter().map(Vec::len).sum();
    let mut colours = crate::memory::try_with_capacity(8 * n, "tree colours")?;
    let mut blocks = crate::memory::try_vec(
        (PAD + n).div_ceil(64),
        RankBlock::default(),
        "tree inner flags",
    )?;
    let mut level_starts = Vec::with_capacity(levels.len() + 1);
    let mut p = PAD;
    for level in levels {
        level_starts.push(p);
        for (inner, colour) in level {
            if inner {
                blocks[p / 64].bits |= 1 << (p % 64);
            }
            for v in colour.0 {
                colours.extend(v.to_le_bytes());
            }
            p += 1;
        }
    }
    level_starts.push(p);
    fill_ranks(&mut blocks);
    QuadTree::finish(
        depth,
        aspect,
        colours.into(),
        blocks,
        level_starts,
        texel_blocks,
    )
    .map(|t| t.with_encoding(encoding))
}

/// Padded rank blocks for `n` nodes whose inner flags are `word(k)` (bits
/// `64k..64k+64` of the unpadded flags; bits past `n` are ignored).
fn rank_blocks(n: usize, word: impl Fn(usize) -> u64) -> Result<Vec<RankBlock>, Error> {
    let words = n.div_ceil(64);
    let masked = |k: usize| match k {
        k if k >= words => 0,
        k if !n.is_multiple_of(64) && k + 1 == words => word(k) & ((1u64 << (n % 64)) - 1),
        k => word(k),
    };
    let mut blocks = crate::memory::try_vec(
        (PAD + n).div_ceil(64),
        RankBlock::default(),
        "tree inner flags",
    )?;
    let mut carry = 0u64;
    for (j, b) in blocks.iter_mut().enumerate() {
        let w = masked(j);
        b.bits = w << PAD | carry;
        carry = w >> (64 - PAD);
    }
    fill_ranks(&mut blocks);
    Ok(blocks)
}

/// Inner nodes at padded indices below `p`, from ranked `blocks`.
fn inner_before(blocks: &[RankBlock], p: usize) -> u64 {
    match blocks.get(p / 64) {
        Some(b) => b.rank + u64::from((b.bits & ((1u64 << (p % 64)) - 1)).count_ones()),
        None => blocks
            .last()
            .map_or(0, |b| b.rank + u64::from(b.bits.count_ones())),
    }
}

/// Sets each rank block's count of inner nodes before it.
fn fill_ranks(blocks: &mut [RankBlock]) {
    let mut rank = 0u64;
    for b in blocks {
        b.rank = rank;
        rank += u64::from(b.bits.count_ones());
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::{BuildOptions, TexelGrid};
    use arbtest::arbitrary::Unstructured;

    /// A photograph-like raster `side × side` (8 to 128 texels): noisy
    /// texels, with uniform 4 × 4 blocks and uniform 16 × 16 squares
    /// among them (stored terminal squares above the block level).
    fn photo(u: &mut Unstructured<'_>) -> arbtest::arbitrary::Result<QuadTree> {
        let side = 1u32 << u.int_in_range(3..=7u32)?;
        let mut bytes = Vec::with_capacity((side * side) as usize);
        let (big, small) = (side.div_ceil(16), side / 4);
        let mut flat = |n: u32| -> arbtest::arbitrary::Result<Vec<Option<u8>>> {
            (0..n * n)
                .map(|_| Ok(u.ratio(1, 3)?.then_some(*u.choose(&[0u8, 90, 255])?)))
                .collect()
        };
        let (big_flat, small_flat) = (flat(big)?, flat(small)?);
        for k in 0..side * side {
            let (c, r) = (k % side, k / side);
            let v = match (big_flat[((r / 16) * big + c / 16) as usize])
                .or(small_flat[((r / 4) * small + c / 4) as usize])
            {
                Some(v) => v,
                None => *u.choose(&[0u8, 40, 128, 200, 255])?,
            };
            bytes.push([v, 255 - v, v / 2, 255]);
        }
        let grid = TexelGrid::from_srgb8(side, side, bytes).unwrap();
        Ok(QuadTree::from_texels(&grid, &BuildOptions::default())
            .unwrap()
            .0)
    }

    fn interval(u: &mut Unstructured<'_>) -> arbtest::arbitrary::Result<(f64, f64)> {
        let a = f64::from(u.int_in_range(0..=1 << 20u32)?) / f64::from(1 << 20u32);
        let b = a + f64::from(u.int_in_range(0..=1 << 16u32)?) / f64::from(1 << 20u32);
        Ok((a, b.min(1.0)))
    }

    /// Every cell's colour read by the stored descent (from the root, and
    /// from the square holding a box around it) is the one the traversals'
    /// node descent gives ([`QuadTree::finest_colour`]), to the bit.
    #[test]
    fn finest_cells_are_what_the_node_descent_finds() {
        arbtest::arbtest(|u| {
            let tree = photo(u)?;
            // An image of uniform squares alone has no texel blocks.
            if tree.texel_blocks().is_none() {
                return Ok(());
            }
            assert!(tree.is_plain_raster());
            let n = 1u32 << tree.depth();
            let h = unit_side(tree.depth());
            for cz in 0..n {
                for cx in 0..n {
                    let want = tree.finest_colour(QuadTree::ROOT, 0, 0, 0, cx, cz).unwrap();
                    let from_root = tree.finest_cell(QuadTree::ROOT_SQUARE, cx, cz).unwrap();
                    assert_eq!(from_root.colour(), want, "cell ({cx}, {cz})");
                    let (x, z) = (f64::from(cx) * h, f64::from(cz) * h);
                    let start = tree.stored_square_holding((x, x + h), (z, z + h));
                    let below = tree.finest_cell(start, cx, cz).unwrap();
                    assert_eq!(below.colour(), want, "cell ({cx}, {cz}) from {start:?}");
                    // The reader, from that square and from the root square's
                    // corner block (the cell is under it or not).
                    let read = tree.cells_below(start).cell(cx, cz).unwrap();
                    assert_eq!(read.colour(), want, "cell ({cx}, {cz}) read from {start:?}");
                    let corner = tree.stored_square_holding((0.0, h), (0.0, h));
                    let read = tree.cells_below(corner).cell(cx, cz).unwrap();
                    assert_eq!(
                        read.colour(),
                        want,
                        "cell ({cx}, {cz}) read from {corner:?}"
                    );
                }
            }
            assert!(tree.finest_cell(QuadTree::ROOT_SQUARE, n, 0).is_none());
            Ok(())
        })
        .budget_ms(1_000);
    }

    /// The square [`QuadTree::stored_square_holding`] gives holds the box,
    /// and no child of it does: it is a block or a terminal square, or the
    /// box crosses one of its middle lines.
    #[test]
    fn the_square_holding_a_box_is_the_deepest() {
        arbtest::arbtest(|u| {
            let tree = photo(u)?;
            let (x, z) = (interval(u)?, interval(u)?);
            let s = tree.stored_square_holding(x, z);
            let side = unit_side(s.level);
            let (x0, z0) = (f64::from(s.ix) * side, f64::from(s.iz) * side);
            assert!(
                x0 <= x.0 && x.1 <= x0 + side && z0 <= z.0 && z.1 <= z0 + side,
                "{s:?} does not hold {x:?} × {z:?}"
            );
            if tree.stored_kind(s) == StoredKind::Inner {
                let (mx, mz) = (x0 + side / 2.0, z0 + side / 2.0);
                let crosses = |(a, b): (f64, f64), m: f64| a < m && b > m;
                assert!(
                    crosses(x, mx) || crosses(z, mz),
                    "a child of {s:?} holds {x:?} × {z:?}"
                );
            }
            Ok(())
        })
        .budget_ms(1_000);
    }
}

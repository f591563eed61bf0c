//! Walking the tree: stored squares, texel-block cells and leaf cells as
//! traversals see them, and the descent to the square holding a box.

use super::{PAD, QuadTree, top_table_offset};
use crate::colour::{Rgba, Unorm16Rgba};
use crate::geometry::unit_side;
use crate::tree::texel_block::TexelBlocks;
use crate::vector::gradient_leaf::square_corners;

/// A stored node of the tree and its square: `level`, column `ix` and row
/// `iz` at that level (tree space, `z` up).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct StoredSquare {
    pub(super) p: usize,
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

impl QuadTree {
    /// The texel block ending the stored node at padded index `p`, if any.
    #[inline]
    pub(super) fn block_at(&self, p: usize) -> Option<usize> {
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
    pub(super) fn top_square(&self, x: (f64, f64), z: (f64, f64), max_level: u8) -> StoredSquare {
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
}

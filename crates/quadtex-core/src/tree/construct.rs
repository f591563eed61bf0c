//! Building a tree from its parts (node lists, flags, colours, blocks)
//! and checking what a file or caller hands over.

use super::ranks::{RankBlock, fill_ranks, inner_before, rank_blocks};
use super::{
    Aspect, MAX_DEPTH, MAX_NODES, MAX_TOP_LEVEL, PAD, QuadTree, top_table_len, top_table_offset,
};
use crate::Error;
use crate::SharedBytes;
use crate::colour::{ColourEncoding, Unorm16Rgba};
use crate::tree::texel_block::TexelBlocks;
use crate::vector::gradient_leaf::square_corners;

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
            channel_ranges: std::sync::OnceLock::new(),
            aspect,
            colours,
            blocks,
            level_starts,
            top_level,
            top: Vec::new(),
            moments: std::sync::OnceLock::new(),
            second_moments: std::sync::OnceLock::new(),
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

    /// Checks that every inner colour is the average of its children to
    /// within rounding (|4·parent − Σ children| ≤ 4 per channel; for half
    /// floats, within two steps of the larger magnitude).
    fn check_averages(&self) -> Result<(), Error> {
        if self.aspect.shrink().is_none() {
            return self.check_averages_over_extent();
        }
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

    /// [`QuadTree::check_averages`] for an extent that is not a power of
    /// two ([`Aspect`]): an inner colour is the mean of its children
    /// weighted by the texture each holds, the pad's weighing nothing.
    fn check_averages_over_extent(&self) -> Result<(), Error> {
        let mut stack = vec![(PAD, 0u8, 0u32, 0u32)];
        while let Some((p, level, ix, iz)) = stack.pop() {
            if !self.is_inner(p) {
                continue;
            }
            let c = self.first_child(p);
            let mut weights = [0.0; 4];
            for (k, w) in weights.iter_mut().enumerate() {
                let (cx, cz) = (2 * ix + (k & 1) as u32, 2 * iz + (k >> 1) as u32);
                *w = self.aspect.texture_fraction(level + 1, cx, cz);
                stack.push((c + k, level + 1, cx, cz));
            }
            let total: f64 = weights.iter().sum();
            let parent = self.encoding.decode_colour(self.colour(p));
            for (ch, &stored) in parent.iter().enumerate() {
                let mean = (0..4)
                    .map(|k| weights[k] * self.encoding.decode(self.colour(c + k).0[ch]))
                    .sum::<f64>()
                    / total;
                let slack = match self.encoding {
                    ColourEncoding::Half => {
                        stored.abs().max(mean.abs()).max(6.1e-5) * (2.0 / 1024.0)
                    }
                    _ => 1.0 / 65535.0,
                };
                if (stored - mean).abs() > slack + 1e-12 {
                    return Err(Error::MalformedTree(format!(
                        "node {}: channel {ch} is {stored} but its children's texture averages {mean}",
                        p - PAD
                    )));
                }
            }
        }
        Ok(())
    }

    /// For each node of the block level (from `block_nodes.start`), the
    /// texels of its block that lie in the texture, as `(columns, rows)`
    /// from the block's bottom-left corner: the whole block except where it
    /// crosses the extent's edge ([`Aspect`]).
    fn block_texture_parts(&self, tb: &TexelBlocks) -> Vec<(u32, u32)> {
        let side = tb.side();
        let mut parts = vec![(side, side); self.block_nodes.len()];
        if self.aspect.shrink().is_some() {
            return parts;
        }
        let [w, h] = self.aspect.cells_at(tb.level() + tb.log2_side());
        let part = |i: u32, n: u64| {
            n.saturating_sub(u64::from(i) * u64::from(side))
                .min(side.into()) as u32
        };
        let mut stack = vec![(PAD, 0u8, 0u32, 0u32)];
        while let Some((p, level, ix, iz)) = stack.pop() {
            if level == tb.level() {
                if let Some(slot) = p
                    .checked_sub(self.block_nodes.start)
                    .and_then(|i| parts.get_mut(i))
                {
                    *slot = (part(ix, w), part(iz, h));
                }
            } else if self.is_inner(p) {
                let c = self.first_child(p);
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
        parts
    }

    /// Checks that block nodes are terminal and hold their texels' mean
    /// (within rounding: `|n·node − Σ texels| ≤ n` per channel).
    fn check_blocks(&self) -> Result<(), Error> {
        let Some(tb) = &self.texel_blocks else {
            return Ok(());
        };
        tb.check_texels()?;
        let parts = self.block_texture_parts(tb);
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
            let (columns, rows) = parts[p - self.block_nodes.start];
            let (sum, n) = tb.texture_sum(b, columns, rows);
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

//! Dense texel blocks: the bottom of a tree stored as texels.
//!
//! Where a photograph's subtree is split down to its texels, nodes cost
//! more than the texels they hold: a 4 × 4 square split to the bottom is 20
//! nodes of 8 bytes, its texels 64 bytes as 8-bit sRGB. A packed tree may
//! therefore end some squares of one level, the *block level*, in a block
//! of `2^b × 2^b` texels kept in the source's precision ([`BlockFormat`]).
//! A block node is terminal in the tree (no children are stored) and holds
//! the rounded mean of its texels like any node; below it, traversals see
//! *cells*: the block's texels grouped `2^j × 2^j`, each the exact mean of
//! its texels, so every integral stays exact.
//!
//! Texels of a block are stored row-major with rows counted **from the
//! bottom** (`z` up), like the tree's squares: texel `(tx, tz)` is entry
//! `tz·2^b + tx`. 8-bit texels are sRGB-encoded with straight alpha, as in
//! the PNG they came from, and decode with [`srgb8_texel`], the same
//! function that made the tree's linear texels from them.

use crate::Error;
use crate::SharedBytes;
use crate::colour::{Rgba, Unorm16Rgba, srgb_decode_f32};

/// Side of a block, `log2`: blocks are 4 × 4 texels.
pub const BLOCK_LOG2_SIDE: u8 = 2;

/// How a block's texels are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum BlockFormat {
    /// Linear, premultiplied RGBA as four `u16` (the tree's own colours):
    /// for 16-bit and float sources, and resampled cells.
    Unorm16Rgba,
    /// sRGB-encoded RGBA with straight alpha, four `u8`: 8-bit sources.
    Srgb8Rgba,
    /// sRGB-encoded RGB, three `u8`: opaque 8-bit sources.
    Srgb8Rgb,
    /// sRGB-encoded grey, one `u8`: opaque grey 8-bit sources.
    Srgb8Grey,
}

impl BlockFormat {
    /// Bytes per texel.
    pub fn bytes_per_texel(self) -> usize {
        match self {
            BlockFormat::Unorm16Rgba => 8,
            BlockFormat::Srgb8Rgba => 4,
            BlockFormat::Srgb8Rgb => 3,
            BlockFormat::Srgb8Grey => 1,
        }
    }

    /// True for the 8-bit sRGB formats.
    pub fn is_srgb8(self) -> bool {
        self != BlockFormat::Unorm16Rgba
    }

    /// The narrowest 8-bit format that holds every texel of `texels`
    /// exactly: grey if all are opaque grey, RGB if all are opaque.
    pub fn narrowest_srgb8(texels: &[[u8; 4]]) -> BlockFormat {
        texels.iter().fold(BlockFormat::Srgb8Grey, |f, &p| {
            f.widest(BlockFormat::of_srgb8(p))
        })
    }

    /// The narrowest 8-bit format for one texel.
    fn of_srgb8([r, g, b, a]: [u8; 4]) -> BlockFormat {
        if a != 255 {
            BlockFormat::Srgb8Rgba
        } else if r != g || g != b {
            BlockFormat::Srgb8Rgb
        } else {
            BlockFormat::Srgb8Grey
        }
    }

    /// The wider of two 8-bit formats (grey < RGB < RGBA).
    pub fn widest(self, other: BlockFormat) -> BlockFormat {
        let rank = |f: BlockFormat| match f {
            BlockFormat::Srgb8Grey => 0,
            BlockFormat::Srgb8Rgb => 1,
            BlockFormat::Srgb8Rgba => 2,
            BlockFormat::Unorm16Rgba => 3,
        };
        if rank(other) > rank(self) {
            other
        } else {
            self
        }
    }

    /// Appends texel `p` (8-bit sRGB, straight alpha) in this format; the
    /// format must hold it ([`BlockFormat::narrowest_srgb8`]).
    pub(crate) fn put_srgb8(self, out: &mut Vec<u8>, p: [u8; 4]) {
        match self {
            BlockFormat::Srgb8Rgba => out.extend(p),
            BlockFormat::Srgb8Rgb => out.extend(&p[..3]),
            BlockFormat::Srgb8Grey => out.push(p[0]),
            BlockFormat::Unorm16Rgba => {
                for v in srgb8_texel(p).0 {
                    out.extend(v.to_le_bytes());
                }
            }
        }
    }

    /// Texel `d` (this format's bytes) as 8-bit sRGB with straight alpha;
    /// `None` for unorm16.
    fn srgb8_of(self, d: &[u8]) -> Option<[u8; 4]> {
        match self {
            BlockFormat::Srgb8Rgba => Some([d[0], d[1], d[2], d[3]]),
            BlockFormat::Srgb8Rgb => Some([d[0], d[1], d[2], 255]),
            BlockFormat::Srgb8Grey => Some([d[0], d[0], d[0], 255]),
            BlockFormat::Unorm16Rgba => None,
        }
    }

    /// The code the `.qtx` header stores.
    pub fn code(self) -> u8 {
        match self {
            BlockFormat::Unorm16Rgba => 1,
            BlockFormat::Srgb8Rgba => 2,
            BlockFormat::Srgb8Rgb => 3,
            BlockFormat::Srgb8Grey => 4,
        }
    }

    /// The format of a header code.
    pub fn from_code(code: u8) -> Option<BlockFormat> {
        match code {
            1 => Some(BlockFormat::Unorm16Rgba),
            2 => Some(BlockFormat::Srgb8Rgba),
            3 => Some(BlockFormat::Srgb8Rgb),
            4 => Some(BlockFormat::Srgb8Grey),
            _ => None,
        }
    }

    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            BlockFormat::Unorm16Rgba => "unorm16 linear RGBA",
            BlockFormat::Srgb8Rgba => "8-bit sRGB RGBA",
            BlockFormat::Srgb8Rgb => "8-bit sRGB RGB",
            BlockFormat::Srgb8Grey => "8-bit sRGB grey",
        }
    }
}

fn srgb8_table() -> &'static [f32; 256] {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    // Through the 16-bit code (×257), as 16-bit sources decode: the same curve.
    TABLE.get_or_init(|| {
        std::array::from_fn(|v| srgb_decode_f32(f32::from(v as u16 * 257) / 65535.0))
    })
}

/// An opaque 8-bit sRGB channel as the tree's unorm16 linear value: what
/// [`srgb8_texel`] gives at alpha 255 (the same arithmetic, tabulated).
fn opaque_table() -> &'static [u16; 256] {
    static TABLE: std::sync::OnceLock<[u16; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|v| srgb8_texel_computed([v as u8, 0, 0, 255]).0[0]))
}

/// An 8-bit sRGB texel with straight alpha as the tree's linear,
/// premultiplied colour.
#[inline]
pub fn srgb8_texel(p: [u8; 4]) -> Unorm16Rgba {
    if p[3] == u8::MAX {
        // Opaque: the same arithmetic, tabulated.
        let t = opaque_table();
        return Unorm16Rgba([
            t[usize::from(p[0])],
            t[usize::from(p[1])],
            t[usize::from(p[2])],
            u16::MAX,
        ]);
    }
    srgb8_texel_computed(p)
}

/// [`srgb8_texel`] computed: decode through the `f32` table, premultiply,
/// round.
fn srgb8_texel_computed(p: [u8; 4]) -> Unorm16Rgba {
    let lut = srgb8_table();
    let a = f32::from(u16::from(p[3]) * 257) / 65535.0;
    Rgba::new(
        lut[usize::from(p[0])] * a,
        lut[usize::from(p[1])] * a,
        lut[usize::from(p[2])] * a,
        a,
    )
    .to_unorm16()
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct FlagWord {
    bits: u64,
    /// Flags set in the words before this one.
    rank: u64,
}

/// The texel blocks of a tree: which nodes of the block level are blocks,
/// and their texels ([module documentation](self)).
#[derive(Debug, Clone, PartialEq)]
pub struct TexelBlocks {
    level: u8,
    log2_side: u8,
    format: BlockFormat,
    /// One flag per node of the block level, in the tree's order.
    flags: Vec<FlagWord>,
    count: u64,
    data: SharedBytes,
}

impl TexelBlocks {
    /// Blocks at `level` of `format`, `2^BLOCK_LOG2_SIDE` texels a side:
    /// `flags` holds one bit per node of that level (bit `i % 64` of word
    /// `i / 64`), set for a block; `data` the blocks' texels in order.
    /// Checks that the data holds exactly one block per flag and that
    /// 16-bit texels are premultiplied; the tree checks the rest.
    pub fn new(
        level: u8,
        format: BlockFormat,
        flags: Vec<u64>,
        data: Vec<u8>,
    ) -> Result<TexelBlocks, Error> {
        let blocks = Self::from_shared(level, format, flags, data.into())?;
        blocks.check_texels()?;
        Ok(blocks)
    }

    /// As [`TexelBlocks::new`], reading the texels in place from `data`
    /// (for example a memory-mapped file): only the sizes are checked, not
    /// the texels ([`crate::QuadTree::verify`] does).
    pub fn from_shared(
        level: u8,
        format: BlockFormat,
        flags: Vec<u64>,
        data: SharedBytes,
    ) -> Result<TexelBlocks, Error> {
        let log2_side = BLOCK_LOG2_SIDE;
        let mut words = crate::memory::try_with_capacity(flags.len(), "block flags")?;
        let mut count = 0u64;
        for bits in flags {
            words.push(FlagWord { bits, rank: count });
            count += u64::from(bits.count_ones());
        }
        let block_bytes = (format.bytes_per_texel() << (2 * log2_side)) as u64;
        if count.checked_mul(block_bytes) != Some(data.len() as u64) {
            return Err(Error::MalformedTree(format!(
                "{count} texel blocks flagged, {} bytes of texels (a block is {block_bytes})",
                data.len()
            )));
        }
        Ok(TexelBlocks {
            level,
            log2_side,
            format,
            flags: words,
            count,
            data,
        })
    }

    /// Checks that 16-bit texels are premultiplied (8-bit texels are
    /// straight and always valid).
    pub(crate) fn check_texels(&self) -> Result<(), Error> {
        if self.format == BlockFormat::Unorm16Rgba {
            for b in 0..self.count as usize {
                for t in 0..self.texels_per_block() {
                    let [r, g, bl, a] = self.texel_at(b, t).0;
                    if r > a || g > a || bl > a {
                        return Err(Error::MalformedTree(format!(
                            "texel block {b}, texel {t}: not premultiplied"
                        )));
                    }
                }
            }
        }
        Ok(())
    }

    /// The level whose nodes may be blocks.
    pub fn level(&self) -> u8 {
        self.level
    }

    /// `log2` of a block's side in texels.
    pub fn log2_side(&self) -> u8 {
        self.log2_side
    }

    /// How texels are stored.
    pub fn format(&self) -> BlockFormat {
        self.format
    }

    /// Number of blocks.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// The flag words (one bit per node of the block level).
    pub fn flag_words(&self) -> impl ExactSizeIterator<Item = u64> + '_ {
        self.flags.iter().map(|w| w.bits)
    }

    /// The blocks' texels, as stored.
    pub fn data(&self) -> &[u8] {
        &self.data
    }

    /// Bytes held (texels and flags).
    pub fn memory_bytes(&self) -> u64 {
        (self.data.len() + self.flags.len() * std::mem::size_of::<FlagWord>()) as u64
    }

    /// Flag words needed for the block level's nodes.
    pub(crate) fn flag_word_count(&self) -> usize {
        self.flags.len()
    }

    /// The block of node `i` of the block level (counted from the level's
    /// first node), if it is one.
    #[inline]
    pub(crate) fn block_of(&self, i: usize) -> Option<usize> {
        let w = self.flags.get(i / 64)?;
        if w.bits >> (i % 64) & 1 == 0 {
            return None;
        }
        let below = w.bits & ((1u64 << (i % 64)) - 1);
        Some((w.rank + u64::from(below.count_ones())) as usize)
    }

    /// Texels on a block's side.
    #[inline]
    pub(crate) fn side(&self) -> u32 {
        1 << self.log2_side
    }

    fn texels_per_block(&self) -> usize {
        1 << (2 * self.log2_side)
    }

    #[inline]
    fn texel_at(&self, block: usize, t: usize) -> Unorm16Rgba {
        let bpt = self.format.bytes_per_texel();
        let o = (block * self.texels_per_block() + t) * bpt;
        let d = &self.data[o..o + bpt];
        match self.format {
            BlockFormat::Srgb8Grey => {
                let v = opaque_table()[usize::from(d[0])];
                Unorm16Rgba([v, v, v, u16::MAX])
            }
            BlockFormat::Srgb8Rgb => {
                let t = opaque_table();
                Unorm16Rgba([
                    t[usize::from(d[0])],
                    t[usize::from(d[1])],
                    t[usize::from(d[2])],
                    u16::MAX,
                ])
            }
            BlockFormat::Srgb8Rgba => srgb8_texel([d[0], d[1], d[2], d[3]]),
            BlockFormat::Unorm16Rgba => Unorm16Rgba(std::array::from_fn(|k| {
                u16::from_le_bytes([d[2 * k], d[2 * k + 1]])
            })),
        }
    }

    /// Texel `(tx, tz)` of `block` (`tz` from the bottom), linear and
    /// premultiplied.
    #[inline]
    pub fn texel(&self, block: usize, tx: u32, tz: u32) -> Unorm16Rgba {
        self.texel_at(block, (tz * self.side() + tx) as usize)
    }

    /// Adds to `acc` (unorm16 units × weight) `Σ wx[tx]·wz[tz]·texel(tx, tz)`
    /// over the texels of `block` with `tx` in `xs` and `tz` in `zs`: a box
    /// over a block is separable, one weight per column and per row.
    #[inline]
    pub(crate) fn add_weighted(
        &self,
        acc: &mut [f64; 4],
        block: usize,
        (wx, xs): (&[f64], std::ops::RangeInclusive<u32>),
        (wz, zs): (&[f64], std::ops::RangeInclusive<u32>),
    ) {
        let side = self.side() as usize;
        let bpt = self.format.bytes_per_texel();
        let base = block * self.texels_per_block() * bpt;
        let table = opaque_table();
        for tz in zs {
            let row = &self.data[base + tz as usize * side * bpt..][..side * bpt];
            let w_row = wz[tz as usize];
            for tx in xs.clone() {
                let w = w_row * wx[tx as usize];
                let d = &row[tx as usize * bpt..][..bpt];
                let c = match self.format {
                    BlockFormat::Srgb8Grey => {
                        let v = f64::from(table[usize::from(d[0])]);
                        [v, v, v, 65535.0]
                    }
                    BlockFormat::Srgb8Rgb => [
                        f64::from(table[usize::from(d[0])]),
                        f64::from(table[usize::from(d[1])]),
                        f64::from(table[usize::from(d[2])]),
                        65535.0,
                    ],
                    BlockFormat::Srgb8Rgba => {
                        srgb8_texel([d[0], d[1], d[2], d[3]]).0.map(f64::from)
                    }
                    BlockFormat::Unorm16Rgba => std::array::from_fn(|k| {
                        f64::from(u16::from_le_bytes([d[2 * k], d[2 * k + 1]]))
                    }),
                };
                for (a, v) in acc.iter_mut().zip(c) {
                    *a += w * v;
                }
            }
        }
    }

    /// The sum (unorm16 units) of the texels of cell `(ix, iz)` of `block`
    /// cut `2^j × 2^j` (`j ≤ log2 side`), and the number of texels in it.
    pub(crate) fn cell_sum(&self, block: usize, j: u8, ix: u32, iz: u32) -> ([u64; 4], u32) {
        let span = self.side() >> j;
        let mut sum = [0u64; 4];
        for tz in iz * span..(iz + 1) * span {
            for tx in ix * span..(ix + 1) * span {
                let c = self.texel(block, tx, tz);
                for (s, v) in sum.iter_mut().zip(c.0) {
                    *s += u64::from(v);
                }
            }
        }
        (sum, span * span)
    }

    /// The sum (unorm16 units) of the texels `tx < columns`, `tz < rows` of
    /// `block`, and their number: a block across the texture's edge counts
    /// its texture part ([`crate::Aspect`]).
    pub(crate) fn texture_sum(&self, block: usize, columns: u32, rows: u32) -> ([u64; 4], u32) {
        let mut sum = [0u64; 4];
        for tz in 0..rows.min(self.side()) {
            for tx in 0..columns.min(self.side()) {
                for (s, v) in sum.iter_mut().zip(self.texel(block, tx, tz).0) {
                    *s += u64::from(v);
                }
            }
        }
        (sum, columns.min(self.side()) * rows.min(self.side()))
    }

    /// The mean of cell `(ix, iz)` of `block` cut `2^j × 2^j`, in `[0, 1]`.
    pub(crate) fn cell_mean(&self, block: usize, j: u8, ix: u32, iz: u32) -> [f64; 4] {
        let (sum, n) = self.cell_sum(block, j, ix, iz);
        let scale = 1.0 / (65535.0 * f64::from(n));
        sum.map(|s| s as f64 * scale)
    }

    /// True when every texel of the cell has the same colour.
    pub(crate) fn cell_is_uniform(&self, block: usize, j: u8, ix: u32, iz: u32) -> bool {
        let span = self.side() >> j;
        let first = self.texel(block, ix * span, iz * span);
        (iz * span..(iz + 1) * span)
            .all(|tz| (ix * span..(ix + 1) * span).all(|tx| self.texel(block, tx, tz) == first))
    }
}

/// Texel blocks while packing: one per block node so far, in the tree's order.
#[derive(Debug, Clone)]
pub(crate) struct BlockWriter {
    pub(crate) level: u8,
    pub(crate) format: BlockFormat,
    /// One flag per node pushed at the block level.
    pub(crate) flags: Vec<bool>,
    pub(crate) data: Vec<u8>,
}

impl BlockWriter {
    /// Bytes of one block.
    pub(crate) fn block_bytes(&self) -> usize {
        self.format.bytes_per_texel() << (2 * BLOCK_LOG2_SIDE)
    }

    /// Re-encodes the blocks so far in the wider 8-bit `format` (a tiled
    /// texture whose later tile needs more channels than the first).
    pub(crate) fn widen(&mut self, format: BlockFormat) -> Result<(), Error> {
        if format == self.format {
            return Ok(());
        }
        let (old, bpt) = (self.format, self.format.bytes_per_texel());
        let texels = self.data.len() / bpt;
        let mut data =
            crate::memory::try_with_capacity(texels * format.bytes_per_texel(), "texel blocks")?;
        for d in self.data.chunks_exact(bpt) {
            if let Some(p) = old.srgb8_of(d) {
                format.put_srgb8(&mut data, p);
            }
        }
        (self.format, self.data) = (format, data);
        Ok(())
    }

    /// The finished blocks.
    pub(crate) fn finish(self) -> Result<Option<TexelBlocks>, Error> {
        if !self.flags.iter().any(|&f| f) {
            return Ok(None);
        }
        let mut words = vec![0u64; self.flags.len().div_ceil(64)];
        for (i, _) in self.flags.iter().enumerate().filter(|(_, f)| **f) {
            words[i / 64] |= 1 << (i % 64);
        }
        TexelBlocks::new(self.level, self.format, words, self.data).map(Some)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb8_decodes_like_the_16_bit_curve_and_premultiplies() {
        assert_eq!(srgb8_texel([0, 0, 0, 0]), Unorm16Rgba([0, 0, 0, 0]));
        assert_eq!(
            srgb8_texel([255, 255, 255, 255]),
            Unorm16Rgba([65535, 65535, 65535, 65535])
        );
        // Mid grey decodes to about 0.2158 linear.
        let g = srgb8_texel([128, 128, 128, 255]).0[0];
        assert!((f64::from(g) / 65535.0 - 0.2158605).abs() < 1e-4, "{g}");
        // Half coverage halves the colour.
        let h = srgb8_texel([255, 0, 0, 128]);
        assert_eq!(h.0[0], h.0[3]);
    }

    #[test]
    fn the_opaque_table_is_the_computed_decoding() {
        for v in 0..=255u8 {
            for p in [[v, 0, 255 - v, 255], [v, v, v, 255], [0, v, 1, 255]] {
                assert_eq!(srgb8_texel(p), srgb8_texel_computed(p));
            }
        }
    }

    #[test]
    fn opaque_formats_decode_like_the_general_path() {
        for v in 0..=255u8 {
            let rgb = TexelBlocks::new(
                0,
                BlockFormat::Srgb8Rgb,
                vec![1],
                [v, 255 - v, v / 3].repeat(16),
            )
            .unwrap();
            assert_eq!(rgb.texel(0, 1, 2), srgb8_texel([v, 255 - v, v / 3, 255]));
            let grey = TexelBlocks::new(0, BlockFormat::Srgb8Grey, vec![1], vec![v; 16]).unwrap();
            assert_eq!(grey.texel(0, 3, 3), srgb8_texel([v, v, v, 255]));
        }
    }

    #[test]
    fn blocks_find_their_texels_and_refuse_short_data() {
        let texel = |b: u8, t: u8| [b, t, 0, 255];
        let data: Vec<u8> = (0..2u8)
            .flat_map(|b| (0..16u8).flat_map(move |t| texel(b, t)))
            .collect();
        let blocks =
            TexelBlocks::new(3, BlockFormat::Srgb8Rgba, vec![0b1010], data.clone()).unwrap();
        assert_eq!(blocks.count(), 2);
        assert_eq!(blocks.block_of(0), None);
        assert_eq!(blocks.block_of(1), Some(0));
        assert_eq!(blocks.block_of(3), Some(1));
        assert_eq!(blocks.texel(1, 2, 3), srgb8_texel(texel(1, 14)));
        let (sum, n) = blocks.cell_sum(0, 1, 1, 0);
        assert_eq!(n, 4);
        let want: u64 = [2u8, 3, 6, 7]
            .iter()
            .map(|&t| u64::from(srgb8_texel(texel(0, t)).0[1]))
            .sum();
        assert_eq!(sum[1], want);
        assert!(TexelBlocks::new(3, BlockFormat::Srgb8Rgba, vec![0b1011], data).is_err());
    }
}

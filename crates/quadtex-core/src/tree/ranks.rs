//! The inner flags, one bit a node, and the rank counters that turn an
//! inner node's index into its first child's without pointers.

use super::{PAD, QuadTree};
use crate::Error;

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct RankBlock {
    /// Bit `i`: the node at padded index `64·block + i` is inner.
    pub(super) bits: u64,
    /// Inner nodes at padded indices below `64·block`.
    pub(super) rank: u64,
}

impl QuadTree {
    #[inline]
    pub(super) fn is_inner(&self, p: usize) -> bool {
        self.blocks[p / 64].bits >> (p % 64) & 1 == 1
    }

    /// Padded index of the first child of the inner node at padded index `p`.
    #[inline]
    pub(super) fn first_child(&self, p: usize) -> usize {
        let b = self.blocks[p / 64];
        let below = b.bits & ((1u64 << (p % 64)) - 1);
        4 + 4 * (b.rank as usize + below.count_ones() as usize)
    }
}

/// Padded rank blocks for `n` nodes whose inner flags are `word(k)` (bits
/// `64k..64k+64` of the unpadded flags; bits past `n` are ignored).
pub(super) fn rank_blocks(n: usize, word: impl Fn(usize) -> u64) -> Result<Vec<RankBlock>, Error> {
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
pub(super) fn inner_before(blocks: &[RankBlock], p: usize) -> u64 {
    match blocks.get(p / 64) {
        Some(b) => b.rank + u64::from((b.bits & ((1u64 << (p % 64)) - 1)).count_ones()),
        None => blocks
            .last()
            .map_or(0, |b| b.rank + u64::from(b.bits.count_ones())),
    }
}

/// Sets each rank block's count of inner nodes before it.
pub(super) fn fill_ranks(blocks: &mut [RankBlock]) {
    let mut rank = 0u64;
    for b in blocks {
        b.rank = rank;
        rank += u64::from(b.bits.count_ones());
    }
}

//! What gradient leaves and contour leaves share: the stored nodes they end
//! (unpadded breadth-first indices, strictly increasing) and, once attached
//! to their tree, the square `(level, ix, iz)` of each.

/// The nodes of one kind of leaf and their squares.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct LeafNodes {
    nodes: Vec<u32>,
    squares: Vec<(u8, u32, u32)>,
    /// Once attached: bit `n % 64` of word `n / 64` is set when node `n`
    /// is a leaf, and `ranks[w]` counts the leaves before word `w`. A
    /// traversal asks at every terminal square it cuts, so the answer is a
    /// bit test (and a popcount for leaves), not a search: 1.5 bits per
    /// node up to the last leaf. Built only once the tree has checked
    /// every node is one of its own, so a file's claim cannot size it.
    bits: Vec<u64>,
    ranks: Vec<u32>,
}

impl LeafNodes {
    /// Leaves at `nodes` (checked by the leaf kinds' constructors).
    pub(crate) fn new(nodes: Vec<u32>) -> LeafNodes {
        LeafNodes {
            nodes,
            squares: Vec::new(),
            bits: Vec::new(),
            ranks: Vec::new(),
        }
    }

    /// Number of leaves.
    pub(crate) fn len(&self) -> usize {
        self.nodes.len()
    }

    /// The nodes, increasing.
    pub(crate) fn nodes(&self) -> &[u32] {
        &self.nodes
    }

    /// The leaf at unpadded node index `node`, if it is one.
    #[inline]
    pub(crate) fn index_of(&self, node: u32) -> Option<usize> {
        if self.bits.is_empty() {
            return self.nodes.binary_search(&node).ok();
        }
        let (w, b) = ((node / 64) as usize, node % 64);
        let word = *self.bits.get(w)?;
        if (word >> b) & 1 == 0 {
            return None;
        }
        Some(self.ranks[w] as usize + (word & ((1u64 << b) - 1)).count_ones() as usize)
    }

    /// Bytes held.
    pub(crate) fn memory_bytes(&self) -> u64 {
        (self.nodes.len() * (4 + 12) + self.bits.len() * 8 + self.ranks.len() * 4) as u64
    }

    /// The node of leaf `leaf`.
    pub(crate) fn node(&self, leaf: usize) -> u32 {
        self.nodes[leaf]
    }

    /// The square of leaf `leaf`.
    #[inline]
    pub(crate) fn square(&self, leaf: usize) -> (u8, u32, u32) {
        self.squares[leaf]
    }

    /// Sets every leaf's square (see `QuadTree::leaf_squares`).
    /// Also builds the lookup bitmap: the tree has checked the nodes.
    pub(crate) fn set_squares(&mut self, squares: Vec<(u8, u32, u32)>) {
        self.squares = squares;
        let words = self.nodes.last().map_or(0, |&n| n as usize / 64 + 1);
        self.bits = vec![0; words];
        for &n in &self.nodes {
            self.bits[n as usize / 64] |= 1 << (n % 64);
        }
        let mut before = 0u32;
        self.ranks = self
            .bits
            .iter()
            .map(|w| {
                let r = before;
                before += w.count_ones();
                r
            })
            .collect();
    }
}

#[cfg(test)]
mod tests {
    use super::LeafNodes;

    #[test]
    fn the_bitmap_answers_as_the_search_does() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for count in [1usize, 2, 63, 64, 65, 300] {
            let mut nodes: Vec<u32> = (0..count)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state % 2000) as u32
                })
                .collect();
            nodes.sort_unstable();
            nodes.dedup();
            let searched = LeafNodes::new(nodes.clone());
            let mut mapped = LeafNodes::new(nodes.clone());
            mapped.set_squares(vec![(0, 0, 0); nodes.len()]);
            assert!(!mapped.bits.is_empty());
            for n in 0..2100u32 {
                assert_eq!(mapped.index_of(n), searched.index_of(n), "node {n}");
            }
            for (i, &n) in nodes.iter().enumerate() {
                assert_eq!(mapped.index_of(n), Some(i));
            }
        }
    }
}

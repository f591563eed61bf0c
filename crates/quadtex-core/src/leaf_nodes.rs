//! What gradient leaves and contour leaves share: the stored nodes they end
//! (unpadded breadth-first indices, strictly increasing) and, once attached
//! to their tree, the square `(level, ix, iz)` of each.

/// The nodes of one kind of leaf and their squares.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct LeafNodes {
    nodes: Vec<u32>,
    squares: Vec<(u8, u32, u32)>,
}

impl LeafNodes {
    /// Leaves at `nodes` (checked by the leaf kinds' constructors).
    pub(crate) fn new(nodes: Vec<u32>) -> LeafNodes {
        LeafNodes {
            nodes,
            squares: Vec::new(),
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
        self.nodes.binary_search(&node).ok()
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
    pub(crate) fn set_squares(&mut self, squares: Vec<(u8, u32, u32)>) {
        self.squares = squares;
    }
}

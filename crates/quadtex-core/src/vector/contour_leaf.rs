//! Contour leaves: terminal squares that keep the edges crossing them.
//!
//! A square of flat vector art (solid fills under the nonzero or even-odd
//! rule, composited *over* in paint order, in translucent groups of plain
//! opacity or not; no gradients, blend modes, clip paths or masks) crossed
//! by at most a budget of edges can be stored as
//! the shapes' contours clipped to it, instead of being split down to the
//! maximum level. Memory then follows the art's edge length at the
//! budget's scale, not `2^L`, and the art stays exact at any magnification:
//!
//! * the fragment integral ([`crate::QuadTree::weighted_colour`]) clips
//!   the leaf's contours to the fragment's overlap and integrates the
//!   composite by the packer's trapezoid sweep: **exact** (up to rounding)
//!   for fragments of any size, down to the `f64` resolution of the
//!   contours. A square wholly inside the fragment counts at its stored
//!   mean (rounded once to 16 bits), as every node;
//! * the exact-pixel walk ([`crate::filter::region`]) sees the leaf as *cells* made
//!   on demand, each at the exact mean of the art over it (the same sweep),
//!   subdivided while edges cross it, at most
//!   [`crate::vector::gradient_leaf::MAX_CELL_LEVELS`] below the leaf and down to
//!   the tree's depth; a cell still crossed by an edge there is taken at its
//!   mean with a full-contrast bound.
//!
//! Contours are stored as they were clipped to the leaf's square, in tree
//! space; a contour that encloses the square without an edge inside it is
//! kept as a winding offset (`base`) of its piece.

use crate::Error;
use crate::geometry::{
    FillRule, SlabScratch, SweepEdge, clip_to_rect, for_each_slab, on_rect_border, signed_area,
    unit_side,
};
use crate::tree::leaf_nodes::LeafNodes;

type Point = [f64; 2];

/// One shape's part of a contour leaf.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeafPiece {
    /// Linear premultiplied colour, channels in `[0, 1]`, `r, g, b <= a`.
    pub colour: [f64; 4],
    /// The shape's fill rule.
    pub rule: FillRule,
    /// Winding of contours that enclose the whole square.
    pub base: i32,
    /// The innermost translucent group the piece is drawn in, an index
    /// into its leaf's groups.
    pub group: Option<u32>,
}

/// A translucent group of a contour leaf: its members are composited in
/// isolation, then faded by `opacity` and composited *over* what lies
/// below (SVG's `<g opacity>`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeafGroup {
    /// In `[0, 1]`.
    pub opacity: f64,
    /// The enclosing group, an index into the same leaf's groups, below
    /// this one's.
    pub parent: Option<u32>,
}

/// Deepest nesting of groups a contour leaf holds.
pub const MAX_LEAF_GROUP_DEPTH: usize = 8;

/// The contour leaves of a tree: per leaf its pieces (paint order), per
/// piece its contours, per contour its points, flattened.
///
/// Invariants: at least one leaf; nodes strictly increasing; every range
/// well formed; contours of at least 3 points, each point finite; colours
/// finite and premultiplied in `[0, 1]`; `depth <= 30`.
#[derive(Debug, Clone, PartialEq)]
pub struct ContourLeaves {
    depth: u8,
    /// The leaves' nodes, and their squares once attached to the tree.
    at: LeafNodes,
    /// First group of each leaf, plus one past the last.
    leaf_groups: Vec<u32>,
    groups: Vec<LeafGroup>,
    /// First piece of each leaf, plus one past the last.
    leaf_pieces: Vec<u32>,
    pieces: Vec<LeafPiece>,
    /// First contour of each piece, plus one past the last.
    piece_contours: Vec<u32>,
    /// First point of each contour, plus one past the last.
    contour_points: Vec<u32>,
    points: Vec<Point>,
    /// `[x0, z0, x1, z1]` of each contour: a query skips those it misses.
    bounds: Vec<[f64; 4]>,
    /// How far the art's flattened curves may lie from the true ones.
    curve_tolerance: Option<f64>,
}

/// Flattened contour leaves, as [`ContourLeaves::new`] takes them and
/// [`ContourLeaves::parts`] gives them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ContourParts {
    /// Unpadded breadth-first index of each leaf's node, increasing.
    pub nodes: Vec<u32>,
    /// First piece of each leaf, plus one past the last (`nodes.len() + 1`).
    pub leaf_pieces: Vec<u32>,
    /// Pieces of all leaves.
    pub pieces: Vec<LeafPiece>,
    /// First contour of each piece, plus one past the last.
    pub piece_contours: Vec<u32>,
    /// First point of each contour, plus one past the last.
    pub contour_points: Vec<u32>,
    /// Points of all contours, tree space.
    pub points: Vec<Point>,
    /// First group of each leaf, plus one past the last.
    pub leaf_groups: Vec<u32>,
    /// Groups of all leaves.
    pub groups: Vec<LeafGroup>,
}

impl ContourParts {
    /// Appends a leaf of node `node` with translucent `groups` whose pieces
    /// are `(piece, contours)` in paint order.
    pub fn push_leaf<'a>(
        &mut self,
        node: u32,
        groups: &[LeafGroup],
        pieces: impl IntoIterator<Item = (LeafPiece, Vec<&'a [Point]>)>,
    ) {
        if self.leaf_pieces.is_empty() {
            self.leaf_pieces.push(0);
            self.piece_contours.push(0);
            self.contour_points.push(0);
            self.leaf_groups.push(0);
        }
        self.groups.extend_from_slice(groups);
        self.leaf_groups.push(self.groups.len() as u32);
        self.nodes.push(node);
        for (piece, contours) in pieces {
            self.pieces.push(piece);
            for c in contours {
                self.points.extend_from_slice(c);
                self.contour_points.push(self.points.len() as u32);
            }
            self.piece_contours
                .push((self.contour_points.len() - 1) as u32);
        }
        self.leaf_pieces.push(self.pieces.len() as u32);
    }
}

impl ContourLeaves {
    /// Contour leaves of a tree answering down to level `depth`.
    /// [`Error::MalformedTree`] names the first broken invariant.
    pub fn new(depth: u8, parts: ContourParts) -> Result<ContourLeaves, Error> {
        let bad = |why: String| Err(Error::MalformedTree(format!("contour leaves: {why}")));
        let ContourParts {
            nodes,
            leaf_pieces,
            pieces,
            piece_contours,
            contour_points,
            points,
            leaf_groups,
            groups,
        } = parts;
        if depth > crate::MAX_DEPTH {
            return bad(format!("depth {depth} exceeds {}", crate::MAX_DEPTH));
        }
        if nodes.is_empty() || nodes.len() > crate::vector::gradient_leaf::MAX_GRADIENT_LEAVES {
            return bad(format!("{} leaves", nodes.len()));
        }
        if let Some(w) = nodes.windows(2).find(|w| w[1] <= w[0]) {
            return bad(format!("node {} does not follow node {}", w[1], w[0]));
        }
        // Each index list starts at 0, never decreases and ends at its items' count.
        let ranges = |name: &str, firsts: &[u32], groups: usize, items: usize| {
            if firsts.len() != groups + 1
                || firsts.first() != Some(&0)
                || firsts.last().map(|&l| l as usize) != Some(items)
                || firsts.windows(2).any(|w| w[1] < w[0])
            {
                return Err(Error::MalformedTree(format!(
                    "contour leaves: {name} do not index {items} items in {groups} groups"
                )));
            }
            Ok(())
        };
        ranges("leaf pieces", &leaf_pieces, nodes.len(), pieces.len())?;
        ranges("leaf groups", &leaf_groups, nodes.len(), groups.len())?;
        for (leaf, w) in leaf_groups.windows(2).enumerate() {
            let count = w[1] - w[0];
            for (k, g) in groups[w[0] as usize..w[1] as usize].iter().enumerate() {
                if !(g.opacity.is_finite() && (0.0..=1.0).contains(&g.opacity))
                    || g.parent.is_some_and(|p| p as usize >= k)
                {
                    return bad(format!(
                        "leaf {leaf}, group {k}: opacity {} or parent {:?} (groups list parents first)",
                        g.opacity, g.parent
                    ));
                }
            }
            let depth_of = |mut k: usize| {
                let mut d = 1;
                while let Some(p) = groups[w[0] as usize + k].parent {
                    k = p as usize;
                    d += 1;
                }
                d
            };
            if let Some(k) = (0..count as usize).find(|&k| depth_of(k) > MAX_LEAF_GROUP_DEPTH) {
                return bad(format!(
                    "leaf {leaf}, group {k}: nested deeper than {MAX_LEAF_GROUP_DEPTH}"
                ));
            }
            let (p0, p1) = (leaf_pieces[leaf] as usize, leaf_pieces[leaf + 1] as usize);
            if let Some(p) = (p0..p1).find(|&p| pieces[p].group.is_some_and(|g| g >= count)) {
                return bad(format!("piece {p}: group {:?} of {count}", pieces[p].group));
            }
        }
        ranges(
            "piece contours",
            &piece_contours,
            pieces.len(),
            contour_points.len().saturating_sub(1),
        )?;
        ranges(
            "contour points",
            &contour_points,
            contour_points.len().saturating_sub(1),
            points.len(),
        )?;
        if let Some(w) = contour_points.windows(2).position(|w| w[1] - w[0] < 3) {
            return bad(format!("contour {w} has fewer than 3 points"));
        }
        if let Some(i) = points
            .iter()
            .position(|p| !(p[0].is_finite() && p[1].is_finite()))
        {
            return bad(format!("point {i} is not finite"));
        }
        for (i, p) in pieces.iter().enumerate() {
            let [r, g, b, a] = p.colour;
            let unit = |v: f64| (0.0..=1.0).contains(&v);
            if !(unit(a) && [r, g, b].iter().all(|&c| unit(c) && c <= a + 1e-12)) {
                return bad(format!(
                    "piece {i}: colour {:?} is not premultiplied in [0, 1]",
                    p.colour
                ));
            }
        }
        let bounds = contour_points
            .windows(2)
            .map(|w| {
                points[w[0] as usize..w[1] as usize].iter().fold(
                    [
                        f64::INFINITY,
                        f64::INFINITY,
                        f64::NEG_INFINITY,
                        f64::NEG_INFINITY,
                    ],
                    |b, p| {
                        [
                            b[0].min(p[0]),
                            b[1].min(p[1]),
                            b[2].max(p[0]),
                            b[3].max(p[1]),
                        ]
                    },
                )
            })
            .collect();
        Ok(ContourLeaves {
            depth,
            at: LeafNodes::new(nodes),
            leaf_groups,
            groups,
            leaf_pieces,
            pieces,
            piece_contours,
            contour_points,
            points,
            bounds,
            curve_tolerance: None,
        })
    }

    /// The leaves, stating that their curves were flattened to within
    /// `tolerance` of the true ones (texture-space units); `None` states
    /// nothing. [`Error::MalformedTree`] unless finite and in `(0, 1]`.
    pub fn with_curve_tolerance(mut self, tolerance: Option<f64>) -> Result<ContourLeaves, Error> {
        if let Some(t) = tolerance
            && !(t.is_finite() && t > 0.0 && t <= 1.0)
        {
            return Err(Error::MalformedTree(format!(
                "contour leaves: curve tolerance {t} is not in (0, 1]"
            )));
        }
        self.curve_tolerance = tolerance;
        Ok(self)
    }

    /// How far the flattened curves may lie from the art's true curves
    /// (texture-space units), when the packer was told.
    pub fn curve_tolerance(&self) -> Option<f64> {
        self.curve_tolerance
    }

    /// The flattened parts (what [`ContourLeaves::new`] took).
    pub fn parts(&self) -> ContourParts {
        ContourParts {
            nodes: self.at.nodes().to_vec(),
            leaf_pieces: self.leaf_pieces.clone(),
            pieces: self.pieces.clone(),
            piece_contours: self.piece_contours.clone(),
            contour_points: self.contour_points.clone(),
            points: self.points.clone(),
            leaf_groups: self.leaf_groups.clone(),
            groups: self.groups.clone(),
        }
    }

    /// Deepest level the tree answers at (cells go no deeper).
    pub fn depth(&self) -> u8 {
        self.depth
    }

    /// Number of leaves.
    pub fn count(&self) -> usize {
        self.at.len()
    }

    /// Number of stored points (every contour's, clipped to its leaf).
    pub fn point_count(&self) -> usize {
        self.points.len()
    }

    /// Most edges in one leaf.
    pub fn max_leaf_edges(&self) -> usize {
        (0..self.count())
            .map(|l| {
                let (p0, p1) = self.piece_range(l);
                let (c0, c1) = (
                    self.piece_contours[p0] as usize,
                    self.piece_contours[p1] as usize,
                );
                (self.contour_points[c1] - self.contour_points[c0]) as usize
            })
            .max()
            .unwrap_or(0)
    }

    /// Bytes held.
    pub fn memory_bytes(&self) -> u64 {
        self.at.memory_bytes()
            + (self.at.len() * (4 + 4)
                + self.groups.len() * std::mem::size_of::<LeafGroup>()
                + self.pieces.len() * (std::mem::size_of::<LeafPiece>() + 4)
                + self.contour_points.len() * (4 + 32)
                + self.points.len() * 16) as u64
    }

    /// The nodes the leaves end and their squares.
    pub(crate) fn at(&self) -> &LeafNodes {
        &self.at
    }

    pub(crate) fn at_mut(&mut self) -> &mut LeafNodes {
        &mut self.at
    }

    pub(crate) fn square(&self, leaf: usize) -> (u8, u32, u32) {
        self.at.square(leaf)
    }

    fn piece_range(&self, leaf: usize) -> (usize, usize) {
        (
            self.leaf_pieces[leaf] as usize,
            self.leaf_pieces[leaf + 1] as usize,
        )
    }

    fn contours_of(&self, piece: usize) -> impl Iterator<Item = &[Point]> + '_ {
        self.bounded_contours_of(piece).map(|(c, _)| c)
    }

    /// The contours of `piece` with their bounds.
    fn bounded_contours_of(&self, piece: usize) -> impl Iterator<Item = (&[Point], [f64; 4])> + '_ {
        let (c0, c1) = (
            self.piece_contours[piece] as usize,
            self.piece_contours[piece + 1] as usize,
        );
        (c0..c1).map(|c| {
            (
                &self.points[self.contour_points[c] as usize..self.contour_points[c + 1] as usize],
                self.bounds[c],
            )
        })
    }

    /// True when every point of leaf `leaf` lies in its square.
    pub(crate) fn inside_square(&self, leaf: usize) -> bool {
        let (level, ix, iz) = self.at.square(leaf);
        let [x0, z0, x1, z1] = rect_of(level, ix.into(), iz.into());
        let (p0, p1) = self.piece_range(leaf);
        (p0..p1).all(|p| {
            self.contours_of(p)
                .flatten()
                .all(|q| q[0] >= x0 && q[0] <= x1 && q[1] >= z0 && q[1] <= z1)
        })
    }

    /// `∫ colour` (times area, linear premultiplied) of leaf `leaf` over
    /// the rectangle `rect` (tree space, inside its square), and whether an
    /// edge crosses the rectangle's inside.
    pub(crate) fn integral(&self, leaf: usize, rect: [f64; 4]) -> ([f64; 4], bool) {
        let (p0, p1) = self.piece_range(leaf);
        if let Some(mean) = self.uniform_over(leaf, rect) {
            let area = (rect[2] - rect[0]) * (rect[3] - rect[1]);
            return (mean.map(|v| v * area), false);
        }
        // Buffers kept per thread: a query allocates nothing once warm.
        SWEEP.with_borrow_mut(|sweep| {
            let Sweep {
                clipped,
                scratch,
                buffers,
            } = sweep;
            clipped.clear();
            for p in p0..p1 {
                clipped.push_piece(self.pieces[p], self.bounded_contours_of(p), rect, scratch);
            }
            let edges = !clipped.points.is_empty();
            let groups =
                &self.groups[self.leaf_groups[leaf] as usize..self.leaf_groups[leaf + 1] as usize];
            (clipped.sweep(rect, groups, buffers), edges)
        })
    }

    /// The one colour of `leaf` over `rect` when no edge enters the closed
    /// rectangle and the leaf has no groups and at most
    /// [`UNIFORM_PIECES`] pieces (the common case of a fragment small
    /// against its leaf, answered without the sweep's buffers); `None`
    /// otherwise.
    fn uniform_over(&self, leaf: usize, rect: [f64; 4]) -> Option<[f64; 4]> {
        let (p0, p1) = self.piece_range(leaf);
        if p1 - p0 > UNIFORM_PIECES || self.leaf_groups[leaf] != self.leaf_groups[leaf + 1] {
            return None;
        }
        let area = (rect[2] - rect[0]) * (rect[3] - rect[1]);
        let centre = [0.5 * (rect[0] + rect[2]), 0.5 * (rect[1] + rect[3])];
        let mut colour = [0.0; 4];
        for p in p0..p1 {
            let piece = &self.pieces[p];
            let mut w = piece.base;
            for (c, b) in self.bounded_contours_of(p) {
                if b[2] < rect[0] || b[0] > rect[2] || b[3] < rect[1] || b[1] > rect[3] {
                    continue;
                }
                let k = winding_if_clear(c, rect, centre)?;
                if area > 0.0 {
                    w += k;
                }
            }
            if piece.rule.covers(w) {
                over(&mut colour, piece.colour);
            }
        }
        Some(colour)
    }

    /// Whether cell `(j, ix, iz)` of `leaf` is subdivided further, its exact
    /// mean colour, and how far a point's colour may be from that mean (0
    /// when no edge crosses the cell, else full contrast).
    pub(crate) fn cell_info(&self, leaf: usize, j: u8, ix: u32, iz: u32) -> (bool, [f64; 4], f64) {
        let (level, lx, lz) = self.at.square(leaf);
        let level = level + j;
        let (cx, cz) = (
            (u64::from(lx) << j) + u64::from(ix),
            (u64::from(lz) << j) + u64::from(iz),
        );
        let rect = rect_of(level, cx, cz);
        let area = (rect[2] - rect[0]) * (rect[3] - rect[1]);
        let (sum, edges) = self.integral(leaf, rect);
        let splits =
            edges && j < crate::vector::gradient_leaf::MAX_CELL_LEVELS && level < self.depth;
        (splits, sum.map(|v| v / area), if edges { 1.0 } else { 0.0 })
    }

    /// The square `(level, ix, iz)` of cell `(j, ix, iz)` of `leaf`.
    pub(crate) fn cell_square(&self, leaf: usize, j: u8, ix: u32, iz: u32) -> (u8, u32, u32) {
        let (level, lx, lz) = self.at.square(leaf);
        (level + j, (lx << j) + ix, (lz << j) + iz)
    }
}

/// `[x0, z0, x1, z1]` of square `(level, ix, iz)` of tree space.
pub(crate) fn rect_of(level: u8, ix: u64, iz: u64) -> [f64; 4] {
    let side = unit_side(level);
    let (x0, z0) = (ix as f64 * side, iz as f64 * side);
    [x0, z0, x0 + side, z0 + side]
}

/// The winding number of the closed polygon `c` around `p` (a point of
/// the rectangle), or `None` when a point of `c`'s boundary lies in the
/// closed rectangle. One pass: an edge whose bounds miss the rectangle
/// only counts towards the winding; the others are tested by
/// Liang–Barsky. Same convention as [`winding`], which it equals when it
/// answers (a crossing of the ray from `p` that misses the rectangle lies
/// right of it).
fn winding_if_clear(c: &[Point], [x0, z0, x1, z1]: [f64; 4], p: Point) -> Option<i32> {
    let mut w = 0;
    let mut a = *c.last()?;
    for &b in c {
        let (lo_x, hi_x) = if a[0] < b[0] {
            (a[0], b[0])
        } else {
            (b[0], a[0])
        };
        let (lo_z, hi_z) = if a[1] < b[1] {
            (a[1], b[1])
        } else {
            (b[1], a[1])
        };
        if hi_x >= x0 && lo_x <= x1 && hi_z >= z0 && lo_z <= z1 {
            let (mut t0, mut t1) = (0.0f64, 1.0f64);
            let d = [b[0] - a[0], b[1] - a[1]];
            let mut inside = true;
            for (dp, q) in [
                (-d[0], a[0] - x0),
                (d[0], x1 - a[0]),
                (-d[1], a[1] - z0),
                (d[1], z1 - a[1]),
            ] {
                if dp == 0.0 {
                    if q < 0.0 {
                        inside = false;
                        break;
                    }
                } else {
                    let r = q / dp;
                    if dp < 0.0 {
                        t0 = t0.max(r);
                    } else {
                        t1 = t1.min(r);
                    }
                }
            }
            if inside && t0 <= t1 {
                return None;
            }
        }
        if (a[1] <= p[1]) != (b[1] <= p[1]) {
            let x = a[0] + (p[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
            if x > p[0] {
                w += if b[1] < a[1] { 1 } else { -1 };
            }
        }
        a = b;
    }
    Some(-w)
}

/// Most pieces [`ContourLeaves::uniform_over`] takes on (more is rare:
/// the sweep is then the smaller part of the cost).
const UNIFORM_PIECES: usize = 64;

thread_local! {
    static SWEEP: std::cell::RefCell<Sweep> = std::cell::RefCell::new(Sweep::default());
}

/// What [`ContourLeaves::integral`] reuses between queries.
#[derive(Default)]
struct Sweep {
    clipped: Clipped,
    scratch: [Vec<Point>; 2],
    buffers: SweepBuffers,
}

/// Scratch of [`Clipped::sweep`].
#[derive(Default)]
struct SweepBuffers {
    edges: Vec<SweepEdge>,
    slabs: SlabScratch,
    crossings: Vec<(f64, usize, i32)>,
    winding: Vec<i32>,
    /// Colours and group chains of the pieces covering a gap.
    covering: Vec<([f64; 4], Chain)>,
    /// Each piece's group chain.
    chains: Vec<Chain>,
}

/// A piece's groups, outermost first, and how many there are.
type Chain = ([u32; MAX_LEAF_GROUP_DEPTH], u8);

/// `c` composited *over* `out`.
fn over(out: &mut [f64; 4], c: [f64; 4]) {
    let keep = 1.0 - c[3];
    for (o, ck) in out.iter_mut().zip(c) {
        *o = ck + *o * keep;
    }
}

/// The composite of `list` (paint order) at group depth `depth`: runs of
/// pieces sharing their group at that depth are composited in isolation,
/// faded by its opacity and laid *over* the rest, as the packer does.
fn composite(list: &[([f64; 4], Chain)], depth: usize, groups: &[LeafGroup]) -> [f64; 4] {
    let group_at = |i: usize| {
        let (chain, len) = list[i].1;
        (depth < usize::from(len)).then(|| chain[depth])
    };
    let mut out = [0.0; 4];
    let mut i = 0;
    while i < list.len() {
        match group_at(i) {
            Some(g) => {
                let j = i
                    + 1
                    + (i + 1..list.len())
                        .take_while(|&k| group_at(k) == Some(g))
                        .count();
                let o = groups[g as usize].opacity;
                over(
                    &mut out,
                    composite(&list[i..j], depth + 1, groups).map(|v| v * o),
                );
                i = j;
            }
            None => {
                over(&mut out, list[i].0);
                i += 1;
            }
        }
    }
    out
}

/// Pieces clipped to a rectangle, ready to sweep.
#[derive(Default)]
struct Clipped {
    pieces: Vec<(LeafPiece, std::ops::Range<usize>)>,
    contours: Vec<std::ops::Range<usize>>,
    points: Vec<Point>,
}

impl Clipped {
    fn clear(&mut self) {
        self.pieces.clear();
        self.contours.clear();
        self.points.clear();
    }

    fn push_piece<'a>(
        &mut self,
        piece: LeafPiece,
        contours: impl Iterator<Item = (&'a [Point], [f64; 4])>,
        rect: [f64; 4],
        scratch: &mut [Vec<Point>; 2],
    ) {
        let first = self.contours.len();
        let mut piece = piece;
        let area = (rect[2] - rect[0]) * (rect[3] - rect[1]);
        let centre = [0.5 * (rect[0] + rect[2]), 0.5 * (rect[1] + rect[3])];
        for (c, b) in contours {
            // Outside its bounds the contour winds 0 around every point.
            if b[2] < rect[0] || b[0] > rect[2] || b[3] < rect[1] || b[1] > rect[3] {
                continue;
            }
            // No point of the contour in the closed rectangle: the
            // rectangle is wholly inside or outside it, and its winding is
            // the centre's (the common case for a small fragment).
            if let Some(w) = winding_if_clear(c, rect, centre) {
                if area > 0.0 {
                    piece.base += w;
                }
                continue;
            }
            let start = self.points.len();
            clip_to_rect(c, rect, scratch, &mut self.points);
            let n = self.points.len() - start;
            if n < 3 {
                self.points.truncate(start);
                continue;
            }
            if on_rect_border(&self.points[start..], rect) {
                if area > 0.0 {
                    piece.base += (signed_area(&self.points[start..]) / area).round() as i32;
                }
                self.points.truncate(start);
            } else {
                self.contours.push(start..self.points.len());
            }
        }
        self.pieces.push((piece, first..self.contours.len()));
    }

    /// The composite where each piece winds `winding` (`chains`: the
    /// pieces' group chains, when there are groups).
    fn colour_at(
        &self,
        winding: &[i32],
        groups: &[LeafGroup],
        chains: &[Chain],
        covering: &mut Vec<([f64; 4], Chain)>,
    ) -> [f64; 4] {
        if groups.is_empty() {
            let mut c = [0.0; 4];
            for ((p, _), &w) in self.pieces.iter().zip(winding) {
                if p.rule.covers(w) {
                    over(&mut c, p.colour);
                }
            }
            return c;
        }
        covering.clear();
        for (((p, _), &w), chain) in self.pieces.iter().zip(winding).zip(chains) {
            if p.rule.covers(w) {
                covering.push((p.colour, *chain));
            }
        }
        composite(covering, 0, groups)
    }

    /// `∫ composite` over `rect`: the trapezoid sweep.
    fn sweep(&self, rect: [f64; 4], groups: &[LeafGroup], buffers: &mut SweepBuffers) -> [f64; 4] {
        let [x0, z0, x1, z1] = rect;
        let SweepBuffers {
            edges,
            slabs,
            crossings,
            covering,
            winding,
            chains,
        } = buffers;
        chains.clear();
        if !groups.is_empty() {
            chains.extend(self.pieces.iter().map(|(p, _)| {
                // Innermost first, then reversed: outermost first.
                let mut chain = ([0u32; MAX_LEAF_GROUP_DEPTH], 0u8);
                let mut g = p.group;
                while let Some(k) = g.filter(|_| usize::from(chain.1) < MAX_LEAF_GROUP_DEPTH) {
                    chain.0[usize::from(chain.1)] = k;
                    chain.1 += 1;
                    g = groups.get(k as usize).and_then(|x| x.parent);
                }
                chain.0[..usize::from(chain.1)].reverse();
                chain
            }));
        }
        if self.contours.is_empty() {
            // No edge inside: one colour, the bases' (the common case for
            // a fragment small against its leaf).
            winding.clear();
            winding.extend(self.pieces.iter().map(|(p, _)| p.base));
            let area = (x1 - x0) * (z1 - z0);
            return self
                .colour_at(winding, groups, chains, covering)
                .map(|c| c * area);
        }
        edges.clear();
        for (pi, (_, cs)) in self.pieces.iter().enumerate() {
            for r in &self.contours[cs.clone()] {
                let c = &self.points[r.clone()];
                for i in 0..c.len() {
                    edges.extend(SweepEdge::new(c[i], c[(i + 1) % c.len()], pi));
                }
            }
        }
        let mut total = [0.0; 4];
        // A leaf holds at most its budget of edges (256 at the max level):
        // its sweep is bounded, so it is never refused.
        let _ = for_each_slab(edges, z0, z1, slabs, u64::MAX, |za, zb, edges, active| {
            let h = zb - za;
            let zm = 0.5 * (za + zb);
            crossings.clear();
            for &k in active {
                let e = &edges[k];
                crossings.push((e.x_at(zm).clamp(x0, x1), e.piece, e.step));
            }
            crossings.sort_by(|a, b| a.0.total_cmp(&b.0));
            winding.clear();
            winding.extend(self.pieces.iter().map(|(p, _)| p.base));
            let mut left = x0;
            let mut gap = |left: f64, right: f64, winding: &[i32], total: &mut [f64; 4]| {
                let width = right - left;
                if width <= 0.0 {
                    return;
                }
                let c = self.colour_at(winding, groups, chains, covering);
                for (t, ck) in total.iter_mut().zip(c) {
                    *t += ck * width * h;
                }
            };
            for &(x, piece, step) in crossings.iter() {
                gap(left, x, winding, &mut total);
                winding[piece] += step;
                left = x;
            }
            gap(left, x1, winding, &mut total);
        });
        total
    }
}

#[cfg(test)]
mod tests {
    use super::{Point, winding_if_clear};
    use crate::geometry::winding;

    /// Whether a point of segment `a–b` lies in the closed rectangle,
    /// by bisection-free dense sampling (enough for these coarse cases).
    fn sampled_touch(a: Point, b: Point, [x0, z0, x1, z1]: [f64; 4]) -> bool {
        (0..=4096).any(|i| {
            let t = f64::from(i) / 4096.0;
            let p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
            p[0] >= x0 && p[0] <= x1 && p[1] >= z0 && p[1] <= z1
        })
    }

    #[test]
    fn winding_if_clear_is_the_winding_of_polygons_that_miss_the_rectangle() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut clear, mut touching) = (0, 0);
        for _ in 0..3000 {
            let n = 3 + (next() * 6.0) as usize;
            let c: Vec<Point> = (0..n).map(|_| [next(), next()]).collect();
            let (x, z, w) = (next() * 0.9, next() * 0.9, next() * 0.1);
            let rect = [x, z, x + w, z + w];
            let centre = [x + 0.5 * w, z + 0.5 * w];
            let touches = (0..n).any(|i| sampled_touch(c[i], c[(i + 1) % n], rect));
            match winding_if_clear(&c, rect, centre) {
                Some(k) => {
                    clear += 1;
                    assert!(!touches, "{c:?} touches {rect:?}");
                    assert_eq!(k, winding(&c, centre), "{c:?} around {centre:?}");
                }
                None => touching += 1,
            }
        }
        assert!(
            clear > 300 && touching > 300,
            "{clear} clear, {touching} touching"
        );
    }
}

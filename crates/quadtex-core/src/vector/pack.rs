//! The packer: recursive subdivision with each shape's contours clipped
//! to each square, leaves closed by the exact mean or kept as gradient
//! or contour leaves.

pub(super) mod sweep;

use super::VECTOR_KNOBS;
use super::art::{MAX_VECTOR_LEVEL, Point, Varying, VectorArt};
use super::composite::{encoded, range_width};
use super::options::{VectorOptions, VectorReport};
use crate::Error;
use crate::colour::Unorm16Rgba;
use crate::geometry::{clip_to_rect, on_rect_border, signed_area};
use crate::memory::{BUILD_BYTES_PER_NODE, check_budget, try_push};
use crate::memory::{CONTOUR_BYTES_PER_LEAF, CONTOUR_BYTES_PER_POINT};
use crate::tree::{self, MAX_DEPTH, MAX_NODES, QuadTree};
use crate::vector::contour_leaf::{ContourLeaves, ContourParts, LeafGroup, LeafPiece};
use crate::vector::gradient_leaf::{GradientLeaves, LeafPaint};
use sweep::{SWEEP_EDGES, SweepScratch};

/// The part of one shape inside a square: its contours are
/// `Pieces::contours[contours]`.
#[derive(Debug, Clone)]
struct Piece {
    shape: u32,
    /// Winding contributed by contours that no longer enter the square.
    base: i32,
    /// Clipped contours that still have edges inside the square.
    contours: std::ops::Range<usize>,
}

/// The pieces of one square, flat: headers, contour ranges and points in
/// three vectors that are cleared and refilled square after square (one
/// per level), so the build allocates per level, not per square.
#[derive(Debug, Default)]
struct Pieces {
    pieces: Vec<Piece>,
    contours: Vec<std::ops::Range<usize>>,
    points: Vec<Point>,
}

impl Pieces {
    fn clear(&mut self) {
        self.pieces.clear();
        self.contours.clear();
        self.points.clear();
    }

    fn contours_of(&self, piece: &Piece) -> impl Iterator<Item = &[Point]> + '_ {
        self.contours[piece.contours.clone()]
            .iter()
            .map(|r| &self.points[r.clone()])
    }
}

#[derive(Debug, Clone, Copy)]
pub(super) struct Square {
    pub(super) x0: f64,
    pub(super) z0: f64,
    pub(super) side: f64,
}

impl Square {
    fn x1(&self) -> f64 {
        self.x0 + self.side
    }
    fn z1(&self) -> f64 {
        self.z0 + self.side
    }
    /// The corners, counter-clockwise.
    fn corners(&self) -> [Point; 4] {
        let (x1, z1) = (self.x1(), self.z1());
        [[self.x0, self.z0], [x1, self.z0], [x1, z1], [self.x0, z1]]
    }

    fn child(&self, k: usize) -> Square {
        let h = self.side / 2.0;
        Square {
            x0: self.x0 + if k & 1 == 1 { h } else { 0.0 },
            z0: self.z0 + if k & 2 == 2 { h } else { 0.0 },
            side: h,
        }
    }
}

struct VectorBuilder<'a> {
    art: &'a VectorArt,
    max_level: u8,
    tolerance: f64,
    max_nodes: u64,
    max_bytes: Option<u64>,
    nodes: u64,
    levels: Vec<Vec<(bool, Unorm16Rgba)>>,
    report: VectorReport,
    /// Whether squares may become gradient leaves.
    gradient_leaves: bool,
    /// Paints of gradient leaves, and the index of each by its gradient
    /// and coefficients' bits.
    leaf_paints: Vec<LeafPaint>,
    leaf_paint_index: std::collections::HashMap<(u32, [u64; 20]), u32>,
    /// `(level, index in level, paint)` of each gradient leaf.
    leaves: Vec<(u8, usize, u32)>,
    /// The edge budget of contour leaves, if they are made.
    contour_budget: Option<usize>,
    /// Points of the contour leaves made so far, counted against the
    /// memory budget with the nodes.
    contour_points: u64,
    /// Each contour leaf's groups, and its pieces (paint order) with their
    /// contours.
    contour_leaves: Vec<ContourLeaf>,
    /// `(level, index in level, contour leaf)` of each contour leaf.
    contour_nodes: Vec<(u8, usize, usize)>,
    /// The leaf [`VectorBuilder::square`] just made of its square.
    made_leaf: Option<Made>,
    /// Clipping buffers.
    scratch: [Vec<Point>; 2],
    /// The pieces of the square being built at each level.
    work: Vec<Pieces>,
    /// Scratch of the trapezoid sweep.
    sweep: SweepScratch,
    /// [`VectorOptions::max_sweep_work`] (the steps so far are
    /// [`VectorReport::sweep_work`]).
    max_sweep_work: u64,
}

impl QuadTree {
    /// Packs vector art (see the [module documentation](crate::vector)).
    /// With a memory budget, art whose estimate
    /// ([`VectorArt::estimate_bytes`]) is above it is refused with
    /// [`Error::MemoryBudget`] before anything is built;
    /// [`QuadTree::from_vector_within`] lowers the settings left to it
    /// instead.
    pub fn from_vector(
        art: &VectorArt,
        options: &VectorOptions,
    ) -> Result<(QuadTree, VectorReport), Error> {
        check_options(options)?;
        art.check_estimate(options)?;
        build(art, options)
    }
}

/// Refuses a level beyond [`MAX_VECTOR_LEVEL`] and a bad tolerance.
pub(super) fn check_options(options: &VectorOptions) -> Result<(), Error> {
    if options.max_level > MAX_VECTOR_LEVEL {
        return Err(Error::DepthTooLarge {
            depth: options.max_level.into(),
            max: MAX_VECTOR_LEVEL.into(),
        });
    }
    if !(options.tolerance.is_finite() && options.tolerance >= 0.0) {
        return Err(Error::BadTolerance(options.tolerance));
    }
    Ok(())
}

/// Packs `art` with `options`, already checked (and their estimate with
/// them), refusing once the nodes and contour leaves built so far pass the
/// memory budget.
pub(super) fn build(
    art: &VectorArt,
    options: &VectorOptions,
) -> Result<(QuadTree, VectorReport), Error> {
    let mut b = VectorBuilder {
        art,
        max_level: options.max_level,
        tolerance: options.tolerance,
        max_nodes: options.max_nodes.min(MAX_NODES),
        max_bytes: options.max_bytes,
        nodes: 1,
        levels: vec![Vec::new(); usize::from(options.max_level) + 1],
        report: VectorReport::default(),
        gradient_leaves: options.gradient_leaves,
        leaf_paints: Vec::new(),
        leaf_paint_index: std::collections::HashMap::new(),
        leaves: Vec::new(),
        contour_budget: options.contour_leaves,
        contour_points: 0,
        contour_leaves: Vec::new(),
        contour_nodes: Vec::new(),
        made_leaf: None,
        scratch: [Vec::new(), Vec::new()],
        work: (0..=options.max_level).map(|_| Pieces::default()).collect(),
        sweep: SweepScratch::default(),
        max_sweep_work: options.max_sweep_work,
    };
    let root = Square {
        x0: 0.0,
        z0: 0.0,
        side: 1.0,
    };
    let mut top = Pieces::default();
    for (s, shape) in art.shapes.iter().enumerate() {
        b.clip_piece_into(
            s as u32,
            0,
            shape
                .contours
                .iter()
                .map(|c| (c.points.as_slice(), Some(c.bounds))),
            root,
            &mut top,
        );
    }
    b.work[0] = top;
    let (_, colour, terminal) = b.square(0, root)?;
    b.levels[0].push((!terminal, colour));
    let made = b.made_leaf.take();
    b.record(made, 0, 0);
    while b.levels.last().is_some_and(Vec::is_empty) {
        b.levels.pop();
    }
    let mut level_start = vec![0usize];
    for l in &b.levels {
        level_start.push(level_start.last().copied().unwrap_or(0) + l.len());
    }
    let mut tree = tree::from_levels(b.levels, tree::Aspect::SQUARE)?;
    if !b.contour_nodes.is_empty() {
        let mut order: Vec<(u32, usize)> = b
            .contour_nodes
            .iter()
            .map(|&(level, i, leaf)| ((level_start[usize::from(level)] + i) as u32, leaf))
            .collect();
        order.sort_unstable();
        let mut parts = ContourParts::default();
        for (node, leaf) in order {
            let (groups, pieces) = std::mem::take(&mut b.contour_leaves[leaf]);
            parts.push_leaf(
                node,
                &groups,
                pieces.iter().map(|(piece, contours)| {
                    (*piece, contours.iter().map(Vec::as_slice).collect())
                }),
            );
        }
        b.report.contour_leaves = parts.nodes.len() as u64;
        let leaves =
            ContourLeaves::new(MAX_DEPTH, parts)?.with_curve_tolerance(art.curve_tolerance())?;
        b.report.contour_leaf_points = leaves.point_count() as u64;
        tree = tree.with_contour_leaves(leaves)?;
    }
    if b.leaves.is_empty() {
        return Ok((tree, b.report));
    }
    let mut leaves: Vec<(u32, u32)> = b
        .leaves
        .iter()
        .map(|&(level, i, paint)| ((level_start[usize::from(level)] + i) as u32, paint))
        .collect();
    leaves.sort_unstable();
    b.report.gradient_leaves = leaves.len() as u64;
    b.report.gradient_leaf_paints = b.leaf_paints.len() as u64;
    let leaves = GradientLeaves::new(
        options.max_level,
        options.tolerance.min(1.0),
        b.leaf_paints,
        &leaves,
    )?;
    Ok((tree.with_gradient_leaves(leaves)?, b.report))
}

fn quantise(c: [f64; 4]) -> Unorm16Rgba {
    let q = c.map(|v| (v * 65535.0 + 0.5).clamp(0.0, 65535.0) as u16);
    let a = q[3];
    Unorm16Rgba([q[0].min(a), q[1].min(a), q[2].min(a), a])
}

impl VectorBuilder<'_> {
    /// Returns the square's exact mean colour, its stored colour and whether
    /// it is terminal; pushes its children's nodes. Its pieces are in
    /// `self.work[level]`.
    fn square(&mut self, level: u8, sq: Square) -> Result<([f64; 4], Unorm16Rgba, bool), Error> {
        let mut here = std::mem::take(&mut self.work[usize::from(level)]);
        let result = self.square_with(level, sq, &mut here);
        self.work[usize::from(level)] = here;
        result
    }

    fn square_with(
        &mut self,
        level: u8,
        sq: Square,
        here: &mut Pieces,
    ) -> Result<([f64; 4], Unorm16Rgba, bool), Error> {
        self.cull(&mut here.pieces);
        if here.pieces.iter().all(|p| p.contours.is_empty()) {
            let covered = &mut self.sweep.covered;
            covered.clear();
            covered.extend(here.pieces.iter().map(|p| p.shape));
            let visible = &mut self.sweep.visible;
            self.art.visible(covered, visible);
            if !self.art.any_gradient(covered) {
                let mean = self.art.composite(visible, 0, covered);
                return Ok((mean, quantise(mean), true));
            }
            let poly = sq.corners();
            let range = encoded(self.art.composite_range(visible, 0, covered, &poly));
            // A point lies within `deviation` of the mean, which cannot be
            // below half the range: only then is the mean worth computing.
            if range_width(&range) <= 2.0 * self.tolerance || level == self.max_level {
                let (mean, error) = self.art.composite_over(visible, covered, &poly);
                let m = encoded(mean.map(|v| [v, v]));
                let deviation = (0..4)
                    .map(|c| (range[c][1] - m[c][0]).max(m[c][0] - range[c][0]))
                    .fold(0.0, f64::max);
                if deviation <= self.tolerance || level == self.max_level {
                    let r = &mut self.report;
                    r.max_smooth_deviation = r.max_smooth_deviation.max(deviation);
                    r.max_mean_error = r.max_mean_error.max(error);
                    return Ok((mean, quantise(mean), true));
                }
            }
            if self.gradient_leaves
                && level < self.max_level
                && let Some((mean, paint)) = self.leaf_paint(&poly)
            {
                self.made_leaf = Some(Made::Gradient(paint));
                return Ok((mean, quantise(mean), true));
            }
            // Smooth colour that varies too much: split like an edge would.
        }
        if let Some(budget) = self.contour_budget
            && self.plain(here)
            && edge_count(here)
                <= if level == self.max_level {
                    budget.max(SWEEP_EDGES)
                } else {
                    budget
                }
        {
            let mean = self.sweep(here, sq)?;
            self.contour_points += edge_count(here) as u64;
            // The leaf's groups, parents first, by their global ids.
            let mut local: Vec<(u32, LeafGroup)> = Vec::new();
            let pieces = here
                .pieces
                .iter()
                .map(|p| {
                    let shape = &self.art.shapes[p.shape as usize];
                    let mut parent = None;
                    for &g in &shape.groups {
                        let k = match local.iter().position(|(id, _)| *id == g) {
                            Some(k) => k,
                            None => {
                                let opacity = self.art.group_opacity[g as usize];
                                local.push((g, LeafGroup { opacity, parent }));
                                local.len() - 1
                            }
                        };
                        parent = Some(k as u32);
                    }
                    let piece = LeafPiece {
                        colour: shape.colour,
                        rule: shape.rule,
                        base: p.base,
                        group: parent,
                    };
                    (piece, here.contours_of(p).map(<[Point]>::to_vec).collect())
                })
                .collect();
            let groups = local.into_iter().map(|(_, g)| g).collect();
            self.contour_leaves.push((groups, pieces));
            self.made_leaf = Some(Made::Contour(self.contour_leaves.len() - 1));
            return Ok((mean, quantise(mean), true));
        }
        if level == self.max_level {
            if self.contour_budget.is_some() && self.plain(here) {
                // Flat art a contour leaf could keep but for its edges.
                self.report.crowded_leaves += 1;
            }
            let (mean, bound) = self.sweep_split(here, sq, 0)?;
            self.report.max_mean_error = self.report.max_mean_error.max(bound);
            return Ok((mean, quantise(mean), true));
        }
        self.nodes += 4;
        if self.nodes > self.max_nodes {
            return Err(Error::TooManyNodes {
                nodes: self.nodes,
                max: self.max_nodes,
            });
        }
        let (nodes, max_level) = (self.nodes, self.max_level);
        let (points, leaves) = (self.contour_points, self.contour_leaves.len() as u64);
        check_budget(
            || format!("packing at level {max_level} (stopped after {nodes} nodes)"),
            nodes * BUILD_BYTES_PER_NODE
                + points * CONTOUR_BYTES_PER_POINT
                + leaves * CONTOUR_BYTES_PER_LEAF,
            self.max_bytes,
            VECTOR_KNOBS,
        )?;
        let mut children = [(Unorm16Rgba::default(), true, None); 4];
        let mut sum = [0.0; 4];
        let next = usize::from(level) + 1;
        for (k, child) in children.iter_mut().enumerate() {
            let csq = sq.child(k);
            let mut below = std::mem::take(&mut self.work[next]);
            below.clear();
            for p in &here.pieces {
                self.clip_piece_into(
                    p.shape,
                    p.base,
                    here.contours_of(p).map(|c| (c, None)),
                    csq,
                    &mut below,
                );
            }
            self.work[next] = below;
            let (mean, colour, terminal) = self.square(level + 1, csq)?;
            for (s, m) in sum.iter_mut().zip(mean) {
                *s += m / 4.0;
            }
            *child = (colour, terminal, self.made_leaf.take());
        }
        for (c, terminal, made) in children {
            let index = self.levels[next].len();
            self.record(made, level + 1, index);
            try_push(&mut self.levels[next], (!terminal, c), "tree level")?;
        }
        Ok((sum, quantise(sum), false))
    }

    /// Notes the leaf made of the square at `index` of `level`.
    fn record(&mut self, made: Option<Made>, level: u8, index: usize) {
        match made {
            Some(Made::Gradient(paint)) => self.leaves.push((level, index, paint)),
            Some(Made::Contour(leaf)) => self.contour_nodes.push((level, index, leaf)),
            None => {}
        }
    }

    /// True when every piece is a solid fill outside clip paths and masks,
    /// in groups (if any) of plain opacity: what a contour leaf can hold.
    fn plain(&self, pieces: &Pieces) -> bool {
        pieces
            .pieces
            .iter()
            .all(|p| self.art.is_plain_shape(p.shape as usize))
    }

    /// The square `poly`'s mean and the index of its gradient-leaf paint,
    /// when its shapes (in `self.sweep`: none has an edge inside) make a
    /// colour affine in one linear gradient whose mean over it is exact.
    fn leaf_paint(&mut self, poly: &[Point; 4]) -> Option<([f64; 4], u32)> {
        let (covered, visible) = (&self.sweep.covered, &self.sweep.visible);
        let (gradient, offset, matrix) = self.art.affine_in_gradient(visible, covered)?;
        let (mean, error) = self.art.composite_over(visible, covered, poly);
        if error != 0.0 {
            return None;
        }
        let mut key = [0u64; 20];
        for (k, v) in offset.iter().chain(matrix.iter().flatten()).enumerate() {
            key[k] = v.to_bits();
        }
        if let Some(&index) = self.leaf_paint_index.get(&(gradient, key)) {
            return Some((mean, index));
        }
        let Varying::Gradient(g) = &self.art.gradients[gradient as usize] else {
            return None;
        };
        // A paint beyond the leaves' limits (an absurdly steep gradient) splits instead.
        let paint = LeafPaint::new(g.clone(), offset, matrix).ok()?;
        let index = self.leaf_paints.len() as u32;
        self.leaf_paints.push(paint);
        self.leaf_paint_index.insert((gradient, key), index);
        Some((mean, index))
    }

    /// Drops shapes that do not reach the square and shapes hidden by an
    /// opaque shape covering all of it.
    fn cull(&self, pieces: &mut Vec<Piece>) {
        pieces.retain(|p| {
            !p.contours.is_empty() || self.art.shapes[p.shape as usize].rule.covers(p.base)
        });
        if let Some(top) = pieces
            .iter()
            .rposition(|p| p.contours.is_empty() && self.art.is_opaque(p.shape))
        {
            if self.art.clips.is_empty() && self.art.masks.is_empty() {
                pieces.drain(..top);
            } else {
                // Clip and mask members below stay: shapes above may be clipped or masked by them.
                let mut i = 0;
                pieces.retain(|p| {
                    i += 1;
                    i > top || self.art.shapes[p.shape as usize].member
                });
            }
        }
    }

    /// Appends to `out` the piece of shape `shape` (winding `base` from
    /// contours no longer inside, and `contours` with their bounds when
    /// known) clipped to `sq`, unless it no longer reaches `sq` (winding 0
    /// and no edges).
    fn clip_piece_into<'c>(
        &mut self,
        shape: u32,
        base: i32,
        contours: impl Iterator<Item = (&'c [Point], Option<[f64; 4]>)>,
        sq: Square,
        out: &mut Pieces,
    ) {
        let first = out.contours.len();
        let mut base = base;
        for (contour, bounds) in contours {
            let b = bounds.unwrap_or_else(|| bounds_of(contour));
            if b[2] < sq.x0 || b[0] > sq.x1() || b[3] < sq.z0 || b[1] > sq.z1() {
                continue; // wholly outside: winds 0 around every interior point
            }
            let start = out.points.len();
            clip_to_square(contour, sq, &mut self.scratch, &mut out.points);
            let clipped = &out.points[start..];
            if clipped.len() < 3 {
                out.points.truncate(start);
                continue;
            }
            if on_border(clipped, sq) {
                let w = signed_area(clipped) / (sq.side * sq.side);
                base += w.round() as i32;
                out.points.truncate(start);
            } else {
                out.contours.push(start..out.points.len());
            }
        }
        let contours = first..out.contours.len();
        if base != 0 || !contours.is_empty() {
            out.pieces.push(Piece {
                shape,
                base,
                contours,
            });
        }
    }
}

/// A contour leaf being built: its groups, and its pieces with their
/// contours.
type ContourLeaf = (Vec<LeafGroup>, Vec<(LeafPiece, Vec<Vec<Point>>)>);

/// The leaf a square was made into.
#[derive(Debug, Clone, Copy)]
enum Made {
    /// A gradient leaf of this paint.
    Gradient(u32),
    /// A contour leaf, by its index in `VectorBuilder::contour_leaves`.
    Contour(usize),
}

/// Edges of the pieces' clipped contours.
fn edge_count(pieces: &Pieces) -> usize {
    pieces
        .pieces
        .iter()
        .flat_map(|p| &pieces.contours[p.contours.clone()])
        .map(|r| r.len())
        .sum()
}

fn bounds_of(points: &[Point]) -> [f64; 4] {
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for p in points {
        b = [
            b[0].min(p[0]),
            b[1].min(p[1]),
            b[2].max(p[0]),
            b[3].max(p[1]),
        ];
    }
    b
}

/// True when every edge of the (clipped) contour runs along the square's border.
pub(super) fn on_border(points: &[Point], sq: Square) -> bool {
    on_rect_border(points, [sq.x0, sq.z0, sq.x1(), sq.z1()])
}

/// Sutherland–Hodgman clipping of a closed polygon to `sq`, appended to
/// `out`; points on the border are set to the border's coordinate exactly,
/// consecutive duplicates removed. `scratch` holds the passes.
pub(super) fn clip_to_square(
    points: &[Point],
    sq: Square,
    scratch: &mut [Vec<Point>; 2],
    out: &mut Vec<Point>,
) {
    clip_to_rect(points, [sq.x0, sq.z0, sq.x1(), sq.z1()], scratch, out);
}

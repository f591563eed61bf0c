//! A leaf's exact mean colour by the trapezoid sweep, split into
//! quadrants where it holds too many edges.

use super::{Pieces, Square, VectorBuilder, edge_count};
use crate::Error;
use crate::geometry::{SlabScratch, SweepEdge, for_each_slab, winding};

/// Edges above which a leaf is swept quadrant by quadrant (see
/// `VectorBuilder::sweep_split`).
pub(in crate::vector) const SWEEP_EDGES: usize = 256;

/// Deepest a leaf is split for its sweep while it holds more than
/// [`SWEEP_EDGES`] edges: `4^6` sub-squares. Below, a square is swept
/// whatever its edges (coincident edges never separate, so splitting
/// further would not pay), unless it holds more than [`SWEEP_HUGE`].
pub(super) const SWEEP_SPLITS: u8 = 6;

/// Edges above which a square keeps splitting past [`SWEEP_SPLITS`]:
/// sweeping them whole could take minutes (thousands of edges crossing
/// each other at as many heights, as dashed strokes piled on a point).
/// Measured: splitting on by the sweep's estimated work instead, or from
/// 64 edges, made such art slower still, or made coincident edges (which
/// never separate) split to the floor.
pub(super) const SWEEP_HUGE: usize = 1024;

/// Deepest a leaf is split for its sweep at all; a square there still
/// holding more than [`SWEEP_HUGE`] edges takes its centre's colour (see
/// `VectorBuilder::sweep_split`), at most `4^-20` of the leaf's area each.
pub(in crate::vector) const SWEEP_FLOOR: u8 = 20;

/// Buffers of [`VectorBuilder::sweep`], kept between leaves.
#[derive(Debug, Default)]
pub(super) struct SweepScratch {
    pub(super) edges: Vec<SweepEdge>,
    pub(super) slabs: SlabScratch,
    pub(super) winding: Vec<i32>,
    /// `(x at mid-slab, piece, winding step, x at slab bottom, x at slab top)`.
    pub(super) crossings: Vec<(f64, usize, i32, f64, f64)>,
    pub(super) covered: Vec<u32>,
    pub(super) visible: Vec<u32>,
    pub(super) memo: FlatColours,
}

/// The flat colours of the last few covered sets a sweep met: gaps
/// between a dashed stroke's dashes alternate between two sets, and
/// compositing is the sweep's dearest step after sorting.
#[derive(Debug, Default)]
pub(super) struct FlatColours {
    /// Each set's shapes, one after the other.
    pub(super) shapes: Vec<u32>,
    /// Each set's end in `shapes`, and its colour.
    pub(super) sets: Vec<(usize, [f64; 4])>,
}

impl FlatColours {
    /// Sets kept; one past them starts the memo afresh.
    const SETS: usize = 8;

    fn clear(&mut self) {
        self.shapes.clear();
        self.sets.clear();
    }

    fn get(&self, covered: &[u32]) -> Option<[f64; 4]> {
        let mut start = 0;
        for &(end, colour) in &self.sets {
            if self.shapes[start..end] == *covered {
                return Some(colour);
            }
            start = end;
        }
        None
    }

    fn put(&mut self, covered: &[u32], colour: [f64; 4]) {
        if self.sets.len() == Self::SETS {
            self.clear();
        }
        self.shapes.extend_from_slice(covered);
        self.sets.push((self.shapes.len(), colour));
    }
}

impl VectorBuilder<'_> {
    /// Mean colour of a leaf: the trapezoid sweep, run on its quadrants
    /// instead (recursively, [`SWEEP_SPLITS`] deep) while it holds more
    /// than [`SWEEP_EDGES`] edges, and deeper while more than
    /// [`SWEEP_HUGE`]. The sweep's cost grows with the edges alive at once
    /// times the heights where they end or cross (a dashed stroke packed
    /// at a low level put 5 000 in one leaf: 4 s; a fuzzed star of dashed
    /// spokes 13 000 meeting in one point: minutes); the mean stays exact,
    /// the average of the quadrants' exact means. Where more than
    /// [`SWEEP_HUGE`] edges still meet in a square [`SWEEP_FLOOR`] levels
    /// below the leaf (they converge on a point), that square takes the
    /// colour at its centre, and its share of the leaf's area (at most
    /// `4^-SWEEP_FLOOR` each) goes into [`VectorReport::max_mean_error`].
    /// Returns the mean and that bound.
    pub(super) fn sweep_split(
        &mut self,
        pieces: &Pieces,
        sq: Square,
        depth: u8,
    ) -> Result<([f64; 4], f64), Error> {
        let edges = edge_count(pieces);
        if edges <= SWEEP_EDGES || (depth >= SWEEP_SPLITS && edges <= SWEEP_HUGE) {
            return Ok((self.sweep(pieces, sq)?, 0.0));
        }
        if depth >= SWEEP_FLOOR {
            return Ok((self.colour_at_centre(pieces, sq), 1.0));
        }
        let mut sum = [0.0; 4];
        let mut bound = 0.0;
        let mut below = Pieces::default();
        for k in 0..4 {
            let csq = sq.child(k);
            below.clear();
            for p in &pieces.pieces {
                self.clip_piece_into(
                    p.shape,
                    p.base,
                    pieces.contours_of(p).map(|c| (c, None)),
                    csq,
                    &mut below,
                );
            }
            self.cull(&mut below.pieces);
            let (mean, b) = self.sweep_split(&below, csq, depth + 1)?;
            for (s, m) in sum.iter_mut().zip(mean) {
                *s += m / 4.0;
            }
            bound += b / 4.0;
        }
        Ok((sum, bound))
    }

    /// The composite at the centre of `sq` (each piece's winding there).
    fn colour_at_centre(&mut self, pieces: &Pieces, sq: Square) -> [f64; 4] {
        let centre = [sq.x0 + 0.5 * sq.side, sq.z0 + 0.5 * sq.side];
        let covered = &mut self.sweep.covered;
        covered.clear();
        for p in &pieces.pieces {
            let w = p.base
                + pieces
                    .contours_of(p)
                    .map(|c| winding(c, centre))
                    .sum::<i32>();
            if self.art.shapes[p.shape as usize].rule.covers(w) {
                covered.push(p.shape);
            }
        }
        let visible = &mut self.sweep.visible;
        self.art.visible(covered, visible);
        let h = 1e-9 * sq.side;
        let dot = [
            [centre[0] - h, centre[1] - h],
            [centre[0] + h, centre[1] - h],
            [centre[0] + h, centre[1] + h],
            [centre[0] - h, centre[1] + h],
        ];
        if self.art.any_gradient(covered) {
            self.art.composite_over(visible, covered, &dot).0
        } else {
            self.art.composite(visible, 0, covered)
        }
    }

    /// Exact mean colour of a leaf by the trapezoid sweep, or
    /// [`Error::SweepWork`] when it would pass the packing's budget.
    pub(super) fn sweep(&mut self, pieces: &Pieces, sq: Square) -> Result<[f64; 4], Error> {
        let SweepScratch {
            edges,
            slabs,
            winding,
            crossings,
            covered,
            visible,
            memo,
        } = &mut self.sweep;
        memo.clear();
        edges.clear();
        for (pi, piece) in pieces.pieces.iter().enumerate() {
            for c in pieces.contours_of(piece) {
                for i in 0..c.len() {
                    edges.extend(SweepEdge::new(c[i], c[(i + 1) % c.len()], pi));
                }
            }
        }
        let mean_error = &mut self.report.max_mean_error;
        self.report.swept_leaves += 1;
        self.report.max_leaf_edges = self.report.max_leaf_edges.max(edges.len());
        let mut total = [0.0; 4];
        let art = self.art;
        let (x0, x1) = (sq.x0, sq.x1());
        let (done, max) = (self.report.sweep_work, self.max_sweep_work);
        let slab = |z0: f64, z1: f64, edges: &[SweepEdge], active: &[usize]| {
            let h = z1 - z0;
            let zm = 0.5 * (z0 + z1);
            crossings.clear();
            for &k in active {
                let e = &edges[k];
                let x_at = |z: f64| e.x_at(z).clamp(x0, x1);
                crossings.push((x_at(zm), e.piece, e.step, x_at(z0), x_at(z1)));
            }
            // Stable: consecutive slabs' orders differ little, and runs sort fast.
            crossings.sort_by(|a, b| a.0.total_cmp(&b.0));
            winding.clear();
            winding.extend(pieces.pieces.iter().map(|p| p.base));
            // The colour of flat art between crossings changes only where
            // a piece's coverage does: kept until then.
            let mut flat: Option<[f64; 4]> = None;
            // A boundary of a gap: x at the slab's middle, bottom and top.
            let mut left = [x0; 3];
            let mut gap = |left: [f64; 3],
                           right: [f64; 3],
                           winding: &[i32],
                           flat: &mut Option<[f64; 4]>,
                           total: &mut [f64; 4]| {
                let width = right[0] - left[0];
                if width <= 0.0 {
                    return;
                }
                let c = match *flat {
                    Some(c) => c,
                    None => {
                        covered.clear();
                        for (p, w) in pieces.pieces.iter().zip(winding) {
                            if art.shapes[p.shape as usize].rule.covers(*w) {
                                covered.push(p.shape);
                            }
                        }
                        if let Some(c) = memo.get(covered) {
                            *flat = Some(c);
                            c
                        } else {
                            art.visible(covered, visible);
                            if art.any_gradient(covered) {
                                let trapezoid =
                                    [[left[1], z0], [right[1], z0], [right[2], z1], [left[2], z1]];
                                let (mean, error) =
                                    art.composite_over(visible, covered, &trapezoid);
                                *mean_error = mean_error.max(error);
                                mean
                            } else {
                                let c = art.composite(visible, 0, covered);
                                memo.put(covered, c);
                                *flat = Some(c);
                                c
                            }
                        }
                    }
                };
                for (t, v) in total.iter_mut().zip(c) {
                    *t += v * width * h;
                }
            };
            for &(x, piece, step, x_lo, x_hi) in crossings.iter() {
                let right = [x, x_lo, x_hi];
                gap(left, right, winding, &mut flat, &mut total);
                let rule = art.shapes[pieces.pieces[piece].shape as usize].rule;
                let before = rule.covers(winding[piece]);
                winding[piece] += step;
                if rule.covers(winding[piece]) != before {
                    flat = None;
                }
                left = right;
            }
            gap(left, [x1; 3], winding, &mut flat, &mut total);
        };
        match for_each_slab(edges, sq.z0, sq.z1(), slabs, max.saturating_sub(done), slab) {
            Ok(work) => self.report.sweep_work = done + work,
            Err(work) => {
                return Err(Error::SweepWork {
                    needed: done.saturating_add(work),
                    max,
                });
            }
        }
        let area = sq.side * sq.side;
        Ok(total.map(|t| t / area))
    }
}

//! Gradient leaves: terminal squares that keep their paint.
//!
//! A square of vector art that no edge enters, painted by one linear
//! gradient composited with flat colour, has a colour that is an affine
//! function of the gradient's colour: `colour(p) = offset + matrix·g(p)`,
//! where `g(p)` is the gradient's linear premultiplied colour at `p` and
//! `offset`, `matrix` come from the layers above and below it (*over*
//! and group opacity are affine in each layer). Instead of splitting such a
//! square until every piece is within the packing tolerance of its mean
//! (about `area·(slope/tolerance)²` squares), the packer stores it once and
//! keeps its [`LeafPaint`]; the tree's cost becomes proportional to the
//! art's edges, whatever the gradients' slopes.
//!
//! **What each traversal sees.**
//! * The fragment integral ([`crate::QuadTree::weighted_colour`]) integrates
//!   a gradient leaf **exactly** over the fragment's overlap: the mean of a
//!   linear gradient over a rectangle is exact
//!   ([`crate::vector::gradient`], below 1e-13 against a compensated reference),
//!   and `offset + matrix·mean` is the mean of the composite. A square
//!   wholly inside the fragment counts at its stored mean (rounded once to
//!   16 bits, as every node).
//! * The exact-pixel walk ([`crate::filter::region`]) and everything built on
//!   [`crate::QuadTree::for_each_leaf`] see the leaf subdivided on demand
//!   into *cells*, each carrying the exact mean of the paint over it; a
//!   cell is terminal once the composite's sRGB-encoded range over it is
//!   within the stored tolerance (the packer's rule for smooth colour), at
//!   the tree's depth, or [`MAX_CELL_LEVELS`] below the leaf. Their results
//!   are therefore those of a tree split to that tolerance, without its
//!   nodes.
//!
//! Leaves live in the tree's square (tree space); so does the gradient's
//! parameter.

use crate::Error;
use crate::colour::srgb_encode;
use crate::tree::leaf_nodes::LeafNodes;
use crate::vector::gradient::Gradient;

type Point = [f64; 2];

/// Deepest a leaf (gradient or contour) is subdivided into cells below
/// its own level: to the deepest level of any tree.
pub const MAX_CELL_LEVELS: u8 = crate::MAX_DEPTH;

/// Most gradient leaves a tree may have (leaves are addressed with 28 bits).
pub const MAX_GRADIENT_LEAVES: usize = 1 << 28;

/// The colour of a gradient leaf: `offset + matrix·g(p)`, linear
/// premultiplied RGBA, `g` a linear [`Gradient`] in tree space.
///
/// Invariant: the gradient is linear; `offset` and `matrix` are finite with
/// magnitudes at most [`LeafPaint::MAX_COEFFICIENT`].
#[derive(Debug, Clone, PartialEq)]
pub struct LeafPaint {
    gradient: Gradient,
    offset: [f64; 4],
    matrix: [[f64; 4]; 4],
}

impl LeafPaint {
    /// Largest magnitude of an `offset` or `matrix` entry. Compositing
    /// colours in `[0, 1]` keeps every entry within `[-1, 1]`; the slack
    /// admits rounding and nothing absurd.
    pub const MAX_COEFFICIENT: f64 = 4.0;

    /// Largest magnitude of the gradient parameter's coefficients
    /// (`t = g[0]·x + g[1]·z + g[2]`): 2^40 periods across the tree.
    pub const MAX_SLOPE: f64 = (1u64 << 40) as f64;

    /// The paint `offset + matrix·gradient(p)`. [`Error::BadVector`] when
    /// the gradient is not linear or a coefficient is not finite or beyond
    /// [`LeafPaint::MAX_COEFFICIENT`].
    pub fn new(
        gradient: Gradient,
        offset: [f64; 4],
        matrix: [[f64; 4]; 4],
    ) -> Result<LeafPaint, Error> {
        if !gradient.is_linear() {
            return Err(Error::BadVector(
                "a gradient leaf's gradient must be linear".into(),
            ));
        }
        let slope_ok = gradient
            .linear_parameter()
            .is_some_and(|g| g.iter().all(|v| v.abs() <= Self::MAX_SLOPE));
        if !slope_ok {
            return Err(Error::BadVector(format!(
                "a gradient leaf's gradient parameter {:?} exceeds {}",
                gradient.linear_parameter(),
                Self::MAX_SLOPE
            )));
        }
        let ok = |v: &f64| v.is_finite() && v.abs() <= Self::MAX_COEFFICIENT;
        if !(offset.iter().all(ok) && matrix.iter().flatten().all(ok)) {
            return Err(Error::BadVector(format!(
                "gradient leaf coefficients {offset:?}, {matrix:?} are not finite or exceed {}",
                Self::MAX_COEFFICIENT
            )));
        }
        Ok(LeafPaint {
            gradient,
            offset,
            matrix,
        })
    }

    /// The gradient.
    pub fn gradient(&self) -> &Gradient {
        &self.gradient
    }

    /// The colour where the gradient's colour is zero.
    pub fn offset(&self) -> [f64; 4] {
        self.offset
    }

    /// Row `c` gives output channel `c` from the gradient's four channels.
    pub fn matrix(&self) -> [[f64; 4]; 4] {
        self.matrix
    }

    fn apply(&self, g: [f64; 4]) -> [f64; 4] {
        std::array::from_fn(|c| {
            self.offset[c] + (0..4).map(|k| self.matrix[c][k] * g[k]).sum::<f64>()
        })
    }

    /// Linear premultiplied colour at tree point `p`.
    pub fn colour_at(&self, p: Point) -> [f64; 4] {
        self.apply(self.gradient.colour_at(p))
    }

    /// Exact mean colour over the convex polygon `poly` (tree space).
    pub fn mean_over(&self, poly: &[Point]) -> [f64; 4] {
        self.apply(self.gradient.mean_over(poly).0)
    }

    /// Per channel `[lo, hi]` of the colour over the convex polygon `poly`:
    /// interval arithmetic through the affine map.
    pub fn range_over(&self, poly: &[Point]) -> [[f64; 2]; 4] {
        let g = self.gradient.range_over(poly);
        std::array::from_fn(|c| {
            let mut r = [self.offset[c]; 2];
            for (k, gk) in g.iter().enumerate() {
                let m = self.matrix[c][k];
                let (a, b) = (m * gk[0], m * gk[1]);
                r[0] += a.min(b);
                r[1] += a.max(b);
            }
            r
        })
    }

    /// Widest channel of the composite's range over `poly`, colour channels
    /// sRGB-encoded (alpha as is): the packer's measure of smooth colour.
    pub fn encoded_width(&self, poly: &[Point]) -> f64 {
        encoded_width(&self.range_over(poly))
    }

    /// Widest channel of the linear range over `poly`.
    pub fn linear_width(&self, poly: &[Point]) -> f64 {
        linear_width(&self.range_over(poly))
    }
}

/// Widest channel of a range, colour channels sRGB-encoded.
fn encoded_width(r: &[[f64; 2]; 4]) -> f64 {
    (0..4)
        .map(|c| {
            if c < 3 {
                srgb_encode(r[c][1]) - srgb_encode(r[c][0])
            } else {
                r[c][1] - r[c][0]
            }
        })
        .fold(0.0, f64::max)
}

/// Widest channel of a linear range.
fn linear_width(r: &[[f64; 2]; 4]) -> f64 {
    r.iter().map(|r| r[1] - r[0]).fold(0.0, f64::max)
}

/// The gradient leaves of a tree (see the [module documentation](self)):
/// their paints, the stored nodes that are leaves (unpadded breadth-first
/// indices, increasing) and the paint of each.
///
/// Invariants: at least one leaf and at most [`MAX_GRADIENT_LEAVES`];
/// nodes strictly increasing; every paint index in range; `depth` at most
/// [`crate::MAX_DEPTH`]; `tolerance` finite, in `[0, 1]`.
#[derive(Debug, Clone, PartialEq)]
pub struct GradientLeaves {
    depth: u8,
    tolerance: f64,
    paints: Vec<LeafPaint>,
    /// The leaves' nodes, and their squares once attached to their tree.
    at: LeafNodes,
    paint_of: Vec<u32>,
}

impl GradientLeaves {
    /// Leaves `(node, paint)` of a tree answering down to level `depth`,
    /// cells terminal within `tolerance` (sRGB-encoded, as
    /// [`crate::VectorOptions::tolerance`]). [`Error::MalformedTree`]
    /// names the first broken invariant.
    pub fn new(
        depth: u8,
        tolerance: f64,
        paints: Vec<LeafPaint>,
        leaves: &[(u32, u32)],
    ) -> Result<GradientLeaves, Error> {
        let bad = |why: String| Err(Error::MalformedTree(format!("gradient leaves: {why}")));
        if depth > crate::MAX_DEPTH {
            return bad(format!("depth {depth} exceeds {}", crate::MAX_DEPTH));
        }
        if !(tolerance.is_finite() && (0.0..=1.0).contains(&tolerance)) {
            return bad(format!("tolerance {tolerance} is not in [0, 1]"));
        }
        if leaves.is_empty() || leaves.len() > MAX_GRADIENT_LEAVES {
            return bad(format!(
                "{} leaves (1 to {MAX_GRADIENT_LEAVES} allowed)",
                leaves.len()
            ));
        }
        for (i, w) in leaves.windows(2).enumerate() {
            if w[1].0 <= w[0].0 {
                return bad(format!(
                    "leaf {}: node {} does not follow node {}",
                    i + 1,
                    w[1].0,
                    w[0].0
                ));
            }
        }
        if let Some((i, &(_, p))) = leaves
            .iter()
            .enumerate()
            .find(|(_, l)| l.1 as usize >= paints.len())
        {
            return bad(format!("leaf {i}: paint {p} of {} paints", paints.len()));
        }
        Ok(GradientLeaves {
            depth,
            tolerance,
            paints,
            at: LeafNodes::new(leaves.iter().map(|l| l.0).collect()),
            paint_of: leaves.iter().map(|l| l.1).collect(),
        })
    }

    /// Deepest level the tree answers at (cells go no deeper).
    pub fn depth(&self) -> u8 {
        self.depth
    }

    /// Largest sRGB-encoded colour range of a terminal cell.
    pub fn tolerance(&self) -> f64 {
        self.tolerance
    }

    /// The distinct paints.
    pub fn paints(&self) -> &[LeafPaint] {
        &self.paints
    }

    /// Number of leaves.
    pub fn count(&self) -> usize {
        self.at.len()
    }

    /// `(node, paint)` of every leaf, in node order.
    pub fn leaves(&self) -> impl ExactSizeIterator<Item = (u32, u32)> + '_ {
        self.at
            .nodes()
            .iter()
            .copied()
            .zip(self.paint_of.iter().copied())
    }

    /// Bytes held.
    pub fn memory_bytes(&self) -> u64 {
        let paints: usize = self
            .paints
            .iter()
            .map(|p| std::mem::size_of::<LeafPaint>() + std::mem::size_of_val(p.gradient.stops()))
            .sum();
        paints as u64 + self.at.memory_bytes()
    }

    /// The nodes the leaves end and their squares.
    pub(crate) fn at(&self) -> &LeafNodes {
        &self.at
    }

    pub(crate) fn at_mut(&mut self) -> &mut LeafNodes {
        &mut self.at
    }

    pub(crate) fn paint(&self, leaf: usize) -> &LeafPaint {
        &self.paints[self.paint_of[leaf] as usize]
    }

    /// `(level, ix, iz)` of leaf `leaf`'s square.
    pub(crate) fn square(&self, leaf: usize) -> (u8, u32, u32) {
        self.at.square(leaf)
    }

    /// The square of cell `(j, ix, iz)` of leaf `leaf` (`j` levels below
    /// it): `(level, corners)`, tree space.
    pub(crate) fn cell(&self, leaf: usize, j: u8, ix: u32, iz: u32) -> (u8, [Point; 4]) {
        let (level, lx, lz) = self.at.square(leaf);
        let level = level + j;
        let (cx, cz) = (
            (u64::from(lx) << j) + u64::from(ix),
            (u64::from(lz) << j) + u64::from(iz),
        );
        (level, square_corners(level, cx, cz))
    }

    /// Whether cell `(j, ix, iz)` of `leaf` is subdivided further, its
    /// exact mean colour, and the widest channel of its linear colour
    /// range (what its colour may differ from the mean by).
    pub(crate) fn cell_info(&self, leaf: usize, j: u8, ix: u32, iz: u32) -> (bool, [f64; 4], f64) {
        let (level, poly) = self.cell(leaf, j, ix, iz);
        let (splits, contrast) = self.split_and_contrast(leaf, j, level, &poly);
        (splits, self.paint(leaf).mean_over(&poly), contrast)
    }

    /// Whether a cell `j` levels below leaf `leaf`, at `level`, with
    /// corners `poly`, has children.
    pub(crate) fn splits(&self, leaf: usize, j: u8, level: u8, poly: &[Point; 4]) -> bool {
        self.split_and_contrast(leaf, j, level, poly).0
    }

    /// [`GradientLeaves::splits`], and the widest channel of the cell's
    /// linear colour range.
    pub(crate) fn split_and_contrast(
        &self,
        leaf: usize,
        j: u8,
        level: u8,
        poly: &[Point; 4],
    ) -> (bool, f64) {
        let range = self.paint(leaf).range_over(poly);
        let splits =
            j < MAX_CELL_LEVELS && level < self.depth && encoded_width(&range) > self.tolerance;
        (splits, linear_width(&range))
    }
}

/// Corners (counter-clockwise) of square `(level, ix, iz)` of tree space.
pub(crate) fn square_corners(level: u8, ix: u64, iz: u64) -> [Point; 4] {
    let side = crate::geometry::unit_side(level);
    let (x0, z0) = (ix as f64 * side, iz as f64 * side);
    let (x1, z1) = (x0 + side, z0 + side);
    [[x0, z0], [x1, z0], [x1, z1], [x0, z1]]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vector::gradient::{Interpolation, Spread, Stop};

    fn ramp() -> Gradient {
        let stops = vec![
            Stop {
                offset: 0.0,
                colour: [0.0, 0.2, 1.0],
                opacity: 1.0,
            },
            Stop {
                offset: 1.0,
                colour: [1.0, 0.8, 0.0],
                opacity: 0.5,
            },
        ];
        Gradient::linear_from_parameter(
            [3.0, 1.0, -0.5],
            stops,
            Spread::Reflect,
            Interpolation::Srgb,
        )
        .unwrap()
    }

    /// Half-transparent grey over the gradient over opaque white, as the
    /// packer's affine form gives it.
    fn paint() -> LeafPaint {
        let (o, grey) = (0.5, 0.2);
        // out = grey·o + (1 − o)·(g + (1 − g_a)·white)
        let mut m = [[0.0; 4]; 4];
        for (c, row) in m.iter_mut().enumerate() {
            row[c] = 1.0 - o;
            row[3] -= 1.0 - o;
        }
        let offset = [
            grey * o + (1.0 - o),
            grey * o + (1.0 - o),
            grey * o + (1.0 - o),
            1.0,
        ];
        m[3][3] = 0.0;
        LeafPaint::new(ramp(), offset, m).unwrap()
    }

    #[test]
    fn mean_is_the_affine_image_of_the_gradient_mean_and_matches_sampling() {
        let p = paint();
        let rect = [[0.1, 0.2], [0.7, 0.2], [0.7, 0.45], [0.1, 0.45]];
        let mean = p.mean_over(&rect);
        let n = 800;
        let mut sum = [0.0; 4];
        for i in 0..n {
            for j in 0..n {
                let x = 0.1 + 0.6 * (i as f64 + 0.5) / n as f64;
                let z = 0.2 + 0.25 * (j as f64 + 0.5) / n as f64;
                let c = p.colour_at([x, z]);
                for k in 0..4 {
                    sum[k] += c[k] / (n * n) as f64;
                }
            }
        }
        for k in 0..4 {
            assert!((mean[k] - sum[k]).abs() < 1e-5, "{mean:?} {sum:?}");
        }
        assert_eq!(mean[3], 1.0);
    }

    #[test]
    fn range_holds_every_sample() {
        let p = paint();
        let rect = [[0.3, 0.3], [0.4, 0.3], [0.4, 0.4], [0.3, 0.4]];
        let r = p.range_over(&rect);
        for i in 0..=20 {
            for j in 0..=20 {
                let c = p.colour_at([0.3 + 0.005 * i as f64, 0.3 + 0.005 * j as f64]);
                for k in 0..4 {
                    assert!(c[k] >= r[k][0] - 1e-12 && c[k] <= r[k][1] + 1e-12);
                }
            }
        }
        assert!(p.encoded_width(&rect) > 0.0);
    }

    #[test]
    fn lies_are_refused() {
        assert!(LeafPaint::new(ramp(), [f64::NAN, 0.0, 0.0, 0.0], [[0.0; 4]; 4]).is_err());
        assert!(LeafPaint::new(ramp(), [0.0; 4], [[9.0; 4]; 4]).is_err());
        let ok = || vec![paint()];
        assert!(GradientLeaves::new(12, 0.001, ok(), &[(3, 0), (3, 0)]).is_err());
        assert!(GradientLeaves::new(12, 0.001, ok(), &[(3, 1)]).is_err());
        assert!(GradientLeaves::new(12, f64::NAN, ok(), &[(3, 0)]).is_err());
        assert!(GradientLeaves::new(31, 0.001, ok(), &[(3, 0)]).is_err());
        assert!(GradientLeaves::new(12, 0.001, ok(), &[]).is_err());
        assert!(GradientLeaves::new(12, 0.001, ok(), &[(3, 0), (9, 0)]).is_ok());
    }
}

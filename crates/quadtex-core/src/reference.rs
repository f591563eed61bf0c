//! Slow, obvious references for the fragment integral, kept public so tests,
//! fuzz targets and benchmarks can check the fast path against them.

use crate::colour::WeightedColour;
use crate::geometry::fragment::Fragment;
use crate::raster::TexelGrid;
use crate::tree::variant::{self, Variant, f_high, f_low};
use crate::tree::{NodeRef, QuadTree, unit_side};

/// Σ over texels of colour × area(texel ∩ fragment), texels as rectangles of
/// the unit square (crate conventions). Visits only the texels the fragment
/// touches: the brute-force baseline, O(covered texels).
pub fn texel_sum(grid: &TexelGrid, fragment: &Fragment) -> WeightedColour {
    let Some(f) = fragment.clip_to_unit() else {
        return WeightedColour::ZERO;
    };
    let (w, h) = (f64::from(grid.width()), f64::from(grid.height()));
    let cols = (f.x0() * w).floor() as u32..((f.x1() * w).ceil() as u32).min(grid.width());
    // Rows count from the top: z in [1-(row+1)/h, 1-row/h).
    let rows = ((1.0 - f.z1()) * h).floor() as u32
        ..(((1.0 - f.z0()) * h).ceil() as u32).min(grid.height());
    let mut acc = [0f64; 4];
    for row in rows {
        let z_lo = 1.0 - f64::from(row + 1) / h;
        let z_hi = 1.0 - f64::from(row) / h;
        let dz = overlap(f.z0(), f.z1(), z_lo, z_hi);
        for col in cols.clone() {
            let dx = overlap(f.x0(), f.x1(), f64::from(col) / w, f64::from(col + 1) / w);
            let t = grid.texel(col, row);
            for (a, &c) in acc.iter_mut().zip(&t.0) {
                *a += dx * dz * f64::from(c);
            }
        }
    }
    WeightedColour(acc.map(|a| a / 65535.0))
}

/// Σ over the squares of the tree truncated at `max_level` (terminal nodes
/// above it, all nodes at it) of colour × area(square ∩ fragment). O(nodes).
/// Squares are taken in texture space: a non-square texture's squares are
/// rectangles there, and those straddling the pad keep their texture part
/// ([`crate::Aspect`]).
pub fn truncated_tree_sum(tree: &QuadTree, fragment: &Fragment, max_level: u8) -> WeightedColour {
    let mut acc = WeightedColour::ZERO;
    let [ex, ez] = tree.aspect().scale();
    tree.for_each_leaf(max_level, |level, ix, iz, colour| {
        let side = unit_side(level);
        let (x0, z0) = (f64::from(ix) * side, f64::from(iz) * side);
        let (x1, z1) = ((x0 + side).min(ex) / ex, (z0 + side).min(ez) / ez);
        let area = overlap(fragment.x0(), fragment.x1(), x0 / ex, x1)
            * overlap(fragment.z0(), fragment.z1(), z0 / ez, z1);
        if area > 0.0 {
            acc += weigh_f(colour, area);
        }
    });
    acc
}

/// The paper's recursive traversal, literally: variants from `init` against
/// the unit square (pass [`variant::f_init`]; tests pass the misprinted one),
/// transitions by eq. 7–8, the four checks in the paper's order, no
/// clipping and no shortcuts.
pub fn paper_traversal(
    tree: &QuadTree,
    fragment: &Fragment,
    max_level: u8,
    init: fn(f64, f64) -> Variant,
) -> WeightedColour {
    let aspect = tree.aspect();
    if !aspect.is_square() {
        // In tree space, where the squares are; areas back in texture units.
        let Some(f) = aspect.tree_fragment(fragment) else {
            return WeightedColour::ZERO;
        };
        return paper_in_tree_space(tree, &f, max_level, init) * aspect.area_ratio();
    }
    paper_in_tree_space(tree, fragment, max_level, init)
}

fn paper_in_tree_space(
    tree: &QuadTree,
    fragment: &Fragment,
    max_level: u8,
    init: fn(f64, f64) -> Variant,
) -> WeightedColour {
    let k = max_level.min(tree.depth());
    let (a_x, b_x, a_z, b_z) = (fragment.x0(), fragment.x1(), fragment.z0(), fragment.z1());
    let (vx, vz) = (init(a_x, b_x), init(a_z, b_z));
    let (inner, colour) = tree.node_info(QuadTree::ROOT);
    if variant::is_disjoint(vx) || variant::is_disjoint(vz) {
        return WeightedColour::ZERO;
    }
    if k == 0 || !inner {
        return weigh_f(colour, fragment.overlap_area(0.0, 0.0, 1.0));
    }
    let mut traversal = PaperTraversal {
        tree,
        fragment,
        max_level: k,
        acc: WeightedColour::ZERO,
    };
    traversal.step(QuadTree::ROOT, 0, 0.0, 0.0, vx, vz);
    traversal.acc
}

/// What stays the same down the seed paper's traversal: the tree, the
/// fragment (tree space), the level it stops at; and the sum so far.
struct PaperTraversal<'a> {
    tree: &'a QuadTree,
    fragment: &'a Fragment,
    max_level: u8,
    acc: WeightedColour,
}

impl PaperTraversal<'_> {
    /// The children of `node` (at `level`, lower-left corner `lo_x, lo_z`,
    /// the fragment's variants `vx, vz` against it), added to the sum.
    fn step(&mut self, node: NodeRef, level: u8, lo_x: f64, lo_z: f64, vx: Variant, vz: Variant) {
        let (tree, f, k) = (self.tree, self.fragment, self.max_level);
        let child_level = level + 1;
        let half = unit_side(child_level);
        let (mx, mz) = (lo_x + half, lo_z + half);
        for c in 0..4 {
            let (hx, hz) = (c & 1 == 1, c & 2 == 2);
            let cvx = if hx {
                f_high(f.x0(), f.x1(), mx, vx)
            } else {
                f_low(f.x0(), f.x1(), mx, vx)
            };
            let cvz = if hz {
                f_high(f.z0(), f.z1(), mz, vz)
            } else {
                f_low(f.z0(), f.z1(), mz, vz)
            };
            let (clo_x, clo_z) = (if hx { mx } else { lo_x }, if hz { mz } else { lo_z });
            let child = tree.child_ref(node, c);
            let (inner, colour) = tree.node_info(child);
            if cvx == variant::SQUARE_INSIDE && cvz == variant::SQUARE_INSIDE {
                self.acc += weigh_f(colour, half * half);
            } else if variant::is_disjoint(cvx) || variant::is_disjoint(cvz) {
                continue;
            } else if !inner || child_level == k {
                self.acc += weigh_f(colour, f.overlap_area(clo_x, clo_z, half));
            } else {
                self.step(child, child_level, clo_x, clo_z, cvx, cvz);
            }
        }
    }
}

fn overlap(a: f64, b: f64, lo: f64, hi: f64) -> f64 {
    (b.min(hi) - a.max(lo)).max(0.0)
}

fn weigh_f(c: [f64; 4], area: f64) -> WeightedColour {
    WeightedColour(c.map(|v| v * area))
}

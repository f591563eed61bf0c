//! The fragment integral: the weighted colour of a rectangle, squares
//! inside it counted whole and the rest by overlap.

use super::navigate::StoredSquare;
use super::{MAX_DEPTH, QuadTree, TraversalStats};
use crate::colour::{ColourEncoding, Unorm16Rgba, WeightedColour};
use crate::geometry::fragment::{Fragment, overlap_1d};
use crate::geometry::unit_side;
use crate::tree::variant::{self, Variant};

impl QuadTree {
    /// Adds to `acc` (unorm16 units × area) the integral over the fragment
    /// `[x0,x1) × [z0,z1)` (tree space) of a texel block, its texels
    /// grouped into cells at level `k` (`>` the block's level) or finer.
    #[inline(never)]
    fn add_block(
        &self,
        acc: &mut [f64; 4],
        BlockSquare { b, level, lo, side }: BlockSquare,
        k: u8,
        [x0, z0, x1, z1]: [f64; 4],
    ) {
        let Some(tb) = &self.texel_blocks else {
            return;
        };
        let j = (k - level).min(tb.log2_side());
        let n = 1u32 << j;
        let cell = side / f64::from(n);
        let range = |a: f64, b: f64, lo: f64| {
            let first = (((a - lo) / cell).floor().max(0.0) as u32).min(n - 1);
            let last = ((((b - lo) / cell).ceil().max(1.0) as u32) - 1).clamp(first, n - 1);
            first..=last
        };
        if j == tb.log2_side() {
            // Texel by texel: separable weights, the overlap of each column
            // and each row (in cell areas, so each texel counts its value).
            let (xs, zs) = (range(x0, x1, lo[0]), range(z0, z1, lo[1]));
            let weights = |a: f64, b: f64, lo: f64, r: &std::ops::RangeInclusive<u32>| {
                let mut w = [0f64; 16];
                for i in r.clone() {
                    let c0 = lo + f64::from(i) * cell;
                    w[i as usize] = overlap_1d(a, b, c0, c0 + cell);
                }
                w
            };
            let (wx, wz) = (weights(x0, x1, lo[0], &xs), weights(z0, z1, lo[1], &zs));
            tb.add_weighted(acc, b, (&wx, xs), (&wz, zs));
            return;
        }
        for cz in range(z0, z1, lo[1]) {
            let (c0, c1) = (
                lo[1] + f64::from(cz) * cell,
                lo[1] + f64::from(cz + 1) * cell,
            );
            let dz = overlap_1d(z0, z1, c0, c1);
            if dz <= 0.0 {
                continue;
            }
            for cx in range(x0, x1, lo[0]) {
                let (c0, c1) = (
                    lo[0] + f64::from(cx) * cell,
                    lo[0] + f64::from(cx + 1) * cell,
                );
                let area = overlap_1d(x0, x1, c0, c1) * dz;
                if area <= 0.0 {
                    continue;
                }
                let (sum, count) = tb.cell_sum(b, j, cx, cz);
                let w = area / f64::from(count);
                for (a, s) in acc.iter_mut().zip(sum) {
                    *a += w * s as f64;
                }
            }
        }
    }

    /// The exact integral (unorm16 units × area) of the gradient or
    /// contour leaf at padded index `p`, if it is one above level `k`, over
    /// the rectangle `[x0, x1) × [z0, z1)` of tree space inside its square.
    #[inline(never)]
    fn leaf_integral(&self, p: usize, k: u8, [x0, z0, x1, z1]: [f64; 4]) -> Option<[f64; 4]> {
        let area = (x1 - x0).max(0.0) * (z1 - z0).max(0.0);
        if let Some((leaf, g)) = self.gradient_leaf(p) {
            if g.square(leaf).0 >= k {
                return None;
            }
            if area <= 0.0 {
                return Some([0.0; 4]);
            }
            let mean = g
                .paint(leaf)
                .mean_over(&[[x0, z0], [x1, z0], [x1, z1], [x0, z1]]);
            return Some(mean.map(|m| m * 65535.0 * area));
        }
        let (leaf, c) = self.contour_leaf(p)?;
        if c.square(leaf).0 >= k {
            return None;
        }
        if area <= 0.0 {
            return Some([0.0; 4]);
        }
        Some(c.integral(leaf, [x0, z0, x1, z1]).0.map(|v| v * 65535.0))
    }

    /// The weighted colour (integral of colour over area) of the fragment's
    /// overlap with the unit square, from a traversal down to level
    /// `max_level` (clamped to [`QuadTree::depth`]). The fragment and the
    /// area are in texture units; levels are the tree's ([`Aspect`]).
    ///
    /// Squares inside the fragment count whole at the highest level they
    /// exist, squares at `max_level` or terminal count by their overlap, as in
    /// the paper. Against the exact integral of the tree truncated at
    /// `max_level` the result is off by float rounding plus at most half a
    /// storage step per channel times the area taken from inner nodes
    /// (`≤ 0.5/65535 × area`): an inner colour is the exact mean of its
    /// region rounded once to 16 bits.
    pub fn weighted_colour(&self, fragment: &Fragment, max_level: u8) -> WeightedColour {
        self.weighted_colour_counted(fragment, max_level, &mut TraversalStats::default())
    }

    /// As [`QuadTree::weighted_colour`], adding the query's cost to `stats`.
    pub fn weighted_colour_counted(
        &self,
        fragment: &Fragment,
        max_level: u8,
        stats: &mut TraversalStats,
    ) -> WeightedColour {
        match self.encoding {
            ColourEncoding::Half => self.integrate::<true>(fragment, max_level, stats),
            _ => self.integrate::<false>(fragment, max_level, stats),
        }
    }

    /// The traversal; colours in unorm16 units (half floats scaled by 65535).
    #[inline]
    fn integrate<const HALF: bool>(
        &self,
        fragment: &Fragment,
        max_level: u8,
        stats: &mut TraversalStats,
    ) -> WeightedColour {
        {
            stats.queries += 1;
        }
        let Some(f) = self.aspect.tree_fragment(fragment) else {
            return WeightedColour::ZERO;
        };
        let ratio = self.aspect.area_ratio();
        let result = |acc: [f64; 4]| scaled(acc.map(|a| a * ratio));
        let k = max_level.min(self.depth);
        let (x0, z0, x1, z1) = (f.x0(), f.z0(), f.x1(), f.z1());

        // Start at the smallest square of level <= min(k, top_level) enclosing the fragment.
        let StoredSquare {
            p: start,
            level,
            ix: sx,
            iz: sz,
        } = self.top_square((x0, x1), (z0, z1), k);

        {
            stats.nodes_visited += 1;
        }
        if level < k
            && let Some(b) = self.block_at(start)
        {
            let side = unit_side(level);
            let lo = [f64::from(sx) * side, f64::from(sz) * side];
            let mut acc = [0f64; 4];
            let block = BlockSquare { b, level, lo, side };
            self.add_block(&mut acc, block, k, [x0, z0, x1, z1]);
            return result(acc);
        }
        if !self.is_inner(start)
            && let Some(w) = self.leaf_integral(start, k, [x0, z0, x1, z1])
        {
            return result(w);
        }
        if level >= k || !self.is_inner(start) {
            return result(weigh::<HALF>(self.colour(start), f.area()));
        }
        let side = unit_side(level);
        let (lo_x, lo_z) = (f64::from(sx) * side, f64::from(sz) * side);
        let vx = variant::classify(x0, x1, lo_x, lo_x + side);
        let vz = variant::classify(z0, z1, lo_z, lo_z + side);
        if vx == variant::SQUARE_INSIDE && vz == variant::SQUARE_INSIDE {
            return result(weigh::<HALF>(self.colour(start), side * side));
        }

        let mut acc = [0f64; 4];
        let start = Pending {
            node: start as u32,
            level,
            vx,
            vz,
            lo_x,
            lo_z,
        };
        // The pending squares live in a buffer kept per thread: a fresh
        // array would be zeroed on every query (3 KiB), a cost measurable
        // against the whole of a small one.
        let visited = PENDING.with_borrow_mut(|stack| {
            self.integrate_below::<HALF>(stack, start, k, [x0, z0, x1, z1], &mut acc)
        });
        {
            stats.nodes_visited += visited;
        }
        result(acc)
    }

    /// Adds to `acc` the integral over the fragment `[x0,x1) × [z0,z1)`
    /// (tree space) of what lies under inner square `start`, which the
    /// fragment overlaps but does not cover, down to level `k`; returns the
    /// nodes visited. `stack` is scratch for the pending squares.
    #[inline]
    fn integrate_below<const HALF: bool>(
        &self,
        stack: &mut Vec<Pending>,
        start: Pending,
        k: u8,
        [x0, z0, x1, z1]: [f64; 4],
        acc: &mut [f64; 4],
    ) -> u64 {
        let mut visited = 0u64;
        stack.clear();
        stack.push(start);
        while let Some(Pending {
            node,
            level,
            vx,
            vz,
            lo_x,
            lo_z,
        }) = stack.pop()
        {
            let child_level = level + 1;
            let half = unit_side(child_level);
            let child_area = half * half;
            let (mx, mz) = (lo_x + half, lo_z + half);
            let vxs = [
                variant::f_low(x0, x1, mx, vx),
                variant::f_high(x0, x1, mx, vx),
            ];
            let vzs = [
                variant::f_low(z0, z1, mz, vz),
                variant::f_high(z0, z1, mz, vz),
            ];
            let first = self.first_child(node as usize);
            let block = self.blocks[first / 64].bits >> (first % 64);
            let descend_allowed = child_level < k;
            for c in 0..4 {
                let (cvx, cvz): (Variant, Variant) = (vxs[c & 1], vzs[c >> 1]);
                if variant::is_disjoint(cvx) || variant::is_disjoint(cvz) {
                    continue;
                }
                visited += 1;
                let colour = self.colour(first + c);
                let (clo_x, clo_z) = (lo_x + (c & 1) as f64 * half, lo_z + (c >> 1) as f64 * half);
                if cvx == variant::SQUARE_INSIDE && cvz == variant::SQUARE_INSIDE {
                    add::<HALF>(acc, colour, child_area);
                } else if block >> c & 1 == 0 || !descend_allowed {
                    match self.block_at(first + c).filter(|_| descend_allowed) {
                        Some(b) => {
                            let block = BlockSquare {
                                b,
                                level: child_level,
                                lo: [clo_x, clo_z],
                                side: half,
                            };
                            self.add_block(acc, block, k, [x0, z0, x1, z1])
                        }
                        None => {
                            let (ox0, ox1) = (x0.max(clo_x), x1.min(clo_x + half));
                            let (oz0, oz1) = (z0.max(clo_z), z1.min(clo_z + half));
                            let leaves =
                                self.gradient_leaves.is_some() || self.contour_leaves.is_some();
                            match leaves
                                .then(|| self.leaf_integral(first + c, k, [ox0, oz0, ox1, oz1]))
                                .flatten()
                            {
                                Some(w) => {
                                    for (a, v) in acc.iter_mut().zip(w) {
                                        *a += v;
                                    }
                                }
                                None => {
                                    let area = overlap_1d(x0, x1, clo_x, clo_x + half)
                                        * overlap_1d(z0, z1, clo_z, clo_z + half);
                                    add::<HALF>(acc, colour, area);
                                }
                            }
                        }
                    }
                } else {
                    stack.push(Pending {
                        node: (first + c) as u32,
                        level: child_level,
                        vx: cvx,
                        vz: cvz,
                        lo_x: clo_x,
                        lo_z: clo_z,
                    });
                }
            }
        }
        visited
    }
}

/// A texel block (its index `b`) and its square: level, low corner `lo`
/// and side (tree space).
#[derive(Clone, Copy)]
struct BlockSquare {
    b: usize,
    level: u8,
    lo: [f64; 2],
    side: f64,
}

thread_local! {
    /// The traversal's pending squares: depth first, each level leaves at
    /// most three siblings pending, so at most `3 · depth + 1`.
    static PENDING: std::cell::RefCell<Vec<Pending>> =
        std::cell::RefCell::new(Vec::with_capacity(4 * MAX_DEPTH as usize + 8));
}

#[derive(Debug, Clone, Copy, Default)]
struct Pending {
    node: u32,
    level: u8,
    vx: Variant,
    vz: Variant,
    lo_x: f64,
    lo_z: f64,
}

/// A stored channel in unorm16 units: the integer, or a half float × 65535.
#[inline(always)]
fn units<const HALF: bool>(c: u16) -> f64 {
    if HALF {
        f64::from(half::f16::from_bits(c).to_f32()) * 65535.0
    } else {
        f64::from(c)
    }
}

#[inline]
fn add<const HALF: bool>(acc: &mut [f64; 4], colour: Unorm16Rgba, area: f64) {
    for (a, &c) in acc.iter_mut().zip(&colour.0) {
        *a += area * units::<HALF>(c);
    }
}

#[inline]
fn weigh<const HALF: bool>(colour: Unorm16Rgba, area: f64) -> [f64; 4] {
    colour.0.map(|c| area * units::<HALF>(c))
}

#[inline]
fn scaled(acc: [f64; 4]) -> WeightedColour {
    WeightedColour(acc.map(|a| a * (1.0 / 65535.0)))
}

//! A bounding-volume hierarchy over a mesh's triangles: binned surface-area
//! heuristic (16 bins on the centroids' longest axis), leaves of at most
//! [`LEAF_SIZE`] triangles, at most [`MAX_DEPTH`] levels (deeper ranges
//! become leaves, so traversal needs a fixed stack). Built once per mesh
//! in O(n log n); a ray visits the nodes whose boxes it crosses, nearest
//! child first, and stops descending past its best hit.

use crate::math::{Ray, Vec3};

/// Most triangles in a leaf.
pub const LEAF_SIZE: usize = 4;

/// Deepest level (ranges still larger there become one leaf).
pub const MAX_DEPTH: usize = 64;

const BINS: usize = 16;

/// An axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Aabb {
    pub lo: Vec3,
    pub hi: Vec3,
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        lo: Vec3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
        hi: Vec3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
    };

    /// Grows the box to hold `p`. A NaN coordinate is ignored, as
    /// `f64::min` would, by one comparison a bound (`f64::min` also orders
    /// the zeros, which no box test distinguishes): the build grows a box
    /// a few times a primitive on every level.
    #[inline]
    fn grow(&mut self, p: Vec3) {
        let lower = |a: f64, b: f64| if b < a { b } else { a };
        let higher = |a: f64, b: f64| if b > a { b } else { a };
        self.lo = Vec3::new(
            lower(self.lo.x, p.x),
            lower(self.lo.y, p.y),
            lower(self.lo.z, p.z),
        );
        self.hi = Vec3::new(
            higher(self.hi.x, p.x),
            higher(self.hi.y, p.y),
            higher(self.hi.z, p.z),
        );
    }

    fn union(&mut self, o: &Aabb) {
        if o.lo.x > o.hi.x {
            return; // empty
        }
        self.grow(o.lo);
        self.grow(o.hi);
    }

    fn area(&self) -> f64 {
        let d = self.hi - self.lo;
        if d.x < 0.0 {
            return 0.0;
        }
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }

    /// The entry distance of a ray (`origin`, `1/direction`) within
    /// `(0, t_max)`, if it crosses the box. A direction component of 0
    /// gives ±∞ (or NaN at a slab's plane, which keeps the interval).
    #[inline]
    fn entry(&self, origin: Vec3, inv: Vec3, t_max: f64) -> Option<f64> {
        let (mut t0, mut t1) = (0.0f64, t_max);
        for (o, i, lo, hi) in [
            (origin.x, inv.x, self.lo.x, self.hi.x),
            (origin.y, inv.y, self.lo.y, self.hi.y),
            (origin.z, inv.z, self.lo.z, self.hi.z),
        ] {
            // Ordered by the direction's sign, not by comparing: a ray in a
            // slab's plane gives NaN there, which must not be swapped onto
            // the other side (it then leaves t0 or t1 as it was).
            let (a, b) = if i >= 0.0 {
                ((lo - o) * i, (hi - o) * i)
            } else {
                ((hi - o) * i, (lo - o) * i)
            };
            t0 = if a > t0 { a } else { t0 };
            t1 = if b < t1 { b } else { t1 };
        }
        // A relative slack so a ray grazing a flat box (a planar mesh) still enters.
        (t0 <= t1 * (1.0 + 1e-12) + 1e-9).then_some(t0)
    }

    /// Whether a box the ray entered at `t_enter` (from [`Aabb::entry`])
    /// would still pass [`Aabb::entry`] with its `t_max` lowered to `t_max`:
    /// the same comparison, its exit side unchanged.
    #[inline]
    fn still_entered(t_enter: f64, t_max: f64) -> bool {
        t_enter <= t_max * (1.0 + 1e-12) + 1e-9
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Node {
    bounds: Aabb,
    /// Leaf: first index into `order`; inner: index of the left child (the
    /// right one follows it).
    start: u32,
    /// Triangles in a leaf; 0 for an inner node.
    count: u32,
}

/// The hierarchy: nodes, and the triangle indices its leaves refer to.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Bvh {
    nodes: Vec<Node>,
    order: Vec<u32>,
}

impl Bvh {
    /// Builds over `n` primitives whose bounds are `bounds(i)`.
    pub fn build(n: usize, bounds: impl Fn(usize) -> Aabb + Sync) -> Bvh {
        let boxes: Vec<Aabb> = (0..n).map(&bounds).collect();
        let centres: Vec<Vec3> = boxes.iter().map(|b| (b.lo + b.hi) * 0.5).collect();
        let mut order: Vec<u32> = (0..n as u32).collect();
        let span = Span::of(&boxes, &centres, &order);
        let prims = Primitives {
            boxes: &boxes,
            centres: &centres,
        };
        let nodes = subtree(&prims, &mut order, span, 0, 0);
        Bvh { nodes, order }
    }

    /// [`Bvh::nearest_below`] with no bound: the nearest hit.
    #[cfg(test)]
    pub fn nearest(
        &self,
        ray: &Ray,
        test: impl FnMut(u32, f64) -> Option<f64>,
    ) -> Option<(u32, f64)> {
        self.nearest_below(ray, f64::INFINITY, test)
    }

    /// Calls `test(i, t_best)` for every primitive whose leaf box `ray`
    /// crosses before its best hit so far (at first `t_bound`); `test`
    /// returns the distance of a hit nearer than `t_best`, if any. Returns
    /// the nearest hit nearer than `t_bound`: whenever the nearest of all
    /// is nearer than that, the same answer as with no bound (a box
    /// entered beyond it holds no nearer hit, and the boxes that are
    /// visited are visited in the same order), with fewer boxes visited.
    pub fn nearest_below(
        &self,
        ray: &Ray,
        t_bound: f64,
        mut test: impl FnMut(u32, f64) -> Option<f64>,
    ) -> Option<(u32, f64)> {
        let d = ray.direction;
        let inv = Vec3::new(1.0 / d.x, 1.0 / d.y, 1.0 / d.z);
        let mut best: Option<(u32, f64)> = None;
        let mut t_best = t_bound;
        // Each node waits with the distance at which the ray enters its box:
        // once a hit is nearer, the box would fail `entry` again (its exit
        // has not moved, only `t_max`), without the test being redone.
        let root = self.nodes[0].bounds.entry(ray.origin, inv, t_best)?;
        let mut stack = [(0u32, 0.0f64); MAX_DEPTH + 2];
        stack[0] = (0, root);
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (index, t_enter) = stack[top];
            if !Aabb::still_entered(t_enter, t_best) {
                continue;
            }
            let node = &self.nodes[index as usize];
            if node.count > 0 {
                let s = node.start as usize;
                for &i in &self.order[s..s + node.count as usize] {
                    if let Some(t) = test(i, t_best)
                        && t < t_best
                    {
                        t_best = t;
                        best = Some((i, t));
                    }
                }
                continue;
            }
            let (l, r) = (node.start as usize, node.start as usize + 1);
            let tl = self.nodes[l].bounds.entry(ray.origin, inv, t_best);
            let tr = self.nodes[r].bounds.entry(ray.origin, inv, t_best);
            // Push the farther first so the nearer is visited first.
            match (tl, tr) {
                (Some(a), Some(b)) => {
                    let (near, far) = if a <= b {
                        ((l, a), (r, b))
                    } else {
                        ((r, b), (l, a))
                    };
                    stack[top] = (far.0 as u32, far.1);
                    stack[top + 1] = (near.0 as u32, near.1);
                    top += 2;
                }
                (Some(a), None) => {
                    stack[top] = (l as u32, a);
                    top += 1;
                }
                (None, Some(b)) => {
                    stack[top] = (r as u32, b);
                    top += 1;
                }
                (None, None) => {}
            }
        }
        best
    }

    /// Whether `test` holds for a primitive whose box the ray enters: any
    /// one, in no particular order, stopping at the first (a shadow ray
    /// needs to know that something is in the way, not what is nearest).
    pub fn any(&self, ray: &Ray, test: impl FnMut(u32) -> bool) -> bool {
        let d = ray.direction;
        let inv = Vec3::new(1.0 / d.x, 1.0 / d.y, 1.0 / d.z);
        self.first_in(|b| b.entry(ray.origin, inv, f64::INFINITY).is_some(), test)
    }

    /// Calls `visit(i)` for every primitive in a leaf whose box is not
    /// wholly outside one of `planes` (`n·p + d ≥ 0` inside, `[n.x, n.y,
    /// n.z, d]`) and passes `may_meet(lo, hi)` (the box's corners; a test
    /// the caller knows is conservative), until `visit` returns true;
    /// returns whether it did. The plane test is conservative too: a box
    /// that reaches into every half-space may still miss their
    /// intersection.
    pub fn overlapping(
        &self,
        planes: &[[f64; 4]],
        may_meet: impl Fn(Vec3, Vec3) -> bool,
        visit: impl FnMut(u32) -> bool,
    ) -> bool {
        let outside = |b: &Aabb| {
            planes.iter().any(|&[x, y, z, d]| {
                // The corner farthest along the normal.
                let far = |n: f64, lo: f64, hi: f64| n * if n > 0.0 { hi } else { lo };
                far(x, b.lo.x, b.hi.x) + far(y, b.lo.y, b.hi.y) + far(z, b.lo.z, b.hi.z) + d < 0.0
            })
        };
        self.first_in(|b| !outside(b) && may_meet(b.lo, b.hi), visit)
    }

    /// Whether `test` holds for a primitive in a leaf reached through boxes
    /// that all pass `enters`, stopping at the first (depth first, no
    /// particular order).
    #[inline]
    fn first_in(&self, enters: impl Fn(&Aabb) -> bool, mut test: impl FnMut(u32) -> bool) -> bool {
        if !enters(&self.nodes[0].bounds) {
            return false;
        }
        let mut stack = [0u32; MAX_DEPTH + 2];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if node.count > 0 {
                let s = node.start as usize;
                if self.order[s..s + node.count as usize]
                    .iter()
                    .any(|&i| test(i))
                {
                    return true;
                }
                continue;
            }
            for child in [node.start as usize, node.start as usize + 1] {
                if enters(&self.nodes[child].bounds) {
                    stack[top] = child as u32;
                    top += 1;
                }
            }
        }
        false
    }

    /// The positions in the leaves' order of every primitive in a leaf
    /// reached through boxes that all pass `enters`, as increasing,
    /// disjoint ranges (adjacent leaves' merged). Once the items are
    /// reordered to the leaves ([`Bvh::reorder_to_leaves`]), a position is
    /// the item's own index. (The walk is [`Bvh::first_in`]'s, children
    /// the other way round; one walker for both, with the order as a flag,
    /// cost the terrain's frame 0.4 % more instructions.)
    pub fn leaf_ranges(&self, enters: impl Fn(&Aabb) -> bool) -> Vec<std::ops::Range<usize>> {
        let mut ranges: Vec<std::ops::Range<usize>> = Vec::new();
        if !self.nodes.first().is_some_and(|root| enters(&root.bounds)) {
            return ranges;
        }
        let mut stack = [0u32; MAX_DEPTH + 2];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if node.count > 0 {
                let (start, end) = (node.start as usize, (node.start + node.count) as usize);
                match ranges.last_mut() {
                    Some(last) if last.end == start => last.end = end,
                    _ => ranges.push(start..end),
                }
                continue;
            }
            // The right child first on the stack: the left one's leaves,
            // the lower positions, come out first.
            for child in [node.start as usize + 1, node.start as usize] {
                if enters(&self.nodes[child].bounds) {
                    stack[top] = child as u32;
                    top += 1;
                }
            }
        }
        ranges
    }

    /// The box around every item, `None` for an empty hierarchy.
    pub fn bounds(&self) -> Option<Aabb> {
        self.nodes.first().map(|n| n.bounds)
    }

    /// Nodes in the hierarchy.
    #[cfg(test)]
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Each primitive's place in the order [`Bvh::overlapping`] visits
    /// primitives when every box passes (`rank[i]` for primitive `i`):
    /// the order it visits any set it reaches, as pruning a depth-first
    /// walk leaves the rest of it in order.
    pub fn visit_ranks(&self) -> Vec<u32> {
        let mut rank = vec![0u32; self.order.len()];
        let mut next = 0u32;
        self.first_in(
            |_| true,
            |i| {
                rank[i as usize] = next;
                next += 1;
                false
            },
        );
        rank
    }

    /// Moves `items` (one per primitive) into the order the leaves visit
    /// them, and the leaves to refer to them there: a leaf's primitives
    /// become adjacent in memory, not scattered over the whole array.
    /// Returns the permutation applied (`new[k] = old[result[k]]`).
    pub fn reorder_to_leaves<T>(&mut self, items: &mut [T]) -> Vec<u32> {
        let order = std::mem::replace(&mut self.order, (0..items.len() as u32).collect());
        // In place, cycle by cycle: `new[k] = old[order[k]]`.
        let mut done = vec![false; items.len()];
        for start in 0..items.len() {
            let mut k = start;
            while !done[k] {
                done[k] = true;
                let next = order[k] as usize;
                if next == start {
                    break;
                }
                items.swap(k, next);
                k = next;
            }
        }
        order
    }

    /// Bytes the hierarchy holds.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node>() + self.order.len() * 4
    }
}

/// Ranges at least this large are split on two threads at the top of the
/// hierarchy (below, one thread builds the rest of each half).
const PARALLEL_RANGE: usize = 1 << 15;

/// What a range of primitives spans: the union of their boxes, and the
/// box of their centroids (the binning's extent). Both are exact minima
/// and maxima, so a child's comes from its bins as well as from its
/// primitives.
#[derive(Debug, Clone, Copy)]
struct Span {
    boxes: Aabb,
    centres: Aabb,
}

impl Span {
    const EMPTY: Span = Span {
        boxes: Aabb::EMPTY,
        centres: Aabb::EMPTY,
    };

    /// The span of the primitives `order` lists (the root's).
    fn of(boxes: &[Aabb], centres: &[Vec3], order: &[u32]) -> Span {
        let mut span = Span::EMPTY;
        for &i in order {
            span.boxes.union(&boxes[i as usize]);
            span.centres.grow(centres[i as usize]);
        }
        span
    }

    fn union(&mut self, o: &Span) {
        self.boxes.union(&o.boxes);
        self.centres.union(&o.centres);
    }
}

/// The primitives' boxes and centroids, as the build reads them.
struct Primitives<'a> {
    boxes: &'a [Aabb],
    centres: &'a [Vec3],
}

/// The hierarchy over `order` (the indices of the primitives, partitioned
/// in place; `span` is theirs), its leaves pointing at `base + position in
/// order`; node 0 is the root, a node's children are adjacent.
fn subtree(
    prims: &Primitives<'_>,
    order: &mut [u32],
    span: Span,
    base: usize,
    depth: usize,
) -> Vec<Node> {
    if order.len() >= PARALLEL_RANGE && depth < 4 {
        if let Some((mid, [ls, rs])) = partition(prims, order, &span, depth) {
            let (left, right) = order.split_at_mut(mid);
            let (l, r) = rayon::join(
                || subtree(prims, left, ls, base, depth + 1),
                || subtree(prims, right, rs, base + mid, depth + 1),
            );
            // Root, then both children, then the rest of each subtree (indices moved).
            let mut nodes = Vec::with_capacity(1 + l.len() + r.len());
            let (lo, ro) = (3, 3 + l.len() - 1);
            let moved = |n: &Node, offset: usize| Node {
                start: if n.count > 0 {
                    n.start
                } else {
                    n.start - 1 + offset as u32
                },
                ..*n
            };
            nodes.push(Node {
                bounds: span.boxes,
                start: 1,
                count: 0,
            });
            nodes.push(moved(&l[0], lo));
            nodes.push(moved(&r[0], ro));
            nodes.extend(l[1..].iter().map(|n| moved(n, lo)));
            nodes.extend(r[1..].iter().map(|n| moved(n, ro)));
            return nodes;
        }
        return vec![Node {
            bounds: span.boxes,
            start: base as u32,
            count: order.len() as u32,
        }];
    }
    let mut nodes = vec![Node {
        bounds: span.boxes,
        start: 0,
        count: 0,
    }];
    // (node, range start, range end, its span, depth)
    let mut work = vec![(0usize, 0usize, order.len(), span, depth)];
    while let Some((node, start, end, span, depth)) = work.pop() {
        nodes[node].bounds = span.boxes;
        let Some((mid, [ls, rs])) = partition(prims, &mut order[start..end], &span, depth) else {
            nodes[node].start = (base + start) as u32;
            nodes[node].count = (end - start) as u32;
            continue;
        };
        let left = nodes.len();
        nodes[node].start = left as u32;
        for _ in 0..2 {
            nodes.push(Node {
                bounds: Aabb::EMPTY,
                start: 0,
                count: 0,
            });
        }
        work.push((left + 1, start + mid, end, rs, depth + 1));
        work.push((left, start, start + mid, ls, depth + 1));
    }
    nodes
}

/// Where to split the primitives `order` lists (`span` is theirs): binned
/// surface-area heuristic on the centroids' longest axis, `order`
/// partitioned so the left part comes first, with both parts' spans (from
/// their bins: no second pass over the primitives). `None` makes a leaf.
fn partition(
    prims: &Primitives<'_>,
    order: &mut [u32],
    span: &Span,
    depth: usize,
) -> Option<(usize, [Span; 2])> {
    let centres = &span.centres;
    let extent = centres.hi - centres.lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let along = |v: Vec3| [v.x, v.y, v.z][axis];
    let (c0, width) = (along(centres.lo), along(extent));
    if order.len() <= LEAF_SIZE || depth >= MAX_DEPTH || width.is_nan() || width <= 0.0 {
        return None;
    }
    let bin_of = |i: u32| {
        let c = along(prims.centres[i as usize]);
        // In [0, BINS] by construction; through `u32`, the saturating
        // conversion costs a clamp, not `u64`'s sign fix-up.
        (((c - c0) / width * BINS as f64) as u32 as usize).min(BINS - 1)
    };
    let mut bins = [Span::EMPTY; BINS];
    let mut counts = [0usize; BINS];
    for &i in order.iter() {
        let b = bin_of(i);
        bins[b].boxes.union(&prims.boxes[i as usize]);
        bins[b].centres.grow(prims.centres[i as usize]);
        counts[b] += 1;
    }
    // What lies right of each split (bins `split..`), swept once from the
    // right; the left side is swept with the splits themselves.
    let mut right_of = [(Span::EMPTY, 0usize); BINS];
    let mut acc = (Span::EMPTY, 0usize);
    for b in (1..BINS).rev() {
        if counts[b] > 0 {
            acc.0.union(&bins[b]);
            acc.1 += counts[b];
        }
        right_of[b] = acc;
    }
    let mut best = (f64::INFINITY, 0usize, Span::EMPTY);
    let mut left = (Span::EMPTY, 0usize);
    for split in 1..BINS {
        // Past an empty bin both sides are those of the split before, and
        // so is the cost, which cannot then be strictly lower.
        if counts[split - 1] == 0 {
            continue;
        }
        left.0.union(&bins[split - 1]);
        left.1 += counts[split - 1];
        let (right, nr) = &right_of[split];
        if left.1 == 0 || *nr == 0 {
            continue;
        }
        let cost = left.0.boxes.area() * left.1 as f64 + right.boxes.area() * *nr as f64;
        if cost < best.0 {
            best = (cost, split, left.0);
        }
    }
    let (_, split, left_span) = best;
    if split == 0 {
        return None;
    }
    let (mut i, mut j) = (0, order.len());
    while i < j {
        if bin_of(order[i]) < split {
            i += 1;
        } else {
            j -= 1;
            order.swap(i, j);
        }
    }
    Some((i, [left_span, right_of[split].0]))
}

#[cfg(test)]
mod quality;
#[cfg(test)]
mod tests;

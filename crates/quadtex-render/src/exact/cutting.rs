//! Cutting a pixel's support among its primitives' regions: front to
//! back ([`Order`], [`Cut::among`]), or whole when they tile it or lie
//! apart ([`Cut::tiling`]), and again as primitives join ([`Cut::insert`]).
//! The support's mesh triangles are first spread to their neighbours
//! ([`Flood`]) so the cut sees every triangle that tiles it.

use std::ops::Deref;

use quadtex_core::ConvexPolygon;

use crate::caster::{Seen, seen_id};
use crate::scene::{Geometry, Scene};
use crate::view::{Placement, placement};

use super::GAP_AREA;
use super::views::{SurfaceViews, ViewMemo, ViewRef, candidate_view};

/// Relative size, against the terms of an edge line's value at a vertex,
/// below which a vertex beyond the line counts as on it in
/// [`overlap_bound`]: a hundred times or so the rounding of clipped
/// vertices and of the line's value.
pub(super) const ON_LINE: f64 = 1e-14;

/// A bound on the area two convex polygons `a` and `b` (boxes `a_box`,
/// `b_box`) overlap by, when an edge line of one has the other on its
/// outer side: `0` when every vertex is on or beyond it, else (vertices a
/// hair inside, where two regions share an edge and rounding puts one
/// vertex across it) the width of that hair, at most [`ON_LINE`] of the
/// line's terms, times the other's box's width plus height (the overlap
/// lies in that strip). `None` when no line shows it: the caller measures
/// the overlap. A repeated vertex's edge has no line (`0 ≤ 0`
/// everywhere) and separates nothing.
pub(super) fn overlap_bound(
    (a, a_box): (&ConvexPolygon, Bounds),
    (b, b_box): (&ConvexPolygon, Bounds),
) -> Option<f64> {
    // Exact sign tests first, stopping at the first vertex inside: most
    // pairs that share an edge are told apart so.
    let outside = |p: &ConvexPolygon, q: &ConvexPolygon| {
        p.edge_lines().any(|[l0, l1, l2]| {
            (l0 != 0.0 || l1 != 0.0)
                && q.vertices()
                    .iter()
                    .all(|&[x, y]| l0 * x + l1 * y + l2 <= 0.0)
        })
    };
    if outside(a, b) || outside(b, a) {
        return Some(0.0);
    }
    let extent = |(lo, hi): Bounds| (hi[0] - lo[0]) + (hi[1] - lo[1]);
    let magnitude = |(lo, hi): Bounds| [lo[0].abs().max(hi[0].abs()), lo[1].abs().max(hi[1].abs())];
    let within = |p: &ConvexPolygon, q: &ConvexPolygon, q_box: Bounds| {
        let [mx, my] = magnitude(q_box);
        p.edge_lines().find_map(|[l0, l1, l2]| {
            let tolerance = ON_LINE * (l0.abs() * mx + l1.abs() * my + l2.abs());
            let mut inside = 0.0f64;
            for &[x, y] in q.vertices() {
                inside = inside.max(l0 * x + l1 * y + l2);
                if inside > tolerance || tolerance.is_nan() {
                    return None;
                }
            }
            let width = inside / (l0 * l0 + l1 * l1).sqrt();
            (width.is_finite()).then(|| width * extent(q_box))
        })
    };
    within(a, b, b_box).or_else(|| within(b, a, a_box))
}

/// A polygon's box, `(lo, hi)` ([`ConvexPolygon::bounds`]).
pub(super) type Bounds = ([f64; 2], [f64; 2]);

/// Whether boxes `(lo, hi)` are apart (or touch along a line): polygons
/// within them overlap in no area.
pub(super) fn boxes_apart((alo, ahi): Bounds, (blo, bhi): Bounds) -> bool {
    alo[0] >= bhi[0] || blo[0] >= ahi[0] || alo[1] >= bhi[1] || blo[1] >= ahi[1]
}

/// Appends `view`'s region of `support` to `regions`, written in its place
/// ([`ViewRef::region_into`]).
pub(super) fn push_region(regions: &mut Regions, view: &ViewRef<'_>, support: &ConvexPolygon) {
    view.region_into(support, regions.next_slot());
    regions.keep_slot();
}

/// The regions of a pixel's views, in slots kept from pixel to pixel: a
/// region is written into its slot in place, vertex by vertex, where
/// pushing one would copy its whole capacity ([`ConvexPolygon`] holds
/// [`MAX_VERTICES`](quadtex_core::MAX_VERTICES) inline), and
/// clearing keeps the slots.
#[derive(Default)]
pub(super) struct Regions {
    slots: Vec<ConvexPolygon>,
    len: usize,
}

impl Regions {
    pub(super) fn clear(&mut self) {
        self.len = 0;
    }

    /// The slot after the last region: what is written there is a region
    /// once [`Regions::keep_slot`] keeps it.
    pub(super) fn next_slot(&mut self) -> &mut ConvexPolygon {
        if self.len == self.slots.len() {
            self.slots.push(ConvexPolygon::EMPTY);
        }
        &mut self.slots[self.len]
    }

    /// Keeps the first `len` regions.
    pub(super) fn truncate(&mut self, len: usize) {
        self.len = self.len.min(len);
    }

    pub(super) fn keep_slot(&mut self) {
        debug_assert!(self.len < self.slots.len(), "no slot written");
        self.len += 1;
    }
}

impl Deref for Regions {
    type Target = [ConvexPolygon];

    fn deref(&self) -> &[ConvexPolygon] {
        &self.slots[..self.len]
    }
}

/// Where regions `a` and `b` overlap, if they do with some area.
pub(super) fn overlap(a: &ConvexPolygon, b: &ConvexPolygon) -> Option<ConvexPolygon> {
    if a.is_empty() || b.is_empty() || boxes_apart(a.bounds(), b.bounds()) {
        return None;
    }
    let o = a.intersect(b);
    (o.area() > 0.0).then_some(o)
}

/// A support cut among primitives: the visible regions of each (by index
/// into the views), the parts none covers yet, and slivers. Its buffers
/// are reused from pixel to pixel ([`Scratch`](super::Scratch)).
#[derive(Default)]
pub(super) struct Cut {
    pub(super) visible_regions: Vec<(usize, ConvexPolygon)>,
    pub(super) remaining: Vec<ConvexPolygon>,
    /// Where [`carve`] gathers what lies outside a region.
    pub(super) spare: Vec<ConvexPolygon>,
    /// What [`Cut::insert`] gives the view it inserts, a visible region it cuts,
    /// and which views are behind it.
    pub(super) inserted: Vec<ConvexPolygon>,
    pub(super) carved: Vec<ConvexPolygon>,
    pub(super) behind: Vec<bool>,
    /// Pieces of at most `sliver_area` (rounding along shared edges): not
    /// cut further, nor integrated over a texture.
    pub(super) slivers: Vec<ConvexPolygon>,
    pub(super) sliver_area: f64,
    /// Area of the support counted twice or not at all when the regions
    /// were taken whole ([`Cut::tiling`]): slivers of rounding along shared
    /// edges, not located.
    pub(super) unaccounted: f64,
    /// The boxes of the non-empty regions [`Cut::tiling`] compares, and
    /// their indices.
    pub(super) boxes: Vec<(usize, Bounds)>,
    /// How many of the first regions are taken whole: all of them when
    /// they tile the support or lie apart ([`Cut::tiling`]), each view's
    /// visible region its whole region, read from the regions, not copied
    /// into `visible_regions`; 0 when the support was cut front to back.
    pub(super) whole: usize,
}

impl Cut {
    /// Cuts the support among `views` (their `regions` of it) front to
    /// back, replacing what the cut held.
    pub(super) fn among(
        &mut self,
        views: &[ViewRef<'_>],
        regions: &[ConvexPolygon],
        support: &ConvexPolygon,
        order: &mut Order,
    ) {
        self.visible_regions.clear();
        self.remaining.clear();
        self.slivers.clear();
        self.sliver_area = GAP_AREA * support.area();
        self.unaccounted = 0.0;
        self.whole = 0;
        if self.taken_whole(regions, support) {
            return;
        }
        let sliver_area = self.sliver_area;
        order.front_to_back(views, regions, sliver_area);
        self.unaccounted += 2.0 * order.hairs;
        self.remaining.push(support.clone());
        if order.cyclic {
            self.each_behind_those_in_front(regions, order, support.area());
            return;
        }
        for &i in &order.order {
            self.take(i, &regions[i]);
        }
    }

    /// The cut when occlusion among the regions is cyclic (no view is in
    /// front of every other it overlaps), so that no order front to back
    /// holds: each view sees its region less the regions of the views in
    /// front of it where they overlap, as [`Order::front_to_back`]
    /// decided each pair. For planar primitives that do not cross, which
    /// is nearer is the same over the whole of a pair's overlap, so this
    /// is what each point shows, whatever the cycles (a pair's hair of an
    /// overlap, which decides nothing, is in the bound). What no region
    /// covers is left for the gaps. Primitives that cross can make a cycle
    /// whose common part every one of them loses to another: what the
    /// pieces, the parts left and the slivers fall short of (or exceed)
    /// the support's area (`support_area`) by goes to the unaccounted
    /// weight.
    pub(super) fn each_behind_those_in_front(
        &mut self,
        regions: &[ConvexPolygon],
        order: &Order,
        support_area: f64,
    ) {
        let sliver_area = self.sliver_area;
        let drop = |_: ConvexPolygon, _: &mut Vec<ConvexPolygon>, _: usize| {};
        for (a, &i) in order.left.iter().enumerate() {
            let Cut {
                visible_regions,
                remaining,
                spare,
                inserted,
                slivers,
                ..
            } = self;
            inserted.clear();
            inserted.push(regions[i].clone());
            for (b, &j) in order.left.iter().enumerate() {
                if order.in_front(a, b) {
                    carve(inserted, &regions[j], spare, slivers, sliver_area, drop);
                }
            }
            keep_visible(i, inserted, visible_regions, slivers, sliver_area);
            carve(remaining, &regions[i], spare, slivers, sliver_area, drop);
        }
        let area = |p: &[ConvexPolygon]| p.iter().map(ConvexPolygon::area).sum::<f64>();
        let shown: f64 = self.visible_regions.iter().map(|(_, p)| p.area()).sum();
        let total = shown + area(&self.remaining) + area(&self.slivers);
        self.unaccounted += (support_area - total).abs();
    }

    /// The cut when no two `regions` overlap by more than a sliver: each
    /// view sees its whole region, whatever their order, and what they
    /// leave of the support (nothing, but for slivers, when they tile it)
    /// is left for the gaps. This is what cutting them front to back
    /// gives, but for how the parts left are split, with fewer visible_regions (a
    /// region cut into each part it reaches) and no order. Returns false,
    /// the cut untouched, when two overlap.
    pub(super) fn taken_whole(
        &mut self,
        regions: &[ConvexPolygon],
        support: &ConvexPolygon,
    ) -> bool {
        if self.tiling(regions, support) {
            return true;
        }
        if self.whole == 0 {
            return false;
        }
        self.remaining.push(support.clone());
        let drop = |_: ConvexPolygon, _: &mut Vec<ConvexPolygon>, _: usize| {};
        for region in regions.iter().filter(|r| !r.is_empty()) {
            let (remaining, spare, slivers) =
                (&mut self.remaining, &mut self.spare, &mut self.slivers);
            carve(remaining, region, spare, slivers, self.sliver_area, drop);
        }
        true
    }

    /// Gives the views taken whole their regions as visible_regions, so that the
    /// cut can be cut again ([`Cut::insert`]).
    pub(super) fn visible_from_whole(&mut self, regions: &[ConvexPolygon]) {
        let whole = std::mem::take(&mut self.whole);
        for (i, region) in regions[..whole].iter().enumerate() {
            if !region.is_empty() {
                self.visible_regions.push((i, region.clone()));
            }
        }
    }

    /// The cut when the `regions` tile the support (the triangles of a
    /// mesh around a pixel, most often): where no two overlap by more than
    /// a sliver and together they cover it but for a sliver, each view
    /// sees its whole region, whatever their order, and nothing is left.
    /// Returns false otherwise: the cut untouched when two overlap or they
    /// cover more; when they lie apart but cover less (gaps), with every
    /// region taken whole ([`Cut::taken_whole`] leaves the gaps). The area
    /// counted twice (or, tiling, not at all: at most three slivers) is
    /// kept in `unaccounted`, for the error bound.
    pub(super) fn tiling(&mut self, regions: &[ConvexPolygon], support: &ConvexPolygon) -> bool {
        let total: f64 = regions.iter().map(ConvexPolygon::area).sum();
        let short = support.area() - total;
        if short < -self.sliver_area {
            return false;
        }
        // Less than the support: the regions may still lie apart, leaving
        // gaps (a far hillside's triangles the list lacks); each is then
        // taken whole, and the gaps are what is left.
        let gaps = short > self.sliver_area;
        let short = short.abs();
        let mut overlapping = 0.0;
        // Each region's box once; empty regions (the centres' triangles
        // that miss this support, most of a crowded list) overlap nothing.
        let boxes = &mut self.boxes;
        boxes.clear();
        boxes.extend(
            (regions.iter().enumerate())
                .filter(|(_, r)| !r.is_empty())
                .map(|(i, r)| (i, r.bounds())),
        );
        for (k, &(i, a_box)) in boxes.iter().enumerate() {
            let a = &regions[i];
            for &(j, b_box) in &boxes[k + 1..] {
                let b = &regions[j];
                if boxes_apart(a_box, b_box) {
                    continue;
                }
                // Neighbours sharing an edge are told apart without clipping.
                overlapping += match overlap_bound((a, a_box), (b, b_box)) {
                    Some(bound) => bound,
                    None => a.intersect(b).area().max(0.0),
                };
                if overlapping > self.sliver_area {
                    return false;
                }
            }
        }
        self.whole = regions.len();
        self.unaccounted = if gaps { 0.0 } else { short } + 2.0 * overlapping;
        !gaps
    }

    /// Each visible region and the index of the view that sees it, in
    /// `regions` when they tile the support.
    pub(super) fn visible<'c>(
        &'c self,
        regions: &'c [ConvexPolygon],
    ) -> impl Iterator<Item = (usize, &'c ConvexPolygon)> + 'c {
        let whole = (regions[..self.whole].iter().enumerate()).filter(|(_, r)| !r.is_empty());
        whole.chain(self.visible_regions.iter().map(|(i, p)| (*i, p)))
    }

    /// Gives view `v` what its `region` covers of the parts not yet
    /// covered (it lies behind every view taken before).
    pub(super) fn take(&mut self, v: usize, region: &ConvexPolygon) {
        if region.is_empty() {
            return;
        }
        let (sliver_area, visible_regions) = (self.sliver_area, &mut self.visible_regions);
        carve(
            &mut self.remaining,
            region,
            &mut self.spare,
            &mut self.slivers,
            sliver_area,
            |visible, slivers, at| {
                if visible.area() > sliver_area {
                    visible_regions.push((v, visible));
                } else {
                    slivers.insert(at, visible);
                }
            },
        );
    }

    /// Adds view `n` to a cut made front to back of the views before it
    /// (in `views` and their `regions`): `n` sees its region less those
    /// of the views in front of it where they overlap (decided at the
    /// overlap's centroid, as [`Order::front_to_back`] decides), and its
    /// region is cut out of the parts not yet covered and of the visible_regions of
    /// the views behind it. The visible_regions are those of cutting the support
    /// again with `n` in its place in the order (when occlusion is not
    /// cyclic), but only what `n`'s region reaches is cut, and `n`'s own
    /// region only where a view in front covers it. Regions taken whole
    /// become visible_regions first ([`Cut::visible_from_whole`]).
    pub(super) fn insert(&mut self, n: usize, views: &[ViewRef<'_>], regions: &[ConvexPolygon]) {
        self.visible_from_whole(regions);
        let region = &regions[n];
        if region.is_empty() {
            return;
        }
        let Cut {
            visible_regions,
            remaining,
            spare,
            inserted,
            carved,
            behind,
            slivers,
            sliver_area,
            ..
        } = self;
        let sliver_area = *sliver_area;
        let drop = |_: ConvexPolygon, _: &mut Vec<ConvexPolygon>, _: usize| {};
        // `behind[v]`: view `v`'s region overlaps `n`'s, behind it.
        behind.clear();
        behind.resize(n, false);
        inserted.clear();
        inserted.push(region.clone());
        for (v, other) in regions[..n].iter().enumerate() {
            let Some(o) = overlap(region, other) else {
                continue;
            };
            let c = o.centroid();
            if views[n].depth_at(c) < views[v].depth_at(c) {
                behind[v] = true;
            } else {
                carve(inserted, other, spare, slivers, sliver_area, drop);
            }
        }
        carve(remaining, region, spare, slivers, sliver_area, drop);
        // In place: a visible region `n` misses stays where it is, one it reaches
        // is replaced by what lies outside it.
        let mut i = 0;
        while i < visible_regions.len() {
            let v = visible_regions[i].0;
            if !behind.get(v).copied().unwrap_or(false)
                || boxes_apart(visible_regions[i].1.bounds(), region.bounds())
            {
                i += 1;
                continue;
            }
            carved.clear();
            carved.push(visible_regions[i].1.clone());
            carve(carved, region, spare, slivers, sliver_area, drop);
            let kept = carved.len();
            visible_regions.splice(i..=i, carved.drain(..).map(|p| (v, p)));
            i += kept;
        }
        keep_visible(n, inserted, visible_regions, slivers, sliver_area);
    }
}

/// Moves `pieces`, what view `view` sees, into the cut: those of more
/// than the sliver area to `visible_regions`, the other pieces with area
/// to `slivers`.
fn keep_visible(
    view: usize,
    pieces: &mut Vec<ConvexPolygon>,
    visible_regions: &mut Vec<(usize, ConvexPolygon)>,
    slivers: &mut Vec<ConvexPolygon>,
    sliver_area: f64,
) {
    for visible in pieces.drain(..) {
        if visible.area() > sliver_area {
            visible_regions.push((view, visible));
        } else if visible.area() > 0.0 {
            slivers.push(visible);
        }
    }
}

/// Cuts `region` out of `parts` in place: a part the region misses stays
/// where it is (a polygon moved is its whole capacity copied), one it
/// reaches is replaced by what lies outside it, in the same place in the
/// list, and outside parts of at most `sliver_area` go to `slivers`.
/// What lies inside goes to `inside(inner, slivers, at)`, with `at` where
/// in `slivers` it goes if it is one: before the outside's slivers, as it
/// was cut first (the slivers' sum keeps its order). `spare`: a buffer.
pub(super) fn carve(
    parts: &mut Vec<ConvexPolygon>,
    region: &ConvexPolygon,
    spare: &mut Vec<ConvexPolygon>,
    slivers: &mut Vec<ConvexPolygon>,
    sliver_area: f64,
    mut inside: impl FnMut(ConvexPolygon, &mut Vec<ConvexPolygon>, usize),
) {
    let bounds = region.bounds();
    let mut i = 0;
    while i < parts.len() {
        let r = &parts[i];
        if boxes_apart(r.bounds(), bounds) {
            i += 1;
            continue;
        }
        match placement(r, region.edge_lines()) {
            Placement::Outside => {
                i += 1;
                continue;
            }
            Placement::Inside => {
                let r = parts.remove(i);
                let at = slivers.len();
                inside(r, slivers, at);
                continue;
            }
            Placement::Straddles => {}
        }
        let slivers_before = slivers.len();
        spare.clear();
        let inner = r.split_by(region, |p| {
            if p.area() > sliver_area {
                spare.push(p);
            } else {
                slivers.push(p);
            }
        });
        if inner.area() > 0.0 {
            inside(inner, slivers, slivers_before);
        }
        let added = spare.len();
        parts.splice(i..=i, spare.drain(..));
        i += added;
    }
}

/// The order of a support's views front to back ([`Order::front_to_back`])
/// and its buffers.
#[derive(Default)]
pub(super) struct Order {
    /// The views with a region, by index.
    pub(super) left: Vec<usize>,
    /// `behind[a·n + b]`: `left[b]` is in front of `left[a]` where their
    /// regions overlap.
    behind: Vec<bool>,
    placed: Vec<bool>,
    /// How many views not yet placed are in front of each.
    ahead: Vec<usize>,
    /// The views front to back.
    pub(super) order: Vec<usize>,
    /// Whether occlusion was cyclic (the order then breaks a cycle at the
    /// nearest view's centroid, which decides nothing exactly).
    pub(super) cyclic: bool,
    /// The area of the overlaps of at most `hair` area, which set no order.
    pub(super) hairs: f64,
}

impl Order {
    /// Orders `views` front to back into [`Order::order`]: repeatedly the one no other
    /// remaining view is in front of where their regions overlap (the
    /// nearest at its own centroid if occlusion is cyclic, which
    /// [`Order::cyclic`] then says). Overlaps of at most `hair` area
    /// (rounding along shared edges), and those whose depths tie at the
    /// centroid, set no order; [`Order::hairs`] sums their areas.
    pub(super) fn front_to_back(
        &mut self,
        views: &[ViewRef<'_>],
        regions: &[ConvexPolygon],
        hair: f64,
    ) {
        let Order {
            left,
            behind,
            placed,
            ahead,
            order,
            cyclic,
            hairs,
        } = self;
        *cyclic = false;
        *hairs = 0.0;
        left.clear();
        left.extend((0..views.len()).filter(|&i| !regions[i].is_empty()));
        let n = left.len();
        // `behind[a·n + b]`: `left[b]` is in front of `left[a]` where their
        // regions overlap (decided once a pair, at the overlap's centroid).
        behind.clear();
        behind.resize(n * n, false);
        for a in 0..n {
            for b in a + 1..n {
                let (i, j) = (left[a], left[b]);
                let Some(overlap) = overlap(&regions[i], &regions[j]) else {
                    continue;
                };
                let area = overlap.area();
                if area <= hair {
                    *hairs += area;
                    continue;
                }
                let c = overlap.centroid();
                let (di, dj) = (views[i].depth_at(c), views[j].depth_at(c));
                behind[a * n + b] = dj < di;
                behind[b * n + a] = di < dj;
                // A tie (or no depth) sets no order either: both may keep
                // the overlap.
                if !(di < dj || dj < di) {
                    *hairs += area;
                }
            }
        }
        placed.clear();
        placed.resize(n, false);
        ahead.clear();
        ahead.extend((0..n).map(|a| behind[a * n..(a + 1) * n].iter().filter(|&&b| b).count()));
        order.clear();
        // Counts kept as views are placed, so that a pick costs a scan, not
        // a scan per view: a shared cut's list runs to a hundred views.
        for _ in 0..n {
            let pick = (0..n)
                .find(|&a| !placed[a] && ahead[a] == 0)
                .unwrap_or_else(|| {
                    // Cyclic occlusion: the nearest at its own centroid.
                    *cyclic = true;
                    let depth = |a: usize| views[left[a]].depth_at(regions[left[a]].centroid());
                    (0..n)
                        .filter(|&a| !placed[a])
                        .fold((usize::MAX, f64::INFINITY), |best, a| {
                            let d = depth(a);
                            if d < best.1 || best.0 == usize::MAX {
                                (a, d)
                            } else {
                                best
                            }
                        })
                        .0
                });
            placed[pick] = true;
            order.push(left[pick]);
            for a in 0..n {
                if behind[a * n + pick] {
                    ahead[a] -= 1;
                }
            }
        }
    }

    /// Whether view `left[b]` is in front of view `left[a]` where their
    /// regions overlap (as the last [`Order::front_to_back`] decided).
    pub(super) fn in_front(&self, a: usize, b: usize) -> bool {
        self.behind[a * self.left.len() + b]
    }
}

/// A pixel's mesh triangles spread to their neighbours across the edges
/// the support reaches over ([`Flood::spread`]).
pub(super) struct Flood<'s, 'a> {
    pub(super) scene: &'s Scene,
    pub(super) cache: &'a SurfaceViews,
    pub(super) support: &'s ConvexPolygon,
    /// Most triangles a spread adds ([`MAX_GAP_PRIMITIVES`](super::MAX_GAP_PRIMITIVES) a pixel).
    pub(super) cap: usize,
}

impl<'a> Flood<'_, 'a> {
    /// Adds to `views` (and `regions`, `tried`) each mesh triangle across
    /// an edge of a listed triangle whose region of the support is not
    /// empty, where the support reaches past that edge, and the same from
    /// those it adds, breadth first, up to its cap: the
    /// triangles of a mesh around those the centres see, which tile the
    /// support with them where the surface does not fold. Their indices go
    /// to `flooded`.
    pub(super) fn spread(
        &self,
        views: &mut Vec<ViewRef<'a>>,
        regions: &mut Regions,
        tried: &mut Vec<(Seen, Option<usize>)>,
        memo: &mut ViewMemo,
        flooded: &mut Vec<usize>,
    ) {
        flooded.clear();
        let corners = self.support.vertices();
        let mut i = 0;
        while i < views.len() && flooded.len() < self.cap {
            let view = &views[i];
            let (surface, triangle) = (view.surface(), view.triangle());
            let mesh = match self.scene.surfaces.get(surface).map(|s| &s.geometry) {
                Some(Geometry::Mesh(mesh)) if !regions[i].is_empty() => mesh,
                _ => {
                    i += 1;
                    continue;
                }
            };
            let (Some(triangle), Some(planar)) = (triangle, view.planar()) else {
                i += 1;
                continue;
            };
            // `lines()`: in front, then the edges in `Mesh::neighbour`'s order.
            let mut edges = [[0.0; 3]; 3];
            for (e, l) in edges.iter_mut().zip(planar.lines().skip(1)) {
                *e = l;
            }
            for (edge, [a, b, c]) in edges.into_iter().enumerate() {
                if corners.iter().all(|&[x, y]| a * x + b * y + c >= 0.0) {
                    continue;
                }
                let Some(next) = mesh.neighbour(triangle, edge) else {
                    continue;
                };
                let id = seen_id(surface, next);
                if tried.iter().any(|(t, _)| *t == id) || flooded.len() == self.cap {
                    continue;
                }
                let Some(Some(next)) = candidate_view(self.scene, self.cache, memo, id) else {
                    continue;
                };
                let region = regions.next_slot();
                next.region_into(self.support, region);
                if !region.is_empty() {
                    regions.keep_slot();
                    flooded.push(views.len());
                    tried.push((id, Some(views.len())));
                    views.push(next);
                }
            }
            i += 1;
        }
    }
}

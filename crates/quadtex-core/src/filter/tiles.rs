//! Tiles of the wrapped texture plane and where a region lies against
//! them: edge lines, classification of boxes, segments of an axis.

use crate::filter::projection::Mat3;
use crate::filter::wrap::WrapMode;
use crate::geometry::polygon::ConvexPolygon;

/// An edge line `n·p + c ≥ 0` (inside).
pub(super) type Line = [f64; 3];

/// The region's edges, plus two that keep a texture's tile off the tree's
/// pad ([`crate::Aspect`]).
pub(super) const MAX_EDGES: usize = crate::geometry::polygon::MAX_VERTICES + 2;

pub(super) fn edges_of(p: &ConvexPolygon) -> ([Line; MAX_EDGES], usize) {
    let mut lines = [[0.0; 3]; MAX_EDGES];
    let mut n = 0;
    for (slot, line) in lines.iter_mut().zip(p.edge_lines()) {
        *slot = line;
        n += 1;
    }
    (lines, n)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Class {
    Outside,
    Inside,
    /// Crossed by the edges in the bit mask.
    Boundary(u32),
}

/// Where the rectangle `[x0, x1] × [z0, z1]` lies against the polygon with
/// `edges`.
#[inline]
pub(super) fn classify(
    edges: &([Line; MAX_EDGES], usize),
    x0: f64,
    z0: f64,
    x1: f64,
    z1: f64,
) -> Class {
    let mut crossing = 0u32;
    for (i, e) in edges.0[..edges.1].iter().enumerate() {
        let base = e[2];
        let (ax0, ax1) = (e[0] * x0, e[0] * x1);
        let (bz0, bz1) = (e[1] * z0, e[1] * z1);
        let min = ax0.min(ax1) + bz0.min(bz1) + base;
        if min >= 0.0 {
            continue;
        }
        let max = ax0.max(ax1) + bz0.max(bz1) + base;
        if max <= 0.0 {
            return Class::Outside;
        }
        crossing |= 1 << i;
    }
    if crossing == 0 {
        Class::Inside
    } else {
        Class::Boundary(crossing)
    }
}

/// One axis of texture space, cut where the wrap changes what it shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Segment {
    /// Tiles `i0..=i1` (the unit tile alone, `0..=0`, for clamp and border).
    Tiles(i64, i64),
    /// Beyond the low edge (clamp, border).
    Low,
    /// Beyond the high edge.
    High,
}

pub(super) fn segments(mode: WrapMode, lo: f64, hi: f64) -> [Option<Segment>; 3] {
    match mode {
        WrapMode::Repeat | WrapMode::Mirror => {
            let (a, b) = (lo.floor(), hi.floor());
            // Far beyond i64: the region is absurdly far out; treat as none.
            if !(a.abs() < 9.0e15 && b.abs() < 9.0e15) {
                return [None; 3];
            }
            let b = if b > a && b == hi { b - 1.0 } else { b };
            [Some(Segment::Tiles(a as i64, b as i64)), None, None]
        }
        WrapMode::Clamp | WrapMode::Border => [
            (lo < 0.0).then_some(Segment::Low),
            (lo < 1.0 && hi > 0.0).then_some(Segment::Tiles(0, 0)),
            (hi > 1.0).then_some(Segment::High),
        ],
    }
}

/// How many tiles an axis's [`segments`] cross when they are one run of
/// tiles (no part outside a clamped or bordered edge); `None` otherwise.
pub(super) fn one_run_of_tiles(s: &[Option<Segment>; 3]) -> Option<f64> {
    match s {
        [Some(Segment::Tiles(a, b)), None, _] => Some((b - a + 1) as f64),
        _ => None,
    }
}

/// How tile `i` of an axis maps to the tree: texture = `sign·local + offset`.
#[inline]
pub(super) fn tile_map(mode: WrapMode, i: i64) -> (f64, f64) {
    match mode {
        WrapMode::Mirror if i.rem_euclid(2) == 1 => (-1.0, (i + 1) as f64),
        _ => (1.0, i as f64),
    }
}

/// A tile's view of the region: the region and its edges in the tile's
/// local coordinates, and the map from local coordinates to the screen.
pub(super) struct TileFrame {
    pub(super) edges: ([Line; MAX_EDGES], usize),
    pub(super) to_screen: Mat3,
    pub(super) det: f64,
}

//! Exact scans of a region over a grid of cells, band by band
//! ([`scan_grid`]), and the flat-grid scan of shallow repeated textures.

use arrayvec::ArrayVec;

use crate::filter::pixel_filter::PixelFilter;
use crate::filter::projection::{Mat3, apply};
use crate::filter::query::RegionQuery;
use crate::filter::tiles::{one_run_of_tiles, segments};
use crate::filter::wrap::{Wrap, fold_cell};
use crate::geometry::polygon::ConvexPolygon;
use crate::tree::QuadTree;

/// Most grid cells [`scan_flat_grid`] clips for one region: about the
/// time the walk spends on its default budget of squares.
pub(super) const SCAN_CELLS: f64 = 512.0;

/// The region over a shallow tree (depth ≤
/// [`crate::tree::FLAT_GRID_MAX_DEPTH`], both axes repeated or mirrored)
/// whose texture-space box `lo..hi` lies in one run of tiles a side,
/// exactly: band by band of the grid at the tree's depth, each cell the
/// region crosses clipped and weighted, at most [`SCAN_CELLS`] cells.
/// `(Σ colour·k, Σ k, cells)`, or `None` (nothing computed) when it does
/// not apply; the walk then takes the region.
///
/// It matters for the thin needles below a horizon: the walk's blocks
/// do not fit inside them and refining tile by tile costs more squares
/// than the budget, while a cell here costs a clip and an area. It runs
/// before a walk is set up (its lines, buffers and queue), which a
/// region it takes does not need.
pub(super) fn scan_flat_grid(
    query: &RegionQuery<'_>,
    (lo, hi): ([f64; 2], [f64; 2]),
    region: &ConvexPolygon,
) -> Option<([f64; 4], f64, f64)> {
    let grid = FlatGrid::over(query.tree, query.wrap, (lo, hi))?;
    scan_grid(
        region,
        &query.projection.screen_from_texture,
        grid.side(),
        query.filter,
        query.centre,
        SCAN_CELLS,
        |x, z| grid.colour(x, z),
    )
}

/// A shallow repeated tree's grid of cells at its depth
/// ([`QuadTree::flat_grid`](crate::tree::QuadTree::flat_grid)), as the
/// scans read it over a texture-space box within one run of tiles a side.
pub(super) struct FlatGrid<'t> {
    cells: &'t [[f64; 4]],
    depth: u8,
    wrap: Wrap,
}

impl<'t> FlatGrid<'t> {
    /// The grid of `tree` under `wrap` over the texture-space box
    /// `lo..hi`; `None` when the tree has none (deeper than
    /// [`crate::tree::FLAT_GRID_MAX_DEPTH`], not repeated or mirrored on
    /// both axes, or of depth 0) or the box spans more than one run of
    /// tiles a side.
    pub(super) fn over(
        tree: &'t QuadTree,
        wrap: Wrap,
        (lo, hi): ([f64; 2], [f64; 2]),
    ) -> Option<FlatGrid<'t>> {
        let cells = tree.flat_grid()?;
        let depth = tree.depth();
        if depth == 0
            || one_run_of_tiles(&segments(wrap.x(), lo[0], hi[0])).is_none()
            || one_run_of_tiles(&segments(wrap.z(), lo[1], hi[1])).is_none()
        {
            return None;
        }
        Some(FlatGrid { cells, depth, wrap })
    }

    /// A cell's side in texture units.
    pub(super) fn side(&self) -> f64 {
        1.0 / (1u64 << self.depth) as f64
    }

    /// The colour of cell `(x, z)` (folded into the tile).
    #[inline(always)]
    pub(super) fn colour(&self, x: i64, z: i64) -> Option<[f64; 4]> {
        let n = 1usize << self.depth;
        Some(
            self.cells[fold_cell(self.wrap.z(), z, self.depth)? * n
                + fold_cell(self.wrap.x(), x, self.depth)?],
        )
    }
}

/// The integral under `filter` centred at `centre` over `region` (grid
/// coordinates: cell `(x, z)` is `[x·h, (x+1)·h) × [z·h, (z+1)·h)`, mapped to
/// the screen by `m`) of the colour `colour(x, z)` of each cell it crosses,
/// exactly: band by band of cells, each cell's piece clipped and weighted.
/// `(Σ colour·k, Σ k, cells)`, or `None` (nothing computed) past
/// `max_cells` cells or where `colour` gives none.
pub(super) fn scan_grid(
    region: &ConvexPolygon,
    m: &Mat3,
    h: f64,
    filter: PixelFilter,
    centre: [f64; 2],
    max_cells: f64,
    mut colour: impl FnMut(i64, i64) -> Option<[f64; 4]>,
) -> Option<([f64; 4], f64, f64)> {
    let (mut colour_sum, mut weight_sum) = ([0.0; 4], 0.0);
    let mut add = |colour: [f64; 4], w: f64| {
        for (a, c) in colour_sum.iter_mut().zip(colour) {
            *a += c * w;
        }
        weight_sum += w;
    };
    let grid = Grid { m, h, centre };
    let cells = if filter == PixelFilter::Box {
        scan_box(region, &grid, max_cells, &mut colour, &mut add)?
    } else {
        scan_bands(region, &grid, &filter, max_cells, &mut colour, &mut add)?
    };
    Some((colour_sum, weight_sum, cells))
}

/// The grid a scan cuts a region by: its cells' side `h` (texture units),
/// the map `m` from texture to screen, and the point the screen
/// coordinates are taken relative to (the filter's centre).
pub(super) struct Grid<'m> {
    pub(super) m: &'m Mat3,
    pub(super) h: f64,
    pub(super) centre: [f64; 2],
}

/// The first and last band (`k0..k1`) and column (`c0..c1`) of cells of
/// side `h` that `region` may cross, or `None` when the least number of
/// cells it must cross is past `max_cells` (the bands' cells number at
/// least the bands, the columns it spans, and its area in cells, less
/// rounding: past `max_cells` by any of these, the scan would stop there,
/// its work thrown away; the regions at a horizon, millions of cells,
/// spent 24 µs each so).
fn grid_span(region: &ConvexPolygon, h: f64, max_cells: f64) -> Option<([f64; 2], [f64; 2])> {
    let (lo, hi) = region.bounds();
    let (k0, k1) = ((lo[1] / h).floor(), (hi[1] / h).ceil());
    let (c0, c1) = ((lo[0] / h).floor(), (hi[0] / h).ceil());
    let least = (k1 - k0).max(c1 - c0).max(region.area() / (h * h) - 1.0);
    if least.is_nan() || least > max_cells {
        return None;
    }
    Some(([k0, k1], [c0, c1]))
}

/// [`scan_grid`] under the box filter: `cells`, each cell's piece weighed
/// by its screen area, into `add`.
fn scan_box(
    region: &ConvexPolygon,
    grid: &Grid<'_>,
    max_cells: f64,
    colour: &mut impl FnMut(i64, i64) -> Option<[f64; 4]>,
    add: &mut impl FnMut([f64; 4], f64),
) -> Option<f64> {
    let (h, centre) = (grid.h, grid.centre);
    let ([k0, k1], [c0, c1]) = grid_span(region, h, max_cells)?;
    // Bands run across the axis the region spans fewer cells of: a
    // needle along z is cut into a few long columns, not many short
    // rows (a band costs a split and the projection of its vertices,
    // a cell within it one cut). The region is transposed for it,
    // `(x, z) → (z, x)`, with the screen map's columns swapped; the
    // orientation this reverses does not matter to the areas, taken as
    // absolute values.
    let transpose = c1 - c0 < k1 - k0;
    let (k0, k1) = if transpose { (c0, c1) } else { (k0, k1) };
    let (k0, k1) = (k0 as i64, k1 as i64);
    let mut m = *grid.m;
    if transpose {
        for row in &mut m {
            row.swap(0, 1);
        }
    }
    // Band `k`, cell `col` within it: the cell's grid position.
    let mut colour = |k: i64, col: i64| {
        if transpose {
            colour(k, col)
        } else {
            colour(col, k)
        }
    };
    let transposed;
    let region = if transpose {
        transposed = region.map(|[x, z]| [z, x]);
        &transposed
    } else {
        region
    };
    let texture = region.vertices();
    let screen = band_to_screen(texture, &m, centre);
    let mut bands = Bands::new(texture, &screen);
    let mut band = BandBuffer::default();
    let mut cells = 0.0;
    for k in k0..k1 {
        let top = if k + 1 < k1 {
            (k + 1) as f64 * h
        } else {
            f64::INFINITY
        };
        bands.next_band(top, &m, centre, &mut band);
        let (texture, screen) = (band.texture(), band.screen());
        if texture.len() < 3 {
            continue;
        }
        // The box weight of a cell's piece is its screen area: the
        // screen area of the band left of the cell's right side, less
        // that left of its left side. One sweep along the band's two
        // chains, no polygon built.
        let total = shoelace(screen);
        let mut sweep = LeftOf::new(texture, screen, total);
        let (m0, m1) = (
            (sweep.x_min / h).floor() as i64,
            (sweep.x_max / h).ceil() as i64,
        );
        cells += (m1 - m0) as f64;
        if cells > max_cells {
            return None;
        }
        let mut left = 0.0;
        for col in m0..m1 {
            let upto = if col + 1 == m1 {
                total
            } else {
                sweep.area((col + 1) as f64 * h, &m, centre)
            };
            let w = 0.5 * (upto - left).abs();
            left = upto;
            add(colour(k, col)?, w);
        }
    }
    Some(cells)
}

/// What a band scan weighs a cell's piece by: a term for each directed
/// screen edge (relative to the scan's centre) whose sum around a closed
/// polygon is the polygon's weight times its orientation's sign, by
/// Green's theorem. One number a piece for a pixel filter
/// ([`PixelFilter::edge_integral`]), or one for each pixel sharing a
/// screen cell ([`crate::filter::screen_cell`]).
pub(super) trait EdgeTerms {
    /// A piece's weight (or weights).
    type Weight: Copy
        + Default
        + std::ops::Add<Output = Self::Weight>
        + std::ops::Sub<Output = Self::Weight>
        + std::ops::Neg<Output = Self::Weight>
        + std::ops::Mul<f64, Output = Self::Weight>;

    /// The term of the directed edge from `a` to `b`.
    fn edge(&self, a: [f64; 2], b: [f64; 2]) -> Self::Weight;
}

impl EdgeTerms for PixelFilter {
    type Weight = f64;

    #[inline(always)]
    fn edge(&self, a: [f64; 2], b: [f64; 2]) -> f64 {
        self.edge_integral(a, b)
    }
}

/// [`scan_grid`] under weights other than the box's areas, by Green's
/// theorem: each cell's piece weighs what the band left of its right side
/// does, less what the band left of its left side does ([`WeightLeftOf`]),
/// into `add`; the number of cells, or `None` past `max_cells` or where
/// `colour` gives none.
pub(super) fn scan_bands<E: EdgeTerms>(
    region: &ConvexPolygon,
    grid: &Grid<'_>,
    edges: &E,
    max_cells: f64,
    colour: &mut impl FnMut(i64, i64) -> Option<[f64; 4]>,
    add: &mut impl FnMut([f64; 4], E::Weight),
) -> Option<f64> {
    let (m, h, centre) = (grid.m, grid.h, grid.centre);
    let ([k0, k1], _) = grid_span(region, h, max_cells)?;
    let (k0, k1) = (k0 as i64, k1 as i64);
    let texture = region.vertices();
    let screen = band_to_screen(texture, m, centre);
    let mut bands = Bands::new(texture, &screen);
    let mut band = BandBuffer::default();
    // Reused band to band: a Mitchell cell's terms are 16 weights an
    // edge, and a buffer built per band was copied out whole.
    let mut terms: ArrayVec<E::Weight, BAND_VERTICES> = ArrayVec::new();
    let mut cells = 0.0;
    // The top edge's term of the band before.
    let mut previous_top: Option<E::Weight> = None;
    for k in k0..k1 {
        let top = if k + 1 < k1 {
            (k + 1) as f64 * h
        } else {
            f64::INFINITY
        };
        bands.next_band(top, m, centre, &mut band);
        let (texture, screen) = (band.texture(), band.screen());
        if texture.len() < 3 {
            previous_top = None;
            continue;
        }
        let n = texture.len();
        let extent = Extent::of(texture);
        let (m0, m1) = (
            (extent.x_min / h).floor() as i64,
            (extent.x_max / h).ceil() as i64,
        );
        cells += (m1 - m0) as f64;
        if cells > max_cells {
            return None;
        }
        // The bottom edge's term is the previous band's top edge's,
        // negated: the same two points, reversed.
        let shared = previous_top.filter(|_| band.bottom_edge);
        terms.clear();
        for i in 0..n {
            terms.push(match shared {
                Some(top) if i == n - 1 => -top,
                _ => edges.edge(screen[i], screen[(i + 1) % n]),
            });
        }
        previous_top = band.top_edge.map(|i| terms[i]);
        let total = terms.iter().fold(E::Weight::default(), |a, &t| a + t);
        let orientation = shoelace(screen).signum();
        let mut sweep = WeightLeftOf::new((texture, screen), extent, &terms, total, edges);
        let mut left = E::Weight::default();
        for col in m0..m1 {
            let upto = if col + 1 == m1 {
                total
            } else {
                sweep.weight((col + 1) as f64 * h, m, centre)
            };
            add(colour(col, k)?, (upto - left) * orientation);
            left = upto;
        }
    }
    Some(cells)
}

/// The texture-space `texture` vertices (at most
/// [`MAX_VERTICES`](crate::geometry::polygon::MAX_VERTICES)) mapped by `m` to screen
/// coordinates relative to `centre` (so that shoelace sums stay at the
/// polygon's own scale), in a buffer that is not zeroed first.
#[inline(always)]
pub(super) fn band_to_screen(
    texture: &[[f64; 2]],
    m: &Mat3,
    centre: [f64; 2],
) -> ArrayVec<[f64; 2], { crate::geometry::polygon::MAX_VERTICES }> {
    (texture.iter().take(crate::geometry::polygon::MAX_VERTICES))
        .map(|&t| {
            let q = apply(m, t);
            [q[0] - centre[0], q[1] - centre[1]]
        })
        .collect()
}

/// The doubled signed area of the polygon with vertices `p`.
#[inline(always)]
pub(super) fn shoelace(p: &[[f64; 2]]) -> f64 {
    let (Some(&first), Some(&last)) = (p.first(), p.last()) else {
        return 0.0;
    };
    let cross = |a: [f64; 2], b: [f64; 2]| a[0] * b[1] - a[1] * b[0];
    let mut sum = 0.0;
    let mut a = first;
    for &b in &p[1..] {
        sum += cross(a, b);
        a = b;
    }
    sum + cross(last, first)
}

/// One band of a region, in its order: texture coordinates and the
/// screen coordinates [`band_to_screen`] gives them (one band has at most
/// the region's vertices and four crossings).
pub(super) struct BandBuffer {
    // Not zeroed arrays: a band is written from its first vertex, and
    // clearing 640 bytes per region cost more than most bands' cuts.
    texture: ArrayVec<[f64; 2], BAND_VERTICES>,
    screen: ArrayVec<[f64; 2], BAND_VERTICES>,
    /// The index of the band's top edge, along the upper cut (from the
    /// first chain's crossing to the second's), when it has one.
    top_edge: Option<usize>,
    /// Whether the band's last edge (back to its first vertex) is its
    /// bottom, along the lower cut: the previous band's top edge, from
    /// the same two points, reversed.
    bottom_edge: bool,
}

/// Most vertices of a band: the region's and four crossings.
pub(super) const BAND_VERTICES: usize = crate::geometry::polygon::MAX_VERTICES + 4;

impl Default for BandBuffer {
    fn default() -> Self {
        BandBuffer {
            texture: ArrayVec::new(),
            screen: ArrayVec::new(),
            top_edge: None,
            bottom_edge: false,
        }
    }
}

impl BandBuffer {
    fn texture(&self) -> &[[f64; 2]] {
        &self.texture
    }

    fn screen(&self) -> &[[f64; 2]] {
        &self.screen
    }

    #[cfg(test)]
    pub(super) fn len(&self) -> usize {
        self.texture.len()
    }

    fn clear(&mut self) {
        self.texture.clear();
        self.screen.clear();
        self.top_edge = None;
        self.bottom_edge = false;
    }

    /// Drops the last vertex.
    fn pop(&mut self) {
        self.texture.pop();
        self.screen.pop();
    }

    #[inline(always)]
    fn push(&mut self, (texture, screen): ([f64; 2], [f64; 2])) {
        if self.texture.len() < BAND_VERTICES {
            self.texture.push(texture);
            self.screen.push(screen);
        }
    }
}

/// A convex texture-space polygon (either orientation) cut into bands
/// `z ∈ [z_k, z_(k+1)]` from the bottom up, for cuts taken in increasing
/// order: a walk up its two chains from its lowest vertex, as [`LeftOf`]
/// walks in `x`. Each crossing of a cut is computed and mapped to the
/// screen once, for the band below it and the band above; the region's
/// own vertices are mapped once, beforehand. A band is the polygon's part
/// between two cuts, in the polygon's order: the first chain's (forward
/// from the lowest vertex) crossing of the lower cut, its vertices between
/// the cuts, its crossing of the upper cut, the second chain's (backward)
/// crossing of it, the second chain's vertices between, and its crossing
/// of the lower cut. A chain's last vertex at or below a cut is that
/// cut's crossing when it lies on the cut (a run of vertices on a cut,
/// which rounding leaves at a convex polygon's top, keeps all but that
/// one as the band's).
///
/// Where rounding leaves a chain not quite monotone in `z`, the walk
/// stops at the first vertex past the cut, as [`LeftOf`] does.
pub(super) struct Bands<'a> {
    texture: &'a [[f64; 2]],
    screen: &'a [[f64; 2]],
    /// Per chain: its last vertex at or below the previous cut.
    at: [usize; 2],
    /// Per chain: its crossing of the previous cut (texture, screen);
    /// `None` before the first band (the lowest vertex starts both).
    low: Option<[([f64; 2], [f64; 2]); 2]>,
}

impl<'a> Bands<'a> {
    pub(super) fn new(texture: &'a [[f64; 2]], screen: &'a [[f64; 2]]) -> Bands<'a> {
        let mut lowest = 0;
        for (i, t) in texture.iter().enumerate() {
            if t[1] < texture[lowest][1] {
                lowest = i;
            }
        }
        Bands {
            texture,
            screen,
            at: [lowest; 2],
            low: None,
        }
    }

    /// The band from the previous cut (the polygon's bottom at first) up
    /// to `top`, into `band`; `top` no less than the previous cut, and
    /// infinite for the last band (the rest of the polygon).
    #[inline(always)]
    pub(super) fn next_band(
        &mut self,
        top: f64,
        m: &Mat3,
        centre: [f64; 2],
        band: &mut BandBuffer,
    ) {
        band.clear();
        let n = self.texture.len();
        if n < 3 {
            return;
        }
        let forward = |i: usize| if i + 1 == n { 0 } else { i + 1 };
        let backward = |i: usize| if i == 0 { n - 1 } else { i - 1 };
        let vertex = |i: usize| (self.texture[i], self.screen[i]);
        match self.low {
            Some([first, _]) => band.push(first),
            None => band.push(vertex(self.at[0])),
        }
        if top == f64::INFINITY {
            // The rest: the vertices after the first chain's last one
            // below, up to the second chain's (not included), then the
            // second chain's crossing. With no cut before, the two chains
            // start at the lowest vertex: the whole polygon.
            let mut i = forward(self.at[0]);
            while i != self.at[1] {
                band.push(vertex(i));
                i = forward(i);
            }
            if let Some([_, second]) = self.low {
                let before = band.texture.len();
                band.push(second);
                band.bottom_edge = band.texture.len() == before + 1;
            }
            return;
        }
        // The lowest vertex is not above any cut and the highest is above
        // this one, so neither walk passes the top (bounded below anyway).
        let crossing = |a: usize, b: usize| {
            let (a, b) = (self.texture[a], self.texture[b]);
            let u = (top - a[1]) / (b[1] - a[1]);
            let t = [a[0] + u * (b[0] - a[0]), top];
            let q = apply(m, t);
            (t, [q[0] - centre[0], q[1] - centre[1]])
        };
        // Each vertex the walk reaches is the band's, but the last one when
        // it lies on the cut: the crossing is that vertex then (`u = 0`
        // gives it exactly), pushed below.
        // At most `n` steps a walk: a top at or above every vertex (which
        // callers' cuts below the region's top never are) cannot cycle.
        let (mut i, mut next) = (self.at[0], forward(self.at[0]));
        let mut steps = 0;
        while steps < n && self.texture[next][1] <= top {
            (i, next) = (next, forward(next));
            band.push(vertex(i));
            steps += 1;
        }
        if i != self.at[0] && self.texture[i][1] == top {
            band.pop();
        }
        self.at[0] = i;
        let first = crossing(i, next);
        let top_edge = band.texture.len();
        band.push(first);
        let (mut i, mut next) = (self.at[1], backward(self.at[1]));
        // The second chain's vertices between the cuts, in the order it
        // meets them (against the polygon's): pushed reversed below.
        let mut between = [0usize; crate::geometry::polygon::MAX_VERTICES];
        let mut count = 0;
        let mut steps = 0;
        while steps < n && self.texture[next][1] <= top {
            steps += 1;
            (i, next) = (next, backward(next));
            if count < between.len() {
                between[count] = i;
                count += 1;
            }
        }
        if i != self.at[1] && self.texture[i][1] == top {
            count = count.saturating_sub(1);
        }
        self.at[1] = i;
        let second = crossing(i, next);
        band.push(second);
        if band.texture.len() == top_edge + 2 {
            band.top_edge = Some(top_edge);
        }
        for &i in between[..count].iter().rev() {
            band.push(vertex(i));
        }
        if let Some([_, low]) = self.low {
            let before = band.texture.len();
            band.push(low);
            band.bottom_edge = band.texture.len() == before + 1;
        }
        self.low = Some([first, second]);
    }
}

/// A texture-space polygon's leftmost vertex (the first of least `x`)
/// and its least and greatest `x`: where the sweeps' chains start and end.
#[derive(Debug, Clone, Copy)]
pub(super) struct Extent {
    first: usize,
    x_min: f64,
    x_max: f64,
}

impl Extent {
    pub(super) fn of(texture: &[[f64; 2]]) -> Extent {
        let (mut first, mut x_min, mut x_max) = (0, f64::INFINITY, f64::NEG_INFINITY);
        for (i, t) in texture.iter().enumerate() {
            if t[0] < x_min {
                (first, x_min) = (i, t[0]);
            }
            x_max = x_max.max(t[0]);
        }
        Extent {
            first,
            x_min,
            x_max,
        }
    }
}

/// The neighbour of vertex `i` of an `n`-gon along chain `chain`: the
/// next (chain 0) or the previous (chain 1) in the polygon's order. By a
/// compare, not `% n`: `n` is not known when compiled, so `%` is an
/// integer division each step.
#[inline(always)]
fn chain_step(chain: usize, i: usize, n: usize) -> usize {
    if chain == 0 {
        if i + 1 == n { 0 } else { i + 1 }
    } else if i == 0 {
        n - 1
    } else {
        i - 1
    }
}

/// The doubled signed screen area of the part of a texture-space convex
/// polygon left of a cut `x = c`, for cuts taken in increasing order: a
/// sweep along the polygon's two chains from its leftmost vertex to its
/// rightmost, each vertex's shoelace term added once as the cuts pass it,
/// so that a cut costs its two crossing points (`O(n + cuts)` a band,
/// against `O(n)` a cut for clipping the band at each).
///
/// The left part's boundary, in the polygon's own order: the first chain
/// (forward from the leftmost vertex) up to its last vertex left of the
/// cut, its crossing, the cut, the second chain's crossing, and the second
/// chain (backward from the leftmost vertex) back to the start. Where
/// rounding leaves a chain not quite monotone in `x` (a vertex a few ulps
/// behind its predecessor), the sweep stops at the first vertex past the
/// cut: the left part then differs from a clip by a sliver of that wiggle's
/// width.
pub(super) struct LeftOf<'a> {
    texture: &'a [[f64; 2]],
    screen: &'a [[f64; 2]],
    /// The doubled signed area of the whole polygon, for cuts past it.
    total: f64,
    /// The leftmost and rightmost `x`.
    x_min: f64,
    x_max: f64,
    /// Per chain (0 forward, 1 backward from the leftmost vertex): the
    /// index of its last vertex left of the cut and the shoelace sum up to
    /// it.
    at: [usize; 2],
    sum: [f64; 2],
}

impl<'a> LeftOf<'a> {
    pub(super) fn new(texture: &'a [[f64; 2]], screen: &'a [[f64; 2]], total: f64) -> LeftOf<'a> {
        let Extent {
            first,
            x_min,
            x_max,
        } = Extent::of(texture);
        LeftOf {
            texture,
            screen,
            total,
            x_min,
            x_max,
            at: [first; 2],
            sum: [0.0; 2],
        }
    }

    /// The doubled signed screen area left of `x = cut` (see the type);
    /// `cut` no less than at the previous call.
    #[inline(always)]
    pub(super) fn area(&mut self, cut: f64, m: &Mat3, centre: [f64; 2]) -> f64 {
        if cut.is_nan() || cut <= self.x_min {
            return 0.0;
        }
        if cut >= self.x_max {
            return self.total;
        }
        let n = self.texture.len();
        let cross = |a: [f64; 2], b: [f64; 2]| a[0] * b[1] - a[1] * b[0];
        let mut crossing = [[0.0; 2]; 2];
        for (chain, point) in crossing.iter_mut().enumerate() {
            let step = |i: usize| chain_step(chain, i, n);
            let (mut i, mut next) = (self.at[chain], step(self.at[chain]));
            // The rightmost vertex lies past the cut: the loop stops there
            // at the latest.
            while self.texture[next][0] <= cut {
                let (a, b) = (self.screen[i], self.screen[next]);
                // The backward chain runs against the polygon's order.
                self.sum[chain] += if chain == 0 { cross(a, b) } else { cross(b, a) };
                (i, next) = (next, step(next));
            }
            self.at[chain] = i;
            let (a, b) = (self.texture[i], self.texture[next]);
            let u = (cut - a[0]) / (b[0] - a[0]);
            let q = apply(m, [cut, a[1] + u * (b[1] - a[1])]);
            *point = [q[0] - centre[0], q[1] - centre[1]];
        }
        let [forward, backward] = crossing;
        self.sum[0]
            + cross(self.screen[self.at[0]], forward)
            + cross(forward, backward)
            + cross(backward, self.screen[self.at[1]])
            + self.sum[1]
    }
}

/// [`LeftOf`]'s sweep for a pixel filter's weight: the Green's-theorem
/// terms ([`PixelFilter::edge_integral`]) of the part of a band left of a
/// cut `x = c`, for cuts taken in increasing order, so that a cell's
/// piece weighs what is left of its right side less what is left of its
/// left side. The part's boundary is [`LeftOf`]'s: each chain up to its
/// crossing of the cut, and the cut's chord between the two crossings.
/// An edge wholly left of the cut adds its whole term (`terms`, the
/// band's, edge `i` from vertex `i` to `i + 1`) once, as the cut passes
/// its far end; the edge a chain crosses adds its part left of the cut,
/// grown from the previous cut's crossing by the piece between the two
/// (short, so within few of the filter's cells: the edge is not
/// integrated again from its start at each cut); the chord is
/// integrated whole.
pub(super) struct WeightLeftOf<'a, E: EdgeTerms> {
    texture: &'a [[f64; 2]],
    screen: &'a [[f64; 2]],
    terms: &'a [E::Weight],
    /// The whole band's weight, for cuts past it.
    total: E::Weight,
    edges: &'a E,
    x_min: f64,
    x_max: f64,
    /// Per chain (0 forward, 1 backward from the leftmost vertex): the
    /// index of its last vertex left of the cut, the terms of its edges
    /// wholly left, its crossing of the previous cut on the edge it now
    /// crosses (`None` when that edge was not crossed before), and that
    /// edge's term up to the crossing.
    at: [usize; 2],
    sum: [E::Weight; 2],
    crossed: [Option<[f64; 2]>; 2],
    part: [E::Weight; 2],
}

impl<'a, E: EdgeTerms> WeightLeftOf<'a, E> {
    pub(super) fn new(
        (texture, screen): (&'a [[f64; 2]], &'a [[f64; 2]]),
        Extent {
            first,
            x_min,
            x_max,
        }: Extent,
        terms: &'a [E::Weight],
        total: E::Weight,
        edges: &'a E,
    ) -> WeightLeftOf<'a, E> {
        WeightLeftOf {
            texture,
            screen,
            terms,
            total,
            edges,
            x_min,
            x_max,
            at: [first; 2],
            sum: [E::Weight::default(); 2],
            crossed: [None; 2],
            part: [E::Weight::default(); 2],
        }
    }

    /// The weight of the band's part left of `x = cut`, times the band's
    /// orientation's sign (see the type); `cut` no less than at the
    /// previous call.
    #[inline(always)]
    pub(super) fn weight(&mut self, cut: f64, m: &Mat3, centre: [f64; 2]) -> E::Weight {
        if cut.is_nan() || cut <= self.x_min {
            return E::Weight::default();
        }
        if cut >= self.x_max {
            return self.total;
        }
        let n = self.texture.len();
        let mut crossing = [[0.0; 2]; 2];
        for (chain, point) in crossing.iter_mut().enumerate() {
            let step = |i: usize| chain_step(chain, i, n);
            let (mut i, mut next) = (self.at[chain], step(self.at[chain]));
            // The rightmost vertex lies past the cut: the loop stops there
            // at the latest.
            while self.texture[next][0] <= cut {
                // The backward chain's edge runs from `next` to `i`.
                self.sum[chain] = self.sum[chain] + self.terms[if chain == 0 { i } else { next }];
                (self.crossed[chain], self.part[chain]) = (None, E::Weight::default());
                (i, next) = (next, step(next));
            }
            self.at[chain] = i;
            let (a, b) = (self.texture[i], self.texture[next]);
            let u = (cut - a[0]) / (b[0] - a[0]);
            let q = apply(m, [cut, a[1] + u * (b[1] - a[1])]);
            *point = [q[0] - centre[0], q[1] - centre[1]];
            let from = self.crossed[chain].unwrap_or(self.screen[i]);
            self.part[chain] = self.part[chain]
                + if chain == 0 {
                    self.edges.edge(from, *point)
                } else {
                    self.edges.edge(*point, from)
                };
            self.crossed[chain] = Some(*point);
        }
        let [forward, backward] = crossing;
        self.sum[0] + self.part[0] + self.edges.edge(forward, backward) + self.part[1] + self.sum[1]
    }
}

/// The doubled signed screen area of the part of a texture-space convex
/// polygon with `x <= x_cut`: Sutherland–Hodgman against one half-plane,
/// the clipped vertices fed straight into the shoelace sum. `screen` holds
/// the vertices as [`band_to_screen`] mapped them. The slow reference
/// [`LeftOf`] is tested against.
#[cfg(test)]
pub(super) fn band_left_of(
    texture: &[[f64; 2]],
    screen: &[[f64; 2]],
    x_cut: f64,
    m: &Mat3,
    centre: [f64; 2],
) -> f64 {
    let n = texture.len();
    let mut sum = 0.0;
    let mut first: Option<[f64; 2]> = None;
    let mut last = [0.0; 2];
    let mut emit = |q: [f64; 2]| {
        match first {
            None => first = Some(q),
            Some(_) => sum += last[0] * q[1] - last[1] * q[0],
        }
        last = q;
    };
    let crossing = |a: [f64; 2], b: [f64; 2]| {
        let u = (x_cut - a[0]) / (b[0] - a[0]);
        let q = apply(m, [x_cut, a[1] + u * (b[1] - a[1])]);
        [q[0] - centre[0], q[1] - centre[1]]
    };
    let mut prev = n.wrapping_sub(1);
    for i in 0..n {
        let (prev_in, cur_in) = (texture[prev][0] <= x_cut, texture[i][0] <= x_cut);
        if cur_in {
            if !prev_in {
                emit(crossing(texture[prev], texture[i]));
            }
            emit(screen[i]);
        } else if prev_in {
            emit(crossing(texture[prev], texture[i]));
        }
        prev = i;
    }
    if let Some(f) = first {
        sum += last[0] * f[1] - last[1] * f[0];
    }
    sum
}

//! Shadow rays toward a directional light through a 2-D grid over the
//! light's view of a mesh, instead of its bounding-volume hierarchy.
//!
//! Every shadow ray toward the sun has the same direction `L`, so seen
//! along `L` it is one point: the triangles it can cross are those whose
//! projection onto the plane ⟂ `L` holds the projection of its origin. The
//! grid bins each triangle by its projected box (widened by a relative
//! `10⁻⁹` so that rounding of either projection cannot lose one); a query
//! tests the triangles of one cell with the mesh's own ray–triangle test
//! ([`Mesh::crosses_beyond`]), so the answer is the hierarchy's. Triangles
//! whose box spans more than [`MAX_CELLS_PER_TRIANGLE`] cells are tested by
//! every query instead.
//!
//! **Triangles no other one can shade.** The first time a shadow ray
//! leaves a triangle, the grid decides once whether any other triangle of
//! the mesh can lie between a point of it and the sun
//! ([`SunGrid::unshadowed`]); where none can, rays leaving it skip the
//! mesh. On the generated 1 M-triangle terrain every triangle is clear at
//! its sun, and its frame's images are unchanged to the byte.

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex, OnceLock, PoisonError, Weak};

use quadtex_core::ConvexPolygon;
use rayon::prelude::*;

use crate::math::{Ray, Vec3};
use crate::scene::Mesh;

/// States of a triangle's [`SunGrid::unshadowed`] answer.
const UNKNOWN: u8 = 0;
const CLEAR: u8 = 1;
const SHADED: u8 = 2;

/// Meshes with fewer triangles than this keep to the hierarchy.
pub(crate) const MIN_TRIANGLES: usize = 4096;

/// Cells per triangle the grid aims at (cells = this × triangles, within
/// [`MAX_CELLS`]). On the 1 M-triangle terrain: 0.25, 0.5, 1 and 2 build in
/// 56, 64, 77 and 108 ms; 1 gave the fastest frame.
const CELLS_PER_TRIANGLE: f64 = 1.0;

/// Most cells a grid has (16 MiB of cell starts).
const MAX_CELLS: usize = 1 << 22;

/// A triangle spanning more cells goes to the list every query tests.
const MAX_CELLS_PER_TRIANGLE: u64 = 64;

/// A mesh whose triangles fill more cell slots than this per triangle (4
/// bytes each), or have more than [`MAX_LARGE`] in the list every query
/// tests, keeps to the hierarchy: the grid stays within 41 bytes a
/// triangle (cell starts, slots, each triangle's depth and whether it is
/// unshadowed), besides 16
/// bytes a triangle while it is built. The 1 M-triangle terrain fills 6.1
/// slots a triangle.
const MAX_ITEMS_PER_TRIANGLE: u64 = 8;

/// Most triangles every query tests (see [`MAX_ITEMS_PER_TRIANGLE`]).
const MAX_LARGE: usize = 64;

/// Slots of the table in which `SunGrid::clear_of_mesh` remembers the
/// triangles it has tested (by a hash of the index, one a slot: a triangle
/// whose slot another took is tested again when met again). A triangle's
/// box spans a few cells, and so do its neighbours': on the 1 M-triangle
/// terrain a classification meets 47 candidates, 20 of them distinct.
const SEEN_SLOTS: usize = 64;
// The slot is the hash's top bits: a power of two, at most 2³².
const _: () =
    assert!(SEEN_SLOTS.is_power_of_two() && SEEN_SLOTS >= 2 && SEEN_SLOTS.trailing_zeros() < 32);

/// The grid of `mesh` along `direction`, built once per process for each
/// mesh and direction (a camera path renders the same scene many times,
/// as its hierarchy is built once at load); `None` as [`SunGrid::build`].
pub(crate) fn shared(mesh: &Arc<Mesh>, direction: Vec3) -> Option<Arc<SunGrid>> {
    type Entry = (Weak<Mesh>, Vec3, Option<Arc<SunGrid>>);
    static CACHE: OnceLock<Mutex<Vec<Entry>>> = OnceLock::new();
    let cache = CACHE.get_or_init(Mutex::default);
    // A poisoned lock only means another thread panicked mid-insert; the
    // list itself is still a valid cache.
    let mut entries = cache.lock().unwrap_or_else(PoisonError::into_inner);
    // Dropped meshes' grids go (a live `Weak` keeps its address unique).
    entries.retain(|(m, _, _)| m.strong_count() > 0);
    if let Some((_, _, grid)) = (entries.iter())
        .find(|(m, d, _)| std::ptr::eq(m.as_ptr(), Arc::as_ptr(mesh)) && *d == direction)
    {
        return grid.clone();
    }
    let grid = SunGrid::build(mesh, direction).map(Arc::new);
    entries.push((Arc::downgrade(mesh), direction, grid.clone()));
    grid
}

/// A mesh's triangles binned by their projection along one light direction.
#[derive(Debug)]
pub(crate) struct SunGrid {
    /// The light direction served; other rays use the hierarchy.
    direction: Vec3,
    /// Orthonormal axes of the plane ⟂ `direction`.
    axes: [Vec3; 2],
    /// The grid's lower corner and cells per unit, per axis.
    origin: [f64; 2],
    scale: [f64; 2],
    dims: [usize; 2],
    /// Cell `c`'s triangles: `items[starts[c]..starts[c + 1]]`.
    starts: Vec<u32>,
    items: Vec<u32>,
    /// Triangles every query tests.
    large: Vec<u32>,
    /// Per triangle, its vertices' greatest depth along `direction`
    /// (`p · direction`), rounded up to `f32`. Each cell's triangles are
    /// sorted by it, deepest first: a shadow ray from depth `d` can only
    /// meet a triangle reaching beyond `d`, so a cell's test stops at the
    /// first triangle that does not.
    tops: Vec<f32>,
    /// Per triangle, whether no other triangle of the mesh can lie between
    /// a point of it and the sun ([`SunGrid::unshadowed`]): [`UNKNOWN`]
    /// until a shadow ray asks.
    unshadowed: Vec<AtomicU8>,
}

impl SunGrid {
    /// The grid of `mesh` seen along `direction` (unit); `None` when the
    /// mesh is small or its projection is degenerate.
    pub fn build(mesh: &Mesh, direction: Vec3) -> Option<SunGrid> {
        if mesh.len() < MIN_TRIANGLES || mesh.len() > u32::MAX as usize {
            return None;
        }
        let helper = if direction.x.abs() < 0.9 {
            Vec3::new(1.0, 0.0, 0.0)
        } else {
            Vec3::new(0.0, 1.0, 0.0)
        };
        let a = direction.cross(helper).normalized()?;
        let b = direction.cross(a).normalized()?;
        let box_of = |t: usize| projected_box(mesh, [a, b], t);
        let (lo, hi) = (0..mesh.len())
            .into_par_iter()
            .filter_map(box_of)
            .map(|b| ([b[0], b[1]], [b[2], b[3]]))
            .reduce(
                || ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
                |(l0, h0), (l1, h1)| {
                    (
                        [l0[0].min(l1[0]), l0[1].min(l1[1])],
                        [h0[0].max(h1[0]), h0[1].max(h1[1])],
                    )
                },
            );
        let size = [hi[0] - lo[0], hi[1] - lo[1]];
        if !(size[0] > 0.0 && size[1] > 0.0 && size.iter().all(|s| s.is_finite())) {
            return None;
        }
        let mut cells = (CELLS_PER_TRIANGLE * mesh.len() as f64).min(MAX_CELLS as f64);
        // Coarser cells, up to twice, when the triangles fill too many.
        for _ in 0..3 {
            if let Some(grid) = Self::binned(mesh, direction, [a, b], (lo, size), cells, &box_of) {
                return Some(grid);
            }
            cells /= 4.0;
        }
        None
    }

    /// The grid of about `cells` cells over the projected box `(lo,
    /// size)`, or `None` when its triangles fill more than
    /// [`MAX_ITEMS_PER_TRIANGLE`] slots a triangle or [`MAX_LARGE`] span
    /// too many cells.
    fn binned(
        mesh: &Mesh,
        direction: Vec3,
        [a, b]: [Vec3; 2],
        (lo, size): ([f64; 2], [f64; 2]),
        cells: f64,
        box_of: &(impl Fn(usize) -> Option<[f64; 4]> + Sync),
    ) -> Option<SunGrid> {
        let cells = cells.max(1.0);
        let nx = ((cells * size[0] / size[1]).sqrt().ceil()).clamp(1.0, cells) as usize;
        let ny = ((cells / nx as f64).ceil()).max(1.0) as usize;
        let scale = [nx as f64 / size[0], ny as f64 / size[1]];
        let mut grid = SunGrid {
            direction,
            axes: [a, b],
            origin: lo,
            scale,
            dims: [nx, ny],
            starts: vec![0; nx * ny + 1],
            items: Vec::new(),
            large: Vec::new(),
            tops: Vec::new(),
            unshadowed: Vec::new(),
        };
        // Each triangle's cells, `[x0, y0, x1, y1]`; `x0 = u32::MAX`: none.
        let ranges: Vec<[u32; 4]> = (0..mesh.len())
            .into_par_iter()
            .map(|t| match box_of(t) {
                Some(b) => {
                    let [x0, y0] = grid.cell([b[0], b[1]]);
                    let [x1, y1] = grid.cell([b[2], b[3]]);
                    [x0, y0, x1, y1].map(|v| v as u32)
                }
                None => [u32::MAX; 4],
            })
            .collect();
        let span = |r: &[u32; 4]| u64::from(r[2] - r[0] + 1) * u64::from(r[3] - r[1] + 1);
        let mut items = 0u64;
        for (t, r) in ranges.iter().enumerate() {
            if r[0] == u32::MAX {
                continue;
            }
            if span(r) > MAX_CELLS_PER_TRIANGLE {
                grid.large.push(t as u32);
                continue;
            }
            items += span(r);
            for y in r[1] as usize..=r[3] as usize {
                for x in r[0] as usize..=r[2] as usize {
                    grid.starts[y * nx + x + 1] += 1;
                }
            }
        }
        if items > MAX_ITEMS_PER_TRIANGLE * mesh.len() as u64 || grid.large.len() > MAX_LARGE {
            return None;
        }
        for c in 0..nx * ny {
            grid.starts[c + 1] += grid.starts[c];
        }
        let mut fill: Vec<u32> = grid.starts[..nx * ny].to_vec();
        grid.items = vec![0; grid.starts[nx * ny] as usize];
        for (t, r) in ranges.iter().enumerate() {
            if r[0] == u32::MAX || span(r) > MAX_CELLS_PER_TRIANGLE {
                continue;
            }
            for y in r[1] as usize..=r[3] as usize {
                for x in r[0] as usize..=r[2] as usize {
                    let slot = &mut fill[y * nx + x];
                    grid.items[*slot as usize] = t as u32;
                    *slot += 1;
                }
            }
        }
        grid.tops = (0..mesh.len())
            .into_par_iter()
            .map(|t| {
                let top = mesh.corners(t).map_or(f64::INFINITY, |c| {
                    c.iter()
                        .map(|p| p.dot(direction))
                        .fold(f64::NEG_INFINITY, f64::max)
                });
                // Rounded up: the test below must never skip a triangle
                // that reaches the ray.
                let rounded = top as f32;
                if f64::from(rounded) < top {
                    rounded.next_up()
                } else {
                    rounded
                }
            })
            .collect();
        // Each cell's triangles deepest first, cells in parallel chunks.
        let mut chunks = Vec::new();
        let mut rest: &mut [u32] = &mut grid.items;
        let cells_per_chunk = (nx * ny).div_ceil(64).max(1);
        for c0 in (0..nx * ny).step_by(cells_per_chunk) {
            let c1 = (c0 + cells_per_chunk).min(nx * ny);
            let len = (grid.starts[c1] - grid.starts[c0]) as usize;
            let (chunk, tail) = rest.split_at_mut(len);
            rest = tail;
            chunks.push((c0, c1, chunk));
        }
        let (starts, tops) = (&grid.starts, &grid.tops);
        chunks.into_par_iter().for_each(|(c0, c1, chunk)| {
            let base = starts[c0];
            for c in c0..c1 {
                let (s, e) = ((starts[c] - base) as usize, (starts[c + 1] - base) as usize);
                chunk[s..e]
                    .sort_unstable_by(|&a, &b| tops[b as usize].total_cmp(&tops[a as usize]));
            }
        });
        grid.unshadowed = (0..mesh.len()).map(|_| AtomicU8::new(UNKNOWN)).collect();
        Some(grid)
    }

    /// Whether no other triangle of `mesh` can lie between a point of
    /// triangle `t` and the sun: each one binned in the cells of `t`'s box
    /// (`box_of`) that reaches deeper along the sun than `t`'s lowest
    /// vertex, and each in the list every query tests, lies behind `t`'s
    /// plane as the sun sees it, or its projection along the sun is apart
    /// from `t`'s. Conservative: false whenever that is not shown. Within a
    /// relative `10⁻⁹` (rounding of the corners, which neighbours do not
    /// share bit for bit) a vertex counts as on the plane or the line; a
    /// shadow ray's own lift off its surface is a thousand times that.
    fn clear_of_mesh(&self, mesh: &Mesh, t: usize) -> bool {
        let project = |p: Vec3| [p.dot(self.axes[0]), p.dot(self.axes[1])];
        let Some(c) = mesh.corners(t) else {
            return false;
        };
        let own = c.map(project);
        let own_box = bounds(&own);
        let Some(b) = padded(own_box) else {
            return false;
        };
        let l = self.direction;
        let normal = (c[1] - c[0]).cross(c[2] - c[0]);
        let facing = normal.dot(l);
        // Edge-on to the sun (or not finite): never lit, so never asked.
        if facing == 0.0 || !facing.is_finite() {
            return false;
        }
        let Some(toward) = (normal * facing.signum()).normalized() else {
            return false;
        };
        let scale = c
            .iter()
            .fold(1f64, |m, p| m.max(p.x.abs()).max(p.y.abs()).max(p.z.abs()));
        let tolerance = 1e-9 * scale;
        // Each candidate is tested against the same edge lines and depths
        // of `t`: built once, not per candidate (its outline polygon only
        // for the few whose projections overlap it).
        let mine_lines = triangle_lines(&own);
        let depths = |p: &[Vec3; 3]| p.map(|v| v.dot(l));
        let mine = Affine::new(&own, depths(&c));
        let bottom = c.iter().map(|p| p.dot(l)).fold(f64::INFINITY, f64::min);
        let floor = bottom - 1e-9 * (bottom.abs() + 1.0);
        // A triangle binned in several cells of `t`'s box is met in each;
        // the ones met are remembered (`SEEN_SLOTS`), so each is mostly
        // fetched and tested once. The answer does not change: a repeat
        // would give the same `false` (a `true` ends the search).
        let mut seen_before = [u32::MAX; SEEN_SLOTS];
        let mut first_meeting = |a: u32| {
            // Fibonacci hashing: neighbouring indices spread over the slots.
            let slot = (a.wrapping_mul(0x9E37_79B9) >> (32 - SEEN_SLOTS.trailing_zeros())) as usize;
            let first = a as usize != t && seen_before[slot] != a;
            seen_before[slot] = a;
            first
        };
        let may_shade = |a: u32| {
            let Some(other) = mesh.corners(a as usize) else {
                return true;
            };
            let behind = other.iter().all(|&p| (p - c[0]).dot(toward) <= tolerance);
            if behind {
                return false;
            }
            let seen = other.map(project);
            // Boxes apart by more than the tolerance: the projections are
            // too (the outline test below would find an edge that shows it).
            let their_box = bounds(&seen);
            if (0..2).any(|k| {
                their_box[0][k] > own_box[1][k] + tolerance
                    || their_box[1][k] < own_box[0][k] - tolerance
            }) {
                return false;
            }
            // The other's lines only where the lit triangle's do not part
            // them (either side's lines parting them shows it).
            if mine_lines
                .as_ref()
                .is_some_and(|mine| beyond(mine, &seen, -tolerance))
                || triangle_lines(&seen).is_some_and(|theirs| beyond(&theirs, &own, -tolerance))
            {
                return false;
            }
            // After the tests on numbers at hand: this one reads the
            // neighbours of `a`, most often a cache miss (on the 1 M-triangle
            // terrain the box and the lines settle 11.5 of the 22 candidates
            // a triangle tests, a shared edge 1.7; all of them at load
            // 0.333 → 0.310 s with it last). Any order gives the same answer.
            if across_shared_edge(mesh, (t as u32, &own), (a, &seen), tolerance) {
                return false;
            }
            // Where the projections overlap, is the other ever nearer the
            // sun? Both depths are affine there, so its corners decide.
            match (mine.as_ref(), Affine::new(&seen, depths(&other))) {
                (Some(mine), Some(theirs)) => {
                    nearer_where_overlapping((&own, mine), (&seen, &theirs), tolerance)
                }
                _ => true,
            }
        };
        if self.large.iter().any(|&a| first_meeting(a) && may_shade(a)) {
            return false;
        }
        let [x0, y0] = self.cell([b[0], b[1]]);
        let [x1, y1] = self.cell([b[2], b[3]]);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let cell = y * self.dims[0] + x;
                let (s, e) = (self.starts[cell] as usize, self.starts[cell + 1] as usize);
                for &a in &self.items[s..e] {
                    // Deepest first: the rest lie wholly below `t`.
                    if f64::from(self.tops[a as usize]) < floor {
                        break;
                    }
                    if first_meeting(a) && may_shade(a) {
                        return false;
                    }
                }
            }
        }
        true
    }

    /// Whether no other triangle of `mesh` (the grid's) can lie between a
    /// point of triangle `t` and the sun, so that a shadow ray leaving it
    /// need not test the mesh: shown the first time a ray asks for `t`
    /// (`clear_of_mesh`) and kept, so a frame pays only for the triangles
    /// it lights. The answer is the one for points on the triangle; a ray
    /// lifted off it (by `10⁻⁶` of its distance, [`crate::frame::lambert`])
    /// may differ only within that distance of an edge.
    pub fn unshadowed(&self, mesh: &Mesh, t: u32) -> bool {
        let Some(state) = self.unshadowed.get(t as usize) else {
            return false;
        };
        // Relaxed: threads that race compute the same answer.
        match state.load(Ordering::Relaxed) {
            CLEAR => true,
            SHADED => false,
            _ => {
                let clear = self.clear_of_mesh(mesh, t as usize);
                state.store(if clear { CLEAR } else { SHADED }, Ordering::Relaxed);
                clear
            }
        }
    }

    /// The cell holding projected point `q`, clamped into the grid
    /// (monotone in `q`, so a box's cells hold every point inside it).
    fn cell(&self, q: [f64; 2]) -> [usize; 2] {
        [0, 1].map(|k| {
            let c = ((q[k] - self.origin[k]) * self.scale[k]).floor();
            c.clamp(0.0, (self.dims[k] - 1) as f64) as usize
        })
    }

    /// Whether this grid answers rays along `direction`.
    pub fn serves(&self, direction: Vec3) -> bool {
        self.direction == direction
    }

    /// Whether `ray` (along this grid's direction) crosses a triangle of
    /// `mesh` beyond `t_min`: [`Mesh::occludes`]'s answer.
    pub fn occludes(&self, mesh: &Mesh, ray: &Ray, t_min: f64) -> bool {
        let hits = |t: &u32| mesh.crosses_beyond(*t, ray, t_min);
        if self.large.iter().any(hits) {
            return true;
        }
        let q = [ray.origin.dot(self.axes[0]), ray.origin.dot(self.axes[1])];
        let inside = (0..2).all(|k| {
            let c = (q[k] - self.origin[k]) * self.scale[k];
            c >= 0.0 && c <= self.dims[k] as f64
        });
        if !inside {
            return false;
        }
        let [x, y] = self.cell(q);
        let c = y * self.dims[0] + x;
        let (s, e) = (self.starts[c] as usize, self.starts[c + 1] as usize);
        // A hit beyond `t_min ≥ 0` lies deeper than the origin (the
        // direction is a unit vector); the margin is many times the
        // rounding of the depths and of the crossing's `t`.
        let depth = ray.origin.dot(self.direction);
        let floor = depth - 1e-9 * (depth.abs() + 1.0);
        for t in &self.items[s..e] {
            if t_min >= 0.0 && f64::from(self.tops[*t as usize]) < floor {
                return false;
            }
            if hits(t) {
                return true;
            }
        }
        false
    }
}

/// Whether triangles `t` and `a` of `mesh` share an edge (are neighbours
/// across it, [`Mesh::neighbour`], and their shared corners' projections
/// `own` and `seen` agree within `tolerance`) with their third corners'
/// projections on either side of its line by more than `tolerance` (times
/// the edge's length): their projections then meet only along that edge,
/// so neither lies between the other's inside and the sun. On a terrain
/// this settles most of a triangle's neighbours without building their
/// outlines. The edge is found by the vertex ids the mesh was built with;
/// each triangle's corners are rebuilt from its own first corner and
/// edges, which round with that corner's magnitude, so where the two
/// rebuilt edges part by more than `tolerance` (a far first corner) this
/// says no and the caller's full test decides.
fn across_shared_edge(
    mesh: &Mesh,
    (t, own): (u32, &[[f64; 2]; 3]),
    (a, seen): (u32, &[[f64; 2]; 3]),
    tolerance: f64,
) -> bool {
    // Edge `e` faces corner `FACING[e]` and joins the other two
    // ([`Mesh::neighbour`]'s numbering).
    const FACING: [usize; 3] = [1, 2, 0];
    let across = |from: u32, to: u32| (0..3).find(|&e| mesh.neighbour(from, e) == Some(to));
    let (Some(mine), Some(theirs)) = (across(t, a), across(a, t)) else {
        return false;
    };
    let k = FACING[mine];
    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
    let r = FACING[theirs];
    let near = |x: [f64; 2], y: [f64; 2]| (x[0] - y[0]).abs().max((x[1] - y[1]).abs()) <= tolerance;
    let (ri, rj) = (seen[(r + 1) % 3], seen[(r + 2) % 3]);
    if !((near(ri, own[i]) && near(rj, own[j])) || (near(ri, own[j]) && near(rj, own[i]))) {
        return false;
    }
    let (p, q) = (own[i], own[j]);
    let edge = [q[0] - p[0], q[1] - p[1]];
    let side = |x: [f64; 2]| edge[0] * (x[1] - p[1]) - edge[1] * (x[0] - p[0]);
    let margin = tolerance * edge[0].hypot(edge[1]);
    let (s_mine, s_theirs) = (side(own[k]), side(seen[r]));
    (s_mine > margin && s_theirs < -margin) || (s_mine < -margin && s_theirs > margin)
}

/// Triangle `t`'s box projected on `axes` (across the sun), widened by a
/// relative `10⁻⁹` against rounding; `None` when not finite.
fn projected_box(mesh: &Mesh, axes: [Vec3; 2], t: usize) -> Option<[f64; 4]> {
    let corners = mesh.corners(t)?;
    padded(bounds(&corners.map(|p| [p.dot(axes[0]), p.dot(axes[1])])))
}

/// The box `[lo, hi]` widened by a relative `10⁻⁹` against rounding, as
/// `[x0, y0, x1, y1]`; `None` when not finite.
fn padded([lo, hi]: [[f64; 2]; 2]) -> Option<[f64; 4]> {
    let slack = |l: f64, h: f64| 1e-9 * (l.abs().max(h.abs()) + (h - l));
    let (sx, sy) = (slack(lo[0], hi[0]), slack(lo[1], hi[1]));
    let b = [lo[0] - sx, lo[1] - sy, hi[0] + sx, hi[1] + sy];
    b.iter().all(|v| v.is_finite()).then_some(b)
}

/// The lower and upper corners of the box around projected points.
fn bounds(points: &[[f64; 2]; 3]) -> [[f64; 2]; 2] {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in points {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    [lo, hi]
}

/// Whether, where projected triangles `own` and `seen` overlap, the depth
/// along the sun of the second (`theirs`) exceeds the first's (`mine`) by
/// more than `tolerance` anywhere: both are affine there, so the overlap's
/// corners decide. Apart from `SunGrid::clear_of_mesh`'s other tests, which
/// settle most candidates without it (and keep its polygons off their
/// stack).
#[inline(never)]
fn nearer_where_overlapping(
    (own, mine): (&[[f64; 2]; 3], &Affine),
    (seen, theirs): (&[[f64; 2]; 3], &Affine),
    tolerance: f64,
) -> bool {
    (ConvexPolygon::hull(own).intersect(&ConvexPolygon::hull(seen)))
        .vertices()
        .iter()
        .any(|&q| theirs.at(q) - mine.at(q) > tolerance)
}

/// A depth along the sun, affine over a projected triangle (from its
/// corners' depths).
struct Affine {
    origin: [f64; 2],
    base: f64,
    gradient: [f64; 2],
}

impl Affine {
    /// `None` when the projected triangle is too thin for its depths to be
    /// interpolated (seen nearly edge-on from the sun).
    fn new(q: &[[f64; 2]; 3], d: [f64; 3]) -> Option<Affine> {
        let (e1, e2) = (
            [q[1][0] - q[0][0], q[1][1] - q[0][1]],
            [q[2][0] - q[0][0], q[2][1] - q[0][1]],
        );
        let det = e1[0] * e2[1] - e1[1] * e2[0];
        let size = e1[0].hypot(e1[1]) * e2[0].hypot(e2[1]);
        if det.abs() <= 1e-6 * size || !det.is_finite() {
            return None;
        }
        let (d1, d2) = (d[1] - d[0], d[2] - d[0]);
        // Barycentric b1 = (x·e2.y − y·e2.x)/det, b2 = (e1.x·y − e1.y·x)/det.
        let gradient = [
            (d1 * e2[1] - d2 * e1[1]) / det,
            (d2 * e1[0] - d1 * e2[0]) / det,
        ];
        Some(Affine {
            origin: q[0],
            base: d[0],
            gradient,
        })
    }

    fn at(&self, q: [f64; 2]) -> f64 {
        self.base
            + self.gradient[0] * (q[0] - self.origin[0])
            + self.gradient[1] * (q[1] - self.origin[1])
    }
}

/// A projected triangle's edge lines `[a, b, c, |(a, b)|]`, `a·x + b·y + c`
/// positive inside, as [`ConvexPolygon::hull`] then
/// [`ConvexPolygon::edge_lines`] give them but for the vertices' order
/// (the shadow test takes millions a frame: no polygon built); `None`
/// when its corners are collinear (the hull has no inside).
fn triangle_lines(p: &[[f64; 2]; 3]) -> Option<[[f64; 4]; 3]> {
    let turn =
        (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[1][1] - p[0][1]) * (p[2][0] - p[0][0]);
    let [a, b, c] = if turn > 0.0 {
        [p[0], p[1], p[2]]
    } else if turn < 0.0 {
        [p[0], p[2], p[1]]
    } else {
        return None;
    };
    Some([(a, b), (b, c), (c, a)].map(|(u, v)| {
        let (nx, ny) = (-(v[1] - u[1]), v[0] - u[0]);
        [nx, ny, -(nx * u[0] + ny * u[1]), (nx * nx + ny * ny).sqrt()]
    }))
}

/// Whether one of a triangle's `lines` ([`triangle_lines`]) has every
/// point of `q` beyond it by more than `margin`: [`apart`]'s test from
/// one side.
fn beyond(lines: &[[f64; 4]; 3], q: &[[f64; 2]; 3], margin: f64) -> bool {
    (lines.iter()).any(|&[l0, l1, l2, norm]| wholly_beyond([l0, l1, l2], norm, q, margin))
}

/// Whether every point of `q` lies beyond line `a·x + b·y + c = 0` (whose
/// normal `(a, b)` has length `norm`, pointing inside) by more than
/// `margin`.
fn wholly_beyond([l0, l1, l2]: [f64; 3], norm: f64, q: &[[f64; 2]], margin: f64) -> bool {
    let limit = -margin * norm;
    // An overflowing norm (edges past 10¹⁵⁴) would make every point
    // beyond a negative margin's line: never apart then.
    norm > 0.0 && norm.is_finite() && q.iter().all(|&[x, y]| l0 * x + l1 * y + l2 < limit)
}

/// Whether an edge line of one of two convex polygons has the other
/// wholly beyond it by more than `margin` (unit-normalised lines; a
/// negative margin counts what lies within `−margin` inside as beyond).
pub(crate) fn apart(a: &ConvexPolygon, b: &ConvexPolygon, margin: f64) -> bool {
    let beyond = |p: &ConvexPolygon, q: &ConvexPolygon| {
        p.edge_lines().any(|[l0, l1, l2]| {
            // Not `hypot`: it was a fifth of this test's cost, and an
            // overflow is refused.
            let norm = (l0 * l0 + l1 * l1).sqrt();
            wholly_beyond([l0, l1, l2], norm, q.vertices(), margin)
        })
    };
    !a.is_empty() && !b.is_empty() && (beyond(a, b) || beyond(b, a))
}

#[cfg(test)]
mod tests;

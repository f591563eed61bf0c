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

use std::sync::{Arc, Mutex, OnceLock, PoisonError, Weak};

use rayon::prelude::*;

use crate::math::{Ray, Vec3};
use crate::scene::Mesh;

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
/// tests, keeps to the hierarchy: the grid stays within 40 bytes a
/// triangle (cell starts, slots and each triangle's depth), besides 16
/// bytes a triangle while it is built. The 1 M-triangle terrain fills 6.1
/// slots a triangle.
const MAX_ITEMS_PER_TRIANGLE: u64 = 8;

/// Most triangles every query tests (see [`MAX_ITEMS_PER_TRIANGLE`]).
const MAX_LARGE: usize = 64;

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
        let project = |p: Vec3| [p.dot(a), p.dot(b)];
        // Each triangle's projected box, widened against rounding.
        let box_of = |t: usize| {
            let corners = mesh.corners(t)?;
            let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
            for p in corners {
                let q = project(p);
                for k in 0..2 {
                    lo[k] = lo[k].min(q[k]);
                    hi[k] = hi[k].max(q[k]);
                }
            }
            let slack = |l: f64, h: f64| 1e-9 * (l.abs().max(h.abs()) + (h - l));
            let (sx, sy) = (slack(lo[0], hi[0]), slack(lo[1], hi[1]));
            let b = [lo[0] - sx, lo[1] - sy, hi[0] + sx, hi[1] + sy];
            b.iter().all(|v| v.is_finite()).then_some(b)
        };
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
        Some(grid)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Triangle;

    /// A bumpy heightfield of `n × n` cells (two triangles each) and a few
    /// large loose triangles floating over it.
    fn terrain(n: usize) -> Mesh {
        let h = |i: usize, j: usize| {
            let (x, z) = (i as f64, j as f64);
            2.0 * (0.3 * x).sin() * (0.23 * z).cos() + 0.3 * ((i * 7 + j * 3) % 5) as f64
        };
        let p = |i: usize, j: usize| Vec3::new(i as f64, h(i, j), j as f64);
        let mut triangles = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let uv = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
                triangles.extend(Triangle::new([p(i, j), p(i + 1, j), p(i + 1, j + 1)], uv));
                triangles.extend(Triangle::new([p(i, j), p(i + 1, j + 1), p(i, j + 1)], uv));
            }
        }
        for k in 0..3 {
            let o = Vec3::new(5.0 + 10.0 * k as f64, 6.0, 8.0);
            triangles.extend(Triangle::new(
                [
                    o,
                    o + Vec3::new(30.0, 1.0, 2.0),
                    o + Vec3::new(3.0, 0.5, 25.0),
                ],
                [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
            ));
        }
        Mesh::new(triangles).unwrap()
    }

    /// Shadow rays from random points on and above the terrain, from under
    /// its vertices (with a sun straight up, along its edges) and from
    /// beside it: the grid's answer is every triangle's and the
    /// hierarchy's, for low and high suns, and both answers occur.
    #[test]
    fn the_grid_answers_as_the_hierarchy() {
        let mesh = terrain(48);
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut rnd = |lo: f64, hi: f64| crate::math::test_uniform(&mut state, lo, hi);
        for sun in [
            Vec3::new(-0.8, 0.5, 0.55),
            Vec3::new(0.2, 0.1, -1.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 0.02, 0.0),
        ] {
            let direction = sun.normalized().unwrap();
            let grid = SunGrid::build(&mesh, direction).unwrap();
            let (mut shadowed, mut lit) = (0, 0);
            for k in 0..4000 {
                let origin = match k % 4 {
                    // Just behind a point of a triangle along the ray, so
                    // that the triangle itself is met a hair away (a
                    // shadow cast by the next bump): the cell's test must
                    // not stop before it.
                    3 => {
                        let t = rnd(0.0, mesh.len() as f64).floor() as usize;
                        let [a, b, c] = mesh.corners(t).unwrap();
                        let (u, v) = (rnd(0.0, 1.0), rnd(0.0, 1.0));
                        let (u, v) = if u + v > 1.0 {
                            (1.0 - u, 1.0 - v)
                        } else {
                            (u, v)
                        };
                        let p = a + (b - a) * u + (c - a) * v;
                        p - direction * [1e-6, 1e-3, 0.05][k % 3]
                    }
                    // On a vertex of the heightfield (rays along edges).
                    0 => {
                        let (i, j) = (rnd(0.0, 48.0).floor(), rnd(0.0, 48.0).floor());
                        Vec3::new(i, rnd(-3.0, 3.0), j)
                    }
                    1 => Vec3::new(rnd(-10.0, 58.0), rnd(-3.0, 8.0), rnd(-10.0, 58.0)),
                    _ => Vec3::new(rnd(0.0, 48.0), rnd(-1.0, 2.0), rnd(0.0, 48.0)),
                };
                let ray = Ray { origin, direction };
                // The slow, obvious answer: every triangle tried.
                let expected = (0..mesh.len() as u32).any(|t| mesh.crosses_beyond(t, &ray, 1e-9));
                assert_eq!(mesh.occludes(&ray, 1e-9), expected, "hierarchy: {ray:?}");
                assert!(grid.serves(direction));
                assert_eq!(grid.occludes(&mesh, &ray, 1e-9), expected, "{ray:?}");
                if expected {
                    shadowed += 1;
                } else {
                    lit += 1;
                }
            }
            assert!(
                shadowed > 200 && lit > 200,
                "{shadowed} shadowed, {lit} lit"
            );
        }
    }

    #[test]
    fn small_meshes_and_other_directions_keep_to_the_hierarchy() {
        assert!(SunGrid::build(&terrain(8), Vec3::new(0.0, 1.0, 0.0)).is_none());
        let grid = SunGrid::build(&terrain(48), Vec3::new(0.0, 1.0, 0.0)).unwrap();
        assert!(!grid.serves(Vec3::new(0.0, 0.0, 1.0)));
    }

    #[test]
    fn a_mesh_and_direction_share_one_grid() {
        let mesh = Arc::new(terrain(48));
        let up = Vec3::new(0.0, 1.0, 0.0);
        let (a, b) = (shared(&mesh, up).unwrap(), shared(&mesh, up).unwrap());
        assert!(Arc::ptr_eq(&a, &b));
        let other = shared(&mesh, Vec3::new(1.0, 0.0, 0.0)).unwrap();
        assert!(!Arc::ptr_eq(&a, &other));
    }
}

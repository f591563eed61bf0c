//! A frame's mesh triangles binned by the screen tiles their projections
//! reach ([`ScreenBins`]), for the camera rays the exact pixel casts
//! through points between the centres (gaps, and the triangles a spread
//! lists): such a ray meets only triangles whose projection holds its
//! screen point, so it tests a tile's few triangles instead of walking the
//! meshes' hierarchies.

use crate::caster::Caster;
use crate::math::Ray;
use crate::scene::{Geometry, Hit, Mesh, Scene};

/// Screen distance (pixels) by which a triangle's projected box is widened
/// when it is binned, plus [`BIN_SLACK_REL`] of each coordinate's
/// magnitude: far above the rounding of the projection of its corners and
/// of the ray's crossing test (relative `10⁻¹⁵` or so).
const BIN_SLACK: f64 = 1e-3;

/// The relative part of [`BIN_SLACK`].
const BIN_SLACK_REL: f64 = 1e-9;

/// The most fine tiles (8 MiB of starts): the tiles grow past
/// [`FINE_TILE`] for images of more than about four million pixels.
const MAX_TILES: usize = 1 << 21;

/// A fine tile's side in pixels, across and down: wide and short, as the
/// triangles of a far terrain are on the screen.
const FINE_TILE: [f64; 2] = [2.0, 1.0];

/// A coarse tile's side in pixels, for triangles that reach more than
/// [`FINE_MAX`] fine tiles (those near the camera).
const COARSE_TILE: [f64; 2] = [32.0, 32.0];

/// The most fine tiles a triangle is binned to; a larger one goes to the
/// coarse tiles.
const FINE_MAX: usize = 64;

/// Coarse entries allowed per coarse tile, on average; past it (many
/// large triangles overlapping), no bins are built and rays walk the
/// hierarchies.
const COARSE_DEPTH: usize = 64;

/// A triangle to bin.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ScreenBox {
    pub surface: u32,
    pub triangle: u32,
    /// `[x0, y0, x1, y1]` (pixels): the projected corners' box, or a box
    /// known to hold what the triangle shows of the screen.
    pub screen: [f64; 4],
    /// A lower bound, at least 0, of the depth `(p − c)·forward` of its
    /// points (`c` the camera's position): the least of its corners'.
    pub near: f64,
}

/// Tiles over the screen from `origin` (both axes): tile `(tx, ty)` covers
/// `[origin + tx·sx, origin + (tx+1)·sx) × [origin + ty·sy, …)` (`side =
/// [sx, sy]`); tile `k = ty·tiles[0] + tx` lists `items[starts[k]..
/// starts[k + 1]]`.
#[derive(Debug, Default)]
struct Tiles {
    origin: f64,
    side: [f64; 2],
    tiles: [usize; 2],
    /// Per axis, whether tile numbers are exact (a power-of-two side, a
    /// whole origin: [`Tiles::reaching`]).
    exact: [bool; 2],
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl Tiles {
    fn new(origin: f64, side: [f64; 2], size: [usize; 2]) -> Tiles {
        let tiles = [0, 1].map(|a| ((size[a] as f64 / side[a]).ceil() as usize).max(1));
        Tiles {
            origin,
            side,
            tiles,
            exact: side.map(|s| s.log2().fract() == 0.0 && origin.fract() == 0.0),
            starts: vec![0; tiles[0] * tiles[1] + 1],
            items: Vec::new(),
        }
    }

    /// Where coordinate `v` lies along axis `a`, in tiles (a tile's own
    /// number at its lower side).
    fn tile_at(&self, v: f64, a: usize) -> f64 {
        (v - self.origin) / self.side[a]
    }

    /// The tiles box `b` touches, `((x0, x1), (y0, y1))` inclusive
    /// (clamped to the grid); `None` when it touches none.
    fn range(&self, b: &[f32; 4]) -> Option<((usize, usize), (usize, usize))> {
        let axis = |lo: f32, hi: f32, a: usize| {
            let last = self.tiles[a] as f64 - 1.0;
            let first = self.tile_at(f64::from(lo), a).floor().max(0.0);
            let end = self.tile_at(f64::from(hi), a).floor().min(last);
            (first <= end).then_some((first as usize, end as usize))
        };
        Some((axis(b[0], b[2], 0)?, axis(b[1], b[3], 1)?))
    }

    /// The tiles a query box `lo..hi` (inside the grid) may find a
    /// triangle in whose box meets it over more than a line
    /// ([`BoxQuery::meets`]), `((x0, x1), (y0, y1))` inclusive: those it
    /// touches, less a last column or row that only touches its right or
    /// bottom side (a one-pixel support on whole pixels would otherwise
    /// read the next row's tile and the next column's). A triangle's box
    /// that starts before the query's end is filed in a tile before it
    /// too where the sides are powers of two and the origin whole, as the
    /// frame's are (elsewhere, and on an axis where the box has no extent,
    /// the last tile stays), up to the rounding of `v − origin`: a box
    /// starting within about `10⁻¹⁵` of a side near the screen's origin
    /// may be filed past it, and its triangle, widened by
    /// [`BIN_SLACK`], then lies that far from the query and shows nothing
    /// in it.
    fn reaching(&self, lo: [f64; 2], hi: [f64; 2]) -> ((usize, usize), (usize, usize)) {
        let axis = |a: usize| {
            let last = self.tiles[a] - 1;
            let first = (self.tile_at(lo[a], a).floor().max(0.0) as usize).min(last);
            let end = self.tile_at(hi[a], a);
            let mut to = end.floor().max(0.0) as usize;
            if self.exact[a] && lo[a] < hi[a] && end.fract() == 0.0 {
                to = to.saturating_sub(1);
            }
            (first, to.clamp(first, last))
        };
        (axis(0), axis(1))
    }

    /// The first tile, `(x, y)`, of those box `b` touches (as
    /// [`Tiles::range`] gives them, where it gives any).
    fn first(&self, b: &[f32; 4]) -> (usize, usize) {
        let axis = |lo: f32, a: usize| self.tile_at(f64::from(lo), a).floor().max(0.0) as usize;
        (axis(b[0], 0), axis(b[1], 1))
    }

    /// The tile holding screen point `c`, if one does.
    fn holding(&self, c: [f64; 2]) -> Option<usize> {
        let tile = |v: f64, a: usize| {
            let t = self.tile_at(v, a).floor();
            (t >= 0.0 && t < self.tiles[a] as f64).then_some(t as usize)
        };
        Some(tile(c[1], 1)? * self.tiles[0] + tile(c[0], 0)?)
    }

    fn count(&mut self, ((x0, x1), (y0, y1)): ((usize, usize), (usize, usize))) {
        for ty in y0..=y1 {
            let row = ty * self.tiles[0];
            for c in &mut self.starts[row + x0..=row + x1] {
                *c += 1;
            }
        }
    }

    /// Turns the counts into starts, and sizes the items.
    fn prefix(&mut self) -> Vec<u32> {
        let mut sum = 0u32;
        for c in &mut self.starts {
            let n = *c;
            *c = sum;
            sum += n;
        }
        self.items = vec![0; sum as usize];
        self.starts.clone()
    }

    fn fill(
        &mut self,
        fill: &mut [u32],
        i: u32,
        ((x0, x1), (y0, y1)): ((usize, usize), (usize, usize)),
    ) {
        for ty in y0..=y1 {
            let row = ty * self.tiles[0];
            for next in &mut fill[row + x0..=row + x1] {
                self.items[*next as usize] = i;
                *next += 1;
            }
        }
    }

    fn at(&self, k: usize) -> &[u32] {
        &self.items[self.starts[k] as usize..self.starts[k + 1] as usize]
    }
}

/// Mesh triangles by screen tile: each triangle is listed in every tile
/// its box, widened by [`BIN_SLACK`], touches (fine tiles, or coarse ones
/// for a triangle past [`FINE_MAX`] fine tiles), each tile's list nearest
/// first by the triangles' least depth. Memory, stated: per
/// triangle the frame projects, 28 B and at most [`FINE_MAX`] fine
/// entries of 4 B; 4 B a tile; at most [`COARSE_DEPTH`] coarse entries a
/// coarse tile on average (25 MB in all for the 1 M-triangle terrain at
/// 1080p); while they are built, 6 B more a triangle and 256 KiB for the
/// depth sort. Built per frame, dropped with it. A camera ray through
/// screen point `c` can meet a triangle only where `c` lies in its
/// projection, inside its box: the nearest hit among the triangles of
/// `c`'s two tiles whose boxes hold `c` is the nearest among all a mesh
/// has ([`ScreenBins::nearest_through`]).
#[derive(Debug, Default)]
pub(crate) struct ScreenBins {
    fine: Tiles,
    coarse: Tiles,
    /// Each binned triangle, by increasing least depth (so every tile's
    /// list is too): surface, triangle, widened box (rounded outward to
    /// `f32`), and a lower bound of its least depth ([`ScreenBox::near`]
    /// lowered by [`NEAR_MARGIN`], rounded down to 8 significant bits).
    triangles: Vec<(u32, u32, [f32; 4], f32)>,
}

/// A screen box `lo..hi` inside the tiles ([`ScreenBins::query`]).
struct BoxQuery {
    lo: [f64; 2],
    hi: [f64; 2],
}

impl BoxQuery {
    /// Whether a binned (widened) box meets this one over more than a
    /// line (on an axis where this box has no extent, touching it is
    /// enough): a triangle whose box only touches a side has nothing of
    /// area inside, and its widened box holds its projection with room to
    /// spare (the tiles then need not read the row or column past the
    /// box's last side, [`Tiles::reaching`]).
    fn meets(&self, &[a0, b0, a1, b1]: &[f32; 4]) -> bool {
        let axis = |a0: f32, a1: f32, lo: f64, hi: f64| {
            let (a0, a1) = (f64::from(a0), f64::from(a1));
            if lo < hi {
                a1 > lo && a0 < hi
            } else {
                !(a1 < lo || a0 > hi)
            }
        };
        axis(a0, a1, self.lo[0], self.hi[0]) && axis(b0, b1, self.lo[1], self.hi[1])
    }
}

/// Relative margin by which a triangle's least depth is lowered before it
/// bounds the rays' hits ([`ScreenBins::nearest_through`]): far above the
/// rounding of the depths and of the crossings' `t`.
pub(crate) const NEAR_MARGIN: f64 = 1e-9;

impl ScreenBins {
    /// Bins `boxes` over the screen rectangle `[origin, origin + size)` on
    /// both axes (`size` in pixels, per axis). `None` when a box is not
    /// finite (a triangle reaching behind the camera with no known box),
    /// or the coarse tiles would hold more than [`COARSE_DEPTH`] entries
    /// each on average.
    pub(crate) fn build(boxes: &[ScreenBox], origin: f64, size: [usize; 2]) -> Option<ScreenBins> {
        let area = (size[0] as f64) * (size[1] as f64);
        let scale = (area / (FINE_TILE[0] * FINE_TILE[1] * MAX_TILES as f64))
            .sqrt()
            .ceil()
            .max(1.0);
        let mut fine = Tiles::new(origin, FINE_TILE.map(|s| s * scale), size);
        let mut coarse = Tiles::new(origin, COARSE_TILE.map(|s| s * scale), size);
        let widen = |v: f64, sign: f64| v + sign * (BIN_SLACK + BIN_SLACK_REL * v.abs());
        // Rounded outward: the f32 box holds the f64 one.
        let down = |v: f64| {
            let f = v as f32;
            if f64::from(f) > v { f.next_down() } else { f }
        };
        let up = |v: f64| {
            let f = v as f32;
            if f64::from(f) < v { f.next_up() } else { f }
        };
        // Nearest first, the order each tile lists its triangles in, by a
        // counting sort on the top 16 bits of each least depth's `f32`
        // (non-negative floats' bits are ordered as their values): the
        // depth kept is that key's, a lower bound within 1/128 of it.
        if boxes.len() > u32::MAX as usize {
            return None;
        }
        let mut keys = Vec::with_capacity(boxes.len());
        for b in boxes {
            if !(b.screen.iter().all(|v| v.is_finite()) && b.near >= 0.0) {
                return None;
            }
            let near = down(b.near * (1.0 - NEAR_MARGIN)).max(0.0);
            keys.push((near.to_bits() >> 16) as u16);
        }
        let mut starts = vec![0u32; 1 << 16];
        for &k in &keys {
            starts[usize::from(k)] += 1;
        }
        let mut sum = 0u32;
        for c in &mut starts {
            (*c, sum) = (sum, sum + *c);
        }
        let mut order = vec![0u32; boxes.len()];
        for (i, &k) in keys.iter().enumerate() {
            let at = &mut starts[usize::from(k)];
            order[*at as usize] = i as u32;
            *at += 1;
        }
        let mut triangles = Vec::with_capacity(boxes.len());
        for i in order {
            let (b, key) = (&boxes[i as usize], keys[i as usize]);
            let [x0, y0, x1, y1] = b.screen;
            let screen = [
                down(widen(x0, -1.0)),
                down(widen(y0, -1.0)),
                up(widen(x1, 1.0)),
                up(widen(y1, 1.0)),
            ];
            let near = f32::from_bits(u32::from(key) << 16);
            triangles.push((b.surface, b.triangle, screen, near));
        }
        // Which tiles each triangle goes to: fine, coarse or none.
        let place = |b: &[f32; 4]| {
            let r = fine.range(b)?;
            let n = (r.0.1 - r.0.0 + 1) * (r.1.1 - r.1.0 + 1);
            Some(if n <= FINE_MAX {
                (true, r)
            } else {
                (false, coarse.range(b)?)
            })
        };
        let placed: Vec<_> = triangles.iter().map(|(_, _, b, _)| place(b)).collect();
        // Entries are counted in u32 (a tile's start): past that, no bins.
        let (mut fine_entries, mut coarse_entries) = (0usize, 0usize);
        for &(is_fine, r) in placed.iter().flatten() {
            let n = (r.0.1 - r.0.0 + 1) * (r.1.1 - r.1.0 + 1);
            if is_fine {
                fine_entries += n;
                fine.count(r);
            } else {
                coarse_entries += n;
                if coarse_entries > COARSE_DEPTH * (coarse.starts.len() - 1) {
                    return None;
                }
                coarse.count(r);
            }
        }
        let most = u32::MAX as usize;
        if triangles.len() > most || fine_entries > most || coarse_entries > most {
            return None;
        }
        let (mut fine_fill, mut coarse_fill) = (fine.prefix(), coarse.prefix());
        for (i, p) in placed.iter().enumerate() {
            match *p {
                Some((true, r)) => fine.fill(&mut fine_fill, i as u32, r),
                Some((false, r)) => coarse.fill(&mut coarse_fill, i as u32, r),
                None => {}
            }
        }
        Some(ScreenBins {
            fine,
            coarse,
            triangles,
        })
    }

    /// The screen box `lo..hi` as the tiles take it; `None` when it is not
    /// wholly inside them.
    fn query(&self, lo: [f64; 2], hi: [f64; 2]) -> Option<BoxQuery> {
        let tiles = &self.fine;
        let end = |a: usize| tiles.origin + tiles.tiles[a] as f64 * tiles.side[a];
        if !(0..2).all(|a| lo[a] >= tiles.origin && hi[a] < end(a) && lo[a] <= hi[a]) {
            return None;
        }
        Some(BoxQuery { lo, hi })
    }

    /// Calls `found` with each binned triangle whose widened box meets
    /// box `q` ([`BoxQuery::meets`]), in the lists of the tiles (fine, then
    /// coarse) `q` reaches ([`Tiles::reaching`]),
    /// each list read nearest first up to least depth `depth`, each
    /// triangle once: from the first of its tiles the query reaches (each
    /// triangle is filed under every tile its box touches, at one level).
    fn each_meeting(
        &self,
        q: &BoxQuery,
        depth: f64,
        mut found: impl FnMut(&(u32, u32, [f32; 4], f32)),
    ) {
        for tiles in [&self.fine, &self.coarse] {
            let ((tx0, tx1), (ty0, ty1)) = tiles.reaching(q.lo, q.hi);
            for ty in ty0..=ty1 {
                for tx in tx0..=tx1 {
                    for &i in tiles.at(ty * tiles.tiles[0] + tx) {
                        let binned = &self.triangles[i as usize];
                        // Not a number compares false: read on.
                        if f64::from(binned.3) >= depth {
                            break;
                        }
                        if !q.meets(&binned.2) {
                            continue;
                        }
                        let (bx, by) = tiles.first(&binned.2);
                        if (tx, ty) != (bx.max(tx0), by.max(ty0)) {
                            continue;
                        }
                        found(binned);
                    }
                }
            }
        }
    }

    /// Every binned triangle whose widened box meets the screen box
    /// `lo..hi`, as `(surface, rank(surface, triangle), triangle)` into
    /// `out`, sorted and each once: a superset of the mesh triangles whose
    /// projections reach into a polygon within that box over some area
    /// (more than a line), in the order
    /// `rank` gives. False (`out` cleared) when the box is not wholly
    /// inside the tiles: the caller searches the hierarchies.
    pub(crate) fn overlapping(
        &self,
        lo: [f64; 2],
        hi: [f64; 2],
        rank: impl Fn(u32, u32) -> u32,
        out: &mut Vec<(u32, u32, u32)>,
    ) -> bool {
        out.clear();
        let Some(q) = self.query(lo, hi) else {
            return false;
        };
        self.each_meeting(&q, f64::INFINITY, |&(surface, triangle, ..)| {
            out.push((surface, rank(surface, triangle), triangle));
        });
        out.sort_unstable();
        true
    }

    /// Every binned triangle whose widened box meets the screen box
    /// `lo..hi` and whose least depth (its bound, [`ScreenBox::near`]) is
    /// below `depth`, as `(surface, triangle, least depth, widened box)`
    /// into `out`, each once, in the tiles' order: a superset of the mesh
    /// triangles that reach into a polygon within that box over some area
    /// and are nearer than `depth` somewhere there. Each tile's list is read nearest first, up to
    /// `depth`.
    /// False (`out` cleared) when the box is not wholly inside the tiles.
    pub(crate) fn nearer_than(
        &self,
        lo: [f64; 2],
        hi: [f64; 2],
        depth: f64,
        out: &mut Vec<(u32, u32, f32, [f32; 4])>,
    ) -> bool {
        out.clear();
        let Some(q) = self.query(lo, hi) else {
            return false;
        };
        self.each_meeting(&q, depth, |&(surface, triangle, b, near)| {
            out.push((surface, triangle, near, b));
        });
        true
    }

    /// What [`Caster::nearest_index`] finds for `ray`, the camera's ray
    /// through screen point `c`: the nearest of the non-mesh surfaces
    /// (each tested) and of the mesh triangles in `c`'s tile whose boxes
    /// hold it. Equal distances go to the lower surface, then (within a
    /// mesh) to the lower triangle. `None` when `c` lies outside the
    /// tiles: the caller casts the ray.
    pub(crate) fn nearest_through(
        &self,
        rays: &Caster<'_>,
        ray: &Ray,
        c: [f64; 2],
    ) -> Option<Option<(usize, Hit)>> {
        let scene: &Scene = rays.scene;
        let (fine, coarse) = (self.fine.holding(c)?, self.coarse.holding(c)?);
        let (cx, cy) = (c[0], c[1]);
        // (t, surface, triangle): the least wins.
        let mut best: Option<(f64, usize, u32)> = None;
        // The mesh of the last surface met (a scene has one mesh, most often).
        let mut mesh_of: (u32, Option<&Mesh>) = (u32::MAX, None);
        // A hit at `t` has depth `t·(direction·forward)` from the camera:
        // once a list reaches triangles whose least depth lies past the
        // best hit's, the rest lie farther still.
        let camera = &scene.camera;
        let along = ray.direction.dot(camera.forward);
        let bounded = ray.origin == camera.position && along > 0.0;
        let mut limit = f64::INFINITY;
        for list in [self.fine.at(fine), self.coarse.at(coarse)] {
            for &i in list {
                let (surface, triangle, [x0, y0, x1, y1], near) = self.triangles[i as usize];
                if f64::from(near) > limit {
                    break;
                }
                if cx < f64::from(x0)
                    || cx > f64::from(x1)
                    || cy < f64::from(y0)
                    || cy > f64::from(y1)
                {
                    continue;
                }
                if mesh_of.0 != surface {
                    let mesh = match scene.surfaces.get(surface as usize).map(|s| &s.geometry) {
                        Some(Geometry::Mesh(mesh)) => Some(&**mesh),
                        _ => None,
                    };
                    mesh_of = (surface, mesh);
                }
                let Some(mesh) = mesh_of.1 else {
                    continue;
                };
                if let Some(t) = mesh.crossing_beyond(triangle, ray, 1e-9) {
                    let key = (t, surface as usize, triangle);
                    if best.is_none_or(|b| key < b) {
                        best = Some(key);
                        if bounded {
                            limit = t * along * (1.0 + NEAR_MARGIN);
                        }
                    }
                }
            }
        }
        let mut hit: Option<(usize, Hit)> = best.and_then(|(_, surface, triangle)| {
            match &scene.surfaces[surface].geometry {
                Geometry::Mesh(mesh) => mesh.intersect_triangle(triangle, ray, 1e-9),
                _ => None,
            }
            .map(|h| (surface, h))
        });
        for (i, s) in scene.surfaces.iter().enumerate() {
            if matches!(s.geometry, Geometry::Mesh(_)) {
                continue;
            }
            if let Some(h) = rays.surface_hit(i, ray)
                && hit
                    .as_ref()
                    .is_none_or(|(j, b)| h.t < b.t || (h.t == b.t && i < *j))
            {
                hit = Some((i, h));
            }
        }
        Some(hit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A query meets a box over more than a line (touching a side is not
    /// enough, but is on an axis where the query has no extent), and reads
    /// no row or column of tiles that only touches its sides, with the
    /// frame's origin (`−PAD`) as with origin 0; a grid whose sides are
    /// not powers of two keeps its last tiles.
    #[test]
    fn queries_on_whole_pixels_read_no_tile_past_their_sides() {
        let q = BoxQuery {
            lo: [0.0, 0.0],
            hi: [16.0, 1.0],
        };
        assert!(!q.meets(&[16.0, 0.0, 17.0, 1.0]));
        assert!(!q.meets(&[-1.0, 0.0, 0.0, 1.0]));
        assert!(!q.meets(&[2.0, 1.0, 3.0, 2.0]));
        assert!(q.meets(&[-1.0, 0.0, 0.5, 1.0]));
        assert!(q.meets(&[15.5, 0.5, 17.0, 2.0]));
        let line = BoxQuery {
            lo: [3.0, 0.0],
            hi: [3.0, 1.0],
        };
        assert!(line.meets(&[2.0, 0.0, 3.0, 1.0]));
        assert!(!line.meets(&[3.5, 0.0, 4.0, 1.0]));
        let fine = Tiles::new(-3.0, [2.0, 1.0], [206, 126]);
        // x from −3: [1, 17] spans tiles 2..=9 and touches 10 at 17.
        assert_eq!(fine.reaching([1.0, 4.0], [17.0, 5.0]), ((2, 9), (7, 7)));
        assert_eq!(fine.reaching([1.5, 4.5], [16.5, 5.5]), ((2, 9), (7, 8)));
        assert_eq!(fine.reaching([1.0, 4.0], [1.0, 5.0]), ((2, 2), (7, 7)));
        let odd = Tiles::new(0.0, [6.0, 3.0], [120, 60]);
        assert_eq!(odd.reaching([0.0, 0.0], [12.0, 3.0]), ((0, 2), (0, 1)));
    }

    /// The triangles the tiles list for a box, nearer than a depth, are
    /// those a scan of every binned triangle finds, each once: random
    /// boxes of every size (fine and coarse tiles), at the grid's edges
    /// too, a third on whole pixels (the tiles past their sides not
    /// read), random depths.
    #[test]
    fn nearer_than_lists_each_triangle_the_scan_finds_once() {
        let mut seed = 3u64;
        let mut next = || crate::math::unit_random(&mut seed);
        let size = [200usize, 120usize];
        let boxes: Vec<ScreenBox> = (0..3000)
            .map(|t| {
                let (w, h) = if t % 10 == 0 {
                    (60.0 * next(), 40.0 * next())
                } else {
                    (6.0 * next(), 2.0 * next())
                };
                let (x, y) = (-10.0 + 210.0 * next(), -10.0 + 130.0 * next());
                ScreenBox {
                    surface: (t % 2) as u32,
                    triangle: t as u32,
                    screen: [x, y, x + w, y + h],
                    near: 100.0 * next(),
                }
            })
            .collect();
        // The frame's origin, −PAD.
        let bins = ScreenBins::build(&boxes, -3.0, size).unwrap();
        let mut out = Vec::new();
        let mut found = 0;
        let mut trimmed = 0;
        for q in 0..600 {
            let (x, y) = (175.0 * next(), 110.0 * next());
            let (mut lo, mut hi) = ([x, y], [x + 17.0 * next(), y + 3.0 * next()]);
            if q % 3 == 0 {
                // On whole pixels, as supports are: the last row and column
                // of tiles, which only touch the box, are not read.
                (lo, hi) = (lo.map(f64::floor), hi.map(f64::ceil));
                let q = bins.query(lo, hi).unwrap();
                let ((_, x1), (_, y1)) = bins.fine.reaching(q.lo, q.hi);
                let touched = bins
                    .fine
                    .range(&[lo[0], lo[1], hi[0], hi[1]].map(|v| v as f32));
                trimmed += usize::from(touched.is_some_and(|t| t.0.1 > x1 || t.1.1 > y1));
            }
            let depth = 100.0 * next();
            assert!(bins.nearer_than(lo, hi, depth, &mut out));
            let q = bins.query(lo, hi).unwrap();
            let mut listed: Vec<(u32, u32)> = out.iter().map(|&(s, t, ..)| (s, t)).collect();
            let n = listed.len();
            listed.sort_unstable();
            listed.dedup();
            assert_eq!(listed.len(), n, "a triangle listed twice");
            let mut scanned: Vec<(u32, u32)> = (bins.triangles.iter())
                .filter(|&&(_, _, b, near)| {
                    f64::from(near) < depth
                        && q.meets(&b)
                        && (bins.fine.range(&b).is_some() || bins.coarse.range(&b).is_some())
                })
                .map(|&(s, t, ..)| (s, t))
                .collect();
            scanned.sort_unstable();
            assert_eq!(listed, scanned);
            found += n;
        }
        assert!(found > 1000, "{found}");
        assert!(trimmed > 150, "{trimmed}");
    }
}

//! The visibility grid: which primitive the camera's ray through each
//! pixel centre meets first ([`crate::caster::Seen`], `0` for the sky), on a
//! grid padded by `pad` pixels around the image (grid cell `(gx, gy)` is the
//! centre `(gx − pad + ½, gy − pad + ½)`).
//!
//! **Rasterised where that is the same answer.** Planes, quads and mesh
//! triangles are planar: each one's screen region is a few half-planes and
//! its ray parameter is `depth / w(s)` with `w` affine in the screen point
//! ([`crate::view::View`]), so the grid is a z-buffer. Planes and quads are
//! drawn into every row; mesh triangles are binned first by the rows of
//! centres their projected corners' box holds, widened by [`BOX_SLACK`]
//! (bands of [`BAND`] rows; a triangle reaching behind the camera's plane
//! goes to every row, one wholly behind it or between the centres to
//! none), then drawn band by band in parallel. The same pass files them
//! by screen tile for the exact pixel's rays ([`ScreenBins`]). Per row,
//! each primitive's span of centres comes from its lines, and each
//! centre in it keeps the nearest primitive. That is what casting the ray
//! finds, except where
//! rounding could make the two disagree; those centres are cast as rays
//! instead: a centre within [`EDGE_MARGIN`] pixel of an edge line (or
//! within a relative `10⁻¹²` of the line's range over the screen), two
//! primitives within a relative [`DEPTH_TIE`] in depth, a ray parameter
//! under [`MIN_DEPTH`], a surface nearly parallel to the ray. A sphere is
//! not planar: the cells of its projected bounding cube's screen box are
//! cast.

use quadtex_core::ConvexPolygon;
use rayon::prelude::*;

use crate::caster::{Caster, Seen, seen_id};
use crate::exact::SurfaceViews;
use crate::math::Vec3;
use crate::reach::MeshReach;
use crate::scene::{Geometry, Mesh, Scene};
use crate::screen_bins::{ScreenBins, ScreenBox};
use crate::view::View;

/// Screen distance (pixels) from an edge line within which a centre is
/// cast as a ray rather than decided by the line's sign: many orders of
/// magnitude above the rounding of either computation.
const EDGE_MARGIN: f64 = 1e-6;

/// Relative depth difference below which two primitives at a centre are
/// cast as a ray (coplanar decals, shared edges).
const DEPTH_TIE: f64 = 1e-9;

/// Smallest ray parameter (unnormalised ray) decided without a ray: the
/// ray cast's own near limit is `10⁻⁹` on the normalised one.
const MIN_DEPTH: f64 = 1e-6;

/// Screen distance (pixels) by which a triangle's projected box is widened
/// when binning it to the rows and columns of centres it may cover, plus
/// [`BOX_SLACK_REL`] of each end's magnitude: far above the rounding of
/// the projection of its corners (relative `10⁻¹⁵` or so).
const BOX_SLACK: f64 = 1e-3;

/// The relative part of [`BOX_SLACK`].
const BOX_SLACK_REL: f64 = 1e-9;

/// The first row of a triangle whose reach is marked but that covers no
/// centre ([`Raster::bin`]).
const NOT_BINNED: u32 = u32::MAX;

/// A mesh triangle as [`Raster`] bins it: its first and last row of
/// centres ([`NOT_BINNED`] first when it holds none), the screen box of its
/// projected corners (an infinite box for one reaching behind the camera's
/// plane), and the least depth `(p − c)·forward` of its corners, at least 0.
type Projected = (u32, u32, [f64; 4], f64);

/// Pixels by which the planes that rule out a mesh's hierarchy boxes
/// ([`Raster::may_show`]) lie outside the grid: beyond the tiles of the
/// mesh's reach that a screen box past the grid's edge still marks (8
/// pixels and 1 of slack), and far above the rounding of the projection.
/// A triangle ruled out covers no centre and reaches no pixel's support
/// (all within the grid): the grid, the reach and what the screen bins
/// answer are as without the test.
const CULL_MARGIN: f64 = 64.0;

/// Triangles per task when the binning projects them.
const PROJECT_RUN: usize = 4096;

/// Grid rows per band of the mesh triangles' bins.
const BAND: usize = 8;

/// Which primitive each centre of the padded grid sees, `gw × gh` cells,
/// row by row, where on the screen mesh triangles may reach, and, when
/// `screen_bins` asks for them (only the exact pixels read them), the
/// triangles by screen tile (from the same binning; `None` where the grid
/// is cast).
pub(crate) fn visibility_grid(
    scene: &Scene,
    rays: &Caster<'_>,
    views: &SurfaceViews,
    (gw, gh): (usize, usize),
    pad: f64,
    screen_bins: bool,
) -> (Vec<Seen>, MeshReach, Option<ScreenBins>) {
    let cast = |gx: usize, gy: usize| {
        let ray = (scene.camera).ray(gx as f64 - pad + 0.5, gy as f64 - pad + 0.5);
        rays.nearest_index(&ray)
            .map_or(0, |(i, hit)| seen_id(i, hit.triangle))
    };
    let mut grid = vec![0; gw * gh];
    if gw == 0 {
        return (grid, MeshReach::everywhere(), None);
    }
    match Raster::new(scene, views, (gw, gh), pad, screen_bins) {
        Some(mut raster) => {
            let boxes = raster.screen_boxes.take();
            // The screen bins are built (on one thread) while the bands
            // are drawn. One task a band: bands cost what their triangles
            // do (see the pixel rows in `render`).
            let (bins, ()) = rayon::join(
                || boxes.and_then(|b| ScreenBins::build(&b, -pad, [gw, gh])),
                || {
                    grid.par_chunks_mut(gw * BAND)
                        .enumerate()
                        .with_max_len(1)
                        .for_each(|(band, cells)| raster.band(band, cells, gw, &cast));
                },
            );
            (grid, raster.reach, bins)
        }
        None => {
            grid.par_chunks_mut(gw)
                .enumerate()
                .with_max_len(1)
                .for_each(|(gy, row)| {
                    for (gx, id) in row.iter_mut().enumerate() {
                        *id = cast(gx, gy);
                    }
                });
            (grid, MeshReach::everywhere(), None)
        }
    }
}

/// Most lines of a view: `w` and a quad's four edges.
const MAX_LINES: usize = 5;

/// One plane, quad or triangle as the z-buffer sees it.
struct Primitive {
    id: Seen,
    /// `w` first, then the edges: `a·x + b·y + c ≥ 0` inside.
    lines: [[f64; 3]; MAX_LINES],
    /// Per line, the value within which a centre counts as on it.
    margins: [f64; MAX_LINES],
    count: usize,
    /// `t = depth / w(s)` (unnormalised ray).
    depth: f64,
    /// Below this `w(s)` the surface is too near parallel to the ray to be
    /// decided without it (the ray cast rejects `|n·d̂| < 10⁻¹²`, and a
    /// triangle `|det| < 10⁻¹⁴`).
    min_w: f64,
}

/// A mesh triangle binned to a band: surface, triangle, first and last
/// grid row its screen box reaches.
type Binned = (u32, u32, u32, u32);

/// The z-buffer over a scene of planes, quads and meshes.
struct Raster<'s> {
    scene: &'s Scene,
    /// Planes and quads: in every row.
    shared: Vec<Primitive>,
    /// Grid boxes `[gx0, gy0, gx1, gy1]` (inclusive) that a sphere may
    /// cover: their cells are cast as rays.
    cast_boxes: Vec<[usize; 4]>,
    /// Mesh triangles by band of [`BAND`] rows.
    bands: Vec<Vec<Binned>>,
    pad: f64,
    /// Screen extent of the grid, for the lines' relative margins.
    extent: [f64; 2],
    /// The longest unnormalised ray direction over the grid.
    d_max: f64,
    /// Where the binned triangles may reach.
    reach: MeshReach,
    /// Every mesh triangle that shows on the grid, and its screen box, for
    /// [`ScreenBins`]; `None` once one shows with no known box.
    screen_boxes: Option<Vec<ScreenBox>>,
}

impl<'s> Raster<'s> {
    /// `None` when a plane or quad is seen edge-on. `screen_bins`: whether
    /// to list the triangles' screen boxes for [`ScreenBins`].
    fn new(
        scene: &'s Scene,
        views: &SurfaceViews,
        (gw, gh): (usize, usize),
        pad: f64,
        screen_bins: bool,
    ) -> Option<Raster<'s>> {
        let planar = views.planar_views();
        let extent = [gw as f64 + pad, gh as f64 + pad];
        // |d| is convex in the screen point: largest at a corner.
        let cam = &scene.camera;
        let d_max = [
            (-pad, -pad),
            (extent[0], -pad),
            (-pad, extent[1]),
            (extent[0], extent[1]),
        ]
        .iter()
        .map(|&(x, y)| cam.direction(x, y).length())
        .fold(0.0, f64::max);
        let mut raster = Raster {
            scene,
            shared: Vec::new(),
            cast_boxes: Vec::new(),
            bands: vec![Vec::new(); gh.div_ceil(BAND)],
            pad,
            extent,
            d_max,
            reach: MeshReach::new((gw, gh), pad),
            screen_boxes: screen_bins.then(Vec::new),
        };
        for (i, s) in scene.surfaces.iter().enumerate() {
            match &s.geometry {
                Geometry::Plane { .. } | Geometry::Quad { .. } => {
                    let view = planar.get(i)?.as_ref()?;
                    raster.shared.push(raster.primitive(
                        view.lines(),
                        view.depth_parts().1,
                        seen_id(i, 0),
                        0.0,
                    )?);
                }
                Geometry::Mesh(mesh) => raster.bin(i, mesh, (gw, gh)),
                Geometry::Sphere { centre, radius } => {
                    let cells = raster.sphere_box(*centre, *radius, (gw, gh));
                    raster.cast_boxes.extend(cells);
                }
            }
        }
        Some(raster)
    }

    /// The z-buffer's form of a view's `lines` (`w` first) and depth
    /// numerator; `det_scale`: a triangle's `|e1×e2|` (0 for planes and
    /// quads). `None` if a figure is not finite.
    fn primitive(
        &self,
        lines: impl Iterator<Item = [f64; 3]>,
        depth: f64,
        id: Seen,
        det_scale: f64,
    ) -> Option<Primitive> {
        let [x_max, y_max] = self.extent;
        let mut min_w = 1e-9 * self.d_max;
        if det_scale > 0.0 {
            min_w = min_w.max(1e-12 * self.d_max / det_scale);
        }
        let mut p = Primitive {
            id,
            lines: [[0.0; 3]; MAX_LINES],
            margins: [0.0; MAX_LINES],
            count: 0,
            depth,
            min_w,
        };
        for [a, b, c] in lines {
            if p.count == MAX_LINES || ![a, b, c].iter().all(|v| v.is_finite()) {
                return None;
            }
            p.lines[p.count] = [a, b, c];
            // Not `hypot`: its care for overflow costs a tenth of the
            // pass; an overflow here only widens the margin to ∞ (cast).
            p.margins[p.count] = EDGE_MARGIN * (a * a + b * b).sqrt()
                + 1e-12 * (a.abs() * x_max + b.abs() * y_max + c.abs());
            p.count += 1;
        }
        (depth.is_finite() && min_w.is_finite() && p.count > 0).then_some(p)
    }

    /// The grid cells a sphere's projection may reach: those of the
    /// projected corners of its bounding cube (the projection of their
    /// convex hull holds the sphere's), the whole grid when a corner lies
    /// behind the camera's plane; `None` when it misses the grid.
    fn sphere_box(
        &self,
        centre: Vec3,
        radius: f64,
        (gw, gh): (usize, usize),
    ) -> Option<[usize; 4]> {
        let r = Vec3::new(radius, radius, radius);
        let Some((lo, hi)) = self.scene.camera.screen_box_of_box(centre - r, centre + r) else {
            return Some([0, 0, gw - 1, gh - 1]);
        };
        let (x0, x1) = self.cells(lo[0], hi[0], gw)?;
        let (y0, y1) = self.cells(lo[1], hi[1], gh)?;
        Some([x0, y0, x1, y1])
    }

    /// The grid cells `first..=last` (of `n`, on one axis) whose centres
    /// may lie in screen interval `[lo, hi]`, with a cell of slack each
    /// side; `None` when none do. Centre of cell `g`: `g − pad + ½`.
    fn cells(&self, lo: f64, hi: f64, n: usize) -> Option<(usize, usize)> {
        if lo.is_nan() || hi.is_nan() {
            return (n > 0).then(|| (0, n - 1));
        }
        let cell = |v: f64| (v + self.pad - 0.5).clamp(-2.0, n as f64 + 1.0);
        let first = (cell(lo).floor() - 1.0).max(0.0) as usize;
        let last = ((cell(hi).ceil() + 1.0).max(0.0) as usize).min(n.checked_sub(1)?);
        (first <= last).then_some((first, last))
    }

    /// The grid cells `first..=last` (of `n`, on one axis) whose centres
    /// lie in screen interval `[lo, hi]` widened by `slack + rel·|end|` at
    /// each end; `None` when none do. Centre of cell `g`: `g − pad + ½`.
    ///
    /// A centre left out lies farther than the slack from the interval:
    /// for a triangle's projected box, farther from the triangle than the
    /// projection's rounding ([`BOX_SLACK`]), so its ray does not meet it
    /// and the other primitives decide the cell, as they would with it;
    /// for a span from the lines, beyond the loosened lines by more than
    /// the division's rounding, where the cell's own test finds it
    /// outside.
    fn centres(&self, lo: f64, hi: f64, n: usize, slack: f64, rel: f64) -> Option<(usize, usize)> {
        if lo.is_nan() || hi.is_nan() {
            return (n > 0).then(|| (0, n - 1));
        }
        if lo == f64::INFINITY || hi == f64::NEG_INFINITY {
            return None;
        }
        let lo = lo - (slack + rel * lo.abs()) + self.pad - 0.5;
        let hi = hi + (slack + rel * hi.abs()) + self.pad - 0.5;
        let first = lo.ceil().max(0.0);
        let last = hi.floor().min(n as f64 - 1.0);
        (first <= last).then_some((first as usize, last as usize))
    }

    /// The screen box `[x0, y0, x1, y1]` of what triangle `t` of mesh
    /// `surface`, reaching behind the camera's plane, shows of the grid:
    /// the grid's rectangle clipped by the triangle's view lines (in front
    /// of the camera, inside its edges); infinite when it has no view
    /// (edge-on), inverted (marks nothing) when it shows nothing.
    fn behind_box(&self, surface: usize, t: usize) -> [f64; 4] {
        let whole = [
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::INFINITY,
        ];
        let Some(view) = (self.scene.surfaces[surface].geometry.planar(t as u32))
            .and_then(|planar| View::new(self.scene, surface, &planar))
        else {
            return whole;
        };
        let [x1, y1] = self.extent;
        let shown = ConvexPolygon::rect(-self.pad, -self.pad, x1, y1).clip_lines(view.lines());
        if shown.is_empty() {
            return [
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ];
        }
        let (lo, hi) = shown.bounds();
        [lo[0], lo[1], hi[0], hi[1]]
    }

    /// Whether a box `[lo, hi]` of world space may hold points the grid
    /// shows: false only when the whole box lies behind the camera's plane
    /// or beyond one of the planes through the camera and the grid's edges
    /// moved out by [`CULL_MARGIN`] pixels. A mesh triangle in such a box
    /// projects (where it is in front of the camera) more than that
    /// margin off the grid: it covers no centre, reaches no tile of the
    /// mesh's reach or the screen bins, and is not binned.
    fn may_show(&self) -> impl Fn(Vec3, Vec3) -> bool + '_ {
        let cam = &self.scene.camera;
        let (width, height) = (f64::from(cam.width), f64::from(cam.height));
        let aspect = width / height;
        let [x_hi, y_hi] = self.extent.map(|v| v + CULL_MARGIN);
        let (x_lo, y_lo) = (-self.pad - CULL_MARGIN, -self.pad - CULL_MARGIN);
        // A point `p` in front (`d·forward > 0`, `d = p − c`) projects to
        // `x ≥ x_lo` iff `d·(right − k·forward) ≥ 0` with `k` the screen
        // slope at `x_lo` ([`Camera::project`]), and so for each edge.
        let kx = |x: f64| (2.0 * x / width - 1.0) * cam.tan_half_fov * aspect;
        let ky = |y: f64| (1.0 - 2.0 * y / height) * cam.tan_half_fov;
        let (f, r, u) = (cam.forward, cam.right, cam.up);
        let normals = [
            f,
            r - f * kx(x_lo),
            f * kx(x_hi) - r,
            f * ky(y_lo) - u,
            u - f * ky(y_hi),
        ];
        let c = cam.position;
        move |lo: Vec3, hi: Vec3| {
            normals.iter().all(|n| {
                // The largest `n·(p − c)` over the box, at the corner
                // farthest along `n`, against a tolerance for its rounding.
                let far =
                    |n: f64, lo: f64, hi: f64, c: f64| n * (if n > 0.0 { hi } else { lo } - c);
                let terms = [
                    far(n.x, lo.x, hi.x, c.x),
                    far(n.y, lo.y, hi.y, c.y),
                    far(n.z, lo.z, hi.z, c.z),
                ];
                let most: f64 = terms.iter().sum();
                let size: f64 = terms.iter().map(|t| t.abs()).sum();
                // NaN (a box not finite) keeps the box.
                most >= -1e-9 * size || most.is_nan() || size.is_nan()
            })
        }
    }

    /// Bins mesh `surface`'s triangles by the grid rows their screen boxes
    /// reach (every row for one reaching behind the camera's plane). The
    /// hierarchy's boxes rule out first the triangles no part of the grid
    /// can show ([`Raster::may_show`]): most of a terrain's seen from on
    /// it (at 1080, 286 043 of the generated terrain's 1 002 528 triangles
    /// reach the grid).
    fn bin(&mut self, surface: usize, mesh: &Mesh, (gw, gh): (usize, usize)) {
        let cam = &self.scene.camera;
        // In runs of at most a few thousand, so the threads share them.
        let runs: Vec<std::ops::Range<usize>> = (mesh.triangles_in(self.may_show()).into_iter())
            .flat_map(|r| {
                (r.start..r.end)
                    .step_by(PROJECT_RUN)
                    .map(move |s| s..(s + PROJECT_RUN).min(r.end))
            })
            .collect();
        let project = |t: usize| -> Option<Projected> {
            let corners = mesh.corners(t)?;
            // Every ray's direction has `d·forward = 1`: a point with
            // `(p − c)·forward ≤ 0` is never hit.
            let (near, far) = cam.depth_range(&corners);
            if far <= 0.0 {
                return None;
            }
            let Some((lo, hi)) = cam.screen_box(corners) else {
                return Some((0, gh as u32 - 1, self.behind_box(surface, t), near));
            };
            self.cells(lo[0], hi[0], gw)?;
            self.cells(lo[1], hi[1], gh)?;
            let screen_box = [lo[0], lo[1], hi[0], hi[1]];
            // A triangle between the centres (most of a far
            // hillside's) marks no cell: it is not binned, but its
            // reach is marked (the gap searches look for it).
            let centres = |axis: usize, n: usize| {
                self.centres(lo[axis], hi[axis], n, BOX_SLACK, BOX_SLACK_REL)
            };
            Some(match (centres(0, gw), centres(1, gh)) {
                (Some(_), Some((first, last))) => (first as u32, last as u32, screen_box, near),
                _ => (NOT_BINNED, 0, screen_box, near),
            })
        };
        // In the triangles' order.
        let rows: Vec<(u32, Projected)> = runs
            .into_par_iter()
            .flat_map_iter(|run| run.filter_map(|t| project(t).map(|p| (t as u32, p))))
            .collect();
        // The reach, the screen boxes and the bands from them at once, on
        // as many threads: they share nothing but the list.
        let (reach, screen_boxes, bands) =
            (&mut self.reach, &mut self.screen_boxes, &mut self.bands);
        let mark_reach = || {
            for &(_, (_, _, [x0, y0, x1, y1], _)) in &rows {
                if x0 == f64::NEG_INFINITY {
                    reach.mark_everywhere();
                    break;
                }
                reach.mark([x0, y0], [x1, y1]);
            }
        };
        let list_boxes = || {
            if screen_boxes.is_none() {
                return;
            }
            let unknown = |b: &[f64; 4]| b[0] == f64::NEG_INFINITY;
            if rows.iter().any(|(_, (_, _, b, _))| unknown(b)) {
                *screen_boxes = None;
            }
            if let Some(boxes) = screen_boxes {
                let shown = (rows.iter())
                    .map(|&(t, (_, _, b, near))| ScreenBox {
                        surface: surface as u32,
                        triangle: t,
                        screen: b,
                        near,
                    })
                    // An inverted box shows nothing.
                    .filter(|b| b.screen[0] <= b.screen[2] && b.screen[1] <= b.screen[3]);
                boxes.extend(shown);
            }
        };
        let fill_bands = || {
            // Sized first: pushing a million entries into growing vectors
            // copies them over and over.
            let mut counts = vec![0usize; bands.len()];
            let binned = |r: &&(u32, Projected)| r.1.0 != NOT_BINNED;
            for &(_, (first, last, _, _)) in rows.iter().filter(binned) {
                for count in &mut counts[first as usize / BAND..=last as usize / BAND] {
                    *count += 1;
                }
            }
            for (band, count) in bands.iter_mut().zip(counts) {
                band.reserve(count);
            }
            for &(t, (first, last, _, _)) in rows.iter().filter(binned) {
                for band in &mut bands[first as usize / BAND..=last as usize / BAND] {
                    band.push((surface as u32, t, first, last));
                }
            }
        };
        rayon::join(mark_reach, || rayon::join(list_boxes, fill_bands));
    }

    /// Fills band `band` (`cells`: its rows, `gw` wide); `cast(gx, gy)` is
    /// the ray cast for a centre the lines and depths do not settle.
    fn band(
        &self,
        band: usize,
        cells: &mut [Seen],
        gw: usize,
        cast: &impl Fn(usize, usize) -> Seen,
    ) {
        let first_row = band * BAND;
        let rows = cells.len() / gw;
        let mut best = vec![f64::INFINITY; cells.len()];
        let mut unsure = vec![false; cells.len()];
        cells.fill(0);
        let mut z = ZBuffer {
            ids: cells,
            best: &mut best,
            unsure: &mut unsure,
            gw,
        };
        for p in &self.shared {
            for r in 0..rows {
                self.draw(p, first_row + r, r, &mut z);
            }
        }
        for &(surface, triangle, lo, hi) in &self.bands[band] {
            let surface = surface as usize;
            let geometry = &self.scene.surfaces[surface].geometry;
            let Geometry::Mesh(mesh) = geometry else {
                continue;
            };
            let id = seen_id(surface, triangle);
            let edges = (geometry.planar(triangle)).and_then(|p| View::edges(self.scene, &p));
            let scale = mesh.determinant_scale(triangle as usize).unwrap_or(0.0);
            let primitive = edges.and_then(|(lines, count, depth)| {
                self.primitive(lines[..count].iter().copied(), depth, id, scale)
            });
            let reach = (lo as usize).max(first_row)..=(hi as usize).min(first_row + rows - 1);
            match primitive {
                Some(p) => reach.for_each(|gy| self.draw(&p, gy, gy - first_row, &mut z)),
                // Edge-on or not finite: its rows are cast.
                None => reach.for_each(|gy| z.unsure[(gy - first_row) * gw..][..gw].fill(true)),
            }
        }
        for &[x0, y0, x1, y1] in &self.cast_boxes {
            for gy in y0.max(first_row)..=y1.min(first_row + rows - 1) {
                unsure[(gy - first_row) * gw..][x0..=x1].fill(true);
            }
        }
        for (i, id) in cells.iter_mut().enumerate() {
            if unsure[i] {
                *id = cast(i % gw, first_row + i / gw);
            }
        }
    }

    /// Draws primitive `p` into row `r` of the band (grid row `gy`).
    fn draw(&self, p: &Primitive, gy: usize, r: usize, z: &mut ZBuffer<'_>) {
        let y = gy as f64 - self.pad + 0.5;
        let n = z.gw;
        let (ids, best, unsure) = (
            &mut z.ids[r * n..][..n],
            &mut z.best[r * n..][..n],
            &mut z.unsure[r * n..][..n],
        );
        let margins = &p.margins[..p.count];
        // Each line along the row: a·x + e ≥ 0, e = b·y + c.
        let mut slope = [0f64; MAX_LINES];
        let mut offset = [0f64; MAX_LINES];
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for (k, (&[a, b, c], &m)) in p.lines[..p.count].iter().zip(margins).enumerate() {
            let e = b * y + c;
            (slope[k], offset[k]) = (a, e);
            // Loosely inside: a·x + e ≥ −m.
            if a > 0.0 {
                lo = lo.max((-m - e) / a);
            } else if a < 0.0 {
                hi = hi.min((-m - e) / a);
            } else if e < -m {
                hi = f64::NEG_INFINITY;
            }
        }
        if lo > hi {
            return;
        }
        let Some((first, last)) = self.centres(lo, hi, n, 0.0, 1e-9) else {
            return;
        };
        for gx in first..=last {
            let x = gx as f64 - self.pad + 0.5;
            let mut on_edge = false;
            let mut outside = false;
            for k in 0..p.count {
                let v = slope[k] * x + offset[k];
                if v < -margins[k] {
                    outside = true;
                    break;
                }
                on_edge |= v < margins[k];
            }
            if outside {
                continue;
            }
            let w = slope[0] * x + offset[0];
            if on_edge || w < p.min_w {
                unsure[gx] = true;
                continue;
            }
            let t = p.depth / w;
            if !(t > MIN_DEPTH && t.is_finite()) {
                unsure[gx] = true;
                continue;
            }
            let b = best[gx];
            if (t - b).abs() <= DEPTH_TIE * t.min(b) {
                unsure[gx] = true;
            }
            if t < b {
                best[gx] = t;
                ids[gx] = p.id;
            }
        }
    }
}

/// A band's cells: the nearest primitive, its depth, and whether a ray
/// must settle the cell.
struct ZBuffer<'a> {
    ids: &'a mut [Seen],
    best: &'a mut [f64],
    unsure: &'a mut [bool],
    gw: usize,
}

#[cfg(test)]
mod tests;

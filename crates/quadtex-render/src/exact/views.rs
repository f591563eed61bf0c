//! Visibility and views: the views of a pixel's candidate primitives
//! (a frame's planes and quads, mesh triangles built on demand and kept
//! from row to row, [`ViewMemo`]), the flood across a mesh's edges
//! ([`Flood`]), and the search of the meshes' hierarchies for what
//! reaches into a screen polygon ([`SurfaceViews::meshes_in`]).

use std::rc::Rc;

use quadtex_core::ConvexPolygon;

use crate::caster::{Seen, seen_id, surface_and_triangle};
use crate::frame::Frame;
use crate::math::Vec3;
use crate::reach::MeshReach;
use crate::scene::{Geometry, Hit, Scene};
use crate::screen_bins::{NEAR_MARGIN, ScreenBins};
use crate::view::View;

use super::sphere::SphereView;

/// The view of candidate `id`: `None` when it has none (a sphere that
/// reaches behind the camera's plane: the pixel takes the tangent-plane
/// path), `Some(None)` when it is seen edge-on. A mesh triangle's view comes from `memo` when a neighbouring
/// pixel built it.
pub(super) fn candidate_view<'a>(
    scene: &Scene,
    cache: &'a SurfaceViews,
    memo: &mut ViewMemo,
    id: Seen,
) -> Option<Option<ViewRef<'a>>> {
    let (surface, triangle) = surface_and_triangle(id);
    if let Some(Some(view)) = cache.views.get(surface) {
        return Some(Some(ViewRef::Frame(view)));
    }
    if let Some(sphere) = cache.spheres.get(surface).and_then(Option::as_ref) {
        return Some(Some(ViewRef::Sphere(sphere)));
    }
    if memo.slots.is_empty() {
        memo.slots.resize(ViewMemo::SLOTS, (0, None));
    }
    let slot = &mut memo.slots[ViewMemo::slot(id)];
    if slot.0 != id {
        let planar = scene.surfaces.get(surface)?.geometry.planar(triangle)?;
        *slot = (id, View::new(scene, surface, &planar).map(Rc::new));
    }
    Some(slot.1.clone().map(ViewRef::Built))
}

/// A view in a pixel's list: one of the frame's (a plane's or a quad's,
/// or a sphere's), or one built for a mesh triangle and shared with the
/// memo. A view is about 330 bytes; a copy per use cost the terrain at
/// 1920×1080 about 0.4 G instructions of `memcpy`, a shared one costs a
/// count.
#[derive(Clone, Debug)]
pub(crate) enum ViewRef<'a> {
    Frame(&'a View),
    Built(Rc<View>),
    Sphere(&'a SphereView),
}

impl ViewRef<'_> {
    /// The planar view, unless this is a sphere's.
    pub(crate) fn planar(&self) -> Option<&View> {
        match self {
            ViewRef::Frame(v) => Some(v),
            ViewRef::Built(v) => Some(v),
            ViewRef::Sphere(_) => None,
        }
    }

    /// The surface this is a view of.
    pub(crate) fn surface(&self) -> usize {
        match self {
            ViewRef::Sphere(s) => s.surface(),
            v => v.planar().map_or(0, View::surface),
        }
    }

    /// The mesh triangle this is the view of, if it is one.
    pub(crate) fn triangle(&self) -> Option<u32> {
        self.planar().and_then(View::triangle)
    }

    /// Ray parameter of the camera's unnormalised ray through `s` where it
    /// meets this primitive ([`View::depth_at`], [`SphereView::depth_at`]).
    pub(crate) fn depth_at(&self, s: [f64; 2]) -> f64 {
        match self {
            ViewRef::Sphere(v) => v.depth_at(s),
            v => v.planar().map_or(f64::INFINITY, |p| p.depth_at(s)),
        }
    }

    /// This primitive's part of `support` (occlusion ignored), into `out`.
    pub(crate) fn region_into(&self, support: &ConvexPolygon, out: &mut ConvexPolygon) {
        match self {
            ViewRef::Sphere(v) => v.region_into(support, out),
            v => {
                if let Some(p) = v.planar() {
                    p.region_into(support, out);
                }
            }
        }
    }
}

/// The views of the mesh triangles recent pixels built, by id (a pixel's
/// neighbour sees mostly the same triangles, and so does the pixel below
/// it): a direct-mapped table, kept by each thread from row to row of one
/// frame ([`ViewMemo::take_for`], [`ViewMemo::keep`]). A view is a
/// function of the scene, the camera and the triangle alone (its uniform
/// light too, [`View::uniform_light`]), so a kept view is the one the
/// pixel would build: the image does not depend on which thread shaded
/// which row. Kept per row only (256 slots), the terrain at 960×540 on
/// one thread built 247 000 views a frame, 0.23 G instructions of 7.13 G;
/// kept from row to row, 126 000 with 2¹³ slots, 114 000 with 2¹⁴ (6.88 G
/// a frame), 108 000 with 2¹⁵ (callgrind, 2026-12-06).
#[derive(Default)]
pub(super) struct ViewMemo {
    /// The frame the views were built for ([`SurfaceViews`]'s `frame`).
    pub(super) frame: u64,
    /// `(id, view)`; id 0 (the sky) marks an empty slot.
    pub(super) slots: Vec<(Seen, Option<Rc<View>>)>,
}

thread_local! {
    /// The thread's memo between rows ([`ViewMemo::keep`]): at most
    /// [`ViewMemo::SLOTS`] views (about 350 bytes each) a thread, kept
    /// until the thread's next frame replaces them.
    static KEPT_VIEWS: std::cell::RefCell<ViewMemo> = std::cell::RefCell::default();
}

impl ViewMemo {
    /// Slots, a power of two: past 2¹⁴ the terrain's frame saves little
    /// more (above), and each slot may hold a view between rows.
    pub(super) const SLOTS: usize = 1 << Self::SLOT_BITS;
    pub(super) const SLOT_BITS: u32 = 14;

    pub(super) fn slot(id: Seen) -> usize {
        fibonacci_slot(id, Self::SLOT_BITS)
    }

    /// The memo this thread kept from its last row, when that row was of
    /// frame `frame`; else an empty one for it.
    pub(super) fn take_for(frame: u64) -> ViewMemo {
        let mut kept = KEPT_VIEWS
            .try_with(|k| std::mem::take(&mut *k.borrow_mut()))
            .unwrap_or_default();
        if kept.frame != frame {
            // The table's allocation is kept; its views are another frame's.
            kept.frame = frame;
            kept.slots.fill((0, None));
        }
        kept
    }

    /// Keeps this memo for the thread's next row.
    pub(super) fn keep(self) {
        // A thread being torn down keeps nothing.
        let _ = KEPT_VIEWS.try_with(|k| *k.borrow_mut() = self);
    }
}

/// Slot of `id` in a direct-mapped table of `2^bits` slots: Fibonacci
/// hashing, so that neighbouring triangle numbers spread out.
pub(super) fn fibonacci_slot(id: Seen, bits: u32) -> usize {
    (id.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - bits)) as usize
}

/// The mesh triangles recent pixels of a row confirmed by a ray through
/// their region ([`exact_pixel`](super::exact_pixel)'s flood): a
/// direct-mapped table of the pixel each was confirmed at.
#[derive(Default)]
pub(super) struct Confirmed {
    slots: Vec<(Seen, u32)>,
}

impl Confirmed {
    pub(super) const SLOTS: usize = 1 << Self::SLOT_BITS;
    pub(super) const SLOT_BITS: u32 = 8;

    /// How far back in the row a confirmation stands, in pixels: a point
    /// within about as far of the support as the centres in reach are.
    pub(super) const REACH: u32 = 2;

    pub(super) fn recent(&self, id: Seen, x: u32) -> bool {
        (self.slots.get(fibonacci_slot(id, Self::SLOT_BITS)))
            .is_some_and(|&(s, at)| s == id && x.wrapping_sub(at) <= Self::REACH)
    }

    pub(super) fn insert(&mut self, id: Seen, x: u32) {
        if self.slots.is_empty() {
            self.slots.resize(Self::SLOTS, (0, 0));
        }
        self.slots[fibonacci_slot(id, Self::SLOT_BITS)] = (id, x);
    }
}

/// The views of a scene's planes and quads, built once per frame (mesh
/// triangles are built when a pixel needs them).
#[derive(Debug)]
pub(crate) struct SurfaceViews {
    /// This frame's number, unique in the process: what tells a thread's
    /// kept views ([`ViewMemo`]) of this frame from another's.
    pub(super) frame: u64,
    pub(super) views: Vec<Option<View>>,
    /// The views of the spheres, by surface (`None`: another shape, or a
    /// sphere reaching behind the camera's plane).
    pub(super) spheres: Vec<Option<SphereView>>,
    /// The surfaces that are meshes.
    meshes: Vec<usize>,
    /// Where the frame's mesh triangles may reach on the screen, once the
    /// visibility pass has binned them (until then: anywhere).
    reach: MeshReach,
    /// The frame's mesh triangles by screen tile, once the visibility pass
    /// has binned them (until then, or where it casts: none).
    bins: Option<ScreenBins>,
}

impl SurfaceViews {
    pub fn new(scene: &Scene) -> SurfaceViews {
        let views = scene
            .surfaces
            .iter()
            .enumerate()
            .map(|(i, s)| match s.geometry {
                Geometry::Plane { .. } | Geometry::Quad { .. } => {
                    s.geometry.planar(0).and_then(|p| View::new(scene, i, &p))
                }
                _ => None,
            })
            .collect();
        let spheres = (0..scene.surfaces.len())
            .map(|i| SphereView::new(scene, i))
            .collect();
        let meshes = (scene.surfaces.iter().enumerate())
            .filter(|(_, s)| matches!(s.geometry, Geometry::Mesh(_)))
            .map(|(i, _)| i)
            .collect();
        static FRAMES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        SurfaceViews {
            frame: FRAMES.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            views,
            spheres,
            meshes,
            reach: MeshReach::everywhere(),
            bins: None,
        }
    }

    /// Where the frame's mesh triangles may reach ([`MeshReach`], from the
    /// visibility pass of the same camera and grid).
    pub(crate) fn set_mesh_reach(&mut self, reach: MeshReach) {
        self.reach = reach;
    }

    /// Sets the frame's mesh triangles by screen tile, from the same pass.
    pub(crate) fn set_screen_bins(&mut self, bins: Option<ScreenBins>) {
        self.bins = bins;
    }

    /// Whether the frame's mesh triangles are filed by screen tile.
    #[cfg(test)]
    pub(crate) fn has_screen_bins(&self) -> bool {
        self.bins.is_some()
    }

    /// What the camera's ray through screen point `c` meets first
    /// ([`crate::caster::Caster::nearest_index`]'s answer), from the screen bins where
    /// they hold `c` ([`ScreenBins::nearest_through`]). `expected`: a
    /// primitive the ray is thought to meet, which bounds the hierarchy's
    /// search otherwise ([`crate::caster::Caster::nearest_index_expecting`]).
    pub(super) fn camera_hit(
        &self,
        frame: &Frame<'_>,
        c: [f64; 2],
        expected: Option<Seen>,
    ) -> Option<(usize, Hit)> {
        let ray = frame.scene.camera.ray(c[0], c[1]);
        if let Some(hit) =
            (self.bins.as_ref()).and_then(|b| b.nearest_through(&frame.rays, &ray, c))
        {
            return hit;
        }
        match expected {
            Some(id) => frame.rays.nearest_index_expecting(&ray, id),
            None => frame.rays.nearest_index(&ray),
        }
    }

    /// Calls `visit(id)` for every mesh triangle that may reach into screen
    /// polygon `polygon` (not wholly outside the planes through the camera
    /// and its edges, nor behind the camera), until `visit` returns true;
    /// returns whether it did.
    pub(crate) fn meshes_in(
        &self,
        scene: &Scene,
        polygon: &ConvexPolygon,
        planes: &mut Vec<[f64; 4]>,
        visit: impl FnMut(Seen) -> bool,
    ) -> bool {
        let bounds = polygon.bounds();
        self.may_reach(bounds) && self.search_hierarchies(scene, polygon, bounds, planes, visit)
    }

    /// Whether a mesh triangle may reach into the screen box `(lo, hi)`:
    /// the scene has meshes, and the visibility pass's reach marks allow.
    pub(super) fn may_reach(&self, (lo, hi): ([f64; 2], [f64; 2])) -> bool {
        !self.meshes.is_empty() && self.reach.may_reach(lo, hi)
    }

    /// [`SurfaceViews::meshes_in`] past its checks, through the meshes'
    /// hierarchies: `(lo, hi)` is `polygon`'s box.
    pub(super) fn search_hierarchies(
        &self,
        scene: &Scene,
        polygon: &ConvexPolygon,
        (lo, hi): ([f64; 2], [f64; 2]),
        planes: &mut Vec<[f64; 4]>,
        mut visit: impl FnMut(Seen) -> bool,
    ) -> bool {
        frustum(scene, polygon, planes);
        // A box wholly in front of the camera projects inside the screen
        // box of its corners: one that misses the polygon's (with a slack
        // far above the projection's rounding) holds nothing that reaches
        // into it. Stronger than the planes for the thin, long frusta of
        // pixels along a terrain's ridge, whose planes far boxes straddle.
        let cam = &scene.camera;
        let slack = 1e-3 + 1e-9 * (lo[0].abs() + lo[1].abs() + hi[0].abs() + hi[1].abs());
        let (lo, hi) = (
            [lo[0] - slack, lo[1] - slack],
            [hi[0] + slack, hi[1] + slack],
        );
        let may_meet = |a: Vec3, b: Vec3| {
            let Some((s_lo, s_hi)) = cam.screen_box_of_box(a, b) else {
                return true;
            };
            // Not a number (an overflow) compares false: kept.
            !(s_hi[0] < lo[0] || s_lo[0] > hi[0] || s_hi[1] < lo[1] || s_lo[1] > hi[1])
        };
        self.meshes
            .iter()
            .any(|&surface| match &scene.surfaces[surface].geometry {
                Geometry::Mesh(mesh) => {
                    mesh.overlapping(planes, may_meet, |t| visit(seen_id(surface, t)))
                }
                _ => false,
            })
    }

    /// [`SurfaceViews::meshes_in`] for a gap of a pixel's support (`found`
    /// is scratch): from the screen bins where they hold the gap
    /// ([`ScreenBins::overlapping`]), else from the hierarchies. The bins
    /// list a superset of what the hierarchies visit, every triangle whose
    /// box meets the gap's, in the order each mesh's hierarchy visits its
    /// triangles: `visit` must turn down those that do not reach into
    /// `polygon` (the gaps' test is exact), so that either way the same
    /// triangles are taken, in the same order (but for any a hierarchy's
    /// planes turn down that reaches in by a rounding sliver).
    pub(crate) fn meshes_in_gap(
        &self,
        scene: &Scene,
        polygon: &ConvexPolygon,
        planes: &mut Vec<[f64; 4]>,
        found: &mut Vec<(u32, u32, u32)>,
        mut visit: impl FnMut(Seen) -> bool,
    ) -> bool {
        let (lo, hi) = polygon.bounds();
        if !self.may_reach((lo, hi)) {
            return false;
        }
        let rank = |surface: u32, t: u32| match scene
            .surfaces
            .get(surface as usize)
            .map(|s| &s.geometry)
        {
            Some(Geometry::Mesh(mesh)) => mesh.visit_rank(t),
            _ => 0,
        };
        if let Some(bins) = &self.bins
            && bins.overlapping(lo, hi, rank, found)
        {
            return (found.iter()).any(|&(surface, _, t)| visit(seen_id(surface as usize, t)));
        }
        self.search_hierarchies(scene, polygon, (lo, hi), planes, visit)
    }

    /// Calls `visit(id, near, bounds)` for every mesh triangle that may
    /// reach into screen polygon `polygon` nearer than `depth` (the
    /// camera's forward distance) somewhere, and for others, until `visit`
    /// returns true; returns whether it did. `near` bounds the triangle's
    /// depth from below; `bounds` is a box holding its projection (widened
    /// and rounded outward), or the whole plane. From the screen bins where they hold the polygon's box
    /// ([`ScreenBins::nearer_than`]), else the triangles the hierarchies
    /// find in its frustum whose least corner depth is below `depth`.
    /// `found`: scratch.
    pub(super) fn meshes_nearer(
        &self,
        scene: &Scene,
        polygon: &ConvexPolygon,
        depth: f64,
        planes: &mut Vec<[f64; 4]>,
        found: &mut Vec<(u32, u32, f32, [f32; 4])>,
        mut visit: impl FnMut(Seen, f64, ([f64; 2], [f64; 2])) -> bool,
    ) -> bool {
        let (lo, hi) = polygon.bounds();
        if !self.may_reach((lo, hi)) {
            return false;
        }
        if let Some(bins) = &self.bins
            && bins.nearer_than(lo, hi, depth, found)
        {
            return (found.iter()).any(|&(surface, t, near, [x0, y0, x1, y1])| {
                let bounds = (
                    [f64::from(x0), f64::from(y0)],
                    [f64::from(x1), f64::from(y1)],
                );
                visit(seen_id(surface as usize, t), f64::from(near), bounds)
            });
        }
        let cam = &scene.camera;
        self.search_hierarchies(scene, polygon, (lo, hi), planes, |id| {
            let (surface, t) = surface_and_triangle(id);
            let near = match scene.surfaces.get(surface).map(|s| &s.geometry) {
                Some(Geometry::Mesh(mesh)) => {
                    (mesh.corners(t as usize)).map_or(0.0, |corners| cam.depth_range(&corners).0)
                }
                _ => 0.0,
            };
            let everywhere = ([f64::NEG_INFINITY; 2], [f64::INFINITY; 2]);
            // Lowered as the bins lower theirs: ties within rounding are
            // kept.
            near * (1.0 - NEAR_MARGIN) < depth && visit(id, near, everywhere)
        })
    }

    /// Whether every sphere's outline misses the screen box `(lo, hi)`
    /// (by its box; a sphere with no view does not count).
    pub(super) fn spheres_miss(&self, (lo, hi): ([f64; 2], [f64; 2])) -> bool {
        (self.spheres.iter().flatten()).all(|s| s.misses_box(lo, hi))
    }

    /// [`SurfaceViews::spheres_miss`] for the spheres other than surface
    /// `own`'s.
    pub(super) fn spheres_miss_except(&self, (lo, hi): ([f64; 2], [f64; 2]), own: usize) -> bool {
        (self.spheres.iter().enumerate())
            .all(|(i, s)| i == own || s.as_ref().is_none_or(|s| s.misses_box(lo, hi)))
    }

    /// The views of the planes and quads, by surface (`None`: another
    /// shape, or seen edge-on).
    pub(crate) fn planar_views(&self) -> &[Option<View>] {
        &self.views
    }

    /// The view of primitive `triangle` of surface `surface`.
    pub(super) fn get(&self, scene: &Scene, surface: usize, triangle: u32) -> Option<ViewRef<'_>> {
        match self.views.get(surface)? {
            Some(v) => Some(ViewRef::Frame(v)),
            None => {
                let planar = scene.surfaces.get(surface)?.geometry.planar(triangle)?;
                View::new(scene, surface, &planar).map(|v| ViewRef::Built(Rc::new(v)))
            }
        }
    }
}

/// Screen length (pixels, `|dx| + |dy|`) below which an edge of a
/// polygon gives no plane of its frustum ([`frustum`]). The plane's normal,
/// the cross product of the camera's directions through the edge's ends,
/// is off by about `10⁻¹⁶` over the angle between them: the plane moves
/// by about `10⁻¹⁶ / (L·θ²)` pixels for an edge `L` pixels long (`θ` a
/// pixel's angle), under `10⁻⁶` pixel from `L = 10⁻³` up at 1080p and
/// 40°. A shorter edge's plane can cut off what the polygon holds (two
/// vertices a rounding apart, where a clip passed near a vertex, cut off
/// a hundredth of a pixel of the terrain at 1080p).
pub(super) const SHORT_EDGE: f64 = 1e-3;

/// The half-spaces `n·p + d ≥ 0` (`[n.x, n.y, n.z, d]`) whose intersection
/// holds every world point that projects into screen polygon `polygon`:
/// one plane through the camera and each edge (but edges shorter than
/// [`SHORT_EDGE`]), and the camera's plane.
pub(super) fn frustum(scene: &Scene, polygon: &ConvexPolygon, planes: &mut Vec<[f64; 4]>) {
    let cam = &scene.camera;
    let c = cam.position;
    let plane = |n: Vec3| [n.x, n.y, n.z, -n.dot(c)];
    let v = polygon.vertices();
    planes.clear();
    planes.push(plane(cam.forward()));
    let centroid = polygon.centroid();
    let inward = cam.direction(centroid[0], centroid[1]);
    for (i, a) in v.iter().enumerate() {
        let b = v[(i + 1) % v.len()];
        // An edge much shorter than a pixel (two vertices a rounding
        // apart, where a clip passed near a vertex) gives a plane whose
        // normal rounding sets: it may cut off what the polygon holds.
        // Left out, the frustum only grows.
        if (b[0] - a[0]).abs() + (b[1] - a[1]).abs() < SHORT_EDGE {
            continue;
        }
        let n = cam.direction(a[0], a[1]).cross(cam.direction(b[0], b[1]));
        if n.dot(n) > 0.0 && n.is_finite() {
            planes.push(plane(if n.dot(inward) < 0.0 { -n } else { n }));
        }
    }
}

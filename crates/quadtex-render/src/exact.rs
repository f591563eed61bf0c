//! Exact pixels: the pixel filter's support resolved in screen space into
//! the parts each planar primitive shows, each integrated over the texture
//! exactly ([`quadtex_core::Texture::integrate_region`]).
//!
//! **Primitives.** Planes, quads and each mesh triangle are planar: the map
//! from screen to texture over one of them is a single projective map
//! ([`View`]), exact, not a tangent-plane approximation; where it covers the
//! screen is the support clipped by a few half-planes (in front of the
//! camera; inside the quad's or triangle's edges).
//!
//! **Visibility.** The render loop records which primitive each pixel
//! centre sees. Where every centre within reach of the filter's support
//! sees the same primitive and its screen region holds the whole support,
//! the pixel is one integral. Otherwise the candidates are the primitives
//! those centres see; they are ordered front to back by comparing depths at
//! the centroid of each pair's screen overlap (planar primitives that do
//! not cross each other inside the pixel have one depth order there), and
//! the support is clipped against them in that order: each primitive gets
//! what the ones in front left. Where the listed regions leave part of the
//! support uncovered, a large mesh's triangles spread first to their
//! neighbours across the edges the support reaches past (shared corners,
//! [`crate::scene::Mesh::neighbour`]), breadth first, up to
//! [`MAX_GAP_PRIMITIVES`]: around the triangles the centres see, these
//! tile the support where the surface does not fold, and the pixel is
//! their regions, whole. Each triangle so listed is confirmed by the ray
//! through its region's centroid (or by one through the same triangle a
//! pixel or two back in the row, [`Confirmed`]; such camera rays test the
//! triangles the frame's screen tiles file under their point,
//! [`crate::screen_bins`], not the meshes' hierarchies); a ray that meets
//! another primitive there (an occluder no centre sees, such as a far
//! hill's crest) undoes the spread, and that primitive joins the list
//! instead. What none of them covers is searched: the
//! ray through each gap's centroid finds the primitive there (a large
//! mesh's triangles smaller than a pixel lie between the centres), which
//! joins the list, until the gaps are sky or slivers of rounding, or
//! [`MAX_GAP_PRIMITIVES`] have joined (past that, a gap takes the colour of
//! the primitive its ray meets over all of it, its weight added to the
//! bound). A gap whose ray meets nothing is sky only once no mesh triangle
//! reaches into it: the meshes' hierarchies are searched with the gap's
//! frustum ([`SurfaceViews::meshes_in`]) and what overlaps it joins the
//! list too; a pixel whose centres in reach all see the sky is searched
//! the same way (planes and quads are always tried). Limit, stated:
//! primitives that intersect inside the pixel are ordered at one point.
//! Spheres are not planar: pixels that involve one are left to the
//! tangent-plane path ([`crate::pixel`]).
//!
//! **Spans.** Consecutive pixels of a row inside one primitive share one
//! texture lookup and one shadow test where the rectangle their supports
//! cover allows it ([`crate::span`]); sky pixels clear of every primitive
//! are taken from the render loop ([`Scratch::sky_pixel`]).
//!
//! **Shading.** Lambert lighting is constant over a planar piece except for
//! shadows, taken at the piece's centroid. The sky's gradient over a whole
//! box-filtered pixel is its value at the centre where a bound on that
//! rule's error is within a quarter of the filter's error bound (everywhere
//! but near the level line, [`sky_at_centre`]), else 2 × 2 Gauss points;
//! over part of a pixel, the midpoint rule on quarter-pixel cells clipped to
//! the sky's part.

use std::borrow::Cow;
use std::ops::Deref;
use std::rc::Rc;

use quadtex_core::{ConvexPolygon, FilterOptions, PixelFilter, Rgba};

use crate::caster::{Seen, seen_id, surface_and_triangle};
use crate::frame::{Frame, lambert, sky};
use crate::math::{Ray, Vec3};
use crate::planar_view::{Placement, View, placement};
use crate::reach::MeshReach;
use crate::scene::{Geometry, Hit, Lighting, Scene};
use crate::screen_bins::ScreenBins;
use crate::span::{SpanAnswer, SpanQuery, UniformSpan, span_rect};
use crate::stats::PixelStats;

/// Meshes up to this many triangles have every triangle tried at a
/// silhouette pixel (larger ones: the triangles the centres see, and those
/// found in the gaps they leave).
const MAX_MESH_SCAN: usize = 256;

/// Pieces of a cut support (covered or not) of at most this fraction of
/// its area are slivers the cuts leave along shared edges (rounding): they
/// take the sky at one point, their weight as the bound, and are neither
/// cut further, integrated over a texture nor searched.
const GAP_AREA: f64 = 1e-9;

/// Most primitives a pixel adds to its list from gaps between the centres.
const MAX_GAP_PRIMITIVES: usize = 16;

/// The view of candidate `id`: `None` when it is not planar (a sphere: the
/// pixel takes the tangent-plane path), `Some(None)` when it is seen
/// edge-on. A mesh triangle's view comes from `memo` when a neighbouring
/// pixel built it.
fn candidate_view<'a>(
    scene: &Scene,
    cache: &'a SurfaceViews,
    memo: &mut ViewMemo,
    id: Seen,
) -> Option<Option<ViewRef<'a>>> {
    let (surface, triangle) = surface_and_triangle(id);
    if let Some(Some(view)) = cache.views.get(surface) {
        return Some(Some(ViewRef::Frame(view)));
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

/// A view in a pixel's list: one of the frame's (a plane's or a quad's),
/// or one built for a mesh triangle and shared with the memo. A view is
/// about 330 bytes; a copy per use cost the terrain at 1920×1080 about
/// 0.4 G instructions of `memcpy`, a shared one costs a count.
#[derive(Clone, Debug)]
pub(crate) enum ViewRef<'a> {
    Frame(&'a View),
    Built(Rc<View>),
}

impl Deref for ViewRef<'_> {
    type Target = View;

    fn deref(&self) -> &View {
        match self {
            ViewRef::Frame(v) => v,
            ViewRef::Built(v) => v,
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
struct ViewMemo {
    /// The frame the views were built for ([`SurfaceViews`]'s `frame`).
    frame: u64,
    /// `(id, view)`; id 0 (the sky) marks an empty slot.
    slots: Vec<(Seen, Option<Rc<View>>)>,
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
    const SLOTS: usize = 1 << Self::SLOT_BITS;
    const SLOT_BITS: u32 = 14;

    fn slot(id: Seen) -> usize {
        fibonacci_slot(id, Self::SLOT_BITS)
    }

    /// The memo this thread kept from its last row, when that row was of
    /// frame `frame`; else an empty one for it.
    fn take_for(frame: u64) -> ViewMemo {
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
    fn keep(self) {
        // A thread being torn down keeps nothing.
        let _ = KEPT_VIEWS.try_with(|k| *k.borrow_mut() = self);
    }
}

/// Slot of `id` in a direct-mapped table of `2^bits` slots: Fibonacci
/// hashing, so that neighbouring triangle numbers spread out.
fn fibonacci_slot(id: Seen, bits: u32) -> usize {
    (id.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - bits)) as usize
}

/// A pixel's mesh triangles spread to their neighbours across the edges
/// the support reaches over ([`Flood::spread`]).
struct Flood<'s, 'a> {
    scene: &'s Scene,
    cache: &'a SurfaceViews,
    support: &'s ConvexPolygon,
}

impl<'a> Flood<'_, 'a> {
    /// Adds to `views` (and `regions`, `tried`) each mesh triangle across
    /// an edge of a listed triangle whose region of the support is not
    /// empty, where the support reaches past that edge, and the same from
    /// those it adds, breadth first, up to [`MAX_GAP_PRIMITIVES`]: the
    /// triangles of a mesh around those the centres see, which tile the
    /// support with them where the surface does not fold. Their indices go
    /// to `flooded`.
    fn spread(
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
        while i < views.len() && flooded.len() < MAX_GAP_PRIMITIVES {
            let view = &views[i];
            let (surface, triangle) = (view.surface(), view.triangle());
            let mesh = match self.scene.surfaces.get(surface).map(|s| &s.geometry) {
                Some(Geometry::Mesh(mesh)) if !regions[i].is_empty() => mesh,
                _ => {
                    i += 1;
                    continue;
                }
            };
            let Some(triangle) = triangle else {
                i += 1;
                continue;
            };
            // `lines()`: in front, then the edges in `Mesh::neighbour`'s order.
            let mut edges = [[0.0; 3]; 3];
            for (e, l) in edges.iter_mut().zip(view.lines().skip(1)) {
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
                if tried.iter().any(|(t, _)| *t == id) || flooded.len() == MAX_GAP_PRIMITIVES {
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

/// The mesh triangles recent pixels of a row confirmed by a ray through
/// their region ([`exact_pixel`]'s flood): a direct-mapped table of the
/// pixel each was confirmed at.
#[derive(Default)]
struct Confirmed {
    slots: Vec<(Seen, u32)>,
}

impl Confirmed {
    const SLOTS: usize = 1 << Self::SLOT_BITS;
    const SLOT_BITS: u32 = 8;

    /// How far back in the row a confirmation stands, in pixels: a point
    /// within about as far of the support as the centres in reach are.
    const REACH: u32 = 2;

    fn recent(&self, id: Seen, x: u32) -> bool {
        (self.slots.get(fibonacci_slot(id, Self::SLOT_BITS)))
            .is_some_and(|&(s, at)| s == id && x.wrapping_sub(at) <= Self::REACH)
    }

    fn insert(&mut self, id: Seen, x: u32) {
        if self.slots.is_empty() {
            self.slots.resize(Self::SLOTS, (0, 0));
        }
        self.slots[fibonacci_slot(id, Self::SLOT_BITS)] = (id, x);
    }
}

/// Relative size, against the terms of an edge line's value at a vertex,
/// below which a vertex beyond the line counts as on it in
/// [`overlap_bound`]: a hundred times or so the rounding of clipped
/// vertices and of the line's value.
const ON_LINE: f64 = 1e-14;

/// A bound on the area two convex polygons `a` and `b` (boxes `a_box`,
/// `b_box`) overlap by, when an edge line of one has the other on its
/// outer side: `0` when every vertex is on or beyond it, else (vertices a
/// hair inside, where two regions share an edge and rounding puts one
/// vertex across it) the width of that hair, at most [`ON_LINE`] of the
/// line's terms, times the other's box's width plus height (the overlap
/// lies in that strip). `None` when no line shows it: the caller measures
/// the overlap. A repeated vertex's edge has no line (`0 ≤ 0`
/// everywhere) and separates nothing.
fn overlap_bound(
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
type Bounds = ([f64; 2], [f64; 2]);

/// Whether boxes `(lo, hi)` are apart (or touch along a line): polygons
/// within them overlap in no area.
fn boxes_apart((alo, ahi): Bounds, (blo, bhi): Bounds) -> bool {
    alo[0] >= bhi[0] || blo[0] >= ahi[0] || alo[1] >= bhi[1] || blo[1] >= ahi[1]
}

/// The views of a scene's planes and quads, built once per frame (mesh
/// triangles are built when a pixel needs them).
#[derive(Debug)]
pub(crate) struct SurfaceViews {
    /// This frame's number, unique in the process: what tells a thread's
    /// kept views ([`ViewMemo`]) of this frame from another's.
    frame: u64,
    views: Vec<Option<View>>,
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
        let meshes = (scene.surfaces.iter().enumerate())
            .filter(|(_, s)| matches!(s.geometry, Geometry::Mesh(_)))
            .map(|(i, _)| i)
            .collect();
        static FRAMES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        SurfaceViews {
            frame: FRAMES.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            views,
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

    /// What the camera's ray through screen point `c` meets first
    /// ([`crate::caster::Caster::nearest_index`]'s answer), from the screen bins where
    /// they hold `c` ([`ScreenBins::nearest_through`]). `expected`: a
    /// primitive the ray is thought to meet, which bounds the hierarchy's
    /// search otherwise ([`crate::caster::Caster::nearest_index_expecting`]).
    fn camera_hit(
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
    fn may_reach(&self, (lo, hi): ([f64; 2], [f64; 2])) -> bool {
        !self.meshes.is_empty() && self.reach.may_reach(lo, hi)
    }

    /// [`SurfaceViews::meshes_in`] past its checks, through the meshes'
    /// hierarchies: `(lo, hi)` is `polygon`'s box.
    fn search_hierarchies(
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

    /// The views of the planes and quads, by surface (`None`: another
    /// shape, or seen edge-on).
    pub(crate) fn planar_views(&self) -> &[Option<View>] {
        &self.views
    }

    /// The view of primitive `triangle` of surface `surface`.
    fn get(&self, scene: &Scene, surface: usize, triangle: u32) -> Option<ViewRef<'_>> {
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
const SHORT_EDGE: f64 = 1e-3;

/// The half-spaces `n·p + d ≥ 0` (`[n.x, n.y, n.z, d]`) whose intersection
/// holds every world point that projects into screen polygon `polygon`:
/// one plane through the camera and each edge (but edges shorter than
/// [`SHORT_EDGE`]), and the camera's plane.
fn frustum(scene: &Scene, polygon: &ConvexPolygon, planes: &mut Vec<[f64; 4]>) {
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

/// The filtered colour of pixel `(x, y)` whose neighbourhood's centres see
/// `candidates` (and the sky if `sky`), or `None` when a candidate is not
/// planar (a sphere): the caller then takes the tangent-plane path.
/// `scratch`: the calling thread's buffers.
#[allow(clippy::too_many_arguments)]
pub(crate) fn exact_pixel<'a>(
    frame: &Frame<'_>,
    options: &FilterOptions,
    filter: PixelFilter,
    (x, y): (u32, u32),
    candidates: &[Seen],
    sees_sky: bool,
    run: u32,
    cache: &'a SurfaceViews,
    scratch: &mut Scratch<'a>,
    stats: &mut PixelStats,
) -> Option<Rgba> {
    let Scratch {
        views,
        tried,
        regions,
        gaps,
        cut,
        order,
        planes,
        binned,
        memo,
        flooded,
        confirmed,
        sky_span,
        uniform_span,
        sky_clear_above: _,
    } = scratch;
    let scene = frame.scene;
    let centre = [f64::from(x) + 0.5, f64::from(y) + 0.5];
    let support = filter.support(centre);
    let mut acc = [0f64; 4];
    let mut weight = 0.0;
    let mut bound = 0.0;
    let mut parts = PixelStats::default();
    let mut add = |c: [f64; 4], w: f64, b: f64| {
        for (a, v) in acc.iter_mut().zip(c) {
            *a += v;
        }
        weight += w;
        bound += b;
    };
    // One primitive over the whole support: one integral.
    if let [id] = candidates
        && !sees_sky
        && let Some(view) = candidate_view(scene, cache, memo, *id)?
    {
        // A run of such pixels: one answer for a span of them.
        let query = SpanQuery {
            frame,
            view: &view,
            filter,
            options,
        };
        let answer = uniform_span.answer(&query, (x, y), *id, run);
        // Counted on this pixel alone, not on the span's copies of it.
        stats.filter.traversal.queries += uniform_span.take_lookups();
        if let Some(answer) = answer {
            let (c, w) =
                shade_span_pixel(frame, &view, &support, filter, centre, &answer, &mut parts);
            add(c, w, 0.0);
            parts.weight_error = weight_error(w);
            parts.filter.record_bound(0.0);
            stats.merge_parts(&parts);
            let colour = mean(acc, weight);
            // The weight is the same bits at every pixel: the box's is the
            // support's area, 1 (its corners are multiples of ½, exact in
            // floats, and so are their products at pixel coordinates below
            // 2³²); the tent's and Mitchell's integrate the support moved
            // to the centre, `centre ± r − centre`, exactly `±r`. With the
            // light known, every pixel of the span comes out as this one.
            if answer.light.is_some() && (filter != PixelFilter::Box || w == 1.0) {
                uniform_span.set_fill(colour, parts);
            }
            return Some(colour);
        }
        let region = view.region(&support);
        let whole =
            matches!(region, Cow::Borrowed(_)) || region.area() >= support.area() * (1.0 - 1e-12);
        if whole {
            // The sun over the pixel's run, when one test settled it for
            // all of the run (the span that failed was refused for its
            // texture), else the pixel's own shadow ray.
            let light = uniform_span.run_light((x, y), *id);
            let (c, w, b) = shade_piece(
                frame, &view, &region, filter, centre, options, light, &mut parts,
            );
            add(c, w, b);
            parts.weight_error = weight_error(w);
            stats.merge_parts(&parts);
            stats.filter.record_bound(b / w.abs().max(1e-300));
            return Some(mean(acc, weight));
        }
    }
    // Only the sky in reach: the sky over the whole support unless a plane,
    // quad or mesh triangle no centre sees reaches into it (the case the
    // general path below covers).
    if candidates.is_empty()
        && sees_sky
        && views_miss(cache, sky_span, filter, (x, y), &support)
        && !cache.meshes_in(scene, &support, planes, |_| true)
    {
        let (c, w) = sky_integral(
            scene,
            &support,
            Whole::Yes,
            filter,
            centre,
            sky_tolerance(options),
        );
        return Some(mean(c, w));
    }
    views.clear();
    // Every primitive tried so far and its view's index (none: edge-on).
    tried.clear();
    for &id in candidates {
        let view = candidate_view(scene, cache, memo, id)?;
        tried.push((id, view.is_some().then_some(views.len())));
        views.extend(view);
    }
    // The centres in reach may all miss a primitive that still reaches into
    // the support (a quad's corner, a triangle's tip near a vertex): every
    // plane and quad of the scene is a candidate here, and every triangle
    // of a (small) mesh one of the centres sees.
    for (surface, s) in scene.surfaces.iter().enumerate() {
        let seen_here = |t: u32| candidates.contains(&seen_id(surface, t));
        match &s.geometry {
            Geometry::Plane { .. } | Geometry::Quad { .. } if !seen_here(0) => {
                let view = cache.get(scene, surface, 0);
                tried.push((seen_id(surface, 0), view.is_some().then_some(views.len())));
                views.extend(view);
            }
            Geometry::Mesh(mesh)
                if mesh.len() <= MAX_MESH_SCAN
                    && candidates
                        .iter()
                        .any(|&id| surface_and_triangle(id).0 == surface) =>
            {
                for t in 0..mesh.len() as u32 {
                    if seen_here(t) {
                        continue;
                    }
                    let view = s
                        .geometry
                        .planar(t)
                        .and_then(|p| View::new(scene, surface, &p));
                    tried.push((seen_id(surface, t), view.is_some().then_some(views.len())));
                    views.extend(view.map(|v| ViewRef::Built(Rc::new(v))));
                }
            }
            _ => {}
        }
    }
    regions.clear();
    for v in views.iter() {
        push_region(regions, v, &support);
    }
    let mut found = 0;
    let covered: f64 = regions.iter().map(ConvexPolygon::area).sum();
    if covered < support.area() * (1.0 - GAP_AREA) {
        let flood = Flood {
            scene,
            cache,
            support: &support,
        };
        let (listed, tried_before) = (views.len(), tried.len());
        flood.spread(views, regions, tried, memo, flooded);
        // Each new triangle is confirmed, as a gap's would be, by the ray
        // through its region's centroid (or one a pixel or two back in the
        // row). A nearer primitive there is an occluder no centre sees (a
        // far hill's crest), in front of triangles the flood listed that it
        // may hide beyond the ray: the flood is undone, the occluder joins
        // the list, and the gaps are searched as without a flood.
        let mut occluder = None;
        for &v in flooded.iter() {
            let id = seen_id(views[v].surface(), views[v].triangle().unwrap_or(0));
            if confirmed.recent(id, x) {
                continue;
            }
            let c = regions[v].centroid();
            let hit = cache.camera_hit(frame, c, Some(id));
            match hit.map(|(surface, hit)| seen_id(surface, hit.triangle)) {
                Some(seen) if seen == id => confirmed.insert(id, x),
                // One the list holds: their order settles it.
                Some(seen) if tried.iter().any(|(t, _)| *t == seen) => {}
                seen => {
                    occluder = Some(seen);
                    break;
                }
            }
        }
        if let Some(seen) = occluder {
            views.truncate(listed);
            regions.truncate(listed);
            tried.truncate(tried_before);
            if let Some(seen) = seen
                && !tried.iter().any(|(t, _)| *t == seen)
            {
                found += 1;
                let view = candidate_view(scene, cache, memo, seen)?;
                if let Some(view) = &view {
                    push_region(regions, view, &support);
                }
                tried.push((seen, view.is_some().then_some(views.len())));
                views.extend(view);
            }
        }
    }
    cut.among(views, regions, &support, order);
    loop {
        // What no primitive in the list covers is sky, or primitives
        // between the centres (a large mesh's triangles smaller than a
        // pixel): the one the ray through a gap's centroid meets joins the
        // list, and the support is cut again (it may hide parts of the
        // others).
        gaps.clear();
        let mut grew = false;
        let listed = views.len();
        for r in cut.remaining.drain(..) {
            let c = r.centroid();
            let Some((surface, hit)) = cache.camera_hit(frame, c, None) else {
                // The ray meets nothing, but a mesh's triangles may still
                // reach into the gap around it: each one whose region
                // overlaps the gap joins the list.
                let mut more = false;
                cache.meshes_in_gap(scene, &r, planes, binned, |id| {
                    if tried.iter().any(|(t, _)| *t == id) {
                        return false;
                    }
                    let Some(Some(view)) = candidate_view(scene, cache, memo, id) else {
                        return false;
                    };
                    let region = regions.next_slot();
                    view.region_into(&support, region);
                    if overlap(region, &r).is_none() {
                        return false;
                    }
                    if found == MAX_GAP_PRIMITIVES {
                        more = true;
                        return true;
                    }
                    found += 1;
                    tried.push((id, Some(views.len())));
                    views.push(view);
                    regions.keep_slot();
                    grew = true;
                    false
                });
                gaps.push((r, if more { Gap::SkyAmong } else { Gap::Sky }));
                continue;
            };
            let id = seen_id(surface, hit.triangle);
            if let Some(&(_, view)) = tried.iter().find(|(t, _)| *t == id) {
                gaps.push((r, Gap::Seen(id, view)));
                continue;
            }
            let view = if found < MAX_GAP_PRIMITIVES {
                found += 1;
                let view = candidate_view(scene, cache, memo, id)?;
                if let Some(v) = &view {
                    push_region(regions, v, &support);
                    grew = true;
                }
                tried.push((id, view.is_some().then_some(views.len())));
                views.extend(view);
                tried.last().and_then(|t| t.1)
            } else {
                None
            };
            gaps.push((r, Gap::Seen(id, view)));
        }
        if !grew {
            break;
        }
        // New primitives that overlap none listed (a mesh's triangles
        // around those the centres see) only fill gaps: the rest of the
        // cut stands. Otherwise the support is cut again.
        let overlaps = (listed..views.len()).any(|v| {
            (0..views.len()).any(|u| u != v && overlap(&regions[u], &regions[v]).is_some())
        });
        cut.remaining.extend(gaps.drain(..).map(|(r, _)| r));
        if overlaps {
            for v in listed..views.len() {
                cut.insert(v, views, regions);
            }
        } else {
            for (v, region) in regions.iter().enumerate().skip(listed) {
                cut.take(v, region);
            }
        }
    }
    // Weight no piece has, or two have (|k| ≤ 1 for every pixel filter):
    // at most the larger of full contrast and the sky's range off.
    add([0.0; 4], 0.0, cut.unaccounted * sky_range(scene).max(1.0));
    for (i, piece) in cut.visible(regions) {
        let (c, w, b) = shade_piece(
            frame, &views[i], piece, filter, centre, options, None, &mut parts,
        );
        add(c, w, b);
    }
    for r in &cut.slivers {
        // The sky at its centroid, whatever covers it: its whole weight
        // times the larger of full contrast and the sky's range as the
        // bound (at most 1e-9 of the support's).
        let w = filter.integral(r, centre);
        let c = r.centroid();
        let colour = sky(scene, &scene.camera.ray(c[0], c[1])).to_array();
        add(
            colour.map(|v| f64::from(v) * w),
            w,
            w.abs() * sky_range(scene).max(1.0),
        );
    }
    let sky_over = |r: &ConvexPolygon| {
        sky_integral(
            scene,
            r,
            Whole::Unknown,
            filter,
            centre,
            sky_tolerance(options),
        )
    };
    for (r, gap) in gaps.iter() {
        match *gap {
            Gap::Sky => {
                let (c, w) = sky_over(r);
                add(c, w, 0.0);
            }
            Gap::SkyAmong => {
                let (c, w) = sky_over(r);
                add(c, w, w.abs());
            }
            Gap::Seen(id, view) => {
                // A gap the list leaves open (past the cap, or where a
                // listed primitive's edge and the ray disagree): the
                // primitive the ray through its centroid meets, as if it
                // covered the gap, with the gap's whole weight (full
                // contrast) as the bound, and the weight of any part of
                // the gap beyond that primitive's horizon (which it does
                // not cover: its colour is not known).
                let view = match view {
                    Some(i) => Some(views[i].clone()),
                    None => candidate_view(scene, cache, memo, id)?,
                };
                if let Some(view) = view {
                    let (c, w, b) =
                        shade_piece(frame, &view, r, filter, centre, options, None, &mut parts);
                    let beyond = (filter.integral(r, centre) - w).abs();
                    add(c, w, b + w.abs() + beyond);
                } else {
                    let (c, w) = sky_over(r);
                    add(c, w, w.abs());
                }
            }
        }
    }
    parts.weight_error = weight_error(weight);
    stats.merge_parts(&parts);
    stats.filter.record_bound(bound / weight.abs().max(1e-300));
    Some(mean(acc, weight))
}

/// How far `weight`, what a pixel's pieces were given, is from the pixel
/// filter's whole weight: 1, as every [`PixelFilter`] integrates to 1 over
/// its support (so nothing is integrated again per pixel).
fn weight_error(weight: f64) -> f64 {
    (weight - 1.0).abs()
}

/// Appends `view`'s region of `support` to `regions`, written in its place
/// ([`View::region_into`]).
fn push_region(regions: &mut Regions, view: &View, support: &ConvexPolygon) {
    view.region_into(support, regions.next_slot());
    regions.keep_slot();
}

/// The regions of a pixel's views, in slots kept from pixel to pixel: a
/// region is written into its slot in place, vertex by vertex, where
/// pushing one would copy its whole capacity ([`ConvexPolygon`] holds
/// [`MAX_VERTICES`](quadtex_core::MAX_VERTICES) inline), and
/// clearing keeps the slots.
#[derive(Default)]
struct Regions {
    slots: Vec<ConvexPolygon>,
    len: usize,
}

impl Regions {
    fn clear(&mut self) {
        self.len = 0;
    }

    /// The slot after the last region: what is written there is a region
    /// once [`Regions::keep_slot`] keeps it.
    fn next_slot(&mut self) -> &mut ConvexPolygon {
        if self.len == self.slots.len() {
            self.slots.push(ConvexPolygon::EMPTY);
        }
        &mut self.slots[self.len]
    }

    /// Keeps the first `len` regions.
    fn truncate(&mut self, len: usize) {
        self.len = self.len.min(len);
    }

    fn keep_slot(&mut self) {
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
fn overlap(a: &ConvexPolygon, b: &ConvexPolygon) -> Option<ConvexPolygon> {
    if a.is_empty() || b.is_empty() || boxes_apart(a.bounds(), b.bounds()) {
        return None;
    }
    let o = a.intersect(b);
    (o.area() > 0.0).then_some(o)
}

/// What a part of a support no listed primitive covers shows.
enum Gap {
    /// The ray through its centroid meets nothing, nor does a mesh reach
    /// into it.
    Sky,
    /// The ray through its centroid meets nothing, but mesh triangles
    /// reach into it past [`MAX_GAP_PRIMITIVES`]: the sky, its whole
    /// weight as the bound.
    SkyAmong,
    /// The ray through its centroid meets this primitive (and its view's
    /// index, if it has one in the list).
    Seen(Seen, Option<usize>),
}

/// A support cut among primitives: the visible pieces of each (by index
/// into the views), the parts none covers yet, and slivers. Its buffers
/// are reused from pixel to pixel ([`Scratch`]).
#[derive(Default)]
struct Cut {
    pieces: Vec<(usize, ConvexPolygon)>,
    remaining: Vec<ConvexPolygon>,
    /// Where [`carve`] gathers what lies outside a region.
    spare: Vec<ConvexPolygon>,
    /// What [`Cut::insert`] gives the view it inserts, a piece it cuts,
    /// and which views are behind it.
    parts: Vec<ConvexPolygon>,
    carved: Vec<ConvexPolygon>,
    behind: Vec<bool>,
    /// Pieces of at most `sliver_area` (rounding along shared edges): not
    /// cut further, nor integrated over a texture.
    slivers: Vec<ConvexPolygon>,
    sliver_area: f64,
    /// Area of the support counted twice or not at all when the regions
    /// were taken whole ([`Cut::tiling`]): slivers of rounding along shared
    /// edges, not located.
    unaccounted: f64,
    /// The boxes of the non-empty regions [`Cut::tiling`] compares, and
    /// their indices.
    boxes: Vec<(usize, Bounds)>,
    /// How many of the first regions are taken whole: all of them when
    /// they tile the support or lie apart ([`Cut::tiling`]), each view's
    /// piece its whole region, read from the regions, not copied into
    /// `pieces`; 0 when the support was cut front to back.
    whole: usize,
}

impl Cut {
    /// Cuts the support among `views` (their `regions` of it) front to
    /// back, replacing what the cut held.
    fn among(
        &mut self,
        views: &[ViewRef<'_>],
        regions: &[ConvexPolygon],
        support: &ConvexPolygon,
        order: &mut Order,
    ) {
        self.pieces.clear();
        self.remaining.clear();
        self.slivers.clear();
        self.sliver_area = GAP_AREA * support.area();
        self.unaccounted = 0.0;
        self.whole = 0;
        if self.taken_whole(regions, support) {
            return;
        }
        self.remaining.push(support.clone());
        for &i in order.front_to_back(views, regions) {
            self.take(i, &regions[i]);
        }
    }

    /// The cut when no two `regions` overlap by more than a sliver: each
    /// view sees its whole region, whatever their order, and what they
    /// leave of the support (nothing, but for slivers, when they tile it)
    /// is left for the gaps. This is what cutting them front to back
    /// gives, but for how the parts left are split, with fewer pieces (a
    /// region cut into each part it reaches) and no order. Returns false,
    /// the cut untouched, when two overlap.
    fn taken_whole(&mut self, regions: &[ConvexPolygon], support: &ConvexPolygon) -> bool {
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

    /// Gives the views taken whole their regions as pieces, so that the
    /// cut can be cut again ([`Cut::insert`]).
    fn pieces_from_whole(&mut self, regions: &[ConvexPolygon]) {
        let whole = std::mem::take(&mut self.whole);
        for (i, region) in regions[..whole].iter().enumerate() {
            if !region.is_empty() {
                self.pieces.push((i, region.clone()));
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
    fn tiling(&mut self, regions: &[ConvexPolygon], support: &ConvexPolygon) -> bool {
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

    /// Each visible piece and the index of the view that sees it, in
    /// `regions` when they tile the support.
    fn visible<'c>(
        &'c self,
        regions: &'c [ConvexPolygon],
    ) -> impl Iterator<Item = (usize, &'c ConvexPolygon)> + 'c {
        let whole = (regions[..self.whole].iter().enumerate()).filter(|(_, r)| !r.is_empty());
        whole.chain(self.pieces.iter().map(|(i, p)| (*i, p)))
    }

    /// Gives view `v` what its `region` covers of the parts not yet
    /// covered (it lies behind every view taken before).
    fn take(&mut self, v: usize, region: &ConvexPolygon) {
        if region.is_empty() {
            return;
        }
        let (sliver_area, pieces) = (self.sliver_area, &mut self.pieces);
        carve(
            &mut self.remaining,
            region,
            &mut self.spare,
            &mut self.slivers,
            sliver_area,
            |piece, slivers, at| {
                if piece.area() > sliver_area {
                    pieces.push((v, piece));
                } else {
                    slivers.insert(at, piece);
                }
            },
        );
    }

    /// Adds view `n` to a cut made front to back of the views before it
    /// (in `views` and their `regions`): `n` sees its region less those
    /// of the views in front of it where they overlap (decided at the
    /// overlap's centroid, as [`Order::front_to_back`] decides), and its
    /// region is cut out of the parts not yet covered and of the pieces of
    /// the views behind it. The pieces are those of cutting the support
    /// again with `n` in its place in the order (when occlusion is not
    /// cyclic), but only what `n`'s region reaches is cut, and `n`'s own
    /// region only where a view in front covers it. Regions taken whole
    /// become pieces first ([`Cut::pieces_from_whole`]).
    fn insert(&mut self, n: usize, views: &[ViewRef<'_>], regions: &[ConvexPolygon]) {
        self.pieces_from_whole(regions);
        let region = &regions[n];
        if region.is_empty() {
            return;
        }
        let Cut {
            pieces,
            remaining,
            spare,
            parts,
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
        parts.clear();
        parts.push(region.clone());
        for (v, other) in regions[..n].iter().enumerate() {
            let Some(o) = overlap(region, other) else {
                continue;
            };
            let c = o.centroid();
            if views[n].depth_at(c) < views[v].depth_at(c) {
                behind[v] = true;
            } else {
                carve(parts, other, spare, slivers, sliver_area, drop);
            }
        }
        carve(remaining, region, spare, slivers, sliver_area, drop);
        // In place: a piece `n` misses stays where it is, one it reaches
        // is replaced by what lies outside it.
        let mut i = 0;
        while i < pieces.len() {
            let v = pieces[i].0;
            if !behind.get(v).copied().unwrap_or(false)
                || boxes_apart(pieces[i].1.bounds(), region.bounds())
            {
                i += 1;
                continue;
            }
            carved.clear();
            carved.push(pieces[i].1.clone());
            carve(carved, region, spare, slivers, sliver_area, drop);
            let kept = carved.len();
            pieces.splice(i..=i, carved.drain(..).map(|p| (v, p)));
            i += kept;
        }
        for part in parts.drain(..) {
            if part.area() > sliver_area {
                pieces.push((n, part));
            } else if part.area() > 0.0 {
                slivers.push(part);
            }
        }
    }
}

/// Cuts `region` out of `parts` in place: a part the region misses stays
/// where it is (a polygon moved is its whole capacity copied), one it
/// reaches is replaced by what lies outside it, in the same place in the
/// list, and outside pieces of at most `sliver_area` go to `slivers`.
/// What lies inside goes to `inside(piece, slivers, at)`, with `at` where
/// in `slivers` it goes if it is one: before the outside's slivers, as it
/// was cut first (the slivers' sum keeps its order). `spare`: a buffer.
fn carve(
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
        let piece = r.split_by(region, |p| {
            if p.area() > sliver_area {
                spare.push(p);
            } else {
                slivers.push(p);
            }
        });
        if piece.area() > 0.0 {
            inside(piece, slivers, slivers_before);
        }
        let added = spare.len();
        parts.splice(i..=i, spare.drain(..));
        i += added;
    }
}

/// Buffers one thread reuses from pixel to pixel, so that the exact pixel
/// allocates nothing once they have grown to the largest neighbourhood.
#[derive(Default)]
pub(crate) struct Scratch<'a> {
    views: Vec<ViewRef<'a>>,
    /// Every primitive tried so far and its view's index (none: edge-on).
    tried: Vec<(Seen, Option<usize>)>,
    regions: Regions,
    gaps: Vec<(ConvexPolygon, Gap)>,
    cut: Cut,
    order: Order,
    planes: Vec<[f64; 4]>,
    /// The triangles [`SurfaceViews::meshes_in_gap`] lists.
    binned: Vec<(u32, u32, u32)>,
    memo: ViewMemo,
    /// The views [`Flood::spread`] added, by index.
    flooded: Vec<usize>,
    confirmed: Confirmed,
    sky_span: SkySpan,
    uniform_span: UniformSpan,
    /// Where [`sky_at_centre`]'s bound is surely within the tolerance
    /// (once per row: the scene and options are the frame's).
    sky_clear_above: Option<f64>,
}

impl<'a> Scratch<'a> {
    /// Empty buffers for a row of the frame of `cache`, with the views of
    /// mesh triangles this thread kept from its last row of that frame
    /// ([`ViewMemo`]); [`Scratch::end_row`] keeps them for its next.
    pub(crate) fn for_row(cache: &SurfaceViews) -> Scratch<'a> {
        Scratch {
            memo: ViewMemo::take_for(cache.frame),
            ..Scratch::default()
        }
    }

    /// Ends a row: the thread keeps its views for its next row.
    pub(crate) fn end_row(self) {
        self.memo.keep();
    }

    /// The colour of box-filtered pixel `(x, y)` whose centres in reach all
    /// see the sky, when the rectangle of its sky span ([`SkySpan`]) is
    /// clear of every plane, quad and mesh triangle and the sky's value at
    /// its centre is within the tolerance ([`sky_at_centre`]): what the
    /// sky-only branch of [`exact_pixel`] gives it (the support's area is
    /// 1, so the mean is that value), without building the support or
    /// testing it. `None` leaves the pixel to [`exact_pixel`]. A triangle
    /// that reaches into no part of the rectangle reaches into none of the
    /// pixel's support, which lies inside it.
    pub(crate) fn sky_pixel(
        &mut self,
        scene: &Scene,
        cache: &'a SurfaceViews,
        options: &FilterOptions,
        filter: PixelFilter,
        (x, y): (u32, u32),
    ) -> Option<Rgba> {
        if filter != PixelFilter::Box || !self.sky_span.views_clear(cache, filter, (x, y)) {
            return None;
        }
        let span = &mut self.sky_span;
        let meshes_clear = match span.meshes_clear {
            Some(clear) => clear,
            None => {
                let wide = span.wide.as_ref()?;
                let clear = !cache.meshes_in(scene, wide, &mut self.planes, |_| true);
                span.meshes_clear = Some(clear);
                clear
            }
        };
        if !meshes_clear {
            return None;
        }
        let centre = [f64::from(x) + 0.5, f64::from(y) + 0.5];
        let tolerance = sky_tolerance(options);
        let clear_above = *self
            .sky_clear_above
            .get_or_insert_with(|| sky_clear_above(scene, tolerance));
        let ray = scene.camera.ray(centre[0], centre[1]);
        if ray.direction.y - std::f64::consts::FRAC_1_SQRT_2 * sky_step(scene) >= clear_above {
            // What `sky_at_centre` gives, its bound not computed.
            return Some(mean(sky(scene, &ray).to_array().map(f64::from), 1.0));
        }
        let (c, bound) = sky_at_centre(scene, centre)?;
        (bound <= tolerance).then(|| mean(c, 1.0))
    }

    /// The colour and counters of pixel `(x, y)` when a span set up by a
    /// pixel before it in its row answers it without any work
    /// ([`UniformSpan::filled`]).
    pub(crate) fn span_fill(&self, (x, y): (u32, u32)) -> Option<&(Rgba, PixelStats)> {
        self.uniform_span.filled((x, y))
    }
}

/// Pixels of one row, from the one that set the span up to `until`
/// (exclusive), whose filter supports every plane and quad of the scene
/// misses when `clear` ([`views_miss`]).
#[derive(Default)]
struct SkySpan {
    row: Option<u32>,
    until: u32,
    clear: bool,
    /// The rectangle the span's supports cover.
    wide: Option<ConvexPolygon>,
    /// Whether no mesh triangle may reach into `wide`, once asked.
    meshes_clear: Option<bool>,
}

impl SkySpan {
    /// Whether every plane and quad misses the rectangle the supports of
    /// the span of pixel `(x, y)` cover, a span of [`SKY_SPAN`] pixels set
    /// up from `x` when none of this row holds it ([`views_miss`]).
    fn views_clear(
        &mut self,
        cache: &SurfaceViews,
        filter: PixelFilter,
        (x, y): (u32, u32),
    ) -> bool {
        if self.row != Some(y) || x >= self.until {
            let wide = span_rect(filter, (x, y), SKY_SPAN);
            *self = SkySpan {
                row: Some(y),
                until: x.saturating_add(SKY_SPAN),
                clear: (cache.views.iter().flatten())
                    .all(|v| matches!(v.placement(&wide), Placement::Outside)),
                wide: Some(wide),
                meshes_clear: None,
            };
        }
        self.clear
    }
}

/// Pixels a row's [`SkySpan`] covers.
const SKY_SPAN: u32 = 32;

/// Whether every plane and quad of the scene misses the support of pixel
/// `(x, y)` (a pixel whose neighbourhood's centres all see the sky), as
/// [`View::misses`] decides it, with the test made once for a span of
/// [`SKY_SPAN`] pixels of the row: the rectangle their supports cover is
/// wholly beyond one line of each view. That implies the same of each
/// pixel's support, computed: its corners lie in the rectangle (the same
/// float expressions, monotone in the pixel), and each line's side test,
/// `a·x + b·y + c` in floats, is monotone in `x` and in `y`, so it is
/// largest at one of the rectangle's corners. A span that fails (a view
/// reaches into it somewhere) leaves its pixels to the test one by one.
fn views_miss(
    cache: &SurfaceViews,
    span: &mut SkySpan,
    filter: PixelFilter,
    (x, y): (u32, u32),
    support: &ConvexPolygon,
) -> bool {
    span.views_clear(cache, filter, (x, y))
        || cache.views.iter().flatten().all(|v| v.misses(support))
}

/// The largest difference between the sky's colours in any channel: how
/// far its colour anywhere is from its colour at one point.
fn sky_range(scene: &Scene) -> f64 {
    match scene.sky {
        crate::scene::Sky::Solid(_) => 0.0,
        crate::scene::Sky::Gradient { horizon, zenith } => (horizon - zenith)
            .to_array()
            .iter()
            .fold(0.0, |m, v| m.max(f64::from(v.abs()))),
    }
}

fn mean(acc: [f64; 4], weight: f64) -> Rgba {
    quadtex_core::RegionIntegral {
        colour: quadtex_core::WeightedColour(acc),
        weight,
        error_bound: 0.0,
    }
    .mean()
    .unwrap_or(Rgba::TRANSPARENT)
}

/// The buffers of [`Order::front_to_back`].
#[derive(Default)]
struct Order {
    left: Vec<usize>,
    behind: Vec<bool>,
    placed: Vec<bool>,
    order: Vec<usize>,
}

impl Order {
    /// Indices of `views` front to back: repeatedly the one no other
    /// remaining view is in front of where their regions overlap (the
    /// nearest at its own centroid if occlusion is cyclic).
    fn front_to_back(&mut self, views: &[ViewRef<'_>], regions: &[ConvexPolygon]) -> &[usize] {
        let Order {
            left,
            behind,
            placed,
            order,
        } = self;
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
                let c = overlap.centroid();
                let (di, dj) = (views[i].depth_at(c), views[j].depth_at(c));
                behind[a * n + b] = dj < di;
                behind[b * n + a] = di < dj;
            }
        }
        placed.clear();
        placed.resize(n, false);
        order.clear();
        for _ in 0..n {
            let free = |a: usize| !placed[a] && (0..n).all(|b| placed[b] || !behind[a * n + b]);
            let pick = (0..n).find(|&a| free(a)).unwrap_or_else(|| {
                // Cyclic occlusion: the nearest at its own centroid.
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
        }
        order
    }
}

/// `(Σ colour·k, Σ k, bound)` of surface `view` over screen `piece`, lit
/// by `light` when the caller knows it for the whole piece (a run's,
/// [`UniformSpan::run_light`]), else by the piece's own shadow ray.
#[allow(clippy::too_many_arguments)]
fn shade_piece(
    frame: &Frame<'_>,
    view: &View,
    piece: &ConvexPolygon,
    filter: PixelFilter,
    centre: [f64; 2],
    options: &FilterOptions,
    light: Option<[f32; 3]>,
    stats: &mut PixelStats,
) -> ([f64; 4], f64, f64) {
    let (c, w, b) = match frame.sampler(view.surface()) {
        Some(sampler) => {
            stats.textured = 1;
            let r = sampler.integrate_region(
                view.projection(),
                piece,
                filter,
                centre,
                options,
                &mut stats.filter,
            );
            (Some(r.colour.0), r.weight, r.error_bound)
        }
        None => (None, filter.integral(piece, centre), 0.0),
    };
    (tint_and_light(frame, view, piece, c, w, light), w, b)
}

/// A piece's colour from its texture integral `texture` (`None`: the
/// surface is untextured) and weight `w`: tinted by the surface's colour,
/// then lit by `light` when the caller knows it for the whole piece, else
/// by the piece's own shadow ray ([`light_piece`]).
fn tint_and_light(
    frame: &Frame<'_>,
    view: &View,
    piece: &ConvexPolygon,
    texture: Option<[f64; 4]>,
    w: f64,
    light: Option<[f32; 3]>,
) -> [f64; 4] {
    let tint = frame.scene.surfaces[view.surface()]
        .colour
        .to_array()
        .map(f64::from);
    let mut c = match texture {
        Some(mut c) => {
            for (v, t) in c.iter_mut().zip(tint) {
                *v *= t;
            }
            c
        }
        None => tint.map(|t| t * w),
    };
    match light.or_else(|| view.uniform_light(|| uniform_light(frame, view))) {
        Some(k) => apply_light(&mut c, k),
        None => light_piece(frame, view, piece, &mut c),
    }
    c
}

/// The lighting factor [`lambert`] gives every point of mesh triangle
/// `view`, when it is shown to be one: the triangle lies in front of the
/// camera, its plane is not seen near edge-on (so the side facing the
/// camera is the same at every point, `|n·(p − c)| > 10⁻⁶ |n| |p − c|`),
/// and, where the sun is above that side, the sun grid shows no other
/// triangle of the mesh between it and the sun
/// and every other surface is a plane or quad the sun's rays from the
/// triangle miss, by a margin (`10⁻⁵` of the distance from the camera, ten
/// times the shadow ray's lift;
/// [`Caster::sun_clear_of_triangle`](crate::caster::Caster::sun_clear_of_triangle)):
/// no shadow ray leaving the triangle meets anything, and the cosine is
/// the same.
/// `None` otherwise (each piece then casts its own shadow ray,
/// [`light_piece`]).
fn uniform_light(frame: &Frame<'_>, view: &View) -> Option<[f32; 3]> {
    let scene = frame.scene;
    let Lighting::Lambert { direction, .. } = scene.lighting else {
        return None;
    };
    let (surface, triangle) = (view.surface(), view.triangle()?);
    let Geometry::Mesh(mesh) = &scene.surfaces.get(surface)?.geometry else {
        return None;
    };
    let corners = mesh.corners(triangle as usize)?;
    let camera = scene.camera.position;
    let forward = scene.camera.forward();
    let normal = view.normal();
    let mut far = 0.0f64;
    for p in corners {
        let d = p - camera;
        let distance = d.length();
        let in_front = d.dot(forward) > 1e-6 * distance;
        if !in_front {
            return None;
        }
        far = far.max(distance);
    }
    let side = normal.dot(corners[0] - camera);
    let facing = side.abs() > 1e-6 * far * normal.length();
    if !facing {
        return None;
    }
    // As `lambert` flips it: toward the camera.
    let n = if side > 0.0 { -normal } else { normal };
    let cos = n.dot(direction).max(0.0);
    if cos > 0.0
        && !frame
            .rays
            .sun_clear_of_triangle((surface, triangle), &corners, camera, direction)
    {
        return None;
    }
    let k = if cos > 0.0 { cos as f32 } else { 0.0 };
    Some(crate::frame::lit_factor(&scene.lighting, k))
}

/// Multiplies `c` by `light`, a lighting factor per channel.
fn apply_light(c: &mut [f64; 4], light: [f32; 3]) {
    for (v, f) in c.iter_mut().zip(light) {
        *v *= f64::from(f);
    }
}

/// What [`shade_piece`] gives a pixel of a [`UniformSpan`] whose whole
/// support is `support`: the span's texture colour (or the surface's tint
/// alone) times the filter's weight there, lit by the span's light or, when
/// the span has none, by the support's own shadow ray. The arithmetic is
/// [`shade_piece`]'s, step for step, so that a pixel comes out the same
/// either way.
fn shade_span_pixel(
    frame: &Frame<'_>,
    view: &View,
    support: &ConvexPolygon,
    filter: PixelFilter,
    centre: [f64; 2],
    answer: &SpanAnswer,
    stats: &mut PixelStats,
) -> ([f64; 4], f64) {
    let w = filter.integral(support, centre);
    let texture = answer.texture.map(|colour| {
        stats.textured = 1;
        // What the region integral's uniform shortcut counts.
        stats.filter.footprints += 1;
        stats.filter.fragments += 1;
        quadtex_core::WeightedColour::from_colour(colour, w).0
    });
    (
        tint_and_light(frame, view, support, texture, w, answer.light),
        w,
    )
}

/// Multiplies `c` by the lighting at `piece`'s centroid on `view`'s
/// primitive (its shadow ray's answer there).
fn light_piece(frame: &Frame<'_>, view: &View, piece: &ConvexPolygon, c: &mut [f64; 4]) {
    let scene = frame.scene;
    if let Lighting::Lambert { .. } = scene.lighting {
        let s = piece.centroid();
        let ray = scene.camera.ray(s[0], s[1]);
        let t = view.depth_at(s);
        if t.is_finite() {
            // The camera's ray is normalised; depth_at is per unnormalised d.
            let d = scene.camera.direction(s[0], s[1]);
            let point = scene.camera.position + d * t;
            let from = (view.surface(), view.triangle().unwrap_or(0));
            let k = lambert(&frame.rays, from, view.normal(), point, &ray);
            apply_light(c, k);
        }
    }
}

/// The screen row where the camera's ray through column `px` is level
/// (`direction.y = 0`), if the camera is not rolled onto its side.
fn level_line(scene: &Scene, px: f64) -> Option<f64> {
    let cam = &scene.camera;
    let (width, height) = (f64::from(cam.width), f64::from(cam.height));
    let aspect = width / height;
    let sx = (2.0 * px / width - 1.0) * cam.tan_half_fov * aspect;
    // forward.y + right.y·sx + up.y·sy = 0.
    if cam.up.y.abs() < 1e-12 {
        return None;
    }
    let sy = -(cam.forward.y + cam.right.y * sx) / cam.up.y;
    Some((1.0 - sy / cam.tan_half_fov) * height / 2.0)
}

/// Cells per pixel side for the sky's midpoint rule.
const SKY_CELLS: f64 = 4.0;

/// How far the sky's integral over a pixel may be from exact when it is
/// taken at the pixel's centre alone ([`sky_at_centre`]): a quarter of the
/// error bound the texture filter aims at (the default under a fixed level).
fn sky_tolerance(options: &FilterOptions) -> f64 {
    use quadtex_core::LevelOfDetail;
    match (options.level_of_detail(), LevelOfDetail::default()) {
        (LevelOfDetail::ErrorBound(e), _) | (_, LevelOfDetail::ErrorBound(e)) => 0.25 * e,
        _ => 0.0,
    }
}

/// The gradient sky at the centre of the unit pixel centred at `centre`,
/// and a bound (per channel) on how far that is from the sky's mean over
/// the pixel; `None` for a solid sky or where the pixel may reach the level
/// line (where the gradient's square root has an unbounded derivative).
///
/// The bound: with `g = 2·tan(fov/2)/height` the change of the unnormalised
/// ray direction per pixel (the same along both axes), the unit direction's
/// height `y` changes by at most `g` and bends by at most `3g²` per pixel
/// (differentiating `D/|D|` twice with `|D| ≥ 1`), so `t = √y` has second
/// derivatives at most `T = 3g²/(2√y) + g²/(4y^{3/2})` along any screen
/// direction, `y` its least over the pixel (at least the centre's less
/// `g/√2`). The midpoint rule over a unit square is then off by at most
/// `T·∫|δ|²/2 = T/12` in `t`, times the sky's contrast in colour. Where the
/// whole pixel looks below level the sky is the horizon colour: exact.
fn sky_at_centre(scene: &Scene, centre: [f64; 2]) -> Option<([f64; 4], f64)> {
    let crate::scene::Sky::Gradient { horizon, zenith } = scene.sky else {
        return None;
    };
    let ray = scene.camera.ray(centre[0], centre[1]);
    let g = sky_step(scene);
    let y_min = ray.direction.y - std::f64::consts::FRAC_1_SQRT_2 * g;
    let bound = if y_min + std::f64::consts::SQRT_2 * g < 0.0 {
        0.0
    } else if y_min > 0.0 {
        let contrast = sky_contrast(horizon, zenith);
        sky_bound(g, contrast, y_min)
    } else {
        return None;
    };
    Some((sky(scene, &ray).to_array().map(f64::from), bound))
}

/// The gradient sky's largest change in a channel, horizon to zenith.
#[inline]
fn sky_contrast(horizon: Rgba, zenith: Rgba) -> f64 {
    (horizon.to_array().iter().zip(zenith.to_array()))
        .map(|(h, z)| f64::from((z - h).abs()))
        .fold(0.0, f64::max)
}

/// `g` of [`sky_at_centre`]: the change of the unnormalised ray direction
/// per pixel.
#[inline]
fn sky_step(scene: &Scene) -> f64 {
    2.0 * scene.camera.tan_half_fov / f64::from(scene.camera.height)
}

/// [`sky_at_centre`]'s bound where the least height over the pixel is
/// `y_min > 0`: `T/12` times the contrast.
#[inline]
fn sky_bound(g: f64, contrast: f64, y_min: f64) -> f64 {
    // 1.5/√y + 0.25/y^{3/2} over one division (one a sky pixel).
    let second = g * g * (1.5 * y_min + 0.25) / (y_min * y_min.sqrt());
    second / 12.0 * contrast
}

/// A height above which [`sky_at_centre`]'s bound is within `tolerance`
/// (`∞` where none is, or the sky is solid): the bound falls as `y_min`
/// grows, and this is where it is half the tolerance (bisected), so that
/// the bound computed in floats above it is within the tolerance too. A
/// sky pixel whose `y_min` is past it takes the centre's value without
/// the bound's square root and divisions, the same answer.
fn sky_clear_above(scene: &Scene, tolerance: f64) -> f64 {
    let crate::scene::Sky::Gradient { horizon, zenith } = scene.sky else {
        return f64::INFINITY;
    };
    let contrast = sky_contrast(horizon, zenith);
    let g = sky_step(scene);
    let within = |y: f64| sky_bound(g, contrast, y) <= 0.5 * tolerance;
    if !within(1.0) {
        return f64::INFINITY;
    }
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..64 {
        let mid = 0.5 * (lo + hi);
        if within(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// Whether a piece is the filter's whole support, when the caller knows.
#[derive(Debug, Clone, Copy)]
enum Whole {
    Yes,
    Unknown,
}

/// `(Σ sky·k, Σ k)` over screen piece `piece`. A whole box-filtered pixel
/// is taken at its centre where [`sky_at_centre`]'s bound is within
/// `tolerance`.
fn sky_integral(
    scene: &Scene,
    piece: &ConvexPolygon,
    whole: Whole,
    filter: PixelFilter,
    centre: [f64; 2],
    tolerance: f64,
) -> ([f64; 4], f64) {
    let colour_at = |s: [f64; 2]| -> [f64; 4] {
        let ray: Ray = scene.camera.ray(s[0], s[1]);
        sky(scene, &ray).to_array().map(f64::from)
    };
    if let crate::scene::Sky::Solid(c) = scene.sky {
        let w = filter.integral(piece, centre);
        return (c.to_array().map(|v| f64::from(v) * w), w);
    }
    let whole = match whole {
        Whole::Yes => true,
        Whole::Unknown => piece.area() >= filter.support(centre).area() * (1.0 - 1e-12),
    };
    if whole
        && filter == PixelFilter::Box
        && let Some((c, bound)) = sky_at_centre(scene, centre)
        && bound <= tolerance
    {
        let w = piece.area();
        return (c.map(|v| v * w), w);
    }
    let (lo, hi) = piece.bounds();
    let step = 1.0 / SKY_CELLS;
    let level = level_line(scene, 0.5 * (lo[0] + hi[0]));
    if whole && level.is_none_or(|yh| yh < lo[1] - 1.0 || yh > hi[1] + 1.0) {
        // The whole support, away from the level line: the sky is smooth
        // there; 2×2 Gauss–Legendre points per unit cell of the filter.
        const G: [f64; 2] = [0.211_324_865_405_187_1, 0.788_675_134_594_812_9];
        let (mut acc, mut weight) = ([0.0; 4], 0.0);
        let r = filter.radius();
        let cells = (2.0 * r).ceil() as i32;
        for j in 0..cells {
            for i in 0..cells {
                let (x0, y0) = (centre[0] - r + f64::from(i), centre[1] - r + f64::from(j));
                let (sx, sy) = ((2.0 * r).min(1.0), (2.0 * r).min(1.0));
                for gy in G {
                    for gx in G {
                        let s = [x0 + gx * sx, y0 + gy * sy];
                        let w = filter.weight(s[0] - centre[0], s[1] - centre[1]) * sx * sy / 4.0;
                        for (a, v) in acc.iter_mut().zip(colour_at(s)) {
                            *a += v * w;
                        }
                        weight += w;
                    }
                }
            }
        }
        // The weights' exact total (the points integrate k only approximately).
        let exact = filter.integral(piece, centre);
        return (acc.map(|v| v * exact / weight), exact);
    }
    // Row boundaries: quarter pixels, graded geometrically towards the line
    // where the view turns level (the gradient's square root has an
    // unbounded derivative there) when it lies at the piece's bottom.
    // Eight halvings: the last row, within 2^-8 of the line's distance,
    // errs by about 0.04·√g·h^{3/2} times the contrast (the midpoint rule
    // on √s over [0, h]; g as in [`sky_at_centre`]), under 1e-6 at the
    // demo's sizes; twenty halvings changed the level line's rows by under
    // 1e-6 and cost 2.3 times the instructions (the demo at 1920 wide:
    // 0.19 → 0.08 G). The coarse rows dominate the error (test
    // `the_sky_at_the_level_line_matches_a_dense_sum`).
    let mut rows = Vec::with_capacity(12);
    match level {
        Some(yh) if yh >= lo[1] && yh <= hi[1] + step => {
            let top = lo[1];
            let d = yh - top;
            rows.push(top);
            for k in 1..=8 {
                let y = yh - d * 0.5f64.powi(k);
                if y > top && y < hi[1] {
                    rows.push(y);
                }
            }
            rows.push(hi[1]);
        }
        _ => {
            let mut y = (lo[1] * SKY_CELLS).floor() * step;
            while y < hi[1] {
                rows.push(y);
                y += step;
            }
            rows.push(y);
        }
    }
    let (mut acc, mut weight) = ([0.0; 4], 0.0);
    // A whole box-filtered pixel is its bounding box: each cell is a
    // rectangle whose weight is its area, no clipping needed.
    let rectangle = whole && filter == PixelFilter::Box;
    for pair in rows.windows(2) {
        let (y0, y1) = (pair[0], pair[1]);
        let mut x0 = (lo[0] * SKY_CELLS).floor() * step;
        while x0 < hi[0] {
            // The cell's sample point and weight.
            let sample = if rectangle {
                let (a, b) = (x0.max(lo[0]), (x0 + step).min(hi[0]));
                let w = (b - a) * (y1 - y0);
                (w > 0.0).then_some(([0.5 * (a + b), 0.5 * (y0 + y1)], w))
            } else {
                let cell = piece.clip_rect(x0, y0, x0 + step, y1);
                (cell.area() > 0.0).then(|| (cell.centroid(), filter.integral(&cell, centre)))
            };
            if let Some((s, w)) = sample {
                for (a, v) in acc.iter_mut().zip(colour_at(s)) {
                    *a += v * w;
                }
                weight += w;
            }
            x0 += step;
        }
    }
    (acc, weight)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The built-in demo scene with its camera at `width × height`.
    fn demo_at(width: u32, height: u32) -> Scene {
        let demo = crate::demo_scene().unwrap();
        Scene {
            camera: demo.camera.with_size(width, height),
            ..demo
        }
    }

    /// A thread's kept views come back for the frame they were built
    /// for, and for no other.
    #[test]
    fn a_memo_is_kept_for_its_frame_alone() {
        let view = Rc::new(View::facing_at(1.0));
        let mut memo = ViewMemo::take_for(7);
        memo.slots.resize(ViewMemo::SLOTS, (0, None));
        memo.slots[ViewMemo::slot(42)] = (42, Some(view));
        memo.keep();
        let again = ViewMemo::take_for(7);
        assert!(matches!(
            again.slots.get(ViewMemo::slot(42)),
            Some((42, Some(_)))
        ));
        again.keep();
        let other = ViewMemo::take_for(8);
        assert_eq!(other.frame, 8);
        assert!((other.slots.iter()).all(|(id, view)| *id == 0 && view.is_none()));
        // Taken, the memo is the row's: the thread keeps nothing meanwhile.
        assert_eq!(ViewMemo::take_for(7).slots.len(), 0);
    }

    /// A triangle's uniform light, where it is shown, is what each of its
    /// pieces' own shadow ray gives ([`light_piece`]), bit for bit: the
    /// triangles of a generated terrain (hills above the runway decal,
    /// the flat ground 0.3 m below it, which the decal shadows in part),
    /// at points spread over each (corners and edges included), under the
    /// scene's sun, a low one (hills shadowing hills), and the scene's sun
    /// with an infinite plane through the hills at 8 m (what lies below it
    /// is in its shadow). Both answers occur, and lit triangles among those
    /// shown.
    #[test]
    fn a_uniform_light_is_what_each_point_gets() {
        let dir = std::env::temp_dir().join(format!("quadtex-light-{}", std::process::id()));
        let file = crate::terrain::write_terrain(&dir, 400, 320, 180).unwrap();
        let scene = crate::load_scene(&file).unwrap();
        std::fs::remove_dir_all(&dir).ok();
        let Lighting::Lambert {
            colour, ambient, ..
        } = scene.lighting
        else {
            panic!("the terrain is lit");
        };
        let low = Scene {
            lighting: Lighting::Lambert {
                direction: Vec3::new(-0.8, 0.08, 0.55).normalized().unwrap(),
                colour,
                ambient,
            },
            ..scene.clone()
        };
        let mut plane = (scene.surfaces.iter())
            .find(|s| matches!(s.geometry, Geometry::Quad { .. }))
            .unwrap()
            .clone();
        plane.geometry = Geometry::Plane {
            point: Vec3::new(0.0, 8.0, 0.0),
            normal: Vec3::new(0.0, 1.0, 0.0),
            u_axis: Vec3::new(1.0, 0.0, 0.0),
            v_axis: Vec3::new(0.0, 0.0, 1.0),
        };
        let mut sliced = scene.clone();
        sliced.surfaces.push(plane);
        for scene in [scene, low, sliced] {
            check_uniform_light(&scene);
        }
    }

    fn check_uniform_light(scene: &Scene) {
        let frame = Frame::new(scene);
        let (surface, mesh) = (scene.surfaces.iter().enumerate())
            .find_map(|(i, s)| match &s.geometry {
                Geometry::Mesh(m) => Some((i, m.clone())),
                _ => None,
            })
            .unwrap();
        let (mut shown, mut lit, mut varies) = (0, 0, 0);
        // Every triangle within 150 m of the runway (10 m cells: some
        // wholly under it, some across its sides), every 7th elsewhere.
        let near_runway = |t: u32| {
            (mesh.corners(t as usize).unwrap())
                .iter()
                .any(|p| p.x.abs() < 150.0 && (-1950.0..150.0).contains(&p.z))
        };
        for t in (0..mesh.len() as u32).filter(|&t| t % 7 == 0 || near_runway(t)) {
            let Some(view) = scene.surfaces[surface]
                .geometry
                .planar(t)
                .and_then(|p| View::new(scene, surface, &p))
            else {
                continue;
            };
            let Some(k) = uniform_light(&frame, &view) else {
                varies += 1;
                continue;
            };
            shown += 1;
            let [a, b, c] = mesh.corners(t as usize).unwrap();
            let points = [
                (0.2, 0.2),
                (0.6, 0.2),
                (0.2, 0.6),
                (0.45, 0.1),
                (0.05, 0.9),
                (0.0, 0.0),
                (1.0, 0.0),
                (0.0, 1.0),
                (0.5, 0.5),
                (0.3, 0.0),
            ];
            for (u, v) in points {
                let p = a + (b - a) * u + (c - a) * v;
                let Some(s) = scene.camera.project(p) else {
                    continue;
                };
                // A piece whose centroid is `s`.
                let piece = ConvexPolygon::new(&[
                    [s[0] - 1e-4, s[1] - 1e-4],
                    [s[0] + 2e-4, s[1] - 1e-4],
                    [s[0] - 1e-4, s[1] + 2e-4],
                ])
                .unwrap();
                let mut own = [1.0; 4];
                light_piece(&frame, &view, &piece, &mut own);
                let mut uniform = [1.0; 4];
                apply_light(&mut uniform, k);
                assert_eq!(own, uniform, "triangle {t} at {u}, {v}");
            }
            lit += usize::from(k != crate::frame::lit_factor(&scene.lighting, 0.0));
        }
        assert!(
            shown > 500 && varies > 500 && lit > 200,
            "{shown} {varies} {lit}"
        );
    }

    /// RMS over every 7th pixel of row `y` of `scenes/checker.toml` at
    /// 960×540: default options against the finished integral.
    fn row_rms(y: f64) -> f64 {
        let mut scene =
            crate::load_scene(std::path::Path::new("../../scenes/checker.toml")).unwrap();
        scene.camera = scene.camera.with_size(960, 540);
        let surface = &scene.surfaces[0];
        let view = View::new(&scene, 0, &surface.geometry.planar(0).unwrap()).unwrap();
        let texture = surface.texture.as_ref().unwrap().sampler(surface.wrap);
        let finished = FilterOptions::default()
            .with_error_bound(1e-6)
            .and_then(|o| o.with_budget(1 << 18))
            .unwrap();
        let (mut sum, mut n) = (0.0, 0);
        for px in (0..960).step_by(7) {
            let x = f64::from(px);
            let support = ConvexPolygon::rect(x, y, x + 1.0, y + 1.0);
            let centre = [x + 0.5, y + 0.5];
            let get = |o: &FilterOptions| {
                view.texture_integral(&texture, &support, PixelFilter::Box, centre, o)
            };
            let (quick, exact) = (get(&FilterOptions::default()), get(&finished));
            assert!(exact.error_bound < 1e-4 * exact.weight, "{exact:?}");
            let d = quick.mean().unwrap().r - exact.mean().unwrap().r;
            assert!(f64::from(d.abs()) <= quick.error_bound / quick.weight + 1e-4);
            sum += f64::from(d * d);
            n += 1;
        }
        (sum / f64::from(n)).sqrt()
    }

    /// The sky taken at a pixel's centre is within its stated bound of
    /// the pixel's mean (a 64 × 64 midpoint grid, itself far closer), on
    /// every row of a small frame (coarse pixels: the loosest case); the
    /// bound is not vacuous (some pixel comes close to it) and refuses the
    /// rows at the level line.
    /// Each view's area in a cut, by view index.
    fn areas_by_view(cut: &Cut, regions: &[ConvexPolygon], views: usize) -> Vec<f64> {
        let mut areas = vec![0.0; views];
        for (v, piece) in cut.visible(regions) {
            areas[v] += piece.area();
        }
        areas
    }

    /// The cut of `support` among `regions` when they tile it.
    fn tiling(regions: &[ConvexPolygon], support: &ConvexPolygon) -> Option<Cut> {
        let mut cut = Cut {
            sliver_area: GAP_AREA * support.area(),
            ..Cut::default()
        };
        cut.tiling(regions, support).then_some(cut)
    }

    #[test]
    fn regions_that_tile_the_support_are_taken_whole() {
        let support = ConvexPolygon::rect(10.0, 20.0, 11.0, 21.0);
        let sliver = GAP_AREA * support.area();
        let tri = |v: &[[f64; 2]]| ConvexPolygon::new(v).unwrap();
        // Fans around random inner points: four triangles that tile the
        // pixel, each taken whole, as cutting them one by one gives.
        let mut seed = 7u64;
        let mut next = || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            0.05 + 0.9 * ((seed >> 11) as f64 / (1u64 << 53) as f64)
        };
        let corners = [[10.0, 20.0], [11.0, 20.0], [11.0, 21.0], [10.0, 21.0]];
        for _ in 0..200 {
            let p = [10.0 + next(), 20.0 + next()];
            let fan: Vec<ConvexPolygon> = (0..4)
                .map(|i| tri(&[corners[i], corners[(i + 1) % 4], p]))
                .collect();
            let whole = tiling(&fan, &support).expect("a fan tiles the pixel");
            assert!(whole.whole == fan.len() && whole.pieces.is_empty());
            assert_eq!(whole.visible(&fan).count(), 4);
            assert!(whole.remaining.is_empty() && whole.slivers.is_empty());
            assert!(whole.unaccounted <= 3.0 * sliver, "{}", whole.unaccounted);
            let mut cut = Cut {
                remaining: vec![support.clone()],
                sliver_area: sliver,
                ..Cut::default()
            };
            for (v, region) in fan.iter().enumerate() {
                cut.take(v, region);
            }
            for (a, b) in areas_by_view(&whole, &fan, 4)
                .iter()
                .zip(areas_by_view(&cut, &fan, 4))
            {
                assert!((a - b).abs() < 1e-12, "{a} vs {b}");
            }
        }
        // A repeated vertex (a clip through a corner) separates nothing:
        // overlapping halves that leave a gap of the same area are still
        // not a tiling.
        let left =
            ConvexPolygon::new(&[[10.0, 20.0], [10.5, 20.0], [10.5, 21.0], [10.0, 21.0]]).unwrap();
        let twice = |p: [f64; 2]| [p, p];
        let right = [[10.4, 20.0], [10.9, 20.0], [10.9, 21.0], [10.4, 21.0]]
            .into_iter()
            .flat_map(twice)
            .collect::<Vec<_>>();
        let right = ConvexPolygon::new(&right).unwrap();
        let boxes = (left.bounds(), right.bounds());
        assert_eq!(overlap_bound((&left, boxes.0), (&right, boxes.1)), None);
        assert_eq!(overlap_bound((&right, boxes.1), (&left, boxes.0)), None);
        assert!(tiling(&[left, right], &support).is_none());
        // A gap: not a tiling.
        let lower = tri(&[[10.0, 20.0], [11.0, 20.0], [11.0, 21.0]]);
        assert!(tiling(std::slice::from_ref(&lower), &support).is_none());
        // Areas that add up to the pixel's, but overlap (and leave a gap).
        let left = ConvexPolygon::rect(10.0, 20.0, 10.5, 21.0);
        let right = ConvexPolygon::rect(10.4, 20.0, 10.9, 21.0);
        assert!((left.area() + right.area() - support.area()).abs() < 1e-12);
        assert!(tiling(&[left, right], &support).is_none());
    }

    /// Regions that lie apart but leave gaps (a fan with triangles left
    /// out): each is taken whole, and what is left of the support, the
    /// gaps, is what cutting them one by one leaves; regions that overlap
    /// are not taken so.
    #[test]
    fn regions_apart_with_gaps_are_taken_whole() {
        let support = ConvexPolygon::rect(10.0, 20.0, 11.0, 21.0);
        let sliver = GAP_AREA * support.area();
        let tri = |v: &[[f64; 2]]| ConvexPolygon::new(v).unwrap();
        let mut seed = 11u64;
        let mut next = || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            0.05 + 0.9 * ((seed >> 11) as f64 / (1u64 << 53) as f64)
        };
        let corners = [[10.0, 20.0], [11.0, 20.0], [11.0, 21.0], [10.0, 21.0]];
        let new_cut = || Cut {
            sliver_area: sliver,
            ..Cut::default()
        };
        for k in 0..200 {
            let p = [10.0 + next(), 20.0 + next()];
            // One to three of the fan's four triangles, and an empty region.
            let fan: Vec<ConvexPolygon> = (0..4)
                .filter(|i| (k >> i) % 2 == 1 || *i == k % 4)
                .map(|i| tri(&[corners[i], corners[(i + 1) % 4], p]))
                .take(3)
                .chain([ConvexPolygon::empty()])
                .collect();
            let mut whole = new_cut();
            assert!(whole.taken_whole(&fan, &support));
            assert_eq!(whole.whole, fan.len());
            assert!(whole.pieces.is_empty());
            assert_eq!(whole.visible(&fan).count(), fan.len() - 1);
            let mut cut = Cut {
                remaining: vec![support.clone()],
                ..new_cut()
            };
            for (v, region) in fan.iter().enumerate() {
                cut.take(v, region);
            }
            for (a, b) in areas_by_view(&whole, &fan, fan.len())
                .iter()
                .zip(areas_by_view(&cut, &fan, fan.len()))
            {
                assert!((a - b).abs() < 1e-12, "{a} vs {b}");
            }
            let left = |c: &Cut| c.remaining.iter().map(ConvexPolygon::area).sum::<f64>();
            let covered: f64 = fan.iter().map(ConvexPolygon::area).sum();
            assert!((left(&whole) - (support.area() - covered)).abs() < 1e-12);
            assert!((left(&whole) - left(&cut)).abs() < 1e-12);
            assert!(whole.unaccounted <= 2.0 * sliver, "{}", whole.unaccounted);
            // Cut again with a region over the others: as cut front to
            // back from the start.
            let over = ConvexPolygon::rect(10.2, 20.2, 10.6, 20.7);
            let mut regions = fan.clone();
            regions.push(over);
            whole.pieces_from_whole(&regions);
            assert_eq!(whole.whole, 0);
            assert_eq!(whole.pieces.len(), fan.len() - 1);
        }
        // Overlapping regions that cover less than the support: cut.
        let left = ConvexPolygon::rect(10.0, 20.0, 10.5, 21.0);
        let right = ConvexPolygon::rect(10.4, 20.0, 10.8, 21.0);
        let mut cut = new_cut();
        assert!(!cut.taken_whole(&[left, right], &support));
        assert_eq!(cut.whole, 0);
        assert!(cut.remaining.is_empty());
    }

    /// Triangles of a fan that share an edge, one of them with its inner
    /// corner moved a hair across it (as rounding leaves clipped regions):
    /// the bound holds the overlap and is of the hair's size; moved a
    /// visible amount across, no bound (the overlap is measured); moved
    /// away, none at all.
    #[test]
    fn a_hair_across_a_shared_edge_is_bounded_not_clipped() {
        let tri = |v: &[[f64; 2]]| ConvexPolygon::new(v).unwrap();
        let mut seed = 5u64;
        let mut next = || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..500 {
            let (x, y) = (1000.0 * next(), 1000.0 * next());
            let p = [x + 0.1 + 0.8 * next(), y + 0.1 + 0.8 * next()];
            let (a, b, c) = ([x, y], [x + 1.0, y], [x + 1.0, y + 1.0]);
            let left = tri(&[a, b, p]);
            // The shared edge is b–p; `right` is beyond it.
            // Some twenty ulps of the coordinates: rounding's size.
            let hair = 2e-15 * (x + y + 1.0);
            for (shift, expect) in [(hair, Some(())), (1e-3, None), (-1e-6, Some(()))] {
                // Moved along the normal of b–p, into `left`.
                let (dx, dy) = (p[0] - b[0], p[1] - b[1]);
                let n = (dx * dx + dy * dy).sqrt();
                let q = [p[0] - dy / n * shift, p[1] + dx / n * shift];
                let right = tri(&[b, c, q]);
                let bound = overlap_bound((&left, left.bounds()), (&right, right.bounds()));
                match expect {
                    Some(()) => {
                        let bound = bound.expect("a hair's overlap is bounded");
                        // The overlap's area, measured near the origin (the
                        // same polygons, moved exactly: Sterbenz), where
                        // its rounding is far below the hair's.
                        let moved = |t: &ConvexPolygon| {
                            let v: Vec<[f64; 2]> =
                                t.vertices().iter().map(|&[u, v]| [u - x, v - y]).collect();
                            ConvexPolygon::new(&v).unwrap()
                        };
                        let overlap = moved(&left).intersect(&moved(&right)).area();
                        assert!(bound >= overlap && bound < 1e-9, "{bound} {overlap}");
                        if shift < 0.0 {
                            assert_eq!(bound, 0.0);
                        }
                    }
                    None => assert_eq!(bound, None),
                }
            }
        }
    }

    /// Views inserted one by one into a cut that left a gap
    /// ([`Cut::insert`]) give each view the area cutting the support again
    /// with every view front to back gives it, and leave the same area
    /// uncovered: a fan that tiles the pixel, one triangle of it missing
    /// at first, and random triangles over and under it (planes facing
    /// the camera, each at its own depth).
    #[test]
    fn inserting_views_gives_what_cutting_again_gives() {
        let support = ConvexPolygon::rect(10.0, 20.0, 11.0, 21.0);
        let sliver = GAP_AREA * support.area();
        let mut seed = 5u64;
        let mut next = || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let view_at = |depth: f64| ViewRef::Built(Rc::new(View::facing_at(depth)));
        let corners = [[10.0, 20.0], [11.0, 20.0], [11.0, 21.0], [10.0, 21.0]];
        let (mut carved, mut hidden) = (0, 0);
        for round in 0..300 {
            let p = [10.05 + 0.9 * next(), 20.05 + 0.9 * next()];
            let mut regions: Vec<ConvexPolygon> = (0..4)
                .map(|i| ConvexPolygon::new(&[corners[i], corners[(i + 1) % 4], p]).unwrap())
                .collect();
            let mut views: Vec<ViewRef<'_>> = (0..4).map(|_| view_at(10.0)).collect();
            for _ in 0..1 + round % 4 {
                let v: Vec<[f64; 2]> = (0..3)
                    .map(|_| [9.8 + 1.4 * next(), 19.8 + 1.4 * next()])
                    .collect();
                let t = ConvexPolygon::hull(&v).intersect(&support);
                if !t.is_empty() {
                    regions.push(t);
                    views.push(view_at(5.0 + 10.0 * next()));
                }
            }
            let (listed, n) = (3 + round % 2, regions.len());
            let mut order = Order::default();
            let mut cut = Cut {
                remaining: vec![support.clone()],
                sliver_area: sliver,
                ..Cut::default()
            };
            for &v in order.front_to_back(&views[..listed], &regions[..listed]) {
                cut.take(v, &regions[v]);
            }
            for v in listed..n {
                cut.insert(v, &views, &regions);
            }
            let mut again = Cut::default();
            again.among(&views, &regions, &support, &mut order);
            let a = areas_by_view(&cut, &regions, n);
            for (v, (&a, b)) in a.iter().zip(areas_by_view(&again, &regions, n)).enumerate() {
                assert!((a - b).abs() < 1e-12, "round {round}, view {v}: {a} vs {b}");
                carved += usize::from(v < listed && a < regions[v].area() - 1e-6);
                hidden += usize::from(v >= listed && a < regions[v].area() - 1e-6);
            }
            let left = |c: &Cut| c.remaining.iter().map(ConvexPolygon::area).sum::<f64>();
            assert!((left(&cut) - left(&again)).abs() < 1e-12, "round {round}");
        }
        // Both ways happen: views listed first lose area to views inserted
        // in front of them, and inserted views to views in front of them.
        assert!(carved > 100 && hidden > 100, "{carved} {hidden}");
    }

    /// The sky over the part of a pixel above the level line (where the
    /// gradient's square root has an unbounded derivative), by the graded
    /// rows of [`sky_integral`], is within the sky's tolerance (a quarter of
    /// the default error bound) of a dense midpoint sum (16 columns × 4096
    /// rows, itself within about 1e-8 there), at two resolutions (the
    /// coarser one has the steeper gradient per pixel). Measured: 8.7e-5
    /// at 960×540 and 2.7e-4 at 96×54 (its coarsest graded rows; eight
    /// halvings or twenty differ by under 1e-6).
    #[test]
    fn the_sky_at_the_level_line_matches_a_dense_sum() {
        for (width, height) in [(960, 540), (96, 54)] {
            let scene = demo_at(width, height);
            let mut worst = 0.0f64;
            for x in (0..width).step_by(width as usize / 7) {
                let x = f64::from(x);
                let yh = level_line(&scene, x + 0.5).unwrap();
                let y0 = yh.floor();
                if yh - y0 < 1e-3 {
                    continue;
                }
                let piece = ConvexPolygon::rect(x, y0, x + 1.0, yh);
                let (c, w) = sky_integral(
                    &scene,
                    &piece,
                    Whole::Unknown,
                    PixelFilter::Box,
                    [x + 0.5, y0 + 0.5],
                    sky_tolerance(&FilterOptions::default()),
                );
                let (nx, ny) = (16, 4096);
                let (dx, dy) = (1.0 / f64::from(nx), (yh - y0) / f64::from(ny));
                let mut dense = [0.0; 4];
                for j in 0..ny {
                    for i in 0..nx {
                        let s = [
                            x + (f64::from(i) + 0.5) * dx,
                            y0 + (f64::from(j) + 0.5) * dy,
                        ];
                        let v = sky(&scene, &scene.camera.ray(s[0], s[1])).to_array();
                        for (d, v) in dense.iter_mut().zip(v) {
                            *d += f64::from(v) * dx * dy;
                        }
                    }
                }
                assert!((w - piece.area()).abs() < 1e-12, "{w} vs {}", piece.area());
                let error = (0..4)
                    .map(|k| (c[k] - dense[k]).abs() / w)
                    .fold(0.0, f64::max);
                worst = worst.max(error);
                assert!(
                    error <= sky_tolerance(&FilterOptions::default()),
                    "{width}x{height}, pixel x {x}: off by {error}"
                );
            }
            eprintln!("{width}x{height}: the level line's sky off by {worst} at most");
        }
    }

    /// Above [`sky_clear_above`], [`sky_at_centre`] always accepts its
    /// value (bound within the tolerance), so the sky pixel's shortcut
    /// gives what it would: every pixel of two frames, the default and a
    /// tight tolerance. Most sky pixels take the shortcut, and the height
    /// is not far above where the bound reaches the tolerance.
    #[test]
    fn the_sky_shortcut_takes_only_pixels_the_bound_accepts() {
        for (width, height) in [(192, 108), (1920, 1080)] {
            let scene = demo_at(width, height);
            for tolerance in [sky_tolerance(&FilterOptions::default()), 1e-7] {
                let clear = sky_clear_above(&scene, tolerance);
                let g = sky_step(&scene);
                let (mut shortcut, mut sky_rows) = (0, 0);
                for y in (0..height).step_by(height as usize / 54) {
                    for x in (0..width).step_by(width as usize / 24) {
                        let centre = [f64::from(x) + 0.5, f64::from(y) + 0.5];
                        let ray = scene.camera.ray(centre[0], centre[1]);
                        let y_min = ray.direction.y - std::f64::consts::FRAC_1_SQRT_2 * g;
                        if y_min > 0.0 {
                            sky_rows += 1;
                        }
                        if y_min >= clear {
                            shortcut += 1;
                            let (c, bound) = sky_at_centre(&scene, centre).unwrap();
                            assert!(bound <= tolerance, "{bound} > {tolerance} at {centre:?}");
                            assert_eq!(c, sky(&scene, &ray).to_array().map(f64::from));
                        }
                    }
                }
                assert!(
                    tolerance < 1e-6 || (clear.is_finite() && 2 * shortcut > sky_rows),
                    "{width}x{height}: {shortcut} of {sky_rows} sky samples"
                );
                // A percent below the height the bound is past half the
                // tolerance: the bisection found the height, not a loose one.
                let crate::scene::Sky::Gradient { horizon, zenith } = scene.sky else {
                    panic!("the demo's sky is a gradient");
                };
                let contrast = sky_contrast(horizon, zenith);
                if clear.is_finite() {
                    assert!(sky_bound(g, contrast, clear * 0.99) > 0.5 * tolerance);
                } else {
                    assert!(sky_bound(g, contrast, 1.0) > 0.5 * tolerance);
                }
            }
        }
    }

    #[test]
    fn the_sky_at_a_pixels_centre_is_within_its_bound() {
        let scene = demo_at(96, 54);
        let (mut refused, mut closest) = (0, 0.0f64);
        for y in 0..54 {
            for x in (0..96).step_by(13) {
                let (x, y) = (f64::from(x), f64::from(y));
                let Some((c, bound)) = sky_at_centre(&scene, [x + 0.5, y + 0.5]) else {
                    refused += 1;
                    continue;
                };
                let n = 64;
                let mut dense = [0.0; 4];
                for j in 0..n {
                    for i in 0..n {
                        let s = [
                            x + (f64::from(i) + 0.5) / f64::from(n),
                            y + (f64::from(j) + 0.5) / f64::from(n),
                        ];
                        let v = sky(&scene, &scene.camera.ray(s[0], s[1])).to_array();
                        for (d, v) in dense.iter_mut().zip(v) {
                            *d += f64::from(v) / f64::from(n * n);
                        }
                    }
                }
                let error = c
                    .iter()
                    .zip(dense)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                assert!(
                    error <= bound * 1.001 + 1e-6,
                    "pixel ({x}, {y}): off by {error}, bound {bound}"
                );
                if bound > 1e-4 {
                    closest = closest.max(error / bound);
                }
            }
        }
        assert!(refused > 0, "no pixel at the level line was refused");
        eprintln!("closest approach to the bound: {closest}");
        assert!(
            closest > 0.05,
            "the bound is vacuous: at most {closest} of it"
        );
    }

    /// The corner decisions agree with the clip they stand in for: over
    /// the demo's planes and quads and every 5th pixel of a 192×108 frame
    /// (box and Mitchell supports), `misses` is the clipped region's
    /// emptiness and `region` is the clip itself, and each of the three
    /// placements occurs.
    #[test]
    fn corner_decisions_agree_with_clipping() {
        let scene = demo_at(192, 108);
        let views = SurfaceViews::new(&scene);
        let mut seen = [0usize; 3];
        for view in views.views.iter().flatten() {
            for y in (0..108).step_by(5) {
                for x in (0..192).step_by(5) {
                    let centre = [f64::from(x) + 0.5, f64::from(y) + 0.5];
                    for filter in [PixelFilter::Box, PixelFilter::Mitchell] {
                        let support = filter.support(centre);
                        let clipped = support.clip_lines(view.lines());
                        assert_eq!(view.misses(&support), clipped.is_empty());
                        assert_eq!(*view.region(&support), clipped);
                        seen[view.placement(&support) as usize] += 1;
                    }
                }
            }
        }
        assert!(seen.iter().all(|&n| n > 0), "placements seen: {seen:?}");
    }

    /// Pixels just below the checker plane's horizon see thin needles
    /// crossing tens of tiles: row 248 (14 tiles, 0.1 tile wide) is
    /// scanned cell by cell, exactly (the walk, cut short by its budget,
    /// was off there by RMS 0.044 before the fallback and 0.009 with it).
    /// Row 243, hundreds of tiles long, has too many cells: the walk and
    /// its coarse fallback answer, within their bound.
    #[test]
    fn horizon_needles_are_scanned_or_fall_back() {
        let scanned = row_rms(248.0);
        assert!(scanned < 1e-6, "row 248: RMS {scanned}");
        let walked = row_rms(243.0);
        eprintln!("row 243: RMS {walked}");
        assert!(walked < 0.01, "row 243: RMS {walked}");
    }

    /// A span's one test answers every pixel of it as the pixel's own test
    /// would: over the demo's sky with 300 small quads scattered in it
    /// (their corners poking into spans anywhere, at the span's ends too),
    /// box and Mitchell supports, row by row, pixel by pixel.
    #[test]
    fn a_sky_span_answers_each_pixel_as_its_own_test() {
        let mut scene = demo_at(320, 180);
        let mut seed = 17u64;
        let mut next = || crate::math::unit_random(&mut seed);
        for _ in 0..300 {
            let size = 0.5 + 6.0 * next();
            scene.surfaces.push(crate::scene::Surface {
                geometry: Geometry::Quad {
                    origin: Vec3::new(
                        -150.0 + 300.0 * next(),
                        16.0 + 60.0 * next(),
                        -350.0 + 400.0 * next(),
                    ),
                    edge_u: Vec3::new(size, 0.0, size * (next() - 0.5)),
                    edge_v: Vec3::new(0.0, size, 0.0),
                },
                texture: None,
                colour: Rgba::opaque(1.0, 1.0, 1.0),
                uv_transform: crate::scene::UvTransform::default(),
                wrap: quadtex_core::Wrap::CLAMP,
            });
        }
        let cache = SurfaceViews::new(&scene);
        for filter in [PixelFilter::Box, PixelFilter::Mitchell] {
            let (mut clear, mut missed, mut hit) = (0, 0, 0);
            for y in 0..180 {
                let mut span = SkySpan::default();
                for x in 0..320 {
                    let support = filter.support([f64::from(x) + 0.5, f64::from(y) + 0.5]);
                    let own = cache.views.iter().flatten().all(|v| v.misses(&support));
                    let spanned = views_miss(&cache, &mut span, filter, (x, y), &support);
                    assert_eq!(spanned, own, "{filter:?} pixel ({x}, {y})");
                    clear += usize::from(span.clear);
                    if own { missed += 1 } else { hit += 1 }
                }
            }
            // Both outcomes, and spans that failed among pixels that miss.
            assert!(
                clear > 1000 && hit > 1000 && missed > clear,
                "{clear} {missed} {hit}"
            );
        }
    }
}

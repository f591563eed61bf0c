//! Rays against a scene: the nearest surface along a ray, a known
//! primitive's hit, and shadow rays ([`Caster`]); the ids of the primitives
//! rays meet ([`Seen`]).

use std::sync::Arc;

use crate::math::{Ray, Vec3};
use crate::scene::{Geometry, Hit, Lighting, QuadFrame, Scene, Surface};
use crate::sun_grid::{self, SunGrid};

/// What a pixel centre sees: `0` for the sky, else
/// `(surface + 1) << 32 | triangle`.
pub(crate) type Seen = u64;

/// The id of primitive `triangle` of surface `surface`.
pub(crate) fn seen_id(surface: usize, triangle: u32) -> Seen {
    ((surface as u64 + 1) << 32) | u64::from(triangle)
}

/// The surface and triangle of a (non-sky) id from [`seen_id`].
pub(crate) fn surface_and_triangle(id: Seen) -> (usize, u32) {
    (((id >> 32) as usize).wrapping_sub(1), id as u32)
}

/// A scene's surfaces ready for rays: each quad's [`QuadFrame`] solved
/// once, not for every ray (visibility grid, shadows, gap search).
#[derive(Debug)]
pub(crate) struct Caster<'a> {
    pub scene: &'a Scene,
    quads: Vec<Option<QuadFrame>>,
    /// Per surface, a large mesh's triangles binned along the sun's
    /// direction for shadow rays ([`Caster::with_sun_grids`]).
    suns: Vec<Option<Arc<SunGrid>>>,
}

/// Builds the shadow grids of `scene`'s large meshes under its sun
/// ([`SunGrid`], kept once per mesh and light direction), so that its first
/// frame finds them ready: a scene read from a file gets them at load, as
/// its meshes get their hierarchies (on the 1 M-triangle terrain, 0.16 s
/// that its first frame took before; later frames never paid it). A
/// scene built another way, or lit from a new direction, gets them at its
/// first frame.
pub(crate) fn prepare_sun_grids(scene: &Scene) {
    drop(Caster::new(scene).with_sun_grids());
}

impl<'a> Caster<'a> {
    pub fn new(scene: &'a Scene) -> Caster<'a> {
        let quads = (scene.surfaces.iter())
            .map(|s| match s.geometry {
                Geometry::Quad { edge_u, edge_v, .. } => QuadFrame::new(edge_u, edge_v),
                _ => None,
            })
            .collect();
        Caster {
            scene,
            quads,
            suns: Vec::new(),
        }
    }

    /// With each large mesh's triangles binned along the sun's direction
    /// ([`SunGrid`], built once per mesh and direction), when the scene is
    /// lit: shadow rays then test one cell's triangles instead of walking
    /// the hierarchy (same answers).
    pub fn with_sun_grids(mut self) -> Caster<'a> {
        if let Lighting::Lambert { direction, .. } = self.scene.lighting {
            self.suns = (self.scene.surfaces.iter())
                .map(|s| match &s.geometry {
                    Geometry::Mesh(mesh) => sun_grid::shared(mesh, direction),
                    _ => None,
                })
                .collect();
        }
        self
    }

    /// The frame of quad `index`, solved once (`None`: not a quad, or a
    /// degenerate one).
    fn quad_frame(&self, index: usize) -> Option<&QuadFrame> {
        self.quads.get(index)?.as_ref()
    }

    /// Where `ray` meets surface `index` beyond `t_min`.
    #[inline]
    fn intersect(&self, index: usize, ray: &Ray, t_min: f64) -> Option<Hit> {
        let geometry = &self.scene.surfaces[index].geometry;
        match (geometry, &self.quads[index]) {
            (Geometry::Quad { origin, .. }, Some(frame)) => frame.hit(*origin, ray, t_min),
            _ => geometry.intersect(ray, t_min),
        }
    }

    /// Where `ray` meets surface `index` (not a mesh: a mesh's triangles
    /// are asked one by one, [`crate::scene::Mesh::crossing_beyond`]), as
    /// [`Caster::nearest_index`] tests it.
    pub(crate) fn surface_hit(&self, index: usize, ray: &Ray) -> Option<Hit> {
        self.intersect(index, ray, 1e-9)
    }

    /// The index of the first surface `ray` meets, and where.
    pub fn nearest_index(&self, ray: &Ray) -> Option<(usize, Hit)> {
        self.nearest_index_below(ray, f64::INFINITY)
    }

    /// [`Caster::nearest_index`] among hits nearer than `t_bound`: the
    /// same answer when the nearest hit is nearer than that, with a mesh's
    /// boxes beyond it not visited ([`crate::bvh::Bvh::nearest_below`]).
    fn nearest_index_below(&self, ray: &Ray, t_bound: f64) -> Option<(usize, Hit)> {
        let mut best: Option<(usize, Hit)> = None;
        for i in 0..self.scene.surfaces.len() {
            let hit = match (&self.scene.surfaces[i].geometry, &self.quads[i]) {
                (Geometry::Mesh(mesh), _) => mesh.intersect_below(ray, 1e-9, t_bound),
                _ => self.intersect(i, ray, 1e-9).filter(|h| h.t < t_bound),
            };
            if let Some(hit) = hit
                && best.as_ref().is_none_or(|(_, b)| hit.t < b.t)
            {
                best = Some((i, hit));
            }
        }
        best
    }

    /// What [`Caster::nearest_index`] finds for `ray`, when `ray` is
    /// expected to meet primitive `expected` (a mesh triangle a pixel's
    /// region holds, whose visibility is in question): where the ray meets
    /// it bounds the search, so that only what lies in front of it is
    /// looked for. The answer is the same; the search is shorter.
    pub fn nearest_index_expecting(&self, ray: &Ray, expected: Seen) -> Option<(usize, Hit)> {
        let (surface, triangle) = surface_and_triangle(expected);
        let own = match self.scene.surfaces.get(surface).map(|s| &s.geometry) {
            Some(Geometry::Mesh(mesh)) => mesh.intersect_triangle(triangle, ray, 1e-9),
            _ => None,
        };
        // A relative margin above the expected hit: a box the ray enters
        // beyond it holds no nearer hit, rounding of the box and of the
        // hit (a few ulps) included.
        own.and_then(|h| self.nearest_index_below(ray, h.t * (1.0 + 1e-9)))
            .or_else(|| self.nearest_index(ray))
    }

    /// What [`Caster::nearest_index`] finds for `ray` when it is known to
    /// see primitive `seen` (0: the sky), from the visibility grid cast
    /// along the same ray: that primitive alone is intersected, not the
    /// scene.
    pub fn nearest_seen(&self, ray: &Ray, seen: Seen) -> Option<(usize, Hit)> {
        if seen == 0 {
            return None;
        }
        let (surface, triangle) = surface_and_triangle(seen);
        let hit = match &self.scene.surfaces.get(surface)?.geometry {
            Geometry::Mesh(mesh) => mesh.intersect_triangle(triangle, ray, 1e-9),
            _ => self.intersect(surface, ray, 1e-9),
        };
        hit.map(|h| (surface, h))
    }

    /// Whether `ray` meets any surface (as [`Caster::nearest_index`] would
    /// find one), without finding the nearest point: for shadow rays, which
    /// leave `from` (a surface, and its triangle if it is a mesh) on the
    /// side they point to. A plane or quad cannot meet such a ray again, so
    /// it is not tested; a mesh is (its other triangles may), unless its sun
    /// grid shows that none lies between the triangle and the sun
    /// ([`SunGrid::unshadowed`]).
    pub fn occluded_leaving(&self, ray: &Ray, (from, triangle): (usize, u32)) -> bool {
        (self.scene.surfaces.iter().enumerate()).any(|(i, s)| match &s.geometry {
            Geometry::Mesh(_)
                if i == from && self.clear_of_own_mesh((i, triangle), ray.direction) =>
            {
                false
            }
            Geometry::Mesh(mesh) => match self.suns.get(i) {
                Some(Some(grid)) if grid.serves(ray.direction) => grid.occludes(mesh, ray, 1e-9),
                _ => mesh.occludes(ray, 1e-9),
            },
            Geometry::Plane { .. } | Geometry::Quad { .. } if i == from => false,
            _ => self.intersect(i, ray, 1e-9).is_some(),
        })
    }

    /// What [`Caster::occluded_leaving`] answers for every shadow ray
    /// leaving a point of triangle `from` (of a mesh, its `corners`),
    /// lifted as [`crate::frame::lambert`] lifts them, when one answer
    /// holds for all: true when none meets anything. The mesh's sun grid
    /// shows no other of its triangles in the way
    /// ([`Caster::clear_of_own_mesh`]), and every other surface is a plane
    /// or quad the rays miss ([`sun_misses`], margins relative to each
    /// corner's distance from `camera`); false otherwise (an answer that
    /// varies, or is not shown). Beside `occluded_leaving` so that what
    /// can cast a shadow is said in one place.
    pub(crate) fn sun_clear_of_triangle(
        &self,
        (surface, triangle): (usize, u32),
        corners: &[Vec3; 3],
        camera: Vec3,
        direction: Vec3,
    ) -> bool {
        self.clear_of_own_mesh((surface, triangle), direction)
            && (self.scene.surfaces.iter().enumerate()).all(|(i, s)| match &s.geometry {
                _ if i == surface => true,
                Geometry::Plane { point, normal, .. } => {
                    sun_misses(*point, *normal, None, corners, camera, direction)
                }
                Geometry::Quad { origin, .. } => self.quad_frame(i).is_some_and(|q| {
                    sun_misses(*origin, q.normal, Some(q), corners, camera, direction)
                }),
                _ => false,
            })
    }

    /// Whether the sun grid of mesh `surface` (toward `direction`) shows
    /// that none of the mesh's other triangles lies between a point of
    /// `triangle` and the sun ([`SunGrid::unshadowed`]); false when that is
    /// not shown or `surface` is no mesh with a grid.
    pub(crate) fn clear_of_own_mesh(
        &self,
        (surface, triangle): (usize, u32),
        direction: Vec3,
    ) -> bool {
        match (self.scene.surfaces.get(surface), self.suns.get(surface)) {
            (Some(s), Some(Some(grid))) => match &s.geometry {
                Geometry::Mesh(mesh) => grid.serves(direction) && grid.unshadowed(mesh, triangle),
                _ => false,
            },
            _ => false,
        }
    }

    /// The first surface `ray` meets, and where.
    pub fn nearest_hit(&self, ray: &Ray) -> Option<(&'a Surface, Hit)> {
        let scene = self.scene;
        self.nearest_index(ray)
            .map(|(i, hit)| (&scene.surfaces[i], hit))
    }
}

/// Whether no ray toward the sun (`direction`) from a point of triangle
/// `corners`, lifted off it by up to 10⁻⁶ of its distance from `camera`
/// (as [`crate::frame::lambert`] lifts its shadow rays), meets the plane
/// through `point` with unit `normal`, or, for a quad (`quad`: its frame, corner `point`),
/// the parallelogram: every corner lies beyond the plane on the sun's
/// side, or every corner's ray meets the plane outside one and the same
/// side of the parallelogram (the rays from the triangle meet the plane
/// in the triangle of those points: the projection along `direction` is
/// affine). Each by a margin of 10⁻⁵ of the corner's distance from the
/// camera (on the plane, over the sine of the sun's angle to it),
/// ten times the lift (and far above the rounding).
fn sun_misses(
    point: Vec3,
    normal: Vec3,
    quad: Option<&QuadFrame>,
    corners: &[Vec3; 3],
    camera: Vec3,
    direction: Vec3,
) -> bool {
    let toward = normal.dot(direction);
    // Not NaN, and not near parallel to the plane.
    let steep = toward.abs() > 1e-3;
    if !steep {
        return false;
    }
    let margin = |p: Vec3| 1e-5 * (1.0 + (p - camera).length());
    let beyond = corners.map(|p| normal.dot(p - point));
    let sun_side = |b: f64| b * toward.signum();
    if (corners.iter().zip(beyond)).all(|(&p, b)| sun_side(b) > margin(p)) {
        return true;
    }
    let Some(q) = quad else {
        return false;
    };
    if !(corners.iter().zip(beyond)).all(|(&p, b)| sun_side(b) < -margin(p)) {
        return false;
    }
    // Where each corner's ray meets the plane, in the quad's coordinates
    // (`s, t ∈ [0, 1]` on it): a point `m` outside the side `s = 0` lies
    // `−s / |∇s|` from it.
    let mut st = [[0.0; 2]; 3];
    let mut slack = [0.0; 3];
    for ((p, b), (st, slack)) in (corners.iter().zip(beyond)).zip(st.iter_mut().zip(&mut slack)) {
        let rel = *p - direction * (b / toward) - point;
        *st = [rel.dot(q.du), rel.dot(q.dv)];
        *slack = margin(*p) / toward.abs();
    }
    [q.du, q.dv].iter().enumerate().any(|(axis, g)| {
        let g = g.length();
        (0..3).all(|k| st[k][axis] < -slack[k] * g)
            || (0..3).all(|k| st[k][axis] > 1.0 + slack[k] * g)
    })
}

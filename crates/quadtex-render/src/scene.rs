//! The scene model: a validated, ready-to-render description. Built by
//! [`crate::load_scene`] from TOML or by [`crate::demo_scene`] in code.
//!
//! World space is right-handed with `y` up, in arbitrary units (metres in the
//! examples). Every surface maps points to *UV* by an affine map (exact for
//! planes and quads; the sphere's latitude-longitude map is linearised at the
//! hit point for footprints), then UV to texture space by the surface's
//! [`UvTransform`]; texture space is the crate-level convention of
//! `quadtex-core` (unit square, `x` right, `z` up, repeating tiles).

use std::sync::Arc;

use quadtex_core::{QuadTree, Rgba, Wrap};
use rayon::prelude::*;

use crate::bvh::{Aabb, Bvh};
use crate::exact::PolarFans;
use crate::math::{Ray, Vec3};

/// A pinhole camera.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    pub(crate) position: Vec3,
    pub(crate) forward: Vec3,
    pub(crate) right: Vec3,
    pub(crate) up: Vec3,
    pub(crate) tan_half_fov: f64,
    pub(crate) width: u32,
    pub(crate) height: u32,
    /// `[d(0, 0), d(1, 0) − d(0, 0), d(0, 1) − d(0, 0)]` for the direction
    /// `d` through an image point ([`Camera::direction`], affine): kept, as
    /// every primitive's view starts from it.
    basis: [Vec3; 3],
}

impl Camera {
    /// A camera at `position` looking at `look_at`; `up` fixes the roll;
    /// `fov_y_degrees` is the vertical field of view. `None` when the view
    /// is degenerate (coincident points, `up` parallel to the view, a field
    /// of view outside `(0, 180)`, non-finite input, zero size).
    pub fn new(
        position: Vec3,
        look_at: Vec3,
        up: Vec3,
        fov_y_degrees: f64,
        width: u32,
        height: u32,
    ) -> Option<Camera> {
        if !(position.is_finite() && look_at.is_finite() && up.is_finite()) {
            return None;
        }
        if !(fov_y_degrees > 0.0 && fov_y_degrees < 180.0) || width == 0 || height == 0 {
            return None;
        }
        let forward = (look_at - position).normalized()?;
        let right = forward.cross(up).normalized()?;
        let up = right.cross(forward);
        let tan_half_fov = (fov_y_degrees.to_radians() / 2.0).tan();
        Some(
            Camera {
                position,
                forward,
                right,
                up,
                tan_half_fov,
                width,
                height,
                basis: [Vec3::new(0.0, 0.0, 0.0); 3],
            }
            .with_basis(),
        )
    }

    /// The camera with its [`Camera::basis`] computed.
    fn with_basis(mut self) -> Camera {
        let d0 = self.direction(0.0, 0.0);
        self.basis = [
            d0,
            self.direction(1.0, 0.0) - d0,
            self.direction(0.0, 1.0) - d0,
        ];
        self
    }

    /// `[d0, dx, dy]` with [`Camera::direction`]`(px, py) = d0 + dx·px +
    /// dy·py` up to rounding: `d0 = d(0, 0)`, `dx = d(1, 0) − d0`, `dy =
    /// d(0, 1) − d0`.
    pub(crate) fn basis(&self) -> [Vec3; 3] {
        self.basis
    }

    /// The camera with another resolution (same field of view).
    pub fn with_size(&self, width: u32, height: u32) -> Camera {
        Camera {
            width,
            height,
            ..self.clone()
        }
        .with_basis()
    }

    /// The camera moved by `offset` (same orientation).
    pub fn translated(&self, offset: Vec3) -> Camera {
        Camera {
            position: self.position + offset,
            ..self.clone()
        }
    }

    /// Unit view direction.
    pub fn forward(&self) -> Vec3 {
        self.forward
    }

    /// The image height that keeps this camera's aspect at `width` (at least 1).
    pub fn height_for_width(&self, width: u32) -> u32 {
        let h = (f64::from(width) * f64::from(self.height) / f64::from(self.width)).round();
        (h as u32).max(1)
    }

    /// Image width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Image height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The least and the greatest of the depths `(p − position)·forward`
    /// of `corners` (a triangle's), the least at least 0: every camera
    /// ray's direction has `d·forward = 1`, so the least bounds where a ray
    /// can meet the triangle from below, and a greatest of at most 0 says
    /// no ray meets it.
    pub(crate) fn depth_range(&self, corners: &[Vec3; 3]) -> (f64, f64) {
        let depths = corners.map(|p| (p - self.position).dot(self.forward));
        let least = depths.into_iter().fold(f64::INFINITY, f64::min).max(0.0);
        let greatest = depths.into_iter().fold(f64::NEG_INFINITY, f64::max);
        (least, greatest)
    }

    /// The image point (pixel units from the top-left corner) where world
    /// point `p` projects, or `None` behind (or at) the camera's plane.
    pub fn project(&self, p: Vec3) -> Option<[f64; 2]> {
        let (width, height) = (f64::from(self.width), f64::from(self.height));
        let d = p - self.position;
        let z = d.dot(self.forward);
        if z <= 1e-9 {
            return None;
        }
        let aspect = width / height;
        let sx = (d.dot(self.right) / z / (self.tan_half_fov * aspect) + 1.0) * width / 2.0;
        let sy = (1.0 - d.dot(self.up) / z / self.tan_half_fov) * height / 2.0;
        Some([sx, sy])
    }

    /// The screen box `(lo, hi)` of the projections of `points`; `None`
    /// when one of them does not project ([`Camera::project`]: on or behind
    /// the camera's plane). Points in front of the camera: their convex
    /// hull projects inside the box.
    pub(crate) fn screen_box(
        &self,
        points: impl IntoIterator<Item = Vec3>,
    ) -> Option<([f64; 2], [f64; 2])> {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in points {
            let s = self.project(p)?;
            for a in 0..2 {
                lo[a] = lo[a].min(s[a]);
                hi[a] = hi[a].max(s[a]);
            }
        }
        Some((lo, hi))
    }

    /// [`Camera::screen_box`] of the eight corners of the box `[lo, hi]`.
    pub(crate) fn screen_box_of_box(&self, lo: Vec3, hi: Vec3) -> Option<([f64; 2], [f64; 2])> {
        self.screen_box((0..8).map(|k| {
            Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            )
        }))
    }

    /// The ray through image point `(px, py)`, in pixel units from the top-left
    /// corner (pixel `(i, j)` covers `[i, i+1) × [j, j+1)`).
    pub fn ray(&self, px: f64, py: f64) -> Ray {
        let d = self.direction(px, py);
        Ray {
            origin: self.position,
            direction: d * (1.0 / d.length()),
        }
    }
}

impl Camera {
    /// The direction through image point `(px, py)`, not normalised: the
    /// view direction plus the image-plane offset at distance 1. Affine in
    /// `(px, py)`, which makes a plane's screen-to-texture map projective.
    pub(crate) fn direction(&self, px: f64, py: f64) -> Vec3 {
        let aspect = f64::from(self.width) / f64::from(self.height);
        let sx = (2.0 * px / f64::from(self.width) - 1.0) * self.tan_half_fov * aspect;
        let sy = (1.0 - 2.0 * py / f64::from(self.height)) * self.tan_half_fov;
        self.forward + self.right * sx + self.up * sy
    }
}

/// Surface shapes.
#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    /// Infinite plane through `point`; UV = coordinates along `u_axis`,
    /// `v_axis` (orthonormal, spanning the plane) in world units.
    Plane {
        /// A point on the plane (UV origin).
        point: Vec3,
        /// Unit normal.
        normal: Vec3,
        /// Unit direction of increasing u.
        u_axis: Vec3,
        /// Unit direction of increasing v.
        v_axis: Vec3,
    },
    /// Parallelogram `origin + s·edge_u + t·edge_v`, `s, t ∈ [0,1]`; UV = `(s, t)`.
    Quad {
        /// Corner with UV (0,0).
        origin: Vec3,
        /// Edge to UV (1,0).
        edge_u: Vec3,
        /// Edge to UV (0,1).
        edge_v: Vec3,
    },
    /// Triangle mesh with per-vertex UVs (from an OBJ file); UV inside a
    /// triangle is the barycentric blend. Rays find their triangle through
    /// a bounding-volume hierarchy (`crate::bvh`); at most
    /// `quadtex_io::Limits::max_mesh_triangles`.
    Mesh(Arc<Mesh>),
    /// Sphere; UV = (longitude / 2π, latitude from the south pole / π).
    Sphere {
        /// Centre.
        centre: Vec3,
        /// Radius.
        radius: f64,
    },
}

/// One triangle, precomputed for intersection and texturing.
#[derive(Debug, Clone, PartialEq)]
pub struct Triangle {
    p0: Vec3,
    e1: Vec3,
    e2: Vec3,
    uv0: [f64; 2],
    normal: Vec3,
    /// Gradients of u and v in the triangle's plane (constant per triangle).
    du: Vec3,
    dv: Vec3,
}

impl Triangle {
    /// A triangle from three vertices and their UVs; `None` when degenerate
    /// (zero area, or UVs that collapse to a line).
    pub fn new(p: [Vec3; 3], uv: [[f64; 2]; 3]) -> Option<Triangle> {
        let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
        let normal = e1.cross(e2).normalized()?;
        let (a1, b1) = (uv[1][0] - uv[0][0], uv[1][1] - uv[0][1]);
        let (a2, b2) = (uv[2][0] - uv[0][0], uv[2][1] - uv[0][1]);
        if (a1 * b2 - a2 * b1).abs() < 1e-300 {
            return None;
        }
        // ∇u = α·e1 + β·e2 with ∇u·e1 = a1, ∇u·e2 = a2 (likewise ∇v): a Gram system.
        let (g11, g12, g22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        let det = g11 * g22 - g12 * g12;
        let solve = |x1: f64, x2: f64| {
            let alpha = (g22 * x1 - g12 * x2) / det;
            let beta = (g11 * x2 - g12 * x1) / det;
            e1 * alpha + e2 * beta
        };
        Some(Triangle {
            p0: p[0],
            e1,
            e2,
            uv0: uv[0],
            normal,
            du: solve(a1, a2),
            dv: solve(b1, b2),
        })
    }
}

/// Bytes a mesh holds per triangle once parsed: the triangle (160), its
/// share of the hierarchy (about 33), its edge neighbours (12), its place
/// in the hierarchy's search order (4), and while it is built the parsed
/// file's arrays alongside (up to about 100), the corners' vertex ids
/// and edges filed to find the neighbours (38) and, found meanwhile, the
/// permutation into the hierarchy's order and its marks (5): 352. Loaders check a mesh
/// against the memory budget at this rate before building it. Once the
/// parsed arrays are gone, a lit scene's load adds the shadow grid (at
/// most 41 bytes a triangle, 16 more while it is built: 266 with the
/// mesh's 209, within this rate), and each frame the visibility grid's
/// bins (about 30 bytes a triangle in view, for the frame).
pub const MESH_BYTES_PER_TRIANGLE: u64 = 352;

/// A triangle mesh with its bounding-volume hierarchy.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    triangles: Vec<Triangle>,
    bvh: Bvh,
    neighbours: Vec<[u32; 3]>,
    /// Each triangle's place in the order [`Mesh::overlapping`] visits
    /// triangles ([`Bvh::visit_ranks`]).
    visit_rank: Vec<u32>,
}

impl Mesh {
    /// A mesh from triangles, with its hierarchy built; `None` when there
    /// are none. Triangles are neighbours where they share two corners
    /// exactly as [`Triangle`] gives them (its corners are rebuilt from
    /// its first corner and edges, which may round); the scene loaders
    /// name each corner's vertex instead, by its position as the model
    /// gives it.
    pub fn new(triangles: Vec<Triangle>) -> Option<Mesh> {
        let mut ids = VertexIds::default();
        let vertices = (triangles.iter())
            .map(|t| [t.p0, t.p0 + t.e1, t.p0 + t.e2].map(|p| ids.id(p)))
            .collect();
        Mesh::with_vertices(triangles, vertices)
    }

    /// A mesh from triangles and, for each, the ids of its three corners'
    /// vertices (the same id where triangles share a corner; see
    /// [`VertexIds`]), with its hierarchy built; `None` when there are
    /// none or the lengths differ. Two triangles sharing an edge (two
    /// vertices, and no third triangle on it) are neighbours
    /// ([`Mesh::neighbour`]).
    pub(crate) fn with_vertices(
        mut triangles: Vec<Triangle>,
        vertices: Vec<[u32; 3]>,
    ) -> Option<Mesh> {
        triangles.first()?;
        if vertices.len() != triangles.len() {
            return None;
        }
        let mut bvh = Bvh::build(triangles.len(), |i| triangle_box(&triangles[i]));
        // Triangle indices are the mesh's own (hits, visibility ids): they
        // may follow the hierarchy's leaves, which keeps a leaf's triangles
        // in adjacent cache lines. The edge neighbours are found in the
        // input's order meanwhile (each is one thread's pass: on the 1
        // M-triangle terrain 0.11 and 0.055 s), then renumbered.
        let (order, by_input) = rayon::join(
            || bvh.reorder_to_leaves(&mut triangles),
            || edge_neighbours(&vertices),
        );
        drop(vertices);
        let mut new_index = vec![0u32; order.len()];
        for (k, &old) in order.iter().enumerate() {
            new_index[old as usize] = k as u32;
        }
        let renumber = |n: u32| {
            if n == NO_NEIGHBOUR {
                n
            } else {
                new_index[n as usize]
            }
        };
        let (neighbours, visit_rank) = rayon::join(
            || {
                (order.par_iter())
                    .map(|&old| by_input[old as usize].map(renumber))
                    .collect()
            },
            || bvh.visit_ranks(),
        );
        Some(Mesh {
            triangles,
            bvh,
            neighbours,
            visit_rank,
        })
    }

    /// Seconds [`Mesh::with_vertices`] takes to build this mesh's
    /// hierarchy and move the triangles into its leaves' order, measured on
    /// a copy of the triangles made before the clock starts (`quadtex
    /// rays`; on the calling thread's rayon pool).
    pub(crate) fn hierarchy_build_seconds(&self) -> f64 {
        let mut copy = self.triangles.clone();
        let start = std::time::Instant::now();
        let mut bvh = Bvh::build(copy.len(), |i| triangle_box(&copy[i]));
        bvh.reorder_to_leaves(&mut copy);
        let seconds = start.elapsed().as_secs_f64();
        drop((bvh, copy));
        seconds
    }

    /// Bytes the triangles and their hierarchy hold.
    pub fn memory_bytes(&self) -> usize {
        self.triangles.len() * std::mem::size_of::<Triangle>()
            + self.neighbours.len() * std::mem::size_of::<[u32; 3]>()
            + self.visit_rank.len() * std::mem::size_of::<u32>()
            + self.bvh.memory_bytes()
    }

    /// The box around every triangle (its hierarchy's root).
    pub(crate) fn bounds(&self) -> Option<crate::bvh::Aabb> {
        self.bvh.bounds()
    }

    /// The triangles in a leaf of the hierarchy reached through boxes that
    /// all pass `enters(lo, hi)`, as increasing ranges of indices (the
    /// triangles follow the leaves' order).
    pub(crate) fn triangles_in(
        &self,
        enters: impl Fn(Vec3, Vec3) -> bool,
    ) -> Vec<std::ops::Range<usize>> {
        self.bvh.leaf_ranges(|b| enters(b.lo, b.hi))
    }

    /// The triangle across edge `edge` of triangle `index`, if one shares
    /// it. Edges are numbered by the corner they face, as the view of a
    /// triangle orders its edge lines ([`crate::view::View::lines`]):
    /// 0 is the edge from corner 0 to corner 2 (where the barycentric
    /// weight of corner 1 is zero), 1 from corner 0 to corner 1, 2 from
    /// corner 1 to corner 2.
    pub(crate) fn neighbour(&self, index: u32, edge: usize) -> Option<u32> {
        let n = *self.neighbours.get(index as usize)?.get(edge)?;
        (n != NO_NEIGHBOUR).then_some(n)
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Always false (a mesh has at least one triangle).
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// The corners of triangle `index`.
    pub(crate) fn corners(&self, index: usize) -> Option<[Vec3; 3]> {
        let t = self.triangles.get(index)?;
        Some([t.p0, t.p0 + t.e1, t.p0 + t.e2])
    }

    /// `|e1 × e2|` of triangle `index` (twice its area): the scale of
    /// [`Mesh::crossing`]'s determinant.
    pub(crate) fn determinant_scale(&self, index: usize) -> Option<f64> {
        let t = self.triangles.get(index)?;
        Some(t.e1.cross(t.e2).length())
    }

    /// Möller–Trumbore: the distance at which `ray` crosses triangle `tri`.
    fn crossing(tri: &Triangle, ray: &Ray) -> Option<f64> {
        let p = ray.direction.cross(tri.e2);
        let det = tri.e1.dot(p);
        if det.abs() < 1e-14 {
            return None;
        }
        let inv = 1.0 / det;
        let s = ray.origin - tri.p0;
        let b1 = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&b1) {
            return None;
        }
        let q = s.cross(tri.e1);
        let b2 = ray.direction.dot(q) * inv;
        if b2 < 0.0 || b1 + b2 > 1.0 {
            return None;
        }
        Some(tri.e2.dot(q) * inv)
    }

    /// Where `ray` crosses triangle `index` beyond `t_min`, if it does: the
    /// distance [`Mesh::intersect`] compares.
    pub(crate) fn crossing_beyond(&self, index: u32, ray: &Ray, t_min: f64) -> Option<f64> {
        (self.triangles.get(index as usize))
            .and_then(|tri| Self::crossing(tri, ray))
            .filter(|&t| t > t_min)
    }

    /// Whether `ray` crosses triangle `index` beyond `t_min` (the test of
    /// [`Mesh::occludes`]).
    pub(crate) fn crosses_beyond(&self, index: u32, ray: &Ray, t_min: f64) -> bool {
        self.crossing_beyond(index, ray, t_min).is_some()
    }

    /// Whether the ray meets a triangle beyond `t_min` (any one).
    pub(crate) fn occludes(&self, ray: &Ray, t_min: f64) -> bool {
        self.bvh.any(ray, |i| {
            Self::crossing(&self.triangles[i as usize], ray).is_some_and(|t| t > t_min)
        })
    }

    /// Calls `visit(i)` for every triangle not wholly outside one of
    /// `planes` (as [`Bvh::overlapping`], each triangle tested by its
    /// vertices) whose hierarchy's boxes pass `may_meet(lo, hi)`, until
    /// `visit` returns true; returns whether it did.
    pub(crate) fn overlapping(
        &self,
        planes: &[[f64; 4]],
        may_meet: impl Fn(Vec3, Vec3) -> bool,
        mut visit: impl FnMut(u32) -> bool,
    ) -> bool {
        self.bvh.overlapping(planes, may_meet, |i| {
            let t = &self.triangles[i as usize];
            let corners = [t.p0, t.p0 + t.e1, t.p0 + t.e2];
            let outside = planes.iter().any(|&[x, y, z, d]| {
                corners
                    .iter()
                    .all(|p| x * p.x + y * p.y + z * p.z + d < 0.0)
            });
            !outside && visit(i)
        })
    }

    /// Triangle `t`'s place in the order [`Mesh::overlapping`] visits
    /// triangles: the triangles it visits come in increasing rank.
    pub(crate) fn visit_rank(&self, t: u32) -> u32 {
        self.visit_rank[t as usize]
    }

    fn intersect(&self, ray: &Ray, t_min: f64) -> Option<Hit> {
        self.intersect_below(ray, t_min, f64::INFINITY)
    }

    /// [`Mesh::intersect`] among hits nearer than `t_bound`: the same hit
    /// when the nearest is nearer than that ([`Bvh::nearest_below`]).
    pub(crate) fn intersect_below(&self, ray: &Ray, t_min: f64, t_bound: f64) -> Option<Hit> {
        let (index, t) = self.bvh.nearest_below(ray, t_bound, |i, _| {
            Self::crossing(&self.triangles[i as usize], ray).filter(|&t| t > t_min)
        })?;
        Some(self.hit(index, t, ray))
    }

    /// Where `ray` meets triangle `index` beyond `t_min`, if it does: what
    /// [`Mesh::intersect`] finds when that triangle is the nearest.
    pub(crate) fn intersect_triangle(&self, index: u32, ray: &Ray, t_min: f64) -> Option<Hit> {
        let t = self.crossing_beyond(index, ray, t_min)?;
        Some(self.hit(index, t, ray))
    }

    fn hit(&self, index: u32, t: f64, ray: &Ray) -> Hit {
        let tri = &self.triangles[index as usize];
        let point = ray.origin + ray.direction * t;
        let d = point - tri.p0;
        let uv = [tri.uv0[0] + tri.du.dot(d), tri.uv0[1] + tri.dv.dot(d)];
        Hit {
            t,
            point,
            normal: tri.normal,
            uv,
            du: tri.du,
            dv: tri.dv,
            triangle: index,
        }
    }
}

/// Triangle `t`'s box, as the hierarchy bins it.
fn triangle_box(t: &Triangle) -> Aabb {
    let mut b = Aabb { lo: t.p0, hi: t.p0 };
    for p in [t.p0 + t.e1, t.p0 + t.e2] {
        b.lo = Vec3::new(b.lo.x.min(p.x), b.lo.y.min(p.y), b.lo.z.min(p.z));
        b.hi = Vec3::new(b.hi.x.max(p.x), b.hi.y.max(p.y), b.hi.z.max(p.z));
    }
    b
}

/// [`Mesh::neighbour`]'s mark for an edge no other triangle shares.
const NO_NEIGHBOUR: u32 = u32::MAX;

/// Vertex ids by exact position: one id per distinct point (its
/// coordinates' bits), so corners a model shares by index, or repeats at a
/// seam with other texture coordinates, are one vertex.
#[derive(Default)]
pub(crate) struct VertexIds {
    ids: std::collections::HashMap<[u64; 3], u32>,
}

impl VertexIds {
    /// The id of point `p` (new points are numbered in order of arrival).
    pub fn id(&mut self, p: Vec3) -> u32 {
        let next = self.ids.len() as u32;
        *self
            .ids
            .entry([p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
            .or_insert(next)
    }
}

/// For each triangle (its corners' vertex ids), the triangle across each
/// of its edges ([`Mesh::neighbour`]'s order), or [`NO_NEIGHBOUR`] where
/// none or more than one other triangle has that edge.
fn edge_neighbours(vertices: &[[u32; 3]]) -> Vec<[u32; 3]> {
    let edges = |v: &[u32; 3]| [(v[0], v[2]), (v[0], v[1]), (v[1], v[2])];
    // Each edge filed under its lower vertex (a counting sort: a vertex
    // has a few edges, so a shared edge's two entries are found in a short
    // scan of one bucket), as (its higher vertex, triangle · 3 + edge).
    let count = vertices
        .iter()
        .flatten()
        .max()
        .map_or(0, |&m| m as usize + 1);
    let mut start = vec![0u32; count + 1];
    for v in vertices {
        for (a, b) in edges(v) {
            start[a.min(b) as usize + 1] += 1;
        }
    }
    for i in 1..start.len() {
        start[i] += start[i - 1];
    }
    let mut filled = start.clone();
    let mut filed = vec![(0u32, 0u32); 3 * vertices.len()];
    for (t, v) in (0u32..).zip(vertices) {
        for (k, (a, b)) in (0u32..).zip(edges(v)) {
            let slot = &mut filled[a.min(b) as usize];
            filed[*slot as usize] = (a.max(b), 3 * t + k);
            *slot += 1;
        }
    }
    let mut out = vec![[NO_NEIGHBOUR; 3]; vertices.len()];
    for bucket in start.windows(2) {
        let bucket = &filed[bucket[0] as usize..bucket[1] as usize];
        for (i, &(high, x)) in bucket.iter().enumerate() {
            let mut sharing = bucket
                .iter()
                .enumerate()
                .filter(|&(j, e)| j != i && e.0 == high);
            // Exactly one other triangle on the edge: neighbours.
            if let (Some((_, &(_, y))), None) = (sharing.next(), sharing.next()) {
                out[(x / 3) as usize][(x % 3) as usize] = y / 3;
            }
        }
    }
    out
}

/// Where a ray meets a surface, with what a footprint needs.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Hit {
    pub t: f64,
    pub point: Vec3,
    pub normal: Vec3,
    pub uv: [f64; 2],
    /// ∂uv/∂p along the tangent plane: uv(q) ≈ uv + [du·(q−p), dv·(q−p)].
    pub du: Vec3,
    pub dv: Vec3,
    /// The mesh triangle hit (0 for other shapes).
    pub triangle: u32,
}

/// A planar primitive as the exact pixel integral sees it: its plane, its
/// affine UV map, and the region of the plane it covers.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Planar {
    /// A point of the plane, where UV is `uv`.
    pub point: Vec3,
    /// UV at `point`.
    pub uv: [f64; 2],
    /// Unit normal.
    pub normal: Vec3,
    /// Gradients of u and v along the plane.
    pub du: Vec3,
    pub dv: Vec3,
    /// Where on the plane the primitive lies.
    pub extent: Extent,
    /// The mesh triangle this is (`None` for planes, quads and tangent
    /// planes): what its shadow rays leave from.
    pub triangle: Option<u32>,
}

/// The part of its plane a planar primitive covers.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Extent {
    /// All of it.
    Plane,
    /// `0 ≤ u, v ≤ 1` (a quad's UV are its edge parameters).
    UnitUv,
    /// Barycentric `b1 = g1·(q − point) ≥ 0`, `b2 = g2·(q − point) ≥ 0`,
    /// `b1 + b2 ≤ 1`.
    Triangle { g1: Vec3, g2: Vec3 },
}

impl Geometry {
    /// The planar primitive `triangle` of this shape (for a mesh; any
    /// index for planes and quads); `None` for spheres.
    pub(crate) fn planar(&self, triangle: u32) -> Option<Planar> {
        match *self {
            Geometry::Plane {
                point,
                normal,
                u_axis,
                v_axis,
            } => Some(Planar {
                point,
                uv: [0.0, 0.0],
                normal,
                du: u_axis,
                dv: v_axis,
                extent: Extent::Plane,
                triangle: None,
            }),
            Geometry::Quad {
                origin,
                edge_u,
                edge_v,
            } => {
                let QuadFrame { normal, du, dv } = QuadFrame::new(edge_u, edge_v)?;
                Some(Planar {
                    point: origin,
                    uv: [0.0, 0.0],
                    normal,
                    du,
                    dv,
                    extent: Extent::UnitUv,
                    triangle: None,
                })
            }
            Geometry::Mesh(ref mesh) => {
                let tri = mesh.triangles.get(triangle as usize)?;
                let (g1, g2) = quad_gradients(tri.e1, tri.e2);
                Some(Planar {
                    point: tri.p0,
                    uv: tri.uv0,
                    normal: tri.normal,
                    du: tri.du,
                    dv: tri.dv,
                    extent: Extent::Triangle { g1, g2 },
                    triangle: Some(triangle),
                })
            }
            Geometry::Sphere { .. } => None,
        }
    }

    pub(crate) fn intersect(&self, ray: &Ray, t_min: f64) -> Option<Hit> {
        match *self {
            Geometry::Plane {
                point,
                normal,
                u_axis,
                v_axis,
            } => {
                let denom = ray.direction.dot(normal);
                if denom.abs() < 1e-12 {
                    return None;
                }
                let t = (point - ray.origin).dot(normal) / denom;
                (t > t_min && t.is_finite()).then(|| {
                    let p = ray.origin + ray.direction * t;
                    let rel = p - point;
                    Hit {
                        t,
                        point: p,
                        normal,
                        uv: [rel.dot(u_axis), rel.dot(v_axis)],
                        du: u_axis,
                        dv: v_axis,
                        triangle: 0,
                    }
                })
            }
            Geometry::Quad {
                origin,
                edge_u,
                edge_v,
            } => QuadFrame::new(edge_u, edge_v)?.hit(origin, ray, t_min),
            Geometry::Mesh(ref mesh) => mesh.intersect(ray, t_min),
            Geometry::Sphere { centre, radius } => {
                let oc = ray.origin - centre;
                let b = oc.dot(ray.direction);
                let c = oc.dot(oc) - radius * radius;
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let s = disc.sqrt();
                let t = if -b - s > t_min { -b - s } else { -b + s };
                if t <= t_min || t.is_nan() {
                    return None;
                }
                let p = ray.origin + ray.direction * t;
                let n = (p - centre) * (1.0 / radius);
                let phi = n.z.atan2(n.x);
                let theta = n.y.clamp(-1.0, 1.0).acos();
                let u = (phi + std::f64::consts::PI) / std::f64::consts::TAU;
                let v = 1.0 - theta / std::f64::consts::PI;
                // Gradients of (u, v) on the sphere at p (linearisation).
                let rxz = (n.x * n.x + n.z * n.z).sqrt().max(1e-9);
                let du = Vec3::new(-n.z, 0.0, n.x) * (1.0 / (std::f64::consts::TAU * radius * rxz));
                let along = Vec3::new(-n.x * n.y, rxz * rxz, -n.z * n.y) * (1.0 / rxz);
                let dv = along * (1.0 / (std::f64::consts::PI * radius));
                Some(Hit {
                    t,
                    point: p,
                    normal: n,
                    uv: [u, v],
                    du,
                    dv,
                    triangle: 0,
                })
            }
        }
    }
}

/// Gradients of `(s, t)` for `p = s·a + t·b` restricted to the plane of `a, b`.
fn quad_gradients(a: Vec3, b: Vec3) -> (Vec3, Vec3) {
    let (aa, ab, bb) = (a.dot(a), a.dot(b), b.dot(b));
    let det = aa * bb - ab * ab;
    let du = (a * bb - b * ab) * (1.0 / det);
    let dv = (b * aa - a * ab) * (1.0 / det);
    (du, dv)
}

/// A quad's unit normal and UV gradients: what its ray test needs beyond
/// its corner, solved once per frame by the ray caster (and per ray by
/// [`Geometry::intersect`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct QuadFrame {
    /// Unit normal, `edge_u × edge_v` normalised.
    pub(crate) normal: Vec3,
    /// Gradient of `u` (in the quad's plane: `u = (p − origin)·du`).
    pub(crate) du: Vec3,
    /// Gradient of `v`.
    pub(crate) dv: Vec3,
}

impl QuadFrame {
    /// `None` for a degenerate quad (parallel edges).
    pub(crate) fn new(edge_u: Vec3, edge_v: Vec3) -> Option<QuadFrame> {
        let normal = edge_u.cross(edge_v).normalized()?;
        let (du, dv) = quad_gradients(edge_u, edge_v);
        Some(QuadFrame { normal, du, dv })
    }

    /// Where `ray` meets the quad with corner `origin` beyond `t_min`.
    #[inline]
    pub(crate) fn hit(&self, origin: Vec3, ray: &Ray, t_min: f64) -> Option<Hit> {
        let QuadFrame { normal, du, dv } = *self;
        let denom = ray.direction.dot(normal);
        if denom.abs() < 1e-12 {
            return None;
        }
        let t = (origin - ray.origin).dot(normal) / denom;
        if !(t > t_min && t.is_finite()) {
            return None;
        }
        let p = ray.origin + ray.direction * t;
        let rel = p - origin;
        let uv = [rel.dot(du), rel.dot(dv)];
        ((0.0..=1.0).contains(&uv[0]) && (0.0..=1.0).contains(&uv[1])).then_some(Hit {
            t,
            point: p,
            normal,
            uv,
            du,
            dv,
            triangle: 0,
        })
    }
}

/// UV → texture space: `rotate(uv ⊙ scale) + offset`, rotation in degrees
/// counter-clockwise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UvTransform {
    /// Per-axis scale (tiles per UV unit).
    pub scale: [f64; 2],
    /// Offset added after scaling and rotation.
    pub offset: [f64; 2],
    /// Rotation in degrees.
    pub rotation_degrees: f64,
}

impl Default for UvTransform {
    fn default() -> Self {
        UvTransform {
            scale: [1.0, 1.0],
            offset: [0.0, 0.0],
            rotation_degrees: 0.0,
        }
    }
}

impl UvTransform {
    /// SceneTexture space back to UV (the inverse of [`UvTransform::apply`]).
    pub fn invert(&self, t: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.sin_cos();
        let (x, z) = (t[0] - self.offset[0], t[1] - self.offset[1]);
        [
            (c * x + s * z) / self.scale[0],
            (-s * x + c * z) / self.scale[1],
        ]
    }

    /// Sine and cosine of the rotation; exact and free for the common zero.
    fn sin_cos(&self) -> (f64, f64) {
        if self.rotation_degrees == 0.0 {
            (0.0, 1.0)
        } else {
            self.rotation_degrees.to_radians().sin_cos()
        }
    }

    /// UV to texture space.
    pub fn apply(&self, uv: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.sin_cos();
        let (x, z) = (uv[0] * self.scale[0], uv[1] * self.scale[1]);
        [
            c * x - s * z + self.offset[0],
            s * x + c * z + self.offset[1],
        ]
    }
}

/// A texture bound to a surface.
#[derive(Clone)]
pub struct SceneTexture {
    /// Where it came from (file name or built-in name), for reports.
    pub name: String,
    /// The packed tree.
    pub tree: Arc<QuadTree>,
    /// Raster baselines (mip pyramid, summed-area table), built on first use.
    baselines: Arc<std::sync::OnceLock<Result<Baselines, String>>>,
    /// The mip pyramid of the largest raster within the tree's memory
    /// ([`same_memory_level`]), built on first use.
    same_memory: Arc<std::sync::OnceLock<Result<quadtex_core::baseline::MipPyramid, String>>>,
    /// Bytes the baselines may take ([`baseline_bytes`]), `None`: no budget.
    memory_budget: Option<u64>,
    /// Spheres' pole fans, by the UV transform and wrap they were drawn
    /// for, each built on first use.
    polar_fans: Arc<std::sync::Mutex<FanCache>>,
}

/// What a texture's pole fans are drawn for: the UV transform's bits
/// (scale, offset, rotation) and the wrap's modes.
type FanKey = ([u64; 5], quadtex_core::WrapMode, quadtex_core::WrapMode);

/// A texture's pole fans drawn so far, by what they were drawn for.
type FanCache = Vec<(FanKey, Arc<PolarFans>)>;

/// The raster forms a baseline filter needs, made from the tree's cells.
pub(crate) struct Baselines {
    pub pyramid: quadtex_core::baseline::MipPyramid,
    pub sat: quadtex_core::baseline::SummedAreaTable,
}

/// The raster baselines see the tree rasterised at `2^clamp(depth, 10, 11)`
/// cells: at least 1024², so small textures (a 2×2 checker) are as sharp as
/// a raster user would make them, at most 2048² to bound memory (the SAT
/// takes 32 bytes a cell). Deeper trees are box-downsampled for them.
pub fn baseline_level(depth: u8) -> u8 {
    depth.clamp(10, 11)
}

/// The level `L` of the largest raster, `2^L` texels a side (at most
/// [`baseline_level`]'s 2048²), whose RGBA8 texels with their mips (16/3
/// bytes a texel) fit in `bytes`; 0 (one texel) when none does.
pub fn same_memory_level(bytes: u64, depth: u8) -> u8 {
    (0..=baseline_level(depth))
        .rev()
        .find(|&l| mipmapped_raster_bytes(l) <= bytes)
        .unwrap_or(0)
}

/// Bytes of an RGBA8 raster `2^level` texels a side with its mips, as a
/// GPU stores it: 16/3 bytes a texel.
pub fn mipmapped_raster_bytes(level: u8) -> u64 {
    16 * (1u64 << (2 * u32::from(level.min(30)))) / 3
}

/// Bytes the raster baselines of one texture take at `level`: the raster
/// (8 bytes a cell), the mip pyramid (16 bytes a cell, 4/3 for the levels)
/// and the summed-area table (32 bytes a cell); 256 MiB at level 11.
pub fn baseline_bytes(level: u8) -> u64 {
    let side = 1u64 << level.min(20);
    let cells = side * side;
    8 * cells + 16 * cells * 4 / 3 + 32 * (side + 1) * (side + 1)
}

impl SceneTexture {
    /// A texture from its tree.
    pub fn new(name: impl Into<String>, tree: Arc<QuadTree>) -> SceneTexture {
        SceneTexture {
            name: name.into(),
            tree,
            baselines: Arc::default(),
            same_memory: Arc::default(),
            memory_budget: None,
            polar_fans: Arc::default(),
        }
    }

    /// The same texture, refusing to build raster baselines whose
    /// [`baseline_bytes`] exceed `bytes` (scenes loaded under
    /// `quadtex_io::Limits` get its `max_memory`).
    pub fn with_memory_budget(mut self, bytes: u64) -> SceneTexture {
        self.memory_budget = Some(bytes);
        self
    }

    /// The filtering view of this texture under `wrap` (shares the tree).
    pub fn texture(&self, wrap: Wrap) -> quadtex_core::Texture {
        quadtex_core::Texture::new(Arc::clone(&self.tree), wrap)
    }

    /// The pole fans of this texture on a sphere whose UV goes to texture
    /// space by `uv`, read under `wrap`: drawn once for each.
    pub(crate) fn polar_fans(&self, uv: &UvTransform, wrap: Wrap) -> Arc<PolarFans> {
        let bits = [uv.scale[0], uv.scale[1], uv.offset[0], uv.offset[1]].map(f64::to_bits);
        let key = (
            [
                bits[0],
                bits[1],
                bits[2],
                bits[3],
                uv.rotation_degrees.to_bits(),
            ],
            wrap.x(),
            wrap.z(),
        );
        // A poisoned lock only means another thread panicked mid-insert;
        // the list itself is still a valid cache.
        let mut caps = (self.polar_fans.lock()).unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some((_, found)) = caps.iter().find(|(k, _)| *k == key) {
            return Arc::clone(found);
        }
        let drawn = Arc::new(PolarFans::new(&self.tree, uv, wrap));
        caps.push((key, Arc::clone(&drawn)));
        drawn
    }

    /// The raster baselines, built once (see [`baseline_level`]).
    pub(crate) fn baselines(&self) -> Result<&Baselines, &str> {
        self.baselines
            .get_or_init(|| {
                let level = baseline_level(self.tree.depth());
                quadtex_core::memory::check_budget(
                    || format!("rasterising at level {level} for the raster baselines"),
                    baseline_bytes(level),
                    self.memory_budget,
                    "use the quadtree filter, or raise --memory-limit",
                )
                .map_err(|e| format!("{}: {e}", self.name))?;
                let grid = self
                    .tree
                    .rasterise(baseline_level(self.tree.depth()))
                    .map_err(|e| format!("{}: {e}", self.name))?;
                Ok(Baselines {
                    pyramid: quadtex_core::baseline::MipPyramid::new(&grid),
                    sat: quadtex_core::baseline::SummedAreaTable::new(&grid),
                })
            })
            .as_ref()
            .map_err(String::as_str)
    }
}

impl SceneTexture {
    /// The mip pyramid of the largest raster that fits the tree's memory
    /// ([`same_memory_level`]), built once.
    pub(crate) fn same_memory_pyramid(&self) -> Result<&quadtex_core::baseline::MipPyramid, &str> {
        self.same_memory
            .get_or_init(|| {
                let level = same_memory_level(self.tree.memory_bytes(), self.tree.depth());
                let grid = self
                    .tree
                    .rasterise(level)
                    .map_err(|e| format!("{}: {e}", self.name))?;
                Ok(quadtex_core::baseline::MipPyramid::new(&grid))
            })
            .as_ref()
            .map_err(String::as_str)
    }
}

impl std::fmt::Debug for SceneTexture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SceneTexture")
            .field("name", &self.name)
            .field("nodes", &self.tree.node_count())
            .finish()
    }
}

/// A renderable surface.
#[derive(Debug, Clone)]
pub struct Surface {
    /// Shape.
    pub geometry: Geometry,
    /// SceneTexture, or `None` for a flat colour.
    pub texture: Option<SceneTexture>,
    /// Flat colour (untextured) or multiplier (textured), linear.
    pub colour: Rgba,
    /// UV to texture space.
    pub uv_transform: UvTransform,
    /// Beyond the unit square (per axis; see [`quadtex_core::Wrap`]).
    pub wrap: Wrap,
}

/// The background seen by rays that hit nothing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sky {
    /// One colour.
    Solid(Rgba),
    /// Blend from `horizon` (looking level) to `zenith` (looking up).
    Gradient {
        /// Colour at the horizon and below.
        horizon: Rgba,
        /// Colour straight up.
        zenith: Rgba,
    },
}

/// Shading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lighting {
    /// SceneTexture colour as is.
    Unlit,
    /// Lambert with one directional light and hard shadows.
    Lambert {
        /// Unit direction *towards* the light.
        direction: Vec3,
        /// Light colour (linear, may exceed 1).
        colour: [f32; 3],
        /// Ambient colour added everywhere.
        ambient: [f32; 3],
    },
}

/// A complete scene.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The camera.
    pub camera: Camera,
    /// The surfaces.
    pub surfaces: Vec<Surface>,
    /// The background.
    pub sky: Sky,
    /// The shading model.
    pub lighting: Lighting,
}

impl Scene {
    /// The scene's textures, each tree once, in order of first use, with the
    /// index of the first surface that uses it.
    pub fn distinct_textures(&self) -> Vec<(usize, &SceneTexture)> {
        let mut out: Vec<(usize, &SceneTexture)> = Vec::new();
        for (i, s) in self.surfaces.iter().enumerate() {
            if let Some(t) = &s.texture
                && !out.iter().any(|(_, o)| Arc::ptr_eq(&o.tree, &t.tree))
            {
                out.push((i, t));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles on an edge are each other's neighbours across it; an
    /// edge three triangles share (not a manifold's) gives none of them a
    /// neighbour; a corner alone shared is no edge.
    #[test]
    fn neighbours_share_an_edge_and_only_two_do() {
        // 0-1-2 and 2-1-3 share edge 1–2 (edge 2 of the first, 1 of the second).
        let two = edge_neighbours(&[[0, 1, 2], [2, 1, 3]]);
        assert_eq!(two[0], [NO_NEIGHBOUR, NO_NEIGHBOUR, 1]);
        assert_eq!(two[1], [NO_NEIGHBOUR, 0, NO_NEIGHBOUR]);
        let three = edge_neighbours(&[[0, 1, 2], [2, 1, 3], [1, 2, 4]]);
        assert!(three.iter().all(|n| *n == [NO_NEIGHBOUR; 3]), "{three:?}");
        let corner = edge_neighbours(&[[0, 1, 2], [2, 3, 4]]);
        assert!(corner.iter().all(|n| *n == [NO_NEIGHBOUR; 3]));
    }

    /// A mesh's neighbours, found in the input's order while the
    /// triangles move into the hierarchy's, name the triangles as the
    /// mesh numbers them: on a shuffled grid of 24 × 24 squares (two
    /// triangles each), every interior edge joins two triangles that name
    /// each other and share that edge's two corners, and no boundary edge
    /// has a neighbour.
    #[test]
    fn neighbours_follow_the_hierarchys_order() {
        let n = 24usize;
        let at = |i: usize, j: usize| Vec3::new(i as f64, (i * j % 7) as f64 * 0.125, j as f64);
        let uv = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        let mut triangles = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
                triangles.push(Triangle::new([a, b, c], uv).unwrap());
                triangles.push(Triangle::new([b, d, c], uv).unwrap());
            }
        }
        // A fixed shuffle: the input's order is not the grid's.
        let mut seed = 11u64;
        for k in (1..triangles.len()).rev() {
            let r = (crate::math::unit_random(&mut seed) * (k + 1) as f64) as usize;
            triangles.swap(k, r.min(k));
        }
        let mesh = Mesh::new(triangles).unwrap();
        let key = |p: Vec3| [p.x, p.y, p.z].map(|v| (v * 1e6).round() as i64);
        // Edge `e` joins the corners other than `FACING[e]`.
        const FACING: [usize; 3] = [1, 2, 0];
        let mut linked = 0;
        for t in 0..mesh.len() as u32 {
            let mine = mesh.corners(t as usize).unwrap().map(key);
            for e in 0..3 {
                let Some(u) = mesh.neighbour(t, e) else {
                    continue;
                };
                linked += 1;
                assert!(
                    (0..3).any(|f| mesh.neighbour(u, f) == Some(t)),
                    "{t} {e} {u}"
                );
                let theirs = mesh.corners(u as usize).unwrap().map(key);
                for k in (0..3).filter(|&k| k != FACING[e]) {
                    assert!(theirs.contains(&mine[k]), "{t} {e} {u}");
                }
                assert!(!theirs.contains(&mine[FACING[e]]), "{t} {e} {u}");
            }
        }
        // Interior edges: 3n² − 2n, each seen from both sides.
        assert_eq!(linked, 2 * (3 * n * n - 2 * n));
    }
}

//! A planar primitive seen from the camera ([`View`]): the projective
//! map from the screen to its texture, the half-planes it is seen within,
//! and where a polygon lies against them ([`placement`]). Shared by the
//! exact pixel ([`crate::exact`]), its spans ([`crate::span`]) and the
//! visibility pass ([`crate::visibility`]).

use std::borrow::Cow;
use std::sync::OnceLock;

use quadtex_core::{ConvexPolygon, FilterOptions, PixelFilter, Projection};

use crate::math::Vec3;
use crate::scene::{Extent, Planar, Scene};

/// Where a polygon lies against the half-planes `a·x + b·y + c ≥ 0` of a
/// view's lines or a region's edges ([`placement`]).
pub(crate) enum Placement {
    /// Wholly beyond one line: the clip is empty.
    Outside,
    /// Within every line: the clip is the polygon itself.
    Inside,
    /// Neither: the clip cuts it.
    Straddles,
}

/// Where `polygon` lies against `lines`, decided from its vertices alone
/// with the clip's own side test: wholly inside (the clip would copy every
/// vertex unchanged) or wholly beyond one line (the clip would come out
/// empty) needs no clip. A rectangle (a pixel's support) is decided from
/// two corners a line ([`rect_sides`]), the same answer.
pub(crate) fn placement(
    polygon: &ConvexPolygon,
    lines: impl Iterator<Item = [f64; 3]>,
) -> Placement {
    placement_with(polygon, lines, |_| {})
}

/// [`placement`], handing each line that some vertex lies beyond to
/// `straddled` (until one shows the polygon outside): the lines a clip of
/// the polygon needs, the others holding all of it.
#[inline]
fn placement_with(
    polygon: &ConvexPolygon,
    lines: impl Iterator<Item = [f64; 3]>,
    mut straddled: impl FnMut([f64; 3]),
) -> Placement {
    let rect = axis_aligned_rect(polygon);
    let mut all_inside = true;
    for line in lines {
        let (some_in, some_out) = sides(polygon, rect, line);
        if !some_in {
            return Placement::Outside;
        }
        if some_out {
            all_inside = false;
            straddled(line);
        }
    }
    if all_inside {
        Placement::Inside
    } else {
        Placement::Straddles
    }
}

/// Whether some vertex of `polygon` (the rectangle `rect`, when it is
/// one, [`axis_aligned_rect`]) lies inside `line`, and whether some lies
/// outside ([`vertex_sides`]).
#[inline]
fn sides(
    polygon: &ConvexPolygon,
    rect: Option<(f64, f64, f64, f64)>,
    line: [f64; 3],
) -> (bool, bool) {
    match rect {
        Some(r) if ordered(r, line) => rect_sides(r, line),
        _ => vertex_sides(polygon, line),
    }
}

/// Whether some vertex of `polygon` lies inside `a·x + b·y + c ≥ 0`, and
/// whether some lies outside (NaN counts as outside), by the clip's test.
#[inline]
fn vertex_sides(polygon: &ConvexPolygon, [a, b, c]: [f64; 3]) -> (bool, bool) {
    let (mut some_in, mut some_out) = (false, false);
    for &[x, y] in polygon.vertices() {
        if a * x + b * y + c >= 0.0 {
            some_in = true;
        } else {
            some_out = true;
        }
    }
    (some_in, some_out)
}

/// `(x0, y0, x1, y1)` when `polygon` has the four vertices of
/// [`ConvexPolygon::rect`] (a pixel filter's support, most often).
#[inline]
fn axis_aligned_rect(polygon: &ConvexPolygon) -> Option<(f64, f64, f64, f64)> {
    match polygon.vertices() {
        &[[x0, y0], [x1, y1], [x2, y2], [x3, y3]]
            if y0 == y1 && x1 == x2 && y2 == y3 && x3 == x0 && x0 < x1 && y0 < y2 =>
        {
            Some((x0, y0, x1, y2))
        }
        _ => None,
    }
}

/// Whether [`rect_sides`] decides for rectangle `r` and `line`: overflow
/// is kept out rather than reasoned about (`∞ − ∞` is NaN, which no order
/// holds), so coefficients from `10²⁹⁰` up, or corners from `10¹⁵`, take
/// the vertex test.
#[inline]
fn ordered((x0, y0, x1, y1): (f64, f64, f64, f64), [a, b, c]: [f64; 3]) -> bool {
    [x0, y0, x1, y1].iter().all(|v| v.abs() < 1e15)
        && a.abs() < 1e290
        && b.abs() < 1e290
        && c.abs() < 1e290
}

/// [`vertex_sides`] of the rectangle `[x0, x1] × [y0, y1]` from two
/// corners: those where `a·x + b·y` is greatest and least (chosen by the
/// signs of `a` and `b`), with the same expression as at every corner.
/// Rounding is monotone, so they are the greatest and least of the four
/// values the vertex test evaluates, and the answer is the same.
#[inline]
fn rect_sides((x0, y0, x1, y1): (f64, f64, f64, f64), [a, b, c]: [f64; 3]) -> (bool, bool) {
    let (x_hi, x_lo) = if a >= 0.0 { (x1, x0) } else { (x0, x1) };
    let (y_hi, y_lo) = if b >= 0.0 { (y1, y0) } else { (y0, y1) };
    (
        a * x_hi + b * y_hi + c >= 0.0,
        a * x_lo + b * y_lo + c < 0.0,
    )
}

/// A planar primitive seen from the camera: rows `(a, b, c)` of affine
/// functions of the screen point `(px, py, 1)`.
#[derive(Debug, Clone)]
pub(crate) struct View {
    surface: usize,
    /// `w`, positive where the primitive's plane is in front of the camera
    /// (proportional to `1/depth`).
    w: [f64; 3],
    /// The plane's depth numerator: ray parameter `t = depth / w(s)`.
    depth: f64,
    /// Half-planes `row · (px, py, 1) ≥ 0` bounding the primitive.
    bounds: [[f64; 3]; 4],
    bound_count: usize,
    projection: Projection,
    normal: Vec3,
    /// The mesh triangle this is the view of, if it is one.
    triangle: Option<u32>,
    /// The lighting factor every point of the primitive gets, once a
    /// renderer has shown it for the frame the view is built for (`None`
    /// inside: it varies, or is not shown), [`View::uniform_light`].
    light: OnceLock<Option<[f32; 3]>>,
}

/// A planar primitive's affine rows over the screen point `(px, py, 1)`:
/// `w` (positive in front of the camera), the depth numerator, `u·w` and
/// `v·w`, and the half-planes of its edges.
struct Rows {
    w: [f64; 3],
    depth: f64,
    u: [f64; 3],
    v: [f64; 3],
    bounds: [[f64; 3]; 4],
    bound_count: usize,
}

impl Rows {
    /// `None` when the camera lies in the primitive's plane.
    fn new(scene: &Scene, planar: &Planar) -> Option<Rows> {
        let cam = &scene.camera;
        // The ray direction through (px, py), affine: d = d0 + dx·px + dy·py.
        let [d0, dx, dy] = cam.basis();
        let c = cam.position;
        let n = planar.normal;
        let np = n.dot(planar.point - c);
        if np.abs() <= 1e-12 * (1.0 + planar.point.length() + c.length()) || np.is_nan() {
            return None;
        }
        let sign = np.signum();
        let row = |g: Vec3| [g.dot(dx), g.dot(dy), g.dot(d0)];
        let nd = row(n);
        let w = nd.map(|v| sign * v);
        // f(q) = f_p + g·(q − p) along the ray: [f(C)·(n·d) + np·(g·d)] / (n·d).
        let affine = |f_p: f64, g: Vec3| {
            let f_c = f_p + g.dot(c - planar.point);
            let gd = row(g);
            [0, 1, 2].map(|k| sign * (f_c * nd[k] + np * gd[k]))
        };
        let u = affine(planar.uv[0], planar.du);
        let v = affine(planar.uv[1], planar.dv);
        let minus = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let (bounds, bound_count) = match planar.extent {
            Extent::Plane => ([[0.0; 3]; 4], 0),
            Extent::UnitUv => ([u, minus(w, u), v, minus(w, v)], 4),
            Extent::Triangle { g1, g2 } => {
                let b1 = affine(0.0, g1);
                let b2 = affine(0.0, g2);
                ([b1, b2, minus(minus(w, b1), b2), [0.0; 3]], 3)
            }
        };
        Some(Rows {
            w,
            depth: np.abs(),
            u,
            v,
            bounds,
            bound_count,
        })
    }
}

impl View {
    /// The view of `planar`, a part of surface `surface`; `None` when the
    /// camera lies in its plane (it is then seen edge-on: nothing).
    pub fn new(scene: &Scene, surface: usize, planar: &Planar) -> Option<View> {
        let Rows {
            w,
            depth,
            u,
            v,
            bounds,
            bound_count,
        } = Rows::new(scene, planar)?;
        let transform = scene.surfaces[surface].uv_transform;
        let o = transform.apply([0.0, 0.0]);
        let ex = transform.apply([1.0, 0.0]);
        let ez = transform.apply([0.0, 1.0]);
        let (a00, a10) = (ex[0] - o[0], ex[1] - o[1]);
        let (a01, a11) = (ez[0] - o[0], ez[1] - o[1]);
        let tex_x = [0, 1, 2].map(|k| a00 * u[k] + a01 * v[k] + o[0] * w[k]);
        let tex_z = [0, 1, 2].map(|k| a10 * u[k] + a11 * v[k] + o[1] * w[k]);
        let projection = Projection::new([tex_x, tex_z, w]).ok()?;
        Some(View {
            surface,
            w,
            depth,
            bounds,
            bound_count,
            projection,
            normal: planar.normal,
            triangle: planar.triangle,
            light: OnceLock::new(),
        })
    }

    /// What the visibility grid needs of `planar`, without the texture
    /// map: its lines ([`View::lines`]: `w`, then the edges) and its depth
    /// numerator ([`View::depth_parts`]); `None` when seen edge-on.
    pub(crate) fn edges(scene: &Scene, planar: &Planar) -> Option<([[f64; 3]; 5], usize, f64)> {
        let rows = Rows::new(scene, planar)?;
        let mut lines = [[0.0; 3]; 5];
        lines[0] = rows.w;
        lines[1..=rows.bound_count].copy_from_slice(&rows.bounds[..rows.bound_count]);
        Some((lines, rows.bound_count + 1, rows.depth))
    }

    /// The part of `support` where this primitive lies (in front of the
    /// camera, inside its edges), ignoring occlusion.
    pub fn region<'s>(&self, support: &'s ConvexPolygon) -> Cow<'s, ConvexPolygon> {
        match self.placement(support) {
            Placement::Outside => Cow::Owned(ConvexPolygon::EMPTY),
            Placement::Inside => Cow::Borrowed(support),
            Placement::Straddles => Cow::Owned(support.clip_lines(self.lines())),
        }
    }

    /// [`View::region`] written into `out`, in place (a polygon moved is
    /// its whole capacity copied; here only its vertices are).
    pub fn region_into(&self, support: &ConvexPolygon, out: &mut ConvexPolygon) {
        // The placement and the lines to clip by in one pass: only the
        // lines some corner of the support lies beyond clip it; the support
        // is within the others, and so is every part of it (in front of the
        // camera, most often).
        let mut lines = [[0.0; 3]; 5];
        let mut n = 0;
        let placed = placement_with(support, self.lines(), |line| {
            lines[n] = line;
            n += 1;
        });
        match placed {
            Placement::Outside => *out = ConvexPolygon::empty(),
            Placement::Inside => out.clone_from(support),
            Placement::Straddles => support.clip_lines_into(&lines[..n], out),
        }
    }

    /// The half-planes `a·x + b·y + c ≥ 0` this primitive is seen within:
    /// in front of the camera, then inside each of its edges.
    pub(crate) fn lines(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        std::iter::once(self.w).chain(self.bounds[..self.bound_count].iter().copied())
    }

    /// Whether this primitive's [`View::region`] of `support` is empty,
    /// without building it where the support's corners decide (the sky's
    /// check of every plane and quad no centre sees, most pixels).
    pub fn misses(&self, support: &ConvexPolygon) -> bool {
        match self.placement(support) {
            Placement::Outside => true,
            Placement::Inside => support.is_empty(),
            Placement::Straddles => self.region(support).is_empty(),
        }
    }

    /// Where `support` lies against this primitive's lines ([`placement`]):
    /// most pixels lie wholly inside or wholly beyond one line.
    pub(crate) fn placement(&self, support: &ConvexPolygon) -> Placement {
        placement(support, self.lines())
    }

    /// The texture's integral over this primitive's part of `support`
    /// (occlusion ignored), under `filter` centred at `centre`.
    pub fn texture_integral(
        &self,
        texture: &quadtex_core::Texture,
        support: &ConvexPolygon,
        filter: PixelFilter,
        centre: [f64; 2],
        options: &FilterOptions,
    ) -> quadtex_core::RegionIntegral {
        texture.integrate_region(
            &self.projection,
            &self.region(support),
            filter,
            centre,
            options,
            &mut quadtex_core::FilterStats::default(),
        )
    }

    /// `(w, depth)`: the ray parameter of the camera's unnormalised ray
    /// through `s` is `depth / w(s)` where `w(s) = w · (s, 1) > 0`
    /// ([`View::lines`] starts with `w`).
    pub(crate) fn depth_parts(&self) -> ([f64; 3], f64) {
        (self.w, self.depth)
    }

    /// For tests: a primitive of surface 0 facing the camera at ray
    /// parameter `depth` everywhere, over the whole screen, with the
    /// identity map to texture space.
    #[cfg(test)]
    pub(crate) fn facing_at(depth: f64) -> View {
        View {
            surface: 0,
            w: [0.0, 0.0, 1.0],
            depth,
            bounds: [[0.0; 3]; 4],
            bound_count: 0,
            projection: Projection::identity(),
            normal: Vec3::new(0.0, 0.0, -1.0),
            triangle: None,
            light: OnceLock::new(),
        }
    }

    /// The surface this primitive is part of.
    pub(crate) fn surface(&self) -> usize {
        self.surface
    }

    /// The map from the screen to the surface's texture.
    pub(crate) fn projection(&self) -> &Projection {
        &self.projection
    }

    /// The primitive's normal (world space, as its surface gives it).
    pub(crate) fn normal(&self) -> Vec3 {
        self.normal
    }

    /// The mesh triangle this is the view of (`None` for planes and quads).
    pub(crate) fn triangle(&self) -> Option<u32> {
        self.triangle
    }

    /// The lighting factor every point of the primitive gets, as `show`
    /// finds it (`None`: it varies from point to point) the first time it
    /// is asked for, kept for the view's life (a frame's, or a row's).
    pub(crate) fn uniform_light(
        &self,
        show: impl FnOnce() -> Option<[f32; 3]>,
    ) -> Option<[f32; 3]> {
        *self.light.get_or_init(show)
    }

    /// Ray parameter (for the camera's unnormalised ray through `s`) of
    /// the plane at screen point `s`; infinite where `w(s) ≤ 0`.
    pub(crate) fn depth_at(&self, s: [f64; 2]) -> f64 {
        let w = self.w[0] * s[0] + self.w[1] * s[1] + self.w[2];
        if w > 0.0 {
            self.depth / w
        } else {
            f64::INFINITY
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The vertex test, as [`placement`] runs it for any polygon.
    fn vertex_placement(polygon: &ConvexPolygon, lines: &[[f64; 3]]) -> Placement {
        let mut all_inside = true;
        for &[a, b, c] in lines {
            let values: Vec<f64> = (polygon.vertices().iter())
                .map(|&[x, y]| a * x + b * y + c)
                .collect();
            if !values.iter().any(|&v| v >= 0.0) {
                return Placement::Outside;
            }
            all_inside &= values.iter().all(|&v| v >= 0.0);
        }
        if all_inside {
            Placement::Inside
        } else {
            Placement::Straddles
        }
    }

    /// The rectangle's two-corner test decides as the vertex test does,
    /// to the last bit: lines through corners, along sides, with zero
    /// coefficients, huge and tiny ones, and random ones.
    #[test]
    fn a_rectangles_placement_is_the_vertex_tests() {
        let mut seed = 0x5eed_u64;
        let mut next = || crate::math::unit_random(&mut seed);
        let mut decided = [0usize; 3];
        for _ in 0..20_000 {
            let (x0, y0) = ((next() * 2000.0).floor(), (next() * 1000.0).floor());
            let r = *[0.5, 1.0, 2.0].get((next() * 3.0) as usize).unwrap_or(&0.5);
            let rect = ConvexPolygon::rect(x0 - r, y0 - r, x0 + r, y0 + r);
            let corners = rect.vertices().to_vec();
            let coefficient = |next: &mut dyn FnMut() -> f64| match (next() * 6.0) as u8 {
                0 => 0.0,
                1 => 1e300 * (next() - 0.5),
                2 => 1e-300 * (next() - 0.5),
                _ => next() * 4.0 - 2.0,
            };
            let lines: Vec<[f64; 3]> = (0..1 + (next() * 4.0) as usize)
                .map(|_| {
                    let (a, b) = (coefficient(&mut next), coefficient(&mut next));
                    // Through a corner (exactly or nearly), or anywhere.
                    let [cx, cy] = corners[(next() * 4.0) as usize % 4];
                    let c = match (next() * 3.0) as u8 {
                        0 => -(a * cx + b * cy),
                        1 => -(a * cx + b * cy) * (1.0 + 1e-16 * (next() - 0.5)),
                        _ => coefficient(&mut next) * 2000.0,
                    };
                    [a, b, c]
                })
                .collect();
            let want = vertex_placement(&rect, &lines);
            let got = placement(&rect, lines.iter().copied());
            assert!(
                std::mem::discriminant(&want) == std::mem::discriminant(&got),
                "{rect:?} against {lines:?}"
            );
            decided[match got {
                Placement::Outside => 0,
                Placement::Inside => 1,
                Placement::Straddles => 2,
            }] += 1;
        }
        // Every outcome was met often.
        assert!(decided.iter().all(|&n| n > 1000), "{decided:?}");
        // Sums that overflow at some corners (∞ − ∞ is NaN there): the
        // vertex test decides these.
        let rect = ConvexPolygon::rect(9.5, 0.5, 10.5, 1.5);
        for lines in [
            [[1e308, -1e308, 0.0]],
            [[-1e308, 1.5e308, -1e308]],
            [[1.7e308, 1.7e308, -1.7e308]],
        ] {
            let want = vertex_placement(&rect, &lines);
            let got = placement(&rect, lines.iter().copied());
            assert!(
                std::mem::discriminant(&want) == std::mem::discriminant(&got),
                "{rect:?} against {lines:?}"
            );
        }
    }

    /// A mesh's neighbours ([`crate::scene::Mesh::neighbour`]) follow its
    /// triangles' views' edge lines: across edge `k`, the neighbour's
    /// centroid lies outside line `k + 1` of [`View::lines`] and the
    /// triangle's own inside. On a bumpy grid, seen from above, every
    /// inner edge has its neighbour, both ways; the border's edges none.
    #[test]
    fn a_neighbour_lies_beyond_the_edge_it_shares() {
        use crate::math::Vec3;
        use crate::scene::{Geometry, Mesh, Triangle, VertexIds};
        let text = "[camera]\nposition = [0.3, 3, 2]\nlook_at = [0, 0, 0]\nfov = 60\n\
                    width = 64\nheight = 48\n\n[[shape]]\ntype = \"sphere\"\n\
                    centre = [0, -9, 0]\nradius = 0.1\n";
        let mut scene = crate::parse_scene(
            text,
            std::path::Path::new("grid.toml"),
            &quadtex_io::Limits::default(),
        )
        .unwrap();
        let n = 6;
        let corner = |i: i32, j: i32| {
            let (x, z) = (f64::from(i) / 3.0 - 1.0, f64::from(j) / 3.0 - 1.0);
            Vec3::new(x, 0.1 * (3.0 * x).sin() * (2.0 * z).cos(), z)
        };
        let (mut triangles, mut vertices, mut ids) = (Vec::new(), Vec::new(), VertexIds::default());
        for j in 0..n {
            for i in 0..n {
                let uv = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
                let (a, b, c, d) = (
                    corner(i, j),
                    corner(i + 1, j),
                    corner(i + 1, j + 1),
                    corner(i, j + 1),
                );
                for p in [[a, d, c], [a, c, b]] {
                    triangles.push(Triangle::new(p, uv).unwrap());
                    vertices.push(p.map(|p| ids.id(p)));
                }
            }
        }
        let count = triangles.len();
        let mesh = Mesh::with_vertices(triangles, vertices).unwrap();
        let mut surface = scene.surfaces[0].clone();
        surface.geometry = Geometry::Mesh(std::sync::Arc::new(mesh.clone()));
        scene.surfaces.push(surface);
        let centroid = |t: u32| {
            let c = mesh.corners(t as usize).unwrap();
            scene
                .camera
                .project((c[0] + c[1] + c[2]) * (1.0 / 3.0))
                .unwrap()
        };
        let mut shared = 0;
        for t in 0..count as u32 {
            let planar = scene.surfaces[1].geometry.planar(t).unwrap();
            let view = View::new(&scene, 1, &planar).unwrap();
            let lines: Vec<[f64; 3]> = view.lines().collect();
            let at = |l: [f64; 3], [x, y]: [f64; 2]| l[0] * x + l[1] * y + l[2];
            for edge in 0..3 {
                let Some(next) = mesh.neighbour(t, edge) else {
                    continue;
                };
                shared += 1;
                assert!(at(lines[edge + 1], centroid(t)) > 0.0);
                assert!(at(lines[edge + 1], centroid(next)) < 0.0, "{t} edge {edge}");
                assert!((0..3).any(|e| mesh.neighbour(next, e) == Some(t)));
            }
        }
        // Inner edges: 2n(n − 1) between cells and n² diagonals, each counted from both sides.
        assert_eq!(shared, 2 * (2 * n * (n - 1) + n * n));
    }
}

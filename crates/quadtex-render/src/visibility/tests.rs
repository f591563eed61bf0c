use super::*;
use crate::math::Vec3;
use crate::scene::{Camera, Lighting, Sky, Surface, UvTransform};
use quadtex_core::{Rgba, Wrap};
use std::sync::Arc;

/// Every cell of the grid against the ray cast, and how many cells the
/// raster left to rays.
fn check(scene: &Scene, pad: usize) -> (usize, usize) {
    let rays = Caster::new(scene);
    let views = SurfaceViews::new(scene);
    let (w, h) = (
        scene.camera.width() as usize,
        scene.camera.height() as usize,
    );
    let (gw, gh) = (w + 2 * pad, h + 2 * pad);
    let raster = Raster::new(scene, &views, (gw, gh), pad as f64, true).expect("no spheres");
    let cast = |gx: usize, gy: usize| {
        let ray = (scene.camera).ray(gx as f64 - pad as f64 + 0.5, gy as f64 - pad as f64 + 0.5);
        rays.nearest_index(&ray)
            .map_or(0, |(i, hit)| seen_id(i, hit.triangle))
    };
    let casts = std::cell::Cell::new(0);
    let counted = |gx: usize, gy: usize| {
        casts.set(casts.get() + 1);
        cast(gx, gy)
    };
    let mut grid = vec![0; gw * gh];
    for (band, cells) in grid.chunks_mut(gw * BAND).enumerate() {
        raster.band(band, cells, gw, &counted);
    }
    for (i, &id) in grid.iter().enumerate() {
        let (gx, gy) = (i % gw, i / gw);
        assert_eq!(id, cast(gx, gy), "cell ({gx}, {gy})");
    }
    let casts = casts.get();
    assert_eq!(
        visibility_grid(scene, &rays, &views, (gw, gh), pad as f64, true).0[..gw],
        (0..gw).map(|gx| cast(gx, 0)).collect::<Vec<_>>()[..]
    );
    (casts, gw * gh)
}

fn surface(geometry: Geometry) -> Surface {
    Surface {
        geometry,
        texture: None,
        colour: Rgba::opaque(1.0, 1.0, 1.0),
        uv_transform: UvTransform::default(),
        wrap: Wrap::CLAMP,
    }
}

fn quad(origin: Vec3, edge_u: Vec3, edge_v: Vec3) -> Surface {
    surface(Geometry::Quad {
        origin,
        edge_u,
        edge_v,
    })
}

#[test]
fn the_demo_grid_is_the_ray_cast() {
    let demo = crate::demo_scene().unwrap();
    let scene = Scene {
        camera: demo.camera.with_size(320, 180),
        ..demo
    };
    let (casts, cells) = check(&scene, 3);
    assert!(casts * 100 < cells, "{casts} of {cells} cells cast");
}

/// Random quads over a ground plane, some lying on it (decals), some
/// sharing an edge, seen from random cameras: the raster must agree
/// with the ray cast at every centre, and settle most of them itself.
#[test]
fn random_quads_match_the_ray_cast() {
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut rnd = |lo: f64, hi: f64| crate::math::test_uniform(&mut state, lo, hi);
    let (mut casts, mut cells) = (0, 0);
    for _ in 0..12 {
        let mut surfaces = vec![surface(Geometry::Plane {
            point: Vec3::new(0.0, 0.0, 0.0),
            normal: Vec3::new(0.0, 1.0, 0.0),
            u_axis: Vec3::new(1.0, 0.0, 0.0),
            v_axis: Vec3::new(0.0, 0.0, -1.0),
        })];
        for _ in 0..3 {
            let o = Vec3::new(rnd(-8.0, 8.0), rnd(0.0, 4.0), rnd(-8.0, 8.0));
            let eu = Vec3::new(rnd(-6.0, 6.0), rnd(-3.0, 3.0), rnd(-6.0, 6.0));
            let ev = Vec3::new(rnd(-6.0, 6.0), rnd(-3.0, 3.0), rnd(-6.0, 6.0));
            surfaces.push(quad(o, eu, ev));
            // Its neighbour across edge `edge_u`, and a decal on the ground.
            surfaces.push(quad(o + eu, ev, eu * -0.7));
            let g = Vec3::new(o.x, 0.0, o.z);
            surfaces.push(quad(
                g,
                Vec3::new(eu.x, 0.0, eu.z),
                Vec3::new(ev.x, 0.0, ev.z),
            ));
        }
        let position = Vec3::new(rnd(-20.0, 20.0), rnd(0.5, 15.0), rnd(-20.0, 20.0));
        let camera = Camera::new(
            position,
            Vec3::new(rnd(-3.0, 3.0), rnd(-1.0, 2.0), rnd(-3.0, 3.0)),
            Vec3::new(0.0, 1.0, 0.0),
            rnd(20.0, 90.0),
            96,
            64,
        )
        .unwrap();
        let scene = Scene {
            camera,
            surfaces,
            sky: Sky::Solid(Rgba::opaque(0.5, 0.5, 0.5)),
            lighting: Lighting::Unlit,
        };
        let (c, n) = check(&scene, 2);
        casts += c;
        cells += n;
    }
    // Decals coplanar with the ground are ties: cast, as they must be.
    assert!(casts * 4 < cells, "{casts} of {cells} cells cast");
}

/// A wavy heightfield mesh (triangles sharing edges, hills hiding
/// valleys) over a quad, and a few loose triangles, some crossing the
/// camera's plane: the raster must agree with the ray cast everywhere.
/// A rolling `n × n` grid of triangles (two a square): point `(i, j)`
/// at `(i − n/2, height(i, j), −j)`, texture coordinates `(i/n, j/n)`.
fn rolling_grid(n: usize, height: impl Fn(usize, usize) -> f64) -> Vec<crate::scene::Triangle> {
    let point =
        |i: usize, j: usize| Vec3::new(i as f64 - (n / 2) as f64, height(i, j), -(j as f64));
    let uv = |i: usize, j: usize| [i as f64 / n as f64, j as f64 / n as f64];
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let c = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)];
            for [a, b, d] in [[c[0], c[1], c[2]], [c[0], c[2], c[3]]] {
                triangles.extend(crate::scene::Triangle::new(
                    [point(a.0, a.1), point(b.0, b.1), point(d.0, d.1)],
                    [uv(a.0, a.1), uv(b.0, b.1), uv(d.0, d.1)],
                ));
            }
        }
    }
    triangles
}

/// Cameras at `positions` looking at `target`, the `k`-th with a field
/// of view of `50 + 10·k` degrees, `size` pixels.
/// The rolling grid the mesh tests share: 24 × 24 cells of hills a
/// few units high, with a little terracing.
fn rolling_hills() -> Vec<crate::scene::Triangle> {
    rolling_grid(24, |i, j| {
        let (x, z) = (i as f64, j as f64);
        1.5 * (0.7 * x).sin() * (0.5 * z).cos() + 0.1 * ((i * 7 + j * 3) % 5) as f64
    })
}

fn cameras(positions: [Vec3; 3], target: Vec3, (w, h): (u32, u32)) -> Vec<Camera> {
    (positions.into_iter().enumerate())
        .map(|(k, position)| {
            Camera::new(
                position,
                target,
                Vec3::new(0.0, 1.0, 0.0),
                50.0 + 10.0 * k as f64,
                w,
                h,
            )
            .unwrap()
        })
        .collect()
}

#[test]
fn meshes_match_the_ray_cast() {
    use crate::scene::{Mesh, Triangle};
    let mut triangles = rolling_hills();
    // Loose triangles, one reaching behind the camera.
    let loose = [
        [
            Vec3::new(-3.0, 2.0, -5.0),
            Vec3::new(2.0, 4.0, -6.0),
            Vec3::new(0.0, 1.0, -3.0),
        ],
        [
            Vec3::new(-2.0, 2.5, 20.0),
            Vec3::new(2.0, 2.5, 20.0),
            Vec3::new(0.0, 2.0, -8.0),
        ],
    ];
    for p in loose {
        triangles.extend(Triangle::new(p, [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]));
    }
    let mesh = Mesh::new(triangles).unwrap();
    let (mut casts, mut cells) = (0, 0);
    for camera in cameras(
        [
            Vec3::new(0.0, 6.0, 8.0),
            Vec3::new(-14.0, 2.5, 2.0),
            Vec3::new(3.0, 1.2, -4.0),
        ],
        Vec3::new(0.0, 0.0, -12.0),
        (120, 70),
    ) {
        let scene = Scene {
            camera,
            surfaces: vec![
                surface(Geometry::Mesh(Arc::new(mesh.clone()))),
                quad(
                    Vec3::new(-12.0, -0.5, 0.0),
                    Vec3::new(24.0, 0.0, 0.0),
                    Vec3::new(0.0, 0.0, -24.0),
                ),
            ],
            sky: Sky::Solid(Rgba::opaque(0.5, 0.5, 0.5)),
            lighting: Lighting::Unlit,
        };
        let (c, n) = check(&scene, 3);
        casts += c;
        cells += n;
    }
    assert!(casts * 20 < cells, "{casts} of {cells} cells cast");
}

/// What [`Raster::may_show`] rules out shows nowhere on the grid: no
/// point of such a triangle (corners, and a lattice over it) in front
/// of the camera projects within a pixel of the padded grid, and the
/// grids come out as the ray cast's with it ([`check`]).
#[test]
fn culled_triangles_show_nowhere_on_the_grid() {
    use crate::scene::Mesh;
    let mesh = Mesh::new(rolling_hills()).unwrap();
    let (mut culled, mut total) = (0, 0);
    for camera in cameras(
        [
            Vec3::new(0.0, 6.0, 8.0),
            Vec3::new(-14.0, 2.5, 2.0),
            Vec3::new(3.0, 1.2, -14.0),
        ],
        Vec3::new(0.0, 0.0, -12.0),
        (160, 96),
    ) {
        let scene = Scene {
            camera,
            surfaces: vec![surface(Geometry::Mesh(Arc::new(mesh.clone())))],
            sky: Sky::Solid(Rgba::opaque(0.5, 0.5, 0.5)),
            lighting: Lighting::Unlit,
        };
        check(&scene, 3);
        let views = SurfaceViews::new(&scene);
        let pad = 3.0;
        let (gw, gh) = (166, 102);
        let raster = Raster::new(&scene, &views, (gw, gh), pad, true).unwrap();
        let kept: Vec<usize> = mesh
            .triangles_in(raster.may_show())
            .into_iter()
            .flatten()
            .collect();
        let cam = &scene.camera;
        for t in 0..mesh.len() {
            total += 1;
            if kept.binary_search(&t).is_ok() {
                continue;
            }
            culled += 1;
            let [a, b, c] = mesh.corners(t).unwrap();
            for i in 0..=8 {
                for j in 0..=8 - i {
                    let (u, v) = (f64::from(i) / 8.0, f64::from(j) / 8.0);
                    let p = a + (b - a) * u + (c - a) * v;
                    if let Some([x, y]) = cam.project(p) {
                        let inside = x > -pad - 1.0
                            && x < gw as f64 - pad + 1.0
                            && y > -pad - 1.0
                            && y < gh as f64 - pad + 1.0;
                        assert!(!inside, "triangle {t} ruled out shows at ({x}, {y})");
                    }
                }
            }
        }
    }
    // The third camera stands among the hills: what lies behind it and
    // to the sides goes (482 of 3456 triangles over the three).
    assert!(culled * 10 > total, "only {culled} of {total} ruled out");
}

/// The gap search ([`SurfaceViews::meshes_in_gap`], from the screen
/// bins) and the hierarchies' ([`SurfaceViews::meshes_in`]) visit every
/// triangle whose region of a polygon has area, against a brute-force
/// scan of the mesh; the bins in the order the hierarchy visits them.
/// The polygons include clipped pixels with two vertices a rounding
/// apart (edges of 10⁻¹³ to 10⁻¹¹ pixel), whose plane through the camera,
/// before edges that short were left out of the frustum, cut off
/// triangles the polygon holds.
#[test]
fn gap_searches_find_every_triangle_that_reaches_in() {
    use crate::scene::Mesh;
    use quadtex_core::ConvexPolygon;
    let triangles = rolling_hills();
    let mesh = Arc::new(Mesh::new(triangles).unwrap());
    let mut seed = 5u64;
    let mut next = || crate::math::unit_random(&mut seed);
    let (mut reached, mut bin_searches) = (0, 0);
    let positions = cameras(
        [
            Vec3::new(0.0, 6.0, 8.0),
            Vec3::new(-14.0, 2.5, 2.0),
            Vec3::new(0.0, 3.0, 40.0),
        ],
        Vec3::new(0.0, 0.0, -12.0),
        (120, 70),
    );
    for camera in positions {
        let scene = Scene {
            camera,
            surfaces: vec![surface(Geometry::Mesh(mesh.clone()))],
            sky: Sky::Solid(Rgba::opaque(0.5, 0.5, 0.5)),
            lighting: Lighting::Unlit,
        };
        let pad = 3;
        let rays = Caster::new(&scene);
        let mut views = SurfaceViews::new(&scene);
        let (_, reach, bins) = visibility_grid(
            &scene,
            &rays,
            &views,
            (120 + 2 * pad, 70 + 2 * pad),
            pad as f64,
            true,
        );
        views.set_mesh_reach(reach);
        views.set_screen_bins(bins);
        let all: Vec<View> = (0..mesh.len() as u32)
            .filter_map(|t| View::new(&scene, 0, &scene.surfaces[0].geometry.planar(t)?))
            .collect();
        let (mut planes, mut found) = (Vec::new(), Vec::new());
        for k in 0..400 {
            let (x, y) = ((next() * 119.0).floor(), (next() * 69.0).floor());
            let pixel = ConvexPolygon::rect(x, y, x + 1.0, y + 1.0);
            // A line through the pixel, or one that cuts a hair off a
            // corner (two vertices that close).
            let polygon = if k % 2 == 0 {
                let angle = next() * std::f64::consts::TAU;
                let (a, b) = (angle.cos(), angle.sin());
                let (px, py) = (x + next(), y + next());
                pixel.clip(a, b, -(a * px + b * py))
            } else {
                let (a, b) = (1.0, 0.3 + next());
                let hair = [1e-11, 1e-12, 1e-13][k / 2 % 3];
                pixel.clip(-a, b, a * (x + 1.0) - b * y - hair)
            };
            if polygon.is_empty() {
                continue;
            }
            let expected: Vec<u32> = (all.iter())
                .filter(|v| v.region(&polygon).area() > 1e-9)
                .map(|v| v.triangle().unwrap())
                .collect();
            reached += expected.len();
            let mut through_bins = Vec::new();
            let binned = views.meshes_in_gap(&scene, &polygon, &mut planes, &mut found, |id| {
                through_bins.push(id);
                false
            });
            assert!(!binned);
            bin_searches += usize::from(!found.is_empty());
            let mut through_hierarchy = Vec::new();
            views.meshes_in(&scene, &polygon, &mut planes, |id| {
                through_hierarchy.push(id);
                false
            });
            for t in &expected {
                let id = crate::caster::seen_id(0, *t);
                assert!(through_bins.contains(&id), "bins miss {t} in {polygon:?}");
                assert!(
                    through_hierarchy.contains(&id),
                    "hierarchy misses {t} in {polygon:?}"
                );
            }
            // What both visit, they visit in the same order.
            let common: Vec<_> = (through_bins.iter())
                .filter(|id| through_hierarchy.contains(id))
                .collect();
            let in_order: Vec<_> = (through_hierarchy.iter())
                .filter(|id| through_bins.contains(id))
                .collect();
            assert_eq!(common, in_order);
        }
    }
    assert!(
        reached > 400 && bin_searches > 200,
        "{reached} {bin_searches}"
    );
}

/// The screen bins answer a camera ray through any point of the grid
/// as the ray cast does: the same surface, the same distance, the same
/// triangle but where two tie (a ray through a shared edge). Points at
/// random, and at the projected corners of the triangles and a hair
/// beside them, over a rolling grid with a triangle reaching behind the
/// camera and a quad below; one camera far off, where the triangles
/// are smaller than a pixel.
#[test]
fn screen_bins_answer_as_the_ray_cast() {
    use crate::scene::{Mesh, Triangle};
    let mut triangles = rolling_hills();
    triangles.extend(Triangle::new(
        [
            Vec3::new(-2.0, 2.5, 20.0),
            Vec3::new(2.0, 2.5, 20.0),
            Vec3::new(0.0, 2.0, -8.0),
        ],
        [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
    ));
    let mesh = Arc::new(Mesh::new(triangles).unwrap());
    let mut seed = 11u64;
    let mut next = || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut hits, mut points) = (0, 0);
    let mut positions = cameras(
        [
            Vec3::new(0.0, 6.0, 8.0),
            Vec3::new(-14.0, 2.5, 2.0),
            Vec3::new(3.0, 1.2, -4.0),
        ],
        Vec3::new(0.0, 0.0, -12.0),
        (120, 70),
    );
    positions.extend(Camera::new(
        Vec3::new(0.0, 4.0, 160.0),
        Vec3::new(0.0, 0.0, -12.0),
        Vec3::new(0.0, 1.0, 0.0),
        30.0,
        120,
        70,
    ));
    for camera in positions {
        let scene = Scene {
            camera,
            surfaces: vec![
                quad(
                    Vec3::new(-12.0, -0.5, 0.0),
                    Vec3::new(24.0, 0.0, 0.0),
                    Vec3::new(0.0, 0.0, -24.0),
                ),
                surface(Geometry::Mesh(mesh.clone())),
            ],
            sky: Sky::Solid(Rgba::opaque(0.5, 0.5, 0.5)),
            lighting: Lighting::Unlit,
        };
        let pad = 3;
        let rays = Caster::new(&scene);
        let views = SurfaceViews::new(&scene);
        let (gw, gh) = (120 + 2 * pad, 70 + 2 * pad);
        let raster = Raster::new(&scene, &views, (gw, gh), pad as f64, true).unwrap();
        let boxes = raster.screen_boxes.as_ref().expect("every box is known");
        let bins = ScreenBins::build(boxes, -(pad as f64), [gw, gh]);
        let bins = bins.as_ref().expect("the bins are built");
        let mut at = Vec::new();
        for _ in 0..3000 {
            at.push([next() * 120.0, next() * 70.0]);
        }
        for t in 0..mesh.len() {
            for p in mesh.corners(t).unwrap() {
                if let Some(s) = scene.camera.project(p) {
                    for d in [0.0, 1e-7, -1e-7, 1e-3] {
                        at.push([s[0] + d, s[1] - d]);
                    }
                }
            }
        }
        for c in at {
            let ray = scene.camera.ray(c[0], c[1]);
            let Some(binned) = bins.nearest_through(&rays, &ray, c) else {
                assert!(c[0] < -2.0 || c[1] < -2.0 || c[0] > 121.0 || c[1] > 71.0);
                continue;
            };
            points += 1;
            let cast = rays.nearest_index(&ray);
            match (binned, cast) {
                (None, None) => {}
                (Some((i, a)), Some((j, b))) => {
                    hits += 1;
                    // Ties to rounding: the hierarchy's boxes may
                    // pass over a hit an ulp nearer than its best.
                    let tie = 1e-12 * a.t.max(b.t);
                    assert_eq!(i, j, "at {c:?}");
                    assert!((a.t - b.t).abs() <= tie, "at {c:?}: {} {}", a.t, b.t);
                    if a.triangle != b.triangle {
                        let both = [a.triangle, b.triangle]
                            .map(|t| mesh.crossing_beyond(t, &ray, 1e-9).unwrap_or(0.0));
                        assert!((both[0] - both[1]).abs() <= tie, "at {c:?}: not a tie");
                    }
                }
                (a, b) => panic!("at {c:?}: bins {a:?}, cast {b:?}"),
            }
        }
    }
    assert!(hits * 2 > points, "{hits} hits of {points} points");
}

/// Spheres in front of quads and a plane, one reaching behind the
/// camera: cells of their boxes are cast, the rest rasterised.
/// The search of the meshes finds every triangle whose screen region
/// reaches into a polygon, and where [`MeshReach`] rules a pixel's
/// support out, no triangle's screen region reaches into it (every triangle clipped, box and
/// Mitchell supports, three cameras over a rolling grid with sky
/// above, one of them over the grid, and a long triangle reaching
/// behind every camera's plane); it rules out most of the sky.
#[test]
fn mesh_searches_miss_no_triangle_that_reaches() {
    use crate::scene::{Mesh, Triangle};
    use quadtex_core::PixelFilter;
    let triangles = rolling_grid(16, |i, j| {
        let (x, z) = (i as f64, j as f64);
        1.2 * (0.7 * x).sin() * (0.5 * z).cos()
    });
    let behind = Triangle::new(
        [
            Vec3::new(-2.0, 2.5, 20.0),
            Vec3::new(2.0, 2.5, 20.0),
            Vec3::new(0.0, 2.0, -8.0),
        ],
        [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
    )
    .unwrap();
    let (mut ruled_out, mut sky, mut searched) = (0, 0, 0);
    for (k, camera) in cameras(
        [
            Vec3::new(0.0, 4.0, 6.0),
            Vec3::new(-11.0, 2.5, 2.0),
            Vec3::new(3.0, 1.8, -3.0),
        ],
        Vec3::new(0.0, 0.5, -10.0),
        (96, 60),
    )
    .into_iter()
    .enumerate()
    {
        let scene_of = |triangles: Vec<Triangle>| Scene {
            camera: camera.clone(),
            surfaces: vec![surface(Geometry::Mesh(Arc::new(
                Mesh::new(triangles).unwrap(),
            )))],
            sky: Sky::Solid(Rgba::opaque(0.5, 0.5, 0.5)),
            lighting: Lighting::Unlit,
        };
        let scene = scene_of(triangles.iter().chain([&behind]).cloned().collect());
        let (rays, views) = (Caster::new(&scene), SurfaceViews::new(&scene));
        let pad = 3;
        let (gw, gh) = (96 + 2 * pad, 60 + 2 * pad);
        let (seen, reach, _) = visibility_grid(&scene, &rays, &views, (gw, gh), pad as f64, true);
        let geometry = &scene.surfaces[0].geometry;
        let regions: Vec<View> = (0..=triangles.len() as u32)
            .filter_map(|t| View::new(&scene, 0, &geometry.planar(t)?))
            .collect();
        // The search of the hierarchy (frustum planes, boxes' screen
        // boxes) finds every triangle whose region reaches into a
        // support or a quarter of one.
        let mut views = views;
        views.set_mesh_reach(reach.clone());
        let mut planes = Vec::new();
        for y in (0..60).step_by(2) {
            for x in (0..96).step_by(2) {
                let (x0, y0) = (x as f64, y as f64);
                for polygon in [
                    ConvexPolygon::rect(x0, y0, x0 + 1.0, y0 + 1.0),
                    ConvexPolygon::rect(x0 + 0.5, y0, x0 + 1.0, y0 + 0.5),
                ] {
                    let mut found = Vec::new();
                    views.meshes_in(&scene, &polygon, &mut planes, |id| {
                        found.push(id);
                        false
                    });
                    for (t, view) in regions.iter().enumerate() {
                        if view.region(&polygon).area() > 0.0 {
                            searched += 1;
                            assert!(
                                found.contains(&seen_id(0, t as u32)),
                                "camera {k}, triangle {t} in {polygon:?}"
                            );
                        }
                    }
                }
            }
        }
        for y in 0..60 {
            for x in 0..96 {
                sky += usize::from(seen[(y + pad) * gw + x + pad] == 0);
                let centre = [x as f64 + 0.5, y as f64 + 0.5];
                for filter in [PixelFilter::Box, PixelFilter::Mitchell] {
                    let support = filter.support(centre);
                    let (lo, hi) = support.bounds();
                    if reach.may_reach(lo, hi) {
                        continue;
                    }
                    ruled_out += usize::from(filter == PixelFilter::Box);
                    for view in &regions {
                        assert!(
                            view.region(&support).is_empty(),
                            "camera {k}, pixel ({x}, {y}), {filter:?}"
                        );
                    }
                }
            }
        }
    }
    assert!(searched > 1000, "{searched} triangles found");
    assert!(
        ruled_out * 2 > sky && sky > 0,
        "{ruled_out} pixels ruled out of {sky} sky pixels"
    );
}

#[test]
fn spheres_are_cast_in_their_boxes() {
    let demo = crate::demo_scene().unwrap();
    let mut scene = Scene {
        camera: demo.camera.with_size(240, 135),
        ..demo
    };
    for (c, r, everywhere) in [
        (Vec3::new(0.0, 5.0, -50.0), 5.0, false),
        (Vec3::new(-30.0, 2.0, -400.0), 30.0, false),
        // Around the camera: its box is the whole grid.
        (Vec3::new(8.0, 14.0, 118.0), 4.0, true),
    ] {
        scene.surfaces.push(surface(Geometry::Sphere {
            centre: c,
            radius: r,
        }));
        let (casts, cells) = check(&scene, 3);
        if everywhere {
            assert_eq!(casts, cells);
        } else {
            assert!(
                casts > 0 && casts * 4 < cells,
                "{casts} of {cells} cells cast"
            );
        }
    }
}

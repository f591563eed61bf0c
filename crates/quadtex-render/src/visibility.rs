//! The visibility grid: which primitive the camera's ray through each
//! pixel centre meets first ([`crate::exact::Seen`], `0` for the sky), on a
//! grid padded by `pad` pixels around the image (grid cell `(gx, gy)` is the
//! centre `(gx − pad + ½, gy − pad + ½)`).
//!
//! **Rasterised where that is the same answer.** When every surface is a
//! plane or a quad, each one's screen region is a few half-planes and its
//! ray parameter `depth / w(s)` with `w` affine in the screen point
//! ([`crate::exact::View`]), so the grid is a z-buffer: per row, each
//! primitive's span of centres is found from its lines, and each centre in
//! it keeps the nearest primitive. That is what casting the ray finds,
//! except where rounding could make the two disagree; those centres are
//! cast as rays instead: a centre within [`EDGE_MARGIN`] pixel of an edge
//! line (or within a relative `10⁻¹²` of the line's range over the
//! screen), two primitives within a relative [`DEPTH_TIE`] in depth, a ray
//! parameter under `10⁻⁶` or a surface nearly parallel to the ray. Scenes
//! with spheres or meshes are cast ray by ray.

use rayon::prelude::*;

use crate::exact::{Seen, SurfaceViews, seen_id};
use crate::scene::{Caster, Geometry, Scene};

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

/// Which primitive each centre of the padded grid sees, `gw × gh` cells,
/// row by row.
pub(crate) fn visibility_grid(
    scene: &Scene,
    rays: &Caster<'_>,
    views: &SurfaceViews,
    (gw, gh): (usize, usize),
    pad: f64,
) -> Vec<Seen> {
    let cast = |gx: usize, gy: usize| {
        let ray = (scene.camera).ray(gx as f64 - pad + 0.5, gy as f64 - pad + 0.5);
        rays.nearest_index(&ray)
            .map_or(0, |(i, hit)| seen_id(i, hit.triangle))
    };
    let raster = Raster::new(scene, views, (gw, gh), pad);
    let mut grid = vec![0; gw * gh];
    grid.par_chunks_mut(gw.max(1))
        .enumerate()
        .for_each(|(gy, row)| match &raster {
            Some(r) => r.row(gy, row, |gx| cast(gx, gy)),
            None => {
                for (gx, id) in row.iter_mut().enumerate() {
                    *id = cast(gx, gy);
                }
            }
        });
    grid
}

/// Most lines of a view: `w` and a quad's four edges.
const MAX_LINES: usize = 5;

/// One plane or quad as the z-buffer sees it.
struct Primitive {
    id: Seen,
    /// `w` first, then the edges: `a·x + b·y + c ≥ 0` inside.
    lines: [[f64; 3]; MAX_LINES],
    /// Per line, the value within which a centre counts as on it.
    margins: [f64; MAX_LINES],
    count: usize,
    /// `t = depth / w(s)` (unnormalised ray).
    depth: f64,
}

/// The z-buffer over a scene of planes and quads.
struct Raster {
    primitives: Vec<Primitive>,
    pad: f64,
    /// Below this `w(s)` the surface is too near parallel to the ray to be
    /// decided without it (the ray cast rejects `|n·d̂| < 10⁻¹²`).
    min_w: f64,
}

impl Raster {
    /// `None` unless every surface is a plane or quad with a view.
    fn new(
        scene: &Scene,
        views: &SurfaceViews,
        (gw, gh): (usize, usize),
        pad: f64,
    ) -> Option<Raster> {
        let planar = views.planar_views();
        let mut primitives = Vec::with_capacity(scene.surfaces.len());
        // Screen extent of the grid, for the lines' relative margins.
        let (x_max, y_max) = (gw as f64 + pad, gh as f64 + pad);
        for (i, s) in scene.surfaces.iter().enumerate() {
            if !matches!(s.geometry, Geometry::Plane { .. } | Geometry::Quad { .. }) {
                return None;
            }
            let view = planar.get(i)?.as_ref()?;
            debug_assert_eq!(view.surface(), i);
            let (_, depth) = view.depth_parts();
            let mut p = Primitive {
                id: seen_id(i, 0),
                lines: [[0.0; 3]; MAX_LINES],
                margins: [0.0; MAX_LINES],
                count: 0,
                depth,
            };
            for [a, b, c] in view.lines() {
                if p.count == MAX_LINES || ![a, b, c].iter().all(|v| v.is_finite()) {
                    return None;
                }
                p.lines[p.count] = [a, b, c];
                p.margins[p.count] = EDGE_MARGIN * a.hypot(b)
                    + 1e-12 * (a.abs() * x_max + b.abs() * y_max + c.abs());
                p.count += 1;
            }
            if !depth.is_finite() || p.count == 0 {
                return None;
            }
            primitives.push(p);
        }
        // |d| is convex in the screen point: largest at a corner.
        let cam = &scene.camera;
        let d_max = [(-pad, -pad), (x_max, -pad), (-pad, y_max), (x_max, y_max)]
            .iter()
            .map(|&(x, y)| cam.direction(x, y).length())
            .fold(0.0, f64::max);
        Some(Raster {
            primitives,
            pad,
            min_w: 1e-9 * d_max,
        })
    }

    /// Fills grid row `gy`; `cast(gx)` is the ray cast for a centre the
    /// lines and depths do not settle.
    fn row(&self, gy: usize, row: &mut [Seen], cast: impl Fn(usize) -> Seen) {
        let y = gy as f64 - self.pad + 0.5;
        let n = row.len();
        let mut best = vec![f64::INFINITY; n];
        let mut unsure = vec![false; n];
        row.fill(0);
        for p in &self.primitives {
            let (lines, margins) = (&p.lines[..p.count], &p.margins[..p.count]);
            // Each line along the row: a·x + e ≥ 0, e = b·y + c.
            let mut slope = [0f64; MAX_LINES];
            let mut offset = [0f64; MAX_LINES];
            let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
            for (k, (&[a, b, c], &m)) in lines.iter().zip(margins).enumerate() {
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
            if lo > hi || n == 0 {
                continue;
            }
            // Centres x = gx − pad + ½, with a cell of slack each side.
            let to_cell = |x: f64| (x + self.pad - 0.5).clamp(-2.0, n as f64 + 1.0);
            let first = (to_cell(lo).floor() - 1.0).max(0.0) as usize;
            let last = ((to_cell(hi).ceil() + 1.0).max(0.0) as usize).min(n - 1);
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
                if on_edge || w < self.min_w {
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
                    row[gx] = p.id;
                }
            }
        }
        for (gx, id) in row.iter_mut().enumerate() {
            if unsure[gx] {
                *id = cast(gx);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use crate::scene::{Camera, Lighting, Sky, Surface, UvTransform};
    use quadtex_core::{Rgba, Wrap};

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
        let raster = Raster::new(scene, &views, (gw, gh), pad as f64).expect("planes and quads");
        let cast = |gx: usize, gy: usize| {
            let ray =
                (scene.camera).ray(gx as f64 - pad as f64 + 0.5, gy as f64 - pad as f64 + 0.5);
            rays.nearest_index(&ray)
                .map_or(0, |(i, hit)| seen_id(i, hit.triangle))
        };
        let mut casts = 0;
        let mut row = vec![0; gw];
        for gy in 0..gh {
            let counted = std::cell::Cell::new(0);
            raster.row(gy, &mut row, |gx| {
                counted.set(counted.get() + 1);
                cast(gx, gy)
            });
            casts += counted.get();
            for (gx, &id) in row.iter().enumerate() {
                assert_eq!(id, cast(gx, gy), "cell ({gx}, {gy})");
            }
        }
        assert_eq!(
            visibility_grid(scene, &rays, &views, (gw, gh), pad as f64)[..gw],
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
        let mut rnd = |lo: f64, hi: f64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            lo + (hi - lo) * ((state >> 11) as f64 / (1u64 << 53) as f64)
        };
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

    #[test]
    fn scenes_with_spheres_are_cast() {
        let mut scene = crate::demo_scene().unwrap();
        scene.surfaces.push(surface(Geometry::Sphere {
            centre: Vec3::new(0.0, 2.0, -50.0),
            radius: 2.0,
        }));
        let views = SurfaceViews::new(&scene);
        assert!(Raster::new(&scene, &views, (10, 10), 0.0).is_none());
    }
}

//! The renderer's rays, dumped for a peer ray caster and timed on
//! quadtex's own ([`ray_dump`], [`time_rays`]; `quadtex rays`,
//! `bench/peers/embree`).
//!
//! **The rays.** Primary: the camera's ray through every pixel centre
//! (`Camera::ray(x + ½, y + ½)`, row by row), closest hit beyond
//! `t = 10⁻⁹`, as the renderer casts them ([`Caster::nearest_index`]).
//! Shadow: for every primary hit whose surface faces the sun, the ray
//! [`crate::frame::lambert`] casts ([`sun_ray`]: from the hit lifted along
//! the normal by `10⁻⁶ (1 + distance)`, towards the sun), any hit beyond
//! `t = 10⁻⁹`, in pixel order. Both in `f64`, as the renderer makes them.
//!
//! **Dump format** (`rays.bin`, little-endian, written by
//! [`write_ray_dump`], read back by [`read_ray_dump`] and by
//! `bench/peers/embree/embree_rays.cpp`):
//!
//! ```text
//! magic        8 bytes  "QTXRAYS1"
//! width        u32      pixels
//! height       u32
//! surfaces     u32      count, then per surface:
//!   kind       u32      0 mesh (ids are the mesh's triangle indices),
//!                       1 quad (two triangles: origin, +u, +u+v; origin, +u+v, +v)
//!   triangles  u32      count, then per triangle 9 × f32: corners x y z
//!                       (a mesh's corners are the f32 of its glTF/OBJ file,
//!                       exact; a quad's corners rounded to f32)
//! primary      u32      count (width × height), then per ray 8 × f64:
//!                       origin x y z, direction x y z (unit), t_min, t_max
//! shadow       u32      count, then per ray 8 × f64 as above, then
//!                       u32 pixel (y × width + x), u32 surface and
//!                       u32 triangle it leaves
//! ```
//!
//! `t_max` is `+∞`; a ray meets what lies at `t_min < t < t_max`.
//!
//! **Results format** (`quadtex-hits.bin`, [`write_ray_results`]):
//!
//! ```text
//! magic        8 bytes  "QTXHITS1"
//! primary      u32      count, then per ray: u32 surface (0xFFFFFFFF: miss),
//!                       u32 triangle (mesh: its index; quad: 0), f64 t
//! shadow       u32      count, then per ray u8: bit 0 occluded (hierarchy
//!                       any-hit), bit 1 occluded (the renderer's path)
//! ```

use std::io::{Read, Write};
use std::path::Path;
use std::time::Instant;

use crate::caster::Caster;
use crate::frame::sun_ray;
use crate::math::{Ray, Vec3};
use crate::render::sized_scene;
use crate::scene::{Geometry, Lighting, Scene};

const DUMP_MAGIC: &[u8; 8] = b"QTXRAYS1";
const RESULTS_MAGIC: &[u8; 8] = b"QTXHITS1";

/// `surface` of a primary ray that meets nothing.
pub const MISS: u32 = u32::MAX;

/// How near a ray's hit may lie ([`Caster`]'s own limit for every test).
const T_MIN: f64 = 1e-9;

/// A ray with the range of `t` it searches (`t_min < t < t_max`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DumpRay {
    /// Where it starts.
    pub origin: [f64; 3],
    /// Its unit direction.
    pub direction: [f64; 3],
    /// Hits at or before this do not count.
    pub t_min: f64,
    /// Hits at or beyond this do not count (`+∞`).
    pub t_max: f64,
}

impl DumpRay {
    fn of(ray: &Ray) -> DumpRay {
        let v = |p: Vec3| [p.x, p.y, p.z];
        DumpRay {
            origin: v(ray.origin),
            direction: v(ray.direction),
            t_min: T_MIN,
            t_max: f64::INFINITY,
        }
    }

    fn ray(&self) -> Ray {
        let v = |p: [f64; 3]| Vec3::new(p[0], p[1], p[2]);
        Ray {
            origin: v(self.origin),
            direction: v(self.direction),
        }
    }
}

/// A shadow ray and where it comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadowRay {
    /// The ray, towards the sun.
    pub ray: DumpRay,
    /// The pixel whose primary hit it leaves (`y × width + x`).
    pub pixel: u32,
    /// The surface it leaves.
    pub surface: u32,
    /// The surface's triangle it leaves (0 unless a mesh).
    pub triangle: u32,
}

/// What a dumped surface is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DumpKind {
    /// A triangle mesh: triangle ids are the mesh's.
    Mesh = 0,
    /// A parallelogram, as two triangles.
    Quad = 1,
}

/// A surface as triangles (corners, `f32`).
#[derive(Debug, Clone, PartialEq)]
pub struct DumpSurface {
    /// Mesh or quad.
    pub kind: DumpKind,
    /// Each triangle's three corners.
    pub triangles: Vec<[[f32; 3]; 3]>,
}

/// A scene's triangles and its frame's primary and shadow rays.
#[derive(Debug, Clone, PartialEq)]
pub struct RayDump {
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
    /// The scene's surfaces, in its order.
    pub surfaces: Vec<DumpSurface>,
    /// One ray per pixel centre, row by row.
    pub primary: Vec<DumpRay>,
    /// The sun's shadow rays, in pixel order.
    pub shadow: Vec<ShadowRay>,
}

/// One primary ray's closest hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrimaryHit {
    /// The surface met ([`MISS`]: none).
    pub surface: u32,
    /// Its triangle (0 unless a mesh).
    pub triangle: u32,
    /// Where along the ray (`+∞` on a miss).
    pub t: f64,
}

/// quadtex's answers for a [`RayDump`]'s rays.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RayResults {
    /// Per primary ray.
    pub primary: Vec<PrimaryHit>,
    /// Per shadow ray: whether the hierarchy finds it occluded.
    pub shadow_bvh: Vec<bool>,
    /// Per shadow ray: whether the renderer's own path
    /// ([`Caster::occluded_leaving`] with the sun's grids) does.
    pub shadow_renderer: Vec<bool>,
}

/// The scene's triangles and the rays of its frame at `width × height`
/// (see the module's documentation). Errors when the scene has a plane or
/// a sphere (no triangles to give a peer) or is unlit (no shadow rays).
pub fn ray_dump(scene: &Scene, width: u32, height: u32) -> Result<RayDump, crate::Error> {
    let scene = sized_scene(scene, width, height)?;
    let surfaces = dump_surfaces(&scene)?;
    let Lighting::Lambert { direction, .. } = scene.lighting else {
        return Err(crate::Error::Option(
            "rays: the scene is unlit (no sun, so no shadow rays)".into(),
        ));
    };
    let caster = Caster::new(&scene);
    let mut primary = Vec::with_capacity(width as usize * height as usize);
    let mut shadow = Vec::new();
    for y in 0..height {
        for x in 0..width {
            let ray = scene.camera.ray(f64::from(x) + 0.5, f64::from(y) + 0.5);
            primary.push(DumpRay::of(&ray));
            if let Some((index, hit)) = caster.nearest_index(&ray)
                && let (_, Some(s)) = sun_ray(direction, hit.normal, hit.point, &ray)
            {
                shadow.push(ShadowRay {
                    ray: DumpRay::of(&s),
                    pixel: y * width + x,
                    surface: index as u32,
                    triangle: hit.triangle,
                });
            }
        }
    }
    Ok(RayDump {
        width,
        height,
        surfaces,
        primary,
        shadow,
    })
}

fn dump_surfaces(scene: &Scene) -> Result<Vec<DumpSurface>, crate::Error> {
    let f = |p: Vec3| [p.x as f32, p.y as f32, p.z as f32];
    (scene.surfaces.iter().enumerate())
        .map(|(i, s)| match &s.geometry {
            Geometry::Mesh(mesh) => Ok(DumpSurface {
                kind: DumpKind::Mesh,
                triangles: (0..mesh.len())
                    .filter_map(|t| mesh.corners(t))
                    .map(|c| c.map(f))
                    .collect(),
            }),
            Geometry::Quad {
                origin,
                edge_u,
                edge_v,
            } => {
                let (a, b) = (*origin, *origin + *edge_u);
                let (c, d) = (b + *edge_v, *origin + *edge_v);
                Ok(DumpSurface {
                    kind: DumpKind::Quad,
                    triangles: vec![[f(a), f(b), f(c)], [f(a), f(c), f(d)]],
                })
            }
            _ => Err(crate::Error::Option(format!(
                "rays: surface {i} is a plane or a sphere, which a peer gets no triangles for"
            ))),
        })
        .collect()
}

/// quadtex's ray casts timed on one thread: per method the median
/// nanoseconds per ray over the passes, and the build times.
#[derive(Debug, Clone)]
pub struct RayTiming {
    /// `(method, median ns per ray, rays)`.
    pub methods: Vec<(String, f64, usize)>,
    /// `(what, seconds)`: each mesh's hierarchy and sun grid built on
    /// one thread.
    pub builds: Vec<(String, f64)>,
    /// The answers (the last pass's).
    pub results: RayResults,
}

/// Times quadtex's caster on `dump`'s rays of `scene` (which must be the
/// scene the dump was made from, at the same size), on the calling thread,
/// `passes` timed passes after one untimed warm-up (which also fills the
/// sun grids' per-triangle answers, as a first frame does): primary rays
/// by [`Caster::nearest_index`]; shadow rays by
/// [`Caster::occluded_leaving`] twice, without the sun's grids (the
/// hierarchy's any-hit: what a generic caster does) and with them (the
/// renderer's path). Then each mesh's hierarchy and sun grid is built
/// again, timed, on a one-thread pool.
pub fn time_rays(scene: &Scene, dump: &RayDump, passes: u32) -> Result<RayTiming, crate::Error> {
    let scene = sized_scene(scene, dump.width, dump.height)?;
    let bvh_only = Caster::new(&scene);
    let renderer = Caster::new(&scene).with_sun_grids();
    let primary: Vec<Ray> = dump.primary.iter().map(DumpRay::ray).collect();
    let shadow: Vec<(Ray, (usize, u32))> = (dump.shadow.iter())
        .map(|s| (s.ray.ray(), (s.surface as usize, s.triangle)))
        .collect();
    let mut results = RayResults {
        primary: vec![
            PrimaryHit {
                surface: MISS,
                triangle: 0,
                t: f64::INFINITY,
            };
            primary.len()
        ],
        shadow_bvh: vec![false; shadow.len()],
        shadow_renderer: vec![false; shadow.len()],
    };
    let RayResults {
        primary: hits,
        shadow_bvh,
        shadow_renderer,
    } = &mut results;
    let mut methods = Vec::new();
    let ns = median_ns(primary.len(), passes, &mut || {
        for (ray, out) in primary.iter().zip(hits.iter_mut()) {
            *out = match bvh_only.nearest_index(ray) {
                Some((i, hit)) => PrimaryHit {
                    surface: i as u32,
                    triangle: hit.triangle,
                    t: hit.t,
                },
                None => PrimaryHit {
                    surface: MISS,
                    triangle: 0,
                    t: f64::INFINITY,
                },
            };
        }
    });
    methods.push(("quadtex primary closest-hit".to_string(), ns, primary.len()));
    let ns = median_ns(shadow.len(), passes, &mut || {
        for ((ray, from), out) in shadow.iter().zip(shadow_bvh.iter_mut()) {
            *out = bvh_only.occluded_leaving(ray, *from);
        }
    });
    methods.push(("quadtex shadow any-hit BVH".to_string(), ns, shadow.len()));
    let ns = median_ns(shadow.len(), passes, &mut || {
        for ((ray, from), out) in shadow.iter().zip(shadow_renderer.iter_mut()) {
            *out = renderer.occluded_leaving(ray, *from);
        }
    });
    methods.push((
        "quadtex shadow renderer (sun grid)".to_string(),
        ns,
        shadow.len(),
    ));
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| crate::Error::Option(format!("a one-thread pool: {e}")))?;
    let mut builds = Vec::new();
    for surface in &scene.surfaces {
        if let Geometry::Mesh(mesh) = &surface.geometry {
            builds.push((
                "quadtex BVH".to_string(),
                one.install(|| mesh.hierarchy_build_seconds()),
            ));
            if let Lighting::Lambert { direction, .. } = scene.lighting {
                let start = Instant::now();
                let grid = one.install(|| crate::sun_grid::SunGrid::build(mesh, direction));
                let seconds = start.elapsed().as_secs_f64();
                if grid.is_some() {
                    builds.push(("quadtex sun grid".to_string(), seconds));
                }
            }
        }
    }
    Ok(RayTiming {
        methods,
        builds,
        results,
    })
}

/// Median nanoseconds per item of `run` over `count` items: one untimed
/// warm-up call, then `passes` timed ones.
fn median_ns(count: usize, passes: u32, run: &mut dyn FnMut()) -> f64 {
    run();
    let mut times: Vec<f64> = (0..passes.max(1))
        .map(|_| {
            let start = Instant::now();
            run();
            start.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    1e9 * times[times.len() / 2] / count.max(1) as f64
}

fn io_error(path: &Path) -> impl Fn(std::io::Error) -> crate::Error + '_ {
    move |source| crate::Error::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn count(n: usize, what: &str) -> Result<u32, crate::Error> {
    u32::try_from(n).map_err(|_| crate::Error::Option(format!("rays: {n} {what}: too many")))
}

fn put_ray(w: &mut impl Write, r: &DumpRay) -> std::io::Result<()> {
    for v in r
        .origin
        .iter()
        .chain(&r.direction)
        .chain([&r.t_min, &r.t_max])
    {
        w.write_all(&v.to_le_bytes())?;
    }
    Ok(())
}

/// Writes `dump` to `path` in the format of the module's documentation.
pub fn write_ray_dump(path: &Path, dump: &RayDump) -> Result<(), crate::Error> {
    let file = std::fs::File::create(path).map_err(io_error(path))?;
    let mut w = std::io::BufWriter::new(file);
    let surfaces = count(dump.surfaces.len(), "surfaces")?;
    let primary = count(dump.primary.len(), "primary rays")?;
    let shadow = count(dump.shadow.len(), "shadow rays")?;
    let mut write = || -> std::io::Result<()> {
        w.write_all(DUMP_MAGIC)?;
        for v in [dump.width, dump.height, surfaces] {
            w.write_all(&v.to_le_bytes())?;
        }
        for s in &dump.surfaces {
            w.write_all(&(s.kind as u32).to_le_bytes())?;
            w.write_all(&(s.triangles.len() as u32).to_le_bytes())?;
            for v in s.triangles.iter().flatten().flatten() {
                w.write_all(&v.to_le_bytes())?;
            }
        }
        w.write_all(&primary.to_le_bytes())?;
        for r in &dump.primary {
            put_ray(&mut w, r)?;
        }
        w.write_all(&shadow.to_le_bytes())?;
        for s in &dump.shadow {
            put_ray(&mut w, &s.ray)?;
            for v in [s.pixel, s.surface, s.triangle] {
                w.write_all(&v.to_le_bytes())?;
            }
        }
        w.flush()
    };
    write().map_err(io_error(path))
}

/// Reads what `read` holds as little-endian values.
struct Reader<R: Read>(R);

impl<R: Read> Reader<R> {
    fn bytes<const N: usize>(&mut self) -> std::io::Result<[u8; N]> {
        let mut b = [0; N];
        self.0.read_exact(&mut b)?;
        Ok(b)
    }
    fn u32(&mut self) -> std::io::Result<u32> {
        self.bytes().map(u32::from_le_bytes)
    }
    fn f32(&mut self) -> std::io::Result<f32> {
        self.bytes().map(f32::from_le_bytes)
    }
    fn f64(&mut self) -> std::io::Result<f64> {
        self.bytes().map(f64::from_le_bytes)
    }
    fn ray(&mut self) -> std::io::Result<DumpRay> {
        let mut v = [0.0; 8];
        for x in &mut v {
            *x = self.f64()?;
        }
        Ok(DumpRay {
            origin: [v[0], v[1], v[2]],
            direction: [v[3], v[4], v[5]],
            t_min: v[6],
            t_max: v[7],
        })
    }
}

fn bad(path: &Path, what: &str) -> crate::Error {
    crate::Error::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidData, what.to_string()),
    }
}

/// Reads a dump [`write_ray_dump`] wrote.
pub fn read_ray_dump(path: &Path) -> Result<RayDump, crate::Error> {
    let file = std::fs::File::open(path).map_err(io_error(path))?;
    let mut r = Reader(std::io::BufReader::new(file));
    let mut read = || -> std::io::Result<Option<RayDump>> {
        if &r.bytes::<8>()? != DUMP_MAGIC {
            return Ok(None);
        }
        let (width, height, n) = (r.u32()?, r.u32()?, r.u32()?);
        let mut surfaces = Vec::new();
        for _ in 0..n {
            let kind = match r.u32()? {
                0 => DumpKind::Mesh,
                1 => DumpKind::Quad,
                _ => return Ok(None),
            };
            let count = r.u32()?;
            let mut triangles = Vec::new();
            for _ in 0..count {
                let mut t = [[0.0; 3]; 3];
                for v in t.iter_mut().flatten() {
                    *v = r.f32()?;
                }
                triangles.push(t);
            }
            surfaces.push(DumpSurface { kind, triangles });
        }
        let primary = (0..r.u32()?)
            .map(|_| r.ray())
            .collect::<std::io::Result<_>>()?;
        let shadow = (0..r.u32()?)
            .map(|_| {
                Ok(ShadowRay {
                    ray: r.ray()?,
                    pixel: r.u32()?,
                    surface: r.u32()?,
                    triangle: r.u32()?,
                })
            })
            .collect::<std::io::Result<_>>()?;
        Ok(Some(RayDump {
            width,
            height,
            surfaces,
            primary,
            shadow,
        }))
    };
    read()
        .map_err(io_error(path))?
        .ok_or_else(|| bad(path, "not a ray dump (QTXRAYS1)"))
}

/// Writes `results` to `path` in the format of the module's documentation.
pub fn write_ray_results(path: &Path, results: &RayResults) -> Result<(), crate::Error> {
    if results.shadow_bvh.len() != results.shadow_renderer.len() {
        return Err(crate::Error::Option(
            "rays: the two shadow answers differ in length".into(),
        ));
    }
    let file = std::fs::File::create(path).map_err(io_error(path))?;
    let mut w = std::io::BufWriter::new(file);
    let primary = count(results.primary.len(), "primary rays")?;
    let shadow = count(results.shadow_bvh.len(), "shadow rays")?;
    let mut write = || -> std::io::Result<()> {
        w.write_all(RESULTS_MAGIC)?;
        w.write_all(&primary.to_le_bytes())?;
        for h in &results.primary {
            w.write_all(&h.surface.to_le_bytes())?;
            w.write_all(&h.triangle.to_le_bytes())?;
            w.write_all(&h.t.to_le_bytes())?;
        }
        w.write_all(&shadow.to_le_bytes())?;
        for (&b, &r) in results.shadow_bvh.iter().zip(&results.shadow_renderer) {
            w.write_all(&[u8::from(b) | u8::from(r) << 1])?;
        }
        w.flush()
    };
    write().map_err(io_error(path))
}

/// Reads results [`write_ray_results`] wrote.
pub fn read_ray_results(path: &Path) -> Result<RayResults, crate::Error> {
    let file = std::fs::File::open(path).map_err(io_error(path))?;
    let mut r = Reader(std::io::BufReader::new(file));
    let mut read = || -> std::io::Result<Option<RayResults>> {
        if &r.bytes::<8>()? != RESULTS_MAGIC {
            return Ok(None);
        }
        let primary = (0..r.u32()?)
            .map(|_| {
                Ok(PrimaryHit {
                    surface: r.u32()?,
                    triangle: r.u32()?,
                    t: r.f64()?,
                })
            })
            .collect::<std::io::Result<_>>()?;
        let flags: Vec<u8> = (0..r.u32()?)
            .map(|_| r.bytes::<1>().map(|b| b[0]))
            .collect::<std::io::Result<_>>()?;
        Ok(Some(RayResults {
            primary,
            shadow_bvh: flags.iter().map(|f| f & 1 != 0).collect(),
            shadow_renderer: flags.iter().map(|f| f & 2 != 0).collect(),
        }))
    };
    read()
        .map_err(io_error(path))?
        .ok_or_else(|| bad(path, "not ray results (QTXHITS1)"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dump_and_results_round_trip() {
        let dir = std::env::temp_dir().join(format!("quadtex-rays-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let ray = |k: f64| DumpRay {
            origin: [k, -2.5, 1e-7],
            direction: [0.6, 0.0, -0.8],
            t_min: T_MIN,
            t_max: f64::INFINITY,
        };
        let dump = RayDump {
            width: 2,
            height: 1,
            surfaces: vec![
                DumpSurface {
                    kind: DumpKind::Mesh,
                    triangles: vec![[[0.0, 1.0, 2.0], [3.5, -4.0, 5.0], [6.0, 7.0, 8.25]]],
                },
                DumpSurface {
                    kind: DumpKind::Quad,
                    triangles: vec![[[1.0; 3], [2.0; 3], [3.0; 3]]; 2],
                },
            ],
            primary: vec![ray(0.0), ray(1.0)],
            shadow: vec![ShadowRay {
                ray: ray(3.0),
                pixel: 1,
                surface: 0,
                triangle: 7,
            }],
        };
        let path = dir.join("rays.bin");
        write_ray_dump(&path, &dump).unwrap();
        assert_eq!(read_ray_dump(&path).unwrap(), dump);
        // Header 20 bytes, surfaces 8 + 36 and 8 + 72, primary 4 + 2 × 64,
        // shadow 4 + 64 + 12.
        let bytes = std::fs::metadata(&path).unwrap().len();
        assert_eq!(bytes, 20 + 44 + 80 + 132 + 80);
        let results = RayResults {
            primary: vec![
                PrimaryHit {
                    surface: 0,
                    triangle: 7,
                    t: 12.25,
                },
                PrimaryHit {
                    surface: MISS,
                    triangle: 0,
                    t: f64::INFINITY,
                },
            ],
            shadow_bvh: vec![true],
            shadow_renderer: vec![false],
        };
        let path = dir.join("hits.bin");
        write_ray_results(&path, &results).unwrap();
        assert_eq!(read_ray_results(&path).unwrap(), results);
        assert!(read_ray_dump(&path).is_err(), "results are not a dump");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

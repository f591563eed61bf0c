//! Shading one ray: what it hits, the texture's filtered colour there (by
//! the chosen [`Filter`]), lighting and shadows, or the sky.

use quadtex_core::texture::filter_footprint;
use quadtex_core::{Rgba, Texture};

use crate::math::Ray;
use crate::options::{Filter, PixelFilter};
use crate::scene::{Hit, Lighting, Scene, Sky, Surface};
use crate::stats::PixelStats;
use crate::view::{self, ScreenArea};

/// A scene ready to shade: each surface's texture bound to its wrap once,
/// so shading a pixel does not touch reference counts.
pub(crate) struct Frame<'a> {
    pub scene: &'a Scene,
    samplers: Vec<Option<Texture>>,
}

impl<'a> Frame<'a> {
    pub fn new(scene: &'a Scene) -> Frame<'a> {
        let samplers = scene
            .surfaces
            .iter()
            .map(|s| s.texture.as_ref().map(|t| t.sampler(s.wrap)))
            .collect();
        Frame { scene, samplers }
    }

    /// The filtering view of surface `index`'s texture.
    pub fn sampler(&self, index: usize) -> Option<&Texture> {
        self.samplers.get(index)?.as_ref()
    }
}

/// The sky's colour along `ray`.
pub(crate) fn sky(scene: &Scene, ray: &Ray) -> Rgba {
    match scene.sky {
        Sky::Solid(c) => c,
        Sky::Gradient { horizon, zenith } => {
            let t = ray.direction.y.clamp(0.0, 1.0).sqrt() as f32;
            horizon.lerp(zenith, t)
        }
    }
}

/// The colour seen along `ray`, whose pixel (or part) is `area`.
pub(crate) fn shade_ray(
    frame: &Frame<'_>,
    filter: Filter,
    pixel_filter: PixelFilter,
    ray: &Ray,
    area: ScreenArea,
    stats: &mut PixelStats,
) -> Rgba {
    let scene = frame.scene;
    let Some((index, hit)) = scene.nearest_index(ray) else {
        return sky(scene, ray);
    };
    let surface = &scene.surfaces[index];
    let base = match frame.sampler(index) {
        None => surface.colour,
        Some(sampler) => {
            stats.textured += 1;
            let tex = texture_colour(
                frame,
                index,
                sampler,
                &hit,
                filter,
                pixel_filter,
                area,
                stats,
            );
            tex * surface.colour
        }
    };
    let k = lambert(scene, hit.normal, hit.point, ray);
    Rgba::new(base.r * k[0], base.g * k[1], base.b * k[2], base.a)
}

/// The lighting factor per colour channel at `point` (normal `normal`)
/// seen along `ray`: ambient plus the sun's `cos` unless shadowed; 1 when
/// the scene is unlit.
pub(crate) fn lambert(
    scene: &Scene,
    normal: crate::math::Vec3,
    point: crate::math::Vec3,
    ray: &Ray,
) -> [f32; 3] {
    match scene.lighting {
        Lighting::Unlit => [1.0; 3],
        Lighting::Lambert {
            direction,
            colour,
            ambient,
        } => {
            let n = if normal.dot(ray.direction) > 0.0 {
                -normal
            } else {
                normal
            };
            let cos = n.dot(direction).max(0.0);
            let lit = cos > 0.0 && {
                let distance = (point - ray.origin).length();
                let shadow = Ray {
                    origin: point + n * 1e-6 * (1.0 + distance),
                    direction,
                };
                scene.nearest_hit(&shadow).is_none()
            };
            let k = if lit { cos as f32 } else { 0.0 };
            [0, 1, 2].map(|i| ambient[i] + k * colour[i])
        }
    }
}

/// The filtered texture colour of surface `index` at `hit` for the screen
/// square `area`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn texture_colour(
    frame: &Frame<'_>,
    index: usize,
    sampler: &Texture,
    hit: &Hit,
    filter: Filter,
    pixel_filter: PixelFilter,
    area: ScreenArea,
    stats: &mut PixelStats,
) -> Rgba {
    let scene = frame.scene;
    let surface = &scene.surfaces[index];
    let centre = view::centre_point(surface, hit);
    let traversal = &mut stats.filter.traversal;
    let footprint = || view::footprint(scene, surface, hit, area);
    match filter {
        Filter::Nearest | Filter::Supersample(_) => sampler.nearest_counted(centre, traversal),
        Filter::Bilinear => sampler.bilinear_counted(centre, traversal),
        Filter::Trilinear | Filter::Ewa { .. } => {
            let (Ok(b), Some(fp)) = (surface_baselines(surface), footprint()) else {
                return sampler.nearest_counted(centre, traversal);
            };
            match filter {
                Filter::Ewa { max_anisotropy } => b.pyramid.ewa(&fp, max_anisotropy, surface.wrap),
                _ => b.pyramid.trilinear(&fp, surface.wrap),
            }
        }
        Filter::Sat(options) => {
            let (Ok(b), Some(fp)) = (surface_baselines(surface), footprint()) else {
                return sampler.nearest_counted(centre, traversal);
            };
            // The table is exact at any size: no level of detail.
            let options = options.with_level(u8::MAX);
            filter_footprint(&b.sat, None, surface.wrap, &fp, &options, &mut stats.filter)
                .unwrap_or_else(|| sampler.nearest_counted(centre, &mut stats.filter.traversal))
        }
        Filter::Quadtree(options) => {
            let mean = match pixel_filter {
                PixelFilter::Box => {
                    footprint().map(|fp| sampler.filter_counted(&fp, &options, &mut stats.filter))
                }
                _ => tangent_filtered(frame, index, sampler, hit, &options, pixel_filter, area),
            };
            mean.unwrap_or_else(|| sampler.nearest_counted(centre, &mut stats.filter.traversal))
        }
    }
}

/// The texture under `filter` over its whole support around `area`'s
/// centre, seen on the tangent plane at `hit` (first order for a sphere).
fn tangent_filtered(
    frame: &Frame<'_>,
    index: usize,
    sampler: &Texture,
    hit: &Hit,
    options: &quadtex_core::FilterOptions,
    filter: PixelFilter,
    area: ScreenArea,
) -> Option<Rgba> {
    let planar = crate::scene::Planar {
        point: hit.point,
        uv: hit.uv,
        normal: hit.normal,
        du: hit.du,
        dv: hit.dv,
        extent: crate::scene::Extent::Plane,
    };
    let view = crate::exact::View::new(frame.scene, index, &planar)?;
    let support = filter.support(area.centre);
    view.texture_integral(sampler, &support, filter, area.centre, options)
        .mean()
}

fn surface_baselines(surface: &Surface) -> Result<&crate::scene::Baselines, &str> {
    match &surface.texture {
        Some(t) => t.baselines(),
        None => Err("untextured"),
    }
}

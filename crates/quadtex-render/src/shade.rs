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

fn sky(scene: &Scene, ray: &Ray) -> Rgba {
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
    match scene.lighting {
        Lighting::Unlit => base,
        Lighting::Lambert {
            direction,
            colour,
            ambient,
        } => {
            let n = if hit.normal.dot(ray.direction) > 0.0 {
                -hit.normal
            } else {
                hit.normal
            };
            let cos = n.dot(direction).max(0.0);
            let lit = cos > 0.0 && {
                let shadow = Ray {
                    origin: hit.point + n * 1e-6 * (1.0 + hit.t),
                    direction,
                };
                scene.nearest_hit(&shadow).is_none()
            };
            let k = if lit { cos as f32 } else { 0.0 };
            Rgba::new(
                base.r * (ambient[0] + k * colour[0]),
                base.g * (ambient[1] + k * colour[1]),
                base.b * (ambient[2] + k * colour[2]),
                base.a,
            )
        }
    }
}

/// Screen-space cells per side of the tent's 2×2-pixel support.
pub(crate) const TENT_CELLS: usize = 8;

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
                PixelFilter::Box => footprint().and_then(|fp| {
                    let tree = &**sampler.tree();
                    filter_footprint(
                        tree,
                        Some(tree),
                        surface.wrap,
                        &fp,
                        &options,
                        &mut stats.filter,
                    )
                }),
                PixelFilter::Tent => tent(frame, index, sampler, hit, &options, area.centre, stats),
            };
            mean.unwrap_or_else(|| sampler.nearest_counted(centre, &mut stats.filter.traversal))
        }
    }
}

fn surface_baselines(surface: &Surface) -> Result<&crate::scene::Baselines, &str> {
    match &surface.texture {
        Some(t) => t.baselines(),
        None => Err("untextured"),
    }
}

/// Mean colour under a tent over the 2×2 pixels around `centre`: equal
/// screen-space cells on the tangent plane at `hit`, each filtered, weighted
/// by the tent at the cell's centre.
fn tent(
    frame: &Frame<'_>,
    index: usize,
    sampler: &Texture,
    hit: &Hit,
    options: &quadtex_core::FilterOptions,
    centre: [f64; 2],
    stats: &mut PixelStats,
) -> Option<Rgba> {
    let scene = frame.scene;
    let surface = &scene.surfaces[index];
    let n = TENT_CELLS;
    let step = 2.0 / n as f64;
    let mut grid = [[None::<[f64; 2]>; TENT_CELLS + 1]; TENT_CELLS + 1];
    for (j, row) in grid.iter_mut().enumerate() {
        for (i, slot) in row.iter_mut().enumerate() {
            let (sx, sy) = (
                centre[0] - 1.0 + i as f64 * step,
                centre[1] - 1.0 + j as f64 * step,
            );
            *slot = view::screen_to_texture(scene, surface, hit, sx, sy);
        }
    }
    let tree = &**sampler.tree();
    let (mut acc, mut weights) = (Rgba::TRANSPARENT, 0f32);
    for j in 0..n {
        for i in 0..n {
            let corners = [
                grid[j][i],
                grid[j][i + 1],
                grid[j + 1][i + 1],
                grid[j + 1][i],
            ];
            let [Some(a), Some(b), Some(c), Some(d)] = corners else {
                continue;
            };
            let Ok(fp) = quadtex_core::Footprint::from_corners([a, b, c, d]) else {
                continue;
            };
            let (dx, dy) = (
                -1.0 + (i as f64 + 0.5) * step,
                -1.0 + (j as f64 + 0.5) * step,
            );
            let w = ((1.0 - dx.abs()) * (1.0 - dy.abs())) as f32;
            if let Some(m) = filter_footprint(
                tree,
                Some(tree),
                surface.wrap,
                &fp,
                options,
                &mut stats.filter,
            ) {
                acc += m * w;
                weights += w;
            }
        }
    }
    (weights > 0.0).then(|| acc * (1.0 / weights))
}

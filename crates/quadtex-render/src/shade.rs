//! Shading one ray: what it hits, the texture's filtered colour there (by
//! the chosen [`TextureFilter`]), lighting and shadows, or the sky.

use quadtex_core::baseline::filter_by_strips;
use quadtex_core::{Rgba, Texture};

use crate::caster::Seen;
use crate::frame::{Frame, lambert, sky};
use crate::math::Ray;
use crate::options::{PixelFilter, TextureFilter};
use crate::scene::{Hit, Surface};
use crate::stats::PixelStats;
use crate::tangent_plane::{self, ScreenSquare};

/// The colour seen along `ray`, whose pixel (or part) is `square`; `seen`,
/// when known, is the primitive the visibility grid found along this very
/// ray (so only it is intersected).
pub(crate) fn shade_ray(
    frame: &Frame<'_>,
    filter: TextureFilter,
    pixel_filter: PixelFilter,
    (ray, seen): (&Ray, Option<Seen>),
    square: ScreenSquare,
    stats: &mut PixelStats,
) -> Rgba {
    let scene = frame.scene;
    let nearest = match seen {
        Some(id) => frame.rays.nearest_seen(ray, id),
        None => frame.rays.nearest_index(ray),
    };
    let Some((index, hit)) = nearest else {
        return sky(scene, ray);
    };
    let surface = &scene.surfaces[index];
    let base = match frame.texture(index) {
        None => surface.colour,
        Some(texture) => {
            stats.textured += 1;
            let at = TexturedHit {
                surface: index,
                texture,
                hit: &hit,
            };
            let tex = texture_colour(
                frame,
                at,
                filter,
                pixel_filter,
                square,
                || tangent_plane::footprint(scene, surface, &hit, square),
                stats,
            );
            tex * surface.colour
        }
    };
    let k = lambert(
        &frame.rays,
        (index, hit.triangle),
        hit.normal,
        hit.point,
        ray,
    );
    Rgba::new(base.r * k[0], base.g * k[1], base.b * k[2], base.a)
}

/// A ray's hit on a textured surface: what [`texture_colour`] filters
/// around.
#[derive(Clone, Copy)]
pub(crate) struct TexturedHit<'h> {
    /// The surface's index in the scene.
    pub surface: usize,
    /// Its texture, bound to its wrap ([`Frame::texture`]).
    pub texture: &'h Texture,
    /// Where the ray meets it.
    pub hit: &'h Hit,
}

/// The filtered texture colour at hit `at` for screen square `square`,
/// whose footprint `footprint` gives when a filter needs it (computed
/// there, or given: lookups are timed without it).
pub(crate) fn texture_colour(
    frame: &Frame<'_>,
    at: TexturedHit<'_>,
    filter: TextureFilter,
    pixel_filter: PixelFilter,
    square: ScreenSquare,
    footprint: impl FnOnce() -> Option<quadtex_core::Footprint>,
    stats: &mut PixelStats,
) -> Rgba {
    let TexturedHit {
        surface: index,
        texture,
        hit,
    } = at;
    let scene = frame.scene;
    let surface = &scene.surfaces[index];
    let centre = tangent_plane::centre_point(surface, hit);
    let traversal = &mut stats.filter.traversal;
    match filter {
        TextureFilter::Nearest | TextureFilter::Supersample(_) => {
            texture.nearest_counted(centre, traversal)
        }
        TextureFilter::Bilinear => texture.bilinear_counted(centre, traversal),
        TextureFilter::Trilinear | TextureFilter::Ewa { .. } => {
            let (Ok(b), Some(fp)) = (surface_baselines(surface), footprint()) else {
                return texture.nearest_counted(centre, traversal);
            };
            match filter {
                TextureFilter::Ewa { max_anisotropy } => {
                    b.pyramid.ewa(&fp, max_anisotropy, surface.wrap)
                }
                _ => b.pyramid.trilinear(&fp, surface.wrap),
            }
        }
        TextureFilter::EwaSameMemory { max_anisotropy } => {
            let same_memory = surface.texture.as_ref().map(|t| t.same_memory_pyramid());
            let (Some(Ok(pyramid)), Some(fp)) = (same_memory, footprint()) else {
                return texture.nearest_counted(centre, traversal);
            };
            pyramid.ewa(&fp, max_anisotropy, surface.wrap)
        }
        TextureFilter::Sat(options) => {
            let (Ok(b), Some(fp)) = (surface_baselines(surface), footprint()) else {
                return texture.nearest_counted(centre, traversal);
            };
            // The table is exact at any size: no level of detail.
            let options = options.with_level(u8::MAX);
            filter_by_strips(&b.sat, None, surface.wrap, &fp, &options, &mut stats.filter)
                .unwrap_or_else(|| texture.nearest_counted(centre, &mut stats.filter.traversal))
        }
        TextureFilter::Quadtree(options) => {
            let mean = match pixel_filter {
                PixelFilter::Box => {
                    footprint().map(|fp| texture.filter_counted(&fp, &options, &mut stats.filter))
                }
                _ => tangent_filtered(frame, at, &options, pixel_filter, square),
            };
            mean.unwrap_or_else(|| texture.nearest_counted(centre, &mut stats.filter.traversal))
        }
    }
}

/// The texture under `filter` over its whole support around `square`'s
/// centre, seen on the tangent plane at `hit` (first order for a sphere).
fn tangent_filtered(
    frame: &Frame<'_>,
    TexturedHit {
        surface: index,
        texture,
        hit,
    }: TexturedHit<'_>,
    options: &quadtex_core::FilterOptions,
    filter: PixelFilter,
    square: ScreenSquare,
) -> Option<Rgba> {
    let planar = crate::scene::Planar {
        point: hit.point,
        uv: hit.uv,
        normal: hit.normal,
        du: hit.du,
        dv: hit.dv,
        extent: crate::scene::Extent::Plane,
        triangle: None,
    };
    let view = crate::view::View::new(frame.scene, index, &planar)?;
    let support = filter.support(square.centre);
    view.texture_integral(texture, &support, filter, square.centre, options)
        .mean()
}

fn surface_baselines(surface: &Surface) -> Result<&crate::scene::Baselines, &str> {
    match &surface.texture {
        Some(t) => t.baselines(),
        None => Err("untextured"),
    }
}

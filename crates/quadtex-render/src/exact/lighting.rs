//! Shading a region of a pixel's support: its texture integral, tint,
//! and Lambert lighting, uniform over a mesh triangle where shown to be
//! ([`uniform_light`]), else from the region's own shadow ray.

use quadtex_core::{ConvexPolygon, FilterOptions, PixelFilter};

use crate::frame::{Frame, lambert};
use crate::scene::{Geometry, Lighting};
use crate::span::SpanAnswer;
use crate::stats::PixelStats;
use crate::view::View;

/// What shading a region of one pixel's support takes besides the region:
/// the frame, the pixel filter centred at `centre`, the texture filter's
/// options, the box `(lo, hi)` of the support the region was cut from
/// (the pixel's, or one of its quarters when it is taken quarter by
/// quarter), and that support's share of the pixel's bound (`1` for the
/// whole support, `|∫k|` over a quarter), which a sphere scales the
/// weight it may leave off its map by.
#[derive(Clone, Copy)]
pub(super) struct Shading<'p> {
    pub(super) frame: &'p Frame<'p>,
    pub(super) filter: PixelFilter,
    pub(super) centre: [f64; 2],
    pub(super) options: &'p FilterOptions,
    pub(super) support: ([f64; 2], [f64; 2]),
    pub(super) share: f64,
}

/// `(Σ colour·k, Σ k, bound)` of surface `view` over screen `region`, lit
/// by `light` when the caller knows it for the whole region (a run's,
/// [`UniformSpan::run_light`](crate::span::UniformSpan::run_light)), else
/// by the region's own shadow ray.
pub(super) fn shade_region(
    shading: &Shading<'_>,
    view: &View,
    region: &ConvexPolygon,
    light: Option<[f32; 3]>,
    stats: &mut PixelStats,
) -> ([f64; 4], f64, f64) {
    let Shading {
        frame,
        filter,
        centre,
        options,
        ..
    } = *shading;
    let (c, w, b) = match frame.texture(view.surface()) {
        Some(texture) => {
            stats.textured = 1;
            let r = texture.integrate_region(
                view.projection(),
                region,
                filter,
                centre,
                options,
                &mut stats.filter,
            );
            (Some(r.colour.0), r.weight, r.error_bound)
        }
        None => (None, filter.integral(region, centre), 0.0),
    };
    (tint_and_light(frame, view, region, c, w, light), w, b)
}

/// A region's colour from its texture integral `texture` (`None`: the
/// surface is untextured) and weight `w`: tinted by the surface's colour,
/// then lit by `light` when the caller knows it for the whole region, else
/// by the region's own shadow ray ([`light_region`]).
pub(super) fn tint_and_light(
    frame: &Frame<'_>,
    view: &View,
    region: &ConvexPolygon,
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
        None => light_region(frame, view, region, &mut c),
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
/// `None` otherwise (each region then casts its own shadow ray,
/// [`light_region`]).
pub(super) fn uniform_light(frame: &Frame<'_>, view: &View) -> Option<[f32; 3]> {
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
pub(super) fn apply_light(c: &mut [f64; 4], light: [f32; 3]) {
    for (v, f) in c.iter_mut().zip(light) {
        *v *= f64::from(f);
    }
}

/// What [`shade_region`] gives a pixel of a [`UniformSpan`](crate::span::UniformSpan) whose whole
/// support is `support`: the span's texture colour (or the surface's tint
/// alone) times the filter's weight there, lit by the span's light or, when
/// the span has none, by the support's own shadow ray. The arithmetic is
/// [`shade_region`]'s, step for step, so that a pixel comes out the same
/// either way.
pub(super) fn shade_span_pixel(
    shading: &Shading<'_>,
    view: &View,
    support: &ConvexPolygon,
    answer: &SpanAnswer,
    stats: &mut PixelStats,
) -> ([f64; 4], f64) {
    let Shading {
        frame,
        filter,
        centre,
        ..
    } = *shading;
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

/// Multiplies `c` by the lighting at `region`'s centroid on `view`'s
/// primitive (its shadow ray's answer there).
pub(super) fn light_region(
    frame: &Frame<'_>,
    view: &View,
    region: &ConvexPolygon,
    c: &mut [f64; 4],
) {
    let scene = frame.scene;
    if let Lighting::Lambert { .. } = scene.lighting {
        let s = region.centroid();
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

//! Screen ↔ texture geometry for the tangent-plane path (spheres and the
//! raster baselines): where a screen point lands in texture space, and a
//! pixel's footprint. Planar primitives under the quadtree filter use their
//! exact projective maps instead (`crate::exact`).
//!
//! **Footprints.** The rays through the pixel's four corners are intersected
//! with the *tangent plane* of the surface at the centre ray's hit, and mapped
//! to texture space by the surface's UV gradients at that hit. For planes and
//! quads this is the exact projective footprint of the pixel square; for
//! spheres it is first-order accurate (the error grows with the footprint's
//! size relative to the radius, as with pbrt's ray differentials). A corner
//! ray that misses the tangent plane (a pixel straddling the horizon) is
//! replaced by the mirror image of the opposite corner through the centre
//! hit, so the footprint keeps the visible half's size instead of becoming
//! infinite.

use quadtex_core::Footprint;

use crate::math::Vec3;
use crate::scene::{Hit, Scene, Surface};

/// A square of the screen: a pixel, or part of one at a silhouette.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ScreenSquare {
    /// Centre, in pixel units from the image's top-left corner.
    pub centre: [f64; 2],
    /// Half the side, in pixels (0.5 for a whole pixel).
    pub half: f64,
}

impl ScreenSquare {
    /// The pixel whose centre is `(cx, cy)`.
    pub fn pixel(cx: f64, cy: f64) -> ScreenSquare {
        ScreenSquare {
            centre: [cx, cy],
            half: 0.5,
        }
    }
}

/// The texture point where the ray through screen point `(sx, sy)` meets the
/// tangent plane at `hit`, if it does (in front of the camera).
pub(crate) fn screen_to_texture(
    scene: &Scene,
    surface: &Surface,
    hit: &Hit,
    sx: f64,
    sy: f64,
) -> Option<[f64; 2]> {
    let ray = scene.camera.ray(sx, sy);
    let denom = ray.direction.dot(hit.normal);
    if denom.abs() <= 1e-12 {
        return None;
    }
    let t = (hit.point - ray.origin).dot(hit.normal) / denom;
    (t > 0.0 && t.is_finite()).then(|| texture_point(surface, hit, ray.origin + ray.direction * t))
}

/// The texture-space point of world point `q` on the tangent plane at `hit`.
fn texture_point(surface: &Surface, hit: &Hit, q: Vec3) -> [f64; 2] {
    let d = q - hit.point;
    surface
        .uv_transform
        .apply([hit.uv[0] + hit.du.dot(d), hit.uv[1] + hit.dv.dot(d)])
}

/// The texture point at the centre hit.
pub(crate) fn centre_point(surface: &Surface, hit: &Hit) -> [f64; 2] {
    surface.uv_transform.apply(hit.uv)
}

/// The corners of the footprint of `square` (module documentation), in pixel
/// order. The texture map is affine on the tangent plane, so mirroring a
/// missing corner through the centre can be done in texture space.
pub(crate) fn footprint_corners(
    scene: &Scene,
    surface: &Surface,
    hit: &Hit,
    square: ScreenSquare,
) -> [[f64; 2]; 4] {
    let h = square.half;
    let offsets = [[-h, -h], [h, -h], [h, h], [-h, h]];
    let c = square.centre;
    let corners = offsets.map(|o| screen_to_texture(scene, surface, hit, c[0] + o[0], c[1] + o[1]));
    let centre = centre_point(surface, hit);
    std::array::from_fn(|i| match (corners[i], corners[(i + 2) % 4]) {
        (Some(t), _) => t,
        (None, Some(opposite)) => [2.0 * centre[0] - opposite[0], 2.0 * centre[1] - opposite[1]],
        (None, None) => centre,
    })
}

/// The footprint of `square`, or `None` if a corner is not finite (a
/// tangent plane seen exactly edge-on).
pub(crate) fn footprint(
    scene: &Scene,
    surface: &Surface,
    hit: &Hit,
    square: ScreenSquare,
) -> Option<Footprint> {
    Footprint::from_corners(footprint_corners(scene, surface, hit, square)).ok()
}

//! A scene ready to shade ([`Frame`]) and what every shading path shares:
//! the sky's colour and the lighting.

use quadtex_core::{Rgba, Texture};

use crate::caster::Caster;
use crate::math::{Ray, Vec3};
use crate::scene::{Lighting, Scene, Sky};

/// A scene ready to shade: each surface's texture bound to its wrap once,
/// so shading a pixel does not touch reference counts.
pub(crate) struct Frame<'a> {
    pub scene: &'a Scene,
    /// The surfaces ready for rays.
    pub rays: Caster<'a>,
    textures: Vec<Option<Texture>>,
}

impl<'a> Frame<'a> {
    pub fn new(scene: &'a Scene) -> Frame<'a> {
        let textures = scene
            .surfaces
            .iter()
            .map(|s| s.texture.as_ref().map(|t| t.texture(s.wrap)))
            .collect();
        Frame {
            scene,
            rays: Caster::new(scene).with_sun_grids(),
            textures,
        }
    }

    /// Surface `index`'s texture, bound to the surface's wrap.
    pub fn texture(&self, index: usize) -> Option<&Texture> {
        self.textures.get(index)?.as_ref()
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

/// The lighting factor per colour channel at `point` (normal `normal`)
/// seen along `ray`: ambient plus the sun's `cos` unless shadowed; 1 when
/// the scene is unlit. `point` lies on `from`, a surface and its mesh
/// triangle (any for other shapes), whose shadow ray leaves it towards the
/// sun.
pub(crate) fn lambert(
    rays: &Caster<'_>,
    from: (usize, u32),
    normal: Vec3,
    point: Vec3,
    ray: &Ray,
) -> [f32; 3] {
    match rays.scene.lighting {
        Lighting::Unlit => [1.0; 3],
        Lighting::Lambert { direction, .. } => {
            let (cos, shadow) = sun_ray(direction, normal, point, ray);
            let lit = shadow.is_some_and(|shadow| !rays.occluded_leaving(&shadow, from));
            let k = if lit { cos as f32 } else { 0.0 };
            lit_factor(&rays.scene.lighting, k)
        }
    }
}

/// The sun's `cos` at `point` (normal `normal`, turned to face `ray`) for
/// a sun towards `direction` (unit), at least 0, and the shadow ray
/// [`lambert`] casts from there when the cos is positive: from `point`
/// lifted along the normal by `10⁻⁶` of `1 +` its distance from the ray's
/// origin, towards the sun. Shared with `quadtex rays`, which dumps these
/// very rays for a peer ray caster.
pub(crate) fn sun_ray(direction: Vec3, normal: Vec3, point: Vec3, ray: &Ray) -> (f64, Option<Ray>) {
    let n = if normal.dot(ray.direction) > 0.0 {
        -normal
    } else {
        normal
    };
    let cos = n.dot(direction).max(0.0);
    let shadow = (cos > 0.0).then(|| {
        let distance = (point - ray.origin).length();
        Ray {
            origin: point + n * 1e-6 * (1.0 + distance),
            direction,
        }
    });
    (cos, shadow)
}

/// The lighting factor per colour channel where the sun's `cos` is `k`
/// (0 in shadow or facing away): ambient plus `k` times the sun's colour,
/// as [`lambert`] gives it; 1 when the scene is unlit.
pub(crate) fn lit_factor(lighting: &Lighting, k: f32) -> [f32; 3] {
    match lighting {
        Lighting::Unlit => [1.0; 3],
        Lighting::Lambert {
            colour, ambient, ..
        } => [0, 1, 2].map(|i| ambient[i] + k * colour[i]),
    }
}

//! The built-in demo: an airfield at dusk from a low approach.

use std::sync::Arc;

use quadtex_core::synth::{self, Art, palette};
use quadtex_core::{BuildOptions, QuadTree, Rgba, TexelGrid, Wrap};

use crate::Error;
use crate::math::Vec3;
use crate::scene::{Camera, Geometry, Lighting, Scene, SceneTexture, Sky, Surface, UvTransform};

/// The sign's art: white lettering on red in the band `z ∈ [0, 1/4)` of the
/// unit square (a 4:1 sign; map it with a UV scale of `[1, 0.25]`).
pub fn sign_art() -> Art {
    let mut art = Art::new(palette::RED);
    art.rect(0.01, 0.005, 0.99, 0.245, palette::BLACK);
    art.rect(0.02, 0.0125, 0.98, 0.2375, palette::RED);
    art.text("RWY 09-27", 0.23, 0.13, 0.01, palette::WHITE);
    art.text("TWY A", 0.35, 0.035, 0.01, palette::YELLOW);
    art
}

pub(crate) fn builtin_grid(name: &str) -> Option<Result<TexelGrid, quadtex_core::Error>> {
    Some(match name {
        "runway" => synth::runway_art().rasterise(2048, 2048),
        "checker" => synth::checkerboard(2, 2),
        "sign" => sign_art().rasterise(1024, 1024),
        _ => return None,
    })
}

/// A built-in texture, packed once per process and shared (with its lazily
/// built raster baselines) by every scene that names it.
pub(crate) fn builtin_texture(name: &str) -> Result<SceneTexture, Error> {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    static CACHE: OnceLock<Mutex<HashMap<String, SceneTexture>>> = OnceLock::new();
    let cache = CACHE.get_or_init(Mutex::default);
    // A poisoned lock only means another thread panicked mid-insert; the
    // map itself is still a valid cache.
    if let Some(t) = cache
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .get(name)
    {
        return Ok(t.clone());
    }
    let texture = pack_builtin(name)?;
    cache
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .insert(name.to_string(), texture.clone());
    Ok(texture)
}

fn pack_builtin(name: &str) -> Result<SceneTexture, Error> {
    let key = format!("builtin:{name}");
    let grid = builtin_grid(name)
        .ok_or_else(|| {
            Error::Option(format!(
                "unknown built-in texture `{name}` (runway, checker, sign)"
            ))
        })?
        .map_err(|source| Error::Pack {
            key: key.clone(),
            source,
        })?;
    let (tree, _) =
        QuadTree::from_texels(&grid, &BuildOptions::default()).map_err(|source| Error::Pack {
            key: key.clone(),
            source,
        })?;
    Ok(SceneTexture::new(key, Arc::new(tree)))
}

/// The demo scene, built in code with no files: a 45 m × 1800 m runway with
/// markings and numbers receding to the horizon, a checkerboard apron to the
/// horizon (repeating 20 m tiles), a sign with text at the runway's side, a
/// dusk sky and a low sun. 1280×720.
pub fn demo_scene() -> Result<Scene, Error> {
    let runway = builtin_texture("runway")?;
    let checker = builtin_texture("checker")?;
    let sign = builtin_texture("sign")?;
    let camera = Camera::new(
        Vec3::new(6.0, 14.0, 120.0),
        Vec3::new(-4.0, 0.0, -400.0),
        Vec3::new(0.0, 1.0, 0.0),
        38.0,
        1280,
        720,
    )
    .ok_or_else(|| Error::Option("demo camera is degenerate".into()))?;
    let white = Rgba::opaque(1.0, 1.0, 1.0);
    let surfaces = vec![
        Surface {
            // The art is a square with the runway in x ∈ [0.3, 0.7]: a 112.5 m
            // × 1800 m quad shows the 45 m runway with grass shoulders.
            geometry: Geometry::Quad {
                origin: Vec3::new(-56.25, 0.02, 0.0),
                edge_u: Vec3::new(112.5, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 0.0, -1800.0),
            },
            texture: Some(runway),
            colour: white,
            uv_transform: UvTransform::default(),
            wrap: Wrap::CLAMP,
        },
        Surface {
            geometry: Geometry::Plane {
                point: Vec3::new(0.0, 0.0, 0.0),
                normal: Vec3::new(0.0, 1.0, 0.0),
                u_axis: Vec3::new(1.0, 0.0, 0.0),
                v_axis: Vec3::new(0.0, 0.0, -1.0),
            },
            texture: Some(checker),
            colour: white,
            uv_transform: UvTransform {
                scale: [1.0 / 20.0, 1.0 / 20.0],
                ..UvTransform::default()
            },
            wrap: Wrap::REPEAT,
        },
        Surface {
            geometry: Geometry::Quad {
                origin: Vec3::new(-80.0, 0.8, -40.0),
                edge_u: Vec3::new(16.0, 0.0, 5.0),
                edge_v: Vec3::new(0.0, 4.0, 0.0),
            },
            texture: Some(sign),
            colour: white,
            uv_transform: UvTransform {
                scale: [1.0, 0.25],
                ..UvTransform::default()
            },
            wrap: Wrap::CLAMP,
        },
    ];
    let light = Vec3::new(-0.8, 0.25, 0.55)
        .normalized()
        .ok_or_else(|| Error::Option("light".into()))?;
    Ok(Scene {
        camera,
        surfaces,
        sky: Sky::Gradient {
            horizon: Rgba::opaque(0.85, 0.38, 0.16),
            zenith: Rgba::opaque(0.04, 0.06, 0.2),
        },
        lighting: Lighting::Lambert {
            direction: light,
            colour: [1.5, 1.0, 0.7],
            ambient: [0.35, 0.35, 0.5],
        },
    })
}

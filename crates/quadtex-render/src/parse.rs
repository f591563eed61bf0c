//! Scene files in TOML (format in `docs/scenes.md`). Values are read from a
//! `toml::Table`; when something is wrong, the same text is parsed once more
//! with spans so the error can name the line of the offending key.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use quadtex_core::MAX_VECTOR_LEVEL;
use quadtex_core::{BuildOptions, QuadTree, Rgba, Wrap, WrapMode};
use toml::{Table, Value};

use crate::Error;
use crate::demo::builtin_texture;
use crate::math::Vec3;
use crate::path::{CameraPath, Key, MAX_PATH_KEYS};
use crate::scene::{
    Camera, Geometry, Lighting, MESH_BYTES_PER_TRIANGLE, Scene, SceneTexture, Sky, Surface,
    UvTransform,
};
use quadtex_io::Limits;

/// Max level of SVG textures without `texture_level` (4096² effective).
const DEFAULT_SVG_LEVEL: u8 = 12;

/// Largest coordinate magnitude accepted in a scene (beyond it `f64`
/// intersections lose the precision footprints need).
const MAX_COORDINATE: f64 = 1e9;

/// The keys every shape table may hold, whatever its type.
const SURFACE_KEYS: [&str; 10] = [
    "type",
    "colour",
    "texture",
    "texture_level",
    "contour_leaves",
    "wrap",
    "border",
    "uv_scale",
    "uv_offset",
    "uv_rotation",
];

/// Reads and validates a scene file under `limits` (scene file size, shapes,
/// mesh triangles, and everything its textures read).
pub fn load_scene(path: &Path, limits: &Limits) -> Result<Scene, Error> {
    let len = std::fs::metadata(path)
        .map_err(|source| Error::Io {
            path: path.into(),
            source,
        })?
        .len();
    if len > limits.max_file_bytes {
        return Err(Error::Scene {
            path: path.into(),
            line: None,
            key: "(file)".into(),
            message: format!(
                "{len} bytes, above max_file_bytes {}",
                limits.max_file_bytes
            ),
        });
    }
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
        path: path.into(),
        source,
    })?;
    parse_scene(&text, path, limits)
}

/// Parses scene text under `limits`; `path` names it in errors and anchors
/// relative paths.
pub fn parse_scene(text: &str, path: &Path, limits: &Limits) -> Result<Scene, Error> {
    let mut cx = Context {
        text,
        path,
        textures: HashMap::new(),
        limits: *limits,
    };
    let root: Table = text.parse().map_err(|e: toml::de::Error| {
        let line = e.span().map(|s| line_of(text, s.start));
        Error::Scene {
            path: path.into(),
            line,
            key: "(syntax)".into(),
            message: e.message().to_string(),
        }
    })?;
    cx.keys(&root, "", &["camera", "sky", "light", "shape"])?;
    let camera = cx.camera(cx.table(&root, "camera")?)?;
    let sky = match root.get("sky") {
        None => Sky::Solid(Rgba::opaque(0.0, 0.0, 0.0)),
        Some(_) => cx.sky(cx.table(&root, "sky")?)?,
    };
    let lighting = match root.get("light") {
        None => Lighting::Unlit,
        Some(_) => cx.light(cx.table(&root, "light")?)?,
    };
    let shapes = match root.get("shape") {
        Some(Value::Array(a)) => a,
        Some(_) => return Err(cx.err("shape", "must be an array of tables: [[shape]]")),
        None => return Err(cx.err("shape", "the scene has no [[shape]]")),
    };
    if shapes.len() > cx.limits.max_scene_shapes {
        return Err(cx.err(
            "shape",
            &format!(
                "{} shapes, more than max_scene_shapes {}",
                shapes.len(),
                cx.limits.max_scene_shapes
            ),
        ));
    }
    let mut surfaces = Vec::with_capacity(shapes.len());
    for (i, s) in shapes.iter().enumerate() {
        let key = format!("shape[{i}]");
        let Value::Table(t) = s else {
            return Err(cx.err(&key, "must be a table"));
        };
        if t.get("type").and_then(Value::as_str) == Some("gltf") {
            surfaces.extend(cx.gltf(t, &key)?);
        } else {
            surfaces.push(cx.surface(t, &key)?);
        }
        if surfaces.len() > cx.limits.max_scene_shapes {
            return Err(cx.err(
                &key,
                &format!(
                    "the scene reaches {} surfaces (a glTF model adds one per material), more than max_scene_shapes {}",
                    surfaces.len(),
                    cx.limits.max_scene_shapes
                ),
            ));
        }
    }
    let scene = Scene {
        camera,
        surfaces,
        sky,
        lighting,
    };
    crate::caster::prepare_sun_grids(&scene);
    Ok(scene)
}

/// Reads and validates a camera path file (format in `docs/scenes.md`,
/// model in [`crate::path`]) under `limits` (its size).
pub fn load_camera_path(path: &Path, limits: &Limits) -> Result<CameraPath, Error> {
    let io = |source| Error::Io {
        path: path.into(),
        source,
    };
    let len = std::fs::metadata(path).map_err(io)?.len();
    if len > limits.max_file_bytes {
        return Err(Error::Scene {
            path: path.into(),
            line: None,
            key: "(file)".into(),
            message: format!(
                "{len} bytes, above max_file_bytes {}",
                limits.max_file_bytes
            ),
        });
    }
    let text = std::fs::read_to_string(path).map_err(io)?;
    parse_camera_path(&text, path)
}

/// Parses camera path text; `path` names it in errors.
pub fn parse_camera_path(text: &str, path: &Path) -> Result<CameraPath, Error> {
    let cx = Context {
        text,
        path,
        textures: HashMap::new(),
        limits: Limits::default(),
    };
    let root: Table = text.parse().map_err(|e: toml::de::Error| Error::Scene {
        path: path.into(),
        line: e.span().map(|s| line_of(text, s.start)),
        key: "(syntax)".into(),
        message: e.message().to_string(),
    })?;
    cx.keys(&root, "", &["key"])?;
    let keys = match root.get("key") {
        Some(Value::Array(a)) => a,
        Some(_) => return Err(cx.err("key", "must be an array of tables: [[key]]")),
        None => return Err(cx.err("key", "the path has no [[key]]")),
    };
    if keys.len() > MAX_PATH_KEYS {
        return Err(cx.err(
            "key",
            &format!("{} keys, more than {MAX_PATH_KEYS}", keys.len()),
        ));
    }
    let mut out = Vec::with_capacity(keys.len());
    for (i, k) in keys.iter().enumerate() {
        let name = format!("key[{i}]");
        let Value::Table(t) = k else {
            return Err(cx.err(&name, "must be a table"));
        };
        cx.keys(t, &name, &["time", "position", "look_at", "up", "fov"])?;
        let previous = out.last();
        let time = match cx.number(t, &name, "time")? {
            Some(time) => time,
            None => previous.map_or(0.0, |p: &Key| p.time + 1.0),
        };
        let up = match cx.vec3(t, &name, "up")? {
            Some(up) => up,
            None => previous.map_or(Vec3::new(0.0, 1.0, 0.0), |p| p.up),
        };
        let fov = match cx.number(t, &name, "fov")? {
            Some(fov) => fov,
            None => previous.map_or(45.0, |p| p.fov),
        };
        out.push(Key {
            time,
            position: cx.required_vec3(t, &name, "position")?,
            look_at: cx.required_vec3(t, &name, "look_at")?,
            up,
            fov,
        });
    }
    CameraPath::new(out).map_err(|message| {
        // The message starts with the key it is about: name it, with its line.
        match message.split(' ').next().filter(|k| k.starts_with("key[")) {
            Some(key) => cx.err(key, message[key.len()..].trim_start()),
            None => cx.err("key", &message),
        }
    })
}

struct Context<'a> {
    text: &'a str,
    path: &'a Path,
    textures: HashMap<(PathBuf, u8, Option<usize>), SceneTexture>,
    limits: Limits,
}

fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())]
        .bytes()
        .filter(|&b| b == b'\n')
        .count()
        + 1
}

impl Context<'_> {
    /// An error at `key` (dotted path, with `[i]` for array items).
    fn err(&self, key: &str, message: &str) -> Error {
        Error::Scene {
            path: self.path.into(),
            line: self.line(key),
            key: key.into(),
            message: message.into(),
        }
    }

    /// The line where `key` is defined, from a spanned parse.
    fn line(&self, key: &str) -> Option<usize> {
        let doc = toml::de::DeTable::parse(self.text).ok()?;
        let mut table = doc.get_ref();
        let mut span = None;
        for part in key.split('.') {
            let (name, index) = match part.split_once('[') {
                Some((n, rest)) => (n, rest.trim_end_matches(']').parse::<usize>().ok()),
                None => (part, None),
            };
            let (k, v) = table.get_key_value(name)?;
            span = Some(k.span().start);
            let mut value = v.get_ref();
            if let (Some(i), toml::de::DeValue::Array(a)) = (index, value) {
                let item = a.get(i)?;
                span = Some(item.span().start);
                value = item.get_ref();
            }
            match value {
                toml::de::DeValue::Table(t) => table = t,
                _ => break,
            }
        }
        span.map(|s| line_of(self.text, s))
    }

    fn keys(&self, t: &Table, prefix: &str, allowed: &[&str]) -> Result<(), Error> {
        for k in t.keys() {
            if !allowed.contains(&k.as_str()) {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                return Err(self.err(
                    &key,
                    &format!("unknown key (expected one of: {})", allowed.join(", ")),
                ));
            }
        }
        Ok(())
    }

    fn table<'t>(&self, t: &'t Table, key: &str) -> Result<&'t Table, Error> {
        match t.get(key) {
            Some(Value::Table(x)) => Ok(x),
            Some(_) => Err(self.err(key, "must be a table")),
            None => Err(self.err(key, "missing")),
        }
    }

    fn number(&self, t: &Table, prefix: &str, key: &str) -> Result<Option<f64>, Error> {
        let full = format!("{prefix}.{key}");
        let v = match t.get(key) {
            None => return Ok(None),
            Some(Value::Float(f)) => *f,
            Some(Value::Integer(i)) => *i as f64,
            Some(_) => return Err(self.err(&full, "must be a number")),
        };
        if !v.is_finite() {
            return Err(self.err(&full, &format!("must be finite, got {v}")));
        }
        if v.abs() > MAX_COORDINATE {
            return Err(self.err(
                &full,
                &format!("{v} is beyond the limit ±{MAX_COORDINATE:e}"),
            ));
        }
        Ok(Some(v))
    }

    fn numbers<const N: usize>(
        &self,
        t: &Table,
        prefix: &str,
        key: &str,
    ) -> Result<Option<[f64; N]>, Error> {
        let full = format!("{prefix}.{key}");
        let Some(v) = t.get(key) else { return Ok(None) };
        let Value::Array(a) = v else {
            return Err(self.err(&full, &format!("must be an array of {N} numbers")));
        };
        if a.len() != N {
            return Err(self.err(&full, &format!("must have {N} numbers, has {}", a.len())));
        }
        let mut out = [0f64; N];
        for (o, x) in out.iter_mut().zip(a) {
            *o = match x {
                Value::Float(f) => *f,
                Value::Integer(i) => *i as f64,
                _ => return Err(self.err(&full, "must contain only numbers")),
            };
            if !o.is_finite() {
                return Err(self.err(&full, &format!("must be finite, got {o}")));
            }
            if o.abs() > MAX_COORDINATE {
                return Err(self.err(
                    &full,
                    &format!("{o} is beyond the limit ±{MAX_COORDINATE:e}"),
                ));
            }
        }
        Ok(Some(out))
    }

    fn vec3(&self, t: &Table, prefix: &str, key: &str) -> Result<Option<Vec3>, Error> {
        Ok(self
            .numbers::<3>(t, prefix, key)?
            .map(|[x, y, z]| Vec3::new(x, y, z)))
    }

    fn required_vec3(&self, t: &Table, prefix: &str, key: &str) -> Result<Vec3, Error> {
        self.vec3(t, prefix, key)?
            .ok_or_else(|| self.err(&format!("{prefix}.{key}"), "missing"))
    }

    fn colour(&self, t: &Table, prefix: &str, key: &str) -> Result<Option<Rgba>, Error> {
        let full = format!("{prefix}.{key}");
        let rgba = match t.get(key) {
            Some(Value::Array(a)) if a.len() == 4 => self.numbers::<4>(t, prefix, key)?,
            _ => self
                .numbers::<3>(t, prefix, key)?
                .map(|[r, g, b]| [r, g, b, 1.0]),
        };
        let Some([r, g, b, a]) = rgba else {
            return Ok(None);
        };
        if [r, g, b, a].iter().any(|&c| c < 0.0) || a > 1.0 {
            return Err(self.err(&full, "colour channels must be >= 0 and alpha <= 1"));
        }
        Ok(Some(Rgba::new(
            (r * a) as f32,
            (g * a) as f32,
            (b * a) as f32,
            a as f32,
        )))
    }

    fn size(&self, t: &Table, key: &str) -> Result<u32, Error> {
        let full = format!("camera.{key}");
        match t.get(key) {
            Some(Value::Integer(i)) if (1..=65536).contains(i) => Ok(*i as u32),
            Some(_) => Err(self.err(&full, "must be an integer in 1..=65536")),
            None => Err(self.err(&full, "missing")),
        }
    }

    fn camera(&self, t: &Table) -> Result<Camera, Error> {
        self.keys(
            t,
            "camera",
            &["position", "look_at", "up", "fov", "width", "height"],
        )?;
        let position = self.required_vec3(t, "camera", "position")?;
        let look_at = self.required_vec3(t, "camera", "look_at")?;
        let up = self
            .vec3(t, "camera", "up")?
            .unwrap_or(Vec3::new(0.0, 1.0, 0.0));
        let fov = self.number(t, "camera", "fov")?.unwrap_or(45.0);
        let (width, height) = (self.size(t, "width")?, self.size(t, "height")?);
        if !(fov > 0.0 && fov < 180.0) {
            return Err(self.err(
                "camera.fov",
                &format!("must be in (0, 180) degrees, got {fov}"),
            ));
        }
        if (look_at - position).normalized().is_none() {
            return Err(self.err("camera.look_at", "coincides with camera.position"));
        }
        Camera::new(position, look_at, up, fov, width, height)
            .ok_or_else(|| self.err("camera.up", "is parallel to the viewing direction"))
    }

    fn sky(&self, t: &Table) -> Result<Sky, Error> {
        self.keys(t, "sky", &["colour", "horizon", "zenith"])?;
        if let Some(c) = self.colour(t, "sky", "colour")? {
            return Ok(Sky::Solid(c));
        }
        let horizon = self
            .colour(t, "sky", "horizon")?
            .ok_or_else(|| self.err("sky", "needs `colour`, or `horizon` and `zenith`"))?;
        let zenith = self
            .colour(t, "sky", "zenith")?
            .ok_or_else(|| self.err("sky.zenith", "missing"))?;
        Ok(Sky::Gradient { horizon, zenith })
    }

    fn light(&self, t: &Table) -> Result<Lighting, Error> {
        self.keys(t, "light", &["direction", "colour", "ambient"])?;
        let direction = self
            .required_vec3(t, "light", "direction")?
            .normalized()
            .ok_or_else(|| self.err("light.direction", "must not be zero"))?;
        let c = self
            .colour(t, "light", "colour")?
            .unwrap_or(Rgba::opaque(1.0, 1.0, 1.0));
        let a = self
            .colour(t, "light", "ambient")?
            .unwrap_or(Rgba::opaque(0.1, 0.1, 0.1));
        Ok(Lighting::Lambert {
            direction,
            colour: [c.r, c.g, c.b],
            ambient: [a.r, a.g, a.b],
        })
    }

    /// Shape table `t` (at `key`) as a surface: its geometry by `type`,
    /// then colour, texture, wrap and texture coordinates, checked in that
    /// order (the first error found is the one reported).
    fn surface(&mut self, t: &Table, key: &str) -> Result<Surface, Error> {
        let kind = match t.get("type") {
            Some(Value::String(s)) => s.as_str(),
            _ => {
                return Err(self.err(
                    &format!("{key}.type"),
                    "missing or not a string (plane, quad, sphere)",
                ));
            }
        };
        let geometry = self.geometry(t, key, kind)?;
        let colour = self
            .colour(t, key, "colour")?
            .unwrap_or(Rgba::opaque(1.0, 1.0, 1.0));
        let texture = self.surface_texture(t, key)?;
        let wrap = self.wrap(t, key)?;
        let uv_transform = self.uv_transform(t, key)?;
        Ok(Surface {
            geometry,
            texture,
            colour,
            uv_transform,
            wrap,
        })
    }

    /// A surface's shape, of type `kind`, from its table `t`.
    fn geometry(&mut self, t: &Table, key: &str, kind: &str) -> Result<Geometry, Error> {
        let geometry = match kind {
            "plane" => self.plane(t, key)?,
            "quad" => {
                self.keys(
                    t,
                    key,
                    &[&SURFACE_KEYS[..], &["origin", "edge_u", "edge_v"]].concat(),
                )?;
                let origin = self.required_vec3(t, key, "origin")?;
                let edge_u = self.required_vec3(t, key, "edge_u")?;
                let edge_v = self.required_vec3(t, key, "edge_v")?;
                if edge_u.cross(edge_v).normalized().is_none() {
                    return Err(self.err(
                        &format!("{key}.edge_v"),
                        "is parallel to edge_u (degenerate quad)",
                    ));
                }
                Geometry::Quad {
                    origin,
                    edge_u,
                    edge_v,
                }
            }
            "sphere" => {
                self.keys(t, key, &[&SURFACE_KEYS[..], &["centre", "radius"]].concat())?;
                let centre = self.required_vec3(t, key, "centre")?;
                let radius = self
                    .number(t, key, "radius")?
                    .ok_or_else(|| self.err(&format!("{key}.radius"), "missing"))?;
                if radius <= 0.0 {
                    return Err(self.err(&format!("{key}.radius"), "must be positive"));
                }
                Geometry::Sphere { centre, radius }
            }
            "mesh" => {
                self.keys(
                    t,
                    key,
                    &[&SURFACE_KEYS[..], &["file", "scale", "translate"]].concat(),
                )?;
                let (file, scale, translate) = self.model_file(t, key, "an .obj file")?;
                Geometry::Mesh(Arc::new(self.mesh(
                    &file,
                    scale,
                    translate,
                    &format!("{key}.file"),
                )?))
            }
            other => {
                return Err(self.err(
                    &format!("{key}.type"),
                    &format!("unknown shape `{other}` (plane, quad, sphere, mesh)"),
                ));
            }
        };
        Ok(geometry)
    }

    /// A plane's point, normal and texture axes.
    fn plane(&self, t: &Table, key: &str) -> Result<Geometry, Error> {
        self.keys(
            t,
            key,
            &[&SURFACE_KEYS[..], &["point", "normal", "u_axis"]].concat(),
        )?;
        let point = self.required_vec3(t, key, "point")?;
        let normal = self
            .required_vec3(t, key, "normal")?
            .normalized()
            .ok_or_else(|| self.err(&format!("{key}.normal"), "must not be zero"))?;
        let hint = self
            .vec3(t, key, "u_axis")?
            .unwrap_or(if normal.x.abs() < 0.9 {
                Vec3::new(1.0, 0.0, 0.0)
            } else {
                Vec3::new(0.0, 0.0, 1.0)
            });
        let u_axis = (hint - normal * hint.dot(normal))
            .normalized()
            .ok_or_else(|| self.err(&format!("{key}.u_axis"), "is parallel to the normal"))?;
        // v = u × n: with n = +y and u = +x, v = +z (texture z runs away).
        let v_axis = u_axis.cross(normal);
        Ok(Geometry::Plane {
            point,
            normal,
            u_axis,
            v_axis,
        })
    }

    /// A surface's texture, packed at its `texture_level` (or the default
    /// for its kind) with its `contour_leaves`; `None` when it has none.
    fn surface_texture(&mut self, t: &Table, key: &str) -> Result<Option<SceneTexture>, Error> {
        let svg_level = match self.number(t, key, "texture_level")? {
            None => None,
            Some(l) if l.fract() == 0.0 && (0.0..=f64::from(MAX_VECTOR_LEVEL)).contains(&l) => {
                Some(l as u8)
            }
            Some(l) => {
                return Err(self.err(
                    &format!("{key}.texture_level"),
                    &format!("{l}: must be an integer 0..={MAX_VECTOR_LEVEL}"),
                ));
            }
        };
        let contour_leaves = match self.number(t, key, "contour_leaves")? {
            None => None,
            Some(n) if n.fract() == 0.0 && (3.0..=1024.0).contains(&n) => Some(n as usize),
            Some(n) => {
                return Err(self.err(
                    &format!("{key}.contour_leaves"),
                    &format!("{n}: must be an integer 3..=1024 (edges a contour leaf may hold)"),
                ));
            }
        };
        let svg_level = svg_level.unwrap_or(if contour_leaves.is_some() {
            quadtex_core::CONTOUR_MAX_LEVEL
        } else {
            DEFAULT_SVG_LEVEL
        });
        let texture = match t.get("texture") {
            None => None,
            Some(Value::String(s)) => {
                Some(self.texture(s, &format!("{key}.texture"), svg_level, contour_leaves)?)
            }
            Some(_) => return Err(self.err(&format!("{key}.texture"), "must be a string")),
        };
        Ok(texture)
    }

    /// A surface's `wrap` (one mode, or one per axis) and `border` colour.
    fn wrap(&self, t: &Table, key: &str) -> Result<Wrap, Error> {
        let mode = |v: &Value| match v {
            Value::String(s) => WrapMode::from_name(s),
            _ => None,
        };
        let bad_wrap = || {
            self.err(
                &format!("{key}.wrap"),
                "must be \"repeat\", \"clamp\", \"mirror\", \"border\", or an array of two of them (x, z)",
            )
        };
        let (x, z) = match t.get("wrap") {
            None => (WrapMode::Repeat, WrapMode::Repeat),
            Some(Value::Array(a)) => match a.as_slice() {
                [x, z] => (mode(x).ok_or_else(bad_wrap)?, mode(z).ok_or_else(bad_wrap)?),
                _ => return Err(bad_wrap()),
            },
            Some(v) => {
                let m = mode(v).ok_or_else(bad_wrap)?;
                (m, m)
            }
        };
        // Finite and within ±10⁹ (`Context::colour`), so `Wrap::new`
        // takes it; its error is kept should those limits change.
        let border = self.colour(t, key, "border")?.unwrap_or(Rgba::TRANSPARENT);
        Wrap::new(x, z, border).map_err(|e| self.err(&format!("{key}.border"), &e.to_string()))
    }

    /// A surface's `uv_scale`, `uv_offset` and `uv_rotation`.
    fn uv_transform(&self, t: &Table, key: &str) -> Result<UvTransform, Error> {
        let scale = self.numbers::<2>(t, key, "uv_scale")?.unwrap_or([1.0, 1.0]);
        if scale.contains(&0.0) {
            return Err(self.err(&format!("{key}.uv_scale"), "must not be zero"));
        }
        Ok(UvTransform {
            scale,
            offset: self
                .numbers::<2>(t, key, "uv_offset")?
                .unwrap_or([0.0, 0.0]),
            rotation_degrees: self.number(t, key, "uv_rotation")?.unwrap_or(0.0),
        })
    }

    /// A model shape's `file` (relative to the scene; `kind` names what it
    /// must be in the error), `scale` (default 1) and `translate`.
    fn model_file(&self, t: &Table, key: &str, kind: &str) -> Result<(PathBuf, f64, Vec3), Error> {
        let file = match t.get("file") {
            Some(Value::String(f)) => self.path.parent().unwrap_or(Path::new(".")).join(f),
            _ => {
                return Err(self.err(
                    &format!("{key}.file"),
                    &format!("missing or not a string ({kind})"),
                ));
            }
        };
        let scale = self.number(t, key, "scale")?.unwrap_or(1.0);
        let translate = self.vec3(t, key, "translate")?.unwrap_or_default();
        Ok((file, scale, translate))
    }

    /// The surfaces of a glTF model shape (one per material).
    fn gltf(&mut self, t: &Table, key: &str) -> Result<Vec<Surface>, Error> {
        self.keys(t, key, &["type", "file", "scale", "translate"])?;
        let (file, scale, translate) = self.model_file(t, key, "a .gltf or .glb file")?;
        let fail = |message: String| {
            self.err(
                &format!("{key}.file"),
                &format!("{}: {message}", file.display()),
            )
        };
        let model =
            crate::gltf_scene::load_gltf(&file, scale, translate, &self.limits).map_err(fail)?;
        let options = BuildOptions {
            max_nodes: self.limits.max_nodes,
            max_bytes: Some(self.limits.max_memory),
            ..BuildOptions::default()
        };
        let mut textures = Vec::with_capacity(model.images.len());
        for (i, grid) in model.images.iter().enumerate() {
            let tree = QuadTree::from_texels(grid, &options)
                .map_err(|e| fail(format!("image {i}: {e}")))?
                .0;
            let name = format!("{}#image{i}", file.display());
            textures.push(
                SceneTexture::new(&name, Arc::new(tree)).with_memory_budget(self.limits.max_memory),
            );
        }
        Ok(model
            .parts
            .into_iter()
            .map(|part| Surface {
                geometry: Geometry::Mesh(Arc::new(part.mesh)),
                texture: part.image.map(|i| textures[i].clone()),
                colour: part.colour,
                uv_transform: UvTransform {
                    scale: [1.0, 1.0],
                    offset: [0.0, 0.0],
                    rotation_degrees: 0.0,
                },
                wrap: Wrap::per_axis(part.wrap.0, part.wrap.1),
            })
            .collect())
    }

    fn mesh(
        &self,
        file: &Path,
        scale: f64,
        translate: Vec3,
        key: &str,
    ) -> Result<crate::scene::Mesh, Error> {
        let fail = |message: String| self.err(key, &format!("{}: {message}", file.display()));
        let len = std::fs::metadata(file)
            .map_err(|e| fail(e.to_string()))?
            .len();
        if len > self.limits.max_file_bytes {
            return Err(fail(format!(
                "{len} bytes, above max_file_bytes {}",
                self.limits.max_file_bytes
            )));
        }
        let bytes = std::fs::read(file).map_err(|e| fail(e.to_string()))?;
        parse_obj_with(&bytes, scale, translate, &self.limits).map_err(fail)
    }

    fn texture(
        &mut self,
        spec: &str,
        key: &str,
        svg_level: u8,
        contour_leaves: Option<usize>,
    ) -> Result<SceneTexture, Error> {
        if let Some(name) = spec.strip_prefix("builtin:") {
            return builtin_texture(name).map_err(|e| self.err(key, &e.to_string()));
        }
        let file = self.path.parent().unwrap_or(Path::new(".")).join(spec);
        let cache_key = (file.clone(), svg_level, contour_leaves);
        if let Some(t) = self.textures.get(&cache_key) {
            return Ok(t.clone());
        }
        let ext = file
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let tree = match ext.as_deref() {
            // Mapped, its payload checksum verified at open: workers
            // rendering the same scene share its pages.
            Some("qtx") => {
                quadtex_io::map_qtx(&file, &self.limits)
                    .map_err(|e| self.err(key, &e.to_string()))?
                    .0
            }
            // EXR and Radiance .hdr pack as HDR trees (half floats).
            Some("png" | "jpg" | "jpeg" | "exr" | "hdr") => {
                let grid = quadtex_io::load_texels(&file, &self.limits)
                    .map_err(|e| self.err(key, &e.to_string()))?;
                let options = BuildOptions {
                    max_nodes: self.limits.max_nodes,
                    max_bytes: Some(self.limits.max_memory),
                    ..BuildOptions::default()
                };
                QuadTree::from_texels(&grid, &options)
                    .map_err(|e| self.err(key, &format!("{}: {e}", file.display())))?
                    .0
            }
            Some("svg") => {
                let options = quadtex_io::SvgOptions {
                    vector: quadtex_core::VectorOptions {
                        max_level: svg_level,
                        contour_leaves,
                        ..quadtex_core::VectorOptions::default()
                    },
                    limits: self.limits,
                    // Scenes keep their levels (a texture that does not fit is refused).
                    adjustable: quadtex_core::Adjustable::NONE,
                };
                quadtex_io::pack_svg(&file, &options)
                    .map_err(|e| self.err(key, &e.to_string()))?
                    .0
            }
            _ => {
                return Err(self.err(
                    key,
                    "unknown texture type (use .qtx, .png, .jpg, .exr, .hdr, .svg or builtin:NAME)",
                ));
            }
        };
        let texture =
            SceneTexture::new(spec, Arc::new(tree)).with_memory_budget(self.limits.max_memory);
        self.textures.insert(cache_key, texture.clone());
        Ok(texture)
    }
}

/// Parses Wavefront OBJ bytes into a mesh under `limits` (its triangle
/// count): every face corner needs a texture coordinate (`vt`), every
/// coordinate must be finite; degenerate triangles are skipped. Materials are
/// not read (`mtllib` is ignored). The error is a message (the caller adds
/// the file's name).
pub fn parse_obj(bytes: &[u8], limits: &Limits) -> Result<crate::scene::Mesh, String> {
    parse_obj_with(bytes, 1.0, Vec3::default(), limits)
}

/// Refuses a face (`f`) or line (`l`) element naming an index of magnitude
/// beyond the file's line count (every vertex, texture coordinate and normal
/// takes a line, so it cannot exist). `tobj` computes offsets from such
/// indices with arithmetic that overflows (a panic in debug builds).
fn check_obj_indices(bytes: &[u8]) -> Result<(), String> {
    let lines = bytes.split(|&b| b == b'\n').count() as u64;
    for (n, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let Ok(line) = std::str::from_utf8(line) else {
            continue; // tobj reports the invalid text.
        };
        let mut words = line.split_whitespace();
        if !matches!(words.next(), Some("f" | "l")) {
            continue;
        }
        for index in words.flat_map(|w| w.split('/')) {
            match index.parse::<i64>() {
                Ok(i) if i.unsigned_abs() > lines => {
                    return Err(format!(
                        "line {}: index {i} out of range (the file has {lines} lines)",
                        n + 1
                    ));
                }
                _ => {}
            }
        }
    }
    Ok(())
}

/// As [`parse_obj`], with `scale` then `translate` applied.
fn parse_obj_with(
    bytes: &[u8],
    scale: f64,
    translate: Vec3,
    limits: &Limits,
) -> Result<crate::scene::Mesh, String> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..tobj::LoadOptions::default()
    };
    check_obj_indices(bytes)?;
    // Materials are not used: no material library is read.
    let (models, _) = tobj::load_obj_buf(&mut std::io::Cursor::new(bytes), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| e.to_string())?;
    let count: u64 = models.iter().map(|m| m.mesh.indices.len() as u64 / 3).sum();
    if count > limits.max_mesh_triangles as u64 {
        return Err(format!(
            "{count} triangles, more than max_mesh_triangles {}",
            limits.max_mesh_triangles
        ));
    }
    let bytes = count.saturating_mul(MESH_BYTES_PER_TRIANGLE);
    if bytes > limits.max_memory {
        return Err(format!(
            "{count} triangles need about {} MiB with their hierarchy, above the memory budget of {} MiB (raise --memory-limit)",
            bytes >> 20,
            limits.max_memory >> 20
        ));
    }
    let mut triangles = Vec::with_capacity(count as usize);
    // Corners by position: faces of different models, or on either side
    // of a texture seam, that share a point are neighbours.
    let mut vertices = Vec::with_capacity(count as usize);
    let mut ids = crate::scene::VertexIds::default();
    // Models without faces (vertices only, or an empty file) add nothing.
    for model in models.iter().filter(|m| !m.mesh.indices.is_empty()) {
        let m = &model.mesh;
        if m.texcoords.is_empty() {
            return Err(format!(
                "model `{}` has no texture coordinates (vt)",
                model.name
            ));
        }
        if m.texcoords.len() / 2 != m.positions.len() / 3 {
            return Err(format!(
                "model `{}`: some face corners have no texture coordinate (vt)",
                model.name
            ));
        }
        for tri in m.indices.chunks_exact(3) {
            let mut p = [Vec3::default(); 3];
            let mut uv = [[0.0; 2]; 3];
            for (k, &i) in tri.iter().enumerate() {
                let i = i as usize;
                let (Some(pos), Some(tc)) = (
                    m.positions.get(3 * i..3 * i + 3),
                    m.texcoords.get(2 * i..2 * i + 2),
                ) else {
                    return Err(format!("index {i} out of range"));
                };
                p[k] = Vec3::new(f64::from(pos[0]), f64::from(pos[1]), f64::from(pos[2])) * scale
                    + translate;
                uv[k] = [f64::from(tc[0]), f64::from(tc[1])];
            }
            if !p.iter().all(|v| v.is_finite()) || !uv.iter().flatten().all(|v| v.is_finite()) {
                return Err("non-finite vertex or texture coordinate".into());
            }
            // Degenerate triangles (zero area or collapsed UVs) are skipped.
            if let Some(t) = crate::scene::Triangle::new(p, uv) {
                triangles.push(t);
                vertices.push(p.map(|p| ids.id(p)));
            }
        }
    }
    drop(ids);
    crate::scene::Mesh::with_vertices(triangles, vertices)
        .ok_or_else(|| "no usable triangles".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
[camera]
position = [0, 2, -10]
look_at = [0, 0, 10]
fov = 50
width = 64
height = 32

[sky]
horizon = [0.8, 0.5, 0.3]
zenith = [0.1, 0.1, 0.3]

[[shape]]
type = "plane"
point = [0, 0, 0]
normal = [0, 1, 0]
texture = "builtin:checker"
uv_scale = [0.5, 0.5]
"#;

    fn parse(text: &str) -> Result<Scene, Error> {
        parse_scene(text, Path::new("test.toml"), &quadtex_io::Limits::default())
    }

    #[test]
    fn parses_a_good_scene() {
        let s = parse(GOOD).unwrap();
        assert_eq!((s.camera.width(), s.camera.height()), (64, 32));
        assert_eq!(s.surfaces.len(), 1);
    }

    fn expect(text: &str, needles: &[&str]) {
        let e = parse(text).unwrap_err().to_string();
        for n in needles {
            assert!(e.contains(n), "`{n}` not in: {e}");
        }
    }

    #[test]
    fn limits_are_overridable() {
        let limits = Limits {
            max_scene_shapes: 0,
            ..Limits::default()
        };
        let e = parse_scene(GOOD, Path::new("small.toml"), &limits)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("small.toml") && e.contains("max_scene_shapes 0"),
            "{e}"
        );
        assert!(parse_scene(GOOD, Path::new("ok.toml"), &quadtex_io::Limits::default()).is_ok());
    }

    #[test]
    fn errors_name_file_line_and_key() {
        expect(
            &GOOD.replace("fov = 50", "fov = 50\nzoom = 2"),
            &["test.toml:6:", "camera.zoom", "unknown key"],
        );
        expect(
            &GOOD.replace("position = [0, 2, -10]", "position = [0, nan, -10]"),
            &["test.toml:3:", "camera.position", "finite"],
        );
        expect(
            &GOOD.replace("position = [0, 2, -10]", "position = [0, 2, 1e300]"),
            &["camera.position", "limit"],
        );
        expect(
            &GOOD.replace("width = 64", "width = 0"),
            &["camera.width", "1..=65536"],
        );
        expect(
            &GOOD.replace("look_at = [0, 0, 10]", "look_at = [0, 2, -10]"),
            &["camera.look_at", "coincides"],
        );
        expect(
            &GOOD.replace("fov = 50", "fov = 50\nup = [0, -2, 20]"),
            &["camera.up", "parallel"],
        );
        expect(
            &GOOD.replace("builtin:checker", "missing.qtx"),
            &["shape[0].texture", "missing.qtx"],
        );
        expect(
            &GOOD.replace("builtin:checker", "art.svg"),
            &["shape[0].texture", "art.svg"],
        );
        expect(
            &GOOD.replace(
                "texture = \"builtin:checker\"",
                "texture = \"builtin:checker\"\ntexture_level = 40",
            ),
            &["shape[0].texture_level", "0..=24"],
        );
        expect(
            &GOOD.replace(
                "texture = \"builtin:checker\"",
                "texture = \"builtin:checker\"\ncontour_leaves = 2",
            ),
            &["shape[0].contour_leaves", "3..=1024"],
        );
        expect(
            &GOOD.replace("type = \"plane\"", "type = \"torus\""),
            &["test.toml:14:", "shape[0].type", "torus"],
        );
        expect(
            &GOOD.replace("normal = [0, 1, 0]", "normal = [0, 0, 0]"),
            &["shape[0].normal"],
        );
        expect(
            &GOOD.replace("uv_scale = [0.5, 0.5]", "uv_scale = [0.5]"),
            &["shape[0].uv_scale", "2 numbers"],
        );
        // A border colour past the numbers' limit (and `f32`'s): refused by
        // its key, never kept as an infinite colour.
        expect(
            &GOOD.replace(
                "texture = \"builtin:checker\"",
                "texture = \"builtin:checker\"\nwrap = \"border\"\nborder = [1e39, 0, 0]",
            ),
            &["shape[0].border"],
        );
        expect("[camera\n", &["test.toml:1:", "syntax"]);
        expect(
            &GOOD.replace("[[shape]]", "[[shapes]]"),
            &["shapes", "unknown key"],
        );
    }
}

//! glTF 2.0 models (`.gltf` with its buffers and images, or `.glb`) as
//! scene meshes: one [`Mesh`] per material, with that material's base
//! colour texture (PNG or JPEG, each image packed once) and factor.
//!
//! What is read: the default scene (or the first), its node hierarchy's
//! transforms (matrices or translation/rotation/scale), triangle
//! primitives (lists, strips and fans; points and lines have no area and
//! are skipped), `POSITION`, `TEXCOORD_n` as the base colour texture names
//! it (float, or normalised 8/16-bit), indices (8/16/32-bit), the sampler's
//! wrap modes, buffers inside the `.glb`, in data URIs or in files beside
//! the model. Every accessor is bounds-checked here before it is read.
//! glTF's texture `v` runs down the image; quadtex's `z` runs up, so
//! `z = 1 − v`. Not read: skins, morph targets, animations, cameras,
//! lights, sparse accessors (refused), other material properties.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use quadtex_core::{Rgba, TexelGrid, WrapMode};
use quadtex_io::Limits;

use crate::math::Vec3;
use crate::scene::{Mesh, Triangle, VertexIds};

/// Deepest node hierarchy followed.
const MAX_NODE_DEPTH: usize = 64;

/// One material's part of a model.
pub(crate) struct Part {
    pub mesh: Mesh,
    /// Index into [`Model::images`] of the base colour texture.
    pub image: Option<usize>,
    /// Base colour factor (linear).
    pub colour: Rgba,
    /// The texture sampler's wrap (x, z).
    pub wrap: (WrapMode, WrapMode),
}

/// A model's parts and the images they use, decoded.
pub(crate) struct Model {
    pub parts: Vec<Part>,
    pub images: Vec<TexelGrid>,
}

/// Triangles gathered for one material before they become a mesh.
#[derive(Default)]
struct Gathered {
    triangles: Vec<Triangle>,
    /// Each triangle's corners as vertex ids (by position, across the
    /// material's primitives): which triangles are neighbours.
    vertices: Vec<[u32; 3]>,
    ids: VertexIds,
    image: Option<usize>,
    colour: [f32; 4],
    wrap: (WrapMode, WrapMode),
}

/// Loads the model in `file` (its buffers and images relative to it),
/// vertices transformed by the node hierarchy, then scaled by `scale` and
/// moved by `translate`. The error is a message (the caller names the key).
pub(crate) fn load_gltf(
    file: &Path,
    scale: f64,
    translate: Vec3,
    limits: &Limits,
) -> Result<Model, String> {
    let bytes = read_limited(file, limits)?;
    let gltf = gltf::Gltf::from_slice(&bytes).map_err(|e| format!("not a valid glTF: {e}"))?;
    let mut buffers = Vec::new();
    for buffer in gltf.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| {
                format!(
                    "buffer {} is the binary chunk, which is missing",
                    buffer.index()
                )
            })?,
            gltf::buffer::Source::Uri(uri) => read_uri(uri, file, limits)
                .map_err(|e| format!("buffer {}: {e}", buffer.index()))?,
        };
        if data.len() < buffer.length() {
            return Err(format!(
                "buffer {}: {} bytes, the model declares {}",
                buffer.index(),
                data.len(),
                buffer.length()
            ));
        }
        buffers.push(data);
    }
    let scene = gltf
        .default_scene()
        .or_else(|| gltf.scenes().next())
        .ok_or("the model has no scene")?;
    let identity = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let mut loader = Loader {
        buffers: &buffers,
        limits,
        scale,
        translate,
        by_material: HashMap::new(),
        images: HashMap::new(),
        grids: Vec::new(),
        triangles: 0,
        file,
    };
    for node in scene.nodes() {
        loader.node(&node, identity, 0)?;
    }
    let mut materials: Vec<(Option<usize>, Gathered)> = loader.by_material.into_iter().collect();
    materials.sort_by_key(|(m, _)| m.map_or(0, |m| m + 1));
    let parts = materials
        .into_iter()
        .filter_map(|(_, g)| {
            let [r, gr, b, a] = g.colour;
            // The position map goes before the mesh's own buffers are built.
            drop(g.ids);
            Some(Part {
                mesh: Mesh::with_vertices(g.triangles, g.vertices)?,
                image: g.image,
                colour: Rgba::new(r * a, gr * a, b * a, a),
                wrap: g.wrap,
            })
        })
        .collect::<Vec<_>>();
    if parts.is_empty() {
        return Err("no usable triangles".into());
    }
    Ok(Model {
        parts,
        images: loader.grids,
    })
}

struct Loader<'a> {
    buffers: &'a [Vec<u8>],
    limits: &'a Limits,
    scale: f64,
    translate: Vec3,
    by_material: HashMap<Option<usize>, Gathered>,
    /// glTF image index → index into `grids`.
    images: HashMap<usize, usize>,
    grids: Vec<TexelGrid>,
    triangles: u64,
    /// The model's file (its URIs are resolved against its folder).
    file: &'a Path,
}

type Matrix = [[f32; 4]; 4];

/// `a · b` for column-major 4×4 matrices.
fn multiply(a: &Matrix, b: &Matrix) -> Matrix {
    let mut out = [[0.0f32; 4]; 4];
    for (c, column) in out.iter_mut().enumerate() {
        for (r, value) in column.iter_mut().enumerate() {
            *value = (0..4).map(|k| a[k][r] * b[c][k]).sum();
        }
    }
    out
}

impl Loader<'_> {
    fn node(&mut self, node: &gltf::Node<'_>, parent: Matrix, depth: usize) -> Result<(), String> {
        if depth > MAX_NODE_DEPTH {
            return Err(format!("nodes nested deeper than {MAX_NODE_DEPTH}"));
        }
        let world = multiply(&parent, &node.transform().matrix());
        if let Some(mesh) = node.mesh() {
            for primitive in mesh.primitives() {
                self.primitive(&primitive, &world).map_err(|e| {
                    format!("mesh {} primitive {}: {e}", mesh.index(), primitive.index())
                })?;
            }
        }
        for child in node.children() {
            self.node(&child, world, depth + 1)?;
        }
        Ok(())
    }

    fn primitive(&mut self, primitive: &gltf::Primitive<'_>, world: &Matrix) -> Result<(), String> {
        use gltf::mesh::Mode;
        let mode = primitive.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            return Ok(()); // points and lines have no area
        }
        let positions = primitive
            .get(&gltf::Semantic::Positions)
            .ok_or("no POSITION attribute")?;
        let positions = read_floats::<3>(&positions, self.buffers, "POSITION")?;
        let material = primitive.material();
        let texture = material.pbr_metallic_roughness().base_color_texture();
        let uvs = match &texture {
            Some(info) => {
                let set = info.tex_coord();
                let accessor = primitive
                    .get(&gltf::Semantic::TexCoords(set))
                    .ok_or_else(|| {
                        format!("the base colour texture uses TEXCOORD_{set}, which is missing")
                    })?;
                let uv = read_floats::<2>(&accessor, self.buffers, "TEXCOORD")?;
                if uv.len() != positions.len() {
                    return Err(format!(
                        "{} texture coordinates for {} positions",
                        uv.len(),
                        positions.len()
                    ));
                }
                Some(uv)
            }
            None => None,
        };
        let indices: Vec<u32> = match primitive.indices() {
            Some(accessor) => read_indices(&accessor, self.buffers)?,
            None => (0..positions.len() as u32).collect(),
        };
        if let Some(&i) = indices.iter().find(|&&i| i as usize >= positions.len()) {
            return Err(format!(
                "index {i} out of range ({} vertices)",
                positions.len()
            ));
        }
        let corners: Vec<[u32; 3]> = match mode {
            Mode::Triangles => indices
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect(),
            Mode::TriangleStrip => (2..indices.len())
                .map(|k| {
                    let (a, b, c) = (indices[k - 2], indices[k - 1], indices[k]);
                    if k % 2 == 0 { [a, b, c] } else { [b, a, c] }
                })
                .collect(),
            _ => (2..indices.len())
                .map(|k| [indices[0], indices[k - 1], indices[k]])
                .collect(),
        };
        self.triangles += corners.len() as u64;
        if self.triangles > self.limits.max_mesh_triangles as u64 {
            return Err(format!(
                "more than max_mesh_triangles {} triangles",
                self.limits.max_mesh_triangles
            ));
        }
        let bytes = self
            .triangles
            .saturating_mul(crate::scene::MESH_BYTES_PER_TRIANGLE);
        if bytes > self.limits.max_memory {
            return Err(format!(
                "{} triangles need about {} MiB with their hierarchy, above the memory budget of {} MiB (raise --memory-limit)",
                self.triangles,
                bytes >> 20,
                self.limits.max_memory >> 20
            ));
        }
        let image = match &texture {
            Some(info) => Some(self.image(&info.texture().source())?),
            None => None,
        };
        let wrap = texture
            .as_ref()
            .map_or((WrapMode::Repeat, WrapMode::Repeat), |info| {
                let sampler = info.texture().sampler();
                (wrap_mode(sampler.wrap_s()), wrap_mode(sampler.wrap_t()))
            });
        let to_world = |p: [f32; 3]| {
            let m = world;
            let c =
                |r: usize| f64::from(m[0][r] * p[0] + m[1][r] * p[1] + m[2][r] * p[2] + m[3][r]);
            Vec3::new(c(0), c(1), c(2)) * self.scale + self.translate
        };
        let points: Vec<Vec3> = positions.iter().map(|&p| to_world(p)).collect();
        if !points.iter().all(|p| p.is_finite()) {
            return Err("non-finite vertex".into());
        }
        let gathered = self
            .by_material
            .entry(material.index())
            .or_insert_with(|| Gathered {
                colour: material.pbr_metallic_roughness().base_color_factor(),
                image,
                wrap,
                ..Gathered::default()
            });
        gathered.triangles.reserve(corners.len());
        gathered.vertices.reserve(corners.len());
        let point_ids: Vec<u32> = points.iter().map(|&p| gathered.ids.id(p)).collect();
        for [a, b, c] in corners {
            let p = [points[a as usize], points[b as usize], points[c as usize]];
            let uv = match &uvs {
                // glTF's v runs down the image, quadtex's z up.
                Some(uv) => [a, b, c].map(|i| {
                    let t = uv[i as usize];
                    [f64::from(t[0]), 1.0 - f64::from(t[1])]
                }),
                // Untextured: any non-degenerate map will do (the plane's x, z).
                None => [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
            };
            if !uv.iter().flatten().all(|v| v.is_finite()) {
                return Err("non-finite texture coordinate".into());
            }
            // Degenerate triangles (zero area, collapsed UVs) are skipped.
            if let Some(t) = Triangle::new(p, uv) {
                gathered.triangles.push(t);
                gathered
                    .vertices
                    .push([a, b, c].map(|i| point_ids[i as usize]));
            }
        }
        Ok(())
    }

    /// The index into `grids` of glTF image `image`, decoded on first use.
    fn image(&mut self, image: &gltf::Image<'_>) -> Result<usize, String> {
        if let Some(&i) = self.images.get(&image.index()) {
            return Ok(i);
        }
        let name = PathBuf::from(format!("image {}", image.index()));
        let data = match image.source() {
            gltf::image::Source::View { view, .. } => {
                let buffer = &self.buffers[view.buffer().index()];
                view.offset()
                    .checked_add(view.length())
                    .and_then(|end| buffer.get(view.offset()..end))
                    .ok_or_else(|| {
                        format!(
                            "image {}: its buffer view runs past its buffer",
                            image.index()
                        )
                    })?
                    .to_vec()
            }
            gltf::image::Source::Uri { uri, .. } => read_uri(uri, self.file, self.limits)
                .map_err(|e| format!("image {}: {e}", image.index()))?,
        };
        let grid = quadtex_io::load_texels_from_bytes(&data, &name, self.limits)
            .map_err(|e| e.to_string())?;
        self.grids.push(grid);
        self.images.insert(image.index(), self.grids.len() - 1);
        Ok(self.grids.len() - 1)
    }
}

fn wrap_mode(mode: gltf::texture::WrappingMode) -> WrapMode {
    match mode {
        gltf::texture::WrappingMode::ClampToEdge => WrapMode::Clamp,
        gltf::texture::WrappingMode::MirroredRepeat => WrapMode::Mirror,
        gltf::texture::WrappingMode::Repeat => WrapMode::Repeat,
    }
}

/// The bytes of the accessor's elements, each `size` bytes at `stride`,
/// after checking every bound (no sparse accessors).
fn elements<'b>(
    accessor: &gltf::Accessor<'_>,
    buffers: &'b [Vec<u8>],
    what: &str,
) -> Result<(&'b [u8], usize, usize), String> {
    if accessor.sparse().is_some() {
        return Err(format!("{what}: sparse accessors are not supported"));
    }
    let view = accessor
        .view()
        .ok_or_else(|| format!("{what}: the accessor has no buffer view"))?;
    let buffer = &buffers[view.buffer().index()];
    let data = view
        .offset()
        .checked_add(view.length())
        .and_then(|end| buffer.get(view.offset()..end))
        .ok_or_else(|| format!("{what}: its buffer view runs past its buffer"))?;
    let size = accessor.size();
    let stride = view.stride().unwrap_or(size);
    if stride < size {
        return Err(format!(
            "{what}: stride {stride} is below the element size {size}"
        ));
    }
    let count = accessor.count();
    let end = count
        .checked_sub(1)
        .and_then(|n| n.checked_mul(stride))
        .and_then(|n| n.checked_add(size))
        .and_then(|n| n.checked_add(accessor.offset()));
    match end {
        Some(end) if end <= data.len() => Ok((&data[accessor.offset()..], stride, count)),
        Some(_) | None if count == 0 => Ok((&[], stride, 0)),
        _ => Err(format!(
            "{what}: {count} elements run past their buffer view ({} bytes)",
            data.len()
        )),
    }
}

/// An accessor of `N` components as floats: `f32`, or normalised unsigned
/// 8/16-bit integers.
fn read_floats<const N: usize>(
    accessor: &gltf::Accessor<'_>,
    buffers: &[Vec<u8>],
    what: &str,
) -> Result<Vec<[f32; N]>, String> {
    use gltf::accessor::{DataType, Dimensions};
    let expected = if N == 3 {
        Dimensions::Vec3
    } else {
        Dimensions::Vec2
    };
    if accessor.dimensions() != expected {
        return Err(format!(
            "{what}: expected {expected:?}, found {:?}",
            accessor.dimensions()
        ));
    }
    let (data, stride, count) = elements(accessor, buffers, what)?;
    let component = |e: &[u8], k: usize| -> Result<f32, String> {
        Ok(match accessor.data_type() {
            DataType::F32 => {
                f32::from_le_bytes([e[4 * k], e[4 * k + 1], e[4 * k + 2], e[4 * k + 3]])
            }
            DataType::U8 if accessor.normalized() => f32::from(e[k]) / 255.0,
            DataType::U16 if accessor.normalized() => {
                f32::from(u16::from_le_bytes([e[2 * k], e[2 * k + 1]])) / 65535.0
            }
            other => {
                return Err(format!(
                    "{what}: components of type {other:?} are not supported"
                ));
            }
        })
    };
    let mut out = Vec::with_capacity(count);
    for i in 0..count {
        let e = &data[i * stride..];
        let mut v = [0.0f32; N];
        for (k, slot) in v.iter_mut().enumerate() {
            *slot = component(e, k)?;
        }
        out.push(v);
    }
    Ok(out)
}

/// An index accessor (unsigned 8, 16 or 32-bit scalars).
fn read_indices(accessor: &gltf::Accessor<'_>, buffers: &[Vec<u8>]) -> Result<Vec<u32>, String> {
    use gltf::accessor::{DataType, Dimensions};
    if accessor.dimensions() != Dimensions::Scalar {
        return Err("indices: expected scalars".into());
    }
    let (data, stride, count) = elements(accessor, buffers, "indices")?;
    let read: fn(&[u8]) -> u32 = match accessor.data_type() {
        DataType::U8 => |e| u32::from(e[0]),
        DataType::U16 => |e| u32::from(u16::from_le_bytes([e[0], e[1]])),
        DataType::U32 => |e| u32::from_le_bytes([e[0], e[1], e[2], e[3]]),
        other => return Err(format!("indices of type {other:?} are not supported")),
    };
    Ok((0..count).map(|i| read(&data[i * stride..])).collect())
}

/// A file's bytes, refused beyond [`Limits::max_file_bytes`].
fn read_limited(file: &Path, limits: &Limits) -> Result<Vec<u8>, String> {
    let len = std::fs::metadata(file).map_err(|e| e.to_string())?.len();
    if len > limits.max_file_bytes {
        return Err(format!(
            "{len} bytes, above max_file_bytes {}",
            limits.max_file_bytes
        ));
    }
    std::fs::read(file).map_err(|e| e.to_string())
}

/// The bytes a buffer or image URI of the model in `model` names: a base64
/// data URI, or a file relative to the model's folder that
/// [`Limits::external_resources`] lets it read (percent-escapes are not
/// decoded; remote URLs are refused).
fn read_uri(uri: &str, model: &Path, limits: &Limits) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest
            .split_once(";base64,")
            .ok_or("a data URI that is not base64")?;
        if payload.len() as u64 / 4 * 3 > limits.max_file_bytes {
            return Err("a data URI above max_file_bytes".into());
        }
        return decode_base64(payload);
    }
    if uri.contains("://") {
        return Err(format!("\"{uri}\" is remote (not fetched)"));
    }
    let file = limits
        .external_resources
        .resolve(model, uri)
        .map_err(|e| e.to_string())?;
    read_limited(&file, limits).map_err(|e| format!("{}: {e}", file.display()))
}

/// Standard base64 (padding optional, no whitespace).
fn decode_base64(text: &str) -> Result<Vec<u8>, String> {
    let value = |c: u8| -> Result<u32, String> {
        Ok(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return Err(format!("invalid base64 character {:?}", c as char)),
        }
        .into())
    };
    let text = text.trim_end_matches('=').as_bytes();
    let mut out = Vec::with_capacity(text.len() / 4 * 3 + 2);
    for chunk in text.chunks(4) {
        let mut n = 0u32;
        for (k, &c) in chunk.iter().enumerate() {
            n |= value(c)? << (18 - 6 * k);
        }
        let bytes = n.to_be_bytes();
        match chunk.len() {
            4 => out.extend_from_slice(&bytes[1..4]),
            3 => out.extend_from_slice(&bytes[1..3]),
            2 => out.push(bytes[1]),
            _ => return Err("truncated base64".into()),
        }
    }
    Ok(out)
}

/// Writes one textured triangle mesh as binary glTF (`.glb`): `positions`
/// and `uvs` (glTF's `v` down the image) per vertex, `indices` in threes,
/// and the base colour texture as PNG bytes (clamped at the edges), if
/// any. For generated test scenes and examples; atomic (temporary file,
/// then rename).
pub fn write_glb(
    path: &Path,
    positions: &[[f32; 3]],
    uvs: &[[f32; 2]],
    indices: &[u32],
    png: Option<&[u8]>,
) -> std::io::Result<()> {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut push = |bytes: &[u8], bin: &mut Vec<u8>| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        views.push(format!(
            "{{\"buffer\":0,\"byteOffset\":{},\"byteLength\":{}}}",
            bin.len(),
            bytes.len()
        ));
        bin.extend_from_slice(bytes);
    };
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let floats = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    push(&floats(positions.as_flattened()), &mut bin);
    push(&floats(uvs.as_flattened()), &mut bin);
    push(
        &indices
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect::<Vec<u8>>(),
        &mut bin,
    );
    if let Some(png) = png {
        push(png, &mut bin);
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let (material, texture) = if png.is_some() {
        (
            ",\"material\":0",
            ",\"materials\":[{\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":0}}}],\"textures\":[{\"source\":0,\"sampler\":0}],\"samplers\":[{\"wrapS\":33071,\"wrapT\":33071}],\"images\":[{\"bufferView\":3,\"mimeType\":\"image/png\"}]",
        )
    } else {
        ("", "")
    };
    let mut json = format!(
        "{{\"asset\":{{\"version\":\"2.0\"}},\"scene\":0,\"scenes\":[{{\"nodes\":[0]}}],\"nodes\":[{{\"mesh\":0}}],\"meshes\":[{{\"primitives\":[{{\"attributes\":{{\"POSITION\":0,\"TEXCOORD_0\":1}},\"indices\":2{material}}}]}}]{texture},\"buffers\":[{{\"byteLength\":{}}}],\"bufferViews\":[{}],\"accessors\":[{{\"bufferView\":0,\"componentType\":5126,\"count\":{},\"type\":\"VEC3\",\"min\":[{},{},{}],\"max\":[{},{},{}]}},{{\"bufferView\":1,\"componentType\":5126,\"count\":{},\"type\":\"VEC2\"}},{{\"bufferView\":2,\"componentType\":5125,\"count\":{},\"type\":\"SCALAR\"}}]}}",
        bin.len(),
        views.join(","),
        positions.len(),
        lo[0],
        lo[1],
        lo[2],
        hi[0],
        hi[1],
        hi[2],
        uvs.len(),
        indices.len()
    )
    .into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut out = Vec::with_capacity(28 + json.len() + bin.len());
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((28 + json.len() + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    let tmp = path.with_extension("glb.tmp");
    std::fs::write(&tmp, &out)?;
    std::fs::rename(&tmp, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_decodes_and_refuses_garbage() {
        assert_eq!(decode_base64("aGVsbG8=").unwrap(), b"hello");
        assert_eq!(decode_base64("aGVsbG8").unwrap(), b"hello");
        assert_eq!(decode_base64("AAEC").unwrap(), [0, 1, 2]);
        assert!(decode_base64("a$bc").is_err());
        assert!(decode_base64("a").is_err());
    }

    /// A textured triangle as a `.gltf` in `tmp/<name>/model/m.gltf`
    /// whose buffer is the file `buffer_uri` and image the file
    /// `image_uri` (both written at `tmp/<name>/outside.*` and beside the
    /// model as `inside.*`); returns the model's path.
    fn external_model(name: &str, buffer_uri: &str, image_uri: &str) -> PathBuf {
        let root = std::env::temp_dir().join(format!("quadtex-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let model = root.join("model");
        std::fs::create_dir_all(&model).unwrap();
        let glb = root.join("t.glb");
        // A 2 × 2 RGB PNG.
        let png = decode_base64("iVBORw0KGgoAAAANSUhEUgAAAAIAAAACCAIAAAD91JpzAAAAEklEQVR4nGP4z8DAAMIM/4EAAB/uBfsL2WiLAAAAAElFTkSuQmCC").unwrap();
        write_glb(
            &glb,
            &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]],
            &[[0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
            &[0, 1, 2],
            Some(&png),
        )
        .unwrap();
        let bytes = std::fs::read(&glb).unwrap();
        let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let json = String::from_utf8(bytes[20..20 + json_len].to_vec()).unwrap();
        let bin = &bytes[20 + json_len + 8..];
        for dir in [&root, &model] {
            let stem = if dir == &root { "outside" } else { "inside" };
            std::fs::write(dir.join(format!("{stem}.bin")), bin).unwrap();
            std::fs::write(dir.join(format!("{stem}.png")), &png).unwrap();
        }
        let json = json
            .replacen(
                "\"buffers\":[{",
                &format!("\"buffers\":[{{\"uri\":\"{buffer_uri}\","),
                1,
            )
            .replacen(
                "\"images\":[{\"bufferView\":3,\"mimeType\":\"image/png\"}]",
                &format!("\"images\":[{{\"uri\":\"{image_uri}\"}}]"),
                1,
            );
        assert!(
            json.contains(buffer_uri) && json.contains(image_uri),
            "{json}"
        );
        let file = model.join("m.gltf");
        std::fs::write(&file, json.trim_end()).unwrap();
        file
    }

    fn load(file: &Path, policy: quadtex_io::ExternalResources) -> Result<Model, String> {
        let limits = Limits {
            external_resources: policy,
            ..Limits::default()
        };
        load_gltf(file, 1.0, Vec3::default(), &limits)
    }

    #[test]
    fn uris_outside_the_model_folder_are_refused_by_default() {
        use quadtex_io::ExternalResources::{Anywhere, None, SameFolder};
        let inside = external_model("gltf-in", "inside.bin", "inside.png");
        let model = load(&inside, SameFolder).unwrap();
        assert_eq!((model.parts.len(), model.images.len()), (1, 1));
        let e = load(&inside, None).err().unwrap();
        assert!(
            e.contains("m.gltf") && e.contains("\"inside.bin\" refused"),
            "{e}"
        );
        for (name, buffer, image, refused) in [
            (
                "gltf-buffer",
                "../outside.bin",
                "inside.png",
                "../outside.bin",
            ),
            (
                "gltf-image",
                "inside.bin",
                "../outside.png",
                "../outside.png",
            ),
        ] {
            let file = external_model(name, buffer, image);
            let e = load(&file, SameFolder).err().unwrap();
            assert!(
                e.contains("m.gltf") && e.contains(&format!("\"{refused}\" refused")),
                "{e}"
            );
            let model = load(&file, Anywhere).unwrap();
            assert_eq!((model.parts.len(), model.images.len()), (1, 1));
            std::fs::remove_dir_all(file.parent().unwrap().parent().unwrap()).unwrap();
        }
        std::fs::remove_dir_all(inside.parent().unwrap().parent().unwrap()).unwrap();
    }

    #[test]
    fn matrices_compose_column_major() {
        // Translate by (1, 2, 3) after scaling by 2.
        let t = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [1.0, 2.0, 3.0, 1.0],
        ];
        let s = [
            [2.0, 0.0, 0.0, 0.0],
            [0.0, 2.0, 0.0, 0.0],
            [0.0, 0.0, 2.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let m = multiply(&t, &s);
        assert_eq!(m[3], [1.0, 2.0, 3.0, 1.0]);
        assert_eq!(m[0][0], 2.0);
    }
}

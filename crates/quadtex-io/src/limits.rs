/// Resource limits applied while reading files, checked before any
/// allocation they bound. The defaults suit this project's 24 GiB machines;
/// embedders lower them (`Limits { max_nodes: 1 << 20, ..Limits::default() }`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Largest image width or height, in texels (default 32768, the raster
    /// builder's deepest grid).
    pub max_dimension: u32,
    /// Largest input file, in bytes (default 16 GiB).
    pub max_file_bytes: u64,
    /// Most nodes in a tree (default [`quadtex_core::MAX_NODES`], 2³¹).
    pub max_nodes: u64,
    /// Deepest tree level (default [`quadtex_core::MAX_DEPTH`], 30).
    pub max_depth: u8,
    /// Most elements in an SVG document, counted with every `use` expanded
    /// (default 100 000; `usvg` itself stops at 1 000 000).
    pub max_svg_elements: u64,
    /// Most shapes in a scene (default 10 000).
    pub max_scene_shapes: usize,
    /// Most triangles in one mesh of a scene (default 20 000: meshes are
    /// intersected without an acceleration structure).
    pub max_mesh_triangles: usize,
}

impl Limits {
    /// Refuses a file of `len` bytes above [`Limits::max_file_bytes`].
    pub(crate) fn check_file_size(
        &self,
        path: &std::path::Path,
        len: u64,
    ) -> Result<(), crate::Error> {
        if len > self.max_file_bytes {
            return Err(crate::Error::Limit {
                path: path.to_path_buf(),
                limit: "max_file_bytes",
                value: len,
                max: self.max_file_bytes,
            });
        }
        Ok(())
    }
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_dimension: 32768,
            max_file_bytes: 16 << 30,
            max_nodes: quadtex_core::MAX_NODES,
            max_depth: quadtex_core::MAX_DEPTH,
            max_svg_elements: 100_000,
            max_scene_shapes: 10_000,
            max_mesh_triangles: 20_000,
        }
    }
}

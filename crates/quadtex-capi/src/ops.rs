//! What the exported functions do, in safe Rust: opening and packing
//! textures, checking options and footprints, filtering.

use std::path::{Path, PathBuf};

use quadtex_core::MAX_VECTOR_LEVEL;
use quadtex_core::{
    BuildOptions, FilterOptions, Footprint, MAX_DEPTH, QuadTree, Rgba, Texture, Threads, Weighting,
    Wrap, WrapMode,
};

use crate::error::Failure;
use crate::{
    QTX_DEFAULT_SVG_LEVEL, QtxFilterOptions, QtxLevel, QtxResources, QtxSvgOptions, QtxTexture,
    QtxTextureInfo, QtxWeighting, QtxWrapMode,
};

/// A C string's bytes as a path. On Unix a file name is any bytes, so any
/// bytes are accepted; elsewhere the path must be UTF-8.
pub(crate) fn bytes_to_path(bytes: &[u8], name: &str) -> Result<PathBuf, Failure> {
    if bytes.is_empty() {
        return Err(Failure::invalid(format!("{name} is empty")));
    }
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        Ok(PathBuf::from(std::ffi::OsStr::from_bytes(bytes)))
    }
    #[cfg(not(unix))]
    {
        std::str::from_utf8(bytes).map(PathBuf::from).map_err(|e| {
            Failure::invalid(format!(
                "{name} is not valid UTF-8 (byte {})",
                e.valid_up_to()
            ))
        })
    }
}

/// Reads a `.qtx` file; repeat wrap (the filter options choose the wrap).
pub(crate) fn open(path: &Path) -> Result<QtxTexture, Failure> {
    let tree = quadtex_io::read_qtx(path, &quadtex_io::Limits::default())?.0;
    Ok(QtxTexture::new(tree))
}

/// Maps a `.qtx` file (structure and payload checksum checked, colours
/// read on demand).
pub(crate) fn open_mapped(path: &Path) -> Result<QtxTexture, Failure> {
    let (tree, _) = quadtex_io::map_qtx(path, &quadtex_io::Limits::default())?;
    Ok(QtxTexture::new(tree))
}

/// Maps a trusted `.qtx` file (structure checked, colours read on demand,
/// their checksum not checked).
pub(crate) fn open_mapped_unverified(path: &Path) -> Result<QtxTexture, Failure> {
    let (tree, _) = quadtex_io::map_qtx_unverified(path, &quadtex_io::Limits::default())?;
    Ok(QtxTexture::new(tree))
}

fn is_svg(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
}

/// Packs an image (PNG, JPEG, OpenEXR) or SVG art, as `quadtex pack` does:
/// raster tolerance in `[0, 1]`, SVG exact (tolerance 0) at `max_level`
/// (default 12, at most 24); raster `max_level` at most 30 (default: the
/// image's natural depth).
/// `qtx_pack_tiles`: a folder of `ROW_COL` tiles, as `quadtex pack-tiles`.
pub(crate) fn pack_tiles(
    dir: &Path,
    tolerance: f64,
    memory_limit: u64,
) -> Result<QtxTexture, Failure> {
    if !(tolerance.is_finite() && (0.0..=1.0).contains(&tolerance)) {
        return Err(Failure::invalid(format!(
            "{}: tolerance must be in [0, 1], got {tolerance}",
            dir.display()
        )));
    }
    let (tree, _, _) = quadtex_io::pack_tiles(dir, tolerance, &limits(memory_limit))?;
    Ok(QtxTexture::new(tree))
}

pub(crate) fn pack(
    path: &Path,
    tolerance: f64,
    max_level: i32,
    memory_limit: u64,
) -> Result<QtxTexture, Failure> {
    let shown = path.display();
    let limits = limits(memory_limit);
    let level = if max_level < 0 { None } else { Some(max_level) };
    if is_svg(path) {
        if tolerance != 0.0 {
            return Err(Failure::invalid(format!(
                "{shown}: tolerance ({tolerance}) applies to raster images; SVG art packs exactly, pass 0"
            )));
        }
        let level = match level {
            None => QTX_DEFAULT_SVG_LEVEL as u8,
            Some(l) => svg_level(l).ok_or_else(|| {
                Failure::invalid(format!(
                    "{shown}: max_level {l} exceeds the vector packer's limit {MAX_VECTOR_LEVEL}"
                ))
            })?,
        };
        let options = quadtex_io::SvgOptions {
            limits,
            // As `quadtex pack`: `QTX_LEVEL_AUTO` is lowered to fit the budget.
            adjustable: quadtex_core::Adjustable {
                max_level: max_level < 0,
                contour_edges: false,
            },
            ..quadtex_io::SvgOptions::at_level(level)
        };
        let (tree, _) = quadtex_io::pack_svg(path, &options)?;
        return Ok(QtxTexture::new(tree));
    }
    if !(tolerance.is_finite() && (0.0..=1.0).contains(&tolerance)) {
        return Err(Failure::invalid(format!(
            "{shown}: tolerance must be in [0, 1], got {tolerance}"
        )));
    }
    let max_level = match level {
        None => None,
        Some(l) => Some(
            u8::try_from(l)
                .ok()
                .filter(|&l| l <= MAX_DEPTH)
                .ok_or_else(|| {
                    Failure::invalid(format!(
                        "{shown}: max_level {l} exceeds the maximum depth {MAX_DEPTH}"
                    ))
                })?,
        ),
    };
    let grid = quadtex_io::load_texels(path, &limits)?;
    let options = BuildOptions {
        tolerance,
        max_level,
        max_nodes: limits.max_nodes,
        max_bytes: Some(limits.max_memory),
        ..BuildOptions::default()
    };
    let (tree, _) = QuadTree::from_texels(&grid, &options)
        .map_err(|e| Failure::from(e).context(&shown.to_string()))?;
    Ok(QtxTexture::new(tree))
}

/// The default limits (as the CLI's), with `memory_limit` bytes as the
/// memory budget unless 0 (`--memory-limit`).
fn limits(memory_limit: u64) -> quadtex_io::Limits {
    let mut limits = quadtex_io::Limits::default();
    if memory_limit > 0 {
        limits.max_memory = memory_limit;
    }
    limits
}

/// `level` if SVG art can be packed at it (0..=`MAX_VECTOR_LEVEL`).
fn svg_level(level: i32) -> Option<u8> {
    u8::try_from(level).ok().filter(|&l| l <= MAX_VECTOR_LEVEL)
}

/// `qtx_svg_options_default`: as `quadtex pack` packs SVG by default.
pub(crate) fn default_svg_options() -> QtxSvgOptions {
    QtxSvgOptions {
        max_level: QtxLevel::Auto as i32,
        contour_leaves: 0,
        max_sweep_work: quadtex_core::DEFAULT_MAX_SWEEP_WORK,
        memory_limit: 0,
        resources: QtxResources::SameFolder as i32,
    }
}

/// `qtx_pack_svg`: SVG art with every packing option checked first.
pub(crate) fn pack_svg(path: &Path, options: &QtxSvgOptions) -> Result<QtxTexture, Failure> {
    let shown = path.display();
    if !is_svg(path) {
        return Err(Failure::invalid(format!(
            "{shown}: qtx_pack_svg packs SVG art (.svg); use qtx_pack for raster images"
        )));
    }
    let contour_leaves = match options.contour_leaves {
        0 => None,
        n @ 3..=1024 => Some(n as usize),
        n => {
            return Err(Failure::invalid(format!(
                "options.contour_leaves must be 0 (none) or in 3..=1024, got {n}"
            )));
        }
    };
    let level_auto = options.max_level < 0;
    let max_level = match options.max_level {
        l if l < 0 => match contour_leaves {
            Some(_) => quadtex_core::CONTOUR_MAX_LEVEL,
            None => QTX_DEFAULT_SVG_LEVEL as u8,
        },
        l => svg_level(l).ok_or_else(|| {
            Failure::invalid(format!(
                "options.max_level must be QTX_LEVEL_AUTO or in 0..={MAX_VECTOR_LEVEL}, got {l}"
            ))
        })?,
    };
    if options.max_sweep_work == 0 {
        return Err(Failure::invalid(
            "options.max_sweep_work must be at least 1 (steps of the exact sweep), got 0",
        ));
    }
    let external_resources = match options.resources {
        r if r == QtxResources::SameFolder as i32 => quadtex_io::ExternalResources::SameFolder,
        r if r == QtxResources::Anywhere as i32 => quadtex_io::ExternalResources::Anywhere,
        r if r == QtxResources::None as i32 => quadtex_io::ExternalResources::None,
        r => {
            return Err(Failure::invalid(format!(
                "options.resources must be QTX_RESOURCES_SAME_FOLDER (0), \
                 QTX_RESOURCES_ANYWHERE (1) or QTX_RESOURCES_NONE (2), got {r}"
            )));
        }
    };
    let options = quadtex_io::SvgOptions {
        vector: quadtex_core::VectorOptions {
            max_level,
            contour_leaves,
            max_sweep_work: options.max_sweep_work,
            ..quadtex_core::VectorOptions::default()
        },
        limits: quadtex_io::Limits {
            external_resources,
            ..limits(options.memory_limit)
        },
        // As `quadtex pack`: `QTX_LEVEL_AUTO` is lowered to fit the budget.
        adjustable: quadtex_core::Adjustable {
            max_level: level_auto,
            contour_edges: false,
        },
    };
    let (tree, _) = quadtex_io::pack_svg(path, &options)?;
    Ok(QtxTexture::new(tree))
}

/// The defaults: repeat on both axes, transparent border, screen weighting,
/// error bound 1/512, automatic level.
pub(crate) fn default_options() -> QtxFilterOptions {
    let defaults = FilterOptions::default();
    QtxFilterOptions {
        wrap_x: QtxWrapMode::Repeat as i32,
        wrap_z: QtxWrapMode::Repeat as i32,
        border: [0.0; 4],
        weighting: QtxWeighting::Screen as i32,
        error_bound: match defaults.level_of_detail() {
            quadtex_core::LevelOfDetail::ErrorBound(e) => e,
            quadtex_core::LevelOfDetail::Fixed(_) => 1.0 / 512.0,
        },
        level: QtxLevel::Auto as i32,
        threads: 0,
    }
}

fn wrap_mode(value: i32, field: &str) -> Result<WrapMode, Failure> {
    match value {
        v if v == QtxWrapMode::Repeat as i32 => Ok(WrapMode::Repeat),
        v if v == QtxWrapMode::Clamp as i32 => Ok(WrapMode::Clamp),
        v if v == QtxWrapMode::Mirror as i32 => Ok(WrapMode::Mirror),
        v if v == QtxWrapMode::Border as i32 => Ok(WrapMode::Border),
        v => Err(Failure::invalid(format!(
            "options.{field} must be a QtxWrapMode (0 repeat, 1 clamp, 2 mirror, 3 border), got {v}"
        ))),
    }
}

/// The C options checked and converted; every message names the field
/// (`options.weighting`).
pub(crate) fn convert_options(
    o: &QtxFilterOptions,
) -> Result<(Wrap, FilterOptions, Threads), Failure> {
    let x = wrap_mode(o.wrap_x, "wrap_x")?;
    let z = wrap_mode(o.wrap_z, "wrap_z")?;
    for (i, &c) in o.border.iter().enumerate() {
        if !c.is_finite() {
            return Err(Failure::invalid(format!(
                "options.border[{i}] is not finite ({c})"
            )));
        }
    }
    let [r, g, b, a] = o.border;
    // Checked above; `Wrap::new`'s own error is kept in the options' form.
    let wrap = Wrap::new(x, z, Rgba::new(r, g, b, a))
        .map_err(|e| Failure::invalid(format!("options.{e}")))?;
    let weighting = match o.weighting {
        v if v == QtxWeighting::Screen as i32 => Weighting::Screen,
        v if v == QtxWeighting::Texture as i32 => Weighting::Texture,
        v => {
            return Err(Failure::invalid(format!(
                "options.weighting must be a QtxWeighting (0 screen, 1 texture), got {v}"
            )));
        }
    };
    let option = |e: quadtex_core::Error| Failure::from(e).context("options");
    let mut options = FilterOptions::default()
        .with_weighting(weighting)
        .with_error_bound(o.error_bound)
        .map_err(option)?;
    if o.level != QtxLevel::Auto as i32 {
        let level = u8::try_from(o.level)
            .ok()
            .filter(|&l| l <= MAX_DEPTH)
            .ok_or_else(|| {
                Failure::invalid(format!(
                    "options.level must be QTX_LEVEL_AUTO (-1) or in 0..={MAX_DEPTH}, got {}",
                    o.level
                ))
            })?;
        options = options.with_level(level);
    }
    let threads = usize::try_from(o.threads).map_err(|_| {
        Failure::invalid(format!(
            "options.threads must be 0 (one a core) or at least 1, got {}",
            o.threads
        ))
    })?;
    Ok((wrap, options, Threads::from_count(threads)))
}

/// Whether two buffers, given as address and length in bytes, share a byte.
pub(crate) fn overlap(a: usize, a_bytes: usize, b: usize, b_bytes: usize) -> bool {
    a_bytes > 0 && b_bytes > 0 && a < b.saturating_add(b_bytes) && b < a.saturating_add(a_bytes)
}

/// Filters the footprints in `quads` (8 numbers each) into `out` (4 each).
/// Every quad is checked before any is filtered, so on failure `out` is
/// untouched; the message names the quad and the corner (`quad 3:
/// coordinate corner[2].z is not finite (NaN)`).
pub(crate) fn filter(
    texture: &QtxTexture,
    quads: &[f64],
    options: &QtxFilterOptions,
    out: &mut [f32],
    mut bounds: Option<&mut [f64]>,
) -> Result<(), Failure> {
    let (wrap, options, threads) = convert_options(options)?;
    let quads: Vec<[f64; 8]> = quads
        .chunks_exact(8)
        .map(|q| [q[0], q[1], q[2], q[3], q[4], q[5], q[6], q[7]])
        .collect();
    // Checked on every core too: the first bad quad is named.
    let checked = quadtex_core::map_runs_on_threads(&quads, threads, |part, out| {
        out.extend(part.iter().map(|q| {
            Footprint::from_corners([[q[0], q[1]], [q[2], q[3]], [q[4], q[5]], [q[6], q[7]]])
        }));
    });
    let footprints = checked
        .into_iter()
        .enumerate()
        .map(|(i, f)| f.map_err(|e| Failure::from(e).context(&format!("quad {i}"))))
        .collect::<Result<Vec<_>, _>>()?;
    let texture = texture.texture.with_wrap(wrap);
    let filtered = texture.filter_batch_with_bounds(&footprints, &options, threads);
    for (i, ((colour, bound), pixel)) in filtered.iter().zip(out.chunks_exact_mut(4)).enumerate() {
        pixel.copy_from_slice(&colour.to_array());
        if let Some(b) = bounds.as_deref_mut() {
            b[i] = *bound;
        }
    }
    Ok(())
}

/// Depth, size and mean colour of a texture.
pub(crate) fn info(texture: &QtxTexture) -> QtxTextureInfo {
    let tree = texture.texture.tree();
    let [columns, rows] = tree.finest_grid();
    QtxTextureInfo {
        depth: u32::from(tree.depth()),
        columns,
        rows,
        colour_format: u32::from(tree.encoding().code()),
        node_count: tree.node_count(),
        memory_bytes: tree.memory_bytes(),
        mean: tree.average().to_array(),
    }
}

impl QtxTexture {
    pub(crate) fn new(tree: QuadTree) -> QtxTexture {
        QtxTexture {
            texture: Texture::new(tree, Wrap::REPEAT),
        }
    }
}

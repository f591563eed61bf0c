//! # quadtex (Python)
//!
//! PyO3 bindings of `quadtex-core` and `quadtex-io`: pack an image (a file or
//! a numpy array) into an incomplete-quadtree texture, open and save `.qtx`
//! files, and filter footprints or integrate rectangles in batches; and of
//! `quadtex-render`: render scenes as `quadtex render` does (`scene.rs`).
//!
//! The Python-facing documentation is `python/quadtex/__init__.pyi`
//! (shipped in the wheel with `py.typed`); this crate's tests are Python
//! (`tests/`, pytest).
//!
//! Batch calls validate their input with the GIL held (reading the numpy
//! array), then release it while the texture work runs, chunk by chunk, so
//! other Python threads run meanwhile and memory stays bounded.
#![forbid(unsafe_code)]

mod arrays;
mod differentials;
mod errors;
mod images;
mod scene;
mod tiles;

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyString, PyTuple};
use quadtex_core::{
    BuildOptions, FilterOptions, Footprint, Fragment, MAX_DEPTH, QuadTree, Rgba, Threads,
    Weighting, Wrap, WrapMode, fill_runs_on_threads, map_runs_on_threads,
};

use crate::errors::{core_error, io_error};

/// Footprints (or rectangles) converted and processed per GIL release.
const CHUNK: usize = 1 << 16;

/// Longest stretch of batch work without the GIL before Ctrl-C is checked.
const SIGNAL_INTERVAL: Duration = Duration::from_millis(50);

/// Items a batch's first stretch gives each thread.
const STEP: usize = 64;

/// Max level of SVG art packed without `max_level` (as `quadtex pack`).
const DEFAULT_SVG_LEVEL: u8 = 12;

/// A packed texture: an incomplete quadtree (linear light, premultiplied
/// RGBA, 16 bits a channel). Made by `quadtex.open` or `quadtex.pack`.
#[pyclass(frozen, module = "quadtex", name = "Texture")]
pub(crate) struct Texture {
    pub(crate) tree: Arc<QuadTree>,
    /// Size of the raster it was packed from (kept in saved files).
    pub(crate) source: Option<(u32, u32)>,
    /// The file it was opened from, named in `verify`'s errors.
    pub(crate) file: Option<PathBuf>,
}

#[pymethods]
impl Texture {
    /// Mean colour over each footprint (the exact filter).
    ///
    /// Parameters:
    ///   quads: `(N, 4, 2)` array-like, the texture-space images of the pixel
    ///     corners (0,0), (1,0), (1,1), (0,1) (any real dtype, read as float64).
    ///   wrap: "repeat", "clamp", "mirror" or "border", or a pair (x, z) of
    ///     them: how texture space continues beyond the unit square.
    ///   weighting: "screen" (a box over the pixel) or "texture" (a box over
    ///     the footprint in texture space).
    ///   border: RGBA (linear, premultiplied) outside the unit square on an
    ///     axis whose wrap is "border".
    ///   error_bound: > 0; the bound each footprint's error aims at (squares
    ///     are refined, largest error first, until it is met).
    ///   level: 0..30, or None; refines every square to this level instead
    ///     of `error_bound`.
    ///   budget: >= 1, or None (the default: no budget); most squares refined
    ///     per footprint, for real-time callers: a footprint that stops at it
    ///     reports a bound above `error_bound`.
    ///   return_bound: also return each footprint's bound reached, `(N,)`
    ///     float64 relative to the texture's contrast.
    ///   threads: None (every core) or >= 1 (1: the calling thread only, for
    ///     callers that run batches on threads of their own); the results
    ///     are bit-identical whatever the count.
    ///
    /// Returns: `(N, 4)` float32, linear premultiplied RGBA; with
    /// `return_bound=True` the pair `(rgba, bound)`.
    ///
    /// Raises: ValueError (a shape, a corner `quads[i]` that is not finite or
    /// beyond 1e15, a quad whose edges cross, an unknown name, an option out
    /// of range), TypeError (`quads` does not hold real numbers),
    /// KeyboardInterrupt (Ctrl-C, checked between stretches of about 50 ms).
    /// The GIL is released while filtering.
    #[pyo3(
        signature = (quads, wrap = None, weighting = "screen", border = None, error_bound = 1.0 / 512.0, level = None, budget = None, return_bound = false, threads = None),
        text_signature = "($self, quads, wrap='repeat', weighting='screen', border=(0.0, 0.0, 0.0, 0.0), error_bound=0.001953125, level=None, budget=None, return_bound=False, threads=None)"
    )]
    fn filter<'py>(
        &self,
        quads: &Bound<'py, PyAny>,
        wrap: Option<&Bound<'py, PyAny>>,
        weighting: &str,
        border: Option<&Bound<'py, PyAny>>,
        error_bound: f64,
        level: Option<i64>,
        budget: Option<u64>,
        return_bound: bool,
        threads: Option<i64>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let py = quads.py();
        let threads = batch_threads(threads)?;
        let border = match border {
            Some(b) => {
                let b = arrays::float64(b, "border", &[Some(4)], "(4,)")?.try_readonly()?;
                let v = b.as_array();
                [v[0], v[1], v[2], v[3]]
            }
            None => [0.0; 4],
        };
        let wrap = parse_wrap(wrap, border)?;
        let mut options = filter_options(weighting, error_bound, level)?;
        if let Some(budget) = budget {
            options = options
                .with_budget(budget)
                .map_err(|e| PyValueError::new_err(e.to_string()))?;
        }
        let texture = quadtex_core::Texture::new(Arc::clone(&self.tree), wrap);
        let quads = arrays::float64(quads, "quads", &[None, Some(4), Some(2)], "(N, 4, 2)")?;
        let readonly = quads.try_readonly()?;
        let view = arrays::view3(&readonly)?;
        let n = view.shape()[0];
        let mut out: Vec<f32> = Vec::with_capacity(4 * n);
        let mut bounds: Vec<f64> = Vec::with_capacity(if return_bound { n } else { 0 });
        // Each quad's corners, `x0 z0 x1 z1 …`.
        let mut corners: Vec<[f64; 8]> = Vec::with_capacity(n.min(CHUNK));
        let mut stretches = Stretches::new(threads);
        for start in (0..n).step_by(CHUNK) {
            // Copied while the GIL is held (another thread may write to the
            // array once it is released), then checked and filtered on every
            // core without it.
            corners.clear();
            arrays::copy_rows(&view, start..(start + CHUNK).min(n), &mut corners);
            let checked = py.detach(|| {
                map_runs_on_threads(&corners, threads, |part, out| {
                    out.extend(part.iter().map(|c| {
                        Footprint::from_corners([0, 1, 2, 3].map(|k| [c[2 * k], c[2 * k + 1]]))
                    }));
                })
            });
            let mut footprints = Vec::with_capacity(checked.len());
            for (k, footprint) in checked.into_iter().enumerate() {
                footprints
                    .push(footprint.map_err(|e| {
                        PyValueError::new_err(format!("quads[{}]: {e}", start + k))
                    })?);
            }
            let mut filtered: Vec<(quadtex_core::Rgba, f64)> = Vec::with_capacity(footprints.len());
            stretches.map(py, &footprints, &mut filtered, |step, out| {
                let mut stats = quadtex_core::FilterStats::default();
                out.extend(
                    step.iter()
                        .map(|f| texture.filter_with_bound(f, &options, &mut stats)),
                );
            })?;
            out.extend(filtered.iter().flat_map(|(c, _)| c.to_array()));
            if return_bound {
                bounds.extend(filtered.iter().map(|&(_, b)| b));
            }
        }
        let rgba = PyArray1::from_vec(py, out).reshape([n, 4])?.into_any();
        if !return_bound {
            return Ok(rgba);
        }
        let bounds = PyArray1::from_vec(py, bounds).into_any();
        Ok(PyTuple::new(py, [rgba, bounds])?.into_any())
    }

    /// Integral of colour over each rectangle's overlap with the unit
    /// square, no wrap: what `quadtex query` prints.
    ///
    /// Parameters:
    ///   rects: `(N, 4)` array-like, rows `x0 z0 x1 z1` with `x0 <= x1`,
    ///     `z0 <= z1` (any real dtype, read as float64).
    ///   level: 0..30, or None (the tree's depth): traverse down to this level.
    ///   threads: None (every core) or >= 1, as for `filter`.
    ///
    /// Returns: `(N, 4)` float64, linear premultiplied RGBA × area; divide by
    /// the rectangle's area for its mean colour.
    ///
    /// Raises: ValueError (a shape, reversed or non-finite bounds
    /// `rects[i]`, `level` out of range), TypeError (`rects` does not hold
    /// real numbers), KeyboardInterrupt (Ctrl-C, checked every 50 ms or so).
    /// The GIL is released while integrating.
    #[pyo3(signature = (rects, level = None, threads = None))]
    fn integrate<'py>(
        &self,
        py: Python<'py>,
        rects: &Bound<'py, PyAny>,
        level: Option<i64>,
        threads: Option<i64>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let threads = batch_threads(threads)?;
        let k = match level {
            Some(level) => check_level(level, "level")?,
            None => self.tree.depth(),
        };
        let rects = arrays::float64(rects, "rects", &[None, Some(4)], "(N, 4)")?;
        let readonly = rects.try_readonly()?;
        let view = arrays::view2(&readonly)?;
        let n = view.shape()[0];
        let tree = &*self.tree;
        // Zeroed lazily by the system: each thread's first writes bring
        // in the pages it fills.
        let mut out = vec![0.0f64; 4 * n];
        let mut copied: Vec<[f64; 4]> = Vec::with_capacity(n.min(CHUNK));
        let mut stretches = Stretches::new(threads);
        for start in (0..n).step_by(CHUNK) {
            // Copied while the GIL is held (another thread may write to the
            // array once it is released), then checked and integrated on
            // every core without it.
            let end = (start + CHUNK).min(n);
            copied.clear();
            arrays::copy_rows(&view, start..end, &mut copied);
            let refused = AtomicBool::new(false);
            stretches.fill(py, &copied, &mut out[4 * start..4 * end], |step, out| {
                for (&[x0, z0, x1, z1], out) in step.iter().zip(out.chunks_exact_mut(4)) {
                    match Fragment::new(x0, z0, x1, z1) {
                        Ok(f) => out.copy_from_slice(&tree.weighted_colour(&f, k).0),
                        Err(_) => refused.store(true, Ordering::Relaxed),
                    }
                }
            })?;
            if refused.into_inner() {
                // The first rectangle refused, named as the check found it.
                for (i, &[x0, z0, x1, z1]) in (start..).zip(&copied) {
                    Fragment::new(x0, z0, x1, z1)
                        .map_err(|e| PyValueError::new_err(format!("rects[{i}]: {e}")))?;
                }
            }
        }
        PyArray1::from_vec(py, out)
            .reshape([n, 4])
            .map(Bound::into_any)
    }

    /// Writes the texture to a `.qtx` file, atomically (a temporary file in
    /// the same directory, renamed over `path`). A symbolic link is followed
    /// (the file it names is replaced; the link stays); a device or FIFO is
    /// written in place.
    ///
    /// Parameters:
    ///   path: str, bytes or os.PathLike; the `.qtx` file to write.
    ///
    /// Returns: None.
    ///
    /// Raises: OSError when the system refuses (the subclass its errno
    /// selects, e.g. IsADirectoryError for a directory, FileNotFoundError
    /// for a missing folder; `errno` and `filename` set).
    #[pyo3(signature = (path))]
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let (tree, source) = (&*self.tree, self.source);
        py.detach(|| quadtex_io::write_qtx(&path, tree, source))
            .map_err(io_error)
    }

    /// Checks every colour and texel of the tree: what `open(path,
    /// mapped=True)` leaves unread (premultiplied colours, each inner colour
    /// the mean of its children, each texel block the mean of its texels).
    ///
    /// Parameters: none.
    ///
    /// Returns: None.
    ///
    /// Raises: ValueError naming the file and the first node that fails.
    #[pyo3(signature = ())]
    fn verify(&self, py: Python<'_>) -> PyResult<()> {
        let tree = &*self.tree;
        py.detach(|| tree.verify())
            .map_err(|e| core_error(&e, self.file.as_deref()))
    }

    /// Depth of the tree (level of its finest squares).
    #[getter]
    fn depth(&self) -> u8 {
        self.tree.depth()
    }

    /// `(columns, rows)` of the finest grid over the texture: a packed
    /// image's own width and height in texels, whatever its size (a texture
    /// uniform down to its texels included); `2^depth` each for square
    /// vector art.
    #[getter]
    fn cells(&self) -> (u64, u64) {
        let [columns, rows] = self.tree.finest_grid();
        (columns, rows)
    }

    /// Number of nodes in the tree.
    #[getter]
    fn node_count(&self) -> u64 {
        self.tree.node_count()
    }

    /// Bytes the tree occupies in memory.
    #[getter]
    fn nbytes(&self) -> u64 {
        self.tree.memory_bytes()
    }

    /// `(width, height)` of the raster the texture was packed from (for SVG
    /// art, the effective raster `2^level` on a side), or None.
    #[getter]
    fn source_size(&self) -> Option<(u32, u32)> {
        self.source
    }

    /// `<quadtex.Texture depth=… node_count=… nbytes=… source=WxH>`.
    fn __repr__(&self) -> String {
        let source = self
            .source
            .map_or(String::new(), |(w, h)| format!(" source={w}x{h}"));
        format!(
            "<quadtex.Texture depth={} node_count={} nbytes={}{source}>",
            self.tree.depth(),
            self.tree.node_count(),
            self.tree.memory_bytes()
        )
    }
}

/// Reads a `.qtx` file (written by `Texture.save` or `quadtex pack`),
/// checking its checksums and every colour.
///
/// Parameters:
///   path: str, bytes or os.PathLike; a `.qtx` file.
///   mapped: if True the file is memory-mapped instead: its header,
///     structure and payload checksum are checked (one pass at memory speed,
///     so a damaged file is refused) and queries read the nodes they touch;
///     `Texture.verify()` checks the colours' invariants.
///   verify: with `mapped=True` only: False skips the payload checksum for
///     trusted files, giving up the promise that a damaged file is refused.
///
/// Returns: a `Texture`.
///
/// Raises: OSError when the system refuses (e.g. FileNotFoundError; `errno`
/// and `filename` set), ValueError for a malformed or damaged file (the
/// message names the file and the field or the damaged bytes), or for
/// `verify=False` without `mapped=True`.
#[pyfunction]
#[pyo3(signature = (path, mapped = false, verify = true))]
fn open(py: Python<'_>, path: PathBuf, mapped: bool, verify: bool) -> PyResult<Texture> {
    if !verify && !mapped {
        return Err(PyValueError::new_err(
            "verify=False applies to mapped=True only (reading a file whole always verifies it)",
        ));
    }
    let limits = quadtex_io::Limits::default();
    let (tree, info) = py
        .detach(|| match (mapped, verify) {
            (true, true) => quadtex_io::map_qtx(&path, &limits),
            (true, false) => quadtex_io::map_qtx_unverified(&path, &limits),
            _ => quadtex_io::read_qtx(&path, &limits),
        })
        .map_err(io_error)?;
    let source = (info.source_width > 0 && info.source_height > 0)
        .then_some((info.source_width, info.source_height));
    Ok(Texture {
        tree: Arc::new(tree),
        source,
        file: Some(path),
    })
}

/// Packs an image file or a numpy array into a texture, as `quadtex pack`
/// does.
///
/// Parameters:
///   source: a path (str, bytes, os.PathLike) to a PNG, JPEG, OpenEXR or
///     Radiance `.hdr` image (recognised by content; OpenEXR and `.hdr`
///     pack as HDR textures) or an SVG document (by its `.svg` extension);
///     or an array `(H, W)` / `(H, W, C)`, C in 1..4 (grey, grey+alpha,
///     RGB, RGBA), row 0 at the top: uint8/uint16 are sRGB with straight
///     alpha, floats linear with premultiplied alpha. A folder of tiles is
///     `pack_tiles`.
///   tolerance: in [0, 1]; largest per-channel deviation of a texel from
///     its leaf's colour (0 is lossless). Raster images only.
///   max_level: 0..30, or None: depth of the finest cells (default: the
///     smallest level whose cells are no larger than a texel; for SVG 12,
///     or 20 with contour_leaves, lowered (not below 8) when the packing's
///     estimate is above `memory_limit`, as `quadtex pack` does: the
///     level packed at is log2 of `source_size`). A level given is kept:
///     art that does not fit at it raises ValueError.
///   hdr: float arrays only: keep them unclamped as half floats (as an
///     OpenEXR file is read); otherwise they are clamped to [0, alpha].
///   contour_leaves: SVG only, 3..1024, or None: squares crossed by at most
///     this many edges keep their contours (`--contour-leaves`).
///   max_sweep_work: SVG only, >= 1, or None: most steps of the exact
///     coverage sweep (`--max-sweep-work`).
///   memory_limit: bytes, >= 1, or None (the detected budget, as the
///     CLI's default): the memory decoding and packing may use
///     (`--memory-limit`); work estimated above it is refused before it
///     allocates.
///   resources: SVG only: which files its `<image href>` may read
///     (`--resources`): "same-folder" (the default: only inside the SVG's
///     folder), "anywhere" (trusted files) or "none" (data: URIs only).
///
/// Returns: a `Texture` (`source_size` is the raster's size).
///
/// Raises: OSError when the system refuses a file (e.g. FileNotFoundError;
/// `errno` and `filename` set); ValueError for a malformed or unsupported
/// file (naming the file and the field), an option out of range, or work
/// above `memory_limit` (the message names the estimate and the budget), or
/// an image reference the `resources` policy refuses (naming it);
/// TypeError for an array of another dtype.
#[pyfunction]
#[pyo3(signature = (source, tolerance = 0.0, max_level = None, hdr = false, contour_leaves = None, max_sweep_work = None, memory_limit = None, resources = None))]
fn pack(
    source: &Bound<'_, PyAny>,
    tolerance: f64,
    max_level: Option<i64>,
    hdr: bool,
    contour_leaves: Option<i64>,
    max_sweep_work: Option<i64>,
    memory_limit: Option<i64>,
    resources: Option<&str>,
) -> PyResult<Texture> {
    let limits = limits(memory_limit)?;
    if !(tolerance.is_finite() && (0.0..=1.0).contains(&tolerance)) {
        return Err(PyValueError::new_err(format!(
            "tolerance must be in [0, 1], got {tolerance}"
        )));
    }
    let max_level = max_level.map(|l| check_level(l, "max_level")).transpose()?;
    let contour_leaves = match contour_leaves {
        None => None,
        Some(n @ 3..=1024) => Some(n as usize),
        Some(n) => {
            return Err(PyValueError::new_err(format!(
                "contour_leaves must be in 3..=1024 (edges a contour leaf may hold), got {n}"
            )));
        }
    };
    let max_sweep_work = match max_sweep_work {
        None => None,
        Some(n @ 1..) => Some(n as u64),
        Some(n) => {
            return Err(PyValueError::new_err(format!(
                "max_sweep_work must be at least 1 (steps of the exact sweep), got {n}"
            )));
        }
    };
    let py = source.py();
    let resources = resources
        .map(|name| {
            quadtex_io::ExternalResources::parse(name).ok_or_else(|| {
                PyValueError::new_err(format!(
                    "resources must be one of {}, got {name:?}",
                    quadtex_io::ExternalResources::NAMES.join(", ")
                ))
            })
        })
        .transpose()?;
    let svg_only = SvgOnly {
        contour_leaves,
        max_sweep_work,
        resources,
    };
    let is_path = source.is_instance_of::<PyString>()
        || source.is_instance_of::<PyBytes>()
        || source.hasattr("__fspath__")?;
    if is_path {
        let path: PathBuf = source.extract()?;
        return pack_file(py, path, tolerance, max_level, svg_only, &limits);
    }
    if let Some(name) = svg_only.given() {
        return Err(PyValueError::new_err(format!(
            "{name} applies to SVG art, not to arrays"
        )));
    }
    let image = arrays::ImageArray::from_py(source)?;
    let image = image.view()?;
    let options = BuildOptions {
        tolerance,
        max_level,
        max_nodes: limits.max_nodes,
        max_bytes: Some(limits.max_memory),
        ..BuildOptions::default()
    };
    let (tree, size) = py
        .detach(|| {
            let grid = image.to_texels(hdr)?;
            let size = (grid.width(), grid.height());
            QuadTree::from_texels(&grid, &options).map(|(tree, _)| (tree, size))
        })
        .map_err(|e| core_error(&e, None))?;
    Ok(Texture {
        tree: Arc::new(tree),
        source: Some(size),
        file: None,
    })
}

/// Packs a folder of raster tiles into one texture, one tile in memory at a
/// time, as `quadtex pack-tiles` does.
///
/// Parameters:
///   directory: str, bytes or os.PathLike; a folder of tiles named
///     `ROW_COL.png` (or `.jpg`; row 0 at the top): a complete grid of 1,
///     2, 4, … tiles a side, every tile the same power-of-two square.
///   tolerance: in [0, 1]; as for `pack` (0 is lossless).
///   memory_limit: bytes, >= 1, or None (the detected budget): as for
///     `pack` (`--memory-limit`).
///
/// Returns: a `Texture`, the one `pack` would make of the whole mosaic.
///
/// Raises: OSError when the system refuses (`errno` and `filename` set);
/// ValueError for a malformed grid or tile (naming the tile), an option
/// out of range, or work above `memory_limit`.
#[pyfunction]
#[pyo3(signature = (directory, tolerance = 0.0, memory_limit = None))]
fn pack_tiles(
    py: Python<'_>,
    directory: PathBuf,
    tolerance: f64,
    memory_limit: Option<i64>,
) -> PyResult<Texture> {
    let limits = limits(memory_limit)?;
    if !(tolerance.is_finite() && (0.0..=1.0).contains(&tolerance)) {
        return Err(PyValueError::new_err(format!(
            "tolerance must be in [0, 1], got {tolerance}"
        )));
    }
    let (tree, _, folder) = py
        .detach(|| quadtex_io::pack_tiles(&directory, tolerance, &limits))
        .map_err(io_error)?;
    Ok(Texture {
        tree: Arc::new(tree),
        source: Some(folder.extent()),
        file: None,
    })
}

/// `pack`'s options that apply to SVG art only.
#[derive(Debug, Clone, Copy)]
struct SvgOnly {
    contour_leaves: Option<usize>,
    max_sweep_work: Option<u64>,
    /// The external-resources policy (default same-folder).
    resources: Option<quadtex_io::ExternalResources>,
}

impl SvgOnly {
    /// The name of the first option given, if any.
    fn given(&self) -> Option<&'static str> {
        if self.contour_leaves.is_some() {
            Some("contour_leaves")
        } else if self.max_sweep_work.is_some() {
            Some("max_sweep_work")
        } else if self.resources.is_some() {
            Some("resources")
        } else {
            None
        }
    }
}

/// `pack` of a file, as `quadtex pack` does it.
fn pack_file(
    py: Python<'_>,
    path: PathBuf,
    tolerance: f64,
    max_level: Option<u8>,
    svg_only: SvgOnly,
    limits: &quadtex_io::Limits,
) -> PyResult<Texture> {
    let SvgOnly {
        contour_leaves,
        max_sweep_work,
        resources,
    } = svg_only;
    let is_svg = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"));
    if is_svg {
        if tolerance != 0.0 {
            return Err(PyValueError::new_err(format!(
                "{}: tolerance applies to raster images; SVG art packs exactly",
                path.display()
            )));
        }
        let level = max_level.unwrap_or(if contour_leaves.is_some() {
            quadtex_core::CONTOUR_MAX_LEVEL
        } else {
            DEFAULT_SVG_LEVEL
        });
        let defaults = quadtex_core::VectorOptions::default();
        let options = quadtex_io::SvgOptions {
            vector: quadtex_core::VectorOptions {
                max_level: level,
                contour_leaves,
                max_sweep_work: max_sweep_work.unwrap_or(defaults.max_sweep_work),
                ..defaults
            },
            limits: quadtex_io::Limits {
                external_resources: resources.unwrap_or_default(),
                ..*limits
            },
            // As `quadtex pack`: a level left out is lowered to fit the budget.
            adjustable: quadtex_core::Adjustable {
                max_level: max_level.is_none(),
                contour_edges: false,
            },
        };
        let (tree, _, fit) = py
            .detach(|| quadtex_io::pack_svg_fitted(&path, &options))
            .map_err(io_error)?;
        let side = 1u32 << fit.max_level.min(31);
        return Ok(Texture {
            tree: Arc::new(tree),
            source: Some((side, side)),
            file: None,
        });
    }
    if let Some(name) = svg_only.given() {
        return Err(PyValueError::new_err(format!(
            "{}: {name} applies to SVG art, not to raster images",
            path.display()
        )));
    }
    let options = BuildOptions {
        tolerance,
        max_level,
        max_nodes: limits.max_nodes,
        max_bytes: Some(limits.max_memory),
        ..BuildOptions::default()
    };
    let grid = py
        .detach(|| quadtex_io::load_texels(&path, limits))
        .map_err(io_error)?;
    let (tree, _) = py
        .detach(|| QuadTree::from_texels(&grid, &options))
        .map_err(|e| core_error(&e, Some(&path)))?;
    Ok(Texture {
        tree: Arc::new(tree),
        source: Some((grid.width(), grid.height())),
        file: None,
    })
}

/// A batch call's work without the GIL, in stretches of about
/// `SIGNAL_INTERVAL`, checking for Ctrl-C between them: a long batch
/// raises `KeyboardInterrupt` promptly instead of at its end. The
/// stretches' length carries over from one part of a batch (`CHUNK` items
/// copied while the GIL is held) to the next: each stretch starts threads
/// of its own, and a few hundred short ones cost more than a batch of
/// cheap items takes.
struct Stretches {
    threads: Threads,
    /// Items the next stretch takes: doubled while a stretch takes under
    /// half the interval, halved past it.
    items: usize,
}

impl Stretches {
    fn new(threads: Threads) -> Stretches {
        Stretches {
            threads,
            items: STEP * threads.count(),
        }
    }

    /// Calls `stretch(range)` over `0..len`, a stretch at a time.
    fn run(
        &mut self,
        py: Python<'_>,
        len: usize,
        mut stretch: impl FnMut(std::ops::Range<usize>),
    ) -> PyResult<()> {
        let mut done = 0;
        while done < len {
            let end = done.saturating_add(self.items).min(len);
            let started = Instant::now();
            stretch(done..end);
            done = end;
            let took = started.elapsed();
            if took < SIGNAL_INTERVAL / 2 {
                self.items = self.items.saturating_mul(2);
            } else if took > SIGNAL_INTERVAL {
                self.items = (self.items / 2).max(STEP);
            }
            py.check_signals()?;
        }
        Ok(())
    }

    /// Runs `work` over `items` (appending to `out`, in the items' order)
    /// on the batch's threads with the GIL released.
    fn map<T: Sync, O: Send>(
        &mut self,
        py: Python<'_>,
        items: &[T],
        out: &mut Vec<O>,
        work: impl Fn(&[T], &mut Vec<O>) + Sync,
    ) -> PyResult<()> {
        let threads = self.threads;
        self.run(py, items.len(), |range| {
            let part = py.detach(|| map_runs_on_threads(&items[range], threads, &work));
            out.extend(part);
        })
    }

    /// [`Stretches::map`] for outputs written in place: `out` holds the
    /// same number of outputs for each item ([`fill_runs_on_threads`]),
    /// written on the threads that compute them.
    fn fill<T: Sync, O: Send>(
        &mut self,
        py: Python<'_>,
        items: &[T],
        out: &mut [O],
        work: impl Fn(&[T], &mut [O]) + Sync,
    ) -> PyResult<()> {
        let (threads, per_item) = (self.threads, out.len() / items.len().max(1));
        self.run(py, items.len(), |range| {
            let out = &mut out[range.start * per_item..range.end * per_item];
            py.detach(|| fill_runs_on_threads(&items[range], out, threads, &work));
        })
    }
}

/// The `threads` argument of a batch call: None for every core, else at
/// least 1.
fn batch_threads(threads: Option<i64>) -> PyResult<Threads> {
    match threads {
        None => Ok(Threads::EveryCore),
        Some(n) => usize::try_from(n)
            .ok()
            .filter(|&n| n >= 1)
            .map(Threads::from_count)
            .ok_or_else(|| {
                PyValueError::new_err(format!(
                    "threads must be None (every core) or at least 1, got {n}"
                ))
            }),
    }
}

/// The default limits (as the CLI's), with `memory_limit` bytes as the
/// memory budget when given (`--memory-limit`).
pub(crate) fn limits(memory_limit: Option<i64>) -> PyResult<quadtex_io::Limits> {
    let mut limits = quadtex_io::Limits::default();
    match memory_limit.map(u64::try_from) {
        None => {}
        Some(Ok(bytes @ 1..)) => limits.max_memory = bytes,
        Some(_) => {
            return Err(PyValueError::new_err(format!(
                "memory_limit must be at least 1 byte, got {}",
                memory_limit.unwrap_or_default()
            )));
        }
    }
    Ok(limits)
}

/// A level in `0..=MAX_DEPTH`.
fn check_level(level: i64, name: &str) -> PyResult<u8> {
    u8::try_from(level)
        .ok()
        .filter(|&l| l <= MAX_DEPTH)
        .ok_or_else(|| {
            PyValueError::new_err(format!("{name} must be in 0..={MAX_DEPTH}, got {level}"))
        })
}

/// `wrap`: a mode name for both axes, or a pair `(x, z)` of names.
fn parse_wrap(wrap: Option<&Bound<'_, PyAny>>, border: [f64; 4]) -> PyResult<Wrap> {
    let mode = |name: &str| {
        WrapMode::from_name(name).ok_or_else(|| {
            PyValueError::new_err(format!(
                "unknown wrap mode {name:?} (expected \"repeat\", \"clamp\", \"mirror\" or \"border\")"
            ))
        })
    };
    let (x, z) = match wrap {
        None => (WrapMode::Repeat, WrapMode::Repeat),
        Some(w) if w.is_instance_of::<PyString>() => {
            let m = mode(&w.extract::<String>()?)?;
            (m, m)
        }
        Some(w) => match w.extract::<Vec<String>>().as_deref() {
            Ok([x, z]) => (mode(x)?, mode(z)?),
            _ => {
                return Err(PyValueError::new_err(format!(
                    "wrap must be a mode name or a pair (x, z) of names, got {}",
                    w.repr().map_or_else(|_| "?".into(), |r| r.to_string())
                )));
            }
        },
    };
    // Finite as a double, a channel may still overflow the float the
    // texture keeps.
    if let Some(i) = border.iter().position(|&v| !(v as f32).is_finite()) {
        let v = border[i];
        return Err(PyValueError::new_err(if v.is_finite() {
            format!("border[{i}] is beyond float32 range ({v:e})")
        } else {
            format!("border[{i}] is not finite ({v})")
        }));
    }
    let [r, g, b, a] = border.map(|v| v as f32);
    Wrap::new(x, z, Rgba::new(r, g, b, a)).map_err(|e| PyValueError::new_err(e.to_string()))
}

fn filter_options(
    weighting: &str,
    error_bound: f64,
    level: Option<i64>,
) -> PyResult<FilterOptions> {
    let weighting = match weighting {
        "screen" => Weighting::Screen,
        "texture" => Weighting::Texture,
        other => {
            return Err(PyValueError::new_err(format!(
                "unknown weighting {other:?} (expected \"screen\" or \"texture\")"
            )));
        }
    };
    let bad = |e: quadtex_core::Error| PyValueError::new_err(e.to_string());
    let mut options = FilterOptions::default()
        .with_weighting(weighting)
        .with_error_bound(error_bound)
        .map_err(bad)?;
    if let Some(level) = level {
        options = options.with_level(check_level(level, "level")?);
    }
    Ok(options)
}

/// Alias-free texture filtering with incomplete-quadtree textures.
///
/// `pack` an image (file or numpy array) or `open` a .qtx file to get a
/// `Texture`; `Texture.filter` averages it over pixel footprints and
/// `Texture.integrate` over rectangles. `Scene.open` a scene file and
/// `Scene.render` it as `quadtex render` does. Colours are linear light,
/// premultiplied alpha; texture space is the unit square, x right, z up.
#[pymodule]
#[pyo3(name = "quadtex")]
fn quadtex_python(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Texture>()?;
    m.add_function(wrap_pyfunction!(open, m)?)?;
    m.add_function(wrap_pyfunction!(pack, m)?)?;
    m.add_function(wrap_pyfunction!(pack_tiles, m)?)?;
    m.add_function(wrap_pyfunction!(tiles::tile_grid, m)?)?;
    m.add_function(wrap_pyfunction!(tiles::mosaic_tiles, m)?)?;
    m.add_function(wrap_pyfunction!(tiles::pack_tile, m)?)?;
    m.add_function(wrap_pyfunction!(tiles::splice_tiles, m)?)?;
    scene::register(m)?;
    differentials::register(m)?;
    images::register(m)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}

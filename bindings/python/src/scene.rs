//! Rendering from Python: `Scene.open` reads what `quadtex render` reads,
//! `Scene.render` renders it as `quadtex render` does (the same library
//! calls, so the pixels are the CLI's EXR output bit for bit), and
//! `Scene.path_frames` gives the cameras of a camera path's frames.
//!
//! The option names and their checks mirror `src/cli/render.rs` (`--filter`,
//! `--pixel-filter`, `--error-bound`, `--budget`, `--level`, `--quality`,
//! `--path`, `--frames`); keep the two in step.

use std::io::Write;
use std::path::{Path, PathBuf};

use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use quadtex_core::FilterOptions;
use quadtex_core::baseline::StripOptions;
use quadtex_render::{CameraPath, PixelFilter, RenderOptions, RenderSummary, TextureFilter};

use crate::errors::io_error;

/// Largest anisotropy of the `ewa` filter, as the CLI's `--filter ewa`.
const EWA_ANISOTROPY: f64 = 8.0;

/// Progress lines a `render(progress=True)` prints (one as each band of
/// rows is done; fewer for images of fewer rows).
const PROGRESS_BANDS: u64 = 10;

/// A scene as `quadtex render` reads it: a TOML scene file (docs/scenes.md)
/// with its planes, quads, spheres, OBJ and glTF models, textures (`.qtx`,
/// PNG, JPEG, OpenEXR, `.hdr`, SVG, built-in) packed once, sky and lights.
/// Made by `Scene.open`.
#[pyclass(frozen, module = "quadtex", name = "Scene")]
pub(crate) struct Scene {
    scene: quadtex_render::Scene,
    /// The limits it was read under (camera paths are read under them too).
    limits: quadtex_io::Limits,
    /// The file it was read from.
    file: PathBuf,
}

/// One frame's camera along a camera path: the pose the path's spline gives
/// at the frame's time. Made by `Scene.path_frames`.
#[pyclass(frozen, module = "quadtex", name = "Camera")]
pub(crate) struct Camera {
    frame: u32,
    key: quadtex_render::Key,
}

fn xyz(v: quadtex_render::Vec3) -> (f64, f64, f64) {
    (v.x, v.y, v.z)
}

#[pymethods]
impl Camera {
    /// The frame's index along the path (0 for the first).
    #[getter]
    fn frame(&self) -> u32 {
        self.frame
    }

    /// The frame's time on the path's clock (the keys' `time` unit).
    #[getter]
    fn time(&self) -> f64 {
        self.key.time
    }

    /// `(x, y, z)`: where the camera is (world space, `y` up).
    #[getter]
    fn position(&self) -> (f64, f64, f64) {
        xyz(self.key.position)
    }

    /// `(x, y, z)`: the point it looks at.
    #[getter]
    fn look_at(&self) -> (f64, f64, f64) {
        xyz(self.key.look_at)
    }

    /// `(x, y, z)`: the up direction fixing the roll, as interpolated (not
    /// made perpendicular to the view).
    #[getter]
    fn up(&self) -> (f64, f64, f64) {
        xyz(self.key.up)
    }

    /// Vertical field of view, degrees.
    #[getter]
    fn fov(&self) -> f64 {
        self.key.fov
    }

    /// `<quadtex.Camera frame=… time=… position=(…) look_at=(…) fov=…>`.
    fn __repr__(&self) -> String {
        let k = &self.key;
        let v = |v: quadtex_render::Vec3| format!("({}, {}, {})", v.x, v.y, v.z);
        format!(
            "<quadtex.Camera frame={} time={} position={} look_at={} up={} fov={}>",
            self.frame,
            k.time,
            v(k.position),
            v(k.look_at),
            v(k.up),
            k.fov
        )
    }
}

#[pymethods]
impl Scene {
    /// Reads a scene file, as `quadtex render SCENE` does: its models and
    /// textures are read and packed now, once.
    ///
    /// Parameters:
    ///   path: str, bytes or os.PathLike; a TOML scene file (docs/scenes.md),
    ///     with its planes, quads, spheres, OBJ and glTF models, and its
    ///     textures (`.qtx`, PNG, JPEG, OpenEXR, `.hdr`, SVG, `builtin:`).
    ///   memory_limit: bytes, >= 1, or None (the detected budget): the
    ///     memory reading and packing textures may use (`--memory-limit`).
    ///   resources: which files glTF models and SVG textures may read
    ///     (`--resources`): "same-folder" (the default), "anywhere" or
    ///     "none".
    ///
    /// Returns: a `Scene`.
    ///
    /// Raises: OSError when the system refuses the scene file (e.g.
    /// FileNotFoundError; `errno` and `filename` set); ValueError for a
    /// malformed scene (naming the file, line and key, e.g.
    /// `shape[0].texture`), a texture that cannot be read or packed (named
    /// by its key, with the system's message), an option out of range.
    /// The GIL is released while reading.
    #[staticmethod]
    #[pyo3(signature = (path, memory_limit = None, resources = None))]
    fn open(
        py: Python<'_>,
        path: PathBuf,
        memory_limit: Option<i64>,
        resources: Option<&str>,
    ) -> PyResult<Scene> {
        let mut limits = crate::limits(memory_limit)?;
        if let Some(name) = resources {
            limits.external_resources =
                quadtex_io::ExternalResources::parse(name).ok_or_else(|| {
                    PyValueError::new_err(format!(
                        "resources must be one of {}, got {name:?}",
                        quadtex_io::ExternalResources::NAMES.join(", ")
                    ))
                })?;
        }
        let scene = py
            .detach(|| quadtex_render::load_scene(&path, &limits))
            .map_err(render_error)?;
        Ok(Scene {
            scene,
            limits,
            file: path,
        })
    }

    /// Renders the scene, as `quadtex render` does: the same pixels as its
    /// OpenEXR output (`--format exr`), bit for bit.
    ///
    /// Parameters:
    ///   width: pixels, >= 1, or None (the camera's; with `height` only, the
    ///     camera's aspect).
    ///   height: pixels, >= 1, or None (the camera's; with `width` only, the
    ///     camera's aspect).
    ///   filter: the texture filter (`--filter`): "quadtree" (the method:
    ///     the exact integral over each pixel's footprint), "nearest",
    ///     "bilinear", "supersample:N" (N×N nearest rays a pixel, N in
    ///     1..64), "trilinear", "ewa" (anisotropy 8) or "sat".
    ///   pixel_filter: "box", "tent" or "mitchell" (`--pixel-filter`), for
    ///     quadtree and supersample.
    ///   path: a camera path file (`--path`, TOML keys, docs/scenes.md), or
    ///     None (the scene's camera). Needs `frame` and `frames`.
    ///   frame: with `path`: which frame to render, 0 <= frame < frames.
    ///   frames: with `path`: frames along it (`--frames`, 1..100000).
    ///   error_bound: quadtree only: > 0, or None (1/512): the bound each
    ///     pixel aims at (`--error-bound`).
    ///   budget: quadtree only: >= 1, or None (64): most squares a pixel
    ///     region refines (`--budget`).
    ///   level: quadtree only: 0..30, or None: refine every square to this
    ///     level instead (`--level`).
    ///   quality: sat only, in [1, 64] (`--quality`).
    ///   progress: print a line to standard error (file descriptor 2) as
    ///     each tenth of the rows is done.
    ///   return_summary: also return what the render cost, as a dict (the
    ///     CLI's summary line under "text").
    ///
    /// Returns: `(height, width, 4)` float32, linear light, premultiplied
    /// RGBA, row 0 at the top; with `return_summary=True` the pair
    /// `(image, summary)`, summary a dict: width, height, seconds,
    /// textured_pixels, max_error_bound, mean_error_bound, over_target,
    /// max_weight_error, text.
    ///
    /// Raises: ValueError naming the argument (an unknown filter name, a
    /// zero size or one above 2^26 pixels, `frame` >= `frames`, `frame`
    /// without `path`, …), or the camera path's file, line and key when it
    /// is malformed, or the frame whose camera is degenerate; OSError when
    /// the system refuses the path file (`errno` and `filename` set).
    /// The GIL is released while rendering (on every core); Ctrl-C is seen
    /// when the frame is done.
    #[pyo3(
        signature = (width = None, height = None, filter = "quadtree", pixel_filter = "box", path = None, frame = None, frames = None, error_bound = None, budget = None, level = None, quality = 1.0, progress = false, return_summary = false)
    )]
    fn render<'py>(
        &self,
        py: Python<'py>,
        width: Option<i64>,
        height: Option<i64>,
        filter: &str,
        pixel_filter: &str,
        path: Option<PathBuf>,
        frame: Option<i64>,
        frames: Option<i64>,
        error_bound: Option<f64>,
        budget: Option<i64>,
        level: Option<i64>,
        quality: f64,
        progress: bool,
        return_summary: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let quadtree = Quadtree {
            error_bound,
            budget,
            level,
        };
        let options = RenderOptions {
            width: size(width, "width")?,
            height: size(height, "height")?,
            filter: texture_filter(filter, quadtree, quality)?,
            pixel_filter: parse_pixel_filter(pixel_filter)?,
            seed: 0,
        };
        let camera = match (path, frame, frames) {
            (None, None, None) => None,
            (Some(path), Some(frame), Some(frames)) => {
                let frames = frame_count(frames)?;
                let frame = u32::try_from(frame)
                    .ok()
                    .filter(|&f| f < frames)
                    .ok_or_else(|| {
                        PyValueError::new_err(format!(
                            "frame must be in 0..{frames} (frames), got {frame}"
                        ))
                    })?;
                let camera_path = self.camera_path(py, &path)?;
                let (w, h) = (self.scene.camera.width(), self.scene.camera.height());
                let camera = camera_path
                    .camera(frame, frames, w, h)
                    .map_err(|e| path_error(&path, &e))?;
                Some(camera)
            }
            (None, _, _) => {
                let given = if frame.is_some() { "frame" } else { "frames" };
                return Err(PyValueError::new_err(format!(
                    "{given} applies to a camera path: give path too (and frame and frames)"
                )));
            }
            (Some(_), None, _) => {
                return Err(PyValueError::new_err(
                    "path needs frame (which frame to render) and frames (how many along it)",
                ));
            }
            (Some(_), Some(_), None) => {
                return Err(PyValueError::new_err(
                    "path needs frames (how many frames along it), as --frames",
                ));
            }
        };
        let scene = &self.scene;
        let (pixels, summary) = py
            .detach(|| {
                let framed;
                let scene = match camera {
                    Some(camera) => {
                        framed = quadtex_render::Scene {
                            camera,
                            ..scene.clone()
                        };
                        &framed
                    }
                    None => scene,
                };
                let report = |done: u64, total: u64| {
                    if progress {
                        report_rows(done, total);
                    }
                };
                let (image, summary) = quadtex_render::render(scene, &options, &report)?;
                let pixels: Vec<f32> = image.pixels.iter().flat_map(|p| p.to_array()).collect();
                Ok::<_, quadtex_render::Error>((pixels, summary))
            })
            .map_err(render_error)?;
        py.check_signals()?;
        let shape = [summary.height as usize, summary.width as usize, 4];
        let image = PyArray1::from_vec(py, pixels).reshape(shape)?.into_any();
        if !return_summary {
            return Ok(image);
        }
        let summary = summary_dict(py, &summary)?.into_any();
        Ok(PyTuple::new(py, [image, summary])?.into_any())
    }

    /// The camera of each frame along a camera path, as `quadtex render
    /// --path PATH --frames N` places them: frame i of N is the path's
    /// pose at time `t0 + (t_last − t0)·i/(N − 1)` (the first key when
    /// N = 1), `position` and `look_at` on a Catmull–Rom spline through
    /// the keys, `up` and `fov` linear between them (docs/scenes.md).
    ///
    /// Parameters:
    ///   path: str, bytes or os.PathLike; a camera path file (TOML keys).
    ///   frames: how many frames along it, 1..100000 (`--frames`).
    ///
    /// Returns: a list of `frames` `Camera`s (frame, time, position,
    /// look_at, up, fov), in frame order.
    ///
    /// Raises: ValueError (a malformed path, naming the file, line and key;
    /// `frames` out of range; a frame whose interpolated camera is
    /// degenerate, naming it, as the CLI checks before rendering);
    /// OSError when the system refuses the file (`errno` and `filename`
    /// set).
    #[pyo3(signature = (path, frames))]
    fn path_frames(&self, py: Python<'_>, path: PathBuf, frames: i64) -> PyResult<Vec<Camera>> {
        let frames = frame_count(frames)?;
        let camera_path = self.camera_path(py, &path)?;
        let (w, h) = (self.scene.camera.width(), self.scene.camera.height());
        (0..frames)
            .map(|frame| {
                camera_path
                    .camera(frame, frames, w, h)
                    .map_err(|e| path_error(&path, &e))?;
                let key = camera_path.pose_at(camera_path.frame_time(frame, frames));
                Ok(Camera { frame, key })
            })
            .collect()
    }

    /// The camera's width in pixels (the default `render` width).
    #[getter]
    fn width(&self) -> u32 {
        self.scene.camera.width()
    }

    /// The camera's height in pixels (the default `render` height).
    #[getter]
    fn height(&self) -> u32 {
        self.scene.camera.height()
    }

    /// `<quadtex.Scene 'file' WxH surfaces=…>`.
    fn __repr__(&self) -> String {
        format!(
            "<quadtex.Scene {:?} {}x{} surfaces={}>",
            self.file.display().to_string(),
            self.scene.camera.width(),
            self.scene.camera.height(),
            self.scene.surfaces.len()
        )
    }
}

impl Scene {
    /// The camera path in `path`, read under the scene's limits.
    fn camera_path(&self, py: Python<'_>, path: &Path) -> PyResult<CameraPath> {
        py.detach(|| quadtex_render::load_camera_path(path, &self.limits))
            .map_err(render_error)
    }
}

/// The quadtree filter's options, before they are checked.
struct Quadtree {
    error_bound: Option<f64>,
    budget: Option<i64>,
    level: Option<i64>,
}

/// `filter=` with its options, as the CLI's `--filter` (and `--error-bound`,
/// `--budget`, `--level`, `--quality`) make it.
fn texture_filter(name: &str, quadtree: Quadtree, quality: f64) -> PyResult<TextureFilter> {
    let bad = |e: quadtex_core::Error| PyValueError::new_err(e.to_string());
    if !(1.0..=64.0).contains(&quality) {
        return Err(PyValueError::new_err(format!(
            "quality must be in [1, 64], got {quality}"
        )));
    }
    let strips = StripOptions::default().with_quality(quality).map_err(bad)?;
    let mut options = FilterOptions::RENDER;
    if let Some(e) = quadtree.error_bound {
        options = options.with_error_bound(e).map_err(bad)?;
    }
    if let Some(n) = quadtree.budget {
        let n = u64::try_from(n)
            .ok()
            .filter(|&n| n >= 1)
            .ok_or_else(|| PyValueError::new_err(format!("budget must be at least 1, got {n}")))?;
        options = options.with_budget(n).map_err(bad)?;
    }
    if let Some(k) = quadtree.level {
        options = options.with_level(crate::check_level(k, "level")?);
    }
    Ok(match name {
        "quadtree" => TextureFilter::Quadtree(options),
        "nearest" => TextureFilter::Nearest,
        "bilinear" => TextureFilter::Bilinear,
        "trilinear" => TextureFilter::Trilinear,
        "ewa" => TextureFilter::Ewa {
            max_anisotropy: EWA_ANISOTROPY,
        },
        "sat" => TextureFilter::Sat(strips),
        other => match other.strip_prefix("supersample:").map(str::parse::<u32>) {
            Some(Ok(n @ 1..=64)) => TextureFilter::Supersample(n),
            Some(Ok(n)) => {
                return Err(PyValueError::new_err(format!(
                    "filter supersample:{n}: the sample grid must be 1..=64 per side"
                )));
            }
            _ => {
                return Err(PyValueError::new_err(format!(
                    "unknown filter {other:?} (expected \"quadtree\", \"nearest\", \"bilinear\", \"supersample:N\", \"trilinear\", \"ewa\" or \"sat\")"
                )));
            }
        },
    })
}

/// `pixel_filter=`.
fn parse_pixel_filter(name: &str) -> PyResult<PixelFilter> {
    match name {
        "box" => Ok(PixelFilter::Box),
        "tent" => Ok(PixelFilter::Tent),
        "mitchell" => Ok(PixelFilter::Mitchell),
        other => Err(PyValueError::new_err(format!(
            "unknown pixel_filter {other:?} (expected \"box\", \"tent\" or \"mitchell\")"
        ))),
    }
}

/// `width=` or `height=`: None, or at least 1 (the render checks the total).
fn size(value: Option<i64>, name: &str) -> PyResult<Option<u32>> {
    value
        .map(|v| {
            u32::try_from(v).ok().filter(|&v| v >= 1).ok_or_else(|| {
                PyValueError::new_err(format!("{name} must be at least 1 pixel, got {v}"))
            })
        })
        .transpose()
}

/// `frames=`: in `1..=MAX_PATH_FRAMES`, as `--frames`.
fn frame_count(frames: i64) -> PyResult<u32> {
    let max = quadtex_render::MAX_PATH_FRAMES;
    u32::try_from(frames)
        .ok()
        .filter(|f| (1..=max).contains(f))
        .ok_or_else(|| PyValueError::new_err(format!("frames must be in 1..={max}, got {frames}")))
}

/// A camera path's refusal of a frame, naming the file.
fn path_error(path: &Path, message: &str) -> PyErr {
    PyValueError::new_err(format!("{}: {message}", path.display()))
}

/// A `quadtex-render` error as an exception: the system's refusal of a file
/// as `OSError` (as `quadtex-io`'s), anything else as `ValueError`.
pub(crate) fn render_error(e: quadtex_render::Error) -> PyErr {
    match e {
        quadtex_render::Error::Io { path, source } => {
            io_error(quadtex_io::Error::Io { path, source })
        }
        other => PyValueError::new_err(other.to_string()),
    }
}

/// `render(progress=True)`'s line for the row count `done` of `total`, when
/// it ends a band. Called from the render's worker threads, each count
/// once; standard error is written directly (no GIL) and a failed write
/// ignored.
fn report_rows(done: u64, total: u64) {
    let band = |rows: u64| rows * PROGRESS_BANDS / total.max(1);
    if done > 0 && band(done) > band(done - 1) {
        let _ = writeln!(
            std::io::stderr().lock(),
            "quadtex: rendered {done}/{total} rows ({}%)",
            100 * done / total.max(1)
        );
    }
}

/// `render(return_summary=True)`'s dict.
fn summary_dict<'py>(py: Python<'py>, s: &RenderSummary) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("width", s.width)?;
    d.set_item("height", s.height)?;
    d.set_item("seconds", s.seconds)?;
    d.set_item("textured_pixels", s.textured_pixels)?;
    d.set_item("max_error_bound", s.filter.max_error_bound)?;
    d.set_item(
        "mean_error_bound",
        s.filter.sum_error_bound / s.textured_pixels.max(1) as f64,
    )?;
    d.set_item("over_target", s.filter.over_target)?;
    d.set_item("max_weight_error", s.max_weight_error)?;
    d.set_item("text", s.to_string())?;
    Ok(d)
}

/// Registers `Scene` and `Camera`.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Scene>()?;
    m.add_class::<Camera>()?;
    Ok(())
}

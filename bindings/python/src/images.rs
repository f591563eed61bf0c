//! Rendered images out: `to_srgb8` (the bytes `quadtex render -o x.png`
//! stores) and `save_image` (PNG or OpenEXR by extension, atomically), both
//! through `quadtex-io`'s own code path.

use std::path::PathBuf;

use numpy::ndarray::{ArrayView3, Axis, Ix3};
use numpy::{
    PyArray1, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use quadtex_core::Rgba;
use quadtex_io::LinearImage;

use crate::errors::io_error;

/// `image` (array-like, `(H, W, 4)`, floating point) as linear premultiplied
/// pixels, row 0 at the top; `TypeError` for another dtype, `ValueError`
/// for another shape.
fn linear_image(image: &Bound<'_, PyAny>) -> PyResult<LinearImage> {
    let np = image.py().import("numpy")?;
    let arr = np
        .call_method1("asarray", (image,))?
        .cast_into::<PyUntypedArray>()?;
    let dtype = arr.dtype();
    if dtype.kind() != b'f' {
        return Err(PyTypeError::new_err(format!(
            "image must be floating point (linear, premultiplied RGBA), got dtype {dtype}"
        )));
    }
    let dims = arr.shape().to_vec();
    let (h, w) = match dims[..] {
        [h, w, 4] => (h, w),
        _ => {
            let dims: Vec<String> = dims.iter().map(usize::to_string).collect();
            let trailing = if dims.len() == 1 { "," } else { "" };
            return Err(PyValueError::new_err(format!(
                "image must have shape (H, W, 4), got ({}{trailing})",
                dims.join(", ")
            )));
        }
    };
    let width = u32::try_from(w).ok().filter(|&w| w >= 1);
    let height = u32::try_from(h).ok().filter(|&h| h >= 1);
    let (Some(width), Some(height)) = (width, height) else {
        return Err(PyValueError::new_err(format!(
            "image must be at least 1x1 pixels, got {w}x{h}"
        )));
    };
    let f32s = np
        .call_method1("asarray", (arr, "float32"))?
        .cast_into::<PyArrayDyn<f32>>()?;
    let readonly = f32s.try_readonly()?;
    let view: ArrayView3<'_, f32> = readonly
        .as_array()
        .into_dimensionality::<Ix3>()
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let pixels = view
        .lanes(Axis(2))
        .into_iter()
        .map(|p| Rgba::new(p[0], p[1], p[2], p[3]))
        .collect();
    Ok(LinearImage {
        width,
        height,
        pixels,
    })
}

/// Encodes a rendered image as 8-bit sRGB with straight alpha: the bytes
/// `quadtex render -o x.png` writes (the same code).
///
/// Parameters:
///   image: `(H, W, 4)` array-like, floating point (float64 is rounded to
///     float32 first): linear light, premultiplied RGBA, as
///     `Scene.render` returns.
///
/// Returns: `(H, W, 4)` uint8: each colour divided by alpha (0 where alpha
/// is not above 0) and sRGB-encoded (NaN and below 0 give 0, above 1 give
/// 255), alpha `round(255·clip(a, 0, 1))`.
///
/// Raises: ValueError (a shape other than `(H, W, 4)`, an empty image),
/// TypeError (not floating point). The GIL is released while encoding.
#[pyfunction]
#[pyo3(signature = (image))]
fn to_srgb8<'py>(image: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    let py = image.py();
    let linear = linear_image(image)?;
    let bytes = py.detach(|| quadtex_io::srgb8_from_linear(&linear.pixels));
    let shape = [linear.height as usize, linear.width as usize, 4];
    Ok(PyArray1::from_vec(py, bytes).reshape(shape)?.into_any())
}

/// Writes a rendered image, atomically (a temporary file in the same
/// directory, renamed over `path`), as `quadtex render -o` writes it; the
/// format follows the extension: `.png` (8-bit sRGB, straight alpha: the
/// bytes of `to_srgb8`) or `.exr` (32-bit float, linear, premultiplied).
///
/// Parameters:
///   path: str, bytes or os.PathLike ending in .png or .exr (any case).
///   image: `(H, W, 4)` array-like, floating point: linear light,
///     premultiplied RGBA, as `Scene.render` returns.
///
/// Returns: None.
///
/// Raises: ValueError (another extension, a shape other than `(H, W, 4)`,
/// an empty image), TypeError (not floating point), OSError when the system
/// refuses (e.g. IsADirectoryError, FileNotFoundError for a missing folder;
/// `errno` and `filename` set). The GIL is released while encoding and
/// writing.
#[pyfunction]
#[pyo3(signature = (path, image))]
fn save_image(py: Python<'_>, path: PathBuf, image: &Bound<'_, PyAny>) -> PyResult<()> {
    let linear = linear_image(image)?;
    py.detach(|| quadtex_io::save_image(&path, &linear))
        .map_err(io_error)
}

/// Registers `to_srgb8` and `save_image`.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(to_srgb8, m)?)?;
    m.add_function(wrap_pyfunction!(save_image, m)?)?;
    Ok(())
}

//! numpy arrays in and out: footprints and rectangles as `float64` views,
//! images as linear premultiplied texels.
//!
//! Inputs go through `numpy.asarray`, so lists and any array (strided,
//! sliced, Fortran-ordered, another byte order) are accepted; the views read
//! them in place when their dtype already matches, converted copies otherwise.

use std::ops::Range;
use std::sync::OnceLock;

use numpy::ndarray::{ArrayView, ArrayView1, ArrayView2, ArrayView3, Axis, Ix2, Ix3, RemoveAxis};
use numpy::{
    PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use quadtex_core::MAX_DIMENSION;
use quadtex_core::{Rgba, TexelGrid, Unorm16Rgba};

/// A shape as Python prints it: `(3, 4)`, `(5,)`.
fn shape_text(dims: &[usize]) -> String {
    match dims {
        [d] => format!("({d},)"),
        _ => format!(
            "({})",
            dims.iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// `numpy.asarray(obj, **kwargs)` as an untyped array.
fn asarray<'py>(
    obj: &Bound<'py, PyAny>,
    dtype: Option<&str>,
) -> PyResult<Bound<'py, PyUntypedArray>> {
    let np = obj.py().import("numpy")?;
    let arr = match dtype {
        None => np.call_method1("asarray", (obj,))?,
        Some(d) => np.call_method1("asarray", (obj, d))?,
    };
    Ok(arr.cast_into::<PyUntypedArray>()?)
}

/// `obj` as a float64 array of shape `shape` (`None`: any length), or a
/// `TypeError` (not real numbers) / `ValueError` (shape) naming `name`.
pub(crate) fn float64<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    shape: &[Option<usize>],
    expected: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let arr = asarray(obj, None)?;
    let dtype = arr.dtype();
    if !matches!(dtype.kind(), b'f' | b'i' | b'u') {
        return Err(PyTypeError::new_err(format!(
            "{name} must hold real numbers, got dtype {dtype}"
        )));
    }
    let dims = arr.shape();
    let fits = dims.len() == shape.len()
        && dims
            .iter()
            .zip(shape)
            .all(|(d, s)| s.is_none_or(|s| s == *d));
    if !fits {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape {expected}, got {}",
            shape_text(dims)
        )));
    }
    Ok(asarray(arr.as_any(), Some("float64"))?.cast_into::<PyArrayDyn<f64>>()?)
}

/// The `(N, 4, 2)` view of a checked array.
pub(crate) fn view3<'a>(a: &'a PyReadonlyArrayDyn<'_, f64>) -> PyResult<ArrayView3<'a, f64>> {
    a.as_array()
        .into_dimensionality::<Ix3>()
        .map_err(|e| PyValueError::new_err(e.to_string()))
}

/// The `(N, 4)` view of a checked array.
pub(crate) fn view2<'a>(a: &'a PyReadonlyArrayDyn<'_, f64>) -> PyResult<ArrayView2<'a, f64>> {
    a.as_array()
        .into_dimensionality::<Ix2>()
        .map_err(|e| PyValueError::new_err(e.to_string()))
}

/// Rows `rows` of `view` (along its first axis), each its `W` numbers in
/// C order, appended to `out`: a C-ordered array's at once, another's
/// number by number. `W` is the row's size the caller checked.
pub(crate) fn copy_rows<D: RemoveAxis, const W: usize>(
    view: &ArrayView<'_, f64, D>,
    rows: Range<usize>,
    out: &mut Vec<[f64; W]>,
) {
    match view.as_slice() {
        Some(all) => out.extend(
            all[W * rows.start..W * rows.end]
                .chunks_exact(W)
                .map(|row| std::array::from_fn(|k| row[k])),
        ),
        None => out.extend(rows.map(|i| {
            let row = view.index_axis(Axis(0), i);
            let mut numbers = row.iter().copied();
            std::array::from_fn(|_| numbers.next().unwrap_or(f64::NAN))
        })),
    }
}

/// An image array held for reading: `H×W` or `H×W×C`, `C` in 1..=4 (grey,
/// grey+alpha, RGB, RGBA).
pub(crate) enum ImageArray<'py> {
    /// sRGB-encoded, straight alpha (as an 8-bit PNG).
    U8(PyReadonlyArrayDyn<'py, u8>),
    /// sRGB-encoded, straight alpha (as a 16-bit PNG).
    U16(PyReadonlyArrayDyn<'py, u16>),
    /// Linear, premultiplied alpha (as OpenEXR); other float widths are
    /// converted to float32.
    F32(PyReadonlyArrayDyn<'py, f32>),
}

/// A view of an [`ImageArray`] as `H×W×C` (sendable to a thread without the GIL).
pub(crate) enum ImageView<'a> {
    U8(ArrayView3<'a, u8>),
    U16(ArrayView3<'a, u16>),
    F32(ArrayView3<'a, f32>),
}

impl<'py> ImageArray<'py> {
    /// Checks dtype and shape of an image given as an array.
    pub(crate) fn from_py(obj: &Bound<'py, PyAny>) -> PyResult<ImageArray<'py>> {
        let arr = asarray(obj, None)?;
        let dims = arr.shape().to_vec();
        let channels_ok = match dims.len() {
            2 => true,
            3 => (1..=4).contains(&dims[2]),
            _ => false,
        };
        if !channels_ok {
            return Err(PyValueError::new_err(format!(
                "image must have shape (H, W) or (H, W, C) with C in 1..4, got {}",
                shape_text(&dims)
            )));
        }
        let (h, w) = (dims[0], dims[1]);
        if h == 0 || w == 0 || h > MAX_DIMENSION as usize || w > MAX_DIMENSION as usize {
            return Err(PyValueError::new_err(format!(
                "image must be 1 to {MAX_DIMENSION} texels on a side, got {w}x{h}"
            )));
        }
        let dtype = arr.dtype();
        let any = arr.as_any();
        Ok(match (dtype.kind(), dtype.itemsize()) {
            (b'u', 1) => ImageArray::U8(
                asarray(any, Some("uint8"))?
                    .cast_into::<PyArrayDyn<u8>>()?
                    .try_readonly()?,
            ),
            (b'u', 2) => ImageArray::U16(
                asarray(any, Some("uint16"))?
                    .cast_into::<PyArrayDyn<u16>>()?
                    .try_readonly()?,
            ),
            (b'f', _) => ImageArray::F32(
                asarray(any, Some("float32"))?
                    .cast_into::<PyArrayDyn<f32>>()?
                    .try_readonly()?,
            ),
            _ => {
                return Err(PyTypeError::new_err(format!(
                    "image dtype must be uint8 or uint16 (sRGB, straight alpha) or floating point (linear, premultiplied), got {dtype}"
                )));
            }
        })
    }

    /// The `H×W×C` view; float images are checked for NaN and infinity.
    pub(crate) fn view(&self) -> PyResult<ImageView<'_>> {
        fn hwc<'a, T>(a: &'a PyReadonlyArrayDyn<'_, T>) -> PyResult<ArrayView3<'a, T>>
        where
            T: numpy::Element,
        {
            let v = a.as_array();
            let v = if v.ndim() == 2 {
                v.insert_axis(Axis(2))
            } else {
                v
            };
            v.into_dimensionality::<Ix3>()
                .map_err(|e| PyValueError::new_err(e.to_string()))
        }
        Ok(match self {
            ImageArray::U8(a) => ImageView::U8(hwc(a)?),
            ImageArray::U16(a) => ImageView::U16(hwc(a)?),
            ImageArray::F32(a) => {
                let v = hwc(a)?;
                if let Some(((r, c, k), x)) = v.indexed_iter().find(|(_, x)| !x.is_finite()) {
                    let index = if a.ndim() == 2 {
                        format!("{r}, {c}")
                    } else {
                        format!("{r}, {c}, {k}")
                    };
                    return Err(PyValueError::new_err(format!(
                        "image[{index}] is not finite ({x})"
                    )));
                }
                ImageView::F32(v)
            }
        })
    }
}

/// sRGB-encoded 16-bit value → linear, built exactly as `quadtex-io` builds
/// its PNG decoding table (8-bit values are widened by ×257 first).
fn decode_table() -> &'static [f32] {
    static TABLE: OnceLock<Vec<f32>> = OnceLock::new();
    TABLE.get_or_init(|| {
        (0..=u16::MAX)
            .map(|v| quadtex_core::srgb_decode_f32(f32::from(v) / 65535.0))
            .collect()
    })
}

/// Grey, grey+alpha, RGB or RGBA channels (one pixel's lane, each mapped
/// by `f`) as RGBA: grey replicated, alpha `opaque` when absent, as the
/// image decoder widens them.
fn rgba<T: Copy, U: Copy>(px: ArrayView1<'_, T>, opaque: U, f: impl Fn(T) -> U) -> [U; 4] {
    let at = |i: usize| f(px[i]);
    match px.len() {
        1 => [at(0), at(0), at(0), opaque],
        2 => [at(0), at(0), at(0), at(1)],
        3 => [at(0), at(1), at(2), opaque],
        _ => [at(0), at(1), at(2), at(3)],
    }
}

impl ImageView<'_> {
    /// The texels, as `quadtex-io` decodes a PNG (integers: sRGB, straight
    /// alpha, premultiplied after decoding; 8-bit ones kept for texel
    /// blocks) or, with `hdr`, an OpenEXR file (floats: linear,
    /// premultiplied, unclamped, alpha clamped to `[0,1]`, NaN and infinity
    /// refused). Floats without `hdr` are clamped: alpha to `[0,1]`,
    /// colour to `[0, alpha]`; without alpha, colour to `[0,1]`.
    pub(crate) fn to_texels(&self, hdr: bool) -> Result<TexelGrid, quadtex_core::Error> {
        let (h, w, _) = match self {
            ImageView::U8(v) => v.dim(),
            ImageView::U16(v) => v.dim(),
            ImageView::F32(v) => v.dim(),
        };
        match self {
            ImageView::U8(v) => {
                let bytes = v
                    .lanes(Axis(2))
                    .into_iter()
                    .map(|px| rgba(px, u8::MAX, |x| x))
                    .collect();
                return TexelGrid::from_srgb8(dim_u32(w), dim_u32(h), bytes);
            }
            ImageView::F32(v) if hdr => {
                let texels: Vec<[f32; 4]> = v
                    .lanes(Axis(2))
                    .into_iter()
                    .map(|px| rgba(px, 1.0, |x| x))
                    .collect();
                return TexelGrid::from_linear_f32(dim_u32(w), dim_u32(h), &texels);
            }
            _ => {}
        }
        let mut texels: Vec<Unorm16Rgba> = Vec::with_capacity(h * w);
        let lut = decode_table();
        let srgb = |p: [u16; 4]| {
            let a = f32::from(p[3]) / 65535.0;
            let c = |v: u16| lut[usize::from(v)] * a;
            Rgba::new(c(p[0]), c(p[1]), c(p[2]), a).to_unorm16()
        };
        match self {
            ImageView::U8(v) => texels.extend(
                v.lanes(Axis(2))
                    .into_iter()
                    .map(|px| srgb(rgba(px, u16::MAX, |x| u16::from(x) * 257))),
            ),
            ImageView::U16(v) => texels.extend(
                v.lanes(Axis(2))
                    .into_iter()
                    .map(|px| srgb(rgba(px, u16::MAX, |x| x))),
            ),
            ImageView::F32(v) => texels.extend(v.lanes(Axis(2)).into_iter().map(|px| {
                let [r, g, b, a] = rgba(px, 1.0, |x| x);
                let a = a.clamp(0.0, 1.0);
                let c = |v: f32| v.clamp(0.0, a);
                Rgba::new(c(r), c(g), c(b), a).to_unorm16()
            })),
        }
        TexelGrid::new(dim_u32(w), dim_u32(h), texels)
    }
}

/// A dimension already checked against `MAX_DIMENSION`.
fn dim_u32(v: usize) -> u32 {
    u32::try_from(v).unwrap_or(u32::MAX)
}

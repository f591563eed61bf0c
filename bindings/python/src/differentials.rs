//! Footprints from ray differentials (`Footprint::from_differentials`),
//! vectorised: what a renderer with texture-coordinate derivatives hands
//! `Texture.filter`.

use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use quadtex_core::Footprint;

use crate::arrays;

/// The footprints a renderer's ray differentials give: parallelograms, the
/// pixel's corners `(0,0), (1,0), (1,1), (0,1)` at `st + (i − ½)·dpdx +
/// (j − ½)·dpdy` for corner `(i, j)` (Rust's
/// `Footprint::from_differentials`), ready for `Texture.filter`.
///
/// Parameters:
///   points: `(N, 2)` array-like, the texture point `(x, z)` at each pixel's
///     centre (any real dtype, read as float64).
///   dpdx: `(N, 2)`, its change per pixel step to the right on the screen.
///   dpdy: `(N, 2)`, its change per pixel step down the screen (the pixel
///     `y` axis runs down).
///
/// Returns: `(N, 4, 2)` float64, the corners in pixel order.
///
/// Raises: ValueError (a shape other than `(N, 2)` or lengths that differ;
/// a coordinate that is not finite, naming it, e.g. `dpdx[3, 1]`; a corner
/// beyond 1e15, naming the row), TypeError (not real numbers).
#[pyfunction]
#[pyo3(signature = (points, dpdx, dpdy))]
fn footprints_from_differentials<'py>(
    points: &Bound<'py, PyAny>,
    dpdx: &Bound<'py, PyAny>,
    dpdy: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let py = points.py();
    let names = ["points", "dpdx", "dpdy"];
    let arrays = [points, dpdx, dpdy]
        .into_iter()
        .zip(names)
        .map(|(a, name)| Ok(arrays::float64(a, name, &[None, Some(2)], "(N, 2)")?.try_readonly()?))
        .collect::<PyResult<Vec<_>>>()?;
    let views = arrays
        .iter()
        .map(arrays::view2)
        .collect::<PyResult<Vec<_>>>()?;
    let n = views[0].shape()[0];
    for (v, name) in views.iter().zip(names).skip(1) {
        if v.shape()[0] != n {
            return Err(PyValueError::new_err(format!(
                "{name} has {} rows, points has {n}",
                v.shape()[0]
            )));
        }
    }
    for (v, name) in views.iter().zip(names) {
        if let Some(((i, k), x)) = v.indexed_iter().find(|(_, x)| !x.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "{name}[{i}, {k}] is not finite ({x})"
            )));
        }
    }
    let mut out: Vec<f64> = Vec::with_capacity(8 * n);
    for i in 0..n {
        let row = |v: usize| [views[v][[i, 0]], views[v][[i, 1]]];
        let footprint = Footprint::from_differentials(row(0), row(1), row(2))
            .map_err(|e| PyValueError::new_err(format!("row {i}: {e}")))?;
        out.extend(footprint.corners().iter().flatten());
    }
    PyArray1::from_vec(py, out)
        .reshape([n, 4, 2])
        .map(Bound::into_any)
}

/// Registers `footprints_from_differentials`.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(footprints_from_differentials, m)?)?;
    Ok(())
}

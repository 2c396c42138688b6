//! Bindings of `imgform_core::lightfield`.

use imgform_core::image::Sample;
use imgform_core::lightfield::{self, LightField};
use numpy::{Element, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::arrays::{contiguous, detached_into, image_dims, AnyImage};
use crate::dispatch_image;

/// `(H, W, C)` of one view of `grid` views stacked along the first axis of
/// an `(U * V * H, W, C)` array.
fn view_dims(shape: &[usize], grid: (usize, usize)) -> PyResult<(usize, usize, usize)> {
    let (rows, w, c) = image_dims(shape, "views")?;
    // Checked: a grid whose product wraps (3 x 0xAAAA...AB is 1) passed.
    let n = grid.0.checked_mul(grid.1).unwrap_or(0);
    if n == 0 || rows % n != 0 {
        return Err(PyValueError::new_err(format!(
            "views must stack grid {grid:?} = {n} views of equal height along axis 0, got shape {shape:?}"
        )));
    }
    Ok((rows / n, w, c))
}

/// Refocuses one sample type into a new `(N, H, W, C)` array.
fn stack<'py, T: Sample + Element>(
    views: PyReadonlyArrayDyn<'py, T>,
    grid: (usize, usize),
    alphas: &[f64],
    aperture: &[bool],
) -> PyResult<Bound<'py, PyAny>> {
    let py = views.py();
    let (h, w, c) = view_dims(views.shape(), grid)?;
    let src = contiguous(&views)?;
    let shape = [alphas.len(), h, w, c];
    let out = detached_into(py, &shape, |out: &mut [T]| {
        let lf = LightField::new(&src, grid, h, w, c)?;
        lightfield::focal_stack(lf, alphas, aperture, out)
    })?;
    Ok(out.into_any())
}

/// Shift-and-add refocusing of `grid` views stacked as `(U * V * H, W, C)`
/// at each disparity of `alphas`, averaging the views flagged in `aperture`
/// (row-major, `U * V` flags): an `(N, H, W, C)` stack of the input dtype.
#[pyfunction]
fn focal_stack<'py>(
    views: &Bound<'py, PyAny>,
    grid: (usize, usize),
    alphas: Vec<f64>,
    aperture: Vec<bool>,
) -> PyResult<Bound<'py, PyAny>> {
    let img = AnyImage::extract(views, "views")?;
    dispatch_image!(img, stack(grid, &alphas, &aperture))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(focal_stack, m)?)?;
    Ok(())
}

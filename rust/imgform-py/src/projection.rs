//! Bindings of `imgform_core::projection`.

use imgform_core::projection;
use numpy::{PyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::arrays::{contiguous, detached_into, points};

/// Pinhole projection of camera-frame points (N, 3) -> (N, 2).
#[pyfunction]
#[pyo3(signature = (points_cam, f, invert=true))]
fn project_pinhole<'py>(
    py: Python<'py>,
    points_cam: &Bound<'py, PyAny>,
    f: f64,
    invert: bool,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let arr = points(points_cam, 3, "points")?;
    let n = arr.shape()[0];
    let src = contiguous(&arr)?;
    detached_into(py, &[n, 2], |out| {
        projection::project_pinhole(&src, f, invert, out)
    })
}

/// Orthographic projection (N, 3) -> (N, 2).
#[pyfunction]
#[pyo3(signature = (points_cam, scale=1.0))]
fn project_orthographic<'py>(
    py: Python<'py>,
    points_cam: &Bound<'py, PyAny>,
    scale: f64,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let arr = points(points_cam, 3, "points")?;
    let n = arr.shape()[0];
    let src = contiguous(&arr)?;
    detached_into(py, &[n, 2], |out| {
        projection::project_orthographic(&src, scale, out)
    })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(project_pinhole, m)?)?;
    m.add_function(wrap_pyfunction!(project_orthographic, m)?)?;
    Ok(())
}

//! Bindings of `imgform_core::metrology`.

use imgform_core::metrology::{self, FitOptions, GroundMetric};
use numpy::{PyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::arrays::{contiguous, detached_into, fixed, points, to_numpy};
use crate::camera::vec3;
use crate::errors::{detached, to_pyerr};

/// A float64 array of shape (2,) as a pixel.
fn pixel(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<[f64; 2]> {
    Ok(fixed(obj, &[2], name)?
        .try_into()
        .expect("checked shape (2,)"))
}

/// (homogeneous (3,), at_infinity, residual, inliers (N,) bool) of segments (N, 4).
#[pyfunction]
#[pyo3(signature = (segments, threshold, seed, allow_infinite))]
#[allow(clippy::type_complexity)]
fn fit_vanishing_point<'py>(
    py: Python<'py>,
    segments: &Bound<'py, PyAny>,
    threshold: f64,
    seed: u64,
    allow_infinite: bool,
) -> PyResult<((f64, f64, f64), bool, f64, Bound<'py, PyArrayDyn<bool>>)> {
    let arr = points(segments, 4, "segments")?;
    let n = arr.shape()[0];
    let src = contiguous(&arr)?;
    let opts = FitOptions {
        threshold,
        seed,
        allow_infinite,
    };
    let fit = detached(py, || metrology::fit_vanishing_point(&src, &opts))?;
    let [a, b, c] = fit.homogeneous;
    let inliers = to_numpy(py, fit.inliers, &[n])?;
    Ok(((a, b, c), fit.at_infinity, fit.residual, inliers))
}

/// The line (a, b, c) through two homogeneous vanishing points.
#[pyfunction]
fn fit_horizon(vp1: &Bound<'_, PyAny>, vp2: &Bound<'_, PyAny>) -> PyResult<(f64, f64, f64)> {
    let [a, b, c] =
        metrology::fit_horizon(vec3(vp1, "vp1")?, vec3(vp2, "vp2")?).map_err(to_pyerr)?;
    Ok((a, b, c))
}

/// The validated ground metric of a horizon, vertical VP and reference.
fn ground_metric(
    horizon: &Bound<'_, PyAny>,
    vertical_vp: &Bound<'_, PyAny>,
    ref_base: &Bound<'_, PyAny>,
    ref_top: &Bound<'_, PyAny>,
    ref_height: f64,
) -> PyResult<GroundMetric> {
    GroundMetric::new(
        vec3(horizon, "horizon")?,
        vec3(vertical_vp, "vertical_vp")?,
        pixel(ref_base, "ref_base")?,
        pixel(ref_top, "ref_top")?,
        ref_height,
    )
    .map_err(to_pyerr)
}

/// Heights (N,) of objects with bases and tops (N, 2) relative to the reference.
#[pyfunction]
#[pyo3(signature = (horizon, vertical_vp, ref_base, ref_top, ref_height, base, top))]
#[allow(clippy::too_many_arguments)]
fn relative_height<'py>(
    py: Python<'py>,
    horizon: &Bound<'py, PyAny>,
    vertical_vp: &Bound<'py, PyAny>,
    ref_base: &Bound<'py, PyAny>,
    ref_top: &Bound<'py, PyAny>,
    ref_height: f64,
    base: &Bound<'py, PyAny>,
    top: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let metric = ground_metric(horizon, vertical_vp, ref_base, ref_top, ref_height)?;
    let base = points(base, 2, "base")?;
    let top = points(top, 2, "top")?;
    let n = base.shape()[0];
    if top.shape()[0] != n {
        return Err(PyValueError::new_err(format!(
            "top must have the shape of base ({n}, 2), got {:?}",
            top.shape()
        )));
    }
    let (base, top) = (contiguous(&base)?, contiguous(&top)?);
    detached_into(py, &[n], |out| metric.heights(&base, &top, out))
}

/// The camera's height above the ground, in the reference's unit.
#[pyfunction]
#[pyo3(signature = (horizon, vertical_vp, ref_base, ref_top, ref_height))]
fn camera_height(
    horizon: &Bound<'_, PyAny>,
    vertical_vp: &Bound<'_, PyAny>,
    ref_base: &Bound<'_, PyAny>,
    ref_top: &Bound<'_, PyAny>,
    ref_height: f64,
) -> PyResult<f64> {
    Ok(ground_metric(horizon, vertical_vp, ref_base, ref_top, ref_height)?.camera_height())
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(fit_vanishing_point, m)?)?;
    m.add_function(wrap_pyfunction!(fit_horizon, m)?)?;
    m.add_function(wrap_pyfunction!(relative_height, m)?)?;
    m.add_function(wrap_pyfunction!(camera_height, m)?)?;
    Ok(())
}

//! Bindings of `imgform_core::distortion`.

use imgform_core::distortion::{remap_points, Direction, Distortion};
use imgform_core::intrinsics::Intrinsics;
use numpy::{PyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::arrays::{contiguous, filled, fixed, points, to_numpy};
use crate::errors::{detached, to_pyerr};

/// A distortion model from its name and coefficients.
pub fn model(name: &str, coeffs: Vec<f64>) -> PyResult<Distortion> {
    Distortion::new(name, &coeffs).map_err(to_pyerr)
}

/// Intrinsics from an optional (3, 3) float64 matrix, called `name` in
/// errors.
pub fn intrinsics(k: Option<&Bound<'_, PyAny>>, name: &str) -> PyResult<Option<Intrinsics>> {
    k.map(|k| {
        let m: [f64; 9] = fixed(k, &[3, 3], name)?
            .try_into()
            .expect("checked shape (3, 3)");
        Intrinsics::named(name, &m).map_err(to_pyerr)
    })
    .transpose()
}

/// Distorts (`undistort=False`) or undistorts points (N, 2); returns the
/// mapped points (NaN where the model cannot map) and how many failed.
#[pyfunction]
#[pyo3(signature = (pts, coeffs, model_name, k=None, undistort=false))]
fn remap_lens_points<'py>(
    py: Python<'py>,
    pts: &Bound<'py, PyAny>,
    coeffs: Vec<f64>,
    model_name: &str,
    k: Option<&Bound<'py, PyAny>>,
    undistort: bool,
) -> PyResult<(Bound<'py, PyArrayDyn<f64>>, usize)> {
    let lens = model(model_name, coeffs)?;
    let k = intrinsics(k, "K")?;
    let arr = points(pts, 2, "points")?;
    let n = arr.shape()[0];
    let src = contiguous(&arr)?;
    let mut out = filled(2 * n, 0.0, "the output points")?;
    let direction = if undistort {
        Direction::Undistort
    } else {
        Direction::Distort
    };
    let failed = detached(py, || {
        remap_points(&src, &lens, k.as_ref(), direction, &mut out)
    })?;
    Ok((to_numpy(py, out, &[n, 2])?, failed))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(remap_lens_points, m)?)?;
    Ok(())
}

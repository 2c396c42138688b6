//! Bindings of `imgform_core::demosaic`.

use imgform_core::cfa::CfaPattern;
use imgform_core::demosaic::{demosaic as demosaic_kernel, Method, SAMPLE_LIMIT};
use imgform_core::image::{ImageView, Sample};
use numpy::{Element, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::arrays::{contiguous, detached_into_given, AnyImage};
use crate::cfa::pattern_arg;
use crate::dispatch_image;
use crate::errors::to_pyerr;

fn demosaic_typed<'py, T: Sample + Element>(
    arr: PyReadonlyArrayDyn<'py, T>,
    py: Python<'py>,
    p: &CfaPattern,
    method: Method,
    white_level: Option<f32>,
    out: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let (h, w) = match *arr.shape() {
        [h, w] => (h, w),
        ref other => {
            return Err(PyValueError::new_err(format!(
                "raw must be a single-channel mosaic of shape (H, W), got shape {other:?}"
            )))
        }
    };
    let src = contiguous(&arr)?;
    let kernel = |out: &mut [T]| {
        let raw = ImageView::contiguous(&src, w, h, 1)?;
        demosaic_kernel(raw, p, method, white_level, out)
    };
    Ok(detached_into_given(py, out, &[h, w, 3], kernel)?.into_any())
}

/// Demosaics a mosaic (H, W) -> (H, W, 3), same dtype, into a new array or
/// into `out`. `white_level` reaches the kernels as `f32` (where a value
/// beyond its range becomes infinite and is refused there).
#[pyfunction]
#[pyo3(signature = (raw, pattern, method="bilinear", *, white_level=None, out=None))]
fn demosaic<'py>(
    py: Python<'py>,
    raw: &Bound<'py, PyAny>,
    pattern: &Bound<'py, PyAny>,
    method: &str,
    white_level: Option<f64>,
    out: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let p = pattern_arg(pattern)?;
    let method = Method::from_name_for(method, &p).map_err(to_pyerr)?;
    let img = AnyImage::extract(raw, "raw")?;
    let level = white_level.map(|v| v as f32);
    dispatch_image!(img, demosaic_typed(py, &p, method, level, out))
}

/// How far a method's output reaches into the mosaic (see `Method::halo`),
/// an alias's being that of the method it selects for the pattern.
#[pyfunction]
fn demosaic_halo(method: &str, pattern: &Bound<'_, PyAny>) -> PyResult<usize> {
    let pattern = pattern_arg(pattern)?;
    let method = Method::from_name_for(method, &pattern).map_err(to_pyerr)?;
    method.check_supports(&pattern).map_err(to_pyerr)?;
    Ok(method.halo(&pattern))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(demosaic, m)?)?;
    m.add_function(wrap_pyfunction!(demosaic_halo, m)?)?;
    m.add("DEMOSAIC_METHODS", PyTuple::new(m.py(), Method::names())?)?;
    let xtrans = PyTuple::new(m.py(), Method::names_for(true))?;
    m.add("XTRANS_DEMOSAIC_METHODS", xtrans)?;
    let bayer = PyTuple::new(m.py(), Method::names_for(false))?;
    m.add("BAYER_DEMOSAIC_METHODS", bayer)?;
    let scaled: Vec<&str> = Method::names()
        .into_iter()
        .filter(|name| Method::from_name(name).is_ok_and(Method::scaled))
        .collect();
    m.add("SCALED_DEMOSAIC_METHODS", PyTuple::new(m.py(), scaled)?)?;
    m.add("DEMOSAIC_SAMPLE_LIMIT", SAMPLE_LIMIT)?;
    Ok(())
}

//! Bindings of `imgform_core::develop`.

use imgform_core::cfa::CfaPattern;
use imgform_core::demosaic::Method;
use imgform_core::develop::{develop as develop_kernel, DevelopParams, Tone};
use imgform_core::image::{ImageView, Sample};
use numpy::{Element, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::arrays::{contiguous, describe, detached_into, fixed};
use crate::cfa::pattern_arg;
use crate::errors::to_pyerr;

fn run<'py, U: Sample + Element>(
    py: Python<'py>,
    src: &[u16],
    (h, w): (usize, usize),
    pattern: &CfaPattern,
    params: &DevelopParams,
) -> PyResult<Bound<'py, PyAny>> {
    let out = detached_into(py, &[h, w, 3], |out: &mut [U]| {
        develop_kernel(ImageView::contiguous(src, w, h, 1)?, pattern, params, out)
    })?;
    Ok(out.into_any())
}

fn f32s(v: Vec<f64>) -> Vec<f32> {
    v.into_iter().map(|x| x as f32).collect()
}

/// Develops a uint16 mosaic (H, W) -> (H, W, 3) uint8 / uint16 / float32.
#[pyfunction]
#[pyo3(signature = (raw, pattern, black, scale, matrix, tone, method, bps))]
#[allow(clippy::too_many_arguments)]
fn develop<'py>(
    py: Python<'py>,
    raw: &Bound<'py, PyAny>,
    pattern: &Bound<'py, PyAny>,
    black: &Bound<'py, PyAny>,
    scale: &Bound<'py, PyAny>,
    matrix: &Bound<'py, PyAny>,
    tone: &str,
    method: &str,
    bps: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let arr = raw.extract::<PyReadonlyArrayDyn<'py, u16>>().map_err(|_| {
        PyTypeError::new_err(format!(
            "raw must be a uint16 mosaic of shape (H, W), got {}",
            describe(raw)
        ))
    })?;
    let (h, w) = match *arr.shape() {
        [h, w] => (h, w),
        ref other => {
            return Err(PyValueError::new_err(format!(
                "raw must be a mosaic of shape (H, W), got shape {other:?}"
            )))
        }
    };
    let pattern = pattern_arg(pattern)?;
    let tile = [pattern.period(), pattern.period()];
    let m = f32s(fixed(matrix, &[3, 3], "matrix")?);
    let params = DevelopParams {
        black: f32s(fixed(black, &tile, "black")?),
        scale: f32s(fixed(scale, &tile, "scale")?),
        matrix: [m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]],
        tone: Tone::from_name(tone).map_err(to_pyerr)?,
        method: Method::from_name(method).map_err(to_pyerr)?,
    };
    let src = contiguous(&arr);
    match bps {
        "8" => run::<u8>(py, &src, (h, w), &pattern, &params),
        "16" => run::<u16>(py, &src, (h, w), &pattern, &params),
        "float" => run::<f32>(py, &src, (h, w), &pattern, &params),
        other => Err(PyValueError::new_err(format!(
            "bps must be \"8\", \"16\" or \"float\", got {other:?}"
        ))),
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(develop, m)?)?;
    m.add("TONES", PyTuple::new(m.py(), Tone::ALL.map(Tone::name))?)?;
    Ok(())
}

//! Bindings of `imgform_core::cfa`.

use imgform_core::cfa::{self, CfaPattern, SensorParams};
use imgform_core::image::{ImageView, Sample};
use numpy::{Element, PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyString;

use crate::arrays::{contiguous, describe, detached_into, image_dims, to_numpy, AnyImage};
use crate::dispatch_image;
use crate::errors::to_pyerr;

/// A pattern argument: a name, or an int64 array of shape (2, 2) / (6, 6).
pub fn pattern_arg(obj: &Bound<'_, PyAny>) -> PyResult<CfaPattern> {
    if let Ok(s) = obj.downcast::<PyString>() {
        return CfaPattern::from_name(&s.to_cow()?).map_err(to_pyerr);
    }
    let arr = obj.extract::<PyReadonlyArrayDyn<'_, i64>>().map_err(|_| {
        PyTypeError::new_err(format!(
            "pattern must be a str (\"RGGB\", \"BGGR\", \"GRBG\", \"GBRG\", \"XTRANS\") or an int64 array of channel indices of shape (2, 2) or (6, 6), got {}",
            describe(obj)
        ))
    })?;
    let (rows, cols) = match *arr.shape() {
        [r, c] => (r, c),
        ref other => {
            return Err(PyValueError::new_err(format!(
                "a CFA pattern array must have shape (2, 2) or (6, 6), got {other:?}"
            )))
        }
    };
    CfaPattern::from_cells(&contiguous(&arr)?, rows, cols).map_err(to_pyerr)
}

/// The pattern as users see it: its name when it has one, else its tile.
fn pattern_object(py: Python<'_>, p: &CfaPattern) -> PyResult<Py<PyAny>> {
    match p.name() {
        Some(name) => Ok(PyString::new(py, name).into_any().unbind()),
        None => Ok(to_numpy(py, p.cells().to_vec(), &[p.period(), p.period()])?
            .into_any()
            .unbind()),
    }
}

/// The tile of a pattern as a uint8 (period, period) array.
#[pyfunction]
fn pattern_cells<'py>(
    py: Python<'py>,
    pattern: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArrayDyn<u8>>> {
    let p = pattern_arg(pattern)?;
    to_numpy(py, p.cells().to_vec(), &[p.period(), p.period()])
}

/// The pattern of a crop starting at (dy, dx).
#[pyfunction]
fn shift_pattern(
    py: Python<'_>,
    pattern: &Bound<'_, PyAny>,
    dy: isize,
    dx: isize,
) -> PyResult<Py<PyAny>> {
    let p = pattern_arg(pattern)?;
    pattern_object(py, &p.shifted(dy, dx))
}

/// (H, W, 3) and its dimensions, refusing other shapes.
fn rgb_dims(shape: &[usize], name: &str) -> PyResult<(usize, usize)> {
    let (h, w, c) = image_dims(shape, name)?;
    if shape.len() != 3 || c != 3 {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape (H, W, 3), got {shape:?}"
        )));
    }
    Ok((h, w))
}

fn mosaic_typed<'py, T: Sample + Element>(
    arr: PyReadonlyArrayDyn<'py, T>,
    py: Python<'py>,
    p: &CfaPattern,
) -> PyResult<Bound<'py, PyAny>> {
    let (h, w) = rgb_dims(arr.shape(), "rgb")?;
    let src = contiguous(&arr)?;
    let out = detached_into(py, &[h, w], |out| {
        cfa::mosaic(ImageView::contiguous(&src, w, h, 3)?, p, out)
    })?;
    Ok(out.into_any())
}

/// Samples an RGB image (H, W, 3) through a pattern -> (H, W), same dtype.
#[pyfunction]
fn mosaic<'py>(
    py: Python<'py>,
    rgb: &Bound<'py, PyAny>,
    pattern: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let p = pattern_arg(pattern)?;
    let img = AnyImage::extract(rgb, "rgb")?;
    dispatch_image!(img, mosaic_typed(py, &p))
}

/// Boolean masks (H, W, 3): where the pattern samples each channel.
#[pyfunction]
fn channel_masks<'py>(
    py: Python<'py>,
    shape: (usize, usize),
    pattern: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArrayDyn<bool>>> {
    let p = pattern_arg(pattern)?;
    let (h, w) = shape;
    detached_into(py, &[h, w, 3], |out| cfa::channel_masks(w, h, &p, out))
}

fn simulate_typed<'py, T: Sample + Element>(
    arr: PyReadonlyArrayDyn<'py, T>,
    py: Python<'py>,
    p: &CfaPattern,
    params: &SensorParams,
) -> PyResult<Bound<'py, PyAny>> {
    let (h, w) = rgb_dims(arr.shape(), "rgb")?;
    let src = contiguous(&arr)?;
    let out = detached_into(py, &[h, w], |out| {
        cfa::simulate_sensor(ImageView::contiguous(&src, w, h, 3)?, p, params, out)
    })?;
    Ok(out.into_any())
}

/// A noisy uint16 raw (H, W) from a linear RGB image (H, W, 3).
#[pyfunction]
#[pyo3(signature = (rgb, pattern, full_well, read_noise, bit_depth, black_level, seed))]
#[allow(clippy::too_many_arguments)]
fn simulate_sensor<'py>(
    py: Python<'py>,
    rgb: &Bound<'py, PyAny>,
    pattern: &Bound<'py, PyAny>,
    full_well: f64,
    read_noise: f64,
    bit_depth: u32,
    black_level: u32,
    seed: u64,
) -> PyResult<Bound<'py, PyAny>> {
    let p = pattern_arg(pattern)?;
    let img = AnyImage::extract(rgb, "rgb")?;
    let params = SensorParams {
        full_well,
        read_noise,
        bit_depth,
        black_level,
        seed,
    };
    dispatch_image!(img, simulate_typed(py, &p, &params))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(pattern_cells, m)?)?;
    m.add_function(wrap_pyfunction!(shift_pattern, m)?)?;
    m.add_function(wrap_pyfunction!(mosaic, m)?)?;
    m.add_function(wrap_pyfunction!(channel_masks, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_sensor, m)?)?;
    Ok(())
}

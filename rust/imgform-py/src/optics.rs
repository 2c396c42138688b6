//! Bindings of `imgform_core::optics`: every formula through one elementwise
//! helper over 1-D float64 arrays that the Python facade has broadcast.

use imgform_core::optics;
use numpy::{PyArrayDyn, PyReadonlyArray1};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;

use crate::arrays::{contiguous, describe, filled, to_numpy};
use crate::errors::detached;

/// A 1-D float64 array (one broadcast, flattened input).
fn column<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<PyReadonlyArray1<'py, f64>> {
    obj.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name} must be a 1-D float64 array, got {}",
            describe(obj)
        ))
    })
}

/// Runs `formula` over `K` 1-D arrays, each of the common length or of one
/// element, with the GIL released.
fn elementwise<const K: usize, O, F>(
    py: Python<'_>,
    args: [(&Bound<'_, PyAny>, &str); K],
    formula: F,
) -> PyResult<Vec<O>>
where
    O: Send + Copy + Default,
    F: Fn([f64; K]) -> imgform_core::Result<O> + Send + Sync,
{
    let arrays = args
        .iter()
        .map(|(obj, name)| column(obj, name))
        .collect::<PyResult<Vec<_>>>()?;
    let slices = arrays
        .iter()
        .map(contiguous)
        .collect::<PyResult<Vec<_>>>()?;
    let inputs: [&[f64]; K] = std::array::from_fn(|k| &*slices[k]);
    // Inputs are either full length or a single value (a scalar argument);
    // as in NumPy, an empty input makes the result empty.
    let n = if inputs.iter().any(|s| s.is_empty()) {
        0
    } else {
        inputs.iter().map(|s| s.len()).max().unwrap_or(0)
    };
    let mut out = filled(n, O::default(), "the output")?;
    detached(py, || optics::vectorised(inputs, &mut out, formula))?;
    Ok(out)
}

/// A 1-D float64 NumPy array.
type Column<'py> = Bound<'py, PyArrayDyn<f64>>;

/// A 1-D result as a NumPy array.
fn column_out(py: Python<'_>, out: Vec<f64>) -> PyResult<Column<'_>> {
    let n = out.len();
    to_numpy(py, out, &[n])
}

/// Image distance D' from 1/D' + 1/D = 1/f.
#[pyfunction]
fn image_distance<'py>(
    py: Python<'py>,
    f: &Bound<'py, PyAny>,
    d: &Bound<'py, PyAny>,
) -> PyResult<Column<'py>> {
    let out = elementwise(py, [(f, "f"), (d, "D")], |[f, d]| {
        optics::image_distance(f, d)
    })?;
    column_out(py, out)
}

/// Magnification magnitude D'/D.
#[pyfunction]
fn magnification<'py>(
    py: Python<'py>,
    f: &Bound<'py, PyAny>,
    d: &Bound<'py, PyAny>,
) -> PyResult<Column<'py>> {
    let out = elementwise(py, [(f, "f"), (d, "D")], |[f, d]| {
        optics::magnification(f, d)
    })?;
    column_out(py, out)
}

/// Circle-of-confusion diameter on the sensor.
#[pyfunction]
fn circle_of_confusion<'py>(
    py: Python<'py>,
    f: &Bound<'py, PyAny>,
    n: &Bound<'py, PyAny>,
    focus_distance: &Bound<'py, PyAny>,
    d: &Bound<'py, PyAny>,
) -> PyResult<Column<'py>> {
    let args = [
        (f, "f"),
        (n, "N"),
        (focus_distance, "focus_distance"),
        (d, "D"),
    ];
    let out = elementwise(py, args, |[f, n, s, d]| {
        optics::circle_of_confusion(f, n, s, d)
    })?;
    column_out(py, out)
}

/// Depth of field (near, far).
#[pyfunction]
fn depth_of_field<'py>(
    py: Python<'py>,
    f: &Bound<'py, PyAny>,
    n: &Bound<'py, PyAny>,
    focus_distance: &Bound<'py, PyAny>,
    coc: &Bound<'py, PyAny>,
) -> PyResult<(Column<'py>, Column<'py>)> {
    let args = [
        (f, "f"),
        (n, "N"),
        (focus_distance, "focus_distance"),
        (coc, "coc"),
    ];
    let out = elementwise(py, args, |[f, n, s, c]| optics::depth_of_field(f, n, s, c))?;
    let (near, far): (Vec<f64>, Vec<f64>) = out.into_iter().map(|[a, b]| (a, b)).unzip();
    Ok((column_out(py, near)?, column_out(py, far)?))
}

/// Hyperfocal distance f^2 / (N c) + f.
#[pyfunction]
fn hyperfocal_distance<'py>(
    py: Python<'py>,
    f: &Bound<'py, PyAny>,
    n: &Bound<'py, PyAny>,
    coc: &Bound<'py, PyAny>,
) -> PyResult<Column<'py>> {
    let out = elementwise(py, [(f, "f"), (n, "N"), (coc, "coc")], |[f, n, c]| {
        optics::hyperfocal_distance(f, n, c)
    })?;
    column_out(py, out)
}

/// Field of view 2 atan(size / 2f) in radians.
#[pyfunction]
fn field_of_view<'py>(
    py: Python<'py>,
    f: &Bound<'py, PyAny>,
    sensor_size: &Bound<'py, PyAny>,
) -> PyResult<Column<'py>> {
    let out = elementwise(py, [(f, "f"), (sensor_size, "sensor_size")], |[f, s]| {
        optics::field_of_view(f, s)
    })?;
    column_out(py, out)
}

/// Focal length f0 d / d0 that keeps the subject's magnification.
#[pyfunction]
fn dolly_zoom_focal_length<'py>(
    py: Python<'py>,
    f0: &Bound<'py, PyAny>,
    d0: &Bound<'py, PyAny>,
    d: &Bound<'py, PyAny>,
) -> PyResult<Column<'py>> {
    let out = elementwise(py, [(f0, "f0"), (d0, "d0"), (d, "d")], |[f0, d0, d]| {
        optics::dolly_zoom_focal_length(f0, d0, d)
    })?;
    column_out(py, out)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(image_distance, m)?)?;
    m.add_function(wrap_pyfunction!(magnification, m)?)?;
    m.add_function(wrap_pyfunction!(circle_of_confusion, m)?)?;
    m.add_function(wrap_pyfunction!(depth_of_field, m)?)?;
    m.add_function(wrap_pyfunction!(hyperfocal_distance, m)?)?;
    m.add_function(wrap_pyfunction!(field_of_view, m)?)?;
    m.add_function(wrap_pyfunction!(dolly_zoom_focal_length, m)?)?;
    Ok(())
}

//! Bindings of `imgform_core::film`: development, Beer-Lambert transmission,
//! halation and grain.

use imgform_core::film::curve::Curve;
use imgform_core::film::develop::Emulsion;
use imgform_core::film::grain::add_grain;
use imgform_core::film::halation::{halation, Halation};
use imgform_core::film::print::print;
use imgform_core::film::transmit::Dyes;
use numpy::{PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

use crate::arrays::{contiguous, describe, detached_into};
use crate::errors::to_pyerr;

/// A float32 `(H, W, channels)` image and its height and width.
fn planes<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    channels: usize,
) -> PyResult<(PyReadonlyArrayDyn<'py, f32>, usize, usize)> {
    let arr = obj.extract::<PyReadonlyArrayDyn<'py, f32>>().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name} must be a float32 array of shape (H, W, {channels}), got {}",
            describe(obj)
        ))
    })?;
    match *arr.shape() {
        [h, w, c] if c == channels && h > 0 && w > 0 => Ok((arr, h, w)),
        ref other => Err(PyValueError::new_err(format!(
            "{name} must have shape (H, W, {channels}), one plane per layer, got {other:?}"
        ))),
    }
}

/// (H, W, n) float32 exposures -> (H, W, n) float32 densities.
///
/// `curves` holds one `(start, step, densities)` per layer; `matrix` the
/// n x n DIR couplers (receiver-major), `diffusion` their Gaussian sigma in
/// pixels; `halation` the per-layer strengths and spread (pixels) applied
/// first, inside the same kernel.
#[pyfunction]
#[pyo3(signature = (exposure, gain, curves, matrix, diffusion, halation=None))]
fn film_develop<'py>(
    py: Python<'py>,
    exposure: &Bound<'py, PyAny>,
    gain: f64,
    curves: Vec<(f64, f64, Vec<f64>)>,
    matrix: Vec<f64>,
    diffusion: f64,
    halation: Option<(Vec<f64>, f64)>,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let emulsion = emulsion(&curves, &matrix, diffusion)?;
    let halation = halation
        .map(|(strength, sigma)| Halation::new(&strength, sigma))
        .transpose()
        .map_err(to_pyerr)?;
    let n = emulsion.layers();
    let (arr, h, w) = planes(exposure, "exposure", n)?;
    let src = contiguous(&arr)?;
    detached_into(py, &[h, w, n], |out| {
        emulsion.develop(&src, (w, h), gain, halation.as_ref(), out)
    })
}

/// The emulsion of `curves` (one `(start, step, densities)` per layer),
/// DIR `matrix` and `diffusion`.
fn emulsion(curves: &[(f64, f64, Vec<f64>)], matrix: &[f64], diffusion: f64) -> PyResult<Emulsion> {
    let curves = curves
        .iter()
        .map(|(start, step, d)| Curve::new(*start, *step, d))
        .collect::<imgform_core::Result<Vec<_>>>()
        .map_err(to_pyerr)?;
    Emulsion::new(curves, matrix, diffusion).map_err(to_pyerr)
}

/// (H, W, n) float32 densities, a base (L,), dyes (n x L) and responses
/// (m x L) -> (H, W, m) float32 `Σ 10^-D(λ) R(λ)`.
#[pyfunction]
fn film_transmit<'py>(
    py: Python<'py>,
    density: &Bound<'py, PyAny>,
    base: Vec<f64>,
    dyes: Vec<f64>,
    response: Vec<f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let model = Dyes::new(&base, &dyes).map_err(to_pyerr)?;
    let (arr, h, w) = planes(density, "density", model.layers())?;
    if response.is_empty() || !response.len().is_multiple_of(base.len()) {
        return Err(PyValueError::new_err(format!(
            "response must hold (m, {}) values, one per wavelength, got {}",
            base.len(),
            response.len()
        )));
    }
    let m = response.len() / base.len();
    let src = contiguous(&arr)?;
    detached_into(py, &[h, w, m], |out| {
        model.transmit(&src, w, h, &response, out)
    })
}

/// (H, W, n) float32 negative densities, the negative's base (L,) and dyes
/// (n x L), the print light (m x L) and the paper's emulsion (as for
/// `film_develop`) -> (H, W, m) float32 paper densities, in one pass when
/// the paper has no couplers.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn film_print<'py>(
    py: Python<'py>,
    density: &Bound<'py, PyAny>,
    base: Vec<f64>,
    dyes: Vec<f64>,
    light: Vec<f64>,
    curves: Vec<(f64, f64, Vec<f64>)>,
    matrix: Vec<f64>,
    diffusion: f64,
    gain: f64,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let negative = Dyes::new(&base, &dyes).map_err(to_pyerr)?;
    let paper = emulsion(&curves, &matrix, diffusion)?;
    let (arr, h, w) = planes(density, "density", negative.layers())?;
    let src = contiguous(&arr)?;
    detached_into(py, &[h, w, paper.layers()], |out| {
        print(&negative, &src, (w, h), &light, &paper, gain, out)
    })
}

/// (H, W, n) float32 exposures -> the same with halation of per-layer
/// `strength` and Gaussian spread `sigma` (pixels).
#[pyfunction]
fn film_halation<'py>(
    py: Python<'py>,
    exposure: &Bound<'py, PyAny>,
    strength: Vec<f64>,
    sigma: f64,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let n = strength.len();
    let (arr, h, w) = planes(exposure, "exposure", n)?;
    let src = contiguous(&arr)?;
    detached_into(py, &[h, w, n], |out| {
        halation(&src, w, h, &strength, sigma, out)
    })
}

/// (H, W, n) float32 densities -> Poisson grain counts times `per_grain`.
#[pyfunction]
fn film_grain<'py>(
    py: Python<'py>,
    density: &Bound<'py, PyAny>,
    per_grain: Vec<f64>,
    seed: u64,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let n = per_grain.len();
    let (arr, h, w) = planes(density, "density", n)?;
    let src = contiguous(&arr)?;
    detached_into(py, &[h, w, n], |out| {
        add_grain(&src, w, h, &per_grain, seed, out)
    })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(film_develop, m)?)?;
    m.add_function(wrap_pyfunction!(film_transmit, m)?)?;
    m.add_function(wrap_pyfunction!(film_print, m)?)?;
    m.add_function(wrap_pyfunction!(film_halation, m)?)?;
    m.add_function(wrap_pyfunction!(film_grain, m)?)?;
    m.add("FILM_MAX_BLUR", imgform_core::film::diffuse::MAX_SIGMA)?;
    Ok(())
}

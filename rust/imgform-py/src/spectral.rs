//! Bindings of `imgform_core::spectral`: grids, integration, the sensor and
//! photon-transfer statistics.

use imgform_core::spectral::falloff::Falloff;
use imgform_core::spectral::grid::{self, Quadrature};
use imgform_core::spectral::integrate::integrate;
use imgform_core::spectral::ptc::pair_stats;
use imgform_core::spectral::sensor::Sensor;
use numpy::{PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

use crate::arrays::{contiguous, describe, detached_into};
use crate::cfa::pattern_arg;
use crate::errors::{detached, to_pyerr};

/// A float32 array with its shape, refusing every other dtype by name.
fn float32_array<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    accepted: &str,
) -> PyResult<PyReadonlyArrayDyn<'py, f32>> {
    obj.extract::<PyReadonlyArrayDyn<'py, f32>>().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name} must be a float32 array of shape {accepted}, got {}",
            describe(obj)
        ))
    })
}

/// A float64 table of `(rows, cols)` with the given number of columns.
fn table(obj: &Bound<'_, PyAny>, name: &str, cols: usize) -> PyResult<(Vec<f64>, usize)> {
    let arr = obj.extract::<PyReadonlyArrayDyn<'_, f64>>().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name} must be a float64 array of shape (C, {cols}), got {}",
            describe(obj)
        ))
    })?;
    match *arr.shape() {
        [rows, c] if c == cols && rows > 0 => Ok((contiguous(&arr)?.into_owned(), rows)),
        ref other => Err(PyValueError::new_err(format!(
            "{name} must have shape (C, {cols}), one row per channel and one column per \
             wavelength, got {other:?}"
        ))),
    }
}

/// `(height, width, depth)` of an array that must be (H, W, depth).
fn hwl(shape: &[usize], name: &str, depth: usize, what: &str) -> PyResult<(usize, usize)> {
    match *shape {
        [h, w, l] if l == depth && h > 0 && w > 0 => Ok((h, w)),
        _ => Err(PyValueError::new_err(format!(
            "{name} must have shape (H, W, {depth}), {what}, got {shape:?}"
        ))),
    }
}

/// `(H, W, L)` of a spectral image: at least one pixel, and one sample of
/// each (L = 0 divided the work into chunks of none).
fn spectra_dims(shape: &[usize]) -> PyResult<(usize, usize, usize)> {
    match *shape {
        [h, w, l] if h > 0 && w > 0 && l > 0 => Ok((h, w, l)),
        _ => Err(PyValueError::new_err(format!(
            "spectra must have shape (H, W, L), at least one pixel of L >= 1 samples, got {shape:?}"
        ))),
    }
}

/// The cos⁴ falloff of `(cx, cy, pitch_over_focal)`, or none.
fn falloff_arg(falloff: Option<(f64, f64, f64)>) -> PyResult<Option<Falloff>> {
    falloff
        .map(|(cx, cy, ratio)| Falloff::new((cx, cy), ratio).map_err(to_pyerr))
        .transpose()
}

/// Quadrature weights (nm) of a wavelength grid.
#[pyfunction]
fn spectral_weights(wavelengths: Vec<f64>, rule: &str) -> PyResult<Vec<f64>> {
    let rule = Quadrature::from_name(rule).map_err(to_pyerr)?;
    grid::weights(&wavelengths, rule).map_err(to_pyerr)
}

/// Checks a wavelength grid.
#[pyfunction]
fn check_wavelengths(wavelengths: Vec<f64>) -> PyResult<()> {
    grid::check_grid(&wavelengths).map_err(to_pyerr)
}

/// Checks a table of spectra (N, L): finite, >= 0, L samples each.
#[pyfunction]
fn check_spectra(name: &str, spectra: Vec<f64>, grid_len: usize) -> PyResult<usize> {
    grid::check_spectra(name, &spectra, grid_len).map_err(to_pyerr)
}

/// Planck's spectral radiance, W m^-2 sr^-1 nm^-1.
#[pyfunction]
fn blackbody(wavelengths: Vec<f64>, temperature: f64) -> PyResult<Vec<f64>> {
    let mut out = vec![0.0; wavelengths.len()];
    grid::blackbody(&wavelengths, temperature, &mut out).map_err(to_pyerr)?;
    Ok(out)
}

/// (H, W, L) float32 spectra x (C, L) responses -> (H, W, C) float32.
#[pyfunction]
fn spectral_integrate<'py>(
    py: Python<'py>,
    spectra: &Bound<'py, PyAny>,
    response: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let arr = float32_array(spectra, "spectra", "(H, W, L)")?;
    let (h, w, l) = spectra_dims(arr.shape())?;
    let (resp, channels) = table(response, "response", l)?;
    let src = contiguous(&arr)?;
    detached_into(py, &[h, w, channels], |out| {
        integrate(&src, w, h, l, &resp, channels, out)
    })
}

/// The temporal and spatial statistics of a flat-field frame pair:
/// (mean, temporal variance, spatial variance), DN.
#[pyfunction]
fn flat_pair_stats(
    py: Python<'_>,
    a: PyReadonlyArrayDyn<'_, u16>,
    b: PyReadonlyArrayDyn<'_, u16>,
) -> PyResult<(f64, f64, f64)> {
    if a.shape() != b.shape() {
        return Err(PyValueError::new_err(format!(
            "the two frames of a pair must have one shape, got {:?} and {:?}",
            a.shape(),
            b.shape()
        )));
    }
    let (a, b) = (contiguous(&a)?, contiguous(&b)?);
    let s = detached(py, || pair_stats(&a, &b))?;
    Ok((s.mean, s.temporal_variance, s.spatial_variance))
}

/// A validated sensor model.
#[pyclass(frozen, name = "NativeSensor", module = "imgform_rs._native")]
pub struct NativeSensor(Sensor);

#[pymethods]
impl NativeSensor {
    #[new]
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (*, exposure_time, full_well, read_noise, electrons_per_dn, analog_gain,
        black_level, bit_depth, dark_current, temperature, reference_temperature,
        doubling_temperature, dsnu, prnu, column_noise, seed, pattern_seed))]
    fn new(
        exposure_time: f64,
        full_well: f64,
        read_noise: f64,
        electrons_per_dn: f64,
        analog_gain: f64,
        black_level: u32,
        bit_depth: u32,
        dark_current: f64,
        temperature: f64,
        reference_temperature: f64,
        doubling_temperature: f64,
        dsnu: f64,
        prnu: f64,
        column_noise: f64,
        seed: u64,
        pattern_seed: u64,
    ) -> PyResult<Self> {
        let s = Sensor {
            exposure_time,
            full_well,
            read_noise,
            electrons_per_dn,
            analog_gain,
            black_level,
            bit_depth,
            dark_current,
            temperature,
            reference_temperature,
            doubling_temperature,
            dsnu,
            prnu,
            column_noise,
            seed,
            pattern_seed,
        };
        s.validate().map_err(to_pyerr)?;
        Ok(Self(s))
    }

    /// The same sensor with another temporal-noise seed and exposure time.
    fn with_frame(&self, seed: u64, exposure_time: f64) -> PyResult<Self> {
        let s = Sensor {
            seed,
            exposure_time,
            ..self.0
        };
        s.validate().map_err(to_pyerr)?;
        Ok(Self(s))
    }

    /// The mean dark current at the sensor's temperature, e-/s.
    fn dark_rate(&self) -> f64 {
        self.0.dark_rate()
    }

    /// (H, W) float32 rates, e-/s -> (H, W) uint16 raw.
    fn capture_rates<'py>(
        &self,
        py: Python<'py>,
        rates: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<u16>>> {
        let arr = float32_array(rates, "rates", "(H, W)")?;
        let (h, w) = match *arr.shape() {
            [h, w] if h > 0 && w > 0 => (h, w),
            ref other => {
                return Err(PyValueError::new_err(format!(
                    "rates must have shape (H, W), got {other:?}"
                )))
            }
        };
        let src = contiguous(&arr)?;
        detached_into(py, &[h, w], |out| self.0.capture_rates(&src, w, h, out))
    }

    /// (H, W, L) float32 spectra and a (3, L) response -> (H, W) uint16 raw,
    /// dimmed by the cos⁴ falloff `(cx, cy, pitch_over_focal)` if given.
    #[pyo3(signature = (spectra, response, pattern, falloff=None))]
    fn capture_spectral<'py>(
        &self,
        py: Python<'py>,
        spectra: &Bound<'py, PyAny>,
        response: &Bound<'py, PyAny>,
        pattern: &Bound<'py, PyAny>,
        falloff: Option<(f64, f64, f64)>,
    ) -> PyResult<Bound<'py, PyArrayDyn<u16>>> {
        let arr = float32_array(spectra, "spectra", "(H, W, L)")?;
        let (h, w, l) = spectra_dims(arr.shape())?;
        let (resp, channels) = table(response, "response", l)?;
        if channels != 3 {
            return Err(PyValueError::new_err(format!(
                "a CFA capture needs a response of 3 channels (R, G, B), got {channels}"
            )));
        }
        let p = pattern_arg(pattern)?;
        let f = falloff_arg(falloff)?;
        let src = contiguous(&arr)?;
        detached_into(py, &[h, w], |out| {
            self.0
                .capture_spectral(&src, w, h, l, &resp, &p, f.as_ref(), out)
        })
    }

    /// (H, W, 3) float32 RGB and a (3, 3) camera matrix -> (H, W) uint16 raw,
    /// dimmed by the cos⁴ falloff `(cx, cy, pitch_over_focal)` if given.
    #[pyo3(signature = (rgb, matrix, pattern, falloff=None))]
    fn capture_rgb<'py>(
        &self,
        py: Python<'py>,
        rgb: &Bound<'py, PyAny>,
        matrix: &Bound<'py, PyAny>,
        pattern: &Bound<'py, PyAny>,
        falloff: Option<(f64, f64, f64)>,
    ) -> PyResult<Bound<'py, PyArrayDyn<u16>>> {
        let arr = float32_array(rgb, "rgb", "(H, W, 3)")?;
        let (h, w) = hwl(arr.shape(), "rgb", 3, "linear R, G, B")?;
        let (m, rows) = table(matrix, "matrix", 3)?;
        if rows != 3 {
            return Err(PyValueError::new_err(format!(
                "matrix must have shape (3, 3), got ({rows}, 3)"
            )));
        }
        let m: [f64; 9] = m.try_into().expect("checked shape (3, 3)");
        let p = pattern_arg(pattern)?;
        let f = falloff_arg(falloff)?;
        let src = contiguous(&arr)?;
        detached_into(py, &[h, w], |out| {
            self.0.capture_rgb(&src, w, h, &m, &p, f.as_ref(), out)
        })
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<NativeSensor>()?;
    m.add_function(wrap_pyfunction!(spectral_weights, m)?)?;
    m.add_function(wrap_pyfunction!(check_wavelengths, m)?)?;
    m.add_function(wrap_pyfunction!(check_spectra, m)?)?;
    m.add_function(wrap_pyfunction!(blackbody, m)?)?;
    m.add_function(wrap_pyfunction!(spectral_integrate, m)?)?;
    m.add_function(wrap_pyfunction!(flat_pair_stats, m)?)?;
    Ok(())
}

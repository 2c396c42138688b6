//! Bindings of `imgform_core::aberration`.

use imgform_core::aberration::{self, PupilPsf, SpotLens};
use imgform_core::image::{ImageView, Sample};
use numpy::{Element, PyArrayDyn, PyReadonlyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;

use crate::arrays::{contiguous, describe, detached_into, image_dims, to_numpy, AnyImage};
use crate::dispatch_image;
use crate::errors::detached;

/// A 2-D float64 PSF as contiguous values and its `(height, width)`.
fn psf_values(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<(Vec<f64>, (usize, usize))> {
    let arr = obj.extract::<PyReadonlyArray2<'_, f64>>().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name} must be a float64 array of shape (H, W), got {}",
            describe(obj)
        ))
    })?;
    let (h, w) = (arr.shape()[0], arr.shape()[1]);
    Ok((contiguous(&arr)?.into_owned(), (h, w)))
}

/// Diffraction PSF of a circular pupil with defocus and spherical aberration.
// The Python signature is the flat keyword list of the issue; the core
// takes them as one `PupilPsf`.
#[allow(clippy::too_many_arguments)]
#[pyfunction]
#[pyo3(signature = (n_pixels, pixel_pitch, f_number, wavelength, defocus, spherical, oversample=None))]
fn pupil_psf<'py>(
    py: Python<'py>,
    n_pixels: usize,
    pixel_pitch: f64,
    f_number: f64,
    wavelength: f64,
    defocus: f64,
    spherical: f64,
    oversample: Option<usize>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let params = PupilPsf {
        n_pixels,
        pixel_pitch,
        f_number,
        wavelength,
        defocus,
        spherical,
        oversample,
    };
    let psf = detached(py, || aberration::pupil_psf(&params))?;
    to_numpy(py, psf, &[n_pixels, n_pixels])
}

/// Ray hits `(N, 2)`, pupil points `(N, 2)` and the RMS spot radius.
type SpotResult<'py> = (
    Bound<'py, PyArrayDyn<f64>>,
    Bound<'py, PyArrayDyn<f64>>,
    f64,
);

/// Geometric spot diagram of a lens with longitudinal spherical aberration.
#[pyfunction]
fn spot_diagram<'py>(
    py: Python<'py>,
    f: f64,
    f_number: f64,
    spherical_lsa: f64,
    n_rays: usize,
    image_plane: f64,
) -> PyResult<SpotResult<'py>> {
    let lens = SpotLens {
        f,
        f_number,
        spherical_lsa,
    };
    let spot = detached(py, || aberration::spot_diagram(&lens, n_rays, image_plane))?;
    Ok((
        to_numpy(py, spot.hits, &[n_rays, 2])?,
        to_numpy(py, spot.pupil, &[n_rays, 2])?,
        spot.rms_radius,
    ))
}

/// Image-plane distance of least RMS spot radius.
#[pyfunction]
fn best_focus(
    py: Python<'_>,
    f: f64,
    f_number: f64,
    spherical_lsa: f64,
    n_rays: usize,
) -> PyResult<f64> {
    let lens = SpotLens {
        f,
        f_number,
        spherical_lsa,
    };
    detached(py, || aberration::best_focus(&lens, n_rays))
}

/// Peak-to-energy ratio of `psf` over that of `reference`.
#[pyfunction]
fn strehl_ratio(
    py: Python<'_>,
    psf: &Bound<'_, PyAny>,
    reference: &Bound<'_, PyAny>,
) -> PyResult<f64> {
    let (a, a_shape) = psf_values(psf, "psf")?;
    let (b, b_shape) = psf_values(reference, "reference")?;
    if a_shape != b_shape {
        return Err(pyo3::exceptions::PyValueError::new_err(format!(
            "psf and reference must have the same shape, got {a_shape:?} and {b_shape:?}"
        )));
    }
    detached(py, || aberration::strehl_ratio(&a, &b))
}

/// Convolves one image type with the PSF.
fn convolve<'py, T: Sample + Element>(
    img: PyReadonlyArrayDyn<'py, T>,
    psf: &[f64],
    psf_shape: (usize, usize),
) -> PyResult<Bound<'py, PyAny>> {
    let py = img.py();
    let shape = img.shape().to_vec();
    let (h, w, c) = image_dims(&shape, "image")?;
    let src = contiguous(&img)?;
    let out = detached_into(py, &shape, |out: &mut [T]| {
        let view = ImageView::contiguous(&src, w, h, c)?;
        aberration::render_aberrated(view, psf, psf_shape, out)
    })?;
    Ok(out.into_any())
}

/// An image blurred by a PSF (convolution, mirrored borders).
#[pyfunction]
fn render_aberrated<'py>(
    image: &Bound<'py, PyAny>,
    psf: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let img = AnyImage::extract(image, "image")?;
    let (taps, shape) = psf_values(psf, "psf")?;
    dispatch_image!(img, convolve(&taps, shape))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(pupil_psf, m)?)?;
    m.add_function(wrap_pyfunction!(spot_diagram, m)?)?;
    m.add_function(wrap_pyfunction!(best_focus, m)?)?;
    m.add_function(wrap_pyfunction!(strehl_ratio, m)?)?;
    m.add_function(wrap_pyfunction!(render_aberrated, m)?)?;
    Ok(())
}

//! Bindings of `imgform_core::chromatic`.

use imgform_core::chromatic::LateralCa;
use imgform_core::remap::{Interpolation, Resample};
use numpy::{Element, PyReadonlyArrayDyn};
use pyo3::prelude::*;

use crate::arrays::AnyImage;
use crate::dispatch_image;
use crate::errors::to_pyerr;
use crate::remap::resample_into;

fn lateral_ca_typed<'py, T: Resample + Element>(
    arr: PyReadonlyArrayDyn<'py, T>,
    py: Python<'py>,
    ca: LateralCa,
    interpolation: Interpolation,
    fill: f64,
    correct: bool,
) -> PyResult<Bound<'py, PyAny>> {
    resample_into(
        py,
        arr,
        |s| s.to_vec(),
        |view, out| ca.apply(view, interpolation, fill, correct, out),
    )
}

/// Adds (`correct=False`) or removes lateral chromatic aberration of an
/// RGB image (H, W, 3).
#[pyfunction]
#[pyo3(signature = (image, scale_r, scale_b, center=None, correct=false, interpolation="bilinear", fill=0.0))]
#[allow(clippy::too_many_arguments)]
fn lateral_ca<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    scale_r: f64,
    scale_b: f64,
    center: Option<(f64, f64)>,
    correct: bool,
    interpolation: &str,
    fill: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let interpolation = Interpolation::from_name(interpolation).map_err(to_pyerr)?;
    let img = AnyImage::extract(image, "image")?;
    let ca = LateralCa {
        scale_r,
        scale_b,
        center,
    };
    dispatch_image!(img, lateral_ca_typed(py, ca, interpolation, fill, correct))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(lateral_ca, m)?)?;
    Ok(())
}

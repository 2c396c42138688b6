//! Bindings of `imgform_core::lens`: one validated correction object per
//! lens setting and image size, so the models are checked once.

use imgform_core::image::ImageView;
use imgform_core::lens::{
    LensCorrection, LensCorrector, Normalization, RadialDistortion, Tca, Vignetting,
};
use imgform_core::remap::{Interpolation, Resample};
use numpy::{Element, PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::arrays::{contiguous, detached_into, detached_into_given, image_dims, AnyImage};
use crate::dispatch_image;
use crate::errors::to_pyerr;
use crate::remap::resample_into;

/// lensfun's corrections of one lens at one setting, for images of one
/// size, with the grids of positions its corrections build kept for the
/// next ones.
#[pyclass(frozen, name = "NativeLensCorrection", module = "imgform_rs._native")]
pub struct NativeLensCorrection(LensCorrector);

impl NativeLensCorrection {
    /// The core corrector, for other bindings that apply it.
    pub fn corrector(&self) -> &LensCorrector {
        &self.0
    }
}

#[pymethods]
impl NativeLensCorrection {
    #[new]
    #[pyo3(signature = (width, height, crop, calibration_crop, aspect_ratio, center, distortion, distortion_terms, tca, tca_terms, vignetting=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        width: usize,
        height: usize,
        crop: f64,
        calibration_crop: f64,
        aspect_ratio: f64,
        center: (f64, f64),
        distortion: &str,
        distortion_terms: Vec<f64>,
        tca: &str,
        tca_terms: Vec<f64>,
        vignetting: Option<[f64; 3]>,
    ) -> PyResult<Self> {
        let normalization =
            Normalization::new(width, height, crop, calibration_crop, aspect_ratio, center)
                .map_err(to_pyerr)?;
        let distortion = RadialDistortion::new(distortion, &distortion_terms).map_err(to_pyerr)?;
        let tca = Tca::new(tca, &tca_terms).map_err(to_pyerr)?;
        if let Some(k) = vignetting.filter(|k| k.iter().any(|v| !v.is_finite())) {
            return Err(pyo3::exceptions::PyValueError::new_err(format!(
                "vignetting terms must be finite, got {k:?}"
            )));
        }
        Ok(Self(LensCorrector::new(LensCorrection {
            width,
            height,
            normalization,
            distortion,
            tca,
            vignetting: vignetting.map(|k| Vignetting { k }),
        })))
    }

    /// Source positions (H, W, 3, 2) float64, lensfunpy's layout.
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let c = self.0.lens();
        detached_into(py, &[c.height, c.width, 3, 2], |out| c.positions(out))
    }

    /// The distortion- and TCA-corrected RGB image, in a new array or in
    /// `out`; with `vignetting`, also devignetted in the same pass (linear
    /// values).
    #[pyo3(signature = (image, interpolation="bilinear", fill=0.0, vignetting=false, *, out=None))]
    fn correct_geometry<'py>(
        &self,
        py: Python<'py>,
        image: &Bound<'py, PyAny>,
        interpolation: &str,
        fill: f64,
        vignetting: bool,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let interpolation = Interpolation::from_name(interpolation).map_err(to_pyerr)?;
        let img = AnyImage::extract(image, "image")?;
        dispatch_image!(
            img,
            geometry_typed(py, &self.0, interpolation, fill, vignetting, out)
        )
    }

    /// The image with vignetting removed above the repeated black tile
    /// (float64, shape (rows, cols)).
    fn devignette<'py>(
        &self,
        py: Python<'py>,
        image: &Bound<'py, PyAny>,
        black: PyReadonlyArrayDyn<'py, f64>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let img = AnyImage::extract(image, "image")?;
        let shape = black.shape().to_vec();
        if shape.len() != 2 {
            return Err(pyo3::exceptions::PyValueError::new_err(format!(
                "black must be a 2-D tile, got shape {shape:?}"
            )));
        }
        let tile = contiguous(&black)?.to_vec();
        dispatch_image!(img, devignette_typed(py, self.0.lens(), &tile, shape[1]))
    }
}

fn geometry_typed<'py, T: Resample + Element>(
    arr: PyReadonlyArrayDyn<'py, T>,
    py: Python<'py>,
    lens: &LensCorrector,
    interpolation: Interpolation,
    fill: f64,
    vignetting: bool,
    out: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let (h, w, c) = image_dims(arr.shape(), "image")?;
    let src = contiguous(&arr)?;
    let kernel = |out: &mut [T]| {
        let view = ImageView::contiguous(&src, w, h, c)?;
        lens.correct_geometry(&view, interpolation, fill, vignetting, out)
    };
    Ok(detached_into_given(py, out, arr.shape(), kernel)?.into_any())
}

fn devignette_typed<'py, T: Resample + Element>(
    arr: PyReadonlyArrayDyn<'py, T>,
    py: Python<'py>,
    lens: &LensCorrection,
    tile: &[f64],
    tile_width: usize,
) -> PyResult<Bound<'py, PyAny>> {
    resample_into(
        py,
        arr,
        |s| s.to_vec(),
        |view, out| lens.devignette(view, tile, tile_width, out),
    )
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<NativeLensCorrection>()?;
    Ok(())
}

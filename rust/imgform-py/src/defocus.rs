//! Bindings of `imgform_core::defocus`.

use imgform_core::defocus::{self, Lens};
use imgform_core::image::{ImageView, Sample};
use numpy::{Element, PyReadonlyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

use crate::arrays::{contiguous, describe, filled, image_dims, to_numpy, AnyImage};
use crate::dispatch_image;
use crate::errors::detached;

/// A depth map in either float precision; the kernel is generic over both.
enum AnyDepth<'py> {
    F32(PyReadonlyArray2<'py, f32>),
    F64(PyReadonlyArray2<'py, f64>),
}

impl<'py> AnyDepth<'py> {
    fn extract(obj: &Bound<'py, PyAny>) -> PyResult<Self> {
        if let Ok(a) = obj.extract() {
            Ok(Self::F32(a))
        } else if let Ok(a) = obj.extract() {
            Ok(Self::F64(a))
        } else {
            Err(PyTypeError::new_err(format!(
                "depth must be a float32 or float64 array of shape (H, W), got {}",
                describe(obj)
            )))
        }
    }

    fn shape(&self) -> &[usize] {
        match self {
            Self::F32(a) => a.shape(),
            Self::F64(a) => a.shape(),
        }
    }
}

/// Runs the kernel on contiguous samples with the GIL released.
fn run<T: Sample, Z: Copy + Into<f64> + Sync>(
    py: Python<'_>,
    src: &[T],
    (h, w, c): (usize, usize, usize),
    depth: &[Z],
    lens: Lens,
) -> PyResult<Vec<T>> {
    let mut out = filled(src.len(), T::default(), "the output")?;
    detached(py, || {
        let view = ImageView::contiguous(src, w, h, c)?;
        defocus::render_defocus(view, depth, lens, &mut out)
    })?;
    Ok(out)
}

/// Renders one image type against either depth type.
fn render<'py, T: Sample + Element>(
    img: PyReadonlyArrayDyn<'py, T>,
    depth: &AnyDepth<'py>,
    lens: Lens,
) -> PyResult<Bound<'py, PyAny>> {
    let py = img.py();
    let shape = img.shape().to_vec();
    let dims = image_dims(&shape, "image")?;
    if depth.shape() != [dims.0, dims.1] {
        return Err(PyValueError::new_err(format!(
            "depth must have the image's height and width ({}, {}), got shape {:?}",
            dims.0,
            dims.1,
            depth.shape()
        )));
    }
    let src = contiguous(&img)?;
    let out = match depth {
        AnyDepth::F32(d) => run(py, &src, dims, &contiguous(d)?, lens)?,
        AnyDepth::F64(d) => run(py, &src, dims, &contiguous(d)?, lens)?,
    };
    Ok(to_numpy(py, out, &shape)?.into_any())
}

/// Thin-lens defocus of an image with its depth map.
#[pyfunction]
fn render_defocus<'py>(
    image: &Bound<'py, PyAny>,
    depth: &Bound<'py, PyAny>,
    f: f64,
    n: f64,
    focus_distance: f64,
    pixel_pitch: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let img = AnyImage::extract(image, "image")?;
    let depth = AnyDepth::extract(depth)?;
    let lens = Lens {
        f,
        n,
        focus_distance,
        pixel_pitch,
    };
    dispatch_image!(img, render(&depth, lens))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(render_defocus, m)?)?;
    Ok(())
}

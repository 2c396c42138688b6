//! Bindings of `imgform_core::remap`: the reusable map object and the
//! resampling pass.

use imgform_core::image::{ImageView, Sample};
use imgform_core::remap::{self, Interpolation, Resample};
use numpy::{Element, PyArrayDyn, PyReadonlyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

use crate::arrays::{contiguous, describe, detached_into, image_dims, to_numpy, AnyImage};
use crate::dispatch_image;
use crate::distortion::{intrinsics, model};
use crate::errors::{detached, to_pyerr};

type Plane<'py> = Bound<'py, PyArrayDyn<f32>>;

/// A precomputed source position for every output pixel.
#[pyclass(name = "RemapMap", module = "imgform_rs._native", frozen)]
pub struct PyRemapMap {
    inner: remap::RemapMap,
}

fn plane<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<PyReadonlyArray2<'py, f32>> {
    obj.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name} must be a float32 array of shape (H, W), got {}",
            describe(obj)
        ))
    })
}

/// `(height, width)` of an output size given as `(H, W)`.
fn size(shape: (usize, usize)) -> PyResult<(usize, usize)> {
    match shape {
        (0, _) | (_, 0) => Err(PyValueError::new_err(format!(
            "shape must be a non-empty (H, W), got {shape:?}"
        ))),
        s => Ok(s),
    }
}

/// Builds an undistortion or distortion map with the GIL released.
fn lens_map(
    py: Python<'_>,
    k: &Bound<'_, PyAny>,
    coeffs: Vec<f64>,
    model_name: &str,
    shape: (usize, usize),
    new_k: Option<&Bound<'_, PyAny>>,
    undistort: bool,
) -> PyResult<PyRemapMap> {
    let lens = model(model_name, coeffs)?;
    let k = intrinsics(Some(k), "K")?.expect("K was given");
    let new_k = intrinsics(new_k, "new_K")?.unwrap_or(k);
    let (h, w) = size(shape)?;
    let inner = detached(py, || {
        if undistort {
            remap::RemapMap::undistort(&k, &lens, &new_k, w, h)
        } else {
            remap::RemapMap::distort(&k, &lens, &new_k, w, h)
        }
    })?;
    Ok(PyRemapMap { inner })
}

#[pymethods]
impl PyRemapMap {
    /// A map from OpenCV-style planes: `map_x[v, u]`, `map_y[v, u]` are the
    /// source column and row of output pixel `(u, v)`.
    #[new]
    fn new(py: Python<'_>, map_x: &Bound<'_, PyAny>, map_y: &Bound<'_, PyAny>) -> PyResult<Self> {
        let (mx, my) = (plane(map_x, "map_x")?, plane(map_y, "map_y")?);
        if mx.shape() != my.shape() {
            return Err(PyValueError::new_err(format!(
                "map_x and map_y must have the same shape, got {:?} and {:?}",
                mx.shape(),
                my.shape()
            )));
        }
        let (h, w) = (mx.shape()[0], mx.shape()[1]);
        let (xs, ys) = (contiguous(&mx)?, contiguous(&my)?);
        let inner = detached(py, || remap::RemapMap::from_planes(&xs, &ys, w, h))?;
        Ok(Self { inner })
    }

    /// The map that undistorts an image taken through `k` and the lens.
    #[staticmethod]
    #[pyo3(signature = (k, coeffs, model_name, shape, new_k=None))]
    fn undistort(
        py: Python<'_>,
        k: &Bound<'_, PyAny>,
        coeffs: Vec<f64>,
        model_name: &str,
        shape: (usize, usize),
        new_k: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        lens_map(py, k, coeffs, model_name, shape, new_k, true)
    }

    /// The map that renders the lens's distortion into an ideal image.
    #[staticmethod]
    #[pyo3(signature = (k, coeffs, model_name, shape, new_k=None))]
    fn distort(
        py: Python<'_>,
        k: &Bound<'_, PyAny>,
        coeffs: Vec<f64>,
        model_name: &str,
        shape: (usize, usize),
        new_k: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        lens_map(py, k, coeffs, model_name, shape, new_k, false)
    }

    /// `(H, W)` of the images the map produces.
    #[getter]
    fn shape(&self) -> (usize, usize) {
        (self.inner.height(), self.inner.width())
    }

    /// The map as OpenCV's two float32 planes `(map_x, map_y)`, each (H, W).
    fn planes<'py>(&self, py: Python<'py>) -> PyResult<(Plane<'py>, Plane<'py>)> {
        let (xs, ys) = self.inner.planes();
        let shape = [self.inner.height(), self.inner.width()];
        Ok((to_numpy(py, xs, &shape)?, to_numpy(py, ys, &shape)?))
    }

    fn __repr__(&self) -> String {
        format!(
            "RemapMap(shape=({}, {}))",
            self.inner.height(),
            self.inner.width()
        )
    }
}

/// The output shape: the map's (H, W) with the input's channel axis, if any.
pub fn output_shape(input: &[usize], height: usize, width: usize) -> Vec<usize> {
    let mut shape = vec![height, width];
    shape.extend_from_slice(&input[2..]);
    shape
}

/// Runs `kernel(view, out)` over a typed image and returns a new array of
/// `out_shape` (same sample type, `(H, W)` or `(H, W, C)` as given).
///
/// Unlike the usual "fill a Vec, hand it to NumPy", the output is allocated
/// by NumPy and written in place: NumPy asks the kernel for transparent huge
/// pages on large arrays, a Rust `Vec` does not, and first-touch faults on
/// 4 KiB pages took about half the time of a 24 MP remap (measured with
/// perf: `clear_page_erms` at 52 %).
pub fn resample_into<'py, T, F>(
    py: Python<'py>,
    arr: PyReadonlyArrayDyn<'py, T>,
    out_shape: impl Fn(&[usize]) -> Vec<usize>,
    kernel: F,
) -> PyResult<Bound<'py, PyAny>>
where
    T: Sample + Element,
    F: Fn(&ImageView<T>, &mut [T]) -> imgform_core::Result<()> + Send + Sync,
{
    let (h, w, c) = image_dims(arr.shape(), "image")?;
    let shape = out_shape(arr.shape());
    let src = contiguous(&arr)?;
    let out = detached_into(py, &shape, |out| {
        let view = ImageView::contiguous(&src, w, h, c)?;
        kernel(&view, out)
    })?;
    Ok(out.into_any())
}

fn remap_typed<'py, T: Resample + Element>(
    arr: PyReadonlyArrayDyn<'py, T>,
    py: Python<'py>,
    map: &remap::RemapMap,
    interpolation: Interpolation,
    fill: f64,
) -> PyResult<Bound<'py, PyAny>> {
    resample_into(
        py,
        arr,
        |s| output_shape(s, map.height(), map.width()),
        |view, out| remap::remap(view, map, interpolation, fill, out),
    )
}

/// Resamples an image through a map; the output has the map's (H, W).
#[pyfunction]
#[pyo3(signature = (image, map, interpolation="bilinear", fill=0.0))]
fn remap_image<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    map: &Bound<'py, PyRemapMap>,
    interpolation: &str,
    fill: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let interpolation = Interpolation::from_name(interpolation).map_err(to_pyerr)?;
    let img = AnyImage::extract(image, "image")?;
    let map = &map.get().inner;
    dispatch_image!(img, remap_typed(py, map, interpolation, fill))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyRemapMap>()?;
    m.add_function(wrap_pyfunction!(remap_image, m)?)?;
    Ok(())
}

//! Bindings of `imgform_core::camera`: one validated camera object, so the
//! matrices are checked once and every batch call goes straight to a kernel.

use imgform_core::camera::Camera;
use numpy::{PyArrayDyn, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

use crate::arrays::{contiguous, describe, detached_into, fixed, points};
use crate::distortion::model;
use crate::errors::to_pyerr;

/// A camera `K [R | t]` with a lens, validated on construction.
#[pyclass(frozen, name = "NativeCamera", module = "imgform_rs._native")]
pub struct NativeCamera(Camera);

/// A float64 array of shape (3,) as a vector.
pub(crate) fn vec3(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<[f64; 3]> {
    Ok(fixed(obj, &[3], name)?
        .try_into()
        .expect("checked shape (3,)"))
}

#[pymethods]
impl NativeCamera {
    #[new]
    #[pyo3(signature = (k, r, t, coeffs, model_name))]
    fn new(
        k: &Bound<'_, PyAny>,
        r: &Bound<'_, PyAny>,
        t: &Bound<'_, PyAny>,
        coeffs: Vec<f64>,
        model_name: &str,
    ) -> PyResult<Self> {
        let k: [f64; 9] = fixed(k, &[3, 3], "K")?
            .try_into()
            .expect("checked shape (3, 3)");
        let r: [f64; 9] = fixed(r, &[3, 3], "R")?
            .try_into()
            .expect("checked shape (3, 3)");
        let t = vec3(t, "t")?;
        let lens = model(model_name, coeffs)?;
        Camera::new(&k, &r, &t, lens).map(Self).map_err(to_pyerr)
    }

    /// World points (N, 3) -> pixels (N, 2).
    fn project<'py>(
        &self,
        py: Python<'py>,
        points_world: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let arr = points(points_world, 3, "points")?;
        let n = arr.shape()[0];
        let src = contiguous(&arr)?;
        detached_into(py, &[n, 2], |out| self.0.project(&src, out))
    }

    /// Pixels (N, 2) and camera-frame depths (N,) -> world points (N, 3).
    fn unproject<'py>(
        &self,
        py: Python<'py>,
        pixels: &Bound<'py, PyAny>,
        depth: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let arr = points(pixels, 2, "pixels")?;
        let n = arr.shape()[0];
        let z = depth.extract::<PyReadonlyArray1<'py, f64>>().map_err(|_| {
            PyTypeError::new_err(format!(
                "depth must be a float64 array of shape ({n},), got {}",
                describe(depth)
            ))
        })?;
        if z.len() != n {
            return Err(PyValueError::new_err(format!(
                "depth must have shape ({n},), one value per pixel, got ({},)",
                z.len()
            )));
        }
        let src = contiguous(&arr)?;
        let z = contiguous(&z)?;
        detached_into(py, &[n, 3], |out| self.0.unproject(&src, &z, out))
    }

    /// Pixels (N, 2) -> unit world directions (N, 3).
    fn rays<'py>(
        &self,
        py: Python<'py>,
        pixels: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let arr = points(pixels, 2, "pixels")?;
        let n = arr.shape()[0];
        let src = contiguous(&arr)?;
        detached_into(py, &[n, 3], |out| self.0.rays(&src, out))
    }

    /// (horizontal, vertical, diagonal) field of view in radians.
    fn fov(&self, width: usize, height: usize) -> PyResult<(f64, f64, f64)> {
        let [h, v, d] = self.0.field_of_view(width, height).map_err(to_pyerr)?;
        Ok((h, v, d))
    }

    /// The camera centre in world coordinates.
    fn center(&self) -> (f64, f64, f64) {
        let [x, y, z] = self.0.center();
        (x, y, z)
    }

    /// (point (2,), homogeneous (3,), at_infinity) of a world direction.
    #[allow(clippy::type_complexity)]
    fn vanishing_point(
        &self,
        direction: &Bound<'_, PyAny>,
    ) -> PyResult<((f64, f64), (f64, f64, f64), bool)> {
        let vp = self
            .0
            .vanishing_point(vec3(direction, "direction")?)
            .map_err(to_pyerr)?;
        let [u, v] = vp.point;
        let [a, b, c] = vp.homogeneous;
        Ok(((u, v), (a, b, c), vp.at_infinity))
    }

    /// Homogeneous line (a, b, c) with a² + b² = 1 (or (0, 0, 1)).
    fn vanishing_line(&self, plane_normal: &Bound<'_, PyAny>) -> PyResult<(f64, f64, f64)> {
        let [a, b, c] = self
            .0
            .vanishing_line(vec3(plane_normal, "plane_normal")?)
            .map_err(to_pyerr)?;
        Ok((a, b, c))
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<NativeCamera>()?;
    Ok(())
}

//! Taking and returning NumPy arrays.
//!
//! The typed Python facade coerces lists and dtypes; this layer still checks
//! everything it receives, so a direct call into `_native` gets a `TypeError`
//! or `ValueError` too, never a panic.

use std::borrow::Cow;

use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{
    Element, IntoPyArray, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArray2,
    PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyMemoryError, PyTypeError, PyValueError};
use pyo3::intern;
use pyo3::prelude::*;

use crate::errors::detached;

/// The slice behind an array: borrowed when C-contiguous, else one
/// standard-layout copy (never two).
///
/// `as_slice` alone is not enough: it also accepts Fortran-ordered arrays
/// (a transposed view, `np.asfortranarray`), whose memory holds the
/// transpose of the row-major order the kernels read.
///
/// # Errors
/// `MemoryError` when the copy cannot be allocated: a failed allocation of
/// a `Vec` aborts the process, as a large strided view (a transposed
/// memmap) in a container with little memory would.
pub fn contiguous<'a, T: Element + Copy, D: numpy::ndarray::Dimension>(
    arr: &'a numpy::PyReadonlyArray<'_, T, D>,
) -> PyResult<Cow<'a, [T]>> {
    if let Ok(s) = arr.as_slice() {
        if arr.is_c_contiguous() {
            return Ok(Cow::Borrowed(s));
        }
    }
    let view = arr.as_array();
    let mut copy = reserved(view.len(), "a contiguous copy of a non-contiguous array")?;
    copy.extend(view.iter().copied());
    Ok(Cow::Owned(copy))
}

/// An empty vector with room for `n` values, or a `MemoryError` naming
/// `what` (a failed allocation of a `Vec` aborts the process).
pub fn reserved<T>(n: usize, what: &str) -> PyResult<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| {
        PyMemoryError::new_err(format!(
            "no memory for {what}: {n} values of {} bytes",
            std::mem::size_of::<T>()
        ))
    })?;
    Ok(v)
}

/// `n` copies of `value`, or a `MemoryError` naming `what`, written by
/// every thread ([`imgform_core::parallel::extend_filled`]).
pub fn filled<T: Clone + Send>(n: usize, value: T, what: &str) -> PyResult<Vec<T>> {
    let mut v = reserved(n, what)?;
    imgform_core::parallel::extend_filled(&mut v, n, value);
    Ok(v)
}

/// The dtype name of any object, for error messages.
pub fn describe(obj: &Bound<'_, PyAny>) -> String {
    match obj.downcast::<PyUntypedArray>() {
        Ok(a) => format!("an array of dtype {} and shape {:?}", a.dtype(), a.shape()),
        Err(_) => format!(
            "an object of type {}",
            obj.get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ),
    }
}

/// A float64 point set of shape `(N, dim)`.
pub fn points<'py>(
    obj: &Bound<'py, PyAny>,
    dim: usize,
    name: &str,
) -> PyResult<PyReadonlyArray2<'py, f64>> {
    let arr = obj.extract::<PyReadonlyArray2<'py, f64>>().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name} must be a float64 array of shape (N, {dim}), got {}",
            describe(obj)
        ))
    })?;
    let shape = arr.shape();
    if shape[1] != dim {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape (N, {dim}), got {:?}",
            shape
        )));
    }
    Ok(arr)
}

/// A float64 array of exactly `shape`, as a contiguous vector.
pub fn fixed<'py>(obj: &Bound<'py, PyAny>, shape: &[usize], name: &str) -> PyResult<Vec<f64>> {
    let arr = obj.extract::<PyReadonlyArrayDyn<'py, f64>>().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name} must be a float64 array of shape {shape:?}, got {}",
            describe(obj)
        ))
    })?;
    exact_shape(name, arr.shape(), shape)?;
    Ok(contiguous(&arr)?.into_owned())
}

/// The `ValueError` for an array `name` of shape `got` where exactly
/// `shape` is accepted.
fn exact_shape(name: &str, got: &[usize], shape: &[usize]) -> PyResult<()> {
    if got == shape {
        return Ok(());
    }
    Err(PyValueError::new_err(format!(
        "{name} must have shape {shape:?}, got {got:?}"
    )))
}

/// Hands a vector to NumPy without copying, shaped `shape`.
pub fn to_numpy<'py, T: Element>(
    py: Python<'py>,
    data: Vec<T>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    let arr = ArrayD::from_shape_vec(IxDyn(shape), data)
        .map_err(|e| PyValueError::new_err(format!("internal shape mismatch: {e}")))?;
    Ok(arr.into_pyarray(py))
}

/// A new zeroed C-contiguous array of `shape` from `numpy.zeros`, or the
/// `MemoryError` NumPy raises for one it cannot allocate: rust-numpy's own
/// constructors panic then.
pub fn zeros<'py, T: Element>(
    py: Python<'py>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    let numpy = py.import(intern!(py, "numpy"))?;
    let array = numpy.call_method1(intern!(py, "zeros"), (shape.to_vec(), T::get_dtype(py)))?;
    Ok(array.downcast_into::<PyArrayDyn<T>>()?)
}

/// Allocates a new C-contiguous array of `shape` through NumPy and lets
/// `kernel` fill it with the GIL released.
///
/// Why not a `Vec` handed over with [`to_numpy`]: NumPy advises the OS to back
/// large arrays with huge pages, so the first write into a fresh buffer costs
/// far fewer page faults. For a 10 M point projection (160 MB out) the faults
/// of a fresh `Vec` took ~75 ms, three times the ~22 ms of the kernel itself.
pub fn detached_into<'py, T, F>(
    py: Python<'py>,
    shape: &[usize],
    kernel: F,
) -> PyResult<Bound<'py, PyArrayDyn<T>>>
where
    T: Element + Send,
    F: Send + FnOnce(&mut [T]) -> imgform_core::Result<()>,
{
    let out = zeros::<T>(py, shape)?;
    fill(py, &out, kernel)?;
    Ok(out)
}

/// Lets `kernel` fill the caller's `out` (an `out=` argument) with the GIL
/// released, as [`detached_into`] fills a new array: for callers that run
/// many images of one size, whose fresh outputs cost page faults and
/// zeroing every time.
///
/// `out` must be an array of `T`, exactly `shape`, C-contiguous and
/// writeable, and share no memory with any input the caller still holds
/// borrowed (NumPy's borrow tracking refuses the write borrow then).
pub fn detached_into_out<'py, T, F>(
    py: Python<'py>,
    out: &Bound<'py, PyAny>,
    shape: &[usize],
    kernel: F,
) -> PyResult<Bound<'py, PyArrayDyn<T>>>
where
    T: Element + Send,
    F: Send + FnOnce(&mut [T]) -> imgform_core::Result<()>,
{
    let dtype = T::get_dtype(py);
    let arr = out.downcast::<PyArrayDyn<T>>().map_err(|_| {
        PyTypeError::new_err(format!(
            "out must be a numpy array of dtype {dtype}, the input's, got {}",
            describe(out)
        ))
    })?;
    exact_shape("out", arr.shape(), shape)?;
    if !arr.is_c_contiguous() {
        return Err(PyValueError::new_err(
            "out must be C-contiguous (a fresh np.empty array is)",
        ));
    }
    fill(py, arr, kernel)?;
    Ok(arr.clone())
}

/// [`detached_into_out`] into the caller's `out` if given, else
/// [`detached_into`] a new array.
pub fn detached_into_given<'py, T: Element + Send>(
    py: Python<'py>,
    out: Option<&Bound<'py, PyAny>>,
    shape: &[usize],
    kernel: impl Send + FnOnce(&mut [T]) -> imgform_core::Result<()>,
) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    match out {
        Some(out) => detached_into_out(py, out, shape, kernel),
        None => detached_into(py, shape, kernel),
    }
}

/// Runs `kernel` on the memory of the C-contiguous `arr` with the GIL
/// released. Only a caller's `out` can fail the write borrow.
fn fill<T, F>(py: Python<'_>, arr: &Bound<'_, PyArrayDyn<T>>, kernel: F) -> PyResult<()>
where
    T: Element + Send,
    F: Send + FnOnce(&mut [T]) -> imgform_core::Result<()>,
{
    let mut view = arr.try_readwrite().map_err(|e| {
        PyValueError::new_err(format!(
            "out must be writeable and share no memory with the input ({e})"
        ))
    })?;
    let slice = view
        .as_slice_mut()
        .map_err(|e| PyValueError::new_err(format!("internal layout error: {e}")))?;
    detached(py, || kernel(slice))
}

/// An image of one of the sample types the kernels accept.
pub enum AnyImage<'py> {
    U8(PyReadonlyArrayDyn<'py, u8>),
    U16(PyReadonlyArrayDyn<'py, u16>),
    F32(PyReadonlyArrayDyn<'py, f32>),
}

impl<'py> AnyImage<'py> {
    /// Accepts a uint8, uint16 or float32 array of shape (H, W) or (H, W, C),
    /// in either byte order.
    pub fn extract(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Self> {
        let obj = &native_order(obj)?;
        let img = if let Ok(a) = obj.extract() {
            Self::U8(a)
        } else if let Ok(a) = obj.extract() {
            Self::U16(a)
        } else if let Ok(a) = obj.extract() {
            Self::F32(a)
        } else {
            return Err(PyTypeError::new_err(format!(
                "{name} must be a uint8, uint16 or float32 array, got {}",
                describe(obj)
            )));
        };
        image_dims(img.shape(), name)?;
        Ok(img)
    }

    pub fn shape(&self) -> &[usize] {
        match self {
            Self::U8(a) => a.shape(),
            Self::U16(a) => a.shape(),
            Self::F32(a) => a.shape(),
        }
    }
}

/// `obj`, or, for a NumPy array stored in the other byte order (a
/// big-endian file read as it is), its copy in this machine's: the kernels
/// take native numbers, and the copy holds the same values.
pub fn native_order<'py>(obj: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    let Ok(array) = obj.downcast::<PyUntypedArray>() else {
        return Ok(obj.clone());
    };
    let dtype = array.dtype();
    if dtype.is_native_byteorder() != Some(false) {
        return Ok(obj.clone());
    }
    let native = dtype.call_method1(intern!(obj.py(), "newbyteorder"), ("=",))?;
    obj.call_method1(intern!(obj.py(), "astype"), (native,))
}

/// `(height, width, channels)` of an image shape (H, W) or (H, W, C).
pub fn image_dims(shape: &[usize], name: &str) -> PyResult<(usize, usize, usize)> {
    let dims = match *shape {
        [h, w] => (h, w, 1),
        [h, w, c] => (h, w, c),
        _ => {
            return Err(PyValueError::new_err(format!(
                "{name} must have shape (H, W) or (H, W, C), got {shape:?}"
            )))
        }
    };
    if dims.0 == 0 || dims.1 == 0 || dims.2 == 0 {
        return Err(PyValueError::new_err(format!(
            "{name} must not be empty, got shape {shape:?}"
        )));
    }
    Ok(dims)
}

/// Calls the generic function `$f::<T>(array, args...)` for whichever sample
/// type an [`AnyImage`] holds: one generic body, no per-dtype copies.
#[macro_export]
macro_rules! dispatch_image {
    ($img:expr, $f:ident ( $($arg:expr),* $(,)? )) => {
        match $img {
            $crate::arrays::AnyImage::U8(a) => $f(a, $($arg),*),
            $crate::arrays::AnyImage::U16(a) => $f(a, $($arg),*),
            $crate::arrays::AnyImage::F32(a) => $f(a, $($arg),*),
        }
    };
}

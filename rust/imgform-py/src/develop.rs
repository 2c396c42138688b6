//! Bindings of `imgform_core::develop`.

use imgform_core::cfa::CfaPattern;
use imgform_core::demosaic::Method;
use imgform_core::develop::{
    develop_corrected, develop_in_place, develop_staging, AutoBright, DevelopParams, Tone,
};
use imgform_core::image::{ImageView, Sample};
use imgform_core::lens::LensCorrector;
use imgform_core::remap::Resample;
use numpy::{Element, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use std::sync::{Mutex, PoisonError};

use crate::arrays::{contiguous, describe, detached_into, fixed, zeros};
use crate::cfa::pattern_arg;
use crate::errors::to_pyerr;
use crate::lens::NativeLensCorrection;

/// Runs `kernel` on the mosaic into a new `(H, W, 3)` array of `U`.
fn run<'py, U, K>(
    py: Python<'py>,
    src: &[u16],
    (h, w): (usize, usize),
    kernel: K,
) -> PyResult<Bound<'py, PyAny>>
where
    U: Sample + Element,
    K: Send + FnOnce(ImageView<'_, u16>, &mut [U]) -> imgform_core::Result<()>,
{
    let out = detached_into(py, &[h, w, 3], |out: &mut [U]| {
        kernel(ImageView::contiguous(src, w, h, 1)?, out)
    })?;
    Ok(out.into_any())
}

/// The working array of the last corrected development of each sample
/// type, kept for the next: the development goes there before its
/// geometry is resampled into the output, and the OS zeroes every page of
/// a fresh array as it is first written (72 MB at 24 MP in 8 bits). A
/// batch of raws of one size reuses it; a call of another size replaces
/// it. A call takes it out while it runs, so concurrent calls never share
/// one.
trait Working: Resample + Element {
    fn kept() -> &'static Mutex<Option<Py<PyArrayDyn<Self>>>>;
}

macro_rules! working {
    ($($t:ty),*) => {$(
        impl Working for $t {
            fn kept() -> &'static Mutex<Option<Py<PyArrayDyn<$t>>>> {
                static KEPT: Mutex<Option<Py<PyArrayDyn<$t>>>> = Mutex::new(None);
                &KEPT
            }
        }
    )*};
}

working!(u8, u16, f32);

/// The staging image of the last staged development (brightened, or
/// nearest and X-Trans) of each demosaic type, kept for the next as the
/// working arrays are: a brightened 24 MP 8-bit development spent a
/// seventh of its time having the OS zero a fresh one. A call takes it out
/// while it runs.
trait Staged: Sample + Send {
    fn kept() -> &'static Mutex<Vec<Self>>;

    /// Runs `f` with the kept staging image, and keeps it again after.
    fn with_kept<R>(f: impl FnOnce(&mut Vec<Self>) -> R) -> R {
        let lock = || Self::kept().lock().unwrap_or_else(PoisonError::into_inner);
        let mut staging = std::mem::take(&mut *lock());
        let result = f(&mut staging);
        *lock() = staging;
        result
    }
}

macro_rules! staged {
    ($($t:ty),*) => {$(
        impl Staged for $t {
            fn kept() -> &'static Mutex<Vec<$t>> {
                static KEPT: Mutex<Vec<$t>> = Mutex::new(Vec::new());
                &KEPT
            }
        }
    )*};
}

staged!(u16, f32);

/// The kept working array of `U` if it holds `len` samples, else a new one
/// that NumPy allocates (it asks the OS to back large arrays with huge
/// pages, so their first writes fault far less often than a `Vec`'s).
fn take_working<U: Working>(py: Python<'_>, len: usize) -> PyResult<Bound<'_, PyArrayDyn<U>>> {
    let kept = U::kept()
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .take();
    match kept.map(|a| a.into_bound(py)) {
        Some(a) if a.len() == len => Ok(a),
        _ => zeros::<U>(py, &[len]),
    }
}

/// [`run`] through a lens correction, developing into a [`Working`] array
/// first when the correction resamples the geometry.
fn run_corrected<'py, T: Staged, U: Working>(
    py: Python<'py>,
    src: &[u16],
    (h, w): (usize, usize),
    (pattern, params): (&CfaPattern, &DevelopParams),
    lens: &LensCorrector,
) -> PyResult<Bound<'py, PyAny>> {
    let len = if lens.lens().corrects_geometry() {
        3 * h * w
    } else {
        0
    };
    let working = take_working::<U>(py, len)?;
    let out = {
        let mut view = working
            .try_readwrite()
            .map_err(|e| PyValueError::new_err(format!("internal borrow error: {e}")))?;
        let developed = view
            .as_slice_mut()
            .map_err(|e| PyValueError::new_err(format!("internal layout error: {e}")))?;
        run(py, src, (h, w), |v, out| {
            T::with_kept(|staging| {
                develop_corrected::<T, U>(v, pattern, params, lens, (staging, developed), out)
            })
        })?
    };
    if len > 0 {
        *U::kept().lock().unwrap_or_else(PoisonError::into_inner) = Some(working.unbind());
    }
    Ok(out)
}

fn f32s(v: Vec<f64>) -> Vec<f32> {
    v.into_iter().map(|x| x as f32).collect()
}

/// The `(rows, cols)` of the `black` array, which `scale` must share: any
/// 2-D shape (the core checks it against the CFA period), else the CFA tile
/// so that `fixed` reports what was expected.
fn tile_shape(black: &Bound<'_, PyAny>, period: usize) -> [usize; 2] {
    match black
        .getattr("shape")
        .and_then(|s| s.extract::<Vec<usize>>())
        .as_deref()
    {
        Ok(&[rows, cols]) => [rows, cols],
        _ => [period, period],
    }
}

/// Develops a uint16 mosaic (H, W) -> (H, W, 3) uint8 / uint16 / float32,
/// through `lens`'s corrections if given (made for the mosaic's size),
/// brightened as LibRaw does by default if `auto_bright` gives the pixels
/// its 1 % is of.
#[pyfunction]
#[pyo3(signature = (raw, pattern, black, scale, matrix, tone, method, bps, lens=None, auto_bright=None))]
#[allow(clippy::too_many_arguments)]
fn develop<'py>(
    py: Python<'py>,
    raw: &Bound<'py, PyAny>,
    pattern: &Bound<'py, PyAny>,
    black: &Bound<'py, PyAny>,
    scale: &Bound<'py, PyAny>,
    matrix: &Bound<'py, PyAny>,
    tone: &str,
    method: &str,
    bps: &str,
    lens: Option<Bound<'py, NativeLensCorrection>>,
    auto_bright: Option<usize>,
) -> PyResult<Bound<'py, PyAny>> {
    let arr = raw.extract::<PyReadonlyArrayDyn<'py, u16>>().map_err(|_| {
        PyTypeError::new_err(format!(
            "raw must be a uint16 mosaic of shape (H, W), got {}",
            describe(raw)
        ))
    })?;
    let (h, w) = match *arr.shape() {
        [h, w] => (h, w),
        ref other => {
            return Err(PyValueError::new_err(format!(
                "raw must be a mosaic of shape (H, W), got shape {other:?}"
            )))
        }
    };
    let pattern = pattern_arg(pattern)?;
    let tile = tile_shape(black, pattern.period());
    let m = f32s(fixed(matrix, &[3, 3], "matrix")?);
    let params = DevelopParams {
        tile: (tile[0], tile[1]),
        black: f32s(fixed(black, &tile, "black")?),
        scale: f32s(fixed(scale, &tile, "scale")?),
        matrix: [m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]],
        tone: Tone::from_name(tone).map_err(to_pyerr)?,
        method: Method::from_name_for(method, &pattern).map_err(to_pyerr)?,
        auto_bright: auto_bright.map(|pixels| AutoBright { pixels }),
    };
    let src = contiguous(&arr)?;
    let (p, pat) = (&params, &pattern);
    let lens = lens.as_ref().map(|l| l.get().corrector());
    // 8-bit output keeps a 16-bit demosaic; 16-bit and float outputs are
    // demosaiced and finished in the output array itself unless a lens
    // correction resamples them.
    let size = (h, w);
    match (bps, &lens) {
        ("8", Some(c)) => run_corrected::<u16, u8>(py, &src, size, (pat, p), c),
        ("8", None) => run(py, &src, size, |v, out| {
            u16::with_kept(|staging| develop_staging::<u16, u8>(v, pat, p, staging, out))
        }),
        ("16", Some(c)) => run_corrected::<u16, u16>(py, &src, size, (pat, p), c),
        ("16", None) => run(py, &src, size, |v, out| {
            develop_in_place::<u16>(v, pat, p, out)
        }),
        ("float", Some(c)) => run_corrected::<f32, f32>(py, &src, size, (pat, p), c),
        ("float", None) => run(py, &src, size, |v, out| {
            develop_in_place::<f32>(v, pat, p, out)
        }),
        (other, _) => Err(PyValueError::new_err(format!(
            "bps must be \"8\", \"16\" or \"float\", got {other:?}"
        ))),
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(develop, m)?)?;
    m.add("TONES", PyTuple::new(m.py(), Tone::ALL.map(Tone::name))?)?;
    Ok(())
}

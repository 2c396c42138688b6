//! Bindings of `imgform_core::align`.

use imgform_core::align::{self, EccOptions, Features, Matrix, Metric, Motion, Options, Pyramid};
use imgform_core::image::{ImageView, Sample};
use numpy::{Element, PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;

use crate::arrays::{contiguous, image_dims, to_numpy, AnyImage};
use crate::dispatch_image;
use crate::errors::{detached, to_pyerr};

/// `b` as an array of the same sample type as `a`.
fn partner<'py, T: Element>(
    b: &Bound<'py, PyAny>,
    a: &PyReadonlyArrayDyn<'py, T>,
    name: &str,
) -> PyResult<PyReadonlyArrayDyn<'py, T>> {
    let arr = AnyImage::extract(b, name)?;
    let dtype = a.dtype();
    b.extract::<PyReadonlyArrayDyn<'py, T>>().map_err(|_| {
        let got = match arr {
            AnyImage::U8(_) => "uint8",
            AnyImage::U16(_) => "uint16",
            AnyImage::F32(_) => "float32",
        };
        PyTypeError::new_err(format!(
            "both images must have the same dtype, got {dtype} and {got}"
        ))
    })
}

/// Runs `kernel` on the two images as core views, with the GIL released.
fn with_views<'py, T, R, F>(
    py: Python<'py>,
    a: PyReadonlyArrayDyn<'py, T>,
    b: &Bound<'py, PyAny>,
    names: (&str, &str),
    kernel: F,
) -> PyResult<R>
where
    T: Element + Sample,
    R: Send,
    F: Send + FnOnce(&ImageView<'_, T>, &ImageView<'_, T>) -> imgform_core::Result<R>,
{
    let b = partner(b, &a, names.1)?;
    let (h, w, c) = image_dims(a.shape(), names.0)?;
    let (hb, wb, cb) = image_dims(b.shape(), names.1)?;
    let (sa, sb) = (contiguous(&a)?, contiguous(&b)?);
    detached(py, || {
        let va = ImageView::contiguous(&sa, w, h, c)?;
        let vb = ImageView::contiguous(&sb, wb, hb, cb)?;
        kernel(&va, &vb)
    })
}

fn similarity_of<'py, T: Element + Sample>(
    a: PyReadonlyArrayDyn<'py, T>,
    py: Python<'py>,
    b: &Bound<'py, PyAny>,
    metric: Metric,
) -> PyResult<f64> {
    with_views(py, a, b, ("a", "b"), |va, vb| {
        align::similarity(va, vb, metric)
    })
}

/// The metric between two same-shaped single-channel images.
#[pyfunction]
fn similarity(
    py: Python<'_>,
    a: &Bound<'_, PyAny>,
    b: &Bound<'_, PyAny>,
    metric: &str,
) -> PyResult<f64> {
    let metric = Metric::parse(metric).map_err(to_pyerr)?;
    let img = AnyImage::extract(a, "a")?;
    dispatch_image!(img, similarity_of(py, b, metric))
}

/// One level: (scale, candidates, (dy, dx), score).
type LevelTuple = (usize, usize, (i64, i64), f64);

/// Everything an alignment returns, flattened for Python.
type AlignTuple<'py> = (
    (f64, f64),
    f64,
    Bound<'py, PyArrayDyn<f64>>,
    (i64, i64),
    Vec<LevelTuple>,
);

fn align_of<'py, T: Element + Sample>(
    a: PyReadonlyArrayDyn<'py, T>,
    py: Python<'py>,
    b: &Bound<'py, PyAny>,
    opts: Options,
) -> PyResult<AlignTuple<'py>> {
    let res = with_views(py, a, b, ("reference", "moving"), |va, vb| {
        align::align(va, vb, &opts)
    })?;
    let levels = res
        .levels
        .iter()
        .map(|l| (l.scale, l.candidates, l.shift, l.score))
        .collect();
    let surface = to_numpy(py, res.surface, &[res.side, res.side])?;
    Ok((res.shift, res.score, surface, res.surface_origin, levels))
}

/// Aligns `moving` onto `reference`; returns (shift, score, surface,
/// surface_origin, levels). `levels=None` is the automatic pyramid.
#[pyfunction]
#[pyo3(signature = (reference, moving, max_shift, metric, crop, levels, features, subpixel))]
#[allow(clippy::too_many_arguments)]
fn align_images<'py>(
    py: Python<'py>,
    reference: &Bound<'py, PyAny>,
    moving: &Bound<'py, PyAny>,
    max_shift: i64,
    metric: &str,
    crop: f64,
    levels: Option<usize>,
    features: &str,
    subpixel: bool,
) -> PyResult<AlignTuple<'py>> {
    let opts = Options {
        max_shift,
        metric: Metric::parse(metric).map_err(to_pyerr)?,
        crop,
        pyramid: levels.map_or(Pyramid::Auto, Pyramid::Levels),
        features: Features::parse(features).map_err(to_pyerr)?,
        subpixel,
    };
    let img = AnyImage::extract(reference, "reference")?;
    dispatch_image!(img, align_of(py, moving, opts))
}

/// What a refinement returns per channel: (matrix rows, score, iterations
/// per level, converged).
type RefineTuple = ([[f64; 3]; 2], f64, Vec<usize>, bool);

fn refine_of<'py, T: Element + Sample>(
    a: PyReadonlyArrayDyn<'py, T>,
    py: Python<'py>,
    movings: &[Bound<'py, PyAny>],
    motion: Motion,
    inits: Vec<Matrix>,
    opts: EccOptions,
) -> PyResult<Vec<RefineTuple>> {
    let bs = movings
        .iter()
        .map(|b| partner(b, &a, "moving"))
        .collect::<PyResult<Vec<_>>>()?;
    let (h, w, c) = image_dims(a.shape(), "reference")?;
    let dims = bs
        .iter()
        .map(|b| image_dims(b.shape(), "moving"))
        .collect::<PyResult<Vec<_>>>()?;
    let sa = contiguous(&a)?;
    let sbs = bs.iter().map(contiguous).collect::<PyResult<Vec<_>>>()?;
    let res = detached(py, || {
        let va = ImageView::contiguous(&sa, w, h, c)?;
        let vbs = sbs
            .iter()
            .zip(&dims)
            .map(|(s, &(hb, wb, cb))| ImageView::contiguous(s, wb, hb, cb))
            .collect::<imgform_core::Result<Vec<_>>>()?;
        align::refine_many(&va, &vbs, motion, &inits, &opts)
    })?;
    Ok(res
        .into_iter()
        .map(|r| (r.matrix, r.score, r.iterations, r.converged))
        .collect())
}

/// Refines each `inits[k]` (2x3, reference pixel to moving position) of
/// `movings[k]` under `motion` by ECC, coarse to fine, with the reference's
/// pyramid shared; `levels=None` is the automatic pyramid.
#[pyfunction]
#[pyo3(signature = (reference, movings, motion, inits, crop, levels, max_iterations, tolerance, features))]
#[allow(clippy::too_many_arguments)]
fn refine_warp(
    py: Python<'_>,
    reference: &Bound<'_, PyAny>,
    movings: Vec<Bound<'_, PyAny>>,
    motion: &str,
    inits: Vec<[[f64; 3]; 2]>,
    crop: f64,
    levels: Option<usize>,
    max_iterations: usize,
    tolerance: f64,
    features: &str,
) -> PyResult<Vec<RefineTuple>> {
    let motion = Motion::parse(motion).map_err(to_pyerr)?;
    let opts = EccOptions {
        crop,
        levels,
        max_iterations,
        tolerance,
        features: Features::parse(features).map_err(to_pyerr)?,
    };
    let img = AnyImage::extract(reference, "reference")?;
    dispatch_image!(img, refine_of(py, &movings, motion, inits, opts))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(similarity, m)?)?;
    m.add_function(wrap_pyfunction!(align_images, m)?)?;
    m.add_function(wrap_pyfunction!(refine_warp, m)?)?;
    Ok(())
}

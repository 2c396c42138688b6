//! Raw development: sensor numbers to a displayable RGB image.
//!
//! Two steps surround the demosaic. Before it, each photosite loses its
//! black level and is multiplied by one per-site factor that folds together
//! the scaling to white (`1 / (white - black)`), the white balance and the
//! exposure; the result is clipped to `[0, 1]` (the sensor clipped there, so
//! the balanced channels clip at the same point, as LibRaw's `highlight=0`
//! does) and rounded to the demosaic's own sample type. After it, each pixel
//! is rounded to that type again, goes through the 3x3 colour matrix, is
//! clipped again and passes the tone curve into the output type. Both steps
//! are pure per pixel, so the result does not depend on the number of
//! threads.
//!
//! Integer outputs demosaic in `u16` units (16 bits hold a 14-bit sensor
//! with WB gains of up to 4x without loss, as in LibRaw); float outputs
//! in `f32`. For every Bayer method but nearest the whole development is
//! one pass: the demosaic loads its tiles or rows through `Prepared` and
//! stores them through `Finish`, so nothing full-size exists but the raw
//! and the output, and each pixel is finished while it is still in cache
//! (a third pass over 144 MB cost about a fifth of the time at 24 MP). The
//! others (nearest, X-Trans) prepare a mosaic image, demosaic it and finish
//! the result in place; both routes give the same bytes. A development
//! brightened as LibRaw does by default ([`AutoBright`]) takes the staged
//! route too: the level is read off the demosaiced image before it is
//! finished.
//!
//! A lens correction ([`develop_corrected`]) adds nothing to the pass but
//! a factor: vignetting is removed as the photosites are prepared, on
//! linear light above black, before the clip to white (a pass of its own
//! over the mosaic into a new one, with the rounding of its result to 16
//! bits, took a tenth of a 24 MP development's time). Distortion and TCA
//! then resample the finished image once.

pub use crate::auto_bright::AutoBright;
use crate::auto_bright::Histograms;
use crate::cfa::{check_out_len, CfaPattern};
use crate::demosaic::{demosaic, demosaic_through, Convert, Method, Mosaic, RgbSink};
use crate::error::{all_finite, CoreError, Result};
use crate::image::{ImageView, Sample};
use crate::invalid;
#[cfg(doc)]
use crate::lens::LensCorrection;
use crate::lens::{GainRows, LensCorrector};
use crate::parallel::for_each_row;
use crate::remap::{Interpolation, Resample};
use rayon::prelude::*;
use std::marker::PhantomData;

/// The transfer curve from linear light to output code values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tone {
    /// No curve: output proportional to light (for further processing).
    Linear,
    /// IEC 61966-2-1 sRGB: a linear toe below 0.0031308, then a 1/2.4 power.
    Srgb,
    /// ITU-R BT.709 camera OETF: linear below 0.018, then a 0.45 power
    /// (also BT.2020's for 10-bit systems, whose constants round to these).
    Bt709,
    /// Adobe RGB (1998): a pure power of 256/563 (gamma 2.19921875), no toe.
    Gamma22,
    /// ROMM RGB (ProPhoto, ISO 22028-2): 16x below 1/512, then a 1/1.8
    /// power; the two meet at exactly 1/32.
    Romm,
}

impl Tone {
    /// Every curve, in documentation order.
    pub const ALL: [Tone; 5] = [
        Tone::Srgb,
        Tone::Linear,
        Tone::Bt709,
        Tone::Gamma22,
        Tone::Romm,
    ];

    /// The curve's name in the Python API.
    pub fn name(self) -> &'static str {
        match self {
            Tone::Linear => "linear",
            Tone::Srgb => "srgb",
            Tone::Bt709 => "bt709",
            Tone::Gamma22 => "gamma22",
            Tone::Romm => "romm",
        }
    }

    /// Parses a name of [`Tone::ALL`].
    ///
    /// # Errors
    /// [`CoreError::InvalidArgument`] listing the accepted names.
    pub fn from_name(name: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|t| t.name() == name)
            .ok_or_else(|| {
                invalid!(
                    "tone must be one of {:?}, got {name:?}",
                    Self::ALL.map(Tone::name)
                )
            })
    }

    /// The curve at linear value `v` in `[0, 1]`.
    pub fn apply(self, v: f32) -> f32 {
        match self {
            Tone::Linear => v,
            Tone::Srgb if v <= 0.003_130_8 => 12.92 * v,
            Tone::Srgb => 1.055 * v.powf(1.0 / 2.4) - 0.055,
            Tone::Bt709 if v < 0.018 => 4.5 * v,
            Tone::Bt709 => 1.099 * v.powf(0.45) - 0.099,
            Tone::Gamma22 => v.powf(256.0 / 563.0),
            Tone::Romm if v < 1.0 / 512.0 => 16.0 * v,
            Tone::Romm => v.powf(1.0 / 1.8),
        }
    }
}

/// Everything the development applies around the demosaic.
#[derive(Debug, Clone)]
pub struct DevelopParams {
    /// `(rows, cols)` of the tile `black` and `scale` describe, repeated from
    /// pixel (0, 0): the CFA period, or a multiple of it when the sensor's
    /// black level repeats with a longer period (a DNG `BlackLevel` pattern
    /// larger than the CFA tile, which LibRaw subtracts pixel by pixel).
    pub tile: (usize, usize),
    /// Black level per tile cell (row-major), in digital numbers.
    pub black: Vec<f32>,
    /// Multiplier per tile cell applied after black subtraction, mapping
    /// white-balanced white to 1.0 (exposure included).
    pub scale: Vec<f32>,
    /// Row-major 3x3 matrix from white-balanced camera RGB to output RGB.
    pub matrix: [f32; 9],
    /// The output transfer curve.
    pub tone: Tone,
    /// The demosaicing method.
    pub method: Method,
    /// Whether to brighten the development as LibRaw does by default
    /// ([`AutoBright`]); it then goes through the staged route, whose
    /// demosaiced image the level is read off before it is finished.
    pub auto_bright: Option<AutoBright>,
}

impl DevelopParams {
    fn check(&self, pattern: &CfaPattern) -> Result<()> {
        let ((rows, cols), p) = (self.tile, pattern.period());
        if rows == 0 || cols == 0 || rows % p != 0 || cols % p != 0 {
            return Err(CoreError::Shape(format!(
                "the black/scale tile must be a multiple of the {p}x{p} CFA tile, got {rows}x{cols}"
            )));
        }
        let cells = rows * cols;
        for (name, v) in [("black", &self.black), ("scale", &self.scale)] {
            if v.len() != cells {
                return Err(CoreError::Shape(format!(
                    "{name} must have one value per cell of the {rows}x{cols} tile ({cells}), got {}",
                    v.len()
                )));
            }
            let as_f64: Vec<f64> = v.iter().map(|&x| f64::from(x)).collect();
            all_finite(name, &as_f64)?;
        }
        if let Some(s) = self.scale.iter().find(|&&s| s < 0.0) {
            return Err(invalid!("scale factors must be >= 0, got {s}"));
        }
        let m: Vec<f64> = self.matrix.iter().map(|&x| f64::from(x)).collect();
        all_finite("matrix", &m)
    }
}

/// Develops a raw mosaic into `out`, `(H, W, 3)` samples of type `U`,
/// demosaicing in the units of type `T` (for `u8` outputs, which keep a
/// 16-bit demosaic: `develop::<u16, u8>`).
///
/// # Errors
/// [`CoreError::Shape`] for a multi-channel or too small `raw`, parameter
/// arrays of the wrong length or a wrong output length;
/// [`CoreError::InvalidArgument`] for non-finite or negative parameters or a
/// pattern the method cannot demosaic (X-Trans).
pub fn develop<T: Sample, U: Sample>(
    raw: ImageView<'_, u16>,
    pattern: &CfaPattern,
    params: &DevelopParams,
    out: &mut [U],
) -> Result<()> {
    develop_staging::<T, U>(raw, pattern, params, &mut Vec::new(), out)
}

/// [`develop`] with the working image of a staged development in
/// `staging`: the linear demosaic that a brightened development counts
/// before finishing it, or that nearest and X-Trans make. `staging` is
/// replaced by one of `out`'s length unless it has that length already, so
/// a caller that keeps it from call to call pays the OS's zeroing of fresh
/// pages once: 0.05 s per 144 MB here, a seventh of a brightened 24 MP
/// 8-bit development. Unused (and untouched) by the one-pass route.
///
/// # Errors
/// As [`develop`].
pub fn develop_staging<T: Sample, U: Sample>(
    raw: ImageView<'_, u16>,
    pattern: &CfaPattern,
    params: &DevelopParams,
    staging: &mut Vec<T>,
    out: &mut [U],
) -> Result<()> {
    develop_devignetted::<T, U>(raw, pattern, params, None, staging, out)
}

/// [`develop`] of a photograph taken through the lens that `corrector`
/// describes, for images of the mosaic's size: its vignetting (if it has
/// a model) is removed from each photosite above black as the mosaic is
/// prepared, its distortion and TCA (if any) by resampling the finished
/// image bilinearly, taps outside it reading 0
/// ([`LensCorrection::correct_geometry`] of the development, bit for bit),
/// through the grid of positions that `corrector` keeps from call to call.
///
/// The resampling reads rows tens of pixels away from the one it writes
/// (more at the corners), so the development goes to `developed` first,
/// working memory of `out`'s length (its contents do not matter; unused
/// without distortion and TCA). The caller provides it so that it can be
/// memory the OS backs with huge pages, as NumPy asks for large arrays (a
/// fresh `Vec` of a 24 MP 8-bit development took ~0.07 s of page faults
/// on 4 KiB pages, a tenth of the corrected develop), or memory kept from
/// an earlier call, which faults no more. `staging` serves a staged
/// development as in [`develop_staging`].
///
/// # Errors
/// As [`develop`], a correction made for another image size, and a
/// `developed` of another length than `out`.
pub fn develop_corrected<T: Sample, U: Resample>(
    raw: ImageView<'_, u16>,
    pattern: &CfaPattern,
    params: &DevelopParams,
    corrector: &LensCorrector,
    (staging, developed): (&mut Vec<T>, &mut [U]),
    out: &mut [U],
) -> Result<()> {
    let lens = corrector.lens();
    let (w, h) = (raw.width(), raw.height());
    if (lens.width, lens.height) != (w, h) {
        return Err(CoreError::Shape(format!(
            "the lens correction was set up for {}x{} images, the mosaic is {h}x{w}",
            lens.height, lens.width
        )));
    }
    let gains = lens.vignetting.map(|_| lens.gain_rows());
    if !lens.corrects_geometry() {
        return develop_devignetted::<T, U>(raw, pattern, params, gains.as_ref(), staging, out);
    }
    check_out_len(out.len(), 3 * w * h, "develop")?;
    if developed.len() != out.len() {
        return Err(CoreError::Shape(format!(
            "the working buffer must hold as many samples as the output ({}), got {}",
            out.len(),
            developed.len()
        )));
    }
    develop_devignetted::<T, U>(raw, pattern, params, gains.as_ref(), staging, developed)?;
    let developed = ImageView::contiguous(developed, w, h, 3)?;
    corrector.correct_geometry(&developed, Interpolation::Bilinear, 0.0, false, out)
}

/// [`develop`] with the photosites above black multiplied by `vignetting`'s
/// gains as they are prepared.
fn develop_devignetted<T: Sample, U: Sample>(
    raw: ImageView<'_, u16>,
    pattern: &CfaPattern,
    params: &DevelopParams,
    vignetting: Option<&GainRows>,
    staging: &mut Vec<T>,
    out: &mut [U],
) -> Result<()> {
    if params.auto_bright.is_none() && fused::<T, U>(raw, pattern, params, vignetting, out)? {
        return Ok(());
    }
    if staging.len() != out.len() {
        // Zeroed by the OS as the demosaic's threads first write it, not
        // here by one thread (as `resize` would).
        *staging = vec![T::default(); out.len()];
    }
    let rgb = &mut staging[..];
    demosaic_prepared(raw, pattern, params, vignetting, rgb)?;
    let row_len = 3 * raw.width();
    let finish = Finish::<T, U>::of(params, rgb, row_len);
    for_each_row(out, row_len, |y, row| {
        finish.pixels(&rgb[row_len * y..row_len * (y + 1)], row);
    });
    Ok(())
}

/// [`develop`] into an output of the demosaic's own type (`u16`, `f32`):
/// where the demosaic needs a mosaic image (nearest, X-Trans), it writes
/// into `out` and is finished there, so no second full-size buffer is made
/// (144 MB less at 24 MP in 16 bits).
///
/// # Errors
/// As [`develop`].
pub fn develop_in_place<T: Sample>(
    raw: ImageView<'_, u16>,
    pattern: &CfaPattern,
    params: &DevelopParams,
    out: &mut [T],
) -> Result<()> {
    if params.auto_bright.is_none() && fused::<T, T>(raw, pattern, params, None, out)? {
        return Ok(());
    }
    demosaic_prepared(raw, pattern, params, None, out)?;
    let finish = Finish::<T, T>::of(params, out, 3 * raw.width());
    for_each_row(out, 3 * raw.width(), |_, row| {
        // The finish reads all of a pixel before writing it, but takes
        // its input apart from its output: one row's copy per call.
        let src = row.to_vec();
        finish.pixels(&src, row);
    });
    Ok(())
}

/// Checks the parameters and the mosaic.
fn check(raw: &ImageView<'_, u16>, pattern: &CfaPattern, params: &DevelopParams) -> Result<()> {
    params.check(pattern)?;
    if raw.channels() != 1 {
        return Err(CoreError::Shape(format!(
            "develop needs a single-channel mosaic of shape (H, W), got {} channels",
            raw.channels()
        )));
    }
    Ok(())
}

/// The one-pass development (see the module docs), or `Ok(false)` for a
/// method that needs a mosaic image.
fn fused<T: Sample, U: Sample>(
    raw: ImageView<'_, u16>,
    pattern: &CfaPattern,
    params: &DevelopParams,
    vignetting: Option<&GainRows>,
    out: &mut [U],
) -> Result<bool> {
    check(&raw, pattern, params)?;
    check_out_len(out.len(), 3 * raw.width() * raw.height(), "develop")?;
    let mosaic = Prepared::<T>::new(raw, params, vignetting);
    let finish = Finish::<T, U>::new(params);
    demosaic_through::<T, _, _, _>(&mosaic, pattern, params.method, &finish, out)
}

/// Checks everything and demosaics the prepared mosaic into `rgb`: through
/// its loads where the method can ([`demosaic_through`]), which spares a
/// mosaic image and its pass (4-9 % of a brightened 24 MP development's
/// time), else from a prepared image ([`demosaic_image`]).
fn demosaic_prepared<T: Sample>(
    raw: ImageView<'_, u16>,
    pattern: &CfaPattern,
    params: &DevelopParams,
    vignetting: Option<&GainRows>,
    rgb: &mut [T],
) -> Result<()> {
    check(&raw, pattern, params)?;
    check_out_len(rgb.len(), 3 * raw.width() * raw.height(), "develop")?;
    let prepared = Prepared::<T>::new(raw, params, vignetting);
    if demosaic_through::<T, _, _, _>(&prepared, pattern, params.method, &Convert, rgb)? {
        return Ok(());
    }
    demosaic_image(&prepared, pattern, params.method, rgb)
}

/// Demosaics `prepared` into `rgb` from an image of it, for the methods
/// that cannot load it row by row.
fn demosaic_image<T: Sample>(
    prepared: &Prepared<'_, T>,
    pattern: &CfaPattern,
    method: Method,
    rgb: &mut [T],
) -> Result<()> {
    let (w, h) = (prepared.width(), prepared.height());
    let mut mosaic = vec![T::default(); w * h];
    for_each_row(&mut mosaic, w, |y, row| {
        let mut lin = vec![0.0f32; w];
        prepared.load(y, 0, &mut lin);
        T::from_f32_row(row, &lin);
    });
    // Prepared at the type's full scale, which is its white level.
    demosaic(
        ImageView::contiguous(&mosaic, w, h, 1)?,
        pattern,
        method,
        Some(T::FULL_SCALE),
        rgb,
    )
}

/// Photosites per step of [`Prepared::load`]: its black levels and factors
/// are laid out for this many columns from any cell of the tile, so the
/// loop over samples is a plain zip that vectorises (a `x % cols` in it cost
/// more than the rest).
const RUN: usize = 256;

/// The raw mosaic as the demosaic sees it: black subtracted, scaled
/// (devignetted too, if a lens correction asks for it), clipped to `[0, 1]`
/// of `T`'s full scale and rounded to `T`, computed as the demosaic loads
/// it.
pub(crate) struct Prepared<'a, T> {
    raw: ImageView<'a, u16>,
    /// `(rows, cols)` of the black/scale tile.
    tile: (usize, usize),
    /// Per tile row, the row's black levels repeated over `cols + RUN`
    /// columns, so that any run of up to [`RUN`] columns starting at any
    /// cell is one slice.
    black: Vec<Vec<f32>>,
    /// The factors likewise, in `T`'s full scale so that one clamp bounds
    /// the result.
    scale: Vec<Vec<f32>>,
    /// The vignetting gains that multiply the factors, photosite by
    /// photosite.
    vignetting: Option<&'a GainRows>,
    sample: PhantomData<T>,
}

impl<'a, T: Sample> Prepared<'a, T> {
    fn new(raw: ImageView<'a, u16>, p: &DevelopParams, vignetting: Option<&'a GainRows>) -> Self {
        let (rows, cols) = p.tile;
        let repeat = |v: &[f32], y: usize, f: f32| -> Vec<f32> {
            let cells = &v[y * cols..(y + 1) * cols];
            cells
                .iter()
                .cycle()
                .take(cols + RUN)
                .map(|&c| c * f)
                .collect()
        };
        Self {
            raw,
            tile: p.tile,
            black: (0..rows).map(|y| repeat(&p.black, y, 1.0)).collect(),
            scale: (0..rows)
                .map(|y| repeat(&p.scale, y, T::FULL_SCALE))
                .collect(),
            vignetting,
            sample: PhantomData,
        }
    }
}

impl<T: Sample> Mosaic for Prepared<'_, T> {
    fn width(&self) -> usize {
        self.raw.width()
    }

    fn height(&self) -> usize {
        self.raw.height()
    }

    #[inline(always)]
    fn load(&self, y: usize, x0: usize, dst: &mut [f32]) {
        let (rows, cols) = self.tile;
        let (black, scale) = (&self.black[y % rows], &self.scale[y % rows]);
        let src = &self.raw.row(y)[x0..x0 + dst.len()];
        let prepare = |v: u16, b: f32, f: f32| {
            T::quantize(((f32::from(v) - b) * f).clamp(0.0, T::FULL_SCALE))
        };
        for (i, (d, s)) in dst.chunks_mut(RUN).zip(src.chunks(RUN)).enumerate() {
            let x = x0 + i * RUN;
            let c = x % cols;
            let (b, f) = (&black[c..c + d.len()], &scale[c..c + d.len()]);
            let Some(vignetting) = self.vignetting else {
                for (((d, &v), &b), &f) in d.iter_mut().zip(s).zip(b).zip(f) {
                    *d = prepare(v, b, f);
                }
                continue;
            };
            let mut gains = [0.0f32; RUN];
            let gains = &mut gains[..d.len()];
            vignetting.row(y, x, gains);
            for ((((d, &v), &b), &f), &g) in d.iter_mut().zip(s).zip(b).zip(f).zip(&*gains) {
                *d = prepare(v, b, f * g);
            }
        }
    }

    fn range(&self) -> (f32, f32) {
        let w = self.width();
        (0..self.height())
            .into_par_iter()
            .map_init(|| vec![0.0f32; w], |row, y| self.row_range(y, row))
            .reduce(
                || (f32::INFINITY, f32::NEG_INFINITY),
                |a, b| (a.0.min(b.0), a.1.max(b.1)),
            )
    }
}

impl<T: Sample> Prepared<'_, T> {
    /// The smallest and largest prepared value of row `y`, loaded into
    /// `row`. Compiled for AVX2 where the CPU has it, as the demosaics that
    /// load the same values are: this pass over the whole mosaic ran in
    /// baseline code, two lanes wide, and with vignetting (a division per
    /// photosite) it took 4 % of a corrected 24 MP develop's profile. The
    /// operations, and so the bits, are the same.
    fn row_range(&self, y: usize, row: &mut [f32]) -> (f32, f32) {
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::has_avx2() {
            // SAFETY: AVX2 was detected just above.
            return unsafe { self.row_range_avx2(y, row) };
        }
        self.row_range_any(y, row)
    }

    /// [`Prepared::row_range`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn row_range_avx2(&self, y: usize, row: &mut [f32]) -> (f32, f32) {
        self.row_range_any(y, row)
    }

    #[inline(always)]
    fn row_range_any(&self, y: usize, row: &mut [f32]) -> (f32, f32) {
        self.load(y, 0, row);
        row.iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            })
    }
}

/// The end of the development: demosaiced pixels, rounded to `T` as a
/// demosaic into `T` would, through the colour matrix, a clip to `[0, 1]`
/// and the tone curve into `U`.
pub(crate) struct Finish<T, U> {
    matrix: [f32; 9],
    curve: Curve<U>,
    sample: PhantomData<T>,
}

/// Per-task buffers of [`Finish`]: one row's values after the matrix, and
/// their tone-table indices, as planes.
pub(crate) type FinishScratch = ([Vec<f32>; 3], [Vec<u16>; 3]);

impl<T: Sample, U: Sample> Finish<T, U> {
    fn new(p: &DevelopParams) -> Self {
        Self {
            matrix: p.matrix,
            curve: Curve::new(p.tone),
            sample: PhantomData,
        }
    }

    /// The finish of `p` for the demosaiced rows `rgb`, `row_len` samples
    /// each: brightened by the gain of `p.auto_bright` on them, if any,
    /// folded into the matrix. LibRaw clips after the matrix and again
    /// after brightening; with a gain of at least 1 that is one clip of
    /// the brightened values.
    fn of(p: &DevelopParams, rgb: &[T], row_len: usize) -> Self {
        let mut finish = Self::new(p);
        if let Some(auto) = p.auto_bright {
            let linear = Finish::<T, u16> {
                curve: Curve::new(Tone::Linear),
                ..Finish::new(p)
            };
            let gain = auto.gain(&Histograms::of(rgb, row_len, |src, codes| {
                linear.pixels(src, codes)
            }));
            finish.matrix = p.matrix.map(|m| (f64::from(m) * gain) as f32);
        }
        finish
    }

    /// Finishes a row of interleaved demosaiced pixels `src` into `out`.
    /// Compiled for AVX2 where the CPU has it, as the one-pass route's
    /// finish is inside the demosaic's tiles: in baseline code the staged
    /// passes of a brightened 24 MP development (its count and finish) took
    /// 35 ms more, a tenth of it. The operations, and so the bits, are the
    /// same.
    fn pixels(&self, src: &[T], out: &mut [U]) {
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::has_avx2() {
            // SAFETY: AVX2 was detected just above.
            return unsafe { self.pixels_avx2(src, out) };
        }
        self.pixels_any(src, out)
    }

    /// [`Finish::pixels`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn pixels_avx2(&self, src: &[T], out: &mut [U]) {
        self.pixels_any(src, out)
    }

    #[inline(always)]
    fn pixels_any(&self, src: &[T], out: &mut [U]) {
        let n = src.len() / 3;
        let mut planes = [0; 3].map(|_| vec![0.0f32; n]);
        // One pass over the pixels, which LLVM turns into shuffles; three
        // strided passes collected into vectors took half the time of a
        // staged finish.
        let [r, g, b] = planes.each_mut();
        let split = r.iter_mut().zip(g.iter_mut()).zip(b.iter_mut());
        for (p, ((r, g), b)) in src.chunks_exact(3).zip(split) {
            (*r, *g, *b) = (p[0].to_f32(), p[1].to_f32(), p[2].to_f32());
        }
        let mut scratch = self.scratch(n);
        self.store(&mut scratch, planes.each_ref().map(|p| &p[..]), None, out);
    }
}

impl<T: Sample, U: Sample> RgbSink<U> for Finish<T, U> {
    type Scratch = FinishScratch;

    fn scratch(&self, width: usize) -> FinishScratch {
        (
            [0, 1, 2].map(|_| vec![0.0; width]),
            [0, 1, 2].map(|_| vec![0; width]),
        )
    }

    /// The matrix runs over planes, where it vectorises 8 pixels wide; the
    /// tone lookups, which cannot, follow in a loop of their own.
    #[inline(always)]
    fn store(
        &self,
        (lin, idx): &mut FinishScratch,
        rgb: [&[f32]; 3],
        within: Option<(f32, f32)>,
        out: &mut [U],
    ) {
        let n = out.len() / 3;
        let (m, inv, span) = (&self.matrix, 1.0 / T::FULL_SCALE, self.curve.span());
        let clamp = |v: f32| within.map_or(v, |(lo, hi)| v.max(lo).min(hi));
        let [r, g, b] = rgb.map(|p| &p[..n]);
        let [l0, l1, l2] = lin;
        let (l0, l1, l2) = (&mut l0[..n], &mut l1[..n], &mut l2[..n]);
        for i in 0..n {
            // Written out rather than an array `map`: inside the larger tile
            // loops of the learned demosaicers the map stopped being inlined
            // and became a call per pixel (13 % of a develop's profile).
            let q = |v: f32| T::quantize(clamp(v)) * inv;
            let (r, g, b) = (q(r[i]), q(g[i]), q(b[i]));
            l0[i] = (m[0] * r + m[1] * g + m[2] * b).clamp(0.0, 1.0) * span;
            l1[i] = (m[3] * r + m[4] * g + m[5] * b).clamp(0.0, 1.0) * span;
            l2[i] = (m[6] * r + m[7] * g + m[8] * b).clamp(0.0, 1.0) * span;
        }
        self.curve.write([&*l0, &*l1, &*l2], idx, out);
    }
}

/// Entries of the tone table: one per 16-bit step of the linear value over
/// `[0, 1]`, exact to the output's resolution.
const TABLE_LEN: usize = 65536;

/// The tone curve into samples of `U`: tabulated for integer outputs
/// (holding the finished sample, so that no `powf` and no second conversion
/// runs per sample), evaluated directly for float outputs.
enum Curve<U> {
    Exact(Tone),
    /// Indexed by a `u16`, so no index can miss and no bounds check runs.
    Table(Box<[U; TABLE_LEN]>),
}

impl<U: Sample> Curve<U> {
    fn new(tone: Tone) -> Self {
        if U::FULL_SCALE == 1.0 {
            return Curve::Exact(tone);
        }
        let mut t = Box::new([U::default(); TABLE_LEN]);
        let steps = (TABLE_LEN - 1) as f32;
        for (i, v) in t.iter_mut().enumerate() {
            *v = U::from_f32(tone.apply(i as f32 / steps) * U::FULL_SCALE);
        }
        Curve::Table(t)
    }

    /// What a linear value of 1 becomes before [`Curve::write`]: a table
    /// position for integer outputs, itself for floats.
    fn span(&self) -> f32 {
        match self {
            Curve::Exact(_) => 1.0,
            Curve::Table(_) => (TABLE_LEN - 1) as f32,
        }
    }

    /// The curve over planes of clipped values `v` scaled by
    /// [`Curve::span`], interleaved into `out`; `idx` is scratch.
    #[inline(always)]
    fn write(&self, v: [&[f32]; 3], idx: &mut [Vec<u16>; 3], out: &mut [U]) {
        match self {
            Curve::Exact(t) => {
                let px = v[0].iter().zip(v[1]).zip(v[2]);
                for (o, ((&r, &g), &b)) in out.chunks_exact_mut(3).zip(px) {
                    let f = |c: f32| U::from_f32(t.apply(c));
                    o.copy_from_slice(&[f(r), f(g), f(b)]);
                }
            }
            Curve::Table(t) => {
                // Positions are in [0, 65535]: rounded half up, they land
                // in the table; the row conversion vectorises.
                for (i, v) in idx.iter_mut().zip(v) {
                    u16::from_f32_row(&mut i[..v.len()], v);
                }
                let px = idx[0].iter().zip(&idx[1]).zip(&idx[2]);
                for (o, ((&r, &g), &b)) in out.chunks_exact_mut(3).zip(px) {
                    let f = |c: u16| t[usize::from(c)];
                    o.copy_from_slice(&[f(r), f(g), f(b)]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lens::LensCorrection;

    fn params(black: f32, scale: f32, tone: Tone) -> DevelopParams {
        DevelopParams {
            tile: (2, 2),
            black: vec![black; 4],
            scale: vec![scale; 4],
            matrix: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            tone,
            method: Method::Bilinear,
            auto_bright: None,
        }
    }

    #[test]
    fn flat_grey_raw_develops_to_its_scaled_value() {
        // (1064 - 64) / 2000 = 0.5 -> 32768 in 16-bit linear (0.5 * 65535 rounded).
        let raw = vec![1064u16; 8 * 6];
        let mut out = vec![0u16; 8 * 6 * 3];
        let p = params(64.0, 1.0 / 2000.0, Tone::Linear);
        let pat = CfaPattern::from_name("RGGB").unwrap();
        develop_in_place(
            ImageView::contiguous(&raw, 8, 6, 1).unwrap(),
            &pat,
            &p,
            &mut out,
        )
        .unwrap();
        assert!(
            out.iter().all(|&v| v.abs_diff(32768) <= 1),
            "{:?}",
            &out[..6]
        );
    }

    #[test]
    fn srgb_tone_maps_half_to_its_standard_code() {
        // sRGB(0.5) = 1.055 * 0.5^(1/2.4) - 0.055 = 0.7354 -> 188 of 255.
        let raw = vec![500u16; 4 * 4];
        let mut out = vec![0u8; 4 * 4 * 3];
        let p = params(0.0, 1.0 / 1000.0, Tone::Srgb);
        let pat = CfaPattern::from_name("GBRG").unwrap();
        develop::<u16, u8>(
            ImageView::contiguous(&raw, 4, 4, 1).unwrap(),
            &pat,
            &p,
            &mut out,
        )
        .unwrap();
        assert!(out.iter().all(|&v| v == 188), "{:?}", &out[..3]);
    }

    #[test]
    fn adobe_and_romm_curves_hit_their_standard_values() {
        // 0.5^(256/563) = 0.729658; 0.5^(1/1.8) = 0.680395; both ends fixed.
        assert!((Tone::Gamma22.apply(0.5) - 0.729_658).abs() < 1e-5);
        assert!((Tone::Romm.apply(0.5) - 0.680_395).abs() < 1e-5);
        for t in [Tone::Gamma22, Tone::Romm] {
            assert_eq!((t.apply(0.0), t.apply(1.0)), (0.0, 1.0));
        }
        // ROMM's toe meets its power at 1/512 -> 1/32 without a step.
        let knee = 1.0 / 512.0;
        let (below, above) = (Tone::Romm.apply(knee * 0.9999), Tone::Romm.apply(knee));
        assert!((below - 1.0 / 32.0).abs() < 1e-5 && (above - 1.0 / 32.0).abs() < 1e-6);
    }

    #[test]
    fn per_cell_scale_and_matrix_reach_the_right_channels() {
        // Red sites read 100, others 200; red scaled x2 makes a flat 0.5 grey
        // once the matrix swaps nothing; then a matrix that copies R into B.
        let pat = CfaPattern::from_name("BGGR").unwrap();
        let raw: Vec<u16> = (0..16)
            .map(|i| {
                if pat.color_at(i / 4, i % 4) == 0 {
                    100
                } else {
                    200
                }
            })
            .collect();
        let mut p = params(0.0, 1.0 / 400.0, Tone::Linear);
        p.scale[3] = 2.0 / 400.0; // BGGR: red is cell (1, 1)
        p.matrix = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.5, 0.0, 0.0];
        let mut out = vec![0.0f32; 16 * 3];
        develop_in_place(
            ImageView::contiguous(&raw, 4, 4, 1).unwrap(),
            &pat,
            &p,
            &mut out,
        )
        .unwrap();
        for px in out.chunks(3) {
            assert!((px[0] - 0.5).abs() < 1e-6 && (px[1] - 0.5).abs() < 1e-6);
            assert!((px[2] - 0.25).abs() < 1e-6, "{px:?}");
        }
    }

    #[test]
    fn highlights_clip_at_white_before_and_after_the_matrix() {
        let raw = vec![4095u16; 4 * 4];
        let mut p = params(0.0, 2.0 / 4095.0, Tone::Linear);
        p.matrix = [1.5, -0.25, -0.25, -0.25, 1.5, -0.25, -0.25, -0.25, 1.5];
        let mut out = vec![0.0f32; 16 * 3];
        let pat = CfaPattern::from_name("RGGB").unwrap();
        develop::<f32, f32>(
            ImageView::contiguous(&raw, 4, 4, 1).unwrap(),
            &pat,
            &p,
            &mut out,
        )
        .unwrap();
        assert!(out.iter().all(|&v| v == 1.0));
    }

    #[test]
    fn in_place_and_separate_buffers_give_identical_bytes() {
        let raw: Vec<u16> = (0..24 * 18).map(|i| ((i * 7919) % 4096) as u16).collect();
        let view = ImageView::contiguous(&raw, 24, 18, 1).unwrap();
        let pat = CfaPattern::from_name("GRBG").unwrap();
        let mut p = params(100.0, 1.0 / 3000.0, Tone::Srgb);
        p.method = Method::HamiltonAdams;
        let (mut a, mut b) = (vec![0u16; 24 * 18 * 3], vec![0u16; 24 * 18 * 3]);
        develop::<u16, u16>(view, &pat, &p, &mut a).unwrap();
        develop_in_place(view, &pat, &p, &mut b).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn a_black_tile_longer_than_the_cfa_period_repeats_with_its_own_period() {
        // A 4x2 black pattern on a 2x2 Bayer tile: rows 0-1 of every four
        // lose 100, rows 2-3 lose nothing; 600 - 100 = 500 -> 0.5, 600 -> 0.6.
        let (w, h) = (6, 8);
        let raw = vec![600u16; w * h];
        let mut p = params(0.0, 1.0 / 1000.0, Tone::Linear);
        p.tile = (4, 2);
        p.black = vec![100.0, 100.0, 100.0, 100.0, 0.0, 0.0, 0.0, 0.0];
        p.scale = vec![1.0 / 1000.0; 8];
        let pat = CfaPattern::from_name("RGGB").unwrap();
        p.check(&pat).unwrap();
        let mosaic = Prepared::<f32>::new(ImageView::contiguous(&raw, w, h, 1).unwrap(), &p, None);
        let mut row = vec![0.0f32; w - 1];
        for y in 0..h {
            // From column 1: a load may start at any cell of the tile.
            mosaic.load(y, 1, &mut row);
            let want = if y % 4 < 2 { 0.5 } else { 0.6 };
            assert!(row.iter().all(|&v| (v - want).abs() < 1e-6), "{y}: {row:?}");
        }
        assert_eq!(mosaic.range(), (0.5, 0.6));
        p.tile = (3, 2);
        let err = p.check(&pat).unwrap_err().to_string();
        assert!(err.contains("multiple of the 2x2"), "{err}");
    }

    #[test]
    fn the_avx2_range_of_a_devignetted_mosaic_is_the_baseline_one() {
        // Vignetting gains push some photosites past white (clipped) and
        // leave the darkest above 0.
        let (w, h) = (301, 21);
        let raw: Vec<u16> = (0..w * h)
            .map(|i| ((i * 7919) % 3000 + 900) as u16)
            .collect();
        let view = ImageView::contiguous(&raw, w, h, 1).unwrap();
        let p = params(100.0, 1.0 / 3000.0, Tone::Linear);
        let gains = lens(w, h, true, false).gain_rows();
        let mosaic = Prepared::<u16>::new(view, &p, Some(&gains));
        let (mut row, mut row_any) = (vec![0.0f32; w], vec![0.0f32; w]);
        for y in 0..h {
            let got = mosaic.row_range(y, &mut row);
            assert_eq!(got, mosaic.row_range_any(y, &mut row_any), "row {y}");
            assert_eq!(row, row_any, "row {y}");
        }
        let (lo, hi) = mosaic.range();
        assert!(lo > 0.0 && hi == u16::FULL_SCALE, "{lo} {hi}");
    }

    /// [`develop`] the long way: the prepared mosaic as an image, the
    /// demosaic into `T`, then the finish, each over the whole image.
    fn staged<T: Sample, U: Sample>(
        raw: ImageView<'_, u16>,
        pat: &CfaPattern,
        p: &DevelopParams,
    ) -> Vec<U> {
        let mut rgb = vec![T::default(); 3 * raw.width() * raw.height()];
        demosaic_image(&Prepared::new(raw, p, None), pat, p.method, &mut rgb).unwrap();
        let mut out = vec![U::default(); rgb.len()];
        let finish = Finish::<T, U>::new(p);
        for (src, dst) in rgb
            .chunks(3 * raw.width())
            .zip(out.chunks_mut(3 * raw.width()))
        {
            finish.pixels(src, dst);
        }
        out
    }

    /// A colour matrix with a camera's typical negative off-diagonals.
    const CAMERA_MATRIX: [f32; 9] = [1.6, -0.4, -0.2, -0.3, 1.5, -0.2, 0.0, -0.5, 1.5];

    /// A mosaic `w` x `h` of values scattered over `0 .. top`.
    fn scrambled(w: usize, h: usize, top: usize) -> Vec<u16> {
        (0..w * h)
            .map(|i| ((i * 7919 + (i / w) * 131) % top) as u16)
            .collect()
    }

    #[test]
    fn one_pass_development_equals_the_staged_one_for_every_method() {
        // Wider than a demosaic tile (384 columns) and odd in both sizes,
        // with a black level above some samples, clipped highlights and a
        // black tile longer than the CFA's.
        let (w, h) = (391, 23);
        let raw = scrambled(w, h, 4500);
        let view = ImageView::contiguous(&raw, w, h, 1).unwrap();
        let pat = CfaPattern::from_name("GBRG").unwrap();
        let mut p = params(90.0, 1.0 / 3800.0, Tone::Srgb);
        p.tile = (2, 4);
        p.black = vec![90.0, 80.0, 100.0, 95.0, 70.0, 90.0, 85.0, 60.0];
        p.scale = vec![1.4 / 3800.0, 1.0 / 3800.0, 1.9 / 3800.0, 1.0 / 3800.0];
        p.scale.extend_from_within(..);
        p.matrix = CAMERA_MATRIX;
        for method in Method::ALL {
            p.method = method;
            let mut a = vec![0u8; 3 * w * h];
            develop::<u16, u8>(view, &pat, &p, &mut a).unwrap();
            assert!(a == staged::<u16, u8>(view, &pat, &p), "{method:?} u8");
            let mut b = vec![0u16; 3 * w * h];
            develop_in_place(view, &pat, &p, &mut b).unwrap();
            assert!(b == staged::<u16, u16>(view, &pat, &p), "{method:?} u16");
        }
        p.method = Method::RcdMenon;
        let mut f = vec![0.0f32; 3 * w * h];
        develop_in_place(view, &pat, &p, &mut f).unwrap();
        assert!(f == staged::<f32, f32>(view, &pat, &p));
    }

    fn lens(w: usize, h: usize, vignetting: bool, geometry: bool) -> LensCorrection {
        use crate::lens::{Normalization, RadialDistortion, Vignetting};
        LensCorrection {
            width: w,
            height: h,
            normalization: Normalization::new(w, h, 1.5, 1.5, 1.5, (0.01, -0.02)).unwrap(),
            distortion: if geometry {
                RadialDistortion::Poly3 { k1: -0.05 }
            } else {
                RadialDistortion::None
            },
            tca: crate::lens::Tca::None,
            vignetting: vignetting.then_some(Vignetting {
                k: [-0.3, 0.1, -0.05],
            }),
        }
    }

    #[test]
    fn auto_bright_equals_developing_twice() {
        // The level read off a linear 16-bit development, then the
        // development with the gain in its matrix: what LibRaw's rule asks,
        // and what the one demosaic must give, for every output type.
        let (w, h) = (64, 40);
        let raw = scrambled(w, h, 3000);
        let view = ImageView::contiguous(&raw, w, h, 1).unwrap();
        let pat = CfaPattern::from_name("RGGB").unwrap();
        let mut p = params(60.0, 1.0 / 3800.0, Tone::Srgb);
        p.matrix = CAMERA_MATRIX;
        p.method = Method::Rcd;
        let auto = AutoBright { pixels: w * h };
        let mut linear = vec![0u16; 3 * w * h];
        let plain = DevelopParams {
            tone: Tone::Linear,
            ..p.clone()
        };
        develop_in_place(view, &pat, &plain, &mut linear).unwrap();
        let gain = auto.gain(&Histograms::of(&linear, 3 * w, |s, d| d.copy_from_slice(s)));
        assert!(gain > 1.2, "a dim mosaic is brightened ({gain})");
        let twice = DevelopParams {
            matrix: p.matrix.map(|m| (f64::from(m) * gain) as f32),
            ..p.clone()
        };
        p.auto_bright = Some(auto);
        // Each output type developed with `p` and with `twice`.
        let n = 3 * w * h;
        let mut eight: [_; 2] = std::array::from_fn(|_| vec![0u8; n]);
        let mut sixteen: [_; 2] = std::array::from_fn(|_| vec![0u16; n]);
        let mut float: [_; 2] = std::array::from_fn(|_| vec![0f32; n]);
        for (params, k) in [(&p, 0), (&twice, 1)] {
            develop::<u16, u8>(view, &pat, params, &mut eight[k]).unwrap();
            develop_in_place(view, &pat, params, &mut sixteen[k]).unwrap();
            develop_in_place(view, &pat, params, &mut float[k]).unwrap();
        }
        assert!(eight[0] == eight[1] && sixteen[0] == sixteen[1] && float[0] == float[1]);
    }

    #[test]
    fn a_kept_staging_image_serves_whatever_it_holds_and_a_wrong_one_is_replaced() {
        let (w, h) = (64, 40);
        let raw = scrambled(w, h, 3000);
        let view = ImageView::contiguous(&raw, w, h, 1).unwrap();
        let pat = CfaPattern::from_name("RGGB").unwrap();
        let mut p = params(60.0, 1.0 / 3800.0, Tone::Srgb);
        p.method = Method::Rcd;
        p.auto_bright = Some(AutoBright { pixels: w * h });
        let n = 3 * w * h;
        let mut fresh = vec![0u8; n];
        develop::<u16, u8>(view, &pat, &p, &mut fresh).unwrap();
        let mut kept = vec![0xabcd_u16; n];
        let address = kept.as_ptr();
        let mut got = vec![0u8; n];
        develop_staging::<u16, u8>(view, &pat, &p, &mut kept, &mut got).unwrap();
        assert!(got == fresh && kept.as_ptr() == address);
        let mut short = vec![0u16; 5];
        got.fill(0);
        develop_staging::<u16, u8>(view, &pat, &p, &mut short, &mut got).unwrap();
        assert!(got == fresh && short.len() == n);
    }

    #[test]
    fn a_corrected_development_is_the_correction_of_the_development() {
        // The one-pass methods and one that demosaics a prepared mosaic.
        let (w, h) = (61, 41);
        let raw: Vec<u16> = (0..w * h)
            .map(|i| ((i * 7919) % 4000 + 100) as u16)
            .collect();
        let view = ImageView::contiguous(&raw, w, h, 1).unwrap();
        let pat = CfaPattern::from_name("RGGB").unwrap();
        let mut p = params(100.0, 1.0 / 3000.0, Tone::Srgb);
        let c = lens(w, h, false, true);
        // One corrector for all: from the second call on, its kept grid.
        let corrector = LensCorrector::new(c);
        for method in [Method::Mlri, Method::Bilinear, Method::Nearest] {
            p.method = method;
            let mut plain = vec![0u8; 3 * w * h];
            develop::<u16, u8>(view, &pat, &p, &mut plain).unwrap();
            let mut want = vec![0u8; plain.len()];
            let plain = ImageView::contiguous(&plain, w, h, 3).unwrap();
            c.correct_geometry(&plain, Interpolation::Bilinear, 0.0, false, &mut want)
                .unwrap();
            let mut got = vec![0u8; want.len()];
            let mut working = vec![0u8; want.len()];
            for _ in 0..2 {
                develop_corrected::<u16, u8>(
                    view,
                    &pat,
                    &p,
                    &corrector,
                    (&mut vec![], &mut working),
                    &mut got,
                )
                .unwrap();
                assert!(got == want, "{method:?}");
            }
        }
        let other = LensCorrector::new(lens(w, h + 2, false, true));
        let mut working = vec![0u8; 3 * w * h];
        let mut out = working.clone();
        let err = develop_corrected::<u16, u8>(
            view,
            &pat,
            &p,
            &other,
            (&mut vec![], &mut working),
            &mut out,
        );
        assert!(matches!(err, Err(CoreError::Shape(_))));
        let err = develop_corrected::<u16, u8>(
            view,
            &pat,
            &p,
            &corrector,
            (&mut vec![], &mut working[1..]),
            &mut out,
        );
        assert!(matches!(err, Err(CoreError::Shape(_))));
    }

    #[test]
    fn vignetting_scales_each_photosite_above_black_before_the_clip() {
        // A flat 0.25 grey: every site's own channel comes out as 0.25
        // times the gain at the site (bilinear keeps sampled values); the
        // gain is below 4 here, so nothing clips.
        let (w, h) = (61, 41);
        let raw = vec![1100u16; w * h];
        let view = ImageView::contiguous(&raw, w, h, 1).unwrap();
        let pat = CfaPattern::from_name("GRBG").unwrap();
        let p = params(100.0, 1.0 / 4000.0, Tone::Linear);
        let c = lens(w, h, true, false);
        let mut out = vec![0.0f32; 3 * w * h];
        // Without distortion and TCA the working buffer is not used.
        develop_corrected::<f32, f32>(
            view,
            &pat,
            &p,
            &LensCorrector::new(c),
            (&mut vec![], &mut []),
            &mut out,
        )
        .unwrap();
        for (i, px) in out.chunks_exact(3).enumerate() {
            let (u, v) = (i % w, i / w);
            let want = 0.25 * c.gain(u as f64, v as f64);
            let got = f64::from(px[usize::from(pat.color_at(v, u))]);
            assert!((got - want).abs() < 1e-6, "({u}, {v}): {got} vs {want}");
        }
        assert!(out[0] > 0.3);
    }

    #[test]
    fn bad_parameters_are_refused() {
        let raw = vec![0u16; 16];
        let pat = CfaPattern::from_name("RGGB").unwrap();
        let view = ImageView::contiguous(&raw, 4, 4, 1).unwrap();
        let mut out = vec![0u8; 48];
        let run = |p: &DevelopParams, out: &mut [u8]| develop::<u16, u8>(view, &pat, p, out);
        let mut p = params(0.0, 1.0, Tone::Linear);
        p.scale.pop();
        assert!(matches!(run(&p, &mut out), Err(CoreError::Shape(_))));
        let mut p = params(0.0, 1.0, Tone::Linear);
        p.matrix[4] = f32::NAN;
        let err = run(&p, &mut out).unwrap_err().to_string();
        assert!(err.contains("matrix"), "{err}");
        assert!(run(&params(0.0, -1.0, Tone::Linear), &mut out).is_err());
        assert!(run(&params(0.0, 1.0, Tone::Linear), &mut out[..47]).is_err());
        let mut f = vec![0.0f32; 47];
        assert!(develop_in_place(view, &pat, &params(0.0, 1.0, Tone::Linear), &mut f).is_err());
        assert!(Tone::from_name("gamma")
            .unwrap_err()
            .to_string()
            .contains("srgb"));
    }
}

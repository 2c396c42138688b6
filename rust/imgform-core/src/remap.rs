//! Geometric resampling: every output pixel is read from a (generally
//! fractional) position of the source image.
//!
//! One sampler serves everything that moves pixels: lens undistortion and
//! distortion through a precomputed [`RemapMap`] (built once, reused for every
//! frame of a camera), and lateral chromatic aberration in
//! [`crate::chromatic`], whose per-channel magnification is an affine
//! [`Coords`] computed on the fly.
//!
//! # Sampling
//! - `Bilinear`: the 2x2 neighbourhood, weights `1 - t` and `t` per axis.
//! - `Bicubic`: the 4x4 neighbourhood with Keys' cubic convolution kernel and
//!   `a = -0.5`, the choice that makes it third-order accurate (Keys 1981).
//!   OpenCV's `INTER_CUBIC` uses `a = -0.75`, a slightly sharper kernel, so the
//!   two agree on smooth images but not bit for bit.
//!
//! Both kernels are interpolating: at integer positions the weights are
//! exactly one and zeros, so an identity map returns the image bit for bit.
//!
//! # Borders
//! Like OpenCV's `BORDER_CONSTANT`: a tap outside the source image reads the
//! constant `fill`, so output pixels near the edge of the source blend the
//! image with `fill` in proportion to their taps' weights. A position that is
//! NaN (where a map is undefined) or so far out that no tap touches the image
//! gives `fill` exactly.
//!
//! # Positions and rounding
//! Source positions are stored and computed in fixed point, 1/256 px
//! ([`FRAC_BITS`]). Bilinear u8/u16 samples are computed exactly in integers
//! (the weights are whole 256ths); bicubic and float samples in `f32`.
//! Integer outputs are rounded half up and clamped to their type's range
//! (bicubic overshoots at edges); float outputs are neither rounded nor
//! clamped.
//!
//! # Speed
//! With a dense [`RemapMap`] on x86-64 with AVX2, u8 (1 or 3 channels) and
//! single-channel u16 images are sampled eight output pixels at a time
//! (`remap_avx2.rs`): interior windows without per-tap bounds or fill
//! handling, the same integer (bilinear) or `f32` (bicubic) operations as
//! the scalar path, so the output is bit-identical to it (tested). The
//! per-channel rows of a lens correction (each channel of an RGB image at
//! its own position, `resample_channels`) are sampled bilinearly eight
//! samples at a time for u8, u16 and f32 (`remap_channels_avx2.rs`), again
//! bit-identical. Pixels near the borders, other layouts, other f32 images
//! and the computed positions of [`crate::chromatic`] take the scalar path. Measured on the shared
//! 2-core AMD machine (24 MP, best of 5, `benchmarks/geometry.py` and
//! interleaved runs): u8 RGB bilinear ~1.3-2x faster than `cv2.remap` with
//! fixed-point maps (its fastest path for RGB), u16 bilinear ~1.2-1.5x
//! faster than with float32 maps (its fastest for u16), bicubic ~1.3x (u16)
//! and ~2x (u8 RGB) faster than either. Building a map is still ~4x slower
//! than `cv2.initUndistortRectifyMap` (scalar f64 per pixel).

use std::ops::{Add, Mul, Range};

use crate::distortion::Distortion;
use crate::error::{CoreError, Result};
use crate::image::{ImageView, Sample};
use crate::intrinsics::Intrinsics;
use crate::invalid;
use crate::parallel::{for_each_band, for_each_row, ROWS_PER_TASK};

#[cfg(target_arch = "x86_64")]
#[path = "remap_avx2.rs"]
mod avx2;

#[cfg(target_arch = "x86_64")]
#[path = "remap_channels_avx512.rs"]
mod avx512;

/// How a fractional position is sampled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interpolation {
    Bilinear,
    Bicubic,
}

impl Interpolation {
    /// Parses `"bilinear"` or `"bicubic"`.
    ///
    /// # Errors
    /// [`CoreError::InvalidArgument`] for any other name.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "bilinear" => Ok(Self::Bilinear),
            "bicubic" => Ok(Self::Bicubic),
            _ => Err(invalid!(
                "unknown interpolation {name:?}; accepted: \"bilinear\", \"bicubic\""
            )),
        }
    }
}

/// Keys' cubic convolution parameter; -0.5 reproduces quadratics exactly.
const KEYS_A: f32 = -0.5;

/// Weights of the taps at `floor(x)` and `floor(x) + 1` for `t = x - floor(x)`.
#[inline(always)]
fn bilinear_weights(t: f32) -> [f32; 2] {
    [1.0 - t, t]
}

/// Weights of the taps at `floor(x) - 1 ..= floor(x) + 2` for `t = x - floor(x)`:
/// Keys' kernel evaluated at distances `1 + t, t, 1 - t, 2 - t`. At `t = 0`
/// they are exactly `[0, 1, 0, 0]` in `f32`.
#[inline(always)]
fn keys_weights(t: f32) -> [f32; 4] {
    let a = KEYS_A;
    // |d| <= 1: (a + 2)|d|³ - (a + 3)|d|² + 1;  1 < |d| < 2: a(|d| - 1)(|d| - 2)², rewritten
    // in the distance to the nearer inner tap so both outer weights share one polynomial.
    let near = |d: f32| ((a + 2.0) * d - (a + 3.0)) * d * d + 1.0;
    let far = |s: f32| a * s * (s - 1.0) * (s - 1.0);
    [far(t), near(t), near(1.0 - t), far(1.0 - t)]
}

/// The arithmetic a sample type is interpolated in: `f32` for everything
/// bicubic and for float images; exact integers for bilinear u8/u16.
pub trait Arith<T>:
    Copy + Default + Add<Output = Self> + Mul<Output = Self> + Send + Sync + 'static
{
    /// Weights of the two bilinear taps at fraction `k / 256`.
    fn bilinear(k: usize) -> [Self; 2];
    fn load(t: T) -> Self;
    /// Rounds half up and converts back (see [`Sample::from_f32`] for floats).
    fn store(self) -> T;
    /// [`Arith::store`] of the sample times `gain`, rounded once (the
    /// vignetting gain a lens correction applies while it resamples).
    fn store_scaled(self, gain: f32) -> T;
}

impl<T: Sample> Arith<T> for f32 {
    fn bilinear(k: usize) -> [f32; 2] {
        bilinear_weights(k as f32 / ONE as f32)
    }
    #[inline(always)]
    fn load(t: T) -> f32 {
        t.to_f32()
    }
    #[inline(always)]
    fn store(self) -> T {
        T::from_f32(self)
    }
    #[inline(always)]
    fn store_scaled(self, gain: f32) -> T {
        T::from_f32(self * gain)
    }
}

/// Bilinear weights in 256ths for integer images: the two stages multiply
/// to 2^16, so `65535 * 2^16 + 2^15` (the largest u16 sum plus the rounding
/// half) still fits a `u32`, and a convex combination needs no clamping.
/// Integer products also skip two float conversions per sample.
macro_rules! fixed_point_bilinear {
    ($($t:ty),*) => {$(
        impl Arith<$t> for u32 {
            fn bilinear(k: usize) -> [u32; 2] {
                [(STEPS - k) as u32, k as u32]
            }
            #[inline(always)]
            fn load(t: $t) -> u32 {
                u32::from(t)
            }
            #[inline(always)]
            fn store(self) -> $t {
                ((self + (1 << (2 * FRAC_BITS - 1))) >> (2 * FRAC_BITS)) as $t
            }
            #[inline(always)]
            fn store_scaled(self, gain: f32) -> $t {
                // The weights' 2^16 goes into the gain: a power of two, exact.
                <$t>::from_f32(self as f32 * (gain / (1u32 << (2 * FRAC_BITS)) as f32))
            }
        }
    )*};
}
fixed_point_bilinear!(u8, u16);

/// A sample type the sampler accepts, with the arithmetic its bilinear
/// interpolation runs in.
pub trait Resample: Sample {
    type Bilinear: Arith<Self>;

    /// Samples one output row, all channels, from the dense map row `xy`
    /// with a SIMD kernel, calling `pixel(x, px)` for the pixels it leaves
    /// to the scalar path. `false` (nothing done) when the type, channel
    /// count or CPU has no such kernel.
    fn simd_row(
        _src: &ImageView<Self>,
        _interpolation: Interpolation,
        _xy: &[i32],
        _row: &mut [Self],
        _pixel: &mut dyn FnMut(usize, &mut [Self]),
    ) -> bool {
        false
    }

    /// Samples one row of `resample_channels` bilinearly with a SIMD
    /// kernel: sample `s` of `row` is channel `s % 3` read at
    /// `xy[2s..2s + 2]`, times `gains[s]` when `gains` is not empty.
    /// `sample(s, px)` writes the samples it leaves to the scalar path.
    /// `false` (nothing done) when the type or CPU has no such kernel.
    fn simd_channel_row(
        _src: &ImageView<Self>,
        _rows: (&[i32], &[f32], &mut [Self]),
        _sample: &mut dyn FnMut(usize, &mut [Self]),
    ) -> bool {
        false
    }
}

/// Runs the AVX2 per-channel kernel `$kernel` over an RGB view when the
/// CPU has AVX2, else returns `false`.
macro_rules! avx2_channel_row {
    ($kernel:ident, $src:expr, $rows:expr, $sample:expr) => {{
        #[cfg(target_arch = "x86_64")]
        if $crate::cpu::has_avx2() && $src.channels() == 3 {
            let size = ($src.width(), $src.height());
            // SAFETY: AVX2 is present; the view guarantees that its data
            // holds an RGB image of `size` with rows `stride` apart; the
            // kernel checks the row lengths.
            return unsafe { avx2::$kernel($src.data(), $src.stride(), size, $rows, $sample) };
        }
        let _ = ($src, $rows, $sample);
        false
    }};
}

impl Resample for u8 {
    type Bilinear = u32;

    fn simd_channel_row(
        src: &ImageView<u8>,
        rows: (&[i32], &[f32], &mut [u8]),
        sample: &mut dyn FnMut(usize, &mut [u8]),
    ) -> bool {
        #[cfg(target_arch = "x86_64")]
        if avx512::available() && src.channels() == 3 {
            let size = (src.width(), src.height());
            // SAFETY: the CPU has the kernel's features; the view holds an
            // RGB image of `size` with rows `stride` apart.
            let (xy, gains, row) = rows;
            if unsafe {
                avx512::channel_row_u8(
                    src.data(),
                    src.stride(),
                    size,
                    (xy, gains, &mut *row),
                    sample,
                )
            } {
                return true;
            }
            return avx2_channel_row!(channel_row_u8, src, (xy, gains, row), sample);
        }
        avx2_channel_row!(channel_row_u8, src, rows, sample)
    }

    fn simd_row(
        src: &ImageView<u8>,
        interpolation: Interpolation,
        xy: &[i32],
        row: &mut [u8],
        pixel: &mut dyn FnMut(usize, &mut [u8]),
    ) -> bool {
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::has_avx2() {
            let (data, stride) = (src.data(), src.stride());
            let size = (src.width(), src.height());
            // SAFETY: AVX2 is present; the view guarantees that `data` holds
            // a `size` image with rows `stride` apart; the kernels check the
            // lengths of `xy` and `row`.
            return unsafe {
                match (interpolation, src.channels()) {
                    (Interpolation::Bilinear, 1) => {
                        avx2::row_u8::<1>(data, stride, size, xy, row, pixel)
                    }
                    (Interpolation::Bilinear, 3) => {
                        avx2::row_u8::<3>(data, stride, size, xy, row, pixel)
                    }
                    (Interpolation::Bicubic, 1) => {
                        avx2::cubic_u8::<1>(data, stride, size, xy, row, pixel)
                    }
                    (Interpolation::Bicubic, 3) => {
                        avx2::cubic_u8::<3>(data, stride, size, xy, row, pixel)
                    }
                    _ => false,
                }
            };
        }
        let _ = (src, interpolation, xy, row, pixel);
        false
    }
}
impl Resample for u16 {
    type Bilinear = u32;

    fn simd_channel_row(
        src: &ImageView<u16>,
        rows: (&[i32], &[f32], &mut [u16]),
        sample: &mut dyn FnMut(usize, &mut [u16]),
    ) -> bool {
        avx2_channel_row!(channel_row_u16, src, rows, sample)
    }

    fn simd_row(
        src: &ImageView<u16>,
        interpolation: Interpolation,
        xy: &[i32],
        row: &mut [u16],
        pixel: &mut dyn FnMut(usize, &mut [u16]),
    ) -> bool {
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::has_avx2() && src.channels() == 1 {
            let (data, stride) = (src.data(), src.stride());
            let size = (src.width(), src.height());
            // SAFETY: as for u8.
            return unsafe {
                match interpolation {
                    Interpolation::Bilinear => avx2::row_u16(data, stride, size, xy, row, pixel),
                    Interpolation::Bicubic => avx2::cubic_u16(data, stride, size, xy, row, pixel),
                }
            };
        }
        let _ = (src, interpolation, xy, row, pixel);
        false
    }
}
impl Resample for f32 {
    type Bilinear = f32;

    fn simd_channel_row(
        src: &ImageView<f32>,
        rows: (&[i32], &[f32], &mut [f32]),
        sample: &mut dyn FnMut(usize, &mut [f32]),
    ) -> bool {
        avx2_channel_row!(channel_row_f32, src, rows, sample)
    }
}

/// Fractional bits of a stored position: 1/256 px. Finer than OpenCV's
/// 1/32 px fixed-point maps; the rounding error (<= 1/512 px) moves a u8 edge
/// of full contrast by at most half a grey level.
pub const FRAC_BITS: u32 = 8;
const ONE: f64 = (1 << FRAC_BITS) as f64;
/// Weight tables have one entry per representable fraction.
const STEPS: usize = 1 << FRAC_BITS;
const FRAC_MASK: i32 = (1 << FRAC_BITS) - 1;

/// Positions are clamped to ±2^22 px so they fit an `i32` with [`FRAC_BITS`]
/// fractional bits; images are limited to that size per side.
pub const MAX_SIDE: usize = 1 << 22;

/// The stored form of "no source" (a NaN position).
const NOWHERE: i32 = i32::MIN;

/// A position in pixels to fixed point, rounded half up; NaN to [`NOWHERE`].
#[inline(always)]
pub(crate) fn to_fixed(v: f64) -> i32 {
    if v.is_nan() {
        return NOWHERE;
    }
    // Shifted positive so that truncation is floor (`f64::floor` is a libm
    // call on baseline x86-64); the clamp keeps infinities in range too.
    let limit = MAX_SIDE as f64;
    let shifted = (v.clamp(-limit, limit) + limit) * ONE + 0.5;
    (shifted as i64 - (MAX_SIDE as i64) * (STEPS as i64)) as i32
}

/// A fixed-point position back to pixels (NaN for [`NOWHERE`]).
fn from_fixed(v: i32) -> f32 {
    if v == NOWHERE {
        f32::NAN
    } else {
        (f64::from(v) / ONE) as f32
    }
}

/// Source positions of output pixels, in fixed point with [`FRAC_BITS`]
/// fractional bits (see [`RemapMap`]).
pub trait Coords: Sync {
    /// Where output pixel `(x, y)` is read from; `x == i32::MIN` for nowhere.
    fn at(&self, x: usize, y: usize) -> (i32, i32);

    /// The interleaved positions of output row `y`, for sources that store
    /// them (SIMD kernels read them in blocks); `None` for computed ones.
    fn row(&self, _y: usize) -> Option<&[i32]> {
        None
    }
}

/// A dense map of source positions, one `(x, y)` pair per output pixel.
///
/// Built once per camera and image size, it makes every further frame a pure
/// resampling pass: the lens model is never evaluated again. Positions are
/// stored interleaved (one output row reads one contiguous run) as `i32` in
/// fixed point with [`FRAC_BITS`] fractional bits: the same 8 bytes per pixel
/// as two `f32` planes, but each frame then splits a position into its tap
/// index and weight-table entry with a shift and a mask instead of float
/// rounding and conversion.
#[derive(Debug, Clone, PartialEq)]
pub struct RemapMap {
    width: usize,
    height: usize,
    xy: Vec<i32>,
}

impl RemapMap {
    /// A map for a `height x width` output from `(x, y)` positions in
    /// pixels, interleaved; NaN marks pixels without a source.
    ///
    /// # Errors
    /// [`CoreError::Shape`] when the size is zero or `xy` does not hold
    /// `2 * width * height` values.
    pub fn from_interleaved(xy: &[f32], width: usize, height: usize) -> Result<Self> {
        check_size(width, height)?;
        if xy.len() != 2 * width * height {
            return Err(CoreError::Shape(format!(
                "a {height}x{width} map needs {} interleaved coordinates, got {}",
                2 * width * height,
                xy.len()
            )));
        }
        Self::from_fn(width, height, |u, v| {
            let i = 2 * (v * width + u);
            (f64::from(xy[i]), f64::from(xy[i + 1]))
        })
    }

    /// Joins separate `map_x` and `map_y` planes (OpenCV's float layout).
    ///
    /// # Errors
    /// [`CoreError::Shape`] when the size is zero or a plane's length is not
    /// `width * height`.
    pub fn from_planes(map_x: &[f32], map_y: &[f32], width: usize, height: usize) -> Result<Self> {
        check_size(width, height)?;
        let n = width * height;
        if map_x.len() != n || map_y.len() != n {
            return Err(CoreError::Shape(format!(
                "map_x and map_y must both hold {n} values for a {height}x{width} map, got {} and {}",
                map_x.len(),
                map_y.len()
            )));
        }
        Self::from_fn(width, height, |u, v| {
            let i = v * width + u;
            (f64::from(map_x[i]), f64::from(map_y[i]))
        })
    }

    /// The map that undistorts: output pixel `(u, v)` is an ideal pinhole
    /// pixel of intrinsics `new_k`; its source is where the lens `dist` with
    /// intrinsics `k` puts that ray in the distorted image. The same map as
    /// `cv2.initUndistortRectifyMap(K, dist, None, new_K, ...)`. NaN where
    /// the model has no distorted image of the ray.
    ///
    /// # Errors
    /// [`CoreError::Shape`] for a zero size.
    pub fn undistort(
        k: &Intrinsics,
        dist: &Distortion,
        new_k: &Intrinsics,
        width: usize,
        height: usize,
    ) -> Result<Self> {
        let normalize = normalizer(new_k);
        Self::from_fn(width, height, |u, v| {
            let (x, y) = normalize(u as f64, v as f64);
            dist.distort(x, y)
                .map_or((f64::NAN, f64::NAN), |(xd, yd)| k.to_pixel(xd, yd))
        })
    }

    /// The map that distorts: output pixel `(u, v)` is a distorted pixel of
    /// the lens `dist` with intrinsics `k`; its source is the ideal pinhole
    /// pixel (intrinsics `new_k`) of the same ray. NaN where the inverse does
    /// not exist (beyond the fold of the model).
    ///
    /// # Errors
    /// [`CoreError::Shape`] for a zero size.
    pub fn distort(
        k: &Intrinsics,
        dist: &Distortion,
        new_k: &Intrinsics,
        width: usize,
        height: usize,
    ) -> Result<Self> {
        let normalize = normalizer(k);
        Self::from_fn(width, height, |u, v| {
            let (xd, yd) = normalize(u as f64, v as f64);
            dist.undistort(xd, yd)
                .map_or((f64::NAN, f64::NAN), |(x, y)| new_k.to_pixel(x, y))
        })
    }

    /// Evaluates `source(u, v)` (in pixels, NaN for none) for every output
    /// pixel, in parallel over rows.
    fn from_fn<F>(width: usize, height: usize, source: F) -> Result<Self>
    where
        F: Fn(usize, usize) -> (f64, f64) + Sync,
    {
        check_size(width, height)?;
        let too_large = || {
            CoreError::Memory(format!(
                "a {height}x{width} map needs 8 bytes a pixel, more memory than can be allocated"
            ))
        };
        let len = width
            .checked_mul(height)
            .and_then(|n| n.checked_mul(2))
            .ok_or_else(too_large)?;
        let mut xy: Vec<i32> = Vec::new();
        xy.try_reserve_exact(len).map_err(|_| too_large())?;
        for_each_row(&mut xy.spare_capacity_mut()[..len], 2 * width, |v, row| {
            for (u, out) in row.chunks_exact_mut(2).enumerate() {
                let (x, y) = source(u, v);
                let (fx, fy) = (to_fixed(x), to_fixed(y));
                // One NaN coordinate leaves the pixel without a source.
                let none = fx == NOWHERE || fy == NOWHERE;
                out[0].write(if none { NOWHERE } else { fx });
                out[1].write(fy);
            }
        });
        // SAFETY: the rows above wrote every one of the `len` values.
        unsafe { xy.set_len(len) };
        Ok(Self { width, height, xy })
    }

    pub fn width(&self) -> usize {
        self.width
    }
    pub fn height(&self) -> usize {
        self.height
    }

    /// The positions as OpenCV's two float planes `(map_x, map_y)`, each
    /// `height * width` long, NaN where there is no source. Values are the
    /// stored ones, i.e. rounded to 1/256 px.
    pub fn planes(&self) -> (Vec<f32>, Vec<f32>) {
        self.xy
            .chunks_exact(2)
            .map(|p| {
                if p[0] == NOWHERE {
                    (f32::NAN, f32::NAN)
                } else {
                    (from_fixed(p[0]), from_fixed(p[1]))
                }
            })
            .unzip()
    }
}

impl Coords for RemapMap {
    #[inline(always)]
    fn at(&self, x: usize, y: usize) -> (i32, i32) {
        let i = 2 * (y * self.width + x);
        (self.xy[i], self.xy[i + 1])
    }

    fn row(&self, y: usize) -> Option<&[i32]> {
        Some(&self.xy[2 * y * self.width..2 * (y + 1) * self.width])
    }
}

/// [`Intrinsics::to_normalized`] with the divisions replaced by products
/// with reciprocals: a map evaluates it for every pixel, and two divisions
/// were a large share of the per-pixel cost. The results differ by an ulp
/// or so, far below the 1/256 px a map stores.
fn normalizer(k: &Intrinsics) -> impl Fn(f64, f64) -> (f64, f64) + Sync + '_ {
    let (inv_fx, inv_fy) = (1.0 / k.fx, 1.0 / k.fy);
    move |u, v| {
        let y = (v - k.cy) * inv_fy;
        ((u - k.cx - k.skew * y) * inv_fx, y)
    }
}

fn check_size(width: usize, height: usize) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(CoreError::Shape(format!(
            "map size must be non-empty, got height {height}, width {width}"
        )));
    }
    Ok(())
}

/// Checks that `fill` is finite and representable in `T` (an integer image
/// cannot hold 0.5 or 300 as u8), and returns it as the sampler's `f32`.
///
/// # Errors
/// [`CoreError::InvalidArgument`] naming the value.
pub fn check_fill<T: Sample>(fill: f64) -> Result<f32> {
    let f = fill as f32;
    if f.is_finite() && T::from_f32(f).to_f32() == f {
        Ok(f)
    } else {
        Err(invalid!(
            "fill must be a finite value the image's sample type {} holds exactly, got {fill}",
            std::any::type_name::<T>()
        ))
    }
}

/// Remaps `src` through `map` into `out`, a contiguous `map.height() x
/// map.width()` image with the source's channel count.
///
/// # Errors
/// `fill` not representable in `T` (see [`check_fill`]) or `out` of the
/// wrong length.
pub fn remap<T: Resample>(
    src: &ImageView<T>,
    map: &RemapMap,
    interpolation: Interpolation,
    fill: f64,
    out: &mut [T],
) -> Result<()> {
    let fill = check_fill::<T>(fill)?;
    let channels = 0..src.channels();
    resample(
        src,
        map,
        map.width,
        map.height,
        channels,
        interpolation,
        fill,
        out,
    )
}

/// Resamples channels `channels` of `src` at the positions `coords` gives for
/// a `width x height` output, writing the same channels of `out` (which has
/// the source's channel count) and leaving its other channels untouched.
///
/// # Errors
/// [`CoreError::Shape`] when `out` is not `width * height * channels` long or
/// the channel range is outside the image.
#[allow(clippy::too_many_arguments)]
pub(crate) fn resample<T: Resample, S: Coords>(
    src: &ImageView<T>,
    coords: &S,
    width: usize,
    height: usize,
    channels: Range<usize>,
    interpolation: Interpolation,
    fill: f32,
    out: &mut [T],
) -> Result<()> {
    let row_len = width * src.channels();
    if out.len() != row_len * height {
        return Err(CoreError::Shape(format!(
            "output must hold {height}x{width}x{} samples, got {}",
            src.channels(),
            out.len()
        )));
    }
    if channels.is_empty() || channels.end > src.channels() {
        return Err(CoreError::Shape(format!(
            "channels {channels:?} are not within the image's {} channels",
            src.channels()
        )));
    }
    if src.width() > MAX_SIDE || src.height() > MAX_SIDE {
        return Err(CoreError::Shape(format!(
            "images are limited to {MAX_SIDE} pixels per side, got {}x{}",
            src.height(),
            src.width()
        )));
    }
    let job = Job {
        src,
        coords,
        channels,
        fill,
    };
    match interpolation {
        Interpolation::Bilinear => job.run::<2, T::Bilinear>(
            out,
            row_len,
            &std::array::from_fn(<T::Bilinear as Arith<T>>::bilinear),
        ),
        // k / 256 is exact in f32, so entry 0 is exactly the identity's weights.
        Interpolation::Bicubic => job.run::<4, f32>(
            out,
            row_len,
            &std::array::from_fn(|k| keys_weights(k as f32 / ONE as f32)),
        ),
    }
    Ok(())
}

/// One resampling pass: the source, where to read it and which channels.
struct Job<'a, T, S> {
    src: &'a ImageView<'a, T>,
    coords: &'a S,
    channels: Range<usize>,
    fill: f32,
}

impl<T: Resample, S: Coords> Job<'_, T, S> {
    /// Samples with weights `table` (one entry per representable fraction)
    /// in arithmetic `V`, through a loop specialised for the channel layout,
    /// so the common ones (1, 3 or 4 channels remapped together; one of 3 for
    /// chromatic aberration) get fully unrolled inner loops.
    fn run<const TAPS: usize, V: Arith<T>>(
        &self,
        out: &mut [T],
        row_len: usize,
        table: &[[V; TAPS]; STEPS],
    ) {
        let c0 = self.channels.start;
        match (self.src.channels(), self.channels.len()) {
            (1, 1) => self.rows::<TAPS, 1, 1, V>(out, row_len, table, c0),
            (3, 3) => self.rows::<TAPS, 3, 3, V>(out, row_len, table, c0),
            (4, 4) => self.rows::<TAPS, 4, 4, V>(out, row_len, table, c0),
            (3, 1) => self.rows::<TAPS, 3, 1, V>(out, row_len, table, c0),
            // Other layouts: one channel per pass.
            _ => {
                for c in self.channels.clone() {
                    self.rows::<TAPS, 0, 1, V>(out, row_len, table, c);
                }
            }
        }
    }

    /// All output rows in parallel, sampling channels `c0..c0 + N`. `NC` is
    /// the image's channel count, 0 for "read it at run time".
    fn rows<const TAPS: usize, const NC: usize, const N: usize, V: Arith<T>>(
        &self,
        out: &mut [T],
        row_len: usize,
        table: &[[V; TAPS]; STEPS],
        c0: usize,
    ) {
        let nc = if NC > 0 { NC } else { self.src.channels() };
        let interpolation = if TAPS == 2 {
            Interpolation::Bilinear
        } else {
            Interpolation::Bicubic
        };
        let taps = Taps::<T, V, TAPS, NC>::new(self.src, table, self.fill);
        for_each_row(out, row_len, |y, row| {
            let mut pixel = |x: usize, px: &mut [T]| {
                let (sx, sy) = self.coords.at(x, y);
                taps.sample::<N>(sx, sy, c0, &mut px[c0..c0 + N]);
            };
            // Whole pixels only: the kernels write every channel.
            if N == nc {
                if let Some(xy) = self.coords.row(y) {
                    if T::simd_row(self.src, interpolation, xy, row, &mut pixel) {
                        return;
                    }
                }
            }
            for (x, px) in row.chunks_exact_mut(nc).enumerate() {
                pixel(x, px);
            }
        });
    }
}

/// The sampler of one source with one weight table: reads the taps around a
/// fixed-point position, shared by the per-pixel and per-channel passes so
/// that both compute the same bits. `NC` is the image's channel count, 0 for
/// "read it at run time".
struct Taps<'a, T, V, const TAPS: usize, const NC: usize> {
    src: &'a ImageView<'a, T>,
    table: &'a [[V; TAPS]; STEPS],
    fill: T,
    fill_v: V,
    // Both fit i32: sides are at most MAX_SIDE.
    w: i32,
    h: i32,
}

impl<'a, T: Resample, V: Arith<T>, const TAPS: usize, const NC: usize> Taps<'a, T, V, TAPS, NC> {
    fn new(src: &'a ImageView<'a, T>, table: &'a [[V; TAPS]; STEPS], fill: f32) -> Self {
        let fill = T::from_f32(fill);
        Self {
            src,
            table,
            fill,
            fill_v: V::load(fill),
            w: src.width() as i32,
            h: src.height() as i32,
        }
    }

    /// Writes channels `c0..c0 + N` of the source sampled at `(sx, sy)`
    /// (fixed point) into `px` (`N` long).
    #[inline(always)]
    fn sample<const N: usize>(&self, sx: i32, sy: i32, c0: usize, px: &mut [T]) {
        match self.value::<N>(sx, sy, c0) {
            Some(value) => {
                for (p, v) in px.iter_mut().zip(value) {
                    *p = v.store();
                }
            }
            None => px.fill(self.fill),
        }
    }

    /// Channels `c0..c0 + N` of the source at `(sx, sy)` (fixed point) in
    /// the arithmetic `V`, before rounding; `None` where no tap touches the
    /// image (the output is `fill` there).
    #[inline(always)]
    fn value<const N: usize>(&self, sx: i32, sy: i32, c0: usize) -> Option<[V; N]> {
        let nc = if NC > 0 { NC } else { self.src.channels() };
        let (w, h) = (self.w, self.h);
        let taps = TAPS as i32;
        // Offset of the first tap from floor(position): 0 for 2 taps, -1 for 4.
        let lead = taps / 2 - 1;
        // The arithmetic shift is floor; NOWHERE lands far outside.
        let (ix, iy) = ((sx >> FRAC_BITS) - lead, (sy >> FRAC_BITS) - lead);
        if ix <= -taps || iy <= -taps || ix >= w || iy >= h {
            return None;
        }
        let wx = &self.table[(sx & FRAC_MASK) as usize];
        let wy = &self.table[(sy & FRAC_MASK) as usize];
        let value = if ix >= 0 && iy >= 0 && ix + taps <= w && iy + taps <= h {
            // Windows of exactly the samples the taps read, so that the
            // tap indices below are provably in bounds and unchecked.
            let start = ix as usize * nc + c0;
            let len = (TAPS - 1) * nc + N;
            let rows: [&[T]; TAPS] =
                std::array::from_fn(|j| &self.src.row(iy as usize + j)[start..start + len]);
            convolve::<TAPS, N, V>(wx, wy, |i, j| {
                std::array::from_fn(|c| V::load(rows[j][i * nc + c]))
            })
        } else {
            convolve::<TAPS, N, V>(wx, wy, |i, j| {
                let (tx, ty) = (ix + i as i32, iy + j as i32);
                std::array::from_fn(|c| {
                    if tx >= 0 && ty >= 0 && tx < w && ty < h {
                        V::load(self.src.at(tx as usize, ty as usize, c0 + c))
                    } else {
                        self.fill_v
                    }
                })
            })
        };
        Some(value)
    }
}

/// Per-channel source positions computed a row at a time: lateral chromatic
/// aberration reads each channel of an RGB image from its own place, and a
/// row of positions computed at once (from a coarse grid, say) costs far
/// less than each position on its own.
pub(crate) trait ChannelRows: Sync {
    /// Working memory of [`ChannelRows::fill_row`], made once per band of
    /// rows so that no row allocates.
    type Scratch: Default;

    /// Writes the positions of output row `y` into `xy`: per pixel, the
    /// fixed-point `(x, y)` of R, G and B in turn (`6 * width` values), and,
    /// when `gains` is not empty, a gain per sample into it (`3 * width`
    /// values) that the sampled values are multiplied by.
    fn fill_row(&self, y: usize, scratch: &mut Self::Scratch, xy: &mut [i32], gains: &mut [f32]);

    /// Whether [`ChannelRows::fill_row`] has gains to give.
    fn has_gains(&self) -> bool;
}

/// Resamples an RGB image whose channels are read from different places
/// (`coords`) into `out`, a contiguous image of the source's size, in one
/// pass: every source row band is visited once for all three channels.
///
/// # Errors
/// [`CoreError::Shape`] when `src` does not have 3 channels, is too large,
/// or `out` is not its size.
pub(crate) fn resample_channels<T: Resample, S: ChannelRows>(
    src: &ImageView<T>,
    coords: &S,
    interpolation: Interpolation,
    fill: f32,
    out: &mut [T],
) -> Result<()> {
    let (width, height) = (src.width(), src.height());
    if src.channels() != 3 || out.len() != width * height * 3 {
        return Err(CoreError::Shape(format!(
            "per-channel resampling needs an RGB image and an output of its size, got {}x{}x{} and {} samples",
            height,
            width,
            src.channels(),
            out.len()
        )));
    }
    if width > MAX_SIDE || height > MAX_SIDE {
        return Err(CoreError::Shape(format!(
            "images are limited to {MAX_SIDE} pixels per side, got {height}x{width}"
        )));
    }
    match interpolation {
        Interpolation::Bilinear => channel_rows(
            &Taps::<T, T::Bilinear, 2, 3>::new(
                src,
                &std::array::from_fn(<T::Bilinear as Arith<T>>::bilinear),
                fill,
            ),
            coords,
            out,
        ),
        Interpolation::Bicubic => channel_rows(
            &Taps::<T, f32, 4, 3>::new(
                src,
                &std::array::from_fn(|k| keys_weights(k as f32 / ONE as f32)),
                fill,
            ),
            coords,
            out,
        ),
    }
    Ok(())
}

/// [`resample_channels`]' loop: bands of rows in parallel, each filling one
/// row of positions at a time into buffers made once per band. Bilinear
/// rows go to the SIMD kernel where there is one.
fn channel_rows<T: Resample, V: Arith<T>, const TAPS: usize, S: ChannelRows>(
    taps: &Taps<T, V, TAPS, 3>,
    coords: &S,
    out: &mut [T],
) {
    let row_len = 3 * taps.src.width();
    let gained = coords.has_gains();
    for_each_band(out, row_len, ROWS_PER_TASK, |y0, band| {
        let mut scratch = S::Scratch::default();
        let mut xy = vec![0i32; 2 * row_len];
        let mut gains = vec![0f32; if gained { row_len } else { 0 }];
        for (i, row) in band.chunks_exact_mut(row_len).enumerate() {
            coords.fill_row(y0 + i, &mut scratch, &mut xy, &mut gains);
            let mut scalar = |s: usize, px: &mut [T]| px[0] = channel_sample(taps, &xy, &gains, s);
            if TAPS == 2 && T::simd_channel_row(taps.src, (&xy, &gains, row), &mut scalar) {
                continue;
            }
            for (s, o) in row.iter_mut().enumerate() {
                *o = channel_sample(taps, &xy, &gains, s);
            }
        }
    });
}

/// Sample `s` of a [`channel_rows`] row: channel `s % 3` read at its own
/// position, times its gain if there are gains, rounded once.
#[inline(always)]
fn channel_sample<T: Resample, V: Arith<T>, const TAPS: usize>(
    taps: &Taps<T, V, TAPS, 3>,
    xy: &[i32],
    gains: &[f32],
    s: usize,
) -> T {
    match taps.value::<1>(xy[2 * s], xy[2 * s + 1], s % 3) {
        Some([v]) if gains.is_empty() => v.store(),
        Some([v]) => v.store_scaled(gains[s]),
        None => taps.fill,
    }
}

/// `Σ_j wy[j] Σ_i wx[i] tap(i, j)` for `N` channels at once: the separable
/// tensor-product sample. Channels are the innermost loop so that their
/// arithmetic maps onto one SIMD register.
#[inline(always)]
fn convolve<const TAPS: usize, const N: usize, V>(
    wx: &[V; TAPS],
    wy: &[V; TAPS],
    tap: impl Fn(usize, usize) -> [V; N],
) -> [V; N]
where
    V: Copy + Default + Add<Output = V> + Mul<Output = V>,
{
    let mut acc = [V::default(); N];
    for (j, &b) in wy.iter().enumerate() {
        let mut line = [V::default(); N];
        for (i, &a) in wx.iter().enumerate() {
            for (l, v) in line.iter_mut().zip(tap(i, j)) {
                *l = *l + a * v;
            }
        }
        for (s, l) in acc.iter_mut().zip(line) {
            *s = *s + b * l;
        }
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize, c: usize) -> Vec<u16> {
        (0..w * h * c).map(|i| (i * 37 % 65536) as u16).collect()
    }

    fn identity(w: usize, h: usize) -> RemapMap {
        RemapMap::from_interleaved(
            &(0..h)
                .flat_map(|y| (0..w).flat_map(move |x| [x as f32, y as f32]))
                .collect::<Vec<f32>>(),
            w,
            h,
        )
        .unwrap()
    }

    #[test]
    fn identity_map_is_bit_exact_for_both_kernels() {
        for c in [1, 2, 3, 4, 5] {
            let img = ramp(13, 7, c);
            let view = ImageView::contiguous(&img, 13, 7, c).unwrap();
            for interp in [Interpolation::Bilinear, Interpolation::Bicubic] {
                let mut out = vec![0u16; img.len()];
                remap(&view, &identity(13, 7), interp, 0.0, &mut out).unwrap();
                assert_eq!(out, img, "{interp:?}, {c} channels");
            }
        }
    }

    /// A dense map seen only through [`Coords::at`], which keeps the
    /// sampler on its scalar path: the oracle for the SIMD rows.
    struct Scalar<'a>(&'a RemapMap);

    impl Coords for Scalar<'_> {
        fn at(&self, x: usize, y: usize) -> (i32, i32) {
            self.0.at(x, y)
        }
    }

    /// Both paths over a map that mixes interior windows (all fractions),
    /// borders, far-away and NaN positions, for every kernel layout.
    fn assert_simd_matches_scalar<T: Resample>(view: &ImageView<T>, interp: Interpolation) {
        let (w, h, c) = (view.width(), view.height(), view.channels());
        let (mw, mh) = (37, 9);
        let mut state = 12345u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        // Rows 0, 3, 6: anywhere; the others such that the whole window is
        // inside the image, so that entire 8-pixel steps take the vector path.
        let (lead, span) = match interp {
            Interpolation::Bilinear => (0.0, 1.0),
            Interpolation::Bicubic => (1.0, 3.0),
        };
        let xy: Vec<f32> = (0..mw * mh)
            .flat_map(|i| {
                let anywhere = i / mw % 3 == 0;
                let (x, y) = if anywhere {
                    (
                        next() * (w as f32 + 4.0) - 2.0,
                        next() * (h as f32 + 4.0) - 2.0,
                    )
                } else {
                    (
                        lead + next() * (w as f32 - span),
                        lead + next() * (h as f32 - span),
                    )
                };
                match i % 29 {
                    0 if anywhere => [f32::NAN, y],
                    1 if anywhere => [x, 1e9],
                    // Exact integers: fraction zero, weight 256.
                    2 => [x.floor(), y.floor()],
                    _ => [x, y],
                }
            })
            .collect();
        let map = RemapMap::from_interleaved(&xy, mw, mh).unwrap();
        let mut fast = vec![T::default(); mw * mh * c];
        let mut slow = fast.clone();
        remap(view, &map, interp, 7.0, &mut fast).unwrap();
        let fill = check_fill::<T>(7.0).unwrap();
        resample(view, &Scalar(&map), mw, mh, 0..c, interp, fill, &mut slow).unwrap();
        assert_eq!(fast, slow, "{interp:?}, {c} channels");
    }

    /// `n` u8 samples of every value.
    fn u8_samples(n: usize) -> Vec<u8> {
        (0..n).map(|i| (i * 97 % 256) as u8).collect()
    }

    /// `n` u16 samples, every third the largest: extreme values exercise
    /// the wrap-around in the 32-bit sums.
    fn u16_samples(n: usize) -> Vec<u16> {
        (0..n)
            .map(|i| {
                if i % 3 == 0 {
                    65535
                } else {
                    (i * 7919 % 65536) as u16
                }
            })
            .collect()
    }

    #[test]
    fn simd_rows_match_the_scalar_path_bit_for_bit() {
        for (w, h, interp) in [
            (16, 12, Interpolation::Bilinear),
            (3, 2, Interpolation::Bilinear),
            (40, 5, Interpolation::Bilinear),
            (16, 12, Interpolation::Bicubic),
            (5, 4, Interpolation::Bicubic),
            (40, 7, Interpolation::Bicubic),
        ] {
            for c in [1, 3, 4] {
                // Contiguous, and with 5 samples of padding after each row.
                for stride in [w * c, w * c + 5] {
                    let n = (h - 1) * stride + w * c;
                    let u8s = u8_samples(n);
                    let view = ImageView::new(&u8s, w, h, c, stride).unwrap();
                    assert_simd_matches_scalar(&view, interp);
                    let u16s = u16_samples(n);
                    let view = ImageView::new(&u16s, w, h, c, stride).unwrap();
                    assert_simd_matches_scalar(&view, interp);
                }
            }
        }
    }

    #[test]
    fn keys_weights_sum_to_one_and_match_the_kernel() {
        for k in 0..=16 {
            let t = k as f32 / 16.0;
            let w = keys_weights(t);
            assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
            // Hand value at t = 0.5: near(0.5) = 1.5/8 - 2.5/4 + 1 = 0.5625, far = -0.0625.
            if k == 8 {
                assert_eq!(w, [-0.0625, 0.5625, 0.5625, -0.0625]);
            }
        }
        assert_eq!(keys_weights(0.0), [0.0, 1.0, 0.0, 0.0]);
    }

    #[test]
    fn bilinear_half_pixel_shift_averages_and_edges_blend_with_fill() {
        let img = [10u8, 20, 30];
        let view = ImageView::contiguous(&img, 3, 1, 1).unwrap();
        let map = RemapMap::from_interleaved(
            &[0.5, 0.0, 2.5, 0.0, -0.5, 0.0, f32::NAN, 0.0, 1e30, 0.0],
            5,
            1,
        )
        .unwrap();
        let mut out = [0u8; 5];
        remap(&view, &map, Interpolation::Bilinear, 100.0, &mut out).unwrap();
        // (10 + 20) / 2; (30 + fill) / 2; (fill + 10) / 2; NaN and far away: fill.
        assert_eq!(out, [15, 65, 55, 100, 100]);
    }

    #[test]
    fn bicubic_reproduces_a_quadratic_and_clamps_overshoot() {
        // Keys a = -0.5 is exact on quadratics away from the border.
        let img: Vec<f32> = (0..12).map(|x| (x * x) as f32).collect();
        let view = ImageView::contiguous(&img, 12, 1, 1).unwrap();
        let map = RemapMap::from_interleaved(&[5.25, 0.0], 1, 1).unwrap();
        let mut out = [0f32; 1];
        remap(&view, &map, Interpolation::Bicubic, 0.0, &mut out).unwrap();
        assert!((out[0] - 5.25 * 5.25).abs() < 1e-4, "{}", out[0]);
        // A step 0 -> 255 overshoots past 255 just after the edge; u8 clamps it.
        let step = [0u8, 0, 0, 255, 255, 255, 255];
        let view = ImageView::contiguous(&step, 7, 1, 1).unwrap();
        let map = RemapMap::from_interleaved(&[3.25, 0.0, 2.75, 0.0], 2, 1).unwrap();
        let mut out = [0u8; 2];
        remap(&view, &map, Interpolation::Bicubic, 0.0, &mut out).unwrap();
        assert_eq!(out[0], 255);
        let mut outf = [0f32; 2];
        let stepf: Vec<f32> = step.iter().map(|&v| f32::from(v)).collect();
        let view = ImageView::contiguous(&stepf, 7, 1, 1).unwrap();
        remap(&view, &map, Interpolation::Bicubic, 0.0, &mut outf).unwrap();
        assert!(outf[0] > 255.0, "floats are not clamped: {}", outf[0]);
    }

    #[test]
    fn undistort_and_distort_maps_are_inverse() {
        let k =
            Intrinsics::from_matrix(&[80.0, 0.0, 31.5, 0.0, 80.0, 23.5, 0.0, 0.0, 1.0]).unwrap();
        let dist = Distortion::new("brown_conrady", &[-0.2, 0.05, 1e-3, -1e-3]).unwrap();
        let und = RemapMap::undistort(&k, &dist, &k, 64, 48).unwrap();
        let dis = RemapMap::distort(&k, &dist, &k, 64, 48).unwrap();
        // distort map at the undistort map's source lands back on the output pixel.
        let ((ux, uy), (dx, dy)) = (und.planes(), dis.planes());
        let i = 7 * 64 + 10;
        let j = uy[i].round() as usize * 64 + ux[i].round() as usize;
        assert!((dx[j] - 10.0).abs() < 1.0 && (dy[j] - 7.0).abs() < 1.0);
        let c = 23 * 64 + 31;
        assert!((ux[c] - 31.0).abs() < 0.01 && (uy[c] - 23.0).abs() < 0.01);
    }

    #[test]
    fn fixed_point_rounds_half_up_and_keeps_nan() {
        assert_eq!(to_fixed(1.5), 384);
        assert_eq!(to_fixed(-0.5 / 256.0), 0);
        assert_eq!(to_fixed(-1.0 / 256.0), -1);
        assert_eq!(to_fixed(f64::NAN), NOWHERE);
        assert_eq!(to_fixed(f64::INFINITY), (MAX_SIDE * STEPS) as i32);
        assert!(from_fixed(NOWHERE).is_nan());
        assert_eq!(from_fixed(-384), -1.5);
    }

    #[test]
    fn bad_arguments_are_refused() {
        assert!(Interpolation::from_name("nearest").is_err());
        assert!(RemapMap::from_interleaved(&[0.0; 5], 2, 1).is_err());
        assert!(RemapMap::from_planes(&[0.0; 2], &[0.0; 3], 2, 1).is_err());
        assert!(check_fill::<u8>(0.5).is_err());
        assert!(check_fill::<u8>(256.0).is_err());
        assert!(check_fill::<f32>(f64::NAN).is_err());
        assert_eq!(check_fill::<f32>(-2.5).unwrap(), -2.5);
        let img = [0u8; 4];
        let view = ImageView::contiguous(&img, 2, 2, 1).unwrap();
        let mut out = [0u8; 3];
        let err = remap(
            &view,
            &identity(2, 2),
            Interpolation::Bilinear,
            0.0,
            &mut out,
        );
        assert!(matches!(err, Err(CoreError::Shape(_))));
    }

    /// Per-sample positions and gains given whole, as a [`ChannelRows`].
    struct Scattered {
        width: usize,
        xy: Vec<i32>,
        gains: Vec<f32>,
    }

    impl ChannelRows for Scattered {
        type Scratch = ();

        fn fill_row(&self, y: usize, _: &mut (), xy: &mut [i32], gains: &mut [f32]) {
            xy.copy_from_slice(&self.xy[6 * self.width * y..][..6 * self.width]);
            if !gains.is_empty() {
                gains.copy_from_slice(&self.gains[3 * self.width * y..][..3 * self.width]);
            }
        }

        fn has_gains(&self) -> bool {
            !self.gains.is_empty()
        }
    }

    /// [`resample_channels`] (the SIMD rows where the CPU has them) against
    /// [`channel_sample`] called for every sample (the scalar path), over
    /// positions inside, across the borders, far outside and NaN, and
    /// smooth rows of them, with and without gains (including saturating
    /// and zero ones).
    fn assert_channel_rows_match_the_scalar_path<T: Resample>(view: &ImageView<T>) {
        let (w, h) = (view.width(), view.height());
        let (xy, gains) = channel_positions(w, h);
        let fill = check_fill::<T>(7.0).unwrap();
        let table = std::array::from_fn(<T::Bilinear as Arith<T>>::bilinear);
        let taps = Taps::<T, T::Bilinear, 2, 3>::new(view, &table, fill);
        for gains in [Vec::new(), gains] {
            let coords = Scattered {
                width: w,
                xy: xy.clone(),
                gains,
            };
            let mut fast = vec![T::default(); 3 * w * h];
            resample_channels(view, &coords, Interpolation::Bilinear, fill, &mut fast).unwrap();
            for (y, row) in fast.chunks_exact(3 * w).enumerate() {
                let row_xy = &coords.xy[6 * w * y..][..6 * w];
                let row_gains = coords.gains.get(3 * w * y..3 * w * (y + 1)).unwrap_or(&[]);
                assert_row_is_scalar(&taps, (row_xy, row_gains), row, (w, y));
            }
        }
    }

    /// Each sample of `row` (of image row `y`) against [`channel_sample`].
    fn assert_row_is_scalar<T: Resample>(
        taps: &Taps<T, T::Bilinear, 2, 3>,
        (xy, gains): (&[i32], &[f32]),
        row: &[T],
        (w, y): (usize, usize),
    ) {
        for (s, &got) in row.iter().enumerate() {
            let want = channel_sample(taps, xy, gains, s);
            assert!(
                got.to_f32().to_bits() == want.to_f32().to_bits(),
                "width {w}, row {y}, sample {s}: {got:?} vs {want:?}"
            );
        }
    }

    /// Per-channel positions (fixed point) and gains for a `w x h` image:
    /// inside, across the borders, far outside and NaN, and smooth rows of
    /// them as a lens correction's, some with the channels rows apart.
    fn channel_positions(w: usize, h: usize) -> (Vec<i32>, Vec<f32>) {
        let mut state = 99u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f64 / (1u64 << 24) as f64
        };
        let (w_f, h_f) = (w as f64, h as f64);
        let xy: Vec<i32> = (0..6 * w * h)
            .map(|i| {
                let (row, is_y) = (i / (6 * w), i % 2 == 1);
                let side = if is_y { h_f } else { w_f };
                match (row % 4, i % 37) {
                    (0, 0) => to_fixed(f64::NAN),
                    (0, 1) => to_fixed(1e9),
                    (0, _) => to_fixed(next() * (side + 4.0) - 2.0),
                    // Smooth, as a lens correction's: each channel near
                    // the pixel, the three a little apart, so that whole
                    // steps take the SIMD path.
                    (3, _) => {
                        let (u, c) = ((i % (6 * w)) / 6, (i % 6 / 2) as f64);
                        let at = if is_y {
                            row as f64 + 0.3 * c - 0.4
                        } else {
                            0.97 * u as f64 + 0.4 * c - 0.3 + 0.2 * next()
                        };
                        to_fixed(at.clamp(0.0, side - 1.0))
                    }
                    // Smooth and sloping, red and blue up to 2.5 rows
                    // from green: steps over one to six source rows.
                    (1, _) => {
                        let (u, c) = ((i % (6 * w)) / 6, (i % 6 / 2) as f64 - 1.0);
                        let at = if is_y {
                            row as f64 + 2.5 * c * u as f64 / w_f + 0.05 * u as f64
                        } else {
                            1.02 * u as f64 + 0.8 * c
                        };
                        to_fixed(at.clamp(0.0, side - 1.0))
                    }
                    // Whole windows inside, some at exact integers.
                    (_, 2) => to_fixed((next() * (side - 1.0)).floor()),
                    _ => to_fixed(next() * (side - 1.0)),
                }
            })
            .collect();
        let gains: Vec<f32> = (0..3 * w * h)
            .map(|i| match i % 23 {
                0 => 0.0,
                1 => 1e30,
                _ => (0.5 + 2.5 * next()) as f32,
            })
            .collect();
        (xy, gains)
    }

    /// Both x86 u8 kernels, called directly (the dispatch takes only the
    /// widest the CPU has), against the scalar path.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn both_u8_channel_kernels_give_the_scalar_bits() {
        type Kernel = unsafe fn(
            &[u8],
            usize,
            (usize, usize),
            (&[i32], &[f32], &mut [u8]),
            &mut dyn FnMut(usize, &mut [u8]),
        ) -> bool;
        let mut kernels: Vec<Kernel> = Vec::new();
        if std::arch::is_x86_feature_detected!("avx2") {
            kernels.push(avx2::channel_row_u8);
        }
        if avx512::available() {
            kernels.push(avx512::channel_row_u8);
        }
        let table = std::array::from_fn(<u32 as Arith<u8>>::bilinear);
        for (w, h) in [(100, 12), (40, 9), (17, 6)] {
            for stride in [3 * w, 3 * w + 5] {
                let data = u8_samples((h - 1) * stride + 3 * w);
                let view = ImageView::new(&data, w, h, 3, stride).unwrap();
                let taps = Taps::<u8, u32, 2, 3>::new(&view, &table, 7.0);
                let (xy, gains) = channel_positions(w, h);
                for (kernel, gained) in kernels.iter().flat_map(|k| [(k, false), (k, true)]) {
                    for y in 0..h {
                        let xy = &xy[6 * w * y..][..6 * w];
                        let gains = if gained {
                            &gains[3 * w * y..][..3 * w]
                        } else {
                            &[][..]
                        };
                        let mut row = vec![0u8; 3 * w];
                        let mut scalar =
                            |s: usize, px: &mut [u8]| px[0] = channel_sample(&taps, xy, gains, s);
                        // SAFETY: the CPU has the kernel's features; `data` holds the view.
                        let done = unsafe {
                            kernel(&data, stride, (w, h), (xy, gains, &mut row), &mut scalar)
                        };
                        assert!(done);
                        assert_row_is_scalar(&taps, (xy, gains), &row, (w, y));
                    }
                }
            }
        }
    }

    #[test]
    fn per_channel_rows_match_the_scalar_path_bit_for_bit() {
        for (w, h) in [(100, 12), (40, 9), (3, 2), (17, 6)] {
            // Contiguous, and with 5 samples of padding after each row.
            for stride in [3 * w, 3 * w + 5] {
                let n = (h - 1) * stride + 3 * w;
                let u8s = u8_samples(n);
                assert_channel_rows_match_the_scalar_path(
                    &ImageView::new(&u8s, w, h, 3, stride).unwrap(),
                );
                let u16s = u16_samples(n);
                assert_channel_rows_match_the_scalar_path(
                    &ImageView::new(&u16s, w, h, 3, stride).unwrap(),
                );
                let f32s: Vec<f32> = (0..n)
                    .map(|i| match i % 11 {
                        0 => -0.0,
                        1 => -3.5,
                        _ => (i * 7919 % 1000) as f32 / 999.0,
                    })
                    .collect();
                assert_channel_rows_match_the_scalar_path(
                    &ImageView::new(&f32s, w, h, 3, stride).unwrap(),
                );
            }
        }
    }
}

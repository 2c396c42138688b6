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
//! # Rounding
//! Samples are computed in `f32`; integer outputs are rounded half up and
//! clamped to their type's range (bicubic overshoots at edges), float outputs
//! are neither rounded nor clamped.

use std::ops::Range;

use crate::distortion::Distortion;
use crate::error::{CoreError, Result};
use crate::image::{ImageView, Sample};
use crate::intrinsics::Intrinsics;
use crate::invalid;
use crate::parallel::for_each_row;

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

/// Source positions of output pixels.
pub trait Coords: Sync {
    /// Where output pixel `(x, y)` is read from, in source pixels (NaN: nowhere).
    fn at(&self, x: usize, y: usize) -> (f32, f32);
}

/// A dense map of source positions, one `(x, y)` pair per output pixel,
/// stored interleaved so that one output row reads one contiguous run.
///
/// Built once per camera and image size, it makes every further frame a pure
/// resampling pass: the lens model is never evaluated again.
#[derive(Debug, Clone, PartialEq)]
pub struct RemapMap {
    width: usize,
    height: usize,
    xy: Vec<f32>,
}

impl RemapMap {
    /// Wraps interleaved `(x, y)` positions for a `height x width` output.
    ///
    /// # Errors
    /// [`CoreError::Shape`] when the size is zero or `xy` does not hold
    /// `2 * width * height` values.
    pub fn from_interleaved(xy: Vec<f32>, width: usize, height: usize) -> Result<Self> {
        check_size(width, height)?;
        if xy.len() != 2 * width * height {
            return Err(CoreError::Shape(format!(
                "a {height}x{width} map needs {} interleaved coordinates, got {}",
                2 * width * height,
                xy.len()
            )));
        }
        Ok(Self { width, height, xy })
    }

    /// Joins separate `map_x` and `map_y` planes (OpenCV's layout).
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
        let xy = map_x
            .iter()
            .zip(map_y)
            .flat_map(|(&x, &y)| [x, y])
            .collect();
        Ok(Self { width, height, xy })
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
        Self::from_fn(width, height, |u, v| {
            let (x, y) = new_k.to_normalized(u, v);
            dist.distort(x, y).map(|(xd, yd)| k.to_pixel(xd, yd))
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
        Self::from_fn(width, height, |u, v| {
            let (xd, yd) = k.to_normalized(u, v);
            dist.undistort(xd, yd).map(|(x, y)| new_k.to_pixel(x, y))
        })
    }

    /// Evaluates `source(u, v)` in f64 for every output pixel, in parallel
    /// over rows; `None` becomes NaN.
    fn from_fn<F>(width: usize, height: usize, source: F) -> Result<Self>
    where
        F: Fn(f64, f64) -> Option<(f64, f64)> + Sync,
    {
        check_size(width, height)?;
        let mut xy = vec![0.0f32; 2 * width * height];
        for_each_row(&mut xy, 2 * width, |v, row| {
            for (u, out) in row.chunks_exact_mut(2).enumerate() {
                let (x, y) = source(u as f64, v as f64).unwrap_or((f64::NAN, f64::NAN));
                out[0] = x as f32;
                out[1] = y as f32;
            }
        });
        Ok(Self { width, height, xy })
    }

    pub fn width(&self) -> usize {
        self.width
    }
    pub fn height(&self) -> usize {
        self.height
    }
    /// The interleaved `(x, y)` positions, row by row.
    pub fn interleaved(&self) -> &[f32] {
        &self.xy
    }
}

impl Coords for RemapMap {
    #[inline(always)]
    fn at(&self, x: usize, y: usize) -> (f32, f32) {
        let i = 2 * (y * self.width + x);
        (self.xy[i], self.xy[i + 1])
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
    if fill.is_finite() && T::from_f32(f).to_f32() == f {
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
pub fn remap<T: Sample>(
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
pub(crate) fn resample<T: Sample, S: Coords>(
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
    let job = Job {
        src,
        coords,
        channels,
        fill,
    };
    match interpolation {
        Interpolation::Bilinear => job.run(out, row_len, bilinear_weights),
        Interpolation::Bicubic => job.run(out, row_len, keys_weights),
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

impl<T: Sample, S: Coords> Job<'_, T, S> {
    /// Picks a kernel specialised for the number of sampled channels, so the
    /// common 1, 3 and 4 get fully unrolled inner loops.
    fn run<const TAPS: usize, W>(&self, out: &mut [T], row_len: usize, weights: W)
    where
        W: Fn(f32) -> [f32; TAPS] + Sync + Copy,
    {
        match self.channels.len() {
            1 => self.rows::<TAPS, 1, W>(out, row_len, weights),
            3 => self.rows::<TAPS, 3, W>(out, row_len, weights),
            4 => self.rows::<TAPS, 4, W>(out, row_len, weights),
            _ => self.rows::<TAPS, 0, W>(out, row_len, weights),
        }
    }

    /// All output rows in parallel. `N` is the number of channels sampled,
    /// or 0 for "as many as `self.channels` says" (the unspecialised case).
    fn rows<const TAPS: usize, const N: usize, W>(&self, out: &mut [T], row_len: usize, weights: W)
    where
        W: Fn(f32) -> [f32; TAPS] + Sync + Copy,
    {
        let n = if N > 0 { N } else { self.channels.len() };
        let c0 = self.channels.start;
        let nc = self.src.channels();
        let (w, h) = (self.src.width() as isize, self.src.height() as isize);
        // Offset of the first tap from floor(position): 0 for 2 taps, -1 for 4.
        let lead = (TAPS / 2 - 1) as isize;
        // Positions further out than this touch no tap; the test also rejects NaN.
        let reach = TAPS as f32;
        let (x_lo, x_hi) = (-reach, w as f32 + reach);
        let (y_lo, y_hi) = (-reach, h as f32 + reach);
        for_each_row(out, row_len, |y, row| {
            for (x, px) in row.chunks_exact_mut(nc).enumerate() {
                let px = &mut px[c0..c0 + n];
                let (sx, sy) = self.coords.at(x, y);
                if !(sx > x_lo && sx < x_hi && sy > y_lo && sy < y_hi) {
                    px.iter_mut().for_each(|p| *p = T::from_f32(self.fill));
                    continue;
                }
                let (fx, fy) = (floor(sx), floor(sy));
                let (wx, wy) = (weights(sx - fx as f32), weights(sy - fy as f32));
                let (ix, iy) = (fx as isize - lead, fy as isize - lead);
                if ix >= 0 && iy >= 0 && ix + TAPS as isize <= w && iy + TAPS as isize <= h {
                    let (ix, iy) = (ix as usize, iy as usize);
                    for (c, p) in px.iter_mut().enumerate() {
                        let base = ix * nc + c0 + c;
                        *p = T::from_f32(convolve(&wx, &wy, |i, j| {
                            self.src.row(iy + j)[base + i * nc].to_f32()
                        }));
                    }
                } else {
                    for (c, p) in px.iter_mut().enumerate() {
                        *p = T::from_f32(convolve(&wx, &wy, |i, j| {
                            let (tx, ty) = (ix + i as isize, iy + j as isize);
                            if tx >= 0 && ty >= 0 && tx < w && ty < h {
                                self.src.at(tx as usize, ty as usize, c0 + c).to_f32()
                            } else {
                                self.fill
                            }
                        }));
                    }
                }
            }
        });
    }
}

/// `floor` by truncation: `f32::floor` is a libm call on baseline x86-64
/// (no SSE4.1), and positions here are already known to be in range.
#[inline(always)]
fn floor(v: f32) -> i32 {
    let t = v as i32;
    t - i32::from((t as f32) > v)
}

/// `Σ_j wy[j] Σ_i wx[i] tap(i, j)`: the separable tensor-product sample.
#[inline(always)]
fn convolve<const TAPS: usize>(
    wx: &[f32; TAPS],
    wy: &[f32; TAPS],
    tap: impl Fn(usize, usize) -> f32,
) -> f32 {
    let mut acc = 0.0;
    for (j, &b) in wy.iter().enumerate() {
        let mut line = 0.0;
        for (i, &a) in wx.iter().enumerate() {
            line += a * tap(i, j);
        }
        acc += b * line;
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
            (0..h)
                .flat_map(|y| (0..w).flat_map(move |x| [x as f32, y as f32]))
                .collect(),
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
            vec![0.5, 0.0, 2.5, 0.0, -0.5, 0.0, f32::NAN, 0.0, 1e30, 0.0],
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
        let map = RemapMap::from_interleaved(vec![5.25, 0.0], 1, 1).unwrap();
        let mut out = [0f32; 1];
        remap(&view, &map, Interpolation::Bicubic, 0.0, &mut out).unwrap();
        assert!((out[0] - 5.25 * 5.25).abs() < 1e-4, "{}", out[0]);
        // A step 0 -> 255 overshoots past 255 just after the edge; u8 clamps it.
        let step = [0u8, 0, 0, 255, 255, 255, 255];
        let view = ImageView::contiguous(&step, 7, 1, 1).unwrap();
        let map = RemapMap::from_interleaved(vec![3.25, 0.0, 2.75, 0.0], 2, 1).unwrap();
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
        let (sx, sy) = und.at(10, 7);
        let (bx, by) = dis.at(sx.round() as usize, sy.round() as usize);
        assert!(
            (bx - 10.0).abs() < 1.0 && (by - 7.0).abs() < 1.0,
            "{bx} {by}"
        );
        let (cx, cy) = und.at(31, 23);
        assert!((cx - 31.0).abs() < 0.01 && (cy - 23.0).abs() < 0.01);
    }

    #[test]
    fn bad_arguments_are_refused() {
        assert!(Interpolation::from_name("nearest").is_err());
        assert!(RemapMap::from_interleaved(vec![0.0; 5], 2, 1).is_err());
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
}

//! Borrowed image views and the sample types kernels are generic over.

use rayon::prelude::*;

use crate::error::{CoreError, Result};

/// A pixel sample type: `u8`, `u16` or `f32`.
///
/// Kernels compute in `f32` and convert back once per output sample: integers
/// are rounded half up and clamped to their type's range, floats pass through
/// unchanged (never clipped, as CONVENTIONS.md asks).
pub trait Sample: Copy + Send + Sync + Default + PartialOrd + std::fmt::Debug + 'static {
    /// Largest value of the type's nominal range (1.0 for floats).
    const FULL_SCALE: f32;
    /// The sample as `f32`.
    fn to_f32(self) -> f32;
    /// Rounds and clamps `v` into the type (floats: identity).
    fn from_f32(v: f32) -> Self;

    /// [`Sample::from_f32`] over a row: `dst[i] = from_f32(src[i])`. Types
    /// override it where the element-wise form does not vectorise well.
    #[inline(always)]
    fn from_f32_row(dst: &mut [Self], src: &[f32]) {
        for (d, s) in dst.iter_mut().zip(src) {
            *d = Self::from_f32(*s);
        }
    }

    /// [`Sample::from_f32_row`] of the values clamped to `[lo, hi]`, two
    /// values of the type (such as the smallest and largest sample of a
    /// mosaic): one pass where a clamp and a conversion took two.
    #[inline(always)]
    fn from_f32_row_within(dst: &mut [Self], src: &[f32], (lo, hi): (f32, f32)) {
        for (d, s) in dst.iter_mut().zip(src) {
            *d = Self::from_f32(s.max(lo).min(hi));
        }
    }

    /// `from_f32(v).to_f32()`: `v` rounded to a value of the type but kept
    /// in `f32`, for pipelines that must match a round trip through the
    /// type. Types override it where that form does not vectorise.
    #[inline(always)]
    fn quantize(v: f32) -> f32 {
        Self::from_f32(v).to_f32()
    }

    /// Writes the planes `r`, `g` and `b` (each at least `out.len() / 3`
    /// long) into `out` as pixels. Types override it where a wider
    /// shuffle than [`crate::interleave::pixels`]' serves them.
    #[inline(always)]
    fn interleave(planes: [&[Self]; 3], out: &mut [Self]) {
        crate::interleave::pixels(planes, out);
    }

    /// Whether the sample is a number: integers always are, so scans for
    /// NaN and infinities compile away for them.
    #[inline(always)]
    fn is_finite(self) -> bool {
        true
    }
}

impl Sample for u8 {
    const FULL_SCALE: f32 = 255.0;
    #[inline(always)]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
    #[inline(always)]
    fn from_f32(v: f32) -> Self {
        // `as` saturates (and maps NaN to 0), so adding 0.5 then truncating
        // rounds half up and clamps to 0..=255 in one step.
        (v + 0.5) as u8
    }

    #[inline(always)]
    fn from_f32_row(dst: &mut [Self], src: &[f32]) {
        Self::from_f32_row_within(dst, src, (0.0, 255.0));
    }

    #[inline(always)]
    fn from_f32_row_within(dst: &mut [Self], src: &[f32], (lo, hi): (f32, f32)) {
        let (lo, hi) = (lo.clamp(0.0, 255.0), hi.clamp(0.0, 255.0));
        for (d, s) in dst.iter_mut().zip(src) {
            *d = round_within(*s, lo, hi) as u8;
        }
    }

    #[inline(always)]
    fn quantize(v: f32) -> f32 {
        round_within(v, 0.0, 255.0) as f32
    }
}

impl Sample for u16 {
    const FULL_SCALE: f32 = 65535.0;
    #[inline(always)]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
    #[inline(always)]
    fn from_f32(v: f32) -> Self {
        (v + 0.5) as u16
    }

    #[inline(always)]
    fn from_f32_row(dst: &mut [Self], src: &[f32]) {
        Self::from_f32_row_within(dst, src, (0.0, 65535.0));
    }

    #[inline(always)]
    fn from_f32_row_within(dst: &mut [Self], src: &[f32], (lo, hi): (f32, f32)) {
        let (lo, hi) = (lo.clamp(0.0, 65535.0), hi.clamp(0.0, 65535.0));
        for (d, s) in dst.iter_mut().zip(src) {
            *d = round_within(*s, lo, hi) as u16;
        }
    }

    #[inline(always)]
    fn quantize(v: f32) -> f32 {
        round_within(v, 0.0, 65535.0) as f32
    }

    #[inline(always)]
    fn interleave(planes: [&[Self]; 3], out: &mut [Self]) {
        crate::interleave::u16s(planes, out);
    }
}

/// `v` clamped to `[lo, hi]` (NaN to `lo`), two integers in `[0, 65535]`,
/// and rounded half up: `from_f32` of the clamped value (`lo = 0` and `hi`
/// the type's largest value), in a form that vectorises.
///
/// Rust's saturating `as` cast from float to int handles NaN and overflow
/// with scalar fix-ups that keep LLVM from vectorising a row of them (a u16
/// RGB row measured ~3x slower that way). The two comparisons below map to
/// `maxps` / `minps` (NaN lands on the lower end because `NaN > x` is
/// false), after which the value is finite and in range, so the unchecked
/// conversion (`cvttps2dq`) is exact. Clamping `v + 0.5` to `[lo + 0.5,
/// hi + 0.5]` gives the bits of clamping `v` first: `lo + 0.5` and `hi +
/// 0.5` are exact and rounding is monotonic.
#[inline(always)]
fn round_within(v: f32, lo: f32, hi: f32) -> i32 {
    let (v, lo, hi) = (v + 0.5, lo + 0.5, hi + 0.5);
    let v = if v > lo { v } else { lo };
    let v = if v < hi { v } else { hi };
    // SAFETY: `v` is finite and in [0.5, 65535.5], which truncates to an
    // i32: the precondition of `to_int_unchecked`.
    unsafe { v.to_int_unchecked::<i32>() }
}

impl Sample for f32 {
    const FULL_SCALE: f32 = 1.0;
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self
    }
    #[inline(always)]
    fn from_f32(v: f32) -> Self {
        v
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
}

/// A read-only, row-strided view of an `(height, width, channels)` image.
#[derive(Debug, Clone, Copy)]
pub struct ImageView<'a, T> {
    data: &'a [T],
    width: usize,
    height: usize,
    channels: usize,
    /// Elements between the starts of two consecutive rows (>= width * channels).
    stride: usize,
}

impl<'a, T: Copy> ImageView<'a, T> {
    /// Wraps `data` as an image.
    ///
    /// # Errors
    /// [`CoreError::Shape`] when a dimension is zero, the stride is shorter
    /// than a row, or `data` is too short for the last row.
    pub fn new(
        data: &'a [T],
        width: usize,
        height: usize,
        channels: usize,
        stride: usize,
    ) -> Result<Self> {
        if width == 0 || height == 0 || channels == 0 {
            return Err(CoreError::Shape(format!(
                "image must be non-empty, got height {height}, width {width}, channels {channels}"
            )));
        }
        let row = width * channels;
        if stride < row {
            return Err(CoreError::Shape(format!(
                "row stride {stride} is shorter than a row of {row} samples"
            )));
        }
        let needed = (height - 1) * stride + row;
        if data.len() < needed {
            return Err(CoreError::Shape(format!(
                "image buffer holds {} samples, a {height}x{width}x{channels} image with stride {stride} needs {needed}",
                data.len()
            )));
        }
        Ok(Self {
            data,
            width,
            height,
            channels,
            stride,
        })
    }

    /// A contiguous image (stride = width * channels).
    ///
    /// # Errors
    /// As [`ImageView::new`].
    pub fn contiguous(data: &'a [T], width: usize, height: usize, channels: usize) -> Result<Self> {
        Self::new(data, width, height, channels, width * channels)
    }

    pub fn width(&self) -> usize {
        self.width
    }
    pub fn height(&self) -> usize {
        self.height
    }
    pub fn channels(&self) -> usize {
        self.channels
    }
    /// Elements between the starts of two consecutive rows.
    pub fn stride(&self) -> usize {
        self.stride
    }
    /// The underlying buffer, from the first sample of row 0 (SIMD kernels
    /// address it with per-pixel offsets).
    pub fn data(&self) -> &'a [T] {
        self.data
    }
    /// Samples in one output row (`width * channels`).
    pub fn row_len(&self) -> usize {
        self.width * self.channels
    }

    /// Row `y` (`width * channels` samples).
    #[inline(always)]
    pub fn row(&self, y: usize) -> &'a [T] {
        let start = y * self.stride;
        &self.data[start..start + self.width * self.channels]
    }

    /// Sample `c` of pixel `(x, y)`.
    #[inline(always)]
    pub fn at(&self, x: usize, y: usize, c: usize) -> T {
        self.data[y * self.stride + x * self.channels + c]
    }

    /// The first sample for which `bad` holds, in row-major order whatever
    /// the thread count: its row and its index in the row.
    pub fn find_first(&self, bad: impl Fn(&T) -> bool + Sync) -> Option<(usize, usize)>
    where
        T: Sync,
    {
        let y = (0..self.height)
            .into_par_iter()
            .find_first(|&y| self.row(y).iter().any(&bad))?;
        Some((y, self.row(y).iter().position(&bad)?))
    }
}

/// Reflects index `i` into `0..n` about the edge samples, without repeating
/// them (`-1 -> 1`, `n -> n - 2`): the mirror that keeps a CFA's parity and
/// has no seam. Indices further out than one period are reflected again.
#[inline(always)]
pub fn mirror(i: isize, n: usize) -> usize {
    let n = n as isize;
    if n == 1 {
        return 0;
    }
    let period = 2 * (n - 1);
    let m = i.rem_euclid(period);
    (if m < n { m } else { period - m }) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integer_conversion_rounds_half_up_and_clamps() {
        assert_eq!(u8::from_f32(-3.0), 0);
        assert_eq!(u8::from_f32(1.49), 1);
        assert_eq!(u8::from_f32(1.5), 2);
        assert_eq!(u8::from_f32(300.0), 255);
        assert_eq!(u8::from_f32(f32::NAN), 0);
        assert_eq!(u16::from_f32(70000.0), 65535);
        assert_eq!(f32::from_f32(-0.25), -0.25);
    }

    #[test]
    fn row_conversion_equals_the_scalar_one() {
        let src: Vec<f32> = [
            -1e9, -0.6, -0.5, 0.0, 0.49, 0.5, 32767.5, 65534.5, 65535.4, 7e4,
        ]
        .into_iter()
        .chain([f32::NAN, f32::INFINITY, f32::NEG_INFINITY])
        .collect();
        let mut row = vec![0u16; src.len()];
        u16::from_f32_row(&mut row, &src);
        let each: Vec<u16> = src.iter().map(|&v| u16::from_f32(v)).collect();
        assert_eq!(row, each);
        let mut row8 = vec![0u8; src.len()];
        u8::from_f32_row(&mut row8, &src);
        let each8: Vec<u8> = src.iter().map(|&v| u8::from_f32(v)).collect();
        assert_eq!(row8, each8);
    }

    #[test]
    fn clamped_row_conversion_equals_a_clamp_then_the_conversion() {
        // Values around the bounds, between and beyond them, and NaN.
        let src: Vec<f32> = (-40..2000)
            .map(|i| i as f32 * 0.37 - 3.0)
            .chain([f32::NAN, 1e9, -1e9, 99.5, 100.5, 1199.5, 1200.49])
            .collect();
        for bounds in [(100.0, 1200.0), (0.0, 255.0), (7.0, 7.0)] {
            let clamped: Vec<f32> = src.iter().map(|v| v.max(bounds.0).min(bounds.1)).collect();
            let (mut fused, mut apart) = (vec![0u16; src.len()], vec![0u16; src.len()]);
            u16::from_f32_row_within(&mut fused, &src, bounds);
            u16::from_f32_row(&mut apart, &clamped);
            assert_eq!(fused, apart, "{bounds:?}");
            let (mut fused, mut apart) = (vec![0u8; src.len()], vec![0u8; src.len()]);
            u8::from_f32_row_within(&mut fused, &src, (bounds.0, bounds.1.min(255.0)));
            let clamped: Vec<f32> = clamped.iter().map(|v| v.min(255.0)).collect();
            u8::from_f32_row(&mut apart, &clamped);
            assert_eq!(fused, apart, "{bounds:?}");
        }
    }

    #[test]
    fn mirror_reflects_without_repeating_the_edge() {
        let got: Vec<usize> = (-3..8).map(|i| mirror(i, 5)).collect();
        assert_eq!(got, vec![3, 2, 1, 0, 1, 2, 3, 4, 3, 2, 1]);
        assert_eq!(mirror(-7, 1), 0);
    }

    #[test]
    fn view_rejects_short_buffers_and_strides() {
        let data = [0u8; 11];
        assert!(ImageView::new(&data, 2, 2, 3, 6).is_err());
        assert!(ImageView::new(&data, 2, 2, 3, 5).is_err());
        assert!(ImageView::new(&data, 2, 2, 2, 6).is_ok());
        assert!(ImageView::<u8>::contiguous(&[], 0, 1, 1).is_err());
    }
}

//! An image blurred by a point spread function: the convolution
//! `out(p) = sum_i psf(i) img(p + c - i)` with the anchor `c = (kh / 2, kw / 2)`
//! (the centre of an odd kernel), so light at a source pixel lands on the
//! pixels the PSF covers around it. Borders are mirrored
//! ([`crate::image::mirror`]); sums are in `f32`, integers are rounded half
//! up and clamped once at the end (as [`Sample::from_f32`]). The PSF is used
//! as given: one that sums to 1 keeps the image's brightness.
//!
//! Small kernels (up to [`DIRECT_MAX_TAPS`] taps) are summed directly, tap
//! by tap, over whole rows; larger ones go through overlap-save FFT tiles
//! (`fft_tiles`), whose cost per pixel grows only with the log of the
//! kernel size. The direct sum skips zero taps, so a delta PSF returns
//! every sample bit for bit; through the FFT a delta PSF returns integer
//! images bit for bit too (the f32 round-off stays far below the rounding
//! step) and float images to ~1e-6.

use crate::error::{all_finite, CoreError, Result};
use crate::image::{mirror, ImageView, Sample};
use crate::invalid;
use crate::parallel::for_each_band;

use super::fft_tiles;

/// Kernels with up to this many taps (6 x 6) are summed directly. Each tap
/// is one multiply-add per sample, while the FFT tiles cost about the same
/// per sample whatever the kernel. Measured on the shared 2-core machine,
/// 6 MP RGB f32: direct 11 x 11 in 1.08 s and 15 x 15 in 1.87 s (~8 ms a
/// tap), FFT tiles 16 x 16 in 0.36 s and 21 x 21 in 0.45 s, so the direct
/// sum only wins below ~40 taps.
pub const DIRECT_MAX_TAPS: usize = 36;

/// Largest PSF side. A 1025-pixel kernel already needs 2048-wide FFT tiles
/// (32 MB of scratch per thread); a blur that wide is better applied to a
/// downscaled image.
pub const MAX_KERNEL: usize = 1025;

/// Output rows per task of the direct sum: the band converts `kh - 1` rows
/// beyond its own, so 32 rows keep that overhead small for the kernels that
/// take this path while a 24 MP image still makes ~125 tasks.
const DIRECT_BAND: usize = 32;

/// A validated PSF, row-major.
#[derive(Debug, Clone, Copy)]
pub(super) struct Kernel<'a> {
    pub taps: &'a [f64],
    pub h: usize,
    pub w: usize,
}

impl Kernel<'_> {
    /// Rows of padding before the image: tap row `i` reads image row
    /// `y + h/2 - i`, the smallest of which is `h - 1 - h/2` above `y`.
    pub fn before_y(&self) -> usize {
        self.h - 1 - self.h / 2
    }
    /// Columns of padding before the image, as [`Kernel::before_y`].
    pub fn before_x(&self) -> usize {
        self.w - 1 - self.w / 2
    }
}

/// Mirrored image indices of `i - before` for `i` in `0..len`: the tables
/// that let the inner loops read padded rows and columns without a branch.
pub(super) fn mirrored(n: usize, before: usize, len: usize) -> Vec<usize> {
    (0..len)
        .map(|i| mirror(i as isize - before as isize, n))
        .collect()
}

/// Convolves `image` with the `psf_h x psf_w` kernel `psf` (row-major) into
/// `out` (contiguous, the image's size and channels).
///
/// # Errors
/// A PSF whose length does not match its sides, an empty PSF or one with a
/// side above [`MAX_KERNEL`], non-finite taps, or an `out` of the wrong size.
pub fn render_aberrated<T: Sample>(
    image: ImageView<'_, T>,
    psf: &[f64],
    (psf_h, psf_w): (usize, usize),
    out: &mut [T],
) -> Result<()> {
    if psf_h == 0 || psf_w == 0 || psf_h > MAX_KERNEL || psf_w > MAX_KERNEL {
        return Err(invalid!(
            "psf sides must be in 1..={MAX_KERNEL}, got {psf_h}x{psf_w}"
        ));
    }
    if psf.len() != psf_h * psf_w {
        return Err(CoreError::Shape(format!(
            "psf must hold {psf_h}x{psf_w} = {} values, got {}",
            psf_h * psf_w,
            psf.len()
        )));
    }
    all_finite("psf", psf)?;
    let (w, h, c) = (image.width(), image.height(), image.channels());
    if out.len() != w * h * c {
        return Err(CoreError::Shape(format!(
            "output must hold {h}x{w}x{c} = {} samples, got {}",
            w * h * c,
            out.len()
        )));
    }
    let kernel = Kernel {
        taps: psf,
        h: psf_h,
        w: psf_w,
    };
    if psf.len() <= DIRECT_MAX_TAPS {
        direct(image, kernel, out);
    } else {
        fft_tiles::convolve(image, kernel, out);
    }
    Ok(())
}

/// The direct sum over bands of [`DIRECT_BAND`] output rows. Each band
/// converts its source rows once into mirrored-padded `f32` rows; each tap
/// then adds a shifted padded row into the accumulator row, a loop that
/// vectorises over all samples of the row.
fn direct<T: Sample>(image: ImageView<'_, T>, k: Kernel<'_>, out: &mut [T]) {
    let (w, h, c) = (image.width(), image.height(), image.channels());
    let (row, padded_row) = (w * c, (w + k.w - 1) * c);
    let cols = mirrored(w, k.before_x(), w + k.w - 1);
    let taps: Vec<f32> = k.taps.iter().map(|&t| t as f32).collect();
    for_each_band(out, row, DIRECT_BAND, |y0, rows| {
        let n_rows = rows.len() / row;
        let mut padded = vec![0.0f32; (n_rows + k.h - 1) * padded_row];
        for (r, dst) in padded.chunks_exact_mut(padded_row).enumerate() {
            let src = image.row(mirror((y0 + r) as isize - k.before_y() as isize, h));
            for (d, &x) in dst.chunks_exact_mut(c).zip(&cols) {
                for (d, s) in d.iter_mut().zip(&src[x * c..(x + 1) * c]) {
                    *d = s.to_f32();
                }
            }
        }
        let mut acc = vec![0.0f32; row];
        for (v, out_row) in rows.chunks_exact_mut(row).enumerate() {
            acc.fill(0.0);
            for (i, tap_row) in taps.chunks_exact(k.w).enumerate() {
                let src = &padded[(v + k.h - 1 - i) * padded_row..][..padded_row];
                for (j, &t) in tap_row.iter().enumerate().filter(|(_, &t)| t != 0.0) {
                    let shifted = &src[(k.w - 1 - j) * c..][..row];
                    for (a, s) in acc.iter_mut().zip(shifted) {
                        *a += t * s;
                    }
                }
            }
            T::from_f32_row(out_row, &acc);
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise<T: Sample>(n: usize, scale: f32) -> Vec<T> {
        (0..n as u32)
            .map(|i| T::from_f32((i.wrapping_mul(2_654_435_761) >> 16) as f32 / 65536.0 * scale))
            .collect()
    }

    fn convolve<T: Sample>(
        img: &[T],
        (w, h, c): (usize, usize, usize),
        psf: &[f64],
        ks: (usize, usize),
    ) -> Vec<T> {
        let mut out = vec![T::default(); img.len()];
        let view = ImageView::contiguous(img, w, h, c).unwrap();
        render_aberrated(view, psf, ks, &mut out).unwrap();
        out
    }

    fn delta(kh: usize, kw: usize) -> Vec<f64> {
        let mut psf = vec![0.0; kh * kw];
        psf[(kh / 2) * kw + kw / 2] = 1.0;
        psf
    }

    /// Reference: the definition, one sample at a time, in f64.
    fn naive(
        img: &[f32],
        (w, h, c): (usize, usize, usize),
        psf: &[f64],
        (kh, kw): (usize, usize),
    ) -> Vec<f32> {
        let mut out = vec![0.0f32; img.len()];
        for y in 0..h {
            for x in 0..w {
                for ch in 0..c {
                    let mut s = 0.0f64;
                    for i in 0..kh {
                        for j in 0..kw {
                            let sy = mirror((y + kh / 2) as isize - i as isize, h);
                            let sx = mirror((x + kw / 2) as isize - j as isize, w);
                            s += psf[i * kw + j] * f64::from(img[(sy * w + sx) * c + ch]);
                        }
                    }
                    out[(y * w + x) * c + ch] = s as f32;
                }
            }
        }
        out
    }

    #[test]
    fn delta_psf_returns_the_image_bit_for_bit() {
        let dims = (37, 29, 3);
        let img: Vec<u16> = noise(37 * 29 * 3, 65535.0);
        for ks in [(1, 1), (5, 7), (21, 19)] {
            assert_eq!(convolve(&img, dims, &delta(ks.0, ks.1), ks), img, "{ks:?}");
        }
        let img: Vec<f32> = noise(37 * 29 * 3, 1.0);
        assert_eq!(convolve(&img, dims, &delta(3, 3), (3, 3)), img);
    }

    #[test]
    fn both_paths_match_the_definition() {
        for (dims, ks) in [
            ((40, 23, 1), (4, 5)),
            ((45, 31, 3), (17, 16)),
            ((9, 70, 2), (21, 13)),
        ] {
            let n = dims.0 * dims.1 * dims.2;
            let img: Vec<f32> = noise(n, 1.0);
            let psf: Vec<f64> = (0..ks.0 * ks.1)
                .map(|i| ((i * 7919) % 13) as f64 / 100.0)
                .collect();
            let got = convolve(&img, dims, &psf, ks);
            let want = naive(&img, dims, &psf, ks);
            for (g, w) in got.iter().zip(&want) {
                assert!((g - w).abs() < 1e-4, "{dims:?} {ks:?}: {g} vs {w}");
            }
        }
    }

    #[test]
    fn bad_kernels_are_refused() {
        let img = [0u8; 12];
        let view = ImageView::contiguous(&img, 4, 3, 1).unwrap();
        let mut out = [0u8; 12];
        assert!(render_aberrated(view, &[1.0; 4], (2, 3), &mut out).is_err());
        assert!(render_aberrated(view, &[f64::NAN], (1, 1), &mut out).is_err());
        assert!(render_aberrated(view, &[], (0, 1), &mut out).is_err());
        assert!(render_aberrated(view, &[1.0], (1, 1), &mut out[..5]).is_err());
    }
}

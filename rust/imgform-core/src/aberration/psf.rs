//! The diffraction PSF of a circular pupil with defocus and spherical
//! aberration, sampled on the sensor's pixels.
//!
//! # Model
//! Fraunhofer diffraction: the amplitude in the focal plane is the Fourier
//! transform of the pupil function `P(rho) = exp(2 pi i W(rho))` inside the
//! unit disc (zero outside), `W(rho) = W020 rho^2 + W040 rho^4` in waves,
//! and the PSF is its squared modulus. A pupil of `K` samples across its
//! diameter, zero-padded to an FFT of `Q`, gives focal-plane samples
//! `dx = lambda N K / Q` apart over a periodic window `K lambda N` wide.
//!
//! # Sampling
//! - `dx = pixel_pitch / oversample`: each pixel is the sum of an
//!   `oversample x oversample` grid of point samples at the centres of its
//!   sub-cells (the midpoint rule for the integral over the pixel area).
//!   `dx` must not exceed `lambda N / 2`, the Nyquist interval of the PSF
//!   (its spectrum, the pupil's autocorrelation, ends at `1 / (lambda N)`):
//!   a coarser grid aliases and is refused. The default oversampling puts
//!   the sub-samples `lambda N / 8` apart, four times the Nyquist rate
//!   (`lambda N / 4` where the FFT would be too long): the midpoint rule's
//!   error falls as the square of the spacing, and at `lambda N / 4` it put
//!   an in-focus peak 2.5 % above the pixel integral.
//! - `K` is the largest of [`MIN_PUPIL_SAMPLES`] (a smooth pupil rim), twice
//!   the crop (`2 n_pixels pixel_pitch / (lambda N)`, so the tails that wrap
//!   around the periodic window land far from the crop) and eight times the
//!   largest wavefront slope `2 |W020| + 4 |W040|` waves per radius (at most a
//!   quarter wave between neighbouring pupil samples). The pupil is never
//!   undersampled: `K` grows instead, and sizes beyond [`MAX_FFT`] are refused.
//! - The FFT is separable, and only the `n_pixels * oversample` rows and
//!   columns of the crop are computed: row transforms of the `K` non-zero
//!   pupil rows, then column transforms of the kept columns. No `Q x Q`
//!   array is ever formed.
//! - The optical axis sits at the centre of the crop: the centre of the
//!   middle pixel for odd `n_pixels`, the corner between the four middle
//!   pixels for even ones (a half-sample tilt of the pupil phase moves it
//!   there exactly, when the sub-sample count is even).

use std::f64::consts::PI;

use rayon::prelude::*;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

use crate::error::{finite, positive, Result};
use crate::invalid;

/// Smallest pupil diameter in samples. The rim of a sampled disc is a
/// staircase; at 128 samples its area error is ~0.5 % and the first dark
/// ring of the Airy pattern moves by less than 0.5 %.
pub const MIN_PUPIL_SAMPLES: f64 = 128.0;

/// Largest FFT length. The work grows as `(K + n_pixels oversample) Q log Q`
/// and the kept rows take `K n_pixels oversample` complex values: at this
/// size up to ~0.5 GB and seconds of CPU, beyond which a geometric spot
/// diagram describes the blur better than a sampled wavefront anyway.
pub const MAX_FFT: usize = 8192;

/// Largest accepted oversampling factor (sub-samples per pixel and axis).
pub const MAX_OVERSAMPLE: usize = 64;

/// Largest PSF side in pixels.
pub const MAX_PIXELS: usize = 1025;

/// What [`pupil_psf`] computes. Lengths are in one unit (mm in the docs).
#[derive(Debug, Clone, Copy)]
pub struct PupilPsf {
    /// Side of the square PSF in pixels.
    pub n_pixels: usize,
    /// Distance between pixel centres on the sensor.
    pub pixel_pitch: f64,
    /// Focal length over aperture diameter.
    pub f_number: f64,
    /// Wavelength of the light, in the unit of `pixel_pitch`.
    pub wavelength: f64,
    /// Defocus coefficient `W020`, in waves at the pupil rim.
    pub defocus: f64,
    /// Spherical aberration coefficient `W040`, in waves at the pupil rim.
    pub spherical: f64,
    /// Sub-samples per pixel and axis; `None` puts them `lambda N / 4` apart.
    pub oversample: Option<usize>,
}

/// The sampling chosen for one PSF (see the module docs).
#[derive(Debug, Clone, Copy)]
struct Sampling {
    oversample: usize,
    /// FFT length.
    q: usize,
    /// Pupil radius between neighbouring samples (2 / K).
    drho: f64,
}

impl PupilPsf {
    fn validate(&self) -> Result<()> {
        positive("pixel_pitch", self.pixel_pitch)?;
        positive("f_number", self.f_number)?;
        positive("wavelength", self.wavelength)?;
        finite("defocus", self.defocus)?;
        finite("spherical", self.spherical)?;
        if self.n_pixels == 0 || self.n_pixels > MAX_PIXELS {
            return Err(invalid!(
                "n_pixels must be in 1..={MAX_PIXELS}, got {}",
                self.n_pixels
            ));
        }
        Ok(())
    }

    /// Chooses `oversample`, `K` and `Q`.
    fn sampling(&self) -> Result<Sampling> {
        let ln = self.wavelength * self.f_number;
        let ratio = self.pixel_pitch / ln;
        let nyquist = (2.0 * ratio).ceil().max(1.0);
        let slope = 2.0 * self.defocus.abs() + 4.0 * self.spherical.abs();
        let k = MIN_PUPIL_SAMPLES
            .max(2.0 * self.n_pixels as f64 * ratio)
            .max(8.0 * slope);
        let oversample = match self.oversample {
            Some(os) if (os as f64) < nyquist || os > MAX_OVERSAMPLE => {
                return Err(invalid!(
                    "oversample must be in {nyquist}..={MAX_OVERSAMPLE}: below {nyquist} the \
                     sub-samples are farther apart than lambda N / 2 = {} and the PSF aliases, \
                     got {os}",
                    ln / 2.0
                ))
            }
            Some(os) => os,
            // Sub-samples lambda N / 8 apart, where the midpoint rule puts
            // an in-focus peak 0.4-0.6 % above the pixel integral (2-2.5 %
            // at lambda N / 4, where it still does where the FFT would
            // otherwise outgrow MAX_FFT: Q grows with the oversampling).
            None => {
                let fits = (MAX_FFT as f64 * ratio / k).floor();
                fits.clamp((4.0 * ratio).ceil(), (8.0 * ratio).ceil())
                    .max(1.0) as usize
            }
        };
        if oversample > MAX_OVERSAMPLE {
            return Err(invalid!(
                "the pixel pitch {} is {ratio:.1} times lambda N = {ln}: the PSF is far smaller \
                 than a pixel and would need an oversampling of {oversample} > {MAX_OVERSAMPLE}; \
                 pass a smaller pixel_pitch",
                self.pixel_pitch
            ));
        }
        let dx = self.pixel_pitch / oversample as f64;
        let q_min = (k * ln / dx).ceil();
        if q_min > MAX_FFT as f64 {
            return Err(invalid!(
                "this PSF needs an FFT of {q_min} samples, more than the supported {MAX_FFT}: \
                 the wavefront error ({slope} waves of slope) or the window of n_pixels = {} \
                 pixels is too large at oversample = {oversample}; use fewer or larger pixels, \
                 a smaller aberration, or the geometric spot_diagram",
                self.n_pixels
            ));
        }
        let q = smooth_len(q_min as usize);
        Ok(Sampling {
            oversample,
            q,
            drho: 2.0 * ln / (q as f64 * dx),
        })
    }

    /// Wavefront error in waves at normalised pupil radius squared `r2`.
    #[inline]
    fn wavefront(&self, r2: f64) -> f64 {
        self.defocus * r2 + self.spherical * r2 * r2
    }
}

/// The smallest `m >= n` whose only prime factors are 2, 3 and 5, the
/// lengths at which rustfft is fastest.
pub(crate) fn smooth_len(n: usize) -> usize {
    (n.max(1)..)
        .find(|&m| {
            let mut r = m;
            for p in [2, 3, 5] {
                while r % p == 0 {
                    r /= p;
                }
            }
            r == 1
        })
        .unwrap_or(n)
}

/// Computes the PSF described by `params` as `n_pixels x n_pixels` values,
/// row-major, summing to 1.
///
/// # Errors
/// A non-positive or non-finite pitch, f-number or wavelength, non-finite
/// coefficients, `n_pixels` outside `1..=MAX_PIXELS`, an `oversample` below
/// the Nyquist rate or above [`MAX_OVERSAMPLE`], or a sampling that needs an
/// FFT longer than [`MAX_FFT`].
pub fn pupil_psf(params: &PupilPsf) -> Result<Vec<f64>> {
    params.validate()?;
    let s = params.sampling()?;
    let m = params.n_pixels * s.oversample;
    let fft = FftPlanner::<f64>::new().plan_fft_forward(s.q);
    let rows = pupil_row_transforms(params, &s, m, fft.as_ref());
    let binned = column_transforms(&rows, &s, m, params.n_pixels, fft.as_ref());
    let mut psf = vec![0.0; params.n_pixels * params.n_pixels];
    // Column t of the sub-sample grid falls in pixel column t / oversample;
    // summing in a fixed order keeps the result thread-count independent.
    for (t, col) in binned.chunks_exact(params.n_pixels).enumerate() {
        let px = t / s.oversample;
        for (py, v) in col.iter().enumerate() {
            psf[py * params.n_pixels + px] += v;
        }
    }
    let total: f64 = psf.iter().sum();
    psf.iter_mut().for_each(|v| *v /= total);
    Ok(psf)
}

/// FFT index of sub-sample `t` of the `m` kept ones: sub-sample `t` sits at
/// `(t - (m - 1) / 2) dx` from the axis, FFT sample `k` at `k - tilt`.
#[inline]
fn kept_index(t: usize, m: usize, q: usize) -> usize {
    (t as isize - ((m - 1) / 2) as isize).rem_euclid(q as isize) as usize
}

/// Half a sub-sample when the kept grid has an even count (its centre falls
/// between two samples), else none.
fn tilt(m: usize) -> f64 {
    if m.is_multiple_of(2) {
        0.5
    } else {
        0.0
    }
}

/// Transforms each non-zero pupil row and keeps its `m` crop columns:
/// `(2 half + 1) x m` values, pupil row `-half..=half` first to last.
fn pupil_row_transforms(
    p: &PupilPsf,
    s: &Sampling,
    m: usize,
    fft: &dyn Fft<f64>,
) -> Vec<Complex<f64>> {
    let half = (1.0 / s.drho).floor() as isize;
    let q = s.q;
    // A linear phase 2 pi tilt j / Q over pupil index j shifts the focal
    // plane by `tilt` samples (the Fourier shift theorem).
    let tilt_phase = 2.0 * PI * tilt(m) / q as f64;
    let mut rows = vec![Complex::default(); (2 * half as usize + 1) * m];
    rows.par_chunks_mut(m).enumerate().for_each_init(
        || scratch(fft, q),
        |(buf, work), (i, out)| {
            let jy = i as isize - half;
            buf.fill(Complex::default());
            for jx in -half..=half {
                let r2 = ((jx * jx + jy * jy) as f64) * s.drho * s.drho;
                if r2 <= 1.0 {
                    let phase = 2.0 * PI * p.wavefront(r2) + tilt_phase * (jx + jy) as f64;
                    buf[jx.rem_euclid(q as isize) as usize] = Complex::from_polar(1.0, phase);
                }
            }
            fft.process_with_scratch(buf, work);
            for (t, o) in out.iter_mut().enumerate() {
                *o = buf[kept_index(t, m, q)];
            }
        },
    );
    rows
}

/// Transforms each kept column of the row transforms and bins its
/// intensities into pixel rows: `m x n_pixels` values, column by column.
fn column_transforms(
    rows: &[Complex<f64>],
    s: &Sampling,
    m: usize,
    n_pixels: usize,
    fft: &dyn Fft<f64>,
) -> Vec<f64> {
    let q = s.q;
    let n_rows = rows.len() / m;
    let half = (n_rows / 2) as isize;
    let mut binned = vec![0.0; m * n_pixels];
    binned.par_chunks_mut(n_pixels).enumerate().for_each_init(
        || scratch(fft, q),
        |(buf, work), (t, out)| {
            buf.fill(Complex::default());
            for (i, row) in rows.chunks_exact(m).enumerate() {
                buf[(i as isize - half).rem_euclid(q as isize) as usize] = row[t];
            }
            fft.process_with_scratch(buf, work);
            out.fill(0.0);
            for t2 in 0..m {
                out[t2 / s.oversample] += buf[kept_index(t2, m, q)].norm_sqr();
            }
        },
    );
    binned
}

/// A transform buffer and its scratch space.
fn scratch(fft: &dyn Fft<f64>, q: usize) -> (Vec<Complex<f64>>, Vec<Complex<f64>>) {
    (
        vec![Complex::default(); q],
        vec![Complex::default(); fft.get_inplace_scratch_len()],
    )
}

/// The Strehl ratio of `psf` against the aberration-free `reference`: the
/// ratio of their peaks, each relative to its own total energy, so that the
/// two need not be normalised alike. Both must be sampled on the same grid.
///
/// # Errors
/// Buffers of different or zero length, a non-finite or negative value, or
/// a PSF whose sum is not positive.
pub fn strehl_ratio(psf: &[f64], reference: &[f64]) -> Result<f64> {
    if psf.is_empty() || psf.len() != reference.len() {
        return Err(invalid!(
            "psf and reference must be non-empty and of the same size, got {} and {} values",
            psf.len(),
            reference.len()
        ));
    }
    Ok(relative_peak(psf, "psf")? / relative_peak(reference, "reference")?)
}

/// Peak over total of a PSF whose values are finite and non-negative.
fn relative_peak(values: &[f64], name: &str) -> Result<f64> {
    if let Some(v) = values.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
        return Err(invalid!(
            "{name} must hold finite, non-negative intensities, got {v}"
        ));
    }
    let total: f64 = values.iter().sum();
    if total <= 0.0 {
        return Err(invalid!("{name} must have a positive sum, got {total}"));
    }
    let peak = values.iter().fold(0.0f64, |a, &v| a.max(v));
    if total.is_infinite() {
        // Summed in units of the peak: a sum of 1e308s overflowed, and the
        // ratio came out 0.
        return Ok(1.0 / values.iter().map(|v| v / peak).sum::<f64>());
    }
    Ok(peak / total)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(n: usize, defocus: f64, spherical: f64) -> PupilPsf {
        PupilPsf {
            n_pixels: n,
            pixel_pitch: 0.25e-3,
            f_number: 4.0,
            wavelength: 0.5e-3,
            defocus,
            spherical,
            oversample: None,
        }
    }

    #[test]
    fn strehl_ratio_of_intensities_of_any_scale() {
        // A sum of 1e308s overflowed: the ratio was 0 where it is 1.
        let huge = [1e308; 9];
        assert_eq!(strehl_ratio(&huge, &[1.0; 9]).unwrap(), 1.0);
        let peaked = [1e308, 5e307, 5e307];
        assert!((strehl_ratio(&peaked, &[1.0, 0.5, 0.5]).unwrap() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn smooth_lengths_have_only_small_factors() {
        assert_eq!(smooth_len(7), 8);
        assert_eq!(smooth_len(1001), 1024);
        assert_eq!(smooth_len(243), 243);
    }

    #[test]
    fn psf_sums_to_one_and_is_symmetric() {
        for n in [15, 16] {
            let psf = pupil_psf(&params(n, 0.3, -0.2)).unwrap();
            assert!((psf.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            for y in 0..n {
                for x in 0..n {
                    let (a, b) = (psf[y * n + x], psf[(n - 1 - y) * n + (n - 1 - x)]);
                    assert!((a - b).abs() < 1e-12, "{n}: {a} vs {b} at {y},{x}");
                }
            }
        }
    }

    #[test]
    fn aberration_lowers_the_peak() {
        let sharp = pupil_psf(&params(15, 0.0, 0.0)).unwrap();
        let blurred = pupil_psf(&params(15, 0.0, 0.3)).unwrap();
        let s = strehl_ratio(&blurred, &sharp).unwrap();
        assert!(s > 0.2 && s < 0.9, "{s}");
        assert_eq!(strehl_ratio(&sharp, &sharp).unwrap(), 1.0);
    }

    #[test]
    fn the_default_sampling_integrates_a_pixel_to_within_a_percent() {
        // Pixels a quarter of lambda N wide, against sub-samples lambda N / 32
        // apart (the midpoint rule's error falls as the spacing squared).
        let sharp = params(9, 0.0, 0.0);
        let fine = pupil_psf(&PupilPsf {
            oversample: Some(8),
            ..sharp
        })
        .unwrap();
        let default = pupil_psf(&sharp).unwrap();
        let excess = default[40] / fine[40] - 1.0;
        assert!(
            excess.abs() < 0.007,
            "peak {excess:+.4} off the pixel integral"
        );
    }

    #[test]
    fn bad_sampling_is_refused_with_the_reason() {
        let mut p = params(15, 0.0, 0.0);
        p.oversample = Some(1);
        p.pixel_pitch = 2e-3;
        let err = pupil_psf(&p).unwrap_err().to_string();
        assert!(err.contains("aliases"), "{err}");
        let err = pupil_psf(&params(15, 0.0, 5000.0)).unwrap_err().to_string();
        assert!(err.contains("FFT of"), "{err}");
        assert!(pupil_psf(&params(0, 0.0, 0.0)).is_err());
        assert!(strehl_ratio(&[1.0], &[1.0, 0.0]).is_err());
        assert!(strehl_ratio(&[f64::NAN], &[1.0]).is_err());
    }
}

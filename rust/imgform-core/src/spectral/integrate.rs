//! Integration of spectral images against channel responses.
//!
//! A channel's response `r_c(λ_l)` already holds everything that multiplies
//! the radiance under the integral (quantum efficiency, filter and IR-cut
//! transmittances, photon conversion, the quadrature weight of the sample),
//! so a channel's value is `Σ_l L(λ_l) r_c(λ_l)`: one dot product.

use super::{all_valid, bands_first_bad, dot};
use crate::error::{CoreError, Result};
use crate::invalid;
use crate::parallel::ROWS_PER_TASK;

/// Checks a `(channels, grid_len)` response table: finite and >= 0 (a
/// transmittance or quantum efficiency cannot be negative).
///
/// # Errors
/// [`CoreError::Shape`] for a table of the wrong size,
/// [`CoreError::InvalidArgument`] naming the first bad entry.
pub fn check_response(response: &[f64], channels: usize, grid_len: usize) -> Result<()> {
    if grid_len == 0 {
        // The kernels walk spectra in chunks of the grid: of none, a panic.
        return Err(invalid!(
            "a spectral grid needs at least one wavelength, got none"
        ));
    }
    if channels == 0 || response.len() != channels * grid_len {
        return Err(CoreError::Shape(format!(
            "the response must be {channels} channels x {grid_len} wavelengths = {} values, \
             got {}",
            channels * grid_len,
            response.len()
        )));
    }
    match response.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
        None => Ok(()),
        Some(i) => Err(invalid!(
            "the spectral response must be finite and >= 0, channel {} at wavelength index {} \
             is {}",
            i / grid_len,
            i % grid_len,
            response[i]
        )),
    }
}

/// The error for a pixel with a negative, NaN or infinite spectral sample.
pub(crate) fn bad_pixel(what: &str, pixel: usize, width: usize) -> CoreError {
    invalid!(
        "{what} must be finite and >= 0 at every wavelength; pixel (row {}, column {}) is not",
        pixel / width,
        pixel % width
    )
}

/// Integrates a spectral image `(height, width, grid_len)` (float32, row
/// major) against `channels` responses `(channels, grid_len)` into `out`
/// `(height, width, channels)`, accumulating in f64.
///
/// # Errors
/// Mismatched lengths ([`CoreError::Shape`]); a bad response, or a pixel with
/// a negative or non-finite sample ([`CoreError::InvalidArgument`], naming the
/// first such pixel in row-major order).
pub fn integrate(
    spectra: &[f32],
    width: usize,
    height: usize,
    grid_len: usize,
    response: &[f64],
    channels: usize,
    out: &mut [f32],
) -> Result<()> {
    check_response(response, channels, grid_len)?;
    let pixels = width * height;
    if spectra.len() != pixels * grid_len || out.len() != pixels * channels {
        return Err(CoreError::Shape(format!(
            "a {height} x {width} image of {grid_len} wavelengths needs {} samples and {} \
             outputs, got {} and {}",
            pixels * grid_len,
            pixels * channels,
            spectra.len(),
            out.len()
        )));
    }
    let bad = bands_first_bad(out, width * channels, ROWS_PER_TASK, |y0, rows| {
        let src = &spectra[y0 * width * grid_len..];
        let mut first_bad = None;
        for (i, (px, o)) in src
            .chunks_exact(grid_len)
            .zip(rows.chunks_exact_mut(channels))
            .enumerate()
        {
            if !all_valid(px) {
                first_bad = first_bad.or(Some(y0 * width + i));
            }
            for (v, r) in o.iter_mut().zip(response.chunks_exact(grid_len)) {
                *v = dot(px, r) as f32;
            }
        }
        first_bad
    });
    match bad {
        None => Ok(()),
        Some(p) => Err(bad_pixel("spectra", p, width)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_channel_is_the_weighted_sum_of_its_pixel() {
        // 2 x 3 pixels, 5 wavelengths, 2 channels; pixel p holds p + l.
        let (w, h, l) = (3, 2, 5);
        let spectra: Vec<f32> = (0..w * h * l).map(|i| (i / l + i % l) as f32).collect();
        let response = [1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.0];
        let mut out = vec![0.0f32; w * h * 2];
        integrate(&spectra, w, h, l, &response, 2, &mut out).unwrap();
        for p in 0..w * h {
            // Σ (p + l) over l = 5p + 10; twice the middle sample = 2 (p + 2).
            assert_eq!(out[2 * p], (5 * p + 10) as f32);
            assert_eq!(out[2 * p + 1], (2 * (p + 2)) as f32);
        }
    }

    #[test]
    fn bad_samples_and_sizes_are_refused_by_name() {
        let mut spectra = vec![1.0f32; 20 * 10 * 4];
        spectra[(13 * 10 + 7) * 4 + 2] = -0.5;
        spectra[(17 * 10) * 4] = f32::NAN;
        let mut out = vec![0.0f32; 20 * 10];
        let err = integrate(&spectra, 10, 20, 4, &[1.0; 4], 1, &mut out).unwrap_err();
        assert!(err.to_string().contains("row 13, column 7"), "{err}");
        let err = integrate(&spectra, 10, 20, 4, &[1.0; 3], 1, &mut out).unwrap_err();
        assert!(matches!(err, CoreError::Shape(_)), "{err}");
        let err = integrate(&spectra, 10, 20, 4, &[1.0, -1.0, 0.0, 0.0], 1, &mut out);
        assert!(err
            .unwrap_err()
            .to_string()
            .contains("channel 0 at wavelength index 1"));
        // No wavelength: chunks of none panicked.
        let err = integrate(&[], 10, 20, 0, &[], 1, &mut out).unwrap_err();
        assert!(err.to_string().contains("at least one wavelength"), "{err}");
    }
}

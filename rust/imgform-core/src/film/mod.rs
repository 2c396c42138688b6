//! Colour film: exposure, development, dyes and printing, per pixel.
//!
//! A film stock has `n` emulsion layers. Each layer turns its exposure `H`
//! into a dye amount through its characteristic curve `D = f(log10 H)`
//! ([`curve`]); development inhibitor releasing (DIR) couplers lower a
//! layer's effective exposure by what its neighbours developed, diffused
//! sideways ([`develop`], [`diffuse`]). The developed layers' dyes absorb by
//! Beer-Lambert, so the film's spectral optical density is linear in the dye
//! amounts and its transmittance is `10^-D(λ)`; integrating that against a
//! set of spectral responses (a printing paper's layers under an enlarger
//! lamp, or the CIE observer under a viewing light) is [`transmit`].
//!
//! The Python layer (`imgform_rs.film`) holds the stock data, builds the
//! responses and chains the steps; these kernels only do the per-pixel work.
//! None of them draws random numbers, so every output is a pure function of
//! the input and identical for any number of threads.

pub mod curve;
pub mod develop;
pub mod diffuse;
pub mod fastmath;
pub mod grain;
pub mod halation;
pub mod inhibit;
pub mod print;
pub mod transmit;

use rayon::prelude::*;

use crate::error::{all_valid, is_valid_sample, CoreError};
use crate::invalid;

/// Samples per task of [`check_samples`].
const CHECK_BLOCK: usize = 1 << 14;

/// The error for the first sample of an `(H, W, C)` buffer that is not a
/// finite number >= 0, or `Ok` when every sample is.
///
/// Every sample is valid in the common case, so each block is scanned by
/// [`all_valid`]'s packed compares with no branch per sample (a per-sample
/// `position_first` cost as much as the kernels it guards);
/// only a block holding a bad sample is searched for it, and taking the
/// first such block names the same pixel for any thread count.
fn check_samples(what: &str, data: &[f32], width: usize, channels: usize) -> Result<(), CoreError> {
    let first = data
        .par_chunks(CHECK_BLOCK)
        .position_first(|block| !all_valid(block))
        .and_then(|k| {
            let start = k * CHECK_BLOCK;
            data[start..]
                .iter()
                .position(|v| !is_valid_sample(*v))
                .map(|i| start + i)
        });
    match first {
        None => Ok(()),
        Some(i) => {
            let pixel = i / channels;
            Err(invalid!(
                "{what} must be finite and >= 0; pixel (row {}, column {}), channel {} is {}",
                pixel / width,
                pixel % width,
                i % channels,
                data[i]
            ))
        }
    }
}

/// Checks that an `(H, W, C)` buffer and its output have the lengths the
/// dimensions say.
fn check_lengths(
    width: usize,
    height: usize,
    (input, in_channels): (&[f32], usize),
    (out, out_channels): (&[f32], usize),
) -> Result<(), CoreError> {
    let pixels = width * height;
    if pixels == 0 || in_channels == 0 || out_channels == 0 {
        return Err(CoreError::Shape(format!(
            "an image of {height} x {width} pixels, {in_channels} channels in and \
             {out_channels} out: every dimension must be > 0"
        )));
    }
    if input.len() != pixels * in_channels || out.len() != pixels * out_channels {
        return Err(CoreError::Shape(format!(
            "a {height} x {width} image needs {} input and {} output samples, got {} and {}",
            pixels * in_channels,
            pixels * out_channels,
            input.len(),
            out.len()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_bad_sample_is_named_by_row_column_and_channel() {
        let mut data = vec![0.5f32; 4 * 5 * 3];
        data[(2 * 5 + 3) * 3 + 1] = -1.0;
        data[(3 * 5) * 3] = f32::NAN;
        let err = check_samples("exposure", &data, 5, 3)
            .unwrap_err()
            .to_string();
        assert!(err.contains("row 2, column 3), channel 1 is -1"), "{err}");
        assert!(check_samples("exposure", &[0.0, 1.0], 1, 2).is_ok());
        // Past the first block, and the first of two blocks holding one.
        let mut long = vec![1.0f32; 5 * CHECK_BLOCK];
        long[3 * CHECK_BLOCK + 7] = f32::INFINITY;
        long[4 * CHECK_BLOCK] = -0.0 - 1e-30;
        let err = check_samples("density", &long, 1, 1)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(&format!("row {}", 3 * CHECK_BLOCK + 7)),
            "{err}"
        );
        long[3 * CHECK_BLOCK + 7] = f32::MAX;
        let err = check_samples("density", &long, 1, 1)
            .unwrap_err()
            .to_string();
        assert!(err.contains(&format!("row {}", 4 * CHECK_BLOCK)), "{err}");
    }

    #[test]
    fn lengths_must_agree_with_the_dimensions() {
        let a = [0.0f32; 6];
        assert!(check_lengths(2, 1, (&a, 3), (&a, 3)).is_ok());
        assert!(check_lengths(2, 1, (&a, 3), (&a[..5], 3)).is_err());
        assert!(check_lengths(0, 1, (&[], 3), (&[], 3)).is_err());
    }
}

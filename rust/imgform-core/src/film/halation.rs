//! Halation: light scattered back into the emulsion from the film base.
//!
//! Light that crosses the emulsion is partly reflected at the back of the
//! base and returns, spread over a wide disc, into the layer nearest the
//! base first: the red-sensitive one, which is why halation glows red
//! around highlights. A fraction `a_i` of each layer's exposure is
//! redistributed by a normalised Gaussian of the spread `σ`,
//!
//! `H'_i = (1 - a_i) H_i + a_i G_σ * H_i`,
//!
//! which keeps the total exposure (energy) of the frame: the blur's taps
//! sum to 1 and its mirrored edges fold what would leave the frame back in.

use super::check_lengths;
use super::diffuse::{blur_columns_then, blur_rows, gaussian_taps};
use super::fastmath::wide;
use crate::error::Result;
use crate::invalid;

/// Halation of per-layer strengths and one spread, validated once.
#[derive(Debug, Clone)]
pub struct Halation {
    strength: Vec<f32>,
    taps: Vec<f32>,
}

impl Halation {
    /// Strengths `strength` (one per layer, in `[0, 1]`) and spread `sigma`
    /// (pixels).
    ///
    /// # Errors
    /// [`crate::CoreError::InvalidArgument`] for a strength outside
    /// `[0, 1]` or a spread that is not > 0.
    pub fn new(strength: &[f64], sigma: f64) -> Result<Self> {
        if let Some(i) = strength.iter().position(|a| !(0.0..=1.0).contains(a)) {
            return Err(invalid!(
                "halation strengths are fractions in [0, 1], layer {i} has {}",
                strength[i]
            ));
        }
        Ok(Self {
            strength: strength.iter().map(|&a| a as f32).collect(),
            taps: gaussian_taps(sigma, "the halation spread")?,
        })
    }

    /// Number of layers.
    pub fn layers(&self) -> usize {
        self.strength.len()
    }

    /// Applies the halation to exposures `(height, width, layers)` (sizes
    /// checked by the caller) into `out`, handing each row of `out` to
    /// `finish(y, row)` once it holds the halated exposures: development
    /// takes their logarithms there while the row is in cache. `scratch`,
    /// as long as `exposure`, takes the blur's row pass; development reuses
    /// it for the couplers' diffusion rather than fault in another
    /// full-size image (the kernel zeroes each fresh page: 15 % of the time
    /// of a development that wrote four such images).
    pub(crate) fn apply_then<F>(
        &self,
        exposure: &[f32],
        (width, height): (usize, usize),
        scratch: &mut [f32],
        out: &mut [f32],
        finish: F,
    ) where
        F: Fn(usize, &mut [f32]) + Sync,
    {
        let n = self.layers();
        blur_rows(exposure, width, n, &self.taps, scratch);
        // The strengths repeated along a row, so that mixing is one plain
        // loop over the row's samples (packed), not one over pixels and
        // their `n` layers.
        let a: Vec<f32> = self
            .strength
            .iter()
            .copied()
            .cycle()
            .take(width * n)
            .collect();
        blur_columns_then(
            scratch,
            width,
            height,
            n,
            &self.taps,
            out,
            width * n,
            |y, blurred, row| {
                mix_wide(&a, &exposure[y * width * n..][..width * n], blurred, row);
                finish(y, row);
            },
        );
    }
}

wide!(
    /// [`mix`], 8 lanes wide where the CPU has them.
    fn mix_wide = mix(strength: &[f32], exposure: &[f32], blurred: &[f32], out: &mut [f32])
);

/// `out = (1 - a) H + a G * H` sample by sample, `strength` holding `a`.
#[inline(always)]
fn mix(strength: &[f32], exposure: &[f32], blurred: &[f32], out: &mut [f32]) {
    for (((v, a), h), g) in out.iter_mut().zip(strength).zip(exposure).zip(blurred) {
        *v = (1.0 - a) * h + a * g;
    }
}

/// Applies halation of strengths `strength` (one per layer, in `[0, 1]`) and
/// spread `sigma` (pixels) to exposures `(height, width, layers)`.
///
/// # Errors
/// [`crate::CoreError::Shape`] for mismatched sizes; [`crate::CoreError::InvalidArgument`]
/// for a strength outside `[0, 1]` or a spread that is not > 0.
pub fn halation(
    exposure: &[f32],
    width: usize,
    height: usize,
    strength: &[f64],
    sigma: f64,
    out: &mut [f32],
) -> Result<()> {
    check_lengths(
        width,
        height,
        (exposure, strength.len()),
        (out, strength.len()),
    )?;
    let mut scratch = vec![0.0f32; exposure.len()];
    Halation::new(strength, sigma)?.apply_then(
        exposure,
        (width, height),
        &mut scratch,
        out,
        |_, _| (),
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::CoreError;

    #[test]
    fn a_point_of_light_keeps_its_energy_and_glows_by_strength() {
        let (w, h) = (61, 61);
        let mut ex = vec![0.0f32; w * h * 3];
        let c = (30 * w + 30) * 3;
        ex[c..c + 3].copy_from_slice(&[1.0, 1.0, 1.0]);
        let mut out = vec![0.0; ex.len()];
        halation(&ex, w, h, &[0.2, 0.05, 0.0], 4.0, &mut out).unwrap();
        // The point keeps 1 - a and gets back a times the blur's centre tap
        // squared (rows, then columns).
        let centre = gaussian_taps(4.0, "sigma").unwrap()[0].powi(2);
        for (i, a) in [0.2f32, 0.05, 0.0].iter().enumerate() {
            let total: f32 = out.iter().skip(i).step_by(3).sum();
            assert!((total - 1.0).abs() < 1e-5, "{i}: {total}");
            assert!((out[c + i] - (1.0 - a + a * centre)).abs() < 1e-6, "{i}");
        }
        // Red (first) glows most, blue not at all, 5 px from the point.
        let near = ((30 * w) + 35) * 3;
        assert!(out[near] > out[near + 1] && out[near + 2] == 0.0);
    }

    #[test]
    fn bad_strengths_and_spreads_are_refused() {
        let mut out = [0.0f32; 2];
        assert!(halation(&[1.0, 1.0], 2, 1, &[1.5], 2.0, &mut out).is_err());
        assert!(halation(&[1.0, 1.0], 2, 1, &[0.5], 0.0, &mut out).is_err());
        assert!(matches!(
            halation(&[1.0], 2, 1, &[0.5], 1.0, &mut out),
            Err(CoreError::Shape(_))
        ));
    }
}

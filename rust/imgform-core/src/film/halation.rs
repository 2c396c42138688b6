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
use super::diffuse::{blur, gaussian_taps};
use crate::error::Result;
use crate::invalid;
use crate::parallel::for_each_row;

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
    let n = strength.len();
    check_lengths(width, height, (exposure, n), (out, n))?;
    if let Some(i) = strength.iter().position(|a| !(0.0..=1.0).contains(a)) {
        return Err(invalid!(
            "halation strengths are fractions in [0, 1], layer {i} has {}",
            strength[i]
        ));
    }
    crate::error::positive("the halation spread (pixels)", sigma)?;
    blur(exposure, width, height, n, &gaussian_taps(sigma), out);
    let a: Vec<f32> = strength.iter().map(|&a| a as f32).collect();
    for_each_row(out, width * n, |y, row| {
        let src = &exposure[y * width * n..][..width * n];
        for (p, o) in src.chunks_exact(n).zip(row.chunks_exact_mut(n)) {
            for ((v, h), a) in o.iter_mut().zip(p).zip(&a) {
                *v = (1.0 - a) * h + a * *v;
            }
        }
    });
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
        let centre = gaussian_taps(4.0)[0].powi(2);
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

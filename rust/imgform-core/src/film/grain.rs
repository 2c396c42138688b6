//! Grain: developed density as a Poisson count of grains.
//!
//! A layer's density in a pixel is the sum of the densities of the grains
//! (silver or dye clouds) that developed there. With grains that each add
//! `g` to the pixel's density and develop independently, their number is
//! Poisson with mean `D / g`, so the grainy density `g k` has mean `D` and
//! variance `g D`: the RMS granularity at density 1 is `sqrt(g)`, the
//! stock parameter from which `g` follows (Nutting's law, `D` proportional
//! to the grains' covered area; the Poisson model of grain of Selwyn, 1935).
//! Each pixel draws from a generator seeded by `(seed, y, x)` alone, so the
//! grain is the same for any thread count.

use super::{check_lengths, check_samples};
use crate::error::Result;
use crate::invalid;
use crate::parallel::for_each_row;
use crate::random::SplitMix64;

/// Replaces the densities `(height, width, layers)` by grain counts times
/// `per_grain[i]`, the density one grain of layer `i` adds to a pixel (0
/// leaves a layer smooth).
///
/// # Errors
/// [`crate::CoreError::Shape`] for mismatched sizes; [`crate::CoreError::InvalidArgument`]
/// for a negative or non-finite grain density or density.
pub fn add_grain(
    density: &[f32],
    width: usize,
    height: usize,
    per_grain: &[f64],
    seed: u64,
    out: &mut [f32],
) -> Result<()> {
    let n = per_grain.len();
    check_lengths(width, height, (density, n), (out, n))?;
    if let Some(i) = per_grain.iter().position(|g| !(g.is_finite() && *g >= 0.0)) {
        return Err(invalid!(
            "the density of a grain must be finite and >= 0, layer {i} has {}",
            per_grain[i]
        ));
    }
    check_samples("densities", density, width, n)?;
    for_each_row(out, width * n, |y, row| {
        let key = SplitMix64::row_key(seed, y);
        let src = &density[y * width * n..][..width * n];
        for (x, (d, o)) in src.chunks_exact(n).zip(row.chunks_exact_mut(n)).enumerate() {
            let mut rng = SplitMix64::in_row(key, x);
            for ((v, &d), &g) in o.iter_mut().zip(d).zip(per_grain) {
                *v = if g > 0.0 {
                    (g * rng.poisson(f64::from(d) / g)) as f32
                } else {
                    d
                };
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
    fn granularity_at_density_one_is_the_root_of_the_grain_density() {
        let (w, h) = (200, 100);
        let density = vec![1.0f32; w * h * 2];
        let mut out = vec![0.0; density.len()];
        add_grain(&density, w, h, &[1e-4, 0.0], 7, &mut out).unwrap();
        let grainy: Vec<f64> = out.iter().step_by(2).map(|&v| f64::from(v)).collect();
        let mean = grainy.iter().sum::<f64>() / grainy.len() as f64;
        let rms =
            (grainy.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / grainy.len() as f64).sqrt();
        assert!((mean - 1.0).abs() < 1e-3, "{mean}");
        assert!((rms / 0.01 - 1.0).abs() < 0.03, "{rms}");
        assert!(out.iter().skip(1).step_by(2).all(|&v| v == 1.0));
    }

    #[test]
    fn bad_grain_densities_are_refused() {
        let mut out = [0.0f32; 2];
        assert!(add_grain(&[1.0, 1.0], 2, 1, &[-1e-3], 0, &mut out).is_err());
        assert!(add_grain(&[1.0, -1.0], 2, 1, &[1e-3], 0, &mut out).is_err());
        assert!(matches!(
            add_grain(&[1.0], 2, 1, &[1e-3], 0, &mut out),
            Err(CoreError::Shape(_))
        ));
    }
}

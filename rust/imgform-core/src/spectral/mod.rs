//! Spectral image formation: light, not RGB, from the scene to the raw.
//!
//! A scene is spectral radiance sampled on a wavelength grid ([`grid`]); a
//! camera channel sees it through its spectral response (quantum efficiency
//! x colour filter x IR-cut filter, times the grid's quadrature weights), so
//! its signal is one dot product per pixel ([`integrate`]). The sensor turns
//! that mean signal into electrons and digital numbers with exact Poisson
//! shot noise and the usual fixed-pattern and read-out defects ([`sensor`]),
//! and [`ptc`] measures a sensor back from flat fields, as EMVA 1288 does
//! for a real one.
//!
//! Every random number comes from a generator seeded by the pixel's
//! coordinates and a seed alone, so a capture is the same for any number of
//! threads.

mod ahead;
mod cfa_rates;
pub mod falloff;
pub mod grid;
pub mod integrate;
pub mod ptc;
pub mod sensor;

use rayon::prelude::*;

pub(crate) use crate::cpu::has_avx2_fma;
pub(crate) use crate::error::{all_valid, is_valid_sample};

/// Runs `kernel(first_row, rows)` over bands of `band_rows` rows of `out`
/// (rows of `row_len` elements) in parallel. Each band returns the index of
/// its first bad input, if any; the smallest over all bands is returned, so
/// error messages name the same pixel for any thread count.
fn bands_first_bad<T, F>(
    out: &mut [T],
    row_len: usize,
    band_rows: usize,
    kernel: F,
) -> Option<usize>
where
    T: Send,
    F: Fn(usize, &mut [T]) -> Option<usize> + Sync,
{
    if row_len == 0 {
        return None;
    }
    out.par_chunks_mut(row_len * band_rows)
        .enumerate()
        .filter_map(|(band, rows)| kernel(band * band_rows, rows))
        .min()
}

/// `Σ x_i w_i` in f64, with four partial sums so the loop vectorises; the
/// summation order depends only on the length, never on the caller.
#[inline(always)]
fn dot(x: &[f32], w: &[f64]) -> f64 {
    let xs = x.chunks_exact(4);
    let ws = w.chunks_exact(4);
    let tail: f64 = xs
        .remainder()
        .iter()
        .zip(ws.remainder())
        .map(|(a, b)| f64::from(*a) * b)
        .sum();
    let mut acc = [0.0f64; 4];
    for (a, b) in xs.zip(ws) {
        for i in 0..4 {
            acc[i] += f64::from(a[i]) * b[i];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dot_matches_the_plain_sum_for_every_tail_length() {
        for n in 0..11 {
            let x: Vec<f32> = (0..n).map(|i| i as f32 + 0.5).collect();
            let w: Vec<f64> = (0..n).map(|i| 1.0 / (i as f64 + 1.0)).collect();
            let want: f64 = x.iter().zip(&w).map(|(a, b)| f64::from(*a) * b).sum();
            assert!((dot(&x, &w) - want).abs() < 1e-12, "{n}");
        }
    }

    #[test]
    fn the_first_bad_band_is_reported_whatever_the_order() {
        let mut out = vec![0u8; 5 * 100];
        let bad = bands_first_bad(&mut out, 5, 8, |y0, _| (y0 >= 40).then_some(y0 * 5 + 3));
        assert_eq!(bad, Some(40 * 5 + 3));
    }
}

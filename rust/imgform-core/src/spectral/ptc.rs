//! Photon-transfer statistics of flat-field frame pairs (EMVA 1288).
//!
//! Two frames `a`, `b` of the same flat field share their fixed patterns, so
//! their difference holds temporal noise only: `σ² = var(a - b) / 2`. Their
//! mean holds the fixed pattern plus half the temporal noise. The sums are
//! taken in exact integer arithmetic, so the statistics are the same for any
//! thread count and any summation order.

use rayon::prelude::*;

use crate::error::{CoreError, Result};

/// Pixels per rayon task: ~0.1 ms of integer sums.
const PIXELS_PER_TASK: usize = 64 * 1024;

/// Mean and variances of a pair of frames of one flat field, in DN.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairStats {
    /// Number of pixels per frame.
    pub pixels: usize,
    /// Mean of both frames.
    pub mean: f64,
    /// Temporal variance: `Σ ((a - b) - mean(a - b))² / (2 N)`, EMVA 1288's
    /// estimator (each frame's variance over time, from their difference).
    pub temporal_variance: f64,
    /// Spatial variance of the pair's mean image `(a + b) / 2` over the
    /// pixels (its fixed pattern plus half the temporal variance).
    pub spatial_variance: f64,
}

#[derive(Default, Clone, Copy)]
struct Sums {
    sum: u128,
    sum_d: i128,
    sum_d2: u128,
    sum_s2: u128,
}

impl Sums {
    fn add(self, o: Self) -> Self {
        Self {
            sum: self.sum + o.sum,
            sum_d: self.sum_d + o.sum_d,
            sum_d2: self.sum_d2 + o.sum_d2,
            sum_s2: self.sum_s2 + o.sum_s2,
        }
    }
}

/// [`PairStats`] of two frames of equal size.
///
/// # Errors
/// [`CoreError::Shape`] for frames of different or zero lengths.
pub fn pair_stats(a: &[u16], b: &[u16]) -> Result<PairStats> {
    if a.len() != b.len() || a.is_empty() {
        return Err(CoreError::Shape(format!(
            "a flat-field pair needs two non-empty frames of one size, got {} and {} pixels",
            a.len(),
            b.len()
        )));
    }
    let sums = a
        .par_chunks(PIXELS_PER_TASK)
        .zip(b.par_chunks(PIXELS_PER_TASK))
        .map(|(ca, cb)| {
            // Per-chunk sums fit in u64 (65535² x 2 x 64 Ki < 2^50).
            let (mut s, mut d, mut d2, mut s2) = (0u64, 0i64, 0u64, 0u64);
            for (&x, &y) in ca.iter().zip(cb) {
                let (x, y) = (u64::from(x), u64::from(y));
                let diff = x as i64 - y as i64;
                s += x + y;
                d += diff;
                d2 += diff.unsigned_abs() * diff.unsigned_abs();
                s2 += (x + y) * (x + y);
            }
            Sums {
                sum: u128::from(s),
                sum_d: i128::from(d),
                sum_d2: u128::from(d2),
                sum_s2: u128::from(s2),
            }
        })
        .reduce(Sums::default, Sums::add);
    let n = a.len() as f64;
    let mean_sum = sums.sum as f64 / n; // mean of a + b
    let mean_d = sums.sum_d as f64 / n;
    let temporal = (sums.sum_d2 as f64 / n - mean_d * mean_d) / 2.0;
    // var((a + b) / 2) = (E[(a + b)²] - E[a + b]²) / 4, with N - 1 for an
    // unbiased estimate of the spatial spread.
    let spatial = (sums.sum_s2 as f64 - n * mean_sum * mean_sum) / (4.0 * (n - 1.0).max(1.0));
    Ok(PairStats {
        pixels: a.len(),
        mean: mean_sum / 2.0,
        temporal_variance: temporal,
        spatial_variance: spatial,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_match_a_direct_computation() {
        let a: Vec<u16> = (0..200_000u64).map(|i| (i * 7919 % 4096) as u16).collect();
        let b: Vec<u16> = (0..200_000u64)
            .map(|i| (i * 104_729 % 4001) as u16)
            .collect();
        let s = pair_stats(&a, &b).unwrap();
        let n = a.len() as f64;
        let fa: Vec<f64> = a.iter().map(|&v| f64::from(v)).collect();
        let fb: Vec<f64> = b.iter().map(|&v| f64::from(v)).collect();
        let mean = (fa.iter().sum::<f64>() + fb.iter().sum::<f64>()) / (2.0 * n);
        let d: Vec<f64> = fa.iter().zip(&fb).map(|(x, y)| x - y).collect();
        let md = d.iter().sum::<f64>() / n;
        let temporal = d.iter().map(|v| (v - md).powi(2)).sum::<f64>() / (2.0 * n);
        let m: Vec<f64> = fa.iter().zip(&fb).map(|(x, y)| (x + y) / 2.0).collect();
        let spatial = m.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        assert!((s.mean - mean).abs() < 1e-9 * mean);
        assert!((s.temporal_variance - temporal).abs() < 1e-9 * temporal);
        assert!((s.spatial_variance - spatial).abs() < 1e-9 * spatial);
        assert!(pair_stats(&a, &b[1..]).is_err());
    }
}

//! DIR inhibition over rows of interleaved layers.
//!
//! Receiver `i` of a pixel loses `Σ_j A_ij q_j` of log exposure, `q` the
//! pixel's blurred donor densities ([`super::develop`]). Pixel by pixel
//! that is an `n x n` matrix product over `n` interleaved samples, which
//! does not vectorise. But sample `k = p n + i` of a row reads donor `j` at
//! `k + (j - i)`, so the product is a sum over the `2n - 1` offsets
//! `d = j - i` of the row shifted by `d` times one coefficient per sample
//! (`A_ij`, or 0 where `j` falls outside the pixel), a pattern that repeats
//! every [`LANES`] pixels: packed multiplies and adds over blocks of `8 n`
//! samples.

use super::fastmath::LANES;

/// A DIR coupler matrix laid out for [`Inhibition::subtract`].
#[derive(Debug, Clone)]
pub struct Inhibition {
    layers: usize,
    /// For each offset `d + n - 1` (`d = j - i`, ascending) the coefficient
    /// of each sample of a block of [`LANES`] pixels.
    coefficients: Vec<f32>,
}

impl Inhibition {
    /// The inhibition of `n x n` `matrix` (row `i` receiving from column
    /// `j`).
    pub fn new(matrix: &[f32], n: usize) -> Self {
        debug_assert_eq!(matrix.len(), n * n);
        let coefficients = (0..2 * n - 1)
            .flat_map(|offset| {
                (0..LANES * n).map(move |k| {
                    let i = k % n;
                    // Donor `j = i + offset - (n - 1)`, if it is in the pixel.
                    match (i + offset).checked_sub(n - 1) {
                        Some(j) if j < n => matrix[i * n + j],
                        _ => 0.0,
                    }
                })
            })
            .collect();
        Self {
            layers: n,
            coefficients,
        }
    }

    /// `row[p n + i] -= Σ_j A_ij near[p n + j]` for every pixel `p` of rows
    /// of `n` interleaved layers. The products are added in the order of
    /// `j`, from -0 as `Iterator::sum` starts, with exact zeros between
    /// them (the other offsets): the bits of a loop over each matrix row.
    #[inline(always)]
    pub fn subtract(&self, near: &[f32], row: &mut [f32]) {
        let reach = self.layers - 1;
        let block_len = LANES * self.layers;
        // A block of `near` with `reach` samples either side for the
        // offsets to read. What they read outside the block (and past a
        // short last block, stale samples) is read with coefficient 0.
        let mut padded = vec![0.0f32; block_len + 2 * reach];
        let mut sum = vec![0.0f32; block_len];
        for (q, v) in near.chunks(block_len).zip(row.chunks_mut(block_len)) {
            padded[reach..][..q.len()].copy_from_slice(q);
            sum.fill(-0.0);
            for (offset, c) in self.coefficients.chunks_exact(block_len).enumerate() {
                for ((s, c), q) in sum.iter_mut().zip(c).zip(&padded[offset..]) {
                    *s += c * q;
                }
            }
            for (v, s) in v.iter_mut().zip(&sum) {
                *v -= s;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shifted_sums_give_the_bits_of_the_matrix_product() {
        for n in [1usize, 2, 3, 4] {
            let matrix: Vec<f32> = (0..n * n).map(|k| 0.013 * (k * k % 7) as f32).collect();
            let inhibition = Inhibition::new(&matrix, n);
            // 19 pixels: two whole blocks and a short one.
            let len = 19 * n;
            let near: Vec<f32> = (0..len).map(|k| ((k * 7919) % 300) as f32 / 97.0).collect();
            let row: Vec<f32> = (0..len).map(|k| 1.0 - (k % 11) as f32 / 3.0).collect();
            let mut got = row.clone();
            inhibition.subtract(&near, &mut got);
            for (k, (g, r)) in got.iter().zip(&row).enumerate() {
                let (p, i) = (k / n, k % n);
                let q = &near[p * n..][..n];
                let s: f32 = matrix[i * n..][..n].iter().zip(q).map(|(a, q)| a * q).sum();
                assert_eq!(g.to_bits(), (r - s).to_bits(), "n {n}, sample {k}");
            }
        }
    }
}

//! Dye densities to spectral transmittance, integrated against responses.
//!
//! Beer-Lambert: each dye absorbs in proportion to its amount, so the
//! developed film's spectral optical density is
//!
//! `D(λ) = b(λ) + Σ_i D_i e_i(λ)`
//!
//! with `b` the base (plus fog and the unformed masking couplers at full
//! strength) and `e_i` the spectral density of layer `i`'s dye per unit of
//! its analytical density (less its masking coupler's, which the dye
//! replaces as it forms). The light a response `R_k` sees through it is
//! `Σ_λ 10^-D(λ) R_k(λ)`: the printing paper's layers under an enlarger lamp
//! or the CIE observer under a viewing light, quadrature weights included.

use super::fastmath::{exp2, wide};
use super::{check_lengths, check_samples};
use crate::error::{all_finite, CoreError, Result};
use crate::invalid;
use crate::parallel::for_each_band;
use crate::parallel::ROWS_PER_TASK;

/// The spectra are stored padded to whole groups of this many wavelengths,
/// an AVX2 register of f32: the padding's exponent is 0 and its response 0,
/// so it adds exactly nothing, and the loops need no tail.
const LANES: usize = 8;

/// The spectral model of one developed film: base density and the dyes'
/// spectral densities on a grid of `grid_len` wavelengths.
#[derive(Debug, Clone)]
pub struct Dyes {
    grid_len: usize,
    /// `-log2(10) b(λ)`, so that the transmittance is `2^(base + Σ D_i dye_i)`,
    /// padded to a multiple of [`LANES`].
    base: Vec<f32>,
    /// `-log2(10) e_i(λ)`, layer-major, each layer padded as `base`.
    dyes: Vec<f32>,
}

impl Dyes {
    /// Dyes of `dyes.len() / base.len()` layers.
    ///
    /// # Errors
    /// [`CoreError::Shape`] when `dyes` is not a whole number of spectra of
    /// `base.len()` samples; [`CoreError::InvalidArgument`] for a
    /// non-finite sample or a negative base density.
    pub fn new(base: &[f64], dyes: &[f64]) -> Result<Self> {
        let l = base.len();
        if l == 0 || dyes.is_empty() || dyes.len() % l != 0 {
            return Err(CoreError::Shape(format!(
                "the dye spectra must be (layers, {l}) for a base of {l} wavelengths, got {} \
                 values",
                dyes.len()
            )));
        }
        all_finite("the base density", base)?;
        all_finite("the dye densities", dyes)?;
        if let Some(i) = base.iter().position(|b| *b < 0.0) {
            return Err(invalid!(
                "the base density must be >= 0, wavelength index {i} is {}",
                base[i]
            ));
        }
        let scale = |d: f64| (-d * std::f64::consts::LOG2_10) as f32;
        Ok(Self {
            grid_len: l,
            base: padded(base, l, scale),
            dyes: padded(dyes, l, scale),
        })
    }

    /// Number of dye layers.
    pub fn layers(&self) -> usize {
        self.dyes.len() / self.lanes()
    }

    /// Number of wavelengths.
    pub fn grid_len(&self) -> usize {
        self.grid_len
    }

    /// The padded length of one spectrum.
    fn lanes(&self) -> usize {
        self.base.len()
    }

    /// `out (H, W, m) = Σ_λ 10^-D(λ) R_k(λ)` for densities `(H, W, layers)`
    /// and responses `(m, grid_len)`.
    ///
    /// # Errors
    /// [`CoreError::Shape`] for mismatched sizes;
    /// [`CoreError::InvalidArgument`] for non-finite responses or densities,
    /// or negative densities (the first one named).
    pub fn transmit(
        &self,
        density: &[f32],
        width: usize,
        height: usize,
        response: &[f64],
        out: &mut [f32],
    ) -> Result<()> {
        self.transmit_then(density, width, height, response, out, |_| ())
    }

    /// [`Dyes::transmit`], handing each row of its output to `finish`, which
    /// may rewrite it in place while it is in cache (printing develops the
    /// paper's exposures there).
    ///
    /// # Errors
    /// As [`Dyes::transmit`].
    pub fn transmit_then<F>(
        &self,
        density: &[f32],
        width: usize,
        height: usize,
        response: &[f64],
        out: &mut [f32],
        finish: F,
    ) -> Result<()>
    where
        F: Fn(&mut [f32]) + Sync,
    {
        let (n, l) = (self.layers(), self.grid_len);
        if response.is_empty() || response.len() % l != 0 {
            return Err(CoreError::Shape(format!(
                "the responses must be (m, {l}), one sample per wavelength, got {} values",
                response.len()
            )));
        }
        all_finite("the responses", response)?;
        let m = response.len() / l;
        check_lengths(width, height, (density, n), (out, m))?;
        check_samples("densities", density, width, n)?;
        let resp = padded(response, l, |r| r as f32);
        for_each_band(out, width * m, ROWS_PER_TASK, |y0, rows| {
            // The spectrum of one pixel, reused for every pixel of the band.
            let mut t = vec![0.0f32; self.lanes()];
            for (i, row) in rows.chunks_mut(width * m).enumerate() {
                let src = &density[(y0 + i) * width * n..][..width * n];
                transmit_row_wide(self, src, &resp, &mut t, row);
                finish(row);
            }
        });
        Ok(())
    }

    /// One pixel of [`Dyes::transmit`]: the spectrum `t = 2^(base + Σ D_i
    /// dye_i)` and its dot with each response, summed in [`LANES`] partial
    /// sums (fixed order: the same bits on every path and thread).
    #[inline(always)]
    fn pixel(&self, density: &[f32], response: &[f32], t: &mut [f32], out: &mut [f32]) {
        let lanes = self.lanes();
        t.copy_from_slice(&self.base);
        for (di, e) in density.iter().zip(self.dyes.chunks_exact(lanes)) {
            t.iter_mut().zip(e).for_each(|(v, e)| *v += di * e);
        }
        t.iter_mut().for_each(|v| *v = exp2(*v));
        for (v, r) in out.iter_mut().zip(response.chunks_exact(lanes)) {
            let mut acc = [0.0f32; LANES];
            for (a, b) in t.chunks_exact(LANES).zip(r.chunks_exact(LANES)) {
                for j in 0..LANES {
                    acc[j] += a[j] * b[j];
                }
            }
            *v = ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]));
        }
    }
}

wide!(
    /// [`transmit_row`], 8 lanes wide where the CPU has them.
    fn transmit_row_wide = transmit_row(
        dyes: &Dyes,
        density: &[f32],
        response: &[f32],
        t: &mut [f32],
        out: &mut [f32],
    )
);

/// The pixels of one row through [`Dyes::pixel`]; `out` holds
/// `response.len() / lanes` values per pixel.
#[inline(always)]
fn transmit_row(dyes: &Dyes, density: &[f32], response: &[f32], t: &mut [f32], out: &mut [f32]) {
    let m = response.len() / dyes.lanes();
    for (d, o) in density
        .chunks_exact(dyes.layers())
        .zip(out.chunks_exact_mut(m))
    {
        dyes.pixel(d, response, t, o);
    }
}

/// Spectra of `l` samples (`values` holds a whole number of them) mapped by
/// `f` and padded with zeros to a multiple of [`LANES`] each.
fn padded(values: &[f64], l: usize, f: impl Fn(f64) -> f32) -> Vec<f32> {
    let lanes = l.div_ceil(LANES) * LANES;
    values
        .chunks_exact(l)
        .flat_map(|s| {
            s.iter()
                .map(|&v| f(v))
                .chain(std::iter::repeat(0.0))
                .take(lanes)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transmittance_follows_beer_lambert() {
        // 3 wavelengths, 2 dyes; the identity response returns 10^-D(λ).
        let dyes = Dyes::new(&[0.1, 0.0, 0.2], &[1.0, 0.5, 0.0, 0.0, 0.2, 1.0]).unwrap();
        let identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let density = [0.3f32, 0.7, 0.0, 0.0];
        let mut out = [0.0f32; 6];
        dyes.transmit(&density, 2, 1, &identity, &mut out).unwrap();
        let want = [0.1 + 0.3, 0.15 + 0.14, 0.2 + 0.7, 0.1, 0.0, 0.2];
        for (o, d) in out.iter().zip(want) {
            assert!((f64::from(*o) - 10f64.powf(-d)).abs() < 1e-6, "{o} {d}");
        }
        // A response sums the weighted transmittance.
        let mut sum = [0.0f32; 2];
        dyes.transmit(&density, 2, 1, &[1.0, 2.0, 3.0], &mut sum)
            .unwrap();
        assert!((sum[1] - (10f32.powf(-0.1) + 2.0 + 3.0 * 10f32.powf(-0.2))).abs() < 1e-5);
    }

    #[test]
    fn the_wide_pixel_gives_the_plain_bits_and_padding_adds_nothing() {
        // 41 wavelengths (padded to 48), 3 dyes, 3 responses.
        let l = 41;
        let spectrum = |k: usize| -> Vec<f64> {
            (0..l)
                .map(|i| 0.05 + ((i * 13 + k * 7) % 17) as f64 / 20.0)
                .collect()
        };
        let base = spectrum(0);
        let dyes: Vec<f64> = (1..4).flat_map(spectrum).collect();
        let response: Vec<f64> = (4..7).flat_map(spectrum).collect();
        let model = Dyes::new(&base, &dyes).unwrap();
        let resp = padded(&response, l, |r| r as f32);
        let density = [0.3f32, 1.7, 0.9];
        let mut t = vec![0.0; model.lanes()];
        let (mut plain, mut wide_px) = ([0.0f32; 3], [0.0f32; 3]);
        transmit_row(&model, &density, &resp, &mut t, &mut plain);
        transmit_row_wide(&model, &density, &resp, &mut t, &mut wide_px);
        assert_eq!(plain, wide_px);
        for (k, got) in plain.iter().enumerate() {
            let want: f64 = (0..l)
                .map(|i| {
                    let d = base[i]
                        + (0..3)
                            .map(|j| f64::from(density[j]) * dyes[j * l + i])
                            .sum::<f64>();
                    10f64.powf(-d) * response[k * l + i]
                })
                .sum();
            assert!(
                (f64::from(*got) / want - 1.0).abs() < 2e-6,
                "{k}: {got} vs {want}"
            );
        }
    }

    #[test]
    fn bad_dyes_densities_and_responses_are_refused() {
        assert!(Dyes::new(&[0.1, 0.0], &[1.0, 0.5, 0.2]).is_err());
        assert!(Dyes::new(&[-0.1, 0.0], &[1.0, 0.5]).is_err());
        let dyes = Dyes::new(&[0.0, 0.0], &[1.0, 0.5]).unwrap();
        let mut out = [0.0f32; 2];
        assert!(dyes
            .transmit(&[-0.1, 0.2], 2, 1, &[1.0, 1.0], &mut out)
            .is_err());
        assert!(dyes
            .transmit(&[0.1, 0.2], 2, 1, &[1.0, 1.0, 1.0], &mut out)
            .is_err());
        assert!(dyes
            .transmit(&[0.1, 0.2], 2, 1, &[f64::NAN, 1.0], &mut out)
            .is_err());
    }
}

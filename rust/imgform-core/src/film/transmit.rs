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

use super::{check_lengths, check_samples};
use crate::error::{all_finite, CoreError, Result};
use crate::invalid;
use crate::parallel::for_each_band;
use crate::parallel::ROWS_PER_TASK;

/// `2^x` for `x` in about `[-126, 126]` (clamped there), to ~2e-7 relative.
///
/// The rounding by adding and subtracting 1.5 x 2^23 and the polynomial
/// vectorise (a call to `exp2f` does not): `2^x = 2^n e^(r ln 2)` with `n`
/// the nearest integer and `|r| <= 1/2`, the exponential's Taylor series to
/// the 6th power (remainder < 0.347^7 / 7! = 1.2e-7), `2^n` built from its
/// IEEE-754 exponent bits.
#[inline(always)]
fn exp2(x: f32) -> f32 {
    const ROUND: f32 = 12_582_912.0;
    let x = x.clamp(-126.0, 126.0);
    let n = (x + ROUND) - ROUND;
    let y = (x - n) * std::f32::consts::LN_2;
    let p = 1.0
        + y * (1.0
            + y * (0.5
                + y * (1.0 / 6.0 + y * (1.0 / 24.0 + y * (1.0 / 120.0 + y * (1.0 / 720.0))))));
    p * f32::from_bits((((n as i32) + 127) as u32) << 23)
}

/// The spectral model of one developed film: base density and the dyes'
/// spectral densities on a grid of `grid_len` wavelengths.
#[derive(Debug, Clone)]
pub struct Dyes {
    grid_len: usize,
    /// `-log2(10) b(λ)`, so that the transmittance is `2^(base + Σ D_i dye_i)`.
    base: Vec<f32>,
    /// `-log2(10) e_i(λ)`, layer-major.
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
        let scale = |v: &[f64]| {
            v.iter()
                .map(|d| (-d * std::f64::consts::LOG2_10) as f32)
                .collect()
        };
        Ok(Self {
            grid_len: l,
            base: scale(base),
            dyes: scale(dyes),
        })
    }

    /// Number of dye layers.
    pub fn layers(&self) -> usize {
        self.dyes.len() / self.grid_len
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
        let resp: Vec<f32> = response.iter().map(|&r| r as f32).collect();
        for_each_band(out, width * m, ROWS_PER_TASK, |y0, rows| {
            // The spectrum of one pixel, reused for every pixel of the band.
            let mut t = vec![0.0f32; l];
            let src = &density[y0 * width * n..];
            for (d, o) in src.chunks_exact(n).zip(rows.chunks_exact_mut(m)) {
                t.copy_from_slice(&self.base);
                for (di, e) in d.iter().zip(self.dyes.chunks_exact(l)) {
                    t.iter_mut().zip(e).for_each(|(v, e)| *v += di * e);
                }
                t.iter_mut().for_each(|v| *v = exp2(*v));
                for (v, r) in o.iter_mut().zip(resp.chunks_exact(l)) {
                    *v = t.iter().zip(r).map(|(a, b)| a * b).sum();
                }
            }
        });
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp2_is_accurate_over_the_film_range() {
        for k in -4000..=400 {
            let x = k as f32 * 0.01;
            let want = 2f64.powf(f64::from(x));
            let got = f64::from(exp2(x));
            assert!((got / want - 1.0).abs() < 3e-7, "{x}: {got} vs {want}");
        }
        assert!(exp2(-500.0) > 0.0 && exp2(-500.0) < 1e-37);
    }

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

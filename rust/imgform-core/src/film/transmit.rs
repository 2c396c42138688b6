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

/// Pixels per step of [`transmit_row`]: one per lane of an AVX2 register
/// of f32, so each wavelength's exponent, exponential and response sums are
/// single packed instructions for eight pixels, with no horizontal sums.
const PIXELS: usize = 8;

/// The spectral model of one developed film: base density and the dyes'
/// spectral densities on a grid of `grid_len` wavelengths.
#[derive(Debug, Clone)]
pub struct Dyes {
    grid_len: usize,
    /// `-log2(10) b(λ)`, so that the transmittance is `2^(base + Σ D_i dye_i)`.
    base: Vec<f32>,
    /// `-log2(10) e_i(λ)`, wavelength-major (`layers` values per
    /// wavelength): the loop over wavelengths reads them in order.
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
        if l == 0 || dyes.is_empty() || !dyes.len().is_multiple_of(l) {
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
            base: base.iter().map(|&b| scale(b)).collect(),
            dyes: by_wavelength(dyes, l, scale),
        })
    }

    /// Number of dye layers.
    pub fn layers(&self) -> usize {
        self.dyes.len() / self.grid_len
    }

    /// Number of wavelengths.
    pub fn grid_len(&self) -> usize {
        self.grid_len
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
        if response.is_empty() || !response.len().is_multiple_of(l) {
            return Err(CoreError::Shape(format!(
                "the responses must be (m, {l}), one sample per wavelength, got {} values",
                response.len()
            )));
        }
        all_finite("the responses", response)?;
        let m = response.len() / l;
        check_lengths(width, height, (density, n), (out, m))?;
        check_samples("densities", density, width, n)?;
        let resp = grouped(response, l);
        for_each_band(out, width * m, ROWS_PER_TASK, |y0, rows| {
            // Eight pixels' dye amounts and spectra, reused within the band.
            let mut amounts = vec![0.0f32; n * PIXELS];
            let mut spectra = vec![[0.0f32; PIXELS]; l];
            for (i, row) in rows.chunks_mut(width * m).enumerate() {
                let src = &density[(y0 + i) * width * n..][..width * n];
                transmit_row_wide(self, src, &resp, (&mut amounts, &mut spectra), row);
                finish(row);
            }
        });
        Ok(())
    }
}

wide!(
    /// [`transmit_row`], 8 lanes wide where the CPU has them.
    fn transmit_row_wide = transmit_row(
        dyes: &Dyes,
        density: &[f32],
        response: &[[f32; GROUP]],
        scratch: (&mut [f32], &mut [[f32; PIXELS]]),
        out: &mut [f32],
    )
);

/// Responses per group of [`grouped`], stored together: the paper's layers
/// and the CIE observer's X, Y, Z are three.
const GROUP: usize = 3;

/// The pixels of one row, eight at a time, the pixels across the lanes:
/// first the transmittance `2^(base + Σ D_i dye_i)` at every wavelength,
/// then its dot with each response ([`dot`], in registers, in a fixed
/// order: every path and thread gives the same bits). `response` is
/// [`grouped`], `out` holds `m` values per pixel, and `scratch` holds the
/// block's amounts (`layers x 8`, layer-major) and spectra (`grid_len` of
/// 8).
#[inline(always)]
fn transmit_row(
    dyes: &Dyes,
    density: &[f32],
    response: &[[f32; GROUP]],
    (amounts, spectra): (&mut [f32], &mut [[f32; PIXELS]]),
    out: &mut [f32],
) {
    let (n, l) = (dyes.layers(), dyes.grid_len);
    let m = out.len() * n / density.len();
    for (d, o) in density.chunks(n * PIXELS).zip(out.chunks_mut(m * PIXELS)) {
        let count = d.len() / n;
        for (i, a) in amounts.chunks_exact_mut(PIXELS).enumerate() {
            // A short block's missing pixels get density 0: computed, never stored.
            for (j, v) in a.iter_mut().enumerate() {
                *v = if j < count { d[j * n + i] } else { 0.0 };
            }
        }
        for ((t, b), e) in spectra
            .iter_mut()
            .zip(&dyes.base)
            .zip(dyes.dyes.chunks_exact(n))
        {
            let mut x = [*b; PIXELS];
            for (a, e) in amounts.chunks_exact(PIXELS).zip(e) {
                for (x, a) in x.iter_mut().zip(a) {
                    *x = a.mul_add(*e, *x);
                }
            }
            *t = x;
        }
        // The exponentials apart, in one loop over all wavelengths: each is a
        // chain of dependent multiply-adds (the polynomial), and taken one
        // wavelength at a time, inside the loop above, they waited on one
        // another; here the iterations are independent and overlap.
        for t in spectra.as_flattened_mut() {
            *t = exp2(*t);
        }
        for (g, group) in response.chunks_exact(l).enumerate() {
            // Loops, not `array::from_fn`: what is not inlined into the wide
            // build is compiled without AVX2 (`from_fn` was not, and the
            // print ran four times slower).
            let mut sums = [[0.0f32; PIXELS]; GROUP];
            for (k, s) in sums.iter_mut().enumerate() {
                *s = dot(spectra, group, k);
            }
            store(&sums, g, count, o);
        }
    }
}

/// `Σ_λ t(λ) r_k(λ)` for eight pixels' spectra `t` and response `k` of a
/// group: the sums over the first and the second half of the wavelengths,
/// each in order, then added. The two halves are two chains of dependent
/// multiply-adds that run side by side; one chain over all 41 wavelengths,
/// each step waiting 5 cycles for the one before (on this machine's CPU),
/// was most of the time. (Three responses' chains in one loop would
/// interleave as well, but the compiler leaves such a loop unvectorised.)
#[inline(always)]
fn dot(spectra: &[[f32; PIXELS]], response: &[[f32; GROUP]], k: usize) -> [f32; PIXELS] {
    let half = spectra.len() / 2;
    let (t_lo, t_hi) = spectra.split_at(half);
    let (r_lo, r_hi) = response.split_at(half);
    let (mut lo, mut hi) = ([0.0f32; PIXELS], [0.0f32; PIXELS]);
    for ((t, r), (u, q)) in t_lo.iter().zip(r_lo).zip(t_hi.iter().zip(r_hi)) {
        for (s, t) in lo.iter_mut().zip(t) {
            *s = t.mul_add(r[k], *s);
        }
        for (s, u) in hi.iter_mut().zip(u) {
            *s = u.mul_add(q[k], *s);
        }
    }
    // An odd number of wavelengths leaves the last one to the second half.
    for (u, q) in t_hi.iter().zip(r_hi).skip(half) {
        for (s, u) in hi.iter_mut().zip(u) {
            *s = u.mul_add(q[k], *s);
        }
    }
    for (s, h) in lo.iter_mut().zip(&hi) {
        *s += h;
    }
    lo
}

/// Writes the sums of response group `g` of `count` pixels into their block
/// `o` of the output (`m` values per pixel), leaving out the padding.
#[inline(always)]
fn store(sums: &[[f32; PIXELS]; GROUP], g: usize, count: usize, o: &mut [f32]) {
    let m = o.len() / count;
    for (j, s) in sums.iter().enumerate() {
        let k = g * GROUP + j;
        if k < m {
            for (p, v) in s.iter().take(count).enumerate() {
                o[p * m + k] = *v;
            }
        }
    }
}

/// Spectra of `l` samples (`values` holds a whole number of them, one after
/// the other) mapped by `f` and stored wavelength-major: for each
/// wavelength, its sample of every spectrum.
fn by_wavelength(values: &[f64], l: usize, f: impl Fn(f64) -> f32) -> Vec<f32> {
    let count = values.len() / l;
    let f = &f;
    (0..l)
        .flat_map(|w| (0..count).map(move |k| f(values[k * l + w])))
        .collect()
}

/// Responses `(m, l)` as f32 in groups of [`GROUP`] for [`transmit_row`]:
/// for each group, for each wavelength, the group's samples (the last group
/// padded with zero responses, summed but never stored).
fn grouped(response: &[f64], l: usize) -> Vec<[f32; GROUP]> {
    let m = response.len() / l;
    (0..m.div_ceil(GROUP))
        .flat_map(|g| {
            (0..l).map(move |w| {
                std::array::from_fn(|j| {
                    let k = g * GROUP + j;
                    if k < m {
                        response[k * l + w] as f32
                    } else {
                        0.0
                    }
                })
            })
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
    fn the_wide_row_gives_the_plain_bits_in_full_and_short_blocks() {
        // 41 and 40 wavelengths (the dots' halves unequal and equal), 3
        // dyes; 11 pixels: a full block of eight and a short one; 1, 3 and
        // 5 responses: part of a group, one group, and two.
        for (l, m) in [(41, 1), (41, 3), (41, 5), (40, 3)] {
            let spectrum = |k: usize| -> Vec<f64> {
                (0..l)
                    .map(|i| 0.05 + ((i * 13 + k * 7) % 17) as f64 / 20.0)
                    .collect()
            };
            let base = spectrum(0);
            let dyes: Vec<f64> = (1..4).flat_map(spectrum).collect();
            let model = Dyes::new(&base, &dyes).unwrap();
            let density: Vec<f32> = (0..33).map(|i| (i % 10) as f32 * 0.2).collect();
            let response: Vec<f64> = (4..4 + m).flat_map(spectrum).collect();
            let resp = grouped(&response, l);
            let (mut amounts, mut spectra) = (vec![0.0; 3 * PIXELS], vec![[0.0; PIXELS]; l]);
            let (mut plain, mut wide_px) = (vec![0.0f32; 11 * m], vec![0.0f32; 11 * m]);
            transmit_row(
                &model,
                &density,
                &resp,
                (&mut amounts, &mut spectra),
                &mut plain,
            );
            transmit_row_wide(
                &model,
                &density,
                &resp,
                (&mut amounts, &mut spectra),
                &mut wide_px,
            );
            assert_eq!(plain, wide_px);
            for (i, got) in plain.iter().enumerate() {
                let (p, k) = (i / m, i % m);
                let want: f64 = (0..l)
                    .map(|w| {
                        let d = base[w]
                            + (0..3)
                                .map(|j| f64::from(density[p * 3 + j]) * dyes[j * l + w])
                                .sum::<f64>();
                        10f64.powf(-d) * response[k * l + w]
                    })
                    .sum();
                assert!(
                    (f64::from(*got) / want - 1.0).abs() < 2e-6,
                    "{m} responses, pixel {p} response {k}: {got} vs {want}"
                );
            }
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

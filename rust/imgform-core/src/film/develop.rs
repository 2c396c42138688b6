//! Development: exposures to dye amounts, with DIR couplers.
//!
//! Each layer `i` develops the density `D_i = f_i(log10(g H_i))` of its
//! characteristic curve `f_i` (`g` the exposure gain, `2^EV`). DIR couplers
//! release, where dye forms in a donor layer `j`, an inhibitor that diffuses
//! (Gaussian of the diffusion length, [`super::diffuse`]) and slows
//! development in a receiver layer `i`. We model its effect as a loss of log
//! exposure proportional to the donors' developed density,
//!
//! `D_i = c_i(log10(g H_i) - Σ_j A_ij G * (D_j - D_j,min))`,
//!
//! with `D_j` from the curves without inhibition (the development the
//! donors would reach) and `A` the donor -> receiver matrix, as in the
//! interimage models of Hanson and Horton (1952) and the description of DIR
//! couplers in Hunt, *The Reproduction of Colour*, 6th ed., sec. 14.8.
//! The receivers' curves `c_i` are the stated ones pre-corrected
//! ([`Curve::pre_corrected`]) so that a neutral, uniform wedge, where the
//! blur changes nothing and every layer sees one log exposure, develops
//! exactly the stated curves: couplers then change only colour contrast
//! (interimage effects) and edges, as they do in a real stock whose
//! datasheet curves are measured on neutral wedges.

use super::curve::{Curve, LayerCurves};
use super::diffuse::{blur_columns_then, blur_rows_of, gaussian_taps};
use super::fastmath::{log2, wide};
use super::halation::Halation;
use super::inhibit::Inhibition;
use super::{check_lengths, check_samples};
use crate::error::{all_finite, positive, CoreError, Result};
use crate::invalid;
use crate::parallel::for_each_row;

/// The layers of one emulsion and their couplers, validated once.
#[derive(Debug, Clone)]
pub struct Emulsion {
    curves: LayerCurves,
    /// `None` without couplers: development is then the curves exactly.
    couplers: Option<Couplers>,
}

/// DIR couplers: the donor -> receiver matrix, the diffusion taps and the
/// receivers' pre-corrected curves.
#[derive(Debug, Clone)]
struct Couplers {
    inhibition: Inhibition,
    taps: Vec<f32>,
    corrected: LayerCurves,
}

impl Emulsion {
    /// An emulsion of `curves.len()` layers; `matrix` is `n x n`, row `i`
    /// receiving from column `j`, every entry >= 0 (an inhibitor never adds
    /// exposure); `diffusion` is the inhibitors' diffusion length in pixels.
    ///
    /// # Errors
    /// [`crate::CoreError::InvalidArgument`] for no layers, a matrix of the
    /// wrong size or with a negative or non-finite entry, a negative or
    /// non-finite diffusion length, or couplers too strong to pre-correct.
    pub fn new(curves: Vec<Curve>, matrix: &[f64], diffusion: f64) -> Result<Self> {
        let n = curves.len();
        if n == 0 || matrix.len() != n * n {
            return Err(invalid!(
                "an emulsion needs >= 1 layer and an n x n coupler matrix, got {n} layers and \
                 {} matrix entries",
                matrix.len()
            ));
        }
        all_finite("the DIR coupler matrix", matrix)?;
        if let Some(i) = matrix.iter().position(|a| *a < 0.0) {
            return Err(invalid!(
                "DIR coupler strengths must be >= 0 (inhibitors only remove exposure), entry \
                 ({}, {}) is {}",
                i / n,
                i % n,
                matrix[i]
            ));
        }
        if !(diffusion.is_finite() && diffusion >= 0.0) {
            return Err(invalid!(
                "the DIR diffusion length must be finite and >= 0 pixels, got {diffusion}"
            ));
        }
        let couplers = if matrix.iter().all(|a| *a == 0.0) {
            None
        } else {
            Some(Couplers::new(&curves, matrix, diffusion)?)
        };
        Ok(Self {
            curves: LayerCurves::new(curves),
            couplers,
        })
    }

    /// Number of layers.
    pub fn layers(&self) -> usize {
        self.curves.layers()
    }

    /// `true` when the emulsion has DIR couplers, whose development reads
    /// the neighbourhood of a pixel, not only the pixel.
    pub fn has_couplers(&self) -> bool {
        self.couplers.is_some()
    }

    /// Develops exposures `(height, width, layers)` (>= 0, relative to the
    /// stock's reference white) at gain `gain` into densities, same shape,
    /// after `halation` if given.
    ///
    /// Each step that reads no neighbours runs inside the pass before it,
    /// on the row in cache, and only `out` and one scratch image are
    /// written: first `out` takes the log exposures (the halation's column
    /// pass hands its rows over for that), and without couplers their
    /// curves too. With couplers the donors' densities are the curves of
    /// those rows, computed inside the diffusion's row pass into the scratch
    /// image (the halation's row pass before), then the column pass hands
    /// each row of `out`, still the log exposures, to be inhibited and
    /// developed by the corrected curves in place.
    ///
    /// # Errors
    /// [`crate::CoreError::Shape`] for mismatched buffers or a halation of
    /// another number of layers; [`crate::CoreError::InvalidArgument`] for a
    /// gain that is not > 0 or an exposure that is negative or not finite
    /// (the first one named).
    pub fn develop(
        &self,
        exposure: &[f32],
        (width, height): (usize, usize),
        gain: f64,
        halation: Option<&Halation>,
        out: &mut [f32],
    ) -> Result<()> {
        let n = self.layers();
        check_lengths(width, height, (exposure, n), (out, n))?;
        if let Some(h) = halation.filter(|h| h.layers() != n) {
            return Err(CoreError::Shape(format!(
                "a halation of {} layers for an emulsion of {n}",
                h.layers()
            )));
        }
        let log_gain = positive("the exposure gain", gain)?.log10() as f32;
        check_samples("exposures", exposure, width, n)?;
        let row_len = width * n;
        // The log exposures of a row, and without couplers its densities.
        let first = |_: usize, row: &mut [f32]| {
            log_exposure_in_place(log_gain, row);
            if self.couplers.is_none() {
                curves_in_place(&self.curves, row);
            }
        };
        let mut scratch = if halation.is_some() || self.couplers.is_some() {
            vec![0.0f32; exposure.len()]
        } else {
            Vec::new()
        };
        match halation {
            Some(h) => h.apply_then(exposure, (width, height), &mut scratch, out, first),
            None => for_each_row(out, row_len, |y, row| {
                row.copy_from_slice(&exposure[y * row_len..][..row_len]);
                first(y, row);
            }),
        }
        let Some(dir) = &self.couplers else {
            return Ok(());
        };
        blur_rows_of(out, width, n, &dir.taps, &mut scratch, |row| {
            donors_in_place(&self.curves, row);
        });
        blur_columns_then(
            &scratch,
            width,
            height,
            n,
            &dir.taps,
            out,
            row_len,
            |_, near, row| {
                inhibit_in_place(&dir.inhibition, near, row);
                curves_in_place(&dir.corrected, row);
            },
        );
        Ok(())
    }

    /// One row of [`Emulsion::develop`] without couplers or halation, in
    /// place: `row` holds exposures on entry and densities on return;
    /// `log_gain` is the gain's `log10`. For kernels that produce the
    /// exposures row by row (printing); the caller checks them and that
    /// there are no couplers.
    pub fn develop_in_place(&self, log_gain: f32, row: &mut [f32]) {
        debug_assert!(self.couplers.is_none());
        log_exposure_in_place(log_gain, row);
        curves_in_place(&self.curves, row);
    }
}

wide!(
    /// [`LayerCurves::apply`], 8 lanes wide where the CPU has them.
    fn curves_in_place = apply_curves(curves: &LayerCurves, row: &mut [f32])
);

#[inline(always)]
fn apply_curves(curves: &LayerCurves, row: &mut [f32]) {
    curves.apply(row);
}

wide!(
    /// [`LayerCurves::apply_above_min`], 8 lanes wide where the CPU has
    /// them.
    fn donors_in_place = apply_donors(curves: &LayerCurves, row: &mut [f32])
);

#[inline(always)]
fn apply_donors(curves: &LayerCurves, row: &mut [f32]) {
    curves.apply_above_min(row);
}

wide!(
    /// [`Inhibition::subtract`], 8 lanes wide where the CPU has them.
    fn inhibit_in_place = subtract_inhibition(
        inhibition: &Inhibition,
        near: &[f32],
        row: &mut [f32],
    )
);

#[inline(always)]
fn subtract_inhibition(inhibition: &Inhibition, near: &[f32], row: &mut [f32]) {
    inhibition.subtract(near, row);
}

wide!(
    /// `H -> log10(gain H)` over a row, as `log2 H log10(2) + log10(gain)`
    /// through the vectorised [`log2`], 8 lanes wide where the CPU has them.
    fn log_exposure_in_place = log_exposure(log_gain: f32, row: &mut [f32])
);

#[inline(always)]
fn log_exposure(log_gain: f32, row: &mut [f32]) {
    for v in row.iter_mut() {
        *v = log2(*v) * std::f32::consts::LOG10_2 + log_gain;
    }
}

impl Couplers {
    fn new(curves: &[Curve], matrix: &[f64], diffusion: f64) -> Result<Self> {
        let n = curves.len();
        let corrected = curves
            .iter()
            .enumerate()
            .map(|(i, c)| {
                c.pre_corrected(|x| {
                    (0..n)
                        .map(|j| {
                            let d = curves[j].eval(x as f32) - curves[j].min_density();
                            matrix[i * n + j] * f64::from(d)
                        })
                        .sum()
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let taps = if diffusion > 0.0 {
            gaussian_taps(diffusion, "the DIR diffusion length")?
        } else {
            vec![1.0]
        };
        let matrix: Vec<f32> = matrix.iter().map(|&a| a as f32).collect();
        Ok(Self {
            inhibition: Inhibition::new(&matrix, n),
            taps,
            corrected: LayerCurves::new(corrected),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three logistic layers of slopes 0.6, 0.65, 0.7 over log H -3..1.
    fn curves() -> Vec<Curve> {
        [0.6, 0.65, 0.7]
            .iter()
            .map(|g| {
                let d: Vec<f64> = (0..401)
                    .map(|k| {
                        let x = -3.0 + 0.01 * k as f64;
                        0.2 + 2.0 / (1.0 + (-2.0 * g * (x + 1.0)).exp())
                    })
                    .collect();
                Curve::new(-3.0, 0.01, &d).unwrap()
            })
            .collect()
    }

    const MATRIX: [f64; 9] = [0.0, 0.15, 0.1, 0.1, 0.0, 0.12, 0.05, 0.1, 0.0];

    fn wedge(w: usize, h: usize) -> Vec<f32> {
        // Columns step through log H = -3.2..0.8, the same in every layer.
        (0..w * h * 3)
            .map(|i| 10f32.powf(-3.2 + 4.0 * ((i / 3) % w) as f32 / (w - 1) as f32))
            .collect()
    }

    #[test]
    fn without_couplers_density_is_the_curve() {
        let e = Emulsion::new(curves(), &[0.0; 9], 2.0).unwrap();
        let (w, h) = (41, 3);
        let ex = wedge(w, h);
        let mut out = vec![0.0; ex.len()];
        e.develop(&ex, (w, h), 2.0, None, &mut out).unwrap();
        for (i, (d, x)) in out.iter().zip(&ex).enumerate() {
            // The vectorised log10 is within 1e-7 of `log10`; the curves'
            // slopes are < 1.
            let want = e.curves.curves()[i % 3].eval((2.0 * x).log10());
            assert!((d - want).abs() < 1e-6, "{i}: {d} vs {want}");
        }
    }

    #[test]
    fn couplers_keep_a_uniform_neutral_on_the_curves_but_change_colour_edges() {
        let e = Emulsion::new(curves(), &MATRIX, 1.5).unwrap();
        let (w, h) = (30, 4);
        for col in 0..w {
            // A uniform field per exposure: no blur, no edge.
            let x = -3.2 + 4.0 * col as f32 / (w - 1) as f32;
            let ex = vec![10f32.powf(x); w * h * 3];
            let mut out = vec![0.0; ex.len()];
            e.develop(&ex, (w, h), 1.0, None, &mut out).unwrap();
            for (i, d) in out.iter().enumerate() {
                assert!(
                    (d - e.curves.curves()[i % 3].eval(x)).abs() < 2e-3,
                    "{x} {i}: {d}"
                );
            }
        }
        // Red exposed 3x more than green and blue: the red donor inhibits
        // green more than a neutral of green's exposure would (interimage
        // effect), so green falls below its curve.
        let mut ex = vec![0.1f32; 20 * 20 * 3];
        ex.chunks_mut(3).for_each(|p| p[0] = 0.3);
        let mut out = vec![0.0; ex.len()];
        e.develop(&ex, (20, 20), 1.0, None, &mut out).unwrap();
        assert!(
            out[1] < e.curves.curves()[1].eval(-1.0) - 0.01,
            "{}",
            out[1]
        );
    }

    #[test]
    fn halation_inside_development_equals_halation_before_it() {
        let (w, h) = (23, 19);
        let ex: Vec<f32> = (0..w * h * 3)
            .map(|i| 10f32.powf(-2.5 + ((i * 7919) % 300) as f32 / 100.0))
            .collect();
        let hal = Halation::new(&[0.2, 0.05, 0.01], 2.5).unwrap();
        let mut spread = vec![0.0; ex.len()];
        crate::film::halation::halation(&ex, w, h, &[0.2, 0.05, 0.01], 2.5, &mut spread).unwrap();
        for matrix in [[0.0; 9], MATRIX] {
            let e = Emulsion::new(curves(), &matrix, 1.5).unwrap();
            let (mut fused, mut apart) = (vec![0.0; ex.len()], vec![0.0; ex.len()]);
            e.develop(&ex, (w, h), 1.3, Some(&hal), &mut fused).unwrap();
            e.develop(&spread, (w, h), 1.3, None, &mut apart).unwrap();
            assert_eq!(fused, apart);
        }
        let two = Halation::new(&[0.2, 0.05], 2.5).unwrap();
        let mut out = vec![0.0; ex.len()];
        let e = Emulsion::new(curves(), &MATRIX, 1.5).unwrap();
        assert!(e.develop(&ex, (w, h), 1.0, Some(&two), &mut out).is_err());
    }

    #[test]
    fn bad_inputs_are_refused() {
        let e = Emulsion::new(curves(), &MATRIX, 1.0).unwrap();
        let mut out = vec![0.0; 12];
        let mut ex = vec![0.5f32; 12];
        ex[7] = f32::NAN;
        let err = e.develop(&ex, (2, 2), 1.0, None, &mut out).unwrap_err();
        assert!(
            err.to_string().contains("row 1, column 0), channel 1"),
            "{err}"
        );
        assert!(e.develop(&ex[..9], (2, 2), 1.0, None, &mut out).is_err());
        assert!(e.develop(&[0.5; 12], (2, 2), 0.0, None, &mut out).is_err());
        let mut m = MATRIX;
        m[4] = -0.1;
        assert!(Emulsion::new(curves(), &m, 1.0)
            .unwrap_err()
            .to_string()
            .contains("(1, 1)"));
        assert!(Emulsion::new(curves(), &MATRIX[..4], 1.0).is_err());
        assert!(Emulsion::new(curves(), &MATRIX, f64::NAN).is_err());
    }
}

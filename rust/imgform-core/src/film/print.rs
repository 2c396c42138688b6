//! Printing: the light through a developed negative, developed on paper.
//!
//! The paper's layer exposures are the negative's transmittance integrated
//! against the enlarger light as each paper layer sees it
//! ([`Dyes::transmit`]); a paper without DIR couplers then develops each
//! pixel by its curves alone, so both steps run on one row while it is in
//! cache and the paper's exposures are never stored as an image.

use super::develop::Emulsion;
use super::transmit::Dyes;
use crate::error::{positive, CoreError, Result};
use crate::invalid;

/// The paper's densities `(height, width, paper layers)` of a negative's
/// `density` `(height, width, negative layers)` printed with `light`
/// (`(paper layers, grid_len)`: lamp x filtration x paper sensitivity x
/// quadrature weight, >= 0) at exposure gain `gain`.
///
/// # Errors
/// [`CoreError::Shape`] for mismatched sizes (including a light of another
/// number of rows than the paper has layers);
/// [`CoreError::InvalidArgument`] for a negative or non-finite light sample,
/// a gain that is not > 0, or densities that are negative or not finite.
pub fn print(
    negative: &Dyes,
    density: &[f32],
    (width, height): (usize, usize),
    light: &[f64],
    paper: &Emulsion,
    gain: f64,
    out: &mut [f32],
) -> Result<()> {
    let m = paper.layers();
    if light.len() != m * negative.grid_len() {
        return Err(CoreError::Shape(format!(
            "the print light must be (paper layers, wavelengths) = ({m}, {}), got {} values",
            negative.grid_len(),
            light.len()
        )));
    }
    if let Some(i) = light.iter().position(|v| !(0.0..=f64::MAX).contains(v)) {
        return Err(invalid!(
            "the print light must be finite and >= 0; layer {}, wavelength index {} is {}",
            i / negative.grid_len(),
            i % negative.grid_len(),
            light[i]
        ));
    }
    let log_gain = positive("the print exposure gain", gain)?.log10() as f32;
    if paper.has_couplers() {
        // The couplers read neighbouring rows: develop the whole exposure.
        let mut exposure = vec![0.0f32; out.len()];
        negative.transmit(density, width, height, light, &mut exposure)?;
        return paper.develop(&exposure, (width, height), gain, None, out);
    }
    negative.transmit_then(density, width, height, light, out, |row| {
        paper.develop_in_place(log_gain, row)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::curve::Curve;

    fn paper(couplers: f64) -> Emulsion {
        let curves = (0..2)
            .map(|i| {
                let d: Vec<f64> = (0..201).map(|k| 0.1 + 0.01 * (k + i) as f64).collect();
                Curve::new(-2.0, 0.02, &d).unwrap()
            })
            .collect();
        Emulsion::new(curves, &[0.0, couplers, couplers, 0.0], 1.0).unwrap()
    }

    fn negative() -> (Dyes, Vec<f32>, Vec<f64>) {
        let dyes = Dyes::new(&[0.1, 0.0, 0.2], &[1.0, 0.5, 0.0, 0.0, 0.2, 1.0]).unwrap();
        let density: Vec<f32> = (0..5 * 4 * 2).map(|i| (i % 7) as f32 * 0.2).collect();
        (dyes, density, vec![0.3, 0.5, 0.1, 0.0, 0.2, 0.6])
    }

    #[test]
    fn one_pass_equals_transmit_then_develop() {
        for couplers in [0.0, 0.1] {
            let (dyes, density, light) = negative();
            let pap = paper(couplers);
            let mut fused = vec![0.0; density.len()];
            print(&dyes, &density, (5, 4), &light, &pap, 1.7, &mut fused).unwrap();
            let mut exposure = vec![0.0; density.len()];
            dyes.transmit(&density, 5, 4, &light, &mut exposure)
                .unwrap();
            let mut apart = vec![0.0; density.len()];
            pap.develop(&exposure, (5, 4), 1.7, None, &mut apart)
                .unwrap();
            assert_eq!(fused, apart, "couplers {couplers}");
        }
    }

    #[test]
    fn bad_light_and_gain_are_refused() {
        let (dyes, density, light) = negative();
        let pap = paper(0.0);
        let mut out = vec![0.0; density.len()];
        let err = print(&dyes, &density, (5, 4), &light[..3], &pap, 1.0, &mut out);
        assert!(matches!(err, Err(CoreError::Shape(_))));
        let mut bad = light.clone();
        bad[4] = -0.1;
        let err = print(&dyes, &density, (5, 4), &bad, &pap, 1.0, &mut out).unwrap_err();
        assert!(
            err.to_string().contains("layer 1, wavelength index 1"),
            "{err}"
        );
        assert!(print(&dyes, &density, (5, 4), &light, &pap, 0.0, &mut out).is_err());
    }
}

//! Wavelength grids, quadrature weights and Planck's law.
//!
//! A spectrum is a vector of samples on a grid of wavelengths in nanometres.
//! Integrating a product of spectra (radiance x sensitivity) over wavelength
//! is a weighted sum of samples; the weights depend on the grid and on the
//! rule, so they are computed once here and folded into the per-channel
//! sensitivities before any pixel is touched.

use crate::error::{CoreError, Result};
use crate::invalid;

/// How far the steps of a grid may differ from their mean, relative to it,
/// for the grid to count as uniform. Grids written as `np.arange(380, 781, 5)`
/// or read from 6-digit text are uniform to ~1e-12; 1e-6 nm on a 5 nm step
/// still refuses any grid with a visibly uneven step.
const UNIFORM_TOLERANCE: f64 = 1e-6;

/// Second radiation constant `c2 = h c / k_B` in m K (CODATA 2018, exact
/// since the 2019 SI redefinition fixed h, c and k_B).
pub const PLANCK_C2: f64 = 1.438_776_877e-2;

/// First radiation constant for spectral radiance, `c1L = 2 h c^2`, in
/// W m^2 sr^-1 (CODATA 2018, exact).
pub const PLANCK_C1L: f64 = 1.191_042_972e-16;

/// The rule that turns samples into an integral over wavelength.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quadrature {
    /// Trapezoids between neighbouring samples: exact for piecewise-linear
    /// spectra, valid on any grid.
    Trapezoid,
    /// Each sample times the grid step, the rule of CIE 15 and of
    /// colour-science's `sd_to_XYZ_integration`. Needs a uniform grid.
    Riemann,
}

impl Quadrature {
    /// Parses `"trapezoid"` or `"riemann"`.
    ///
    /// # Errors
    /// [`CoreError::InvalidArgument`] naming the accepted rules.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "trapezoid" => Ok(Self::Trapezoid),
            "riemann" => Ok(Self::Riemann),
            _ => Err(invalid!(
                "quadrature must be \"trapezoid\" or \"riemann\", got {name:?}"
            )),
        }
    }
}

/// Checks that `wavelengths` (nm) form a grid: at least two samples, finite,
/// positive and strictly increasing.
///
/// # Errors
/// [`CoreError::InvalidArgument`] naming the first offending sample.
pub fn check_grid(wavelengths: &[f64]) -> Result<()> {
    if wavelengths.len() < 2 {
        return Err(invalid!(
            "a wavelength grid needs at least 2 samples, got {}",
            wavelengths.len()
        ));
    }
    if let Some(i) = wavelengths
        .iter()
        .position(|w| !(w.is_finite() && *w > 0.0))
    {
        return Err(invalid!(
            "wavelengths must be finite and > 0 nm, sample {i} is {}",
            wavelengths[i]
        ));
    }
    if let Some(i) = wavelengths.windows(2).position(|p| p[1] <= p[0]) {
        return Err(invalid!(
            "wavelengths must be strictly increasing, sample {} ({} nm) follows {} nm",
            i + 1,
            wavelengths[i + 1],
            wavelengths[i]
        ));
    }
    Ok(())
}

/// The quadrature weights (nm) of `wavelengths`: `integral f dλ ≈ Σ w_i f_i`.
///
/// # Errors
/// A bad grid (see [`check_grid`]), or [`Quadrature::Riemann`] on a grid whose
/// steps differ by more than 1e-6 of their mean.
pub fn weights(wavelengths: &[f64], rule: Quadrature) -> Result<Vec<f64>> {
    check_grid(wavelengths)?;
    let n = wavelengths.len();
    let steps: Vec<f64> = wavelengths.windows(2).map(|p| p[1] - p[0]).collect();
    match rule {
        Quadrature::Trapezoid => Ok((0..n)
            .map(|i| {
                let left = if i > 0 { steps[i - 1] } else { 0.0 };
                let right = steps.get(i).copied().unwrap_or(0.0);
                0.5 * (left + right)
            })
            .collect()),
        Quadrature::Riemann => {
            let mean = (wavelengths[n - 1] - wavelengths[0]) / (n - 1) as f64;
            match steps
                .iter()
                .position(|s| (s - mean).abs() > UNIFORM_TOLERANCE * mean)
            {
                Some(i) => Err(invalid!(
                    "the \"riemann\" rule needs a uniform grid; step {i} is {} nm, the mean \
                     step {mean} nm (use \"trapezoid\" for any grid)",
                    steps[i]
                )),
                None => Ok(vec![mean; n]),
            }
        }
    }
}

/// Checks that a table of spectra (rows of `grid_len` samples) matches its
/// grid, and that every sample is finite and >= 0: radiance, reflectance,
/// transmittance and quantum efficiency cannot be negative.
///
/// # Errors
/// [`CoreError::Shape`] for a length that is not a multiple of the grid,
/// [`CoreError::InvalidArgument`] naming the first bad sample.
pub fn check_spectra(name: &str, spectra: &[f64], grid_len: usize) -> Result<usize> {
    if grid_len == 0 || !spectra.len().is_multiple_of(grid_len) || spectra.is_empty() {
        return Err(CoreError::Shape(format!(
            "{name} must hold spectra of {grid_len} samples, one per wavelength, got {} values",
            spectra.len()
        )));
    }
    if let Some(i) = spectra.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
        return Err(invalid!(
            "{name} must be finite and >= 0, spectrum {} at wavelength index {} is {}",
            i / grid_len,
            i % grid_len,
            spectra[i]
        ));
    }
    Ok(spectra.len() / grid_len)
}

/// Spectral radiance of a black body at `temperature` kelvin, in
/// W m^-2 sr^-1 nm^-1, at each of `wavelengths` (nm) into `out`:
/// `L = c1L / λ^5 / (exp(c2 / (λ T)) - 1)` with λ in metres, times 1e-9 per nm.
///
/// # Errors
/// A bad grid, a non-positive temperature, or a wrong output length.
pub fn blackbody(wavelengths: &[f64], temperature: f64, out: &mut [f64]) -> Result<()> {
    check_grid(wavelengths)?;
    crate::error::positive("temperature", temperature)?;
    if out.len() != wavelengths.len() {
        return Err(CoreError::Shape(format!(
            "blackbody output must hold {} values, got {}",
            wavelengths.len(),
            out.len()
        )));
    }
    for (o, &nm) in out.iter_mut().zip(wavelengths) {
        let m = nm * 1e-9;
        // exp_m1 keeps the Rayleigh-Jeans end (c2 / λT << 1) accurate.
        *o = PLANCK_C1L / m.powi(5) / (PLANCK_C2 / (m * temperature)).exp_m1() * 1e-9;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grids_are_checked() {
        assert!(check_grid(&[380.0, 390.0]).is_ok());
        for (bad, what) in [
            (vec![380.0], "at least 2"),
            (vec![380.0, f64::NAN], "finite"),
            (vec![-1.0, 390.0], "finite and > 0"),
            (vec![390.0, 390.0], "strictly increasing"),
        ] {
            let err = check_grid(&bad).unwrap_err().to_string();
            assert!(err.contains(what), "{err}");
        }
    }

    #[test]
    fn trapezoid_weights_integrate_a_line_exactly_on_an_uneven_grid() {
        let grid = [400.0, 410.0, 425.0, 460.0, 461.0];
        let w = weights(&grid, Quadrature::Trapezoid).unwrap();
        let integral: f64 = grid.iter().zip(&w).map(|(x, w)| (2.0 * x + 1.0) * w).sum();
        let exact = (461.0f64 * 461.0 + 461.0) - (400.0 * 400.0 + 400.0);
        assert!(
            (integral - exact).abs() < 1e-9 * exact,
            "{integral} {exact}"
        );
    }

    #[test]
    fn riemann_needs_a_uniform_grid() {
        let uniform: Vec<f64> = (0..41).map(|i| 380.0 + 10.0 * f64::from(i)).collect();
        assert_eq!(
            weights(&uniform, Quadrature::Riemann).unwrap(),
            vec![10.0; 41]
        );
        let err = weights(&[380.0, 390.0, 395.0], Quadrature::Riemann).unwrap_err();
        assert!(err.to_string().contains("uniform grid"), "{err}");
    }

    #[test]
    fn spectra_must_be_non_negative_and_match_the_grid() {
        assert_eq!(check_spectra("s", &[0.0, 1.0, 2.0, 3.0], 2), Ok(2));
        let err = check_spectra("s", &[0.0, 1.0, -2.0, 3.0], 2).unwrap_err();
        assert!(
            err.to_string().contains("spectrum 1 at wavelength index 0"),
            "{err}"
        );
        assert!(matches!(
            check_spectra("s", &[0.0; 3], 2),
            Err(CoreError::Shape(_))
        ));
    }

    #[test]
    fn blackbody_peaks_where_wien_says() {
        // Wien's displacement law: λ_max T = 2.897771955e-3 m K.
        let grid: Vec<f64> = (0..4001).map(|i| 300.0 + 0.1 * f64::from(i)).collect();
        let mut out = vec![0.0; grid.len()];
        blackbody(&grid, 5000.0, &mut out).unwrap();
        let peak = (0..out.len())
            .max_by(|&a, &b| out[a].total_cmp(&out[b]))
            .unwrap();
        assert!((grid[peak] - 579.554).abs() < 0.1, "{}", grid[peak]);
        // Far in the infrared Planck tends to Rayleigh-Jeans, 2 c k T / λ^4,
        // which checks the two constants against each other (c1L / c2 = 2 c k).
        let (c, k) = (299_792_458.0, 1.380_649e-23);
        // At λ = 1 m, c2 / λT = 2.2e-6: the two agree to ~1e-6.
        let (nm, t) = (1.0e9, 6500.0);
        let mut one = [0.0; 2];
        blackbody(&[nm, 2.0 * nm], t, &mut one).unwrap();
        let rj = 2.0 * c * k * t / (nm * 1e-9f64).powi(4) * 1e-9;
        assert!((one[0] / rj - 1.0).abs() < 1e-5, "{} {rj}", one[0]);
        assert!(blackbody(&grid, 0.0, &mut out).is_err());
    }
}

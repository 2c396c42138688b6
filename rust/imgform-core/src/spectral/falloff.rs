//! The natural `cos⁴ θ` falloff of image-plane irradiance, applied a row at
//! a time inside the capture kernels, so that no falloff image is built and
//! no extra pass is made over the frame.
//!
//! A pixel `r` from the optical centre sees the scene along a chief ray at
//! `θ = atan(r / f)` (lens focused at infinity): its irradiance is the
//! on-axis one times `cos⁴ θ = 1 / (1 + r² / f²)²`, computed without
//! trigonometry.

use crate::error::Result;
use crate::invalid;

/// Where the optical axis meets the sensor and how far pixels are from it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Falloff {
    /// Optical centre, pixels (column, row).
    center: (f64, f64),
    /// Pixel pitch over focal length: a pixel step's `tan θ` near the axis.
    pitch_over_focal: f64,
}

impl Falloff {
    /// A falloff about `center = (cx, cy)` (pixels) for pixels of pitch
    /// `pitch_over_focal` focal lengths.
    ///
    /// # Errors
    /// [`crate::CoreError::InvalidArgument`] for a non-finite centre or a
    /// ratio that is not finite and > 0.
    pub fn new(center: (f64, f64), pitch_over_focal: f64) -> Result<Self> {
        if !(center.0.is_finite() && center.1.is_finite()) {
            return Err(invalid!(
                "the optical centre must be finite, got {center:?}"
            ));
        }
        if !(pitch_over_focal.is_finite() && pitch_over_focal > 0.0) {
            return Err(invalid!(
                "the pixel pitch over the focal length must be finite and > 0, got \
                 {pitch_over_focal}"
            ));
        }
        Ok(Self {
            center,
            pitch_over_focal,
        })
    }

    /// `cos⁴ θ` of pixel `(y, x)`.
    #[inline(always)]
    pub fn at(&self, y: usize, x: usize) -> f64 {
        let s = self.pitch_over_focal;
        let ty = (y as f64 - self.center.1) * s;
        let tx = (x as f64 - self.center.0) * s;
        let q = 1.0 + ty * ty + tx * tx;
        1.0 / (q * q)
    }

    /// Multiplies row `y` of rates by the falloff of its pixels.
    pub(super) fn apply_row(&self, y: usize, rates: &mut [f64]) {
        for (x, r) in rates.iter_mut().enumerate() {
            *r *= self.at(y, x);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_falloff_is_the_fourth_power_of_the_chief_ray_cosine() {
        let f = Falloff::new((3.0, 5.0), 0.09).unwrap();
        for (y, x) in [(5, 3), (0, 0), (8, 12), (5, 10)] {
            let r = ((y as f64 - 5.0).hypot(x as f64 - 3.0)) * 0.09;
            let want = r.atan().cos().powi(4);
            assert!((f.at(y, x) - want).abs() < 1e-12, "({y}, {x})");
        }
        let mut row = vec![2.0; 13];
        f.apply_row(5, &mut row);
        assert_eq!(row[3], 2.0);
        assert_eq!(row[10], 2.0 * f.at(5, 10));
    }

    #[test]
    fn bad_geometry_is_refused() {
        assert!(Falloff::new((f64::NAN, 0.0), 1.0).is_err());
        for bad in [0.0, -1.0, f64::INFINITY] {
            let err = Falloff::new((0.0, 0.0), bad).unwrap_err();
            assert!(err.to_string().contains("focal length"), "{err}");
        }
    }
}

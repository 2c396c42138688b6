//! Camera intrinsics `K = [[fx, s, cx], [0, fy, cy], [0, 0, 1]]`: the map
//! between normalised image coordinates (`x / z`, `y / z`) and pixels.

use crate::error::{all_finite, Result};
use crate::invalid;

/// The five intrinsic parameters of a pinhole camera, in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub skew: f64,
}

impl Intrinsics {
    /// Reads a row-major 3x3 matrix.
    ///
    /// # Errors
    /// As [`Self::named`], naming the matrix `K`.
    pub fn from_matrix(k: &[f64; 9]) -> Result<Self> {
        Self::named("K", k)
    }

    /// Reads a row-major 3x3 matrix that the caller calls `name` (a
    /// function taking two, such as `K` and `new_K`, says which is wrong).
    ///
    /// # Errors
    /// Non-finite entries, a bottom row other than `[0, 0, 1]`, a non-zero
    /// `K[1][0]`, or a zero focal length (a singular `K`).
    pub fn named(name: &str, k: &[f64; 9]) -> Result<Self> {
        all_finite(name, k)?;
        if k[3] != 0.0 || k[6] != 0.0 || k[7] != 0.0 || k[8] != 1.0 {
            return Err(invalid!(
                "{name} must be upper triangular with {name}[2] = [0, 0, 1], got rows {:?}, {:?}, {:?}",
                &k[0..3],
                &k[3..6],
                &k[6..9]
            ));
        }
        if k[0] == 0.0 || k[4] == 0.0 {
            return Err(invalid!(
                "{name} is singular: fx = {} and fy = {} must both be non-zero",
                k[0],
                k[4]
            ));
        }
        Ok(Self {
            fx: k[0],
            fy: k[4],
            cx: k[2],
            cy: k[5],
            skew: k[1],
        })
    }

    /// The row-major 3x3 matrix.
    pub fn matrix(&self) -> [f64; 9] {
        [
            self.fx, self.skew, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0,
        ]
    }

    /// Normalised coordinates `(x, y)` to pixels `(u, v)`.
    #[inline(always)]
    pub fn to_pixel(&self, x: f64, y: f64) -> (f64, f64) {
        (self.fx * x + self.skew * y + self.cx, self.fy * y + self.cy)
    }

    /// Pixels `(u, v)` to normalised coordinates: the exact inverse of [`Self::to_pixel`].
    #[inline(always)]
    pub fn to_normalized(&self, u: f64, v: f64) -> (f64, f64) {
        let y = (v - self.cy) / self.fy;
        ((u - self.cx - self.skew * y) / self.fx, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_round_trip_with_skew() {
        let k = Intrinsics::from_matrix(&[800.0, 2.5, 320.0, 0.0, 780.0, 240.0, 0.0, 0.0, 1.0])
            .unwrap();
        let (u, v) = k.to_pixel(0.1, -0.2);
        let (x, y) = k.to_normalized(u, v);
        assert!((x - 0.1).abs() < 1e-15 && (y + 0.2).abs() < 1e-15);
    }

    #[test]
    fn singular_or_malformed_k_is_refused() {
        assert!(Intrinsics::from_matrix(&[0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0]).is_err());
        assert!(Intrinsics::from_matrix(&[1.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 2.0]).is_err());
        assert!(
            Intrinsics::from_matrix(&[1.0, 0.0, f64::NAN, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0]).is_err()
        );
    }
}

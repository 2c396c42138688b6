//! The lecture's projection models (section 2.1, eq. 1-3).
//!
//! Pinhole: a point `(x, y, z)` in camera coordinates lands on the image
//! plane behind the pinhole at `x' = -f x / z`, `y' = -f y / z` — inverted.
//! The upright "virtual" plane in front of the pinhole drops the sign.
//! Orthographic: depth is dropped, `x' = s x`, `y' = s y`; it is the limit of
//! perspective as `z -> inf` with `f / z` held at `s`.

use crate::error::{positive, CoreError, Result};
use crate::parallel::map_points;

/// Checks that `points` holds whole records of `dim` values and `out` has room
/// for as many records of `out_dim` values.
///
/// # Errors
/// [`CoreError::Shape`] when the lengths disagree.
pub fn check_points(points: &[f64], dim: usize, out: &[f64], out_dim: usize) -> Result<usize> {
    if !points.len().is_multiple_of(dim) {
        return Err(CoreError::Shape(format!(
            "points must be (N, {dim}) values, got a buffer of {} values",
            points.len()
        )));
    }
    let n = points.len() / dim;
    if out.len() != n * out_dim {
        return Err(CoreError::Shape(format!(
            "output must hold {n} x {out_dim} values, got {}",
            out.len()
        )));
    }
    Ok(n)
}

/// Turns the index of the first non-finite point into an error.
pub(crate) fn reject_non_finite(bad: Option<usize>, what: &str) -> Result<()> {
    match bad {
        None => Ok(()),
        Some(i) => Err(CoreError::InvalidArgument(format!(
            "{what} must be finite, point {i} contains NaN or infinity"
        ))),
    }
}

/// Pinhole projection of camera-frame points `(N, 3)` into `out` `(N, 2)`.
///
/// With `invert` the image is the real one behind the pinhole
/// (`x' = -f x / z`); without it the upright virtual image. Points at or
/// behind the pinhole (`z <= 0`) have no image and become NaN.
///
/// # Errors
/// `f` not finite and positive, non-finite coordinates, or mismatched lengths.
pub fn project_pinhole(points: &[f64], f: f64, invert: bool, out: &mut [f64]) -> Result<()> {
    let f = positive("f", f)?;
    check_points(points, 3, out, 2)?;
    let scale = if invert { -f } else { f };
    let bad = map_points(points, 3, out, 2, move |p, q| {
        let (x, y, z) = (p[0], p[1], p[2]);
        let w = if z > 0.0 { scale / z } else { f64::NAN };
        q[0] = w * x;
        q[1] = w * y;
        x.is_finite() & y.is_finite() & z.is_finite()
    });
    reject_non_finite(bad, "points")
}

/// Orthographic (parallel) projection `(x, y, z) -> (s x, s y)`.
///
/// # Errors
/// `scale` not finite and positive, non-finite coordinates, or mismatched lengths.
pub fn project_orthographic(points: &[f64], scale: f64, out: &mut [f64]) -> Result<()> {
    let s = positive("scale", scale)?;
    check_points(points, 3, out, 2)?;
    let bad = map_points(points, 3, out, 2, move |p, q| {
        q[0] = s * p[0];
        q[1] = s * p[1];
        p.iter().all(|v| v.is_finite())
    });
    reject_non_finite(bad, "points")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pinhole_follows_equations_1_and_2() {
        let mut out = [0.0; 4];
        project_pinhole(&[1.0, 2.0, 4.0, 0.0, 0.0, -1.0], 2.0, true, &mut out).unwrap();
        assert_eq!(out[..2], [-0.5, -1.0]);
        assert!(out[2].is_nan() && out[3].is_nan());
        project_pinhole(&[1.0, 2.0, 4.0, 1.0, 1.0, 0.0], 2.0, false, &mut out).unwrap();
        assert_eq!(out[..2], [0.5, 1.0]);
        assert!(out[2].is_nan());
    }

    #[test]
    fn pinhole_rejects_bad_focal_length_and_nan_points() {
        let mut out = [0.0; 2];
        assert!(project_pinhole(&[0.0, 0.0, 1.0], 0.0, true, &mut out).is_err());
        let err = project_pinhole(&[f64::NAN, 0.0, 1.0], 1.0, true, &mut out).unwrap_err();
        assert!(err.to_string().contains("point 0"));
        assert!(project_pinhole(&[0.0, 1.0], 1.0, true, &mut out).is_err());
    }

    #[test]
    fn orthographic_scales_and_drops_depth() {
        let mut out = [0.0; 2];
        project_orthographic(&[1.0, -2.0, 9.0], 0.5, &mut out).unwrap();
        assert_eq!(out, [0.5, -1.0]);
    }
}

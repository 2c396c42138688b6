//! Lens distortion models (lecture section 3.3) in normalised coordinates.
//!
//! *Distorting* maps where an ideal pinhole would put a point to where the
//! real lens puts it; *undistorting* is the inverse. Brown-Conrady uses
//! OpenCV's coefficient order `(k1, k2, p1, p2[, k3[, k4, k5, k6]])`, so
//! calibration results from `cv2.calibrateCamera` can be passed unchanged.
//! The one-parameter division model (Fitzgibbon 2001) is defined in the
//! other direction, `x_u = x_d / (1 + λ r_d²)`, which is why it undistorts in
//! closed form and distorts by solving a quadratic.

use crate::error::{all_finite, Result};
use crate::intrinsics::Intrinsics;
use crate::invalid;
use crate::parallel::map_points;
use crate::projection::{check_points, reject_non_finite};

/// Newton iterations allowed for the Brown-Conrady inverse. Convergence is
/// quadratic, so realistic lenses need 3-6; the cap only stops divergence.
const MAX_NEWTON_STEPS: usize = 50;

/// Residual (in normalised units) at which the inverse counts as exact: a
/// focal length of 10 000 px turns it into 1e-10 px, below the 1e-9 px
/// promised, and it is still ~100 ulp above f64 rounding noise near r = 1.
const NEWTON_TOLERANCE: f64 = 1e-14;

/// A lens distortion model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Distortion {
    /// `[k1, k2, p1, p2, k3, k4, k5, k6]`, missing ones zero.
    BrownConrady([f64; 8]),
    /// `λ` of the division model; `λ < 0` is barrel distortion.
    Division(f64),
}

impl Distortion {
    /// Builds a model from its name and coefficients.
    ///
    /// # Errors
    /// Unknown model, a coefficient count the model does not take, or a
    /// non-finite coefficient.
    pub fn new(model: &str, coeffs: &[f64]) -> Result<Self> {
        all_finite("distortion coefficients", coeffs)?;
        match model {
            "brown_conrady" => match coeffs.len() {
                0 | 4 | 5 | 8 => {
                    let mut k = [0.0; 8];
                    k[..coeffs.len()].copy_from_slice(coeffs);
                    Ok(Self::BrownConrady(k))
                }
                n => Err(invalid!(
                    "brown_conrady takes 4, 5 or 8 coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6]]), got {n}"
                )),
            },
            "division" => match coeffs {
                [lambda] => Ok(Self::Division(*lambda)),
                _ => Err(invalid!("division takes 1 coefficient (lambda), got {}", coeffs.len())),
            },
            _ => Err(invalid!("unknown distortion model {model:?}; accepted: \"brown_conrady\", \"division\"")),
        }
    }

    /// `true` when the model is the identity.
    pub fn is_identity(&self) -> bool {
        match self {
            Self::BrownConrady(k) => k.iter().all(|&c| c == 0.0),
            Self::Division(lambda) => *lambda == 0.0,
        }
    }

    /// Ideal normalised point to distorted one; `None` where the model has
    /// no distorted image of it: beyond its fold, where Brown-Conrady's
    /// polynomial turns back (OpenCV's `projectPoints` puts such a point on
    /// the other side of the axis, or back inside the frame) and the
    /// division model's quadratic has no root.
    #[inline]
    pub fn distort(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        match *self {
            Self::BrownConrady(k) => {
                let (p, jacobian) = brown_conrady(&k, x, y);
                one_to_one(jacobian).then_some(p)
            }
            Self::Division(lambda) => division_distort(lambda, x, y),
        }
    }

    /// Distorted normalised point to ideal one; `None` where the inverse
    /// does not converge or lands beyond the fold of the model (where the
    /// lens maps two ideal points onto one and the inverse is ambiguous).
    #[inline]
    pub fn undistort(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        match *self {
            Self::BrownConrady(k) => brown_conrady_inverse(&k, xd, yd),
            Self::Division(lambda) => {
                // r_u = r_d / (1 + λ r_d²) rises while |λ r_d²| < 1: beyond
                // that (λ > 0) it falls again, and the forward direction
                // images the same ideal point before the fold instead.
                let l = lambda * (xd * xd + yd * yd);
                (l.abs() < 1.0).then(|| (xd / (1.0 + l), yd / (1.0 + l)))
            }
        }
    }
}

/// Brown-Conrady forward model and its Jacobian `[[a, b], [b, c]]` (it is
/// symmetric: both cross terms equal `2xy g' + 2 p1 x + 2 p2 y`).
#[inline]
fn brown_conrady(k: &[f64; 8], x: f64, y: f64) -> ((f64, f64), [f64; 3]) {
    let [k1, k2, p1, p2, k3, k4, k5, k6] = *k;
    let r2 = x * x + y * y;
    let num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    let den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6));
    let g = num / den;
    let dnum = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3);
    let dden = k4 + r2 * (2.0 * k5 + 3.0 * r2 * k6);
    let dg = (dnum * den - num * dden) / (den * den);
    let xd = x * g + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
    let yd = y * g + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
    let a = g + 2.0 * x * x * dg + 2.0 * p1 * y + 6.0 * p2 * x;
    let b = 2.0 * x * y * dg + 2.0 * p1 * x + 2.0 * p2 * y;
    let c = g + 2.0 * y * y * dg + 6.0 * p1 * y + 2.0 * p2 * x;
    ((xd, yd), [a, b, c])
}

/// Whether Brown-Conrady's Jacobian `[[a, b], [b, c]]` is positive
/// definite: true around the axis, up to the fold where the lens starts to
/// map two ideal points onto one.
#[inline]
fn one_to_one([a, b, c]: [f64; 3]) -> bool {
    a > 0.0 && a * c - b * b > 0.0
}

/// Newton's method on `distort(p) = (xd, yd)`, kept on the lens's side of
/// its fold: every iterate has a positive definite Jacobian (the region
/// around the axis where the model is one-to-one) and a smaller residual
/// than the last, halving a step until it does. A plain Newton step from a
/// corner of a strong barrel lens (k1 = -0.34) overshoots past the fold and
/// converges to the wrong branch, or not at all, and the inverse was lost
/// for points well inside the image. It starts at the distorted point, or
/// nearer the axis (where the Jacobian is the identity) if that point is
/// beyond the fold.
fn brown_conrady_inverse(k: &[f64; 8], xd: f64, yd: f64) -> Option<(f64, f64)> {
    let residual = |(fx, fy): (f64, f64)| (fx - xd, fy - yd);
    if !(xd.is_finite() && yd.is_finite()) {
        return None;
    }
    let tolerance = NEWTON_TOLERANCE * (1.0 + xd.abs().max(yd.abs()));
    let (mut p, mut at) = ((xd, yd), brown_conrady(k, xd, yd));
    while !one_to_one(at.1) {
        if p == (0.0, 0.0) {
            // Not one-to-one even on the axis: coefficients so large that
            // the Jacobian there overflows (2 p1 = inf, times 0), no inverse.
            return None;
        }
        p = (p.0 * 0.5, p.1 * 0.5);
        at = brown_conrady(k, p.0, p.1);
    }
    for _ in 0..MAX_NEWTON_STEPS {
        let ((ex, ey), [a, b, c]) = (residual(at.0), at.1);
        if ex.abs().max(ey.abs()) <= tolerance {
            return Some(p);
        }
        let det = a * c - b * b;
        let step = ((c * ex - b * ey) / det, (a * ey - b * ex) / det);
        let norm = ex * ex + ey * ey;
        let mut t = 1.0;
        loop {
            let q = (p.0 - t * step.0, p.1 - t * step.1);
            let next = brown_conrady(k, q.0, q.1);
            let (nx, ny) = residual(next.0);
            if one_to_one(next.1) && nx * nx + ny * ny < norm {
                (p, at) = (q, next);
                break;
            }
            t *= 0.5;
            if t < 1e-12 {
                return None;
            }
        }
    }
    None
}

/// Division model forward direction: solves `r_u = r_d / (1 + λ r_d²)` for
/// the root `r_d` that tends to `r_u` as `λ -> 0`.
#[inline]
fn division_distort(lambda: f64, x: f64, y: f64) -> Option<(f64, f64)> {
    let ru = (x * x + y * y).sqrt();
    if ru > FAR {
        return division_far(lambda, x, y);
    }
    let t = lambda * ru;
    if t == 0.0 {
        return Some((x, y));
    }
    let disc = 1.0 - 4.0 * t * ru;
    if disc < 0.0 {
        return None;
    }
    // rd / ru = (1 - sqrt(disc)) / (2 t ru), rewritten without cancellation.
    let s = 2.0 / (1.0 + disc.sqrt());
    Some((x * s, y * s))
}

/// Beyond this `r_u` the squares in [`division_distort`] overflow.
const FAR: f64 = 1e150;

/// [`division_distort`] for points so far off axis that `r_u²` overflows
/// (a ray all but parallel to the image plane): the same root with `r_u`
/// taken out of the square root, `r_d = 2 / (1 / r_u + sqrt(1 / r_u² - 4 λ))`,
/// which tends to the fold radius `1 / sqrt(-λ)` of a barrel lens. Such
/// points went to the centre. A pincushion lens (`λ > 0`) has no image
/// there.
#[cold]
fn division_far(lambda: f64, x: f64, y: f64) -> Option<(f64, f64)> {
    if lambda > 0.0 {
        return None;
    }
    let m = x.abs().max(y.abs());
    let (xm, ym) = (x / m, y / m);
    let h = xm.hypot(ym);
    let inv = (m * h).recip();
    let rd = if lambda == 0.0 {
        m * h
    } else {
        2.0 / (inv + (inv * inv - 4.0 * lambda).sqrt())
    };
    Some((xm / h * rd, ym / h * rd))
}

/// Which way [`remap_points`] maps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    Distort,
    Undistort,
}

/// Distorts or undistorts points `(N, 2)` into `out`, in pixels through `k`
/// when given, else in normalised coordinates. Points the model cannot map
/// become NaN; the count of those is returned.
///
/// # Errors
/// Non-finite input points or mismatched lengths.
pub fn remap_points(
    points: &[f64],
    model: &Distortion,
    k: Option<&Intrinsics>,
    direction: Direction,
    out: &mut [f64],
) -> Result<usize> {
    check_points(points, 2, out, 2)?;
    let bad = map_points(points, 2, out, 2, |p, q| {
        let (x, y) = match k {
            Some(k) => k.to_normalized(p[0], p[1]),
            None => (p[0], p[1]),
        };
        let mapped = match direction {
            Direction::Distort => model.distort(x, y),
            Direction::Undistort => model.undistort(x, y),
        };
        let (u, v) = match (mapped, k) {
            (Some((x, y)), Some(k)) => k.to_pixel(x, y),
            (Some(xy), None) => xy,
            (None, _) => (f64::NAN, f64::NAN),
        };
        q[0] = u;
        q[1] = v;
        p[0].is_finite() && p[1].is_finite()
    });
    reject_non_finite(bad, "points")?;
    Ok(out.iter().step_by(2).filter(|v| v.is_nan()).count())
}

#[cfg(test)]
mod tests {
    use super::*;

    const LENS: [f64; 8] = [-0.28, 0.07, 1e-3, -5e-4, -0.01, 0.0, 0.0, 0.0];

    #[test]
    fn brown_conrady_matches_hand_computed_value() {
        // x = 0.5, y = 0: r2 = 0.25, radial = 1 - 0.28 * 0.25 + 0.07 * 0.0625 - 0.01 * 0.015625
        // = 0.93421875; xd = 0.5 * radial + p2 * (0.25 + 0.5) = 0.467109375 - 0.000375.
        let (xd, yd) = Distortion::BrownConrady(LENS).distort(0.5, 0.0).unwrap();
        assert!((xd - 0.466734375).abs() < 1e-15, "{xd}");
        assert!((yd - 1e-3 * 0.25).abs() < 1e-15, "{yd}");
    }

    #[test]
    fn far_points_of_a_barrel_division_lens_approach_its_fold() {
        // r_d -> 1 / sqrt(0.2) as r_u grows; past 1e154 the squares overflowed
        // and the points went to the centre.
        let fold = 1.0 / 0.2f64.sqrt();
        let lens = Distortion::Division(-0.2);
        let mut last = 0.0;
        for ru in [1e3, 1e100, 1e149, 1e151, 1e160, 1e200, 1e300] {
            let (xd, yd) = lens.distort(0.6 * ru, -0.8 * ru).unwrap();
            let rd = xd.hypot(yd);
            assert!(
                rd > last - 1e-15 && rd <= fold + 1e-15,
                "{ru}: {rd} after {last}"
            );
            assert!(fold - rd < 3.0 / ru + 1e-15, "{ru}: {rd}");
            assert!(
                (yd / xd + 0.8 / 0.6).abs() < 1e-12,
                "{ru}: the direction is kept"
            );
            last = rd;
        }
        assert!(Distortion::Division(0.2).distort(1e200, 0.0).is_none());
        assert_eq!(
            Distortion::Division(0.0).distort(1e200, 0.0),
            Some((1e200, 0.0))
        );
    }

    #[test]
    fn undistort_inverts_distort_to_machine_precision() {
        for model in [Distortion::BrownConrady(LENS), Distortion::Division(-0.2)] {
            for i in -10..=10 {
                for j in -10..=10 {
                    let (x, y) = (i as f64 * 0.06, j as f64 * 0.05);
                    let (xd, yd) = model.distort(x, y).unwrap();
                    let (xu, yu) = model.undistort(xd, yd).unwrap();
                    assert!(
                        (xu - x).abs() < 1e-13 && (yu - y).abs() < 1e-13,
                        "{model:?} {x} {y}"
                    );
                }
            }
        }
    }

    #[test]
    fn beyond_the_fold_there_is_no_inverse() {
        // Strong barrel: r_d(r) = r (1 - 0.5 r²) peaks at r = 0.816, r_d = 0.544.
        let model = Distortion::BrownConrady([-0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert!(model.undistort(0.5, 0.0).is_some());
        assert!(model.undistort(0.6, 0.0).is_none());
        assert!(model.distort(0.8, 0.0).is_some() && model.distort(0.9, 0.0).is_none());
        assert!(Distortion::Division(0.5).distort(1.0, 0.0).is_none());
    }

    #[test]
    fn coefficients_that_overflow_on_the_axis_have_no_inverse() {
        // 2 p1 = inf, times 0 on the axis: the Jacobian is NaN everywhere the
        // search for a one-to-one start looked, and it halved forever.
        for k in [[0.0, 0.0, 1e308, 0.0, 0.0], [0.0, 0.0, 0.0, 1e308, 0.0]] {
            let model = Distortion::new("brown_conrady", &k).unwrap();
            assert_eq!(model.undistort(0.3, 0.2), None);
        }
    }

    #[test]
    fn a_strong_barrel_lens_inverts_up_to_its_fold() {
        // r_d(r) = r (1 - 0.34 r² + 0.105 r⁴ - 0.011 r⁶) rises to its fold
        // at r = 2.127 (r_d = 1.2599): every r_d below has one preimage
        // before it, which a plain Newton step from r_d overshoots.
        let model = Distortion::BrownConrady([-0.34, 0.105, 0.0, 0.0, -0.011, 0.0, 0.0, 0.0]);
        for i in 1..=210 {
            let r = f64::from(i) * 0.01;
            for angle in [0.0f64, 0.3, 0.7, 1.2] {
                let (x, y) = (r * angle.cos(), r * angle.sin());
                let (xd, yd) = model.distort(x, y).unwrap();
                let (xu, yu) = model.undistort(xd, yd).unwrap();
                assert!(
                    (xu - x).abs() < 1e-12 && (yu - y).abs() < 1e-12,
                    "r {r} at {angle}"
                );
            }
        }
        assert!(
            model.undistort(1.27, 0.0).is_none(),
            "beyond the fold's r_d"
        );
        assert!(model.undistort(f64::NAN, 0.0).is_none());
    }

    #[test]
    fn the_division_model_has_no_inverse_beyond_its_fold() {
        // λ = 0.7: r_u = r_d / (1 + λ r_d²) peaks at r_d = 1/√λ = 1.195.
        let model = Distortion::Division(0.7);
        let (xu, _) = model.undistort(1.1, 0.0).unwrap();
        assert!((model.distort(xu, 0.0).unwrap().0 - 1.1).abs() < 1e-14);
        assert!(model.undistort(1.3, 0.0).is_none());
        assert!(Distortion::Division(-0.7).undistort(1.3, 0.0).is_none());
    }

    #[test]
    fn coefficient_counts_follow_opencv() {
        assert!(Distortion::new("brown_conrady", &[0.1; 5]).is_ok());
        let err = Distortion::new("brown_conrady", &[0.1; 3])
            .unwrap_err()
            .to_string();
        assert!(err.contains("4, 5 or 8") && err.contains("got 3"), "{err}");
        assert!(Distortion::new("fisheye", &[]).is_err());
        assert!(Distortion::new("division", &[f64::NAN]).is_err());
    }

    #[test]
    fn remap_points_goes_through_pixels_and_counts_failures() {
        let k = Intrinsics {
            fx: 1000.0,
            fy: 1000.0,
            cx: 500.0,
            cy: 400.0,
            skew: 0.0,
        };
        let model = Distortion::BrownConrady([-0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let pts = [600.0, 400.0, 1500.0, 400.0];
        let mut out = [0.0; 4];
        let failed = remap_points(&pts, &model, Some(&k), Direction::Undistort, &mut out).unwrap();
        assert_eq!(failed, 1);
        assert!(out[2].is_nan());
        let mut back = [0.0; 2];
        remap_points(&out[..2], &model, Some(&k), Direction::Distort, &mut back).unwrap();
        assert!((back[0] - 600.0).abs() < 1e-9 && (back[1] - 400.0).abs() < 1e-9);
    }
}

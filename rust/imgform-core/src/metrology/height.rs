//! The horizon and heights on the ground plane (Criminisi, Reid, Zisserman,
//! "Single view metrology", IJCV 40(2), 2000).
//!
//! With the horizon `l` (the ground's vanishing line) and the
//! vertical vanishing point `v`, a ground point `b` and the point `t` a height
//! `Z` above it satisfy `t ≃ b + Z α v` once `b` is scaled so that
//! `l · b = l · o` (`o` the image of the world origin). Hence
//! `α Z / (l · o) = -g(b, t)` with `g = ((b × t) · (v × t)) / ((l · b) |v × t|²)`
//! (the least-squares solution of `b × t = λ v × t` when noise leaves the
//! three points slightly off one line). A reference of known height fixes the
//! unknown factor, so `Z = Z_ref g(b, t) / g(b_ref, t_ref)`. A top on the
//! horizon has `l · t = 0`, which gives the camera height
//! `Z_c = Z_ref / (g(b_ref, t_ref) (l · v))`. Every formula is homogeneous, so
//! a vertical vanishing point at infinity (affine views) or a horizon at
//! infinity (looking straight down) need no special case.

use super::{cross, dot, incidence, unit, Vec3, COINCIDENCE_TOLERANCE};
use crate::camera::norm;
use crate::error::{all_finite, positive, Result};
use crate::invalid;
use crate::parallel::map_points_indexed;
use crate::projection::check_points;

/// A line scaled so that `a² + b² = 1` (then `l · (u, v, 1)` is a signed
/// distance in pixels), or `(0, 0, ±1)` for the line at infinity.
fn line_scale(l: Vec3) -> Vec3 {
    let ab = l[0].hypot(l[1]);
    if ab <= COINCIDENCE_TOLERANCE * norm(l) {
        return [0.0, 0.0, l[2].signum()];
    }
    [l[0] / ab, l[1] / ab, l[2] / ab]
}

/// The horizon through two vanishing points of horizontal directions
/// (homogeneous, either may be at infinity): `vp1 × vp2`, scaled so that
/// `a² + b² = 1` and `b < 0` (or `a < 0` when `b = 0`). Then `a u + b v + c`
/// is the signed distance in pixels, positive above the line: the sign of
/// `vanishing_line(camera, up)` for any camera whose image up points skywards.
/// Two points at infinity give the line at infinity `(0, 0, 1)`.
///
/// # Errors
/// Non-finite or zero vectors, or two coincident vanishing points.
pub fn fit_horizon(vp1: Vec3, vp2: Vec3) -> Result<Vec3> {
    let l = cross(unit("vp1", vp1)?, unit("vp2", vp2)?);
    if norm(l) <= COINCIDENCE_TOLERANCE {
        return Err(invalid!(
            "vp1 {vp1:?} and vp2 {vp2:?} are the same point: a line needs two distinct vanishing points"
        ));
    }
    let l = line_scale(l);
    if l[0] == 0.0 && l[1] == 0.0 {
        return Ok([0.0, 0.0, 1.0]);
    }
    let flip = l[1] > 0.0 || (l[1] == 0.0 && l[0] > 0.0);
    Ok(if flip { [-l[0], -l[1], -l[2]] } else { l })
}

/// The ground plane's metric, fixed by the horizon, the vertical vanishing
/// point and one reference object of known height.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundMetric {
    horizon: Vec3,
    vertical: Vec3,
    /// `Z_ref / g(b_ref, t_ref)`: multiplies `g(b, t)` into a height.
    scale: f64,
}

/// Why an object's height cannot be measured.
enum Degenerate {
    NonFinite,
    BaseOnHorizon,
    TopAtVertex,
}

impl GroundMetric {
    /// Validates the geometry and measures the reference.
    ///
    /// # Errors
    /// Non-finite or zero `horizon`/`vertical_vp`, a vertical vanishing point
    /// on the horizon, `ref_height` not finite and positive, a reference base
    /// on the horizon, a reference top at the vertical vanishing point, or a
    /// reference with no vertical extent in the image.
    pub fn new(
        horizon: Vec3,
        vertical_vp: Vec3,
        ref_base: [f64; 2],
        ref_top: [f64; 2],
        ref_height: f64,
    ) -> Result<Self> {
        let horizon = line_scale(unit("horizon", horizon)?);
        let vertical = unit("vertical_vp", vertical_vp)?;
        let ref_height = positive("ref_height", ref_height)?;
        all_finite("ref_base", &ref_base)?;
        all_finite("ref_top", &ref_top)?;
        if incidence(horizon, vertical).abs() <= COINCIDENCE_TOLERANCE {
            return Err(invalid!(
                "vertical_vp {vertical_vp:?} lies on the horizon {horizon:?}: a vertical direction cannot vanish on the ground's vanishing line"
            ));
        }
        let unscaled = Self {
            horizon,
            vertical,
            scale: 1.0,
        };
        let g = unscaled
            .ratio(ref_base, ref_top)
            .map_err(|why| invalid!("{}", why.message("the reference", ref_base, ref_top)))?;
        if g == 0.0 {
            return Err(invalid!(
                "the reference has no vertical extent in the image (ref_base {ref_base:?}, ref_top {ref_top:?}): its image must run towards the vertical vanishing point"
            ));
        }
        Ok(Self {
            scale: ref_height / g,
            ..unscaled
        })
    }

    /// `g(b, t)` of the module doc, or why it does not exist.
    fn ratio(&self, base: [f64; 2], top: [f64; 2]) -> std::result::Result<f64, Degenerate> {
        if !(base.iter().chain(&top).all(|c| c.is_finite())) {
            return Err(Degenerate::NonFinite);
        }
        let b = [base[0], base[1], 1.0];
        let t = [top[0], top[1], 1.0];
        let lb = dot(self.horizon, b);
        if lb.abs() <= COINCIDENCE_TOLERANCE * norm(self.horizon) * norm(b) {
            return Err(Degenerate::BaseOnHorizon);
        }
        let vt = cross(self.vertical, t);
        let vt2 = dot(vt, vt);
        if vt2.sqrt() <= COINCIDENCE_TOLERANCE * norm(t) {
            return Err(Degenerate::TopAtVertex);
        }
        let bt = cross(b, t);
        let g = dot(bt, vt) / (vt2 * lb);
        // Cancellation can leave a tiny residue for a zero-height object.
        Ok(if dot(bt, bt) == 0.0 { 0.0 } else { g })
    }

    /// Heights `out` `(N,)` of objects with bases `(N, 2)` and tops `(N, 2)`.
    ///
    /// # Errors
    /// Mismatched lengths; an object with non-finite coordinates, its base on
    /// the horizon or its top at the vertical vanishing point (named by index).
    pub fn heights(&self, base: &[f64], top: &[f64], out: &mut [f64]) -> Result<()> {
        let n = check_points(base, 2, out, 1)?;
        check_points(top, 2, &out[..], 1).map_err(|_| {
            invalid!(
                "top must hold one (x, y) per base ({n} points), got {} values",
                top.len()
            )
        })?;
        let metric = *self;
        let bad = map_points_indexed(base, 2, out, 1, move |i, b, q| {
            let t = [top[2 * i], top[2 * i + 1]];
            match metric.ratio([b[0], b[1]], t) {
                Ok(g) => {
                    q[0] = metric.scale * g;
                    true
                }
                Err(_) => false,
            }
        });
        match bad {
            None => Ok(()),
            Some(i) => {
                let (b, t) = ([base[2 * i], base[2 * i + 1]], [top[2 * i], top[2 * i + 1]]);
                let why = self
                    .ratio(b, t)
                    .err()
                    .map(|w| w.message(&format!("object {i}"), b, t));
                Err(invalid!("{}", why.unwrap_or_default()))
            }
        }
    }

    /// The camera's height above the ground, in the reference's unit: the
    /// height of an object whose top touches the horizon.
    pub fn camera_height(&self) -> f64 {
        self.scale / dot(self.horizon, self.vertical)
    }
}

impl Degenerate {
    fn message(&self, who: &str, base: [f64; 2], top: [f64; 2]) -> String {
        match self {
            Self::NonFinite => format!(
                "{who} must have finite coordinates, got base {base:?} and top {top:?}"
            ),
            Self::BaseOnHorizon => format!(
                "{who} has its base {base:?} on the horizon: a ground point there is infinitely far, its height is undetermined"
            ),
            Self::TopAtVertex => format!(
                "{who} has its top {top:?} at the vertical vanishing point: its height is unbounded"
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn horizon_through_two_points_has_the_up_sign() {
        let close = |a: Vec3, b: Vec3| (0..3).all(|i| (a[i] - b[i]).abs() < 1e-12);
        let l = fit_horizon([100.0, 200.0, 1.0], [500.0, 200.0, 1.0]).unwrap();
        assert!(close(l, [0.0, -1.0, 200.0]), "{l:?}");
        let l = fit_horizon([-1.0, 0.0, 0.0], [300.0, 200.0, 1.0]).unwrap();
        assert!(close(l, [0.0, -1.0, 200.0]), "{l:?}");
        let at_infinity = fit_horizon([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]).unwrap();
        assert_eq!(at_infinity, [0.0, 0.0, 1.0]);
        assert!(fit_horizon([1.0, 2.0, 1.0], [2.0, 4.0, 2.0]).is_err());
        assert!(fit_horizon([0.0; 3], [2.0, 4.0, 2.0]).is_err());
    }

    /// A level camera (f = 500, horizon at row 240, vertical VP at infinity)
    /// 1.5 above the ground; a pole of height `h` at depth `z` spans rows
    /// `240 + f (1.5 - h) / z` to `240 + f 1.5 / z`.
    fn level_pole(h: f64, z: f64, u: f64) -> ([f64; 2], [f64; 2]) {
        ([u, 240.0 + 750.0 / z], [u, 240.0 + 500.0 * (1.5 - h) / z])
    }

    #[test]
    fn level_camera_heights_and_camera_height() {
        let (rb, rt) = level_pole(2.0, 10.0, 300.0);
        let m = GroundMetric::new([0.0, -1.0, 240.0], [0.0, 1.0, 0.0], rb, rt, 2.0).unwrap();
        assert!((m.camera_height() - 1.5).abs() < 1e-12);
        let (b1, t1) = level_pole(0.7, 4.0, 100.0);
        let (b2, t2) = level_pole(1.5, 25.0, 500.0);
        let mut out = [0.0; 2];
        m.heights(&[b1, b2].concat(), &[t1, t2].concat(), &mut out)
            .unwrap();
        assert!(
            (out[0] - 0.7).abs() < 1e-12 && (out[1] - 1.5).abs() < 1e-12,
            "{out:?}"
        );
    }

    #[test]
    fn degenerate_heights_are_named() {
        let (rb, rt) = level_pole(2.0, 10.0, 300.0);
        let l = [0.0, -1.0, 240.0];
        let up = [0.0, 1.0, 0.0];
        let err = |r: Result<GroundMetric>| r.unwrap_err().to_string();
        assert!(err(GroundMetric::new(l, up, [3.0, 240.0], rt, 1.0)).contains("on the horizon"));
        assert!(err(GroundMetric::new(l, up, rb, rb, 1.0)).contains("no vertical extent"));
        assert!(
            err(GroundMetric::new(l, [1.0, 0.0, 0.0], rb, rt, 1.0)).contains("lies on the horizon")
        );
        assert!(err(GroundMetric::new(l, up, rb, rt, 0.0)).contains("ref_height"));
        let m = GroundMetric::new(l, up, rb, rt, 2.0).unwrap();
        let mut out = [0.0; 2];
        let e = m
            .heights(
                &[1.0, 300.0, 5.0, 240.0],
                &[1.0, 250.0, 5.0, 230.0],
                &mut out,
            )
            .unwrap_err();
        assert!(e.to_string().starts_with("object 1 has its base"), "{e}");
        let e = m
            .heights(&[1.0, 300.0], &[1.0, f64::NAN], &mut out[..1])
            .unwrap_err();
        assert!(e.to_string().contains("object 0 must have finite"), "{e}");
        assert!(m.heights(&[1.0, 300.0], &[1.0], &mut out[..1]).is_err());
    }
}

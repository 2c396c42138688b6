//! Geometric spot diagrams of a lens with longitudinal spherical aberration.
//!
//! # Model
//! A distant on-axis point sends a parallel beam into a thin lens of focal
//! length `f` and aperture radius `h_max = f / (2 N)`. The ray entering at
//! height `h` crosses the axis at `z(h) = f - LSA (h / h_max)^2` behind the
//! lens: paraxial rays at `f`, the marginal ray (`h = h_max`) displaced by
//! the full `LSA` towards the lens when `LSA > 0` (the under-corrected
//! aberration of a simple positive lens). A plane at distance `z` cuts each
//! ray, a straight line from its pupil point to its focus, at
//! `p = h_vec (1 - z / z(h))`.
//!
//! # Pupil sampling
//! The full pupil, not a fan: ray `k` of `n` enters at radius
//! `h_max sqrt(k / (n - 1))` and angle `k` times the golden angle (Vogel's
//! sunflower). The square root gives every ray an equal share of the pupil
//! area, so the RMS over rays estimates the light-weighted RMS of the spot;
//! ray 0 is the chief ray and ray `n - 1` the marginal ray, so both
//! foci are in the set exactly.
//!
//! # Best focus
//! Every hit is linear in `z`, so the mean squared distance of the hits from
//! their centroid is a quadratic in `z`, minimised in closed form by
//! [`best_focus`]. For the model above, with `u = h / h_max` and the pupil
//! area weight `2 u du`, a small defocus `d` from the paraxial focus leaves
//! the transverse error `~ u (d + LSA u^2) / f`, and
//! `int_0^1 u^2 (d + LSA u^2)^2 2u du = d^2/2 + 2 d LSA/3 + LSA^2/4`
//! is least at `d = -2 LSA / 3`: the least-RMS plane lies two thirds of the
//! way from the paraxial to the marginal focus (the circle of least
//! confusion, which minimises the *largest* radius instead, lies at 3/4).

use crate::error::{finite, positive, Result};
use crate::invalid;

/// Most rays in one diagram: 16 M rays take ~0.5 GB of hits and pupil
/// points; a smooth RMS needs only a few thousand.
pub const MAX_RAYS: usize = 1 << 24;

/// The lens of a spot diagram; lengths in one unit (mm in the docs).
#[derive(Debug, Clone, Copy)]
pub struct SpotLens {
    /// Focal length (the paraxial focus distance).
    pub f: f64,
    /// Focal length over aperture diameter.
    pub f_number: f64,
    /// Longitudinal spherical aberration of the marginal ray: its focus lies
    /// at `f - spherical_lsa`.
    pub spherical_lsa: f64,
}

/// Ray hits on one image plane.
#[derive(Debug, Clone, PartialEq)]
pub struct Spot {
    /// `(x, y)` of each ray on the image plane, `2 n` values.
    pub hits: Vec<f64>,
    /// `(x, y)` where each ray crosses the lens, `2 n` values.
    pub pupil: Vec<f64>,
    /// RMS distance of the hits from their centroid.
    pub rms_radius: f64,
}

/// One ray: its pupil point and where it crosses the axis.
#[derive(Debug, Clone, Copy)]
struct Ray {
    x: f64,
    y: f64,
    focus: f64,
}

impl SpotLens {
    fn validate(&self, n_rays: usize) -> Result<()> {
        positive("f", self.f)?;
        positive("f_number", self.f_number)?;
        finite("spherical_lsa", self.spherical_lsa)?;
        if self.spherical_lsa >= self.f {
            return Err(invalid!(
                "spherical_lsa must be smaller than f = {} (the marginal focus must lie behind \
                 the lens), got {}",
                self.f,
                self.spherical_lsa
            ));
        }
        if !(2..=MAX_RAYS).contains(&n_rays) {
            return Err(invalid!("n_rays must be in 2..={MAX_RAYS}, got {n_rays}"));
        }
        Ok(())
    }

    /// The sunflower of rays described in the module docs.
    fn rays(&self, n_rays: usize) -> Vec<Ray> {
        let h_max = self.f / (2.0 * self.f_number);
        // The golden angle spreads successive rays as evenly as possible.
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let last = (n_rays - 1) as f64;
        (0..n_rays)
            .map(|k| {
                let u2 = k as f64 / last;
                let (s, c) = (golden * k as f64).sin_cos();
                let h = h_max * u2.sqrt();
                Ray {
                    x: h * c,
                    y: h * s,
                    focus: self.f - self.spherical_lsa * u2,
                }
            })
            .collect()
    }
}

/// Traces `n_rays` rays (see the module docs) to the plane at distance
/// `image_plane` behind the lens.
///
/// # Errors
/// Non-positive `f`, `f_number` or `image_plane`, a non-finite
/// `spherical_lsa` or one of at least `f`, or `n_rays` outside
/// `2..=MAX_RAYS`.
pub fn spot_diagram(lens: &SpotLens, n_rays: usize, image_plane: f64) -> Result<Spot> {
    lens.validate(n_rays)?;
    positive("image_plane", image_plane)?;
    let rays = lens.rays(n_rays);
    let hits: Vec<f64> = rays
        .iter()
        .flat_map(|r| {
            let s = 1.0 - image_plane / r.focus;
            [r.x * s, r.y * s]
        })
        .collect();
    let pupil = rays.iter().flat_map(|r| [r.x, r.y]).collect();
    let rms_radius = rms_about_centroid(&hits);
    Ok(Spot {
        hits,
        pupil,
        rms_radius,
    })
}

/// RMS distance of `(x, y)` pairs from their mean.
fn rms_about_centroid(xy: &[f64]) -> f64 {
    let n = (xy.len() / 2) as f64;
    let (cx, cy) = mean_xy(xy.chunks_exact(2).map(|p| (p[0], p[1])));
    let ss: f64 = xy
        .chunks_exact(2)
        .map(|p| (p[0] - cx).powi(2) + (p[1] - cy).powi(2))
        .sum();
    (ss / n).sqrt()
}

/// Mean of a sequence of `(x, y)` pairs.
fn mean_xy(points: impl ExactSizeIterator<Item = (f64, f64)>) -> (f64, f64) {
    let n = points.len() as f64;
    let (sx, sy) = points.fold((0.0, 0.0), |(sx, sy), (x, y)| (sx + x, sy + y));
    (sx / n, sy / n)
}

/// The image-plane distance of least RMS spot radius for the same rays as
/// [`spot_diagram`], in closed form: with hits `p_k = a_k - z b_k`
/// (`a_k` the pupil point, `b_k = a_k / z_k`), the centred mean square
/// `mean |a'_k - z b'_k|^2` is least at `z = mean(a' . b') / mean(b' . b')`.
/// It lies between the paraxial and the marginal focus (at ~2/3 of the
/// way, see the module docs).
///
/// # Errors
/// As [`spot_diagram`].
pub fn best_focus(lens: &SpotLens, n_rays: usize) -> Result<f64> {
    lens.validate(n_rays)?;
    let rays = lens.rays(n_rays);
    let (ax, ay) = mean_xy(rays.iter().map(|r| (r.x, r.y)));
    let (bx, by) = mean_xy(rays.iter().map(|r| (r.x / r.focus, r.y / r.focus)));
    let (ab, bb) = rays.iter().fold((0.0, 0.0), |(ab, bb), r| {
        let (a, b) = (
            (r.x - ax, r.y - ay),
            (r.x / r.focus - bx, r.y / r.focus - by),
        );
        (ab + a.0 * b.0 + a.1 * b.1, bb + b.0 * b.0 + b.1 * b.1)
    });
    Ok(ab / bb)
}

#[cfg(test)]
mod tests {
    use super::*;

    const LENS: SpotLens = SpotLens {
        f: 50.0,
        f_number: 2.0,
        spherical_lsa: 0.3,
    };

    #[test]
    fn marginal_ray_meets_the_axis_at_the_marginal_focus() {
        let spot = spot_diagram(&LENS, 101, LENS.f - LENS.spherical_lsa).unwrap();
        let last = &spot.hits[200..];
        assert!(last[0].abs() < 1e-12 && last[1].abs() < 1e-12, "{last:?}");
        let r = spot.pupil[200].hypot(spot.pupil[201]);
        assert!((r - 12.5).abs() < 1e-12, "{r}");
    }

    #[test]
    fn best_focus_is_two_thirds_of_the_way_to_the_marginal_focus() {
        let z = best_focus(&LENS, 20_000).unwrap();
        let fraction = (LENS.f - z) / LENS.spherical_lsa;
        assert!((fraction - 2.0 / 3.0).abs() < 0.01, "{fraction}");
        let rms = |z| spot_diagram(&LENS, 20_000, z).unwrap().rms_radius;
        assert!(rms(z) < rms(z + 0.01) && rms(z) < rms(z - 0.01));
    }

    #[test]
    fn without_aberration_every_ray_meets_at_f() {
        let lens = SpotLens {
            spherical_lsa: 0.0,
            ..LENS
        };
        assert!(spot_diagram(&lens, 50, 50.0).unwrap().rms_radius < 1e-12);
        assert!((best_focus(&lens, 50).unwrap() - 50.0).abs() < 1e-9);
    }

    #[test]
    fn bad_lenses_are_refused() {
        let bad = SpotLens {
            spherical_lsa: 60.0,
            ..LENS
        };
        assert!(spot_diagram(&bad, 10, 40.0).is_err());
        assert!(spot_diagram(&LENS, 1, 40.0).is_err());
        assert!(spot_diagram(&LENS, 10, f64::NAN).is_err());
    }
}

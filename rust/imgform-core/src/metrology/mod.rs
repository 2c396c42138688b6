//! Single-view metrology (lecture section 2.1, item 5): vanishing points
//! fitted to image line segments, the horizon through two of them, and the
//! heights of objects standing on the ground plane measured against one
//! reference object (Criminisi, Reid, Zisserman, "Single view metrology",
//! IJCV 40(2), 2000).
//!
//! [`vanishing`] fits vanishing points to segments; [`height`] spans the
//! horizon and measures heights. Both work on homogeneous 3-vectors, so
//! points and lines at infinity need no special case.

use crate::camera::{norm, normalized};
use crate::error::{all_finite, Result};
use crate::invalid;

pub mod height;
pub mod vanishing;

pub use height::{fit_horizon, GroundMetric};
pub use vanishing::{fit_vanishing_point, FitOptions, VanishingFit, MAX_HYPOTHESES};

/// Relative size below which a cross product or an incidence `l · p`
/// counts as zero: two lines are the same line, a point lies on a line.
/// f64 rounding of pixel-sized coordinates leaves ~1e-16 relative, so 1e-12
/// flags only exact (up to rounding) coincidences, never a real scene.
pub(crate) const COINCIDENCE_TOLERANCE: f64 = 1e-12;

pub(crate) type Vec3 = [f64; 3];

#[inline]
pub(crate) fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
pub(crate) fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// A finite, non-zero homogeneous 3-vector scaled to unit length.
pub(crate) fn unit(name: &str, p: Vec3) -> Result<Vec3> {
    all_finite(name, &p)?;
    if p == [0.0; 3] {
        return Err(invalid!(
            "{name} must be a non-zero homogeneous vector, got (0, 0, 0)"
        ));
    }
    Ok(normalized(p))
}

/// `l · p` relative to the lengths: 0 when `p` lies on `l`, whatever scales.
#[inline]
pub(crate) fn incidence(l: Vec3, p: Vec3) -> f64 {
    dot(l, p) / (norm(l) * norm(p))
}

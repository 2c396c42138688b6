//! Motion models between two colour channels: the 2x3 matrix of a warp and
//! the parameters Gauss-Newton updates.
//!
//! A warp `M` maps a reference pixel `(x, y)` (column, row) to the position
//! of the moving image that lands there: `moving(M (x, y, 1))` is the moving
//! channel registered onto the reference (OpenCV's `findTransformECC`
//! convention with the reference as template). The parameters live in
//! coordinates centred on the image: the rotation and scale of a plate are
//! about its middle, so centring keeps them nearly independent of the
//! translation, which makes the normal equations well conditioned.

use crate::error::Result;
use crate::invalid;

/// A 2x3 affine matrix, row-major: `[[a00, a01, tx], [a10, a11, ty]]`.
pub type Matrix = [[f64; 3]; 2];

/// The identity warp.
pub const IDENTITY: Matrix = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

/// Most parameters a motion has (affine).
pub const MAX_PARAMS: usize = 6;

/// The affine warp's derivatives at the identity, `(gx u, gx v, gx, gy u,
/// gy v, gy)` for a gradient `(gx, gy)` at centred position `(u, v)`: every
/// motion's are combinations of these six ([`Motion::affine_basis`]).
pub const AFFINE: usize = 6;

/// Which warps are searched.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Motion {
    /// `(tx, ty)`.
    Translation,
    /// A rotation and a translation: `(theta, tx, ty)`.
    Euclidean,
    /// Rotation, isotropic scale and translation: `(a, b, tx, ty)` with the
    /// linear part `[[a, -b], [b, a]]`.
    Similarity,
    /// Any affine map: the six entries of the matrix.
    Affine,
}

impl Motion {
    /// Parses `"translation"`, `"euclidean"`, `"similarity"` or `"affine"`.
    ///
    /// # Errors
    /// [`crate::CoreError::InvalidArgument`] naming the unknown motion.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "translation" => Ok(Self::Translation),
            "euclidean" => Ok(Self::Euclidean),
            "similarity" => Ok(Self::Similarity),
            "affine" => Ok(Self::Affine),
            other => Err(invalid!(
                "unknown motion {other:?}; accepted: \"translation\", \"euclidean\", \
                 \"similarity\", \"affine\""
            )),
        }
    }

    /// The motion's name with its indefinite article, for messages ("an
    /// affine motion"): `Debug` would print "a Affine".
    pub fn with_article(self) -> &'static str {
        match self {
            Self::Translation => "a translation",
            Self::Euclidean => "a Euclidean",
            Self::Similarity => "a similarity",
            Self::Affine => "an affine",
        }
    }

    /// Number of parameters.
    pub fn params(self) -> usize {
        match self {
            Self::Translation => 2,
            Self::Euclidean => 3,
            Self::Similarity => 4,
            Self::Affine => 6,
        }
    }

    /// How each parameter moves a point at the identity, in the affine
    /// parameters `(a00, a01, tx, a10, a11, ty)`: row `k` is the derivative
    /// of the affine parameters in parameter `k` (rows past `params()` are
    /// zero). A rotation `theta` moves `(u, v)` by `(-v, u)`, so its row
    /// is `a01 = -1, a10 = 1`; a similarity's `a` and `b` enter as
    /// `[[a, -b], [b, a]]`.
    pub fn affine_basis(self) -> [[f64; AFFINE]; MAX_PARAMS] {
        const TX: [f64; AFFINE] = [0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
        const TY: [f64; AFFINE] = [0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        const TURN: [f64; AFFINE] = [0.0, -1.0, 0.0, 1.0, 0.0, 0.0];
        const ZOOM: [f64; AFFINE] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        const NONE: [f64; AFFINE] = [0.0; AFFINE];
        match self {
            Self::Translation => [TX, TY, NONE, NONE, NONE, NONE],
            Self::Euclidean => [TURN, TX, TY, NONE, NONE, NONE],
            Self::Similarity => [ZOOM, TURN, TX, TY, NONE, NONE],
            Self::Affine => std::array::from_fn(|k| std::array::from_fn(|a| f64::from(k == a))),
        }
    }
}

/// A warp in the centred coordinates of one pyramid level: `u' = A u + t`
/// with `u = (x - cx, y - cy)` on both images (they have one size).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Centred {
    pub motion: Motion,
    /// The parameters, `motion.params()` of them used.
    pub p: [f64; MAX_PARAMS],
}

impl Centred {
    /// The warp of `m` (pixel coordinates of the level) about `centre`,
    /// projected onto `motion` (a rotation is read from the matrix's first
    /// column, a similarity from the average of its two).
    pub fn from_matrix(motion: Motion, m: &Matrix, centre: (f64, f64)) -> Self {
        let (cx, cy) = centre;
        // t_c = A c + t - c: the displacement of the centre.
        let tx = m[0][0] * cx + m[0][1] * cy + m[0][2] - cx;
        let ty = m[1][0] * cx + m[1][1] * cy + m[1][2] - cy;
        let mut p = [0.0; MAX_PARAMS];
        match motion {
            Motion::Translation => p[..2].copy_from_slice(&[tx, ty]),
            Motion::Euclidean => p[..3].copy_from_slice(&[m[1][0].atan2(m[0][0]), tx, ty]),
            Motion::Similarity => {
                let a = 0.5 * (m[0][0] + m[1][1]);
                let b = 0.5 * (m[1][0] - m[0][1]);
                p[..4].copy_from_slice(&[a, b, tx, ty]);
            }
            Motion::Affine => p.copy_from_slice(&[m[0][0], m[0][1], tx, m[1][0], m[1][1], ty]),
        }
        Self { motion, p }
    }

    /// The linear part `A` and the centre's displacement `t`.
    pub fn linear_and_shift(&self) -> ([[f64; 2]; 2], (f64, f64)) {
        let p = &self.p;
        match self.motion {
            Motion::Translation => ([[1.0, 0.0], [0.0, 1.0]], (p[0], p[1])),
            Motion::Euclidean => {
                let (s, c) = p[0].sin_cos();
                ([[c, -s], [s, c]], (p[1], p[2]))
            }
            Motion::Similarity => ([[p[0], -p[1]], [p[1], p[0]]], (p[2], p[3])),
            Motion::Affine => ([[p[0], p[1]], [p[3], p[4]]], (p[2], p[5])),
        }
    }

    /// The warp in pixel coordinates: `x' = A (x - c) + t + c`.
    pub fn matrix(&self, centre: (f64, f64)) -> Matrix {
        let (a, (tx, ty)) = self.linear_and_shift();
        let (cx, cy) = centre;
        [
            [a[0][0], a[0][1], tx + cx - a[0][0] * cx - a[0][1] * cy],
            [a[1][0], a[1][1], ty + cy - a[1][0] * cx - a[1][1] * cy],
        ]
    }

    /// The warp of `motion` whose parameters are `delta` away from the
    /// identity's (a Gauss-Newton step).
    pub fn increment(motion: Motion, delta: &[f64; MAX_PARAMS]) -> Self {
        let mut p = *delta;
        match motion {
            Motion::Translation | Motion::Euclidean => {}
            Motion::Similarity => p[0] += 1.0,
            Motion::Affine => {
                p[0] += 1.0;
                p[4] += 1.0;
            }
        }
        Self { motion, p }
    }

    /// `self` after the inverse of `step`: `x -> self(step^-1(x))`, the
    /// inverse-compositional update (both about the same centre); `None`
    /// when `step` is singular.
    pub fn then_inverse_of(&self, step: &Centred) -> Option<Self> {
        let origin = (0.0, 0.0);
        let m = compose(&self.matrix(origin), &invert(&step.matrix(origin))?);
        Some(Self::from_matrix(self.motion, &m, origin))
    }
}

/// `x -> outer(inner(x))`.
pub fn compose(outer: &Matrix, inner: &Matrix) -> Matrix {
    std::array::from_fn(|r| {
        let o = outer[r];
        [
            o[0] * inner[0][0] + o[1] * inner[1][0],
            o[0] * inner[0][1] + o[1] * inner[1][1],
            o[0] * inner[0][2] + o[1] * inner[1][2] + o[2],
        ]
    })
}

/// The matrix of a level `2^level` times coarser than the full resolution,
/// whose pixel `i` is the box average of full-resolution pixels `s i ..
/// s i + s - 1`, centred at `s i + (s - 1) / 2`.
pub fn to_level(m: &Matrix, level: usize) -> Matrix {
    let (s, o) = scale_offset(level);
    // x = s x_l + o on both sides: x'_l = (A (s x_l + o) + t - o) / s.
    let mut out = *m;
    for row in &mut out {
        row[2] = (row[0] * o + row[1] * o + row[2] - o) / s;
    }
    out
}

/// The inverse of [`to_level`].
pub fn from_level(m: &Matrix, level: usize) -> Matrix {
    let (s, o) = scale_offset(level);
    let mut out = *m;
    for row in &mut out {
        row[2] = s * row[2] + o - row[0] * o - row[1] * o;
    }
    out
}

fn scale_offset(level: usize) -> (f64, f64) {
    let s = (1u64 << level) as f64;
    (s, 0.5 * (s - 1.0))
}

/// The inverse of an affine matrix, `None` when it is singular.
pub fn invert(m: &Matrix) -> Option<Matrix> {
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    if !det.is_finite() || det.abs() < 1e-12 {
        return None;
    }
    let (a, b, c, d) = (m[1][1] / det, -m[0][1] / det, -m[1][0] / det, m[0][0] / det);
    Some([
        [a, b, -(a * m[0][2] + b * m[1][2])],
        [c, d, -(c * m[0][2] + d * m[1][2])],
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &Matrix, b: &Matrix) -> bool {
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .all(|(x, y)| (x - y).abs() < 1e-12)
    }

    #[test]
    fn centred_parameters_round_trip_the_matrix() {
        let (s, c) = (0.01f64.sin() * 1.002, 0.01f64.cos() * 1.002);
        let m = [[c, -s, 3.5], [s, c, -7.25]];
        for motion in [Motion::Similarity, Motion::Affine] {
            let p = Centred::from_matrix(motion, &m, (40.0, 30.0));
            assert!(close(&p.matrix((40.0, 30.0)), &m), "{motion:?}");
        }
        let r = [
            [0.01f64.cos(), -0.01f64.sin(), 3.5],
            [0.01f64.sin(), 0.01f64.cos(), 2.0],
        ];
        let p = Centred::from_matrix(Motion::Euclidean, &r, (40.0, 30.0));
        assert!((p.p[0] - 0.01).abs() < 1e-15);
        assert!(close(&p.matrix((40.0, 30.0)), &r));
    }

    #[test]
    fn the_affine_basis_is_each_motions_derivative_at_the_identity() {
        let eps = 1e-7;
        for motion in [
            Motion::Translation,
            Motion::Euclidean,
            Motion::Similarity,
            Motion::Affine,
        ] {
            let at = |d: &[f64; MAX_PARAMS]| Centred::increment(motion, d).matrix((0.0, 0.0));
            let base = at(&[0.0; MAX_PARAMS]);
            assert!(close(&base, &IDENTITY), "{motion:?}");
            let basis = motion.affine_basis();
            for k in 0..MAX_PARAMS {
                let mut d = [0.0; MAX_PARAMS];
                d[k] = eps;
                let m = at(&d);
                let flat = [m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2]];
                let id = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
                for a in 0..AFFINE {
                    // Parameters past params() must not move anything.
                    let want = if k < motion.params() {
                        basis[k][a]
                    } else {
                        0.0
                    };
                    assert!(
                        ((flat[a] - id[a]) / eps - want).abs() < 1e-6,
                        "{motion:?} {k} {a}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_warp_after_its_own_inverse_is_the_identity() {
        let w = Centred::from_matrix(
            Motion::Similarity,
            &[[1.01, -0.02, 5.0], [0.02, 1.01, -3.0]],
            (0.0, 0.0),
        );
        let id = w.then_inverse_of(&w).unwrap();
        assert!(close(&id.matrix((0.0, 0.0)), &IDENTITY), "{id:?}");
        let shift = Centred::increment(Motion::Translation, &[1.0, 2.0, 0.0, 0.0, 0.0, 0.0]);
        let moved = w.then_inverse_of(&shift).unwrap().matrix((0.0, 0.0));
        // w(x - (1, 2)): the linear part is w's, the offset moves by -A (1, 2).
        assert!(
            (moved[0][2] - (5.0 - 1.01 + 0.04)).abs() < 1e-12,
            "{moved:?}"
        );
        assert!(
            (moved[1][2] - (-3.0 - 0.02 - 2.02)).abs() < 1e-12,
            "{moved:?}"
        );
    }

    #[test]
    fn levels_and_inverse_compose_to_the_identity() {
        let m = [[1.01, -0.02, 5.0], [0.03, 0.99, -2.0]];
        assert!(close(&from_level(&to_level(&m, 3), 3), &m));
        let inv = invert(&m).unwrap();
        // M (M^-1 x) = x for the origin and a far point.
        for (x, y) in [(0.0, 0.0), (100.0, -50.0)] {
            let u = inv[0][0] * x + inv[0][1] * y + inv[0][2];
            let v = inv[1][0] * x + inv[1][1] * y + inv[1][2];
            let back = (
                m[0][0] * u + m[0][1] * v + m[0][2],
                m[1][0] * u + m[1][1] * v + m[1][2],
            );
            assert!((back.0 - x).abs() < 1e-9 && (back.1 - y).abs() < 1e-9);
        }
        assert!(invert(&[[1.0, 2.0, 0.0], [2.0, 4.0, 0.0]]).is_none());
        // A translation of 4 full-resolution pixels is 1 pixel at level 2.
        let t = to_level(&[[1.0, 0.0, 4.0], [0.0, 1.0, -8.0]], 2);
        assert!(close(&t, &[[1.0, 0.0, 1.0], [0.0, 1.0, -2.0]]));
    }
}

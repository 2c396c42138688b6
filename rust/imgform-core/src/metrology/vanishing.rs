//! Vanishing points fitted to image line segments.
//!
//! A segment `(p1, p2)` is consistent with a candidate
//! vanishing point `v` when the line through its midpoint `m` and `v` passes
//! through its end points; the residual is the distance of an end point from
//! that line (the same for both, since `m` is their midpoint). It is a
//! distance in pixels, so a threshold is meaningful, and it is a good
//! stand-in for the maximum-likelihood residual under isotropic end-point
//! noise (the measure of Rother 2002 and Tardif 2009). It is not weighted by
//! segment length: a long segment already counts for more because the same
//! angular error moves its end points further.
//!
//! Robustness is RANSAC with the MSAC cost (Torr, Zisserman 2000): each
//! hypothesis is the intersection of two segments' lines, scored by
//! `sum min(r², t²)`. With up to [`MAX_HYPOTHESES`] pairs every pair is tried
//! (deterministic, no seed involved); beyond, pairs are drawn from a
//! counter-based generator keyed by `(seed, hypothesis index)`. Why not IRLS:
//! it starts from an ordinary least-squares fit, which a single wild segment
//! can drag into the wrong basin (breakdown point zero); RANSAC needs no
//! starting point. The winner is refined by Levenberg-Marquardt on its
//! inliers, re-selecting inliers until they no longer change.
//!
//! All fitting runs in Hartley-normalised coordinates (end points centred,
//! mean distance √2; Hartley 1997) so the 3-vectors mix numbers of one
//! magnitude, and the vanishing point is a unit homogeneous 3-vector, so a
//! point at infinity (parallel image lines) is just `z = 0`, not an overflow.

use rayon::prelude::*;

use super::{cross, dot, Vec3, COINCIDENCE_TOLERANCE};
use crate::camera::{norm, normalized};
use crate::error::{positive, Result};
use crate::invalid;
use crate::random::SplitMix64;

/// The most RANSAC hypotheses tried. All pairs of up to 63 segments (1953
/// pairs) fit under it, so small problems are solved exhaustively. Above, with
/// half the segments outliers, the chance that none of 2000 random pairs is
/// all-inlier is `0.75^2000`, i.e. nil; a whole fit of 10 000 segments, half
/// of them outliers, takes ~50 ms of one core.
pub const MAX_HYPOTHESES: usize = 2000;

/// A fitted vanishing point whose homogeneous `z` is below this fraction of
/// its (unit) length counts as at infinity. In normalised coordinates the
/// segments span ~√2, so such a point lies 1e10 spans away: the image lines
/// then meet at angles below 1e-10 rad, which no pixel measurement resolves.
const INFINITY_TOLERANCE: f64 = 1e-10;

/// Inlier re-selection rounds after RANSAC. Each round is a refit; the set
/// settles in 2-3 rounds in practice, 10 bounds a set that oscillates.
const MAX_ROUNDS: usize = 10;

/// Levenberg-Marquardt iterations per refit; convergence from a RANSAC
/// start takes under 10.
const MAX_ITERATIONS: usize = 100;

/// How to fit a vanishing point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// Largest residual (pixels) of an inlier segment.
    pub threshold: f64,
    /// Seed of the hypothesis sampler, used only above [`MAX_HYPOTHESES`] pairs.
    pub seed: u64,
    /// Return a vanishing point at infinity instead of refusing it.
    pub allow_infinite: bool,
}

/// A vanishing point fitted to segments.
#[derive(Debug, Clone, PartialEq)]
pub struct VanishingFit {
    /// `(u, v, 1)` in pixels, or `(du, dv, 0)` with `du² + dv² = 1` (the
    /// common image direction, `du > 0`, or `dv > 0` when `du = 0`) at infinity.
    pub homogeneous: Vec3,
    /// `true` when the image lines are parallel.
    pub at_infinity: bool,
    /// Root-mean-square residual of the inliers, in pixels.
    pub residual: f64,
    /// Which segments are inliers.
    pub inliers: Vec<bool>,
}

/// Pixel <-> Hartley-normalised coordinates: `x' = s (x - c)`.
#[derive(Debug, Clone, Copy)]
struct Frame {
    cx: f64,
    cy: f64,
    s: f64,
}

impl Frame {
    /// The frame centring the end points with mean distance √2.
    fn of(segments: &[f64]) -> Self {
        let n = (segments.len() / 2) as f64;
        let (sx, sy) = segments
            .chunks_exact(2)
            .fold((0.0, 0.0), |(sx, sy), p| (sx + p[0], sy + p[1]));
        let (cx, cy) = (sx / n, sy / n);
        let mean = segments
            .chunks_exact(2)
            .map(|p| (p[0] - cx).hypot(p[1] - cy))
            .sum::<f64>()
            / n;
        Self {
            cx,
            cy,
            s: std::f64::consts::SQRT_2 / mean,
        }
    }

    fn point(&self, x: f64, y: f64) -> Vec3 {
        [(x - self.cx) * self.s, (y - self.cy) * self.s, 1.0]
    }

    /// A homogeneous point of the normalised frame in pixels.
    fn to_pixels(self, v: Vec3) -> Vec3 {
        [
            v[0] / self.s + self.cx * v[2],
            v[1] / self.s + self.cy * v[2],
            v[2],
        ]
    }
}

/// A segment in normalised coordinates.
#[derive(Debug, Clone, Copy)]
struct Segment {
    /// `p1 × m = (p1 × p2) / 2`: the segment's line, scaled so that
    /// `line · v` over `|v_xy - v_z m|` is the residual.
    line: Vec3,
    mid: [f64; 2],
    /// Half the length: the residual when `v` sits on the midpoint (any
    /// line through `m` is then as good as any other; this is the worst).
    half: f64,
}

impl Segment {
    fn new(frame: &Frame, s: &[f64]) -> Self {
        let p1 = frame.point(s[0], s[1]);
        let p2 = frame.point(s[2], s[3]);
        let c = cross(p1, p2);
        Self {
            line: [0.5 * c[0], 0.5 * c[1], 0.5 * c[2]],
            mid: [0.5 * (p1[0] + p2[0]), 0.5 * (p1[1] + p2[1])],
            half: 0.5 * (p2[0] - p1[0]).hypot(p2[1] - p1[1]),
        }
    }

    /// `v_xy - v_z m` (the direction from the midpoint to unit `v`) and its
    /// squared length, or `None` when `v` sits on the midpoint. Every `v`
    /// here is a unit vector (hypotheses and iterates are normalised), so an
    /// absolute tolerance is a relative one.
    #[inline]
    fn toward(&self, v: Vec3) -> Option<([f64; 2], f64)> {
        let w = [v[0] - v[2] * self.mid[0], v[1] - v[2] * self.mid[1]];
        let d2 = w[0] * w[0] + w[1] * w[1];
        (d2 > COINCIDENCE_TOLERANCE * COINCIDENCE_TOLERANCE).then_some((w, d2))
    }

    /// Signed distance of an end point from the line through the midpoint
    /// and unit `v`.
    #[inline]
    fn residual(&self, v: Vec3) -> f64 {
        match self.toward(v) {
            Some((_, d2)) => dot(self.line, v) / d2.sqrt(),
            None => self.half,
        }
    }

    /// The squared residual without a square root: RANSAC scores every
    /// segment against every hypothesis, and this is its inner loop.
    #[inline]
    fn residual_sq(&self, v: Vec3) -> f64 {
        match self.toward(v) {
            Some((_, d2)) => dot(self.line, v).powi(2) / d2,
            None => self.half * self.half,
        }
    }

    /// Gradient of [`Segment::residual`] with respect to `v`; zero where the
    /// residual is the constant `half`.
    fn gradient(&self, v: Vec3) -> Vec3 {
        let Some((w, d2)) = self.toward(v) else {
            return [0.0; 3];
        };
        // r = (line · v) / d, with d = |v_xy - v_z m|:
        // ∇d = (w_x, w_y, -m · w) / d, so ∇r = (line - r ∇d) / d.
        let d = d2.sqrt();
        let r = dot(self.line, v) / d;
        let grad_d = [w[0], w[1], -(self.mid[0] * w[0] + self.mid[1] * w[1])];
        [
            (self.line[0] - r * grad_d[0] / d) / d,
            (self.line[1] - r * grad_d[1] / d) / d,
            (self.line[2] - r * grad_d[2] / d) / d,
        ]
    }
}

/// Checks the segment buffer and returns the number of segments.
fn check_segments(segments: &[f64]) -> Result<usize> {
    if !segments.len().is_multiple_of(4) {
        return Err(invalid!(
            "segments must be (N, 4) values [x1, y1, x2, y2], got a buffer of {} values",
            segments.len()
        ));
    }
    let n = segments.len() / 4;
    if n < 2 {
        return Err(invalid!(
            "a vanishing point needs at least 2 segments, got {n}"
        ));
    }
    for (i, s) in segments.chunks_exact(4).enumerate() {
        if !s.iter().all(|c| c.is_finite()) {
            return Err(invalid!("segments must be finite, segment {i} is {s:?}"));
        }
        if s[0] == s[2] && s[1] == s[3] {
            return Err(invalid!(
                "segment {i} has zero length (both end points are ({}, {})): it has no direction",
                s[0],
                s[1]
            ));
        }
    }
    Ok(n)
}

/// The `k`-th of `count` RANSAC pairs: all pairs in order when they fit in
/// [`MAX_HYPOTHESES`], else a pair drawn from `(seed, k)` alone, so any
/// thread may draw any hypothesis.
fn hypothesis_pairs(n: usize, seed: u64) -> Vec<(usize, usize)> {
    if n.saturating_mul(n - 1) / 2 <= MAX_HYPOTHESES {
        return (0..n)
            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
            .collect();
    }
    (0..MAX_HYPOTHESES)
        .map(|k| {
            let mut g = SplitMix64::for_site(seed, k, 0);
            let i = (g.next_u64() % n as u64) as usize;
            let j = (g.next_u64() % (n as u64 - 1)) as usize;
            (i, if j >= i { j + 1 } else { j })
        })
        .collect()
}

/// The intersection of two segments' lines as a unit vector; `None` when
/// they are the same line.
fn intersect(a: &Segment, b: &Segment) -> Option<Vec3> {
    let v = cross(a.line, b.line);
    let n = norm(v);
    (n > COINCIDENCE_TOLERANCE * norm(a.line) * norm(b.line)).then(|| normalized(v))
}

/// MSAC cost: inliers pay their squared residual, outliers the threshold's.
fn msac_cost(segments: &[Segment], v: Vec3, t2: f64) -> f64 {
    segments.iter().map(|s| s.residual_sq(v).min(t2)).sum()
}

/// The best hypothesis over all pairs, by cost then by index, so the winner
/// is unique and the same for any thread count.
fn best_hypothesis(segments: &[Segment], t: f64, seed: u64) -> Result<Vec3> {
    let pairs = hypothesis_pairs(segments.len(), seed);
    let best = pairs
        .par_iter()
        .enumerate()
        .filter_map(|(k, &(i, j))| {
            let v = intersect(&segments[i], &segments[j])?;
            Some((msac_cost(segments, v, t * t), k, v))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    best.map(|(_, _, v)| v).ok_or_else(|| {
        invalid!(
            "all {} segments lie on one image line: their vanishing point could be anywhere on it",
            segments.len()
        )
    })
}

/// Two unit vectors spanning the tangent plane of the sphere at unit `v`.
fn tangent_basis(v: Vec3) -> (Vec3, Vec3) {
    // Cross with the axis least aligned with v, so the product is never small.
    let axis = if v[0].abs() <= v[1].abs() && v[0].abs() <= v[2].abs() {
        [1.0, 0.0, 0.0]
    } else if v[1].abs() <= v[2].abs() {
        [0.0, 1.0, 0.0]
    } else {
        [0.0, 0.0, 1.0]
    };
    let e1 = normalized(cross(v, axis));
    (e1, cross(v, e1))
}

/// Sum of squared residuals of the inliers.
fn cost(segments: &[Segment], inliers: &[bool], v: Vec3) -> f64 {
    segments
        .iter()
        .zip(inliers)
        .filter(|(_, &inl)| inl)
        .map(|(s, _)| s.residual_sq(v))
        .sum()
}

/// Gauss-Newton normal equations `(JᵀJ, Jᵀr)` in the tangent basis at `v`,
/// as `[jj00, jj01, jj11]` and `[jr0, jr1]`.
fn normal_equations(
    segments: &[Segment],
    inliers: &[bool],
    v: Vec3,
    (e1, e2): (Vec3, Vec3),
) -> ([f64; 3], [f64; 2]) {
    let mut jj = [0.0; 3];
    let mut jr = [0.0; 2];
    for (s, _) in segments.iter().zip(inliers).filter(|(_, &inl)| inl) {
        let g = s.gradient(v);
        let (j0, j1, r) = (dot(g, e1), dot(g, e2), s.residual(v));
        jj[0] += j0 * j0;
        jj[1] += j0 * j1;
        jj[2] += j1 * j1;
        jr[0] += j0 * r;
        jr[1] += j1 * r;
    }
    (jj, jr)
}

/// Levenberg-Marquardt on the unit sphere: minimises the inliers' squared
/// residuals over `v`, starting at unit `v`. Returns the refined `v` and
/// `JᵀJ` there (its conditioning tells whether `v` is determined).
fn refine(segments: &[Segment], inliers: &[bool], mut v: Vec3) -> (Vec3, [f64; 3]) {
    let mut current = cost(segments, inliers, v);
    let mut lambda = 1e-3;
    for _ in 0..MAX_ITERATIONS {
        let basis = tangent_basis(v);
        let (jj, jr) = normal_equations(segments, inliers, v, basis);
        // Marquardt's scaling of the diagonal, floored so a zero column
        // (all gradients zero) still gives a solvable system.
        let floor = 1e-12 * (jj[0] + jj[2]).max(f64::MIN_POSITIVE);
        let a00 = jj[0] + lambda * jj[0].max(floor);
        let a11 = jj[2] + lambda * jj[2].max(floor);
        let det = a00 * a11 - jj[1] * jj[1];
        let d0 = -(a11 * jr[0] - jj[1] * jr[1]) / det;
        let d1 = -(a00 * jr[1] - jj[1] * jr[0]) / det;
        let (e1, e2) = basis;
        let trial = normalized([
            v[0] + d0 * e1[0] + d1 * e2[0],
            v[1] + d0 * e1[1] + d1 * e2[1],
            v[2] + d0 * e1[2] + d1 * e2[2],
        ]);
        let next = cost(segments, inliers, trial);
        if next.is_finite() && next <= current {
            // 1e-12 of the unit vector is ~1e-12 of the segments' spread,
            // far below any pixel: further steps only chase rounding.
            let settled = current - next <= 1e-12 * current || d0.hypot(d1) <= 1e-12;
            (v, current, lambda) = (trial, next, lambda * 0.1);
            if settled {
                break;
            }
        } else {
            lambda *= 10.0;
            if lambda > 1e12 {
                break;
            }
        }
    }
    let (jj, _) = normal_equations(segments, inliers, v, tangent_basis(v));
    (v, jj)
}

/// Marks the segments within `t` of `v`; returns how many.
fn select_inliers(segments: &[Segment], v: Vec3, t: f64, inliers: &mut [bool]) -> usize {
    for (s, inl) in segments.iter().zip(inliers.iter_mut()) {
        *inl = s.residual(v).abs() <= t;
    }
    inliers.iter().filter(|&&b| b).count()
}

/// Least-squares vanishing point of image line segments `(N, 4)`
/// `[x1, y1, x2, y2]` in pixels, robust to outliers (see the module doc).
///
/// # Errors
/// A buffer that is not `(N, 4)`, fewer than 2 segments, non-finite or
/// zero-length segments, a non-positive threshold, all segments on one image
/// line or fewer than 2 inliers left (the point is then undetermined), and
/// parallel image lines (a vanishing point at infinity) unless
/// `allow_infinite`.
pub fn fit_vanishing_point(segments: &[f64], opts: &FitOptions) -> Result<VanishingFit> {
    let n = check_segments(segments)?;
    let threshold = positive("threshold", opts.threshold)?;
    let frame = Frame::of(segments);
    let segs: Vec<Segment> = segments
        .chunks_exact(4)
        .map(|s| Segment::new(&frame, s))
        .collect();
    let t = threshold * frame.s;
    let mut v = best_hypothesis(&segs, t, opts.seed)?;
    let mut inliers = vec![false; n];
    let mut count = select_inliers(&segs, v, t, &mut inliers);
    let mut jj = [0.0; 3];
    for _ in 0..MAX_ROUNDS {
        (v, jj) = refine(&segs, &inliers, v);
        let before = inliers.clone();
        count = select_inliers(&segs, v, t, &mut inliers);
        if inliers == before || count < 2 {
            break;
        }
    }
    check_determined(count, jj, threshold)?;
    let residual = (cost(&segs, &inliers, v) / count as f64).sqrt() / frame.s;
    // Decided in the normalised frame, where the tolerance means an angle
    // between the image lines: in pixels it would scale with the image.
    let at_infinity = v[2].abs() <= INFINITY_TOLERANCE * norm(v);
    let homogeneous = pixel_point(frame.to_pixels(v), at_infinity);
    if at_infinity && !opts.allow_infinite {
        return Err(invalid!(
            "the segments are parallel in the image: their vanishing point is at infinity, in direction ({:.6}, {:.6}); pass allow_infinite=True to get it as a homogeneous direction",
            homogeneous[0],
            homogeneous[1]
        ));
    }
    Ok(VanishingFit {
        homogeneous,
        at_infinity,
        residual,
        inliers,
    })
}

/// Refuses a fit left with too few inliers, or whose inliers all lie on one
/// line (`JᵀJ` then has a null direction: `v` can slide along that line).
fn check_determined(count: usize, jj: [f64; 3], threshold: f64) -> Result<()> {
    if count < 2 {
        return Err(invalid!(
            "fewer than 2 segments lie within threshold {threshold} px of the best vanishing point; raise the threshold"
        ));
    }
    // Eigenvalues of the symmetric 2x2 [[a, b], [b, c]].
    let (a, b, c) = (jj[0], jj[1], jj[2]);
    let mean = 0.5 * (a + c);
    let spread = (0.5 * (a - c)).hypot(b);
    if mean - spread <= COINCIDENCE_TOLERANCE * (mean + spread) {
        return Err(invalid!(
            "the {count} inlier segments all lie on one image line: their vanishing point could be anywhere on it"
        ));
    }
    Ok(())
}

/// Canonical pixel form of a homogeneous point: `(u, v, 1)`, or, `at_infinity`,
/// a unit direction `(du, dv, 0)` with `du > 0` (or `dv > 0` when `du = 0`).
fn pixel_point(p: Vec3, at_infinity: bool) -> Vec3 {
    if !at_infinity {
        return [p[0] / p[2], p[1] / p[2], 1.0];
    }
    let len = p[0].hypot(p[1]);
    let sign = if p[0] > 0.0 || (p[0] == 0.0 && p[1] > 0.0) {
        1.0
    } else {
        -1.0
    };
    [sign * p[0] / len, sign * p[1] / len, 0.0]
}

#[cfg(test)]
mod tests {
    use super::*;

    const OPTS: FitOptions = FitOptions {
        threshold: 1.0,
        seed: 0,
        allow_infinite: false,
    };

    /// Segments from the points `(x, y)` towards `vp`, `len` pixels long.
    fn towards(vp: [f64; 2], starts: &[[f64; 2]], len: f64) -> Vec<f64> {
        starts
            .iter()
            .flat_map(|&[x, y]| {
                let (dx, dy) = (vp[0] - x, vp[1] - y);
                let k = len / dx.hypot(dy);
                [x, y, x + k * dx, y + k * dy]
            })
            .collect()
    }

    #[test]
    fn exact_segments_meet_at_their_vanishing_point() {
        let segs = towards(
            [900.0, -150.0],
            &[[10.0, 400.0], [50.0, 20.0], [300.0, 300.0], [120.0, 250.0]],
            80.0,
        );
        let fit = fit_vanishing_point(&segs, &OPTS).unwrap();
        assert!(!fit.at_infinity);
        assert!((fit.homogeneous[0] - 900.0).abs() < 1e-8, "{fit:?}");
        assert!((fit.homogeneous[1] + 150.0).abs() < 1e-8, "{fit:?}");
        assert!(fit.residual < 1e-9 && fit.inliers.iter().all(|&b| b));
    }

    #[test]
    fn an_outlier_is_rejected() {
        let mut segs = towards(
            [400.0, 100.0],
            &[
                [0.0, 0.0],
                [0.0, 300.0],
                [100.0, 400.0],
                [50.0, 200.0],
                [10.0, 90.0],
            ],
            60.0,
        );
        segs.extend([300.0, 0.0, 310.0, 400.0]);
        let fit = fit_vanishing_point(&segs, &OPTS).unwrap();
        assert_eq!(fit.inliers, [true, true, true, true, true, false]);
        assert!((fit.homogeneous[0] - 400.0).abs() < 1e-8, "{fit:?}");
    }

    #[test]
    fn parallel_lines_are_refused_or_returned_at_infinity() {
        let segs = [
            0.0, 0.0, 10.0, 20.0, 5.0, 0.0, 15.0, 20.0, 9.0, 1.0, 19.0, 21.0,
        ];
        let err = fit_vanishing_point(&segs, &OPTS).unwrap_err().to_string();
        assert!(err.contains("parallel"), "{err}");
        let opts = FitOptions {
            allow_infinite: true,
            ..OPTS
        };
        let fit = fit_vanishing_point(&segs, &opts).unwrap();
        assert!(fit.at_infinity);
        let s = 1.0 / 5f64.sqrt();
        assert!(
            (fit.homogeneous[0] - s).abs() < 1e-12 && (fit.homogeneous[1] - 2.0 * s).abs() < 1e-12
        );
    }

    #[test]
    fn bad_segments_are_named() {
        let err = |s: &[f64]| fit_vanishing_point(s, &OPTS).unwrap_err().to_string();
        assert!(err(&[0.0, 0.0, 1.0, 1.0]).contains("at least 2"));
        assert!(err(&[0.0, 0.0, 1.0]).contains("(N, 4)"));
        assert!(
            err(&[0.0, 0.0, 1.0, 1.0, 2.0, 2.0, 2.0, 2.0]).contains("segment 1 has zero length")
        );
        assert!(err(&[0.0, 0.0, 1.0, f64::NAN, 2.0, 2.0, 3.0, 3.0]).contains("segment 0"));
        assert!(err(&[0.0, 0.0, 1.0, 1.0, 2.0, 2.0, 3.0, 3.0]).contains("one image line"));
    }

    #[test]
    fn sampled_hypotheses_are_a_pure_function_of_the_seed() {
        let a = hypothesis_pairs(100, 7);
        assert_eq!(a.len(), MAX_HYPOTHESES);
        assert_eq!(a, hypothesis_pairs(100, 7));
        assert_ne!(a, hypothesis_pairs(100, 8));
        assert!(a.iter().all(|&(i, j)| i != j && i < 100 && j < 100));
        assert_eq!(hypothesis_pairs(4, 0).len(), 6);
    }
}

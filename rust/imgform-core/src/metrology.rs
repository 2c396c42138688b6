//! Single-view metrology (lecture section 2.1, item 5): vanishing points
//! fitted to image line segments, the horizon through two of them, and the
//! heights of objects standing on the ground plane measured against one
//! reference object (Criminisi, Reid, Zisserman, "Single view metrology",
//! IJCV 40(2), 2000).
//!
//! **Vanishing points.** A segment `(p1, p2)` is consistent with a candidate
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
//!
//! **Heights.** With the horizon `l` (the ground's vanishing line) and the
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

use rayon::prelude::*;

use crate::camera::{norm, normalized};
use crate::cfa::SplitMix64;
use crate::error::{all_finite, positive, Result};
use crate::invalid;
use crate::parallel::map_points_indexed;
use crate::projection::check_points;

/// The most RANSAC hypotheses tried. All pairs of up to 63 segments (1953
/// pairs) fit under it, so small problems are solved exhaustively. Above, with
/// half the segments outliers, the chance that none of 2000 random pairs is
/// all-inlier is `0.75^2000`, i.e. nil; scoring them against 10 000 segments
/// takes ~20 ms on one core.
pub const MAX_HYPOTHESES: usize = 2000;

/// A fitted vanishing point whose homogeneous `z` is below this fraction of
/// its (unit) length counts as at infinity. In normalised coordinates the
/// segments span ~√2, so such a point lies 1e10 spans away: the image lines
/// then meet at angles below 1e-10 rad, which no pixel measurement resolves.
const INFINITY_TOLERANCE: f64 = 1e-10;

/// Relative size below which a cross product or an incidence `l · p`
/// counts as zero: two lines are the same line, a point lies on a line.
/// f64 rounding of pixel-sized coordinates leaves ~1e-16 relative, so 1e-12
/// flags only exact (up to rounding) coincidences, never a real scene.
const COINCIDENCE_TOLERANCE: f64 = 1e-12;

/// Inlier re-selection rounds after RANSAC. Each round is a refit; the set
/// settles in 2-3 rounds in practice, 10 bounds a set that oscillates.
const MAX_ROUNDS: usize = 10;

/// Levenberg-Marquardt iterations per refit; convergence from a RANSAC
/// start takes under 10.
const MAX_ITERATIONS: usize = 100;

type Vec3 = [f64; 3];

#[inline]
fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

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
    if segments.len() % 4 != 0 {
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
    let (homogeneous, at_infinity) = pixel_point(frame.to_pixels(v));
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

/// Canonical pixel form of a homogeneous point: `(u, v, 1)`, or a unit
/// direction `(du, dv, 0)` with `du > 0` (or `dv > 0` when `du = 0`).
fn pixel_point(p: Vec3) -> (Vec3, bool) {
    if p[2].abs() > INFINITY_TOLERANCE * norm(p) {
        return ([p[0] / p[2], p[1] / p[2], 1.0], false);
    }
    let len = p[0].hypot(p[1]);
    let sign = if p[0] > 0.0 || (p[0] == 0.0 && p[1] > 0.0) {
        1.0
    } else {
        -1.0
    };
    ([sign * p[0] / len, sign * p[1] / len, 0.0], true)
}

/// A finite, non-zero homogeneous 3-vector scaled to unit length.
fn unit(name: &str, p: Vec3) -> Result<Vec3> {
    all_finite(name, &p)?;
    if p == [0.0; 3] {
        return Err(invalid!(
            "{name} must be a non-zero homogeneous vector, got (0, 0, 0)"
        ));
    }
    Ok(normalized(p))
}

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

/// `l · p` relative to the lengths: 0 when `p` lies on `l`, whatever scales.
#[inline]
fn incidence(l: Vec3, p: Vec3) -> f64 {
    dot(l, p) / (norm(l) * norm(p))
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

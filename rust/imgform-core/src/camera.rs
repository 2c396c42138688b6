//! A full projective camera: intrinsics `K`, pose `(R, t)` and a lens.
//!
//! A world point `X` lands at `X_cam = R X + t` (world to camera, the
//! OpenCV/COLMAP frame: x right, y down, z forward), then at the normalised
//! point `(x, y) = (X_cam / Z_cam, Y_cam / Z_cam)`, then where the lens moves
//! that point (distortion acts in normalised coordinates, as in OpenCV), then
//! at the pixel `K (x_d, y_d, 1)`. Points at or behind the pinhole
//! (`Z_cam <= 0`) have no image and become NaN. The inverse direction goes
//! pixel -> normalised -> undistorted -> ray, which is why `unproject` and
//! `rays` undistort first.
//!
//! Points at infinity follow the same map with `t` dropped: a world direction
//! `d` is imaged at the homogeneous point `K R d` (its vanishing point), and a
//! plane with normal `n` has the vanishing line `K^-T R n`; the horizon is the
//! vanishing line of the ground plane.

use crate::distortion::Distortion;
use crate::error::{all_finite, CoreError, Result};
use crate::intrinsics::Intrinsics;
use crate::invalid;
use crate::parallel::{map_points, map_points_indexed};
use crate::projection::{check_points, reject_non_finite};

/// How far `R R^T` may be from the identity, and `det R` from 1, for `R` to
/// count as a rotation. Rotations composed or converted in f64 (Rodrigues,
/// quaternions, `look_at`) stay within ~1e-15; 1e-9 still admits matrices read
/// from text files with 10 significant digits, and refuses anything that
/// would visibly shear or scale the scene.
const ROTATION_TOLERANCE: f64 = 1e-9;

/// Below this fraction of its length, the depth (z) component of a
/// camera-frame direction counts as zero: the direction is parallel to the
/// image plane. A finite vanishing point would then lie more than 1e12 focal
/// lengths from the principal point, where f64 pixel coordinates carry no
/// sub-pixel information; reporting "at infinity" is the honest answer.
const PARALLEL_TOLERANCE: f64 = 1e-12;

/// A lens as the batch kernels see it: the camera's [`Distortion`], or
/// [`NoLens`] when that is the identity, so an undistorted camera's loops are
/// compiled without any distortion code instead of paying a model evaluation
/// (or a Newton step) per point.
trait Lens: Copy + Sync {
    fn distort(self, x: f64, y: f64) -> Option<(f64, f64)>;
    fn undistort(self, x: f64, y: f64) -> Option<(f64, f64)>;
}

/// The identity lens.
#[derive(Clone, Copy)]
struct NoLens;

impl Lens for NoLens {
    #[inline(always)]
    fn distort(self, x: f64, y: f64) -> Option<(f64, f64)> {
        Some((x, y))
    }

    #[inline(always)]
    fn undistort(self, x: f64, y: f64) -> Option<(f64, f64)> {
        Some((x, y))
    }
}

impl Lens for Distortion {
    #[inline(always)]
    fn distort(self, x: f64, y: f64) -> Option<(f64, f64)> {
        Distortion::distort(&self, x, y)
    }

    #[inline(always)]
    fn undistort(self, x: f64, y: f64) -> Option<(f64, f64)> {
        Distortion::undistort(&self, x, y)
    }
}

/// Evaluates `$body` with `$lens` bound to the camera's lens: [`NoLens`] when
/// the distortion is the identity, else the [`Distortion`] itself. The body
/// is compiled once for each.
macro_rules! with_lens {
    ($cam:expr, |$lens:ident| $body:expr) => {
        if $cam.dist.is_identity() {
            let $lens = NoLens;
            $body
        } else {
            let $lens = $cam.dist;
            $body
        }
    };
}

/// A pinhole camera with pose and lens distortion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Intrinsics `K`.
    pub k: Intrinsics,
    /// World-to-camera rotation, row-major.
    pub r: [f64; 9],
    /// World-to-camera translation: `X_cam = R X + t`.
    pub t: [f64; 3],
    /// Lens distortion, in normalised coordinates.
    pub dist: Distortion,
}

/// The image of the point at infinity along a world direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VanishingPoint {
    /// Pixel `(u, v)` where the lens puts the vanishing point; NaN when it is
    /// at infinity or the lens has no image of it.
    pub point: [f64; 2],
    /// The ideal (pinhole, undistorted) vanishing point: `(u, v, 1)` when
    /// finite; `(du, dv, 0)` with `du² + dv² = 1` when at infinity, i.e. the
    /// common image direction of the (then parallel) image lines.
    pub homogeneous: [f64; 3],
    /// `true` when the direction is parallel to the image plane.
    pub at_infinity: bool,
}

impl Camera {
    /// Builds a camera from a row-major `K`, a row-major rotation `R`, a
    /// translation `t` and a lens.
    ///
    /// # Errors
    /// A singular or malformed `K` (see [`Intrinsics::from_matrix`]),
    /// non-finite `R` or `t`, or an `R` that is not a rotation (not
    /// orthonormal, or a reflection with `det R = -1`).
    pub fn new(k: &[f64; 9], r: &[f64; 9], t: &[f64; 3], dist: Distortion) -> Result<Self> {
        let k = Intrinsics::from_matrix(k)?;
        check_rotation(r)?;
        all_finite("t", t)?;
        Ok(Self {
            k,
            r: *r,
            t: *t,
            dist,
        })
    }

    /// The camera centre in world coordinates, `-R^T t`.
    pub fn center(&self) -> [f64; 3] {
        let c = self.rotate_back([-self.t[0], -self.t[1], -self.t[2]]);
        [c[0], c[1], c[2]]
    }

    /// Projects world points `(N, 3)` to pixels `out` `(N, 2)`. Points at or
    /// behind the pinhole, and points the lens has no image of (the division
    /// model beyond its fold), become NaN.
    ///
    /// # Errors
    /// Non-finite coordinates or mismatched lengths.
    pub fn project(&self, points: &[f64], out: &mut [f64]) -> Result<()> {
        check_points(points, 3, out, 2)?;
        let bad = with_lens!(self, |lens| self.project_with(lens, points, out));
        reject_non_finite(bad, "points")
    }

    fn project_with<L: Lens>(&self, lens: L, points: &[f64], out: &mut [f64]) -> Option<usize> {
        let [r0, r1, r2, r3, r4, r5, r6, r7, r8] = self.r;
        let [t0, t1, t2] = self.t;
        let k = self.k;
        map_points(points, 3, out, 2, move |p, q| {
            let (x, y, z) = (p[0], p[1], p[2]);
            let zc = r6 * x + r7 * y + r8 * z + t2;
            let w = if zc > 0.0 { 1.0 / zc } else { f64::NAN };
            let xn = (r0 * x + r1 * y + r2 * z + t0) * w;
            let yn = (r3 * x + r4 * y + r5 * z + t1) * w;
            let (u, v) = match lens.distort(xn, yn) {
                Some((xd, yd)) => k.to_pixel(xd, yd),
                None => (f64::NAN, f64::NAN),
            };
            q[0] = u;
            q[1] = v;
            x.is_finite() & y.is_finite() & z.is_finite()
        })
    }

    /// The world points `out` `(N, 3)` seen at pixels `(N, 2)` at camera-frame
    /// depths `depth` `(N,)` (z, not distance along the ray). Depths `<= 0` and
    /// pixels the lens inverse cannot map give NaN.
    ///
    /// # Errors
    /// Non-finite pixels or depths, or mismatched lengths.
    pub fn unproject(&self, pixels: &[f64], depth: &[f64], out: &mut [f64]) -> Result<()> {
        let n = check_points(pixels, 2, out, 3)?;
        if depth.len() != n {
            return Err(CoreError::Shape(format!(
                "depth must hold one value per pixel ({n}), got {}",
                depth.len()
            )));
        }
        reject_non_finite(depth.iter().position(|z| !z.is_finite()), "depth")?;
        let bad = with_lens!(self, |lens| self.unproject_with(lens, pixels, depth, out));
        reject_non_finite(bad, "pixels")
    }

    fn unproject_with<L: Lens>(
        &self,
        lens: L,
        pixels: &[f64],
        depth: &[f64],
        out: &mut [f64],
    ) -> Option<usize> {
        let cam = *self;
        map_points_indexed(pixels, 2, out, 3, move |i, p, q| {
            let z = if depth[i] > 0.0 { depth[i] } else { f64::NAN };
            let world = match cam.ray_camera(lens, p[0], p[1]) {
                Some([x, y, _]) => {
                    cam.rotate_back([x * z - cam.t[0], y * z - cam.t[1], z - cam.t[2]])
                }
                None => [f64::NAN; 3],
            };
            q.copy_from_slice(&world);
            p[0].is_finite() & p[1].is_finite()
        })
    }

    /// Unit world directions `out` `(N, 3)` of the rays through pixels
    /// `(N, 2)`, pointing forward (into the scene). NaN where the lens
    /// inverse cannot map a pixel.
    ///
    /// # Errors
    /// Non-finite pixels or mismatched lengths.
    pub fn rays(&self, pixels: &[f64], out: &mut [f64]) -> Result<()> {
        check_points(pixels, 2, out, 3)?;
        let bad = with_lens!(self, |lens| self.rays_with(lens, pixels, out));
        reject_non_finite(bad, "pixels")
    }

    fn rays_with<L: Lens>(&self, lens: L, pixels: &[f64], out: &mut [f64]) -> Option<usize> {
        let cam = *self;
        map_points(pixels, 2, out, 3, move |p, q| {
            let dir = match cam.ray_camera(lens, p[0], p[1]) {
                Some(d) => cam.rotate_back(normalized(d)),
                None => [f64::NAN; 3],
            };
            q.copy_from_slice(&dir);
            p[0].is_finite() & p[1].is_finite()
        })
    }

    /// Horizontal, vertical and diagonal field of view (radians) of a
    /// `width` x `height` image: the angles between the rays through the
    /// outer edges of opposite border pixels (pixel centres are integers, so
    /// the image spans `[-0.5, width - 0.5]`). Horizontal uses the row of the
    /// principal point, vertical its column, diagonal the two corners
    /// top-left and bottom-right. The rays are undistorted, so this is the
    /// field the real lens sees; an edge the lens inverse cannot map gives NaN.
    ///
    /// # Errors
    /// A zero width or height.
    pub fn field_of_view(&self, width: usize, height: usize) -> Result<[f64; 3]> {
        if width == 0 || height == 0 {
            return Err(invalid!(
                "image size must be positive, got width {width} and height {height}"
            ));
        }
        let (right, bottom) = (width as f64 - 0.5, height as f64 - 0.5);
        let (cx, cy) = (self.k.cx, self.k.cy);
        let angle = |a: (f64, f64), b: (f64, f64)| match (
            self.ray_camera(self.dist, a.0, a.1),
            self.ray_camera(self.dist, b.0, b.1),
        ) {
            (Some(p), Some(q)) => angle_between(p, q),
            _ => f64::NAN,
        };
        Ok([
            angle((-0.5, cy), (right, cy)),
            angle((cx, -0.5), (cx, bottom)),
            angle((-0.5, -0.5), (right, bottom)),
        ])
    }

    /// The vanishing point of world direction `direction`: the image of the
    /// point at infinity along it, where the images of all lines parallel to
    /// it meet. `d` and `-d` share it. With a lens, `point` is the distorted
    /// image of the finite ideal vanishing point (the images of the lines are
    /// then curves through it); `homogeneous` stays the ideal one.
    ///
    /// # Errors
    /// A non-finite or zero direction.
    pub fn vanishing_point(&self, direction: [f64; 3]) -> Result<VanishingPoint> {
        let d = self.rotate(nonzero("direction", direction)?);
        let length = norm(d);
        if d[2].abs() <= PARALLEL_TOLERANCE * length {
            // Parallel to the image plane: K (dx, dy, 0) is a pure image direction.
            let (du, dv) = (self.k.fx * d[0] + self.k.skew * d[1], self.k.fy * d[1]);
            let len = du.hypot(dv);
            return Ok(VanishingPoint {
                point: [f64::NAN; 2],
                homogeneous: [du / len, dv / len, 0.0],
                at_infinity: true,
            });
        }
        let (x, y) = (d[0] / d[2], d[1] / d[2]);
        let (u, v) = self.k.to_pixel(x, y);
        let point = match self.dist.distort(x, y) {
            Some((xd, yd)) => {
                let (ud, vd) = self.k.to_pixel(xd, yd);
                [ud, vd]
            }
            None => [f64::NAN; 2],
        };
        Ok(VanishingPoint {
            point,
            homogeneous: [u, v, 1.0],
            at_infinity: false,
        })
    }

    /// The vanishing line `(a, b, c)` of planes with world normal
    /// `plane_normal`, scaled so that `a² + b² = 1` (then `a u + b v + c` is
    /// the signed distance in pixels from the line): `K^-T R n`. It is the
    /// line of the ideal pinhole image; with a lens its image is a curve. The
    /// horizon is the vanishing line of the ground plane. A plane parallel to
    /// the image plane vanishes at the line at infinity, returned as
    /// `(0, 0, 1)`.
    ///
    /// # Errors
    /// A non-finite or zero normal.
    pub fn vanishing_line(&self, plane_normal: [f64; 3]) -> Result<[f64; 3]> {
        // Rescaled: a normal of 5e-324s underflowed into a NaN line.
        let m = self.rotate(rescaled(nonzero("plane_normal", plane_normal)?));
        if m[0].hypot(m[1]) <= PARALLEL_TOLERANCE * norm(m) {
            return Ok([0.0, 0.0, 1.0]);
        }
        // K^-T m, written out for K = [[fx, s, cx], [0, fy, cy], [0, 0, 1]]:
        // a point p lies on the line exactly when the ray K^-1 p is
        // perpendicular to m.
        let Intrinsics {
            fx,
            fy,
            cx,
            cy,
            skew,
        } = self.k;
        let a = m[0] / fx;
        let b = (m[1] - skew * a) / fy;
        let c = m[2] - cx * a - cy * b;
        let len = a.hypot(b);
        Ok([a / len, b / len, c / len])
    }

    /// The undistorted camera-frame ray `(x, y, 1)` through pixel `(u, v)`.
    #[inline(always)]
    fn ray_camera<L: Lens>(&self, lens: L, u: f64, v: f64) -> Option<[f64; 3]> {
        let (xd, yd) = self.k.to_normalized(u, v);
        let (x, y) = lens.undistort(xd, yd)?;
        Some([x, y, 1.0])
    }

    /// `R v`: world to camera.
    #[inline]
    fn rotate(&self, v: [f64; 3]) -> [f64; 3] {
        let r = &self.r;
        [
            r[0] * v[0] + r[1] * v[1] + r[2] * v[2],
            r[3] * v[0] + r[4] * v[1] + r[5] * v[2],
            r[6] * v[0] + r[7] * v[1] + r[8] * v[2],
        ]
    }

    /// `R^T v`: camera to world (the inverse rotation).
    #[inline]
    fn rotate_back(&self, v: [f64; 3]) -> [f64; 3] {
        let r = &self.r;
        [
            r[0] * v[0] + r[3] * v[1] + r[6] * v[2],
            r[1] * v[0] + r[4] * v[1] + r[7] * v[2],
            r[2] * v[0] + r[5] * v[1] + r[8] * v[2],
        ]
    }
}

/// Checks that `r` is orthonormal with determinant +1.
fn check_rotation(r: &[f64; 9]) -> Result<()> {
    all_finite("R", r)?;
    let mut worst: f64 = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            let dot: f64 = (0..3).map(|k| r[3 * i + k] * r[3 * j + k]).sum();
            let expected = if i == j { 1.0 } else { 0.0 };
            worst = worst.max((dot - expected).abs());
        }
    }
    if worst > ROTATION_TOLERANCE {
        return Err(invalid!(
            "R must be a rotation matrix (orthonormal, det +1): R R^T differs from the identity by {worst:.3e} (tolerance {ROTATION_TOLERANCE:e}); rows {:?}, {:?}, {:?}",
            &r[0..3],
            &r[3..6],
            &r[6..9]
        ));
    }
    let det = r[0] * (r[4] * r[8] - r[5] * r[7]) - r[1] * (r[3] * r[8] - r[5] * r[6])
        + r[2] * (r[3] * r[7] - r[4] * r[6]);
    if (det - 1.0).abs() > ROTATION_TOLERANCE {
        return Err(invalid!(
            "R must be a rotation matrix (det +1), got det {det} (a reflection); flip the sign of one axis"
        ));
    }
    Ok(())
}

/// Checks that a direction is finite and not the zero vector.
fn nonzero(name: &str, v: [f64; 3]) -> Result<[f64; 3]> {
    all_finite(name, &v)?;
    if v == [0.0; 3] {
        return Err(invalid!("{name} must be a non-zero vector, got (0, 0, 0)"));
    }
    Ok(v)
}

#[inline]
pub(crate) fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// `v` at unit length. Where its squares would lose precision or overflow
/// (components beyond 1e-150..1e150, as a homogeneous line or point of any
/// scale may have), it is scaled by its largest component first: a horizon times
/// 1e160 normalised to a zero vector, the line at infinity. Other vectors
/// keep the bits of the plain division.
#[inline]
pub(crate) fn normalized(v: [f64; 3]) -> [f64; 3] {
    let s = rescaled(v);
    let n = norm(s);
    [s[0] / n, s[1] / n, s[2] / n]
}

/// `v` itself, or, with components beyond 1e-150..1e150, `v` divided by its
/// largest: the same direction, whose squares neither underflow nor
/// overflow.
#[inline]
fn rescaled(v: [f64; 3]) -> [f64; 3] {
    let top = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if (1e-150..=1e150).contains(&top) || top == 0.0 || !top.is_finite() {
        return v;
    }
    [v[0] / top, v[1] / top, v[2] / top]
}

/// The angle between two vectors, accurate also near 0 and pi (unlike `acos`).
fn angle_between(a: [f64; 3], b: [f64; 3]) -> f64 {
    let cross = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    norm(cross).atan2(a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    const K: [f64; 9] = [800.0, 0.0, 320.0, 0.0, 780.0, 240.0, 0.0, 0.0, 1.0];
    const IDENTITY: [f64; 9] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    const NO_LENS: Distortion = Distortion::BrownConrady([0.0; 8]);

    /// A rotation by `angle` about the y axis (yaw).
    fn yaw(angle: f64) -> [f64; 9] {
        let (s, c) = angle.sin_cos();
        [c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c]
    }

    #[test]
    fn vectors_of_any_scale_normalise_to_the_same_direction() {
        let v = [3.0, -4.0, 12.0];
        let want = normalized(v);
        assert_eq!(want, [3.0 / 13.0, -4.0 / 13.0, 12.0 / 13.0]);
        for scale in [1e-200, 1e-160, 1e160, 1e300] {
            let got = normalized([v[0] * scale, v[1] * scale, v[2] * scale]);
            for (g, w) in got.iter().zip(want) {
                assert!((g - w).abs() < 1e-15, "{scale}: {got:?}");
            }
        }
    }

    #[test]
    fn project_matches_hand_computed_pixel() {
        // R = I, t = (0, 0, 1): X = (1, 2, 3) -> X_cam = (1, 2, 4) -> (0.25, 0.5)
        // -> u = 800 * 0.25 + 320 = 520, v = 780 * 0.5 + 240 = 630.
        let cam = Camera::new(&K, &IDENTITY, &[0.0, 0.0, 1.0], NO_LENS).unwrap();
        let mut out = [0.0; 4];
        cam.project(&[1.0, 2.0, 3.0, 0.0, 0.0, -1.0], &mut out)
            .unwrap();
        assert_eq!(out[..2], [520.0, 630.0]);
        assert!(out[2].is_nan() && out[3].is_nan(), "z_cam = 0 has no image");
    }

    #[test]
    fn unproject_and_rays_invert_project_through_a_lens() {
        let lens = Distortion::new("brown_conrady", &[-0.2, 0.05, 1e-3, -1e-3, 0.0]).unwrap();
        let cam = Camera::new(&K, &yaw(0.3), &[0.2, -0.1, 2.0], lens).unwrap();
        let world = [0.5, -0.4, 3.0, -1.0, 0.3, 6.0];
        let mut pix = [0.0; 4];
        cam.project(&world, &mut pix).unwrap();
        let depth: Vec<f64> = world
            .chunks(3)
            .map(|p| cam.rotate([p[0], p[1], p[2]])[2] + cam.t[2])
            .collect();
        let mut back = [0.0; 6];
        cam.unproject(&pix, &depth, &mut back).unwrap();
        let mut dirs = [0.0; 6];
        cam.rays(&pix, &mut dirs).unwrap();
        let c = cam.center();
        for i in 0..2 {
            let to_point: Vec<f64> = (0..3).map(|j| world[3 * i + j] - c[j]).collect();
            let dist = norm([to_point[0], to_point[1], to_point[2]]);
            for j in 0..3 {
                assert!((back[3 * i + j] - world[3 * i + j]).abs() < 1e-9);
                assert!((dirs[3 * i + j] - to_point[j] / dist).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn non_positive_depth_gives_nan_and_bad_depth_count_is_refused() {
        let cam = Camera::new(&K, &IDENTITY, &[0.0; 3], NO_LENS).unwrap();
        let mut out = [0.0; 3];
        cam.unproject(&[320.0, 240.0], &[-1.0], &mut out).unwrap();
        assert!(out.iter().all(|v| v.is_nan()));
        assert!(cam
            .unproject(&[320.0, 240.0], &[1.0, 2.0], &mut out)
            .is_err());
        let err = cam
            .unproject(&[320.0, 240.0], &[f64::NAN], &mut out)
            .unwrap_err();
        assert!(err.to_string().contains("depth"), "{err}");
    }

    #[test]
    fn non_rotations_are_refused() {
        let scaled = [2.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let err = Camera::new(&K, &scaled, &[0.0; 3], NO_LENS).unwrap_err();
        assert!(err.to_string().contains("orthonormal"), "{err}");
        let mirror = [-1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let err = Camera::new(&K, &mirror, &[0.0; 3], NO_LENS).unwrap_err();
        assert!(err.to_string().contains("det -1"), "{err}");
    }

    #[test]
    fn fov_of_a_centred_camera_is_twice_the_half_angle() {
        // width 641: the image spans 641 px about cx = 320, so tan(h / 2) = 320.5 / 800.
        let cam = Camera::new(&K, &IDENTITY, &[0.0; 3], NO_LENS).unwrap();
        let [h, v, d] = cam.field_of_view(641, 481).unwrap();
        assert!((h - 2.0 * (320.5f64 / 800.0).atan()).abs() < 1e-15);
        assert!((v - 2.0 * (240.5f64 / 780.0).atan()).abs() < 1e-15);
        let half_diag = (320.5f64 / 800.0).hypot(240.5 / 780.0);
        assert!((d - 2.0 * half_diag.atan()).abs() < 1e-15);
        assert!(cam.field_of_view(0, 10).is_err());
    }

    #[test]
    fn vanishing_points_finite_and_at_infinity() {
        let cam = Camera::new(&K, &IDENTITY, &[0.0; 3], NO_LENS).unwrap();
        let forward = cam.vanishing_point([0.0, 0.0, -5.0]).unwrap();
        assert!(!forward.at_infinity);
        assert_eq!(forward.point, [320.0, 240.0]);
        let sideways = cam.vanishing_point([0.0, 2.0, 0.0]).unwrap();
        assert!(sideways.at_infinity && sideways.point[0].is_nan());
        assert_eq!(sideways.homogeneous, [0.0, 1.0, 0.0]);
        assert!(cam.vanishing_point([0.0; 3]).is_err());
    }

    #[test]
    fn horizon_of_a_level_camera_is_the_principal_row() {
        // Ground normal along -y (up, in the y-down camera frame): the horizon
        // is v = cy, i.e. (0, 1, -cy) up to sign.
        let cam = Camera::new(&K, &yaw(0.7), &[1.0, 2.0, 3.0], NO_LENS).unwrap();
        let [a, b, c] = cam.vanishing_line([0.0, -1.0, 0.0]).unwrap();
        assert!(a.abs() < 1e-15 && (b.abs() - 1.0).abs() < 1e-15);
        assert!((c / b + 240.0).abs() < 1e-12);
        let facing = cam
            .vanishing_line(cam.rotate_back([0.0, 0.0, 1.0]))
            .unwrap();
        assert_eq!(facing, [0.0, 0.0, 1.0]);
        // A normal of any scale is the same plane (5e-324s gave NaN).
        let line = cam.vanishing_line([1.0, 1.0, 0.0]).unwrap();
        for scale in [5e-324, 1e-200, 1e200] {
            let scaled = cam.vanishing_line([scale, scale, 0.0]).unwrap();
            assert!(
                (0..3).all(|i| (scaled[i] - line[i]).abs() < 1e-12),
                "{scaled:?}"
            );
        }
    }
}

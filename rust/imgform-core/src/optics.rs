//! The thin lens and its phenomena (lecture sections 3.1-3.2).
//!
//! Every formula is a scalar function with its own domain checks; the
//! vectorised entry points run one of them over many elements through
//! [`vectorised`], so each formula exists exactly once.
//!
//! Units: all lengths (focal length `f`, object distance `D`, image distance
//! `D'`, focus distance `S`, circle of confusion, sensor size) are in one
//! consistent unit; the docs use millimetres. The f-number `N` is
//! dimensionless, angles are radians. Distances are measured from the lens
//! (thin, in air), object side positive, image side positive.

use rayon::prelude::*;

use crate::error::{positive, CoreError, Result};
use crate::invalid;
use crate::parallel::POINTS_PER_TASK;

/// Checks that an object distance lies beyond the focal length.
///
/// An object at `D <= f` has no real image: at `D = f` the rays leave the
/// lens parallel, inside `f` they diverge and only a virtual image forms.
fn beyond_focal_length(name: &str, d: f64, f: f64) -> Result<f64> {
    if d.is_finite() && d > f {
        Ok(d)
    } else {
        Err(invalid!(
            "{name} must be finite and greater than the focal length f = {f} \
             (an object at or inside the focal length forms no real image), got {name} = {d}"
        ))
    }
}

/// Image distance `D'` from the thin-lens law `1/D' + 1/D = 1/f`, i.e.
/// `D' = f D / (D - f)`.
///
/// It falls towards `f` as `D` grows (an object at infinity is imaged in the
/// focal plane) and grows without bound as `D` approaches `f`.
///
/// # Errors
/// `f` not finite and positive, or `D` not finite or not beyond `f`.
pub fn image_distance(f: f64, d: f64) -> Result<f64> {
    let f = positive("f", f)?;
    let d = beyond_focal_length("D", d, f)?;
    // f / (1 - f/D) rather than f D / (D - f): no overflow of f D for huge D.
    Ok(f / (1.0 - f / d))
}

/// Lateral magnification magnitude `m = D'/D = f / (D - f)`.
///
/// Sign convention: the magnitude is returned (positive). The real image of a
/// thin lens is inverted, so the signed lateral magnification is `-m`, in line
/// with the inverted pinhole image `x' = -f x / z` of CONVENTIONS.md.
///
/// # Errors
/// As [`image_distance`].
pub fn magnification(f: f64, d: f64) -> Result<f64> {
    Ok(image_distance(f, d)? / d)
}

/// Diameter of the circle of confusion on the sensor for an object at `D`
/// when the lens (focal length `f`, f-number `N`) is focused at `S`.
///
/// The aperture diameter is `A = f/N`; the sensor sits at `S'`, the image of
/// the object at `D'`; the cone of rays converging to `D'` cuts the sensor in
/// a disc of diameter `A |S' - D'| / D'`, which simplifies to
/// `c = A |D - S| / D * f / (S - f)`. It is 0 at `D = S`, grows monotonically
/// on both sides, and tends to `A f / (S - f)` as `D -> inf`.
///
/// # Errors
/// `f`, `N` not finite and positive; `S` or `D` not finite or not beyond `f`.
pub fn circle_of_confusion(f: f64, n: f64, focus_distance: f64, d: f64) -> Result<f64> {
    let f = positive("f", f)?;
    let n = positive("N", n)?;
    let s = beyond_focal_length("focus_distance", focus_distance, f)?;
    let d = beyond_focal_length("D", d, f)?;
    Ok(f / n * (d - s).abs() / d * f / (s - f))
}

/// Hyperfocal distance `H = f^2 / (N c) + f`: focused there, everything from
/// `H/2` (approximately) to infinity has a circle of confusion of at most `c`.
///
/// # Errors
/// `f`, `N` or `coc` not finite and positive.
pub fn hyperfocal_distance(f: f64, n: f64, coc: f64) -> Result<f64> {
    let f = positive("f", f)?;
    let n = positive("N", n)?;
    let c = positive("coc", coc)?;
    Ok(f * f / (n * c) + f)
}

/// Depth of field `(near, far)` of a lens focused at `S` for the acceptable
/// circle of confusion `coc`: the distances where [`circle_of_confusion`]
/// equals `coc` exactly,
/// `near = S (H - f) / (H + S - 2f)`, `far = S (H - f) / (H - S)`,
/// with `far = +inf` when `S >= H` (focused at or beyond the hyperfocal
/// distance). Always `f < near < S < far`.
///
/// # Errors
/// `f`, `N`, `coc` not finite and positive, `coc >= f/N`, or `S` not finite
/// or not beyond `f`.
pub fn depth_of_field(f: f64, n: f64, focus_distance: f64, coc: f64) -> Result<[f64; 2]> {
    let h = hyperfocal_distance(f, n, coc)?;
    let s = beyond_focal_length("focus_distance", focus_distance, f)?;
    // In front of the focus the blur never exceeds the aperture diameter
    // (it tends to A as D -> f), so a tolerance of A or more has no near limit.
    let aperture = f / n;
    if coc >= aperture {
        return Err(invalid!(
            "coc must be smaller than the aperture diameter f/N = {aperture} \
             (no object beyond f is blurred more than that), got coc = {coc}"
        ));
    }
    // H - f computed directly: for long lenses H is much larger than f and
    // the difference would lose digits.
    let k = f * f / (n * coc);
    let near = s * k / (k + (s - f));
    let far = if s >= h {
        f64::INFINITY
    } else {
        s * k / (h - s)
    };
    Ok([near, far])
}

/// Angular field of view `2 atan(size / (2 f))` in radians across a sensor
/// dimension `size` (width, height or diagonal), for a lens focused at
/// infinity (image distance `f`).
///
/// # Errors
/// `f` or `sensor_size` not finite and positive.
pub fn field_of_view(f: f64, sensor_size: f64) -> Result<f64> {
    let f = positive("f", f)?;
    let size = positive("sensor_size", sensor_size)?;
    Ok(2.0 * (size / (2.0 * f)).atan())
}

/// Focal length that keeps a subject's image the same size when the camera
/// moves from distance `d0` (with focal length `f0`) to `d`: `f = f0 d / d0`.
///
/// This is exact for the thin lens, not only the pinhole approximation: the
/// thin-lens magnification `f / (D - f)` stays at `f0 / (d0 - f0)` exactly
/// when `f / D` stays at `f0 / d0`.
///
/// # Errors
/// `f0`, `d` not finite and positive, or `d0` not finite or not beyond `f0`.
pub fn dolly_zoom_focal_length(f0: f64, d0: f64, d: f64) -> Result<f64> {
    let f0 = positive("f0", f0)?;
    let d0 = beyond_focal_length("d0", d0, f0)?;
    let d = positive("d", d)?;
    Ok(f0 * d / d0)
}

/// Fills `out[i] = f(i)` in parallel chunks of [`POINTS_PER_TASK`] elements.
///
/// On failure returns the error of the smallest failing index together with
/// that index, the same whatever the thread count. A chunk stops at its first
/// failure, so a bad input costs no more than a good one.
///
/// # Errors
/// The first `(index, error)` for which `f` failed.
pub fn try_fill<O, F>(out: &mut [O], f: F) -> std::result::Result<(), (usize, CoreError)>
where
    O: Send,
    F: Fn(usize) -> Result<O> + Sync,
{
    out.par_chunks_mut(POINTS_PER_TASK)
        .enumerate()
        .filter_map(|(chunk, dst)| {
            let start = chunk * POINTS_PER_TASK;
            dst.iter_mut()
                .enumerate()
                .find_map(|(i, o)| match f(start + i) {
                    Ok(v) => {
                        *o = v;
                        None
                    }
                    Err(e) => Some((start + i, e)),
                })
        })
        .min_by_key(|(i, _)| *i)
        .map_or(Ok(()), Err)
}

/// Runs a scalar formula over `K` equally long input arrays (already
/// broadcast against each other by the caller) into `out`.
///
/// This is the one elementwise driver behind every vectorised optics
/// function: `vectorised([&f, &d], &mut out, |[f, d]| image_distance(f, d))`.
///
/// # Errors
/// [`CoreError::Shape`] when the lengths differ; otherwise the formula's own
/// error for the first failing element, naming that element when there is
/// more than one.
pub fn vectorised<const K: usize, O, F>(inputs: [&[f64]; K], out: &mut [O], f: F) -> Result<()>
where
    O: Send,
    F: Fn([f64; K]) -> Result<O> + Sync,
{
    let n = out.len();
    if let Some(bad) = inputs.iter().find(|s| s.len() != n) {
        return Err(CoreError::Shape(format!(
            "all inputs must have {n} elements after broadcasting, got one with {}",
            bad.len()
        )));
    }
    try_fill(out, |i| f(inputs.map(|s| s[i]))).map_err(|(i, e)| match e {
        CoreError::InvalidArgument(msg) if n > 1 => invalid!("{msg} (at element {i})"),
        other => other,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
    }

    #[test]
    fn thin_lens_law_holds() {
        let (f, d) = (50.0, 2000.0);
        let di = image_distance(f, d).unwrap();
        assert!(close(1.0 / di + 1.0 / d, 1.0 / f));
        assert!(close(magnification(f, d).unwrap(), di / d));
        // Unit magnification at D = 2f.
        assert!(close(magnification(f, 2.0 * f).unwrap(), 1.0));
    }

    #[test]
    fn object_inside_focal_length_is_refused() {
        let err = image_distance(50.0, 30.0).unwrap_err().to_string();
        assert!(
            err.contains("no real image") && err.contains("D = 30"),
            "{err}"
        );
        assert!(image_distance(50.0, 50.0).is_err());
        assert!(image_distance(0.0, 100.0).is_err());
    }

    #[test]
    fn depth_of_field_limits_have_exactly_the_given_coc() {
        let (f, n, s, c) = (50.0, 2.8, 3000.0, 0.03);
        let [near, far] = depth_of_field(f, n, s, c).unwrap();
        assert!(near < s && s < far);
        assert!(close(circle_of_confusion(f, n, s, near).unwrap(), c));
        assert!(close(circle_of_confusion(f, n, s, far).unwrap(), c));
        let h = hyperfocal_distance(f, n, c).unwrap();
        assert_eq!(depth_of_field(f, n, h, c).unwrap()[1], f64::INFINITY);
    }

    #[test]
    fn dolly_zoom_keeps_magnification() {
        let (f0, d0, d) = (35.0, 1000.0, 4000.0);
        let f = dolly_zoom_focal_length(f0, d0, d).unwrap();
        assert!(close(
            magnification(f, d).unwrap(),
            magnification(f0, d0).unwrap()
        ));
    }

    #[test]
    fn field_of_view_of_a_normal_lens() {
        let fov = field_of_view(50.0, 36.0).unwrap().to_degrees();
        assert!((fov - 39.5978).abs() < 1e-3, "{fov}");
    }

    #[test]
    fn vectorised_reports_the_first_bad_element_for_any_chunking() {
        let n = 2 * POINTS_PER_TASK + 9;
        let f = vec![50.0; n];
        let mut d: Vec<f64> = (0..n).map(|i| 100.0 + i as f64).collect();
        d[POINTS_PER_TASK + 3] = 10.0;
        d[2 * POINTS_PER_TASK + 1] = f64::NAN;
        let mut out = vec![0.0; n];
        let err = vectorised([&f, &d], &mut out, |[f, d]| image_distance(f, d))
            .unwrap_err()
            .to_string();
        assert!(
            err.ends_with(&format!("(at element {})", POINTS_PER_TASK + 3)),
            "{err}"
        );
        let short = [1.0];
        assert!(matches!(
            vectorised([&f, &short], &mut out, |[f, d]| image_distance(f, d)),
            Err(CoreError::Shape(_))
        ));
    }
}

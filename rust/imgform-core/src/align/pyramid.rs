//! What the search reads: the caller's image converted row by row, and the
//! `f32` planes of the coarser levels and of gradient features.

use rayon::prelude::*;

use super::metric::Metric;
use crate::error::{CoreError, Result};
use crate::image::{mirror, ImageView, Sample};
use crate::parallel::{for_each_row, ROWS_PER_TASK};

/// Rows of `f32` samples with `offset` subtracted (`stored = value -
/// offset`), the form every kernel of the search reads.
///
/// Centring keeps the `f32` cross products of the search small next to
/// their sum: a plate whose structure is a few levels on a large mean (a
/// dim 16-bit scan near white, floats far from [0, 1]) would otherwise lose
/// the covariance NCC is made of to rounding. The search centres each image
/// on its own mean for NCC, which no offset changes, and both on the mean
/// of the two for SSD, which needs a common one, and cosine, which undoes it
/// ([`Converted::centre`]).
pub trait Rows: Sync {
    fn width(&self) -> usize;
    fn height(&self) -> usize;
    fn offset(&self) -> f64;
    /// Writes row `y` into `out` (`width` samples).
    fn fill_row(&self, y: usize, out: &mut [f32]);
}

/// The caller's single-channel image, converted to `f32` one row at a time
/// when a task reads it: the full-resolution level never exists as a float
/// copy, which would cost more (allocation, page faults, one more pass over
/// ~50 MB per plate channel) than converting the rows a band needs.
pub struct Converted<'a, T> {
    view: ImageView<'a, T>,
    offset: f32,
    /// The mean of the samples.
    mean: f64,
}

/// The largest magnitude of a sample the search takes: 2^50, so that the
/// `f32` products of two (centred) samples, 2^102 at most, summed over a row
/// of up to 2^17 stay within `f32` (2^128); ±3e38 made every score NaN.
pub const SAMPLE_LIMIT: f32 = (1u64 << 50) as f32;

/// Whether the search takes a sample: finite and within [`SAMPLE_LIMIT`].
#[inline]
fn good(v: f32) -> bool {
    v.is_finite() && v.abs() <= SAMPLE_LIMIT
}

/// A row's sum and whether all its samples are [`good`], over independent
/// `f32` accumulators that vectorise. The sum only centres the samples, and
/// any centre gives the same scores, so `f32`'s rounding does not matter;
/// it needs to come out the same on every run, which it does.
fn row_sum<T: Sample>(row: &[T]) -> (f64, bool) {
    const LANES: usize = 16;
    let (mut sums, mut all) = ([0.0f32; LANES], true);
    for chunk in row.chunks(LANES) {
        for (s, v) in sums.iter_mut().zip(chunk) {
            let v = v.to_f32();
            all &= good(v);
            *s += v;
        }
    }
    (sums.iter().map(|&s| f64::from(s)).sum(), all)
}

impl<'a, T: Sample> Converted<'a, T> {
    /// Wraps a view after checking it.
    ///
    /// # Errors
    /// [`CoreError::Shape`] for a multi-channel view;
    /// [`CoreError::InvalidArgument`] naming the first sample that is NaN,
    /// infinite or beyond [`SAMPLE_LIMIT`].
    pub fn new(view: &ImageView<'a, T>, name: &str) -> Result<Self> {
        if view.channels() != 1 {
            return Err(CoreError::Shape(format!(
                "{name} must be a single-channel (H, W) image, got {} channels",
                view.channels()
            )));
        }
        // One pass: each row's sum and whether all its samples are good,
        // rows in parallel, the sums then added in order (the same mean
        // whatever the thread count); the first bad sample is found again
        // only to name it.
        let rows: Vec<(f64, bool)> = (0..view.height())
            .into_par_iter()
            .with_min_len(ROWS_PER_TASK)
            .map(|y| row_sum(view.row(y)))
            .collect();
        if rows.iter().any(|&(_, all_good)| !all_good) {
            let (y, x) = view.find_first(|v| !good(v.to_f32())).unwrap_or_default();
            let v = view.row(y)[x].to_f32();
            let (why, v) = if v.is_finite() {
                (
                    "lie within ±2^50 (the search sums their products in float32)",
                    format!("{v:e}"),
                )
            } else {
                ("be finite", v.to_string())
            };
            return Err(crate::invalid!(
                "{name}'s samples must {why}, got {v} at row {y}, column {x}"
            ));
        }
        let sums: Vec<f64> = rows.into_iter().map(|(sum, _)| sum).collect();
        let count = (view.width() * view.height()).max(1) as f64;
        Ok(Self {
            view: *view,
            offset: T::FULL_SCALE / 2.0,
            mean: sums.iter().sum::<f64>() / count,
        })
    }

    /// The pair centred as the search of `metric` reads them best: each on
    /// its own mean for NCC, both on the mean of the two otherwise (see
    /// [`Rows`]).
    pub fn centre(a: &mut Self, b: &mut Self, metric: Metric) {
        let common = (0.5 * (a.mean + b.mean)) as f32;
        if metric == Metric::Ncc {
            (a.offset, b.offset) = (a.mean as f32, b.mean as f32);
        } else {
            (a.offset, b.offset) = (common, common);
        }
    }
}

impl<T: Sample> Rows for Converted<'_, T> {
    fn width(&self) -> usize {
        self.view.width()
    }
    fn height(&self) -> usize {
        self.view.height()
    }
    fn offset(&self) -> f64 {
        f64::from(self.offset)
    }
    #[inline]
    fn fill_row(&self, y: usize, out: &mut [f32]) {
        for (o, &v) in out.iter_mut().zip(self.view.row(y)) {
            *o = v.to_f32() - self.offset;
        }
    }
}

/// A contiguous single-channel `f32` image in the [`Rows`] form: a coarser
/// level of the pyramid, or gradient features.
#[derive(Debug, Clone, PartialEq)]
pub struct Plane {
    pub data: Vec<f32>,
    pub width: usize,
    pub height: usize,
    pub offset: f64,
}

#[cfg(test)]
impl Plane {
    /// A test plane with `f(x, y)` at pixel `(x, y)` (signed, so tests can
    /// sample a pattern at shifted, possibly negative, positions).
    pub(crate) fn from_fn(w: usize, h: usize, f: impl Fn(i64, i64) -> f32) -> Self {
        let data = (0..h as i64)
            .flat_map(|y| (0..w as i64).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y))
            .collect();
        Self {
            data,
            width: w,
            height: h,
            offset: 0.0,
        }
    }
}

impl Rows for Plane {
    fn width(&self) -> usize {
        self.width
    }
    fn height(&self) -> usize {
        self.height
    }
    fn offset(&self) -> f64 {
        self.offset
    }
    #[inline]
    fn fill_row(&self, y: usize, out: &mut [f32]) {
        out.copy_from_slice(self.row(y));
    }
}

impl Plane {
    /// The plane as a single-channel view.
    ///
    /// # Errors
    /// [`CoreError::Shape`] for an empty plane.
    pub fn view(&self) -> Result<ImageView<'_, f32>> {
        ImageView::contiguous(&self.data, self.width, self.height, 1)
    }

    /// Row `y`.
    #[inline(always)]
    pub fn row(&self, y: usize) -> &[f32] {
        &self.data[y * self.width..(y + 1) * self.width]
    }

    /// The 2x2 box average of `src` (odd last row/column dropped): halves
    /// the resolution with the cheapest filter that still suppresses the
    /// aliasing a plain decimation would feed to the coarse search.
    pub fn downsample(src: &impl Rows) -> Self {
        let (sw, w, h) = (src.width(), src.width() / 2, src.height() / 2);
        let mut data = vec![0.0f32; w * h];
        for_each_row(&mut data, w, |y, row| {
            // Two source rows per output row: an allocation per row, not
            // per pixel, and only for the (4x smaller) coarse levels.
            let mut r0 = vec![0.0f32; sw];
            let mut r1 = vec![0.0f32; sw];
            src.fill_row(2 * y, &mut r0);
            src.fill_row(2 * y + 1, &mut r1);
            for (x, o) in row.iter_mut().enumerate() {
                *o = 0.25 * ((r0[2 * x] + r0[2 * x + 1]) + (r1[2 * x] + r1[2 * x + 1]));
            }
        });
        Self {
            data,
            width: w,
            height: h,
            offset: src.offset(),
        }
    }

    /// Sobel gradient magnitude `sqrt(gx^2 + gy^2) / 8` of `src` with
    /// mirrored borders. Edges sit in the same place in every colour channel
    /// even when their brightness differs (the "Emir" plate), so channels
    /// whose intensities do not match still agree on their gradients. The
    /// result has offset 0 (a gradient does not depend on the intensity
    /// offset).
    pub fn gradient(src: &impl Rows) -> Self {
        let (w, h) = (src.width(), src.height());
        let mut data = vec![0.0f32; w * h];
        for_each_row(&mut data, w, |y, row| {
            // Three source rows per output row (an allocation per row).
            let yi = y as isize;
            let mut rows = [vec![0.0f32; w], vec![0.0f32; w], vec![0.0f32; w]];
            for (r, dy) in rows.iter_mut().zip([-1, 0, 1]) {
                src.fill_row(mirror(yi + dy, h), r);
            }
            let [up, mid, down] = &rows;
            let pick = |v: &[f32], l: usize, x: usize, r: usize| [v[l], v[x], v[r]];
            // Mirrored neighbours only at the two border columns.
            for x in [0, w - 1] {
                let (l, r) = (mirror(x as isize - 1, w), mirror(x as isize + 1, w));
                row[x] = sobel(pick(up, l, x, r), pick(mid, l, x, r), pick(down, l, x, r));
            }
            // Zipped 3-wide windows: no index checks, so the loop vectorises.
            let inner = row.iter_mut().skip(1).take(w.saturating_sub(2));
            let windows = up.windows(3).zip(mid.windows(3)).zip(down.windows(3));
            for (o, ((u, m), d)) in inner.zip(windows) {
                *o = sobel([u[0], u[1], u[2]], [m[0], m[1], m[2]], [d[0], d[1], d[2]]);
            }
        });
        Self {
            data,
            width: w,
            height: h,
            offset: 0.0,
        }
    }
}

/// Sobel magnitude `sqrt(gx^2 + gy^2) / 8` of a 3x3 neighbourhood given as
/// its rows (left, centre, right); the 1/8 makes a unit ramp give 1.
#[inline(always)]
fn sobel(u: [f32; 3], m: [f32; 3], d: [f32; 3]) -> f32 {
    let gx = (u[2] - u[0]) + 2.0 * (m[2] - m[0]) + (d[2] - d[0]);
    let gy = (d[0] - u[0]) + 2.0 * (d[1] - u[1]) + (d[2] - u[2]);
    0.125 * (gx * gx + gy * gy).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversion_subtracts_mid_scale_and_rejects_nan() {
        let px = [0u16, 65535, 100, 7];
        let view = ImageView::contiguous(&px, 2, 2, 1).unwrap();
        let c = Converted::new(&view, "a").unwrap();
        let mut row = [0.0f32; 2];
        c.fill_row(1, &mut row);
        assert_eq!(row, [-32667.5, -32760.5]);
        assert_eq!(c.offset(), 32767.5);
        let bad = [0.0f32, 1.0, 2.0, f32::NAN, 0.0, f32::INFINITY];
        let view = ImageView::contiguous(&bad, 2, 3, 1).unwrap();
        let err = Converted::new(&view, "moving").err().unwrap().to_string();
        assert!(err.contains("moving's samples must be finite, got NaN at row 1, column 1"));
        // Finite, but its products overflow the search's f32 sums (NaN scores).
        let huge = [0.0f32, 3e38, 1.0, 2.0];
        let view = ImageView::contiguous(&huge, 2, 2, 1).unwrap();
        let err = Converted::new(&view, "a").err().unwrap().to_string();
        assert!(
            err.contains("within ±2^50") && err.contains("row 0, column 1"),
            "{err}"
        );
        let rgb = [0u8; 12];
        let view = ImageView::contiguous(&rgb, 2, 2, 3).unwrap();
        assert!(Converted::new(&view, "a").is_err());
    }

    #[test]
    fn ncc_centres_each_image_on_its_mean_the_others_on_a_common_one() {
        let (pa, pb) = ([60000u16, 60002, 60004, 60006], [5000u16, 5001, 5002, 5005]);
        let (va, vb) = (
            ImageView::contiguous(&pa, 2, 2, 1).unwrap(),
            ImageView::contiguous(&pb, 2, 2, 1).unwrap(),
        );
        let (mut a, mut b) = (
            Converted::new(&va, "a").unwrap(),
            Converted::new(&vb, "b").unwrap(),
        );
        Converted::centre(&mut a, &mut b, Metric::Ncc);
        assert_eq!((a.offset(), b.offset()), (60003.0, 5002.0));
        let mut row = [0.0f32; 2];
        a.fill_row(0, &mut row);
        assert_eq!(row, [-3.0, -1.0]);
        for metric in [Metric::Ssd, Metric::Cosine] {
            Converted::centre(&mut a, &mut b, metric);
            assert_eq!((a.offset(), b.offset()), (32502.5, 32502.5));
        }
    }

    #[test]
    fn downsample_averages_blocks() {
        let p = Plane::downsample(&Plane::from_fn(5, 3, |x, y| (x + 10 * y) as f32));
        assert_eq!((p.width, p.height), (2, 1));
        // Block (0..2, 0..2): (0 + 1 + 10 + 11) / 4 = 5.5.
        assert_eq!(p.data, vec![5.5, 7.5]);
    }

    #[test]
    fn gradient_of_a_ramp_is_its_slope() {
        // I = 3x: gx = 3 * 2 * (1 + 2 + 1) = 24, / 8 = 3 inside.
        let g = Plane::gradient(&Plane::from_fn(6, 5, |x, _| 3.0 * x as f32));
        assert_eq!(g.data[2 * 6 + 2], 3.0);
        // Mirrored border: the ramp folds back, the slope vanishes.
        assert_eq!(g.data[2 * 6], 0.0);
    }
}

//! The `f32` planes the search runs on: conversion, 2x downsampling and
//! gradient features.

use std::sync::atomic::{AtomicUsize, Ordering};

use crate::error::{CoreError, Result};
use crate::image::{mirror, ImageView, Sample};
use crate::parallel::for_each_row;

/// A contiguous single-channel `f32` image whose samples are stored minus
/// `offset` (`stored = value - offset`).
///
/// The offset is the middle of the input type's range (127.5 for `u8`,
/// 32767.5 for `u16`, 0.5 for `f32`). Centring keeps the `f32` cross
/// products of the search small next to their sum, so a 16-bit plate with a
/// large mean does not lose the covariance NCC is made of to rounding; SSD
/// and NCC do not depend on a common offset, cosine undoes it (see
/// [`super::metric::Sums::score`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Plane {
    pub data: Vec<f32>,
    pub width: usize,
    pub height: usize,
    pub offset: f64,
}

impl Plane {
    /// Row `y`.
    #[inline(always)]
    pub fn row(&self, y: usize) -> &[f32] {
        &self.data[y * self.width..(y + 1) * self.width]
    }

    /// Converts a single-channel view to a plane, row band by row band in
    /// parallel.
    ///
    /// # Errors
    /// [`CoreError::Shape`] for a multi-channel view;
    /// [`CoreError::InvalidArgument`] naming the first row holding a NaN or
    /// an infinity.
    pub fn from_view<T: Sample>(view: &ImageView<'_, T>, name: &str) -> Result<Self> {
        if view.channels() != 1 {
            return Err(CoreError::Shape(format!(
                "{name} must be a single-channel (H, W) image, got {} channels",
                view.channels()
            )));
        }
        let (w, h) = (view.width(), view.height());
        let offset = T::FULL_SCALE / 2.0;
        let mut data = vec![0.0f32; w * h];
        // The smallest row holding a NaN or infinity, checked while the row
        // is in cache; `fetch_min` makes it the same for any thread count.
        let bad = AtomicUsize::new(usize::MAX);
        for_each_row(&mut data, w, |y, row| {
            for (o, &v) in row.iter_mut().zip(view.row(y)) {
                *o = v.to_f32() - offset;
            }
            if row.iter().any(|v| !v.is_finite()) {
                bad.fetch_min(y, Ordering::Relaxed);
            }
        });
        let y = bad.into_inner();
        if y != usize::MAX {
            let x = data[y * w..(y + 1) * w]
                .iter()
                .position(|v| !v.is_finite())
                .unwrap_or(0);
            return Err(crate::invalid!(
                "{name} must contain only finite values, row {y} holds {}",
                view.at(x, y, 0).to_f32()
            ));
        }
        Ok(Self {
            data,
            width: w,
            height: h,
            offset: f64::from(offset),
        })
    }

    /// The 2x2 box average (odd last row/column dropped): halves the
    /// resolution with the cheapest filter that still suppresses the
    /// aliasing a plain decimation would feed to the coarse search.
    pub fn downsample(&self) -> Self {
        let (w, h) = (self.width / 2, self.height / 2);
        let mut data = vec![0.0f32; w * h];
        for_each_row(&mut data, w, |y, row| {
            let (r0, r1) = (self.row(2 * y), self.row(2 * y + 1));
            for (x, o) in row.iter_mut().enumerate() {
                *o = 0.25 * ((r0[2 * x] + r0[2 * x + 1]) + (r1[2 * x] + r1[2 * x + 1]));
            }
        });
        Self {
            data,
            width: w,
            height: h,
            offset: self.offset,
        }
    }

    /// Sobel gradient magnitude `sqrt(gx^2 + gy^2) / 8` with mirrored
    /// borders. Edges sit in the same place in every colour channel even when
    /// their brightness differs (the "Emir" plate), so channels whose
    /// intensities do not match still agree on their gradients. The result
    /// has offset 0 (a gradient does not depend on the intensity offset).
    pub fn gradient(&self) -> Self {
        let (w, h) = (self.width, self.height);
        let mut data = vec![0.0f32; w * h];
        for_each_row(&mut data, w, |y, row| {
            let yi = y as isize;
            let up = self.row(mirror(yi - 1, h));
            let mid = self.row(y);
            let down = self.row(mirror(yi + 1, h));
            for (x, o) in row.iter_mut().enumerate() {
                let (l, r) = (mirror(x as isize - 1, w), mirror(x as isize + 1, w));
                let gx = (up[r] - up[l]) + 2.0 * (mid[r] - mid[l]) + (down[r] - down[l]);
                let gy = (down[l] - up[l]) + 2.0 * (down[x] - up[x]) + (down[r] - up[r]);
                *o = 0.125 * (gx * gx + gy * gy).sqrt();
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

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(w: usize, h: usize, f: impl Fn(usize, usize) -> f32) -> Plane {
        let data = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y))
            .collect();
        Plane {
            data,
            width: w,
            height: h,
            offset: 0.0,
        }
    }

    #[test]
    fn conversion_subtracts_mid_scale_and_rejects_nan() {
        let px = [0u16, 65535, 100, 7];
        let p = Plane::from_view(&ImageView::contiguous(&px, 2, 2, 1).unwrap(), "a").unwrap();
        assert_eq!(p.data, vec![-32767.5, 32767.5, -32667.5, -32760.5]);
        let bad = [0.0f32, 1.0, f32::NAN, 0.0];
        let err = Plane::from_view(&ImageView::contiguous(&bad, 2, 2, 1).unwrap(), "moving")
            .unwrap_err()
            .to_string();
        assert!(err.contains("moving") && err.contains("row 1"), "{err}");
        let rgb = [0u8; 12];
        assert!(Plane::from_view(&ImageView::contiguous(&rgb, 2, 2, 3).unwrap(), "a").is_err());
    }

    #[test]
    fn downsample_averages_blocks() {
        let p = plane(5, 3, |x, y| (x + 10 * y) as f32).downsample();
        assert_eq!((p.width, p.height), (2, 1));
        // Block (0..2, 0..2): (0 + 1 + 10 + 11) / 4 = 5.5.
        assert_eq!(p.data, vec![5.5, 7.5]);
    }

    #[test]
    fn gradient_of_a_ramp_is_its_slope() {
        // I = 3x: gx = 3 * 2 * (1 + 2 + 1) = 24, / 8 = 3 inside.
        let g = plane(6, 5, |x, _| 3.0 * x as f32).gradient();
        assert_eq!(g.data[2 * 6 + 2], 3.0);
        // Mirrored border: the ramp folds back, the slope vanishes.
        assert_eq!(g.data[2 * 6], 0.0);
    }
}

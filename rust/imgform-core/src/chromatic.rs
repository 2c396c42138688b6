//! Lateral chromatic aberration (lecture section 3.3): the refractive index
//! of glass depends on wavelength, so a lens magnifies red, green and blue by
//! slightly different amounts and colour fringes grow towards the corners.
//!
//! Modelled as a radial magnification of the red and blue channels about the
//! optical centre relative to green, which stays put. Adding the aberration
//! scales channel `c` by `s_c` (a feature at radius `r` moves to `s_c r`);
//! correcting it applies exactly the inverse magnification `1 / s_c`. Both
//! are resampling passes of [`crate::remap`]'s sampler with the same borders
//! (taps outside the image read `fill`) and rounding.

use crate::error::{finite, positive, CoreError, Result};
use crate::image::ImageView;
use crate::parallel::for_each_row;
use crate::remap::{check_fill, resample, to_fixed, Coords, Interpolation, Resample};

/// Magnification by `factor` about `(cx, cy)`: output pixel `p` reads the
/// source at `c + (p - c) / factor`.
struct Magnify {
    cx: f64,
    cy: f64,
    inv: f64,
}

impl Coords for Magnify {
    #[inline(always)]
    fn at(&self, x: usize, y: usize) -> (i32, i32) {
        (
            to_fixed(self.cx + (x as f64 - self.cx) * self.inv),
            to_fixed(self.cy + (y as f64 - self.cy) * self.inv),
        )
    }
}

/// Lateral chromatic aberration of one lens: the magnifications of red and
/// blue relative to green and the optical centre they are taken about.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LateralCa {
    pub scale_r: f64,
    pub scale_b: f64,
    /// `(cx, cy)` in pixels; `None` is the image centre `((W - 1) / 2, (H - 1) / 2)`.
    pub center: Option<(f64, f64)>,
}

impl LateralCa {
    /// Renders the aberration into an RGB image: red magnified by `scale_r`,
    /// blue by `scale_b`, green copied unchanged.
    ///
    /// # Errors
    /// See [`LateralCa::apply`].
    pub fn add<T: Resample>(
        &self,
        src: &ImageView<T>,
        interpolation: Interpolation,
        fill: f64,
        out: &mut [T],
    ) -> Result<()> {
        self.apply(src, interpolation, fill, false, out)
    }

    /// Removes the aberration [`LateralCa::add`] renders: red magnified by
    /// `1 / scale_r`, blue by `1 / scale_b`, green copied unchanged.
    ///
    /// # Errors
    /// See [`LateralCa::apply`].
    pub fn correct<T: Resample>(
        &self,
        src: &ImageView<T>,
        interpolation: Interpolation,
        fill: f64,
        out: &mut [T],
    ) -> Result<()> {
        self.apply(src, interpolation, fill, true, out)
    }

    /// Copies `src` into `out` (a contiguous image of the same shape), then
    /// resamples red and blue over it.
    ///
    /// # Errors
    /// A scale that is not finite and positive, a non-finite centre, an
    /// image without exactly 3 channels, a `fill` the sample type cannot
    /// hold, or `out` of the wrong length.
    pub fn apply<T: Resample>(
        &self,
        src: &ImageView<T>,
        interpolation: Interpolation,
        fill: f64,
        invert: bool,
        out: &mut [T],
    ) -> Result<()> {
        let scales = [
            (0, positive("scale_r", self.scale_r)?),
            (2, positive("scale_b", self.scale_b)?),
        ];
        let (w, h) = (src.width(), src.height());
        let (cx, cy) = match self.center {
            Some((cx, cy)) => (finite("center x", cx)?, finite("center y", cy)?),
            None => ((w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0),
        };
        if src.channels() != 3 {
            return Err(CoreError::Shape(format!(
                "lateral chromatic aberration needs an RGB image (H, W, 3), got {} channels",
                src.channels()
            )));
        }
        let fill = check_fill::<T>(fill)?;
        let row_len = src.row_len();
        if out.len() != row_len * h {
            return Err(CoreError::Shape(format!(
                "output must hold {h}x{w}x3 samples, got {}",
                out.len()
            )));
        }
        for_each_row(out, row_len, |y, row| row.copy_from_slice(src.row(y)));
        for (channel, scale) in scales {
            let inv = if invert { scale } else { 1.0 / scale };
            let coords = Magnify { cx, cy, inv };
            resample(
                src,
                &coords,
                w,
                h,
                channel..channel + 1,
                interpolation,
                fill,
                out,
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth RGB test card whose channels differ.
    fn card(w: usize, h: usize) -> Vec<f32> {
        (0..h)
            .flat_map(|y| {
                (0..w).flat_map(move |x| {
                    let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
                    [u * v, (3.0 * u).sin() * 0.5 + 0.5, v * v]
                })
            })
            .collect()
    }

    #[test]
    fn green_is_unchanged_and_red_moves_outwards() {
        let (w, h) = (41, 31);
        let img = card(w, h);
        let view = ImageView::contiguous(&img, w, h, 3).unwrap();
        let ca = LateralCa {
            scale_r: 1.1,
            scale_b: 0.95,
            center: None,
        };
        let mut out = vec![0.0f32; img.len()];
        ca.add(&view, Interpolation::Bilinear, 0.0, &mut out)
            .unwrap();
        for i in (1..img.len()).step_by(3) {
            assert_eq!(out[i], img[i]);
        }
        // Red is u * v, magnified 1.1x about (20, 15): output (30, 15) reads (20 + 10 / 1.1, 15),
        // a position stored to 1/256 px (red changes by 0.012 per px here).
        let expect = (20.0 + 10.0 / 1.1) / w as f32 * (15.0 / h as f32);
        let got = out[(15 * w + 30) * 3];
        assert!((got - expect).abs() < 5e-5, "{got} vs {expect}");
        // The centre pixel does not move in any channel.
        let c = (15 * w + 20) * 3;
        assert_eq!(&out[c..c + 3], &img[c..c + 3]);
    }

    #[test]
    fn correct_undoes_add_in_the_interior() {
        let (w, h) = (64, 48);
        let img = card(w, h);
        let view = ImageView::contiguous(&img, w, h, 3).unwrap();
        let ca = LateralCa {
            scale_r: 1.02,
            scale_b: 0.98,
            center: Some((30.0, 25.0)),
        };
        let mut aberrated = vec![0.0f32; img.len()];
        ca.add(&view, Interpolation::Bicubic, 0.0, &mut aberrated)
            .unwrap();
        let view = ImageView::contiguous(&aberrated, w, h, 3).unwrap();
        let mut back = vec![0.0f32; img.len()];
        ca.correct(&view, Interpolation::Bicubic, 0.0, &mut back)
            .unwrap();
        for y in 4..h - 4 {
            for x in 4..w - 4 {
                for c in 0..3 {
                    let i = (y * w + x) * 3 + c;
                    assert!((back[i] - img[i]).abs() < 2e-3, "({x}, {y}, {c})");
                }
            }
        }
    }

    #[test]
    fn bad_scales_and_channel_counts_are_refused() {
        let img = vec![0u8; 4 * 4 * 3];
        let view = ImageView::contiguous(&img, 4, 4, 3).unwrap();
        let mut out = vec![0u8; img.len()];
        for (r, b) in [(0.0, 1.0), (1.0, f64::NAN), (-1.0, 1.0)] {
            let ca = LateralCa {
                scale_r: r,
                scale_b: b,
                center: None,
            };
            assert!(ca
                .add(&view, Interpolation::Bilinear, 0.0, &mut out)
                .is_err());
        }
        let grey = ImageView::contiguous(&img[..16], 4, 4, 1).unwrap();
        let ca = LateralCa {
            scale_r: 1.0,
            scale_b: 1.0,
            center: None,
        };
        let err = ca
            .add(&grey, Interpolation::Bilinear, 0.0, &mut out[..16])
            .unwrap_err();
        assert!(err.to_string().contains("got 1 channels"), "{err}");
    }
}

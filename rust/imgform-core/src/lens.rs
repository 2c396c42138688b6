//! Lens corrections from calibrated profiles: distortion, lateral
//! chromatic aberration (TCA) and vignetting with the models and the
//! coordinate conventions of the lensfun library (version 0.3.4, the one the
//! `lensfunpy` wheel bundles), so that a profile from its database corrects
//! an image exactly as lensfun would.
//!
//! # Coordinates
//! lensfun measures distortion and TCA in *normalised* coordinates, where
//! `r = 1` is half the short side of the calibration sensor, and vignetting
//! in coordinates where `r = 1` is half its diagonal. An image from another
//! sensor (other crop factor or aspect ratio) is mapped onto the calibration
//! sensor through the diagonal, because crop factors are defined by it
//! ([`Normalization::new`] carries lensfun's formulas over unchanged,
//! including that its sizes run from the first to the last pixel centre,
//! `W - 1` and `H - 1`).
//!
//! # Order
//! Correcting reads every output pixel from where the lens put it: the
//! undistorted position is distorted first, then red and blue are
//! magnified by the TCA model (lensfun's `ApplySubpixelGeometryDistortion`
//! order), and each channel is sampled once from the source with
//! [`crate::remap`]'s sampler. Vignetting divides linear values by the
//! calibrated falloff `1 + k1 r² + k2 r⁴ + k3 r⁶` (the `pa` model) at the
//! pixel's own position, so it belongs before any tone curve and before the
//! geometry is resampled (it describes the uncorrected image).
//!
//! # Precision
//! Everything is evaluated in `f64` per pixel. lensfun works in `f32`,
//! accumulates pixel steps, and its SSE paths approximate square roots with
//! `rcp(rsqrt(x))` (12 bits): against its scalar path positions agree to a
//! few thousandths of a pixel, against its SSE path (whole-row calls on
//! aligned buffers) only to about 1e-4 of the radius.

use crate::error::{positive, CoreError, Result};
use crate::image::{ImageView, Sample};
use crate::invalid;
use crate::parallel::for_each_row;
use crate::remap::{check_fill, resample, to_fixed, Coords, Interpolation, Resample};

/// Radial distortion models of lensfun, as the ratio `r_d / r_u` of the
/// distorted to the undistorted radius (normalised coordinates).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RadialDistortion {
    None,
    /// `r_d = r_u (1 - k1 + k1 r_u²)`.
    Poly3 {
        k1: f64,
    },
    /// `r_d = r_u (1 + k1 r_u² + k2 r_u⁴)`.
    Poly5 {
        k1: f64,
        k2: f64,
    },
    /// PanoTools: `r_d = r_u (a r_u³ + b r_u² + c r_u + 1 - a - b - c)`.
    PtLens {
        a: f64,
        b: f64,
        c: f64,
    },
}

impl RadialDistortion {
    /// A model by lensfun's name (`"none"`, `"poly3"`, `"poly5"`, `"ptlens"`)
    /// and its terms in lensfun's order.
    ///
    /// # Errors
    /// An unknown name, too few terms or a non-finite one.
    pub fn new(model: &str, terms: &[f64]) -> Result<Self> {
        let needed = match model {
            "none" => 0,
            "poly3" => 1,
            "poly5" => 2,
            "ptlens" => 3,
            _ => {
                return Err(invalid!(
                "unknown distortion model {model:?}; accepted: \"none\", \"poly3\", \"poly5\", \"ptlens\""
            ))
            }
        };
        let t = terms_of("distortion", model, terms, needed)?;
        Ok(match model {
            "poly3" => Self::Poly3 { k1: t[0] },
            "poly5" => Self::Poly5 { k1: t[0], k2: t[1] },
            "ptlens" => Self::PtLens {
                a: t[0],
                b: t[1],
                c: t[2],
            },
            _ => Self::None,
        })
    }

    /// `r_d / r_u` at `r_u² = r2`.
    #[inline(always)]
    fn ratio(&self, r2: f64) -> f64 {
        match *self {
            Self::None => 1.0,
            Self::Poly3 { k1 } => 1.0 - k1 + k1 * r2,
            Self::Poly5 { k1, k2 } => 1.0 + k1 * r2 + k2 * r2 * r2,
            Self::PtLens { a, b, c } => {
                let r = r2.sqrt();
                a * r2 * r + b * r2 + c * r + 1.0 - a - b - c
            }
        }
    }
}

/// Lateral chromatic aberration models of lensfun: the radius of red and
/// blue relative to green's, which stays put.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Tca {
    None,
    /// `r_c = k_c r`.
    Linear {
        kr: f64,
        kb: f64,
    },
    /// `r_c = r (b_c r² + c_c r + v_c)`; fields hold `[red, blue]`.
    Poly3 {
        v: [f64; 2],
        c: [f64; 2],
        b: [f64; 2],
    },
}

impl Tca {
    /// A model by lensfun's name (`"none"`, `"linear"`, `"poly3"`) and its
    /// terms in lensfun's order (`kr, kb` and `vr, vb, cr, cb, br, bb`).
    ///
    /// # Errors
    /// An unknown name, too few terms or a non-finite one.
    pub fn new(model: &str, terms: &[f64]) -> Result<Self> {
        let needed = match model {
            "none" => 0,
            "linear" => 2,
            "poly3" => 6,
            _ => {
                return Err(invalid!(
                    "unknown TCA model {model:?}; accepted: \"none\", \"linear\", \"poly3\""
                ))
            }
        };
        let t = terms_of("TCA", model, terms, needed)?;
        Ok(match model {
            "linear" => Self::Linear { kr: t[0], kb: t[1] },
            "poly3" => Self::Poly3 {
                v: [t[0], t[1]],
                c: [t[2], t[3]],
                b: [t[4], t[5]],
            },
            _ => Self::None,
        })
    }

    /// The radius ratio of `channel` (0 red, 1 green, 2 blue) at `r² = r2`.
    #[inline(always)]
    fn ratio(&self, channel: usize, r2: f64) -> f64 {
        let side = match channel {
            0 => 0,
            2 => 1,
            _ => return 1.0,
        };
        match *self {
            Self::None => 1.0,
            Self::Linear { kr, kb } => [kr, kb][side],
            Self::Poly3 { v, c, b } => b[side] * r2 + c[side] * r2.sqrt() + v[side],
        }
    }
}

/// lensfun's `pa` vignetting model: the image is darker by
/// `1 + k1 r² + k2 r⁴ + k3 r⁶` (`r = 1` at half the calibration diagonal).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vignetting {
    pub k: [f64; 3],
}

impl Vignetting {
    /// The gain that undoes the falloff at `r² = r2`. Where the polynomial
    /// is not positive (far outside the calibrated circle) the gain is 0,
    /// as lensfun clamps the corrected value at 0 there.
    #[inline(always)]
    fn gain(&self, r2: f64) -> f64 {
        let [k1, k2, k3] = self.k;
        let falloff = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        if falloff > 0.0 {
            1.0 / falloff
        } else {
            0.0
        }
    }
}

/// Pixel positions to lensfun's normalised coordinates and back.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Normalization {
    /// Normalised units per pixel (lensfun's `NormScale`).
    scale: f64,
    /// The optical centre, in normalised units from pixel (0, 0).
    center: (f64, f64),
    /// Normalised to vignetting units (`1 / AspectRatioCorrection`).
    to_diagonal: f64,
}

impl Normalization {
    /// lensfun's `lfModifier` constructor for a `width x height` image
    /// from a camera of crop factor `crop`, with a profile calibrated at
    /// `calibration_crop` on a sensor of long/short `aspect_ratio`, and the
    /// profile's centre offset `center` (normalised units).
    ///
    /// # Errors
    /// A size below 1, a crop factor or aspect ratio that is not finite and
    /// positive, or a non-finite centre.
    pub fn new(
        width: usize,
        height: usize,
        crop: f64,
        calibration_crop: f64,
        aspect_ratio: f64,
        center: (f64, f64),
    ) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(CoreError::Shape(format!(
                "image size must be non-empty, got height {height}, width {width}"
            )));
        }
        let crop = positive("crop factor", crop)?;
        let calibration_crop = positive("calibration crop factor", calibration_crop)?;
        let aspect_ratio = positive("aspect ratio", aspect_ratio)?;
        if !(center.0.is_finite() && center.1.is_finite()) {
            return Err(invalid!("the centre offset must be finite, got {center:?}"));
        }
        // Pixel centres span W - 1 by H - 1 (at least 1: lensfun's guard).
        let w = width.saturating_sub(1).max(1) as f64;
        let h = height.saturating_sub(1).max(1) as f64;
        let size = w.min(h);
        let image_aspect = w.max(h) / size;
        let aspect_correction = aspect_ratio.hypot(1.0);
        // Image short-side units -> image diagonal -> calibration diagonal
        // (crop factors) -> calibration short-side units.
        let correction = calibration_crop / crop * aspect_correction / image_aspect.hypot(1.0);
        let scale = 2.0 / size * correction;
        Ok(Self {
            scale,
            center: (
                (w / size + center.0) * correction,
                (h / size + center.1) * correction,
            ),
            to_diagonal: 1.0 / aspect_correction,
        })
    }

    #[inline(always)]
    fn to_normalized(self, u: f64, v: f64) -> (f64, f64) {
        (
            u * self.scale - self.center.0,
            v * self.scale - self.center.1,
        )
    }

    #[inline(always)]
    fn to_pixel(self, x: f64, y: f64) -> (f64, f64) {
        (
            (x + self.center.0) / self.scale,
            (y + self.center.1) / self.scale,
        )
    }
}

/// The corrections of one lens at one focal length / aperture / distance,
/// for images of one size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LensCorrection {
    pub width: usize,
    pub height: usize,
    pub normalization: Normalization,
    pub distortion: RadialDistortion,
    pub tca: Tca,
    pub vignetting: Option<Vignetting>,
}

impl LensCorrection {
    /// Where the corrected image's pixel `(u, v)` of channel `channel` (0,
    /// 1, 2 = R, G, B) lies in the uncorrected one, in pixels.
    #[inline(always)]
    pub fn source(&self, channel: usize, u: f64, v: f64) -> (f64, f64) {
        let n = &self.normalization;
        let (x, y) = n.to_normalized(u, v);
        let d = self.distortion.ratio(x * x + y * y);
        let (x, y) = (x * d, y * d);
        let t = self.tca.ratio(channel, x * x + y * y);
        n.to_pixel(x * t, y * t)
    }

    /// The vignetting gain at pixel `(u, v)` (1 without a vignetting model).
    #[inline(always)]
    pub fn gain(&self, u: f64, v: f64) -> f64 {
        self.vignetting.map_or(1.0, |vig| {
            let n = &self.normalization;
            let (x, y) = n.to_normalized(u, v);
            vig.gain((x * x + y * y) * n.to_diagonal * n.to_diagonal)
        })
    }

    /// Writes the source positions of every pixel, `(H, W, 3, 2)` as
    /// `(x, y)` per channel R, G, B: the layout of lensfunpy's
    /// `apply_subpixel_geometry_distortion`.
    ///
    /// # Errors
    /// `out` not `height * width * 6` long.
    pub fn positions(&self, out: &mut [f64]) -> Result<()> {
        let row_len = 6 * self.width;
        if out.len() != row_len * self.height {
            return Err(CoreError::Shape(format!(
                "positions need {} values for a {}x{} image, got {}",
                row_len * self.height,
                self.height,
                self.width,
                out.len()
            )));
        }
        for_each_row(out, row_len, |v, row| {
            for (u, px) in row.chunks_exact_mut(6).enumerate() {
                for (c, xy) in px.chunks_exact_mut(2).enumerate() {
                    let (x, y) = self.source(c, u as f64, v as f64);
                    xy[0] = x;
                    xy[1] = y;
                }
            }
        });
        Ok(())
    }

    /// Resamples an RGB image into its distortion- and TCA-corrected form:
    /// each channel of `out` (contiguous, the source's shape) is read once
    /// from `src` at [`LensCorrection::source`]. Taps outside the source
    /// read `fill`, as in [`crate::remap`].
    ///
    /// # Errors
    /// An image that is not `height x width x 3`, a `fill` the sample type
    /// cannot hold, or `out` of the wrong length.
    pub fn correct_geometry<T: Resample>(
        &self,
        src: &ImageView<T>,
        interpolation: Interpolation,
        fill: f64,
        out: &mut [T],
    ) -> Result<()> {
        self.check_image(src, 3)?;
        let fill = check_fill::<T>(fill)?;
        for channel in 0..3 {
            let coords = ChannelSource {
                lens: self,
                channel,
            };
            resample(
                src,
                &coords,
                self.width,
                self.height,
                channel..channel + 1,
                interpolation,
                fill,
                out,
            )?;
        }
        Ok(())
    }

    /// Removes vignetting: `out = black + (src - black) * gain`, where
    /// `black` is a tile repeated over the image (`black_tile` rows of
    /// `black_width` values; one zero for developed linear data, the black
    /// levels of a raw mosaic's CFA tile for raw data). Integer results are
    /// rounded and clamped to the type's range, as lensfun clamps them.
    ///
    /// # Errors
    /// An image of the wrong size, an empty or ragged black tile, or `out`
    /// of the wrong length.
    pub fn devignette<T: Sample>(
        &self,
        src: &ImageView<T>,
        black_tile: &[f64],
        black_width: usize,
        out: &mut [T],
    ) -> Result<()> {
        self.check_image(src, src.channels())?;
        if black_width == 0 || black_tile.is_empty() || black_tile.len() % black_width != 0 {
            return Err(CoreError::Shape(format!(
                "the black tile must be a non-empty (rows, {black_width}) array, got {} values",
                black_tile.len()
            )));
        }
        let row_len = src.row_len();
        if out.len() != row_len * self.height {
            return Err(CoreError::Shape(format!(
                "output must hold {} samples, got {}",
                row_len * self.height,
                out.len()
            )));
        }
        let tile_rows = black_tile.len() / black_width;
        let channels = src.channels();
        for_each_row(out, row_len, |v, row| {
            let blacks = &black_tile[(v % tile_rows) * black_width..][..black_width];
            for (u, (px, s)) in row
                .chunks_exact_mut(channels)
                .zip(src.row(v).chunks_exact(channels))
                .enumerate()
            {
                let gain = self.gain(u as f64, v as f64);
                let black = blacks[u % black_width];
                for (o, &value) in px.iter_mut().zip(s) {
                    *o = T::from_f32((black + (f64::from(value.to_f32()) - black) * gain) as f32);
                }
            }
        });
        Ok(())
    }

    fn check_image<T: Copy>(&self, src: &ImageView<T>, channels: usize) -> Result<()> {
        if (src.width(), src.height(), src.channels()) != (self.width, self.height, channels) {
            return Err(CoreError::Shape(format!(
                "the correction was set up for {}x{}x{channels} images, got {}x{}x{}",
                self.height,
                self.width,
                src.height(),
                src.width(),
                src.channels()
            )));
        }
        Ok(())
    }
}

/// The source positions of one channel, computed per pixel: no map is
/// stored (three dense maps of a 24 MP image would take 576 MB).
struct ChannelSource<'a> {
    lens: &'a LensCorrection,
    channel: usize,
}

impl Coords for ChannelSource<'_> {
    #[inline(always)]
    fn at(&self, x: usize, y: usize) -> (i32, i32) {
        let (sx, sy) = self.lens.source(self.channel, x as f64, y as f64);
        (to_fixed(sx), to_fixed(sy))
    }
}

/// `terms[..needed]`, checked to be there and finite.
fn terms_of<'t>(kind: &str, model: &str, terms: &'t [f64], needed: usize) -> Result<&'t [f64]> {
    if terms.len() < needed {
        return Err(invalid!(
            "the {kind} model {model:?} needs {needed} terms, got {}",
            terms.len()
        ));
    }
    let used = &terms[..needed];
    if let Some(t) = used.iter().find(|t| !t.is_finite()) {
        return Err(invalid!("{kind} terms must be finite, got {t} in {used:?}"));
    }
    Ok(used)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn correction(distortion: RadialDistortion, tca: Tca) -> LensCorrection {
        let (width, height) = (61, 41);
        LensCorrection {
            width,
            height,
            normalization: Normalization::new(width, height, 1.5, 1.5, 1.5, (0.0, 0.0)).unwrap(),
            distortion,
            tca,
            vignetting: Some(Vignetting {
                k: [-0.3, 0.1, -0.05],
            }),
        }
    }

    #[test]
    fn a_3_2_image_of_the_calibration_sensor_is_normalised_to_its_short_side() {
        // W - 1 = 60, H - 1 = 40: the short half-side is 20 px.
        let n = Normalization::new(61, 41, 1.5, 1.5, 1.5, (0.0, 0.0)).unwrap();
        assert!((n.scale - 1.0 / 20.0).abs() < 1e-12);
        let (x, y) = n.to_normalized(30.0, 40.0);
        assert!(x.abs() < 1e-12 && (y - 1.0).abs() < 1e-12);
        // Vignetting's unit is half the diagonal: sqrt(1.5² + 1) short half-sides.
        assert!((n.to_diagonal - 1.0 / 1.5f64.hypot(1.0)).abs() < 1e-12);
    }

    #[test]
    fn a_sensor_of_twice_the_crop_factor_sees_half_the_radius() {
        let full = Normalization::new(61, 41, 1.0, 1.0, 1.5, (0.0, 0.0)).unwrap();
        let crop = Normalization::new(61, 41, 2.0, 1.0, 1.5, (0.0, 0.0)).unwrap();
        assert!((crop.scale * 2.0 - full.scale).abs() < 1e-12);
    }

    #[test]
    fn identity_models_keep_every_pixel_in_place_with_unit_gain() {
        let mut c = correction(RadialDistortion::None, Tca::None);
        c.vignetting = None;
        for (u, v) in [(0.0, 0.0), (60.0, 40.0), (13.0, 7.0)] {
            for ch in 0..3 {
                let (x, y) = c.source(ch, u, v);
                assert!((x - u).abs() < 1e-9 && (y - v).abs() < 1e-9);
            }
            assert_eq!(c.gain(u, v), 1.0);
        }
    }

    #[test]
    fn barrel_distortion_reads_the_corners_from_nearer_the_centre() {
        let c = correction(RadialDistortion::Poly3 { k1: -0.05 }, Tca::None);
        let (x, y) = c.source(1, 0.0, 0.0);
        assert!(x > 0.0 && y > 0.0);
        // The centre itself does not move.
        let (x, y) = c.source(1, 30.0, 20.0);
        assert!((x - 30.0).abs() < 1e-9 && (y - 20.0).abs() < 1e-9);
    }

    #[test]
    fn tca_moves_red_and_blue_only() {
        let c = correction(RadialDistortion::None, Tca::Linear { kr: 1.01, kb: 0.99 });
        let g = c.source(1, 0.0, 0.0);
        assert!((g.0).abs() < 1e-9);
        let r = c.source(0, 0.0, 0.0);
        let b = c.source(2, 0.0, 0.0);
        assert!(r.0 < 0.0 && b.0 > 0.0);
    }

    #[test]
    fn vignetting_gain_is_one_at_the_centre_and_grows_outwards() {
        let c = correction(RadialDistortion::None, Tca::None);
        assert!((c.gain(30.0, 20.0) - 1.0).abs() < 1e-12);
        assert!(c.gain(0.0, 0.0) > c.gain(10.0, 10.0));
        let dark = Vignetting {
            k: [-2.0, 0.0, 0.0],
        };
        assert_eq!(dark.gain(1.0), 0.0);
    }

    #[test]
    fn geometry_is_the_same_for_one_and_many_threads() {
        let c = correction(
            RadialDistortion::PtLens {
                a: 0.01,
                b: -0.03,
                c: 0.02,
            },
            Tca::Poly3 {
                v: [1.001, 0.999],
                c: [0.0, 0.0],
                b: [0.0002, -0.0001],
            },
        );
        let img: Vec<u16> = (0..61 * 41 * 3).map(|i| (i * 37 % 65536) as u16).collect();
        let view = ImageView::contiguous(&img, 61, 41, 3).unwrap();
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut out = vec![0u16; img.len()];
            pool.install(|| c.correct_geometry(&view, Interpolation::Bicubic, 0.0, &mut out))
                .unwrap();
            out
        };
        assert_eq!(run(1), run(3));
    }

    #[test]
    fn devignetting_scales_the_signal_above_black() {
        let c = correction(RadialDistortion::None, Tca::None);
        let img = vec![1000u16; 61 * 41];
        let view = ImageView::contiguous(&img, 61, 41, 1).unwrap();
        let mut out = vec![0u16; img.len()];
        c.devignette(&view, &[200.0, 100.0], 2, &mut out).unwrap();
        let want = 200.0 + 800.0 * c.gain(0.0, 0.0);
        assert_eq!(out[0], (want + 0.5) as u16);
        assert_eq!(out[30 + 20 * 61], 1000);
    }

    #[test]
    fn bad_models_and_sizes_are_errors() {
        assert!(RadialDistortion::new("poly7", &[0.1]).is_err());
        assert!(RadialDistortion::new("ptlens", &[0.1, 0.2]).is_err());
        assert!(Tca::new("poly3", &[1.0, 1.0, 0.0, 0.0, f64::NAN, 0.0]).is_err());
        assert!(Normalization::new(10, 10, 0.0, 1.0, 1.5, (0.0, 0.0)).is_err());
        let c = correction(RadialDistortion::None, Tca::None);
        let img = vec![0u8; 10 * 10 * 3];
        let view = ImageView::contiguous(&img, 10, 10, 3).unwrap();
        let mut out = vec![0u8; img.len()];
        assert!(c
            .correct_geometry(&view, Interpolation::Bilinear, 0.0, &mut out)
            .is_err());
    }
}

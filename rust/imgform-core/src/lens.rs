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
//! order), and the three channels are sampled in one pass from the source
//! with [`crate::remap`]'s sampler, each at its own position. Vignetting divides linear values by the
//! calibrated falloff `1 + k1 r² + k2 r⁴ + k3 r⁶` (the `pa` model) at the
//! pixel's own position, so it belongs before any tone curve and before the
//! geometry is resampled (it describes the uncorrected image). On linear
//! RGB, [`LensCorrection::correct_geometry`] applies it in the resampling
//! pass, each sample times the gain at its own source position.
//!
//! # Precision
//! Everything is evaluated in `f64`. The positions are exact on a grid of
//! nodes at most 16 px apart and bilinearly interpolated in between, the
//! step refined until the interpolation is within 0.002 px of the exact
//! positions at every cell centre (`GRID_TOLERANCE`; vignetting gains
//! interpolated on the same grid to 1e-5, `GAIN_TOLERANCE`). lensfun works in `f32`,
//! accumulates pixel steps, and its SSE paths approximate square roots with
//! `rcp(rsqrt(x))` (12 bits): against its scalar path positions agree to a
//! few thousandths of a pixel, against its SSE path (whole-row calls on
//! aligned buffers) only to about 1e-4 of the radius.

use crate::error::{positive, CoreError, Result};
use crate::image::{ImageView, Sample};
use crate::invalid;
use crate::parallel::{for_each_band, for_each_row, ROWS_PER_TASK};
use rayon::prelude::*;
use std::sync::OnceLock;
use step::{nearest, step_cells, Cell, STEP_BITS};

#[path = "lens_step.rs"]
mod step;

use crate::remap::{
    check_fill, resample_channels, to_fixed, ChannelRows, Interpolation, Resample, FRAC_BITS,
    MAX_SIDE,
};

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

    /// The radius ratios of red, green and blue at `r² = r2`: one call for
    /// all three, so that `poly3` takes its square root once per position
    /// rather than once per channel (the grid evaluates this at every node
    /// and every cell centre it checks).
    #[inline(always)]
    fn ratios(&self, r2: f64) -> [f64; 3] {
        match *self {
            Self::None => [1.0; 3],
            Self::Linear { kr, kb } => [kr, 1.0, kb],
            Self::Poly3 { v, c, b } => {
                let r = r2.sqrt();
                let side = |s: usize| b[s] * r2 + c[s] * r + v[s];
                [side(0), 1.0, side(1)]
            }
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
        // Both sides computed, then selected: a loop of gains vectorises.
        let gain = 1.0 / falloff;
        if falloff > 0.0 {
            gain
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

/// A [`LensCorrection`] that keeps the grids of source positions it
/// builds (one without and one with vignetting gains), so that correcting
/// many images of one size, the frames of a sequence or a batch from one
/// lens at one setting, builds each grid once: at 24 MP a grid is ~100 k
/// lens-model evaluations, ~4 ms of a ~50 ms 8-bit correction. A grid
/// holds 48 bytes per node (~7 MB at 24 MP).
#[derive(Debug)]
pub struct LensCorrector {
    lens: LensCorrection,
    grids: [OnceLock<PositionGrid>; 2],
}

impl LensCorrector {
    pub fn new(lens: LensCorrection) -> Self {
        Self {
            lens,
            grids: Default::default(),
        }
    }

    /// The correction it applies.
    pub fn lens(&self) -> &LensCorrection {
        &self.lens
    }

    /// [`LensCorrection::correct_geometry`] through the kept grid (built
    /// on first use; a concurrent first use waits for it).
    ///
    /// # Errors
    /// As [`LensCorrection::correct_geometry`].
    pub fn correct_geometry<T: Resample>(
        &self,
        src: &ImageView<T>,
        interpolation: Interpolation,
        fill: f64,
        vignetting: bool,
        out: &mut [T],
    ) -> Result<()> {
        self.lens.check_image(src, 3)?;
        let fill = check_fill::<T>(fill)?;
        let grid = self.grids[usize::from(vignetting)]
            .get_or_init(|| PositionGrid::new(&self.lens, vignetting));
        resample_channels(src, grid, interpolation, fill, out)
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
    /// Where the corrected image's pixel `(u, v)` lies in the uncorrected
    /// one, in pixels: `(x, y)` of R, G and B. The distortion is evaluated
    /// once and each channel's TCA applied to its result.
    #[inline(always)]
    pub fn sources(&self, u: f64, v: f64) -> [f64; 6] {
        let n = &self.normalization;
        let (x, y) = n.to_normalized(u, v);
        let d = self.distortion.ratio(x * x + y * y);
        let (x, y) = (x * d, y * d);
        let ratios = self.tca.ratios(x * x + y * y);
        let mut out = [0.0; 6];
        for (xy, t) in out.chunks_exact_mut(2).zip(ratios) {
            (xy[0], xy[1]) = n.to_pixel(x * t, y * t);
        }
        out
    }

    /// Whether the correction moves pixels (has a distortion or TCA model).
    pub fn corrects_geometry(&self) -> bool {
        self.distortion != RadialDistortion::None || self.tca != Tca::None
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

    /// Writes the source positions the geometry correction samples at,
    /// `(H, W, 3, 2)` as `(x, y)` per channel R, G, B (the layout of
    /// lensfunpy's `apply_subpixel_geometry_distortion`): exact on a coarse
    /// grid, interpolated in between to within [`GRID_TOLERANCE`] px.
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
        let grid = PositionGrid::new(self, false);
        for_each_band(out, row_len, ROWS_PER_TASK, |v0, band| {
            let mut line = Vec::new();
            for (i, row) in band.chunks_exact_mut(row_len).enumerate() {
                grid.row(v0 + i, &mut line, |u, p| {
                    row[6 * u..6 * u + 6].copy_from_slice(&p);
                });
            }
        });
        Ok(())
    }

    /// Resamples an RGB image into its distortion- and TCA-corrected form in
    /// one pass: each channel of `out` (contiguous, the source's shape) is
    /// read from `src` at its own position (see
    /// [`LensCorrection::positions`]; the sampler's 1/256 px fixed point is
    /// stepped along each grid cell, so a position can differ from theirs
    /// by one such step where it lies within 2^-16 of a rounding tie).
    /// Taps outside the source read `fill`, as in [`crate::remap`].
    ///
    /// With `vignetting` (and a vignetting model), each sample is also
    /// multiplied by the gain at its own source position, so that one pass
    /// does what [`LensCorrection::devignette`] followed by this method
    /// does in two. Both approximate the same continuous image: they differ
    /// by the gain's change across one pixel times the local contrast (0 on
    /// flat areas, a few 1e-4 of full scale at the corners of a 24 MP frame
    /// of a strongly vignetting lens), and integers are rounded once instead
    /// of twice. Samples that read only `fill` stay `fill`.
    ///
    /// # Errors
    /// An image that is not `height x width x 3`, a `fill` the sample type
    /// cannot hold, or `out` of the wrong length.
    pub fn correct_geometry<T: Resample>(
        &self,
        src: &ImageView<T>,
        interpolation: Interpolation,
        fill: f64,
        vignetting: bool,
        out: &mut [T],
    ) -> Result<()> {
        LensCorrector::new(*self).correct_geometry(src, interpolation, fill, vignetting, out)
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
        if black_width == 0
            || black_tile.is_empty()
            || !black_tile.len().is_multiple_of(black_width)
        {
            return Err(CoreError::Shape(format!(
                "the black tile must be a non-empty (rows, {black_width}) array, got {} values",
                black_tile.len()
            )));
        }
        if let Some(b) = black_tile.iter().find(|b| !b.is_finite()) {
            // NaN or inf made every output sample 0.
            return Err(invalid!("the black levels must be finite, got {b}"));
        }
        let row_len = src.row_len();
        if out.len() != row_len * self.height {
            return Err(CoreError::Shape(format!(
                "output must hold {} samples, got {}",
                row_len * self.height,
                out.len()
            )));
        }
        let channels = src.channels();
        // The black tile laid out over whole rows, so that the loop over a
        // row's samples is a plain zip that vectorises (cycling through the
        // tile in it, or indexing `u % black_width`, did not).
        let black_rows: Vec<Vec<f64>> = black_tile
            .chunks_exact(black_width)
            .map(|tile| tile.iter().copied().cycle().take(row_len).collect())
            .collect();
        let gains = self.gain_rows();
        for_each_band(out, row_len, ROWS_PER_TASK, |v0, band| {
            let mut gain = vec![0.0f32; self.width];
            let mut per_sample = vec![0.0f32; if channels > 1 { row_len } else { 0 }];
            for (i, row) in band.chunks_exact_mut(row_len).enumerate() {
                let v = v0 + i;
                gains.row(v, 0, &mut gain);
                let gain = if channels > 1 {
                    for (g, &p) in per_sample.chunks_exact_mut(channels).zip(&gain) {
                        g.fill(p);
                    }
                    &per_sample
                } else {
                    &gain
                };
                let black = &black_rows[v % black_rows.len()];
                for (((o, &value), &g), &black) in
                    row.iter_mut().zip(src.row(v)).zip(gain).zip(black)
                {
                    let g = f64::from(g);
                    *o = T::from_f32((black + (f64::from(value.to_f32()) - black) * g) as f32);
                }
            }
        });
        Ok(())
    }

    /// The vignetting gains by row: `r²` splits into a column and a row term,
    /// so each row's gains cost one polynomial per pixel and no coordinate
    /// transform. The terms are exact `f64` values rounded once to `f32`
    /// (see [`GainRows`]).
    pub(crate) fn gain_rows(&self) -> GainRows {
        let n = &self.normalization;
        // In vignetting units, so that a row adds its term and evaluates.
        let square = |p: f64, centre: f64| {
            let d = (p * n.scale - centre) * n.to_diagonal;
            d * d
        };
        GainRows {
            k: self.vignetting.map(|v| v.k.map(|k| k as f32)),
            columns: (0..self.width)
                .map(|u| square(u as f64, n.center.0) as f32)
                .collect(),
            rows: (0..self.height)
                .map(|v| square(v as f64, n.center.1) as f32)
                .collect(),
        }
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

/// The largest distance, in pixels, between an interpolated source position
/// and the exact one that the geometry correction's grid accepts at its
/// cells' centres: below the 1/512 px rounding of the sampler's fixed point,
/// and far below the 0.01 px to which lensfun's own positions are reproduced.
pub const GRID_TOLERANCE: f64 = 0.002;

/// The largest error of an interpolated vignetting gain (relative, or
/// absolute below 1) that the grid accepts at its cells' centres: a tenth
/// of the 1e-4 to which the gains match lensfun's.
pub const GAIN_TOLERANCE: f64 = 1e-5;

/// The coarsest grid step used, in pixels. Lens models are smooth low-order
/// polynomials of the radius, so on camera-sized images bilinear
/// interpolation over 8-16 px cells is within [`GRID_TOLERANCE`]; tiny
/// images (a radius of tens of pixels) need finer steps. Coarser cells
/// would step their positions through more roundings (see `lens_step.rs`).
const COARSEST_STEP: usize = 16;

/// The step of the probe grid that the grid's step is predicted from: four
/// times the coarsest, so that the probe costs a sixteenth of a grid of
/// that step.
const PROBE_STEP: usize = 4 * COARSEST_STEP;

/// The share of a tolerance that a predicted step aims at: the error of
/// bilinear interpolation grows with the square of the step only to first
/// order, and a prediction that misses costs a whole grid more.
const PREDICTION_MARGIN: f64 = 0.8;

/// Source positions evaluated exactly only at grid nodes and bilinearly
/// interpolated in between: the lens models (a square root, TCA per
/// channel) cost far more than a 6-wide interpolation, and a 24 MP image
/// needs ~100 k nodes instead of 24 M evaluations.
///
/// The step is the largest that keeps every cell centre (where bilinear
/// interpolation strays furthest from a smooth function) within
/// [`GRID_TOLERANCE`] of the exact position, as predicted from a coarser
/// probe and then checked; at step 1 every pixel is a node.
#[derive(Debug)]
struct PositionGrid {
    columns: Axis,
    rows: Axis,
    /// `(x, y)` of R, G and B per node, rows of `columns.nodes.len()`.
    nodes: Vec<[f64; 6]>,
    /// The vignetting gains at those positions, per node (empty when the
    /// pass does not devignette): as smooth as the positions, so the same
    /// grid interpolates them far below the 1e-4 they are matched to.
    gains: Vec<[f64; 3]>,
}

/// The nodes along one side and, per pixel, the cell it falls in and its
/// weight towards the cell's far node.
#[derive(Debug)]
struct Axis {
    nodes: Vec<usize>,
    /// Per cell, one over its length in pixels (1 for a cell of zero
    /// length): the position rows step by differences times this, where a
    /// division per coordinate and cell was their setup's hottest spot. The
    /// product is within an ulp of the quotient, and a step is rounded to
    /// 2^-24 px.
    reciprocal: Vec<f64>,
    cell: Vec<usize>,
    weight: Vec<f64>,
}

impl Axis {
    /// Every `step`-th pixel of `n` and the last one; a side of one pixel
    /// has its node twice (a cell of zero length, weight 0).
    fn new(n: usize, step: usize) -> Self {
        let mut nodes: Vec<usize> = (0..n).step_by(step).collect();
        if nodes.len() < 2 || nodes[nodes.len() - 1] != n - 1 {
            nodes.push(n - 1);
        }
        let reciprocal = nodes
            .windows(2)
            .map(|c| 1.0 / (c[1] - c[0]).max(1) as f64)
            .collect();
        let mut axis = Self {
            nodes,
            reciprocal,
            cell: Vec::with_capacity(n),
            weight: Vec::with_capacity(n),
        };
        for i in 0..axis.nodes.len() - 1 {
            let (a, b) = (axis.nodes[i], axis.nodes[i + 1]);
            for p in axis.span(i, n) {
                axis.cell.push(i);
                axis.weight.push(if b > a {
                    (p - a) as f64 / (b - a) as f64
                } else {
                    0.0
                });
            }
        }
        axis
    }

    /// The pixels of cell `i` on a side of `n`: from its node up to the
    /// next, which only the last cell includes.
    #[inline(always)]
    fn span(&self, i: usize, n: usize) -> std::ops::Range<usize> {
        let (a, b) = (self.nodes[i], self.nodes[i + 1]);
        let end = if i + 2 == self.nodes.len() { b + 1 } else { b };
        a..end.min(n)
    }
}

impl PositionGrid {
    /// The grid of `lens`'s positions and, with `gains` (and a vignetting
    /// model), of its vignetting gains there, within both tolerances
    /// ([`GRID_TOLERANCE`], [`GAIN_TOLERANCE`]) at every cell centre.
    ///
    /// The errors of a probe grid of [`PROBE_STEP`] predict the step, as
    /// bilinear errors grow with the step squared; a grid that still fails
    /// its check predicts the next, finer step from its own errors. Halving
    /// the step from 16 px instead took a typical zoom lens on a 24 MP
    /// frame to 8 px cells where 12 px ones were within tolerance: four
    /// times the nodes of a 16 px grid rather than twice, and half as many
    /// pixels per cell to spread each cell's set-up over.
    fn new(lens: &LensCorrection, gains: bool) -> Self {
        let probe = Self::with_step(lens, PROBE_STEP, gains);
        let mut step = next_step(PROBE_STEP, probe.worst_errors(lens)).min(COARSEST_STEP);
        loop {
            let grid = Self::with_step(lens, step, gains);
            let errors = grid.worst_errors(lens);
            if step == 1 || (errors.0 <= GRID_TOLERANCE && errors.1 <= GAIN_TOLERANCE) {
                return grid;
            }
            step = next_step(step, errors);
        }
    }

    /// The grid of nodes every `step` pixels, with gains if `gains`.
    fn with_step(lens: &LensCorrection, step: usize, gains: bool) -> Self {
        let columns = Axis::new(lens.width, step);
        let rows = Axis::new(lens.height, step);
        let mut nodes = vec![[0.0; 6]; columns.nodes.len() * rows.nodes.len()];
        for_each_row(&mut nodes, columns.nodes.len(), |j, line| {
            let v = rows.nodes[j] as f64;
            for (p, &u) in line.iter_mut().zip(&columns.nodes) {
                *p = lens.sources(u as f64, v);
            }
        });
        let mut grid = Self {
            columns,
            rows,
            nodes,
            gains: Vec::new(),
        };
        if gains {
            grid.add_gains(lens);
        }
        grid
    }

    /// Evaluates the vignetting gains at the nodes' source positions
    /// (nothing without a vignetting model: the pass then has no gains).
    fn add_gains(&mut self, lens: &LensCorrection) {
        if lens.vignetting.is_none() {
            return;
        }
        let n = self.columns.nodes.len();
        self.gains = vec![[0.0; 3]; self.nodes.len()];
        for_each_row(&mut self.gains, n, |j, line| {
            for (g, p) in line.iter_mut().zip(&self.nodes[j * n..]) {
                *g = std::array::from_fn(|c| lens.gain(p[2 * c], p[2 * c + 1]));
            }
        });
    }

    /// The largest coordinate error (px) and relative gain error (0 without
    /// gains) at the cells' centres; infinite when a value there is not
    /// finite (such a grid is refined to step 1).
    ///
    /// In parallel over rows of cells: the check evaluates the models as
    /// often as the grid itself, and on one thread it held the other idle
    /// (the grid was 5.5 % of a 24 MP float32 correction's profile). A
    /// maximum does not depend on the order it is taken in, so neither
    /// does the grid.
    fn worst_errors(&self, lens: &LensCorrection) -> (f64, f64) {
        let centres = |nodes: &[usize]| -> Vec<usize> {
            nodes.windows(2).map(|c| (c[0] + c[1]) / 2).collect()
        };
        let (us, vs) = (centres(&self.columns.nodes), centres(&self.rows.nodes));
        let worse = |worst: f64, e: f64| {
            if e.is_nan() {
                f64::INFINITY
            } else {
                worst.max(e)
            }
        };
        let row = |v: usize| {
            let (mut position, mut gain) = (0.0f64, 0.0f64);
            for &u in &us {
                let exact = lens.sources(u as f64, v as f64);
                for (a, b) in self.at(&self.nodes, u, v).iter().zip(exact) {
                    position = worse(position, (a - b).abs());
                }
                if !self.gains.is_empty() {
                    for (c, g) in self.at(&self.gains, u, v).iter().enumerate() {
                        let want = lens.gain(exact[2 * c], exact[2 * c + 1]);
                        gain = worse(gain, (g - want).abs() / want.abs().max(1.0));
                    }
                }
            }
            (position, gain)
        };
        vs.into_par_iter()
            .map(row)
            .reduce(|| (0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)))
    }

    /// The interpolated values (positions or gains) of pixel `(u, v)`: the
    /// same operations in the same order as [`PositionGrid::row`], so the
    /// same bits.
    fn at<const N: usize>(&self, nodes: &[[f64; N]], u: usize, v: usize) -> [f64; N] {
        let n = self.columns.nodes.len();
        let (j, ty) = (self.rows.cell[v], self.rows.weight[v]);
        let (i, tx) = (self.columns.cell[u], self.columns.weight[u]);
        let node = |j: usize, i: usize| &nodes[j * n + i];
        let left = lerp(node(j, i), node(j + 1, i), ty);
        let right = lerp(node(j, i + 1), node(j + 1, i + 1), ty);
        lerp(&left, &right, tx)
    }

    /// The grid rows of `nodes` (positions or gains) around image row `v`
    /// interpolated to it, into `line` (one value per grid column).
    #[inline(always)]
    fn vertical<const N: usize>(&self, nodes: &[[f64; N]], v: usize, line: &mut Vec<[f64; N]>) {
        let n = self.columns.nodes.len();
        let (j, t) = (self.rows.cell[v], self.rows.weight[v]);
        let (above, below) = (&nodes[j * n..][..n], &nodes[(j + 1) * n..][..n]);
        line.clear();
        line.extend(above.iter().zip(below).map(|(a, b)| lerp(a, b, t)));
    }

    /// Calls `f(u, positions)` for every pixel of row `v`, interpolating the
    /// grid rows around it into `line` first.
    #[inline(always)]
    fn row(&self, v: usize, line: &mut Vec<[f64; 6]>, mut f: impl FnMut(usize, [f64; 6])) {
        self.vertical(&self.nodes, v, line);
        for (u, (&i, &t)) in self
            .columns
            .cell
            .iter()
            .zip(&self.columns.weight)
            .enumerate()
        {
            f(u, lerp(&line[i], &line[i + 1], t));
        }
    }
}

/// The step a grid of `step` with worst errors `(position, gain)` should
/// be refined to: the step whose errors, scaled by the step squared, come
/// to [`PREDICTION_MARGIN`] of the tighter tolerance, but at least one
/// pixel finer than `step` and no finer than 1 (where an infinite error,
/// a value that is not finite, goes).
fn next_step(step: usize, (position, gain): (f64, f64)) -> usize {
    let room = (GRID_TOLERANCE / position).min(GAIN_TOLERANCE / gain);
    let scaled = step as f64 * (PREDICTION_MARGIN * room).sqrt();
    // `as` saturates: an infinite room (no error) gives usize::MAX.
    (scaled as usize).min(step - 1).max(1)
}

/// `a + (b - a) t` per coordinate.
#[inline(always)]
fn lerp<const N: usize>(a: &[f64; N], b: &[f64; N], t: f64) -> [f64; N] {
    std::array::from_fn(|k| a[k] + (b[k] - a[k]) * t)
}

/// Grid rows interpolated to one image row, reused from row to row.
#[derive(Default)]
pub(crate) struct GridLines {
    positions: Vec<[f64; 6]>,
    gains: Vec<[f64; 3]>,
    /// The row's cells whose positions are stepped.
    cells: Vec<Cell>,
}

impl ChannelRows for PositionGrid {
    type Scratch = GridLines;

    /// The grid rows around `y` are interpolated once; along each cell the
    /// fixed-point positions then advance by a constant integer step, which
    /// replaces six multiplications, conversions and clamps per pixel by
    /// six additions. Cells whose nodes are not finite or out of the fixed
    /// point's range take the exact per-pixel form, clamps and NaN included.
    ///
    /// Compiled for AVX2 where the CPU has it: the interpolations are
    /// `f64` work that the baseline build does two lanes wide. Without
    /// fused multiply-adds the operations, and so the bits, are the same.
    fn fill_row(&self, y: usize, lines: &mut GridLines, xy: &mut [i32], gains: &mut [f32]) {
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::has_avx2() {
            // SAFETY: AVX2 was detected just above.
            return unsafe { self.fill_row_avx2(y, lines, xy, gains) };
        }
        self.fill_row_any(y, lines, xy, gains);
    }

    fn has_gains(&self) -> bool {
        !self.gains.is_empty()
    }
}

impl PositionGrid {
    /// [`ChannelRows::fill_row`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn fill_row_avx2(&self, y: usize, lines: &mut GridLines, xy: &mut [i32], gains: &mut [f32]) {
        self.fill_row_any(y, lines, xy, gains);
    }

    /// [`ChannelRows::fill_row`] for whichever instruction set it is
    /// inlined into.
    #[inline(always)]
    fn fill_row_any(&self, y: usize, lines: &mut GridLines, xy: &mut [i32], gains: &mut [f32]) {
        self.vertical(&self.nodes, y, &mut lines.positions);
        let line = &lines.positions;
        let width = self.columns.cell.len();
        let scale = f64::from(1u32 << (FRAC_BITS + STEP_BITS));
        lines.cells.clear();
        for i in 0..line.len() - 1 {
            let span = self.columns.span(i, width);
            let (a, b) = (&line[i], &line[i + 1]);
            let in_range = |p: &[f64; 6]| p.iter().all(|v| v.abs() < MAX_SIDE as f64);
            if !(in_range(a) && in_range(b)) {
                let out = &mut xy[6 * span.start..6 * span.end];
                for (q, &w) in out.chunks_exact_mut(6).zip(&self.columns.weight[span]) {
                    for (q, v) in q.iter_mut().zip(lerp(a, b, w)) {
                        *q = to_fixed(v);
                    }
                }
                continue;
            }
            let per_pixel = self.columns.reciprocal[i] * scale;
            let mut cell = Cell {
                pixels: span,
                start: [0; 6],
                step: [0; 6],
            };
            // Plain loops: `array::map` was not inlined, a call per cell.
            for k in 0..6 {
                cell.start[k] = nearest(a[k] * scale);
                cell.step[k] = nearest((b[k] - a[k]) * per_pixel);
            }
            lines.cells.push(cell);
        }
        step_cells(&lines.cells, xy);
        if !gains.is_empty() {
            self.vertical(&self.gains, y, &mut lines.gains);
            let line = &lines.gains;
            // Cell by cell, as `lerp` computes them (the same bits) but
            // with the cell's differences taken once, not per pixel.
            for i in 0..line.len() - 1 {
                let span = self.columns.span(i, width);
                let (a, b) = (&line[i], &line[i + 1]);
                let d: [f64; 3] = std::array::from_fn(|k| b[k] - a[k]);
                let out = &mut gains[3 * span.start..3 * span.end];
                cell_gains((a, &d), &self.columns.weight[span], out);
            }
        }
    }
}

/// Pixels per step of [`cell_gains`]: four pixels' twelve gains fill three
/// AVX2 registers of `f64`.
const GAIN_PIXELS: usize = 4;

/// The gains of one cell's pixels, `a + d w` per channel at each pixel's
/// weight `w`, rounded to `f32` (`lerp`'s operations, so its bits). Whole
/// steps of [`GAIN_PIXELS`] pixels are one flat run of values that the
/// compiler vectorises; a loop of three values per pixel compiled to
/// scalar code and took about half of a devignetting correction's
/// position rows in a profile.
#[inline(always)]
fn cell_gains((a, d): (&[f64; 3], &[f64; 3]), weights: &[f64], out: &mut [f32]) {
    const N: usize = 3 * GAIN_PIXELS;
    let (a_run, d_run): ([f64; N], [f64; N]) = (
        std::array::from_fn(|i| a[i % 3]),
        std::array::from_fn(|i| d[i % 3]),
    );
    let mut steps = out.chunks_exact_mut(N);
    let mut step_weights = weights.chunks_exact(GAIN_PIXELS);
    for (g, w) in (&mut steps).zip(&mut step_weights) {
        for i in 0..N {
            g[i] = (a_run[i] + d_run[i] * w[i / 3]) as f32;
        }
    }
    let rest = steps.into_remainder().chunks_exact_mut(3);
    for (g, &w) in rest.zip(step_weights.remainder()) {
        for k in 0..3 {
            g[k] = (a[k] + d[k] * w) as f32;
        }
    }
}

/// The vignetting gains of whole rows, in `f32` (see
/// [`LensCorrection::gain_rows`]).
///
/// A development evaluates a gain for every photosite twice (its range
/// pass and the demosaic's loads), and in `f64` the division and the
/// conversions held AVX2 to four lanes. In `f32` a gain is within a few
/// units in the last place, a few 1e-7 relative, of the `f64` one: far
/// below the 1e-4 to which the gains match lensfun's (which computes them
/// in `f32` itself), and below the 16-bit rounding of the values it
/// multiplies.
pub(crate) struct GainRows {
    /// The `pa` coefficients; `None` without a vignetting model.
    k: Option<[f32; 3]>,
    /// `x²` of each column and `y²` of each row, in vignetting units.
    columns: Vec<f32>,
    rows: Vec<f32>,
}

impl GainRows {
    /// Writes the gains of row `v`, columns `x0 .. x0 + out.len()`, into
    /// `out`. Inlined, so that it runs in the instruction set of the
    /// demosaic that loads the photosites (a division per photosite, four
    /// lanes wide in the baseline build, eight in AVX2).
    #[inline(always)]
    pub(crate) fn row(&self, v: usize, x0: usize, out: &mut [f32]) {
        let Some([k1, k2, k3]) = self.k else {
            out.fill(1.0);
            return;
        };
        let y2 = self.rows[v];
        for (g, &x2) in out.iter_mut().zip(&self.columns[x0..]) {
            let r2 = x2 + y2;
            let falloff = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
            // As `Vignetting::gain`: both sides computed, then selected.
            let gain = 1.0 / falloff;
            *g = if falloff > 0.0 { gain } else { 0.0 };
        }
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

    fn source(c: &LensCorrection, channel: usize, u: f64, v: f64) -> (f64, f64) {
        let p = c.sources(u, v);
        (p[2 * channel], p[2 * channel + 1])
    }

    fn strong(width: usize, height: usize, distortion: RadialDistortion) -> LensCorrection {
        LensCorrection {
            width,
            height,
            normalization: Normalization::new(width, height, 1.5, 1.5, 1.5, (0.01, -0.02)).unwrap(),
            distortion,
            tca: Tca::Poly3 {
                v: [1.002, 0.998],
                c: [0.001, -0.001],
                b: [0.0005, -0.0004],
            },
            vignetting: None,
        }
    }

    #[test]
    fn interpolated_positions_stay_within_the_tolerance_of_the_exact_ones() {
        let models = [
            RadialDistortion::Poly3 { k1: -0.08 },
            RadialDistortion::Poly5 { k1: 0.1, k2: -0.04 },
            RadialDistortion::PtLens {
                a: 0.02,
                b: -0.06,
                c: 0.03,
            },
        ];
        // Tiny (steps refine), odd, one-pixel-wide and camera-like shapes.
        for (w, h) in [(37, 23), (1, 9), (400, 267), (1201, 800)] {
            for d in models {
                let c = strong(w, h, d);
                let mut pos = vec![0.0; w * h * 6];
                c.positions(&mut pos).unwrap();
                let mut worst = 0.0f64;
                for (i, p) in pos.chunks_exact(6).enumerate() {
                    let exact = c.sources((i % w) as f64, (i / w) as f64);
                    for (a, b) in p.iter().zip(exact) {
                        worst = worst.max((a - b).abs());
                    }
                }
                // Cell centres are checked against GRID_TOLERANCE; elsewhere
                // bilinear error is smaller for these smooth models.
                assert!(worst <= GRID_TOLERANCE, "{w}x{h} {d:?}: {worst}");
            }
        }
    }

    #[test]
    fn a_typical_lens_on_a_24_mp_frame_needs_only_a_coarse_grid() {
        // Bilinear error grows with the step squared and shrinks with the
        // image size: k1 = -0.02 on 6000 x 4000 px is within tolerance at 8 px.
        let c = strong(6000, 4000, RadialDistortion::Poly3 { k1: -0.02 });
        let grid = PositionGrid::new(&c, false);
        assert!(grid.columns.nodes[1] >= 8, "step {}", grid.columns.nodes[1]);
        assert_eq!(*grid.columns.nodes.last().unwrap(), 5999);
        assert_eq!(*grid.rows.nodes.last().unwrap(), 3999);
    }

    /// Channel `channel`'s fixed-point positions (rows of `6 * width`), read
    /// pixel by pixel through the remap sampler's per-pixel path.
    struct OneChannel<'a>(&'a [i32], usize, usize);

    impl crate::remap::Coords for OneChannel<'_> {
        fn at(&self, x: usize, y: usize) -> (i32, i32) {
            let p = &self.0[6 * (y * self.2 + x) + 2 * self.1..];
            (p[0], p[1])
        }
    }

    /// The fixed-point positions the pass samples at, row by row, and its
    /// gains (empty without `gains`).
    fn pass_rows(c: &LensCorrection, gains: bool) -> (Vec<i32>, Vec<f32>) {
        let grid = PositionGrid::new(c, gains);
        let (w, h) = (c.width, c.height);
        let mut xy = vec![0; 6 * w * h];
        let mut g = vec![0.0; if grid.has_gains() { 3 * w * h } else { 0 }];
        let mut lines = GridLines::default();
        for v in 0..h {
            let gv = if g.is_empty() {
                &mut []
            } else {
                &mut g[3 * w * v..3 * w * (v + 1)]
            };
            grid.fill_row(v, &mut lines, &mut xy[6 * w * v..6 * w * (v + 1)], gv);
        }
        (xy, g)
    }

    #[test]
    fn stepped_positions_are_the_rounded_interpolated_ones_within_one_step() {
        let models = [
            RadialDistortion::Poly3 { k1: -0.08 },
            RadialDistortion::PtLens {
                a: 0.02,
                b: -0.06,
                c: 0.03,
            },
        ];
        for (w, h) in [(37, 23), (1, 9), (9, 1), (1, 1), (400, 267)] {
            for d in models {
                let c = strong(w, h, d);
                let mut pos = vec![0.0; w * h * 6];
                c.positions(&mut pos).unwrap();
                let (xy, _) = pass_rows(&c, false);
                let off = pos
                    .iter()
                    .zip(&xy)
                    .filter(|&(&p, &q)| {
                        let e = (to_fixed(p) - q).abs();
                        assert!(e <= 1, "{w}x{h} {d:?}: {p} -> {q}");
                        e == 1
                    })
                    .count();
                // A step off only within ~2^-13 of a rounding tie: rare.
                assert!(off * 500 <= pos.len(), "{w}x{h}: {off} of {}", pos.len());
            }
        }
    }

    #[test]
    fn the_avx2_position_rows_are_the_baseline_ones_bit_for_bit() {
        // With gains, on an odd size whose last cell is short; the dispatch
        // takes the AVX2 build where the CPU has it.
        let (w, h) = (203, 37);
        let mut c = strong(w, h, RadialDistortion::Poly3 { k1: -0.05 });
        c.vignetting = Some(Vignetting {
            k: [-0.3, 0.1, -0.05],
        });
        let grid = PositionGrid::new(&c, true);
        let mut lines = GridLines::default();
        let (mut xy, mut g) = (vec![0; 6 * w], vec![0.0f32; 3 * w]);
        let (mut xy_any, mut g_any) = (xy.clone(), g.clone());
        for v in 0..h {
            grid.fill_row(v, &mut lines, &mut xy, &mut g);
            grid.fill_row_any(v, &mut lines, &mut xy_any, &mut g_any);
            assert_eq!(xy, xy_any, "row {v}");
            let bits = |g: &[f32]| g.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&g), bits(&g_any), "row {v}");
        }
    }

    #[test]
    fn cell_gains_are_the_interpolated_gains_bit_for_bit() {
        let (a, b) = ([1.25, 0.8, 3.0e-3], [1.5, 0.7999, 2.0]);
        let d = std::array::from_fn(|k| b[k] - a[k]);
        // No pixel, fewer than a step, whole steps and a remainder.
        for n in 0..=11 {
            let weights: Vec<f64> = (0..n).map(|p| p as f64 / 11.0).collect();
            let mut out = vec![0.0f32; 3 * n];
            cell_gains((&a, &d), &weights, &mut out);
            for (g, &w) in out.chunks_exact(3).zip(&weights) {
                let want = lerp(&a, &b, w).map(|v| (v as f32).to_bits());
                assert_eq!(g.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), want);
            }
        }
    }

    #[test]
    fn a_refined_step_is_the_largest_the_squared_scaling_admits() {
        let fits = |s: usize, step: usize, (p, g): (f64, f64)| {
            let shrink = (s as f64 / step as f64).powi(2);
            p * shrink <= PREDICTION_MARGIN * GRID_TOLERANCE
                && g * shrink <= PREDICTION_MARGIN * GAIN_TOLERANCE
        };
        for (step, errors) in [
            (64, (0.05, 0.0)),
            (64, (0.01, 4e-4)),
            (16, (0.0029, 0.0)),
            (16, (0.0021, 1.2e-5)),
            (12, (0.5, 0.0)),
        ] {
            let s = next_step(step, errors);
            assert!((1..step).contains(&s), "{step} {errors:?}: {s}");
            assert!(s == 1 || fits(s, step, errors), "{step} {errors:?}: {s}");
            assert!(
                s == step - 1 || !fits(s + 1, step, errors),
                "{step} {errors:?}: {s}"
            );
        }
        // 16 * sqrt(0.8 * 0.002 / 0.0029) = 11.9.
        assert_eq!(next_step(16, (0.0029, 0.0)), 11);
        assert_eq!(next_step(64, (0.0, 0.0)), 63);
        assert_eq!(next_step(16, (f64::INFINITY, 0.0)), 1);
    }

    #[test]
    fn a_zoom_lens_on_a_24_mp_frame_gets_a_step_between_the_powers_of_two() {
        // The benchmark's Canon EF-S 18-55mm at 18 mm on an EOS 550D: its
        // 16 px grid misses the tolerance, and halving the step would make
        // the cells finer than needed.
        let (w, h) = (6000, 4000);
        let mut c = LensCorrection {
            width: w,
            height: h,
            normalization: Normalization::new(w, h, 1.613, 1.622, 1.5, (0.0, 0.0)).unwrap(),
            distortion: RadialDistortion::PtLens {
                a: 0.00644,
                b: -0.01245,
                c: -0.0348,
            },
            tca: Tca::Poly3 {
                v: [1.0009927, 0.9995018],
                c: [0.0, 0.0],
                b: [-0.0003176, 0.0002609],
            },
            vignetting: Some(Vignetting {
                k: [-0.3159, 0.0175, 0.0074],
            }),
        };
        for gains in [false, true] {
            let grid = PositionGrid::new(&c, gains);
            let step = grid.columns.nodes[1];
            assert!((9..COARSEST_STEP).contains(&step), "step {step}");
            let (position, gain) = grid.worst_errors(&c);
            assert!(position <= GRID_TOLERANCE && gain <= GAIN_TOLERANCE);
        }
        c.vignetting = None;
        assert!(
            PositionGrid::with_step(&c, COARSEST_STEP, false)
                .worst_errors(&c)
                .0
                > GRID_TOLERANCE
        );
    }

    #[test]
    fn positions_out_of_the_fixed_point_range_take_the_exact_form() {
        // A huge pincushion sends the corners millions of pixels away:
        // clamped as `to_fixed` clamps, never wrapped around.
        let c = strong(31, 21, RadialDistortion::Poly5 { k1: 1e6, k2: 1e9 });
        let mut pos = vec![0.0; 31 * 21 * 6];
        c.positions(&mut pos).unwrap();
        let (xy, _) = pass_rows(&c, false);
        assert_eq!(xy[0], to_fixed(pos[0]));
        assert!(xy[0] < 0 && xy[1] < 0);
        let img = vec![0.5f32; 31 * 21 * 3];
        let view = ImageView::contiguous(&img, 31, 21, 3).unwrap();
        let mut out = vec![0.0f32; img.len()];
        c.correct_geometry(&view, Interpolation::Bilinear, -1.0, false, &mut out)
            .unwrap();
        assert_eq!(&out[..3], &[-1.0; 3]);
    }

    #[test]
    fn the_fused_gain_is_the_vignetting_gain_at_each_channels_source() {
        let (w, h) = (601, 401);
        let mut c = strong(w, h, RadialDistortion::Poly3 { k1: -0.05 });
        c.vignetting = Some(Vignetting {
            k: [-0.3, 0.1, -0.05],
        });
        let img = vec![0.5f32; w * h * 3];
        let view = ImageView::contiguous(&img, w, h, 3).unwrap();
        let mut out = vec![0.0f32; img.len()];
        c.correct_geometry(&view, Interpolation::Bilinear, 0.0, true, &mut out)
            .unwrap();
        // Devignetting first: the same on a flat image but for the gain's
        // curvature over a pixel.
        let mut devignetted = vec![0.0f32; img.len()];
        c.devignette(&view, &[0.0], 1, &mut devignetted).unwrap();
        let dv = ImageView::contiguous(&devignetted, w, h, 3).unwrap();
        let mut two_pass = vec![0.0f32; img.len()];
        c.correct_geometry(&dv, Interpolation::Bilinear, 0.0, false, &mut two_pass)
            .unwrap();
        let inside = |x: f64, y: f64| {
            (0.0..=(w - 1) as f64).contains(&x) && (0.0..=(h - 1) as f64).contains(&y)
        };
        let (mut worst, mut checked) = (0.0f64, 0);
        for v in 0..h {
            for u in 0..w {
                let p = c.sources(u as f64, v as f64);
                for ch in 0..3 {
                    // Taps outside read the fill (0), not the flat image.
                    if !inside(p[2 * ch], p[2 * ch + 1]) {
                        continue;
                    }
                    let want = 0.5 * c.gain(p[2 * ch], p[2 * ch + 1]);
                    let i = 3 * (v * w + u) + ch;
                    worst = worst.max((f64::from(out[i]) / want - 1.0).abs());
                    let (a, b) = (out[i], two_pass[i]);
                    assert!((a - b).abs() <= 1e-4 * b, "{a} vs {b}");
                    checked += 1;
                }
            }
        }
        assert!(checked > w * h * 3 * 9 / 10);
        // The gain grid's interpolation, far below lensfun's 1e-4.
        assert!(worst < 2e-5, "{worst}");
    }

    #[test]
    fn fused_gains_round_integers_once_and_leave_fill_alone() {
        // Pincushion: the corners read outside the source, i.e. `fill`.
        let (w, h) = (61, 41);
        let mut c = strong(w, h, RadialDistortion::Poly3 { k1: 0.3 });
        c.vignetting = Some(Vignetting {
            k: [-0.3, 0.1, -0.05],
        });
        let flat: Vec<f32> = (0..w * h * 3).map(|i| (i * 53 % 251) as f32).collect();
        let img: Vec<u16> = flat.iter().map(|&v| v as u16).collect();
        let mut float = vec![0.0f32; img.len()];
        let fv = ImageView::contiguous(&flat, w, h, 3).unwrap();
        c.correct_geometry(&fv, Interpolation::Bilinear, 7.0, true, &mut float)
            .unwrap();
        let mut ints = vec![0u16; img.len()];
        let iv = ImageView::contiguous(&img, w, h, 3).unwrap();
        c.correct_geometry(&iv, Interpolation::Bilinear, 7.0, true, &mut ints)
            .unwrap();
        assert_eq!(&ints[..3], &[7, 7, 7]);
        assert_eq!(&float[..3], &[7.0, 7.0, 7.0]);
        for (&i, &f) in ints.iter().zip(&float) {
            // The integer path weighs in exact 256ths, the float one in f32.
            assert!(
                (f64::from(i) - f64::from(f)).abs() <= 0.5 + 1e-3,
                "{i} vs {f}"
            );
        }
    }

    #[test]
    fn one_pass_over_three_channels_equals_the_per_channel_passes() {
        for (w, h) in [(61, 41), (1, 9), (9, 1)] {
            one_pass_equals_per_channel(w, h);
        }
    }

    fn one_pass_equals_per_channel(w: usize, h: usize) {
        let c = strong(w, h, RadialDistortion::Poly3 { k1: -0.05 });
        let img: Vec<u8> = (0..w * h * 3).map(|i| (i * 53 % 251) as u8).collect();
        let view = ImageView::contiguous(&img, w, h, 3).unwrap();
        let (pos, _) = pass_rows(&c, false);
        for interp in [Interpolation::Bilinear, Interpolation::Bicubic] {
            let mut fused = vec![0u8; img.len()];
            c.correct_geometry(&view, interp, 7.0, false, &mut fused)
                .unwrap();
            let mut separate = vec![0u8; img.len()];
            for ch in 0..3 {
                crate::remap::resample(
                    &view,
                    &OneChannel(&pos, ch, w),
                    w,
                    h,
                    ch..ch + 1,
                    interp,
                    7.0,
                    &mut separate,
                )
                .unwrap();
            }
            assert_eq!(fused, separate);
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
                let (x, y) = source(&c, ch, u, v);
                assert!((x - u).abs() < 1e-9 && (y - v).abs() < 1e-9);
            }
            assert_eq!(c.gain(u, v), 1.0);
        }
    }

    #[test]
    fn barrel_distortion_reads_the_corners_from_nearer_the_centre() {
        let c = correction(RadialDistortion::Poly3 { k1: -0.05 }, Tca::None);
        let (x, y) = source(&c, 1, 0.0, 0.0);
        assert!(x > 0.0 && y > 0.0);
        // The centre itself does not move.
        let (x, y) = source(&c, 1, 30.0, 20.0);
        assert!((x - 30.0).abs() < 1e-9 && (y - 20.0).abs() < 1e-9);
    }

    #[test]
    fn tca_moves_red_and_blue_only() {
        let c = correction(RadialDistortion::None, Tca::Linear { kr: 1.01, kb: 0.99 });
        let g = source(&c, 1, 0.0, 0.0);
        assert!((g.0).abs() < 1e-9);
        let r = source(&c, 0, 0.0, 0.0);
        let b = source(&c, 2, 0.0, 0.0);
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
            pool.install(|| {
                c.correct_geometry(&view, Interpolation::Bicubic, 0.0, false, &mut out)?;
                let mut fused = vec![0u16; img.len()];
                c.correct_geometry(&view, Interpolation::Bilinear, 9.0, true, &mut fused)?;
                out.extend(fused);
                Ok::<_, CoreError>(())
            })
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
        let rows = c.gain_rows();
        let mut row = vec![0.0f32; 61];
        rows.row(0, 0, &mut row);
        let want = 200.0 + 800.0 * f64::from(row[0]);
        assert_eq!(out[0], (want + 0.5) as u16);
        assert!(want > 1000.0);
        assert_eq!(out[30 + 20 * 61], 1000);
        for v in [0, 17, 40] {
            rows.row(v, 0, &mut row);
            // Rows of gains in f32 are the exact per-pixel gains to a few
            // units in the last place.
            for (u, &g) in row.iter().enumerate() {
                let exact = c.gain(u as f64, v as f64);
                assert!((f64::from(g) / exact - 1.0).abs() < 5e-7, "{g} vs {exact}");
            }
            // A run from any column: the same gains.
            let mut tail = vec![0.0; 61 - 13];
            rows.row(v, 13, &mut tail);
            assert_eq!(tail, row[13..]);
        }
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
            .correct_geometry(&view, Interpolation::Bilinear, 0.0, true, &mut out)
            .is_err());
    }
}

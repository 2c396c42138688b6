//! Raw development: sensor numbers to a displayable RGB image.
//!
//! Two fused passes surround the demosaic. Before it, each photosite loses its
//! black level and is multiplied by one per-site factor that folds together
//! the scaling to white (`1 / (white - black)`), the white balance and the
//! exposure; the result is clipped to `[0, 1]` (the sensor clipped there, so
//! the balanced channels clip at the same point, as LibRaw's `highlight=0`
//! does) and stored in the demosaic's own sample type. After it, each pixel
//! goes through the 3x3 colour matrix, is clipped again and passes the tone
//! curve into the output type. Both passes are row-parallel and pure per
//! pixel, so the result does not depend on the number of threads.
//!
//! Integer outputs demosaic a `u16` mosaic (16 bits hold a 14-bit sensor
//! with WB gains of up to 4x without loss, as in LibRaw); float outputs
//! demosaic in `f32`. When the output has the demosaic's type
//! ([`develop_in_place`]) the demosaic writes into the output and the second
//! pass finishes it there, so the only extra memory is the prepared mosaic.

use crate::cfa::{check_out_len, CfaPattern};
use crate::demosaic::{demosaic, Method};
use crate::error::{all_finite, CoreError, Result};
use crate::image::{ImageView, Sample};
use crate::invalid;
use crate::parallel::for_each_row;

/// The transfer curve from linear light to output code values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tone {
    /// No curve: output proportional to light (for further processing).
    Linear,
    /// IEC 61966-2-1 sRGB: a linear toe below 0.0031308, then a 1/2.4 power.
    Srgb,
    /// ITU-R BT.709 camera OETF: linear below 0.018, then a 0.45 power.
    Bt709,
}

impl Tone {
    /// Every curve, in documentation order.
    pub const ALL: [Tone; 3] = [Tone::Srgb, Tone::Linear, Tone::Bt709];

    /// The curve's name in the Python API.
    pub fn name(self) -> &'static str {
        match self {
            Tone::Linear => "linear",
            Tone::Srgb => "srgb",
            Tone::Bt709 => "bt709",
        }
    }

    /// Parses a name of [`Tone::ALL`].
    ///
    /// # Errors
    /// [`CoreError::InvalidArgument`] listing the accepted names.
    pub fn from_name(name: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|t| t.name() == name)
            .ok_or_else(|| {
                invalid!(
                    "tone must be one of {:?}, got {name:?}",
                    Self::ALL.map(Tone::name)
                )
            })
    }

    /// The curve at linear value `v` in `[0, 1]`.
    pub fn apply(self, v: f32) -> f32 {
        match self {
            Tone::Linear => v,
            Tone::Srgb if v <= 0.003_130_8 => 12.92 * v,
            Tone::Srgb => 1.055 * v.powf(1.0 / 2.4) - 0.055,
            Tone::Bt709 if v < 0.018 => 4.5 * v,
            Tone::Bt709 => 1.099 * v.powf(0.45) - 0.099,
        }
    }
}

/// Everything the development applies around the demosaic.
#[derive(Debug, Clone)]
pub struct DevelopParams {
    /// `(rows, cols)` of the tile `black` and `scale` describe, repeated from
    /// pixel (0, 0): the CFA period, or a multiple of it when the sensor's
    /// black level repeats with a longer period (a DNG `BlackLevel` pattern
    /// larger than the CFA tile, which LibRaw subtracts pixel by pixel).
    pub tile: (usize, usize),
    /// Black level per tile cell (row-major), in digital numbers.
    pub black: Vec<f32>,
    /// Multiplier per tile cell applied after black subtraction, mapping
    /// white-balanced white to 1.0 (exposure included).
    pub scale: Vec<f32>,
    /// Row-major 3x3 matrix from white-balanced camera RGB to output RGB.
    pub matrix: [f32; 9],
    /// The output transfer curve.
    pub tone: Tone,
    /// The demosaicing method.
    pub method: Method,
}

impl DevelopParams {
    fn check(&self, pattern: &CfaPattern) -> Result<()> {
        let ((rows, cols), p) = (self.tile, pattern.period());
        if rows == 0 || cols == 0 || rows % p != 0 || cols % p != 0 {
            return Err(CoreError::Shape(format!(
                "the black/scale tile must be a multiple of the {p}x{p} CFA tile, got {rows}x{cols}"
            )));
        }
        let cells = rows * cols;
        for (name, v) in [("black", &self.black), ("scale", &self.scale)] {
            if v.len() != cells {
                return Err(CoreError::Shape(format!(
                    "{name} must have one value per cell of the {rows}x{cols} tile ({cells}), got {}",
                    v.len()
                )));
            }
            let as_f64: Vec<f64> = v.iter().map(|&x| f64::from(x)).collect();
            all_finite(name, &as_f64)?;
        }
        if let Some(s) = self.scale.iter().find(|&&s| s < 0.0) {
            return Err(invalid!("scale factors must be >= 0, got {s}"));
        }
        let m: Vec<f64> = self.matrix.iter().map(|&x| f64::from(x)).collect();
        all_finite("matrix", &m)
    }
}

/// Develops a raw mosaic into `out`, `(H, W, 3)` samples of type `U`,
/// demosaicing in type `T` in a buffer of its own (for `u8` outputs, which
/// keep a 16-bit demosaic: `develop::<u16, u8>`).
///
/// # Errors
/// [`CoreError::Shape`] for a multi-channel or too small `raw`, parameter
/// arrays of the wrong length or a wrong output length;
/// [`CoreError::InvalidArgument`] for non-finite or negative parameters or a
/// pattern the method cannot demosaic (X-Trans).
pub fn develop<T: Sample, U: Sample>(
    raw: ImageView<'_, u16>,
    pattern: &CfaPattern,
    params: &DevelopParams,
    out: &mut [U],
) -> Result<()> {
    check_out_len(out.len(), 3 * raw.width() * raw.height(), "develop")?;
    let mut rgb = vec![T::default(); out.len()];
    demosaic_prepared(raw, pattern, params, &mut rgb)?;
    let curve = Curve::new(params.tone);
    let row_len = 3 * raw.width();
    for_each_row(out, row_len, |y, row| {
        let mut px = vec![0.0f32; row_len];
        load_row(&rgb[row_len * y..row_len * (y + 1)], &mut px);
        curve.finish_row(&mut px, &params.matrix, row);
    });
    Ok(())
}

/// [`develop`] with the demosaic written straight into `out` and finished
/// there: no second full-size buffer (144 MB less at 24 MP in 16 bits).
/// For `u16` and `f32` outputs.
///
/// # Errors
/// As [`develop`].
pub fn develop_in_place<T: Sample>(
    raw: ImageView<'_, u16>,
    pattern: &CfaPattern,
    params: &DevelopParams,
    out: &mut [T],
) -> Result<()> {
    demosaic_prepared(raw, pattern, params, out)?;
    let curve = Curve::new(params.tone);
    for_each_row(out, 3 * raw.width(), |_, row| {
        let mut px = vec![0.0f32; row.len()];
        load_row(row, &mut px);
        curve.finish_row(&mut px, &params.matrix, row);
    });
    Ok(())
}

/// Checks everything, prepares the mosaic in `T` and demosaics it into `rgb`.
fn demosaic_prepared<T: Sample>(
    raw: ImageView<'_, u16>,
    pattern: &CfaPattern,
    params: &DevelopParams,
    rgb: &mut [T],
) -> Result<()> {
    params.check(pattern)?;
    let (w, h) = (raw.width(), raw.height());
    if raw.channels() != 1 {
        return Err(CoreError::Shape(format!(
            "develop needs a single-channel mosaic of shape (H, W), got {} channels",
            raw.channels()
        )));
    }
    check_out_len(rgb.len(), 3 * w * h, "develop")?;
    let mut mosaic = vec![T::default(); w * h];
    prepare(raw, params, &mut mosaic);
    demosaic(
        ImageView::contiguous(&mosaic, w, h, 1)?,
        pattern,
        params.method,
        rgb,
    )
}

/// A row of samples as linear values in [0, 1].
fn load_row<T: Sample>(src: &[T], px: &mut [f32]) {
    let inv = 1.0 / T::FULL_SCALE;
    for (p, s) in px.iter_mut().zip(src) {
        *p = s.to_f32() * inv;
    }
}

/// Black subtraction, scaling and clipping into the demosaic's sample type.
///
/// Each task first lays the tile row's black levels and factors out along
/// the whole image row (the tile may be as large as a black-level map, so
/// only one row of them is ever expanded), so the loop over the samples is
/// a plain zip that vectorises (a `x % cols` in it cost more than the rest),
/// and the conversion runs on its own over the row, where it vectorises too.
fn prepare<T: Sample>(raw: ImageView<'_, u16>, p: &DevelopParams, out: &mut [T]) {
    let (w, (rows, cols)) = (raw.width(), p.tile);
    for_each_row(out, w, |y, row| {
        let cells = (y % rows) * cols..(y % rows + 1) * cols;
        let (mut black, mut scale) = (vec![0.0f32; w], vec![0.0f32; w]);
        let tile_row = p.black[cells.clone()].iter().zip(&p.scale[cells]).cycle();
        for ((b, s), (&tb, &ts)) in black.iter_mut().zip(scale.iter_mut()).zip(tile_row) {
            // Factors in the type's full scale, so one clamp bounds the result.
            (*b, *s) = (tb, ts * T::FULL_SCALE);
        }
        let mut lin = vec![0.0f32; w];
        for (((l, &v), b), s) in lin.iter_mut().zip(raw.row(y)).zip(&black).zip(&scale) {
            *l = ((f32::from(v) - b) * s).clamp(0.0, T::FULL_SCALE);
        }
        T::from_f32_row(row, &lin);
    });
}

/// The tone curve into samples of `U`: tabulated for integer outputs (one
/// entry per 16-bit step of the linear value, exact to the output's
/// resolution, holding the finished sample so that no `powf` and no second
/// conversion runs per sample), evaluated directly for float outputs.
enum Curve<U> {
    Exact(Tone),
    Table(Vec<U>),
}

/// Steps of the tone table over [0, 1]: one per 16-bit code value.
const TABLE_STEPS: usize = 65535;

impl<U: Sample> Curve<U> {
    fn new(tone: Tone) -> Self {
        if U::FULL_SCALE == 1.0 {
            Curve::Exact(tone)
        } else {
            Curve::Table(
                (0..=TABLE_STEPS)
                    .map(|i| U::from_f32(tone.apply(i as f32 / TABLE_STEPS as f32) * U::FULL_SCALE))
                    .collect(),
            )
        }
    }

    /// Colour matrix, highlight clip and tone curve over a row of linear
    /// RGB `px` (overwritten), into `out`. The matrix loop has no table
    /// lookup in it, so it vectorises; the lookups follow on their own.
    fn finish_row(&self, px: &mut [f32], m: &[f32; 9], out: &mut [U]) {
        // Table positions for integer outputs, linear values for floats.
        let span = match self {
            Curve::Exact(_) => 1.0,
            Curve::Table(_) => TABLE_STEPS as f32,
        };
        for p in px.chunks_exact_mut(3) {
            let (r, g, b) = (p[0], p[1], p[2]);
            for (i, o) in p.iter_mut().enumerate() {
                let v = m[3 * i] * r + m[3 * i + 1] * g + m[3 * i + 2] * b;
                *o = v.clamp(0.0, 1.0) * span;
            }
        }
        match self {
            Curve::Exact(t) => {
                for (o, &v) in out.iter_mut().zip(px.iter()) {
                    *o = U::from_f32(t.apply(v));
                }
            }
            // Positions are in [0, TABLE_STEPS], so the rounded index is in
            // the table; the `min` lets the compiler drop the bounds check.
            Curve::Table(t) => {
                for (o, &v) in out.iter_mut().zip(px.iter()) {
                    *o = t[((v + 0.5) as usize).min(TABLE_STEPS)];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(black: f32, scale: f32, tone: Tone) -> DevelopParams {
        DevelopParams {
            tile: (2, 2),
            black: vec![black; 4],
            scale: vec![scale; 4],
            matrix: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            tone,
            method: Method::Bilinear,
        }
    }

    #[test]
    fn flat_grey_raw_develops_to_its_scaled_value() {
        // (1064 - 64) / 2000 = 0.5 -> 32768 in 16-bit linear (0.5 * 65535 rounded).
        let raw = vec![1064u16; 8 * 6];
        let mut out = vec![0u16; 8 * 6 * 3];
        let p = params(64.0, 1.0 / 2000.0, Tone::Linear);
        let pat = CfaPattern::from_name("RGGB").unwrap();
        develop_in_place(
            ImageView::contiguous(&raw, 8, 6, 1).unwrap(),
            &pat,
            &p,
            &mut out,
        )
        .unwrap();
        assert!(
            out.iter().all(|&v| v.abs_diff(32768) <= 1),
            "{:?}",
            &out[..6]
        );
    }

    #[test]
    fn srgb_tone_maps_half_to_its_standard_code() {
        // sRGB(0.5) = 1.055 * 0.5^(1/2.4) - 0.055 = 0.7354 -> 188 of 255.
        let raw = vec![500u16; 4 * 4];
        let mut out = vec![0u8; 4 * 4 * 3];
        let p = params(0.0, 1.0 / 1000.0, Tone::Srgb);
        let pat = CfaPattern::from_name("GBRG").unwrap();
        develop::<u16, u8>(
            ImageView::contiguous(&raw, 4, 4, 1).unwrap(),
            &pat,
            &p,
            &mut out,
        )
        .unwrap();
        assert!(out.iter().all(|&v| v == 188), "{:?}", &out[..3]);
    }

    #[test]
    fn per_cell_scale_and_matrix_reach_the_right_channels() {
        // Red sites read 100, others 200; red scaled x2 makes a flat 0.5 grey
        // once the matrix swaps nothing; then a matrix that copies R into B.
        let pat = CfaPattern::from_name("BGGR").unwrap();
        let raw: Vec<u16> = (0..16)
            .map(|i| {
                if pat.color_at(i / 4, i % 4) == 0 {
                    100
                } else {
                    200
                }
            })
            .collect();
        let mut p = params(0.0, 1.0 / 400.0, Tone::Linear);
        p.scale[3] = 2.0 / 400.0; // BGGR: red is cell (1, 1)
        p.matrix = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.5, 0.0, 0.0];
        let mut out = vec![0.0f32; 16 * 3];
        develop_in_place(
            ImageView::contiguous(&raw, 4, 4, 1).unwrap(),
            &pat,
            &p,
            &mut out,
        )
        .unwrap();
        for px in out.chunks(3) {
            assert!((px[0] - 0.5).abs() < 1e-6 && (px[1] - 0.5).abs() < 1e-6);
            assert!((px[2] - 0.25).abs() < 1e-6, "{px:?}");
        }
    }

    #[test]
    fn highlights_clip_at_white_before_and_after_the_matrix() {
        let raw = vec![4095u16; 4 * 4];
        let mut p = params(0.0, 2.0 / 4095.0, Tone::Linear);
        p.matrix = [1.5, -0.25, -0.25, -0.25, 1.5, -0.25, -0.25, -0.25, 1.5];
        let mut out = vec![0.0f32; 16 * 3];
        let pat = CfaPattern::from_name("RGGB").unwrap();
        develop::<f32, f32>(
            ImageView::contiguous(&raw, 4, 4, 1).unwrap(),
            &pat,
            &p,
            &mut out,
        )
        .unwrap();
        assert!(out.iter().all(|&v| v == 1.0));
    }

    #[test]
    fn in_place_and_separate_buffers_give_identical_bytes() {
        let raw: Vec<u16> = (0..24 * 18).map(|i| ((i * 7919) % 4096) as u16).collect();
        let view = ImageView::contiguous(&raw, 24, 18, 1).unwrap();
        let pat = CfaPattern::from_name("GRBG").unwrap();
        let mut p = params(100.0, 1.0 / 3000.0, Tone::Srgb);
        p.method = Method::HamiltonAdams;
        let (mut a, mut b) = (vec![0u16; 24 * 18 * 3], vec![0u16; 24 * 18 * 3]);
        develop::<u16, u16>(view, &pat, &p, &mut a).unwrap();
        develop_in_place(view, &pat, &p, &mut b).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn a_black_tile_longer_than_the_cfa_period_repeats_with_its_own_period() {
        // A 4x2 black pattern on a 2x2 Bayer tile: rows 0-1 of every four
        // lose 100, rows 2-3 lose nothing; 600 - 100 = 500 -> 0.5, 600 -> 0.6.
        let (w, h) = (6, 8);
        let raw = vec![600u16; w * h];
        let mut p = params(0.0, 1.0 / 1000.0, Tone::Linear);
        p.tile = (4, 2);
        p.black = vec![100.0, 100.0, 100.0, 100.0, 0.0, 0.0, 0.0, 0.0];
        p.scale = vec![1.0 / 1000.0; 8];
        let pat = CfaPattern::from_name("RGGB").unwrap();
        let mut mosaic = vec![0.0f32; w * h];
        p.check(&pat).unwrap();
        prepare(
            ImageView::contiguous(&raw, w, h, 1).unwrap(),
            &p,
            &mut mosaic,
        );
        for (y, row) in mosaic.chunks(w).enumerate() {
            let want = if y % 4 < 2 { 0.5 } else { 0.6 };
            assert!(row.iter().all(|&v| (v - want).abs() < 1e-6), "{y}: {row:?}");
        }
        p.tile = (3, 2);
        let err = p.check(&pat).unwrap_err().to_string();
        assert!(err.contains("multiple of the 2x2"), "{err}");
    }

    #[test]
    fn bad_parameters_are_refused() {
        let raw = vec![0u16; 16];
        let pat = CfaPattern::from_name("RGGB").unwrap();
        let view = ImageView::contiguous(&raw, 4, 4, 1).unwrap();
        let mut out = vec![0u8; 48];
        let run = |p: &DevelopParams, out: &mut [u8]| develop::<u16, u8>(view, &pat, p, out);
        let mut p = params(0.0, 1.0, Tone::Linear);
        p.scale.pop();
        assert!(matches!(run(&p, &mut out), Err(CoreError::Shape(_))));
        let mut p = params(0.0, 1.0, Tone::Linear);
        p.matrix[4] = f32::NAN;
        let err = run(&p, &mut out).unwrap_err().to_string();
        assert!(err.contains("matrix"), "{err}");
        assert!(run(&params(0.0, -1.0, Tone::Linear), &mut out).is_err());
        assert!(run(&params(0.0, 1.0, Tone::Linear), &mut out[..47]).is_err());
        let mut f = vec![0.0f32; 47];
        assert!(develop_in_place(view, &pat, &params(0.0, 1.0, Tone::Linear), &mut f).is_err());
        assert!(Tone::from_name("gamma")
            .unwrap_err()
            .to_string()
            .contains("srgb"));
    }
}

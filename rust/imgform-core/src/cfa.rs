//! Colour filter arrays: the pattern type, mosaicing, channel masks and a
//! sensor simulator.
//!
//! A pattern is the periodic tile of channel indices (0 = R, 1 = G, 2 = B)
//! that starts at pixel (0, 0) of the array it describes (CONVENTIONS.md).
//! Bayer tiles are 2x2; the Fujifilm X-Trans tile is 6x6.

use crate::error::{CoreError, Result};
use crate::image::{ImageView, Sample};
use crate::invalid;
use crate::parallel::for_each_row;
use crate::random::SplitMix64;

/// Channel index of red in a pattern (and in an RGB image).
pub const RED: u8 = 0;
/// Channel index of green.
pub const GREEN: u8 = 1;
/// Channel index of blue.
pub const BLUE: u8 = 2;

/// The four Bayer phases, named by their 2x2 tile read row by row.
pub const BAYER_NAMES: [&str; 4] = ["RGGB", "BGGR", "GRBG", "GBRG"];

/// The X-Trans tile as Fujifilm draws it: two kinds of 3x3 blocks (green
/// corners and centre; red and blue on the edges, swapped between the kinds)
/// laid out as a checkerboard. Every row and column holds all three colours.
const XTRANS: [[u8; 6]; 6] = [
    [1, 2, 1, 1, 0, 1],
    [0, 1, 0, 2, 1, 2],
    [1, 2, 1, 1, 0, 1],
    [1, 0, 1, 1, 2, 1],
    [2, 1, 2, 0, 1, 0],
    [1, 0, 1, 1, 2, 1],
];

/// A colour filter array tile: Bayer (2x2) or X-Trans (6x6).
///
/// Only valid layouts can be built, so kernels can rely on the structure:
/// a Bayer tile has its two greens on a diagonal, an X-Trans tile is a
/// shifted, flipped or transposed copy of the Fujifilm layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CfaPattern {
    period: usize,
    cells: [u8; 36],
}

impl CfaPattern {
    /// Parses "RGGB", "BGGR", "GRBG", "GBRG" or "XTRANS" (case-insensitive).
    ///
    /// # Errors
    /// [`CoreError::InvalidArgument`] naming the string and the accepted names.
    pub fn from_name(name: &str) -> Result<Self> {
        let upper = name.trim().to_ascii_uppercase();
        if upper == "XTRANS" || upper == "X-TRANS" {
            return Ok(Self::xtrans());
        }
        if upper.len() == 4 && BAYER_NAMES.contains(&upper.as_str()) {
            let cells: Vec<i64> = upper
                .bytes()
                .map(|b| match b {
                    b'R' => 0,
                    b'G' => 1,
                    _ => 2,
                })
                .collect();
            return Self::from_cells(&cells, 2, 2);
        }
        Err(invalid!(
            "unknown CFA pattern {name:?}; accepted: \"RGGB\", \"BGGR\", \"GRBG\", \"GBRG\", \"XTRANS\", or a (2, 2) / (6, 6) array of channel indices 0=R, 1=G, 2=B"
        ))
    }

    /// The Fujifilm X-Trans tile in its usual drawing.
    pub fn xtrans() -> Self {
        let mut cells = [0u8; 36];
        for (y, row) in XTRANS.iter().enumerate() {
            cells[6 * y..6 * y + 6].copy_from_slice(row);
        }
        Self { period: 6, cells }
    }

    /// Builds a pattern from a `rows x cols` tile of channel indices, row by
    /// row. A 6x6 tile that repeats a Bayer 2x2 tile is reduced to it.
    ///
    /// # Errors
    /// [`CoreError::Shape`] for a tile that is not 2x2 or 6x6;
    /// [`CoreError::InvalidArgument`] for indices outside 0..=2 or a layout
    /// that is neither a Bayer phase nor an X-Trans tile.
    pub fn from_cells(cells: &[i64], rows: usize, cols: usize) -> Result<Self> {
        if rows != cols || !(rows == 2 || rows == 6) || cells.len() != rows * cols {
            return Err(CoreError::Shape(format!(
                "a CFA pattern array must have shape (2, 2) or (6, 6), got ({rows}, {cols})"
            )));
        }
        if let Some(bad) = cells.iter().find(|&&c| !(0..=2).contains(&c)) {
            return Err(invalid!(
                "a CFA pattern array holds channel indices 0=R, 1=G, 2=B, got {bad}"
            ));
        }
        let mut tile = [0u8; 36];
        for (t, &c) in tile.iter_mut().zip(cells) {
            *t = c as u8;
        }
        let pattern = Self {
            period: rows,
            cells: tile,
        };
        if rows == 2 {
            let count = |c: u8| tile[..4].iter().filter(|&&v| v == c).count();
            // Two greens on a diagonal, red and blue on the other one.
            let diagonal =
                (tile[0] == GREEN && tile[3] == GREEN) || (tile[1] == GREEN && tile[2] == GREEN);
            if count(RED) == 1 && count(BLUE) == 1 && diagonal {
                return Ok(pattern);
            }
            return Err(invalid!(
                "a Bayer pattern needs one R, one B and two G with the greens on a diagonal, got {:?}; accepted: RGGB [[0, 1], [1, 2]], BGGR, GRBG, GBRG",
                [[tile[0], tile[1]], [tile[2], tile[3]]]
            ));
        }
        if let Some(bayer) = pattern.as_repeated_bayer() {
            return Ok(bayer);
        }
        if xtrans_variants().any(|v| v == pattern) {
            return Ok(pattern);
        }
        Err(invalid!(
            "a (6, 6) CFA pattern must be an X-Trans tile (a shift, flip or transpose of Fujifilm's layout) or a repeated Bayer tile, got rows {:?}",
            tile.chunks(6).collect::<Vec<_>>()
        ))
    }

    /// The 2x2 Bayer tile a 6x6 tile repeats, if it does.
    fn as_repeated_bayer(&self) -> Option<Self> {
        let mut two = [0i64; 4];
        for (i, t) in two.iter_mut().enumerate() {
            *t = i64::from(self.cells[6 * (i / 2) + i % 2]);
        }
        let bayer = Self::from_cells(&two, 2, 2).ok()?;
        let repeats = (0..6).all(|y| (0..6).all(|x| bayer.color_at(y, x) == self.color_at(y, x)));
        repeats.then_some(bayer)
    }

    /// Tile size: 2 for Bayer, 6 for X-Trans.
    pub fn period(&self) -> usize {
        self.period
    }

    /// The tile's channel indices row by row (`period * period` values).
    pub fn cells(&self) -> &[u8] {
        &self.cells[..self.period * self.period]
    }

    /// The channels of row `y`'s first `period` pixels: cycling through
    /// them walks the row without the two divisions of [`Self::color_at`]
    /// per pixel.
    pub fn row(&self, y: usize) -> &[u8] {
        let p = self.period;
        &self.cells[(y % p) * p..][..p]
    }

    /// Channel index (0 = R, 1 = G, 2 = B) of pixel `(y, x)`.
    #[inline(always)]
    pub fn color_at(&self, y: usize, x: usize) -> u8 {
        let p = self.period;
        self.cells[(y % p) * p + x % p]
    }

    /// Whether this is one of the four Bayer phases.
    pub fn is_bayer(&self) -> bool {
        self.period == 2
    }

    /// Position `(row, col)` of red inside a Bayer tile; `None` for X-Trans.
    /// Demosaicers use it as their phase offset: blue sits at the opposite
    /// corner and green on the other diagonal.
    pub fn bayer_red(&self) -> Option<(usize, usize)> {
        if !self.is_bayer() {
            return None;
        }
        let i = self.cells[..4].iter().position(|&c| c == RED)?;
        Some((i / 2, i % 2))
    }

    /// The name of the pattern: a Bayer phase, "XTRANS" for the canonical
    /// X-Trans tile, `None` for other X-Trans shifts.
    pub fn name(&self) -> Option<&'static str> {
        if *self == Self::xtrans() {
            return Some("XTRANS");
        }
        let (ry, rx) = self.bayer_red()?;
        Some(match (ry, rx) {
            (0, 0) => "RGGB",
            (1, 1) => "BGGR",
            (0, 1) => "GRBG",
            _ => "GBRG",
        })
    }

    /// The pattern of the array cropped to start at `(dy, dx)` of this one:
    /// cropping an odd number of rows or columns changes a Bayer phase.
    /// Negative offsets (padding) are allowed.
    pub fn shifted(&self, dy: isize, dx: isize) -> Self {
        let p = self.period;
        let mut cells = [0u8; 36];
        for y in 0..p {
            for x in 0..p {
                let sy = (y as isize + dy).rem_euclid(p as isize) as usize;
                let sx = (x as isize + dx).rem_euclid(p as isize) as usize;
                cells[y * p + x] = self.cells[sy * p + sx];
            }
        }
        Self { period: p, cells }
    }

    /// This pattern with its rows (`vertical`) or columns reversed, for a
    /// tile of `period` size; used to enumerate the X-Trans variants.
    fn flipped(&self, vertical: bool) -> Self {
        let p = self.period;
        let mut cells = [0u8; 36];
        for y in 0..p {
            for x in 0..p {
                let (sy, sx) = if vertical {
                    (p - 1 - y, x)
                } else {
                    (y, p - 1 - x)
                };
                cells[y * p + x] = self.cells[sy * p + sx];
            }
        }
        Self { period: p, cells }
    }

    fn transposed(&self) -> Self {
        let p = self.period;
        let mut cells = [0u8; 36];
        for y in 0..p {
            for x in 0..p {
                cells[y * p + x] = self.cells[x * p + y];
            }
        }
        Self { period: p, cells }
    }
}

/// Every layout an X-Trans sensor can present: the 36 shifts of the tile and
/// of its flips and transpose (cameras read out from different corners).
fn xtrans_variants() -> impl Iterator<Item = CfaPattern> {
    let base = CfaPattern::xtrans();
    let t = base.transposed();
    [base, base.flipped(true), base.flipped(false), t]
        .into_iter()
        .flat_map(|v| (0..36).map(move |s| v.shifted(s / 6, s % 6)))
}

/// Checks that `out` holds exactly `expected` elements.
pub(crate) fn check_out_len(out_len: usize, expected: usize, what: &str) -> Result<()> {
    if out_len == expected {
        Ok(())
    } else {
        Err(CoreError::Shape(format!(
            "{what} output buffer holds {out_len} elements, expected {expected}"
        )))
    }
}

/// Samples an RGB image through the pattern: `out[y, x] = rgb[y, x, c(y, x)]`.
///
/// # Errors
/// [`CoreError::Shape`] when `rgb` does not have 3 channels or `out` is not
/// `height * width` long.
pub fn mosaic<T: Sample>(rgb: ImageView<'_, T>, pattern: &CfaPattern, out: &mut [T]) -> Result<()> {
    if rgb.channels() != 3 {
        return Err(CoreError::Shape(format!(
            "mosaic needs an RGB image of shape (H, W, 3), got {} channels",
            rgb.channels()
        )));
    }
    let w = rgb.width();
    check_out_len(out.len(), w * rgb.height(), "mosaic")?;
    for_each_row(out, w, |y, row| {
        let src = rgb.row(y);
        for (x, (o, px)) in row.iter_mut().zip(src.chunks_exact(3)).enumerate() {
            *o = px[usize::from(pattern.color_at(y, x))];
        }
    });
    Ok(())
}

/// Fills `out`, an `(height, width, 3)` boolean buffer, with `true` where
/// the pattern samples each channel.
///
/// # Errors
/// [`CoreError::Shape`] when a dimension is zero or `out` has the wrong length.
pub fn channel_masks(
    width: usize,
    height: usize,
    pattern: &CfaPattern,
    out: &mut [bool],
) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(CoreError::Shape(format!(
            "channel masks need a non-empty shape, got ({height}, {width})"
        )));
    }
    check_out_len(out.len(), 3 * width * height, "channel_masks")?;
    for_each_row(out, 3 * width, |y, row| {
        for (x, px) in row.chunks_exact_mut(3).enumerate() {
            let c = usize::from(pattern.color_at(y, x));
            for (k, m) in px.iter_mut().enumerate() {
                *m = k == c;
            }
        }
    });
    Ok(())
}

/// Parameters of [`simulate_sensor`], in electrons and digital numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorParams {
    /// Electrons collected at the input's full scale (1.0, 255 or 65535).
    pub full_well: f64,
    /// Standard deviation of the Gaussian read noise, in electrons.
    pub read_noise: f64,
    /// ADC resolution; the output spans `0 ..= 2^bit_depth - 1`.
    pub bit_depth: u32,
    /// Offset added to every pixel, in digital numbers.
    pub black_level: u32,
    /// Seed of the noise; equal seeds give equal raws.
    pub seed: u64,
}

impl SensorParams {
    fn validate(&self) -> Result<()> {
        crate::error::positive("full_well", self.full_well)?;
        if !(self.read_noise.is_finite() && self.read_noise >= 0.0) {
            return Err(invalid!(
                "read_noise must be a finite number >= 0, got {}",
                self.read_noise
            ));
        }
        if !(1..=16).contains(&self.bit_depth) {
            return Err(invalid!(
                "bit_depth must be between 1 and 16, got {}",
                self.bit_depth
            ));
        }
        let white = (1u32 << self.bit_depth) - 1;
        if self.black_level >= white {
            return Err(invalid!(
                "black_level must be below the white level {white} of {} bits, got {}",
                self.bit_depth,
                self.black_level
            ));
        }
        Ok(())
    }
}

/// Simulates a raw capture of a linear RGB image: mosaic through `pattern`,
/// Poisson photon noise, Gaussian read noise, an ADC that maps `full_well`
/// electrons to the white level, rounding, the black level, and clipping to
/// `0 ..= 2^bit_depth - 1`. Input values are fractions of full scale (floats
/// nominally in [0, 1]); negative values count as no light.
///
/// The noise of pixel `(y, x)` comes from a generator seeded by
/// `(seed, y, x)` alone, so the raw is the same for any thread count.
///
/// # Errors
/// [`CoreError::InvalidArgument`] for a bad parameter (named);
/// [`CoreError::Shape`] for a non-RGB input or a wrong output length.
pub fn simulate_sensor<T: Sample>(
    rgb: ImageView<'_, T>,
    pattern: &CfaPattern,
    params: &SensorParams,
    out: &mut [u16],
) -> Result<()> {
    params.validate()?;
    if rgb.channels() != 3 {
        return Err(CoreError::Shape(format!(
            "simulate_sensor needs an RGB image of shape (H, W, 3), got {} channels",
            rgb.channels()
        )));
    }
    let w = rgb.width();
    check_out_len(out.len(), w * rgb.height(), "simulate_sensor")?;
    // NaN became no light and +inf 0 DN: refused, as the spectral sensor's
    // captures refuse them (a negative is no light, as documented).
    if let Some((y, i)) = rgb.find_first(|v| !v.is_finite()) {
        return Err(invalid!(
            "the image must hold finite values, got {:?} at row {y}, column {}, channel {}",
            rgb.row(y)[i],
            i / 3,
            i % 3
        ));
    }
    let white = f64::from((1u32 << params.bit_depth) - 1);
    let black = f64::from(params.black_level);
    let gain = (white - black) / params.full_well;
    for_each_row(out, w, |y, row| {
        let src = rgb.row(y);
        for (x, (o, px)) in row.iter_mut().zip(src.chunks_exact(3)).enumerate() {
            let v = f64::from(px[usize::from(pattern.color_at(y, x))].to_f32());
            let electrons_mean = (v / f64::from(T::FULL_SCALE)).max(0.0) * params.full_well;
            let mut rng = SplitMix64::for_site(params.seed, y, x);
            let electrons = rng.poisson(electrons_mean) + params.read_noise * rng.normal();
            let dn = (black + gain * electrons).round().clamp(0.0, white);
            *o = dn as u16;
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_to_their_phase_and_back() {
        for name in BAYER_NAMES {
            let p = CfaPattern::from_name(name).unwrap();
            assert_eq!(p.name(), Some(name));
            let s: String = p
                .cells()
                .iter()
                .map(|&c| ['R', 'G', 'B'][usize::from(c)])
                .collect();
            assert_eq!(s, name);
        }
        assert_eq!(CfaPattern::from_name("xtrans").unwrap().period(), 6);
        let err = CfaPattern::from_name("RGBG").unwrap_err().to_string();
        assert!(
            err.contains("\"RGBG\"") && err.contains("accepted"),
            "{err}"
        );
    }

    #[test]
    fn bayer_arrays_must_put_the_greens_on_a_diagonal() {
        assert_eq!(
            CfaPattern::from_cells(&[1, 2, 0, 1], 2, 2).unwrap().name(),
            Some("GBRG")
        );
        // R G / B G: greens in one column.
        assert!(CfaPattern::from_cells(&[0, 1, 2, 1], 2, 2).is_err());
        assert!(CfaPattern::from_cells(&[0, 0, 2, 1], 2, 2).is_err());
        assert!(CfaPattern::from_cells(&[0, 1, 1, 3], 2, 2).is_err());
        assert!(CfaPattern::from_cells(&[0, 1, 1], 3, 1).is_err());
    }

    #[test]
    fn six_by_six_tiles_are_xtrans_variants_or_repeated_bayer() {
        let x = CfaPattern::xtrans();
        let cells: Vec<i64> = x.shifted(1, 4).cells().iter().map(|&c| c.into()).collect();
        let p = CfaPattern::from_cells(&cells, 6, 6).unwrap();
        assert_eq!(p.name(), None);
        assert_eq!(p, x.shifted(1, 4));
        let bayer: Vec<i64> = (0..36)
            .map(|i| [2, 1, 1, 0][(i / 6 % 2) * 2 + i % 2])
            .collect();
        assert_eq!(
            CfaPattern::from_cells(&bayer, 6, 6).unwrap().name(),
            Some("BGGR")
        );
        let mut broken = cells.clone();
        broken.swap(0, 1);
        assert!(CfaPattern::from_cells(&broken, 6, 6).is_err());
    }

    #[test]
    fn shifting_by_one_changes_the_bayer_phase() {
        let rggb = CfaPattern::from_name("RGGB").unwrap();
        assert_eq!(rggb.shifted(0, 1).name(), Some("GRBG"));
        assert_eq!(rggb.shifted(1, 0).name(), Some("GBRG"));
        assert_eq!(rggb.shifted(1, 1).name(), Some("BGGR"));
        assert_eq!(rggb.shifted(-3, 2).name(), Some("GBRG"));
        assert_eq!(CfaPattern::xtrans().shifted(6, -12), CfaPattern::xtrans());
    }

    #[test]
    fn mosaic_takes_each_pixels_own_channel() {
        let rgb: Vec<u8> = (0..2 * 3 * 3).map(|v| v as u8).collect();
        let view = ImageView::contiguous(&rgb, 3, 2, 3).unwrap();
        let mut out = vec![0u8; 6];
        mosaic(view, &CfaPattern::from_name("GRBG").unwrap(), &mut out).unwrap();
        // Row 0: G R G -> channels 1, 0, 1; row 1: B G B -> 2, 1, 2.
        assert_eq!(out, vec![1, 3, 7, 11, 13, 17]);
    }

    #[test]
    fn masks_mark_one_channel_per_pixel() {
        let mut out = vec![false; 3 * 4 * 3];
        channel_masks(4, 3, &CfaPattern::from_name("BGGR").unwrap(), &mut out).unwrap();
        assert!(out
            .chunks(3)
            .all(|px| px.iter().filter(|&&m| m).count() == 1));
        // (0, 0) is blue, (1, 1) is red.
        assert!(out[2] && out[3 * 5]);
    }

    #[test]
    fn sensor_refuses_light_that_is_not_a_number() {
        // NaN read as no light, and +inf as 0 DN, a black pixel.
        for bad in [f32::NAN, f32::INFINITY] {
            let mut rgb = vec![0.5f32; 4 * 3 * 3];
            rgb[(2 * 4 + 1) * 3 + 2] = bad;
            let view = ImageView::contiguous(&rgb, 4, 3, 3).unwrap();
            let params = SensorParams {
                full_well: 1000.0,
                read_noise: 0.0,
                bit_depth: 12,
                black_level: 0,
                seed: 0,
            };
            let pattern = CfaPattern::from_name("RGGB").unwrap();
            let e = simulate_sensor(view, &pattern, &params, &mut [0u16; 12])
                .unwrap_err()
                .to_string();
            assert!(e.contains("at row 2, column 1, channel 2"), "{e}");
        }
    }

    #[test]
    fn sensor_noise_has_the_poisson_plus_read_mean_and_variance() {
        let (w, h) = (200, 100);
        let level = 0.25f32;
        let rgb = vec![level; w * h * 3];
        let view = ImageView::contiguous(&rgb, w, h, 3).unwrap();
        let params = SensorParams {
            full_well: 4000.0,
            read_noise: 5.0,
            bit_depth: 16,
            black_level: 100,
            seed: 7,
        };
        let mut out = vec![0u16; w * h];
        simulate_sensor(
            view,
            &CfaPattern::from_name("RGGB").unwrap(),
            &params,
            &mut out,
        )
        .unwrap();
        let gain = (65535.0 - 100.0) / 4000.0;
        let e: Vec<f64> = out.iter().map(|&d| (f64::from(d) - 100.0) / gain).collect();
        let mean = e.iter().sum::<f64>() / e.len() as f64;
        let var = e.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / e.len() as f64;
        assert!((mean - 1000.0).abs() < 1.0, "{mean}");
        // Poisson variance 1000 plus read variance 25, within sampling error.
        assert!((var / 1025.0 - 1.0).abs() < 0.03, "{var}");
        let mut again = vec![0u16; w * h];
        simulate_sensor(
            view,
            &CfaPattern::from_name("RGGB").unwrap(),
            &params,
            &mut again,
        )
        .unwrap();
        assert_eq!(out, again);
    }

    #[test]
    fn bad_sensor_parameters_are_named() {
        let rgb = [0.5f32; 12];
        let view = ImageView::contiguous(&rgb, 2, 2, 3).unwrap();
        let p = CfaPattern::from_name("RGGB").unwrap();
        let mut out = [0u16; 4];
        let base = SensorParams {
            full_well: 100.0,
            read_noise: 1.0,
            bit_depth: 12,
            black_level: 64,
            seed: 0,
        };
        for (params, word) in [
            (
                SensorParams {
                    full_well: 0.0,
                    ..base
                },
                "full_well",
            ),
            (
                SensorParams {
                    read_noise: -1.0,
                    ..base
                },
                "read_noise",
            ),
            (
                SensorParams {
                    bit_depth: 17,
                    ..base
                },
                "bit_depth",
            ),
            (
                SensorParams {
                    black_level: 4095,
                    ..base
                },
                "black_level",
            ),
        ] {
            let err = simulate_sensor(view, &p, &params, &mut out)
                .unwrap_err()
                .to_string();
            assert!(err.contains(word), "{err}");
        }
    }
}

//! The sensor: mean photo-electron rates in, digital numbers out.
//!
//! For each pixel, with rate `r` (e-/s) and exposure time `t`:
//!
//! 1. the signal `r t` is scaled by the pixel's fixed gain `1 + prnu z1`
//!    (photo-response non-uniformity) and the dark charge `d t` is added,
//!    `d` the dark current at the sensor's temperature (doubling every
//!    `doubling_temperature` kelvin);
//! 2. the collected charge is an exact Poisson variate of that mean (shot
//!    noise of light and dark current alike), clipped at the full well;
//! 3. read-out adds the pixel's fixed offset `dsnu z2` (dark-signal
//!    non-uniformity), its column's fixed offset `column_noise z3` and
//!    Gaussian read noise, all in electrons;
//! 4. the amplifier and ADC map electrons to digital numbers with
//!    `analog_gain / electrons_per_dn`, add the black level, round to the
//!    nearest integer and clip to `0 ..= 2^bit_depth - 1`.
//!
//! `z1, z2` come from a generator seeded by `(pattern_seed, y, x)` and `z3` by
//! `(pattern_seed, column)`, so the fixed patterns are the same in every
//! frame of one sensor; the temporal noise comes from `(seed, y, x)`, so a new
//! seed is a new frame. Either way a frame does not depend on the thread count.
//!
//! The read-out runs a row at a time in vector steps (`random::Lanes` for
//! the normals, `random::PoissonRow` for the shot noise), compiled for AVX2
//! where the CPU has it; every pixel still draws exactly what its own
//! scalar generator would, so the frame is the same on any CPU.

use super::ahead::{Ahead, RowRates};
use super::cfa_rates::{self, colors_from, Responses};
use super::falloff::Falloff;
use super::integrate::{bad_pixel, check_response};
use super::{bands_first_bad, has_avx2_fma, is_valid_sample};
use crate::cfa::{check_out_len, CfaPattern};
use crate::error::{CoreError, Result};
use crate::invalid;
use crate::random::{ziggurat, Lanes, PoissonRow, SplitMix64, Ziggurat, LANES};

/// Rows per parallel task. Each band's first row is read without noise to
/// hide behind ([`Ahead`]), so bands are longer than the library's usual
/// eight rows: 1/32 of the input read on its own, and still over a hundred
/// tasks for a 24 MP frame to balance between the cores.
const ROWS_PER_BAND: usize = 32;

/// Mixed into the pattern seed for the column offsets, so that they are not
/// the row-0 pixel offsets in disguise.
const COLUMN_STREAM: u64 = 0xC01C_0FF5_E7C0_1005;

/// A sensor's parameters. Charges are in electrons, levels in digital
/// numbers (DN), times in seconds, temperatures in degrees Celsius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sensor {
    /// Exposure time, s (> 0).
    pub exposure_time: f64,
    /// Charge at which a photodiode saturates, e- (> 0).
    pub full_well: f64,
    /// Standard deviation of the read noise, e- (>= 0).
    pub read_noise: f64,
    /// Electrons per DN at unity analog gain (the inverse of EMVA's system
    /// gain `K` at base ISO), > 0.
    pub electrons_per_dn: f64,
    /// Analog gain before the ADC (ISO / base ISO), > 0.
    pub analog_gain: f64,
    /// Offset added before clipping, DN; below the white level.
    pub black_level: u32,
    /// ADC resolution, 1..=16 bits.
    pub bit_depth: u32,
    /// Mean dark current at `reference_temperature`, e-/s (>= 0).
    pub dark_current: f64,
    /// Sensor temperature, °C.
    pub temperature: f64,
    /// Temperature at which `dark_current` holds, °C.
    pub reference_temperature: f64,
    /// Warming by this many kelvin doubles the dark current (> 0).
    pub doubling_temperature: f64,
    /// Standard deviation of the fixed per-pixel offset, e- (>= 0).
    pub dsnu: f64,
    /// Standard deviation of the fixed per-pixel gain, relative (0 <= prnu < 1).
    pub prnu: f64,
    /// Standard deviation of the fixed per-column offset, e- (>= 0).
    pub column_noise: f64,
    /// Seed of the temporal noise (a new seed is a new frame).
    pub seed: u64,
    /// Seed of the fixed patterns (a new seed is another sensor of the model).
    pub pattern_seed: u64,
}

fn check_input_len(name: &str, got: usize, expected: usize) -> Result<()> {
    if got == expected {
        Ok(())
    } else {
        Err(CoreError::Shape(format!(
            "{name} must hold {expected} values for the frame, got {got}"
        )))
    }
}

fn non_negative(name: &str, value: f64) -> Result<()> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(invalid!("{name} must be a finite number >= 0, got {value}"))
    }
}

impl Sensor {
    /// Checks every parameter.
    ///
    /// # Errors
    /// [`CoreError::InvalidArgument`] naming the first bad parameter and its
    /// accepted range.
    pub fn validate(&self) -> Result<()> {
        use crate::error::{finite, positive};
        positive("exposure_time", self.exposure_time)?;
        positive("full_well", self.full_well)?;
        non_negative("read_noise", self.read_noise)?;
        positive("electrons_per_dn", self.electrons_per_dn)?;
        positive("analog_gain", self.analog_gain)?;
        non_negative("dark_current", self.dark_current)?;
        finite("temperature", self.temperature)?;
        finite("reference_temperature", self.reference_temperature)?;
        positive("doubling_temperature", self.doubling_temperature)?;
        non_negative("dsnu", self.dsnu)?;
        non_negative("column_noise", self.column_noise)?;
        if !(self.prnu.is_finite() && (0.0..1.0).contains(&self.prnu)) {
            return Err(invalid!(
                "prnu must be a relative standard deviation in [0, 1), got {}",
                self.prnu
            ));
        }
        if !(1..=16).contains(&self.bit_depth) {
            return Err(invalid!(
                "bit_depth must be between 1 and 16, got {}",
                self.bit_depth
            ));
        }
        if self.black_level >= self.white_level() {
            return Err(invalid!(
                "black_level must be below the white level {} of {} bits, got {}",
                self.white_level(),
                self.bit_depth,
                self.black_level
            ));
        }
        if !self.dark_rate().is_finite() {
            return Err(invalid!(
                "the dark current at {} °C overflows: {} e-/s doubling every {} K from {} °C",
                self.temperature,
                self.dark_current,
                self.doubling_temperature,
                self.reference_temperature
            ));
        }
        Ok(())
    }

    /// The largest output value, `2^bit_depth - 1`.
    pub fn white_level(&self) -> u32 {
        (1u32 << self.bit_depth.min(16)) - 1
    }

    /// Digital numbers per electron: `analog_gain / electrons_per_dn` (EMVA
    /// 1288's system gain `K`).
    pub fn dn_per_electron(&self) -> f64 {
        self.analog_gain / self.electrons_per_dn
    }

    /// The mean dark current at the sensor's temperature, e-/s.
    pub fn dark_rate(&self) -> f64 {
        let warming = self.temperature - self.reference_temperature;
        self.dark_current * (warming / self.doubling_temperature).exp2()
    }

    /// The fixed offset of every column, e-.
    fn column_offsets(&self, width: usize) -> Vec<f64> {
        if self.column_noise == 0.0 {
            return vec![0.0; width];
        }
        (0..width)
            .map(|x| {
                let mut g = SplitMix64::for_site(self.pattern_seed ^ COLUMN_STREAM, 0, x);
                self.column_noise * g.normal()
            })
            .collect()
    }

    /// Reads a `height x width` frame from `input`, whose rows are
    /// `input.len() / height` values each (the caller checked the length).
    /// `rates` (a [`RowRates`] kernel) turns a row's input into its mean
    /// rates (e-/s); the row is dimmed by `falloff`, if any, and the sensor
    /// reads it. Returns the first pixel whose input `rates` found bad, for
    /// the caller to name in its own terms.
    ///
    /// Working a row at a time keeps the input's loop (a dot product per
    /// pixel) apart from the noise's, so each stays simple enough to
    /// optimise, while a row of rates stays in cache between the two. The
    /// next row is integrated while the current one's noise is drawn
    /// ([`Ahead`]), so the memory bus is busy while the core computes; only
    /// the first row of a band of [`ROWS_PER_BAND`] is read on its own.
    fn read_frame<F: RowRates>(
        &self,
        (width, height): (usize, usize),
        falloff: Option<&Falloff>,
        input: &[f32],
        out: &mut [u16],
        rates: F,
    ) -> Result<Option<usize>> {
        self.validate()?;
        check_out_len(out.len(), width * height, "the sensor")?;
        let row_len = input.len() / height.max(1);
        let columns = self.column_offsets(width);
        let readout = Readout::new(self);
        let bad = bands_first_bad(out, width, ROWS_PER_BAND, |y0, rows| {
            let mut scratch = RowScratch::new(width);
            let mut next = vec![0.0; width];
            // The band's input; its last row integrates nothing ahead (the
            // next band may be another thread's).
            let band = &input[y0 * row_len..][..rows.len() / width * row_len];
            let mut src_rows = band.chunks_exact(row_len);
            let mut first_bad =
                Ahead::new(y0, src_rows.next(), &mut scratch.rates, &rates).finish();
            for (dy, row) in rows.chunks_exact_mut(width).enumerate() {
                let y = y0 + dy;
                if let Some(f) = falloff {
                    f.apply_row(y, &mut scratch.rates);
                }
                let mut ahead = Ahead::new(y + 1, src_rows.next(), &mut next, &rates);
                let keys = RowKeys::new(self, y, &columns);
                readout.row(keys, row, &mut scratch, |done, total| {
                    ahead.upto(done, total)
                });
                first_bad = first_bad.or(ahead.finish());
                std::mem::swap(&mut scratch.rates, &mut next);
            }
            first_bad
        });
        Ok(bad)
    }

    /// A frame of mean photo-electron rates `rates` `(height, width)`, e-/s:
    /// flat fields, or a scene already integrated per pixel.
    ///
    /// # Errors
    /// A bad parameter, mismatched lengths, or a negative or non-finite rate.
    pub fn capture_rates(
        &self,
        rates: &[f32],
        width: usize,
        height: usize,
        out: &mut [u16],
    ) -> Result<()> {
        check_input_len("rates", rates.len(), width * height)?;
        let bad = self.read_frame((width, height), None, rates, out, |_, _, src, row| {
            for (r, &v) in row.iter_mut().zip(src) {
                *r = f64::from(v);
            }
            src.iter().position(|&v| !is_valid_sample(v))
        })?;
        bad.map_or(Ok(()), |p| {
            Err(invalid!(
                "rates must be finite and >= 0 (e-/s); pixel (row {}, column {}) is {}",
                p / width,
                p % width,
                rates[p]
            ))
        })
    }

    /// A raw capture of a spectral image `(height, width, grid_len)` through
    /// a colour filter array: pixel `(y, x)` integrates its spectrum against
    /// `response[c]`, `c` its filter's channel (0 = R, 1 = G, 2 = B), the
    /// response in e-/s per unit of the image, dimmed by `falloff` if any.
    /// The dot products are in f32 (see `cfa_rates` for their error: under
    /// 1e-6 relative).
    ///
    /// # Errors
    /// A bad parameter or response, mismatched lengths, or a pixel with a
    /// negative or non-finite sample.
    // The slice-kernel convention (a buffer, its dimensions, its output)
    // plus the response and the pattern: grouping them into a struct for
    // one function would only move the list.
    #[allow(clippy::too_many_arguments)]
    pub fn capture_spectral(
        &self,
        spectra: &[f32],
        width: usize,
        height: usize,
        grid_len: usize,
        response: &[f64],
        pattern: &CfaPattern,
        falloff: Option<&Falloff>,
        out: &mut [u16],
    ) -> Result<()> {
        check_response(response, 3, grid_len)?;
        if grid_len == 0 || spectra.len() != width * height * grid_len {
            return Err(CoreError::Shape(format!(
                "a {height} x {width} image of {grid_len} wavelengths needs {} samples, got {}",
                width * height * grid_len,
                spectra.len()
            )));
        }
        let responses = Responses::new(response, grid_len);
        let bad = self.read_frame((width, height), falloff, spectra, out, |y, x0, src, row| {
            cfa_rates::row(src, (pattern.row(y), x0), &responses, row)
        })?;
        bad.map_or(Ok(()), |p| Err(bad_pixel("spectra", p, width)))
    }

    /// A raw capture of an RGB image `(height, width, 3)` whose pixels stand
    /// for spectra linear in RGB (a three-function basis): channel `c` of
    /// the camera then sees `matrix[c] · rgb`, with `matrix` row-major 3x3
    /// in e-/s per unit of RGB, dimmed by `falloff` if any. Negative
    /// components are out of the basis' gamut and count as 0.
    ///
    /// # Errors
    /// A bad parameter, a non-finite or negative matrix entry, mismatched
    /// lengths, or a non-finite pixel.
    // The slice-kernel convention plus the matrix, pattern and falloff (see
    // `capture_spectral`).
    #[allow(clippy::too_many_arguments)]
    pub fn capture_rgb(
        &self,
        rgb: &[f32],
        width: usize,
        height: usize,
        matrix: &[f64; 9],
        pattern: &CfaPattern,
        falloff: Option<&Falloff>,
        out: &mut [u16],
    ) -> Result<()> {
        if let Some(i) = matrix.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
            // check_response would name a spectral response and a wavelength.
            return Err(invalid!(
                "the RGB response matrix must be finite and >= 0 (rates of light), entry \
                 ({}, {}) is {}",
                i / 3,
                i % 3,
                matrix[i]
            ));
        }
        check_input_len("rgb", rgb.len(), 3 * width * height)?;
        let bad = self.read_frame((width, height), falloff, rgb, out, |y, x0, src, row| {
            let mut first_bad = None;
            let pixels = src.chunks_exact(3).zip(colors_from(pattern.row(y), x0));
            for (x, (r, (px, &c))) in row.iter_mut().zip(pixels).enumerate() {
                let m = &matrix[3 * usize::from(c)..][..3];
                let [red, green, blue] = [px[0], px[1], px[2]].map(|v| f64::from(v.max(0.0)));
                *r = m[0] * red + m[1] * green + m[2] * blue;
                if !px.iter().fold(true, |ok, v| ok & v.is_finite()) {
                    first_bad = first_bad.or(Some(x));
                }
            }
            first_bad
        })?;
        bad.map_or(Ok(()), |p| {
            Err(invalid!(
                "rgb must be finite in every channel; pixel (row {}, column {}) is {:?}",
                p / width,
                p % width,
                &rgb[3 * p..3 * p + 3]
            ))
        })
    }
}

/// The per-frame constants of the read-out chain, derived once so that the
/// per-pixel code only multiplies and adds.
struct Readout {
    exposure_time: f64,
    dark_electrons: f64,
    full_well: f64,
    /// A mean so far above the full well that a Poisson count of it falls
    /// below the full well with a probability under e^-500 (Chernoff's
    /// bound `exp(-t² / 2λ)`): drawing from it instead of any larger mean
    /// changes no reading. `f64::min` also maps a
    /// NaN mean (bad input, which the caller reports) to it, so no input
    /// can send the sampler into an endless rejection loop.
    saturating_mean: f64,
    read_noise: f64,
    prnu: f64,
    dsnu: f64,
    black: f64,
    white: f64,
    dn_per_electron: f64,
}

impl Readout {
    fn new(s: &Sensor) -> Self {
        Self {
            exposure_time: s.exposure_time,
            dark_electrons: s.dark_rate() * s.exposure_time,
            full_well: s.full_well,
            saturating_mean: s.full_well + 40.0 * s.full_well.sqrt() + 1000.0,
            read_noise: s.read_noise,
            prnu: s.prnu,
            dsnu: s.dsnu,
            black: f64::from(s.black_level),
            white: f64::from(s.white_level()),
            dn_per_electron: s.dn_per_electron(),
        }
    }

    /// Reads the row of `keys`, its mean rates (e-/s) in `scratch.rates`,
    /// into `out`, through the widest vector unit the CPU has (the same
    /// bits either way), reporting its progress to `progress` (see
    /// [`Self::row_lanes`]).
    fn row(
        &self,
        keys: RowKeys<'_>,
        out: &mut [u16],
        scratch: &mut RowScratch,
        progress: impl FnMut(usize, usize),
    ) {
        #[cfg(target_arch = "x86_64")]
        if has_avx2_fma() {
            // SAFETY: AVX2 and FMA support was detected just above.
            unsafe { self.row_avx2(keys, out, scratch, progress) };
            return;
        }
        self.row_lanes(keys, out, scratch, progress);
    }

    /// [`Self::row_lanes`] compiled for AVX2 (and FMA, which the arithmetic
    /// does not use: the same IEEE operations, hence the same bits).
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn row_avx2(
        &self,
        keys: RowKeys<'_>,
        out: &mut [u16],
        scratch: &mut RowScratch,
        progress: impl FnMut(usize, usize),
    ) {
        self.row_lanes(keys, out, scratch, progress);
    }

    /// Reads a row in three passes over it, each [`LANES`] pixels at a time
    /// (the last `width % LANES` pixels one at a time): the fixed patterns
    /// and the mean charges; the Poisson counts ([`PoissonRow`], whose
    /// undecided pixels are finished together across the row); the read
    /// noise and the ADC. Each pixel draws what the per-pixel model `pixel`
    /// (in the tests) draws. `progress(done, total)` is called as the last
    /// two passes, the arithmetic-bound ones, advance: the Poisson pass
    /// counts for two thirds of the row's work (its first round and its
    /// exact rounds each about as long as the read-noise pass), the read
    /// noise for the last third. The first pass is a few multiplications a
    /// pixel when the sensor has no fixed patterns.
    #[inline(always)]
    fn row_lanes(
        &self,
        keys: RowKeys<'_>,
        out: &mut [u16],
        scratch: &mut RowScratch,
        mut progress: impl FnMut(usize, usize),
    ) {
        let RowScratch {
            rates,
            means,
            offsets,
            counts,
            states,
            poisson,
        } = scratch;
        let (width, columns) = (rates.len(), keys.columns);
        let blocks = width / LANES * LANES;
        for x0 in (0..blocks).step_by(LANES) {
            let at = x0..x0 + LANES;
            let (mean, offset) = self.charges(&keys, x0, rates[at.clone()].try_into().unwrap());
            means[at.clone()].copy_from_slice(&mean);
            offsets[at].copy_from_slice(&offset);
        }
        for x in blocks..width {
            (means[x], offsets[x]) = self.pixel_charges(&keys, x, rates[x]);
        }
        for (x, s) in states.iter_mut().enumerate() {
            *s = SplitMix64::at(keys.temporal, x).state();
        }
        poisson.fill(means, counts, states, |done| progress(done, 3 * width));
        for x0 in (0..blocks).step_by(LANES) {
            progress(2 * width + x0, 3 * width);
            let at = x0..x0 + LANES;
            let mut electrons = [0.0; LANES];
            for (i, e) in electrons.iter_mut().enumerate() {
                *e = counts[x0 + i].min(self.full_well) + offsets[x0 + i] + columns[x0 + i];
            }
            if self.read_noise > 0.0 {
                let noise = Lanes::from_states(states[at.clone()].try_into().unwrap())
                    .normal(keys.ziggurat);
                for (e, n) in electrons.iter_mut().zip(noise) {
                    *e += self.read_noise * n;
                }
            }
            for (o, e) in out[at].iter_mut().zip(electrons) {
                *o = self.adc(e);
            }
        }
        for x in blocks..width {
            let electrons = counts[x].min(self.full_well) + offsets[x] + columns[x];
            out[x] = self.read(electrons, &mut SplitMix64::from_state(states[x]));
        }
    }

    /// The mean charges of pixels `x0 .. x0 + LANES` of signal rates
    /// `rates` (e-/s), and their fixed offsets: [`Self::pixel_charges`]
    /// lane by lane, with the fixed-pattern generators stepped together.
    #[inline(always)]
    fn charges(
        &self,
        keys: &RowKeys,
        x0: usize,
        rates: &[f64; LANES],
    ) -> ([f64; LANES], [f64; LANES]) {
        let mut signal = *rates;
        for s in &mut signal {
            *s *= self.exposure_time;
        }
        let mut offset = [0.0; LANES];
        if self.prnu > 0.0 || self.dsnu > 0.0 {
            let mut g = Lanes::at(keys.fixed, x0);
            let gain = g.normal(keys.ziggurat);
            let dark = g.normal(keys.ziggurat);
            for i in 0..LANES {
                signal[i] *= self.gain(gain[i]);
                offset[i] = self.dsnu * dark[i];
            }
        }
        for s in &mut signal {
            *s = self.mean(*s);
        }
        (signal, offset)
    }

    /// Pixel `x`'s mean charge for a signal of `rate` e-/s, dimmed by its
    /// fixed gain and with dark charge, and its fixed offset (DSNU).
    #[inline(always)]
    fn pixel_charges(&self, keys: &RowKeys, x: usize, rate: f64) -> (f64, f64) {
        let mut signal = rate * self.exposure_time;
        let mut offset = 0.0;
        if self.prnu > 0.0 || self.dsnu > 0.0 {
            let mut g = SplitMix64::at(keys.fixed, x);
            signal *= self.gain(g.normal());
            offset = self.dsnu * g.normal();
        }
        (self.mean(signal), offset)
    }

    /// The code of a charge of `electrons` after read noise from `rng`.
    #[inline(always)]
    fn read(&self, mut electrons: f64, rng: &mut SplitMix64) -> u16 {
        if self.read_noise > 0.0 {
            electrons += self.read_noise * rng.normal();
        }
        self.adc(electrons)
    }

    /// Pixel `x`'s reading of a signal of mean `rate` e-/s: the sensor's
    /// model, one pixel at a time, as [`Self::row_lanes`] runs it by lanes.
    #[cfg(test)]
    fn pixel(&self, keys: &RowKeys<'_>, x: usize, rate: f64) -> u16 {
        let (mean, offset) = self.pixel_charges(keys, x, rate);
        let mut rng = SplitMix64::at(keys.temporal, x);
        let collected = rng.poisson(mean);
        self.read(
            collected.min(self.full_well) + offset + keys.columns[x],
            &mut rng,
        )
    }

    /// The fixed gain `1 + prnu z`. A gain below zero needs a draw beyond
    /// 1/prnu sigma; such a pixel is dead (gain 0): it cannot un-collect
    /// light.
    #[inline(always)]
    fn gain(&self, z: f64) -> f64 {
        (1.0 + self.prnu * z).max(0.0)
    }

    /// The mean charge of a signal, dark charge included, capped at
    /// [`Self::saturating_mean`].
    #[inline(always)]
    fn mean(&self, signal: f64) -> f64 {
        (signal + self.dark_electrons).min(self.saturating_mean)
    }

    /// The code of a charge in electrons. The ADC has no negative codes.
    /// Clipping first, then rounding half up by truncation gives the code
    /// that rounding half away from zero then clipping would, without a
    /// call to libm's `round` (not an instruction of baseline x86-64).
    #[inline(always)]
    fn adc(&self, electrons: f64) -> u16 {
        let dn = (self.black + electrons * self.dn_per_electron).clamp(0.0, self.white);
        (dn + 0.5) as u16
    }
}

/// The per-row buffers of [`Readout::row_lanes`], allocated once per band.
struct RowScratch {
    /// The row's mean rates, e-/s: the read-out's input.
    rates: Vec<f64>,
    means: Vec<f64>,
    offsets: Vec<f64>,
    counts: Vec<f64>,
    states: Vec<u64>,
    poisson: PoissonRow,
}

impl RowScratch {
    fn new(width: usize) -> Self {
        Self {
            rates: vec![0.0; width],
            means: vec![0.0; width],
            offsets: vec![0.0; width],
            counts: vec![0.0; width],
            states: vec![0; width],
            poisson: PoissonRow::default(),
        }
    }
}

/// What a row's pixels share: the bases of its fixed-pattern and temporal
/// generators ([`SplitMix64::row_base`]), the ziggurat's table and the
/// frame's column offsets (e-).
struct RowKeys<'a> {
    fixed: u64,
    temporal: u64,
    ziggurat: &'static Ziggurat,
    columns: &'a [f64],
}

impl<'a> RowKeys<'a> {
    fn new(sensor: &Sensor, y: usize, columns: &'a [f64]) -> Self {
        let base = |seed| SplitMix64::row_base(SplitMix64::row_key(seed, y));
        Self {
            fixed: base(sensor.pattern_seed),
            temporal: base(sensor.seed),
            ziggurat: ziggurat(),
            columns,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An ideal sensor: 1 e- per DN, 16 bits, no offset, no noise but shot
    /// noise, a full well no test reaches.
    pub(crate) fn ideal() -> Sensor {
        Sensor {
            exposure_time: 1.0,
            full_well: 1e9,
            read_noise: 0.0,
            electrons_per_dn: 1.0,
            analog_gain: 1.0,
            black_level: 0,
            bit_depth: 16,
            dark_current: 0.0,
            temperature: 25.0,
            reference_temperature: 25.0,
            doubling_temperature: 6.0,
            dsnu: 0.0,
            prnu: 0.0,
            column_noise: 0.0,
            seed: 1,
            pattern_seed: 2,
        }
    }

    fn mean_var(v: &[u16]) -> (f64, f64) {
        let n = v.len() as f64;
        let mean = v.iter().map(|&d| f64::from(d)).sum::<f64>() / n;
        let var = v
            .iter()
            .map(|&d| (f64::from(d) - mean).powi(2))
            .sum::<f64>()
            / (n - 1.0);
        (mean, var)
    }

    #[test]
    fn poisson_counts_have_variance_equal_to_mean_from_0_3_to_1e5() {
        // 2e5 samples: the standard error of var/mean is <= 0.8 % at 0.3 e-
        // (fourth cumulant of a Poisson variate) and ~0.3 % above, so 2 % is
        // a > 2.5-sigma margin everywhere. 1e5 e- needs 2 e- per DN in 16 bits.
        let n = 200_000;
        for mean in [0.3, 1.0, 3.0, 9.9, 10.0, 30.0, 100.0, 1e3, 1e4, 1e5] {
            let per_dn = if mean > 3e4 { 2.0 } else { 1.0 };
            let s = Sensor {
                electrons_per_dn: per_dn,
                ..ideal()
            };
            let mut out = vec![0u16; n];
            s.capture_rates(&vec![mean as f32; n], 1000, n / 1000, &mut out)
                .unwrap();
            let (m, v) = mean_var(&out);
            let (m, v) = (m * per_dn, v * per_dn * per_dn);
            assert!((m / mean - 1.0).abs() < 0.01, "mean {mean}: got {m}");
            // Halving then rounding adds ~1/12 DN² (4/12 e-²), 3e-6 of 1e5.
            assert!(
                (v / m - 1.0).abs() < 0.02,
                "mean {mean}: var/mean {}",
                v / m
            );
        }
    }

    #[test]
    fn the_adc_maps_electrons_with_gain_black_level_and_clipping() {
        let s = Sensor {
            electrons_per_dn: 4.0,
            analog_gain: 2.0,
            black_level: 100,
            bit_depth: 12,
            full_well: 5000.0,
            ..ideal()
        };
        let mut out = vec![0u16; 3];
        s.capture_rates(&[0.0, 400.0, 1e7], 3, 1, &mut out).unwrap();
        assert_eq!(out[0], 100);
        // 400 e- ± 20 at 0.5 DN/e-: 300 ± 10 DN.
        assert!((260..=340).contains(&out[1]), "{}", out[1]);
        // 5000 e- (the full well) -> 100 + 2500 DN, below the 4095 white.
        assert_eq!(out[2], 2600);
    }

    #[test]
    fn dark_current_doubles_every_doubling_temperature() {
        let s = Sensor {
            dark_current: 10.0,
            temperature: 37.0,
            reference_temperature: 25.0,
            doubling_temperature: 6.0,
            ..ideal()
        };
        assert!((s.dark_rate() - 40.0).abs() < 1e-12);
        let n = 100_000;
        let mut out = vec![0u16; n];
        s.capture_rates(&vec![0.0; n], 1000, 100, &mut out).unwrap();
        let (m, v) = mean_var(&out);
        assert!(
            (m - 40.0).abs() < 0.2 && (v / m - 1.0).abs() < 0.03,
            "{m} {v}"
        );
    }

    #[test]
    fn fixed_patterns_repeat_across_frames_and_temporal_noise_does_not() {
        let s = Sensor {
            prnu: 0.01,
            dsnu: 2.0,
            column_noise: 1.0,
            read_noise: 2.0,
            black_level: 200,
            ..ideal()
        };
        let n = 64 * 64;
        let rates = vec![1000.0f32; n];
        let mut frames = Vec::new();
        for seed in 0..16 {
            let mut out = vec![0u16; n];
            Sensor { seed, ..s }
                .capture_rates(&rates, 64, 64, &mut out)
                .unwrap();
            frames.push(out);
        }
        let frame_mean = |p: usize| frames.iter().map(|f| f64::from(f[p])).sum::<f64>() / 16.0;
        let means: Vec<f64> = (0..n).map(frame_mean).collect();
        let mm = means.iter().sum::<f64>() / n as f64;
        let spatial = means.iter().map(|m| (m - mm).powi(2)).sum::<f64>() / (n - 1) as f64;
        // Fixed: prnu (0.01 x 1000)² = 100 e² + dsnu 4 + columns 1; the
        // 16-frame mean keeps 1/16 of the temporal 1000 + 4 + 1/12 e²:
        // ~ 167.8 e² in all (4096 pixels: standard error ~ 4 e²).
        assert!((spatial - 167.8).abs() < 12.0, "{spatial}");
        assert_ne!(frames[0], frames[1]);
        let mut again = vec![0u16; n];
        Sensor { seed: 0, ..s }
            .capture_rates(&rates, 64, 64, &mut again)
            .unwrap();
        assert_eq!(again, frames[0]);
    }

    #[test]
    fn frames_do_not_depend_on_the_thread_count() {
        let s = Sensor {
            prnu: 0.01,
            dsnu: 2.0,
            column_noise: 1.0,
            read_noise: 2.0,
            ..ideal()
        };
        let (w, h) = (37, 53);
        let rates: Vec<f32> = (0..w * h).map(|i| (i % 97) as f32 * 3.7).collect();
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut out = vec![0u16; w * h];
            pool.install(|| s.capture_rates(&rates, w, h, &mut out))
                .unwrap();
            out
        };
        assert_eq!(run(1), run(2));
        assert_eq!(run(1), run(3));
    }

    #[test]
    fn spectral_and_rgb_captures_pick_the_channel_of_each_pixel() {
        let pattern = CfaPattern::from_name("GRBG").unwrap();
        let (w, h, l) = (4, 2, 3);
        // Every pixel's spectrum is (1, 2, 3); channel c responds to sample c.
        let spectra: Vec<f32> = (0..w * h).flat_map(|_| [1.0f32, 2.0, 3.0]).collect();
        let mut response = vec![0.0; 3 * l];
        for c in 0..3 {
            response[c * l + c] = 100.0;
        }
        let s = Sensor {
            full_well: 1e9,
            ..ideal()
        };
        let mut spec = vec![0u16; w * h];
        s.capture_spectral(&spectra, w, h, l, &response, &pattern, None, &mut spec)
            .unwrap();
        let rgb: Vec<f32> = (0..w * h).flat_map(|_| [1.0f32, 2.0, 3.0]).collect();
        let eye = [100.0, 0.0, 0.0, 0.0, 100.0, 0.0, 0.0, 0.0, 100.0];
        let mut from_rgb = vec![0u16; w * h];
        s.capture_rgb(&rgb, w, h, &eye, &pattern, None, &mut from_rgb)
            .unwrap();
        // Same means, same seeds: the same frame.
        assert_eq!(spec, from_rgb);
        // G R / B G: means 200 100 / 300 200, each within 5 sigma.
        for (i, &v) in spec.iter().enumerate() {
            let c = usize::from(pattern.color_at(i / w, i % w));
            let mean = 100.0 * (c + 1) as f64;
            assert!((f64::from(v) - mean).abs() < 5.0 * mean.sqrt(), "{i}: {v}");
        }
    }

    /// Reads a row pixel by pixel, the scalar oracle of the lanes.
    fn row_by_pixels(s: &Sensor, y: usize, rates: &[f64], columns: &[f64]) -> Vec<u16> {
        let (readout, keys) = (Readout::new(s), RowKeys::new(s, y, columns));
        (0..rates.len())
            .map(|x| readout.pixel(&keys, x, rates[x]))
            .collect()
    }

    #[test]
    fn lanes_read_every_pixel_as_the_scalar_model_does() {
        // Means from 0 to past the full well, on both Poisson branches and
        // with every defect on; 61 columns leave a 5-pixel scalar tail.
        let s = Sensor {
            prnu: 0.02,
            dsnu: 3.0,
            read_noise: 2.5,
            dark_current: 0.7,
            full_well: 2e4,
            black_level: 64,
            ..ideal()
        };
        let means = [0.0, 0.3, 2.0, 9.9, 10.0, 11.0, 40.0, 700.0, 1e4, 3e4, 1e7];
        let w = 61;
        let rates: Vec<f64> = (0..w).map(|x| means[(x * 7) % means.len()]).collect();
        let columns: Vec<f64> = (0..w).map(|x| x as f64 * 0.1 - 3.0).collect();
        // Work interleaved with the read-out must change nothing.
        let mut calls = 0;
        let mut scratch = RowScratch::new(w);
        let readout = Readout::new(&s);
        for y in 0..40 {
            let want = row_by_pixels(&s, y, &rates, &columns);
            scratch.rates.copy_from_slice(&rates);
            let mut got = vec![0u16; w];
            let keys = RowKeys::new(&s, y, &columns);
            readout.row_lanes(keys, &mut got, &mut scratch, |_, _| {});
            assert_eq!(got, want, "row {y}");
            scratch.rates.copy_from_slice(&rates);
            let mut dispatched = vec![0u16; w];
            let keys = RowKeys::new(&s, y, &columns);
            readout.row(keys, &mut dispatched, &mut scratch, |done, total| {
                assert!(done <= total && total == 3 * w);
                calls += 1;
            });
            assert_eq!(dispatched, want, "row {y}");
        }
        assert!(calls > 0);
    }

    #[test]
    fn the_falloff_dims_each_pixel_by_its_cos4() {
        let (w, h) = (48, 40);
        let falloff = Falloff::new((20.0, 15.0), 0.03).unwrap();
        let rgb = vec![1.0f32; 3 * w * h];
        let eye = [1e4, 0.0, 0.0, 0.0, 1e4, 0.0, 0.0, 0.0, 1e4];
        let pattern = CfaPattern::from_name("RGGB").unwrap();
        let mut out = vec![0u16; w * h];
        ideal()
            .capture_rgb(&rgb, w, h, &eye, &pattern, Some(&falloff), &mut out)
            .unwrap();
        // The corner's cos⁴ is ~0.48: the image must follow it pixel by pixel.
        for (i, &v) in out.iter().enumerate() {
            let mean = 1e4 * falloff.at(i / w, i % w);
            assert!(
                (f64::from(v) - mean).abs() < 5.0 * mean.sqrt(),
                "{i}: {v} vs {mean}"
            );
        }
        assert!(falloff.at(0, 47) < 0.5);
    }

    #[test]
    fn bad_input_and_parameters_are_named() {
        let pattern = CfaPattern::from_name("RGGB").unwrap();
        let mut out = vec![0u16; 4];
        let mut spectra = vec![1.0f32; 4 * 2];
        spectra[3 * 2 + 1] = f32::NAN;
        let err = ideal()
            .capture_spectral(&spectra, 2, 2, 2, &[1.0; 6], &pattern, None, &mut out)
            .unwrap_err();
        assert!(err.to_string().contains("row 1, column 1"), "{err}");
        let err = Sensor {
            prnu: 1.5,
            ..ideal()
        }
        .capture_rates(&[1.0; 4], 2, 2, &mut out)
        .unwrap_err();
        assert!(err.to_string().starts_with("prnu must be"), "{err}");
        let err = Sensor {
            black_level: 70_000,
            ..ideal()
        }
        .validate()
        .unwrap_err();
        assert!(err.to_string().contains("white level 65535"), "{err}");
        let err = ideal()
            .capture_rates(&[1.0; 3], 2, 2, &mut out)
            .unwrap_err();
        assert!(matches!(err, CoreError::Shape(_)), "{err}");
    }
}

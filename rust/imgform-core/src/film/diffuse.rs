//! Lateral diffusion: a Gaussian blur of interleaved `(H, W, C)` planes.
//!
//! Development inhibitors released in one spot diffuse through the gelatin
//! before they act, so a layer is inhibited by a blurred copy of what the
//! layers developed (the edge effects DIR couplers are known for). A
//! diffusion from a point source spreads as a Gaussian whose standard
//! deviation is the diffusion length; the blur is separable, rows then
//! columns, with mirrored edges so that a uniform field stays exactly
//! uniform (the neutral wedge relies on this).

use super::fastmath::wide;
use crate::error::Result;
use crate::image::mirror;
use crate::invalid;
use crate::parallel::{for_each_band, ROWS_PER_TASK};

/// The widest Gaussian blurred (pixels): 3000 taps each side, a blur wider
/// than any frame's diffusion or halation (tens of pixels) by far, and still
/// seconds a megapixel. Beyond it the taps alone would not fit in memory
/// (`sigma` = 1e18 asked for a vector of 3e18).
pub const MAX_SIGMA: f64 = 1000.0;

/// Taps of a normalised Gaussian of standard deviation `sigma` (pixels),
/// out to 3 sigma (0.3 % of the weight beyond), centre first.
///
/// # Errors
/// [`crate::CoreError::InvalidArgument`] naming `what` for a `sigma` that
/// is not in `(0, MAX_SIGMA]`.
pub fn gaussian_taps(sigma: f64, what: &str) -> Result<Vec<f32>> {
    if !(sigma > 0.0 && sigma <= MAX_SIGMA) {
        return Err(invalid!(
            "{what} must be > 0 and at most {MAX_SIGMA} pixels, got {sigma}"
        ));
    }
    let radius = (3.0 * sigma).ceil() as usize;
    let raw: Vec<f64> = (0..=radius)
        .map(|k| (-0.5 * (k as f64 / sigma).powi(2)).exp())
        .collect();
    let total = raw[0] + 2.0 * raw[1..].iter().sum::<f64>();
    Ok(raw.iter().map(|w| (w / total) as f32).collect())
}

/// Blurs `src` `(height, width, channels)` into `out` with the symmetric
/// `taps` (centre first) along rows then columns. A one-tap kernel copies.
pub fn blur(
    src: &[f32],
    width: usize,
    height: usize,
    channels: usize,
    taps: &[f32],
    out: &mut [f32],
) {
    let mut across = vec![0.0f32; src.len()];
    blur_rows(src, width, channels, taps, &mut across);
    blur_columns_then(
        &across,
        width,
        height,
        channels,
        taps,
        out,
        width * channels,
        |_, b, o| o.copy_from_slice(b),
    );
}

/// The row pass of [`blur`]: each row of `src` `(H, width, channels)`
/// convolved with `taps` into `out`, mirrored at the ends.
pub fn blur_rows(src: &[f32], width: usize, channels: usize, taps: &[f32], out: &mut [f32]) {
    blur_rows_of(src, width, channels, taps, out, |_| ());
}

/// [`blur_rows`] of `map(row)` for each row of `src`, `map` rewriting a
/// copy of the row in place: development blurs the donors' densities, the
/// curves of the log exposures, without storing them as an image.
pub fn blur_rows_of<F>(
    src: &[f32],
    width: usize,
    channels: usize,
    taps: &[f32],
    out: &mut [f32],
    map: F,
) where
    F: Fn(&mut [f32]) + Sync,
{
    let row_len = width * channels;
    let pad = (taps.len() - 1) * channels;
    for_each_band(out, row_len, ROWS_PER_TASK, |y0, rows| {
        // One padded copy of the source row per row, reused within the band.
        let mut padded = vec![0.0f32; row_len + 2 * pad];
        let reach = taps.len() - 1;
        for (i, row) in rows.chunks_mut(row_len).enumerate() {
            let line = &mut padded[pad..pad + row_len];
            line.copy_from_slice(&src[(y0 + i) * row_len..][..row_len]);
            map(line);
            // Only the `reach` pixels beyond either end are mirrored.
            let ends = (0..reach).chain(reach + width..2 * reach + width);
            for x in ends {
                let sx = mirror(x as isize - reach as isize, width);
                padded.copy_within(pad + sx * channels..pad + (sx + 1) * channels, x * channels);
            }
            convolve_row_wide(&padded, pad, channels, taps, row);
        }
    });
}

wide!(
    /// [`convolve_row`], 8 lanes wide where the CPU has them.
    fn convolve_row_wide = convolve_row(
        padded: &[f32],
        pad: usize,
        channels: usize,
        taps: &[f32],
        row: &mut [f32],
    )
);

/// `row[k] = Σ_t taps[|t|] padded[pad + k + t channels]` by
/// [`symmetric_sums`].
#[inline(always)]
fn convolve_row(padded: &[f32], pad: usize, channels: usize, taps: &[f32], row: &mut [f32]) {
    let n = row.len();
    symmetric_sums(
        taps,
        |t| {
            let d = t * channels;
            (&padded[pad - d..][..n], &padded[pad + d..][..n])
        },
        row,
    );
}

wide!(
    /// [`column_rows`], 8 lanes wide where the CPU has them.
    fn column_rows_wide = column_rows(
        lines: &[&[f32]],
        taps: &[f32],
        out: &mut [f32],
        stride: usize,
    )
);

/// Output rows per step of the column pass. Each row `y` is
/// `taps[0] r(y) + Σ_t taps[t] (r(y - t) + r(y + t))` over the input rows
/// `r`; four neighbouring outputs read mostly the same rows, so one step
/// loads two new rows per tap and reuses six held in registers, where a row
/// at a time loaded two per tap per output: the column pass was limited by
/// those loads (from the second-level cache), at three times the time of
/// the row pass for the same arithmetic.
const ROWS: usize = 4;

/// [`ROWS`] output rows of the column pass over one strip: row `r` of `out`
/// (at `r stride`, as long as the lines) centred on `lines[c + r]`, with
/// `c = taps.len() - 1` the first output's centre line and `lines` the
/// input rows from `c` above it to `c + ROWS - 1` below its last. Each sum
/// adds its terms in the order of [`symmetric_sums`] (the same bits as a
/// row at a time), eight samples per step and then one.
#[inline(always)]
fn column_rows(lines: &[&[f32]], taps: &[f32], out: &mut [f32], stride: usize) {
    let len = lines[0].len();
    let whole = len - len % 8;
    for x in (0..whole).step_by(8) {
        column_step::<8>(lines, taps, x, out, stride);
    }
    for x in whole..len {
        column_step::<1>(lines, taps, x, out, stride);
    }
}

/// Samples `x..x + B` of the [`ROWS`] outputs of [`column_rows`]. At tap
/// `t` output `r` adds rows `c + r - t` and `c + r + t`: `up[r]` and
/// `down[r]`, which the step before held in `up[r - 1]` and `down[r + 1]`,
/// so each tap loads only `up[0]` and `down[ROWS - 1]`.
#[inline(always)]
fn column_step<const B: usize>(
    lines: &[&[f32]],
    taps: &[f32],
    x: usize,
    out: &mut [f32],
    stride: usize,
) {
    let c = taps.len() - 1;
    let load = |line: usize| -> [f32; B] { lines[line][x..x + B].try_into().expect("B samples") };
    let mut up = [[0.0f32; B]; ROWS];
    for (r, u) in up.iter_mut().enumerate() {
        *u = load(c + r);
    }
    let mut down = up;
    let mut sums = [[0.0f32; B]; ROWS];
    for (s, u) in sums.iter_mut().zip(&up) {
        for (s, u) in s.iter_mut().zip(u) {
            *s = taps[0] * u;
        }
    }
    for (t, w) in taps.iter().enumerate().skip(1) {
        for r in (1..ROWS).rev() {
            up[r] = up[r - 1];
        }
        up[0] = load(c - t);
        for r in 0..ROWS - 1 {
            down[r] = down[r + 1];
        }
        down[ROWS - 1] = load(c + ROWS - 1 + t);
        for ((s, u), d) in sums.iter_mut().zip(&up).zip(&down) {
            for ((s, u), d) in s.iter_mut().zip(u).zip(d) {
                *s += w * (u + d);
            }
        }
    }
    for (r, s) in sums.iter().enumerate() {
        out[r * stride + x..][..B].copy_from_slice(s);
    }
}

/// Samples per block of [`symmetric_sums`]: four 8-lane registers of sums,
/// independent chains that hide the adds' latency.
const BLOCK: usize = 32;

/// `out[k] = taps[0] c[k] + Σ_{t >= 1} taps[t] (a_t[k] + b_t[k])` with
/// `(a_t, b_t) = pair(t)` (slices as long as `out`, `c` the first of
/// `pair(0)`), the terms added in that order for every sample, path and
/// thread (the same bits).
///
/// Block by block of [`BLOCK`] samples, the sums staying in registers over
/// all the taps: summing one tap over the whole line at a time loaded and
/// stored every sum once per tap, which made the loads (not the
/// arithmetic) the limit. The last `len % BLOCK` samples go tap by tap.
#[inline(always)]
fn symmetric_sums<'a>(
    taps: &[f32],
    pair: impl Fn(usize) -> (&'a [f32], &'a [f32]),
    out: &mut [f32],
) {
    let whole = out.len() - out.len() % BLOCK;
    let (blocks, tail) = out.split_at_mut(whole);
    let block = |line: &'a [f32], x0: usize| -> &'a [f32; BLOCK] {
        line[x0..x0 + BLOCK].try_into().expect("a whole block")
    };
    for (x0, o) in (0..whole)
        .step_by(BLOCK)
        .zip(blocks.chunks_exact_mut(BLOCK))
    {
        let mut sum = [0.0f32; BLOCK];
        for (s, c) in sum.iter_mut().zip(block(pair(0).0, x0)) {
            *s = taps[0] * c;
        }
        for (t, w) in taps.iter().enumerate().skip(1) {
            let (a, b) = pair(t);
            for ((s, a), b) in sum.iter_mut().zip(block(a, x0)).zip(block(b, x0)) {
                *s += w * (a + b);
            }
        }
        o.copy_from_slice(&sum);
    }
    for (o, c) in tail.iter_mut().zip(&pair(0).0[whole..]) {
        *o = taps[0] * c;
    }
    for (t, w) in taps.iter().enumerate().skip(1) {
        let (a, b) = pair(t);
        for ((o, a), b) in tail.iter_mut().zip(&a[whole..]).zip(&b[whole..]) {
            *o += w * (a + b);
        }
    }
}

/// The column pass of [`blur`] over the row pass's output `across`, handing
/// each blurred row to `finish(y, blurred, out_row)` (out rows of
/// `out_row_len` elements): the per-pixel stage that reads the blur runs
/// while a band's few blurred rows are in cache, and no blurred image is
/// stored.
#[allow(clippy::too_many_arguments)]
pub fn blur_columns_then<T, F>(
    across: &[f32],
    width: usize,
    height: usize,
    channels: usize,
    taps: &[f32],
    out: &mut [T],
    out_row_len: usize,
    finish: F,
) where
    T: Send,
    F: Fn(usize, &[f32], &mut [T]) + Sync,
{
    let row_len = width * channels;
    for_each_band(out, out_row_len, COLUMN_BAND, |y0, rows| {
        let band = rows.len() / out_row_len;
        // Whole steps of `ROWS`: a short band's extra rows (mirrored) are
        // computed and dropped.
        let mut blurred = vec![0.0f32; band.next_multiple_of(ROWS) * row_len];
        let mut lines: Vec<&[f32]> = Vec::with_capacity(2 * taps.len() + ROWS);
        let reach = taps.len() as isize - 1;
        // Strip by strip, so that the rows the band's taps read stay in the
        // second-level cache from one output row to the next (whole rows of
        // a wide image, times the taps, would not fit).
        for x0 in (0..row_len).step_by(COLUMN_STRIP) {
            let len = COLUMN_STRIP.min(row_len - x0);
            for (i, b) in blurred.chunks_exact_mut(ROWS * row_len).enumerate() {
                let y = (y0 + i * ROWS) as isize;
                let at = |dy: isize| &across[mirror(y + dy, height) * row_len + x0..][..len];
                lines.clear();
                lines.extend((-reach..=reach + ROWS as isize - 1).map(at));
                column_rows_wide(&lines, taps, &mut b[x0..], row_len);
            }
        }
        for (i, (b, row)) in blurred
            .chunks_exact(row_len)
            .zip(rows.chunks_mut(out_row_len))
            .enumerate()
        {
            finish(y0 + i, b, row);
        }
    });
}

/// Rows per task of the column pass. A band reads the rows within reach of
/// its taps above and below it too: with the halation's reach of 30 rows,
/// bands of 8 read each input row from memory 8.5 times over (the pass
/// waited on those loads), bands of 32 read it 2.9 times; a 24 MP image
/// still makes 125 tasks.
const COLUMN_BAND: usize = 32;

/// Samples per strip of the column pass: a band's rows within reach of a
/// wide blur (8 + 60 for the halation's) take 270 KB of strips of 1024.
const COLUMN_STRIP: usize = 1024;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn taps_are_refused_beyond_the_widest_blur() {
        for sigma in [0.0, -1.0, f64::NAN, MAX_SIGMA * 1.01, 1e18] {
            let err = gaussian_taps(sigma, "the spread").unwrap_err().to_string();
            assert!(
                err.contains("the spread must be > 0 and at most 1000"),
                "{err}"
            );
        }
        assert_eq!(gaussian_taps(MAX_SIGMA, "s").unwrap().len(), 3001);
    }

    #[test]
    fn taps_sum_to_one_and_fall() {
        let t = gaussian_taps(2.0, "sigma").unwrap();
        assert_eq!(t.len(), 7);
        let sum: f32 = t[0] + 2.0 * t[1..].iter().sum::<f32>();
        assert!((sum - 1.0).abs() < 1e-6);
        assert!(t.windows(2).all(|p| p[1] < p[0]));
    }

    #[test]
    fn the_wide_row_convolution_gives_the_plain_bits() {
        let taps = gaussian_taps(3.3, "sigma").unwrap();
        let (channels, n) = (3, 3 * 45);
        let pad = (taps.len() - 1) * channels;
        let padded: Vec<f32> = (0..n + 2 * pad)
            .map(|i| ((i * 7919) % 1000) as f32 / 77.0)
            .collect();
        let (mut plain, mut wide_row) = (vec![0.0; n], vec![0.0; n]);
        convolve_row(&padded, pad, channels, &taps, &mut plain);
        convolve_row_wide(&padded, pad, channels, &taps, &mut wide_row);
        assert_eq!(plain, wide_row);
        // Sample 4 (channel 1 of pixel 1, in the first block) and sample
        // 133 (in the tail past the blocks), summed tap by tap as documented.
        for k in [4, n - 2] {
            let mut want = taps[0] * padded[pad + k];
            for (t, w) in taps.iter().enumerate().skip(1) {
                want += w * (padded[pad + k - 3 * t] + padded[pad + k + 3 * t]);
            }
            assert_eq!(plain[k], want, "{k}");
        }
    }

    #[test]
    fn the_column_pass_adds_each_rows_taps_in_order() {
        // 37 rows: a band of 32 and a short one of 5 (steps of 4 rows with
        // rows to drop); 13 pixels of 3 samples: steps of 8 and a tail.
        let (w, h, c) = (13, 37, 3);
        let taps = gaussian_taps(3.3, "sigma").unwrap();
        let across: Vec<f32> = (0..w * h * c)
            .map(|i| ((i * 7919) % 1000) as f32 / 77.0)
            .collect();
        let mut out = vec![0.0f32; across.len()];
        blur_columns_then(&across, w, h, c, &taps, &mut out, w * c, |_, b, o| {
            o.copy_from_slice(b)
        });
        let at = |y: isize, k: usize| across[mirror(y, h) * w * c + k];
        for (i, got) in out.iter().enumerate() {
            let (y, k) = ((i / (w * c)) as isize, i % (w * c));
            let mut want = taps[0] * at(y, k);
            for (t, wt) in taps.iter().enumerate().skip(1) {
                want += wt * (at(y - t as isize, k) + at(y + t as isize, k));
            }
            assert_eq!(got.to_bits(), want.to_bits(), "row {y}, sample {k}");
        }
    }

    #[test]
    fn mirror_reflects_about_the_edge_samples() {
        let got: Vec<usize> = (-3..8).map(|i| mirror(i, 5)).collect();
        assert_eq!(got, [3, 2, 1, 0, 1, 2, 3, 4, 3, 2, 1]);
        assert_eq!(mirror(-7, 1), 0);
        // A radius larger than the image folds back and forth.
        assert_eq!(mirror(9, 3), 1);
    }

    #[test]
    fn a_uniform_field_stays_uniform_and_mass_is_kept_inside() {
        let (w, h, c) = (13, 9, 2);
        let src: Vec<f32> = (0..w * h * c)
            .map(|i| if i % 2 == 0 { 0.7 } else { 1.3 })
            .collect();
        let mut out = vec![0.0; src.len()];
        blur(
            &src,
            w,
            h,
            c,
            &gaussian_taps(1.5, "sigma").unwrap(),
            &mut out,
        );
        for (a, b) in src.iter().zip(&out) {
            assert!((a - b).abs() < 1e-6);
        }
        // A point in the middle spreads but keeps its total.
        let mut point = vec![0.0f32; 31 * 31];
        point[15 * 31 + 15] = 1.0;
        let mut spread = vec![0.0; point.len()];
        blur(
            &point,
            31,
            31,
            1,
            &gaussian_taps(2.0, "sigma").unwrap(),
            &mut spread,
        );
        let total: f32 = spread.iter().sum();
        assert!((total - 1.0).abs() < 1e-5);
        assert!(spread[15 * 31 + 15] < 0.05);
        assert_eq!(spread[15 * 31 + 14], spread[15 * 31 + 16]);
        assert_eq!(spread[14 * 31 + 15], spread[15 * 31 + 14]);
    }
}

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
use crate::image::mirror;
use crate::parallel::{for_each_band, ROWS_PER_TASK};

/// Taps of a normalised Gaussian of standard deviation `sigma` (pixels),
/// out to 3 sigma (0.3 % of the weight beyond), centre first.
pub fn gaussian_taps(sigma: f64) -> Vec<f32> {
    let radius = (3.0 * sigma).ceil().max(0.0) as usize;
    let raw: Vec<f64> = (0..=radius)
        .map(|k| (-0.5 * (k as f64 / sigma).powi(2)).exp())
        .collect();
    let total = raw[0] + 2.0 * raw[1..].iter().sum::<f64>();
    raw.iter().map(|w| (w / total) as f32).collect()
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
    /// [`column()`], 8 lanes wide where the CPU has them.
    fn column_wide = column(rows: &[(&[f32], &[f32])], taps: &[f32], out: &mut [f32])
);

/// One row of the column pass: `out = Σ_t taps[t] (up_t + down_t)` over the
/// rows `t` above and below (`rows[0]` holds the centre row twice; the
/// centre tap counts it once), by [`symmetric_sums`].
#[inline(always)]
fn column(rows: &[(&[f32], &[f32])], taps: &[f32], out: &mut [f32]) {
    symmetric_sums(taps, |t| rows[t], out);
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
    for_each_band(out, out_row_len, ROWS_PER_TASK, |y0, rows| {
        let band = rows.len() / out_row_len;
        let mut blurred = vec![0.0f32; band * row_len];
        let mut lines: Vec<(&[f32], &[f32])> = Vec::with_capacity(taps.len());
        // Strip by strip, so that the rows the band's taps read stay in the
        // second-level cache from one output row to the next (whole rows of
        // a wide image, times the taps, would not fit).
        for x0 in (0..row_len).step_by(COLUMN_STRIP) {
            let len = COLUMN_STRIP.min(row_len - x0);
            for (i, b) in blurred.chunks_exact_mut(row_len).enumerate() {
                let y = (y0 + i) as isize;
                let at = |dy: isize| &across[mirror(y + dy, height) * row_len + x0..][..len];
                lines.clear();
                lines.extend((0..taps.len() as isize).map(|t| (at(-t), at(t))));
                column_wide(&lines, taps, &mut b[x0..x0 + len]);
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

/// Samples per strip of the column pass: a band's rows within reach of a
/// wide blur (8 + 60 for the halation's) take 270 KB of strips of 1024.
const COLUMN_STRIP: usize = 1024;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn taps_sum_to_one_and_fall() {
        let t = gaussian_taps(2.0);
        assert_eq!(t.len(), 7);
        let sum: f32 = t[0] + 2.0 * t[1..].iter().sum::<f32>();
        assert!((sum - 1.0).abs() < 1e-6);
        assert!(t.windows(2).all(|p| p[1] < p[0]));
    }

    #[test]
    fn the_wide_row_convolution_gives_the_plain_bits() {
        let taps = gaussian_taps(3.3);
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
        blur(&src, w, h, c, &gaussian_taps(1.5), &mut out);
        for (a, b) in src.iter().zip(&out) {
            assert!((a - b).abs() < 1e-6);
        }
        // A point in the middle spreads but keeps its total.
        let mut point = vec![0.0f32; 31 * 31];
        point[15 * 31 + 15] = 1.0;
        let mut spread = vec![0.0; point.len()];
        blur(&point, 31, 31, 1, &gaussian_taps(2.0), &mut spread);
        let total: f32 = spread.iter().sum();
        assert!((total - 1.0).abs() < 1e-5);
        assert!(spread[15 * 31 + 15] < 0.05);
        assert_eq!(spread[15 * 31 + 14], spread[15 * 31 + 16]);
        assert_eq!(spread[14 * 31 + 15], spread[15 * 31 + 14]);
    }
}

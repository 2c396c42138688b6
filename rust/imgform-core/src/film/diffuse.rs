//! Lateral diffusion: a Gaussian blur of interleaved `(H, W, C)` planes.
//!
//! Development inhibitors released in one spot diffuse through the gelatin
//! before they act, so a layer is inhibited by a blurred copy of what the
//! layers developed (the edge effects DIR couplers are known for). A
//! diffusion from a point source spreads as a Gaussian whose standard
//! deviation is the diffusion length; the blur is separable, rows then
//! columns, with mirrored edges so that a uniform field stays exactly
//! uniform (the neutral wedge relies on this).

use crate::image::mirror;
use crate::parallel::{for_each_band, for_each_row, ROWS_PER_TASK};

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
    let row_len = width * channels;
    let mut across = vec![0.0f32; src.len()];
    let r = taps.len() as isize - 1;
    for_each_band(&mut across, row_len, ROWS_PER_TASK, |y0, rows| {
        // One padded copy of the source row per row, reused within the band.
        let pad = (r as usize) * channels;
        let mut padded = vec![0.0f32; row_len + 2 * pad];
        for (i, row) in rows.chunks_mut(row_len).enumerate() {
            let line = &src[(y0 + i) * row_len..][..row_len];
            for (x, p) in padded.chunks_mut(channels).enumerate() {
                let sx = mirror(x as isize - r, width);
                p.copy_from_slice(&line[sx * channels..][..channels]);
            }
            for (k, o) in row.iter_mut().enumerate() {
                let c = k + pad;
                let mut acc = taps[0] * padded[c];
                for (t, w) in taps.iter().enumerate().skip(1) {
                    let d = t * channels;
                    acc += w * (padded[c - d] + padded[c + d]);
                }
                *o = acc;
            }
        }
    });
    for_each_row(out, row_len, |y, row| {
        let at = |dy: isize| &across[mirror(y as isize + dy, height) * row_len..][..row_len];
        for (o, a) in row.iter_mut().zip(at(0)) {
            *o = taps[0] * a;
        }
        for (t, w) in taps.iter().enumerate().skip(1) {
            let (up, down) = (at(-(t as isize)), at(t as isize));
            for ((o, a), b) in row.iter_mut().zip(up).zip(down) {
                *o += w * (a + b);
            }
        }
    });
}

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

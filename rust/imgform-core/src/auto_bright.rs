//! LibRaw's automatic brightening (`postprocess()` without
//! `no_auto_bright`), for [`crate::develop`]: white goes to the start of
//! the highest bin of 8 codes of the linear, clipped 16-bit development
//! above which more than 1 % of the pixels lie, in the channel where that
//! bin is highest, and never below bin 32.
//!
//! The level is read off histograms of the demosaiced image, which the
//! development then finishes with the gain in its matrix: one demosaic.
//! Developing twice (a linear image to find the level, then the
//! brightened one) cost 2.3 times a plain development at 24 MP.

use crate::image::Sample;
use rayon::prelude::*;

/// Bins of each channel's histogram: 16-bit codes in bins of 8.
const BINS: usize = 0x2000;
/// Codes per bin, as a shift.
const SHIFT: u32 = 3;
/// The lowest bin white may start at.
const FLOOR: usize = 32;
/// The fraction of the pixels that may lie above white (LibRaw's
/// `auto_bright_thr`).
const THRESHOLD: f64 = 0.01;

/// The brightening of a development.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AutoBright {
    /// The pixels the 1 % is of: LibRaw counts those of the final image,
    /// after a non-square sensor's stretch, but takes the values before it.
    pub pixels: usize,
}

/// Each channel's histogram, [`BINS`] bins each, one after the other.
pub(crate) struct Histograms(Vec<u64>);

impl Histograms {
    /// The histograms of interleaved RGB rows `rgb`, each `row_len` samples
    /// long, once `linear` has turned each row into 16-bit codes (into a
    /// row of scratch). Integer counts, so the sum over the threads' rows
    /// does not depend on how they were split.
    pub(crate) fn of<T, F>(rgb: &[T], row_len: usize, linear: F) -> Self
    where
        T: Sample,
        F: Fn(&[T], &mut [u16]) + Sync,
    {
        let counts = rgb
            .par_chunks(row_len)
            .fold(
                || (vec![0u64; 3 * BINS], vec![0u16; row_len]),
                |(mut counts, mut codes), row| {
                    linear(row, &mut codes[..row.len()]);
                    for pixel in codes[..row.len()].chunks_exact(3) {
                        for (c, &v) in pixel.iter().enumerate() {
                            counts[c * BINS + usize::from(v >> SHIFT)] += 1;
                        }
                    }
                    (counts, codes)
                },
            )
            .map(|(counts, _)| counts)
            .reduce(
                || vec![0; 3 * BINS],
                |mut a, b| {
                    a.iter_mut().zip(b).for_each(|(a, b)| *a += b);
                    a
                },
            );
        Histograms(counts)
    }
}

impl AutoBright {
    /// The gain that takes the start of the white bin of `histograms` to
    /// full scale (LibRaw's curve maps its `white << 3` to `0x10000`).
    pub(crate) fn gain(self, histograms: &Histograms) -> f64 {
        let perc = (self.pixels as f64 * THRESHOLD) as u64;
        let white = histograms
            .0
            .chunks_exact(BINS)
            .map(|counts| {
                // From the top down, the first bin with more than `perc`
                // pixels at or above it.
                let mut above = 0;
                (FLOOR + 1..BINS)
                    .rev()
                    .find(|&bin| {
                        above += counts[bin];
                        above > perc
                    })
                    .unwrap_or(FLOOR)
            })
            .max()
            .unwrap_or(FLOOR);
        f64::from(0x10000u32) / (white << SHIFT) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The histograms of `n` pixels whose channels are all `code(i)`.
    fn histograms(n: usize, code: impl Fn(usize) -> u16) -> Histograms {
        let rgb: Vec<u16> = (0..n).flat_map(|i| [code(i); 3]).collect();
        Histograms::of(&rgb, 30, |src, dst| dst.copy_from_slice(src))
    }

    #[test]
    fn white_is_the_bin_with_more_than_one_percent_above_it() {
        // 1000 pixels, codes 0, 64, ..., the highest 63936: 10 may lie
        // above white, so it is the bin of the 11th highest, 63296.
        let h = histograms(1000, |i| (64 * i) as u16);
        let white = (64 * 989) >> SHIFT;
        assert_eq!(
            AutoBright { pixels: 1000 }.gain(&h),
            65536.0 / (white << 3) as f64
        );
        // Counted against more pixels (a stretched image), fewer lie above.
        let stretched = AutoBright { pixels: 1500 }.gain(&h);
        assert_eq!(stretched, 65536.0 / ((64 * 984) >> SHIFT << 3) as f64);
    }

    #[test]
    fn the_brightest_channel_sets_white_and_dark_images_stop_at_the_floor() {
        let rgb: Vec<u16> = (0..400u16).flat_map(|i| [i, 40 * i, 2 * i]).collect();
        let h = Histograms::of(&rgb, 60, |src, dst| dst.copy_from_slice(src));
        // Green's 5th highest, 40 * 395, sets it.
        let white = (40 * 395) >> SHIFT;
        assert_eq!(
            AutoBright { pixels: 400 }.gain(&h),
            65536.0 / (white << 3) as f64
        );
        let dark = histograms(1000, |i| (i % 200) as u16);
        assert_eq!(AutoBright { pixels: 1000 }.gain(&dark), 65536.0 / 256.0);
        // Fewer pixels than the 1 % of a stretched count: the floor too.
        let few = histograms(50, |_| 60000);
        assert_eq!(AutoBright { pixels: 5000 }.gain(&few), 65536.0 / 256.0);
        assert_eq!(AutoBright { pixels: 50 }.gain(&few), 65536.0 / 60000.0);
    }

    #[test]
    fn the_counts_do_not_depend_on_the_threads() {
        let h = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| histograms(100_000, |i| (i * 7919 % 65536) as u16).0)
        };
        assert_eq!(h(1), h(3));
    }
}

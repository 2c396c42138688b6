//! How colourful a base is around each pixel, for the saturated classes of
//! the fusion and of "raisr_cd" ([`super::raisr::Bank::saturation`]): the
//! absolute values of the sums of `R - G` and `B - G` over a 4x4 window,
//! added.
//!
//! Where colours are saturated, the channels are weakly correlated, and
//! filters fitted on photographs (whose channels mostly move together) lean
//! on colour differences that no longer hold: on the held-out training
//! photographs with their chroma tripled, the fusion trailed MLRI by 0.6
//! dB and "raisr_cd" by 0.7 dB. Filters of their own for such pixels
//! recover most of it.
//!
//! The window is the four CFA quads (the 2x2 cells, red at the top left)
//! that meet at a corner of the quads' grid, and it decides the four pixels
//! around that corner: each pixel takes its nearest corner's, so no window
//! reaches further than two rows or columns, as the filters' windows do.
//! The sums are *signed* and over whole CFA periods, so the false colour a
//! mosaic aliases into on fine grey detail, which alternates in sign from
//! pixel to pixel, cancels instead of sending the pixel to the saturated
//! filters: the mean of `|R - G| + |B - G|` left 11 % more false colour on
//! the grey zone plate for the same gain. Each pixel's own 5x5 tent of
//! signed differences, which this replaced, scored the same (within 0.02
//! dB at every chroma scale, for "raisr_cd" and the fusion) with a little
//! more false colour (5134 against 5040 for "raisr_cd"), but its sums took
//! 6 % of "raisr_cd"'s time, these 2 %: the tent kept "best" below 4x
//! LibRaw's AHD.
//!
//! The sums stream with the base's rows ([`super::refined::Window`]): a
//! red row leaves its differences, and the blue row below adds its own,
//! completes the quads and, with the quads above, the corners between
//! them. Each sum is taken in the training script's order.

use super::raisr::PITCH;
use super::RowKind;
use std::ops::Range;

/// Pixels of a window.
const WINDOW: f32 = 16.0;

/// The running sums of the base's colour differences. They are kept at
/// every column, though only those of the quads' first columns are a
/// quad's or a corner's: contiguous loops that the compiler vectorises
/// cost less than gathering every other column. Few rows are kept, and
/// each blue row's corners are found in one pass, since the sums' rows
/// compete for the cache with the filters'.
pub(super) struct Saturation {
    /// `R - G` and `B - G` of the red row; once the blue row below has
    /// come, with its own added: each column's of the quads.
    columns: Vec<f32>,
    /// The sums of the quads at and two columns left of each column, of
    /// the last row of quads.
    above: Vec<f32>,
    /// The saturated bin's offset or zero for each corner of the last row
    /// of corners, at the column to its right.
    corners: Vec<u32>,
    /// The red sites' column parity, where quads start.
    red: usize,
    /// The tile row just below the last corners (a red row).
    corner: usize,
}

impl Saturation {
    pub(super) fn new() -> Self {
        Saturation {
            columns: vec![0.0; 2 * PITCH],
            above: vec![0.0; 2 * PITCH],
            corners: vec![0; PITCH],
            red: 0,
            corner: 0,
        }
    }

    /// Takes the base's (clamped) row `ty` of `kind`, its planes own
    /// chroma, green and other chroma `n` long, the base's rows starting at
    /// tile row `first` and sound in columns `first .. n - first` (a tile's
    /// base is as narrow as it is short); a blue row completes the corners
    /// above it, each saturated if its sums' absolute values add up to at
    /// least `least` (of [`least_saturated`]), which moves its pixels'
    /// classes `offset` on.
    #[inline(always)]
    pub(super) fn push(
        &mut self,
        kind: RowKind,
        [own, green, other]: [&[f32]; 3],
        (ty, first): (usize, usize),
        (least, offset): (f32, u32),
    ) {
        let (red, blue) = if kind.blue {
            (other, own)
        } else {
            (own, other)
        };
        if kind.blue && ty == first {
            return; // no red row above
        }
        let n = green.len();
        for (p, chroma) in [red, blue].into_iter().enumerate() {
            let columns = &mut self.columns[p * PITCH..p * PITCH + n];
            let differences = chroma.iter().zip(green).map(|(c, g)| c - g);
            if kind.blue {
                for (d, v) in columns.iter_mut().zip(differences) {
                    *d += v;
                }
            } else {
                for (d, v) in columns.iter_mut().zip(differences) {
                    *d = v;
                }
            }
        }
        if !kind.blue {
            return;
        }
        // The corners' sums add the quads' sums of the row above to this
        // row's, which then take their place. Below the tile's first row
        // of quads, the first row of corners is not an output row's.
        self.corner = ty - 1;
        self.red = 1 - kind.chroma_parity;
        let (columns, above) = (&self.columns, &mut self.above);
        let quads = |p: usize, x: usize| {
            let c = &columns[p * PITCH + x..p * PITCH + n];
            c.iter().zip(&c[1..]).map(|(a, b)| a + b)
        };
        let pairs = |p: usize| quads(p, 0).zip(quads(p, 2)).map(|(a, b)| a + b);
        let (above_red, above_blue) = above.split_at_mut(PITCH);
        let above = above_red[2..n - 1]
            .iter_mut()
            .zip(&mut above_blue[2..n - 1]);
        let sums = pairs(0).zip(pairs(1));
        for (c, ((ar, ab), (r, b))) in self.corners[2..n - 1].iter_mut().zip(above.zip(sums)) {
            let total = (*ar + r).abs() + (*ab + b).abs();
            *c = if total >= least { offset } else { 0 };
            (*ar, *ab) = (r, b);
        }
    }

    /// Moves the columns `cols` of output row `y`'s `class` that are
    /// saturated to the saturated bin: `y` is one of the rows about the
    /// last corners, and `cols` lie two columns within the sound ones of
    /// [`Saturation::push`].
    #[inline(always)]
    pub(super) fn classes(&self, y: usize, class: &mut [u32], cols: Range<usize>) {
        debug_assert!(y == self.corner || y + 1 == self.corner, "row {y}");
        // A pixel takes the corner at its left edge in a quad's first
        // column (the red sites'), at its right edge in the second: a
        // blend of masks, where a select compiled to gathers.
        let x = cols.start;
        let corners = self.corners[x..].iter().zip(&self.corners[x + 1..]);
        for (x, (k, (l, r))) in cols.clone().zip(class[cols].iter_mut().zip(corners)) {
            let left = (((x ^ self.red) & 1) as u32).wrapping_sub(1);
            *k += (l & left) | (r & !left);
        }
    }
}

/// What the training script compares with the saturated bin's threshold:
/// the window sums' absolute values, added (`sum`, in the samples' scale),
/// as means on [0, 1] data (`inv_scale` of the samples).
#[inline(always)]
fn mean(sum: f32, inv_scale: f32) -> f32 {
    sum * inv_scale / WINDOW
}

/// The least sum whose [`mean`] reaches `threshold`, for a positive
/// `inv_scale`. Each rounding of [`mean`] is monotonic, so a sum is
/// saturated exactly when it reaches this one: each corner then takes one
/// comparison instead of a product and a division.
pub(super) fn least_saturated(threshold: f32, inv_scale: f32) -> f32 {
    if mean(0.0, inv_scale) >= threshold {
        return 0.0;
    }
    // Non-negative floats are ordered as their bits. `mean` of `lo` stays
    // below the threshold, of `hi` at or above it (infinity's is infinite).
    let (mut lo, mut hi) = (0u32, f32::INFINITY.to_bits());
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if mean(f32::from_bits(mid), inv_scale) >= threshold {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    f32::from_bits(hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The classes of output row 2 of five rows of `n` columns whose red
    /// and blue minus green at column `x` are `chroma(x)`, red rows first,
    /// the red sites in column parity `rx`, samples `scale` times data on
    /// [0, 1].
    fn classes(n: usize, rx: usize, scale: f32, chroma: impl Fn(usize) -> (f32, f32)) -> Vec<u32> {
        let mut s = Saturation::new();
        let least = least_saturated(0.3, 1.0 / scale);
        for ty in 0..5 {
            let blue = ty % 2 == 1;
            let kind = RowKind {
                blue,
                chroma_parity: if blue { 1 - rx } else { rx },
            };
            let green = vec![0.5 * scale; n];
            let [red, blue]: [Vec<f32>; 2] = std::array::from_fn(|p| {
                let d = |x: usize| [chroma(x).0, chroma(x).1][p];
                (0..n).map(|x| scale * (0.5 + d(x))).collect()
            });
            let (own, other) = if kind.blue {
                (&blue, &red)
            } else {
                (&red, &blue)
            };
            s.push(kind, [own, &green, other], (ty, 0), (least, 100));
        }
        let mut class = vec![5; n];
        s.classes(2, &mut class, 2..n - 2);
        class
    }

    #[test]
    fn the_least_saturated_sum_decides_as_the_means_do() {
        for (threshold, scale) in [(0.3, 1.0), (0.3, 255.0), (0.3, 4095.0), (0.45, 65535.0)] {
            let inv = 1.0 / scale;
            let least = least_saturated(threshold, inv);
            assert!(mean(least, inv) >= threshold);
            assert!(mean(f32::from_bits(least.to_bits() - 1), inv) < threshold);
            // Sums a few thousand steps of the last bit either side.
            for k in 0..4000u32 {
                for sum in [least.to_bits() + k, least.to_bits() - k].map(f32::from_bits) {
                    assert_eq!(sum >= least, mean(sum, inv) >= threshold, "{sum}");
                }
            }
        }
        assert_eq!(least_saturated(0.0, 1.0), 0.0);
        assert_eq!(least_saturated(-1.0, 1.0), 0.0);
    }

    #[test]
    fn saturated_pixels_take_the_classes_past_the_offset() {
        let n = 40;
        for scale in [1.0, 255.0, 4095.0] {
            for rx in [0, 1] {
                // R - G grows along the row, B - G falls as fast: a
                // window's means are its centre's, 0.3 x / 20 in all, and
                // reach 0.3 past column 20. The corners lie between
                // columns `rx + 2k - 1` and `rx + 2k`, half a column from
                // the pixels they decide.
                let class = classes(n, rx, scale, |x| {
                    (0.3 * x as f32 / 40.0, -0.3 * x as f32 / 40.0)
                });
                let first = 21 - rx;
                for (x, &c) in class.iter().enumerate() {
                    let inside = (2..n - 2).contains(&x);
                    let want = if inside && x >= first { 105 } else { 5 };
                    assert_eq!(c, want, "column {x}, scale {scale}, red column {rx}");
                }
            }
        }
    }

    #[test]
    fn aliased_colour_that_alternates_is_not_saturation() {
        // |R - G| is 0.5 everywhere, but its sign alternates by column, as
        // a mosaic's false colour on fine grey detail does: the window's
        // mean is zero.
        let class = classes(30, 0, 255.0, |x| (if x % 2 == 0 { 0.5 } else { -0.5 }, 0.0));
        assert!(class.iter().all(|&c| c == 5));
        // The same colour, unchanging, is saturated.
        let class = classes(30, 0, 255.0, |_| (0.5, 0.0));
        assert!(class[2..28].iter().all(|&c| c == 105));
    }
}

//! How colourful a base is around each pixel, for the fusion's saturated
//! classes ([`super::raisr::Weights`] with two saturation bins,
//! [`super::raisr::Bank::saturation`]): the absolute values of the local
//! means of `R - G` and `B - G`, added.
//!
//! Where colours are saturated, the channels are weakly correlated, and
//! filters fitted on photographs (whose channels mostly move together) lean
//! on colour differences that no longer hold: on the held-out training
//! photographs with their chroma tripled, the fusion trailed MLRI by 0.6
//! dB. Filters of their own for such pixels recover most of it.
//!
//! The means are of *signed* differences over a 5x5 tent (two 3x3 box sums
//! in a row), so the false colour a mosaic aliases into on fine grey
//! detail, which alternates in sign from pixel to pixel, averages away
//! instead of sending the pixel to the saturated filters: the 3x3 mean of
//! `|R - G| + |B - G|` left 11 % more false colour on the grey zone plate
//! (the fusion alone, 6494 against 5875) for the same gain.
//!
//! The sums stream with the base's rows, as the structure tensor's do
//! ([`super::refined::Window`]): each row that comes adds the horizontal
//! 3-sums of its differences and completes the 3x3 sums of the row above
//! it, which are kept as their horizontal 3-sums; the output row two above
//! adds three of those. Each sum is taken once, in the training script's
//! order.

use super::raisr::PITCH;
use super::ring::Ring;
use super::RowKind;
use std::ops::Range;

/// Rows of each stage's sums kept: the three its next stage adds.
const DEPTH: usize = 3;

/// Plane `p` (`R - G`, then `B - G`) of a ring's row, its planes [`PITCH`]
/// apart.
fn difference_plane(row: &[f32], p: usize) -> &[f32] {
    &row[p * PITCH..(p + 1) * PITCH]
}

/// `(a + b) + c` of three sequences: every sum here, in the training
/// script's order, as loops the compiler vectorises.
#[inline(always)]
fn sum3<'a>(
    a: impl Iterator<Item = f32> + 'a,
    b: impl Iterator<Item = f32> + 'a,
    c: impl Iterator<Item = f32> + 'a,
) -> impl Iterator<Item = f32> + 'a {
    a.zip(b).zip(c).map(|((a, b), c)| (a + b) + c)
}

/// The sums of a row's values one column left, at and one right of each
/// column from `x` on.
#[inline(always)]
fn across(row: &[f32], x: usize) -> impl Iterator<Item = f32> + '_ {
    let from = |x: usize| row[x..].iter().copied();
    sum3(from(x - 1), from(x), from(x + 1))
}

/// The sums of plane `p` of three rows over columns `cols`, added.
#[inline(always)]
fn down<'a>(rows: [&'a [f32]; 3], p: usize, cols: Range<usize>) -> impl Iterator<Item = f32> + 'a {
    let [a, b, c] = rows.map(|r| difference_plane(r, p)[cols.clone()].iter().copied());
    sum3(a, b, c)
}

/// The running sums of the base's colour differences.
pub(super) struct Saturation {
    /// Each row's horizontal 3-sums of `R - G` and `B - G`.
    across: Ring,
    /// The horizontal 3-sums of the 3x3 sums (three rows of `across`,
    /// added): three rows of these, added, are the tent's sums.
    boxed: Ring,
    /// Room for a plane of a row's 3x3 sums.
    scratch: Vec<f32>,
}

impl Saturation {
    pub(super) fn new() -> Self {
        Saturation {
            across: Ring::new(2 * PITCH, DEPTH, 0),
            boxed: Ring::new(2 * PITCH, DEPTH, 0),
            scratch: vec![0.0; PITCH],
        }
    }

    /// Takes the base's (clamped) row `ty` of `kind`, its planes own
    /// chroma, green and other chroma `n` long, the base's rows starting at
    /// tile row `first` and sound in columns `first .. n - first` (a tile's
    /// base is as narrow as it is short).
    #[inline(always)]
    pub(super) fn push(
        &mut self,
        kind: RowKind,
        [own, green, other]: [&[f32]; 3],
        ty: usize,
        first: usize,
    ) {
        let n = green.len();
        let inner = first + 1..n - first - 1;
        let (red, blue) = if kind.blue {
            (other, own)
        } else {
            (own, other)
        };
        let row = self.across.row_mut(ty);
        for (p, chroma) in [red, blue].into_iter().enumerate() {
            let diff = |x: usize| chroma[x..].iter().zip(&green[x..]).map(|(c, g)| c - g);
            let (x, dst) = (
                inner.start,
                &mut row[p * PITCH..p * PITCH + n][inner.clone()],
            );
            for (d, v) in dst.iter_mut().zip(sum3(diff(x - 1), diff(x), diff(x + 1))) {
                *d = v;
            }
        }
        if ty >= first + 2 {
            let y = ty - 1;
            let rows = [y - 1, y, y + 1].map(|r| self.across.row(r));
            let (dst, boxed) = (self.boxed.row_mut(y), &mut self.scratch[..n]);
            for p in 0..2 {
                for (d, v) in boxed[inner.clone()]
                    .iter_mut()
                    .zip(down(rows, p, inner.clone()))
                {
                    *d = v;
                }
                let x = inner.start + 1;
                let dst = &mut dst[p * PITCH..p * PITCH + n][x..inner.end - 1];
                for (d, v) in dst.iter_mut().zip(across(boxed, x)) {
                    *d = v;
                }
            }
        }
    }

    /// Moves the columns `cols` of output row `y`'s `class` whose tent
    /// sums' absolute values add up to at least `least` (of
    /// [`least_saturated`]) to the saturated bin, `offset` classes on. The
    /// sums run in the training script's order (each row's three columns,
    /// then the rows), so the classes are its; `cols` lie two columns
    /// within the sound ones of [`Saturation::push`].
    #[inline(always)]
    pub(super) fn classes(
        &self,
        y: usize,
        (least, offset): (f32, u32),
        class: &mut [u32],
        cols: Range<usize>,
    ) {
        let rows = [y - 1, y, y + 1].map(|r| self.boxed.row(r));
        let sums = down(rows, 0, cols.clone()).zip(down(rows, 1, cols.clone()));
        for (k, (t0, t1)) in class[cols].iter_mut().zip(sums) {
            *k += if t0.abs() + t1.abs() >= least {
                offset
            } else {
                0
            };
        }
    }
}

/// What the training script compares with the saturated bin's threshold:
/// the tent sums' absolute values, added (`sum`, in the samples' scale),
/// as means on [0, 1] data (`inv_scale` of the samples) of the tent's 81
/// weights.
#[inline(always)]
fn mean(sum: f32, inv_scale: f32) -> f32 {
    sum * inv_scale / 9.0 / 9.0
}

/// The least sum whose [`mean`] reaches `threshold`, for a positive
/// `inv_scale`. Each rounding of [`mean`] is monotonic, so a sum is
/// saturated exactly when it reaches this one: each pixel then takes one
/// comparison instead of a product and two divisions.
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
    /// and blue minus green at column `x` are `chroma(x)`, alternately red
    /// and blue rows, samples `scale` times data on [0, 1].
    fn classes(n: usize, scale: f32, chroma: impl Fn(usize) -> (f32, f32)) -> Vec<u32> {
        let mut s = Saturation::new();
        for ty in 0..5 {
            let kind = RowKind {
                blue: ty % 2 == 1,
                chroma_parity: 0,
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
            s.push(kind, [own, &green, other], ty, 0);
        }
        let mut class = vec![5; n];
        s.classes(
            2,
            (least_saturated(0.3, 1.0 / scale), 100),
            &mut class,
            2..n - 2,
        );
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
            // R - G grows along the row, B - G falls as fast: the tent's
            // means are the centre's, 0.3 x / 20 in all.
            let class = classes(n, scale, |x| {
                (0.3 * x as f32 / 40.0, -0.3 * x as f32 / 40.0)
            });
            for (x, &c) in class.iter().enumerate() {
                let want = match x {
                    0 | 1 => 5,
                    x if x >= n - 2 => 5,
                    x if x < 20 => 5,
                    x if x > 20 => 105,
                    _ => c, // on the threshold: either, by rounding
                };
                assert_eq!(c, want, "column {x}, scale {scale}");
            }
        }
    }

    #[test]
    fn aliased_colour_that_alternates_is_not_saturation() {
        // |R - G| is 0.5 everywhere, but its sign alternates by column, as
        // a mosaic's false colour on fine grey detail does: the tent's
        // mean is 0.5 / 9.
        let class = classes(30, 255.0, |x| (if x % 2 == 0 { 0.5 } else { -0.5 }, 0.0));
        assert!(class.iter().all(|&c| c == 5));
        // The same colour, unchanging, is saturated.
        let class = classes(30, 255.0, |_| (0.5, 0.0));
        assert!(class[2..28].iter().all(|&c| c == 105));
    }
}

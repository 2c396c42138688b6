//! Fixed-point positions stepped along one cell of the position grid
//! (`PositionGrid::fill_row`): a cell's pixels are evenly spaced, so their
//! six coordinates (x and y of R, G and B) advance by constant integer
//! steps, one addition each instead of an interpolation.
//!
//! The running values carry [`STEP_BITS`] fractional bits beyond the
//! sampler's and are kept biased by 2^47 so that they are never negative:
//! rounding to the sampler's fixed point is then a logical shift, which
//! AVX2 has for 64-bit lanes (it has no arithmetic one), and both paths
//! compute the same integers.

use std::ops::Range;

/// Fractional bits beyond the sampler's of the positions stepped along a
/// cell: a 16 px cell accumulates at most 8 roundings of 2^-17, so a
/// position differs from the rounded exact interpolation only when that
/// lies within ~2^-13 of the sampler's (1/256 px) rounding tie.
pub(super) const STEP_BITS: u32 = 16;

/// The bias of the running values: positions are below 2^22 px, i.e.
/// 2^46 in units of 2^-24 px, so biased they stay within `(0, 2^48)`.
const BIAS: u64 = 1 << 47;

/// `BIAS` after the shift, in the 32 bits of a position.
const BIAS_SHIFTED: u32 = (BIAS >> STEP_BITS) as u32;

/// `x` rounded to the nearest integer (ties to even) without a libm call
/// (baseline x86-64 has no rounding instruction): adding 1.5 · 2^52 leaves
/// no fractional bits, and the sum, in `[2^52, 2^53)` where one unit of the
/// last place is 1, has bits that exceed the constant's by exactly the
/// integer. Exact for `|x| < 2^51`. Integer arithmetic on the bits rather
/// than a float-to-integer cast, which Rust saturates with compares and
/// selects per value (most of the cell setup's instructions in a profile).
#[inline(always)]
pub(super) fn nearest(x: f64) -> i64 {
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    ((x + MAGIC).to_bits() as i64).wrapping_sub(MAGIC.to_bits() as i64)
}

/// One cell of a row: coordinate `k` of its `p`-th pixel is
/// `(start[k] + p · step[k] + 2^15) >> STEP_BITS`, the sampler's fixed point
/// rounded half up. `start` and every value reached lie below 2^46 in
/// magnitude.
#[derive(Debug, Clone)]
pub(super) struct Cell {
    /// The row's pixels the cell covers.
    pub(super) pixels: Range<usize>,
    pub(super) start: [i64; 6],
    pub(super) step: [i64; 6],
}

/// Writes the positions of every cell's pixels into `out` (six per pixel
/// of the row): one dispatch per row, as the cells are short.
pub(super) fn step_cells(cells: &[Cell], out: &mut [i32]) {
    #[cfg(target_arch = "x86_64")]
    if crate::cpu::has_avx2() {
        // SAFETY: AVX2 was detected just above.
        return unsafe { avx2::step_cells(cells, out) };
    }
    for cell in cells {
        let (at, step) = biased(cell);
        scalar(
            at,
            step,
            &mut out[6 * cell.pixels.start..6 * cell.pixels.end],
        );
    }
}

/// The cell's first values biased, and its steps, as the loops add them.
/// (Plain loops: `array::map` was not inlined, a call per cell.)
#[inline(always)]
fn biased(cell: &Cell) -> ([u64; 6], [u64; 6]) {
    let (mut at, mut step) = ([0; 6], [0; 6]);
    for k in 0..6 {
        at[k] = ((cell.start[k] + (1 << (STEP_BITS - 1))) as u64).wrapping_add(BIAS);
        step[k] = cell.step[k] as u64;
    }
    (at, step)
}

/// The positions of a cell from its biased first values, one at a time.
fn scalar(mut at: [u64; 6], step: [u64; 6], out: &mut [i32]) {
    for q in out.chunks_exact_mut(6) {
        for k in 0..6 {
            q[k] = unbias(at[k]);
            at[k] = at[k].wrapping_add(step[k]);
        }
    }
}

/// A biased running value to the sampler's fixed point.
#[inline(always)]
fn unbias(at: u64) -> i32 {
    ((at >> STEP_BITS) as u32).wrapping_sub(BIAS_SHIFTED) as i32
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    use super::{Cell, BIAS, BIAS_SHIFTED, STEP_BITS};

    /// [`super::step_cells`] with two pixels (12 values, three registers of
    /// four) per iteration and a cell's odd last pixel from the first six
    /// of them. The registers are set up from the cell's arrays with four
    /// loads and a few vector additions: built from 24 scalar values, the
    /// set-up took about as many instructions as stepping the cell's 8-16
    /// pixels (a count of the generated code, not a timing).
    ///
    /// # Safety
    /// AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn step_cells(cells: &[Cell], out: &mut [i32]) {
        let low_halves = _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6);
        let bias = _mm256_set1_epi32(BIAS_SHIFTED as i32);
        // The sampler's rounding half and the bias, as `super::biased` adds them.
        let first = _mm256_set1_epi64x((1i64 << (STEP_BITS - 1)).wrapping_add(BIAS as i64));
        // The sampler's fixed point of four running values, in the low
        // half of a register.
        let positions = |v: __m256i| {
            let shifted = _mm256_srli_epi64(v, STEP_BITS as i32);
            let lows = _mm256_permutevar8x32_epi32(shifted, low_halves);
            _mm256_castsi256_si128(_mm256_sub_epi32(lows, bias))
        };
        for cell in cells {
            let out = &mut out[6 * cell.pixels.start..6 * cell.pixels.end];
            // SAFETY: values 0-3 and 2-5 of arrays of six.
            let load =
                |a: &[i64; 6], i: usize| unsafe { _mm256_loadu_si256(a.as_ptr().add(i).cast()) };
            let (start, step) = (
                [0, 2].map(|i| _mm256_add_epi64(load(&cell.start, i), first)),
                [0, 2].map(|i| load(&cell.step, i)),
            );
            let twice = step.map(|s| _mm256_add_epi64(s, s));
            // Values 0-3 of pixel 0; 4, 5 of pixel 0 and 0, 1 of pixel 1;
            // 2-5 of pixel 1. Each advances by two steps.
            let second = _mm256_add_epi64(start[0], step[0]);
            let mut v = [
                start[0],
                _mm256_permute2x128_si256::<0x21>(start[1], second),
                _mm256_add_epi64(start[1], step[1]),
            ];
            let d = [
                twice[0],
                _mm256_permute2x128_si256::<0x21>(twice[1], twice[0]),
                twice[1],
            ];
            let pairs = out.len() / 12;
            let dst = out.as_mut_ptr();
            for p in 0..pairs {
                for (r, (v, d)) in v.iter_mut().zip(&d).enumerate() {
                    // SAFETY: pair p writes values 12p .. 12p + 12 of `out`.
                    unsafe { _mm_storeu_si128(dst.add(12 * p + 4 * r).cast(), positions(*v)) };
                    *v = _mm256_add_epi64(*v, *d);
                }
            }
            if !out.len().is_multiple_of(12) {
                // SAFETY: the odd last pixel's six values follow the pairs'.
                unsafe {
                    _mm_storeu_si128(dst.add(12 * pairs).cast(), positions(v[0]));
                    _mm_storel_epi64(dst.add(12 * pairs + 4).cast(), positions(v[1]));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rounds_ties_to_even_and_keeps_large_values() {
        for (x, want) in [
            (0.4, 0),
            (0.5, 0),
            (1.5, 2),
            (-0.5, 0),
            (-1.6, -2),
            (2.7e13, 27_000_000_000_000),
        ] {
            assert_eq!(nearest(x), want, "{x}");
        }
        assert_eq!(nearest(-(1i64 << 46) as f64 - 0.75), -(1i64 << 46) - 1);
        // Over the positions' whole range, halves and near-halves included.
        for e in 0..46 {
            for x in [
                2f64.powi(e) * 1.37,
                -(2f64.powi(e)) * 1.37,
                (1u64 << e) as f64,
            ] {
                for t in [x, x + 0.5, x - 0.5, x + 0.499_999_9, x + 1.5] {
                    assert_eq!(nearest(t), t.round_ties_even() as i64, "{t}");
                }
            }
        }
    }

    #[test]
    fn both_paths_step_to_the_exact_multiples() {
        // Negative and positive positions and steps, near the ends of the
        // range, over even and odd pixel counts, cells side by side.
        let start = [-(1i64 << 45), 123_456_789, -5, (1 << 45) + 77, 0, -65_536];
        let step = [16_777_216, -16_777_300, 1, -3_000_000, 65_535, -65_537];
        let mut cells = Vec::new();
        let mut first = 0;
        for (c, n) in [0, 1, 2, 7, 16, 17].into_iter().enumerate() {
            let shift = c as i64 * 1_000_003;
            cells.push(Cell {
                pixels: first..first + n,
                start: start.map(|s| s + shift),
                step: step.map(|s| s - shift / 1000),
            });
            first += n;
        }
        let mut fast = vec![0; 6 * first];
        step_cells(&cells, &mut fast);
        let mut slow = vec![0; 6 * first];
        for cell in &cells {
            let (at, step) = biased(cell);
            scalar(
                at,
                step,
                &mut slow[6 * cell.pixels.start..6 * cell.pixels.end],
            );
        }
        assert_eq!(fast, slow);
        for cell in &cells {
            for (p, u) in cell.pixels.clone().enumerate() {
                for k in 0..6 {
                    let want = (cell.start[k] + p as i64 * cell.step[k] + (1 << 15)) >> STEP_BITS;
                    assert_eq!(i64::from(fast[6 * u + k]), want, "pixel {u}, value {k}");
                }
            }
        }
    }
}

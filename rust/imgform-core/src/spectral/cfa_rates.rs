//! The rates of a row of photosites behind a colour filter array, from a
//! row of a spectral image: each site integrates its spectrum against the
//! one response of its filter's channel.
//!
//! A 24 MP image of 41 samples is 3.9 GB of float32. Once the read runs
//! behind the sensor's noise (see `ahead`), what is left of this kernel's
//! cost is its own instructions, so they are few. The dot product is in
//! f32 with fused multiply-adds over eight lanes (one AVX2 register,
//! written with intrinsics: the compiler does not vectorise a loop of
//! runtime length into one register's lanes), and eight pixels run side
//! by side, so that their independent chains fill the pipeline where one
//! pixel's would wait on each multiply-add's latency, and their lane sums
//! share the shuffles of one transposition. The last `L % 8` samples of a
//! pixel take one masked load, and the check of the samples costs one OR
//! a register: it only has to be cheap when every sample is valid (see
//! [`group_avx2`]); a group that fails it is checked again sample by
//! sample. The samples and responses are >= 0, so no term cancels
//! another, and the f32 result is within `(ceil(L / 8) + 4) 2^-24`
//! relative of the exact sum (for 41 samples: 6 roundings along a lane, 3
//! in the final tree, 1 of the response to f32): 6e-7. At the 20 000 e- of
//! a full well that is 0.01 e-, four orders of magnitude below the shot
//! noise of 141 e-.

use super::{all_valid, has_avx2_fma};

/// Lanes of the dot product: eight f32 fill an AVX2 register.
const DOT_LANES: usize = 8;

/// Pixels whose dot products [`group_avx2`] runs side by side: eight
/// accumulators are eight registers of the sixteen, and their lane sums
/// make exactly one register of results.
#[cfg(target_arch = "x86_64")]
const GROUP: usize = 8;

/// The lanes' starting values: the products of the last `len % 8` terms
/// (lane `j` takes the `j`-th of them), zero in the other lanes.
#[inline(always)]
fn tail_products(x: &[f32], w: &[f32]) -> [f32; DOT_LANES] {
    let mut acc = [0.0f32; DOT_LANES];
    let tail = x.len() / DOT_LANES * DOT_LANES;
    for (a, (&xt, &wt)) in acc.iter_mut().zip(x[tail..].iter().zip(&w[tail..])) {
        *a = xt * wt;
    }
    acc
}

/// The lanes summed by a fixed tree.
#[inline(always)]
fn lane_sum(acc: [f32; DOT_LANES]) -> f32 {
    let quad = [
        acc[0] + acc[4],
        acc[1] + acc[5],
        acc[2] + acc[6],
        acc[3] + acc[7],
    ];
    (quad[0] + quad[2]) + (quad[1] + quad[3])
}

/// `Σ x_i w_i` in f32, and whether every `x_i` is a valid sample: lane
/// `j` starts from [`tail_products`] and accumulates the terms `8 c + j`
/// of the full chunks `c` in order with fused multiply-adds, then
/// [`lane_sum`] adds the lanes. The order depends only on the length, so
/// [`group_avx2`] and this scalar form (software `fma`, slower but
/// correctly rounded too) give the same bits.
#[inline(always)]
fn dot_checked(x: &[f32], w: &[f32]) -> (f32, bool) {
    let mut acc = tail_products(x, w);
    for (xc, wc) in x.chunks_exact(DOT_LANES).zip(w.chunks_exact(DOT_LANES)) {
        for ((a, &xv), &wv) in acc.iter_mut().zip(xc).zip(wc) {
            *a = xv.mul_add(wv, *a);
        }
    }
    (lane_sum(acc), all_valid(x))
}

/// The three channels' responses `(3, L)` in f32, and for [`group_avx2`]'s
/// masked tail each channel's last `L % 8` weights in lanes `0 .. L % 8`
/// (zeros after), with the mask of those lanes.
pub(super) struct Responses {
    weights: Vec<f32>,
    grid_len: usize,
    tails: [[f32; DOT_LANES]; 3],
    tail_lanes: [i32; DOT_LANES],
}

impl Responses {
    /// `response`: `(3, grid_len)` e-/s per unit of the samples, checked by
    /// the caller; `grid_len > 0`. f32 keeps the dot product cheap; its
    /// rounding is far below the shot noise (see the module's docs).
    pub(super) fn new(response: &[f64], grid_len: usize) -> Self {
        let weights: Vec<f32> = response.iter().map(|&v| v as f32).collect();
        let tail = grid_len % DOT_LANES;
        let mut tails = [[0.0; DOT_LANES]; 3];
        for (t, w) in tails.iter_mut().zip(weights.chunks_exact(grid_len)) {
            t[..tail].copy_from_slice(&w[grid_len - tail..]);
        }
        let mut tail_lanes = [0; DOT_LANES];
        tail_lanes[..tail].fill(-1);
        Self {
            weights,
            grid_len,
            tails,
            tail_lanes,
        }
    }

    /// Channel `c`'s weights.
    #[inline(always)]
    fn channel(&self, c: u8) -> &[f32] {
        let c = usize::from(c);
        &self.weights[c * self.grid_len..(c + 1) * self.grid_len]
    }
}

/// The CFA channels of a row's pixels from column `x0` on: `colors`, the
/// channels of one period of the row, repeated from the phase of `x0`.
pub(super) fn colors_from(colors: &[u8], x0: usize) -> impl Iterator<Item = &u8> + Clone {
    colors.iter().cycle().skip(x0 % colors.len())
}

/// Fills `rates[from..]` with the rate of each of those sites of a run of
/// a row, one [`dot_checked`] each (see [`row`] for the arguments), and
/// returns the offset of the first of them with bad input.
#[inline(always)]
fn pixels_from(
    from: usize,
    src: &[f32],
    (colors, x0): (&[u8], usize),
    responses: &Responses,
    rates: &mut [f64],
) -> Option<usize> {
    let len = responses.grid_len;
    let pixels = src[from * len..]
        .chunks_exact(len)
        .zip(colors_from(colors, x0 + from));
    let mut first_bad = None;
    for (x, (r, (px, &c))) in rates[from..].iter_mut().zip(pixels).enumerate() {
        let (rate, valid) = dot_checked(px, responses.channel(c));
        *r = f64::from(rate);
        if !valid {
            first_bad = first_bad.or(Some(from + x));
        }
    }
    first_bad
}

/// [`lane_sum`] of [`GROUP`] accumulators at once, pixel `p`'s sum in
/// lane `p`: the halves of each register added (`acc[j] + acc[j + 4]`),
/// then the pairs `(0, 2)` and `(1, 3)` of the quads, then those two: the
/// same additions in the same order, transposed: fourteen shuffles and
/// seven additions for the eight pixels, where one pixel at a time took
/// six dependent steps of its own.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn lane_sums(acc: [std::arch::x86_64::__m256; GROUP]) -> std::arch::x86_64::__m256 {
    use std::arch::x86_64::*;
    // Pixels p and p + 4's quads, in the low and high halves.
    let quads = |p: usize| {
        _mm256_add_ps(
            _mm256_permute2f128_ps::<0x20>(acc[p], acc[p + 4]),
            _mm256_permute2f128_ps::<0x31>(acc[p], acc[p + 4]),
        )
    };
    // Two registers of quads `a, b` -> `[a0 + a2, a1 + a3, b0 + b2, b1 + b3]`
    // in each half.
    let pairs = |a, b| {
        _mm256_add_ps(
            _mm256_shuffle_ps::<0b01_00_01_00>(a, b),
            _mm256_shuffle_ps::<0b11_10_11_10>(a, b),
        )
    };
    let low = pairs(quads(0), quads(1));
    let high = pairs(quads(2), quads(3));
    _mm256_add_ps(
        _mm256_shuffle_ps::<0b10_00_10_00>(low, high),
        _mm256_shuffle_ps::<0b11_01_11_01>(low, high),
    )
}

/// The rates of [`GROUP`] pixels `x` (`len` samples each, `len` the
/// responses' grid length) of channels `channels` into `rates`: each is
/// [`dot_checked`]'s sum, bit for bit. Returns `false` when a pixel may
/// have a bad sample, so that the caller checks them one by one.
///
/// The check costs one OR a register: a sample is bad when negative, NaN
/// or infinite, and the sign bits ORed over every sample catch the
/// negatives (and -0, a valid sample the caller's recheck lets through),
/// while a NaN or infinite sample makes its pixel's sum NaN or infinite
/// (the weights being finite and >= 0), which one compare of the sums
/// catches; a sum that overflows from valid samples also fails, and is
/// cleared by the recheck too.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn group_avx2(
    x: &[f32],
    len: usize,
    channels: [u8; GROUP],
    responses: &Responses,
    rates: &mut [f64],
) -> bool {
    use std::arch::x86_64::*;
    let pixels: [*const f32; GROUP] = std::array::from_fn(|p| x[p * len..][..len].as_ptr());
    let weights: [*const f32; GROUP] =
        std::array::from_fn(|p| responses.channel(channels[p])[..len].as_ptr());
    let rates = &mut rates[..GROUP];
    let whole = len / DOT_LANES * DOT_LANES;
    let zero = _mm256_setzero_ps();
    let mut acc = [zero; GROUP];
    // Two registers of sign bits, so that the ORs are two chains.
    let mut signs = [zero; 2];
    if whole < len {
        let lanes = _mm256_loadu_si256(responses.tail_lanes.as_ptr().cast());
        for (p, a) in acc.iter_mut().enumerate() {
            // SAFETY: the mask enables lanes `0 .. len - whole` only,
            // samples `whole .. len` of pixel `p`: inside `x` (a masked
            // lane is neither read nor able to fault).
            let tail = unsafe { _mm256_maskload_ps(pixels[p].add(whole), lanes) };
            let w = &responses.tails[usize::from(channels[p])];
            // SAFETY: `w` is eight readable floats (an unaligned load).
            *a = _mm256_mul_ps(tail, unsafe { _mm256_loadu_ps(w.as_ptr()) });
            signs[p % 2] = _mm256_or_ps(signs[p % 2], tail);
        }
    }
    for k in (0..whole).step_by(DOT_LANES) {
        for (p, a) in acc.iter_mut().enumerate() {
            // SAFETY: `k + 8 <= whole <= len`, and `pixels[p]` and
            // `weights[p]` start `len` readable floats (sliced above).
            let (v, w) = unsafe {
                (
                    _mm256_loadu_ps(pixels[p].add(k)),
                    _mm256_loadu_ps(weights[p].add(k)),
                )
            };
            *a = _mm256_fmadd_ps(v, w, *a);
            signs[p % 2] = _mm256_or_ps(signs[p % 2], v);
        }
    }
    let sums = lane_sums(acc);
    let finite = _mm256_cmp_ps::<_CMP_LE_OQ>(sums, _mm256_set1_ps(f32::MAX));
    let fine = _mm256_andnot_ps(_mm256_or_ps(signs[0], signs[1]), finite);
    let (low, high) = rates.split_at_mut(GROUP / 2);
    // SAFETY: `low` and `high` are four writable f64 each.
    unsafe {
        _mm256_storeu_pd(
            low.as_mut_ptr(),
            _mm256_cvtps_pd(_mm256_castps256_ps128(sums)),
        );
        _mm256_storeu_pd(
            high.as_mut_ptr(),
            _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(sums)),
        );
    }
    _mm256_movemask_ps(fine) == 0xFF
}

/// [`row`] by [`group_avx2`], `len` the grid length (a constant where the
/// caller specialises on it), the last `rates.len() % 8` pixels by
/// [`pixels_from`].
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn groups_avx2(
    len: usize,
    src: &[f32],
    (colors, x0): (&[u8], usize),
    responses: &Responses,
    rates: &mut [f64],
) -> Option<usize> {
    let mut phase = x0 % colors.len();
    let mut first_bad = None;
    let groups = src
        .chunks_exact(GROUP * len)
        .zip(rates.chunks_exact_mut(GROUP));
    for (g, (x, r)) in groups.enumerate() {
        // The period walked without a division per pixel.
        let channels = std::array::from_fn(|_| {
            let c = colors[phase];
            phase = if phase + 1 == colors.len() {
                0
            } else {
                phase + 1
            };
            c
        });
        // SAFETY: the caller vouches for AVX2 and FMA.
        if !unsafe { group_avx2(x, len, channels, responses, r) } && first_bad.is_none() {
            let bad = x.chunks_exact(len).position(|px| !all_valid(px));
            first_bad = bad.map(|p| g * GROUP + p);
        }
    }
    let rest = pixels_from(
        rates.len() / GROUP * GROUP,
        src,
        (colors, x0),
        responses,
        rates,
    );
    first_bad.or(rest)
}

/// [`groups_avx2`] for this grid's length, compiled apart for the default
/// grids' 41 and 81 samples (380-780 nm every 10 and 5 nm): with the
/// length a constant, the chunk loop unrolls and every load's offset is an
/// immediate.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn row_avx2(
    src: &[f32],
    colors: (&[u8], usize),
    responses: &Responses,
    rates: &mut [f64],
) -> Option<usize> {
    // SAFETY: the caller vouches for AVX2 and FMA.
    unsafe {
        match responses.grid_len {
            41 => groups_avx2(41, src, colors, responses, rates),
            81 => groups_avx2(81, src, colors, responses, rates),
            len => groups_avx2(len, src, colors, responses, rates),
        }
    }
}

/// Fills `rates` with the rate of each site of a run of a row: `src` holds
/// the run's spectra (`L` samples per pixel), `colors` the CFA channels of
/// one period of the row and the run's first column (see [`colors_from`]).
/// Returns the offset of the first pixel with a negative or non-finite
/// sample. The widest vector unit the CPU has does the work; the same bits
/// either way.
pub(super) fn row(
    src: &[f32],
    colors: (&[u8], usize),
    responses: &Responses,
    rates: &mut [f64],
) -> Option<usize> {
    #[cfg(target_arch = "x86_64")]
    if has_avx2_fma() {
        // SAFETY: AVX2 and FMA support was detected just above.
        return unsafe { row_avx2(src, colors, responses, rates) };
    }
    pixels_from(0, src, colors, responses, rates)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A spectrum-like row: `w` pixels of `l` samples, positive, varied.
    fn spectra(w: usize, l: usize) -> Vec<f32> {
        (0..w * l)
            .map(|i| 0.1 + ((i * 7919) % 1000) as f32 / 333.0)
            .collect()
    }

    /// Responses of `l` samples, different in each channel.
    fn responses(l: usize) -> Responses {
        let response: Vec<f64> = (0..3 * l).map(|i| (i % 13) as f64 * 0.37).collect();
        Responses::new(&response, l)
    }

    /// A run of X-Trans-like channels, period 6.
    const COLORS: [u8; 6] = [1, 0, 2, 1, 1, 2];

    #[test]
    fn the_f32_dot_is_within_its_bound_of_the_exact_sum() {
        for l in [1, 7, 8, 9, 16, 31, 41, 81] {
            let x = spectra(1, l);
            let w: Vec<f32> = (0..l).map(|i| 1.0 / (i as f32 + 1.7)).collect();
            let exact: f64 = x
                .iter()
                .zip(&w)
                .map(|(a, b)| f64::from(*a) * f64::from(*b))
                .sum();
            let bound = (l.div_ceil(8) + 3) as f64 * f64::from(f32::EPSILON) / 2.0;
            let got = f64::from(dot_checked(&x, &w).0);
            assert!((got / exact - 1.0).abs() <= bound, "{l}: {got} vs {exact}");
        }
    }

    /// [`row`]'s rates and verdict through AVX2 and pixel by pixel.
    fn both_ways(src: &[f32], x0: usize, r: &Responses) -> [(Vec<u64>, Option<usize>); 2] {
        let w = src.len() / r.grid_len;
        let (mut scalar, mut wide) = (vec![0.0; w], vec![0.0; w]);
        let scalar_bad = pixels_from(0, src, (&COLORS, x0), r, &mut scalar);
        // SAFETY: the callers checked AVX2 and FMA support.
        let wide_bad = unsafe { row_avx2(src, (&COLORS, x0), r, &mut wide) };
        let bits = |v: Vec<f64>| v.into_iter().map(f64::to_bits).collect();
        [(bits(scalar), scalar_bad), (bits(wide), wide_bad)]
    }

    #[test]
    fn the_avx2_groups_give_the_scalar_bits_for_every_length_and_phase() {
        if !has_avx2_fma() {
            return;
        }
        // Lengths with and without whole chunks and tails, both
        // specialised ones; 37 pixels: four groups and five alone.
        for l in [1, 5, 7, 8, 9, 16, 17, 41, 81] {
            let r = responses(l);
            let src = spectra(37, l);
            for x0 in [0, 1, 5] {
                let [scalar, wide] = both_ways(&src, x0, &r);
                assert_eq!(scalar, wide, "{l} samples from column {x0}");
                assert_eq!(wide.1, None);
            }
        }
        // Column 4 is channel 1 (COLORS[4]), against the f64 sum.
        let (l, r) = (41, responses(41));
        let src = spectra(37, l);
        let mut rates = vec![0.0; 37];
        row(&src, (&COLORS, 0), &r, &mut rates);
        let want: f64 = src[4 * l..5 * l]
            .iter()
            .zip(r.channel(1))
            .map(|(a, b)| f64::from(*a) * f64::from(*b))
            .sum();
        assert!((rates[4] / want - 1.0).abs() < 1e-6);
    }

    #[test]
    fn every_kind_of_bad_sample_is_caught_where_it_is() {
        if !has_avx2_fma() {
            return;
        }
        // Bad values in a whole chunk and in the tail, in a group and
        // among the last pixels; -0 is a valid 0, and so are samples whose
        // sum overflows f32 (the recheck clears both).
        let bad = [-1.0, -1e-30, f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
        for l in [5, 17, 41] {
            let r = responses(l);
            for (value, at) in bad.iter().flat_map(|&v| [(v, 3), (v, l - 1)]) {
                for pixel in [2, 9, 34] {
                    let mut src = spectra(37, l);
                    src[pixel * l + at] = value;
                    src[35 * l] = -2.0;
                    let [scalar, wide] = both_ways(&src, 1, &r);
                    assert_eq!(wide.1, Some(pixel), "{value} in {pixel} at {at} of {l}");
                    assert_eq!(scalar, wide);
                }
            }
            let mut src = spectra(37, l);
            src[3 * l + l - 1] = -0.0;
            src[4 * l..5 * l].fill(f32::MAX);
            let [scalar, wide] = both_ways(&src, 0, &r);
            assert_eq!(wide.1, None, "{l}");
            assert_eq!(scalar, wide);
        }
    }

    #[test]
    fn the_first_bad_column_is_reported() {
        for l in [5, 9] {
            let w = 10;
            let mut src = spectra(w, l);
            src[6 * l + l - 1] = -1.0;
            src[8 * l] = f32::NAN;
            let mut rates = vec![0.0; w];
            let responses = Responses::new(&vec![1.0; 3 * l], l);
            let bad = row(&src, (&[0], 0), &responses, &mut rates);
            assert_eq!(bad, Some(6), "{l} samples");
        }
    }

    #[test]
    fn colors_repeat_from_the_phase_of_the_first_column() {
        let colors = [0u8, 1, 2];
        let run: Vec<u8> = colors_from(&colors, 7).take(5).copied().collect();
        assert_eq!(run, [1, 2, 0, 1, 2]);
    }
}

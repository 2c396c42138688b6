//! The rates of a row of photosites behind a colour filter array, from a
//! row of a spectral image: each site integrates its spectrum against the
//! one response of its filter's channel.
//!
//! A 24 MP image of 41 samples is 3.9 GB of float32, so this kernel is
//! bound by reading it once: the dot product is in f32 with fused
//! multiply-adds over eight lanes (one AVX2 register, written with
//! intrinsics: the compiler does not vectorise a loop of runtime length
//! into one register's lanes), and the check of the samples rides along in
//! the same registers. Once the read runs behind the sensor's noise (see
//! `ahead`), the kernel's own instructions are what is left of its cost,
//! so the last `L % 8` samples take one load of the pixel's last eight
//! rather than a loop of their own. The samples and responses are >= 0, so no term cancels
//! another, and the f32 result is within `(ceil(L / 8) + 4) 2^-24` relative
//! of the exact sum (for 41 samples: 6 roundings along a lane, 3 in the
//! final tree, 1 of the response to f32): 6e-7. At the 20 000 e- of a full well that is 0.01 e-,
//! four orders of magnitude below the shot noise of 141 e-.

use super::{all_valid, has_avx2_fma};

/// Lanes of the dot product: eight f32 fill an AVX2 register.
const DOT_LANES: usize = 8;

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
/// [`dot_avx2`] and this scalar form (software `fma`, slower but correctly
/// rounded too) give the same bits.
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

/// The three channels' responses `(3, L)` in f32, and each channel's last
/// `L % 8` weights laid out for [`dot_avx2`]'s tail: in the last lanes of
/// eight, after zeros, to meet the pixel's last eight samples.
pub(super) struct Responses {
    weights: Vec<f32>,
    grid_len: usize,
    tails: [[f32; DOT_LANES]; 3],
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
            t[DOT_LANES - tail..].copy_from_slice(&w[grid_len - tail..]);
        }
        Self {
            weights,
            grid_len,
            tails,
        }
    }

    /// Channel `c`'s weights.
    #[inline(always)]
    fn channel(&self, c: u8) -> &[f32] {
        let c = usize::from(c);
        &self.weights[c * self.grid_len..(c + 1) * self.grid_len]
    }
}

/// [`dot_checked`] with the multiply-adds and checks in one AVX2 register
/// each (a sample is valid when `0 <= v <= f32::MAX`, which NaN fails, as
/// [`all_valid`] has it). The tail's products come from the pixel's last
/// eight samples times `tail` (the channel's [`Responses::tails`]), kept in
/// the tail's lanes and rotated to lanes `0 .. L % 8`, where
/// [`tail_products`] puts them; the samples before the tail are checked
/// twice, which changes nothing.
///
/// # Safety
/// The CPU must support AVX2 and FMA, and `x.len() >= 8`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn dot_avx2(x: &[f32], w: &[f32], tail: &[f32; DOT_LANES]) -> (f32, bool) {
    use std::arch::x86_64::*;
    let load = |chunk: &[f32]| {
        let lanes: &[f32; DOT_LANES] = chunk.try_into().expect("a chunk of eight");
        // SAFETY: `lanes` is eight readable floats (an unaligned load).
        unsafe { _mm256_loadu_ps(lanes.as_ptr()) }
    };
    let (zero, max) = (_mm256_setzero_ps(), _mm256_set1_ps(f32::MAX));
    let in_range = |v| {
        _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GE_OQ>(v, zero),
            _mm256_cmp_ps::<_CMP_LE_OQ>(v, max),
        )
    };
    let n = x.len();
    let last = load(&x[n - DOT_LANES..]);
    // Lane j takes lane (j + 8 - t) % 8; the lanes from t on are cleared
    // (an AND, so that they are +0 as in `tail_products`, never -0).
    let t = (n % DOT_LANES) as i32;
    let lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let from = _mm256_and_si256(
        _mm256_add_epi32(lane, _mm256_set1_epi32(8 - t)),
        _mm256_set1_epi32(7),
    );
    let kept = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(t), lane));
    let products = _mm256_mul_ps(last, load(tail));
    let mut acc = _mm256_and_ps(_mm256_permutevar8x32_ps(products, from), kept);
    let mut valid = in_range(last);
    for (xc, wc) in x.chunks_exact(DOT_LANES).zip(w.chunks_exact(DOT_LANES)) {
        let v = load(xc);
        acc = _mm256_fmadd_ps(v, load(wc), acc);
        valid = _mm256_and_ps(valid, in_range(v));
    }
    let mut lanes = [0.0f32; DOT_LANES];
    // SAFETY: `lanes` is eight writable floats (an unaligned store).
    unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), acc) };
    (lane_sum(lanes), _mm256_movemask_ps(valid) == 0xFF)
}

/// The CFA channels of a row's pixels from column `x0` on: `colors`, the
/// channels of one period of the row, repeated from the phase of `x0`.
pub(super) fn colors_from(colors: &[u8], x0: usize) -> impl Iterator<Item = &u8> + Clone {
    colors.iter().cycle().skip(x0 % colors.len())
}

/// Fills `rates` with the rate of each site of a run of a row: `src` holds
/// the run's spectra (`L` samples per pixel), `colors` the CFA channel of
/// each of its pixels ([`colors_from`]), `dot(samples, c)` the checked dot
/// product with channel `c`'s response ([`dot_checked`] or [`dot_avx2`]).
/// Returns the offset of the first pixel with a negative or non-finite
/// sample.
#[inline(always)]
fn row_with<'c>(
    dot: impl Fn(&[f32], u8) -> (f32, bool),
    src: &[f32],
    colors: impl Iterator<Item = &'c u8>,
    grid_len: usize,
    rates: &mut [f64],
) -> Option<usize> {
    let mut first_bad = None;
    let pixels = src.chunks_exact(grid_len).zip(colors);
    for (x, (r, (px, &c))) in rates.iter_mut().zip(pixels).enumerate() {
        let (rate, valid) = dot(px, c);
        *r = f64::from(rate);
        if !valid {
            first_bad = first_bad.or(Some(x));
        }
    }
    first_bad
}

/// [`row_with`] [`dot_avx2`].
///
/// # Safety
/// The CPU must support AVX2 and FMA, and the grid have at least 8 samples.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn row_avx2<'c>(
    src: &[f32],
    colors: impl Iterator<Item = &'c u8>,
    responses: &Responses,
    rates: &mut [f64],
) -> Option<usize> {
    // SAFETY: the caller vouches for AVX2, FMA and the grid's length.
    let dot = |x: &[f32], c| unsafe {
        dot_avx2(x, responses.channel(c), &responses.tails[usize::from(c)])
    };
    row_with(dot, src, colors, responses.grid_len, rates)
}

/// The rates of a run of a row (see [`row_with`]) through the widest
/// vector unit the CPU has; the same bits either way.
pub(super) fn row<'c>(
    src: &[f32],
    colors: impl Iterator<Item = &'c u8>,
    responses: &Responses,
    rates: &mut [f64],
) -> Option<usize> {
    #[cfg(target_arch = "x86_64")]
    if has_avx2_fma() && responses.grid_len >= DOT_LANES {
        // SAFETY: AVX2 and FMA support was detected just above, and the
        // grid is long enough.
        return unsafe { row_avx2(src, colors, responses, rates) };
    }
    let dot = |x: &[f32], c| dot_checked(x, responses.channel(c));
    row_with(dot, src, colors, responses.grid_len, rates)
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

    /// [`dot_avx2`] of `x` with the response of channel 0 of `responses`.
    fn dot_wide(x: &[f32], responses: &Responses) -> (f32, bool) {
        // SAFETY: the callers checked AVX2 and FMA support, and pass at
        // least eight samples.
        unsafe { dot_avx2(x, responses.channel(0), &responses.tails[0]) }
    }

    #[test]
    fn the_avx2_dot_gives_the_scalar_bits_and_verdict() {
        if !has_avx2_fma() {
            return;
        }
        let x = spectra(3, 41);
        let w: Vec<f64> = (0..x.len()).map(|i| 1.0 / (i as f64 + 1.7)).collect();
        for l in [8, 9, 15, 16, 17, 41, 81] {
            for start in [0, 1, 5] {
                let x = &x[start..start + l];
                let w: Vec<f64> = w[start..]
                    .iter()
                    .take(l)
                    .cycle()
                    .take(3 * l)
                    .copied()
                    .collect();
                let responses = Responses::new(&w, l);
                let (wide, valid) = dot_wide(x, &responses);
                let (scalar, scalar_valid) = dot_checked(x, responses.channel(0));
                assert_eq!(wide.to_bits(), scalar.to_bits(), "{l} from {start}");
                assert!(valid && scalar_valid);
            }
        }
        // Each bad value in a full chunk and in the tail; -0 is a valid 0.
        let responses = Responses::new(&w[..3 * 41], 41);
        for (bad, at) in [(-1.0, 3), (f32::NAN, 17), (f32::INFINITY, 40), (-1e-30, 40)] {
            let mut x = spectra(1, 41);
            x[at] = bad;
            assert!(!dot_wide(&x, &responses).1, "{bad} at {at}");
            assert!(!dot_checked(&x, responses.channel(0)).1);
        }
        let mut x = spectra(1, 41);
        x[9] = -0.0;
        x[40] = -0.0;
        let (wide, valid) = dot_wide(&x, &responses);
        assert!(valid);
        assert_eq!(
            wide.to_bits(),
            dot_checked(&x, responses.channel(0)).0.to_bits()
        );
    }

    #[test]
    fn the_avx2_row_gives_the_scalar_bits() {
        if !has_avx2_fma() {
            return;
        }
        let (w, l) = (37, 41);
        let src = spectra(w, l);
        let response: Vec<f64> = (0..3 * l).map(|i| (i % 13) as f64 * 0.37).collect();
        let responses = Responses::new(&response, l);
        let colors = [1u8, 0, 2];
        let (mut scalar, mut wide) = (vec![0.0; w], vec![0.0; w]);
        let dot = |x: &[f32], c| dot_checked(x, responses.channel(c));
        row_with(dot, &src, colors_from(&colors, 0), l, &mut scalar);
        // SAFETY: AVX2 and FMA support was checked above; 41 >= 8 samples.
        unsafe { row_avx2(&src, colors_from(&colors, 0), &responses, &mut wide) };
        assert_eq!(scalar, wide);
        // Column 4 is channel 0 (4 % 3 = 1 -> colors[1]).
        let px = &src[4 * l..5 * l];
        let want: f64 = px
            .iter()
            .zip(&response[..l])
            .map(|(a, b)| f64::from(*a) * b)
            .sum();
        assert!((scalar[4] / want - 1.0).abs() < 1e-5);
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
            let bad = row(&src, colors_from(&[0], 0), &responses, &mut rates);
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

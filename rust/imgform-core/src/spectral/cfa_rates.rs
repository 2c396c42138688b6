//! The rates of a row of photosites behind a colour filter array, from a
//! row of a spectral image: each site integrates its spectrum against the
//! one response of its filter's channel.
//!
//! A 24 MP image of 41 samples is 3.9 GB of float32, so this kernel is
//! bound by reading it once: the dot product is in f32 with fused
//! multiply-adds over eight lanes (one AVX2 register, written with
//! intrinsics: the compiler does not vectorise a loop of runtime length
//! into one register's lanes), and the check of the samples rides along in
//! the same registers, cheap enough to keep up with memory. The samples and responses are >= 0, so no term cancels
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

/// [`dot_checked`] with the chunks' multiply-adds and checks in one AVX2
/// register each (a sample is valid when `0 <= v <= f32::MAX`, which NaN
/// fails, as [`all_valid`] has it).
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn dot_avx2(x: &[f32], w: &[f32]) -> (f32, bool) {
    use std::arch::x86_64::*;
    let load = |chunk: &[f32]| {
        let lanes: &[f32; DOT_LANES] = chunk.try_into().expect("a chunk of eight");
        // SAFETY: `lanes` is eight readable floats (an unaligned load).
        unsafe { _mm256_loadu_ps(lanes.as_ptr()) }
    };
    let chunks = x.chunks_exact(DOT_LANES);
    let tail_valid = all_valid(chunks.remainder());
    let mut acc = load(&tail_products(x, w));
    let (zero, max) = (_mm256_setzero_ps(), _mm256_set1_ps(f32::MAX));
    let mut valid = _mm256_cmp_ps::<_CMP_EQ_OQ>(zero, zero);
    for (xc, wc) in chunks.zip(w.chunks_exact(DOT_LANES)) {
        let v = load(xc);
        acc = _mm256_fmadd_ps(v, load(wc), acc);
        let in_range = _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GE_OQ>(v, zero),
            _mm256_cmp_ps::<_CMP_LE_OQ>(v, max),
        );
        valid = _mm256_and_ps(valid, in_range);
    }
    let mut lanes = [0.0f32; DOT_LANES];
    // SAFETY: `lanes` is eight writable floats (an unaligned store).
    unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), acc) };
    (
        lane_sum(lanes),
        tail_valid & (_mm256_movemask_ps(valid) == 0xFF),
    )
}

/// Fills `rates` with the rate of each site of a row: `response` holds the
/// f32 responses `(3, L)`, `src` the row's spectra (`L` samples per pixel,
/// `L > 0`), `colors` the CFA channel of each column (repeated), `dot` the
/// checked dot product ([`dot_checked`] or [`dot_avx2`]). Returns the
/// column of the first pixel with a negative or non-finite sample.
#[inline(always)]
fn row_with(
    dot: impl Fn(&[f32], &[f32]) -> (f32, bool),
    src: &[f32],
    colors: &[u8],
    response: &[f32],
    rates: &mut [f64],
) -> Option<usize> {
    let grid_len = response.len() / 3;
    let mut first_bad = None;
    let pixels = src.chunks_exact(grid_len).zip(colors.iter().cycle());
    for (x, (r, (px, &c))) in rates.iter_mut().zip(pixels).enumerate() {
        let c = usize::from(c);
        let (rate, valid) = dot(px, &response[c * grid_len..(c + 1) * grid_len]);
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
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn row_avx2(
    src: &[f32],
    colors: &[u8],
    response: &[f32],
    rates: &mut [f64],
) -> Option<usize> {
    // SAFETY: the caller vouches for AVX2 and FMA.
    let dot = |x: &[f32], w: &[f32]| unsafe { dot_avx2(x, w) };
    row_with(dot, src, colors, response, rates)
}

/// The rates of a row (see [`row_with`]) through the widest vector unit
/// the CPU has; the same bits either way.
pub(super) fn row(
    src: &[f32],
    colors: &[u8],
    response: &[f32],
    rates: &mut [f64],
) -> Option<usize> {
    #[cfg(target_arch = "x86_64")]
    if has_avx2_fma() {
        // SAFETY: AVX2 and FMA support was detected just above.
        return unsafe { row_avx2(src, colors, response, rates) };
    }
    row_with(dot_checked, src, colors, response, rates)
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

    #[test]
    fn the_avx2_dot_gives_the_scalar_bits_and_verdict() {
        if !has_avx2_fma() {
            return;
        }
        let x = spectra(3, 41);
        let w: Vec<f32> = (0..x.len()).map(|i| 1.0 / (i as f32 + 1.7)).collect();
        for l in [0, 1, 7, 8, 9, 16, 41, 81] {
            for start in [0, 1, 5] {
                let (x, w) = (&x[start..start + l], &w[start..start + l]);
                // SAFETY: AVX2 and FMA support was checked above.
                let (wide, valid) = unsafe { dot_avx2(x, w) };
                let (scalar, scalar_valid) = dot_checked(x, w);
                assert_eq!(wide.to_bits(), scalar.to_bits(), "{l} from {start}");
                assert!(valid && scalar_valid);
            }
        }
        // Each bad value in a full chunk and in the tail; -0 is a valid 0.
        for (bad, at) in [(-1.0, 3), (f32::NAN, 17), (f32::INFINITY, 40), (-1e-30, 40)] {
            let mut x = spectra(1, 41);
            x[at] = bad;
            // SAFETY: as above.
            assert!(!unsafe { dot_avx2(&x, &w[..41]) }.1, "{bad} at {at}");
            assert!(!dot_checked(&x, &w[..41]).1);
        }
        let mut x = spectra(1, 41);
        x[9] = -0.0;
        // SAFETY: as above.
        assert!(unsafe { dot_avx2(&x, &w[..41]) }.1);
    }

    #[test]
    fn the_avx2_row_gives_the_scalar_bits() {
        if !has_avx2_fma() {
            return;
        }
        let (w, l) = (37, 41);
        let src = spectra(w, l);
        let response: Vec<f32> = (0..3 * l).map(|i| (i % 13) as f32 * 0.37).collect();
        let colors = [1u8, 0, 2];
        let (mut scalar, mut wide) = (vec![0.0; w], vec![0.0; w]);
        row_with(dot_checked, &src, &colors, &response, &mut scalar);
        // SAFETY: AVX2 and FMA support was checked above.
        unsafe { row_avx2(&src, &colors, &response, &mut wide) };
        assert_eq!(scalar, wide);
        // Column 4 is channel 0 (4 % 3 = 1 -> colors[1]).
        let px = &src[4 * l..5 * l];
        let want: f64 = px
            .iter()
            .zip(&response[..l])
            .map(|(a, b)| f64::from(a * b))
            .sum();
        assert!((scalar[4] / want - 1.0).abs() < 1e-5);
    }

    #[test]
    fn the_first_bad_column_is_reported() {
        let (w, l) = (10, 9);
        let mut src = spectra(w, l);
        src[6 * l + 8] = -1.0;
        src[8 * l] = f32::NAN;
        let mut rates = vec![0.0; w];
        assert_eq!(row(&src, &[0], &[1.0; 27], &mut rates), Some(6));
    }
}

//! AVX-512 bilinear rows of `resample_channels` for u8 RGB images, sixteen
//! samples a step.
//!
//! The AVX2 kernel assembles each window row of a step from eight scalar
//! loads, and those loads bound its speed. A lens correction's samples are
//! near one another, though: sixteen consecutive ones (R, G, B of five or
//! six pixels, each at its own position) take their taps from a few dozen
//! bytes of a few source rows. So a step loads 64 bytes of each row it
//! needs, once, and a byte permutation (`vpermb`, AVX-512 VBMI) picks every
//! lane's two taps out of them, already spread into the 16-bit pairs that
//! `madd` weighs. A step whose samples reach further apart than the loaded
//! bytes, have windows starting on more than four rows, or have a window
//! that is not wholly inside goes to the scalar path, as does the row's
//! tail. On a 24 MP correction of a kit zoom (distortion and TCA, red and
//! blue up to 3 px from green) one step in 10,000 does.
//!
//! Lateral chromatic aberration puts a step's lanes on several source rows
//! (on one row in 31 % of that correction's steps, two in 52 %, three or
//! more in 17 %): each row a lane needs is loaded once and permuted into
//! the lanes that start there. A two-table permutation per pair of rows
//! (`vpermi2b`) took 8 % longer on Zen 4.
//!
//! The arithmetic is the AVX2 kernel's (see `remap_avx2`): exact integers
//! in 256ths, rounded once, so the bits are the scalar path's (tested).

use std::arch::x86_64::*;

use super::FRAC_BITS;

/// Samples per vector step.
const LANES: usize = 16;

/// Steps ahead whose first source bytes are prefetched, every other step
/// (a step advances about 16 bytes through the source, a cache line is
/// 64): the map decides the addresses, so the hardware prefetcher misses
/// the first touch of each source row. Measured on the 24 MP lens
/// correction: 8 steps ahead 56 ms, 16 53, 32 52.5, 64 53.7, none 61.
const AHEAD: usize = 32;

/// Bytes of each source row that a step loads.
const SPAN: i32 = 64;

/// Bytes the loads start before lane 0's left tap: another lane may read
/// left of it (lane 0 can be blue with red one pixel on; lateral chromatic
/// aberration moves channels apart).
const LEAD: i32 = 8;

/// Byte mask of the two taps' bytes in each 32-bit lane: bytes 0 and 2
/// take the left and right tap, bytes 1 and 3 are zero (the high halves of
/// the 16-bit pairs).
const TAP_BYTES: u64 = 0x5555_5555_5555_5555;

/// Whether the CPU has the instructions [`channel_row_u8`] is built with.
pub(super) fn available() -> bool {
    use std::arch::is_x86_feature_detected as has;
    crate::cpu::allows(crate::cpu::Level::Avx512)
        && has!("avx512f")
        && has!("avx512bw")
        && has!("avx512dq")
        && has!("avx512vbmi")
}

/// The source as a step addresses it.
struct Source {
    base: *const u8,
    /// Bytes per source row.
    stride: i32,
    /// One more than the largest first-tap column and row of a window wholly
    /// inside: `width - 1`, `height - 1`.
    last: (i32, i32),
    /// The largest start of a step's first load that leaves room for its
    /// loads up to four rows further down.
    room: i64,
}

impl Source {
    /// Asks for the cache lines of sample `s`'s window rows, if it has a
    /// window inside.
    #[inline(always)]
    fn prefetch(&self, xy: &[i32], s: usize) {
        if let Some(p) = xy.get(2 * s..2 * s + 2) {
            let (ix, iy) = (p[0] >> FRAC_BITS, p[1] >> FRAC_BITS);
            if ix >= 0 && iy >= 0 && ix < self.last.0 && iy < self.last.1 {
                let at = (iy * self.stride + 3 * ix) as usize;
                // SAFETY: prefetching has no effect on memory, and both
                // addresses are inside the source (the window is).
                unsafe {
                    _mm_prefetch::<_MM_HINT_T0>(self.base.wrapping_add(at).cast());
                    _mm_prefetch::<_MM_HINT_T0>(
                        self.base.wrapping_add(at + self.stride as usize).cast(),
                    );
                }
            }
        }
    }
}

/// Where one step reads and how it weighs what it reads.
struct Step {
    /// Byte offset of the first load: the highest source row any lane
    /// reads, a little left of lane 0's left tap.
    start: usize,
    /// Per lane: the tap pair's byte indices into a 64-byte load, as
    /// `vpermb` takes them.
    picks: __m512i,
    /// Per lane: the rows from the step's first to its window's first.
    down: __m512i,
    fx: __m512i,
    fy: __m512i,
}

/// The first lane of `v` (a vector's lowest 32 bits).
#[target_feature(enable = "avx512f")]
fn first(v: __m512i) -> i32 {
    _mm_cvtsi128_si32(_mm512_castsi512_si128(v))
}

/// Positions of samples `16k .. 16k + 16` of a row, whose channels are
/// `channel` (0, 1, 2 repeating from the first lane's), and whether the
/// vector path may take them.
///
/// # Safety
/// The features of [`channel_row_u8`]; `xy` holds 32 readable values.
#[inline(always)]
unsafe fn step(xy: *const i32, channel: __m512i, src: &Source) -> Option<Step> {
    // SAFETY: the caller guarantees 32 values at `xy`.
    let (a, b) = unsafe {
        (
            _mm512_loadu_si512(xy.cast()),
            _mm512_loadu_si512(xy.add(LANES).cast()),
        )
    };
    let even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
    let sx = _mm512_permutex2var_epi32(a, even, b);
    let sy = _mm512_permutex2var_epi32(a, _mm512_add_epi32(even, _mm512_set1_epi32(1)), b);
    let (ix, iy) = (
        _mm512_srai_epi32::<{ FRAC_BITS }>(sx),
        _mm512_srai_epi32::<{ FRAC_BITS }>(sy),
    );
    // Unsigned, negative indices (and NOWHERE's) are beyond `last`.
    let inside = _mm512_cmplt_epu32_mask(ix, _mm512_set1_epi32(src.last.0))
        & _mm512_cmplt_epu32_mask(iy, _mm512_set1_epi32(src.last.1));
    if inside != u16::MAX {
        return None;
    }
    // The highest row a lane's window starts on.
    let row = _mm512_reduce_min_epi32(iy);
    let down = _mm512_sub_epi32(iy, _mm512_set1_epi32(row));
    // Each sample's left tap as a byte of its row: 3 per pixel plus its channel.
    let column = _mm512_add_epi32(_mm512_add_epi32(ix, _mm512_slli_epi32::<1>(ix)), channel);
    let lead = first(column) - LEAD;
    let picks = _mm512_sub_epi32(column, _mm512_set1_epi32(lead));
    // The right tap is 3 bytes on, so the left one's index is at most 60.
    let near = _mm512_cmple_epu32_mask(picks, _mm512_set1_epi32(SPAN - 4));
    let rows = _mm512_cmple_epu32_mask(down, _mm512_set1_epi32(3));
    let start = i64::from(row) * i64::from(src.stride) + i64::from(lead);
    if near & rows != u16::MAX || !(0..=src.room).contains(&start) {
        return None;
    }
    // Byte 0 the left tap, byte 2 the right one, 3 bytes on.
    let picks = _mm512_or_si512(
        picks,
        _mm512_slli_epi32::<16>(_mm512_add_epi32(picks, _mm512_set1_epi32(3))),
    );
    let mask = _mm512_set1_epi32((1 << FRAC_BITS) - 1);
    Some(Step {
        start: start as usize,
        picks,
        down,
        fx: _mm512_and_si512(sx, mask),
        fy: _mm512_and_si512(sy, mask),
    })
}

/// The two window rows of a step's lanes as 16-bit tap pairs: every
/// lane's picked from the first two rows, then those of the lanes further
/// down overwritten from each next pair, as long as some lane is lower.
///
/// # Safety
/// The features of [`channel_row_u8`]; the step's loads, up to four rows
/// below its first, lie inside the buffer at `src.base`.
#[inline(always)]
unsafe fn window_rows(s: &Step, src: &Source) -> (__m512i, __m512i) {
    let stride = src.stride as usize;
    // SAFETY: `step` admitted `start` only with these loads in bounds.
    let load = |r: usize| unsafe { _mm512_loadu_si512(src.base.add(s.start + r * stride).cast()) };
    let mut lower = load(1);
    let mut top = _mm512_maskz_permutexvar_epi8(TAP_BYTES, s.picks, load(0));
    let mut bottom = _mm512_maskz_permutexvar_epi8(TAP_BYTES, s.picks, lower);
    let mut r = 0;
    while _mm512_cmpgt_epi32_mask(s.down, _mm512_set1_epi32(r)) != 0 {
        r += 1;
        let upper = lower;
        lower = load(r as usize + 1);
        let lanes = _mm512_cmpeq_epi32_mask(s.down, _mm512_set1_epi32(r));
        let bytes = _mm512_movepi8_mask(_mm512_movm_epi32(lanes)) & TAP_BYTES;
        top = _mm512_mask_permutexvar_epi8(top, bytes, s.picks, upper);
        bottom = _mm512_mask_permutexvar_epi8(bottom, bytes, s.picks, lower);
    }
    (top, bottom)
}

/// The sixteen samples of a step, as 32-bit lanes in `0..=255`: the sums
/// `top · 256 + (bottom - top) · fy` of the horizontal sums in 256ths,
/// rounded half up (times the gains, if any, rounded once).
///
/// # Safety
/// As [`window_rows`]; `gains` is empty or holds the step's sixteen.
#[inline(always)]
unsafe fn samples(s: &Step, src: &Source, gains: Option<*const f32>) -> __m512i {
    // Horizontal weights `(256 - fx) | fx << 16`.
    let wx = _mm512_add_epi32(
        _mm512_set1_epi32(1 << FRAC_BITS),
        _mm512_sub_epi32(_mm512_slli_epi32::<16>(s.fx), s.fx),
    );
    // SAFETY: the caller's guarantees.
    let (top, bottom) = unsafe { window_rows(s, src) };
    let (top, bottom) = (_mm512_madd_epi16(top, wx), _mm512_madd_epi16(bottom, wx));
    let sum = _mm512_add_epi32(
        _mm512_slli_epi32::<{ FRAC_BITS }>(top),
        _mm512_mullo_epi32(_mm512_sub_epi32(bottom, top), s.fy),
    );
    let Some(gains) = gains else {
        let half = _mm512_set1_epi32(1 << (2 * FRAC_BITS - 1));
        return _mm512_srli_epi32::<{ 2 * FRAC_BITS }>(_mm512_add_epi32(sum, half));
    };
    // Below 255 · 2^16 < 2^24: the conversion is exact, and so is the
    // power-of-two scale. Then `(v + 0.5) as u8`, whose saturation (NaN to
    // 0) the clamp reproduces: `max` returns its second operand for NaN.
    // SAFETY: the caller guarantees sixteen gains.
    let g = _mm512_mul_ps(
        unsafe { _mm512_loadu_ps(gains) },
        _mm512_set1_ps(1.0 / 65536.0),
    );
    let v = _mm512_add_ps(
        _mm512_mul_ps(_mm512_cvtepi32_ps(sum), g),
        _mm512_set1_ps(0.5),
    );
    let v = _mm512_min_ps(_mm512_max_ps(v, _mm512_setzero_ps()), _mm512_set1_ps(255.0));
    _mm512_cvttps_epi32(v)
}

/// u8 RGB: sample `s` of `out` is channel `s % 3` of `src` read bilinearly
/// at `xy[2s..2s + 2]` (times `gains[s]` when there are gains); `sample`
/// writes the samples left to the scalar path. `false`, with nothing done,
/// when the lengths do not fit or offsets may overflow an `i32`.
///
/// # Safety
/// The CPU has the enabled features ([`available`]); `src` is an RGB image
/// of `w x h` pixels with rows `stride` bytes apart.
#[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vbmi")]
pub(super) unsafe fn channel_row_u8(
    src: &[u8],
    stride: usize,
    (w, h): (usize, usize),
    (xy, gains, out): (&[i32], &[f32], &mut [u8]),
    sample: &mut dyn FnMut(usize, &mut [u8]),
) -> bool {
    let n = out.len();
    if xy.len() != 2 * n || !(gains.is_empty() || gains.len() == n) {
        return false;
    }
    let (Ok(stride), Ok(_)) = (i32::try_from(stride), i32::try_from(src.len())) else {
        return false;
    };
    let source = Source {
        base: src.as_ptr(),
        stride,
        last: (w as i32 - 1, h as i32 - 1),
        room: src.len() as i64 - 4 * i64::from(stride) - i64::from(SPAN),
    };
    // Lane l of step k is channel (16k + l) % 3, and 16k % 3 = k % 3.
    let lane = _mm512_setr_epi32(0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0);
    let channels = [0, 1, 2].map(|c| {
        let shifted = _mm512_add_epi32(lane, _mm512_set1_epi32(c));
        // (lane + c) mod 3 for lane + c below 6.
        let wrap = _mm512_cmpge_epi32_mask(shifted, _mm512_set1_epi32(3));
        _mm512_mask_sub_epi32(shifted, wrap, shifted, _mm512_set1_epi32(3))
    });
    let dst = out.as_mut_ptr();
    for k in 0..n / LANES {
        if k % 2 == 0 {
            source.prefetch(xy, LANES * (k + AHEAD));
        }
        // SAFETY: step k reads xy[32k .. 32k + 32], inside since k < n / 16.
        let Some(s) = (unsafe { step(xy.as_ptr().add(2 * LANES * k), channels[k % 3], &source) })
        else {
            for s in LANES * k..LANES * (k + 1) {
                // SAFETY: s < n, and no vector store is pending on it.
                sample(s, unsafe { std::slice::from_raw_parts_mut(dst.add(s), 1) });
            }
            continue;
        };
        // SAFETY: step k has sixteen gains when there are any.
        let gains = (!gains.is_empty()).then(|| unsafe { gains.as_ptr().add(LANES * k) });
        // SAFETY: `step` admitted the loads; samples 16k .. 16k + 16 are
        // inside `out`.
        unsafe {
            let v = samples(&s, &source, gains);
            _mm_storeu_si128(dst.add(LANES * k).cast(), _mm512_cvtepi32_epi8(v));
        }
    }
    for s in n / LANES * LANES..n {
        sample(s, &mut out[s..=s]);
    }
    true
}

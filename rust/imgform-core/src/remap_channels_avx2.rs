//! AVX2 bilinear rows whose samples each have a position of their own: the
//! lateral chromatic aberration correction reads red, green and blue of an
//! RGB image from three places (`resample_channels`).
//!
//! Sample `s` of an output row is channel `s % 3` read at `xy[2s..2s + 2]`,
//! so the row is a single-channel map over `3 W` samples whose two taps per
//! source row are one pixel (three samples) apart and offset by the
//! sample's channel. Eight samples per step, through the parent module's
//! [`walk`]; the arithmetic is the scalar path's, so the bits are the same
//! (tested against it): exact integers in 256ths for u8 and u16, the scalar
//! `f32` operations in their order for f32. With gains, each sample's
//! unrounded value is multiplied by its gain and rounded once, as
//! `Arith::store_scaled` does.

use std::arch::x86_64::*;

use super::{
    gather_at, lane_offsets, round_sum, store_gray_u8, store_u16, vertical_sum, walk, weight_pairs,
    Geometry, Step, LANES,
};

/// The channel of each lane of step `k` is `(8k + lane) % 3`; `8k % 3`
/// cycles through 0, 2, 1.
const CHANNELS: [[i32; LANES]; 3] = [
    [0, 1, 2, 0, 1, 2, 0, 1],
    [2, 0, 1, 2, 0, 1, 2, 0],
    [1, 2, 0, 1, 2, 0, 1, 2],
];

/// The byte offsets of the lanes' channels in samples of `size` bytes, for
/// steps `k` with `k % 3` = 0, 1, 2: made once per row, so that a step
/// only picks one (see [`ChannelBytes::of`]).
struct ChannelBytes([__m256i; 3]);

impl ChannelBytes {
    #[target_feature(enable = "avx2")]
    fn new(size: i32) -> Self {
        Self(CHANNELS.map(|c| {
            // SAFETY: the array holds 8 lanes.
            let c = unsafe { _mm256_loadu_si256(c.as_ptr().cast()) };
            _mm256_mullo_epi32(c, _mm256_set1_epi32(size))
        }))
    }

    /// The offsets of a step whose index is `third` modulo 3 (a `match`
    /// rather than an index, which would need a bounds check).
    #[inline(always)]
    fn of(&self, third: usize) -> __m256i {
        match third {
            0 => self.0[0],
            1 => self.0[1],
            _ => self.0[2],
        }
    }
}

/// Whether the lengths fit: two coordinates and, if any, one gain per
/// output sample.
fn fits(xy: &[i32], gains: &[f32], samples: usize) -> bool {
    xy.len() == 2 * samples && (gains.is_empty() || gains.len() == samples)
}

/// Step `k`'s gains times `scale` (`2^-16` for the integer sums: a power
/// of two, exact like the scalar division).
///
/// # Safety
/// AVX2; `gains` holds step `k`'s.
#[target_feature(enable = "avx2")]
unsafe fn gain_lanes(gains: &[f32], k: usize, scale: f32) -> __m256 {
    // SAFETY: the caller guarantees gains 8k .. 8k + 8.
    let g = unsafe { _mm256_loadu_ps(gains.as_ptr().add(LANES * k)) };
    _mm256_mul_ps(g, _mm256_set1_ps(scale))
}

/// `(v + 0.5) as T` lane by lane for integer types of largest value `max`:
/// `as` truncates and saturates (NaN to 0), which the clamp reproduces
/// (`max_ps` returns its second operand, 0, for a NaN).
#[target_feature(enable = "avx2")]
fn round_to(v: __m256, max: f32) -> __m256i {
    let v = _mm256_add_ps(v, _mm256_set1_ps(0.5));
    let v = _mm256_min_ps(_mm256_max_ps(v, _mm256_setzero_ps()), _mm256_set1_ps(max));
    _mm256_cvttps_epi32(v)
}

/// `v as f32` for unsigned 32-bit lanes, rounded once to nearest as `as`
/// does: the high half times 2^16 and the low half are exact, so only the
/// sum rounds.
#[target_feature(enable = "avx2")]
fn u32_to_f32(v: __m256i) -> __m256 {
    let high = _mm256_cvtepi32_ps(_mm256_srli_epi32(v, 16));
    let low = _mm256_cvtepi32_ps(_mm256_and_si256(v, _mm256_set1_epi32(0xffff)));
    _mm256_add_ps(_mm256_mul_ps(high, _mm256_set1_ps(65536.0)), low)
}

/// Bytes of source row that the steps between two prefetches may cross:
/// half a cache line, so that each line is asked for at least once ahead
/// of its loads even where the distortion stretches the source a little.
const PREFETCH_BYTES: usize = 32;

/// The geometry of an RGB source of `T` samples for per-channel taps:
/// `read` bytes from a window's first tap without its channel offset.
/// A step's eight samples advance about eight samples through the source,
/// so it prefetches every [`PREFETCH_BYTES`] of them.
fn geometry<T>(src: &[T], stride: usize, size: (usize, usize), read: usize) -> Option<Geometry> {
    let bytes = std::mem::size_of::<T>();
    let g = Geometry::new(
        src.as_ptr().cast(),
        std::mem::size_of_val(src),
        bytes * stride,
        3 * bytes,
        2,
        size,
        read,
    )?;
    Some(g.prefetching_every(PREFETCH_BYTES / (LANES * bytes)))
}

/// The first byte of the source row below the one at `base`: the lower
/// taps are read at the upper ones' offsets from there.
fn below(base: *const u8, g: &Geometry) -> *const u8 {
    base.wrapping_add(g.stride as usize)
}

/// u8 RGB: per lane one 4-byte read at the left tap, whose first and last
/// bytes are the two taps of the sample's channel.
///
/// # Safety
/// AVX2; `src` is an RGB image of `w x h` pixels with rows `stride` bytes
/// apart.
#[target_feature(enable = "avx2")]
pub(in crate::remap) unsafe fn channel_row_u8(
    src: &[u8],
    stride: usize,
    size: (usize, usize),
    (xy, gains, out): (&[i32], &[f32], &mut [u8]),
    sample: &mut dyn FnMut(usize, &mut [u8]),
) -> bool {
    // The 4-byte read at the left tap, up to 2 bytes further for blue.
    let Some(g) = geometry(src, stride, size, 6).filter(|_| fits(xy, gains, out.len())) else {
        return false;
    };
    let (base, dst) = (src.as_ptr(), out.as_mut_ptr());
    let pairs = _mm256_setr_epi8(
        0, -1, 3, -1, 4, -1, 7, -1, 8, -1, 11, -1, 12, -1, 15, -1, 0, -1, 3, -1, 4, -1, 7, -1, 8,
        -1, 11, -1, 12, -1, 15, -1,
    );
    let lower = below(base, &g);
    let channels = ChannelBytes::new(1);
    let body = |k: usize, third: usize, s: Step| {
        // SAFETY: `step` admitted only windows inside `src`: no offset is negative.
        let at = unsafe { lane_offsets(_mm256_add_epi32(s.top, channels.of(third))) };
        let wx = weight_pairs(s.fx);
        // SAFETY: `step` admitted only windows whose reads end inside `src`.
        let line = |row: *const u8| unsafe {
            _mm256_madd_epi16(_mm256_shuffle_epi8(gather_at(row, &at), pairs), wx)
        };
        let sum = vertical_sum(line(base), line(lower), s.fy);
        let v = if gains.is_empty() {
            round_sum(sum)
        } else {
            // Below 255 · 2^16 < 2^24: the conversion is exact.
            // SAFETY: the row has a gain per sample.
            let g = unsafe { gain_lanes(gains, k, 1.0 / 65536.0) };
            round_to(_mm256_mul_ps(_mm256_cvtepi32_ps(sum), g), 255.0)
        };
        // SAFETY: step k writes samples 8k .. 8k + 8 of the row.
        unsafe { store_gray_u8(dst.add(LANES * k), v) };
    };
    // SAFETY: AVX2; the body writes only step k's samples.
    unsafe { walk(xy, &g, body, (dst, 1), sample) };
    true
}

/// u16 RGB: per lane one 4-byte read at each tap, of which the low half is
/// the sample. The sums reach `65535 · 2^16`, beyond `madd`'s range, so
/// both stages multiply in 32 bits.
///
/// # Safety
/// As for [`channel_row_u8`], with `stride` in samples.
#[target_feature(enable = "avx2")]
pub(in crate::remap) unsafe fn channel_row_u16(
    src: &[u16],
    stride: usize,
    size: (usize, usize),
    (xy, gains, out): (&[i32], &[f32], &mut [u16]),
    sample: &mut dyn FnMut(usize, &mut [u16]),
) -> bool {
    // Blue's right tap: 4 + 6 bytes on, read 4 bytes.
    let Some(g) = geometry(src, stride, size, 14).filter(|_| fits(xy, gains, out.len())) else {
        return false;
    };
    let (base, dst) = (src.as_ptr().cast::<u8>(), out.as_mut_ptr());
    let (lower, low) = (below(base, &g), _mm256_set1_epi32(0xffff));
    let channels = ChannelBytes::new(2);
    let body = |k: usize, third: usize, s: Step| {
        // SAFETY: `step` admitted only windows inside `src`: no offset is negative.
        let at = unsafe { lane_offsets(_mm256_add_epi32(s.top, channels.of(third))) };
        let line = |row: *const u8| {
            // SAFETY: `step` admitted only windows whose reads end inside
            // `src`; the right tap is a pixel (6 bytes) on.
            let (l, r) = unsafe { (gather_at(row, &at), gather_at(row.wrapping_add(6), &at)) };
            let (l, r) = (_mm256_and_si256(l, low), _mm256_and_si256(r, low));
            _mm256_add_epi32(
                _mm256_slli_epi32(l, 8),
                _mm256_mullo_epi32(_mm256_sub_epi32(r, l), s.fx),
            )
        };
        let sum = vertical_sum(line(base), line(lower), s.fy);
        let v = if gains.is_empty() {
            round_sum(sum)
        } else {
            // SAFETY: the row has a gain per sample.
            let g = unsafe { gain_lanes(gains, k, 1.0 / 65536.0) };
            round_to(_mm256_mul_ps(u32_to_f32(sum), g), 65535.0)
        };
        // SAFETY: step k writes samples 8k .. 8k + 8 of the row.
        unsafe { store_u16(dst.add(LANES * k), v) };
    };
    // SAFETY: as in `channel_row_u8`.
    unsafe { walk(xy, &g, body, (dst, 1), sample) };
    true
}

/// The first and last `f32` of 16 bytes read at each of eight byte
/// offsets of `base`, as two vectors of 8 lanes: in an RGB row of `f32` a
/// channel's left and right taps are 12 bytes apart, so one 16-byte load
/// per lane fetches both. Four registers of two loads each are then
/// sorted in two rounds of shuffles; half the loads of two 4-byte
/// [`gather_at`]s, and no inserts of single lanes.
///
/// # Safety
/// AVX2; every `base + offset .. + 16` lies inside one buffer.
#[target_feature(enable = "avx2")]
unsafe fn gather_ends(base: *const u8, o: &[usize; LANES]) -> (__m256, __m256) {
    // SAFETY: the caller guarantees the reads are in bounds.
    unsafe {
        let read = |i: usize| _mm_loadu_ps(base.wrapping_add(o[i]).cast());
        // Lanes i and i + 4 in one register, so that the 128-bit halves
        // below stay those of lanes 0-3 and 4-7.
        let pair = |i: usize| _mm256_insertf128_ps(_mm256_castps128_ps256(read(i)), read(i + 4), 1);
        // [first, last] of lanes (0, 1) | (4, 5), then of (2, 3) | (6, 7).
        let low = _mm256_shuffle_ps(pair(0), pair(1), 0b11_00_11_00);
        let high = _mm256_shuffle_ps(pair(2), pair(3), 0b11_00_11_00);
        (
            _mm256_shuffle_ps(low, high, 0b10_00_10_00),
            _mm256_shuffle_ps(low, high, 0b11_01_11_01),
        )
    }
}

/// f32 RGB: the scalar path's operations, `((0 + a0 p0) + a1 p1)` per row
/// and the same of the rows, in `f32` without fused multiply-adds (the
/// additions to zero turn a -0 into +0, as the scalar sums do).
///
/// # Safety
/// As for [`channel_row_u8`], with `stride` in samples.
#[target_feature(enable = "avx2")]
pub(in crate::remap) unsafe fn channel_row_f32(
    src: &[f32],
    stride: usize,
    size: (usize, usize),
    (xy, gains, out): (&[i32], &[f32], &mut [f32]),
    sample: &mut dyn FnMut(usize, &mut [f32]),
) -> bool {
    // Blue's taps: 8 bytes on, read 16 bytes.
    let Some(g) = geometry(src, stride, size, 24).filter(|_| fits(xy, gains, out.len())) else {
        return false;
    };
    let (base, dst) = (src.as_ptr().cast::<u8>(), out.as_mut_ptr());
    let lower = below(base, &g);
    let (zero, one, unit) = (
        _mm256_setzero_ps(),
        _mm256_set1_ps(1.0),
        _mm256_set1_ps(1.0 / 256.0),
    );
    let weights = |f: __m256i| {
        let t = _mm256_mul_ps(_mm256_cvtepi32_ps(f), unit);
        (_mm256_sub_ps(one, t), t)
    };
    let blend = |(a0, a1): (__m256, __m256), p0: __m256, p1: __m256| {
        _mm256_add_ps(
            _mm256_add_ps(zero, _mm256_mul_ps(a0, p0)),
            _mm256_mul_ps(a1, p1),
        )
    };
    let channels = ChannelBytes::new(4);
    let body = |k: usize, third: usize, s: Step| {
        // SAFETY: `step` admitted only windows inside `src`: no offset is negative.
        let at = unsafe { lane_offsets(_mm256_add_epi32(s.top, channels.of(third))) };
        let wx = weights(s.fx);
        let line = |row: *const u8| {
            // SAFETY: `step` admitted only windows whose reads end inside `src`.
            let (l, r) = unsafe { gather_ends(row, &at) };
            blend(wx, l, r)
        };
        let mut v = blend(weights(s.fy), line(base), line(lower));
        if !gains.is_empty() {
            // SAFETY: the row has a gain per sample.
            v = _mm256_mul_ps(v, unsafe { gain_lanes(gains, k, 1.0) });
        }
        // SAFETY: step k writes samples 8k .. 8k + 8 of the row.
        unsafe { _mm256_storeu_ps(dst.add(LANES * k), v) };
    };
    // SAFETY: as in `channel_row_u8`.
    unsafe { walk(xy, &g, body, (dst, 1), sample) };
    true
}

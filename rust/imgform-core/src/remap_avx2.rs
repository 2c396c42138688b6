//! AVX2 bilinear rows for u8 (1 or 3 channels) and u16 (1 channel) images
//! remapped through a dense [`super::RemapMap`].
//!
//! Eight output pixels per step: their positions are split into tap offsets
//! and fractions in vector registers, the 2x2 windows are fetched with one
//! load per pixel and row (see [`gather`]), and the weights are applied in integers. The arithmetic is the
//! scalar path's: `Σ p_ij (256 - fx | fx)_i (256 - fy | fy)_j`, exact in 32
//! bits, plus 2^15 and shifted right by 16. The order of the exact integer
//! operations differs (`top · 256 + (bottom - top) · fy` for the vertical
//! stage) but the sum is the same integer, so outputs are bit-identical
//! (the tests compare both paths).
//!
//! A step runs only when all eight windows lie inside the source and every
//! load, which reads a few bytes past the last tap, stays inside the
//! buffer; otherwise the step's pixels go to the scalar `pixel` callback,
//! which also handles the row's last `width % 8` pixels. In an undistortion
//! map that is a thin margin along the borders. The source windows of the
//! step [`AHEAD`] steps on are prefetched.

use std::arch::x86_64::*;

use super::{FRAC_BITS, KEYS_A};

#[path = "remap_channels_avx2.rs"]
mod channels;
pub(super) use channels::{channel_row_f32, channel_row_u16, channel_row_u8};

/// Pixels per vector step.
const LANES: usize = 8;

/// Source geometry in bytes, as the loads address it.
struct Geometry {
    /// The source's first byte.
    base: *const u8,
    /// Bytes per source row.
    stride: i32,
    /// Bytes per pixel.
    pixel: i32,
    /// Taps per axis: 2 (bilinear) or 4 (bicubic).
    taps: i32,
    /// One more than the largest index of a window's first tap per axis
    /// that keeps the window inside: `width - taps + 1`, `height - taps + 1`.
    last: (i32, i32),
    /// One more than the largest byte offset of a window's lower-left tap
    /// whose loads stay inside the buffer.
    reach: i32,
    /// Steps per prefetch (see [`Geometry::prefetch`]).
    prefetch_every: usize,
}

impl Geometry {
    /// `None` when offsets into the buffer may not fit an `i32`.
    fn new(
        base: *const u8,
        len_bytes: usize,
        stride: usize,
        pixel: usize,
        taps: usize,
        (w, h): (usize, usize),
        read: usize,
    ) -> Option<Self> {
        let len = i32::try_from(len_bytes).ok()?;
        let taps = taps as i32;
        Some(Self {
            base,
            stride: i32::try_from(stride).ok()?,
            pixel: pixel as i32,
            taps,
            last: (w as i32 - taps + 1, h as i32 - taps + 1),
            reach: len - read as i32 + 1,
            prefetch_every: 1,
        })
    }

    /// The same geometry, prefetching for every `steps`-th step only: a
    /// step whose eight samples advance a few bytes through the source
    /// would otherwise ask for the same cache line several times over.
    fn prefetching_every(self, steps: usize) -> Self {
        Self {
            prefetch_every: steps.max(1),
            ..self
        }
    }
}

/// Steps ahead whose source windows are prefetched.
const AHEAD: usize = 8;

impl Geometry {
    /// Asks for the cache lines of the first and last window rows of map
    /// pixel `x` (if any): the loads of a step stall on source memory, and
    /// the hardware prefetcher cannot predict map-driven addresses.
    #[inline(always)]
    fn prefetch(&self, xy: &[i32], x: usize) {
        if let Some(p) = xy.get(2 * x..2 * x + 2) {
            let lead = self.taps / 2 - 1;
            let (ix, iy) = ((p[0] >> FRAC_BITS) - lead, (p[1] >> FRAC_BITS) - lead);
            if ix >= 0 && iy >= 0 && ix < self.last.0 && iy < self.last.1 {
                let top = (iy * self.stride + ix * self.pixel) as usize;
                let bottom = top + ((self.taps - 1) * self.stride) as usize;
                // SAFETY: prefetching has no effect on memory, and the
                // addresses are inside the source (the window is).
                unsafe {
                    _mm_prefetch::<_MM_HINT_T0>(self.base.wrapping_add(top).cast());
                    _mm_prefetch::<_MM_HINT_T0>(self.base.wrapping_add(bottom).cast());
                }
            }
        }
    }
}

/// Tap offsets and fractions of eight pixels.
struct Step {
    /// Byte offset of each pixel's upper-left tap.
    top: __m256i,
    /// Fractions in 256ths.
    fx: __m256i,
    fy: __m256i,
}

/// Loads the positions of pixels `8k .. 8k + 8` of a map row and decides
/// whether the vector path may take them.
///
/// Always inlined into the AVX2 kernels rather than a `target_feature`
/// function of its own, like [`walk`].
///
/// # Safety
/// AVX2; `xy` holds at least 16 values from `xy`.
#[inline(always)]
unsafe fn step(xy: *const i32, g: &Geometry) -> Option<Step> {
    // SAFETY: the caller guarantees AVX2 and 16 readable values.
    unsafe {
        let (a, b) = (
            _mm256_loadu_si256(xy.cast()),
            _mm256_loadu_si256(xy.add(LANES).cast()),
        );
        // x0 y0 x1 y1 .. -> x0 x1 x2 x3 y0 y1 y2 y3 per register, then join.
        let split = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
        let (a, b) = (
            _mm256_permutevar8x32_epi32(a, split),
            _mm256_permutevar8x32_epi32(b, split),
        );
        let sx = _mm256_permute2x128_si256(a, b, 0x20);
        let sy = _mm256_permute2x128_si256(a, b, 0x31);
        // The arithmetic shift is floor; NOWHERE lands far outside. The first
        // tap is one left of and above floor(position) for 4 taps.
        let lead = _mm256_set1_epi32(g.taps / 2 - 1);
        let ix = _mm256_sub_epi32(_mm256_srai_epi32(sx, FRAC_BITS as i32), lead);
        let iy = _mm256_sub_epi32(_mm256_srai_epi32(sy, FRAC_BITS as i32), lead);
        let top = _mm256_add_epi32(
            _mm256_mullo_epi32(iy, _mm256_set1_epi32(g.stride)),
            _mm256_mullo_epi32(ix, _mm256_set1_epi32(g.pixel)),
        );
        let below = _mm256_add_epi32(top, _mm256_set1_epi32((g.taps - 1) * g.stride));
        let minus_one = _mm256_set1_epi32(-1);
        // Offsets of pixels outside wrap around, but they are excluded by the
        // index tests, which come first in meaning (all are and-ed).
        let inside = _mm256_and_si256(
            _mm256_and_si256(
                _mm256_and_si256(
                    _mm256_cmpgt_epi32(ix, minus_one),
                    _mm256_cmpgt_epi32(_mm256_set1_epi32(g.last.0), ix),
                ),
                _mm256_and_si256(
                    _mm256_cmpgt_epi32(iy, minus_one),
                    _mm256_cmpgt_epi32(_mm256_set1_epi32(g.last.1), iy),
                ),
            ),
            _mm256_cmpgt_epi32(_mm256_set1_epi32(g.reach), below),
        );
        if _mm256_movemask_epi8(inside) != -1 {
            return None;
        }
        let mask = _mm256_set1_epi32((1 << FRAC_BITS) - 1);
        Some(Step {
            top,
            fx: _mm256_and_si256(sx, mask),
            fy: _mm256_and_si256(sy, mask),
        })
    }
}

/// Horizontal bilinear weights as 16-bit pairs `(256 - fx) | fx << 16`,
/// i.e. `256 + fx · (2^16 - 1)`, for `madd`.
#[target_feature(enable = "avx2")]
fn weight_pairs(fx: __m256i) -> __m256i {
    _mm256_add_epi32(
        _mm256_set1_epi32(1 << FRAC_BITS),
        _mm256_sub_epi32(_mm256_slli_epi32(fx, 16), fx),
    )
}

/// `(top · 256 + (bottom - top) · fy + 2^15) >> 16` lane by lane: the
/// vertical stage and the rounding ([`vertical_sum`], [`round_sum`]).
#[target_feature(enable = "avx2")]
fn vertical(top: __m256i, bottom: __m256i, fy: __m256i) -> __m256i {
    round_sum(vertical_sum(top, bottom, fy))
}

/// `top · 256 + (bottom - top) · fy` lane by lane: the window's exact sum
/// in 2^16ths. Exact modulo 2^32, and the true value is below 2^32 (at
/// most `65535 · 2^16`), so as an unsigned lane it is that value even when
/// intermediate terms wrap.
#[target_feature(enable = "avx2")]
fn vertical_sum(top: __m256i, bottom: __m256i, fy: __m256i) -> __m256i {
    _mm256_add_epi32(
        _mm256_slli_epi32(top, FRAC_BITS as i32),
        _mm256_mullo_epi32(_mm256_sub_epi32(bottom, top), fy),
    )
}

/// `(sum + 2^15) >> 16` of unsigned sums below `2^32 - 2^15`: rounded half
/// up (the logical shift reads a wrapped sign bit as 2^31).
#[target_feature(enable = "avx2")]
fn round_sum(sum: __m256i) -> __m256i {
    _mm256_srli_epi32(
        _mm256_add_epi32(sum, _mm256_set1_epi32(1 << (2 * FRAC_BITS - 1))),
        2 * FRAC_BITS as i32,
    )
}

/// Reads 4 bytes at each byte offset of `base`, as 8 lanes.
///
/// Eight scalar loads assembled into a vector, not `vpgatherdd`: on the AMD
/// Zen machine this was measured on, the gather instruction made a 24 MP
/// remap ~1.5-2x slower than these loads (which the out-of-order core
/// overlaps across steps).
///
/// # Safety
/// AVX2; every `offset .. offset + 4` lies inside the buffer at `base`
/// (so no offset is negative).
#[inline(always)]
unsafe fn gather(base: *const u8, offsets: __m256i) -> __m256i {
    // SAFETY: the caller's guarantees are `gather_at`'s.
    unsafe { gather_at(base, &lane_offsets(offsets)) }
}

/// The eight byte offsets of a step as `usize`s, for the scalar loads of
/// [`gather_at`]. Taken out once per step, so that the loads of both
/// window rows (and several loads per row) share them: extracting the
/// lanes of a vector again for each row was a fifth of a kernel's
/// instructions.
///
/// # Safety
/// AVX2; no offset is negative (they are zero-extended, which costs no
/// instruction, unlike a sign extension per lane).
#[inline(always)]
unsafe fn lane_offsets(offsets: __m256i) -> [usize; LANES] {
    let mut o = [0u32; LANES];
    // SAFETY: `o` holds 8 lanes; the caller guarantees AVX2.
    unsafe { _mm256_storeu_si256(o.as_mut_ptr().cast(), offsets) };
    o.map(|v| v as usize)
}

/// [`gather`] at offsets taken out by [`lane_offsets`], from `base`: the
/// source's first byte, or a row further down for a window's lower taps.
///
/// # Safety
/// AVX2; every `base + offset .. + 4` lies inside one buffer.
#[inline(always)]
unsafe fn gather_at(base: *const u8, o: &[usize; LANES]) -> __m256i {
    // SAFETY: the caller guarantees AVX2 and that the reads are in bounds.
    unsafe {
        let r = |i: usize| base.wrapping_add(o[i]).cast::<i32>().read_unaligned();
        _mm256_setr_epi32(r(0), r(1), r(2), r(3), r(4), r(5), r(6), r(7))
    }
}

/// Reads 8 bytes at each of four byte offsets of `base` (scalar loads, as
/// in [`gather`]).
///
/// # Safety
/// AVX2; every `offset .. offset + 8` lies inside the buffer at `base`.
#[target_feature(enable = "avx2")]
unsafe fn gather8(base: *const u8, offsets: __m128i) -> __m256i {
    let mut o = [0i32; 4];
    // SAFETY: `o` holds 4 lanes; the caller guarantees the reads are in bounds.
    unsafe {
        _mm_storeu_si128(o.as_mut_ptr().cast(), offsets);
        let r = |i: usize| base.add(o[i] as usize).cast::<i64>().read_unaligned();
        _mm256_setr_epi64x(r(0), r(1), r(2), r(3))
    }
}

/// Runs `f(k, k % 3, step)` for every full step of a row whose windows are
/// inside and `pixel(x, px)` for the others and for the tail, `px` being
/// the `nc` samples of pixel `x` at `out`. The per-channel kernels pick
/// their lanes' channels by `k % 3`.
///
/// Always inlined into the AVX2 kernels (which have the instruction set)
/// rather than a `target_feature` function of its own: LLVM once stopped
/// inlining it into the per-channel kernels, and the kernel body became a
/// closure called through memory per step.
///
/// # Safety
/// AVX2; `out` is valid for `nc · xy.len() / 2` samples, and `f(k, _, _)`
/// writes only those of pixels `8k .. 8k + 8` (so the two never overlap).
#[inline(always)]
unsafe fn walk<T>(
    xy: &[i32],
    g: &Geometry,
    mut f: impl FnMut(usize, usize, Step),
    (out, nc): (*mut T, usize),
    pixel: &mut dyn FnMut(usize, &mut [T]),
) {
    // SAFETY: x < n, so the pixel's samples are inside `out`, and `f` is
    // not writing them.
    let mut scalar = |x: usize| {
        pixel(x, unsafe {
            std::slice::from_raw_parts_mut(out.add(nc * x), nc)
        })
    };
    let n = xy.len() / 2;
    let steps = n / LANES;
    // Both counters are carried along: `k % 3` and `k % prefetch_every`
    // cost a multiply and a division per step.
    let (mut third, mut to_prefetch) = (0, 0);
    for k in 0..steps {
        if to_prefetch == 0 {
            g.prefetch(xy, LANES * (k + AHEAD));
            to_prefetch = g.prefetch_every;
        }
        to_prefetch -= 1;
        // SAFETY: step k reads xy[16k .. 16k + 16], inside since k < n / 8.
        match unsafe { step(xy.as_ptr().add(2 * LANES * k), g) } {
            Some(s) => f(k, third, s),
            None => (LANES * k..LANES * (k + 1)).for_each(&mut scalar),
        }
        third = if third == 2 { 0 } else { third + 1 };
    }
    (LANES * steps..n).for_each(scalar);
}

/// u8 with `NC` = 1 or 3 channels; see the module documentation.
///
/// # Safety
/// AVX2; `src` is an image of `w x h` pixels of `NC` bytes with rows
/// `stride` bytes apart; `row` holds `NC · xy.len() / 2` bytes.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn row_u8<const NC: usize>(
    src: &[u8],
    stride: usize,
    (w, h): (usize, usize),
    xy: &[i32],
    row: &mut [u8],
    pixel: &mut dyn FnMut(usize, &mut [u8]),
) -> bool {
    // Gray reads 4 bytes at the left tap, RGB 8.
    let read = if NC == 1 { 4 } else { 8 };
    if row.len() != NC * (xy.len() / 2) {
        return false;
    }
    let Some(g) = Geometry::new(src.as_ptr(), src.len(), stride, NC, 2, (w, h), read) else {
        return false;
    };
    let base = src.as_ptr();
    let out = row.as_mut_ptr();
    let stride_v = _mm256_set1_epi32(g.stride);
    // The left and right taps' samples as 16-bit pairs (p0 | p1 << 16).
    let pairs = _mm256_setr_epi8(
        0, -1, 1, -1, 4, -1, 5, -1, 8, -1, 9, -1, 12, -1, 13, -1, 0, -1, 1, -1, 4, -1, 5, -1, 8,
        -1, 9, -1, 12, -1, 13, -1,
    );
    let body = |k: usize, _, s: Step| {
        let below = _mm256_add_epi32(s.top, stride_v);
        // SAFETY (loads): `step` admitted only windows whose reads end
        // before `reach`, i.e. inside `src`. (Stores): `row` holds
        // NC · n bytes and step k writes NC · 8 of them from NC · 8k.
        if NC == 1 {
            let (t, b) = unsafe { (gather(base, s.top), gather(base, below)) };
            let wx = weight_pairs(s.fx);
            let top = _mm256_madd_epi16(_mm256_shuffle_epi8(t, pairs), wx);
            let bottom = _mm256_madd_epi16(_mm256_shuffle_epi8(b, pairs), wx);
            let v = vertical(top, bottom, s.fy);
            unsafe { store_gray_u8(out.add(LANES * k), v) };
        } else {
            // Per pixel and row one 8-byte read [r0 g0 b0 r1 g1 b1 _ _],
            // widened to 16 bits and reordered into (left, right) pairs per
            // channel [r0 r1 g0 g1 b0 b1 _ _]. The pixels are gathered in
            // the order 0 4 1 5 | 2 6 3 7 so that register q holds pixels q
            // and q + 4, one per 128-bit lane, like the weights below.
            let order = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7);
            let pairs = _mm256_setr_epi8(
                0, 1, 6, 7, 2, 3, 8, 9, 4, 5, 10, 11, 12, 13, 14, 15, 0, 1, 6, 7, 2, 3, 8, 9, 4, 5,
                10, 11, 12, 13, 14, 15,
            );
            let line = |offsets: __m256i| {
                let offsets = _mm256_permutevar8x32_epi32(offsets, order);
                // SAFETY: `step` admitted only reads inside `src`.
                let (p, q) = unsafe {
                    (
                        gather8(base, _mm256_castsi256_si128(offsets)),
                        gather8(base, _mm256_extracti128_si256::<1>(offsets)),
                    )
                };
                let widen = |h: __m128i| _mm256_shuffle_epi8(_mm256_cvtepu8_epi16(h), pairs);
                [
                    widen(_mm256_castsi256_si128(p)),
                    widen(_mm256_extracti128_si256::<1>(p)),
                    widen(_mm256_castsi256_si128(q)),
                    widen(_mm256_extracti128_si256::<1>(q)),
                ]
            };
            let (t, b) = (line(s.top), line(below));
            let spread = |v: __m256i| {
                [
                    _mm256_shuffle_epi32::<0x00>(v),
                    _mm256_shuffle_epi32::<0x55>(v),
                    _mm256_shuffle_epi32::<0xAA>(v),
                    _mm256_shuffle_epi32::<0xFF>(v),
                ]
            };
            let (wx, fy) = (spread(weight_pairs(s.fx)), spread(s.fy));
            // Each lane: R, G, B and a discarded fourth value.
            let v: [__m256i; 4] = std::array::from_fn(|q| {
                vertical(
                    _mm256_madd_epi16(t[q], wx[q]),
                    _mm256_madd_epi16(b[q], wx[q]),
                    fy[q],
                )
            });
            unsafe { store_rgb_u8(out.add(3 * LANES * k), v) };
        }
    };
    // SAFETY: AVX2 is enabled here; `row` holds NC samples per map pixel
    // (checked above) and the body writes only step k's pixels.
    unsafe { walk(xy, &g, body, (out, NC), pixel) };
    true
}

/// u16 with one channel; see the module documentation. The samples reach
/// 65535, beyond `madd`'s signed 16-bit range, so both stages multiply in
/// 32 bits.
///
/// # Safety
/// AVX2; `src` is an image of `w x h` samples with rows `stride` samples
/// apart; `row` holds `xy.len() / 2` samples.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn row_u16(
    src: &[u16],
    stride: usize,
    (w, h): (usize, usize),
    xy: &[i32],
    row: &mut [u16],
    pixel: &mut dyn FnMut(usize, &mut [u16]),
) -> bool {
    if row.len() != xy.len() / 2 {
        return false;
    }
    let Some(g) = Geometry::new(
        src.as_ptr().cast(),
        2 * src.len(),
        2 * stride,
        2,
        2,
        (w, h),
        4,
    ) else {
        return false;
    };
    let base = src.as_ptr().cast::<u8>();
    let out = row.as_mut_ptr();
    let stride_v = _mm256_set1_epi32(g.stride);
    let low = _mm256_set1_epi32(0xffff);
    let body = |k: usize, _, s: Step| {
        let fx = s.fx;
        let line = |offsets: __m256i| {
            // SAFETY: `step` admitted only reads inside `src`.
            let p = unsafe { gather(base, offsets) };
            let (l, r) = (_mm256_and_si256(p, low), _mm256_srli_epi32(p, 16));
            // l · 256 + (r - l) · fx, at most 65535 · 256.
            _mm256_add_epi32(
                _mm256_slli_epi32(l, FRAC_BITS as i32),
                _mm256_mullo_epi32(_mm256_sub_epi32(r, l), fx),
            )
        };
        let v = vertical(line(s.top), line(_mm256_add_epi32(s.top, stride_v)), s.fy);
        // SAFETY: step k writes samples 8k .. 8k + 8 of `row`.
        unsafe { store_u16(out.add(LANES * k), v) };
    };
    // SAFETY: as in `row_u8`.
    unsafe { walk(xy, &g, body, (out, 1), pixel) };
    true
}

/// Stores eight values in `0..=255`, one per lane, as bytes.
///
/// # Safety
/// AVX2; `dst` is valid for 8 bytes.
#[target_feature(enable = "avx2")]
unsafe fn store_gray_u8(dst: *mut u8, v: __m256i) {
    let v16 = _mm256_packus_epi32(v, v);
    let v8 = _mm256_packus_epi16(v16, v16);
    let v8 = _mm256_permutevar8x32_epi32(v8, _mm256_setr_epi32(0, 4, 0, 4, 0, 4, 0, 4));
    // SAFETY: the caller guarantees 8 writable bytes.
    unsafe { _mm_storel_epi64(dst.cast(), _mm256_castsi256_si128(v8)) };
}

/// Stores eight values in `0..=65535`, one per lane, as u16.
///
/// # Safety
/// AVX2; `dst` is valid for 8 samples.
#[target_feature(enable = "avx2")]
unsafe fn store_u16(dst: *mut u16, v: __m256i) {
    let v16 = _mm256_permute4x64_epi64::<0b1000>(_mm256_packus_epi32(v, v));
    // SAFETY: the caller guarantees 16 writable bytes.
    unsafe { _mm_storeu_si128(dst.cast(), _mm256_castsi256_si128(v16)) };
}

/// Stores eight RGB pixels given as four registers, register q holding
/// pixel q in its low and pixel q + 4 in its high 128-bit lane, each as
/// R, G, B and a discarded fourth value in `0..=255`.
///
/// # Safety
/// AVX2; `dst` is valid for 24 bytes.
#[target_feature(enable = "avx2")]
unsafe fn store_rgb_u8(dst: *mut u8, v: [__m256i; 4]) {
    let v16 = [
        _mm256_packus_epi32(v[0], v[1]),
        _mm256_packus_epi32(v[2], v[3]),
    ];
    // Lane 0: pixels 0-3 as RGB_, lane 1: pixels 4-7.
    let v8 = _mm256_packus_epi16(v16[0], v16[1]);
    let drop = _mm256_setr_epi8(
        0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1, -1, 0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13,
        14, -1, -1, -1, -1,
    );
    let packed = _mm256_permutevar8x32_epi32(
        _mm256_shuffle_epi8(v8, drop),
        _mm256_setr_epi32(0, 1, 2, 4, 5, 6, 3, 7),
    );
    // SAFETY: the caller guarantees 24 writable bytes.
    unsafe {
        _mm_storeu_si128(dst.cast(), _mm256_castsi256_si128(packed));
        _mm_storel_epi64(dst.add(16).cast(), _mm256_extracti128_si256::<1>(packed));
    }
}

/// Keys weights of the four taps for fractions `k / 256`, lane by lane:
/// the same `f32` operations in the same order as [`super::keys_weights`]
/// (no fused multiply-add), hence the same bits as the scalar table.
///
/// Not a `target_feature` function but always inlined into one: LLVM
/// declined to inline the 4x4 kernels on its own, and the calls with
/// their vector arguments passed through memory took ~half the time.
///
/// # Safety
/// AVX2.
#[inline(always)]
unsafe fn keys(k: __m256i) -> [__m256; 4] {
    // SAFETY: the caller guarantees AVX2.
    unsafe {
        let one = _mm256_set1_ps(1.0);
        // Multiplying by 2^-8 is exact, like the scalar division by 256.
        let t = _mm256_mul_ps(
            _mm256_cvtepi32_ps(k),
            _mm256_set1_ps(1.0 / (1 << FRAC_BITS) as f32),
        );
        let u = _mm256_sub_ps(one, t);
        let near = |d: __m256| {
            let c = _mm256_sub_ps(
                _mm256_mul_ps(_mm256_set1_ps(KEYS_A + 2.0), d),
                _mm256_set1_ps(KEYS_A + 3.0),
            );
            _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(c, d), d), one)
        };
        let far = |s: __m256| {
            let s1 = _mm256_sub_ps(s, one);
            _mm256_mul_ps(
                _mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(KEYS_A), s), s1),
                s1,
            )
        };
        [far(t), near(t), near(u), far(u)]
    }
}

/// `Σ_j wy[j] Σ_i wx[i] tap(i, j)` in the scalar `convolve`'s order, from
/// zero, rounded half up and clamped to `0..=max` (NaN to 0) like
/// `Sample::from_f32`.
///
/// # Safety
/// AVX2 (inlined like [`keys`]).
#[inline(always)]
unsafe fn cubic(
    wx: &[__m256; 4],
    wy: &[__m256; 4],
    tap: impl Fn(usize, usize) -> __m256,
    max: f32,
) -> __m256i {
    // SAFETY: the caller guarantees AVX2.
    unsafe {
        let mut acc = _mm256_setzero_ps();
        for (j, b) in wy.iter().enumerate() {
            let mut line = _mm256_setzero_ps();
            for (i, a) in wx.iter().enumerate() {
                line = _mm256_add_ps(line, _mm256_mul_ps(*a, tap(i, j)));
            }
            acc = _mm256_add_ps(acc, _mm256_mul_ps(*b, line));
        }
        // max_ps returns its second operand for NaN.
        let v = _mm256_max_ps(_mm256_add_ps(acc, _mm256_set1_ps(0.5)), _mm256_setzero_ps());
        _mm256_cvttps_epi32(_mm256_min_ps(v, _mm256_set1_ps(max)))
    }
}

/// The eight lanes of `v`.
#[target_feature(enable = "avx2")]
fn lanes(v: __m256i) -> [i32; 8] {
    let mut o = [0i32; 8];
    // SAFETY: `o` holds 32 bytes.
    unsafe { _mm256_storeu_si256(o.as_mut_ptr().cast(), v) };
    o
}

/// Bicubic u8 with `NC` = 1 or 3 channels; see [`row_u8`] for the contract.
///
/// # Safety
/// As [`row_u8`].
#[target_feature(enable = "avx2")]
pub(super) unsafe fn cubic_u8<const NC: usize>(
    src: &[u8],
    stride: usize,
    (w, h): (usize, usize),
    xy: &[i32],
    row: &mut [u8],
    pixel: &mut dyn FnMut(usize, &mut [u8]),
) -> bool {
    // Gray reads the 4 bytes of a window row, RGB 16 (12 used).
    let read = if NC == 1 { 4 } else { 16 };
    if row.len() != NC * (xy.len() / 2) {
        return false;
    }
    let Some(g) = Geometry::new(src.as_ptr(), src.len(), stride, NC, 4, (w, h), read) else {
        return false;
    };
    let base = src.as_ptr();
    let out = row.as_mut_ptr();
    let stride_v = _mm256_set1_epi32(g.stride);
    let byte = _mm256_set1_epi32(0xff);
    let body = |k: usize, _, s: Step| {
        // SAFETY: AVX2 is enabled here.
        let (wx, wy) = unsafe { (keys(s.fx), keys(s.fy)) };
        let rows: [__m256i; 4] = std::array::from_fn(|j| {
            _mm256_add_epi32(
                s.top,
                _mm256_mullo_epi32(_mm256_set1_epi32(j as i32), stride_v),
            )
        });
        // SAFETY (loads): `step` admitted only windows whose reads end
        // inside `src`. (Stores): step k writes pixels 8k .. 8k + 8 of `row`.
        if NC == 1 {
            // Lane = pixel; one 4-byte read per window row.
            let p = rows.map(|r| unsafe { gather(base, r) });
            let tap = |i: usize, j: usize| {
                let v = _mm256_and_si256(
                    _mm256_srlv_epi32(p[j], _mm256_set1_epi32(8 * i as i32)),
                    byte,
                );
                _mm256_cvtepi32_ps(v)
            };
            // SAFETY: AVX2 is enabled here.
            let v = unsafe { cubic(&wx, &wy, tap, 255.0) };
            unsafe { store_gray_u8(out.add(LANES * k), v) };
        } else {
            let offsets = rows.map(|r| lanes(r));
            // SAFETY: AVX2 is enabled here; `step` admitted only reads
            // inside `src`.
            let v = unsafe {
                [
                    rgb_cubic::<0>(base, &offsets, &wx, &wy),
                    rgb_cubic::<1>(base, &offsets, &wx, &wy),
                    rgb_cubic::<2>(base, &offsets, &wx, &wy),
                    rgb_cubic::<3>(base, &offsets, &wx, &wy),
                ]
            };
            unsafe { store_rgb_u8(out.add(3 * LANES * k), v) };
        }
    };
    // SAFETY: as in `row_u8`.
    unsafe { walk(xy, &g, body, (out, NC), pixel) };
    true
}

/// Register `Q` of an RGB bicubic step: pixel `Q` in the low, `Q + 4` in
/// the high 128-bit lane, channels R, G, B, 0 in each (the layout of
/// [`store_rgb_u8`]). Each window row is one 16-byte read per pixel (12
/// used); each tap is moved into place with one byte shuffle. A function
/// of its own, always inlined, with `Q` a constant: as a closure over `q`
/// LLVM kept it out of line.
///
/// # Safety
/// AVX2; every `offsets[j][x] .. + 16` lies inside the buffer at `base`.
#[inline(always)]
unsafe fn rgb_cubic<const Q: usize>(
    base: *const u8,
    offsets: &[[i32; 8]; 4],
    wx: &[__m256; 4],
    wy: &[__m256; 4],
) -> __m256i {
    // SAFETY: the caller guarantees AVX2 and the reads.
    unsafe {
        let p: [__m256i; 4] = std::array::from_fn(|j| {
            let at = |x: usize| _mm_loadu_si128(base.add(offsets[j][x] as usize).cast());
            _mm256_set_m128i(at(Q + 4), at(Q))
        });
        let tap = |i: usize, j: usize| {
            let b = 3 * i as i8;
            #[rustfmt::skip]
            let select = _mm256_setr_epi8(
                b, -1, -1, -1, b + 1, -1, -1, -1, b + 2, -1, -1, -1, -1, -1, -1, -1,
                b, -1, -1, -1, b + 1, -1, -1, -1, b + 2, -1, -1, -1, -1, -1, -1, -1,
            );
            _mm256_cvtepi32_ps(_mm256_shuffle_epi8(p[j], select))
        };
        // Pixel Q's weights in every lane of the low half, Q + 4's in the high.
        let spread =
            |w: &[__m256; 4]| w.map(|v| _mm256_permutevar_ps(v, _mm256_set1_epi32(Q as i32)));
        cubic(&spread(wx), &spread(wy), tap, 255.0)
    }
}

/// Bicubic u16 with one channel; see [`row_u16`] for the contract.
///
/// # Safety
/// As [`row_u16`].
#[target_feature(enable = "avx2")]
pub(super) unsafe fn cubic_u16(
    src: &[u16],
    stride: usize,
    (w, h): (usize, usize),
    xy: &[i32],
    row: &mut [u16],
    pixel: &mut dyn FnMut(usize, &mut [u16]),
) -> bool {
    if row.len() != xy.len() / 2 {
        return false;
    }
    let Some(g) = Geometry::new(
        src.as_ptr().cast(),
        2 * src.len(),
        2 * stride,
        2,
        4,
        (w, h),
        8,
    ) else {
        return false;
    };
    let base = src.as_ptr().cast::<u8>();
    let out = row.as_mut_ptr();
    let stride_v = _mm256_set1_epi32(g.stride);
    let low = _mm256_set1_epi32(0xffff);
    // One 8-byte read per pixel and window row; splitting the four reads
    // of two registers into taps (0, 1) and (2, 3) leaves the pixels in the
    // order 0 1 4 5 | 2 3 6 7, so the fractions are put in that order too
    // and the results back (the permutation is its own inverse).
    let order = _mm256_setr_epi32(0, 1, 4, 5, 2, 3, 6, 7);
    let body = |k: usize, _, s: Step| {
        // SAFETY: AVX2 is enabled here.
        let (wx, wy) = unsafe {
            (
                keys(_mm256_permutevar8x32_epi32(s.fx, order)),
                keys(_mm256_permutevar8x32_epi32(s.fy, order)),
            )
        };
        let p: [[__m256i; 2]; 4] = std::array::from_fn(|j| {
            let r = _mm256_add_epi32(
                s.top,
                _mm256_mullo_epi32(_mm256_set1_epi32(j as i32), stride_v),
            );
            // SAFETY: `step` admitted only reads inside `src`.
            let (a, b) = unsafe {
                (
                    _mm256_castsi256_ps(gather8(base, _mm256_castsi256_si128(r))),
                    _mm256_castsi256_ps(gather8(base, _mm256_extracti128_si256::<1>(r))),
                )
            };
            [
                _mm256_castps_si256(_mm256_shuffle_ps::<0b10_00_10_00>(a, b)),
                _mm256_castps_si256(_mm256_shuffle_ps::<0b11_01_11_01>(a, b)),
            ]
        });
        let tap = |i: usize, j: usize| {
            let v = p[j][i / 2];
            let v = if i.is_multiple_of(2) {
                _mm256_and_si256(v, low)
            } else {
                _mm256_srli_epi32(v, 16)
            };
            _mm256_cvtepi32_ps(v)
        };
        // SAFETY: AVX2 is enabled here.
        let v = unsafe { cubic(&wx, &wy, tap, 65535.0) };
        let v = _mm256_permutevar8x32_epi32(v, order);
        // SAFETY: step k writes samples 8k .. 8k + 8 of `row`.
        unsafe { store_u16(out.add(LANES * k), v) };
    };
    // SAFETY: as in `row_u8`.
    unsafe { walk(xy, &g, body, (out, 1), pixel) };
    true
}

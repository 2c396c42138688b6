//! Three planes written out as R, G, B pixels: the last step of every
//! demosaicer, which computes in planes.
//!
//! The element-wise loop stores one sample at a time (LLVM does not turn a
//! stride-3 store into shuffles, and a loop over fixed blocks of 16 pixels
//! was no faster): at 24 MP it took 4 % of "best"'s time. With AVX-512 the
//! 16-bit samples of raw data take three two-table permutes and three
//! blends per 32 pixels instead; with AVX2 alone, nine byte shuffles,
//! six ORs and three lane moves per 16 pixels.

/// Writes `r`, `g` and `b` (each at least `out.len() / 3` long) into `out`
/// as pixels, one sample at a time.
#[inline(always)]
pub(crate) fn each<T: Copy>([r, g, b]: [&[T]; 3], out: &mut [T]) {
    for (o, ((r, g), b)) in out.chunks_exact_mut(3).zip(r.iter().zip(g).zip(b)) {
        o[0] = *r;
        o[1] = *g;
        o[2] = *b;
    }
}

/// [`each`] for 16-bit samples, 32 pixels a step with AVX-512 or 16 with
/// AVX2 where the CPU has them (and `IMGFORM_ISA` allows them); the same
/// samples either way.
#[inline(always)]
pub(crate) fn u16s(planes: [&[u16]; 3], out: &mut [u16]) {
    #[cfg(target_arch = "x86_64")]
    let done = {
        use crate::cpu::{level, Level};
        // SAFETY: the level says the CPU has AVX-512 F and BW, or AVX2.
        match level() {
            Level::Avx512 => unsafe { u16s_avx512(planes, out) },
            Level::Avx2 => unsafe { u16s_avx2(planes, out) },
            Level::Baseline => 0,
        }
    };
    #[cfg(not(target_arch = "x86_64"))]
    let done = 0;
    each(planes.map(|p| &p[done..]), &mut out[3 * done..]);
}

/// The byte shuffles that move each plane's samples into block `k` (bytes
/// `16 k .. 16 k + 16`) of eight pixels' 24 samples, the same in both
/// 128-bit lanes: byte `i` of plane `c`'s takes byte `i % 2` of the
/// plane's pixel of sample `8 k + i / 2` if that sample is the plane's
/// colour, and zero (a set top bit) if not.
#[cfg(target_arch = "x86_64")]
const fn picks(k: usize) -> [[u8; 32]; 3] {
    let mut bytes = [[0x80; 32]; 3];
    let mut i = 0;
    while i < 16 {
        let sample = 8 * k + i / 2;
        let byte = (2 * (sample / 3) + i % 2) as u8;
        (bytes[sample % 3][i], bytes[sample % 3][16 + i]) = (byte, byte);
        i += 1;
    }
    bytes
}

/// [`picks`] of every block.
#[cfg(target_arch = "x86_64")]
const PICKS: [[[u8; 32]; 3]; 3] = [picks(0), picks(1), picks(2)];

/// The whole steps of 16 pixels of [`u16s`] with AVX2; returns the pixels
/// written. A byte shuffle stays within 128-bit lanes, so a step
/// interleaves pixels 0-7 in the low lanes and 8-15 in the high ones
/// (three blocks of 16 bytes each), then moves the six blocks into
/// pixel order.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn u16s_avx2([r, g, b]: [&[u16]; 3], out: &mut [u16]) -> usize {
    use std::arch::x86_64::*;
    const STEP: usize = 16;
    let n = out.len() / 3;
    assert!(r.len() >= n && g.len() >= n && b.len() >= n);
    // SAFETY (every load and store below): the steps stay within the `n`
    // pixels the assertion and `out`'s length hold, and the loads and
    // stores are unaligned ones.
    let picks = PICKS.map(|block| block.map(|m| unsafe { _mm256_loadu_si256(m.as_ptr().cast()) }));
    for (step, out) in out[..3 * (n - n % STEP)]
        .chunks_exact_mut(3 * STEP)
        .enumerate()
    {
        let x = step * STEP;
        let load = |p: &[u16]| unsafe { _mm256_loadu_si256(p[x..x + STEP].as_ptr().cast()) };
        let planes = [load(r), load(g), load(b)];
        let [v0, v1, v2] = picks.map(|[pr, pg, pb]| {
            let red_green = _mm256_or_si256(
                _mm256_shuffle_epi8(planes[0], pr),
                _mm256_shuffle_epi8(planes[1], pg),
            );
            _mm256_or_si256(red_green, _mm256_shuffle_epi8(planes[2], pb))
        });
        // Blocks 0-2 of the low pixels, then of the high ones.
        let blocks = [
            _mm256_permute2x128_si256::<0x20>(v0, v1),
            _mm256_permute2x128_si256::<0x30>(v2, v0),
            _mm256_permute2x128_si256::<0x31>(v1, v2),
        ];
        for (k, v) in blocks.into_iter().enumerate() {
            let dst = &mut out[STEP * k..STEP * (k + 1)];
            unsafe { _mm256_storeu_si256(dst.as_mut_ptr().cast(), v) };
        }
    }
    n - n % STEP
}

/// Pixels per step of [`u16s_avx512`]: one 512-bit register of each plane.
#[cfg(target_arch = "x86_64")]
const STEP: usize = 32;

/// For output register `k` of a step (samples `32 k .. 32 k + 32` of its
/// 96), where each sample comes from: its pixel's index in the step (of
/// red, or of green plus 32, for the two-table permute of red and green),
/// and whether it is blue's.
#[cfg(target_arch = "x86_64")]
const fn sources(k: usize) -> ([u16; STEP], [u16; STEP], u32) {
    let (mut red_green, mut blue, mut is_blue) = ([0; STEP], [0; STEP], 0);
    let mut j = 0;
    while j < STEP {
        let (pixel, channel) = ((STEP * k + j) / 3, (STEP * k + j) % 3);
        match channel {
            0 => red_green[j] = pixel as u16,
            1 => red_green[j] = (STEP + pixel) as u16,
            _ => {
                blue[j] = pixel as u16;
                is_blue |= 1 << j;
            }
        }
        j += 1;
    }
    (red_green, blue, is_blue)
}

#[cfg(target_arch = "x86_64")]
const SOURCES: [([u16; STEP], [u16; STEP], u32); 3] = [sources(0), sources(1), sources(2)];

/// The whole steps of [`u16s`]; returns the pixels written.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw")]
fn u16s_avx512([r, g, b]: [&[u16]; 3], out: &mut [u16]) -> usize {
    use std::arch::x86_64::*;
    let n = out.len() / 3;
    assert!(r.len() >= n && g.len() >= n && b.len() >= n);
    // SAFETY (every load and store below): the steps stay within the `n`
    // pixels the assertion and `out`'s length hold, and the loads and
    // stores are unaligned ones.
    let table = |t: &[u16; STEP]| unsafe { _mm512_loadu_si512(t.as_ptr().cast()) };
    let tables = SOURCES.map(|(rg, b, mask)| (table(&rg), table(&b), mask));
    for (step, out) in out[..3 * (n - n % STEP)]
        .chunks_exact_mut(3 * STEP)
        .enumerate()
    {
        let x = step * STEP;
        let load = |p: &[u16]| unsafe { _mm512_loadu_si512(p[x..x + STEP].as_ptr().cast()) };
        let (vr, vg, vb) = (load(r), load(g), load(b));
        for (k, &(rg, bb, mask)) in tables.iter().enumerate() {
            let red_green = _mm512_permutex2var_epi16(vr, rg, vg);
            let blue = _mm512_permutexvar_epi16(bb, vb);
            let v = _mm512_mask_blend_epi16(mask, red_green, blue);
            let dst = &mut out[STEP * k..STEP * (k + 1)];
            unsafe { _mm512_storeu_si512(dst.as_mut_ptr().cast(), v) };
        }
    }
    n - n % STEP
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An interleaving of 16-bit planes.
    type Build = fn([&[u16]; 3], &mut [u16]);

    /// Every build this CPU has: the widest (through [`u16s`]) and AVX2's.
    fn builds() -> Vec<Build> {
        let mut builds: Vec<Build> = vec![u16s];
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            builds.push(|planes, out| {
                // SAFETY: the CPU has AVX2.
                let done = unsafe { u16s_avx2(planes, out) };
                each(planes.map(|p| &p[done..]), &mut out[3 * done..]);
            });
        }
        builds
    }

    #[test]
    fn every_width_gives_the_samples_in_pixel_order() {
        // Widths around both steps, and planes longer than the row; samples
        // whose high and low bytes differ.
        for n in [0, 1, 15, 16, 17, 31, 32, 33, 48, 64, 95, 100] {
            let planes: [Vec<u16>; 3] = std::array::from_fn(|c| {
                (0..n + 5)
                    .map(|x| (1000 * c + 257 * x + 1) as u16)
                    .collect()
            });
            let planes = planes.each_ref().map(|p| &p[..]);
            let want: Vec<u16> = (0..n)
                .flat_map(|x| (0..3).map(move |c| planes[c][x]))
                .collect();
            for (i, build) in builds().into_iter().enumerate() {
                let mut out = vec![0u16; 3 * n];
                build(planes, &mut out);
                assert_eq!(out, want, "{n} pixels, build {i}");
            }
        }
    }
}

//! Three planes written out as R, G, B pixels: the last step of every
//! demosaicer, which computes in planes.
//!
//! The element-wise loop stores one sample at a time (LLVM does not turn a
//! stride-3 store into shuffles, and a loop over fixed blocks of 16 pixels
//! was no faster): at 24 MP it took 4 % of "best"'s time. With AVX-512 the
//! 16-bit samples of raw data take three two-table permutes and three
//! blends per 32 pixels instead, and with AVX2 samples of any size nine
//! byte shuffles, six ORs and three lane moves per 32 bytes of each plane.

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

/// [`each`], 32 bytes of each plane a step with AVX2 where the CPU has it
/// (and `IMGFORM_ISA` allows it); the same samples either way.
#[inline(always)]
pub(crate) fn pixels<T: Copy>(planes: [&[T]; 3], out: &mut [T]) {
    #[cfg(target_arch = "x86_64")]
    let done = if crate::cpu::level() >= crate::cpu::Level::Avx2 {
        // SAFETY: the level says the CPU has AVX2.
        unsafe { lanes_avx2(planes, out) }
    } else {
        0
    };
    #[cfg(not(target_arch = "x86_64"))]
    let done = 0;
    each(planes.map(|p| &p[done..]), &mut out[3 * done..]);
}

/// [`pixels`] for 16-bit samples, 32 pixels a step with AVX-512 where the
/// CPU has it.
#[inline(always)]
pub(crate) fn u16s(planes: [&[u16]; 3], out: &mut [u16]) {
    #[cfg(target_arch = "x86_64")]
    if crate::cpu::level() >= crate::cpu::Level::Avx512 {
        // SAFETY: the level says the CPU has AVX-512 F and BW.
        let done = unsafe { u16s_avx512(planes, out) };
        return each(planes.map(|p| &p[done..]), &mut out[3 * done..]);
    }
    pixels(planes, out);
}

/// The byte shuffles that move each plane's samples of `size` bytes into
/// block `k` (bytes `16 k .. 16 k + 16`) of the samples of `48 / size`
/// pixels, the same in both 128-bit lanes: byte `i` of plane `c`'s takes
/// byte `i % size` of the plane's pixel of sample `(16 k + i) / size` if
/// that sample is the plane's colour, and zero (a set top bit) if not.
#[cfg(target_arch = "x86_64")]
const fn picks(size: usize) -> [[[u8; 32]; 3]; 3] {
    assert!(16 % size == 0, "a sample size that does not divide a lane");
    let mut bytes = [[[0x80; 32]; 3]; 3];
    let mut at = 0;
    while at < 48 {
        let (k, i, sample) = (at / 16, at % 16, at / size);
        let byte = (size * (sample / 3) + at % size) as u8;
        (bytes[k][sample % 3][i], bytes[k][sample % 3][16 + i]) = (byte, byte);
        at += 1;
    }
    bytes
}

/// The whole steps of [`pixels`] with AVX2 (32 bytes of each plane);
/// returns the pixels written. A byte shuffle stays within 128-bit lanes,
/// so a step interleaves the first half of its pixels in the low lanes and
/// the second half in the high ones (three blocks of 16 bytes each), then
/// moves the six blocks into pixel order.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn lanes_avx2<T: Copy>([r, g, b]: [&[T]; 3], out: &mut [T]) -> usize {
    use std::arch::x86_64::*;
    let step = 32 / size_of::<T>();
    let n = out.len() / 3;
    assert!(r.len() >= n && g.len() >= n && b.len() >= n);
    // SAFETY (every load and store below): the steps stay within the `n`
    // pixels the assertion and `out`'s length hold, and the loads and
    // stores are unaligned ones.
    let picks = const { picks(size_of::<T>()) }
        .map(|block| block.map(|m| unsafe { _mm256_loadu_si256(m.as_ptr().cast()) }));
    for (i, out) in out[..3 * (n - n % step)]
        .chunks_exact_mut(3 * step)
        .enumerate()
    {
        let x = i * step;
        let load = |p: &[T]| unsafe { _mm256_loadu_si256(p[x..x + step].as_ptr().cast()) };
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
            let dst = &mut out[step * k..step * (k + 1)];
            unsafe { _mm256_storeu_si256(dst.as_mut_ptr().cast(), v) };
        }
    }
    n - n % step
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

    /// An interleaving of planes of `T`.
    type Build<T> = fn([&[T]; 3], &mut [T]);

    /// Every build this CPU has: the widest (through `widest`) and AVX2's.
    fn builds<T: Copy>(widest: Build<T>) -> Vec<Build<T>> {
        let mut builds = vec![widest];
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            builds.push(|planes, out| {
                // SAFETY: the CPU has AVX2.
                let done = unsafe { lanes_avx2(planes, out) };
                each(planes.map(|p| &p[done..]), &mut out[3 * done..]);
            });
        }
        builds
    }

    /// Every build of `widest` gives each width's samples in pixel order,
    /// for widths around every step, from planes longer than the row;
    /// `sample(c, x)` is plane `c`'s at `x`.
    fn check<T: Copy + PartialEq + std::fmt::Debug>(
        widest: Build<T>,
        sample: fn(usize, usize) -> T,
    ) {
        for n in [0, 1, 7, 8, 9, 15, 16, 17, 31, 32, 33, 48, 64, 65, 95, 100] {
            let planes: [Vec<T>; 3] =
                std::array::from_fn(|c| (0..n + 5).map(|x| sample(c, x)).collect());
            let planes = planes.each_ref().map(|p| &p[..]);
            let want: Vec<T> = (0..n)
                .flat_map(|x| (0..3).map(move |c| planes[c][x]))
                .collect();
            // Two fills, so that a sample left unwritten differs in one.
            for (i, build) in builds(widest).into_iter().enumerate() {
                for fill in [sample(0, 0), sample(0, 1)] {
                    let mut out = vec![fill; 3 * n];
                    build(planes, &mut out);
                    assert_eq!(out, want, "{n} pixels, build {i}");
                }
            }
        }
    }

    #[test]
    fn every_width_gives_the_samples_in_pixel_order() {
        // Samples whose bytes all differ.
        check(u16s, |c, x| (1000 * c + 257 * x + 1) as u16);
        check(pixels::<u16>, |c, x| (1000 * c + 257 * x + 1) as u16);
        check(pixels::<u8>, |c, x| (100 * c + x) as u8);
        check(pixels::<f32>, |c, x| {
            1000.0 * c as f32 + x as f32 * 1.0625 + 0.3
        });
    }
}

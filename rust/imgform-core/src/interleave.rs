//! Three planes written out as R, G, B pixels: the last step of every
//! demosaicer, which computes in planes.
//!
//! The element-wise loop stores one sample at a time (LLVM does not turn a
//! stride-3 store into shuffles, and a loop over fixed blocks of 16 pixels
//! was no faster): at 24 MP it took 4 % of "best"'s time. With AVX-512 the
//! 16-bit samples of raw data take three two-table permutes and three
//! blends per 32 pixels instead.

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

/// [`each`] for 16-bit samples, 32 pixels a step with AVX-512 where the
/// CPU has it (and `IMGFORM_ISA` allows it); the same samples either way.
#[inline(always)]
pub(crate) fn u16s(planes: [&[u16]; 3], out: &mut [u16]) {
    #[allow(unused_mut)]
    let mut done = 0;
    #[cfg(target_arch = "x86_64")]
    if crate::cpu::level() == crate::cpu::Level::Avx512 {
        // SAFETY: the level says the CPU has AVX-512 F and BW.
        done = unsafe { u16s_avx512(planes, out) };
    }
    each(planes.map(|p| &p[done..]), &mut out[3 * done..]);
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

    #[test]
    fn every_width_gives_the_samples_in_pixel_order() {
        // Widths around the step, and planes longer than the row.
        for n in [0, 1, 31, 32, 33, 64, 95, 100] {
            let planes: [Vec<u16>; 3] =
                std::array::from_fn(|c| (0..n + 5).map(|x| (1000 * c + x) as u16).collect());
            let planes = planes.each_ref().map(|p| &p[..]);
            let mut out = vec![0u16; 3 * n];
            u16s(planes, &mut out);
            let want: Vec<u16> = (0..n)
                .flat_map(|x| (0..3).map(move |c| planes[c][x]))
                .collect();
            assert_eq!(out, want, "{n} pixels");
        }
    }
}

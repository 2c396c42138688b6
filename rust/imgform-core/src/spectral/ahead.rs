//! Integrating the next row's input while the current row's noise is drawn.
//!
//! A capture does two kinds of work per row: reading the row's input (for a
//! spectral cube, 41 floats per pixel: bound by memory) and drawing its
//! noise (bound by arithmetic, the input untouched). Run one after the
//! other, they add up. [`Ahead`] interleaves them: the read-out's passes
//! over row `y` report their progress, and at each report `Ahead`
//! integrates the same share of row `y + 1`, a chunk of a few pixels at a
//! time, with software prefetches a few kilobytes in front of it. The
//! memory stream then runs while the core computes, and each line is used
//! within a microsecond of its arrival, from L1, before anything can evict
//! it (a whole row of a 24 MP cube, ~1 MB, overruns the per-core L2). The
//! integration is the same function on the same pixels whatever the
//! interleaving, so the results do not depend on it.

/// Bytes of a cache line on the CPUs the kernels target.
const LINE: usize = 64;

/// Pixels integrated per call of the input's kernel: enough to amortise the
/// call, few enough (2.6 KB of a 41-sample cube) that the integration stays
/// spread over the read-out.
const CHUNK: usize = 16;

/// How far the prefetches run ahead of the integration, bytes. At the
/// read-out's pace (~30 ns a pixel, ~5 GB/s of cube a core) 4 KiB is ~0.7
/// µs, several memory latencies; and with the chunk being integrated it
/// stays well inside the 32 KiB L1.
const PREFETCH_DISTANCE: usize = 4096;

/// A row's input kernel: `(y, x0, src, rates)` fills `rates` with the mean
/// rates (e-/s) of pixels `x0 ..` of row `y` from their input `src`, and
/// returns the offset in `rates` of the first pixel with bad input.
pub(super) trait RowRates:
    Fn(usize, usize, &[f32], &mut [f64]) -> Option<usize> + Sync
{
}

impl<F: Fn(usize, usize, &[f32], &mut [f64]) -> Option<usize> + Sync> RowRates for F {}

/// One row's integration, advanced a share at a time.
pub(super) struct Ahead<'a, F> {
    /// The row.
    y: usize,
    /// Its input, `per_pixel` values a pixel (empty: nothing to do).
    src: &'a [f32],
    per_pixel: usize,
    /// Its rates, filled as the integration advances.
    rates: &'a mut [f64],
    kernel: &'a F,
    /// Pixels integrated so far.
    done: usize,
    /// Bytes of `src` asked for so far (whole lines).
    fetched: usize,
    /// The first pixel (`y * width + x`) with bad input.
    first_bad: Option<usize>,
}

impl<'a, F: RowRates> Ahead<'a, F> {
    /// Row `y` of input `src` (`None` or empty: no row), to be integrated
    /// by `kernel` into `rates` (one per pixel).
    pub(super) fn new(
        y: usize,
        src: Option<&'a [f32]>,
        rates: &'a mut [f64],
        kernel: &'a F,
    ) -> Self {
        let src = src.unwrap_or_default();
        Self {
            y,
            per_pixel: src.len() / rates.len().max(1),
            src,
            rates,
            kernel,
            done: 0,
            fetched: 0,
            first_bad: None,
        }
    }

    /// Advances the integration to the share `done / total` of the row, so
    /// that a loop calling this as it progresses spreads the row evenly
    /// over its iterations. The lines up to [`PREFETCH_DISTANCE`] past that
    /// share are asked for now, the pixels integrated by whole chunks.
    #[inline(always)]
    pub(super) fn upto(&mut self, done: usize, total: usize) {
        if self.src.is_empty() {
            return;
        }
        let width = self.rates.len();
        let want = width * done / total.max(1);
        self.prefetch(want * self.per_pixel * size_of::<f32>() + PREFETCH_DISTANCE);
        while self.done + CHUNK <= want {
            self.integrate(self.done + CHUNK);
        }
    }

    /// Integrates what is left of the row and returns its first bad pixel.
    pub(super) fn finish(mut self) -> Option<usize> {
        self.integrate(self.rates.len());
        self.first_bad
    }

    /// Integrates the pixels from `self.done` to `end`.
    fn integrate(&mut self, end: usize) {
        let x0 = self.done;
        if x0 >= end || self.src.is_empty() {
            return;
        }
        let src = &self.src[x0 * self.per_pixel..end * self.per_pixel];
        if let Some(x) = (self.kernel)(self.y, x0, src, &mut self.rates[x0..end]) {
            let width = self.rates.len();
            self.first_bad = self.first_bad.or(Some(self.y * width + x0 + x));
        }
        self.done = end;
    }

    /// Asks for the lines of `src` up to byte `end` (clipped to the row)
    /// not asked for yet. A prefetch only moves data between memory and
    /// cache.
    #[inline(always)]
    fn prefetch(&mut self, end: usize) {
        let end = end.min(size_of_val(self.src));
        while self.fetched < end {
            #[cfg(target_arch = "x86_64")]
            {
                use std::arch::x86_64::{_mm_prefetch, _MM_HINT_NTA};
                let line = self.src.as_ptr().cast::<i8>().wrapping_add(self.fetched);
                // SAFETY: a prefetch reads nothing architecturally and
                // cannot fault; SSE, which it needs, is part of baseline
                // x86-64; and the address is inside the row anyway. The
                // non-temporal hint: each line is read once, soon, so it
                // need not displace the read-out's buffers from L2.
                unsafe { _mm_prefetch::<_MM_HINT_NTA>(line) };
            }
            self.fetched += LINE;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A kernel that records each pixel's column and flags negative input.
    fn columns(_: usize, x0: usize, src: &[f32], rates: &mut [f64]) -> Option<usize> {
        for (i, r) in rates.iter_mut().enumerate() {
            *r = (x0 + i) as f64;
        }
        src.chunks_exact(2).position(|px| px[0] < 0.0)
    }

    #[test]
    fn shares_integrate_whole_chunks_and_finish_the_rest() {
        let width = 3 * CHUNK + 5;
        let mut src = vec![1.0f32; 2 * width];
        src[2 * (CHUNK + 3)] = -1.0;
        src[2 * (2 * CHUNK + 1)] = -1.0;
        let mut rates = vec![-1.0; width];
        let mut ahead = Ahead::new(7, Some(&src), &mut rates, &columns);
        ahead.upto(1, 3);
        assert_eq!(ahead.done, CHUNK, "a third of the row: one whole chunk");
        ahead.upto(1, 4);
        assert_eq!(ahead.done, CHUNK, "a smaller share does nothing more");
        let lines = size_of_val(&src[..]).next_multiple_of(LINE);
        assert_eq!(ahead.fetched, lines, "the prefetch reached the row's end");
        ahead.upto(3, 3);
        assert_eq!(ahead.done, 3 * CHUNK);
        assert_eq!(ahead.finish(), Some(7 * width + CHUNK + 3));
        let want: Vec<f64> = (0..width).map(|x| x as f64).collect();
        assert_eq!(rates, want);
        let mut none = Ahead::new(0, None, &mut rates, &columns);
        none.upto(5, 5);
        assert_eq!((none.done, none.fetched), (0, 0));
        assert_eq!(none.finish(), None);
        assert_eq!(rates, want, "no row: the rates are left alone");
    }
}

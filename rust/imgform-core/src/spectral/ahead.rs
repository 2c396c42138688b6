//! Streaming the next row's input into cache while the current row's noise
//! is drawn.
//!
//! A capture alternates two phases per row: reading the row's input (for a
//! spectral cube, 41 floats per pixel: memory bound, one core saturates the
//! memory bus) and drawing its noise (arithmetic bound, the input untouched).
//! Run back to back, the phases add up. [`Ahead`] spreads software prefetches
//! for the next row over the noise loops, so the memory bus keeps working
//! while the core computes, and the next row's read then finds its lines in
//! cache. A prefetch only moves data between memory and cache: results do
//! not depend on it.

/// Bytes of a cache line on the CPUs the kernels target.
const LINE: usize = 64;

/// The cache lines of one row of input, asked for a share at a time.
pub(super) struct Ahead<'a> {
    row: &'a [f32],
    /// Lines of the row.
    lines: usize,
    /// Lines asked for so far.
    asked: usize,
}

impl<'a> Ahead<'a> {
    /// The lines of `row` (empty: nothing to ask for).
    pub(super) fn new(row: &'a [f32]) -> Self {
        let lines = std::mem::size_of_val(row).div_ceil(LINE);
        Self {
            row,
            lines,
            asked: 0,
        }
    }

    /// Asks for the lines up to the share `done / total` of the row, so that
    /// a loop calling this as it progresses spreads them evenly over its
    /// iterations rather than stalling on a burst.
    #[inline(always)]
    pub(super) fn upto(&mut self, done: usize, total: usize) {
        let want = self.lines * done / total.max(1);
        while self.asked < want {
            self.prefetch(self.asked * LINE);
            self.asked += 1;
        }
    }

    /// Asks for the line at byte `offset` of the row (inside it: `upto`
    /// stops at the row's last line).
    #[inline(always)]
    fn prefetch(&self, offset: usize) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let line = self.row.as_ptr().cast::<i8>().wrapping_add(offset);
            // SAFETY: a prefetch reads nothing architecturally and cannot
            // fault; SSE, which it needs, is part of baseline x86-64; and
            // the address is inside the row anyway.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(line) };
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = offset;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_line_is_asked_for_once_by_the_end() {
        // 100 floats = 400 bytes: 7 lines (the last one partial).
        let row = vec![0.0f32; 100];
        let mut ahead = Ahead::new(&row);
        assert_eq!(ahead.lines, 7);
        ahead.upto(1, 2);
        assert_eq!(ahead.asked, 3);
        ahead.upto(1, 3);
        assert_eq!(ahead.asked, 3, "a smaller share asks for nothing more");
        ahead.upto(2, 2);
        assert_eq!(ahead.asked, 7);
        let mut none = Ahead::new(&[]);
        none.upto(5, 5);
        assert_eq!(none.asked, 0);
    }
}

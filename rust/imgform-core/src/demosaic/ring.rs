//! Rows of a plane for methods that stream down a tile: a stage that reads
//! its input a few rows above and below keeps only those rows, in a ring,
//! instead of a whole plane. A dozen rings of a dozen rows stay in the
//! core's own cache where as many tile planes spill to the shared one.

/// Floats in a cache line (64 bytes).
const LINE: usize = 16;

/// Floats a buffer needs beyond its length for [`cache_aligned`].
pub(super) const ALIGN_PAD: usize = LINE - 1;

/// `buf` from its first cache-line (64-byte) boundary on, at most
/// [`ALIGN_PAD`] floats in. Rows of a multiple of 16 floats then all start
/// on a line, and 32-byte loads at multiples of 8 floats never straddle two
/// lines (a straddling load costs two).
pub(super) fn cache_aligned(buf: &mut [f32]) -> &mut [f32] {
    let skip = buf.as_ptr().align_offset(4 * LINE).min(ALIGN_PAD);
    &mut buf[skip..]
}

/// The last `depth` rows written of a plane: row `ty` lives in slot
/// `ty % depth` until row `ty + depth` replaces it. Rows of `f32`, or of
/// the integers a quantised stage keeps (`i16`).
pub(super) struct Ring<T = f32> {
    data: Vec<T>,
    /// Where the first slot starts in `data`: on a cache line.
    first: usize,
    stride: usize,
    depth: usize,
    /// The newest row written, to check in debug builds that a read row
    /// is still held.
    newest: usize,
}

impl<T: Copy + Default> Ring<T> {
    /// A ring whose rows have their column `col` on a cache line (all rows
    /// when `stride` is a multiple of a line's values): a stage that reads
    /// and writes its rows from that column on then never has a vector
    /// load straddle two lines at an aligned offset.
    pub(super) fn new(stride: usize, depth: usize, col: usize) -> Self {
        let line = 64 / std::mem::size_of::<T>();
        let lead = (line - col % line) % line;
        let data = vec![T::default(); stride * depth + line - 1 + lead];
        let first = data.as_ptr().align_offset(64).min(line - 1) + lead;
        Self {
            data,
            first,
            stride,
            depth,
            newest: 0,
        }
    }

    /// Makes rows `stride` long, at most as long as the ring was made for:
    /// a row of tiles ends with a narrower one.
    pub(super) fn fit(&mut self, stride: usize) {
        assert!(
            self.first + stride * self.depth <= self.data.len(),
            "a ring grew"
        );
        self.stride = stride;
    }

    /// Row `ty` to write, replacing row `ty - depth`.
    #[inline(always)]
    pub(super) fn row_mut(&mut self, ty: usize) -> &mut [T] {
        self.newest = ty;
        let start = self.first + (ty % self.depth) * self.stride;
        &mut self.data[start..start + self.stride]
    }

    /// Tile row `ty`, `stride` long.
    #[inline(always)]
    pub(super) fn row(&self, ty: usize) -> &[T] {
        debug_assert!(
            ty <= self.newest && self.newest - ty < self.depth,
            "row {ty} read when the ring holds {} rows up to {}",
            self.depth,
            self.newest
        );
        let start = self.first + (ty % self.depth) * self.stride;
        &self.data[start..start + self.stride]
    }
}

/// Step `j` of a sweep down a tile, one row of raw data further each step.
#[derive(Clone, Copy)]
pub(super) struct Step(pub(super) usize);

impl Step {
    /// The row a stage computes at this step, `lag` rows behind the raw
    /// data, if it is one of its rows (from `first` on).
    #[inline(always)]
    pub(super) fn due_from(self, lag: usize, first: usize) -> Option<usize> {
        self.0.checked_sub(lag).filter(|&ty| ty >= first)
    }

    /// [`Step::due_from`] for a stage of reach `r`, which lags `r` rows.
    #[inline(always)]
    pub(super) fn due(self, r: usize) -> Option<usize> {
        self.due_from(r, r)
    }
}

/// Ring depth for a stage computing row `j - from` at step `j` whose last
/// reader computes row `j - to`, reading `back` rows above it.
pub(super) const fn depth(from: usize, to: usize, back: usize) -> usize {
    to + back - from + 1
}

/// A plane's rows by tile row: a whole plane of rows `stride` long, or a
/// [`Ring`] of its last rows (whose own stride is the same).
pub(crate) trait Rows {
    fn row_of(&self, ty: usize, stride: usize) -> &[f32];
    fn row_of_mut(&mut self, ty: usize, stride: usize) -> &mut [f32];
}

impl Rows for [f32] {
    #[inline(always)]
    fn row_of(&self, ty: usize, stride: usize) -> &[f32] {
        &self[ty * stride..(ty + 1) * stride]
    }
    #[inline(always)]
    fn row_of_mut(&mut self, ty: usize, stride: usize) -> &mut [f32] {
        &mut self[ty * stride..(ty + 1) * stride]
    }
}

impl Rows for Vec<f32> {
    #[inline(always)]
    fn row_of(&self, ty: usize, stride: usize) -> &[f32] {
        self[..].row_of(ty, stride)
    }
    #[inline(always)]
    fn row_of_mut(&mut self, ty: usize, stride: usize) -> &mut [f32] {
        self[..].row_of_mut(ty, stride)
    }
}

impl Rows for Ring {
    #[inline(always)]
    fn row_of(&self, ty: usize, stride: usize) -> &[f32] {
        debug_assert_eq!(stride, self.stride);
        self.row(ty)
    }
    #[inline(always)]
    fn row_of_mut(&mut self, ty: usize, stride: usize) -> &mut [f32] {
        debug_assert_eq!(stride, self.stride);
        self.row_mut(ty)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ring_holds_its_last_rows() {
        let mut ring = Ring::new(4, 3, 0);
        for ty in 0..7 {
            ring.row_mut(ty).fill(ty as f32);
            for back in 0..3.min(ty + 1) {
                assert_eq!(ring.row(ty - back), [(ty - back) as f32; 4]);
            }
        }
        // A narrower tile: rows shrink, the slots stay.
        ring.fit(2);
        ring.row_mut(7).fill(7.0);
        assert_eq!(ring.row(7), [7.0; 2]);
    }

    #[test]
    #[should_panic(expected = "row 3 read")]
    #[cfg(debug_assertions)]
    fn reading_a_replaced_row_is_caught_in_debug_builds() {
        let mut ring: Ring = Ring::new(4, 3, 0);
        for ty in 0..7 {
            ring.row_mut(ty);
        }
        ring.row(3);
    }

    #[test]
    fn rows_of_a_multiple_of_16_floats_start_on_cache_lines() {
        let mut ring: Ring = Ring::new(48, 5, 0);
        for ty in 0..5 {
            assert_eq!(ring.row_mut(ty).as_ptr() as usize % 64, 0, "row {ty}");
        }
        // Rows of integers too: 64 of `i16` to a line.
        let mut codes: Ring<i16> = Ring::new(64, 3, 0);
        for ty in 0..3 {
            assert_eq!(codes.row_mut(ty).as_ptr() as usize % 64, 0, "row {ty}");
        }
        let mut buf = vec![0.0f32; 100 + ALIGN_PAD];
        for skip in 0..4 {
            let part = cache_aligned(&mut buf[skip..]);
            assert_eq!(part.as_ptr() as usize % 64, 0);
            assert!(part.len() >= 100 - skip);
        }
    }

    #[test]
    fn the_chosen_column_of_every_row_starts_a_cache_line() {
        for col in [0, 5, 16, 20, 31] {
            let mut ring: Ring = Ring::new(64, 4, col);
            for ty in 0..6 {
                let at = ring.row_mut(ty)[col..].as_ptr() as usize;
                assert_eq!(at % 64, 0, "column {col}, row {ty}");
            }
        }
    }
}

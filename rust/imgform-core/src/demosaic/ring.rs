//! Rows of a plane for methods that stream down a tile: a stage that reads
//! its input a few rows above and below keeps only those rows, in a ring,
//! instead of a whole plane. A dozen rings of a dozen rows stay in the
//! core's own cache where as many tile planes spill to the shared one.

/// Rows of a plane indexed by tile row.
pub(super) trait Rows {
    /// Tile row `ty`, `stride` long.
    fn row(&self, ty: usize) -> &[f32];
}

/// The last `depth` rows written of a plane: row `ty` lives in slot
/// `ty % depth` until row `ty + depth` replaces it.
pub(super) struct Ring {
    data: Vec<f32>,
    stride: usize,
    depth: usize,
    /// The newest row written, to check in debug builds that a read row
    /// is still held.
    newest: usize,
}

impl Ring {
    pub(super) fn new(stride: usize, depth: usize) -> Self {
        Self {
            data: vec![0.0; stride * depth],
            stride,
            depth,
            newest: 0,
        }
    }

    /// Makes rows `stride` long, at most as long as the ring was made for:
    /// a row of tiles ends with a narrower one.
    pub(super) fn fit(&mut self, stride: usize) {
        assert!(stride * self.depth <= self.data.len(), "a ring grew");
        self.stride = stride;
    }

    /// Row `ty` to write, replacing row `ty - depth`.
    #[inline(always)]
    pub(super) fn row_mut(&mut self, ty: usize) -> &mut [f32] {
        self.newest = ty;
        let start = (ty % self.depth) * self.stride;
        &mut self.data[start..start + self.stride]
    }
}

impl Rows for Ring {
    #[inline(always)]
    fn row(&self, ty: usize) -> &[f32] {
        debug_assert!(
            ty <= self.newest && self.newest - ty < self.depth,
            "row {ty} read when the ring holds {} rows up to {}",
            self.depth,
            self.newest
        );
        let start = (ty % self.depth) * self.stride;
        &self.data[start..start + self.stride]
    }
}

/// A whole tile plane, read as rows.
pub(super) struct Plane<'a> {
    pub(super) data: &'a [f32],
    pub(super) stride: usize,
}

impl Rows for Plane<'_> {
    #[inline(always)]
    fn row(&self, ty: usize) -> &[f32] {
        &self.data[ty * self.stride..(ty + 1) * self.stride]
    }
}

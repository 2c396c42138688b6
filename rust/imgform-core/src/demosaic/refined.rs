//! RAISR's filters over MLRI alone ([`super::Method::Raisr`], and with the
//! hash of orientation and shape [`super::Method::RaisrFast`]), over
//! [`super::differences`] ([`super::Method::RaisrCd`]) or over the fusion
//! ([`super::Method::FusionRefined`]), applied to the base's rows as they
//! stream out of its tile. The text below says MLRI for any base.
//!
//! The filters and their hash read MLRI two rows above and below an output
//! row and nothing else, so a ring of the last four MLRI rows and one of
//! the last three rows of the hash's sums are all they keep: each row MLRI
//! hands over extends the sums by a row and completes the output row two
//! above it, which is refined and handed on at once. Gathering MLRI's rows
//! into chunks and refining them as planes of sub-tiles, as the fusion must
//! for its second base ([`super::fusion`]), copied every value three times
//! and kept ~4 MB of planes per thread; this keeps ~0.3 MB. The arithmetic
//! per pixel is the planes' ([`Filters`]), so the bits are the same.

use super::mlri::Mlri;
use super::raisr::{Bank, Filters, Row, REACH};
use super::ring::Ring;
use super::tiled::{Emit, Load, StreamKernel, Tile};

/// A base (MLRI, [`super::differences::Differences`] or
/// [`super::fusion::Fusion`]) refined by the filter bank of
/// [`Filters::bank`].
pub(super) struct Refined<B: 'static, K = Mlri> {
    pub(super) base: K,
    pub(super) filters: Filters<B>,
}

/// Rows MLRI's output is kept for: the output row's three, and the row
/// below them whose arrival completes it.
const BASE_ROWS: usize = 2 * REACH;
/// Rows of the horizontal sums of the tensor kept: the 3x3 sums' three.
const SUM_ROWS: usize = 3;

pub(super) struct State<S> {
    base_state: S,
    /// MLRI's rows (own chroma, green, other chroma), clamped.
    base: [Ring; 3],
    /// The horizontal 3-sums of the gradient products (xx, xy, yy).
    sums: [Ring; 3],
    /// One row of the gradients of green.
    grad: [Vec<f32>; 2],
    /// The class of each column of the output row.
    class: Vec<u32>,
    /// The refined output row.
    out: [Vec<f32>; 3],
}

impl<B: Bank, K: StreamKernel> StreamKernel for Refined<B, K> {
    type State = State<K::State>;
    const HALO: usize = K::HALO + REACH;
    const ROWS: usize = K::ROWS;
    const COLS: usize = K::COLS;
    const AVX512: bool = K::AVX512;

    fn rows(height: usize, across: usize, threads: usize) -> usize {
        K::rows(height, across, threads)
    }

    fn state(&self, stride: usize, rows: usize) -> Self::State {
        let row = || vec![0.0f32; stride];
        State {
            base_state: self.base.state(stride, rows),
            base: [0; 3].map(|_| Ring::new(stride, BASE_ROWS, 0)),
            sums: [0; 3].map(|_| Ring::new(stride, SUM_ROWS, 0)),
            grad: [row(), row()],
            class: vec![0; stride],
            out: [row(), row(), row()],
        }
    }

    #[inline(always)]
    fn stream<E: Emit, L: Load>(&self, st: &mut Self::State, t: &Tile, raw: &L, out: &mut E) {
        let State {
            base_state,
            base,
            sums,
            grad,
            class,
            out: row,
        } = st;
        for ring in base.iter_mut().chain(sums.iter_mut()) {
            ring.fit(t.stride);
        }
        let mut rows = Rows::<B, E> {
            first: K::HALO,
            halo: Self::HALO,
            filters: &self.filters,
            t,
            base,
            sums,
            grad,
            class: &mut class[..t.stride],
            row: row.each_mut().map(|r| &mut r[..t.stride]),
            out,
        };
        // The base, run on the same tile, emits `REACH` rows and columns
        // more than the tile's output: its halo is that much narrower.
        self.base.stream(base_state, t, raw, &mut rows);
    }
}

/// Takes MLRI's rows and hands on each output row once the row two below
/// it has come.
struct Rows<'a, B: 'static, E> {
    /// The base's halo (its first row and column) and the output's.
    first: usize,
    halo: usize,
    filters: &'a Filters<B>,
    t: &'a Tile,
    base: &'a mut [Ring; 3],
    sums: &'a mut [Ring; 3],
    grad: &'a mut [Vec<f32>; 2],
    class: &'a mut [u32],
    row: [&'a mut [f32]; 3],
    out: &'a mut E,
}

impl<B: Bank, E: Emit> Emit for Rows<'_, B, E> {
    #[inline(always)]
    fn emit(&mut self, ty: usize, rows: [&[f32]; 3]) {
        let f = self.filters;
        for (ring, row) in self.base.iter_mut().zip(rows) {
            f.clamp(row, ring.row_mut(ty));
        }
        // The base's first row is tile row `first`; the hash's sums start a
        // row below it (gradients across rows), the output two below that.
        let first = self.first;
        if ty >= first + 2 {
            let y = ty - 1;
            let g = [y - 1, y, y + 1].map(|r| self.base[1].row(r));
            let sums = self.sums.each_mut().map(|s| s.row_mut(y));
            f.tensor_row(g, first + 1, self.grad, sums);
        }
        if ty >= first + 2 + REACH {
            self.refine(ty - REACH);
        }
    }
}

impl<B: Bank, E: Emit> Rows<'_, B, E> {
    /// Refines tile row `y` and hands it on.
    #[inline(always)]
    fn refine(&mut self, y: usize) {
        let (f, halo) = (self.filters, self.halo);
        let kind = self.t.kind(f.phase, y);
        let sums = self
            .sums
            .each_ref()
            .map(|s| [y - 1, y, y + 1].map(|r| s.row(r)));
        let windows: [&[f32]; 9] = std::array::from_fn(|k| self.base[k % 3].row(y + k / 3 - 1));
        let [own, green, other] = &mut self.row;
        let dst = [own, green, other].map(|r| &mut **r);
        let row = Row {
            kind,
            halo,
            sums,
            windows: &windows,
        };
        B::refine_row(f, row, self.class, dst);
        let [own, green, other] = &self.row;
        self.out.emit(y, [own, green, other]);
    }
}

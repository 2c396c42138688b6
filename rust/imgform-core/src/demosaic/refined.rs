//! RAISR's filters over MLRI alone ([`super::Method::Raisr`], and with the
//! hash of orientation and shape [`super::Method::RaisrFast`]), over
//! [`super::differences`] ([`super::Method::RaisrCd`]) or over the fusion
//! ([`super::Method::FusionRefined`]), applied to the base's rows as they
//! stream out of its tile. The text below says MLRI for any base.
//!
//! The filters and their hash read MLRI two rows above and below an output
//! row and nothing else, so a ring of the last four MLRI rows and one of
//! the last three rows of the hash's sums are all they keep ([`Window`]):
//! each row MLRI hands over extends the sums by a row and completes the
//! output row two above it, which is refined and handed on at once.
//! Gathering MLRI's rows into chunks and refining them as planes of
//! sub-tiles copied every value three times and kept ~4 MB of planes per
//! thread; this keeps ~0.3 MB. The fusion keeps a [`Window`] too, beside
//! its second base's rows ([`super::fusion`]).

use super::differences::Differences;
use super::fusion::Fusion;
use super::mlri::Mlri;
use super::oriented::Oriented;
use super::raisr::{plane, plane_mut, plane_row, Bank, Filters, Row, PITCH, REACH, WINDOWS};
use super::ring::Ring;
use super::saturation::Saturation;
use super::tiled::{Emit, Load, StreamKernel, Tile};
use super::RowKind;
use std::ops::Range;

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
    rows: Window,
}

/// What refining a streamed base keeps: its last rows, clamped, the
/// structure tensor's sums, and room for a refined row. The fusion keeps
/// one too, besides its second base's rows.
pub(super) struct Window {
    /// The base's rows, clamped, each holding its own chroma, green and
    /// other chroma [`PITCH`] apart (see [`super::raisr::plane`]), as the
    /// hashed filters read them.
    pub(super) base: Ring,
    /// The horizontal 3-sums of the gradient products (xx, xy, yy).
    sums: [Ring; 3],
    /// One row of the gradients of green.
    grad: [Vec<f32>; 2],
    /// The base's local saturation, for banks whose classes it splits.
    saturation: Saturation,
    /// The class of each column of the output row.
    class: Vec<u32>,
    /// The refined output row.
    out: [Vec<f32>; 3],
    /// The tile's stride: the length of each plane of a row of `base`.
    stride: usize,
}

/// What refining an output row reads and writes ([`Window::parts`]), all
/// `t.stride` long but the rows: the base's windows and their rows, the
/// tensor's sums, room for the classes and the row to write.
pub(super) struct Parts<'a> {
    pub(super) windows: [&'a [f32]; WINDOWS],
    pub(super) rows: [&'a [f32]; 3],
    pub(super) sums: [[&'a [f32]; 3]; 3],
    pub(super) class: &'a mut [u32],
    pub(super) dst: [&'a mut [f32]; 3],
    saturation: &'a Saturation,
}

impl Parts<'_> {
    /// Moves the classes of output row `y`'s columns `cols` that are
    /// saturated to the bank's saturated bin, if it has one.
    #[inline(always)]
    pub(super) fn saturate<B>(&mut self, f: &Filters<B>, y: usize, cols: Range<usize>) {
        if f.saturated.is_some() {
            self.saturation.classes(y, self.class, cols);
        }
    }
}

/// Whether the tiles of `K` (halo included) fit the rows' pitch.
const fn fits<K: StreamKernel>() -> bool {
    K::COLS + 2 * K::HALO <= PITCH
}

// Every refined base's tiles fit, the fusion's (the deepest) too.
const _: () = assert!(
    fits::<Refined<Oriented, Mlri>>()
        && fits::<Refined<Oriented, Differences>>()
        && fits::<Refined<Oriented, Fusion<Differences>>>()
);

/// A ring of a base's last rows, their planes [`PITCH`] apart (every
/// tile fits: see [`fits`]).
pub(super) fn planes_ring() -> Ring {
    Ring::new(3 * PITCH, BASE_ROWS, 0)
}

impl Window {
    pub(super) fn new(stride: usize) -> Self {
        let row = || vec![0.0f32; stride];
        Window {
            base: planes_ring(),
            sums: [0; 3].map(|_| Ring::new(stride, SUM_ROWS, 0)),
            grad: [row(), row()],
            saturation: Saturation::new(),
            class: vec![0; stride],
            out: [row(), row(), row()],
            stride,
        }
    }

    /// Fits the rows to a tile `stride` wide.
    pub(super) fn fit(&mut self, stride: usize) {
        for ring in self.sums.iter_mut() {
            ring.fit(stride);
        }
        self.stride = stride;
    }

    /// Takes the base's tile row `ty` of `kind` (the base's rows starting
    /// at tile row `first`) and extends the hash's sums, and the
    /// saturation's if the bank's classes need them; the output row it
    /// completes, two above it, if any.
    #[inline(always)]
    pub(super) fn push<B>(
        &mut self,
        f: &Filters<B>,
        first: usize,
        (ty, kind): (usize, RowKind),
        rows: [&[f32]; 3],
    ) -> Option<usize> {
        let dst = self.base.row_mut(ty);
        for (p, row) in rows.into_iter().enumerate() {
            f.clamp(row, plane_mut(dst, p, row.len()));
        }
        if let Some(bin) = f.saturated {
            let clamped = plane_row(self.base.row(ty), self.stride);
            self.saturation.push(kind, clamped, (ty, first), bin);
        }
        // The hash's sums start a row below the base's first row
        // (gradients across rows), the output two below that.
        if ty >= first + 2 {
            let y = ty - 1;
            let g = [y - 1, y, y + 1].map(|r| plane(self.base.row(r), 1, self.stride));
            let sums = self.sums.each_mut().map(|s| s.row_mut(y));
            f.tensor_row(g, first + 1, &mut self.grad, sums);
        }
        (ty >= first + 2 + REACH).then(|| ty - REACH)
    }

    /// The tensor's 3x3 sums at row `y`: the horizontal sums of the rows
    /// above, at and below it.
    #[inline(always)]
    fn sums(sums: &[Ring; 3], y: usize) -> [[&[f32]; 3]; 3] {
        sums.each_ref().map(|s| [y - 1, y, y + 1].map(|r| s.row(r)))
    }

    /// What refining output row `y` reads and writes. Then
    /// [`Window::hand_on`].
    #[inline(always)]
    pub(super) fn parts(&mut self, t: &Tile, y: usize) -> Parts<'_> {
        let Window {
            base,
            sums,
            saturation,
            class,
            out,
            ..
        } = self;
        Parts {
            windows: Self::windows(base, y, t.stride),
            rows: Self::rows(base, y),
            sums: Self::sums(sums, y),
            class: &mut class[..t.stride],
            dst: out.each_mut().map(|r| &mut r[..t.stride]),
            saturation,
        }
    }

    /// Hands the refined row `y` on to `out`.
    #[inline(always)]
    pub(super) fn hand_on<E: Emit>(&self, t: &Tile, y: usize, out: &mut E) {
        out.emit(y, self.out.each_ref().map(|r| &r[..t.stride]));
    }

    /// The windows of row `y` of a ring of planes' rows (see [`plane`]),
    /// `n` long, in the order of [`super::raisr`]'s taps: window `3 * r +
    /// p` is plane `p` on row `y + r - 1`.
    #[inline(always)]
    fn windows(ring: &Ring, y: usize, n: usize) -> [&[f32]; WINDOWS] {
        std::array::from_fn(|k| plane(ring.row(y + k / 3 - 1), k % 3, n))
    }

    /// The rows of those windows: the rows above, at and below row `y`.
    #[inline(always)]
    pub(super) fn rows(ring: &Ring, y: usize) -> [&[f32]; 3] {
        [y - 1, y, y + 1].map(|r| ring.row(r))
    }
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
        State {
            base_state: self.base.state(stride, rows),
            rows: Window::new(stride),
        }
    }

    #[inline(always)]
    fn stream<E: Emit, L: Load>(&self, st: &mut Self::State, t: &Tile, raw: &L, out: &mut E) {
        let State { base_state, rows } = st;
        rows.fit(t.stride);
        let mut rows = Rows::<B, E> {
            halo: Self::HALO,
            filters: &self.filters,
            t,
            rows,
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
    /// The output's halo; the base's is [`REACH`] narrower.
    halo: usize,
    filters: &'a Filters<B>,
    t: &'a Tile,
    rows: &'a mut Window,
    out: &'a mut E,
}

impl<B: Bank, E: Emit> Emit for Rows<'_, B, E> {
    #[inline(always)]
    fn emit(&mut self, ty: usize, rows: [&[f32]; 3]) {
        let (f, halo, t) = (self.filters, self.halo, self.t);
        let kind = t.kind(f.phase, ty);
        let Some(y) = self.rows.push(f, halo - REACH, (ty, kind), rows) else {
            return;
        };
        let mut p = self.rows.parts(t, y);
        let (windows, rows) = (p.windows, p.rows);
        let row = Row {
            kind: t.kind(f.phase, y),
            halo,
            sums: p.sums,
            windows: &windows,
            rows: &rows,
        };
        B::classes(f, &row, p.class);
        p.saturate(f, y, halo..t.stride - halo);
        B::correct(f, row, p.class, p.dst.each_mut().map(|r| &mut **r));
        self.rows.hand_on(t, y, self.out);
    }
}

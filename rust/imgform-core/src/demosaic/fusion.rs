//! The learned fusion of MLRI and RCD
//! ([`super::Method::Fusion`]): RAISR's filters over MLRI that also see the
//! second base, run so that no base does more work than it does alone.
//!
//! MLRI streams down tiles as tall as the image with a halo of 30 pixels; RCD
//! and the filters work on planes of small tiles with a halo of 12. Run as
//! one plane kernel on small tiles, MLRI recomputed its wide halo around
//! every 128 x 384 tile (1.8 times its own work) and all of them kept full
//! tile planes (19 % of the output in memory). Here MLRI streams down the
//! tall tile as it does alone; its rows gather into chunks of [`CHUNK_ROWS`]
//! output rows (2 more on each side for the filters' hash), and each chunk is
//! refined in sub-tiles [`SUB_COLS`] wide, where RCD and the filters
//! ([`Raisr`]) see the MLRI rows as a [`Given`] base. Every output pixel gets
//! the same arithmetic on the same values as in any other cut, so the bits do
//! not depend on the tiling nor on the thread count. (The filters over MLRI
//! alone need no second base's planes: they refine MLRI's rows as they stream
//! out, [`super::refined`].)

use super::mlri::{Buffers, Mlri};
use super::raisr::{self, Given, Raisr, Secondary, REACH};
use super::ring::{cache_aligned, ALIGN_PAD};
use super::tiled::{Emit, Load, StreamKernel, Tile, TileKernel};

/// Output rows per chunk: RCD recomputes 12 halo rows
/// above and below each chunk (38 % more rows at 64), while its planes,
/// the filters' and the chunk's grow with it.
const CHUNK_ROWS: usize = 64;
/// Output columns per sub-tile: RCD's own tile width,
/// whose planes stay in cache.
const SUB_COLS: usize = 384;

/// MLRI refined by filters that also see `S`.
pub(super) struct Fusion<S> {
    pub(super) mlri: Mlri,
    pub(super) refine: Raisr<Given, S>,
}

impl<S: Secondary> Fusion<S> {
    /// The halo of a sub-tile: the secondary's plus the filters' reach.
    const SUB_HALO: usize = <Raisr<Given, S> as TileKernel>::HALO;
}

pub(super) struct State<S: Secondary> {
    mlri: Buffers,
    chunk: Chunk<S>,
}

/// The buffers of one chunk and of its sub-tiles.
struct Chunk<S: Secondary> {
    /// MLRI's rows of the chunk, from [`REACH`] rows above its first output
    /// row to as many below its last (tall-tile columns).
    base: [Vec<f32>; 3],
    /// How many rows of `base` are filled.
    filled: usize,
    /// The raw rows of the chunk and its sub-tiles' halo.
    raw: Vec<f32>,
    /// The chunk's refined rows (tall-tile columns).
    out: [Vec<f32>; 3],
    /// One sub-tile's raw plane.
    sub_raw: Vec<f32>,
    refine: raisr::State<[Vec<f32>; 3], S::State>,
}

impl<S: Secondary> StreamKernel for Fusion<S> {
    type State = State<S>;
    const HALO: usize = <Mlri as StreamKernel>::HALO + REACH;
    const ROWS: usize = <Mlri as StreamKernel>::ROWS;
    const COLS: usize = <Mlri as StreamKernel>::COLS;
    const AVX512: bool = <Mlri as StreamKernel>::AVX512;

    fn rows(height: usize, across: usize, threads: usize) -> usize {
        <Mlri as StreamKernel>::rows(height, across, threads)
    }

    fn state(&self, stride: usize, rows: usize) -> State<S> {
        let sub_stride = SUB_COLS + 2 * Self::SUB_HALO;
        let sub_len = sub_stride * (CHUNK_ROWS + 2 * Self::SUB_HALO);
        let planes = |rows: usize| [0; 3].map(|_| vec![0.0f32; stride * rows]);
        State {
            mlri: self.mlri.state(stride, rows),
            chunk: Chunk {
                base: planes(CHUNK_ROWS + 2 * REACH),
                filled: 0,
                raw: vec![0.0; stride * (CHUNK_ROWS + 2 * Self::SUB_HALO)],
                out: planes(CHUNK_ROWS),
                sub_raw: vec![0.0; sub_len + ALIGN_PAD],
                refine: TileKernel::state(&self.refine, sub_stride, sub_len),
            },
        }
    }

    #[inline(always)]
    fn stream<E: Emit, L: Load>(&self, st: &mut State<S>, t: &Tile, raw: &L, out: &mut E) {
        let State { mlri, chunk } = st;
        chunk.filled = 0;
        let mut chunks = Chunks {
            refine: &self.refine,
            chunk,
            t,
            raw,
            out,
            next: Self::HALO,
        };
        // MLRI, run on the same tile, emits `REACH` rows and columns more
        // than the tile's output: its halo is that much narrower.
        self.mlri.stream(mlri, t, raw, &mut chunks);
        chunks.flush();
    }
}

/// Gathers MLRI's rows and refines each chunk once it is complete.
struct Chunks<'a, S: Secondary, L, E> {
    refine: &'a Raisr<Given, S>,
    chunk: &'a mut Chunk<S>,
    t: &'a Tile,
    raw: &'a L,
    out: &'a mut E,
    /// The tile row of the next chunk's first output row.
    next: usize,
}

impl<S: Secondary, L: Load, E: Emit> Emit for Chunks<'_, S, L, E> {
    #[inline(always)]
    fn emit(&mut self, ty: usize, rows: [&[f32]; 3]) {
        let c = &mut *self.chunk;
        debug_assert_eq!(ty, self.next - REACH + c.filled);
        let i = c.filled * self.t.stride..(c.filled + 1) * self.t.stride;
        for (p, row) in c.base.iter_mut().zip(rows) {
            p[i.clone()].copy_from_slice(row);
        }
        c.filled += 1;
        if c.filled == CHUNK_ROWS + 2 * REACH {
            self.flush();
        }
    }
}

impl<S: Secondary, L: Load, E: Emit> Chunks<'_, S, L, E> {
    /// The halo of a sub-tile ([`Fusion::SUB_HALO`]).
    const SUB_HALO: usize = Fusion::<S>::SUB_HALO;

    /// Refines and emits the chunk's output rows (those MLRI has given with
    /// their [`REACH`] rows below), then keeps the rows the next chunk's
    /// hash reads above it.
    #[inline(always)]
    fn flush(&mut self) {
        let Some(n) = self.chunk.filled.checked_sub(2 * REACH).filter(|&n| n > 0) else {
            return;
        };
        let stride = self.t.stride;
        self.load_raw(n);
        let halo = <Fusion<S> as StreamKernel>::HALO;
        let mut x0 = halo;
        while x0 < stride - halo {
            let cols = SUB_COLS.min(stride - halo - x0);
            self.sub_tile(n, x0, cols);
            x0 += cols;
        }
        let c = &mut *self.chunk;
        for r in 0..n {
            let row = r * stride..(r + 1) * stride;
            self.out
                .emit(self.next + r, c.out.each_ref().map(|p| &p[row.clone()]));
        }
        for p in &mut c.base {
            p.copy_within(n * stride..(n + 2 * REACH) * stride, 0);
        }
        c.filled = 2 * REACH;
        self.next += n;
    }

    /// The raw rows of `n` output rows from `self.next` and the sub-tiles'
    /// halo above and below.
    #[inline(always)]
    fn load_raw(&mut self, n: usize) {
        let stride = self.t.stride;
        let raw = &mut self.chunk.raw[..stride * (n + 2 * Self::SUB_HALO)];
        for (r, row) in raw.chunks_exact_mut(stride).enumerate() {
            self.raw.load(self.next - Self::SUB_HALO + r, row);
        }
    }

    /// Refines the sub-tile of `n` output rows from `self.next` and `cols`
    /// output columns from tall-tile column `x0` (even, as the halos are,
    /// so sub-tile columns keep the CFA parity).
    #[inline(always)]
    fn sub_tile(&mut self, n: usize, x0: usize, cols: usize) {
        let (stride, c) = (self.t.stride, &mut *self.chunk);
        let sub = Tile {
            stride: cols + 2 * Self::SUB_HALO,
            rows: n + 2 * Self::SUB_HALO,
            y0: self.t.y0 + (self.next - Self::SUB_HALO) as isize,
        };
        let sub_raw = &mut cache_aligned(&mut c.sub_raw)[..sub.stride * sub.rows];
        let whole = Rect {
            rows: sub.rows,
            cols: sub.stride,
        };
        whole.copy(
            (sub_raw, sub.stride, 0),
            (&c.raw, stride, x0 - Self::SUB_HALO),
        );
        // The filters read MLRI `REACH` rows and columns around the output.
        let (top, reach) = (Self::SUB_HALO - REACH, Rect::around(n, cols, REACH));
        for (dst, src) in c.refine.given().iter_mut().zip(&c.base) {
            let at = top * sub.stride + top;
            reach.copy((dst, sub.stride, at), (src, stride, x0 - REACH));
        }
        let planes = TileKernel::run(self.refine, &mut c.refine, &sub, sub_raw);
        let inner = Rect::around(n, cols, 0);
        for (dst, src) in c.out.iter_mut().zip(planes) {
            let at = Self::SUB_HALO * sub.stride + Self::SUB_HALO;
            inner.copy((dst, stride, x0), (src, sub.stride, at));
        }
    }
}

/// A rectangle of rows and columns copied between planes of different
/// strides.
struct Rect {
    rows: usize,
    cols: usize,
}

impl Rect {
    /// `n` rows of `cols` columns and `reach` more on every side.
    fn around(n: usize, cols: usize, reach: usize) -> Self {
        Rect {
            rows: n + 2 * reach,
            cols: cols + 2 * reach,
        }
    }

    /// Copies the rectangle at index `at` of a plane of the given stride
    /// from `src` into `dst`.
    #[inline(always)]
    fn copy(&self, dst: (&mut [f32], usize, usize), src: (&[f32], usize, usize)) {
        let ((d, d_stride, d_at), (s, s_stride, s_at)) = (dst, src);
        for r in 0..self.rows {
            let (d0, s0) = (d_at + r * d_stride, s_at + r * s_stride);
            d[d0..d0 + self.cols].copy_from_slice(&s[s0..s0 + self.cols]);
        }
    }
}

//! The learned fusion of MLRI and RCD ([`super::Method::Fusion`]): RAISR's
//! filters over MLRI that also see how RCD differs from it.
//!
//! All three stream down tiles as tall as the image, a row at a time. MLRI
//! hands over each row it completes; RCD is stepped down the same tile
//! until it has the same row ([`Rcd::step`]), and the filters keep the
//! last rows of both, as the filters over MLRI alone do
//! ([`super::refined`]), refining each row once the row two below it has
//! come. Each stage keeps only the rows later stages still read, in rings:
//! RCD's ~65 rows (0.4 MB a thread at 24 MP) and the filters' ~20 add a
//! fifth to MLRI's own, where the planes they replace doubled it.
//!
//! Before, RCD and the filters ran on planes of small sub-tiles over
//! chunks of MLRI's rows: RCD recomputed its halo of 10 rows above and
//! below every 64-row chunk, every value was copied three times, and the
//! planes took ~5 MB a thread. The arithmetic per pixel is the same, so
//! the bits are too.

use super::mlri::{Buffers, Mlri};
use super::raisr::{Filters, REACH, WINDOWS};
use super::rcd::{self, Rcd, R_OUT};
use super::refined::{plane, plane_mut, planes_ring, Window};
use super::ring::Ring;
use super::tiled::{Emit, Load, StreamKernel, Tile};

/// MLRI refined by filters that also see RCD.
pub(super) struct Fusion {
    pub(super) mlri: Mlri,
    pub(super) rcd: Rcd,
    pub(super) filters: Filters,
}

pub(super) struct State {
    mlri: Buffers,
    rcd: rcd::Stream,
    rows: Window,
    /// RCD's rows minus MLRI's, each clamped first: what the filters see of
    /// the second base, its planes in each row as in [`Window`]'s.
    diff: Ring,
}

impl StreamKernel for Fusion {
    type State = State;
    const HALO: usize = <Mlri as StreamKernel>::HALO + REACH;
    const ROWS: usize = <Mlri as StreamKernel>::ROWS;
    const COLS: usize = <Mlri as StreamKernel>::COLS;
    const AVX512: bool = <Mlri as StreamKernel>::AVX512;

    fn rows(height: usize, across: usize, threads: usize) -> usize {
        <Mlri as StreamKernel>::rows(height, across, threads)
    }

    fn state(&self, stride: usize, rows: usize) -> State {
        State {
            mlri: self.mlri.state(stride, rows),
            rcd: self.rcd.stream_state(stride),
            rows: Window::new(stride),
            diff: planes_ring(stride),
        }
    }

    #[inline(always)]
    fn stream<E: Emit, L: Load>(&self, st: &mut State, t: &Tile, raw: &L, out: &mut E) {
        let State {
            mlri,
            rcd,
            rows,
            diff,
        } = st;
        rows.fit(t.stride);
        // RCD's tile starts `R_OUT` rows above MLRI's first row, so that its
        // first row is MLRI's.
        let top = <Mlri as StreamKernel>::HALO - R_OUT;
        let mut fused = Fused {
            fusion: self,
            t,
            rcd_tile: Tile {
                stride: t.stride,
                rows: t.rows - 2 * top,
                y0: t.y0 + top as isize,
            },
            top,
            steps: 0,
            rcd,
            rows,
            diff,
            raw,
            out,
        };
        self.mlri.stream(mlri, t, raw, &mut fused);
    }
}

/// The raw rows of a tile from row `.1` on: RCD's tile, which starts below
/// MLRI's.
struct Below<'a, L>(&'a L, usize);

impl<L: Load> Load for Below<'_, L> {
    #[inline(always)]
    fn load(&self, ty: usize, dst: &mut [f32]) {
        self.0.load(ty + self.1, dst);
    }
}

/// Takes MLRI's rows, steps RCD to the same row, and hands on each output
/// row once the row two below it has come.
struct Fused<'a, L, E> {
    fusion: &'a Fusion,
    t: &'a Tile,
    /// RCD's tile: `t` from row `top` on.
    rcd_tile: Tile,
    top: usize,
    /// RCD's steps so far.
    steps: usize,
    rcd: &'a mut rcd::Stream,
    rows: &'a mut Window,
    diff: &'a mut Ring,
    raw: &'a L,
    out: &'a mut E,
}

impl<L: Load, E: Emit> Emit for Fused<'_, L, E> {
    #[inline(always)]
    fn emit(&mut self, ty: usize, rows: [&[f32]; 3]) {
        let (k, t) = (self.fusion, self.t);
        let f = &k.filters;
        let halo = <Fusion as StreamKernel>::HALO;
        let row = self.step_to(ty);
        let second = k.rcd.row(self.rcd, row);
        let y = self.rows.push(f, halo - REACH, ty, rows);
        let (lo, hi) = f.bounds;
        let (d, c) = (self.diff.row_mut(ty), self.rows.base.row(ty));
        for (p, s) in second.into_iter().enumerate() {
            let (d, c) = (plane_mut(d, p, t.stride), plane(c, p, t.stride));
            for ((d, s), c) in d.iter_mut().zip(s).zip(c) {
                *d = s.max(lo).min(hi) - c;
            }
        }
        let Some(y) = y else {
            return;
        };
        let p = self.rows.parts(t, y);
        let [a, b, c] = p.rows;
        let [d, e, g] = Window::rows(self.diff, y);
        let kind = t.kind(f.phase, y);
        f.hash_row(kind, halo, p.sums, p.class);
        f.correct_row::<{ 2 * WINDOWS }>(kind, halo, p.class, p.dst, &[a, b, c, d, e, g]);
        self.rows.hand_on(t, y, self.out);
    }
}

impl<L: Load, E: Emit> Fused<'_, L, E> {
    /// Steps RCD down to tile row `ty`: its row of RCD's tile.
    #[inline(always)]
    fn step_to(&mut self, ty: usize) -> usize {
        let (rcd, top) = (&self.fusion.rcd, self.top);
        let row = ty - top;
        while self.steps <= row + R_OUT {
            let j = self.steps;
            rcd.step(self.rcd, &self.rcd_tile, j, &Below(self.raw, top));
            self.steps += 1;
        }
        row
    }
}

//! The learned fusion of "ri_cd" and RCD ([`super::Method::Fusion`]):
//! RAISR's filters over [`super::differences`] (MLRI's green,
//! colour-difference chroma) that also see how RCD differs from it.
//!
//! The first base may be any kernel that streams its rows. Over MLRI
//! itself, retrained (both without the bounds below), "fusion_refined"
//! scores 0.02 / 0.08 / 0.07 dB more on the three validation subsets and
//! 0.14 dB more on the held-out training photographs, but takes 1.23 times
//! as long (496 against 403 ms at 24 MP, Rust harness: 48 MP/s where 50
//! are asked for) and leaves 1.64 times the false colour on the grey zone
//! plate (13157 against 8027: MLRI's chroma aliases there).
//!
//! Two bounds keep RCD's aliased colours out: the filters see RCD's
//! differences from the base clamped to [`SECOND_LIMIT`], and move no
//! missing colour's difference from green further than
//! [`super::raisr::CHROMA_LIMIT`] from the base's ([`super::raisr::bound`];
//! the cascade's second stage is bounded the same way). On the grey zone
//! plate "fusion_refined" then left 6015 of false colour instead of 8027,
//! for 0.01-0.02 dB on each validation subset.
//!
//! The classes are split by the base's local saturation
//! ([`super::saturation`]): pixels whose colours are saturated, where the
//! channels are weakly correlated, get filters of their own.
//!
//! All three stream down tiles as tall as the image, a row at a time. The
//! base hands over each row it completes; RCD is stepped down the same
//! tile until it has the same row ([`Rcd::step`]), and the filters keep
//! the last rows of both, as the filters over one base do
//! ([`super::refined`]), refining each row once the row two below it has
//! come. Each stage keeps only the rows later stages still read, in rings:
//! RCD's ~65 rows (0.4 MB a thread at 24 MP) and the filters' ~20 add a
//! fifth to the base's own, where planes of the tile would double it.

use super::raisr::{plane, plane_mut, Filters, REACH, WINDOWS};
use super::rcd::{self, Rcd, R_OUT};
use super::refined::{planes_ring, Window};
use super::ring::Ring;
use super::tiled::{Emit, Load, StreamKernel, Tile};

/// How far RCD may differ from the base in what the filters see, per
/// colour, as a fraction of the full scale (the training script clamps
/// the same). Where the mosaic aliases, on fine grey detail, RCD's colours
/// stray far from the base's and the filters, fitted on photographs where
/// differences that large are rare, pass them on as false colour.
pub(super) const SECOND_LIMIT: f32 = 32.0 / 255.0;

/// A base that streams its rows, refined by filters that also see RCD.
pub(super) struct Fusion<K> {
    pub(super) base: K,
    pub(super) rcd: Rcd,
    pub(super) filters: Filters,
    /// [`SECOND_LIMIT`] in the sample type's scale.
    pub(super) second_bound: f32,
}

pub(super) struct State<S> {
    base: S,
    rcd: rcd::Stream,
    rows: Window,
    /// RCD's rows minus the base's, each clamped first: what the filters
    /// see of the second base, its planes in each row as in [`Window`]'s.
    diff: Ring,
}

impl<K: StreamKernel> StreamKernel for Fusion<K> {
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
            base: self.base.state(stride, rows),
            rcd: self.rcd.stream_state(stride),
            rows: Window::new(stride),
            diff: planes_ring(),
        }
    }

    #[inline(always)]
    fn stream<E: Emit, L: Load>(&self, st: &mut Self::State, t: &Tile, raw: &L, out: &mut E) {
        let State {
            base,
            rcd,
            rows,
            diff,
        } = st;
        rows.fit(t.stride);
        // RCD's tile starts `R_OUT` rows above the base's first row, so
        // that its first row is the base's.
        let top = K::HALO - R_OUT;
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
        self.base.stream(base, t, raw, &mut fused);
    }
}

/// The raw rows of a tile from row `.1` on: RCD's tile, which starts below
/// the base's.
struct Below<'a, L>(&'a L, usize);

impl<L: Load> Load for Below<'_, L> {
    #[inline(always)]
    fn load(&self, ty: usize, dst: &mut [f32]) {
        self.0.load(ty + self.1, dst);
    }
}

/// Takes the base's rows, steps RCD to the same row, and hands on each
/// output row once the row two below it has come.
struct Fused<'a, K, L, E> {
    fusion: &'a Fusion<K>,
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

impl<K: StreamKernel, L: Load, E: Emit> Emit for Fused<'_, K, L, E> {
    #[inline(always)]
    fn emit(&mut self, ty: usize, rows: [&[f32]; 3]) {
        let (k, t) = (self.fusion, self.t);
        let f = &k.filters;
        let halo = <Fusion<K> as StreamKernel>::HALO;
        let row = self.step_to(ty);
        let second = k.rcd.row(self.rcd, row);
        let first = halo - REACH;
        let y = self.rows.push(f, first, (ty, t.kind(f.phase, ty)), rows);
        let (lo, hi) = f.bounds;
        let limit = k.second_bound;
        let (d, c) = (self.diff.row_mut(ty), self.rows.base.row(ty));
        for (p, s) in second.into_iter().enumerate() {
            let (d, c) = (plane_mut(d, p, t.stride), plane(c, p, t.stride));
            for ((d, s), c) in d.iter_mut().zip(s).zip(c) {
                *d = (s.max(lo).min(hi) - c).max(-limit).min(limit);
            }
        }
        let Some(y) = y else {
            return;
        };
        let mut p = self.rows.parts(t, y);
        let [a, b, c] = p.rows;
        let [d, e, g] = Window::rows(self.diff, y);
        let kind = t.kind(f.phase, y);
        f.hash_row(kind, halo, p.sums, p.class);
        p.saturate(f, y, halo..t.stride - halo);
        let dst = p.dst.each_mut().map(|r| &mut **r);
        f.correct_row::<{ 2 * WINDOWS }>(kind, halo, p.class, dst, &[a, b, c, d, e, g]);
        self.rows.hand_on(t, y, self.out);
    }
}

impl<K, L: Load, E: Emit> Fused<'_, K, L, E> {
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

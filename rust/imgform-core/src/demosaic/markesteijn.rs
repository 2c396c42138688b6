//! X-Trans demosaicing of Frank Markesteijn's kind (the method behind
//! dcraw's and LibRaw's `xtrans_interpolate`), one pass.
//!
//! Four complete RGB images are interpolated, one per direction
//! (horizontal, vertical and the two diagonals), and each pixel takes the
//! mean of the directions whose neighbourhood is the most homogeneous:
//!
//! 1. Green along each direction: at a red or blue site, the two nearest
//!    greens on the line through the site, interpolated linearly, plus the
//!    site's own colour's second difference along the same line (the
//!    Hamilton-Adams correction, generalised to X-Trans's uneven spacing;
//!    see [`Finder::green`]). The result is clamped to the range of the greens in the
//!    3x3 neighbourhood, as Markesteijn does, so a wrong direction cannot
//!    overshoot.
//! 2. Red and blue by colour differences to that direction's green: from
//!    the nearest samples on the line when both sides have one within two
//!    pixels, else from the samples in the 3x3 neighbourhood (X-Trans puts
//!    every colour in every 3x3 window). Red and blue sites come first, from
//!    the other colour's samples; green sites then use every red or blue
//!    site, as Markesteijn orders it.
//! 3. Homogeneity as in AHD: each direction's image is taken to YPbPr and
//!    its second difference along that direction measured; a direction
//!    scores, at each pixel of the 3x3 window, when that measure is within
//!    8 times the smallest of the four at the window's centre. Scores are
//!    summed over 5x5 and the directions within 1/8 of the best are
//!    averaged.
//!
//! The X-Trans layout has no fixed 2x2 structure, so every formula comes
//! from a table of taps (offsets and weights) built once per call for each
//! of the 36 positions in the tile, by searching the pattern itself: any
//! shift, flip or transpose of the tile works the same way. For speed the
//! six sites of each tile row are then merged into one table per formula
//! with per-lane weights ([`PhasedSum`]), so every stage runs 8 columns at
//! a time without branches or gathers (AVX2 when the CPU has it), giving
//! the same bits as the per-site sums. Tiles of rows
//! and columns with a mirrored halo run in parallel, as in [`super::tiled`];
//! the mirror is moved by up to 3 pixels to the nearest sample of the same
//! colour, so the halo keeps the 6x6 period.

use super::{interleave, select, tiled, Isa, Packed};
use crate::cfa::CfaPattern;
use crate::image::{mirror, ImageView, Sample};
use rayon::prelude::*;

/// Output rows per tile (a multiple of the period, so tile row `ty` has the
/// phase of `ty % 6`).
const ROWS: usize = 96;
/// Output columns per tile: the 26 planes of a tile (~3 MB per thread)
/// mostly stay in the 1 MB L2 and the shared L3 of this machine; 384
/// columns (~6 MB) ran at 10.4 MP per CPU-second, 192 at 14.7, 96 (more
/// halo) at 11.4.
const COLS: usize = 192;
/// Columns computed together: one AVX vector of 8 lanes. (Runs of 24
/// columns, the period times 4, left LLVM's vectoriser with scalar code.)
const LANES: usize = 8;
/// Length of the per-lane weight tables: 24 (the least common multiple of
/// the period and `LANES`) plus `LANES`, so that the run starting at tile
/// column `tx` takes its weights at `tx % 24 ..` (see [`Phased`]).
const SPREAD: usize = 32;
/// Mirrored rows and columns around a tile: the reach of every stage added
/// up (green 6, chroma 2 + 2, derivative 1, homogeneity 1, 5x5 sum 2),
/// rounded up to the period.
pub(super) const HALO: usize = 18;
const _: () = assert!(ROWS.is_multiple_of(6) && COLS.is_multiple_of(6) && HALO.is_multiple_of(6));

/// How far each stage reaches beyond the pixel it computes, cumulated: the
/// margin of the tile it leaves uncomputed.
const GREEN_MARGIN: usize = 6;
const CHROMA_MARGIN: usize = GREEN_MARGIN + 4;
const DRV_MARGIN: usize = CHROMA_MARGIN + 1;
const HOMO_MARGIN: usize = DRV_MARGIN + 1;

/// Colour masks for [`Finder::nearest`] and [`Finder::window`].
const RED: u8 = 1;
const GREEN: u8 = 2;
const BLUE: u8 = 4;

/// The four interpolation directions as (row, column) steps.
const DIRS: [(isize, isize); 4] = [(0, 1), (1, 0), (1, 1), (1, -1)];

/// The farthest a sample is looked for along a line: a whole period, which
/// holds every colour on every row and column.
const SEARCH: isize = 6;

/// A weighted sum of samples at fixed offsets from a pixel.
#[derive(Clone, Copy, Default)]
struct Taps {
    n: usize,
    off: [isize; 9],
    w: [f32; 9],
}

impl Taps {
    fn push(&mut self, off: isize, w: f32) {
        self.off[self.n] = off;
        self.w[self.n] = w;
        self.n += 1;
    }

    /// The taps as `(offset, weight)`, in the order they were pushed.
    fn iter(&self) -> impl Iterator<Item = (isize, f32)> + '_ {
        self.off[..self.n]
            .iter()
            .copied()
            .zip(self.w[..self.n].iter().copied())
    }
}

/// The formulas at one position of the 6x6 tile.
#[derive(Clone, Copy, Default)]
struct Site {
    colour: usize,
    /// Green along each direction (red and blue sites only).
    green: [Taps; 4],
    /// The greens of the 3x3 neighbourhood, to clamp green estimates into.
    greens_around: Taps,
    /// Per direction, red's and blue's colour difference to green (at
    /// sites of another colour), indexed by colour / 2.
    chroma: [[Taps; 2]; 4],
}

/// The site formulas of the 36 tile positions, with offsets for planes
/// `stride` wide, in row-major order.
fn sites(pattern: &CfaPattern, stride: usize) -> [Site; 36] {
    std::array::from_fn(|i| {
        Finder {
            pattern,
            y: (i / 6) as isize,
            x: (i % 6) as isize,
            stride: stride as isize,
        }
        .site()
    })
}

/// A per-phase value spread over columns: entry `k` holds `f(k % 6)`, and
/// the run starting at tile column `tx` finds its lanes at `tx % 24 ..`.
type Phased<T> = [T; SPREAD];

fn phased<T>(f: impl Fn(usize) -> T) -> Phased<T> {
    std::array::from_fn(|k| f(k % 6))
}

/// `p[i + off ..][.. LANES]`, copied. The stages load what they need into
/// such local arrays and store each result with [`put`] at the end: the
/// planes are separate `Vec`s that LLVM cannot prove apart, and a store
/// between loads kept it from vectorising the lanes.
#[inline(always)]
fn at<T: Copy + Default>(p: &[T], i: usize, off: isize) -> [T; LANES] {
    let j = (i as isize + off) as usize;
    let mut v = [T::default(); LANES];
    v.copy_from_slice(&p[j..j + LANES]);
    v
}

/// Stores `v` at `p[i ..]`.
#[inline(always)]
fn put(p: &mut [f32], i: usize, v: [f32; LANES]) {
    p[i..i + LANES].copy_from_slice(&v);
}

/// The lanes `f(0) .. f(LANES - 1)`. A loop here rather than
/// `array::from_fn`, whose closures were compiled as functions of their
/// own and called for every step of the passes: 16 % less time at 24 MP,
/// same bits.
#[inline(always)]
fn lanes(f: impl Fn(usize) -> f32) -> [f32; LANES] {
    let mut v = [0.0; LANES];
    for (l, v) in v.iter_mut().enumerate() {
        *v = f(l);
    }
    v
}

/// The six sites of a tile row as one weighted sum over a run of `LANES`
/// columns: each tap weighs zero in the lanes of the phases that do not
/// use it. The six tap lists are merged keeping each one's order (a tap
/// found again later in the merged list is reused, else inserted), so
/// every lane adds its own site's terms in the order of its [`Taps`],
/// interleaved only with zero terms: the straight-line vector sum equals
/// the per-site sum to the bit (adding `+0` or `-0` leaves a finite sum
/// that started at `+0` unchanged). The union is about twice a site's taps,
/// but it runs on 8 lanes without a branch or a gather.
struct PhasedSum(Vec<(isize, Phased<f32>)>);

impl PhasedSum {
    /// Merges `taps[c]`, the taps of column phase `c`.
    fn new(taps: &[Taps; 6]) -> Self {
        let mut merged: Vec<(isize, [Option<f32>; 6])> = Vec::new();
        for (c, t) in taps.iter().enumerate() {
            let mut pos = 0;
            for (off, w) in t.iter() {
                let free = |(o, ws): &(isize, [Option<f32>; 6])| *o == off && ws[c].is_none();
                pos = match merged[pos..].iter().position(free) {
                    Some(k) => pos + k,
                    None => {
                        merged.insert(pos, (off, [None; 6]));
                        pos
                    }
                };
                merged[pos].1[c] = Some(w);
                pos += 1;
            }
        }
        let spread = |ws: [Option<f32>; 6]| phased(|c| ws[c].unwrap_or(0.0));
        Self(merged.into_iter().map(|(o, ws)| (o, spread(ws))).collect())
    }

    /// `sum w * p[i + off]` over the run of columns starting at `i`.
    #[inline(always)]
    fn apply(&self, p: &[f32], i: usize, q: usize) -> [f32; LANES] {
        let mut s = [0.0f32; LANES];
        for (off, w) in &self.0 {
            let (v, w) = (at(p, i, *off), at(w, q, 0));
            for l in 0..LANES {
                s[l] += w[l] * v[l];
            }
        }
        s
    }

    /// `sum w * (a - b)` at `i + off` over the run starting at `i`.
    #[inline(always)]
    fn apply_diff(&self, a: &[f32], b: &[f32], i: usize, q: usize) -> [f32; LANES] {
        let mut s = [0.0f32; LANES];
        for (off, w) in &self.0 {
            let (va, vb, w) = (at(a, i, *off), at(b, i, *off), at(w, q, 0));
            for l in 0..LANES {
                s[l] += w[l] * (va[l] - vb[l]);
            }
        }
        s
    }
}

/// The smallest and largest sample at per-phase offsets over a run of
/// `LANES` columns: each offset of the union carries a bias, 0 in the lanes
/// whose site uses it and infinite in the others, which moves the sample
/// out of the way of the minimum (`+bias`) and the maximum (`-bias`).
struct PhasedRange(Vec<(isize, Phased<f32>)>);

impl PhasedRange {
    /// The range over `offs[c]` in the lanes of phase `c`.
    fn new(offs: &[Vec<isize>; 6]) -> Self {
        let mut all: Vec<isize> = offs.concat();
        all.sort_unstable();
        all.dedup();
        let bias = |o: isize| {
            phased(|c| {
                if offs[c].contains(&o) {
                    0.0
                } else {
                    f32::INFINITY
                }
            })
        };
        Self(all.into_iter().map(|o| (o, bias(o))).collect())
    }

    /// Writes the smallest and largest sample of the run starting at `i`
    /// to `lo[i ..]` and `hi[i ..]`.
    #[inline(always)]
    fn apply(&self, p: &[f32], (i, q): (usize, usize), lo: &mut [f32], hi: &mut [f32]) {
        let (mut min, mut max) = ([f32::INFINITY; LANES], [f32::NEG_INFINITY; LANES]);
        for (off, bias) in &self.0 {
            let (v, bias) = (at(p, i, *off), at(bias, q, 0));
            for l in 0..LANES {
                min[l] = min[l].min(v[l] + bias[l]);
                max[l] = max[l].max(v[l] - bias[l]);
            }
        }
        put(lo, i, min);
        put(hi, i, max);
    }
}

/// The formulas of one row of the 6x6 tile (see [`Site`]) as
/// [`PhasedSum`]s over runs of `LANES` columns.
struct Row {
    /// Green along each direction at red and blue sites (nothing at green
    /// sites, whose [`Row::greens_around`] is the site alone).
    green: [PhasedSum; 4],
    /// The 3x3 greens that green estimates are clamped into.
    greens_around: PhasedRange,
    /// Per direction, red's and blue's difference to green at red and blue
    /// sites (the first chroma pass).
    chroma: [[PhasedSum; 2]; 4],
    /// The same at green sites (the second pass).
    chroma_green: [[PhasedSum; 2]; 4],
    /// Per colour, all ones in the lanes of its sites (for [`select`]).
    is: [Phased<u32>; 3],
}

impl Row {
    fn new(sites: &[Site]) -> Self {
        let sum =
            |f: &dyn Fn(&Site) -> Taps| PhasedSum::new(&std::array::from_fn(|c| f(&sites[c])));
        let none = Taps::default();
        let green = |d: usize| sum(&|s| if s.colour == 1 { none } else { s.green[d] });
        let around = |s: &Site| match s.colour {
            1 => vec![0],
            _ => s.greens_around.iter().map(|(o, _)| o).collect(),
        };
        let chroma =
            |d: usize, k: usize| sum(&|s| if s.colour == 1 { none } else { s.chroma[d][k] });
        let chroma_green =
            |d: usize, k: usize| sum(&|s| if s.colour == 1 { s.chroma[d][k] } else { none });
        Self {
            green: std::array::from_fn(green),
            greens_around: PhasedRange::new(&std::array::from_fn(|c| around(&sites[c]))),
            chroma: std::array::from_fn(|d| [0, 1].map(|k| chroma(d, k))),
            chroma_green: std::array::from_fn(|d| [0, 1].map(|k| chroma_green(d, k))),
            is: std::array::from_fn(|c| {
                phased(|p| if sites[p].colour == c { u32::MAX } else { 0 })
            }),
        }
    }
}

/// The formulas of the six tile rows, with offsets for planes `stride`
/// wide.
struct Layout {
    rows: [Row; 6],
    stride: usize,
}

impl Layout {
    fn new(pattern: &CfaPattern, stride: usize) -> Self {
        let sites = sites(pattern, stride);
        Self {
            rows: std::array::from_fn(|r| Row::new(&sites[6 * r..6 * r + 6])),
            stride,
        }
    }

    /// The formulas of tile row `ty`.
    #[inline(always)]
    fn row(&self, ty: usize) -> &Row {
        &self.rows[ty % 6]
    }
}

/// Builds the taps of the site at tile position `(y, x)` by looking at the
/// pattern around it.
struct Finder<'a> {
    pattern: &'a CfaPattern,
    y: isize,
    x: isize,
    stride: isize,
}

impl Finder<'_> {
    fn colour(&self, dy: isize, dx: isize) -> usize {
        let y = (self.y + dy).rem_euclid(6) as usize;
        let x = (self.x + dx).rem_euclid(6) as usize;
        self.pattern.color_at(y, x) as usize
    }

    fn off(&self, dy: isize, dx: isize) -> isize {
        dy * self.stride + dx
    }

    /// Whether the sample at `(dy, dx)` has one of the colours of `mask`
    /// (bit `c` for colour `c`).
    fn is(&self, dy: isize, dx: isize, mask: u8) -> bool {
        mask & (1 << self.colour(dy, dx)) != 0
    }

    /// Steps `k` (1 ..= `max`) to the nearest sample of a colour of `mask`
    /// along `(dy, dx)`.
    fn nearest(&self, (dy, dx): (isize, isize), mask: u8, max: isize) -> Option<isize> {
        (1..=max).find(|&k| self.is(k * dy, k * dx, mask))
    }

    fn site(&self) -> Site {
        let colour = self.colour(0, 0);
        let mut s = Site {
            colour,
            greens_around: self.window(GREEN),
            ..Site::default()
        };
        for (d, &dir) in DIRS.iter().enumerate() {
            if colour != 1 {
                s.green[d] = self.green(dir);
            }
            for c in [0, 2] {
                if colour == 1 {
                    s.chroma[d][c / 2] = self.chroma(dir, RED | BLUE);
                } else if c != colour {
                    s.chroma[d][c / 2] = self.chroma(dir, 1 << c);
                }
            }
        }
        s
    }

    /// The samples of the colours of `mask` in the 3x3 window but the
    /// centre, with bilinear weights (2 on the sides, 1 on the corners)
    /// summing to 1.
    fn window(&self, mask: u8) -> Taps {
        let mut t = Taps::default();
        let mut total = 0.0;
        for (dy, dx) in (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (dy, dx))) {
            if (dy, dx) != (0, 0) && self.is(dy, dx, mask) {
                let w = if dy == 0 || dx == 0 { 2.0 } else { 1.0 };
                t.push(self.off(dy, dx), w);
                total += w;
            }
        }
        t.w[..t.n].iter_mut().for_each(|w| *w /= total);
        t
    }

    /// Green along `dir` at a red or blue site (see the module doc): greens
    /// at `-a` and `+b` interpolated linearly, plus `2ab / (ce)` times the
    /// own colour's deviation from its line through its samples at `-c`
    /// and `+e`. Half that factor reproduces quadratics exactly; twice it,
    /// like Hamilton-Adams's Bayer weights, keeps more of the own colour's
    /// detail (+0.2 dB mean CPSNR on the benchmark images, and better than
    /// three times). A cubic through two greens each side instead was
    /// 0.9 dB worse. Falls back to the 3x3 mean when a side has no green.
    fn green(&self, dir: (isize, isize)) -> Taps {
        let mut t = Taps::default();
        let Some((a, b)) = self.line(dir, GREEN, SEARCH, &mut t) else {
            return self.window(GREEN);
        };
        let mut own = Taps::default();
        if let Some((c, e)) = self.line(dir, 1 << self.colour(0, 0), SEARCH, &mut own) {
            let q = 2.0 * (a * b) as f32 / (c * e) as f32;
            t.push(0, q);
            for k in 0..own.n {
                t.push(own.off[k], -q * own.w[k]);
            }
        }
        t
    }

    /// A colour's difference to green along `dir`, from the samples of
    /// `mask`: the nearest on both sides within 2 steps, interpolated
    /// linearly, else the 3x3 window's.
    fn chroma(&self, dir: (isize, isize), mask: u8) -> Taps {
        let mut t = Taps::default();
        match self.line(dir, mask, 2, &mut t) {
            Some(_) => t,
            None => self.window(mask),
        }
    }

    /// Adds to `t` the linear interpolation at the site between the nearest
    /// samples of `mask` at `-a` and `+b` along `(dy, dx)` (within `max`
    /// steps), and returns `(a, b)`; `None`, adding nothing, when a side
    /// has none.
    fn line(
        &self,
        (dy, dx): (isize, isize),
        mask: u8,
        max: isize,
        t: &mut Taps,
    ) -> Option<(isize, isize)> {
        let a = self.nearest((-dy, -dx), mask, max)?;
        let b = self.nearest((dy, dx), mask, max)?;
        let (af, bf) = (a as f32, b as f32);
        t.push(self.off(-a * dy, -a * dx), bf / (af + bf));
        t.push(self.off(b * dy, b * dx), af / (af + bf));
        Some((a, b))
    }
}

/// Mirrors `i` into `0 .. n` (see [`mirror`]) and moves the result to the
/// nearest index with the same remainder modulo 6, so the mirrored mosaic
/// keeps the X-Trans period. `n >= 6`.
fn mirror6(i: isize, n: usize) -> usize {
    let m = mirror(i, n) as isize;
    let r = (i - m).rem_euclid(6);
    let (up, down) = (m + r, m + r - 6);
    let ok = |v: isize| (0..n as isize).contains(&v);
    let v = if (r <= 3 && ok(up)) || !ok(down) {
        up
    } else {
        down
    };
    v as usize
}

/// Where a tile sits and how much of its planes is used.
struct Tile {
    stride: usize,
    rows: usize,
    cols: usize,
}

impl Tile {
    /// Calls `f(row, i, q)` for runs of `LANES` columns covering every
    /// pixel at least `m` from the tile's edges, `i` being the plane index
    /// of the run's first column, `q` where its lanes start in the
    /// [`Phased`] tables and `row` its row's formulas. Runs end up to `LANES - 1` columns past
    /// the stage's area, into the padding of the plane's row: values there
    /// are never read by a pixel of a later stage's area.
    #[inline(always)]
    fn runs(&self, layout: &Layout, m: usize, mut f: impl FnMut(&Row, usize, usize)) {
        for ty in m..self.rows - m {
            let row = layout.row(ty);
            for tx in (m - m % 6..self.cols - m).step_by(LANES) {
                f(row, ty * self.stride + tx, tx % 24);
            }
        }
    }
}

/// One direction's image: R, G, B planes.
type Rgb = [Vec<f32>; 3];

/// Per-thread planes, reused from tile to tile (every stage reads only what
/// earlier stages of the same tile wrote).
struct Scratch<T> {
    raw: Vec<f32>,
    /// The smallest and largest green around each site.
    range: [Vec<f32>; 2],
    dirs: [Rgb; 4],
    ypbpr: [Vec<f32>; 3],
    drv: [Vec<f32>; 4],
    homo: [Vec<f32>; 4],
    /// The image columns of the tile's columns.
    cols: Vec<usize>,
    out: [Vec<f32>; 3],
    packed: Packed<T>,
}

impl<T: Sample> Scratch<T> {
    fn new(len: usize, stride: usize, cols: usize) -> Self {
        let plane = || vec![0.0f32; len];
        Self {
            raw: plane(),
            range: [plane(), plane()],
            dirs: [0, 1, 2, 3].map(|_| [plane(), plane(), plane()]),
            ypbpr: [plane(), plane(), plane()],
            drv: [0, 1, 2, 3].map(|_| plane()),
            homo: [0, 1, 2, 3].map(|_| plane()),
            cols: vec![0; stride],
            out: [0, 1, 2].map(|_| vec![0.0; cols + LANES]),
            packed: Packed::new(cols),
        }
    }
}

/// What every tile of one [`run`] call shares.
struct Ctx<'a, T> {
    raw: &'a ImageView<'a, T>,
    layout: Layout,
    bounds: (f32, f32),
}

/// Demosaics an X-Trans mosaic (at least 6x6) into `out`, clamped to the
/// range of `raw`, with the instruction set `isa` (any gives the same bits).
pub(super) fn run<T: Sample>(
    raw: &ImageView<'_, T>,
    pattern: &CfaPattern,
    isa: Isa,
    out: &mut [T],
) {
    let w = raw.width();
    // `LANES` columns of padding take the runs' overshoot (see
    // [`Tile::runs`]).
    let stride = w.min(COLS) + 2 * HALO + LANES;
    let ctx = Ctx {
        raw,
        layout: Layout::new(pattern, stride),
        bounds: tiled::range(raw),
    };
    let len = stride * (ROWS + 2 * HALO);
    let bands = raw.height().div_ceil(ROWS);
    out.par_chunks_mut(3 * w * ROWS)
        .with_min_len(bands.div_ceil(2 * rayon::current_num_threads()))
        .enumerate()
        .for_each_init(
            || Scratch::new(len, stride, w.min(COLS)),
            |s, (i, rows)| {
                for x0 in (0..w).step_by(COLS) {
                    match isa {
                        Isa::Baseline => tile(&ctx, (x0, i * ROWS), s, rows),
                        #[cfg(target_arch = "x86_64")]
                        // SAFETY: `Isa::Avx2` and `Isa::Avx512` are only made on CPUs
                        // with AVX2.
                        Isa::Avx2 | Isa::Avx512 => unsafe {
                            tile_avx2(&ctx, (x0, i * ROWS), s, rows)
                        },
                    }
                }
            },
        );
}

/// [`tile`] compiled for AVX2; the stages inline into it, and their runs of
/// `LANES` columns become three 8-lane vectors.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn tile_avx2<T: Sample>(
    ctx: &Ctx<'_, T>,
    origin: (usize, usize),
    s: &mut Scratch<T>,
    rows: &mut [T],
) {
    tile(ctx, origin, s, rows);
}

/// The tile of output columns `x0 .. x0 + COLS` of the band `rows`
/// starting at row `y0`.
#[inline(always)]
fn tile<T: Sample>(ctx: &Ctx<'_, T>, (x0, y0): (usize, usize), s: &mut Scratch<T>, rows: &mut [T]) {
    let (raw, layout) = (ctx.raw, &ctx.layout);
    let w = raw.width();
    let n = rows.len() / (3 * w);
    let tw = COLS.min(w - x0);
    let t = Tile {
        stride: layout.stride,
        rows: n + 2 * HALO,
        cols: tw + 2 * HALO,
    };
    load(raw, &t, (x0, y0), s);
    let [lo, hi] = &mut s.range;
    t.runs(
        layout,
        GREEN_MARGIN,
        #[inline(always)]
        |row, i, q| {
            row.greens_around.apply(&s.raw, (i, q), lo, hi);
        },
    );
    for (d, (rgb, drv)) in s.dirs.iter_mut().zip(&mut s.drv).enumerate() {
        green(&t, layout, d, &s.raw, &s.range, &mut rgb[1]);
        chroma(&t, layout, d, &s.raw, rgb);
        to_ypbpr(&t, layout, rgb, &mut s.ypbpr);
        derivative(&t, layout, DIRS[d], &s.ypbpr, drv);
    }
    homogeneity(&t, layout, &s.drv, &mut s.homo);
    for (i, o) in rows.chunks_exact_mut(3 * w).enumerate() {
        blend_row(&t, layout, HALO + i, s);
        for (c, dst) in s.out.iter_mut().zip(s.packed.0.iter_mut()) {
            c[..tw]
                .iter_mut()
                .for_each(|v| *v = v.max(ctx.bounds.0).min(ctx.bounds.1));
            T::from_f32_row(&mut dst[..tw], &c[..tw]);
        }
        interleave(&s.packed, &mut o[3 * x0..3 * (x0 + tw)]);
    }
}

/// Loads the tile's raw plane, mirrored with [`mirror6`] around the image.
#[inline(always)]
fn load<T: Sample>(raw: &ImageView<'_, T>, t: &Tile, (x0, y0): (usize, usize), s: &mut Scratch<T>) {
    let (w, h) = (raw.width(), raw.height());
    let (top, left) = (y0 as isize - HALO as isize, x0 as isize - HALO as isize);
    let cols = &mut s.cols[..t.cols];
    for (tx, c) in cols.iter_mut().enumerate() {
        *c = mirror6(left + tx as isize, w);
    }
    for (ty, dst) in s.raw.chunks_exact_mut(t.stride).take(t.rows).enumerate() {
        let src = raw.row(mirror6(top + ty as isize, h));
        for (d, &x) in dst.iter_mut().zip(cols.iter()) {
            *d = src[x].to_f32();
        }
    }
}

/// Green along direction `d`: the directional estimate clamped into the
/// greens around, which at green sites are the site alone (so the raw
/// sample).
#[inline(always)]
fn green(
    t: &Tile,
    layout: &Layout,
    d: usize,
    raw: &[f32],
    [lo, hi]: &[Vec<f32>; 2],
    g: &mut [f32],
) {
    t.runs(
        layout,
        GREEN_MARGIN,
        #[inline(always)]
        |row, i, q| {
            let est = row.green[d].apply(raw, i, q);
            let (lo, hi) = (at(lo, i, 0), at(hi, i, 0));
            put(g, i, lanes(|l| est[l].max(lo[l]).min(hi[l])));
        },
    );
}

/// Red and blue along direction `d` from colour differences to its green:
/// first at red and blue sites from the samples of the other colour, then
/// at green sites from every red or blue site, now complete (denser, so
/// the line through the site finds them closer, as in Markesteijn's order).
/// The first pass leaves green at the green sites, which the second pass
/// overwrites and nothing reads before.
#[inline(always)]
fn chroma(t: &Tile, layout: &Layout, d: usize, raw: &[f32], rgb: &mut Rgb) {
    let [r, g, b] = rgb;
    t.runs(
        layout,
        CHROMA_MARGIN - 2,
        #[inline(always)]
        |row, i, q| {
            for (k, plane) in [&mut *r, &mut *b].into_iter().enumerate() {
                let diff = row.chroma[d][k].apply_diff(raw, g, i, q);
                let (own, src, g) = (at(&row.is[2 * k], q, 0), at(raw, i, 0), at(g, i, 0));
                put(plane, i, lanes(|l| select(own[l], src[l], g[l] + diff[l])));
            }
        },
    );
    t.runs(
        layout,
        CHROMA_MARGIN,
        #[inline(always)]
        |row, i, q| {
            for (k, plane) in [&mut *r, &mut *b].into_iter().enumerate() {
                let diff = row.chroma_green[d][k].apply_diff(plane, g, i, q);
                let (green, g, old) = (at(&row.is[1], q, 0), at(g, i, 0), at(plane, i, 0));
                put(
                    plane,
                    i,
                    lanes(|l| select(green[l], g[l] + diff[l], old[l])),
                );
            }
        },
    );
}

/// BT.2020 luma and scaled colour differences: a cheap perceptual space in
/// which to compare the directions (Markesteijn's 3-pass variant uses it
/// instead of CIELab).
#[inline(always)]
fn to_ypbpr(t: &Tile, layout: &Layout, [r, g, b]: &Rgb, out: &mut [Vec<f32>; 3]) {
    let [y, pb, pr] = out;
    t.runs(
        layout,
        CHROMA_MARGIN,
        #[inline(always)]
        |_, i, _| {
            let (r, g, b) = (at(r, i, 0), at(g, i, 0), at(b, i, 0));
            let luma: [f32; LANES] =
                std::array::from_fn(|l| 0.2627 * r[l] + 0.678 * g[l] + 0.0593 * b[l]);
            put(y, i, luma);
            put(pb, i, std::array::from_fn(|l| (b[l] - luma[l]) * 0.56433));
            put(pr, i, std::array::from_fn(|l| (r[l] - luma[l]) * 0.67815));
        },
    );
}

/// The squared second difference of the YPbPr image along `dir`: small
/// where interpolating along that direction left a smooth image.
#[inline(always)]
fn derivative(
    t: &Tile,
    layout: &Layout,
    (dy, dx): (isize, isize),
    ypbpr: &[Vec<f32>; 3],
    drv: &mut [f32],
) {
    let step = dy * t.stride as isize + dx;
    t.runs(
        layout,
        DRV_MARGIN,
        #[inline(always)]
        |_, i, _| {
            let mut out = [0.0f32; LANES];
            for p in ypbpr {
                let (c, a, b) = (at(p, i, 0), at(p, i, -step), at(p, i, step));
                for l in 0..LANES {
                    let v = 2.0 * c[l] - a[l] - b[l];
                    out[l] += v * v;
                }
            }
            put(drv, i, out);
        },
    );
}

/// Each direction's count of 3x3 neighbours whose derivative is within 8
/// times the smallest derivative of the four at the centre (counts are
/// small integers, exact in any order).
#[inline(always)]
fn homogeneity(t: &Tile, layout: &Layout, drv: &[Vec<f32>; 4], homo: &mut [Vec<f32>; 4]) {
    let s = t.stride as isize;
    let window = [-s - 1, -s, -s + 1, -1, 0, 1, s - 1, s, s + 1];
    t.runs(
        layout,
        HOMO_MARGIN,
        #[inline(always)]
        |_, i, _| {
            let mut tr = [f32::INFINITY; LANES];
            for p in drv {
                let p = at(p, i, 0);
                for l in 0..LANES {
                    tr[l] = tr[l].min(p[l]);
                }
            }
            tr.iter_mut().for_each(|v| *v *= 8.0);
            for (p, h) in drv.iter().zip(homo.iter_mut()) {
                let mut count = [0.0f32; LANES];
                for &o in &window {
                    let v = at(p, i, o);
                    for l in 0..LANES {
                        count[l] += if v[l] <= tr[l] { 1.0 } else { 0.0 };
                    }
                }
                put(h, i, count);
            }
        },
    );
}

/// Tile row `ty`'s output into `s.out`: per pixel, the mean of the
/// directions whose 5x5 homogeneity sum is within 1/8 of the best, with the
/// site's own sample as its own colour. Directions left out add `+0`, which
/// leaves the sum as it was.
#[inline(always)]
fn blend_row<T>(t: &Tile, layout: &Layout, ty: usize, s: &mut Scratch<T>) {
    let row = layout.row(ty);
    let st = t.stride as isize;
    for tx in (HALO..t.cols - HALO).step_by(LANES) {
        let i = ty * t.stride + tx;
        let mut score = [[0.0f32; LANES]; 4];
        for (sum, h) in score.iter_mut().zip(&s.homo) {
            for dy in -2..=2 {
                for dx in -2..=2 {
                    let v = at(h, i, dy * st + dx);
                    for l in 0..LANES {
                        sum[l] += v[l];
                    }
                }
            }
        }
        let mut keep = [0.0f32; LANES];
        for sc in &score {
            for l in 0..LANES {
                keep[l] = keep[l].max(sc[l]);
            }
        }
        keep.iter_mut().for_each(|k| *k -= *k / 8.0);
        let mut sum = [[0.0f32; LANES]; 3];
        let mut count = [0.0f32; LANES];
        for (rgb, sc) in s.dirs.iter().zip(&score) {
            for (acc, p) in sum.iter_mut().zip(rgb) {
                let p = at(p, i, 0);
                for l in 0..LANES {
                    acc[l] += if sc[l] >= keep[l] { p[l] } else { 0.0 };
                }
            }
            for l in 0..LANES {
                count[l] += if sc[l] >= keep[l] { 1.0 } else { 0.0 };
            }
        }
        let (own, q) = (at(&s.raw, i, 0), tx % 24);
        for ((o, acc), is) in s.out.iter_mut().zip(sum).zip(&row.is) {
            let is = at(is, q, 0);
            put(
                o,
                tx - HALO,
                std::array::from_fn(|l| select(is[l], own[l], acc[l] / count[l])),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mirror6_keeps_the_period_and_stays_inside() {
        for n in [6usize, 7, 11, 40] {
            for i in -30isize..(n as isize + 30) {
                let m = mirror6(i, n);
                assert!(m < n, "{i} {n} -> {m}");
                assert_eq!((i - m as isize).rem_euclid(6), 0, "{i} {n} -> {m}");
            }
            for i in 0..n {
                assert_eq!(mirror6(i as isize, n), i);
            }
        }
    }

    #[test]
    fn every_instruction_set_gives_the_same_bits() {
        // Two tiles each way, so seams and the runs' overshoot are covered.
        let (w, h) = (COLS + 37, ROWS + 29);
        let raw: Vec<u16> = (0..w * h).map(|i| ((i * 7919) % 4099) as u16).collect();
        let view = ImageView::contiguous(&raw, w, h, 1).unwrap();
        let run_with = |isa| {
            let mut out = vec![0u16; 3 * w * h];
            run(&view, &CfaPattern::xtrans(), isa, &mut out);
            out
        };
        let base = run_with(Isa::Baseline);
        for isa in Isa::available() {
            assert_eq!(base, run_with(isa), "{isa:?}");
        }
    }

    #[test]
    fn green_weights_sum_to_one_so_constants_stay() {
        let p = CfaPattern::xtrans();
        for s in sites(&p, 100).iter().filter(|s| s.colour != 1) {
            for g in &s.green {
                let sum: f32 = g.w[..g.n].iter().sum();
                assert!((sum - 1.0).abs() < 1e-6);
            }
        }
    }
}

//! The skeleton of the multi-stage methods (RCD, Menon 2007): each stage
//! reads earlier planes several pixels away, so a ring of rows per stage
//! would need one ring per plane and careful lags. Instead a band of output
//! rows is computed in a tile of `f32` planes covering the band plus a halo
//! of mirrored rows and columns on every side; each stage fills the tile
//! minus its reach, which shrinks from stage to stage, and the band's rows
//! come out of the middle. Extra memory is a few tile planes per running
//! task (about 128 rows each), never a full-size temporary.
//!
//! The halo is even, so a tile coordinate has the CFA parity of the image
//! coordinate it stands for; mirroring without repeating the edge keeps the
//! mosaic plausible across the border, as in the row kernels.
//!
//! A method may instead stream down its tile ([`StreamKernel`]), keeping a
//! ring of recent rows per stage and handing over each output row as soon
//! as it is done; its tiles can then be much taller, so fewer halo rows
//! are recomputed, with memory that does not grow with their height.

use super::ring::{cache_aligned, Rows, ALIGN_PAD};
use super::{Isa, Mosaic, Phase, RgbSink, RowKind};
use crate::image::{mirror, ImageView, Sample};
use rayon::prelude::*;
use std::ops::Range;

/// Output rows per tile: the halo (8 to 10 rows each side) is recomputed
/// for every tile, so tiles are twice as tall as the row kernels' bands
/// (~15 % overhead) while 24 MP still gives ~30 tasks to balance.
const ROWS_PER_TILE: usize = 128;

/// Output columns per tile: a dozen planes of 148 x 404 values (~3 MB)
/// stay in cache, where full-width tiles (40 MB at 6000 columns) made two
/// threads slower than one.
const COLS_PER_TILE: usize = 384;

/// Where a tile sits: plane index `ty * stride + tx` is image pixel
/// `(y0 + ty, tx - K::HALO)`.
pub(crate) struct Tile {
    pub(crate) stride: usize,
    pub(crate) rows: usize,
    pub(crate) y0: isize,
}

impl Tile {
    /// The kind of tile row `ty`.
    pub(crate) fn kind(&self, phase: Phase, ty: usize) -> RowKind {
        phase.row(self.y0 + ty as isize)
    }

    /// Equal-length views of tile row `ty` for a stage of reach `s`: its
    /// columns `s .. stride - s`.
    pub(crate) fn span(&self, ty: usize, s: usize) -> Span {
        Span {
            stride: self.stride,
            ty,
            s,
            n: self.stride - 2 * s,
        }
    }
}

/// The columns one stage fills in one tile row; see [`Tile::span`]. It
/// reads and writes whole planes and rings alike ([`Rows`]), so a stage's
/// code serves a method run on tiles and one streaming down them.
#[derive(Clone, Copy)]
pub(crate) struct Span {
    stride: usize,
    ty: usize,
    s: usize,
    pub(crate) n: usize,
}

impl Span {
    /// Plane `p` seen `dy` rows down and `dx` columns right of the span.
    #[inline(always)]
    pub(crate) fn at<R: Rows + ?Sized>(self, p: &R, dy: isize, dx: isize) -> &[f32] {
        let start = (self.s as isize + dx) as usize;
        let ty = (self.ty as isize + dy) as usize;
        &p.row_of(ty, self.stride)[start..start + self.n]
    }

    /// The span's indices in a plane (for planes of masks).
    #[inline(always)]
    pub(crate) fn range(self) -> std::ops::Range<usize> {
        let base = self.ty * self.stride + self.s;
        base..base + self.n
    }

    /// Plane `p`'s own row, writable.
    #[inline(always)]
    pub(crate) fn out<R: Rows + ?Sized>(self, p: &mut R) -> &mut [f32] {
        &mut p.row_of_mut(self.ty, self.stride)[self.s..self.s + self.n]
    }
}

/// A multi-stage method run on tiles.
pub(crate) trait TileKernel: Sync {
    /// Planes and scratch, made once per tile.
    type State;
    /// Mirrored rows and columns needed around the output (even).
    const HALO: usize;
    /// Planes of `len` values for tiles `stride` wide.
    fn state(&self, stride: usize, len: usize) -> Self::State;
    /// Computes the tile from the raw plane `raw`, returning the planes of
    /// the row's own chroma, green and the other chroma (see [`RowKind`]),
    /// valid at least over the tile's middle.
    fn run<'s>(&self, st: &'s mut Self::State, t: &Tile, raw: &[f32]) -> [&'s [f32]; 3];
}

/// A method run on tiles that hands over its output row by row: what
/// [`run_tiled`] drives. Plane kernels ([`TileKernel`]) are streams whose
/// rows all come at the end; a method that keeps only rings of recent rows
/// per stage (MLRI) emits each row as soon as its last stage reaches it,
/// and can take much taller tiles, since its memory no longer grows with
/// their height.
pub(crate) trait StreamKernel: Sync {
    /// Buffers, made once per rayon worker split.
    type State;
    /// Mirrored rows and columns needed around the output (even).
    const HALO: usize;
    /// Output rows and columns per tile (rows: see [`StreamKernel::rows`]).
    const ROWS: usize;
    const COLS: usize;
    /// Whether the kernel runs in its AVX-512 copy on CPUs that have it
    /// ([`Isa::Avx512`]), or in its AVX2 one.
    const AVX512: bool = true;
    /// Output rows per tile of a mosaic `height` tall, `across` tiles
    /// wide, on `threads` threads (even): `ROWS`, for kernels whose memory
    /// grows with it.
    fn rows(_height: usize, _across: usize, _threads: usize) -> usize {
        Self::ROWS
    }
    /// Buffers for tiles `stride` wide and `rows` tall (halo included).
    fn state(&self, stride: usize, rows: usize) -> Self::State;
    /// Computes the tile from its raw rows, which `raw` loads, handing
    /// `out` each tile row of `HALO .. t.rows - HALO` once, in order.
    fn stream<E: Emit, L: Load>(&self, st: &mut Self::State, t: &Tile, raw: &L, out: &mut E);
}

/// Where a [`StreamKernel`] gets its raw rows: a kernel that streams down
/// its tile loads them as it goes, into a ring that stays in cache,
/// instead of a whole tile plane loaded first.
pub(crate) trait Load {
    /// Tile row `ty` as `f32`, into `dst` (`t.stride` long).
    fn load(&self, ty: usize, dst: &mut [f32]);

    /// Tile rows `rows`, one after the other, into `dst` (whole rows of
    /// `t.stride`): one call for a plane kernel's tile.
    #[inline(always)]
    fn load_rows(&self, rows: Range<usize>, dst: &mut [f32]) {
        for (ty, row) in rows_in(rows, dst) {
            self.load(ty, row);
        }
    }
}

impl<L: Load + ?Sized> Load for &L {
    #[inline(always)]
    fn load(&self, ty: usize, dst: &mut [f32]) {
        (**self).load(ty, dst);
    }

    #[inline(always)]
    fn load_rows(&self, rows: Range<usize>, dst: &mut [f32]) {
        (**self).load_rows(rows, dst);
    }
}

/// Where a [`StreamKernel`] hands its output rows. A trait rather than a
/// closure: a closure was compiled apart from the AVX2 tile function that
/// calls it, in SSE2 code that took 6-11 % of `"best"`'s profile. The
/// stages that kernels stack inline into each other; the tile's own store
/// is a trait object that runs in the kernel's instruction set ([`on`]).
pub(crate) trait Emit {
    /// Tile row `ty` of the row's own chroma, green and the other chroma
    /// (each `t.stride` long).
    fn emit(&mut self, ty: usize, rows: [&[f32]; 3]);

    /// Tile rows `rows` of planes that hold them one after the other,
    /// `stride` apart: one call for a plane kernel's tile.
    #[inline(always)]
    fn emit_rows(&mut self, rows: Range<usize>, stride: usize, planes: [&[f32]; 3]) {
        for (i, ty) in rows.enumerate() {
            self.emit(ty, nth_row(planes, i, stride));
        }
    }
}

/// The rows `rows` of `dst`, which holds them one after the other.
#[inline(always)]
fn rows_in(rows: Range<usize>, dst: &mut [f32]) -> impl Iterator<Item = (usize, &mut [f32])> {
    let stride = dst.len() / rows.len();
    rows.zip(dst.chunks_exact_mut(stride))
}

/// Row `i` of planes that hold their rows `stride` apart.
#[inline(always)]
fn nth_row(planes: [&[f32]; 3], i: usize, stride: usize) -> [&[f32]; 3] {
    planes.map(|p| &p[i * stride..(i + 1) * stride])
}

impl<E: Emit + ?Sized> Emit for &mut E {
    #[inline(always)]
    fn emit(&mut self, ty: usize, rows: [&[f32]; 3]) {
        (**self).emit(ty, rows);
    }

    #[inline(always)]
    fn emit_rows(&mut self, rows: Range<usize>, stride: usize, planes: [&[f32]; 3]) {
        (**self).emit_rows(rows, stride, planes);
    }
}

/// A [`TileKernel`]'s buffers: the tile's raw plane, and its own.
pub(crate) struct Planes<S> {
    raw: Vec<f32>,
    kernel: S,
}

impl<K: TileKernel> StreamKernel for K {
    type State = Planes<K::State>;
    const HALO: usize = <K as TileKernel>::HALO;
    const ROWS: usize = ROWS_PER_TILE;
    const COLS: usize = COLS_PER_TILE;

    fn state(&self, stride: usize, rows: usize) -> Self::State {
        Planes {
            raw: vec![0.0f32; stride * rows + ALIGN_PAD],
            kernel: TileKernel::state(self, stride, stride * rows),
        }
    }

    #[inline(always)]
    fn stream<E: Emit, L: Load>(&self, st: &mut Self::State, t: &Tile, raw: &L, out: &mut E) {
        let plane = &mut cache_aligned(&mut st.raw)[..t.stride * t.rows];
        raw.load_rows(0..t.rows, plane);
        let planes = self.run(&mut st.kernel, t, plane);
        let halo = <K as TileKernel>::HALO;
        let first = halo * t.stride;
        out.emit_rows(halo..t.rows - halo, t.stride, planes.map(|p| &p[first..]));
    }
}

/// The smallest and largest sample of `raw`, to clamp outputs into.
/// Compared in the sample type, with comparisons that map to vector
/// min / max instructions (the samples are finite): converting each to
/// `f32` first and using `f32::min` made the scan 2.0 % of MLRI's profile
/// at 24 MP, this 1.4 %.
pub(super) fn range<T: Sample>(raw: &ImageView<'_, T>) -> (f32, f32) {
    let first = raw.row(0)[0];
    let (lo, hi) = (0..raw.height())
        .into_par_iter()
        .map(|y| {
            raw.row(y).iter().fold((first, first), |(lo, hi), &v| {
                (if v < lo { v } else { lo }, if v > hi { v } else { hi })
            })
        })
        .reduce(
            || (first, first),
            |(lo, hi), (l, h)| (if l < lo { l } else { lo }, if h > hi { h } else { hi }),
        );
    (lo.to_f32(), hi.to_f32())
}

/// Runs `k` over every tile and writes the result through `sink`,
/// clamped to the range of `raw` (min and max are exact whatever the
/// thread count).
pub(crate) fn run_tiled<M, O, S, K>(raw: &M, phase: Phase, k: &K, isa: Isa, sink: &S, out: &mut [O])
where
    M: Mosaic,
    O: Send,
    S: RgbSink<O>,
    K: StreamKernel,
{
    let bounds = raw.range();
    // Kernels without an AVX-512 copy run their AVX2 one, which every
    // AVX-512 CPU can run.
    #[cfg(target_arch = "x86_64")]
    let isa = match isa {
        Isa::Avx512 if !K::AVX512 => Isa::Avx2,
        isa => isa,
    };
    let (w, threads) = (raw.width(), rayon::current_num_threads());
    let tw = tile_width(w, K::COLS);
    let band = K::rows(raw.height(), w.div_ceil(tw), threads);
    // One set of planes per rayon worker split, reused from tile to tile:
    // fresh multi-megabyte planes per tile spent a third of the time in
    // page faults. Each stage only reads what earlier stages of the same
    // tile wrote, so leftovers of the previous tile never reach the output
    // (the thread-count tests compare runs with different reuse).
    let stride = tw + 2 * K::HALO;
    let rows = band + 2 * K::HALO;
    let init = || Scratch {
        state: k.state(stride, rows),
        sink: sink.scratch(tw),
    };
    let ctx = Ctx {
        raw,
        phase,
        k,
        sink,
        bounds,
        isa,
    };
    let tasks = tasks(out, w, band, tw);
    // Tiles cost about the same: a run of them per thread makes rayon call
    // `init` about once per thread instead of once per split.
    let run = tasks.len().div_ceil(2 * threads);
    tasks
        .into_par_iter()
        .with_min_len(run)
        .for_each_init(init, |scratch, mut task| tile(&ctx, scratch, &mut task));
}

/// The width of the tiles of a mosaic `w` wide, at most `cols`: as few
/// tiles as that allows, of equal widths rounded up to whole cache lines
/// (16 floats; `cols` is a multiple), so that the threads get equal work
/// and rings of [`cache_aligned`] rows keep their alignment.
fn tile_width(w: usize, cols: usize) -> usize {
    w.div_ceil(w.div_ceil(cols)).next_multiple_of(16).min(w)
}

/// The tile of `rows` (segments of output rows, `3 * width` long each) at
/// image row `y0` and column `x0`.
struct Task<'o, O> {
    y0: usize,
    x0: usize,
    rows: Vec<&'o mut [O]>,
}

/// The tiles of bands of `band` rows and `tw` columns of an output `w`
/// pixels wide, band by band, each holding its own segments of the
/// output rows: tiles side by side can then run on different threads.
fn tasks<O>(out: &mut [O], w: usize, band: usize, tw: usize) -> Vec<Task<'_, O>> {
    let mut tasks: Vec<Task<'_, O>> = Vec::new();
    for (i, rows) in out.chunks_mut(3 * w * band).enumerate() {
        let first = tasks.len();
        tasks.extend((0..w).step_by(tw).map(|x0| Task {
            y0: i * band,
            x0,
            rows: Vec::with_capacity(band),
        }));
        for row in rows.chunks_exact_mut(3 * w) {
            for (task, segment) in tasks[first..].iter_mut().zip(row.chunks_mut(3 * tw)) {
                task.rows.push(segment);
            }
        }
    }
    tasks
}

/// What every tile of one [`run_tiled`] call shares.
struct Ctx<'a, M, K, S> {
    raw: &'a M,
    phase: Phase,
    k: &'a K,
    sink: &'a S,
    bounds: (f32, f32),
    /// The kernel's instruction set, which the rows' loads and stores
    /// share.
    isa: Isa,
}

/// Per-thread buffers of [`run_tiled`].
struct Scratch<S, Q> {
    state: S,
    sink: Q,
}

/// Computes `task`'s tile and writes its output rows.
fn tile<M: Mosaic, O, S: RgbSink<O>, K: StreamKernel>(
    ctx: &Ctx<'_, M, K, S>,
    scratch: &mut Scratch<K::State, S::Scratch>,
    task: &mut Task<'_, O>,
) {
    let halo = K::HALO;
    let (n, tw) = (task.rows.len(), task.rows[0].len() / 3);
    let t = Tile {
        stride: tw + 2 * halo,
        rows: n + 2 * halo,
        y0: task.y0 as isize - halo as isize,
    };
    let Scratch { state, sink } = scratch;
    let raw = Source {
        raw: ctx.raw,
        t: &t,
        left: task.x0 as isize - halo as isize,
        isa: ctx.isa,
    };
    let mut store = Store {
        ctx,
        t: &t,
        sink,
        rows: &mut task.rows,
    };
    let job = Stream {
        k: ctx.k,
        state,
        t: &t,
        raw: &raw,
        out: &mut store,
    };
    on(ctx.isa, job);
}

/// Work that runs in the copy of its code compiled for an instruction set
/// ([`on`]): its `run` is always inlined into that copy.
trait Job {
    fn run(self);
}

/// Runs `job` in its copy for `isa`, which the caller has checked the CPU
/// for ([`Isa::detect`](super::Isa)).
fn on<J: Job>(isa: Isa, job: J) {
    match isa {
        Isa::Baseline => job.run(),
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::Avx2` is only made after detecting AVX2 and FMA.
        Isa::Avx2 => unsafe { on_avx2(job) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::Avx512` is only made after detecting the four
        // AVX-512 subsets `on_avx512` enables.
        Isa::Avx512 => unsafe { on_avx512(job) },
    }
}

/// `job` compiled for AVX2 and FMA (both of which [`Isa::Avx2`] requires).
/// Rust never contracts a product and a sum, so FMA only serves the
/// kernels that ask for fused multiply-adds (the orientation-hashed
/// filters' `mul_add`): without it, their scalar columns called a software
/// `fmaf` per tap.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn on_avx2<J: Job>(job: J) {
    job.run();
}

/// `job` compiled for AVX-512 (see [`Isa::Avx512`]). The kernels fuse no
/// multiply-add they do not ask for (Rust never contracts), so the bits
/// are AVX2's.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl")]
fn on_avx512<J: Job>(job: J) {
    job.run();
}

/// A kernel's run over one tile. It sees the mosaic and the output only
/// as trait objects (called once per row, or once per tile for a plane
/// kernel), so each kernel is compiled once per instruction set, not once
/// more for every pairing of mosaic and output (`demosaic`'s three sample
/// types, ranged or not, and the three developments): such copies were
/// three quarters of the extension's release build, and the calls through
/// the trait objects cost no measurable time.
struct Stream<'a, 'o, K: StreamKernel> {
    k: &'a K,
    state: &'a mut K::State,
    t: &'a Tile,
    raw: &'a dyn Load,
    out: &'a mut (dyn Emit + 'o),
}

impl<K: StreamKernel> Job for Stream<'_, '_, K> {
    #[inline(always)]
    fn run(self) {
        let mut out = self.out;
        self.k.stream(self.state, self.t, &self.raw, &mut out);
    }
}

/// The output rows of one tile, which [`Emit`] clamps and writes.
struct Store<'a, 'c, 'o, M, K, S: RgbSink<O>, O> {
    ctx: &'c Ctx<'c, M, K, S>,
    t: &'a Tile,
    sink: &'a mut S::Scratch,
    rows: &'a mut [&'o mut [O]],
}

impl<M: Mosaic, K: StreamKernel, S: RgbSink<O>, O> Emit for Store<'_, '_, '_, M, K, S, O> {
    fn emit(&mut self, ty: usize, rows: [&[f32]; 3]) {
        self.emit_rows(ty..ty + 1, rows[0].len(), rows);
    }

    fn emit_rows(&mut self, rows: Range<usize>, stride: usize, planes: [&[f32]; 3]) {
        let isa = self.ctx.isa;
        let job = Write {
            to: self,
            rows,
            stride,
            planes,
        };
        on(isa, job);
    }
}

/// Output rows' stores, in the kernel's instruction set: the sinks'
/// conversions are loops that vectorise.
struct Write<'s, 'r, E> {
    to: &'s mut E,
    rows: Range<usize>,
    stride: usize,
    planes: [&'r [f32]; 3],
}

impl<M: Mosaic, K: StreamKernel, S: RgbSink<O>, O> Job
    for Write<'_, '_, Store<'_, '_, '_, M, K, S, O>>
{
    #[inline(always)]
    fn run(self) {
        for (i, ty) in self.rows.enumerate() {
            self.to.write(ty, nth_row(self.planes, i, self.stride));
        }
    }
}

impl<M: Mosaic, K: StreamKernel, S: RgbSink<O>, O> Store<'_, '_, '_, M, K, S, O> {
    #[inline(always)]
    fn write(&mut self, ty: usize, [own, green, other]: [&[f32]; 3]) {
        let (ctx, halo) = (self.ctx, K::HALO);
        let tw = self.t.stride - 2 * halo;
        let rgb = if self.t.kind(ctx.phase, ty).blue {
            [other, green, own]
        } else {
            [own, green, other]
        };
        let rgb = rgb.map(|p| &p[halo..halo + tw]);
        let row = &mut *self.rows[ty - halo];
        ctx.sink.store(self.sink, rgb, Some(ctx.bounds), row);
    }
}

/// The raw rows of one tile: image columns `left ..` are tile columns `0 ..`.
struct Source<'a, M> {
    raw: &'a M,
    t: &'a Tile,
    left: isize,
    isa: Isa,
}

impl<M: Mosaic> Load for Source<'_, M> {
    fn load(&self, ty: usize, dst: &mut [f32]) {
        self.load_rows(ty..ty + 1, dst);
    }

    fn load_rows(&self, rows: Range<usize>, dst: &mut [f32]) {
        on(
            self.isa,
            Read {
                from: self,
                rows,
                dst,
            },
        );
    }
}

/// Raw rows' loads, in the kernel's instruction set.
struct Read<'s, 'd, M> {
    from: &'s Source<'s, M>,
    rows: Range<usize>,
    dst: &'d mut [f32],
}

impl<M: Mosaic> Job for Read<'_, '_, M> {
    #[inline(always)]
    fn run(self) {
        for (ty, row) in rows_in(self.rows, self.dst) {
            self.from.read(ty, row);
        }
    }
}

impl<M: Mosaic> Source<'_, M> {
    /// The columns inside the image are loaded as one run, the rest are
    /// mirrored, copied from the run where it holds them (it always does
    /// but in images narrower than the halo).
    #[inline(always)]
    fn read(&self, ty: usize, dst: &mut [f32]) {
        let (raw, left) = (self.raw, self.left);
        let (w, h) = (raw.width(), raw.height());
        let stride = self.t.stride;
        let (in_lo, in_hi) = (
            left.max(0) as usize,
            (left + stride as isize).min(w as isize) as usize,
        );
        let run = (in_lo as isize - left) as usize;
        let y = mirror(self.t.y0 + ty as isize, h);
        raw.load(y, in_lo, &mut dst[run..run + in_hi - in_lo]);
        for tx in (0..run).chain(run + in_hi - in_lo..stride) {
            let x = mirror(left + tx as isize, w);
            dst[tx] = if (in_lo..in_hi).contains(&x) {
                dst[run + x - in_lo]
            } else {
                let mut v = [0.0];
                raw.load(y, x, &mut v);
                v[0]
            };
        }
    }
}

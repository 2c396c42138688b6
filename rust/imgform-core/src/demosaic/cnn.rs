//! A small convolutional network over a base's output ([`super::Method::
//! FusionCnn`] over [`super::Method::FusionRefined`]), applied to the
//! base's rows as they stream out of its tile.
//!
//! The hashed filters of the learned methods are linear within a class;
//! what they leave is mostly where a class cannot tell aliasing from
//! texture. A network of a few 3x3 layers sees that over a wider window
//! and decides it non-linearly. It works on the mosaic's 2x2 cells
//! ("quads", red at the top left whatever the phase): each quad's twelve
//! values (red, green and blue of its four pixels, row by row) go through
//! [`LAYERS`] convolutions of 3x3 quads, [`WIDTH`] channels between them,
//! with a ReLU after each but the last, whose twelve outputs are added to
//! the base, clamped to the mosaic's range, except at each pixel's own
//! sample, which stays as measured. Four pixels per position make every
//! layer a quarter of the work of one over pixels, for a receptive field
//! twice as wide (26 x 26 pixels).
//!
//! The layers have no biases, so the network is positively homogeneous:
//! scaling the mosaic by `a > 0` scales its correction by `a`. It needs no
//! white level, and its corrections neither grow nor vanish in the dark as
//! a network with biases, trained on 8-bit photographs, would make them.
//!
//! Streaming: each layer keeps a ring of its last three rows of quads, the
//! base's quads are kept for [`LAYERS`] rows more (the correction of a row
//! comes that much later), so a tile 768 pixels wide keeps ~0.6 MB.
//!
//! Arithmetic: the weights are `i8` (per output channel, on its largest
//! weight), the input and every activation 15-bit codes, and a layer's
//! sums exact `i32`; each hidden sum becomes the next code by one scale,
//! ReLU, rounding ([`requantise`]). The input codes count in steps of the
//! mosaic's largest sample over 32767 and each layer's in a power of two
//! that its calibration gives (`python -m imgform_rs.training.cnn`), so the
//! network is still scale-free: a dark mosaic keeps all 15 bits. Where the
//! image lies far below its largest sample, the steps are coarse, and each
//! quad takes a share of the correction by its level ([`trust`]): with one
//! white pixel over the validation images 8-12 stops darker the method
//! stays at or above its base (within 0.02 dB of the `f32` network this
//! replaced at 8 stops), where the whole correction cost up to 0.77 dB at
//! 10 stops and 12 dB on a photograph at 13 (the guide gives the figures).
//! Integer sums cannot depend on their order, so every instruction set
//! gives the same bits, and the scaled ones are the same operations on
//! each.
//!
//! Speed: the layers are ~11 k multiply-adds per pixel, most of the time.
//! A multiply-add of pairs of `i16` takes 32 products an AVX-512
//! instruction, fused with the sum by VNNI ([`x86::Vnni`]): the method
//! runs at 12.6 MP/s at 6 MP on two threads (the `f32` network took 9.0),
//! 8.0 MP/s with `IMGFORM_ISA=avx2` (6.1) and 0.9 with
//! `IMGFORM_ISA=baseline` (0.07: each `f32` fused multiply-add was a call
//! on x86 without FMA). AVX2 fuses the two with AVX-VNNI where the CPU has
//! it (Intel's cores since Alder Lake, which lack AVX-512): 8.6 against
//! 7.9 MP/s on the Xeon that has both, capped to AVX2 (interleaved runs).
//! Where the CPU has Intel's AMX tiles (x86-64 Linux), the layers multiply
//! there (the `amx` module, 16 k products an instruction): 18 MP/s at
//! 24 MP against 12.7 with AVX-512 and VNNI.

use super::ring::Ring;
use super::tiled::{Emit, Load, StreamKernel, Tile};
use super::{Isa, Phase};
use std::sync::OnceLock;

#[cfg(amx)]
mod amx;

/// Convolutions of the shipped network.
pub(super) const LAYERS: usize = 6;
/// Channels between them.
pub(super) const WIDTH: usize = 32;
/// Values per quad: red, green, blue of its four pixels.
const QUAD: usize = 12;
/// Pixels an output reaches beyond its own quad: a quad per layer each way,
/// and one pixel more, since the quads start on the phase's red pixel.
pub(super) const REACH: usize = 2 * LAYERS + 2;
/// Sums in a vector register (AVX-512's sixteen `i32`): each layer's
/// outputs are kept in whole registers, the last layer's twelve padded to
/// sixteen.
const LANES: usize = 16;
/// The colour each pixel of a quad samples: red, green / green, blue.
const SAMPLED: [usize; 4] = [0, 1, 1, 2];
/// The last layer's outputs per quad, padded.
const PADDED: usize = QUAD.next_multiple_of(LANES);
/// The top code of the input and of every activation: 15 bits, so that a
/// layer's sums (at most 288 products of 32767 by 128) stay within `i32`.
pub(super) const TOP: i16 = i16::MAX;
/// Registers that hold sums: of AVX-512's 32, the rest hold the weights.
const SUMS: usize = 24;
/// Output quads computed together, their sums held in registers: as many
/// quads of [`WIDTH`] channels as [`SUMS`] hold, sixteen of the last
/// layer's sixteen.
const BLOCK_WIDE: usize = SUMS / (WIDTH / LANES);
const BLOCK_LAST: usize = 16;
const _: () = assert!(
    WIDTH.is_multiple_of(LANES) && QUAD.is_multiple_of(2) && WIDTH.is_multiple_of(2),
    "hidden layers fill whole registers, inputs come in pairs"
);

/// One layer of a [`Network`].
struct Layer {
    /// Weights (`i8` values) as `[tap][pair][output][2]`: each output's
    /// weights for two neighbouring input channels side by side, which is
    /// how a multiply-add of pairs (`vpmaddwd`) takes them; taps row by
    /// row, outputs padded to whole registers with zeros.
    weights: Vec<i16>,
    /// Per output (padded with zeros): what turns its sum into the next
    /// layer's code, or, for the last layer, into the correction as a
    /// fraction of the quantisation's white.
    factors: Vec<f32>,
    /// The weights as AMX's tiles take them.
    #[cfg(amx)]
    tiles: amx::Tiles,
}

/// The network's layers, quantised: `i8` weights, 15-bit activations,
/// exact integer sums. The sums' order cannot change them, so every
/// instruction set gives the same bits; the one step in floating point,
/// each sum's conversion to the next layer's code ([`requantise`]), is the
/// same three operations everywhere.
pub(super) struct Network {
    layers: Vec<Layer>,
}

/// The channels into and out of each layer.
const fn shape(layer: usize) -> (usize, usize) {
    let cin = if layer == 0 { QUAD } else { WIDTH };
    let cout = if layer == LAYERS - 1 { QUAD } else { WIDTH };
    (cin, cout)
}

/// The magic number that starts a network file, before its layer count
/// and, per layer, its input and output channels (`u32` each).
const MAGIC: &[u8; 8] = b"IFCNN\x00\x02\x00";

/// The bytes of a network file, read from the front.
struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let (head, rest) = self
            .0
            .split_first_chunk::<N>()
            .ok_or("the file ends early")?;
        self.0 = rest;
        Ok(*head)
    }

    fn u32(&mut self) -> Result<u32, String> {
        self.take().map(u32::from_le_bytes)
    }
}

impl Network {
    /// Reads a network file: [`MAGIC`], the layer count, then per layer
    /// its channel counts (`u32`), its outputs' factors (`f32`) and its
    /// weights (`i8`, `[tap][input][output]`), little-endian (what
    /// `python -m imgform_rs.training.cnn` writes).
    pub(super) fn parse(bytes: &[u8]) -> Result<Self, String> {
        let body = bytes
            .strip_prefix(MAGIC)
            .ok_or("not a network file (bad magic number)")?;
        let mut r = Reader(body);
        let count = r.u32()? as usize;
        if count != LAYERS {
            return Err(format!("{count} layers, the kernel runs {LAYERS}"));
        }
        let layers = (0..LAYERS)
            .map(|layer| Layer::parse(&mut r, layer))
            .collect::<Result<_, _>>()?;
        if !r.0.is_empty() {
            return Err("the file goes on after the last layer".into());
        }
        Ok(Network { layers })
    }

    /// The shipped network of [`super::Method::FusionCnn`], parsed once.
    pub(super) fn fusion_cnn() -> &'static Network {
        static NETWORK: OnceLock<Network> = OnceLock::new();
        NETWORK.get_or_init(|| {
            Network::parse(include_bytes!("fusion_cnn_weights.bin"))
                .expect("the shipped network parses (a unit test checks it)")
        })
    }
}

impl Layer {
    fn parse(r: &mut Reader, layer: usize) -> Result<Self, String> {
        let (cin, cout) = shape(layer);
        let got = (r.u32()?, r.u32()?);
        if got != (cin as u32, cout as u32) {
            return Err(format!(
                "layer {layer} maps {} to {} channels, the kernel {cin} to {cout}",
                got.0, got.1
            ));
        }
        let padded = cout.next_multiple_of(LANES);
        let mut factors = vec![0.0; padded];
        for f in &mut factors[..cout] {
            *f = f32::from_le_bytes(r.take()?);
        }
        if !factors.iter().all(|f| f.is_finite() && *f >= 0.0) {
            return Err(format!(
                "layer {layer} has a factor that is negative or not finite"
            ));
        }
        let mut weights = vec![0; 9 * cin * padded];
        for t in 0..9 {
            for i in 0..cin {
                for o in 0..cout {
                    let [w] = r.take::<1>()?;
                    weights[paired(cin, padded, t, i, o)] = i16::from(w as i8);
                }
            }
        }
        Ok(Layer {
            #[cfg(amx)]
            tiles: amx::Tiles::pack(cin, cout, |t, i, o| {
                weights[paired(cin, padded, t, i, o)] as i8
            }),
            weights,
            factors,
        })
    }
}

/// Where [`Layer::weights`] holds tap `t`'s weight from input `i` to
/// output `o` of a layer of `cin` inputs and `padded` outputs.
const fn paired(cin: usize, padded: usize, t: usize, i: usize, o: usize) -> usize {
    t * cin * padded + ((i / 2) * padded + o) * 2 + i % 2
}

/// A sample (clamped, so at least 0 where the mosaic is) as the
/// network's input code, `unit` codes to the mosaic's unit.
#[inline(always)]
fn quantise(v: f32, unit: f32) -> i16 {
    to_code(v * unit)
}

/// A hidden layer's sum as its output code: scaled, clipped below by the
/// ReLU and above by 15 bits, and rounded to the nearest (ties to even).
#[inline(always)]
fn requantise(sum: i32, factor: f32) -> i16 {
    to_code(sum as f32 * factor)
}

/// `v` clipped to `0 ..= TOP` and rounded to the nearest integer, ties to
/// even, by adding 2^23: from there a float's last bit is a unit, so the
/// sum is rounded so and its mantissa's low bits hold the integer. Both
/// `round_ties_even` (a call of `rintf` per value on CPUs without SSE4.1)
/// and the checked conversion of a float to an integer (`as`) stayed
/// scalar: over half the network's time, a third of the method's. This
/// vectorises on any CPU.
#[inline(always)]
fn to_code(v: f32) -> i16 {
    const SHIFT: f32 = 8_388_608.0;
    ((v.clamp(0.0, f32::from(TOP)) + SHIFT).to_bits() - SHIFT.to_bits()) as i16
}

/// Input codes of a quad's brightest value below which it takes none of
/// the network's correction, and from which it takes all of it.
const DIM: f32 = 16.0;
const BRIGHT: f32 = 128.0;

/// The share of the network's correction a quad takes, by its brightest
/// value in input codes: linear from none at [`DIM`] to all at [`BRIGHT`].
/// Far below the mosaic's largest sample the input spans a few codes and
/// the correction is mostly their rounding: with one sample at 1 and the
/// rest 11-13 stops darker, the whole correction put the method 1-12 dB
/// below its base. Quads of an 8-bit mosaic with any sample above 0 take
/// all of it. Local to the quad, so the same in any tiling or chunking.
#[inline(always)]
fn trust(level: f32) -> f32 {
    ((level - DIM) / (BRIGHT - DIM)).clamp(0.0, 1.0)
}

/// The largest of a quad's twelve values, by a tree of comparisons: a
/// chain of twelve `max` (NaN-aware, several instructions each) cost the
/// method 8 % of its time; the values are clamped, never NaN.
#[inline(always)]
fn brightest(v: &[f32]) -> f32 {
    let larger = |a: f32, b: f32| if a > b { a } else { b };
    let m: [f32; 4] = std::array::from_fn(|i| larger(larger(v[i], v[i + 4]), v[i + 8]));
    larger(larger(m[0], m[1]), larger(m[2], m[3]))
}

/// A base refined by a [`Network`].
pub(super) struct Convolved<K> {
    pub(super) base: K,
    pub(super) network: &'static Network,
    pub(super) phase: Phase,
    pub(super) isa: Isa,
    /// The mosaic's range: the network was trained on clamped outputs,
    /// so it sees the base clamped (as the output is, in the end). The
    /// input codes count in steps of the top's 32767th (a dark mosaic
    /// keeps all 15 bits), so no white level is needed: the network has
    /// no biases, and scaling its input scales its output.
    pub(super) bounds: (f32, f32),
}

/// What the network keeps while a tile streams through it.
pub(super) struct State<S> {
    base_state: S,
    rings: Rings,
}

/// The rings of quad rows, and room for a pending red row and for the
/// corrected output rows.
struct Rings {
    /// The base's quads: [`LAYERS`] rows of the correction's lag and one.
    quads: Ring,
    /// Their codes, the first layer's input: its three rows.
    codes: Ring<i16>,
    /// Each hidden layer's last three rows of codes.
    hidden: Vec<Ring<i16>>,
    /// The network's output row (the correction of one quad row).
    correction: Vec<f32>,
    /// A layer's input rows split into bytes, for AMX.
    #[cfg(amx)]
    planes: amx::Planes,
    /// The red row waiting for the blue row below it, and the tile row it
    /// came as.
    red: [Vec<f32>; 3],
    red_row: Option<usize>,
    /// The two corrected pixel rows of a quad row, as own chroma, green,
    /// other chroma.
    out: [[Vec<f32>; 3]; 2],
    /// The quads' count across the tile, and the column of the first.
    across: usize,
    first_col: usize,
}

impl Rings {
    fn new(stride: usize) -> Self {
        let quads = stride / 2;
        let row = || vec![0.0f32; stride];
        Rings {
            quads: Ring::new(quads * QUAD, LAYERS + 1, 0),
            codes: Ring::new(quads * QUAD, 3, 0),
            hidden: (1..LAYERS)
                .map(|_| Ring::new(quads * WIDTH, 3, 0))
                .collect(),
            correction: vec![0.0; quads * PADDED],
            #[cfg(amx)]
            planes: amx::Planes::default(),
            red: [row(), row(), row()],
            red_row: None,
            out: [[row(), row(), row()], [row(), row(), row()]],
            across: quads,
            first_col: 0,
        }
    }

    /// Fits the rings to a tile `stride` wide whose red pixels are in
    /// columns of parity `first_col`.
    fn fit(&mut self, stride: usize, first_col: usize) {
        self.across = (stride - first_col) / 2;
        self.first_col = first_col;
        self.quads.fit(self.across * QUAD);
        self.codes.fit(self.across * QUAD);
        for ring in &mut self.hidden {
            ring.fit(self.across * WIDTH);
        }
        self.red_row = None;
    }
}

impl<K: StreamKernel> StreamKernel for Convolved<K> {
    type State = State<K::State>;
    const HALO: usize = K::HALO + REACH;
    const ROWS: usize = K::ROWS;
    /// Half the base's: the layers' rings grow with the tile's width, and
    /// 1.5 k columns made the method's extra memory 7.2 % of the output;
    /// the base's halo, recomputed per tile, is a small part of the time.
    const COLS: usize = K::COLS / 2;
    const AVX512: bool = K::AVX512;

    fn rows(height: usize, across: usize, threads: usize) -> usize {
        K::rows(height, across, threads)
    }

    fn state(&self, stride: usize, rows: usize) -> Self::State {
        State {
            base_state: self.base.state(stride, rows),
            rings: Rings::new(stride),
        }
    }

    #[inline(always)]
    fn stream<E: Emit, L: Load>(&self, st: &mut Self::State, t: &Tile, raw: &L, out: &mut E) {
        let State { base_state, rings } = st;
        rings.fit(t.stride, self.phase.rx);
        let white = self.bounds.1;
        let mut quads = Quads {
            network: self.network,
            phase: self.phase,
            isa: self.isa,
            #[cfg(amx)]
            amx: self.isa == Isa::Avx512 && crate::cpu::has_amx(),
            bounds: self.bounds,
            // An all-black mosaic: every code 0, so no correction.
            unit: if white > 0.0 {
                f32::from(TOP) / white
            } else {
                0.0
            },
            halo: Self::HALO,
            t,
            rings,
            step: 0,
            first_row: 0,
            out,
        };
        self.base.stream(base_state, t, raw, &mut quads);
    }
}

/// Takes the base's rows, pairs them into quad rows, runs the layers as
/// each quad row comes and hands on the corrected rows [`LAYERS`] quad
/// rows behind.
struct Quads<'a, E> {
    network: &'static Network,
    phase: Phase,
    isa: Isa,
    /// Whether the layers run on AMX's tiles ([`crate::cpu::has_amx`]).
    #[cfg(amx)]
    amx: bool,
    bounds: (f32, f32),
    /// Input codes per unit of the mosaic.
    unit: f32,
    /// The output's halo: rows outside it are not handed on.
    halo: usize,
    t: &'a Tile,
    rings: &'a mut Rings,
    /// Quad rows taken so far, and the tile row of the first one's red row.
    step: usize,
    first_row: usize,
    out: &'a mut E,
}

impl<E: Emit> Emit for Quads<'_, E> {
    #[inline(always)]
    fn emit(&mut self, ty: usize, rows: [&[f32]; 3]) {
        let kind = self.t.kind(self.phase, ty);
        let rings = &mut *self.rings;
        if !kind.blue {
            for (dst, src) in rings.red.iter_mut().zip(rows) {
                dst[..src.len()].copy_from_slice(src);
            }
            rings.red_row = Some(ty);
            return;
        }
        // A blue row before any red one has no quad to complete.
        if rings.red_row.take() != Some(ty.wrapping_sub(1)) {
            return;
        }
        if self.step == 0 {
            self.first_row = ty - 1;
        }
        let q = self.step;
        pack(rings, q, rows, self.bounds, self.unit);
        self.layers(q);
        self.step += 1;
        if let Some(done) = q.checked_sub(LAYERS).filter(|&d| d >= LAYERS) {
            self.hand_on(done);
        }
    }
}

impl<E: Emit> Quads<'_, E> {
    /// Runs every layer whose next row quad row `q` completes: hidden
    /// layer `k` computes row `q - k`, the last layer row `q - LAYERS`
    /// into [`Rings::correction`].
    #[inline(always)]
    fn layers(&mut self, q: usize) {
        let rings = &mut *self.rings;
        let n = rings.across;
        for k in 1..=LAYERS {
            let Some(row) = q.checked_sub(k).filter(|&r| r >= k) else {
                return;
            };
            let (before, after) = rings.hidden.split_at_mut(k - 1);
            let src = if k == 1 { &rings.codes } else { &before[k - 2] };
            let input = [row - 1, row, row + 1].map(|r| src.row(r));
            let (isa, layer) = (self.isa, &self.network.layers[k - 1]);
            let out = if k == LAYERS {
                // In the mosaic's unit: the factors' fraction of white.
                Out::Correction(&mut rings.correction, self.bounds.1)
            } else {
                Out::Codes(after[0].row_mut(row))
            };
            #[cfg(amx)]
            if self.amx {
                // SAFETY: `amx` is set only with `Isa::Avx512` and where
                // `has_amx` says the CPU has the tiles and the OS granted
                // them.
                unsafe {
                    match k {
                        1 => amx::conv_row::<QUAD>(input, layer, &mut rings.planes, out, n),
                        _ => amx::conv_row::<WIDTH>(input, layer, &mut rings.planes, out, n),
                    }
                }
                continue;
            }
            const V: usize = WIDTH / LANES;
            match k {
                LAYERS => conv_row::<WIDTH, 1, BLOCK_LAST>(isa, input, layer, out, n),
                1 => conv_row::<QUAD, V, BLOCK_WIDE>(isa, input, layer, out, n),
                _ => conv_row::<WIDTH, V, BLOCK_WIDE>(isa, input, layer, out, n),
            }
        }
    }

    /// Adds the correction to quad row `q`'s base and hands on its two
    /// pixel rows that lie inside the output.
    #[inline(always)]
    fn hand_on(&mut self, q: usize) {
        let rings = &mut *self.rings;
        let base = rings.quads.row(q);
        let (c0, n) = (rings.first_col, rings.across);
        let [top, bottom] = &mut rings.out;
        // Quad columns 0 and n - 1 have no correction; the halo keeps
        // them (and the columns the network could not see) outside the
        // output.
        for x in 1..n - 1 {
            let v = &base[x * QUAD..(x + 1) * QUAD];
            let d = &rings.correction[x * PADDED..x * PADDED + QUAD];
            let share = trust(brightest(v) * self.unit);
            let px = c0 + 2 * x;
            for (i, rows) in [(0, &mut *top), (1, &mut *bottom)] {
                for j in 0..2 {
                    let p = 3 * (2 * i + j);
                    // The pixel's own sample stays as the mosaic has it. (A
                    // loop: an `array::map` here was left as calls, 2 % of
                    // the method's time, 9 % with the share.)
                    let mut rgb = [0.0f32; 3];
                    for (c, out) in rgb.iter_mut().enumerate() {
                        let own = c == SAMPLED[2 * i + j];
                        *out = v[p + c] + if own { 0.0 } else { d[p + c] * share };
                    }
                    // Top rows are red rows: own chroma red; bottom rows blue.
                    let (own, other) = if i == 0 { (0, 2) } else { (2, 0) };
                    rows[0][px + j] = rgb[own];
                    rows[1][px + j] = rgb[1];
                    rows[2][px + j] = rgb[other];
                }
            }
        }
        let ty = self.first_row + 2 * q;
        let t = self.t;
        for (i, rows) in rings.out.iter().enumerate() {
            if (self.halo..t.rows - self.halo).contains(&(ty + i)) {
                self.out
                    .emit(ty + i, rows.each_ref().map(|r| &r[..t.stride]));
            }
        }
    }
}

/// Packs quad row `q` from the pending red row and the blue row `blue`
/// (each as own chroma, green, other chroma), clamped to `(lo, hi)`, into
/// the ring of quads, and their codes (`unit` per unit of the mosaic)
/// into the ring of codes.
#[inline(always)]
fn pack(rings: &mut Rings, q: usize, blue: [&[f32]; 3], (lo, hi): (f32, f32), unit: f32) {
    let (c0, n) = (rings.first_col, rings.across);
    let red = &rings.red;
    let dst = rings.quads.row_mut(q);
    let codes = rings.codes.row_mut(q);
    for x in 0..n {
        let px = c0 + 2 * x;
        let quad = &mut dst[x * QUAD..(x + 1) * QUAD];
        for j in 0..2 {
            // Red rows hold red as their own chroma, blue rows blue.
            let top = [red[0][px + j], red[1][px + j], red[2][px + j]];
            let bottom = [blue[2][px + j], blue[1][px + j], blue[0][px + j]];
            let clamp = |v: [f32; 3]| v.map(|v| v.max(lo).min(hi));
            quad[3 * j..3 * j + 3].copy_from_slice(&clamp(top));
            quad[6 + 3 * j..9 + 3 * j].copy_from_slice(&clamp(bottom));
        }
        for (c, &v) in codes[x * QUAD..(x + 1) * QUAD].iter_mut().zip(&*quad) {
            *c = quantise(v, unit);
        }
    }
}

/// Where a layer's row goes: the next layer's codes, or the correction in
/// the mosaic's unit (the factors are fractions of the white given).
enum Out<'a> {
    Codes(&'a mut [i16]),
    Correction(&'a mut [f32], f32),
}

/// One row of a 3x3 convolution over quads: output quads `1 .. n - 1`
/// from input rows `rows` (above, at, below), `CIN` channels per quad in,
/// `16 V` out. Blocks of `B` outputs keep their sums in registers while
/// the taps stream past, then go out through [`Out`].
#[inline(always)]
fn conv_row<const CIN: usize, const V: usize, const B: usize>(
    isa: Isa,
    rows: [&[i16]; 3],
    layer: &Layer,
    mut out: Out,
    n: usize,
) {
    let cout = V * LANES;
    #[cfg(target_arch = "x86_64")]
    let vnni = match isa {
        Isa::Avx512 => std::arch::is_x86_feature_detected!("avx512vnni"),
        Isa::Avx2 => std::arch::is_x86_feature_detected!("avxvnni"),
        Isa::Baseline => false,
    };
    let mut sums = [0i32; SUMS * LANES];
    let mut block = |x, wide: bool| {
        let count = if wide { B } else { 1 };
        let sums = &mut sums[..count * cout];
        let w = &layer.weights[..];
        #[cfg(target_arch = "x86_64")]
        let vectors = isa != Isa::Baseline;
        #[cfg(not(target_arch = "x86_64"))]
        let vectors = false;
        #[cfg(target_arch = "x86_64")]
        if vectors {
            // SAFETY: `Isa::Avx512` is only made on CPUs with AVX-512 F
            // and BW, `Isa::Avx2` on CPUs with AVX2, `vnni` only where
            // they also have the VNNI of their width.
            unsafe {
                match (isa, vnni, wide) {
                    (Isa::Avx512, true, true) => x86::vnni::<CIN, V, B>(rows, w, sums, x),
                    (Isa::Avx512, true, false) => x86::vnni::<CIN, V, 1>(rows, w, sums, x),
                    (Isa::Avx512, false, true) => x86::avx512::<CIN, V, B>(rows, w, sums, x),
                    (Isa::Avx512, false, false) => x86::avx512::<CIN, V, 1>(rows, w, sums, x),
                    (_, true, true) => x86::avx2_vnni::<CIN, V, B>(rows, w, sums, x),
                    (_, true, false) => x86::avx2_vnni::<CIN, V, 1>(rows, w, sums, x),
                    (_, false, true) => x86::avx2::<CIN, V, B>(rows, w, sums, x),
                    (_, false, false) => x86::avx2::<CIN, V, 1>(rows, w, sums, x),
                }
            }
        }
        if !vectors && wide {
            block::<CIN, V, B>(rows, w, sums, x);
        } else if !vectors {
            block::<CIN, V, 1>(rows, w, sums, x);
        }
        finish(layer, sums, &mut out, x, cout);
    };
    let mut x = 1;
    while x + B < n {
        block(x, true);
        x += B;
    }
    while x + 1 < n {
        block(x, false);
        x += 1;
    }
}

/// Sends the sums of output quads `x ..` (`cout` each) out: as codes
/// ([`requantise`]) or as the correction.
#[inline(always)]
fn finish(layer: &Layer, sums: &[i32], out: &mut Out, x: usize, cout: usize) {
    let quads = sums.chunks_exact(cout);
    match out {
        Out::Codes(codes) => {
            for (dst, sums) in codes[x * cout..].chunks_exact_mut(cout).zip(quads) {
                for ((d, &s), &f) in dst.iter_mut().zip(sums).zip(&layer.factors) {
                    *d = requantise(s, f);
                }
            }
        }
        Out::Correction(correction, white) => {
            for (dst, sums) in correction[x * cout..].chunks_exact_mut(cout).zip(quads) {
                for ((d, &s), &f) in dst.iter_mut().zip(sums).zip(&layer.factors) {
                    *d = s as f32 * f * *white;
                }
            }
        }
    }
}

/// Output quads `x .. x + B` of [`conv_row`], in portable code (x86
/// without AVX2, and other CPUs): exact integer sums, as every path's.
///
/// It works in runs of a few quads whose sums (`V` vectors of 16 a quad)
/// fit in registers with one input pair's weights (NEON's 32 take four
/// quads of 16 channels or two of 32).
#[inline(always)]
fn block<const CIN: usize, const V: usize, const B: usize>(
    rows: [&[i16]; 3],
    weights: &[i16],
    sums: &mut [i32],
    x: usize,
) {
    let (cout, step) = (V * LANES, run_len(V, B));
    for s in (0..B).step_by(step) {
        let (sums, x) = (&mut sums[s * cout..], x + s);
        match step {
            4 => run::<CIN, V, 4>(rows, weights, sums, x),
            2 => run::<CIN, V, 2>(rows, weights, sums, x),
            _ => run::<CIN, V, 1>(rows, weights, sums, x),
        }
    }
}

/// Quads a run of [`block`] (and of AVX2's) takes at once: four of 16
/// channels (`v` 1) or two of 32, whose sums fill half of 16 or 32
/// registers with room for one input pair's weights, where `b` splits so.
const fn run_len(v: usize, b: usize) -> usize {
    if v == 1 && b.is_multiple_of(4) {
        4
    } else if v == 2 && b.is_multiple_of(2) {
        2
    } else {
        1
    }
}

/// Output quads `x .. x + S` of [`block`], their sums into `sums`. The
/// loops over a quad's sums are nested zips over whole arrays, which the
/// compiler unrolls into registers; a `flatten` over them was left as a
/// loop over the sums in memory, at a thirtieth of the speed.
#[inline(always)]
fn run<const CIN: usize, const V: usize, const S: usize>(
    rows: [&[i16]; 3],
    weights: &[i16],
    sums: &mut [i32],
    x: usize,
) {
    let cout = V * LANES;
    let mut acc = [[[0i32; LANES]; V]; S];
    for (dy, row) in rows.iter().enumerate() {
        let window = &row[(x - 1) * CIN..(x + S + 1) * CIN];
        for dx in 0..3 {
            let tap = &weights[(3 * dy + dx) * CIN * cout..][..CIN * cout];
            for (p, w) in tap.chunks_exact(2 * cout).enumerate() {
                for (b, sum) in acc.iter_mut().enumerate() {
                    let at = (b + dx) * CIN + 2 * p;
                    let (a0, a1) = (i32::from(window[at]), i32::from(window[at + 1]));
                    for (s, w) in sum.iter_mut().zip(w.chunks_exact(2 * LANES)) {
                        for (s, w) in s.iter_mut().zip(w.chunks_exact(2)) {
                            *s += a0 * i32::from(w[0]) + a1 * i32::from(w[1]);
                        }
                    }
                }
            }
        }
    }
    for (dst, sum) in sums.chunks_exact_mut(cout).zip(&acc) {
        for (d, s) in dst.chunks_exact_mut(LANES).zip(sum) {
            d.copy_from_slice(s);
        }
    }
}

/// The x86 vector blocks: one loop over the vector operations of
/// [`x86::Pairs`], in AVX-512 (with or without VNNI) and AVX2.
#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    /// What [`run`] needs of a vector of `i32` sums, per instruction set.
    /// Every method needs the CPU features of its kind; pointers are read
    /// a whole vector on.
    pub(super) trait Pairs: Copy {
        /// Sums per vector.
        const LANES: usize;
        unsafe fn zero() -> Self;
        unsafe fn load(p: *const i16) -> Self;
        /// The pair of inputs `pair` (two `i16`) in every lane.
        unsafe fn splat(pair: i32) -> Self;
        /// `acc` plus each lane's two products of `v` and `w` (`vpmaddwd`).
        unsafe fn madd(acc: Self, v: Self, w: Self) -> Self;
        unsafe fn store(self, p: *mut i32);
    }

    /// AVX-512 F and BW: 16 sums, a multiply-add of pairs and an add.
    #[derive(Clone, Copy)]
    pub(super) struct Zmm(__m512i);
    /// AVX-512 with VNNI: the two fused (`vpdpwssd`): 12.7 against 10.1
    /// MP/s for the whole method at 6 MP on two threads.
    #[derive(Clone, Copy)]
    pub(super) struct Vnni(__m512i);
    /// AVX2 with AVX-VNNI (Intel's cores since Alder Lake, which have no
    /// AVX-512): 8 sums, the two fused as [`Vnni`] does.
    #[derive(Clone, Copy)]
    pub(super) struct VnniYmm(__m256i);

    impl Pairs for Zmm {
        const LANES: usize = 16;
        #[inline(always)]
        unsafe fn zero() -> Self {
            // SAFETY: by the trait's contract.
            Zmm(unsafe { _mm512_setzero_si512() })
        }
        #[inline(always)]
        unsafe fn load(p: *const i16) -> Self {
            // SAFETY: by the trait's contract.
            Zmm(unsafe { _mm512_loadu_si512(p.cast()) })
        }
        #[inline(always)]
        unsafe fn splat(pair: i32) -> Self {
            // SAFETY: by the trait's contract.
            Zmm(unsafe { _mm512_set1_epi32(pair) })
        }
        #[inline(always)]
        unsafe fn madd(acc: Self, v: Self, w: Self) -> Self {
            // SAFETY: by the trait's contract.
            Zmm(unsafe { _mm512_add_epi32(acc.0, _mm512_madd_epi16(v.0, w.0)) })
        }
        #[inline(always)]
        unsafe fn store(self, p: *mut i32) {
            // SAFETY: by the trait's contract.
            unsafe { _mm512_storeu_si512(p.cast(), self.0) }
        }
    }

    impl Pairs for Vnni {
        const LANES: usize = 16;
        #[inline(always)]
        unsafe fn zero() -> Self {
            // SAFETY: by the trait's contract.
            Vnni(unsafe { Zmm::zero() }.0)
        }
        #[inline(always)]
        unsafe fn load(p: *const i16) -> Self {
            // SAFETY: by the trait's contract.
            Vnni(unsafe { Zmm::load(p) }.0)
        }
        #[inline(always)]
        unsafe fn splat(pair: i32) -> Self {
            // SAFETY: by the trait's contract.
            Vnni(unsafe { Zmm::splat(pair) }.0)
        }
        #[inline(always)]
        unsafe fn madd(acc: Self, v: Self, w: Self) -> Self {
            // SAFETY: by the trait's contract.
            Vnni(unsafe { _mm512_dpwssd_epi32(acc.0, v.0, w.0) })
        }
        #[inline(always)]
        unsafe fn store(self, p: *mut i32) {
            // SAFETY: by the trait's contract.
            unsafe { Zmm(self.0).store(p) }
        }
    }

    impl Pairs for __m256i {
        const LANES: usize = 8;
        #[inline(always)]
        unsafe fn zero() -> Self {
            // SAFETY: by the trait's contract.
            unsafe { _mm256_setzero_si256() }
        }
        #[inline(always)]
        unsafe fn load(p: *const i16) -> Self {
            // SAFETY: by the trait's contract.
            unsafe { _mm256_loadu_si256(p.cast()) }
        }
        #[inline(always)]
        unsafe fn splat(pair: i32) -> Self {
            // SAFETY: by the trait's contract.
            unsafe { _mm256_set1_epi32(pair) }
        }
        #[inline(always)]
        unsafe fn madd(acc: Self, v: Self, w: Self) -> Self {
            // SAFETY: by the trait's contract.
            unsafe { _mm256_add_epi32(acc, _mm256_madd_epi16(v, w)) }
        }
        #[inline(always)]
        unsafe fn store(self, p: *mut i32) {
            // SAFETY: by the trait's contract.
            unsafe { _mm256_storeu_si256(p.cast(), self) }
        }
    }

    impl Pairs for VnniYmm {
        const LANES: usize = 8;
        #[inline(always)]
        unsafe fn zero() -> Self {
            // SAFETY: by the trait's contract.
            VnniYmm(unsafe { __m256i::zero() })
        }
        #[inline(always)]
        unsafe fn load(p: *const i16) -> Self {
            // SAFETY: by the trait's contract.
            VnniYmm(unsafe { __m256i::load(p) })
        }
        #[inline(always)]
        unsafe fn splat(pair: i32) -> Self {
            // SAFETY: by the trait's contract.
            VnniYmm(unsafe { __m256i::splat(pair) })
        }
        #[inline(always)]
        unsafe fn madd(acc: Self, v: Self, w: Self) -> Self {
            // SAFETY: by the trait's contract.
            VnniYmm(unsafe { _mm256_dpwssd_avx_epi32(acc.0, v.0, w.0) })
        }
        #[inline(always)]
        unsafe fn store(self, p: *mut i32) {
            // SAFETY: by the trait's contract.
            unsafe { self.0.store(p) }
        }
    }

    /// A [`super::block`] compiled for the CPU features `$features`: `$run`
    /// (generic over the vector type) with `$pairs`. A macro, since a
    /// function with `target_feature` cannot be generic over its features.
    macro_rules! with_features {
        ($(#[$doc:meta])* $name:ident, $features:literal, $run:ident::<$pairs:ty>) => {
            $(#[$doc])*
            ///
            /// # Safety
            /// The CPU must have the features named.
            #[target_feature(enable = $features)]
            pub(super) unsafe fn $name<const CIN: usize, const V: usize, const B: usize>(
                rows: [&[i16]; 3],
                weights: &[i16],
                sums: &mut [i32],
                x: usize,
            ) {
                // SAFETY: the caller's.
                unsafe { $run::<$pairs, CIN, V, B>(rows, weights, sums, x) }
            }
        };
    }

    with_features!(
        /// AVX-512 (F and BW), all `B` quads at once.
        avx512, "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma", run::<Zmm>
    );
    with_features!(
        /// [`avx512`] with VNNI.
        vnni, "avx512f,avx512bw,avx512dq,avx512vl,avx512vnni,avx2,fma", run::<Vnni>
    );
    with_features!(
        /// AVX2, in runs of quads ([`halves`]).
        avx2, "avx2,fma", halves::<__m256i>
    );
    with_features!(
        /// [`avx2`] with AVX-VNNI.
        avx2_vnni, "avx2,fma,avxvnni", halves::<VnniYmm>
    );

    /// [`run`] with vectors of half [`super::LANES`] (AVX2's), in runs of
    /// quads whose sums fill half its 16 registers: four of 16 channels
    /// (`V` 1), two of 32.
    ///
    /// # Safety
    /// The CPU must have `P`'s features.
    #[inline(always)]
    unsafe fn halves<P: Pairs, const CIN: usize, const V: usize, const B: usize>(
        rows: [&[i16]; 3],
        weights: &[i16],
        sums: &mut [i32],
        x: usize,
    ) {
        let (cout, step) = (V * super::LANES, super::run_len(V, B));
        for s in (0..B).step_by(step) {
            let (sums, x) = (&mut sums[s * cout..], x + s);
            // SAFETY: the caller's.
            unsafe {
                match (V, step) {
                    (1, 4) => run::<P, CIN, 2, 4>(rows, weights, sums, x),
                    (1, _) => run::<P, CIN, 2, 1>(rows, weights, sums, x),
                    (_, 2) => run::<P, CIN, 4, 2>(rows, weights, sums, x),
                    _ => run::<P, CIN, 4, 1>(rows, weights, sums, x),
                }
            }
        }
    }

    /// Sums of output quads `x .. x + S`, `W` vectors each, in registers:
    /// each input pair broadcast once for them and multiplied with its
    /// weights and added pairwise (32 products an AVX-512 instruction,
    /// twice a fused multiply-add of `f32`).
    ///
    /// # Safety
    /// The CPU must have `P`'s features.
    #[inline(always)]
    unsafe fn run<P: Pairs, const CIN: usize, const W: usize, const S: usize>(
        rows: [&[i16]; 3],
        weights: &[i16],
        sums: &mut [i32],
        x: usize,
    ) {
        let cout = W * P::LANES;
        // SAFETY (all blocks): by the caller, the CPU has `P`'s features.
        let mut acc = [[unsafe { P::zero() }; W]; S];
        for (dy, row) in rows.iter().enumerate() {
            let window = &row[(x - 1) * CIN..(x + S + 1) * CIN];
            for dx in 0..3 {
                let tap = &weights[(3 * dy + dx) * CIN * cout..][..CIN * cout];
                for p in 0..CIN / 2 {
                    // `tap` holds `CIN / 2` pairs of `2 cout` weights.
                    let w: [P; W] = std::array::from_fn(|k| unsafe {
                        P::load(tap[(p * cout + k * P::LANES) * 2..].as_ptr())
                    });
                    for (b, sum) in acc.iter_mut().enumerate() {
                        // Channels `2 p` and `2 p + 1` of quad `b + dx`.
                        let pair = &window[(b + dx) * CIN + 2 * p..][..2];
                        let v = unsafe { P::splat(pair.as_ptr().cast::<i32>().read_unaligned()) };
                        for (s, w) in sum.iter_mut().zip(w) {
                            *s = unsafe { P::madd(*s, v, w) };
                        }
                    }
                }
            }
        }
        for (dst, sum) in sums.chunks_exact_mut(cout).zip(acc) {
            for (d, s) in dst.chunks_exact_mut(P::LANES).zip(sum) {
                unsafe { s.store(d.as_mut_ptr()) };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cfa::CfaPattern;
    use crate::demosaic::{demosaic, Method};
    use crate::image::ImageView;

    /// A network file of `layers` layers with the given channel counts,
    /// factors 0.5 and weights `w(layer, index)`.
    fn file(shapes: &[(u32, u32)], w: impl Fn(usize, usize) -> i8) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        out.extend((shapes.len() as u32).to_le_bytes());
        for (layer, &(cin, cout)) in shapes.iter().enumerate() {
            out.extend(cin.to_le_bytes());
            out.extend(cout.to_le_bytes());
            for _ in 0..cout {
                out.extend(0.5f32.to_le_bytes());
            }
            out.extend((0..9 * cin as usize * cout as usize).map(|i| w(layer, i) as u8));
        }
        out
    }

    fn shapes() -> Vec<(u32, u32)> {
        (0..LAYERS)
            .map(shape)
            .map(|(i, o)| (i as u32, o as u32))
            .collect()
    }

    #[test]
    fn the_shipped_network_parses() {
        assert_eq!(Network::fusion_cnn().layers.len(), LAYERS);
    }

    #[test]
    fn a_bad_network_file_is_refused_with_a_reason() {
        let good = file(&shapes(), |_, i| (i % 255) as i8);
        assert!(Network::parse(&good).is_ok());
        // The first layer's first factor.
        let at = MAGIC.len() + 12;
        let mut nan = good.clone();
        nan[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        let mut negative = good.clone();
        negative[at..at + 4].copy_from_slice(&(-1.0f32).to_le_bytes());
        let mut wrong = shapes();
        wrong[2].1 = 16;
        let wrong_reason = format!("layer 2 maps {WIDTH} to 16");
        let cases = [
            (b"NOTACNN\0".to_vec(), "bad magic"),
            (b"IFCNN\x00\x01\x00".to_vec(), "bad magic"),
            (file(&shapes()[..4], |_, _| 0), "4 layers"),
            (file(&wrong, |_, _| 0), wrong_reason.as_str()),
            (good[..good.len() - 1].to_vec(), "ends early"),
            ([good.clone(), vec![0; 1]].concat(), "goes on after"),
            (nan, "not finite"),
            (negative, "negative"),
        ];
        for (bytes, reason) in cases {
            let err = Network::parse(&bytes).err().unwrap();
            assert!(err.contains(reason), "{err}");
        }
    }

    /// The weights' layout: each output's weights for input channels `2 p`
    /// and `2 p + 1` side by side, outputs padded.
    #[test]
    fn weights_are_laid_out_in_pairs_of_inputs() {
        let net = Network::parse(&file(&shapes(), |layer, i| (layer * 7 + i % 100) as i8)).unwrap();
        for (k, layer) in net.layers.iter().enumerate() {
            let (cin, cout) = shape(k);
            let padded = cout.next_multiple_of(LANES);
            for (t, i, o) in [(0, 0, 0), (4, 3, 5), (8, cin - 1, cout - 1)] {
                let want = (k * 7 + ((t * cin + i) * cout + o) % 100) as i16;
                // The layout spelled out, as the vector code reads it.
                let got = layer.weights[(t * cin * padded) + ((i / 2) * padded + o) * 2 + i % 2];
                assert_eq!(got, want, "layer {k} tap {t} in {i} out {o}");
            }
            assert!(layer.factors[cout..].iter().all(|&f| f == 0.0));
        }
    }

    /// A block's sums in every vector build this CPU has, against the
    /// portable code's, for each layer shape the network has: integer sums
    /// cannot differ, but a wrong offset or pairing in one build would.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn every_vector_build_sums_as_the_portable_code() {
        fn agree<const CIN: usize, const V: usize, const B: usize>() {
            use std::arch::is_x86_feature_detected as has;
            type Build = unsafe fn([&[i16]; 3], &[i16], &mut [i32], usize);
            let cout = V * LANES;
            let mut seed = 0x9e37_79b9_u32;
            let mut next = move || {
                seed ^= seed << 13;
                seed ^= seed >> 17;
                seed ^= seed << 5;
                seed
            };
            let n = B + 2;
            let rows: Vec<Vec<i16>> = (0..3)
                .map(|_| (0..n * CIN).map(|_| (next() % 32768) as i16).collect())
                .collect();
            let weights: Vec<i16> = (0..9 * CIN * cout)
                .map(|_| (next() % 255) as i16 - 127)
                .collect();
            let rows = [&rows[0][..], &rows[1][..], &rows[2][..]];
            let mut want = vec![0; B * cout];
            block::<CIN, V, B>(rows, &weights, &mut want, 1);
            let avx512 =
                has!("avx512f") && has!("avx512bw") && has!("avx512dq") && has!("avx512vl");
            let builds: [(&str, bool, Build); 4] = [
                ("avx2", has!("avx2") && has!("fma"), x86::avx2::<CIN, V, B>),
                (
                    "avx2_vnni",
                    has!("avx2") && has!("fma") && has!("avxvnni"),
                    x86::avx2_vnni::<CIN, V, B>,
                ),
                ("avx512", avx512, x86::avx512::<CIN, V, B>),
                ("vnni", avx512 && has!("avx512vnni"), x86::vnni::<CIN, V, B>),
            ];
            for (name, _, build) in builds.into_iter().filter(|b| b.1) {
                let mut got = vec![0; B * cout];
                // SAFETY: the CPU has the build's features (filtered above).
                unsafe { build(rows, &weights, &mut got, 1) };
                assert_eq!(got, want, "{name}, {CIN} -> {cout}, {B} quads");
            }
        }
        agree::<QUAD, { WIDTH / LANES }, BLOCK_WIDE>();
        agree::<WIDTH, { WIDTH / LANES }, BLOCK_WIDE>();
        agree::<WIDTH, { WIDTH / LANES }, 1>();
        agree::<WIDTH, { PADDED / LANES }, BLOCK_LAST>();
        agree::<WIDTH, { PADDED / LANES }, 1>();
    }

    /// The corrected image by direct convolution over the whole image's
    /// quads in 64-bit integers, with the kernel's codes: `base` (RGB,
    /// clamped to `bounds`) plus the network's output, except at the
    /// sampled colours; `None` where the network cannot see all it needs.
    fn direct(
        base: &[f32],
        w: usize,
        h: usize,
        (ry, rx): (usize, usize),
        (lo, hi): (f32, f32),
    ) -> Vec<Option<f32>> {
        let net = Network::fusion_cnn();
        let unit = f32::from(TOP) / hi;
        let (qw, qh) = ((w - rx) / 2, (h - ry) / 2);
        let mut clamped = vec![vec![0.0; QUAD]; qw * qh];
        for (q, quad) in clamped.iter_mut().enumerate() {
            let (qy, qx) = (q / qw, q % qw);
            for (p, (i, j)) in [(0, 0), (0, 1), (1, 0), (1, 1)].into_iter().enumerate() {
                let (y, x) = (ry + 2 * qy + i, rx + 2 * qx + j);
                for c in 0..3 {
                    quad[3 * p + c] = base[3 * (y * w + x) + c].clamp(lo, hi);
                }
            }
        }
        let mut act: Vec<Vec<i64>> = clamped
            .iter()
            .map(|quad| {
                let code = |v: f32| (v * unit).round_ties_even().clamp(0.0, 32767.0);
                quad.iter().map(|&v| code(v) as i64).collect()
            })
            .collect();
        let mut correction = vec![vec![0.0f32; QUAD]; qw * qh];
        for (k, layer) in net.layers.iter().enumerate() {
            let (cin, cout) = shape(k);
            let padded = cout.next_multiple_of(LANES);
            let weight = |t: usize, i: usize, o: usize| {
                i64::from(layer.weights[paired(cin, padded, t, i, o)])
            };
            let mut next = vec![vec![0; cout]; qw * qh];
            for qy in 1..qh - 1 {
                for qx in 1..qw - 1 {
                    let q = qy * qw + qx;
                    for o in 0..cout {
                        let mut sum = 0i64;
                        for t in 0..9 {
                            let src = &act[(qy + t / 3 - 1) * qw + qx + t % 3 - 1];
                            sum += (0..cin).map(|i| src[i] * weight(t, i, o)).sum::<i64>();
                        }
                        let scaled = sum as f32 * layer.factors[o];
                        if k + 1 < LAYERS {
                            next[q][o] = scaled.round_ties_even().clamp(0.0, 32767.0) as i64;
                        } else {
                            correction[q][o] = scaled * hi;
                        }
                    }
                }
            }
            act = next;
        }
        let mut out = vec![None; 3 * w * h];
        for qy in LAYERS..qh - LAYERS {
            for qx in LAYERS..qw - LAYERS {
                let (v, d) = (&clamped[qy * qw + qx], &correction[qy * qw + qx]);
                let share = trust(brightest(v) * unit);
                for (p, (i, j)) in [(0, 0), (0, 1), (1, 0), (1, 1)].into_iter().enumerate() {
                    let k = 3 * ((ry + 2 * qy + i) * w + rx + 2 * qx + j);
                    for c in 0..3 {
                        let own = c == SAMPLED[p];
                        let dc = if own { 0.0 } else { d[3 * p + c] * share };
                        out[k + c] = Some((v[3 * p + c] + dc).clamp(lo, hi));
                    }
                }
            }
        }
        out
    }

    #[test]
    fn the_streamed_network_is_the_direct_convolution_for_every_phase() {
        let (w, h) = (61, 58);
        // Columns 40 on are 9 stops darker: the correction fades there.
        let raw: Vec<f32> = (0..w * h)
            .map(|i| ((i * 7919 + (i / w) * 104_729) % 1001) as f32 / 1000.0)
            .enumerate()
            .map(|(i, v)| if i % w >= 40 { v / 512.0 } else { v })
            .collect();
        let view = ImageView::contiguous(&raw, w, h, 1).unwrap();
        let bounds = raw
            .iter()
            .fold((1.0f32, 0.0f32), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        for (name, phase) in [
            ("RGGB", (0, 0)),
            ("GRBG", (0, 1)),
            ("GBRG", (1, 0)),
            ("BGGR", (1, 1)),
        ] {
            let pattern = CfaPattern::from_name(name).unwrap();
            let run = |method| {
                let mut out = vec![0.0f32; 3 * w * h];
                demosaic(view, &pattern, method, None, &mut out).unwrap();
                out
            };
            let base = run(Method::FusionRefined);
            let got = run(Method::FusionCnn);
            let want = direct(&base, w, h, phase, bounds);
            let mut compared = 0;
            for (g, want) in got.iter().zip(&want) {
                if let Some(v) = want {
                    assert_eq!(g.to_bits(), v.to_bits(), "{name}: {g} vs {v}");
                    compared += 1;
                }
            }
            assert!(compared > 3 * 20 * 20, "{name}: {compared} values compared");
            assert!(got != base, "{name}: the network changed nothing");
        }
    }
}

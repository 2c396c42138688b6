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
//! comes that much later), so a tile 768 pixels wide keeps ~0.9 MB.
//!
//! Speed: the layers are ~11 k multiply-adds per pixel, nearly all of the
//! time; AVX-512 runs them at ~60 G multiply-adds per second per thread in
//! [`avx512::block`] (8.4 MP/s for the whole method on two threads).
//! Other CPUs run the portable [`block`], which the compiler vectorises:
//! AVX2 ones compiled for AVX2 and FMA ([`avx2::block`], 5.5 MP/s with
//! `IMGFORM_ISA=avx2` on the same machine). x86 CPUs without FMA are slow
//! (0.07 MP/s: each fused multiply-add is a call). All give the same bits.

use super::ring::Ring;
use super::tiled::{Emit, Load, StreamKernel, Tile};
use super::{Isa, Phase};
use std::sync::OnceLock;

/// Convolutions of the shipped network.
pub(super) const LAYERS: usize = 6;
/// Channels between them.
pub(super) const WIDTH: usize = 32;
/// Values per quad: red, green, blue of its four pixels.
const QUAD: usize = 12;
/// Pixels an output reaches beyond its own quad: a quad per layer each way,
/// and one pixel more, since the quads start on the phase's red pixel.
pub(super) const REACH: usize = 2 * LAYERS + 2;
/// Floats in a vector register (AVX-512's): each layer's outputs are kept
/// in whole registers, the last layer's twelve padded to sixteen.
const LANES: usize = 16;
/// The colour each pixel of a quad samples: red, green / green, blue.
const SAMPLED: [usize; 4] = [0, 1, 1, 2];
/// The last layer's outputs per quad, padded.
const PADDED: usize = QUAD.next_multiple_of(LANES);
/// Registers that hold sums: of AVX-512's 32, the rest hold the weights.
const SUMS: usize = 24;
/// Output quads computed together, their sums held in registers: as many
/// quads of [`WIDTH`] channels as [`SUMS`] hold, sixteen of the last
/// layer's sixteen.
const BLOCK_WIDE: usize = SUMS / (WIDTH / LANES);
const BLOCK_LAST: usize = 16;
const _: () = assert!(
    WIDTH.is_multiple_of(LANES),
    "hidden layers fill whole registers"
);

/// The network's weights, layer by layer, each `[tap][input][output]`
/// (taps row by row, outputs padded to whole registers with zeros) so that
/// the inner loop runs over outputs.
pub(super) struct Network {
    layers: Vec<Vec<f32>>,
}

/// The channels into and out of each layer.
const fn shape(layer: usize) -> (usize, usize) {
    let cin = if layer == 0 { QUAD } else { WIDTH };
    let cout = if layer == LAYERS - 1 { QUAD } else { WIDTH };
    (cin, cout)
}

/// The magic number that starts a network file, before its layer count
/// and, per layer, its input and output channels (`u32` each).
const MAGIC: &[u8; 8] = b"IFCNN\x00\x01\x00";

impl Network {
    /// Reads a network file: [`MAGIC`], then per layer its channel counts
    /// and its `f32` weights, little-endian, in the layers' order (what
    /// `python -m imgform_rs.training.cnn` writes).
    pub(super) fn parse(bytes: &[u8]) -> Result<Self, String> {
        let body = bytes
            .strip_prefix(MAGIC)
            .ok_or("not a network file (bad magic number)")?;
        let mut words = body.chunks_exact(4).map(|w| [w[0], w[1], w[2], w[3]]);
        if body.len() % 4 != 0 {
            return Err("the file's length is not a whole number of words".into());
        }
        let mut word = || {
            words
                .next()
                .ok_or_else(|| "the file ends early".to_string())
        };
        let count = u32::from_le_bytes(word()?) as usize;
        if count != LAYERS {
            return Err(format!("{count} layers, the kernel runs {LAYERS}"));
        }
        let mut layers = Vec::with_capacity(LAYERS);
        for layer in 0..LAYERS {
            let (cin, cout) = shape(layer);
            let got = (u32::from_le_bytes(word()?), u32::from_le_bytes(word()?));
            if got != (cin as u32, cout as u32) {
                return Err(format!(
                    "layer {layer} maps {} to {} channels, the kernel {cin} to {cout}",
                    got.0, got.1
                ));
            }
            let padded = cout.next_multiple_of(LANES);
            let mut weights = vec![0.0; 9 * cin * padded];
            for row in weights.chunks_exact_mut(padded) {
                for w in &mut row[..cout] {
                    *w = f32::from_le_bytes(word()?);
                }
            }
            if !weights.iter().all(|w| w.is_finite()) {
                return Err(format!("layer {layer} has a weight that is not finite"));
            }
            layers.push(weights);
        }
        if word().is_ok() {
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

/// A base refined by a [`Network`].
pub(super) struct Convolved<K> {
    pub(super) base: K,
    pub(super) network: &'static Network,
    pub(super) phase: Phase,
    pub(super) isa: Isa,
    /// The mosaic's range: the network was trained on clamped outputs,
    /// so it sees the base clamped (as the output is, in the end).
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
    /// Each hidden layer's last three rows.
    hidden: Vec<Ring>,
    /// The network's output row (the correction of one quad row).
    correction: Vec<f32>,
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
            hidden: (1..LAYERS)
                .map(|_| Ring::new(quads * WIDTH, 3, 0))
                .collect(),
            correction: vec![0.0; quads * PADDED],
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
        let mut quads = Quads {
            network: self.network,
            phase: self.phase,
            isa: self.isa,
            bounds: self.bounds,
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
    bounds: (f32, f32),
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
        pack(rings, q, rows, self.bounds);
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
            let src = if k == 1 { &rings.quads } else { &before[k - 2] };
            let input = [row - 1, row, row + 1].map(|r| src.row(r));
            let (isa, weights) = (self.isa, &self.network.layers[k - 1]);
            const V: usize = WIDTH / LANES;
            if k == LAYERS {
                let out = &mut rings.correction;
                conv_row::<WIDTH, 1, BLOCK_LAST, false>(isa, input, weights, out, n);
            } else if k == 1 {
                let out = after[0].row_mut(row);
                conv_row::<QUAD, V, BLOCK_WIDE, true>(isa, input, weights, out, n);
            } else {
                let out = after[0].row_mut(row);
                conv_row::<WIDTH, V, BLOCK_WIDE, true>(isa, input, weights, out, n);
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
            let px = c0 + 2 * x;
            for (i, rows) in [(0, &mut *top), (1, &mut *bottom)] {
                for j in 0..2 {
                    let p = 3 * (2 * i + j);
                    // The pixel's own sample stays as the mosaic has it.
                    let rgb = [0, 1, 2].map(|c| {
                        v[p + c]
                            + if c == SAMPLED[2 * i + j] {
                                0.0
                            } else {
                                d[p + c]
                            }
                    });
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
/// the ring of quads.
#[inline(always)]
fn pack(rings: &mut Rings, q: usize, blue: [&[f32]; 3], (lo, hi): (f32, f32)) {
    let (c0, n) = (rings.first_col, rings.across);
    let red = &rings.red;
    let dst = rings.quads.row_mut(q);
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
    }
}

/// One row of a 3x3 convolution over quads: output quads `1 .. n - 1` of
/// `out` from input rows `rows` (above, at, below), `CIN` channels per quad
/// in, `16 V` out (see [`Layer`]), ReLU'd if `RELU`. Blocks of `B` outputs
/// keep their sums in registers while the taps stream past.
#[inline(always)]
fn conv_row<const CIN: usize, const V: usize, const B: usize, const RELU: bool>(
    isa: Isa,
    rows: [&[f32]; 3],
    weights: &[f32],
    out: &mut [f32],
    n: usize,
) {
    let block = |x, out: &mut [f32], wide: bool| {
        #[cfg(target_arch = "x86_64")]
        if isa == Isa::Avx512 {
            // SAFETY: `Isa::Avx512` is only made on CPUs with AVX-512F
            // (and FMA, which every such CPU has).
            return unsafe {
                if wide {
                    avx512::block::<CIN, V, B, RELU>(rows, weights, out, x)
                } else {
                    avx512::block::<CIN, V, 1, RELU>(rows, weights, out, x)
                }
            };
        }
        #[cfg(target_arch = "x86_64")]
        if isa == Isa::Avx2 {
            // SAFETY: `Isa::Avx2` is only made on CPUs with AVX2 and FMA.
            return unsafe {
                if wide {
                    avx2::block::<CIN, V, B, RELU>(rows, weights, out, x)
                } else {
                    avx2::block::<CIN, V, 1, RELU>(rows, weights, out, x)
                }
            };
        }
        if wide {
            block::<CIN, V, B, RELU>(rows, weights, out, x);
        } else {
            block::<CIN, V, 1, RELU>(rows, weights, out, x);
        }
    };
    let mut x = 1;
    while x + B < n {
        block(x, out, true);
        x += B;
    }
    while x + 1 < n {
        block(x, out, false);
        x += 1;
    }
}

/// Output quads `x .. x + B` of [`conv_row`], in portable code: the same
/// fused multiply-adds in the same order as [`avx512::block`], so the
/// same bits. Run by [`avx2::block`] too, compiled for AVX2 and FMA.
///
/// It works in runs of a few quads whose sums (`V` vectors of 16 floats a
/// quad) fit in registers with one input channel's weights: AVX2's 16
/// take four quads of 16 channels or two of 32 (NEON's 32 the same).
#[inline(always)]
fn block<const CIN: usize, const V: usize, const B: usize, const RELU: bool>(
    rows: [&[f32]; 3],
    weights: &[f32],
    out: &mut [f32],
    x: usize,
) {
    if V == 1 && B.is_multiple_of(4) {
        for s in (0..B).step_by(4) {
            run::<CIN, V, 4, RELU>(rows, weights, out, x + s);
        }
    } else if V == 2 && B.is_multiple_of(2) {
        for s in (0..B).step_by(2) {
            run::<CIN, V, 2, RELU>(rows, weights, out, x + s);
        }
    } else {
        for s in 0..B {
            run::<CIN, V, 1, RELU>(rows, weights, out, x + s);
        }
    }
}

/// Output quads `x .. x + S` of [`block`]. The loops over a quad's sums
/// are nested zips over whole arrays, which the compiler unrolls into
/// registers; a `flatten` over them was left as a loop over the sums in
/// memory, at a thirtieth of the speed.
#[inline(always)]
fn run<const CIN: usize, const V: usize, const S: usize, const RELU: bool>(
    rows: [&[f32]; 3],
    weights: &[f32],
    out: &mut [f32],
    x: usize,
) {
    let cout = V * LANES;
    let mut sums = [[[0.0f32; LANES]; V]; S];
    for (dy, row) in rows.iter().enumerate() {
        let window = &row[(x - 1) * CIN..(x + S + 1) * CIN];
        for dx in 0..3 {
            let tap = &weights[(3 * dy + dx) * CIN * cout..][..CIN * cout];
            for (ci, w) in tap.chunks_exact(cout).enumerate() {
                for (b, sum) in sums.iter_mut().enumerate() {
                    let v = window[(b + dx) * CIN + ci];
                    for (s, w) in sum.iter_mut().zip(w.chunks_exact(LANES)) {
                        for (s, w) in s.iter_mut().zip(w) {
                            *s = v.mul_add(*w, *s);
                        }
                    }
                }
            }
        }
    }
    let out = &mut out[x * cout..(x + S) * cout];
    for (dst, sum) in out.chunks_exact_mut(cout).zip(&sums) {
        for (d, s) in dst.chunks_exact_mut(LANES).zip(sum) {
            for (d, &s) in d.iter_mut().zip(s) {
                *d = if RELU { s.max(0.0) } else { s };
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::LANES;
    use std::arch::x86_64::*;

    /// [`super::block`] in AVX-512: `B x V` sums in registers (24 of the
    /// 32 for 32 channels out), each input value broadcast once for them.
    /// The compiler's own vectors of the portable code over a whole block
    /// of 12 quads ran at a fifth of this speed.
    ///
    /// # Safety
    /// The CPU must have AVX-512F and FMA.
    #[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma")]
    pub(super) unsafe fn block<
        const CIN: usize,
        const V: usize,
        const B: usize,
        const RELU: bool,
    >(
        rows: [&[f32]; 3],
        weights: &[f32],
        out: &mut [f32],
        x: usize,
    ) {
        let cout = V * LANES;
        let mut sums = [[_mm512_setzero_ps(); V]; B];
        for (dy, row) in rows.iter().enumerate() {
            let window = &row[(x - 1) * CIN..(x + B + 1) * CIN];
            for dx in 0..3 {
                let tap = &weights[(3 * dy + dx) * CIN * cout..][..CIN * cout];
                for ci in 0..CIN {
                    // SAFETY: `tap` holds `CIN` rows of `cout` weights.
                    let w: [__m512; V] = std::array::from_fn(|k| unsafe {
                        _mm512_loadu_ps(tap.as_ptr().add(ci * cout + k * LANES))
                    });
                    for (b, sum) in sums.iter_mut().enumerate() {
                        // SAFETY: `window` holds `B + 2` quads of `CIN`.
                        let v =
                            _mm512_set1_ps(unsafe { *window.get_unchecked((b + dx) * CIN + ci) });
                        for (s, w) in sum.iter_mut().zip(w) {
                            *s = _mm512_fmadd_ps(v, w, *s);
                        }
                    }
                }
            }
        }
        let out = &mut out[x * cout..(x + B) * cout];
        for (dst, sum) in out.chunks_exact_mut(cout).zip(sums) {
            for (d, s) in dst.chunks_exact_mut(LANES).zip(sum) {
                let s = if RELU {
                    _mm512_max_ps(s, _mm512_setzero_ps())
                } else {
                    s
                };
                // SAFETY: `d` is `LANES` floats long.
                unsafe { _mm512_storeu_ps(d.as_mut_ptr(), s) };
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

    /// A network file of `layers` layers with the given channel counts and
    /// weights `w(layer, index)`.
    fn file(shapes: &[(u32, u32)], w: impl Fn(usize, usize) -> f32) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        out.extend((shapes.len() as u32).to_le_bytes());
        for (layer, &(cin, cout)) in shapes.iter().enumerate() {
            out.extend(cin.to_le_bytes());
            out.extend(cout.to_le_bytes());
            for i in 0..9 * cin as usize * cout as usize {
                out.extend(w(layer, i).to_le_bytes());
            }
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
        let good = file(&shapes(), |_, _| 0.5);
        assert!(Network::parse(&good).is_ok());
        let mut nan = good.clone();
        let at = nan.len() - 4;
        nan[at..].copy_from_slice(&f32::NAN.to_le_bytes());
        let mut wrong = shapes();
        wrong[2].1 = 16;
        let wrong_reason = format!("layer 2 maps {WIDTH} to 16");
        let cases = [
            (b"NOTACNN\0".to_vec(), "bad magic"),
            (file(&shapes()[..4], |_, _| 0.0), "4 layers"),
            (file(&wrong, |_, _| 0.0), wrong_reason.as_str()),
            (good[..good.len() - 4].to_vec(), "ends early"),
            (good[..good.len() - 2].to_vec(), "whole number of words"),
            ([good.clone(), vec![0; 4]].concat(), "goes on after"),
            (nan, "not finite"),
        ];
        for (bytes, reason) in cases {
            let err = Network::parse(&bytes).err().unwrap();
            assert!(err.contains(reason), "{err}");
        }
    }

    /// The corrected image by direct convolution over the whole image's
    /// quads: `base` (RGB, clamped) plus the network's output, except at
    /// the sampled colours; `None` where the network cannot see all it needs.
    fn direct(base: &[f32], w: usize, h: usize, (ry, rx): (usize, usize)) -> Vec<Option<f32>> {
        let net = Network::fusion_cnn();
        let (qw, qh) = ((w - rx) / 2, (h - ry) / 2);
        let mut act: Vec<Vec<f32>> = vec![vec![0.0; QUAD]; qw * qh];
        for (q, quad) in act.iter_mut().enumerate() {
            let (qy, qx) = (q / qw, q % qw);
            for (p, (i, j)) in [(0, 0), (0, 1), (1, 0), (1, 1)].into_iter().enumerate() {
                let (y, x) = (ry + 2 * qy + i, rx + 2 * qx + j);
                quad[3 * p..3 * p + 3].copy_from_slice(&base[3 * (y * w + x)..][..3]);
            }
        }
        for (layer, weights) in net.layers.iter().enumerate() {
            let (cin, cout) = shape(layer);
            let padded = cout.next_multiple_of(LANES);
            let mut next = vec![vec![0.0; cout]; qw * qh];
            for qy in 1..qh - 1 {
                for qx in 1..qw - 1 {
                    let sums = &mut next[qy * qw + qx];
                    for t in 0..9 {
                        let src = &act[(qy + t / 3 - 1) * qw + qx + t % 3 - 1];
                        for ci in 0..cin {
                            for (co, s) in sums.iter_mut().enumerate() {
                                *s += src[ci] * weights[(t * cin + ci) * padded + co];
                            }
                        }
                    }
                    if layer + 1 < LAYERS {
                        sums.iter_mut().for_each(|s| *s = s.max(0.0));
                    }
                }
            }
            act = next;
        }
        let mut out = vec![None; 3 * w * h];
        for qy in LAYERS..qh - LAYERS {
            for qx in LAYERS..qw - LAYERS {
                let d = &act[qy * qw + qx];
                for (p, (i, j)) in [(0, 0), (0, 1), (1, 0), (1, 1)].into_iter().enumerate() {
                    let k = 3 * ((ry + 2 * qy + i) * w + rx + 2 * qx + j);
                    for c in 0..3 {
                        let own = c == SAMPLED[p];
                        out[k + c] = Some(base[k + c] + if own { 0.0 } else { d[3 * p + c] });
                    }
                }
            }
        }
        out
    }

    #[test]
    fn the_streamed_network_is_the_direct_convolution_for_every_phase() {
        let (w, h) = (61, 58);
        let raw: Vec<f32> = (0..w * h)
            .map(|i| ((i * 7919 + (i / w) * 104_729) % 1001) as f32 / 1000.0)
            .collect();
        let view = ImageView::contiguous(&raw, w, h, 1).unwrap();
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
            let want = direct(&base, w, h, phase);
            let mut compared = 0;
            for (g, want) in got.iter().zip(&want) {
                if let Some(v) = want {
                    assert!((g - v.clamp(0.0, 1.0)).abs() < 1e-5, "{name}: {g} vs {v}");
                    compared += 1;
                }
            }
            assert!(compared > 3 * 20 * 20, "{name}: {compared} values compared");
            assert!(got != base, "{name}: the network changed nothing");
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    /// [`super::block`] compiled for AVX2 and FMA: the compiler's own
    /// vectors of the portable loops, its fused multiply-adds in hardware.
    ///
    /// # Safety
    /// The CPU must have AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn block<
        const CIN: usize,
        const V: usize,
        const B: usize,
        const RELU: bool,
    >(
        rows: [&[f32]; 3],
        weights: &[f32],
        out: &mut [f32],
        x: usize,
    ) {
        super::block::<CIN, V, B, RELU>(rows, weights, out, x);
    }
}

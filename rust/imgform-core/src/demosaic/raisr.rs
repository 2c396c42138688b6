//! A learned refinement of our best classical demosaicer, in the manner of
//! RAISR: Romano, Isidoro and Milanfar, "RAISR: Rapid and Accurate Image
//! Super Resolution", IEEE Transactions on Computational Imaging 3(1), 2017.
//!
//! RAISR learns, per class of local structure, a least-squares linear filter
//! from a cheap upscaler's output to the truth. Here the cheap estimate is
//! the RCD / Menon 2007 mean and the filters predict its residual: at every
//! pixel, the two colours the photosite did not see get a correction that is
//! a linear function of 26 features of the base output around the pixel.
//! The filter is chosen by the pixel's CFA position (red or blue row, chroma
//! or green site) and a hash of the structure tensor of the base's green over
//! a 3x3 window (RAISR's angle, strength and coherence), so the map is
//! linear within a class but adapts to edges and texture across classes.
//!
//! The features are differences (each colour at the 8 neighbours minus the
//! same colour at the centre, and the centre's two chroma minus its green),
//! and the filters have no bias term: a flat image has all features zero and
//! comes back unchanged. Colours are named in the centre row's frame (its own
//! chroma, green, the other chroma), so one set of filters serves all four
//! Bayer phases. The known colour of each site is never touched.
//!
//! The filters are trained by `python -m imgform_rs.training.demosaic` on
//! openly licensed images that are not the benchmark's (see the docs) and
//! shipped in `raisr_weights.bin`, whose layout [`Weights::parse`] reads.

use super::tiled::{Tile, TileKernel};
use super::Phase;
use std::sync::OnceLock;

/// Features per pixel: 8 neighbours x 3 colours, plus 2 centre differences.
pub(crate) const FEATURES: usize = 26;
/// Angle bins of the structure tensor's orientation (fixed by [`angle_bin`]).
const ANGLES: usize = 8;
/// CFA positions: (blue row, chroma site) pairs.
const POSITIONS: usize = 4;
/// Header magic of the weights file.
const MAGIC: &[u8; 8] = b"IGRAISR1";

/// One filter: the corrections of the pixel's two missing colours.
type Filter = [[f32; FEATURES]; 2];

/// The trained filter bank and its hashing thresholds.
pub(crate) struct Weights {
    /// Upper bounds of the strength bins but the last, on the largest
    /// eigenvalue of the structure tensor of full-scale-normalised green.
    strength: Vec<f32>,
    /// Upper bounds of the coherence bins but the last.
    coherence: Vec<f32>,
    filters: Vec<Filter>,
}

impl Weights {
    /// Reads the little-endian layout: the 8-byte magic `IGRAISR1`; `u32`
    /// counts of angle, strength and coherence bins and of features; the
    /// strength then coherence thresholds (`f32`, one fewer than bins); the
    /// filters (`f32`), indexed `[position][angle][strength][coherence]
    /// [missing colour][feature]`, position being `2 * blue_row + chroma_site`.
    ///
    /// Returns `None` for a malformed file.
    pub(crate) fn parse(bytes: &[u8]) -> Option<Weights> {
        let body = bytes.strip_prefix(MAGIC)?;
        let mut words = body.chunks_exact(4).map(|w| [w[0], w[1], w[2], w[3]]);
        let mut count = || words.next().map(|w| u32::from_le_bytes(w) as usize);
        let (na, ns, nc, nf) = (count()?, count()?, count()?, count()?);
        if na != ANGLES || nf != FEATURES || ns == 0 || nc == 0 {
            return None;
        }
        let rest: Vec<f32> = words.map(f32::from_le_bytes).collect();
        let nfilters = POSITIONS * na * ns * nc;
        if body.len() % 4 != 0 || rest.len() != ns - 1 + nc - 1 + nfilters * 2 * nf {
            return None;
        }
        let (strength, rest) = rest.split_at(ns - 1);
        let (coherence, rest) = rest.split_at(nc - 1);
        let filters = rest
            .chunks_exact(2 * FEATURES)
            .map(|f| {
                let mut filter = [[0.0; FEATURES]; 2];
                filter[0].copy_from_slice(&f[..FEATURES]);
                filter[1].copy_from_slice(&f[FEATURES..]);
                filter
            })
            .collect();
        Some(Weights {
            strength: strength.to_vec(),
            coherence: coherence.to_vec(),
            filters,
        })
    }

    /// The shipped filter bank, parsed on first use.
    pub(crate) fn shipped() -> &'static Weights {
        static WEIGHTS: OnceLock<Weights> = OnceLock::new();
        WEIGHTS.get_or_init(|| {
            // The file is part of the crate and checked by a unit test, so
            // a parse failure is a build defect, not bad input.
            Weights::parse(include_bytes!("raisr_weights.bin"))
                .expect("raisr_weights.bin is malformed")
        })
    }

    /// The filter of a CFA position and structure-tensor sums.
    #[inline(always)]
    fn filter(&self, position: usize, sxx: f32, sxy: f32, syy: f32) -> &Filter {
        let (ns, nc) = (self.strength.len() + 1, self.coherence.len() + 1);
        let (l1, coh) = eigen(sxx, sxy, syy);
        let s = bin(&self.strength, l1);
        let c = bin(&self.coherence, coh);
        let a = angle_bin(sxx - syy, 2.0 * sxy);
        &self.filters[((position * ANGLES + a) * ns + s) * nc + c]
    }
}

/// The number of thresholds `v` reaches.
#[inline(always)]
fn bin(thresholds: &[f32], v: f32) -> usize {
    thresholds.iter().filter(|&&t| v >= t).count()
}

/// The largest eigenvalue of the tensor `[[sxx, sxy], [sxy, syy]]` and the
/// coherence `(sqrt(l1) - sqrt(l2)) / (sqrt(l1) + sqrt(l2))` (0 when flat).
#[inline(always)]
fn eigen(sxx: f32, sxy: f32, syy: f32) -> (f32, f32) {
    let half_trace = 0.5 * (sxx + syy);
    let half_diff = 0.5 * (sxx - syy);
    let d = (half_diff * half_diff + sxy * sxy).sqrt();
    let l1 = half_trace + d;
    let l2 = (half_trace - d).max(0.0);
    let (r1, r2) = (l1.sqrt(), l2.sqrt());
    let sum = r1 + r2;
    let coherence = if sum > 0.0 { (r1 - r2) / sum } else { 0.0 };
    (l1, coherence)
}

/// The octant of the doubled orientation angle `atan2(b, a)` of the tensor
/// (`a = sxx - syy`, `b = 2 sxy`), rotated by 22.5 degrees so that bins
/// are centred on horizontal, diagonal and vertical gradients. Comparisons
/// instead of `atan2`, so the training script reproduces it exactly.
#[inline(always)]
fn angle_bin(a: f32, b: f32) -> usize {
    const COS: f32 = 0.923_879_5;
    const SIN: f32 = 0.382_683_43;
    let (u, v) = (a * COS - b * SIN, a * SIN + b * COS);
    match (v >= 0.0, u >= 0.0) {
        (true, true) => usize::from(v > u),
        (true, false) => 2 + usize::from(v < -u),
        (false, false) => 4 + usize::from(-v > -u),
        (false, true) => 6 + usize::from(-v < u),
    }
}

/// The base kernel refined by the filter bank.
pub(super) struct Raisr<B> {
    pub(super) base: B,
    pub(super) phase: Phase,
    /// `1 / FULL_SCALE` of the sample type, so the hash sees [0, 1] data.
    pub(super) inv_scale: f32,
    /// The mosaic's smallest and largest sample: the base is clamped to
    /// them before the features are taken, as the training script sees it.
    pub(super) bounds: (f32, f32),
    pub(super) weights: &'static Weights,
}

pub(super) struct State<S> {
    base: S,
    gx: Vec<f32>,
    gy: Vec<f32>,
    /// Products of gradients, for the 3x3 sums of the structure tensor.
    pxx: Vec<f32>,
    pxy: Vec<f32>,
    pyy: Vec<f32>,
    clamped: [Vec<f32>; 3],
    out: [Vec<f32>; 3],
}

/// The 3x3 neighbours in feature order (row by row, centre excluded).
const NEIGHBOURS: [(isize, isize); 8] = [
    (-1, -1),
    (-1, 0),
    (-1, 1),
    (0, -1),
    (0, 1),
    (1, -1),
    (1, 0),
    (1, 1),
];

/// Rows `ty - 1, ty, ty + 1` of the three colours in the centre row's frame.
struct Window<'a> {
    own: [&'a [f32]; 3],
    green: [&'a [f32]; 3],
    other: [&'a [f32]; 3],
}

impl Window<'_> {
    /// The features of column `x` (see the module docs for their order).
    #[inline(always)]
    fn features(&self, x: usize) -> [f32; FEATURES] {
        let mut f = [0.0; FEATURES];
        let colours = [&self.own, &self.green, &self.other];
        for (k, &(dy, dx)) in NEIGHBOURS.iter().enumerate() {
            let (r, c) = ((1 + dy) as usize, (x as isize + dx) as usize);
            for (j, rows) in colours.iter().enumerate() {
                f[3 * k + j] = rows[r][c] - rows[1][x];
            }
        }
        f[24] = self.own[1][x] - self.green[1][x];
        f[25] = self.other[1][x] - self.green[1][x];
        f
    }
}

/// The sum of a plane over the 3x3 window centred at index `i`.
#[inline(always)]
fn box3(p: &[f32], i: usize, stride: usize) -> f32 {
    let row = |j: usize| p[j - 1] + p[j] + p[j + 1];
    row(i - stride) + row(i) + row(i + stride)
}

/// `a · b`, in four interleaved partial sums: one running sum would chain
/// 26 dependent additions per dot product (float addition is not
/// reassociated by the compiler) and bound the whole kernel by their latency.
#[inline(always)]
fn dot(a: &[f32; FEATURES], b: &[f32; FEATURES]) -> f32 {
    let mut acc = [0.0f32; 4];
    let (a4, b4) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f32 = a4
        .remainder()
        .iter()
        .zip(b4.remainder())
        .map(|(a, b)| a * b)
        .sum();
    for (ca, cb) in a4.zip(b4) {
        for ((s, a), b) in acc.iter_mut().zip(ca).zip(cb) {
            *s += a * b;
        }
    }
    ((acc[0] + acc[1]) + (acc[2] + acc[3])) + tail
}

impl<B: TileKernel> TileKernel for Raisr<B> {
    type State = State<B::State>;
    /// The base's halo plus the 2 pixels the hash reaches (1 for the 3x3
    /// sums, 1 for the central differences).
    const HALO: usize = B::HALO + 2;

    fn state(&self, stride: usize, len: usize) -> Self::State {
        let plane = || vec![0.0f32; len];
        State {
            base: self.base.state(stride, len),
            gx: plane(),
            gy: plane(),
            pxx: plane(),
            pxy: plane(),
            pyy: plane(),
            clamped: [plane(), plane(), plane()],
            out: [plane(), plane(), plane()],
        }
    }

    /// Inlined, as every kernel is, into the tile loop compiled for AVX2:
    /// a call boundary here ran the base and the filters in baseline SSE2.
    #[inline(always)]
    fn run<'s>(&self, st: &'s mut Self::State, t: &Tile, raw: &[f32]) -> [&'s [f32]; 3] {
        let State {
            base,
            gx,
            gy,
            pxx,
            pxy,
            pyy,
            clamped,
            out,
        } = st;
        let (lo, hi) = self.bounds;
        let len = t.stride * t.rows;
        for (c, p) in clamped.iter_mut().zip(self.base.run(base, t, raw)) {
            for (c, p) in c[..len].iter_mut().zip(&p[..len]) {
                *c = p.max(lo).min(hi);
            }
        }
        let planes = [&clamped[0][..], &clamped[1][..], &clamped[2][..]];
        let halo = Self::HALO;
        self.tensor(t, planes[1], [gx, gy], [pxx, pxy, pyy]);
        for ty in halo..t.rows - halo {
            self.refine_row(t, ty, planes, [pxx, pxy, pyy], out);
        }
        let [own, green, other] = out;
        [own, green, other]
    }
}

impl<B: TileKernel> Raisr<B> {
    /// Gradients of green (central differences, scaled to [0, 1] data) and
    /// their products, over the output plus one pixel.
    #[inline(always)]
    fn tensor(&self, t: &Tile, g: &[f32], grad: [&mut Vec<f32>; 2], prod: [&mut Vec<f32>; 3]) {
        let s = Self::HALO - 1;
        let k = 0.5 * self.inv_scale;
        let [gx, gy] = grad;
        let [pxx, pxy, pyy] = prod;
        for ty in s..t.rows - s {
            let sp = t.span(ty, s);
            let (e, w, n, so) = (
                sp.at(g, 0, 1),
                sp.at(g, 0, -1),
                sp.at(g, -1, 0),
                sp.at(g, 1, 0),
            );
            for ((d, e), w) in sp.out(gx).iter_mut().zip(e).zip(w) {
                *d = (e - w) * k;
            }
            for ((d, n), so) in sp.out(gy).iter_mut().zip(n).zip(so) {
                *d = (so - n) * k;
            }
            let (x, y) = (sp.at(gx, 0, 0), sp.at(gy, 0, 0));
            let r = sp.range();
            for (((xx, xy), yy), (x, y)) in pxx[r.clone()]
                .iter_mut()
                .zip(&mut pxy[r.clone()])
                .zip(&mut pyy[r])
                .zip(x.iter().zip(y))
            {
                *xx = x * x;
                *xy = x * y;
                *yy = y * y;
            }
        }
    }

    /// Copies the base's row `ty` and adds the filters' corrections to the
    /// missing colours of every output column.
    #[inline(always)]
    fn refine_row(
        &self,
        t: &Tile,
        ty: usize,
        base: [&[f32]; 3],
        prod: [&mut Vec<f32>; 3],
        out: &mut [Vec<f32>; 3],
    ) {
        let halo = Self::HALO;
        let stride = t.stride;
        let [own, green, other] = base.map(|p| move |r: usize| &p[r * stride..(r + 1) * stride]);
        // Rows above and below are of the other kind: their "own" chroma is
        // this row's "other".
        let win = Window {
            own: [other(ty - 1), own(ty), other(ty + 1)],
            green: [green(ty - 1), green(ty), green(ty + 1)],
            other: [own(ty - 1), other(ty), own(ty + 1)],
        };
        let kind = t.kind(self.phase, ty);
        let blue = usize::from(kind.blue);
        let [pxx, pxy, pyy] = prod;
        let [o_own, o_green, o_other] = out;
        let r = ty * stride..(ty + 1) * stride;
        o_own[r.clone()].copy_from_slice(win.own[1]);
        o_green[r.clone()].copy_from_slice(win.green[1]);
        o_other[r].copy_from_slice(win.other[1]);
        for x in halo..stride - halo {
            let i = ty * stride + x;
            let chroma = usize::from(x & 1 == kind.chroma_parity);
            let (sxx, sxy, syy) = (
                box3(pxx, i, stride),
                box3(pxy, i, stride),
                box3(pyy, i, stride),
            );
            let filter = self.weights.filter(2 * blue + chroma, sxx, sxy, syy);
            let f = win.features(x);
            let (d0, d1) = (dot(&filter[0], &f), dot(&filter[1], &f));
            if chroma == 1 {
                o_green[i] += d0;
            } else {
                o_own[i] += d0;
            }
            o_other[i] += d1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_weights_parse() {
        let w = Weights::shipped();
        assert_eq!(
            w.filters.len(),
            POSITIONS * ANGLES * (w.strength.len() + 1) * (w.coherence.len() + 1)
        );
        assert!(w.filters.iter().flatten().flatten().all(|v| v.is_finite()));
    }

    #[test]
    fn malformed_weights_are_refused() {
        let bytes = include_bytes!("raisr_weights.bin");
        assert!(Weights::parse(&bytes[..bytes.len() - 4]).is_none());
        assert!(Weights::parse(&bytes[1..]).is_none());
    }

    #[test]
    fn angle_bins_follow_the_doubled_orientation() {
        // Doubled angle 0 (horizontal gradient), 90 (diagonal), 180
        // (vertical), 270 (anti-diagonal) degrees.
        assert_eq!(angle_bin(1.0, 0.0), 0);
        assert_eq!(angle_bin(0.0, 1.0), 2);
        assert_eq!(angle_bin(-1.0, 0.0), 4);
        assert_eq!(angle_bin(0.0, -1.0), 6);
        assert_eq!(angle_bin(1.0, 1.0), 1);
        assert_eq!(angle_bin(1.0, -1.0), 7);
    }

    #[test]
    fn a_flat_tensor_has_no_strength_nor_coherence() {
        assert_eq!(eigen(0.0, 0.0, 0.0), (0.0, 0.0));
        let (l1, c) = eigen(4.0, 0.0, 0.0);
        assert_eq!((l1, c), (4.0, 1.0));
    }
}

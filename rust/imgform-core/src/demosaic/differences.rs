//! Residual-interpolated green with red and blue by directional colour
//! differences ([`super::Method::RiCd`]).
//!
//! MLRI's red / blue stage, guided filters over 11x11 windows, is ~40 % of
//! its time. Here the full green of its green stage guides a cheaper
//! chroma, the colour-difference interpolation of Hamilton and Adams with
//! each direction weighted by how smooth it is (as in the direction weights
//! of Pekkucuksen and Altunbasak's GBTF):
//! 1. at the sites of the other chroma, the difference `C - G` of a chroma
//!    `C` is the weighted mean of its two diagonals' means;
//! 2. at the green sites, all four neighbours then carry one, and the
//!    vertical and horizontal means are weighted the same way.
//!
//! A direction's weight is `1 / (eps + g^2)`, where `g` adds the gradient
//! of the differences along it, the gradient of green and half its second
//! difference. Every sum is taken in an order a mirror maps onto itself, so
//! the four Bayer phases stay exact flips of each other.
//!
//! On its own this is above MLRI on the validation photographs (CBSD68,
//! Urban100) and below it on the scikit-image seven and the held-out
//! training photographs, whose colours correlate less; it is the base of
//! [`super::Method::RaisrCd`], whose learned filters bring it to
//! [`super::Method::RaisrFast`]'s accuracy at a fraction of MLRI's red /
//! blue cost. The green stage streams its rows here; two stages of one row
//! each complete an output row two rows behind them.

use super::mlri::{Buffers, Mlri};
use super::ring::Ring;
use super::tiled::{Emit, Load, StreamKernel, Tile};
use super::{chroma_masks, select, shifted, Phase};

/// The direction weights' floor on the squared gradient sum, relative to
/// the squared full scale: equal weights on flat data, no division by 0.
const EPS: f32 = 1e-6;

/// MLRI's green stage followed by the colour-difference chroma.
pub(super) struct Differences {
    pub(super) green: Mlri<false>,
    /// [`EPS`] in the data's squared units.
    eps: f32,
}

impl Differences {
    pub(super) fn new(phase: Phase, full_scale: f32) -> Self {
        Self {
            green: Mlri::new(phase, full_scale),
            eps: EPS * full_scale * full_scale,
        }
    }
}

pub(super) struct State {
    green_stage: Buffers,
    /// The raw rows and the full green, as the green stage hands them on.
    raw: Ring,
    green: Ring,
    /// Per chroma (red, blue), `C - G` at each row's chroma sites: measured
    /// at the chroma's own samples, from the diagonals at the other's.
    at_chroma: [Ring; 2],
    /// The output row's own and other chroma.
    out: [Vec<f32>; 2],
    masks: [Vec<u32>; 2],
}

/// Rows the raw data is kept for: the three the diagonals read.
const RAW_ROWS: usize = 3;
/// Rows the green is kept for: from the output row's upper neighbour to
/// the newest row.
const GREEN_ROWS: usize = 4;

impl StreamKernel for Differences {
    type State = State;
    const HALO: usize = <Mlri<false> as StreamKernel>::HALO + 2;
    const ROWS: usize = <Mlri<false> as StreamKernel>::ROWS;
    const COLS: usize = <Mlri<false> as StreamKernel>::COLS;
    const AVX512: bool = <Mlri<false> as StreamKernel>::AVX512;

    fn rows(height: usize, across: usize, threads: usize) -> usize {
        <Mlri<false> as StreamKernel>::rows(height, across, threads)
    }

    fn state(&self, stride: usize, rows: usize) -> State {
        let ring = |depth| Ring::new(stride, depth, 0);
        State {
            green_stage: self.green.state(stride, rows),
            raw: ring(RAW_ROWS),
            green: ring(GREEN_ROWS),
            at_chroma: [ring(3), ring(3)],
            out: [vec![0.0; stride], vec![0.0; stride]],
            masks: chroma_masks(stride),
        }
    }

    #[inline(always)]
    fn stream<E: Emit, L: Load>(&self, st: &mut State, t: &Tile, raw: &L, out: &mut E) {
        let State {
            green_stage,
            raw: raw_rows,
            green,
            at_chroma,
            out: chroma,
            masks,
        } = st;
        for ring in [&mut *raw_rows, &mut *green]
            .into_iter()
            .chain(at_chroma.iter_mut())
        {
            ring.fit(t.stride);
        }
        let mut rows = Rows {
            k: self,
            t,
            raw: raw_rows,
            green,
            at_chroma,
            chroma,
            masks,
            out,
        };
        self.green.stream(green_stage, t, raw, &mut rows);
    }
}

/// Takes the green stage's rows and hands on each output row once the row
/// two below it has come.
struct Rows<'a, E> {
    k: &'a Differences,
    t: &'a Tile,
    raw: &'a mut Ring,
    green: &'a mut Ring,
    at_chroma: &'a mut [Ring; 2],
    chroma: &'a mut [Vec<f32>; 2],
    masks: &'a [Vec<u32>; 2],
    out: &'a mut E,
}

impl<E: Emit> Emit for Rows<'_, E> {
    #[inline(always)]
    fn emit(&mut self, ty: usize, [raw, green, _]: [&[f32]; 3]) {
        let n = self.t.stride;
        self.raw.row_mut(ty)[..n].copy_from_slice(&raw[..n]);
        self.green.row_mut(ty)[..n].copy_from_slice(&green[..n]);
        let first = <Mlri<false> as StreamKernel>::HALO;
        if ty >= first + 2 {
            self.diagonals(ty - 1, first + 1);
        }
        if ty >= first + 4 {
            self.output(ty - 2, first + 2);
        }
    }
}

/// How rough a direction is whose differences are `a` and `b` at its two
/// ends, where green is `ga` and `gb` and `g` at the centre: `eps` plus
/// the square of the summed gradients. Its weight is the reciprocal.
#[inline(always)]
fn roughness(eps: f32, (a, b): (f32, f32), (ga, g, gb): (f32, f32, f32)) -> f32 {
    let grad = (a - b).abs() + (ga - gb).abs() + 0.5 * (2.0 * g - (ga + gb)).abs();
    eps + grad * grad
}

/// The mean of two directions' means weighted by the reciprocals of their
/// roughness: `(a1, b1)` and `(a2, b2)` the differences at their ends,
/// `q1` and `q2` their roughness. One division instead of three: each
/// mean is weighted by the other's roughness.
#[inline(always)]
fn blend((a1, b1, q1): (f32, f32, f32), (a2, b2, q2): (f32, f32, f32)) -> f32 {
    ((a1 + b1) * q2 + (a2 + b2) * q1) / (2.0 * (q1 + q2))
}

impl<E: Emit> Rows<'_, E> {
    /// Stage 1 at tile row `y`, columns `r ..`: `C - G` at the row's chroma
    /// sites, for its own chroma measured, for the other one from the
    /// diagonal neighbours (its samples in the rows above and below). Both
    /// are computed at every column, without a branch (the green sites'
    /// values are never read).
    #[inline(always)]
    fn diagonals(&mut self, y: usize, r: usize) {
        let n = self.t.stride - 2 * r;
        let kind = self.t.kind(self.k.green.phase, y);
        let (raw, green) = (&*self.raw, &*self.green);
        let side = |row: usize, dx: isize| {
            let (c, g) = (raw.row(row), green.row(row));
            (shifted(c, r, dx, n), shifted(g, r, dx, n))
        };
        let (c, g) = side(y, 0);
        let ((cnw, gnw), (cne, gne)) = (side(y - 1, -1), side(y - 1, 1));
        let ((csw, gsw), (cse, gse)) = (side(y + 1, -1), side(y + 1, 1));
        let eps = self.k.eps;
        let [red, blue] = &mut *self.at_chroma;
        let (own, other) = if kind.blue { (blue, red) } else { (red, blue) };
        let taps = [c, g, cnw, gnw, cne, gne, csw, gsw, cse, gse];
        diagonal_row(
            eps,
            taps,
            &mut own.row_mut(y)[r..][..n],
            &mut other.row_mut(y)[r..][..n],
        );
    }

    /// Stage 2 at tile row `y`, columns `r ..`: both chroma everywhere (the
    /// green sites from their four neighbours' differences), and the row
    /// handed on.
    #[inline(always)]
    fn output(&mut self, y: usize, r: usize) {
        let n = self.t.stride - 2 * r;
        let kind = self.t.kind(self.k.green.phase, y);
        let m = &self.masks[kind.chroma_parity][r..][..n];
        let green = self.green.row(y);
        let raw = shifted(self.raw.row(y), r, 0, n);
        let (g, gw, ge) = (
            shifted(green, r, 0, n),
            shifted(green, r, -1, n),
            shifted(green, r, 1, n),
        );
        let (gn, gs) = (
            shifted(self.green.row(y - 1), r, 0, n),
            shifted(self.green.row(y + 1), r, 0, n),
        );
        let eps = self.k.eps;
        let order = if kind.blue { [1, 0] } else { [0, 1] };
        for (slot, class) in order.into_iter().enumerate() {
            let d = &self.at_chroma[class];
            let mid = d.row(y);
            let (dm, dw, de) = (
                shifted(mid, r, 0, n),
                shifted(mid, r, -1, n),
                shifted(mid, r, 1, n),
            );
            let (dn, ds) = (
                shifted(d.row(y - 1), r, 0, n),
                shifted(d.row(y + 1), r, 0, n),
            );
            // The own chroma keeps its samples; the other takes its
            // diagonal estimate there.
            let keep = if slot == 0 { raw } else { g };
            let out = &mut self.chroma[slot][r..][..n];
            let taps = [dm, dw, de, dn, ds, keep];
            output_row(eps, taps, [g, gw, ge, gn, gs], slot == 1, m, out);
        }
        let [own, other] = &*self.chroma;
        self.out.emit(y, [own, green, other]);
    }
}

/// Stage 1's loop over a row (see [`Rows::diagonals`]): the taps are the
/// raw row and green at the centre, then at the north-west, north-east,
/// south-west and south-east neighbours. Its own function, with its outputs
/// as arguments, so that the compiler knows they alias no input and
/// vectorises the loop (inlined into the stage, it did not).
#[inline(always)]
fn diagonal_row(eps: f32, taps: [&[f32]; 10], own: &mut [f32], other: &mut [f32]) {
    let n = own.len();
    let other = &mut other[..n];
    let [c, g, cnw, gnw, cne, gne, csw, gsw, cse, gse] = taps;
    let (c, g, cnw, gnw, cne) = (&c[..n], &g[..n], &cnw[..n], &gnw[..n], &cne[..n]);
    let (gne, csw, gsw, cse, gse) = (&gne[..n], &csw[..n], &gsw[..n], &cse[..n], &gse[..n]);
    for i in 0..n {
        own[i] = c[i] - g[i];
        let (nw, se) = (cnw[i] - gnw[i], cse[i] - gse[i]);
        let (ne, sw) = (cne[i] - gne[i], csw[i] - gsw[i]);
        let q1 = roughness(eps, (nw, se), (gnw[i], g[i], gse[i]));
        let q2 = roughness(eps, (ne, sw), (gne[i], g[i], gsw[i]));
        other[i] = blend((nw, se, q1), (ne, sw, q2));
    }
}

/// Stage 2's loop over a row for one chroma (see [`Rows::output`]): its
/// differences at the centre and the west, east, north and south
/// neighbours, and what the chroma sites (`m`) keep; green at the centre
/// and its west, east, north and south neighbours. The other
/// chroma (`estimate`) adds its difference at the chroma sites, the own
/// keeps its samples. Its own function for the reason of [`diagonal_row`].
#[inline(always)]
fn output_row(
    eps: f32,
    [dm, dw, de, dn, ds, keep]: [&[f32]; 6],
    [g, gw, ge, gn, gs]: [&[f32]; 5],
    estimate: bool,
    m: &[u32],
    out: &mut [f32],
) {
    let n = out.len();
    let (dm, dw, de, dn, ds, keep) = (&dm[..n], &dw[..n], &de[..n], &dn[..n], &ds[..n], &keep[..n]);
    let (g, gw, ge, gn, gs, m) = (&g[..n], &gw[..n], &ge[..n], &gn[..n], &gs[..n], &m[..n]);
    let add = if estimate { 1.0 } else { 0.0 };
    for i in 0..n {
        let qv = roughness(eps, (dn[i], ds[i]), (gn[i], g[i], gs[i]));
        let qh = roughness(eps, (dw[i], de[i]), (gw[i], g[i], ge[i]));
        let at_green = g[i] + blend((dn[i], ds[i], qv), (dw[i], de[i], qh));
        // `add` is 0 for the own chroma: its samples plus +-0, exactly.
        let at_chroma = keep[i] + add * dm[i];
        out[i] = select(m[i], at_chroma, at_green);
    }
}

#[cfg(test)]
mod tests {
    use crate::cfa::CfaPattern;
    use crate::demosaic::{demosaic, Method};
    use crate::image::ImageView;

    #[test]
    fn constant_colour_differences_are_reproduced() {
        // Red and blue are green plus constants, green a plane that the
        // green stage reproduces: wherever a chroma is interpolated (green
        // sites, the other chroma's sites) its difference from the
        // output's green is that constant, whichever direction wins.
        let (w, h) = (64, 56);
        let green = |x: usize, y: usize| 500.0 + 4.0 * x as f32 - 3.0 * y as f32;
        for name in ["RGGB", "GBRG", "GRBG", "BGGR"] {
            let pattern = CfaPattern::from_name(name).unwrap();
            let raw: Vec<f32> = (0..w * h)
                .map(|i| {
                    let (x, y) = (i % w, i / w);
                    green(x, y) + [30.0, 0.0, -20.0][usize::from(pattern.color_at(y, x))]
                })
                .collect();
            let view = ImageView::contiguous(&raw, w, h, 1).unwrap();
            let mut out = vec![0.0f32; 3 * w * h];
            demosaic(view, &pattern, Method::RiCd, &mut out).unwrap();
            for y in 24..h - 24 {
                for x in 24..w - 24 {
                    let site = usize::from(pattern.color_at(y, x));
                    let px = &out[3 * (y * w + x)..][..3];
                    for (c, want) in [(0, 30.0), (2, -20.0)] {
                        if c != site {
                            let got = px[c] - px[1];
                            assert!((got - want).abs() < 1e-3, "{name} ({x}, {y}) {c}: {got}");
                        }
                    }
                }
            }
        }
    }
}

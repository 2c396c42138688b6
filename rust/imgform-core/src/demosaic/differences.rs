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
use super::Phase;

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

/// Each stage computes a value at half of a row's sites only (stage 1 at
/// its chroma sites, stage 2's interpolation at its green sites), so the
/// rows are kept in halves: a row's *chroma half* holds its values at its
/// chroma sites (columns `2j + p`, `p` the row's chroma parity), its
/// *green half* those at its green sites (`2j + 1 - p`). Computed at
/// every column and selected, as first written, the stages did twice the
/// arithmetic; splitting and joining rows costs less than that half.
pub(super) struct State {
    green_stage: Buffers,
    /// The chroma halves of the raw rows and of the full green.
    raw: Ring,
    green: Ring,
    /// The green halves of the full green.
    green_sites: Ring,
    /// Per chroma (red, blue), the chroma halves of `C - G`: measured at
    /// the chroma's own samples, from the diagonals at the other's.
    at_chroma: [Ring; 2],
    /// The output row's own and other chroma at its green sites, and its
    /// other chroma at its chroma sites (the own keeps the raw samples).
    halves: [Vec<f32>; 3],
    /// The output rows (own chroma, green, other chroma), joined.
    out: [Vec<f32>; 3],
}

/// Rows the raw data's chroma halves are kept for: the three the
/// diagonals read.
const RAW_ROWS: usize = 3;
/// Rows green's chroma halves are kept for: from the output row's upper
/// neighbour to the newest row.
const GREEN_ROWS: usize = 4;
/// Rows green's green halves are kept for: from the output row to the
/// newest.
const GREEN_SITE_ROWS: usize = 3;

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
        let half = |depth| Ring::new(stride.div_ceil(2), depth, 0);
        let row = || vec![0.0; stride.div_ceil(2)];
        State {
            green_stage: self.green.state(stride, rows),
            raw: half(RAW_ROWS),
            green: half(GREEN_ROWS),
            green_sites: half(GREEN_SITE_ROWS),
            at_chroma: [half(3), half(3)],
            halves: [row(), row(), row()],
            out: [0; 3].map(|_| vec![0.0; stride]),
        }
    }

    #[inline(always)]
    fn stream<E: Emit, L: Load>(&self, st: &mut State, t: &Tile, raw: &L, out: &mut E) {
        let State {
            green_stage,
            raw: raw_rows,
            green,
            green_sites,
            at_chroma,
            halves,
            out: joined,
        } = st;
        let rings = [&mut *raw_rows, &mut *green, &mut *green_sites];
        for ring in rings.into_iter().chain(at_chroma.iter_mut()) {
            ring.fit(t.stride.div_ceil(2));
        }
        let mut rows = Rows {
            k: self,
            t,
            raw: raw_rows,
            green,
            green_sites,
            at_chroma,
            halves,
            joined,
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
    green_sites: &'a mut Ring,
    at_chroma: &'a mut [Ring; 2],
    halves: &'a mut [Vec<f32>; 3],
    joined: &'a mut [Vec<f32>; 3],
    out: &'a mut E,
}

impl<E: Emit> Emit for Rows<'_, E> {
    #[inline(always)]
    fn emit(&mut self, ty: usize, [raw, green, _]: [&[f32]; 3]) {
        let n = self.t.stride;
        let p = self.parity(ty);
        pick(&raw[..n], p, self.raw.row_mut(ty));
        split(
            &green[..n],
            p,
            [self.green.row_mut(ty), self.green_sites.row_mut(ty)],
        );
        let first = <Mlri<false> as StreamKernel>::HALO;
        if ty >= first + 2 {
            self.diagonals(ty - 1, first + 1);
        }
        if ty >= first + 4 {
            self.output(ty - 2, first + 2);
        }
    }
}

/// The values of `row` at its columns of parity `q`: `half[j]` is column
/// `2j + q`.
#[inline(always)]
fn pick(row: &[f32], q: usize, half: &mut [f32]) {
    let row = &row[q..];
    let pairs = row.chunks_exact(2);
    if let [last] = pairs.remainder() {
        half[row.len() / 2] = *last;
    }
    for (h, pair) in half.iter_mut().zip(pairs) {
        *h = pair[0];
    }
}

/// Splits `row` into the values at the columns of parity `p` and at the
/// others: `halves[0][j]` is column `2j + p`, `halves[1][j]` column `2j +
/// 1 - p`.
#[inline(always)]
fn split(row: &[f32], p: usize, [a, b]: [&mut [f32]; 2]) {
    let (even, odd) = if p == 0 { (a, b) } else { (b, a) };
    let pairs = row.chunks_exact(2);
    if let [last] = pairs.remainder() {
        even[row.len() / 2] = *last;
    }
    for ((pair, e), o) in pairs.zip(even).zip(odd) {
        (*e, *o) = (pair[0], pair[1]);
    }
}

/// The inverse of [`split`].
#[inline(always)]
fn join([a, b]: [&[f32]; 2], p: usize, row: &mut [f32]) {
    let (even, odd) = if p == 0 { (a, b) } else { (b, a) };
    let last = row.len() / 2;
    let mut pairs = row.chunks_exact_mut(2);
    for ((pair, e), o) in (&mut pairs).zip(even).zip(odd) {
        (pair[0], pair[1]) = (*e, *o);
    }
    if let [tail] = pairs.into_remainder() {
        *tail = even[last];
    }
}

/// `n` values of a half from index `j0 + dj`.
#[inline(always)]
fn at(half: &[f32], j0: usize, dj: isize, n: usize) -> &[f32] {
    let start = (j0 as isize + dj) as usize;
    &half[start..start + n]
}

/// The indices `j` of a half of parity `q` (its columns `2j + q`) whose
/// columns lie in `r .. stride - r`.
#[inline(always)]
fn span(q: usize, r: usize, stride: usize) -> (usize, usize) {
    let (lo, hi) = ((r + 1 - q) / 2, (stride - r + 1 - q) / 2);
    (lo, hi - lo)
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
    /// The column parity of tile row `y`'s chroma sites.
    fn parity(&self, y: usize) -> usize {
        self.t.kind(self.k.green.phase, y).chroma_parity
    }

    /// Stage 1 at tile row `y`, columns `r ..`: `C - G` at the row's chroma
    /// sites, for its own chroma measured, for the other one from the
    /// diagonal neighbours (its samples in the rows above and below, at
    /// their chroma sites).
    #[inline(always)]
    fn diagonals(&mut self, y: usize, r: usize) {
        let kind = self.t.kind(self.k.green.phase, y);
        let p = kind.chroma_parity;
        let (j0, n) = span(p, r, self.t.stride);
        let (raw, green) = (&*self.raw, &*self.green);
        // Columns `x - 1` and `x + 1` of the rows above and below are their
        // chroma sites `j + p - 1` and `j + p`.
        let side = |row: usize, dj: isize| {
            let (c, g) = (raw.row(row), green.row(row));
            (at(c, j0, dj, n), at(g, j0, dj, n))
        };
        let (west, east) = (p as isize - 1, p as isize);
        let (c, g) = side(y, 0);
        let ((cnw, gnw), (cne, gne)) = (side(y - 1, west), side(y - 1, east));
        let ((csw, gsw), (cse, gse)) = (side(y + 1, west), side(y + 1, east));
        let eps = self.k.eps;
        let [red, blue] = &mut *self.at_chroma;
        let (own, other) = if kind.blue { (blue, red) } else { (red, blue) };
        let taps = [c, g, cnw, gnw, cne, gne, csw, gsw, cse, gse];
        diagonal_row(
            eps,
            taps,
            &mut own.row_mut(y)[j0..][..n],
            &mut other.row_mut(y)[j0..][..n],
        );
    }

    /// Stage 2 at tile row `y`, columns `r ..`: both chroma at the green
    /// sites from their four neighbours' differences, the other chroma at
    /// the chroma sites from its diagonal estimate; the halves joined and
    /// the row handed on.
    #[inline(always)]
    fn output(&mut self, y: usize, r: usize) {
        let (stride, kind) = (self.t.stride, self.t.kind(self.k.green.phase, y));
        let p = kind.chroma_parity;
        let [own_g, other_g, other_c] = &mut *self.halves;
        // At the green sites `j`, the west and east neighbours are chroma
        // sites `j - p` and `j + 1 - p` of the row, the north and south
        // ones chroma sites `j` of the rows above and below.
        let (j0, n) = span(1 - p, r, stride);
        let (west, east) = (-(p as isize), 1 - p as isize);
        let green = self.green.row(y);
        let g = at(self.green_sites.row(y), j0, 0, n);
        let (gw, ge) = (at(green, j0, west, n), at(green, j0, east, n));
        let (gn, gs) = (
            at(self.green.row(y - 1), j0, 0, n),
            at(self.green.row(y + 1), j0, 0, n),
        );
        let eps = self.k.eps;
        let order = if kind.blue { [1, 0] } else { [0, 1] };
        for (class, out) in order.into_iter().zip([&mut *own_g, &mut *other_g]) {
            let d = &self.at_chroma[class];
            let mid = d.row(y);
            let (dw, de) = (at(mid, j0, west, n), at(mid, j0, east, n));
            let (dn, ds) = (at(d.row(y - 1), j0, 0, n), at(d.row(y + 1), j0, 0, n));
            let out = &mut out[j0..][..n];
            green_row(eps, [dn, ds, dw, de], [g, gw, ge, gn, gs], out);
        }
        // At the chroma sites: the own chroma's samples are the raw ones,
        // the other chroma is green plus its diagonal estimate.
        let (j0, n) = span(p, r, stride);
        let estimate = at(self.at_chroma[order[1]].row(y), j0, 0, n);
        sum_row(at(green, j0, 0, n), estimate, &mut other_c[j0..][..n]);
        let raw = self.raw.row(y);
        let [own, joined_green, other] = &mut *self.joined;
        let (own_g, other_g, other_c) = (&*own_g, &*other_g, &*other_c);
        join([raw, own_g], p, own);
        join([green, self.green_sites.row(y)], p, joined_green);
        join([other_c, other_g], p, other);
        self.out.emit(y, [own, joined_green, other]);
    }
}

/// Stage 1's loop over the chroma sites of a row (see
/// [`Rows::diagonals`]): the taps are the raw row and green at the centre,
/// then at the north-west, north-east, south-west and south-east
/// neighbours. Its own function, with its outputs as arguments, so that
/// the compiler knows they alias no input and vectorises the loop
/// (inlined into the stage, it did not).
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

/// Stage 2's loop over the green sites of a row for one chroma (see
/// [`Rows::output`]): its differences at the north, south, west and east
/// neighbours, green at the centre and its west, east, north and south
/// neighbours. Its own function for the reason of [`diagonal_row`].
#[inline(always)]
fn green_row(
    eps: f32,
    [dn, ds, dw, de]: [&[f32]; 4],
    [g, gw, ge, gn, gs]: [&[f32]; 5],
    out: &mut [f32],
) {
    let n = out.len();
    let (dn, ds, dw, de) = (&dn[..n], &ds[..n], &dw[..n], &de[..n]);
    let (g, gw, ge, gn, gs) = (&g[..n], &gw[..n], &ge[..n], &gn[..n], &gs[..n]);
    for i in 0..n {
        let qv = roughness(eps, (dn[i], ds[i]), (gn[i], g[i], gs[i]));
        let qh = roughness(eps, (dw[i], de[i]), (gw[i], g[i], ge[i]));
        out[i] = g[i] + blend((dn[i], ds[i], qv), (dw[i], de[i], qh));
    }
}

/// `out = a + b`, element by element.
#[inline(always)]
fn sum_row(a: &[f32], b: &[f32], out: &mut [f32]) {
    for ((o, a), b) in out.iter_mut().zip(a).zip(b) {
        *o = a + b;
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
            demosaic(view, &pattern, Method::RiCd, None, &mut out).unwrap();
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

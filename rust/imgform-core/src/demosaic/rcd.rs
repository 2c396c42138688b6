//! Ratio Corrected Demosaicing, Luis Sanz Rodríguez (2017), as described
//! for RawTherapee: a local vertical/horizontal discrimination from squared
//! high-pass responses, green from the four cardinal neighbours each
//! corrected by the ratio of a low-pass luminance at the site and at the
//! neighbour's far side, weighted by inverse gradients; then the opposite
//! chroma along the diagonals (same discrimination on the two diagonals)
//! and the chroma at green sites from colour differences to green.
//!
//! Every weighted pair `(g_b a + g_a b) / (g_a + g_b)` is evaluated as
//! `m + t d` with `m` the mean, `d` the half difference and `t` the
//! normalised gradient difference. Both forms are equal; this one is
//! exactly `a` when `a = b`, and a flip of the image swaps the pair into
//! bit-identical results, which keeps the four Bayer phases consistent.
//!
//! Each stage is a function of one row, reading planes and rings alike
//! ([`Rows`]): run stage by stage over a tile's planes ([`TileKernel`]), or
//! a step at a time down a tall tile, keeping only the rows later stages
//! still read ([`Rcd::step`], for the fusion).

use super::ring::{depth, Ring, Rows, Step};
use super::tiled::{Load, Span, Tile, TileKernel};
use super::{chroma_masks, select, Phase};

/// RCD's tolerance on data scaled to `[0, 1]`; scaled by the sample type's
/// full scale.
const EPS: f32 = 1e-5;

pub(super) struct Rcd {
    pub(super) phase: Phase,
    /// `EPS` in the data's units, and its square for squared statistics.
    pub(super) eps: f32,
}

impl Rcd {
    pub(super) fn new(phase: Phase, full_scale: f32) -> Self {
        Self {
            phase,
            eps: EPS * full_scale,
        }
    }
}

pub(super) struct State {
    /// Squared high-pass responses: vertical / horizontal, then reused for
    /// the two diagonals.
    sq: [Vec<f32>; 2],
    /// Direction weights: the share of horizontal estimation (cardinal) and
    /// the signed diagonal preference, then their refined versions.
    vh: Vec<f32>,
    vhd: Vec<f32>,
    pq: Vec<f32>,
    pqd: Vec<f32>,
    lpf: Vec<f32>,
    green: Vec<f32>,
    /// The other chroma at chroma sites.
    x: Vec<f32>,
    own: Vec<f32>,
    other: Vec<f32>,
    /// Chroma-site masks for column parity 0 and 1.
    chroma: [Vec<u32>; 2],
}

/// `(g_b a + g_a b) / (g_a + g_b)`: `a` weighted by the gradient on `b`'s
/// side and vice versa, in the flip-exact form described above.
#[inline(always)]
fn weigh(a: f32, g_a: f32, b: f32, g_b: f32) -> f32 {
    0.5 * (a + b) + (g_b - g_a) / (g_b + g_a) * (0.5 * (a - b))
}

/// RCD's gradient towards one cardinal neighbour `near` of a site `z`
/// (`opp` the opposite neighbour, `f2`..`f4` further out on `near`'s side).
#[inline(always)]
fn green_grad(z: f32, near: f32, opp: f32, f2: f32, f3: f32, f4: f32) -> f32 {
    (near - opp).abs() + (z - f2).abs() + (near - f3).abs() + (f2 - f4).abs()
}

/// The gradient towards a neighbour `near` holding the colour being
/// interpolated (`opp` opposite it, `far` two steps further), plus the
/// green change `z - g2` over two steps in that direction.
#[inline(always)]
fn diff_grad(z: f32, g2: f32, near: f32, opp: f32, far: f32) -> f32 {
    (near - opp).abs() + (near - far).abs() + (z - g2).abs()
}

/// Green `g` of a neighbour scaled by the ratio of the low-pass luminance
/// at the site (`lc`, already clamped) and at the neighbour's far side
/// (`lf`): exactly `g` on flat data. Clamped at zero so negative float
/// data cannot divide by zero.
#[inline(always)]
fn ratio_estimate(g: f32, lc: f32, lf: f32, eps: f32) -> f32 {
    g * (2.0 * lc + eps) / (lc + lf.max(0.0) + eps)
}

/// The colour difference to green at a green site `z` along one direction,
/// from the chroma at distances -3, -1, 1, 3 (`k`) and the greens at -1,
/// 1, -2, 2 (`g`).
#[inline(always)]
fn cardinal_diff(z: f32, k: [f32; 4], g: [f32; 4], eps: f32) -> f32 {
    let (a, b) = (k[1], k[2]);
    let grad_a = eps + diff_grad(z, g[2], a, b, k[0]);
    let grad_b = eps + diff_grad(z, g[3], b, a, k[3]);
    weigh(a - g[0], grad_a, b - g[1], grad_b)
}

/// The refined direction weight: the mean of the four diagonal neighbours
/// when it is more decided (further from `neutral`) than the centre.
#[inline(always)]
fn refine(c: f32, ul: f32, ur: f32, dl: f32, dr: f32, neutral: f32) -> f32 {
    let n = 0.25 * ((ul + ur) + (dl + dr));
    if (neutral - c).abs() < (neutral - n).abs() {
        n
    } else {
        c
    }
}

/// The cardinal and the diagonal directions, each pair's first the one
/// whose share or preference the stage computes.
const CARDINAL: [(isize, isize); 2] = [(1, 0), (0, 1)];
const DIAGONAL: [(isize, isize); 2] = [(1, 1), (1, -1)];

/// The reach of each stage: the rows and columns it leaves at each side
/// of its input, and so also, streaming, how many rows it lags the raw
/// data ([`Step::due`]).
const R_SQUARES: usize = 3;
const R_SHARE: usize = 4;
const R_REFINED: usize = 5;
const R_LOWPASS: usize = 1;
const R_GREEN: usize = 5;
const R_DIAGONAL: usize = 7;
pub(super) const R_OUT: usize = 10;

/// RCD's 7-tap high-pass `[1, -3, -1, 6, -1, -3, 1]` squared, along both
/// directions of `dirs`.
#[inline(always)]
fn squares<R: Rows + ?Sized>(sp: Span, c: &R, dirs: [(isize, isize); 2], out: [&mut [f32]; 2]) {
    for ((dy, dx), out) in dirs.into_iter().zip(out) {
        let at = |k: isize| sp.at(c, k * dy, k * dx);
        let (m3, m2, m1, z, p1, p2, p3) = (at(-3), at(-2), at(-1), at(0), at(1), at(2), at(3));
        for i in 0..sp.n {
            let v = ((m3[i] + p3[i]) - 3.0 * (m2[i] + p2[i])) - (m1[i] + p1[i]) + 6.0 * z[i];
            out[i] = v * v;
        }
    }
}

/// The value of a direction weight that prefers neither direction: an
/// even share along the cardinals, no preference along the diagonals.
#[inline(always)]
fn neutral(dirs: [(isize, isize); 2]) -> f32 {
    if dirs == DIAGONAL {
        0.0
    } else {
        0.5
    }
}

/// The refined direction weight of a row (see [`refine`]).
#[inline(always)]
fn refined<R: Rows + ?Sized>(sp: Span, src: &R, neutral: f32, out: &mut [f32]) {
    let (c0, ul, ur) = (sp.at(src, 0, 0), sp.at(src, -1, -1), sp.at(src, -1, 1));
    let (dl, dr) = (sp.at(src, 1, -1), sp.at(src, 1, 1));
    for i in 0..sp.n {
        out[i] = refine(c0[i], ul[i], ur[i], dl[i], dr[i], neutral);
    }
}

/// A luminance estimate: the 3x3 binomial filter sees every colour in
/// Bayer proportions at any site.
#[inline(always)]
fn lowpass<R: Rows + ?Sized>(sp: Span, c: &R, out: &mut [f32]) {
    let (z, n, s, w, e) = (
        sp.at(c, 0, 0),
        sp.at(c, -1, 0),
        sp.at(c, 1, 0),
        sp.at(c, 0, -1),
        sp.at(c, 0, 1),
    );
    let (nw, ne, sw, se) = (
        sp.at(c, -1, -1),
        sp.at(c, -1, 1),
        sp.at(c, 1, -1),
        sp.at(c, 1, 1),
    );
    for i in 0..sp.n {
        out[i] = z[i]
            + 0.5 * ((n[i] + s[i]) + (w[i] + e[i]))
            + 0.25 * ((nw[i] + ne[i]) + (sw[i] + se[i]));
    }
}

/// One row of each stage, over the planes of a tile or the rings of a
/// stream alike.
impl Rcd {
    /// The first direction's share of the two directions' summed squared
    /// responses; along the diagonals their normalised difference instead,
    /// a signed preference.
    #[inline(always)]
    fn share<R: Rows + ?Sized>(
        &self,
        sp: Span,
        [sa, sb]: [&R; 2],
        dirs: [(isize, isize); 2],
        out: &mut [f32],
    ) {
        let signed = dirs == DIAGONAL;
        let eps2 = self.eps * self.eps;
        let [(ay, ax), (by, bx)] = dirs;
        let (a0, am, ap) = (sp.at(sa, 0, 0), sp.at(sa, -ay, -ax), sp.at(sa, ay, ax));
        let (b0, bm, bp) = (sp.at(sb, 0, 0), sp.at(sb, -by, -bx), sp.at(sb, by, bx));
        for i in 0..sp.n {
            let a = ((am[i] + ap[i]) + a0[i]).max(eps2);
            let b = ((bm[i] + bp[i]) + b0[i]).max(eps2);
            out[i] = if signed {
                (a - b) / (a + b)
            } else {
                a / (a + b)
            };
        }
    }

    /// Green at chroma sites (`m`), from the four cardinal neighbours.
    #[inline(always)]
    fn green<R: Rows + ?Sized>(
        &self,
        sp: Span,
        [c, lpf, vhd]: [&R; 3],
        m: &[u32],
        out: &mut [f32],
    ) {
        let eps = self.eps;
        let v = |dy, dx| sp.at(c, dy, dx);
        let l = |dy, dx| sp.at(lpf, dy, dx);
        let (c0, l0, hd) = (v(0, 0), l(0, 0), sp.at(vhd, 0, 0));
        let (n1, n2, n3, n4) = (v(-1, 0), v(-2, 0), v(-3, 0), v(-4, 0));
        let (s1, s2, s3, s4) = (v(1, 0), v(2, 0), v(3, 0), v(4, 0));
        let (w1, w2, w3, w4) = (v(0, -1), v(0, -2), v(0, -3), v(0, -4));
        let (e1, e2, e3, e4) = (v(0, 1), v(0, 2), v(0, 3), v(0, 4));
        let (ln, ls, lw, le) = (l(-2, 0), l(2, 0), l(0, -2), l(0, 2));
        for i in 0..sp.n {
            let z = c0[i];
            // Gradients towards each side.
            let gn = eps + green_grad(z, n1[i], s1[i], n2[i], n3[i], n4[i]);
            let gs = eps + green_grad(z, s1[i], n1[i], s2[i], s3[i], s4[i]);
            let gw = eps + green_grad(z, w1[i], e1[i], w2[i], w3[i], w4[i]);
            let ge = eps + green_grad(z, e1[i], w1[i], e2[i], e3[i], e4[i]);
            // Each neighbour's green scaled by the luminance ratio between
            // the site and the neighbour's far side; clamped at zero so
            // negative float data cannot divide by zero.
            let lc = l0[i].max(0.0);
            let (en, es) = (
                ratio_estimate(n1[i], lc, ln[i], eps),
                ratio_estimate(s1[i], lc, ls[i], eps),
            );
            let (ew, ee) = (
                ratio_estimate(w1[i], lc, lw[i], eps),
                ratio_estimate(e1[i], lc, le[i], eps),
            );
            let vert = weigh(en, gn, es, gs);
            let horz = weigh(ew, gw, ee, ge);
            let g = vert + hd[i] * (horz - vert);
            out[i] = select(m[i], g, z);
        }
    }

    /// The other chroma at chroma sites, from colour differences along the
    /// two diagonals (the diagonal neighbours hold it).
    #[inline(always)]
    fn diagonal<R: Rows + ?Sized>(&self, sp: Span, [c, green, pqd]: [&R; 3], out: &mut [f32]) {
        let eps = self.eps;
        let v = |dy, dx| sp.at(c, dy, dx);
        let g = |dy, dx| sp.at(green, dy, dx);
        let (g0, dq) = (g(0, 0), sp.at(pqd, 0, 0));
        let (nw, ne, sw, se) = (v(-1, -1), v(-1, 1), v(1, -1), v(1, 1));
        let (nw3, ne3, sw3, se3) = (v(-3, -3), v(-3, 3), v(3, -3), v(3, 3));
        let (gnw, gne, gsw, gse) = (g(-1, -1), g(-1, 1), g(1, -1), g(1, 1));
        let (gnw2, gne2, gsw2, gse2) = (g(-2, -2), g(-2, 2), g(2, -2), g(2, 2));
        for i in 0..sp.n {
            let z = g0[i];
            let gnw_ = eps + diff_grad(z, gnw2[i], nw[i], se[i], nw3[i]);
            let gne_ = eps + diff_grad(z, gne2[i], ne[i], sw[i], ne3[i]);
            let gsw_ = eps + diff_grad(z, gsw2[i], sw[i], ne[i], sw3[i]);
            let gse_ = eps + diff_grad(z, gse2[i], se[i], nw[i], se3[i]);
            let p = weigh(nw[i] - gnw[i], gnw_, se[i] - gse[i], gse_);
            let q = weigh(ne[i] - gne[i], gne_, sw[i] - gsw[i], gsw_);
            out[i] = z + 0.5 * (p + q) + dq[i] * (0.5 * (q - p));
        }
    }

    /// Chroma at green sites from colour differences to the four cardinal
    /// neighbours; the row's own chroma is sampled along the row and
    /// estimated (`x`) along the column, the other vice versa. At chroma
    /// sites (`m`) the sample and `x`.
    #[inline(always)]
    fn chroma<R: Rows + ?Sized>(
        &self,
        sp: Span,
        [c, x, green, vhd]: [&R; 4],
        m: &[u32],
        [own_o, other_o]: [&mut [f32]; 2],
    ) {
        let eps = self.eps;
        let (c0, x0, g0, hd) = (
            sp.at(c, 0, 0),
            sp.at(x, 0, 0),
            sp.at(green, 0, 0),
            sp.at(vhd, 0, 0),
        );
        let g = |dy, dx| sp.at(green, dy, dx);
        let (gn1, gs1, gw1, ge1) = (g(-1, 0), g(1, 0), g(0, -1), g(0, 1));
        let (gn2, gs2, gw2, ge2) = (g(-2, 0), g(2, 0), g(0, -2), g(0, 2));
        // Sampled / estimated neighbours at distance 1 and 3.
        let cv: [&[f32]; 4] = [-3, -1, 1, 3].map(|k| sp.at(c, k, 0));
        let ch: [&[f32]; 4] = [-3, -1, 1, 3].map(|k| sp.at(c, 0, k));
        let xv: [&[f32]; 4] = [-3, -1, 1, 3].map(|k| sp.at(x, k, 0));
        let xh: [&[f32]; 4] = [-3, -1, 1, 3].map(|k| sp.at(x, 0, k));
        for i in 0..sp.n {
            let z = g0[i];
            let gv = [gn1[i], gs1[i], gn2[i], gs2[i]];
            let gh = [gw1[i], ge1[i], gw2[i], ge2[i]];
            let own_v = cardinal_diff(z, [xv[0][i], xv[1][i], xv[2][i], xv[3][i]], gv, eps);
            let own_h = cardinal_diff(z, [ch[0][i], ch[1][i], ch[2][i], ch[3][i]], gh, eps);
            let other_v = cardinal_diff(z, [cv[0][i], cv[1][i], cv[2][i], cv[3][i]], gv, eps);
            let other_h = cardinal_diff(z, [xh[0][i], xh[1][i], xh[2][i], xh[3][i]], gh, eps);
            let own_g = z + (own_v + hd[i] * (own_h - own_v));
            let other_g = z + (other_v + hd[i] * (other_h - other_v));
            own_o[i] = select(m[i], c0[i], own_g);
            other_o[i] = select(m[i], x0[i], other_g);
        }
    }

    /// The chroma-site mask of tile row `ty` for a stage of reach `r`.
    #[inline(always)]
    fn mask<'a>(&self, masks: &'a [Vec<u32>; 2], t: &Tile, ty: usize, r: usize) -> &'a [u32] {
        &masks[t.kind(self.phase, ty).chroma_parity][r..t.stride - r]
    }
}

impl TileKernel for Rcd {
    type State = State;
    const HALO: usize = R_OUT;

    fn state(&self, stride: usize, len: usize) -> State {
        let plane = || vec![0.0f32; len];
        State {
            sq: [plane(), plane()],
            vh: plane(),
            vhd: plane(),
            pq: plane(),
            pqd: plane(),
            lpf: plane(),
            green: plane(),
            x: plane(),
            own: plane(),
            other: plane(),
            chroma: chroma_masks(stride),
        }
    }

    /// Each stage over the whole tile in turn.
    #[inline(always)]
    fn run<'s>(&self, st: &'s mut State, t: &Tile, c: &[f32]) -> [&'s [f32]; 3] {
        let State {
            sq,
            vh,
            vhd,
            pq,
            pqd,
            lpf,
            green,
            x,
            own,
            other,
            chroma,
        } = st;
        let rows = |r: usize| (r..t.rows - r).map(move |ty| (ty, t.span(ty, r)));
        // The share of horizontal estimation: vertical activity over total.
        self.direction(t, c, sq, CARDINAL, [vh, vhd]);
        for (_, sp) in rows(R_LOWPASS) {
            lowpass(sp, c, sp.out(lpf));
        }
        for (ty, sp) in rows(R_GREEN) {
            let m = self.mask(chroma, t, ty, R_GREEN);
            self.green(sp, [c, lpf, vhd], m, sp.out(green));
        }
        // Signed diagonal preference: > 0 when the NW-SE diagonal is busier.
        self.direction(t, c, sq, DIAGONAL, [pq, pqd]);
        for (_, sp) in rows(R_DIAGONAL) {
            self.diagonal(sp, [c, green, pqd], sp.out(x));
        }
        for (ty, sp) in rows(R_OUT) {
            let m = self.mask(chroma, t, ty, R_OUT);
            self.chroma(sp, [c, x, green, vhd], m, [sp.out(own), sp.out(other)]);
        }
        [&*own, &*green, &*other]
    }
}

impl Rcd {
    /// The squared responses along `dirs` over the tile, then `share`, the
    /// first direction's share of them (signed along the diagonals), then
    /// its refinement `fine`.
    #[inline(always)]
    fn direction(
        &self,
        t: &Tile,
        c: &[f32],
        [sa, sb]: &mut [Vec<f32>; 2],
        dirs: [(isize, isize); 2],
        [share, fine]: [&mut [f32]; 2],
    ) {
        for ty in R_SQUARES..t.rows - R_SQUARES {
            let sp = t.span(ty, R_SQUARES);
            squares(sp, c, dirs, [sp.out(sa), sp.out(sb)]);
        }
        for ty in R_SHARE..t.rows - R_SHARE {
            let sp = t.span(ty, R_SHARE);
            self.share(sp, [&sa[..], &sb[..]], dirs, sp.out(share));
        }
        for ty in R_REFINED..t.rows - R_REFINED {
            let sp = t.span(ty, R_REFINED);
            refined(sp, &*share, neutral(dirs), sp.out(fine));
        }
    }
}

/// RCD streaming down a tile ([`Rcd::step`]), for the fusion: each stage
/// keeps the rows of its output that later stages still read, in rings,
/// where the planes of a tile hold all of them. The rows are those of a
/// tile starting at the stream's first raw row.
pub(super) struct Stream {
    raw: Ring,
    /// The cardinal and the diagonal squared responses.
    sq: [Ring; 2],
    sqd: [Ring; 2],
    vh: Ring,
    vhd: Ring,
    pq: Ring,
    pqd: Ring,
    lpf: Ring,
    green: Ring,
    x: Ring,
    own: Vec<f32>,
    other: Vec<f32>,
    chroma: [Vec<u32>; 2],
}

impl Rcd {
    /// The rings for tiles of rows `stride` long.
    pub(super) fn stream_state(&self, stride: usize) -> Stream {
        // A stage computing row `j - from` at step `j`, read last by the
        // stage computing row `j - to`, `back` rows above that.
        let ring = |from, to, back| Ring::new(stride, depth(from, to, back), 0);
        Stream {
            raw: ring(0, R_OUT, 3),
            sq: [0; 2].map(|_| ring(R_SQUARES, R_SHARE, 1)),
            sqd: [0; 2].map(|_| ring(R_SQUARES, R_SHARE, 1)),
            vh: ring(R_SHARE, R_REFINED, 1),
            vhd: ring(R_REFINED, R_OUT, 0),
            pq: ring(R_SHARE, R_REFINED, 1),
            pqd: ring(R_REFINED, R_DIAGONAL, 0),
            lpf: ring(R_LOWPASS, R_GREEN, 2),
            green: ring(R_GREEN, R_OUT, 2),
            x: ring(R_DIAGONAL, R_OUT, 3),
            own: vec![0.0; stride],
            other: vec![0.0; stride],
            chroma: chroma_masks(stride),
        }
    }

    /// Step `j` down tile `t`: takes raw row `j` (from `raw`) and
    /// computes every stage's row that is then due, the last stage's
    /// being row `j - R_OUT`, which [`Rcd::row`] then gives. Each row gets
    /// the arithmetic of the same row of a tile's planes
    /// ([`TileKernel::run`]), so the bits are the same.
    #[inline(always)]
    pub(super) fn step<L: Load>(&self, st: &mut Stream, t: &Tile, j: usize, raw: &L) {
        raw.load(j, st.raw.row_mut(j));
        let j = Step(j);
        let directions = [
            (CARDINAL, &mut st.sq, [&mut st.vh, &mut st.vhd]),
            (DIAGONAL, &mut st.sqd, [&mut st.pq, &mut st.pqd]),
        ];
        for (dirs, [a, b], [share, fine]) in directions {
            if let Some(ty) = j.due(R_SQUARES) {
                let sp = t.span(ty, R_SQUARES);
                squares(sp, &st.raw, dirs, [sp.out(a), sp.out(b)]);
            }
            if let Some(ty) = j.due(R_SHARE) {
                let sp = t.span(ty, R_SHARE);
                self.share(sp, [&*a, &*b], dirs, sp.out(share));
            }
            if let Some(ty) = j.due(R_REFINED) {
                let sp = t.span(ty, R_REFINED);
                refined(sp, &*share, neutral(dirs), sp.out(fine));
            }
        }
        let c = &st.raw;
        if let Some(ty) = j.due(R_LOWPASS) {
            let sp = t.span(ty, R_LOWPASS);
            lowpass(sp, c, sp.out(&mut st.lpf));
        }
        if let Some(ty) = j.due(R_GREEN) {
            let (sp, m) = (t.span(ty, R_GREEN), self.mask(&st.chroma, t, ty, R_GREEN));
            self.green(sp, [c, &st.lpf, &st.vhd], m, sp.out(&mut st.green));
        }
        if let Some(ty) = j.due(R_DIAGONAL) {
            let sp = t.span(ty, R_DIAGONAL);
            self.diagonal(sp, [c, &st.green, &st.pqd], sp.out(&mut st.x));
        }
        if let Some(ty) = j.due(R_OUT) {
            let (sp, m) = (t.span(ty, R_OUT), self.mask(&st.chroma, t, ty, R_OUT));
            let out = [&mut st.own[R_OUT..], &mut st.other[R_OUT..]];
            let planes = [c, &st.x, &st.green, &st.vhd];
            self.chroma(sp, planes, m, out.map(|o| &mut o[..sp.n]));
        }
    }

    /// Output row `ty` (own chroma, green, other chroma) once step `ty +
    /// R_OUT` has run, over columns `R_OUT .. stride - R_OUT`.
    #[inline(always)]
    pub(super) fn row<'s>(&self, st: &'s Stream, ty: usize) -> [&'s [f32]; 3] {
        [&st.own[..], st.green.row(ty), &st.other[..]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tile's raw rows from a plane.
    struct Plane<'a>(&'a [f32], usize);

    impl Load for Plane<'_> {
        fn load(&self, ty: usize, dst: &mut [f32]) {
            dst.copy_from_slice(&self.0[ty * self.1..(ty + 1) * self.1]);
        }
    }

    /// The stream computes each row as the tile's planes do: the fusion's
    /// bits, and the weights trained over them, rest on it.
    #[test]
    fn the_stream_gives_the_tile_planes_bits() {
        let (stride, rows) = (48, 40);
        let raw: Vec<f32> = (0..stride * rows)
            .map(|i| ((i * 7919 % 1013) as f32 * 0.37).sin() * 500.0 + 600.0)
            .collect();
        for phase in [Phase { ry: 0, rx: 0 }, Phase { ry: 1, rx: 1 }] {
            let rcd = Rcd::new(phase, 1000.0);
            let t = Tile {
                stride,
                rows,
                y0: 3,
            };
            let mut planes = TileKernel::state(&rcd, stride, raw.len());
            let [own, green, other] = rcd.run(&mut planes, &t, &raw).map(<[f32]>::to_vec);
            let mut stream = rcd.stream_state(stride);
            for j in 0..rows {
                rcd.step(&mut stream, &t, j, &Plane(&raw, stride));
                let Some(ty) = Step(j).due(R_OUT) else {
                    continue;
                };
                let cols = ty * stride + R_OUT..(ty + 1) * stride - R_OUT;
                let got = rcd.row(&stream, ty).map(|r| &r[R_OUT..stride - R_OUT]);
                for (p, (got, plane)) in got.iter().zip([&own, &green, &other]).enumerate() {
                    let want = &plane[cols.clone()];
                    let same = got
                        .iter()
                        .zip(want)
                        .all(|(a, b)| a.to_bits() == b.to_bits());
                    assert!(same, "plane {p}, row {ty}, {phase:?}");
                }
            }
        }
    }
}

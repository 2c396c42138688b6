//! Minimized-Laplacian residual interpolation: Kiku, Monno, Tanaka and
//! Okutomi, "Minimized-Laplacian residual interpolation for color image
//! demosaicking", Proc. SPIE 9023, Digital Photography X, 2014.
//!
//! Residual interpolation replaces the colour differences of classical
//! demosaicers (`G - R`, assumed smooth) by residuals `R - R~` between
//! each sample and a *tentative estimate* `R~` made by a guided filter
//! (He, Sun and Tang) from a denser guide image. The residual is far
//! smoother than the colour difference wherever colours correlate
//! linearly, so the plain interpolation of residuals loses less. MLRI
//! fits the guided filter's slope on Laplacians (`a = sum(L(I) L(p)) /
//! sum(L(I)^2)` over the window's samples) rather than on the samples
//! themselves, which makes the tentative estimate follow the guide's
//! curvature and leaves an even smoother residual.
//!
//! Steps:
//! 1. Along each direction (rows, then columns) every site gets a guide:
//!    the mean of its two neighbours on the line, i.e. the other class of
//!    that line interpolated linearly. A guided filter per CFA class on
//!    the line (samples of the class, guide at those samples) gives
//!    tentative values of that class everywhere on the line; the missing
//!    class at each site is its tentative value plus the mean of the two
//!    neighbouring residuals. The difference `G - C` follows per
//!    direction.
//! 2. The two directional colour differences are combined as in the
//!    residual-interpolation papers (after Pekkucuksen and Altunbasak's
//!    GBTF): one-sided Gaussian means towards north, south, west and east,
//!    weighted by the inverse squared colour-difference gradient on that
//!    side. Green is the sample plus that difference.
//! 3. Red and blue are guided-filtered from the full green over a 11x11
//!    window of their own samples, and their residuals interpolated
//!    bilinearly.
//!
//! The window sizes are those of the residual-interpolation reference
//! implementations: an 11-sample line (radius 5) for the directional
//! green estimates, 11x11 for red and blue, a 3x3 gradient sum and a
//! Gaussian of sigma 1 over 5 samples for the combination.
//!
//! Boxes are sums of mirrored pairs ([`boxsum`]), so the four Bayer phases
//! are exact flips of each other; every sampled value is returned
//! unchanged.
//!
//! Speed comes from keeping the many intermediate planes of a guided filter
//! out of memory: the green stage runs line by line on buffers of one
//! line (tile columns are first transposed into contiguous lines), and
//! the red / blue stage sums its classes one row at a time, so only the
//! planes that later stages read in 2-D (differences, green, products,
//! coefficients, residuals) are ever written whole.

use super::boxsum::{all_sums, class_sums, square_sum, window_sum, Parity};
use super::tiled::{Span, Tile, TileKernel};
use super::{chroma_masks, select, shifted, Phase};

/// Radius of the directional guided filters of the green stage.
const LINE_RADIUS: usize = 5;
/// Radius of the square guided filters of the red / blue stage.
const SQUARE_RADIUS: usize = 5;
/// The guided filter's floor on the mean squared Laplacian, relative to
/// the squared full scale: the references use `1e-5 * 255^2` on 8-bit
/// data. Without it a flat guide would divide noise by zero.
const FLAT: f32 = 1e-5;
/// Floor on the squared gradient sums of the direction weights, relative
/// to the squared full scale: equal weights on flat data and no overflow.
const WEIGHT_EPS: f32 = 1e-10;

/// Reach (pixels from the ends of a line, or from the tile's sides) at
/// which each stage is valid.
const R_GUIDE: usize = 1;
const R_LAPLACE: usize = R_GUIDE + 2;
const R_COEF: usize = R_LAPLACE + LINE_RADIUS;
const R_MEAN: usize = R_COEF + LINE_RADIUS;
const R_DIF: usize = R_MEAN + 1;
const R_GREEN: usize = R_DIF + 4;
const R_RB_LAPLACE: usize = R_GREEN + 2;
const R_RB_COEF: usize = R_RB_LAPLACE + SQUARE_RADIUS;
const R_RB_MEAN: usize = R_RB_COEF + SQUARE_RADIUS;
const R_OUT: usize = R_RB_MEAN + 1;

pub(super) struct Mlri {
    pub(super) phase: Phase,
    /// [`FLAT`] in the data's squared units.
    flat: f32,
    /// [`WEIGHT_EPS`] in the data's squared units.
    weight_eps: f32,
}

impl Mlri {
    pub(super) fn new(phase: Phase, full_scale: f32) -> Self {
        let fs2 = full_scale * full_scale;
        Self {
            phase,
            flat: FLAT * fs2,
            weight_eps: WEIGHT_EPS * fs2,
        }
    }
}

/// The four statistics a guided filter sums over its window: guide,
/// input, Laplacian products and squared guide Laplacians.
const STATS: usize = 4;

/// Buffers of one line of the green stage, as long as the longest line.
struct Line {
    /// The guide, and the products of Laplacians (`L(I) L(p)`, `L(I)^2`).
    guide: Vec<f32>,
    prod: [Vec<f32>; 2],
    /// Window sums of the statistics over the same and the other class.
    sums: [[Vec<f32>; 2]; STATS],
    /// Coefficients (a, b) of the chroma and the green class, then their
    /// window sums.
    coef: [Vec<f32>; 4],
    mean: [Vec<f32>; 4],
    /// Residuals of each site's own class, tentative values of the other.
    res: Vec<f32>,
    part: Vec<f32>,
    /// Pair sums of [`class_sums`].
    pairs: Vec<f32>,
}

/// Buffers of one tile row of the red / blue stage.
struct Row {
    /// A vertical window sum, the input of the horizontal ones.
    vsum: Vec<f32>,
    /// Class sums of the statistics: vertical parity (same, other) by
    /// horizontal parity (same, other).
    sums: [[Vec<f32>; 4]; STATS],
    /// Box sums of the four coefficient planes.
    mean: [Vec<f32>; 4],
    /// Pair sums of [`class_sums`].
    pairs: Vec<f32>,
}

pub(super) struct State {
    line: Line,
    row: Row,
    /// The raw tile transposed, and the column differences in that layout:
    /// the green stage reads columns as contiguous lines.
    across: Vec<f32>,
    across_dif: Vec<f32>,
    /// Products of Laplacians of the red / blue stage.
    prod: [Vec<f32>; 2],
    /// Guided-filter coefficients (a, b) of red, then blue.
    coef: [Vec<f32>; 4],
    tmp: Vec<f32>,
    /// Residuals and tentative values of red and blue.
    res: [Vec<f32>; 2],
    part: [Vec<f32>; 2],
    /// Directional colour differences `G - C` (rows, columns) and their
    /// summed gradients.
    dif: [Vec<f32>; 2],
    grad: [Vec<f32>; 2],
    weight: [Vec<f32>; 2],
    green: Vec<f32>,
    own: Vec<f32>,
    other: Vec<f32>,
    chroma: [Vec<u32>; 2],
}

/// The guided filter's coefficients from window sums over `n` samples,
/// given as `window(n, flat)`: the slope fitted on Laplacians, the offset
/// on the samples.
#[inline(always)]
fn coefficients(s: [f32; STATS], (floor, inv_n): (f32, f32)) -> (f32, f32) {
    let [si, sp, sip, sii] = s;
    let a = sip / sii.max(floor);
    (a, (sp - a * si) * inv_n)
}

/// What [`coefficients`] needs of a window of `n` samples: the floor on its
/// sum of squared Laplacians, and `1 / n` (a product per pixel where a
/// quotient cost as much as the rest of the formula).
fn window(n: usize, flat: f32) -> (f32, f32) {
    (n as f32 * flat, 1.0 / n as f32)
}

/// [`select`] between two [`window`]s.
#[inline(always)]
fn select_window(m: u32, a: (f32, f32), b: (f32, f32)) -> (f32, f32) {
    (select(m, a.0, b.0), select(m, a.1, b.1))
}

/// The statistics of sample `i` from one slice per statistic.
#[inline(always)]
fn stats(q: &[&[f32]; STATS], i: usize) -> [f32; STATS] {
    [q[0][i], q[1][i], q[2][i], q[3][i]]
}

/// [`select`] on each statistic.
#[inline(always)]
fn blend(m: u32, a: [f32; STATS], b: [f32; STATS]) -> [f32; STATS] {
    [
        select(m, a[0], b[0]),
        select(m, a[1], b[1]),
        select(m, a[2], b[2]),
        select(m, a[3], b[3]),
    ]
}

/// The weights of a one-sided Gaussian of sigma 1 over distances 0..=4,
/// normalised to sum to one.
fn half_gaussian() -> [f32; 5] {
    let g = [0.0f32, 1.0, 2.0, 3.0, 4.0].map(|d| (-0.5 * d * d).exp());
    let total: f32 = g.iter().sum();
    g.map(|v| v / total)
}

/// Plane `p` at distances 0..=4 from the span along `(dy, dx)`: one side
/// of the combination's Gaussian.
#[inline(always)]
fn arm(sp: Span, p: &[f32], (dy, dx): (isize, isize)) -> [&[f32]; 5] {
    [0, 1, 2, 3, 4].map(|k| sp.at(p, k * dy, k * dx))
}

/// `&mut v[r .. len - r]`: a line buffer over the sites a stage fills.
#[inline(always)]
fn inner(v: &mut [f32], r: usize, len: usize) -> &mut [f32] {
    &mut v[r..len - r]
}

impl Mlri {
    #[inline(always)]
    fn mask<'a>(
        &self,
        chroma: &'a [Vec<u32>; 2],
        t: &Tile,
        ty: usize,
        s: usize,
        n: usize,
    ) -> &'a [u32] {
        &chroma[t.kind(self.phase, ty).chroma_parity][s..s + n]
    }

    /// Step 1 on one line `c` (a tile row, or a tile column made
    /// contiguous) whose chroma sites `m` marks: the colour difference
    /// `G - C` into `out`, valid `R_DIF` from the line's ends.
    #[inline(always)]
    fn green_line(&self, lb: &mut Line, c: &[f32], m: &[u32], out: &mut [f32]) {
        let len = c.len();
        // The guide: the line's other class, interpolated linearly.
        let n = len - 2 * R_GUIDE;
        let (a, b) = (shifted(c, R_GUIDE, -1, n), shifted(c, R_GUIDE, 1, n));
        for ((o, a), b) in inner(&mut lb.guide, R_GUIDE, len).iter_mut().zip(a).zip(b) {
            *o = 0.5 * (a + b);
        }
        // Laplacians along the line over same-class samples (two steps).
        let (r, n) = (R_LAPLACE, len - 2 * R_LAPLACE);
        let g = |k: isize| shifted(&lb.guide, r, k, n);
        let v = |k: isize| shifted(c, r, k, n);
        let (g0, gm, gp, c0, cm, cp) = (g(0), g(-2), g(2), v(0), v(-2), v(2));
        let [ip, ii] = &mut lb.prod;
        let (ip, ii) = (inner(ip, r, len), inner(ii, r, len));
        for i in 0..n {
            let li = 2.0 * g0[i] - (gm[i] + gp[i]);
            let lp = 2.0 * c0[i] - (cm[i] + cp[i]);
            ip[i] = li * lp;
            ii[i] = li * li;
        }
        let [ip, ii] = &lb.prod;
        let sources: [&[f32]; STATS] = [&lb.guide, c, ip, ii];
        for (src, [same, other]) in sources.iter().zip(lb.sums.iter_mut()) {
            let (same, other) = (inner(same, R_COEF, len), inner(other, R_COEF, len));
            class_sums(src, R_COEF, same, other, &mut lb.pairs);
        }
        self.line_coefficients(lb, &m[R_COEF..len - R_COEF]);
        for (src, dst) in lb.coef.iter().zip(lb.mean.iter_mut()) {
            all_sums(src, R_MEAN, inner(dst, R_MEAN, len), &mut lb.pairs);
        }
        line_residuals(lb, c, m, len);
        // The missing class: its tentative value plus the mean of the two
        // neighbouring residuals.
        let (r, n) = (R_DIF, len - 2 * R_DIF);
        let (c0, part) = (shifted(c, r, 0, n), shifted(&lb.part, r, 0, n));
        let (rm, rp) = (shifted(&lb.res, r, -1, n), shifted(&lb.res, r, 1, n));
        let (m, o) = (&m[r..len - r], inner(out, r, len));
        for i in 0..n {
            let est = part[i] + 0.5 * (rm[i] + rp[i]);
            o[i] = select(m[i], est - c0[i], c0[i] - est);
        }
    }

    /// Coefficients of the chroma and the green class of a line, from its
    /// class sums, at the sites `m` covers (from `R_COEF` on).
    #[inline(always)]
    fn line_coefficients(&self, lb: &mut Line, m: &[u32]) {
        let n = m.len();
        let (n_same, n_other) = (
            window(Parity::Same.count(LINE_RADIUS), self.flat),
            window(Parity::Other.count(LINE_RADIUS), self.flat),
        );
        let same = lb.sums.each_ref().map(|q| &q[0][R_COEF..R_COEF + n]);
        let other = lb.sums.each_ref().map(|q| &q[1][R_COEF..R_COEF + n]);
        let [ac, bc, ag, bg] = &mut lb.coef;
        let (ac, bc) = (&mut ac[R_COEF..R_COEF + n], &mut bc[R_COEF..R_COEF + n]);
        let (ag, bg) = (&mut ag[R_COEF..R_COEF + n], &mut bg[R_COEF..R_COEF + n]);
        for i in 0..n {
            let (a_s, b_s) = coefficients(stats(&same, i), n_same);
            let (a_o, b_o) = coefficients(stats(&other, i), n_other);
            ac[i] = select(m[i], a_s, a_o);
            bc[i] = select(m[i], b_s, b_o);
            ag[i] = select(m[i], a_o, a_s);
            bg[i] = select(m[i], b_o, b_s);
        }
    }

    /// Step 1 along the rows: `st.dif[0]`.
    #[inline(always)]
    fn green_rows(&self, st: &mut State, t: &Tile, c: &[f32]) {
        for ty in R_DIF..t.rows - R_DIF {
            let line = ty * t.stride..(ty + 1) * t.stride;
            let m = self.mask(&st.chroma, t, ty, 0, t.stride);
            self.green_line(&mut st.line, &c[line.clone()], m, &mut st.dif[0][line]);
        }
    }

    /// Step 1 along the columns: `st.dif[1]`, through the transposed tile.
    #[inline(always)]
    fn green_columns(&self, st: &mut State, t: &Tile, c: &[f32]) {
        let len = t.stride * t.rows;
        transpose::transpose(&c[..len], &mut st.across[..len], t.stride, t.rows);
        // Column `tx` holds chroma on the rows whose chroma parity is its
        // own parity; row parities alternate from row 0's.
        let first = t.kind(self.phase, 0).chroma_parity;
        for tx in R_DIF..t.stride - R_DIF {
            let line = tx * t.rows..(tx + 1) * t.rows;
            let m = &st.chroma[usize::from(first != tx % 2)][..t.rows];
            let (c, out) = (&st.across[line.clone()], &mut st.across_dif[line]);
            self.green_line(&mut st.line, c, m, out);
        }
        transpose::transpose(
            &st.across_dif[..len],
            &mut st.dif[1][..len],
            t.rows,
            t.stride,
        );
    }
}

/// The residual of each site's own class on a line, and the tentative
/// value of the line's other class there (guided by the sample itself).
#[inline(always)]
fn line_residuals(lb: &mut Line, c: &[f32], m: &[u32], len: usize) {
    let (r, n) = (R_MEAN, len - 2 * R_MEAN);
    let scale = 1.0 / Parity::All.count(LINE_RADIUS) as f32;
    let (c0, g0) = (shifted(c, r, 0, n), shifted(&lb.guide, r, 0, n));
    let [ac, bc, ag, bg] = lb.mean.each_ref().map(|p| shifted(p, r, 0, n));
    let m = &m[r..len - r];
    let (res, part) = (inner(&mut lb.res, r, len), inner(&mut lb.part, r, len));
    for i in 0..n {
        let (ac, bc, ag, bg) = (scale * ac[i], scale * bc[i], scale * ag[i], scale * bg[i]);
        let own_a = select(m[i], ac, ag);
        let own_b = select(m[i], bc, bg);
        let far_a = select(m[i], ag, ac);
        let far_b = select(m[i], bg, bc);
        res[i] = c0[i] - (own_a * g0[i] + own_b);
        part[i] = far_a * c0[i] + far_b;
    }
}

impl Mlri {
    /// Step 2: green from the two directional colour differences.
    #[inline(always)]
    fn combine(&self, st: &mut State, t: &Tile, c: &[f32]) {
        let r = R_DIF + 1;
        for ty in r..t.rows - r {
            let sp = t.span(ty, r);
            for (k, (dy, dx)) in [(0, 1), (1, 0)].into_iter().enumerate() {
                let (a, b) = (sp.at(&st.dif[k], -dy, -dx), sp.at(&st.dif[k], dy, dx));
                for ((o, a), b) in sp.out(&mut st.grad[k]).iter_mut().zip(a).zip(b) {
                    *o = (b - a).abs();
                }
            }
        }
        for (g, w) in st.grad.iter().zip(st.weight.iter_mut()) {
            square_sum(
                t,
                g,
                &mut st.tmp,
                w,
                1,
                (Parity::All, Parity::All),
                R_DIF + 2,
            );
        }
        let gauss = half_gaussian();
        let eps = self.weight_eps;
        for ty in R_GREEN..t.rows - R_GREEN {
            let sp = t.span(ty, R_GREEN);
            let m = self.mask(&st.chroma, t, ty, R_GREEN, sp.n);
            let [dh, dv] = &st.dif;
            let [wh, wv] = &st.weight;
            let (ww, we) = (sp.at(wh, 0, -1), sp.at(wh, 0, 1));
            let (wn, ws) = (sp.at(wv, -1, 0), sp.at(wv, 1, 0));
            let (aw, ae) = (arm(sp, dh, (0, -1)), arm(sp, dh, (0, 1)));
            let (an, as_) = (arm(sp, dv, (-1, 0)), arm(sp, dv, (1, 0)));
            let c0 = sp.at(c, 0, 0);
            let o = sp.out(&mut st.green);
            for i in 0..sp.n {
                let mean = |a: &[&[f32]; 5]| {
                    let mut s = 0.0;
                    for (g, p) in gauss.iter().zip(a) {
                        s += g * p[i];
                    }
                    s
                };
                let weight = |v: f32| 1.0 / (v * v + eps);
                let (w_w, w_e, w_n, w_s) =
                    (weight(ww[i]), weight(we[i]), weight(wn[i]), weight(ws[i]));
                let num =
                    (w_n * mean(&an) + w_s * mean(&as_)) + (w_w * mean(&aw) + w_e * mean(&ae));
                let dif = num / ((w_n + w_s) + (w_w + w_e));
                o[i] = select(m[i], c0[i] + dif, c0[i]);
            }
        }
    }

    /// Step 3: red and blue guided by the full green.
    #[inline(always)]
    fn chroma(&self, st: &mut State, t: &Tile, c: &[f32]) {
        let r = R_RB_LAPLACE;
        for ty in r..t.rows - r {
            let sp = t.span(ty, r);
            // Laplacians over same-class samples: two steps each way.
            let (g, v) = (cross(sp, &st.green, 2), cross(sp, c, 2));
            let [ip, ii] = &mut st.prod;
            let (ip, ii) = (sp.out(ip), sp.out(ii));
            for i in 0..sp.n {
                let lg = 4.0 * g[0][i] - ((g[1][i] + g[2][i]) + (g[3][i] + g[4][i]));
                let lc = 4.0 * v[0][i] - ((v[1][i] + v[2][i]) + (v[3][i] + v[4][i]));
                ip[i] = lg * lc;
                ii[i] = lg * lg;
            }
        }
        for ty in R_RB_COEF..t.rows - R_RB_COEF {
            self.row_class_sums(st, t, c, ty);
            self.chroma_coefficients(st, t, ty);
        }
        for ty in R_RB_MEAN..t.rows - R_RB_MEAN {
            self.chroma_residuals(st, t, c, ty);
        }
        for ty in R_OUT..t.rows - R_OUT {
            let sp = t.span(ty, R_OUT);
            let m = self.mask(&st.chroma, t, ty, R_OUT, sp.n);
            let (own_k, other_k) = if t.kind(self.phase, ty).blue {
                (1, 0)
            } else {
                (0, 1)
            };
            // Each class's tentative value plus its residuals interpolated
            // bilinearly (they are zero away from the class's samples).
            let own = sp.out(&mut st.own);
            interpolate_residual(sp, &st.part[own_k], &st.res[own_k], own);
            interpolate_residual(
                sp,
                &st.part[other_k],
                &st.res[other_k],
                sp.out(&mut st.other),
            );
            for (o, (m, c0)) in own.iter_mut().zip(m.iter().zip(sp.at(c, 0, 0))) {
                *o = select(*m, *c0, *o);
            }
        }
    }

    /// The class sums of tile row `ty` into `st.row.sums`, from `R_RB_COEF`
    /// on: vertical parity (same, other) by horizontal parity, each
    /// vertical sum kept in one row buffer for its two horizontal ones.
    #[inline(always)]
    fn row_class_sums(&self, st: &mut State, t: &Tile, c: &[f32], ty: usize) {
        let [ip, ii] = &st.prod;
        let sources: [&[f32]; STATS] = [&st.green, c, ip, ii];
        let at = t.span(ty, R_RB_LAPLACE).range().start;
        let (wide, n) = (t.stride - 2 * R_RB_LAPLACE, t.stride - 2 * R_RB_COEF);
        let parities = [Parity::Same, Parity::Other];
        let Row {
            vsum, sums, pairs, ..
        } = &mut st.row;
        for (src, sums) in sources.iter().zip(sums.iter_mut()) {
            for (pair, vertical) in sums.chunks_exact_mut(2).zip(parities) {
                let column = &mut vsum[..wide];
                window_sum(src, at, t.stride, column, SQUARE_RADIUS, vertical);
                let (same, other) = pair.split_at_mut(1);
                let (same, other) = (&mut same[0][..n], &mut other[0][..n]);
                class_sums(vsum, SQUARE_RADIUS, same, other, pairs);
            }
        }
    }

    /// Red and blue coefficients of tile row `ty` from its class sums.
    #[inline(always)]
    fn chroma_coefficients(&self, st: &mut State, t: &Tile, ty: usize) {
        let sp = t.span(ty, R_RB_COEF);
        let m = self.mask(&st.chroma, t, ty, R_RB_COEF, sp.n);
        let count = |v: Parity, h: Parity| {
            window(v.count(SQUARE_RADIUS) * h.count(SQUARE_RADIUS), self.flat)
        };
        let (same, other) = (Parity::Same, Parity::Other);
        let (own_at_chroma, own_at_green) = (count(same, same), count(same, other));
        let (far_at_chroma, far_at_green) = (count(other, other), count(other, same));
        // The row's own chroma class (vertical parity same) and the other
        // one; each row's chroma sites share the own class's column parity.
        let pick = |k: usize| st.row.sums.each_ref().map(|q| &q[k][..sp.n]);
        let (ss, so, os, oo) = (pick(0), pick(1), pick(2), pick(3));
        let [ar, br, ab, bb] = &mut st.coef;
        let (ao, bo, ax, bx) = if t.kind(self.phase, ty).blue {
            (sp.out(ab), sp.out(bb), sp.out(ar), sp.out(br))
        } else {
            (sp.out(ar), sp.out(br), sp.out(ab), sp.out(bb))
        };
        for i in 0..sp.n {
            let mi = m[i];
            let (s_ss, s_so, s_os, s_oo) =
                (stats(&ss, i), stats(&so, i), stats(&os, i), stats(&oo, i));
            let own = blend(mi, s_ss, s_so);
            let far = blend(mi, s_oo, s_os);
            let own_n = select_window(mi, own_at_chroma, own_at_green);
            let far_n = select_window(mi, far_at_chroma, far_at_green);
            (ao[i], bo[i]) = coefficients(own, own_n);
            (ax[i], bx[i]) = coefficients(far, far_n);
        }
    }

    /// Tentative red and blue values of tile row `ty` from the box means of
    /// their coefficients, and their residuals at their own samples.
    #[inline(always)]
    fn chroma_residuals(&self, st: &mut State, t: &Tile, c: &[f32], ty: usize) {
        let at = t.span(ty, R_RB_COEF).range().start;
        let sp = t.span(ty, R_RB_MEAN);
        let wide = t.stride - 2 * R_RB_COEF;
        let Row {
            vsum, mean, pairs, ..
        } = &mut st.row;
        for (src, dst) in st.coef.iter().zip(mean.iter_mut()) {
            let column = &mut vsum[..wide];
            window_sum(src, at, t.stride, column, SQUARE_RADIUS, Parity::All);
            all_sums(vsum, SQUARE_RADIUS, &mut dst[..sp.n], pairs);
        }
        let scale = 1.0 / (Parity::All.count(SQUARE_RADIUS).pow(2)) as f32;
        let m = self.mask(&st.chroma, t, ty, R_RB_MEAN, sp.n);
        let blue_row = t.kind(self.phase, ty).blue;
        let (c0, g0) = (sp.at(c, 0, 0), sp.at(&st.green, 0, 0));
        for (k, (res, part)) in st.res.iter_mut().zip(st.part.iter_mut()).enumerate() {
            // Class k (0 red, 1 blue) is sampled at this row's chroma
            // sites when the row is of its kind.
            let sampled = if (k == 1) == blue_row { u32::MAX } else { 0 };
            let (a, b) = (&mean[2 * k][..sp.n], &mean[2 * k + 1][..sp.n]);
            let (res, part) = (sp.out(res), sp.out(part));
            let inputs = a.iter().zip(b).zip(g0.iter().zip(c0)).zip(m);
            for ((res, part), (((a, b), (g, c)), m)) in res.iter_mut().zip(part).zip(inputs) {
                let tent = scale * a * g + scale * b;
                *part = tent;
                *res = select(m & sampled, c - tent, 0.0);
            }
        }
    }
}

/// `part` plus the bilinear interpolation of the sparse residual `res`,
/// over the span, into `out`.
#[inline(always)]
fn interpolate_residual(sp: Span, part: &[f32], res: &[f32], out: &mut [f32]) {
    let (part, e) = (sp.at(part, 0, 0), cross(sp, res, 1));
    let d = [(-1, -1), (-1, 1), (1, -1), (1, 1)].map(|(dy, dx)| sp.at(res, dy, dx));
    for i in 0..sp.n {
        let edge = (e[1][i] + e[2][i]) + (e[3][i] + e[4][i]);
        let corner = (d[0][i] + d[1][i]) + (d[2][i] + d[3][i]);
        out[i] = part[i] + ((e[0][i] + 0.5 * edge) + 0.25 * corner);
    }
}

/// Plane `p` at the span and at its four neighbours `step` away: centre,
/// north, south, west, east.
#[inline(always)]
fn cross(sp: Span, p: &[f32], step: isize) -> [&[f32]; 5] {
    [
        sp.at(p, 0, 0),
        sp.at(p, -step, 0),
        sp.at(p, step, 0),
        sp.at(p, 0, -step),
        sp.at(p, 0, step),
    ]
}

impl TileKernel for Mlri {
    type State = State;
    const HALO: usize = R_OUT + R_OUT % 2;

    fn state(&self, stride: usize, len: usize) -> State {
        let plane = || vec![0.0f32; len];
        // Lines run along rows (`stride` long) and columns (`len / stride`).
        let longest = stride.max(len / stride);
        let line = || vec![0.0f32; longest];
        State {
            line: Line {
                guide: line(),
                prod: [line(), line()],
                sums: [0; STATS].map(|_| [line(), line()]),
                coef: [0; 4].map(|_| line()),
                mean: [0; 4].map(|_| line()),
                res: line(),
                part: line(),
                pairs: line(),
            },
            row: Row {
                vsum: line(),
                sums: [0; STATS].map(|_| [0; 4].map(|_| line())),
                mean: [0; 4].map(|_| line()),
                pairs: line(),
            },
            across: plane(),
            across_dif: plane(),
            prod: [plane(), plane()],
            coef: [0; 4].map(|_| plane()),
            tmp: plane(),
            res: [plane(), plane()],
            part: [plane(), plane()],
            dif: [plane(), plane()],
            grad: [plane(), plane()],
            weight: [plane(), plane()],
            green: plane(),
            own: plane(),
            other: plane(),
            chroma: chroma_masks(longest),
        }
    }

    #[inline(always)]
    fn run<'s>(&self, st: &'s mut State, t: &Tile, c: &[f32]) -> [&'s [f32]; 3] {
        self.green_rows(st, t, c);
        self.green_columns(st, t, c);
        self.combine(st, t, c);
        self.chroma(st, t, c);
        [&st.own, &st.green, &st.other]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cfa::CfaPattern;
    use crate::demosaic::{demosaic, Method};
    use crate::image::ImageView;

    #[test]
    fn coefficients_recover_a_linear_relation() {
        // p = 2 I + 3 on four samples: the Laplacian sums keep the slope,
        // the sample sums the offset.
        let guide = [1.0f32, 4.0, 2.0, 7.0];
        let lap = [0.5f32, -1.0, 2.0, 0.25];
        let si: f32 = guide.iter().sum();
        let sp: f32 = guide.iter().map(|g| 2.0 * g + 3.0).sum();
        let sii: f32 = lap.iter().map(|l| l * l).sum();
        let (a, b) = coefficients([si, sp, 2.0 * sii, sii], window(4, 1e-5));
        assert_eq!((a, b), (2.0, 3.0));
        // A flat guide: the floor keeps the slope finite and small.
        let (a, b) = coefficients([4.0, 8.0, 0.0, 0.0], window(4, 1e-5));
        assert_eq!((a, b), (0.0, 2.0));
    }

    /// The RMS error of `method` over the interior of a textured image
    /// whose red and blue are affine functions of green.
    fn affine_colour_error(method: Method) -> f32 {
        let (w, h) = (64, 48);
        let rgb: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let g = 100.0 + 40.0 * (0.7 * x).sin() * (0.5 * y).cos() + 0.5 * x;
                [0.5 * g + 30.0, g, 0.8 * g - 20.0]
            })
            .collect();
        let pattern = CfaPattern::from_name("GRBG").unwrap();
        let raw: Vec<f32> = (0..w * h)
            .map(|i| rgb[i][usize::from(pattern.color_at(i / w, i % w))])
            .collect();
        let mut out = vec![0.0f32; 3 * w * h];
        let view = ImageView::contiguous(&raw, w, h, 1).unwrap();
        demosaic(view, &pattern, method, &mut out).unwrap();
        let (mut sum, mut n) = (0.0, 0.0);
        for y in 12..h - 12 {
            for x in 12..w - 12 {
                for c in 0..3 {
                    sum += (out[3 * (y * w + x) + c] - rgb[y * w + x][c]).powi(2);
                    n += 1.0;
                }
            }
        }
        (sum / n).sqrt()
    }

    #[test]
    fn colours_affine_in_green_follow_the_guide() {
        // Where red and blue are affine in green, the guided filters fit
        // them; colour-difference methods assume a unit slope and a smooth
        // difference, which fine texture breaks.
        let mlri = affine_colour_error(Method::Mlri);
        for other in [Method::Bilinear, Method::Menon2007, Method::Rcd] {
            let e = affine_colour_error(other);
            assert!(mlri < 0.5 * e, "MLRI {mlri} vs {other:?} {e}");
        }
    }
}

//! Residual interpolation with a minimized-Laplacian red / blue stage:
//! green as in Kiku, Monno, Tanaka and Okutomi, "Residual interpolation for
//! color image demosaicking", ICIP 2013 (RI), red and blue as in their
//! "Minimized-Laplacian residual interpolation for color image
//! demosaicking", Proc. SPIE 9023, Digital Photography X, 2014 (MLRI).
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
//!    the line (samples of the class, guide at those samples; RI's
//!    least-squares line) gives tentative values of that class everywhere
//!    on the line; the missing class at each site is its tentative value
//!    plus the mean of the two neighbouring residuals. The difference
//!    `G - C` follows per direction.
//! 2. The two directional colour differences are combined as in the
//!    residual-interpolation papers (after Pekkucuksen and Altunbasak's
//!    GBTF): one-sided Gaussian means towards north, south, west and east,
//!    weighted by the inverse square of the colour-difference gradients
//!    summed over a 5x5 window on that side. Green is the sample plus that
//!    difference.
//! 3. Red and blue are guided-filtered from the full green over a 11x11
//!    window of their own samples (MLRI's Laplacian slope), and their
//!    residuals interpolated bilinearly.
//!
//! The guided filters' windows are those of the residual-interpolation
//! reference implementations: an 11-sample line (radius 5) for the
//! directional green estimates, 11x11 for red and blue. The choices
//! between the two papers were made on the training photographs of
//! [`super::raisr`] (mean CPSNR in a NumPy model of this file), never on
//! the validation sets:
//! - the combination takes RI's 5x5 gradient windows ending at the site
//!   rather than the MLRI code's 3x3 ones a step out, and a Gaussian of
//!   sigma 2 over 5 samples (41.58 dB; sigma 1 41.56, sigma 3 41.29, a
//!   flat mean 40.84; the MLRI code's 3x3 windows with sigma 1 41.59, but
//!   2.0 dB less on CBSD68, 1.5 on Urban100, 0.4 on the scikit-image seven:
//!   see [`WEIGHT_RADIUS`]);
//! - the green stage fits RI's line on the samples rather than MLRI's
//!   slope on Laplacians (41.72 dB against 41.58; on the validation
//!   subsets +0.04 / +0.39 / +0.45 dB), while red and blue keep MLRI's
//!   (RI's there did worse in the model).
//!
//! Boxes are sums of mirrored pairs ([`super::boxsum`]), so the four Bayer phases
//! are exact flips of each other; every sampled value is returned
//! unchanged.
//!
//! Speed comes from keeping the many intermediate planes of a guided filter
//! out of memory. A tile streams down its rows: each stage computes one row
//! per step, as many rows behind the raw data as its reach, and keeps its
//! output in a [`Ring`] just deep enough for the stages that read it, so
//! the rings stay small (~1.2 MB a thread) whatever the tile's height, and
//! tiles can be tall (a haloed tile recomputes its 64 halo rows). The
//! green stage's vertical pass runs ahead in blocks of steps of its own
//! ([`Mlri::columns_pass`]): that was faster than running its stages in
//! the same steps as the rest. Columns
//! need no transposes: across rows, a vertical filter is the same
//! arithmetic, sample by sample, as a horizontal one along a row, and sums
//! keep the groups of their line versions ([`class_sums_across_at`]), so
//! the green stage's columns give the bits of a line-by-line run (running
//! the row code on transposed 8-column strips gave those bits 25-40 %
//! slower). Those groups, pair and quadruple sums of rows, are rings of
//! their own, each row summed once for all the windows that hold it (7 %
//! fewer instructions than summing 11 rows per window); the green stage's
//! loops that need the window sums add the groups themselves
//! ([`ClassTaps`], [`BoxTaps`]). Along a row there are no groups: the row
//! is in the first-level cache, so the loop that needs a window's sums
//! reads its 11 samples ([`class_sums_at`], [`all_sums_at`]) rather than a
//! pass storing partial sums first; what the compiler must see for such
//! loops to vectorise is said where they are built ([`ClassTaps`]).

use std::ops::Range;

use super::boxsum::{
    all_sums_across, all_sums_across_at, all_sums_at, class_sum_across_by_column,
    class_sums_across_at, class_sums_at, line_taps, pair_row, pair_taps, quad_row, quad_taps,
    window_sum, window_sum_by, Parity,
};
use super::ring::{depth, Ring, Step};
use super::tiled::{Emit, Load, StreamKernel, Tile};
use super::{chroma_masks, select, shifted, Phase};

/// Radius of the directional guided filters of the green stage.
const LINE_RADIUS: usize = 5;
/// Radius of the square guided filters of the red / blue stage.
const SQUARE_RADIUS: usize = 5;
/// The guided filters' floor on the mean squared Laplacian (red / blue)
/// or the guide's variance (green), relative to the squared full scale:
/// the references use `1e-5 * 255^2` on 8-bit data. Without it a flat
/// guide would divide noise by zero.
const FLAT: f32 = 1e-5;
/// Floor on the squared gradient sums of the direction weights, relative
/// to the squared full scale: equal weights on flat data and no overflow.
const WEIGHT_EPS: f32 = 1e-10;
/// Radius of the square sums of colour-difference gradients that weigh
/// each direction, and how far towards its side each direction's window
/// is centred: 5x5 windows ending at the site, as in residual
/// interpolation (Kiku et al. 2013). The MLRI reference code's 3x3
/// windows one step out judge the direction on too few gradients: on
/// textured photographs (the validation sets) that cost 1.5-2 dB, while on
/// the smooth training photographs both scored alike.
const WEIGHT_RADIUS: usize = 2;
const WEIGHT_SHIFT: usize = 2;
/// Samples of the one-sided means of the colour differences towards each
/// side, the site's own included.
const ONE_SIDED: usize = 5;
const ONE_SIDED_SIGMA: f32 = 2.0;

/// Reach (pixels from the ends of a line, or from the tile's sides) at
/// which each stage is valid. A stage of reach `r` computes tile row
/// `j - r` at step `j`, so what it reads `r - r'` rows further down of a
/// stage of reach `r'` was computed earlier in the same step.
const R_GUIDE: usize = 1;
const R_PRODUCT: usize = R_GUIDE;
const R_COEF: usize = R_PRODUCT + LINE_RADIUS;
const R_MEAN: usize = R_COEF + LINE_RADIUS;
const R_DIF: usize = R_MEAN + 1;
const R_GRAD: usize = R_DIF + 1;
const R_WEIGHT: usize = R_GRAD + WEIGHT_RADIUS;
const R_GREEN: usize = max(R_DIF + ONE_SIDED - 1, R_WEIGHT + WEIGHT_SHIFT);
const R_RB_LAPLACE: usize = R_GREEN + 2;
const R_RB_COEF: usize = R_RB_LAPLACE + SQUARE_RADIUS;
const R_RB_MEAN: usize = R_RB_COEF + SQUARE_RADIUS;
const R_OUT: usize = R_RB_MEAN + 1;
/// First column of the vertical pass of step 1. Its filters are
/// column-local, so it may start anywhere left of the columns later stages
/// read of it (`R_GRAD` on). Column 0 puts its vector loads on the
/// 64-byte boundaries its rows start on ([`Ring`]); a load that straddles
/// two cache lines costs two. Against column 8 (32-byte boundaries) that
/// made the AVX-512 copy 5-8 % faster on two Intel cores and the AVX2 one
/// no slower (interleaved runs, 24 MP).
const V_COLS: usize = 0;
/// Lags of the pair and quadruple sums across rows: they need rows 2 and 3
/// further down than the row they are for.
const PAIRS: usize = R_PRODUCT + 2;
const QUADS: usize = R_COEF + 3;
const RB_PAIRS: usize = R_RB_LAPLACE + 2;
const RB_QUADS: usize = R_RB_COEF + 3;

/// `max` for the reaches, which `Ord::max` cannot compute in a constant.
const fn max(a: usize, b: usize) -> usize {
    if a > b {
        a
    } else {
        b
    }
}

/// Output rows per tile, at least (see [`StreamKernel::rows`]): the recomputed halo
/// rows cost ~12 % where the 128-row tiles of the plane version cost ~50 %.
/// Output columns per tile: wide tiles recompute fewer halo columns. When
/// all stages ran in one stream, 2048 columns beat 768 by 5-15 % at 24 MP
/// on two Zen 2 cores (512 KB of L2 each), though their rings (281 rows of
/// 2112 values, ~2.4 MB) no longer fit in L2. Since the vertical pass runs
/// apart ([`Mlri::columns_pass`]), 1024 and 1536 columns beat 2048
/// by about 6 % on two Intel cores (2 MB of L2 each; three interleaved
/// rounds of 7 runs), 512 and 768 lost to 1024 by 2-5 %, and 3072 by 15 %.
/// Since tiles run the full height ([`StreamKernel::rows`]), four tiles
/// across 24 MP (1536 columns at most) beat six (1024) by ~2 % on two
/// threads and tie on one; five (1280) fall between, and 2048 lost 3 %.
const ROWS_PER_TILE: usize = 512;
const COLS_PER_TILE: usize = 1536;
/// Steps the vertical green pass runs ahead of the other stages
/// ([`Mlri::columns_pass`]); 16, 64 and 256 ran equally fast on two Intel
/// cores, 16, 32 and 64 on two Zen 4 cores, and two of its rings hold as
/// many rows more: 16 rather than 64 keeps 1.1 MiB less at 24 MP.
const BLOCK: usize = 16;

/// The kernel, whole (`CHROMA`), or its green stage alone, which hands on
/// each row of the full green with the raw row in place of red and blue
/// (for [`super::differences`], which fills them in by colour
/// differences: the red / blue stage is ~40 % of MLRI's time).
pub(super) struct Mlri<const CHROMA: bool = true> {
    pub(super) phase: Phase,
    /// [`FLAT`] in the data's squared units.
    flat: f32,
    /// [`WEIGHT_EPS`] in the data's squared units.
    weight_eps: f32,
}

impl<const CHROMA: bool> Mlri<CHROMA> {
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
/// input, guide times input and guide squared (of Laplacians in the red /
/// blue stage).
const STATS: usize = 4;
/// The statistics the green stage sums itself: all but the guide's, which
/// [`guide_sums`] derives from the input's.
const SUMMED: usize = STATS - 1;

/// Buffers of one row of the green stage's horizontal pass.
struct Line {
    /// The guide, and the products of guide and samples (`I p`, `I^2`).
    guide: Vec<f32>,
    prod: [Vec<f32>; 2],
    /// Coefficients (a, b) of the chroma and the green class. Their window
    /// sums, like those of the statistics, are taken in the loops that use
    /// them ([`ClassTaps`], [`BoxTaps`]): a row is in the first-level
    /// cache, so reading 11 samples costs less than storing and reloading
    /// partial sums.
    coef: [Vec<f32>; 4],
    /// Residuals of each site's own class, tentative values of the other.
    res: Vec<f32>,
    part: Vec<f32>,
}

/// The green stage's vertical pass: the rows of [`Line`] as rings where
/// later steps read them across rows, single rows where they do not.
/// Its window sums go through rings of pair and quadruple sums
/// ([`pair_row`], [`quad_row`]), each computed once per row and shared by
/// the windows of several rows.
struct Columns {
    guide: Ring,
    prod: [Ring; 2],
    pairs: [Ring; SUMMED],
    coef: [Ring; 4],
    quads: [Ring; 4],
    res: Ring,
    part: Ring,
}

/// The combination of the two directions.
struct Combine {
    /// Directional colour differences `G - C` (rows, columns), their
    /// gradients and the gradients' 3x3 sums.
    dif: [Ring; 2],
    grad: [Ring; 2],
    weight: [Ring; 2],
    /// The vertical pass of a 3x3 sum.
    tmp: Vec<f32>,
}

/// The red / blue stage.
struct Chroma {
    /// Products of Laplacians.
    prod: [Ring; 2],
    /// Pair sums of the statistics across rows, as in [`Columns`].
    pairs: [Ring; STATS],
    /// Vertical window sums of each statistic over each column's class:
    /// the row's own chroma in its columns, the other chroma in the others.
    /// The coefficients' loop sums them along the row ([`ClassTaps`]),
    /// and the residuals' loop the vertical box sums of the coefficients
    /// that later take their place.
    vsum: [Vec<f32>; STATS],
    /// Guided-filter coefficients (a, b) of red, then blue, and their
    /// quadruple sums across rows.
    coef: [Ring; 4],
    quads: [Ring; 4],
    /// Residuals and tentative values of red and blue.
    res: [Ring; 2],
    part: [Ring; 2],
    /// The output row's own and other chroma.
    own: Vec<f32>,
    other: Vec<f32>,
}

/// What a thread keeps from tile to tile: the raw rows, loaded a block
/// of steps ahead into a ring that the last stage reads `R_OUT` rows
/// behind, and the stages' buffers. A ring rather than a plane of the
/// whole tile keeps the raw rows in cache (a plane of a full-height tile
/// of 24 MP is 1568 x 4064 values, 25 MB) and lets tiles be as tall as
/// the image.
pub(super) struct Buffers {
    raw: Ring,
    stages: State,
}

pub(super) struct State {
    line: Line,
    columns: Columns,
    combine: Combine,
    green: Ring,
    chroma: Chroma,
    masks: [Vec<u32>; 2],
}

impl State {
    /// Makes every row `stride` long: the last tile of a row of tiles is
    /// narrower than the others, and stages size their loops by their rows.
    fn fit(&mut self, stride: usize) {
        let State {
            line: l,
            columns: v,
            combine: cb,
            green,
            chroma: x,
            ..
        } = self;
        let rows = [&mut l.guide, &mut l.res, &mut l.part]
            .into_iter()
            .chain(l.prod.iter_mut().chain(l.coef.iter_mut()))
            .chain([&mut cb.tmp, &mut x.own, &mut x.other])
            .chain(x.vsum.iter_mut());
        for row in rows {
            row.resize(stride, 0.0);
        }
        let rings = [&mut v.guide, &mut v.res, &mut v.part, green]
            .into_iter()
            .chain(v.prod.iter_mut().chain(&mut v.coef))
            .chain(v.pairs.iter_mut().chain(&mut v.quads))
            .chain(cb.dif.iter_mut().chain(&mut cb.grad).chain(&mut cb.weight))
            .chain(x.prod.iter_mut().chain(&mut x.coef))
            .chain(x.pairs.iter_mut().chain(&mut x.quads))
            .chain(x.res.iter_mut().chain(&mut x.part));
        for ring in rings {
            ring.fit(stride);
        }
    }
}

/// The guided filter's coefficients from window sums over `n` samples,
/// given as `window(n, flat)`: the slope fitted on Laplacians (MLRI), the
/// offset on the samples.
#[inline(always)]
fn coefficients(s: [f32; STATS], (floor, inv_n): (f32, f32)) -> (f32, f32) {
    let [si, sp, sip, sii] = s;
    let a = sip / sii.max(floor);
    (a, (sp - a * si) * inv_n)
}

/// The guided filter's coefficients from window sums of the guide, the
/// samples, their products and the guide's squares over `n` samples, given
/// as `window(n, flat)`: He et al.'s least-squares line (RI), its variance
/// floored as the Laplacians' sum is in [`coefficients`].
#[inline(always)]
fn regression(s: [f32; STATS], (floor, inv_n): (f32, f32)) -> (f32, f32) {
    let [si, sp, sip, sii] = s.map(|v| v * inv_n);
    let a = (sip - si * sp) / (sii - si * si).max(floor * inv_n);
    (a, sp - a * si)
}

/// What [`coefficients`] and [`regression`] need of a window of `n`
/// samples: the floor on its sum of squared Laplacians (or of squared
/// deviations), and `1 / n` (a product per pixel where a quotient cost as
/// much as the rest of the formula).
fn window(n: usize, flat: f32) -> (f32, f32) {
    (n as f32 * flat, 1.0 / n as f32)
}

/// [`select`] between two [`window`]s.
#[inline(always)]
fn select_window(m: u32, a: (f32, f32), b: (f32, f32)) -> (f32, f32) {
    (select(m, a.0, b.0), select(m, a.1, b.1))
}

/// The guide's sums over the same and the other class of a line from the
/// input's, `outer5` and `outer6` being the sums of the input's two samples
/// 5 and 6 steps away. The guide is the midpoint of each site's two
/// neighbours, so its same-class sites average the other class (the
/// outermost samples count half) and its other-class sites the same class
/// (with half of the two beyond the window). Exact on integer data, and a
/// quarter of the green stage's sums saved.
#[inline(always)]
fn guide_sums(same: f32, other: f32, outer5: f32, outer6: f32) -> (f32, f32) {
    (other - 0.5 * outer5, same + 0.5 * outer6)
}

/// `(select(m, a, b), select(m, b, a))`: a pair whose roles swap at the
/// sites `m` marks, in four bit operations where two selects take six.
#[inline(always)]
fn swap(m: u32, a: f32, b: f32) -> (f32, f32) {
    let t = (a.to_bits() ^ b.to_bits()) & m;
    (
        f32::from_bits(b.to_bits() ^ t),
        f32::from_bits(a.to_bits() ^ t),
    )
}

/// The weights of the one-sided means: a Gaussian of sigma
/// [`ONE_SIDED_SIGMA`] over distances `0..ONE_SIDED`, normalised to sum to
/// one.
fn one_sided_kernel() -> [f32; ONE_SIDED] {
    let s2 = ONE_SIDED_SIGMA * ONE_SIDED_SIGMA;
    let g: [f32; ONE_SIDED] = std::array::from_fn(|d| (-0.5 * (d * d) as f32 / s2).exp());
    let total: f32 = g.iter().sum();
    g.map(|v| v / total)
}

/// `&v[r .. len - r]` of a row: the columns a stage of reach `r` fills.
#[inline(always)]
fn cols(v: &[f32], r: usize) -> &[f32] {
    &v[r..v.len() - r]
}

/// [`cols`], writable.
#[inline(always)]
fn cols_mut(v: &mut [f32], r: usize) -> &mut [f32] {
    let len = v.len();
    &mut v[r..len - r]
}

/// Row `ty + d` of `p`, columns `r ..` on: what a stage of reach `r` reads
/// across rows.
#[inline(always)]
fn across<'a>(p: &'a Ring, ty: usize, r: usize) -> impl Fn(isize) -> &'a [f32] {
    move |d| &p.row((ty as isize + d) as usize)[r..]
}

/// The guide: the midpoints of the line's two neighbours `a` and `b`.
#[inline(always)]
fn midpoints(a: &[f32], b: &[f32], out: &mut [f32]) {
    for ((o, a), b) in out.iter_mut().zip(a).zip(b) {
        *o = 0.5 * (a + b);
    }
}

/// The products of the green stage's regression at each site: guide
/// times sample (`ip`) and guide squared (`ii`).
#[inline(always)]
fn products(g: &[f32], c: &[f32], ip: &mut [f32], ii: &mut [f32]) {
    for (((ip, ii), g), c) in ip.iter_mut().zip(ii.iter_mut()).zip(g).zip(c) {
        *ip = g * c;
        *ii = g * g;
    }
}

/// `|b - a|`: the gradient of a difference plane across a site.
#[inline(always)]
fn gradient(a: &[f32], b: &[f32], out: &mut [f32]) {
    for ((o, a), b) in out.iter_mut().zip(a).zip(b) {
        *o = (b - a).abs();
    }
}

/// The missing class at each site of a line: its tentative value plus the
/// mean of the two neighbouring residuals (`rm`, `rp`); then `G - C`.
#[inline(always)]
fn difference(part: &[f32], (rm, rp): (&[f32], &[f32]), c: &[f32], m: &[u32], out: &mut [f32]) {
    for i in 0..out.len() {
        let est = part[i] + 0.5 * (rm[i] + rp[i]);
        out[i] = select(m[i], est - c[i], c[i] - est);
    }
}

/// Where a statistic's window sums over the same and the other class are
/// read at the sites of a line: a line cut by [`line_taps`] (along a row),
/// or a centre row and its pair sums cut by [`pair_taps`] (across rows).
///
/// Traits with inlined methods, not closures: in a kernel this large the
/// compiler stops inlining closures (and `array::map`), and a call left in
/// a loop, or a slice whose length it no longer sees, keeps the loop
/// scalar (measured: 1.5-3x slower). For the same reason the loops that
/// take these sums cut their taps by direct calls, and get their outputs as
/// separate `&mut` arguments ([`Mlri::chroma_coefficient_row`]).
trait ClassTaps {
    fn at(&self, i: usize) -> (f32, f32);
}

/// Along a row the sums are taken in the loop that uses them: a row is in
/// the first-level cache, so reading 11 samples costs less than a pass
/// storing partial sums and reloading them.
impl ClassTaps for &[f32] {
    #[inline(always)]
    fn at(&self, i: usize) -> (f32, f32) {
        class_sums_at(self, i)
    }
}

/// Across rows the loop adds the stored pair sums itself: about 3 % less
/// time at 24 MP on two threads than passes storing the class sums first
/// (interleaved runs, same bits), and fewer buffers.
impl ClassTaps for [&[f32]; 6] {
    #[inline(always)]
    fn at(&self, i: usize) -> (f32, f32) {
        class_sums_across_at(self, i)
    }
}

/// Where a plane's whole-window sums are read: a line cut by
/// [`line_taps`], or rows and quadruple sums cut by [`quad_taps`] (see
/// [`ClassTaps`]).
trait BoxTaps {
    fn at(&self, i: usize) -> f32;
}

impl BoxTaps for &[f32] {
    #[inline(always)]
    fn at(&self, i: usize) -> f32 {
        all_sums_at(self, i)
    }
}

impl BoxTaps for [&[f32]; 5] {
    #[inline(always)]
    fn at(&self, i: usize) -> f32 {
        all_sums_across_at(self, i)
    }
}

/// Same- and other-class window sums of `K` statistics, site by site.
struct Classes<T, const K: usize>([T; K]);

impl<T: ClassTaps, const K: usize> Classes<T, K> {
    #[inline(always)]
    fn at(&self, i: usize) -> ([f32; K], [f32; K]) {
        let (mut same, mut other) = ([0.0; K], [0.0; K]);
        for k in 0..K {
            (same[k], other[k]) = self.0[k].at(i);
        }
        (same, other)
    }
}

/// Whole-window sums of `K` planes, site by site.
struct Boxes<T, const K: usize>([T; K]);

impl<T: BoxTaps, const K: usize> Boxes<T, K> {
    #[inline(always)]
    fn at(&self, i: usize) -> [f32; K] {
        let mut out = [0.0; K];
        for (o, t) in out.iter_mut().zip(&self.0) {
            *o = t.at(i);
        }
        out
    }
}

/// The residual of each site's own class on a line, and the tentative
/// value of the line's other class there (guided by the sample itself),
/// from the window sums `mean` of the coefficients.
#[inline(always)]
fn line_residuals(
    mean: Boxes<impl BoxTaps, 4>,
    (c, g): (&[f32], &[f32]),
    m: &[u32],
    res: &mut [f32],
    part: &mut [f32],
) {
    let scale = 1.0 / Parity::All.count(LINE_RADIUS) as f32;
    let n = m.len();
    let (c, g, res, part) = (&c[..n], &g[..n], &mut res[..n], &mut part[..n]);
    for i in 0..n {
        let [ac, bc, ag, bg] = mean.at(i);
        let (ac, bc, ag, bg) = (scale * ac, scale * bc, scale * ag, scale * bg);
        let (own_a, far_a) = swap(m[i], ac, ag);
        let (own_b, far_b) = swap(m[i], bc, bg);
        res[i] = c[i] - (own_a * g[i] + own_b);
        part[i] = far_a * c[i] + far_b;
    }
}

impl<const CHROMA: bool> Mlri<CHROMA> {
    /// The chroma sites of tile row `ty`, columns `r ..` on.
    #[inline(always)]
    fn mask<'a>(&self, masks: &'a [Vec<u32>; 2], t: &Tile, ty: usize, r: usize) -> &'a [u32] {
        &masks[t.kind(self.phase, ty).chroma_parity][r..t.stride - r]
    }

    /// Coefficients of the chroma and the green class of a line, from the
    /// window sums over its same and other class of the [`SUMMED`]
    /// statistics (in the order of [`STATS`], less the guide) and the input `outer`
    /// 5 and 6 steps away (before, after), at the sites `m` covers.
    #[inline(always)]
    fn line_coefficients(
        &self,
        sums: Classes<impl ClassTaps, SUMMED>,
        outer: [&[f32]; 4],
        m: &[u32],
        [ac, bc, ag, bg]: [&mut [f32]; 4],
    ) {
        let (n_same, n_other) = (
            window(Parity::Same.count(LINE_RADIUS), self.flat),
            window(Parity::Other.count(LINE_RADIUS), self.flat),
        );
        let n = m.len();
        let [before5, after5, before6, after6] = outer.map(|o| &o[..n]);
        let (ac, bc, ag, bg) = (&mut ac[..n], &mut bc[..n], &mut ag[..n], &mut bg[..n]);
        for i in 0..n {
            let ([sp, sip, sii], [op, oip, oii]) = sums.at(i);
            let outer5 = before5[i] + after5[i];
            let outer6 = before6[i] + after6[i];
            let (si, oi) = guide_sums(sp, op, outer5, outer6);
            let (a_s, b_s) = regression([si, sp, sip, sii], n_same);
            let (a_o, b_o) = regression([oi, op, oip, oii], n_other);
            (ac[i], ag[i]) = swap(m[i], a_s, a_o);
            (bc[i], bg[i]) = swap(m[i], b_s, b_o);
        }
    }

    /// Step 1 along tile row `c` whose chroma sites `m` marks: the colour
    /// difference `G - C` into `out`, valid `R_DIF` from the row's ends.
    #[inline(always)]
    fn green_row(&self, lb: &mut Line, c: &[f32], m: &[u32], out: &mut [f32]) {
        let len = c.len();
        let n = len - 2 * R_GUIDE;
        let (a, b) = (shifted(c, R_GUIDE, -1, n), shifted(c, R_GUIDE, 1, n));
        midpoints(a, b, cols_mut(&mut lb.guide, R_GUIDE));
        let r = R_PRODUCT;
        let [ip, ii] = &mut lb.prod;
        products(
            cols(&lb.guide, r),
            cols(c, r),
            cols_mut(ip, r),
            cols_mut(ii, r),
        );
        let [ip, ii] = &lb.prod;
        let n = len - 2 * R_COEF;
        let (tc, tp, ti) = (
            line_taps(c, R_COEF, n),
            line_taps(ip, R_COEF, n),
            line_taps(ii, R_COEF, n),
        );
        let sums = Classes([tc, tp, ti]);
        let outer = [-5, 5, -6, 6].map(|k| shifted(c, R_COEF, k, n));
        let coef = lb.coef.each_mut().map(|p| cols_mut(p, R_COEF));
        self.line_coefficients(sums, outer, &m[R_COEF..][..n], coef);
        let r = R_MEAN;
        let n = len - 2 * r;
        let [t0, t1, t2, t3] = &lb.coef;
        let (t0, t1) = (line_taps(t0, r, n), line_taps(t1, r, n));
        let (t2, t3) = (line_taps(t2, r, n), line_taps(t3, r, n));
        let mean = Boxes([t0, t1, t2, t3]);
        let (res, part) = (cols_mut(&mut lb.res, r), cols_mut(&mut lb.part, r));
        line_residuals(
            mean,
            (cols(c, r), cols(&lb.guide, r)),
            &m[r..][..n],
            &mut res[..n],
            part,
        );
        let (r, n) = (R_DIF, len - 2 * R_DIF);
        let near = (shifted(&lb.res, r, -1, n), shifted(&lb.res, r, 1, n));
        difference(
            cols(&lb.part, r),
            near,
            cols(c, r),
            &m[r..len - r],
            cols_mut(out, r),
        );
    }
}

/// The vertical pass of step 1, one stage per method: each computes tile
/// row `ty` over the columns `V_COLS ..` whose lines step 1 needs.
impl<const CHROMA: bool> Mlri<CHROMA> {
    #[inline(always)]
    fn columns_guide(&self, v: &mut Columns, c: &Ring, ty: usize) {
        let (a, b) = (cols(c.row(ty - 1), V_COLS), cols(c.row(ty + 1), V_COLS));
        midpoints(a, b, cols_mut(v.guide.row_mut(ty), V_COLS));
    }

    #[inline(always)]
    fn columns_products(&self, v: &mut Columns, c: &Ring, ty: usize) {
        let [ip, ii] = &mut v.prod;
        products(
            cols(v.guide.row(ty), V_COLS),
            cols(c.row(ty), V_COLS),
            cols_mut(ip.row_mut(ty), V_COLS),
            cols_mut(ii.row_mut(ty), V_COLS),
        );
    }

    #[inline(always)]
    fn columns_coefficients(&self, v: &mut Columns, c: &Ring, m: &[u32], ty: usize) {
        let n = m.len();
        let [q0, q1, q2] = &v.pairs;
        let [p0, p1] = &v.prod;
        let sums = Classes([
            pair_taps(cols(c.row(ty), V_COLS), across(q0, ty, V_COLS), n),
            pair_taps(cols(p0.row(ty), V_COLS), across(q1, ty, V_COLS), n),
            pair_taps(cols(p1.row(ty), V_COLS), across(q2, ty, V_COLS), n),
        ]);
        let outer = [-5, 5, -6, 6].map(|d| &c.row((ty as isize + d) as usize)[V_COLS..]);
        let coef = v.coef.each_mut().map(|p| cols_mut(p.row_mut(ty), V_COLS));
        self.line_coefficients(sums, outer, m, coef);
    }

    #[inline(always)]
    fn columns_residuals(&self, v: &mut Columns, c: &Ring, m: &[u32], ty: usize) {
        let n = m.len();
        let [a0, a1, a2, a3] = &v.coef;
        let [f0, f1, f2, f3] = &v.quads;
        let mean = Boxes([
            quad_taps(across(a0, ty, V_COLS), across(f0, ty, V_COLS), n),
            quad_taps(across(a1, ty, V_COLS), across(f1, ty, V_COLS), n),
            quad_taps(across(a2, ty, V_COLS), across(f2, ty, V_COLS), n),
            quad_taps(across(a3, ty, V_COLS), across(f3, ty, V_COLS), n),
        ]);
        let inputs = (cols(c.row(ty), V_COLS), cols(v.guide.row(ty), V_COLS));
        let res = cols_mut(v.res.row_mut(ty), V_COLS);
        let part = cols_mut(v.part.row_mut(ty), V_COLS);
        line_residuals(mean, inputs, m, res, part);
    }

    #[inline(always)]
    fn columns_difference(&self, v: &Columns, c: &Ring, m: &[u32], ty: usize, out: &mut [f32]) {
        let near = (
            cols(v.res.row(ty - 1), V_COLS),
            cols(v.res.row(ty + 1), V_COLS),
        );
        let part = cols(v.part.row(ty), V_COLS);
        difference(
            part,
            near,
            cols(c.row(ty), V_COLS),
            m,
            cols_mut(out, V_COLS),
        );
    }

    /// The vertical pass of step 1 over the block of `steps`, into the
    /// ring `combine.dif[1]`, which holds a block more rows than its
    /// readers need: the other stages then run the same steps. Run apart,
    /// a whole tile at a time, it took 8-15 % less time at 24 MP on two
    /// threads than the same stages inside the stream's steps (interleaved
    /// runs, Intel VM, same bits); blocks of 16 to 256 steps ran as fast
    /// with memory that does not grow with the tile. Splitting the stream
    /// further (a green plane, then red and blue) gained nothing more, and
    /// 64-column strips of this pass (rings in the first-level cache) were
    /// slower. Likely cause, not verified: a step touching fewer rings
    /// keeps more of them in cache.
    #[inline(always)]
    fn columns_pass(&self, st: &mut State, t: &Tile, c: &Ring, steps: Range<usize>) {
        let State {
            columns: v,
            combine: cb,
            masks,
            ..
        } = st;
        let mask = |ty: usize| self.mask(masks, t, ty, V_COLS);
        for j in steps.map(Step) {
            if let Some(ty) = j.due(R_GUIDE) {
                self.columns_guide(v, c, ty);
            }
            if let Some(ty) = j.due(R_PRODUCT) {
                self.columns_products(v, c, ty);
            }
            if let Some(ty) = j.due_from(PAIRS, R_PRODUCT) {
                let sources: [&Ring; SUMMED] = [c, &v.prod[0], &v.prod[1]];
                pair_rows(sources, &mut v.pairs, ty, V_COLS);
            }
            if let Some(ty) = j.due(R_COEF) {
                self.columns_coefficients(v, c, mask(ty), ty);
            }
            if let Some(ty) = j.due_from(QUADS, R_COEF) {
                quad_rows(&v.coef, &mut v.quads, ty, V_COLS);
            }
            if let Some(ty) = j.due(R_MEAN) {
                self.columns_residuals(v, c, mask(ty), ty);
            }
            if let Some(ty) = j.due(R_DIF) {
                self.columns_difference(v, c, mask(ty), ty, cb.dif[1].row_mut(ty));
            }
        }
    }
}

impl<const CHROMA: bool> Mlri<CHROMA> {
    /// The gradients of both directional differences at tile row `ty`.
    #[inline(always)]
    fn gradients(&self, cb: &mut Combine, ty: usize) {
        let (r, n) = (R_GRAD, cb.tmp.len() - 2 * R_GRAD);
        let dh = cb.dif[0].row(ty);
        let (a, b) = (shifted(dh, r, -1, n), shifted(dh, r, 1, n));
        gradient(a, b, cols_mut(cb.grad[0].row_mut(ty), r));
        let (a, b) = (
            cols(cb.dif[1].row(ty - 1), r),
            cols(cb.dif[1].row(ty + 1), r),
        );
        gradient(a, b, cols_mut(cb.grad[1].row_mut(ty), r));
    }

    /// The square sums of the gradients at tile row `ty`
    /// ([`WEIGHT_RADIUS`]): the weights.
    #[inline(always)]
    fn weights(&self, cb: &mut Combine, ty: usize) {
        let Combine {
            grad, weight, tmp, ..
        } = cb;
        for (g, w) in grad.iter().zip(weight.iter_mut()) {
            let r = WEIGHT_RADIUS;
            window_sum_by(across(g, ty, R_GRAD), cols_mut(tmp, R_GRAD), r, Parity::All);
            let out = cols_mut(w.row_mut(ty), R_WEIGHT);
            window_sum(tmp, R_WEIGHT, 1, out, r, Parity::All);
        }
    }

    /// Step 2 at tile row `ty`: green from the two directional colour
    /// differences.
    #[inline(always)]
    fn green(&self, cb: &Combine, c: &Ring, m: &[u32], ty: usize, out: &mut [f32]) {
        let (r, n) = (R_GREEN, m.len());
        let kernel = one_sided_kernel();
        let eps = self.weight_eps;
        let [dh, dv] = &cb.dif;
        let [wh, wv] = &cb.weight;
        let d = WEIGHT_SHIFT as isize;
        let (ww, we) = (shifted(wh.row(ty), r, -d, n), shifted(wh.row(ty), r, d, n));
        let (wn, ws) = (
            cols(wv.row(ty - WEIGHT_SHIFT), r),
            cols(wv.row(ty + WEIGHT_SHIFT), r),
        );
        let dh = dh.row(ty);
        let taps: [usize; ONE_SIDED] = std::array::from_fn(|k| k);
        let (aw, ae) = (
            taps.map(|k| shifted(dh, r, -(k as isize), n)),
            taps.map(|k| shifted(dh, r, k as isize, n)),
        );
        let (an, as_) = (
            taps.map(|k| cols(dv.row(ty - k), r)),
            taps.map(|k| cols(dv.row(ty + k), r)),
        );
        let c0 = cols(c.row(ty), r);
        for i in 0..n {
            let mean = |a: &[&[f32]; ONE_SIDED]| {
                let mut s = 0.0;
                for (g, p) in kernel.iter().zip(a) {
                    s += g * p[i];
                }
                s
            };
            let weight = |v: f32| 1.0 / (v * v + eps);
            let (w_w, w_e, w_n, w_s) = (weight(ww[i]), weight(we[i]), weight(wn[i]), weight(ws[i]));
            let num = (w_n * mean(&an) + w_s * mean(&as_)) + (w_w * mean(&aw) + w_e * mean(&ae));
            let dif = num / ((w_n + w_s) + (w_w + w_e));
            out[i] = select(m[i], c0[i] + dif, c0[i]);
        }
    }
}

/// Step 3: red and blue guided by the full green, one stage per method.
impl<const CHROMA: bool> Mlri<CHROMA> {
    /// Products of Laplacians over same-class samples (two steps each
    /// way) at tile row `ty`.
    #[inline(always)]
    fn chroma_products(&self, x: &mut Chroma, green: &Ring, c: &Ring, ty: usize) {
        let r = R_RB_LAPLACE;
        let [ip, ii] = &mut x.prod;
        let (ip, ii) = (cols_mut(ip.row_mut(ty), r), cols_mut(ii.row_mut(ty), r));
        let n = ip.len();
        let (g, v) = (cross(green, ty, r, n), cross(c, ty, r, n));
        for i in 0..n {
            let lg = 4.0 * g[0][i] - ((g[1][i] + g[2][i]) + (g[3][i] + g[4][i]));
            let lc = 4.0 * v[0][i] - ((v[1][i] + v[2][i]) + (v[3][i] + v[4][i]));
            ip[i] = lg * lc;
            ii[i] = lg * lg;
        }
    }

    /// The vertical class sums of tile row `ty` into `x.vsum`. The own
    /// chroma's samples lie in the row's class of rows and the chroma
    /// sites' columns (`m`), the other chroma's in the other rows and
    /// columns: a vertical sum per column over the class of rows its column
    /// calls for, then the same- and other-column sums along the row (in
    /// [`Self::chroma_coefficients`]), give both at every site, half the
    /// sums of all four parities.
    #[inline(always)]
    fn chroma_sums(&self, x: &mut Chroma, green: &Ring, c: &Ring, m: &[u32], ty: usize) {
        let Chroma {
            prod, pairs, vsum, ..
        } = x;
        let sources: [&Ring; STATS] = [green, c, &prod[0], &prod[1]];
        let r = R_RB_LAPLACE;
        for ((src, q), v) in sources.into_iter().zip(&*pairs).zip(vsum.iter_mut()) {
            class_sum_across_by_column(
                cols(src.row(ty), r),
                across(q, ty, r),
                m,
                &mut v[..m.len()],
            );
        }
    }

    /// Red and blue coefficients of tile row `ty` from its class sums.
    #[inline(always)]
    fn chroma_coefficients(&self, x: &mut Chroma, m: &[u32], blue_row: bool, ty: usize) {
        let n = m.len();
        // Taps cut here, not by a closure, so that the compiler sees their
        // lengths and drops the bounds checks that would keep the loop
        // scalar.
        let [v0, v1, v2, v3] = &x.vsum;
        let (v0, v1) = (
            line_taps(v0, SQUARE_RADIUS, n),
            line_taps(v1, SQUARE_RADIUS, n),
        );
        let (v2, v3) = (
            line_taps(v2, SQUARE_RADIUS, n),
            line_taps(v3, SQUARE_RADIUS, n),
        );
        let sums = Classes([v0, v1, v2, v3]);
        let [ar, br, ab, bb] = x
            .coef
            .each_mut()
            .map(|p| cols_mut(p.row_mut(ty), R_RB_COEF));
        let (ao, bo, ax, bx) = if blue_row {
            (ab, bb, ar, br)
        } else {
            (ar, br, ab, bb)
        };
        self.chroma_coefficient_row(&sums, m, ao, bo, ax, bx);
    }

    /// [`Self::chroma_coefficients`] of one row into the coefficients of
    /// the row's own chroma (`ao`, `bo`) and of the other one (`ax`, `bx`).
    /// Its own function so that the compiler knows its outputs apart.
    #[inline(always)]
    fn chroma_coefficient_row(
        &self,
        sums: &Classes<&[f32], STATS>,
        m: &[u32],
        ao: &mut [f32],
        bo: &mut [f32],
        ax: &mut [f32],
        bx: &mut [f32],
    ) {
        let count = |v: Parity, h: Parity| {
            window(v.count(SQUARE_RADIUS) * h.count(SQUARE_RADIUS), self.flat)
        };
        let (same, other) = (Parity::Same, Parity::Other);
        let (own_at_chroma, own_at_green) = (count(same, same), count(same, other));
        let (far_at_chroma, far_at_green) = (count(other, other), count(other, same));
        let n = m.len();
        let (ao, bo, ax, bx) = (&mut ao[..n], &mut bo[..n], &mut ax[..n], &mut bx[..n]);
        for i in 0..n {
            let mi = m[i];
            // The own chroma lies in the chroma sites' columns: the
            // same-column sums are its own at chroma sites, the other
            // chroma's at green ones.
            let same_n = select_window(mi, own_at_chroma, far_at_green);
            let other_n = select_window(mi, far_at_chroma, own_at_green);
            let (same, other) = sums.at(i);
            let (a_s, b_s) = coefficients(same, same_n);
            let (a_o, b_o) = coefficients(other, other_n);
            (ao[i], ax[i]) = swap(mi, a_s, a_o);
            (bo[i], bx[i]) = swap(mi, b_s, b_o);
        }
    }

    /// Tentative red and blue values of tile row `ty` from the box means of
    /// their coefficients, and their residuals at their own samples.
    #[inline(always)]
    fn chroma_residuals(
        &self,
        x: &mut Chroma,
        g: &Ring,
        c: &Ring,
        m: &[u32],
        blue_row: bool,
        ty: usize,
    ) {
        let Chroma {
            coef,
            quads,
            vsum,
            res,
            part,
            ..
        } = x;
        let r = R_RB_COEF;
        let n = m.len();
        for ((src, f), v) in coef.iter().zip(&*quads).zip(vsum.iter_mut()) {
            all_sums_across(
                across(src, ty, r),
                across(f, ty, r),
                &mut v[..n + 2 * SQUARE_RADIUS],
            );
        }
        let scale = 1.0 / (Parity::All.count(SQUARE_RADIUS).pow(2)) as f32;
        let (c0, g0) = (&c.row(ty)[R_RB_MEAN..][..n], &g.row(ty)[R_RB_MEAN..][..n]);
        for (k, (res, part)) in res.iter_mut().zip(part.iter_mut()).enumerate() {
            // Class k (0 red, 1 blue) is sampled at this row's chroma
            // sites when the row is of its kind.
            let sampled = if (k == 1) == blue_row { u32::MAX } else { 0 };
            let (a, b) = (&vsum[2 * k], &vsum[2 * k + 1]);
            let mean = Boxes([
                line_taps(a, SQUARE_RADIUS, n),
                line_taps(b, SQUARE_RADIUS, n),
            ]);
            let (res, part) = (
                &mut res.row_mut(ty)[R_RB_MEAN..][..n],
                &mut part.row_mut(ty)[R_RB_MEAN..][..n],
            );
            for i in 0..n {
                let [a, b] = mean.at(i);
                let tent = scale * a * g0[i] + scale * b;
                part[i] = tent;
                res[i] = select(m[i] & sampled, c0[i] - tent, 0.0);
            }
        }
    }

    /// The output chroma of tile row `ty`: each class's tentative value
    /// plus its residuals interpolated bilinearly (they are zero away from
    /// the class's samples); the row's own samples are kept.
    #[inline(always)]
    fn chroma_output(&self, x: &mut Chroma, c: &Ring, m: &[u32], blue_row: bool, ty: usize) {
        let (own_k, other_k) = if blue_row { (1, 0) } else { (0, 1) };
        let Chroma {
            res,
            part,
            own,
            other,
            ..
        } = x;
        let own = cols_mut(own, R_OUT);
        interpolate_residual(&part[own_k], &res[own_k], ty, own);
        interpolate_residual(&part[other_k], &res[other_k], ty, cols_mut(other, R_OUT));
        for (o, (m, c0)) in own.iter_mut().zip(m.iter().zip(cols(c.row(ty), R_OUT))) {
            *o = select(*m, *c0, *o);
        }
    }
}

/// Tile row `ty` of the [`pair_row`]s of the statistics `sources`, over
/// the columns `r ..`.
#[inline(always)]
fn pair_rows<const K: usize>(sources: [&Ring; K], pairs: &mut [Ring; K], ty: usize, r: usize) {
    for (src, q) in sources.into_iter().zip(pairs.iter_mut()) {
        let (a, b) = (cols(src.row(ty), r), cols(src.row(ty + 2), r));
        pair_row(a, b, cols_mut(q.row_mut(ty), r));
    }
}

/// Tile row `ty` of the [`quad_row`]s of the four coefficients `coef`,
/// over the columns `r ..`.
#[inline(always)]
fn quad_rows(coef: &[Ring; 4], quads: &mut [Ring; 4], ty: usize, r: usize) {
    for (src, f) in coef.iter().zip(quads.iter_mut()) {
        quad_row(across(src, ty, r), cols_mut(f.row_mut(ty), r));
    }
}

/// Tile row `ty` of `p` at the columns `r .. r + n` and two steps away
/// from them: centre, north, south, west, east (the nearest samples of the
/// same class).
#[inline(always)]
fn cross(p: &Ring, ty: usize, r: usize, n: usize) -> [&[f32]; 5] {
    let row = p.row(ty);
    let (north, south) = (
        shifted(p.row(ty - 2), r, 0, n),
        shifted(p.row(ty + 2), r, 0, n),
    );
    let (west, east) = (shifted(row, r, -2, n), shifted(row, r, 2, n));
    [shifted(row, r, 0, n), north, south, west, east]
}

/// Tile row `ty` of `part` plus the bilinear interpolation of the sparse
/// residual `res`, over the columns `R_OUT ..`, into `out`.
#[inline(always)]
fn interpolate_residual(part: &Ring, res: &Ring, ty: usize, out: &mut [f32]) {
    let (r, n) = (R_OUT, out.len());
    let part = &part.row(ty)[r..];
    let (up, mid, down) = (res.row(ty - 1), res.row(ty), res.row(ty + 1));
    let side = |row, dx| shifted(row, r, dx, n);
    let e = [
        side(mid, 0),
        side(up, 0),
        side(down, 0),
        side(mid, -1),
        side(mid, 1),
    ];
    let d = [side(up, -1), side(up, 1), side(down, -1), side(down, 1)];
    for i in 0..n {
        let edge = (e[1][i] + e[2][i]) + (e[3][i] + e[4][i]);
        let corner = (d[0][i] + d[1][i]) + (d[2][i] + d[3][i]);
        out[i] = part[i] + ((e[0][i] + 0.5 * edge) + 0.25 * corner);
    }
}

impl<const CHROMA: bool> StreamKernel for Mlri<CHROMA> {
    type State = Buffers;
    const HALO: usize = if CHROMA {
        R_OUT + R_OUT % 2
    } else {
        R_GREEN + R_GREEN % 2
    };
    const ROWS: usize = ROWS_PER_TILE;
    const COLS: usize = COLS_PER_TILE;
    /// Its AVX-512 copy runs 4-10 % faster than the AVX2 one at 24 MP on
    /// two Intel cores (interleaved runs), with the vertical pass in its
    /// own sweep from column 0 on 1024-column tiles. Before those changes
    /// it ran 3-4 % slower on two Zen 4 cores, where AVX-512 splits each
    /// 64-byte operation in two; not measured there since.
    const AVX512: bool = true;

    /// Its memory does not grow with the tile's height (the raw rows too
    /// are a ring, [`Buffers`]), so tiles are as tall as an equal number of
    /// tiles per thread allows: the threads share the tiles side by side,
    /// and a mosaic is cut into bands only when the tiles across are not a
    /// multiple of the threads. At 24 MP on two threads (four tiles across),
    /// full-height tiles recompute 1.6 % of their rows as halo, where four
    /// bands of 1000 rows recomputed 6 %: 2-3 % less time with the raw ring
    /// (interleaved runs, same bits), none with a whole-tile raw plane,
    /// whose page faults and memory traffic ate the gain.
    fn rows(height: usize, across: usize, threads: usize) -> usize {
        let bands = (1..threads)
            .find(|b| (across * b).is_multiple_of(threads))
            .unwrap_or(threads);
        height
            .div_ceil(bands)
            .next_multiple_of(2)
            .max(ROWS_PER_TILE)
    }

    fn state(&self, stride: usize, _rows: usize) -> Buffers {
        let row = || vec![0.0f32; stride];
        // Rings of a stage computing row `j - from`, read until row `j -
        // to` (`back` rows above), with their column `col` on cache lines:
        // the column most of their loads start from, chosen so that the
        // loads across rows of the window sums do not straddle two lines
        // (AVX-512: 4-6 % less time at 24 MP on two Intel cores, same bits).
        let ring = |from, to, back, col| Ring::new(stride, depth(from, to, back), col);
        let two = |from, to, back, col| [0; 2].map(|_| ring(from, to, back, col));
        let rings = |from, to, back, col| [0; 4].map(|_| ring(from, to, back, col));
        let stages = State {
            line: Line {
                guide: row(),
                prod: [row(), row()],
                coef: [0; 4].map(|_| row()),
                res: row(),
                part: row(),
            },
            columns: Columns {
                guide: ring(R_GUIDE, R_MEAN, 0, V_COLS),
                prod: two(R_PRODUCT, R_COEF, 0, V_COLS),
                pairs: [0; SUMMED].map(|_| ring(PAIRS, R_COEF, LINE_RADIUS, V_COLS)),
                coef: rings(R_COEF, R_MEAN, 1, V_COLS),
                quads: rings(QUADS, R_MEAN, LINE_RADIUS, V_COLS),
                res: ring(R_MEAN, R_DIF, 1, V_COLS),
                part: ring(R_MEAN, R_DIF, 0, V_COLS),
            },
            combine: Combine {
                // The vertical difference, written a block ahead.
                dif: [
                    ring(R_DIF, R_GREEN, ONE_SIDED - 1, R_GRAD),
                    ring(R_DIF, R_GREEN, ONE_SIDED - 1 + BLOCK, R_GRAD),
                ],
                grad: two(R_GRAD, R_WEIGHT, WEIGHT_RADIUS, R_GRAD),
                weight: two(R_WEIGHT, R_GREEN, WEIGHT_SHIFT, R_GREEN),
                tmp: row(),
            },
            // Read by the last stage, as the output's green.
            green: ring(R_GREEN, R_OUT, 0, R_RB_LAPLACE),
            chroma: Chroma {
                prod: two(R_RB_LAPLACE, R_RB_COEF, 0, R_RB_LAPLACE),
                pairs: rings(RB_PAIRS, R_RB_COEF, SQUARE_RADIUS, R_RB_LAPLACE),
                vsum: [0; STATS].map(|_| row()),
                coef: rings(R_RB_COEF, R_RB_MEAN, 1, R_RB_COEF),
                quads: rings(RB_QUADS, R_RB_MEAN, SQUARE_RADIUS, R_RB_COEF),
                res: two(R_RB_MEAN, R_OUT, 1, R_RB_MEAN),
                part: two(R_RB_MEAN, R_OUT, 0, R_RB_MEAN),
                own: row(),
                other: row(),
            },
            masks: chroma_masks(stride),
        };
        Buffers {
            // Read from R_OUT rows behind the step to a block ahead of it.
            raw: Ring::new(stride, depth(0, R_OUT, 0) + BLOCK, 0),
            stages,
        }
    }

    #[inline(always)]
    fn stream<E: Emit, L: Load>(&self, bufs: &mut Buffers, t: &Tile, raw: &L, out: &mut E) {
        let Buffers { raw: c, stages: st } = bufs;
        c.fit(t.stride);
        st.fit(t.stride);
        for j0 in (0..t.rows).step_by(BLOCK) {
            let steps = j0..(j0 + BLOCK).min(t.rows);
            for ty in steps.clone() {
                raw.load(ty, c.row_mut(ty));
            }
            self.columns_pass(st, t, c, steps.clone());
            for j in steps.map(Step) {
                self.stream_step(st, t, c, j, out);
            }
        }
    }
}

impl<const CHROMA: bool> Mlri<CHROMA> {
    /// Step `j` of every stage after the vertical pass: what
    /// [`StreamKernel::stream`] runs after [`Mlri::columns_pass`] has run
    /// the block of steps that holds `j`.
    #[inline(always)]
    fn stream_step<E: Emit>(&self, st: &mut State, t: &Tile, c: &Ring, j: Step, out: &mut E) {
        let State {
            line,
            combine: cb,
            green,
            chroma: x,
            masks,
            ..
        } = st;
        let mask = |ty: usize, r: usize| self.mask(masks, t, ty, r);
        let emitted = Self::HALO..t.rows - Self::HALO;
        if let Some(ty) = j.due(R_DIF) {
            self.green_row(line, c.row(ty), mask(ty, 0), cb.dif[0].row_mut(ty));
        }
        if let Some(ty) = j.due(R_GRAD) {
            self.gradients(cb, ty);
        }
        if let Some(ty) = j.due(R_WEIGHT) {
            self.weights(cb, ty);
        }
        if let Some(ty) = j.due(R_GREEN) {
            let out = cols_mut(green.row_mut(ty), R_GREEN);
            self.green(cb, c, mask(ty, R_GREEN), ty, out);
        }
        if !CHROMA {
            if let Some(ty) = j.due(R_GREEN).filter(|ty| emitted.contains(ty)) {
                out.emit(ty, [c.row(ty), green.row(ty), c.row(ty)]);
            }
            return;
        }
        if let Some(ty) = j.due(R_RB_LAPLACE) {
            self.chroma_products(x, green, c, ty);
        }
        if let Some(ty) = j.due_from(RB_PAIRS, R_RB_LAPLACE) {
            let sources: [&Ring; STATS] = [green, c, &x.prod[0], &x.prod[1]];
            pair_rows(sources, &mut x.pairs, ty, R_RB_LAPLACE);
        }
        let blue_row = |ty: usize| t.kind(self.phase, ty).blue;
        if let Some(ty) = j.due(R_RB_COEF) {
            self.chroma_sums(x, green, c, mask(ty, R_RB_LAPLACE), ty);
            self.chroma_coefficients(x, mask(ty, R_RB_COEF), blue_row(ty), ty);
        }
        if let Some(ty) = j.due_from(RB_QUADS, R_RB_COEF) {
            quad_rows(&x.coef, &mut x.quads, ty, R_RB_COEF);
        }
        if let Some(ty) = j.due(R_RB_MEAN) {
            self.chroma_residuals(x, green, c, mask(ty, R_RB_MEAN), blue_row(ty), ty);
        }
        if let Some(ty) = j.due(R_OUT).filter(|ty| emitted.contains(ty)) {
            self.chroma_output(x, c, mask(ty, R_OUT), blue_row(ty), ty);
            out.emit(ty, [&x.own, green.row(ty), &x.other]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cfa::CfaPattern;
    use crate::demosaic::{demosaic, Method};
    use crate::image::ImageView;

    #[test]
    fn tile_heights_do_not_change_the_output() {
        // 1100 rows one tile wide make one tile on one thread and two of
        // 550 rows on two: the seams move, the output must not.
        let (w, h) = (40, 1100);
        assert_ne!(Mlri::<true>::rows(h, 1, 1), Mlri::<true>::rows(h, 1, 2));
        let raw: Vec<u16> = (0..w * h).map(|i| ((i * 7919) % 4099) as u16).collect();
        let pattern = CfaPattern::from_name("GBRG").unwrap();
        let run_on = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let view = ImageView::contiguous(&raw, w, h, 1).unwrap();
            let mut out = vec![0u16; 3 * w * h];
            pool.install(|| demosaic(view, &pattern, Method::Mlri, None, &mut out))
                .unwrap();
            out
        };
        assert_eq!(run_on(1), run_on(2));
    }

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

    #[test]
    fn regression_recovers_a_linear_relation() {
        // p = 2 I + 3 on four samples: the least-squares line.
        let guide = [1.0f32, 4.0, 2.0, 7.0];
        let si: f32 = guide.iter().sum();
        let sp: f32 = guide.iter().map(|g| 2.0 * g + 3.0).sum();
        let sip: f32 = guide.iter().map(|g| g * (2.0 * g + 3.0)).sum();
        let sii: f32 = guide.iter().map(|g| g * g).sum();
        let (a, b) = regression([si, sp, sip, sii], window(4, 1e-5));
        assert!((a - 2.0).abs() < 1e-5 && (b - 3.0).abs() < 1e-4, "{a} {b}");
        // A flat guide: the floor on the variance keeps the slope at zero
        // and the offset at the samples' mean.
        let (a, b) = regression([4.0, 8.0, 4.0 * 2.0, 4.0], window(4, 1e-5));
        assert_eq!((a, b), (0.0, 2.0));
    }

    #[test]
    fn guide_sums_are_the_sums_of_the_midpoints() {
        // Integer samples, as from u8 / u16 mosaics: the derived sums must be
        // the direct ones to the bit; float samples to rounding.
        let len = 40;
        let lines = [
            (0..len)
                .map(|i| ((i * 7919) % 4099) as f32)
                .collect::<Vec<_>>(),
            (0..len)
                .map(|i| (0.37 * i as f32).sin() * 0.8 + 1.0)
                .collect(),
        ];
        for (k, c) in lines.iter().enumerate() {
            let mut guide = vec![0.0; len];
            midpoints(&c[..len - 2], &c[2..], &mut guide[1..len - 1]);
            let (at, n) = (7, len - 14);
            let (tg, tc) = (line_taps(&guide, at, n), line_taps(c, at, n));
            for i in 0..n {
                let x = at + i;
                let ((gs, go), (cs, co)) = (class_sums_at(tg, i), class_sums_at(tc, i));
                let (outer5, outer6) = (c[x - 5] + c[x + 5], c[x - 6] + c[x + 6]);
                let (s, o) = guide_sums(cs, co, outer5, outer6);
                if k == 0 {
                    assert_eq!((s, o), (gs, go), "at {x}");
                } else {
                    assert!((s - gs).abs() < 1e-5 && (o - go).abs() < 1e-5, "at {x}");
                }
            }
        }
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
        demosaic(view, &pattern, method, None, &mut out).unwrap();
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
            assert!(mlri < 0.7 * e, "MLRI {mlri} vs {other:?} {e}");
        }
    }
}

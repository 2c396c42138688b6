//! Sub-pixel refinement of a warp by maximising the enhanced correlation
//! coefficient (ECC, Evangelidis & Psarakis 2008; OpenCV's
//! `findTransformECC`), coarse to fine.
//!
//! ECC is the NCC of the reference with the warped moving channel, so like
//! the translation search it ignores gain and offset between the channels.
//! The steps are the paper's inverse-compositional ones: a Gauss-Newton step
//! linearises the *reference* in the parameters of a small warp applied to
//! it (about the identity), solves a small normal system for the warp that
//! best matches it to the moving channel read through the current warp, and
//! composes the current warp with that small warp's inverse. The Jacobian
//! rows (the reference's gradient times the warp's derivatives) and their
//! normal matrix therefore do not change from step to step: they are summed
//! once per pyramid level, and once for all the channels aligned onto one
//! reference. A step only reads one bilinear sample of the moving channel
//! per pixel and adds seven products (the forward-additive form samples the
//! moving channel's gradient too and re-sums the normal matrix every step).
//!
//! The correlation is computed on the intensities or, with
//! [`Features::Gradient`], on the Sobel gradient magnitudes. The exposures of
//! a plate record different content (a red face is bright in R, dark in G),
//! and the intensity correlation's maximum then sits where a small rotation,
//! scale or shift trades some of that difference away, not at the true warp:
//! on the benchmark's plate built from a photograph's R and G the intensity
//! ECC of R peaks 0.03 % off the true scale (0.77 px at the window's
//! corners). Edges sit at the same place in every channel whatever their brightness
//! and sign, which also lets gradient features follow channels that are
//! anti-correlated, where the intensity ECC has no step that raises the
//! correlation. The gradient fit of that R still lands 0.014 % (0.27 px)
//! off the synthetic scale, but that is the photograph's own geometry, not
//! a bias: its R and B are 1.56 and 1.10 parts in 10 000 smaller than its G
//! (measured on the plate built without motion; the fits compose and
//! invert consistently), most likely the camera's lateral chromatic
//! aberration; with it taken out the fit is within 0.024-0.032 px.
//!
//! Full resolution is read straight from the caller's samples (the moving
//! channel bilinearly, the reference's gradient by central differences as
//! the rows are read): no full-resolution copy of a plate is made. The
//! coarser levels are `f32` box averages.
//!
//! Every sum is kept in the basis of the affine warp's six derivatives,
//! `(gx u, gx v, gx, gy u, gy v, gy)` with `(u, v)` the pixel's position
//! about the centre: `v` is constant along a row, so a pixel adds only
//! powers of `u` and each row's total is combined with its `v` once; every
//! motion's Jacobian is a fixed combination of the six
//! ([`Motion::affine_basis`]). Sums are in `f64`, over bands of rows fixed by
//! the image and added in order: the result is bit-identical for any thread
//! count.

use std::ops::Range;

use rayon::prelude::*;

use super::motion::{from_level, to_level, Centred, Matrix, Motion, AFFINE, MAX_PARAMS};
use super::pyramid::{Converted, Plane};
use super::search::Window;
use super::Features;
use crate::error::Result;
use crate::image::{ImageView, Sample};
use crate::invalid;

/// Reference rows per task: a band of a 3000-pixel plate is ~100 k pixels,
/// ~1 ms of work, far above rayon's per-task cost.
const BAND_ROWS: usize = 32;

/// Powers `(a, b)` of `u^a v^b` of the basis functions `u`, `v`, 1 that
/// multiply each gradient component: affine derivative `k` is
/// `g[k / 3] * u^a v^b` with `(a, b) = POWERS[k % 3]`.
const POWERS: [(usize, usize); 3] = [(1, 0), (0, 1), (0, 0)];

/// The coarsest level ECC starts at keeps at least this many pixels on its
/// shorter side: enough structure for a rotation to show, while 1/8 of a
/// full plate makes its iterations ~64 times cheaper than full resolution.
pub const MIN_LEVEL_SIDE: usize = 160;

/// The fewest window pixels per parameter a level must compare: fewer make
/// the normal equations an interpolation, not an estimate.
pub const MIN_PIXELS_PER_PARAM: usize = 64;

/// Options of [`refine`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EccOptions {
    /// Fraction of each border of the reference left out, in `[0, 0.5)`.
    pub crop: f64,
    /// Halvings of the coarsest level; `None` halves while the shorter side
    /// stays >= `MIN_LEVEL_SIDE`.
    pub levels: Option<usize>,
    /// Most Gauss-Newton steps per level.
    pub max_iterations: usize,
    /// A level stops once a step moves no window corner by more than this
    /// many full-resolution pixels.
    pub tolerance: f64,
    /// What is correlated: the intensities, or the Sobel gradient
    /// magnitudes of every channel (see the module's doc for why).
    pub features: Features,
}

/// The result of [`refine`].
#[derive(Debug, Clone, PartialEq)]
pub struct Refined {
    /// Maps reference pixels to moving positions (see `motion`).
    pub matrix: Matrix,
    /// The ECC (the NCC of the reference and the warped channel) over the
    /// full-resolution window, at the warp the last step started from.
    pub score: f64,
    /// Steps taken per level, coarsest first.
    pub iterations: Vec<usize>,
    /// Whether the finest level met `tolerance` within `max_iterations`.
    pub converged: bool,
}

/// Sums over reference pixels of what depends on the reference alone: its
/// moments and those of the affine derivatives `J` (the side a step
/// linearises).
#[derive(Debug, Clone, Copy, Default)]
struct Template {
    n: f64,
    st: f64,
    stt: f64,
    j1: [f64; AFFINE],
    jt: [f64; AFFINE],
    jj: [[f64; AFFINE]; AFFINE],
}

/// One row's [`Template`] as sums over powers of `u`: `g[c][p]` is
/// `sum g_c u^p`, `tg` the same times `t`, `gg[c][d][p]` is `sum g_c g_d
/// u^p`.
#[derive(Debug, Clone, Copy, Default)]
struct TemplateRow {
    n: f64,
    st: f64,
    stt: f64,
    g: [[f64; 2]; 2],
    tg: [[f64; 2]; 2],
    gg: [[[f64; 3]; 2]; 2],
}

impl TemplateRow {
    #[inline(always)]
    fn add(&mut self, t: f64, g: [f64; 2], u: f64) {
        let pu = [1.0, u, u * u];
        self.n += 1.0;
        self.st += t;
        self.stt += t * t;
        for c in 0..2 {
            for (p, &up) in pu[..2].iter().enumerate() {
                self.g[c][p] += g[c] * up;
                self.tg[c][p] += t * g[c] * up;
            }
            for d in 0..2 {
                for (p, &up) in pu.iter().enumerate() {
                    self.gg[c][d][p] += g[c] * g[d] * up;
                }
            }
        }
    }
}

impl Template {
    /// Adds a row whose centred ordinate is `v`.
    fn add_row(&mut self, r: &TemplateRow, v: f64) {
        let pv = [1.0, v, v * v];
        self.n += r.n;
        self.st += r.st;
        self.stt += r.stt;
        for k in 0..AFFINE {
            let (c, (a, b)) = (k / 3, POWERS[k % 3]);
            self.j1[k] += r.g[c][a] * pv[b];
            self.jt[k] += r.tg[c][a] * pv[b];
            for l in 0..AFFINE {
                let (d, (a2, b2)) = (l / 3, POWERS[l % 3]);
                self.jj[k][l] += r.gg[c][d][a + a2] * pv[b + b2];
            }
        }
    }

    /// `self + sign * o`.
    fn add_scaled(&mut self, o: &Self, sign: f64) {
        self.n += sign * o.n;
        self.st += sign * o.st;
        self.stt += sign * o.stt;
        for k in 0..AFFINE {
            self.j1[k] += sign * o.j1[k];
            self.jt[k] += sign * o.jt[k];
            for l in 0..AFFINE {
                self.jj[k][l] += sign * o.jj[k][l];
            }
        }
    }
}

/// Sums over the valid pixels of one step of what involves the moving
/// channel read through the warp, `i`: its moments, its product with the
/// reference and its projections `sum J_k i`.
#[derive(Debug, Clone, Copy, Default)]
struct Warped {
    si: f64,
    sii: f64,
    sti: f64,
    ji: [f64; AFFINE],
}

/// One row's [`Warped`]; `gi[c][p]` is `sum i g_c u^p`.
#[derive(Debug, Clone, Copy, Default)]
struct WarpedRow {
    si: f64,
    sii: f64,
    sti: f64,
    gi: [[f64; 2]; 2],
}

impl WarpedRow {
    #[inline(always)]
    fn add(&mut self, t: f64, g: [f64; 2], i: f64, u: f64) {
        self.si += i;
        self.sii += i * i;
        self.sti += t * i;
        let (ix, iy) = (i * g[0], i * g[1]);
        self.gi[0][0] += ix;
        self.gi[0][1] += ix * u;
        self.gi[1][0] += iy;
        self.gi[1][1] += iy * u;
    }
}

impl Warped {
    fn add_row(&mut self, r: &WarpedRow, v: f64) {
        let pv = [1.0, v];
        self.si += r.si;
        self.sii += r.sii;
        self.sti += r.sti;
        for k in 0..AFFINE {
            let (c, (a, b)) = (k / 3, POWERS[k % 3]);
            self.ji[k] += r.gi[c][a] * pv[b];
        }
    }

    fn add(&mut self, o: &Self) {
        self.si += o.si;
        self.sii += o.sii;
        self.sti += o.sti;
        for k in 0..AFFINE {
            self.ji[k] += o.ji[k];
        }
    }
}

/// Bilinear sample of `img` at `(x, y)`, `None` when a tap is outside.
#[inline(always)]
fn sample<S: Sample>(img: &ImageView<'_, S>, x: f64, y: f64) -> Option<f64> {
    let inside =
        x >= 0.0 && y >= 0.0 && x < (img.width() - 1) as f64 && y < (img.height() - 1) as f64;
    if !inside {
        return None;
    }
    let (ix, iy) = (x as usize, y as usize);
    let (fx, fy) = ((x - ix as f64) as f32, (y - iy as f64) as f32);
    let (d, s) = (img.data(), img.stride());
    let i = iy * s + ix;
    let (a, b) = (d[i].to_f32(), d[i + 1].to_f32());
    let (c, e) = (d[i + s].to_f32(), d[i + s + 1].to_f32());
    let top = a + fx * (b - a);
    let bottom = c + fx * (e - c);
    Some(f64::from(top + fy * (bottom - top)))
}

/// Three rows of the reference around one and the spacing of the outer two.
struct Rows3<'a, S> {
    up: &'a [S],
    mid: &'a [S],
    down: &'a [S],
    /// `1 / (down - up)`: 1/2 inside, 1 at the first and last rows.
    inv_dy: f32,
}

impl<S: Sample> Rows3<'_, S> {
    /// The sample at `x` and its central-difference gradient (one-sided at
    /// the image's borders, over the one-pixel step there).
    #[inline(always)]
    fn at(&self, x: usize) -> (f64, [f64; 2]) {
        let last = self.mid.len() - 1;
        let (l, r) = (x.saturating_sub(1), (x + 1).min(last));
        let inv_dx = if r - l == 2 { 0.5 } else { 1.0 };
        let gx = (self.mid[r].to_f32() - self.mid[l].to_f32()) * inv_dx;
        let gy = (self.down[x].to_f32() - self.up[x].to_f32()) * self.inv_dy;
        (
            f64::from(self.mid[x].to_f32()),
            [f64::from(gx), f64::from(gy)],
        )
    }
}

/// One level's reference and window.
struct Level<'a, S> {
    reference: ImageView<'a, S>,
    window: Window,
    centre: (f64, f64),
}

impl<'a, S: Sample> Level<'a, S> {
    fn new(reference: ImageView<'a, S>, crop: f64) -> Self {
        let (w, h) = (reference.width(), reference.height());
        Self {
            reference,
            window: Window::cropped(w, h, crop),
            centre: (0.5 * (w as f64 - 1.0), 0.5 * (h as f64 - 1.0)),
        }
    }

    fn rows3(&self, y: usize) -> Rows3<'a, S> {
        let last = self.reference.height() - 1;
        let (up, down) = (y.saturating_sub(1), (y + 1).min(last));
        Rows3 {
            up: self.reference.row(up),
            mid: self.reference.row(y),
            down: self.reference.row(down),
            inv_dy: if down - up == 2 { 0.5 } else { 1.0 },
        }
    }

    /// `band` over the window's bands of rows, in parallel, in band order.
    fn bands<A: Send>(&self, band: impl Fn(Range<usize>) -> A + Sync) -> Vec<A> {
        let w = self.window;
        let starts: Vec<usize> = (w.y0..w.y1).step_by(BAND_ROWS).collect();
        starts
            .par_iter()
            .map(|&y0| band(y0..(y0 + BAND_ROWS).min(w.y1)))
            .collect()
    }

    /// The [`Template`] of the whole window.
    fn template(&self) -> Template {
        let mut total = Template::default();
        for part in self.bands(|rows| {
            let mut s = Template::default();
            for y in rows {
                let r = self.rows3(y);
                let mut row = TemplateRow::default();
                for x in self.window.x0..self.window.x1 {
                    let (t, g) = r.at(x);
                    row.add(t, g, x as f64 - self.centre.0);
                }
                s.add_row(&row, y as f64 - self.centre.1);
            }
            s
        }) {
            total.add_scaled(&part, 1.0);
        }
        total
    }

    /// The [`Warped`] sums of `moving` read through `warp`, and the
    /// [`Template`] of the window pixels whose sample falls outside it (to
    /// be taken off the window's).
    fn warped(&self, moving: &ImageView<'_, S>, warp: &Centred) -> (Warped, Template) {
        let (a, (tx, ty)) = warp.linear_and_shift();
        let (cx, cy) = self.centre;
        let (mut total, mut outside) = (Warped::default(), Template::default());
        for (w, o) in self.bands(|rows| {
            let (mut w, mut o) = (Warped::default(), Template::default());
            for y in rows {
                let v = y as f64 - cy;
                let r = self.rows3(y);
                // Where u = 0 of this row lands; a pixel adds A's first
                // column times its u.
                let (ox, oy) = (a[0][1] * v + tx + cx, a[1][1] * v + ty + cy);
                let (mut row, mut out) = (WarpedRow::default(), TemplateRow::default());
                for x in self.window.x0..self.window.x1 {
                    let u = x as f64 - cx;
                    let (t, g) = r.at(x);
                    match sample(moving, a[0][0] * u + ox, a[1][0] * u + oy) {
                        Some(i) => row.add(t, g, i, u),
                        None => out.add(t, g, u),
                    }
                }
                w.add_row(&row, v);
                o.add_row(&out, v);
            }
            (w, o)
        }) {
            total.add(&w);
            outside.add_scaled(&o, 1.0);
        }
        (total, outside)
    }
}

/// Why no Gauss-Newton step exists.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stall {
    /// Singular normal equations: a channel without texture along some
    /// parameter (constant, or stripes that a shift along them leaves alike).
    Flat,
    /// The step would lower the correlation: the channels do not match.
    Mismatch,
}

/// The ECC of a step's sums over the valid pixels, and the parameters (of
/// `motion`, about the identity) of the small warp of the reference that
/// best matches it to the warped channel.
fn step(
    t: &Template,
    w: &Warped,
    motion: Motion,
) -> (f64, std::result::Result<[f64; MAX_PARAMS], Stall>) {
    let n = motion.params();
    let basis = motion.affine_basis();
    let project = |v: &[f64; AFFINE]| -> [f64; MAX_PARAMS] {
        std::array::from_fn(|k| (0..AFFINE).map(|a| basis[k][a] * v[a]).sum())
    };
    let (j1, jt, ji) = (project(&t.j1), project(&t.jt), project(&w.ji));
    let (mt, mi) = (t.st / t.n, w.si / t.n);
    let t_norm2 = t.stt - t.n * mt * mt;
    let i_norm2 = w.sii - t.n * mi * mi;
    let corr = w.sti - t.n * mt * mi;
    let rho = corr / (t_norm2 * i_norm2).sqrt();
    // The normal matrix of the mean-free Jacobian, J^T J - J^T 1 1^T J / n:
    // mean-free like the channels, so a brightness offset does not bias it.
    let mut h = [[0.0; MAX_PARAMS]; MAX_PARAMS];
    for k in 0..n {
        // Row k of B^T (J^T J) B, B the motion's affine basis.
        let jj_k: [f64; AFFINE] =
            std::array::from_fn(|b| (0..AFFINE).map(|a| basis[k][a] * t.jj[a][b]).sum());
        let row = project(&jj_k);
        for l in 0..n {
            h[k][l] = row[l] - j1[k] * j1[l] / t.n;
        }
    }
    let mut tp = [0.0; MAX_PARAMS];
    let mut ip = [0.0; MAX_PARAMS];
    for k in 0..n {
        tp[k] = jt[k] - mt * j1[k];
        ip[k] = ji[k] - mi * j1[k];
    }
    let Some(h_tp) = solve(&h, &tp, n) else {
        return (rho, Err(Stall::Flat));
    };
    let dot_n = |a: &[f64; MAX_PARAMS], b: &[f64; MAX_PARAMS]| -> f64 {
        a[..n].iter().zip(&b[..n]).map(|(x, y)| x * y).sum()
    };
    // ECC's optimal gain between the channels at this linearisation.
    let lambda_n = t_norm2 - dot_n(&tp, &h_tp);
    let lambda_d = corr - dot_n(&ip, &h_tp);
    if lambda_d.is_nan() || lambda_d <= 0.0 {
        return (rho, Err(Stall::Mismatch));
    }
    let lambda = lambda_n / lambda_d;
    let mut err = [0.0; MAX_PARAMS];
    for k in 0..n {
        err[k] = lambda * ip[k] - tp[k];
    }
    (rho, solve(&h, &err, n).ok_or(Stall::Flat))
}

/// Solves `h x = b` (`n x n`, symmetric) by Gaussian elimination with
/// partial pivoting after scaling by the diagonal (the rotation column is
/// ~1000 times the translation's on a plate); `None` when singular.
fn solve(
    h: &[[f64; MAX_PARAMS]; MAX_PARAMS],
    b: &[f64; MAX_PARAMS],
    n: usize,
) -> Option<[f64; MAX_PARAMS]> {
    let mut d = [0.0; MAX_PARAMS];
    for k in 0..n {
        if !(h[k][k] > 0.0 && h[k][k].is_finite()) {
            return None;
        }
        d[k] = 1.0 / h[k][k].sqrt();
    }
    let mut a = [[0.0; MAX_PARAMS + 1]; MAX_PARAMS];
    for k in 0..n {
        for l in 0..n {
            a[k][l] = d[k] * h[k][l] * d[l];
        }
        a[k][n] = d[k] * b[k];
    }
    for c in 0..n {
        let p = (c..n).max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))?;
        // The scaled matrix has a unit diagonal: a pivot this small means
        // two parameters move the image the same way.
        if a[p][c].abs() < 1e-9 {
            return None;
        }
        a.swap(c, p);
        let pivot = a[c];
        for row in &mut a[c + 1..n] {
            let f = row[c] / pivot[c];
            for (v, p) in row[c..=n].iter_mut().zip(&pivot[c..=n]) {
                *v -= f * p;
            }
        }
    }
    let mut x = [0.0; MAX_PARAMS];
    for c in (0..n).rev() {
        let rest: f64 = (c + 1..n).map(|k| a[c][k] * x[k]).sum();
        x[c] = (a[c][n] - rest) / a[c][c];
    }
    for k in 0..n {
        x[k] *= d[k];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// How far a parameter step moves the window's farthest corner, in pixels of
/// the level.
fn displacement(before: &Centred, after: &Centred, half: (f64, f64)) -> f64 {
    let (a0, t0) = before.linear_and_shift();
    let (a1, t1) = after.linear_and_shift();
    let mut worst: f64 = 0.0;
    for (u, v) in [
        (-half.0, -half.1),
        (half.0, -half.1),
        (-half.0, half.1),
        (half.0, half.1),
    ] {
        let dx = (a1[0][0] - a0[0][0]) * u + (a1[0][1] - a0[0][1]) * v + t1.0 - t0.0;
        let dy = (a1[1][0] - a0[1][0]) * u + (a1[1][1] - a0[1][1]) * v + t1.1 - t0.1;
        worst = worst.max(dx.hypot(dy));
    }
    worst
}

/// Refines `init` (reference pixel to moving position, e.g. the shift the
/// translation search found) under `motion`, coarse to fine.
///
/// # Errors
/// As [`refine_many`].
pub fn refine<T: Sample>(
    reference: &ImageView<'_, T>,
    moving: &ImageView<'_, T>,
    motion: Motion,
    init: &Matrix,
    opts: &EccOptions,
) -> Result<Refined> {
    let mut all = refine_many(reference, &[*moving], motion, &[*init], opts)?;
    Ok(all.remove(0))
}

/// [`refine`] for several moving channels onto one reference (the two
/// other channels of a plate): the reference's pyramid and its per-level
/// sums are computed once for all of them. Each result is the one
/// [`refine`] gives for that channel alone.
///
/// # Errors
/// [`crate::CoreError::Shape`] for images of different shapes or with more
/// than one channel; [`crate::CoreError::InvalidArgument`] for NaN samples,
/// as many `inits` as channels not given, a non-finite init, bad options,
/// images too small for the motion (fewer than `MIN_PIXELS_PER_PARAM`
/// window pixels per parameter at the coarsest level), a channel without
/// texture (constant, or no gradient along some parameter), or a warp that
/// leaves too little overlap.
pub fn refine_many<T: Sample>(
    reference: &ImageView<'_, T>,
    moving: &[ImageView<'_, T>],
    motion: Motion,
    inits: &[Matrix],
    opts: &EccOptions,
) -> Result<Vec<Refined>> {
    if moving.len() != inits.len() {
        return Err(invalid!(
            "one initial matrix per moving channel is needed, got {} channels and {} matrices",
            moving.len(),
            inits.len()
        ));
    }
    for (m, init) in moving.iter().zip(inits) {
        super::same_size(reference, m, ("reference", "moving"))?;
        check_options(init, opts)?;
    }
    let levels = level_count(reference, motion, opts)?;
    match opts.features {
        Features::Intensity => refine_views(reference, moving, levels, motion, inits, opts),
        Features::Gradient => {
            let magnitude =
                |v: &ImageView<'_, T>, name| Ok(Plane::gradient(&Converted::new(v, name)?));
            let r = magnitude(reference, "reference")?;
            let ms = moving
                .iter()
                .map(|m| magnitude(m, "moving"))
                .collect::<Result<Vec<_>>>()?;
            let views = ms.iter().map(Plane::view).collect::<Result<Vec<_>>>()?;
            refine_views(&r.view()?, &views, levels, motion, inits, opts)
        }
    }
}

/// [`refine_many`] on the images compared, with `levels` halvings.
fn refine_views<S: Sample>(
    reference: &ImageView<'_, S>,
    moving: &[ImageView<'_, S>],
    levels: usize,
    motion: Motion,
    inits: &[Matrix],
    opts: &EccOptions,
) -> Result<Vec<Refined>> {
    let refs = pyramid(&Converted::new(reference, "reference")?, levels);
    let movs = moving
        .iter()
        .map(|m| Ok(pyramid(&Converted::new(m, "moving")?, levels)))
        .collect::<Result<Vec<_>>>()?;
    let mut found: Vec<Refined> = inits
        .iter()
        .map(|m| Refined {
            matrix: *m,
            score: f64::NAN,
            iterations: Vec::with_capacity(levels + 1),
            converged: false,
        })
        .collect();
    for l in (1..=levels).rev() {
        let views = movs
            .iter()
            .map(|p| p[l - 1].view())
            .collect::<Result<Vec<_>>>()?;
        run_level(refs[l - 1].view()?, &views, l, motion, opts, &mut found)?;
    }
    run_level(*reference, moving, 0, motion, opts, &mut found)?;
    Ok(found)
}

/// The number of halvings: `opts.levels`, or as many as keep the shorter
/// side at least `MIN_LEVEL_SIDE`; refused when the coarsest window is too
/// small for the motion.
fn level_count<T>(reference: &ImageView<'_, T>, motion: Motion, opts: &EccOptions) -> Result<usize>
where
    T: Copy,
{
    let (w, h) = (reference.width(), reference.height());
    let levels = opts.levels.unwrap_or_else(|| {
        let mut n = 0;
        while w.min(h) >> (n + 1) >= MIN_LEVEL_SIDE {
            n += 1;
        }
        n
    });
    let need = MIN_PIXELS_PER_PARAM * motion.params();
    // `checked_shr`: a plain `>>` of 64 levels or more shifts by the count
    // modulo 64 in release builds, and such a pyramid passed the check.
    let halve = |side: usize| side.checked_shr(levels.try_into().unwrap_or(u32::MAX));
    let (cw, ch) = (halve(w).unwrap_or(0), halve(h).unwrap_or(0));
    let coarsest = Window::cropped(cw, ch, opts.crop);
    let area = coarsest.y1.saturating_sub(coarsest.y0) * coarsest.x1.saturating_sub(coarsest.x0);
    if cw < 2 || ch < 2 || area < need {
        return Err(invalid!(
            "images of {h}x{w} are too small for {} motion with crop={} and {levels} \
             pyramid levels: the coarsest window has {area} pixels, {need} are needed ({} per \
             parameter)",
            motion.with_article(),
            opts.crop,
            MIN_PIXELS_PER_PARAM
        ));
    }
    Ok(levels)
}

/// Levels 1..=`levels` of `src` (level 0 is `src` itself, read in place).
fn pyramid<T: Sample>(src: &Converted<'_, T>, levels: usize) -> Vec<Plane> {
    let mut out: Vec<Plane> = Vec::with_capacity(levels);
    for l in 0..levels {
        let next = match l {
            0 => Plane::downsample(src),
            _ => Plane::downsample(&out[l - 1]),
        };
        out.push(next);
    }
    out
}

/// Refines every channel's warp at pyramid level `index` (images `2^index`
/// times smaller than full resolution), from and into `found`.
fn run_level<S: Sample>(
    reference: ImageView<'_, S>,
    moving: &[ImageView<'_, S>],
    index: usize,
    motion: Motion,
    opts: &EccOptions,
    found: &mut [Refined],
) -> Result<()> {
    let level = Level::new(reference, opts.crop);
    let template = level.template();
    let tolerance = opts.tolerance / (1u64 << index) as f64;
    for (m, f) in moving.iter().zip(found) {
        let start = Centred::from_matrix(motion, &to_level(&f.matrix, index), level.centre);
        let (warp, took, rho, done) = iterate(&level, &template, m, start, opts, tolerance, index)?;
        f.matrix = from_level(&warp.matrix(level.centre), index);
        f.iterations.push(took);
        (f.score, f.converged) = (rho, done);
    }
    Ok(())
}

/// Gauss-Newton steps on one level until a step moves no corner by more
/// than `tolerance`: the warp, the steps taken, the ECC the last step
/// started from and whether it converged.
fn iterate<S: Sample>(
    level: &Level<'_, S>,
    template: &Template,
    moving: &ImageView<'_, S>,
    mut warp: Centred,
    opts: &EccOptions,
    tolerance: f64,
    index: usize,
) -> Result<(Centred, usize, f64, bool)> {
    let motion = warp.motion;
    let win = level.window;
    let half = (
        0.5 * (win.x1 - win.x0) as f64,
        0.5 * (win.y1 - win.y0) as f64,
    );
    let need = (MIN_PIXELS_PER_PARAM * motion.params()) as f64;
    let mut score = f64::NAN;
    for it in 0..opts.max_iterations {
        let (warped, outside) = level.warped(moving, &warp);
        let mut valid = *template;
        valid.add_scaled(&outside, -1.0);
        if valid.n < need {
            return Err(invalid!(
                "the warp leaves {} of the window's pixels inside the moving image at pyramid \
                 level {index} ({} needed): the motion is beyond what can be estimated",
                valid.n,
                need
            ));
        }
        let (rho, delta) = step(&valid, &warped, motion);
        score = rho;
        let why = match delta {
            Ok(delta) => match warp.then_inverse_of(&Centred::increment(motion, &delta)) {
                Some(next) => {
                    let before = std::mem::replace(&mut warp, next);
                    if displacement(&before, &warp, half) <= tolerance {
                        return Ok((warp, it + 1, score, true));
                    }
                    continue;
                }
                None => "a step would make the warp singular",
            },
            Err(Stall::Flat) => "a channel is constant or has no texture along some parameter",
            Err(Stall::Mismatch) => {
                "the channels do not match (a step would lower the correlation)"
            }
        };
        return Err(invalid!(
            "cannot estimate {} motion at pyramid level {index}: {why} (ECC {rho:.3})",
            motion.with_article()
        ));
    }
    Ok((warp, opts.max_iterations, score, false))
}

fn check_options(init: &Matrix, opts: &EccOptions) -> Result<()> {
    if !init.iter().flatten().all(|v| v.is_finite()) {
        return Err(invalid!("the initial matrix must be finite, got {init:?}"));
    }
    if !(opts.crop.is_finite() && (0.0..0.5).contains(&opts.crop)) {
        return Err(invalid!("crop must be in [0, 0.5), got {}", opts.crop));
    }
    if opts.max_iterations == 0 {
        return Err(invalid!("max_iterations must be >= 1, got 0"));
    }
    if !(opts.tolerance.is_finite() && opts.tolerance > 0.0) {
        return Err(invalid!(
            "tolerance must be a finite number > 0, got {}",
            opts.tolerance
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::align::motion::{invert, IDENTITY};

    /// Smooth, non-periodic, with structure at several scales.
    fn pattern(x: f64, y: f64) -> f32 {
        let v = 0.5
            + 0.15 * (0.05 * x + 0.021 * y).sin()
            + 0.12 * (0.023 * x - 0.047 * y).cos()
            + 0.08 * (0.0011 * x * y).sin()
            + 0.05 * (0.13 * x + 0.07 * y).sin();
        v as f32
    }

    /// `pattern` sampled at `m (x, y)`: the moving image whose warp (read
    /// at `M x` to land on `pattern`) is `m^-1`.
    fn warped(w: usize, h: usize, m: &Matrix) -> Vec<f32> {
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x as f64, y as f64)))
            .map(|(x, y)| {
                pattern(
                    m[0][0] * x + m[0][1] * y + m[0][2],
                    m[1][0] * x + m[1][1] * y + m[1][2],
                )
            })
            .collect()
    }

    fn opts() -> EccOptions {
        EccOptions {
            crop: 0.1,
            levels: None,
            max_iterations: 50,
            tolerance: 1e-3,
            features: Features::Intensity,
        }
    }

    fn similarity(angle: f64, scale: f64, tx: f64, ty: f64) -> Matrix {
        let (s, c) = (scale * angle.sin(), scale * angle.cos());
        [[c, -s, tx], [s, c, ty]]
    }

    /// The largest difference between two matrices' entries.
    fn max_difference(a: &Matrix, b: &Matrix) -> f64 {
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn recovers_a_similarity_from_a_translation_start() {
        let (w, h) = (400, 340);
        let truth = similarity(0.02, 1.01, 5.3, -3.7);
        let r = warped(w, h, &IDENTITY);
        let m = warped(w, h, &invert(&truth).unwrap());
        let (rv, mv) = (
            ImageView::contiguous(&r, w, h, 1).unwrap(),
            ImageView::contiguous(&m, w, h, 1).unwrap(),
        );
        let start = [[1.0, 0.0, 5.0], [0.0, 1.0, -4.0]];
        for motion in [Motion::Similarity, Motion::Affine] {
            let got = refine(&rv, &mv, motion, &start, &opts()).unwrap();
            let err = max_difference(&got.matrix, &truth);
            assert!(err < 2e-3, "{motion:?}: {:?} vs {truth:?}", got.matrix);
            assert!(got.converged && got.score > 0.999, "{got:?}");
            assert_eq!(got.iterations.len(), 2);
        }
        let rigid = similarity(-0.015, 1.0, -2.2, 1.4);
        let m = warped(w, h, &invert(&rigid).unwrap());
        let mv = ImageView::contiguous(&m, w, h, 1).unwrap();
        let got = refine(&rv, &mv, Motion::Euclidean, &IDENTITY, &opts()).unwrap();
        let angle = got.matrix[1][0].atan2(got.matrix[0][0]);
        assert!((angle + 0.015).abs() < 2e-5, "{angle}");
        assert!(
            (got.matrix[0][2] - rigid[0][2]).abs() < 0.02,
            "{:?}",
            got.matrix
        );
    }

    #[test]
    fn pixels_read_outside_the_moving_image_are_left_out_exactly() {
        // No crop: the reference pixels within ~9 px of two borders read
        // outside the moving image at the truth, and must be left out of
        // every sum (the reference's per-level sums minus theirs).
        let (w, h) = (360, 300);
        let truth = similarity(0.01, 0.995, 8.5, -6.0);
        let r = warped(w, h, &IDENTITY);
        let m = warped(w, h, &invert(&truth).unwrap());
        let (rv, mv) = (
            ImageView::contiguous(&r, w, h, 1).unwrap(),
            ImageView::contiguous(&m, w, h, 1).unwrap(),
        );
        let o = EccOptions {
            crop: 0.0,
            ..opts()
        };
        let start = [[1.0, 0.0, 8.0], [0.0, 1.0, -6.0]];
        let got = refine(&rv, &mv, Motion::Similarity, &start, &o).unwrap();
        let err = max_difference(&got.matrix, &truth);
        assert!(err < 2e-3, "{:?} vs {truth:?}", got.matrix);
    }

    #[test]
    fn channels_refined_together_match_each_alone() {
        let (w, h) = (240, 200);
        let r = warped(w, h, &IDENTITY);
        let rv = ImageView::contiguous(&r, w, h, 1).unwrap();
        let truths = [
            similarity(0.015, 1.004, 2.5, -1.5),
            similarity(-0.01, 0.997, -3.0, 2.0),
        ];
        let ms: Vec<Vec<f32>> = truths
            .iter()
            .map(|t| warped(w, h, &invert(t).unwrap()))
            .collect();
        let views: Vec<_> = ms
            .iter()
            .map(|m| ImageView::contiguous(m, w, h, 1).unwrap())
            .collect();
        let inits = [IDENTITY, IDENTITY];
        let both = refine_many(&rv, &views, Motion::Similarity, &inits, &opts()).unwrap();
        for (v, got) in views.iter().zip(&both) {
            assert_eq!(
                got,
                &refine(&rv, v, Motion::Similarity, &IDENTITY, &opts()).unwrap()
            );
        }
        let e = refine_many(&rv, &views, Motion::Similarity, &inits[..1], &opts())
            .unwrap_err()
            .to_string();
        assert!(e.contains("one initial matrix per moving channel"), "{e}");
    }

    #[test]
    fn identical_images_stay_at_the_identity_for_any_thread_count() {
        let (w, h) = (200, 180);
        let r = warped(w, h, &IDENTITY);
        let rv = ImageView::contiguous(&r, w, h, 1).unwrap();
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| refine(&rv, &rv, Motion::Affine, &IDENTITY, &opts()).unwrap())
        };
        let one = run(1);
        assert_eq!(one, run(3));
        assert!(one.score > 0.999_999);
        for (a, b) in one.matrix.iter().flatten().zip(IDENTITY.iter().flatten()) {
            assert!((a - b).abs() < 1e-9, "{:?}", one.matrix);
        }
    }

    #[test]
    fn gradient_features_follow_anti_correlated_channels() {
        // The moving channel is the negative of the reference's scene: the
        // intensity ECC finds no step that raises the correlation, the
        // gradient magnitudes (blind to an edge's sign) recover the warp.
        let (w, h) = (400, 340);
        let truth = similarity(-0.012, 0.996, -3.4, 2.6);
        let r = warped(w, h, &IDENTITY);
        let m: Vec<f32> = warped(w, h, &invert(&truth).unwrap())
            .iter()
            .map(|v| 1.0 - v)
            .collect();
        let (rv, mv) = (
            ImageView::contiguous(&r, w, h, 1).unwrap(),
            ImageView::contiguous(&m, w, h, 1).unwrap(),
        );
        let start = [[1.0, 0.0, -3.0], [0.0, 1.0, 3.0]];
        let e = refine(&rv, &mv, Motion::Similarity, &start, &opts())
            .unwrap_err()
            .to_string();
        assert!(e.contains("do not match"), "{e}");
        let o = EccOptions {
            features: Features::Gradient,
            ..opts()
        };
        let got = refine(&rv, &mv, Motion::Similarity, &start, &o).unwrap();
        let err = max_difference(&got.matrix, &truth);
        // Within 0.02 px of the truth (magnitudes have kinks where the
        // gradient vanishes, so a little less sharp than intensities).
        assert!(err < 0.03, "{:?} vs {truth:?}", got.matrix);
        assert!(got.converged && got.score > 0.99, "{got:?}");
    }

    #[test]
    fn constant_tiny_and_bad_input_is_refused() {
        let flat = vec![0.5f32; 100 * 100];
        let fv = ImageView::contiguous(&flat, 100, 100, 1).unwrap();
        let e = refine(&fv, &fv, Motion::Euclidean, &IDENTITY, &opts())
            .unwrap_err()
            .to_string();
        assert!(e.contains("constant"), "{e}");
        assert!(e.contains("cannot estimate a Euclidean motion"), "{e}");
        let tiny = warped(12, 12, &IDENTITY);
        let tv = ImageView::contiguous(&tiny, 12, 12, 1).unwrap();
        let e = refine(&tv, &tv, Motion::Affine, &IDENTITY, &opts())
            .unwrap_err()
            .to_string();
        assert!(e.contains("too small for an affine motion"), "{e}");
        let r = warped(100, 100, &IDENTITY);
        let rv = ImageView::contiguous(&r, 100, 100, 1).unwrap();
        let far = [[1.0, 0.0, 95.0], [0.0, 1.0, 95.0]];
        let e = refine(&rv, &rv, Motion::Translation, &far, &opts())
            .unwrap_err()
            .to_string();
        assert!(e.contains("beyond"), "{e}");
        let nan = [[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert!(refine(&rv, &rv, Motion::Translation, &nan, &opts()).is_err());
        // 64 levels and more shifted by their count modulo 64 and passed,
        // then asked for a pyramid that vector of levels could not hold.
        for levels in [20, 64, 1 << 32, 1 << 62] {
            let deep = EccOptions {
                levels: Some(levels),
                ..opts()
            };
            let e = refine(&rv, &rv, Motion::Translation, &IDENTITY, &deep)
                .unwrap_err()
                .to_string();
            assert!(e.contains(&format!("and {levels} pyramid levels")), "{e}");
        }
    }
}

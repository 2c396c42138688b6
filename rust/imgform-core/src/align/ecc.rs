//! Sub-pixel refinement of a warp by maximising the enhanced correlation
//! coefficient (ECC, Evangelidis & Psarakis 2008; OpenCV's
//! `findTransformECC`), coarse to fine.
//!
//! ECC is the NCC of the reference with the warped moving channel, so like
//! the translation search it ignores gain and offset between the channels.
//! Each Gauss-Newton step linearises the warped channel in the warp
//! parameters and solves a small normal system; every per-pixel quantity
//! (the bilinear samples of the channel and its gradient, the Jacobian rows,
//! the Hessian) is summed in one pass over the window, in `f64`, in bands
//! of rows that are fixed by the image and added in order: the result is
//! bit-identical for any thread count.

use rayon::prelude::*;

use super::motion::{from_level, to_level, Centred, Matrix, Motion, MAX_PARAMS};
use super::pyramid::{Converted, Plane};
use super::search::Window;
use crate::error::Result;
use crate::image::{ImageView, Sample};
use crate::invalid;

/// Reference rows per task: a band of a 3000-pixel plate is ~100 k pixels,
/// ~1 ms of work, far above rayon's per-task cost.
const BAND_ROWS: usize = 32;

/// Entries of the upper triangle of the largest (6 x 6) Hessian.
const TRIANGLE: usize = MAX_PARAMS * (MAX_PARAMS + 1) / 2;

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
}

/// The result of [`refine`].
#[derive(Debug, Clone, PartialEq)]
pub struct Refined {
    /// Maps reference pixels to moving positions (see `motion`).
    pub matrix: Matrix,
    /// The ECC (the NCC of the reference and the warped channel) over the
    /// full-resolution window, at the final warp.
    pub score: f64,
    /// Steps taken per level, coarsest first.
    pub iterations: Vec<usize>,
    /// Whether the finest level met `tolerance` within `max_iterations`.
    pub converged: bool,
}

/// The moving channel of one level with its central-difference gradient,
/// interleaved so one bilinear fetch reads all three.
struct Packed {
    data: Vec<[f32; 3]>,
    width: usize,
    height: usize,
}

impl Packed {
    fn new(src: &Plane) -> Self {
        let (w, h) = (src.width, src.height);
        let at = |x: usize, y: usize| src.data[y * w + x];
        let mut data = vec![[0.0f32; 3]; w * h];
        crate::parallel::for_each_row(&mut data, w, |y, row| {
            let (up, down) = (y.saturating_sub(1), (y + 1).min(h - 1));
            for (x, o) in row.iter_mut().enumerate() {
                let (l, r) = (x.saturating_sub(1), (x + 1).min(w - 1));
                // One-sided at the borders (the step is halved there too).
                let gx = (at(r, y) - at(l, y)) / (r - l).max(1) as f32;
                let gy = (at(x, down) - at(x, up)) / (down - up).max(1) as f32;
                *o = [at(x, y), gx, gy];
            }
        });
        Self {
            data,
            width: w,
            height: h,
        }
    }

    /// Bilinear `(value, gx, gy)` at `(x, y)`, `None` when a tap is outside.
    #[inline(always)]
    fn sample(&self, x: f64, y: f64) -> Option<[f64; 3]> {
        if !(x >= 0.0 && y >= 0.0 && x < (self.width - 1) as f64 && y < (self.height - 1) as f64) {
            return None;
        }
        let (ix, iy) = (x as usize, y as usize);
        let (fx, fy) = ((x - ix as f64) as f32, (y - iy as f64) as f32);
        let i = iy * self.width + ix;
        let (a, b) = (self.data[i], self.data[i + 1]);
        let (c, d) = (self.data[i + self.width], self.data[i + self.width + 1]);
        let mut out = [0.0; 3];
        for k in 0..3 {
            let top = a[k] + fx * (b[k] - a[k]);
            let bottom = c[k] + fx * (d[k] - c[k]);
            out[k] = f64::from(top + fy * (bottom - top));
        }
        Some(out)
    }
}

/// Sums over the valid window pixels of one warp: the moments of the
/// reference `t` and the warped channel `i`, and the projections of the
/// Jacobian rows `j` onto 1, `t`, `i` and themselves.
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    n: f64,
    st: f64,
    si: f64,
    stt: f64,
    sii: f64,
    sti: f64,
    j1: [f64; MAX_PARAMS],
    jt: [f64; MAX_PARAMS],
    ji: [f64; MAX_PARAMS],
    jj: [f64; TRIANGLE],
}

impl Sums {
    fn add(&mut self, o: &Self) {
        self.n += o.n;
        self.st += o.st;
        self.si += o.si;
        self.stt += o.stt;
        self.sii += o.sii;
        self.sti += o.sti;
        for k in 0..MAX_PARAMS {
            self.j1[k] += o.j1[k];
            self.jt[k] += o.jt[k];
            self.ji[k] += o.ji[k];
        }
        for k in 0..TRIANGLE {
            self.jj[k] += o.jj[k];
        }
    }
}

/// One level's images and window.
struct Level<'a> {
    reference: &'a Plane,
    moving: &'a Packed,
    window: Window,
    centre: (f64, f64),
}

impl Level<'_> {
    /// The sums of `warp` over the window, bands in parallel, added in order.
    fn sums(&self, warp: &Centred) -> Sums {
        let w = self.window;
        let bands: Vec<usize> = (w.y0..w.y1).step_by(BAND_ROWS).collect();
        let partial: Vec<Sums> = bands
            .par_iter()
            .map(|&y0| self.band(warp, y0..(y0 + BAND_ROWS).min(w.y1)))
            .collect();
        let mut total = Sums::default();
        for s in &partial {
            total.add(s);
        }
        total
    }

    fn band(&self, warp: &Centred, rows: std::ops::Range<usize>) -> Sums {
        match warp.motion.params() {
            2 => self.band_of::<2>(warp, rows),
            3 => self.band_of::<3>(warp, rows),
            4 => self.band_of::<4>(warp, rows),
            _ => self.band_of::<MAX_PARAMS>(warp, rows),
        }
    }

    /// [`Self::band`] for a motion of `N` parameters: with `N` known at
    /// compile time the per-pixel products unroll into straight-line code
    /// (about twice as fast as loops over a runtime count).
    fn band_of<const N: usize>(&self, warp: &Centred, rows: std::ops::Range<usize>) -> Sums {
        let (a, (tx, ty)) = warp.linear_and_shift();
        let (cx, cy) = self.centre;
        let mut s = Sums::default();
        let (mut j1, mut jt, mut ji) = ([0.0; N], [0.0; N], [0.0; N]);
        let mut jj = [[0.0; N]; N];
        for y in rows {
            let v = y as f64 - cy;
            let t_row = &self.reference.row(y)[self.window.x0..self.window.x1];
            for (x, &t) in (self.window.x0..).zip(t_row) {
                let u = x as f64 - cx;
                let px = a[0][0] * u + a[0][1] * v + tx + cx;
                let py = a[1][0] * u + a[1][1] * v + ty + cy;
                let Some([i, gx, gy]) = self.moving.sample(px, py) else {
                    continue;
                };
                let t = f64::from(t);
                let (dx, dy) = warp.derivatives(u, v);
                let j: [f64; N] = std::array::from_fn(|k| gx * dx[k] + gy * dy[k]);
                s.n += 1.0;
                s.st += t;
                s.si += i;
                s.stt += t * t;
                s.sii += i * i;
                s.sti += t * i;
                for k in 0..N {
                    j1[k] += j[k];
                    jt[k] += j[k] * t;
                    ji[k] += j[k] * i;
                    for l in 0..N {
                        jj[k][l] += j[k] * j[l];
                    }
                }
            }
        }
        s.j1[..N].copy_from_slice(&j1);
        s.jt[..N].copy_from_slice(&jt);
        s.ji[..N].copy_from_slice(&ji);
        let upper = (0..N).flat_map(|k| (k..N).map(move |l| (k, l)));
        for ((k, l), out) in upper.zip(&mut s.jj) {
            *out = jj[k][l];
        }
        s
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

/// The ECC of a warp's sums, and the Gauss-Newton step that increases it.
fn step(s: &Sums, n: usize) -> (f64, std::result::Result<[f64; MAX_PARAMS], Stall>) {
    let (mt, mi) = (s.st / s.n, s.si / s.n);
    let t_norm2 = s.stt - s.n * mt * mt;
    let i_norm2 = s.sii - s.n * mi * mi;
    let corr = s.sti - s.n * mt * mi;
    let rho = corr / (t_norm2 * i_norm2).sqrt();
    // The Hessian of the mean-free warped channel, J^T J - J^T 1 1^T J / n:
    // mean-free like the channel, so a brightness offset does not bias it.
    let mut h = [[0.0; MAX_PARAMS]; MAX_PARAMS];
    let pairs = (0..n).flat_map(|k| (k..n).map(move |l| (k, l)));
    for ((k, l), jj) in pairs.zip(s.jj) {
        h[k][l] = jj - s.j1[k] * s.j1[l] / s.n;
        h[l][k] = h[k][l];
    }
    let mut ip = [0.0; MAX_PARAMS];
    let mut tp = [0.0; MAX_PARAMS];
    for k in 0..n {
        ip[k] = s.ji[k] - mi * s.j1[k];
        tp[k] = s.jt[k] - mt * s.j1[k];
    }
    let Some(h_ip) = solve(&h, &ip, n) else {
        return (rho, Err(Stall::Flat));
    };
    let dot = |a: &[f64; MAX_PARAMS], b: &[f64; MAX_PARAMS]| -> f64 {
        a[..n].iter().zip(&b[..n]).map(|(x, y)| x * y).sum()
    };
    // ECC's optimal gain between the channels at this linearisation.
    let lambda_n = i_norm2 - dot(&ip, &h_ip);
    let lambda_d = corr - dot(&tp, &h_ip);
    if lambda_d.is_nan() || lambda_d <= 0.0 {
        return (rho, Err(Stall::Mismatch));
    }
    let lambda = lambda_n / lambda_d;
    let mut err = [0.0; MAX_PARAMS];
    for k in 0..n {
        err[k] = lambda * tp[k] - ip[k];
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
/// [`crate::CoreError::Shape`] for images of different shapes or with more
/// than one channel; [`crate::CoreError::InvalidArgument`] for NaN samples,
/// a non-finite `init`, bad options, images too small for the motion (fewer
/// than `MIN_PIXELS_PER_PARAM` window pixels per parameter at the coarsest
/// level), a channel without texture (constant, or no gradient along some
/// parameter), or a warp that leaves too little overlap.
pub fn refine<T: Sample>(
    reference: &ImageView<'_, T>,
    moving: &ImageView<'_, T>,
    motion: Motion,
    init: &Matrix,
    opts: &EccOptions,
) -> Result<Refined> {
    super::same_size(reference, moving, ("reference", "moving"))?;
    check_options(init, opts)?;
    let (w, h) = (reference.width(), reference.height());
    let levels = opts.levels.unwrap_or_else(|| {
        let mut n = 0;
        while w.min(h) >> (n + 1) >= MIN_LEVEL_SIDE {
            n += 1;
        }
        n
    });
    let need = MIN_PIXELS_PER_PARAM * motion.params();
    let coarsest = Window::cropped(w >> levels, h >> levels, opts.crop);
    let area = coarsest.y1.saturating_sub(coarsest.y0) * coarsest.x1.saturating_sub(coarsest.x0);
    if w >> levels < 2 || h >> levels < 2 || area < need {
        return Err(invalid!(
            "images of {h}x{w} are too small for a {motion:?} motion with crop={} and {levels} \
             pyramid levels: the coarsest window has {area} pixels, {need} are needed ({} per \
             parameter)",
            opts.crop,
            MIN_PIXELS_PER_PARAM
        ));
    }
    let mut refs = vec![Plane::from_rows(&Converted::new(reference, "reference")?)];
    let mut movs = vec![Plane::from_rows(&Converted::new(moving, "moving")?)];
    for _ in 0..levels {
        refs.push(Plane::downsample(refs.last().expect("level 0 exists")));
        movs.push(Plane::downsample(movs.last().expect("level 0 exists")));
    }
    let mut matrix = *init;
    let mut iterations = Vec::with_capacity(levels + 1);
    let (mut score, mut converged) = (f64::NAN, false);
    for l in (0..=levels).rev() {
        let (r, m) = (&refs[l], Packed::new(&movs[l]));
        let level = Level {
            reference: r,
            moving: &m,
            window: Window::cropped(r.width, r.height, opts.crop),
            centre: (0.5 * (r.width as f64 - 1.0), 0.5 * (r.height as f64 - 1.0)),
        };
        let tolerance = opts.tolerance / (1u64 << l) as f64;
        let (warp, took, rho, done) = iterate(
            &level,
            Centred::from_matrix(motion, &to_level(&matrix, l), level.centre),
            opts.max_iterations,
            tolerance,
            l,
        )?;
        matrix = from_level(&warp.matrix(level.centre), l);
        iterations.push(took);
        (score, converged) = (rho, done);
    }
    Ok(Refined {
        matrix,
        score,
        iterations,
        converged,
    })
}

/// Gauss-Newton steps on one level until a step moves no corner by more
/// than `tolerance`: the warp, the steps taken, the final ECC and whether it
/// converged.
fn iterate(
    level: &Level<'_>,
    mut warp: Centred,
    max_iterations: usize,
    tolerance: f64,
    index: usize,
) -> Result<(Centred, usize, f64, bool)> {
    let n = warp.motion.params();
    let win = level.window;
    let half = (
        0.5 * (win.x1 - win.x0) as f64,
        0.5 * (win.y1 - win.y0) as f64,
    );
    let need = (MIN_PIXELS_PER_PARAM * n) as f64;
    // The ECC of the last sums: the warp before a step that moved it by at
    // most `tolerance` once converged.
    let mut score = f64::NAN;
    for it in 0..max_iterations {
        let s = level.sums(&warp);
        if s.n < need {
            return Err(invalid!(
                "the warp leaves {} of the window's pixels inside the moving image at pyramid \
                 level {index} ({} needed): the motion is beyond what can be estimated",
                s.n,
                need
            ));
        }
        let (rho, delta) = step(&s, n);
        score = rho;
        let delta = delta.map_err(|stall| {
            let why = match stall {
                Stall::Flat => "a channel is constant or has no texture along some parameter",
                Stall::Mismatch => "the channels do not match (a step would lower the correlation)",
            };
            invalid!(
                "cannot estimate a {:?} motion at pyramid level {index}: {why} (ECC {rho:.3})",
                warp.motion
            )
        })?;
        let before = warp;
        for (p, d) in warp.p.iter_mut().zip(&delta) {
            *p += d;
        }
        if displacement(&before, &warp, half) <= tolerance {
            return Ok((warp, it + 1, score, true));
        }
    }
    Ok((warp, max_iterations, score, false))
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
        }
    }

    fn similarity(angle: f64, scale: f64, tx: f64, ty: f64) -> Matrix {
        let (s, c) = (scale * angle.sin(), scale * angle.cos());
        [[c, -s, tx], [s, c, ty]]
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
            let err = got
                .matrix
                .iter()
                .flatten()
                .zip(truth.iter().flatten())
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
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
    fn constant_tiny_and_bad_input_is_refused() {
        let flat = vec![0.5f32; 100 * 100];
        let fv = ImageView::contiguous(&flat, 100, 100, 1).unwrap();
        let e = refine(&fv, &fv, Motion::Euclidean, &IDENTITY, &opts())
            .unwrap_err()
            .to_string();
        assert!(e.contains("constant"), "{e}");
        let tiny = warped(12, 12, &IDENTITY);
        let tv = ImageView::contiguous(&tiny, 12, 12, 1).unwrap();
        let e = refine(&tv, &tv, Motion::Affine, &IDENTITY, &opts())
            .unwrap_err()
            .to_string();
        assert!(e.contains("too small"), "{e}");
        let r = warped(100, 100, &IDENTITY);
        let rv = ImageView::contiguous(&r, 100, 100, 1).unwrap();
        let far = [[1.0, 0.0, 95.0], [0.0, 1.0, 95.0]];
        let e = refine(&rv, &rv, Motion::Translation, &far, &opts())
            .unwrap_err()
            .to_string();
        assert!(e.contains("beyond"), "{e}");
        let nan = [[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert!(refine(&rv, &rv, Motion::Translation, &nan, &opts()).is_err());
    }
}

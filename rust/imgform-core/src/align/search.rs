//! Exhaustive scoring of a square of candidate shifts.
//!
//! For a shift `(dy, dx)` the reference pixel `(y, x)` of the crop window is
//! compared with the moving pixel `(y - dy, x - dx)` (where `np.roll(moving,
//! (dy, dx))` puts it), and only pairs whose moving pixel exists are used: no
//! wrap-around. While the shift is smaller than the crop margin every
//! candidate sees the whole window, so all scores are over the same pixels.
//!
//! Work is split into tasks of one candidate row `dy` times one band of
//! [`BAND_ROWS`] image rows. Inside a task each image row is loaded once and
//! compared at every `dx` while it sits in L1 cache: the whole candidate row
//! costs one pass over memory instead of `2r + 1`. The sums of `a`, `a^2`,
//! `b`, `b^2` over each shift's columns come from per-row prefix sums in
//! `f64`, so only the cross term is computed per shift, in `f32` with 16
//! independent accumulators (which the compiler turns into SIMD) and added
//! to an `f64` total once per row. Bands are fixed by the image, not by the
//! thread count, and are summed in order, so the scores are bit-identical
//! for any number of threads.

use rayon::prelude::*;

use super::metric::{Metric, Sums};
use super::pyramid::Plane;

/// Image rows per task. 32 rows of a 3000-pixel plate are ~0.4 MB of both
/// images, small enough to stay in L2 across a candidate row and, at ~100 k
/// multiply-adds per `dx`, far above rayon's per-task cost of a few µs.
const BAND_ROWS: usize = 32;

/// Independent accumulators of the row kernels: enough to fill two 8-lane
/// (or four 4-lane) SIMD registers and hide the add latency.
const LANES: usize = 16;

/// The compared region of the reference: rows `y0..y1`, columns `x0..x1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    pub y0: usize,
    pub y1: usize,
    pub x0: usize,
    pub x1: usize,
}

impl Window {
    /// The window left after cutting `floor(crop * size)` off each border.
    pub fn cropped(width: usize, height: usize, crop: f64) -> Self {
        let my = (crop * height as f64).floor() as usize;
        let mx = (crop * width as f64).floor() as usize;
        Self {
            y0: my,
            y1: height - my,
            x0: mx,
            x1: width - mx,
        }
    }

    /// Rows (or columns) of the overlap for a shift `d` along an axis whose
    /// window is `lo..hi` and whose image has `size` samples.
    #[inline]
    fn span(lo: usize, hi: usize, size: usize, d: i64) -> (usize, usize) {
        let start = (lo as i64).max(d);
        let end = (hi as i64).min(size as i64 + d);
        (start.max(0) as usize, end.max(start).max(0) as usize)
    }

    /// Pixels along each axis of the smallest overlap over shifts up to
    /// `max_shift` in size: what the search has to compare at worst.
    pub fn worst_overlap(&self, width: usize, height: usize, max_shift: i64) -> (usize, usize) {
        let rows = |d| {
            let (s, e) = Self::span(self.y0, self.y1, height, d);
            e - s
        };
        let cols = |d| {
            let (s, e) = Self::span(self.x0, self.x1, width, d);
            e - s
        };
        (
            rows(max_shift).min(rows(-max_shift)),
            cols(max_shift).min(cols(-max_shift)),
        )
    }
}

/// A square of candidate shifts `center ± radius`, of which only those with
/// both components in `[-limit, limit]` are scored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Candidates {
    pub center: (i64, i64),
    pub radius: i64,
    pub limit: i64,
}

impl Candidates {
    /// Side of the square, `2 radius + 1`.
    pub fn side(&self) -> usize {
        (2 * self.radius + 1) as usize
    }

    /// The in-limit shifts along one axis, with their index in the square.
    fn axis(&self, c: i64) -> impl Iterator<Item = (usize, i64)> + '_ {
        (-self.radius..=self.radius)
            .enumerate()
            .map(move |(i, o)| (i, c + o))
            .filter(|&(_, d)| d.abs() <= self.limit)
    }

    /// The shift of entry `(i, j)` of the square.
    pub fn shift(&self, i: usize, j: usize) -> (i64, i64) {
        (
            self.center.0 - self.radius + i as i64,
            self.center.1 - self.radius + j as i64,
        )
    }
}

/// Scores of every candidate, row-major over the square; NaN for shifts
/// outside the limit or without overlap.
pub fn surface(
    reference: &Plane,
    moving: &Plane,
    metric: Metric,
    window: Window,
    cands: Candidates,
) -> Vec<f64> {
    let side = cands.side();
    let dxs: Vec<(usize, i64)> = cands.axis(cands.center.1).collect();
    // One task per (candidate row, band of image rows), in a fixed order.
    let tasks: Vec<(usize, i64, usize, usize)> = cands
        .axis(cands.center.0)
        .flat_map(|(i, dy)| {
            let (ys, ye) = Window::span(window.y0, window.y1, reference.height, dy);
            (ys..ye)
                .step_by(BAND_ROWS)
                .map(move |b| (i, dy, b, (b + BAND_ROWS).min(ye)))
        })
        .collect();
    let partial: Vec<(usize, Vec<Sums>)> = tasks
        .par_iter()
        .map(|&(i, dy, ys, ye)| {
            let band = band_sums(reference, moving, metric, window, dy, ys..ye, &dxs);
            (i, band)
        })
        .collect();
    let mut totals = vec![Sums::default(); side * side];
    for (i, band) in &partial {
        for (&(j, _), s) in dxs.iter().zip(band) {
            totals[i * side + j].add(s);
        }
    }
    totals
        .iter()
        .map(|s| s.score(metric, reference.offset))
        .collect()
}

/// The sums of one candidate row `dy` over image rows `rows`, one entry per
/// shift of `dxs`.
fn band_sums(
    reference: &Plane,
    moving: &Plane,
    metric: Metric,
    window: Window,
    dy: i64,
    rows: std::ops::Range<usize>,
    dxs: &[(usize, i64)],
) -> Vec<Sums> {
    let w = reference.width;
    let spans: Vec<(usize, usize)> = dxs
        .iter()
        .map(|&(_, dx)| Window::span(window.x0, window.x1, w, dx))
        .collect();
    let mut sums = vec![Sums::default(); dxs.len()];
    // SSD accumulates (a - b)^2 directly: no prefix sums needed, and
    // ssd(a, a) is exactly 0 instead of a difference of rounded sums.
    let prefixed = metric != Metric::Ssd;
    let mut pa = Prefix::new(if prefixed { w } else { 0 });
    let mut pb = Prefix::new(if prefixed { w } else { 0 });
    for y in rows {
        let a = reference.row(y);
        let b = moving.row((y as i64 - dy) as usize);
        if prefixed {
            pa.fill(a);
            pb.fill(b);
        }
        for ((&(_, dx), &(xs, xe)), s) in dxs.iter().zip(&spans).zip(sums.iter_mut()) {
            if xe <= xs {
                continue;
            }
            let (ms, me) = ((xs as i64 - dx) as usize, (xe as i64 - dx) as usize);
            let (ar, br) = (&a[xs..xe], &b[ms..me]);
            s.n += (xe - xs) as f64;
            if prefixed {
                s.cross += f64::from(lanes(ar, br, |x, y| x * y));
                (s.sa, s.saa) = pa.add_range(xs, xe, s.sa, s.saa);
                (s.sb, s.sbb) = pb.add_range(ms, me, s.sb, s.sbb);
            } else {
                s.cross += f64::from(lanes(ar, br, |x, y| (x - y) * (x - y)));
            }
        }
    }
    sums
}

/// Prefix sums of a row and of its squares, in `f64`.
struct Prefix {
    s: Vec<f64>,
    ss: Vec<f64>,
}

impl Prefix {
    fn new(width: usize) -> Self {
        Self {
            s: vec![0.0; width + 1],
            ss: vec![0.0; width + 1],
        }
    }

    fn fill(&mut self, row: &[f32]) {
        let (mut s, mut ss) = (0.0f64, 0.0f64);
        for (i, &v) in row.iter().enumerate() {
            let v = f64::from(v);
            s += v;
            ss += v * v;
            self.s[i + 1] = s;
            self.ss[i + 1] = ss;
        }
    }

    /// `(acc_s + sum row[lo..hi], acc_ss + sum row[lo..hi]^2)`.
    #[inline]
    fn add_range(&self, lo: usize, hi: usize, acc_s: f64, acc_ss: f64) -> (f64, f64) {
        (
            acc_s + (self.s[hi] - self.s[lo]),
            acc_ss + (self.ss[hi] - self.ss[lo]),
        )
    }
}

/// `sum f(a[i], b[i])` over [`LANES`] independent accumulators, combined in
/// a fixed order (so the result depends on the data only).
#[inline(always)]
fn lanes(a: &[f32], b: &[f32], f: impl Fn(f32, f32) -> f32) -> f32 {
    let mut acc = [0.0f32; LANES];
    let (ca, cb) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
    let tail: f32 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(&x, &y)| f(x, y))
        .sum();
    for (x, y) in ca.zip(cb) {
        for k in 0..LANES {
            acc[k] += f(x[k], y[k]);
        }
    }
    acc.iter().sum::<f32>() + tail
}

/// The best candidate of a surface: the best score; among equal scores the
/// smallest `dy^2 + dx^2` (do not move without evidence), then the
/// lexicographically smallest `(dy, dx)`. Returns the entry's index.
pub fn best(surface: &[f64], metric: Metric, cands: Candidates) -> Option<usize> {
    let side = cands.side();
    let mut best: Option<usize> = None;
    for (k, &v) in surface.iter().enumerate() {
        if v.is_nan() {
            continue;
        }
        let replace = match best {
            None => true,
            Some(b) => {
                let u = surface[b];
                let key = |k: usize| {
                    let (dy, dx) = cands.shift(k / side, k % side);
                    (dy * dy + dx * dx, dy, dx)
                };
                metric.better(v, u) || (v == u && key(k) < key(b))
            }
        };
        if replace {
            best = Some(k);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(w: usize, h: usize, f: impl Fn(i64, i64) -> f32) -> Plane {
        let data = (0..h as i64)
            .flat_map(|y| (0..w as i64).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y))
            .collect();
        Plane {
            data,
            width: w,
            height: h,
            offset: 0.0,
        }
    }

    /// A smooth, non-periodic pattern.
    fn pattern(x: i64, y: i64) -> f32 {
        let (x, y) = (x as f32, y as f32);
        (0.31 * x + 0.17 * y).sin() + (0.07 * x * y / 9.0).cos() + 0.01 * x
    }

    #[test]
    fn finds_a_known_shift_with_every_metric() {
        let (dy, dx) = (3, -2);
        let r = plane(40, 36, pattern);
        // moving(y, x) = reference(y + dy, x + dx): rolling it by (dy, dx) lands it.
        let m = plane(40, 36, |x, y| pattern(x + dx, y + dy));
        let win = Window::cropped(40, 36, 0.1);
        let c = Candidates {
            center: (0, 0),
            radius: 4,
            limit: 4,
        };
        for metric in [Metric::Ssd, Metric::Cosine, Metric::Ncc] {
            let s = surface(&r, &m, metric, win, c);
            let k = best(&s, metric, c).unwrap();
            assert_eq!(c.shift(k / 9, k % 9), (dy, dx), "{metric:?}");
        }
    }

    #[test]
    fn ties_go_to_the_smallest_shift() {
        let flat = plane(20, 20, |_, _| 1.0);
        let c = Candidates {
            center: (0, 0),
            radius: 2,
            limit: 1,
        };
        let s = surface(&flat, &flat, Metric::Ncc, Window::cropped(20, 20, 0.1), c);
        // Outside the limit: NaN; inside: the defined 0 of a constant patch.
        assert!(s[0].is_nan());
        assert_eq!(s[2 * 5 + 2], 0.0);
        let k = best(&s, Metric::Ncc, c).unwrap();
        assert_eq!(c.shift(k / 5, k % 5), (0, 0));
    }

    #[test]
    fn lanes_matches_a_plain_sum() {
        let a: Vec<f32> = (0..37).map(|i| i as f32).collect();
        let b: Vec<f32> = (0..37).map(|i| (i % 5) as f32).collect();
        let plain: f32 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
        assert_eq!(lanes(&a, &b, |x, y| x * y), plain);
    }

    #[test]
    fn overlap_shrinks_only_beyond_the_margin() {
        let win = Window::cropped(100, 50, 0.1);
        assert_eq!(
            win,
            Window {
                y0: 5,
                y1: 45,
                x0: 10,
                x1: 90
            }
        );
        assert_eq!(win.worst_overlap(100, 50, 5), (40, 80));
        // Shift 20: rows 20..45 of 5..45, columns 20..90 of 10..90.
        assert_eq!(win.worst_overlap(100, 50, 20), (25, 70));
    }
}

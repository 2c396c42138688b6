//! Exhaustive scoring of a square of candidate shifts.
//!
//! For a shift `(dy, dx)` the reference pixel `(y, x)` of the crop window is
//! compared with the moving pixel `(y - dy, x - dx)` (where `np.roll(moving,
//! (dy, dx))` puts it), and only pairs whose moving pixel exists are used: no
//! wrap-around. While the shift is smaller than the crop margin every
//! candidate sees the whole window, so all scores are over the same pixels.
//!
//! Work is split into tasks of one band of [`BAND_ROWS`] reference rows, each
//! scoring every candidate. Inside a task each reference row is loaded once
//! and compared with the moving rows of every `dy` at every `dx` while they
//! sit in cache, so the search costs about one pass over memory, not one per
//! candidate. The sums of `a`, `a^2`, `b`, `b^2` over each shift's columns
//! come from per-row running sums in `f64` (computed once per row and band),
//! so only the cross term is computed per shift, in `f32` with 16
//! independent accumulators (which the compiler turns into SIMD) and added
//! to an `f64` total once per row. Bands are fixed by the image, not by the
//! thread count, and are summed in order, so the scores are bit-identical
//! for any number of threads.

use rayon::prelude::*;

use super::metric::{Metric, Sums};
use super::pyramid::Rows;

/// Reference rows per task. 32 rows (plus `2r` moving rows) of a 3000-pixel
/// plate are ~0.5 MB of samples, small enough to stay in L2
/// while every candidate reads them, and at ~100 k multiply-adds per
/// candidate far above rayon's per-task cost of a few µs. Bands are fixed by
/// the window, never by the thread count.
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
    pub(super) fn span(lo: usize, hi: usize, size: usize, d: i64) -> (usize, usize) {
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
    pub(super) fn axis(&self, c: i64) -> impl Iterator<Item = (usize, i64)> + '_ {
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
pub fn surface<S: Rows>(
    reference: &S,
    moving: &S,
    metric: Metric,
    window: Window,
    cands: Candidates,
) -> Vec<f64> {
    let side = cands.side();
    let dys: Vec<(usize, i64)> = cands.axis(cands.center.0).collect();
    let dxs: Vec<(usize, i64)> = cands.axis(cands.center.1).collect();
    // One task per band of window rows, for every candidate; the bands depend
    // on the window only.
    let bands: Vec<(usize, usize)> = (window.y0..window.y1)
        .step_by(BAND_ROWS)
        .map(|b| (b, (b + BAND_ROWS).min(window.y1)))
        .collect();
    let partial: Vec<Vec<Sums>> = bands
        .par_iter()
        .map(|&(ys, ye)| band_sums(reference, moving, metric, window, ys..ye, &dys, &dxs))
        .collect();
    let mut totals = vec![Sums::default(); side * side];
    for band in &partial {
        for (&(i, _), row) in dys.iter().zip(band.chunks(dxs.len().max(1))) {
            for (&(j, _), s) in dxs.iter().zip(row) {
                totals[i * side + j].add(s);
            }
        }
    }
    totals
        .iter()
        .map(|s| s.score(metric, reference.offset()))
        .collect()
}

/// The sums of every candidate `(dy, dx)` over the reference rows `rows`
/// (those of them that have a moving row for `dy`), `dys.len() x dxs.len()`
/// row-major.
///
/// Each reference row's running sums ([`Breaks`]) are computed once for all
/// candidates, and each moving row's once per band: ~2 passes over the
/// image instead of 2 per candidate row.
fn band_sums<S: Rows>(
    reference: &S,
    moving: &S,
    metric: Metric,
    window: Window,
    rows: std::ops::Range<usize>,
    dys: &[(usize, i64)],
    dxs: &[(usize, i64)],
) -> Vec<Sums> {
    let (w, h) = (reference.width(), reference.height());
    let (spans, moved) = column_spans(window, w, dxs);
    // For each candidate row, the rows of this band that have a moving row.
    let ranges: Vec<(usize, usize)> = dys
        .iter()
        .map(|&(_, dy)| {
            let (s, e) = Window::span(window.y0, window.y1, h, dy);
            let s = s.max(rows.start);
            (s, e.min(rows.end).max(s))
        })
        .collect();
    // The moving rows `y - dy` the band reads.
    let (mut lo, mut hi) = (usize::MAX, 0);
    for (&(_, dy), &(s, e)) in dys.iter().zip(&ranges) {
        if e > s {
            lo = lo.min((s as i64 - dy) as usize);
            hi = hi.max((e as i64 - dy) as usize);
        }
    }
    let mut sums = vec![Sums::default(); dys.len() * dxs.len()];
    if lo >= hi {
        return sums;
    }
    // SSD accumulates (a - b)^2 directly: no running sums needed, and
    // ssd(a, a) is exactly 0 instead of a difference of rounded sums.
    let summed = metric != Metric::Ssd;
    let prows = if summed { hi - lo } else { 0 };
    let mut pa = Breaks::new(spans.iter().copied(), 1);
    let mut pb = Breaks::new(moved.into_iter(), prows);
    // The band's moving rows, converted once; the reference row of the
    // moment in `a`.
    let mut band = vec![0.0f32; (hi - lo) * w];
    for (r, out) in band.chunks_exact_mut(w).enumerate() {
        moving.fill_row(lo + r, out);
        if summed {
            pb.fill(r, out);
        }
    }
    let mut a = vec![0.0f32; w];
    for y in rows {
        reference.fill_row(y, &mut a);
        if summed {
            pa.fill(0, &a);
        }
        for ((&(_, dy), &(s, e)), out) in dys
            .iter()
            .zip(&ranges)
            .zip(sums.chunks_mut(dxs.len().max(1)))
        {
            if y < s || y >= e {
                continue;
            }
            let mrow = (y as i64 - dy) as usize - lo;
            let b = &band[mrow * w..(mrow + 1) * w];
            for (j, ((&(_, dx), &(xs, xe)), s)) in
                dxs.iter().zip(&spans).zip(out.iter_mut()).enumerate()
            {
                if xe <= xs {
                    continue;
                }
                let (ms, me) = ((xs as i64 - dx) as usize, (xe as i64 - dx) as usize);
                let (ar, br) = (&a[xs..xe], &b[ms..me]);
                s.n += (xe - xs) as f64;
                if summed {
                    s.cross += f64::from(lanes(ar, br, |x, y| x * y));
                    let ((ra, raa), (rb, rbb)) = (pa.span(0, j), pb.span(mrow, j));
                    (s.sa, s.saa, s.sb, s.sbb) = (s.sa + ra, s.saa + raa, s.sb + rb, s.sbb + rbb);
                } else {
                    s.cross += f64::from(lanes(ar, br, |x, y| (x - y) * (x - y)));
                }
            }
        }
    }
    sums
}

/// Column ranges `(start, end)`, one per candidate `dx`.
pub(super) type Spans = Vec<(usize, usize)>;

/// For each `dx`, the reference columns of the overlap and the moving
/// columns they meet.
pub(super) fn column_spans(window: Window, width: usize, dxs: &[(usize, i64)]) -> (Spans, Spans) {
    dxs.iter()
        .map(|&(_, dx)| {
            let (s, e) = Window::span(window.x0, window.x1, width, dx);
            ((s, e), ((s as i64 - dx) as usize, (e as i64 - dx) as usize))
        })
        .unzip()
}

/// Running sums of rows (and of their squares) at the few columns where
/// some candidate's span starts or ends.
///
/// A full prefix sum would be a serial chain of `f64` additions per sample;
/// summing only the segments between breakpoints uses independent
/// accumulators (SIMD) and is several times faster, and its sums over a span
/// are exact differences of the same running totals.
pub(super) struct Breaks {
    /// Sorted, distinct breakpoints.
    points: Vec<usize>,
    /// For each span, the indices of its start and end in `points`.
    index: Vec<(usize, usize)>,
    /// Running sums per stored row: `points.len()` pairs `(sum, sum of squares)`.
    cum: Vec<(f64, f64)>,
}

impl Breaks {
    pub(super) fn new(spans: impl Iterator<Item = (usize, usize)> + Clone, rows: usize) -> Self {
        let mut points: Vec<usize> = spans.clone().flat_map(|(s, e)| [s, e]).collect();
        points.sort_unstable();
        points.dedup();
        let at = |x: usize| points.binary_search(&x).unwrap_or(0);
        let index = spans.map(|(s, e)| (at(s), at(e))).collect();
        let cum = vec![(0.0, 0.0); points.len() * rows];
        Self { points, index, cum }
    }

    /// Stores the running sums of `row` as row `r`.
    fn fill(&mut self, r: usize, row: &[f32]) {
        let n = self.points.len();
        running(&self.points, row, &mut self.cum[r * n..(r + 1) * n]);
    }

    /// The breakpoints, and every stored row's running sums to fill (with
    /// [`running`]), `points.len()` pairs a row.
    pub(super) fn rows_mut(&mut self) -> (&[usize], &mut [(f64, f64)]) {
        (&self.points, &mut self.cum)
    }

    /// How many breakpoints, the length of a stored row.
    pub(super) fn len(&self) -> usize {
        self.points.len()
    }

    /// `(sum, sum of squares)` of stored row `r` from the first breakpoint to
    /// the last.
    pub(super) fn whole(&self, r: usize) -> (f64, f64) {
        let n = self.points.len();
        self.cum[(r + 1) * n - 1]
    }

    /// The columns from the first breakpoint to the last.
    pub(super) fn extent(&self) -> usize {
        self.points.last().map_or(0, |&e| e - self.points[0])
    }

    /// `(sum, sum of squares)` of row `r` over span `j`.
    #[inline]
    pub(super) fn span(&self, r: usize, j: usize) -> (f64, f64) {
        let n = self.points.len();
        let (lo, hi) = self.index[j];
        let (a, b) = (self.cum[r * n + lo], self.cum[r * n + hi]);
        (b.0 - a.0, b.1 - a.1)
    }
}

/// Writes the running sums of `row` at each of `points` into `cum` (the
/// first stays `(0, 0)`).
pub(super) fn running(points: &[usize], row: &[f32], cum: &mut [(f64, f64)]) {
    let mut acc = (0.0, 0.0);
    for (k, pair) in points.windows(2).enumerate() {
        let (s, ss) = sums64(&row[pair[0]..pair[1]]);
        acc = (acc.0 + s, acc.1 + ss);
        cum[k + 1] = acc;
    }
}

/// `(sum v, sum v^2)` in `f64` over [`LANES`] independent accumulators.
fn sums64(v: &[f32]) -> (f64, f64) {
    let mut s = [0.0f64; LANES];
    let mut ss = [0.0f64; LANES];
    let chunks = v.chunks_exact(LANES);
    let tail = chunks.remainder();
    for c in chunks {
        for k in 0..LANES {
            let x = f64::from(c[k]);
            s[k] += x;
            ss[k] += x * x;
        }
    }
    let (mut ts, mut tss) = (0.0, 0.0);
    for &x in tail {
        let x = f64::from(x);
        ts += x;
        tss += x * x;
    }
    (s.iter().sum::<f64>() + ts, ss.iter().sum::<f64>() + tss)
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
    use crate::align::pyramid::Plane;

    /// A smooth, non-periodic pattern.
    fn pattern(x: i64, y: i64) -> f32 {
        let (x, y) = (x as f32, y as f32);
        (0.31 * x + 0.17 * y).sin() + (0.07 * x * y / 9.0).cos() + 0.01 * x
    }

    #[test]
    fn finds_a_known_shift_with_every_metric() {
        let (dy, dx) = (3, -2);
        let r = Plane::from_fn(40, 36, pattern);
        // moving(y, x) = reference(y + dy, x + dx): rolling it by (dy, dx) lands it.
        let m = Plane::from_fn(40, 36, |x, y| pattern(x + dx, y + dy));
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
        let flat = Plane::from_fn(20, 20, |_, _| 1.0);
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

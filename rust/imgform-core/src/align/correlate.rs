//! Scores of a wide square of candidate shifts through one correlation by FFT.
//!
//! The direct search ([`super::search`]) spends one multiply-add per window
//! pixel and candidate: 961 of them per pixel for an exhaustive ±15 search.
//! The cross terms of all candidates together are a correlation of the two
//! images, which FFTs give in O(N log N) whatever the number of candidates.
//! Every other sum of a candidate (`n`, `sum a`, `sum a^2`, `sum b`,
//! `sum b^2`) is a sum over a rectangle whose sides are among the few rows and
//! columns where some candidate's overlap starts or ends, read from running
//! sums at those breakpoints ([`Breaks`]) accumulated down the rows.
//!
//! The reference's window goes in the real part of one complex plane and the
//! moving samples any candidate reads in its imaginary part, so one forward
//! transform serves both: their spectra are separated by conjugate symmetry.
//! The plane's sides are long enough that no candidate's lag wraps onto
//! another's samples, so the circular correlation is the exact overlap sum,
//! and only the candidates' lags are transformed back.
//!
//! Everything is in `f64`. Unlike the direct search's sums, which add up one
//! patch's samples, these sums round relative to the whole images' (~1e-16
//! log N of them): fine for any patch with a variance of its own, but a
//! constant patch beside far larger values would get rounding for a
//! variance, and any NCC. So each candidate's sums carry the whole images'
//! sums of squares as the floor under which a variance counts as none
//! ([`Sums::floor`]). Rows and columns are transformed in tasks fixed by the
//! plane's shape, so the scores are the same whatever the number of threads.

use std::sync::Arc;

use rayon::prelude::*;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

use super::metric::{Metric, Sums};
use super::pyramid::Rows;
use super::search::{column_spans, running, Breaks, Candidates, Window};
use crate::aberration::psf::smooth_len;

type C64 = Complex<f64>;

/// What a correlation costs per sample of its plane, in ns on two cores
/// (measured at 1024 x 1024 to 4096 x 4096, crop 0.1): 8.5 while the
/// plane fits [`CACHED_PLANE`] samples (16 MiB), 21 beyond.
const PLANE_NS: (f64, f64) = (8.5, 21.0);
const CACHED_PLANE: usize = 1 << 20;

/// What the direct search costs per window pixel and candidate, in ns on
/// two cores (0.045-0.049 over the same images). The correlation pays from
/// ~200 candidates at 1024 x 1024 and ~500 at 2048 x 2048 and beyond.
const DIRECT_NS: f64 = 0.047;

/// The most memory a correlation takes (512 MiB): the plane and the two
/// images' running sums. Beyond it the direct search, whose memory does
/// not grow with the image, scores instead.
const MAX_BYTES: usize = 1 << 29;

/// Rows or columns of the plane per task: ~30 k samples of work (a
/// transform of ~2 k points each) against rayon's cost of a few µs a task.
const LINES_PER_TASK: usize = 16;

/// One axis of the search.
#[derive(Debug, Clone, Copy)]
struct Axis {
    /// The reference's window, `lo..hi`.
    lo: usize,
    hi: usize,
    /// The moving samples some candidate reads, `m0..m1`.
    m0: usize,
    m1: usize,
    /// The transform's length.
    n: usize,
}

impl Axis {
    /// The axis of an image of `size` samples, window `lo..hi` and the
    /// candidates' shifts `shifts` (ascending).
    fn new(lo: usize, hi: usize, size: usize, shifts: &[(usize, i64)]) -> Self {
        let (dmin, dmax) = (shifts[0].1, shifts[shifts.len() - 1].1);
        let m0 = (lo as i64 - dmax).clamp(0, size as i64) as usize;
        let m1 = (hi as i64 - dmin).clamp(m0 as i64, size as i64) as usize;
        let mut axis = Self {
            lo,
            hi,
            m0,
            m1,
            n: 0,
        };
        // Window sample `u` meets moving sample `u + lag(d)`. A lag that
        // leaves the plane must wrap into its zero padding, never onto a
        // moving sample: n >= window + largest lag, n >= moving - smallest.
        let (lag_lo, lag_hi) = (axis.lag(dmax), axis.lag(dmin));
        let longest = ((hi - lo) as i64 + lag_hi.max(0)).max((m1 - m0) as i64 - lag_lo.min(0));
        axis.n = smooth_len(longest.max(1) as usize);
        axis
    }

    /// The offset from a window sample to the moving sample it meets at
    /// shift `d`: the reference's `lo + u` meets the moving `lo + u - d`.
    fn lag(&self, d: i64) -> i64 {
        self.lo as i64 - self.m0 as i64 - d
    }

    /// Where the correlation of lag `lag(d)` lands in the transform.
    fn index(&self, d: i64) -> usize {
        self.lag(d).rem_euclid(self.n as i64) as usize
    }

    fn window_len(&self) -> usize {
        self.hi - self.lo
    }

    fn moving_len(&self) -> usize {
        self.m1 - self.m0
    }
}

/// Sums of an image and of its squares over rectangles: any run of stored
/// rows, and one of the column spans of a [`Breaks`].
struct Rectangles {
    /// Its stored rows turned into running sums down the image: row `r`
    /// holds the sums over rows `0..=r`.
    breaks: Breaks,
    rows: usize,
}

impl Rectangles {
    /// Accumulates the first `rows` rows of `breaks` (filled) down the image.
    fn new(mut breaks: Breaks, rows: usize) -> Self {
        let n = breaks.len();
        let (_, cum) = breaks.rows_mut();
        for r in 1..rows {
            let (above, here) = cum.split_at_mut(r * n);
            for (h, a) in here[..n].iter_mut().zip(&above[(r - 1) * n..]) {
                *h = (h.0 + a.0, h.1 + a.1);
            }
        }
        Self { breaks, rows }
    }

    /// `(sum, sum of squares)` over stored rows `r0..r1` and span `j`.
    fn sum(&self, r0: usize, r1: usize, j: usize) -> (f64, f64) {
        let upto = |r: usize| match r {
            0 => (0.0, 0.0),
            _ => self.breaks.span(r - 1, j),
        };
        let (a, b) = (upto(r1), upto(r0));
        (a.0 - b.0, a.1 - b.1)
    }

    /// `(n, sum, sum of squares)` over every stored row and column: what
    /// the rounding of every rectangle's sums, and of the correlation, is
    /// relative to.
    fn total(&self) -> (f64, f64, f64) {
        let (s, ss) = match self.rows {
            0 => (0.0, 0.0),
            r => self.breaks.whole(r - 1),
        };
        ((self.rows * self.breaks.extent()) as f64, s, ss)
    }
}

/// The search's two axes: the in-limit shifts along each, and their [`Axis`].
struct Search {
    dys: Vec<(usize, i64)>,
    dxs: Vec<(usize, i64)>,
    ay: Axis,
    ax: Axis,
}

impl Search {
    /// `None` when no candidate is within the limit.
    fn new(window: Window, cands: Candidates, width: usize, height: usize) -> Option<Self> {
        let dys: Vec<(usize, i64)> = cands.axis(cands.center.0).collect();
        let dxs: Vec<(usize, i64)> = cands.axis(cands.center.1).collect();
        if dys.is_empty() || dxs.is_empty() {
            return None;
        }
        let ay = Axis::new(window.y0, window.y1, height, &dys);
        let ax = Axis::new(window.x0, window.x1, width, &dxs);
        Some(Self { dys, dxs, ay, ax })
    }
}

/// Whether [`surface`] is the faster way to score `cands` on an image of
/// `width x height` ([`PLANE_NS`] against [`DIRECT_NS`]), within
/// [`MAX_BYTES`].
pub fn pays(window: Window, cands: Candidates, width: usize, height: usize) -> bool {
    let Some(s) = Search::new(window, cands, width, height) else {
        return false;
    };
    let plane = s.ay.n.saturating_mul(s.ax.n);
    let area = s.ay.window_len() * s.ax.window_len();
    let per_sample = if plane <= CACHED_PLANE {
        PLANE_NS.0
    } else {
        PLANE_NS.1
    };
    let direct = (s.dys.len() * s.dxs.len()) as f64 * area as f64 * DIRECT_NS;
    // Each image's running sums: a pair a row at up to two breakpoints a shift.
    let sums = 2 * s.ay.window_len().max(s.ay.moving_len()) * (2 * s.dxs.len()) * 16;
    let bytes = plane.saturating_mul(16).saturating_add(sums);
    plane as f64 * per_sample < direct && bytes <= MAX_BYTES
}

/// Scores of every candidate, row-major over the square; NaN for shifts
/// outside the limit or without overlap. The same sums as
/// [`super::search::surface`], so the same scores up to rounding.
pub fn surface<S: Rows>(
    reference: &S,
    moving: &S,
    metric: Metric,
    window: Window,
    cands: Candidates,
) -> Vec<f64> {
    let side = cands.side();
    let mut scores = vec![f64::NAN; side * side];
    let (w, h) = (reference.width(), reference.height());
    let Some(Search { dys, dxs, ay, ax }) = Search::new(window, cands, w, h) else {
        return scores;
    };
    let (plane, ref_sums, mov_sums) = transformed(reference, moving, ay, ax, &dxs);
    let cross = correlation(&plane, ay, ax, &dys, &dxs);
    // The rounding of every sum below is relative to the whole images', so
    // a patch is constant when its variance is rounding next to theirs.
    let floor = |(n, sa, saa): (f64, f64, f64)| {
        let total = Sums {
            n,
            sa,
            saa,
            ..Sums::default()
        };
        total.squares(metric, reference.offset()).0
    };
    let (fa, fb) = (floor(ref_sums.total()), floor(mov_sums.total()));
    for (a, &(i, dy)) in dys.iter().enumerate() {
        let (r0, r1) = Window::span(ay.lo, ay.hi, h, dy);
        for (b, &(j, dx)) in dxs.iter().enumerate() {
            let (c0, c1) = Window::span(ax.lo, ax.hi, w, dx);
            if r1 <= r0 || c1 <= c0 {
                continue;
            }
            let n = ((r1 - r0) * (c1 - c0)) as f64;
            let (sa, saa) = ref_sums.sum(r0 - ay.lo, r1 - ay.lo, b);
            let m0 = (r0 as i64 - dy) as usize - ay.m0;
            let (sb, sbb) = mov_sums.sum(m0, m0 + (r1 - r0), b);
            let sums = Sums {
                n,
                sa,
                sb,
                saa,
                sbb,
                cross: cross[a * dxs.len() + b],
                floor: (fa, fb),
            };
            scores[i * side + j] = sums.score(metric, reference.offset());
        }
    }
    scores
}

/// The plane transformed along its rows (row-major, `ay.n` rows of `ax.n`),
/// and the rectangle sums of the window and of the moving samples, all from
/// one pass over the images' rows.
fn transformed<S: Rows>(
    reference: &S,
    moving: &S,
    ay: Axis,
    ax: Axis,
    dxs: &[(usize, i64)],
) -> (Vec<C64>, Rectangles, Rectangles) {
    let w = reference.width();
    let window = Window {
        y0: ay.lo,
        y1: ay.hi,
        x0: ax.lo,
        x1: ax.hi,
    };
    let (spans, moved) = column_spans(window, w, dxs);
    // Both images' running sums get a row for every plane row read, so that
    // one task's rows of the plane and of both sums are chunks of one size.
    let rows = ay.window_len().max(ay.moving_len());
    let mut ra = Breaks::new(spans.into_iter(), rows);
    let mut rb = Breaks::new(moved.into_iter(), rows);
    let mut plane = vec![C64::default(); ay.n * ax.n];
    let fft = FftPlanner::new().plan_fft_forward(ax.n);
    let (pa, ca) = ra.rows_mut();
    let (pb, cb) = rb.rows_mut();
    let task = LINES_PER_TASK;
    // Rows past both images stay zero, and so does their transform.
    plane[..rows * ax.n]
        .par_chunks_mut(ax.n * task)
        .zip(ca.par_chunks_mut(pa.len() * task))
        .zip(cb.par_chunks_mut(pb.len() * task))
        .enumerate()
        .for_each_init(
            || (vec![0.0f32; w], scratch(&fft)),
            |(row, work), (t, ((lines, ca), cb))| {
                for (k, line) in lines.chunks_exact_mut(ax.n).enumerate() {
                    let u = t * task + k;
                    if u < ay.window_len() {
                        reference.fill_row(ay.lo + u, row);
                        for (z, &v) in line.iter_mut().zip(&row[ax.lo..ax.hi]) {
                            z.re = f64::from(v);
                        }
                        running(pa, row, &mut ca[k * pa.len()..(k + 1) * pa.len()]);
                    }
                    if u < ay.moving_len() {
                        moving.fill_row(ay.m0 + u, row);
                        for (z, &v) in line.iter_mut().zip(&row[ax.m0..ax.m1]) {
                            z.im = f64::from(v);
                        }
                        running(pb, row, &mut cb[k * pb.len()..(k + 1) * pb.len()]);
                    }
                }
                fft.process_with_scratch(lines, work);
            },
        );
    let ref_sums = Rectangles::new(ra, ay.window_len());
    let mov_sums = Rectangles::new(rb, ay.moving_len());
    (plane, ref_sums, mov_sums)
}

/// The cross terms `sum a b` of every candidate, `dys.len() x dxs.len()`
/// row-major, from the plane transformed along its rows.
///
/// The correlation's spectrum is `conj(A) B`, with `A` and `B` the real and
/// imaginary parts' spectra, `(Z(k) +- conj(Z(-k))) / 2`. It is Hermitian,
/// so only the columns up to the middle are needed: each task copies a band
/// of them and their mirror columns out of the plane, transforms them along
/// y, forms the correlation's spectrum and transforms it back along y,
/// keeping the candidates' rows. Those rows are then transformed back along
/// x, the columns past the middle being the conjugates of their mirrors.
fn correlation(
    plane: &[C64],
    ay: Axis,
    ax: Axis,
    dys: &[(usize, i64)],
    dxs: &[(usize, i64)],
) -> Vec<f64> {
    let (ny, nx) = (ay.n, ax.n);
    let rows: Vec<usize> = dys.iter().map(|&(_, dy)| ay.index(dy)).collect();
    let (fwd_y, inv_y) = {
        let mut planner = FftPlanner::new();
        (planner.plan_fft_forward(ny), planner.plan_fft_inverse(ny))
    };
    let bands: Vec<usize> = (0..=nx / 2).step_by(LINES_PER_TASK).collect();
    // For each kept column (0..=nx/2), the candidates' rows.
    let half: Vec<C64> = bands
        .par_iter()
        .map_init(
            || {
                let work = fwd_y
                    .get_inplace_scratch_len()
                    .max(inv_y.get_inplace_scratch_len());
                let cols = vec![C64::default(); 2 * LINES_PER_TASK * ny];
                (cols, vec![C64::default(); work])
            },
            |(cols, work), &k0| {
                let k1 = (k0 + LINES_PER_TASK).min(nx / 2 + 1);
                let (own, mirror) = cols.split_at_mut(LINES_PER_TASK * ny);
                let (own, mirror) = (&mut own[..(k1 - k0) * ny], &mut mirror[..(k1 - k0) * ny]);
                for (y, line) in plane.chunks_exact(nx).enumerate() {
                    for kx in k0..k1 {
                        own[(kx - k0) * ny + y] = line[kx];
                        mirror[(kx - k0) * ny + y] = line[(nx - kx) % nx];
                    }
                }
                fwd_y.process_with_scratch(own, work);
                fwd_y.process_with_scratch(mirror, work);
                let mut kept = Vec::with_capacity((k1 - k0) * rows.len());
                for (col, mcol) in own.chunks_exact_mut(ny).zip(mirror.chunks_exact(ny)) {
                    for (ky, c) in col.iter_mut().enumerate() {
                        let m = mcol[(ny - ky) % ny].conj();
                        let (a, b) = ((*c + m) * 0.5, (*c - m) * C64::new(0.0, -0.5));
                        *c = a.conj() * b;
                    }
                    inv_y.process_with_scratch(col, work);
                    kept.extend(rows.iter().map(|&r| col[r]));
                }
                kept
            },
        )
        .flatten_iter()
        .collect();
    let inv_x = FftPlanner::new().plan_fft_inverse(nx);
    let scale = 1.0 / (ny * nx) as f64;
    let n = rows.len();
    (0..n)
        .into_par_iter()
        .flat_map_iter(|r| {
            let mut line: Vec<C64> = (0..nx)
                .map(|kx| {
                    if kx <= nx / 2 {
                        half[kx * n + r]
                    } else {
                        half[(nx - kx) * n + r].conj()
                    }
                })
                .collect();
            inv_x.process(&mut line);
            dxs.iter()
                .map(move |&(_, dx)| line[ax.index(dx)].re * scale)
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Working memory for one task's transforms.
fn scratch(fft: &Arc<dyn Fft<f64>>) -> Vec<C64> {
    vec![C64::default(); fft.get_inplace_scratch_len()]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::align::pyramid::Plane;
    use crate::align::search;

    /// A non-periodic pattern with fine detail.
    fn pattern(x: i64, y: i64) -> f32 {
        let (x, y) = (x as f32, y as f32);
        (0.31 * x + 0.17 * y).sin() + (0.07 * x * y / 9.0).cos() + 0.01 * x + 0.3 * (1.7 * x).sin()
    }

    /// Every score agrees with the direct search's, whatever the overlap:
    /// shifts inside the crop margin, beyond it, and with no overlap at all.
    #[test]
    fn scores_match_the_direct_search() {
        let r = Plane::from_fn(53, 41, pattern);
        let m = Plane::from_fn(53, 41, |x, y| pattern(x - 4, y + 3) + 0.05);
        for (crop, center, radius, limit) in [
            (0.1, (0, 0), 6, 6),
            (0.0, (0, 0), 9, 9),
            (0.2, (-3, 4), 5, 7),
            (0.0, (0, 0), 45, 45),
        ] {
            let win = Window::cropped(53, 41, crop);
            let c = Candidates {
                center,
                radius,
                limit,
            };
            for metric in [Metric::Cosine, Metric::Ncc] {
                let (fast, direct) = (
                    surface(&r, &m, metric, win, c),
                    search::surface(&r, &m, metric, win, c),
                );
                for (k, (a, b)) in fast.iter().zip(&direct).enumerate() {
                    let same = (a.is_nan() && b.is_nan()) || (a - b).abs() < 1e-6;
                    assert!(same, "{metric:?} {crop} {center:?} at {k}: {a} vs {b}");
                }
            }
        }
    }

    /// A constant overlap scores NCC's defined 0 however large the rest of
    /// the image: its sums of squares (1e10 a sample) are rounding next to
    /// the textured rows' (~1e23), and scored anything up to 1 while only
    /// the patch's own sums served as the floor.
    #[test]
    fn a_constant_overlap_scores_zero_beside_huge_values() {
        let rough = |x: i64, y: i64| ((x * 7919 + y * 104_729) % 1000) as f32 * 1e9 - 5e11;
        let r = Plane::from_fn(60, 40, |x, y| if y < 4 { rough(x, y) } else { 1e5 });
        let m = Plane::from_fn(60, 40, pattern);
        let win = Window::cropped(60, 40, 0.0);
        let c = Candidates {
            center: (0, 0),
            radius: 15,
            limit: 15,
        };
        let s = surface(&r, &m, Metric::Ncc, win, c);
        // From dy = 4 on, the reference rows compared are all flat.
        for (k, &v) in s.iter().enumerate().skip((15 + 4) * 31) {
            assert_eq!(v, 0.0, "{:?}", c.shift(k / 31, k % 31));
        }
        assert!(s[..(15 + 4) * 31].iter().any(|&v| v != 0.0));
    }

    #[test]
    fn lags_never_wrap_onto_samples() {
        let shifts: Vec<(usize, i64)> = (0..11).map(|i| (i, i as i64 - 5)).collect();
        let a = Axis::new(2, 18, 20, &shifts);
        assert_eq!((a.m0, a.m1), (0, 20));
        // Window 16 + largest lag 7 = moving 20 - smallest lag -3 = 23,
        // rounded up to a length of factors 2, 3 and 5.
        assert_eq!(a.n, 24, "{a:?}");
        assert_eq!((a.lag(5), a.lag(-5)), (-3, 7));
    }
}

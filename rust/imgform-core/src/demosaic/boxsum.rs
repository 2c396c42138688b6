//! Window sums along a row or across the rows of a ring, the building
//! block of guided filters.
//!
//! Every sum is a tree of additions that a mirror maps onto itself: the
//! samples at `-k` and `+k` are added first, or two groups that are each
//! other's mirror image. Addition is commutative in IEEE arithmetic, so a
//! mirrored image gives bit-identical mirrored sums: a running sum (add
//! the entering sample, subtract the leaving one) is cheaper per tap but
//! depends on the scan direction, which would break the exact flip
//! symmetry between Bayer phases that the tests check.
//!
//! Sums come in three parities along a line through a site: every sample
//! within `radius` (`All`), only those an even number of steps away
//! (`Same`: the site's own CFA class along that line) or an odd number
//! (`Other`: the neighbouring class). Guided filters over sparse CFA
//! samples need the class sums; their coefficients then need the full box.

use super::select;

/// Which samples of a window a sum keeps, by their distance to the centre.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Parity {
    /// Every distance `0 ..= radius`.
    All,
    /// Even distances: the centre's CFA class along the line.
    Same,
    /// Odd distances: the other CFA class along the line.
    Other,
}

impl Parity {
    /// The number of samples kept by a window of `radius` on one line.
    pub(super) fn count(self, radius: usize) -> usize {
        match self {
            Parity::All => 2 * radius + 1,
            Parity::Same => 2 * (radius / 2) + 1,
            Parity::Other => 2 * radius.div_ceil(2),
        }
    }

    /// The distances kept, nearest first (the centre, 0, is not listed).
    fn steps(self, radius: usize) -> impl Iterator<Item = usize> {
        let (first, step) = match self {
            Parity::All => (1, 1),
            Parity::Same => (2, 2),
            Parity::Other => (1, 2),
        };
        (first..=radius).step_by(step)
    }
}

/// `out[i]` = the sum of `src` around index `at + i`, over the samples
/// `k * step` away for the distances `k <= radius` that `parity` keeps
/// (`step` 1 along a row).
///
/// `src` must hold `radius * step` values beyond both ends.
#[inline(always)]
pub(super) fn window_sum(
    src: &[f32],
    at: usize,
    step: usize,
    out: &mut [f32],
    radius: usize,
    parity: Parity,
) {
    let n = out.len();
    let view = |d: isize| {
        let start = (at as isize + d * step as isize) as usize;
        &src[start..start + n]
    };
    window_sum_by(view, out, radius, parity);
}

/// [`window_sum`] over any layout: `view(d)` gives the samples `d` steps
/// from the centres (at least `out.len()` of them), whether they lie along
/// a row or in the rows of a ring.
///
/// The plain window sum: the reference the shared-sum versions are tested
/// against, and the direction weights' 5x5 box, which gets a loop whose
/// taps are known at compile time (each sum stays in a register).
#[inline(always)]
pub(super) fn window_sum_by<'a>(
    view: impl Fn(isize) -> &'a [f32],
    out: &mut [f32],
    radius: usize,
    parity: Parity,
) {
    match (parity, radius) {
        (Parity::All, 1) => taps(&view, out, [1]),
        (Parity::All, 2) => taps(&view, out, [1, 2]),
        _ => {
            let n = out.len();
            if parity == Parity::Other {
                out.fill(0.0);
            } else {
                out.copy_from_slice(&view(0)[..n]);
            }
            for k in parity.steps(radius) {
                let (a, b) = (&view(-(k as isize))[..n], &view(k as isize)[..n]);
                for ((o, a), b) in out.iter_mut().zip(a).zip(b) {
                    *o += a + b;
                }
            }
        }
    }
}

/// [`window_sum_by`] over the centre and the mirrored pairs at `dist`
/// (nearest first): the pairs are added in order, then the centre, so a
/// mirrored line gives the same bits.
#[inline(always)]
fn taps<'a, const K: usize>(view: &impl Fn(isize) -> &'a [f32], out: &mut [f32], dist: [usize; K]) {
    let n = out.len();
    let left = dist.map(|d| &view(-(d as isize))[..n]);
    let right = dist.map(|d| &view(d as isize)[..n]);
    let mid = &view(0)[..n];
    for i in 0..n {
        let mut s = left[0][i] + right[0][i];
        for k in 1..K {
            s += left[k][i] + right[k][i];
        }
        out[i] = mid[i] + s;
    }
}

/// The samples of a line that the windows of radius 5 around its `n`
/// sites from `at` on read: `n + 10` of them, from `at - 5` on.
#[inline(always)]
pub(super) fn line_taps(src: &[f32], at: usize, n: usize) -> &[f32] {
    &src[at - 5..at + n + 5]
}

/// The same-class and other-class sums of radius 5 along a line at site
/// `i` of a line cut by [`line_taps`]: with the pair sums `q(y) = v(y) +
/// v(y + 2)` of neighbours of one class, `same(x) = v(x) + (q(x - 4) +
/// q(x + 2))` and `other(x) = q(x - 1) + (q(x - 5) + q(x + 3))`. Each inner
/// sum adds a pair that a mirror swaps, so a mirrored line gives the same
/// bits, and the versions across rows ([`class_sums_across_at`]) the bits of
/// this one. Taken in the loop that uses them: a row is in the first-level
/// cache, where 11 loads cost less than a pass storing the pairs.
#[inline(always)]
pub(super) fn class_sums_at(t: &[f32], i: usize) -> (f32, f32) {
    let t = &t[i..i + 11];
    let same = t[5] + ((t[1] + t[3]) + (t[7] + t[9]));
    let other = (t[4] + t[6]) + ((t[0] + t[2]) + (t[8] + t[10]));
    (same, other)
}

/// The 11-sample sum at site `i` of a line cut by [`line_taps`], with the
/// quadruple sums `f(y) = (v(y) + v(y + 1)) + (v(y + 2) + v(y + 3))`:
/// `(v(x) + (v(x - 1) + v(x + 1))) + (f(x - 5) + f(x + 2))`, mirror
/// symmetric as [`class_sums_at`] is, and the bits of [`all_sums_across`].
#[inline(always)]
pub(super) fn all_sums_at(t: &[f32], i: usize) -> f32 {
    let t = &t[i..i + 11];
    let (left, right) = (
        (t[0] + t[1]) + (t[2] + t[3]),
        (t[7] + t[8]) + (t[9] + t[10]),
    );
    (t[5] + (t[4] + t[6])) + (left + right)
}

/// One row of the pair sums `q(y) = s(y) + s(y + 2)` that [`class_sums_at`]
/// shares between sites, from the rows `s(y)` and `s(y + 2)`: a method
/// streaming down its rows keeps them in a ring for [`class_sums_across_at`].
#[inline(always)]
pub(super) fn pair_row(a: &[f32], b: &[f32], q: &mut [f32]) {
    for ((q, a), b) in q.iter_mut().zip(a).zip(b) {
        *q = a + b;
    }
}

/// The rows [`class_sums_across_at`] reads for the centre row `s`: `s`
/// and the [`pair_row`]s `q(d)` of the rows `d` from it (4 and 2 for the
/// same class, 1, 5 and 3 for the other), `n` long.
#[inline(always)]
pub(super) fn pair_taps<'a>(
    s: &'a [f32],
    q: impl Fn(isize) -> &'a [f32],
    n: usize,
) -> [&'a [f32]; 6] {
    [
        &s[..n],
        &q(-4)[..n],
        &q(2)[..n],
        &q(-1)[..n],
        &q(-5)[..n],
        &q(3)[..n],
    ]
}

/// [`class_sums_at`] across rows at column `i` of rows cut by
/// [`pair_taps`]: the same groups added in the same order, so a column
/// gives the bits it gives as a line. Taken in the loop that uses them, as
/// along a row: stored first, they cost a pass and a reload.
#[inline(always)]
pub(super) fn class_sums_across_at(t: &[&[f32]; 6], i: usize) -> (f32, f32) {
    let [s, left, right, mid, far_left, far_right] = t;
    (
        s[i] + (left[i] + right[i]),
        mid[i] + (far_left[i] + far_right[i]),
    )
}

/// [`class_sums_across_at`] over a row, keeping one class per column: the
/// same-class sum where `m` is set, the other-class sum elsewhere. A square
/// window over the samples of one CFA class reads one class of rows in one
/// class of columns, so it needs no more.
#[inline(always)]
pub(super) fn class_sum_across_by_column<'a>(
    s: &'a [f32],
    q: impl Fn(isize) -> &'a [f32],
    m: &[u32],
    out: &mut [f32],
) {
    let n = out.len();
    let (t, m) = (pair_taps(s, q, n), &m[..n]);
    for i in 0..n {
        let (same, other) = class_sums_across_at(&t, i);
        out[i] = select(m[i], same, other);
    }
}

/// One row of the quadruple sums `f(y) = (s(y) + s(y + 1)) + (s(y + 2) +
/// s(y + 3))` of [`all_sums_at`], from the rows `s(y + d)`.
#[inline(always)]
pub(super) fn quad_row<'a>(s: impl Fn(isize) -> &'a [f32], f: &mut [f32]) {
    let n = f.len();
    let s = [0, 1, 2, 3].map(|d| &s(d)[..n]);
    for (i, f) in f.iter_mut().enumerate() {
        *f = (s[0][i] + s[1][i]) + (s[2][i] + s[3][i]);
    }
}

/// The rows [`all_sums_across_at`] reads: the rows `s(d)` 0, -1 and 1
/// from the centre and the [`quad_row`]s `f(d)` -5 and 2, `n` long.
#[inline(always)]
pub(super) fn quad_taps<'a>(
    s: impl Fn(isize) -> &'a [f32],
    f: impl Fn(isize) -> &'a [f32],
    n: usize,
) -> [&'a [f32]; 5] {
    [&s(0)[..n], &s(-1)[..n], &s(1)[..n], &f(-5)[..n], &f(2)[..n]]
}

/// [`all_sums_at`] across rows at column `i` of rows cut by [`quad_taps`]
/// (see [`class_sums_across_at`]).
#[inline(always)]
pub(super) fn all_sums_across_at(t: &[&[f32]; 5], i: usize) -> f32 {
    let [c, l, r, fl, fr] = t;
    (c[i] + (l[i] + r[i])) + (fl[i] + fr[i])
}

/// [`all_sums_across_at`] over a row, into `out`.
#[inline(always)]
pub(super) fn all_sums_across<'a>(
    s: impl Fn(isize) -> &'a [f32],
    f: impl Fn(isize) -> &'a [f32],
    out: &mut [f32],
) {
    let t = quad_taps(s, f, out.len());
    for (i, o) in out.iter_mut().enumerate() {
        *o = all_sums_across_at(&t, i);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`class_sums_at`] over the `n` sites of a line from `at` on.
    fn class_sums(src: &[f32], at: usize, n: usize) -> (Vec<f32>, Vec<f32>) {
        let t = line_taps(src, at, n);
        (0..n).map(|i| class_sums_at(t, i)).unzip()
    }

    /// [`all_sums_at`] over the `n` sites of a line from `at` on.
    fn all_sums(src: &[f32], at: usize, n: usize) -> Vec<f32> {
        let t = line_taps(src, at, n);
        (0..n).map(|i| all_sums_at(t, i)).collect()
    }

    /// A plane of distinct, irregular values.
    fn plane(len: usize) -> Vec<f32> {
        (0..len)
            .map(|i| ((i * 37 + 11) % 23) as f32 - 7.0)
            .collect()
    }

    /// Values whose sums round differently in different orders.
    fn rounding(len: usize) -> Vec<f32> {
        (0..len)
            .map(|i| 1.0 / (1.0 + (i % 29) as f32 * 0.37).powi(3) + (i % 7) as f32 * 1e3)
            .collect()
    }

    #[test]
    fn counts_match_the_kept_distances() {
        for r in 0..8 {
            for p in [Parity::All, Parity::Same, Parity::Other] {
                let centre = usize::from(p != Parity::Other);
                assert_eq!(p.count(r), centre + 2 * p.steps(r).count(), "{p:?} {r}");
            }
        }
        assert_eq!(Parity::Same.count(5), 5);
        assert_eq!(Parity::Other.count(5), 6);
        assert_eq!(Parity::Other.count(3), 4);
    }

    #[test]
    fn window_sums_match_a_direct_sum() {
        let (w, h) = (17, 13);
        let src = plane(w * h);
        for (step, parity, r) in [
            (1, Parity::Other, 3),
            (w, Parity::Same, 3),
            (1, Parity::All, 1),
            (w, Parity::All, 5),
            (w, Parity::Other, 5),
        ] {
            let at = 6 * w + 6;
            let mut out = vec![f32::NAN; 4];
            window_sum(&src, at, step, &mut out, r, parity);
            for (i, got) in out.iter().enumerate() {
                let want: f32 = (-(r as isize)..=r as isize)
                    .filter(|k| match parity {
                        Parity::All => true,
                        Parity::Same => k % 2 == 0,
                        Parity::Other => k % 2 != 0,
                    })
                    .map(|k| src[((at + i) as isize + k * step as isize) as usize])
                    .sum();
                assert_eq!(*got, want, "{step} {parity:?} {r} at {i}");
            }
        }
    }

    #[test]
    fn class_sums_match_the_window_sums() {
        let src = plane(64);
        let (same, other) = class_sums(&src, 8, 40);
        let (mut want_same, mut want_other) = (vec![0.0; 40], vec![0.0; 40]);
        window_sum(&src, 8, 1, &mut want_same, 5, Parity::Same);
        window_sum(&src, 8, 1, &mut want_other, 5, Parity::Other);
        // Small integers: every order of addition gives the same sums.
        assert_eq!(same, want_same);
        assert_eq!(other, want_other);
    }

    #[test]
    fn all_sums_match_the_window_sum() {
        let src = plane(64);
        let out = all_sums(&src, 8, 40);
        let mut want = vec![0.0; 40];
        window_sum(&src, 8, 1, &mut want, 5, Parity::All);
        assert_eq!(out, want);
    }

    #[test]
    fn sums_across_rows_give_the_bits_of_sums_along_a_line() {
        // Column x of a plane, summed across its rows through pair and
        // quadruple rows, against the same column copied out as a line.
        let (w, h) = (5, 31);
        let src = rounding(w * h);
        let row = |y: isize| &src[y as usize * w..][..w];
        let (mut pairs, mut quads) = (vec![0.0; h * w], vec![0.0; h * w]);
        for y in 0..h - 2 {
            pair_row(
                row(y as isize),
                row(y as isize + 2),
                &mut pairs[y * w..][..w],
            );
        }
        for y in 0..h - 3 {
            quad_row(|d| row(y as isize + d), &mut quads[y * w..][..w]);
        }
        let n = h - 10;
        let (mut same, mut other, mut all) = (vec![0.0; n * w], vec![0.0; n * w], vec![0.0; n * w]);
        // Odd columns keep the same class, even ones the other.
        let odd: Vec<u32> = (0..w)
            .map(|x| if x % 2 == 1 { u32::MAX } else { 0 })
            .collect();
        let mut by_column = vec![0.0; n * w];
        for k in 0..n {
            let y = (k + 5) as isize;
            let q = |d: isize| &pairs[(y + d) as usize * w..][..w];
            let f = |d: isize| &quads[(y + d) as usize * w..][..w];
            let t = pair_taps(row(y), q, w);
            for x in 0..w {
                (same[k * w + x], other[k * w + x]) = class_sums_across_at(&t, x);
            }
            class_sum_across_by_column(row(y), q, &odd, &mut by_column[k * w..][..w]);
            all_sums_across(|d| row(y + d), f, &mut all[k * w..][..w]);
        }
        for x in 0..w {
            let line: Vec<f32> = (0..h).map(|y| src[y * w + x]).collect();
            let ((ls, lo), la) = (class_sums(&line, 5, n), all_sums(&line, 5, n));
            for k in 0..n {
                let i = k * w + x;
                assert_eq!(same[i].to_bits(), ls[k].to_bits(), "same ({k}, {x})");
                assert_eq!(other[i].to_bits(), lo[k].to_bits(), "other ({k}, {x})");
                assert_eq!(all[i].to_bits(), la[k].to_bits(), "all ({k}, {x})");
                let kept = if x % 2 == 1 { ls[k] } else { lo[k] };
                assert_eq!(
                    by_column[i].to_bits(),
                    kept.to_bits(),
                    "by column ({k}, {x})"
                );
            }
        }
    }

    #[test]
    fn sums_are_exactly_mirror_symmetric() {
        let w = 21;
        let src = rounding(w);
        let flipped: Vec<f32> = src.iter().rev().copied().collect();
        let n = w - 10;
        for kind in 0..5 {
            let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
            for (src, out) in [(&src, &mut a), (&flipped, &mut b)] {
                match kind {
                    0 => window_sum(src, 5, 1, out, 5, Parity::All),
                    1 => window_sum(src, 5, 1, out, 5, Parity::Other),
                    2 => *out = class_sums(src, 5, n).0,
                    3 => *out = class_sums(src, 5, n).1,
                    _ => *out = all_sums(src, 5, n),
                }
            }
            for x in 0..n {
                assert_eq!(a[x].to_bits(), b[n - 1 - x].to_bits(), "kind {kind} at {x}");
            }
        }
    }
}

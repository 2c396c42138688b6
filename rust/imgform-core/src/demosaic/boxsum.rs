//! Window sums over tile planes, the building block of guided filters.
//!
//! Every sum adds the two samples at `-k` and `+k` first, then accumulates
//! those pairs from the centre outwards. Addition is commutative in IEEE
//! arithmetic, so a mirrored image gives bit-identical mirrored sums: a
//! running sum (add the entering sample, subtract the leaving one) is
//! cheaper per tap but depends on the scan direction, which would break
//! the exact flip symmetry between Bayer phases that the tests check.
//!
//! Sums come in three parities along a line through a site: every sample
//! within `radius` (`All`), only those an even number of steps away
//! (`Same`: the site's own CFA class along that line) or an odd number
//! (`Other`: the neighbouring class). Guided filters over sparse CFA
//! samples need the class sums; their coefficients then need the full box.

use super::tiled::Tile;

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
/// (`step` 1 along a row, the row stride down a column).
///
/// The one loop behind every box of the method: it works on any flat
/// buffer, so a stage can sum a whole tile plane or a single row it keeps
/// in cache. `src` must hold `radius * step` values beyond both ends.
/// The method's windows (radius 5, and the 3x3 box) get a loop whose taps
/// are known at compile time, which keeps each sum in a register.
#[inline(always)]
pub(super) fn window_sum(
    src: &[f32],
    at: usize,
    step: usize,
    out: &mut [f32],
    radius: usize,
    parity: Parity,
) {
    match (parity, radius) {
        (Parity::All, 1) => taps(src, at, step, out, true, [1]),
        (Parity::All, 5) => taps(src, at, step, out, true, [1, 2, 3, 4, 5]),
        (Parity::Same, 5) => taps(src, at, step, out, true, [2, 4]),
        (Parity::Other, 5) => taps(src, at, step, out, false, [1, 3, 5]),
        _ => {
            let n = out.len();
            if parity == Parity::Other {
                out.fill(0.0);
            } else {
                out.copy_from_slice(&src[at..at + n]);
            }
            for k in parity.steps(radius) {
                let d = k * step;
                let (a, b) = (&src[at - d..at - d + n], &src[at + d..at + d + n]);
                for ((o, a), b) in out.iter_mut().zip(a).zip(b) {
                    *o += a + b;
                }
            }
        }
    }
}

/// [`window_sum`] over the mirrored pairs at `dist` (nearest first) and,
/// if `centre`, the centre: the pairs are added in order, then the centre,
/// so a mirrored line gives the same bits.
#[inline(always)]
fn taps<const K: usize>(
    src: &[f32],
    at: usize,
    step: usize,
    out: &mut [f32],
    centre: bool,
    dist: [usize; K],
) {
    let n = out.len();
    let left = dist.map(|d| &src[at - d * step..][..n]);
    let right = dist.map(|d| &src[at + d * step..][..n]);
    let mid = &src[at..at + n];
    for i in 0..n {
        let mut s = left[0][i] + right[0][i];
        for k in 1..K {
            s += left[k][i] + right[k][i];
        }
        out[i] = if centre { mid[i] + s } else { s };
    }
}

/// The same-class and other-class sums of radius 5 along a line (step 1)
/// around `at + i`, into `same[i]` and `other[i]`, through the pair sums
/// `q(y) = src(y) + src(y + 2)` of neighbours of one class kept in `q`:
/// `same(x) = src(x) + (q(x - 4) + q(x + 2))` and
/// `other(x) = q(x - 1) + (q(x - 5) + q(x + 3))`, 5 additions for both
/// where [`window_sum`] needs 9. Each inner sum adds a pair that a mirror
/// swaps, so a mirrored line still gives the same bits.
#[inline(always)]
pub(super) fn class_sums(
    src: &[f32],
    at: usize,
    same: &mut [f32],
    other: &mut [f32],
    q: &mut [f32],
) {
    let n = same.len();
    // q[j] = q(at - 5 + j), for j in 0 .. n + 8.
    let m = n + 8;
    let (a, b) = (&src[at - 5..][..m], &src[at - 3..][..m]);
    for ((q, a), b) in q[..m].iter_mut().zip(a).zip(b) {
        *q = a + b;
    }
    let q = |d: usize| &q[d..d + n];
    let (c, left, right) = (&src[at..at + n], q(1), q(7));
    for (((o, c), l), r) in same.iter_mut().zip(c).zip(left).zip(right) {
        *o = c + (l + r);
    }
    let (mid, left, right) = (q(4), q(0), q(8));
    for (((o, c), l), r) in other[..n].iter_mut().zip(mid).zip(left).zip(right) {
        *o = c + (l + r);
    }
}

/// The 11-sample sums along a line (step 1) around `at + i` into
/// `out[i]`, through the pair sums `d(y) = src(y) + src(y + 1)` and
/// quadruple sums `f(y) = d(y) + d(y + 2)` kept in `f`:
/// `out(x) = (src(x) + (src(x - 1) + src(x + 1))) + (f(x - 5) + f(x + 2))`,
/// 6 additions where [`window_sum`] needs 10; a mirror swaps the members of
/// every inner sum, so a mirrored line still gives the same bits.
#[inline(always)]
pub(super) fn all_sums(src: &[f32], at: usize, out: &mut [f32], f: &mut [f32]) {
    let n = out.len();
    // f[j] = d(at - 5 + j) for j < n + 9, then f(at - 5 + j) for j < n + 7.
    let f = &mut f[..n + 9];
    let (a, b) = (&src[at - 5..][..n + 9], &src[at - 4..][..n + 9]);
    for ((f, a), b) in f.iter_mut().zip(a).zip(b) {
        *f = a + b;
    }
    for j in 0..n + 7 {
        f[j] += f[j + 2];
    }
    let (c, l, r) = (&src[at..][..n], &src[at - 1..][..n], &src[at + 1..][..n]);
    let (fl, fr) = (&f[..n], &f[7..7 + n]);
    for i in 0..n {
        out[i] = (c[i] + (l[i] + r[i])) + (fl[i] + fr[i]);
    }
}

/// `out` = the sum of `src` over a line window of `radius` along `dir`
/// (`(0, 1)` along rows, `(1, 0)` along columns), keeping `parity`.
///
/// Filled on tile rows `rows` and, within them, the columns at least
/// `cols` from the tile's sides; `src` must be valid `radius` steps
/// further along `dir`.
#[inline(always)]
pub(super) fn line_sum(
    t: &Tile,
    src: &[f32],
    out: &mut [f32],
    (dy, dx): (isize, isize),
    radius: usize,
    parity: Parity,
    (rows, cols): (std::ops::Range<usize>, usize),
) {
    let step = dy as usize * t.stride + dx as usize;
    for ty in rows {
        let sp = t.span(ty, cols);
        window_sum(src, sp.range().start, step, sp.out(out), radius, parity);
    }
}

/// `out` = the 2D sum of `src` over the `(2 radius + 1)`-square window,
/// keeping `parity` along the columns and `along_rows` along the rows
/// (vertical pass into `tmp`, then horizontal). Filled `reach` from the
/// tile's sides; `src` must be valid `reach - radius` from them.
#[inline(always)]
pub(super) fn square_sum(
    t: &Tile,
    src: &[f32],
    tmp: &mut [f32],
    out: &mut [f32],
    radius: usize,
    (vertical, along_rows): (Parity, Parity),
    reach: usize,
) {
    let inner = reach - radius;
    line_sum(
        t,
        src,
        tmp,
        (1, 0),
        radius,
        vertical,
        (reach..t.rows - reach, inner),
    );
    line_sum(
        t,
        tmp,
        out,
        (0, 1),
        radius,
        along_rows,
        (reach..t.rows - reach, reach),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tile(w: usize, h: usize) -> Tile {
        Tile {
            stride: w,
            rows: h,
            y0: 0,
        }
    }

    /// A plane of distinct, irregular values.
    fn plane(len: usize) -> Vec<f32> {
        (0..len)
            .map(|i| ((i * 37 + 11) % 23) as f32 - 7.0)
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
    fn line_sums_match_a_direct_sum() {
        let (w, h, r) = (17, 13, 3);
        let t = tile(w, h);
        let src = plane(w * h);
        for (dir, parity) in [
            ((0, 1), Parity::Other),
            ((1, 0), Parity::Same),
            ((0, 1), Parity::All),
        ] {
            let mut out = vec![f32::NAN; w * h];
            line_sum(&t, &src, &mut out, dir, r, parity, (r..h - r, r));
            for y in r..h - r {
                for x in r..w - r {
                    let want: f32 = (-(r as isize)..=r as isize)
                        .filter(|k| match parity {
                            Parity::All => true,
                            Parity::Same => k % 2 == 0,
                            Parity::Other => k % 2 != 0,
                        })
                        .map(|k| {
                            let (yy, xx) = (y as isize + k * dir.0, x as isize + k * dir.1);
                            src[yy as usize * w + xx as usize]
                        })
                        .sum();
                    assert_eq!(out[y * w + x], want, "{dir:?} {parity:?} at ({y}, {x})");
                }
            }
        }
    }

    #[test]
    fn square_sums_keep_the_class_of_each_axis() {
        // Ones on the even rows and odd columns only: an "R" class of a
        // Bayer-like lattice. From an odd row and an even column, the
        // other-parity sums of a radius-5 window see 6 x 6 of them.
        let (w, h, r) = (24, 24, 5);
        let t = tile(w, h);
        let src: Vec<f32> = (0..w * h)
            .map(|i| f32::from(u8::from((i / w) % 2 == 0 && (i % w) % 2 == 1)))
            .collect();
        let (mut tmp, mut out) = (vec![0.0; w * h], vec![0.0; w * h]);
        square_sum(
            &t,
            &src,
            &mut tmp,
            &mut out,
            r,
            (Parity::Other, Parity::Other),
            2 * r,
        );
        assert_eq!(out[11 * w + 12], 36.0);
        square_sum(
            &t,
            &src,
            &mut tmp,
            &mut out,
            r,
            (Parity::Same, Parity::Other),
            2 * r,
        );
        assert_eq!(out[12 * w + 12], 30.0);
        assert_eq!(out[11 * w + 12], 0.0);
        // Rows 7..=17 hold five even rows, columns 7..=17 six odd ones.
        square_sum(
            &t,
            &src,
            &mut tmp,
            &mut out,
            r,
            (Parity::All, Parity::All),
            2 * r,
        );
        assert_eq!(out[12 * w + 12], 30.0);
    }

    #[test]
    fn class_sums_match_the_window_sums() {
        let src = plane(64);
        let (mut same, mut other, mut q) = (vec![0.0; 40], vec![0.0; 40], vec![0.0; 48]);
        class_sums(&src, 8, &mut same, &mut other, &mut q);
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
        let (mut out, mut f) = (vec![0.0; 40], vec![0.0; 50]);
        all_sums(&src, 8, &mut out, &mut f);
        let mut want = vec![0.0; 40];
        window_sum(&src, 8, 1, &mut want, 5, Parity::All);
        assert_eq!(out, want);
    }

    #[test]
    fn sums_are_exactly_mirror_symmetric() {
        // Values whose sums round differently in different orders.
        let (w, h, r) = (21, 3, 5);
        let t = tile(w, h);
        let src: Vec<f32> = (0..w * h)
            .map(|i| 1.0 / (1.0 + (i % w) as f32 * 0.37).powi(3))
            .collect();
        let flipped: Vec<f32> = src
            .chunks_exact(w)
            .flat_map(|row| row.iter().rev().copied())
            .collect();
        let (mut a, mut b) = (vec![0.0; w * h], vec![0.0; w * h]);
        line_sum(&t, &src, &mut a, (0, 1), r, Parity::All, (0..h, r));
        line_sum(&t, &flipped, &mut b, (0, 1), r, Parity::All, (0..h, r));
        for y in 0..h {
            for x in r..w - r {
                assert_eq!(a[y * w + x].to_bits(), b[y * w + w - 1 - x].to_bits());
            }
        }
    }
}

//! Splitting work over rayon so that results never depend on the thread count.
//!
//! Each task owns a disjoint band of output rows (or a chunk of points) and
//! computes it with the same sequential code whatever the number of threads,
//! so outputs are bit-identical for `RAYON_NUM_THREADS=1` and `N`.

use rayon::prelude::*;

/// Rows per rayon task. A 24 MP image has ~4000 rows, so 8 rows make ~500
/// tasks: enough for load balance on any core count, while the per-task
/// overhead (a few µs) stays below 1 % of the ~0.5 ms a band of 8 rows takes.
pub const ROWS_PER_TASK: usize = 8;

/// Points per rayon task. 16 Ki points are ~0.1 ms of projection work, large
/// enough that task overhead vanishes and small enough to balance 10 M points.
pub const POINTS_PER_TASK: usize = 16 * 1024;

/// Calls `f(y, row)` for every row of `out`, a buffer of rows of `row_len`
/// elements, in parallel over bands of [`ROWS_PER_TASK`] rows.
pub fn for_each_row<T, F>(out: &mut [T], row_len: usize, f: F)
where
    T: Send,
    F: Fn(usize, &mut [T]) + Sync,
{
    if row_len == 0 {
        return;
    }
    out.par_chunks_mut(row_len * ROWS_PER_TASK)
        .enumerate()
        .for_each(|(band, rows)| {
            for (i, row) in rows.chunks_mut(row_len).enumerate() {
                f(band * ROWS_PER_TASK + i, row);
            }
        });
}

/// Calls `f(first_row, rows)` for consecutive bands of `rows_per_band` rows
/// of `out` (rows of `row_len` elements) in parallel.
///
/// For kernels that carry state from row to row inside a band (ring buffers
/// of converted input rows, intermediate planes): the state is rebuilt at
/// each band start, so a band's output never depends on which thread ran
/// the previous one.
pub fn for_each_band<T, F>(out: &mut [T], row_len: usize, rows_per_band: usize, f: F)
where
    T: Send,
    F: Fn(usize, &mut [T]) + Sync,
{
    if row_len == 0 || rows_per_band == 0 {
        return;
    }
    out.par_chunks_mut(row_len * rows_per_band)
        .enumerate()
        .for_each(|(band, rows)| f(band * rows_per_band, rows));
}

/// Maps point `i` of `input` (records of `in_dim` values) to record `i` of
/// `out` (records of `out_dim` values) in parallel, and returns the index of
/// the first point for which `f` returned `false` (an invalid input), if any.
///
/// The index is the smallest such one whatever the thread count, so error
/// messages are deterministic too.
pub fn map_points<F>(
    input: &[f64],
    in_dim: usize,
    out: &mut [f64],
    out_dim: usize,
    f: F,
) -> Option<usize>
where
    F: Fn(&[f64], &mut [f64]) -> bool + Sync,
{
    input
        .par_chunks(in_dim * POINTS_PER_TASK)
        .zip(out.par_chunks_mut(out_dim * POINTS_PER_TASK))
        .enumerate()
        .filter_map(|(chunk, (src, dst))| {
            src.chunks_exact(in_dim)
                .zip(dst.chunks_exact_mut(out_dim))
                .enumerate()
                .fold(None, |bad, (i, (p, q))| match (f(p, q), bad) {
                    (false, None) => Some(chunk * POINTS_PER_TASK + i),
                    _ => bad,
                })
        })
        .min()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn for_each_row_visits_every_row_once_with_its_index() {
        let mut out = vec![0usize; 3 * 37];
        for_each_row(&mut out, 3, |y, row| row.iter_mut().for_each(|v| *v += y));
        for (y, row) in out.chunks(3).enumerate() {
            assert_eq!(row, &[y, y, y]);
        }
    }

    #[test]
    fn for_each_band_covers_every_row_once_including_a_short_last_band() {
        let mut out = vec![0usize; 2 * 11];
        for_each_band(&mut out, 2, 4, |y0, rows| {
            for (i, row) in rows.chunks_mut(2).enumerate() {
                row.iter_mut().for_each(|v| *v += y0 + i);
            }
        });
        for (y, row) in out.chunks(2).enumerate() {
            assert_eq!(row, &[y, y]);
        }
    }

    #[test]
    fn map_points_reports_the_first_bad_point() {
        let n = 3 * POINTS_PER_TASK + 5;
        let input: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let mut out = vec![0.0; 2 * n];
        let bad = map_points(&input, 1, &mut out, 2, |p, q| {
            q[0] = p[0];
            q[1] = -p[0];
            p[0] as usize % POINTS_PER_TASK != 7 || p[0] < 1000.0
        });
        assert_eq!(bad, Some(POINTS_PER_TASK + 7));
        assert_eq!(out[2 * (n - 1) + 1], -((n - 1) as f64));
    }
}

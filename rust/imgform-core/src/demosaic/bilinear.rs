//! Bilinear interpolation: each missing colour is the mean of its nearest
//! samples, the 3x3 kernels `[0 1 0; 1 4 1; 0 1 0] / 4` (green) and
//! `[1 2 1; 2 4 2; 1 2 1] / 4` (red, blue).
//!
//! Sums are grouped as (left + right) + (up + down), so the result is
//! bit-identical under the flips that map one Bayer phase to another.

use super::{run_rows, write_row, Estimate, Phase, Sites};
use crate::image::{ImageView, Sample};

struct Bilinear<'a> {
    up: &'a [f32],
    row: &'a [f32],
    down: &'a [f32],
}

impl Sites for Bilinear<'_> {
    #[inline(always)]
    fn chroma(&self, x: usize) -> Estimate {
        let (u, c, d) = (self.up, self.row, self.down);
        let cross = (c[x - 1] + c[x + 1]) + (u[x] + d[x]);
        let diag = (u[x - 1] + u[x + 1]) + (d[x - 1] + d[x + 1]);
        [c[x], 0.25 * cross, 0.25 * diag]
    }

    #[inline(always)]
    fn green(&self, x: usize) -> Estimate {
        let (u, c, d) = (self.up, self.row, self.down);
        [0.5 * (c[x - 1] + c[x + 1]), c[x], 0.5 * (u[x] + d[x])]
    }
}

pub(super) fn run<T: Sample>(raw: &ImageView<'_, T>, phase: Phase, out: &mut [T]) {
    run_rows(
        raw,
        out,
        1,
        |_| (),
        |_, ring, y, o| {
            let k = Bilinear {
                up: ring.row(y - 1),
                row: ring.row(y),
                down: ring.row(y + 1),
            };
            write_row(&k, phase.row(y), o);
        },
    );
}

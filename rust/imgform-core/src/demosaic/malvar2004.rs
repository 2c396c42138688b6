//! Malvar, He and Cutler (ICASSP 2004), "High-quality linear interpolation
//! for demosaicing of Bayer-patterned color images".
//!
//! Bilinear interpolation corrected by the Laplacian of the colour sampled
//! at the site, with the paper's gains (1/2 for green, 5/8 and 3/4 for red
//! and blue). As 5x5 kernels, in eighths:
//!
//! - green at a chroma site: `[.. -1 ..; .. 2 ..; -1 2 4 2 -1; .. 2 ..; .. -1 ..]`
//! - chroma at a green site, along the row holding it:
//!   `[.. 1/2 ..; -1 . -1; -1 4 5 4 -1; -1 . -1; .. 1/2 ..]` (transposed for columns)
//! - the other chroma at a chroma site:
//!   `[.. -3/2 ..; 2 . 2; -3/2 . 6 . -3/2; 2 . 2; .. -3/2 ..]`
//!
//! Symmetric taps are summed in pairs (left + right, up + down), so results
//! are bit-identical under the flips that map one Bayer phase to another.

use super::{run_rows, write_row, Estimate, Phase, Sites};
use crate::image::{ImageView, Sample};

struct Malvar<'a> {
    /// Rows y-2 ..= y+2.
    r: [&'a [f32]; 5],
}

impl Sites for Malvar<'_> {
    #[inline(always)]
    fn chroma(&self, x: usize) -> Estimate {
        let [u2, u1, c, d1, d2] = self.r;
        let near = (c[x - 1] + c[x + 1]) + (u1[x] + d1[x]);
        let far = (c[x - 2] + c[x + 2]) + (u2[x] + d2[x]);
        let diag = (u1[x - 1] + u1[x + 1]) + (d1[x - 1] + d1[x + 1]);
        let green = 0.125 * (4.0 * c[x] + 2.0 * near - far);
        let other = 0.125 * (6.0 * c[x] + 2.0 * diag - 1.5 * far);
        [c[x], green, other]
    }

    #[inline(always)]
    fn green(&self, x: usize) -> Estimate {
        let [u2, u1, c, d1, d2] = self.r;
        let diag = (u1[x - 1] + u1[x + 1]) + (d1[x - 1] + d1[x + 1]);
        let base = 5.0 * c[x] - diag;
        let horiz = 4.0 * (c[x - 1] + c[x + 1]) - (c[x - 2] + c[x + 2]);
        let vert = 4.0 * (u1[x] + d1[x]) - (u2[x] + d2[x]);
        let own = 0.125 * (base + horiz + 0.5 * (u2[x] + d2[x]));
        let other = 0.125 * (base + vert + 0.5 * (c[x - 2] + c[x + 2]));
        [own, c[x], other]
    }
}

pub(super) fn run<T: Sample>(raw: &ImageView<'_, T>, phase: Phase, out: &mut [T]) {
    run_rows(
        raw,
        out,
        2,
        |_| (),
        |_, ring, y, o| {
            let k = Malvar {
                r: [
                    ring.row(y - 2),
                    ring.row(y - 1),
                    ring.row(y),
                    ring.row(y + 1),
                    ring.row(y + 2),
                ],
            };
            write_row(&k, phase.row(y), o);
        },
    );
}

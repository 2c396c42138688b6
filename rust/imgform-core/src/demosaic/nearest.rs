//! Nearest neighbour: every pixel of a 2x2 cell (aligned to the array
//! origin) takes the cell's red and blue, and the green of its own row.
//!
//! Cells aligned to the origin make the method commute with the flips of
//! even-sized images; a last, half cell of an odd-sized image borrows its
//! missing row or column by mirroring, which keeps the CFA parity.

use super::Phase;
use crate::image::{mirror, ImageView, Sample};
use crate::parallel::for_each_row;

pub(super) fn run<T: Sample>(raw: &ImageView<'_, T>, phase: Phase, out: &mut [T]) {
    let (w, h) = (raw.width(), raw.height());
    for_each_row(out, 3 * w, |y, o| {
        let pair = [raw.row(y & !1), raw.row(mirror((y | 1) as isize, h))];
        let (red, own, blue) = (pair[phase.ry], raw.row(y), pair[1 - phase.ry]);
        // Column offset of green inside a cell on this row: opposite to red
        // on a red row, to blue (= where red is) on a blue row.
        let green_dx = if (y & 1) == phase.ry {
            1 - phase.rx
        } else {
            phase.rx
        };
        let pick = |cell: &[T], dx: usize| if dx == 0 { cell[0] } else { cell[1] };
        let cells = red
            .chunks_exact(2)
            .zip(own.chunks_exact(2))
            .zip(blue.chunks_exact(2));
        for (px, ((r, g), b)) in o.chunks_exact_mut(6).zip(cells) {
            let rgb = [pick(r, phase.rx), pick(g, green_dx), pick(b, 1 - phase.rx)];
            px[..3].copy_from_slice(&rgb);
            px[3..].copy_from_slice(&rgb);
        }
        if w % 2 == 1 {
            // A last half cell borrows its missing column by mirroring,
            // which lands on the cell's first column's neighbour, w - 2.
            let x0 = w - 1;
            let col = |dx: usize| if dx == 0 { x0 } else { x0 - 1 };
            let rgb = [
                red[col(phase.rx)],
                own[col(green_dx)],
                blue[col(1 - phase.rx)],
            ];
            o[3 * x0..].copy_from_slice(&rgb);
        }
    });
}

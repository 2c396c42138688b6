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
        let own = raw.row(y);
        let red = pair[phase.ry];
        let blue = pair[1 - phase.ry];
        // Column offset of green inside a cell on this row: opposite to red
        // on a red row, to blue (= where red is) on a blue row.
        let green_dx = if (y & 1) == phase.ry {
            1 - phase.rx
        } else {
            phase.rx
        };
        for (cell, px) in o.chunks_mut(6).enumerate() {
            let x0 = 2 * cell;
            // The cell's second column, mirrored for a last half cell.
            let col = |dx: usize| if x0 + dx < w { x0 + dx } else { x0 - 1 };
            let rgb = [
                red[col(phase.rx)],
                own[col(green_dx)],
                blue[col(1 - phase.rx)],
            ];
            for p in px.chunks_exact_mut(3) {
                p.copy_from_slice(&rgb);
            }
        }
    });
}

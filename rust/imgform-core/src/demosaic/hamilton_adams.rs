//! Hamilton and Adams, "Adaptive color plane interpolation in single sensor
//! color electronic camera", US patent 5,629,734 (1997).
//!
//! Green first: at a chroma site, along the row and along the column,
//! the classifier is |gradient of green| + |second derivative of the
//! chroma|, and the estimate is the green mean plus a quarter of that second
//! derivative; the direction with the smaller classifier wins, a tie takes
//! the mean of both. Then red and blue from colour differences to the full
//! green plane: at a green site the mean difference of the two neighbours
//! holding the colour; at the opposite chroma site the same choice between
//! the two diagonals, by |chroma gradient| + |green second derivative|.
//!
//! Green is kept as unrounded `f32` rows in a ring of three, computed once
//! per row of the band (plus two halo rows per band).

use super::{run_rows, write_row, Estimate, Phase, Ring, Sites, PAD};
use crate::image::{ImageView, Sample};

/// The estimate along the better of two directions, or their mean on a tie
/// (so that flipping the image flips the choice exactly).
#[inline(always)]
fn choose(class_a: f32, est_a: f32, class_b: f32, est_b: f32) -> f32 {
    if class_a < class_b {
        est_a
    } else if class_b < class_a {
        est_b
    } else {
        0.5 * (est_a + est_b)
    }
}

/// Green of raw row `c` (rows `u2, u1, c, d1, d2` around it) into `g`, for
/// padded columns `2 .. len - 2`; `green_parity` is the column parity of the
/// row's green sites.
fn green_row(r: [&[f32]; 5], green_parity: usize, g: &mut [f32]) {
    let [u2, u1, c, d1, d2] = r;
    let len = c.len();
    for x in 2..len - 2 {
        g[x] = if x & 1 == green_parity {
            c[x]
        } else {
            let twice = 2.0 * c[x];
            let lap_h = twice - (c[x - 2] + c[x + 2]);
            let lap_v = twice - (u2[x] + d2[x]);
            let class_h = (c[x - 1] - c[x + 1]).abs() + lap_h.abs();
            let class_v = (u1[x] - d1[x]).abs() + lap_v.abs();
            let est_h = 0.5 * (c[x - 1] + c[x + 1]) + 0.25 * lap_h;
            let est_v = 0.5 * (u1[x] + d1[x]) + 0.25 * lap_v;
            choose(class_h, est_h, class_v, est_v)
        };
    }
}

struct ColourDifference<'a> {
    /// Raw rows y-1, y, y+1.
    raw: [&'a [f32]; 3],
    /// Green rows y-1, y, y+1.
    green: [&'a [f32]; 3],
}

impl Sites for ColourDifference<'_> {
    #[inline(always)]
    fn chroma(&self, x: usize) -> Estimate {
        let [ru, rc, rd] = self.raw;
        let [gu, gc, gd] = self.green;
        let g = gc[x];
        let twice = 2.0 * g;
        // NE-SW and NW-SE diagonals hold the other chroma.
        let lap_a = twice - (gu[x + 1] + gd[x - 1]);
        let lap_b = twice - (gu[x - 1] + gd[x + 1]);
        let class_a = (ru[x + 1] - rd[x - 1]).abs() + lap_a.abs();
        let class_b = (ru[x - 1] - rd[x + 1]).abs() + lap_b.abs();
        let est_a = 0.5 * (ru[x + 1] + rd[x - 1]) + 0.5 * lap_a;
        let est_b = 0.5 * (ru[x - 1] + rd[x + 1]) + 0.5 * lap_b;
        [rc[x], g, choose(class_a, est_a, class_b, est_b)]
    }

    #[inline(always)]
    fn green(&self, x: usize) -> Estimate {
        let [ru, rc, rd] = self.raw;
        let [gu, gc, gd] = self.green;
        let g = rc[x];
        let own = g + 0.5 * ((rc[x - 1] - gc[x - 1]) + (rc[x + 1] - gc[x + 1]));
        let other = g + 0.5 * ((ru[x] - gu[x]) + (rd[x] - gd[x]));
        [own, g, other]
    }
}

/// Per-band state: the green ring and the next green row to compute.
struct Greens {
    ring: Ring,
    next: isize,
}

pub(super) fn run<T: Sample>(raw: &ImageView<'_, T>, phase: Phase, out: &mut [T]) {
    let w = raw.width();
    let init = |y0: usize| Greens {
        ring: Ring::new(w, 3),
        next: y0 as isize - 1,
    };
    run_rows(raw, out, 3, init, |greens, ring, y, o| {
        while greens.next <= y + 1 {
            let gy = greens.next;
            let rows = [-2, -1, 0, 1, 2].map(|d| ring.row(gy + d));
            let green_parity = 1 - phase.row(gy).chroma_parity;
            green_row(rows, green_parity, greens.ring.row_mut(gy));
            greens.next += 1;
        }
        let k = ColourDifference {
            raw: [ring.row(y - 1), ring.row(y), ring.row(y + 1)],
            green: [
                greens.ring.row(y - 1),
                greens.ring.row(y),
                greens.ring.row(y + 1),
            ],
        };
        write_row(&k, phase.row(y), o);
    });
}

// PAD must cover the green plane one column beyond the image, computed from
// raw two columns further out.
const _: () = assert!(PAD >= 3);

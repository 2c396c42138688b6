//! Bilinear-like interpolation for any CFA, used for X-Trans: each missing
//! colour is the weighted mean of the samples of that colour in the
//! smallest window around the pixel that holds one, with weights
//! `(r + 1 - |dy|) (r + 1 - |dx|)` for the window of radius `r`.
//!
//! With radius 1 these are the bilinear weights (4 at the centre, 2 at the
//! sides, 1 at the corners), so on a Bayer mosaic this is exactly the
//! nearest-samples mean. On X-Trans every 3x3 window inside the image holds
//! every colour; only near corners, where the window is cut by the border,
//! a larger one is needed (a 6x6 window holds a whole tile, so radius 5
//! always succeeds). Borders are not mirrored: mirroring does not keep the
//! 6x6 phase, so only samples inside the image are used.
//!
//! Scalar per-pixel code: X-Trans files are few and this is the fallback,
//! not a fast path.

use crate::cfa::CfaPattern;
use crate::image::{ImageView, Sample};
use crate::parallel::for_each_band;

/// Rows per rayon task.
const ROWS_PER_BAND: usize = 32;

/// The largest window radius searched: a 6x6 window (radius 5 on the far
/// side) holds a whole tile, so every colour is found by then.
pub(super) const MAX_RADIUS: usize = 5;

pub(super) fn run<T: Sample>(raw: &ImageView<'_, T>, pattern: &CfaPattern, out: &mut [T]) {
    let w = raw.width();
    for_each_band(out, 3 * w, ROWS_PER_BAND, |y0, rows| {
        for (i, o) in rows.chunks_exact_mut(3 * w).enumerate() {
            let y = y0 + i;
            for (x, px) in o.chunks_exact_mut(3).enumerate() {
                let own = pattern.color_at(y, x) as usize;
                for (c, v) in px.iter_mut().enumerate() {
                    *v = if c == own {
                        raw.row(y)[x]
                    } else {
                        T::from_f32(mean_of_colour(raw, pattern, y, x, c as u8))
                    };
                }
            }
        }
    });
}

/// The weighted mean of colour `c` around `(y, x)` in the smallest window
/// that holds a sample of it.
fn mean_of_colour<T: Sample>(
    raw: &ImageView<'_, T>,
    pattern: &CfaPattern,
    y: usize,
    x: usize,
    c: u8,
) -> f32 {
    let (w, h) = (raw.width(), raw.height());
    for r in 1..=MAX_RADIUS {
        let (mut sum, mut weight) = (0.0f32, 0.0f32);
        for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
            let wy = (r + 1 - yy.abs_diff(y)) as f32;
            let x0 = x.saturating_sub(r);
            let row = &raw.row(yy)[x0..(x + r + 1).min(w)];
            for (xx, v) in (x0..).zip(row) {
                if pattern.color_at(yy, xx) == c {
                    let wt = wy * (r + 1 - xx.abs_diff(x)) as f32;
                    sum += wt * v.to_f32();
                    weight += wt;
                }
            }
        }
        if weight > 0.0 {
            return sum / weight;
        }
    }
    // Not reached: `demosaic` asks X-Trans mosaics for at least 6x6
    // pixels, so the radius-5 window spans a whole tile.
    0.0
}

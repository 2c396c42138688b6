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

use super::{run_stencil, select, shifted, Isa, Mosaic, Phase, RgbSink, RowKind, RowPlanes};

/// Fills `p` from raw rows `r` = y-2 ..= y+2 for a row of kind `kind`.
#[inline(always)]
fn planes(r: [&[f32]; 5], kind: RowKind, p: &mut RowPlanes) {
    let n = r[2].len() - 4;
    let at = |row, dx| shifted(row, 2, dx, n);
    let [u2, u1, c, d1, d2] = r;
    let (c2l, cl, cc, cr, c2r) = (at(c, -2), at(c, -1), at(c, 0), at(c, 1), at(c, 2));
    let (ul, uc, ur) = (at(u1, -1), at(u1, 0), at(u1, 1));
    let (dl, dc, dr) = (at(d1, -1), at(d1, 0), at(d1, 1));
    let (uu, dd) = (at(u2, 0), at(d2, 0));
    let RowPlanes {
        own,
        green,
        other,
        chroma,
    } = p;
    let m = &chroma[kind.chroma_parity][2..2 + n];
    let (own, green, other) = (
        &mut own[2..2 + n],
        &mut green[2..2 + n],
        &mut other[2..2 + n],
    );
    for i in 0..n {
        let x = cc[i];
        let near_h = cl[i] + cr[i];
        let near_v = uc[i] + dc[i];
        let far_h = c2l[i] + c2r[i];
        let far_v = uu[i] + dd[i];
        let diag = (ul[i] + ur[i]) + (dl[i] + dr[i]);
        // At a chroma site.
        let far = far_h + far_v;
        let g_at_c = 0.125 * (4.0 * x + 2.0 * (near_h + near_v) - far);
        let other_at_c = 0.125 * (6.0 * x + 2.0 * diag - 1.5 * far);
        // At a green site: own chroma along the row, the other along the column.
        let base = 5.0 * x - diag;
        let own_at_g = 0.125 * (base + (4.0 * near_h - far_h) + 0.5 * far_v);
        let other_at_g = 0.125 * (base + (4.0 * near_v - far_v) + 0.5 * far_h);
        own[i] = select(m[i], x, own_at_g);
        green[i] = select(m[i], g_at_c, x);
        other[i] = select(m[i], other_at_c, other_at_g);
    }
}

pub(super) fn run<M, O, K>(raw: &M, phase: Phase, isa: Isa, sink: &K, out: &mut [O])
where
    M: Mosaic,
    O: Send,
    K: RgbSink<O>,
{
    run_stencil(
        raw,
        (phase, isa),
        2,
        #[inline(always)]
        |ring, y, kind, p| planes([-2, -1, 0, 1, 2].map(|d| ring.row(y + d)), kind, p),
        sink,
        out,
    );
}

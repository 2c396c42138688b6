//! Bilinear interpolation: each missing colour is the mean of its nearest
//! samples, the 3x3 kernels `[0 1 0; 1 4 1; 0 1 0] / 4` (green) and
//! `[1 2 1; 2 4 2; 1 2 1] / 4` (red, blue).
//!
//! Sums are grouped as (left + right) + (up + down), so the result is
//! bit-identical under the flips that map one Bayer phase to another.

use super::{run_stencil, select, shifted, Isa, Mosaic, Phase, RgbSink, RowKind, RowPlanes};

/// Fills `p` for raw rows `up`, `row`, `down` of a row of kind `kind`.
#[inline(always)]
fn planes(up: &[f32], row: &[f32], down: &[f32], kind: RowKind, p: &mut RowPlanes) {
    let n = row.len() - 2;
    let at = |r, dx| shifted(r, 1, dx, n);
    let (cl, cc, cr) = (at(row, -1), at(row, 0), at(row, 1));
    let (ul, uc, ur) = (at(up, -1), at(up, 0), at(up, 1));
    let (dl, dc, dr) = (at(down, -1), at(down, 0), at(down, 1));
    let RowPlanes {
        own,
        green,
        other,
        chroma,
    } = p;
    let m = &chroma[kind.chroma_parity][1..1 + n];
    let (own, green, other) = (
        &mut own[1..1 + n],
        &mut green[1..1 + n],
        &mut other[1..1 + n],
    );
    for i in 0..n {
        let horiz = 0.5 * (cl[i] + cr[i]);
        let vert = 0.5 * (uc[i] + dc[i]);
        let cross = 0.5 * (horiz + vert);
        let diag = 0.25 * ((ul[i] + ur[i]) + (dl[i] + dr[i]));
        own[i] = select(m[i], cc[i], horiz);
        green[i] = select(m[i], cross, cc[i]);
        other[i] = select(m[i], diag, vert);
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
        1,
        #[inline(always)]
        |ring, y, kind, p| planes(ring.row(y - 1), ring.row(y), ring.row(y + 1), kind, p),
        sink,
        out,
    );
}

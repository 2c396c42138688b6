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

use super::{
    run_rows, select, shifted, write_row, Isa, Mosaic, Phase, RgbSink, Ring, RowKind, RowPlanes,
    PAD,
};

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

/// Green of raw rows `r` = y-2 ..= y+2 into `g`, for padded columns
/// `2 .. len - 2`; `chroma` marks the chroma sites of row y.
#[inline(always)]
fn green_row(r: [&[f32]; 5], chroma: &[u32], g: &mut [f32]) {
    let n = r[2].len() - 4;
    let at = |row, dx| shifted(row, 2, dx, n);
    let [u2, u1, c, d1, d2] = r;
    let (c2l, cl, cc, cr, c2r) = (at(c, -2), at(c, -1), at(c, 0), at(c, 1), at(c, 2));
    let (uu, uc, dc, dd) = (at(u2, 0), at(u1, 0), at(d1, 0), at(d2, 0));
    let m = &chroma[2..2 + n];
    let g = &mut g[2..2 + n];
    for i in 0..n {
        let twice = 2.0 * cc[i];
        let lap_h = twice - (c2l[i] + c2r[i]);
        let lap_v = twice - (uu[i] + dd[i]);
        let class_h = (cl[i] - cr[i]).abs() + lap_h.abs();
        let class_v = (uc[i] - dc[i]).abs() + lap_v.abs();
        let est_h = 0.5 * (cl[i] + cr[i]) + 0.25 * lap_h;
        let est_v = 0.5 * (uc[i] + dc[i]) + 0.25 * lap_v;
        let est = choose(class_h, est_h, class_v, est_v);
        g[i] = select(m[i], est, cc[i]);
    }
}

/// Fills `p` for row y from raw rows `r` and green rows `g` (y-1 ..= y+1).
#[inline(always)]
fn colour_planes(r: [&[f32]; 3], gr: [&[f32]; 3], kind: RowKind, p: &mut RowPlanes) {
    let n = r[1].len() - 2;
    let at = |row, dx| shifted(row, 1, dx, n);
    let [ru, rc, rd] = r;
    let [gu, gc, gd] = gr;
    let (rul, ruc, rur) = (at(ru, -1), at(ru, 0), at(ru, 1));
    let (rcl, rcc, rcr) = (at(rc, -1), at(rc, 0), at(rc, 1));
    let (rdl, rdc, rdr) = (at(rd, -1), at(rd, 0), at(rd, 1));
    let (gul, guc, gur) = (at(gu, -1), at(gu, 0), at(gu, 1));
    let (gcl, gcc, gcr) = (at(gc, -1), at(gc, 0), at(gc, 1));
    let (gdl, gdc, gdr) = (at(gd, -1), at(gd, 0), at(gd, 1));
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
        // At a chroma site: the other chroma on the better diagonal
        // (a: NE-SW, b: NW-SE).
        let twice = 2.0 * gcc[i];
        let lap_a = twice - (gur[i] + gdl[i]);
        let lap_b = twice - (gul[i] + gdr[i]);
        let class_a = (rur[i] - rdl[i]).abs() + lap_a.abs();
        let class_b = (rul[i] - rdr[i]).abs() + lap_b.abs();
        let est_a = 0.5 * (rur[i] + rdl[i]) + 0.5 * lap_a;
        let est_b = 0.5 * (rul[i] + rdr[i]) + 0.5 * lap_b;
        let other_at_c = choose(class_a, est_a, class_b, est_b);
        // At a green site: mean colour difference of the two neighbours
        // holding each chroma (along the row: own; along the column: other).
        let x = rcc[i];
        let own_at_g = x + 0.5 * ((rcl[i] - gcl[i]) + (rcr[i] - gcr[i]));
        let other_at_g = x + 0.5 * ((ruc[i] - guc[i]) + (rdc[i] - gdc[i]));
        own[i] = select(m[i], x, own_at_g);
        green[i] = select(m[i], gcc[i], x);
        other[i] = select(m[i], other_at_c, other_at_g);
    }
}

/// Per-band state: the output planes (as `f32`, and the sink's buffers), the green ring and the
/// next green row to compute.
struct State<S> {
    planes: RowPlanes,
    scratch: S,
    greens: Ring,
    next: isize,
}

pub(super) fn run<M, O, K>(raw: &M, phase: Phase, isa: Isa, sink: &K, out: &mut [O])
where
    M: Mosaic,
    O: Send,
    K: RgbSink<O>,
{
    let w = raw.width();
    let init = |y0: usize| State {
        planes: RowPlanes::new(w),
        scratch: sink.scratch(w),
        greens: Ring::new(w, 3),
        next: y0 as isize - 1,
    };
    run_rows(
        raw,
        out,
        3,
        isa,
        init,
        #[inline(always)]
        |st, ring, y, o| {
            while st.next <= y + 1 {
                let gy = st.next;
                let rows = [-2, -1, 0, 1, 2].map(|d| ring.row(gy + d));
                let chroma = &st.planes.chroma[phase.row(gy).chroma_parity];
                green_row(rows, chroma, st.greens.row_mut(gy));
                st.next += 1;
            }
            let kind = phase.row(y);
            let raws = [ring.row(y - 1), ring.row(y), ring.row(y + 1)];
            let greens = [st.greens.row(y - 1), st.greens.row(y), st.greens.row(y + 1)];
            colour_planes(raws, greens, kind, &mut st.planes);
            write_row(&st.planes, sink, &mut st.scratch, kind, o);
        },
    );
}

// PAD must cover the green plane one column beyond the image, computed from
// raw two columns further out.
const _: () = assert!(PAD >= 3);

//! Menon, Andriani and Calvagno, "Demosaicing with directional filtering and
//! a posteriori decision", IEEE Transactions on Image Processing 16(1), 2007
//! (DDFAPD), with its refinement step.
//!
//! Green is interpolated both along the row and along the column with the
//! filter `[-1/4, 1/2, 1/2, 1/2, -1/4]`; the direction is chosen a
//! posteriori, at each chroma site, by comparing sums of colour-difference
//! gradients over a 5x5 window (horizontal wins ties). Red and blue follow
//! from colour differences to green (at a chroma site along the chosen
//! direction). The refinement re-estimates green at chroma sites, then
//! chroma at green sites, then the opposite chroma, from colour differences
//! averaged along the chosen direction.
//!
//! Planes hold, per row, the row's own chroma and the other chroma (see
//! [`RowKind`](super::RowKind)); the row above or below has the other
//! kind, so a vertical neighbour's "own" is this row's "other".

use super::tiled::{Tile, TileKernel};
use super::Phase;
use super::{chroma_masks, select};

pub(super) struct Menon2007 {
    pub(super) phase: Phase,
}

pub(super) struct State {
    gh: Vec<f32>,
    gv: Vec<f32>,
    ch: Vec<f32>,
    cv: Vec<f32>,
    green: Vec<f32>,
    /// All ones where the horizontal estimate was chosen.
    horizontal: Vec<u32>,
    own: Vec<f32>,
    other: Vec<f32>,
    green2: Vec<f32>,
    own2: Vec<f32>,
    other2: Vec<f32>,
    other3: Vec<f32>,
    chroma: [Vec<u32>; 2],
}

/// The mean of three, summed symmetrically so that flips are exact.
#[inline(always)]
fn mean3(a: f32, z: f32, b: f32) -> f32 {
    ((a + b) + z) * (1.0 / 3.0)
}

impl TileKernel for Menon2007 {
    type State = State;
    const HALO: usize = 10;

    fn state(&self, stride: usize, len: usize) -> State {
        let plane = || vec![0.0f32; len];
        State {
            gh: plane(),
            gv: plane(),
            ch: plane(),
            cv: plane(),
            green: plane(),
            horizontal: vec![0; len],
            own: plane(),
            other: plane(),
            green2: plane(),
            own2: plane(),
            other2: plane(),
            other3: plane(),
            chroma: chroma_masks(stride),
        }
    }

    #[inline(always)]
    fn run<'s>(&self, st: &'s mut State, t: &Tile, c: &[f32]) -> [&'s [f32]; 3] {
        let State {
            gh,
            gv,
            ch,
            cv,
            green,
            horizontal,
            own,
            other,
            green2,
            own2,
            other2,
            other3,
            chroma,
        } = st;
        let mask =
            |ty: usize, s: usize, n: usize| &chroma[t.kind(self.phase, ty).chroma_parity][s..s + n];
        // Directional green and colour differences (zero at green sites).
        for ty in 2..t.rows - 2 {
            let sp = t.span(ty, 2);
            let m = mask(ty, 2, sp.n);
            let z = sp.at(c, 0, 0);
            let (w1, w2, e1, e2) = (
                sp.at(c, 0, -1),
                sp.at(c, 0, -2),
                sp.at(c, 0, 1),
                sp.at(c, 0, 2),
            );
            let (n1, n2, s1, s2) = (
                sp.at(c, -1, 0),
                sp.at(c, -2, 0),
                sp.at(c, 1, 0),
                sp.at(c, 2, 0),
            );
            let (gh, gv) = (sp.out(gh), sp.out(gv));
            let (ch, cv) = (sp.out(ch), sp.out(cv));
            for i in 0..sp.n {
                let x = z[i];
                let h = 0.5 * (w1[i] + e1[i]) + (0.5 * x - 0.25 * (w2[i] + e2[i]));
                let v = 0.5 * (n1[i] + s1[i]) + (0.5 * x - 0.25 * (n2[i] + s2[i]));
                gh[i] = select(m[i], h, x);
                gv[i] = select(m[i], v, x);
                ch[i] = select(m[i], x - h, 0.0);
                cv[i] = select(m[i], x - v, 0.0);
            }
        }
        // The a posteriori decision and the chosen green.
        for ty in 4..t.rows - 4 {
            let sp = t.span(ty, 4);
            let (h0, v0) = (sp.at(gh, 0, 0), sp.at(gv, 0, 0));
            // Sums of |C(p) - C(p + 2 steps)| over the 5x5 window, with
            // the centre row (column) weighted 3.
            let (hw, hc, he) = (sp.at(ch, 0, -2), sp.at(ch, 0, 0), sp.at(ch, 0, 2));
            let (huw, huc, hue) = (sp.at(ch, -2, -2), sp.at(ch, -2, 0), sp.at(ch, -2, 2));
            let (hdw, hdc, hde) = (sp.at(ch, 2, -2), sp.at(ch, 2, 0), sp.at(ch, 2, 2));
            let (hnl, hnr, hsl, hsr) = (
                sp.at(ch, -1, -1),
                sp.at(ch, -1, 1),
                sp.at(ch, 1, -1),
                sp.at(ch, 1, 1),
            );
            let (vn, vc, vs) = (sp.at(cv, -2, 0), sp.at(cv, 0, 0), sp.at(cv, 2, 0));
            let (vln, vlc, vls) = (sp.at(cv, -2, -2), sp.at(cv, 0, -2), sp.at(cv, 2, -2));
            let (vrn, vrc, vrs) = (sp.at(cv, -2, 2), sp.at(cv, 0, 2), sp.at(cv, 2, 2));
            let (vlu, vld, vru, vrd) = (
                sp.at(cv, -1, -1),
                sp.at(cv, 1, -1),
                sp.at(cv, -1, 1),
                sp.at(cv, 1, 1),
            );
            let (g, hz) = (sp.out(green), &mut horizontal[sp.range()]);
            for i in 0..sp.n {
                let dh = 3.0 * ((hw[i] - hc[i]).abs() + (hc[i] - he[i]).abs())
                    + (((huw[i] - huc[i]).abs() + (huc[i] - hue[i]).abs())
                        + ((hdw[i] - hdc[i]).abs() + (hdc[i] - hde[i]).abs()))
                    + ((hnl[i] - hnr[i]).abs() + (hsl[i] - hsr[i]).abs());
                let dv = 3.0 * ((vn[i] - vc[i]).abs() + (vc[i] - vs[i]).abs())
                    + (((vln[i] - vlc[i]).abs() + (vlc[i] - vls[i]).abs())
                        + ((vrn[i] - vrc[i]).abs() + (vrc[i] - vrs[i]).abs()))
                    + ((vlu[i] - vld[i]).abs() + (vru[i] - vrd[i]).abs());
                let h = if dv >= dh { u32::MAX } else { 0 };
                hz[i] = h;
                g[i] = select(h, h0[i], v0[i]);
            }
        }
        // Chroma at green sites: the row's own along the row, the other
        // along the column.
        for ty in 5..t.rows - 5 {
            let sp = t.span(ty, 5);
            let m = mask(ty, 5, sp.n);
            let (z, g0) = (sp.at(c, 0, 0), sp.at(green, 0, 0));
            let (cw, ce, cn, cs) = (
                sp.at(c, 0, -1),
                sp.at(c, 0, 1),
                sp.at(c, -1, 0),
                sp.at(c, 1, 0),
            );
            let (gw, ge, gn, gs) = (
                sp.at(green, 0, -1),
                sp.at(green, 0, 1),
                sp.at(green, -1, 0),
                sp.at(green, 1, 0),
            );
            let (own, other) = (sp.out(own), sp.out(other));
            for i in 0..sp.n {
                let x = g0[i];
                let own_g = x + (0.5 * (cw[i] + ce[i]) - 0.5 * (gw[i] + ge[i]));
                let other_g = x + (0.5 * (cn[i] + cs[i]) - 0.5 * (gn[i] + gs[i]));
                own[i] = select(m[i], z[i], own_g);
                other[i] = other_g;
            }
        }
        // The other chroma at chroma sites, along the chosen direction (a
        // vertical neighbour's own chroma is this row's other one).
        for ty in 6..t.rows - 6 {
            let sp = t.span(ty, 6);
            let m = mask(ty, 6, sp.n);
            let (z, hz, o0) = (sp.at(c, 0, 0), &horizontal[sp.range()], sp.at(other, 0, 0));
            let (ow, oe, xw, xe) = (
                sp.at(own, 0, -1),
                sp.at(own, 0, 1),
                sp.at(other, 0, -1),
                sp.at(other, 0, 1),
            );
            let (on, os, xn, xs) = (
                sp.at(own, -1, 0),
                sp.at(own, 1, 0),
                sp.at(other, -1, 0),
                sp.at(other, 1, 0),
            );
            let out = sp.out(other3);
            for i in 0..sp.n {
                let h = z[i] + (0.5 * (xw[i] + xe[i]) - 0.5 * (ow[i] + oe[i]));
                let v = z[i] + (0.5 * (on[i] + os[i]) - 0.5 * (xn[i] + xs[i]));
                out[i] = select(m[i], select(hz[i], h, v), o0[i]);
            }
        }
        // Refinement 1: green at chroma sites from the own chroma's
        // difference to green, averaged along the chosen direction.
        for ty in 7..t.rows - 7 {
            let sp = t.span(ty, 7);
            let m = mask(ty, 7, sp.n);
            let (z, g0, hz) = (sp.at(c, 0, 0), sp.at(green, 0, 0), &horizontal[sp.range()]);
            let (ow, oe, gw, ge) = (
                sp.at(own, 0, -1),
                sp.at(own, 0, 1),
                sp.at(green, 0, -1),
                sp.at(green, 0, 1),
            );
            let (xn, xs, gn, gs) = (
                sp.at(other3, -1, 0),
                sp.at(other3, 1, 0),
                sp.at(green, -1, 0),
                sp.at(green, 1, 0),
            );
            let out = sp.out(green2);
            for i in 0..sp.n {
                let d0 = z[i] - g0[i];
                let h = mean3(ow[i] - gw[i], d0, oe[i] - ge[i]);
                let v = mean3(xn[i] - gn[i], d0, xs[i] - gs[i]);
                out[i] = select(m[i], z[i] - select(hz[i], h, v), z[i]);
            }
        }
        // Refinement 2: chroma at green sites from the sampled neighbours'
        // differences to the refined green.
        for ty in 8..t.rows - 8 {
            let sp = t.span(ty, 8);
            let m = mask(ty, 8, sp.n);
            let (z, o0, x0) = (sp.at(c, 0, 0), sp.at(own, 0, 0), sp.at(other3, 0, 0));
            let (cw, ce, cn, cs) = (
                sp.at(c, 0, -1),
                sp.at(c, 0, 1),
                sp.at(c, -1, 0),
                sp.at(c, 1, 0),
            );
            let (gw, ge, gn, gs) = (
                sp.at(green2, 0, -1),
                sp.at(green2, 0, 1),
                sp.at(green2, -1, 0),
                sp.at(green2, 1, 0),
            );
            let (own_o, other_o) = (sp.out(own2), sp.out(other2));
            for i in 0..sp.n {
                let x = z[i];
                let own_g = x + 0.5 * ((cw[i] - gw[i]) + (ce[i] - ge[i]));
                let other_g = x + 0.5 * ((cn[i] - gn[i]) + (cs[i] - gs[i]));
                own_o[i] = select(m[i], o0[i], own_g);
                other_o[i] = select(m[i], x0[i], other_g);
            }
        }
        // Refinement 3: the other chroma at chroma sites from the
        // difference between the two chromas along the chosen direction.
        for ty in 9..t.rows - 9 {
            let sp = t.span(ty, 9);
            let m = mask(ty, 9, sp.n);
            let (z, x0, hz) = (sp.at(c, 0, 0), sp.at(other2, 0, 0), &horizontal[sp.range()]);
            let (ow, oe, xw, xe) = (
                sp.at(own2, 0, -1),
                sp.at(own2, 0, 1),
                sp.at(other2, 0, -1),
                sp.at(other2, 0, 1),
            );
            let (on, os, xn, xs) = (
                sp.at(own2, -1, 0),
                sp.at(own2, 1, 0),
                sp.at(other2, -1, 0),
                sp.at(other2, 1, 0),
            );
            let out = sp.out(other3);
            for i in 0..sp.n {
                let d0 = x0[i] - z[i];
                let h = mean3(xw[i] - ow[i], d0, xe[i] - oe[i]);
                let v = mean3(on[i] - xn[i], d0, os[i] - xs[i]);
                out[i] = select(m[i], z[i] + select(hz[i], h, v), x0[i]);
            }
        }
        [&*own2, &*green2, &*other3]
    }
}

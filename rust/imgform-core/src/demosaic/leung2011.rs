//! Frequency-domain demosaicing: least-squares luma-chroma demultiplexing.
//!
//! A Bayer mosaic is a luma signal plus chroma signals modulated onto the
//! corners and edges of the spectrum (Alleysson, Süsstrunk and Hérault,
//! "Linear demosaicing inspired by the human visual system", IEEE TIP
//! 14(4), 2005). With red at the origin of the 2x2 tile,
//!
//! `f = L + C1·(-1)^(x+y) + C2·((-1)^x + (-1)^y)`,
//!
//! where `L = (R + 2G + B) / 4`, `C1 = (R - 2G + B) / 4` and
//! `C2 = (R - B) / 4`. `C1` is demodulated from (π, π); `C2` appears twice,
//! at (π, 0) and (0, π), and at each pixel the copy less disturbed by luma
//! is preferred, weighting the two by the local luma energy measured
//! between the bands (Dubois, "Frequency-domain methods for demosaicking of
//! Bayer-sampled color images", IEEE SPL 12(12), 2005). The chroma filters
//! are designed by least squares on training images (Leung, Jeon and
//! Dubois, "Least-squares luma-chroma demultiplexing algorithm for Bayer
//! demosaicking", IEEE TIP 20(7), 2011). Luma is what remains of the
//! mosaic once the modulated chroma is removed.
//!
//! Two choices of ours, for speed and exactness:
//! - each filter is separable, `[1 2 1] * q` along both axes with `q`
//!   symmetric (11 taps) and fitted by alternating least squares
//!   (`python -m imgform_rs.training.leung2011`); the `[1 2 1]` factor puts
//!   an exact zero on the carrier, so a grey image has no chroma at all,
//!   bit for bit, and the symmetric taps make flips exact;
//! - demodulation is folded into the filters (`K * (f·c) = c·(K' * f)`
//!   with `K'` the taps of `K` times `(-1)^k`), so the kernel filters the
//!   mosaic itself and only flips signs per site.

use super::tiled::{Tile, TileKernel};
use super::{chroma_masks, select, Phase};
use filters::{C1_H, C1_V, C2_H, C2_V};

mod filters {
    include!("leung2011_filters.rs");
}

/// Unique taps of a symmetric 11-tap filter: `q[0]` at the centre, `q[k]`
/// at `±k`.
type Taps = [f32; 6];

/// The taps of `q` modulated by `(-1)^k`.
const fn alternate(q: Taps) -> Taps {
    let mut out = q;
    let mut k = 1;
    while k < out.len() {
        out[k] = -out[k];
        k += 2;
    }
    out
}

/// Vertical and horizontal taps of the three estimates, demodulation
/// folded in (see the module docs): `C1` from (π, π), `C2` from (π, 0)
/// and its transpose from (0, π).
const Z1: (Taps, Taps) = (alternate(C1_V), alternate(C1_H));
const ZA: (Taps, Taps) = (C2_V, alternate(C2_H));
const ZB: (Taps, Taps) = (alternate(C2_H), C2_V);

pub(super) struct Leung2011 {
    pub(super) phase: Phase,
}

pub(super) struct State {
    /// `[-1 2 -1]` in both directions; `[1 2 1]` down and `[-1 2 -1]`
    /// across; and its transpose: the carriers' zeros, per estimate.
    pre: [Vec<f32>; 3],
    /// The three pre-filtered planes filtered down the columns.
    down: [Vec<f32>; 3],
    /// `Z1`, `Za`, `Zb`: the estimates before their carrier signs.
    z: [Vec<f32>; 3],
    /// Squared band-pass responses across and down, then their row sums
    /// and their 5x5 sums.
    band: [Vec<f32>; 2],
    band_rows: [Vec<f32>; 2],
    energy: [Vec<f32>; 2],
    own: Vec<f32>,
    green: Vec<f32>,
    other: Vec<f32>,
    /// `(-1)^(x - rx)` per tile column.
    sign: Vec<f32>,
    chroma: [Vec<u32>; 2],
}

/// `q[0]·c + Σ q[k]·(a_k + b_k)`: one output of a symmetric filter over
/// the 11 lines `l` (the centre at 5), summed from the outside in so that
/// flips give identical results.
#[inline(always)]
fn symmetric(q: &Taps, l: &[&[f32]; 11], i: usize) -> f32 {
    let mut acc = q[5] * (l[0][i] + l[10][i]);
    for k in (1..5).rev() {
        acc += q[k] * (l[5 - k][i] + l[5 + k][i]);
    }
    acc + q[0] * l[5][i]
}

impl TileKernel for Leung2011 {
    type State = State;
    /// 1 for the pre-filters plus 5 for the 11-tap filters.
    const HALO: usize = 6;

    fn state(&self, stride: usize, len: usize) -> State {
        let plane = || vec![0.0f32; len];
        State {
            pre: [plane(), plane(), plane()],
            down: [plane(), plane(), plane()],
            z: [plane(), plane(), plane()],
            band: [plane(), plane()],
            band_rows: [plane(), plane()],
            energy: [plane(), plane()],
            own: plane(),
            green: plane(),
            other: plane(),
            // Tile columns have the parity of image columns (even halo and
            // tile origins).
            sign: (0..stride)
                .map(|x| {
                    if (x + self.phase.rx) & 1 == 0 {
                        1.0
                    } else {
                        -1.0
                    }
                })
                .collect(),
            chroma: chroma_masks(stride),
        }
    }

    // The stages are `#[inline(always)]` so that they are compiled into
    // the AVX2 copy of the tile loop (see `tiled`), not only for the
    // baseline instruction set.
    #[inline(always)]
    fn run<'s>(&self, st: &'s mut State, t: &Tile, c: &[f32]) -> [&'s [f32]; 3] {
        prefilter(t, c, &mut st.pre);
        band_energy(t, c, &mut st.band, &mut st.band_rows, &mut st.energy);
        for (j, (v, h)) in [Z1, ZA, ZB].iter().enumerate() {
            filter_down(t, v, &st.pre[j], &mut st.down[j]);
            filter_across(t, h, &st.down[j], &mut st.z[j]);
        }
        self.combine(st, t, c);
        [&st.own, &st.green, &st.other]
    }
}

/// The pre-filters of the three estimates, from 3x3 neighbourhoods: with
/// `d = 2c - (w + e)` and `s = 2c + (w + e)` per row, `[-1 2 -1]` down `d`,
/// `[1 2 1]` down `d`, and `[-1 2 -1]` down `s`.
#[inline(always)]
fn prefilter(t: &Tile, c: &[f32], pre: &mut [Vec<f32>; 3]) {
    let [p1, pa, pb] = pre;
    for ty in 1..t.rows - 1 {
        let sp = t.span(ty, 1);
        let row = |dy| (sp.at(c, dy, -1), sp.at(c, dy, 0), sp.at(c, dy, 1));
        let (n, z, s) = (row(-1), row(0), row(1));
        let (p1, pa, pb) = (sp.out(p1), sp.out(pa), sp.out(pb));
        for i in 0..sp.n {
            let side = |r: (&[f32], &[f32], &[f32])| r.0[i] + r.2[i];
            let (dn, dz, ds) = (
                2.0 * n.1[i] - side(n),
                2.0 * z.1[i] - side(z),
                2.0 * s.1[i] - side(s),
            );
            let (sn, sz, ss) = (
                2.0 * n.1[i] + side(n),
                2.0 * z.1[i] + side(z),
                2.0 * s.1[i] + side(s),
            );
            p1[i] = 2.0 * dz - (dn + ds);
            pa[i] = 2.0 * dz + (dn + ds);
            pb[i] = 2.0 * sz - (sn + ss);
        }
    }
}

/// The symmetric taps `q` down the columns of `src`, over every row the
/// horizontal pass needs.
#[inline(always)]
fn filter_down(t: &Tile, q: &Taps, src: &[f32], dst: &mut [f32]) {
    for ty in 6..t.rows - 6 {
        let sp = t.span(ty, 1);
        let lines: [&[f32]; 11] = std::array::from_fn(|j| sp.at(src, j as isize - 5, 0));
        let out = sp.out(dst);
        // Equal lengths let LLVM drop the bounds checks in the loop.
        let lines = lines.map(|l| &l[..out.len()]);
        for (i, o) in out.iter_mut().enumerate() {
            *o = symmetric(q, &lines, i);
        }
    }
}

/// The symmetric taps `q` along the rows of `src`.
#[inline(always)]
fn filter_across(t: &Tile, q: &Taps, src: &[f32], dst: &mut [f32]) {
    for ty in 6..t.rows - 6 {
        let sp = t.span(ty, 6);
        let lines: [&[f32]; 11] = std::array::from_fn(|j| sp.at(src, 0, j as isize - 5));
        let out = sp.out(dst);
        // Equal lengths let LLVM drop the bounds checks in the loop.
        let lines = lines.map(|l| &l[..out.len()]);
        for (i, o) in out.iter_mut().enumerate() {
            *o = symmetric(q, &lines, i);
        }
    }
}

/// Local luma energy between the chroma bands, across and down: the
/// squared response of `[-1 0 2 0 -1]` (peak at π/2, zeros at 0 and π) one
/// way and `[1 2 1]` (zero at π) the other, summed over 5x5.
#[inline(always)]
fn band_energy(
    t: &Tile,
    c: &[f32],
    band: &mut [Vec<f32>; 2],
    rows: &mut [Vec<f32>; 2],
    energy: &mut [Vec<f32>; 2],
) {
    for ty in 2..t.rows - 2 {
        let sp = t.span(ty, 2);
        // Rows -1, 0, 1 at columns -2, 0, 2, and columns -1, 0, 1 at rows
        // -2, 0, 2.
        let across: [[&[f32]; 3]; 3] = std::array::from_fn(|r| {
            std::array::from_fn(|k| sp.at(c, r as isize - 1, 2 * k as isize - 2))
        });
        let down: [[&[f32]; 3]; 3] = std::array::from_fn(|r| {
            std::array::from_fn(|k| sp.at(c, 2 * k as isize - 2, r as isize - 1))
        });
        let [bx, by] = band;
        let (bx, by) = (sp.out(bx), sp.out(by));
        for i in 0..sp.n {
            let bp = |l: &[&[f32]; 3]| 2.0 * l[1][i] - (l[0][i] + l[2][i]);
            let x = 2.0 * bp(&across[1]) + (bp(&across[0]) + bp(&across[2]));
            let y = 2.0 * bp(&down[1]) + (bp(&down[0]) + bp(&down[2]));
            bx[i] = x * x;
            by[i] = y * y;
        }
    }
    for (b, (r, e)) in band.iter().zip(rows.iter_mut().zip(energy.iter_mut())) {
        for ty in 2..t.rows - 2 {
            let sp = t.span(ty, 4);
            let l: [&[f32]; 5] = std::array::from_fn(|j| sp.at(b, 0, j as isize - 2));
            for (i, o) in sp.out(r).iter_mut().enumerate() {
                *o = ((l[0][i] + l[4][i]) + (l[1][i] + l[3][i])) + l[2][i];
            }
        }
        for ty in 4..t.rows - 4 {
            let sp = t.span(ty, 4);
            let l: [&[f32]; 5] = std::array::from_fn(|j| sp.at(r, j as isize - 2, 0));
            for (i, o) in sp.out(e).iter_mut().enumerate() {
                *o = ((l[0][i] + l[4][i]) + (l[1][i] + l[3][i])) + l[2][i];
            }
        }
    }
}

impl Leung2011 {
    /// Carrier signs, the adaptive `C2`, luma, and the three colours as the
    /// row's own chroma, green and other chroma; measured samples are kept.
    #[inline(always)]
    fn combine(&self, st: &mut State, t: &Tile, c: &[f32]) {
        let State {
            z,
            energy,
            own,
            green,
            other,
            sign,
            chroma,
            ..
        } = st;
        for ty in 6..t.rows - 6 {
            let kind = t.kind(self.phase, ty);
            let sy = if kind.blue { -1.0f32 } else { 1.0 };
            let sp = t.span(ty, 6);
            // Masks and signs are per tile column.
            let m = &chroma[kind.chroma_parity][6..6 + sp.n];
            let sx = &sign[6..6 + sp.n];
            let f = sp.at(c, 0, 0);
            let (z1, za, zb) = (sp.at(&z[0], 0, 0), sp.at(&z[1], 0, 0), sp.at(&z[2], 0, 0));
            let (ex, ey) = (sp.at(&energy[0], 0, 0), sp.at(&energy[1], 0, 0));
            let (own, green, other) = (sp.out(own), sp.out(green), sp.out(other));
            for i in 0..sp.n {
                let total = ex[i] + ey[i];
                // Much luma energy across: the (π, 0) copy is disturbed,
                // so lean on the (0, π) one.
                let w = if total > 0.0 { ex[i] / total } else { 0.5 };
                let c1 = sy * sx[i] * z1[i];
                let c2 = w * (sy * zb[i]) + (1.0 - w) * (sx[i] * za[i]);
                let luma = f[i] - z1[i] - c2 * (sx[i] + sy);
                let chroma2 = 2.0 * sy * c2;
                own[i] = select(m[i], f[i], (luma + c1) + chroma2);
                green[i] = select(m[i], luma - c1, f[i]);
                other[i] = (luma + c1) - chroma2;
            }
        }
    }
}

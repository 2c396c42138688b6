//! Hirakawa and Parks, "Adaptive homogeneity-directed demosaicing
//! algorithm", IEEE Transactions on Image Processing 14(3), 2005.
//!
//! Two complete images are interpolated, one along rows and one along
//! columns: green with the filter `[-1/4, 1/2, 1/2, 1/2, -1/4]` limited to
//! the range of its two green neighbours, then red and blue from colour
//! differences to that green. Each pixel then takes the image that is more
//! *homogeneous* around it: both are converted to CIELab, and a neighbour
//! counts as homogeneous when its luminance and chrominance distances stay
//! within thresholds set by the less busy direction; the counts are summed
//! over 3x3 and the larger sum wins (a tie takes the mean).
//!
//! The samples are treated as linear sRGB scaled to the type's full scale
//! for the CIELab conversion, which only serves to compare distances.

use super::tiled::{Span, Tile, TileKernel};
use super::Phase;
use super::{chroma_masks, select};

pub(super) struct Ahd {
    pub(super) phase: Phase,
    pub(super) full_scale: f32,
}

/// One direction's planes.
pub(super) struct Dir {
    green: Vec<f32>,
    own: Vec<f32>,
    other: Vec<f32>,
    lab: [Vec<f32>; 3],
    hom: Vec<f32>,
}

pub(super) struct State {
    dirs: [Dir; 2],
    out: [Vec<f32>; 3],
    chroma: [Vec<u32>; 2],
}

/// The cube root for CIELab's `f`, by a bit-level first guess and three
/// Newton steps: vectorisable, and the same bits on every CPU, unlike a
/// call to the C library.
#[inline(always)]
fn cbrt(t: f32) -> f32 {
    let mut y = f32::from_bits(t.to_bits() / 3 + 709_921_077);
    for _ in 0..3 {
        y = y - (y * y * y - t) / (3.0 * y * y);
    }
    y
}

/// CIELab's `f`, for `t` > 0 and below (linear part).
#[inline(always)]
fn lab_f(t: f32) -> f32 {
    let t = t.max(0.0);
    let root = cbrt(t.max(0.008_856));
    let linear = 7.787 * t + 16.0 / 116.0;
    select(if t > 0.008_856 { u32::MAX } else { 0 }, root, linear)
}

impl Ahd {
    /// Green along `(dy, dx)` at chroma sites, limited to its neighbours' range.
    #[inline(always)]
    fn green(
        &self,
        t: &Tile,
        c: &[f32],
        (dy, dx): (isize, isize),
        chroma: &[Vec<u32>; 2],
        g: &mut [f32],
    ) {
        for ty in 2..t.rows - 2 {
            let sp = t.span(ty, 2);
            let m = &chroma[t.kind(self.phase, ty).chroma_parity][2..2 + sp.n];
            let (z, a1, b1, a2, b2) = (
                sp.at(c, 0, 0),
                sp.at(c, -dy, -dx),
                sp.at(c, dy, dx),
                sp.at(c, -2 * dy, -2 * dx),
                sp.at(c, 2 * dy, 2 * dx),
            );
            let o = sp.out(g);
            for i in 0..sp.n {
                let est = 0.5 * ((a1[i] + b1[i]) + z[i]) - 0.25 * (a2[i] + b2[i]);
                let (lo, hi) = (a1[i].min(b1[i]), a1[i].max(b1[i]));
                o[i] = select(m[i], est.max(lo).min(hi), z[i]);
            }
        }
    }

    /// Red and blue from colour differences to one direction's green, then
    /// that image in CIELab.
    #[inline(always)]
    fn colour(&self, t: &Tile, c: &[f32], chroma: &[Vec<u32>; 2], d: &mut Dir) {
        let Dir {
            green,
            own,
            other,
            lab,
            ..
        } = d;
        let inv = 1.0 / self.full_scale;
        for ty in 3..t.rows - 3 {
            let sp: Span = t.span(ty, 3);
            let kind = t.kind(self.phase, ty);
            let m = &chroma[kind.chroma_parity][3..3 + sp.n];
            let v = |dy, dx| sp.at(c, dy, dx);
            let g = |dy, dx| sp.at(green, dy, dx);
            let (z, g0) = (v(0, 0), g(0, 0));
            let (cw, ce, cn, cs) = (v(0, -1), v(0, 1), v(-1, 0), v(1, 0));
            let (gw, ge, gn, gs) = (g(0, -1), g(0, 1), g(-1, 0), g(1, 0));
            let (cnw, cse, cne, csw) = (v(-1, -1), v(1, 1), v(-1, 1), v(1, -1));
            let (gnw, gse, gne, gsw) = (g(-1, -1), g(1, 1), g(-1, 1), g(1, -1));
            let (own, other) = (sp.out(own), sp.out(other));
            let [l_o, a_o, b_o] = lab;
            let (l_o, a_o, b_o) = (sp.out(l_o), sp.out(a_o), sp.out(b_o));
            for i in 0..sp.n {
                let x = g0[i];
                let own_g = x + 0.5 * ((cw[i] - gw[i]) + (ce[i] - ge[i]));
                let other_g = x + 0.5 * ((cn[i] - gn[i]) + (cs[i] - gs[i]));
                let diag = ((cnw[i] - gnw[i]) + (cse[i] - gse[i]))
                    + ((cne[i] - gne[i]) + (csw[i] - gsw[i]));
                let o = select(m[i], z[i], own_g);
                let p = select(m[i], x + 0.25 * diag, other_g);
                own[i] = o;
                other[i] = p;
                let (r, b) = if kind.blue { (p, o) } else { (o, p) };
                let (r, g, b) = (r * inv, x * inv, b * inv);
                let fx = lab_f((0.412_453 * r + 0.357_580 * g + 0.180_423 * b) / 0.950_456);
                let fy = lab_f(0.212_671 * r + 0.715_160 * g + 0.072_169 * b);
                let fz = lab_f((0.019_334 * r + 0.119_193 * g + 0.950_227 * b) / 1.088_754);
                l_o[i] = 116.0 * fy - 16.0;
                a_o[i] = 500.0 * (fx - fy);
                b_o[i] = 200.0 * (fy - fz);
            }
        }
    }
}

/// Each channel's view at the pixel and at its four neighbours.
#[inline(always)]
fn lab_views(sp: Span, lab: &[Vec<f32>; 3]) -> [(&[f32], [&[f32]; 4]); 3] {
    lab.each_ref()
        .map(|p| (sp.at(p, 0, 0), STEPS.map(|(dy, dx)| sp.at(p, dy, dx))))
}

/// The 3x3 views of `p` around the span.
#[inline(always)]
fn around(sp: Span, p: &[f32]) -> [[&[f32]; 3]; 3] {
    [-1, 0, 1].map(|dy| [-1, 0, 1].map(|dx| sp.at(p, dy, dx)))
}

/// One direction's own chroma, green and other chroma at the span.
#[inline(always)]
fn planes_at(sp: Span, d: &Dir) -> [&[f32]; 3] {
    [&d.own, &d.green, &d.other].map(|p| sp.at(p, 0, 0))
}

/// Left, right, up, down.
const STEPS: [(isize, isize); 4] = [(0, -1), (0, 1), (-1, 0), (1, 0)];

/// L distance and squared (a, b) distance to the four neighbours, from
/// each channel's `(centre, [neighbours])` views.
#[inline(always)]
fn steps_dist(lab: &[(&[f32], [&[f32]; 4]); 3], i: usize) -> [(f32, f32); 4] {
    // Not `[0, 1, 2, 3].map(..)` nor a closure: both stayed a call per
    // pixel once the tile loop grew.
    [
        step_dist(lab, i, 0),
        step_dist(lab, i, 1),
        step_dist(lab, i, 2),
        step_dist(lab, i, 3),
    ]
}

/// [`steps_dist`] to neighbour `k`.
#[inline(always)]
fn step_dist(lab: &[(&[f32], [&[f32]; 4]); 3], i: usize, k: usize) -> (f32, f32) {
    let [(l0, ln), (a0, an), (b0, bn)] = lab;
    let l = (l0[i] - ln[k][i]).abs();
    let a = a0[i] - an[k][i];
    let b = b0[i] - bn[k][i];
    (l, a * a + b * b)
}

/// How many of the four neighbours are within both thresholds.
#[inline(always)]
fn homogeneous(d: [(f32, f32); 4], leps: f32, abeps: f32) -> f32 {
    let one = |(l, ab): (f32, f32)| f32::from(u8::from(l <= leps && ab <= abeps));
    (one(d[0]) + one(d[1])) + (one(d[2]) + one(d[3]))
}

/// The sum of a 3x3 neighbourhood, symmetric under flips.
#[inline(always)]
fn sum3x3(p: &[[&[f32]; 3]; 3], i: usize) -> f32 {
    let row = |r: &[&[f32]; 3]| (r[0][i] + r[2][i]) + r[1][i];
    (row(&p[0]) + row(&p[2])) + row(&p[1])
}

/// The row image's value `a` when its homogeneity `sh` is larger, the
/// column image's `b` when `sv` is, their mean on a tie.
#[inline(always)]
fn pick(sh: f32, sv: f32, a: f32, b: f32) -> f32 {
    let mean = 0.5 * (a + b);
    let h = select(if sh > sv { u32::MAX } else { 0 }, a, mean);
    select(if sv > sh { u32::MAX } else { 0 }, b, h)
}

impl TileKernel for Ahd {
    type State = State;
    const HALO: usize = 6;

    fn state(&self, stride: usize, len: usize) -> State {
        let plane = || vec![0.0f32; len];
        let dir = || Dir {
            green: plane(),
            own: plane(),
            other: plane(),
            lab: [plane(), plane(), plane()],
            hom: plane(),
        };
        State {
            dirs: [dir(), dir()],
            out: [plane(), plane(), plane()],
            chroma: chroma_masks(stride),
        }
    }

    #[inline(always)]
    fn run<'s>(&self, st: &'s mut State, t: &Tile, c: &[f32]) -> [&'s [f32]; 3] {
        let State { dirs, out, chroma } = st;
        for (d, step) in dirs.iter_mut().zip([(0, 1), (1, 0)]) {
            self.green(t, c, step, chroma, &mut d.green);
            self.colour(t, c, chroma, d);
        }
        // Homogeneity: neighbours within the thresholds set by the quieter
        // direction (left/right in the row image, up/down in the column one).
        let [h, v] = dirs;
        for ty in 4..t.rows - 4 {
            let sp = t.span(ty, 4);
            // Each image's L, a, b at the pixel and its four neighbours.
            let (lh, lv) = (lab_views(sp, &h.lab), lab_views(sp, &v.lab));
            let (hom_h, hom_v) = (&mut h.hom[sp.range()], &mut v.hom[sp.range()]);
            for i in 0..sp.n {
                let dh = steps_dist(&lh, i);
                let dv = steps_dist(&lv, i);
                let leps = dh[0].0.max(dh[1].0).min(dv[2].0.max(dv[3].0));
                let abeps = dh[0].1.max(dh[1].1).min(dv[2].1.max(dv[3].1));
                hom_h[i] = homogeneous(dh, leps, abeps);
                hom_v[i] = homogeneous(dv, leps, abeps);
            }
        }
        // The direction with more homogeneous neighbours over 3x3.
        for ty in 5..t.rows - 5 {
            let sp = t.span(ty, 5);
            let (nh, nv) = (around(sp, &h.hom), around(sp, &v.hom));
            let (ph, pv) = (planes_at(sp, h), planes_at(sp, v));
            let [o_own, o_green, o_other] = out;
            let (o_own, o_green, o_other) = (sp.out(o_own), sp.out(o_green), sp.out(o_other));
            for i in 0..sp.n {
                let (sh, sv) = (sum3x3(&nh, i), sum3x3(&nv, i));
                o_own[i] = pick(sh, sv, ph[0][i], pv[0][i]);
                o_green[i] = pick(sh, sv, ph[1][i], pv[1][i]);
                o_other[i] = pick(sh, sv, ph[2][i], pv[2][i]);
            }
        }
        let [own, green, other] = &*out;
        [own, green, other]
    }
}

#[cfg(test)]
mod tests {
    use super::cbrt;

    #[test]
    fn cube_root_is_exact_to_a_few_float_steps() {
        // A geometric sweep over CIELab's cube-root range and beyond, against
        // f64: three Newton steps from the bit-level guess leave ~1e-7.
        let (lo, hi, n) = (0.008_856f64, 8.0f64, 100_000);
        let worst = (0..=n)
            .map(|i| {
                let t = (lo * (hi / lo).powf(i as f64 / n as f64)) as f32;
                let exact = f64::from(t).cbrt();
                (f64::from(cbrt(t)) / exact - 1.0).abs()
            })
            .fold(0.0, f64::max);
        assert!(worst < 2e-7, "worst relative error {worst:e}");
    }
}

//! X-Trans demosaicing of Frank Markesteijn's kind (the method behind
//! dcraw's and LibRaw's `xtrans_interpolate`), one pass.
//!
//! Four complete RGB images are interpolated, one per direction
//! (horizontal, vertical and the two diagonals), and each pixel takes the
//! mean of the directions whose neighbourhood is the most homogeneous:
//!
//! 1. Green along each direction: at a red or blue site, the two nearest
//!    greens on the line through the site, interpolated linearly, plus the
//!    site's own colour's second difference along the same line (the
//!    Hamilton-Adams correction, generalised to X-Trans's uneven spacing;
//!    see [`Finder::green`]). The result is clamped to the range of the greens in the
//!    3x3 neighbourhood, as Markesteijn does, so a wrong direction cannot
//!    overshoot.
//! 2. Red and blue by colour differences to that direction's green: from
//!    the nearest samples on the line when both sides have one within two
//!    pixels, else from the samples in the 3x3 neighbourhood (X-Trans puts
//!    every colour in every 3x3 window). Red and blue sites come first, from
//!    the other colour's samples; green sites then use every red or blue
//!    site, as Markesteijn orders it.
//! 3. Homogeneity as in AHD: each direction's image is taken to YPbPr and
//!    its second difference along that direction measured; a direction
//!    scores, at each pixel of the 3x3 window, when that measure is within
//!    8 times the smallest of the four at the window's centre. Scores are
//!    summed over 5x5 and the directions within 1/8 of the best are
//!    averaged.
//!
//! The X-Trans layout has no fixed 2x2 structure, so every formula comes
//! from a table of taps (offsets and weights) built once per call for each
//! of the 36 positions in the tile, by searching the pattern itself: any
//! shift, flip or transpose of the tile works the same way. Tiles of rows
//! and columns with a mirrored halo run in parallel, as in [`super::tiled`];
//! the mirror is moved by up to 3 pixels to the nearest sample of the same
//! colour, so the halo keeps the 6x6 period.

use super::{interleave, tiled, Packed};
use crate::cfa::CfaPattern;
use crate::image::{mirror, ImageView, Sample};
use rayon::prelude::*;

/// Output rows per tile (a multiple of the period, so tile row `ty` has the
/// phase of `ty % 6`).
const ROWS: usize = 96;
/// Output columns per tile: the ~25 planes of a tile (~4 MB) stay in cache.
const COLS: usize = 384;
/// Mirrored rows and columns around a tile: the reach of every stage added
/// up (green 6, chroma 2 + 2, derivative 1, homogeneity 1, 5x5 sum 2),
/// rounded up to the period.
pub(super) const HALO: usize = 18;
const _: () = assert!(ROWS % 6 == 0 && COLS % 6 == 0 && HALO % 6 == 0);

/// How far each stage reaches beyond the pixel it computes, cumulated: the
/// margin of the tile it leaves uncomputed.
const GREEN_MARGIN: usize = 6;
const CHROMA_MARGIN: usize = GREEN_MARGIN + 4;
const DRV_MARGIN: usize = CHROMA_MARGIN + 1;
const HOMO_MARGIN: usize = DRV_MARGIN + 1;

/// Colour masks for [`Finder::nearest`] and [`Finder::window`].
const RED: u8 = 1;
const GREEN: u8 = 2;
const BLUE: u8 = 4;

/// The four interpolation directions as (row, column) steps.
const DIRS: [(isize, isize); 4] = [(0, 1), (1, 0), (1, 1), (1, -1)];

/// The farthest a sample is looked for along a line: a whole period, which
/// holds every colour on every row and column.
const SEARCH: isize = 6;

/// A weighted sum of samples at fixed offsets from a pixel.
#[derive(Clone, Copy, Default)]
struct Taps {
    n: usize,
    off: [isize; 9],
    w: [f32; 9],
}

impl Taps {
    fn push(&mut self, off: isize, w: f32) {
        self.off[self.n] = off;
        self.w[self.n] = w;
        self.n += 1;
    }

    /// `sum w * p[i + off]`.
    #[inline(always)]
    fn apply(&self, p: &[f32], i: usize) -> f32 {
        let mut s = 0.0;
        for k in 0..self.n {
            s += self.w[k] * p[(i as isize + self.off[k]) as usize];
        }
        s
    }

    /// `sum w * (a - b)` over the taps.
    #[inline(always)]
    fn apply_diff(&self, a: &[f32], b: &[f32], i: usize) -> f32 {
        let mut s = 0.0;
        for k in 0..self.n {
            let j = (i as isize + self.off[k]) as usize;
            s += self.w[k] * (a[j] - b[j]);
        }
        s
    }

    /// Smallest and largest `p[i + off]`.
    #[inline(always)]
    fn range(&self, p: &[f32], i: usize) -> (f32, f32) {
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for &o in &self.off[..self.n] {
            let v = p[(i as isize + o) as usize];
            lo = lo.min(v);
            hi = hi.max(v);
        }
        (lo, hi)
    }
}

/// The formulas at one position of the 6x6 tile.
#[derive(Clone, Copy, Default)]
struct Site {
    colour: usize,
    /// Green along each direction (red and blue sites only).
    green: [Taps; 4],
    /// The greens of the 3x3 neighbourhood, to clamp green estimates into.
    greens_around: Taps,
    /// Per direction, red's and blue's colour difference to green (at
    /// sites of another colour), indexed by colour / 2.
    chroma: [[Taps; 2]; 4],
}

/// Site formulas for the 36 tile positions, with offsets for planes
/// `stride` wide.
struct Layout {
    sites: [Site; 36],
    stride: isize,
}

impl Layout {
    fn new(pattern: &CfaPattern, stride: usize) -> Self {
        let mut sites = [Site::default(); 36];
        let stride = stride as isize;
        for (i, s) in sites.iter_mut().enumerate() {
            *s = Finder {
                pattern,
                y: (i / 6) as isize,
                x: (i % 6) as isize,
                stride,
            }
            .site();
        }
        Self { sites, stride }
    }

    /// The sites of tile row `ty`, by column phase.
    fn row(&self, ty: usize) -> &[Site] {
        let p = ty % 6;
        &self.sites[6 * p..6 * p + 6]
    }
}

/// Builds the taps of the site at tile position `(y, x)` by looking at the
/// pattern around it.
struct Finder<'a> {
    pattern: &'a CfaPattern,
    y: isize,
    x: isize,
    stride: isize,
}

impl Finder<'_> {
    fn colour(&self, dy: isize, dx: isize) -> usize {
        let y = (self.y + dy).rem_euclid(6) as usize;
        let x = (self.x + dx).rem_euclid(6) as usize;
        self.pattern.color_at(y, x) as usize
    }

    fn off(&self, dy: isize, dx: isize) -> isize {
        dy * self.stride + dx
    }

    /// Whether the sample at `(dy, dx)` has one of the colours of `mask`
    /// (bit `c` for colour `c`).
    fn is(&self, dy: isize, dx: isize, mask: u8) -> bool {
        mask & (1 << self.colour(dy, dx)) != 0
    }

    /// Steps `k` (1 ..= `max`) to the nearest sample of a colour of `mask`
    /// along `(dy, dx)`.
    fn nearest(&self, (dy, dx): (isize, isize), mask: u8, max: isize) -> Option<isize> {
        (1..=max).find(|&k| self.is(k * dy, k * dx, mask))
    }

    fn site(&self) -> Site {
        let colour = self.colour(0, 0);
        let mut s = Site {
            colour,
            greens_around: self.window(GREEN),
            ..Site::default()
        };
        for (d, &dir) in DIRS.iter().enumerate() {
            if colour != 1 {
                s.green[d] = self.green(dir);
            }
            for c in [0, 2] {
                if colour == 1 {
                    s.chroma[d][c / 2] = self.chroma(dir, RED | BLUE);
                } else if c != colour {
                    s.chroma[d][c / 2] = self.chroma(dir, 1 << c);
                }
            }
        }
        s
    }

    /// The samples of the colours of `mask` in the 3x3 window but the
    /// centre, with bilinear weights (2 on the sides, 1 on the corners)
    /// summing to 1.
    fn window(&self, mask: u8) -> Taps {
        let mut t = Taps::default();
        let mut total = 0.0;
        for (dy, dx) in (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (dy, dx))) {
            if (dy, dx) != (0, 0) && self.is(dy, dx, mask) {
                let w = if dy == 0 || dx == 0 { 2.0 } else { 1.0 };
                t.push(self.off(dy, dx), w);
                total += w;
            }
        }
        t.w[..t.n].iter_mut().for_each(|w| *w /= total);
        t
    }

    /// Green along `dir` at a red or blue site (see the module doc): greens
    /// at `-a` and `+b` interpolated linearly, plus `2ab / (ce)` times the
    /// own colour's deviation from its line through its samples at `-c`
    /// and `+e`. Half that factor reproduces quadratics exactly; twice it,
    /// like Hamilton-Adams's Bayer weights, keeps more of the own colour's
    /// detail (+0.2 dB mean CPSNR on the benchmark images, and better than
    /// three times). A cubic through two greens each side instead was
    /// 0.9 dB worse. Falls back to the 3x3 mean when a side has no green.
    fn green(&self, dir: (isize, isize)) -> Taps {
        let mut t = Taps::default();
        let Some((a, b)) = self.line(dir, GREEN, SEARCH, &mut t) else {
            return self.window(GREEN);
        };
        let mut own = Taps::default();
        if let Some((c, e)) = self.line(dir, 1 << self.colour(0, 0), SEARCH, &mut own) {
            let q = 2.0 * (a * b) as f32 / (c * e) as f32;
            t.push(0, q);
            for k in 0..own.n {
                t.push(own.off[k], -q * own.w[k]);
            }
        }
        t
    }

    /// A colour's difference to green along `dir`, from the samples of
    /// `mask`: the nearest on both sides within 2 steps, interpolated
    /// linearly, else the 3x3 window's.
    fn chroma(&self, dir: (isize, isize), mask: u8) -> Taps {
        let mut t = Taps::default();
        match self.line(dir, mask, 2, &mut t) {
            Some(_) => t,
            None => self.window(mask),
        }
    }

    /// Adds to `t` the linear interpolation at the site between the nearest
    /// samples of `mask` at `-a` and `+b` along `(dy, dx)` (within `max`
    /// steps), and returns `(a, b)`; `None`, adding nothing, when a side
    /// has none.
    fn line(
        &self,
        (dy, dx): (isize, isize),
        mask: u8,
        max: isize,
        t: &mut Taps,
    ) -> Option<(isize, isize)> {
        let a = self.nearest((-dy, -dx), mask, max)?;
        let b = self.nearest((dy, dx), mask, max)?;
        let (af, bf) = (a as f32, b as f32);
        t.push(self.off(-a * dy, -a * dx), bf / (af + bf));
        t.push(self.off(b * dy, b * dx), af / (af + bf));
        Some((a, b))
    }
}

/// Mirrors `i` into `0 .. n` (see [`mirror`]) and moves the result to the
/// nearest index with the same remainder modulo 6, so the mirrored mosaic
/// keeps the X-Trans period. `n >= 6`.
fn mirror6(i: isize, n: usize) -> usize {
    let m = mirror(i, n) as isize;
    let r = (i - m).rem_euclid(6);
    let (up, down) = (m + r, m + r - 6);
    let ok = |v: isize| (0..n as isize).contains(&v);
    let v = if (r <= 3 && ok(up)) || !ok(down) {
        up
    } else {
        down
    };
    v as usize
}

/// Where a tile sits and how much of its planes is used.
struct Tile {
    stride: usize,
    rows: usize,
    cols: usize,
}

impl Tile {
    /// Calls `f(ty, sites, i)` for every pixel at least `m` from the tile's
    /// edges, `i` being its plane index and `sites` its row's site table.
    #[inline(always)]
    fn each(&self, layout: &Layout, m: usize, mut f: impl FnMut(usize, &Site, usize)) {
        for ty in m..self.rows - m {
            let sites = layout.row(ty);
            for tx in m..self.cols - m {
                f(ty, &sites[tx % 6], ty * self.stride + tx);
            }
        }
    }
}

/// One direction's image: R, G, B planes.
type Rgb = [Vec<f32>; 3];

/// Per-thread planes, reused from tile to tile (every stage reads only what
/// earlier stages of the same tile wrote).
struct Scratch<T> {
    raw: Vec<f32>,
    dirs: [Rgb; 4],
    ypbpr: [Vec<f32>; 3],
    drv: [Vec<f32>; 4],
    homo: [Vec<f32>; 4],
    out: [Vec<f32>; 3],
    packed: Packed<T>,
}

impl<T: Sample> Scratch<T> {
    fn new(len: usize, cols: usize) -> Self {
        let plane = || vec![0.0f32; len];
        Self {
            raw: plane(),
            dirs: [0, 1, 2, 3].map(|_| [plane(), plane(), plane()]),
            ypbpr: [plane(), plane(), plane()],
            drv: [0, 1, 2, 3].map(|_| plane()),
            homo: [0, 1, 2, 3].map(|_| plane()),
            out: [0, 1, 2].map(|_| vec![0.0; cols]),
            packed: Packed::new(cols),
        }
    }
}

/// Demosaics an X-Trans mosaic (at least 6x6) into `out`, clamped to the
/// range of `raw`.
pub(super) fn run<T: Sample>(raw: &ImageView<'_, T>, pattern: &CfaPattern, out: &mut [T]) {
    let bounds = tiled::range(raw);
    let w = raw.width();
    let stride = w.min(COLS) + 2 * HALO;
    let layout = Layout::new(pattern, stride);
    let len = stride * (ROWS + 2 * HALO);
    let bands = raw.height().div_ceil(ROWS);
    out.par_chunks_mut(3 * w * ROWS)
        .with_min_len(bands.div_ceil(2 * rayon::current_num_threads()))
        .enumerate()
        .for_each_init(
            || Scratch::new(len, w.min(COLS)),
            |s, (i, rows)| {
                for x0 in (0..w).step_by(COLS) {
                    tile(raw, &layout, bounds, (x0, i * ROWS), s, rows);
                }
            },
        );
}

/// The tile of output columns `x0 .. x0 + COLS` of the band `rows`
/// starting at row `y0`.
fn tile<T: Sample>(
    raw: &ImageView<'_, T>,
    layout: &Layout,
    bounds: (f32, f32),
    (x0, y0): (usize, usize),
    s: &mut Scratch<T>,
    rows: &mut [T],
) {
    let (w, h) = (raw.width(), raw.height());
    let n = rows.len() / (3 * w);
    let tw = COLS.min(w - x0);
    let t = Tile {
        stride: layout.stride as usize,
        rows: n + 2 * HALO,
        cols: tw + 2 * HALO,
    };
    let (top, left) = (y0 as isize - HALO as isize, x0 as isize - HALO as isize);
    for (ty, dst) in s.raw.chunks_exact_mut(t.stride).take(t.rows).enumerate() {
        let src = raw.row(mirror6(top + ty as isize, h));
        for (tx, d) in dst[..t.cols].iter_mut().enumerate() {
            *d = src[mirror6(left + tx as isize, w)].to_f32();
        }
    }
    for (d, (rgb, drv)) in s.dirs.iter_mut().zip(&mut s.drv).enumerate() {
        green(&t, layout, d, &s.raw, &mut rgb[1]);
        chroma(&t, layout, d, &s.raw, rgb);
        to_ypbpr(&t, layout, rgb, &mut s.ypbpr);
        derivative(&t, layout, DIRS[d], &s.ypbpr, drv);
    }
    homogeneity(&t, layout, &s.drv, &mut s.homo);
    for (i, o) in rows.chunks_exact_mut(3 * w).enumerate() {
        blend_row(&t, layout, HALO + i, s);
        for (c, dst) in s.out.iter_mut().zip(s.packed.0.iter_mut()) {
            c[..tw]
                .iter_mut()
                .for_each(|v| *v = v.max(bounds.0).min(bounds.1));
            T::from_f32_row(&mut dst[..tw], &c[..tw]);
        }
        interleave(&s.packed, &mut o[3 * x0..3 * (x0 + tw)]);
    }
}

/// Green along direction `d`: the raw sample at green sites, the clamped
/// directional estimate elsewhere.
fn green(t: &Tile, layout: &Layout, d: usize, raw: &[f32], g: &mut [f32]) {
    t.each(layout, GREEN_MARGIN, |_, site, i| {
        g[i] = if site.colour == 1 {
            raw[i]
        } else {
            let (lo, hi) = site.greens_around.range(raw, i);
            site.green[d].apply(raw, i).max(lo).min(hi)
        };
    });
}

/// Red and blue along direction `d` from colour differences to its green:
/// first at red and blue sites from the samples of the other colour, then
/// at green sites from every red or blue site, now complete (denser, so
/// the line through the site finds them closer, as in Markesteijn's order).
fn chroma(t: &Tile, layout: &Layout, d: usize, raw: &[f32], rgb: &mut Rgb) {
    let [r, g, b] = rgb;
    t.each(layout, CHROMA_MARGIN - 2, |_, site, i| {
        for (c, plane) in [(0, &mut *r), (2, &mut *b)] {
            if site.colour == c {
                plane[i] = raw[i];
            } else if site.colour != 1 {
                plane[i] = g[i] + site.chroma[d][c / 2].apply_diff(raw, g, i);
            }
        }
    });
    t.each(layout, CHROMA_MARGIN, |_, site, i| {
        if site.colour == 1 {
            for (c, plane) in [(0, &mut *r), (2, &mut *b)] {
                plane[i] = g[i] + site.chroma[d][c / 2].apply_diff(plane, g, i);
            }
        }
    });
}

/// BT.2020 luma and scaled colour differences: a cheap perceptual space in
/// which to compare the directions (Markesteijn's 3-pass variant uses it
/// instead of CIELab).
fn to_ypbpr(t: &Tile, layout: &Layout, [r, g, b]: &Rgb, out: &mut [Vec<f32>; 3]) {
    let [y, pb, pr] = out;
    t.each(layout, CHROMA_MARGIN, |_, _, i| {
        let l = 0.2627 * r[i] + 0.678 * g[i] + 0.0593 * b[i];
        y[i] = l;
        pb[i] = (b[i] - l) * 0.56433;
        pr[i] = (r[i] - l) * 0.67815;
    });
}

/// The squared second difference of the YPbPr image along `dir`: small
/// where interpolating along that direction left a smooth image.
fn derivative(
    t: &Tile,
    layout: &Layout,
    (dy, dx): (isize, isize),
    ypbpr: &[Vec<f32>; 3],
    drv: &mut [f32],
) {
    let step = dy * t.stride as isize + dx;
    t.each(layout, DRV_MARGIN, |_, _, i| {
        let (a, b) = ((i as isize - step) as usize, (i as isize + step) as usize);
        drv[i] = ypbpr
            .iter()
            .map(|p| {
                let v = 2.0 * p[i] - p[a] - p[b];
                v * v
            })
            .sum();
    });
}

/// Each direction's count of 3x3 neighbours whose derivative is within 8
/// times the smallest derivative of the four at the centre.
fn homogeneity(t: &Tile, layout: &Layout, drv: &[Vec<f32>; 4], homo: &mut [Vec<f32>; 4]) {
    let s = t.stride as isize;
    let window = [-s - 1, -s, -s + 1, -1, 0, 1, s - 1, s, s + 1];
    t.each(layout, HOMO_MARGIN, |_, _, i| {
        let tr = 8.0 * drv.iter().map(|p| p[i]).fold(f32::INFINITY, f32::min);
        for (p, h) in drv.iter().zip(homo.iter_mut()) {
            h[i] = window
                .iter()
                .filter(|&&o| p[(i as isize + o) as usize] <= tr)
                .count() as f32;
        }
    });
}

/// Tile row `ty`'s output into `s.out`: per pixel, the mean of the
/// directions whose 5x5 homogeneity sum is within 1/8 of the best, with the
/// site's own sample as its own colour.
fn blend_row<T>(t: &Tile, layout: &Layout, ty: usize, s: &mut Scratch<T>) {
    let sites = layout.row(ty);
    let st = t.stride;
    for tx in HALO..t.cols - HALO {
        let i = ty * st + tx;
        let score = s.homo.each_ref().map(|h| {
            (0..5)
                .map(|k| h[i + k * st - 2 * st - 2..][..5].iter().sum::<f32>())
                .sum::<f32>()
        });
        let best = score.iter().fold(0.0f32, |a, &b| a.max(b));
        let keep = best - best / 8.0;
        let mut sum = [0.0f32; 3];
        let mut count = 0.0f32;
        for (rgb, &sc) in s.dirs.iter().zip(&score) {
            if sc >= keep {
                sum.iter_mut().zip(rgb).for_each(|(a, p)| *a += p[i]);
                count += 1.0;
            }
        }
        let x = tx - HALO;
        for (o, v) in s.out.iter_mut().zip(sum) {
            o[x] = v / count;
        }
        let own = sites[tx % 6].colour;
        s.out[own][x] = s.raw[i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mirror6_keeps_the_period_and_stays_inside() {
        for n in [6usize, 7, 11, 40] {
            for i in -30isize..(n as isize + 30) {
                let m = mirror6(i, n);
                assert!(m < n, "{i} {n} -> {m}");
                assert_eq!((i - m as isize).rem_euclid(6), 0, "{i} {n} -> {m}");
            }
            for i in 0..n {
                assert_eq!(mirror6(i as isize, n), i);
            }
        }
    }

    #[test]
    fn green_weights_sum_to_one_so_constants_stay() {
        let p = CfaPattern::xtrans();
        let layout = Layout::new(&p, 100);
        for s in layout.sites.iter().filter(|s| s.colour != 1) {
            for g in &s.green {
                let sum: f32 = g.w[..g.n].iter().sum();
                assert!((sum - 1.0).abs() < 1e-6);
            }
        }
    }
}

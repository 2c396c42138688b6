//! Overlap-save convolution over FFT tiles, for kernels too large to sum
//! directly.
//!
//! The output is cut into row bands of `vh = th - kh + 1` rows (one rayon
//! task each) and each band into tiles of `vw = tw - kw + 1` columns. A
//! `th x tw` tile of mirrored input around an output tile is transformed,
//! multiplied by the kernel's spectrum and transformed back; its circular
//! convolution equals the linear one on the `vh x vw` samples whose kernel
//! footprint did not wrap around, which are kept (overlap-save).
//!
//! The kernel is real, so a tile can carry two real planes at once, one in
//! the real and one in the imaginary part, and both come back unmixed: the
//! planes of a band (each tile, each channel) are paired up, halving the
//! transforms. 2-D transforms are rows, a transpose, columns; the inverse
//! only transforms the rows it keeps. Each band's result depends only on the
//! input, never on which thread ran it.

use std::sync::Arc;

use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

use super::convolve::{mirrored, Kernel};
use super::psf::smooth_len;
use crate::image::{ImageView, Sample};
use crate::parallel::for_each_band;

type C32 = Complex<f32>;

/// Smallest tile side: shorter transforms spend more on setup than on work.
const MIN_TILE: usize = 32;

/// Tile sides as multiples of the kernel's: the fraction of each transform
/// that is kept, `(t - k + 1) / t`, is ~7/8 across and ~3/4 down. Tiles
/// are shorter than wide because each band of tile rows is one task: a
/// 65-tap kernel gives 512 x 256 tiles, two thirds of each transform kept,
/// and ~21 bands for a 4000-row image, enough to keep several threads busy.
const TILE_W_FACTOR: usize = 8;
const TILE_H_FACTOR: usize = 4;

/// A tile side for a kernel of `k` taps over an image of `n` samples: a
/// power of two, but no longer than the smooth length the whole image needs.
fn tile_len(k: usize, n: usize, factor: usize) -> usize {
    let wanted = (factor * (k - 1)).max(MIN_TILE).next_power_of_two();
    wanted.min(smooth_len(n + k - 1))
}

/// Transforms and the kernel spectrum shared by all bands.
struct Plan {
    th: usize,
    tw: usize,
    /// Kept rows and columns of a tile.
    vh: usize,
    vw: usize,
    fwd_x: Arc<dyn Fft<f32>>,
    inv_x: Arc<dyn Fft<f32>>,
    fwd_y: Arc<dyn Fft<f32>>,
    inv_y: Arc<dyn Fft<f32>>,
    scratch_len: usize,
    /// The kernel's transform, column-major (`tw` columns of `th`), divided
    /// by `th tw` so that the inverse transforms need no scaling.
    spectrum: Vec<C32>,
}

impl Plan {
    fn new(k: Kernel<'_>, h: usize, w: usize) -> Self {
        let th = tile_len(k.h, h, TILE_H_FACTOR);
        let tw = tile_len(k.w, w, TILE_W_FACTOR);
        let mut planner = FftPlanner::new();
        let (fwd_x, inv_x) = (planner.plan_fft_forward(tw), planner.plan_fft_inverse(tw));
        let (fwd_y, inv_y) = (planner.plan_fft_forward(th), planner.plan_fft_inverse(th));
        let scratch_len = [&fwd_x, &inv_x, &fwd_y, &inv_y]
            .iter()
            .map(|f| f.get_inplace_scratch_len())
            .max()
            .unwrap_or(0);
        let mut plan = Self {
            th,
            tw,
            vh: th - k.h + 1,
            vw: tw - k.w + 1,
            fwd_x,
            inv_x,
            fwd_y,
            inv_y,
            scratch_len,
            spectrum: Vec::new(),
        };
        let mut s = plan.scratch();
        for (dst, src) in s.buf.chunks_exact_mut(tw).zip(k.taps.chunks_exact(k.w)) {
            for (d, &t) in dst.iter_mut().zip(src) {
                *d = C32::new(t as f32, 0.0);
            }
        }
        plan.forward(&mut s);
        let scale = 1.0 / (th * tw) as f32;
        plan.spectrum = s.tmp.iter().map(|v| v * scale).collect();
        plan
    }

    /// Zeroed buffers for one band.
    fn scratch(&self) -> Scratch {
        let n = self.th * self.tw;
        Scratch {
            buf: vec![C32::default(); n],
            tmp: vec![C32::default(); n],
            work: vec![C32::default(); self.scratch_len],
        }
    }

    /// 2-D transform of the row-major tile in `buf`; the result is left
    /// column-major in `tmp`.
    fn forward(&self, s: &mut Scratch) {
        self.fwd_x.process_with_scratch(&mut s.buf, &mut s.work);
        transpose::transpose(&s.buf, &mut s.tmp, self.tw, self.th);
        self.fwd_y.process_with_scratch(&mut s.tmp, &mut s.work);
    }

    /// Multiplies the spectrum in `tmp` by the kernel's and transforms back
    /// into row-major `buf`; only the kept rows (from `first_row`) are
    /// transformed along x.
    fn inverse(&self, s: &mut Scratch, first_row: usize) {
        for (v, k) in s.tmp.iter_mut().zip(&self.spectrum) {
            *v *= k;
        }
        self.inv_y.process_with_scratch(&mut s.tmp, &mut s.work);
        transpose::transpose(&s.tmp, &mut s.buf, self.th, self.tw);
        self.inv_x
            .process_with_scratch(&mut s.buf[first_row * self.tw..], &mut s.work);
    }
}

/// Per-band working memory.
struct Scratch {
    buf: Vec<C32>,
    tmp: Vec<C32>,
    work: Vec<C32>,
}

/// One real plane of a tile: its first output column and its channel.
type Plane = (usize, usize);

/// Convolves `image` with `k` (see the module docs) into `out`.
pub(super) fn convolve<T: Sample>(image: ImageView<'_, T>, k: Kernel<'_>, out: &mut [T]) {
    let (w, h, c) = (image.width(), image.height(), image.channels());
    let plan = Plan::new(k, h, w);
    let rows = mirrored(h, k.before_y(), h.div_ceil(plan.vh) * plan.vh + plan.th);
    let cols = mirrored(w, k.before_x(), w.div_ceil(plan.vw) * plan.vw + plan.tw);
    let planes: Vec<Plane> = (0..w.div_ceil(plan.vw))
        .flat_map(|t| (0..c).map(move |ch| (t * plan.vw, ch)))
        .collect();
    for_each_band(out, w * c, plan.vh, |y0, band| {
        let mut s = plan.scratch();
        for pair in planes.chunks(2) {
            gather(image, &rows[y0..y0 + plan.th], &cols, pair, &mut s.buf);
            plan.forward(&mut s);
            plan.inverse(&mut s, k.h - 1);
            scatter(&s.buf, &plan, k, pair, (w, c), band);
        }
    });
}

/// Fills the tile `buf` (rows of `cols` samples read at mirrored `rows`)
/// with plane `pair[0]` in the real and `pair[1]` (if any) in the imaginary
/// part.
fn gather<T: Sample>(
    image: ImageView<'_, T>,
    rows: &[usize],
    cols: &[usize],
    pair: &[Plane],
    buf: &mut [C32],
) {
    let c = image.channels();
    let tw = buf.len() / rows.len();
    let (xa, ca) = pair[0];
    for (&y, dst) in rows.iter().zip(buf.chunks_exact_mut(tw)) {
        let src = image.row(y);
        let re = cols[xa..xa + tw].iter().map(|&x| src[x * c + ca].to_f32());
        match pair.get(1) {
            Some(&(xb, cb)) => {
                let im = cols[xb..xb + tw].iter().map(|&x| src[x * c + cb].to_f32());
                for (d, (r, i)) in dst.iter_mut().zip(re.zip(im)) {
                    *d = C32::new(r, i);
                }
            }
            None => {
                for (d, r) in dst.iter_mut().zip(re) {
                    *d = C32::new(r, 0.0);
                }
            }
        }
    }
}

/// Writes the kept samples of the tile `buf` into the band's output rows:
/// the real part to plane `pair[0]`, the imaginary part to `pair[1]`.
fn scatter<T: Sample>(
    buf: &[C32],
    plan: &Plan,
    k: Kernel<'_>,
    pair: &[Plane],
    (w, c): (usize, usize),
    band: &mut [T],
) {
    for (v, out_row) in band.chunks_exact_mut(w * c).enumerate() {
        let kept = &buf[(k.h - 1 + v) * plan.tw + k.w - 1..];
        for (p, &(x0, ch)) in pair.iter().enumerate() {
            let n = plan.vw.min(w - x0);
            let dst = out_row[x0 * c + ch..].iter_mut().step_by(c);
            for (d, s) in dst.zip(&kept[..n]) {
                *d = T::from_f32(if p == 0 { s.re } else { s.im });
            }
        }
    }
}

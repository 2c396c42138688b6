//! Depth-aware defocus: render what a thin lens focused at one distance sees,
//! given a sharp (pinhole) image and its depth map.
//!
//! # Model
//! Every source pixel `q` at depth `z_q` is spread by the lens over a disc of
//! radius `r_q = coc(z_q) / (2 pixel_pitch)` pixels (the circle of confusion
//! of [`crate::optics::circle_of_confusion`]), carrying its light uniformly,
//! so with weight `1 / area`, which we take as `1 / (r_q + 1/2)^2` (the area of
//! the anti-aliased disc below, up to the common factor pi). Scattering every
//! disc and summing is computed as a gather: output pixel `p` visits the
//! neighbours `q` whose disc covers it and takes the normalised weighted mean
//! `sum_q w_q cov(q, p) I_q / sum_q w_q cov(q, p)`.
//!
//! The disc edge is anti-aliased, `cov = clamp(r + 1/2 - |p - q|, 0, 1)`, so
//! the blur grows continuously with the radius and a pixel whose disc is
//! narrower than one pixel (`r < 1/2`) covers only itself: in-focus regions are
//! returned unchanged, bit for bit.
//!
//! Occlusion follows depth order. A neighbour *nearer* than `p` spreads its
//! full disc over `p` (a blurred foreground veils whatever is behind it). A
//! neighbour *farther* than `p` is hidden by `p`'s own surface except within
//! `p`'s own blur, so its radius is clamped to `min(r_q, r_p)`. Hence
//! - a sharp foreground does not bleed into a blurred background: its discs
//!   are too small to reach any neighbour;
//! - a blurred background does not smear over a sharp foreground edge: behind
//!   a sharp `p` its radius is clamped to `r_p < 1/2`;
//! - two neighbours on the same blurred surface blur each other symmetrically
//!   up to their common radius, so a slanted plane blurs smoothly.
//!
//! This is the "scatter-as-gather" rule of real-time depth-of-field renderers
//! evaluated exactly per pair of pixels; it cannot recover what the pinhole
//! image never saw (background hidden behind a foreground object), so a
//! blurred foreground edge spreads over the visible background only.
//!
//! Borders are mirrored (`image::mirror`). The work is `O(r^2)` per pixel
//! where `r` is the largest radius reaching it, found per 16x16 tile, so
//! in-focus regions cost almost nothing; radii above [`MAX_RADIUS`] are
//! refused rather than silently taking minutes.

use crate::error::{positive, CoreError, Result};
use crate::image::{mirror, ImageView, Sample};
use crate::invalid;
use crate::optics::{circle_of_confusion, try_fill};
use crate::parallel::for_each_row;

/// Largest accepted circle-of-confusion radius in pixels (a 64 px wide disc).
/// A gather visits `~pi (r + 1)^2` neighbours per pixel: at this limit ~3400,
/// about 10 s for a fully blurred 12 MP RGB image on 2 cores. Larger blurs are
/// better rendered on a downscaled image and upsampled.
pub const MAX_RADIUS: f32 = 32.0;

/// Side of the square tiles over which the search radius is bounded. 16 px
/// tiles keep the tile map small (47 k tiles for 12 MP) while a tile's
/// radius is rarely much above that of its own pixels.
const TILE: usize = 16;

/// What the gather needs to know of a source pixel.
#[derive(Debug, Clone, Copy, Default)]
struct Disc {
    /// Depth, for the occlusion order.
    z: f32,
    /// Circle-of-confusion radius in pixels.
    r: f32,
    /// Light per unit area of the disc, `1 / (r + 1/2)^2`.
    w: f32,
}

/// Lens and sensor of a defocus render, all lengths in one unit (mm).
#[derive(Debug, Clone, Copy)]
pub struct Lens {
    /// Focal length.
    pub f: f64,
    /// f-number (focal length over aperture diameter).
    pub n: f64,
    /// Object distance the lens is focused at (> f).
    pub focus_distance: f64,
    /// Distance between pixel centres on the sensor.
    pub pixel_pitch: f64,
}

impl Lens {
    /// The disc of a source pixel at `depth`.
    fn disc(&self, depth: f64) -> Result<Disc> {
        if !(depth.is_finite() && depth > self.f) {
            return Err(invalid!(
                "depth must be finite and greater than the focal length f = {} \
                 (a surface at or inside the focal length forms no real image), got {depth}",
                self.f
            ));
        }
        let coc = circle_of_confusion(self.f, self.n, self.focus_distance, depth)?;
        let r = (coc / (2.0 * self.pixel_pitch)) as f32;
        if r > MAX_RADIUS {
            return Err(invalid!(
                "the circle of confusion at depth {depth} is {:.1} px wide, more than the \
                 supported {} px; use a larger pixel_pitch (a smaller image), a larger N or a \
                 focus distance nearer that depth",
                2.0 * r,
                2.0 * MAX_RADIUS
            ));
        }
        Ok(Disc {
            z: depth as f32,
            r,
            w: 1.0 / ((r + 0.5) * (r + 0.5)),
        })
    }
}

/// Renders `image` as seen through `lens`, blurring every pixel by its own
/// circle of confusion with depth-aware occlusion (see the module docs), into
/// `out` (contiguous, same height, width and channels as `image`).
///
/// `depth` holds one distance per pixel (row-major, `height * width`) in the
/// unit of `lens.f`; `f32` and `f64` depth maps are both accepted.
///
/// # Errors
/// Lens parameters not finite and positive, `focus_distance <= f`, a depth
/// that is not finite or not beyond `f` (the message names the pixel), a
/// circle of confusion wider than `2 MAX_RADIUS` px, or mismatched buffer
/// lengths.
pub fn render_defocus<T: Sample, Z: Copy + Into<f64> + Sync>(
    image: ImageView<'_, T>,
    depth: &[Z],
    lens: Lens,
    out: &mut [T],
) -> Result<()> {
    positive("f", lens.f)?;
    positive("N", lens.n)?;
    positive("pixel_pitch", lens.pixel_pitch)?;
    // Validates focus_distance against f once, with its own name.
    circle_of_confusion(lens.f, lens.n, lens.focus_distance, lens.focus_distance)?;
    let (w, h, c) = (image.width(), image.height(), image.channels());
    if depth.len() != w * h {
        return Err(CoreError::Shape(format!(
            "depth must have one value per pixel, {h}x{w} = {}, got {}",
            w * h,
            depth.len()
        )));
    }
    if out.len() != w * h * c {
        return Err(CoreError::Shape(format!(
            "output must hold {h}x{w}x{c} = {} samples, got {}",
            w * h * c,
            out.len()
        )));
    }
    let mut discs = vec![Disc::default(); w * h];
    try_fill(&mut discs, |i| lens.disc(depth[i].into())).map_err(|(i, e)| match e {
        CoreError::InvalidArgument(msg) => {
            invalid!("{msg} (at pixel row {}, column {})", i / w, i % w)
        }
        other => other,
    })?;
    gather(image, &discs, out);
    Ok(())
}

/// Search radius (in whole pixels) of each `TILE`x`TILE` tile: the largest
/// `r + 1/2` of any disc that can reach a pixel of the tile.
fn tile_search_radii(discs: &[Disc], w: usize, h: usize) -> (Vec<usize>, usize) {
    let (tw, th) = (w.div_ceil(TILE), h.div_ceil(TILE));
    let mut reach = vec![0.0f32; tw * th];
    for (y, row) in discs.chunks_exact(w).enumerate() {
        for (x, d) in row.iter().enumerate() {
            let t = &mut reach[(y / TILE) * tw + x / TILE];
            *t = t.max(d.r + 0.5);
        }
    }
    // Tiles whose indices differ by k >= 1 (Chebyshev) have pixels at least
    // (k - 1) TILE + 1 apart; a disc reaching that far must be searched for.
    let k_max = (MAX_RADIUS as usize + 1).div_ceil(TILE) + 1;
    let mut radii = vec![0usize; tw * th];
    for ty in 0..th {
        for tx in 0..tw {
            let mut best = 0.0f32;
            for sy in ty.saturating_sub(k_max)..(ty + k_max + 1).min(th) {
                for sx in tx.saturating_sub(k_max)..(tx + k_max + 1).min(tw) {
                    let k = sy.abs_diff(ty).max(sx.abs_diff(tx));
                    let gap = if k == 0 { 0 } else { (k - 1) * TILE + 1 };
                    let r = reach[sy * tw + sx];
                    if (gap as f32) < r {
                        best = best.max(r);
                    }
                }
            }
            // Neighbours are at least 1 px away: a reach of 1 or less
            // (every disc narrower than 1 px) needs no search at all.
            radii[ty * tw + tx] = if best <= 1.0 { 0 } else { best.ceil() as usize };
        }
    }
    let max = radii.iter().copied().max().unwrap_or(0);
    (radii, max)
}

/// Mirrored indices of `-pad..n + pad`, so the inner loop needs no branch
/// for the border.
fn mirrored(n: usize, pad: usize) -> Vec<usize> {
    (0..n + 2 * pad)
        .map(|i| mirror(i as isize - pad as isize, n))
        .collect()
}

/// Everything the per-pixel gather reads, shared by all row bands.
struct Gather<'a, T> {
    image: ImageView<'a, T>,
    discs: &'a [Disc],
    /// Search radius of each tile, row-major over `tiles_w` tiles a row.
    radii: Vec<usize>,
    tiles_w: usize,
    /// The largest search radius: the padding of the tables below.
    g_max: usize,
    /// Mirrored column / row of `i - g_max`.
    cols: Vec<usize>,
    rows: Vec<usize>,
    /// `|(dy, dx)|` for offsets in `-g_max..=g_max`, row-major.
    dist: Vec<f32>,
}

impl<'a, T: Sample> Gather<'a, T> {
    fn new(image: ImageView<'a, T>, discs: &'a [Disc]) -> Self {
        let (w, h) = (image.width(), image.height());
        let (radii, g_max) = tile_search_radii(discs, w, h);
        let side = 2 * g_max + 1;
        let dist = (0..side * side)
            .map(|i| {
                let dy = (i / side) as f32 - g_max as f32;
                let dx = (i % side) as f32 - g_max as f32;
                (dx * dx + dy * dy).sqrt()
            })
            .collect();
        Self {
            image,
            discs,
            radii,
            tiles_w: w.div_ceil(TILE),
            g_max,
            cols: mirrored(w, g_max),
            rows: mirrored(h, g_max),
            dist,
        }
    }

    /// Renders every row into `out`. `C` is the channel count when it is a
    /// common one (1, 3, 4), so the channel loop unrolls; 0 means "read it
    /// at run time". One body serves all of them.
    fn run<const C: usize>(&self, out: &mut [T]) {
        let (w, c) = (self.image.width(), self.image.channels());
        for_each_row(out, w * c, |y, out_row| {
            let mut acc = vec![0.0f32; c];
            for (x, out_px) in out_row.chunks_exact_mut(c).enumerate() {
                self.pixel::<C>(x, y, &mut acc, out_px);
            }
        });
    }

    /// Gathers output pixel `(x, y)`.
    #[inline(always)]
    fn pixel<const C: usize>(&self, x: usize, y: usize, acc: &mut [f32], out_px: &mut [T]) {
        let w = self.image.width();
        let p = self.discs[y * w + x];
        let g = self.radii[(y / TILE) * self.tiles_w + x / TILE];
        let g_max = self.g_max;
        acc.fill(0.0);
        let mut wsum = 0.0f32;
        for oy in g_max - g..=g_max + g {
            let dy = oy.abs_diff(g_max);
            let span = ((g * g - dy * dy) as f32).sqrt() as usize;
            let (lo, qy) = (g_max - span, self.rows[y + oy]);
            // Away from the left and right borders the columns are direct,
            // which lets the compiler drop the table look-up.
            wsum += if x >= span && x + span < w {
                self.row::<C>(p, (qy, oy), lo..=g_max + span, |ox| x + ox - g_max, acc)
            } else {
                self.row::<C>(p, (qy, oy), lo..=g_max + span, |ox| self.cols[x + ox], acc)
            };
        }
        // p always covers itself with weight `self_wt` (r_p + 1/2 - 0 >= 1/2).
        // When nothing else reached it, return it untouched: (wt I) / wt need
        // not round back to I in f32.
        let self_wt = (p.r + 0.5).min(1.0) * p.w;
        if wsum == self_wt {
            out_px.copy_from_slice(&self.image.row(y)[x * out_px.len()..(x + 1) * out_px.len()]);
        } else {
            for (o, a) in out_px.iter_mut().zip(acc.iter()) {
                *o = T::from_f32(a / wsum);
            }
        }
    }

    /// Adds the discs of source row `qy` (offset `oy - g_max` from the pixel)
    /// at offsets `oxs` that cover `p` into `acc`; returns their total weight.
    /// `col` maps an offset to the source column.
    #[inline(always)]
    fn row<const C: usize>(
        &self,
        p: Disc,
        (qy, oy): (usize, usize),
        oxs: std::ops::RangeInclusive<usize>,
        col: impl Fn(usize) -> usize,
        acc: &mut [f32],
    ) -> f32 {
        let c = if C == 0 { self.image.channels() } else { C };
        let w = self.image.width();
        let side = 2 * self.g_max + 1;
        let (disc_row, img_row) = (&self.discs[qy * w..(qy + 1) * w], self.image.row(qy));
        let dist_row = &self.dist[oy * side..(oy + 1) * side];
        // Register accumulators for the common channel counts; the run-time
        // channel count accumulates in `acc` directly.
        let mut local = [0.0f32; 4];
        let mut wsum = 0.0f32;
        for ox in oxs {
            let qx = col(ox);
            let q = disc_row[qx];
            // Occlusion: a farther neighbour reaches p only within p's blur.
            let r = if q.z > p.z { q.r.min(p.r) } else { q.r };
            // Branch-free: uncovered neighbours add a zero weight.
            let wt = (r + 0.5 - dist_row[ox]).clamp(0.0, 1.0) * q.w;
            wsum += wt;
            let src = &img_row[qx * c..(qx + 1) * c];
            if C == 0 {
                for (a, s) in acc.iter_mut().zip(src) {
                    *a += wt * s.to_f32();
                }
            } else {
                for (a, s) in local.iter_mut().zip(src) {
                    *a += wt * s.to_f32();
                }
            }
        }
        if C != 0 {
            for (a, l) in acc.iter_mut().zip(local) {
                *a += l;
            }
        }
        wsum
    }
}

/// The gather itself, row bands in parallel.
fn gather<T: Sample>(image: ImageView<'_, T>, discs: &[Disc], out: &mut [T]) {
    let g = Gather::new(image, discs);
    match image.channels() {
        1 => g.run::<1>(out),
        3 => g.run::<3>(out),
        4 => g.run::<4>(out),
        _ => g.run::<0>(out),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LENS: Lens = Lens {
        f: 50.0,
        n: 2.0,
        focus_distance: 1000.0,
        pixel_pitch: 0.02,
    };

    fn render<T: Sample>(img: &[T], depth: &[f64], w: usize, h: usize, c: usize) -> Vec<T> {
        let mut out = vec![T::default(); img.len()];
        let view = ImageView::contiguous(img, w, h, c).unwrap();
        render_defocus(view, depth, LENS, &mut out).unwrap();
        out
    }

    fn noise(n: usize) -> Vec<u8> {
        (0..n as u32)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
            .collect()
    }

    #[test]
    fn in_focus_image_is_returned_unchanged() {
        let (w, h) = (23, 17);
        let img = noise(w * h * 3);
        assert_eq!(render(&img, &vec![1000.0; w * h], w, h, 3), img);
    }

    #[test]
    fn constant_image_stays_constant_under_any_blur() {
        let (w, h) = (20, 13);
        let img = vec![0.375f32; w * h];
        let depth: Vec<f64> = (0..w * h).map(|i| 600.0 + 37.0 * i as f64).collect();
        for v in render(&img, &depth, w, h, 1) {
            assert!((v - 0.375).abs() < 1e-6, "{v}");
        }
    }

    #[test]
    fn out_of_focus_pixels_are_averaged_with_their_neighbours() {
        let (w, h) = (15, 15);
        let mut img = vec![0u16; w * h];
        img[7 * w + 7] = 60000;
        // r = 3 px at 1100 mm: the centre spreads to its neighbours, not to the corner.
        let out = render(&img, &vec![1100.0; w * h], w, h, 1);
        assert!(out[7 * w + 7] < 60000 && out[7 * w + 8] > 0);
        assert_eq!(out[0], 0);
    }

    #[test]
    fn bad_depth_names_the_pixel_and_large_blur_is_refused() {
        let img = [0u8; 6];
        let mut out = [0u8; 6];
        let view = ImageView::contiguous(&img, 3, 2, 1).unwrap();
        let mut depth = [1000.0f32; 6];
        depth[4] = 20.0;
        let err = render_defocus(view, &depth, LENS, &mut out)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("row 1, column 1") && err.contains("no real image"),
            "{err}"
        );
        let far = [1e9f32; 6];
        let err = render_defocus(view, &far, LENS, &mut out)
            .unwrap_err()
            .to_string();
        assert!(err.contains("supported 64 px"), "{err}");
        assert!(render_defocus(view, &far[..5], LENS, &mut out).is_err());
    }
}

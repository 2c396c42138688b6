//! Depth-aware defocus: render what a thin lens focused at one distance sees,
//! given a sharp (pinhole) image and its depth map.
//!
//! # Model
//! Every source pixel `q` at depth `z_q` is spread by the lens over a disc of
//! radius `r_q = coc(z_q) / (2 pixel_pitch)` pixels (the circle of confusion
//! of [`crate::optics::circle_of_confusion`]), carrying its light uniformly:
//! with weight `cov / A(r_q)`, `A` the disc's total coverage on the pixel
//! grid ([`disc_area`]), so that every pixel's light sums to 1 over its disc.
//! Scattering every disc and summing is computed as a gather: output pixel
//! `p` visits the neighbours `q` whose disc covers it.
//!
//! The disc edge is anti-aliased, `cov = clamp(r + 1/2 - |p - q|, 0, 1)`, so
//! the blur grows continuously with the radius and a pixel whose disc is
//! narrower than one pixel (`r < 1/2`) covers only itself: in-focus regions are
//! returned unchanged, bit for bit.
//!
//! Occlusion follows depth order, composited front to back at `p`:
//! - Neighbours *nearer* than `p` veil it: their light `F` and coverage
//!   `a_F` (their weights' sum) are laid over the rest, `F + (1 - a_F) S`
//!   (normalised if they cover it fully, `a_F >= 1`).
//! - `S` is `p`'s own surface: the neighbours as near as `p` or farther. A
//!   farther one is hidden by `p`'s surface except within `p`'s own blur, so
//!   its radius is clamped to `min(r_q, r_p)`. Where that surface covers `p`
//!   only partly (coverage `a_S < 1`: `p` is near the edge of a blurred
//!   object), the rest of `p`'s light comes from behind it, which the pinhole
//!   image hid: it is taken to be the farther neighbours' mean within `p`'s
//!   disc, `S = S_light + (1 - a_S) B`. With nothing farther in reach, or a
//!   full coverage, `S` is the surface's normalised mean.
//!
//! Hence
//! - a sharp foreground does not bleed into a blurred background: its discs
//!   are too small to reach any neighbour;
//! - a blurred background does not smear over a sharp foreground edge: behind
//!   a sharp `p` its radius is clamped to `r_p < 1/2`;
//! - a blurred foreground is soft on both sides of its edge, and a small
//!   blurred object keeps its light: a bright pixel in front of a dark
//!   background is spread over its disc (a normalised mean would return it
//!   whole and add the halo it casts);
//! - two neighbours on the same blurred surface blur each other symmetrically
//!   up to their common radius, so a slanted plane blurs smoothly, and a
//!   uniform depth is a normalised disc filter.
//!
//! This is the "scatter-as-gather" rule of real-time depth-of-field renderers
//! evaluated exactly per pair of pixels, with layered compositing of the
//! occluders; it cannot recover what the pinhole image never saw, so hidden
//! background is guessed from the visible background around it.
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
use std::sync::OnceLock;

/// Largest accepted circle-of-confusion radius in pixels (a 64 px wide disc).
/// A gather visits `~pi (r + 1)^2` neighbours per pixel, measured at ~6 ns
/// each per core on the 2-core development machine (three layers of light
/// each): a 12 MP RGB image blurred at r = 9 px takes ~8 s of CPU; at this
/// limit, ~3400 visits per pixel, it would take minutes. Larger blurs are
/// better rendered on a downscaled image and upsampled.
pub const MAX_RADIUS: f32 = 32.0;

/// Side of the square tiles over which the search radius is bounded. 16 px
/// tiles keep the tile map small (47 k tiles for 12 MP) while a tile's
/// radius is rarely much above that of its own pixels.
const TILE: usize = 16;

/// The layers a pixel's gather keeps apart: its occluders, its own surface
/// and what lies behind it.
const LAYERS: usize = 3;

/// What the gather needs to know of a source pixel.
#[derive(Debug, Clone, Copy, Default)]
struct Disc {
    /// Depth, for the occlusion order.
    z: f32,
    /// Circle-of-confusion radius in pixels.
    r: f32,
    /// Light per unit of coverage, `1 / A(r)` ([`disc_area`]).
    w: f32,
}

/// `A(r) = sum_o clamp(r + 1/2 - |o|, 0, 1)` over the integer offsets `o`:
/// the total coverage of an anti-aliased disc of radius `r` on the pixel
/// grid, the amount a pixel's light is divided by so that it sums to 1 over
/// its disc. Exact, from the offsets' distances sorted once: those up to
/// `r - 1/2` count 1, those below `r + 1/2` the rest of their ramp.
fn disc_area(r: f64) -> f64 {
    static DISTANCES: OnceLock<(Vec<f64>, Vec<f64>)> = OnceLock::new();
    let (dist, prefix) = DISTANCES.get_or_init(|| {
        let reach = MAX_RADIUS as i64 + 2;
        let mut dist: Vec<f64> = (-reach..=reach)
            .flat_map(|dy| (-reach..=reach).map(move |dx| ((dx * dx + dy * dy) as f64).sqrt()))
            .collect();
        dist.sort_by(f64::total_cmp);
        let prefix = std::iter::once(0.0)
            .chain(dist.iter().scan(0.0, |sum, d| {
                *sum += d;
                Some(*sum)
            }))
            .collect();
        (dist, prefix)
    });
    let full = dist.partition_point(|&d| d <= r - 0.5);
    let part = dist.partition_point(|&d| d < r + 0.5);
    full as f64 + (r + 0.5) * (part - full) as f64 - (prefix[part] - prefix[full])
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
            w: (1.0 / disc_area(f64::from(r))) as f32,
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
            let mut acc = vec![0.0f32; LAYERS * c];
            for (x, out_px) in out_row.chunks_exact_mut(c).enumerate() {
                self.pixel::<C>(x, y, &mut acc, out_px);
            }
        });
    }

    /// Gathers output pixel `(x, y)`: its occluders' light laid over its own
    /// surface's (see the module docs).
    #[inline(always)]
    fn pixel<const C: usize>(&self, x: usize, y: usize, acc: &mut [f32], out_px: &mut [T]) {
        let w = self.image.width();
        let p = self.discs[y * w + x];
        let g = self.radii[(y / TILE) * self.tiles_w + x / TILE];
        let g_max = self.g_max;
        acc.fill(0.0);
        let mut weights = [0.0f32; LAYERS];
        for oy in g_max - g..=g_max + g {
            let dy = oy.abs_diff(g_max);
            let span = ((g * g - dy * dy) as f32).sqrt() as usize;
            let (lo, qy) = (g_max - span, self.rows[y + oy]);
            // Away from the left and right borders the columns are direct,
            // which lets the compiler drop the table look-up.
            let row = if x >= span && x + span < w {
                self.row::<C>(p, (qy, oy), lo..=g_max + span, |ox| x + ox - g_max, acc)
            } else {
                self.row::<C>(p, (qy, oy), lo..=g_max + span, |ox| self.cols[x + ox], acc)
            };
            weights.iter_mut().zip(row).for_each(|(a, b)| *a += b);
        }
        let [front, own, behind] = weights;
        // p always covers itself with weight `self_wt` (r_p + 1/2 - 0 >= 1/2).
        // When nothing else reached it and nothing lies behind it, return it
        // untouched: (wt I) / wt need not round back to I in f32.
        let self_wt = (p.r + 0.5).min(1.0) * p.w;
        if front == 0.0 && own == self_wt && behind == 0.0 {
            out_px.copy_from_slice(&self.image.row(y)[x * out_px.len()..(x + 1) * out_px.len()]);
            return;
        }
        let c = out_px.len();
        for (k, o) in out_px.iter_mut().enumerate() {
            let (f, s, b) = (acc[k], acc[c + k], acc[2 * c + k]);
            let surface = if own >= 1.0 || behind == 0.0 {
                s / own
            } else {
                s + (1.0 - own) * b / behind
            };
            let v = if front >= 1.0 {
                f / front
            } else {
                f + (1.0 - front) * surface
            };
            *o = T::from_f32(v);
        }
    }

    /// Adds the discs of source row `qy` (offset `oy - g_max` from the pixel)
    /// at offsets `oxs` that cover `p` into `acc`, by layer: the light of
    /// nearer neighbours, of `p`'s own surface, and of the farther ones
    /// within `p`'s disc (for what `p`'s surface leaves uncovered); returns
    /// the weights of each. `col` maps an offset to the source column.
    #[inline(always)]
    fn row<const C: usize>(
        &self,
        p: Disc,
        (qy, oy): (usize, usize),
        oxs: std::ops::RangeInclusive<usize>,
        col: impl Fn(usize) -> usize,
        acc: &mut [f32],
    ) -> [f32; LAYERS] {
        let c = if C == 0 { self.image.channels() } else { C };
        let w = self.image.width();
        let side = 2 * self.g_max + 1;
        let (disc_row, img_row) = (&self.discs[qy * w..(qy + 1) * w], self.image.row(qy));
        let dist_row = &self.dist[oy * side..(oy + 1) * side];
        // Register accumulators for the common channel counts; the run-time
        // channel count accumulates in `acc` directly.
        let mut local = [[0.0f32; 4]; LAYERS];
        let mut sums = [0.0f32; LAYERS];
        for ox in oxs {
            let qx = col(ox);
            let (q, d) = (disc_row[qx], dist_row[ox]);
            // Occlusion: a farther neighbour reaches p only within p's blur.
            let r = if q.z > p.z { q.r.min(p.r) } else { q.r };
            // Branch-free: uncovered neighbours add zero weights.
            let wt = (r + 0.5 - d).clamp(0.0, 1.0) * q.w;
            let front = if q.z < p.z { wt } else { 0.0 };
            let behind = if q.z > p.z {
                (p.r + 0.5 - d).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let layer = [front, wt - front, behind];
            sums.iter_mut().zip(layer).for_each(|(a, b)| *a += b);
            let src = &img_row[qx * c..(qx + 1) * c];
            for (k, s) in src.iter().enumerate() {
                let v = s.to_f32();
                for (l, wl) in layer.iter().enumerate() {
                    if C == 0 {
                        acc[l * c + k] += wl * v;
                    } else {
                        local[l][k] += wl * v;
                    }
                }
            }
        }
        if C != 0 {
            for (l, light) in local.iter().enumerate() {
                for (a, v) in acc[l * c..(l + 1) * c].iter_mut().zip(light) {
                    *a += v;
                }
            }
        }
        sums
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
    fn disc_areas_are_the_sums_of_their_coverage() {
        for r in [0.0, 0.3, 0.5, 1.25, 2.0, 7.7, 31.9] {
            let g = (r + 1.0f64).ceil() as i64;
            let brute: f64 = (-g..=g)
                .flat_map(|dy| (-g..=g).map(move |dx| ((dx * dx + dy * dy) as f64).sqrt()))
                .map(|d| (r + 0.5 - d).clamp(0.0, 1.0))
                .sum();
            assert!(
                (disc_area(r) - brute).abs() < 1e-9,
                "r {r}: {}",
                disc_area(r)
            );
        }
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

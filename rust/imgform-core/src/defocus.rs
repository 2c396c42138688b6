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
//!
//! Speed: the pixels of a tile visit the same offsets, so eight or sixteen
//! adjacent ones are gathered together, one per vector lane, each offset's
//! neighbours one load per plane of their block's sources, converted once
//! to `f32` planes (depth, radius, weight, channels). Each lane computes its
//! pixel with the same operations in the same order as any other lane
//! count, so every instruction set gives the same bits. A 12 MP render of
//! `benchmarks/optics.py`'s scene takes 0.97 s with AVX-512 and 1.4 s with
//! AVX2, where a gather of one pixel at a time took 5.9 s; the discs' areas
//! are counted rather than searched for (`Offsets::count`).

use crate::error::{positive, CoreError, Result};
use crate::image::{mirror, ImageView, Sample};
use crate::invalid;
use crate::optics::{circle_of_confusion, try_fill};
use crate::parallel::{extend_filled, for_each_band};
use rayon::prelude::*;
use std::sync::OnceLock;

/// Largest accepted circle-of-confusion radius in pixels (a 64 px wide disc).
/// A gather visits `~pi (r + 1)^2` neighbours per pixel, measured at 0.85 ns
/// each per core with AVX-512 on the 2-core development machine (1.4 ns with
/// AVX2, 4.3 ns with SSE2; three layers of light each): a 12 MP RGB image
/// blurred at r = 11 px takes ~4.5 s of CPU; at this limit, ~3400 visits per
/// pixel, it would take ~35 s, minutes without AVX-512. Larger blurs are
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
    // A disc at most a pixel wide covers its own pixel alone, by r + 1/2:
    // what the sums below give too, without them (most pixels of a render
    // are in focus).
    if r <= 0.5 {
        return r + 0.5;
    }
    let offsets = Offsets::get();
    let full = offsets.count(r - 0.5, |d| d <= r - 0.5);
    let part = offsets.count(r + 0.5, |d| d < r + 0.5);
    let prefix = &offsets.prefix;
    full as f64 + (r + 0.5) * (part - full) as f64 - (prefix[part] - prefix[full])
}

/// The integer offsets within reach of the largest disc, by distance.
struct Offsets {
    /// Sums of the first `n` distances in increasing order, `n = 0..`.
    prefix: Vec<f64>,
    /// How many offsets lie within each squared distance `k`: `x^2 + y^2 <= k`.
    within: Vec<usize>,
    /// `sqrt(k)` for each `k` of `within`.
    roots: Vec<f64>,
}

impl Offsets {
    fn get() -> &'static Offsets {
        static OFFSETS: OnceLock<Offsets> = OnceLock::new();
        OFFSETS.get_or_init(|| {
            let reach = MAX_RADIUS as i64 + 2;
            let mut squares: Vec<i64> = (-reach..=reach)
                .flat_map(|dy| (-reach..=reach).map(move |dx| dx * dx + dy * dy))
                .collect();
            squares.sort_unstable();
            let prefix = std::iter::once(0.0)
                .chain(squares.iter().scan(0.0, |sum, &k| {
                    *sum += (k as f64).sqrt();
                    Some(*sum)
                }))
                .collect();
            let within = (0..=reach * reach)
                .map(|k| squares.partition_point(|&s| s <= k))
                .collect();
            let roots = (0..=reach * reach).map(|k| (k as f64).sqrt()).collect();
            Offsets {
                prefix,
                within,
                roots,
            }
        })
    }

    /// How many offsets have a distance `d` that passes `holds`, a test
    /// that passes up to a length near `t` and fails beyond it. `t^2` gives
    /// the last squared distance that passes but for rounding, which the
    /// test itself settles, on the same `sqrt` the distances were made of:
    /// so the count is the one a search of the sorted distances would give,
    /// in a few look-ups instead of two dozen steps.
    fn count(&self, t: f64, holds: impl Fn(f64) -> bool) -> usize {
        let last = self.within.len() - 1;
        let mut k = ((t * t) as usize).min(last);
        while k > 0 && !holds(self.roots[k]) {
            k -= 1;
        }
        while k < last && holds(self.roots[k + 1]) {
            k += 1;
        }
        self.within[k]
    }
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
    let mut discs = Vec::with_capacity(w * h);
    extend_filled(&mut discs, w * h, Disc::default());
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
    // A row of tiles at a time, in parallel: one pass over every disc.
    reach
        .par_chunks_mut(tw)
        .zip(discs.par_chunks(w * TILE))
        .for_each(|(tiles, rows)| {
            for row in rows.chunks_exact(w) {
                for (x, d) in row.iter().enumerate() {
                    let t = &mut tiles[x / TILE];
                    *t = t.max(d.r + 0.5);
                }
            }
        });
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

/// Output pixels the AVX-512 build gathers at once, one per lane of its
/// sixteen.
const LANES_WIDE: usize = 16;
/// Output pixels the other builds gather at once: AVX2's eight lanes.
/// Images narrower than this go one pixel at a time, rather than leave
/// most lanes idle.
const LANES: usize = 8;

/// Output rows and columns of the blocks whose sources are converted at
/// once ([`Sources`]): each block converts `2 g_max` rows and columns of
/// halo more than it renders, and its sources stay within the L2 cache
/// whatever the image's shape (under 0.9 MB at the largest radius with four
/// channels), where sources of whole rows took 375 MB for a 1 x 200000
/// image.
const BLOCK_ROWS: usize = 32;
const BLOCK_COLS: usize = 256;
// A block's pixels from a multiple of the lane count lie in one tile, so
// they visit the same offsets, and each offset's neighbours of all lanes
// are one contiguous load.
const _: () = assert!(
    TILE.is_multiple_of(LANES_WIDE)
        && TILE.is_multiple_of(LANES)
        && BLOCK_COLS.is_multiple_of(TILE)
);

/// Channels gathered in one pass: four sums of light per layer stay in
/// registers with the weights. Images with more channels take more passes.
const GROUP: usize = 4;

/// Sums of a group of lanes: light by layer and channel, weights by layer.
type Sums<const C: usize, const L: usize> = ([[[f32; L]; C]; LAYERS], [[f32; L]; LAYERS]);

/// Everything the gather reads, shared by all bands.
struct Gather<'a, T> {
    image: ImageView<'a, T>,
    discs: &'a [Disc],
    /// Search radius of each tile, row-major over `tiles_w` tiles a row.
    radii: Vec<usize>,
    tiles_w: usize,
    /// The largest search radius: the padding of the sources.
    g_max: usize,
    /// `|(dy, dx)|` for offsets in `-g_max..=g_max`, row-major.
    dist: Vec<f32>,
    /// Whether the image holds a NaN or an infinity ([`Gather::lanes`]).
    specials: bool,
}

/// A block's source pixels as the lanes read them, in planes of `pitch`
/// floats a row: the discs' depths, radii and light per unit of coverage,
/// then the channels gathered. Rows run from `g_max` above the block to
/// `g_max` below it, columns from `g_max` left of it to `g_max` right of
/// its width rounded up to whole groups of lanes, mirrored at the image's
/// borders, so the inner loop reads every neighbour with neither a bound
/// nor a table. One buffer serves a band's blocks in turn.
#[derive(Default)]
struct Sources {
    data: Vec<f32>,
    pitch: usize,
    /// Floats from one plane to the next.
    plane: usize,
}

impl Sources {
    /// `L` floats of plane `p` from index `i` of a plane.
    #[inline(always)]
    fn lanes<const L: usize>(&self, p: usize, i: usize) -> &[f32; L] {
        let at = p * self.plane + i;
        self.data[at..at + L].try_into().expect("L floats")
    }
}

/// The share of a pixel that a disc of radius `r` covers at distance `d`:
/// its anti-aliased edge.
#[inline(always)]
fn cover(r: f32, d: f32) -> f32 {
    (r + 0.5 - d).clamp(0.0, 1.0)
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
        let specials = (0..h)
            .into_par_iter()
            .any(|y| image.row(y).iter().any(|v| !v.is_finite()));
        Self {
            image,
            discs,
            radii,
            tiles_w: w.div_ceil(TILE),
            g_max,
            dist,
            specials,
        }
    }

    /// Renders channels `first..first + C` of every row into `out`, bands of
    /// rows in parallel, each through the widest build the CPU has. Every
    /// build computes each pixel with the same operations in the same order,
    /// whatever its lane count, so all give the same bits.
    fn run<const C: usize>(&self, first: usize, out: &mut [T]) {
        let (w, c) = (self.image.width(), self.image.channels());
        // At least 16 bands where the image has the rows, so that a short
        // image still keeps every core busy.
        let rows = self.image.height().div_ceil(16).clamp(1, BLOCK_ROWS);
        for_each_band(out, w * c, rows, |y0, rows| {
            if w < LANES {
                return self.band::<C, 1>(first, y0, rows);
            }
            #[cfg(target_arch = "x86_64")]
            {
                if crate::cpu::has_avx512() && w >= LANES_WIDE {
                    // SAFETY: AVX-512 support was detected just above.
                    return unsafe { self.band_avx512::<C>(first, y0, rows) };
                }
                if crate::cpu::has_avx2() {
                    // SAFETY: AVX2 support was detected just above.
                    return unsafe { self.band_avx2::<C>(first, y0, rows) };
                }
            }
            self.band::<C, LANES>(first, y0, rows);
        });
    }

    /// [`Gather::band`] compiled for AVX-512, sixteen pixels at a time.
    ///
    /// # Safety
    /// The CPU must support AVX-512 F.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,avx512f")]
    unsafe fn band_avx512<const C: usize>(&self, first: usize, y0: usize, out: &mut [T]) {
        self.band::<C, LANES_WIDE>(first, y0, out);
    }

    /// [`Gather::band`] compiled for AVX2, eight pixels at a time.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn band_avx2<const C: usize>(&self, first: usize, y0: usize, out: &mut [T]) {
        self.band::<C, LANES>(first, y0, out);
    }

    /// Renders channels `first..first + C` of the band of rows from `y0`
    /// into `out` (those rows, every channel), block by block, `L` pixels
    /// at a time.
    #[inline(always)]
    fn band<const C: usize, const L: usize>(&self, first: usize, y0: usize, out: &mut [T]) {
        let (w, c) = (self.image.width(), self.image.channels());
        let rows = out.len() / (w * c);
        let mut src = Sources::default();
        for x0 in (0..w).step_by(BLOCK_COLS) {
            let x1 = (x0 + BLOCK_COLS).min(w);
            let radius = |y: usize, x: usize| self.radii[(y / TILE) * self.tiles_w + x / TILE];
            let blurred = (y0..y0 + rows).any(|y| (x0..x1).step_by(TILE).any(|x| radius(y, x) > 0));
            if blurred {
                self.sources::<C, L>(first, (x0, x1), (y0, rows), &mut src);
            }
            for (dy, out_row) in out.chunks_exact_mut(w * c).enumerate() {
                let y = y0 + dy;
                for gx in (x0..x1).step_by(L) {
                    let pixels = &mut out_row[gx * c..(gx + L).min(x1) * c];
                    let g = radius(y, gx);
                    if g == 0 {
                        // Every disc that reaches these pixels is narrower than one.
                        for (x, px) in (gx..).zip(pixels.chunks_exact_mut(c)) {
                            self.copy::<C>(first, x, y, px);
                        }
                        continue;
                    }
                    let (light, weights) = if self.specials {
                        self.lanes::<C, L, true>(&src, (gx - x0, dy), g)
                    } else {
                        self.lanes::<C, L, false>(&src, (gx - x0, dy), g)
                    };
                    for (l, px) in pixels.chunks_exact_mut(c).enumerate() {
                        let layers = weights.map(|wl| wl[l]);
                        let light = light.map(|layer| layer.map(|ch| ch[l]));
                        let at = (gx + l, y);
                        self.composite::<C>(first, at, layers, light, !self.specials, px);
                    }
                }
            }
        }
    }

    /// Converts into `src` the [`Sources`] of the block of columns `x0..x1`
    /// and `rows` rows from `y0`, channels `first..first + C`, for groups of
    /// `L` lanes. The channels are halved, so that no difference of two
    /// finite values overflows ([`Gather::lanes`]).
    fn sources<const C: usize, const L: usize>(
        &self,
        first: usize,
        (x0, x1): (usize, usize),
        (y0, rows): (usize, usize),
        src: &mut Sources,
    ) {
        let (w, h, c) = (
            self.image.width(),
            self.image.height(),
            self.image.channels(),
        );
        let g = self.g_max as isize;
        src.pitch = (x1 - x0).next_multiple_of(L) + 2 * self.g_max;
        src.plane = (rows + 2 * self.g_max) * src.pitch;
        // Every float up to this length is written below.
        src.data.resize(src.plane * (3 + C), 0.0);
        let (pitch, plane, data) = (src.pitch, src.plane, &mut src.data);
        let cols: Vec<usize> = (0..pitch)
            .map(|i| mirror((x0 + i) as isize - g, w))
            .collect();
        for r in 0..rows + 2 * self.g_max {
            let y = mirror((y0 + r) as isize - g, h);
            let (discs, image) = (&self.discs[y * w..(y + 1) * w], self.image.row(y));
            for (i, &x) in cols.iter().enumerate() {
                let (d, at) = (discs[x], r * pitch + i);
                data[at] = d.z;
                data[plane + at] = d.r;
                data[2 * plane + at] = d.w;
                for k in 0..C {
                    data[(3 + k) * plane + at] = 0.5 * image[x * c + first + k].to_f32();
                }
            }
        }
    }

    /// The light and the weights, by layer (occluders, own surface, what lies
    /// behind it), that the discs around pixels `x0..x0 + L` of the block's
    /// row `dy` lay on each, over the offsets within `g` (see the module
    /// docs). Lane `l` is pixel `x0 + l`'s gather, in the same operations and
    /// order whatever `L`.
    ///
    /// The light is summed as each neighbour's difference from the pixel
    /// itself, in halves ([`Gather::sources`]): the sums' rounding then
    /// scales with the local contrast, not with the level, and a flat region
    /// comes back exactly flat. Where the image holds a NaN or an infinity
    /// (`SPECIALS`), whose differences would be NaN or infinite for every
    /// pixel around it, the light is summed as it is, and a neighbour whose
    /// disc misses the pixel adds nothing at all (not `0 x inf`, a NaN), so
    /// such values reach only what their discs cover.
    ///
    /// Each sum is one running sum per lane. Its rounding grows with the
    /// radius, on noise ~5e-7 of the range at 5 px, 8e-6 at 22 px and 1.1e-5
    /// at 32 px (1 in 65535 for 16-bit images); sums per row of offsets,
    /// added up at the end, kept it at 3e-7 but spilled the sums out of the
    /// registers, 1.5 times slower with AVX-512 and 3 times with AVX2.
    #[inline(always)]
    fn lanes<const C: usize, const L: usize, const SPECIALS: bool>(
        &self,
        src: &Sources,
        (x0, dy): (usize, usize),
        g: usize,
    ) -> Sums<C, L> {
        let g_max = self.g_max;
        let side = 2 * g_max + 1;
        let centre = (dy + g_max) * src.pitch + x0 + g_max;
        let (pz, pr) = (*src.lanes::<L>(0, centre), *src.lanes::<L>(1, centre));
        let pw = *src.lanes::<L>(2, centre);
        let pc: [[f32; L]; C] = if SPECIALS {
            [[0.0; L]; C]
        } else {
            std::array::from_fn(|k| *src.lanes::<L>(3 + k, centre))
        };
        let mut light = [[[0.0f32; L]; C]; LAYERS];
        let mut weights = [[0.0f32; L]; LAYERS];
        for oy in g_max - g..=g_max + g {
            let ay = oy.abs_diff(g_max);
            let span = ((g * g - ay * ay) as f32).sqrt() as usize;
            let dist = &self.dist[oy * side..(oy + 1) * side];
            let left = g_max - span;
            for (ox, &d) in (left..).zip(&dist[left..=g_max + span]) {
                let i = (dy + oy) * src.pitch + x0 + ox;
                let (qz, qr, qw) = (
                    src.lanes::<L>(0, i),
                    src.lanes::<L>(1, i),
                    src.lanes::<L>(2, i),
                );
                let q: [&[f32; L]; C] = std::array::from_fn(|k| src.lanes::<L>(3 + k, i));
                for l in 0..L {
                    // Occlusion: a farther neighbour reaches p only within p's blur.
                    let farther = qz[l] > pz[l];
                    let r = if farther { qr[l].min(pr[l]) } else { qr[l] };
                    // Branch-free: uncovered neighbours add zero weights.
                    let wt = cover(r, d) * qw[l];
                    let front = if qz[l] < pz[l] { wt } else { 0.0 };
                    // What lies behind weighs as p's own disc spreads it,
                    // so that its light sums to no more than its largest
                    // value (a sum of coverages reached ~3300 at 32 px and
                    // overflowed beyond 2e35).
                    let behind = if farther {
                        cover(pr[l], d) * pw[l]
                    } else {
                        0.0
                    };
                    let layer = [front, wt - front, behind];
                    for (sum, wl) in weights.iter_mut().zip(layer) {
                        sum[l] += wl;
                    }
                    for (acc, wl) in light.iter_mut().zip(layer) {
                        for ((ch, v), c) in acc.iter_mut().zip(q).zip(&pc) {
                            let add = wl * (v[l] - c[l]);
                            ch[l] += if SPECIALS && wl == 0.0 { 0.0 } else { add };
                        }
                    }
                }
            }
        }
        (light, weights)
    }

    /// Pixel `(x, y)`'s channels `first..first + C`, written into `px` (all
    /// its channels): its occluders' light laid over its own surface's (see
    /// the module docs), or the pixel as it is when nothing else reached it.
    /// The light is halves of differences from the pixel's own value, or
    /// halves of the light itself where not `differences`
    /// ([`Gather::lanes`]).
    #[inline(always)]
    fn composite<const C: usize>(
        &self,
        first: usize,
        (x, y): (usize, usize),
        [front, own, behind]: [f32; LAYERS],
        light: [[f32; C]; LAYERS],
        differences: bool,
        px: &mut [T],
    ) {
        let p = self.discs[y * self.image.width() + x];
        // p always covers itself with weight `self_wt` (r_p + 1/2 - 0 >= 1/2).
        // When nothing else reached it and nothing lies behind it, return it
        // untouched: (wt I) / wt need not round back to I in f32.
        let self_wt = (p.r + 0.5).min(1.0) * p.w;
        if front == 0.0 && own == self_wt && behind == 0.0 {
            return self.copy::<C>(first, x, y, px);
        }
        let at = x * self.image.channels() + first;
        let centre = &self.image.row(y)[at..at + C];
        for (k, (o, c)) in px[first..first + C].iter_mut().zip(centre).enumerate() {
            let (f, s, b) = (light[0][k], light[1][k], light[2][k]);
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
            let v = if differences {
                c.to_f32() + v + v
            } else {
                v + v
            };
            // One NaN for every build: vector and scalar instructions make
            // NaNs of different signs from the same inputs.
            *o = T::from_f32(if v.is_nan() { f32::NAN } else { v });
        }
    }

    /// Pixel `(x, y)`'s channels `first..first + C` as they are in the image.
    #[inline(always)]
    fn copy<const C: usize>(&self, first: usize, x: usize, y: usize, px: &mut [T]) {
        let at = x * self.image.channels() + first;
        px[first..first + C].copy_from_slice(&self.image.row(y)[at..at + C]);
    }
}

/// The gather itself: [`GROUP`] channels or fewer a pass (each pass
/// converts the discs again, a small share of its time).
fn gather<T: Sample>(image: ImageView<'_, T>, discs: &[Disc], out: &mut [T]) {
    let g = Gather::new(image, discs);
    let c = image.channels();
    for first in (0..c).step_by(GROUP) {
        match c - first {
            1 => g.run::<1>(first, out),
            2 => g.run::<2>(first, out),
            3 => g.run::<3>(first, out),
            _ => g.run::<GROUP>(first, out),
        }
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

    /// Renders channels `0..C` of `img` band by band with `L` lanes.
    fn render_lanes<const C: usize, const L: usize>(g: &Gather<'_, f32>, w: usize) -> Vec<f32> {
        let mut out = vec![0.0; g.discs.len() * C];
        for (band, rows) in out.chunks_mut(w * C * BLOCK_ROWS).enumerate() {
            g.band::<C, L>(0, band * BLOCK_ROWS, rows);
        }
        out
    }

    #[test]
    fn every_lane_count_gives_the_same_bits() {
        // Neither side a multiple of the lanes or the bands; depths on both
        // sides of the focus, so that every layer takes light; a NaN and
        // infinities, which spread through the blur.
        let (w, h) = (45 + BLOCK_COLS, 70);
        let mut img: Vec<f32> = noise(w * h * 3)
            .iter()
            .map(|&v| f32::from(v) / 255.0)
            .collect();
        img[3 * (9 * w + 20)] = f32::NAN;
        img[3 * (40 * w + 100) + 1] = f32::INFINITY;
        img[3 * (60 * w + 300) + 2] = f32::NEG_INFINITY;
        let discs: Vec<Disc> = noise(w * h)
            .iter()
            .map(|&v| LENS.disc(700.0 + 8.0 * f64::from(v)).unwrap())
            .collect();
        let g = Gather::new(ImageView::contiguous(&img, w, h, 3).unwrap(), &discs);
        assert!(g.g_max > 4, "{}", g.g_max);
        let bits = |v: Vec<f32>| v.into_iter().map(f32::to_bits).collect::<Vec<_>>();
        let one = bits(render_lanes::<3, 1>(&g, w));
        assert!(one.iter().any(|&b| f32::from_bits(b).is_nan()));
        assert_eq!(bits(render_lanes::<3, LANES>(&g, w)), one);
        assert_eq!(bits(render_lanes::<3, LANES_WIDE>(&g, w)), one);
        let mut whole = vec![0.0; img.len()];
        gather(g.image, &discs, &mut whole);
        assert_eq!(bits(whole), one);
    }

    #[test]
    fn disc_areas_count_as_a_search_of_the_sorted_distances_would() {
        let reach = MAX_RADIUS as i64 + 2;
        let mut dist: Vec<f64> = (-reach..=reach)
            .flat_map(|dy| (-reach..=reach).map(move |dx| ((dx * dx + dy * dy) as f64).sqrt()))
            .collect();
        dist.sort_by(f64::total_cmp);
        let offsets = Offsets::get();
        // Radii that put r -/+ 1/2 on every distance, and just beside it.
        let mut radii: Vec<f64> = (0..1200)
            .map(|k| (k as f64).sqrt())
            .flat_map(|d| [d - 0.5, d + 0.5])
            .flat_map(|r| [r, r.next_down(), r.next_up()])
            .filter(|&r| r > 0.5 && r <= f64::from(MAX_RADIUS))
            .collect();
        radii.extend((0..3200).map(|i| 0.51 + f64::from(i) * 0.01));
        for r in radii {
            let full = dist.partition_point(|&d| d <= r - 0.5);
            let part = dist.partition_point(|&d| d < r + 0.5);
            assert_eq!(offsets.count(r - 0.5, |d| d <= r - 0.5), full, "r {r}");
            assert_eq!(offsets.count(r + 0.5, |d| d < r + 0.5), part, "r {r}");
        }
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

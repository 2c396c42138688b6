//! Three-colour alignment (lecture section 4): find the shift that lands one
//! colour channel on another by scoring every candidate in `[-k, k]^2`.
//!
//! Shifts follow CONVENTIONS.md: `(dy, dx)` is what `np.roll(moving, (dy, dx),
//! axis=(0, 1))` needs to land `moving` on `reference` (scikit-image's
//! `phase_cross_correlation` convention).
//!
//! A full-resolution glass plate (~3200 x 3700 pixels, shifts of 100+ pixels)
//! would need ~60 000 candidates at full resolution. The coarse-to-fine
//! pyramid searches the whole range only at a level small enough that it is
//! at most [`COARSE_RADIUS`] pixels, then refines by [`REFINE_RADIUS`] at each
//! finer level: a few hundred candidates at the top, 25 per level below.

mod correlate;
mod ecc;
mod metric;
mod motion;
mod pyramid;
mod search;

pub use ecc::{refine, refine_many, EccOptions, Refined};
pub use metric::Metric;
pub use motion::{invert, Matrix, Motion, IDENTITY};
use pyramid::{Converted, Plane, Rows};

use crate::error::{CoreError, Result};
use crate::image::{ImageView, Sample};
use crate::invalid;
use search::{Candidates, Window};

/// Largest search radius (in pixels of that level) `Pyramid::Auto` accepts at
/// the coarsest level: 17 x 17 = 289 candidates.
pub const COARSE_RADIUS: i64 = 8;

/// Radius searched around twice the coarser level's shift. The doubled
/// coarse shift is within 1 pixel of the truth (rounding at the coarse
/// level); 2 leaves one pixel of slack for features that differ between
/// levels and keeps a neighbour on each side of the peak for the subpixel fit.
pub const REFINE_RADIUS: i64 = 2;

/// The smallest side `Pyramid::Auto` lets a level shrink to: below ~64 pixels
/// a plate has too little structure for the coarse search to be reliable.
pub const MIN_LEVEL_SIDE: usize = 64;

/// Fewest pixels per axis the worst-case overlap must keep: fewer leaves no
/// variance for NCC to measure.
pub const MIN_OVERLAP: usize = 2;

/// What the channels are compared on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Features {
    /// The intensities themselves.
    Intensity,
    /// The Sobel gradient magnitude, for channels whose brightness differs.
    Gradient,
}

impl Features {
    /// Parses `"intensity"` or `"gradient"`.
    ///
    /// # Errors
    /// [`CoreError::InvalidArgument`] naming the unknown value.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "intensity" => Ok(Self::Intensity),
            "gradient" => Ok(Self::Gradient),
            other => Err(invalid!(
                "unknown features {other:?}; accepted: \"intensity\", \"gradient\""
            )),
        }
    }
}

/// How many times the images are halved before the search.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pyramid {
    /// Halve while the search radius exceeds [`COARSE_RADIUS`] and the
    /// halved image keeps at least [`MIN_LEVEL_SIDE`] pixels per side.
    Auto,
    /// Exactly this many halvings; 0 is a single-scale exhaustive search.
    Levels(usize),
}

/// Parameters of [`align`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// Largest `|dy|` and `|dx|` searched, in full-resolution pixels.
    pub max_shift: i64,
    pub metric: Metric,
    /// Fraction of each border left out of the comparison, in `[0, 0.5)`:
    /// scanned plates have damaged, unevenly exposed edges.
    pub crop: f64,
    pub pyramid: Pyramid,
    pub features: Features,
    /// Refine the peak with a quadratic fit per axis.
    pub subpixel: bool,
}

/// What one level of the pyramid searched and found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Level {
    /// Downsampling factor of the level (1 = full resolution).
    pub scale: usize,
    /// Number of candidates scored.
    pub candidates: usize,
    /// Best shift, in pixels of this level.
    pub shift: (i64, i64),
    pub score: f64,
}

/// The result of [`align`].
#[derive(Debug, Clone, PartialEq)]
pub struct Alignment {
    /// The shift (integer unless `subpixel`).
    pub shift: (f64, f64),
    /// Score of the best integer shift at full resolution.
    pub score: f64,
    /// Full-resolution scores, `side x side` row-major; entry `(i, j)` is the
    /// shift `surface_origin + (i, j)`; NaN where not searched.
    pub surface: Vec<f64>,
    pub side: usize,
    pub surface_origin: (i64, i64),
    /// Coarsest level first.
    pub levels: Vec<Level>,
}

/// Checks that two views have the same size.
fn same_size<T: Copy>(
    a: &ImageView<'_, T>,
    b: &ImageView<'_, T>,
    names: (&str, &str),
) -> Result<()> {
    if (a.height(), a.width(), a.channels()) != (b.height(), b.width(), b.channels()) {
        return Err(CoreError::Shape(format!(
            "{} and {} must have the same shape, got {}x{}x{} and {}x{}x{}",
            names.0,
            names.1,
            a.height(),
            a.width(),
            a.channels(),
            b.height(),
            b.width(),
            b.channels()
        )));
    }
    Ok(())
}

/// The metric between two whole single-channel images of the same size, with
/// no shift and no crop: exactly the score [`align`] gives the shift (0, 0)
/// with `crop = 0`.
///
/// # Errors
/// [`CoreError::Shape`] for different shapes or more than one channel;
/// [`CoreError::InvalidArgument`] for NaN or infinite samples.
pub fn similarity<T: Sample>(
    a: &ImageView<'_, T>,
    b: &ImageView<'_, T>,
    metric: Metric,
) -> Result<f64> {
    same_size(a, b, ("a", "b"))?;
    let (mut pa, mut pb) = (Converted::new(a, "a")?, Converted::new(b, "b")?);
    Converted::centre(&mut pa, &mut pb, metric);
    let zero = Candidates {
        center: (0, 0),
        radius: 0,
        limit: 0,
    };
    let window = Window::cropped(pa.width(), pa.height(), 0.0);
    Ok(search::surface(&pa, &pb, metric, window, zero)[0])
}

/// The number of halvings to use, after checking the search fits every level.
fn level_count(width: usize, height: usize, opts: &Options) -> Result<usize> {
    let levels = match opts.pyramid {
        Pyramid::Levels(n) => n,
        Pyramid::Auto => {
            let mut n = 0;
            while ceil_shift(opts.max_shift, n) > COARSE_RADIUS
                && width.min(height) >> (n + 1) >= MIN_LEVEL_SIDE
            {
                n += 1;
            }
            n
        }
    };
    for l in 0..=levels {
        let (w, h) = (width >> l, height >> l);
        let k = ceil_shift(opts.max_shift, l);
        let (rows, cols) = if w == 0 || h == 0 {
            (0, 0)
        } else {
            Window::cropped(w, h, opts.crop).worst_overlap(w, h, k)
        };
        if rows < MIN_OVERLAP || cols < MIN_OVERLAP {
            return Err(invalid!(
                "images of {height}x{width} are too small for max_shift={} with crop={} at \
                 pyramid level {l} ({h}x{w} pixels, shifts up to {k}): the overlap must keep at \
                 least {MIN_OVERLAP} pixels per axis; use a smaller max_shift, crop or pyramid",
                opts.max_shift,
                opts.crop
            ));
        }
    }
    Ok(levels)
}

/// `ceil(k / 2^level)`: the largest shift at a level.
fn ceil_shift(k: i64, level: usize) -> i64 {
    (k + (1 << level) - 1) >> level
}

/// Finds the shift that best lands `moving` on `reference`.
///
/// # Errors
/// [`CoreError::Shape`] for different shapes or multi-channel images;
/// [`CoreError::InvalidArgument`] for NaN samples, `max_shift` negative or not
/// smaller than the image, `crop` outside `[0, 0.5)`, or images too small for
/// the search at some level.
pub fn align<T: Sample>(
    reference: &ImageView<'_, T>,
    moving: &ImageView<'_, T>,
    opts: &Options,
) -> Result<Alignment> {
    same_size(reference, moving, ("reference", "moving"))?;
    let (w, h) = (reference.width(), reference.height());
    if !(opts.crop.is_finite() && (0.0..0.5).contains(&opts.crop)) {
        return Err(invalid!("crop must be in [0, 0.5), got {}", opts.crop));
    }
    if opts.max_shift < 0 || opts.max_shift as usize >= w.min(h) {
        return Err(invalid!(
            "max_shift must be >= 0 and smaller than the image ({h}x{w}), got {}",
            opts.max_shift
        ));
    }
    let n_levels = level_count(w, h, opts)?;
    let (mut r0, mut m0) = (
        Converted::new(reference, "reference")?,
        Converted::new(moving, "moving")?,
    );
    Converted::centre(&mut r0, &mut m0, opts.metric);
    // Levels 1..=n_levels; level 0 is read from the caller's images.
    let mut coarse: Vec<(Plane, Plane)> = Vec::with_capacity(n_levels);
    for _ in 0..n_levels {
        let next = match coarse.last() {
            None => (Plane::downsample(&r0), Plane::downsample(&m0)),
            Some((r, m)) => (Plane::downsample(r), Plane::downsample(m)),
        };
        coarse.push(next);
    }
    let mut levels = Vec::with_capacity(n_levels + 1);
    let mut found = (0i64, 0i64);
    let mut last = None;
    for l in (0..=n_levels).rev() {
        let limit = ceil_shift(opts.max_shift, l);
        let cands = if l == n_levels {
            Candidates {
                center: (0, 0),
                radius: limit,
                limit,
            }
        } else {
            Candidates {
                center: (2 * found.0, 2 * found.1),
                radius: REFINE_RADIUS,
                limit,
            }
        };
        let surface = match l {
            0 => level_surface(&r0, &m0, opts, cands),
            _ => {
                let (r, m) = &coarse[l - 1];
                level_surface(r, m, opts, cands)
            }
        };
        // Every level keeps an overlap (checked above), so the centre's
        // in-limit neighbourhood always holds a score.
        let k = search::best(&surface, opts.metric, cands)
            .ok_or_else(|| invalid!("no candidate shift could be scored at level {l}"))?;
        let side = cands.side();
        found = cands.shift(k / side, k % side);
        levels.push(Level {
            scale: 1 << l,
            candidates: surface.iter().filter(|v| !v.is_nan()).count(),
            shift: found,
            score: surface[k],
        });
        last = Some((surface, cands, k));
    }
    let (surface, cands, k) = last.expect("the loop runs at least once");
    let side = cands.side();
    let (i, j) = (k / side, k % side);
    let mut shift = (found.0 as f64, found.1 as f64);
    if opts.subpixel {
        let at = |i: usize, j: usize| surface[i * side + j];
        let up = (i > 0).then(|| at(i - 1, j));
        let down = (i + 1 < side).then(|| at(i + 1, j));
        let left = (j > 0).then(|| at(i, j - 1));
        let right = (j + 1 < side).then(|| at(i, j + 1));
        shift.0 += vertex(up, at(i, j), down, opts.metric);
        shift.1 += vertex(left, at(i, j), right, opts.metric);
    }
    Ok(Alignment {
        shift,
        score: surface[k],
        surface,
        side,
        surface_origin: cands.shift(0, 0),
        levels,
    })
}

/// The scores of `cands` on one level, on intensities or gradients.
fn level_surface<S: Rows>(r: &S, m: &S, opts: &Options, cands: Candidates) -> Vec<f64> {
    let window = Window::cropped(r.width(), r.height(), opts.crop);
    match opts.features {
        Features::Intensity => scores(r, m, opts.metric, window, cands),
        Features::Gradient => {
            let (gr, gm) = (Plane::gradient(r), Plane::gradient(m));
            scores(&gr, &gm, opts.metric, window, cands)
        }
    }
}

/// The scores of `cands`: by one FFT correlation where that is the faster
/// ([`correlate::pays`]: a wide search), each scored directly otherwise.
///
/// SSD always scores directly: its sums of squared differences are then
/// exact at a perfect match (0 for an image against itself), where the
/// correlation's `sum a^2 + sum b^2 - 2 sum a b` leaves rounding.
fn scores<S: Rows>(r: &S, m: &S, metric: Metric, window: Window, cands: Candidates) -> Vec<f64> {
    if metric != Metric::Ssd && correlate::pays(window, cands, r.width(), r.height()) {
        correlate::surface(r, m, metric, window, cands)
    } else {
        search::surface(r, m, metric, window, cands)
    }
}

/// Offset of the vertex of the parabola through `(-1, m)`, `(0, c)`, `(1, p)`
/// from 0, in `[-0.5, 0.5]`; 0 when a neighbour is missing or the parabola
/// does not open the way the metric's optimum does (a plateau, a ridge).
///
/// SSD's scores are distances, the square roots of the sums, whose surface
/// is a V at its minimum: a parabola through them pulls the vertex towards
/// the integer shift (2.166 for 2.25). It goes through the sums themselves,
/// which a small shift of a smooth image changes quadratically.
fn vertex(m: Option<f64>, c: f64, p: Option<f64>, metric: Metric) -> f64 {
    let (Some(m), Some(p)) = (m, p) else {
        return 0.0;
    };
    let (m, c, p) = if metric == Metric::Ssd {
        (m * m, c * c, p * p)
    } else {
        (m, c, p)
    };
    let curvature = m - 2.0 * c + p;
    let opens = if metric.higher_is_better() {
        curvature < 0.0
    } else {
        curvature > 0.0
    };
    if !opens || !curvature.is_finite() {
        return 0.0;
    }
    (0.5 * (m - p) / curvature).clamp(-0.5, 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Smooth (no aliasing at 1/4 scale) and not periodic.
    fn pattern(x: f64, y: f64) -> f32 {
        let v = 0.5
            + 0.15 * (0.06 * x + 0.02 * y).sin()
            + 0.15 * (0.025 * x - 0.05 * y).cos()
            + 0.1 * (0.0004 * x * y).sin();
        v as f32
    }

    fn image(w: usize, h: usize, dy: f64, dx: f64) -> Vec<f32> {
        (0..h)
            .flat_map(|y| (0..w).map(move |x| pattern(x as f64 + dx, y as f64 + dy)))
            .collect()
    }

    fn opts(max_shift: i64) -> Options {
        Options {
            max_shift,
            metric: Metric::Ncc,
            crop: 0.1,
            pyramid: Pyramid::Auto,
            features: Features::Intensity,
            subpixel: false,
        }
    }

    #[test]
    fn pyramid_recovers_a_large_shift() {
        let (w, h) = (400, 360);
        let r = image(w, h, 0.0, 0.0);
        let m = image(w, h, 27.0, -21.0);
        let (rv, mv) = (
            ImageView::contiguous(&r, w, h, 1).unwrap(),
            ImageView::contiguous(&m, w, h, 1).unwrap(),
        );
        for features in [Features::Intensity, Features::Gradient] {
            let got = align(
                &rv,
                &mv,
                &Options {
                    features,
                    ..opts(30)
                },
            )
            .unwrap();
            assert_eq!(got.shift, (27.0, -21.0), "{features:?}");
            assert_eq!(got.levels.len(), 3);
            assert!(
                got.levels.iter().all(|l| l.candidates <= 17 * 17),
                "{:?}",
                got.levels
            );
            assert_eq!(got.side, 5);
        }
    }

    #[test]
    fn subpixel_refines_towards_a_fractional_shift() {
        let (w, h) = (120, 100);
        let r = image(w, h, 0.0, 0.0);
        let m = image(w, h, 2.3, -1.0);
        let (rv, mv) = (
            ImageView::contiguous(&r, w, h, 1).unwrap(),
            ImageView::contiguous(&m, w, h, 1).unwrap(),
        );
        let got = align(
            &rv,
            &mv,
            &Options {
                subpixel: true,
                ..opts(5)
            },
        )
        .unwrap();
        assert!((got.shift.0 - 2.3).abs() < 0.15, "{:?}", got.shift);
        assert!((got.shift.1 + 1.0).abs() < 0.15, "{:?}", got.shift);
    }

    #[test]
    fn bad_input_is_refused() {
        let a = vec![0.5f32; 30 * 30];
        let b = vec![0.5f32; 30 * 31];
        let av = ImageView::contiguous(&a, 30, 30, 1).unwrap();
        let bv = ImageView::contiguous(&b, 31, 30, 1).unwrap();
        assert!(matches!(
            align(&av, &bv, &opts(3)),
            Err(CoreError::Shape(_))
        ));
        for k in [-1, 30, 100] {
            let e = align(&av, &av, &opts(k)).unwrap_err().to_string();
            assert!(e.contains("max_shift"), "{e}");
        }
        let e = align(&av, &av, &opts(27)).unwrap_err().to_string();
        assert!(e.contains("too small"), "{e}");
        let e = align(
            &av,
            &av,
            &Options {
                crop: 0.5,
                ..opts(3)
            },
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("crop"), "{e}");
    }

    #[test]
    fn constant_images_align_at_zero() {
        let a = vec![7u8; 40 * 40];
        let v = ImageView::contiguous(&a, 40, 40, 1).unwrap();
        let got = align(&v, &v, &opts(4)).unwrap();
        assert_eq!((got.shift, got.score), ((0.0, 0.0), 0.0));
        assert_eq!(similarity(&v, &v, Metric::Ssd).unwrap(), 0.0);
    }
}

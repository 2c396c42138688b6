//! Bayer demosaicing: estimating the two colours each photosite did not see.
//!
//! Every method shares one skeleton. The output is cut into bands of rows,
//! one rayon task each. A task converts the raw rows it needs to `f32` once,
//! into a small ring of rows padded by mirroring on both sides, so the inner
//! loops never test for a border; vertical borders are mirrored when a ring
//! row is loaded. The kernels then compute in `f32` and convert each output
//! sample once (integers rounded half up and clamped, floats untouched; see
//! [`Sample`]). Extra memory is a few padded rows per running task, never a
//! full-size temporary.
//!
//! Phases are handled by offsets, not by copies of the kernels: each row is
//! either a "red row" (red and green sites) or a "blue row" (blue and green),
//! and its chroma sites sit on one column parity. A kernel computes, at each
//! site, the row's own chroma, green, and the other chroma into
//! planar rows; a shared writer converts them and puts them into R, G, B
//! order.
//!
//! Mirroring without repeating the edge ([`mirror`]) keeps the CFA parity,
//! so a border pixel sees a plausible mosaic and no black frame or
//! wrap-around appears.

mod ahd;
mod bilinear;
mod boxsum;
mod cnn;
mod differences;
mod ensemble;
mod fusion;
mod hamilton_adams;
mod leung2011;
mod malvar2004;
mod markesteijn;
mod menon2007;
mod mlri;
mod nearest;
mod oriented;
mod raisr;
mod rcd;
mod refined;
mod ring;
mod saturation;
mod tiled;
mod xtrans;

use crate::cfa::{check_out_len, CfaPattern};
use crate::error::{positive, CoreError, Result};
use crate::image::{mirror, ImageView, Sample};
use crate::invalid;
use crate::parallel::for_each_band;
use menon2007::Menon2007;
use rcd::Rcd;
use tiled::TileKernel;

/// A demosaicing method.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Each 2x2 cell's red and blue, and the green of the same row, copied to
    /// the cell's pixels: the cheapest reconstruction, blocky by design.
    Nearest,
    /// Average of the nearest samples of each colour (3x3 support). The
    /// only method that also accepts X-Trans, as the weighted mean of each
    /// colour's samples in the smallest window holding one.
    Bilinear,
    /// Malvar, He and Cutler, "High-quality linear interpolation for
    /// demosaicing of Bayer-patterned color images", ICASSP 2004: bilinear
    /// plus a Laplacian correction from the site's own colour (5x5 support).
    Malvar2004,
    /// Hamilton and Adams, US patent 5,629,734 (1997): green interpolated
    /// along the direction with the smaller gradient plus second derivative,
    /// then red and blue from colour differences to green, again choosing
    /// the better diagonal at the opposite chroma site.
    HamiltonAdams,
    /// Ratio Corrected Demosaicing, Luis Sanz Rodríguez (2017): green from
    /// cardinal neighbours corrected by low-pass luminance ratios, weighted
    /// by a local direction statistic, then colour differences along the
    /// diagonals and the cardinals. Outputs are clamped to the input's range.
    Rcd,
    /// Menon, Andriani and Calvagno, "Demosaicing with directional
    /// filtering and a posteriori decision", IEEE TIP 2007, with its
    /// refinement step. Outputs are clamped to the input's range.
    Menon2007,
    /// The mean of [`Method::Rcd`] and [`Method::Menon2007`]: not from the
    /// literature, but their errors are weakly correlated, so the mean beats
    /// both (39.63 dB mean CPSNR on the benchmark images against 38.68 and
    /// 38.76). Outputs are clamped to the input's range.
    RcdMenon,
    /// Hirakawa and Parks, "Adaptive homogeneity-directed demosaicing
    /// algorithm", IEEE TIP 2005: row- and column-interpolated images, the
    /// more homogeneous in CIELab chosen per pixel. Outputs are clamped to
    /// the input's range.
    Ahd,
    /// Frequency-domain luma-chroma demultiplexing: the mosaic as luma plus
    /// chroma modulated at (π, π), (π, 0) and (0, π) (Alleysson, Süsstrunk
    /// and Hérault, IEEE TIP 2005), the less aliased of the two (π, 0) /
    /// (0, π) chroma copies preferred per pixel (Dubois, IEEE SPL 2005),
    /// with least-squares-designed filters (Leung, Jeon and Dubois, IEEE TIP
    /// 2011), separable here. Outputs are clamped to the input's range.
    Leung2011,
    /// Kiku, Monno, Tanaka and Okutomi, "Minimized-Laplacian residual
    /// interpolation for color image demosaicking", Proc. SPIE 9023, 2014:
    /// directional guided filters fitted on Laplacians give tentative
    /// values whose residuals are interpolated instead of colour
    /// differences; red and blue follow from the full green the same way.
    /// Outputs are clamped to the input's range.
    Mlri,
    /// A learned refinement of [`Method::Mlri`] in the manner of Romano,
    /// Isidoro and Milanfar, "RAISR: Rapid and Accurate Image Super
    /// Resolution", IEEE TCI 2017: per CFA position and structure-tensor
    /// class, a least-squares linear filter predicts the residual of the
    /// missing colours. Not flip-symmetric (the filters are learned).
    /// Outputs are clamped to the input's range.
    Raisr,
    /// [`Method::Raisr`] with a hash of orientation and shape alone: per CFA
    /// position, quadrant of the structure tensor's orientation and
    /// whether the tensor is anisotropic (32 classes), a least-squares
    /// linear filter predicts the residual of MLRI's missing colours. Its
    /// filters run sixteen pixels side by side, at a small fraction of
    /// RAISR's cost, for most of its gain. Not flip-symmetric.
    /// Outputs are clamped to the input's range.
    RaisrFast,
    /// Residual-interpolated green (MLRI's green stage, Kiku et al. 2013)
    /// with red and blue by colour differences, each interpolated along
    /// the smoother of two directions in the manner of Hamilton and Adams
    /// and GBTF's weights: the base of [`Method::RaisrCd`], ~40 % cheaper
    /// than MLRI, whose red / blue guided filters it replaces. Outputs are
    /// clamped to the input's range.
    RiCd,
    /// [`Method::RaisrFast`]'s orientation-hashed filters trained over
    /// [`Method::RiCd`]: they recover what the cheaper red and blue lose
    /// against MLRI's (within 0.04 dB of [`Method::RaisrFast`] on each
    /// validation subset), at 0.80x its time. Not flip-symmetric.
    /// Outputs are clamped to the input's range.
    RaisrCd,
    /// A learned adaptive fusion of [`Method::RiCd`] and [`Method::Rcd`]:
    /// filters as [`Method::Raisr`]'s over "ri_cd" that also see RCD's
    /// difference from it over the 3x3 window. Residual interpolation wins
    /// where the colour channels are weakly correlated, RCD's colour
    /// differences where they are strongly correlated; per class of local
    /// structure the filters learn how far to trust either. Not
    /// flip-symmetric. Outputs are clamped to the input's range.
    Fusion,
    /// [`Method::Fusion`] refined by a second stage, a cascade: the
    /// orientation- and shape-hashed filters of [`Method::RaisrFast`]
    /// trained over the fusion's output, applied to its rows as they stream
    /// out. Not flip-symmetric. Outputs are clamped to the input's range.
    FusionRefined,
    /// [`Method::FusionRefined`] corrected by a small convolutional network
    /// (six 3x3 layers of 32 channels over the mosaic's 2x2 cells, no
    /// biases), applied to its rows as they stream out ([`cnn`]): it sees
    /// a window of 26 x 26 pixels and tells aliasing from texture where
    /// the hashed filters' classes cannot. Not flip-symmetric. Outputs are
    /// clamped to the input's range.
    FusionCnn,
    /// Markesteijn's X-Trans method as in dcraw's `xtrans_interpolate`
    /// (one pass): green, then red and blue by colour differences, along
    /// four directions; per pixel the mean of the directions with the most
    /// homogeneous YPbPr neighbourhood. X-Trans only. Outputs are clamped
    /// to the input's range.
    Markesteijn,
}

impl Method {
    /// Every method for Bayer mosaics, in the order the documentation lists
    /// them.
    pub const ALL: [Method; 17] = [
        Method::Nearest,
        Method::Bilinear,
        Method::Malvar2004,
        Method::HamiltonAdams,
        Method::Rcd,
        Method::Menon2007,
        Method::RcdMenon,
        Method::Ahd,
        Method::Leung2011,
        Method::Mlri,
        Method::Raisr,
        Method::RaisrFast,
        Method::RiCd,
        Method::RaisrCd,
        Method::Fusion,
        Method::FusionRefined,
        Method::FusionCnn,
    ];

    /// The name users pass.
    pub fn name(self) -> &'static str {
        match self {
            Method::Nearest => "nearest",
            Method::Bilinear => "bilinear",
            Method::Malvar2004 => "malvar2004",
            Method::HamiltonAdams => "hamilton_adams",
            Method::Rcd => "rcd",
            Method::Menon2007 => "menon2007",
            Method::RcdMenon => "rcd_menon",
            Method::Ahd => "ahd",
            Method::Leung2011 => "leung2011",
            Method::Mlri => "mlri",
            Method::Raisr => "raisr",
            Method::RaisrFast => "raisr_fast",
            Method::RiCd => "ri_cd",
            Method::RaisrCd => "raisr_cd",
            Method::Fusion => "fusion",
            Method::FusionRefined => "fusion_refined",
            Method::FusionCnn => "fusion_cnn",
            Method::Markesteijn => "markesteijn",
        }
    }

    /// Our most accurate method at about the speed of the fast ones, which
    /// the name "best" selects: the orientation-hashed filters over
    /// residual-interpolated green and colour-difference chroma
    /// ([`Method::RaisrCd`]), chosen on the validation subsets rather than
    /// the scikit-image seven alone. Mean CPSNR on the seven 39.65 dB,
    /// CBSD68 39.82, Urban24 36.18: 0.62-0.85 dB above every classical peer
    /// we run, within 0.04 dB of [`Method::RaisrFast`] on each subset at
    /// 0.80x its time, and 0.91x MLRI's.
    pub const BEST: Method = Method::RaisrCd;

    /// The most accurate method, which the name "quality" selects, whatever
    /// its speed: by the mean over the validation subsets, the small
    /// network over [`Method::FusionRefined`] (0.08 dB ahead of it: 0.31
    /// on CBSD68 and 0.06 on the seven, 0.14 behind on Urban24).
    pub const QUALITY: Method = Method::FusionCnn;

    /// The names that select a method by what it is for rather than by what
    /// it does: each with its Bayer and its X-Trans method.
    const ALIASES: [(&'static str, Method, Method); 2] = [
        ("best", Self::BEST, Self::BEST_XTRANS),
        ("quality", Self::QUALITY, Self::BEST_XTRANS),
    ];

    /// Every name [`Method::from_name`] accepts: the methods' own, then
    /// the aliases ("best", "quality").
    pub fn names() -> Vec<&'static str> {
        let mut names: Vec<&str> = Self::ALL.iter().map(|m| m.name()).collect();
        names.push(Method::Markesteijn.name());
        names.extend(Self::ALIASES.map(|(name, ..)| name));
        names
    }

    /// The alias `name` stands for, on Bayer or X-Trans mosaics.
    fn alias(name: &str, xtrans: bool) -> Option<Method> {
        let (_, bayer, other) = Self::ALIASES.into_iter().find(|&(n, ..)| n == name)?;
        Some(if xtrans { other } else { bayer })
    }

    /// How far, in pixels, an output pixel's value reaches into the mosaic:
    /// output `(y, x)` depends only on input pixels with `|dy|, |dx| <= halo`
    /// (besides the input's range, which the clamping methods use). Chunked
    /// callers (Dask's `map_overlap`) pad each chunk by at least this much so
    /// that its interior equals the whole-image result bit for bit.
    ///
    /// X-Trans widens the bilinear window up to radius 5 near image corners
    /// (see `xtrans.rs`), so the halo depends on the pattern. Every method
    /// must state its reach here: the match is exhaustive on purpose.
    pub fn halo(self, pattern: &CfaPattern) -> usize {
        match self {
            // The pixel's 2x2 cell, or the mirrored row/column of a half cell.
            Method::Nearest => 1,
            Method::Bilinear if !pattern.is_bayer() => xtrans::MAX_RADIUS,
            // The 3x3 neighbourhood.
            Method::Bilinear => 1,
            // The 5x5 Laplacian-corrected kernel.
            Method::Malvar2004 => 2,
            // Chroma reads green one pixel away, computed from raw two further.
            Method::HamiltonAdams => 3,
            Method::Rcd => <Rcd as TileKernel>::HALO,
            Method::Menon2007 => <Menon2007 as TileKernel>::HALO,
            Method::RcdMenon => <ensemble::Ensemble as TileKernel>::HALO,
            Method::Ahd => <ahd::Ahd as TileKernel>::HALO,
            Method::Leung2011 => <leung2011::Leung2011 as TileKernel>::HALO,
            Method::Mlri => <mlri::Mlri as tiled::StreamKernel>::HALO,
            Method::Raisr => <refined::Refined<raisr::Weights> as tiled::StreamKernel>::HALO,
            Method::RaisrFast => {
                <refined::Refined<oriented::Oriented> as tiled::StreamKernel>::HALO
            }
            Method::RiCd => <differences::Differences as tiled::StreamKernel>::HALO,
            Method::RaisrCd => <refined::Refined<oriented::Oriented, differences::Differences> as tiled::StreamKernel>::HALO,
            Method::Fusion => <FusionKernel as tiled::StreamKernel>::HALO,
            Method::FusionRefined => <FusionRefinedKernel as tiled::StreamKernel>::HALO,
            Method::FusionCnn => {
                <cnn::Convolved<FusionRefinedKernel> as tiled::StreamKernel>::HALO
            }
            Method::Markesteijn => markesteijn::HALO,
        }
    }

    /// Whether the method's result depends on the white level (see
    /// [`demosaic`]): RCD's and MLRI's regularisers, AHD's Lab and the
    /// learned methods' hash and bounds are fractions of it; the others
    /// are linear or compare samples with each other only. Exhaustive on
    /// purpose, as [`Method::halo`] is.
    pub fn scaled(self) -> bool {
        match self {
            Method::Rcd
            | Method::RcdMenon
            | Method::Ahd
            | Method::Mlri
            | Method::RiCd
            | Method::Raisr
            | Method::RaisrFast
            | Method::RaisrCd
            | Method::Fusion
            | Method::FusionRefined
            | Method::FusionCnn => true,
            Method::Nearest
            | Method::Bilinear
            | Method::Malvar2004
            | Method::HamiltonAdams
            | Method::Menon2007
            | Method::Leung2011
            | Method::Markesteijn => false,
        }
    }

    /// Every method for X-Trans mosaics.
    pub const XTRANS: [Method; 2] = [Method::Bilinear, Method::Markesteijn];

    /// The best X-Trans method, which "best" selects for X-Trans patterns:
    /// 38.63 dB mean CPSNR on the benchmark's seven images mosaiced with
    /// X-Trans, against bilinear's 32.77 and LibRaw's Markesteijn 38.42
    /// (3-pass) and 38.34 (1-pass).
    pub const BEST_XTRANS: Method = Method::Markesteijn;

    /// Whether the method demosaics mosaics of `pattern`.
    pub fn supports(self, pattern: &CfaPattern) -> bool {
        self.supports_kind(!pattern.is_bayer())
    }

    /// `Ok` where the method demosaics mosaics of `pattern`, else the error
    /// that names the methods that do.
    pub fn check_supports(self, pattern: &CfaPattern) -> Result<()> {
        if self.supports(pattern) {
            Ok(())
        } else {
            Err(unsupported(self, pattern))
        }
    }

    /// The names of the methods for Bayer (`xtrans == false`) or X-Trans
    /// mosaics, then the aliases.
    pub fn names_for(xtrans: bool) -> Vec<&'static str> {
        Self::names()
            .into_iter()
            .filter(|&n| {
                Self::from_name(n).is_ok_and(|m| m.supports_kind(xtrans))
                    || Self::alias(n, xtrans).is_some()
            })
            .collect()
    }

    fn supports_kind(self, xtrans: bool) -> bool {
        if xtrans {
            Self::XTRANS.contains(&self)
        } else {
            self != Method::Markesteijn
        }
    }

    /// Parses a method name for mosaics of `pattern`: "best" gives
    /// [`Method::BEST`] for Bayer patterns and [`Method::BEST_XTRANS`] for
    /// X-Trans ones, "quality" [`Method::QUALITY`] and
    /// [`Method::BEST_XTRANS`].
    ///
    /// # Errors
    /// As [`Method::from_name`].
    pub fn from_name_for(name: &str, pattern: &CfaPattern) -> Result<Self> {
        match Self::alias(name, !pattern.is_bayer()) {
            Some(method) => Ok(method),
            None => Self::from_name(name),
        }
    }

    /// Parses a method name (an alias gives its Bayer method).
    ///
    /// # Errors
    /// [`CoreError::InvalidArgument`] naming the string and the accepted names.
    pub fn from_name(name: &str) -> Result<Self> {
        if let Some(method) = Self::alias(name, false) {
            return Ok(method);
        }
        Self::ALL
            .into_iter()
            .chain([Method::Markesteijn])
            .find(|m| m.name() == name)
            .ok_or_else(|| {
                let names = Self::names();
                invalid!("unknown demosaicing method {name:?}; accepted: {names:?}")
            })
    }
}

/// Demosaics `raw`, an `(H, W)` mosaic sampled through `pattern`, into
/// `out`, an `(H, W, 3)` RGB buffer of the same sample type.
///
/// Every method returns each sampled value unchanged at its own site.
///
/// `white_level` is the value of a saturated sample, from which the
/// [scaled](Method::scaled) methods take their thresholds, bounds and
/// learned hash; `None` for [`white_level`]'s default.
///
/// # Errors
/// [`CoreError::Shape`] for a multi-channel `raw`, an image smaller than
/// 2x2 (6x6 for X-Trans) or a wrong output length;
/// [`CoreError::InvalidArgument`] for a method that does not support the
/// pattern (see [`Method::supports`]), a float mosaic holding NaN or an
/// infinity, or a white level that is not a finite number > 0.
pub fn demosaic<T: Sample>(
    raw: ImageView<'_, T>,
    pattern: &CfaPattern,
    method: Method,
    white_level: Option<f32>,
    out: &mut [T],
) -> Result<()> {
    if let Some(level) = white_level {
        positive("white_level", f64::from(level))?;
    }
    if raw.channels() != 1 {
        return Err(CoreError::Shape(format!(
            "demosaic needs a single-channel mosaic of shape (H, W), got {} channels",
            raw.channels()
        )));
    }
    check_finite(&raw)?;
    let Some(phase) = checked_phase(raw.width(), raw.height(), pattern, method, out.len())? else {
        match method {
            Method::Markesteijn => markesteijn::run(&raw, pattern, Isa::detect(), out),
            _ => xtrans::run(&raw, pattern, out),
        }
        return Ok(());
    };
    let isa = Isa::detect();
    match method {
        Method::Nearest => nearest::run(&raw, phase, out),
        _ if method.scaled() => {
            // The range is found once, for the level and every stage after.
            let raw = &Ranged::new(&raw);
            let level = white_level.unwrap_or_else(|| self::white_level::<T>(raw.range().1));
            run_method(raw, phase, method, level, isa, &Convert, out);
        }
        _ => run_method(&raw, phase, method, T::FULL_SCALE, isa, &Convert, out),
    }
    Ok(())
}

/// The white level of a mosaic of `T` whose largest sample is `largest`,
/// when none is given: for integer types the smallest bit depth of at least
/// 8 that holds `largest` (`2^bits - 1`, at most the type's full scale),
/// since raw files keep 10-, 12- and 14-bit photosites in 16-bit arrays,
/// where the type's full scale would make them look 4 to 64 times darker
/// than they are. Floats are taken on a 0..1 scale, or up to `largest` if
/// that is beyond 1: data on 0..255 or 0..4095 then demosaic as well as on
/// 0..1, and a highlight just past 1 moves the level only as far.
pub fn white_level<T: Sample>(largest: f32) -> f32 {
    if T::FULL_SCALE == 1.0 {
        return largest.max(1.0);
    }
    let mut level = 255.0f32;
    while level < largest && level < T::FULL_SCALE {
        level = level * 2.0 + 1.0;
    }
    level.min(T::FULL_SCALE)
}

/// [`demosaic`] of any [`Mosaic`] through any [`RgbSink`], with `T` the
/// sample type whose full scale is the white level. Only the methods that read
/// the mosaic through [`Mosaic::load`] alone can run so: every Bayer method
/// but nearest (which copies samples). For the others nothing is done and
/// `Ok(false)` returned, so that the caller can demosaic an image instead.
///
/// # Errors
/// As [`demosaic`].
pub(crate) fn demosaic_through<T, M, O, K>(
    raw: &M,
    pattern: &CfaPattern,
    method: Method,
    sink: &K,
    out: &mut [O],
) -> Result<bool>
where
    T: Sample,
    M: Mosaic,
    O: Send,
    K: RgbSink<O>,
{
    match checked_phase(raw.width(), raw.height(), pattern, method, out.len())? {
        Some(phase) if method != Method::Nearest => {
            run_method(raw, phase, method, T::FULL_SCALE, Isa::detect(), sink, out);
            Ok(true)
        }
        _ => Ok(false),
    }
}

/// The largest magnitude a mosaic's sample may have: 2^100, far beyond any
/// light level, and far enough below `f32::MAX` (2^128) that no method's
/// sums of weighted neighbours overflow (they did from ~1e37: infinities,
/// and clamped samples in place of measured ones).
pub const SAMPLE_LIMIT: f32 = (1u128 << 100) as f32;

/// Refuses NaN, infinities and samples beyond [`SAMPLE_LIMIT`]: every
/// method mixes neighbouring samples, so one would spread into (or be
/// clamped into) numbers around it that look valid. The first bad sample in
/// row-major order is named, whatever the thread count.
fn check_finite<T: Sample>(raw: &ImageView<'_, T>) -> Result<()> {
    let bad = |v: &T| !(v.is_finite() && v.to_f32().abs() <= SAMPLE_LIMIT);
    let Some((y, x)) = raw.find_first(bad) else {
        return Ok(());
    };
    let row = raw.row(y);
    if row[x].is_finite() {
        return Err(invalid!(
            "the mosaic's samples must lie within ±2^100, got one beyond at row {y}, column \
             {x} (sums of its neighbours would overflow float32)"
        ));
    }
    Err(invalid!(
        "the mosaic must hold finite numbers, got {:?} at row {y}, column {x}",
        row[x]
    ))
}

/// Checks the size, the output length and the method against the pattern;
/// the Bayer phase, or `None` for X-Trans.
fn checked_phase(
    w: usize,
    h: usize,
    pattern: &CfaPattern,
    method: Method,
    out_len: usize,
) -> Result<Option<Phase>> {
    if w < 2 || h < 2 {
        return Err(CoreError::Shape(format!(
            "demosaic needs a mosaic of at least 2x2 pixels (one full CFA tile), got ({h}, {w})"
        )));
    }
    check_out_len(out_len, 3 * w * h, "demosaic")?;
    method.check_supports(pattern)?;
    match pattern.bayer_red() {
        Some((ry, rx)) => Ok(Some(Phase { ry, rx })),
        None if w < 6 || h < 6 => Err(CoreError::Shape(format!(
            "demosaic needs an X-Trans mosaic of at least 6x6 pixels (one full CFA tile), got ({h}, {w})"
        ))),
        None => Ok(None),
    }
}

/// The mosaic a demosaic reads, row piece by row piece as `f32`: an image
/// of samples, or, for development, raw sensor numbers prepared as they are
/// loaded, so that no full-size prepared copy is ever made.
pub(crate) trait Mosaic: Sync {
    fn width(&self) -> usize;
    fn height(&self) -> usize;
    /// Writes row `y`, columns `x0 .. x0 + dst.len()`, into `dst`. Pure per
    /// sample, so a value loaded twice (halos, mirrors) is the same value.
    fn load(&self, y: usize, x0: usize, dst: &mut [f32]);
    /// The smallest and largest value of the whole mosaic, which the
    /// clamping methods clamp to (exact whatever the thread count).
    fn range(&self) -> (f32, f32);
}

impl<T: Sample> Mosaic for ImageView<'_, T> {
    fn width(&self) -> usize {
        ImageView::width(self)
    }

    fn height(&self) -> usize {
        ImageView::height(self)
    }

    #[inline(always)]
    fn load(&self, y: usize, x0: usize, dst: &mut [f32]) {
        for (d, s) in dst.iter_mut().zip(&self.row(y)[x0..]) {
            *d = s.to_f32();
        }
    }

    fn range(&self) -> (f32, f32) {
        tiled::range(self)
    }
}

/// A mosaic whose range was found once: the learned methods need it for
/// their filters and again for the output's clamp, and for development's
/// prepared mosaic each [`Mosaic::range`] is a full pass over the
/// photosites (with the vignetting gains).
struct Ranged<'a, M> {
    raw: &'a M,
    bounds: (f32, f32),
}

impl<'a, M: Mosaic> Ranged<'a, M> {
    fn new(raw: &'a M) -> Self {
        Ranged {
            raw,
            bounds: raw.range(),
        }
    }
}

impl<M: Mosaic> Mosaic for Ranged<'_, M> {
    fn width(&self) -> usize {
        self.raw.width()
    }

    fn height(&self) -> usize {
        self.raw.height()
    }

    #[inline(always)]
    fn load(&self, y: usize, x0: usize, dst: &mut [f32]) {
        self.raw.load(y, x0, dst);
    }

    fn range(&self) -> (f32, f32) {
        self.bounds
    }
}

/// Where a demosaic puts its result: planes of red, green and blue in the
/// mosaic's units, written as interleaved pixels of `O`. Plain demosaicing
/// converts them ([`Convert`]); development finishes them into display
/// colours while they are still in cache.
pub(crate) trait RgbSink<O>: Sync {
    /// Per-task buffers, made once per band or tile run, never per row.
    type Scratch;
    /// Buffers for rows of up to `width` pixels.
    fn scratch(&self, width: usize) -> Self::Scratch;
    /// Writes pixel `i` of the planes `rgb` (equal lengths) to
    /// `out[3 i .. 3 i + 3]`, clamped to `within` if given (the mosaic's
    /// range, two of its samples). Sinks fold the clamp into their
    /// conversion: a pass of its own took 1.5 % of MLRI's time.
    fn store(
        &self,
        scratch: &mut Self::Scratch,
        rgb: [&[f32]; 3],
        within: Option<(f32, f32)>,
        out: &mut [O],
    );
}

/// The sink of [`demosaic`]: each plane converted to the sample type (see
/// [`write_row`] for why planes first), then interleaved.
pub(crate) struct Convert;

impl<T: Sample> RgbSink<T> for Convert {
    type Scratch = Packed<T>;

    fn scratch(&self, width: usize) -> Packed<T> {
        Packed::new(width)
    }

    #[inline(always)]
    fn store(
        &self,
        packed: &mut Packed<T>,
        rgb: [&[f32]; 3],
        within: Option<(f32, f32)>,
        out: &mut [T],
    ) {
        let n = out.len() / 3;
        for (dst, src) in packed.0.iter_mut().zip(rgb) {
            let (dst, src) = (&mut dst[..n], &src[..n]);
            match within {
                None => T::from_f32_row(dst, src),
                Some(bounds) => T::from_f32_row_within(dst, src, bounds),
            }
        }
        interleave(packed, out);
    }
}

/// The error for a method given a pattern it does not support, naming the
/// methods that do.
fn unsupported(method: Method, pattern: &CfaPattern) -> CoreError {
    let xtrans = Method::names_for(true);
    if pattern.is_bayer() {
        invalid!(
            "method {:?} supports X-Trans patterns only, got a 2x2 Bayer pattern; Bayer mosaics are supported by {:?}",
            method.name(),
            Method::names_for(false)
        )
    } else {
        invalid!(
            "method {:?} supports the Bayer patterns RGGB, BGGR, GRBG and GBRG, got a 6x6 X-Trans pattern; X-Trans is supported by \"{}\"",
            method.name(),
            xtrans.join("\", \"")
        )
    }
}

/// The instruction sets the kernels are compiled for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Isa {
    /// The target's baseline (SSE2 on x86-64).
    Baseline,
    /// x86-64 with AVX2 and FMA, detected at run time (every CPU with the
    /// one has the other; the orientation-hashed filters fuse their
    /// multiply-adds, in their scalar code too, so all paths agree).
    #[cfg(target_arch = "x86_64")]
    Avx2,
    /// x86-64 with AVX-512 (F, BW, DQ and VL) besides AVX2 and FMA,
    /// detected at run time. The tiled kernels run in a copy compiled for
    /// it: half the instructions of AVX2 for the same work, which made
    /// "best" and "raisr" 3-10 % faster on Zen 4 cores (interleaved runs),
    /// and the orientation-hashed filters take 16 pixels a step. MLRI,
    /// which it made slower, the row kernels, Markesteijn and the full
    /// RAISR filter taps keep their AVX2 code, which AVX-512 CPUs run too.
    #[cfg(target_arch = "x86_64")]
    Avx512,
}

impl Isa {
    /// The widest instruction set of this CPU that the kernels have and
    /// the cap ([`crate::cpu`]) allows.
    fn detect() -> Self {
        Self::available().pop().unwrap_or(Isa::Baseline)
    }

    /// Every instruction set of this CPU that the kernels have and the cap
    /// allows, narrowest first.
    fn available() -> Vec<Self> {
        let mut isas = vec![Isa::Baseline];
        #[cfg(target_arch = "x86_64")]
        {
            if crate::cpu::has_avx2_fma() {
                isas.push(Isa::Avx2);
            }
            if crate::cpu::has_avx512() {
                isas.push(Isa::Avx512);
            }
        }
        isas
    }
}

/// Runs a Bayer `method` (not nearest) with `scale` as the white level.
fn run_method<M, O, K>(
    raw: &M,
    phase: Phase,
    method: Method,
    scale: f32,
    isa: Isa,
    sink: &K,
    out: &mut [O],
) where
    M: Mosaic,
    O: Send,
    K: RgbSink<O>,
{
    match method {
        Method::Bilinear => bilinear::run(raw, phase, isa, sink, out),
        Method::Malvar2004 => malvar2004::run(raw, phase, isa, sink, out),
        Method::HamiltonAdams => hamilton_adams::run(raw, phase, isa, sink, out),
        Method::Menon2007 => tiled::run_tiled(raw, phase, &Menon2007 { phase }, isa, sink, out),
        Method::Rcd => {
            let k = Rcd::new(phase, scale);
            tiled::run_tiled(raw, phase, &k, isa, sink, out);
        }
        Method::Ahd => {
            let k = ahd::Ahd {
                phase,
                full_scale: scale,
            };
            tiled::run_tiled(raw, phase, &k, isa, sink, out);
        }
        Method::Mlri => {
            let k: mlri::Mlri = mlri::Mlri::new(phase, scale);
            tiled::run_tiled(raw, phase, &k, isa, sink, out);
        }
        Method::RiCd => {
            let k = differences::Differences::new(phase, scale);
            tiled::run_tiled(raw, phase, &k, isa, sink, out);
        }
        Method::Leung2011 => {
            let k = leung2011::Leung2011 { phase };
            tiled::run_tiled(raw, phase, &k, isa, sink, out);
        }
        Method::Nearest | Method::Markesteijn => {
            unreachable!("callers route nearest and X-Trans-only methods elsewhere")
        }
        Method::RcdMenon => {
            let k = rcd_menon(phase, scale);
            tiled::run_tiled(raw, phase, &k, isa, sink, out);
        }
        Method::Raisr => {
            let bank = (raisr::Weights::raisr(), Bound::Free);
            let base = |_: &_| mlri::Mlri::<true>::new(phase, scale);
            run_refined(raw, phase, base, bank, scale, isa, sink, out);
        }
        Method::RaisrFast => {
            let bank = (oriented::Oriented::raisr_fast(), Bound::Free);
            let base = |_: &_| mlri::Mlri::<true>::new(phase, scale);
            run_refined(raw, phase, base, bank, scale, isa, sink, out);
        }
        Method::RaisrCd => {
            let bank = (oriented::Oriented::raisr_cd(), Bound::Chroma);
            let base = |_: &_| differences::Differences::new(phase, scale);
            run_refined(raw, phase, base, bank, scale, isa, sink, out);
        }
        Method::Fusion => {
            let raw = &Ranged::new(raw);
            let k = fusion_kernel(raw, phase, scale, isa);
            tiled::run_tiled(raw, phase, &k, isa, sink, out);
        }
        Method::FusionRefined => {
            let bank = (oriented::Oriented::fusion_refined(), Bound::Chroma);
            let base = |raw: &_| fusion_kernel(raw, phase, scale, isa);
            run_refined(raw, phase, base, bank, scale, isa, sink, out);
        }
        Method::FusionCnn => {
            let raw = &Ranged::new(raw);
            let bank = (oriented::Oriented::fusion_refined(), Bound::Chroma);
            let base = fusion_kernel(raw, phase, scale, isa);
            let k = cnn::Convolved {
                base: refined_kernel(raw, phase, base, bank, scale, isa),
                network: cnn::Network::fusion_cnn(),
                phase,
                isa,
                bounds: raw.bounds,
            };
            tiled::run_tiled(raw, phase, &k, isa, sink, out);
        }
    }
}

/// Whether a learned method's corrections are bounded.
enum Bound {
    Free,
    /// As the fusion, its cascade and [`Method::RaisrCd`] are
    /// ([`raisr::CHROMA_LIMIT`]).
    Chroma,
}

/// The base that `base` makes for the ranged mosaic, refined by the
/// learned filters of `bank` ([`refined::Refined`]), with the mosaic's
/// range found once for the filters, the base's own and the clamp.
#[allow(clippy::too_many_arguments)]
fn run_refined<'r, M, O, K, S, B>(
    raw: &'r M,
    phase: Phase,
    base: impl FnOnce(&Ranged<'r, M>) -> S,
    (bank, bound): (&'static B, Bound),
    scale: f32,
    isa: Isa,
    sink: &K,
    out: &mut [O],
) where
    M: Mosaic,
    O: Send,
    K: RgbSink<O>,
    S: tiled::StreamKernel,
    B: raisr::Bank,
{
    let raw = &Ranged::new(raw);
    let k = refined_kernel(raw, phase, base(raw), (bank, bound), scale, isa);
    tiled::run_tiled(raw, phase, &k, isa, sink, out);
}

/// `base` refined by the learned filters of `bank` for the mosaic `raw`
/// (whose range the filters clamp to).
fn refined_kernel<B: raisr::Bank, S>(
    raw: &impl Mosaic,
    phase: Phase,
    base: S,
    (bank, bound): (&'static B, Bound),
    scale: f32,
    isa: Isa,
) -> refined::Refined<B, S> {
    let filters = filters(bank, raw, phase, scale, isa);
    refined::Refined {
        base,
        filters: match bound {
            Bound::Free => filters,
            Bound::Chroma => bounded(filters, scale),
        },
    }
}

/// The kernel of [`Method::Fusion`].
type FusionKernel = fusion::Fusion<differences::Differences>;

/// The kernel of [`Method::FusionRefined`].
type FusionRefinedKernel = refined::Refined<oriented::Oriented, FusionKernel>;

/// [`Method::Fusion`]'s kernel for `raw` (whose range its filters clamp
/// to: a [`Ranged`] mosaic finds it once for every stage).
fn fusion_kernel(raw: &impl Mosaic, phase: Phase, scale: f32, isa: Isa) -> FusionKernel {
    let bank = raisr::Weights::fusion();
    fusion::Fusion {
        base: differences::Differences::new(phase, scale),
        rcd: Rcd::new(phase, scale),
        filters: bounded(filters(bank, raw, phase, scale, isa), scale),
        second_bound: fusion::SECOND_LIMIT * scale,
    }
}

/// A learned method's filter bank, with the mosaic's white level `scale`
/// and range.
fn filters<B: raisr::Bank>(
    bank: &'static B,
    raw: &impl Mosaic,
    phase: Phase,
    scale: f32,
    isa: Isa,
) -> raisr::Filters<B> {
    raisr::Filters {
        phase,
        inv_scale: 1.0 / scale,
        bounds: raw.range(),
        bank,
        isa,
        chroma_bound: None,
        saturated: bank
            .saturation()
            .map(|(t, offset)| (saturation::least_saturated(t, 1.0 / scale), offset)),
    }
}

/// `f` bounded as [`Bound::Chroma`] says, at the white level `scale`.
fn bounded<B>(f: raisr::Filters<B>, scale: f32) -> raisr::Filters<B> {
    raisr::Filters {
        chroma_bound: Some(raisr::CHROMA_LIMIT * scale),
        ..f
    }
}

/// The mean of RCD and Menon 2007 ([`Method::RcdMenon`]), which the
/// fusion's filters also see.
fn rcd_menon(phase: Phase, full_scale: f32) -> ensemble::Ensemble {
    ensemble::Ensemble {
        rcd: Rcd::new(phase, full_scale),
        menon: Menon2007 { phase },
    }
}

/// Where red sits in the 2x2 tile; blue is at the opposite corner.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Phase {
    ry: usize,
    rx: usize,
}

/// What a row of the mosaic holds.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RowKind {
    /// Whether the row's chroma is blue (a "blue row"): then the kernel's
    /// own chroma goes to channel 2 and the other chroma to channel 0.
    blue: bool,
    /// Column parity of the row's chroma sites.
    pub(crate) chroma_parity: usize,
}

impl Phase {
    /// The kind of row `y` (any integer: mirrored rows keep their parity).
    pub(crate) fn row(self, y: isize) -> RowKind {
        let red = (y - self.ry as isize).rem_euclid(2) == 0;
        RowKind {
            blue: !red,
            chroma_parity: if red { self.rx } else { 1 - self.rx },
        }
    }
}

/// Output rows per rayon task. A band reloads `2 * radius` halo rows (and
/// Hamilton-Adams recomputes 2 green rows), so 64 rows keep that overhead
/// near 6 % while a 24 MP image (4000 rows) still gives ~60 tasks to balance.
const ROWS_PER_BAND: usize = 64;

/// Mirrored columns kept on each side of a ring row: the widest kernels
/// reach 2 columns out, and Hamilton-Adams needs its green plane 1 column
/// beyond the image, computed from raw 2 further. Even, so a padded index
/// has the parity of its column.
pub(crate) const PAD: usize = 4;

/// Raw rows converted to `f32` and padded by mirroring, in a ring indexed by
/// row number modulo its number of slots.
pub(crate) struct Ring {
    data: Vec<f32>,
    stride: usize,
    slots: usize,
}

impl Ring {
    /// A ring of `slots` rows for an image `width` wide.
    pub(crate) fn new(width: usize, slots: usize) -> Self {
        let stride = width + 2 * PAD;
        Self {
            data: vec![0.0; stride * slots],
            stride,
            slots,
        }
    }

    fn start(&self, y: isize) -> usize {
        y.rem_euclid(self.slots as isize) as usize * self.stride
    }

    /// Row `y` (padded: column `x` is at index `x + PAD`).
    #[inline(always)]
    pub(crate) fn row(&self, y: isize) -> &[f32] {
        let s = self.start(y);
        &self.data[s..s + self.stride]
    }

    /// Row `y`, for kernels that fill a ring themselves.
    pub(crate) fn row_mut(&mut self, y: isize) -> &mut [f32] {
        let s = self.start(y);
        &mut self.data[s..s + self.stride]
    }

    /// Converts raw row `mirror(y)` into slot `y` and mirrors its ends.
    #[inline(always)]
    pub(crate) fn load<M: Mosaic>(&mut self, raw: &M, y: isize) {
        let w = raw.width();
        let src = mirror(y, raw.height());
        let row = self.row_mut(y);
        raw.load(src, 0, &mut row[PAD..PAD + w]);
        for j in 1..=PAD {
            row[PAD - j] = row[PAD + mirror(-(j as isize), w)];
            row[PAD + w - 1 + j] = row[PAD + mirror((w - 1 + j) as isize, w)];
        }
    }
}

/// Runs a single-stage stencil kernel: `planes(ring, y, kind, planes)`
/// fills one output row's planes from the ring (rows `y - radius ..=
/// y + radius` loaded), which are then written as R, G, B through `sink`.
pub(crate) fn run_stencil<M, O, K, F>(
    raw: &M,
    (phase, isa): (Phase, Isa),
    radius: usize,
    planes: F,
    sink: &K,
    out: &mut [O],
) where
    M: Mosaic,
    O: Send,
    K: RgbSink<O>,
    F: Fn(&Ring, isize, RowKind, &mut RowPlanes) + Sync,
{
    let w = raw.width();
    run_rows(
        raw,
        out,
        radius,
        isa,
        |_| (RowPlanes::new(w), sink.scratch(w)),
        #[inline(always)]
        |(p, scratch), ring, y, o| {
            let kind = phase.row(y);
            planes(ring, y, kind, p);
            write_row(p, sink, scratch, kind, o);
        },
    );
}

/// Runs a row kernel over every output row in parallel bands.
///
/// `radius` raw rows above and below each output row are in the ring when
/// `row(state, ring, y, out_row)` is called; `init` makes the per-band state
/// (intermediate rings) once per band, never per pixel.
///
/// With [`Isa::Avx2`] the band runs in a copy of the code compiled for
/// AVX2 (8 lanes instead of SSE2's 4; measured ~1.5x faster at 24 MP).
/// Both copies do the same IEEE operations in the same order (no fused
/// multiply-add), so the output is identical on every CPU. Callers mark
/// their `row` closures (and the closures those call) `#[inline(always)]`:
/// left to the inliner, they were compiled apart from the AVX2 copy, as
/// SSE2 code (Malvar 8 % and Hamilton-Adams 17 % slower at 24 MP).
pub(crate) fn run_rows<M, O, S, I, F>(
    raw: &M,
    out: &mut [O],
    radius: usize,
    isa: Isa,
    init: I,
    row: F,
) where
    M: Mosaic,
    O: Send,
    I: Fn(usize) -> S + Sync,
    F: Fn(&mut S, &Ring, isize, &mut [O]) + Sync,
{
    for_each_band(out, 3 * raw.width(), ROWS_PER_BAND, |y0, rows| match isa {
        Isa::Baseline => band(raw, rows, y0, radius, &init, &row),
        #[cfg(target_arch = "x86_64")]
        // SAFETY: calling a function compiled for AVX2 requires a CPU with
        // AVX2; `Isa::Avx2` and `Isa::Avx512` are only made on such CPUs.
        Isa::Avx2 | Isa::Avx512 => unsafe { band_avx2(raw, rows, y0, radius, &init, &row) },
    });
}

/// [`band`] compiled for AVX2; the kernels inline into it.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn band_avx2<M, O, S, I, F>(raw: &M, rows: &mut [O], y0: usize, radius: usize, init: &I, row: &F)
where
    M: Mosaic,
    I: Fn(usize) -> S,
    F: Fn(&mut S, &Ring, isize, &mut [O]),
{
    band(raw, rows, y0, radius, init, row);
}

/// One band of output rows starting at row `y0`.
#[inline(always)]
fn band<M, O, S, I, F>(raw: &M, rows: &mut [O], y0: usize, radius: usize, init: &I, row: &F)
where
    M: Mosaic,
    I: Fn(usize) -> S,
    F: Fn(&mut S, &Ring, isize, &mut [O]),
{
    let w = raw.width();
    let r = radius as isize;
    let mut ring = Ring::new(w, 2 * radius + 1);
    let mut state = init(y0);
    let y0 = y0 as isize;
    for y in y0 - r..y0 + r {
        ring.load(raw, y);
    }
    for (i, o) in rows.chunks_exact_mut(3 * w).enumerate() {
        let y = y0 + i as isize;
        ring.load(raw, y + r);
        row(&mut state, &ring, y, o);
    }
}

/// One output row in planar form, padded like a ring row: the row's own
/// chroma, green, and the other chroma (see [`RowKind`]), plus which padded
/// columns are chroma sites for either parity.
///
/// Kernels fill the planes with branch-free, unit-stride loops over every
/// column (computing both the chroma-site and the green-site formula and
/// selecting by the mask), which LLVM vectorises; [`write_row`] then
/// interleaves and converts. Computing both formulas costs twice the
/// arithmetic but runs 4 or 8 lanes wide, which measured faster than
/// per-pair scalar code.
pub(crate) struct RowPlanes {
    pub(crate) own: Vec<f32>,
    pub(crate) green: Vec<f32>,
    pub(crate) other: Vec<f32>,
    /// Chroma-site masks for chroma parity 0 and 1: all ones at chroma
    /// sites, zero at green sites (for [`select`]).
    pub(crate) chroma: [Vec<u32>; 2],
}

impl RowPlanes {
    pub(crate) fn new(width: usize) -> Self {
        let len = width + 2 * PAD;
        Self {
            own: vec![0.0; len],
            green: vec![0.0; len],
            other: vec![0.0; len],
            chroma: chroma_masks(len),
        }
    }
}

/// Chroma-site masks of `len` columns for column parity 0 and 1: all ones
/// at the columns of that parity, zero elsewhere (for [`select`]). Tile
/// kernels index them with a tile column, which has its image column's
/// parity because halos are even.
pub(crate) fn chroma_masks(len: usize) -> [Vec<u32>; 2] {
    [0, 1].map(|parity| {
        (0..len)
            .map(|x| if x & 1 == parity { u32::MAX } else { 0 })
            .collect()
    })
}

/// `a` where `mask` is all ones, `b` where it is zero. A bitwise blend
/// rather than `if`: LLVM turned the `if` form into a branch per pixel, and
/// an arithmetic blend would turn infinities into NaN.
#[inline(always)]
pub(crate) fn select(mask: u32, a: f32, b: f32) -> f32 {
    f32::from_bits((a.to_bits() & mask) | (b.to_bits() & !mask))
}

/// `row[reach + dx ..][..n]`: the row seen `dx` columns to the right, for a
/// loop over the `n` padded columns `reach .. reach + n`. Equal-length
/// slices let LLVM drop the bounds checks inside the loop.
#[inline(always)]
pub(crate) fn shifted(row: &[f32], reach: usize, dx: isize, n: usize) -> &[f32] {
    let start = (reach as isize + dx) as usize;
    &row[start..start + n]
}

/// Writes the planes of one row through `sink` as R, G, B.
///
/// For [`Convert`], two passes: the conversions (rounding, clamping) run
/// over each plane on its own, where they vectorise; the interleaving then
/// only moves samples. Converting while interleaving measured about twice
/// as slow, the compiler turning it into shuffles around scalar conversions.
#[inline(always)]
pub(crate) fn write_row<O, K: RgbSink<O>>(
    planes: &RowPlanes,
    sink: &K,
    scratch: &mut K::Scratch,
    kind: RowKind,
    out: &mut [O],
) {
    let w = out.len() / 3;
    let (red, blue) = if kind.blue {
        (&planes.other, &planes.own)
    } else {
        (&planes.own, &planes.other)
    };
    let rgb = [red, &planes.green, blue].map(|p| &p[PAD..PAD + w]);
    sink.store(scratch, rgb, None, out);
}

/// Writes three converted planes as R, G, B pixels.
#[inline(always)]
pub(crate) fn interleave<T: Sample>(packed: &Packed<T>, out: &mut [T]) {
    T::interleave(packed.0.each_ref().map(|p| &p[..]), out);
}

/// One output row as three converted planes, for [`write_row`].
pub(crate) struct Packed<T>([Vec<T>; 3]);

impl<T: Sample> Packed<T> {
    pub(crate) fn new(width: usize) -> Self {
        Self([0, 1, 2].map(|_| vec![T::default(); width]))
    }
}

#[cfg(test)]
mod tests;

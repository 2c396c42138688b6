//! RAISR's filters over MLRI with a hash of orientation and shape alone
//! ([`super::Method::RaisrFast`]; over RI-CD, [`super::Method::RaisrCd`];
//! over the fusion, [`super::Method::FusionRefined`]).
//!
//! The full hash ([`super::raisr`]) picks one of 288 filters per pixel from
//! the structure tensor's angle, strength and coherence. A filter chosen
//! pixel by pixel has to be fetched pixel by pixel, and 288 filters' taps
//! (83 KB) do not stay in the first-level cache: that refinement costs
//! about 40 % of MLRI's own time, this one 17 %. Most of what it gains comes from the CFA
//! position and the edge's orientation (in a NumPy model trained on the
//! same photographs, four orientations kept all but 0.1-0.2 dB of the
//! eight-angle, nine-shape hash on the validation subsets; splitting each
//! orientation into isotropic and anisotropic tensors won back 0.05-0.07
//! dB on CBSD68, Urban24 and held-out photographs, 0.01-0.02 on the
//! seven), and 32 filters allow another way to apply them. Along a row the
//! CFA position alternates between two, the orientation takes four values
//! and the shape two ([`coherent`]), so each tap has just 16 values across
//! a row's classes: one 16-float table, from which a single permute gives
//! the tap of each of sixteen pixels with AVX-512. AVX2's permute takes
//! eight entries, the classes of one column parity, so it filters every
//! other pixel of sixteen side by side ([`Halves`]). The pixels are then
//! filtered like a convolution, with no per-pixel fetch, and the tables of
//! a row (3.5 KB) stay in cache.
//!
//! "raisr_cd" ("best") also splits its classes by the base's local
//! saturation, as the fusion does ([`super::saturation`]): 64 filters, so
//! a row's classes take 32 values, the saturated ones in the tables'
//! second half. AVX-512 picks from both halves with one two-table permute,
//! AVX2 with two permutes and a blend; a step of pixels none of
//! which is saturated (88 % of the steps on the benchmark's photograph)
//! reads the first half alone, as a bank without the split does. On the
//! held-out photographs with their chroma tripled, the split adds 0.5 dB
//! (0.22 dB at double chroma, 0.02-0.08 dB on the validation subsets) and
//! costs "best" about 6 % of its time. Its corrections are bounded as the
//! fusion's are ([`super::raisr::bound`]), in registers as they are
//! stored.
//!
//! The features, the taps' windows and the training are RAISR's
//! ([`super::raisr::taps`]); only the class differs: the quadrant of the
//! doubled orientation of the 3x3 structure tensor of MLRI's green
//! ([`orientation`]) and whether the tensor is anisotropic enough to be an
//! edge ([`coherent`]). The filters are trained by
//! `python -m imgform_rs.training.demosaic --method raisr_fast` and shipped
//! in `raisr_fast_weights.bin` (the layout of [`File::read`], with one
//! strength bin, two coherence bins, one or two saturation bins, and the
//! bound of [`coherent`] as the coherence threshold).

use super::raisr::{add1, taps, At, Bank, File, Filters, Row, FEATURES, POSITIONS, WINDOWS};
use super::{Isa, RowKind};
use std::ops::Range;
use std::sync::OnceLock;

/// Orientation bins: quadrants of the doubled angle ([`orientation`]).
const ORIENTATIONS: usize = 4;
/// Shape bins: isotropic or not ([`coherent`]).
const SHAPES: usize = 2;
/// Taps per missing colour: 3 columns of each window.
const TAPS: usize = 3 * WINDOWS;

/// Entries of a [`Table`] per saturation bin: the classes of a row's
/// pixels of one bin.
const LANES: usize = 16;

/// One tap of every class of a row: entry `LANES * saturated + 2 *
/// (SHAPES * orientation + shape) + chroma_site` (the [`Oriented::lane`],
/// in the saturated half when the bank has one and the pixel is
/// saturated).
type Table = [f32; 2 * LANES];

/// A [`Table`] by the CFA parity of the class, then by saturation bin:
/// the eight classes of one parity, which are the classes of every other
/// pixel of a row. AVX2's eight-entry permute takes a tap of eight
/// pixels of one parity from one of them ([`add_avx2`]).
type Halves = [[[f32; 8]; 2]; 2];

/// The filter bank of the orientation hash, as tap tables.
pub(super) struct Oriented {
    /// Per row kind (red row, blue row), per tap `3 * window + column` (the
    /// columns of [`super::raisr`]'s windows, left to right), per missing
    /// colour, the tap of each class.
    tables: [[[Table; 2]; TAPS]; 2],
    /// The same taps as [`Halves`].
    halves: [[[Halves; 2]; TAPS]; 2],
    /// The bound of [`coherent`].
    coherence: f32,
    /// The lower bound of the saturated bin, if the bank has one, on the
    /// base's local saturation ([`super::saturation`]).
    saturation: Option<f32>,
}

impl Oriented {
    /// Reads a [`File`] of [`ORIENTATIONS`] angle bins, one strength,
    /// [`SHAPES`] coherence and one or two saturation bins, and
    /// [`FEATURES`] features, whose numbers are the bound of [`coherent`]
    /// (positive) and that of the saturated bin (finite), if any, then the
    /// filters indexed `[saturation][position][orientation][shape][missing
    /// colour][feature]`.
    ///
    /// Returns `None` for a malformed file.
    pub(super) fn parse(bytes: &[u8]) -> Option<Oriented> {
        let file = File::read(bytes)?;
        let saturations = file.bins[3];
        let per_bin = POSITIONS * ORIENTATIONS * SHAPES;
        if file.bins[..3] != [ORIENTATIONS, 1, SHAPES]
            || !(1..=2).contains(&saturations)
            || file.features != FEATURES
            || file.numbers.len() != saturations * (1 + per_bin * 2 * FEATURES)
        {
            return None;
        }
        let (bounds, filters) = file.numbers.split_at(saturations);
        let (coherence, saturation) = (bounds[0], bounds.get(1).copied());
        let finite = saturation.is_none_or(f32::is_finite);
        if !(coherence > 0.0 && coherence.is_finite() && finite) {
            return None;
        }
        let mut tables = [[[[0.0; 2 * LANES]; 2]; TAPS]; 2];
        for (class, filter) in filters.chunks_exact(2 * FEATURES).enumerate() {
            let (saturated, class) = (class / per_bin, class % per_bin);
            let per_position = ORIENTATIONS * SHAPES;
            let (position, rest) = (class / per_position, class % per_position);
            let (lane, kind) = (
                LANES * saturated + Self::lane(position, rest / SHAPES, rest % SHAPES),
                &mut tables[position / 2],
            );
            // The fourth column of each window is zero: it is not a tap.
            for (k, window) in taps(filter.split_at(FEATURES), WINDOWS).iter().enumerate() {
                for (dx, tap) in kind[3 * k..3 * k + 3].iter_mut().enumerate() {
                    tap[0][lane] = window[dx];
                    tap[1][lane] = window[4 + dx];
                }
            }
        }
        let halves = tables.map(|kind| kind.map(|tap| tap.map(|t| Self::halves(&t))));
        Some(Oriented {
            tables,
            halves,
            coherence,
            saturation,
        })
    }

    /// A class's entry in its row's tables: the parity of its CFA
    /// `position` in the lowest bit, so that along a row two neighbours of
    /// the same orientation and shape differ in it alone.
    #[inline(always)]
    fn lane(position: usize, orientation: usize, shape: usize) -> usize {
        2 * (SHAPES * orientation + shape) + position % 2
    }

    /// `table`'s entries as [`Halves`].
    fn halves(table: &Table) -> Halves {
        std::array::from_fn(|parity| {
            std::array::from_fn(|bin| std::array::from_fn(|j| table[LANES * bin + 2 * j + parity]))
        })
    }

    /// A shipped filter bank, parsed on first use.
    fn shipped(cell: &'static OnceLock<Oriented>, bytes: &[u8]) -> &'static Oriented {
        cell.get_or_init(|| {
            // The files are part of the crate and checked by a unit test, so
            // a parse failure is a build defect, not bad input.
            Oriented::parse(bytes).expect("a shipped weights file is malformed")
        })
    }

    /// The shipped bank of [`super::Method::RaisrFast`], over MLRI.
    pub(super) fn raisr_fast() -> &'static Oriented {
        static BANK: OnceLock<Oriented> = OnceLock::new();
        Self::shipped(&BANK, include_bytes!("raisr_fast_weights.bin"))
    }

    /// The shipped bank of [`super::Method::RaisrCd`], over
    /// [`super::Method::RiCd`].
    pub(super) fn raisr_cd() -> &'static Oriented {
        static BANK: OnceLock<Oriented> = OnceLock::new();
        Self::shipped(&BANK, include_bytes!("raisr_cd_weights.bin"))
    }

    /// The shipped bank of [`super::Method::FusionRefined`], over
    /// [`super::Method::Fusion`].
    pub(super) fn fusion_refined() -> &'static Oriented {
        static BANK: OnceLock<Oriented> = OnceLock::new();
        Self::shipped(&BANK, include_bytes!("fusion_refined_weights.bin"))
    }
}

/// Whether the structure tensor (`a = sxx - syy`, `c = 2 sxy`, trace
/// `t`) is anisotropic: `(l1 - l2)^2 > k (l1 + l2)^2` for its eigenvalues,
/// as `a^2 + c^2` is `(l1 - l2)^2`. RAISR's coherence, `(sqrt l1 - sqrt
/// l2) / (sqrt l1 + sqrt l2)`, is a monotone function of the same ratio, so
/// a bound on it is a bound on this one, without a square root; a flat
/// tensor is isotropic. Reproduced exactly by the training script.
#[inline(always)]
fn coherent(a: f32, c: f32, t: f32, k: f32) -> bool {
    a * a + c * c > k * (t * t)
}

/// The quadrant of the doubled orientation `atan2(c, a)` of the structure
/// tensor (`a = sxx - syy`, `c = 2 sxy`), centred on 0, 90, 180 and 270
/// degrees: horizontal, diagonal, vertical and anti-diagonal gradients. A
/// flat tensor is in the first. Comparisons, reproduced exactly by the
/// training script.
#[inline(always)]
fn orientation(a: f32, c: f32) -> u32 {
    let size = c.abs();
    let slanted = if c > 0.0 { 1 } else { 3 };
    let upright = if -a >= size { 2 } else { slanted };
    if a >= size {
        0
    } else {
        upright
    }
}

impl Bank for Oriented {
    fn saturation(&self) -> Option<(f32, u32)> {
        self.saturation.map(|t| (t, LANES as u32))
    }

    #[inline(always)]
    fn classes(f: &Filters<Self>, row: &Row, class: &mut [u32]) {
        let end = class.len() - row.halo;
        let k = f.bank.coherence;
        let hash = |position, xx: f32, xy: f32, yy: f32| {
            let (a, c) = (xx - yy, 2.0 * xy);
            let shape = usize::from(coherent(a, c, xx + yy, k));
            Oriented::lane(position, orientation(a, c) as usize, shape) as u32
        };
        f.classes_row(row.kind, row.halo..end, row.sums, class, hash);
    }

    #[inline(always)]
    fn correct(f: &Filters<Self>, row: Row, class: &[u32], dst: [&mut [f32]; 3]) {
        // Only a bank with a saturated bin pays for tables twice as wide.
        if f.bank.saturation.is_some() {
            correct_row::<true>(f, row, class, dst);
        } else {
            correct_row::<false>(f, row, class, dst);
        }
    }
}

/// [`Bank::correct`] with tables of `2 * LANES` classes (`WIDE`) or of
/// [`LANES`], the classes of a bank without a saturated bin.
#[inline(always)]
fn correct_row<const WIDE: bool>(
    f: &Filters<Oriented>,
    row: Row,
    class: &[u32],
    mut dst: [&mut [f32]; 3],
) {
    let Row {
        kind,
        halo,
        windows,
        ..
    } = row;
    let end = class.len() - halo;
    let tables = &f.bank.tables[usize::from(kind.blue)];
    #[cfg(target_arch = "x86_64")]
    let both = (tables, &f.bank.halves[usize::from(kind.blue)]);
    let mut x = halo;
    let src = [windows[3], windows[4], windows[5]];
    #[cfg(target_arch = "x86_64")]
    if f.isa == Isa::Avx512 {
        let dst = dst.each_mut().map(|d| &mut **d);
        // SAFETY: `Isa::Avx512` is only made on CPUs with the AVX-512
        // subsets, AVX2 and FMA.
        let cols = (x..end, f.chroma_bound);
        x = unsafe { add_avx512::<WIDE>(both, kind, class, src, dst, windows, cols) };
    }
    #[cfg(target_arch = "x86_64")]
    if f.isa != Isa::Baseline {
        let dst = dst.each_mut().map(|d| &mut **d);
        // SAFETY: `Isa::Avx2` and `Isa::Avx512` are only made on CPUs
        // with AVX2 and FMA.
        let cols = (x..end, f.chroma_bound);
        x = unsafe { add_avx2::<WIDE>(both, kind, class, src, dst, windows, cols) };
    }
    for (x, &c) in class[..end].iter().enumerate().skip(x) {
        let d = apply(tables, c as usize, windows, x);
        add1(
            kind,
            src,
            dst.each_mut().map(|d| &mut **d),
            (x, f.chroma_bound),
            d,
        );
    }
}

/// The two corrections of the pixel at column `x` of class `class`: one
/// partial sum per window row, each tap a fused multiply-add, in the order
/// [`add_avx2`] and [`add_avx512`] compute in, so all give the same bits.
/// Fused, the vector loops are 20-25 % faster than with a product and a
/// sum per tap (one rounding less, too); where this runs without FMA
/// hardware, on a few columns per row, `mul_add` is computed in software.
#[inline(always)]
fn apply(
    tables: &[[Table; 2]; TAPS],
    class: usize,
    rows: &[&[f32]; WINDOWS],
    x: usize,
) -> (f32, f32) {
    let mut acc = [[0.0f32; 2]; 3];
    for (k, row) in rows.iter().enumerate() {
        for (dx, tap) in tables[3 * k..3 * k + 3].iter().enumerate() {
            let v = row[x - 1 + dx];
            for (a, t) in acc[k / 3].iter_mut().zip(tap) {
                *a = t[class].mul_add(v, *a);
            }
        }
    }
    let sum = |o: usize| (acc[0][o] + acc[1][o]) + acc[2][o];
    (sum(0), sum(1))
}

/// [`apply`] and [`add1`] for the columns `cols`, sixteen at a time as
/// far as whole sixteens go, then eight; returns the first column left.
///
/// A step of sixteen splits the pixels by column parity, as two vectors
/// of eight whose classes share a CFA parity, so each tap of eight pixels
/// is one permute of an eight-entry half table ([`Halves`]; a saturated
/// pixel adds a second permute and a blend). The window rows are split
/// alike, four shuffles per row, and the corrections interleaved again at
/// the end. Eight pixels side by side would need two permutes and a blend
/// per tap (four and three for the saturated classes), all but the blends
/// on the one port that permutes: split, raisr_cd with AVX2 alone takes a
/// fifth less time.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
fn add_avx2<const WIDE: bool>(
    (tables, halves): (&[[Table; 2]; TAPS], &[[Halves; 2]; TAPS]),
    kind: RowKind,
    class: &[u32],
    src: [&[f32]; 3],
    [own, green, other]: [&mut [f32]; 3],
    rows: &[&[f32]; WINDOWS],
    (cols, limit): (Range<usize>, Option<f32>),
) -> usize {
    use std::arch::x86_64::*;
    // A step from column `x` reads the window rows' columns `x - 1 .. x +
    // 17`: checked once here, so the loads need no checks of their own.
    let fits = |len: usize| cols.start >= 1 && len > cols.end;
    assert!(rows.iter().all(|r| fits(r.len())) && class.len() >= cols.end);
    let mut x = cols.start;
    while x + 16 <= cols.end {
        // SAFETY: the assertion above keeps every load in bounds (and the
        // loads are unaligned ones); the classes are within the tables, by
        // the caller's contract.
        let [d0, d1] = unsafe {
            let c = class.as_ptr().add(x);
            let (a, b) = (
                _mm256_loadu_si256(c.cast()),
                _mm256_loadu_si256(c.add(8).cast()),
            );
            let split = split_parities(_mm256_castsi256_ps(a), _mm256_castsi256_ps(b));
            let index = split.map(|v| _mm256_srli_epi32::<1>(_mm256_castps_si256(v)));
            // The half tables of the first pixel's parity and the other's.
            let first = (*c & 1) as usize;
            let bin = _mm256_slli_epi32::<27>(_mm256_or_si256(a, b));
            let saturated = WIDE && _mm256_movemask_ps(_mm256_castsi256_ps(bin)) != 0;
            if saturated {
                split_step::<true>(halves, rows, (index, first), x)
            } else {
                split_step::<false>(halves, rows, (index, first), x)
            }
        };
        // The first eight columns interleave the low halves of the
        // 128-bit lanes, the next eight the high ones.
        let (lo, hi) = (
            [d0, d1].map(|[even, odd]| _mm256_unpacklo_ps(even, odd)),
            [d0, d1].map(|[even, odd]| _mm256_unpackhi_ps(even, odd)),
        );
        for (x, d) in [(x, lo), (x + 8, hi)] {
            let dst = [&mut *own, &mut *green, &mut *other];
            // SAFETY: AVX2 is enabled here.
            unsafe { super::raisr::add8_avx2(kind, src, dst, (x, limit), d) };
        }
        x += 16;
    }
    let cols = (x..cols.end, limit);
    let dst = [own, green, other];
    // SAFETY: AVX2 and FMA are enabled here.
    unsafe { add_lanes::<__m256, WIDE>(tables, kind, class, src, dst, rows, cols) }
}

/// Eight values at even positions of `a` then `b` (the rows' next eight),
/// and eight at odd ones, in the order `a0 a2 b0 b2 | a4 a6 b4 b6`, which
/// unpacking the two interleaves again.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn split_parities(
    a: std::arch::x86_64::__m256,
    b: std::arch::x86_64::__m256,
) -> [std::arch::x86_64::__m256; 2] {
    use std::arch::x86_64::_mm256_shuffle_ps;
    // SAFETY: the caller has AVX.
    unsafe {
        [
            _mm256_shuffle_ps::<0x88>(a, b),
            _mm256_shuffle_ps::<0xdd>(a, b),
        ]
    }
}

/// The two corrections, as pixels at even and at odd offsets of sixteen
/// from column `x` (in the order of [`split_parities`]), whose classes
/// halved are `index` and whose first pixel's class has parity `first`:
/// [`split_row_sums`] of each window row, added as [`apply`] adds them.
///
/// # Safety
/// AVX2 and FMA, columns `x - 1 .. x + 17` of the window rows in bounds,
/// and the classes below [`LANES`] unless `WIDE`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn split_step<const WIDE: bool>(
    halves: &[[Halves; 2]; TAPS],
    rows: &[&[f32]; WINDOWS],
    index: ([std::arch::x86_64::__m256i; 2], usize),
    x: usize,
) -> [[std::arch::x86_64::__m256; 2]; 2] {
    use std::arch::x86_64::_mm256_add_ps as add;
    // SAFETY: by the caller's contract. Written out, as in `step`.
    unsafe {
        let a = split_row_sums::<WIDE>(halves, rows, index, 0, x);
        let b = split_row_sums::<WIDE>(halves, rows, index, 1, x);
        let c = split_row_sums::<WIDE>(halves, rows, index, 2, x);
        [
            [add(add(a[0], b[0]), c[0]), add(add(a[1], b[1]), c[1])],
            [add(add(a[2], b[2]), c[2]), add(add(a[3], b[3]), c[3])],
        ]
    }
}

/// [`row_sums`] for [`split_step`]: the first correction of the even and
/// the odd pixels, then the second's. An even pixel's window columns are
/// the odd ones from `x - 1`, the even ones from `x` and the odd ones from
/// `x + 1`; an odd pixel's are shifted one on.
///
/// # Safety
/// As [`split_step`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn split_row_sums<const WIDE: bool>(
    halves: &[[Halves; 2]; TAPS],
    rows: &[&[f32]; WINDOWS],
    ([even, odd], first): ([std::arch::x86_64::__m256i; 2], usize),
    r: usize,
    x: usize,
) -> [std::arch::x86_64::__m256; 4] {
    use std::arch::x86_64::*;
    // SAFETY: by the caller's contract.
    unsafe {
        let mut acc = [_mm256_setzero_ps(); 4];
        for k in 3 * r..3 * r + 3 {
            let at = |dx: usize| _mm256_loadu_ps(rows[k].as_ptr().add(x + dx - 1));
            let [before, _] = split_parities(at(0), at(8));
            let [here, after] = split_parities(at(1), at(9));
            let [_, shifted] = split_parities(at(2), at(10));
            let columns = [[before, here, after], [here, after, shifted]];
            for dx in 0..3 {
                let [t0, t1] = &halves[3 * k + dx];
                for (pixels, (i, parity)) in
                    [(even, first), (odd, 1 - first)].into_iter().enumerate()
                {
                    let v = columns[pixels][dx];
                    acc[pixels] = _mm256_fmadd_ps(half_tap::<WIDE>(&t0[parity], i), v, acc[pixels]);
                    acc[2 + pixels] =
                        _mm256_fmadd_ps(half_tap::<WIDE>(&t1[parity], i), v, acc[2 + pixels]);
                }
            }
        }
        acc
    }
}

/// A tap of eight pixels of one parity, whose classes halved are `index`,
/// from its half tables: one permute, and for `WIDE` a second one blended
/// in where bit 3 of `index` (the saturated bin) is set.
///
/// # Safety
/// AVX2.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn half_tap<const WIDE: bool>(
    bins: &[[f32; 8]; 2],
    index: std::arch::x86_64::__m256i,
) -> std::arch::x86_64::__m256 {
    use std::arch::x86_64::*;
    // SAFETY: by the caller's contract; the permutes read the index's low
    // three bits.
    unsafe {
        let pick = |bin: &[f32; 8]| _mm256_permutevar8x32_ps(_mm256_loadu_ps(bin.as_ptr()), index);
        if WIDE {
            let saturated = _mm256_castsi256_ps(_mm256_slli_epi32::<28>(index));
            _mm256_blendv_ps(pick(&bins[0]), pick(&bins[1]), saturated)
        } else {
            pick(&bins[0])
        }
    }
}

/// [`add_avx2`] sixteen pixels at a time: each tap table fills a 512-bit
/// register and one permute by sixteen classes gives their taps. On Zen
/// 4, which splits 512-bit operations in two, this took a sixth less time
/// than eight pixels a step even with 8-entry tables (fewer instructions
/// to issue). It takes the tables as [`add_avx2`] does, and reads the
/// whole ones alone.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,fma")]
#[inline]
fn add_avx512<const WIDE: bool>(
    (tables, _): (&[[Table; 2]; TAPS], &[[Halves; 2]; TAPS]),
    kind: RowKind,
    class: &[u32],
    src: [&[f32]; 3],
    dst: [&mut [f32]; 3],
    rows: &[&[f32]; WINDOWS],
    cols: (Range<usize>, Option<f32>),
) -> usize {
    // SAFETY: the AVX-512 subsets, AVX2 and FMA are enabled here.
    unsafe {
        add_lanes::<std::arch::x86_64::__m512, WIDE>(tables, kind, class, src, dst, rows, cols)
    }
}

/// The vector operations of the filter loop ([`add_lanes`]), at eight
/// lanes (AVX2) or sixteen (AVX-512), so that one loop serves both. The
/// methods are always inlined into the `target_feature` functions that
/// run the loop, which have the instructions.
///
/// # Safety
/// Every method needs the CPU features of its width (AVX2 and FMA, or the
/// AVX-512 subsets of [`add_avx512`]); pointers are read `N` values on.
#[cfg(target_arch = "x86_64")]
trait Lanes: Copy {
    /// Pixels per step.
    const N: usize;
    /// The classes of a step's pixels.
    type Index: Copy;
    unsafe fn classes(p: *const u32) -> Self::Index;
    /// Whether any of the classes is in a table's second half.
    unsafe fn saturated(index: Self::Index) -> bool;
    unsafe fn load(p: *const f32) -> Self;
    /// A tap of each pixel's class, from the tap's table: its first
    /// [`LANES`] entries, or all of them if `WIDE`.
    unsafe fn tap<const WIDE: bool>(table: &Table, index: Self::Index) -> Self;
    unsafe fn zero() -> Self;
    /// `a * b + c`, rounded once.
    unsafe fn fmadd(a: Self, b: Self, c: Self) -> Self;
    unsafe fn add(a: Self, b: Self) -> Self;
    /// [`add1`] for the `N` columns from `x`, the corrections as vectors
    /// [`super::raisr::bound`] by `limit`.
    unsafe fn store(kind: RowKind, src: [&[f32]; 3], dst: [&mut [f32]; 3], at: At, d: [Self; 2]);
}

#[cfg(target_arch = "x86_64")]
impl Lanes for std::arch::x86_64::__m256 {
    const N: usize = 8;
    /// The classes, and bits 3 and 4 of each moved to the sign bit, which
    /// pick the table's eights in blends.
    type Index = (std::arch::x86_64::__m256i, [std::arch::x86_64::__m256; 2]);
    #[inline(always)]
    unsafe fn classes(p: *const u32) -> Self::Index {
        use std::arch::x86_64::*;
        // SAFETY: by the trait's contract.
        let index = unsafe { _mm256_loadu_si256(p.cast()) };
        let bit = |b: __m256i| _mm256_castsi256_ps(b);
        let bits = [
            bit(_mm256_slli_epi32::<28>(index)),
            bit(_mm256_slli_epi32::<27>(index)),
        ];
        (index, bits)
    }
    #[inline(always)]
    unsafe fn saturated((_, [_, b4]): Self::Index) -> bool {
        // SAFETY: by the trait's contract.
        unsafe { std::arch::x86_64::_mm256_movemask_ps(b4) != 0 }
    }
    #[inline(always)]
    unsafe fn load(p: *const f32) -> Self {
        // SAFETY: by the trait's contract.
        unsafe { std::arch::x86_64::_mm256_loadu_ps(p) }
    }
    #[inline(always)]
    unsafe fn tap<const WIDE: bool>(table: &Table, (index, [b3, b4]): Self::Index) -> Self {
        use std::arch::x86_64::*;
        // SAFETY: by the trait's contract; a table holds 32 values, and
        // the permutes read the classes' low 3 bits.
        unsafe {
            let sixteen = |from: usize| {
                let eight = |k: usize| {
                    let v = _mm256_loadu_ps(table.as_ptr().add(from + 8 * k));
                    _mm256_permutevar8x32_ps(v, index)
                };
                _mm256_blendv_ps(eight(0), eight(1), b3)
            };
            if WIDE {
                _mm256_blendv_ps(sixteen(0), sixteen(LANES), b4)
            } else {
                sixteen(0)
            }
        }
    }
    #[inline(always)]
    unsafe fn zero() -> Self {
        // SAFETY: by the trait's contract.
        unsafe { std::arch::x86_64::_mm256_setzero_ps() }
    }
    #[inline(always)]
    unsafe fn fmadd(a: Self, b: Self, c: Self) -> Self {
        // SAFETY: by the trait's contract.
        unsafe { std::arch::x86_64::_mm256_fmadd_ps(a, b, c) }
    }
    #[inline(always)]
    unsafe fn add(a: Self, b: Self) -> Self {
        // SAFETY: by the trait's contract.
        unsafe { std::arch::x86_64::_mm256_add_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn store(kind: RowKind, src: [&[f32]; 3], dst: [&mut [f32]; 3], at: At, d: [Self; 2]) {
        // SAFETY: by the trait's contract.
        unsafe { super::raisr::add8_avx2(kind, src, dst, at, d) }
    }
}

#[cfg(target_arch = "x86_64")]
impl Lanes for std::arch::x86_64::__m512 {
    const N: usize = 16;
    type Index = std::arch::x86_64::__m512i;
    #[inline(always)]
    unsafe fn classes(p: *const u32) -> Self::Index {
        // SAFETY: by the trait's contract.
        unsafe { std::arch::x86_64::_mm512_loadu_si512(p.cast()) }
    }
    #[inline(always)]
    unsafe fn saturated(index: Self::Index) -> bool {
        use std::arch::x86_64::*;
        // SAFETY: by the trait's contract.
        unsafe { _mm512_test_epi32_mask(index, _mm512_set1_epi32(LANES as i32)) != 0 }
    }
    #[inline(always)]
    unsafe fn load(p: *const f32) -> Self {
        // SAFETY: by the trait's contract.
        unsafe { std::arch::x86_64::_mm512_loadu_ps(p) }
    }
    #[inline(always)]
    unsafe fn tap<const WIDE: bool>(table: &Table, index: Self::Index) -> Self {
        use std::arch::x86_64::*;
        // SAFETY: by the trait's contract; a table holds 32 values, and
        // the classes are below 32 (below 16 unless `WIDE`).
        unsafe {
            let low = _mm512_loadu_ps(table.as_ptr());
            if WIDE {
                let high = _mm512_loadu_ps(table.as_ptr().add(LANES));
                _mm512_permutex2var_ps(low, index, high)
            } else {
                _mm512_permutexvar_ps(index, low)
            }
        }
    }
    #[inline(always)]
    unsafe fn zero() -> Self {
        // SAFETY: by the trait's contract.
        unsafe { std::arch::x86_64::_mm512_setzero_ps() }
    }
    #[inline(always)]
    unsafe fn fmadd(a: Self, b: Self, c: Self) -> Self {
        // SAFETY: by the trait's contract.
        unsafe { std::arch::x86_64::_mm512_fmadd_ps(a, b, c) }
    }
    #[inline(always)]
    unsafe fn add(a: Self, b: Self) -> Self {
        // SAFETY: by the trait's contract.
        unsafe { std::arch::x86_64::_mm512_add_ps(a, b) }
    }
    /// The first correction goes to green at the chroma sites and to the
    /// own chroma elsewhere, by masks.
    #[inline(always)]
    unsafe fn store(
        kind: RowKind,
        src: [&[f32]; 3],
        dst: [&mut [f32]; 3],
        (x, limit): At,
        d: [Self; 2],
    ) {
        use std::arch::x86_64::*;
        let ([so, sg, st], [own, green, other], [d0, d1]) = (src, dst, d);
        // Lanes of chroma sites: the even ones when column `x` is one.
        let chroma: __mmask16 = if x & 1 == kind.chroma_parity {
            0x5555
        } else {
            0xaaaa
        };
        let (d0, d1) = match limit {
            // `bound`, lane by lane.
            Some(limit) => {
                let (lo, hi) = (_mm512_set1_ps(-limit), _mm512_set1_ps(limit));
                let clamp = |v: __m512| _mm512_min_ps(_mm512_max_ps(v, lo), hi);
                let moved = clamp(_mm512_mask_sub_ps(d1, chroma, d1, d0));
                (
                    _mm512_mask_mov_ps(d0, !chroma, clamp(d0)),
                    _mm512_mask_add_ps(moved, chroma, d0, moved),
                )
            }
            None => (d0, d1),
        };
        let (o, g, t) = (
            &mut own[x..x + 16],
            &mut green[x..x + 16],
            &mut other[x..x + 16],
        );
        let (so, sg, st) = (&so[x..x + 16], &sg[x..x + 16], &st[x..x + 16]);
        // SAFETY: by the trait's contract; each slice holds the 16 floats
        // loaded or stored (unaligned).
        unsafe {
            let (vo, vg, vt) = (
                _mm512_loadu_ps(so.as_ptr()),
                _mm512_loadu_ps(sg.as_ptr()),
                _mm512_loadu_ps(st.as_ptr()),
            );
            _mm512_storeu_ps(o.as_mut_ptr(), _mm512_mask_add_ps(vo, !chroma, vo, d0));
            _mm512_storeu_ps(g.as_mut_ptr(), _mm512_mask_add_ps(vg, chroma, vg, d0));
            _mm512_storeu_ps(t.as_mut_ptr(), _mm512_add_ps(vt, d1));
        }
    }
}

/// [`apply`] and [`add1`] for the columns `cols`, [`Lanes::N`] at a time
/// as far as whole steps go; returns the first column left.
///
/// # Safety
/// The CPU features of `V`'s width; the classes below [`LANES`] unless
/// `WIDE`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn add_lanes<V: Lanes, const WIDE: bool>(
    tables: &[[Table; 2]; TAPS],
    kind: RowKind,
    class: &[u32],
    src: [&[f32]; 3],
    [own, green, other]: [&mut [f32]; 3],
    rows: &[&[f32]; WINDOWS],
    (cols, limit): (Range<usize>, Option<f32>),
) -> usize {
    // A step of pixels from column `x` reads their windows' columns `x - 1
    // .. x + N + 1`: checked once here, so the loads need no checks of
    // their own.
    let fits = |len: usize| cols.start >= 1 && len > cols.end;
    assert!(rows.iter().all(|r| fits(r.len())) && class.len() >= cols.end);
    let mut x = cols.start;
    while x + V::N <= cols.end {
        // SAFETY: the assertion above keeps every load in bounds (and the
        // loads are unaligned ones); the classes are within the tables, by
        // the caller's contract.
        let d = unsafe {
            let index = V::classes(class.as_ptr().add(x));
            // Most steps have no saturated pixel (nine in ten on the
            // benchmark's photograph): those read the tables' first half
            // alone, which gives the same taps at half the loads.
            if WIDE && V::saturated(index) {
                step::<V, true>(tables, rows, (index, x - 1))
            } else {
                step::<V, false>(tables, rows, (index, x - 1))
            }
        };
        // SAFETY: the caller's features; `x + N` is within the rows.
        let dst = [&mut *own, &mut *green, &mut *other];
        unsafe { V::store(kind, src, dst, (x, limit), d) };
        x += V::N;
    }
    x
}

/// The two corrections of a step's pixels of classes `index` whose
/// windows start at column `left`: [`row_sums`] of each window row, added.
///
/// # Safety
/// As [`row_sums`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn step<V: Lanes, const WIDE: bool>(
    tables: &[[Table; 2]; TAPS],
    rows: &[&[f32]; WINDOWS],
    (index, left): (V::Index, usize),
) -> [V; 2] {
    // SAFETY: by the caller's contract. Written out: closures here were
    // not inlined (each call passed its vectors through memory).
    unsafe {
        let [a0, a1] = row_sums::<V, WIDE>(tables, rows, index, 0, left);
        let [b0, b1] = row_sums::<V, WIDE>(tables, rows, index, 1, left);
        let [c0, c1] = row_sums::<V, WIDE>(tables, rows, index, 2, left);
        [V::add(V::add(a0, b0), c0), V::add(V::add(a1, b1), c1)]
    }
}

/// The two corrections' partial sums over window row `r` (windows `3 r ..
/// 3 r + 3`) of a step's pixels of classes `index` whose windows start at
/// column `left`, summed tap by tap as [`apply`] does. Two accumulators,
/// so they stay in registers: one loop over all 27 taps into an array of
/// six kept them on the stack.
///
/// # Safety
/// The CPU features of `V`'s width, columns `left .. left + N + 2` of the
/// window rows in bounds, and the classes below [`LANES`] unless `WIDE`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn row_sums<V: Lanes, const WIDE: bool>(
    tables: &[[Table; 2]; TAPS],
    rows: &[&[f32]; WINDOWS],
    index: V::Index,
    r: usize,
    left: usize,
) -> [V; 2] {
    // SAFETY: by the caller's contract.
    unsafe {
        let (mut a0, mut a1) = (V::zero(), V::zero());
        for k in 3 * r..3 * r + 3 {
            for dx in 0..3 {
                let [t0, t1] = &tables[3 * k + dx];
                let v = V::load(rows[k].as_ptr().add(left + dx));
                a0 = V::fmadd(V::tap::<WIDE>(t0, index), v, a0);
                a1 = V::fmadd(V::tap::<WIDE>(t1, index), v, a1);
            }
        }
        [a0, a1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_weights_parse_and_malformed_ones_are_refused() {
        for bank in [
            Oriented::raisr_fast(),
            Oriented::raisr_cd(),
            Oriented::fusion_refined(),
        ] {
            let taps = || bank.tables.iter().flatten().flatten().flatten();
            assert!(taps().all(|v| v.is_finite()));
            assert!(taps().any(|&v| v != 0.0));
        }
        // "best" (raisr_cd) has a saturated bin; the others have none.
        assert_eq!(Oriented::raisr_cd().saturation(), Some((0.3, 16)));
        assert!(Oriented::raisr_fast().saturation.is_none());
        assert!(Oriented::fusion_refined().saturation.is_none());
        let bytes = include_bytes!("raisr_fast_weights.bin");
        assert!(Oriented::parse(&bytes[..bytes.len() - 4]).is_none());
        // RAISR's bank has the full hash's bins.
        assert!(Oriented::parse(include_bytes!("raisr_weights.bin")).is_none());
        // The bound of `coherent` comes first, and must be positive.
        let mut bound = bytes.to_vec();
        bound[28..32].copy_from_slice(&(-0.5f32).to_le_bytes());
        assert!(Oriented::parse(&bound).is_none());
        // The saturated bin's bound follows it, and must be finite.
        let saturated = include_bytes!("raisr_cd_weights.bin");
        let mut bound = saturated.to_vec();
        bound[32..36].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(Oriented::parse(&bound).is_none());
        // One or two saturation bins, and the numbers to match.
        for (file, bins) in [(&bytes[..], 2u32), (&saturated[..], 1), (&saturated[..], 3)] {
            let mut odd = file.to_vec();
            odd[20..24].copy_from_slice(&bins.to_le_bytes());
            assert!(Oriented::parse(&odd).is_none(), "{bins} bins");
        }
    }

    #[test]
    fn edges_are_coherent_and_flat_or_isotropic_tensors_are_not() {
        let k = Oriented::raisr_cd().coherence;
        // (sxx, sxy, syy): a vertical edge, a diagonal one, isotropic, flat.
        let shape = |(xx, xy, yy): (f32, f32, f32)| coherent(xx - yy, 2.0 * xy, xx + yy, k);
        assert!(shape((1.0, 0.0, 0.0)) && shape((0.5, 0.5, 0.5)));
        assert!(!shape((1.0, 0.0, 1.0)) && !shape((0.0, 0.0, 0.0)));
        // Eigenvalues 1 and l2: anisotropic up to RAISR's coherence 0.3,
        // where sqrt(l2) = 0.7 / 1.3.
        let l2 = (0.7f32 / 1.3).powi(2);
        assert!(shape((1.0, 0.0, l2 * 0.98)) && !shape((1.0, 0.0, l2 * 1.02)));
    }

    #[test]
    fn orientations_are_the_quadrants_of_the_doubled_angle() {
        assert_eq!(orientation(0.0, 0.0), 0);
        assert_eq!(orientation(1.0, 0.5), 0);
        assert_eq!(orientation(0.5, 1.0), 1);
        assert_eq!(orientation(-1.0, 0.5), 2);
        assert_eq!(orientation(0.5, -1.0), 3);
        // On the diagonals the upright bins win.
        assert_eq!(orientation(1.0, 1.0), 0);
        assert_eq!(orientation(-1.0, -1.0), 2);
    }

    /// The vector loops (sixteen pixels a step split by parity, then
    /// eight, with AVX2; sixteen side by side with AVX-512) give the bits
    /// of the scalar code, pixel by pixel, from either column parity.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_vector_filters_give_the_scalar_bits() {
        use std::arch::is_x86_feature_detected as has;
        if !(has!("avx2") && has!("fma")) {
            return;
        }
        let wide = has!("avx512f") && has!("avx512dq") && has!("avx512vl");
        const LEN: usize = 48;
        let planes: Vec<Vec<f32>> = (0..WINDOWS)
            .map(|k| {
                (0..LEN)
                    .map(|i| ((i * 37 + k * 11) % 29) as f32 * 0.37 - 3.1)
                    .collect()
            })
            .collect();
        let rows: [&[f32]; WINDOWS] = std::array::from_fn(|k| &planes[k][..]);
        type Loop = unsafe fn(
            (&[[Table; 2]; TAPS], &[[Halves; 2]; TAPS]),
            RowKind,
            &[u32],
            [&[f32]; 3],
            [&mut [f32]; 3],
            &[&[f32]; WINDOWS],
            (Range<usize>, Option<f32>),
        ) -> usize;
        for bank in [
            Oriented::raisr_fast(),
            Oriented::raisr_cd(),
            Oriented::fusion_refined(),
        ] {
            let (loops, lanes): (Vec<Loop>, _) = match bank.saturation {
                Some(_) => (vec![add_avx2::<true>, add_avx512::<true>], 2 * LANES),
                None => (vec![add_avx2::<false>, add_avx512::<false>], LANES),
            };
            let loops = &loops[..1 + usize::from(wide)];
            // Every class of the bank's tables, the saturated half too, with
            // the CFA parity of each column in the lowest bit, as the hash
            // gives it. Saturated classes from column 20 on only, so that
            // some steps of either width have none (and read the tables'
            // first half).
            let class: Vec<u32> = (0..LEN)
                .map(|i| {
                    let lane = i * 7 % if i < 20 { LANES } else { lanes };
                    (lane & !1 | i & 1) as u32
                })
                .collect();
            let tables = bank.tables.iter().zip(&bank.halves);
            for (blue, (tables, halves)) in tables.enumerate() {
                // Unbounded, and bounded tightly enough to cut corrections;
                // steps from odd and from even columns.
                let cases = [0, 1]
                    .into_iter()
                    .flat_map(|p| [(p, None), (p, Some(0.05))]);
                for ((parity, limit), first) in cases.flat_map(|c| [(c, 1), (c, 2)]) {
                    let kind = RowKind {
                        blue: blue == 1,
                        chroma_parity: parity,
                    };
                    let src = [rows[3], rows[4], rows[5]];
                    let scalar = |planes: &mut [Vec<f32>; 3], cols: Range<usize>| {
                        for x in cols {
                            let d = apply(tables, class[x] as usize, &rows, x);
                            let dst = planes.each_mut().map(|p| &mut p[..]);
                            add1(kind, src, dst, (x, limit), d);
                        }
                    };
                    let cols = first..first + 41;
                    let mut slow = [0; 3].map(|_| vec![1.0f32; LEN]);
                    scalar(&mut slow, cols.clone());
                    for (run, step) in loops.iter().zip([8, 16]) {
                        let mut fast = [0; 3].map(|_| vec![1.0f32; LEN]);
                        let dst = fast.each_mut().map(|p| &mut p[..]);
                        let at = ((cols.clone(), limit), (tables, halves));
                        // SAFETY: the features were detected above.
                        let end = unsafe { run(at.1, kind, &class, src, dst, &rows, at.0) };
                        // Whole steps (AVX2's last one of eight).
                        assert_eq!(end, cols.end - 41 % step);
                        scalar(&mut fast, end..cols.end);
                        let bits = |p: &[Vec<f32>; 3]| {
                            p.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>()
                        };
                        assert_eq!(bits(&fast), bits(&slow), "{step} a step from {first}");
                    }
                }
            }
        }
    }
}

//! A learned refinement of our best classical demosaicer, in the manner of
//! RAISR: Romano, Isidoro and Milanfar, "RAISR: Rapid and Accurate Image
//! Super Resolution", IEEE Transactions on Computational Imaging 3(1), 2017.
//!
//! RAISR learns, per class of local structure, a least-squares linear filter
//! from a cheap upscaler's output to the truth. Here the estimate is MLRI's
//! ([`super::mlri`]) and the filters predict its residual: at every
//! pixel, the two colours the photosite did not see get a correction that is
//! a linear function of 26 features of the base output around the pixel.
//! The filter is chosen by the pixel's CFA position (red or blue row, chroma
//! or green site) and a hash of the structure tensor of the base's green over
//! a 3x3 window (RAISR's angle, strength and coherence), so the map is
//! linear within a class but adapts to edges and texture across classes.
//!
//! The features are differences (each colour at the 8 neighbours minus the
//! same colour at the centre, and the centre's two chroma minus its green),
//! and the filters have no bias term: a flat image has all features zero and
//! comes back unchanged. Colours are named in the centre row's frame (its own
//! chroma, green, the other chroma), so one set of filters serves all four
//! Bayer phases. The known colour of each site is never touched.
//!
//! The same machinery fuses two bases ([`super::fusion`]): the filters then
//! also see the second base's difference from the first over the 3x3
//! window, 27 features more, and learn per class how far to trust either
//! (the learned fusion of "ri_cd" and RCD, [`super::Method::Fusion`]).
//!
//! The filters are trained by `python -m imgform_rs.training.demosaic` on
//! openly licensed images that are not the benchmark's (see the docs) and
//! shipped in `raisr_weights.bin` and `fusion_weights.bin`, whose layout
//! [`Weights::parse`] reads.

use super::{Isa, Phase, RowKind};
use std::ops::Range;
use std::sync::OnceLock;

/// Features per pixel of one base: 8 neighbours x 3 colours, plus 2 centre
/// differences.
pub(crate) const FEATURES: usize = 26;
/// Features a second base adds: its difference from the first, 3 colours
/// at each pixel of the 3x3 window.
const SECOND_FEATURES: usize = 27;
/// Tap windows (a plane on a row, 4 columns) per base: 3 planes x 3 rows.
pub(super) const WINDOWS: usize = 9;
/// Floats from one plane to the next in the rows the hashed filters read:
/// each row holds its base's three planes this far apart, so that a row's
/// three windows are one pointer and two constant offsets. The filters
/// then keep the pointers of their six rows (two bases) in registers
/// instead of loading one of eighteen per window and pixel: 3 % less time
/// for "fusion_refined" at 24 MP (Rust harness, same bits). It bounds the
/// width of the tiles refined (checked at compile time in
/// [`super::refined`]).
pub(super) const PITCH: usize = 1664;
/// The most rows a filter's windows lie on: three for each of two bases.
const MAX_ROWS: usize = 6;

/// Plane `p` (own chroma, green, other chroma), `n` long, of a row of a
/// ring holding a base's planes [`PITCH`] apart.
#[inline(always)]
pub(super) fn plane(row: &[f32], p: usize, n: usize) -> &[f32] {
    &row[p * PITCH..p * PITCH + n]
}

/// The three planes of such a row, `n` long.
#[inline(always)]
pub(super) fn plane_row(row: &[f32], n: usize) -> [&[f32]; 3] {
    [0, 1, 2].map(|p| plane(row, p, n))
}

/// How far the fusion, its cascade and "raisr_cd" may move a missing colour's
/// difference from green away from their base's, as a fraction of the full
/// scale ([`Filters::chroma_bound`]). Larger moves were false colour on
/// grey detail, where the mosaic aliases, far more often than corrections:
/// the filters were fitted on photographs, where moves that large are rare.
pub(super) const CHROMA_LIMIT: f32 = 8.0 / 255.0;

/// [`plane`] to write.
#[inline(always)]
pub(super) fn plane_mut(row: &mut [f32], p: usize, n: usize) -> &mut [f32] {
    &mut row[p * PITCH..p * PITCH + n]
}

/// Angle bins of the structure tensor's orientation (fixed by [`angle_bin`]).
const ANGLES: usize = 8;
/// Strength and coherence bins: fixed, so the thresholds are arrays and the
/// hash of a row compiles to straight-line vector code.
const STRENGTHS: usize = 3;
const COHERENCES: usize = 3;
/// CFA positions: (blue row, chroma site) pairs.
pub(super) const POSITIONS: usize = 4;
/// Header magic of the weights file.
const MAGIC: &[u8; 8] = b"IGRAISR2";
/// Classes of one saturation bin: the filters of a bank with two follow
/// those of the unsaturated bin ([`Weights::parse`]).
const HASHED: usize = POSITIONS * ANGLES * STRENGTHS * COHERENCES;

/// A filter rewritten as taps on the tile's planes, one [`Window`] per
/// plane and row: window `3 * r + p` is plane `p` (own chroma, green, other
/// chroma of *that* row) of the first base on row `y + r - 1`, columns
/// `x - 1 ..= x + 2`; with a second base, window `9 + 3 * r + p` is its
/// difference from the first.
type Taps<const N: usize> = [Window; N];

/// The taps of one window: lanes 0..4 give the first missing colour, lanes
/// 4..8 the second. The fourth column's tap is zero: it only makes a
/// window one 4-wide load, which both halves of an 8-wide multiply share.
pub(super) type Window = [f32; 8];

/// The trained filter bank, as taps, and its hashing thresholds.
pub(crate) struct Weights {
    /// Windows per filter: [`WINDOWS`] for one base, twice that for two.
    windows: usize,
    /// Upper bounds of the strength bins but the last, on the largest
    /// eigenvalue of the structure tensor of full-scale-normalised green.
    strength: [f32; STRENGTHS - 1],
    /// Upper bounds of the coherence bins but the last.
    coherence: [f32; COHERENCES - 1],
    /// The lower bound of the saturated bin, when the bank has one, on the
    /// base's local saturation ([`super::saturation`]).
    saturation: Option<f32>,
    /// The filters' windows, `windows` per class.
    taps: Vec<Window>,
}

/// A weights file's contents: its bin counts (angle, strength, coherence,
/// saturation), its feature count and its numbers (thresholds, then
/// filters).
pub(super) struct File {
    pub(super) bins: [usize; 4],
    pub(super) features: usize,
    pub(super) numbers: Vec<f32>,
}

impl File {
    /// Reads the little-endian layout: the 8-byte magic `IGRAISR2`; `u32`
    /// counts of angle, strength, coherence and saturation bins and of
    /// features; then `f32`s. Returns `None` for a malformed file.
    pub(super) fn read(bytes: &[u8]) -> Option<File> {
        let body = bytes.strip_prefix(MAGIC)?;
        if body.len() % 4 != 0 {
            return None;
        }
        let mut words = body.chunks_exact(4).map(|w| [w[0], w[1], w[2], w[3]]);
        let mut count = || words.next().map(|w| u32::from_le_bytes(w) as usize);
        let bins = [count()?, count()?, count()?, count()?];
        Some(File {
            bins,
            features: count()?,
            numbers: words.map(f32::from_le_bytes).collect(),
        })
    }
}

impl Weights {
    /// Reads a [`File`] of [`ANGLES`], [`STRENGTHS`], [`COHERENCES`] and
    /// one or two saturation bins and [`FEATURES`] features for one base,
    /// [`SECOND_FEATURES`] more for two, whose numbers are the strength,
    /// coherence and saturation thresholds (one fewer than bins each) and
    /// the filters, indexed `[saturation][position][angle][strength]
    /// [coherence][missing colour][feature]`, position being `2 *
    /// blue_row + chroma_site`.
    ///
    /// Returns `None` for a malformed file.
    pub(crate) fn parse(bytes: &[u8]) -> Option<Weights> {
        let File {
            bins,
            features,
            numbers: rest,
        } = File::read(bytes)?;
        let windows = match features {
            FEATURES => WINDOWS,
            f if f == FEATURES + SECOND_FEATURES => 2 * WINDOWS,
            _ => return None,
        };
        let saturations = bins[3];
        let thresholds = STRENGTHS - 1 + COHERENCES - 1 + saturations.checked_sub(1)?;
        if bins[..3] != [ANGLES, STRENGTHS, COHERENCES]
            || saturations > 2
            || rest.len() != thresholds + saturations * HASHED * 2 * features
        {
            return None;
        }
        let (strength, rest) = rest.split_at(STRENGTHS - 1);
        let (coherence, rest) = rest.split_at(COHERENCES - 1);
        let (saturation, rest) = rest.split_at(saturations - 1);
        if !saturation.iter().all(|t| t.is_finite()) {
            return None;
        }
        let taps = rest
            .chunks_exact(2 * features)
            .flat_map(|f| taps(f.split_at(features), windows))
            .collect();
        Some(Weights {
            windows,
            strength: strength.try_into().ok()?,
            coherence: coherence.try_into().ok()?,
            saturation: saturation.first().copied(),
            taps,
        })
    }

    /// A shipped filter bank, parsed on first use.
    fn shipped(cell: &'static OnceLock<Weights>, bytes: &[u8], windows: usize) -> &'static Weights {
        cell.get_or_init(|| {
            // The files are part of the crate and checked by a unit test, so
            // a parse failure is a build defect, not bad input.
            Weights::parse(bytes)
                .filter(|w| w.windows == windows)
                .expect("a shipped weights file is malformed")
        })
    }

    /// The shipped filter bank of the refinement of MLRI alone.
    pub(crate) fn raisr() -> &'static Weights {
        static WEIGHTS: OnceLock<Weights> = OnceLock::new();
        Self::shipped(&WEIGHTS, include_bytes!("raisr_weights.bin"), WINDOWS)
    }

    /// The shipped filter bank of the fusion of "ri_cd" and RCD.
    pub(crate) fn fusion() -> &'static Weights {
        static WEIGHTS: OnceLock<Weights> = OnceLock::new();
        Self::shipped(&WEIGHTS, include_bytes!("fusion_weights.bin"), 2 * WINDOWS)
    }

    /// The windows of class `class`'s filter.
    #[inline(always)]
    fn filter<const N: usize>(&self, class: u32) -> &Taps<N> {
        let start = class as usize * N;
        self.taps[start..start + N]
            .try_into()
            .expect("N is the bank's window count")
    }

    /// The class (index into `taps`) of a CFA position and structure-tensor
    /// sums; [`hash_avx2`] computes eight at a time, to the same bits.
    #[inline(always)]
    fn class(&self, position: usize, sxx: f32, sxy: f32, syy: f32) -> usize {
        let (l1, coh) = eigen(sxx, sxy, syy);
        let s = bin(&self.strength, l1);
        let c = bin(&self.coherence, coh);
        let a = angle_bin(sxx - syy, 2.0 * sxy);
        ((position * ANGLES + a) * STRENGTHS + s) * COHERENCES + c
    }
}

/// The plane holding colour `j` of the centre row's frame (0 own chroma,
/// 1 green, 2 other chroma) on a row `dy` away: rows above and below are of
/// the other kind, so their own chroma is the centre's other.
fn plane_of(j: usize, dy: isize) -> usize {
    if dy == 0 {
        j
    } else {
        2 - j
    }
}

/// Rewrites a filter (its two missing colours' weights on the features) as
/// `windows` windows of taps on the planes: feature `f[3k + j] = C_j(n_k) -
/// C_j(centre)` puts `w` on the neighbour and `-w` on the centre, `f[24] =
/// own - green`, `f[25] = other - green`; a second base's feature
/// `f[26 + 3m + j]`, its difference in colour `j` at the `m`-th pixel of
/// the 3x3 window (row by row), is a tap on the difference planes. The sums
/// are the same linear map, evaluated with fewer operations.
pub(super) fn taps((first, second): (&[f32], &[f32]), windows: usize) -> Vec<Window> {
    let mut t = vec![[0.0f32; 8]; windows];
    for (half, w) in [first, second].into_iter().enumerate() {
        let mut add = |base: usize, dy: isize, dx: isize, j: usize, v: f32| {
            let window = WINDOWS * base + 3 * (1 + dy) as usize + plane_of(j, dy);
            t[window][4 * half + (1 + dx) as usize] += v;
        };
        for (k, &(dy, dx)) in NEIGHBOURS.iter().enumerate() {
            for j in 0..3 {
                add(0, dy, dx, j, w[3 * k + j]);
                add(0, 0, 0, j, -w[3 * k + j]);
            }
        }
        add(0, 0, 0, 0, w[24]);
        add(0, 0, 0, 2, w[25]);
        add(0, 0, 0, 1, -(w[24] + w[25]));
        for (m, w) in w[FEATURES..].chunks_exact(3).enumerate() {
            let (dy, dx) = (m as isize / 3 - 1, m as isize % 3 - 1);
            for (j, &v) in w.iter().enumerate() {
                add(1, dy, dx, j, v);
            }
        }
    }
    t
}

/// The number of thresholds `v` reaches.
#[inline(always)]
fn bin<const N: usize>(thresholds: &[f32; N], v: f32) -> usize {
    thresholds.iter().map(|&t| usize::from(v >= t)).sum()
}

/// The largest eigenvalue of the tensor `[[sxx, sxy], [sxy, syy]]` and the
/// coherence `(sqrt(l1) - sqrt(l2)) / (sqrt(l1) + sqrt(l2))` (0 when flat).
#[inline(always)]
fn eigen(sxx: f32, sxy: f32, syy: f32) -> (f32, f32) {
    let half_trace = 0.5 * (sxx + syy);
    let half_diff = 0.5 * (sxx - syy);
    let d = (half_diff * half_diff + sxy * sxy).sqrt();
    let l1 = half_trace + d;
    let l2 = (half_trace - d).max(0.0);
    let (r1, r2) = (l1.sqrt(), l2.sqrt());
    let sum = r1 + r2;
    let coherence = if sum > 0.0 { (r1 - r2) / sum } else { 0.0 };
    (l1, coherence)
}

/// cos and sin of 22.5 degrees: [`angle_bin`]'s rotation of the doubled
/// angle, shared by its vector twin [`hash_avx2`].
const COS: f32 = 0.923_879_5;
const SIN: f32 = 0.382_683_43;

/// The octant of the doubled orientation angle `atan2(b, a)` of the tensor
/// (`a = sxx - syy`, `b = 2 sxy`), rotated by 22.5 degrees so that bins
/// are centred on horizontal, diagonal and vertical gradients. Comparisons
/// instead of `atan2`, so the training script reproduces it exactly; the
/// quadrant comes from the signs, the octant within it from one comparison.
#[inline(always)]
fn angle_bin(a: f32, b: f32) -> usize {
    let (u, v) = (a * COS - b * SIN, a * SIN + b * COS);
    let (top, right) = (v >= 0.0, u >= 0.0);
    let quadrant = 2 * usize::from(!top) + usize::from(top != right);
    let upper = match (top, right) {
        (true, true) => v > u,
        (true, false) => v < -u,
        (false, false) => -v > -u,
        (false, true) => -v < u,
    };
    2 * quadrant + usize::from(upper)
}

/// [`Filters::hash_row`]'s classes ([`Weights::class`]) of the columns
/// `cols`, eight at a time, by the same IEEE operations in the same order
/// (no fused multiply-adds), so every class is the scalar one; returns the
/// first column left for the scalar loop. The hash is a dependent chain of
/// two square roots and a division per pixel, which one at a time cost
/// more than the filters it chooses.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn hash_avx2(
    w: &Weights,
    kind: RowKind,
    sums: [[&[f32]; 3]; 3],
    class: &mut [u32],
    cols: Range<usize>,
) -> usize {
    use std::arch::x86_64::*;
    let ps = _mm256_set1_ps;
    let ints = _mm256_castps_si256;
    let lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    // Columns advance by eight, so each lane keeps its column's parity.
    let odd = _mm256_and_si256(
        _mm256_add_epi32(lanes, _mm256_set1_epi32(cols.start as i32)),
        _mm256_set1_epi32(1),
    );
    let parity = _mm256_set1_epi32(kind.chroma_parity as i32);
    let chroma = _mm256_and_si256(_mm256_cmpeq_epi32(odd, parity), _mm256_set1_epi32(1));
    let position = _mm256_add_epi32(_mm256_set1_epi32(2 * i32::from(kind.blue)), chroma);
    let first = _mm256_mullo_epi32(
        position,
        _mm256_set1_epi32((ANGLES * STRENGTHS * COHERENCES) as i32),
    );
    // A comparison's mask (-1 or 0) as `k` or 0.
    let count = |mask: __m256, k: i32| _mm256_and_si256(ints(mask), _mm256_set1_epi32(k));
    let mut x = cols.start;
    while x + 8 <= cols.end {
        // SAFETY: the slice holds the eight values read.
        let load = |r: &[f32]| unsafe { _mm256_loadu_ps(r[x..x + 8].as_ptr()) };
        let add3 =
            |p: &[&[f32]; 3]| _mm256_add_ps(_mm256_add_ps(load(p[0]), load(p[1])), load(p[2]));
        let [sxx, sxy, syy] = sums.each_ref().map(add3);
        // eigen()
        let half_trace = _mm256_mul_ps(ps(0.5), _mm256_add_ps(sxx, syy));
        let half_diff = _mm256_mul_ps(ps(0.5), _mm256_sub_ps(sxx, syy));
        let d = _mm256_sqrt_ps(_mm256_add_ps(
            _mm256_mul_ps(half_diff, half_diff),
            _mm256_mul_ps(sxy, sxy),
        ));
        let l1 = _mm256_add_ps(half_trace, d);
        let l2 = _mm256_max_ps(_mm256_sub_ps(half_trace, d), _mm256_setzero_ps());
        let (r1, r2) = (_mm256_sqrt_ps(l1), _mm256_sqrt_ps(l2));
        let sum = _mm256_add_ps(r1, r2);
        let coherence = _mm256_and_ps(
            _mm256_div_ps(_mm256_sub_ps(r1, r2), sum),
            _mm256_cmp_ps::<_CMP_GT_OQ>(sum, _mm256_setzero_ps()),
        );
        // angle_bin()
        let a = _mm256_sub_ps(sxx, syy);
        let b = _mm256_mul_ps(ps(2.0), sxy);
        let u = _mm256_sub_ps(_mm256_mul_ps(a, ps(COS)), _mm256_mul_ps(b, ps(SIN)));
        let v = _mm256_add_ps(_mm256_mul_ps(a, ps(SIN)), _mm256_mul_ps(b, ps(COS)));
        let negate = |p: __m256| _mm256_xor_ps(p, ps(-0.0));
        let top = _mm256_cmp_ps::<_CMP_GE_OQ>(v, _mm256_setzero_ps());
        let right = _mm256_cmp_ps::<_CMP_GE_OQ>(u, _mm256_setzero_ps());
        let upper = _mm256_blendv_ps(
            _mm256_blendv_ps(
                _mm256_cmp_ps::<_CMP_GT_OQ>(negate(v), negate(u)),
                _mm256_cmp_ps::<_CMP_LT_OQ>(negate(v), u),
                right,
            ),
            _mm256_blendv_ps(
                _mm256_cmp_ps::<_CMP_LT_OQ>(v, negate(u)),
                _mm256_cmp_ps::<_CMP_GT_OQ>(v, u),
                right,
            ),
            top,
        );
        let bottom = _mm256_xor_ps(top, _mm256_castsi256_ps(_mm256_set1_epi32(-1)));
        let turned = _mm256_xor_ps(top, right);
        let per_angle = (STRENGTHS * COHERENCES) as i32;
        let mut c = _mm256_add_epi32(first, count(bottom, 4 * per_angle));
        c = _mm256_add_epi32(c, count(turned, 2 * per_angle));
        c = _mm256_add_epi32(c, count(upper, per_angle));
        for &t in &w.strength {
            c = _mm256_add_epi32(
                c,
                count(_mm256_cmp_ps::<_CMP_GE_OQ>(l1, ps(t)), COHERENCES as i32),
            );
        }
        for &t in &w.coherence {
            c = _mm256_add_epi32(c, count(_mm256_cmp_ps::<_CMP_GE_OQ>(coherence, ps(t)), 1));
        }
        // SAFETY: the slice holds the eight values written.
        unsafe { _mm256_storeu_si256(class[x..x + 8].as_mut_ptr().cast(), c) };
        x += 8;
    }
    x
}

/// A filter bank with what applying it needs: the hash's scale and the
/// clamping bounds. Its methods work a row at a time, on a base's rows as
/// they stream out, alone ([`super::refined`]) or beside a second base's
/// ([`super::fusion`]).
pub(super) struct Filters<B: 'static = Weights> {
    pub(super) phase: Phase,
    /// `1 / FULL_SCALE` of the sample type, so the hash sees [0, 1] data.
    pub(super) inv_scale: f32,
    /// The mosaic's smallest and largest sample: the base is clamped to
    /// them before the features are taken, as the training script sees it.
    pub(super) bounds: (f32, f32),
    pub(super) bank: &'static B,
    /// Whether the filters run in AVX ([`apply_avx2`]) or scalar code.
    pub(super) isa: Isa,
    /// How far the filters may move a missing colour's difference from
    /// green away from the base's, in the sample type's scale (see
    /// [`CHROMA_LIMIT`]); `None`: as far as they like.
    pub(super) chroma_bound: Option<f32>,
    /// The least sum that makes a pixel saturated, in the sample type's
    /// scale ([`super::saturation::least_saturated`]), and the offset of
    /// the saturated bin's classes, if the bank has that bin
    /// ([`Bank::saturation`]).
    pub(super) saturated: Option<(f32, u32)>,
}

/// What refining a row reads: the row's kind, the columns it leaves at
/// each end, the structure tensor's horizontal sums on the rows above, at
/// and below it (see [`Filters::tensor_row`]) and the base's windows.
pub(super) struct Row<'a> {
    pub(super) kind: RowKind,
    pub(super) halo: usize,
    pub(super) sums: [[&'a [f32]; 3]; 3],
    pub(super) windows: &'a [&'a [f32]; WINDOWS],
    /// The windows' rows, each holding the base's three planes [`PITCH`]
    /// apart (the hashed filters read these).
    pub(super) rows: &'a [&'a [f32]; 3],
}

/// A filter bank that refines rows: how it classes a row's pixels from the
/// structure tensor's 3x3 sums and corrects them from the base's windows.
pub(super) trait Bank: Sync + Sized + 'static {
    /// The saturated bin's lower bound and how many classes on its filters
    /// start, if the bank's classes are split by the base's saturation
    /// ([`super::saturation`]).
    fn saturation(&self) -> Option<(f32, u32)>;

    /// Writes the class of every column `halo .. len - halo` of a row
    /// into `class`, from its structure tensor; [`Bank::saturation`] then
    /// moves the saturated ones.
    fn classes(f: &Filters<Self>, row: &Row, class: &mut [u32]);

    /// Writes the columns `halo .. len - halo` of `dst` (own chroma,
    /// green, other chroma): the base's row (the windows' middle row) plus
    /// the corrections of each column's class. The other columns are left
    /// as they were.
    fn correct(f: &Filters<Self>, row: Row, class: &[u32], dst: [&mut [f32]; 3]);
}

impl Bank for Weights {
    fn saturation(&self) -> Option<(f32, u32)> {
        self.saturation.map(|t| (t, HASHED as u32))
    }

    #[inline(always)]
    fn classes(f: &Filters<Self>, row: &Row, class: &mut [u32]) {
        f.hash_row(row.kind, row.halo, row.sums, class);
    }

    #[inline(always)]
    fn correct(f: &Filters<Self>, row: Row, class: &[u32], dst: [&mut [f32]; 3]) {
        f.correct_row::<WINDOWS>(row.kind, row.halo, class, dst, row.rows);
    }
}

/// The 3x3 neighbours in feature order (row by row, centre excluded).
const NEIGHBOURS: [(isize, isize); 8] = [
    (-1, -1),
    (-1, 0),
    (-1, 1),
    (0, -1),
    (0, 1),
    (1, -1),
    (1, 0),
    (1, 1),
];

/// The two corrections of the pixel at column `x` whose windows' rows are
/// `rows` (see [`Taps`]). Eight independent lanes, one partial sum per
/// window row (three short dependency chains instead of one of nine or
/// eighteen additions), each a product then a sum (no fused multiply-add),
/// then the pairwise sum of each half: the order [`apply_avx2`] computes
/// in, so both give the same bits.
#[inline(always)]
fn apply<const N: usize>(taps: &Taps<N>, rows: &[&[f32]], x: usize) -> (f32, f32) {
    let mut acc = [[0.0f32; 8]; 3];
    for (k, t) in taps.iter().enumerate() {
        let v = &rows[k / 3][k % 3 * PITCH + x - 1..][..4];
        for (l, a) in acc[k / 3 % 3].iter_mut().enumerate() {
            *a += t[l] * v[l & 3];
        }
    }
    let lane = |l: usize| (acc[0][l] + acc[1][l]) + acc[2][l];
    let half = |o: usize| (lane(o) + lane(o + 1)) + (lane(o + 2) + lane(o + 3));
    (half(0), half(4))
}

/// [`apply`] in AVX: each window is one 4-wide load broadcast to both
/// halves of an 8-wide register, so a pixel costs 9 loads, multiplies and
/// adds; two horizontal adds give `(a0 + a1) + (a2 + a3)` per half. The
/// compiler does not find this itself: it kept [`apply`] in scalar code.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn apply_avx2<const N: usize>(taps: &Taps<N>, rows: &[&[f32]], x: usize) -> (f32, f32) {
    use std::arch::x86_64::*;
    // SAFETY: this function runs with AVX2, which `lanes_avx2` needs.
    let acc = unsafe { lanes_avx2(taps, rows, x) };
    let h = _mm_hadd_ps(_mm256_castps256_ps128(acc), _mm256_extractf128_ps::<1>(acc));
    let h = _mm_hadd_ps(h, h);
    (_mm_cvtss_f32(h), _mm_cvtss_f32(_mm_movehdup_ps(h)))
}

/// The eight lanes of [`apply`] before the sums of its halves: the first
/// correction's four partial sums, then the second's.
///
/// Always inlined, so not a `target_feature` function (which cannot be):
/// compiled as one of its own and called per pixel, it checked its windows'
/// bounds and reloaded their pointers at every call and loaded each window
/// in two steps, a load and an insert, where inlined it is one broadcast.
/// 9 % less time for the fusion at 24 MP (Rust harness, same bits).
///
/// # Safety
/// The caller runs with AVX2.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn lanes_avx2<const N: usize>(
    taps: &Taps<N>,
    rows: &[&[f32]],
    x: usize,
) -> std::arch::x86_64::__m256 {
    use std::arch::x86_64::*;
    let mut acc = [_mm256_setzero_ps(); 3];
    // Loops of constant trip counts, with window `9 * block + 3 * r + p`
    // going to accumulator `r` (as `k / 3 % 3` in [`apply`]): unrolled with
    // the accumulators in registers. One loop over the windows, indexing
    // the accumulators by `k`, was not unrolled for two bases: it kept them
    // on the stack, a store and reload per window (30 % of the fusion's
    // profile, most of it that chain).
    for block in 0..N / WINDOWS {
        for (r, a) in acc.iter_mut().enumerate() {
            let row = rows[3 * block + r];
            for p in 0..3 {
                let k = block * WINDOWS + 3 * r + p;
                let v = &row[p * PITCH + x - 1..][..4];
                // SAFETY: `v` and `taps[k]` hold 4 and 8 floats (slice and
                // array lengths); the loads are unaligned ones.
                let (v, t) =
                    unsafe { (_mm_loadu_ps(v.as_ptr()), _mm256_loadu_ps(taps[k].as_ptr())) };
                *a = _mm256_add_ps(*a, _mm256_mul_ps(t, _mm256_set_m128(v, v)));
            }
        }
    }
    _mm256_add_ps(_mm256_add_ps(acc[0], acc[1]), acc[2])
}

/// [`apply_avx2`] for the eight pixels from column `x`, each with its own
/// class: the halves' sums of all eight come from six horizontal adds
/// (two levels of pairs, as in [`apply`]) instead of sixteen, and the
/// corrections as two vectors, the first's of the eight pixels and the
/// second's.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn apply8_avx2<const N: usize>(
    weights: &Weights,
    class: &[u32],
    rows: &[&[f32]],
    x: usize,
) -> [std::arch::x86_64::__m256; 2] {
    use std::arch::x86_64::*;
    // The eight pixels' rows (all three planes) and classes, sliced once:
    // the loads of each pixel then need no bounds checks (a dozen compares
    // per pixel). Loops in this function rather than `array::from_fn`, whose closures
    // were compiled as functions of their own, the second called for each
    // pixel (26 % of the fusion's profile): 13 % less time for the fusion,
    // 23 % for RAISR at 24 MP, same bits.
    let mut cut: [&[f32]; MAX_ROWS] = [&[]; MAX_ROWS];
    for (c, row) in cut.iter_mut().zip(rows) {
        *c = &row[x - 1..2 * PITCH + x + 11];
    }
    let (rows, class) = (&cut[..rows.len()], &class[x..x + 8]);
    let mut a = [_mm256_setzero_ps(); 8];
    for (i, a) in a.iter_mut().enumerate() {
        // SAFETY: this function runs with AVX2.
        *a = unsafe { lanes_avx2(weights.filter::<N>(class[i]), rows, i + 1) };
    }
    // Per 128-bit half: pairs of lanes of pixels (0, 1), then their sums
    // for pixels 0..4 (first correction, low half; second, high half).
    let pairs = [0, 2, 4, 6].map(|i| _mm256_hadd_ps(a[i], a[i + 1]));
    let low = _mm256_hadd_ps(pairs[0], pairs[1]);
    let high = _mm256_hadd_ps(pairs[2], pairs[3]);
    [
        _mm256_permute2f128_ps::<0x20>(low, high),
        _mm256_permute2f128_ps::<0x31>(low, high),
    ]
}

/// Pixels the hash reaches beyond the output: 1 for the 3x3 sums of the
/// structure tensor, 1 for the central differences under them.
pub(super) const REACH: usize = 2;

impl<B> Filters<B> {
    /// `src` clamped to the mosaic's range, into `dst`.
    #[inline(always)]
    pub(super) fn clamp(&self, src: &[f32], dst: &mut [f32]) {
        let (lo, hi) = self.bounds;
        for (d, s) in dst.iter_mut().zip(src) {
            *d = s.max(lo).min(hi);
        }
    }

    /// The horizontal 3-sums of the gradient products of a row of green
    /// `g` (with the rows above and below), over its columns `s + 1 ..
    /// len - s - 1`: the gradients (central differences, scaled to [0, 1]
    /// data) over `s .. len - s` go through `grad`.
    #[inline(always)]
    pub(super) fn tensor_row(
        &self,
        [up, g, down]: [&[f32]; 3],
        s: usize,
        [gx, gy]: &mut [Vec<f32>; 2],
        [hxx, hxy, hyy]: [&mut [f32]; 3],
    ) {
        let k = 0.5 * self.inv_scale;
        let n = g.len() - 2 * s;
        let (e, w) = (&g[s + 1..s + 1 + n], &g[s - 1..s - 1 + n]);
        for ((d, e), w) in gx[s..s + n].iter_mut().zip(e).zip(w) {
            *d = (e - w) * k;
        }
        for ((d, n), so) in gy[s..s + n]
            .iter_mut()
            .zip(&up[s..s + n])
            .zip(&down[s..s + n])
        {
            *d = (so - n) * k;
        }
        let n = n - 2;
        let [x0, x1, x2] = [0, 1, 2].map(|dx| &gx[s + dx..s + dx + n]);
        let [y0, y1, y2] = [0, 1, 2].map(|dx| &gy[s + dx..s + dx + n]);
        let r = s + 1..s + 1 + n;
        for (i, ((xx, xy), yy)) in hxx[r.clone()]
            .iter_mut()
            .zip(&mut hxy[r.clone()])
            .zip(&mut hyy[r])
            .enumerate()
        {
            *xx = (x0[i] * x0[i] + x1[i] * x1[i]) + x2[i] * x2[i];
            *xy = (x0[i] * y0[i] + x1[i] * y1[i]) + x2[i] * y2[i];
            *yy = (y0[i] * y0[i] + y1[i] * y1[i]) + y2[i] * y2[i];
        }
    }

    /// The class of every column `halo .. len - halo` of a row of `kind`:
    /// `hash` of its CFA position and the 3x3 sums of the structure tensor
    /// (the rows above, at and below of the horizontal sums of
    /// [`Filters::tensor_row`], added).
    #[inline(always)]
    pub(super) fn classes_row(
        &self,
        kind: RowKind,
        cols: Range<usize>,
        sums: [[&[f32]; 3]; 3],
        class: &mut [u32],
        hash: impl Fn(usize, f32, f32, f32) -> u32,
    ) {
        let blue = usize::from(kind.blue);
        let start = cols.start;
        let [xx, xy, yy] = sums.map(|rows| rows.map(|r| &r[cols.clone()]));
        for (i, c) in class[cols.clone()].iter_mut().enumerate() {
            let add3 = |p: &[&[f32]; 3]| (p[0][i] + p[1][i]) + p[2][i];
            let chroma = usize::from((start + i) & 1 == kind.chroma_parity);
            *c = hash(2 * blue + chroma, add3(&xx), add3(&xy), add3(&yy));
        }
    }
}

/// Where corrections are written: the column, and the [`bound`] of their
/// moves ([`Filters::chroma_bound`]).
pub(super) type At = (usize, Option<f32>);

/// The corrections `d` of a pixel at a chroma site (`at_chroma`: green's,
/// then the other chroma's) or a green site (the own chroma's, then the
/// other's), bounded by `limit` ([`Filters::chroma_bound`]): each missing
/// colour's difference from green moves at most `limit` from the base's.
/// At a chroma site the other chroma's difference moves by `d.1 - d.0`.
/// Applied as the corrections are written, in registers, where a pass of
/// its own over the output rows cost "best" 1-2 % of its time.
#[inline(always)]
pub(super) fn bound(limit: Option<f32>, at_chroma: bool, (d0, d1): (f32, f32)) -> (f32, f32) {
    let Some(limit) = limit else {
        return (d0, d1);
    };
    let clamp = |v: f32| v.max(-limit).min(limit);
    if at_chroma {
        (d0, d0 + clamp(d1 - d0))
    } else {
        (clamp(d0), clamp(d1))
    }
}

impl Filters<Weights> {
    /// [`Filters::classes_row`] by the full hash, [`Weights::class`].
    #[inline(always)]
    pub(super) fn hash_row(
        &self,
        kind: RowKind,
        halo: usize,
        sums: [[&[f32]; 3]; 3],
        class: &mut [u32],
    ) {
        let weights = self.bank;
        let end = class.len() - halo;
        #[allow(unused_mut)]
        let mut x = halo;
        #[cfg(target_arch = "x86_64")]
        if self.isa != Isa::Baseline {
            // SAFETY: `Isa::Avx2` and `Isa::Avx512` are only made on CPUs
            // with AVX2.
            x = unsafe { hash_avx2(weights, kind, sums, class, halo..end) };
        }
        self.classes_row(kind, x..end, sums, class, |position, xx, xy, yy| {
            weights.class(position, xx, xy, yy) as u32
        });
    }

    /// Writes the columns `halo .. len - halo` of a row of `kind` to `dst`:
    /// the windows' middle row (the base's row) with the corrections of
    /// the filters (of the class of each column) added to its missing
    /// colours, the first to green at a chroma site, to the own chroma at
    /// a green site. `rows` are the windows' rows, three per base (above,
    /// at and below), each holding its planes [`PITCH`] apart.
    #[inline(always)]
    pub(super) fn correct_row<const N: usize>(
        &self,
        kind: RowKind,
        halo: usize,
        class: &[u32],
        [own, green, other]: [&mut [f32]; 3],
        rows: &[&[f32]],
    ) {
        let end = class.len() - halo;
        let mut x = halo;
        debug_assert_eq!(3 * rows.len(), N);
        let src = plane_row(rows[1], class.len());
        #[cfg(target_arch = "x86_64")]
        if self.isa != Isa::Baseline {
            let dst = [&mut *own, &mut *green, &mut *other];
            // SAFETY: `Isa::Avx2` and `Isa::Avx512` are only made on CPUs
            // with AVX2.
            let cols = (halo..end, self.chroma_bound);
            x = unsafe { add_avx2::<N>(self.bank, kind, class, src, dst, rows, cols) };
        }
        for (x, &c) in class[..end].iter().enumerate().skip(x) {
            let taps = self.bank.filter::<N>(c);
            // A branch per pixel that always goes the same way: calling
            // `apply_avx2` directly here lets it inline into the AVX2 tile
            // loop, which a closure chosen per row prevented.
            let d = match self.isa {
                Isa::Baseline => apply(taps, rows, x),
                // SAFETY: as above.
                #[cfg(target_arch = "x86_64")]
                Isa::Avx2 | Isa::Avx512 => unsafe { apply_avx2(taps, rows, x) },
            };
            let dst = [&mut *own, &mut *green, &mut *other];
            add1(kind, src, dst, (x, self.chroma_bound), d);
        }
    }
}

/// Writes column `x` of a row of `kind`: `src`'s colours (own chroma,
/// green, other chroma) with the two corrections `(d0, d1)` added,
/// [`bound`] by `limit`: the first to green at a chroma site and to the own
/// chroma at a green site, the second to the other chroma. Read from the
/// base's row rather than added in place, which saved copying each row
/// first.
#[inline(always)]
pub(super) fn add1(
    kind: RowKind,
    src: [&[f32]; 3],
    [own, green, other]: [&mut [f32]; 3],
    (x, limit): At,
    d: (f32, f32),
) {
    let [o, g, t] = src.map(|r| r[x]);
    let at_chroma = x & 1 == kind.chroma_parity;
    let d = bound(limit, at_chroma, d);
    (own[x], green[x]) = if at_chroma {
        (o, g + d.0)
    } else {
        (o + d.0, g)
    };
    other[x] = t + d.1;
}

/// [`add1`] for the eight columns from `x`, the corrections as vectors: the
/// first goes to green or the own chroma by a blend on the columns' parity.
/// Always inlined into its callers, which have the instructions: as a
/// function of its own (a `target_feature` one may only be an inlining
/// hint) it was called per eight pixels with its vectors passed through
/// memory (a twentieth of `"best"`'s samples on AVX2; inlined, "best" is
/// 1-3 % faster there).
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) unsafe fn add8_avx2(
    kind: RowKind,
    [so, sg, st]: [&[f32]; 3],
    [own, green, other]: [&mut [f32]; 3],
    (x, limit): At,
    [d0, d1]: [std::arch::x86_64::__m256; 2],
) {
    use std::arch::x86_64::*;
    // Lanes of chroma sites: every other one, from the first when column
    // `x` is one (lane 0 is the low half of each 64-bit pair).
    let lanes: i64 = if x & 1 == kind.chroma_parity {
        0xffff_ffff
    } else {
        -1 << 32
    };
    let chroma = _mm256_castsi256_ps(_mm256_set1_epi64x(lanes));
    let (d0, d1) = match limit {
        // `bound`, lane by lane.
        Some(limit) => {
            let (lo, hi) = (_mm256_set1_ps(-limit), _mm256_set1_ps(limit));
            let clamp = |v: __m256| _mm256_min_ps(_mm256_max_ps(v, lo), hi);
            let moved = clamp(_mm256_blendv_ps(d1, _mm256_sub_ps(d1, d0), chroma));
            (
                _mm256_blendv_ps(clamp(d0), d0, chroma),
                _mm256_blendv_ps(moved, _mm256_add_ps(d0, moved), chroma),
            )
        }
        None => (d0, d1),
    };
    let (o, g, t) = (
        &mut own[x..x + 8],
        &mut green[x..x + 8],
        &mut other[x..x + 8],
    );
    let (so, sg, st) = (&so[x..x + 8], &sg[x..x + 8], &st[x..x + 8]);
    // SAFETY: each slice holds the 8 floats loaded or stored (unaligned).
    unsafe {
        let (vo, vg, vt) = (
            _mm256_loadu_ps(so.as_ptr()),
            _mm256_loadu_ps(sg.as_ptr()),
            _mm256_loadu_ps(st.as_ptr()),
        );
        let vg = _mm256_blendv_ps(vg, _mm256_add_ps(vg, d0), chroma);
        let vo = _mm256_blendv_ps(_mm256_add_ps(vo, d0), vo, chroma);
        _mm256_storeu_ps(o.as_mut_ptr(), vo);
        _mm256_storeu_ps(g.as_mut_ptr(), vg);
        _mm256_storeu_ps(t.as_mut_ptr(), _mm256_add_ps(vt, d1));
    }
}

/// [`Filters::correct_row`] over `cols`, eight pixels at a time, as far as
/// whole eights go; returns the first column left. The first correction
/// goes to green or the own chroma by a blend on the columns' parity, so
/// each colour gets the same sums as pixel by pixel. One call per row (not
/// per eight pixels, which spent ~7 instructions a pixel setting up the
/// rows) whether or not the compiler inlines it.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn add_avx2<const N: usize>(
    weights: &Weights,
    kind: RowKind,
    class: &[u32],
    src: [&[f32]; 3],
    [own, green, other]: [&mut [f32]; 3],
    rows: &[&[f32]],
    (cols, limit): (Range<usize>, Option<f32>),
) -> usize {
    let mut x = cols.start;
    while x + 8 <= cols.end {
        let d = apply8_avx2::<N>(weights, class, rows, x);
        let dst = [&mut *own, &mut *green, &mut *other];
        // SAFETY: AVX2 is enabled here.
        unsafe { add8_avx2(kind, src, dst, (x, limit), d) };
        x += 8;
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_weights_parse() {
        // The fusion's classes are split by saturation, RAISR's are not.
        for (w, windows, saturations) in [
            (Weights::raisr(), WINDOWS, 1),
            (Weights::fusion(), 2 * WINDOWS, 2),
        ] {
            assert_eq!(w.taps.len(), saturations * HASHED * windows);
            assert_eq!(w.saturation.is_some(), saturations == 2);
            assert!(w.taps.iter().flatten().all(|v| v.is_finite()));
        }
    }

    #[test]
    fn malformed_weights_are_refused() {
        let bytes = include_bytes!("raisr_weights.bin");
        assert!(Weights::parse(&bytes[..bytes.len() - 4]).is_none());
        assert!(Weights::parse(&bytes[1..]).is_none());
        // A feature count of neither layout.
        let mut odd = bytes.to_vec();
        odd[24] = 27;
        assert!(Weights::parse(&odd).is_none());
        // No saturation bin, or three.
        for saturations in [0, 3] {
            let mut odd = bytes.to_vec();
            odd[20] = saturations;
            assert!(Weights::parse(&odd).is_none());
        }
        // The previous layout's magic.
        let mut old = bytes.to_vec();
        old[7] = b'1';
        assert!(Weights::parse(&old).is_none());
    }

    /// The vector hash gives every column the scalar class, at the bins'
    /// edges too: sums exactly on a strength or coherence threshold, flat
    /// and isotropic tensors, and gradients on the octants' borders.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_vector_hash_gives_the_scalar_classes() {
        if !crate::cpu::has_avx2() {
            return;
        }
        let w = Weights::raisr();
        let mut seed = 11u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32
        };
        let n = 203;
        let mut rows: [[Vec<f32>; 3]; 3] =
            std::array::from_fn(|_| std::array::from_fn(|_| vec![0.0; n]));
        for x in 0..n {
            let scale = 10f32.powi((x % 7) as i32 - 6);
            let (xx, xy, yy) = match x % 5 {
                // Exactly on a threshold: the other two rows stay zero.
                0 => (w.strength[x % 2], 0.0, 0.0),
                1 => (0.0, 0.0, 0.0),
                2 => (scale, if x % 2 == 0 { scale } else { -scale }, scale),
                _ => (next() * scale, (next() - 0.5) * scale, next() * scale),
            };
            for (p, v) in rows.iter_mut().zip([xx, xy, yy]) {
                if x % 5 < 3 {
                    p[0][x] = v;
                } else {
                    p.iter_mut().for_each(|r| r[x] = v * next());
                }
            }
        }
        let sums = rows.each_ref().map(|p| p.each_ref().map(|r| &r[..]));
        for blue in [false, true] {
            for chroma_parity in [0, 1] {
                let kind = RowKind {
                    blue,
                    chroma_parity,
                };
                let mut scalar = vec![0u32; n];
                let mut vector = vec![0u32; n];
                let f = Filters {
                    phase: Phase { ry: 0, rx: 0 },
                    inv_scale: 1.0,
                    bounds: (0.0, 1.0),
                    bank: w,
                    isa: Isa::Baseline,
                    chroma_bound: None,
                    saturated: None,
                };
                f.hash_row(kind, 3, sums, &mut scalar);
                // SAFETY: the CPU has AVX2.
                let end = unsafe { hash_avx2(w, kind, sums, &mut vector, 3..n - 3) };
                assert!(end > n - 3 - 8);
                f.classes_row(kind, end..n - 3, sums, &mut vector, |p, a, b, c| {
                    w.class(p, a, b, c) as u32
                });
                assert_eq!(
                    scalar, vector,
                    "blue row {blue}, chroma parity {chroma_parity}"
                );
            }
        }
    }

    /// The taps give the filter's value on the features (module docs) of
    /// a window, up to rounding: those of one base, and of two.
    #[test]
    fn taps_are_the_filter_on_the_features() {
        let mut seed = 7u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32
        };
        const ALL: usize = FEATURES + SECOND_FEATURES;
        let filter: Vec<f32> = (0..2 * ALL).map(|_| next() - 0.5).collect();
        // Planes of 3 rows x 4 columns, the first base's then the
        // differences'; the centre is row 1, column 1.
        let planes: Vec<Vec<f32>> = (0..6).map(|_| (0..12).map(|_| next()).collect()).collect();
        let colour = |base: usize, j: usize, dy: isize, dx: isize| {
            planes[3 * base + plane_of(j, dy)][4 * (1 + dy) as usize + (1 + dx) as usize]
        };
        let mut f = [0.0f32; ALL];
        for (k, &(dy, dx)) in NEIGHBOURS.iter().enumerate() {
            for j in 0..3 {
                f[3 * k + j] = colour(0, j, dy, dx) - colour(0, j, 0, 0);
            }
        }
        f[24] = colour(0, 0, 0, 0) - colour(0, 1, 0, 0);
        f[25] = colour(0, 2, 0, 0) - colour(0, 1, 0, 0);
        for m in 0..9 {
            for j in 0..3 {
                f[FEATURES + 3 * m + j] = colour(1, j, m as isize / 3 - 1, m as isize % 3 - 1);
            }
        }
        // The windows' rows: plane `p` of row `r` of base `b` at `p * PITCH`.
        let rows: Vec<Vec<f32>> = (0..6)
            .map(|row| {
                let mut r = vec![0.0; 3 * PITCH];
                for p in 0..3 {
                    let plane = &planes[row / 3 * 3 + p][4 * (row % 3)..][..4];
                    r[p * PITCH..p * PITCH + 4].copy_from_slice(plane);
                }
                r
            })
            .collect();
        let rows: Vec<&[f32]> = rows.iter().map(|r| &r[..]).collect();
        let dot = |w: &[f32], n: usize| w[..n].iter().zip(&f).map(|(a, b)| a * b).sum::<f32>();
        let (w0, w1) = filter.split_at(ALL);
        // One base: the first 26 features of each half.
        let one = taps((&w0[..FEATURES], &w1[..FEATURES]), WINDOWS);
        let (d0, d1) = apply::<WINDOWS>(one[..].try_into().unwrap(), &rows[..3], 1);
        assert!((d0 - dot(w0, FEATURES)).abs() < 1e-5, "{d0}");
        assert!((d1 - dot(w1, FEATURES)).abs() < 1e-5, "{d1}");
        let two = taps((w0, w1), 2 * WINDOWS);
        let (d0, d1) = apply::<{ 2 * WINDOWS }>(two[..].try_into().unwrap(), &rows, 1);
        assert!((d0 - dot(w0, ALL)).abs() < 1e-5, "{d0}");
        assert!((d1 - dot(w1, ALL)).abs() < 1e-5, "{d1}");
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_avx2_filters_give_the_scalar_bits() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        // Six rows of three planes, 16 columns each, `PITCH` apart.
        let rows: Vec<Vec<f32>> = (0..MAX_ROWS)
            .map(|row| {
                (0..3 * PITCH)
                    .map(|i| ((i % PITCH * 37 + (3 * row + i / PITCH) * 11) % 29) as f32 * 0.37)
                    .collect()
            })
            .collect();
        fn check<const N: usize>(w: &Weights, rows: &[Vec<f32>]) {
            let rows: Vec<&[f32]> = rows[..N / 3].iter().map(|r| &r[..]).collect();
            for c in 0..(w.taps.len() / N) as u32 {
                let (taps, x) = (w.filter::<N>(c), 1 + c as usize % 12);
                // SAFETY: AVX2 was detected by the caller.
                let fast = unsafe { apply_avx2(taps, &rows, x) };
                let slow = apply(taps, &rows, x);
                assert_eq!(fast.0.to_bits(), slow.0.to_bits());
                assert_eq!(fast.1.to_bits(), slow.1.to_bits());
            }
        }
        check::<WINDOWS>(Weights::raisr(), &rows);
        check::<{ 2 * WINDOWS }>(Weights::fusion(), &rows);
    }

    #[test]
    fn angle_bins_follow_the_doubled_orientation() {
        // Doubled angle 0 (horizontal gradient), 90 (diagonal), 180
        // (vertical), 270 (anti-diagonal) degrees.
        assert_eq!(angle_bin(1.0, 0.0), 0);
        assert_eq!(angle_bin(0.0, 1.0), 2);
        assert_eq!(angle_bin(-1.0, 0.0), 4);
        assert_eq!(angle_bin(0.0, -1.0), 6);
        assert_eq!(angle_bin(1.0, 1.0), 1);
        assert_eq!(angle_bin(1.0, -1.0), 7);
    }

    #[test]
    fn a_flat_tensor_has_no_strength_nor_coherence() {
        assert_eq!(eigen(0.0, 0.0, 0.0), (0.0, 0.0));
        let (l1, c) = eigen(4.0, 0.0, 0.0);
        assert_eq!((l1, c), (4.0, 1.0));
    }

    #[test]
    fn bounded_corrections_move_missing_differences_by_at_most_the_limit() {
        let (n, limit) = (40, 0.1f32);
        let wave = |k: usize, s: f32| (0..n).map(move |x| ((x * k) as f32 * s).sin() * 0.4 + 0.5);
        let src: [Vec<f32>; 3] = [
            wave(3, 0.7).collect(),
            wave(5, 0.3).collect(),
            wave(7, 0.9).collect(),
        ];
        // Corrections up to 0.5, the first to green at a chroma site (even
        // columns here) and to the own chroma at a green site, the second
        // to the other chroma: unbounded (`filtered`) and bounded (`dst`).
        let d: Vec<(f32, f32)> = (0..n)
            .map(|x| ((x as f32 * 1.3).sin() * 0.5, (x as f32 * 0.8).cos() * 0.5))
            .collect();
        let kind = RowKind {
            blue: false,
            chroma_parity: 0,
        };
        let [mut filtered, mut dst] = [src.clone(), src.clone()];
        for (x, &dx) in d.iter().enumerate().take(n - 2).skip(2) {
            let planes = src.each_ref().map(|r| &r[..]);
            for (out, bound) in [(&mut filtered, None), (&mut dst, Some(limit))] {
                add1(
                    kind,
                    planes,
                    out.each_mut().map(|r| &mut r[..]),
                    (x, bound),
                    dx,
                );
            }
        }
        let eps = 1e-6;
        for x in 0..n {
            let [so, sg, st] = src.each_ref().map(|r| r[x]);
            let [o, g, t] = dst.each_ref().map(|r| r[x]);
            if !(2..n - 2).contains(&x) {
                assert_eq!([o, g, t], filtered.each_ref().map(|r| r[x]));
                continue;
            }
            // Green is the filters' everywhere, the own chroma of a chroma
            // site the base's.
            assert_eq!(g, filtered[1][x]);
            let moved = |v: f32, base: f32| (v - base).abs();
            if x % 2 == 0 {
                assert_eq!(o, so);
                let step = moved(t - g, st - sg);
                assert!(step <= limit + eps, "{x}: {step}");
                let wanted = moved(filtered[2][x] - g, st - sg);
                assert!((step - wanted.min(limit)).abs() <= eps, "{x}");
            } else {
                for (v, base, wanted) in [(o, so, d[x].0), (t, st, d[x].1)] {
                    assert!(
                        (moved(v, base) - wanted.abs().min(limit)).abs() <= eps,
                        "{x}"
                    );
                }
            }
        }
    }
}

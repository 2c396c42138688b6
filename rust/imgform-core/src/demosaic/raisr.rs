//! A learned refinement of our best classical demosaicer, in the manner of
//! RAISR: Romano, Isidoro and Milanfar, "RAISR: Rapid and Accurate Image
//! Super Resolution", IEEE Transactions on Computational Imaging 3(1), 2017.
//!
//! RAISR learns, per class of local structure, a least-squares linear filter
//! from a cheap upscaler's output to the truth. Here the cheap estimate is
//! the RCD / Menon 2007 mean and the filters predict its residual: at every
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
//! The filters are trained by `python -m imgform_rs.training.demosaic` on
//! openly licensed images that are not the benchmark's (see the docs) and
//! shipped in `raisr_weights.bin`, whose layout [`Weights::parse`] reads.

use super::tiled::{Tile, TileKernel};
use super::{Isa, Phase};
use std::sync::OnceLock;

/// Features per pixel: 8 neighbours x 3 colours, plus 2 centre differences.
pub(crate) const FEATURES: usize = 26;
/// Angle bins of the structure tensor's orientation (fixed by [`angle_bin`]).
const ANGLES: usize = 8;
/// Strength and coherence bins: fixed, so the thresholds are arrays and the
/// hash of a row compiles to straight-line vector code.
const STRENGTHS: usize = 3;
const COHERENCES: usize = 3;
/// CFA positions: (blue row, chroma site) pairs.
const POSITIONS: usize = 4;
/// Header magic of the weights file.
const MAGIC: &[u8; 8] = b"IGRAISR1";

/// One trained filter: the corrections of the pixel's two missing colours
/// as functions of the features.
type Filter = [[f32; FEATURES]; 2];

/// A filter rewritten as taps on the tile's planes: window `3 * r + p` is
/// plane `p` (own chroma, green, other chroma of *that* row) on row
/// `y + r - 1`, columns `x - 1 ..= x + 2`; lanes 0..4 give the first missing
/// colour, lanes 4..8 the second. The fourth column's tap is zero: it only
/// makes a window one 4-wide load, which both halves of an 8-wide multiply
/// share.
type Taps = [[f32; 8]; 9];

/// The trained filter bank, as taps, and its hashing thresholds.
pub(crate) struct Weights {
    /// Upper bounds of the strength bins but the last, on the largest
    /// eigenvalue of the structure tensor of full-scale-normalised green.
    strength: [f32; STRENGTHS - 1],
    /// Upper bounds of the coherence bins but the last.
    coherence: [f32; COHERENCES - 1],
    taps: Vec<Taps>,
}

impl Weights {
    /// Reads the little-endian layout: the 8-byte magic `IGRAISR1`; `u32`
    /// counts of angle, strength and coherence bins and of features; the
    /// strength then coherence thresholds (`f32`, one fewer than bins); the
    /// filters (`f32`), indexed `[position][angle][strength][coherence]
    /// [missing colour][feature]`, position being `2 * blue_row + chroma_site`.
    ///
    /// Returns `None` for a malformed file.
    pub(crate) fn parse(bytes: &[u8]) -> Option<Weights> {
        let body = bytes.strip_prefix(MAGIC)?;
        let mut words = body.chunks_exact(4).map(|w| [w[0], w[1], w[2], w[3]]);
        let mut count = || words.next().map(|w| u32::from_le_bytes(w) as usize);
        let counts = [count()?, count()?, count()?, count()?];
        if counts != [ANGLES, STRENGTHS, COHERENCES, FEATURES] {
            return None;
        }
        let rest: Vec<f32> = words.map(f32::from_le_bytes).collect();
        let nfilters = POSITIONS * ANGLES * STRENGTHS * COHERENCES;
        let thresholds = STRENGTHS - 1 + COHERENCES - 1;
        if body.len() % 4 != 0 || rest.len() != thresholds + nfilters * 2 * FEATURES {
            return None;
        }
        let (strength, rest) = rest.split_at(STRENGTHS - 1);
        let (coherence, rest) = rest.split_at(COHERENCES - 1);
        let taps = rest
            .chunks_exact(2 * FEATURES)
            .map(|f| {
                let mut filter = [[0.0; FEATURES]; 2];
                filter[0].copy_from_slice(&f[..FEATURES]);
                filter[1].copy_from_slice(&f[FEATURES..]);
                taps(&filter)
            })
            .collect();
        Some(Weights {
            strength: strength.try_into().ok()?,
            coherence: coherence.try_into().ok()?,
            taps,
        })
    }

    /// The shipped filter bank, parsed on first use.
    pub(crate) fn shipped() -> &'static Weights {
        static WEIGHTS: OnceLock<Weights> = OnceLock::new();
        WEIGHTS.get_or_init(|| {
            // The file is part of the crate and checked by a unit test, so
            // a parse failure is a build defect, not bad input.
            Weights::parse(include_bytes!("raisr_weights.bin"))
                .expect("raisr_weights.bin is malformed")
        })
    }

    /// The class (index into `taps`) of a CFA position and structure-tensor
    /// sums. Branch-free, so a row of them vectorises.
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

/// Rewrites a filter on the difference features as taps on the planes:
/// feature `f[3k + j] = C_j(n_k) - C_j(centre)` puts `w` on the neighbour
/// and `-w` on the centre, `f[24] = own - green`, `f[25] = other - green`.
/// The sums are the same linear map, evaluated with fewer operations.
fn taps(filter: &Filter) -> Taps {
    let mut t = [[0.0f32; 8]; 9];
    for (half, w) in filter.iter().enumerate() {
        let mut add = |dy: isize, dx: isize, j: usize, v: f32| {
            let window = 3 * (1 + dy) as usize + plane_of(j, dy);
            t[window][4 * half + (1 + dx) as usize] += v;
        };
        for (k, &(dy, dx)) in NEIGHBOURS.iter().enumerate() {
            for j in 0..3 {
                add(dy, dx, j, w[3 * k + j]);
                add(0, 0, j, -w[3 * k + j]);
            }
        }
        add(0, 0, 0, w[24]);
        add(0, 0, 2, w[25]);
        add(0, 0, 1, -(w[24] + w[25]));
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

/// The octant of the doubled orientation angle `atan2(b, a)` of the tensor
/// (`a = sxx - syy`, `b = 2 sxy`), rotated by 22.5 degrees so that bins
/// are centred on horizontal, diagonal and vertical gradients. Comparisons
/// instead of `atan2`, so the training script reproduces it exactly; the
/// quadrant comes from the signs, the octant within it from one comparison.
#[inline(always)]
fn angle_bin(a: f32, b: f32) -> usize {
    const COS: f32 = 0.923_879_5;
    const SIN: f32 = 0.382_683_43;
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

/// The base kernel refined by the filter bank.
pub(super) struct Raisr<B> {
    pub(super) base: B,
    pub(super) phase: Phase,
    /// `1 / FULL_SCALE` of the sample type, so the hash sees [0, 1] data.
    pub(super) inv_scale: f32,
    /// The mosaic's smallest and largest sample: the base is clamped to
    /// them before the features are taken, as the training script sees it.
    pub(super) bounds: (f32, f32),
    pub(super) weights: &'static Weights,
    /// Whether the filters run in AVX ([`apply_avx2`]) or scalar code.
    pub(super) isa: Isa,
}

pub(super) struct State<S> {
    base: S,
    gx: Vec<f32>,
    gy: Vec<f32>,
    /// Horizontal 3-sums of the gradient products; the 3x3 sums of the
    /// structure tensor add three of them vertically.
    hxx: Vec<f32>,
    hxy: Vec<f32>,
    hyy: Vec<f32>,
    /// The class of each column of the current row.
    class: Vec<u32>,
    clamped: [Vec<f32>; 3],
    out: [Vec<f32>; 3],
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
/// window row (three short dependency chains instead of one of nine
/// additions), each a product then a sum (no fused multiply-add), then the
/// pairwise sum of each half: the order [`apply_avx2`] computes in, so both
/// give the same bits.
#[inline(always)]
fn apply(taps: &Taps, rows: &[&[f32]; 9], x: usize) -> (f32, f32) {
    let mut acc = [[0.0f32; 8]; 3];
    for (k, (t, row)) in taps.iter().zip(rows).enumerate() {
        let v = &row[x - 1..x + 3];
        for (l, a) in acc[k / 3].iter_mut().enumerate() {
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
fn apply_avx2(taps: &Taps, rows: &[&[f32]; 9], x: usize) -> (f32, f32) {
    use std::arch::x86_64::*;
    let mut acc = [_mm256_setzero_ps(); 3];
    for (k, (t, row)) in taps.iter().zip(rows).enumerate() {
        let v = &row[x - 1..x + 3];
        // SAFETY: `v` and `t` hold 4 and 8 floats (slice and array
        // lengths); the loads are unaligned ones.
        let (v, t) = unsafe { (_mm_loadu_ps(v.as_ptr()), _mm256_loadu_ps(t.as_ptr())) };
        acc[k / 3] = _mm256_add_ps(acc[k / 3], _mm256_mul_ps(t, _mm256_set_m128(v, v)));
    }
    let acc = _mm256_add_ps(_mm256_add_ps(acc[0], acc[1]), acc[2]);
    let h = _mm_hadd_ps(_mm256_castps256_ps128(acc), _mm256_extractf128_ps::<1>(acc));
    let h = _mm_hadd_ps(h, h);
    (_mm_cvtss_f32(h), _mm_cvtss_f32(_mm_movehdup_ps(h)))
}

impl<B: TileKernel> TileKernel for Raisr<B> {
    type State = State<B::State>;
    /// The base's halo plus the 2 pixels the hash reaches (1 for the 3x3
    /// sums, 1 for the central differences).
    const HALO: usize = B::HALO + 2;

    fn state(&self, stride: usize, len: usize) -> Self::State {
        let plane = || vec![0.0f32; len];
        State {
            base: self.base.state(stride, len),
            gx: plane(),
            gy: plane(),
            hxx: plane(),
            hxy: plane(),
            hyy: plane(),
            class: vec![0; stride],
            clamped: [plane(), plane(), plane()],
            out: [plane(), plane(), plane()],
        }
    }

    /// Inlined, as every kernel is, into the tile loop compiled for AVX2:
    /// a call boundary here ran the base and the filters in baseline SSE2.
    #[inline(always)]
    fn run<'s>(&self, st: &'s mut Self::State, t: &Tile, raw: &[f32]) -> [&'s [f32]; 3] {
        let State {
            base,
            gx,
            gy,
            hxx,
            hxy,
            hyy,
            class,
            clamped,
            out,
        } = st;
        let (lo, hi) = self.bounds;
        let len = t.stride * t.rows;
        for (c, p) in clamped.iter_mut().zip(self.base.run(base, t, raw)) {
            for (c, p) in c[..len].iter_mut().zip(&p[..len]) {
                *c = p.max(lo).min(hi);
            }
        }
        let planes = [&clamped[0][..], &clamped[1][..], &clamped[2][..]];
        let halo = Self::HALO;
        self.tensor(t, planes[1], [gx, gy], [hxx, hxy, hyy]);
        for ty in halo..t.rows - halo {
            self.classes(t, ty, [&**hxx, &**hxy, &**hyy], class);
            self.refine_row(t, ty, planes, class, out);
        }
        let [own, green, other] = out;
        [own, green, other]
    }
}

impl<B: TileKernel> Raisr<B> {
    /// Gradients of green (central differences, scaled to [0, 1] data) over
    /// the output plus one pixel, and the horizontal 3-sums of their
    /// products over the output columns (rows plus one).
    #[inline(always)]
    fn tensor(&self, t: &Tile, g: &[f32], grad: [&mut Vec<f32>; 2], sums: [&mut Vec<f32>; 3]) {
        let s = Self::HALO - 1;
        let k = 0.5 * self.inv_scale;
        let [gx, gy] = grad;
        let [hxx, hxy, hyy] = sums;
        for ty in s..t.rows - s {
            let sp = t.span(ty, s);
            let (e, w, n, so) = (
                sp.at(g, 0, 1),
                sp.at(g, 0, -1),
                sp.at(g, -1, 0),
                sp.at(g, 1, 0),
            );
            for ((d, e), w) in sp.out(gx).iter_mut().zip(e).zip(w) {
                *d = (e - w) * k;
            }
            for ((d, n), so) in sp.out(gy).iter_mut().zip(n).zip(so) {
                *d = (so - n) * k;
            }
            let sp = t.span(ty, s + 1);
            let [x0, x1, x2] = [-1, 0, 1].map(|dx| sp.at(gx, 0, dx));
            let [y0, y1, y2] = [-1, 0, 1].map(|dx| sp.at(gy, 0, dx));
            let r = sp.range();
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
    }

    /// The class of every output column of row `ty`: the 3x3 sums of the
    /// structure tensor (three horizontal sums added vertically), hashed.
    #[inline(always)]
    fn classes(&self, t: &Tile, ty: usize, sums: [&[f32]; 3], class: &mut [u32]) {
        let halo = Self::HALO;
        let kind = t.kind(self.phase, ty);
        let blue = usize::from(kind.blue);
        let sp = t.span(ty, halo);
        let [xx, xy, yy] = sums.map(|h| [-1, 0, 1].map(|dy| sp.at(h, dy, 0)));
        for (i, c) in class[halo..t.stride - halo].iter_mut().enumerate() {
            let add3 = |p: &[&[f32]; 3]| (p[0][i] + p[1][i]) + p[2][i];
            let chroma = usize::from((halo + i) & 1 == kind.chroma_parity);
            *c = self
                .weights
                .class(2 * blue + chroma, add3(&xx), add3(&xy), add3(&yy)) as u32;
        }
    }

    /// Copies the base's row `ty` and adds the filters' corrections.
    #[inline(always)]
    fn refine_row(
        &self,
        t: &Tile,
        ty: usize,
        base: [&[f32]; 3],
        class: &[u32],
        out: &mut [Vec<f32>; 3],
    ) {
        let stride = t.stride;
        let row = |p: usize, r: usize| &base[p][r * stride..(r + 1) * stride];
        let rows: [&[f32]; 9] = std::array::from_fn(|k| row(k % 3, ty + k / 3 - 1));
        let r = ty * stride..(ty + 1) * stride;
        let [o_own, o_green, o_other] = out;
        let [own, green, other] = [
            &mut o_own[r.clone()],
            &mut o_green[r.clone()],
            &mut o_other[r],
        ];
        own.copy_from_slice(rows[3]);
        green.copy_from_slice(rows[4]);
        other.copy_from_slice(rows[5]);
        self.correct(t, ty, class, [own, green, other], &rows);
    }

    /// Adds the corrections of the filters (of the class of each column)
    /// to the missing colours of the output columns of row `ty`: the first
    /// is green at a chroma site, the own chroma at a green site.
    #[inline(always)]
    fn correct(
        &self,
        t: &Tile,
        ty: usize,
        class: &[u32],
        [own, green, other]: [&mut [f32]; 3],
        rows: &[&[f32]; 9],
    ) {
        let halo = Self::HALO;
        let chroma_parity = t.kind(self.phase, ty).chroma_parity;
        for x in halo..t.stride - halo {
            let taps = &self.weights.taps[class[x] as usize];
            // A branch per pixel that always goes the same way: calling
            // `apply_avx2` directly here lets it inline into the AVX2 tile
            // loop, which a closure chosen per row prevented.
            let (d0, d1) = match self.isa {
                Isa::Baseline => apply(taps, rows, x),
                // SAFETY: `Isa::Avx2` and `Isa::Avx512` are only made on CPUs
                // with AVX2.
                #[cfg(target_arch = "x86_64")]
                Isa::Avx2 | Isa::Avx512 => unsafe { apply_avx2(taps, rows, x) },
            };
            if x & 1 == chroma_parity {
                green[x] += d0;
            } else {
                own[x] += d0;
            }
            other[x] += d1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_weights_parse() {
        let w = Weights::shipped();
        assert_eq!(w.taps.len(), POSITIONS * ANGLES * STRENGTHS * COHERENCES);
        assert!(w.taps.iter().flatten().flatten().all(|v| v.is_finite()));
    }

    #[test]
    fn malformed_weights_are_refused() {
        let bytes = include_bytes!("raisr_weights.bin");
        assert!(Weights::parse(&bytes[..bytes.len() - 4]).is_none());
        assert!(Weights::parse(&bytes[1..]).is_none());
    }

    /// The taps give the filter's value on the difference features (module
    /// docs) of a window, up to rounding.
    #[test]
    fn taps_are_the_filter_on_the_features() {
        let mut seed = 7u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32
        };
        let filter: Filter = [(); 2].map(|_| [(); FEATURES].map(|_| next() - 0.5));
        // Planes of 3 rows x 4 columns; the centre is row 1, column 1.
        let planes: Vec<Vec<f32>> = (0..3).map(|_| (0..12).map(|_| next()).collect()).collect();
        let colour = |j: usize, dy: isize, dx: isize| {
            planes[plane_of(j, dy)][4 * (1 + dy) as usize + (1 + dx) as usize]
        };
        let mut f = [0.0f32; FEATURES];
        for (k, &(dy, dx)) in NEIGHBOURS.iter().enumerate() {
            for j in 0..3 {
                f[3 * k + j] = colour(j, dy, dx) - colour(j, 0, 0);
            }
        }
        f[24] = colour(0, 0, 0) - colour(1, 0, 0);
        f[25] = colour(2, 0, 0) - colour(1, 0, 0);
        let rows: [&[f32]; 9] = std::array::from_fn(|k| &planes[k % 3][4 * (k / 3)..][..4]);
        let (d0, d1) = apply(&taps(&filter), &rows, 1);
        let dot = |w: &[f32; FEATURES]| w.iter().zip(&f).map(|(a, b)| a * b).sum::<f32>();
        assert!((d0 - dot(&filter[0])).abs() < 1e-5, "{d0}");
        assert!((d1 - dot(&filter[1])).abs() < 1e-5, "{d1}");
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_avx2_filters_give_the_scalar_bits() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let w = Weights::shipped();
        let planes: Vec<Vec<f32>> = (0..9)
            .map(|k| {
                (0..16)
                    .map(|i| ((i * 37 + k * 11) % 29) as f32 * 0.37)
                    .collect()
            })
            .collect();
        let rows: [&[f32]; 9] = std::array::from_fn(|k| &planes[k][..]);
        for (c, taps) in w.taps.iter().enumerate() {
            let x = 1 + c % 12;
            // SAFETY: AVX2 was detected above.
            let fast = unsafe { apply_avx2(taps, &rows, x) };
            let slow = apply(taps, &rows, x);
            assert_eq!(fast.0.to_bits(), slow.0.to_bits());
            assert_eq!(fast.1.to_bits(), slow.1.to_bits());
        }
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
}

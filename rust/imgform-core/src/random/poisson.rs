//! Exact Poisson variates: inversion by sequential search for means below
//! 10, Hörmann's transformed rejection with squeeze (PTRS, 1993) above.
//! Neither switches to a Gaussian at any mean.
//!
//! A site's variate depends on its own generator alone, so rows can be
//! sampled in any order and by any number of threads. [`PoissonRow`]
//! samples a row of sites with the same draws as [`SplitMix64::poisson`]
//! at each site, but in vector steps: every site's first PTRS candidate
//! and squeeze (which accepts ~76 % of them) eight sites at a time, then
//! full rounds with the exact test for the undecided sites, sixteen at a
//! time, gathered from across the row, until every site has its variate.
//! PTRS's exact test needs `ln lam`, `ln k!` and an exponential; here they
//! are polynomials in IEEE operations only (no libm call, which no loop
//! vectorises), and the per-site model runs the same code with one lane,
//! so it gets the same bits.

use std::sync::OnceLock;

use super::vf::{Mask, Vf, TWO_52};
use super::{mix, unit, SplitMix64, LANES};

impl SplitMix64 {
    /// A Poisson variate of mean `lam` (0 for `lam <= 0` or NaN): one
    /// uniform inverted by search below [`SEARCH_BELOW`], PTRS's rounds of
    /// two uniforms each above.
    #[inline(always)]
    pub(crate) fn poisson(&mut self, lam: f64) -> f64 {
        if lam >= SEARCH_BELOW {
            return self.poisson_by_rejection(lam);
        }
        let u = self.uniform();
        search(Vf([lam]), Vf([u])).0[0]
    }

    /// PTRS's loop: a candidate from two uniforms per round until one is
    /// accepted (~90 % of rounds).
    fn poisson_by_rejection(&mut self, lam: f64) -> f64 {
        let ptrs = Ptrs::new(Vf([lam]));
        loop {
            let (u, v) = (self.uniform(), self.uniform());
            let candidate = ptrs.candidate(Vf([u]), Vf([v]));
            if (candidate.squeezed | ptrs.exact(&candidate, Vf([v]))).0[0] {
                return candidate.k.0[0];
            }
        }
    }
}

/// The mean from which [`SplitMix64::poisson`] samples by PTRS (valid from
/// 10 on); below it the search takes ~`lam` steps, fewer than PTRS's work.
const SEARCH_BELOW: f64 = 10.0;

/// The search's largest count: beyond 100 the tail has probability < 1e-60
/// for a mean below 10 (and a `u` above the rounded total mass stops here).
const SEARCH_MAX: u32 = 100;

/// Poisson variates of means `lam` (< [`SEARCH_BELOW`]) by inverting the
/// distribution function at the uniforms `u`: the smallest `k` with
/// `u <= P(0) + .. + P(k)`, each `P(k) = P(k - 1) lam / k`. The elements
/// step together until none is still searching; one that has stopped keeps
/// its values, so each gets exactly what it would alone.
#[inline(always)]
fn search<const N: usize>(lam: Vf<N>, u: Vf<N>) -> Vf<N> {
    let mut p = exp(-lam);
    let mut cdf = p;
    let mut k = Vf::from(0.0);
    for j in 1..=SEARCH_MAX {
        let on = u.gt(cdf);
        if !on.any() {
            break;
        }
        // One division per step for all elements: `p lam (1 / j)`.
        let j = f64::from(j);
        let next = p * lam * (1.0 / j);
        k = on.select(Vf::from(j), k);
        p = on.select(next, p);
        cdf = on.select(cdf + next, cdf);
    }
    k
}

/// Hörmann's PTRS for means `lam` (>= 10): its hat's constants.
struct Ptrs<const N: usize> {
    lam: Vf<N>,
    a: Vf<N>,
    b: Vf<N>,
}

/// A PTRS candidate: the count `k`, the uniform's distance `us` from the
/// nearer end of [0, 1], `r = 1 / us`, and whether the squeeze accepts it.
struct Candidate<const N: usize> {
    k: Vf<N>,
    us: Vf<N>,
    r: Vf<N>,
    squeezed: Mask<N>,
}

impl<const N: usize> Ptrs<N> {
    #[inline(always)]
    fn new(lam: Vf<N>) -> Self {
        let b = lam.sqrt() * 2.53 + 0.931;
        Self {
            lam,
            a: b * 0.02483 - 0.059,
            b,
        }
    }

    /// The candidate of the uniforms `u01, v`, and the squeeze's verdict.
    #[inline(always)]
    fn candidate(&self, u01: Vf<N>, v: Vf<N>) -> Candidate<N> {
        let u = u01 - 0.5;
        let us = -u.abs() + 0.5;
        let r = us.recip();
        let k = ((self.a * 2.0 * r + self.b) * u + self.lam + 0.43).floor();
        // The squeeze `v <= 0.9277 - 3.6224 / (b - 2)` (b > 8 here),
        // multiplied out to spare a division.
        let squeezed = us.ge(0.07) & ((-v + 0.9277) * (self.b - 2.0)).ge(3.6224);
        Candidate { k, us, r, squeezed }
    }

    /// PTRS's exact test of a candidate the squeeze did not accept:
    /// `ln(v alpha^-1 / (a / us² + b)) <= ln P(k)`, taken as
    /// `v (1.1239 (b - 3.4) + 1.1328) <= (b - 3.4) (a / us² + b) P(k)`
    /// (both sides times `b - 3.4 > 0`; alpha^-1 = 1.1239 + 1.1328 / (b -
    /// 3.4)), `P(k) = exp(k ln lam - lam - ln k!)`. Branch-free: a
    /// candidate rejected early (below 0 or in the hat's far tail) may
    /// compute nonsense in the test, which its mask discards.
    #[inline(always)]
    fn exact(&self, c: &Candidate<N>, v: Vf<N>) -> Mask<N> {
        let early = c.k.lt(0.0) | (c.us.lt(0.013) & v.gt(c.us));
        let hat = self.b - 3.4;
        let pk = exp(c.k * ln(self.lam) - self.lam - ln_factorial_of_count(c.k));
        let test = (v * (hat * 1.1239 + 1.1328)).le(hat * (self.a * c.r * c.r + self.b) * pk);
        !early & test
    }
}

/// Samples rows of Poisson variates with the draws of
/// [`SplitMix64::poisson`] at every site; keeps the list of undecided
/// sites between rows, so that a band of rows allocates it once.
#[derive(Default)]
pub(crate) struct PoissonRow {
    /// The undecided sites, in `undecided[..len]` (the rest is room for a
    /// whole row, so that sites are appended without a branch).
    undecided: Vec<usize>,
    len: usize,
}

impl PoissonRow {
    /// `counts[x]`: a Poisson variate of mean `lam[x]` drawn by the
    /// generator whose state is `states[x]`, left in `states[x]` past the
    /// variate's draws (for the draws that follow it).
    ///
    /// `progress(done)` is called as the work advances, so that a caller
    /// can interleave work of its own (the sensor integrates its next row);
    /// `done` runs up to `2 * lam.len()`: the first round's sites count
    /// for the first half, the first exact round's (about as long, though
    /// only a quarter of the sites get there) for the second.
    #[inline(always)]
    pub(crate) fn fill(
        &mut self,
        lam: &[f64],
        counts: &mut [f64],
        states: &mut [u64],
        mut progress: impl FnMut(usize),
    ) {
        let n = lam.len();
        self.undecided.resize(n, 0);
        self.len = 0;
        let blocks = n / LANES * LANES;
        for x0 in (0..blocks).step_by(LANES) {
            self.first_round(x0, lam, counts, states);
            progress(x0 + LANES);
        }
        for x in blocks..n {
            let mut g = SplitMix64(states[x]);
            counts[x] = g.poisson(lam[x]);
            states[x] = g.0;
        }
        let first = self.len;
        self.exact_rounds(lam, counts, states, |tested| {
            progress(n + n * tested / first);
        });
        while self.len > 0 {
            self.exact_rounds(lam, counts, states, |_| {});
        }
    }

    /// Sites `x0 .. x0 + LANES`: the means below [`SEARCH_BELOW`] searched
    /// together on their first draw; the others' first PTRS candidates,
    /// kept where the squeeze accepts them. The rest are left undecided,
    /// their states before the round.
    #[inline(always)]
    fn first_round(&mut self, x0: usize, lam: &[f64], counts: &mut [f64], states: &mut [u64]) {
        let lam = Vf::<LANES>(lam[x0..x0 + LANES].try_into().unwrap());
        let states = &mut states[x0..x0 + LANES];
        let (u, v) = uniform_pair(&<[u64; LANES]>::try_from(&*states).unwrap());
        let by_rejection = lam.ge(SEARCH_BELOW);
        let mut k = Vf::from(0.0);
        if (!by_rejection).any() {
            // The other lanes search from a mean of 0: they stop at once.
            k = search(by_rejection.select(Vf::from(0.0), lam), u);
        }
        let mut decided = !by_rejection;
        if by_rejection.any() {
            let c = Ptrs::new(lam).candidate(u, v);
            k = by_rejection.select(c.k, k);
            decided = decided | c.squeezed;
        }
        counts[x0..x0 + LANES].copy_from_slice(&k.0);
        let mut draws = [0; LANES];
        for ((d, &decided), &rejection) in draws.iter_mut().zip(&decided.0).zip(&by_rejection.0) {
            *d = u64::from(decided) * (1 + u64::from(rejection));
        }
        for (s, d) in states.iter_mut().zip(draws) {
            *s = s.wrapping_add(SplitMix64::GOLDEN.wrapping_mul(d));
        }
        // Appended without a branch per site (a quarter are undecided, at
        // random): every site is written, only the undecided ones counted.
        for (i, &decided) in decided.0.iter().enumerate() {
            self.undecided[self.len] = x0 + i;
            self.len += usize::from(!decided);
        }
    }

    /// One full PTRS round for every undecided site, [`EXACT_LANES`] at a time
    /// (the last group padded with its own last site, whose duplicates
    /// compute the same values); the sites it rejects stay undecided.
    /// `progress(tested)` follows each group with the sites tested so far.
    #[inline(always)]
    fn exact_rounds(
        &mut self,
        lam: &[f64],
        counts: &mut [f64],
        states: &mut [u64],
        mut progress: impl FnMut(usize),
    ) {
        let mut kept = 0;
        for start in (0..self.len).step_by(EXACT_LANES) {
            let n = EXACT_LANES.min(self.len - start);
            let mut sites = [0; EXACT_LANES];
            let mut before = [0; EXACT_LANES];
            for (i, (site, state)) in sites.iter_mut().zip(&mut before).enumerate() {
                *site = self.undecided[start + i.min(n - 1)];
                *state = states[*site];
            }
            let (u, v) = uniform_pair(&before);
            let ptrs = Ptrs::new(Vf::from_each(&sites, |x| lam[x]));
            let c = ptrs.candidate(u, v);
            let accepted = c.squeezed | ptrs.exact(&c, v);
            for (i, &x) in sites.iter().enumerate().take(n) {
                states[x] = before[i].wrapping_add(SplitMix64::GOLDEN.wrapping_mul(2));
                counts[x] = if accepted.0[i] { c.k.0[i] } else { counts[x] };
                self.undecided[kept] = x;
                kept += usize::from(!accepted.0[i]);
            }
            progress(start + n);
        }
        self.len = kept;
    }
}

/// Sites per vector step of the exact tests: each is a chain of ~250
/// cycles of dependent operations (logarithm, exponential), so sixteen
/// sites (four AVX2 registers per value) keep the vector units busy.
const EXACT_LANES: usize = 16;

/// The next two uniforms of each generator state, without stepping them.
#[inline(always)]
fn uniform_pair<const N: usize>(states: &[u64; N]) -> (Vf<N>, Vf<N>) {
    let draw = |n: u64| {
        Vf::from_each(states, |s| {
            unit(mix(s.wrapping_add(SplitMix64::GOLDEN.wrapping_mul(n))))
        })
    };
    (draw(1), draw(2))
}

/// The counts whose `ln k!` [`ln_factorial_of_count`] reads from a table
/// (512 KiB): the charges of common full wells, up to ~65 000 e-.
const CACHED_FACTORIALS: usize = 1 << 16;

/// `ln k!` for `k = 0 .. CACHED_FACTORIALS`, by [`ln_factorial`] itself,
/// built on first use.
fn ln_factorial_table() -> &'static [f64; CACHED_FACTORIALS] {
    static TABLE: OnceLock<Box<[f64; CACHED_FACTORIALS]>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut table = Box::new([0.0; CACHED_FACTORIALS]);
        for (k, t) in table.iter_mut().enumerate() {
            *t = ln_factorial(Vf([k as f64])).0[0];
        }
        table
    })
}

/// `ln k!` of the candidates `k`: read from [`ln_factorial_table`] when
/// every element's `k` is below [`CACHED_FACTORIALS`] (elements below 0,
/// which PTRS rejects anyway, read entry 0), else computed by
/// [`ln_factorial`]. The table holds that function's values, so either
/// way gives the same bits; the table spares a logarithm and a division
/// per test.
#[inline(always)]
fn ln_factorial_of_count<const N: usize>(k: Vf<N>) -> Vf<N> {
    if !k.lt(CACHED_FACTORIALS as f64).all() {
        return ln_factorial(k);
    }
    let table = ln_factorial_table();
    let k = k.lt(0.0).select(Vf::from(0.0), k);
    // The index from the low mantissa bits of k + 2^52, as in
    // `ln_factorial`.
    (k + TWO_52).map(|v| table[v.to_bits() as usize & (CACHED_FACTORIALS - 1)])
}

/// `ln(k!)` of integers `k >= 0`: exact table below 10, Stirling's series
/// above (error < 1e-10). Both are computed and one is kept per element.
#[inline(always)]
fn ln_factorial<const N: usize>(k: Vf<N>) -> Vf<N> {
    // ln(k!) for k = 0..9, padded to 16 entries so that any index the mask
    // below can make is in bounds.
    const TABLE: [f64; 16] = [
        0.0,
        0.0,
        std::f64::consts::LN_2,
        1.791_759_469_228_055,
        3.178_053_830_347_945_7,
        4.787_491_742_782_046,
        6.579_251_212_010_101,
        8.525_161_361_065_415,
        10.604_602_902_745_25,
        12.801_827_480_081_469,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
    ];
    /// `ln(2 pi) / 2`.
    const HALF_LN_TAU: f64 = 0.918_938_533_204_672_8;
    // The index from the low mantissa bits of k + 2^52 (AVX2 has no f64 to
    // integer conversion of 64 bits); for k outside 0..=9 it is discarded.
    let small = (k + TWO_52).map(|v| TABLE[(v.to_bits() & 0xF) as usize]);
    let inv = k.recip();
    let inv2 = inv * inv;
    let series = inv * ((inv2 * (1.0 / 1260.0) - 1.0 / 360.0) * inv2 + 1.0 / 12.0);
    let stirling = (k + 0.5) * ln(k) - k + HALF_LN_TAU + series;
    k.lt(10.0).select(small, stirling)
}

/// `ln 2` split so that `n LN_2_HI` is exact for the exponents `n` of f64.
const LN_2_HI: f64 = 6.931_471_803_691_238e-1;
const LN_2_LO: f64 = 1.908_214_929_270_587_7e-10;

/// `1 / (2n + 1)` for n = 0..=11: the atanh series of [`ln`].
const ODD_RECIPROCALS: [f64; 12] = [
    1.0,
    1.0 / 3.0,
    1.0 / 5.0,
    1.0 / 7.0,
    1.0 / 9.0,
    1.0 / 11.0,
    1.0 / 13.0,
    1.0 / 15.0,
    1.0 / 17.0,
    1.0 / 19.0,
    1.0 / 21.0,
    1.0 / 23.0,
];

/// `1 / j!` for j = 0..=13: the Taylor series of [`exp`].
const INV_FACTORIALS: [f64; 14] = [
    1.0,
    1.0,
    1.0 / 2.0,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5_040.0,
    1.0 / 40_320.0,
    1.0 / 362_880.0,
    1.0 / 3_628_800.0,
    1.0 / 39_916_800.0,
    1.0 / 479_001_600.0,
    1.0 / 6_227_020_800.0,
];

/// `Σ coefficients[j] x^j`, as `even(x²) + x odd(x²)`: two Horner chains
/// of half the length, side by side, since the exact tests are bound by
/// the latency of such chains. Index loops, which the compiler unrolls,
/// where folds over reversed iterators were left as calls.
#[inline(always)]
fn polynomial<const N: usize>(coefficients: &[f64], x: Vf<N>) -> Vf<N> {
    let x2 = x * x;
    let mut even = Vf::from(0.0);
    let mut odd = Vf::from(0.0);
    for j in (0..coefficients.len()).rev() {
        if j % 2 == 0 {
            even = even * x2 + coefficients[j];
        } else {
            odd = odd * x2 + coefficients[j];
        }
    }
    even + x * odd
}

/// `ln x` for positive normal `x`, within a few ulp, from IEEE operations
/// only (libm's `ln` is a call per element, which no loop vectorises):
/// `x = 2^e m` with `m` in [sqrt(1/2), sqrt(2)), and `ln m = 2 atanh(s)`,
/// `s = (m - 1) / (m + 1)`, `|s| <= 0.172`, by its odd series to `s^23`
/// (the next term is below 2^-60 of the sum).
#[inline(always)]
fn ln<const N: usize>(x: Vf<N>) -> Vf<N> {
    const ONE: u64 = 0x3FF0_0000_0000_0000;
    const MANTISSA: u64 = 0x000F_FFFF_FFFF_FFFF;
    // The biased exponent made a float through the mantissa of 2^52.
    let biased = x.map_bits(|b| TWO_52.to_bits() | (b >> 52)) - TWO_52;
    let m = x.map_bits(|b| (b & MANTISSA) | ONE);
    let high = m.gt(std::f64::consts::SQRT_2);
    let m = high.select(m * 0.5, m);
    let e = biased - 1023.0 + high.select(Vf::from(1.0), Vf::from(0.0));
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let series = polynomial(&ODD_RECIPROCALS, s2);
    e * LN_2_HI + (e * LN_2_LO + s * 2.0 * series)
}

/// `e^y` for `y <= 700` (below -708 it returns e^-708, ~3e-308, which no
/// comparison here tells from 0), within a few ulp, from IEEE operations
/// only: `y = n ln 2 + r`, `|r| <= ln 2 / 2`, `e^r` by its Taylor series to
/// `r^13` (the next term is below 2^-57), times `2^n` built in the
/// exponent bits.
#[inline(always)]
fn exp<const N: usize>(y: Vf<N>) -> Vf<N> {
    /// 1.5 2^52: adding it rounds to an integer held in the low bits, for
    /// negative numbers too.
    const ROUNDER: f64 = 6_755_399_441_055_744.0;
    let y = y.lt(-708.0).select(Vf::from(-708.0), y);
    let y = y.gt(700.0).select(Vf::from(700.0), y);
    let shifted = y * std::f64::consts::LOG2_E + ROUNDER;
    let n = shifted - ROUNDER;
    let r = (y - n * LN_2_HI) - n * LN_2_LO;
    let poly = polynomial(&INV_FACTORIALS, r);
    // The low bits of `shifted` hold n in two's complement.
    let scale = shifted.map_bits(|b| b.wrapping_sub(ROUNDER.to_bits()).wrapping_add(1023) << 52);
    poly * scale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poisson_probabilities_match_the_law_on_both_branches() {
        // P(k) for means below and above the switch, against the exact law
        // (libm's logarithms), each within 5 binomial standard errors; 12.5
        // sends many candidates below k = 10, to the table of ln k!.
        let n = 400_000;
        for lam in [0.3f64, 3.0, 9.9, 12.5, 40.0, 3000.0] {
            let mut g = SplitMix64::for_site(1, 2, 3);
            let mut counts = vec![0usize; 4000];
            for _ in 0..n {
                counts[g.poisson(lam) as usize] += 1;
            }
            let mut ln_factorial = 0.0;
            for (k, &count) in counts.iter().enumerate() {
                let kf = k as f64;
                if k > 0 {
                    ln_factorial += kf.ln();
                }
                let p = (-lam + kf * lam.ln() - ln_factorial).exp();
                let sigma = (n as f64 * p * (1.0 - p)).sqrt();
                assert!(
                    (count as f64 - n as f64 * p).abs() < 5.0 * sigma + 1.0,
                    "mean {lam}, P({k}): {count} of {n}"
                );
            }
        }
    }

    /// Fills a row from the generators of `row_base`.
    fn fill_row(lam: &[f64], row_base: u64) -> (Vec<f64>, Vec<u64>) {
        let mut states: Vec<u64> = (0..lam.len())
            .map(|x| SplitMix64::at(row_base, x).state())
            .collect();
        let mut counts = vec![0.0; lam.len()];
        PoissonRow::default().fill(lam, &mut counts, &mut states, |_| {});
        (counts, states)
    }

    /// [`fill_row`] compiled as the sensor's AVX2 read-out is.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn fill_row_avx2(lam: &[f64], row_base: u64) -> (Vec<f64>, Vec<u64>) {
        fill_row(lam, row_base)
    }

    #[test]
    fn rows_draw_what_each_site_draws_alone() {
        // Means on both sides of the switch and of the squeeze, mixed across
        // lanes, then log-uniform from 0.1 to 1e6; 61 sites leave a 5-site
        // scalar tail. The baseline and the AVX2 builds must both give each
        // site's own variate and leave its generator where it would be.
        let means = [
            0.0,
            0.3,
            4.0,
            9.99,
            10.0,
            12.5,
            60.0,
            3e3,
            1e5,
            -1.0,
            f64::NAN,
        ];
        let mut g = SplitMix64::for_site(31, 0, 0);
        for row in 0..400usize {
            let base = SplitMix64::row_base(SplitMix64::row_key(9, row));
            let lam: Vec<f64> = if row < 100 {
                (0..61)
                    .map(|x| means[(x * 7 + row) % means.len()])
                    .collect()
            } else {
                (0..61)
                    .map(|_| 10f64.powf(7.0 * g.uniform() - 1.0))
                    .collect()
            };
            let got = fill_row(&lam, base);
            #[cfg(target_arch = "x86_64")]
            if crate::cpu::has_avx2_fma() {
                // SAFETY: AVX2 and FMA support was detected just above.
                let wide = unsafe { fill_row_avx2(&lam, base) };
                assert_eq!(wide.1, got.1, "row {row}");
                let bits = |v: &[f64]| v.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&wide.0), bits(&got.0), "row {row}");
            }
            for (x, &l) in lam.iter().enumerate() {
                let mut site = SplitMix64::at(base, x);
                let want = site.poisson(l);
                assert_eq!(
                    got.0[x].to_bits(),
                    want.to_bits(),
                    "row {row} site {x} mean {l}"
                );
                assert_eq!(got.1[x], site.state(), "row {row} site {x}");
            }
        }
    }

    #[test]
    fn ln_and_exp_are_within_a_few_ulp_of_libm() {
        let mut g = SplitMix64::for_site(5, 0, 0);
        for _ in 0..200_000 {
            let x = 10f64.powf(g.uniform() * 600.0 - 300.0);
            let want = x.ln();
            let got = ln(Vf([x])).0[0];
            assert!(
                (got - want).abs() <= 4.0 * f64::EPSILON * want.abs().max(1.0),
                "ln {x}: {got} vs {want}"
            );
            let y = g.uniform() * 1400.0 - 705.0;
            let (got, want) = (exp(Vf([y])).0[0], y.exp());
            assert!(
                (got / want - 1.0).abs() <= 4.0 * f64::EPSILON,
                "exp {y}: {got} vs {want}"
            );
        }
        assert_eq!(exp(Vf([-1e4])), exp(Vf([-708.0])));
    }

    #[test]
    fn stirling_matches_the_table_where_they_meet() {
        let exact_10 = 15.104_412_573_075_516;
        assert!((ln_factorial(Vf([10.0])).0[0] - exact_10).abs() < 1e-10);
        assert_eq!(ln_factorial(Vf([9.0])).0[0], 12.801_827_480_081_469);
        // The table is the function's cache: the same bits on either side
        // of its end, and for candidates below 0 (rejected anyway) entry 0.
        let edge = CACHED_FACTORIALS as f64;
        let k = Vf([0.0, 9.0, 10.0, 1234.0, edge - 1.0]);
        assert_eq!(ln_factorial_of_count(k), ln_factorial(k));
        let beyond = Vf([5.0, edge, edge + 1.0]);
        assert_eq!(ln_factorial_of_count(beyond), ln_factorial(beyond));
        assert_eq!(ln_factorial_of_count(Vf([-3.0, 4.0])).0[0], 0.0);
    }
}

//! Random variates that are pure functions of a seed and a site.
//!
//! Simulated noise must not depend on the number of threads, so no generator
//! is shared between pixels: each site `(y, x)` seeds its own tiny generator
//! from `(seed, y, x)`. That makes the per-site set-up and every draw part of
//! the per-pixel cost of a sensor simulation, which is why the variates here
//! avoid libm on their common paths: the normal by Marsaglia and Tsang's
//! ziggurat, the Poisson by Hörmann's PTRS with polynomial logarithms and
//! exponentials ([`poisson`]).
//!
//! [`Lanes`] steps the normals of [`LANES`] neighbouring sites together,
//! and [`PoissonRow`] the Poisson variates of a whole row, so that the
//! common paths run as vector instructions across pixels; every site still
//! draws exactly the numbers its own [`SplitMix64`] would.

use std::sync::OnceLock;

mod poisson;
mod vf;

pub(crate) use poisson::PoissonRow;
use vf::TWO_52;

/// SplitMix64 (Steele, Lea, Flood 2014): a tiny generator whose state can be
/// set from any counter, which is what makes the noise of each pixel a pure
/// function of `(seed, y, x)`.
pub(crate) struct SplitMix64(u64);

impl SplitMix64 {
    const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

    /// The generator of site `(y, x)` under `seed`.
    pub(crate) fn for_site(seed: u64, y: usize, x: usize) -> Self {
        Self::in_row(Self::row_key(seed, y), x)
    }

    /// The part of [`Self::for_site`] that depends on the row only, so that
    /// a kernel mixes it once per row rather than once per pixel.
    pub(crate) fn row_key(seed: u64, y: usize) -> u64 {
        // Mix the seed and each coordinate in turn, so nearby sites and
        // nearby seeds start from unrelated states.
        Self(seed).next_u64() ^ (y as u64)
    }

    /// The generator of column `x` in the row of `row_key`.
    #[inline(always)]
    pub(crate) fn in_row(row_key: u64, x: usize) -> Self {
        Self::at(Self::row_base(row_key), x)
    }

    /// The part of [`Self::in_row`] shared by a whole row: one mix of the
    /// row key, hoisted out of the loop over columns.
    #[inline(always)]
    pub(crate) fn row_base(row_key: u64) -> u64 {
        Self(row_key).next_u64()
    }

    /// The generator of column `x` from its row's [`Self::row_base`]: the
    /// base with `x` mixed in, one step on (the first output is skipped so
    /// that a site's draws never start with the plain mix of its key).
    #[inline(always)]
    pub(crate) fn at(row_base: u64, x: usize) -> Self {
        Self((row_base ^ x as u64).wrapping_add(Self::GOLDEN))
    }

    /// The generator's state, to resume it later with [`Self::from_state`].
    #[inline(always)]
    pub(crate) fn state(&self) -> u64 {
        self.0
    }

    /// The generator left in `state`.
    #[inline(always)]
    pub(crate) fn from_state(state: u64) -> Self {
        Self(state)
    }

    #[inline(always)]
    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(Self::GOLDEN);
        mix(self.0)
    }

    /// Uniform in [0, 1) with 53 random bits.
    #[inline(always)]
    pub(crate) fn uniform(&mut self) -> f64 {
        unit(self.next_u64())
    }

    /// A standard normal variate by the ziggurat method (Marsaglia and Tsang
    /// 2000, 256 layers). One 64-bit draw gives the layer (8 bits), the sign
    /// (1 bit) and the abscissa (53 bits), so the three never share bits
    /// (the defect Doornik 2005 found in the 32-bit original); ~99 % of
    /// draws end after one comparison.
    #[inline(always)]
    pub(crate) fn normal(&mut self) -> f64 {
        self.normal_from(ziggurat())
    }

    #[inline(always)]
    fn normal_from(&mut self, z: &Ziggurat) -> f64 {
        let bits = self.next_u64();
        match z.first_try(bits) {
            (x, true) => with_sign(x, bits),
            _ => self.normal_after_miss(z, bits),
        }
    }

    /// The rest of [`Self::normal`] after the draw `bits` missed the fast
    /// path: its edge test, then fresh draws.
    #[cold]
    fn normal_after_miss(&mut self, z: &Ziggurat, bits: u64) -> f64 {
        let (x, _) = z.first_try(bits);
        match self.normal_edge(z, (bits & 0xFF) as usize, x) {
            Some(x) => with_sign(x, bits),
            None => self.normal_from(z),
        }
    }

    /// The rare cases of [`Self::normal`]: a draw beyond the base layer's
    /// rectangle (from the tail, by Marsaglia's 1964 method) or in a layer's
    /// wedge (accepted under the density). `None` rejects the draw.
    #[cold]
    fn normal_edge(&mut self, z: &Ziggurat, layer: usize, x: f64) -> Option<f64> {
        if layer == 0 {
            loop {
                // 1 - u is in (0, 1], so the logarithms are finite.
                let t = -(1.0 - self.uniform()).ln() / TAIL_START;
                let e = -(1.0 - self.uniform()).ln();
                if 2.0 * e >= t * t {
                    return Some(TAIL_START + t);
                }
            }
        }
        let y = z.f[layer] + self.uniform() * (z.f[layer + 1] - z.f[layer]);
        (y < density(x)).then_some(x)
    }
}

/// Pixels whose generators [`Lanes`] steps together: eight f64 lanes fill
/// two AVX2 registers, enough to hide the latency of the square root and
/// division of PTRS behind independent work.
pub(crate) const LANES: usize = 8;

/// The generators of [`LANES`] consecutive sites of a row, stepped
/// together. Each variate takes one vector step for all lanes; a lane that
/// the step does not decide is rewound or continued by the scalar code, so
/// lane `i` yields exactly what `SplitMix64::at(base, x0 + i)` would.
pub(crate) struct Lanes([u64; LANES]);

impl Lanes {
    /// The generators of columns `x0 .. x0 + LANES` of the row with
    /// [`SplitMix64::row_base`] `row_base`.
    #[inline(always)]
    pub(crate) fn at(row_base: u64, x0: usize) -> Self {
        let mut states = [0; LANES];
        for (i, s) in states.iter_mut().enumerate() {
            *s = SplitMix64::at(row_base, x0 + i).0;
        }
        Self(states)
    }

    /// The generators left in `states` (e.g. by a [`PoissonRow`]).
    #[inline(always)]
    pub(crate) fn from_states(states: [u64; LANES]) -> Self {
        Self(states)
    }

    #[inline(always)]
    fn next_u64(&mut self) -> [u64; LANES] {
        let mut out = [0; LANES];
        for (o, s) in out.iter_mut().zip(self.0.iter_mut()) {
            *s = s.wrapping_add(SplitMix64::GOLDEN);
            *o = mix(*s);
        }
        out
    }

    /// Runs the scalar generator of lane `i` from its current state.
    #[inline(always)]
    fn finish<R>(&mut self, i: usize, f: impl FnOnce(&mut SplitMix64) -> R) -> R {
        let mut g = SplitMix64(self.0[i]);
        let r = f(&mut g);
        self.0[i] = g.0;
        r
    }

    /// A standard normal variate per lane ([`SplitMix64::normal`]).
    #[inline(always)]
    pub(crate) fn normal(&mut self, z: &Ziggurat) -> [f64; LANES] {
        let bits = self.next_u64();
        let mut out = [0.0; LANES];
        let mut hit = [false; LANES];
        for ((o, h), &b) in out.iter_mut().zip(hit.iter_mut()).zip(&bits) {
            let (x, fast) = z.first_try(b);
            *o = with_sign(x, b);
            *h = fast;
        }
        for i in 0..LANES {
            if !hit[i] {
                out[i] = self.finish(i, |g| g.normal_after_miss(z, bits[i]));
            }
        }
        out
    }
}

/// SplitMix64's output function: a bijective mix of the state.
#[inline(always)]
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// `x` with bit 8 of `bits` as its sign bit: a branch here would be
/// mispredicted on every other draw.
#[inline(always)]
fn with_sign(x: f64, bits: u64) -> f64 {
    f64::from_bits(x.to_bits() ^ ((bits & 0x100) << 55))
}

/// The top 53 bits of `bits` as a uniform number in [0, 1):
/// `(bits >> 11) 2^-53`, computed from the two 32-bit halves, each made a
/// float by placing it in the mantissa of 2^52 and subtracting 2^52. Every
/// step is exact, so this is the plain conversion's value; but x86-64 has no
/// vector instruction converting u64 to f64 before AVX-512, and this form
/// vectorises with AVX2.
#[inline(always)]
fn unit(bits: u64) -> f64 {
    let half = |h: u64| f64::from_bits(TWO_52.to_bits() | h) - TWO_52;
    let hi = half(bits >> 32);
    let lo = half(bits & 0xFFFF_F800);
    (hi * 4_294_967_296.0 + lo) * (1.0 / 18_446_744_073_709_551_616.0)
}

/// Layers of the ziggurat.
const LAYERS: usize = 256;
/// Where the tail of the 256-layer ziggurat starts (Marsaglia and Tsang 2000).
const TAIL_START: f64 = 3.654_152_885_361_009;
/// The area of each layer, and of the base layer with the tail (ibid.).
const LAYER_AREA: f64 = 4.928_673_233_99e-3;

/// The unnormalised standard normal density `exp(-x² / 2)`.
fn density(x: f64) -> f64 {
    (-0.5 * x * x).exp()
}

/// The ziggurat's layer edges: layer `i` is the box `[0, x[i]] x [f[i],
/// f[i + 1]]`, `f = density(x)`, all of area [`LAYER_AREA`]; layer 0 is the
/// base box (its width stretched to carry the tail's area) and `x[256] = 0`.
pub(crate) struct Ziggurat {
    x: [f64; LAYERS + 1],
    f: [f64; LAYERS + 1],
}

impl Ziggurat {
    /// The abscissa of the draw `bits` in its layer (the low 8 bits), and
    /// whether it lies inside the layer's rectangle, where it is accepted.
    #[inline(always)]
    fn first_try(&self, bits: u64) -> (f64, bool) {
        let layer = (bits & 0xFF) as usize;
        let x = unit(bits) * self.x[layer];
        (x, x < self.x[layer + 1])
    }
}

/// The ziggurat's table, built on first use.
pub(crate) fn ziggurat() -> &'static Ziggurat {
    static TABLE: OnceLock<Ziggurat> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut x = [0.0; LAYERS + 1];
        x[0] = LAYER_AREA / density(TAIL_START);
        x[1] = TAIL_START;
        for i in 1..LAYERS - 1 {
            // The next edge up is where the box of width x[i] from
            // density(x[i]) reaches the layer's area.
            x[i + 1] = (-2.0 * (LAYER_AREA / x[i] + density(x[i])).ln()).sqrt();
        }
        // x[256] would be ~1e-9 from rounding in the constants: it is 0.
        let f = x.map(density);
        Ziggurat { x, f }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sites_are_mixed_from_a_row_key() {
        // The split keeps the stream of every site as it was before it:
        // vanishing-point RANSAC draws its pairs from it.
        let mut g = SplitMix64::for_site(5, 7, 11);
        let a = SplitMix64(5).next_u64() ^ 7;
        let b = SplitMix64(a).next_u64() ^ 11;
        let mut reference = SplitMix64(b);
        reference.next_u64();
        assert_eq!(g.next_u64(), reference.next_u64());
    }

    #[test]
    fn the_ziggurat_has_equal_layers_that_close_at_the_top() {
        let z = ziggurat();
        for i in 1..LAYERS {
            let area = z.x[i] * (z.f[i + 1] - z.f[i]);
            assert!((area / LAYER_AREA - 1.0).abs() < 1e-6, "layer {i}: {area}");
        }
        assert!(z.x[LAYERS - 1] > 0.0 && z.x[LAYERS - 1] < 0.3);
    }

    #[test]
    fn normal_variates_follow_the_normal_law() {
        let mut g = SplitMix64::for_site(3, 1, 4);
        let n = 1_000_000;
        let draws: Vec<f64> = (0..n).map(|_| g.normal()).collect();
        let mean = draws.iter().sum::<f64>() / n as f64;
        let var = draws.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / n as f64;
        let m4 = draws.iter().map(|d| (d - mean).powi(4)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.005, "{mean}");
        assert!((var - 1.0).abs() < 0.005, "{var}");
        assert!(
            (m4 / (var * var) - 3.0).abs() < 0.03,
            "kurtosis {}",
            m4 / var / var
        );
        // P(|Z| > t) at the edges of the base layer, the wedges and the tail
        // (erfc values), each within 5 binomial standard errors.
        for (t, p) in [
            (0.5, 0.617_075_077_5),
            (1.0, 0.317_310_507_9),
            (2.0, 0.045_500_263_9),
            (3.0, 0.002_699_796_1),
            (TAIL_START, 0.000_258_004_8),
            (4.5, 0.000_006_795_3),
        ] {
            let count = draws.iter().filter(|d| d.abs() > t).count() as f64;
            let sigma = (n as f64 * p * (1.0 - p)).sqrt();
            assert!(
                (count - n as f64 * p).abs() < 5.0 * sigma + 1.0,
                "P(|Z| > {t}): {count} of {n}"
            );
        }
    }

    /// Two normals per lane, as the sensor's fixed patterns draw them.
    #[inline(always)]
    fn lane_normals(lanes: &mut Lanes, z: &Ziggurat) -> [[f64; LANES]; 2] {
        [lanes.normal(z), lanes.normal(z)]
    }

    /// [`lane_normals`] compiled as the sensor's AVX2 read-out is.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn lane_normals_avx2(lanes: &mut Lanes, z: &Ziggurat) -> [[f64; LANES]; 2] {
        lane_normals(lanes, z)
    }

    #[test]
    fn lanes_draw_the_normals_each_site_draws_alone() {
        // 16 000 rows of eight lanes: ~1 300 draws miss the fast path, some
        // into the tail. The baseline and the AVX2 builds of the lanes must
        // both give each site's own draws.
        let z = ziggurat();
        for row in 0..16_000usize {
            let base = SplitMix64::row_base(SplitMix64::row_key(9, row));
            let x0 = (row % 5) * LANES;
            let mut lanes = Lanes::at(base, x0);
            let got = lane_normals(&mut lanes, z);
            #[cfg(target_arch = "x86_64")]
            if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
                let mut wide = Lanes::at(base, x0);
                // SAFETY: AVX2 and FMA support was detected above.
                let wide_got = unsafe { lane_normals_avx2(&mut wide, z) };
                assert_eq!(
                    wide_got.map(|d| d.map(f64::to_bits)),
                    got.map(|d| d.map(f64::to_bits))
                );
                assert_eq!(wide.0, lanes.0, "row {row}");
            }
            for i in 0..LANES {
                let mut g = SplitMix64::at(base, x0 + i);
                for d in got {
                    assert_eq!(d[i].to_bits(), g.normal().to_bits(), "row {row} lane {i}");
                }
                assert_eq!(lanes.0[i], g.0);
            }
        }
    }

    #[test]
    fn unit_is_the_plain_conversion_of_the_top_53_bits() {
        let mut g = SplitMix64(17);
        let edges = [0, u64::MAX, 1 << 11, (1 << 11) - 1, 1 << 63, 0xFFFF_FFFF];
        for bits in edges.into_iter().chain((0..100_000).map(|_| g.next_u64())) {
            let plain = (bits >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
            assert_eq!(unit(bits).to_bits(), plain.to_bits(), "{bits:#x}");
        }
    }
}

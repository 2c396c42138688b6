//! `2^x` and `log2 x` in f32 that vectorise, and the macro that builds the
//! film's row kernels for AVX2 + FMA.
//!
//! A call to `exp2f` or `log10f` is opaque to the vectoriser, and the film
//! takes 41 exponentials per printed pixel and a logarithm per layer and
//! development. These polynomials are plain arithmetic on `f32` and bit
//! operations, so a row loop over them compiles to packed instructions.
//! `2^x`'s polynomial is written with `mul_add`: one fused instruction in the
//! AVX2 build, libm's `fmaf` (rounded once as well) in the baseline build,
//! so both builds give the same bits; the compiler contracts nothing else.

/// Pixels per block of the kernels that read rows of `n` interleaved layers
/// sample by sample, each sample with its own layer's parameters: `8 n`
/// samples, a whole number of 8-lane registers whose pattern of layers
/// repeats from block to block.
pub const LANES: usize = 8;

/// `2^x` for `x` in about `[-126, 126]` (clamped there), to 1.7e-7
/// relative: three operations fewer than a 6th-power Taylor series of
/// `e^(r ln 2)`, and closer (that gave 2.3e-7).
///
/// The rounding by adding and subtracting 1.5 x 2^23 and the polynomial
/// vectorise: `2^x = 2^n 2^r` with `n` the nearest integer and
/// `|r| <= 1/2`; `2^r` is a degree-5 polynomial in `r` with its constant
/// fixed at 1 (so `2^n` is exact), the other coefficients fitted for the
/// least maximum relative error on `[-1/2, 1/2]` (Lawson's iteration;
/// 9.1e-8 in exact arithmetic, the rest is f32 rounding); `2^n` is built
/// from its IEEE-754 exponent bits.
#[inline(always)]
pub fn exp2(x: f32) -> f32 {
    const ROUND: f32 = 12_582_912.0;
    /// `(127 - bits(ROUND)) << 23`: added to `bits(x + ROUND) << 23`, whose
    /// low mantissa bits hold `bits(ROUND) + n`, it leaves `(n + 127) << 23`,
    /// the bits of `2^n` (two integer operations where a subtraction of the
    /// bits, an add of the bias and a shift were three).
    const BIAS: u32 = 127u32.wrapping_sub(ROUND_BITS) << 23;
    /// `ROUND.to_bits()` (not callable in a `const` before Rust 1.83, the
    /// crate's minimum is 1.80; the test of exact powers of two checks it).
    const ROUND_BITS: u32 = 0x4b40_0000;
    let x = x.clamp(-126.0, 126.0);
    let rounded = x + ROUND;
    let r = x - (rounded - ROUND);
    let p = EXP2_POLY
        .iter()
        .fold(EXP2_TOP, |acc: f32, c| acc.mul_add(r, *c));
    p * f32::from_bits((rounded.to_bits() << 23).wrapping_add(BIAS))
}

/// The coefficient of `r^5` of [`exp2`]'s polynomial.
const EXP2_TOP: f32 = 0.001_326_472_8;
/// The coefficients of `r^4` down to `r^0` of [`exp2`]'s polynomial (that
/// of `r` is fitted, 1.8e-7 below `ln 2`).
#[allow(clippy::approx_constant)]
const EXP2_POLY: [f32; 5] = [0.009_671_513, 0.055_507_336, 0.240_222_42, 0.693_147, 1.0];

/// `log2 x` for finite `x >= 0`, to ~1e-7 absolute; 0 gives about -127
/// (below every curve's toe, as `-inf` is), subnormals about -127 too.
///
/// `x = m 2^e` with the mantissa `m` moved into `[sqrt(1/2), sqrt(2))`; then
/// `ln m = 2 atanh(s)`, `s = (m - 1) / (m + 1)`, `|s| <= 0.1716`, whose odd
/// series to `s^9` leaves `2 s^11 / 11 < 7e-10`.
#[inline(always)]
pub fn log2(x: f32) -> f32 {
    let bits = x.to_bits();
    // The exponent, and the mantissa as a number in [1, 2).
    let e = ((bits >> 23) & 0xff) as i32 - 127;
    let m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    let big = m > std::f32::consts::SQRT_2;
    let (m, e) = if big { (0.5 * m, e + 1) } else { (m, e) };
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let series =
        s * (2.0 + s2 * (2.0 / 3.0 + s2 * (2.0 / 5.0 + s2 * (2.0 / 7.0 + s2 * (2.0 / 9.0)))));
    e as f32 + series * std::f32::consts::LOG2_E
}

/// Defines `fn $name(args)` that runs the `#[inline(always)]` function
/// `$plain(args)` compiled for AVX2 and FMA when the CPU has them, and as it
/// is otherwise: the film's row loops are plain loops over slices, and this
/// is where they get 8-lane instructions. (A closure handed to a
/// feature-enabled function is not inlined into it, so the plain function
/// must be named.) The compiler contracts no multiply-add to FMA; where a
/// loop writes `mul_add` it is fused in both builds (by `fmaf` in the
/// baseline one), so both builds give the same bits, which the tests check.
macro_rules! wide {
    ($(#[$doc:meta])* fn $name:ident = $plain:ident($($arg:ident: $ty:ty),* $(,)?)) => {
        $(#[$doc])*
        #[inline]
        fn $name($($arg: $ty),*) {
            /// # Safety
            /// The CPU must support AVX2 and FMA.
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2,fma")]
            unsafe fn with_avx2_fma($($arg: $ty),*) {
                $plain($($arg),*)
            }
            #[cfg(target_arch = "x86_64")]
            if $crate::cpu::has_avx2_fma() {
                // SAFETY: AVX2 and FMA support was detected just above.
                return unsafe { with_avx2_fma($($arg),*) };
            }
            $plain($($arg),*)
        }
    };
}
pub(crate) use wide;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp2_is_accurate_over_the_film_range() {
        for k in -4000..=400 {
            let x = k as f32 * 0.01;
            let want = 2f64.powf(f64::from(x));
            let got = f64::from(exp2(x));
            assert!((got / want - 1.0).abs() < 3e-7, "{x}: {got} vs {want}");
        }
        assert!(exp2(-500.0) > 0.0 && exp2(-500.0) < 1e-37);
        // The polynomial is 1 at r = 0, so powers of two are exact.
        for n in -126..=126 {
            assert_eq!(exp2(n as f32), 2f32.powi(n), "{n}");
        }
    }

    #[test]
    fn log2_is_accurate_from_tiny_to_huge_exposures() {
        let mut x = 1e-30f32;
        while x < 1e30 {
            let want = f64::from(x).log2();
            let got = f64::from(log2(x));
            assert!(
                (got - want).abs() < 2.5e-7 * want.abs().max(1.0),
                "{x}: {got} vs {want}"
            );
            x *= 1.0137;
        }
        for x in [1.0f32, 2.0, 0.5, 1024.0] {
            assert_eq!(log2(x), x.log2());
        }
        assert!(log2(0.0) <= -126.0 && log2(1e-42) <= -126.0);
    }
}

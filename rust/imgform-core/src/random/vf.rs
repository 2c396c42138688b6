//! `N` f64 values under one operation at a time.
//!
//! The samplers' arithmetic is written once on [`Vf`] and run with `N = 1`
//! for one site or `N = LANES` for the sites a row steps together. Every
//! operation is its own loop over the elements with nothing but IEEE
//! arithmetic and selects in it, so the compiler turns each into vector
//! instructions, and an element gets the same bits whatever `N` is.

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

/// `N` f64 values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Vf<const N: usize>(pub(crate) [f64; N]);

/// One truth value per element of a [`Vf`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Mask<const N: usize>(pub(crate) [bool; N]);

impl<const N: usize> From<f64> for Vf<N> {
    #[inline(always)]
    fn from(v: f64) -> Self {
        Self([v; N])
    }
}

/// An element-wise binary operator between two `Vf`s or two `Mask`s.
macro_rules! elementwise {
    ($type:ident, $trait:ident, $method:ident, $assign:tt) => {
        impl<const N: usize> $trait for $type<N> {
            type Output = Self;
            #[inline(always)]
            fn $method(self, rhs: Self) -> Self {
                let mut out = self.0;
                for (o, r) in out.iter_mut().zip(rhs.0) {
                    *o $assign r;
                }
                Self(out)
            }
        }
    };
}

/// An arithmetic operator between two `Vf`s, and between a `Vf` and an
/// `f64` (only in that order: with `f64 op Vf` too, a float literal on the
/// left would leave its type ambiguous).
macro_rules! arithmetic {
    ($trait:ident, $method:ident, $assign:tt) => {
        elementwise!(Vf, $trait, $method, $assign);
        impl<const N: usize> $trait<f64> for Vf<N> {
            type Output = Self;
            #[inline(always)]
            fn $method(self, rhs: f64) -> Self {
                $trait::$method(self, Self::from(rhs))
            }
        }
    };
}

arithmetic!(Add, add, +=);
arithmetic!(Sub, sub, -=);
arithmetic!(Mul, mul, *=);
arithmetic!(Div, div, /=);
elementwise!(Mask, BitAnd, bitand, &=);
elementwise!(Mask, BitOr, bitor, |=);

impl<const N: usize> Neg for Vf<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        self.map(|v| -v)
    }
}

/// The element-wise comparisons, each against a `Vf` or an `f64`.
macro_rules! comparison {
    ($($method:ident: $op:tt),*) => {
        $(
            #[inline(always)]
            pub(crate) fn $method(self, rhs: impl Into<Self>) -> Mask<N> {
                let rhs = rhs.into();
                let mut out = [false; N];
                for ((o, a), b) in out.iter_mut().zip(self.0).zip(rhs.0) {
                    *o = a $op b;
                }
                Mask(out)
            }
        )*
    };
}

impl<const N: usize> Vf<N> {
    /// `f` of every element. A loop: `array::map` is often left as a call,
    /// out of the vector build.
    #[inline(always)]
    pub(crate) fn map(self, f: impl Fn(f64) -> f64) -> Self {
        let mut out = self.0;
        for o in &mut out {
            *o = f(*o);
        }
        Self(out)
    }

    /// The elements made from `N` values of another type by `f`.
    #[inline(always)]
    pub(crate) fn from_each<T: Copy>(values: &[T; N], f: impl Fn(T) -> f64) -> Self {
        let mut out = [0.0; N];
        for (o, &v) in out.iter_mut().zip(values) {
            *o = f(v);
        }
        Self(out)
    }

    /// The elements' bits transformed by `f`.
    #[inline(always)]
    pub(crate) fn map_bits(self, f: impl Fn(u64) -> u64) -> Self {
        self.map(|v| f64::from_bits(f(v.to_bits())))
    }

    /// `1 / self`.
    #[inline(always)]
    pub(crate) fn recip(self) -> Self {
        Self::from(1.0) / self
    }

    #[inline(always)]
    pub(crate) fn sqrt(self) -> Self {
        self.map(f64::sqrt)
    }

    #[inline(always)]
    pub(crate) fn abs(self) -> Self {
        self.map_bits(|b| b & !SIGN)
    }

    /// The elements rounded down, without a call to libm (`floor` is not
    /// an instruction of baseline x86-64): rounded to an integer by adding
    /// and subtracting 2^52 with the element's sign, then corrected where
    /// that rounded up. From 2^52 up every float is an integer already.
    #[inline(always)]
    pub(crate) fn floor(self) -> Self {
        let shift = self.map_bits(|b| (b & SIGN) | TWO_52.to_bits());
        let rounded = self.abs().lt(TWO_52).select((self + shift) - shift, self);
        rounded.gt(self).select(rounded - 1.0, rounded)
    }

    comparison!(lt: <, le: <=, gt: >, ge: >=);
}

/// The sign bit of an f64.
const SIGN: u64 = 1 << 63;

/// 2^52: from there on every f64 is an integer, so adding it to a number in
/// [0, 2^52) rounds that number to an integer held in the low mantissa bits.
pub(crate) const TWO_52: f64 = 4_503_599_627_370_496.0;

impl<const N: usize> Mask<N> {
    /// `if_true` where the mask is set, else `if_false`.
    #[inline(always)]
    pub(crate) fn select(self, if_true: Vf<N>, if_false: Vf<N>) -> Vf<N> {
        let mut out = if_false.0;
        for ((o, t), m) in out.iter_mut().zip(if_true.0).zip(self.0) {
            *o = if m { t } else { *o };
        }
        Vf(out)
    }

    /// Whether every element is set.
    #[inline(always)]
    pub(crate) fn all(self) -> bool {
        self.0.iter().fold(true, |a, &m| a & m)
    }

    /// Whether any element is set.
    #[inline(always)]
    pub(crate) fn any(self) -> bool {
        self.0.iter().fold(false, |a, &m| a | m)
    }
}

impl<const N: usize> Not for Mask<N> {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        let mut out = self.0;
        for o in &mut out {
            *o = !*o;
        }
        Self(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_matches_the_library_floor() {
        for v in [
            -2.5,
            -2.0,
            -0.3,
            -0.0,
            0.0,
            0.7,
            3.0,
            1e15 + 0.5,
            -1e17,
            1e300,
            // Around 2^52, where adding 2^52 would round by 2, and the
            // float just below 1/2, which the addition rounds up.
            4_503_599_627_370_495.5,
            -4_503_599_627_370_495.5,
            4_503_599_627_370_496.0,
            0.499_999_999_999_999_94,
            -0.499_999_999_999_999_94,
        ] {
            assert_eq!(Vf([v]).floor().0[0], v.floor(), "{v}");
        }
    }

    #[test]
    fn operators_and_selects_act_per_element() {
        let a = Vf([1.0, -4.0, 9.0]);
        let b = Vf([2.0, 2.0, 3.0]);
        assert_eq!((a + b).0, [3.0, -2.0, 12.0]);
        assert_eq!((a - 1.0).0, [0.0, -5.0, 8.0]);
        assert_eq!((a * 2.0 / b).0, [1.0, -4.0, 6.0]);
        assert_eq!(b.recip().0, [0.5, 0.5, 1.0 / 3.0]);
        assert_eq!((-a).abs().sqrt().0, [1.0, 2.0, 3.0]);
        let m = a.lt(b) & !a.lt(0.0);
        assert_eq!(m.0, [true, false, false]);
        assert_eq!(m.select(a, b).0, [1.0, 2.0, 3.0]);
        assert!((m | a.ge(9.0)).any() && !a.gt(9.0).any());
        assert!(a.lt(10.0).all() && !a.lt(9.0).all());
    }
}

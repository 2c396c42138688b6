//! The one error type of the core. The bindings map each variant to a Python
//! exception class in one exhaustive match, so every message here must say what
//! was given and what is accepted.

/// Why a kernel refused its input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CoreError {
    /// A value is outside its domain: `f <= 0`, a NaN, a singular matrix, an
    /// unknown method name. Maps to Python's `ValueError`.
    #[error("{0}")]
    InvalidArgument(String),
    /// Buffer lengths or dimensions do not agree with each other. Maps to
    /// Python's `ValueError`.
    #[error("{0}")]
    Shape(String),
    /// A buffer the input asks for cannot be allocated (a map of 10⁵ x 10⁵
    /// pixels): refused rather than aborting the process, as a failed
    /// `vec!` does. Maps to Python's `MemoryError`.
    #[error("{0}")]
    Memory(String),
}

/// Result of every fallible kernel.
pub type Result<T> = std::result::Result<T, CoreError>;

/// Shorthand for an [`CoreError::InvalidArgument`] with a formatted message.
#[macro_export]
macro_rules! invalid {
    ($($arg:tt)*) => { $crate::error::CoreError::InvalidArgument(format!($($arg)*)) };
}

/// Checks that a scalar parameter is finite and strictly positive.
///
/// # Errors
/// [`CoreError::InvalidArgument`] naming the parameter and its value.
#[inline(always)]
pub fn positive(name: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(invalid!("{name} must be a finite number > 0, got {value}"))
    }
}

/// Checks that a scalar parameter is finite.
///
/// # Errors
/// [`CoreError::InvalidArgument`] naming the parameter and its value.
pub fn finite(name: &str, value: f64) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(invalid!("{name} must be finite, got {value}"))
    }
}

/// `true` for an image sample a kernel can take as a physical quantity
/// (radiance, exposure, density, rate): finite and >= 0 (NaN fails both
/// comparisons).
#[inline(always)]
pub(crate) fn is_valid_sample(v: f32) -> bool {
    (0.0..=f32::MAX).contains(&v)
}

/// `true` when every sample of `x` is valid: a branch-free fold, which
/// compiles to packed compares, so the check costs little beside a kernel
/// that reads the same samples.
#[inline(always)]
pub(crate) fn all_valid(x: &[f32]) -> bool {
    x.iter().fold(true, |ok, &v| ok & is_valid_sample(v))
}

/// Checks that every entry of a small parameter array (a matrix, a vector of
/// coefficients) is finite.
///
/// # Errors
/// [`CoreError::InvalidArgument`] naming the parameter and the first bad entry.
pub fn all_finite(name: &str, values: &[f64]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(invalid!(
            "{name} must contain only finite numbers, entry {i} is {}",
            values[i]
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_must_be_finite_and_non_negative() {
        assert!(all_valid(&[0.0, 1.0, f32::MAX]));
        for bad in [-1e-30, f32::NAN, f32::INFINITY] {
            assert!(!all_valid(&[1.0, bad]), "{bad}");
        }
    }

    #[test]
    fn positive_rejects_zero_nan_and_negative() {
        assert!(positive("f", 1.0).is_ok());
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let err = positive("f", bad).unwrap_err().to_string();
            assert!(err.starts_with("f must be a finite number > 0"), "{err}");
        }
    }

    #[test]
    fn all_finite_names_the_entry() {
        let err = all_finite("K", &[1.0, f64::NAN]).unwrap_err().to_string();
        assert!(err.contains("entry 1"), "{err}");
    }
}

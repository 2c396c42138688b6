//! Similarity metrics of the lecture (eqs. 5-7) computed from running sums.
//!
//! The search accumulates, for every candidate shift, a handful of sums over
//! the overlapping pixels; each metric is a closed form of those sums. Samples
//! are read with an offset `c` subtracted (see [`super::pyramid::Rows`]) so
//! that the `f32` cross products do not cancel catastrophically for 16-bit
//! data; the formulas below undo the offset where a metric depends on it.

use crate::error::Result;
use crate::invalid;

/// How two equally sized patches are compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Metric {
    /// `sqrt(sum (a - b)^2)`, the lecture's square-rooted sum of squared
    /// differences (eq. 5); lower is better.
    Ssd,
    /// `sum a b / (|a| |b|)` (eq. 6); higher is better.
    Cosine,
    /// Normalised cross-correlation, the cosine of the mean-free patches
    /// (eq. 7); higher is better and invariant to `a * I + b` with `a > 0`.
    Ncc,
}

impl Metric {
    /// Parses `"ssd"`, `"cosine"` or `"ncc"`.
    ///
    /// # Errors
    /// [`crate::CoreError::InvalidArgument`] naming the unknown metric.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "ssd" => Ok(Self::Ssd),
            "cosine" => Ok(Self::Cosine),
            "ncc" => Ok(Self::Ncc),
            other => Err(invalid!(
                "unknown metric {other:?}; accepted: \"ssd\", \"cosine\", \"ncc\""
            )),
        }
    }

    /// Whether a larger score means a better match.
    pub fn higher_is_better(self) -> bool {
        !matches!(self, Self::Ssd)
    }

    /// True when `a` is a strictly better score than `b` (NaN is never better).
    pub fn better(self, a: f64, b: f64) -> bool {
        if b.is_nan() {
            return !a.is_nan();
        }
        if self.higher_is_better() {
            a > b
        } else {
            a < b
        }
    }
}

/// Sums over the overlap of one candidate shift, in offset-free units
/// (`a' = a - c`, `b' = b - c`). For [`Metric::Ssd`] `cross` is
/// `sum (a' - b')^2`, for the other metrics `sum a' b'`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Sums {
    pub n: f64,
    pub sa: f64,
    pub sb: f64,
    pub saa: f64,
    pub sbb: f64,
    pub cross: f64,
    /// The sums of squares (as [`Sums::squares`] gives them) whose size
    /// these sums' rounding is relative to, when larger than their own: 0
    /// for sums accumulated over the patch alone, the whole images' for sums
    /// taken as differences of running sums or from a correlation of the
    /// whole images. A patch whose variance is rounding next to them counts
    /// as constant.
    pub floor: (f64, f64),
}

impl Sums {
    /// Adds another partial sum (a row, a band) to this one.
    #[inline]
    pub fn add(&mut self, o: &Sums) {
        self.n += o.n;
        self.sa += o.sa;
        self.sb += o.sb;
        self.saa += o.saa;
        self.sbb += o.sbb;
        self.cross += o.cross;
    }

    /// The metric's score; `offset` is the `c` subtracted from both images.
    ///
    /// Degenerate patches get a defined score rather than NaN: for cosine a
    /// patch of zeros, for NCC a patch without variance (a constant image),
    /// scores 0, "no evidence of similarity". An alignment of a constant image
    /// therefore sees a flat surface and, by the tie rule, returns (0, 0).
    pub fn score(&self, metric: Metric, offset: f64) -> f64 {
        let n = self.n;
        if n <= 0.0 {
            return f64::NAN;
        }
        let (fa, fb) = self.floor;
        match metric {
            Metric::Ssd => self.cross.max(0.0).sqrt(),
            Metric::Cosine => {
                // Undo the offset: a = a' + c.
                let c = offset;
                let sab = self.cross + c * (self.sa + self.sb) + n * c * c;
                let (saa, sbb) = self.squares(metric, offset);
                normalised(sab, above(saa, fa), above(sbb, fb))
            }
            Metric::Ncc => {
                // Mean-free sums are offset-free already.
                let sab = self.cross - self.sa * self.sb / n;
                let saa = centred(self.saa, self.sa, n, fa);
                let sbb = centred(self.sbb, self.sb, n, fb);
                normalised(sab, saa, sbb)
            }
        }
    }

    /// The sums of squares of `a` and `b` the metric's formula reads: with
    /// the offset undone for cosine, offset-free for the others.
    pub fn squares(&self, metric: Metric, offset: f64) -> (f64, f64) {
        let (c, n) = (offset, self.n);
        match metric {
            Metric::Cosine => (
                self.saa + 2.0 * c * self.sa + n * c * c,
                self.sbb + 2.0 * c * self.sb + n * c * c,
            ),
            Metric::Ssd | Metric::Ncc => (self.saa, self.sbb),
        }
    }
}

/// Relative size under which a sum of squares counts as zero: the rounding
/// left by subtracting `n * mean^2` from a sum of squares accumulated in `f64`
/// over up to ~10^7 `f32` samples stays below 1e-9 of the raw sum, while a
/// real image's variance is never that small next to its mean square (16-bit
/// quantisation alone leaves ~1e-10 only for a patch of one level).
const DEGENERATE: f64 = 1e-9;

/// `sab / sqrt(saa sbb)`, clamped to [-1, 1]; 0 when either norm vanishes.
fn normalised(sab: f64, saa: f64, sbb: f64) -> f64 {
    if saa <= 0.0 || sbb <= 0.0 {
        return 0.0;
    }
    let r = sab / (saa.sqrt() * sbb.sqrt());
    r.clamp(-1.0, 1.0)
}

/// The mean-free sum of squares `saa - sa^2 / n`, or 0 when it is rounding
/// noise next to `saa` or `floor` (a constant patch) so that NCC then takes
/// its defined value 0.
fn centred(saa: f64, sa: f64, n: f64, floor: f64) -> f64 {
    above(saa - sa * sa / n, saa.max(floor))
}

/// `s`, or 0 when it is rounding noise next to `floor`.
fn above(s: f64, floor: f64) -> f64 {
    if s <= DEGENERATE * floor {
        0.0
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sums(a: &[f64], b: &[f64], metric: Metric) -> Sums {
        let mut s = Sums::default();
        for (&x, &y) in a.iter().zip(b) {
            s.n += 1.0;
            s.sa += x;
            s.sb += y;
            s.saa += x * x;
            s.sbb += y * y;
            s.cross += if metric == Metric::Ssd {
                (x - y) * (x - y)
            } else {
                x * y
            };
        }
        s
    }

    #[test]
    fn hand_computed_scores() {
        // a = (1, 2, 3), b = (2, 4, 7): sum (a-b)^2 = 1 + 4 + 16 = 21.
        let (a, b) = ([1.0, 2.0, 3.0], [2.0, 4.0, 7.0]);
        let ssd = sums(&a, &b, Metric::Ssd).score(Metric::Ssd, 0.0);
        assert!((ssd - 21f64.sqrt()).abs() < 1e-12);
        // a.b = 2 + 8 + 21 = 31, |a|^2 = 14, |b|^2 = 69.
        let cos = sums(&a, &b, Metric::Cosine).score(Metric::Cosine, 0.0);
        assert!((cos - 31.0 / (14f64 * 69.0).sqrt()).abs() < 1e-12);
        // Mean-free a = (-1, 0, 1), b = (-7/3, -1/3, 8/3): 5 / sqrt(2 * 114/9).
        let ncc = sums(&a, &b, Metric::Ncc).score(Metric::Ncc, 0.0);
        assert!((ncc - 5.0 / (2.0 * 114.0 / 9.0f64).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn cosine_undoes_the_offset() {
        let (a, b) = ([1.0, 2.0, 3.0], [2.0, 4.0, 7.0]);
        let c = 10.0;
        let (a2, b2): (Vec<f64>, Vec<f64>) = (
            a.iter().map(|v| v - c).collect(),
            b.iter().map(|v| v - c).collect(),
        );
        let direct = sums(&a, &b, Metric::Cosine).score(Metric::Cosine, 0.0);
        let shifted = sums(&a2, &b2, Metric::Cosine).score(Metric::Cosine, c);
        assert!((direct - shifted).abs() < 1e-12);
    }

    #[test]
    fn constant_patches_score_zero_not_nan() {
        let s = sums(&[3.0; 4], &[1.0, 2.0, 3.0, 4.0], Metric::Ncc);
        assert_eq!(s.score(Metric::Ncc, 0.0), 0.0);
        let z = sums(&[0.0; 4], &[1.0; 4], Metric::Cosine);
        assert_eq!(z.score(Metric::Cosine, 0.0), 0.0);
    }

    #[test]
    fn parse_rejects_unknown_names() {
        assert_eq!(Metric::parse("ncc").unwrap(), Metric::Ncc);
        let err = Metric::parse("mse").unwrap_err().to_string();
        assert!(err.contains("\"mse\"") && err.contains("\"ssd\""), "{err}");
    }
}

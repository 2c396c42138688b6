//! Characteristic curves: density as a function of log exposure.
//!
//! A curve is sampled at uniform steps of `log10 H` and read by linear
//! interpolation, held flat beyond its ends (below the toe the film shows its
//! fog, above the shoulder its maximum density). Uniform steps make a lookup
//! one multiply, which matters at 24 MP x 3 layers.

use super::fastmath::LANES;
use crate::error::Result;
use crate::invalid;

/// `D(log10 H)` sampled at `start + k step`, `k = 0..density.len()`.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    start: f64,
    step: f64,
    /// `1 / step` and `-start / step` in f32: [`Curve::eval`] is one
    /// multiply-add where a division in f64 would not vectorise.
    scale: f32,
    shift: f32,
    density: Vec<f32>,
}

impl Curve {
    /// A curve from its samples.
    ///
    /// # Errors
    /// [`crate::CoreError::InvalidArgument`] unless there are >= 2 samples, `start`
    /// is finite, `step` > 0, and the densities are finite, >= 0 and strictly
    /// monotone (rising for a negative, falling for a reversal film): a flat
    /// or wiggling stretch would map two exposures to one density.
    pub fn new(start: f64, step: f64, density: &[f64]) -> Result<Self> {
        if density.len() < 2 || !start.is_finite() || !(step.is_finite() && step > 0.0) {
            return Err(invalid!(
                "a curve needs >= 2 samples, a finite start and a step > 0, got {} samples, \
                 start {start}, step {step}",
                density.len()
            ));
        }
        if let Some(i) = density.iter().position(|d| !(d.is_finite() && *d >= 0.0)) {
            return Err(invalid!(
                "curve densities must be finite and >= 0, sample {i} is {}",
                density[i]
            ));
        }
        let rising = density[1] > density[0];
        if let Some(i) = density
            .windows(2)
            .position(|p| (p[1] > p[0]) != rising || p[1] == p[0])
        {
            return Err(invalid!(
                "a characteristic curve must be strictly monotone; it {} from sample 0 to 1 \
                 but not from sample {i} ({}) to {} ({})",
                if rising { "rises" } else { "falls" },
                density[i],
                i + 1,
                density[i + 1]
            ));
        }
        Ok(Self::sampled(
            start,
            step,
            density.iter().map(|&d| d as f32).collect(),
        ))
    }

    fn sampled(start: f64, step: f64, density: Vec<f32>) -> Self {
        Self {
            start,
            step,
            scale: (1.0 / step) as f32,
            shift: (-start / step) as f32,
            density,
        }
    }

    /// The density at log exposure `x`; NaN and -inf (zero exposure) give
    /// the first sample.
    pub fn eval(&self, x: f32) -> f32 {
        let last = self.density.len() - 1;
        let (i, f) = locate(x, self.scale, self.shift, last as f32, last as i32 - 1);
        let (lo, hi) = (self.density[i], self.density[i + 1]);
        lo + f * (hi - lo)
    }

    /// The smallest density of the curve: its fog (negative) or its
    /// maximum exposure's density (reversal).
    pub fn min_density(&self) -> f32 {
        self.density[0].min(self.density[self.density.len() - 1])
    }

    /// The log exposure of sample `k`.
    fn at(&self, k: usize) -> f64 {
        self.start + k as f64 * self.step
    }

    /// The curve a layer must follow so that, with its log exposure lowered
    /// by `inhibition(x)` (the DIR couplers' share of what a neutral wedge
    /// at log exposure `x` developed), it still gives `D(x)`.
    ///
    /// With `u(x) = x - inhibition(x)` the corrected curve is
    /// `C(u(x)) = D(x)`: sampled at (at most) the same step from `u(start)` to
    /// `u(end)` by inverting `u` piecewise linearly between the samples.
    ///
    /// # Errors
    /// [`crate::CoreError::InvalidArgument`] when `u` is not strictly increasing on
    /// the curve's samples (the couplers inhibit so strongly that more light
    /// develops less dye: no curve can compensate that).
    pub fn pre_corrected(&self, inhibition: impl Fn(f64) -> f64) -> Result<Self> {
        let u: Vec<f64> = (0..self.density.len())
            .map(|k| self.at(k) - inhibition(self.at(k)))
            .collect();
        if let Some(k) = u.windows(2).position(|p| p[1] <= p[0]) {
            return Err(invalid!(
                "the DIR couplers are too strong: the inhibited log exposure falls from {:.4} to \
                 {:.4} between log exposures {:.3} and {:.3}; lower the coupler matrix",
                u[k],
                u[k + 1],
                self.at(k),
                self.at(k + 1)
            ));
        }
        let (first, last) = (u[0], u[u.len() - 1]);
        // At most the stated step, and a whole number of steps from `u(start)`
        // to `u(end)`, so that the last sample lands on `u(end)` exactly.
        let samples = ((last - first) / self.step).ceil() as usize + 1;
        let step = (last - first) / (samples - 1) as f64;
        let mut k = 0;
        let density: Vec<f32> = (0..samples)
            .map(|j| {
                let t = first + j as f64 * step;
                while k + 2 < u.len() && u[k + 1] < t {
                    k += 1;
                }
                let f = ((t - u[k]) / (u[k + 1] - u[k])).clamp(0.0, 1.0);
                let (d0, d1) = (self.density[k], self.density[k + 1]);
                f64::from(d0) + f * f64::from(d1 - d0)
            })
            .map(|d| d as f32)
            .collect();
        // Not re-checked as strictly monotone: two corrected samples may
        // round to one f32 where the stated curve is nearly flat.
        Ok(Self::sampled(first, step, density))
    }
}

/// The sample `i` below log exposure `x` and the fraction `f` of the step
/// from it to `i + 1`, on a curve of samples `0..=last` (`top = last - 1`
/// as an integer, `scale` and `shift` as in [`Curve`]), held at the ends.
#[inline(always)]
fn locate(x: f32, scale: f32, shift: f32, last: f32, top: i32) -> (usize, f32) {
    // The sample index in f32: for curves of < 2^12 samples its rounding
    // moves `x` by < 3e-4 of a step, a density error below 3e-4 of one
    // step's rise (~1e-6 on the shipped curves).
    let t = x * scale + shift;
    // `max` maps NaN to 0 too; then the index is in 0..last.
    let t = t.max(0.0).min(last);
    // An i32 conversion lets a loop of lookups compile to packed
    // conversions (a usize conversion would not vectorise).
    let i = (t as i32).max(0).min(top);
    (i as usize, t - i as f32)
}

/// `f` of each layer's curve at every position of a block of [`LANES`]
/// pixels: position `k` holds layer `k mod n`.
fn per_lane<T>(curves: &[Curve], f: impl Fn(&Curve) -> T) -> Vec<T> {
    (0..LANES).flat_map(|_| curves.iter().map(&f)).collect()
}

/// The curves of an emulsion's `n` layers, read over rows of interleaved
/// layers (`n` samples per pixel) in place.
///
/// One curve per register does not fit interleaved layers, and taking them
/// apart into planes and back cost two scalar stores per sample, more than
/// the lookups themselves. So a block of [`LANES`] pixels is read as it
/// lies, each of its `8 n` positions with its own layer's parameters (the
/// pattern repeats from block to block); the curves share one table of
/// `(density, rise to the next sample)` pairs, one 8-byte read per lookup.
/// Each density is `lo + f rise`, `rise = hi - lo` rounded as
/// [`Curve::eval`] rounds it: the same bits.
#[derive(Debug, Clone)]
pub struct LayerCurves {
    curves: Vec<Curve>,
    /// Per position of a block, the `scale`, `shift`, `last` and first
    /// table entry of its layer's curve, and its minimum density.
    scale: Vec<f32>,
    shift: Vec<f32>,
    last: Vec<f32>,
    top: Vec<i32>,
    first: Vec<u32>,
    min: Vec<f32>,
    /// 0 at every position: [`LayerCurves::apply`] subtracts nothing.
    zero: Vec<f32>,
    table: Vec<[f32; 2]>,
}

impl LayerCurves {
    /// The curves of layers `0..curves.len()`, in that order.
    pub fn new(curves: Vec<Curve>) -> Self {
        let mut first = Vec::with_capacity(curves.len());
        let mut table = Vec::new();
        for c in &curves {
            first.push(table.len() as u32);
            table.extend(c.density.windows(2).map(|p| [p[0], p[1] - p[0]]));
        }
        Self {
            scale: per_lane(&curves, |c| c.scale),
            shift: per_lane(&curves, |c| c.shift),
            last: per_lane(&curves, |c| (c.density.len() - 1) as f32),
            top: per_lane(&curves, |c| c.density.len() as i32 - 2),
            first: (0..LANES).flat_map(|_| first.iter().copied()).collect(),
            min: per_lane(&curves, Curve::min_density),
            zero: per_lane(&curves, |_| 0.0),
            table,
            curves,
        }
    }

    /// The curves, one per layer.
    pub fn curves(&self) -> &[Curve] {
        &self.curves
    }

    /// Number of layers.
    pub fn layers(&self) -> usize {
        self.curves.len()
    }

    /// Log exposures to densities over a row of interleaved layers, in
    /// place.
    #[inline(always)]
    pub fn apply(&self, row: &mut [f32]) {
        self.apply_less(row, &self.zero);
    }

    /// Log exposures to each layer's density above its curve's minimum (a
    /// DIR donor's development), over a row of interleaved layers, in place.
    #[inline(always)]
    pub fn apply_above_min(&self, row: &mut [f32]) {
        self.apply_less(row, &self.min);
    }

    /// `row[k] = D(row[k]) - less[k mod 8 n]`, block by block.
    #[inline(always)]
    fn apply_less(&self, row: &mut [f32], less: &[f32]) {
        for block in row.chunks_mut(self.scale.len()) {
            let lanes = self.scale.iter().zip(&self.shift).zip(&self.last);
            let more = self.top.iter().zip(&self.first).zip(less);
            for (v, (((scale, shift), last), ((top, first), less))) in
                block.iter_mut().zip(lanes.zip(more))
            {
                let (i, f) = locate(*v, *scale, *shift, *last, *top);
                // SAFETY: `i <= top = last - 1`, and the `last` pairs of this
                // curve start at `first`.
                let [lo, rise] = unsafe { *self.table.get_unchecked(*first as usize + i) };
                *v = lo + f * rise - less;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp() -> Curve {
        // D = 0.1 + 0.5 (x + 2) on x = -2..2 in steps of 0.5.
        let d: Vec<f64> = (0..9).map(|k| 0.1 + 0.25 * k as f64).collect();
        Curve::new(-2.0, 0.5, &d).unwrap()
    }

    #[test]
    fn eval_interpolates_and_holds_the_ends() {
        let c = ramp();
        assert!((c.eval(0.0) - 1.1).abs() < 1e-6);
        assert!((c.eval(0.25) - 1.225).abs() < 1e-6);
        assert_eq!(c.eval(-5.0), 0.1);
        assert_eq!(c.eval(f32::NEG_INFINITY), 0.1);
        assert_eq!(c.eval(f32::NAN), 0.1);
        assert_eq!(c.eval(9.0), 2.1);
        assert_eq!(c.min_density(), 0.1);
    }

    #[test]
    fn layer_curves_give_each_layer_the_bits_of_its_curve() {
        let falling: Vec<f64> = (0..13).map(|k| 3.0 - 0.2 * k as f64).collect();
        let curves = vec![ramp(), Curve::new(-1.0, 0.25, &falling).unwrap()];
        let layers = LayerCurves::new(curves.clone());
        // 11 pixels: a whole block of 8 and a short one; values inside,
        // between and beyond the samples, and the zero exposure's -inf.
        let x: Vec<f32> = (0..22)
            .map(|k| match k {
                3 => f32::NEG_INFINITY,
                8 => f32::NAN,
                _ => -3.0 + 0.37 * k as f32,
            })
            .collect();
        let (mut densities, mut above) = (x.clone(), x.clone());
        layers.apply(&mut densities);
        layers.apply_above_min(&mut above);
        for (k, v) in x.iter().enumerate() {
            let c = &curves[k % 2];
            assert_eq!(densities[k].to_bits(), c.eval(*v).to_bits(), "{k}");
            assert_eq!(above[k], c.eval(*v) - c.min_density(), "{k}");
        }
    }

    #[test]
    fn bad_curves_are_refused_with_the_sample() {
        let flat = Curve::new(0.0, 0.1, &[0.1, 0.2, 0.2, 0.3]).unwrap_err();
        assert!(flat.to_string().contains("sample 1"), "{flat}");
        let wiggle = Curve::new(0.0, 0.1, &[0.1, 0.2, 0.15]).unwrap_err();
        assert!(wiggle.to_string().contains("rises"), "{wiggle}");
        let neg = Curve::new(0.0, 0.1, &[-0.1, 0.2]).unwrap_err();
        assert!(neg.to_string().contains(">= 0"), "{neg}");
        assert!(Curve::new(0.0, 0.0, &[0.1, 0.2]).is_err());
        assert!(Curve::new(0.0, 0.1, &[0.3, 0.2, 0.1]).is_ok());
    }

    #[test]
    fn no_inhibition_gives_the_curve_back_exactly() {
        let c = ramp();
        assert_eq!(c.pre_corrected(|_| 0.0).unwrap(), c);
    }

    #[test]
    fn the_corrected_curve_undoes_the_inhibition() {
        let c = ramp();
        let a = 0.3;
        let pre = c
            .pre_corrected(|x| a * f64::from(c.eval(x as f32)))
            .unwrap();
        for k in 0..40 {
            let x = -2.5 + 0.125 * k as f64;
            let inhibited = x - a * f64::from(c.eval(x as f32));
            let got = pre.eval(inhibited as f32);
            assert!((got - c.eval(x as f32)).abs() < 1e-5, "{x}: {got}");
        }
    }

    #[test]
    fn too_strong_couplers_are_refused() {
        let c = ramp();
        let err = c
            .pre_corrected(|x| 3.0 * f64::from(c.eval(x as f32)))
            .unwrap_err();
        assert!(err.to_string().contains("too strong"), "{err}");
    }
}

//! Synthetic refocusing of a light field by shift-and-add (Ng et al. 2005,
//! "Light field photography with a hand-held plenoptic camera").
//!
//! # Model
//! A light field here is a `(U, V)` grid of sub-aperture views, each an
//! `(H, W, C)` image, taken by pinhole cameras on a regular grid in the
//! aperture plane with parallel optical axes: view `(u, v)` sits
//! `(u - u_c, v - v_c)` grid steps below and right of the centre
//! `(u_c, v_c) = ((U - 1) / 2, (V - 1) / 2)` (array-axis order, as a shift
//! `(dy, dx)` in CONVENTIONS.md). A point at depth `Z` then appears in view
//! `(u, v)` displaced by `-d (u - u_c, v - v_c)` pixels from where the central
//! view sees it, with the disparity `d = baseline * f / Z` (pixels per view
//! step) linear in inverse depth.
//!
//! Refocusing at `alpha` (pixels per view step) shifts every view by
//! `+alpha (u - u_c, v - v_c)` and averages:
//! `out(y, x) = mean_(u,v) L_uv(y - alpha (u - u_c), x - alpha (v - v_c))`.
//! Points with `d = alpha` line up in every view and come out as sharp as in
//! one view; others spread over a copy of the aperture scaled by
//! `|d - alpha|`, so their blur grows with the disparity difference and
//! shrinks with the set of views averaged (the synthetic aperture).
//! `alpha = 0` is the plain mean of the views.
//!
//! Sub-pixel shifts are bilinear; samples outside a view are mirrored
//! (`image::mirror`), so the frame keeps its brightness at the borders.
//!
//! # Determinism
//! Each output row is the sum over the selected views in one fixed order
//! (row-major in the grid) of that row's interpolated samples, computed by
//! the same sequential code whichever rayon task runs it, so results are
//! bit-identical for any thread count.

use crate::error::{CoreError, Result};
use crate::image::{mirror, ImageView, Sample};
use crate::invalid;
use crate::parallel::{for_each_band, ROWS_PER_TASK};

/// A read-only `(U, V, H, W, C)` light field, C-contiguous.
#[derive(Debug, Clone, Copy)]
pub struct LightField<'a, T> {
    data: &'a [T],
    grid: (usize, usize),
    height: usize,
    width: usize,
    channels: usize,
}

impl<'a, T: Copy> LightField<'a, T> {
    /// Wraps `data` as a `grid.0 x grid.1` grid of `height x width x
    /// channels` views.
    ///
    /// # Errors
    /// [`CoreError::Shape`] when a dimension is zero or `data` does not hold
    /// exactly that many samples.
    pub fn new(
        data: &'a [T],
        grid: (usize, usize),
        height: usize,
        width: usize,
        channels: usize,
    ) -> Result<Self> {
        let dims = [grid.0, grid.1, height, width, channels];
        if dims.contains(&0) {
            return Err(CoreError::Shape(format!(
                "light field must be non-empty, got shape (U, V, H, W, C) = {dims:?}"
            )));
        }
        let needed = dims.iter().try_fold(1usize, |n, &d| n.checked_mul(d));
        if needed != Some(data.len()) {
            let needed = needed.map_or("more than memory holds".into(), |n| n.to_string());
            return Err(CoreError::Shape(format!(
                "light field buffer holds {} samples, shape (U, V, H, W, C) = {dims:?} needs {needed}",
                data.len()
            )));
        }
        Ok(Self {
            data,
            grid,
            height,
            width,
            channels,
        })
    }

    /// Number of views, `U * V`.
    pub fn views(&self) -> usize {
        self.grid.0 * self.grid.1
    }

    /// Samples in one view, `H * W * C`.
    pub fn view_len(&self) -> usize {
        self.height * self.width * self.channels
    }

    /// View number `i` (row-major in the grid) as an image.
    fn view(&self, i: usize) -> ImageView<'a, T> {
        let len = self.view_len();
        ImageView::contiguous(
            &self.data[i * len..(i + 1) * len],
            self.width,
            self.height,
            self.channels,
        )
        .expect("view dimensions were checked in LightField::new")
    }
}

/// A sampling offset along one axis: the integer part `k` and the fraction
/// `f`, so the value at `i + offset` is `(1 - f) s[i + k] + f s[i + k + 1]`.
#[derive(Debug, Clone, Copy)]
struct Shift {
    k: isize,
    f: f32,
}

impl Shift {
    /// The offset `offset` along an axis of `n` samples, with `k` reduced
    /// into `[-(n - 1), n - 1)`.
    ///
    /// Mirroring is periodic with period `2 (n - 1)`, so the reduction
    /// changes no sample and keeps the index arithmetic in range for any
    /// finite shift, however large; `rem_euclid` of an integral float is
    /// exact. Offsets already in range (every useful one) are kept as they
    /// are, so the contiguous interior run of [`add_shifted_row`] keeps its
    /// length.
    fn new(offset: f64, n: usize) -> Self {
        let whole = offset.floor();
        let period = (2 * n.saturating_sub(1)).max(1) as f64;
        let mut k = whole.rem_euclid(period);
        if k >= period / 2.0 {
            k -= period;
        }
        Self {
            k: k as isize,
            f: (offset - whole) as f32,
        }
    }
}

/// Where every view is sampled for one refocused frame.
///
/// The shift of view `(u, v)` is `alpha (u - u_c, v - v_c)`: its row part
/// depends on `u` only and its column part on `v` only. Shifts are linear
/// and commute, so the frame is `sum_v shift_x(v) [sum_u shift_y(u) L_uv]`:
/// each grid column's views are shifted vertically and summed into one row
/// buffer, which is then shifted horizontally once. That is 2 taps per view
/// and sample plus 2 per grid column, instead of 4 per view.
#[derive(Debug, Clone)]
struct Frame {
    /// Vertical sampling offset of grid row `u`.
    rows: Vec<Shift>,
    /// Horizontal sampling offset of grid column `v`.
    cols: Vec<Shift>,
}

impl Frame {
    /// The offsets of every grid row and column for refocusing at `alpha`.
    /// A view shifted by `+alpha * offset` is sampled at `-alpha * offset`.
    fn new<T: Copy>(lf: &LightField<'_, T>, alpha: f64) -> Result<Self> {
        let axis = |count: usize, n: usize| -> Result<Vec<Shift>> {
            let centre = (count as f64 - 1.0) / 2.0;
            (0..count)
                .map(|i| {
                    let offset = -alpha * (i as f64 - centre);
                    if offset.is_finite() {
                        Ok(Shift::new(offset, n))
                    } else {
                        Err(invalid!(
                            "alpha = {alpha} shifts grid line {i} by a non-finite amount"
                        ))
                    }
                })
                .collect()
        };
        Ok(Self {
            rows: axis(lf.grid.0, lf.height)?,
            cols: axis(lf.grid.1, lf.width)?,
        })
    }
}

/// `acc[i] += wa a[i] + wb b[i]` over `acc`: the one arithmetic step of the
/// kernel, used for the vertical blend of two source rows, for the
/// horizontal blend of a row with itself one pixel on (interior runs, so it
/// vectorises) and for single mirrored border pixels.
#[inline(always)]
fn add_blend<T: Sample>(acc: &mut [f32], a: &[T], b: &[T], wa: f32, wb: f32) {
    let n = acc.len();
    let (a, b) = (&a[..n], &b[..n]);
    for i in 0..n {
        acc[i] += wa * a[i].to_f32() + wb * b[i].to_f32();
    }
}

/// Adds `row` (`width` pixels of `c` samples) sampled at `x + shift` to
/// `acc`.
///
/// Output columns whose two source columns both lie inside the row form one
/// contiguous run; the few columns at either end are mirrored one by one.
#[inline(always)]
fn add_shifted_row(acc: &mut [f32], row: &[f32], shift: Shift, width: usize, c: usize) {
    let (k, wb) = (shift.k, shift.f);
    let wa = 1.0 - wb;
    let w = width as isize;
    let lo = (-k).clamp(0, w) as usize;
    let hi = (w - 1 - k).clamp(lo as isize, w) as usize;
    for x in (0..lo).chain(hi..width) {
        let x0 = mirror(x as isize + k, width) * c;
        let x1 = mirror(x as isize + k + 1, width) * c;
        add_blend(&mut acc[x * c..(x + 1) * c], &row[x0..], &row[x1..], wa, wb);
    }
    if lo < hi {
        let s = (lo as isize + k) as usize * c;
        add_blend(&mut acc[lo * c..hi * c], &row[s..], &row[s + c..], wa, wb);
    }
}

/// Buffers of one rayon task, a band of rows each: the frame rows being
/// summed and one grid column's vertically shifted sum.
struct Buffers {
    acc: Vec<f32>,
    column: Vec<f32>,
}

/// A validated focal-stack job: the light field, one [`Frame`] per alpha and
/// the views averaged.
struct Stack<'a, T> {
    lf: LightField<'a, T>,
    frames: Vec<Frame>,
    aperture: &'a [bool],
}

impl<T: Sample> Stack<'_, T> {
    /// Consecutive rows of one frame, from row `first` of the stack (row
    /// `first % H` of frame `first / H`), into `out`: the mean of the shifted
    /// views selected by the aperture.
    ///
    /// Views are the outer loop and the band's rows the inner one, so each
    /// view is read as one run of consecutive rows. Reading one row of
    /// each of 81 views per output row instead left the loads waiting on
    /// memory (81 streams defeat the hardware prefetcher): 40 % of the time
    /// sat on one load. Each output sample still sums its views in the same
    /// order, so the result does not depend on how rows are banded.
    #[inline(always)]
    fn run(&self, first: usize, buf: &mut Buffers, out: &mut [T]) {
        let lf = &self.lf;
        let (h, gu, gv) = (lf.height, lf.grid.0, lf.grid.1);
        let row_len = lf.width * lf.channels;
        let (frame, y0) = (&self.frames[first / h], first % h);
        let acc = &mut buf.acc[..out.len()];
        let column = &mut buf.column[..out.len()];
        acc.fill(0.0);
        let mut count = 0usize;
        for (v, &col_shift) in frame.cols.iter().enumerate() {
            column.fill(0.0);
            let mut any = false;
            for u in (0..gu).filter(|&u| self.aperture[u * gv + v]) {
                let view = lf.view(u * gv + v);
                let Shift { k, f } = frame.rows[u];
                for (j, col) in column.chunks_mut(row_len).enumerate() {
                    let y = (y0 + j) as isize + k;
                    let (a, b) = (view.row(mirror(y, h)), view.row(mirror(y + 1, h)));
                    add_blend(col, a, b, 1.0 - f, f);
                }
                count += 1;
                any = true;
            }
            if any {
                for (a, c) in acc.chunks_mut(row_len).zip(column.chunks(row_len)) {
                    add_shifted_row(a, c, col_shift, lf.width, lf.channels);
                }
            }
        }
        let scale = 1.0 / count as f32;
        for v in acc.iter_mut() {
            *v *= scale;
        }
        for (o, a) in out.chunks_mut(row_len).zip(acc.chunks(row_len)) {
            T::from_f32_row(o, a);
        }
    }

    /// [`Stack::run`] compiled for AVX2, twice the vector width of the
    /// x86-64 baseline (SSE2) the crate is built for. The arithmetic is the
    /// same sequence of IEEE operations (no FMA contraction), so both paths
    /// give the same bits.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(&self, first: usize, buf: &mut Buffers, out: &mut [T]) {
        self.run(first, buf, out);
    }

    /// [`Stack::run`] through the widest vector unit the CPU has.
    fn run_dispatch(&self, first: usize, buf: &mut Buffers, out: &mut [T]) {
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::has_avx2() {
            // SAFETY: AVX2 support was detected just above.
            unsafe { self.run_avx2(first, buf, out) };
            return;
        }
        self.run(first, buf, out);
    }

    /// A band of rows from row `first` of the stack, split where it
    /// crosses from one frame into the next.
    fn band(&self, first: usize, rows: &mut [T]) {
        let row_len = self.lf.width * self.lf.channels;
        let mut buf = Buffers {
            acc: vec![0.0; rows.len()],
            column: vec![0.0; rows.len()],
        };
        let (mut r, mut rest) = (first, rows);
        while !rest.is_empty() {
            let n = (rest.len() / row_len).min(self.lf.height - r % self.lf.height);
            let (part, tail) = std::mem::take(&mut rest).split_at_mut(n * row_len);
            self.run_dispatch(r, &mut buf, part);
            (r, rest) = (r + n, tail);
        }
    }
}

/// Refocuses `lf` at every disparity of `alphas` into `out`, an
/// `(N, H, W, C)` focal stack.
///
/// `alphas[n]` is in pixels per view step (see the module docs for the sign);
/// `aperture` selects the views averaged, one flag per view in grid order
/// (`U * V` flags). Integer outputs are rounded half up and clamped.
///
/// # Errors
/// [`CoreError::Shape`] when `aperture` or `out` has the wrong length;
/// [`CoreError::InvalidArgument`] when `alphas` is empty, an alpha is not
/// finite (or shifts a view by a non-finite amount), or `aperture` selects no
/// view.
pub fn focal_stack<T: Sample>(
    lf: LightField<'_, T>,
    alphas: &[f64],
    aperture: &[bool],
    out: &mut [T],
) -> Result<()> {
    if aperture.len() != lf.views() {
        return Err(CoreError::Shape(format!(
            "aperture must have one flag per view, {} x {} = {}, got {}",
            lf.grid.0,
            lf.grid.1,
            lf.views(),
            aperture.len()
        )));
    }
    if !aperture.contains(&true) {
        return Err(invalid!("aperture selects no view; select at least one"));
    }
    if alphas.is_empty() {
        return Err(invalid!(
            "alphas must hold at least one disparity, got none"
        ));
    }
    if let Some(bad) = alphas.iter().find(|a| !a.is_finite()) {
        return Err(invalid!("alpha must be finite, got {bad}"));
    }
    let frame_len = lf.view_len();
    if out.len() != alphas.len() * frame_len {
        return Err(CoreError::Shape(format!(
            "output holds {} samples, {} frames of {frame_len} need {}",
            out.len(),
            alphas.len(),
            alphas.len() * frame_len
        )));
    }
    let frames = alphas
        .iter()
        .map(|&alpha| Frame::new(&lf, alpha))
        .collect::<Result<_>>()?;
    let stack = Stack {
        lf,
        frames,
        aperture,
    };
    let row_len = lf.width * lf.channels;
    for_each_band(out, row_len, ROWS_PER_TASK, |first, rows| {
        stack.band(first, rows)
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3x3 grid of 6x7 two-channel views filled with distinct values.
    fn field() -> Vec<f32> {
        (0..9 * 6 * 7 * 2)
            .map(|i| ((i * 37) % 101) as f32)
            .collect()
    }

    /// Refocuses the 3x3 field `data` of [`field`] at `alpha` through
    /// `aperture`.
    fn refocus_field(data: &[f32], alpha: f64, aperture: &[bool; 9]) -> Result<Vec<f32>> {
        let lf = LightField::new(data, (3, 3), 6, 7, 2)?;
        let mut out = vec![0.0f32; lf.view_len()];
        focal_stack(lf, &[alpha], aperture, &mut out)?;
        Ok(out)
    }

    /// [`refocus_field`] through view `only` alone.
    fn through_one_view(data: &[f32], only: usize, alpha: f64) -> Vec<f32> {
        let mut aperture = [false; 9];
        aperture[only] = true;
        refocus_field(data, alpha, &aperture).unwrap()
    }

    #[test]
    fn alpha_zero_is_the_mean_of_the_views() {
        let data = field();
        let out = refocus_field(&data, 0.0, &[true; 9]).unwrap();
        for (i, &got) in out.iter().enumerate() {
            let mean = (0..9).map(|v| data[v * 84 + i]).sum::<f32>() / 9.0;
            assert!((got - mean).abs() < 1e-4, "{i}: {got} vs {mean}");
        }
    }

    #[test]
    fn integer_shift_moves_each_view_by_its_offset() {
        // Alpha = 2 with only the view right of the centre selected: the
        // output is that view moved right by 2 columns, mirrored at the left.
        let data = field();
        let out = through_one_view(&data, 5, 2.0);
        let view = ImageView::contiguous(&data[5 * 84..6 * 84], 7, 6, 2).unwrap();
        for y in 0..6 {
            for x in 0..7 {
                let src = mirror(x as isize - 2, 7);
                assert_eq!(out[(y * 7 + x) * 2 + 1], view.at(src, y, 1));
            }
        }
    }

    #[test]
    fn half_pixel_shift_averages_neighbours() {
        // One view below the centre at alpha = 0.5: rows move down by half a
        // row, so output row y is the mean of source rows y - 1 and y.
        let data = field();
        let out = through_one_view(&data, 7, 0.5);
        let view = ImageView::contiguous(&data[7 * 84..8 * 84], 7, 6, 2).unwrap();
        let expect = 0.5 * (view.at(3, 1, 0) + view.at(3, 2, 0));
        assert!((out[(2 * 7 + 3) * 2] - expect).abs() < 1e-4);
    }

    #[test]
    fn huge_shifts_stay_in_range() {
        let data = field();
        let mut out = refocus_field(&data, 1e300, &[true; 9]).unwrap();
        assert!(out.iter().all(|v| v.is_finite()));
        // Views 1.5 steps from the centre of a 1x4 grid overflow f64.
        let row = LightField::new(&data[..4 * 84], (1, 4), 6, 7, 2).unwrap();
        let err = focal_stack(row, &[f64::MAX], &[true; 4], &mut out).unwrap_err();
        assert!(err.to_string().contains("non-finite"), "{err}");
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_path_gives_the_same_bits() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let data: Vec<u8> = (0..9 * 5 * 40 * 3)
            .map(|i| ((i * 53) % 256) as u8)
            .collect();
        let lf = LightField::new(&data, (3, 3), 5, 40, 3).unwrap();
        let mut aperture = [true; 9];
        aperture[0] = false;
        let stack = Stack {
            lf,
            frames: vec![Frame::new(&lf, 1.37).unwrap()],
            aperture: &aperture,
        };
        let mut buf = Buffers {
            acc: vec![0.0; 600],
            column: vec![0.0; 600],
        };
        let (mut plain, mut wide) = (vec![0u8; 600], vec![0u8; 600]);
        stack.run(0, &mut buf, &mut plain);
        // SAFETY: AVX2 support was detected above.
        unsafe { stack.run_avx2(0, &mut buf, &mut wide) };
        assert_eq!(plain, wide);
    }

    #[test]
    fn banding_does_not_change_the_result() {
        // Frames of 6 rows in bands of ROWS_PER_TASK = 8: bands straddle
        // frames; every row must equal the frame refocused on its own.
        let data = field();
        let lf = LightField::new(&data, (3, 3), 6, 7, 2).unwrap();
        let alphas = [0.3, -1.7, 2.2];
        let mut stack = vec![0.0f32; 3 * lf.view_len()];
        focal_stack(lf, &alphas, &[true; 9], &mut stack).unwrap();
        for (frame, &alpha) in stack.chunks(lf.view_len()).zip(&alphas) {
            assert_eq!(frame, refocus_field(&data, alpha, &[true; 9]).unwrap());
        }
    }

    #[test]
    fn bad_input_is_refused() {
        let data = field();
        assert!(LightField::new(&data, (3, 3), 6, 7, 3).is_err());
        assert!(LightField::new(&data[..0], (0, 3), 6, 7, 2).is_err());
        let lf = LightField::new(&data, (3, 3), 6, 7, 2).unwrap();
        let mut out = vec![0.0f32; lf.view_len()];
        let msg = |r: Result<()>| r.unwrap_err().to_string();
        assert!(msg(focal_stack(lf, &[0.0], &[false; 9], &mut out)).contains("no view"));
        assert!(msg(focal_stack(lf, &[0.0], &[true; 8], &mut out)).contains("one flag"));
        assert!(msg(focal_stack(lf, &[f64::NAN], &[true; 9], &mut out)).contains("finite"));
        assert!(msg(focal_stack(lf, &[], &[true; 9], &mut out)).contains("at least one"));
        assert!(msg(focal_stack(lf, &[0.0, 1.0], &[true; 9], &mut out)).contains("frames"));
    }
}

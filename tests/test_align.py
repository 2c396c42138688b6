"""Three-colour alignment: metrics, exhaustive search, pyramid, plates, CLI."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import imgform_rs as ig
from conftest import assert_clash_refused, output_with_threads
from imgform_rs._png import write_png
from imgform_rs.align import FRAME_SEARCH, default_max_shift, frame_box
from imgform_rs.cli import main

ROOT = Path(__file__).resolve().parents[1]
METRICS = ["ssd", "cosine", "ncc"]
DTYPES = [np.uint8, np.uint16, np.float32]


def shared_file(rel: str) -> Path | None:
    """``../shared/<rel>`` next to the checkout (or next to a folder of
    worktrees above it), or None."""
    for base in (ROOT, *ROOT.parents):
        p = base.parent / "shared" / rel
        if p.is_file():
            return p
    return None


def smooth_field(seed: int, h: int, w: int, sigma: float = 1.5) -> np.ndarray:
    """White noise blurred by a Gaussian: smooth, not periodic, in [0, 1]."""
    r = math.ceil(3 * sigma)
    noise = np.random.default_rng(seed).standard_normal((h + 2 * r, w + 2 * r))
    t = np.arange(-r, r + 1)
    kern = np.exp(-0.5 * (t / sigma) ** 2)
    kern /= kern.sum()
    out = np.apply_along_axis(np.convolve, 0, noise, kern, mode="valid")
    out = np.apply_along_axis(np.convolve, 1, out, kern, mode="valid")
    assert out.shape == (h, w)
    out -= out.min()
    return out / out.max()


def as_dtype(field: np.ndarray, dtype) -> np.ndarray:
    if dtype == np.float32:
        return field.astype(np.float32)
    top = np.iinfo(dtype).max
    return np.floor(field * top + 0.5).astype(dtype)


def shifted_pair(seed, h, w, k, dy, dx, dtype=np.float32):
    """(reference, moving) with ``np.roll(moving, (dy, dx))`` landing moving on
    reference: both are windows of one larger field, so the moving image has
    real content (not fill) beyond the reference's frame."""
    big = as_dtype(smooth_field(seed, h + 2 * k, w + 2 * k), dtype)
    ref = big[k : k + h, k : k + w]
    mov = big[k + dy : k + dy + h, k + dx : k + dx + w]
    return np.ascontiguousarray(ref), np.ascontiguousarray(mov)


def reference_score(a: np.ndarray, b: np.ndarray, metric: str) -> float:
    """The lecture's equations 5-7 in float64, with the documented value 0
    for a patch without variance (NCC) or norm (cosine)."""
    a = a.astype(np.float64).ravel()
    b = b.astype(np.float64).ravel()
    if metric == "ssd":
        return float(np.sqrt(np.sum((a - b) ** 2)))
    if metric == "ncc":
        a, b = a - a.mean(), b - b.mean()
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    return 0.0 if na == 0 or nb == 0 else float(a @ b / (na * nb))


def brute_force_surface(ref, mov, k, metric, crop):
    """Every shift in [-k, k]^2 scored over the cropped window, no wrap-around."""
    h, w = ref.shape
    my, mx = math.floor(crop * h), math.floor(crop * w)
    out = np.empty((2 * k + 1, 2 * k + 1))
    for i, dy in enumerate(range(-k, k + 1)):
        for j, dx in enumerate(range(-k, k + 1)):
            y0, y1 = max(my, dy), min(h - my, h + dy)
            x0, x1 = max(mx, dx), min(w - mx, w + dx)
            a = ref[y0:y1, x0:x1]
            b = mov[y0 - dy : y1 - dy, x0 - dx : x1 - dx]
            out[i, j] = reference_score(a, b, metric)
    return out


shift_case = st.tuples(
    st.integers(0, 10_000),
    st.integers(-6, 6),
    st.integers(-6, 6),
    st.sampled_from(DTYPES),
)


# --- metrics ---------------------------------------------------------------


@given(seed=st.integers(0, 10_000), dtype=st.sampled_from(DTYPES))
def test_self_similarity(seed, dtype):
    a = as_dtype(smooth_field(seed, 20, 23), dtype)
    assert ig.similarity(a, a, "ssd") == 0.0
    assert ig.similarity(a, a, "cosine") == pytest.approx(1.0, abs=1e-6)
    assert ig.similarity(a, a, "ncc") == pytest.approx(1.0, abs=1e-6)


@given(seed=st.integers(0, 10_000), metric=st.sampled_from(METRICS))
def test_metrics_are_symmetric_and_match_the_equations(seed, metric):
    a = smooth_field(seed, 17, 19).astype(np.float32)
    b = smooth_field(seed + 1, 17, 19).astype(np.float32)
    ab, ba = ig.similarity(a, b, metric), ig.similarity(b, a, metric)
    assert ab == ba
    assert ab == pytest.approx(reference_score(a, b, metric), rel=1e-5, abs=1e-6)


@given(
    seed=st.integers(0, 10_000),
    mean=st.floats(1e3, 6.4e4),
    levels=st.floats(8, 64),
    metric=st.sampled_from(METRICS),
)
def test_metrics_keep_a_few_levels_of_structure_on_a_large_mean(seed, mean, levels, metric):
    """A dim 16-bit plate near white: its structure is a few levels on tens of
    thousands. Centred on mid-scale, the f32 sums lost it (NCC 1.0 for 0.91)."""
    a = np.round(mean + levels * smooth_field(seed, 40, 50)).astype(np.uint16)
    b = np.round(0.9 * mean + levels * smooth_field(seed + 1, 40, 50)).astype(np.uint16)
    want = reference_score(a, b, metric)
    assert ig.similarity(a, b, metric) == pytest.approx(want, rel=1e-4, abs=1e-5)
    floats = a.astype(np.float32) * 100  # floats far outside [0, 1]
    got = ig.similarity(floats, b.astype(np.float32) * 100, metric)
    assert got == pytest.approx(reference_score(floats, b * 100.0, metric), rel=1e-4, abs=1e-5)


@given(case=shift_case)
def test_ncc_finds_the_shift_of_a_faint_plate_on_a_large_mean(case):
    seed, dy, dx, _ = case
    ref, mov = shifted_pair(seed, 60, 70, 6, dy, dx)
    ref, mov = (np.round(60000 + 20 * p).astype(np.uint16) for p in (ref, mov))
    assert ig.align(ref, mov, max_shift=6, metric="ncc", pyramid=0).shift == (dy, dx)


def test_hand_computed_values():
    a = np.array([[1, 2, 3]], np.float32)
    b = np.array([[2, 4, 7]], np.float32)
    assert ig.similarity(a, b, "ssd") == pytest.approx(math.sqrt(21))
    assert ig.similarity(a, b, "cosine") == pytest.approx(31 / math.sqrt(14 * 69))
    assert ig.similarity(a, b, "ncc") == pytest.approx(5 / math.sqrt(2 * 114 / 9))


# --- the search --------------------------------------------------------------


@given(case=shift_case, metric=st.sampled_from(METRICS))
def test_every_metric_recovers_a_known_shift(case, metric):
    seed, dy, dx, dtype = case
    ref, mov = shifted_pair(seed, 40, 44, 6, dy, dx, dtype)
    got = ig.align(ref, mov, max_shift=6, metric=metric, pyramid=0)
    assert got.shift == (dy, dx)
    # Landing it: the rolled moving image equals the reference inside the overlap.
    rolled = np.roll(mov, (dy, dx), axis=(0, 1))
    inner = (slice(6, -6), slice(6, -6))
    np.testing.assert_array_equal(rolled[inner], ref[inner])


@given(
    case=shift_case,
    gain=st.floats(0.2, 5.0),
    bias=st.floats(-1.0, 1.0),
)
def test_ncc_recovers_the_shift_under_an_affine_intensity_change(case, gain, bias):
    seed, dy, dx, _ = case
    ref, mov = shifted_pair(seed, 40, 44, 6, dy, dx)
    changed = (gain * mov + bias).astype(np.float32)
    assert ig.align(ref, changed, max_shift=6, metric="ncc", pyramid=0).shift == (dy, dx)


@given(
    seed=st.integers(0, 10_000),
    metric=st.sampled_from(METRICS),
    k=st.integers(0, 4),
    crop=st.sampled_from([0.0, 0.1, 0.25]),
    dtype=st.sampled_from(DTYPES),
)
def test_exhaustive_search_equals_a_brute_force_reference(seed, metric, k, crop, dtype):
    ref = as_dtype(smooth_field(seed, 15, 18), dtype)
    mov = as_dtype(smooth_field(seed + 7, 15, 18), dtype)
    got = ig.align(ref, mov, max_shift=k, metric=metric, crop=crop, pyramid=0)
    want = brute_force_surface(ref, mov, k, metric, crop)
    assert got.surface_origin == (-k, -k)
    np.testing.assert_allclose(got.surface, want, rtol=1e-5, atol=1e-5)
    # The chosen shift is a best one of the reference surface (up to rounding).
    i, j = got.shift[0] + k, got.shift[1] + k
    best = want.min() if metric == "ssd" else want.max()
    assert want[i, j] == pytest.approx(best, rel=1e-5, abs=1e-5)


@settings(max_examples=30)
@given(
    seed=st.integers(0, 10_000),
    metric=st.sampled_from(["cosine", "ncc"]),
    k=st.integers(12, 16),
    crop=st.sampled_from([0.0, 0.1]),
    dtype=st.sampled_from(DTYPES),
)
def test_a_wide_search_scored_by_one_correlation_equals_the_brute_force_reference(
    seed, metric, k, crop, dtype
):
    # Searches this wide on images this large (625-1089 candidates, 120-150
    # rows) are scored for cosine and NCC through one FFT correlation, which
    # must give the direct sums; the Rust tests cover every overlap, down to
    # none, on the correlation itself.
    ref = as_dtype(smooth_field(seed, 120 + seed % 31, 150), dtype)
    mov = as_dtype(smooth_field(seed + 7, *ref.shape), dtype)
    got = ig.align(ref, mov, max_shift=k, metric=metric, crop=crop, pyramid=0)
    want = brute_force_surface(ref, mov, k, metric, crop)
    # The samples are f32 (centred); the sums, the transforms included, f64.
    np.testing.assert_allclose(got.surface, want, rtol=1e-6, atol=1e-7)


def test_pyramid_finds_a_large_shift_with_few_candidates_per_level():
    ref, mov = shifted_pair(3, 540, 520, 60, 47, -38)
    for features in ["intensity", "gradient"]:
        got = ig.align(ref, mov, max_shift=60, features=features)
        assert got.shift == (47, -38)
        assert len(got.levels) >= 3
        assert all(lv.candidates <= 17 * 17 for lv in got.levels)
        assert got.levels[-1].scale == 1
        assert got.surface.shape == (5, 5)
        oy, ox = got.surface_origin
        assert oy <= 47 <= oy + 4 and ox <= -38 <= ox + 4


def test_gradient_features_align_channels_with_inverted_brightness():
    """The "Emir" failure: a channel whose brightness is inverted, so raw
    intensities anti-correlate while edges still coincide."""
    ref, mov = shifted_pair(11, 96, 100, 8, 5, -3)
    inverted = (1.0 - mov).astype(np.float32)
    assert ig.align(ref, inverted, max_shift=8, features="gradient").shift == (5, -3)
    assert ig.align(ref, inverted, max_shift=8, metric="ssd").shift != (5, -3)


def periodic_field(seed: int, n: int = 256, sigma: float = 4.0):
    """``at(dy, dx)``: the middle of a smooth periodic field moved by a
    fractional shift exactly (a phase ramp of its spectrum)."""
    rng = np.random.default_rng(seed)
    fy, fx = np.meshgrid(np.fft.fftfreq(n), np.fft.fftfreq(n), indexing="ij")
    low = np.exp(-2 * (np.pi * sigma) ** 2 * (fx**2 + fy**2))
    spectrum = np.fft.fft2(rng.random((n, n))) * low

    def at(dy: float, dx: float) -> np.ndarray:
        img = np.fft.ifft2(spectrum * np.exp(2j * np.pi * (fy * dy + fx * dx))).real
        return img[48:-48, 48:-48].astype(np.float32)

    return at


@pytest.mark.parametrize("fraction", [0.1, 0.25, 0.4])
def test_subpixel_refinement(fraction):
    """Every metric's parabola lands near the fractional shift, and SSD's
    where the others' do: it went through SSD's distances (square roots), a
    V at the minimum, and pulled the shift towards the integer (2.166 for
    2.25, where NCC found 2.247)."""
    at = periodic_field(1)
    shift = (2 + fraction, -1 - fraction)
    got = {m: ig.align(at(0, 0), at(*shift), max_shift=5, subpixel=True, metric=m) for m in METRICS}
    for metric, found in got.items():
        np.testing.assert_allclose(found.shift, shift, atol=0.03, err_msg=metric)
        assert isinstance(found.shift[0], float)
    np.testing.assert_allclose(got["ssd"].shift, got["ncc"].shift, atol=0.005)


def test_results_do_not_depend_on_the_thread_count():
    code = """
    import sys, numpy as np, imgform_rs as ig
    rng = np.random.default_rng(5)
    big = rng.integers(0, 65535, (700, 650), dtype=np.uint16)
    ref, mov = big[30:630, 30:580], big[47:647, 9:559]
    for metric in ["ssd", "cosine", "ncc"]:
        for features in ["intensity", "gradient"]:
            got = ig.align(ref, mov, max_shift=30, metric=metric, features=features)
            sys.stdout.buffer.write(repr((got.shift, got.score)).encode())
            sys.stdout.buffer.write(got.surface.tobytes())
    got = ig.align(ref, mov, max_shift=8, pyramid=0, subpixel=True)
    sys.stdout.buffer.write(repr(got.shift).encode() + got.surface.tobytes())
    """
    one = output_with_threads(code, 1)
    assert one == output_with_threads(code, 2)
    assert b"(17, -21)" in one


def test_non_contiguous_and_fortran_ordered_inputs():
    ref, mov = shifted_pair(2, 60, 64, 6, 3, -2)
    assert ig.align(ref.T, mov.T, max_shift=6).shift == (-2, 3)
    assert ig.align(np.asfortranarray(ref), np.asfortranarray(mov), max_shift=6).shift == (3, -2)
    wide_ref, wide_mov = shifted_pair(2, 60, 128, 6, 3, -4)
    assert ig.align(wide_ref[:, ::2], wide_mov[:, ::2], max_shift=6).shift == (3, -2)


# --- bad input ---------------------------------------------------------------


def test_bad_input_raises_clear_errors():
    a = np.zeros((30, 30), np.float32) + smooth_field(0, 30, 30).astype(np.float32)
    with pytest.raises(ValueError, match="same shape"):
        ig.align(a, a[:, :29])
    with pytest.raises(ValueError, match="same shape"):
        ig.similarity(a, a[:29])
    for k in (-1, 30, 31):
        with pytest.raises(ValueError, match="max_shift"):
            ig.align(a, a, max_shift=k)
    with pytest.raises(ValueError, match="too small"):
        ig.align(a[:6, :6], a[:6, :6], max_shift=5, crop=0.1)
    huge = a.astype(np.float64)
    huge[3, 4] = 1e300  # reported as "holds inf" once narrowed
    with pytest.raises(ValueError, match=r"moving holds 1e\+300 at \(3, 4\), beyond float32's"):
        ig.align(a.astype(np.float64), huge)
    bad = a.copy()
    bad[3, 4] = np.nan
    with pytest.raises(ValueError, match=r"finite.*row 3"):
        ig.align(a, bad)
    with pytest.raises(ValueError, match="finite"):
        ig.similarity(bad, a)
    with pytest.raises(ValueError, match=r"unknown metric \"mse\""):
        ig.align(a, a, metric="mse")
    with pytest.raises(ValueError, match="unknown metric"):
        ig.similarity(a, a, "l1")
    with pytest.raises(ValueError, match="features"):
        ig.align(a, a, features="edges")
    with pytest.raises(ValueError, match="pyramid"):
        ig.align(a, a, pyramid="deep")
    with pytest.raises(ValueError, match="pyramid"):
        ig.align(a, a, pyramid=-1)
    with pytest.raises(ValueError, match="crop"):
        ig.align(a, a, crop=0.5)
    with pytest.raises(ValueError, match=r"single-channel"):
        ig.align(np.zeros((8, 8, 3), np.uint8), np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(TypeError, match="same dtype"):
        ig.align(a, (a * 255).astype(np.uint8))
    with pytest.raises(TypeError, match="int64"):
        ig.similarity(np.zeros((4, 4), np.int64), np.zeros((4, 4), np.int64))
    with pytest.raises(TypeError):
        ig.align(a, a, max_shift=2.5)


def test_counts_beyond_the_native_integers_are_value_errors():
    """They were OverflowErrors from the conversion to Rust's i64 / usize."""
    a = smooth_field(0, 30, 30).astype(np.float32)
    for k in (2**63, -(2**63) - 1):
        with pytest.raises(ValueError, match=r"max_shift must be >= 0 and smaller .* \(30x30\)"):
            ig.align(a, a, max_shift=k)
    for steps in (-1, 0, 2**64):
        with pytest.raises(
            ValueError, match=rf"max_iterations must be an int in \[1, 2\*\*64\), got {steps}"
        ):
            ig.align(a, a, max_shift=3, motion="euclidean", max_iterations=steps)
    with pytest.raises(ValueError, match="pyramid must be"):
        ig.align(a, a, max_shift=3, pyramid=2**64)


def test_constant_images_have_a_defined_result():
    flat = np.full((40, 40), 9, np.uint8)
    other = as_dtype(smooth_field(1, 40, 40), np.uint8)
    got = ig.align(flat, flat, max_shift=5)
    assert got.shift == (0, 0)
    assert got.score == 0.0
    assert np.all(got.surface == 0.0)
    assert ig.similarity(flat, other, "ncc") == 0.0
    zeros = np.zeros((40, 40), np.float32)
    assert ig.similarity(zeros, other.astype(np.float32), "cosine") == 0.0
    assert ig.align(flat, other, max_shift=5, metric="ncc").shift == (0, 0)


# --- shifting, stacking, plates ----------------------------------------------


@given(
    seed=st.integers(0, 1000),
    dy=st.integers(-9, 9),
    dx=st.integers(-10, 10),
    dtype=st.sampled_from(DTYPES),
)
def test_integer_apply_shift_is_roll_without_wrap_around(seed, dy, dx, dtype):
    img = as_dtype(smooth_field(seed, 10, 11), dtype)
    got = ig.apply_shift(img, (dy, dx), fill=7)
    rolled = np.roll(img, (dy, dx), axis=(0, 1))
    valid = np.zeros(img.shape, bool)
    valid[max(dy, 0) : 10 + min(dy, 0), max(dx, 0) : 11 + min(dx, 0)] = True
    np.testing.assert_array_equal(got[valid], rolled[valid])
    assert np.all(got[~valid] == 7)
    assert got.dtype == img.dtype
    assert np.all(ig.apply_shift(img, (10, 0), fill=7) == 7)


def test_fractional_apply_shift_interpolates_bilinearly():
    img = np.arange(20, dtype=np.float32).reshape(4, 5) * 4
    got = ig.apply_shift(img, (0.5, -0.25), fill=-1)
    # out[y, x] = img(y - 0.5, x + 0.25) on the ramp 20 y + 4 x.
    assert got[2, 1] == pytest.approx(20 * 1.5 + 4 * 1.25)
    assert np.all(got[0] == -1)
    assert np.all(got[:, -1] == -1)
    u8 = ig.apply_shift(np.array([[0, 255]], np.uint8), (0, 0.5))
    assert u8.dtype == np.uint8 and u8[0, 1] == 128
    with pytest.raises(ValueError, match="shift"):
        ig.apply_shift(img, (1.0, np.nan))


def test_a_nan_of_the_image_stays_nan_where_it_is_read_and_only_outside_is_fill():
    """NaN marked the taps from outside, so every pixel that read the
    image's own NaN became ``fill`` too."""
    row = np.array([[1.0, np.nan, 3.0, 4.0, 5.0]])
    got = ig.apply_shift(row, (0, 0.5), fill=-1)
    np.testing.assert_array_equal(got, [[-1.0, np.nan, np.nan, 3.5, 4.5]])
    np.testing.assert_array_equal(ig.apply_shift(row, (0, 1), fill=-1), [[-1, 1, np.nan, 3, 4]])


@pytest.mark.parametrize("dtype", [np.int64, np.uint64])
def test_a_fractional_shift_keeps_64_bit_integers_at_their_limits(dtype):
    """The interpolation ran in float64, whose 2^63 for int64's largest value
    wrapped round to the most negative in the cast back (uint64's largest
    became 0), and values beyond 2^53 and a fill near the limits rounded."""
    info = np.iinfo(dtype)
    for value in (info.max, info.min, 2**53 + 1):
        img = np.full((2, 3), value, dtype)
        got = ig.apply_shift(img, (0, 0.5), fill=info.max)
        assert got.dtype == dtype
        if np.finfo(np.longdouble).nmant >= 63:
            # x86's long double holds every 64-bit integer.
            assert got[:, 1:].tolist() == [[value] * 2] * 2
        else:
            assert np.all(np.sign(got[:, 1:].astype(float)) == np.sign(value))
        assert got[:, 0].tolist() == [info.max] * 2


@pytest.mark.parametrize("shift", [(1, 0), (1.5, 0)])
def test_apply_shift_refuses_a_fill_the_dtype_cannot_hold(shift):
    """-1 on uint8 was an OverflowError for an integer shift and became 0
    for a fractional one."""
    u8 = np.arange(12, dtype=np.uint8).reshape(3, 4)
    for fill in (-1, 256, 0.5, np.nan):
        with pytest.raises(
            ValueError, match=f"fill must be an integer from 0 to 255 for uint8, got {fill}"
        ):
            ig.apply_shift(u8, shift, fill=fill)
    with pytest.raises(ValueError, match="fill must be an integer from -32768 to 32767 for int16"):
        ig.apply_shift(u8.astype(np.int16), shift, fill=40000)
    with pytest.raises(ValueError, match="fill must be within float32's range"):
        ig.apply_shift(u8.astype(np.float32), shift, fill=1e300)
    with pytest.raises(TypeError, match="fill must be a real number"):
        ig.apply_shift(u8, shift, fill="7")
    assert (ig.apply_shift(u8, shift, fill=255)[0] == 255).all()
    assert np.isnan(ig.apply_shift(u8.astype(np.float32), shift, fill=np.nan)[0]).all()


def test_stack_channels():
    r, g, b = (np.full((2, 3), v, np.uint16) for v in (1, 2, 3))
    rgb = ig.stack_channels(r, g, b)
    assert rgb.shape == (2, 3, 3) and list(rgb[0, 0]) == [1, 2, 3]
    with pytest.raises(ValueError, match="one shape and dtype"):
        ig.stack_channels(r, g, b.astype(np.uint8))


def synthetic_plate(dtype=np.uint8, h=150, w=160, g=(3, -2), r=(-4, 5), seed=4, pad=10):
    """A B, G, R plate where ``np.roll`` of G by ``g`` and of R by ``r`` lands
    them on B (all three are windows of one scene, with per-channel noise);
    shifts up to ``pad``."""
    k = pad
    big = smooth_field(seed, h + 2 * k, w + 2 * k, sigma=2.5)
    rng = np.random.default_rng(seed)

    def window(d):
        ch = big[k + d[0] : k + d[0] + h, k + d[1] : k + d[1] + w]
        return as_dtype(np.clip(ch + rng.normal(0, 0.01, ch.shape), 0, 1), dtype)

    return np.vstack([window((0, 0)), window(g), window(r)])


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_colorize_plate_recovers_the_channel_shifts(dtype):
    plate = synthetic_plate(dtype)
    rgb, shifts = ig.colorize_plate(plate, reference="b", frame=False)
    assert shifts == {"r": (-4, 5), "g": (3, -2), "b": (0, 0)}
    assert rgb.dtype == dtype
    # The borders the shifts emptied are cropped: 3 + 4 rows, 5 + 2 columns.
    assert rgb.shape == (150 - 7, 160 - 7, 3)
    _, onto_g = ig.colorize_plate(plate, reference="g", frame=False)
    assert onto_g == {"r": (-7, 7), "g": (0, 0), "b": (-3, 2)}


def test_colorize_plate_crops_a_scanning_frame():
    plate = synthetic_plate(np.uint8, h=200, w=200).copy()
    for third in range(3):
        plate[third * 200 : third * 200 + 6] = 0  # black frame on top of each exposure
        plate[third * 200 :, :5] = 255  # white margin on the left
    rgb, _ = ig.colorize_plate(plate, reference="b")
    framed, _ = ig.colorize_plate(plate, reference="b", frame=False)
    # After the shift crop (3 rows, 5 columns) G's black rows are the first 6
    # and R's white columns the first 5; nothing else is frame.
    np.testing.assert_array_equal(rgb, framed[6:, 5:])


def test_colorize_plate_refuses_bad_plates():
    with pytest.raises(ValueError, match=r"\(3 H, W\)"):
        ig.colorize_plate(np.zeros((2, 10), np.uint8))
    with pytest.raises(ValueError, match="reference"):
        ig.colorize_plate(synthetic_plate(), reference="x")


CATHEDRAL = shared_file("data/pg/cathedral.jpg")


@pytest.mark.skipif(CATHEDRAL is None, reason="shared/data/pg/cathedral.jpg is not present")
@pytest.mark.parametrize(
    ("metric", "features"), [("ncc", "intensity"), ("ssd", "intensity"), ("ncc", "gradient")]
)
def test_cathedral_gives_the_published_shifts(metric, features):
    """The published G (5, 2), R (12, 3) relative to blue are (row, column)
    displacements that move G and R onto B, i.e. our np.roll convention."""
    rgb, shifts = ig.colorize_plate(CATHEDRAL, reference="b", metric=metric, features=features)
    assert shifts["g"] == (5, 2)
    assert shifts["r"] == (12, 3)
    assert rgb.dtype == np.uint8 and rgb.ndim == 3


# --- CLI ----------------------------------------------------------------------


def test_cli_reports_a_bad_file_and_processes_the_rest(tmp_path, capsys):
    good = tmp_path / "good.png"
    write_png(good, synthetic_plate())
    tif = tmp_path / "deep.tif"
    iio = pytest.importorskip("imageio.v3")
    iio.imwrite(tif, synthetic_plate(np.uint16))
    bad = tmp_path / "broken.jpg"
    bad.write_bytes(b"not an image")
    out = tmp_path / "out"
    status = main(["align", str(good), str(bad), str(tif), "-o", str(out), "--reference", "b"])
    captured = capsys.readouterr()
    assert status != 0
    assert "broken.jpg" in captured.err and "cannot read plate" in captured.err
    assert "G shift (3, -2), NCC 0.9" in captured.out and "R shift (-4, 5), NCC" in captured.out
    assert "LOW CONFIDENCE" not in captured.out
    assert (out / "good.png").is_file()
    deep = iio.imread(out / "deep.png")
    assert deep.ndim == 3
    cv2 = pytest.importorskip("cv2")
    assert cv2.imread(str(out / "deep.png"), cv2.IMREAD_UNCHANGED).dtype == np.uint16


@pytest.mark.parametrize(("writer", "channels"), [("ours", 3), ("cv2", 3), ("cv2", 4)])
def test_a_16_bit_rgb_png_plate_keeps_its_16_bits(tmp_path, capsys, writer, channels):
    """Pillow (imageio's PNG reader) keeps the high byte of a 16-bit colour
    PNG; read_plate and the 16-bit output of ``imgform align`` need both."""
    grey = np.clip(synthetic_plate(np.uint16), 1, 65534)
    rgb = np.dstack([grey - 1, grey, grey + 1, grey // 2][:channels])  # averages to grey
    path = tmp_path / "plate.png"
    if writer == "ours":
        write_png(path, rgb)
    else:
        cv2 = pytest.importorskip("cv2")  # libpng's filters: Sub, Up, Average, Paeth rows
        assert cv2.imwrite(str(path), rgb[..., [2, 1, 0, 3][:channels]])
    plate = ig.read_plate(path)
    assert plate.dtype == np.uint16
    np.testing.assert_array_equal(plate, grey)
    out = tmp_path / "out"
    assert main(["align", str(path), "-o", str(out)]) == 0
    header = (out / "plate.png").read_bytes()[24:26]
    assert header == bytes([16, 2])  # IHDR: bit depth 16, colour type RGB


def test_cli_reports_the_score_and_a_low_confidence_translation(tmp_path, capsys):
    plate = tmp_path / "plate.png"
    write_png(plate, synthetic_plate())  # G (3, -2), R (-4, 5) onto B
    args = ["align", str(plate), "-o", str(tmp_path / "out"), "--reference", "b"]
    assert main([*args, "--max-shift", "4", "--metric", "ssd"]) == 0
    out = capsys.readouterr().out
    # R's dx = 5 is beyond the range: its best shift lies on the edge.
    low = r"R shift \(-4, 4\), SSD [\d.]+ \(LOW CONFIDENCE: on the edge of the search range\)"
    assert re.search(low + r", G shift \(3, -2\), SSD \d+\.\d{3} onto B", out), out


def test_cli_keeps_existing_outputs_unless_overwrite(tmp_path, capsys):
    good = tmp_path / "plate.png"
    write_png(good, synthetic_plate())
    out = tmp_path / "out"
    out.mkdir()
    target = out / "plate.png"
    target.write_bytes(b"old")
    assert main(["align", str(good), "-o", str(out)]) == 0
    assert target.read_bytes() == b"old"
    assert "kept" in capsys.readouterr().out
    assert main(["align", str(good), "-o", str(out), "--overwrite", "--metric", "ssd"]) == 0
    assert target.read_bytes().startswith(b"\x89PNG")


def test_cli_never_writes_an_output_onto_its_input(tmp_path, capsys):
    plate = tmp_path / "plate.png"
    write_png(plate, synthetic_plate())
    before = plate.read_bytes()
    (tmp_path / "link").symlink_to(tmp_path)
    for out in (tmp_path, tmp_path / "link"):
        assert main(["align", str(plate), "-o", str(out), "--overwrite"]) == 2
        assert "would replace an input" in capsys.readouterr().err
    assert plate.read_bytes() == before


def test_cli_leaves_no_part_of_an_output_it_failed_to_write(tmp_path, capsys, monkeypatch):
    """A write that fails half-way (a full disk, a kill) leaves no truncated
    file under the output's name, which a later run would keep as done."""
    from imgform_rs import _png

    def half(path, image, **_):
        Path(path).write_bytes(b"\x89PNG half")
        raise OSError(28, "No space left on device")

    plate = tmp_path / "plate.png"
    write_png(plate, synthetic_plate())
    out = tmp_path / "out"
    monkeypatch.setattr(_png, "write_png", half)
    assert main(["align", str(plate), "-o", str(out)]) == 1
    assert "No space left" in capsys.readouterr().err
    assert list(out.iterdir()) == []


@pytest.mark.parametrize("extra", [[], ["--overwrite"]])
def test_cli_refuses_plates_with_one_output_before_writing_anything(tmp_path, capsys, extra):
    plates = [tmp_path / "a" / "plate.png", tmp_path / "b" / "plate.png"]
    for seed, path in enumerate(plates):
        path.parent.mkdir()
        write_png(path, synthetic_plate(seed=seed))
    out = tmp_path / "out"
    assert main(["align", *map(str, plates), "-o", str(out), *extra]) == 2
    assert_clash_refused(capsys.readouterr(), "align", plates, out)


def test_cli_says_in_one_line_that_the_output_folder_is_a_file(tmp_path, capsys):
    plate = tmp_path / "plate.png"
    write_png(plate, synthetic_plate())
    out = tmp_path / "out"
    out.write_bytes(b"a file, not a folder")
    assert main(["align", str(plate), "-o", str(out)]) == 2
    assert capsys.readouterr().err == f"imgform align: the output folder {out} is a file\n"


def test_cli_draws_a_progress_bar_on_a_terminal(tmp_path, monkeypatch, capsys):
    import io
    import sys

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    plates = []
    for name in ("a", "b", "c"):
        plates.append(tmp_path / f"{name}.png")
        write_png(plates[-1], synthetic_plate(seed=len(plates)))
    term = Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    assert main(["align", *map(str, plates), "-o", str(tmp_path / "out")]) == 0
    bar = term.getvalue()
    assert "1/3 plates" in bar and bar.endswith("3/3 plates\n")
    assert capsys.readouterr().out.count(" in ") == 3


# --- defaults and frames of full-size plates -------------------------------------


def test_default_search_range_covers_15_percent_of_the_channel():
    h, w = 160, 200
    far = (-24, 30)  # 15 % of the channel's height and width
    plate = synthetic_plate(np.uint16, h=h, w=w, g=far, r=(20, -19), seed=7, pad=40)
    assert default_max_shift(h, w) == 32
    _, shifts = ig.colorize_plate(plate, reference="b", frame=False)
    assert shifts == {"r": (20, -19), "g": far, "b": (0, 0)}


@pytest.mark.parametrize("rows", [16, 17, 18, 25])
@pytest.mark.parametrize("crop", [0.0, 0.1, 0.3])
def test_the_default_search_range_is_one_align_takes(rows, crop):
    """A floor of 15 on channels of 16 or 17 rows: align refused the
    max_shift=15 that colorize_plate chose, naming a parameter never given."""
    chan = (smooth_field(rows, rows, 60) * 255).astype(np.uint8)
    k = default_max_shift(rows, 60, crop)
    assert ig.align(chan, chan, max_shift=k, crop=crop).shift == (0, 0)
    if k < 15:  # cut by the overlap: one more is refused
        with pytest.raises(ValueError, match="too small for max_shift"):
            ig.align(chan, chan, max_shift=k + 1, crop=crop)
    plate = np.concatenate([chan, chan, chan])
    rgb, shifts = ig.colorize_plate(plate, frame=False, crop=crop)
    assert rgb.shape == (rows, 60, 3)
    assert shifts == {"r": (0, 0), "g": (0, 0), "b": (0, 0)}


def test_frame_detection_reads_full_resolution_rows_of_a_large_plate():
    """On a plate large enough for the sampled statistics (step 2), the crop
    still falls on the exact full-resolution rows and columns of the frame."""
    h, w = 520, 600
    plate = synthetic_plate(np.uint16, h=h, w=w, g=(3, -2), r=(-4, 5), seed=3).copy()
    for third in range(3):
        rows = slice(third * h, (third + 1) * h)
        plate[rows][:13] = 0  # scanner border on top of each exposure
        plate[rows][-9:] = 65535  # white margin at the bottom
        plate[rows][:, -11:] = 0  # and on the right
    rgb, _ = ig.colorize_plate(plate, reference="b")
    framed, _ = ig.colorize_plate(plate, reference="b", frame=False)
    # After the common-area crop (3 rows at the top, 4 at the bottom, 5
    # columns left, 2 right), G's black rows reach row 13 - 3 + 3 = 13 of the
    # crop and so on; nothing inside the frame is cut.
    assert framed.shape == (h - 7, w - 7, 3)
    top, bottom = 13, (h - 7) - (9 + 4 - 4)
    right = (w - 7) - (11 + 2 - 2)
    np.testing.assert_array_equal(rgb, framed[top:bottom, :right])


def test_frame_box_of_a_plate_without_frame_keeps_everything():
    rgb, _ = ig.colorize_plate(synthetic_plate(np.uint8, h=300, w=280), frame=False)
    assert frame_box(rgb) == (0, rgb.shape[0], 0, rgb.shape[1])


def full_resolution_frame_box(rgb: np.ndarray) -> tuple[int, int, int, int]:
    """:func:`frame_box`'s documented rule applied to every pixel: each
    channel stretched to its 1st..99th percentiles, a row (column) of the
    outer ``FRAME_SEARCH`` is frame when its mean level is below 0.1 or above
    0.95 or the 75th percentile of its channels' disagreement exceeds the
    median row's by more than 0.05; the crop keeps what lies inside the
    innermost frame row."""
    chans = []
    for c in np.moveaxis(rgb.astype(np.float64), -1, 0):
        lo, hi = np.percentile(c, [1, 99])
        chans.append((c - lo) / max(hi - lo, 1e-12))
    n = np.stack(chans)
    level = n.mean(axis=0)
    spread = np.abs(n - level).mean(axis=0)

    def depth(axis: int, size: int, far: bool) -> int:
        disagree = np.percentile(spread, 75, axis=axis)
        mean = level.mean(axis=axis)
        frame = (mean < 0.1) | (mean > 0.95) | (disagree - np.median(disagree) > 0.05)
        band = (frame[::-1] if far else frame)[: int(FRAME_SEARCH * size)]
        hits = np.flatnonzero(band)
        return int(hits[-1]) + 1 if hits.size else 0

    h, w = level.shape
    return depth(1, h, False), h - depth(1, h, True), depth(0, w, False), w - depth(0, w, True)


def ragged_plate(seed: int, h: int = 1100, w: int = 1200) -> np.ndarray:
    """An aligned (h, w, 3) uint8 plate with a ragged dark scanner border on
    top (its depth a random walk along the side, another per channel), a
    ragged white margin on the right and a straight dark band at the bottom."""
    rng = np.random.default_rng(seed)
    scene = 40 + 170 * smooth_field(seed, h, w, sigma=6.0)
    chans = []
    for _ in range(3):
        c = scene + rng.normal(0, 4, scene.shape)
        top = np.clip(30 + np.cumsum(rng.integers(-2, 3, w)), 8, 60)
        c[np.arange(h)[:, None] < top[None, :]] = rng.uniform(0, 12)
        right = np.clip(25 + np.cumsum(rng.integers(-1, 2, h)), 6, 50)
        c[np.arange(w)[None, :] >= w - right[:, None]] = 250
        c[-15:] = 3
        chans.append(np.clip(c, 0, 255).astype(np.uint8))
    return np.stack(chans, axis=-1)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_frame_detection_makes_the_full_resolution_crop_decisions(seed):
    # The detector reads only the outer bands, every 4th pixel along a side
    # here: its crop must be the one the rule gives on every pixel. Exactly
    # on a straight border; within one row on a ragged one, whose partly
    # covered rows can sit at the threshold, where a sampled mean may fall
    # on the other side of it.
    rgb = ragged_plate(seed)
    box, full = frame_box(rgb), full_resolution_frame_box(rgb)
    assert box[1] == full[1] == rgb.shape[0] - 15
    assert max(abs(a - b) for a, b in zip(box, full, strict=True)) <= 1, (box, full)
    if CATHEDRAL is not None:
        plate, _ = ig.colorize_plate(CATHEDRAL, reference="b", frame=False)
        assert frame_box(plate) == full_resolution_frame_box(plate)


def test_low_confidence_flags_unrelated_channels_and_shifts_at_the_limit():
    ref, mov = shifted_pair(3, 120, 130, 12, 5, -4)
    good = ig.align(ref, mov, max_shift=10)
    assert good.shift == (5, -4) and not good.low_confidence
    beyond = ig.align(ref, mov, max_shift=4)  # the true dy = 5 is out of range
    assert beyond.at_limit and beyond.low_confidence
    noise = np.random.default_rng(1).random(ref.shape).astype(np.float32)
    unrelated = ig.align(ref, noise, max_shift=10)
    assert unrelated.low_confidence and unrelated.score < 0.3
    flat = np.zeros_like(ref)
    assert ig.align(flat, flat, max_shift=3).low_confidence


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
def test_auto_balance_equalises_channel_means_and_stretches(dtype):
    field = smooth_field(2, 90, 100)
    gains = (0.9, 0.5, 0.3)
    rgb = np.stack([as_dtype(0.1 + 0.6 * g * field, dtype) for g in gains], axis=-1)
    white = ig.auto_balance(rgb, contrast=False)
    means = white.reshape(-1, 3).astype(np.float64).mean(axis=0)
    np.testing.assert_allclose(means, means.mean(), rtol=0.01)
    both = ig.auto_balance(rgb, clip=0.01)
    assert both.dtype == dtype and both.shape == rgb.shape
    top = 1.0 if dtype == np.float32 else np.iinfo(dtype).max
    level = both.astype(np.float64).mean(axis=-1)
    # The 1 % quantiles of the channels' mean go to black and white (up to
    # what clipping single channels moves the mean).
    lo, hi = np.quantile(level, [0.01, 0.99])
    assert lo <= 0.05 * top and hi >= 0.95 * top
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        ig.auto_balance(rgb[..., 0])
    with pytest.raises(ValueError, match="clip"):
        ig.auto_balance(rgb, clip=0.5)
    with pytest.raises(TypeError, match="dtype"):
        ig.auto_balance(rgb.astype(np.int32))


@pytest.mark.parametrize("value", [np.nan, np.inf])
@pytest.mark.parametrize("options", [{}, {"contrast": False}, {"white_balance": False}])
def test_auto_balance_refuses_a_nan_or_infinite_sample(value, options):
    """One NaN made every gain NaN, so all of G and B (or did nothing)."""
    rgb = np.random.default_rng(3).random((40, 50, 3)).astype(np.float32)
    rgb[7, 9, 0] = value
    with pytest.raises(ValueError, match=rf"finite numbers, got {value} at index \(7, 9, 0\)"):
        ig.auto_balance(rgb, **options)


@pytest.mark.parametrize("shape", [(0, 5, 3), (5, 0, 3)])
def test_auto_balance_refuses_an_empty_image(shape):
    with pytest.raises(
        ValueError, match=r"non-empty \(H, W, 3\) image, got shape " + re.escape(str(shape))
    ):
        ig.auto_balance(np.zeros(shape, np.uint8))


def test_colorize_plate_finishes_with_balance_on_request():
    plate = synthetic_plate(np.uint16)
    plain, _ = ig.colorize_plate(plate, frame=False)
    done, _ = ig.colorize_plate(plate, frame=False, white_balance=True, auto_contrast=True)
    assert done.shape == plain.shape and done.dtype == np.uint16
    np.testing.assert_array_equal(done, ig.auto_balance(plain))


def test_a_float_rgb_plate_keeps_its_fractions_and_one_beyond_0_1_is_refused(tmp_path):
    """A float RGB scan's mean was rounded to 0 or 1 (a black-and-white plate);
    one on 0..255 was written clipped, all white."""
    tifffile = pytest.importorskip("tifffile")
    from imgform_rs.align import read_plate

    grey = synthetic_plate(np.float32)
    tifffile.imwrite(tmp_path / "rgb.tif", np.repeat(grey[..., None], 3, -1), photometric="rgb")
    np.testing.assert_allclose(read_plate(tmp_path / "rgb.tif"), grey, atol=1e-6)
    tifffile.imwrite(tmp_path / "big.tif", grey * 255)
    with pytest.raises(ValueError, match="a float plate holds values from 0 to 1"):
        read_plate(tmp_path / "big.tif")

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import imgform_rs as ig
from conftest import output_with_threads

focal = st.floats(1.0, 1000.0)
fnumber = st.floats(0.7, 64.0)
# Focus distances as multiples of f beyond it (1.01 f .. 1e4 f).
beyond = st.floats(1.01, 1e4)
LENS = {"f": 50.0, "N": 2.0, "focus_distance": 1000.0}


# --- the thin-lens law -------------------------------------------------------


@given(f=focal, k=st.floats(1.001, 1e6))
def test_thin_lens_law_holds(f, k):
    d = k * f
    di = ig.image_distance(f, d)
    np.testing.assert_allclose(1.0 / di + 1.0 / d, 1.0 / f, rtol=1e-12)
    np.testing.assert_allclose(ig.magnification(f, d), di / d, rtol=1e-15)


@given(f=focal)
def test_image_distance_tends_to_f_as_the_object_recedes(f):
    d = f * np.logspace(0.1, 12, 60)
    di = ig.image_distance(f, d)
    assert np.all(np.diff(di) <= 0), "D' must fall as D grows"
    assert np.all(di > f)
    np.testing.assert_allclose(di, f * d / (d - f), rtol=1e-13)
    assert abs(di[-1] - f) <= 1e-9 * f


def test_unit_magnification_at_twice_the_focal_length():
    assert ig.magnification(50.0, 100.0) == 1.0
    assert ig.image_distance(50.0, 100.0) == 100.0


# --- circle of confusion and depth of field --------------------------------


@given(
    f=focal,
    n=fnumber,
    s=beyond,
    ts=st.lists(st.floats(0.0, 1.0), min_size=2, max_size=20, unique=True),
)
def test_coc_is_zero_at_focus_and_grows_away_on_both_sides(f, n, s, ts):
    s = s * f
    t = np.sort(np.array(ts))
    near = s - (s - f) * 0.999 * t  # from S down towards f
    far = s * (1.0 + 1e3 * t)  # from S out towards infinity
    assert ig.circle_of_confusion(f, n, s, s) == 0.0
    for side in (near, far):
        c = ig.circle_of_confusion(f, n, s, side)
        assert np.all(np.diff(c) >= 0), c
        assert np.all(c[side != s] > 0)
    # Towards infinity it tends to A f / (S - f).
    limit = (f / n) * f / (s - f)
    assert ig.circle_of_confusion(f, n, s, 1e300) == pytest.approx(limit, rel=1e-12)


@given(f=focal, n=fnumber, s=beyond, frac=st.floats(1e-6, 0.99))
def test_depth_of_field_brackets_the_focus_and_is_infinite_beyond_hyperfocal(f, n, s, frac):
    # The tolerated blur as a fraction of the aperture diameter (it must be less).
    s, c = s * f, frac * f / n
    near, far = ig.depth_of_field(f, n, s, c)
    h = ig.hyperfocal_distance(f, n, c)
    assert f < near < s < far
    assert np.isinf(far) == (s >= h)
    # The limits are where the circle of confusion reaches c. The check is
    # ill-conditioned when a limit lies very close to S (|D - S| cancels) or
    # S nears H (H - S cancels), hence the loose tolerance.
    assert ig.circle_of_confusion(f, n, s, near) == pytest.approx(c, rel=1e-6)
    if np.isfinite(far):
        assert ig.circle_of_confusion(f, n, s, far) == pytest.approx(c, rel=1e-6)


def test_focused_at_hyperfocal_sharp_from_half_of_it_to_infinity():
    h = ig.hyperfocal_distance(35.0, 8.0, 0.03)
    near, far = ig.depth_of_field(35.0, 8.0, h, 0.03)
    assert far == np.inf
    assert near == pytest.approx(h / 2, rel=1e-12)


@given(f0=focal, k0=st.floats(1.01, 1e4), ratio=st.floats(0.02, 50.0))
def test_dolly_zoom_keeps_magnification_constant(f0, k0, ratio):
    d0 = k0 * f0
    d = ratio * d0
    f = ig.dolly_zoom_focal_length(f0, d0, d)
    np.testing.assert_allclose(ig.magnification(f, d), ig.magnification(f0, d0), rtol=1e-9)


@pytest.mark.parametrize(
    ("f", "size", "degrees"),
    [(50.0, 36.0, 39.598), (50.0, 24.0, 26.991), (24.0, 36.0, 73.740), (200.0, 43.267, 12.347)],
)
def test_field_of_view_known_values(f, size, degrees):
    assert np.degrees(ig.field_of_view(f, size)) == pytest.approx(degrees, abs=1e-3)


def test_inputs_broadcast_like_numpy():
    f = np.array([[35.0], [50.0], [85.0]])
    d = np.array([500.0, 1000.0, 2000.0, 4000.0])
    got = ig.image_distance(f, d)
    assert got.shape == (3, 4) and got.dtype == np.float64
    np.testing.assert_array_equal(got, [[ig.image_distance(a, b) for b in d] for a in f[:, 0]])
    near, far = ig.depth_of_field(50.0, [2.0, 8.0], [[1000.0], [3000.0]], 0.03)
    assert near.shape == far.shape == (2, 2)
    assert isinstance(ig.field_of_view(50, 36), np.float64)
    # Single values are repeated by the kernel, not expanded, whatever their shape.
    np.testing.assert_array_equal(ig.image_distance([50.0], [100.0, 200.0]), [100.0, 200.0 / 3.0])
    assert ig.image_distance([[50.0]], 100.0).shape == (1, 1)
    assert ig.image_distance(50.0, np.empty((0, 3))).shape == (0, 3)
    # Integer and float32 inputs are accepted and computed in float64.
    assert ig.image_distance(np.int32(50), np.float32(100)) == 100.0


def test_large_inputs_run_in_parallel_and_name_the_first_bad_element():
    d = np.linspace(100.0, 1e5, 100_000)
    got = ig.image_distance(50.0, d)
    np.testing.assert_allclose(got, 50.0 * d / (d - 50.0), rtol=1e-12)
    d[[70_000, 40_001]] = 20.0
    with pytest.raises(ValueError, match=r"got D = 20\b.*\(at element 40001\)"):
        ig.image_distance(50.0, d)


@pytest.mark.parametrize(
    ("call", "exc", "match"),
    [
        (lambda: ig.image_distance(0.0, 100.0), ValueError, "f must be a finite number > 0, got 0"),
        (lambda: ig.image_distance(-5.0, 100.0), ValueError, "f must be .* got -5"),
        (lambda: ig.image_distance(50.0, 30.0), ValueError, r"D must be .* greater than .* f = 50"),
        (lambda: ig.image_distance(50.0, 50.0), ValueError, "inside the focal length"),
        (lambda: ig.image_distance(np.nan, 100.0), ValueError, "f must be a finite number"),
        (lambda: ig.image_distance(50.0, np.nan), ValueError, "got D = NaN"),
        (lambda: ig.magnification(50.0, np.inf), ValueError, "D must be finite"),
        (lambda: ig.circle_of_confusion(50, 0.0, 1000, 2000), ValueError, "N must be .* got 0"),
        (lambda: ig.circle_of_confusion(50, 2, 40, 2000), ValueError, "focus_distance = 40"),
        (lambda: ig.depth_of_field(50, 2, 1000, -0.03), ValueError, "coc must be .* got -0.03"),
        (lambda: ig.depth_of_field(50, 2, 1000, 25.0), ValueError, "aperture diameter f/N = 25"),
        (lambda: ig.hyperfocal_distance(50, -1, 0.03), ValueError, "N must be"),
        (lambda: ig.field_of_view(50, 0), ValueError, "sensor_size must be"),
        (lambda: ig.dolly_zoom_focal_length(50, 40, 100), ValueError, "d0 = 40"),
        (lambda: ig.image_distance("50", 100), TypeError, "f must be an array of real numbers"),
        (lambda: ig.image_distance(50, None), TypeError, "D must be an array of numbers, got None"),
        (lambda: ig.image_distance(50, [1j]), TypeError, "got dtype complex128"),
        (lambda: ig.image_distance([50, 35], [1e3] * 3), ValueError, r"f \(2,\), D \(3,\)"),
    ],
)
def test_bad_input_says_what_was_given(call, exc, match):
    with pytest.raises(exc, match=match):
        call()


def test_native_formulas_check_their_arrays_too():
    from imgform_rs import _native

    with pytest.raises(TypeError, match="f must be a 1-D float64 array, got an array of dtype"):
        _native.image_distance(np.zeros(2, np.float32), np.ones(2))
    with pytest.raises(ValueError, match="must have 1 or 3 elements, got one with 2"):
        _native.image_distance(np.ones(2), np.ones(3))


# --- render_defocus -----------------------------------------------------------


def _noise(shape, dtype, seed=0):
    rng = np.random.default_rng(seed)
    if dtype == np.float32:
        return rng.random(shape, dtype=np.float32)
    return rng.integers(0, np.iinfo(dtype).max, shape, endpoint=True).astype(dtype)


def _defocus(img, depth, pixel_pitch=0.02, **lens):
    return ig.render_defocus(img, depth, pixel_pitch=pixel_pitch, **{**LENS, **lens})


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
@pytest.mark.parametrize("shape", [(31, 47), (31, 47, 3), (9, 8, 4)])
def test_in_focus_image_is_returned_bit_exact(dtype, shape):
    img = _noise(shape, dtype)
    # Slightly off focus too: discs under one pixel wide change nothing.
    depth = np.full(shape[:2], 1000.0) + np.linspace(0, 5, shape[1])
    out = _defocus(img, depth)
    assert out.dtype == dtype and out.shape == shape and out.flags.c_contiguous
    np.testing.assert_array_equal(out, img)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
def test_constant_image_stays_constant_under_any_depth_map(dtype):
    value = {np.uint8: 173, np.uint16: 40_000, np.float32: 0.3}[dtype]
    img = np.full((40, 50, 3), value, dtype)
    depth = np.random.default_rng(1).uniform(600.0, 9000.0, (40, 50))
    out = _defocus(img, depth)
    assert out.dtype == dtype
    if dtype == np.float32:
        # float32 sums of up to ~3000 weighted terms: a few ulp.
        np.testing.assert_allclose(out, value, rtol=4e-6)
    else:
        np.testing.assert_array_equal(out, img)


def test_blur_grows_with_distance_from_focus_on_both_sides():
    img = _noise((64, 64), np.float32)
    near = [1000.0, 950.0, 900.0, 800.0, 700.0]
    far = [1000.0, 1100.0, 1300.0, 1700.0, 3000.0]
    for depths in (near, far):
        # Residual variance: less texture survives the wider disc.
        var = [_defocus(img, np.full(img.shape, z)).var() for z in depths]
        assert np.all(np.diff(var) < 0), var


def test_constant_depth_is_a_normalised_disc_filter_like_cv2():
    cv2 = pytest.importorskip("cv2")
    img = _noise((48, 56, 3), np.float32, seed=3)
    depth = np.full((48, 56), 1500.0)
    r = ig.circle_of_confusion(50.0, 2.0, 1000.0, 1500.0) / 0.02 / 2
    g = int(np.ceil(r + 0.5))
    yy, xx = np.mgrid[-g : g + 1, -g : g + 1]
    kernel = np.clip(r + 0.5 - np.hypot(yy, xx), 0.0, 1.0).astype(np.float32)
    # Mirrored borders without repeating the edge pixel are BORDER_REFLECT_101.
    want = cv2.filter2D(img, -1, kernel / kernel.sum(), borderType=cv2.BORDER_REFLECT_101)
    np.testing.assert_allclose(_defocus(img, depth), want, atol=2e-6)


def _reference_defocus(img, depth, pixel_pitch=0.02):
    """The gather of the module docs in float64, offset by offset over the
    whole image (the discs' depths, radii and weights rounded to float32, as
    the kernel keeps them)."""
    h, w = depth.shape
    img = img.astype(np.float64).reshape(h, w, -1)
    coc = ig.circle_of_confusion(LENS["f"], LENS["N"], LENS["focus_distance"], depth)
    r = (coc / (2 * pixel_pitch)).astype(np.float32).astype(np.float64)
    z = depth.astype(np.float32).astype(np.float64)
    g = int(np.ceil(r.max() + 1))
    dist = np.hypot(*np.mgrid[-g : g + 1, -g : g + 1])
    area = np.clip(r[..., None, None] + 0.5 - dist, 0.0, 1.0).sum((-2, -1))
    unit = (1.0 / area).astype(np.float32).astype(np.float64)
    pad = [(g, g), (g, g)]
    zq, rq, uq = (np.pad(a, pad, mode="reflect") for a in (z, r, unit))
    iq = np.pad(img, [*pad, (0, 0)], mode="reflect")
    weights = np.zeros((3, h, w))
    light = np.zeros((3, *img.shape))
    for dy in range(-g, g + 1):
        for dx in range(-g, g + 1):
            at = np.s_[g + dy : g + dy + h, g + dx : g + dx + w]
            d = np.hypot(dy, dx)
            farther = zq[at] > z
            wt = np.clip(np.where(farther, np.minimum(rq[at], r), rq[at]) + 0.5 - d, 0, 1)
            wt = wt * uq[at]
            front = np.where(zq[at] < z, wt, 0.0)
            behind = np.where(farther, np.clip(r + 0.5 - d, 0, 1), 0.0)
            for k, layer in enumerate((front, wt - front, behind)):
                weights[k] += layer
                # A neighbour whose disc misses the pixel adds nothing, not
                # 0 x inf.
                with np.errstate(invalid="ignore"):
                    light[k] += np.where(layer[..., None] > 0, layer[..., None] * iq[at], 0.0)
    (front, own, behind), (f, s, b) = weights[..., None], light
    with np.errstate(invalid="ignore", divide="ignore"):
        surface = np.where((own >= 1) | (behind == 0), s / own, s + (1 - own) * b / behind)
        return np.where(front >= 1, f / front, f + (1 - front) * surface)


@pytest.mark.parametrize(
    ("seed", "far", "atol"), [(0, 2500, 2e-6), (1, 2500, 2e-6), (2, 3e4, 3e-5)]
)
def test_the_gather_matches_a_float64_reference(seed, far, atol):
    rng = np.random.default_rng(seed)
    h, w = rng.integers(9, 40, 2)
    img = rng.random((h, w, 3), dtype=np.float32)
    # Depths on both sides of the focus, in patches, so that pixels have
    # occluders, surfaces and backgrounds of every radius (up to 20 px, or
    # 32 px, the largest, where ~3400 terms a sum round to ~1e-5).
    depth = rng.uniform(650.0, far, (h // 4 + 1, w // 4 + 1)).repeat(4, 0).repeat(4, 1)
    depth = depth[:h, :w] + rng.uniform(0.0, 30.0, (h, w))
    want = _reference_defocus(img, depth).reshape(img.shape)
    np.testing.assert_allclose(_defocus(img, depth), want, atol=atol)


def test_values_near_the_float32_limit_do_not_overflow():
    """The light is summed as differences from each pixel: of 2e38 and
    -2e38 that overflowed to NaN, until the differences were halved; and
    what lies behind a pixel was weighed by coverage alone, whose sum reached
    ~3300 at 32 px, so 1e36 behind a blurred edge overflowed to inf."""
    img = np.array([[2e38, -2e38, 0.0, 0.0]], np.float32)
    depth = np.full(img.shape, 1300.0)
    got = _defocus(img, depth)
    assert np.isfinite(got).all()
    np.testing.assert_allclose(got, _reference_defocus(img, depth)[..., 0], rtol=1e-5)
    step = np.zeros((40, 80), np.float32)
    depth = np.full(step.shape, 20000.0)
    step[:, 40:], depth[:, 40:] = 1e36, 30000.0
    got = _defocus(step, depth)
    assert np.isfinite(got).all()
    want = _reference_defocus(step, depth)[..., 0]
    # r ~ 32 px: sums of ~3400 terms round to a few 1e-5 of the range.
    np.testing.assert_allclose(got, want, rtol=0, atol=5e-5 * 1e36)


def test_nan_and_infinities_reach_only_what_their_discs_cover():
    """Light summed as differences from each pixel made an infinite pixel's
    neighbours NaN, and 0 x inf spread NaN beyond its disc, into pixels in
    focus."""
    img = np.random.default_rng(9).random((40, 90), dtype=np.float32)
    depth = np.full(img.shape, 1000.0)
    depth[:, 50:] = 1500.0  # blurred, r ~ 11 px
    img[10, 5] = np.inf  # in focus, far from the blur
    img[20, 70] = np.inf  # blurred
    img[30, 45] = np.nan  # in focus, within the blur's reach
    got = _defocus(img, depth)
    want = _reference_defocus(img, depth)[..., 0]
    np.testing.assert_allclose(got, want, atol=2e-6)
    assert np.isposinf(got[20, 70]) and np.isnan(got[30, 45])
    # The sharp side keeps every other pixel as it was.
    sharp = np.ones(img.shape, bool)
    sharp[:, 38:] = False
    sharp[10, 5] = False
    np.testing.assert_array_equal(got[sharp], img[sharp])


def _fg_scene():
    """A sharp bright square (200, at the focus distance) in front of a dim
    textured background (0..100) far out of focus."""
    rng = np.random.default_rng(7)
    img = rng.integers(0, 101, (80, 80), endpoint=True).astype(np.uint8)
    depth = np.full((80, 80), 4000.0)
    img[25:55, 25:55] = 200
    depth[25:55, 25:55] = 1000.0
    return img, depth


def test_sharp_foreground_does_not_bleed_into_blurred_background():
    img, depth = _fg_scene()
    out = _defocus(img, depth)
    background = depth > 1000.0
    # No background pixel, even right at the square's edge, gets its light.
    assert out[background].max() <= 100
    # ... while the background really is blurred (r ~ 15 px).
    assert out[background].std() < 0.3 * img[background].std()


def test_blurred_background_does_not_smear_over_sharp_foreground():
    img, depth = _fg_scene()
    out = _defocus(img, depth)
    np.testing.assert_array_equal(out[25:55, 25:55], 200)


def test_blurred_foreground_veils_the_sharp_background_behind_its_edge():
    img = np.zeros((60, 60), np.float32)
    depth = np.full((60, 60), 1000.0)  # sharp, dark background
    img[:, :30] = 1.0
    depth[:, :30] = 700.0  # bright, out-of-focus foreground, r ~ 14 px
    out = _defocus(img, depth)
    edge = out[30, 30:50]
    assert edge[0] > 0.2 and edge[-1] == 0.0
    assert np.all(np.diff(edge) <= 0)


def _layered_disc(mask, r):
    """A mask blurred by the anti-aliased disc of radius ``r``: the coverage
    of a blurred foreground layer composited over what is behind it."""
    from scipy import ndimage

    g = int(np.ceil(r + 1))
    yy, xx = np.mgrid[-g : g + 1, -g : g + 1]
    kernel = np.clip(r + 0.5 - np.hypot(yy, xx), 0.0, 1.0)
    return ndimage.convolve(mask, kernel / kernel.sum(), mode="mirror")


def test_a_blurred_foreground_edge_is_soft_on_both_sides_as_layers_composite():
    pytest.importorskip("scipy")
    img = np.zeros((48, 48), np.float32)
    depth = np.full((48, 48), 1000.0)  # a sharp black background
    img[:, :24] = 1.0
    depth[:, :24] = 800.0  # a bright foreground half-plane, out of focus
    r = ig.circle_of_confusion(50.0, 2.0, 1000.0, 800.0) / 0.02 / 2
    want = _layered_disc((img > 0).astype(np.float64), r)
    got = _defocus(img, depth)
    # Within a few % of the layered rendering, inside the foreground's edge too
    # (a normalised gather kept it at 1.0 up to the edge: a hard silhouette).
    np.testing.assert_allclose(got[24, 10:38], want[24, 10:38], atol=0.03)
    assert got[24, 23] < 0.7


def test_a_blurred_point_in_front_of_a_dark_background_keeps_its_light():
    img = np.zeros((40, 40), np.float32)
    depth = np.full((40, 40), 1000.0)
    img[20, 20] = 1.0
    depth[20, 20] = 800.0
    out = _defocus(img, depth)
    # Spread over its disc (r ~ 8 px), not kept whole with a halo added.
    assert out.sum() == pytest.approx(1.0, rel=1e-4)
    assert out[20, 20] < 0.01 and out[20, 27] > 0.0


def test_depth_may_be_float32_and_inputs_non_contiguous():
    img, depth = _fg_scene()
    # float32 depths differ from float64 ones by rounding, so compare like with like.
    want = _defocus(img, depth.astype(np.float32).astype(np.float64))
    got = _defocus(np.asfortranarray(img), np.asfortranarray(depth, np.float32))
    np.testing.assert_array_equal(got, want)
    # Big-endian depths were refused as "not float64".
    np.testing.assert_array_equal(_defocus(img, depth.astype(">f8")), _defocus(img, depth))


def test_each_channel_renders_as_it_would_alone():
    # Four channels go through a pass; a fifth and sixth take another.
    img = _noise((37, 53, 6), np.uint16, seed=4)
    depth = np.random.default_rng(4).uniform(600.0, 4000.0, (37, 53))
    whole = _defocus(img, depth)
    for k in range(6):
        np.testing.assert_array_equal(whole[..., k], _defocus(img[..., k], depth))


def test_thread_count_does_not_change_the_result():
    code = """
import hashlib, sys
import numpy as np
import imgform_rs as ig
rng = np.random.default_rng(5)
img = rng.integers(0, 65535, (150, 130, 3), endpoint=True).astype(np.uint16)
depth = rng.uniform(600.0, 5000.0, (150, 130))
out = ig.render_defocus(img, depth, f=50.0, N=2.0, focus_distance=1000.0, pixel_pitch=0.03)
dist = ig.circle_of_confusion(50.0, 2.0, 1000.0, np.linspace(60.0, 1e6, 200_000))
sys.stdout.write(hashlib.sha256(out.tobytes() + dist.tobytes()).hexdigest())
"""
    assert output_with_threads(code, 1) == output_with_threads(code, 2)


@pytest.mark.parametrize(
    ("image", "depth", "lens", "exc", "match"),
    [
        (np.zeros((4, 4), np.float64), np.full((4, 4), 1e3), {}, TypeError, "uint8, uint16 or"),
        (np.zeros((4, 4), np.uint8), np.full((4, 4), 1000), {}, TypeError, "got dtype int64"),
        (np.zeros((4, 4), np.uint8), np.full((4, 5), 1e3), {}, ValueError, r"\(4, 4\), got"),
        (np.zeros((2, 4, 4, 1), np.uint8), np.full((4, 4), 1e3), {}, ValueError, r"\(H, W\) or"),
        (np.zeros((4, 4), np.uint8), np.full((4, 4), 1e3), {"f": 0.0}, ValueError, "f must be"),
        (np.zeros((4, 4), np.uint8), np.full((4, 4), 1e3), {"N": -2.0}, ValueError, "N must be"),
        (
            np.zeros((4, 4), np.uint8),
            np.full((4, 4), 1e3),
            {"focus_distance": 30.0},
            ValueError,
            "focus_distance = 30",
        ),
        (
            np.zeros((4, 4), np.uint8),
            np.full((4, 4), 1e3),
            {"pixel_pitch": np.nan},
            ValueError,
            "pixel_pitch must be",
        ),
        (
            np.zeros((4, 4), np.uint8),
            np.where(np.eye(4, dtype=bool)[::-1], np.nan, 1e3),
            {},
            ValueError,
            r"depth must be finite .* got NaN \(at pixel row 0, column 3\)",
        ),
        (
            np.zeros((4, 4), np.uint8),
            np.full((4, 4), 40.0),
            {},
            ValueError,
            "inside the focal length",
        ),
        (
            np.zeros((4, 4), np.uint8),
            np.full((4, 4), 1e6),
            {},
            ValueError,
            "px wide, more than the supported 64 px",
        ),
    ],
)
def test_render_defocus_bad_input_says_what_was_given(image, depth, lens, exc, match):
    with pytest.raises(exc, match=match):
        _defocus(image, depth, **lens)

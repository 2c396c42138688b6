import warnings

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

import imgform_rs as ig
from conftest import output_with_threads

BAYER = ["RGGB", "BGGR", "GRBG", "GBRG"]
METHODS = list(ig.BAYER_DEMOSAIC_METHODS)
DTYPES = [np.uint8, np.uint16, np.float32]


def random_raw(seed, h, w, dtype):
    rng = np.random.default_rng(seed)
    if dtype == np.float32:
        return rng.random((h, w), dtype=np.float32)
    return rng.integers(0, np.iinfo(dtype).max, (h, w), endpoint=True).astype(dtype)


def smooth_rgb(seed, h, w):
    """A smooth textured float32 image with a little noise."""
    ndimage = pytest.importorskip("scipy.ndimage")
    rng = np.random.default_rng(seed)
    rgb = ndimage.gaussian_filter(rng.random((h, w, 3)), (1.5, 1.5, 0))
    return (rgb + 1e-3 * rng.random(rgb.shape)).astype(np.float32)


@st.composite
def mosaics(draw, min_side=2, max_side=24):
    dtype = draw(st.sampled_from(DTYPES))
    h = draw(st.integers(min_side, max_side))
    w = draw(st.integers(min_side, max_side))
    return random_raw(draw(st.integers(0, 2**32 - 1)), h, w, dtype)


def flipped_pattern(pattern, shape, vertical, horizontal):
    """The pattern of ``raw[::-1]`` / ``raw[:, ::-1]`` given the one of ``raw``."""
    masks = ig.channel_masks(shape, pattern)
    masks = masks[:: -1 if vertical else 1, :: -1 if horizontal else 1]
    return masks[:2, :2].argmax(-1)


def test_methods_are_exactly_the_documented_ones():
    assert ig.DEMOSAIC_METHODS == (
        "nearest",
        "bilinear",
        "malvar2004",
        "hamilton_adams",
        "rcd",
        "menon2007",
        "rcd_menon",
        "ahd",
        "leung2011",
        "mlri",
        "raisr",
        "raisr_fast",
        "ri_cd",
        "raisr_cd",
        "fusion",
        "fusion_refined",
        "fusion_cnn",
        "markesteijn",
        "best",
        "quality",
    )


@pytest.mark.parametrize(("alias", "method"), [("best", "raisr_cd"), ("quality", "fusion_cnn")])
def test_aliases_name_a_method(alias, method):
    raw = np.random.default_rng(4).integers(0, 4096, (40, 52)).astype(np.uint16)
    for pattern in ["RGGB", "GBRG"]:
        np.testing.assert_array_equal(
            ig.demosaic(raw, pattern, alias), ig.demosaic(raw, pattern, method)
        )


def test_rcd_menon_is_the_rcd_menon_mean():
    # Smooth data, so that neither method reaches the clamp (the mean is
    # clamped, not its terms).
    raw = ig.mosaic(smooth_rgb(9, 20, 30), "BGGR")
    raw[0, 0], raw[-1, -1] = -1, 2  # widen the clamp range, away from the middle
    best = ig.demosaic(raw, "BGGR", "rcd_menon")
    want = 0.5 * (ig.demosaic(raw, "BGGR", "rcd") + ig.demosaic(raw, "BGGR", "menon2007"))
    np.testing.assert_allclose(best[4:-4, 4:-4], want[4:-4, 4:-4], rtol=0, atol=1e-6)


# The multi-stage methods clamp their outputs to the input's range.
CLAMPED = ["rcd", "menon2007", "rcd_menon", "ahd", "leung2011", "mlri", "best"]


@given(raw=mosaics(), p=st.sampled_from(BAYER), method=st.sampled_from(CLAMPED))
def test_clamped_methods_stay_within_the_input_range(raw, p, method):
    out = ig.demosaic(raw, p, method)
    assert raw.min() <= out.min() and out.max() <= raw.max()


@given(raw=mosaics(), p=st.sampled_from(BAYER), method=st.sampled_from(METHODS))
def test_every_sample_comes_back_unchanged_at_its_site(raw, p, method):
    out = ig.demosaic(raw, p, method)
    assert out.dtype == raw.dtype and out.shape == (*raw.shape, 3)
    masks = ig.channel_masks(raw.shape, p)
    np.testing.assert_array_equal(out[masks], raw.ravel())


@given(
    dtype=st.sampled_from(DTYPES),
    value=st.floats(0, 1),
    h=st.integers(2, 20),
    w=st.integers(2, 20),
    p=st.sampled_from(BAYER),
    method=st.sampled_from(METHODS),
)
def test_a_constant_mosaic_gives_a_constant_image(dtype, value, h, w, p, method):
    scale = 1.0 if dtype == np.float32 else np.iinfo(dtype).max
    raw = np.full((h, w), value * scale, dtype=np.float64).round().astype(dtype)
    if dtype == np.float32:
        raw = np.full((h, w), value, np.float32)
    out = ig.demosaic(raw, p, method)
    if dtype == np.float32:
        # Malvar's taps (4, 2, -1, 5/8, 3/2) round in float32, and MLRI's means
        # over 5 to 121 samples; the others are exact.
        rtol = 2e-6 if method == "mlri" else 2e-7
        np.testing.assert_allclose(out, raw[0, 0], rtol=rtol, atol=1e-12)
    else:
        assert (out == raw[0, 0]).all()


@given(
    a=st.integers(-40, 40),
    b=st.integers(-40, 40),
    h=st.integers(3, 20),
    w=st.integers(3, 20),
    p=st.sampled_from(BAYER),
    dtype=st.sampled_from(DTYPES),
)
def test_bilinear_reproduces_a_linear_ramp_in_the_interior(a, b, h, w, p, dtype):
    y, x = np.mgrid[0:h, 0:w]
    if dtype == np.uint8:
        a, b = a // 8, b // 8
    ramp = (128 if dtype == np.uint8 else 2000) + a * y + b * x
    assume(dtype != np.uint8 or (0 <= ramp.min() and ramp.max() <= 255))
    raw = ramp.astype(dtype)
    out = ig.demosaic(raw, p, "bilinear")
    want = np.repeat(raw[..., None], 3, axis=2)
    np.testing.assert_array_equal(out[1:-1, 1:-1], want[1:-1, 1:-1])


# The learned filters of "raisr", "raisr_fast", "raisr_cd", "fusion" and
# "fusion_refined", and "fusion_cnn"'s network ("best" and "quality" name learned
# methods) are not mirror-symmetric, so flips change their output slightly;
# tests/test_raisr.py and tests/test_cnn.py check their tile seams by a shift instead.
LEARNED = (
    "raisr",
    "raisr_fast",
    "raisr_cd",
    "best",
    "fusion",
    "fusion_refined",
    "fusion_cnn",
    "quality",
)
FLIP_SYMMETRIC = [m for m in METHODS if m not in LEARNED]


@given(
    raw=mosaics(),
    p=st.sampled_from(BAYER),
    method=st.sampled_from(FLIP_SYMMETRIC),
    vertical=st.booleans(),
    horizontal=st.booleans(),
)
def test_methods_commute_with_the_flips_between_phases(raw, p, method, vertical, horizontal):
    if method == "nearest":
        # Its 2x2 cells are aligned to the array origin: only even sizes map
        # cells onto cells.
        raw = raw[: raw.shape[0] // 2 * 2, : raw.shape[1] // 2 * 2]
    sl = (slice(None, None, -1 if vertical else 1), slice(None, None, -1 if horizontal else 1))
    q = flipped_pattern(p, raw.shape, vertical, horizontal)
    flipped_first = ig.demosaic(np.ascontiguousarray(raw[sl]), q, method)
    np.testing.assert_array_equal(flipped_first, ig.demosaic(raw, p, method)[sl])


@pytest.mark.parametrize("method", [m for m in CLAMPED if m not in LEARNED])
def test_tile_seams_do_not_show(method):
    # The multi-stage methods work in tiles of up to 384 columns (mlri 1536)
    # counted from the left; flipping a wide mosaic moves every seam, so
    # equal results mean the seams leave no trace.
    raw = random_raw(3, 30, 2101, np.uint16)
    q = flipped_pattern("GRBG", raw.shape, False, True)
    flipped_first = ig.demosaic(np.ascontiguousarray(raw[:, ::-1]), q, method)
    np.testing.assert_array_equal(flipped_first, ig.demosaic(raw, "GRBG", method)[:, ::-1])


@given(raw=mosaics(min_side=6), shift=st.tuples(st.integers(0, 5), st.integers(0, 5)))
def test_xtrans_bilinear_keeps_samples_and_the_range(raw, shift):
    pattern = np.roll(ig.channel_masks((6, 6), "XTRANS").argmax(-1), shift, axis=(0, 1))
    out = ig.demosaic(raw, pattern, "bilinear")
    masks = ig.channel_masks(raw.shape, pattern)
    np.testing.assert_array_equal(out[masks], raw.ravel())
    if raw.dtype != np.float32:
        assert raw.min() <= out.min() and out.max() <= raw.max()


@given(value=st.integers(0, 65535), h=st.integers(6, 20), w=st.integers(6, 20))
def test_xtrans_bilinear_keeps_a_constant(value, h, w):
    raw = np.full((h, w), value, np.uint16)
    assert (ig.demosaic(raw, "XTRANS", "bilinear") == value).all()


def test_xtrans_bilinear_reconstructs_a_natural_image():
    data = pytest.importorskip("skimage.data")
    rgb = data.astronaut()
    raw = ig.mosaic(rgb, "XTRANS")
    out = ig.demosaic(raw, "XTRANS", "bilinear").astype(np.float64)
    mse = ((out - rgb)[10:-10, 10:-10] ** 2).mean()
    # Far better than leaving the missing colours at zero (~13 dB); a little
    # below Bayer bilinear on the same image.
    assert 10 * np.log10(255**2 / mse) > 27


def test_results_do_not_depend_on_the_thread_count():
    code = """
        import sys, numpy as np, imgform_rs as ig
        rng = np.random.default_rng(11)
        raw16 = rng.integers(0, 65536, (301, 803), dtype=np.uint16)
        rawf = rng.random((150, 97), dtype=np.float32)
        for m in ig.BAYER_DEMOSAIC_METHODS:
            sys.stdout.buffer.write(ig.demosaic(raw16, "GBRG", m).tobytes())
            sys.stdout.buffer.write(ig.demosaic(rawf, "BGGR", m).tobytes())
        for m in ig.XTRANS_DEMOSAIC_METHODS:
            sys.stdout.buffer.write(ig.demosaic(raw16, "XTRANS", m).tobytes())
            sys.stdout.buffer.write(ig.demosaic(rawf, "XTRANS", m).tobytes())
    """
    one = output_with_threads(code, 1)
    assert len(one) > 0
    assert one == output_with_threads(code, 2)


@pytest.mark.parametrize("p", BAYER)
@pytest.mark.parametrize(
    ("method", "peer"),
    [
        ("bilinear", "demosaicing_CFA_Bayer_bilinear"),
        ("malvar2004", "demosaicing_CFA_Bayer_Malvar2004"),
    ],
)
def test_linear_methods_match_colour_demosaicing_in_the_interior(p, method, peer):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cd = pytest.importorskip("colour_demosaicing")
    raw = random_raw(21, 37, 50, np.float32)
    want = getattr(cd, peer)(raw.astype(np.float64), p)
    got = ig.demosaic(raw, p, method)
    np.testing.assert_allclose(got[2:-2, 2:-2], want[2:-2, 2:-2], rtol=0, atol=1e-5)


@pytest.mark.parametrize("p", BAYER)
def test_menon2007_matches_colour_demosaicing_in_the_interior(p):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cd = pytest.importorskip("colour_demosaicing")
    # No exact ties in the a posteriori decision on this image, which
    # float32 and float64 could break apart.
    raw = ig.mosaic(smooth_rgb(5, 60, 70), p)
    want = cd.demosaicing_CFA_Bayer_Menon2007(raw.astype(np.float64), p)
    want = np.clip(want, raw.min(), raw.max())
    got = ig.demosaic(raw, p, "menon2007")
    np.testing.assert_allclose(got[10:-10, 10:-10], want[10:-10, 10:-10], rtol=0, atol=2e-6)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize(
    ("p", "code"),
    # OpenCV names Bayer codes after the second row: our RGGB is its BayerBG.
    [("RGGB", "BG"), ("BGGR", "RG"), ("GRBG", "GB"), ("GBRG", "GR")],
)
def test_bilinear_equals_opencv_in_the_interior(dtype, p, code):
    cv2 = pytest.importorskip("cv2")
    raw = random_raw(4, 40, 51, dtype)
    want = cv2.cvtColor(raw, getattr(cv2, f"COLOR_Bayer{code}2RGB"))
    np.testing.assert_array_equal(ig.demosaic(raw, p, "bilinear")[1:-1, 1:-1], want[1:-1, 1:-1])


def test_adaptive_methods_beat_bilinear_on_a_natural_image():
    data = pytest.importorskip("skimage.data")
    rgb = data.astronaut()
    raw = ig.mosaic(rgb, "RGGB")

    def mse(method):
        out = ig.demosaic(raw, "RGGB", method).astype(np.float64)
        return ((out - rgb)[10:-10, 10:-10] ** 2).mean()

    errors = {m: mse(m) for m in METHODS}
    assert errors["bilinear"] < errors["nearest"]
    assert errors["malvar2004"] < errors["bilinear"]
    assert errors["hamilton_adams"] < errors["bilinear"]
    # RCD's ratio-corrected green beats Hamilton-Adams' (38.7 vs 38.1 dB mean
    # CPSNR on the benchmark's seven images).
    assert errors["rcd"] < errors["hamilton_adams"]
    assert errors["menon2007"] < errors["hamilton_adams"]
    assert errors["rcd_menon"] < min(errors["rcd"], errors["menon2007"])
    assert errors["ahd"] < errors["malvar2004"]
    # The frequency-domain method is at least 1 dB better than Malvar's.
    assert errors["leung2011"] < errors["malvar2004"] / 10**0.1
    # Residual interpolation beats both of the single methods it competes
    # with (39.80 dB mean CPSNR on the benchmark's seven images against 38.7 /
    # 38.8; 38.89 on CBSD68 against 35.0 / 37.6).
    assert errors["mlri"] < min(errors["rcd"], errors["menon2007"])


@pytest.mark.parametrize("name", ["grass", "gravel"])
def test_mlri_leads_on_fine_grey_texture(name):
    # Any chroma is an error on a grey image, and fine texture is where the
    # green stage's choice of direction decides. Weighing the directions
    # over 5x5 gradient windows (RI's) rather than the MLRI code's 3x3 ones
    # is worth 2.4 / 2.7 dB here (33.4 / 39.9 dB against 31.0 / 37.2), RI's
    # green regression 0.3 / 0.6 more: 1.8 / 2.2 dB above the RCD / Menon
    # mean, which the MLRI code's choices trailed.
    data = pytest.importorskip("skimage.data")
    grey = getattr(data, name)()
    rgb = np.repeat(grey[..., None], 3, axis=2)
    raw = ig.mosaic(rgb, "RGGB")

    def cpsnr(method):
        out = ig.demosaic(raw, "RGGB", method).astype(np.float64)
        return 10 * np.log10(255**2 / ((out - rgb)[10:-10, 10:-10] ** 2).mean())

    assert cpsnr("mlri") > cpsnr("rcd_menon") + 1.0


def test_borders_are_mirrored_not_black_or_wrapped():
    # Wider than MLRI's reach (30 columns), so only wrapping could carry the
    # bright last column into the first.
    raw = np.full((9, 40), 1000, np.uint16)
    raw[:, -1] = 3000  # a bright last column must not leak into the first
    for method in METHODS:
        out = ig.demosaic(raw, "GRBG", method)
        assert (out[:, 0] == 1000).all(), method
        assert out.min() > 0, method


def test_non_contiguous_input_gives_the_same_result():
    raw = random_raw(8, 30, 40, np.uint16)
    for view in [raw[:, ::-1][:, ::-1], np.asfortranarray(raw), raw.T.copy().T]:
        np.testing.assert_array_equal(ig.demosaic(view, "RGGB"), ig.demosaic(raw, "RGGB"))


@given(raw=mosaics(min_side=6), p=st.sampled_from([*BAYER, "XTRANS"]), data=st.data())
def test_out_receives_the_result_a_new_array_would_hold(raw, p, data):
    methods = ig.XTRANS_DEMOSAIC_METHODS if p == "XTRANS" else METHODS
    method = data.draw(st.sampled_from(methods))
    # Stale values in the buffer must not leak into the result.
    out = np.full((*raw.shape, 3), 7, raw.dtype)
    assert ig.demosaic(raw, p, method, out=out) is out
    np.testing.assert_array_equal(out, ig.demosaic(raw, p, method))


def test_out_can_be_reused_across_images():
    out = np.empty((30, 40, 3), np.uint16)
    for seed in range(3):
        raw = random_raw(seed, 30, 40, np.uint16)
        ig.demosaic(raw, "GRBG", "best", out=out)
        np.testing.assert_array_equal(out, ig.demosaic(raw, "GRBG", "best"))


def read_only(a):
    a.flags.writeable = False
    return a


U16 = np.zeros((8, 10), np.uint16)
SHARED = np.zeros((8, 10, 3), np.uint16)


@pytest.mark.parametrize(
    ("raw", "out", "exc", "match"),
    [
        (U16, np.empty((8, 10, 3), np.float32), TypeError, "dtype uint16.*dtype float32"),
        (U16, [[0.0]], TypeError, "dtype uint16.*got an object of type list"),
        (U16, np.empty((8, 10, 4), np.uint16), ValueError, r"shape \[8, 10, 3\], got \[8, 10, 4\]"),
        (U16, np.empty((10, 8, 3), np.uint16), ValueError, r"shape \[8, 10, 3\]"),
        (U16, np.empty((8, 10, 3), np.uint16, order="F"), ValueError, "C-contiguous"),
        (U16, np.empty((8, 20, 3), np.uint16)[:, ::2], ValueError, "C-contiguous"),
        (U16, read_only(np.empty((8, 10, 3), np.uint16)), ValueError, "not writeable"),
        (SHARED[..., 1], SHARED, ValueError, "share no memory with the input"),
    ],
)
def test_a_bad_out_names_what_is_wrong(raw, out, exc, match):
    with pytest.raises(exc, match=match):
        ig.demosaic(raw, "RGGB", "rcd", out=out)


Z8 = np.zeros((4, 4), np.uint8)
SHAPE = r"\(2, 2\) or \(6, 6\), got \(3, 3\)"
DTYPE = "integer or float array"


def float_with(value, shape, at):
    raw = np.zeros(shape, np.float32)
    raw[at] = value
    return raw


@pytest.mark.parametrize(
    ("raw", "pattern", "method", "exc", "match"),
    [
        (np.zeros((4, 4, 3), np.uint8), "RGGB", "bilinear", ValueError, r"shape \(H, W\), got"),
        (np.zeros((4, 4), np.complex128), "RGGB", "bilinear", TypeError, DTYPE + ".*complex128"),
        (np.zeros((4, 4), bool), "RGGB", "bilinear", TypeError, DTYPE + ".*bool"),
        (np.full((4, 4), -3, np.int16), "RGGB", "rcd", ValueError, r"0\.\.65535.*got -3\.\.-3"),
        (np.full((4, 4), 70000, np.int32), "RGGB", "rcd", ValueError, r"int32.*70000"),
        (np.full((4, 4), 1e39), "RGGB", "rcd", ValueError, "beyond float32's range"),
        (
            float_with(np.nan, (4, 4), (2, 3)).astype(np.float64),
            "RGGB",
            "rcd",
            ValueError,
            "NaN at row 2, column 3",
        ),
        (Z8, "RGBX", "bilinear", ValueError, "unknown CFA pattern.*accepted"),
        (Z8, "RGGB", "vng", ValueError, r'unknown demosaicing method "vng"; accepted: \["nearest"'),
        (Z8, "RGGB", None, TypeError, "method must be a str"),
        (Z8, np.zeros((3, 3), int), "bilinear", ValueError, SHAPE),
        (Z8, "XTRANS", "rcd", ValueError, 'supports the Bayer patterns.*X-Trans.*"bilinear"'),
        (Z8, "XTRANS", "bilinear", ValueError, r"X-Trans mosaic of at least 6x6 .*got \(4, 4\)"),
        (None, "RGGB", "bilinear", TypeError, "got None"),
        (Z8, None, "bilinear", TypeError, "got None"),
        (np.zeros((0, 4), np.uint8), "RGGB", "bilinear", ValueError, "must not be empty"),
        (np.zeros((1, 5), np.uint8), "RGGB", "bilinear", ValueError, r"2x2 .*got \(1, 5\)"),
        (float_with(np.nan, (4, 4), (1, 2)), "RGGB", "rcd", ValueError, "NaN at row 1, column 2"),
        (float_with(-np.inf, (6, 6), (5, 5)), "XTRANS", "markesteijn", ValueError, "-inf at row 5"),
        # Sums of neighbours of 3e38 overflowed: infinities, or clamped samples.
        (float_with(3e38, (4, 4), (3, 1)), "RGGB", "ahd", ValueError, "2\\^100.*row 3, column 1"),
        (float_with(-1e31, (6, 6), (0, 4)), "XTRANS", "bilinear", ValueError, "row 0, column 4"),
    ],
)
def test_bad_input_names_what_was_given_and_what_is_accepted(raw, pattern, method, exc, match):
    with pytest.raises(exc, match=match):
        ig.demosaic(raw, pattern, method)


def test_native_layer_checks_too():
    from imgform_rs import _native

    with pytest.raises(TypeError, match="pattern must be a str"):
        _native.demosaic(np.zeros((4, 4), np.uint8), 3.5, "bilinear")


def test_mlri_beats_colour_demosaicing_menon2007():
    cd = pytest.importorskip("colour_demosaicing")
    data = pytest.importorskip("skimage.data")
    rgb = data.astronaut()
    raw = ig.mosaic(rgb, "RGGB")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        peer = cd.demosaicing_CFA_Bayer_Menon2007(raw.astype(np.float64), "RGGB")
    peer = np.clip(np.round(peer), 0, 255)

    def cpsnr(out):
        mse = ((out.astype(np.float64) - rgb)[10:-10, 10:-10] ** 2).mean()
        return 10 * np.log10(255**2 / mse)

    # 37.1 dB against 36.1 on this image.
    assert cpsnr(ig.demosaic(raw, "RGGB", "mlri")) > cpsnr(peer) + 0.5


# Other dtypes: converted on the way in and back out (imgform_rs._samples).

OTHER_INTS = [np.int8, np.int16, np.int32, np.int64, np.uint32, np.uint64, np.dtype(">u2")]


@given(
    dtype=st.sampled_from(OTHER_INTS),
    method=st.sampled_from(METHODS),
    pattern=st.sampled_from(BAYER),
    seed=st.integers(0, 2**32 - 1),
)
def test_other_integers_demosaic_exactly_as_uint16(dtype, method, pattern, seed):
    top = min(np.iinfo(dtype).max, 65535)
    raw = np.random.default_rng(seed).integers(0, top, (9, 12), endpoint=True)
    got = ig.demosaic(raw.astype(dtype), pattern, method)
    want = ig.demosaic(raw.astype(np.uint16), pattern, method)
    assert got.dtype == np.dtype(dtype)
    # The uint16 result, only clamped to the narrower top of int8 / int16.
    np.testing.assert_array_equal(got, np.minimum(want, top))


@given(method=st.sampled_from(METHODS), seed=st.integers(0, 2**32 - 1))
def test_float64_demosaics_with_float32_precision(method, seed):
    raw = np.random.default_rng(seed).random((10, 14))
    got = ig.demosaic(raw, "GRBG", method)
    assert got.dtype == np.float64
    np.testing.assert_array_equal(got, ig.demosaic(raw.astype(np.float32), "GRBG", method))
    # Each sample comes back at its own site to float32's precision.
    np.testing.assert_allclose(ig.mosaic(got, "GRBG"), raw, rtol=6e-8, atol=0)


def test_float16_goes_through_float32_exactly():
    raw = np.random.default_rng(3).random((8, 8)).astype(np.float16)
    got = ig.demosaic(raw, "RGGB", "bilinear")
    assert got.dtype == np.float16
    want = ig.demosaic(raw.astype(np.float32), "RGGB", "bilinear").astype(np.float16)
    np.testing.assert_array_equal(got, want)


def test_scikit_image_float_images_demosaic():
    skimage = pytest.importorskip("skimage")
    rgb = skimage.util.img_as_float(skimage.data.astronaut()[100:164, 100:164])
    assert rgb.dtype == np.float64
    out = ig.demosaic(ig.mosaic(rgb, "RGGB"), "RGGB", "best")
    assert out.dtype == np.float64 and out.shape == rgb.shape
    mse = ((out - rgb)[4:-4, 4:-4] ** 2).mean()
    assert 10 * np.log10(1 / mse) > 28


def test_out_takes_the_dtype_given():
    raw = np.random.default_rng(4).integers(0, 1000, (8, 10)).astype(np.int32)
    out = np.full((8, 10, 3), -1, np.int32)
    assert ig.demosaic(raw, "RGGB", "rcd", out=out) is out
    np.testing.assert_array_equal(out, ig.demosaic(raw, "RGGB", "rcd"))
    for bad, exc, match in [
        (np.empty((8, 10, 3), np.uint16), TypeError, "dtype int32, got dtype uint16"),
        (np.empty((8, 10, 4), np.int32), ValueError, r"shape \[8, 10, 3\], got \[8, 10, 4\]"),
        (np.empty((8, 10, 3), np.int32, order="F"), ValueError, "C-contiguous"),
        (read_only(np.empty((8, 10, 3), np.int32)), ValueError, "not writeable"),
    ]:
        with pytest.raises(exc, match=match):
            ig.demosaic(raw, "RGGB", "rcd", out=bad)


@given(
    dtype=st.sampled_from([np.float64, np.float16, np.int64, np.int8, np.uint32]),
    pattern=st.sampled_from([*BAYER, "XTRANS"]),
    seed=st.integers(0, 2**32 - 1),
)
def test_mosaic_of_any_dtype_samples_exactly(dtype, pattern, seed):
    rgb = (np.random.default_rng(seed).random((7, 13, 3)) * 100).astype(dtype)
    got = ig.mosaic(rgb, pattern)
    assert got.dtype == np.dtype(dtype) and got.flags.c_contiguous
    masks = ig.channel_masks((7, 13), pattern)
    np.testing.assert_array_equal(got, rgb[masks].reshape(7, 13))


SCALED = set(ig.SCALED_DEMOSAIC_METHODS)


def test_the_scaled_methods_are_the_documented_ones():
    classical = {"rcd", "rcd_menon", "ahd", "mlri", "ri_cd"}
    assert SCALED == classical | set(LEARNED)


@given(
    raw=mosaics(min_side=6).map(lambda r: r.astype(np.float32) / max(float(r.max()), 1.0)),
    p=st.sampled_from([*BAYER, "XTRANS"]),
    exponent=st.integers(-4, 8),
    data=st.data(),
)
def test_results_scale_exactly_with_the_white_level(raw, p, exponent, data):
    # A power of two scales every float operation exactly, so the mosaic and
    # its white level scaled together scale the result bit for bit: no method
    # hides a threshold in absolute units.
    method = data.draw(st.sampled_from(ig.XTRANS_DEMOSAIC_METHODS if p == "XTRANS" else METHODS))
    s = np.float32(2.0**exponent)
    level = float(s) if method in SCALED else None
    expected = ig.demosaic(raw, p, method) * s
    np.testing.assert_array_equal(ig.demosaic(raw * s, p, method, white_level=level), expected)
    if method not in SCALED:
        # ...and the white level changes nothing for the others.
        np.testing.assert_array_equal(ig.demosaic(raw, p, method, white_level=7.0), expected / s)


@pytest.mark.parametrize("method", sorted(SCALED - {"best", "quality"}))
def test_integer_mosaics_are_taken_at_their_bit_depth(method):
    # Raw files keep 10- to 14-bit photosites in uint16: at uint16's full
    # scale they would look 4 to 64 times darker than they are.
    data = pytest.importorskip("skimage.data")
    rgb = data.astronaut()[120:248, 160:288]

    def cpsnr(out, shift):
        err = (out.astype(np.float64) / 2**shift - rgb)[10:-10, 10:-10]
        return 10 * np.log10(255**2 / (err**2).mean())

    eight = cpsnr(ig.demosaic(ig.mosaic(rgb, "RGGB"), "RGGB", method), 0)
    for bits in (10, 12, 14):
        shift = bits - 8
        raw = ig.mosaic(rgb.astype(np.uint16) << shift, "RGGB")
        out = ig.demosaic(raw, "RGGB", method)
        given = ig.demosaic(raw, "RGGB", method, white_level=2**bits - 1)
        np.testing.assert_array_equal(out, given)
        assert abs(cpsnr(out, shift) - eight) < 0.05, bits
    # 8-bit samples in uint16 are demosaicked exactly as in uint8.
    raw8 = ig.mosaic(rgb, "RGGB")
    np.testing.assert_array_equal(
        ig.demosaic(raw8.astype(np.uint16), "RGGB", method),
        ig.demosaic(raw8, "RGGB", method).astype(np.uint16),
    )


def test_float_mosaics_beyond_one_are_taken_up_to_their_largest_sample():
    data = pytest.importorskip("skimage.data")
    # Detail and colour enough for the level to show: the face, hair and flag.
    rgb = data.astronaut()[100:356, 100:356]
    raw = ig.mosaic(rgb, "RGGB").astype(np.float32)
    out = ig.demosaic(raw, "RGGB", "quality")
    np.testing.assert_array_equal(out, ig.demosaic(raw, "RGGB", "quality", white_level=raw.max()))

    def mse(o):
        return ((o - rgb)[10:-10, 10:-10] ** 2).mean()

    # As well on 0..255 as on 0..1, not as if 255 times brighter.
    unit = ig.demosaic(raw / raw.max(), "RGGB", "quality") * raw.max()
    assert abs(mse(out) / mse(unit) - 1) < 0.01
    assert mse(ig.demosaic(raw, "RGGB", "quality", white_level=1.0)) > mse(out) * 1.05


@given(
    h=st.integers(2, 24),
    w=st.integers(2, 24),
    seed=st.integers(0, 2**32 - 1),
    p=st.sampled_from([*BAYER, "XTRANS"]),
    data=st.data(),
)
def test_8_bit_samples_demosaic_alike_in_uint8_and_uint16(h, w, seed, p, data):
    assume(p != "XTRANS" or min(h, w) >= 6)
    method = data.draw(st.sampled_from(ig.XTRANS_DEMOSAIC_METHODS if p == "XTRANS" else METHODS))
    raw = random_raw(seed, h, w, np.uint8)
    # The same white level, so the same values up to uint8's clamp of the
    # methods that overshoot.
    wide = np.minimum(ig.demosaic(raw.astype(np.uint16), p, method), 255)
    np.testing.assert_array_equal(wide, ig.demosaic(raw, p, method))


def test_the_learned_methods_need_the_right_white_level():
    data = pytest.importorskip("skimage.data")
    rgb = data.astronaut()[120:248, 160:288]
    raw = ig.mosaic(rgb.astype(np.uint16) << 4, "RGGB")

    def mse(level):
        out = ig.demosaic(raw, "RGGB", "quality", white_level=level).astype(np.float64) / 16
        return ((out - rgb)[10:-10, 10:-10] ** 2).mean()

    # uint16's full scale for 12-bit data costs more than 0.3 dB.
    assert mse(65535) > mse(4095) * 10**0.03


@pytest.mark.parametrize(
    ("level", "exc", "match"),
    [
        ("255", TypeError, "white_level must be a real number or None, got '255'"),
        (True, TypeError, "white_level must be a real number"),
        (0, ValueError, "white_level must be a finite number > 0 within float32's range, got 0"),
        (-1.5, ValueError, "got -1.5"),
        (np.nan, ValueError, "got nan"),
        (np.inf, ValueError, "got inf"),
        (1e39, ValueError, "got 1e[+]?39"),
        (1e-50, ValueError, "got 1e-50"),
        (10**400, ValueError, "within float32's range, got 1000"),
    ],
)
def test_a_bad_white_level_names_what_is_accepted(level, exc, match):
    with pytest.raises(exc, match=match):
        ig.demosaic(Z8, "RGGB", "mlri", white_level=level)


def test_native_layer_checks_the_white_level_too():
    from imgform_rs import _native

    with pytest.raises(ValueError, match="white_level must be a finite number > 0, got 0"):
        _native.demosaic(np.zeros((4, 4), np.float32), "RGGB", "mlri", white_level=0.0)


def test_float16_results_past_its_largest_number_stay_finite():
    # Malvar's and Hamilton-Adams's overshoot beyond float16's 65504.
    g = ig.channel_masks((10, 10), "RGGB")[..., 1]
    raw = np.where(g, np.float16(60000), np.float16(0)).astype(np.float16)
    for method in ("malvar2004", "hamilton_adams"):
        assert np.isfinite(ig.demosaic(raw, "RGGB", method)).all()

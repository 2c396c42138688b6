import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import imgform_rs as ig
from conftest import output_with_threads
from imgform_rs.dng import write_dng

BAYER = ["RGGB", "BGGR", "GRBG", "GBRG"]
DTYPES = [np.uint8, np.uint16, np.float32]
patterns = st.sampled_from([*BAYER, "XTRANS"])


def random_rgb(rng, h, w, dtype):
    if dtype == np.float32:
        return rng.random((h, w, 3), dtype=np.float32)
    return rng.integers(0, np.iinfo(dtype).max, (h, w, 3), endpoint=True).astype(dtype)


@pytest.mark.parametrize("name", BAYER)
def test_names_and_arrays_describe_the_same_tile(name):
    cells = ig.pattern_cells(name)
    assert "".join("RGB"[c] for c in cells.ravel()) == name
    assert ig.shift_pattern(cells, 0, 0) == name
    # A 6x6 array repeating the tile is the same Bayer pattern.
    assert ig.shift_pattern(np.tile(cells, (3, 3)), 0, 0) == name


def test_xtrans_tile_has_its_colour_counts_and_every_colour_in_every_line():
    t = ig.pattern_cells("XTRANS")
    assert np.bincount(t.ravel()).tolist() == [8, 20, 8]
    for line in [*t, *t.T]:
        assert set(line.tolist()) == {0, 1, 2}
    # Shifted, flipped and transposed tiles are X-Trans too; shifts come back as arrays.
    shifted = ig.shift_pattern("XTRANS", 2, 3)
    assert isinstance(shifted, np.ndarray)
    for variant in [shifted, t[::-1], t[:, ::-1], t.T]:
        np.testing.assert_array_equal(ig.pattern_cells(variant), variant)


@given(p=patterns, a=st.integers(-20, 20), b=st.integers(-20, 20), c=st.integers(-20, 20))
def test_shifts_compose(p, a, b, c):
    once = ig.pattern_cells(ig.shift_pattern(p, a + c, b - c))
    twice = ig.pattern_cells(ig.shift_pattern(ig.shift_pattern(p, a, b), c, -c))
    np.testing.assert_array_equal(once, twice)


@pytest.mark.parametrize(("dy", "dx"), [(1.7, 0), (0, 1.0), (np.float64(2), 0), (True, 0)])
def test_shift_pattern_refuses_shifts_that_are_not_ints(dy, dx):
    """1.7 was truncated to 1: no crop removes a fraction of a row."""
    with pytest.raises(TypeError, match=r"d[yx] must be an int \(rows or columns cropped\)"):
        ig.shift_pattern("RGGB", dy, dx)


@given(p=patterns, a=st.integers(-(2**80), 2**80), b=st.integers(-(2**80), 2**80))
def test_any_int_shift_is_its_remainder_modulo_the_tile(p, a, b):
    """Beyond the native isize too (an OverflowError before)."""
    np.testing.assert_array_equal(
        ig.pattern_cells(ig.shift_pattern(p, a, b)),
        ig.pattern_cells(ig.shift_pattern(p, a % 6, b % 6)),
    )


@given(
    p=patterns,
    dy=st.integers(0, 7),
    dx=st.integers(0, 7),
    dtype=st.sampled_from(DTYPES),
    seed=st.integers(0, 2**32 - 1),
)
def test_cropping_and_shift_pattern_agree_with_mosaic(p, dy, dx, dtype, seed):
    rgb = random_rgb(np.random.default_rng(seed), 15, 14, dtype)
    whole = ig.mosaic(rgb, p)
    crop = ig.mosaic(rgb[dy:, dx:], ig.shift_pattern(p, dy, dx))
    np.testing.assert_array_equal(crop, whole[dy:, dx:])


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("p", [*BAYER, "XTRANS"])
def test_mosaic_is_the_masked_sum(dtype, p):
    rgb = random_rgb(np.random.default_rng(3), 13, 19, dtype)
    masks = ig.channel_masks((13, 19), p)
    assert masks.dtype == np.bool_ and masks.shape == (13, 19, 3)
    assert (masks.sum(-1) == 1).all()
    got = ig.mosaic(rgb, p)
    assert got.dtype == dtype
    np.testing.assert_array_equal(got, rgb[masks].reshape(13, 19))
    # Non-contiguous input gives the same result.
    np.testing.assert_array_equal(ig.mosaic(np.asfortranarray(rgb), p), got)


@pytest.mark.parametrize(
    ("pattern", "exc", "match"),
    [
        ("RGBG", ValueError, r'unknown CFA pattern "RGBG".*accepted'),
        (None, TypeError, "got None"),
        ([[0, 1], [2, 1]], ValueError, "greens on a diagonal"),
        ([[0, 1, 1], [2, 1, 0], [1, 1, 1]], ValueError, r"\(2, 2\) or \(6, 6\), got \(3, 3\)"),
        ([0, 1, 1, 2], ValueError, r"shape \(2, 2\) or \(6, 6\), got \[4\]"),
        ([[0, 1], [1, 3]], ValueError, "channel indices"),
        (np.zeros((6, 6), np.int64), ValueError, "X-Trans"),
        ([[0.0, 1.0], [1.0, 2.0]], TypeError, "got dtype float64"),
        (3, TypeError, "got the scalar 3"),
        # Beyond int64: the message named the wrapped value (-1).
        (np.array([[2**64 - 1, 1], [1, 2]], np.uint64), ValueError, "got 18446744073709551615"),
    ],
)
def test_bad_patterns_say_what_is_accepted(pattern, exc, match):
    with pytest.raises(exc, match=match):
        ig.pattern_cells(pattern)


@pytest.mark.parametrize(
    ("rgb", "exc", "match"),
    [
        (np.zeros((4, 4), np.uint8), ValueError, r"shape \(H, W, 3\), got \[4, 4\]"),
        (np.zeros((4, 4, 4), np.uint8), ValueError, r"\(H, W, 3\)"),
        (np.zeros((4, 4, 3), np.complex64), TypeError, "integer or float.*complex64"),
        (np.zeros((4, 4, 3), bool), TypeError, "dtype bool"),
        (np.zeros((4, 4), np.int64), ValueError, r"shape \(H, W, 3\), got \[4, 4\]"),
        (np.zeros((0, 4, 3), np.float64), ValueError, "must not be empty"),
        (np.zeros((0, 4, 3), np.uint8), ValueError, "must not be empty"),
        (None, TypeError, "got None"),
    ],
)
def test_bad_images_say_what_is_accepted(rgb, exc, match):
    with pytest.raises(exc, match=match):
        ig.mosaic(rgb, "RGGB")


@pytest.mark.parametrize("shape", [(0, 3), (True, 5), (10**20, 5), (2.0, 3), [4]])
def test_channel_masks_checks_its_shape(shape):
    with pytest.raises(ValueError, match=r"shape must be a tuple \(H, W\) of two ints"):
        ig.channel_masks(shape, "RGGB")


def test_sensor_levels_noise_and_seed():
    flat = np.full((100, 120, 3), 0.5, np.float32)
    kw = {"full_well": 8000.0, "read_noise": 4.0, "bit_depth": 14, "black_level": 512}
    raw = ig.simulate_sensor(flat, "RGGB", seed=1, **kw)
    assert raw.dtype == np.uint16 and raw.shape == (100, 120)
    gain = (2**14 - 1 - 512) / 8000.0
    electrons = (raw.astype(np.float64) - 512) / gain
    assert abs(electrons.mean() - 4000) < 2
    # Photon variance equals the mean; read variance adds; rounding adds 1/12 DN^2.
    expected_var = 4000 + 16 + 1 / 12 / gain**2
    assert abs(electrons.var() / expected_var - 1) < 0.05
    np.testing.assert_array_equal(raw, ig.simulate_sensor(flat, "RGGB", seed=1, **kw))
    assert (raw != ig.simulate_sensor(flat, "RGGB", seed=2, **kw)).mean() > 0.9
    dark = ig.simulate_sensor(np.zeros_like(flat), "RGGB", read_noise=0.0, black_level=64)
    assert (dark == 64).all()
    bright = ig.simulate_sensor(np.full_like(flat, 2.0), "XTRANS", bit_depth=10)
    assert (bright == 1023).all()


def test_sensor_reads_integer_images_as_fractions_of_full_scale():
    rgb8 = np.full((20, 20, 3), 255, np.uint8)
    raw = ig.simulate_sensor(rgb8, "GBRG", full_well=1e6, read_noise=0.0, bit_depth=12)
    # 1e6 electrons: photon noise is 0.1 % of the signal, 4 DN at most here.
    assert abs(raw.astype(float).mean() - 4095) < 4


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"full_well": 0.0}, "full_well must be"),
        ({"read_noise": -1.0}, "read_noise must be"),
        ({"bit_depth": 17}, "bit_depth must be an int from 1 to 16, got 17"),
        ({"black_level": 5000}, "black_level must be an int from 0 to below the white level 4095"),
        ({"seed": -1}, r"seed must be an int in \[0, 2\*\*64\), got -1"),
        # Were OverflowErrors.
        ({"black_level": -1}, "black_level must be an int from 0 .* got -1"),
        ({"seed": 2**64}, r"seed must be an int in \[0, 2\*\*64\)"),
        # Were truncated to 12 and 1.
        ({"bit_depth": 12.7}, "bit_depth must be an int from 1 to 16, got 12.7"),
        ({"black_level": 1.9}, "black_level must be an int .* got 1.9"),
        ({"bit_depth": True}, "bit_depth must be an int"),
    ],
)
def test_bad_sensor_parameters_are_named(kw, match):
    with pytest.raises(ValueError, match=match):
        ig.simulate_sensor(np.zeros((4, 4, 3), np.float32), "RGGB", **kw)


def test_sensor_parameters_at_their_limits_are_accepted():
    white = np.ones((4, 4, 3), np.float32)
    raw = ig.simulate_sensor(
        white, "RGGB", bit_depth=np.int64(12), black_level=4094, seed=2**64 - 1
    )
    # A full well is the one DN from black to white (its photon noise 1 %).
    assert (raw == 4095).all()


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_sensor_refuses_nan_and_infinite_radiance(value):
    """These have no number of electrons: NaN became the black level, +inf
    0 or the white level."""
    rgb = np.full((6, 8, 3), 0.5, np.float32)
    rgb[3, 5, 2] = value
    with pytest.raises(
        ValueError, match=rf"rgb must hold finite numbers, got {value} at index \(3, 5, 2\)"
    ):
        ig.simulate_sensor(rgb, "RGGB")


def test_sensor_and_mosaic_do_not_depend_on_the_thread_count():
    code = """
        import sys, numpy as np, imgform_rs as ig
        rgb = np.random.default_rng(5).random((301, 257, 3), dtype=np.float32)
        sys.stdout.buffer.write(ig.simulate_sensor(rgb, "GRBG", seed=9).tobytes())
        sys.stdout.buffer.write(ig.mosaic(rgb, "XTRANS").tobytes())
    """
    assert output_with_threads(code, 1) == output_with_threads(code, 2)


@pytest.mark.parametrize("name", BAYER)
def test_dng_round_trips_through_libraw(tmp_path, name):
    rawpy = pytest.importorskip("rawpy")
    mosaic = np.random.default_rng(7).integers(0, 4096, (38, 53), dtype=np.uint16)
    path = tmp_path / "m.dng"
    write_dng(path, mosaic, name, white_level=4095, black_level=128)
    with rawpy.imread(str(path)) as raw:
        np.testing.assert_array_equal(raw.raw_image_visible, mosaic)
        assert ig.pattern_from_rawpy(raw) == name
        assert raw.white_level == 4095
        assert list(raw.black_level_per_channel) == [128] * 4


def test_pattern_from_rawpy_refuses_other_colours():
    class Cmyg:
        raw_pattern = np.array([[0, 1], [2, 3]], np.uint8)
        color_desc = b"CMYG"

    with pytest.raises(ValueError, match="only R, G, B"):
        ig.pattern_from_rawpy(Cmyg())
    Cmyg.raw_pattern = np.array([[0, 1], [4, 2]], np.uint8)  # an IndexError before
    with pytest.raises(ValueError, match="raw_pattern names colour 4, but color_desc 'CMYG'"):
        ig.pattern_from_rawpy(Cmyg())


@pytest.mark.parametrize(
    ("cfa", "kw", "exc", "match"),
    [
        (np.zeros((30, 30), np.float32), {}, TypeError, "uint16.*float32"),
        (np.zeros((30, 30, 3), np.uint16), {}, ValueError, r"\(H, W\) mosaic"),
        (np.zeros((30, 30), np.uint16), {"black_level": 5000}, ValueError, "black_level"),
        # LibRaw read these as a zero matrix and white balance [0, 1, 0, 0].
        (
            np.zeros((30, 30), np.uint16),
            {"color_matrix": np.eye(2)},
            ValueError,
            r"color_matrix must be a finite \(3, 3\) matrix, got shape \(2, 2\)",
        ),
        (
            np.zeros((30, 30), np.uint16),
            {"as_shot_neutral": (0.5, 1)},
            ValueError,
            r"as_shot_neutral must be three finite values > 0 .*got \(0\.5, 1\)",
        ),
        # These raised struct.error.
        (np.zeros((30, 30), np.uint16), {"as_shot_neutral": (-1, 1, 1)}, ValueError, "> 0"),
        (
            np.zeros((30, 30), np.uint16),
            {"color_matrix": np.full((3, 3), 1e12)},
            ValueError,
            r"cannot be written as TIFF SRATIONALs",
        ),
        (np.zeros((30, 30), np.uint16), {"focal_length": 1e12}, ValueError, "TIFF RATIONALs"),
        (np.zeros((30, 30), np.uint16), {"pixel_aspect": 1e12}, ValueError, "0.1..10"),
        (
            np.zeros((30, 30), np.uint16),
            {"color_matrix": [[1, 0, 0], [0, np.nan, 0], [0, 0, 1]]},
            ValueError,
            "color_matrix must be a finite",
        ),
        (np.zeros((30, 30), np.uint16), {"as_shot_neutral": (1, np.inf, 1)}, ValueError, "> 0"),
        (
            np.zeros((30, 30), np.uint16),
            {"forward_matrix": np.eye(4)},
            ValueError,
            r"forward_matrix must be a finite \(3, 3\)",
        ),
    ],
)
def test_dng_writer_refuses_bad_input(tmp_path, cfa, kw, exc, match):
    with pytest.raises(exc, match=match):
        write_dng(tmp_path / "x.dng", cfa, "RGGB", white_level=4095, **kw)
    assert not (tmp_path / "x.dng").exists()

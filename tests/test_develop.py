"""develop: the raw pipeline against LibRaw's colour science, and round trips."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys

import numpy as np
import pytest
import rawpy

import imgform_rs as ig
from conftest import assert_clash_refused, output_with_threads, shared_path
from imgform_rs.dng import write_dng

RAW_DIR = shared_path("data/raw")
PHASES = ["RGGB", "BGGR", "GRBG", "GBRG"]


def bayer_raws() -> list[str]:
    if RAW_DIR is None:
        return []
    lines = (RAW_DIR / "MANIFEST.tsv").read_text().splitlines()
    return [line.split("\t")[0] for line in lines[1:] if line.split("\t")[1] == "bayer"]


def psnr(a: np.ndarray, b: np.ndarray, peak: float, border: int = 8) -> float:
    crop = (slice(border, -border), slice(border, -border))
    err = a[crop].astype(np.float64) - b[crop].astype(np.float64)
    return float(10 * np.log10(peak**2 / np.mean(err**2)))


def libraw(path, **options) -> np.ndarray:
    """rawpy's development with the issue's settings, ``options`` overriding."""
    settings = dict(
        demosaic_algorithm=rawpy.DemosaicAlgorithm.LINEAR,
        use_camera_wb=True,
        output_color=rawpy.ColorSpace.sRGB,
        gamma=(1, 1),
        no_auto_bright=True,
        output_bps=16,
        user_flip=0,
    )
    with rawpy.imread(str(path)) as r:
        return r.postprocess(**{**settings, **options})


def ours(path, **options) -> np.ndarray:
    """Our development with the settings matching :func:`libraw`."""
    settings = dict(
        demosaic="bilinear",
        white_balance="camera",
        color="srgb",
        tone="linear",
        bps=16,
        orientation="none",
    )
    return ig.develop(path, **{**settings, **options})


def smooth_scene(h: int, w: int, lo: float = 0.05, hi: float = 0.7) -> np.ndarray:
    """A smooth colourful linear image in [lo, hi]."""
    y, x = np.mgrid[0:h, 0:w] / max(h, w)
    chans = [
        np.sin(7 * x + 3 * y) + np.cos(5 * y),
        np.cos(6 * x - 4 * y) + np.sin(3 * x),
        np.sin(4 * x * y * 9 + 1) + np.cos(8 * y - 2 * x),
    ]
    rgb = np.stack(chans, -1)
    rgb = (rgb - rgb.min()) / (rgb.max() - rgb.min())
    return (lo + (hi - lo) * rgb).astype(np.float32)


@pytest.mark.skipif(RAW_DIR is None, reason="../shared/data/raw is not present")
@pytest.mark.parametrize("name", bayer_raws())
def test_real_raws_match_libraw_colour_science(name):
    ref = libraw(RAW_DIR / name)
    got = ours(RAW_DIR / name)
    assert got.shape == ref.shape and got.dtype == np.uint16
    assert psnr(got, ref, 65535) >= 40


@pytest.mark.parametrize("pattern", PHASES)
def test_synthetic_dngs_of_every_phase_match_libraw(tmp_path, pattern):
    # A camera unlike sRGB (a non-trivial matrix), an as-shot balance and a
    # black level, so every step of the pipeline is exercised.
    cam_from_xyz = np.array([[1.1, -0.3, -0.1], [-0.4, 1.3, 0.1], [0.0, -0.2, 0.9]])
    cfa = ig.simulate_sensor(
        smooth_scene(96, 128), pattern, full_well=1e7, read_noise=0, black_level=128
    )
    path = tmp_path / f"{pattern}.dng"
    write_dng(
        path,
        cfa,
        pattern,
        white_level=4095 + 128,
        black_level=128,
        color_matrix=cam_from_xyz,
        as_shot_neutral=(0.6, 1.0, 0.75),
    )
    assert psnr(ours(path), libraw(path), 65535) >= 40


def sensor_dng(path, pattern="RGGB", black=0, **kw):
    """A DNG of :func:`smooth_scene` with a black level (or pattern) added."""
    grid = np.atleast_2d(black)
    cfa = ig.simulate_sensor(smooth_scene(96, 128), pattern, full_well=1e7, read_noise=0)
    cfa = cfa + np.tile(grid, (-(-96 // grid.shape[0]), -(-128 // grid.shape[1])))[:96, :128]
    write_dng(path, cfa.astype(np.uint16), pattern, white_level=4095 + 400, black_level=black, **kw)
    return path


# Black-level patterns longer than the 2x2 tile stay a map in LibRaw
# (cblack[6:]); a 2x2 one is folded into the per-channel levels.
BLACK_PATTERNS = {
    "4x4": [[100, 180, 140, 220], [260, 120, 300, 160], [90, 210, 130, 170], [240, 110, 190, 280]],
    "3x2": [[100, 200], [300, 150], [120, 260]],
    "2x2": [[100, 200], [300, 150]],
}


@pytest.mark.parametrize("shape", BLACK_PATTERNS)
def test_black_level_patterns_are_subtracted_as_libraw_does(tmp_path, shape):
    pattern = np.array(BLACK_PATTERNS[shape])
    path = sensor_dng(tmp_path / "black.dng", "GBRG", pattern)
    ref = libraw(path)
    assert psnr(ours(path), ref, 65535) >= 40
    raw = ig.load_raw(path)
    if shape != "2x2":
        # The map matters: without it the result is far off.
        flat = dataclasses.replace(raw, black_map=np.zeros((1, 1)))
        assert psnr(ours(flat), ref, 65535) < 35


def test_a_black_map_on_an_x_trans_sensor_repeats_with_the_common_period(tmp_path):
    # A 4x4 black pattern on the 6x6 X-Trans tile: a 12x12 tile in the core.
    path = sensor_dng(tmp_path / "xt.dng", ig.pattern_cells("XTRANS"), BLACK_PATTERNS["4x4"])
    raw = ig.load_raw(path)
    assert raw.black_map.shape == (4, 4)
    ref = libraw(path)
    assert psnr(ours(raw), ref, 65535) >= 40
    flat = dataclasses.replace(raw, black_map=np.zeros((1, 1)))
    assert psnr(ours(flat), ref, 65535) < 35


@pytest.mark.parametrize("aspect", [1.5, 0.6])
def test_non_square_pixels_are_stretched_as_libraw_does(tmp_path, aspect):
    # Wide photosites add columns, tall ones rows; a turn swaps the two.
    path = sensor_dng(tmp_path / "wide.dng", "GBRG", 64, pixel_aspect=aspect, orientation=6)
    raw = ig.load_raw(path)
    for orientation, flip in [("none", 0), ("auto", None)]:
        got, ref = ours(path, orientation=orientation), libraw(path, user_flip=flip)
        assert got.shape == ref.shape and psnr(got, ref, 65535) >= 40
    assert got.shape[:2] == raw.output_size


@pytest.mark.parametrize("orientation", range(1, 9))
def test_every_exif_orientation_turns_the_image_as_libraw_does(tmp_path, orientation):
    path = sensor_dng(tmp_path / "turned.dng", "GRBG", 64, orientation=orientation)
    raw = ig.load_raw(path)
    got = ours(path, orientation="auto")
    ref = libraw(path, user_flip=None)
    assert got.shape == ref.shape and got.shape[:2] == raw.output_size
    assert psnr(got, ref, 65535) >= 40


# Our white balances and LibRaw's options for the same: grey world, the
# camera's daylight multipliers (pre_mul, LibRaw's default), user multipliers.
LIBRAW_WB = {
    "auto": dict(use_camera_wb=False, use_auto_wb=True),
    "daylight": dict(use_camera_wb=False),
    (2, 1, 1.5): dict(use_camera_wb=False, user_wb=[2, 1, 1.5, 1]),
    "none": dict(use_camera_wb=False, user_wb=[1, 1, 1, 1]),
}


@pytest.mark.skipif(RAW_DIR is None, reason="../shared/data/raw is not present")
@pytest.mark.parametrize(
    ("name", "wb"),
    [
        # Grey world skips blocks near the white LibRaw adjusted to the data
        # (the Blackmagic's range 65023 becomes 64960): 72 dB without that.
        ("blackmagic_pocket_cinema_4k.dng", "auto"),
        # No usable as-shot balance; non-square pixels.
        ("kodak_dc120_P003908_uncompressed.KDC", "auto"),
        ("canon_eos_kiss_x4_magiclantern_colorchart.dng", "daylight"),
    ],
)
def test_real_raws_white_balances_match_libraw(name, wb):
    # The same multipliers as LibRaw's reach about 90 dB (rounding only); a
    # slightly different balance would still pass 40 dB.
    got = ours(RAW_DIR / name, white_balance=wb)
    assert psnr(got, libraw(RAW_DIR / name, **LIBRAW_WB[wb]), 65535) >= 80


# exposure="auto": LibRaw's default brightening (postprocess without
# no_auto_bright). Measured 61.8 dB (PiCamera2: 13x gain on 10-bit data) to
# 92.7 dB on the real raws.
@pytest.mark.skipif(RAW_DIR is None, reason="../shared/data/raw is not present")
@pytest.mark.parametrize("name", bayer_raws())
def test_real_raws_auto_exposure_matches_libraw(name):
    ref = libraw(RAW_DIR / name, no_auto_bright=False)
    assert psnr(ours(RAW_DIR / name, exposure="auto"), ref, 65535) >= 55


def test_auto_exposure_puts_one_percent_at_white_as_libraw(tmp_path):
    path = sensor_dng(tmp_path / "auto.dng", "GRBG", 64, as_shot_neutral=(0.5, 1, 0.7))
    got = ours(path, exposure="auto")
    assert psnr(got, libraw(path, no_auto_bright=False), 65535) >= 55
    # LibRaw's rule on the unbrightened 16-bit image: white goes to the
    # start of the highest bin of 8 codes where, counted from the top, more
    # than 1 % of pixels lie (the largest over the channels). The gain is
    # read off the two images, to within a bin.
    plain = ours(path).astype(np.float64)
    ok = (got < 60000) & (plain > 2000)
    white = 65536 / np.median(got[ok] / plain[ok])
    assert max(np.mean(plain[..., c] >= white - 8) for c in range(3)) > 0.01
    assert max(np.mean(plain[..., c] >= white + 16) for c in range(3)) <= 0.01


def test_auto_exposure_leaves_unclipped_highlights_alone_as_libraw(tmp_path):
    path = sensor_dng(tmp_path / "auto.dng", "RGGB", as_shot_neutral=(0.5, 1, 0.7))
    got = ours(path, exposure="auto", highlights="unclip")
    np.testing.assert_array_equal(got, ours(path, highlights="unclip"))
    ref = libraw(path, no_auto_bright=False, highlight_mode=rawpy.HighlightMode.Ignore)
    assert psnr(got, ref, 65535) >= 40


# Output colour spaces against LibRaw's output_color (linear, as the
# matrices are what is compared; the curves are tested below). Measured
# 83.8-93.8 dB on the real raws (XYZ lowest: its Z clips).
LIBRAW_SPACES = {
    "adobe_rgb": rawpy.ColorSpace.Adobe,
    "display_p3": rawpy.ColorSpace.P3D65,
    "rec2020": rawpy.ColorSpace.Rec2020,
    "prophoto": rawpy.ColorSpace.ProPhoto,
    "xyz": rawpy.ColorSpace.XYZ,
    "aces2065_1": rawpy.ColorSpace.ACES,
}


@pytest.mark.skipif(RAW_DIR is None, reason="../shared/data/raw is not present")
@pytest.mark.parametrize("name", bayer_raws())
def test_real_raws_match_libraw_in_every_colour_space(name):
    if np.array_equal(ig.load_raw(RAW_DIR / name).camera_to_srgb, np.eye(3)):
        # No colour data (the PiDNG without Make/Model): LibRaw ignores
        # output_color and writes camera RGB; we take it as sRGB.
        pytest.skip("LibRaw has no colour matrix for this camera")
    for color, space in LIBRAW_SPACES.items():
        ref = libraw(RAW_DIR / name, output_color=space)
        assert psnr(ours(RAW_DIR / name, color=color), ref, 65535) >= 75, color


def test_colour_space_matrices_match_colour_science():
    colour = pytest.importorskip("colour")
    from imgform_rs.colorspace import COLOR_SPACES, srgb_to

    names = {
        "srgb": "sRGB",
        "adobe_rgb": "Adobe RGB (1998)",
        "display_p3": "Display P3",
        "rec2020": "ITU-R BT.2020",
        "prophoto": "ProPhoto RGB",
        "aces2065_1": "ACES2065-1",
    }
    assert set(names) | {"xyz"} == set(COLOR_SPACES)
    for ours_name, theirs in names.items():
        want = colour.RGB_to_RGB(
            np.eye(3), "sRGB", theirs, chromatic_adaptation_transform="Bradford"
        )
        # colour-science's D50 and ACES white differ from ours in the 5th digit.
        np.testing.assert_allclose(srgb_to(ours_name), want.T, atol=3e-4, err_msg=ours_name)
        assert np.allclose(srgb_to(ours_name).sum(axis=1), 1), "white must stay white"
    srgb = colour.models.RGB_COLOURSPACE_sRGB
    np.testing.assert_allclose(srgb_to("xyz"), srgb.matrix_RGB_to_XYZ, atol=1e-4)


# Each space's own curve (tone="auto") against LibRaw with that curve's
# gamma: rawpy's (1 / exponent, toe slope); 0 is a pure power.
@pytest.mark.parametrize(
    ("color", "gamma"),
    [("adobe_rgb", (563 / 256, 0)), ("prophoto", (1.8, 16)), ("display_p3", (2.4, 12.92))],
)
def test_each_space_is_encoded_with_its_own_curve_as_libraw_would(tmp_path, color, gamma):
    path = sensor_dng(tmp_path / "space.dng", "RGGB", 64, as_shot_neutral=(0.5, 1, 0.7))
    got = ours(path, color=color, tone="auto")
    ref = libraw(path, output_color=LIBRAW_SPACES[color], gamma=gamma)
    assert psnr(got, ref, 65535) >= 45
    assert np.array_equal(ours(path, color="xyz", tone="auto"), ours(path, color="xyz"))


@pytest.mark.parametrize("wb", list(LIBRAW_WB), ids=str)
def test_every_white_balance_matches_libraw(tmp_path, wb):
    path = sensor_dng(tmp_path / "wb.dng", "BGGR", 64, as_shot_neutral=(0.5, 1, 0.7))
    assert psnr(ours(path, white_balance=wb), libraw(path, **LIBRAW_WB[wb]), 65535) >= 40


def test_unclipped_highlights_match_libraw(tmp_path):
    # An over-exposed card: clip and unclip differ wherever a channel clips.
    path = tmp_path / "bright.dng"
    cfa = ig.simulate_sensor(smooth_scene(96, 128, 0.3, 1.0), "RGGB", full_well=1e7, read_noise=0)
    write_dng(path, cfa, "RGGB", white_level=4095, as_shot_neutral=(0.5, 1, 0.7))
    got = ours(path, highlights="unclip")
    ref = libraw(path, highlight_mode=rawpy.HighlightMode.Ignore)
    assert psnr(got, ref, 65535) >= 40 and psnr(ours(path), ref, 65535) < 30


# rawpy's gamma is (1 / exponent, toe slope): sRGB and BT.709 as LibRaw
# builds them. The curves are steep near black, so integer outputs differ by
# a few codes there: the bar is 45 dB.
LIBRAW_GAMMA = {"srgb": (2.4, 12.92), "bt709": (1 / 0.45, 4.5)}


@pytest.mark.parametrize("tone", list(LIBRAW_GAMMA))
@pytest.mark.parametrize("bps", [8, 16])
def test_tone_curves_and_bit_depths_match_libraw(tmp_path, tone, bps):
    path = sensor_dng(tmp_path / "tone.dng", "RGGB", 64, as_shot_neutral=(0.5, 1, 0.7))
    got = ours(path, tone=tone, bps=bps)
    ref = libraw(path, gamma=LIBRAW_GAMMA[tone], output_bps=bps)
    assert got.dtype == ref.dtype and psnr(got, ref, 255 if bps == 8 else 65535) >= 45


def test_round_trip_through_a_dng_recovers_the_scene(tmp_path):
    scene = smooth_scene(128, 160)
    cfa = ig.simulate_sensor(scene, "GRBG", full_well=1e7, read_noise=0, black_level=64)
    path = tmp_path / "scene.dng"
    write_dng(path, cfa, "GRBG", white_level=4095 + 64, black_level=64)
    got = ig.develop(path, tone="linear", bps="float")  # the default, best demosaicer
    assert got.dtype == np.float32 and got.shape == scene.shape
    assert psnr(got, scene, 1.0) >= 35


@pytest.fixture(scope="module")
def grey_card(tmp_path_factory):
    """A synthetic DNG and its RawImage (camera RGB = sRGB, neutral balance)."""
    path = tmp_path_factory.mktemp("dng") / "card.dng"
    cfa = ig.simulate_sensor(smooth_scene(40, 56, hi=0.45), "RGGB", full_well=1e7, read_noise=0)
    write_dng(path, cfa, "RGGB", white_level=4095 + 64, black_level=64)
    return path, ig.load_raw(path)


@pytest.mark.parametrize(
    ("field", "value", "exc", "match"),
    [
        ("cfa", [[1, 2], [3, 4]], TypeError, "RawImage.cfa must be a NumPy array"),
        ("cfa", np.zeros((0, 0), np.uint16), ValueError, r"RawImage.cfa .*got \(0, 0\)"),
        ("cfa", np.zeros((40, 56), np.float32), TypeError, "RawImage.cfa must be a NumPy"),
        ("black_levels", np.zeros(3), ValueError, r"black_levels .*shape \(4\), got \(3,\)"),
        ("black_map", np.zeros((0, 0)), ValueError, r"black_map .*got \(0, 0\)"),
        ("camera_to_srgb", np.eye(3) * np.nan, ValueError, "camera_to_srgb must be finite"),
        ("white_level", "4095", TypeError, "white_level must be an int"),
        ("white_level", 4095.5, TypeError, "RawImage.white_level must be an integer"),
        ("white_level", 10, ValueError, r"black_levels must lie in 0\.\.white_level \(10\)"),
        ("flip", -1, ValueError, "flip is LibRaw's orientation code 0..7, got -1"),
        ("flip", 0.0, TypeError, "RawImage.flip must be an integer, got 0.0"),
        ("pixel_aspect", 0, ValueError, r"pixel_aspect must be in 0\.0625\.\.16, got 0"),
        ("pixel_aspect", 1e-9, ValueError, "pixel_aspect must be in"),
        ("pixel_aspect", "1", TypeError, "RawImage.pixel_aspect must be a real number, got '1'"),
        ("pixel_aspect", True, TypeError, "RawImage.pixel_aspect must be a real number"),
        ("pattern", "GBRG", ValueError, r"channel_tile \[\[0, 1\], \[3, 2\]\] .* 'GBRG'"),
        ("pattern", "RGB", ValueError, "RawImage.pattern: "),
        ("channel_tile", np.array([[0, 1]], np.uint8), ValueError, "not the tile of"),
    ],
)
def test_a_raw_image_with_a_field_develop_cannot_use_is_named(grey_card, field, value, exc, match):
    # Before: AttributeError, IndexError, ZeroDivisionError, MemoryError (298 GiB),
    # a flip of -1 silently read as a transpose, a flip of 0.0 a TypeError on
    # "&" and a pixel aspect of True read as 1.
    _, raw = grey_card
    with pytest.raises(exc, match=match):
        ig.develop(dataclasses.replace(raw, **{field: value}))


def test_a_crop_that_shifts_the_pattern_and_the_tile_develops_as_the_whole(grey_card):
    # Before, a crop that shifted only the pattern developed in false colour:
    # the white balance and black levels follow the tile.
    _, raw = grey_card
    crop = dataclasses.replace(
        raw,
        cfa=raw.cfa[1:, 1:],
        pattern=ig.shift_pattern(raw.pattern, 1, 1),
        channel_tile=np.roll(raw.channel_tile, (-1, -1), (0, 1)),
    )
    # Bilinear: its interior does not depend on the phase (learned filters do).
    whole, part = (ig.develop(r, bps=16, exposure=0, demosaic="bilinear") for r in (raw, crop))
    np.testing.assert_array_equal(part[2:-2, 2:-2], whole[1:, 1:][2:-2, 2:-2])


def test_output_types_and_tone_curves_agree(grey_card):
    _, raw = grey_card
    # Bilinear: Hamilton-Adams' direction choice may flip on a rounded input.
    lin = ig.develop(raw, tone="linear", bps="float", demosaic="bilinear")
    for bps, dtype, peak in [(8, np.uint8, 255), (16, np.uint16, 65535)]:
        out = ig.develop(raw, tone="linear", bps=bps, demosaic="bilinear")
        assert out.dtype == dtype and out.shape == lin.shape
        # The integer path rounds twice (16-bit mosaic, then the output).
        assert np.abs(out / peak - lin).max() <= 1 / peak
    srgb = ig.develop(raw, tone="srgb", bps="float", demosaic="bilinear")
    curve = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)
    np.testing.assert_allclose(srgb, curve, atol=1e-5)
    bt709 = ig.develop(raw, tone="bt709", bps="float", demosaic="bilinear")
    assert np.all(bt709 >= lin - 1e-6)
    assert set(ig.TONES) == {"srgb", "linear", "bt709", "gamma22", "romm"}
    gamma22 = ig.develop(raw, tone="gamma22", bps="float", demosaic="bilinear")
    np.testing.assert_allclose(gamma22, lin ** (256 / 563), atol=1e-5)
    romm = ig.develop(raw, tone="romm", bps="float", demosaic="bilinear")
    np.testing.assert_allclose(romm, np.where(lin < 1 / 512, 16 * lin, lin ** (1 / 1.8)), atol=1e-5)


def test_exposure_and_white_balance_scale_linear_light(grey_card):
    _, raw = grey_card
    # RCD / Menon scale with the light; the default ("best", MLRI) does not
    # quite: its guided filters' floor on flat guides is a fixed fraction of
    # the full scale, so doubling the light moves where the floor applies.
    opts = dict(tone="linear", bps="float", white_balance="none", demosaic="rcd_menon")
    base = ig.develop(raw, **opts)
    brighter = ig.develop(raw, **opts, exposure=1)
    np.testing.assert_allclose(brighter, np.minimum(2 * base, 1), atol=1e-5)
    explicit = ig.develop(raw, **{**opts, "white_balance": (1, 1, 1)})
    np.testing.assert_array_equal(explicit, base)
    # Multipliers are normalised to the smallest: (2, 1, 1) doubles red only
    # (bilinear keeps the channels independent).
    opts = dict(tone="linear", bps="float", color="camera", demosaic="bilinear")
    plain = ig.develop(raw, white_balance="none", **opts)
    red = ig.develop(raw, white_balance=(2, 1, 1), **opts)
    np.testing.assert_allclose(red[..., 0], 2 * plain[..., 0], atol=1e-5)
    np.testing.assert_allclose(red[..., 1:], plain[..., 1:], atol=1e-6)
    for wb in ("camera", "daylight", "auto"):
        assert ig.develop(raw, white_balance=wb).dtype == np.uint8


def test_bad_options_are_refused(grey_card):
    _, raw = grey_card
    cases = [
        (dict(bps=12), "bps must be 8, 16"),
        (dict(color="wide_gamut"), "color must be one of"),
        (dict(tone="gamma"), "tone must be one of"),
        (dict(highlights="blend"), "highlights must be"),
        (dict(orientation="left"), "orientation must be"),
        (dict(white_balance="tungsten"), "white_balance must be one of"),
        (dict(white_balance=(1, 0, 1)), "three finite numbers > 0"),
        (dict(exposure=float("nan")), "exposure must be"),
        (dict(exposure="bright"), 'exposure must be "auto" or a number of stops from -32 to 32'),
        (dict(exposure=None), "exposure must be"),
        # An internal "scale must contain only finite numbers" or an OverflowError.
        (dict(exposure=200), "from -32 to 32, got 200"),
        (dict(exposure=1100), "from -32 to 32, got 1100"),
        (dict(exposure=-33.5), "from -32 to 32, got -33.5"),
        (dict(exposure=True), "from -32 to 32, got True"),
        (dict(demosaic="magic"), "magic"),
    ]
    for kwargs, message in cases:
        with pytest.raises(ValueError, match=message):
            ig.develop(raw, **kwargs)
    with pytest.raises(TypeError, match="demosaic must be a str"):
        ig.develop(raw, demosaic=3)


def test_the_exposure_limits_make_every_pixel_white_or_black(grey_card):
    """The range refuses no change a picture could show: at its ends the
    card is all white, or black."""
    _, raw = grey_card
    assert (ig.develop(raw, exposure=32, demosaic="bilinear") == 255).all()
    assert (ig.develop(raw, exposure=-32, bps=16, demosaic="bilinear") == 0).all()


def test_orientation_follows_libraw_flip_codes():
    from imgform_rs.develop import _orient

    img = np.arange(2 * 3 * 3).reshape(2, 3, 3)
    assert _orient(img, 0).shape == (2, 3, 3)
    np.testing.assert_array_equal(_orient(img, 3), img[::-1, ::-1])
    # 6: 90 degrees clockwise, 5: counter-clockwise (dcraw's flip_index).
    np.testing.assert_array_equal(_orient(img, 6), np.rot90(img, -1))
    np.testing.assert_array_equal(_orient(img, 5), np.rot90(img, 1))


def test_result_does_not_depend_on_thread_count(grey_card):
    path, _ = grey_card
    code = f"""
        import sys, imgform_rs as ig
        for options in ({{}}, {{"exposure": "auto", "color": "adobe_rgb"}}):
            rgb = ig.develop({str(path)!r}, bps=16, **options)
            sys.stdout.buffer.write(rgb.tobytes())
    """
    assert output_with_threads(code, 1) == output_with_threads(code, 2)


def test_write_image_round_trips_and_never_overwrites_by_default(tmp_path):
    rgb16 = (np.arange(6 * 5 * 3).reshape(6, 5, 3) * 1000).astype(np.uint16)
    for name, img in [("a.png", rgb16), ("b.tif", rgb16), ("c.png", rgb16.astype(np.uint8))]:
        path = ig.write_image(tmp_path / name, img)
        np.testing.assert_array_equal(iio_read(path), img)
        with pytest.raises(FileExistsError, match="overwrite=True"):
            ig.write_image(path, img)
        ig.write_image(path, img[::-1], overwrite=True)
        np.testing.assert_array_equal(iio_read(path), img[::-1])
    with pytest.raises(
        ValueError, match=r"must end in \.jpg, \.jpeg, \.png, \.tif, \.tiff or \.exr"
    ):
        ig.write_image(tmp_path / "a.bmp", rgb16)
    with pytest.raises(ValueError, match="PNG takes uint8, uint16"):
        ig.write_image(tmp_path / "f.png", rgb16.astype(np.float32))


def test_cli_develops_good_files_reports_bad_ones_and_keeps_outputs(tmp_path, capsys, grey_card):
    from imgform_rs.cli import main

    good, _ = grey_card
    bad = tmp_path / "broken.nef"
    bad.write_bytes(b"II*\0not a raw at all")
    out = tmp_path / "out"
    assert main(["develop", str(good), str(bad), "-o", str(out), "--bps", "16"]) == 1
    captured = capsys.readouterr()
    assert f"{bad}: not a raw file LibRaw can open" in captured.err
    assert "1 of 2 raws failed" in captured.err
    img = iio_read(out / "card.png")
    assert img.dtype == np.uint16 and img.shape == (40, 56, 3)
    before = (out / "card.png").stat().st_mtime_ns
    assert main(["develop", str(good), "-o", str(out), "--format", "tiff", "-j", "2"]) == 0
    assert main(["develop", str(good), "-o", str(out)]) == 0
    assert "exists, kept" in capsys.readouterr().out
    assert (out / "card.png").stat().st_mtime_ns == before and (out / "card.tif").is_file()
    assert main(["develop", str(good), "-o", str(out), "--overwrite"]) == 0
    assert iio_read(out / "card.png").dtype == np.uint8


def test_cli_brightens_by_default_and_passes_every_option(tmp_path, grey_card):
    from imgform_rs.cli import main

    good, raw = grey_card
    out = tmp_path / "out"
    assert main(["develop", str(good), "-o", str(out), "--bps", "16"]) == 0
    np.testing.assert_array_equal(
        iio_read(out / "card.png"), ig.develop(raw, bps=16, exposure="auto")
    )
    options = dict(
        demosaic="bilinear",
        white_balance=(1.5, 1.0, 1.25),
        exposure=-0.5,
        highlights="unclip",
        color="adobe_rgb",
        tone="linear",
        bps=16,
        orientation="none",
    )
    argv = ["develop", str(good), "-o", str(out), "--overwrite", "--demosaic", "bilinear"]
    argv += ["--white-balance", "1.5,1,1.25", "--exposure", "-0.5", "--highlights", "unclip"]
    argv += ["--color", "adobe_rgb", "--tone", "linear", "--bps", "16", "--orientation", "none"]
    assert main(argv) == 0
    np.testing.assert_array_equal(iio_read(out / "card.png"), ig.develop(raw, **options))


def test_cli_dry_run_lists_and_touches_nothing(tmp_path, capsys, grey_card):
    from imgform_rs.cli import main

    good, _ = grey_card
    out = tmp_path / "out"
    missing = tmp_path / "missing.dng"
    # 1: a file would fail, as the run itself would say.
    assert main(["develop", str(good), str(missing), "-o", str(out), "--dry-run"]) == 1
    printed = capsys.readouterr().out
    assert "exposure='auto'" in printed and "color='srgb'" in printed
    assert f"{good}: would write {out / 'card.png'}" in printed
    assert f"{missing}: no such file, would fail" in printed
    assert not out.exists()
    # A kept output is kept whatever its input: decided first, as a run does
    # (the dry run said "no such file, would fail" where the run kept it).
    out.mkdir()
    (out / "missing.png").write_bytes(b"made before")
    assert main(["develop", str(missing), "-o", str(out), "--dry-run"]) == 0
    assert "missing.png exists, would keep it" in capsys.readouterr().out
    assert main(["develop", str(missing), "-o", str(out)]) == 0
    assert "missing.png exists, kept" in capsys.readouterr().out


@pytest.mark.parametrize("source", [".", "..", "a/..", "/"])
def test_cli_refuses_a_folder_as_input_before_anything(tmp_path, capsys, source):
    """Its output was OUTDIR/.png, refused as a path 'that must end in .png'."""
    from imgform_rs.cli import main

    out = tmp_path / "out"
    assert main(["develop", source, "-o", str(out)]) == 2
    assert f"{source}: a folder, not a file; nothing was written" in capsys.readouterr().err
    assert not out.exists()


def test_an_interrupted_parallel_develop_says_every_file_it_wrote(
    tmp_path, capsys, grey_card, monkeypatch
):
    """Ctrl-C: the files in progress finish (threads cannot be stopped); they
    were written without a line saying so."""
    import shutil

    from imgform_rs import cli

    good, _ = grey_card
    sources = [shutil.copy(good, tmp_path / f"card{i}.dng") for i in range(4)]

    def interrupt(*args):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_progress", interrupt)  # after the first file's line
    out = tmp_path / "out"
    assert cli.main(["develop", *map(str, sources), "-o", str(out), "-j", "2"]) == 130
    captured = capsys.readouterr()
    assert "interrupted; finishing the" in captured.err
    written = sorted(os.listdir(out))
    assert written and all(f"-> {out / name}" in captured.out for name in written)


@pytest.mark.parametrize("extra", [[], ["--overwrite"], ["--dry-run"], ["-j", "2"]])
def test_cli_refuses_inputs_with_one_output_before_writing_anything(
    tmp_path, capsys, grey_card, extra
):
    """a/card.dng and b/card.kdc both develop to OUT/card.png: all but one
    result would be lost, so the run refuses, naming them, and writes nothing."""
    from imgform_rs.cli import main

    good, _ = grey_card
    twin = tmp_path / "b" / "card.kdc"
    twin.parent.mkdir()
    twin.write_bytes(good.read_bytes())
    out = tmp_path / "out"
    assert main(["develop", str(good), str(twin), "-o", str(out), *extra]) == 2
    assert_clash_refused(capsys.readouterr(), "develop", [good, twin], out)


def test_cli_says_in_one_line_that_the_output_folder_is_a_file(tmp_path, capsys, grey_card):
    from imgform_rs.cli import main

    good, _ = grey_card
    out = tmp_path / "out"
    out.write_bytes(b"a file, not a folder")
    for dry_run in ([], ["--dry-run"]):
        assert main(["develop", str(good), "-o", str(out), *dry_run]) == 2
        assert capsys.readouterr().err == f"imgform develop: the output folder {out} is a file\n"
    assert out.read_bytes() == b"a file, not a folder"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--exposure", "bright"], 'must be "auto" or a number of stops'),
        (["--exposure", "inf"], "number of stops"),
        (["--exposure", "1100"], "a number of stops from -32 to 32, got '1100'"),
        (["--white-balance", "1,0,1"], "three multipliers R,G,B > 0"),
        (["--white-balance", "tungsten"], "camera, daylight, auto, none"),
        (["--color", "cmyk"], "invalid choice"),
        (["-j", "x"], "argument -j/--jobs: must be an int >= 1, got 'x'"),  # "invalid _jobs"
        (["--workers", "0"], "argument --workers: must be an int >= 1, got '0'"),
    ],
)
def test_cli_refuses_bad_develop_options(tmp_path, capsys, argv, message):
    from imgform_rs.cli import main

    with pytest.raises(SystemExit):
        main(["develop", "a.dng", "-o", str(tmp_path), *argv])
    assert message in capsys.readouterr().err


def iio_read(path):
    """PNG through OpenCV (Pillow reads 16-bit RGB PNG as 8-bit), TIFF through imageio."""
    if path.suffix == ".png":
        cv2 = pytest.importorskip("cv2")
        return cv2.imread(str(path), cv2.IMREAD_UNCHANGED)[..., ::-1]
    import imageio.v3 as iio

    return iio.imread(path)


def test_non_square_pixels_repeat_columns_as_libraw_does():
    from imgform_rs.develop import _stretch

    img = np.arange(4 * 3 * 3, dtype=np.uint16).reshape(4, 3, 3)
    wide = _stretch(img, 1.5)  # 3 columns -> 4.5 + 0.5 -> 5
    assert wide.shape == (4, 5, 3)
    # Source column floor(j / 1.5): 0, 0, 1, 2, 2.
    np.testing.assert_array_equal(wide, img[:, [0, 0, 1, 2, 2]])
    tall = _stretch(img, 0.5)
    np.testing.assert_array_equal(tall, img[[0, 0, 1, 1, 2, 2, 3, 3]])


@pytest.mark.skipif(sys.platform != "linux", reason="needs a file system of bytes")
def test_the_cli_names_a_file_whose_name_the_terminal_cannot_print(tmp_path):
    """A Latin-1 name under a UTF-8 terminal is printed with escapes: the
    file is developed and reported, run again it is kept, and nothing fails."""
    name = os.path.join(os.fsencode(tmp_path), b"caf\xe9.dng")
    cfa = np.random.default_rng(5).integers(0, 4096, (32, 48)).astype(np.uint16)
    write_dng(os.fsdecode(name), cfa, "RGGB", white_level=4095)
    command = [sys.executable, "-m", "imgform_rs.cli", "develop", name, "-o", str(tmp_path / "o")]
    env = {**os.environ, "PYTHONIOENCODING": "utf-8"}
    for said in ("-> ", "exists, kept"):
        done = subprocess.run(command, capture_output=True, timeout=120, env=env)
        assert done.returncode == 0, done.stderr.decode()
        assert "caf\\udce9.dng" in done.stdout.decode() and said in done.stdout.decode()

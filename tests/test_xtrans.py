"""X-Trans demosaicing: "markesteijn" (and "best" for X-Trans) against bilinear."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import imgform_rs as ig
from conftest import output_with_threads
from imgform_rs.dng import write_dng

TILE = ig.pattern_cells("XTRANS")
# Every layout: the 36 shifts of Fujifilm's tile, and of its transpose.
LAYOUTS = [
    np.roll(t, (dy, dx), axis=(0, 1)) for t in (TILE, TILE.T) for dy in range(6) for dx in range(6)
]


def cpsnr(out, ref):
    d = out[10:-10, 10:-10].astype(np.float64) - ref[10:-10, 10:-10].astype(np.float64)
    return 10 * np.log10(255.0**2 / np.mean(d**2))


def smooth_image(h=96, w=120):
    """A grey scene (a soft disc and waves) under a slowly varying tint: channels
    that vary together, as in natural images, which colour-difference methods
    exploit."""
    y, x = np.mgrid[0:h, 0:w] / max(h, w)
    disc = 1 / (1 + np.exp(((y - 0.4) ** 2 + (x - 0.5) ** 2 - 0.06) * 300))
    waves = 0.5 + 0.5 * np.sin(2 * np.pi * 10 * (x + 0.5 * y) ** 2)
    light = 0.25 + 0.35 * waves + 0.35 * disc
    tint = np.stack([0.8 + 0.2 * x, 0.9 + 0.1 * y, 1.0 - 0.3 * x], axis=-1)
    return np.round(255 * light[..., None] * tint).astype(np.uint8)


@pytest.mark.parametrize("index", range(len(LAYOUTS)))
def test_every_layout_keeps_samples_and_the_range(index):
    pattern = LAYOUTS[index]
    raw = np.random.default_rng(index).integers(100, 3000, (31, 47)).astype(np.uint16)
    out = ig.demosaic(raw, pattern, "markesteijn")
    masks = ig.channel_masks(raw.shape, pattern)
    np.testing.assert_array_equal(out[masks], raw.ravel())
    assert raw.min() <= out.min() and out.max() <= raw.max()


@pytest.mark.parametrize("index", [0, 7, 20, 41])
def test_every_layout_reconstructs_a_smooth_image(index):
    pattern = LAYOUTS[index]
    rgb = smooth_image()
    out = ig.demosaic(ig.mosaic(rgb, pattern), pattern, "markesteijn")
    assert cpsnr(out, rgb) > 40


@given(
    value=st.integers(0, 255),
    h=st.integers(6, 30),
    w=st.integers(6, 30),
    dtype=st.sampled_from([np.uint8, np.uint16, np.float32]),
)
def test_a_constant_stays_constant(value, h, w, dtype):
    raw = np.full((h, w), value, dtype)
    out = ig.demosaic(raw, "XTRANS", "markesteijn")
    assert out.dtype == dtype
    assert (out == value).all()


def test_float_outputs_stay_in_the_input_range():
    raw = np.random.default_rng(3).random((40, 50), dtype=np.float32) * 2 - 0.5
    out = ig.demosaic(raw, "XTRANS", "markesteijn")
    assert raw.min() <= out.min() and out.max() <= raw.max()


def test_quality_is_well_above_bilinear():
    rgb = smooth_image(192, 240)
    raw = ig.mosaic(rgb, "XTRANS")
    ours = cpsnr(ig.demosaic(raw, "XTRANS", "markesteijn"), rgb)
    # 52.8 dB against 38.9.
    assert ours > cpsnr(ig.demosaic(raw, "XTRANS", "bilinear"), rgb) + 10


def test_quality_on_a_natural_image():
    data = pytest.importorskip("skimage.data")
    rgb = data.astronaut()
    raw = ig.mosaic(rgb, "XTRANS")
    # 36.06 dB (bilinear 29.7, LibRaw's 3-pass Markesteijn 35.7).
    assert cpsnr(ig.demosaic(raw, "XTRANS", "markesteijn"), rgb) > 35.5


def test_best_is_markesteijn_for_x_trans_and_unchanged_for_bayer():
    raw = np.random.default_rng(5).integers(0, 4096, (24, 30)).astype(np.uint16)
    best = ig.demosaic(raw, "XTRANS", "best")
    np.testing.assert_array_equal(best, ig.demosaic(raw, "XTRANS", "markesteijn"))
    np.testing.assert_array_equal(ig.demosaic(raw, "XTRANS", "quality"), best)
    bayer = ig.demosaic(raw, "RGGB", "best")
    np.testing.assert_array_equal(bayer, ig.demosaic(raw, "RGGB", "raisr_cd"))
    assert ig.XTRANS_DEMOSAIC_METHODS == ("bilinear", "markesteijn", "best", "quality")
    assert "markesteijn" not in ig.BAYER_DEMOSAIC_METHODS


@pytest.mark.parametrize("alias", ["best", "quality"])
def test_an_alias_has_the_halo_of_the_method_it_selects(alias):
    """demosaic_dask pads chunks by the halo: for X-Trans that of
    "markesteijn" (18), not of the aliases' Bayer methods (22, 24)."""
    for layout in (TILE, LAYOUTS[7], "XTRANS"):
        assert ig.demosaic_halo(alias, layout) == ig.demosaic_halo("markesteijn", layout)
    bayer = {"best": "raisr_cd", "quality": "fusion_cnn"}[alias]
    for pattern in ("RGGB", np.array([[1, 0], [2, 1]])):
        assert ig.demosaic_halo(alias, pattern) == ig.demosaic_halo(bayer, pattern)


def test_results_do_not_depend_on_the_thread_count():
    # 400 columns and 130 rows: more than one tile each way.
    code = """
        import sys, numpy as np, imgform_rs as ig
        raw = np.random.default_rng(2).integers(0, 65536, (130, 400), dtype=np.uint16)
        sys.stdout.buffer.write(ig.demosaic(raw, "XTRANS", "markesteijn").tobytes())
    """
    one = output_with_threads(code, 1)
    assert len(one) == 130 * 400 * 3 * 2
    assert one == output_with_threads(code, 2)


@pytest.mark.parametrize(
    ("pattern", "method", "match"),
    [
        ("RGGB", "markesteijn", 'supports X-Trans patterns only.*Bayer.*"rcd"'),
        ("XTRANS", "rcd", 'X-Trans is supported by "bilinear", "markesteijn", "best"'),
    ],
)
def test_methods_refuse_the_other_kind_of_pattern(pattern, method, match):
    with pytest.raises(ValueError, match=match):
        ig.demosaic(np.zeros((12, 12), np.uint16), pattern, method)


def test_a_mosaic_smaller_than_a_tile_is_refused():
    with pytest.raises(ValueError, match=r"at least 6x6 pixels.*got \(5, 8\)"):
        ig.demosaic(np.zeros((5, 8), np.uint16), "XTRANS", "markesteijn")


def test_develop_uses_markesteijn_for_x_trans_by_default(tmp_path):
    rgb = smooth_image(48, 60)
    cfa = ig.mosaic(rgb, "XTRANS").astype(np.uint16) * 16
    path = tmp_path / "xtrans.dng"
    write_dng(path, cfa, TILE, white_level=4095)
    raw = ig.load_raw(path)
    np.testing.assert_array_equal(ig.develop(raw), ig.develop(raw, demosaic="markesteijn"))
    assert not np.array_equal(ig.develop(raw), ig.develop(raw, demosaic="bilinear"))


def test_libraw_reads_our_x_trans_dng_and_agrees_with_markesteijn(tmp_path):
    rawpy = pytest.importorskip("rawpy")
    data = pytest.importorskip("skimage.data")
    # LibRaw refused (an I/O error) the smaller crops tried, 240x300 to 256x384.
    rgb = data.astronaut()
    raw = ig.mosaic(rgb, "XTRANS")
    path = tmp_path / "xtrans.dng"
    write_dng(path, raw.astype(np.uint16) * 257, TILE, white_level=65535)
    with rawpy.imread(str(path)) as r:
        np.testing.assert_array_equal(r.raw_pattern, TILE)
        out = r.postprocess(
            demosaic_algorithm=rawpy.DemosaicAlgorithm.AHD,
            output_bps=16,
            gamma=(1, 1),
            no_auto_bright=True,
            output_color=rawpy.ColorSpace.raw,
            use_camera_wb=False,
            use_auto_wb=False,
            user_wb=[1.0, 1.0, 1.0, 1.0],
            user_flip=0,
            user_black=0,
            user_sat=65535,
        )
    libraw = np.clip(np.round(out / 257), 0, 255)
    ours = ig.demosaic(raw, "XTRANS", "markesteijn")
    # Two Markesteijn implementations: both far above bilinear, close to
    # each other.
    bilinear = cpsnr(ig.demosaic(raw, "XTRANS", "bilinear"), rgb)
    assert cpsnr(libraw, rgb) > bilinear + 3
    assert cpsnr(ours, rgb) > bilinear + 3
    assert cpsnr(ours, libraw) > 35

"""The frequency-domain demosaicer against a NumPy transcription of the method, and
the reproducibility of its least-squares filter design."""

import numpy as np
import pytest

import imgform_rs as ig

ndimage = pytest.importorskip("scipy.ndimage")
leung2011 = pytest.importorskip("imgform_rs.training.leung2011")


def full(q, alternate=False):
    """An 11-tap symmetric filter from its unique taps, optionally times (-1)^k."""
    taps = np.r_[q[:0:-1], q].astype(np.float64)
    return taps * (-1.0) ** np.arange(-5, 6) if alternate else taps


def along(img, taps, axis):
    return ndimage.correlate1d(img, taps, axis=axis, mode="mirror")


def reference(raw, pattern):
    """The method written out with whole-image filters in float64 (SciPy's
    "mirror" is our border: reflection without repeating the edge)."""
    f = raw.astype(np.float64)
    q = leung2011.shipped()
    d, s = np.array([-1.0, 2, -1]), np.array([1.0, 2, 1])

    def separable(down, across, q_down, q_across):
        return along(along(along(along(f, down, 0), across, 1), q_down, 0), q_across, 1)

    z1 = separable(d, d, full(q["C1_V"], True), full(q["C1_H"], True))
    za = separable(s, d, full(q["C2_V"]), full(q["C2_H"], True))
    zb = separable(d, s, full(q["C2_H"], True), full(q["C2_V"]))
    band = np.array([-1.0, 0, 2, 0, -1])
    ex = along(along(f, band, 1), s, 0) ** 2
    ey = along(along(f, band, 0), s, 1) ** 2
    ex, ey = (along(along(e, np.ones(5), 0), np.ones(5), 1) for e in (ex, ey))
    w = np.divide(ex, ex + ey, out=np.full_like(ex, 0.5), where=ex + ey > 0)
    masks = ig.channel_masks(raw.shape, pattern)
    ry, rx = np.argwhere(masks[:2, :2, 0])[0]
    y, x = np.indices(raw.shape)
    sx, sy = (-1.0) ** (x - rx), (-1.0) ** (y - ry)
    c1 = sx * sy * z1
    c2 = w * sy * zb + (1 - w) * sx * za
    luma = f - z1 - c2 * (sx + sy)
    rgb = np.stack([luma + c1 + 2 * c2, luma - c1, luma + c1 - 2 * c2], axis=-1)
    rgb[masks] = f.ravel()
    return np.clip(rgb, f.min(), f.max())


def smooth_mosaic(seed, h, w, pattern):
    rng = np.random.default_rng(seed)
    rgb = ndimage.gaussian_filter(rng.random((h, w, 3)), (1.5, 1.5, 0)) * 4e4 + 1e4
    return ig.mosaic(rgb.astype(np.uint16), pattern)


@pytest.mark.parametrize("pattern", ["RGGB", "BGGR", "GRBG", "GBRG"])
@pytest.mark.parametrize("shape", [(37, 50), (140, 401)])
def test_matches_the_whole_image_formulation(pattern, shape):
    # 140 x 401 spans two tiles each way (128 rows, 384 columns per tile).
    raw = smooth_mosaic(1, *shape, pattern)
    got = ig.demosaic(raw, pattern, "leung2011").astype(np.float64)
    np.testing.assert_allclose(got, reference(raw, pattern), rtol=0, atol=1.0)


def test_float_input_matches_without_rounding():
    raw = smooth_mosaic(2, 30, 44, "GRBG").astype(np.float32) / 65535
    got = ig.demosaic(raw, "GRBG", "leung2011")
    np.testing.assert_allclose(got, reference(raw, "GRBG"), rtol=0, atol=2e-5)


def test_grey_flat_areas_get_no_false_colour():
    raw = np.full((40, 40), 700, np.uint16)
    raw[:, 20:] = 3000  # a grey step: chroma only near the edge
    out = ig.demosaic(raw, "RGGB", "leung2011").astype(int)
    far = np.r_[0:8, 32:40]
    assert (out[:, far] == raw[:, far, None]).all()


def test_the_filter_design_is_reproducible():
    small = {"seed": 3, "leaves": 1, "size": 64, "grey": ("coins",)}
    first, second = leung2011.design(**small), leung2011.design(**small)
    assert first.keys() == {"C1_V", "C1_H", "C2_V", "C2_H"}
    for name in first:
        np.testing.assert_array_equal(first[name], second[name])
    # Each estimate passes its chroma at DC with unit gain (the [1 2 1] factors
    # give 4 per axis).
    for v, h in [("C1_V", "C1_H"), ("C2_V", "C2_H")]:
        gain = 16 * full(first[v]).sum() * full(first[h]).sum()
        assert gain == pytest.approx(1, abs=0.05)


@pytest.mark.slow
def test_the_shipped_filters_are_the_designed_ones():
    shipped = leung2011.shipped()
    for name, taps in leung2011.design().items():
        np.testing.assert_array_equal(np.float32(taps), np.float32(shipped[name]))

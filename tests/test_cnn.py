"""``"fusion_cnn"``: a small network over ``"fusion_refined"``. What the shared
demosaic tests don't cover (it is not flip-symmetric): range, tile seams, the
network the training script encodes, the views it trains on, and what it is for."""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from test_demosaic import BAYER, mosaics, random_raw

import imgform_rs as ig

WEIGHTS = Path(__file__).parents[1] / "rust/imgform-core/src/demosaic/fusion_cnn_weights.bin"


@given(raw=mosaics(), p=st.sampled_from(BAYER))
def test_outputs_stay_within_the_input_range(raw, p):
    out = ig.demosaic(raw, p, "fusion_cnn")
    assert raw.min() <= out.min() and out.max() <= raw.max()


@pytest.mark.parametrize("dtype", [np.uint16, np.float32])
def test_tile_seams_do_not_show(dtype):
    # Tiles are 768 columns: dropping an even number of columns keeps the
    # phase and moves every seam, so the interiors agree.
    raw = random_raw(5, 1700, 1001, dtype)
    shift, reach = 50, ig.demosaic_halo("fusion_cnn", "GBRG") + 8
    whole = ig.demosaic(raw, "GBRG", "fusion_cnn")
    cut = ig.demosaic(np.ascontiguousarray(raw[:, shift:]), "GBRG", "fusion_cnn")
    np.testing.assert_array_equal(cut[:, reach:-reach], whole[:, shift + reach : -reach])


def test_it_removes_error_from_fusion_refined_and_keeps_the_samples():
    # On four of the benchmark's scikit-image photographs (held out of the
    # training) the correction removes 1-3 % of "fusion_refined"'s squared
    # error, at the missing colours only.
    data = pytest.importorskip("skimage.data")
    errors = {"fusion_refined": 0.0, "fusion_cnn": 0.0}
    for name in ("astronaut", "coffee", "chelsea", "rocket"):
        rgb = getattr(data, name)().astype(np.float32) / 255
        raw = ig.mosaic(rgb, "RGGB")
        for method in errors:
            out = ig.demosaic(raw, "RGGB", method)
            errors[method] += float(((out - rgb)[20:-20, 20:-20] ** 2).mean())
        masks = ig.channel_masks(raw.shape, "RGGB")
        np.testing.assert_array_equal(out[masks], raw.ravel())
    assert errors["fusion_cnn"] < 0.99 * errors["fusion_refined"]


def test_the_kernel_runs_the_network_the_training_script_encodes():
    torch = pytest.importorskip("torch")
    from imgform_rs.training import cnn

    net = cnn.network()
    blob = WEIGHTS.read_bytes()
    offset = len(cnn.MAGIC) + 4
    with torch.no_grad():
        for layer in (m for m in net if hasattr(m, "weight")):
            cout, cin = layer.weight.shape[:2]
            n = 9 * cin * cout
            w = np.frombuffer(blob, "<f4", n, offset + 8).reshape(3, 3, cin, cout)
            layer.weight.copy_(torch.from_numpy(w.transpose(3, 2, 0, 1).copy()))
            offset += 8 + 4 * n
    assert offset == len(blob) and cnn.encode(net) == blob
    rgb = np.random.default_rng(3).random((64, 80, 3)).astype(np.float32)
    raw = ig.mosaic(rgb, "RGGB")
    base = ig.demosaic(raw, "RGGB", "fusion_refined")
    with torch.no_grad():
        d = net(torch.from_numpy(cnn.quads(base))[None])[0].numpy()
    want = base.copy()
    edge = 2 * cnn.LAYERS
    for k, (i, j) in enumerate([(0, 0), (0, 1), (1, 0), (1, 1)]):
        cells = want[i + edge : 64 - edge : 2, j + edge : 80 - edge : 2]
        cells += d[3 * k : 3 * k + 3].transpose(1, 2, 0)
    masks = ig.channel_masks(raw.shape, "RGGB")
    want[masks] = raw.ravel()
    got = ig.demosaic(raw, "RGGB", "fusion_cnn")
    inner = (slice(edge, -edge), slice(edge, -edge))
    np.testing.assert_allclose(got[inner], np.clip(want, raw.min(), raw.max())[inner], atol=2e-6)


def test_the_training_views_are_the_eight_flips_and_transpositions():
    from imgform_rs.training import cnn

    rgb = np.random.default_rng(5).random((3, 5, 3))
    views = list(cnn.views(rgb))
    # Each view is one of the square's symmetries applied to the image: the
    # same pixels, the corners in a different place each time.
    assert len({v.tobytes() for v in views}) == 8
    assert sorted(v.shape for v in views) == [(3, 5, 3)] * 4 + [(5, 3, 3)] * 4
    for v in views:
        np.testing.assert_array_equal(np.sort(v, axis=None), np.sort(rgb, axis=None))
        assert v.flags.c_contiguous
    corners = {tuple(v[i, j].tolist()) for v in views for i in (0, -1) for j in (0, -1)}
    assert len(corners) == 4
    assert {tuple(v[0, 0].tolist()) for v in views} == corners

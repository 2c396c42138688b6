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


def test_far_below_its_largest_sample_it_stays_at_its_base():
    # One sample at 1, the rest 12 stops darker: the input spans a few codes
    # there, and the correction of their rounding once put the method 4.8 dB
    # below its base (13 stops: 12 dB). Quads that dim take none of it.
    data = pytest.importorskip("skimage.data")
    rgb = data.astronaut()[100:356, 100:356].astype(np.float32) / 255
    raw = ig.mosaic(rgb, "RGGB") * np.float32(2.0**-12)
    raw[0, 0] = 1.0
    inner = (slice(10, -10), slice(10, -10))

    def error(method: str) -> float:
        out = ig.demosaic(raw, "RGGB", method) * np.float32(2.0**12)
        return float(((out - rgb)[inner] ** 2).mean())

    assert error("fusion_cnn") <= 1.01 * error("fusion_refined")


def read_network(blob: bytes) -> list[tuple[np.ndarray, np.ndarray]]:
    """The shipped file's layers as int8 weights ``(3, 3, in, out)`` and float32
    factors, read by its documented format."""
    from imgform_rs.training import cnn

    assert blob[:8] == cnn.MAGIC
    (count,) = np.frombuffer(blob, "<u4", 1, 8)
    layers, offset = [], 12
    for _ in range(count):
        cin, cout = (int(v) for v in np.frombuffer(blob, "<u4", 2, offset))
        factors = np.frombuffer(blob, "<f4", cout, offset + 8)
        offset += 8 + 4 * cout
        w = np.frombuffer(blob, "i1", 9 * cin * cout, offset).reshape(3, 3, cin, cout)
        layers.append((w, factors))
        offset += w.size
    assert offset == len(blob)
    return layers


def test_the_kernel_runs_the_shipped_network_in_exact_integers():
    # The network in numpy, as the file's format and the training script's
    # quantisation define it: 15-bit codes of the clamped base on the
    # mosaic's largest sample, 64-bit sums, each hidden sum scaled and
    # rounded to even into the next codes, the last one scaled back. The
    # kernel gives the same bits.
    from imgform_rs.training import cnn

    layers = read_network(WEIGHTS.read_bytes())
    rgb = np.random.default_rng(3).random((64, 80, 3)).astype(np.float32) * 0.3
    rgb[:, 40:] /= 256  # 8 stops darker: quads there take part of the correction
    raw = ig.mosaic(rgb, "RGGB")
    lo, hi = raw.min(), raw.max()
    base = np.clip(ig.demosaic(raw, "RGGB", "fusion_refined"), lo, hi)
    unit = np.float32(cnn.TOP) / hi
    act = np.clip(np.round(cnn.quads(base) * unit), 0, cnn.TOP).astype(np.int64)
    for k, (w, factors) in enumerate(layers):
        _, h, wd = act.shape
        sums = sum(
            np.einsum(
                "ihw,io->ohw", act[:, dy : h - 2 + dy, dx : wd - 2 + dx], w[dy, dx].astype(np.int64)
            )
            for dy in range(3)
            for dx in range(3)
        )
        scaled = sums.astype(np.float32) * factors[:, None, None]
        if k + 1 < len(layers):
            act = np.clip(np.round(scaled), 0, cnn.TOP).astype(np.int64)
    correction = scaled * hi
    edge = 2 * cnn.LAYERS
    # Each quad takes a share of it by its brightest value in codes (none up
    # to 16, all from 128: the correction of a few codes is their rounding).
    level = cnn.quads(base)[:, cnn.LAYERS : -cnn.LAYERS, cnn.LAYERS : -cnn.LAYERS].max(0) * unit
    correction = correction * np.clip((level - np.float32(16)) / np.float32(112), 0, 1)
    want = base.copy()
    for k, (i, j) in enumerate([(0, 0), (0, 1), (1, 0), (1, 1)]):
        cells = want[i + edge : 64 - edge : 2, j + edge : 80 - edge : 2]
        cells += correction[3 * k : 3 * k + 3].transpose(1, 2, 0)
    masks = ig.channel_masks(raw.shape, "RGGB")
    want[masks] = raw.ravel()
    got = ig.demosaic(raw, "RGGB", "fusion_cnn")
    inner = (slice(edge, -edge), slice(edge, -edge))
    np.testing.assert_array_equal(got[inner], np.clip(want, lo, hi)[inner])


def test_quantisation_keeps_each_weight_within_half_a_step():
    torch = pytest.importorskip("torch")
    from imgform_rs.training import cnn

    torch.manual_seed(0)
    net = cnn.network()
    with torch.no_grad():
        net[-1].weight.normal_()
    steps = [2.0**-13, 2.0**-14, 2.0**-12, 2.0**-13, 2.0**-15]
    layers = cnn.quantised(net, steps)
    weights = [m.weight.detach().numpy() for m in net if hasattr(m, "weight")]
    step_in = [1 / cnn.TOP, *steps]
    for k, ((q, factor), w) in enumerate(zip(layers, weights, strict=True)):
        scale = np.abs(w).reshape(len(w), -1).max(1) / cnn.WEIGHT_TOP
        assert np.abs(q).max() == cnn.WEIGHT_TOP
        assert np.all(
            np.abs(q * scale[:, None, None, None] - w) <= scale[:, None, None, None] / 2 + 1e-9
        )
        want = step_in[k] * scale / (steps[k] if k < len(steps) else 1.0)
        np.testing.assert_allclose(factor, want, rtol=1e-7)
    blob = cnn.encode(net, steps)
    assert [(q.tolist(), f.tolist()) for q, f in layers] == [
        (w.transpose(3, 2, 0, 1).tolist(), f.tolist()) for w, f in read_network(blob)
    ]


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

"""The learned demosaicers ("raisr", "raisr_fast", "raisr_cd", "fusion" and
"fusion_refined"): properties the shared demosaic tests don't cover (they are not
flip-symmetric), agreement with their training script, reproducible training."""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from test_demosaic import BAYER, mosaics, random_raw

import imgform_rs as ig

KERNELS = Path(__file__).parents[1] / "rust/imgform-core/src/demosaic"
WEIGHTS = KERNELS / "raisr_weights.bin"
LEARNED = ["raisr", "raisr_fast", "raisr_cd", "fusion", "fusion_refined"]


@given(raw=mosaics(), p=st.sampled_from(BAYER), method=st.sampled_from(LEARNED))
def test_outputs_stay_within_the_input_range(raw, p, method):
    out = ig.demosaic(raw, p, method)
    assert raw.min() <= out.min() and out.max() <= raw.max()


@pytest.mark.parametrize("method", LEARNED)
@pytest.mark.parametrize("dtype", [np.uint16, np.float32])
def test_tile_seams_do_not_show(dtype, method):
    # Tiles are 384 columns counted from the left: dropping an even number of
    # columns keeps the phase and moves every seam, so the interiors agree.
    raw = random_raw(5, 40, 1001, dtype)
    shift, reach = 50, ig.demosaic_halo(method, "GBRG") + 8
    whole = ig.demosaic(raw, "GBRG", method)
    cut = ig.demosaic(np.ascontiguousarray(raw[:, shift:]), "GBRG", method)
    np.testing.assert_array_equal(cut[:, reach:-reach], whole[:, shift + reach : -reach])


@pytest.mark.parametrize("method", LEARNED)
def test_the_kernel_applies_the_filters_the_training_script_fitted(method):
    # The training script reimplements the kernel's features and hash in
    # NumPy; the shipped filters applied there must give the kernel's output.
    data = pytest.importorskip("skimage.data")
    from imgform_rs.training import demosaic as tr

    crop = data.coffee()[100:180, 200:290] / 255.0
    truth, bases, position = tr.prepare(crop, tr.BASES[method])
    base = bases[0]
    mosaic = np.ascontiguousarray((truth * ig.channel_masks(truth.shape[:2], "RGGB")).sum(-1))
    out = ig.demosaic(mosaic.astype(np.float32), "RGGB", method)
    blob = (KERNELS / f"{method}_weights.bin").read_bytes()
    _, strengths, coherences, saturations, nf = (int(n) for n in np.frombuffer(blob, "<u4", 5, 8))
    thresholds = np.frombuffer(blob, "<f4", strengths - 1 + coherences - 1 + saturations - 1, 28)
    filters = np.frombuffer(blob, "<f4", offset=28 + 4 * len(thresholds)).reshape(-1, 2, nf)
    assert saturations == (2 if method in tr.SATURATED else 1)
    if method in tr.ORIENTED:
        classify, nclasses = tr.oriented_classes, tr.ORIENTED_CLASSES
    else:

        def classify(base, position):
            return tr.classes(*tr.hash_inputs(base, position), thresholds[: strengths - 1])

        nclasses = tr.CLASSES
    if method in tr.SATURATED:
        assert thresholds[-1] == tr.SATURATION
        classify = tr.with_saturation(classify, nclasses)
    cls = classify(base, position)
    assert len(filters) == saturations * nclasses
    if method in tr.SATURATED:
        # The crop has saturated and unsaturated pixels.
        assert 0 < np.mean(cls >= nclasses) < 1
    feats, _ = tr.samples(truth, bases, position)
    want = np.einsum("nf,nkf->nk", feats, filters[cls])
    blue, chroma = tr.interior(position >= 2, 0), tr.interior(position % 2 == 1, 0)
    if method in tr.BOUNDED:
        bounded = tr.bound_chroma(want, chroma)
        # The bound acts on this crop, and the kernel applies it.
        assert (bounded != want).any()
        want = bounded

    def missing(rgb):
        """The two missing colours of each interior pixel, in the kernel's order."""
        frame = np.where(blue[:, None], rgb[:, ::-1], rgb)
        return np.where(chroma[:, None], frame[:, 1:], frame[:, [0, 2]])

    got = missing(tr.interior(out - base, 0))
    # Outputs are clamped to the mosaic's range: compare where they are not.
    inside = missing(tr.interior((out > mosaic.min()) & (out < mosaic.max()), 0))
    assert np.abs(want).max() > 1e-3 and inside.mean() > 0.9
    np.testing.assert_allclose(got[inside], want[inside], rtol=0, atol=1e-6)


def test_a_small_training_gives_identical_bytes_twice():
    pytest.importorskip("skimage.data")
    from imgform_rs.training.demosaic import train

    first = train("fusion", small=True)
    assert first.startswith(b"IGRAISR2") and len(first) > 100_000
    assert train("fusion", small=True) == first


@pytest.mark.slow
def test_the_shipped_weights_are_what_training_gives():
    pytest.importorskip("skimage.data")
    from imgform_rs.training.demosaic import train
    from imgform_rs.training.photos import DEFAULT_DATA

    if not (DEFAULT_DATA / ".fetched-extended").exists():
        pytest.skip("the training photographs are not fetched (make training-data)")
    for method in LEARNED:
        assert train(method) == (KERNELS / f"{method}_weights.bin").read_bytes()


def test_photos_are_downsampled_by_area_averages():
    from imgform_rs.training.photos import area_downsample

    rgb = np.arange(5 * 7 * 3, dtype=np.uint8).reshape(5, 7, 3)
    out = area_downsample(rgb, 2)
    assert out.shape == (2, 3, 3)
    np.testing.assert_allclose(out[1, 2], rgb[2:4, 4:6].reshape(-1, 3).mean(0))


def test_a_photo_with_other_bytes_is_refused(tmp_path):
    from imgform_rs.training import photos

    photo = photos.TRAINING[0]
    (tmp_path / photo.path).parent.mkdir(parents=True)
    (tmp_path / photo.path).write_bytes(b"not the wallpaper")
    with pytest.raises(ValueError, match="SHA-256"):
        photos.load(photo, tmp_path)

"""The training sets of the learned demosaicers: no evaluation image in them, every
photograph openly licensed, and the augmentation and synthetic images deterministic."""

from __future__ import annotations

import csv
import struct

import numpy as np
import pytest

from conftest import shared_path
from imgform_rs.training import catalogue, leung2011, photos, sets, synthetic
from imgform_rs.training import demosaic as raisr_training

ALL_PHOTOS = [*catalogue.EXTENDED, *catalogue.EXTENDED_HELD_OUT]
FREE_LICENCES = {
    "public-domain",
    "CC0-1.0",
    "CC-BY-2.0",
    "CC-BY-3.0",
    "CC-BY-SA-3.0",
    "CC-BY-SA-4.0",
    "GPL-2+",
}
#: The extended set's packages, fetched by `make training-data` after raisr's.
EXTENDED_FETCHED = photos.DEFAULT_DATA / ".fetched-extended"
needs_data = pytest.mark.skipif(
    not EXTENDED_FETCHED.exists(), reason="out/training-data is absent: run `make training-data`"
)


def test_no_scikit_image_evaluation_image_is_trained_on():
    trained = {*raisr_training.SMALL, *leung2011.GREY}
    assert not trained & raisr_training.HELD_OUT
    # leung2011 also trains on the Hubble deep field, which no benchmark scores.
    assert "hubble_deep_field" not in raisr_training.EVALUATION_IMAGES
    photo_names = {photo.name.rsplit("/", 1)[-1].lower() for photo in ALL_PHOTOS}
    assert not photo_names & set(raisr_training.EVALUATION_IMAGES)


def test_no_validation_image_is_among_the_training_photographs():
    manifest = shared_path("data/demosaic-val/MANIFEST.tsv")
    if manifest is None:
        pytest.skip("../shared/data/demosaic-val is absent")
    with manifest.open(newline="") as f:
        digests = [row["sha256"] for row in csv.DictReader(f, delimiter="\t")]
    assert len(digests) == 92
    for photo in [*photos.TRAINING, *photos.HELD_OUT, *ALL_PHOTOS]:
        assert len(photo.sha256) == 16
        clashes = [d for d in digests if d.startswith(photo.sha256)]
        assert not clashes, f"{photo.name} is a validation image"


def test_the_extended_set_keeps_the_raisr_set_and_holds_some_photographs_out():
    assert catalogue.EXTENDED[: len(photos.TRAINING)] == photos.TRAINING
    assert catalogue.EXTENDED_HELD_OUT[: len(photos.HELD_OUT)] == photos.HELD_OUT
    held_out = {photo.sha256 for photo in catalogue.EXTENDED_HELD_OUT}
    assert not held_out & {photo.sha256 for photo in catalogue.EXTENDED}
    assert len(catalogue.EXTENDED_HELD_OUT) > len(photos.HELD_OUT)
    assert len({photo.sha256 for photo in ALL_PHOTOS}) == len(ALL_PHOTOS) >= 300
    assert len({photo.name for photo in ALL_PHOTOS}) == len(ALL_PHOTOS)


def test_every_new_photograph_is_openly_licensed():
    new = [photo for photo in ALL_PHOTOS if photo not in [*photos.TRAINING, *photos.HELD_OUT]]
    assert {photo.name for photo in new} == set(catalogue.LICENCES)
    assert set(catalogue.LICENCES.values()) <= FREE_LICENCES
    # Licences that ask for attribution get it, and only they are credited.
    credited = {name for name, licence in catalogue.LICENCES.items() if "BY" in licence}
    assert credited == set(catalogue.ATTRIBUTION)
    assert all(author and source for author, source in catalogue.ATTRIBUTION.values())


def _resource_file(files: dict[str, bytes], compressed: bool = False) -> bytes:
    """A Qt resource file (format version 1) holding ``files`` in one folder ``d``."""
    names = b""
    name_offsets = {}
    for name in ["d", *files]:
        name_offsets[name] = len(names)
        names += struct.pack(">HI", len(name), 0) + name.encode("utf-16-be")
    data = b""
    data_offsets = {}
    for name, content in files.items():
        data_offsets[name] = len(data)
        data += struct.pack(">I", len(content)) + content
    nodes = struct.pack(">IHII", 0, 2, 1, 1)  # the root: one child, node 1
    nodes += struct.pack(">IHII", name_offsets["d"], 2, len(files), 2)
    for name in files:
        nodes += struct.pack(">IHII", name_offsets[name], int(compressed), 0, data_offsets[name])
    tree = 20
    return (
        b"qres"
        + struct.pack(">4I", 1, tree, tree + len(nodes), tree + len(nodes) + len(data))
        + nodes
        + data
        + names
    )


def test_photographs_are_read_from_qt_resource_files():
    archive = _resource_file({"a.webp": b"first", "b.webp": b"second member"})
    assert photos.read_rcc(archive, "/d/a.webp") == b"first"
    assert photos.read_rcc(archive, "/d/b.webp") == b"second member"
    with pytest.raises(KeyError, match=r"/d/c\.webp"):
        photos.read_rcc(archive, "/d/c.webp")
    with pytest.raises(KeyError, match="folder"):
        photos.read_rcc(archive, "/d")
    with pytest.raises(ValueError, match="compressed"):
        photos.read_rcc(_resource_file({"a.webp": b"x"}, compressed=True), "/d/a.webp")
    with pytest.raises(ValueError, match="qres"):
        photos.read_rcc(b"PK\x03\x04" + bytes(20), "/d/a.webp")


def test_a_broken_resource_file_is_named(tmp_path):
    photo = photos.Photo("p", "/d/a.webp", "0" * 16, rcc="gcompris.rcc")
    (tmp_path / "gcompris.rcc").write_bytes(_resource_file({"a.webp": b"x"})[:30])
    with pytest.raises(ValueError, match=r"^p: .*gcompris\.rcc: unpack"):
        photos.load(photo, tmp_path)
    (tmp_path / "gcompris.rcc").write_bytes(_resource_file({"b.webp": b"x"}))
    with pytest.raises(ValueError, match=r"gcompris\.rcc: /d/a\.webp is not in"):
        photos.load(photo, tmp_path)


def test_a_missing_data_folder_says_how_to_fetch_it(tmp_path):
    with pytest.raises(FileNotFoundError, match="make training-data"):
        sets.training_images("photos", data=tmp_path / "absent")
    with pytest.raises(FileNotFoundError, match="make training-data"):
        photos.load(catalogue.EXTENDED[-1], data=tmp_path)
    with pytest.raises(ValueError, match="unknown training set 'kodak'"):
        sets.training_images("kodak", data=tmp_path)


def test_augmentation_is_seeded_and_bounded():
    image = np.random.default_rng(0).random((90, 120, 3), dtype=np.float32)
    first = [sets.augment(image, np.random.default_rng([7, i])) for i in range(12)]
    again = [sets.augment(image, np.random.default_rng([7, i])) for i in range(12)]
    other = [sets.augment(image, np.random.default_rng([8, i])) for i in range(12)]
    assert all(a.tobytes() == b.tobytes() for a, b in zip(first, again, strict=True))
    assert any(a.tobytes() != b.tobytes() for a, b in zip(first, other, strict=True))
    shapes = {a.shape for a in first}
    assert len(shapes) > 1, "crops and quarter turns vary the shape"
    for a in first:
        assert a.dtype == np.float32 and a.flags.c_contiguous
        assert 0.0 <= a.min() and a.max() <= 1.0
        assert min(a.shape[:2]) >= round(0.6 * 90) and max(a.shape[:2]) <= 120


def _draw(kind: str, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if kind == "text":
        return synthetic.text_image(rng, 96)
    if kind == "fabric":
        return synthetic.fabric_image(rng, 96)
    luminance = 0.2 + 0.6 * synthetic.smooth_noise(np.random.default_rng(99), (96, 128), 20)
    return synthetic.colour_field_image(luminance, rng)


@pytest.mark.parametrize("kind", ["colour field", "text", "fabric"])
def test_synthetic_images_are_seeded_and_bounded(kind):
    first, again, other = _draw(kind, 1), _draw(kind, 1), _draw(kind, 2)
    assert first.tobytes() == again.tobytes()
    assert first.tobytes() != other.tobytes()
    assert first.dtype == np.float32 and first.ndim == 3 and first.shape[2] == 3
    assert 0.0 <= first.min() and first.max() <= 1.0


def _saturation(rgb: np.ndarray) -> float:
    top, bottom = rgb.max(axis=-1), rgb.min(axis=-1)
    return float(np.mean((top - bottom) / np.maximum(top, 1e-6)))


def test_synthetic_colours_are_saturated_and_weakly_correlated():
    for kind in ["colour field", "text", "fabric"]:
        images = [_draw(kind, seed) for seed in range(4)]
        assert np.mean([_saturation(a) for a in images]) > 0.6, kind
        assert np.mean([synthetic.highpass_correlation(a) for a in images]) < 0.6, kind
    # A grey image's channels are fully correlated; the measure sees it.
    grey = np.repeat(_draw("colour field", 0).mean(axis=-1, keepdims=True), 3, axis=-1)
    assert synthetic.highpass_correlation(grey) > 0.99


def test_synthetic_text_and_cloth_are_band_limited():
    # Drawn at four times the size and area-averaged: no pixel-scale checkerboard.
    for kind in ["text", "fabric"]:
        image = _draw(kind, 3).mean(axis=-1)
        spectrum = np.abs(np.fft.fft2(image - image.mean()))
        assert spectrum[48, 48] < 0.05 * spectrum.max(), kind


@pytest.mark.parametrize("seed", range(4))
def test_the_threads_are_far_from_nyquist(seed):
    image = _draw("fabric", seed).mean(axis=-1)
    spectrum = np.abs(np.fft.fft2(image - image.mean()))
    fy, fx = np.unravel_index(np.argmax(spectrum), spectrum.shape)
    frequency = np.hypot(*(min(f, 96 - f) / 96 for f in (fy, fx)))
    assert frequency <= 1 / synthetic.THREAD_PERIOD[0] + 1 / 96


@needs_data
def test_colour_fields_are_less_correlated_than_the_photographs():
    rng = np.random.default_rng(5)
    chosen = rng.choice(len(photos.TRAINING), size=8, replace=False)
    images = [sets.cached_load(photos.TRAINING[i]) for i in chosen]
    fields = [synthetic.colour_field_image(a @ synthetic.LUMA, rng) for a in images]
    photo_correlation = np.mean([synthetic.highpass_correlation(a) for a in images])
    field_correlation = np.mean([synthetic.highpass_correlation(a) for a in fields])
    assert field_correlation < photo_correlation - 0.2


def _thumbnail(rgb: np.ndarray) -> np.ndarray:
    """A 24x24 grey area average, zero-mean and unit-norm: a fingerprint that survives
    re-encoding and resizing."""
    from PIL import Image

    grey = Image.fromarray(np.round(np.clip(rgb, 0, 1) * 255).astype(np.uint8)).convert("L")
    t = np.asarray(grey.resize((24, 24), Image.Resampling.BOX), dtype=np.float64).ravel()
    t -= t.mean()
    return t / max(np.linalg.norm(t), 1e-9)


@needs_data
def test_no_validation_image_is_among_the_photographs_even_re_encoded():
    import imageio.v3 as iio

    folder = shared_path("data/demosaic-val")
    if folder is None:
        pytest.skip("../shared/data/demosaic-val is absent")
    validation = []
    for file in sorted(folder.glob("*/*.png")):
        rgb = iio.imread(file)[..., :3] / 255.0
        validation += [_thumbnail(rgb), _thumbnail(np.rot90(rgb))]
    validation = np.array(validation)
    for photo in ALL_PHOTOS:
        # Unrelated photographs with a horizon in the same place reach about 0.91.
        similarity = validation @ _thumbnail(sets.cached_load(photo))
        assert similarity.max() < 0.97, f"{photo.name} looks like a validation image"


@needs_data
def test_the_raisr_set_is_what_load_gives():
    photo = photos.TRAINING[0]
    assert np.array_equal(sets.cached_load(photo), photos.load(photo).astype(np.float32))


@needs_data
def test_the_photo_set_is_reproducible():
    first, again = sets.training_images("photos"), sets.training_images("photos")
    assert len(first) == len(catalogue.EXTENDED)
    assert all(a.tobytes() == b.tobytes() for a, b in zip(first, again, strict=True))
    assert all(a.dtype == np.float32 and a.shape[2] == 3 for a in first)


def test_saturate_scales_the_chroma_and_keeps_the_luma():
    rng = np.random.default_rng(3)
    # Muted colours, so that tripled chroma stays in range.
    image = (0.45 + 0.1 * rng.random((20, 30, 3))).astype(np.float32)
    ycc = image @ sets.YCBCR.T
    assert np.allclose(sets.saturate(image, 1.0), image, atol=1e-6)
    for gain in (1.5, 3.0):
        out = sets.saturate(image, gain)
        assert out.dtype == np.float32 and out.flags.c_contiguous
        got = out @ sets.YCBCR.T
        np.testing.assert_allclose(got[..., 0], ycc[..., 0], atol=1e-5)
        np.testing.assert_allclose(got[..., 1:], gain * ycc[..., 1:], atol=1e-5)
    # Grey stays grey; colours past the gamut clip to [0, 1].
    grey = np.full((4, 4, 3), 0.4, np.float32)
    np.testing.assert_allclose(sets.saturate(grey, 3.0), grey, atol=1e-6)
    vivid = sets.saturate(np.float32([[[0.9, 0.1, 0.1]]]), 3.0)
    assert vivid.min() == 0.0 and vivid.max() == 1.0


@needs_data
def test_the_saturated_photo_set_is_a_fifth_of_the_photos_more_colourful():
    plain, saturated = sets.training_images("photos"), sets.training_images("saturated-photos")
    again = sets.training_images("saturated-photos")
    assert all(a.tobytes() == b.tobytes() for a, b in zip(saturated, again, strict=True))
    assert 0.12 < len(saturated) / len(plain) < 0.28

    def luma(image):
        return image @ sets.YCBCR[0]

    def chroma(image):
        return np.abs(image @ sets.YCBCR[1:].T).mean()

    for image in saturated:
        # Its photograph: the same shape and, but where colours clip, the same luma;
        # clipping keeps some of the gain (1.5 to 3) from the mean chroma.
        same = [p for p in plain if p.shape == image.shape]
        source = min(same, key=lambda p: np.abs(luma(p) - luma(image)).mean())
        assert np.median(np.abs(luma(source) - luma(image))) < 0.02
        assert chroma(image) > 1.2 * chroma(source)

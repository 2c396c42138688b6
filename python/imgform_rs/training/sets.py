"""Training images for the learned demosaicers, by set name: one entry point.

``training_images(name, data, seed)`` returns a list of float32 (H, W, 3) arrays in
[0, 1]; the sets (:data:`SETS`):

- ``"raisr"``: the first 33 photographs (:data:`imgform_rs.training.photos.TRAINING`),
  which raisr's weights were trained on while it refined ``"rcd_menon"``, as
  :func:`~imgform_rs.training.photos.load` gives them, unaugmented;
- ``"photos"``: the 293 photographs of :data:`imgform_rs.training.catalogue.EXTENDED`,
  each augmented once by :func:`augment`;
- ``"synthetic"``: saturated, weakly correlated images from
  :mod:`imgform_rs.training.synthetic` (colour fields over the photographs'
  luminance, coloured text, woven cloth);
- ``"union"``: ``"photos"`` then ``"synthetic"``;
- ``"saturated-photos"``: a fifth of ``"photos"`` (:data:`SATURATED_SHARE`, drawn per
  photograph) made more colourful by :func:`saturate`, their chroma scaled by a gain
  drawn from :data:`SATURATION_GAIN`, so that weakly correlated colours are common
  enough for filters of their own;
- ``"held-out"``: :data:`imgform_rs.training.catalogue.EXTENDED_HELD_OUT`,
  unaugmented, to check a trained method on photographs it has not seen; never
  train on it.

Memory: photographs are area-downsampled as ``load`` does (by an integer factor of
at least 2, to a shorter side of about 500 for a large one; most of the set, the
GCompris photographs, is smaller: of ``"photos"``, the median shorter side is 241 px
after it, and a tenth is under 80 px) and kept as float32, about 4.5 MB for a
2560x1600 wallpaper; the crops of :func:`augment` keep 36 % to 100 % of that, so the
``"union"`` set takes about 0.8 GB, which several trainers can afford at once on a
24 GB machine, where full-size photographs (4 to 25 times more) could not be held.

Decoding the JPEG and WebP files and downsampling them in float64, and drawing the
synthetic images at four times their size, take most of the time, so both are
cached in ``<data>/cache``: each photograph's float32 array under its SHA-256 prefix
(checked by ``load`` when the cache is written) and the downsampling rule; the
synthetic images under a hash of the seed and of the code that draws them (and of
the photograph list), so an edit to either never serves stale images. Everything is
drawn from generators seeded by ``seed`` and the image's index, so two calls give
identical arrays.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from imgform_rs.training import catalogue, synthetic
from imgform_rs.training.photos import DEFAULT_DATA, SIDE_PER_FACTOR, TRAINING, Photo, load

SEED = 20261127
#: Side of each crop, as a fraction of the photograph's side (drawn per axis).
CROP_FRACTION = (0.6, 1.0)
#: Exposure change in stops of the encoded values (with a power-law tone curve of
#: exponent 2.2, a gain g on encoded values is a gain g**2.2 on linear light, so this
#: is -2.2 to +1.1 stops of exposure). Values pushed past 1 clip, as a sensor does.
GAIN_STOPS = (-1.0, 0.5)
#: Side of the synthetic text and cloth images and of the colour-field crops.
SYNTHETIC_SIZE = 384
#: The share of ``"saturated-photos"`` whose chroma is scaled, and the range its
#: gain is drawn from.
SATURATED_SHARE = 0.2
SATURATION_GAIN = (1.5, 3.0)
#: BT.601's luma and chroma (Cb, Cr) of RGB.
YCBCR = np.array([[0.299, 0.587, 0.114], [-0.168736, -0.331264, 0.5], [0.5, -0.418688, -0.081312]])
#: How many synthetic images of each kind.
COLOUR_FIELDS, TEXTS, FABRICS = 96, 48, 48


def _write_atomically(path: Path, save: Callable[[object], None]) -> None:
    """``save(file)`` into another name, then renamed: a reader never sees half a file."""
    path.parent.mkdir(exist_ok=True)
    partial = path.with_name(f"{path.name}.{os.getpid()}.partial")
    with partial.open("wb") as f:
        save(f)
    partial.replace(path)


def cached_load(photo: Photo, data: Path = DEFAULT_DATA) -> np.ndarray:
    """``load(photo, data)`` as float32 (grey photographs repeated to three channels),
    cached in ``<data>/cache``."""
    cache = data / "cache" / f"{photo.sha256}-side{SIDE_PER_FACTOR}.npy"
    if cache.is_file():
        return np.load(cache)
    image = load(photo, data).astype(np.float32)
    if image.shape[2] == 1:
        image = np.repeat(image, 3, axis=2)
    _write_atomically(cache, lambda f: np.save(f, image))
    return image


def augment(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A random crop of ``image`` (each side :data:`CROP_FRACTION` of the original),
    one of the eight flips and quarter turns, and an exposure gain
    (:data:`GAIN_STOPS`), clipped to [0, 1]; float32, C-contiguous."""
    h, w = image.shape[:2]
    ch = max(1, round(h * rng.uniform(*CROP_FRACTION)))
    cw = max(1, round(w * rng.uniform(*CROP_FRACTION)))
    top, left = int(rng.integers(h - ch + 1)), int(rng.integers(w - cw + 1))
    crop = np.rot90(image[top : top + ch, left : left + cw], int(rng.integers(4)))
    if rng.integers(2):
        crop = crop[:, ::-1]
    gain = 2.0 ** rng.uniform(*GAIN_STOPS)
    return np.ascontiguousarray(np.clip(crop * gain, 0.0, 1.0), dtype=np.float32)


def saturate(image: np.ndarray, gain: float) -> np.ndarray:
    """``image`` with its BT.601 chroma scaled by ``gain`` and its luma kept, clipped
    to [0, 1]; float32, C-contiguous. Photographs of the wallpaper kind have
    strongly correlated channels; scaled so, their colours are those of saturated
    film scans, with the same structure."""
    ycc = image.astype(np.float64) @ YCBCR.T
    ycc[..., 1:] *= gain
    rgb = ycc @ np.linalg.inv(YCBCR).T
    return np.ascontiguousarray(np.clip(rgb, 0.0, 1.0), dtype=np.float32)


def _raisr(data: Path, seed: int) -> list[np.ndarray]:
    return [cached_load(photo, data) for photo in TRAINING]


def _photos(data: Path, seed: int) -> list[np.ndarray]:
    return [
        augment(cached_load(photo, data), np.random.default_rng([seed, 0, index]))
        for index, photo in enumerate(catalogue.EXTENDED)
    ]


def _saturated_photos(data: Path, seed: int) -> list[np.ndarray]:
    saturated = []
    for index, image in enumerate(_photos(data, seed)):
        rng = np.random.default_rng([seed, 5, index])
        if rng.random() < SATURATED_SHARE:
            saturated.append(saturate(image, rng.uniform(*SATURATION_GAIN)))
    return saturated


def _held_out(data: Path, seed: int) -> list[np.ndarray]:
    return [cached_load(photo, data) for photo in catalogue.EXTENDED_HELD_OUT]


def _luminance_crop(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The luminance of a random :data:`SYNTHETIC_SIZE` square of ``image`` (all of it
    along a shorter side)."""
    h, w = image.shape[:2]
    ch, cw = min(h, SYNTHETIC_SIZE), min(w, SYNTHETIC_SIZE)
    top, left = int(rng.integers(h - ch + 1)), int(rng.integers(w - cw + 1))
    return image[top : top + ch, left : left + cw] @ synthetic.LUMA


def _synthetic(data: Path, seed: int) -> list[np.ndarray]:
    # The colour fields depend on the photograph list too.
    modules = (synthetic.__file__, catalogue.__file__, __file__)
    code = b"".join(Path(module).read_bytes() for module in modules)
    key = hashlib.sha256(code + str(seed).encode()).hexdigest()[:16]
    cache = data / "cache" / f"synthetic-{key}.npz"
    if cache.is_file():
        with np.load(cache) as stored:
            return [stored[f"arr_{i}"] for i in range(len(stored.files))]
    images = _draw_synthetic(data, seed)
    _write_atomically(cache, lambda f: np.savez(f, *images))
    return images


def _draw_synthetic(data: Path, seed: int) -> list[np.ndarray]:
    # The colour fields modulate photographs chosen at random from the extended set,
    # at least 200 pixels on a side, so that each field has room to change hue.
    pick = np.random.default_rng([seed, 1])
    large = [p for p in catalogue.EXTENDED if min(cached_load(p, data).shape[:2]) >= 200]
    chosen = pick.choice(len(large), size=COLOUR_FIELDS, replace=False)
    images = []
    for index, photo_index in enumerate(chosen):
        rng = np.random.default_rng([seed, 2, index])
        luminance = _luminance_crop(cached_load(large[photo_index], data), rng)
        images.append(synthetic.colour_field_image(luminance, rng))
    for index in range(TEXTS):
        rng = np.random.default_rng([seed, 3, index])
        images.append(synthetic.text_image(rng, SYNTHETIC_SIZE))
    for index in range(FABRICS):
        rng = np.random.default_rng([seed, 4, index])
        images.append(synthetic.fabric_image(rng, SYNTHETIC_SIZE))
    return images


def _union(data: Path, seed: int) -> list[np.ndarray]:
    return _photos(data, seed) + _synthetic(data, seed)


SETS: dict[str, Callable[[Path, int], list[np.ndarray]]] = {
    "raisr": _raisr,
    "photos": _photos,
    "synthetic": _synthetic,
    "union": _union,
    "saturated-photos": _saturated_photos,
    "held-out": _held_out,
}


def training_images(name: str, data: Path = DEFAULT_DATA, seed: int = SEED) -> list[np.ndarray]:
    """The images of the set ``name`` (one of :data:`SETS`), float32 (H, W, 3) in
    [0, 1]; the same ``seed`` gives identical arrays.

    Raises ``ValueError`` for an unknown set name and ``FileNotFoundError`` (saying
    to run ``make training-data``) when ``data`` lacks the photographs.

    Example: ``images = training_images("union")``.
    """
    if name not in SETS:
        raise ValueError(f"unknown training set {name!r}; the sets are {', '.join(SETS)}")
    data = Path(data)
    if not data.is_dir():
        raise FileNotFoundError(f"{data} is missing: run `make training-data`")
    return SETS[name](data, seed)

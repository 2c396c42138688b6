"""Openly licensed colour photographs for training, fetched from PyPI and Debian.

``make training-data`` puts them in ``out/training-data`` (the commands are in the
Makefile): ``apt-get download`` of three Debian wallpaper packages (unpacked with
``dpkg -x``)
and ``pip download --no-deps`` of the scikit-learn and matplotlib wheels, whose images
are read straight from the zip. Every file is checked against the first 16 hex digits
of its SHA-256, so a run either sees the very bytes the shipped weights were trained on
or stops.

The photographs and their licences (the Debian packages' ``copyright`` files):

- KDE Plasma wallpapers (Debian ``plasma-workspace-wallpapers`` 4:5.27.5-2; each
  wallpaper's ``metadata.json`` says LGPLv3, the package's ``copyright`` file GPL-2+):
  BytheWater (Maciej Wiklo), ColdRipple, DarkestHour, Kite, OneStandsOut, summer_1am
  (Risto Saukonpää), ColorfulCups (Dmitri Popov), FallenLeaf (Martin Klapetek), Grey
  (Sigi Sagi), all 2560x1600 JPEG. EveningGlow (Ian Hex) and Path (Risto Saukonpää) are
  held out of training as a check on unseen photographs; the painted wallpapers
  (Autumn, PastelHills, the vector art) are not used.
- Ubuntu Touch wallpapers (Debian ``lomiri-wallpapers-16.04`` 20.04.0-2): Bridge (Sander
  Klootwijk), Dragonfly (Bolly), free and greentock (Peter Nerlich): CC BY-SA 4.0;
  Picture_0B and Picture_1A (freespace), Wine (Jakkub Mede), aitzgorri, friends, life
  and picosdeeuropa (Aitzol Berasategi): CC BY 4.0; seeding (Clements Engelhardt):
  CC0 1.0. sunset (Aitzol Berasategi, CC BY 4.0) is held out; umang and analogpattern
  (abstract) are not used.
- MATE's nature backgrounds (Debian ``mate-backgrounds`` 1.26.0-1), GPL-2+: Aqua
  (Charles Barbin), Blinds (Lennart Poettering), Dune (Marco Cogoni), FreshFlower
  (Jens Ansorg), GreenMeadow (Timothy Schellhase), RainDrops (blackcombwhistler07),
  Storm (Sergey Nazarov), TwoWings (Charles Barbin), Wood (Jean-François Fortin Tam).
- scikit-learn's ``sklearn/datasets/images``: china.jpg and flower.jpg, CC BY 2.0
  (danielbuechele and vultilion on Flickr, per the folder's README.txt).
- matplotlib's ``mpl-data/sample_data/grace_hopper.jpg``: US Navy photograph, public
  domain.

The extended set for the other learned demosaicers (these photographs and 266 more)
is in :mod:`imgform_rs.training.catalogue`; :mod:`imgform_rs.training.sets` turns it
into training images.

JPEG compression and the camera's own demosaicing leave artefacts at the pixel scale
that a demosaicer must not learn as truth, so each photo is downsampled by an integer
factor with an area average: the shorter side over 500, at least 2.
"""

from __future__ import annotations

import hashlib
import io
import struct
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DEFAULT_DATA = Path(__file__).resolve().parents[3] / "out/training-data"
#: Shorter side per unit of the downsampling factor.
SIDE_PER_FACTOR = 500


@dataclass(frozen=True)
class Photo:
    """A photograph: where it lives under the data folder (inside ``wheel``'s zip, or
    inside the Qt resource file ``rcc``, if one is given) and its SHA-256 prefix."""

    name: str
    path: str
    sha256: str
    wheel: str | None = None
    rcc: str | None = None


def _plasma(name: str, sha256: str) -> Photo:
    return Photo(name, f"plasma/usr/share/wallpapers/{name}/contents/images/2560x1600.jpg", sha256)


def _lomiri(name: str, sha256: str) -> Photo:
    return Photo(name, f"lomiri/usr/share/backgrounds/{name}.jpg", sha256)


def _mate(name: str, sha256: str) -> Photo:
    return Photo(name, f"mate/usr/share/backgrounds/mate/nature/{name}.jpg", sha256)


TRAINING = [
    _plasma("BytheWater", "c272434ef39f2abf"),
    _plasma("ColdRipple", "05bef6722fc0ed81"),
    _plasma("ColorfulCups", "6e0f3a72feb5a4a9"),
    _plasma("DarkestHour", "8e3703fae3a3c217"),
    _plasma("FallenLeaf", "95603a6560c7e8d5"),
    _plasma("Grey", "88c31d8944b7e693"),
    _plasma("Kite", "bdca288ce296a981"),
    _plasma("OneStandsOut", "cb507baf1dafdcae"),
    _plasma("summer_1am", "c868b50789591dd4"),
    _lomiri("Bridge_by_Sander_Klootwijk", "bd86b081f9975e2b"),
    _lomiri("Dragonfly_by_Bolly", "af5af17841009732"),
    _lomiri("Picture_0B_by_freespace", "c8c0ab18e48d9e04"),
    _lomiri("Picture_1A_by_freespace", "89e86af38d04daae"),
    _lomiri("Wine_by_Jakkub_Mede", "d2e96e6d4da40dd8"),
    _lomiri("aitzgorri_by_Aitzol_Berasategi", "66268e7b48f8854d"),
    _lomiri("free_by_Peter_Nerlich", "85a5453c2fed514c"),
    _lomiri("friends_by_Aitzol_Berasategi", "cc40e313c74e421e"),
    _lomiri("greentock_by_Peter_Nerlich", "e7b20e2db9dcd6e2"),
    _lomiri("life_by_Aitzol_Berasategi", "4c119350ead80201"),
    _lomiri("picosdeeuropa_by_Aitzol_Berasategi", "414d0072b2f6f2c5"),
    _lomiri("seeding_by_Clements_Engelhardt", "a5634d1ab5e41a35"),
    _mate("Aqua", "5c30118205982da4"),
    _mate("Blinds", "f7aac0dcc2e06d04"),
    _mate("Dune", "8a67c2cb0be8c46b"),
    _mate("FreshFlower", "972b0a0c4e5e3fa9"),
    _mate("GreenMeadow", "8fa0de0aa4089f73"),
    _mate("RainDrops", "3e4ea9671c28c90a"),
    _mate("Storm", "77ca53077831d323"),
    _mate("TwoWings", "665e5abf8a539907"),
    _mate("Wood", "19c78500ac00a622"),
    Photo("china", "sklearn/datasets/images/china.jpg", "8378025ad2519d64", "scikit_learn"),
    Photo("flower", "sklearn/datasets/images/flower.jpg", "a77f6ec41e353afd", "scikit_learn"),
    Photo(
        "grace_hopper",
        "matplotlib/mpl-data/sample_data/grace_hopper.jpg",
        "a8ca6d734765703b",
        "matplotlib",
    ),
]
#: Photographs never trained on, to check the method on images it has not seen.
HELD_OUT = [
    _plasma("EveningGlow", "586682dcb362b9f6"),
    _plasma("Path", "7477457d7f17b736"),
    _lomiri("sunset_by_Aitzol_Berasategi", "474dab6a4b9f94dc"),
]


#: Flags of a node in a Qt resource file (Qt's ``rcc`` format).
_RCC_COMPRESSED, _RCC_DIRECTORY, _RCC_ZSTD = 1, 2, 4
#: A node: name offset, flags, then (child count, first child) for a directory or
#: (locale, data offset) for a file.
_RCC_NODE = struct.Struct(">IHII")


def read_rcc(archive: bytes, member: str) -> bytes:
    """The bytes of ``member`` (a path such as ``"/a/b.webp"``) in a Qt resource file.

    The format (Qt's ``rcc``): the magic ``qres``, a version and the offsets of a
    tree of fixed-size nodes, of the file data and of the names; node 0 is the root.
    GCompris ships its photographs this way, stored uncompressed (WebP is compressed
    already), so compressed members are refused rather than decoded.
    """
    if archive[:4] != b"qres":
        raise ValueError("not a Qt resource file (no 'qres' magic)")
    version, tree, data, names = struct.unpack_from(">4I", archive, 4)
    node_size = 14 if version == 1 else 22  # version 2 added a modification time

    def node(index: int) -> tuple[int, int, int, int]:
        return _RCC_NODE.unpack_from(archive, tree + index * node_size)

    def name(offset: int) -> str:
        (length,) = struct.unpack_from(">H", archive, names + offset)
        start = names + offset + 6  # after the length and the name's hash
        return archive[start : start + 2 * length].decode("utf-16-be")

    index = 0
    for part in member.strip("/").split("/"):
        _, flags, count, first = node(index)
        children = range(first, first + count) if flags & _RCC_DIRECTORY else range(0)
        found = [child for child in children if name(node(child)[0]) == part]
        if not found:
            raise KeyError(f"{member} is not in the resource file")
        index = found[0]
    _, flags, _, offset = node(index)
    if flags & _RCC_DIRECTORY:
        raise KeyError(f"{member} is a folder of the resource file")
    if flags & (_RCC_COMPRESSED | _RCC_ZSTD):
        raise ValueError(f"{member} is stored compressed in the resource file")
    (size,) = struct.unpack_from(">I", archive, data + offset)
    return archive[data + offset + 4 : data + offset + 4 + size]


def _read_bytes(photo: Photo, data: Path) -> bytes:
    if photo.wheel is None:
        file = data / (photo.rcc or photo.path)
        if not file.is_file():
            raise FileNotFoundError(f"{file} is missing: run `make training-data`")
        raw = file.read_bytes()
        if photo.rcc is None:
            return raw
        try:
            return read_rcc(raw, photo.path)
        except (KeyError, ValueError, struct.error) as error:
            raise ValueError(f"{photo.name}: {file}: {error.args[0]}") from error
    wheels = sorted(data.glob(f"{photo.wheel}-*.whl"))
    if not wheels:
        raise FileNotFoundError(f"no {photo.wheel} wheel in {data}: run `make training-data`")
    with zipfile.ZipFile(wheels[-1]) as z:
        return z.read(photo.path)


def area_downsample(rgb: np.ndarray, factor: int) -> np.ndarray:
    """The mean of each ``factor`` x ``factor`` block (the edge remainder is cut)."""
    h, w = rgb.shape[0] // factor * factor, rgb.shape[1] // factor * factor
    blocks = rgb[:h, :w].reshape(h // factor, factor, w // factor, factor, -1)
    return blocks.astype(np.float64).mean(axis=(1, 3))


def load(photo: Photo, data: Path = DEFAULT_DATA) -> np.ndarray:
    """The photo as float64 in [0, 1], shaped (H, W, 3) (grey photos (H, W, 1)),
    downsampled by ``max(2, shorter side // SIDE_PER_FACTOR)``; raises ``ValueError``
    if its bytes are not the expected ones."""
    import imageio.v3 as iio

    raw = _read_bytes(photo, data)
    digest = hashlib.sha256(raw).hexdigest()[:16]
    if digest != photo.sha256:
        raise ValueError(f"{photo.name}: SHA-256 {digest}..., expected {photo.sha256}...")
    pixels = iio.imread(io.BytesIO(raw))
    if pixels.ndim == 2:
        pixels = pixels[..., None]
    factor = max(2, min(pixels.shape[:2]) // SIDE_PER_FACTOR)
    return area_downsample(pixels, factor) / 255.0

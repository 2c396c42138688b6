"""A minimal PNG encoder (8- or 16-bit grey or RGB) on the standard library's zlib,
and a reader of 16-bit colour PNGs.

Both exist for what imageio cannot do: imageio's PNG codec is Pillow's, and
Pillow has no 16-bit RGB mode (``Image.fromarray`` refuses (H, W, 3) uint16,
and it reads such a file as 8-bit RGB), so 16-bit colour PNGs are written
here, with their ICC profile (``iCCP``) and EXIF (``eXIf``) chunks, and read
here at full depth. :func:`imgform_rs.write_image` hands every other PNG to
imageio.
"""

from __future__ import annotations

import io
import struct
import zlib
from pathlib import Path

import numpy as np

from ._files import read_regular

# zlib level 1: level 6 took twice the time for files 0-5 % smaller (no
# row filters here; 16-bit photographs barely compress either way).
_LEVEL = 1

_SIGNATURE = b"\x89PNG\r\n\x1a\n"

# Pillow's unpackers of 16-bit RGB and RGBA PNG pixels (big-endian samples,
# of which it keeps the high bytes), and those of pixels of the same size
# whose little-endian samples' high bytes are the other bytes.
_LOW_BYTES = {"RGB;16B": "RGB;16L", "RGBA;16B": "RGBA;16L"}


def _chunk(kind: bytes, payload: bytes) -> bytes:
    body = kind + payload
    return struct.pack(">I", len(payload)) + body + struct.pack(">I", zlib.crc32(body))


def write_png(
    path: str | Path, image: np.ndarray, *, icc: bytes | None = None, exif: bytes | None = None
) -> Path:
    """Write a uint8 or uint16 (H, W) or (H, W, 3) array as a PNG file and
    return its path (16-bit samples keep their full depth). ``icc`` is an
    ICC profile, ``exif`` EXIF as Pillow makes it (a leading ``Exif\0\0``
    is dropped, as PNG's ``eXIf`` chunk starts at the TIFF header)."""
    img = np.asarray(image)
    if (
        img.dtype not in (np.uint8, np.uint16)
        or img.ndim not in (2, 3)
        or (img.ndim == 3 and img.shape[2] != 3)
    ):
        raise ValueError(
            f"write_png takes uint8 or uint16 (H, W) or (H, W, 3), got {img.dtype} {img.shape}"
        )
    height, width = img.shape[:2]
    colour_type = 2 if img.ndim == 3 else 0
    depth = 8 * img.dtype.itemsize
    # PNG stores 16-bit samples big-endian; as bytes, every row is then a
    # plain byte string led by filter type 0 (none); zlib compresses.
    rows = np.ascontiguousarray(img, dtype=img.dtype.newbyteorder(">")).view(np.uint8)
    rows = rows.reshape(height, -1)
    raw = np.hstack([np.zeros((height, 1), np.uint8), rows]).tobytes()
    header = struct.pack(">IIBBBBB", width, height, depth, colour_type, 0, 0, 0)
    data = b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", header)
    if icc:
        # Profile name, its terminator, compression method 0 (zlib).
        data += _chunk(b"iCCP", b"ICC profile\0\0" + zlib.compress(icc))
    if exif:
        data += _chunk(b"eXIf", exif.removeprefix(b"Exif\0\0"))
    data += _chunk(b"IDAT", zlib.compress(raw, _LEVEL)) + _chunk(b"IEND", b"")
    path = Path(path)
    path.write_bytes(data)
    return path


def read_png16(data: bytes) -> np.ndarray | None:
    """The samples of a 16-bit RGB or RGBA PNG file's bytes, uint16 (H, W, 3)
    or (H, W, 4); None for any other file, which imageio reads whole.

    Pillow decodes the file twice, inflating and undoing the row filters in
    its own C code: once as it would (each sample's high byte) and once
    unpacking the same pixels as if their samples were little-endian, which
    gives the low bytes.
    """
    from PIL import Image

    if not data.startswith(_SIGNATURE):
        return None
    with Image.open(io.BytesIO(data)) as im:
        if len(im.tile) != 1 or im.tile[0][3] not in _LOW_BYTES:
            return None
        high = np.asarray(im)
    with Image.open(io.BytesIO(data)) as im:
        name, box, offset, rawmode = im.tile[0]
        im.tile = [(name, box, offset, _LOW_BYTES[rawmode])]
        low = np.asarray(im)
    return high.astype(np.uint16) << 8 | low


#: Pillow's modes whose channels are not R, G, B: read as RGB.
_NOT_RGB = ("CMYK", "YCbCr", "LAB", "HSV")


def upright(img: np.ndarray, data: bytes) -> np.ndarray:
    """``img``, decoded from ``data`` without Pillow's turn, turned by the
    file's EXIF orientation as Pillow turns what it decodes: the LibRaw flip
    code that the orientation stands for, applied as ``develop`` applies it."""
    from PIL import Image

    from ._exif import _EXIF_ORIENTATION, _ORIENTATION
    from .develop import _orient

    with Image.open(io.BytesIO(data)) as im:
        orientation = im.getexif().get(_ORIENTATION, 1)
    flips = {tag: flip for flip, tag in _EXIF_ORIENTATION.items()}
    return _orient(img, flips.get(orientation, 0))


def read_image(path: Path) -> np.ndarray:
    """The pixels of an image file: a 16-bit colour PNG at its full depth
    (:func:`read_png16`), any other file by imageio. Decoded from the file's
    bytes, as imageio leaves a file it fails on open otherwise.

    What Pillow decodes comes upright, turned by its EXIF orientation as
    viewers show it, and in RGB where its file holds other channels (a CMYK
    JPEG's C, M, Y were read as R, G, B)."""
    import imageio.v3 as iio

    data = read_regular(path)
    img = read_png16(data)
    if img is not None:
        return upright(img, data)
    ext = path.suffix or None
    mode = iio.immeta(data, extension=ext).get("mode")
    if mode is None:  # not Pillow's: tifffile's TIFF, ...
        return np.asarray(iio.imread(data, extension=ext))
    rgb = "RGB" if mode in _NOT_RGB else None
    return np.asarray(iio.imread(data, extension=ext, rotate=True, mode=rgb))


def for_png(rgb: np.ndarray) -> np.ndarray:
    """uint8/uint16 pass through; float images are clipped to [0, 1] and
    written with 16 bits."""
    if rgb.dtype in (np.uint8, np.uint16):
        return rgb
    return np.floor(np.clip(rgb, 0.0, 1.0) * 65535.0 + 0.5).astype(np.uint16)

"""A minimal DNG writer for CFA mosaics, so LibRaw (rawpy) can read our raws.

We write just what the DNG 1.4 specification requires for an uncompressed CFA
image, plus the colour tags LibRaw needs to develop it: one little-endian TIFF
IFD holding the mosaic as a single uint16 strip, ``PhotometricInterpretation =
CFA``, ``CFARepeatPatternDim`` / ``CFAPattern`` (0 = R, 1 = G, 2 = B, the same
indices as our patterns), black and white levels (the black level may be a
repeating pattern), ``ColorMatrix1``, ``AsShotNeutral`` and the orientation;
optionally how the shot was taken (lens, focal length, f-number) in an EXIF
sub-IFD, where cameras put it and LibRaw reads it, so that lens corrections
can be tested on files whose metadata are known. It serves the LibRaw
benchmark and the raw pipeline's tests.
"""

from __future__ import annotations

import os
import struct
from fractions import Fraction
from typing import Any

import numpy as np
import numpy.typing as npt

from ._arrays import integer, real
from .cfa import Pattern, pattern_cells

# TIFF field types.
_BYTE, _ASCII, _SHORT, _LONG, _RATIONAL, _SRATIONAL = 1, 2, 3, 4, 5, 10
_TYPE_SIZE = {_BYTE: 1, _ASCII: 1, _SHORT: 2, _LONG: 4, _RATIONAL: 8, _SRATIONAL: 8}
_TYPE_CODE = {_BYTE: "B", _ASCII: "B", _SHORT: "H", _LONG: "I"}
_CFA = 32803  # PhotometricInterpretation of a colour filter array image.
_D65 = 21  # CalibrationIlluminant code.
# EXIF tags (CIPA DC-008): the sub-IFD pointer in IFD0 and what goes in it.
_EXIF_IFD, _F_NUMBER, _FOCAL_LENGTH, _LENS_MODEL = 34665, 33437, 37386, 42036

#: The shortest side a DNG may have: LibRaw refuses images under 22 pixels on
#: a side (as rawpy reports), so a smaller file would be unreadable.
MIN_SIDE = 22

# XYZ (D65) to linear sRGB: with it as ColorMatrix1 a developer maps the
# camera's RGB to sRGB unchanged, which suits synthetic mosaics of sRGB images.
XYZ_TO_SRGB = (
    (3.2404542, -1.5371385, -0.4985314),
    (-0.9692660, 1.8760108, 0.0415560),
    (0.0556434, -0.2040259, 1.0572252),
)


#: The photosite aspects of a DNG LibRaw opens (``DefaultScale``'s ratio).
PIXEL_ASPECTS = (0.1, 10.0)


def _rationals(values: Any, signed: bool) -> list[int]:
    flat = np.asarray(values, np.float64).ravel()
    out = []
    for v in flat:
        f = Fraction(float(v)).limit_denominator(1_000_000)
        if not signed and abs(f - float(v)) > 1e-6 * abs(v):
            # The unsigned ones are measures > 0 (a neutral, an aspect, a
            # focal length): 1e-7 was written as 0 / 1.
            raise ValueError(
                f"{float(v)!r} cannot be written as a TIFF RATIONAL to 1e-6 of itself "
                "(denominators up to 1000000)"
            )
        out += [f.numerator, f.denominator]
    fmt = "i" if signed else "I"
    try:
        struct.pack(f"<{len(out)}{fmt}", *out)  # range check: raises for overflow
    except struct.error as exc:
        kind = "SRATIONAL" if signed else "RATIONAL"
        raise ValueError(
            f"{flat.tolist()} cannot be written as TIFF {kind}s (32-bit {'signed ' * signed}"
            "numerators over denominators up to 1000000)"
        ) from exc
    return out


def _matrix(value: Any, name: str) -> npt.NDArray[np.float64]:
    """``value`` as a finite (3, 3) matrix; ValueError naming ``name``
    otherwise (LibRaw reads a smaller one as zeros)."""
    m = np.asarray(value, np.float64)
    if m.shape != (3, 3):
        raise ValueError(f"{name} must be a finite (3, 3) matrix, got shape {m.shape}")
    if not np.isfinite(m).all():
        raise ValueError(f"{name} must be a finite (3, 3) matrix, got {m.tolist()}")
    return m


class _Ifd:
    """Collects entries, then lays out the IFD and its out-of-line values."""

    def __init__(self) -> None:
        self.entries: list[tuple[int, int, int, bytes]] = []

    def add(self, tag: int, kind: int, values: Any) -> None:
        if kind == _ASCII:
            payload = values.encode("ascii") + b"\0"
            count = len(payload)
        elif kind in (_RATIONAL, _SRATIONAL):
            nums = _rationals(values, kind == _SRATIONAL)
            payload = struct.pack(f"<{len(nums)}{'i' if kind == _SRATIONAL else 'I'}", *nums)
            count = len(nums) // 2
        else:
            vals = [int(v) for v in np.atleast_1d(values)]
            payload = struct.pack(f"<{len(vals)}{_TYPE_CODE[kind]}", *vals)
            count = len(vals)
        self.entries.append((tag, kind, count, payload))

    def pack(self, offset: int) -> bytes:
        """The IFD (starting at file offset ``offset``) followed by its data."""
        self.entries.sort()
        head_len = 2 + 12 * len(self.entries) + 4
        data = b""
        table = struct.pack("<H", len(self.entries))
        for tag, kind, count, payload in self.entries:
            if len(payload) <= 4:
                field = payload.ljust(4, b"\0")
            else:
                if (offset + head_len + len(data)) % 2:
                    data += b"\0"  # TIFF values start on word boundaries
                field = struct.pack("<I", offset + head_len + len(data))
                data += payload
            table += struct.pack("<HHI", tag, kind, count) + field
        return table + struct.pack("<I", 0) + data


def _black_pattern(black_level: Any, white_level: int) -> npt.NDArray[np.int64]:
    """The black level as an (r, c) integer pattern, checked against white."""
    black = np.asarray(black_level)
    if black.ndim == 0:
        black = black.reshape(1, 1)
    if black.dtype.kind not in "iu" or black.ndim != 2 or black.size == 0:
        raise ValueError(
            f"black_level must be an int or an (r, c) integer pattern, got {black_level!r}"
        )
    if max(black.shape) > 64 or not (0 <= black.min() and black.max() < white_level <= 65535):
        raise ValueError(
            "levels must satisfy 0 <= black_level < white_level <= 65535 with a black "
            f"pattern of at most 64 x 64, got black_level={black_level}, "
            f"white_level={white_level}"
        )
    return black.astype(np.int64)


def write_dng(
    path: str | os.PathLike[str],
    cfa: npt.NDArray[np.integer],
    pattern: Pattern,
    *,
    white_level: int,
    black_level: int | npt.ArrayLike = 0,
    color_matrix: Any = XYZ_TO_SRGB,
    as_shot_neutral: Any = (1.0, 1.0, 1.0),
    forward_matrix: Any = None,
    model: str = "imgform-rs synthetic",
    make: str = "imgform-rs",
    orientation: int = 1,
    pixel_aspect: float = 1.0,
    lens: str = "",
    focal_length: float = 0.0,
    f_number: float = 0.0,
) -> None:
    """Write a CFA mosaic as an uncompressed DNG that LibRaw reads back exactly.

    Parameters
    ----------
    path : str or PathLike
        File to create (overwritten).
    cfa : ndarray, shape (H, W), uint16 (or uint8, widened)
        The mosaic; ``rawpy.imread(path).raw_image_visible`` returns it unchanged.
        At least :data:`MIN_SIDE` (22) pixels on a side: LibRaw refuses smaller
        images.
    pattern : str or array_like
        Bayer name or tile, or an X-Trans tile, of pixel (0, 0).
    white_level : int
        Saturation level in digital numbers (e.g. 4095 for 12 bits).
    black_level : int or array_like of int, shape (r, c)
        Offset subtracted by raw developers; an array is a pattern repeating
        from pixel (0, 0) (``BlackLevelRepeatDim`` = (r, c), at most 64 x 64).
    color_matrix : array_like (3, 3)
        DNG ``ColorMatrix1``: XYZ (D65) to camera RGB. The default makes camera
        RGB linear sRGB.
    as_shot_neutral : array_like (3,)
        White balance as camera RGB of a neutral; (1, 1, 1) leaves it alone.
    forward_matrix : array_like (3, 3), optional
        DNG ``ForwardMatrix1``: white-balanced camera RGB to XYZ (D50), which
        DNG readers prefer to inverting ``ColorMatrix1`` (LibRaw ignores it).
    model : str
        ``UniqueCameraModel`` (also written as Model).
    make : str
        ``Make``: with ``model``, the camera lensfun is searched for.
    orientation : int
        EXIF / TIFF ``Orientation``, 1 (as stored) to 8.
    pixel_aspect : float
        Width / height of a photosite, written as ``DefaultScale``
        (``pixel_aspect``, 1): developers stretch the image to square pixels.
        0.1 to 10 (:data:`PIXEL_ASPECTS`): LibRaw opens no file beyond.
    lens : str
        EXIF ``LensModel``, e.g. ``"EF-S 18-55mm f/3.5-5.6 IS"``.
    focal_length, f_number : float
        EXIF ``FocalLength`` (mm) and ``FNumber``; 0 leaves them out.

    Raises
    ------
    TypeError
        For a non-integer mosaic, a ``white_level`` or ``orientation`` that
        is not an integer, a ``pixel_aspect``, ``focal_length`` or
        ``f_number`` that is not a real number.
    ValueError
        For a mosaic that is not 2-D or under 22 pixels on a side, levels outside 0..65535 or
        black not below white, a black pattern over 64 x 64, a colour or
        forward matrix that is not a finite (3, 3) one, a neutral that is not
        three finite values > 0, an orientation outside 1..8, a pixel aspect
        outside 0.1..10, a focal length or f-number that is not a positive
        finite number (0: unknown), numbers beyond a TIFF rational's range or
        too small for its precision, or text that is not ASCII.

    Examples
    --------
    >>> import tempfile, rawpy
    >>> raw = np.arange(32 * 32, dtype=np.uint16).reshape(32, 32)
    >>> with tempfile.TemporaryDirectory() as d:
    ...     write_dng(f"{d}/a.dng", raw, "GRBG", white_level=4095)
    ...     with rawpy.imread(f"{d}/a.dng") as r:
    ...         bool((r.raw_image_visible == raw).all())
    True
    """
    arr = np.asarray(cfa)
    if arr.dtype not in (np.uint8, np.uint16):
        raise TypeError(f"cfa must be a uint16 (or uint8) mosaic, got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.size == 0:
        raise ValueError(f"cfa must be a non-empty (H, W) mosaic, got shape {arr.shape}")
    if min(arr.shape) < MIN_SIDE:
        # A file no raw reader opens would only fail later, elsewhere.
        raise ValueError(
            f"cfa must be at least {MIN_SIDE} pixels on a side (LibRaw refuses smaller "
            f"images), got shape {arr.shape}"
        )
    white_level = integer(white_level, "white_level")
    black = _black_pattern(black_level, white_level)
    if integer(orientation, "orientation") not in range(1, 9):
        raise ValueError(f"orientation must be an EXIF orientation 1..8, got {orientation!r}")
    pixel_aspect = real(pixel_aspect, "pixel_aspect")
    lo, hi = PIXEL_ASPECTS
    if not lo <= pixel_aspect <= hi:
        # LibRaw opens no file beyond these.
        raise ValueError(f"pixel_aspect must be in {lo:g}..{hi:g}, got {pixel_aspect!r}")
    focal_length, f_number = real(focal_length, "focal_length"), real(f_number, "f_number")
    for name, value in (("focal_length", focal_length), ("f_number", f_number)):
        if not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be a positive number or 0 (unknown), got {value!r}")
    for name, text in (("make", make), ("model", model), ("lens", lens)):
        if not (isinstance(text, str) and text.isascii()):
            raise ValueError(f"{name} must be an ASCII str (a TIFF ASCII tag), got {text!r}")
    matrix = _matrix(color_matrix, "color_matrix")
    forward = None if forward_matrix is None else _matrix(forward_matrix, "forward_matrix")
    neutral = np.asarray(as_shot_neutral, np.float64)
    if neutral.shape != (3,) or not (np.isfinite(neutral).all() and (neutral > 0).all()):
        raise ValueError(
            "as_shot_neutral must be three finite values > 0 (camera R, G, B of a neutral), "
            f"got {as_shot_neutral!r}"
        )
    tile = pattern_cells(pattern)
    h, w = arr.shape
    pixels = np.ascontiguousarray(arr, dtype="<u2").tobytes()

    ifd = _Ifd()
    ifd.add(254, _LONG, 0)  # NewSubfileType: the main image
    ifd.add(256, _LONG, w)
    ifd.add(257, _LONG, h)
    ifd.add(258, _SHORT, 16)
    ifd.add(259, _SHORT, 1)  # no compression
    ifd.add(262, _SHORT, _CFA)
    ifd.add(271, _ASCII, make)
    ifd.add(272, _ASCII, model)
    ifd.add(274, _SHORT, orientation)
    ifd.add(277, _SHORT, 1)
    ifd.add(278, _LONG, h)
    ifd.add(279, _LONG, len(pixels))
    ifd.add(284, _SHORT, 1)
    ifd.add(33421, _SHORT, tile.shape)  # CFARepeatPatternDim
    ifd.add(33422, _BYTE, tile.ravel())  # CFAPattern
    ifd.add(50706, _BYTE, (1, 4, 0, 0))  # DNGVersion
    ifd.add(50707, _BYTE, (1, 1, 0, 0))  # DNGBackwardVersion
    ifd.add(50708, _ASCII, model)
    ifd.add(50710, _BYTE, (0, 1, 2))  # CFAPlaneColor: our indices are R, G, B
    ifd.add(50711, _SHORT, 1)  # CFALayout: rectangular
    ifd.add(50713, _SHORT, black.shape)  # BlackLevelRepeatDim
    ifd.add(50714, _LONG, black.ravel())
    ifd.add(50717, _LONG, int(white_level))
    ifd.add(50718, _RATIONAL, (pixel_aspect, 1.0))  # DefaultScale
    ifd.add(50721, _SRATIONAL, matrix)
    ifd.add(50728, _RATIONAL, neutral)
    ifd.add(50778, _SHORT, _D65)
    if forward is not None:
        ifd.add(50964, _SRATIONAL, forward)

    # Header, then the pixels (so the strip offset is known), then the EXIF
    # IFD if any (so IFD0 can point to it), then IFD0.
    strip_offset = 8
    exif_offset = strip_offset + len(pixels) + (len(pixels) % 2)
    exif = _shot_ifd(lens, focal_length, f_number)
    exif_body = b""
    if exif is not None:
        exif_body = exif.pack(exif_offset)
        exif_body += b"\0" * (len(exif_body) % 2)
        ifd.add(_EXIF_IFD, _LONG, exif_offset)
    ifd_offset = exif_offset + len(exif_body)
    ifd.add(273, _LONG, strip_offset)
    body = ifd.pack(ifd_offset)
    with open(path, "wb") as f:
        f.write(b"II*\0" + struct.pack("<I", ifd_offset))
        f.write(pixels)
        f.write(b"\0" * (len(pixels) % 2))
        f.write(exif_body)
        f.write(body)


def _shot_ifd(lens: str, focal_length: float, f_number: float) -> _Ifd | None:
    """The EXIF sub-IFD holding what is known of the shot, or None."""
    exif = _Ifd()
    if f_number:
        exif.add(_F_NUMBER, _RATIONAL, f_number)
    if focal_length:
        exif.add(_FOCAL_LENGTH, _RATIONAL, focal_length)
    if lens:
        exif.add(_LENS_MODEL, _ASCII, lens)
    return exif if exif.entries else None

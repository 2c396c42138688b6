"""The EXIF a developed picture carries over from its raw, built by Pillow.

What is copied: camera make and model, lens, ISO, exposure time, f-number,
focal length, capture date and artist. LibRaw reads these from every format it
decodes (CRW and QTK too, where there is no TIFF to copy from), and rawpy
exposes them (``RawPy.other``, ``RawPy.lens``) except make and model, which
come from the file's TIFF tags or a CRW's CIFF record (:attr:`RawImage.make`). LibRaw reports 0 or
1970-01-01 for what a file does not record; those are left out. It also turns
the APEX shutter and aperture values 0 that some writers leave in place of
unknown ones (Magic Lantern's DNGs) into 1 s at f/1: that exact pair is taken
as unknown too, rather than copied as a wrong exposure.

The orientation tag says how to turn the stored pixels for display: 1 (as
stored) when :func:`~imgform_rs.develop` has already turned them, else the
raw's own orientation, converted from LibRaw's flip code.

Exposure time, f-number and focal length are RATIONALs, the type CIPA
DC-008 gives them (readers such as exiftool and piexif expect it; Pillow
would write a float as DOUBLE), and the Exif IFD carries the ExifVersion it
makes mandatory.

Text (make, model, artist, lens) is written as its UTF-8 bytes in the ASCII
tags, as cameras and exiftool write what ASCII cannot hold, and text in an
EXIF given to the writers passes with its bytes unchanged: Pillow would write
every other character as "?", and tifffile refuses it. Pillow also loads tags
without their types and writes each by its own table; a given tag of a
one-byte type (BYTE, ASCII, SBYTE, UNDEFINED) keeps the type it came with.

The tags that describe the written image rather than the shot are added by
:func:`for_image` as the file is written: its size (PixelXDimension,
PixelYDimension), whether its colours are sRGB (ColorSpace 1) or anything else
(0xFFFF, "uncalibrated": Exif has no other value for Display P3 or Adobe RGB,
whose ICC profile then says what they are), FlashpixVersion and, for JPEG, how
its components are stored (ComponentsConfiguration Y, Cb, Cr), which Exif 2.32
makes mandatory for compressed images. An ISO above 65535, which the SHORT
PhotographicSensitivity tag cannot hold, is written as 65535 there and in full
as the RecommendedExposureIndex (a LONG), with SensitivityType 2 saying so, as
cameras record their highest ISO settings.
"""

from __future__ import annotations

import datetime as dt
import struct
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

# LibRaw flip code (bit 0 flips columns, bit 1 rows, bit 2 transposes, in
# that order) -> the EXIF orientation that displays the stored pixels as
# LibRaw orients them.
_EXIF_ORIENTATION = {0: 1, 1: 2, 2: 4, 3: 3, 4: 5, 5: 8, 6: 6, 7: 7}

# EXIF tags, IFD0 and the Exif sub-IFD (CIPA DC-008).
_MAKE, _MODEL, _ORIENTATION, _SOFTWARE, _DATETIME, _ARTIST = 271, 272, 274, 305, 306, 315
_EXIF_IFD = 0x8769
_EXPOSURE_TIME, _F_NUMBER, _ISO, _DATETIME_ORIGINAL = 33434, 33437, 34855, 36867
_FOCAL_LENGTH, _LENS_MAKE, _LENS_MODEL = 37386, 42035, 42036
# ExifVersion: the tags written here are those of Exif 2.32 (CIPA DC-008-2019).
_EXIF_VERSION, _VERSION = 36864, b"0232"
_SENSITIVITY_TYPE, _RECOMMENDED_EXPOSURE_INDEX = 34864, 34866
# What PhotographicSensitivity (a SHORT) holds at most, and the
# SensitivityType saying the full value is the RecommendedExposureIndex.
_ISO_SHORT_MAX, _REI_ONLY = 65535, 2
# The written image's tags: its components' order (Y, Cb, Cr; mandatory for
# compressed files), Flashpix version 1.0, colour space, size.
_COMPONENTS, _YCBCR = 37121, b"\x01\x02\x03\x00"
# The TIFF type of opaque bytes.
_UNDEFINED = 7
_ASCII = 2
#: TIFF types whose values are one-byte units: BYTE, ASCII, SBYTE, UNDEFINED.
_ONE_BYTE = {1, 2, 6, 7}
_FLASHPIX_VERSION, _FLASHPIX_1_0 = 40960, b"0100"
_COLOR_SPACE, _SRGB, _UNCALIBRATED = 40961, 1, 0xFFFF
_PIXEL_X, _PIXEL_Y = 40962, 40963

_NO_DATE = dt.datetime(1970, 1, 1)


@dataclass(frozen=True)
class ShotInfo:
    """How a raw was taken, as LibRaw read it; 0, "" or None where unknown.

    Attributes
    ----------
    make, model : str
        The camera.
    lens_make, lens : str
        The lens, when the file names it.
    iso : float
    exposure_time : float
        Seconds.
    f_number : float
    focal_length : float
        Millimetres.
    taken : datetime or None
        Capture time as the camera's clock recorded it (no time zone).
    artist : str
    """

    make: str = ""
    model: str = ""
    lens_make: str = ""
    lens: str = ""
    iso: float = 0.0
    exposure_time: float = 0.0
    f_number: float = 0.0
    focal_length: float = 0.0
    taken: dt.datetime | None = None
    artist: str = ""


def _text(value: Any) -> str:
    return value.strip() if isinstance(value, str) else ""


def _positive(value: Any) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        return 0.0
    return number if 0 < number < float("inf") else 0.0


def shot_info(raw: Any, make: str, model: str) -> ShotInfo:
    """A :class:`ShotInfo` from an open ``rawpy.RawPy``; never raises (a
    value rawpy cannot give is left unknown)."""
    other, lens = getattr(raw, "other", None), getattr(raw, "lens", None)
    taken = getattr(other, "timestamp", None)
    shutter, aperture = (_positive(getattr(other, k, 0)) for k in ("shutter_speed", "aperture"))
    if (shutter, aperture) == (1.0, 1.0):
        shutter = aperture = 0.0
    return ShotInfo(
        make=make,
        model=model,
        lens_make=_text(getattr(lens, "make", "")),
        lens=_text(getattr(lens, "model", "")),
        iso=_positive(getattr(other, "iso_speed", 0)),
        exposure_time=shutter,
        f_number=aperture,
        focal_length=_positive(getattr(other, "focal_length", 0)),
        taken=taken if isinstance(taken, dt.datetime) and taken > _NO_DATE else None,
        artist=_text(getattr(other, "artist", "")),
    )


def _simplest(value: float) -> Fraction:
    """The fraction of least denominator (up to 10^6) that rounds to the same
    float32 as ``value``: LibRaw reports float32s, and 1/125 s or f/5.6 is
    what a camera wrote, not the binary fraction 0.008 rounds to."""
    single = np.float32(value)
    for limit in (10**k for k in range(7)):
        fraction = Fraction(float(value)).limit_denominator(limit)
        if np.float32(fraction.numerator / fraction.denominator) == single:
            return fraction
    return Fraction(float(value)).limit_denominator(10**6)


def exif_bytes(info: ShotInfo, flip: int, oriented: bool) -> bytes:
    """EXIF for a picture developed from a raw: ``info`` and its orientation
    (``flip`` is LibRaw's code; ``oriented``: the pixels are already turned).
    The bytes start with ``Exif\\0\\0``, as Pillow's JPEG and PNG writers take
    them."""
    from PIL import Image
    from PIL.TiffImagePlugin import IFDRational

    exif = Image.Exif()
    exif[_ORIENTATION] = 1 if oriented else _EXIF_ORIENTATION.get(flip & 7, 1)
    exif[_SOFTWARE] = "imgform-rs"
    for tag, text in ((_MAKE, info.make), (_MODEL, info.model), (_ARTIST, info.artist)):
        if text:
            _put_text(exif, None, tag, text.encode())
    sub = exif.get_ifd(_EXIF_IFD)
    texts = {}
    sub[_EXIF_VERSION] = _VERSION
    if info.taken is not None:
        stamp = info.taken.strftime("%Y:%m:%d %H:%M:%S")
        exif[_DATETIME] = sub[_DATETIME_ORIGINAL] = stamp
    numbers = (
        (_EXPOSURE_TIME, info.exposure_time),
        (_F_NUMBER, info.f_number),
        (_FOCAL_LENGTH, info.focal_length),
    )
    for tag, value in numbers:
        if value:
            fraction = _simplest(value)
            sub[tag] = IFDRational(fraction.numerator, fraction.denominator)
    if info.iso:
        iso = round(info.iso)
        sub[_ISO] = min(iso, _ISO_SHORT_MAX)
        if iso > _ISO_SHORT_MAX:
            sub[_SENSITIVITY_TYPE] = _REI_ONLY
            sub[_RECOMMENDED_EXPOSURE_INDEX] = iso
    for tag, text in ((_LENS_MAKE, info.lens_make), (_LENS_MODEL, info.lens)):
        if text:
            _put_text(sub, _EXIF_IFD, tag, text.encode())
            texts[tag] = _ASCII
    return _retype(exif.tobytes(), _EXIF_IFD, texts)


def for_image(exif: bytes, width: int, height: int, *, jpeg: bool, srgb: bool) -> bytes:
    """``exif`` (led by ``Exif\\0\\0``) with the tags of the image it goes
    into, ``width`` x ``height`` pixels: size, colour space (``srgb``: sRGB
    primaries and curve), Flashpix version and, for a ``jpeg``, the YCbCr
    components; the Exif IFD is made if ``exif`` has none. Other tags are
    kept as they are."""
    from PIL import Image

    tags = Image.Exif()
    tags.load(exif)
    sub = tags.get_ifd(_EXIF_IFD)
    # Pillow loads the values without their types and writes each by its
    # own table: the one-byte types it writes otherwise are put back.
    given = {group: _types(exif, group) for group in (None, _EXIF_IFD)}
    for ifd, group in ((tags, None), (sub, _EXIF_IFD)):
        for tag, value in list(ifd.items()):
            if isinstance(value, str):
                _put_text(ifd, group, tag, text_bytes(value))
    sub.setdefault(_EXIF_VERSION, _VERSION)
    sub[_FLASHPIX_VERSION] = _FLASHPIX_1_0
    sub[_COLOR_SPACE] = _SRGB if srgb else _UNCALIBRATED
    sub[_PIXEL_X], sub[_PIXEL_Y] = width, height
    if jpeg:
        sub[_COMPONENTS] = _YCBCR
    else:
        sub.pop(_COMPONENTS, None)
    if jpeg:
        given[_EXIF_IFD][_COMPONENTS] = _UNDEFINED
    written = _retype(tags.tobytes(), None, given[None])
    return _retype(written, _EXIF_IFD, given[_EXIF_IFD])


def text_bytes(value: str) -> bytes:
    """The bytes of a text tag as Pillow loaded it: Pillow decodes every
    ASCII tag as Latin-1, so this gives back what the file holds, the UTF-8
    that cameras and exiftool write beyond ASCII included."""
    return value.encode("latin-1")


def _put_text(ifd: Any, group: int | None, tag: int, raw: bytes) -> None:
    """Sets the text ``tag`` of ``ifd`` (of the sub-IFD ``group``) to the
    bytes ``raw`` as they are: Pillow writes a ``str`` as ASCII with every
    other character made "?". A tag Pillow knows as ASCII takes the bytes and
    Pillow ends them with NUL; Pillow would write any other tag's bytes as
    BYTE, so it gets its NUL here, and :func:`_retype` makes it ASCII."""
    from PIL import TiffTags

    known = TiffTags.lookup(tag, group).type == _ASCII
    ifd[tag] = raw if known else raw + b"\0"


def _types(exif: bytes, group: int | None) -> dict[int, int]:
    """The TIFF type of each tag of ``exif``'s IFD0 (``group`` None) or of
    its sub-IFD ``group`` (none if it has none, or cannot be read)."""
    tiff = exif.removeprefix(b"Exif\0\0")
    try:
        order = "<" if tiff[:2] == b"II" else ">"
        found = _ifd(tiff, order, group)
        if found is None:
            return {}
        return {
            struct.unpack_from(order + "H", tiff, entry)[0]: struct.unpack_from(
                order + "H", tiff, entry + 2
            )[0]
            for entry in _entries(tiff, order, found)
        }
    except struct.error:
        return {}


def _retype(exif: bytes, group: int | None, types: dict[int, int]) -> bytes:
    """``exif`` with the tags of its IFD0 (``group`` None) or sub-IFD
    ``group`` typed as ``types`` says, where both the type written and the
    type wanted have one-byte units (BYTE, ASCII, SBYTE, UNDEFINED), so the
    entry keeps its layout: text as ASCII, ComponentsConfiguration as CIPA
    DC-008 types it (UNDEFINED, which Pillow, knowing no type for it,
    writes as BYTE), and a caller's tags as they came."""
    tiff = bytearray(exif.removeprefix(b"Exif\0\0"))
    order = "<" if tiff[:2] == b"II" else ">"
    found = _ifd(tiff, order, group)
    for entry in _entries(tiff, order, found) if found is not None else ():
        tag, kind = struct.unpack_from(order + "HH", tiff, entry)
        wanted = types.get(tag, kind)
        if kind in _ONE_BYTE and wanted in _ONE_BYTE:
            struct.pack_into(order + "H", tiff, entry + 2, wanted)
    return b"Exif\0\0" + bytes(tiff)


def _ifd(tiff: bytes, order: str, group: int | None) -> int | None:
    """The offset of IFD0 (``group`` None) or of the sub-IFD ``group``."""
    (ifd0,) = struct.unpack_from(order + "I", tiff, 4)
    if group is None:
        return ifd0
    return next(
        (
            struct.unpack_from(order + "I", tiff, entry + 8)[0]
            for entry in _entries(tiff, order, ifd0)
            if struct.unpack_from(order + "H", tiff, entry)[0] == group
        ),
        None,
    )


def _entries(tiff: bytes, order: str, offset: int) -> range:
    """The offsets of the 12-byte entries of the IFD at ``offset``."""
    (count,) = struct.unpack_from(order + "H", tiff, offset)
    return range(offset + 2, offset + 2 + 12 * count, 12)

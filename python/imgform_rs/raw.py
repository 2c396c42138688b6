"""Reading raw files: LibRaw (through rawpy) decodes, everything after is ours.

:func:`load_raw` opens a DNG, CR2, NEF, ... and returns a :class:`RawImage`: the
visible colour filter array data exactly as the sensor delivered it, plus the
metadata a developer needs (black and white levels, white balance, colour
matrices, orientation). Nothing is processed yet; :func:`imgform_rs.develop`
does that.

LibRaw describes a Bayer sensor with four colours ``R, G, B, G2``; per-channel
values (black levels, white balance) are given in that order, and
:attr:`RawImage.channel_tile` indexes into them. ``pattern`` is the same tile
with both greens as G, in our usual form (see ``docs/conventions.rst``).

Broken files never come back as garbage: a stub header, a truncated or
stripped file, a format LibRaw cannot decode, or a file whose "pixels" are not
really there (LibRaw returns zeros, or the leftovers of the file it decoded
before, for a DNG whose image data was removed) raise :class:`RawError` naming
the file.
"""

from __future__ import annotations

import hashlib
import io
import os
import threading
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ._arrays import integer, real
from ._ciff import make_model
from ._exif import ShotInfo, shot_info
from ._files import read_regular
from ._native import RawError
from ._tiff import Value, first_tag, tiff_ifds
from .cfa import pattern_cells, pattern_from_rawpy

# Linear sRGB (D65) to XYZ, IEC 61966-2-1.
SRGB_TO_XYZ = np.array(
    [
        [0.4124564, 0.3575761, 0.1804375],
        [0.2126729, 0.7151522, 0.0721750],
        [0.0193339, 0.1191920, 0.9503041],
    ]
)

# TIFF tags LibRaw develops with that rawpy does not expose.
_MAKE, _MODEL = 271, 272
_SUBFILE_TYPE, _PHOTOMETRIC, _CFA_PHOTOMETRIC = 254, 262, 32803
_DNG_VERSION = 50706
_BLACK_REPEAT_DIM, _BLACK_LEVEL = 50713, 50714
_KODAK_RGB_CAM = 37400
# LibRaw takes a file's cmatrix only when its first entry exceeds this.
_CMATRIX_MIN = 0.125
# LibRaw's cblack array holds at most this many pattern entries.
_MAX_BLACK_CELLS = 4095

# A raw format stores at least one bit per four photosites even for a flat
# frame under lossless JPEG; a file smaller than that cannot hold its image,
# whatever LibRaw reports (the exiftool-stripped DNG claims 8 Mpx in 13 kB).
_MIN_BITS_PER_PIXEL = 0.25

# Visible-data digests of the files decoded so far in this process, mapped to
# a digest of each file's bytes: LibRaw can hand a data-less file the buffer
# of the previous one, and only a second file with identical pixels but other
# bytes can reveal it. Bounded so a long batch does not grow it without limit.
_SEEN_DATA: dict[bytes, bytes] = {}
_SEEN_LIMIT = 4096
# `imgform develop -j N` loads files from several threads.
_SEEN_LOCK = threading.Lock()
# Every this many rows go into a pixel digest: stale data are whole buffers,
# so a subsample identifies them as well as every row would.
_DIGEST_ROW_STEP = 16


@dataclass(frozen=True, eq=False)
class RawImage:
    """A decoded raw file: sensor data and the metadata to develop it.

    Attributes
    ----------
    cfa : ndarray, uint16, shape (H, W)
        The visible sensor area (LibRaw's ``raw_image_visible``), untouched.
    pattern : str or ndarray of uint8, shape (6, 6)
        Bayer name or X-Trans tile of ``cfa[0, 0]``.
    channel_tile : ndarray of uint8, shape (2, 2) or (6, 6)
        LibRaw's colour index per tile cell (0 = R, 1 = G, 2 = B, 3 = G2),
        the index into the per-channel values below.
    black_levels : ndarray, float64, shape (4,)
        Black level per channel R, G, B, G2, in digital numbers (rawpy's
        ``black_level_per_channel``: LibRaw folds a DNG ``BlackLevel`` pattern
        of the CFA tile's size into these, and adds the minimum of a larger
        pattern and the mean of ``BlackLevelDeltaH`` / ``BlackLevelDeltaV``).
    black_map : ndarray, float64, shape (r, c)
        The rest of a black-level pattern that repeats with a period other
        than the CFA tile's, from ``cfa[0, 0]``: added to ``black_levels``
        pixel by pixel, as LibRaw subtracts its ``cblack[6:]`` pattern. rawpy
        does not expose that pattern, so it is read from the file's DNG
        ``BlackLevelRepeatDim`` / ``BlackLevel`` tags; shape (1, 1) holding 0
        for every other file (non-DNG formats with such a pattern, such as
        some Fujifilm RAFs, and an open ``RawPy`` given to :func:`load_raw`
        cannot supply it).
    white_level : int
        Saturation level in digital numbers.
    camera_white_balance, daylight_white_balance : ndarray, float64, shape (4,)
        Multipliers R, G, B, G2 (as-shot and the camera's daylight). A missing
        G2 is G; an all-zero as-shot balance means the file has none.
    camera_to_srgb : ndarray, float64, shape (3, 3)
        LibRaw's ``rgb_cam``: white-balanced camera RGB to linear sRGB (D65).
    camera_to_xyz : ndarray, float64, shape (3, 3)
        White-balanced camera RGB to CIE XYZ (D65): ``SRGB_TO_XYZ @ camera_to_srgb``.
    flip : int
        LibRaw's orientation code: bit 2 transposes, bit 1 flips rows, bit 0
        flips columns (0 = as stored, 3 = 180 degrees, 5 / 6 = 90 degrees).
    pixel_aspect : float
        Width / height of one photosite; LibRaw stretches the output when it is not 1.
    make, model : str
        TIFF ``Make`` / ``Model`` of the file, or for a Canon CRW its CIFF
        record of both (rawpy does not expose LibRaw's names); empty for
        formats that are neither (QTK, ...) and for an open ``RawPy``.
    output_size : (int, int)
        ``(H, W)`` of the image LibRaw's ``postprocess`` would return (after
        orientation and aspect correction).
    source : str
        The file name, or a description of a buffer, used in error messages.
    shot : ShotInfo
        Camera, lens, exposure and date as LibRaw read them, what
        :func:`~imgform_rs.write_image` copies into EXIF.
    """

    cfa: npt.NDArray[np.uint16]
    pattern: str | npt.NDArray[np.uint8]
    channel_tile: npt.NDArray[np.uint8]
    black_levels: npt.NDArray[np.float64]
    black_map: npt.NDArray[np.float64]
    white_level: int
    camera_white_balance: npt.NDArray[np.float64]
    daylight_white_balance: npt.NDArray[np.float64]
    camera_to_srgb: npt.NDArray[np.float64]
    camera_to_xyz: npt.NDArray[np.float64]
    flip: int
    pixel_aspect: float
    make: str
    model: str
    output_size: tuple[int, int]
    source: str
    shot: ShotInfo = field(default_factory=ShotInfo)


#: The photosite aspects :func:`~imgform_rs.develop` stretches (LibRaw's
#: cameras have 1, 2 and 0.5): far beyond, the stretched picture would not
#: fit in memory.
PIXEL_ASPECTS = (1 / 16, 16.0)


def check_raw_image(raw: RawImage) -> None:
    """TypeError / ValueError naming the field of a hand-made (or edited)
    :class:`RawImage` that :func:`~imgform_rs.develop` cannot use, before
    it fails deeper with an error that names nothing."""

    def array(name: str, shape: tuple[int | None, ...], dtype: str = "iuf") -> np.ndarray:
        value = getattr(raw, name)
        arr = np.asarray(value)
        if not isinstance(value, np.ndarray) or arr.dtype.kind not in dtype:
            raise TypeError(f"RawImage.{name} must be a NumPy array of numbers, got {value!r}")
        sides = zip(shape, arr.shape, strict=False)  # lengths compared first
        fits = arr.ndim == len(shape) and all(n in (None, m) for n, m in sides)
        # Integers are finite: no pass over a whole mosaic for them.
        finite = arr.dtype.kind in "iu" or np.isfinite(arr).all()
        if not fits or arr.size == 0 or not finite:
            want = "(" + ", ".join("n" if n is None else str(n) for n in shape) + ")"
            raise ValueError(
                f"RawImage.{name} must be finite numbers of shape {want}, got {arr.shape}"
            )
        return arr

    cfa = array("cfa", (None, None), "u")
    if cfa.dtype != np.uint16:
        raise TypeError(f"RawImage.cfa must be uint16, got {cfa.dtype}")
    tile = array("channel_tile", (None, None), "u")
    if tile.max() > 3:
        raise ValueError(f"RawImage.channel_tile holds channels 0..3, got {tile.max()}")
    _check_tile(tile, raw.pattern)
    black = array("black_levels", (4,))
    array("black_map", (None, None))
    for name in ("camera_white_balance", "daylight_white_balance"):
        array(name, (4,))
    for name in ("camera_to_srgb", "camera_to_xyz"):
        array(name, (3, 3))
    white = integer(raw.white_level, "RawImage.white_level")
    if not black.min() >= 0 or black.max() >= white:
        raise ValueError(
            f"RawImage.black_levels must lie in 0..white_level ({white}), got {black.tolist()}"
        )
    if integer(raw.flip, "RawImage.flip") not in range(8):
        raise ValueError(f"RawImage.flip is LibRaw's orientation code 0..7, got {raw.flip!r}")
    lo, hi = PIXEL_ASPECTS
    if not lo <= real(raw.pixel_aspect, "RawImage.pixel_aspect") <= hi:
        raise ValueError(
            f"RawImage.pixel_aspect must be in {lo:g}..{hi:g}, got {raw.pixel_aspect!r}"
        )


def _check_tile(tile: np.ndarray, pattern: Any) -> None:
    """The white balance and black levels go by ``channel_tile``, the
    demosaicing by ``pattern``: a crop that shifts only one of them would
    develop in false colour."""
    try:
        cells = pattern_cells(pattern)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"RawImage.pattern: {exc}") from exc
    if tile.shape != cells.shape or not np.array_equal(np.where(tile == 3, 1, tile), cells):
        raise ValueError(
            f"RawImage.channel_tile {tile.tolist()} (3: the second green) is not the tile "
            f"of RawImage.pattern {pattern!r}: a crop by (dy, dx) shifts both, the pattern "
            "with cfa.shift_pattern and the tile with np.roll(tile, (-dy, -dx), (0, 1))"
        )


def _describe(source: Any) -> str:
    if isinstance(source, (str, os.PathLike)):
        return os.fspath(source)
    if isinstance(source, (bytes, bytearray, memoryview)):
        return f"<{len(source)} bytes>"
    name = getattr(source, "name", None)
    return str(name) if isinstance(name, str) else f"<{type(source).__name__}>"


def _read_bytes(source: Any, name: str) -> bytes:
    if isinstance(source, (str, os.PathLike)):
        try:
            return read_regular(source)
        except OSError as exc:
            raise RawError(f"{name}: cannot read the file ({exc.strerror or exc})") from exc
    if isinstance(source, (bytes, bytearray, memoryview)):
        return bytes(source)
    if isinstance(source, io.TextIOBase):
        raise TypeError(
            f"a file object given to load_raw must be opened in binary mode, got {name}"
        )
    if hasattr(source, "read"):
        data = source.read()
        if not isinstance(data, (bytes, bytearray)):
            raise TypeError(
                f"a file object given to load_raw must be opened in binary mode, got {name}"
            )
        return bytes(data)
    raise TypeError(
        "source must be a path, bytes, a binary file object or an open rawpy.RawPy, "
        f"got {type(source).__name__}"
    )


def _wb(values: Any) -> npt.NDArray[np.float64]:
    wb = np.asarray(values, np.float64)[:4].copy()
    if wb[3] == 0:
        wb[3] = wb[1]
    return wb


def _camera_to_srgb(raw: Any, ifds: list[dict[int, Value]] | None) -> npt.NDArray[np.float64]:
    """LibRaw's ``rgb_cam``, which rawpy does not expose, rebuilt from its
    sources in LibRaw's order of precedence (``identify()`` with the options
    in force when rawpy opens a file):

    1. a DNG's own matrix (``color_matrix``, LibRaw's ``cmatrix``); for other
       formats LibRaw ignores ``cmatrix`` unless ``use_camera_wb`` is set
       when the file is opened, which rawpy never does;
    2. a matrix the file stores as camera RGB to sRGB: the old Kodak tag
       37400 (Kodak DC50, DC120, ...), read from the file's bytes;
    3. the XYZ-to-camera matrix (``rgb_xyz_matrix``, from LibRaw's tables)
       turned around as LibRaw's ``cam_xyz_coeff`` does;
    4. else the identity (a camera LibRaw has no colour data for).

    ``ifds`` are the file's TIFF IFDs, None without the file's bytes (an
    open ``RawPy`` was given): then step 2 is skipped and ``color_matrix`` is
    trusted for every format.
    """
    cmatrix = np.asarray(raw.color_matrix, np.float64)[:, :3]
    if ifds is None:
        ifds, is_dng = [], True
    else:
        is_dng = first_tag(ifds, _DNG_VERSION) is not None
    if cmatrix[0, 0] > _CMATRIX_MIN and is_dng:
        return cmatrix.copy()
    kodak = first_tag(ifds, _KODAK_RGB_CAM)
    if isinstance(kodak, tuple) and len(kodak) == 12:
        # Four numbers a row; LibRaw skips the first of each.
        return np.array(kodak, np.float64).reshape(3, 4)[:, 1:]
    cam_xyz = np.asarray(raw.rgb_xyz_matrix, np.float64)[:3]
    if not np.any(cam_xyz):
        return np.eye(3)
    cam_rgb = cam_xyz @ SRGB_TO_XYZ
    # Rows normalised so camera (1, 1, 1) is sRGB white: the white balance
    # has already made a neutral equal in every channel.
    sums = cam_rgb.sum(axis=1, keepdims=True)
    cam_rgb = np.where(sums > 1e-5, cam_rgb / np.where(sums > 1e-5, sums, 1), 0)
    try:
        return np.linalg.inv(cam_rgb)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(cam_rgb)


def _black_map(
    ifds: list[dict[int, Value]], black: npt.NDArray[np.float64], tile: tuple[int, ...]
) -> npt.NDArray[np.float64]:
    """The black-level pattern LibRaw keeps apart from the per-channel levels
    (see :attr:`RawImage.black_map`), from the DNG raw IFD's tags, as LibRaw
    parses them: a ``BlackLevelRepeatDim`` pattern of more than 4095 cells
    falls back to one value, and the values are truncated to integers."""
    none = np.zeros((1, 1))
    if first_tag(ifds, _DNG_VERSION) is None:
        return none
    cfa_ifd = next(
        (
            ifd
            for ifd in ifds
            if ifd.get(_PHOTOMETRIC) == (_CFA_PHOTOMETRIC,)
            and ifd.get(_SUBFILE_TYPE, (0.0,)) == (0.0,)
        ),
        {},
    )
    dims, levels = cfa_ifd.get(_BLACK_REPEAT_DIM, (1.0, 1.0)), cfa_ifd.get(_BLACK_LEVEL)
    if not isinstance(levels, tuple) or not isinstance(dims, tuple) or len(dims) != 2:
        return none
    rows, cols = (int(d) for d in dims) if dims[0] * dims[1] <= _MAX_BLACK_CELLS else (1, 1)
    # LibRaw folds a pattern that fits the CFA tile into the per-channel levels.
    folded = rows * cols == 1 or (tile == (2, 2) and rows <= 2 and cols <= 2)
    if folded or rows < 1 or cols < 1 or len(levels) < rows * cols:
        return none
    pattern = np.trunc(np.array(levels[: rows * cols])).reshape(rows, cols)
    # LibRaw moves the pattern's minimum into every channel's level; levels
    # that differ mean it read another pattern than this one: add nothing.
    if np.ptp(black) != 0 or black[0] < pattern.min():
        return none
    return pattern - pattern.min()


def _output_size(sizes: Any) -> tuple[int, int]:
    h, w = int(sizes.height), int(sizes.width)
    aspect = float(sizes.pixel_aspect)
    # LibRaw's stretch(): the short axis grows to square pixels.
    if aspect < 1:
        h = int(h / aspect + 0.5)
    elif aspect > 1:
        w = int(w * aspect + 0.5)
    return (w, h) if int(sizes.flip) & 4 else (h, w)


def _from_rawpy(raw: Any, name: str, data: bytes | None) -> RawImage:
    rawpy = _rawpy()
    try:
        if raw.raw_type != rawpy.RawType.Flat or raw.raw_pattern is None:
            raise RawError(
                f"{name}: no colour filter array to demosaic (LibRaw raw type "
                f"{raw.raw_type.name}: a linear / already demosaiced DNG or a scanner file)"
            )
        try:
            pattern = pattern_from_rawpy(raw)
        except ValueError as exc:
            raise RawError(f"{name}: unsupported sensor layout: {exc}") from exc
        cfa = np.array(raw.raw_image_visible, dtype=np.uint16, copy=True)
        sizes = raw.sizes
        black = np.asarray(raw.black_level_per_channel, np.float64)
        tile = np.asarray(raw.raw_pattern, np.uint8)
        complaints: list[str] = []
        ifds = None if data is None else tiff_ifds(data, complaints)
        _check_tags(complaints, name, data)
        meta = dict(
            channel_tile=tile,
            black_levels=black,
            black_map=_black_map(ifds or [], black, tile.shape),
            white_level=int(raw.white_level),
            camera_white_balance=_wb(raw.camera_whitebalance),
            daylight_white_balance=_wb(raw.daylight_whitebalance),
            camera_to_srgb=_camera_to_srgb(raw, ifds),
            flip=int(sizes.flip),
            pixel_aspect=float(sizes.pixel_aspect),
        )
        pixels = int(sizes.raw_height) * int(sizes.raw_width)
        make, model = (first_tag(ifds or [], tag) for tag in (_MAKE, _MODEL))
        make, model = (v if isinstance(v, str) else "" for v in (make, model))
        if not (make or model) and data is not None:
            make, model = make_model(data)
        if ifds and first_tag(ifds, _DNG_VERSION) is None and not (make or model):
            # LibRaw reads such a file's pixels as a Bayer mosaic all the same.
            raise RawError(
                f"{name}: a TIFF image with neither DNG tags nor a camera make or "
                "model: not a camera raw"
            )
        shot = shot_info(raw, make, model)
    except RawError:
        raise
    except Exception as exc:  # LibRawError, or a bad attribute LibRaw could not fill
        raise RawError(f"{name}: LibRaw cannot decode it ({_reason(exc)})") from exc
    _check_pixels(cfa, meta["white_level"], name, data, pixels)
    return RawImage(
        cfa=cfa,
        pattern=pattern,
        camera_to_xyz=SRGB_TO_XYZ @ meta["camera_to_srgb"],
        make=make,
        model=model,
        output_size=_output_size(sizes),
        source=name,
        shot=shot,
        **meta,
    )


def _check_tags(complaints: list[str], name: str, data: bytes | None) -> None:
    """Refuse a file whose TIFF tags point past its end: a file cut short
    after its pixels (a DNG whose tags follow them, as ``write_dng``'s do)
    loses its colour matrix and white balance, which LibRaw skips without a
    word, and would develop in false colour."""
    past = [c for c in complaints if "invalid value offset" in c]
    if past and data is not None:
        values = "value lies" if len(past) == 1 else f"{len(past)} values lie"
        raise RawError(
            f"{name}: the file is truncated or corrupt: a TIFF tag's {values} past "
            f"its end ({len(data)} bytes)"
        )


def _reason(exc: BaseException) -> str:
    text = str(exc)
    if text.startswith("b'") or text.startswith('b"'):
        text = text[2:-1]
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _check_pixels(
    cfa: npt.NDArray[np.uint16],
    white: int,
    name: str,
    data: bytes | None,
    pixels: int,
) -> None:
    """Refuse data LibRaw 'decoded' from nothing (see the module docstring)."""
    if cfa.size == 0:
        raise RawError(f"{name}: the file has no visible pixels")
    if white <= 0:
        raise RawError(f"{name}: white level {white} is not positive")
    lo, hi = int(cfa.min()), int(cfa.max())
    if lo == hi and (lo == 0 or not _holds_pixels(data, pixels, white)):
        raise RawError(
            f"{name}: every pixel is {lo}: the file has no real image data "
            "(stripped, zero-filled or unreadable pixel data)"
        )
    if data is None:
        return
    if pixels * _MIN_BITS_PER_PIXEL / 8 > len(data):
        raise RawError(
            f"{name}: the file is too small to hold its {pixels} pixels: "
            "its image data is missing (stripped file)"
        )
    # Cheap identities, so a 24 MP file costs milliseconds: the file by its
    # size and its two ends (where headers and tags live), the pixels by a
    # subsample of rows.
    file_digest = hashlib.blake2b(
        data[:65536] + data[-65536:] + len(data).to_bytes(8, "little"), digest_size=16
    ).digest()
    data_digest = hashlib.blake2b(cfa[::_DIGEST_ROW_STEP].tobytes(), digest_size=16).digest()
    with _SEEN_LOCK:
        previous = _SEEN_DATA.get(data_digest)
        if len(_SEEN_DATA) >= _SEEN_LIMIT:
            _SEEN_DATA.pop(next(iter(_SEEN_DATA)))
        _SEEN_DATA.setdefault(data_digest, file_digest)
    # Only a file too small to store its pixels uncompressed can be hiding
    # missing data this way; identical pixels in two uncompressed files (a
    # copy with edited metadata) are genuine.
    if previous is not None and previous != file_digest and len(data) < 2 * pixels:
        raise RawError(
            f"{name}: LibRaw returned the pixels of a file decoded earlier: "
            "this file's image data is missing or unreadable"
        )


def _holds_pixels(data: bytes | None, pixels: int, white: int) -> bool:
    """Whether the file is large enough to store every pixel uncompressed at
    the white level's bit depth. LibRaw hands a stripped file a frame of one
    value, and a download cut short leaves zeros; a file that holds its
    pixels and reads as one value above 0 is a genuine flat frame (a
    noise-free dark frame at the black level, from ``spectral.write_dng``)."""
    return data is not None and len(data) * 8 >= pixels * white.bit_length()


def _rawpy() -> Any:
    import rawpy

    return rawpy


def load_raw(source: Any) -> RawImage:
    """Decode a raw file with LibRaw and return its sensor data and metadata.

    Parameters
    ----------
    source : str, PathLike, bytes, binary file object or rawpy.RawPy
        The file. An open ``rawpy.RawPy`` is read but not closed, and skips
        what needs the file's bytes: the size and repeated-data checks, and
        the tags read beyond rawpy (the Kodak colour matrix, a DNG
        black-level map, whether the file is a DNG).

    Returns
    -------
    RawImage

    Raises
    ------
    RawError
        Naming the file, for a missing, empty, truncated, stripped or
        unsupported file, one without a colour filter array (linear DNG, film
        scanner) or with no real pixel data: all zeros, one value in a file
        too small to store it (a flat frame above 0 that the file stores, such
        as a noise-free dark frame, is read), a file too small
        for its pixel count, or pixels identical to those of a different file
        decoded earlier in this process while the file is too small to store
        them uncompressed (LibRaw's stale buffer; a compressed raw copied with
        edited metadata is refused too: open such a copy with rawpy and pass
        the ``RawPy``, which skips the byte-level checks and keeps only the
        constant-data one).
    TypeError
        For a source of another type.

    Examples
    --------
    >>> import tempfile
    >>> from imgform_rs.dng import write_dng
    >>> cfa = np.arange(32 * 48, dtype=np.uint16).reshape(32, 48)
    >>> with tempfile.TemporaryDirectory() as d:
    ...     write_dng(f"{d}/a.dng", cfa, "GBRG", white_level=4095, black_level=64)
    ...     raw = load_raw(f"{d}/a.dng")
    >>> raw.pattern, raw.white_level, raw.black_levels.tolist(), raw.cfa.shape
    ('GBRG', 4095, [64.0, 64.0, 64.0, 64.0], (32, 48))
    """
    rawpy = _rawpy()
    name = _describe(source)
    if isinstance(source, rawpy.RawPy):
        return _from_rawpy(source, name, None)
    data = _read_bytes(source, name)
    if not data:
        raise RawError(f"{name}: the file is empty")
    try:
        raw = rawpy.imread(io.BytesIO(data))
    except Exception as exc:  # every LibRaw failure, whatever its class
        raise RawError(f"{name}: not a raw file LibRaw can open ({_reason(exc)})") from exc
    with raw:
        return _from_rawpy(raw, name, data)

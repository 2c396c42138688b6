"""Colour filter arrays (lecture section 6): patterns, mosaicing, sensor simulation.

A pattern is either a name — ``"RGGB"``, ``"BGGR"``, ``"GRBG"``, ``"GBRG"`` (the
2x2 Bayer tile read row by row) or ``"XTRANS"`` (Fujifilm's 6x6 tile) — or an
integer array of channel indices (0 = R, 1 = G, 2 = B) of shape (2, 2) or (6, 6).
It describes pixel (0, 0) of the array it goes with; see :func:`shift_pattern`
for crops.
"""

from __future__ import annotations

from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt

from . import _native, _samples
from ._arrays import as_seed, is_int, real, require_finite

Pattern = str | npt.ArrayLike
"""A pattern name or a (2, 2) / (6, 6) array of channel indices."""

SampleT = TypeVar("SampleT", np.uint8, np.uint16, np.float32)
AnySampleT = TypeVar("AnySampleT", bound=np.number[Any])

_CHANNEL_OF_LETTER = {"R": 0, "G": 1, "B": 2}
#: The longest side an array can have.
_MAX_SIDE = int(np.iinfo(np.intp).max)


def as_pattern(pattern: Any) -> str | npt.NDArray[np.int64]:
    """A pattern in the form the native layer takes: a str, or an int64 array.

    Raises
    ------
    TypeError
        For None or a non-integer array.
    """
    if pattern is None:
        raise TypeError(
            'pattern must be a str ("RGGB", "BGGR", "GRBG", "GBRG", "XTRANS") or a (2, 2) / '
            "(6, 6) array of channel indices, got None"
        )
    if isinstance(pattern, str):
        return pattern
    arr = np.asarray(pattern)
    if arr.dtype.kind not in "iu" or arr.ndim == 0:
        got = f"dtype {arr.dtype}" if arr.ndim else f"the scalar {pattern!r}"
        raise TypeError(
            "a CFA pattern must be a name or an array of integer channel indices "
            f"0=R, 1=G, 2=B, got {got}"
        )
    if arr.size and arr.max() > 2:  # before int64, which would wrap 2**63 and above
        raise ValueError(
            f"a CFA pattern array must hold channel indices 0=R, 1=G, 2=B, got {arr.max()}"
        )
    return np.asarray(arr, dtype=np.int64, order="C")


def as_image(value: Any, name: str) -> np.ndarray:
    """``value`` as an array for the native layer, which checks dtype and shape."""
    if value is None:
        raise TypeError(f"{name} must be a uint8, uint16 or float32 array, got None")
    return np.asarray(value)


def pattern_cells(pattern: Pattern) -> npt.NDArray[np.uint8]:
    """The tile of a pattern as channel indices.

    Parameters
    ----------
    pattern : str or array_like
        A pattern name or tile.

    Returns
    -------
    ndarray, uint8, shape (2, 2) or (6, 6)
        0 = R, 1 = G, 2 = B.

    Raises
    ------
    TypeError, ValueError
        For anything that is not a valid Bayer or X-Trans pattern.

    Examples
    --------
    >>> pattern_cells("GRBG").tolist()
    [[1, 0], [2, 1]]
    """
    return _native.pattern_cells(as_pattern(pattern))


def shift_pattern(pattern: Pattern, dy: int, dx: int) -> str | npt.NDArray[np.uint8]:
    """The pattern of ``raw[dy:, dx:]`` given the pattern of ``raw``.

    Cropping an odd number of rows or columns changes a Bayer phase; negative
    shifts (padding) are allowed.

    Parameters
    ----------
    pattern : str or array_like
        The pattern at pixel (0, 0).
    dy, dx : int
        Rows and columns removed at the top and at the left.

    Returns
    -------
    str or ndarray of uint8, shape (6, 6)
        The name when the result has one (every Bayer phase; the canonical
        X-Trans tile), else the tile.

    Raises
    ------
    TypeError
        For a shift that is not an int (a crop has no fraction of a row),
        and as :func:`pattern_cells`.
    ValueError
        As :func:`pattern_cells`.

    Examples
    --------
    >>> shift_pattern("RGGB", 1, 0)
    'GBRG'
    """
    for name, value in (("dy", dy), ("dx", dx)):
        if not is_int(value):
            raise TypeError(f"{name} must be an int (rows or columns cropped), got {value!r}")
    # Every tile is 2x2 or 6x6, so 6 rows or columns change no phase: the
    # remainder also keeps any int within the native isize.
    return _native.shift_pattern(as_pattern(pattern), int(dy) % 6, int(dx) % 6)


def pattern_from_rawpy(raw: Any) -> str | npt.NDArray[np.uint8]:
    """The pattern of ``raw.raw_image_visible`` for a file opened with rawpy.

    LibRaw describes a Bayer sensor with four colours, ``color_desc = b"RGBG"``,
    and ``raw_pattern`` indexes into them; both greens become G here.

    Parameters
    ----------
    raw : rawpy.RawPy
        An opened raw file.

    Returns
    -------
    str or ndarray of uint8, shape (6, 6)
        A Bayer name, or the X-Trans tile as the file lays it out.

    Raises
    ------
    ValueError
        For sensors other than RGB Bayer or X-Trans (CMYG, Foveon, linear DNG).
    """
    tile = getattr(raw, "raw_pattern", None)
    if tile is None:
        raise ValueError("this raw file has no colour filter array (raw_pattern is None)")
    desc = raw.color_desc.decode("ascii") if isinstance(raw.color_desc, bytes) else raw.color_desc
    tile = np.asarray(tile)
    beyond = [int(i) for i in tile.ravel() if not 0 <= i < len(desc)]
    if beyond:
        raise ValueError(
            f"raw_pattern names colour {beyond[0]}, but color_desc {desc!r} has {len(desc)} colours"
        )
    letters = [desc[i] for i in tile.ravel()]
    unknown = sorted(set(letters) - set(_CHANNEL_OF_LETTER))
    if unknown:
        raise ValueError(
            f"only R, G, B filter arrays are supported, got colours {desc!r} with {unknown}"
        )
    cells = np.array([_CHANNEL_OF_LETTER[c] for c in letters], np.int64).reshape(tile.shape)
    return shift_pattern(cells, 0, 0)


def mosaic(rgb: npt.NDArray[AnySampleT], pattern: Pattern) -> npt.NDArray[AnySampleT]:
    """Sample an RGB image through a colour filter array.

    Parameters
    ----------
    rgb : ndarray, shape (H, W, 3), any integer or float dtype
        uint8, uint16 and float32 go through the native kernel; other dtypes
        (float64 from scikit-image's ``img_as_float``, int32, ...) are sampled
        in NumPy, exactly as well.
    pattern : str or array_like

    Returns
    -------
    ndarray, shape (H, W), same dtype
        ``out[y, x] = rgb[y, x, c]`` with ``c`` the channel of pixel (y, x).

    Raises
    ------
    TypeError
        For a bool, complex or object dtype or a bad pattern type.
    ValueError
        For another shape, an empty image or an invalid pattern.

    Examples
    --------
    >>> rgb = np.arange(12, dtype=np.uint8).reshape(2, 2, 3)
    >>> mosaic(rgb, "RGGB").tolist()
    [[0, 4], [7, 11]]
    """
    arr = _samples.as_array(rgb, "rgb")
    if arr.dtype in _samples.NATIVE:
        return _native.mosaic(arr, as_pattern(pattern))
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise ValueError(f"rgb must have shape (H, W, 3), got {list(arr.shape)}")
    if arr.size == 0:
        raise ValueError(f"rgb must not be empty, got shape {list(arr.shape)}")
    h, w = arr.shape[:2]
    cells = pattern_cells(pattern)
    th, tw = cells.shape
    channel = np.tile(cells, (-(-h // th), -(-w // tw)))[:h, :w, None]
    return np.ascontiguousarray(np.take_along_axis(arr, channel.astype(np.intp), axis=2)[..., 0])


def channel_masks(shape: tuple[int, int], pattern: Pattern) -> npt.NDArray[np.bool_]:
    """Where a pattern samples each channel.

    Parameters
    ----------
    shape : (int, int)
        ``(H, W)`` of the mosaic.
    pattern : str or array_like

    Returns
    -------
    ndarray, bool, shape (H, W, 3)
        Exactly one channel is True per pixel, so ``(rgb * masks).sum(-1)``
        equals ``mosaic(rgb, pattern)``.

    Examples
    --------
    >>> channel_masks((2, 2), "BGGR")[..., 2].tolist()
    [[True, False], [False, False]]
    """
    if (
        not isinstance(shape, (tuple, list))
        or len(shape) != 2
        or not all(is_int(v) and 0 < v <= _MAX_SIDE for v in shape)
    ):
        raise ValueError(
            f"shape must be a tuple (H, W) of two ints from 1 to {_MAX_SIDE}, got {shape!r}"
        )
    return _native.channel_masks((int(shape[0]), int(shape[1])), as_pattern(pattern))


def simulate_sensor(
    rgb: npt.NDArray[Any],
    pattern: Pattern,
    *,
    full_well: float = 10_000.0,
    read_noise: float = 3.0,
    bit_depth: int = 12,
    black_level: int = 64,
    seed: int = 0,
) -> npt.NDArray[np.uint16]:
    """Simulate a raw capture of a linear RGB scene.

    The image is mosaiced, each pixel collects a Poisson number of electrons
    with mean ``value / full_scale * full_well`` (full scale: 1.0 for float32,
    255 or 65535 for integers), Gaussian read noise of ``read_noise`` electrons
    is added, and an ADC maps ``full_well`` electrons to the white level
    ``2**bit_depth - 1`` above ``black_level``, rounds and clips.

    Parameters
    ----------
    rgb : ndarray, shape (H, W, 3), uint8, uint16 or float32
        Linear scene radiance as a fraction of full scale (no gamma).
    pattern : str or array_like
    full_well : float
        Electrons at full scale; photon noise relative to signal falls as
        ``1 / sqrt(electrons)``.
    read_noise : float
        Standard deviation in electrons (>= 0).
    bit_depth : int
        1..16.
    black_level : int
        Offset in digital numbers, 0 up to below the white level.
    seed : int
        0 <= seed < 2**64. The noise is a pure function of ``(seed, y, x)``:
        equal seeds give equal raws, whatever the number of threads.

    Returns
    -------
    ndarray, uint16, shape (H, W)

    Raises
    ------
    TypeError, ValueError
        For bad arrays or patterns; TypeError naming a ``full_well`` or
        ``read_noise`` that is not a real number; ValueError naming a bad
        parameter (the ints above must be ints, not floats to truncate), or
        the first NaN or infinite sample of ``rgb``, which has no number of
        electrons.

    Examples
    --------
    >>> raw = simulate_sensor(np.full((4, 4, 3), 0.5, np.float32), "RGGB", read_noise=0)
    >>> raw.dtype, raw.shape
    (dtype('uint16'), (4, 4))
    """
    # Checked here: int() would truncate a float, and an int beyond the
    # native layer's u32 / u64 would be an OverflowError there.
    if not (is_int(bit_depth) and 1 <= bit_depth <= 16):
        raise ValueError(f"bit_depth must be an int from 1 to 16, got {bit_depth!r}")
    white = 2 ** int(bit_depth) - 1
    if not (is_int(black_level) and 0 <= black_level < white):
        raise ValueError(
            f"black_level must be an int from 0 to below the white level {white} of "
            f"{bit_depth} bits, got {black_level!r}"
        )
    as_seed(seed, "seed")
    arr = as_image(rgb, "rgb")
    require_finite(arr, "rgb")
    return _native.simulate_sensor(
        arr,
        as_pattern(pattern),
        real(full_well, "full_well"),
        real(read_noise, "read_noise"),
        int(bit_depth),
        int(black_level),
        int(seed),
    )

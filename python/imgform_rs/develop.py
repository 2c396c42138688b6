"""Raw development: a raw file (or :class:`RawImage`) to an RGB picture.

LibRaw decodes; black subtraction, scaling, white balance, demosaicing, the
colour matrix and the tone curve run in one Rust pipeline (one pass: the
demosaic loads prepared photosites and finishes each tile as it stores it;
nearest and the X-Trans methods demosaic a prepared mosaic instead). The
colour science follows LibRaw's ``dcraw_process``,
so ``develop(path, demosaic="bilinear", tone="linear", bps=16,
orientation="none")`` matches ``rawpy``'s ``postprocess(demosaic_algorithm=LINEAR,
use_camera_wb=True, gamma=(1, 1), no_auto_bright=True, output_bps=16,
user_flip=0)``:

- black: each channel's level (``RawImage.black_levels``) is subtracted,
  plus, pixel by pixel, a DNG black-level pattern longer than the CFA tile
  (``RawImage.black_map``, LibRaw's ``cblack[6:]``);
- white: the data are divided by ``white_level - min(black_levels)``; when the
  brightest value actually present lies between 75 % and 100 % of that range,
  it is taken as white instead (LibRaw's ``adjust_maximum_thr`` default,
  which absorbs white levels that cameras report a little too high);
- white balance: the multipliers are divided by the smallest, so no channel
  is scaled below 1 and all clip together at white (LibRaw ``highlight=0``;
  ``highlights="unclip"`` divides by the largest, LibRaw ``highlight=1``);
  a file without an as-shot balance falls back to grey world, as LibRaw does;
- colour: LibRaw's ``rgb_cam`` (``RawImage.camera_to_srgb``, rebuilt by
  :func:`load_raw` from rawpy's matrices and the file's own tags), then a
  clip to [0, 1] and the tone curve.

Cameras with non-square photosites (``RawImage.pixel_aspect != 1``, e.g. the
Kodak DC120) are stretched to square pixels along the short axis by
repeating lines, as LibRaw's ``stretch()`` does (its code interpolates, but
truncates the weight to zero).

Where LibRaw develops with data rawpy does not expose and the file cannot
supply either, the results differ: a colour matrix LibRaw picks in code
(Canon PowerShot 600, Logitech Fotoman, Nikon E880-E990, Kodak DC20/25), a
black-level pattern of a non-DNG format, the white of LibRaw's decoders
with a fixed maximum (Broadcom, Nokia and Android sensor dumps, 8-bit and
Kodak YCbCr formats: LibRaw skips the white adjustment for them, and rawpy
does not say which decoder read a file), and, for an open ``rawpy.RawPy``
source, whatever :func:`load_raw` reads from the file's bytes (see its
docs and the README's "Colour science").
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from . import _native
from ._exif import exif_bytes
from ._imagefile import check_exr, check_format, check_quality, path_kind, write_image
from .colorspace import COLOR_SPACES, srgb_to
from .demosaic import DEMOSAIC_METHODS
from .raw import RawImage, check_raw_image, load_raw

DEFAULT_DEMOSAIC = "best" if "best" in DEMOSAIC_METHODS else "hamilton_adams"
"""The demosaicer :func:`develop` uses unless told otherwise."""

TONES: tuple[str, ...] = tuple(_native.TONES)
"""Every tone curve :func:`develop` accepts (besides ``"auto"``, the colour
space's own): ``"srgb"``, ``"linear"``, ``"bt709"``, ``"gamma22"`` (Adobe RGB's
563/256 power), ``"romm"`` (ProPhoto's)."""

MAX_EXPOSURE = 32.0
"""The largest exposure change :func:`develop` takes, in stops either way:
2**32 is more than a 16-bit raw's range times a 16-bit output's, so a
larger change can only make every pixel white, or black in 8- and 16-bit
output (and from about 128 stops the gain is beyond float32's range)."""

WHITE_BALANCES = ("camera", "daylight", "auto", "none")
HIGHLIGHTS = ("clip", "unclip")
COLORS: tuple[str, ...] = (*COLOR_SPACES, "camera")
"""Every output colour :func:`develop` accepts (see :mod:`imgform_rs.colorspace`)."""

# LibRaw's default adjust_maximum_thr (see the module docstring).
_ADJUST_MAXIMUM = 0.75
# LibRaw's grey-world blocks: 8x8 photosites; a block with a value within 25
# of white is skipped, as clipped data would bias the balance.
_GREY_BLOCK = 8
_GREY_MARGIN = 25

_BPS = {8: "8", 16: "16", "float": "float"}


def _grey_world(raw: RawImage) -> npt.NDArray[np.float64]:
    """LibRaw's automatic white balance: channel means over the blocks whose
    black-subtracted values all stay 25 below white (white after LibRaw's
    maximum adjustment, :func:`_white_range`); the blocks at the right and
    bottom edges may be partial, as in LibRaw. LibRaw subtracts only the
    per-channel black levels at that point, not the black-level map."""
    return _grey_multipliers(_grey_sums(raw.cfa, raw, 0, 0, _white_range(raw)))


def _grey_sums(
    block: npt.NDArray[Any], raw: RawImage, y0: int, x0: int, white: float
) -> npt.NDArray[np.float64]:
    """Per channel (R, G, B, G2): the photosites and the black-subtracted
    signal in the unclipped 8x8 blocks of ``block``, the part of ``raw.cfa``
    at ``(y0, x0)`` (a multiple of 8), so that chunked callers can add them up."""
    h, w = block.shape
    b = _GREY_BLOCK
    th, tw = raw.channel_tile.shape
    chan = raw.channel_tile[((y0 + np.arange(h)) % th)[:, None], ((x0 + np.arange(w)) % tw)]
    signal = np.maximum(block - raw.black_levels[chan], 0)
    block_max = np.maximum.reduceat(
        np.maximum.reduceat(signal, np.arange(0, h, b), axis=0), np.arange(0, w, b), axis=1
    )
    ok = block_max <= white - _GREY_MARGIN
    keep = np.repeat(np.repeat(ok, b, axis=0), b, axis=1)[:h, :w]
    sums = [(np.sum(keep & (chan == c)), signal[keep & (chan == c)].sum()) for c in range(4)]
    return np.array(sums, np.float64)


def _grey_multipliers(sums: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Count over signal per channel, 1 for a channel with no signal."""
    count, total = sums.T
    return np.where(total > 0, count / np.where(total > 0, total, 1), 1.0)


def check_bps(bps: Any) -> None:
    """ValueError unless ``bps`` is one :func:`develop` takes."""
    if isinstance(bps, bool) or bps not in _BPS:
        raise ValueError(f'bps must be 8, 16 or "float", got {bps!r}')


def _multipliers(raw: RawImage, white_balance: Any) -> npt.NDArray[np.float64]:
    """White-balance multipliers R, G, B, G2 before normalisation."""
    if isinstance(white_balance, str):
        if white_balance == "camera":
            if raw.camera_white_balance[0] > 1e-5:
                return raw.camera_white_balance
            return _grey_world(raw)
        if white_balance == "daylight":
            return raw.daylight_white_balance
        if white_balance == "auto":
            return _grey_world(raw)
        if white_balance == "none":
            return np.ones(4)
        raise ValueError(
            f"white_balance must be one of {WHITE_BALANCES} or (r, g, b), got {white_balance!r}"
        )
    rgb = np.asarray(white_balance, np.float64)
    if rgb.shape != (3,) or not np.all(np.isfinite(rgb)) or np.any(rgb <= 0):
        raise ValueError(
            "white_balance multipliers must be three finite numbers > 0 (r, g, b), "
            f"got {white_balance!r}"
        )
    return np.array([rgb[0], rgb[1], rgb[2], rgb[1]])


def _tiles(
    raw: RawImage, scale4: npt.NDArray[np.float64]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Black level and scale per cell of one tile that repeats both the CFA
    tile and the black-level map (their least common multiple)."""
    (th, tw), (mh, mw) = raw.channel_tile.shape, raw.black_map.shape
    rows, cols = math.lcm(th, mh), math.lcm(tw, mw)
    chan = np.tile(raw.channel_tile, (rows // th, cols // tw))
    black = raw.black_levels[chan] + np.tile(raw.black_map, (rows // mh, cols // mw))
    return np.ascontiguousarray(black), np.ascontiguousarray(scale4[chan])


def _white_range(raw: RawImage) -> float:
    """Digital numbers from black to white after black subtraction."""
    span = float(raw.white_level - raw.black_levels.min())
    th, tw = raw.channel_tile.shape
    data_max = max(
        float(raw.cfa[i::th, j::tw].max()) - raw.black_levels[raw.channel_tile[i, j]]
        for i in range(min(th, raw.cfa.shape[0]))
        for j in range(min(tw, raw.cfa.shape[1]))
    )
    if 0 < data_max < span and data_max > span * _ADJUST_MAXIMUM:
        return data_max
    return span


def _stretch(img: np.ndarray, aspect: float) -> np.ndarray:
    """Square up non-square pixels along the short axis as LibRaw's stretch()
    does: its interpolation weight is truncated to an int (always 0), so it
    repeats source lines, the one at the accumulated position ``rc += step``."""
    if aspect == 1:
        return img
    axis, step = (0, aspect) if aspect < 1 else (1, 1 / aspect)
    n = img.shape[axis]
    size = int(n / step + 0.5)
    # Sequential float64 accumulation, exactly LibRaw's loop (a product
    # j * step can land on the other side of an integer).
    pos = np.cumsum(np.r_[0.0, np.full(size - 1, step)])
    src = np.minimum(pos.astype(np.intp), n - 1)
    return np.ascontiguousarray(np.take(img, src, axis=axis))


def _orient(img: np.ndarray, flip: int) -> np.ndarray:
    """LibRaw's flip code applied: columns, rows, then transpose."""
    if flip & 1:
        img = img[:, ::-1]
    if flip & 2:
        img = img[::-1]
    if flip & 4:
        img = img.transpose(1, 0, 2)
    return np.ascontiguousarray(img)


def _stretched_pixels(shape: tuple[int, ...], aspect: float) -> int:
    """Pixels of an image of ``shape`` after :func:`_stretch`."""
    h, w = shape[:2]
    if aspect < 1:
        h = int(h / aspect + 0.5)
    elif aspect > 1:
        w = int(w * aspect + 0.5)
    return h * w


def _tone_for(color: str, tone: str) -> str:
    """``tone``, or for "auto" the curve ``color`` is encoded with."""
    if tone != "auto":
        return tone
    return COLOR_SPACES[color].tone if color in COLOR_SPACES else "srgb"


def develop(
    source: Any,
    *,
    demosaic: str = DEFAULT_DEMOSAIC,
    white_balance: str | tuple[float, float, float] = "camera",
    color: str = "srgb",
    tone: str = "auto",
    exposure: float | str = 0.0,
    highlights: str = "clip",
    bps: int | str = 8,
    orientation: str = "auto",
    lens_correction: Any = "off",
) -> npt.NDArray[Any]:
    """Develop a raw file into an RGB image.

    Parameters
    ----------
    source : path, bytes, binary file object, rawpy.RawPy or RawImage
        Anything :func:`load_raw` takes, or its result.
    demosaic : str
        One of :data:`DEMOSAIC_METHODS` that supports the sensor's pattern.
        The default ``"best"`` is ``"raisr_cd"`` for Bayer sensors and
        ``"markesteijn"`` for X-Trans ones.
    white_balance : {"camera", "daylight", "auto", "none"} or (r, g, b)
        As shot, the camera's daylight balance, LibRaw's grey world, none, or
        explicit multipliers.
    color : str
        One of :data:`COLORS`: ``"srgb"``, ``"adobe_rgb"`` (Adobe RGB (1998)),
        ``"display_p3"``, ``"rec2020"``, ``"prophoto"``, ``"xyz"`` (CIE XYZ,
        D65), ``"aces2065_1"``, each reached from the camera through sRGB's
        linear primaries as LibRaw's ``output_color`` does (see
        :mod:`imgform_rs.colorspace`); or ``"camera"`` to keep camera RGB.
    tone : {"auto", "srgb", "linear", "bt709", "gamma22", "romm"}
        Output transfer curve. ``"auto"``: the one ``color`` is encoded with
        (sRGB's for sRGB, Display P3 and camera RGB, 563/256 power for Adobe
        RGB, BT.709's for Rec. 2020, ROMM's for ProPhoto, linear for XYZ and
        ACES2065-1).
    exposure : float or "auto"
        Exposure change in stops, applied before the sensor clip, from
        ``-MAX_EXPOSURE`` to ``MAX_EXPOSURE`` (32); or
        ``"auto"``, LibRaw's default brightening (``postprocess()`` without
        ``no_auto_bright``): the demosaiced image's histograms give, per
        channel, the level that only the brightest 1 % of pixels exceed, and
        the largest becomes white (a gain on linear light after the colour
        matrix, so the brightest 1 % clip). It costs a histogram pass, not
        a second development. As in LibRaw, nothing is
        brightened with ``highlights="unclip"``. The default 0 keeps the
        file's exposure, which is darker than most converters show.
    highlights : {"clip", "unclip"}
        "clip": white-balance multipliers are divided by the smallest, so
        every channel reaches white at the sensor's white and highlights clip
        to neutral white (LibRaw's ``highlight=0``). "unclip": divided by the
        largest, so no channel is pushed past the sensor's white: clipped
        highlights keep the sensor's (often tinted) colour and the image is
        darker by the multipliers' ratio (LibRaw's ``highlight=1``, rawpy's
        ``HighlightMode.Ignore``).
    bps : {8, 16, "float"}
        Output uint8, uint16 or float32 in [0, 1].
    orientation : {"auto", "none"}
        Rotate / mirror as the camera recorded it, or keep the sensor's layout
        (non-square pixels are squared up either way).
    lens_correction : {"off", "auto"}, LensProfile or LensMatch
        Lens corrections from the lensfun database (:mod:`imgform_rs.lens`,
        needs the ``lens`` extra). ``"auto"`` looks the camera and lens up
        from the file (:func:`~imgform_rs.lens.match_lens`; no match develops
        uncorrected); a profile or match applies that. Vignetting is removed
        from the photosites above black before anything else (linear light),
        distortion and TCA in one resampling of the developed image before it
        is oriented (bilinear; the border the correction uncovers is 0).
        Sensors with non-square photosites are not corrected (``"auto"``
        leaves them as they are, a profile raises ``ValueError``). The
        development before the resampling goes to a working array of the
        output's size that is kept for the next corrected develop (its
        pages are not allocated and zeroed again for every raw of a batch).

    Returns
    -------
    ndarray, shape (H, W, 3), uint8 / uint16 / float32
        R, G, B; ``H, W`` are ``RawImage.output_size`` with ``orientation="auto"``.

    Raises
    ------
    RawError
        For a file that cannot be decoded (see :func:`load_raw`).
    ValueError
        For an unknown option, a bad white balance or exposure, or an
        X-Trans sensor with a Bayer-only demosaicer.
    ImportError
        ``lens_correction="auto"`` without lensfunpy installed.

    Notes
    -----
    The steps and their order are LibRaw's (see the module docstring): with
    ``demosaic="bilinear", tone="linear", bps=16, orientation="none"`` the
    result matches rawpy's ``postprocess`` with LINEAR, camera white balance,
    ``gamma=(1, 1)``, ``no_auto_bright=True``, ``output_bps=16`` and
    ``user_flip=0`` to >= 40 dB, non-square pixels included; the module
    docstring lists the cameras where rawpy and the file lack what LibRaw
    uses.

    Examples
    --------
    >>> import tempfile
    >>> from imgform_rs.dng import write_dng
    >>> cfa = np.full((32, 32), 95 + 1000, np.uint16)  # 1/4 of black..white
    >>> cfa[:, 16:] += 1000  # and 1/2
    >>> with tempfile.TemporaryDirectory() as d:
    ...     write_dng(f"{d}/grey.dng", cfa, "RGGB", white_level=4095, black_level=95)
    ...     rgb = develop(f"{d}/grey.dng", tone="linear", bps=16, demosaic="bilinear")
    >>> rgb.shape, rgb.dtype, int(rgb[8, 8, 1]), int(rgb[8, 24, 1])
    ((32, 32, 3), dtype('uint16'), 16384, 32768)
    """
    check_bps(bps)
    if color not in COLORS:
        raise ValueError(f"color must be one of {COLORS}, got {color!r}")
    if tone != "auto" and tone not in TONES:
        raise ValueError(f"tone must be one of {('auto', *TONES)}, got {tone!r}")
    if highlights not in HIGHLIGHTS:
        raise ValueError(f"highlights must be one of {HIGHLIGHTS}, got {highlights!r}")
    if orientation not in ("auto", "none"):
        raise ValueError(f'orientation must be "auto" or "none", got {orientation!r}')
    auto = isinstance(exposure, str) and exposure == "auto"
    if not auto and not (
        isinstance(exposure, (int, float, np.number))
        and not isinstance(exposure, bool)
        and abs(exposure) <= MAX_EXPOSURE
    ):
        raise ValueError(
            f'exposure must be "auto" or a number of stops from {-MAX_EXPOSURE:g} to '
            f"{MAX_EXPOSURE:g}, got {exposure!r}"
        )
    if not isinstance(demosaic, str):
        raise TypeError(f"demosaic must be a str, one of {DEMOSAIC_METHODS}, got {demosaic!r}")
    raw = source if isinstance(source, RawImage) else load_raw(source)
    check_raw_image(raw)
    mul = _multipliers(raw, white_balance)
    mul = mul / (mul.min() if highlights == "clip" else mul.max())
    scale4 = mul / _white_range(raw) * 2.0 ** (0.0 if auto else exposure)
    matrix = np.eye(3) if color == "camera" else srgb_to(color) @ raw.camera_to_srgb
    pattern = raw.pattern if isinstance(raw.pattern, str) else np.asarray(raw.pattern, np.int64)
    tiles = _tiles(raw, scale4)
    profile = _lens_profile(raw, lens_correction)
    h, w = raw.cfa.shape
    m = np.ascontiguousarray(matrix, np.float64)
    native = None if profile is None else profile.native(w, h)
    # LibRaw's brightening: the level is read off the demosaiced image (the
    # devignetted one, before its geometry is corrected) and folded into the
    # matrix, with the pixels counted after a non-square sensor's stretch.
    brighten = None
    if auto and highlights == "clip":
        brighten = _stretched_pixels((h, w), raw.pixel_aspect)
    args = (m, _tone_for(color, tone), demosaic, _BPS[bps], native, brighten)
    rgb = _native.develop(raw.cfa, pattern, *tiles, *args)
    rgb = _stretch(rgb, raw.pixel_aspect)
    return _orient(rgb, raw.flip) if orientation == "auto" else rgb


def _lens_profile(raw: RawImage, lens_correction: Any) -> Any:
    """The :class:`~imgform_rs.lens.LensProfile` that ``lens_correction``
    (as :func:`develop` takes it) selects for ``raw``, or ``None``."""
    auto = isinstance(lens_correction, str) and lens_correction == "auto"
    if isinstance(lens_correction, str):
        if lens_correction == "off":
            return None
        if lens_correction != "auto":
            raise ValueError(
                'lens_correction must be "auto", "off", a LensProfile or a LensMatch, '
                f"got {lens_correction!r}"
            )
        from .lens import match_lens

        lens_correction = match_lens(raw)
    from .lens import LensMatch, LensProfile

    if isinstance(lens_correction, LensMatch):
        lens_correction = lens_correction.profile
    if lens_correction is None:
        return None
    if not isinstance(lens_correction, LensProfile):
        raise TypeError(
            'lens_correction must be "auto", "off", a LensProfile or a LensMatch, '
            f"got {type(lens_correction).__name__}"
        )
    if raw.pixel_aspect != 1:
        if auto:
            return None
        raise ValueError(
            f"{raw.source}: lens corrections need square photosites, "
            f"this sensor's are {raw.pixel_aspect:g}:1"
        )
    return lens_correction


def raw_exif(raw: RawImage, orientation: str = "auto") -> bytes:
    """EXIF for a picture developed from ``raw``, for :func:`write_image`.

    Camera, lens, ISO, exposure time, f-number, focal length, capture date
    and artist where the raw records them (``RawImage.shot``), and the
    orientation: 1 when :func:`develop` turned the pixels
    (``orientation="auto"``), else the raw's own, so that viewers turn them.

    Parameters
    ----------
    raw : RawImage
    orientation : {"auto", "none"}
        What was given to :func:`develop`.

    Returns
    -------
    bytes
        Starting with ``Exif\\0\\0``, as Pillow writes it.

    Examples
    --------
    >>> import tempfile
    >>> from PIL import Image
    >>> from imgform_rs.dng import write_dng
    >>> cfa = (np.arange(32 * 32) % 2000 + 100).astype(np.uint16).reshape(32, 32)
    >>> with tempfile.TemporaryDirectory() as d:
    ...     write_dng(f"{d}/a.dng", cfa, "RGGB", white_level=4095, orientation=6)
    ...     raw = load_raw(f"{d}/a.dng")
    >>> exif = Image.Exif()
    >>> exif.load(raw_exif(raw, orientation="none"))
    >>> exif[274], exif[305]  # turn 90 degrees clockwise to view
    (6, 'imgform-rs')
    """
    if not isinstance(raw, RawImage):
        raise TypeError(f"raw must be a RawImage (see load_raw), got {type(raw).__name__}")
    if orientation not in ("auto", "none"):
        raise ValueError(f'orientation must be "auto" or "none", got {orientation!r}')
    return exif_bytes(raw.shot, raw.flip, oriented=orientation == "auto")


def develop_file(
    source: Any,
    path: str | os.PathLike[str],
    *,
    quality: int = 92,
    overwrite: bool = False,
    **options: Any,
) -> Path:
    """Develop a raw and write it with its colour profile and EXIF.

    :func:`develop` with ``options``, then :func:`write_image` with the
    matching ICC profile and :func:`raw_exif`; what ``imgform develop`` runs.

    Parameters
    ----------
    source : path, bytes, binary file object, rawpy.RawPy or RawImage
    path : str or PathLike
        ``.jpg`` / ``.jpeg``, ``.png``, ``.tif`` / ``.tiff``, ``.exr``; JPEG
        needs ``bps=8``, float32 (``bps="float"``) needs TIFF or EXR, and EXR
        also ``tone="linear"`` (with ``orientation="auto"``).
    quality : int
        JPEG quality, 1 to 100.
    overwrite : bool
    **options
        Keywords of :func:`develop`.

    Returns
    -------
    Path

    Raises
    ------
    As :func:`develop` and :func:`write_image`; checked before developing
    where possible (format, quality, an existing file).

    Examples
    --------
    >>> import tempfile
    >>> from PIL import Image
    >>> from imgform_rs.dng import write_dng
    >>> cfa = (np.arange(32 * 32) % 2000 + 100).astype(np.uint16).reshape(32, 32)
    >>> with tempfile.TemporaryDirectory() as d:
    ...     write_dng(f"{d}/a.dng", cfa, "RGGB", white_level=4095)
    ...     out = develop_file(f"{d}/a.dng", f"{d}/a.png", color="adobe_rgb", bps=16)
    ...     with Image.open(out) as im:
    ...         "icc_profile" in im.info
    True
    """
    return develop_to(source, path, quality, overwrite, options)[0]


def develop_to(
    source: Any, path: str | os.PathLike[str], quality: int, overwrite: bool, options: dict
) -> tuple[Path, tuple[int, int], str]:
    """:func:`develop_file`, also returning the picture's ``(H, W)`` and the
    line saying what lens correction was matched and applied ("" when off),
    for the command line's and the batch's per-file reports."""
    target = Path(path)
    kind = path_kind(target)
    check_format(kind, options.get("bps", 8))
    check_quality(quality)
    if target.exists() and not overwrite:
        raise FileExistsError(f"{target} exists (pass overwrite=True to replace it)")
    raw = source if isinstance(source, RawImage) else load_raw(source)
    exif = raw_exif(raw, options.get("orientation", "auto"))
    color, tone = options.get("color", "srgb"), options.get("tone", "auto")
    if kind == "exr":
        check_exr(color, _tone_for(color, tone), exif)
    lens, lens_report = _resolve_lens(raw, options.get("lens_correction", "off"))
    rgb = develop(raw, **{**options, "lens_correction": lens})
    written = write_image(
        target,
        rgb,
        color=color,
        tone=tone,
        exif=exif,
        quality=quality,
        overwrite=overwrite,
    )
    return written, (rgb.shape[0], rgb.shape[1]), lens_report


def _resolve_lens(raw: RawImage, lens_correction: Any) -> tuple[Any, str]:
    """``lens_correction`` with ``"auto"`` looked up once for ``raw``, and
    the report of what that matched and will apply ("" when off)."""
    if isinstance(lens_correction, str) and lens_correction == "off":
        return lens_correction, ""
    if isinstance(lens_correction, str) and lens_correction == "auto":
        from .lens import match_lens

        match = match_lens(raw)
        if match.profile is not None and raw.pixel_aspect != 1:
            # develop leaves such sensors uncorrected under "auto" (see its docs).
            return "off", "lens correction: none (non-square photosites)"
        return match, match.report()
    profile = _lens_profile(raw, lens_correction)  # checks type and photosites
    if profile is not None:
        return profile, f"lens correction: {profile.describe()}"
    from .lens import LensMatch

    if isinstance(lens_correction, LensMatch):  # one that found nothing says why
        return lens_correction, lens_correction.report()
    return lens_correction, ""

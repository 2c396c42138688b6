"""Developed pictures to files: JPEG, PNG and TIFF with their ICC profile and EXIF.

Encoders are maintained libraries': Pillow through imageio for JPEG and 8-bit
PNG, tifffile for TIFF, and our small PNG writer only for 16-bit RGB, which
Pillow cannot hold (see :mod:`imgform_rs._png`). Profiles come from
:mod:`imgform_rs._icc` (LittleCMS), EXIF from :mod:`imgform_rs._exif`
(Pillow).

tifffile writes no EXIF sub-IFD, so a TIFF gets the IFD0 part of the EXIF
(make, model, date, artist, orientation, software) as baseline TIFF tags; the
exposure settings and lens are in JPEG and PNG files only.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ._icc import icc_profile
from ._png import write_png

FORMATS = {".png": "png", ".tif": "tiff", ".tiff": "tiff", ".jpg": "jpeg", ".jpeg": "jpeg"}
_DTYPES = {
    "png": (np.uint8, np.uint16),
    "tiff": (np.uint8, np.uint16, np.float32),
    "jpeg": (np.uint8,),
}
# Integer TIFFs: zlib at level 1 with the horizontal predictor, and PNG at
# level 1 (Pillow also picks each row's filter): on a 4 MP picture level 6
# cost 2-6x the time for 5-15 % smaller files (Pillow's default PNG: 13 s
# against 2.3 s on our shared 2-core machine). Float TIFFs stay uncompressed:
# without the floating-point predictor (tifffile needs imagecodecs for it)
# zlib saved 18 % in 8.8 s.
_ZLIB = {"compression": "zlib", "compressionargs": {"level": 1}, "predictor": True}
_PNG_LEVEL = 1
# Baseline TIFF tags copied from the EXIF's IFD0, with their TIFF types
# (Software, 305, goes through tifffile's own argument).
_TIFF_TAGS = {271: "s", 272: "s", 274: "H", 306: "s", 315: "s"}
_SOFTWARE = 305


def check_quality(quality: Any) -> int:
    """JPEG quality: an int from 1 (smallest) to 100 (best)."""
    if isinstance(quality, bool) or not isinstance(quality, (int, np.integer)):
        raise ValueError(f"quality must be an int from 1 to 100, got {quality!r}")
    if not 1 <= quality <= 100:
        raise ValueError(f"quality must be an int from 1 to 100, got {quality}")
    return int(quality)


def check_format(kind: str, bps: Any) -> None:
    """ValueError if a file ``kind`` cannot hold :func:`develop`'s ``bps``."""
    dtype = {8: np.uint8, 16: np.uint16, "float": np.float32}.get(bps)
    if dtype is not None and dtype not in _DTYPES[kind]:
        accepted = {"jpeg": "8", "png": "8 or 16", "tiff": "8, 16 or float"}[kind]
        raise ValueError(f"{kind.upper()} files take bps {accepted}, got bps={bps!r}")


def _check_exif(exif: Any) -> bytes:
    """``exif`` led by ``Exif\\0\\0`` as JPEG's APP1 needs it; TypeError /
    ValueError unless it is EXIF that Pillow reads (a file must not carry
    bytes that viewers choke on)."""
    if not isinstance(exif, bytes):
        raise TypeError(f"exif must be bytes (see raw_exif) or None, got {type(exif).__name__}")
    from PIL import Image

    try:
        Image.Exif().load(exif)
        readable = exif.removeprefix(b"Exif\0\0")[:4] in (b"II*\0", b"MM\0*")
    except Exception:  # Pillow's parse errors are of several classes
        readable = False
    if not readable:
        raise ValueError("exif must be EXIF data (a TIFF header, optionally after Exif\\0\\0)")
    return b"Exif\0\0" + exif.removeprefix(b"Exif\0\0")


def _check_image(img: np.ndarray, kind: str) -> None:
    allowed = _DTYPES[kind]
    if img.dtype not in allowed or not (img.ndim == 2 or (img.ndim == 3 and img.shape[2] == 3)):
        names = ", ".join(np.dtype(t).name for t in allowed)
        raise ValueError(
            f"{kind.upper()} takes {names} images of shape (H, W) or (H, W, 3), "
            f"got {img.dtype} {img.shape}"
        )


def _pillow(
    target: Path, img: np.ndarray, kind: str, icc: bytes | None, exif: bytes | None, quality: int
) -> None:
    import imageio.v3 as iio

    options: dict[str, Any] = {"compress_level": _PNG_LEVEL}
    if kind == "jpeg":
        options = {"quality": quality}
    if icc:
        options["icc_profile"] = icc
    if exif:
        options["exif"] = exif
    iio.imwrite(target, img, extension=".jpg" if kind == "jpeg" else ".png", **options)


def _tiff(target: Path, img: np.ndarray, icc: bytes | None, exif: bytes | None) -> None:
    import tifffile

    extratags, software = [], "imgform-rs"
    if exif:
        from PIL import Image

        ifd0 = Image.Exif()
        ifd0.load(exif)
        software = ifd0.get(_SOFTWARE, software)
        for tag, kind in _TIFF_TAGS.items():
            value = ifd0.get(tag)
            if value is not None:
                extratags.append((tag, kind, 1 if kind == "H" else 0, value, True))
    tifffile.imwrite(
        target,
        img,
        photometric="rgb" if img.ndim == 3 else "minisblack",
        iccprofile=icc,
        software=software,
        extratags=extratags,
        metadata=None,
        **({} if img.dtype == np.float32 else _ZLIB),
    )


def write_image(
    path: str | os.PathLike[str],
    image: npt.NDArray[Any],
    *,
    color: str = "srgb",
    tone: str = "auto",
    exif: bytes | None = None,
    quality: int = 92,
    overwrite: bool = False,
) -> Path:
    """Write a developed image as JPEG, PNG or TIFF, with its colour profile.

    Parameters
    ----------
    path : str or PathLike
        Ends in ``.jpg`` / ``.jpeg`` (8 bit), ``.png`` (8 or 16 bit) or
        ``.tif`` / ``.tiff`` (8, 16 bit, zlib-compressed, or float32).
    image : ndarray, shape (H, W) or (H, W, 3)
        uint8, uint16 or float32 as the format allows.
    color, tone : str
        The image's colour space and transfer curve, as given to
        :func:`~imgform_rs.develop`: the matching ICC profile, built by
        LittleCMS, is embedded (none for ``"xyz"`` and ``"camera"``, which an
        RGB profile cannot describe).
    exif : bytes, optional
        EXIF to embed, e.g. :func:`~imgform_rs.raw_exif` of the raw (TIFF
        files keep its IFD0 tags only: make, model, date, artist, orientation).
    quality : int
        JPEG quality, 1 to 100.
    overwrite : bool
        Replace an existing file; by default an existing file is never touched.

    Returns
    -------
    Path

    Raises
    ------
    FileExistsError
        When ``path`` exists and ``overwrite`` is False.
    ValueError
        For another extension, dtype or shape, an unknown colour space or
        tone, or a quality outside 1..100.

    Examples
    --------
    >>> import tempfile
    >>> from PIL import Image
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = write_image(f"{d}/a.jpg", np.zeros((4, 4, 3), np.uint8), color="display_p3")
    ...     with Image.open(p) as im:
    ...         p.name, im.info["icc_profile"][36:40]
    ('a.jpg', b'acsp')
    """
    from .develop import COLORS, TONES, _tone_for

    target = Path(path)
    kind = FORMATS.get(target.suffix.lower())
    if kind is None:
        raise ValueError(f"path must end in .jpg, .jpeg, .png, .tif or .tiff, got {target.name!r}")
    if color not in COLORS:
        raise ValueError(f"color must be one of {COLORS}, got {color!r}")
    if tone != "auto" and tone not in TONES:
        raise ValueError(f"tone must be one of {('auto', *TONES)}, got {tone!r}")
    quality = check_quality(quality)
    if exif is not None:
        exif = _check_exif(exif)
    img = np.asarray(image)
    _check_image(img, kind)
    if target.exists() and not overwrite:
        raise FileExistsError(f"{target} exists (pass overwrite=True to replace it)")
    icc = icc_profile(color, _tone_for(color, tone))
    if kind == "tiff":
        _tiff(target, img, icc, exif)
    elif kind == "png" and img.dtype == np.uint16 and img.ndim == 3:
        write_png(target, img, icc=icc, exif=exif)
    else:
        _pillow(target, img, kind, icc, exif, quality)
    return target

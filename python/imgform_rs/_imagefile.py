"""Developed pictures to files: JPEG, PNG, TIFF and EXR with their colour
metadata and EXIF.

Encoders are maintained libraries': Pillow through imageio for JPEG and 8-bit
PNG, tifffile for TIFF, OpenEXR's own Python bindings for EXR (the ``exr``
extra), and our small PNG writer only for 16-bit RGB, which Pillow cannot
hold (see :mod:`imgform_rs._png`). Profiles come from :mod:`imgform_rs._icc`
(LittleCMS), EXIF from :mod:`imgform_rs._exif` (Pillow).

A TIFF gets the IFD0 part of the EXIF (make, model, date, artist,
orientation, software) as baseline TIFF tags, not the EXIF sub-IFD with the
exposure settings and lens, because neither library can write that sub-IFD
into our TIFFs (checked with tifffile 2026.3 and Pillow 13.0):

- tifffile drops tag 34665 (ExifIFD) from ``extratags`` (it is in
  ``TIFF.TAG_FILTERED``, with the other tags that point to IFDs: it would
  have to lay the sub-IFD out itself, and it has no writer for one);
- Pillow writes the sub-IFD (``exif=``) only with its own, uncompressed TIFF
  encoder and only for 8-bit images (it has no 16-bit or float RGB mode);
  any compression goes through libtiff, which refuses the tag ("Bad LONG8 or
  IFD8 value ... for EXIFIFDOffset", then "Error setting from dictionary").

An EXR holds linear light by definition: it is written only for a linear
tone, with the colour space's ``chromaticities`` (OpenEXR's standard
attribute, in place of an ICC profile) and the EXIF as OpenEXR's standard
camera attributes (``cameraMake``, ``lensModel``, ``expTime``, ...).

Every file is written under a hidden name in the target's folder, then
renamed onto the target (``os.replace``, atomic within one file system):
an encoder that fails halfway (disk full, a limit it checks only as it
writes) leaves no partial file and, with ``overwrite=True``, keeps the old
file whole. The limits we know are checked before that, with a clear error.
"""

from __future__ import annotations

import errno
import hashlib
import numbers
import os
import stat
import uuid
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from . import _exif
from ._arrays import native
from ._icc import icc_profile
from ._png import write_png

FORMATS = {
    ".jpg": "jpeg",
    ".jpeg": "jpeg",
    ".png": "png",
    ".tif": "tiff",
    ".tiff": "tiff",
    ".exr": "exr",
}
_DTYPES = {
    "png": (np.uint8, np.uint16),
    "tiff": (np.uint8, np.uint16, np.float32),
    "jpeg": (np.uint8,),
    "exr": (np.float32,),
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
# OpenEXR's convention for XYZ data (its Technical Introduction): primaries
# (1, 0), (0, 1), (0, 0) and white (1/3, 1/3) make the RGB-to-XYZ matrix the
# identity, so R, G, B are X, Y, Z.
_EXR_XYZ = (1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1 / 3, 1 / 3)
# EXIF tags (IFD0, then the Exif sub-IFD) -> OpenEXR's standard attributes
# (ImfStandardAttributes.h) of the same meaning and unit.
_EXR_TEXT = {271: "cameraMake", 272: "cameraModel", 315: "owner"}
_EXR_SHOT = {
    33434: "expTime",
    33437: "aperture",
    34855: "isoSpeed",
    37386: "focalLength",
    36867: "capDate",
    42035: "lensMake",
    42036: "lensModel",
}
_EXIF_IFD = 0x8769
# libjpeg's JPEG_MAX_DIMENSION (the format itself allows 65535).
_JPEG_MAX_SIDE = 65500
# The EXIF of a JPEG is one APP1 segment, whose 16-bit length counts itself:
# 65533 bytes from Exif\0\0 on (Pillow's MAX_BYTES_IN_MARKER).
_JPEG_MAX_EXIF = 65533


def path_kind(path: str | os.PathLike[str]) -> str:
    """The format a file name asks for ("png", "tiff", "jpeg", "exr")."""
    kind = FORMATS.get(Path(path).suffix.lower())
    if kind is None:
        *others, last = FORMATS
        raise ValueError(f"path must end in {', '.join(others)} or {last}, got {Path(path).name!r}")
    return kind


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
        accepted = {"jpeg": "8", "png": "8 or 16", "tiff": "8, 16 or float", "exr": '"float"'}[kind]
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


def _check_image(img: np.ndarray, kind: str, exif: bytes | None) -> None:
    """ValueError for an image ``kind`` cannot hold, before any file is
    opened: the encoders find an empty image, or JPEG's size limits, only
    once they write."""
    allowed = _DTYPES[kind]
    if img.dtype not in allowed or not (img.ndim == 2 or (img.ndim == 3 and img.shape[2] == 3)):
        names = ", ".join(np.dtype(t).name for t in allowed)
        raise ValueError(
            f"{kind.upper()} takes {names} images of shape (H, W) or (H, W, 3), "
            f"got {img.dtype} {img.shape}"
        )
    if img.size == 0:
        raise ValueError(f"image must have at least one pixel, got shape {img.shape}")
    if kind != "jpeg":
        return
    if max(img.shape[:2]) > _JPEG_MAX_SIDE:
        height, width = img.shape[:2]
        raise ValueError(
            f"JPEG images are at most {_JPEG_MAX_SIDE} pixels a side, got {width} x {height} "
            "(write PNG or TIFF)"
        )
    if exif and len(exif) > _JPEG_MAX_EXIF:
        raise ValueError(
            f"JPEG holds at most {_JPEG_MAX_EXIF} bytes of EXIF (from Exif\\0\\0 on), "
            f"got {len(exif)}"
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

    extratags: list[tuple] = []
    software: str | bytes = "imgform-rs"
    if exif:
        from PIL import Image

        ifd0 = Image.Exif()
        ifd0.load(exif)
        if isinstance(ifd0.get(_SOFTWARE), str):
            software = _exif.text_bytes(ifd0[_SOFTWARE])
        for tag, kind in _TIFF_TAGS.items():
            value = ifd0.get(tag)
            if isinstance(value, str):  # its bytes: tifffile takes only ASCII text
                value = _exif.text_bytes(value)
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


def _openexr() -> Any:
    try:
        import OpenEXR
    except ImportError as exc:
        raise ImportError("EXR files need OpenEXR: pip install imgform-rs[exr]") from exc
    return OpenEXR


def _chromaticities(color: str) -> tuple[float, ...] | None:
    """OpenEXR's ``chromaticities`` of an output colour space (red, green,
    blue and white x, y); None for camera RGB, which has no primaries."""
    from .colorspace import COLOR_SPACES

    space = COLOR_SPACES.get(color)
    if space is None:
        return None
    if space.primaries is None:
        return _EXR_XYZ
    return tuple(float(v) for xy in (*space.primaries, space.white) for v in xy)


def _exr_attributes(exif: bytes | None) -> dict[str, Any]:
    """The EXIF's camera, lens, exposure and date as OpenEXR attributes."""
    if not exif:
        return {}
    from PIL import Image

    ifd0 = Image.Exif()
    ifd0.load(exif)
    sub = ifd0.get_ifd(_EXIF_IFD)
    attributes = {}
    for ifd, names in ((ifd0, _EXR_TEXT), (sub, _EXR_SHOT)):
        for tag, name in names.items():
            value = ifd.get(tag)
            if isinstance(value, tuple):
                # A tag of several values (EXIF 2.2's ISOSpeedRatings may be
                # (0, 200)): the first one that is set; OpenEXR's is a float.
                value = next((v for v in value if v), None)
            if isinstance(value, str):  # OpenEXR's text is UTF-8, as EXIF's mostly is
                attributes[name] = _exif.text_bytes(value).decode(errors="replace")
            elif isinstance(value, numbers.Real):  # rationals are Pillow's IFDRational
                attributes[name] = float(value)
    return attributes


def _exr(target: Path, img: np.ndarray, color: str, exif: bytes | None) -> None:
    openexr = _openexr()
    header: dict[str, Any] = {
        "compression": openexr.ZIP_COMPRESSION,
        "type": openexr.scanlineimage,
        **_exr_attributes(exif),
    }
    chromaticities = _chromaticities(color)
    if chromaticities is not None:
        header["chromaticities"] = chromaticities
    channels = {"RGB" if img.ndim == 3 else "Y": np.ascontiguousarray(img)}
    try:
        with openexr.File(header, channels) as exr:
            exr.write(str(target))
    except RuntimeError as exc:  # OpenEXR's I/O errors (no such folder, disk full)
        raise OSError(f"{target}: {exc}") from exc


def check_exr(color: str, tone: str, exif: bytes | None) -> None:
    """An EXR holds linear values and has no orientation attribute: refuse
    what its readers would show wrongly (``tone`` resolved, not "auto"), and
    fail early without OpenEXR."""
    if tone != "linear":
        raise ValueError(
            f'EXR files hold linear light: develop with tone="linear" (the {color!r} '
            f"data given are encoded with the {tone!r} curve)"
        )
    if exif:
        from PIL import Image

        tags = Image.Exif()
        tags.load(exif)
        turn = tags.get(274, 1)
        if turn != 1:
            raise ValueError(
                f'EXR files have no orientation: develop with orientation="auto" '
                f"(the EXIF says to turn the pixels: orientation {turn})"
            )
    _openexr()


#: The longest file name (bytes) of the common file systems (ext4, XFS,
#: Btrfs, APFS, NTFS in UTF-16 units): a partial name is kept within it.
NAME_MAX = 255
#: The random part of a partial name.
_TAG_HEX = 32


def partial_path(target: Path) -> Path:
    """A unique name beside ``target`` with its suffix (writers pick the
    format from it), hidden, so a half-written file is never mistaken for
    an output; its stem is :func:`partial_stem`'s."""
    return target.with_name(f".{partial_stem(target)}.part-{uuid.uuid4().hex}{target.suffix}")


def partial_stem(target: Path) -> str:
    """``target``'s stem as :func:`partial_path` names it: whole where the
    name fits in :data:`NAME_MAX` bytes, else cut to fit and marked by a
    digest of the whole stem (a name the file system takes must not become
    one it refuses by the 40 bytes a partial name adds)."""
    stem = os.fsencode(target.stem)
    suffix = os.fsencode(target.suffix)
    room = NAME_MAX - len(b"..part-") - _TAG_HEX - len(suffix)
    if len(stem) <= room:
        return target.stem
    digest = hashlib.sha256(stem).hexdigest()[:8]
    keep = max(room - len(digest) - 1, 0)  # none, beside a suffix of ~200 bytes
    cut = target.stem[:keep]
    while len(os.fsencode(cut)) > keep:
        cut = cut[:-1]  # whole characters: a name stays valid UTF-8
    return f"{cut}~{digest}"


def landing(target: Path) -> Path:
    """Where a file written to ``target`` lands: through a symbolic link to
    the file it names (as ``open`` writes), so that replacing a linked file
    keeps the link, and the partial file beside it is on its file system.
    A loop of links is the ``OSError`` that ``open`` raises (Python 3.11's
    ``resolve`` raises ``RuntimeError``)."""
    if not target.is_symlink():
        return target
    try:
        return target.resolve()
    except RuntimeError:
        raise OSError(errno.ELOOP, os.strerror(errno.ELOOP), str(target)) from None


def replace_onto(partial: Path, dest: Path) -> None:
    """Renames the finished ``partial`` onto ``dest`` (atomic), giving it the
    permission bits of the file it replaces: a replaced file stays as
    readable, or as private, as it was. (Its owner becomes the writer.)"""
    try:
        os.chmod(partial, stat.S_IMODE(dest.stat().st_mode))
    except FileNotFoundError:
        pass
    os.replace(partial, dest)


def _reserve(target: Path) -> Path:
    """A new, empty file beside ``target`` for the encoder to write
    (:func:`partial_path`).

    Created here ("x": no one else has it) rather than by :mod:`tempfile`,
    whose files are private (0600): this one becomes the output, so it gets
    the permissions any new file gets. Its failure names ``target``.
    """
    partial = partial_path(target)
    try:
        partial.open("xb").close()
    except OSError as exc:  # no such folder, no permission
        raise type(exc)(exc.errno, exc.strerror, str(target)) from None
    return partial


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
    """Write a developed image as JPEG, PNG, TIFF or EXR, with its colour profile.

    Parameters
    ----------
    path : str or PathLike
        Ends in ``.jpg`` / ``.jpeg`` (8 bit), ``.png`` (8 or 16 bit),
        ``.tif`` / ``.tiff`` (8, 16 bit, zlib-compressed, or float32) or
        ``.exr`` (linear float32, ZIP-compressed; needs the ``exr`` extra).
    image : ndarray, shape (H, W) or (H, W, 3)
        uint8, uint16 or float32 as the format allows.
    color, tone : str
        The image's colour space and transfer curve, as given to
        :func:`~imgform_rs.develop`: the matching ICC profile, built by
        LittleCMS, is embedded (none for ``"xyz"`` and ``"camera"``, which an
        RGB profile cannot describe). An EXR takes only a linear tone and
        carries the space's primaries and white as its ``chromaticities``
        (XYZ by OpenEXR's convention for it; none for ``"camera"``). An
        (H, W) image gets a grey profile with the tone curve alone: an RGB
        profile does not apply to one channel (libpng drops it).
    exif : bytes, optional
        EXIF to embed, e.g. :func:`~imgform_rs.raw_exif` of the raw. JPEG
        and PNG files get it with the Exif tags of the image itself added:
        its size, ColorSpace (sRGB for ``"srgb"`` with the sRGB curve, else
        uncalibrated, the profile saying what it is), FlashpixVersion and,
        for JPEG, ComponentsConfiguration. TIFF files keep its IFD0 tags
        only (make, model, date, artist, orientation); EXR files its camera,
        lens, exposure and date as OpenEXR's standard attributes, and refuse
        an orientation other than 1, which EXR cannot record.
    quality : int
        JPEG quality, 1 to 100.
    overwrite : bool
        Replace an existing file; by default an existing file is never touched.
        The file is written under a temporary name beside ``path`` and
        renamed onto it, so a failed write leaves the old file as it was. A
        replaced file keeps its permission bits; a symbolic link stays, and
        the file it names is replaced.

    Returns
    -------
    Path

    Raises
    ------
    FileExistsError
        When ``path`` exists and ``overwrite`` is False.
    ValueError
        For another extension, dtype or shape, an empty image, an unknown
        colour space or tone, or a quality outside 1..100; for JPEG, a side
        over 65500 pixels or EXIF over 65533 bytes; for EXR, a tone other
        than linear or an EXIF orientation other than 1.
    ImportError
        For EXR without OpenEXR installed.

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
    kind = path_kind(target)
    if color not in COLORS:
        raise ValueError(f"color must be one of {COLORS}, got {color!r}")
    if tone != "auto" and tone not in TONES:
        raise ValueError(f"tone must be one of {('auto', *TONES)}, got {tone!r}")
    quality = check_quality(quality)
    if exif is not None:
        exif = _check_exif(exif)
    img = native(image)  # big-endian samples: the values they hold
    if exif is not None and kind in ("jpeg", "png") and img.ndim in (2, 3):
        srgb = color == "srgb" and _tone_for(color, tone) == "srgb"
        height, width = img.shape[:2]
        exif = _exif.for_image(exif, width, height, jpeg=kind == "jpeg", srgb=srgb)
    _check_image(img, kind, exif)
    if kind == "exr":
        check_exr(color, _tone_for(color, tone), exif)
    if target.exists() and not overwrite:
        raise FileExistsError(f"{target} exists (pass overwrite=True to replace it)")
    if target.is_dir():  # found now, not after the whole image is encoded
        raise IsADirectoryError(errno.EISDIR, "is a folder, not a file to replace", str(target))
    grey = img.ndim == 2
    icc = None if kind == "exr" else icc_profile(color, _tone_for(color, tone), grey=grey)
    dest = landing(target)
    partial = _reserve(dest)
    try:
        if kind == "exr":
            _exr(partial, img, color, exif)
        elif kind == "tiff":
            _tiff(partial, img, icc, exif)
        elif kind == "png" and img.dtype == np.uint16 and img.ndim == 3:
            write_png(partial, img, icc=icc, exif=exif)
        else:
            _pillow(partial, img, kind, icc, exif, quality)
        replace_onto(partial, dest)
    except BaseException:  # an interrupt too: the partial file must not stay
        partial.unlink(missing_ok=True)
        raise
    return target

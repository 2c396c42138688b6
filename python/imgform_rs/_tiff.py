"""Reading TIFF tags from the bytes of a TIFF-based raw file (DNG, KDC, NEF, ...).

rawpy exposes most of what LibRaw reads, but not everything LibRaw uses to
develop: the colour matrix some Kodak cameras store in tag 37400 and the DNG
black-level pattern larger than the 2x2 tile are two such values. tifffile
parses the file; this module walks the IFDs LibRaw's TIFF parser walks (IFD0
and its successors, each followed by the SubIFDs it points to) and returns
each IFD's tags as plain numbers or text. It never raises on malformed data:
whatever tifffile cannot read is left out, and what tifffile says about it
goes to the caller rather than to the log (stderr).
"""

from __future__ import annotations

import io
import logging
import threading
from typing import Any

import numpy as np

Value = str | tuple[float, ...]

# A corrupt file can chain IFDs in a loop or claim millions of them.
_MAX_IFDS = 64
_RATIONALS = (5, 10)  # RATIONAL, SRATIONAL: tifffile keeps numerator, denominator pairs


class _Complaints(logging.Filter):
    """Holds back tifffile's log records while this module parses a file, for
    :func:`tiff_ifds`'s caller. Per thread: batches parse files on many."""

    def __init__(self) -> None:
        super().__init__()
        self.local = threading.local()

    def filter(self, record: logging.LogRecord) -> bool:
        caught = getattr(self.local, "caught", None)
        if caught is None:
            return True  # someone else's parse: theirs to log
        caught.append(record.getMessage())
        return False


_COMPLAINTS = _Complaints()
logging.getLogger("tifffile").addFilter(_COMPLAINTS)


def _value(tag: Any) -> Value | None:
    """A tag's value as a str, or a tuple of floats with rationals divided
    out; None for what tifffile decoded into something else (a dict)."""
    value = tag.value
    if isinstance(value, str):
        return value.strip()
    if isinstance(value, bytes):
        return tuple(float(b) for b in value)
    if isinstance(value, (int, float, np.number)):
        value = (value,)
    if isinstance(value, np.ndarray):
        value = tuple(value.ravel())
    if not isinstance(value, tuple) or not all(
        isinstance(v, (int, float, np.number)) for v in value
    ):
        return None
    if int(tag.dtype) in _RATIONALS:
        pairs = zip(value[0::2], value[1::2], strict=False)
        return tuple(float(n) / float(d) if d else 0.0 for n, d in pairs)
    return tuple(float(v) for v in value)


def _tags(page: Any) -> dict[int, Value]:
    found = {}
    for tag in page.tags.values():
        value = _value(tag)
        if value is not None:
            found[tag.code] = value
    return found


def _walk(pages: Any, found: list[dict[int, Value]]) -> None:
    """Appends the tags of ``pages`` in LibRaw's order: each IFD, then the
    SubIFDs it points to, then the next IFD."""
    for page in pages:
        if len(found) >= _MAX_IFDS:
            return
        found.append(_tags(page))
        subs = page.pages
        if subs is not None:
            _walk(subs, found)


def tiff_ifds(data: bytes, complaints: list[str] | None = None) -> list[dict[int, Value]]:
    """Every IFD of a TIFF file, in the order LibRaw parses them.

    Parameters
    ----------
    data : bytes
        The whole file.
    complaints : list of str, optional
        Receives what tifffile logged about the file (such as a tag whose
        value lies past the end of a truncated file); dropped if not given.

    Returns
    -------
    list of dict
        Tag number -> value (a str for ASCII, else a tuple of floats with
        rationals divided out); empty for a file that is not TIFF, and cut
        short where tifffile finds the file corrupt.
    """
    import tifffile

    found: list[dict[int, Value]] = []
    _COMPLAINTS.local.caught = [] if complaints is None else complaints
    try:
        with tifffile.TiffFile(io.BytesIO(data)) as tif:
            _walk(tif.pages, found)
    except Exception:  # tifffile's errors on corrupt files are of many classes
        pass
    finally:
        _COMPLAINTS.local.caught = None
    return found


def first_tag(ifds: list[dict[int, Value]], tag: int) -> Value | None:
    """The value of ``tag`` in the first IFD that has it, else None."""
    return next((ifd[tag] for ifd in ifds if tag in ifd), None)

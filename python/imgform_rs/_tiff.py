"""Reading TIFF tags from the bytes of a TIFF-based raw file (DNG, KDC, NEF, ...).

rawpy exposes most of what LibRaw reads, but not everything LibRaw uses to
develop: the colour matrix some Kodak cameras store in tag 37400 and the DNG
black-level pattern larger than the 2x2 tile are two such values. This module
walks the IFDs LibRaw's TIFF parser walks (IFD0 and its successors, and the
SubIFDs they point to) and returns each IFD's tags decoded to numbers or text.
It never raises on malformed data: whatever cannot be read is left out.
"""

from __future__ import annotations

import struct

Value = str | tuple[float, ...]

# TIFF field type -> (struct code, bytes per value); rationals are two codes.
_TYPES = {
    1: ("B", 1),
    2: ("s", 1),
    3: ("H", 2),
    4: ("I", 4),
    5: ("II", 8),
    6: ("b", 1),
    7: ("B", 1),
    8: ("h", 2),
    9: ("i", 4),
    10: ("ii", 8),
    11: ("f", 4),
    12: ("d", 8),
    13: ("I", 4),
}
_SUB_IFDS = 330
# A corrupt file can chain IFDs in a loop or claim millions of them.
_MAX_IFDS = 64
_MAX_VALUES = 1 << 16


def _value(data: bytes, order: str, kind: int, count: int, field: int) -> Value | None:
    """The value of one IFD entry whose 12 bytes start at ``field``."""
    code, size = _TYPES[kind]
    if count > _MAX_VALUES:
        return None
    start = field + 8
    if size * count > 4:
        (start,) = struct.unpack_from(order + "I", data, start)
    raw = data[start : start + size * count]
    if len(raw) < size * count:
        return None
    if kind == 2:
        return raw.split(b"\0")[0].decode("latin-1").strip()
    nums = struct.unpack(f"{order}{count * len(code)}{code[0]}", raw)
    if len(code) == 2:
        return tuple(n / d if d else 0.0 for n, d in zip(nums[0::2], nums[1::2], strict=True))
    return tuple(float(n) for n in nums)


def _ifd(data: bytes, order: str, offset: int) -> tuple[dict[int, Value], int]:
    """The tags of the IFD at ``offset`` and the offset of the next IFD."""
    (count,) = struct.unpack_from(order + "H", data, offset)
    tags: dict[int, Value] = {}
    for i in range(count):
        field = offset + 2 + 12 * i
        tag, kind, n = struct.unpack_from(order + "HHI", data, field)
        if kind in _TYPES:
            value = _value(data, order, kind, n, field)
            if value is not None:
                tags[tag] = value
    (following,) = struct.unpack_from(order + "I", data, offset + 2 + 12 * count)
    return tags, following


def tiff_ifds(data: bytes) -> list[dict[int, Value]]:
    """Every IFD of a TIFF file, in the order LibRaw parses them.

    Parameters
    ----------
    data : bytes
        The whole file.

    Returns
    -------
    list of dict
        Tag number -> value (a str for ASCII, else a tuple of floats with
        rationals divided out); empty for a file that is not TIFF.
    """
    order = {b"II": "<", b"MM": ">"}.get(data[:2])
    if order is None or len(data) < 8:
        return []
    pending = [struct.unpack_from(order + "I", data, 4)[0]]
    seen: set[int] = set()
    found: list[dict[int, Value]] = []
    while pending and len(seen) < _MAX_IFDS:
        offset = pending.pop(0)
        if offset in seen or not 8 <= offset < len(data):
            continue
        seen.add(offset)
        try:
            tags, following = _ifd(data, order, offset)
        except struct.error:
            continue
        found.append(tags)
        subs = tags.get(_SUB_IFDS, ())
        pending = [int(s) for s in subs if isinstance(s, float)] + [following] + pending
    return found


def first_tag(ifds: list[dict[int, Value]], tag: int) -> Value | None:
    """The value of ``tag`` in the first IFD that has it, else None."""
    return next((ifd[tag] for ifd in ifds if tag in ifd), None)

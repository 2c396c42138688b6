"""Camera make and model from a CIFF raw: Canon's CRW files (1998-2004).

rawpy does not expose the camera names LibRaw reads, and the readers that
give them for TIFF-based raws (tifffile, Pillow, exifread) do not parse CIFF,
the heap format of Canon's raws before CR2. So this module reads the one
record that holds both names. A CIFF file is a header (byte order, header
length, ``HEAPCCDR``) and a heap that runs to the end of the file. A heap's
last four bytes give the offset of its table of records, each a 16-bit type,
a 32-bit length and a 32-bit offset from the heap's start. Records of two
data formats are heaps in their turn; the make and model are type 0x080A,
``"<make>\\0<model>\\0"``. It never raises on malformed data: whatever does
not fit is left out.
"""

from __future__ import annotations

import struct

_SIGNATURE = b"HEAPCCDR"
_MAKE_MODEL = 0x080A
# A record's bits 14-15 say where its value is (0: in the heap); bits 11-13
# its data format, of which these two are heaps within the heap.
_IN_RECORD = 0xC000
_FORMAT = 0x3800
_HEAPS = (0x2800, 0x3000)
_TYPE = 0x3FFF
_RECORD = 10  # bytes of a table entry
# Real files nest three heaps deep. A heap's records lie before its table,
# so heaps within it are smaller and the descent ends, but a corrupt file
# can list the same heap thousands of times at every level: the depth and
# the heaps read are capped.
_MAX_DEPTH = 8
_MAX_HEAPS = 256


def make_model(data: bytes) -> tuple[str, str]:
    """The camera's make and model in the CIFF file ``data``, or empty
    strings when it is not a CIFF file or holds no such record."""
    if len(data) < 14 or data[:2] not in (b"II", b"MM") or data[6:14] != _SIGNATURE:
        return "", ""
    order = "<" if data[:2] == b"II" else ">"
    (start,) = struct.unpack_from(order + "I", data, 2)
    value = _find(data, order, (start, len(data)), 0, [_MAX_HEAPS])
    if value is None:
        return "", ""
    names = [n.decode("latin-1").strip() for n in value.split(b"\0")]
    return (names + ["", ""])[0], (names + ["", ""])[1]


def _find(
    data: bytes, order: str, heap: tuple[int, int], depth: int, budget: list[int]
) -> bytes | None:
    """The make-and-model record's value in the heap ``data[start:end]`` or
    in the heaps it holds, depth first as they are listed."""
    start, end = heap
    budget[0] -= 1
    if depth > _MAX_DEPTH or budget[0] < 0 or not 0 <= start <= end - 4:
        return None
    (table,) = struct.unpack_from(order + "I", data, end - 4)
    at = start + table
    if at + 2 > end - 4:
        return None
    (count,) = struct.unpack_from(order + "H", data, at)
    if at + 2 + _RECORD * count > end - 4:
        return None
    for i in range(count):
        kind, length, offset = struct.unpack_from(order + "HII", data, at + 2 + _RECORD * i)
        lo, hi = start + offset, start + offset + length
        if kind & _IN_RECORD or hi > at:
            continue
        if kind & _TYPE == _MAKE_MODEL:
            return data[lo:hi]
        if kind & _FORMAT in _HEAPS:
            found = _find(data, order, (lo, hi), depth + 1, budget)
            if found is not None:
                return found
    return None

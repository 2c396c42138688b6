"""ICC profiles for the output colour spaces, built by LittleCMS.

Pillow's ``ImageCms`` can build only an sRGB profile, but the LittleCMS it
links (Pillow's wheels bundle it) builds any matrix/TRC RGB profile from a
white point, three primaries and three parametric curves
(``cmsCreateRGBProfile``). We call that library directly through ctypes, so
every byte of a profile is LittleCMS's: we only choose the numbers, those of
:mod:`imgform_rs.colorspace`. LittleCMS writes ICC v4 profiles (D50
connection space, its ``chad`` tag holding the Bradford adaptation from the
space's white).

A greyscale image gets a grey profile (``cmsCreateGrayProfile``: the tone
curve as ``grayTRC`` and the D50 media white point) rather than its space's
RGB profile, which libpng drops from a grey PNG ("iCCP: RGB color space not
permitted on grayscale PNG") and LittleCMS cannot apply to one channel, so
the tone curve would be lost.

XYZ and camera RGB get no profile: an ICC RGB profile needs real primaries
for RGB data, and PNG and JPEG embed only RGB or grey profiles.
"""

from __future__ import annotations

import ctypes
import functools
import struct
from typing import Any

from .colorspace import COLOR_SPACES

# ICC parametric curves, as LittleCMS numbers them. Each decodes (code value
# to linear light); type 1 is Y = X^g, type 4 (ICC's "type 3") is
# Y = (a X + b)^g for X >= d, else c X.
_POWER, _TOED = 1, 4
_CURVES: dict[str, tuple[int, tuple[float, ...]]] = {
    "linear": (_POWER, (1.0,)),
    "gamma22": (_POWER, (563 / 256,)),
    "srgb": (_TOED, (2.4, 1 / 1.055, 0.055 / 1.055, 1 / 12.92, 0.04045)),
    # The BT.709 OETF inverted: its knee 0.018 encodes to 4.5 * 0.018.
    "bt709": (_TOED, (1 / 0.45, 1 / 1.099, 0.099 / 1.099, 1 / 4.5, 0.081)),
    # ROMM: 16x below 1/512, whose code value is 1/32.
    "romm": (_TOED, (1.8, 1.0, 0.0, 1 / 16, 1 / 32)),
}
_DESC, _CPRT = 0x64657363, 0x63707274  # 'desc', 'cprt'
#: The profiles' creation date and time, ICC header bytes 24-35 (year, month,
#: day, hour, minute, second as big-endian u16). LittleCMS stamps the moment a
#: profile is made, so two processes (a batch's workers and the caller) wrote
#: files that differed in those bytes; a fixed date makes a profile, and every
#: file embedding it, the same bytes wherever and whenever it is made.
_CREATED = struct.pack(">6H", 2026, 1, 1, 0, 0, 0)
_CREATED_AT = 24


class _XyY(ctypes.Structure):
    _fields_ = [("x", ctypes.c_double), ("y", ctypes.c_double), ("Y", ctypes.c_double)]


class _XyYTriple(ctypes.Structure):
    _fields_ = [("red", _XyY), ("green", _XyY), ("blue", _XyY)]


@functools.cache
def _lcms() -> Any:
    """LittleCMS, as linked by Pillow's colour-management extension (its
    symbols resolve through the extension's own dependencies)."""
    from PIL import _imagingcms

    lib = ctypes.CDLL(_imagingcms.__file__)
    vp, u32 = ctypes.c_void_p, ctypes.c_uint32
    signatures = {
        "cmsBuildParametricToneCurve": (vp, [vp, ctypes.c_int32, ctypes.POINTER(ctypes.c_double)]),
        "cmsFreeToneCurve": (None, [vp]),
        "cmsCreateRGBProfile": (vp, [ctypes.POINTER(_XyY), ctypes.POINTER(_XyYTriple), vp * 3]),
        "cmsCreateGrayProfile": (vp, [ctypes.POINTER(_XyY), vp]),
        "cmsD50_xyY": (ctypes.POINTER(_XyY), []),
        "cmsMLUalloc": (vp, [vp, u32]),
        "cmsMLUsetASCII": (ctypes.c_int, [vp, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p]),
        "cmsMLUfree": (None, [vp]),
        "cmsWriteTag": (ctypes.c_int, [vp, u32, vp]),
        "cmsMD5computeID": (ctypes.c_int, [vp]),
        "cmsSaveProfileToMem": (ctypes.c_int, [vp, vp, ctypes.POINTER(u32)]),
        "cmsOpenProfileFromMem": (vp, [ctypes.c_char_p, u32]),
        "cmsCloseProfile": (ctypes.c_int, [vp]),
    }
    for name, (restype, argtypes) in signatures.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    return lib


def _text(lib: Any, profile: int, tag: int, text: str) -> None:
    mlu = lib.cmsMLUalloc(None, 1)
    try:
        lib.cmsMLUsetASCII(mlu, b"en", b"US", text.encode("ascii"))
        lib.cmsWriteTag(profile, tag, mlu)
    finally:
        lib.cmsMLUfree(mlu)


@functools.cache
def icc_profile(color: str, tone: str, *, grey: bool = False) -> bytes | None:
    """The ICC profile of RGB ``color`` encoded with ``tone``, or with
    ``grey`` that of its greys (a grey profile: the curve alone); None for a
    space that has none (XYZ, camera RGB; see the module docstring)."""
    space = COLOR_SPACES.get(color)
    if space is None or space.primaries is None or tone not in _CURVES:
        return None
    lib = _lcms()
    kind, params = _CURVES[tone]
    curve = lib.cmsBuildParametricToneCurve(None, kind, (ctypes.c_double * len(params))(*params))
    if not curve:
        raise RuntimeError(f"LittleCMS could not build the {tone} curve")
    if grey:
        # A grey profile has no chromatic adaptation tag: its white is the
        # connection space's D50, the white every v4 profile adapts to, so a
        # grey of any space's white point shows neutral.
        title = f"{space.title} grey"
        profile = lib.cmsCreateGrayProfile(lib.cmsD50_xyY(), curve)
    else:
        title = space.title
        white = _XyY(*space.white, 1.0)
        primaries = _XyYTriple(*(_XyY(x, y, 1.0) for x, y in space.primaries))
        profile = lib.cmsCreateRGBProfile(
            ctypes.byref(white), ctypes.byref(primaries), (ctypes.c_void_p * 3)(curve, curve, curve)
        )
    lib.cmsFreeToneCurve(curve)
    if not profile:
        raise RuntimeError(f"LittleCMS could not build a profile for {title}")
    try:
        encoding = "linear" if tone == "linear" else f"{tone} curve"
        _text(lib, profile, _DESC, f"{title}, {encoding} (imgform-rs)")
        _text(lib, profile, _CPRT, "No copyright, use freely")
        stamped = _save(lib, profile, title)
    finally:
        lib.cmsCloseProfile(profile)
    # LittleCMS has no setter for the date: it reads it back from the header.
    end = _CREATED_AT + len(_CREATED)
    dated = stamped[:_CREATED_AT] + _CREATED + stamped[end:]
    profile = lib.cmsOpenProfileFromMem(dated, len(dated))
    if not profile:
        raise RuntimeError(f"LittleCMS could not read back the {title} profile")
    try:
        lib.cmsMD5computeID(profile)
        return _save(lib, profile, title)
    finally:
        lib.cmsCloseProfile(profile)


def _save(lib: Any, profile: int, title: str) -> bytes:
    size = ctypes.c_uint32(0)
    lib.cmsSaveProfileToMem(profile, None, ctypes.byref(size))
    buffer = ctypes.create_string_buffer(size.value)
    if not lib.cmsSaveProfileToMem(profile, buffer, ctypes.byref(size)):
        raise RuntimeError(f"LittleCMS could not write the {title} profile")
    return buffer.raw[: size.value]

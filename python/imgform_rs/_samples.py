"""Sample dtypes beyond the kernels' three, converted on the way in and back out.

The Rust kernels take uint8, uint16 and float32. Users hold other arrays:
scikit-image's ``img_as_float`` gives float64, and integer data often arrive as
int32 or int64 (a raw read by a generic TIFF reader, a NumPy sum). They are
accepted where the conversion is lossless or documented:

- other integers (int8..int64, uint32, uint64, non-native byte order) whose
  values all lie in 0..65535 go through uint16 exactly, and the result comes
  back in the input's dtype, clamped to ``[0, min(dtype max, 65535)]`` (the
  uint16 kernel's rounding and clamping, the narrower top of int8 / uint8
  inputs included); negative or larger values raise ValueError, since a
  shift or scale would be a guess;
- float16 goes through float32 exactly; float64 through float32, so the result
  (returned as float64) carries float32's precision, about 7 significant digits
  (relative error below 6e-8, far under any sensor's noise); a finite float64
  beyond float32's range raises ValueError instead of becoming an infinity.

bool and complex arrays are refused with TypeError: neither is a sample.
"""

from __future__ import annotations

from typing import Any

import numpy as np

NATIVE = (np.dtype(np.uint8), np.dtype(np.uint16), np.dtype(np.float32))
"""The dtypes the kernels take as they are."""

ACCEPTED = "an integer or float array (uint8, uint16, float32 natively, others converted)"

_U16_MAX = np.iinfo(np.uint16).max
F32_MAX = float(np.finfo(np.float32).max)
"""The largest finite float32."""
F32_TINY = float(np.finfo(np.float32).tiny)
"""The smallest normal float32."""


def check_dtype(dtype: np.dtype, name: str) -> None:
    """TypeError unless ``dtype`` holds real samples."""
    if np.dtype(dtype).kind not in "iuf":
        raise TypeError(f"{name} must be {ACCEPTED}, got dtype {dtype}")


def as_array(value: Any, name: str) -> np.ndarray:
    """``value`` as an array of real samples, TypeError for anything else."""
    if value is None:
        raise TypeError(f"{name} must be {ACCEPTED}, got None")
    arr = np.asarray(value)
    check_dtype(arr.dtype, name)
    return arr


def kernel_dtype(dtype: np.dtype) -> np.dtype:
    """The dtype the kernels run a ``dtype`` input in."""
    dtype = np.dtype(dtype)
    if dtype in NATIVE:
        return dtype
    return NATIVE[2] if dtype.kind == "f" else NATIVE[1]


def check_range(lo: float, hi: float, dtype: np.dtype, name: str) -> None:
    """ValueError if values from ``lo`` to ``hi`` of ``dtype`` do not convert
    to :func:`kernel_dtype` as the module docstring promises."""
    dtype = np.dtype(dtype)
    if dtype in NATIVE or (dtype.kind == "f" and dtype.itemsize <= 4):
        return
    if dtype.kind in "iu" and (lo < 0 or hi > _U16_MAX):
        raise ValueError(
            f"{name} ({dtype}) must hold values in 0..{_U16_MAX} to be processed exactly as "
            f"uint16, got {lo}..{hi}; offset or scale it, or pass float32"
        )
    # NaN compares false and is left to the kernels' own check.
    if dtype.kind == "f" and max(-lo, hi) > F32_MAX and np.isfinite(max(-lo, hi)):
        raise ValueError(
            f"{name} ({dtype}) holds {lo}..{hi}, beyond float32's range (±{F32_MAX:.3e})"
        )


def to_kernel(arr: np.ndarray, name: str) -> np.ndarray:
    """``arr`` in :func:`kernel_dtype`, checked by :func:`check_range`."""
    target = kernel_dtype(arr.dtype)
    if arr.dtype == target:
        return arr
    if arr.size:
        finite = arr[np.isfinite(arr)] if arr.dtype.kind == "f" else arr
        if finite.size:
            check_range(finite.min(), finite.max(), arr.dtype, name)
    return arr.astype(target)


def from_kernel(result: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """A kernel's result back in the input's ``dtype`` (see the module docstring)."""
    dtype = np.dtype(dtype)
    if result.dtype == dtype:
        return result
    if dtype.kind in "iu":
        top = min(int(np.iinfo(dtype).max), _U16_MAX)
        result = np.minimum(result, np.array(top, result.dtype))
    elif dtype.kind == "f" and dtype.itemsize < result.dtype.itemsize:
        # An overshoot past float16's largest number (65504) stays finite.
        top = np.array(np.finfo(dtype).max, result.dtype)
        result = np.clip(result, -top, top)
    return result.astype(dtype)


def fill_out(out: Any, result: np.ndarray, source: np.ndarray) -> np.ndarray:
    """Copies ``result`` into a caller's ``out``, after the checks the native
    layer makes for its own dtypes."""
    if not isinstance(out, np.ndarray) or out.dtype != result.dtype:
        got = f"dtype {out.dtype}" if isinstance(out, np.ndarray) else type(out).__name__
        raise TypeError(f"out must be an array of dtype {result.dtype}, got {got}")
    if out.shape != result.shape:
        raise ValueError(f"out must have shape {list(result.shape)}, got {list(out.shape)}")
    if not out.flags.c_contiguous:
        raise ValueError("out must be C-contiguous")
    if not out.flags.writeable:
        raise ValueError("out is not writeable")
    if np.shares_memory(out, source):
        raise ValueError("out must share no memory with the input")
    out[...] = result
    return out

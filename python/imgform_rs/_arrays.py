"""Input coercion shared by the public facade.

The native layer checks everything again; this layer turns the convenient forms
users pass (lists, a single point, int or float32 arrays) into the float64,
C-contiguous arrays the kernels take, and says clearly what it refused.
"""

from __future__ import annotations

import numbers
from typing import Any

import numpy as np
import numpy.typing as npt

Float64Array = npt.NDArray[np.float64]


def _numeric(value: Any, name: str) -> np.ndarray:
    if value is None:
        raise TypeError(f"{name} must be an array of numbers, got None")
    arr = np.asarray(value)
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"{name} must be an array of real numbers, got dtype {arr.dtype}")
    return arr


def as_points(points: Any, dim: int, name: str = "points") -> tuple[Float64Array, bool]:
    """Returns ``points`` as a contiguous float64 (N, dim) array, and whether a
    single point of shape (dim,) was given (the caller then returns one point)."""
    arr = _numeric(points, name)
    single = arr.ndim == 1
    if single:
        arr = arr.reshape(1, -1)
    if arr.ndim != 2 or arr.shape[1] != dim:
        raise ValueError(f"{name} must have shape (N, {dim}) or ({dim},), got {np.shape(points)}")
    return np.ascontiguousarray(arr, dtype=np.float64), single


def unbatch(out: Float64Array, single: bool) -> Float64Array:
    """Undoes the batching of a single point."""
    return out[0] if single else out


def as_matrix(value: Any, shape: tuple[int, ...], name: str) -> Float64Array:
    """A float64 array of exactly ``shape`` with finite entries."""
    arr = _numeric(value, name).astype(np.float64)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must contain only finite numbers, got {arr.tolist()}")
    return np.ascontiguousarray(arr)


def native(value: Any) -> np.ndarray:
    """``value`` as an array in this machine's byte order: big-endian data
    (a FITS or TIFF read as it is) keeps its values, and a check of its
    dtype against ``np.uint16`` no longer refuses the uint16 it is."""
    arr = np.asarray(value)
    return arr if arr.dtype.isnative else arr.astype(arr.dtype.newbyteorder("="))


def require_finite(arr: np.ndarray, name: str) -> None:
    """A ValueError naming the first NaN or infinity of a float ``arr`` and
    its index (integer arrays hold none)."""
    if arr.dtype.kind == "f" and not np.isfinite(arr).all():
        at = tuple(int(i) for i in np.argwhere(~np.isfinite(arr))[0])
        raise ValueError(f"{name} must hold finite numbers, got {arr[at]} at index {at}")


def as_real(value: Any, name: str, dtype: Any) -> np.ndarray:
    """An array of real numbers in ``dtype`` (no copy when it is one); bool,
    complex and object arrays are a TypeError, where a cast would read True
    as 1, drop an imaginary part or parse strings."""
    return _numeric(value, name).astype(dtype, copy=False)


def as_float_array(value: Any, name: str) -> Float64Array:
    """Any real scalar or array as float64, for the vectorised optics formulas."""
    return _numeric(value, name).astype(np.float64, copy=False)


def _scalar(value: Any) -> Any:
    """The number a 0-d real array holds (what ``np.sum`` or an index into an
    array may give); anything else as it is."""
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        return value[()]
    return value


def real(value: Any, name: str) -> float:
    """``value`` as a float when it is one real number: a Python or NumPy int
    or float, a 0-d real array. A TypeError naming ``name`` for anything else,
    where ``float()`` would parse the str ``"1e4"``, read ``True`` as 1, or
    fail with a message that names no parameter. An int beyond float64's
    range is ``inf``, which the callers' range checks then refuse."""
    number = _scalar(value)
    if isinstance(number, bool) or not isinstance(number, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {value!r}")
    try:
        return float(number)
    except OverflowError:
        return float("-inf") if number < 0 else float("inf")


def flag(value: Any, name: str) -> bool:
    """A switch checked to be a bool: a str such as ``"no"`` is truthy and
    would silently switch it on."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be a bool, got {value!r}")
    return bool(value)


def is_int(value: Any) -> bool:
    """Whether ``value`` is an int (a NumPy one too), and not a bool."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def integer(value: Any, name: str) -> int:
    """``value`` as an int when it is one (a NumPy int or 0-d integer array
    too, not a bool); a TypeError naming ``name`` otherwise, where ``int()``
    would truncate 1.5 and ``operator.index`` name no parameter."""
    number = _scalar(value)
    if not is_int(number):
        raise TypeError(f"{name} must be an integer, got {value!r}")
    return int(number)


def as_seed(value: Any, name: str) -> int:
    """``value`` as a seed of the native generators: an int in [0, 2**64),
    checked here because the native layer would raise OverflowError."""
    if not (is_int(value) and 0 <= value < 2**64):
        raise ValueError(f"{name} must be an int in [0, 2**64), got {value!r}")
    return int(value)

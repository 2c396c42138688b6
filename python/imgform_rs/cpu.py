"""Which vector instructions the kernels use, and how to cap them.

The kernels pick, at run time, the widest build the CPU has: AVX-512 with
Intel's AMX tiles (Xeons since Sapphire Rapids, on Linux), AVX-512, AVX2
with FMA, or the baseline. The ``IMGFORM_ISA`` environment variable, read
once when the first kernel asks, caps that choice at ``baseline``, ``avx2``,
``avx512`` or ``amx``. Every build gives the same bits (each kernel's tests compare
them), so the cap changes only the speed: on a wide machine it times what a
narrower one runs, e.g. ``IMGFORM_ISA=avx2 python benchmarks/lens.py``.
"""

from __future__ import annotations

import os
import warnings

from . import _native

__all__ = ["instruction_set"]


def instruction_set() -> str:
    """The widest instruction set the kernels run here, within the cap.

    Returns
    -------
    str
        ``"baseline"``, ``"avx2"``, ``"avx512"`` or ``"amx"``.

    Examples
    --------
    >>> from imgform_rs import instruction_set
    >>> instruction_set() in ("baseline", "avx2", "avx512", "amx")
    True
    """
    return str(_native.instruction_set())


def _check_cap() -> None:
    """Warns when ``IMGFORM_ISA`` names no level (the kernels then ignore it)."""
    asked = os.environ.get("IMGFORM_ISA")
    names = list(_native.instruction_sets())
    if asked is not None and asked.strip().lower() not in names:
        warnings.warn(
            f"IMGFORM_ISA={asked!r} is not one of {names}; the kernels ignore it "
            "and use the widest instruction set this CPU has",
            RuntimeWarning,
            stacklevel=3,
        )


_check_cap()

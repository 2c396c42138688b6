"""Lateral chromatic aberration (lecture section 3.3).

Glass bends short wavelengths more, so a lens images red, green and blue at
slightly different magnifications and colour fringes grow towards the corners.
Modelled as a radial magnification of red and blue about the optical centre
relative to green, which is left untouched. Resampling, borders and rounding
are those of :func:`imgform_rs.remap`.
"""

from __future__ import annotations

from typing import Any

from . import _native
from ._arrays import real
from .remap import ImageT, Interpolation


def _center(center: Any) -> tuple[float, float] | None:
    if center is None:
        return None
    try:
        cx, cy = center
    except (TypeError, ValueError):
        raise ValueError(f"center must be a pair (cx, cy) in pixels, got {center!r}") from None
    return real(cx, "center[0]"), real(cy, "center[1]")


def _lateral_ca(
    image: ImageT,
    scale_r: Any,
    scale_b: Any,
    center: Any,
    inverse: bool,
    interpolation: Interpolation,
    fill: Any,
) -> ImageT:
    """The native resampling of both directions, with the numbers checked
    here (a str is named, not parsed; a bool is no scale)."""
    scales = real(scale_r, "scale_r"), real(scale_b, "scale_b")
    return _native.lateral_ca(
        image, *scales, _center(center), inverse, interpolation, real(fill, "fill")
    )


def add_lateral_ca(
    image: ImageT,
    scale_r: float,
    scale_b: float,
    center: Any = None,
    *,
    interpolation: Interpolation = "bilinear",
    fill: float = 0,
) -> ImageT:
    """Render lateral chromatic aberration into an RGB image.

    Red is magnified by ``scale_r`` and blue by ``scale_b`` about ``center``
    (a feature at radius ``r`` moves to ``scale * r``); green is copied.

    Parameters
    ----------
    image : ndarray (H, W, 3), uint8, uint16 or float32
        R, G, B order (OpenCV's BGR images: swap the scales).
    scale_r, scale_b : float
        Magnifications relative to green, finite and > 0 (typically within
        0.1 % of 1).
    center : (cx, cy), optional
        Optical centre in pixels (column, row), e.g. ``(K[0, 2], K[1, 2])``;
        default the image centre ``((W - 1) / 2, (H - 1) / 2)``.
    interpolation : {"bilinear", "bicubic"}
    fill : float
        Value read outside the image (where a channel shrinks, ``scale < 1``,
        its outermost ring samples beyond the edge); finite, held exactly by
        the dtype, as in :func:`imgform_rs.remap`.

    Returns
    -------
    ndarray
        Same shape and dtype.

    Raises
    ------
    TypeError
        Unsupported dtype; a scale, centre coordinate or ``fill`` that is not
        a real number.
    ValueError
        Not (H, W, 3); a scale that is NaN, infinite or <= 0; a bad centre.

    Examples
    --------
    >>> import numpy as np
    >>> img = np.zeros((5, 5, 3), np.float32)
    >>> img[2, 3] = 1.0
    >>> out = add_lateral_ca(img, 2.0, 1.0)
    >>> float(out[2, 4, 0]), float(out[2, 3, 1])
    (1.0, 1.0)
    """
    return _lateral_ca(image, scale_r, scale_b, center, False, interpolation, fill)


def correct_lateral_ca(
    image: ImageT,
    scale_r: float,
    scale_b: float,
    center: Any = None,
    *,
    interpolation: Interpolation = "bilinear",
    fill: float = 0,
) -> ImageT:
    """Remove the aberration :func:`add_lateral_ca` renders: red is magnified
    by exactly ``1 / scale_r`` and blue by ``1 / scale_b`` about ``center``.
    Parameters as :func:`add_lateral_ca` (the same scales, not their inverses).

    Examples
    --------
    >>> import numpy as np
    >>> img = np.zeros((5, 5, 3), np.float32)
    >>> img[2, 4, 0] = 1.0
    >>> float(correct_lateral_ca(img, 2.0, 1.0)[2, 3, 0])
    1.0
    """
    return _lateral_ca(image, scale_r, scale_b, center, True, interpolation, fill)

"""Projection models of lecture section 2.1: pinhole and orthographic."""

from __future__ import annotations

from typing import Any

from . import _native
from ._arrays import Float64Array, as_points, flag, real, unbatch


def project_pinhole(points: Any, f: float, *, invert: bool = True) -> Float64Array:
    """Project camera-frame points through a pinhole (eq. 1-2).

    Parameters
    ----------
    points : array_like, shape (N, 3) or (3,)
        Points ``(x, y, z)`` in the camera frame (x right, y down, z forward).
    f : float
        Distance from the pinhole to the image plane, > 0.
    invert : bool
        ``True`` (default) gives the real, inverted image behind the pinhole,
        exactly ``x' = -f x / z``, ``y' = -f y / z``. ``False`` gives the upright
        virtual image plane in front of it, ``x' = f x / z``.

    Returns
    -------
    ndarray, float64, shape (N, 2) or (2,)
        Image-plane coordinates in the units of ``f``. Points with ``z <= 0``
        (at or behind the pinhole) have no image and come back as NaN.

    Raises
    ------
    TypeError
        ``points`` is not numeric, or ``f`` not a real number.
    ValueError
        Wrong shape, non-finite coordinates, or ``f`` not finite and positive.

    Examples
    --------
    >>> project_pinhole([[1.0, 2.0, 4.0]], f=2.0)
    array([[-0.5, -1. ]])
    """
    arr, single = as_points(points, 3)
    return unbatch(_native.project_pinhole(arr, real(f, "f"), flag(invert, "invert")), single)


def project_orthographic(points: Any, *, scale: float = 1.0) -> Float64Array:
    """Project points orthographically: ``(x, y, z) -> (scale x, scale y)`` (eq. 3).

    It is the limit of :func:`project_pinhole` (upright) as ``z -> inf`` with
    ``f / z`` held at ``scale``: telephoto lenses far from their subject.

    Examples
    --------
    >>> project_orthographic([1.0, -2.0, 9.0], scale=0.5)
    array([ 0.5, -1. ])
    """
    arr, single = as_points(points, 3)
    return unbatch(_native.project_orthographic(arr, real(scale, "scale")), single)

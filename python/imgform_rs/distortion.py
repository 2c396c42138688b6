"""Lens distortion of points (lecture section 3.3): Brown-Conrady and division models."""

from __future__ import annotations

from typing import Any, Literal

import numpy as np

from . import _native
from ._arrays import Float64Array, as_float_array, as_matrix, as_points, unbatch

DistortionModel = Literal["brown_conrady", "division"]


def lens_coefficients(dist: Any) -> list[float]:
    """Distortion coefficients as a flat list (OpenCV's ``(1, n)`` arrays accepted)."""
    if dist is None:
        return []
    return [float(c) for c in as_float_array(dist, "dist").ravel()]


def model_name(model: Any) -> str:
    """``model`` checked to be a name (the kernels refuse names they do not
    know, and list theirs): a None got an error about "model_name"."""
    if not isinstance(model, str):
        raise TypeError(
            f'model must be a distortion model\'s name ("brown_conrady" or "division"), '
            f"got {model!r}"
        )
    return model


def _remap(points: Any, dist: Any, K: Any, model: str, undistort: bool):
    arr, single = as_points(points, 2)
    k = None if K is None else as_matrix(K, (3, 3), "K")
    coeffs = lens_coefficients(dist)
    out, failed = _native.remap_lens_points(arr, coeffs, model_name(model), k, undistort)
    return unbatch(out, single), failed


def distort_points(
    points: Any, dist: Any, *, K: Any = None, model: DistortionModel = "brown_conrady"
) -> Float64Array:
    """Move ideal (pinhole) image points to where the distorting lens puts them.

    Parameters
    ----------
    points : array_like, shape (N, 2) or (2,)
        Pixels ``(u, v)`` when ``K`` is given, else normalised coordinates
        ``(x / z, y / z)``.
    dist : array_like
        ``"brown_conrady"``: 4, 5 or 8 coefficients in OpenCV's order
        ``(k1, k2, p1, p2[, k3[, k4, k5, k6]])``; ``"division"``: one ``lambda``
        (``x_u = x_d / (1 + lambda r_d^2)``, negative for barrel).
    K : array_like (3, 3), optional
        Intrinsics; points are then in pixels.

    Returns
    -------
    ndarray, float64, same shape as ``points``
        NaN where the model has no image: beyond its fold, where a
        Brown-Conrady polynomial turns back or the division model has no root.

    Examples
    --------
    >>> distort_points([0.5, 0.0], [-0.2, 0.0, 0.0, 0.0])
    array([0.475, 0.   ])
    """
    return _remap(points, dist, K, model, undistort=False)[0]


def undistort_points(
    points: Any,
    dist: Any,
    *,
    K: Any = None,
    model: DistortionModel = "brown_conrady",
    return_converged: bool = False,
) -> Float64Array | tuple[Float64Array, np.ndarray]:
    """Invert :func:`distort_points` numerically (Newton's method, to 1e-14 in
    normalised units, i.e. far below 1e-9 px).

    Points where the inverse does not converge, or where it would land beyond
    the fold of the model (where the lens maps two ideal points onto one and
    the inverse is ambiguous), come back as NaN instead of a wrong value. With
    ``return_converged=True`` a boolean mask of the good points is returned too.

    Examples
    --------
    >>> p = undistort_points([0.475, 0.0], [-0.2, 0.0, 0.0, 0.0])
    >>> bool(abs(p[0] - 0.5) < 1e-12)
    True
    """
    out, _ = _remap(points, dist, K, model, undistort=True)
    if return_converged:
        return out, ~np.isnan(out[..., 0])
    return out

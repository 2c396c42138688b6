"""Single-view metrology (lecture section 2.1, item 5): measuring from one image.

Parallel lines of the world meet in the image at their vanishing point; the
vanishing points of two horizontal directions span the horizon, the ground
plane's vanishing line. With the horizon and the vertical vanishing point, the
heights of objects standing on the ground can be compared through a cross ratio
(Criminisi, Reid, Zisserman, "Single view metrology", IJCV 2000): one object of
known height measures them all, and the camera's own height, without knowing
the camera.

Points are pixels ``(u, v)`` (column, row; y down), as in ``docs/conventions.rst``.
A vanishing point may be given as a pixel ``(2,)``, a homogeneous point ``(3,)``
(``(du, dv, 0)`` is at infinity), or the result of :func:`fit_vanishing_point` or
:func:`imgform_rs.vanishing_point`. Lines are homogeneous ``(a, b, c)``:
``a u + b v + c = 0``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from . import _native
from ._arrays import Float64Array, as_float_array, as_matrix, as_points, as_seed, flag, real

BoolArray = npt.NDArray[np.bool_]


class VanishingPointFit(NamedTuple):
    """A vanishing point fitted to image line segments.

    Attributes
    ----------
    point : ndarray, float64, shape (2,)
        Pixel ``(u, v)`` of the vanishing point; NaN when ``at_infinity``.
    homogeneous : ndarray, float64, shape (3,)
        ``(u, v, 1)``; at infinity ``(du, dv, 0)`` with ``du² + dv² = 1``, the
        common image direction of the parallel lines (``du > 0``, or ``dv > 0``
        when ``du = 0``). Pass it to :func:`fit_horizon` or as ``vertical_vp``.
    residual : float
        Root-mean-square distance in pixels of the inliers' end points from
        the lines through their midpoints and the vanishing point.
    inliers : ndarray, bool, shape (N,)
        Segments within ``threshold`` of the vanishing point.
    at_infinity : bool
        ``True`` when the lines are parallel in the image (only with
        ``allow_infinite=True``; otherwise that is an error).
    """

    point: Float64Array
    homogeneous: Float64Array
    residual: float
    inliers: BoolArray
    at_infinity: bool


def _homogeneous(value: Any, name: str) -> Float64Array:
    """A finite homogeneous point (3,) from a pixel (2,), a homogeneous point
    (3,), or anything with a ``homogeneous`` attribute (a vanishing point)."""
    value = getattr(value, "homogeneous", value)
    arr = as_float_array(value, name)
    if arr.shape == (2,):
        arr = np.append(arr, 1.0)
    if arr.shape != (3,):
        raise ValueError(
            f"{name} must be a pixel (2,), a homogeneous point (3,) or a vanishing point, "
            f"got shape {arr.shape}"
        )
    arr = as_matrix(arr, (3,), name)
    # Its scale is free: a largest component of 1 keeps products finite.
    largest = np.abs(arr).max()
    return arr / largest if largest > 0 else arr


def _pixel(value: Any, name: str) -> Float64Array:
    return as_matrix(value, (2,), name)


def fit_vanishing_point(
    segments: Any,
    *,
    threshold: float = 2.0,
    seed: int = 0,
    allow_infinite: bool = False,
) -> VanishingPointFit:
    """The least-squares vanishing point of image line segments, robust to
    outliers.

    A segment agrees with a vanishing point ``v`` when the line through its
    midpoint and ``v`` passes through its end points; the residual is the
    distance in pixels of an end point from that line (Rother 2002, Tardif
    2009: close to the maximum-likelihood residual for end-point noise).
    Segments are not weighted by length: the same angular error already moves
    a long segment's end points further, so it counts for more.

    Robustness is RANSAC: every pair of segments proposes the intersection of
    their lines, scored by MSAC (``sum min(r², threshold²)``). Up to 63
    segments all pairs are tried, so the result does not depend on ``seed``;
    above, 2000 pairs are drawn from a generator keyed by ``seed`` and the
    hypothesis index. The winner is refined by Levenberg-Marquardt on its
    inliers (inliers re-selected until they settle). RANSAC rather than IRLS
    because IRLS starts from the plain least-squares point, which one wild
    segment can drag arbitrarily far. Fitting runs in Hartley-normalised
    coordinates with a homogeneous unit vector, so nearly parallel lines
    (a vanishing point far away) stay well conditioned. The result is the same
    for any number of threads.

    Parameters
    ----------
    segments : array_like, shape (N, 4)
        ``[x1, y1, x2, y2]`` per segment, pixels; ``N >= 2``.
    threshold : float
        Largest residual of an inlier, pixels (> 0). The default suits
        end-point noise up to ~0.7 px.
    seed : int
        Seed of the hypothesis sampler (0 <= seed < 2**64); only used above
        63 segments.
    allow_infinite : bool
        Return parallel image lines' vanishing point at infinity (``point``
        NaN, ``homogeneous = (du, dv, 0)``) instead of raising. A point counts
        as at infinity when its homogeneous ``z`` is below 1e-10 of its length
        in normalised coordinates (lines meeting at under ~1e-10 rad).

    Returns
    -------
    VanishingPointFit
        ``(point, homogeneous, residual, inliers, at_infinity)``.

    Raises
    ------
    TypeError
        Non-numeric segments, a ``threshold`` that is not a real number.
    ValueError
        Not (N, 4), fewer than 2 segments, non-finite or zero-length segments,
        all segments on one image line, fewer than 2 inliers, a non-positive
        threshold, a bad seed, or parallel lines without ``allow_infinite``.

    Examples
    --------
    >>> segs = [[0, 0, 100, 50], [0, 100, 100, 100], [0, 200, 100, 150]]
    >>> fit = fit_vanishing_point(segs)
    >>> fit.point.round(9), round(fit.residual, 9), fit.inliers
    (array([200., 100.]), 0.0, array([ True,  True,  True]))
    """
    arr, _ = as_points(segments, 4, "segments")
    seed_int = as_seed(seed, "seed")
    homogeneous, at_infinity, residual, inliers = _native.fit_vanishing_point(
        arr, real(threshold, "threshold"), seed_int, flag(allow_infinite, "allow_infinite")
    )
    h = np.array(homogeneous)
    point = np.full(2, np.nan) if at_infinity else h[:2].copy()
    return VanishingPointFit(point, h, residual, inliers, at_infinity)


def fit_horizon(vp1: Any, vp2: Any) -> Float64Array:
    """The horizon: the vanishing line through the vanishing points of two
    horizontal (ground-plane) directions.

    ``l = vp1 × vp2``, scaled so that ``a² + b² = 1`` and ``b < 0`` (``a < 0``
    when ``b = 0``). Then ``a u + b v + c`` is the signed distance in pixels of
    ``(u, v)`` from the horizon, positive above it: the same line and sign as
    :func:`imgform_rs.vanishing_line` of the ground's up normal for a camera
    whose image up points to the sky (roll under 90°). Either point may be at
    infinity; two points at infinity give the line at infinity ``(0, 0, 1)``
    (a camera looking straight down).

    Parameters
    ----------
    vp1, vp2 : array_like, shape (2,) or (3,), or a vanishing point
        Pixels, homogeneous points, or :class:`VanishingPointFit` /
        :class:`imgform_rs.VanishingPoint` results.

    Returns
    -------
    ndarray, float64, shape (3,)
        ``(a, b, c)``.

    Raises
    ------
    TypeError
        Non-numeric input.
    ValueError
        Wrong shapes, non-finite or zero vectors, or coincident points.

    Examples
    --------
    >>> fit_horizon([100.0, 240.0], [900.0, 240.0]).round(9) + 0.0
    array([  0.,  -1., 240.])
    """
    return np.array(_native.fit_horizon(_homogeneous(vp1, "vp1"), _homogeneous(vp2, "vp2")))


def _ground(
    horizon: Any, vertical_vp: Any, ref_base: Any, ref_top: Any, ref_height: float
) -> tuple[Float64Array, Float64Array, Float64Array, Float64Array, float]:
    return (
        as_matrix(horizon, (3,), "horizon"),
        _homogeneous(vertical_vp, "vertical_vp"),
        _pixel(ref_base, "ref_base"),
        _pixel(ref_top, "ref_top"),
        real(ref_height, "ref_height"),
    )


def relative_height(
    horizon: Any,
    base: Any,
    top: Any,
    ref_base: Any,
    ref_top: Any,
    ref_height: float = 1.0,
    *,
    vertical_vp: Any,
) -> Float64Array | float:
    """Heights of objects standing on the ground plane, measured against a
    reference object of known height (Criminisi, Reid, Zisserman 2000).

    With the horizon ``l`` and the vertical vanishing point ``v``, an object
    from ground point ``b`` up to ``t`` has ``Z ∝ g(b, t) = ((b × t) · (v × t))
    / ((l · b) |v × t|²)`` (homogeneous pixels ``(u, v, 1)``): the cross ratio of
    ``b``, ``t``, ``v`` and the point where the line meets the horizon, with
    the unknown camera factor cancelled by the reference,
    ``Z = ref_height g(b, t) / g(ref_base, ref_top)``. When noise leaves ``b``,
    ``t`` and ``v`` off one line, ``g`` is the least-squares ratio. Heights are
    signed: a top below the base (in the world) gives a negative height. It
    needs no camera calibration; the horizon and ``v`` may be at infinity
    (an affine view, a camera looking straight down).

    ``vertical_vp`` is required: the construction needs the vertical vanishing
    point in general, and guessing it (say, from the object lines themselves)
    would hide the assumption. Fit it to vertical edges with
    :func:`fit_vanishing_point` (``allow_infinite=True`` for a level camera,
    whose verticals stay parallel), or take ``vanishing_point(camera, up)``.

    Parameters
    ----------
    horizon : array_like, shape (3,)
        The ground's vanishing line ``(a, b, c)``, any scale and sign
        (:func:`fit_horizon`, :func:`imgform_rs.vanishing_line`).
    base, top : array_like, shape (N, 2) or (2,)
        Pixels of the objects' ground contact points and tops.
    ref_base, ref_top : array_like, shape (2,)
        Pixels of the reference object's base and top.
    ref_height : float
        The reference's height (> 0); results come in its unit.
    vertical_vp : array_like, shape (2,) or (3,), or a vanishing point
        The vertical vanishing point.

    Returns
    -------
    ndarray, float64, shape (N,), or float for a single object

    Raises
    ------
    TypeError
        Non-numeric input.
    ValueError
        Wrong shapes; non-finite values; a base on the horizon (infinitely far,
        its height undetermined), a top at the vertical vanishing point, a
        vertical vanishing point on the horizon, a reference of zero image
        height, or ``ref_height <= 0``. The message names the object.

    Examples
    --------
    A level camera 1.5 m above the ground (horizon at row 240, verticals
    parallel); a 2 m reference pole 10 m away, and a pole 4 m away:

    >>> h = relative_height([0, -1, 240], [100, 427.5], [100, 340], [300, 315],
    ...                     [300, 215], 2.0, vertical_vp=[0, 1, 0])
    >>> round(h, 9)
    0.7
    """
    ground = _ground(horizon, vertical_vp, ref_base, ref_top, ref_height)
    b, single = as_points(base, 2, "base")
    t, single_top = as_points(top, 2, "top")
    if single != single_top or b.shape != t.shape:
        raise ValueError(
            f"base and top must have the same shape (N, 2) or (2,), got {np.shape(base)} "
            f"and {np.shape(top)}"
        )
    heights = _native.relative_height(*ground, b, t)
    return float(heights[0]) if single else heights


def camera_height(
    horizon: Any,
    ref_base: Any,
    ref_top: Any,
    ref_height: float = 1.0,
    *,
    vertical_vp: Any,
) -> float:
    """The camera's height above the ground plane, in the reference's unit.

    An object whose top touches the horizon is exactly as tall as the camera is
    high (its top is level with the eye), so the height is that of
    :func:`relative_height` for a top on the horizon:
    ``ref_height / (g(ref_base, ref_top) (l · v))``, independent of where the
    base is.

    Parameters
    ----------
    horizon, ref_base, ref_top, ref_height, vertical_vp
        As in :func:`relative_height`.

    Returns
    -------
    float
        Positive for a camera above the ground.

    Raises
    ------
    TypeError
        Non-numeric input.
    ValueError
        As in :func:`relative_height`.

    Examples
    --------
    >>> round(camera_height([0, -1, 240], [300, 315], [300, 215], 2.0, vertical_vp=[0, 1, 0]), 9)
    1.5
    """
    return _native.camera_height(*_ground(horizon, vertical_vp, ref_base, ref_top, ref_height))

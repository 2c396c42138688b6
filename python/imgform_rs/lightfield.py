"""Light fields and refocusing after capture (lecture section 7).

A plenoptic camera records, behind each microlens, the light arriving from
every part of the main lens' aperture; regrouped, those samples form a grid of
*sub-aperture views*, each a small pinhole picture of the scene seen through
one spot of the aperture. Here a light field is an array of shape
``(U, V, H, W[, C])``: ``light_field[u, v]`` is the view of the camera in row
``u`` and column ``v`` of a regular grid in the aperture plane, all cameras
looking along the same axis (parallel optical axes).

Grid and sign convention
------------------------
Array-axis order, as shifts ``(dy, dx)`` in the conventions: view ``(u, v)``
sits ``(u - u_c, v - v_c)`` grid steps *below and right of* the centre
``(u_c, v_c) = ((U - 1) / 2, (V - 1) / 2)``, one step being ``baseline``
apart. A point at depth ``Z`` (along the optical axis) then appears in view
``(u, v)`` moved by ``-d * (u - u_c, v - v_c)`` pixels from where the centre
sees it, where

    d = baseline * f / Z    (pixels per view step, f the focal length in pixels)

is its *disparity*, linear in inverse depth (:func:`view_disparity`).

Refocusing (Ng et al. 2005, shift-and-add) at ``alpha`` shifts every view by
``+alpha * (u - u_c, v - v_c)`` pixels (``np.roll``'s direction) and averages
them: points whose disparity equals ``alpha`` line up and come out as sharp as
in one view, the rest are spread over a copy of the synthetic aperture scaled
by ``|d - alpha|``. So ``alpha`` picks the plane in focus (``alpha = 0``:
infinity, the plain mean of the views; larger ``alpha``: nearer), and a smaller
``aperture`` (fewer views averaged) gives a deeper depth of field.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt

from . import _native
from ._arrays import native
from .camera import Camera

Image = TypeVar("Image", npt.NDArray[np.uint8], npt.NDArray[np.uint16], npt.NDArray[np.float32])
Shader = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
_DTYPES = (np.uint8, np.uint16, np.float32)


def _positive_int(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def _grid(grid: Any) -> tuple[int, int]:
    if isinstance(grid, np.ndarray) and grid.ndim == 1:
        grid = grid.tolist()  # its NumPy ints pass as ints
    if not isinstance(grid, Sequence) or len(grid) != 2:
        raise ValueError(f"grid must be a pair (U, V) of integers >= 1, got {grid!r}")
    return _positive_int(grid[0], "grid[0]"), _positive_int(grid[1], "grid[1]")


def _offsets(grid: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Row and column offsets ``u - u_c``, ``v - v_c`` of every view, (U, V) each."""
    u, v = np.mgrid[0 : grid[0], 0 : grid[1]].astype(np.float64)
    return u - (grid[0] - 1) / 2, v - (grid[1] - 1) / 2


def _positive_length(value: Any, name: str) -> float:
    """``value`` as a float, checked: one real number, finite and > 0."""
    arr = np.asarray(value)
    if arr.ndim or arr.dtype.kind not in "iuf":
        raise TypeError(f"{name} must be a real number, got {value!r}")
    if not (math.isfinite(arr) and arr > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return float(arr)


def view_disparity(camera: Camera, baseline: float, depth: Any) -> Any:
    """Disparity in pixels per view step of points at ``depth``:
    ``baseline * f / depth`` with ``f`` the camera's horizontal focal length
    in pixels (``K[0, 0]``; square pixels assumed).

    The ``alpha`` at which :func:`refocus` brings a plane at ``depth`` into
    focus, for a light field from :func:`render_light_field` with the same
    ``camera`` and ``baseline`` (lengths in the scene's unit).

    Parameters
    ----------
    camera : Camera
    baseline : float
        Distance between neighbouring views (finite, > 0), as given to
        :func:`render_light_field`.
    depth : float or array_like of float
        Depths along the optical axis (> 0: a point at or behind the
        pinhole has no disparity, and a negative one would refocus the
        wrong way silently). ``inf`` is the far distance, disparity 0: the
        views' plain mean (``refocus(lf, 0.0)``) focuses there.

    Returns
    -------
    float or ndarray
        A NumPy float for a scalar ``depth``, else an array of its shape.

    Raises
    ------
    TypeError
        ``camera`` is not a :class:`Camera`, or ``baseline`` or ``depth`` not
        real numbers.
    ValueError
        A ``baseline`` that is not finite and > 0, or a ``depth`` that is NaN
        or not > 0.

    Examples
    --------
    >>> cam = Camera.from_intrinsics(500.0, 500.0, 63.5, 47.5)
    >>> view_disparity(cam, 0.02, [2.0, 5.0, 10.0, float("inf")])
    array([5., 2., 1., 0.])
    """
    if not isinstance(camera, Camera):
        raise TypeError(f"camera must be an imgform_rs.Camera, got {type(camera).__name__}")
    b = _positive_length(baseline, "baseline")
    z = np.asarray(depth)
    if z.dtype.kind not in "iuf":
        raise TypeError(f"depth must be real numbers, got {depth!r}")
    z = z.astype(np.float64)
    bad = ~(z > 0)  # NaN too
    if bad.any():
        got = float(z[bad].flat[0])
        raise ValueError(f"depth must be > 0 (inf for the far distance), got {got}")
    return b * float(camera.K[0, 0]) / z


def render_light_field(
    scene: Any,
    *,
    camera: Camera,
    baseline: float,
    grid: tuple[int, int] = (9, 9),
    supersample: int = 1,
    dtype: type = np.uint8,
) -> np.ndarray:
    """Render the sub-aperture views of a plenoptic camera by ray casting.

    A ``U x V`` grid of copies of ``camera`` (same intrinsics, lens and
    orientation, so parallel optical axes), translated in its own image plane
    by ``baseline * (v - v_c)`` along its x axis (right) and ``baseline * (u -
    u_c)`` along its y axis (down); see the module docs for the grid and sign
    convention. A fronto-parallel plane at depth ``Z`` then moves by
    ``baseline * f / Z`` pixels per view step (:func:`view_disparity`).

    Parameters
    ----------
    scene : callable or module
        ``shade(origin, directions) -> (colour, distance)`` casting rays from
        one ``origin`` (3,) along unit ``directions`` (N, 3) and returning RGB
        in [0, 1] (N, 3) and the distance along each ray (N,), like
        :func:`imgform_rs.scene.shade`; or an object with such a ``shade``
        attribute (the module :mod:`imgform_rs.scene` itself).
    camera : Camera
        The central view, with ``image_size`` set.
    baseline : float
        Distance between neighbouring views, in the scene's unit (> 0).
    grid : (int, int)
        Views ``(U, V)``, rows and columns of the grid (>= 1 each).
    supersample : int
        Rays per pixel along each axis (>= 1), averaged: anti-aliasing.
    dtype : {numpy.uint8, numpy.float32}
        ``uint8`` (rounded, what a camera records) or ``float32`` in [0, 1].

    Returns
    -------
    ndarray, shape (U, V, H, W, 3)
        The views, ``(H, W) = camera.image_size``.

    Raises
    ------
    TypeError
        ``scene`` is not callable, ``camera`` is not a :class:`Camera`, or an
        unsupported ``dtype``.
    ValueError
        No ``image_size`` on the camera, a bad ``grid``, ``supersample`` or
        ``baseline``.

    Examples
    --------
    >>> from imgform_rs import Camera, scene
    >>> cam = Camera.from_fov(0.8, (24, 32)).look_at([4.5, 1.6, -3.0], [-0.5, 0.9, 9.0])
    >>> render_light_field(scene, camera=cam, baseline=0.05, grid=(3, 5)).shape
    (3, 5, 24, 32, 3)
    """
    shade = getattr(scene, "shade", scene)
    if not callable(shade):
        raise TypeError(f"scene must be a shade(origin, directions) callable, got {scene!r}")
    if not isinstance(camera, Camera):
        raise TypeError(f"camera must be an imgform_rs.Camera, got {type(camera).__name__}")
    if camera.image_size is None:
        raise ValueError("camera needs image_size=(height, width) to render views")
    baseline = _positive_length(baseline, "baseline")
    if np.dtype(dtype) not in (np.uint8, np.float32):
        raise TypeError(f"dtype must be numpy.uint8 or numpy.float32, got {np.dtype(dtype)}")
    grid = _grid(grid)
    s = _positive_int(supersample, "supersample")
    h, w = camera.image_size
    # Sub-pixel sample positions: s x s per pixel, centred on the pixel.
    sub = (np.arange(s) + 0.5) / s - 0.5
    ys = (np.arange(h)[:, None] + sub).ravel()
    xs = (np.arange(w)[:, None] + sub).ravel()
    pixels = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    rays = camera.rays(pixels)
    lost = ~np.isfinite(rays).all(axis=1)
    if lost.any():
        # Beyond the lens's fold its rays are NaN: the shader was blamed.
        x, y = pixels[np.argmax(lost)]
        raise ValueError(
            f"the camera's lens sees no ray at {int(lost.sum())} of {len(rays)} sample "
            f"positions (beyond its distortion's fold, from pixel ({x:.2f}, {y:.2f})): "
            "give a lens that covers its image_size"
        )
    du, dv = _offsets(grid)
    right, down = camera.R[0], camera.R[1]
    views = np.empty((*grid, h, w, 3), dtype=dtype)
    for u, v in np.ndindex(*grid):
        origin = camera.center + baseline * (dv[u, v] * right + du[u, v] * down)
        colour = _shaded(shade(origin, rays), len(rays))
        colour = np.clip(colour.reshape(h, s, w, s, 3).mean(axis=(1, 3)), 0.0, 1.0)
        views[u, v] = colour * 255 + 0.5 if views.dtype == np.uint8 else colour
    return views


def _shaded(result: Any, n: int) -> np.ndarray:
    """The colours of a ``shade`` callback's ``(colour, distance)``, checked:
    real, finite and (N, 3), where a (3, N) array would reshape into
    scrambled views and NaN clip to black."""
    try:
        first, _ = result
    except (TypeError, ValueError):
        raise TypeError(
            f"shade must return (colour, distance), got {type(result).__name__}"
        ) from None
    colour = np.asarray(first)
    if colour.dtype.kind not in "iuf":
        raise TypeError(f"shade's colours must be real numbers, got dtype {colour.dtype}")
    if colour.shape != (n, 3):
        raise ValueError(f"shade's colours must have shape ({n}, 3), got {colour.shape}")
    if not np.isfinite(colour).all():
        raise ValueError("shade's colours must be finite numbers in [0, 1]")
    return colour


def _aperture_mask(aperture: Any, grid: tuple[int, int]) -> np.ndarray:
    """The (U, V) boolean mask of the views to average."""
    if aperture is None:
        return np.ones(grid, dtype=bool)
    arr = np.asarray(aperture)
    if arr.dtype == bool:
        if arr.shape != grid:
            raise ValueError(f"aperture mask must have the grid's shape {grid}, got {arr.shape}")
        mask = arr
    elif arr.ndim == 0 and arr.dtype.kind in "iuf":
        radius = float(arr)
        if not (math.isfinite(radius) and radius >= 0):
            raise ValueError(f"aperture radius must be a finite number >= 0, got {radius}")
        du, dv = _offsets(grid)
        # A relative tolerance so that radius 1 includes the four neighbours
        # whatever rounding the offsets carry.
        mask = du**2 + dv**2 <= radius**2 * (1 + 1e-9)
    else:
        raise TypeError(
            "aperture must be None, a radius in view steps or a boolean (U, V) mask, "
            f"got {type(aperture).__name__} of dtype {arr.dtype}"
        )
    if not mask.any():
        raise ValueError(f"aperture selects no view of the {grid[0]}x{grid[1]} grid")
    return mask


def _as_light_field(light_field: Any) -> tuple[np.ndarray, tuple[int, int]]:
    """``light_field`` as a C-contiguous (U, V, H, W, C) array of a kernel dtype."""
    arr = native(light_field)
    if arr.dtype not in _DTYPES:
        raise TypeError(
            f"light_field must be a uint8, uint16 or float32 array, got dtype {arr.dtype}"
        )
    if arr.ndim not in (4, 5):
        raise ValueError(
            f"light_field must have shape (U, V, H, W) or (U, V, H, W, C), got {arr.shape}"
        )
    if arr.size == 0:
        raise ValueError(f"light_field must not be empty, got shape {arr.shape}")
    full = arr if arr.ndim == 5 else arr[..., None]
    return np.ascontiguousarray(full), (arr.shape[0], arr.shape[1])


def focal_stack(light_field: Image, alphas: Any, *, aperture: Any = None) -> Image:
    """Refocus a light field at several disparities: a focal stack.

    Parameters
    ----------
    light_field : ndarray, uint8, uint16 or float32, shape (U, V, H, W[, C])
        Sub-aperture views in the grid convention of the module docs.
    alphas : array_like of float, shape (N,)
        Disparities in focus, pixels per view step (finite).
    aperture : None, float or ndarray of bool, shape (U, V)
        The views averaged: all (None), those within a radius of the centre
        in view steps (``(u - u_c)**2 + (v - v_c)**2 <= r**2``; a smaller radius
        gives a deeper depth of field), or a boolean mask.

    Returns
    -------
    ndarray, shape (N, H, W[, C])
        One refocused frame per alpha, the dtype of ``light_field`` (integers
        rounded half up and clamped).

    Raises
    ------
    TypeError
        An unsupported dtype or aperture type.
    ValueError
        A wrong ``ndim``, an empty light field or ``alphas``, a non-finite
        alpha, an aperture mask not of the grid's shape or selecting no view,
        a negative radius.

    Examples
    --------
    One row of three views of a point at disparity 1 (columns 4, 3, 2): the
    mean of the views smears it, alpha = 1 gathers it.

    >>> lf = np.zeros((1, 3, 1, 7), np.float32)
    >>> for v, x in enumerate([4, 3, 2]):
    ...     lf[0, v, 0, x] = 1.0
    >>> focal_stack(lf, [0.0, 1.0])[:, 0]
    array([[0.        , 0.        , 0.33333334, 0.33333334, 0.33333334,
            0.        , 0.        ],
           [0.        , 0.        , 0.        , 1.        , 0.        ,
            0.        , 0.        ]], dtype=float32)
    """
    arr, grid = _as_light_field(light_field)
    given = np.asarray(alphas)
    if given.dtype.kind not in "iuf":
        # np.asarray(..., float64) would read the string "1" as 1.0.
        raise TypeError(f"alphas must be numbers, got {alphas!r}")
    if given.ndim > 1:
        raise ValueError(f"alphas must be a 1-D sequence of disparities, got shape {given.shape}")
    alpha_list = given.astype(np.float64).ravel()
    if alpha_list.size == 0:
        raise ValueError("alphas must hold at least one disparity, got none")
    if not np.all(np.isfinite(alpha_list)):
        raise ValueError(f"alphas must be finite, got {alpha_list.tolist()}")
    mask = _aperture_mask(aperture, grid)
    u, v, h, w, c = arr.shape
    views = arr.reshape(u * v * h, w, c)
    out = _native.focal_stack(views, grid, alpha_list.tolist(), mask.ravel().tolist())
    return out if np.ndim(light_field) == 5 else out[..., 0]  # type: ignore[no-any-return]


def refocus(light_field: Image, alpha: float, *, aperture: Any = None) -> Image:
    """Refocus a light field by shift-and-add (Ng et al. 2005).

    Every view ``(u, v)`` is shifted by ``alpha * (u - u_c, v - v_c)`` pixels
    (rows, columns; bilinear for sub-pixel shifts, mirrored borders) and the
    views selected by ``aperture`` are averaged. A plane whose disparity
    (:func:`view_disparity`) equals ``alpha`` comes out as sharp as in the
    central view; ``alpha = 0`` is the plain mean of the views. The sum runs
    in Rust over rows in parallel, in one fixed order of views, so results are
    identical for any thread count.

    Parameters
    ----------
    light_field : ndarray, uint8, uint16 or float32, shape (U, V, H, W[, C])
        Sub-aperture views in the grid convention of the module docs.
    alpha : float
        Disparity in focus, pixels per view step (finite); one number, a
        NumPy scalar or 0-d array included. For several, :func:`focal_stack`.
    aperture : None, float or ndarray of bool, shape (U, V)
        As in :func:`focal_stack`.

    Returns
    -------
    ndarray, shape (H, W[, C])
        The refocused image, dtype of ``light_field``.

    Raises
    ------
    TypeError, ValueError
        As :func:`focal_stack`; ValueError also for an ``alpha`` of more than
        one value, which would otherwise refocus at its first alone.

    Examples
    --------
    Views of one picture moved by ``-(u - 1, v - 1)`` pixels (a plane at
    disparity 1) refocus at ``alpha = 1`` to that picture, away from the
    borders where ``np.roll`` wraps around and refocusing mirrors:

    >>> img = np.arange(48, dtype=np.uint8).reshape(6, 8)
    >>> lf = np.stack([[np.roll(img, (1 - u, 1 - v), (0, 1)) for v in range(3)] for u in range(3)])
    >>> np.array_equal(refocus(lf, 1.0)[1:-1, 1:-1], img[1:-1, 1:-1])
    True
    >>> refocus(lf, 1.0, aperture=0.0)[0]  # the central view alone
    array([0, 1, 2, 3, 4, 5, 6, 7], dtype=uint8)
    """
    if np.ndim(alpha) != 0:
        raise ValueError(
            f"alpha must be one disparity, got shape {np.shape(alpha)}; for several, call "
            "focal_stack(light_field, alphas)"
        )
    return focal_stack(light_field, [alpha], aperture=aperture)[0]  # type: ignore[no-any-return]

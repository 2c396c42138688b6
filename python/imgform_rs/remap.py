"""Resampling images through lens distortion (lecture section 3.3).

A :class:`RemapMap` holds, for every output pixel, the position in the source
image it is read from. Building it evaluates the lens model once per pixel;
applying it (:func:`remap`) is then a pure resampling pass, so a map built for
one camera and image size is reused for every frame.

Sampling is ``"bilinear"`` (2x2 taps) or ``"bicubic"`` (4x4 taps, Keys' cubic
convolution with ``a = -0.5``; OpenCV's ``INTER_CUBIC`` uses ``a = -0.75``, so
the two agree closely on smooth images but not exactly). An identity map
returns the image bit for bit with either kernel.

Borders work like OpenCV's ``BORDER_CONSTANT``: a tap outside the source reads
``fill``, so pixels whose taps straddle the edge blend the image with
``fill``; a pixel whose source is undefined (NaN in the map, e.g. beyond the
fold of a strongly distorting lens) or entirely outside is ``fill``.

Integer images are rounded half up and clamped to their range (bicubic
overshoots at edges); float32 images are neither rounded nor clamped. Stored
positions are rounded to 1/256 px (OpenCV's fixed-point maps: 1/32 px).
"""

from __future__ import annotations

from typing import Any, Literal, TypeVar

import numpy as np
import numpy.typing as npt

from . import _native
from ._arrays import as_matrix, as_real, is_int, real
from .distortion import DistortionModel, lens_coefficients, model_name

RemapMap = _native.RemapMap

Interpolation = Literal["bilinear", "bicubic"]
ImageT = TypeVar("ImageT", npt.NDArray[np.uint8], npt.NDArray[np.uint16], npt.NDArray[np.float32])


def _lens(
    camera_or_K: Any, dist: Any, model: DistortionModel | None
) -> tuple[np.ndarray, list[float], str]:
    """``K``, the coefficients and the model, from a camera-like object or
    given apart: a camera's coefficients mean nothing under another model."""
    if hasattr(camera_or_K, "K") and hasattr(camera_or_K, "dist"):
        if dist is not None:
            raise TypeError(
                "dist was given twice: pass a camera (with .K and .dist) or K and dist, not both"
            )
        own = getattr(camera_or_K, "model", "brown_conrady")
        if model is not None and model != own:
            raise ValueError(
                f"model={model!r} contradicts the camera's own model {own!r}: "
                "leave model out to use the camera's"
            )
        camera_or_K, dist, model = camera_or_K.K, camera_or_K.dist, own
    K = as_matrix(camera_or_K, (3, 3), "K")
    return K, lens_coefficients(dist), model_name("brown_conrady" if model is None else model)


def _shape(shape: Any) -> tuple[int, int]:
    """(H, W) from an image shape (H, W) or (H, W, C)."""
    if shape is None:
        raise TypeError("shape is required: the output (H, W), e.g. image.shape")
    try:
        dims = tuple(shape)
    except TypeError:  # a bare int
        dims = ()
    if len(dims) not in (2, 3) or not all(is_int(d) for d in dims):
        raise ValueError(f"shape must be (H, W) or (H, W, C) integers, got {shape!r}")
    if min(dims[:2]) < 1:
        raise ValueError(f"shape must be a non-empty (H, W), sizes >= 1, got {shape!r}")
    return int(dims[0]), int(dims[1])


def _lens_map(camera_or_K, dist, shape, model, new_K, undistort: bool) -> RemapMap:
    K, coeffs, model = _lens(camera_or_K, dist, model)
    new_k = None if new_K is None else as_matrix(new_K, (3, 3), "new_K")
    build = RemapMap.undistort if undistort else RemapMap.distort
    return build(K, coeffs, model, _shape(shape), new_k)


def undistort_map(
    camera_or_K: Any,
    dist: Any = None,
    shape: Any = None,
    *,
    model: DistortionModel | None = None,
    new_K: Any = None,
) -> RemapMap:
    """The map that removes lens distortion, built once and reused per frame.

    Output pixel ``(u, v)`` is an ideal pinhole pixel of ``new_K``; it is read
    from where the lens puts that ray in the distorted input. This is the map
    of ``cv2.initUndistortRectifyMap(K, dist, None, new_K, (W, H), CV_32FC1)``.

    Parameters
    ----------
    camera_or_K : Camera or array_like (3, 3)
        An object with ``.K`` and ``.dist`` attributes, or the intrinsics.
    dist : array_like, optional
        Distortion coefficients (OpenCV's order for ``"brown_conrady"``:
        ``(k1, k2, p1, p2[, k3[, k4, k5, k6]])``; one ``lambda`` for
        ``"division"``). Not allowed together with a camera.
    shape : tuple
        Output ``(H, W)`` in NumPy's order (an image's ``.shape`` works),
        not OpenCV's ``(W, H)``.
    model : {"brown_conrady", "division"}, optional
        The camera's own model (its ``.model``) for a camera, else
        ``"brown_conrady"``.
    new_K : array_like (3, 3), optional
        Intrinsics of the undistorted image; default ``K``.

    Returns
    -------
    RemapMap
        ``.shape`` is ``(H, W)``; ``.planes()`` gives OpenCV's float32
        ``(map_x, map_y)`` (NaN where the lens has no image of the ray).

    Raises
    ------
    TypeError
        ``shape`` missing, ``dist`` given twice, non-numeric ``K``.
    ValueError
        Malformed or singular ``K``, wrong coefficient count, bad ``shape``.

    Examples
    --------
    >>> K = [[100.0, 0, 31.5], [0, 100.0, 23.5], [0, 0, 1]]
    >>> m = undistort_map(K, [-0.2, 0.0, 0.0, 0.0], (48, 64))
    >>> m.shape
    (48, 64)
    """
    return _lens_map(camera_or_K, dist, shape, model, new_K, undistort=True)


def distort_map(
    camera_or_K: Any,
    dist: Any = None,
    shape: Any = None,
    *,
    model: DistortionModel | None = None,
    new_K: Any = None,
) -> RemapMap:
    """The map that renders lens distortion into an ideal (pinhole) image.

    Output pixel ``(u, v)`` is a distorted pixel of ``K`` and the lens; it is
    read from the ideal pixel (intrinsics ``new_K``, default ``K``) of the
    same ray, found by the exact numeric inverse of the lens model. Where
    that inverse does not exist (beyond the fold of a strong lens) the map
    is NaN and the output is ``fill``. Parameters as :func:`undistort_map`.

    Examples
    --------
    >>> K = [[100.0, 0, 31.5], [0, 100.0, 23.5], [0, 0, 1]]
    >>> distort_map(K, [-0.2, 0.0, 0.0, 0.0], (48, 64)).shape
    (48, 64)
    """
    return _lens_map(camera_or_K, dist, shape, model, new_K, undistort=False)


def _as_map(map: Any) -> RemapMap:
    if isinstance(map, RemapMap):
        return map
    if isinstance(map, tuple) and len(map) == 2:
        names = ("map_x", "map_y")
        map_x, map_y = (as_real(m, n, np.float32) for m, n in zip(map, names, strict=True))
        return RemapMap(map_x, map_y)
    given = type(map).__name__
    raise TypeError(
        f"map must be a RemapMap or a (map_x, map_y) pair of (H, W) arrays, got {given}"
    )


def remap(
    image: ImageT,
    map: RemapMap | tuple[Any, Any],
    *,
    interpolation: Interpolation = "bilinear",
    fill: float = 0,
) -> ImageT:
    """Resample ``image`` through a map: ``out[v, u] = image at map[v, u]``.

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, C), uint8, uint16 or float32
        Any channel count; non-contiguous arrays are copied once.
    map : RemapMap or (map_x, map_y)
        Source positions (column, row) for each output pixel; OpenCV-style
        float planes are converted once (build a :class:`RemapMap` to reuse).
    interpolation : {"bilinear", "bicubic"}
    fill : float
        Value of taps outside the image; a finite value the image's dtype
        holds exactly (an integer 0..255 for uint8; not NaN: the kernels
        weigh every tap, and a NaN tap would spread into its neighbours).

    Returns
    -------
    ndarray
        The map's ``(H, W)`` with the input's channels and dtype.

    Raises
    ------
    TypeError
        Unsupported dtype (e.g. int64, bool, float64) or map type, a ``fill``
        that is not a real number.
    ValueError
        Wrong number of dimensions, unknown interpolation, a ``fill`` the
        dtype cannot hold.

    Examples
    --------
    >>> img = np.arange(12, dtype=np.uint8).reshape(3, 4)
    >>> map_x = np.array([[0.5, 2.0]], dtype=np.float32)
    >>> map_y = np.array([[1.0, 0.5]], dtype=np.float32)
    >>> remap(img, (map_x, map_y))
    array([[5, 4]], dtype=uint8)
    """
    return _native.remap_image(image, _as_map(map), interpolation, real(fill, "fill"))


def _image_remap(image, camera_or_K, dist, model, new_K, interpolation, fill, map, undistort):
    if map is None:
        shape = getattr(image, "shape", None)
        if shape is None:
            raise TypeError(
                f"image must be a uint8, uint16 or float32 array, got {type(image).__name__}"
            )
        map = _lens_map(camera_or_K, dist, shape[:2], model, new_K, undistort)
    return remap(image, map, interpolation=interpolation, fill=fill)


def undistort_image(
    image: ImageT,
    camera_or_K: Any = None,
    dist: Any = None,
    *,
    model: DistortionModel | None = None,
    new_K: Any = None,
    interpolation: Interpolation = "bilinear",
    fill: float = 0,
    map: RemapMap | None = None,
) -> ImageT:
    """Remove lens distortion from an image.

    Builds :func:`undistort_map` for the image's size and applies it; pass
    ``map`` (from :func:`undistort_map`) to skip the building when many
    frames share one camera — ``camera_or_K`` and ``dist`` are then unused.
    Agrees with ``cv2.initUndistortRectifyMap`` + ``cv2.remap`` (which take
    BGR images: the channel order does not matter here).

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, C), uint8, uint16 or float32
    camera_or_K, dist, model, new_K
        As :func:`undistort_map`.
    interpolation, fill
        As :func:`remap`.
    map : RemapMap, optional
        A precomputed map.

    Returns
    -------
    ndarray
        Same dtype and channels; ``(H, W)`` of the map (the input's by default).

    Examples
    --------
    >>> K = [[100.0, 0, 31.5], [0, 100.0, 23.5], [0, 0, 1]]
    >>> img = np.full((48, 64), 200, np.uint8)
    >>> int(undistort_image(img, K, [-0.1, 0, 0, 0])[24, 32])
    200
    """
    return _image_remap(image, camera_or_K, dist, model, new_K, interpolation, fill, map, True)


def distort_image(
    image: ImageT,
    camera_or_K: Any = None,
    dist: Any = None,
    *,
    model: DistortionModel | None = None,
    new_K: Any = None,
    interpolation: Interpolation = "bilinear",
    fill: float = 0,
    map: RemapMap | None = None,
) -> ImageT:
    """Render lens distortion into an ideal (pinhole) image: the inverse of
    :func:`undistort_image`, through :func:`distort_map`. Parameters as
    :func:`undistort_image`.

    Examples
    --------
    >>> K = [[100.0, 0, 31.5], [0, 100.0, 23.5], [0, 0, 1]]
    >>> img = np.full((48, 64, 3), 0.5, np.float32)
    >>> float(distort_image(img, K, [-0.1, 0, 0, 0])[24, 32, 1])
    0.5
    """
    return _image_remap(image, camera_or_K, dist, model, new_K, interpolation, fill, map, False)

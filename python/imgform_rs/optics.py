"""The thin lens and its phenomena (lecture sections 3.1-3.2).

All lengths are in one consistent unit; the docs use millimetres (focal length,
distances, circle of confusion, sensor size, pixel pitch). ``N`` is the
f-number, angles are radians. Every function broadcasts its arguments like a
NumPy ufunc and returns float64 (a NumPy scalar when all arguments are scalars);
each formula is evaluated once per element in Rust, in parallel for large inputs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt

from . import _native
from ._arrays import Float64Array, as_float_array, native, real

# What the vectorised formulas return: an array of the broadcast shape, or a
# NumPy float64 scalar when every argument was a scalar.
Floats = Float64Array | np.float64
Image = TypeVar("Image", npt.NDArray[np.uint8], npt.NDArray[np.uint16], npt.NDArray[np.float32])


def _elementwise(native: Callable[..., Any], **args: Any) -> tuple[Floats, ...]:
    """Broadcasts ``args``, runs ``native`` once over the flattened arrays
    (single values stay single) and reshapes every output back to the
    broadcast shape."""
    arrays = [as_float_array(value, name) for name, value in args.items()]
    try:
        shape = np.broadcast_shapes(*(a.shape for a in arrays))
    except ValueError:
        given = ", ".join(f"{name} {a.shape}" for name, a in zip(args, arrays, strict=True))
        raise ValueError(
            f"arguments must broadcast against each other, got shapes {given}"
        ) from None
    # A single value is passed as is (the kernel repeats it); only arrays
    # that really vary are expanded to the broadcast shape.
    flat = [a.ravel() if a.size == 1 else np.broadcast_to(a, shape).ravel() for a in arrays]
    out = native(*flat)
    outs = out if isinstance(out, tuple) else (out,)
    return tuple(o.reshape(shape)[()] for o in outs)


def image_distance(f: Any, D: Any) -> Floats:
    """Image distance ``D'`` of an object at ``D`` from the thin-lens law
    ``1/D' + 1/D = 1/f``.

    Parameters
    ----------
    f : array_like
        Focal length (mm), finite and > 0.
    D : array_like
        Object distance from the lens (mm), finite and > ``f``.

    Returns
    -------
    ndarray or numpy.float64
        ``D' = f D / (D - f)`` in mm, broadcast shape of the arguments. It tends
        to ``f`` as ``D -> inf`` and grows without bound as ``D -> f``.

    Raises
    ------
    TypeError
        An argument is not numeric.
    ValueError
        ``f <= 0``, a NaN or infinity, ``D <= f`` (an object at or inside the
        focal length forms no real image), or shapes that do not broadcast.

    Examples
    --------
    >>> float(image_distance(50.0, 100.0))
    100.0
    >>> image_distance(50.0, [200.0, 1050.0])
    array([66.66666667, 52.5       ])
    """
    return _elementwise(_native.image_distance, f=f, D=D)[0]


def magnification(f: Any, D: Any) -> Floats:
    """Lateral magnification ``m = D'/D = f / (D - f)`` of an object at ``D``.

    The magnitude is returned (always positive). The real image of a thin lens
    is inverted, like the pinhole image ``x' = -f x / z``, so the signed lateral
    magnification is ``-m``. Arguments and errors as :func:`image_distance`.

    Examples
    --------
    >>> float(magnification(50.0, 100.0))
    1.0
    """
    return _elementwise(_native.magnification, f=f, D=D)[0]


def circle_of_confusion(f: Any, N: Any, focus_distance: Any, D: Any) -> Floats:
    """Diameter of the blur disc on the sensor of an object at ``D`` when the
    lens is focused at ``focus_distance``.

    With aperture ``A = f / N`` and focus distance ``S``,
    ``c = A |D - S| / D * f / (S - f)``: 0 at ``D = S``, growing monotonically
    on both sides, tending to ``A f / (S - f)`` as ``D -> inf``.

    Parameters
    ----------
    f, N : array_like
        Focal length (mm) and f-number, finite and > 0.
    focus_distance, D : array_like
        Focused and object distances (mm), finite and > ``f``.

    Returns
    -------
    ndarray or numpy.float64
        Circle-of-confusion diameter in mm.

    Raises
    ------
    TypeError
        An argument is not numeric.
    ValueError
        A value outside its domain (the message names it), or shapes that do not
        broadcast.

    Examples
    --------
    >>> round(float(circle_of_confusion(50.0, 2.0, 1000.0, 2000.0)), 6)
    0.657895
    """
    return _elementwise(_native.circle_of_confusion, f=f, N=N, focus_distance=focus_distance, D=D)[
        0
    ]


def hyperfocal_distance(f: Any, N: Any, coc: Any) -> Floats:
    """Hyperfocal distance ``H = f^2 / (N coc) + f`` (mm).

    Focused at ``H``, everything from about ``H / 2`` to infinity is imaged
    with a circle of confusion of at most ``coc``. All arguments finite and > 0.

    Examples
    --------
    >>> round(float(hyperfocal_distance(50.0, 8.0, 0.03)), 3)
    10466.667
    """
    return _elementwise(_native.hyperfocal_distance, f=f, N=N, coc=coc)[0]


def depth_of_field(f: Any, N: Any, focus_distance: Any, coc: Any) -> tuple[Floats, Floats]:
    """Near and far limits of the depth of field.

    The distances where :func:`circle_of_confusion` equals ``coc``, with
    ``H = hyperfocal_distance(f, N, coc)`` and ``S = focus_distance``:
    ``near = S (H - f) / (H + S - 2 f)``, ``far = S (H - f) / (H - S)``, and
    ``far = inf`` when ``S >= H``. Always ``near < S < far``.

    Parameters
    ----------
    f, N, coc : array_like
        Focal length (mm), f-number, acceptable circle of confusion (mm), > 0;
        ``coc`` below the aperture diameter ``f / N`` (in front of the focus
        the blur never reaches it, so a larger tolerance has no near limit).
    focus_distance : array_like
        Focused distance (mm), finite and > ``f``.

    Returns
    -------
    (near, far) : tuple of ndarray or numpy.float64
        Distances in mm, broadcast shape of the arguments.

    Raises
    ------
    TypeError
        An argument is not numeric.
    ValueError
        A value outside its domain, or shapes that do not broadcast.

    Examples
    --------
    >>> near, far = depth_of_field(50.0, 8.0, 3000.0, 0.03)
    >>> round(float(near), 1), round(float(far), 1)
    (2337.9, 4185.3)
    >>> depth_of_field(50.0, 8.0, 20000.0, 0.03)[1]
    np.float64(inf)
    """
    near, far = _elementwise(
        _native.depth_of_field, f=f, N=N, focus_distance=focus_distance, coc=coc
    )
    return near, far


def field_of_view(f: Any, sensor_size: Any) -> Floats:
    """Angular field of view ``2 atan(sensor_size / (2 f))`` in radians.

    ``sensor_size`` is the sensor's width, height or diagonal (mm); the lens is
    taken focused at infinity (image distance ``f``). Both arguments > 0.

    Examples
    --------
    >>> round(float(np.degrees(field_of_view(50.0, 36.0))), 2)
    39.6
    """
    return _elementwise(_native.field_of_view, f=f, sensor_size=sensor_size)[0]


def dolly_zoom_focal_length(f0: Any, d0: Any, d: Any) -> Floats:
    """Focal length that keeps a subject the same size on the sensor when the
    camera moves from ``d0`` (with focal length ``f0``) to ``d``: ``f0 d / d0``.

    Exact for the thin lens, not only for the pinhole: the magnification
    ``f / (D - f)`` is unchanged whenever ``f / D`` is. ``f0`` and ``d`` > 0,
    ``d0 > f0``.

    Examples
    --------
    >>> float(dolly_zoom_focal_length(24.0, 1000.0, 3000.0))
    72.0
    """
    return _elementwise(_native.dolly_zoom_focal_length, f0=f0, d0=d0, d=d)[0]


def render_defocus(
    image: Image,
    depth: npt.NDArray[np.float32] | npt.NDArray[np.float64],
    *,
    f: float,
    N: float,
    focus_distance: float,
    pixel_pitch: float,
) -> Image:
    """Render an all-in-focus image as a thin lens focused at one distance sees it.

    Every pixel is spread over a disc whose diameter is its circle of confusion
    (:func:`circle_of_confusion` at its depth, divided by ``pixel_pitch``), its
    light summing to 1 over the disc, and each output pixel gathers the discs
    covering it. Occlusion follows depth, composited front to back: nearer
    pixels' discs are laid over the pixel's own surface, and a farther pixel
    spreads over a nearer one only within the nearer one's own blur; where a
    blurred surface covers a pixel only partly (near its edge), the rest is
    what lies behind it, taken from the farther pixels around. So a sharp
    foreground neither bleeds into a blurred background nor is smeared over by
    it, a blurred foreground is soft on both sides of its edge and veils the
    background behind it, and a small blurred object keeps its light. Pixels
    whose disc is narrower than one pixel are returned unchanged. Borders are
    mirrored.

    Parameters
    ----------
    image : ndarray, uint8, uint16 or float32, shape (H, W) or (H, W, C)
        The sharp (pinhole) image.
    depth : ndarray, float32 or float64, shape (H, W)
        Distance of each pixel's surface from the lens (mm), finite and > ``f``.
    f, N : float
        Focal length (mm) and f-number, > 0.
    focus_distance : float
        Distance the lens is focused at (mm), > ``f``.
    pixel_pitch : float
        Distance between pixel centres on the sensor (mm), > 0.

    Returns
    -------
    ndarray
        The defocused image, same shape and dtype as ``image``.

    Raises
    ------
    TypeError
        ``image`` or ``depth`` of an unsupported dtype, a parameter that is
        not a real number.
    ValueError
        Wrong shapes, a parameter outside its domain, a depth that is not finite
        or not beyond ``f`` (the pixel is named), or a circle of confusion wider
        than 64 pixels (the cost grows with its area; render a smaller image).

    Examples
    --------
    >>> img = np.zeros((5, 5), np.uint8)
    >>> img[2, 2] = 250
    >>> depth = np.full((5, 5), 1100.0)
    >>> render_defocus(img, depth, f=50.0, N=2.0, focus_distance=1000.0, pixel_pitch=0.1)[1:4, 1:4]
    array([[  0,  18,   0],
           [ 18, 180,  18],
           [  0,  18,   0]], dtype=uint8)
    """
    depth_arr = native(depth)
    if depth_arr.dtype not in (np.float32, np.float64):
        raise TypeError(f"depth must be a float32 or float64 array, got dtype {depth_arr.dtype}")
    lens = (real(f, "f"), real(N, "N"), real(focus_distance, "focus_distance"))
    return _native.render_defocus(  # type: ignore[no-any-return]
        image, depth_arr, *lens, real(pixel_pitch, "pixel_pitch")
    )

"""A full projective camera ``K [R | t]`` with lens distortion (lecture section 2).

World points go to the camera frame by ``X_cam = R @ X + t`` (x right, y down,
z forward), to normalised coordinates ``(X_cam / Z_cam, Y_cam / Z_cam)``,
through the lens (distortion acts on normalised coordinates, as in OpenCV), and
to pixels through ``K = [[fx, s, cx], [0, fy, cy], [0, 0, 1]]``. Pixel centres
are integers: the top-left pixel is centred at (0, 0). Image sizes are given as
``(height, width)``, the order of ``image.shape[:2]``.
"""

from __future__ import annotations

import math
from typing import Any, Literal, NamedTuple

import numpy as np

from . import _native
from ._arrays import Float64Array, as_float_array, as_matrix, as_points, is_int, real, unbatch
from .distortion import DistortionModel, lens_coefficients, model_name

FovAxis = Literal["horizontal", "vertical", "diagonal"]


class VanishingPoint(NamedTuple):
    """Where the images of all lines along one world direction meet.

    Attributes
    ----------
    point : ndarray, float64, shape (2,)
        Pixel ``(u, v)`` of the vanishing point as the lens images it; NaN when
        ``at_infinity`` (or when the lens has no image of it).
    homogeneous : ndarray, float64, shape (3,)
        The ideal pinhole vanishing point ``K R d``: ``(u, v, 1)`` when finite;
        ``(du, dv, 0)`` with ``du² + dv² = 1`` when at infinity, which is then
        the common direction, in the image, of the parallel image lines.
    at_infinity : bool
        ``True`` when the direction is parallel to the image plane (its
        camera-frame z component is 0 to 1e-12 of its length): the image lines
        stay parallel and meet only at infinity.
    """

    point: Float64Array
    homogeneous: Float64Array
    at_infinity: bool


def _vector3(value: Any, name: str) -> Float64Array:
    """A finite 3-vector; OpenCV's (3, 1) and (1, 3) column/row forms too."""
    arr = as_float_array(value, name)
    if arr.shape in ((3, 1), (1, 3)):
        arr = arr.reshape(3)
    return as_matrix(arr, (3,), name)


def _direction(value: Any, name: str) -> Float64Array:
    """A finite 3-vector whose length does not matter, scaled to a largest
    component of 1: a direction of 1e308 overflows the products it enters."""
    arr = _vector3(value, name)
    largest = np.abs(arr).max()
    return arr / largest if largest > 0 else arr


def _image_size(image_size: Any) -> tuple[int, int] | None:
    if image_size is None:
        return None
    try:
        sides = tuple(image_size)
    except TypeError:
        sides = ()
    # Ints only: True was read as 1 and 480.0 as 480.
    if len(sides) != 2 or not all(is_int(s) and s > 0 for s in sides):
        raise ValueError(
            f"image_size must be two positive integers (height, width), got {image_size!r}"
        )
    return int(sides[0]), int(sides[1])


def _frozen(arr: Float64Array) -> Float64Array:
    arr.flags.writeable = False
    return arr


def _length(v: Float64Array) -> float:
    """The Euclidean length of a non-zero ``v``, scaled first only where its
    squares overflow or underflow: (0, 0, 1e-200) had length 0, so a NaN
    rotation, and (0, 0, 1e200) infinity, so a false "parallel"."""
    with np.errstate(over="ignore", under="ignore"):
        length = float(np.linalg.norm(v))
    if 0.0 < length < np.inf:
        return length
    top = float(np.abs(v).max())
    return top * float(np.linalg.norm(v / top))


def look_at(eye: Any, target: Any, up: Any = (0.0, 1.0, 0.0)) -> tuple[Float64Array, Float64Array]:
    """The pose ``(R, t)`` of a camera at ``eye`` looking at ``target``.

    The camera's z axis points from ``eye`` to ``target`` and its y axis (image
    down) points away from ``up``, so ``up`` appears upward in the image. The
    default ``up`` is +y, the up axis of :mod:`imgform_rs.scene`.

    Parameters
    ----------
    eye, target, up : array_like, shape (3,)
        Camera centre, a point it looks at, and the world's up direction.

    Returns
    -------
    R : ndarray, float64, shape (3, 3)
        World-to-camera rotation.
    t : ndarray, float64, shape (3,)
        World-to-camera translation, ``-R @ eye``.

    Raises
    ------
    ValueError
        ``eye == target``, ``up`` parallel to the viewing direction, or
        non-finite input.

    Examples
    --------
    >>> R, t = look_at([0.0, 1.0, -5.0], [0.0, 1.0, 0.0])
    >>> R.round(12) + 0.0
    array([[-1.,  0.,  0.],
           [ 0., -1.,  0.],
           [ 0.,  0.,  1.]])
    """
    eye_v, target_v, up_v = (
        _vector3(eye, "eye"),
        _vector3(target, "target"),
        _vector3(up, "up"),
    )
    forward = target_v - eye_v
    if not np.any(forward):
        raise ValueError(f"eye and target must differ, both are {eye_v.tolist()}")
    if not np.isfinite(forward).all():
        raise ValueError(
            f"target - eye overflows: eye {eye_v.tolist()}, target {target_v.tolist()}"
        )
    forward /= _length(forward)
    top = np.abs(up_v).max()
    if top > 0 and not 1e-150 < top < 1e150:  # its cross product would under- or overflow
        up_v = up_v / top
    right = np.cross(forward, up_v)
    norm = np.linalg.norm(right)
    if norm <= 1e-12 * max(np.linalg.norm(up_v), 1e-300):
        raise ValueError(
            f"up {up_v.tolist()} must not be parallel to the viewing direction "
            f"{forward.tolist()}; choose another up vector"
        )
    right /= norm
    down = np.cross(forward, right)
    R = np.stack([right, down, forward])
    return R, -R @ eye_v


class Camera:
    """A pinhole camera ``K [R | t]`` with an optional distorting lens.

    Parameters
    ----------
    K : array_like, shape (3, 3)
        Intrinsics ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` in pixels;
        ``fx, fy != 0``.
    R : array_like, shape (3, 3), optional
        World-to-camera rotation (orthonormal, ``det R = +1`` to 1e-9);
        identity by default. ``cv2.Rodrigues(rvec)[0]`` gives it from OpenCV.
    t : array_like, shape (3,) or (3, 1), optional
        World-to-camera translation, ``X_cam = R @ X + t``; zero by default.
    dist : array_like, optional
        Lens coefficients in OpenCV's order ``(k1, k2, p1, p2[, k3[, k4, k5,
        k6]])`` for ``model="brown_conrady"`` (OpenCV's results pass unchanged),
        or one ``lambda`` for ``model="division"``. None: no distortion.
    model : {"brown_conrady", "division"}
        Distortion model, see :func:`imgform_rs.distort_points`.
    image_size : (int, int), optional
        ``(height, width)`` in pixels; needed only by :attr:`fov`.

    Raises
    ------
    TypeError
        Non-numeric arrays.
    ValueError
        Wrong shapes, non-finite entries, a singular or malformed ``K``, an
        ``R`` that is not a rotation, a wrong number of coefficients, an
        unknown model or a bad ``image_size``.

    Examples
    --------
    >>> cam = Camera.from_intrinsics(800.0, 800.0, 320.0, 240.0, t=[0.0, 0.0, 2.0])
    >>> cam.project([0.5, -0.25, 2.0])
    array([420., 190.])
    >>> cam.unproject([420.0, 190.0], 4.0)
    array([ 0.5 , -0.25,  2.  ])
    """

    def __init__(
        self,
        K: Any,
        R: Any = None,
        t: Any = None,
        dist: Any = None,
        *,
        model: DistortionModel = "brown_conrady",
        image_size: Any = None,
    ) -> None:
        self._K = _frozen(as_matrix(K, (3, 3), "K"))
        self._R = _frozen(np.eye(3) if R is None else as_matrix(R, (3, 3), "R"))
        self._t = _frozen(np.zeros(3) if t is None else _vector3(t, "t"))
        coeffs = lens_coefficients(dist)
        self._dist = _frozen(np.array(coeffs, dtype=np.float64))
        self._model = model_name(model)
        self._image_size = _image_size(image_size)
        self._native = _native.NativeCamera(self._K, self._R, self._t, coeffs, self._model)

    @classmethod
    def from_intrinsics(
        cls,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
        skew: float = 0.0,
        R: Any = None,
        t: Any = None,
        dist: Any = None,
        *,
        model: DistortionModel = "brown_conrady",
        image_size: Any = None,
    ) -> Camera:
        """A camera from focal lengths, principal point and skew, in pixels.

        Examples
        --------
        >>> Camera.from_intrinsics(500.0, 500.0, 320.0, 240.0).K
        array([[500.,   0., 320.],
               [  0., 500., 240.],
               [  0.,   0.,   1.]])
        """
        K = [[fx, skew, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]
        return cls(K, R, t, dist, model=model, image_size=image_size)

    @classmethod
    def from_fov(
        cls,
        fov: float,
        image_size: Any,
        *,
        axis: FovAxis = "horizontal",
        R: Any = None,
        t: Any = None,
        dist: Any = None,
        model: DistortionModel = "brown_conrady",
    ) -> Camera:
        """A camera with square pixels and the principal point at the image
        centre whose pinhole field of view along ``axis`` is ``fov``.

        ``f = (extent / 2) / tan(fov / 2)`` with ``extent`` the width, height or
        diagonal of the image in pixels, and ``(cx, cy) = ((w - 1) / 2, (h - 1)
        / 2)``, so :attr:`fov` of the result gives ``fov`` back (exactly so
        without a lens; a lens changes the field it sees).

        Parameters
        ----------
        fov : float
            Field of view in radians, in (0, pi).
        image_size : (int, int)
            ``(height, width)`` in pixels.
        axis : {"horizontal", "vertical", "diagonal"}
            Which field ``fov`` is.

        Examples
        --------
        >>> cam = Camera.from_fov(np.deg2rad(90.0), (480, 640))
        >>> round(float(cam.K[0, 0]), 9), round(float(np.rad2deg(cam.fov[0])), 9)
        (320.0, 90.0)
        """
        fov = real(fov, "fov")
        if not 0.0 < fov < math.pi:
            raise ValueError(f"fov must be an angle in radians in (0, pi), got {fov}")
        size = _image_size(image_size)
        if size is None:
            raise ValueError("from_fov needs image_size=(height, width), got None")
        height, width = size
        extents = {"horizontal": width, "vertical": height, "diagonal": math.hypot(width, height)}
        if axis not in extents:
            raise ValueError(f"axis must be 'horizontal', 'vertical' or 'diagonal', got {axis!r}")
        f = 0.5 * extents[axis] / math.tan(0.5 * fov)
        return cls.from_intrinsics(
            f,
            f,
            0.5 * (width - 1),
            0.5 * (height - 1),
            R=R,
            t=t,
            dist=dist,
            model=model,
            image_size=size,
        )

    @property
    def K(self) -> Float64Array:
        """Intrinsics, (3, 3) float64 (read-only)."""
        return self._K

    @property
    def R(self) -> Float64Array:
        """World-to-camera rotation, (3, 3) float64 (read-only)."""
        return self._R

    @property
    def t(self) -> Float64Array:
        """World-to-camera translation, (3,) float64 (read-only)."""
        return self._t

    @property
    def dist(self) -> Float64Array:
        """Lens coefficients as given (empty without a lens), float64 (read-only)."""
        return self._dist

    @property
    def model(self) -> str:
        """Distortion model name."""
        return self._model

    @property
    def image_size(self) -> tuple[int, int] | None:
        """``(height, width)`` in pixels, or None when not given."""
        return self._image_size

    @property
    def center(self) -> Float64Array:
        """The camera centre in world coordinates, ``-R.T @ t``, (3,) float64."""
        return np.array(self._native.center())

    @property
    def fov(self) -> tuple[float, float, float]:
        """Horizontal, vertical and diagonal field of view in radians.

        The angles between the rays through the outer edges of opposite border
        pixels (the image spans ``[-0.5, width - 0.5]``): along the principal
        row, along the principal column, and between the top-left and
        bottom-right corners. The rays are undistorted, so with a lens this is
        the field the lens really sees; NaN if an edge lies where the lens
        has no inverse.

        Raises
        ------
        ValueError
            The camera was built without ``image_size``.
        """
        if self._image_size is None:
            raise ValueError(
                "fov needs the image size: build the Camera with image_size=(height, width)"
            )
        height, width = self._image_size
        return self._native.fov(width, height)

    def project(self, points_world: Any) -> Float64Array:
        """Project world points to pixels.

        Parameters
        ----------
        points_world : array_like, shape (N, 3) or (3,)
            Points in world coordinates.

        Returns
        -------
        ndarray, float64, shape (N, 2) or (2,)
            Pixels ``(u, v)``. Points at or behind the pinhole (``Z_cam <= 0``)
            have no image and come back as NaN, as do points the lens has no
            image of: beyond the fold of its model, where Brown-Conrady's
            polynomial turns back (``cv2.projectPoints`` then puts a point
            on the wrong side of the axis) or the division model has no root.

        Raises
        ------
        TypeError
            Non-numeric input.
        ValueError
            Wrong shape or non-finite coordinates.
        """
        arr, single = as_points(points_world, 3, "points")
        return unbatch(self._native.project(arr), single)

    def unproject(self, pixels: Any, depth: Any) -> Float64Array:
        """The world points seen at ``pixels`` at camera-frame depth ``depth``.

        Pixels are undistorted first, so ``unproject(project(X), Z_cam) == X``.

        Parameters
        ----------
        pixels : array_like, shape (N, 2) or (2,)
            Pixels ``(u, v)``.
        depth : float or array_like, shape (N,)
            Depth along the optical axis (``Z_cam``, not the distance along the
            ray); a scalar applies to every pixel.

        Returns
        -------
        ndarray, float64, shape (N, 3) or (3,)
            World points; NaN for ``depth <= 0`` (no pixel sees such a point)
            and where the lens inverse does not converge.

        Raises
        ------
        TypeError
            Non-numeric input.
        ValueError
            Wrong shapes or non-finite pixels or depths.
        """
        arr, single = as_points(pixels, 2, "pixels")
        z = as_float_array(depth, "depth")
        n = len(arr)
        if z.ndim == 0:
            z = np.full(n, float(z))
        elif z.shape != (n,):
            raise ValueError(
                f"depth must be a scalar or have shape ({n},), one value per pixel, got {z.shape}"
            )
        return unbatch(self._native.unproject(arr, np.ascontiguousarray(z)), single)

    def rays(self, pixels: Any) -> Float64Array:
        """Unit world directions of the rays through ``pixels`` (undistorted).

        Returns
        -------
        ndarray, float64, shape (N, 3) or (3,)
            Unit vectors pointing into the scene (``Z_cam > 0``); a point
            ``center + s * ray`` with ``s > 0`` projects back to the pixel. NaN
            where the lens inverse does not converge.
        """
        arr, single = as_points(pixels, 2, "pixels")
        return unbatch(self._native.rays(arr), single)

    def look_at(self, eye: Any, target: Any, up: Any = (0.0, 1.0, 0.0)) -> Camera:
        """This camera (same intrinsics and lens) moved to ``eye`` and aimed at
        ``target``; see :func:`look_at`.

        Examples
        --------
        >>> cam = Camera.from_intrinsics(500.0, 500.0, 320.0, 240.0)
        >>> cam.look_at([0.0, 2.0, -10.0], [0.0, 2.0, 0.0]).project([0.0, 2.0, 5.0])
        array([320., 240.])
        """
        R, t = look_at(eye, target, up)
        return Camera(self._K, R, t, self._dist, model=self._model, image_size=self._image_size)

    def __reduce__(self):
        # The native object cannot be pickled; rebuilding from the parameters
        # re-validates them and works across processes (multiprocessing).
        return _rebuild, (self._K, self._R, self._t, self._dist, self._model, self._image_size)

    def __repr__(self) -> str:
        fx, fy, cx, cy = self._K[0, 0], self._K[1, 1], self._K[0, 2], self._K[1, 2]
        return (
            f"Camera(fx={fx:g}, fy={fy:g}, cx={cx:g}, cy={cy:g}, skew={self._K[0, 1]:g}, "
            f"center={self.center.tolist()}, dist={self._dist.tolist()}, "
            f"model={self._model!r}, image_size={self._image_size})"
        )


def _rebuild(K, R, t, dist, model, image_size) -> Camera:
    return Camera(K, R, t, dist, model=model, image_size=image_size)


def vanishing_point(camera: Camera, direction: Any) -> VanishingPoint:
    """The vanishing point of a world direction: the image of the point at
    infinity along it, where the images of all 3D lines parallel to it meet.

    ``direction`` and ``-direction`` share it. A direction parallel to the image
    plane has its vanishing point at infinity: the image lines stay parallel;
    the result says so (``at_infinity``) and gives their image direction
    instead of a meaningless huge coordinate. With a lens, ``point`` is the
    distorted image of the ideal vanishing point (the images of straight lines
    are then curves through it); ``homogeneous`` stays the ideal one.

    Parameters
    ----------
    camera : Camera
    direction : array_like, shape (3,)
        A non-zero world direction.

    Returns
    -------
    VanishingPoint
        ``(point, homogeneous, at_infinity)``.

    Raises
    ------
    ValueError
        A zero or non-finite direction.

    Examples
    --------
    >>> cam = Camera.from_intrinsics(500.0, 500.0, 320.0, 240.0)
    >>> vanishing_point(cam, [0.0, 0.0, 1.0]).point
    array([320., 240.])
    >>> vanishing_point(cam, [1.0, 0.0, 0.0]).at_infinity
    True
    """
    point, homogeneous, at_infinity = camera._native.vanishing_point(
        _direction(direction, "direction")
    )
    return VanishingPoint(np.array(point), np.array(homogeneous), at_infinity)


def vanishing_line(camera: Camera, plane_normal: Any) -> Float64Array:
    """The vanishing line of all planes with world normal ``plane_normal``.

    ``l = K^-T R n``, scaled so that ``a² + b² = 1``: then ``a u + b v + c`` is
    the signed distance in pixels of pixel ``(u, v)`` from the line. The
    vanishing points of all directions in those planes lie on it; the horizon
    is the vanishing line of the ground plane (normal = the world's up). It is
    the line of the ideal pinhole image (with a lens, its image is a curve). A
    plane parallel to the image plane vanishes at the line at infinity,
    returned as ``(0, 0, 1)``.

    Parameters
    ----------
    camera : Camera
    plane_normal : array_like, shape (3,)
        A non-zero world normal.

    Returns
    -------
    ndarray, float64, shape (3,)
        ``(a, b, c)``.

    Raises
    ------
    ValueError
        A zero or non-finite normal.

    Examples
    --------
    >>> cam = Camera.from_intrinsics(500.0, 500.0, 320.0, 240.0)
    >>> vanishing_line(cam, [0.0, -1.0, 0.0])  # level camera: the horizon is row cy
    array([  0.,  -1., 240.])
    """
    return np.array(camera._native.vanishing_line(_direction(plane_normal, "plane_normal")))

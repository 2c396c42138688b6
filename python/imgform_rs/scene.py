"""The built-in sample scene: a checkerboard ground plane and boxes at several depths.

A small NumPy ray caster, so the demo and the tests have a 3D scene with exact
depth, parallel edges (for vanishing points) and sharp texture at every distance
(for depth of field) without any asset file. World frame: y up, ground at y = 0.
:func:`render` averages the ground's checkerboard over each pixel's footprint, so
its horizon fades to grey instead of aliasing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ._arrays import Float64Array


@dataclass(frozen=True)
class Box:
    """An axis-aligned box standing on the ground, with a base colour (RGB in [0, 1])."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    colour: tuple[float, float, float]


# Three boxes at near, middle and far distance, so one focus distance can show
# the foreground and background out of focus at once.
BOXES = (
    Box((0.2, 0.0, 2.2), (1.2, 1.0, 3.2), (0.85, 0.25, 0.2)),
    Box((0.4, 0.0, 7.0), (1.6, 1.6, 8.2), (0.2, 0.45, 0.85)),
    Box((-1.5, 0.0, 15.0), (0.5, 3.0, 17.0), (0.95, 0.75, 0.15)),
)
# Light from the upper left behind the camera, unit length.
LIGHT = np.array([-0.4, 0.8, -0.45]) / np.linalg.norm([-0.4, 0.8, -0.45])


def _hit_boxes(origin: Float64Array, dirs: Float64Array):
    """Nearest box hit per ray: distance (inf if none), box index and face normal."""
    n = len(dirs)
    best = np.full(n, np.inf)
    which = np.full(n, -1)
    normal = np.zeros((n, 3))
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dirs
        for i, box in enumerate(BOXES):
            t0 = (np.array(box.lo) - origin) * inv
            t1 = (np.array(box.hi) - origin) * inv
            near = np.minimum(t0, t1)
            t_in = near.max(axis=1)
            t_out = np.maximum(t0, t1).min(axis=1)
            hit = (t_in <= t_out) & (t_in > 0) & (t_in < best)
            best[hit] = t_in[hit]
            which[hit] = i
            axis = near.argmax(axis=1)
            face = np.zeros((n, 3))
            face[np.arange(n), axis] = -np.sign(dirs[np.arange(n), axis])
            normal[hit] = face[hit]
    return best, which, normal


# The ground's checkerboard: 1 m cells, light and dark, with red grid lines
# LINE_HALF m either side of every cell edge.
LIGHT_CELL, DARK_CELL = np.array([0.92, 0.9, 0.85]), np.array([0.18, 0.2, 0.22])
LINE_COLOUR, LINE_HALF = np.array([0.55, 0.1, 0.1]), 0.02
_INTERIOR = 1.0 - 2.0 * LINE_HALF


def _interior(t: Float64Array, r: Float64Array) -> Float64Array:
    """Mean over [t - r, t + r] of g(t): 1 inside a cell, 0 on a grid line.

    Its integral from 0 is ``floor(t) (1 - 2 LINE_HALF)`` plus the part of the
    current cell past its line, so the box mean is a difference of two values
    of that closed form; ``r = 0`` gives the point value.
    """

    def integral(x: Float64Array) -> Float64Array:
        cell = np.floor(x)
        return cell * _INTERIOR + np.clip(x - cell - LINE_HALF, 0.0, _INTERIOR)

    return _box_mean(integral, t, r)


def _signed_interior(t: Float64Array, r: Float64Array) -> Float64Array:
    """Mean over [t - r, t + r] of g(t) s(t), s = (-1)^floor(t) the cells' sign.

    The integral has period 2 (a cell's +1 cancels the next one's -1), so it
    is a trapezoid wave: up across an even cell's interior, down across an
    odd one's.
    """

    def integral(x: Float64Array) -> Float64Array:
        p = np.mod(x, 2.0)
        rise = np.clip(p - LINE_HALF, 0.0, _INTERIOR)
        fall = _INTERIOR - np.clip(p - 1.0 - LINE_HALF, 0.0, _INTERIOR)
        return np.where(p < 1.0, rise, fall)

    return _box_mean(integral, t, r)


def _box_mean(integral, t: Float64Array, r: Float64Array) -> Float64Array:
    """``(F(t + r) - F(t - r)) / 2r`` of an antiderivative ``F``.

    ``r`` is raised to at least 1e-9 |t|: below that the difference of two
    nearly equal values of ``F`` would lose its digits. At that width the mean
    of a piecewise-constant g is its point value (to ~1e-6) away from an edge,
    so ``r = 0`` point-samples."""
    floor = 1e-9 * np.maximum(np.abs(t), 1.0)
    half = np.maximum(r, floor)
    return (integral(t + half) - integral(t - half)) / (2.0 * half)


def _checker(points: Float64Array, half_widths: Float64Array | None = None) -> Float64Array:
    """Ground colour (N, 3) at ``points``, box-filtered over ``±half_widths``
    (N, 2) metres along x and z (none: point-sampled).

    With ``g`` 1 inside a cell and 0 on a line and ``s`` the cell's sign
    along each axis, the colour is
    ``line + (mid - line) g(x) g(z) - amp (g s)(x) (g s)(z)``
    (``mid``/``amp`` the half sum / difference of the light and dark cells).
    Every term is a product of one function of x and one of z, so its mean
    over an axis-aligned box is the product of two 1-D means, each a
    closed form: the filtered texture is exact for that box, at any distance.
    """
    x, z = points[:, 0], points[:, 2]
    r = np.zeros((len(points), 2)) if half_widths is None else half_widths
    mid, amp = (LIGHT_CELL + DARK_CELL) / 2, (LIGHT_CELL - DARK_CELL) / 2
    inside = _interior(x, r[:, 0]) * _interior(z, r[:, 1])
    signed = _signed_interior(x, r[:, 0]) * _signed_interior(z, r[:, 1])
    return LINE_COLOUR + inside[:, None] * (mid - LINE_COLOUR) - signed[:, None] * amp


def ground_steps(
    dirs: Float64Array, t: Float64Array, d_du: Float64Array, d_dv: Float64Array
) -> tuple[Float64Array, Float64Array]:
    """How far (x, z), shape (N, 2) each, a ray's ground point moves over one
    pixel step along u and along v: the two edges of its footprint.

    A ray ``o + t d`` meets the plane y = 0 at ``P = o - o_y d / d_y``; a
    pixel step changes ``d`` by ``δd`` (``d_du`` or ``d_dv``) and ``P`` by
    ``t (δd - d δd_y / d_y)`` (Igehy's ray differentials).
    """
    steps = [t[:, None] * (d - dirs * (d[:, 1] / dirs[:, 1])[:, None]) for d in (d_du, d_dv)]
    return steps[0][:, [0, 2]], steps[1][:, [0, 2]]


#: Most strips a footprint is cut into (see :func:`filtered_checker`): 32
#: keeps the demo's horizon rows within 0.01 of a 32 x 32-ray reference.
MAX_STRIPS = 32


def filtered_checker(points: Float64Array, a: Float64Array, b: Float64Array) -> Float64Array:
    """Mean ground colour (N, 3) over the parallelograms centred on
    ``points`` with edges ``a`` and ``b`` (N, 2 each, in x and z).

    :func:`_checker` averages exactly over axis-aligned boxes; a footprint
    near the horizon is a long thin parallelogram at an angle to the grid,
    and one box of the same spread would blur across the stripes it only
    grazes. So the footprint is cut along its longer edge into strips about
    as long as they are wide (at most :data:`MAX_STRIPS`), and each strip
    stands for a box with its spread (second moment) along x and along z: a
    strip with edges ``p`` and ``q`` gets a box ``sqrt(p_x² + q_x²)`` wide
    along x (likewise z), where its bounding box, ``|p_x| + |q_x|``, would
    blur diagonal strips more than they reach.
    """
    a_len, b_len = np.hypot(*a.T), np.hypot(*b.T)
    swap = a_len < b_len
    long = np.where(swap[:, None], b, a)
    short = np.where(swap[:, None], a, b)
    ratio = np.maximum(a_len, b_len) / np.maximum(np.minimum(a_len, b_len), 1e-300)
    strips = np.clip(np.ceil(ratio), 1, MAX_STRIPS).astype(np.int64)
    # Most footprints are one strip: sorted by strip count, the footprints
    # that still have an i-th strip are a prefix, so no pass masks them all.
    order = np.argsort(-strips, kind="stable")
    m, long, short, points = strips[order, None], long[order], short[order], points[order]
    total = np.zeros((len(points), 3))
    for i in range(int(m.max(initial=0))):
        n = int(np.searchsorted(-m[:, 0], -i, side="left"))
        centre = points[:n].copy()
        centre[:, [0, 2]] += ((i + 0.5) / m[:n] - 0.5) * long[:n]
        half = np.hypot(long[:n] / m[:n], short[:n]) / 2.0
        total[:n] += _checker(centre, half)
    out = np.empty_like(total)
    out[order] = total / m
    return out


def shade(
    origin: Float64Array,
    dirs: Float64Array,
    footprint: tuple[Float64Array, Float64Array] | None = None,
) -> tuple[Float64Array, Float64Array]:
    """Colour (N, 3) in [0, 1] and distance along each unit ray (N,) (inf for sky).

    ``footprint``, the change of each ray's direction over one pixel step
    along u and along v (two (N, 3) arrays: the rays through the next column
    and the next row minus these), makes the ground's texture the mean over
    each pixel's footprint (:func:`filtered_checker`) instead of its value
    at the ray: the checkerboard then fades to its mean grey at the horizon
    instead of aliasing into coloured noise.
    """
    t_box, which, normal = _hit_boxes(origin, dirs)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_ground = -origin[1] / dirs[:, 1]
    # Ahead of the ray only: from below the ground, a ray going down never
    # meets it (its negative distance used to paint it).
    t_ground = np.where(t_ground > 0, t_ground, np.inf)
    ground = t_ground < t_box
    t = np.minimum(t_box, t_ground)
    sky = np.clip(0.55 + 0.45 * dirs[:, 1:2], 0, 1) * np.array([0.55, 0.75, 1.0])
    colour = sky.copy()
    hit_ground = ground & np.isfinite(t)
    pts = origin + dirs[hit_ground] * t[hit_ground, None]
    if footprint is None:
        colour[hit_ground] = _checker(pts)
    else:
        d_du, d_dv = (np.asarray(d, np.float64)[hit_ground] for d in footprint)
        steps = ground_steps(dirs[hit_ground], t[hit_ground], d_du, d_dv)
        colour[hit_ground] = filtered_checker(pts, *steps)
    hit_box = ~ground & np.isfinite(t)
    lambert = 0.35 + 0.65 * np.clip(normal[hit_box] @ LIGHT, 0, 1)
    box_colour = np.array([b.colour for b in BOXES])[which[hit_box]]
    colour[hit_box] = box_colour * lambert[:, None]
    return colour, t


def render(camera: Any, pixels: Float64Array) -> tuple[Float64Array, Float64Array]:
    """Colour (N, 3) in [0, 1] and z-depth (N,) (m; inf for sky) of the scene
    seen by ``camera`` (an :class:`imgform_rs.Camera`) through ``pixels``
    (N, 2), the ground's texture averaged over each pixel's footprint; one
    pixel (2,) gives a colour (3,) and a depth.

    The footprint comes from the rays through the next column and the next
    row (:func:`shade`'s ``footprint``), so lens distortion shapes it too.
    """
    pixels = np.asarray(pixels, np.float64)
    if pixels.shape == (2,):  # one pixel, as the point sets take it
        colour, depth = render(camera, pixels[None])
        return colour[0], depth[0]
    rays = camera.rays(pixels)
    d_du, d_dv = (camera.rays(pixels + step) - rays for step in ((1.0, 0.0), (0.0, 1.0)))
    colour, dist = shade(camera.center, rays, (d_du, d_dv))
    return colour, dist * (rays @ camera.R[2])

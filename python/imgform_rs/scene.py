"""The built-in sample scene: a checkerboard ground plane and boxes at several depths.

A small NumPy ray caster, so the demo and the tests have a 3D scene with exact
depth, parallel edges (for vanishing points) and sharp texture at every distance
(for depth of field) without any asset file. World frame: y up, ground at y = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

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


def _checker(points: Float64Array) -> Float64Array:
    """Ground texture: 1 m checkerboard with thin grid lines, RGB."""
    x, z = points[:, 0], points[:, 2]
    cell = (np.floor(x) + np.floor(z)) % 2
    base = np.where(cell[:, None] > 0, [0.92, 0.9, 0.85], [0.18, 0.2, 0.22])
    fx, fz = x - np.floor(x), z - np.floor(z)
    line = (np.minimum(fx, 1 - fx) < 0.02) | (np.minimum(fz, 1 - fz) < 0.02)
    return np.where(line[:, None], [0.55, 0.1, 0.1], base)


def shade(origin: Float64Array, dirs: Float64Array) -> tuple[Float64Array, Float64Array]:
    """Colour (N, 3) in [0, 1] and distance along each unit ray (N,) (inf for sky)."""
    t_box, which, normal = _hit_boxes(origin, dirs)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_ground = np.where(dirs[:, 1] < 0, -origin[1] / dirs[:, 1], np.inf)
    ground = t_ground < t_box
    t = np.minimum(t_box, t_ground)
    sky = np.clip(0.55 + 0.45 * dirs[:, 1:2], 0, 1) * np.array([0.55, 0.75, 1.0])
    colour = sky.copy()
    hit_ground = ground & np.isfinite(t)
    pts = origin + dirs[hit_ground] * t[hit_ground, None]
    colour[hit_ground] = _checker(pts)
    hit_box = ~ground & np.isfinite(t)
    lambert = 0.35 + 0.65 * np.clip(normal[hit_box] @ LIGHT, 0, 1)
    box_colour = np.array([b.colour for b in BOXES])[which[hit_box]]
    colour[hit_box] = box_colour * lambert[:, None]
    return colour, t

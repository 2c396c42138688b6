"""Synthetic single-view metrology scenes, shared by tests/test_metrology.py and
benchmarks/metrology.py.

A camera at height ``eye_height`` above the ground (world y up, ground y = 0),
pitched down, yawed and rolled, looks at vertical poles standing on the ground
and at ground lines along two horizontal directions. Everything is projected by
:class:`imgform_rs.Camera`, so the truth (pole heights, vanishing points, the
horizon) is exact.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import imgform_rs as ig

UP = np.array([0.0, 1.0, 0.0])
IMAGE_SIZE = (480, 640)


@dataclass(frozen=True)
class Pose:
    eye_height: float
    pitch: float  # radians below the horizontal
    yaw: float
    roll: float
    hfov: float


@dataclass(frozen=True)
class PoleScene:
    camera: ig.Camera
    eye_height: float
    heights: np.ndarray  # (P,)
    poles: np.ndarray  # (P, 4): base (u, v) then top (u, v), pixels
    ground: tuple[np.ndarray, np.ndarray]  # (M, 4) segments along two directions
    directions: tuple[np.ndarray, np.ndarray]  # their world directions


def make_camera(pose: Pose) -> ig.Camera:
    forward = np.array(
        [
            np.sin(pose.yaw) * np.cos(pose.pitch),
            -np.sin(pose.pitch),
            np.cos(pose.yaw) * np.cos(pose.pitch),
        ]
    )
    right = np.array([np.cos(pose.yaw), 0.0, -np.sin(pose.yaw)])
    up = np.cos(pose.roll) * UP + np.sin(pose.roll) * right
    eye = np.array([0.0, pose.eye_height, 0.0])
    cam = ig.Camera.from_fov(pose.hfov, IMAGE_SIZE)
    return cam.look_at(eye, eye + forward, up)


def ground_points(cam: ig.Camera, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` ground points seen in the image no further than 40 eye heights."""
    eye = cam.center
    found: list[np.ndarray] = []
    while len(found) < n:
        pix = rng.uniform((0, 0), (IMAGE_SIZE[1] - 1, IMAGE_SIZE[0] - 1), size=(4 * n, 2))
        rays = cam.rays(pix)
        s = -eye[1] / np.minimum(rays[:, 1], -1e-12)
        keep = (rays[:, 1] < 0) & (s < 40 * eye[1])
        found.extend(eye + s[keep, None] * rays[keep])
    return np.array(found[:n])


def in_front(cam: ig.Camera, points: np.ndarray) -> bool:
    return bool(np.all(((points @ cam.R.T) + cam.t)[..., 2] > 1e-3))


def pole_scene(pose: Pose, seed: int, n_poles: int = 6, n_lines: int = 8) -> PoleScene | None:
    """A scene for ``pose``, or None when a random pole or line would reach
    behind the camera (the caller draws another)."""
    rng = np.random.default_rng(seed)
    cam = make_camera(pose)
    h = pose.eye_height
    base = ground_points(cam, n_poles, rng)
    heights = rng.uniform(0.2, 2.5, n_poles) * h
    top = base + heights[:, None] * UP
    angles = pose.yaw + np.array([-1.0, 1.0]) * rng.uniform(0.35, 1.0, 2)
    directions = tuple(np.array([np.sin(a), 0.0, np.cos(a)]) for a in angles)
    starts = [ground_points(cam, n_lines, rng) for _ in directions]
    ends = [
        p + rng.uniform(0.3, 2.0, (n_lines, 1)) * h * d
        for p, d in zip(starts, directions, strict=True)
    ]
    if not all(in_front(cam, p) for p in (top, *ends)):
        return None
    poles = np.hstack([cam.project(base), cam.project(top)])
    ground = tuple(
        np.hstack([cam.project(p), cam.project(q)]) for p, q in zip(starts, ends, strict=True)
    )
    return PoleScene(cam, h, heights, poles, ground, directions)


def random_scenes(n: int, seed: int) -> list[PoleScene]:
    """``n`` scenes at random poses (1-5 m up, pitched down 0.15-0.5 rad, any
    yaw, rolled up to 0.3 rad, 60° field) with 10 poles and 20 lines per
    direction, the same for the same ``seed``."""
    rng = np.random.default_rng(seed)
    found: list[PoleScene] = []
    while len(found) < n:
        pose = Pose(
            rng.uniform(1.0, 5.0),
            rng.uniform(0.15, 0.5),
            rng.uniform(-np.pi, np.pi),
            rng.uniform(-0.3, 0.3),
            np.deg2rad(60.0),
        )
        scene = pole_scene(pose, int(rng.integers(1 << 31)), n_poles=10, n_lines=20)
        if scene is not None:
            found.append(scene)
    return found


def algebraic_vanishing_point(segments: np.ndarray) -> np.ndarray:
    """The textbook peer: the homogeneous point minimising ``sum (l_i · v)²``
    over the segments' lines ``l_i`` (Hartley-normalised, ``a² + b² = 1``),
    the smallest right singular vector; no robustness, no end-point model."""
    ends = np.vstack([segments[:, :2], segments[:, 2:]])
    c = ends.mean(axis=0)
    s = np.sqrt(2.0) / np.linalg.norm(ends - c, axis=1).mean()
    T = np.array([[s, 0.0, -s * c[0]], [0.0, s, -s * c[1]], [0.0, 0.0, 1.0]])
    ones = np.ones((len(segments), 1))
    p1 = np.hstack([segments[:, :2], ones]) @ T.T
    p2 = np.hstack([segments[:, 2:], ones]) @ T.T
    lines = np.cross(p1, p2)
    lines /= np.linalg.norm(lines[:, :2], axis=1, keepdims=True)
    return np.linalg.solve(T, np.linalg.svd(lines)[2][-1])


def vp_angle(cam: ig.Camera, estimate: np.ndarray, truth: np.ndarray) -> float:
    """Angle (radians) between the viewing directions of two homogeneous
    vanishing points, blind to sign (a vanishing point is a line of sight)."""
    k_inv = np.linalg.inv(cam.K)
    a, b = k_inv @ estimate, k_inv @ truth
    # atan2 of |sin| and |cos|: arccos loses half the digits near 0.
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), abs(a @ b)))


@dataclass(frozen=True)
class Measurement:
    height_errors: np.ndarray  # relative, of the non-reference poles
    camera_height_error: float  # relative
    vp_errors: np.ndarray  # radians: vertical, then the two horizontal
    horizon: np.ndarray
    vertical_vp: np.ndarray


def measure(scene: PoleScene, sigma: float = 0.0, seed: int = 0) -> Measurement:
    """Fits the vanishing points and the horizon to the scene's segments with
    Gaussian noise ``sigma`` px on every end point, then measures the poles
    against pole 0."""
    rng = np.random.default_rng(seed)

    def noisy(segments: np.ndarray) -> np.ndarray:
        return segments + rng.normal(0.0, sigma, segments.shape)

    poles = noisy(scene.poles)
    vertical = ig.fit_vanishing_point(poles, allow_infinite=True)
    horizontal = [ig.fit_vanishing_point(noisy(g)) for g in scene.ground]
    horizon = ig.fit_horizon(*horizontal)
    base, top = poles[:, :2], poles[:, 2:]
    args = (base[0], top[0], scene.heights[0])
    heights = ig.relative_height(horizon, base[1:], top[1:], *args, vertical_vp=vertical)
    cam_h = ig.camera_height(horizon, *args, vertical_vp=vertical)
    truths = [ig.vanishing_point(scene.camera, d).homogeneous for d in (UP, *scene.directions)]
    fits = [vertical, *horizontal]
    return Measurement(
        height_errors=np.abs(heights / scene.heights[1:] - 1.0),
        camera_height_error=abs(cam_h / scene.eye_height - 1.0),
        vp_errors=np.array(
            [vp_angle(scene.camera, f.homogeneous, t) for f, t in zip(fits, truths, strict=True)]
        ),
        horizon=horizon,
        vertical_vp=vertical.homogeneous,
    )

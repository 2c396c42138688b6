"""The main job of ``make demo``: a synthetic 3D scene through the camera models."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._png import write_png
from .projection import project_pinhole


def _ground_grid(step: float = 0.5, extent: float = 10.0, depth: float = 40.0) -> np.ndarray:
    xs = np.arange(-extent, extent + step, step)
    zs = np.arange(1.0, depth, step / 4)
    x, z = np.meshgrid(xs, zs)
    return np.stack([x.ravel(), np.full(x.size, 1.5), z.ravel()], axis=1)


def run(out: Path) -> list[Path]:
    """Render the scene and return the paths written under ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    width, height, f_px = 640, 480, 500.0
    uv = project_pinhole(_ground_grid(), f_px, invert=False) + [width / 2, height / 2]
    inside = np.all((uv >= 0) & (uv < [width, height]), axis=1)
    image = np.zeros((height, width), np.uint8)
    cols, rows = np.round(uv[inside]).astype(int).T
    image[np.minimum(rows, height - 1), np.minimum(cols, width - 1)] = 255
    return [write_png(out / "pinhole_ground.png", image)]

"""Single-view metrology: the error curve under end-point noise, and speed.

Scenes (tests/metrology_scene.py): a camera 1-5 m above the ground, pitched
down 0.15-0.5 rad, any yaw, rolled up to 0.3 rad, 60° horizontal field on a
640x480 image; 10 vertical poles (0.2-2.5 eye heights tall) and 20 ground lines
along each of two horizontal directions, all projected by ``imgform_rs.Camera``.
Gaussian noise of ``sigma`` px is added to every segment end point (poles
included: their end points are also the bases and tops measured). Vanishing
points are fitted with ``fit_vanishing_point``, the horizon with
``fit_horizon``, and the 9 other poles are measured against pole 0 with
``relative_height``. Reported: median and 90th percentile of the relative
height error and of the vanishing-point angular error (angle between the
viewing directions of the fitted and the true vanishing point), and the
camera-height error. Then the horizontal vanishing points against the
textbook algebraic least-squares fit (numpy SVD of the normalised lines), and
the speed of the calls.

Run: ``.venv/bin/python benchmarks/metrology.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
from _bench import measure as time_it
from _bench import table
from metrology_scene import algebraic_vanishing_point, measure, random_scenes, vp_angle

import imgform_rs as ig

SIGMAS = (0.0, 0.1, 0.25, 0.5, 1.0, 2.0)
N_SCENES = 60


def pct(values: np.ndarray, q: float, unit: float = 1.0) -> str:
    return f"{np.percentile(values, q) * unit:.3g}"


def error_curve() -> None:
    all_scenes = random_scenes(N_SCENES, seed=7)
    rows = []
    for sigma in SIGMAS:
        ms = [measure(s, sigma, seed=i) for i, s in enumerate(all_scenes)]
        heights = np.concatenate([m.height_errors for m in ms]) * 100
        vps = np.degrees(np.concatenate([m.vp_errors for m in ms]))
        cams = np.array([m.camera_height_error for m in ms]) * 100
        rows.append(
            [
                f"{sigma:g}",
                pct(heights, 50),
                pct(heights, 90),
                pct(vps, 50),
                pct(vps, 90),
                pct(cams, 50),
                pct(cams, 90),
            ]
        )
    headers = [
        "sigma px",
        "height err % p50",
        "p90",
        "VP err deg p50",
        "p90",
        "camera height err % p50",
        "p90",
    ]
    print(f"{N_SCENES} scenes x 9 poles, 3 vanishing points each")
    print(table(headers, rows))


def versus_algebraic() -> None:
    """Horizontal vanishing points (no outliers) from the same noisy segments:
    ours (threshold 4 sigma, at least the default 2 px, so no inlier is lost)
    against the algebraic least-squares fit of the segments' lines."""
    all_scenes = random_scenes(N_SCENES, seed=7)
    rng = np.random.default_rng(0)
    rows = []
    for sigma in SIGMAS[1:]:
        ours, peer = [], []
        for scene in all_scenes:
            for segs, d in zip(scene.ground, scene.directions, strict=True):
                noisy = segs + rng.normal(0.0, sigma, segs.shape)
                truth = ig.vanishing_point(scene.camera, d).homogeneous
                fit = ig.fit_vanishing_point(noisy, threshold=max(2.0, 4 * sigma))
                ours.append(vp_angle(scene.camera, fit.homogeneous, truth))
                peer.append(vp_angle(scene.camera, algebraic_vanishing_point(noisy), truth))
        ours_deg, peer_deg = np.degrees(ours), np.degrees(peer)
        rows.append(
            [
                f"{sigma:g}",
                pct(ours_deg, 50),
                pct(ours_deg, 90),
                pct(peer_deg, 50),
                pct(peer_deg, 90),
            ]
        )
    headers = ["sigma px", "ours deg p50", "p90", "algebraic LS deg p50", "p90"]
    print(table(headers, rows))


def speed() -> None:
    rng = np.random.default_rng(1)
    rows = []
    for n in (20, 200, 2000, 20000):
        starts = rng.uniform(0, 1000, (n, 2))
        d = np.array([1500.0, -400.0]) - starts
        ends = starts + 60 * d / np.linalg.norm(d, axis=1, keepdims=True)
        segs = np.hstack([starts, ends]) + rng.normal(0, 0.5, (n, 4))
        segs[: n // 4] = rng.uniform(0, 1000, (n // 4, 4))  # a quarter outliers
        t = time_it(f"fit {n}", lambda s=segs: ig.fit_vanishing_point(s), repeat=5)
        rows.append([f"fit_vanishing_point, {n} segments (25 % outliers)", f"{t.best * 1e3:.2f}"])
    n = 1_000_000
    base = rng.uniform(0, 640, (n, 2)) + [0, 300]
    top = base - [0, 50]
    ref = ([300.0, 400.0], [300.0, 350.0], 1.0)
    t = time_it(
        "heights",
        lambda: ig.relative_height([0.01, -1, 240], base, top, *ref, vertical_vp=[20, 5000]),
    )
    rows.append([f"relative_height, {n} objects", f"{t.best * 1e3:.2f}"])
    print(table(["call", "best ms"], rows))


if __name__ == "__main__":
    error_curve()
    print()
    versus_algebraic()
    print()
    speed()

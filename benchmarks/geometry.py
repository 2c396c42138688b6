"""Camera geometry throughput, side by side with NumPy and OpenCV, in one run.

- Projection of 10 M points: ``project_pinhole`` and ``Camera.project`` (full K, R,
  t) against NumPy's vectorised eq. 1-2 and ``cv2.projectPoints``. OpenCV runs on
  1 M points and is scaled (it is ~50x slower; say so in the table).
- Undistortion of a 24 MP image (uint8 RGB and uint16 single-channel,
  bilinear and bicubic) with a precomputed map: ``remap`` against
  ``cv2.remap`` with float32 maps and with the fixed-point maps of
  ``cv2.convertMaps``.
"""

from __future__ import annotations

import numpy as np
from _bench import measure, table

import imgform_rs as ig

N_POINTS = 10_000_000
N_CV2 = 1_000_000


def _scene_points(n: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    pts = rng.uniform(-5.0, 5.0, (n, 3))
    pts[:, 2] = rng.uniform(1.0, 50.0, n)
    return pts


def projection_rows() -> list[list[str]]:
    pts = _scene_points(N_POINTS)
    K = np.array([[1500.0, 0.0, 960.0], [0.0, 1500.0, 540.0], [0.0, 0.0, 1.0]])
    angle = np.deg2rad(10.0)
    R = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]])
    t = np.array([0.1, -0.2, 0.5])
    camera = ig.Camera(K, R, t)

    def numpy_eq12():
        return -1500.0 * pts[:, :2] / pts[:, 2:3]

    timings = [
        (measure("imgform project_pinhole", lambda: ig.project_pinhole(pts, 1500.0)), N_POINTS),
        (measure("imgform Camera.project (K, R, t)", lambda: camera.project(pts)), N_POINTS),
        (measure("NumPy eq. 1-2", numpy_eq12), N_POINTS),
    ]
    try:
        import cv2

        rvec = cv2.Rodrigues(R)[0]
        sub = pts[:N_CV2]
        timings.append(
            (
                measure(
                    "cv2.projectPoints (K, R, t), 1 M pts",
                    lambda: cv2.projectPoints(sub, rvec, t, K, None),
                    repeat=3,
                ),
                N_CV2,
            )
        )
    except ImportError:
        pass
    numpy_rate = timings[2][0].rate(N_POINTS)
    return [
        [
            tm.name,
            f"{tm.best * 1e3:.1f}",
            f"{tm.median * 1e3:.1f}",
            f"{tm.rate(n) / 1e6:.1f}",
            f"{tm.rate(n) / numpy_rate:.2f}",
        ]
        for tm, n in timings
    ]


def undistort_rows() -> list[list[str]]:
    h, w = 4000, 6000
    rng = np.random.default_rng(1)
    K = np.array([[4500.0, 0.0, w / 2], [0.0, 4500.0, h / 2], [0.0, 0.0, 1.0]])
    dist = np.array([-0.12, 0.03, 0.0, 0.0, 0.0])
    ours_map = ig.undistort_map(K, dist, (h, w))
    rgb = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    raw = rng.integers(0, 65536, (h, w), dtype=np.uint16)
    cases = [
        ("uint8 RGB bilinear", rgb, "bilinear"),
        ("uint16 (H, W) bilinear", raw, "bilinear"),
        ("uint8 RGB bicubic", rgb, "bicubic"),
        ("uint16 (H, W) bicubic", raw, "bicubic"),
    ]
    try:
        import cv2

        mx, my = cv2.initUndistortRectifyMap(K, dist, None, K, (w, h), cv2.CV_32FC1)
        m1, m2 = cv2.convertMaps(mx, my, cv2.CV_16SC2)
        flags = {"bilinear": cv2.INTER_LINEAR, "bicubic": cv2.INTER_CUBIC}
    except ImportError:
        cv2 = None
    mp = h * w / 1e6
    rows = []
    for label, img, interp in cases:
        ours = measure(
            f"{label}: imgform remap",
            lambda img=img, interp=interp: ig.remap(img, ours_map, interpolation=interp),
        )
        timings = [ours]
        if cv2 is not None:
            flag = flags[interp]
            timings += [
                measure(
                    f"{label}: cv2.remap, float32 maps",
                    lambda img=img, flag=flag: cv2.remap(img, mx, my, flag),
                ),
                measure(
                    f"{label}: cv2.remap, fixed-point maps",
                    lambda img=img, flag=flag: cv2.remap(img, m1, m2, flag),
                ),
            ]
        rows += [
            [
                tm.name,
                f"{tm.best * 1e3:.1f}",
                f"{tm.median * 1e3:.1f}",
                f"{mp / tm.best:.0f}",
                f"{tm.best / ours.best:.2f}",
            ]
            for tm in timings
        ]
    return rows


def main() -> None:
    print("### Projection of 10 M points (float64)\n")
    print(table(["method", "best ms", "median ms", "M points/s", "x NumPy"], projection_rows()))
    print("\n### Undistortion of a 24 MP image (precomputed map)\n")
    print(table(["method", "best ms", "median ms", "MP/s", "time / ours"], undistort_rows()))


if __name__ == "__main__":
    main()

"""Optics II: light-field refocusing.

- ``refocus`` of a 9x9 x 512x512 RGB uint8 light field at a sub-pixel alpha
  (the issue asks >= 20 frames/s on 2 cores), against a NumPy/OpenCV
  shift-and-add: ``cv2.warpAffine`` of each view by its shift (bilinear,
  ``BORDER_REFLECT_101``, the same mirror as ours) accumulated in float32 with
  ``cv2.accumulate``, averaged and rounded. Both are timed best of 3 in the
  same run; the fidelity column is the largest difference of the two results
  (OpenCV interpolates u8 with 5-bit fixed-point weights, we in float32).
"""

from __future__ import annotations

import numpy as np
from _bench import measure, table

import imgform_rs as ig

GRID, SIZE, ALPHA = (9, 9), (512, 512), 1.37


def light_field() -> np.ndarray:
    """Views of one random RGB texture moved by one pixel per view step."""
    img = np.random.default_rng(0).integers(0, 256, (*SIZE, 3), dtype=np.uint8)
    uc, vc = (GRID[0] - 1) // 2, (GRID[1] - 1) // 2
    rows = [
        [np.roll(img, (uc - u, vc - v), (0, 1)) for v in range(GRID[1])] for u in range(GRID[0])
    ]
    return np.ascontiguousarray(np.stack(rows))


def cv2_refocus(cv2, lf: np.ndarray, alpha: float) -> np.ndarray:
    """Shift-and-add with one ``cv2.warpAffine`` per view."""
    gu, gv, h, w, _ = lf.shape
    acc = np.zeros((h, w, 3), np.float32)
    for u in range(gu):
        for v in range(gv):
            shift = np.float32(
                [[1, 0, alpha * (v - (gv - 1) / 2)], [0, 1, alpha * (u - (gu - 1) / 2)]]
            )
            moved = cv2.warpAffine(
                lf[u, v], shift, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101
            )
            cv2.accumulate(moved, acc)
    return (acc / (gu * gv) + 0.5).astype(np.uint8)


def refocus() -> None:
    lf = light_field()
    frames = f"{GRID[0]}x{GRID[1]} x {SIZE[1]}x{SIZE[0]} RGB u8"
    ours = measure("refocus", lambda: ig.refocus(lf, ALPHA), repeat=3)
    row = [f"refocus {frames}, alpha {ALPHA}", f"{ours.rate(1):.1f} frames/s"]
    try:
        import cv2
    except ImportError:
        row += ["-", "-", "-"]
    else:
        peer = measure("cv2", lambda: cv2_refocus(cv2, lf, ALPHA), repeat=3)
        diff = np.abs(ig.refocus(lf, ALPHA).astype(int) - cv2_refocus(cv2, lf, ALPHA)).max()
        row += [
            f"cv2.warpAffine + accumulate {peer.rate(1):.1f} frames/s",
            f"{peer.best / ours.best:.1f}x",
            f"max |diff| {diff}",
        ]
    print(
        table(["task", "imgform_rs (best of 3)", "peer (best of 3)", "speed-up", "fidelity"], [row])
    )


def main() -> None:
    refocus()


if __name__ == "__main__":
    main()

"""Thin-lens optics: vectorised formulas and depth-aware defocus.

- ``circle_of_confusion`` over 10 M distances against the same NumPy expression.
- ``render_defocus`` of a synthetic scene (a textured ground plane receding from
  1 m to 10 m with a box in focus at 2 m; f = 50 mm, focused at 2 m) at 640x480
  and 12 MP. No peer renders depth-aware defocus, so as a yardstick we time
  OpenCV's depth-unaware ``filter2D`` with the disc of the scene's *largest*
  circle of confusion, and on a constant-depth image we check that both agree.
"""

from __future__ import annotations

import numpy as np
from _bench import measure, table

import imgform_rs as ig

F, FOCUS = 50.0, 2000.0


def scene(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    rows = np.linspace(0.0, 1.0, h)[:, None]
    depth = np.broadcast_to(10_000.0 - 9_000.0 * rows**2, (h, w)).copy()
    depth[h // 3 : 2 * h // 3, w // 3 : w // 2] = FOCUS
    return img, depth


def disc(r: float) -> np.ndarray:
    g = int(np.ceil(r + 0.5))
    yy, xx = np.mgrid[-g : g + 1, -g : g + 1]
    k = np.clip(r + 0.5 - np.hypot(yy, xx), 0.0, 1.0).astype(np.float32)
    return k / k.sum()


def main() -> None:
    rows = []
    d = np.linspace(60.0, 1e5, 10_000_000)
    n = 2.8
    ours = measure("coc", lambda: ig.circle_of_confusion(F, n, FOCUS, d))
    numpy = measure("numpy", lambda: F / n * np.abs(d - FOCUS) / d * F / (FOCUS - F))
    rows.append(
        [
            "circle_of_confusion, 10 M",
            f"{ours.best * 1e3:.0f} ms",
            f"NumPy {numpy.best * 1e3:.0f} ms",
            f"{numpy.best / ours.best:.1f}x",
        ]
    )
    try:
        import cv2
    except ImportError:
        cv2 = None
    for label, (h, w), pitch, n, repeat in [
        ("640x480", (480, 640), 0.056, 2.8, 5),
        ("12 MP", (3000, 4000), 0.009, 8.0, 1),
    ]:
        img, depth = scene(h, w)
        radius = ig.circle_of_confusion(F, n, FOCUS, depth) / pitch / 2
        lens = {"f": F, "N": n, "focus_distance": FOCUS, "pixel_pitch": pitch}
        t = measure(
            label,
            lambda img=img, depth=depth, lens=lens: ig.render_defocus(img, depth, **lens),
            repeat,
        )
        peer = "-"
        ratio = "-"
        if cv2 is not None:
            k = disc(float(radius.max()))
            p = measure("cv2", lambda img=img, k=k: cv2.filter2D(img, -1, k), repeat)
            peer = f"cv2.filter2D {p.best * 1e3:.0f} ms"
            ratio = f"{p.best / t.best:.2f}x"
        rows.append(
            [
                f"render_defocus {label} RGB u8, r mean {radius.mean():.1f} max {radius.max():.1f}",
                f"{t.best * 1e3:.0f} ms",
                peer,
                ratio,
            ]
        )
    print(table(["task", "imgform_rs (best)", "peer (best)", "speed-up"], rows))
    if cv2 is not None:
        img = np.random.default_rng(1).random((480, 640, 3), dtype=np.float32)
        depth = np.full((480, 640), 3000.0)
        r = float(ig.circle_of_confusion(F, 2.8, FOCUS, 3000.0)) / 0.056 / 2
        ours = ig.render_defocus(img, depth, f=F, N=2.8, focus_distance=FOCUS, pixel_pitch=0.056)
        theirs = cv2.filter2D(img, -1, disc(r), borderType=cv2.BORDER_REFLECT_101)
        print(
            f"constant depth (r = {r:.2f} px) vs cv2.filter2D disc: max |diff| = "
            f"{np.abs(ours - theirs).max():.1e}"
        )


if __name__ == "__main__":
    main()

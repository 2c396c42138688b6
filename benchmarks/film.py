"""Film: a linear sRGB image exposed on the generic negative and printed.

Ours: ``film.expose`` (a 3 x 3 matrix in Rust), ``film.develop`` with
halation and DIR couplers (curves, a Gaussian diffusion of the donors,
pre-corrected curves), ``film.print`` (Beer-Lambert over 41 wavelengths per
pixel, 3 paper layer integrals and the paper's curves in one pass). The peer
is ``tests/film_reference.py``, the same model in plain NumPy, chunked; both
in the same run, as ratios. Printing needs a balance (a few 3 x 3 solves),
done once outside the timing.

Default 6 MP so engineers sharing the machine keep memory; ``--mp 24`` for the
issue's goal (24 MP through negative + print in < 3 s, >= 20x NumPy). The
NumPy reference runs at ``--numpy-mp`` (default 6: at 24 MP it takes minutes
and several GB); the ratio compares both at that size, and ours is timed at
``--mp`` too, with its stages.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from _bench import measure_rounds, table

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
from film_reference import negative_print

from imgform_rs import film


def size(mp: float) -> tuple[int, int]:
    """A 2:3 frame of about ``mp`` megapixels, even sides."""
    h = round(float(np.sqrt(mp * 1e6 * 2 / 3)) / 2) * 2
    return h, round(h * 1.5 / 2) * 2


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--mp", type=float, default=6.0, help="megapixels")
    parser.add_argument("--numpy-mp", type=float, default=6.0, help="the reference's size")
    parser.add_argument("--numpy-repeat", type=int, default=1)
    args = parser.parse_args()
    neg, paper = film.load_stock("generic-negative"), film.load_stock("generic-paper")
    fil = film.balance_print(neg, paper)
    rng = np.random.default_rng(0)

    def ours(rgb: np.ndarray) -> np.ndarray:
        dens = film.develop(film.expose(rgb, neg), neg)
        return film.print(dens, neg, paper, filtration=fil)

    h, w = size(args.numpy_mp)
    rgb = rng.random((h, w, 3), dtype=np.float32)
    timings = measure_rounds(
        {
            "ours": (lambda: ours(rgb), 3),
            "numpy": (lambda: negative_print(rgb, neg, paper), args.numpy_repeat),
        }
    )
    small = rgb[:256, :256]
    err = np.abs(ours(small) - negative_print(small, neg, paper)).max()
    rows = [
        [
            f"{h}x{w} RGB, 41 wl, DIR on",
            f"{timings['ours'].best:.3f} s",
            f"{timings['numpy'].best:.3f} s",
            f"{timings['numpy'].best / timings['ours'].best:.1f}x",
            f"{err:.1e}",
        ]
    ]
    if args.mp != args.numpy_mp:
        del rgb
        h, w = size(args.mp)
        rgb = rng.random((h, w, 3), dtype=np.float32)
        big = measure_rounds({"ours": (lambda: ours(rgb), 3)})["ours"]
        rows.append([f"{h}x{w} RGB, 41 wl, DIR on", f"{big.best:.3f} s", "", "", ""])
    print(table(["negative + print", "ours", "numpy", "ratio", "max |Δ density|"], rows))
    print(f"\n## Stages of ours at {h}x{w} (best of 3, each timed alone)\n")
    exposure = film.expose(rgb, neg)
    dens = film.develop(exposure, neg)
    stages = {
        "expose (RGB -> 3 layer exposures)": lambda: film.expose(rgb, neg),
        "develop (halation, curves, DIR couplers)": lambda: film.develop(exposure, neg),
        "print (41 wl Beer-Lambert, paper curves)": lambda: film.print(
            dens, neg, paper, filtration=fil
        ),
    }
    best = {}
    for name, fn in stages.items():
        fn()
        runs = []
        for _ in range(3):
            start = time.perf_counter()
            fn()
            runs.append(time.perf_counter() - start)
        best[name] = min(runs)
    print(table(["stage", "ours"], [[k, f"{v:.3f} s"] for k, v in best.items()]))


if __name__ == "__main__":
    main()

"""Film: a linear sRGB image exposed on the generic negative and printed.

Ours: ``film.expose`` (a 3 x 3 matrix in Rust), ``film.develop`` with DIR
couplers (curves, a Gaussian diffusion of the donors, pre-corrected curves),
``film.print`` (Beer-Lambert over 41 wavelengths per pixel, 3 paper layer
integrals, the paper's curves). The peer is ``tests/film_reference.py``, the
same model in plain NumPy, chunked; both in the same run, as ratios.
Printing needs a balance (a few 3 x 3 solves), done once outside the timing.

Default 6 MP so engineers sharing the machine keep memory; ``--mp 24`` for the
issue's goal (24 MP through negative + print in < 3 s, >= 20x NumPy).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from _bench import measure_rounds, table

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
from film_reference import negative_print

from imgform_rs import film


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--mp", type=float, default=6.0, help="megapixels")
    parser.add_argument("--numpy-repeat", type=int, default=1)
    args = parser.parse_args()
    h = round(float(np.sqrt(args.mp * 1e6 * 2 / 3)) / 2) * 2
    w = round(h * 1.5 / 2) * 2
    neg, paper = film.load_stock("generic-negative"), film.load_stock("generic-paper")
    fil = film.balance_print(neg, paper)
    rgb = np.random.default_rng(0).random((h, w, 3), dtype=np.float32)

    def ours() -> np.ndarray:
        dens = film.develop(film.expose(rgb, neg), neg)
        return film.print(dens, neg, paper, filtration=fil)

    def numpy() -> np.ndarray:
        return negative_print(rgb, neg, paper)

    timings = measure_rounds({"ours": (ours, 3), "numpy": (numpy, args.numpy_repeat)})
    small = rgb[:256, :256]
    err = np.abs(
        film.print(film.develop(film.expose(small, neg), neg), neg, paper, filtration=fil)
        - negative_print(small, neg, paper)
    ).max()
    print(
        table(
            ["negative + print", "ours", "numpy", "ratio", "max |Δ density|"],
            [
                [
                    f"{h}x{w} RGB, 41 wl, DIR on",
                    f"{timings['ours'].best:.3f} s",
                    f"{timings['numpy'].best:.3f} s",
                    f"{timings['numpy'].best / timings['ours'].best:.1f}x",
                    f"{err:.1e}",
                ]
            ],
        )
    )


if __name__ == "__main__":
    main()

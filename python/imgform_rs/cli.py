"""The ``imgform`` command line."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

# The sample plate beside the checkout (shared/ is not part of the project).
SAMPLE_PLATE = Path("../shared/data/pg/cathedral.jpg")


def _demo(args: argparse.Namespace) -> int:
    from .demo import run

    if args.plate is None:
        plate = SAMPLE_PLATE if SAMPLE_PLATE.is_file() else None
    elif Path(args.plate).is_file():
        plate = Path(args.plate)
    else:
        print(f"imgform demo: no plate file at {args.plate}", file=sys.stderr)
        return 2
    for path in run(Path(args.out), plate=plate):
        print(f"wrote {path}")
    return 0


def _for_png(rgb):
    """uint8/uint16 pass through; float plates are clipped to [0, 1] and
    written with 16 bits."""
    import numpy as np

    if rgb.dtype in (np.uint8, np.uint16):
        return rgb
    return np.floor(np.clip(rgb, 0.0, 1.0) * 65535.0 + 0.5).astype(np.uint16)


def _progress(done: int, total: int) -> None:
    """A one-line bar on stderr, drawn only on a terminal (logs stay clean)."""
    if total < 2 or not sys.stderr.isatty():
        return
    width = 30
    filled = width * done // total
    end = "\n" if done == total else ""
    sys.stderr.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} plates{end}")
    sys.stderr.flush()


def _align(args: argparse.Namespace) -> int:
    import time

    from ._png import write_png
    from .align import colorize_plate, read_plate

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    failed = 0
    for i, name in enumerate(args.plates, start=1):
        path = Path(name)
        target = out / f"{path.stem}.png"
        if target.exists() and not args.overwrite:
            print(f"{path}: {target} exists, kept (use --overwrite to replace it)")
        else:
            start = time.perf_counter()
            try:
                rgb, shifts = colorize_plate(
                    read_plate(path),
                    reference=args.reference,
                    metric=args.metric,
                    max_shift=args.max_shift,
                    features=args.features,
                )
                write_png(target, _for_png(rgb))
            except (ValueError, TypeError, OSError) as exc:
                failed += 1
                print(f"imgform align: {path}: {exc}", file=sys.stderr)
            else:
                took = time.perf_counter() - start
                moved = ", ".join(f"{c.upper()} {shifts[c]}" for c in "rgb" if c != args.reference)
                print(f"{path}: {moved} onto {args.reference.upper()} in {took:.2f} s -> {target}")
        _progress(i, len(args.plates))
    if failed:
        print(f"imgform align: {failed} of {len(args.plates)} plates failed", file=sys.stderr)
    return 1 if failed else 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="imgform",
        description="Rust-accelerated image formation: geometry, optics, sensors, demosaicing.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    demo = sub.add_parser(
        "demo", help="render the built-in sample scene through every camera model"
    )
    demo.add_argument("--out", default="out", help="output folder (default: out)")
    demo.add_argument(
        "--plate",
        help=f"a Prokudin-Gorskii scan to colourise (default: {SAMPLE_PLATE}, when present)",
    )
    demo.set_defaults(run=_demo)
    align = sub.add_parser(
        "align",
        help="colourise Prokudin-Gorskii plates (B, G, R stacked top to bottom)",
        description="Align the three exposures of each plate and write OUTDIR/<name>.png "
        "(16-bit for 16-bit scans). Shifts are (dy, dx) in the np.roll convention.",
    )
    align.add_argument("plates", nargs="+", metavar="PLATE", help="8-bit JPG or 16-bit TIFF scans")
    align.add_argument("-o", "--out", required=True, metavar="OUTDIR", help="output folder")
    align.add_argument("--metric", default="ncc", choices=["ncc", "ssd", "cosine"])
    align.add_argument("--reference", default="g", choices=["r", "g", "b"])
    align.add_argument(
        "--max-shift",
        type=int,
        default=None,
        help="largest |dy|, |dx| searched (default: 5%% of a channel's shorter side, >= 15)",
    )
    align.add_argument("--features", default="intensity", choices=["intensity", "gradient"])
    align.add_argument(
        "--overwrite", action="store_true", help="replace existing outputs (default: keep them)"
    )
    align.set_defaults(run=_align)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return int(args.run(args))


if __name__ == "__main__":
    sys.exit(main())

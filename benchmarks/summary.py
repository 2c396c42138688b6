"""The README's short benchmark table, generated from the committed records.

The README cannot render ``benchmarks/results/*.json`` the way the docs site
does, and a table retyped by hand drifts from the records (it did: its
numbers came from runs nobody could find any more). So the table sits
between two markers in README.md, this script writes it from the latest
records, and ``tests/test_docs.py`` fails when the README's copy differs
from what the records give.

Run ``.venv/bin/python benchmarks/summary.py`` to print the table and
``--write`` to put it into README.md after ``make bench``.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
README = ROOT / "README.md"
START = "<!-- benchmark summary: made by benchmarks/summary.py from benchmarks/results -->"
END = "<!-- end of benchmark summary -->"


@dataclass(frozen=True)
class Cell:
    """One number of a record: the table whose title starts with ``table``,
    the row whose first cell is ``row``, the column headed ``column``."""

    table: str
    row: str
    column: str
    unit: str = ""


@dataclass(frozen=True)
class Line:
    """A README row: what was measured, ours against a peer of the same run."""

    what: str
    record: str
    ours: Cell
    peer_name: str
    peer: Cell


PROJECTION = "Projection of 10 M points"
PLATE = "colorize_plate on the framed plate"

LINES = (
    Line(
        "project 10 M points, `Camera.project`",
        "geometry",
        Cell(PROJECTION, "imgform Camera.project (K, R, t)", "M points/s", " M/s"),
        "`cv2.projectPoints`",
        Cell(PROJECTION, "cv2.projectPoints (K, R, t), 1 M pts", "M points/s", " M/s"),
    ),
    Line(
        "undistort 24 MP u8 RGB, bicubic, precomputed map",
        "geometry",
        Cell("Undistortion", "uint8 RGB bicubic: imgform remap", "best ms", " ms"),
        "`cv2.remap`",
        Cell("Undistortion", "uint8 RGB bicubic: cv2.remap, float32 maps", "best ms", " ms"),
    ),
    Line(
        "align a 3 x 3700 x 3200 16-bit plate, `colorize_plate`",
        "align",
        Cell(PLATE, "imgform-rs colorize_plate (defaults)", "best s", " s"),
        "scikit-image `phase_cross_correlation`",
        Cell(PLATE, "skimage phase_cross_correlation (R, B)", "best s", " s"),
    ),
    Line(
        'demosaic 24 MP uint16 RGGB, `"best"`',
        "demosaic",
        Cell("Speed", "ours best", "MP/s", " MP/s"),
        "LibRaw AHD",
        Cell("Speed", "LibRaw AHD", "MP/s", " MP/s"),
    ),
    Line(
        "develop a decoded 24 MP DNG to 16-bit sRGB",
        "develop",
        Cell("24 MP (6000x4000) RGGB DNG", "ours:best", "best s", " s"),
        "LibRaw AHD",
        Cell("24 MP (6000x4000) RGGB DNG", "libraw:AHD", "best s", " s"),
    ),
)


def load(name: str) -> dict[str, Any]:
    return json.loads((RESULTS / f"{name}.json").read_text())


def value(record: dict[str, Any], name: str, cell: Cell) -> str:
    """The cell's text, or a ``LookupError`` naming what the record lacks
    (a renamed row must fail here, not print a stale number)."""
    for table in record["tables"]:
        if table["title"].startswith(cell.table):
            for row in table["rows"]:
                if row[0] == cell.row:
                    return row[table["headers"].index(cell.column)] + cell.unit
            raise LookupError(f"{name}.json: table {cell.table!r} has no row {cell.row!r}")
    raise LookupError(f"{name}.json: no table titled {cell.table!r}...")


def run_of(record: dict[str, Any]) -> str:
    load_before = record.get("load_average_before") or [float("nan")]
    return f"{record['started'][:10]}, load {load_before[0]:.1f}"


def summary() -> str:
    """The markdown table, between its markers."""
    rows = ["| what | imgform-rs | peer, same run | run |", "|---|---|---|---|"]
    for line in LINES:
        record = load(line.record)
        ours = value(record, line.record, line.ours)
        peer = value(record, line.record, line.peer)
        rows.append(f"| {line.what} | {ours} | {line.peer_name}: {peer} | {run_of(record)} |")
    return "\n".join([START, *rows, END])


def readme_with(table: str, readme: str) -> str:
    start, end = readme.index(START), readme.index(END) + len(END)
    return readme[:start] + table + readme[end:]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="update README.md in place")
    args = parser.parse_args()
    table = summary()
    if args.write:
        README.write_text(readme_with(table, README.read_text()))
    print(table)


if __name__ == "__main__":
    main()

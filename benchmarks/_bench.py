"""Timing helpers shared by the benchmarks.

Each call is warmed up once, then timed separately with the garbage collector
off; we report the minimum (the least disturbed run: on a shared 2-core machine
the others measure the neighbours) and the median. Ratios are always against a
peer measured in the same run, never against a number from elsewhere.

Every table a benchmark prints is also kept, and when the script exits it is
written to ``benchmarks/results/<script>.json`` (or the folder named by
``IMGFORM_BENCH_RESULTS``) with what the numbers depend on: the CPU, the core
count, the date, the load average before and after, the commit and the
versions of imgform-rs and of every peer installed. The documentation renders
the committed files as its benchmark tables; nobody retypes a number. Each
table is saved with the text printed since the previous one (its heading and
notes), so a script needs no change to be recorded.
"""

from __future__ import annotations

import atexit
import datetime
import gc
import io
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any, TextIO

from imgform_rs import instruction_set


@dataclass
class Timing:
    name: str
    best: float
    median: float
    # Every timed run, in order (the warm-up left out).
    times: list[float]

    def rate(self, items: float) -> float:
        """Items per second at the best time."""
        return items / self.best


def measure(name: str, fn: Callable[[], object], repeat: int = 5) -> Timing:
    """One call, timed `repeat` times after a warm-up run."""
    return measure_rounds({name: (fn, repeat)})[name]


def measure_rounds(calls: dict[str, tuple[Callable[[], object], int]]) -> dict[str, Timing]:
    """Times each call `repeat` times after a warm-up run, in rounds: round
    k runs every call that still has a run due, one after the other. On a
    VM whose speed drifts by tens of percent within minutes, timing each
    call in one block lets the drift land on a single call and skew its
    ratio to the others; rounds spread it over all of them."""
    for fn, _ in calls.values():
        fn()
    times: dict[str, list[float]] = {name: [] for name in calls}
    gc.disable()
    try:
        for k in range(max(repeat for _, repeat in calls.values())):
            for name, (fn, repeat) in calls.items():
                if k < repeat:
                    start = time.perf_counter()
                    fn()
                    times[name].append(time.perf_counter() - start)
    finally:
        gc.enable()
    return {name: Timing(name, min(t), statistics.median(t), t) for name, t in times.items()}


def table(headers: list[str], rows: list[list[str]]) -> str:
    """A Markdown table, columns padded for reading in a terminal too."""
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(headers)]
    line = "| " + " | ".join(h.ljust(w) for h, w in zip(headers, widths, strict=True)) + " |"
    rule = "|" + "|".join("-" * (w + 2) for w in widths) + "|"
    body = [
        "| " + " | ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) + " |" for r in rows
    ]
    text = "\n".join([line, rule, *body])
    _RECORD.table(headers, rows, text)
    return text


# The distributions whose versions the numbers depend on: ours and the peers.
PEERS = (
    "imgform-rs",
    "numpy",
    "scipy",
    "opencv-python-headless",
    "opencv-python",
    "scikit-image",
    "colour-demosaicing",
    "rawpy",
    "lensfunpy",
    "eari-demosaic",
    "demosaicnet",
    "torch",
    "dask",
    "distributed",
)
RESULTS = Path(__file__).parent / "results"


def machine() -> dict[str, Any]:
    """What a benchmark's numbers depend on besides the code: CPU, cores,
    the instruction set our kernels ran (``IMGFORM_ISA`` may cap it), date,
    load, Python and the versions of the peers installed (a peer that is not
    installed is left out)."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    versions = {}
    for name in PEERS:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    try:
        import rawpy

        versions["LibRaw"] = ".".join(map(str, rawpy.libraw_version))
    except (ImportError, AttributeError):
        pass
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "instruction_set": instruction_set(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "versions": versions,
    }


def commit() -> str | None:
    """The commit checked out, with ``-dirty`` appended when tracked files differ
    from it: a record made from uncommitted code must not pass for the commit's.
    ``None`` outside a git checkout."""
    try:
        return subprocess.run(
            ["git", "describe", "--always", "--dirty", "--abbrev=7", "--exclude=*"],
            cwd=Path(__file__).parent,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None


class _Record(io.TextIOBase):
    """Passes everything printed through to the real stdout and keeps it, so
    that each table can be saved with the heading printed before it."""

    def __init__(self, out: TextIO) -> None:
        self.out = out
        self.since_table: list[str] = []
        self.tables: list[dict[str, Any]] = []
        self.opening_notes: list[str] = []
        self.printing = ""
        self.started = datetime.datetime.now(datetime.timezone.utc)
        self.load_before = os.getloadavg() if hasattr(os, "getloadavg") else None
        # Taken as the run starts: the code measured is the code checked out then.
        self.commit = commit()

    def write(self, text: str) -> int:
        # The table's own text is in the record already, as rows.
        if self.printing and self.printing in text:
            kept, self.printing = text.replace(self.printing, "", 1), ""
            self.since_table.append(kept)
        else:
            self.since_table.append(text)
        return self.out.write(text)

    def flush(self) -> None:
        self.out.flush()

    def table(self, headers: list[str], rows: list[list[str]], text: str) -> None:
        """Keeps a table with the paragraphs printed since the previous one.
        The last Markdown heading's paragraph (else the last paragraph) is its
        title and those after it its notes; those before it close the
        previous table (or open the run)."""
        paragraphs = _paragraphs("".join(self.since_table))
        self.since_table = []
        headed = [i for i, p in enumerate(paragraphs) if p.startswith("#")]
        at = headed[-1] if headed else len(paragraphs) - 1
        title = paragraphs[at].lstrip("#").strip() if paragraphs else ""
        before, after = paragraphs[: max(at, 0)], paragraphs[at + 1 :]
        (self.tables[-1]["notes"] if self.tables else self.opening_notes).extend(before)
        self.tables.append({"title": title, "notes": after, "headers": headers, "rows": rows})
        self.printing = text

    def failed(self, kind, value, traceback) -> None:
        """Keeps the results of the last complete run: a run that raised is
        not saved over them."""
        self.tables = []
        sys.__excepthook__(kind, value, traceback)

    def save(self) -> None:
        if not self.tables:
            return
        folder = Path(os.environ.get("IMGFORM_BENCH_RESULTS", RESULTS))
        folder.mkdir(parents=True, exist_ok=True)
        script = Path(sys.argv[0])
        result = {
            "benchmark": script.stem,
            "command": " ".join(["python", f"benchmarks/{script.name}", *sys.argv[1:]]),
            "started": self.started.isoformat(timespec="seconds"),
            "finished": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "load_average_before": self.load_before,
            "load_average_after": os.getloadavg() if hasattr(os, "getloadavg") else None,
            **machine(),
            "commit": self.commit,
            "opening_notes": self.opening_notes,
            "tables": self.tables,
            "closing_notes": _paragraphs("".join(self.since_table)),
        }
        path = folder / f"{script.stem}.json"
        path.write_text(json.dumps(result, indent=1, ensure_ascii=False) + "\n")
        print(f"results written to {path}", file=sys.__stderr__)


def _paragraphs(text: str) -> list[str]:
    """Printed text as paragraphs (runs of non-blank lines joined by spaces)."""
    out: list[str] = []
    lines: list[str] = []
    for line in [*text.splitlines(), ""]:
        if line.strip():
            lines.append(line.strip())
        elif lines:
            out.append(" ".join(lines))
            lines = []
    return out


def _running_a_benchmark() -> bool:
    """True in a benchmark script run as a program, false in the child
    interpreters some benchmarks start (``python -c``) and in imports."""
    main = Path(sys.argv[0]) if sys.argv and sys.argv[0] else None
    return (
        main is not None
        and main.suffix == ".py"
        and main.resolve().parent == Path(__file__).resolve().parent
        and main.name != "_bench.py"
    )


_RECORD = _Record(sys.stdout)
if _running_a_benchmark():
    sys.stdout = _RECORD
    sys.excepthook = _RECORD.failed
    atexit.register(_RECORD.save)

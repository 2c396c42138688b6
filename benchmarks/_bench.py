"""Timing helpers shared by the benchmarks.

Each call is warmed up once, then timed separately with the garbage collector
off; we report the minimum (the least disturbed run: on a shared 2-core machine
the others measure the neighbours) and the median. Ratios are always against a
peer measured in the same run, never against a number from elsewhere.
"""

from __future__ import annotations

import gc
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass


@dataclass
class Timing:
    name: str
    best: float
    median: float

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
    return {name: Timing(name, min(t), statistics.median(t)) for name, t in times.items()}


def table(headers: list[str], rows: list[list[str]]) -> str:
    """A Markdown table, columns padded for reading in a terminal too."""
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(headers)]
    line = "| " + " | ".join(h.ljust(w) for h, w in zip(headers, widths, strict=True)) + " |"
    rule = "|" + "|".join("-" * (w + 2) for w in widths) + "|"
    body = [
        "| " + " | ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) + " |" for r in rows
    ]
    return "\n".join([line, rule, *body])

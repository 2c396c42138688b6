"""Scale-out on Dask: many raws on 1 and 2 workers, and a gigapixel demosaic.

Part 1 develops ``--count`` generated DNGs (default 100 of 12 MP, 4000 x 3000
RGGB, 12 bits, through ``simulate_sensor``) to 8-bit PNGs three ways:

- a plain local loop, ``develop`` + ``write_image`` one file after the other,
  in a fresh interpreter with ``RAYON_NUM_THREADS=1``;
- ``develop_many`` on a ``local_client`` of 1 worker process, then of 2, each
  with one thread and ``RAYON_NUM_THREADS=1``, so a worker uses one core and
  the only difference between the runs is the number of workers.

Both sides do the same work (the same ``develop``, the same PNG encoder at
the same zlib level, the same files) and are warmed up alike: the loop and
every worker develop the first raw once before the clock starts, so neither
side's time includes first imports (rawpy) or first-touch memory.

It reports the overhead of 1 worker against the local loop (scheduling,
pickling, the atomic rename; goal < 10 %) and the scaling efficiency from 1
to 2 workers, ``t1 / (2 t2)`` (goal >= 85 % on a 2-core machine), and where
the time went: the sum of the per-file times measured inside the tasks (so
``busy %`` is the share of the workers' time spent in a task, the rest is
scheduling and idling), and the CPU seconds and minor page faults of the
worker processes per file, which other jobs on a shared machine barely
change, unlike the wall-clock times.

Part 2 demosaics a ``--side`` x ``--side`` uint16 mosaic (default 32768, 1.07
gigapixels, 2 GB in and 6 GB out) with ``demosaic_dask`` on 2 workers, chunks
of ``--chunk`` pixels. The mosaic is generated inside the workers (a lazy
array of hashed coordinates) and the result reduced per chunk (its channel maxima), so the
image is never whole anywhere: each worker's peak resident memory (its
``ru_maxrss`` after the run, minus its size before) is then bounded by a few
chunks, not by the image.

Each configuration runs once (the machine is shared; the whole run takes
minutes). Run: ``.venv/bin/python benchmarks/scale_out.py`` (``--count 20``
for a shorter first part, ``--raws DIR`` to keep the generated DNGs for the
next run).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _bench import table

import imgform_rs as ig
from imgform_rs.batch import demosaic_dask, develop_many, local_client
from imgform_rs.dng import write_dng

ONE_CORE = {"RAYON_NUM_THREADS": "1"}

# The same work as one batch task, minus the atomic rename: what a user's
# own loop would do. Warmed up on the first raw like the workers are.
LOCAL_LOOP = """
import json, resource, sys, time
from pathlib import Path
from imgform_rs import develop, write_image
paths, out = sys.argv[1:-1], Path(sys.argv[-1])
write_image(out / "warm-up.png", develop(paths[0]))
def usage():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime, r.ru_minflt
before = usage()
seconds = []
start = time.perf_counter()
for p in paths:
    t = time.perf_counter()
    write_image(out / (Path(p).stem + ".png"), develop(p))
    seconds.append(time.perf_counter() - t)
wall = time.perf_counter() - start
cpu, faults = (b - a for a, b in zip(before, usage()))
print(json.dumps({"wall": wall, "in tasks": sum(seconds), "cpu": cpu, "faults": faults}))
"""


@dataclass
class Run:
    """One way of developing the batch, and where its time went."""

    wall: float
    in_tasks: float
    """Sum of the per-file times measured around each file's work."""
    cpu: float
    """CPU seconds (user + system) of the worker processes during the batch:
    unlike ``wall``, barely inflated by other jobs on the machine."""
    faults: int
    """Minor page faults of the worker processes during the batch."""
    workers: int = 1
    control: float = 0.0
    """CPU seconds of this process (client, scheduler and nannies of a local
    cluster) during the batch: on a loaded machine they share this session's
    CPU with the workers (the kernel's autogroup fairness)."""

    def busy(self) -> float:
        """The share of the workers' time spent inside a task."""
        return self.in_tasks / (self.wall * self.workers)


def make_raws(folder: Path, count: int, megapixels: float) -> list[str]:
    """``count`` DNGs of one scene, each with its own sensor noise."""
    w = round((megapixels * 1e6 * 4 / 3) ** 0.5 / 2) * 2
    h = round(w * 3 / 8) * 2
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    rgb = np.stack(
        [
            0.45 + 0.4 * np.sin(x / 97),
            0.4 + 0.3 * np.cos(y / 61),
            0.3 + 0.25 * np.sin((x + y) / 43),
        ],
        -1,
    ).astype(np.float32)
    paths = []
    for i in range(count):
        cfa = simulate(rgb, i)
        paths.append(str(folder / f"raw{i:04d}.dng"))
        write_dng(paths[-1], cfa, "RGGB", white_level=4095 + 64, black_level=64)
    return paths


def simulate(rgb: np.ndarray, seed: int) -> np.ndarray:
    return ig.simulate_sensor(rgb, "RGGB", bit_depth=12, black_level=64, seed=seed)


def local_loop(paths: list[str], out: Path) -> Run:
    out.mkdir()
    env = {**os.environ, **ONE_CORE}
    env.pop("MALLOC_TRIM_THRESHOLD_", None)  # a nanny may have set it in this process
    code = textwrap.dedent(LOCAL_LOOP)
    run = subprocess.run(
        [sys.executable, "-c", code, *paths, str(out)], env=env, capture_output=True, text=True
    )
    if run.returncode:
        raise RuntimeError(run.stderr)
    res = json.loads(run.stdout)
    return Run(res["wall"], res["in tasks"], res["cpu"], res["faults"])


def warm_up(source: str, scratch: str) -> None:
    """One file developed in each worker before the timing, as in the loop:
    the first call's lazy imports (rawpy) and first-touch memory are not
    the batch's steady cost."""
    ig.write_image(Path(scratch) / f"warm-up-{os.getpid()}.png", ig.develop(source))


def usage() -> tuple[float, int]:
    """CPU seconds and minor page faults of this process so far."""
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime, r.ru_minflt


def on_cluster(paths: list[str], out: Path, workers: int) -> Run:
    with local_client(workers, env=ONE_CORE) as client:
        client.run(warm_up, paths[0], str(out.parent))
        before, control = client.run(usage), usage()[0]
        start = time.perf_counter()
        report = develop_many(paths, out, client=client)
        took = time.perf_counter() - start
        after, control = client.run(usage), usage()[0] - control
    if report.failed:
        raise RuntimeError(report.failed[0].reason)
    cpu, faults = (sum(a[i] - before[w][i] for w, a in after.items()) for i in (0, 1))
    return Run(took, sum(f.seconds for f in report.files), cpu, faults, workers, control)


def part_one(folder: Path, raws: Path, count: int, megapixels: float) -> dict[str, Run]:
    paths = sorted(str(p) for p in raws.glob("raw*.dng"))[:count]
    if len(paths) < count:
        start = time.perf_counter()
        paths = make_raws(raws, count, megapixels)
        print(f"generated {count} DNGs in {time.perf_counter() - start:.0f} s", file=sys.stderr)
    runs = {"local loop": local_loop(paths, folder / "local")}
    for n in (1, 2):
        runs[f"{n} worker{'s' * (n > 1)}"] = on_cluster(paths, folder / f"w{n}", n)
    return runs


def report_one(runs: dict[str, Run], count: int, megapixels: float) -> None:
    rows = [
        [
            k,
            f"{r.wall:.1f}",
            f"{count / r.wall:.2f}",
            f"{r.in_tasks / count:.3f}",
            f"{100 * r.busy():.1f}",
            f"{r.cpu / count:.3f}",
            f"{r.control / count:.3f}",
            f"{r.faults / count / 1000:.1f}",
        ]
        for k, r in runs.items()
    ]
    print(f"## {count} x {megapixels:g} MP DNGs -> 8-bit PNG\n")
    heads = [
        "run",
        "seconds",
        "files/s",
        "s per file in task",
        "busy %",
        "CPU s per file",
        "control CPU s per file",
        "k page faults/file",
    ]
    print(table(heads, rows))
    t0, t1, t2 = (r.wall for r in runs.values())
    loop, one = runs["local loop"], runs["1 worker"]
    print(f"\noverhead of 1 worker against the local loop: {100 * (t1 / t0 - 1):+.1f} %", end="")
    print(f" (inside the tasks {100 * (one.in_tasks / loop.in_tasks - 1):+.1f} %,", end="")
    print(f" in CPU time {100 * (one.cpu / loop.cpu - 1):+.1f} %)")
    print(f"scaling efficiency 1 -> 2 workers: {100 * t1 / (2 * t2):.1f} %\n")


def peak_rss_kib() -> int:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def current_rss_kib() -> int:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS"))


def texture(block: np.ndarray, block_info: dict | None = None) -> np.ndarray:
    """12-bit pseudo-random values hashed from the pixel coordinates: ten
    times cheaper than a random generator, so the run measures the demosaic."""
    (y0, y1), (x0, x1) = block_info[0]["array-location"]
    y = np.arange(y0, y1, dtype=np.uint32)[:, None] * np.uint32(2654435761)
    x = np.arange(x0, x1, dtype=np.uint32)[None, :] * np.uint32(40503)
    return ((y ^ x) * np.uint32(2246822519) >> np.uint32(20)).astype(np.uint16)


def part_two(side: int, chunk: int, method: str) -> dict:
    import dask.array as da

    with local_client(2, env=ONE_CORE) as client:
        client.run(lambda: __import__("imgform_rs"))
        before = client.run(current_rss_kib)
        mosaic = da.zeros((side, side), dtype=np.uint16, chunks=chunk).map_blocks(
            texture, dtype=np.uint16
        )
        start = time.perf_counter()
        maxima = demosaic_dask(mosaic, "RGGB", method).max(axis=(0, 1)).compute()
        took = time.perf_counter() - start
        peaks = client.run(peak_rss_kib)
    growth = {w: (peaks[w] - before[w]) / 1024 for w in peaks}
    return {"seconds": took, "maxima": maxima.tolist(), "peak MiB per worker": growth}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=100, help="raws in part 1 (default 100)")
    parser.add_argument("--megapixels", type=float, default=12.0, help="per raw (default 12)")
    parser.add_argument("--side", type=int, default=32768, help="mosaic side in part 2")
    parser.add_argument("--chunk", type=int, default=4096, help="chunk side in part 2")
    parser.add_argument("--method", default="bilinear", choices=ig.DEMOSAIC_METHODS)
    parser.add_argument(
        "--raws", help="keep the generated DNGs in this folder and reuse them in later runs"
    )
    parser.add_argument("--skip", choices=["batch", "mosaic"], help="leave one part out")
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="imgform-scale-out-"))
    try:
        if args.skip != "batch":
            raws = Path(args.raws) if args.raws else folder
            raws.mkdir(parents=True, exist_ok=True)
            report_one(
                part_one(folder, raws, args.count, args.megapixels), args.count, args.megapixels
            )
        if args.skip != "mosaic":
            res = part_two(args.side, args.chunk, args.method)
            gp = args.side**2 / 1e9
            print(f"## demosaic_dask, {gp:.2f} GP uint16, {args.method}, chunks {args.chunk}\n")
            print(f"{res['seconds']:.1f} s ({args.side**2 / res['seconds'] / 1e6:.0f} MP/s)")
            chunk_mib = args.chunk**2 * 2 / 2**20
            print(f"one input chunk: {chunk_mib:.0f} MiB, its RGB result {3 * chunk_mib:.0f} MiB")
            print("peak growth per worker (MiB):", json.dumps(res["peak MiB per worker"]))
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()

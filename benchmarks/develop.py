"""Raw development: a 24 MP DNG to 16-bit sRGB, ours against LibRaw's postprocess.

The raw is a synthetic 6000 x 4000 RGGB DNG written by our writer: a smooth
colourful scene with fine detail, through ``simulate_sensor`` (14 bits,
photon and read noise), a camera matrix that is not sRGB and an as-shot
white balance. Each contender develops it to a (4000, 6000, 3) uint16 array
from the already decoded raw, so the time is the development alone (the
decoding is LibRaw's on both sides and would only dilute the ratio):

- ours: ``develop(raw, bps=16)`` (camera white balance, sRGB, sRGB tone) on the
  ``RawImage`` of ``load_raw(path)``, with our default demosaicer and with
  bilinear;
- LibRaw: ``postprocess(use_camera_wb=True, output_bps=16, gamma=(2.4,
  12.92), no_auto_bright=True)`` (the sRGB curve, no auto brightening: the
  same picture as ours) on the ``RawPy`` of ``rawpy.imread(path)`` (which
  unpacks the data), with ``demosaic_algorithm`` AHD (its default) and
  LINEAR.

The ``+auto`` rows brighten as LibRaw does by default: ours with
``exposure="auto"`` (a second, linear development finds the level), LibRaw
without ``no_auto_bright``; they show what the automatic exposure costs.

The last column compares each result with LibRaw AHD's (with the same
brightening), so it shows how far the demosaicers (and nothing else) differ.

Each contender runs in a fresh interpreter, so the peak resident memory it
reports (``VmHWM`` minus the resident size after decoding, just before the
first call) belongs to that contender's development alone; there it
develops the raw ``REPEAT`` times (the previous result freed first) and we
report the best time, as ``_bench.measure`` does: on a shared 2-core machine
a single run mostly measures the neighbours (one run of ours has been seen at 1.6x and 4.5x
LibRaw's speed on the same day). The CPU column (the least process CPU
time, all threads) is steadier there: it counts work, not waiting for a
core, though it hides how well each side uses the cores.

Run: ``.venv/bin/python benchmarks/develop.py [repeat]`` (default 5).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _bench import table

import imgform_rs as ig
from imgform_rs.dng import write_dng

H, W = 4000, 6000
REPEAT = 5

CHILD = """
import json, sys, time
import numpy as np
import imgform_rs as ig
import rawpy

def status(key):
    # VmHWM, unlike ru_maxrss, starts afresh at exec (ru_maxrss keeps the
    # parent's peak at fork).
    with open("/proc/self/status") as f:
        return next(int(l.split()[1]) * 1024 for l in f if l.startswith(key + ":"))

path, who, repeat = sys.argv[1], sys.argv[2], int(sys.argv[4])
side, _, method = who.partition(":")
method, _, auto = method.partition("+")
if side == "ours":
    raw = ig.load_raw(path)
    def run():
        return ig.develop(raw, demosaic=method, bps=16, exposure="auto" if auto else 0.0)
else:
    algo = getattr(rawpy.DemosaicAlgorithm, method)
    raw = rawpy.imread(path)
    def run():
        return raw.postprocess(
            demosaic_algorithm=algo, use_camera_wb=True, output_bps=16,
            gamma=(2.4, 12.92), no_auto_bright=not auto,
        )
before = status("VmRSS")
times, cpu, out = [], [], None
for _ in range(repeat):
    out = None
    start, start_cpu = time.perf_counter(), time.process_time()
    out = run()
    times.append(time.perf_counter() - start)
    cpu.append(time.process_time() - start_cpu)
peak = status("VmHWM")
np.save(sys.argv[3], out)
print(json.dumps({"seconds": min(times), "median": sorted(times)[len(times) // 2],
                  "cpu": min(cpu),
                  "peak": peak - before, "shape": list(out.shape)}))
"""


def scene() -> np.ndarray:
    """Smooth colour ramps plus fine stripes, linear, in [0.02, 0.8]."""
    y = np.linspace(0, 1, H, dtype=np.float32)[:, None]
    x = np.linspace(0, 1, W, dtype=np.float32)[None, :]
    rgb = np.empty((H, W, 3), np.float32)
    rgb[..., 0] = 0.4 + 0.3 * np.sin(6 * x + 2 * y) + 0.08 * np.sin(900 * x * y)
    rgb[..., 1] = 0.4 + 0.3 * np.cos(5 * y - 3 * x) + 0.08 * np.sin(700 * (x + y))
    rgb[..., 2] = 0.4 + 0.3 * np.sin(4 * x * y + 1) + 0.08 * np.cos(800 * y)
    return np.clip(rgb, 0.02, 0.8)


def run(path: Path, who: str, npy: Path, repeat: int) -> dict:
    env = dict(os.environ)
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(CHILD), str(path), who, str(npy), str(repeat)],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(done.stdout)


def main() -> None:
    repeat = int(sys.argv[1]) if len(sys.argv) > 1 else REPEAT
    methods = ig.BAYER_DEMOSAIC_METHODS
    best = "best" if "best" in methods else "hamilton_adams"
    contenders = [f"ours:{best}", "ours:bilinear", "libraw:AHD", "libraw:LINEAR"]
    contenders += [f"ours:{best}+auto", "libraw:AHD+auto"]
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "24mp.dng"
        cfa = ig.simulate_sensor(scene(), "RGGB", bit_depth=14, black_level=512, full_well=30000)
        cam_from_xyz = [[1.1, -0.3, -0.1], [-0.4, 1.3, 0.1], [0.0, -0.2, 0.9]]
        write_dng(
            path,
            cfa,
            "RGGB",
            white_level=16383 + 512,
            black_level=512,
            color_matrix=cam_from_xyz,
            as_shot_neutral=(0.55, 1.0, 0.7),
        )
        del cfa
        results = {}
        for who in contenders:
            results[who] = run(path, who, Path(d) / f"{who.replace(':', '_')}.npy", repeat)
        refs = {
            auto: np.load(Path(d) / f"libraw_AHD{auto}.npy").astype(np.float64)
            for auto in ("", "+auto")
        }
        ahd, linear = results["libraw:AHD"], results["libraw:LINEAR"]
        rows = []
        for who in contenders:
            r = results[who]
            ref = refs["+auto" if who.endswith("+auto") else ""]
            out = np.load(Path(d) / f"{who.replace(':', '_')}.npy").astype(np.float64)
            err = np.mean((out[8:-8, 8:-8] - ref[8:-8, 8:-8]) ** 2)
            psnr = "inf" if err == 0 else f"{10 * np.log10(65535**2 / err):.1f}"
            rows.append(
                [
                    who,
                    f"{r['seconds']:.3f}",
                    f"{r['median']:.3f}",
                    f"{r['cpu']:.3f}",
                    f"{ahd['seconds'] / r['seconds']:.2f}x",
                    f"{linear['seconds'] / r['seconds']:.2f}x",
                    f"{r['peak'] / 2**20:.0f}",
                    psnr,
                ]
            )
    print(f"24 MP ({W}x{H}) RGGB DNG, decoded -> 16-bit sRGB, best of {repeat}")
    headers = [
        "who",
        "best s",
        "median s",
        "CPU s",
        "vs AHD",
        "vs LINEAR",
        "peak MiB",
        "PSNR vs AHD (dB)",
    ]
    print(table(headers, rows))


if __name__ == "__main__":
    main()

"""The instruction-set cap (``IMGFORM_ISA``): every level the CPU has gives
the same bits, kernel by kernel, and a bad value is reported."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import imgform_rs as ig

# Runs in a fresh interpreter (the cap is read once): hashes of the outputs
# of kernels with baseline, AVX2, AVX-512 and AMX builds.
SCRIPT = r"""
import hashlib, json
import numpy as np
import imgform_rs as ig
from imgform_rs.lens import LensProfile

rng = np.random.default_rng(7)
h, w = 150, 200
yy, xx = np.mgrid[0:h, 0:w] / 9.0
rgb = np.stack([np.sin(xx + yy), np.cos(xx * 1.3), np.sin(yy * 0.7 - xx)], -1) * 0.4 + 0.5
rgb = np.clip(rgb + 0.05 * rng.standard_normal(rgb.shape), 0, 1)
digest = lambda a: hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()[:16]
out = {"isa": ig.instruction_set()}
for dtype, full in ((np.uint16, 65535), (np.float32, 1.0)):
    raw = ig.mosaic((rgb * full).astype(dtype), "GRBG")
    for method in ig.BAYER_DEMOSAIC_METHODS:
        out[f"demosaic {method} {dtype.__name__}"] = digest(ig.demosaic(raw, "GRBG", method))
profile = LensProfile(
    "test / lens", "test / camera", 1.5, 1.5, 1.5, (0.0, 0.0), 20.0, 4.0, 1000.0,
    ("ptlens", (0.0064, -0.0125, -0.0348)),
    ("poly3", (1.001, 0.9995, 0.0, 0.0, -0.0003, 0.0003)),
    (-0.316, 0.0175, 0.0074),
)
depth = rng.uniform(700.0, 4000.0, (h, w))
for dtype, full in ((np.uint8, 255), (np.uint16, 65535), (np.float32, 1.0)):
    img = (rgb * full).astype(dtype)
    out[f"lens {dtype.__name__}"] = digest(profile.correct(img))
    out[f"lens plain {dtype.__name__}"] = digest(profile.correct(img, vignetting=False))
    out[f"defocus {dtype.__name__}"] = digest(
        ig.render_defocus(img, depth, f=50.0, N=2.0, focus_distance=1000.0, pixel_pitch=0.03)
    )
# NaN and infinities spread through the blur: one NaN for every build.
special = (rgb * 1e30).astype(np.float32)
special[5, 5], special[20, 30], special[30, 10] = np.nan, np.inf, -np.inf
out["defocus specials"] = digest(
    ig.render_defocus(special, depth, f=50.0, N=2.0, focus_distance=1000.0, pixel_pitch=0.03)
)
print(json.dumps(out))
"""


def _run(cap: str | None) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "IMGFORM_ISA"}
    if cap is not None:
        env["IMGFORM_ISA"] = cap
    return subprocess.run(
        [sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, check=True
    )


def test_every_instruction_set_gives_the_same_bits() -> None:
    widest = ig.instruction_set()
    levels = ["baseline", "avx2", "avx512", "amx"]
    runs = {cap: json.loads(_run(cap).stdout) for cap in levels[: levels.index(widest) + 1]}
    for cap, hashes in runs.items():
        assert hashes.pop("isa") == cap
    reference = runs["baseline"]
    assert len(reference) > 20
    for cap, hashes in runs.items():
        differing = [k for k in reference if hashes[k] != reference[k]]
        assert not differing, f"{cap}: {differing}"


def test_a_cap_above_the_cpu_gives_its_widest_and_a_bad_one_warns() -> None:
    ran = _run("amx")
    assert json.loads(ran.stdout)["isa"] == ig.instruction_set()
    ran = _run("sse9")
    assert "IMGFORM_ISA='sse9' is not one of" in ran.stderr
    assert json.loads(ran.stdout)["isa"] == ig.instruction_set()

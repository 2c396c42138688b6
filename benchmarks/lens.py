"""Lens corrections (lensfun profiles) at 24 MP: their cost inside a develop, and
the correction alone against lensfunpy's maps + ``cv2.remap`` in the same run.

The lens is a real database entry with every kind of model: the Canon EF-S
18-55mm f/3.5-5.6 IS on a Canon EOS 550D at 18 mm f/5.6 (distortion ptlens,
TCA poly3, vignetting pa).

- develop: ``develop(raw)`` (default demosaicer, 8-bit sRGB) of a synthetic
  6000 x 4000 RGGB DNG written as from that camera, with ``lens_correction``
  off and with the profile; the ratio is what the corrections add.
- correction alone, a (4000, 6000, 3) float32 linear image (lensfunpy's
  vignetting takes no uint16 image with three channels):
  ours ``LensProfile.correct`` (distortion, TCA and vignetting in one pass:
  each channel sampled bilinearly at its own position, times the vignetting
  gain there, positions stepped along a coarse grid), into a new array and
  with ``out=`` into one array reused from call to call, as for the frames
  of a sequence (a new 288 MB output is zeroed by the OS as it is first
  written, which the reused one is not); lensfunpy
  ``Modifier.apply_subpixel_geometry_distortion`` (the maps) +
  ``apply_color_modification`` (vignetting, in place) + ``cv2.remap``
  (bilinear, one call per channel with its own map, as TCA needs).

Times are the best of ``REPEAT`` (``_bench.measure_rounds``); ratios are of
those best times, within this run.

Run: ``.venv/bin/python benchmarks/lens.py [repeat]`` (default 5).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import cv2
import lensfunpy
import numpy as np
from _bench import measure_rounds, table

from imgform_rs import develop
from imgform_rs.dng import write_dng
from imgform_rs.lens import find_profile
from imgform_rs.raw import load_raw

H, W = 4000, 6000
REPEAT = 5
LENS, CAMERA, FOCAL, APERTURE = "EF-S 18-55mm f/3.5-5.6 IS", ("Canon", "Canon EOS 550D"), 18, 5.6


def mosaic() -> np.ndarray:
    """A smooth 14-bit mosaic with fine detail (no need for a real scene:
    the corrections' cost does not depend on the content)."""
    y = np.linspace(0, 40, H, dtype=np.float32)[:, None]
    x = np.linspace(0, 60, W, dtype=np.float32)[None, :]
    return (3000 + 2500 * np.sin(x) * np.cos(y) + 1500 * np.sin(7 * x + y)).astype(np.uint16)


def lensfunpy_correct(img: np.ndarray, profile) -> np.ndarray:
    db = lensfunpy.Database(load_common=False)
    cam = db.find_cameras(*CAMERA)[0]
    lens = db.find_lenses(cam, None, LENS)[0]
    mod = lensfunpy.Modifier(lens, cam.crop_factor, W, H)
    mod.initialize(FOCAL, APERTURE, profile.distance, scale=1.0, pixel_format=np.float32)
    maps = mod.apply_subpixel_geometry_distortion()
    out = img.copy()
    mod.apply_color_modification(out)
    return np.dstack(
        [
            cv2.remap(np.ascontiguousarray(out[..., c]), maps[:, :, c], None, cv2.INTER_LINEAR)
            for c in range(3)
        ]
    )


def main() -> None:
    repeat = int(sys.argv[1]) if len(sys.argv) > 1 else REPEAT
    match = find_profile(LENS, CAMERA, focal_length=FOCAL, aperture=APERTURE)
    profile = match.profile
    assert profile is not None, match.report()
    print(f"# Lens corrections, {W}x{H}: {profile.describe()}\n")
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "lens.dng"
        write_dng(path, mosaic(), "RGGB", white_level=16383, black_level=512, model=CAMERA[1])
        raw = load_raw(path)
    times = measure_rounds(
        {
            "develop": (lambda: develop(raw), repeat),
            "develop + lens": (lambda: develop(raw, lens_correction=profile), repeat),
        }
    )
    base = times["develop"].best
    rows = [
        [name, f"{t.best:.3f}", f"{t.median:.3f}", f"{t.best / base:.2f}x"]
        for name, t in times.items()
    ]
    print("## Inside a develop (8-bit sRGB)\n")
    print(table(["develop", "best s", "median s", "vs uncorrected"], rows))

    img = np.random.default_rng(0).random((H, W, 3), dtype=np.float32)
    ours = profile.correct(img)
    peer = lensfunpy_correct(img, profile)
    inner = (slice(8, -8), slice(8, -8))
    diff = np.abs(ours[inner] - peer[inner]).mean()
    reused = np.empty_like(img)
    times = measure_rounds(
        {
            "imgform_rs LensProfile.correct": (lambda: profile.correct(img), repeat),
            "imgform_rs LensProfile.correct, out=": (
                lambda: profile.correct(img, out=reused),
                repeat,
            ),
            "lensfunpy maps + vignetting + cv2.remap": (
                lambda: lensfunpy_correct(img, profile),
                max(2, repeat // 2),
            ),
        }
    )
    peer_best = times["lensfunpy maps + vignetting + cv2.remap"].best
    rows = [
        [name, f"{t.best:.3f}", f"{t.median:.3f}", f"{peer_best / t.best:.1f}x"]
        for name, t in times.items()
    ]
    print("\n## Correction alone, float32 RGB\n")
    print(table(["correction", "best s", "median s", "speed vs lensfunpy"], rows))
    print(f"\nmean |ours - lensfunpy + cv2| away from the border: {diff:.2e} (values in [0, 1))")


if __name__ == "__main__":
    main()

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
``exposure="auto"`` (the demosaiced image's histograms give the level), LibRaw
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

The second table is a photographer's whole job, a raw file to a
lens-corrected 8-bit sRGB JPEG (quality 92), from a second 24 MP DNG of the
same scene written as from a Canon EOS 550D with its EF-S 18-55mm IS kit lens
at 18 mm f/5.6 (lensfun: ptlens distortion, poly3 TCA, pa vignetting). Each
contender decodes, develops, corrects and encodes:

- ours: ``develop_file(path, "x.jpg", lens_correction="auto")`` (the lens
  matched from the file's EXIF, our default demosaicer), and the same
  with ``lens_correction="off"`` for the corrections' share;
- LibRaw AHD + lensfunpy + cv2 + Pillow, as a user would chain them:
  ``postprocess`` to linear 16 bit, lensfunpy's vignetting on float32,
  its subpixel maps through ``cv2.remap`` (one bilinear call per channel,
  as TCA needs), the sRGB curve in NumPy, Pillow's JPEG encoder;
- RawTherapee (``rawtherapee-cli``, Debian's package, when installed): its
  neutral processing profile plus ``[LensProfile] LcMode=lfauto`` (distortion,
  TCA and vignetting from its own lensfun database, matched from the same
  EXIF), AMaZE demosaicing, JPEG quality 92; the time includes starting the
  program (about 1.5 s for a small file here), which is part of using it.

The outputs agree in geometry, not in look: RawTherapee's neutral profile
has its own tone and colour, so only ours and the LibRaw chain are compared
(PSNR of ours against it, both from the same camera white balance, sRGB,
no brightening). That PSNR is lower than the first table's: both sides
are JPEG-compressed, and lensfunpy's whole-image maps come from lensfun's
SSE code, whose positions differ from exact ones by up to about 1e-3 of
the radius (a few pixels in the corners at 24 MP, see
``docs/guide/lens.rst``), on a scene of fine stripes.

Run: ``.venv/bin/python benchmarks/develop.py [repeat]`` (default 5; the
JPEG table runs ``max(2, repeat // 2)`` times, RawTherapee being slow).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _bench import measure_rounds, table

import imgform_rs as ig
from imgform_rs.dng import write_dng

H, W = 4000, 6000
REPEAT = 5
CAM_FROM_XYZ = [[1.1, -0.3, -0.1], [-0.4, 1.3, 0.1], [0.0, -0.2, 0.9]]
KIT = dict(
    make="Canon",
    model="Canon EOS 550D",
    lens="EF-S 18-55mm f/3.5-5.6 IS",
    focal_length=18.0,
    f_number=5.6,
)
# RawTherapee's processing profile: its neutral defaults plus lensfun's
# automatic match (the section and keys of RawTherapee 5.9's .pp3 files).
LENS_PP3 = """[Version]
AppVersion=5.9
Version=346

[LensProfile]
LcMode=lfauto
UseDistortion=true
UseVignette=true
UseCA=true
"""

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


def write_raw(path: Path, **metadata) -> None:
    """The 24 MP scene as a 14-bit DNG with a non-sRGB camera and white balance."""
    cfa = ig.simulate_sensor(scene(), "RGGB", bit_depth=14, black_level=512, full_well=30000)
    write_dng(
        path,
        cfa,
        "RGGB",
        white_level=16383 + 512,
        black_level=512,
        color_matrix=CAM_FROM_XYZ,
        as_shot_neutral=(0.55, 1.0, 0.7),
        **metadata,
    )


def libraw_lensfunpy_jpeg(path: Path, out: Path, lens, crop: float) -> None:
    """LibRaw AHD, lensfunpy's corrections through cv2.remap, Pillow's JPEG."""
    import cv2
    import lensfunpy
    import rawpy
    from PIL import Image

    with rawpy.imread(str(path)) as raw:
        linear = raw.postprocess(
            demosaic_algorithm=rawpy.DemosaicAlgorithm.AHD,
            use_camera_wb=True,
            output_bps=16,
            gamma=(1, 1),
            no_auto_bright=True,
        )
    img = linear.astype(np.float32) / 65535
    del linear
    h, w = img.shape[:2]
    mod = lensfunpy.Modifier(lens, crop, w, h)
    mod.initialize(KIT["focal_length"], KIT["f_number"], 1000.0, scale=1.0, pixel_format=np.float32)
    mod.apply_color_modification(img)
    maps = mod.apply_subpixel_geometry_distortion()
    img = np.dstack(
        [
            cv2.remap(np.ascontiguousarray(img[..., c]), maps[..., c, :], None, cv2.INTER_LINEAR)
            for c in range(3)
        ]
    )
    img = np.clip(img, 0, 1)
    srgb = np.where(img <= 0.0031308, 12.92 * img, 1.055 * img ** (1 / 2.4) - 0.055)
    Image.fromarray(np.round(srgb * 255).astype(np.uint8)).save(out, quality=92)


def rawtherapee_version() -> str | None:
    """``rawtherapee-cli``'s version line, or None when it is not installed."""
    exe = shutil.which("rawtherapee-cli")
    if exe is None:
        return None
    done = subprocess.run([exe, "-v"], capture_output=True, text=True)
    lines = (done.stdout + done.stderr).splitlines()
    return next((line for line in lines if "version" in line.lower()), lines[0] if lines else exe)


def rawtherapee_jpeg(path: Path, out: Path, pp3: Path) -> None:
    subprocess.run(
        ["rawtherapee-cli", "-q", "-Y", "-p", str(pp3), "-j92", "-o", str(out), "-c", str(path)],
        capture_output=True,
        check=True,
    )


def jpeg_table(folder: Path, repeat: int) -> None:
    """A raw file to a lens-corrected JPEG: ours, LibRaw + lensfunpy + cv2 +
    Pillow, RawTherapee (see the module docstring)."""
    from PIL import Image

    from imgform_rs.lens import lens_database, match_lens

    path = folder / "kit.dng"
    write_raw(path, **KIT)
    match = match_lens(ig.load_raw(path))
    assert match.profile is not None, match.report()
    db = lens_database()
    camera = db.find_cameras(KIT["make"], KIT["model"])[0]
    lens = db.find_lenses(camera, None, KIT["lens"])[0]
    pp3 = folder / "lens.pp3"
    pp3.write_text(LENS_PP3)
    out = {name: folder / f"{name}.jpg" for name in ("ours", "off", "libraw", "rt")}
    calls = {
        "ours (lens auto)": lambda: ig.develop_file(
            path, out["ours"], lens_correction="auto", overwrite=True
        ),
        "ours (lens off)": lambda: ig.develop_file(path, out["off"], overwrite=True),
        "LibRaw AHD + lensfunpy + cv2 + Pillow": lambda: libraw_lensfunpy_jpeg(
            path, out["libraw"], lens, camera.crop_factor
        ),
    }
    rt = rawtherapee_version()
    if rt is not None:
        calls["RawTherapee (lensfun auto)"] = lambda: rawtherapee_jpeg(path, out["rt"], pp3)
    times = measure_rounds({name: (fn, repeat) for name, fn in calls.items()})
    peer = times["LibRaw AHD + lensfunpy + cv2 + Pillow"].best
    ref = np.asarray(Image.open(out["libraw"])).astype(np.float64)
    ours = np.asarray(Image.open(out["ours"])).astype(np.float64)
    inner = (slice(16, -16), slice(16, -16))
    psnr = 10 * np.log10(255**2 / np.mean((ours[inner] - ref[inner]) ** 2))
    rows = [
        [name, f"{t.best:.2f}", f"{t.median:.2f}", f"{peer / t.best:.2f}x"]
        for name, t in times.items()
    ]
    print(f"\n24 MP raw -> lens-corrected 8-bit sRGB JPEG (q 92), best of {repeat}")
    print(f"lens: {match.report()}")
    print(table(["pipeline", "best s", "median s", "speed vs LibRaw chain"], rows))
    print(f"\nours vs the LibRaw chain (AHD against our demosaicer): {psnr:.1f} dB")
    if rt is None:
        print(
            "RawTherapee: rawtherapee-cli is not installed (apt-get install rawtherapee); left out."
        )
    else:
        size = Image.open(out["rt"]).size
        print(f"RawTherapee: {rt}, output {size[0]}x{size[1]} (it crops a few border pixels).")


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
        write_raw(path)
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
    with tempfile.TemporaryDirectory() as d:
        jpeg_table(Path(d), max(2, repeat // 2))


if __name__ == "__main__":
    main()

"""Demosaicing: speed on a 24 MP uint16 RGGB mosaic and CPSNR on three sets of
RGB images, for every method of ours and every peer installed, in one run.

``python benchmarks/demosaic.py [section ...]`` runs some of the sections (speed,
memory, quality, noisy, oracle, artefacts, xtrans), e.g. ``quality`` alone; none runs
them all.

Speed. The mosaic is a simulated 14-bit raw (``simulate_sensor``) of
scikit-image's astronaut resized to 6000 x 4000, so adaptive methods see real
edges. Peers:

- OpenCV ``cvtColor``: ``COLOR_BayerBG2RGB`` (bilinear; OpenCV names codes after
  the second row, so our RGGB is its BayerBG) and ``_EA`` on the same uint16
  mosaic; ``_VNG`` only accepts uint8, so it runs on the mosaic shifted to 8 bits.
- LibRaw through rawpy: the mosaic is written as a DNG by our writer; we time
  ``postprocess`` of an already-decoded file (``rawpy.imread`` done outside the
  timer). ``postprocess`` also scales, converts colour and packs the output, so it
  is an upper bound on LibRaw's demosaic time; its LINEAR row shows the floor.
- colour-demosaicing (NumPy/SciPy, float64) is slow, so it runs on a 1 MP crop and
  its MP/s is scaled from that.

Artefacts: on a grey zone plate and a grey Siemens star (512 x 512, 8-bit), the
false-colour energy (any chroma is an error on a grey chart) and Lu and Tan's
zipper fraction, for every method of ours and of the peers.

CPSNR (the usual 8-bit protocol): uint8 RGB image, mosaic RGGB, demosaic, crop 10
pixels on every side, ``CPSNR = 10 log10(255^2 / MSE)`` with the MSE over all three
channels. Float peers are rounded to uint8 first; LibRaw reads the mosaic
(times 257, 16 bits) from a DNG and develops it linearly in camera RGB without
white balance, so only its demosaicer differs. The peers are OpenCV, LibRaw,
colour-demosaicing, eari-demosaic's residual interpolation (``pyeari.ri``, float32
NumPy/SciPy/OpenCV; ``make bench`` installs it without its opencv-python
dependency, which would clash with our headless OpenCV) and, if installed,
demosaicnet. Three subsets, each scored by the mean CPSNR over its
images, and one mean over the subsets, so that the 68 small CBSD68 images do not
outweigh the others:

- skimage7: scikit-image's seven RGB images in ``EVALUATION_IMAGES``, held out of
  every training.
- CBSD68: the colour versions of the 68 BSDS300 test images (481 x 321, either way
  up): natural scenes.
- Urban24: Urban100's img_001..img_024 at full resolution (long side 1024 to 1280),
  buildings whose regular structures alias. img_011 is achromatic (R = G = B), so
  any chroma there is pure false colour; it counts like any other image.

Noisy: the same CPSNR, against the clean images, of mosaics with photon noise
(variance proportional to the value, 2 levels at mid grey) and read noise (0.5
level), rounded back to 8 bits and seeded per image: what a method's lead is worth
on data like a sensor's, with no denoising by anyone.

CBSD68 and Urban24 are in the shared folder ``demosaic-val`` next to the repository
(``../shared/data/demosaic-val``; the environment variable ``IMGFORM_DEMOSAIC_VAL``
names another), whose README and MANIFEST.tsv give their sources (cszn/FFDNet's
CBSD68, the Urban100 authors' SelfExSR) and licences: research test sets that we
may only evaluate on. Never commit them, and never train or tune anything
shipped on them. Without the folder only skimage7 is scored.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
import zlib
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _bench import measure, measure_rounds, table

import imgform_rs as ig
from imgform_rs.dng import write_dng
from imgform_rs.training.demosaic import EVALUATION_IMAGES

H, W = 4000, 6000
MP = H * W / 1e6
CROP = (800, 1250)  # 1 MP for colour-demosaicing
IMAGES = EVALUATION_IMAGES  # held out of every training
LIBRAW_METHODS = ["LINEAR", "VNG", "PPG", "AHD", "DCB", "DHT", "AAHD"]
SECTIONS = ["speed", "memory", "quality", "noisy", "oracle", "artefacts", "xtrans"]
SKIMAGE7 = "skimage7"
# The subsets in the shared demosaic-val folder: name in the tables, subfolder.
VALIDATION_SUBSETS = {"CBSD68": "cbsd68", "Urban24": "urban24"}
DEMOSAICNET = "demosaicnet (Gharbi 2016)"
LEARNED_PEERS = {DEMOSAICNET}  # left out of "best classical peer"
Methods = dict[str, Callable[[np.ndarray, str], np.ndarray]]
Scores = dict[str, dict[str, dict[str, float]]]  # method -> subset -> image -> CPSNR


def optional(name: str):
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return __import__(name)
    except ImportError:
        return None


cv2 = optional("cv2")
rawpy = optional("rawpy")
cd = optional("colour_demosaicing")
demosaicnet = optional("demosaicnet")  # the bench-learned extra
pyeari = optional("pyeari")  # eari-demosaic, installed by make bench with --no-deps


def demosaicnet_rggb(net, raw: np.ndarray) -> np.ndarray:
    """Gharbi et al.'s network on our uint8 RGGB mosaic (protocol of ``quality``).

    The network takes a GRBG mosaic as three masked channels in [0, 1], whose
    sides are even: our RGGB seen from column 1 on is GRBG, so the mosaic is cut to
    even sides from column 1, mirrored by 48 pixels (the unpadded network shrinks
    its input) and the output's middle put back; the pixels left out are within
    the 10 cropped pixels.
    """
    import torch

    h, w = raw.shape
    masks = ig.channel_masks(raw.shape, "RGGB")
    planes = raw[..., None] * masks / np.float32(255)
    sub = planes[: h // 2 * 2, 1 : 1 + (w - 1) // 2 * 2].astype(np.float32)
    pad = 48
    padded = np.pad(sub, ((pad, pad), (pad, pad), (0, 0)), mode="reflect")
    with torch.no_grad():
        out = net(torch.from_numpy(padded.transpose(2, 0, 1).copy())[None])[0].numpy()
    out = out.transpose(1, 2, 0)
    dy, dx = ((o - s) // 2 for o, s in zip(out.shape[:2], sub.shape[:2], strict=True))
    rgb = np.zeros((h, w, 3), np.uint8)
    rgb[: sub.shape[0], 1 : 1 + sub.shape[1]] = to_u8(
        out[dy : dy + sub.shape[0], dx : dx + sub.shape[1]], 255.0
    )
    return rgb


def libraw_develop(path: str, algorithm: str):
    """A decoded file and the call that develops it with one demosaicer."""
    raw = rawpy.imread(path)
    algo = getattr(rawpy.DemosaicAlgorithm, algorithm)
    if not algo.isSupported:
        raw.close()
        return None, None

    def develop():
        return raw.postprocess(
            demosaic_algorithm=algo,
            output_bps=16,
            gamma=(1, 1),
            no_auto_bright=True,
            output_color=rawpy.ColorSpace.raw,
            use_camera_wb=False,
            use_auto_wb=False,
            user_wb=[1.0, 1.0, 1.0, 1.0],
            user_flip=0,
            user_black=0,
            user_sat=65535,
        )

    return raw, develop


def speed_mosaic(pattern: str = "RGGB") -> np.ndarray:
    from skimage import data

    scene = data.astronaut().astype(np.float32) / 255.0
    if cv2 is not None:
        scene = cv2.resize(scene, (W, H), interpolation=cv2.INTER_LINEAR)
    else:
        scene = np.kron(scene, np.ones((8, 12, 1), np.float32))[:H, :W]
    linear = scene**2.2
    return ig.simulate_sensor(linear, pattern, full_well=20000, bit_depth=14, black_level=0)


def speed(tmp: Path) -> None:
    raw = speed_mosaic()
    calls: dict[str, tuple[Callable[[], object], int]] = {}
    meta: dict[str, tuple[float, str]] = {}
    handles = []

    def add(name: str, fn: Callable[[], object], mp: float, repeat: int, note: str = ""):
        calls[name] = (fn, repeat)
        meta[name] = (mp, note)

    for m in ig.BAYER_DEMOSAIC_METHODS:
        add(f"ours {m}", lambda m=m: ig.demosaic(raw, "RGGB", m), MP, 7)
    buf = np.empty((*raw.shape, 3), raw.dtype)
    reuse = "into a reused buffer: no fresh output's page faults"
    add("ours best, out=", lambda: ig.demosaic(raw, "RGGB", "best", out=buf), MP, 7, reuse)
    if cv2 is not None:
        add("OpenCV bilinear", lambda: cv2.cvtColor(raw, cv2.COLOR_BayerBG2RGB), MP, 7)
        add("OpenCV EA", lambda: cv2.cvtColor(raw, cv2.COLOR_BayerBG2RGB_EA), MP, 5)
        raw8 = (raw >> 6).astype(np.uint8)
        vng = cv2.COLOR_BayerBG2RGB_VNG
        add("OpenCV VNG", lambda: cv2.cvtColor(raw8, vng), MP, 3, "uint8 input")
    if rawpy is not None:
        path = str(tmp / "speed.dng")
        write_dng(path, raw, "RGGB", white_level=2**14 - 1)

        def decode():
            with rawpy.imread(path) as r:
                return r.raw_image_visible.shape

        add("LibRaw decode", decode, MP, 3, "imread + unpack; not in the rows below")
        for algo in ["LINEAR", "VNG", "PPG", "AHD"]:
            handle, develop = libraw_develop(path, algo)
            if develop is None:
                continue
            handles.append(handle)
            # As many runs as ours get (nearly): best of 2 would favour us
            # on this VM, whose speed swings between runs.
            add(f"LibRaw {algo}", develop, MP, 5, "postprocess, file decoded")
    if cd is not None:
        crop = raw[: CROP[0], : CROP[1]].astype(np.float64) / (2**14 - 1)
        mp = crop.size / 1e6
        for name, fn in [
            ("bilinear", cd.demosaicing_CFA_Bayer_bilinear),
            ("Malvar2004", cd.demosaicing_CFA_Bayer_Malvar2004),
            ("Menon2007", cd.demosaicing_CFA_Bayer_Menon2007),
        ]:
            reps = 1 if name == "Menon2007" else 2
            add(f"colour {name}", lambda fn=fn: fn(crop, "RGGB"), mp, reps, "1 MP crop, scaled")
    # Interleaved rounds, so that the VM's drift cannot favour ours or a peer.
    timings = measure_rounds(calls)
    for handle in handles:
        handle.close()
    results = {name: t.best for name, t in timings.items()}
    rows = []
    for name, t in timings.items():
        mp, note = meta[name]
        ms = [f"{t.best * 1e3:.1f}", f"{t.median * 1e3:.1f}"]
        rows.append([name, *ms, f"{mp / t.best:.0f}", note])
    print(f"\n## Speed: {W}x{H} ({MP:.0f} MP) uint16 RGGB, {os.cpu_count()} cores")
    print("best of N, timed in interleaved rounds; MP/s at the best time\n")
    print(table(["method", "best ms", "median ms", "MP/s", "note"], rows))
    ratios = []
    for ours in ig.BAYER_DEMOSAIC_METHODS:
        for peer in ["OpenCV bilinear", "OpenCV EA", "LibRaw LINEAR", "LibRaw AHD"]:
            if peer in results:
                ratio = results[peer] / results[f"ours {ours}"]
                ratios.append([ours, peer, f"{ratio:.2f}x"])
    print("\nSpeed-up of ours over each peer (same run; > 1 means ours is faster)\n")
    print(table(["ours", "peer", "speed-up"], ratios))


# Peak resident memory of a fresh process around one demosaic call, minus the
# output: what the call needs beyond its result. The mosaic is built without
# temporaries, so the peak before the call is just the interpreter and input.
# Linux's VmHWM, not ru_maxrss: the latter keeps the parent's peak across
# fork and exec, which hid the child's growth here.
MEMORY_CODE = """
import sys, numpy as np, imgform_rs as ig
def peak():
    line = [s for s in open("/proc/self/status") if s.startswith("VmHWM")][0]
    return int(line.split()[1]) * 1024
raw = np.zeros((4000, 6000), np.uint16)
raw[:] = np.arange(6000, dtype=np.uint16) % 4096
ig.demosaic(raw[:64, :64], "RGGB", sys.argv[1])
before = peak()
out = ig.demosaic(raw, "RGGB", sys.argv[1])
print(peak() - before - out.nbytes, out.nbytes)
"""


def memory() -> None:
    import subprocess

    if not os.path.exists("/proc/self/status"):
        print("\n(extra memory: needs Linux's /proc, skipped)")
        return
    rows = []
    for m in ig.BAYER_DEMOSAIC_METHODS:
        done = subprocess.run(
            [sys.executable, "-c", MEMORY_CODE, m], capture_output=True, text=True, check=True
        )
        extra, out = (int(v) for v in done.stdout.split())
        rows.append([m, f"{out / 2**20:.0f}", f"{extra / 2**20:.1f}", f"{100 * extra / out:.1f} %"])
    print("\n## Extra memory at 24 MP uint16 (peak RSS growth minus the output)\n")
    print(table(["method", "output MiB", "extra MiB", "extra / output"], rows))


def load_images() -> dict[str, np.ndarray]:
    from skimage import data

    images = {}
    for name in IMAGES:
        # The left view of the Middlebury motorcycle pair is stereo_motorcycle()[0].
        loader = data.stereo_motorcycle if name == "motorcycle_left" else getattr(data, name)
        try:
            img = loader()
        except Exception as exc:  # a download that is impossible here
            print(f"skipped {name}: {type(exc).__name__}: {str(exc)[:80]}")
            continue
        if isinstance(img, tuple):  # (left, right, disparity): take the left view
            img = img[0]
        if img.ndim == 3 and img.shape[2] == 3:
            images[name] = np.ascontiguousarray(img.astype(np.uint8))
    return images


def validation_dir() -> Path:
    """The shared demosaic-val folder: outside the repository, because its images
    may not be redistributed; ``IMGFORM_DEMOSAIC_VAL`` points elsewhere."""
    env = os.environ.get("IMGFORM_DEMOSAIC_VAL")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "demosaic-val"


def load_pngs(folder: Path) -> dict[str, np.ndarray]:
    """Every PNG of a folder by file stem, checked to be 8-bit RGB (the protocol)."""
    from skimage.io import imread

    images = {}
    for path in sorted(folder.glob("*.png")):
        img = imread(path)
        if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
            raise ValueError(f"{path}: {img.dtype} {img.shape}, expected uint8 RGB")
        images[path.stem] = np.ascontiguousarray(img)
    return images


def validation_images() -> dict[str, dict[str, np.ndarray]]:
    """The quality images as ``{subset: {name: uint8 RGB}}``: skimage7 always,
    CBSD68 and Urban24 when the demosaic-val folder is there (for evaluation only:
    never train or tune on them)."""
    subsets = {SKIMAGE7: load_images()}
    root = validation_dir()
    for subset, folder in VALIDATION_SUBSETS.items():
        images = load_pngs(root / folder) if (root / folder).is_dir() else {}
        if images:
            subsets[subset] = images
        else:
            print(f"skipped {subset}: no PNGs in {root / folder} (set IMGFORM_DEMOSAIC_VAL)")
    return subsets


def cpsnr(out: np.ndarray, ref: np.ndarray) -> float:
    d = out[10:-10, 10:-10].astype(np.float64) - ref[10:-10, 10:-10].astype(np.float64)
    return 10 * np.log10(255.0**2 / np.mean(d**2))


def to_u8(x: np.ndarray, scale: float) -> np.ndarray:
    return np.clip(np.round(x * scale), 0, 255).astype(np.uint8)


def all_methods(tmp: Path) -> dict[str, Callable[[np.ndarray, str], np.ndarray]]:
    """Every demosaicer, ours and the peers', as ``f(uint8 RGGB mosaic, name) -> uint8 RGB``."""
    methods: dict[str, Callable[[np.ndarray, str], np.ndarray]] = {}
    for m in ig.BAYER_DEMOSAIC_METHODS:
        methods[f"ours {m}"] = lambda raw, name, m=m: ig.demosaic(raw, "RGGB", m)
    if cv2 is not None:
        for label, code in [("bilinear", ""), ("VNG", "_VNG"), ("EA", "_EA")]:
            c = getattr(cv2, f"COLOR_BayerBG2RGB{code}")
            methods[f"OpenCV {label}"] = lambda raw, name, c=c: cv2.cvtColor(raw, c)
    if cd is not None:
        for label in ["bilinear", "Malvar2004", "Menon2007"]:
            fn = getattr(cd, f"demosaicing_CFA_Bayer_{label}")
            methods[f"colour {label}"] = lambda raw, name, fn=fn: to_u8(
                fn(raw.astype(np.float64) / 255.0, "RGGB"), 255.0
            )
    if rawpy is not None:
        for algo in LIBRAW_METHODS:
            if not getattr(rawpy.DemosaicAlgorithm, algo).isSupported:
                print(f"LibRaw {algo}: not supported by this rawpy build")
                continue

            def libraw(raw, name, algo=algo):
                path = str(tmp / f"{name}.dng")
                if not os.path.exists(path):
                    write_dng(path, raw.astype(np.uint16) * 257, "RGGB", white_level=65535)
                handle, develop = libraw_develop(path, algo)
                with handle:
                    return to_u8(develop(), 1 / 257)

            methods[f"LibRaw {algo}"] = libraw
    if pyeari is not None:
        # pyeari.ri is the function: the package's `from .ri import ri` shadows the
        # submodule of that name, so there is no pyeari.ri.ri.
        ri = pyeari.ri
        methods["eari-demosaic RI"] = lambda raw, name: to_u8(ri(raw, "RGGB"), 255.0)
    else:
        # The strongest classical peer: without it the margins are over a weaker
        # one, so say so where the tables are read.
        print("\nskipped eari-demosaic RI: pyeari is not installed (make bench-peers)")
    if demosaicnet is not None:
        net = demosaicnet.BayerDemosaick(pretrained=True, pad=False).eval()
        methods[DEMOSAICNET] = lambda raw, name: demosaicnet_rggb(net, raw)
    return methods


def clean_mosaic(rgb: np.ndarray, key: str) -> np.ndarray:
    """The RGGB mosaic of ``rgb``, as sampled."""
    return ig.mosaic(rgb, "RGGB")


def score(
    tmp: Path,
    methods: Methods,
    subsets: dict[str, dict[str, np.ndarray]],
    mosaic: Callable[[np.ndarray, str], np.ndarray] = clean_mosaic,
) -> tuple[Scores, dict[str, float]]:
    """CPSNR of every method on every image's ``mosaic``, against the image, and
    each method's seconds in all. An image is named ``mosaic-subset-name`` to the
    methods: LibRaw's DNG is keyed by it, so two subsets' images of the same name,
    or one image's clean and noisy mosaics, cannot share one."""
    scores: Scores = {m: {s: {} for s in subsets} for m in methods}
    seconds = dict.fromkeys(methods, 0.0)
    for subset, images in subsets.items():
        for name, rgb in images.items():
            key = f"{mosaic.__name__}-{subset}-{name}"
            raw = mosaic(rgb, key)
            for m, fn in methods.items():
                start = time.perf_counter()
                out = fn(raw, key)
                seconds[m] += time.perf_counter() - start
                scores[m][subset][name] = cpsnr(out, rgb)
            (tmp / f"{key}.dng").unlink(missing_ok=True)  # 99 DNGs would add up
    return scores, seconds


def subset_means(scores: Scores) -> dict[str, dict[str, float]]:
    """Per method, each subset's mean CPSNR and, under "mean", their mean: every
    subset weighs the same, however many images it has."""
    means = {}
    for m, by_subset in scores.items():
        means[m] = {s: float(np.mean(list(v.values()))) for s, v in by_subset.items()}
        means[m]["mean"] = float(np.mean(list(means[m].values())))
    return means


def print_seven(scores: Scores) -> None:
    """The per-image table on skimage7, as before the other subsets came."""
    names = list(next(iter(scores.values()))[SKIMAGE7])
    rows = []
    for m in sorted(scores, key=lambda m: -np.mean(list(scores[m][SKIMAGE7].values()))):
        vals = [scores[m][SKIMAGE7][n] for n in names]
        rows.append([m, *(f"{v:.2f}" for v in vals), f"{np.mean(vals):.2f}"])
    print(f"\n## CPSNR (dB) on {SKIMAGE7}, per image; sorted by mean\n")
    print(table(["method", *names, "mean"], rows))


def print_margins(means: dict[str, dict[str, float]], columns: list[str], what: str = "") -> None:
    """Per subset, the best of ours against the best classical peer (learned
    peers such as demosaicnet left out): positive margins are ours ahead."""
    ours = [m for m in means if m.startswith("ours ")]
    peers = [m for m in means if not m.startswith("ours ") and m not in LEARNED_PEERS]
    if not peers:
        return
    rows = []
    for col in columns:
        a = max(ours, key=lambda m: means[m][col])
        b = max(peers, key=lambda m: means[m][col])
        margin = means[a][col] - means[b][col]
        label = "mean of subsets" if col == "mean" else col
        rows.append([label, a, f"{means[a][col]:.2f}", b, f"{means[b][col]:.2f}", f"{margin:+.2f}"])
    print(f"\n## Best of ours against the best classical peer{what}, per subset (CPSNR dB)\n")
    print(table(["subset", "best of ours", "dB", "best classical peer", "dB", "margin"], rows))


def print_means(means: dict[str, dict[str, float]], subsets: dict[str, dict]) -> list[str]:
    """The table of subset means, sorted by their mean; the columns printed."""
    columns = [*subsets, "mean"]
    head = ["method", *(f"{s} ({len(subsets[s])})" for s in subsets), "mean of subsets"]
    rows = [
        [m, *(f"{means[m][c]:.2f}" for c in columns)]
        for m in sorted(means, key=lambda m: -means[m]["mean"])
    ]
    print(table(head, rows))
    return columns


def quality(tmp: Path, methods: Methods) -> None:
    """CPSNR by subset: a method can win on CBSD68's natural scenes and lose on
    Urban24's aliasing structures, which one mean over all images would hide."""
    start = time.perf_counter()
    subsets = validation_images()
    scores, seconds = score(tmp, methods, subsets)
    took = time.perf_counter() - start
    if SKIMAGE7 in subsets:
        print_seven(scores)
    means = subset_means(scores)
    print("\n## CPSNR (dB), 8-bit protocol, RGGB, 10 px border cropped: mean over each")
    print("subset's images (image count in brackets); sorted by the mean of the subset means\n")
    columns = print_means(means, subsets)
    print_margins(means, columns)
    count = sum(len(v) for v in subsets.values())
    mp = sum(rgb.shape[0] * rgb.shape[1] for v in subsets.values() for rgb in v.values()) / 1e6
    rows = [[m, f"{seconds[m]:.2f}"] for m in sorted(seconds, key=lambda m: -seconds[m])]
    print(f"\n## Seconds per method over the {count} images ({mp:.1f} MP), 1 run each\n")
    print(table(["method", "s"], rows))
    print(f"\nquality took {took:.0f} s in all ({os.cpu_count()} cores)")


# The classical bases of the oracle and the sets of them it chooses from: each
# alone, each pair with MLRI, the best three, all five.
#: Noise of :func:`noisy_mosaic`, in 8-bit levels: photon noise of variance
#: ``value / SHOT`` (2 levels at mid grey) and read noise.
SHOT, READ = 32.0, 0.5
NOISE_SEED = 20261205


def noisy_mosaic(rgb: np.ndarray, key: str) -> np.ndarray:
    """The RGGB mosaic of ``rgb`` with photon and read noise (:data:`SHOT`,
    :data:`READ`), rounded back to 8 bits; seeded by the image's key, so every
    method sees the same samples in every run."""
    raw = ig.mosaic(rgb, "RGGB").astype(np.float64)
    rng = np.random.default_rng([NOISE_SEED, zlib.crc32(key.encode())])
    sigma = np.sqrt(raw / SHOT + READ**2)
    return np.clip(np.round(raw + sigma * rng.standard_normal(raw.shape)), 0, 255).astype(np.uint8)


def noisy(tmp: Path, methods: Methods) -> None:
    """CPSNR against the clean images of noisy mosaics: whether a method's lead
    holds on data like a sensor's, where gradients and hashes also see noise."""
    subsets = validation_images()
    scores, _ = score(tmp, methods, subsets, noisy_mosaic)
    means = subset_means(scores)
    print(f"\n## CPSNR (dB) of noisy mosaics (photon noise of variance value / {SHOT:.0f}, 2")
    print(f"levels at mid grey, read noise {READ} level, rounded to 8 bits) against the clean")
    print("images; otherwise as the CPSNR table; sorted by the mean of the subset means\n")
    columns = print_means(means, subsets)
    print_margins(means, columns, " on noisy mosaics")


ORACLE_BASES = ["mlri", "menon2007", "rcd", "leung2011", "ahd"]
ORACLE_SETS = [
    *([b] for b in ORACLE_BASES),
    *(["mlri", b] for b in ORACLE_BASES[1:]),
    ["mlri", "menon2007", "rcd"],
    ORACLE_BASES,
]


def oracle() -> None:
    """The per-pixel oracle: at every pixel the base whose three colours are
    closest to the truth, scored like ``quality``. It bounds what any per-pixel
    combination of these bases can reach, so it says whether a fusion of them has
    room left (its own row, ``ours fusion``, for comparison) before a better base
    is needed. An upper bound only: it picks with the truth in hand."""
    subsets = validation_images()
    choices = {"+".join(c): c for c in ORACLE_SETS} | {"ours fusion": ["fusion"]}
    scores = {name: {s: [] for s in subsets} for name in choices}
    for subset, images in subsets.items():
        for rgb in images.values():
            raw = ig.mosaic(rgb, "RGGB")
            ref = rgb[10:-10, 10:-10].astype(np.float64)
            err = {}
            for m in [*ORACLE_BASES, "fusion"]:
                out = ig.demosaic(raw, "RGGB", m)[10:-10, 10:-10].astype(np.float64)
                err[m] = ((out - ref) ** 2).sum(-1)
            for name, c in choices.items():
                mse = np.min([err[m] for m in c], axis=0).mean() / 3
                scores[name][subset].append(10 * np.log10(255.0**2 / mse))
    rows = [[name, *(f"{np.mean(v[s]):.2f}" for s in subsets)] for name, v in scores.items()]
    print("\n## Per-pixel oracle over our classical bases: CPSNR (dB) of the best base at")
    print("each pixel, chosen with the truth (an upper bound for any per-pixel fusion)\n")
    print(table(["bases", *subsets], rows))


def zone_plate(n: int = 512) -> np.ndarray:
    """A grey zone plate: rings whose frequency grows to Nyquist at the corners."""
    y, x = (np.mgrid[0:n, 0:n] - n / 2) / n
    return 0.5 + 0.5 * np.cos(np.pi * n * (x**2 + y**2))


def starburst(n: int = 512, spokes: int = 72) -> np.ndarray:
    """A grey Siemens star: spokes whose period shrinks towards the centre."""
    y, x = np.mgrid[0:n, 0:n] - (n - 1) / 2
    return 0.5 + 0.5 * np.sin(spokes * np.arctan2(y, x))


def zipper_fraction(out: np.ndarray, ref: np.ndarray) -> float:
    """Lu and Tan's zipper measure (IEEE TIP 2003): for each pixel, the
    8-neighbour of the most similar colour in the reference; a zipper pixel is
    one whose CIELab difference to that neighbour grows by more than 2.3 in the
    output. Returns the fraction of zipper pixels (border cropped)."""
    from skimage.color import rgb2lab

    lab_ref, lab_out = rgb2lab(ref), rgb2lab(out)
    h, w = ref.shape[:2]
    core = (slice(10, h - 10), slice(10, w - 10))
    best_d = np.full((h - 20, w - 20), np.inf)
    change = np.zeros((h - 20, w - 20))
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy == dx == 0:
                continue
            nb = (slice(10 + dy, h - 10 + dy), slice(10 + dx, w - 10 + dx))
            d_ref = np.linalg.norm(lab_ref[core] - lab_ref[nb], axis=-1)
            d_out = np.linalg.norm(lab_out[core] - lab_out[nb], axis=-1)
            closer = d_ref < best_d
            best_d = np.where(closer, d_ref, best_d)
            change = np.where(closer, np.abs(d_out - d_ref), change)
    return float(np.mean(change > 2.3))


def artefacts(methods: dict[str, Callable[[np.ndarray, str], np.ndarray]]) -> None:
    """False colour and zipper on grey test charts, where any chroma is an error."""
    charts = {"zoneplate": zone_plate(), "starburst": starburst()}
    rows = []
    results = {m: [] for m in methods}
    for name, grey in charts.items():
        rgb = np.repeat((grey * 255).round().astype(np.uint8)[..., None], 3, axis=2)
        raw = ig.mosaic(rgb, "RGGB")
        for m, fn in methods.items():
            full = fn(raw, name)
            out = full.astype(np.float64)[10:-10, 10:-10]
            g = out[..., 1]
            false_colour = np.mean((out[..., 0] - g) ** 2 + (out[..., 2] - g) ** 2)
            results[m] += [false_colour, 100 * zipper_fraction(full, rgb)]
    for m in sorted(methods, key=lambda m: results[m][0] + results[m][2]):
        rows.append([m, *(f"{v:.1f}" for v in results[m])])
    print("\n## Artefacts on grey 512x512 charts (RGGB, 8-bit, 10 px crop); lower is better\n")
    print("false colour: mean of (R-G)^2 + (B-G)^2; zipper: % of pixels (Lu-Tan, CIELab > 2.3)\n")
    head = ["method", "zone plate false colour", "zone plate zipper %"]
    head += ["starburst false colour", "starburst zipper %"]
    print(table(head, rows))


# LibRaw runs Markesteijn on X-Trans for every algorithm but LINEAR: 1 pass
# for VNG and PPG, 3 passes from AHD up (dcraw's quality > 2).
XTRANS_LIBRAW = ["LINEAR", "PPG", "AHD"]


def xtrans(tmp: Path) -> None:
    """X-Trans: CPSNR on the images mosaiced with Fujifilm's tile, and speed at
    24 MP, ours against LibRaw's Markesteijn (same protocol as above). LibRaw
    refuses X-Trans images under 512 pixels a side, so for it smaller images are
    mirror-padded at the bottom and right (which keeps the tile's phase) and its
    output cropped back."""
    tile = ig.pattern_cells("XTRANS")
    methods: dict[str, Callable[[np.ndarray, str], np.ndarray]] = {}
    for m in ig.XTRANS_DEMOSAIC_METHODS[:-1]:
        methods[f"ours {m}"] = lambda rgb, name, m=m: ig.demosaic(ig.mosaic(rgb, tile), tile, m)
    for algo in XTRANS_LIBRAW if rawpy is not None else []:

        def libraw(rgb, name, algo=algo):
            path = str(tmp / f"xtrans-{name}.dng")
            if not os.path.exists(path):
                h, w = rgb.shape[:2]
                padded = np.pad(
                    rgb, ((0, max(0, 512 - h)), (0, max(0, 512 - w)), (0, 0)), "reflect"
                )
                raw = ig.mosaic(np.ascontiguousarray(padded), tile)
                write_dng(path, raw.astype(np.uint16) * 257, tile, white_level=65535)
            handle, develop = libraw_develop(path, algo)
            with handle:
                return to_u8(develop(), 1 / 257)[: rgb.shape[0], : rgb.shape[1]]

        methods[f"LibRaw {algo}"] = libraw
    images = load_images()
    rows = []
    for m, fn in methods.items():
        vals = [cpsnr(fn(rgb, name), rgb) for name, rgb in images.items()]
        rows.append([m, *(f"{v:.2f}" for v in vals), f"{np.mean(vals):.2f}"])
    print("\n## X-Trans CPSNR (dB), 8-bit protocol, 10 px border cropped\n")
    print(table(["method", *images, "mean"], rows))

    raw = speed_mosaic("XTRANS")
    rows = []
    for m in ig.XTRANS_DEMOSAIC_METHODS[:-1]:
        t = measure(m, lambda m=m: ig.demosaic(raw, "XTRANS", m), repeat=3)
        rows.append([f"ours {m}", f"{t.best * 1e3:.0f}", f"{MP / t.best:.1f}"])
    if rawpy is not None:
        path = str(tmp / "xtrans-speed.dng")
        write_dng(path, raw, tile, white_level=2**14 - 1)
        handle, develop = libraw_develop(path, "AHD")
        t = measure("LibRaw AHD", develop, repeat=2)
        rows.append(
            ["LibRaw AHD (3-pass Markesteijn)", f"{t.best * 1e3:.0f}", f"{MP / t.best:.1f}"]
        )
        handle.close()
    print(f"\n## X-Trans speed: {W}x{H} uint16, {os.cpu_count()} cores, best of 3 (LibRaw 2)\n")
    print(table(["method", "best ms", "MP/s"], rows))


def sections() -> set[str]:
    """The sections named on the command line, all of them if none is."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    # Checked by hand: argparse rejects an empty list for nargs="*" with choices.
    parser.add_argument("section", nargs="*", help=f"any of {', '.join(SECTIONS)}; default all")
    wanted = parser.parse_args().section
    unknown = set(wanted) - set(SECTIONS)
    if unknown:
        parser.error(f"unknown section {', '.join(sorted(unknown))}; choose from {SECTIONS}")
    return set(wanted or SECTIONS)


def main() -> None:
    wanted = sections()
    with tempfile.TemporaryDirectory() as d:
        if "speed" in wanted:
            speed(Path(d))
        if "memory" in wanted:
            memory()
        if wanted & {"quality", "noisy", "artefacts"}:
            methods = all_methods(Path(d))
            if "quality" in wanted:
                quality(Path(d), methods)
            if "noisy" in wanted:
                noisy(Path(d), methods)
            if "artefacts" in wanted:
                artefacts(methods)
        if "oracle" in wanted:
            oracle()
        if "xtrans" in wanted:
            xtrans(Path(d))


if __name__ == "__main__":
    main()

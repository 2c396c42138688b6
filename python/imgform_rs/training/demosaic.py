"""Training of the learned demosaicers' filter banks: ``"raisr"`` (rebuilds
``raisr_weights.bin``), ``"raisr_fast"`` (``raisr_fast_weights.bin``), ``"raisr_cd"``
(``raisr_cd_weights.bin``), ``"fusion"`` (``fusion_weights.bin``) and
``"fusion_refined"`` (``fusion_refined_weights.bin``).

RAISR (Romano, Isidoro and Milanfar, "RAISR: Rapid and Accurate Image Super
Resolution", IEEE Transactions on Computational Imaging 3(1), 2017) learns, per
class of local structure, a least-squares linear filter from a cheap estimate to the
truth. Here the estimate is ``demosaic(..., "mlri")`` and each filter maps 26
features of it around a pixel to the residual (truth - estimate) of the pixel's two
missing colours. The classes, the features and the hash are those of
``rust/imgform-core/src/demosaic/raisr.rs``, reproduced here operation for
operation in float32 so that a pixel falls in the same class in both.

``"raisr_fast"`` keeps the features and drops most of the hash: its 32 classes are
the CFA position, the quadrant of the tensor's doubled orientation
(:func:`orientation`) and whether the tensor is anisotropic (:func:`coherent`), as in
``rust/imgform-core/src/demosaic/oriented.rs``, few enough for the kernel to filter
sixteen pixels side by side. ``"raisr_cd"`` is the same
over ``demosaic(..., "ri_cd")``, whose red and blue are colour differences.

``"fusion"`` is the same machinery with two bases: the filters refine
``demosaic(..., "ri_cd")`` and also see ``"rcd"``'s difference from it over the
3x3 window (27 more features), so that per class they learn how far to trust either
(``Method::Fusion`` in ``rust/imgform-core/src/demosaic/mod.rs``).

``"fusion_refined"`` is a cascade: ``"raisr_fast"``'s classes and features over the
output of ``"fusion"`` as the extension built with the shipped ``fusion_weights.bin``
computes it, so it is retrained after any change to ``"fusion"`` and a rebuild.

All of them train on the extended photographs (:func:`imgform_rs.training.sets.training_images`,
set ``"photos"``: 293 openly licensed photographs, each cropped, flipped or turned and
re-exposed once at random), never on the benchmark's images nor the validation
subsets. Every image is quantised to 8 bits, mosaicked RGGB (the four CFA positions
all occur) and demosaicked in float32. The normal equations are summed exactly and
solved with a small ridge term in a fixed order (:mod:`imgform_rs.training.lstsq`),
and the filters rounded to float32: every run gives identical bytes, on any machine
(BLAS kernels sum in an order of their own, which made weights trained on one CPU
differ from another's in a few last bits). The choices were made on the nine held-out photographs of
that module (set ``"held-out"``), mean CPSNR:

=================================================================  =========
method, trained on                                                 held out
=================================================================  =========
``"mlri"`` alone (no training)                                     36.62
``"raisr"`` over ``"rcd_menon"``, the first 33 photographs         36.55
``"raisr"`` over ``"mlri"``, the 293 photographs                   37.31
``"raisr_fast"`` over ``"mlri"``, orientation (16 classes)         37.14
``"raisr_fast"`` over ``"mlri"``, orientation, shape (32)          37.19
``"ri_cd"`` alone (no training)                                    36.55
``"raisr_cd"`` over ``"ri_cd"``, orientation (16 classes)          36.98
``"raisr_cd"`` over ``"ri_cd"``, orientation, shape (32)           37.04
``"raisr_cd"``, saturated classes, bounded (64; shipped)           37.10
``"fusion"`` with ``"rcd_menon"``, 33 photographs and textures     37.01
``"fusion"`` with ``"rcd_menon"``, the 293 photographs             37.43
``"fusion"`` with ``"rcd_menon"``, 293 photographs, 192 synthetic  35.99
``"fusion"`` with ``"rcd"``, the 293 photographs                   37.48
``"fusion_refined"``: over ``"fusion"``, orientation, shape (32)   **37.54**
``"fusion"`` over ``"ri_cd"`` (not ``"mlri"``), ``"rcd"``          37.33
``"fusion_refined"`` over that ``"fusion"``                        37.40
``"fusion"`` as above, bounded                                     37.30
``"fusion_refined"`` over that ``"fusion"``, bounded               37.38
``"fusion"``, saturated classes (shipped)                          37.33
``"fusion_refined"`` over that ``"fusion"`` (shipped)              37.41
=================================================================  =========

The fusion's classes are split in two by the base's saturation (:func:`saturation`:
the absolute means of ``R - G`` and ``B - G`` over the 4x4 window of CFA quads nearest
each pixel, added, at least :data:`SATURATION`). The unsaturated half is fitted on the
photographs alone, the saturated half on those and on ``"saturated-photos"`` (a fifth
of them with their chroma scaled by 1.5-3; :func:`only_saturated` keeps those images' other pixels
out). On the held-out photographs with their BT.601 chroma doubled and tripled, where
the cascade trailed ``"mlri"`` by 0.6 dB at triple chroma, it gains 0.19 and 0.47 dB
(33.93 and 31.82; ``"mlri"`` 33.76 and 31.95); 0.05 / 0.08 dB more on CBSD68 and
Urban24, 0.05 less on the seven, and 6 % less false colour on the zone plate (5665).
Chosen on a NumPy model of the fusion alone: a threshold of 0.45 gave less at triple
chroma (+0.43 dB against +0.59), the 3x3 mean of ``|R - G| + |B - G|`` as the measure
11 % more false colour for the same gain (aliased colour alternates in sign and
averages out of signed means), and fitting every class on the colour-boosted
photographs cost 0.13-0.42 dB on CBSD68.

``"raisr_cd"`` (``"best"``) has its 32 classes split the same way (64, trained the
same way: ``SATURATED`` and ``BOUNDED`` hold it) and is bounded as the fusion is
(below). It gains 0.22 and 0.52 dB at doubled and tripled chroma (33.72 and 31.74;
``"mlri"`` 33.76 and 31.95), 0.02-0.08 dB on the seven, CBSD68 and Urban24, and leaves
less false colour on the zone plate (5040 against 5309), for about 6 % of its speed.
Its first measure, each pixel's 5x5 tent of signed differences, scored the same but
its sums made ``"raisr_cd"`` 9 % slower, below 4x LibRaw's AHD in a benchmark run
(3.81x); the quads' sums are taken once per quad and corner, so the measure costs
about a third as much (2 % of the time of ``"raisr_cd"`` against 6 %), and the
fusion's scores moved by at most 0.01 dB with it (5690 of false colour against 5743).
In its NumPy model, unbounded, the split scored 0.04 and 0.11 dB more at doubled and
tripled chroma but left 5 % more false colour (5412 against 5333 with the quads); a
threshold of 0.2 cost 0.13 dB on CBSD68, one of 0.45 gained 0.14 and 0.11 dB less at
doubled and tripled chroma (both with the tent).

The fusion is over ``"ri_cd"`` (the last four rows) rather than ``"mlri"``: unbounded
(below), the cascade runs 1.23 times as fast (58 MP/s at 24 MP on two cores, where 50
are asked for) and leaves 0.61 times the false colour on the grey zone plate, for 0.14
dB less held out and 0.02-0.08 dB less on each validation subset. A full hash (288
classes) for the second stage instead of orientation and shape scored the same
(within 0.02 dB on each subset) with 5 % more false colour.

Both stages of the cascade are bounded: the fusion's features see ``"rcd"``'s
differences from ``"ri_cd"`` clamped to :data:`SECOND_LIMIT` (32/255 of the full
scale), and the kernels of both stages move no missing colour's difference from
green more than :data:`CHROMA_LIMIT` (8/255) away from their base's
(:func:`bound_chroma`). On the grey zone plate, where the mosaic aliases, unbounded
they passed RCD's aliased colours on: bounded, ``"fusion_refined"`` leaves 6015 of
false colour instead of 8027 (``"rcd_menon"`` 6091, ``"ri_cd"`` 5884), for 0.02 dB
held out and 0.01-0.02 dB on each validation subset. On ``"fusion"`` alone (a NumPy
model of its kernel), bounding only its features (16/255) cut its false colour by 16
% for 0.02 dB held out, only its output (8/255) by 22 % for 0.02 dB, and both by 26
% for 0.02 dB; neither alone brings the fusion below 6100, and the cascade adds about
180.

Menon's half of the ``"rcd_menon"`` mean added nothing the filters used: with ``"rcd"``
alone as the second base they score as well (0.05 dB better held out, within 0.03 dB
on each validation subset) and the fusion runs a quarter faster.

The synthetic images (saturated colour fields, coloured text, woven cloth; weakly
correlated channels) made the filters worse on photographs than none, as procedural
textures (dead leaves, coloured zone plates, sinusoidal "fabrics") did before: their
near-Nyquist aliasing dominates the squared error.

Run ``python -m imgform_rs.training.demosaic [--method METHOD] [--out PATH] [--data DIR]
[--small]`` (``METHOD``: raisr, raisr_fast, raisr_cd, fusion or fusion_refined; ``--small``: two
scikit-image images coloured by a smooth random field, no download; for the tests).
"""

from __future__ import annotations

import argparse
import struct
from collections.abc import Callable
from pathlib import Path

import numpy as np

import imgform_rs as ig
from imgform_rs.training.lstsq import NormalEquations
from imgform_rs.training.photos import DEFAULT_DATA

#: How a method classes the samples of an image: ``classify(base, position)``.
Classify = Callable[[np.ndarray, np.ndarray], np.ndarray]
#: Images and how to class their samples, for :func:`solve`.
Batch = tuple[list[np.ndarray], Classify]

SEED = 20170101
FEATURES = 26
#: Features of a second base: its difference from the first, 3 colours x 3x3.
SECOND_FEATURES = 27
#: How far the second base may differ from the first in its features, per colour
#: (``SECOND_LIMIT`` in fusion.rs): beyond it, on aliased grey detail, its colours
#: were false colour that the filters passed on.
SECOND_LIMIT = np.float32(32 / 255)
#: How far the kernels of :data:`BOUNDED` let their filters move a missing colour's
#: difference from green away from their base's (``CHROMA_LIMIT`` in raisr.rs,
#: :func:`bound_chroma`): applied to the output, so not part of the least squares.
CHROMA_LIMIT = np.float32(8 / 255)
#: The methods whose kernels bound their filters' output so.
BOUNDED = {"fusion", "fusion_refined", "raisr_cd"}
#: The bases of each learned method: the one refined, then the one compared.
BASES = {
    "raisr": ("mlri",),
    "raisr_fast": ("mlri",),
    "raisr_cd": ("ri_cd",),
    "fusion": ("ri_cd", "rcd"),
    "fusion_refined": ("fusion",),
}
#: The methods whose filters are chosen by CFA position, orientation and shape alone.
ORIENTED = {"raisr_fast", "raisr_cd", "fusion_refined"}
#: The training set of all (:func:`imgform_rs.training.sets.training_images`); the
#: saturated classes see ``"saturated-photos"`` too.
TRAINING_SET = "photos"
#: The methods whose classes are split by the base's saturation
#: (:func:`with_saturation`) at :data:`SATURATION`.
SATURATED = {"fusion", "raisr_cd"}
SATURATION = np.float32(0.3)
ANGLES, STRENGTHS, COHERENCES = 8, 3, 3
#: Orientation bins of the oriented methods: quadrants of the doubled angle.
ORIENTATIONS = 4
#: Shape bins of the oriented methods: isotropic or not (:func:`coherent`).
SHAPES = 2
#: The bound of :func:`coherent`: ``((1 - r) / (1 + r))^2`` with ``r = 0.7 / 1.3``, the
#: ratio of the square roots of the eigenvalues where RAISR's coherence is 0.3, the
#: full hash's first coherence bound. On the held-out photographs, coherence 0.45
#: (0.56 here) scored 0.01 dB more and 0.2 or 0.6 less; 0.45 left 9 % more false
#: colour on the grey zone plate.
ANISOTROPY = np.float32(0.303)
POSITIONS = 4
CLASSES = POSITIONS * ANGLES * STRENGTHS * COHERENCES
#: Classes of the oriented methods (per saturation bin).
ORIENTED_CLASSES = POSITIONS * ORIENTATIONS * SHAPES
STRENGTH_QUANTILES = (0.5, 0.85)
COHERENCE_THRESHOLDS = (0.3, 0.6)
#: Pixels at the border left out of training (the kernel's reach is 12).
BORDER = 12
#: Classes seen fewer times than this keep a zero filter (no correction).
MIN_SAMPLES = 500
RIDGE = 1e-3
#: The scikit-image images of ``--small`` (CC0), grey, coloured at random.
SMALL = ["brick", "grass"]
# The quality table of ``benchmarks/demosaic.py`` reads this list, so what is
# evaluated and what is held out of training cannot drift apart.
EVALUATION_IMAGES = [
    "astronaut",
    "coffee",
    "chelsea",
    "rocket",
    "immunohistochemistry",
    "retina",
    "motorcycle_left",
]
# motorcycle_right is the other view of motorcycle_left's scene.
HELD_OUT = {*EVALUATION_IMAGES, "motorcycle_right"}
KERNELS = Path(__file__).resolve().parents[3] / "rust/imgform-core/src/demosaic"


def smooth_field(rng: np.random.Generator, shape: tuple[int, int], sigma: float) -> np.ndarray:
    """Gaussian-smoothed noise rescaled to [0, 1]."""
    from scipy import ndimage

    f = ndimage.gaussian_filter(rng.random(shape), sigma)
    return (f - f.min()) / max(f.max() - f.min(), 1e-12)


def colourise(grey: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A grey image times a smooth random colour field (gains in [0.45, 1])."""
    gains = [0.45 + 0.55 * smooth_field(rng, grey.shape, 40.0) for _ in range(3)]
    return grey[..., None] * np.stack(gains, -1)


def small_images() -> list[np.ndarray]:
    """The quick set of ``--small``: :data:`SMALL` coloured from the fixed seed, each
    also turned by 90 degrees; no download."""
    import skimage.data

    rng = np.random.default_rng(SEED)
    images = [colourise(getattr(skimage.data, name)() / 255.0, rng) for name in SMALL]
    return [im for rgb in images for im in (rgb, np.rot90(rgb))]


def quantise(rgb: np.ndarray) -> np.ndarray:
    """8-bit values as float32 in [0, 1], as the benchmark's images are."""
    return (np.round(np.clip(rgb, 0, 1) * 255) / 255).astype(np.float32)


def box3(p: np.ndarray) -> np.ndarray:
    """3x3 sums in the kernel's order (each row left to right, then the rows)."""
    rows = (p[:, :-2] + p[:, 1:-1]) + p[:, 2:]
    return (rows[:-2] + rows[1:-1]) + rows[2:]


def eigen(sxx: np.ndarray, sxy: np.ndarray, syy: np.ndarray):
    """Largest eigenvalue and coherence, as ``eigen`` in raisr.rs."""
    half = np.float32(0.5)
    half_trace = half * (sxx + syy)
    half_diff = half * (sxx - syy)
    d = np.sqrt(half_diff * half_diff + sxy * sxy)
    l1 = half_trace + d
    l2 = np.maximum(half_trace - d, np.float32(0))
    r1, r2 = np.sqrt(l1), np.sqrt(l2)
    total = r1 + r2
    with np.errstate(invalid="ignore", divide="ignore"):
        coherence = np.where(total > 0, (r1 - r2) / total, np.float32(0))
    return l1, coherence.astype(np.float32)


def angle_bin(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Octant of the doubled orientation, as ``angle_bin`` in raisr.rs."""
    cos, sin = np.float32(0.9238795), np.float32(0.38268343)
    u, v = a * cos - b * sin, a * sin + b * cos
    top, right = v >= 0, u >= 0
    return np.select(
        [top & right, top & ~right, ~top & ~right],
        [(v > u) * 1, 2 + (v < -u), 4 + (-v > -u)],
        6 + (-v < u),
    )


def orientation(a: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Quadrant of the doubled orientation ``atan2(c, a)`` centred on 0, 90, 180
    and 270 degrees (horizontal, diagonal, vertical, anti-diagonal gradients), as
    ``orientation`` in oriented.rs; a flat tensor falls in the first."""
    size = np.abs(c)
    return np.select([a >= size, -a >= size, c > 0], [0, 2, 1], 3)


def tensor(green: np.ndarray):
    """Structure-tensor sums over 3x3 of the green's central differences,
    for the pixels 2 away from the border."""
    k = np.float32(0.5)
    gx = (green[1:-1, 2:] - green[1:-1, :-2]) * k
    gy = (green[2:, 1:-1] - green[:-2, 1:-1]) * k
    return box3(gx * gx), box3(gx * gy), box3(gy * gy)


def features(base: np.ndarray, blue_rows: np.ndarray) -> np.ndarray:
    """The 26 features of every pixel 1 away from the border, (H-2, W-2, 26)."""
    red_frame = base
    blue_frame = base[..., ::-1]
    h, w = base.shape[:2]
    out = []
    for frame in (red_frame, blue_frame):
        centre = frame[1:-1, 1:-1]
        f = [
            frame[1 + dy : h - 1 + dy, 1 + dx : w - 1 + dx] - centre
            for dy in (-1, 0, 1)
            for dx in (-1, 0, 1)
            if (dy, dx) != (0, 0)
        ]
        f = np.concatenate(f, -1)
        own, green, other = centre[..., 0], centre[..., 1], centre[..., 2]
        out.append(np.concatenate([f, (own - green)[..., None], (other - green)[..., None]], -1))
    return np.where(blue_rows[1:-1, None, None], out[1], out[0])


def second_features(base: np.ndarray, second: np.ndarray, blue_rows: np.ndarray) -> np.ndarray:
    """The second base minus the first, clamped to :data:`SECOND_LIMIT`, at each
    pixel of the 3x3 window, colours in the centre row's frame: (H-2, W-2, 27) for
    the pixels 1 away from the border."""
    h, w = base.shape[:2]
    out = []
    steps = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1)]
    clamped = np.clip(second - base, -SECOND_LIMIT, SECOND_LIMIT)
    for diff in (clamped, clamped[..., ::-1]):
        f = [diff[1 + dy : h - 1 + dy, 1 + dx : w - 1 + dx] for dy, dx in steps]
        out.append(np.concatenate(f, -1))
    return np.where(blue_rows[1:-1, None, None], out[1], out[0])


def prepare(rgb: np.ndarray, bases: tuple[str, ...]):
    """The 8-bit truth, its RGGB mosaic demosaicked by each base (the first's
    output, then the others' differences from it), and the CFA positions
    (``2 * blue_row + chroma_site``) of every pixel."""
    truth = quantise(rgb)
    h, w = truth.shape[:2]
    masks = ig.channel_masks((h, w), "RGGB")
    mosaic = np.ascontiguousarray((truth * masks).sum(-1), dtype=np.float32)
    outputs = [ig.demosaic(mosaic, "RGGB", m) for m in bases]
    yy, xx = np.mgrid[:h, :w]
    blue = yy % 2 == 1
    chroma = (xx % 2 == 0) ^ blue
    return truth, outputs, 2 * blue + chroma


def bound_chroma(corrections: np.ndarray, chroma: np.ndarray) -> np.ndarray:
    """The corrections (N, 2) of a :data:`BOUNDED` method's filters, the missing
    colours in the kernel's order (green then the other chroma at a chroma site, the
    own then the other chroma at a green site), bounded as its kernel bounds them:
    each missing chroma's difference from green moved by at most
    :data:`CHROMA_LIMIT`. ``chroma``: whether each pixel is a chroma site."""
    first, second = corrections[:, 0], corrections[:, 1]
    lo, hi = -CHROMA_LIMIT, CHROMA_LIMIT
    second = np.where(chroma, first + np.clip(second - first, lo, hi), np.clip(second, lo, hi))
    first = np.where(chroma, first, np.clip(first, lo, hi))
    return np.stack([first, second], -1)


def interior(a: np.ndarray, reach: int) -> np.ndarray:
    """The pixels ``BORDER`` away from the border of an array that starts
    ``reach`` pixels into the image, flattened."""
    h, w = a.shape[:2]
    b = BORDER - reach
    return a[b : h - b, b : w - b].reshape(-1, *a.shape[2:])


def hash_inputs(base: np.ndarray, position: np.ndarray):
    """Structure-tensor sums and positions of the interior pixels."""
    return [interior(s, 2) for s in tensor(base[..., 1])], interior(position, 0)


def samples(truth: np.ndarray, bases: list[np.ndarray], position: np.ndarray):
    """Features and targets (residuals of the first base's two missing colours in
    the centre row's frame) of the interior pixels."""
    blue = position >= 2
    base = bases[0]
    feats = [features(base, blue[:, 0])]
    feats += [second_features(base, other, blue[:, 0]) for other in bases[1:]]
    feats = interior(np.concatenate(feats, -1), 1)
    residual = truth - base
    frame = np.where(blue[..., None], residual[..., ::-1], residual)
    chroma = (position % 2 == 1)[..., None]
    target = np.where(chroma, frame[..., 1:], frame[..., [0, 2]])
    return feats, interior(target, 0)


def classes(sums, position, strength: np.ndarray) -> np.ndarray:
    """Class index of each sample, as ``Weights::class`` in raisr.rs."""
    sxx, sxy, syy = sums
    l1, coherence = eigen(sxx, sxy, syy)
    s = (l1[:, None] >= strength).sum(1)
    c = (coherence[:, None] >= np.float32(COHERENCE_THRESHOLDS)).sum(1)
    a = angle_bin(sxx - syy, np.float32(2) * sxy)
    return ((position * ANGLES + a) * STRENGTHS + s) * COHERENCES + c


def saturation(base: np.ndarray) -> np.ndarray:
    """How colourful the base (RGGB) is around each interior pixel, as ``Saturation``
    in saturation.rs computes it: the absolute values of the means of ``R - G`` and
    ``B - G`` over the four CFA quads (2x2 cells, red at the top left) that meet at the
    quads' corner nearest the pixel (a 4x4 window), added."""
    h, w = base.shape[:2]
    rows, cols = h // 2, w // 2
    total = np.zeros((rows, cols), np.float32)
    for chroma in (base[..., 0], base[..., 2]):
        d = (chroma - base[..., 1])[: 2 * rows, : 2 * cols]
        columns = d[0::2] + d[1::2]
        quads = columns[:, 0::2] + columns[:, 1::2]
        across = quads[:, :-1] + quads[:, 1:]
        # Corner [q, p], at the top left of quad (q, p), from quads q - 1 .. q and
        # p - 1 .. p.
        total[1:, 1:] += np.abs(across[:-1] + across[1:])
    # Rows 2q - 1 and 2q, columns 2p - 1 and 2p take corner [q, p].
    means = np.zeros((h, w), np.float32)
    means[: 2 * rows - 1, : 2 * cols - 1] = total.repeat(2, 0).repeat(2, 1)[1:, 1:]
    return interior(means / np.float32(16), 0)


def with_saturation(classify: Classify, nclasses: int) -> Classify:
    """``classify`` (``nclasses`` classes) with its classes moved by ``nclasses``
    where the base is saturated (:func:`saturation` at least :data:`SATURATION`), as
    the kernels of :data:`SATURATED` do."""

    def saturated(base: np.ndarray, position: np.ndarray) -> np.ndarray:
        return classify(base, position) + nclasses * (saturation(base) >= SATURATION)

    return saturated


def only_saturated(classify: Classify, nclasses: int) -> Classify:
    """``classify`` (of :func:`with_saturation`) with its unsaturated samples left
    out (given a class past the last, which :func:`solve` skips)."""

    def saturated(base: np.ndarray, position: np.ndarray) -> np.ndarray:
        cls = classify(base, position)
        return np.where(cls >= nclasses, cls, 2 * nclasses)

    return saturated


def coherent(a: np.ndarray, c: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Whether the tensor is anisotropic, as ``coherent`` in oriented.rs:
    ``(l1 - l2)^2 > k (l1 + l2)^2`` for its eigenvalues, from ``a = sxx - syy``,
    ``c = 2 sxy`` and the trace ``t``."""
    return (a * a + c * c) > ANISOTROPY * (t * t)


def oriented_classes(base: np.ndarray, position: np.ndarray) -> np.ndarray:
    """Class index of each sample of an oriented method, as ``Oriented`` in
    oriented.rs: CFA position, then orientation, then shape."""
    (sxx, sxy, syy), position = hash_inputs(base, position)
    a, c = sxx - syy, np.float32(2) * sxy
    shape = coherent(a, c, sxx + syy)
    return (position * ORIENTATIONS + orientation(a, c)) * SHAPES + shape


def strength_thresholds(images, bases: tuple[str, ...]) -> np.ndarray:
    """The strength bin bounds: quantiles of the largest eigenvalue, as float32."""
    l1 = []
    for rgb in images:
        _, outputs, position = prepare(rgb, bases)
        l1.append(eigen(*hash_inputs(outputs[0], position)[0])[0])
    return np.quantile(np.concatenate(l1).astype(np.float64), STRENGTH_QUANTILES).astype(np.float32)


def solve(batches: list[Batch], bases: tuple[str, ...], nclasses: int) -> np.ndarray:
    """Least-squares filters per class, (nclasses, 2, features) float32, from
    batches of images and how to class their samples: ``classify(base, position)``,
    ``base`` the first base's output; samples of a class past the last are left
    out. The images are demosaicked again here rather than kept from
    :func:`strength_thresholds`: several hundred images' bases would not fit in
    memory."""
    nf = FEATURES + SECOND_FEATURES * (len(bases) - 1)
    equations = NormalEquations(nclasses, nf, 2)
    for rgb, classify in ((rgb, classify) for images, classify in batches for rgb in images):
        truth, bases_out, position = prepare(rgb, bases)
        cls = classify(bases_out[0], position)
        feats, target = samples(truth, bases_out, position)
        # Sorted once, so each class's samples are one contiguous block.
        order = np.argsort(cls, kind="stable")
        feats, target = feats[order], target[order]
        bounds = np.searchsorted(cls[order], np.arange(nclasses + 1))
        for k in np.flatnonzero(np.diff(bounds)):
            equations.add(k, feats[bounds[k] : bounds[k + 1]], target[bounds[k] : bounds[k + 1]])
    return equations.solve(RIDGE, MIN_SAMPLES)


def encode(bins: tuple[int, int, int, int], thresholds: np.ndarray, filters: np.ndarray) -> bytes:
    """The weights file (layout documented at ``Weights::parse`` in raisr.rs):
    angle, strength, coherence and saturation bin counts, thresholds, filters."""
    nf = filters.shape[2]
    header = b"IGRAISR2" + struct.pack("<5I", *bins, nf)
    return header + thresholds.astype("<f4").tobytes() + filters.astype("<f4").tobytes()


def views(small: bool, data: Path, name: str = TRAINING_SET) -> list[np.ndarray]:
    """The training images: the set ``name``'s (:func:`imgform_rs.training.sets.
    training_images`; the photographs already flipped and turned at random by its
    augmentation), or the quick ``small`` set (for ``"saturated-photos"``, those
    with their chroma doubled)."""
    if small:
        images = small_images()
        if name == "saturated-photos":
            from imgform_rs.training.sets import saturate

            return [saturate(image, 2.0) for image in images]
        return images
    from imgform_rs.training import sets

    return sets.training_images(name, data)


def train(method: str = "raisr", small: bool = False, data: Path = DEFAULT_DATA) -> bytes:
    """The weights file of ``method`` trained from the fixed seed (``small``: a
    quick subset)."""
    images = views(small, data)
    bases = BASES[method]
    if method in ORIENTED:
        classify, nclasses = oriented_classes, ORIENTED_CLASSES
        bins, thresholds = (ORIENTATIONS, 1, SHAPES), [np.float32([ANISOTROPY])]
    else:
        strength = strength_thresholds(images, bases)

        def classify(base, position):
            return classes(*hash_inputs(base, position), strength)

        nclasses = CLASSES
        bins = (ANGLES, STRENGTHS, COHERENCES)
        thresholds = [strength, np.float32(COHERENCE_THRESHOLDS)]
    if method not in SATURATED:
        filters = solve([(images, classify)], bases, nclasses)
        return encode((*bins, 1), np.concatenate(thresholds), filters)
    # The unsaturated classes see the photographs alone; the saturated ones those
    # too, and the photographs made more colourful.
    classify = with_saturation(classify, nclasses)
    saturated = views(small, data, "saturated-photos")
    batches = [(images, classify), (saturated, only_saturated(classify, nclasses))]
    filters = solve(batches, bases, 2 * nclasses)
    thresholds.append(np.float32([SATURATION]))
    return encode((*bins, 2), np.concatenate(thresholds), filters)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--method", choices=sorted(BASES), default="raisr")
    parser.add_argument("--out", type=Path, help="where to write (default: the shipped file)")
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="photographs folder")
    parser.add_argument("--small", action="store_true", help="a quick subset (for tests)")
    args = parser.parse_args()
    out = args.out or KERNELS / f"{args.method}_weights.bin"
    out.write_bytes(train(args.method, args.small, args.data))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()

"""Training of ``"fusion_cnn"``'s network (rebuilds ``fusion_cnn_weights.bin``).

The network corrects ``"fusion_refined"`` as the built extension computes it: six
3x3 convolutions over the mosaic's 2x2 cells (12 values in, 32 channels between, 12
out, ReLU after all but the last, no biases), its output added to the base
(``rust/imgform-core/src/demosaic/cnn.rs`` says why each choice). It trains here,
with PyTorch on the CPU (the ``train`` extra; never a runtime dependency: the kernel
is ours), on the 293 extended photographs (set ``"photos"`` of
:func:`imgform_rs.training.sets.training_images`), each in its eight views (see
:func:`views`), quantised to 8 bits, mosaicked RGGB and demosaicked by
``"fusion_refined"`` in float32, never on the benchmark's images nor the validation
subsets. The views hold ~7 GB in memory.

Training: random 96 x 96 pixel crops (48 x 48 cells; the convolutions are unpadded,
so the loss sees the middle 72 x 72) drawn by each view's area, 16 a step, mean
squared error against the truth at the missing colours (the kernel keeps each
pixel's own sample whatever the network says for it), Adam from a learning rate of
1e-3 decaying to 0 along a cosine over :data:`STEPS` steps; the last layer starts at
zero (the network starts as the identity on its base), the others as He et al.
(2015) give ReLU layers. The network runs in ``torch.autocast`` to bfloat16: on a
CPU with AMX, as here, a step takes 35 instead of 80 ms (60 000 steps, 41 minutes on
one core). Everything is seeded and runs on one thread with PyTorch's deterministic
algorithms, so a run on the same PyTorch and CPU instruction set gives identical
bytes (PyTorch's CPU kernels may sum, and round to bfloat16, in another order on
another instruction set, which would change the last bits).

The file holds the network quantised, as the kernel runs it in exact integers
(``cnn.rs`` says why): the weights as int8, symmetric per output channel on its
largest weight; each hidden layer's activations as 15-bit codes whose top stands
for their largest value on every :data:`CALIBRATION`-th training photograph,
rounded up to a power of two (:func:`calibrate`); each output's factor takes its
integer sum to its next code (:func:`quantised`). That moved CPSNR by at most
0.01 dB: on the validation subsets 40.290 / 40.837 / 36.969 with the ``f32``
network, 40.291 / 40.841 / 36.968 quantised; on the held-out photographs (chroma
x1 / x2 / x3) 38.258 / 34.701 / 32.610 and 38.261 / 34.701 / 32.611. (The kernel
also fades the correction out in cells whose brightest value is below 128 codes, far
below the mosaic's largest sample; in 8-bit mosaics every cell with a sample above 0
takes all of it, so training and these scores never see the fade.)

Choices, by mean CPSNR on the nine held-out photographs (set ``"held-out"``;
``"fusion_refined"`` 37.39 there by this protocol: 8-bit, RGGB, 10 px crop), and
for the last rows the validation subsets (scikit-image seven / CBSD68 / Urban24)
and the grey zone plate's zipper (share of pixels):

========================================================  =========  =====================  ======
network, training                                         held out   validation             zipper
========================================================  =========  =====================  ======
6 x 32, photographs and 192 synthetic images, 28 k steps
6 x 32, photographs, default initialisation, 17 k steps   37.76
6 x 32, photographs, He initialisation, 13.5 k steps      37.79
6 x 32, photographs, He initialisation, 30 k steps (1)    37.81      40.05 / 40.44 / 36.44  39.8 %
6 x 32, as (1) in bfloat16, masked loss (2), 40 k steps   37.73      40.07 / 40.41 / 36.44
6 x 48, as (2), 26 k steps                                37.83      40.11 / 40.44 / 36.49  40.3 %
6 x 32, as (2), eight views, 44 k steps, seed 0 (3)       38.25      40.37 / 40.91 / 37.05  34.4 %
as (3), half the crops drawn by their base's error        38.02      40.25 / 40.61 / 36.87
6 x 48, as (3), 36 k steps                                38.18      40.33 / 40.82 / 36.95  37.2 %
6 x 32, as (2), eight views, 60 k steps: shipped          **38.26**  40.29 / 40.84 / 36.97  35.7 %
as (3), two more views per photograph, chroma x1.5-3 (4)  38.16      40.39 / 40.80 / 36.97
========================================================  =========  =====================  ======

(1) was shipped before the eight views: each photograph came in the one view its
augmentation drew, and Urban24's aliasing buildings, whose lines run along rows and
columns, were rare in it. The views are worth +0.45 dB held out and +0.2-0.5 on the
validation subsets, more than width ever was; the runs (3) were scripts outside the
repository, with a schedule by time. With the 192 synthetic images (saturated colour
fields, text, cloth), whose errors are ten times the photographs', the network gained
nothing over its base on any validation subset (that run was only scored there): they
took its capacity. Crops drawn by their base's error, as demosaicnet mined its hard
patches, cost 0.2 dB: the loss then weighs the photographs' rare worst places over
their common ones. (4) added two views of each photograph with its BT.601 chroma
multiplied by 1.5-3 (a fifth of the crops): +0.18 / +0.42 dB on the held-out
photographs at chroma x2 / x3, but -0.07 at x1, the photographs as they are.

Nor did a larger network, or more bases, pay at equal training (as (2), eight views,
15 000 steps each; scored unquantised, reflect-padded, held out then validation):
6 x 32 gave 38.00, 40.18 / 40.64 / 36.81; 6 x 64 (3.7 times the multiply-adds)
38.06, 40.20 / 40.68 / 36.85; 10 x 32 (1.8 times) 37.86, 40.07 / 40.56 / 36.65; and
6 x 32 that also sees RCD's and Menon's outputs (36 values a quad in; the
per-pixel oracle of MLRI, Menon and RCD reaches 42.3 dB on the seven), 37.87,
40.12 / 40.57 / 36.71. What separates this network from demosaicnet (1.35 / 0.46 / 1.07 dB) is
not its size at this data and training.

Nor much more of the same data (as above, 15 000 steps, 6 x 32): the first 146
photographs gave 37.95, 40.08 / 40.56 / 36.74 against the 293's 38.00, 40.18 / 40.64 /
36.81, so doubling the photographs buys 0.05-0.10 dB; each photograph also at half
its size (a second area-downsampling, the 78 large enough, drawn twice as often by
area) gave 38.00, 40.28 / 40.58 / 36.85. At that rate the 0.65 dB that the seven lack
to come within 0.7 dB of demosaicnet would take some 2^6 times these photographs.

Nor a network that picks among the bases, as the per-pixel oracle above would: one
whose output is a softmax over fusion_refined, MLRI, Menon and RCD per colour (started
near fusion_refined alone) plus a correction, trained as above, gave 37.41, 40.04 /
40.12 / 36.60, no better than fusion_refined itself.
"""

from __future__ import annotations

import argparse
import math
import struct
from pathlib import Path

import numpy as np

from imgform_rs.training.photos import DEFAULT_DATA

#: Where the kernel includes the shipped network from.
KERNELS = Path(__file__).resolve().parents[3] / "rust" / "imgform-core" / "src" / "demosaic"
SEED = 20261206
LAYERS, WIDTH, QUAD = 6, 32, 12
#: Training steps, crops per step and a crop's side in cells.
STEPS, BATCH, CELLS = 60000, 16, 48
LEARNING_RATE = 1e-3
#: Each cell's sampled colours: red at the top left, green at the top right
#: and bottom left, blue at the bottom right (of :func:`quads`'s twelve).
SAMPLED = (0, 4, 7, 11)
#: What a network file starts with (``cnn.rs``'s ``MAGIC``): version 2,
#: the quantised network.
MAGIC = b"IFCNN\x00\x02\x00"
#: The top code of the input and of every activation (15 bits, ``cnn.rs``'s
#: ``TOP``), and of the weights' magnitudes (8 bits).
TOP, WEIGHT_TOP = 32767, 127
#: Every this many training photographs calibrates the activations' steps.
CALIBRATION = 15


def quads(rgb: np.ndarray) -> np.ndarray:
    """(H, W, 3) -> (12, H/2, W/2): each 2x2 cell's red, green, blue at its
    top left, top right, bottom left, bottom right (the kernel's order)."""
    h, w = rgb.shape[0] // 2 * 2, rgb.shape[1] // 2 * 2
    cells = [rgb[i:h:2, j:w:2].transpose(2, 0, 1) for i in (0, 1) for j in (0, 1)]
    return np.ascontiguousarray(np.concatenate(cells, 0))


def views(rgb: np.ndarray):
    """The photograph's eight views: as it is and transposed, each also flipped
    left-right, upside down and both. Each view is mosaicked anew, so each adds
    new samples, and every structure comes in all four orientations on the CFA."""
    for image in (rgb, rgb.transpose(1, 0, 2)):
        for view in (image, image[:, ::-1], image[::-1], image[::-1, ::-1]):
            yield np.ascontiguousarray(view)


def pairs(images: list[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray]]:
    """(base, truth) cells of every view of every image at least two crops
    wide: the 8-bit view mosaicked RGGB and demosaicked by
    ``"fusion_refined"``."""
    import imgform_rs as ig
    from imgform_rs.training.demosaic import quantise

    out = []
    for rgb in images:
        if min(rgb.shape[:2]) < 2 * 2 * CELLS:
            continue
        for view in views(rgb):
            truth = quantise(view)
            base = ig.demosaic(ig.mosaic(truth, "RGGB"), "RGGB", "fusion_refined")
            out.append((quads(base), quads(truth)))
    return out


def network():
    """The untrained network (seed set by the caller)."""
    from torch import nn

    convs = [nn.Conv2d(QUAD if i == 0 else WIDTH, WIDTH, 3, bias=False) for i in range(LAYERS - 1)]
    for conv in convs:
        nn.init.kaiming_normal_(conv.weight, nonlinearity="relu")
    last = nn.Conv2d(WIDTH, QUAD, 3, bias=False)
    nn.init.zeros_(last.weight)
    layers = [m for conv in convs for m in (conv, nn.ReLU())]
    return nn.Sequential(*layers, last)


def crops(data: list[tuple[np.ndarray, np.ndarray]], rng: np.random.Generator):
    """One step's crops of (base, truth), drawn by area."""
    import torch

    area = np.array([b.shape[1] * b.shape[2] for b, _ in data], float)
    picks = rng.choice(len(data), BATCH, p=area / area.sum())
    bases, truths = [], []
    for k in picks:
        base, truth = data[k]
        y = rng.integers(0, base.shape[1] - CELLS + 1)
        x = rng.integers(0, base.shape[2] - CELLS + 1)
        bases.append(base[:, y : y + CELLS, x : x + CELLS])
        truths.append(truth[:, y + LAYERS : y + CELLS - LAYERS, x + LAYERS : x + CELLS - LAYERS])
    return torch.from_numpy(np.stack(bases)), torch.from_numpy(np.stack(truths))


def fit(data: list[tuple[np.ndarray, np.ndarray]], steps: int, log=print):
    """The network trained on ``data`` for ``steps`` steps."""
    import torch

    torch.manual_seed(SEED)
    torch.set_num_threads(1)
    torch.use_deterministic_algorithms(True)
    rng = np.random.default_rng(SEED)
    net = network()
    opt = torch.optim.Adam(net.parameters(), lr=LEARNING_RATE)
    # The loss leaves out each cell's sampled colours: the kernel keeps them.
    interpolated = torch.ones(QUAD, 1, 1)
    interpolated[list(SAMPLED)] = 0
    for step in range(steps):
        for group in opt.param_groups:
            group["lr"] = LEARNING_RATE * 0.5 * (1 + math.cos(math.pi * step / steps))
        base, truth = crops(data, rng)
        with torch.autocast("cpu", dtype=torch.bfloat16):
            correction = net(base)
        error = base[..., LAYERS:-LAYERS, LAYERS:-LAYERS] + correction.float() - truth
        loss = (error**2 * interpolated).sum() / (interpolated.sum() * truth[:, 0].numel())
        opt.zero_grad()
        loss.backward()
        opt.step()
        if (step + 1) % 1000 == 0:
            log(f"step {step + 1}: {10 * math.log10(1 / loss.item()):.2f} dB on its crops")
    return net


def calibrate(net, images: list[np.ndarray]) -> list[float]:
    """Each hidden layer's step (what one code stands for): its largest
    activation over every :data:`CALIBRATION`-th image's base, clamped and
    divided by its mosaic's largest sample as the kernel's input codes are, at
    the top code, rounded up to a power of two so that the last bits of another
    CPU's sums cannot move it. The largest, not a high percentile: at the
    99.99th the grey charts' activations, 4 to 10 times it, were clipped, with
    40 % more false colour on the zone plate than the ``f32`` network and twice
    as much on the Siemens star."""
    import torch

    import imgform_rs as ig
    from imgform_rs.training.demosaic import quantise

    tops = [0.0] * (LAYERS - 1)
    for rgb in images[::CALIBRATION]:
        raw = ig.mosaic(quantise(rgb), "RGGB")
        base = ig.demosaic(raw, "RGGB", "fusion_refined")
        x = torch.from_numpy(quads(np.clip(base, raw.min(), raw.max()) / raw.max()))[None]
        with torch.no_grad():
            for k, layer in enumerate(net):
                x = layer(x)
                if k % 2 == 1:  # after each ReLU
                    tops[k // 2] = max(tops[k // 2], float(x.max()))
    return [2.0 ** math.ceil(math.log2(top / TOP)) for top in tops]


def quantised(net, steps: list[float]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each layer's weights as int8 ``(out, in, 3, 3)``, symmetric per output
    channel, and each output's factor: from its integer sum to its code (the
    input's step is ``1 / TOP``, the hidden layers' ``steps``) or, for the last
    layer, to the correction as a fraction of the mosaic's largest sample."""
    weights = [m.weight.detach().numpy().astype(np.float64) for m in net if hasattr(m, "weight")]
    out, step = [], 1.0 / TOP
    for k, w in enumerate(weights):
        scale = np.abs(w).reshape(len(w), -1).max(1) / WEIGHT_TOP
        scale[scale == 0] = 1.0  # an output of zeros: any scale
        q = np.clip(np.round(w / scale[:, None, None, None]), -WEIGHT_TOP, WEIGHT_TOP)
        factor = step * scale
        if k < len(steps):
            factor, step = factor / steps[k], steps[k]
        out.append((q.astype(np.int8), factor.astype(np.float32)))
    return out


def encode(net, steps: list[float]) -> bytes:
    """The network file of ``net`` quantised with ``steps`` (see
    :func:`quantised`): :data:`MAGIC`, the layer count, then per layer its input
    and output channels, its outputs' factors (float32) and its weights (int8,
    ``[tap][input][output]``, taps row by row), all little-endian."""
    layers = quantised(net, steps)
    out = [MAGIC, struct.pack("<I", len(layers))]
    for w, factor in layers:  # (out, in, 3, 3)
        out.append(struct.pack("<II", w.shape[1], w.shape[0]))
        out.append(factor.astype("<f4").tobytes())
        out.append(np.ascontiguousarray(w.transpose(2, 3, 1, 0)).tobytes())
    return b"".join(out)


def train(steps: int = STEPS, small: bool = False, data: Path = DEFAULT_DATA) -> bytes:
    """The network file trained from the fixed seed (``small``: a quick
    subset, for tests)."""
    if small:
        from imgform_rs.training.demosaic import small_images

        images = small_images()
    else:
        from imgform_rs.training import sets

        images = sets.training_images("photos", data)
    net = fit(pairs(images), steps)
    return encode(net, calibrate(net, images))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, help="where to write (default: the shipped file)")
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="photographs folder")
    parser.add_argument("--steps", type=int, default=STEPS, help="training steps")
    parser.add_argument("--small", action="store_true", help="a quick subset (for tests)")
    args = parser.parse_args()
    out = args.out or KERNELS / "fusion_cnn_weights.bin"
    out.write_bytes(train(args.steps, args.small, args.data))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()

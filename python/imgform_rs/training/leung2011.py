"""Least-squares design of the ``"leung2011"`` demosaicer's chroma filters.

``python -m imgform_rs.training.leung2011`` rebuilds
``rust/imgform-core/src/demosaic/leung2011_filters.rs`` bit for bit (``--check``
compares instead of writing). Following Leung, Jeon and Dubois (IEEE TIP 2011),
each chroma filter minimises the squared error between the chroma it extracts from
the mosaic and the true chroma of training images; ours are separable
(``[1 2 1] * q`` along each axis, ``q`` symmetric with 11 taps), fitted by
alternating least squares: with the vertical taps fixed the horizontal ones are a
linear least-squares problem, and the other way round.

Training images, all openly licensed and shipped in scikit-image's wheel:

- grey textures and photographs, coloured by a smooth random colour field (so the
  chroma is smoother than the luma, as in natural images): ``brick``, ``grass``,
  ``gravel`` (CC0 Textures / DeviantArt, CC0), ``camera`` (CC0, Lav Varshney),
  ``coins`` (Brooklyn Museum, no known restrictions), ``text`` (Wikipedia, public
  domain), ``clock`` (public domain, Stefan van der Walt), ``microaneurysms``
  (CC0, Andreas Maier);
- ``hubble_deep_field`` (NASA, public domain), in colour;
- dead-leaves images (random discs with a power-law size distribution), generated.

Every image also enters transposed, since the (0, π) filter is the (π, 0) one
transposed. The seven colour images of the quality benchmark (astronaut, coffee,
chelsea, rocket, immunohistochemistry, retina, motorcycle_left) are held out, and
so is ``motorcycle_right``, the other view of the same scene.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np

GREY = ["brick", "grass", "gravel", "camera", "coins", "text", "clock", "microaneurysms"]
HALF = 5
OUT = Path(__file__).resolve().parents[3] / "rust/imgform-core/src/demosaic/leung2011_filters.rs"


def dead_leaves(rng: np.random.Generator, n: int) -> np.ndarray:
    """An (n, n, 3) float image of opaque discs, radii 2 to 60 px with density
    ~ 1/r^3 (scale invariant, like natural images), slightly blurred by optics."""
    from scipy.ndimage import gaussian_filter

    img = np.zeros((n, n, 3))
    filled = np.zeros((n, n), bool)
    lo = (2 / 60) ** 2
    while not filled.all():
        r = 2 / np.sqrt(rng.random() * (1 - lo) + lo)
        cy, cx = rng.random(2) * n
        y0, y1 = max(int(cy - r), 0), min(int(cy + r) + 1, n)
        x0, x1 = max(int(cx - r), 0), min(int(cx + r) + 1, n)
        yy, xx = np.mgrid[y0:y1, x0:x1]
        disc = ((yy - cy) ** 2 + (xx - cx) ** 2 < r * r) & ~filled[y0:y1, x0:x1]
        grey = rng.random() * 200 + 30
        img[y0:y1, x0:x1][disc] = grey * (1 + 0.3 * rng.standard_normal(3))
        filled[y0:y1, x0:x1] |= disc
    return np.clip(gaussian_filter(img, (0.6, 0.6, 0)), 0, 255)


def training_images(
    seed: int = 0, leaves: int = 6, size: int = 384, grey: tuple[str, ...] = GREY
) -> list[np.ndarray]:
    """The training set (float64 RGB in 0..255), deterministic for a seed."""
    from scipy.ndimage import gaussian_filter
    from skimage import data

    rng = np.random.default_rng(seed)
    images = []
    for name in grey:
        grey = getattr(data, name)().astype(np.float64)
        if grey.ndim == 3:
            grey = grey[..., :3].mean(axis=2)
        field = np.stack(
            [gaussian_filter(rng.standard_normal(grey.shape), 20) for _ in range(3)], axis=-1
        )
        field /= field.std()
        images.append(np.clip(grey[..., None] * (1 + 0.25 * field), 0, 255))
    images.append(data.hubble_deep_field()[..., :3].astype(np.float64))
    images += [dead_leaves(rng, size) for _ in range(leaves)]
    return images + [np.ascontiguousarray(im.transpose(1, 0, 2)) for im in images]


def _mosaic(rgb: np.ndarray) -> np.ndarray:
    """RGGB mosaic of an RGB image."""
    out = rgb[..., 1].copy()
    out[0::2, 0::2] = rgb[0::2, 0::2, 0]
    out[1::2, 1::2] = rgb[1::2, 1::2, 2]
    return out


def _pre(img: np.ndarray, axis: int) -> np.ndarray:
    """``[1 2 1]`` along ``axis`` (mirrored borders; the crop hides them)."""
    from scipy.ndimage import correlate1d

    return correlate1d(img, [1.0, 2.0, 1.0], axis=axis, mode="mirror")


def _symmetric(img: np.ndarray, q: np.ndarray, axis: int) -> np.ndarray:
    """The symmetric taps ``q`` (centre first) along ``axis``."""
    from scipy.ndimage import correlate1d

    return correlate1d(img, np.r_[q[:0:-1], q], axis=axis, mode="mirror")


def _features(img: np.ndarray, axis: int, crop: int) -> np.ndarray:
    """Columns ``img`` and ``img[-k] + img[+k]`` along ``axis`` (k = 1..HALF), cropped."""
    cols = [img]
    for k in range(1, HALF + 1):
        cols.append(np.roll(img, k, axis) + np.roll(img, -k, axis))
    return np.stack([c[crop:-crop, crop:-crop].ravel() for c in cols], axis=1)


def _fit(pairs, fixed: np.ndarray, fixed_axis: int, crop: int = 8) -> np.ndarray:
    """Least-squares taps along the other axis, with ``fixed`` along ``fixed_axis``."""
    free = 1 - fixed_axis
    gram = np.zeros((HALF + 1, HALF + 1))
    rhs = np.zeros(HALF + 1)
    for modulated, target in pairs:
        t = _pre(_symmetric(_pre(modulated, fixed_axis), fixed, fixed_axis), free)
        x = _features(t, free, crop)
        gram += x.T @ x
        rhs += x.T @ target[crop:-crop, crop:-crop].ravel()
    return np.linalg.solve(gram, rhs)


def design_filter(images, carrier: str, target: str, sweeps: int = 6):
    """Vertical and horizontal taps extracting ``target`` ("C1" or "C2") from the
    mosaic modulated by ``carrier`` ("xy" or "x")."""
    pairs = []
    for rgb in images:
        f = _mosaic(rgb)
        y, x = np.indices(f.shape)
        sign = (-1.0) ** (x + y) if carrier == "xy" else (-1.0) ** x
        r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
        pairs.append((f * sign, (r - 2 * g + b) / 4 if target == "C1" else (r - b) / 4))
    vertical = np.r_[1.0, np.zeros(HALF)]
    for _ in range(sweeps):
        horizontal = _fit(pairs, vertical, fixed_axis=0)
        vertical = _fit(pairs, horizontal, fixed_axis=1)
    # Only the product is determined: give both factors the same DC gain.
    gain_v, gain_h = (4 * (q[0] + 2 * q[1:].sum()) for q in (vertical, horizontal))
    common = np.sqrt(gain_v * gain_h)
    return vertical * common / gain_v, horizontal * common / gain_h


def design(
    seed: int = 0, leaves: int = 6, size: int = 384, grey: tuple[str, ...] = GREY
) -> dict[str, np.ndarray]:
    """The four tap vectors, rounded to 7 significant digits (so that the last
    bits of BLAS sums never change the shipped file)."""
    images = training_images(seed, leaves, size, grey)
    c1 = design_filter(images, "xy", "C1")
    c2 = design_filter(images, "x", "C2")
    taps = {"C1_V": c1[0], "C1_H": c1[1], "C2_V": c2[0], "C2_H": c2[1]}
    return {k: np.array([float(f"{v:.7g}") for v in q]) for k, q in taps.items()}


def render(taps: dict[str, np.ndarray]) -> str:
    """The Rust source of the filters."""
    lines = [
        "// Generated by `python -m imgform_rs.training.leung2011`: do not edit.",
        "// Unique taps (centre first) of the symmetric 11-tap factors `q` of the",
        "// separable chroma filters `([1 2 1] * q_v) x ([1 2 1] * q_h)`.",
    ]
    for name, q in taps.items():
        # The shortest decimal that reads back as the same float32.
        values = ", ".join(np.format_float_scientific(np.float32(v), unique=True) for v in q)
        lines.append(f"pub(super) const {name}: super::Taps = [{values}];")
    return "\n".join(lines) + "\n"


def shipped(path: Path = OUT) -> dict[str, np.ndarray]:
    """The taps in the shipped Rust file."""
    found = re.findall(r"const (\w+): super::Taps = \[([^\]]*)\];", path.read_text())
    return {name: np.array([float(v) for v in values.split(",")]) for name, values in found}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT, help="the Rust file to write")
    parser.add_argument("--check", action="store_true", help="compare instead of writing")
    args = parser.parse_args(argv)
    text = render(design())
    if args.check:
        same = args.out.read_text() == text
        print(f"{args.out}: {'identical' if same else 'DIFFERENT'}")
        return 0 if same else 1
    args.out.write_text(text)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

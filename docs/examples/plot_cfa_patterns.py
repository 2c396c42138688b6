"""
Colour filter arrays: Bayer and X-Trans
=======================================

Each photosite sees one colour. A Bayer sensor repeats a 2x2 tile (half the
sites green, a quarter each red and blue); Fujifilm's X-Trans repeats a 6x6
tile in which every row and column holds all three colours, which makes
aliasing less regular. :func:`~imgform_rs.channel_masks` says which site saw
which colour, :func:`~imgform_rs.mosaic` samples an RGB picture through a
pattern, and :func:`~imgform_rs.demosaic` reconstructs it: here with
``"bilinear"`` and with each pattern's ``"best"`` method.
"""

import matplotlib.pyplot as plt
import numpy as np
from skimage import data

import imgform_rs as ig

# %%
# The tiles, drawn in the colour each site records.
fig, axes = plt.subplots(1, 3, figsize=(10, 3.4), layout="constrained")
for ax, pattern in zip(axes, ["RGGB", "GBRG", "XTRANS"], strict=True):
    masks = ig.channel_masks((12, 12), pattern)  # (12, 12, 3) booleans
    ax.imshow(masks.astype(float), interpolation="nearest")
    ax.set_title(f'"{pattern}"')
    ax.set_xticks(np.arange(-0.5, 12, 1), minor=True)
    ax.set_yticks(np.arange(-0.5, 12, 1), minor=True)
    ax.grid(which="minor", color="white", lw=0.5)
    ax.tick_params(which="both", length=0, labelbottom=False, labelleft=False)
axes[1].set_xlabel("RGGB cropped by one row: shift_pattern('RGGB', 1, 0) == 'GBRG'")
print(ig.shift_pattern("RGGB", 1, 0))
plt.show()

# %%
# The same photograph through both arrays and back. CPSNR is the colour PSNR
# over the image with a 10 pixel border left out.
rgb = data.coffee()


def cpsnr(reference, estimate, border=10):
    inner = (slice(border, -border), slice(border, -border))
    err = reference[inner].astype(np.float64) - estimate[inner]
    return 10 * np.log10(255.0**2 / np.mean(err**2))


crop = (slice(120, 220), slice(180, 330))
fig, axes = plt.subplots(2, 3, figsize=(12, 5.8), layout="constrained")
for row, pattern in zip(axes, ["RGGB", "XTRANS"], strict=True):
    raw = ig.mosaic(rgb, pattern)
    row[0].imshow(raw[crop], cmap="gray", interpolation="nearest")
    row[0].set_title(f"{pattern} mosaic")
    for ax, method in zip(row[1:], ["bilinear", "best"], strict=True):
        out = ig.demosaic(raw, pattern, method)
        ax.imshow(out[crop], interpolation="nearest")
        ax.set_title(f"{method}: {cpsnr(rgb, out):.2f} dB")
for ax in axes.flat:
    ax.set_axis_off()
plt.show()

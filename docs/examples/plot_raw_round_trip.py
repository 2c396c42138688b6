"""
A simulated raw, developed
==========================

:func:`~imgform_rs.simulate_sensor` turns a linear RGB picture into what a
12-bit Bayer sensor would record: photon shot noise (Poisson, from the full-well
capacity), Gaussian read noise, a black level and the colour filter array.
:func:`~imgform_rs.dng.write_dng` stores it as a DNG that LibRaw (through
rawpy) decodes, and :func:`~imgform_rs.develop` develops it: black subtraction,
white balance, colour matrix, demosaicing and the sRGB tone curve in one pass.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from skimage import data

import imgform_rs as ig
from imgform_rs.dng import write_dng

# sRGB-ish gamma undone: the sensor sees linear light.
linear = ((data.chelsea() / 255.0) ** 2.2).astype(np.float32)
captures = {}
for full_well in (40_000, 2_000, 200):
    captures[full_well] = ig.simulate_sensor(
        linear, "RGGB", full_well=full_well, read_noise=2.0, bit_depth=12, black_level=64, seed=1
    )
raw = captures[40_000]
print("raw", raw.shape, raw.dtype, "range", raw.min(), raw.max())

# %%
# Each capture written as a DNG and developed back; fewer electrons per pixel
# (a smaller photosite, or less light) means more shot noise.
fig, axes = plt.subplots(1, 4, figsize=(13, 2.9), layout="constrained")
axes[0].imshow(raw[100:200, 150:280], cmap="gray", interpolation="nearest")
axes[0].set_title("the raw mosaic (crop)")
with tempfile.TemporaryDirectory() as folder:
    for ax, (full_well, capture) in zip(axes[1:], captures.items(), strict=True):
        path = Path(folder) / f"chelsea_{full_well}.dng"
        write_dng(path, capture, "RGGB", white_level=4095, black_level=64)
        rgb = ig.develop(path, demosaic="best", white_balance="none")
        ax.imshow(rgb)
        ax.set_title(f"developed, full well {full_well} e-")
for ax in axes:
    ax.set_axis_off()
plt.show()

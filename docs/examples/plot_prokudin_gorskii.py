"""
The three-colour technique: a Prokudin-Gorskii plate aligned
============================================================

Sergei Prokudin-Gorskii photographed the Russian Empire around 1910 as three
exposures on one glass plate, through blue, green and red filters, top to
bottom. Stacking the thirds gives colour only once they are aligned: the camera
and the subject moved between exposures. :func:`~imgform_rs.colorize_plate`
cuts the plate, aligns two channels onto the third with
:func:`~imgform_rs.align` (normalised cross-correlation, coarse to fine), and
crops what the shifts and the scanning frame leave.

The example reads the cathedral plate from the shared sample data when it sits
beside the checkout (``../shared/data/pg/cathedral.jpg``, the folder the tests
use); elsewhere it builds a plate of the same kind from a colour photograph,
with known shifts and a different brightness per filter.
"""

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import imgform_rs as ig


def shared_plate() -> Path | None:
    """The cathedral scan in a ``shared`` folder beside the checkout, if any."""
    for base in Path.cwd().resolve().parents:
        candidate = base / "shared" / "data" / "pg" / "cathedral.jpg"
        if candidate.exists():
            return candidate
    return None


def synthetic_plate() -> np.ndarray:
    """Blue, green and red exposures of scikit-image's coffee, stacked top to
    bottom, each moved by its own shift and exposed differently."""
    from skimage import data

    rgb = data.coffee().astype(np.float64)
    # The shifts that realign each exposure onto blue, as on the real plate;
    # the exposure itself is displaced the other way.
    moves = {"b": (0, 0), "g": (5, 2), "r": (12, 3)}
    gains = {"b": 0.8, "g": 1.0, "r": 0.9}
    thirds = []
    for c, index in (("b", 2), ("g", 1), ("r", 0)):
        channel = np.roll(rgb[..., index] * gains[c], np.negative(moves[c]), axis=(0, 1))
        thirds.append(np.clip(channel, 0, 255).astype(np.uint8))
    return np.vstack(thirds)


path = shared_plate()
plate = ig.read_plate(path) if path is not None else synthetic_plate()
print("plate:", path.name if path else "synthetic (coffee)", plate.shape, plate.dtype)

# %%
# Before: the thirds stacked as they are. After: aligned onto blue, the frame
# in which the published shifts are usually given.
h = plate.shape[0] // 3
b, g, r = plate[:h], plate[h : 2 * h], plate[2 * h : 3 * h]
naive = ig.stack_channels(r, g, b)
rgb, shifts = ig.colorize_plate(plate, reference="b")
for channel, shift in shifts.items():
    print(f"{channel}: shift (dy, dx) = {shift}")

fig, axes = plt.subplots(1, 3, figsize=(12, 5), layout="constrained")
axes[0].imshow(plate, cmap="gray")
axes[0].set_title("the plate: B, G, R")
axes[1].imshow(naive)
axes[1].set_title("thirds stacked unaligned")
axes[2].imshow(rgb)
moved = ", ".join(f"{c.upper()} {s}" for c, s in shifts.items() if c != "b")
axes[2].set_title(f"colorize_plate: {moved}")
for ax in axes:
    ax.set_axis_off()
plt.show()

# %%
# The score surface of the green-onto-blue search: normalised cross-correlation
# at every candidate shift of the finest level; its peak is the shift.
result = ig.align(b, g, metric="ncc")
fig, ax = plt.subplots(figsize=(5, 4.2), layout="constrained")
image = ax.imshow(result.surface, cmap="viridis")
ax.set_title(f"NCC over the candidate shifts; best {result.shift}")
fig.colorbar(image)
plt.show()

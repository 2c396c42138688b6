"""
Spherical aberration: through-focus PSFs and spot diagrams
==========================================================

A lens with spherical aberration focuses its marginal rays closer than its
paraxial ones. In wave optics the pupil carries the wavefront error

.. math::

   W(\\rho) = W_{020} \\rho^2 + W_{040} \\rho^4

(defocus and spherical aberration, in waves, :math:`\\rho` the normalised pupil
radius), and the point-spread function is :math:`|\\mathcal{F}\\{P e^{2\\pi i W}\\}|^2`.
:func:`~imgform_rs.pupil_psf` computes it, integrated over each pixel.
Without aberration the PSFs are mirror images about the paraxial focus; with one
wave of :math:`W_{040}` the sharpest plane moves to :math:`W_{020} = -1` and the two
sides blur differently.
"""

import matplotlib.pyplot as plt
import numpy as np

import imgform_rs as ig

optics = {"n_pixels": 41, "pixel_pitch": 0.55e-3, "f_number": 2.0, "wavelength": 0.55e-3}
defocus = np.linspace(-2.0, 2.0, 9)
rows = {
    w040: [ig.pupil_psf(defocus=d, spherical=w040, **optics) for d in defocus] for w040 in (0, 1)
}
airy = rows[0][4]
peak = max(float(p.max()) for row in rows.values() for p in row)

fig, axes = plt.subplots(2, 9, figsize=(12, 3.4), layout="constrained")
for r, (w040, psfs) in enumerate(rows.items()):
    for ax, d, psf in zip(axes[r], defocus, psfs, strict=True):
        # Square-rooted, one scale for all, so the rings show.
        ax.imshow(np.sqrt(psf / peak), cmap="gray", vmin=0, vmax=1)
        ax.set_title(f"W020={d:+.1f}\nStrehl {ig.strehl_ratio(psf, airy):.2f}", fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
    axes[r, 0].set_ylabel(f"W040 = {w040}")
fig.suptitle("Through-focus PSFs, f/2, 550 nm, 0.55 µm pixels")
plt.show()

# %%
# The geometric view: a spot diagram traces rays through the pupil of a 50 mm
# f/2 lens whose marginal ray focuses 0.3 mm before the paraxial focus. The
# smallest RMS spot lies two thirds of the way to the marginal focus, where
# :func:`~imgform_rs.best_focus` finds it.
best = ig.best_focus(f=50.0, f_number=2.0, spherical_lsa=0.3)
planes = [50.0, best, 49.7]
names = ["paraxial focus", "best focus", "marginal focus"]
fig, axes = plt.subplots(1, 3, figsize=(10, 3.6), layout="constrained", sharex=True, sharey=True)
for ax, plane, name in zip(axes, planes, names, strict=True):
    spot = ig.spot_diagram(f=50.0, f_number=2.0, spherical_lsa=0.3, n_rays=3000, image_plane=plane)
    ax.plot(*spot.hits.T * 1000, ".", ms=1)
    ax.set_aspect("equal")
    ax.set_title(f"{name}, {plane:.3f} mm\nRMS radius {spot.rms_radius * 1000:.1f} µm", fontsize=9)
    ax.set_xlabel("x (µm)")
axes[0].set_ylabel("y (µm)")
plt.show()

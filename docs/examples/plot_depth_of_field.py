"""
Depth of field: a focus and aperture sweep
==========================================

A thin lens focused at distance :math:`D_f` images a point at distance :math:`D`
as a disc, the circle of confusion, of diameter

.. math::

   c(D) = \\frac{f^2}{N (D_f - f)} \\, \\frac{|D - D_f|}{D},

where :math:`f` is the focal length and :math:`N` the f-number.
:func:`~imgform_rs.render_defocus` blurs every pixel of a picture by its own disc,
from its depth, without letting a sharp foreground bleed into a blurred background.
Here the sample scene is focused on each box in turn at f/1.2, then on the middle
box at three apertures.
"""

import matplotlib.pyplot as plt
import numpy as np

import imgform_rs as ig
from imgform_rs import scene

F_MM, SENSOR_MM, WIDTH, HEIGHT = 50.0, 36.0, 640, 480
PITCH_MM = SENSOR_MM / WIDTH

camera = ig.Camera.from_fov(float(ig.field_of_view(F_MM, SENSOR_MM)), (HEIGHT, WIDTH))
camera = camera.look_at(eye=(4.5, 1.6, -3.0), target=(-0.5, 0.9, 9.0))
v, u = np.mgrid[0:HEIGHT, 0:WIDTH]
colour, z = scene.render(camera, np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64))
image = (colour.reshape(HEIGHT, WIDTH, 3).clip(0, 1) * 255 + 0.5).astype(np.uint8)
# render_defocus takes z-depth in mm; the sky (no hit) is put at 10 km.
depth = np.where(np.isfinite(z), z * 1000.0, 1e7).reshape(HEIGHT, WIDTH).astype(np.float32)

# %%
# The z-depth of each box's centre, in mm: the focus distances of the sweep.
centres = [(np.array(b.lo) + np.array(b.hi)) / 2 for b in scene.BOXES]
focus = [float((camera.R @ c + camera.t)[2]) * 1000.0 for c in centres]
print("box distances (mm):", [round(d) for d in focus])

# Shown at about one screen pixel per image pixel, the part with the boxes:
# the blur discs are a few pixels wide.
view = (slice(60, 400), slice(100, 640))
fig, axes = plt.subplots(2, 3, figsize=(12, 5.6), layout="constrained")
for ax, d in zip(axes[0], focus, strict=True):
    near, far = ig.depth_of_field(F_MM, 1.2, d, coc=0.03)
    out = ig.render_defocus(image, depth, f=F_MM, N=1.2, focus_distance=d, pixel_pitch=PITCH_MM)
    ax.imshow(out[view])
    ax.set_title(
        f"f/1.2 focused at {d / 1000:.1f} m\nsharp from {near / 1000:.2f} to {far / 1000:.2f} m"
    )
for ax, n in zip(axes[1], (1.2, 4.0, 16.0), strict=True):
    out = ig.render_defocus(
        image, depth, f=F_MM, N=n, focus_distance=focus[1], pixel_pitch=PITCH_MM
    )
    ax.imshow(out[view])
    near, far = ig.depth_of_field(F_MM, n, focus[1], coc=0.03)
    ax.set_title(
        f"f/{n:g} at {focus[1] / 1000:.1f} m: sharp {near / 1000:.1f} to {far / 1000:.1f} m"
    )
for ax in axes.flat:
    ax.set_axis_off()
plt.show()

# %%
# The depth of field itself: the near and far limits of acceptable sharpness
# (c = 0.03 mm, a full-frame sensor's usual value) against the f-number, for
# the focus on the middle box. Past the hyperfocal distance the far limit is
# infinite.
n = np.geomspace(1.2, 22, 60)
near, far = ig.depth_of_field(F_MM, n, focus[1], coc=0.03)
hyperfocal = ig.hyperfocal_distance(F_MM, n, 0.03)
fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
ax.fill_between(n, near / 1000, np.minimum(far, 1e5) / 1000, alpha=0.3, label="in focus")
ax.plot(n, hyperfocal / 1000, "k--", label="hyperfocal distance")
ax.axhline(focus[1] / 1000, color="tab:blue", lw=1, label="focus distance")
ax.set_xscale("log")
ax.set_yscale("log")
ax.set_ylim(1, 100)
ax.set_xlabel("f-number N")
ax.set_ylabel("distance (m)")
ax.set_title(f"Depth of field of a 50 mm lens focused at {focus[1] / 1000:.1f} m")
ax.legend()
plt.show()

"""
Vanishing points and the horizon
================================

Lines that are parallel in the world meet in the image at their direction's
vanishing point, :math:`v \\simeq K R d`; the vanishing points of all horizontal
directions lie on the horizon, the ground plane's vanishing line. This example
renders the sample scene through a pinhole camera, extends every box edge along
the two horizontal axes to its vanishing point, and draws the horizon from
:func:`~imgform_rs.vanishing_line`.
"""

import matplotlib.pyplot as plt
import numpy as np

import imgform_rs as ig
from imgform_rs import scene

# %%
# A 50 mm lens on a 36 mm wide sensor, 640 x 480 pixels, 1.6 m above the
# ground (the scene's world frame has y up), looking slightly down the scene.
camera = ig.Camera.from_fov(float(ig.field_of_view(50.0, 36.0)), (480, 640))
camera = camera.look_at(eye=(4.5, 1.6, -3.0), target=(-0.5, 0.9, 9.0))

# One ray per pixel centre, shaded by the scene's ray caster, the ground's
# checkerboard averaged over each pixel's footprint.
v, u = np.mgrid[0:480, 0:640]
colour, _ = scene.render(camera, np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64))
image = colour.reshape(480, 640, 3).clip(0, 1)

# %%
# The vanishing points of the world's x and z axes, and the horizon as a line
# :math:`a u + b v + c = 0`.
vps = {name: ig.vanishing_point(camera, d) for name, d in [("x", (1, 0, 0)), ("z", (0, 0, 1))]}
a, b, c = ig.vanishing_line(camera, (0, 1, 0))
for name, vp in vps.items():
    print(f"{name} axis: vanishing point {vp.point.round(1)}, at infinity: {vp.at_infinity}")
print(f"horizon: {a:.4f} u + {b:.4f} v + {c:.1f} = 0")

# %%
# Every box corner joined to both vanishing points: the edges of the boxes lie
# on these lines.
fig, ax = plt.subplots(figsize=(12, 3.4), layout="constrained")
ax.imshow(image)
colours = {"x": "tab:red", "z": "tab:blue"}
for box in scene.BOXES:
    (x0, y0, z0), (x1, y1, z1) = box.lo, box.hi
    for corner in [(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]:
        start = camera.project(corner)
        for name, vp in vps.items():
            ax.plot(*zip(start, vp.point, strict=True), color=colours[name], lw=0.6)
for name, vp in vps.items():
    ax.plot(*vp.point, "o", color=colours[name], ms=8, label=f"vanishing point of {name}")
# A canvas wide enough for both points and the picture, 40 px to spare.
points = np.array([vp.point for vp in vps.values()] + [[0, 0], [640, 480]])
(left, top), (right, bottom) = points.min(axis=0) - 40, points.max(axis=0) + 40
us = np.array([left, right])
ax.plot(us, -(a * us + c) / b, color="tab:green", lw=2, label="horizon")
ax.set_xlim(left, right)
ax.set_ylim(bottom, top)
ax.legend(loc="upper right", fontsize=8)
ax.set_title("Box edges meet at their vanishing points, which lie on the horizon")
plt.show()

"""
Measuring heights in one image
==============================

Single-view metrology (Criminisi, Reid and Zisserman): with the vertical
vanishing point and the horizon, the height of anything standing on the ground
follows from one reference of known height, by a cross-ratio along the
vertical. No calibration is needed: the camera below is used only to render the
picture and to give the true heights to compare with.

The segments are the images of the boxes' vertical and horizontal edges, with
half a pixel of noise on every end point, as a line detector would give them.
"""

import matplotlib.pyplot as plt
import numpy as np

import imgform_rs as ig
from imgform_rs import scene

camera = ig.Camera.from_fov(float(ig.field_of_view(50.0, 36.0)), (480, 640))
camera = camera.look_at(eye=(4.5, 1.6, -3.0), target=(-0.5, 0.9, 9.0))
v, u = np.mgrid[0:480, 0:640]
colour, _ = scene.render(camera, np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64))
image = colour.reshape(480, 640, 3).clip(0, 1)

rng = np.random.default_rng(0)


def segment(p, q):
    """The image of the 3D segment p-q as [x1, y1, x2, y2], 0.5 px of noise."""
    return np.hstack([camera.project(p), camera.project(q)]) + rng.normal(0, 0.5, 4)


# %%
# Each box's four vertical edges, and its edges along the world's x and z axes
# (the top and bottom faces' edges).
vertical, along_x, along_z, poles = [], [], [], []
for box in scene.BOXES:
    (x0, y0, z0), (x1, y1, z1) = box.lo, box.hi
    for x, z in [(x0, z0), (x1, z0), (x0, z1), (x1, z1)]:
        vertical.append(segment((x, y0, z), (x, y1, z)))
    for y in (y0, y1):
        along_x += [segment((x0, y, z), (x1, y, z)) for z in (z0, z1)]
        along_z += [segment((x, y, z0), (x, y, z1)) for x in (x0, x1)]
    # The front edge nearer the camera (which stands to the right, at x = 4.5)
    # is the one we measure: visible on every box.
    poles.append(vertical[-3])

vertical_fit = ig.fit_vanishing_point(vertical, allow_infinite=True)
vp_x = ig.fit_vanishing_point(along_x)
vp_z = ig.fit_vanishing_point(along_z)
horizon = ig.fit_horizon(vp_x.homogeneous, vp_z.homogeneous)
print(f"vertical vanishing point {vertical_fit.point.round(1)}")
print(f"RMS residual of its segments {vertical_fit.residual:.2f} px")
print(f"horizon (a, b, c) = {np.round(horizon, 4)}")

# %%
# The near box (1.0 m) is the reference; the others are measured against it,
# and so is the camera's height above the ground.
poles = np.array(poles)
base, top = poles[:, :2], poles[:, 2:]
reference = 1.0
heights = ig.relative_height(
    horizon, base[1:], top[1:], base[0], top[0], reference, vertical_vp=vertical_fit.homogeneous
)
eye_height = ig.camera_height(
    horizon, base[0], top[0], reference, vertical_vp=vertical_fit.homogeneous
)
truth = [box.hi[1] - box.lo[1] for box in scene.BOXES]
for h, t in zip(heights, truth[1:], strict=True):
    print(f"measured {h:.3f} m, true {t:.3f} m ({100 * (h / t - 1):+.1f} %)")
print(f"camera height {eye_height:.3f} m (true 1.6 m)")

# %%
# The measurements drawn on the picture: each measured edge, and the horizon
# through the two horizontal vanishing points.
fig, ax = plt.subplots(figsize=(9, 6.75), layout="constrained")
ax.imshow(image)
us = np.array([0.0, 639.0])
a, b, c = horizon
ax.plot(us, -(a * us + c) / b, color="tab:green", lw=1.5, label="fitted horizon")
labels = [f"reference {reference:.2f} m"] + [
    f"{h:.2f} m (true {t:.2f})" for h, t in zip(heights, truth[1:], strict=True)
]
for (x1, y1, x2, y2), text in zip(poles, labels, strict=True):
    ax.plot([x1, x2], [y1, y2], color="white", lw=3)
    ax.plot([x1, x2], [y1, y2], color="black", lw=1.2)
    ax.annotate(
        text,
        (x2, y2),
        xytext=(-10, -12),
        textcoords="offset points",
        ha="right",
        fontsize=9,
        bbox={"boxstyle": "round", "fc": "white", "alpha": 0.85},
    )
ax.set_title(f"Heights from one image; camera height {eye_height:.2f} m (true 1.60)")
ax.legend(loc="lower right")
ax.set_axis_off()
plt.show()

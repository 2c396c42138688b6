"""
Light fields: a focal stack after capture
=========================================

A plenoptic camera records the scene from a grid of sub-aperture viewpoints.
A plane at depth :math:`Z` moves by :math:`\\alpha = b f / Z` pixels from one view
to the next (baseline :math:`b`, focal length :math:`f` in pixels), so shifting
view :math:`(u, v)` by :math:`\\alpha (u - u_c, v - v_c)` and averaging brings
that plane into focus and blurs the others (shift-and-add, Ng 2005).
:func:`~imgform_rs.render_light_field` renders a 7 x 7 grid of the sample
scene, :func:`~imgform_rs.focal_stack` refocuses it on each box, and a smaller
synthetic aperture (fewer views) deepens the depth of field.
"""

import matplotlib.pyplot as plt
import numpy as np

import imgform_rs as ig
from imgform_rs import scene

camera = ig.Camera.from_fov(float(ig.field_of_view(50.0, 36.0)), (192, 256))
camera = camera.look_at(eye=(4.5, 1.6, -3.0), target=(-0.5, 0.9, 9.0))
baseline = 0.06  # metres between neighbouring views
lf = ig.render_light_field(scene, camera=camera, baseline=baseline, grid=(7, 7))
print("light field", lf.shape, lf.dtype)  # (U, V, H, W, 3)

# %%
# The disparity of each box's centre, in pixels per view step.
centres = [(np.array(b.lo) + np.array(b.hi)) / 2 for b in scene.BOXES]
depths = [float((camera.R @ c + camera.t)[2]) for c in centres]
alphas = [float(ig.view_disparity(camera, baseline, z)) for z in depths]
for z, a in zip(depths, alphas, strict=True):
    print(f"box at {z:5.1f} m: alpha = {a:.2f} px per view")

# %%
# Four views from the corners of the grid, then the focal stack.
fig, axes = plt.subplots(1, 4, figsize=(12, 2.5), layout="constrained")
for ax, (i, j) in zip(axes, [(0, 0), (0, 6), (6, 0), (6, 6)], strict=True):
    ax.imshow(lf[i, j])
    ax.set_title(f"view ({i}, {j})")
    ax.set_axis_off()
plt.show()

stack = ig.focal_stack(lf, alphas)
small = ig.refocus(lf, alphas[0], aperture=1.0)
fig, axes = plt.subplots(2, 2, figsize=(10, 7.6), layout="constrained")
names = ("near", "middle", "far")
titles = [f"focus on the {n} box, alpha {a:.2f}" for n, a in zip(names, alphas, strict=True)]
for ax, frame, title in zip(
    axes.flat, [*stack, small], [*titles, "near box, aperture=1"], strict=True
):
    ax.imshow(frame)
    ax.set_title(title)
    ax.set_axis_off()
plt.show()

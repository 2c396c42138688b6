"""
Lens distortion and lateral chromatic aberration
================================================

A Brown-Conrady lens moves each normalised image point :math:`(x, y)` at radius
:math:`r` to

.. math::

   x_d = x (1 + k_1 r^2 + k_2 r^4 + k_3 r^6) + 2 p_1 x y + p_2 (r^2 + 2 x^2),

and likewise for :math:`y`. With :math:`k_1 < 0` straight lines bow outwards
(barrel distortion). Here the sample scene is ray-traced through such a lens
(:meth:`Camera.rays <imgform_rs.Camera.rays>` inverts the model per pixel), then
:func:`~imgform_rs.undistort_image` straightens it again. Below, lateral
chromatic aberration: red and blue magnified differently about the centre, and
undone by :func:`~imgform_rs.correct_lateral_ca`.
"""

import matplotlib.pyplot as plt
import numpy as np

import imgform_rs as ig
from imgform_rs import scene

BARREL = (-0.7, 0.25, 0.0, 0.0, 0.0)  # k1, k2, p1, p2, k3: OpenCV's order


def render(camera):
    h, w = camera.image_size
    v, u = np.mgrid[0:h, 0:w]
    colour, _ = scene.render(camera, np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64))
    return (colour.reshape(h, w, 3).clip(0, 1) * 255 + 0.5).astype(np.uint8)


fov = float(ig.field_of_view(50.0, 36.0))
eye, target = (4.5, 1.6, -3.0), (-0.5, 0.9, 9.0)
pinhole = ig.Camera.from_fov(fov, (480, 640)).look_at(eye, target)
lens = ig.Camera.from_fov(fov, (480, 640), dist=BARREL).look_at(eye, target)
barrel = render(lens)
straight = ig.undistort_image(barrel, lens)

fig, axes = plt.subplots(1, 3, figsize=(12, 3.4), layout="constrained")
for ax, img, title in zip(
    axes,
    [render(pinhole), barrel, straight],
    ["pinhole (no distortion)", "barrel lens, k1 = -0.7, k2 = 0.25", "undistort_image of it"],
    strict=True,
):
    ax.imshow(img)
    ax.set_title(title)
    ax.set_axis_off()
plt.show()

# %%
# Lateral chromatic aberration scales red by 1.008 and blue by 0.992 about the
# image centre: colour fringes grow towards the corners. The crops show the
# top-right corner, magnified three times.
image = render(pinhole)
fringed = ig.add_lateral_ca(image, scale_r=1.008, scale_b=0.992)
fixed = ig.correct_lateral_ca(fringed, 1.008, 0.992)
crop = (slice(150, 260), slice(470, 640))
fig, axes = plt.subplots(1, 3, figsize=(12, 2.9), layout="constrained")
for ax, img, title in zip(
    axes, [image, fringed, fixed], ["original", "add_lateral_ca", "correct_lateral_ca"], strict=True
):
    ax.imshow(img[crop], interpolation="nearest")
    ax.set_title(title)
    ax.set_axis_off()
plt.show()

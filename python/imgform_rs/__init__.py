"""imgform-rs: how a photograph is formed, in Rust, for NumPy.

Camera geometry and lens optics, colour filter arrays and demosaicing,
three-colour alignment and raw development. Conventions (axis order, colour
order, camera frame, CFA patterns, shift sign) are documented in
``CONVENTIONS.md``.
"""

from ._native import RawError
from .distortion import distort_points, undistort_points
from .optics import (
    circle_of_confusion,
    depth_of_field,
    dolly_zoom_focal_length,
    field_of_view,
    hyperfocal_distance,
    image_distance,
    magnification,
    render_defocus,
)
from .projection import project_orthographic, project_pinhole

__all__ = [
    "RawError",
    "circle_of_confusion",
    "depth_of_field",
    "distort_points",
    "dolly_zoom_focal_length",
    "field_of_view",
    "hyperfocal_distance",
    "image_distance",
    "magnification",
    "project_orthographic",
    "project_pinhole",
    "render_defocus",
    "undistort_points",
]

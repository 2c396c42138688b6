"""imgform-rs: how a photograph is formed, in Rust, for NumPy.

Camera geometry and lens optics, colour filter arrays and demosaicing,
three-colour alignment and raw development. Conventions (axis order, colour
order, camera frame, CFA patterns, shift sign) are documented in
``CONVENTIONS.md``.
"""

from ._native import RawError
from .align import (
    Alignment,
    align,
    apply_shift,
    colorize_plate,
    read_plate,
    similarity,
    stack_channels,
)
from .camera import Camera, VanishingPoint, look_at, vanishing_line, vanishing_point
from .chromatic import add_lateral_ca, correct_lateral_ca
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
from .remap import (
    RemapMap,
    distort_image,
    distort_map,
    remap,
    undistort_image,
    undistort_map,
)

__all__ = [
    "Alignment",
    "Camera",
    "RawError",
    "RemapMap",
    "VanishingPoint",
    "add_lateral_ca",
    "align",
    "apply_shift",
    "circle_of_confusion",
    "colorize_plate",
    "correct_lateral_ca",
    "depth_of_field",
    "distort_image",
    "distort_map",
    "distort_points",
    "dolly_zoom_focal_length",
    "field_of_view",
    "hyperfocal_distance",
    "image_distance",
    "look_at",
    "magnification",
    "project_orthographic",
    "project_pinhole",
    "read_plate",
    "remap",
    "render_defocus",
    "similarity",
    "stack_channels",
    "undistort_image",
    "undistort_map",
    "undistort_points",
    "vanishing_line",
    "vanishing_point",
]

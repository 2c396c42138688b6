"""imgform-rs: how a photograph is formed, in Rust, for NumPy.

Camera geometry and lens optics, colour filter arrays and demosaicing,
three-colour alignment and raw development. Conventions (axis order, colour
order, camera frame, CFA patterns, shift sign) are documented in
``CONVENTIONS.md``.
"""

from ._native import RawError
from .camera import Camera, VanishingPoint, look_at, vanishing_line, vanishing_point
from .distortion import distort_points, undistort_points
from .projection import project_orthographic, project_pinhole

__all__ = [
    "Camera",
    "RawError",
    "VanishingPoint",
    "distort_points",
    "look_at",
    "project_orthographic",
    "project_pinhole",
    "undistort_points",
    "vanishing_line",
    "vanishing_point",
]

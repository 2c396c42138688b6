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
from .distortion import distort_points, undistort_points
from .projection import project_orthographic, project_pinhole

__all__ = [
    "Alignment",
    "RawError",
    "align",
    "apply_shift",
    "colorize_plate",
    "distort_points",
    "project_orthographic",
    "project_pinhole",
    "read_plate",
    "similarity",
    "stack_channels",
    "undistort_points",
]
